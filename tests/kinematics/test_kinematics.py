"""kinematics.model and kinematics.dynamics: agreement with pinocchio, physics identities,
and input checking."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kinematics import dynamics as dyn
from kinematics.model import Body, Joint, Model
from kinematics.spatial import (
    box_inertia,
    combine_parts,
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    rot_x,
    rot_y,
    rot_z,
    transform,
    transform_from,
    transform_from_pq,
    tube_inertia,
)
from kinematics.templates import build
from tests.conftest import TEMPLATES

try:
    from tests import pin_ref
except ImportError:  # pinocchio missing: only the comparisons skip
    pin_ref = None
needs_pinocchio = pytest.mark.skipif(pin_ref is None, reason="pinocchio is not installed")

TOL = 1e-9
B = 3  # configurations per comparison


def random_model(seed: int, n: int = 9, gravity=(0.0, 0.0, -9.81)) -> Model:
    """A random tree (not in depth-first order) with all joint kinds and skewed axes."""
    rng = np.random.default_rng(seed)
    bodies, joints = [], []
    for i in range(n):
        m = rng.uniform(0.05, 2.0)
        size = rng.uniform(0.02, 0.3, 3)
        R = matrix_from_axis_angle(rng.standard_normal(3), rng.uniform(0, np.pi))
        bodies.append(Body(f"b{i}", m, rng.normal(0, 0.1, 3), R @ box_inertia(m, size) @ R.T))
        parent = -1 if i == 0 else int(rng.integers(-1 if i < 3 else 0, i))
        kind = ("revolute", "continuous", "fixed")[i % 3]
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        origin = transform(rng.normal(0, 0.2, 3), rng.uniform(-np.pi, np.pi, 3))
        joints.append(Joint(f"j{i}", parent, i, kind, origin, axis))
    return Model(tuple(bodies), tuple(joints), gravity=np.array(gravity))


MODELS = {name: build(name).model for name in TEMPLATES}
MODELS["random_a"] = random_model(1)
MODELS["random_b"] = random_model(2, n=12, gravity=(0.3, -1.0, -9.0))
_REFS: dict[str, object] = {}


def ref(name: str):
    if name not in _REFS:
        _REFS[name] = pin_ref.PinRef(MODELS[name])
    return _REFS[name]


def states(model: Model, seed: int = 0, batch: int = B):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (batch, model.nv))
    v = rng.normal(0, 2.0, (batch, model.nv))
    a = rng.normal(0, 5.0, (batch, model.nv))
    f = rng.normal(0, 3.0, (batch, model.nbodies, 6))
    return q, v, a, f


# --- against pinocchio -----------------------------------------------------------------------


@needs_pinocchio
@pytest.mark.parametrize("name", list(MODELS))
def test_rnea_and_wrenches_match_pinocchio(name: str) -> None:
    model, r = MODELS[name], ref(name)
    q, v, a, f = states(model, 1)
    tau = dyn.rnea(model, q, v, a)
    tau_f = dyn.rnea(model, q, v, a, f)
    wrench = dyn.joint_wrenches(model, q, v, a, f)
    for b in range(B):
        np.testing.assert_allclose(tau[b], r.rnea(q[b], v[b], a[b]), rtol=0, atol=TOL)
        np.testing.assert_allclose(tau_f[b], r.rnea(q[b], v[b], a[b], f[b]), rtol=0, atol=TOL)
        np.testing.assert_allclose(wrench[b], r.wrenches(), rtol=0, atol=TOL)


@needs_pinocchio
@pytest.mark.parametrize("name", list(MODELS))
def test_kinematics_and_mass_matrix_match_pinocchio(name: str) -> None:
    model, r = MODELS[name], ref(name)
    q = states(model, 2)[0]
    T = dyn.forward_kinematics(model, q)
    M = dyn.mass_matrix(model, q)
    com = dyn.center_of_mass(model, q)
    for b in range(B):
        np.testing.assert_allclose(T[b], r.placements(q[b]), rtol=0, atol=TOL)
        np.testing.assert_allclose(M[b], r.crba(q[b]), rtol=0, atol=TOL)
        np.testing.assert_allclose(com[b], r.com(q[b]), rtol=0, atol=TOL)


@needs_pinocchio
@pytest.mark.parametrize("name", list(MODELS))
def test_jacobian_matches_pinocchio(name: str) -> None:
    model, r = MODELS[name], ref(name)
    q = states(model, 3, batch=1)[0][0]
    point = np.array([0.03, -0.02, 0.05])
    for body in range(model.nbodies):
        np.testing.assert_allclose(
            dyn.jacobian(model, q, body, point), r.jacobian(q, body, point), rtol=0, atol=TOL
        )
    np.testing.assert_allclose(
        dyn.jacobian(model, q, model.nbodies - 1),
        r.jacobian(q, model.nbodies - 1, np.zeros(3)),
        rtol=0,
        atol=TOL,
    )


# --- physics identities ------------------------------------------------------------------------

IDENTITY_MODELS = ["random_a", "random_b", "HumanoidRobot", "Manipulator6DOF"]


@pytest.mark.parametrize("name", IDENTITY_MODELS)
def test_rnea_is_mass_matrix_times_a_plus_nonlinear_effects(name: str) -> None:
    model = MODELS[name]
    q, v, a, _ = states(model, 4)
    lhs = dyn.rnea(model, q, v, a)
    rhs = np.einsum("bij,bj->bi", dyn.mass_matrix(model, q), a) + dyn.nonlinear_effects(model, q, v)
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-9)
    M = dyn.mass_matrix(model, q)
    np.testing.assert_array_equal(M, M.transpose(0, 2, 1))
    assert np.all(np.linalg.eigvalsh(M) > 0)


@pytest.mark.parametrize("name", IDENTITY_MODELS)
def test_gravity_torques_are_the_gradient_of_potential_energy(name: str) -> None:
    model = MODELS[name]
    q = states(model, 5, batch=1)[0][0]

    def potential(x: np.ndarray) -> np.ndarray:  # (..., nv) -> (...) J
        return -model.total_mass * dyn.center_of_mass(model, x) @ model.gravity

    h = 1e-6
    steps = np.eye(model.nv) * h
    grad = (potential(q + steps) - potential(q - steps)) / (2 * h)
    np.testing.assert_allclose(dyn.gravity_torques(model, q), grad, rtol=0, atol=1e-7)


@pytest.mark.parametrize("name", IDENTITY_MODELS)
def test_power_balance_without_gravity(name: str) -> None:
    """v . C(q, v) v = 1/2 v . dM/dt v (the skew symmetry of dM/dt - 2C)."""
    model = dataclasses.replace(MODELS[name], gravity=np.zeros(3))
    q, v, _, _ = states(model, 6)
    power = np.einsum("bi,bi->b", v, dyn.nonlinear_effects(model, q, v))
    h = 1e-6
    dM = (dyn.mass_matrix(model, q + h * v) - dyn.mass_matrix(model, q - h * v)) / (2 * h)
    np.testing.assert_allclose(power, 0.5 * np.einsum("bi,bij,bj->b", v, dM, v), atol=1e-6)


@pytest.mark.parametrize("name", IDENTITY_MODELS)
def test_jacobian_matches_finite_differences(name: str) -> None:
    model = MODELS[name]
    q = states(model, 7, batch=1)[0][0]
    body = model.nbodies - 1
    point = np.array([0.1, 0.0, -0.05])
    h = 1e-6
    J = np.zeros((6, model.nv))
    T0 = dyn.forward_kinematics(model, q)[body]
    for k in range(model.nv):
        dq = np.zeros(model.nv)
        dq[k] = h
        Tp, Tm = (dyn.forward_kinematics(model, q + s * dq)[body] for s in (1, -1))
        J[:3, k] = (Tp[:3, :3] @ point + Tp[:3, 3] - Tm[:3, :3] @ point - Tm[:3, 3]) / (2 * h)
        W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T0[:3, :3].T  # skew(angular velocity)
        J[3:, k] = [W[2, 1], W[0, 2], W[1, 0]]
    np.testing.assert_allclose(dyn.jacobian(model, q, body, point), J, rtol=0, atol=1e-7)


@pytest.mark.parametrize("name", IDENTITY_MODELS)
def test_batched_call_equals_single_calls(name: str) -> None:
    model = MODELS[name]
    q, v, a, f = states(model, 8, batch=5)
    tau = dyn.rnea(model, q, v, a, f)
    wrench = dyn.joint_wrenches(model, q, v, a, f)
    for b in range(5):
        np.testing.assert_array_equal(tau[b].shape, (model.nv,))
        np.testing.assert_allclose(tau[b], dyn.rnea(model, q[b], v[b], a[b], f[b]), atol=1e-12)
        np.testing.assert_allclose(
            wrench[b], dyn.joint_wrenches(model, q[b], v[b], a[b], f[b]), atol=1e-12
        )
    # a batch larger than one chunk, and an odd size, give the same as small calls
    q, v, a, _ = states(model, 9, batch=2 * dyn.CHUNK + 7)
    tau = dyn.rnea(model, q, v, a)
    for b in (0, dyn.CHUNK, 2 * dyn.CHUNK + 6):
        np.testing.assert_allclose(tau[b], dyn.rnea(model, q[b], v[b], a[b]), atol=1e-12)


def test_batch_of_one_broadcasts() -> None:
    model = MODELS["random_a"]
    q, v, a, _ = states(model, 10, batch=4)
    tau = dyn.rnea(model, q, v[0], np.zeros(model.nv))
    assert tau.shape == (4, model.nv)
    np.testing.assert_allclose(tau[2], dyn.rnea(model, q[2], v[0], np.zeros(model.nv)))
    assert dyn.rnea(model, q[0], v[0], a[0]).shape == (model.nv,)
    assert dyn.forward_kinematics(model, q[0]).shape == (model.nbodies, 4, 4)
    assert dyn.center_of_mass(model, q).shape == (4, 3)
    assert dyn.mass_matrix(model, q[0]).shape == (model.nv, model.nv)


def test_external_force_at_is_jacobian_transpose() -> None:
    """A world force F at a world point of body b changes the torques by -J(point)^T F."""
    model = MODELS["HexapodRobot"]
    q, v, a, _ = states(model, 11)
    body = model.body("lf_tibia_link")
    local = np.array([0.01, 0.0, -0.12])
    T = dyn.forward_kinematics(model, q)[:, body]
    point = np.einsum("bij,j->bi", T[:, :3, :3], local) + T[:, :3, 3]
    force = np.array([1.0, -2.0, 30.0])
    fext = np.zeros((B, model.nbodies, 6))
    fext[:, body] = dyn.external_force_at(model, q, body, point, force)
    J = np.stack([dyn.jacobian(model, q[b], body, local) for b in range(B)])
    expected = dyn.rnea(model, q, v, a) - np.einsum("bji,j->bi", J[:, :3], force)
    np.testing.assert_allclose(dyn.rnea(model, q, v, a, fext), expected, atol=1e-9)


def test_root_wrench_carries_the_whole_weight() -> None:
    """At rest, the fixed root joint transmits the weight of everything above the world;
    a movable joint's torque is its axis component of the transmitted moment."""
    for name in ("HexapodRobot", "HumanoidRobot", "SkidSteerRobot"):
        model = MODELS[name]
        q = states(model, 12)[0]
        zero = np.zeros_like(q)
        W = dyn.joint_wrenches(model, q, zero, zero)
        np.testing.assert_allclose(
            W[:, 0, :3], np.tile(-model.total_mass * model.gravity, (B, 1)), atol=1e-9
        )
        tau = dyn.gravity_torques(model, q)
        for i in model.q_joints:
            np.testing.assert_allclose(
                tau[:, model.q_index[i]], W[:, i, 3:] @ model.joints[i].axis, atol=1e-12
            )


# --- bad input ----------------------------------------------------------------------------------


def test_wrong_shapes_are_rejected_clearly() -> None:
    model = MODELS["Manipulator3DOF"]
    nv = model.nv
    good = np.zeros(nv)
    with pytest.raises(ValueError, match=r"q must have shape \(nv,\) or \(B, nv\) with nv = 4"):
        dyn.rnea(model, np.zeros(nv + 1), good, good)
    with pytest.raises(ValueError, match="v must have shape"):
        dyn.rnea(model, good, np.zeros((2, 3, nv)), good)
    with pytest.raises(ValueError, match="batch sizes differ"):
        dyn.rnea(model, np.zeros((2, nv)), np.zeros((3, nv)), good)
    with pytest.raises(ValueError, match="fext must have shape"):
        dyn.rnea(model, good, good, good, np.zeros((model.nbodies, 3)))
    with pytest.raises(ValueError, match="must be finite"):
        dyn.gravity_torques(model, np.full(nv, np.nan))
    with pytest.raises(ValueError, match="no body 'hand'; bodies: base"):
        dyn.jacobian(model, good, "hand")
    with pytest.raises(ValueError, match="point must be"):
        dyn.jacobian(model, good, 1, [0.0, 1.0])
    with pytest.raises(ValueError, match="force_world must have shape"):
        dyn.external_force_at(model, good, 1, np.zeros(3), np.zeros(2))


def _chain(**changes) -> Model:
    """A two-body chain; ``changes`` replace fields of the second body or joint."""
    b0 = Body("a", 1.0, np.zeros(3), np.eye(3) * 0.01)
    j0 = Joint("ja", -1, 0, "fixed", np.eye(4))
    body = {k: v for k, v in changes.items() if k in ("mass", "com", "inertia")}
    joint = {k: v for k, v in changes.items() if k not in body}
    b1 = Body(**{"name": "b", "mass": 1.0, "com": np.zeros(3), "inertia": np.eye(3) * 0.01, **body})
    j1 = Joint(
        **{"name": "jb", "parent": 0, "child": 1, "kind": "revolute", "origin": np.eye(4), **joint}
    )
    return Model((b0, b1), (j0, j1))


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"axis": np.array([0.0, 0.0, 2.0])}, "not a unit vector"),
        ({"parent": 1}, "topologically ordered"),
        ({"parent": -2}, "topologically ordered"),
        ({"child": 0}, "its child must be body 1"),
        ({"kind": "prismatic"}, "is not one of"),
        ({"origin": np.diag([1.0, 1.0, 2.0, 1.0])}, "not a rigid transform"),
        ({"lower": 1.0, "upper": -1.0}, "lower"),
        ({"effort": -1.0}, "effort and velocity"),
        ({"mass": -0.1}, "mass must be finite and >= 0"),
        ({"inertia": np.array([[1.0, 0.1, 0], [0, 1.0, 0], [0, 0, 1.0]])}, "not symmetric"),
        ({"inertia": np.diag([1.0, -1.0, 1.0])}, "not positive semi-definite"),
        ({"inertia": np.diag([1.0, 1.0, 3.0])}, "triangle inequality"),
        ({"com": np.zeros(2)}, r"com must have shape \(3,\)"),
        ({"name": "ja"}, "duplicate joint name"),
    ],
)
def test_invalid_models_are_rejected(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _chain(**changes)


def test_model_structure_checks_and_immutability() -> None:
    m = _chain()
    with pytest.raises(ValueError, match="one joint per body"):
        Model(m.bodies, m.joints[:1])
    with pytest.raises(ValueError, match="duplicate body name"):
        Model((m.bodies[0], m.bodies[0]), m.joints)
    with pytest.raises(ValueError, match="at least one body"):
        Model((), ())
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.nv = 3  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        m.joints[1].axis[0] = 1.0
    assert (m.nq, m.nv, m.q_index, m.q_joints, m.q_names) == (1, 1, (-1, 0), (1,), ("jb",))
    assert m.body("b") == 1 and m.joint("jb") == 1 and m.total_mass == 2.0
    assert m == _chain() and m != _chain(mass=2.0)
    with pytest.raises(ValueError, match="no joint 'x'; joints: ja, jb"):
        m.joint("x")
    relimited = dataclasses.replace(m, joints=(m.joints[0], dataclasses.replace(m.joints[1])))
    assert relimited == m


# --- frames and inertia helpers ---------------------------------------------------------------


def test_frames() -> None:
    rng = np.random.default_rng(13)
    rpy = rng.uniform(-np.pi, np.pi, 3)
    R = matrix_from_rpy(rpy)
    np.testing.assert_allclose(R, rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0]))
    np.testing.assert_allclose(matrix_from_axis_angle([0, 0, 1], 0.3), rot_z(0.3), atol=1e-15)
    T = transform([1.0, 2.0, 3.0], rpy)
    np.testing.assert_allclose(T @ invert_transform(T), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(transform_from(R, [1, 2, 3]), T)
    half = np.sqrt(0.5)
    np.testing.assert_allclose(
        transform_from_pq([1, 2, 3, half, 0, 0, half]),
        transform([1, 2, 3], [0, 0, np.pi / 2]),
        atol=1e-15,
    )


def test_inertia_helpers() -> None:
    # a thin rod along x: m L^2 / 12 about y and z, ~0 about x
    rod = tube_inertia(2.0, 1.0, 1e-6, 0.0, (1, 0, 0))
    np.testing.assert_allclose(np.diag(rod), [0.0, 1 / 6, 1 / 6], atol=1e-9)
    # a thin-walled tube about its axis: m r^2
    np.testing.assert_allclose(tube_inertia(1.0, 0.1, 0.1, 0.1, (0, 0, 1))[2, 2], 0.01)
    # two point masses 1 m apart on x: COM in the middle, 0.5 kg m^2 about y and z
    m, c, inertia = combine_parts(
        [(1.0, np.zeros(3), np.zeros((3, 3))), (1.0, np.array([1.0, 0, 0]), np.zeros((3, 3)))]
    )
    assert m == 2.0
    np.testing.assert_allclose(c, [0.5, 0, 0])
    np.testing.assert_allclose(np.diag(inertia), [0.0, 0.5, 0.5])
    with pytest.raises(ValueError, match="r_inner"):
        tube_inertia(1.0, 1.0, 0.01, 0.02)
    with pytest.raises(ValueError, match="mass"):
        box_inertia(-1.0, (1, 1, 1))
