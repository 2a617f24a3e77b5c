"""MJCF exporter: the hand-built assemblies of test_urdf.py and, when export/assembly.py
works, the default design of every base configuration. The model must compile in MuJoCo
with its meshes, carry exactly the assembly's mass and inertia, one servo per movable joint
limited to the stall torque, collide with the floor but never with itself, and simulate:
a fixed-base arm holds its pose, free robots dropped on the floor settle."""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from export.mjcf import SERVO_BAND, load_mjcf, mjcf_string, principal_inertia, quat_from_matrix
from export.model3d import Assembly
from export.urdf import PASSIVE_DAMPING
from tests.export.test_urdf import (
    HAND_BUILT,
    REPO,
    arm,
    frames,
    legged,
    mesh_files,
    real_assemblies,
    tf,
    wheeled,
)

mujoco = pytest.importorskip("mujoco")


@pytest.fixture(scope="session")
def real(kb, designer) -> dict[str, Assembly]:
    return real_assemblies(kb, designer)


def load(assembly: Assembly):
    return load_mjcf(mjcf_string(assembly), mesh_files(assembly))


def rotation(quat) -> np.ndarray:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, dtype=float))
    return R.reshape(3, 3)


def movable(assembly: Assembly):
    """The joints a servo drives (a free wheel's passive joint has none)."""
    return [j for j in assembly.joints if j.kind != "fixed" and not j.passive]


def check_model(assembly: Assembly, model) -> None:
    """Mass, inertia, frames, joints and actuators of ``model`` match ``assembly``."""
    total = float(model.body_mass.sum())
    assert abs(total - assembly.total_mass) <= 1e-9 * assembly.total_mass
    assert model.nbody == len(assembly.bodies) + 1  # the world carries only the floor
    for b in assembly.bodies:
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b.name)
        assert i > 0, b.name
        assert abs(model.body_mass[i] - b.mass) <= 1e-9 * max(b.mass, 1e-3)
        if b.mass == 0:
            continue
        assert np.allclose(model.body_ipos[i], b.com, atol=1e-11)
        R = rotation(model.body_iquat[i])
        tensor = R @ np.diag(model.body_inertia[i]) @ R.T
        floor = max(1e-12, 1e-9 * float(np.max(np.linalg.eigvalsh(b.inertia))))
        assert np.allclose(tensor, b.inertia, rtol=1e-8, atol=2 * floor), b.name
    # frames at the initial configuration: the chain of origins, lifted to spawn height
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    lift = tf((0, 0, assembly.spawn_height))
    for name, T in frames(assembly).items():
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        assert np.allclose(data.xpos[i], (lift @ T)[:3, 3], atol=1e-9), name
        assert np.allclose(data.xmat[i].reshape(3, 3), T[:3, :3], atol=1e-9), name
    # the free joint, if any, is on the root
    free = [k for k in range(model.njnt) if model.jnt_type[k] == mujoco.mjtJoint.mjJNT_FREE]
    assert len(free) == (0 if assembly.fixed_base else 1)
    # one hinge and one servo per movable joint, forcerange = +-stall torque
    moving = movable(assembly)
    assert model.nu == len(moving)
    hinges = model.njnt - len(free)
    passive = [j for j in assembly.joints if j.passive]
    assert hinges == len(moving) + len(passive)
    for j in passive:  # a hinge with its bearing's damping, no actuator
        k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name)
        assert model.jnt_type[k] == mujoco.mjtJoint.mjJNT_HINGE
        assert model.dof_damping[model.jnt_dofadr[k]] == PASSIVE_DAMPING
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, j.name) == -1
    for j in moving:
        k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name)
        a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, j.name)
        assert model.actuator_trnid[a, 0] == k
        assert model.jnt_type[k] == mujoco.mjtJoint.mjJNT_HINGE
        assert np.allclose(model.jnt_axis[k], j.axis / np.linalg.norm(j.axis), atol=1e-12)
        assert model.actuator_forcelimited[a]
        assert np.allclose(model.actuator_forcerange[a], [-j.effort, j.effort], rtol=1e-9)
        if j.kind == "revolute":
            assert model.jnt_limited[k]
            assert np.allclose(model.jnt_range[k], [j.lower, j.upper], rtol=1e-9)
            assert np.allclose(model.actuator_ctrlrange[a], [j.lower, j.upper], rtol=1e-9)
            assert math.isclose(model.actuator_gainprm[a, 0], j.effort / SERVO_BAND, rel_tol=1e-9)
            assert math.isclose(model.actuator_biasprm[a, 1], -j.effort / SERVO_BAND, rel_tol=1e-9)
            assert model.actuator_biasprm[a, 2] <= 0  # the servo's derivative gain -kv
            # back-EMF damping: saturated at stall torque the joint tends to no-load speed
            dof = model.jnt_dofadr[k]
            assert math.isclose(model.dof_damping[dof], j.effort / j.velocity, rel_tol=1e-9)
        else:  # a velocity servo on a continuous joint: the DC motor line
            assert not model.jnt_limited[k]
            assert math.isclose(model.actuator_gainprm[a, 0], j.effort / j.velocity, rel_tol=1e-9)
            assert np.allclose(model.actuator_ctrlrange[a], [-j.velocity, j.velocity])


def check_contacts(model, data) -> None:
    """Every active contact is between the floor and a robot geom."""
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    for c in data.contact[: data.ncon]:
        assert floor in (c.geom1, c.geom2), (c.geom1, c.geom2)


def settle(assembly: Assembly, seconds: float = 1.5):
    """Drop ``assembly`` at its spawn height with every servo holding 0; the final data."""
    model = load(assembly)
    data = mujoco.MjData(model)
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
        assert np.all(np.isfinite(data.qpos))
    return model, data


def check_settled(assembly: Assembly, model, data) -> None:
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert data.qpos[2] > 0.0  # the root stays above the floor
    assert abs(data.qpos[2] - assembly.spawn_height) < 0.5 * max(assembly.spawn_height, 0.02)
    assert np.linalg.norm(data.qvel[:3]) < 0.05  # at rest
    up = rotation(data.qpos[3:7])[:, 2]
    assert up[2] > 0.9  # not tipped over
    assert data.ncon > 0
    check_contacts(model, data)


# --- hand-built ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(HAND_BUILT))
def test_hand_built_compiles_and_matches(name: str) -> None:
    assembly = HAND_BUILT[name]()
    check_model(assembly, load(assembly))


def test_text_shape() -> None:
    text = mjcf_string(arm())
    root = ET.fromstring(text)
    assert root.get("model") == "Manipulator3DOF"
    assert root.find("compiler").attrib == {
        "angle": "radian", "meshdir": "meshes", "autolimits": "true", "inertiafromgeom": "false",
    }  # fmt: skip
    assert root.find("option").attrib == {"timestep": "0.002", "integrator": "implicitfast"}
    assert {m.get("file") for m in root.iter("mesh")} == {
        "base_plate.stl", "link_l1.stl", "link_l2.stl", "link_l3.stl",
    }  # fmt: skip
    world = root.find("worldbody")
    assert world.find("geom").get("type") == "plane" and world.find("light") is not None
    base = world.find("body")
    assert base.get("name") == "base" and base.get("pos") == "0 0 0.02"
    assert base.find("freejoint") is None  # the arm is bolted down
    assert [a.tag for a in root.find("actuator")] == ["position"] * 4
    free = ET.fromstring(mjcf_string(legged())).find("worldbody/body")
    assert free.find("freejoint") is not None and free.get("pos") == "0 0 0.07"
    assert "-0 " not in text


def test_mesh_dir_argument() -> None:
    a = arm()
    text = mjcf_string(a, mesh_dir="parts")
    assert ET.fromstring(text).find("compiler").get("meshdir") == "parts"
    model = load_mjcf(text, {p.name: p.stl for p in a.printed})  # keys without ".stl"
    assert model.nmesh == 4


def test_contact_scheme_floor_only() -> None:
    for make in HAND_BUILT.values():
        model = load(make())
        floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        for g in range(model.ngeom):
            if g == floor:
                continue
            t, a = model.geom_contype[g], model.geom_conaffinity[g]
            assert (t & a) == 0  # no robot-robot pair can collide
            assert (t & model.geom_conaffinity[floor]) or (model.geom_contype[floor] & a)
            assert model.geom_priority[g] > model.geom_priority[floor]


def test_friction_per_kind() -> None:
    def friction(model, body: str) -> set[tuple[float, int]]:
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        return {
            (float(model.geom_friction[g, 0]), int(model.geom_condim[g]))
            for g in range(model.ngeom)
            if model.geom_bodyid[g] == b
        }

    quad = load(legged())
    assert friction(quad, "lf_tibia") == {(1.0, 4)}
    assert friction(quad, "trunk") == {(0.5, 3)}
    diff = load(wheeled())
    assert friction(diff, "left_wheel") == {(1.0, 3)}
    assert friction(diff, "caster") == {(0.05, 3)}


def test_fixed_base_arm_holds_its_pose() -> None:
    a = arm()
    model = load(a)
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.0
    for _ in range(int(0.5 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    # gravity pulls each joint off its target by torque / kp < SERVO_BAND rad
    assert np.max(np.abs(data.qpos)) < 0.05, data.qpos
    assert np.max(np.abs(data.qvel)) < 0.05, data.qvel
    # and it tracks a new target
    data.ctrl[:] = [0.5, -0.3, 0.4, 0.2]
    for _ in range(int(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert np.max(np.abs(data.qpos - data.ctrl)) < 0.05, data.qpos


@pytest.mark.parametrize("make", [legged, wheeled], ids=["legged", "wheeled"])
def test_free_robot_settles_on_the_floor(make) -> None:
    a = make()
    model, data = settle(a)
    check_settled(a, model, data)


def test_wheeled_robot_drives_forward() -> None:
    a = wheeled()
    model, data = settle(a, 0.5)
    x0 = float(data.qpos[0])
    data.ctrl[:] = [8.0, 8.0]  # rad/s, both wheels forward (+y axes)
    for _ in range(int(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert data.qpos[0] - x0 > 0.1  # close to 8 rad/s x 0.03 m = 0.24 m/s
    assert abs(data.qpos[1]) < 0.02


def test_deterministic() -> None:
    for make in HAND_BUILT.values():
        assert mjcf_string(make()) == mjcf_string(make())


def test_names_are_escaped() -> None:
    a = arm()
    weird = 'base <&> "q"'
    bodies = tuple(
        dataclasses.replace(b, name=weird if b.name == "base" else b.name) for b in a.bodies
    )
    joints = tuple(
        dataclasses.replace(
            j, name=f"{j.name}&<'>", parent=weird if j.parent == "base" else j.parent
        )
        for j in a.joints
    )
    a = dataclasses.replace(a, robot_type='R&D <"bot">', root=weird, bodies=bodies, joints=joints)
    text = mjcf_string(a)
    assert "&amp;" in text and "&lt;" in text
    assert ET.fromstring(text).get("model") == 'R&D <"bot">'
    model = load(a)
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, weird) == 1
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "base_yaw&<'>") == 0
    check_model(a, model)


@pytest.mark.parametrize("mesh", ["../evil", "sub/part", "..", "a\\b", "/abs.stl", ""])
def test_bad_mesh_names_are_refused(mesh: str) -> None:
    a = arm()
    base = a.bodies[0]
    part = base.parts[0]
    bad = dataclasses.replace(part, geometry=dataclasses.replace(part.geometry, mesh=mesh))
    a = dataclasses.replace(
        a, bodies=(dataclasses.replace(base, parts=(bad, *base.parts[1:])), *a.bodies[1:])
    )
    with pytest.raises(ValueError, match="mesh"):
        mjcf_string(a)
    with pytest.raises(ValueError, match="mesh"):
        load_mjcf(mjcf_string(arm()), {mesh: b""})


def test_deterministic_across_processes() -> None:
    code = (
        "import sys; from tests.export.test_urdf import legged; "
        "from export.mjcf import mjcf_string; "
        "sys.stdout.write(mjcf_string(legged()))"
    )
    env = {**os.environ, "PYTHONHASHSEED": "4321", "PYTHONPATH": str(REPO)}
    argv = [sys.executable, "-c", code]
    r = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=REPO, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout == mjcf_string(legged())


def test_world_is_a_reserved_body_name() -> None:
    a = legged()
    bodies = tuple(
        dataclasses.replace(b, name="world") if b.name == "trunk" else b for b in a.bodies
    )
    joints = tuple(
        dataclasses.replace(j, parent="world") if j.parent == "trunk" else j for j in a.joints
    )
    with pytest.raises(ValueError, match="world"):
        mjcf_string(dataclasses.replace(a, root="world", bodies=bodies, joints=joints))


def test_movable_joint_needs_effort() -> None:
    a = arm()
    joints = (dataclasses.replace(a.joints[0], effort=0.0), *a.joints[1:])
    with pytest.raises(ValueError, match="effort"):
        mjcf_string(dataclasses.replace(a, joints=joints))


def test_massless_welded_body_compiles() -> None:
    from export.model3d import BodySpec, JointSpec

    a = arm()
    frame = BodySpec("tool_frame", (), 0.0, np.zeros(3), np.zeros((3, 3)))
    j = JointSpec("tool", "gripper", "tool_frame", "fixed", tf((0.05, 0, 0)), np.array([0, 0, 1]))
    a = dataclasses.replace(a, bodies=(*a.bodies, frame), joints=(*a.joints, j))
    check_model(a, load(a))


@pytest.mark.parametrize(
    "inertia",
    [
        np.diag([3e-5, 1e-5, 2e-5]),
        np.zeros((3, 3)),  # a point mass
        np.diag([0.0, 1e-4, 1e-4]),  # an ideal thin rod along x
        tf(rpy=(0.3, -0.7, 1.1))[:3, :3]
        @ np.diag([1e-5, 2e-5, 2.5e-5])
        @ tf(rpy=(0.3, -0.7, 1.1))[:3, :3].T,
        tf(rpy=(0.0, 0.0, 0.4))[:3, :3]
        @ np.diag([1e-5, 1e-5, 1.5e-5])
        @ tf(rpy=(0.0, 0.0, 0.4))[:3, :3].T,
    ],
)
def test_principal_inertia(inertia: np.ndarray) -> None:
    moments, axes = principal_inertia(inertia, "test")
    assert np.allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    assert math.isclose(np.linalg.det(axes), 1.0, rel_tol=1e-12)
    floor = max(1e-12, 1e-9 * float(np.max(np.linalg.eigvalsh(inertia))))
    assert np.all(moments >= floor)
    assert np.allclose(axes @ np.diag(moments) @ axes.T, inertia, atol=2 * floor)
    a, b, c = moments
    assert a + b >= c and b + c >= a and a + c >= b  # MuJoCo's triangle inequality
    if not np.any(inertia - np.diag(np.diag(inertia))):
        assert np.array_equal(axes, np.eye(3))  # a diagonal tensor keeps the body axes
    again = principal_inertia(inertia.copy(), "test")
    assert np.array_equal(again[0], moments) and np.array_equal(again[1], axes)


@pytest.mark.parametrize("rpy", [(0, 0, 0), (math.pi, 0, 0), (0, math.pi, 0), (0.3, -1.2, 2.9)])
def test_quat_from_matrix(rpy) -> None:
    R = tf(rpy=rpy)[:3, :3]
    q = quat_from_matrix(R)
    assert q[np.flatnonzero(q)[0]] > 0
    assert np.allclose(rotation(q), R, atol=1e-12)


# --- the real assemblies of every base configuration -----------------------------------------


def test_real_assemblies_compile_and_match(real: dict[str, Assembly]) -> None:
    assert len(real) >= 8
    for assembly in real.values():
        check_model(assembly, load(assembly))
        assert mjcf_string(assembly) == mjcf_string(assembly)


def test_real_assemblies_simulate(real: dict[str, Assembly]) -> None:
    """Arms hold their home pose; mobile robots dropped at their spawn height settle upright."""
    for robot_type, assembly in real.items():
        if assembly.fixed_base:
            model = load(assembly)
            data = mujoco.MjData(model)
            for _ in range(int(0.5 / model.opt.timestep)):
                mujoco.mj_step(model, data)
            assert np.all(np.isfinite(data.qpos)), robot_type
            assert np.max(np.abs(data.qpos)) < SERVO_BAND, (robot_type, data.qpos)
        else:
            model, data = settle(assembly)
            check_settled(assembly, model, data)
            assert np.max(np.abs(data.qpos[7:])) < SERVO_BAND, (robot_type, data.qpos[7:])
