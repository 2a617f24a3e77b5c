"""URDF of an :class:`~export.model3d.Assembly` (pure: returns the text).

The robot is built with yourdfpy's data model (:func:`urdf_robot`: ``yourdfpy.Robot`` of
``Link``/``Joint``/``Inertial``/``Visual``/``Collision``/``Geometry``), the one structure a
caller can also hand to ``yourdfpy.URDF(robot=...)`` for forward kinematics; the text is
written from the same builder with plain records in place of the classes (``_RECORDS``), so
writing it does not import yourdfpy (and trimesh behind it). yourdfpy's own
writer formats numbers with ``str`` and recomputes roll-pitch-yaw from each 4x4 with
``euler_from_matrix`` (float noise such as ``6.1e-17``), so :func:`urdf_string` serialises the
same data model with :mod:`xml.etree.ElementTree` and deterministic numbers instead: 10
significant digits, ``-0`` written as ``0``, values below 1e-12 (m, rad) written as ``0``.
The tests load every written file back with yourdfpy (meshes included) and ``check_urdf``.

Conventions: SI units; one ``<link>`` per body; its ``<inertial>`` sits at the body's centre
of mass with the body's axes (``rpy = 0``), so the inertia tensor is the body's tensor about
its COM in body axes. A body of zero mass (a pure frame) gets no ``<inertial>``: URDF reads
that as a massless link, which is legal; no artificial inertia is invented. Every part
geometry becomes a ``<visual>`` and a ``<collision>``; meshes are referenced as
``MESH_DIR/NAME.stl`` relative to the URDF file.

The helpers :func:`number`, :func:`mesh_file` and :func:`check_assembly` are shared with
the MJCF exporter; roll-pitch-yaw comes from :func:`kinematics.spatial.rpy_from_matrix`.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape

import numpy as np

from export.assembly import with_payload as loaded
from export.model3d import Assembly, BodySpec, Geometry, JointSpec
from kinematics.spatial import rpy_from_matrix

if TYPE_CHECKING:  # yourdfpy (and trimesh behind it) is imported only when exporting
    import yourdfpy

#: Significant digits of every number written.
DIGITS = 10
#: Lengths (m) and angles (rad) smaller than this are written as 0 (float noise).
SNAP = 1e-12
JOINT_KINDS = ("revolute", "continuous", "fixed")
#: m per STL unit: the STL files are in millimetres, as every slicer expects.
MESH_SCALE = 0.001
GEOMETRY_KINDS = ("mesh", "box", "cylinder", "sphere")
#: N m s/rad: the viscous friction of a passive joint's bearing hub (a free wheel's two
#: small ball bearings, greased: of the order of 1e-4), in both models.
PASSIVE_DAMPING = 1e-4


# --- shared helpers ------------------------------------------------------------------------


def number(x: float) -> str:
    """Deterministic text of a finite float: ``DIGITS`` significant digits, no ``-0``."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot export the non-finite number {x!r}")
    s = f"{x:.{DIGITS}g}"
    return "0" if float(s) == 0.0 else s


def numbers(xs, snap: float = 0.0) -> str:
    """Space-separated :func:`number` of each value; ``|x| < snap`` is written as 0."""
    return " ".join(number(0.0 if abs(float(x)) < snap else x) for x in xs)


def check_name(name: str, what: str) -> str:
    """``name`` if it is a non-empty string XML can carry (escaping is ElementTree's job)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"{what} name must be a non-empty string, got {name!r}")
    bad = [c for c in name if ord(c) < 0x20 or 0xD800 <= ord(c) <= 0xDFFF or c in "\ufffe\uffff"]
    if bad:
        raise ValueError(f"{what} name {name!r} contains characters XML cannot hold")
    return name


def mesh_file(mesh: str | None) -> str:
    """The file name (``NAME.stl``) of a mesh geometry; ``.stl`` is added when missing.

    A mesh name comes from the assembly (ultimately from user-chosen names), so it must be
    a plain file name: a path separator, ``..``, or a character XML cannot hold is a
    ``ValueError``, never a path outside the mesh folder.
    """
    if not isinstance(mesh, str) or not mesh.strip():
        raise ValueError(f"a mesh geometry needs a file name, got {mesh!r}")
    if "/" in mesh or "\\" in mesh or ".." in mesh or ":" in mesh:
        raise ValueError(f"mesh file name {mesh!r} must not contain '/', '\\', ':' or '..'")
    check_name(mesh, "mesh")
    return mesh if mesh.lower().endswith(".stl") else f"{mesh}.stl"


def mesh_path(mesh_dir: str, file: str) -> str:
    """``mesh_dir/file`` with a forward slash (URDF and MJCF paths), or ``file`` alone."""
    d = mesh_dir.rstrip("/")
    return f"{d}/{file}" if d else file


def joint_damping(j: JointSpec) -> float:
    """N m s/rad: the passive damping of joint ``j`` in both models, the servo motor's
    back-EMF ``effort / velocity`` of a position servo (a revolute joint with a speed); 0
    for wheels (their velocity servo is the motor line) and fixed joints; a passive joint's
    bearing: ``PASSIVE_DAMPING``. Neither model has dry friction (URDF ``friction`` 0, MJCF
    no ``frictionloss``)."""
    if j.passive:
        return PASSIVE_DAMPING
    if j.kind != "revolute" or not (math.isfinite(j.velocity) and j.velocity > 0):
        return 0.0
    return float(j.effort / j.velocity)


def unit_axis(axis: np.ndarray, joint: str) -> np.ndarray:
    """The joint axis (3,) normalised; a zero or non-finite axis is a ``ValueError``."""
    a = np.asarray(axis, dtype=float)
    n = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
    if not (math.isfinite(n) and n > 0):
        raise ValueError(f"joint {joint!r}: axis must be a non-zero finite (3,) vector")
    return a / n


def _check_transform(T: np.ndarray, what: str) -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{what}: origin must be a finite (4, 4) transform")
    rpy_from_matrix(T[:3, :3])  # checks the rotation
    return T


def check_assembly(assembly: Assembly) -> dict[str, BodySpec]:
    """Validate the tree of ``assembly``: unique valid names, one inbound joint per
    non-root body, parents before children. Returns body name -> body."""
    check_name(assembly.robot_type, "robot")
    bodies: dict[str, BodySpec] = {}
    for b in assembly.bodies:
        check_name(b.name, "body")
        if b.name in bodies:
            raise ValueError(f"body {b.name!r} appears twice")
        if not (math.isfinite(b.mass) and b.mass >= 0):
            raise ValueError(f"body {b.name!r}: mass must be finite and >= 0, got {b.mass}")
        bodies[b.name] = b
    if assembly.root not in bodies:
        raise ValueError(f"root body {assembly.root!r} is not among the bodies")
    placed, joints = {assembly.root}, set()
    for j in assembly.joints:
        check_name(j.name, "joint")
        if j.name in joints:
            raise ValueError(f"joint {j.name!r} appears twice")
        joints.add(j.name)
        if j.kind not in JOINT_KINDS:
            raise ValueError(f"joint {j.name!r}: kind {j.kind!r} is not one of {JOINT_KINDS}")
        if j.parent not in placed:
            raise ValueError(f"joint {j.name!r}: parent {j.parent!r} is not placed before it")
        if j.child not in bodies or j.child in placed:
            raise ValueError(f"joint {j.name!r}: child {j.child!r} is unknown or has a joint")
        placed.add(j.child)
        _check_transform(j.origin, f"joint {j.name!r}")
        unit_axis(j.axis, j.name)
        if j.kind == "revolute" and not (j.lower <= j.upper):
            raise ValueError(f"joint {j.name!r}: lower {j.lower} > upper {j.upper}")
    missing = sorted(set(bodies) - placed)
    if missing:
        raise ValueError(f"bodies without a joint to the tree: {', '.join(missing)}")
    return bodies


def symmetric_inertia(inertia: np.ndarray, what: str) -> np.ndarray:
    """The (3,3) tensor symmetrised, with off-diagonal float noise snapped to 0."""
    inertia = np.asarray(inertia, dtype=float)
    if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
        raise ValueError(f"{what}: inertia must be a finite (3, 3) matrix")
    out = 0.5 * (inertia + inertia.T)
    scale = float(np.max(np.abs(out)))
    out[np.abs(out) < 1e-12 * scale] = 0.0
    return out


# --- the yourdfpy data model ---------------------------------------------------------------


#: yourdfpy's classes as plain records (``types.SimpleNamespace`` of the keyword fields
#: given, which is all :func:`robot_xml` reads): the text is written without importing
#: yourdfpy, and trimesh and scipy.spatial behind it (about half a second of every
#: ``design --out``). The builders give every field the writer reads, for that reason.
_RECORDS = SimpleNamespace(
    **{
        name: SimpleNamespace
        for name in (
            "Robot", "Link", "Joint", "Inertial", "Visual", "Collision", "Material", "Color",
            "Geometry", "Mesh", "Box", "Cylinder", "Sphere", "Limit", "Dynamics",
        )
    }
)  # fmt: skip


def _geometry(g: Geometry, mesh_dir: str, y) -> yourdfpy.Geometry:
    size = tuple(float(s) for s in g.size)
    shape = {"mesh": None, "box": None, "cylinder": None, "sphere": None}
    if g.kind == "mesh":
        file = mesh_path(mesh_dir, mesh_file(g.mesh))
        shape["mesh"] = y.Mesh(filename=file, scale=np.full(3, MESH_SCALE))
    elif g.kind == "box" and len(size) == 3:
        shape["box"] = y.Box(size=np.array(size))
    elif g.kind == "cylinder" and len(size) == 2:
        shape["cylinder"] = y.Cylinder(radius=size[0], length=size[1])
    elif g.kind == "sphere" and len(size) == 1:
        shape["sphere"] = y.Sphere(radius=size[0])
    else:
        raise ValueError(f"geometry {g.name!r}: kind {g.kind!r} with size {size} is not supported")
    return y.Geometry(**shape)


def material_name(rgba) -> str:
    """A material name unique per colour (urdfdom shares materials by name)."""
    return "rgba_" + "_".join(number(c) for c in rgba)


def _link(body: BodySpec, mesh_dir: str, y) -> yourdfpy.Link:
    link = y.Link(name=body.name, inertial=None, visuals=[], collisions=[])
    if body.mass > 0:
        origin = np.eye(4)
        origin[:3, 3] = np.asarray(body.com, dtype=float)
        link.inertial = y.Inertial(
            origin=origin,
            mass=float(body.mass),
            inertia=symmetric_inertia(body.inertia, f"body {body.name!r}"),
        )
    k = 0
    for part in body.parts:
        g = part.geometry
        if g is None:
            continue
        if g.kind not in GEOMETRY_KINDS:
            raise ValueError(f"body {body.name!r}: geometry kind {g.kind!r} is not supported")
        # unique in the robot (MuJoCo's URDF import names its geoms after them)
        name = check_name(f"{body.name}/{k}/{g.name or part.name}", "geometry")
        k += 1
        origin = _check_transform(g.origin, f"geometry {name!r}")
        rgba = np.array([float(c) for c in g.rgba])
        material = y.Material(name=material_name(rgba), color=y.Color(rgba=rgba), texture=None)
        link.visuals.append(
            y.Visual(
                name=name, origin=origin, geometry=_geometry(g, mesh_dir, y), material=material
            )
        )
        link.collisions.append(
            y.Collision(name=f"{name}/collision", origin=origin, geometry=_geometry(g, mesh_dir, y))
        )
    return link


def _joint(j: JointSpec, y) -> yourdfpy.Joint:
    limit = None
    if j.kind == "revolute":
        limit = y.Limit(
            effort=float(j.effort),
            velocity=float(j.velocity),
            lower=float(j.lower),
            upper=float(j.upper),
        )
    elif j.kind == "continuous" and not j.passive:  # a passive joint: no actuator, no limit
        limit = y.Limit(effort=float(j.effort), velocity=float(j.velocity), lower=None, upper=None)
    return y.Joint(
        name=j.name,
        type=j.kind,
        parent=j.parent,
        child=j.child,
        origin=np.asarray(j.origin, dtype=float),
        axis=None if j.kind == "fixed" else unit_axis(j.axis, j.name),
        limit=limit,
        dynamics=None if j.kind == "fixed" else y.Dynamics(damping=joint_damping(j), friction=0.0),
    )


def urdf_robot(assembly: Assembly, mesh_dir: str = "meshes", classes=None) -> yourdfpy.Robot:
    """yourdfpy's data model of ``assembly``: links in body order, joints in tree order.
    ``classes``: where the classes come from (default the ``yourdfpy`` module; ``_RECORDS``
    for plain records of the same fields)."""
    if classes is None:
        import yourdfpy as classes

    bodies = check_assembly(assembly)
    return classes.Robot(
        name=assembly.robot_type,
        links=[_link(b, mesh_dir, classes) for b in bodies.values()],
        joints=[_joint(j, classes) for j in assembly.joints],
    )


# --- deterministic serialisation -----------------------------------------------------------


def _origin(parent: ET.Element, T: np.ndarray | None) -> None:
    if T is None:
        return
    T = np.asarray(T, dtype=float)
    ET.SubElement(
        parent,
        "origin",
        xyz=numbers(T[:3, 3], SNAP),
        rpy=numbers(rpy_from_matrix(T[:3, :3]), SNAP),
    )


def _write_geometry(parent: ET.Element, g: yourdfpy.Geometry) -> None:
    el = ET.SubElement(parent, "geometry")
    if g.mesh is not None:
        ET.SubElement(el, "mesh", filename=g.mesh.filename, scale=numbers(g.mesh.scale))
    elif g.box is not None:
        ET.SubElement(el, "box", size=numbers(g.box.size))
    elif g.cylinder is not None:
        ET.SubElement(
            el, "cylinder", radius=number(g.cylinder.radius), length=number(g.cylinder.length)
        )
    else:
        ET.SubElement(el, "sphere", radius=number(g.sphere.radius))


def _write_link(parent: ET.Element, link: yourdfpy.Link) -> None:
    el = ET.SubElement(parent, "link", name=link.name)
    if link.inertial is not None:
        inertial = ET.SubElement(el, "inertial")
        _origin(inertial, link.inertial.origin)
        ET.SubElement(inertial, "mass", value=number(link.inertial.mass))
        m = link.inertial.inertia
        ET.SubElement(
            inertial,
            "inertia",
            ixx=number(m[0, 0]),
            ixy=number(m[0, 1]),
            ixz=number(m[0, 2]),
            iyy=number(m[1, 1]),
            iyz=number(m[1, 2]),
            izz=number(m[2, 2]),
        )
    for v in link.visuals:
        vis = ET.SubElement(el, "visual", name=v.name)
        _origin(vis, v.origin)
        _write_geometry(vis, v.geometry)
        mat = ET.SubElement(vis, "material", name=v.material.name)
        ET.SubElement(mat, "color", rgba=numbers(v.material.color.rgba))
    for c in link.collisions:
        col = ET.SubElement(el, "collision", name=c.name)
        _origin(col, c.origin)
        _write_geometry(col, c.geometry)


def _write_joint(parent: ET.Element, joint: yourdfpy.Joint) -> None:
    el = ET.SubElement(parent, "joint", name=joint.name, type=joint.type)
    _origin(el, joint.origin)
    ET.SubElement(el, "parent", link=joint.parent)
    ET.SubElement(el, "child", link=joint.child)
    if joint.axis is not None:
        ET.SubElement(el, "axis", xyz=numbers(joint.axis, SNAP))
    lim = joint.limit
    if lim is not None:
        attrs = {}
        if lim.lower is not None:
            attrs["lower"] = number(lim.lower)
            attrs["upper"] = number(lim.upper)
        attrs["effort"] = number(lim.effort)
        attrs["velocity"] = number(lim.velocity)
        ET.SubElement(el, "limit", attrs)
    if joint.dynamics is not None:
        dyn = joint.dynamics
        ET.SubElement(el, "dynamics", damping=number(dyn.damping), friction=number(dyn.friction))


#: MuJoCo's URDF extension (ignored by urdfdom, pinocchio, yourdfpy and RViz): mesh file
#: names are looked up by their base name in ``meshes/`` beside the URDF (so an absolute URI
#: of a moved folder still loads), and the root link is not fused into MuJoCo's world body
#: (its mass stays in the model's ``body_mass``).
MUJOCO_COMPILER = {"meshdir": "meshes", "strippath": "true", "fusestatic": "false"}

_MESH_FILENAME = re.compile(r'(<mesh filename=")([^"]*)(")')


def anchor_meshes(urdf: str, folder: Path) -> str:
    """``urdf`` with each relative mesh path (``meshes/NAME.stl``) made the absolute URI
    ``file://FOLDER/meshes/NAME.stl``: pinocchio resolves a relative path only against
    package directories given to it (or ``ROS_PACKAGE_PATH``), so the written bundle names
    its meshes where they are; URIs with a scheme (``package://``) are left as they are.
    The folder is written as is (no percent-encoding: pinocchio does not decode it)."""
    base = os.fspath(folder).rstrip("/")

    def one(m: re.Match) -> str:
        path = m.group(2)
        if "://" in path or path.startswith("/"):
            return m.group(0)
        return m.group(1) + escape(f"file://{base}/{path}", {'"': "&quot;"}) + m.group(3)

    return _MESH_FILENAME.sub(one, urdf)


_ANCHORED = re.compile(r'(<mesh filename=")file://[^"]*/(meshes/[^"/]+)(")')


def relative_meshes(urdf: str) -> str:
    """The inverse of :func:`anchor_meshes` wherever the bundle now is: each
    ``file://.../meshes/NAME`` URI becomes ``meshes/NAME`` (the folder the URI names may be
    gone, as MuJoCo's ``meshdir`` lookup assumes)."""
    return _ANCHORED.sub(r"\1\2\3", urdf)


def robot_xml(robot: yourdfpy.Robot) -> str:
    """URDF text of a yourdfpy ``Robot`` built by :func:`urdf_robot` (deterministic), with
    MuJoCo's compiler extension (``MUJOCO_COMPILER``) first."""
    root = ET.Element("robot", name=robot.name)
    ET.SubElement(ET.SubElement(root, "mujoco"), "compiler", MUJOCO_COMPILER)
    for link in robot.links:
        _write_link(root, link)
    for joint in robot.joints:
        _write_joint(root, joint)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, "unicode") + "\n"


def urdf_string(assembly: Assembly, mesh_dir: str = "meshes", with_payload: bool = False) -> str:
    """URDF text of ``assembly``: the robot is named after ``assembly.robot_type``; mesh
    files are referenced as ``mesh_dir/NAME.stl``. Identical input gives identical text.

    Raises ``ValueError`` on an invalid tree or name, or a mesh name that is not a plain
    file name. ``with_payload``: the payload (``Assembly.payload``) is added to the body
    that holds it (by default the URDF is the robot alone).
    """
    if with_payload:
        assembly = loaded(assembly)
    return robot_xml(urdf_robot(assembly, mesh_dir, _RECORDS))
