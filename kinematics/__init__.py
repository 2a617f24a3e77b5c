"""Kinematic tree models and dynamics (forward kinematics, RNEA); imports nothing of parmor.

The names below are read from their modules when first asked for (``kinematics.rnea``), so
that importing a light module of the package (``kinematics.bodyplan``) does not import
numpy and the dynamics.
"""

from importlib import import_module

#: name -> the module that defines it
_WHERE = {
    "Body": "kinematics.model",
    "Joint": "kinematics.model",
    "Model": "kinematics.model",
    "Segment": "kinematics.templates",
    "Template": "kinematics.templates",
    "TemplateParams": "kinematics.templates",
    "box_inertia": "kinematics.spatial",
    "build": "kinematics.templates",
    "center_of_mass": "kinematics.dynamics",
    "combine_parts": "kinematics.spatial",
    "default_lengths": "kinematics.templates",
    "external_force_at": "kinematics.dynamics",
    "forward_kinematics": "kinematics.dynamics",
    "gravity_torques": "kinematics.dynamics",
    "invert_transform": "kinematics.spatial",
    "jacobian": "kinematics.dynamics",
    "joint_wrenches": "kinematics.dynamics",
    "mass_matrix": "kinematics.dynamics",
    "matrix_from_axis_angle": "kinematics.spatial",
    "matrix_from_rpy": "kinematics.spatial",
    "nonlinear_effects": "kinematics.dynamics",
    "point_inertia": "kinematics.spatial",
    "rnea": "kinematics.dynamics",
    "rot_x": "kinematics.spatial",
    "rot_y": "kinematics.spatial",
    "rot_z": "kinematics.spatial",
    "sphere_inertia": "kinematics.spatial",
    "transform": "kinematics.spatial",
    "transform_from": "kinematics.spatial",
    "transform_from_pq": "kinematics.spatial",
    "tube_inertia": "kinematics.spatial",
    "tube_mass": "kinematics.spatial",
}


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'kinematics' has no attribute {name!r}")


__all__ = [
    "Body",
    "Joint",
    "Model",
    "Segment",
    "Template",
    "TemplateParams",
    "box_inertia",
    "build",
    "center_of_mass",
    "combine_parts",
    "default_lengths",
    "external_force_at",
    "forward_kinematics",
    "gravity_torques",
    "invert_transform",
    "jacobian",
    "joint_wrenches",
    "mass_matrix",
    "matrix_from_axis_angle",
    "matrix_from_rpy",
    "nonlinear_effects",
    "point_inertia",
    "rnea",
    "rot_x",
    "rot_y",
    "rot_z",
    "sphere_inertia",
    "transform",
    "transform_from",
    "transform_from_pq",
    "tube_inertia",
    "tube_mass",
]
