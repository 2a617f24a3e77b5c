"""kinematics.templates: agreement with the ontology, masses, geometry and input checking.

The ontology test reads every count from the knowledge base (the base configurations,
their parts and modules, and the class hierarchy), so it follows the ontology when it
changes; nothing about robot types is hard-coded there.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from math import pi

import numpy as np
import pytest

from kinematics import dynamics as dyn
from kinematics.spatial import tube_mass
from kinematics.templates import (
    DEFAULT_ACTUATOR_MASS,
    DEFAULTS,
    Template,
    TemplateParams,
    build,
    default_lengths,
)
from synth.reasoning.solver import Query
from tests.conftest import TEMPLATES

# --- agreement with the ontology ---------------------------------------------------------------


@pytest.fixture(scope="module")
def ancestors(kb) -> dict[str, set[str]]:
    """Every class with all its superclasses (itself included), from ``subclass`` facts."""
    parents: dict[str, set[str]] = defaultdict(set)
    for sub, sup, *_ in kb.translation.relation("subclass"):
        parents[str(sub)].add(str(sup))
    closure: dict[str, set[str]] = {}

    def up(c: str) -> set[str]:
        if c not in closure:
            closure[c] = {c}
            for p in parents.get(c, ()):
                closure[c] |= up(p)
        return closure[c]

    for c in list(parents):
        up(c)
    return defaultdict(set, closure)


@pytest.fixture(scope="module")
def base_configurations(designer) -> list[str]:
    return [c.robot_type for c in designer.reasoner.solve(Query()).candidates]


def count(pairs, ancestors, kind: str) -> int:
    """How many of the (class, count) ``pairs`` are of ``kind`` or a subclass of it."""
    return sum(n for c, n in pairs if kind in ancestors[c] or c == kind)


def test_every_base_configuration_has_a_template(base_configurations) -> None:
    assert base_configurations, "the ontology names no base configuration"
    missing = sorted(set(base_configurations) - set(TEMPLATES))
    assert not missing, f"base configurations without a kinematic template: {missing}"


def test_templates_agree_with_the_ontology(designer, ancestors, base_configurations) -> None:
    for robot_type in base_configurations:
        cand = designer.describe(robot_type)
        parts, modules, passive = cand.parts, cand.modules, cand.passive
        snake = count(parts, ancestors, "SnakeModule")
        params = TemplateParams(modules=snake) if snake else TemplateParams()
        t = build(robot_type, params)
        where = f"{robot_type}: "
        actuators = count(modules, ancestors, "ActuatorModule")
        # a passive joint (a free wheel's) turns on a bearing hub, not an actuator
        assert t.model.nv - len(t.passive) == actuators, where + "movable joints != actuators"
        assert len(t.passive) == count(passive, ancestors, "BearingModule"), where + "hubs"
        assert t.legs == count(parts, ancestors, "RobotLeg"), where + "legs"
        assert len(t.feet) == len(t.foot_points) == count(passive, ancestors, "FootModule")
        rolling = count(parts, ancestors, "Wheel") - count(parts, ancestors, "CasterWheel")
        assert len(t.wheels) == rolling, where + "wheels"
        assert len(t.casters) == count(parts, ancestors, "CasterWheel"), where + "casters"
        grippers = count(parts, ancestors, "RoboticGripper")
        assert len(t.end_effectors) == grippers, where + "grippers"
        # a manipulator is itself one arm: the ontology names its gripper but no arm part
        assert t.arms == (count(parts, ancestors, "RobotArm") or grippers), where + "arms"
        gripper_joints = t.groups.get("gripper", ())
        assert len(gripper_joints) == count(modules, ancestors, "EndEffectorActuator")
        wheel_joints = [
            j for j in t.model.joints if j.kind == "continuous" and j.name not in t.passive
        ]
        assert len(wheel_joints) == count(modules, ancestors, "ContinuousRotationServomotor")
        tubes = count(passive, ancestors, "LinkModule")
        tubes += count(passive, ancestors, "SnakeBracketModule")
        assert len(t.segments) >= tubes, where + "printed tubes"
        if snake:
            assert len(t.segments) == count(passive, ancestors, "SnakeBracketModule")
        limbs = t.legs + t.arms
        if limbs and count(parts, ancestors, "RobotLimb"):
            # every limb part of the ontology carries its own link modules here
            assert tubes == len(t.segments), where + "link modules of the limbs"


# --- masses and segments ---------------------------------------------------------------------

PARAMS = TemplateParams(
    lengths={},
    density=1100.0,
    payload=0.21,
    trunk_mass=0.37,
    foot_mass=0.013,
    gripper_mass=0.029,
    wheel_mass=0.041,
    caster_mass=0.017,
    modules=5,
)


def expected_mass(t: Template, p: TemplateParams) -> float:
    actuators = sum(
        p.actuator_mass.get(j.group, DEFAULT_ACTUATOR_MASS)
        for j in t.model.joints
        if j.movable and j.name not in t.passive
    )
    actuators += len(t.passive) * p.bearing_mass  # a free wheel's hub
    tubes = sum(tube_mass(p.density, s.length, s.r_outer, s.r_inner) for s in t.segments)
    ends = (
        len(t.feet) * p.foot_mass
        + len(t.end_effectors) * p.gripper_mass
        + len(t.wheels) * p.wheel_mass
        + len(t.casters) * p.caster_mass
    )
    return actuators + tubes + ends + p.payload + p.trunk_mass


@pytest.mark.parametrize("robot_type", TEMPLATES)
def test_total_mass_is_the_sum_of_the_parts(robot_type: str) -> None:
    groups = sorted(build(robot_type).groups)
    masses = {g: 0.02 + 0.01 * i for i, g in enumerate(groups)}
    lengths = {k: 1.3 * x for k, x in DEFAULTS[robot_type].items()}
    tube_names = sorted({s.length_name for s in build(robot_type).segments})
    tubes = {k: (0.015, 0.011) for k in tube_names[:1]}
    p = dataclasses.replace(PARAMS, actuator_mass=masses, lengths=lengths, tubes=tubes)
    t = build(robot_type, p)
    assert t.model.total_mass == pytest.approx(expected_mass(t, p), rel=1e-12)
    assert t.model.total_mass != pytest.approx(build(robot_type, PARAMS).model.total_mass)
    for s in t.segments:
        if s.length_name in tubes:
            assert (s.r_outer, s.r_inner) == tubes[s.length_name]


@pytest.mark.parametrize("robot_type", TEMPLATES)
def test_segments_are_tubes_that_end_at_their_distal_joint(robot_type: str) -> None:
    t = build(robot_type, PARAMS)
    m = t.model
    assert len({s.name for s in t.segments}) == len(t.segments)
    assert set(t.length_names) == set(DEFAULTS[robot_type])
    for s in t.segments:
        assert s.length > 0 and 0 <= s.r_inner < s.r_outer
        assert s.length == t.lengths[s.length_name]
        assert np.linalg.norm(s.direction) == pytest.approx(1.0)
        body = m.body(s.body)
        if s.distal_joint is not None:
            j = m.joints[m.joint(s.distal_joint)]
            assert j.parent == body, f"{s.name} ends at a joint of another body"
            np.testing.assert_allclose(j.origin[:3, 3], s.end, atol=1e-15)


@pytest.mark.parametrize("robot_type", TEMPLATES)
def test_joints_limits_groups_and_zero_pose(robot_type: str) -> None:
    t = build(robot_type)
    m = t.model
    assert m.joints[0].kind == "fixed" and m.joints[0].parent == -1
    for j in m.joints:
        assert j.lower <= 0.0 <= j.upper, f"{j.name}: zero pose outside the limits"
        assert j.effort == 0.0 and j.velocity == 0.0
        if j.name != "root" and robot_type != "SnakeRobot":
            assert m.bodies[j.child].name == f"{j.name}_link"
        if j.movable and j.name not in t.passive:  # a passive joint has no actuator
            assert j.group, f"{j.name} has no group"
    # joints of one group on alike limbs (none above another, unlike a snake's chain) are
    # alike: the same gravity torque in the zero pose
    tau = dyn.gravity_torques(m, np.zeros(m.nv))
    for group, names in t.groups.items():
        idx = [m.joint(n) for n in names]
        if any(i in m.ancestors(k) for i in idx for k in idx if i != k):
            continue
        values = [tau[m.q_index[i]] for i in idx]
        np.testing.assert_allclose(values, values[0], atol=1e-12, err_msg=group)


def world_point(t: Template, body: str, point=(0.0, 0.0, 0.0), q=None) -> np.ndarray:
    m = t.model
    T = dyn.forward_kinematics(m, np.zeros(m.nv) if q is None else q)[m.body(body)]
    return T[:3, :3] @ np.asarray(point, dtype=float) + T[:3, 3]


def test_manipulator_geometry_follows_the_lengths() -> None:
    L = {"L1": 0.11, "L2": 0.23, "L3": 0.17}
    t = build("Manipulator3DOF", TemplateParams(lengths=L))
    np.testing.assert_allclose(world_point(t, "gripper_link"), [0.40, 0, 0.11], atol=1e-15)
    q = np.array([pi / 2, -pi / 2, 0.0, 0.0])  # yaw to +y, arm straight up
    np.testing.assert_allclose(world_point(t, "gripper_link", q=q), [0, 0, 0.51], atol=1e-15)
    t6 = build("Manipulator6DOF", TemplateParams(lengths={**L, "L4": 0.05}))
    np.testing.assert_allclose(world_point(t6, "gripper_link"), [0.45, 0, 0.11], atol=1e-15)
    # the payload at the gripper loads the shoulder by its weight times the reach
    p1 = TemplateParams(lengths=L, payload=0.5)
    t1 = build("Manipulator3DOF", p1)
    dtau = dyn.gravity_torques(t1.model, np.zeros(4)) - dyn.gravity_torques(t.model, np.zeros(4))
    np.testing.assert_allclose(dtau, [0, -0.5 * 9.81 * 0.40, -0.5 * 9.81 * 0.17, 0], atol=1e-12)


@pytest.mark.parametrize("robot_type", ["HexapodRobot", "QuadrupedRobot"])
def test_multiped_geometry_follows_the_lengths(robot_type: str) -> None:
    L = {"La1": 0.3, "La2": 0.2, "coxa": 0.05, "femur": 0.07, "tibia": 0.11}
    t = build(robot_type, TemplateParams(lengths=L))
    assert len(t.feet) == t.legs == {"HexapodRobot": 6, "QuadrupedRobot": 4}[robot_type]
    feet = {f: world_point(t, f, p) for f, p in zip(t.feet, t.foot_points, strict=True)}
    reach = 0.1 + 0.05 + 0.07  # half the width, coxa and femur
    np.testing.assert_allclose(feet["lf_tibia_link"], [0.15, reach, -0.11], atol=1e-15)
    np.testing.assert_allclose(feet["rh_tibia_link"], [-0.15, -reach, -0.11], atol=1e-15)
    assert all(f[2] == pytest.approx(-0.11) for f in feet.values())


def test_humanoid_geometry_follows_the_lengths() -> None:
    L = {
        "trunk_height": 0.2,
        "hip_width": 0.1,
        "shoulder_width": 0.18,
        "femur": 0.12,
        "tibia": 0.1,
        "foot": 0.09,
        "upper_arm": 0.08,
        "forearm": 0.06,
    }
    p = TemplateParams(lengths=L)
    t = build("HumanoidRobot", p)
    sole = p.actuator_size[2] / 2
    left = world_point(t, t.feet[0], t.foot_points[0])
    np.testing.assert_allclose(left, [0, 0.05, -0.22 - sole], atol=1e-15)
    np.testing.assert_allclose(world_point(t, "r_gripper_link"), [0, -0.09, 0.06], atol=1e-15)
    knee = np.zeros(t.model.nv)
    knee[t.model.q_index[t.model.joint("l_knee_pitch")]] = pi / 2  # shank turned backwards
    np.testing.assert_allclose(
        world_point(t, "l_ankle_pitch_link", q=knee), [-0.1, 0.05, -0.12], atol=1e-15
    )


def test_snake_and_wheeled_geometry() -> None:
    t = build("SnakeRobot", TemplateParams(modules=6, lengths={"module": 0.07}))
    assert t.model.nv == 6 and len(t.segments) == 6
    axes = [tuple(t.model.joints[i].axis) for i in t.model.q_joints]
    assert axes == [(0, 1, 0), (0, 0, 1)] * 3  # vertical and horizontal modules alternate
    np.testing.assert_allclose(world_point(t, "module_6", t.segments[-1].end), [0.42, 0, 0])
    d = build("DifferentialDriveRobot", TemplateParams(lengths={"L1": 0.2, "L2": 0.15}))
    left, right = (world_point(d, w) for w in d.wheels)
    assert left[1] - right[1] == pytest.approx(0.15)
    assert left[0] == right[0] == 0  # the root frame is the axle centre
    np.testing.assert_allclose(world_point(d, d.casters[0]), [-0.15, 0, -0.03])
    s = build("SkidSteerRobot", TemplateParams(lengths={"L1": 0.2, "L2": 0.15}))
    centres = np.array([world_point(s, w) for w in s.wheels])
    np.testing.assert_allclose(np.ptp(centres, axis=0), [0.2, 0.15, 0.0])
    assert all(
        s.model.joints[s.model.joint(w[: -len("_link")])].kind == "continuous" for w in s.wheels
    )


# --- bad input --------------------------------------------------------------------------------


def test_bad_input_lists_the_valid_names() -> None:
    with pytest.raises(ValueError, match="unknown robot type 'Hexapod': no body plan"):
        build("Hexapod")
    with pytest.raises(ValueError, match="has no length L9; lengths: L1, L2, L3"):
        build("Manipulator3DOF", TemplateParams(lengths={"L9": 0.1}))
    with pytest.raises(ValueError, match="length femur must be a positive number"):
        build("HexapodRobot", TemplateParams(lengths={"femur": 0.0}))
    with pytest.raises(ValueError, match="length L1 must be a positive number"):
        build("SkidSteerRobot", TemplateParams(lengths={"L1": float("nan")}))
    with pytest.raises(ValueError, match="r_inner < r_outer"):
        build("HexapodRobot", TemplateParams(tubes={"femur": (0.01, 0.01)}))
    with pytest.raises(ValueError, match="has no tube La1; tubes: coxa, femur, tibia"):
        build("HexapodRobot", TemplateParams(tubes={"La1": (0.02, 0.01)}))
    with pytest.raises(ValueError, match="has no joint group knee; groups: leg_coxa"):
        build("HexapodRobot", TemplateParams(actuator_mass={"knee": 0.1}))
    with pytest.raises(ValueError, match="modules must be an integer >= 1"):
        build("SnakeRobot", TemplateParams(modules=0))
    with pytest.raises(ValueError, match="payload must be"):
        build("Manipulator3DOF", TemplateParams(payload=-1.0))
    with pytest.raises(ValueError, match="unknown robot type"):
        default_lengths("Robot")


def test_default_lengths_are_a_copy() -> None:
    d = default_lengths("HumanoidRobot")
    assert d == dict(DEFAULTS["HumanoidRobot"]) and "femur" in d
    d["femur"] = 1.0
    assert default_lengths("HumanoidRobot")["femur"] != 1.0
    assert build("HumanoidRobot").lengths == DEFAULTS["HumanoidRobot"]


def test_build_returns_the_same_template_for_the_same_params_unless_they_changed():
    """Built again with equal params: the same (immutable) template; params that differ
    in one float's sign, or a params dict changed in place since, build a new one."""
    from kinematics.templates import TemplateParams, build

    lengths = {"L1": 0.05, "L2": 0.1, "L3": 0.1}
    a = build("Manipulator3DOF", TemplateParams(lengths=dict(lengths)))
    assert build("Manipulator3DOF", TemplateParams(lengths=dict(lengths))) is a
    p = TemplateParams(lengths=dict(lengths), payload=0.0)
    assert build("Manipulator3DOF", p) is a
    q = TemplateParams(lengths=dict(lengths), payload=-0.0)
    assert build("Manipulator3DOF", q) is not a  # -0.0 is told apart
    mutable = dict(lengths)
    b = build("Manipulator3DOF", TemplateParams(lengths=mutable, payload=0.25))
    mutable["L2"] = 0.2  # changed in place after the build
    c = build("Manipulator3DOF", TemplateParams(lengths=dict(mutable), payload=0.25))
    assert c is not b and c.lengths["L2"] == 0.2
    d = build("Manipulator3DOF", TemplateParams(lengths={**lengths, "L2": 0.1}, payload=0.25))
    assert d is not b and d.lengths["L2"] == 0.1
