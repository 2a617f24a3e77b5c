"""Manipulators (paper section 4.3.3): inverse kinematics of serial arms and the
``pick-and-place``, ``grasping``, ``positioning`` (``move_to``), ``move_to_pose`` and
``orienting`` behaviours.

A chain may end in a gripper (its own joint, last in q), a tool without joints (a fixed
``tool_link`` whose origin is the tool's tip: a probe, a nozzle, a camera) or nothing (a
fixed ``tip_link`` at the end of the last link): grasping behaviours only with a gripper;
with a tool also ``pointing`` and ``scanning`` (the tool's axis along a direction, by
damped least squares on the chain's angular Jacobian, with the ``joint-hold`` loop); a
2-joint chain (a pan-tilt head) cannot place a point and only points its tool.

Any serial chain from the base to the gripper (3 to 7 joints in the part kinds, any axes)
is served by the numerical IK of :mod:`gaits.arm_ik` (task-priority damped least squares
with joint limits, seeded restarts); what the chain can do is read from it
(:func:`gaits.arm_ik.chain_rank`): rank 3 places the gripper, 4 or 5 also point the tool
down where they can (a soft secondary task: grasping from above), 6 orients the tool every
way (``orienting``; the positioning's roll, pitch, yaw); a redundant chain's spare freedom
keeps its joints off their limits. The closed forms below serve, as a fast path, the chains
they fit (the part kinds' chains of 3 and 6 joints: checked on the chain's own forward
kinematics, :meth:`ManipulatorController._closed_form`); what follows describes them.

Geometry (``kinematics.templates``, Fig. 16 and 31; base frame = the template's root
frame: z up at the top of the base plate, x forward): ``base_yaw`` turns about z at the
origin; a column ``L1`` carries ``shoulder_pitch`` at (0, 0, L1); the upper arm ``L2`` and
the forearm ``L3`` lie along +x at zero and pitch about +y (a positive angle turns a link
down). The 3-DOF arm's gripper (the ``gripper_link`` origin, which the gripper joint turns
about its own z without moving it) is at the forearm tip. The 6-DOF arm has a roll-pitch-
roll wrist at the forearm tip (``wrist_roll`` about x, ``wrist_pitch`` about y, then the
wrist tube ``L4`` along x and ``tool_roll`` about x): the three wrist axes meet at the
wrist centre and the gripper lies on the tool-roll axis, so position and orientation
decouple and both arms have closed-form inverse kinematics (:func:`ik_3dof`,
:func:`ik_6dof`); :func:`ik_dls` (damped least squares on
:func:`kinematics.dynamics.jacobian`) solves any template numerically and cross-checks them.

Branch choices: the elbow is *up* by default (``elbow_pitch >= 0``: the upper arm rises
and the forearm comes down onto the target, the elbow above the shoulder-gripper line,
away from the table); ``elbow="down"`` mirrors it, and the controller falls back to it when
the up branch leaves the joint limits. The base yaw faces the target (no reaching over the
top: the shoulder's +-pi/2 forbids it). The 6-DOF wrist's two solutions (``wrist_pitch``
of either sign, rolls turned by pi) are chosen inside the limits and nearest to a reference
configuration (the previous sample along a path, so the wrist never flips mid-motion).

Orientation of the 6-DOF tool: the frame of ``tool_roll_link`` (= ``gripper_link`` with
the gripper at 0), as URDF roll-pitch-yaw ``rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)``: rpy
(0, 0, 0) points the tool along +x; pitch = pi/2 points it straight down.

Trajectories: every segment is a minimum-jerk (quintic) profile, zero velocity and
acceleration at both ends: in joint space between configurations (the approach and the
transfer), or along a straight Cartesian line at constant tool orientation (descend, lift,
retreat: the gripper goes straight down onto the object and straight up). A segment lasts
as long as its slowest joint needs: peak speed at most ``speed_margin`` (default 0.5) of
the actuator's no-load speed (``DesignGeometry.joint_speed``) and peak acceleration at most
``max_acceleration`` (default 3 rad/s^2, the catalog's ``max_joint_acceleration`` that the
designer sized the actuators for; the record does not carry it). All positions stay within
the template's joint limits; the gripper (the ``gripper_link`` origin) never goes below
``FLOOR_CLEARANCE`` above the floor (world z = 0).

Frames: behaviour parameters are in the base frame; ``Trajectory.info["target"]`` is in the
world frame, ``base_position + target`` (the MJCF welds the base at ``(0, 0,
spawn_height)``: the bundle lifts it so the modules under the plate stand on the floor;
pass that as ``base_position``). Other ``info`` keys: ``target_base`` (base frame),
``pick`` (world), ``placed_at_s`` (pick-and-place: when the gripper has opened on the
target, before the retreat lifts it; measure the placing error there), ``grasped_at_s``,
``orientation_rpy`` (6-DOF), ``segments`` ((name, start s, end s) each), ``accelerations``
((N, nj) rad/s^2), ``planned_positions`` (with droop compensation).

Servo droop: a position servo is a spring of stiffness ``kp`` (N m/rad) towards its
reference, so under the arm's weight it settles ``g(q) / kp`` short of it (measured on the
default 3-DOF design in MuJoCo: 2.8 mm at the gripper at the default place target, 7.4 mm
near full reach; 0.05 and 0.2 mm with the compensation). Given ``stiffness``, the
controller sends ``q + g(q) / kp`` (gravity torques from the dynamics model) so the arm
settles on the planned path; ``info["planned_positions"]`` keeps the uncompensated path.

Masses: the dynamics model (gravity compensation, :func:`peak_torques`) is the ``model``
argument (e.g. the designer's sized template, ``Structure.template.model``); without it, the
template rebuilt from the record's lengths with the record's payload (``params.payload``)
and the template's default tube radii and actuator masses (design.json lists the actuators
but not their masses).

The MJCF models the payload as a point mass fixed on ``gripper_link``: "placing the
payload" is bringing the gripper to the place target; closing and opening the gripper turn
its joint between ``lower`` (closed, 0) and ``upper`` (open, pi/2) of its limits.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from functools import lru_cache

import numpy as np

from gaits.arm_ik import chain_rank, rotation_error, serial_chain, solve_ik
from gaits.base import (
    BehaviorSpec,
    Controller,
    DesignGeometry,
    Parameter,
    Trajectory,
    min_jerk,
)
from kinematics.dynamics import forward_kinematics, gravity_torques, jacobian, rnea
from kinematics.model import Model
from kinematics.partkinds import evaluate, load
from kinematics.spatial import matrix_from_rpy, rot_y, rot_z
from kinematics.templates import TemplateParams, build

__all__ = [
    "FLOOR_CLEARANCE",
    "MAX_ACCELERATION",
    "SPEED_MARGIN",
    "ManipulatorController",
    "arm_reach",
    "ik_3dof",
    "ik_6dof",
    "ik_dls",
    "min_jerk",
    "peak_torques",
    "serial_chain",
    "solve_ik",
]

#: Trajectory sample period, s (the simulation interpolates linearly between samples).
SAMPLE_DT = 0.01
#: Fraction of an actuator's no-load speed a segment may reach (a servo loaded by the arm's
#: weight runs slower than at no load).
SPEED_MARGIN = 0.5
#: Peak joint acceleration, rad/s^2: the catalog's ``design.max_joint_acceleration``, which
#: the designer's worst-case load (stretched, full payload) assumed.
MAX_ACCELERATION = 3.0
#: Speed rad/s assumed for a joint whose record gives none.
DEFAULT_SPEED = 1.0
#: Shortest segment, s.
MIN_SEGMENT = 0.3
#: Lowest height m of the gripper origin above the floor (world z = 0): about the half-
#: diagonal of the gripper's servo box, so no part of it touches the floor.
FLOOR_CLEARANCE = 0.04
#: Largest joint step rad between neighbouring IK samples of a Cartesian line (sampled at
#: 400 points or more): a bigger one means the IK switched branch.
MAX_STEP = 0.1
#: Iterations the numerical IK spends per sample of a Cartesian line on its secondary and
#: tertiary tasks once the gripper is on the line (each sample starts from the last, and
#: the steps that bring it there carry them: 0 keeps the line's first sample where the
#: segment before ended).
LINE_REFINE = 0
#: The feedback loop of a tool's pointing and scanning (:mod:`gaits.feedback`): an integral
#: on the servos' read-back, which removes part of the steady error their play leaves.
POINTING_FEEDBACK = {"loop": "joint-hold", "ki": 4.0}
#: Peak |s'| and |s''| of the minimum-jerk profile s(tau) on [0, 1].
_PEAK_SPEED = 1.875
_PEAK_ACCEL = 10.0 / math.sqrt(3.0)
#: The serial chains the closed forms are written for, by joint count: the part kinds'
#: ``[serial]`` rows of 3 (yaw, pitch, pitch) and 6 joints (a roll-pitch-roll wrist added).
_CLOSED_FORMS = (3, 6)


@lru_cache(maxsize=1)
def _serial_rows() -> dict[int, tuple[tuple[str, float, float], ...]]:
    """(joint, lower, upper rad) of the [serial] rows the closed forms serve."""

    rows = load().serial
    return {
        n: tuple((r[0], evaluate(r[2], {}), evaluate(r[3], {})) for r in rows[n])
        for n in _CLOSED_FORMS
    }


def _chain(n: int) -> tuple[str, ...]:
    """The joint names of the closed forms' chain of ``n`` joints."""
    return tuple(name for name, _, _ in _serial_rows()[n])


# --- profiles ------------------------------------------------------------------------------------


def _wrap(a: float) -> float:
    """Angle rad wrapped to [-pi, pi]."""
    return (a + math.pi) % (2 * math.pi) - math.pi


# --- inverse kinematics --------------------------------------------------------------------------


def arm_reach(lengths: Mapping[str, float], elbow_limit: float = 5 * math.pi / 6) -> tuple:
    """(nearest, farthest) distance m from the shoulder (0, 0, L1) to the forearm tip, with
    the elbow bent at most ``elbow_limit`` rad."""
    L2, L3 = lengths["L2"], lengths["L3"]
    c = math.cos(min(abs(elbow_limit), math.pi))
    return math.sqrt(max(L2 * L2 + L3 * L3 + 2 * L2 * L3 * c, 0.0)), L2 + L3


def _check_limits(names: Sequence[str], q: np.ndarray, limits: Mapping | None) -> None:
    if limits is None:
        return
    for name, x in zip(names, q, strict=True):
        lo, hi = limits[name]
        if not lo - 1e-9 <= x <= hi + 1e-9:
            raise ValueError(
                f"{name} would need {x:.4f} rad, outside its limits [{lo:.4f}, {hi:.4f}]"
            )


def ik_3dof(
    lengths: Mapping[str, float],
    position: Sequence[float],
    elbow: str = "up",
    yaw: float = 0.0,
    limits: Mapping[str, tuple[float, float]] | None = None,
) -> np.ndarray:
    """Joint angles (base_yaw, shoulder_pitch, elbow_pitch) rad that put the forearm tip of a
    3-joint serial arm at ``position`` (3,) m in the base frame, in closed form.

    ``lengths``: L1, L2, L3 m. ``elbow``: "up" (elbow_pitch >= 0) or "down" (<= 0).
    ``yaw``: the base yaw kept for a target on the base axis (where any yaw works).
    ``limits``: joint name -> (lower, upper) rad; default the template's (shoulder +-pi/2,
    elbow +-5pi/6). ValueError for a target out of reach (the message gives the reach) or
    outside the joint limits.
    """
    if elbow not in ("up", "down"):
        raise ValueError(f"elbow: expected 'up' or 'down', got {elbow!r}")
    L1, L2, L3 = (float(lengths[k]) for k in ("L1", "L2", "L3"))
    x, y, z = (float(c) for c in position)
    if not all(math.isfinite(c) for c in (x, y, z)):
        raise ValueError(f"target ({x}, {y}, {z}) is not finite")
    lim = dict(limits) if limits is not None else _default_limits()
    near, far = arm_reach(lengths, max(abs(v) for v in lim["elbow_pitch"]))
    r = math.hypot(x, y)
    down = L1 - z  # vertical drop from the shoulder, positive down
    d = math.hypot(r, down)
    tol = 1e-9 * max(1.0, far)
    if d > far + tol or d < near - tol:
        raise ValueError(
            f"target ({x:.4f}, {y:.4f}, {z:.4f}) m is {d:.4f} m from the shoulder at "
            f"(0, 0, {L1:.4f}); the arm reaches {near:.4f} to {far:.4f} m from it"
        )
    base = math.atan2(y, x) if r > 1e-12 else yaw
    c3 = (d * d - L2 * L2 - L3 * L3) / (2 * L2 * L3)
    q3 = math.acos(min(1.0, max(-1.0, c3)))
    if elbow == "down":
        q3 = -q3
    # planar 2R arm in (r, down): r = L2 c2 + L3 c23, down = L2 s2 + L3 s23
    q2 = math.atan2(down, r) - math.atan2(L3 * math.sin(q3), L2 + L3 * math.cos(q3))
    q = np.array([base, _wrap(q2), q3])
    _check_limits(_chain(3), q, lim)
    return q


def _default_limits() -> dict[str, tuple[float, float]]:
    """The part kinds' joint limits of the closed forms' chains (the 6-joint chain's
    include the 3-joint chain's)."""
    return {n: (lo, hi) for n, lo, hi in _serial_rows()[6]}


def ik_6dof(
    lengths: Mapping[str, float],
    position: Sequence[float],
    rotation: np.ndarray,
    elbow: str = "up",
    reference: Sequence[float] | None = None,
    limits: Mapping[str, tuple[float, float]] | None = None,
) -> np.ndarray:
    """Joint angles (base_yaw, shoulder_pitch, elbow_pitch, wrist_roll, wrist_pitch,
    tool_roll) rad of a 6-joint serial arm whose gripper is at ``position`` (3,) m with the tool
    frame ``rotation`` (3, 3) (base frame), in closed form (spherical-wrist decoupling).

    The wrist centre is ``position - L4 * rotation[:, 0]`` (the tool's x axis points from
    it to the gripper); the first three joints place it (:func:`ik_3dof`), then the wrist is
    the roll-pitch-roll (x-y-x) Euler decomposition of ``R_forearm^T @ rotation``. Of its two
    solutions the one inside the limits nearest to ``reference`` (6,) rad is returned
    (default: zero); at the wrist singularity (wrist_pitch 0, both rolls aligned) the wrist
    roll keeps the reference's. ValueError when out of reach or outside the limits.
    """
    R = np.asarray(rotation, dtype=float)
    if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
        raise ValueError("rotation must be a (3, 3) rotation matrix")
    lim = dict(limits) if limits is not None else _default_limits()
    ref = np.zeros(6) if reference is None else np.asarray(reference, dtype=float)
    p = np.asarray(position, dtype=float)
    centre = p - float(lengths["L4"]) * R[:, 0]
    try:
        arm = ik_3dof(lengths, centre, elbow, float(ref[0]), lim)
    except ValueError as e:
        raise ValueError(
            f"the wrist centre (the gripper less L4 = {float(lengths['L4']):.4f} m along the "
            f"tool's x axis) is out of reach: {e}"
        ) from None
    forearm = rot_z(arm[0]) @ rot_y(arm[1] + arm[2])
    M = forearm.T @ R
    sb = math.hypot(M[0, 1], M[0, 2])
    b = math.atan2(sb, M[0, 0])  # in [0, pi]; accurate near 0, unlike acos
    if sb > 1e-9:
        a = math.atan2(M[1, 0], -M[2, 0])
        c = math.atan2(M[0, 1], M[0, 2])
        wrists = [(a, b, c), (_wrap(a + math.pi), -b, _wrap(c + math.pi))]
    else:  # aligned rolls: only a + c (b = 0) or a - c (b = pi) is determined
        a = float(ref[3])
        s = math.atan2(M[2, 1], M[1, 1])
        wrists = [(a, b, _wrap(s - a) if b < 1.0 else _wrap(a - s))]
    names = _chain(6)
    best, err = None, None
    for w in wrists:
        q = np.concatenate([arm, w])
        try:
            _check_limits(names, q, lim)
        except ValueError as e:
            err = err or e
            continue
        if best is None or np.sum((q[3:] - ref[3:]) ** 2) < np.sum((best[3:] - ref[3:]) ** 2):
            best = q
    if best is None:
        raise ValueError(f"the tool orientation is out of the wrist's range: {err}")
    return best


def rpy_yaw_at_gimbal_lock(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) rad of a rotation (3, 3), ``R = rot_z(y) rot_y(p) rot_x(r)``, as
    ``move_to_pose`` records the tool's orientation (``info["orientation_rpy"]``): pitch by
    ``asin`` in [-pi/2, pi/2]; at pitch = +-pi/2 the roll is 0 and the yaw takes the rotation
    about z. Not :func:`kinematics.spatial.rpy_from_matrix` (the URDF writer's: at gimbal lock
    the roll takes it, and its pitch comes from ``atan2``, exact where ``asin`` loses about
    1e-8 rad near +-pi/2): the recorded orientation errors of shipped designs (6.6e-9 rad on
    the 6-DOF arm's default pose) stay what they were until that change is made on purpose."""
    R = np.asarray(R, dtype=float)
    p = math.asin(min(1.0, max(-1.0, -R[2, 0])))
    if abs(R[2, 0]) < 1 - 1e-12:
        return np.array([math.atan2(R[2, 1], R[2, 2]), p, math.atan2(R[1, 0], R[0, 0])])
    return np.array([0.0, p, math.atan2(-R[0, 1], R[1, 1])])


_rotation_error = rotation_error


def ik_dls(
    model: Model,
    body: str,
    position: Sequence[float],
    rotation: np.ndarray | None = None,
    q0: Sequence[float] | None = None,
    joints: Sequence[str] | None = None,
    tol: float = 1e-6,
    damping: float = 1e-3,
    max_iter: int = 500,
) -> np.ndarray:
    """Configuration q (nv,) rad whose ``body`` origin is at ``position`` (3,) m (and whose
    frame is ``rotation`` (3, 3) if given), by damped least squares from ``q0`` (default
    zero), moving only ``joints`` (default all) and clipping to the joint limits.

    Converged when the position error is below ``tol`` m and the orientation error below
    ``tol`` rad; ValueError otherwise (unreachable, or a local minimum). The step is
    ``J^T (J J^T + damping^2 I)^-1 e`` with J from :func:`kinematics.dynamics.jacobian`.
    """
    bi = model.body(body)
    q = np.zeros(model.nv) if q0 is None else np.array(q0, dtype=float)
    names = model.q_names
    cols = (
        np.arange(model.nv)
        if joints is None
        else np.array([names.index(j) for j in joints], dtype=int)
    )
    lo, hi = model.lower, model.upper
    target = np.asarray(position, dtype=float)
    rows = slice(0, 6) if rotation is not None else slice(0, 3)
    err = np.inf
    for _ in range(max_iter):
        T = forward_kinematics(model, q)[bi]
        e = target - T[:3, 3]
        if rotation is not None:
            e = np.concatenate([e, _rotation_error(T[:3, :3], np.asarray(rotation))])
        err = float(np.max(np.abs(e)))
        if np.linalg.norm(e[:3]) < tol and (rotation is None or np.linalg.norm(e[3:]) < tol):
            return q
        J = jacobian(model, q, bi)[rows][:, cols]
        step = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(J.shape[0]), e)
        q[cols] = np.clip(q[cols] + step, lo[cols], hi[cols])
    raise ValueError(f"damped least squares did not converge (error {err:.3g} after {max_iter})")


# --- torques -------------------------------------------------------------------------------------


def peak_torques(traj: Trajectory, model: Model) -> dict[str, float]:
    """Peak |tau| N m per joint along ``traj`` by RNEA on ``model`` (a kinematics Model with
    the design's masses): the planned path (``info["planned_positions"]`` when the positions
    carry servo-droop compensation), its velocities and its accelerations
    (``info["accelerations"]``, else differentiated)."""
    q = np.asarray(traj.info.get("planned_positions", traj.positions))
    v = traj.velocities
    a = traj.info.get("accelerations")
    a = np.gradient(v, traj.times, axis=0) if a is None else np.asarray(a)
    names = model.q_names
    cols = [names.index(j) for j in traj.joints]
    Q, V, A = (np.zeros((len(traj.times), model.nv)) for _ in range(3))
    Q[:, cols], V[:, cols], A[:, cols] = q, v, a
    tau = rnea(model, Q, V, A)
    return {j: float(np.max(np.abs(tau[:, c]))) for j, c in zip(traj.joints, cols, strict=True)}


# --- the controller ------------------------------------------------------------------------------


class _Plan:
    """Samples of a trajectory under construction: times s, q, qd, qdd (n, nq)."""

    def __init__(self, q0: np.ndarray) -> None:
        self.t = [np.zeros(1)]
        self.q = [q0[None, :].copy()]
        self.qd = [np.zeros((1, len(q0)))]
        self.qdd = [np.zeros((1, len(q0)))]
        self.segments: list[tuple[str, float, float]] = []

    @property
    def last(self) -> np.ndarray:
        return self.q[-1][-1].copy()

    @property
    def now(self) -> float:
        return float(self.t[-1][-1])

    def at(self, t: float) -> np.ndarray:
        """The planned configuration at time ``t`` s (the last sample at or before it)."""
        times = np.concatenate(self.t)
        k = int(np.searchsorted(times, t + 1e-12, side="right")) - 1
        return np.concatenate(self.q)[max(k, 0)].copy()

    def add(
        self,
        name: str,
        tau: np.ndarray,
        T: float,
        q: np.ndarray,
        dq: np.ndarray,
        ddq: np.ndarray,
    ) -> None:
        """Append a segment lasting ``T`` s, sampled at ``tau`` (n,) in [0, 1]: q (n, nq) rad,
        dq = dq/dtau and ddq = d2q/dtau2 (n, nq); its first sample repeats the plan's last."""
        t0 = self.now
        self.t.append(t0 + T * tau[1:])
        self.q.append(q[1:])
        self.qd.append(dq[1:] / T)
        self.qdd.append(ddq[1:] / T**2)
        self.segments.append((name, t0, t0 + T))

    def arrays(self) -> tuple[np.ndarray, ...]:
        return tuple(np.concatenate(x) for x in (self.t, self.q, self.qd, self.qdd))


class ManipulatorController(Controller):
    """The behaviours of a serial arm: every joint of the model on the chain from the base
    to the gripper (the template's end effector), the gripper's own joint last.

    ``base_position`` (3,) m: where the base frame sits in the world (the MJCF's root body
    position; the floor is the world plane z = 0). ``model``: a kinematics Model with the
    design's masses (gravity compensation, :meth:`peak_torques`); default see the module
    docstring. ``stiffness``: joint name -> servo stiffness N m/rad (the MJCF's ``kp``):
    when given, positions are compensated for the servos' droop under gravity.
    ``gravity``: (N, nj) positions -> (N, nj) gravity torques N m of the joints, used for the
    droop instead of ``model`` (e.g. the simulator's own model, so the compensation matches
    the masses it simulates).
    ``speed_margin``: fraction of each no-load speed used; ``max_acceleration`` rad/s^2;
    ``elbow``: the preferred elbow branch, "up" or "down".
    """

    PLAN_IGNORES = frozenset({"mass_kg", "joint_torque", "calibration"})

    def __init__(
        self,
        geometry: DesignGeometry,
        base_position: Sequence[float] = (0.0, 0.0, 0.0),
        model: Model | None = None,
        stiffness: Mapping[str, float] | None = None,
        gravity: Callable[[np.ndarray], np.ndarray] | None = None,
        speed_margin: float = SPEED_MARGIN,
        max_acceleration: float = MAX_ACCELERATION,
        elbow: str = "up",
    ) -> None:
        super().__init__(geometry)
        kin = self.template.model
        if not self.template.end_effectors:
            raise ValueError(
                f"ManipulatorController drives a serial arm ending in a gripper, a tool or "
                f"nothing; {geometry.template} has no end effector"
            )
        self.chain = serial_chain(kin, self.template.end_effectors[0])
        chain = self.chain.joints
        end = kin.joints[kin.body(self.chain.end_body)]
        #: the chain ends in a gripper (its own joint, last in q), not a tool or nothing
        self.grip = end.movable
        if kin.q_names != ((*chain, end.name) if self.grip else tuple(chain)):
            raise ValueError(
                f"ManipulatorController drives a serial arm whose every joint is on the "
                f"chain to its end; {geometry.template}'s joints are "
                f"{', '.join(kin.q_names)}"
            )
        #: the arm's joints: the first ``na`` of q (the gripper, if any, after them)
        self.na = len(chain)
        #: the rank of the chain's Jacobian: 3 places the gripper, 6 also orients the tool
        #: every way, 4 or 5 leave some orientation freedom (the tool points down)
        self.rank = chain_rank(self.chain)
        #: the chain moves its end point in three dimensions (else it only points its
        #: tool: a pan-tilt head)
        self.places = chain_rank(self.chain, position_only=True) >= 3
        if not self.places and (self.grip or self.na < 2):
            raise ValueError(
                f"ManipulatorController: the joints {', '.join(chain)} of {geometry.template} "
                "cannot move the gripper in three dimensions"
                if self.grip
                else f"ManipulatorController: {geometry.template} has one joint: it cannot "
                "point its tool"
            )
        if not 0 < speed_margin <= 1:
            raise ValueError(f"speed_margin must be in (0, 1], got {speed_margin}")
        if not max_acceleration > 0:
            raise ValueError(f"max_acceleration must be > 0, got {max_acceleration}")
        if elbow not in ("up", "down"):
            raise ValueError(f"elbow: expected 'up' or 'down', got {elbow!r}")
        self.six = self.places and self.rank >= 6  # the tool takes any orientation
        self.points = self.places and self.rank > 3  # the tool can point down
        self.arm = chain
        self.lengths = dict(self.template.lengths)
        self._shoulder, self._reach = self.chain.shoulder()
        #: how far above the gripper a tool pointing down holds the wrist (0: a chain
        #: that cannot point its tool)
        self.tool_length = self.chain.tool_length() if self.points else 0.0
        self.base_position = np.array(base_position, dtype=float)
        if self.base_position.shape != (3,) or not np.all(np.isfinite(self.base_position)):
            raise ValueError(f"base_position must be 3 finite numbers, got {base_position!r}")
        self.elbow = elbow
        self.speed_margin = float(speed_margin)
        self.max_acceleration = float(max_acceleration)
        self.joints = kin.q_names  # arm joints, then the gripper (if any)
        self.lower, self.upper = kin.lower, kin.upper
        self.limits = {
            n: (lo, hi) for n, lo, hi in zip(self.joints, self.lower, self.upper, strict=True)
        }
        #: the closed forms' joint count when they fit this chain (:meth:`_closed_form`),
        #: else None: the numerical IK (:func:`gaits.arm_ik.solve_ik`) serves it
        self.closed = self._closed_form()
        no_load = [geometry.joint_speed.get(j, 0.0) for j in self.joints]
        self.speed = np.array([self.speed_margin * w if w > 0 else DEFAULT_SPEED for w in no_load])
        if model is None:
            payload = float(geometry.params.get("payload", 0.0))
            model = build(
                geometry.template, TemplateParams(lengths=self.lengths, payload=payload)
            ).model
        if model.q_names != self.joints:
            raise ValueError(f"the dynamics model's joints {model.q_names} are not {self.joints}")
        self.model = model
        self.stiffness = None
        if stiffness is not None:
            missing = sorted(set(self.joints) - set(stiffness))
            if missing:
                raise ValueError(f"stiffness: no value for {', '.join(missing)}")
            k = np.array([float(stiffness[j]) for j in self.joints])
            if not np.all(k > 0):
                raise ValueError("stiffness values must be > 0 N m/rad")
            self.stiffness = k
        self.gravity = gravity
        self.home = self._home()
        #: named joint-space poses (full configurations, gripper open) for move_to_pose
        zero = np.clip(np.zeros(len(self.joints)), self.lower, self.upper)
        if self.grip:
            zero[-1] = self.upper[-1]
        self.poses = {"ready": self.home, "home": zero}
        self._behaviors = self._specs()

    # --- geometry helpers ----------------------------------------------------------------

    @property
    def reach(self) -> float:
        """Reach m of the gripper from the shoulder (the lengths between the joints after
        it and the gripper: the arm stretched)."""
        return self._reach

    def _closed_form(self) -> int | None:
        """The closed forms' joint count when one serves this chain: its joints are the
        part kinds' [serial] row of that count and the closed form round-trips the
        chain's own forward kinematics at three configurations (so a chain of the same
        names but other link placements goes to the numerical IK)."""
        n = len(self.arm)
        if n not in _CLOSED_FORMS or self.arm != _chain(n):
            return None
        rng = np.random.default_rng(7)
        lo, hi = self.lower[: self.na], self.upper[: self.na]
        for _ in range(3):
            q = 0.3 * (lo + rng.random(n) * (hi - lo))
            p, R = self.chain.forward(q)
            elbow = "up" if q[2] >= 0 else "down"
            try:
                if n == 6:
                    qc = ik_6dof(self.lengths, p, R, elbow, q, self.limits)
                else:
                    qc = ik_3dof(self.lengths, p, elbow, float(q[0]), self.limits)
            except (KeyError, ValueError):
                return None
            p2, R2 = self.chain.forward(qc)
            if np.linalg.norm(p2 - p) > 1e-6 or (n == 6 and not np.allclose(R2, R, atol=1e-6)):
                return None
        return n

    def _home(self) -> np.ndarray:
        """Ready pose, gripper open, clipped to the limits. The closed forms' chains:
        upper arm raised 45 degrees and forearm 45 degrees down (3 joints: the gripper at
        shoulder height for L2 = L3); 6 joints: forearm horizontal, tool pointing down
        (the gripper L4 under the wrist). Any other chain: the wrist 0.6 of the arm's
        reach (less the tool's length) in front of the shoulder and a quarter of it above,
        the tool pointing down as far as the chain can, the elbow up (of the IK's solutions the
        one whose lowest joint stands highest, then nearest the middle of the ranges)."""
        q = np.zeros(len(self.joints))
        if self.grip:
            q[-1] = self.upper[-1]
        if not self.places:  # a pointing head: its zero pose, within its limits
            return np.clip(q, self.lower, self.upper)
        if self.closed is not None:
            q[1], q[2] = -math.pi / 4, math.pi / 2
            if self.six:
                q[2] = math.pi / 4
                q[4] = math.pi / 2 - (q[1] + q[2])
            return np.clip(q, self.lower, self.upper)
        arm = self.reach - self.tool_length
        target = self._shoulder + np.array([0.6 * arm, 0.0, 0.25 * arm - self.tool_length])
        # a long tool: not below the floor
        target[2] = max(target[2], FLOOR_CLEARANCE + 0.02 - float(self.base_position[2]))
        lo, hi = self.lower[: self.na], self.upper[: self.na]
        mid = np.where(np.isfinite(lo) & np.isfinite(hi), (lo + hi) / 2, 0.0)
        span = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo, math.inf)

        # the joints whose height tells the branches apart: every one (the gripper arms,
        # as they were designed); a tool's or a bare arm's: those after its first, whose
        # origin stands still (else the first always stands lowest and the elbow's branch
        # falls to the range's middle: elbow down, and a branch flip to the next target)
        above = 0 if self.grip else 1

        def elbow_up(x: np.ndarray) -> float:
            _, _, _, origins = self.chain.frames(x)
            low = float(origins[above:, 2].min())
            return -low + 1e-3 * float(np.sum(((x - mid) / span) ** 2))

        down = (0.0, 0.0, -1.0) if self.points else None  # a wish: not the whole frame
        q[: self.na] = solve_ik(self.chain, target, None, down, mid, score=elbow_up)
        return q

    def gripper_position(self, q: np.ndarray) -> np.ndarray:
        """End point (the gripper's ``gripper_link`` origin, a tool's tip, the end of a bare
        arm's last link) position (B?, 3) m in the base frame at q."""
        T = forward_kinematics(self.template.model, q)
        return T[..., self.template.model.body(self.chain.end_body), :3, 3]

    def tool_rotation(self, q: np.ndarray) -> np.ndarray:
        """Tool frame (3, 3) in the base frame at q: the frame of the body the gripper
        hangs on (``tool_roll_link`` on the 6-joint arm)."""
        m = self.template.model
        return forward_kinematics(m, q)[m.body(self.chain.tool_body), :3, :3]

    def down(self, position: Sequence[float]) -> np.ndarray:
        """Tool frame whose tool axis (the chain's last link, x on the part kinds' arms)
        points straight down, its y axis across the arm's plane at ``position`` (so the
        wrist needs no roll)."""
        yaw = math.atan2(position[1], position[0]) if math.hypot(*position[:2]) > 1e-9 else 0.0
        R = rot_z(yaw) @ rot_y(math.pi / 2)
        a = self.chain.tool_axis
        x = np.array([1.0, 0.0, 0.0])
        if np.allclose(a, x):
            return R
        v, c = np.cross(x, a), float(x @ a)  # the turn A taking x to the tool axis
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        A = np.eye(3) + K + K @ K / (1 + c) if c > -1 + 1e-9 else np.diag([-1.0, -1.0, 1.0])
        return R @ A.T

    def ik(
        self,
        position: Sequence[float],
        rotation: np.ndarray | None = None,
        reference: np.ndarray | None = None,
        elbow: str | None = None,
        refine: int = 50,
    ) -> np.ndarray:
        """Arm joint angles (nq - 1,) rad that put the gripper at ``position`` m (base frame)
        with (a chain that orients its tool every way) the tool frame ``rotation``
        (default: pointing down). The closed forms: the preferred elbow branch first, then
        the other. Any other chain: :func:`gaits.arm_ik.solve_ik` from ``reference`` (the
        tool pointing down as far as the chain allows; ``refine``: iterations spent on
        that and on keeping off the joint limits once the gripper is there). ValueError
        when no solution is found."""
        ref = self.home[: self.na] if reference is None else np.asarray(reference)
        if self.closed is None:
            if rotation is not None and not self.six:
                raise ValueError(
                    f"this arm cannot choose its tool orientation: its joints "
                    f"({', '.join(self.arm)}) give {self.rank - 3} of its 3 degrees of freedom"
                )
            R = rotation if rotation is not None or not self.six else self.down(position)
            down = (0.0, 0.0, -1.0) if self.points and R is None else None
            return solve_ik(self.chain, position, R, down, ref, refine=refine)
        branches = (elbow,) if elbow else (self.elbow, "down" if self.elbow == "up" else "up")
        errors = []
        for e in branches:
            try:
                if self.six:
                    R = self.down(position) if rotation is None else rotation
                    return ik_6dof(self.lengths, position, R, e, ref, self.limits)
                if rotation is not None:
                    raise ValueError("a 3-DOF arm cannot choose its tool orientation")
                return ik_3dof(self.lengths, position, e, float(ref[0]), self.limits)
            except ValueError as err:
                errors.append(f"elbow {e}: {err}")
        raise ValueError(
            f"cannot reach ({', '.join(f'{c:.4f}' for c in position)}) m: " + "; ".join(errors)
        )

    # --- behaviours ----------------------------------------------------------------------

    def _specs(self) -> dict[str, BehaviorSpec]:
        # from the chain: the shoulder's height, the reach less the tool's length
        # (3 joints: L1, L2 + L3; 6 joints: L1, L2 + L3 with the L4 tool pointing down)
        height = float(self._shoulder[2])
        arm = self.reach - self.tool_length
        r0 = 0.6 * arm
        z0 = 0.5 * height
        side = r0 / math.sqrt(2)
        clear = 0.15 * arm

        def box(k: int, v: float) -> tuple[float, float]:
            """Coordinate ``k``'s range: the shoulder's +- the reach (the box around the
            sphere the gripper reaches), to the 0.1 mm outwards, z from
            ``FLOOR_CLEARANCE`` above the floor; holding ``v``."""
            c = float(self._shoulder[k])
            lo = math.floor((c - self.reach) * 1e4) / 1e4
            hi = math.ceil((c + self.reach) * 1e4) / 1e4
            if k == 2:
                floor = FLOOR_CLEARANCE - float(self.base_position[2])
                lo = max(lo, math.ceil(floor * 1e4 - 1e-6) / 1e4)
            return min(lo, round(v, 4)), max(hi, round(v, 4))

        def xyz(prefix: str, where: str, y: float, z: float = z0) -> tuple[Parameter, ...]:
            return tuple(
                Parameter(
                    f"{prefix}{c}",
                    "float",
                    round(v, 4),
                    f"{where} {c} in the base frame",
                    "m",
                    low=box(k, v)[0],
                    high=box(k, v)[1],
                )
                for k, (c, v) in enumerate((("x", side), ("y", y), ("z", z)))
            )

        heights = (
            Parameter(
                "clearance",
                "float",
                round(clear, 4),
                "height above the object of the approach and the lift",
                "m",
                low=0.0,
                high=self.reach,
            ),
            Parameter(
                "retreat",
                "float",
                round(clear, 4),
                "rise after releasing the payload (0: end at the place target)",
                "m",
                low=0.0,
                high=self.reach,
            ),
        )
        home = self.gripper_position(self.home)
        orient = (
            Parameter(
                "roll",
                "float",
                0.0,
                "tool roll about its x axis",
                "rad",
                low=-math.pi,
                high=math.pi,
            ),
            Parameter(
                "pitch",
                "float",
                math.pi / 2,
                "tool pitch (pi/2: pointing down)",
                "rad",
                low=-math.pi / 2,
                high=math.pi / 2,
            ),
            Parameter(
                "yaw",
                "float",
                0.0,
                "tool yaw about the vertical",
                "rad",
                low=-math.pi,
                high=math.pi,
            ),
        )
        move = xyz("", "gripper target" if self.grip else "end point target", 0.0)
        if not self.places:  # a pointing head: pointing and scanning, its poses
            return self._pointing_specs()
        specs = {
            "pick-and-place": BehaviorSpec(
                "pick-and-place",
                "approach above the object, descend, close the gripper, lift, move, descend, "
                "open, retreat (minimum-jerk segments)",
                (*xyz("pick_", "object", -side), *xyz("place_", "place target", side), *heights),
            ),
            "grasping": BehaviorSpec(
                "grasping",
                "approach above the object, descend, close the gripper and lift it",
                (*xyz("", "object", 0.0), heights[0]),
            ),
            "positioning": BehaviorSpec(
                "positioning",
                "move the gripper to (x, y, z)"
                + (" with the tool at (roll, pitch, yaw)" if self.six else ""),
                move + (orient if self.six else ()),
            ),
        }
        specs["move_to"] = BehaviorSpec(
            "move_to",
            "alias of positioning",
            specs["positioning"].params,
            ability="positioning",
            alias_of="positioning",
        )
        specs["move_to_pose"] = BehaviorSpec(
            "move_to_pose",
            "move the joints to a named pose: ready (where every behaviour starts) or home "
            "(every arm joint at 0: the arm stretched along its zero pose), gripper open",
            (Parameter("pose", "choice", "ready", "the named pose", choices=tuple(self.poses)),),
            ability="positioning",
        )
        if not self.grip:  # a tool or nothing at the tip: nothing to grasp; a tool points
            del specs["pick-and-place"], specs["grasping"]
            specs.update(self._pointing_specs(pose=False))
        if self.six:
            tilt = Parameter(
                "pitch",
                "float",
                math.pi / 4,
                "tool pitch (pi/2: pointing down)",
                "rad",
                low=-math.pi / 2,
                high=math.pi / 2,
            )
            specs["orienting"] = BehaviorSpec(
                "orienting",
                "turn the tool to (roll, pitch, yaw) with the gripper at (x, y, z) "
                "(default: where the home pose holds it, the tool tilted 45 degrees down)",
                (
                    orient[0],
                    tilt,
                    orient[2],
                    *(
                        Parameter(
                            c,
                            "float",
                            round(float(v), 4),
                            f"gripper {c}, base frame",
                            "m",
                            low=box(k, float(v))[0],
                            high=box(k, float(v))[1],
                        )
                        for k, (c, v) in enumerate(zip("xyz", home, strict=True))
                    ),
                ),
            )
        return specs

    def _pointing_specs(self, pose: bool = True) -> dict[str, BehaviorSpec]:
        """``pointing`` (the tool's axis along a direction: azimuth about the vertical from
        the base's x, elevation above the horizontal) and ``scanning`` (the axis swept
        from one azimuth to another at an elevation, through ``stops`` directions), and
        (``pose``: a chain that cannot place its end point) ``move_to_pose`` for them."""
        pi = math.pi

        def angle(name: str, default: float, doc: str, lo: float, hi: float) -> Parameter:
            return Parameter(name, "float", default, doc, "rad", low=lo, high=hi)

        el = angle("elevation", 0.2, "above the horizontal (negative: below)", -pi / 2, pi / 2)
        specs = {
            "pointing": BehaviorSpec(
                "pointing",
                "point the tool's axis along (azimuth, elevation) (a minimum-jerk joint move)",
                (angle("azimuth", 0.5, "about the vertical, from the base's x", -pi, pi), el),
            ),
            "scanning": BehaviorSpec(
                "scanning",
                "sweep the tool's axis from one azimuth to another at an elevation, through "
                "evenly spaced directions",
                (
                    angle("from_azimuth", -0.6, "where the sweep starts", -pi, pi),
                    angle("to_azimuth", 0.6, "where the sweep ends", -pi, pi),
                    el,
                    Parameter("stops", "int", 5, "directions along the sweep", low=2, high=50),
                ),
                ability="pointing",
            ),
        }
        if pose:
            specs["move_to_pose"] = BehaviorSpec(
                "move_to_pose",
                "move the joints to a named pose: ready (where every behaviour starts) or "
                "home (every joint at 0)",
                (
                    Parameter(
                        "pose", "choice", "ready", "the named pose", choices=tuple(self.poses)
                    ),
                ),
                ability="pointing",
            )
        return specs

    def point(self, azimuth: float, elevation: float, reference: np.ndarray) -> np.ndarray:
        """Arm joint angles (na,) rad that turn the tool's axis (the chain's last link's
        direction, :attr:`gaits.arm_ik.SerialChain.tool_axis`) along the direction of
        ``azimuth`` and ``elevation`` rad (base frame), nearest ``reference``: damped least
        squares on the axis' error through the chain's angular Jacobian, within the
        joints' limits. ValueError when the chain cannot turn it there (0.1 deg)."""
        ce = math.cos(elevation)
        d = np.array([ce * math.cos(azimuth), ce * math.sin(azimuth), math.sin(elevation)])
        lo, hi = self.lower[: self.na], self.upper[: self.na]
        best, err = None, math.inf
        for seed in (np.asarray(reference, dtype=float), np.clip(np.zeros(self.na), lo, hi)):
            q = np.clip(seed.copy(), lo, hi)
            for _ in range(200):
                _, R, axes, _ = self.chain.frames(q)
                a = R @ self.chain.tool_axis
                if float(a @ d) < -0.999:  # pointing away: no gradient; turn first
                    q = np.clip(q + 0.5, lo, hi)
                    continue
                J = np.cross(axes, a).T  # d a / d q (3, na)
                step = J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(3), d - a)
                q = np.clip(q + step, lo, hi)
                if np.linalg.norm(step) < 1e-10:
                    break
            _, R, _, _ = self.chain.frames(q)
            miss = math.acos(max(-1.0, min(1.0, float((R @ self.chain.tool_axis) @ d))))
            if miss < err - 1e-12:
                best, err = q, miss
            if err < 1e-4:
                break
        if best is None or err > math.radians(0.1):
            raise ValueError(
                f"the tool cannot point at azimuth {azimuth:.3f}, elevation {elevation:.3f} "
                f"rad: its joints ({', '.join(self.arm)}) and their limits leave it "
                f"{math.degrees(err):.1f} deg off"
            )
        return best

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        return self._behaviors

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        plan = _Plan(self.home)
        info: dict[str, object] = {}
        if name == "move_to_pose":
            q = self.poses[str(params["pose"])].copy()
            self._joint(plan, "move", q)
            target = self.gripper_position(q)
            if self.six:
                info["orientation_rpy"] = tuple(
                    float(a) for a in rpy_yaw_at_gimbal_lock(self.tool_rotation(q))
                )
            return self._finish(name, plan, info, target)
        P = {k: float(v) for k, v in params.items()}  # type: ignore[arg-type]
        if name in ("pointing", "scanning"):
            el = P["elevation"]
            stops = (
                [P["azimuth"]]
                if name == "pointing"
                else list(np.linspace(P["from_azimuth"], P["to_azimuth"], int(P["stops"])))
            )
            for k, az in enumerate(stops):
                q = plan.last
                q[: self.na] = self.point(float(az), el, q[: self.na])
                self._joint(plan, f"point {k + 1}" if len(stops) > 1 else "point", q)
            # held still a moment, the servos' read-back integrated (gaits.feedback): the
            # tool's tip swings with the chain's whole length; on a 3-joint probe arm's
            # perturbed runs (seeds 1-3) the open loop ended 6.1-6.5 mm off, the loop
            # 5.7-6.3 mm (the play's own sag is out of the read-back's sight)
            self._joint(plan, "hold", plan.last)
            info["feedback"] = dict(POINTING_FEEDBACK)
            info["direction_rad"] = (float(stops[-1]), el)
            return self._finish(name, plan, info, self.gripper_position(plan.last))
        if name == "pick-and-place":
            pick = np.array([P["pick_x"], P["pick_y"], P["pick_z"]])
            place = np.array([P["place_x"], P["place_y"], P["place_z"]])
            up = np.array([0.0, 0.0, P["clearance"]])
            self._grasp(plan, pick, up)
            self._line(plan, "lift", pick, pick + up, self._rot(pick))
            q_above = self._ik_near(place + up, self._rot(place), plan.last)
            self._joint(plan, "move", q_above)
            self._line(plan, "descend", place + up, place, self._rot(place))
            self._gripper(plan, "open", self.upper[-1])
            info["placed_at_s"] = plan.now
            if P["retreat"] > 0:
                rise = np.array([0.0, 0.0, P["retreat"]])
                self._line(plan, "retreat", place, place + rise, self._rot(place))
            info["pick"] = tuple(float(c) for c in self.base_position + pick)
            target = place
        elif name == "grasping":
            target = np.array([P["x"], P["y"], P["z"]])
            up = np.array([0.0, 0.0, P["clearance"]])
            self._grasp(plan, target, up)
            info["grasped_at_s"] = plan.now
            info["placed_at_s"] = plan.now  # the gripper closes on the object here
            self._line(plan, "lift", target, target + up, self._rot(target))
        elif name in ("positioning", "move_to", "orienting"):
            target = np.array([P["x"], P["y"], P["z"]])
            R = matrix_from_rpy((P["roll"], P["pitch"], P["yaw"])) if self.six else None
            self._joint(plan, "move", self._ik_near(target, R, plan.last))
            if R is not None:
                info["orientation_rpy"] = (P["roll"], P["pitch"], P["yaw"])
        else:  # pragma: no cover - run() checks the names
            raise ValueError(f"unknown behaviour {name!r}")
        return self._finish(name, plan, info, target)

    def _finish(
        self, name: str, plan: _Plan, info: dict[str, object], target: np.ndarray
    ) -> Trajectory:
        """The promise (``info``) and the trajectory. A tool that orients is measured on
        its own body: the target is then that body's origin where the plan holds the
        gripper on ``target`` (the same point on the part kinds' arms)."""
        info["motion"] = "orient" if "orientation_rpy" in info else "place"
        info["tool_body"] = self.chain.tool_body if self.six else self.chain.end_body
        measured = np.asarray(target, dtype=float)
        if self.six and np.any(self.chain.tool_offset != 0):
            at = plan.at(float(info.get("placed_at_s", plan.now)))
            measured = measured - self.tool_rotation(at) @ self.chain.tool_offset
        info["target"] = tuple(float(c) for c in self.base_position + measured)
        info["target_base"] = tuple(float(c) for c in target)
        info["base_position"] = tuple(float(c) for c in self.base_position)
        return self._trajectory(name, plan, info)

    def _rot(self, position: np.ndarray) -> np.ndarray | None:
        return self.down(position) if self.six else None

    def _grasp(self, plan: _Plan, obj: np.ndarray, up: np.ndarray) -> None:
        """Approach above ``obj`` (joint space), descend onto it, close the gripper."""
        self._check_floor(obj, "object")
        self._joint(plan, "approach", self._ik_near(obj + up, self._rot(obj), plan.last))
        self._line(plan, "descend", obj + up, obj, self._rot(obj))
        self._gripper(plan, "close", self.lower[-1])

    def _check_floor(self, p: np.ndarray, what: str) -> None:
        z = float(self.base_position[2] + p[2])
        if z < FLOOR_CLEARANCE - 1e-9:
            raise ValueError(
                f"{what} at z = {p[2]:.4f} m (base frame) is {z:.4f} m above the floor; the "
                f"gripper needs {FLOOR_CLEARANCE} m (base at {self.base_position[2]:.4f} m)"
            )

    def _ik_near(
        self,
        p: np.ndarray,
        R: np.ndarray | None,
        q: np.ndarray,
        elbow: str | None = None,
        refine: int = 50,
    ) -> np.ndarray:
        """Full configuration (arm by IK near ``q``, gripper as in ``q``)."""
        self._check_floor(p, "target")
        out = q.copy()
        out[: self.na] = self.ik(p, R, q[: self.na], elbow, refine)
        return out

    # --- segments ------------------------------------------------------------------------

    def _duration(self, dq: np.ndarray, ddq: np.ndarray) -> float:
        """Seconds so that peaks |dq/dtau| / T and |ddq/dtau^2| / T^2 (per joint) stay in
        the speed and acceleration limits."""
        T_v = float(np.max(dq / self.speed))
        T_a = math.sqrt(float(np.max(ddq)) / self.max_acceleration)
        return max(MIN_SEGMENT, T_v, T_a)

    @staticmethod
    def _grid(T: float) -> np.ndarray:
        return np.linspace(0.0, 1.0, max(3, math.ceil(T / SAMPLE_DT)) + 1)

    def _joint(self, plan: _Plan, name: str, q1: np.ndarray) -> None:
        """Minimum-jerk joint-space segment from the plan's last configuration to ``q1``."""
        q0 = plan.last
        d = q1 - q0
        T = self._duration(np.abs(d) * _PEAK_SPEED, np.abs(d) * _PEAK_ACCEL)
        tau = self._grid(T)
        s, ds, dds = min_jerk(tau)
        q = q0 + np.outer(s, d)
        self._check_path(name, q)
        plan.add(name, tau, T, q, np.outer(ds, d), np.outer(dds, d))

    def _gripper(self, plan: _Plan, name: str, angle: float) -> None:
        q1 = plan.last
        q1[-1] = angle
        self._joint(plan, name, q1)

    def _line(self, plan: _Plan, name: str, p0, p1, R: np.ndarray | None) -> None:
        """Minimum-jerk straight line of the gripper from ``p0`` to ``p1`` (base frame) at
        constant tool orientation; joint velocities and accelerations by differentiating
        the closed-form IK along the path (four times finer, central differences)."""
        q_start = plan.last
        # closed forms: stay on the start's elbow branch; the numerical IK starts each
        # sample from the one before (and spends few iterations keeping off the limits)
        elbow = ("up" if q_start[2] >= 0 else "down") if self.closed is not None else None
        p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)

        def path(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            fine = np.linspace(0.0, 1.0, 4 * (len(tau) - 1) + 1)
            s = min_jerk(fine)[0]
            q = np.empty((len(fine), len(q_start)))
            ref = q_start
            for k, sk in enumerate(s):  # on the start's elbow branch, the wrist nearest
                q[k] = self._ik_near(p0 + sk * (p1 - p0), R, ref, elbow, LINE_REFINE)
                ref = q[k]
            jump = float(np.max(np.abs(np.diff(q, axis=0)))) if len(q) > 1 else 0.0
            if jump > MAX_STEP:
                raise ValueError(
                    f"segment {name!r}: the arm would jump {jump:.3f} rad between samples "
                    "(a wrist or elbow singularity on the line); choose other targets"
                )
            dq = np.gradient(q, fine, axis=0, edge_order=2)
            dq[[0, -1]] = 0.0  # exact: the profile's s' vanishes at both ends
            ddq = np.gradient(dq, fine, axis=0, edge_order=2)
            ddq[[0, -1]] = 0.0
            return q[::4], dq[::4], ddq[::4]

        _, dq, ddq = path(np.linspace(0.0, 1.0, 101))
        T = self._duration(np.abs(dq).max(axis=0), np.abs(ddq).max(axis=0))
        tau = self._grid(T)
        q, dq, ddq = path(tau)
        if np.max(np.abs(q[0] - q_start)) > 1e-6:
            raise ValueError(f"{name}: the line starts off the previous segment's end")
        q[0] = q_start
        self._check_path(name, q)
        plan.add(name, tau, T, q, dq, ddq)

    def _check_path(self, name: str, q: np.ndarray) -> None:
        if np.any(q < self.lower - 1e-9) or np.any(q > self.upper + 1e-9):
            raise ValueError(f"segment {name!r} leaves the joint limits")
        z = self.gripper_position(q)[:, 2] + self.base_position[2]
        if float(z.min()) < FLOOR_CLEARANCE - 1e-6:
            raise ValueError(
                f"segment {name!r} brings the gripper {z.min():.4f} m above the floor "
                f"(needs {FLOOR_CLEARANCE} m)"
            )

    def _trajectory(self, name: str, plan: _Plan, info: dict[str, object]) -> Trajectory:
        t, q, qd, qdd = plan.arrays()
        info["segments"] = tuple(plan.segments)
        info["accelerations"] = qdd
        positions = q
        if self.stiffness is not None:
            g = self.gravity(q) if self.gravity is not None else gravity_torques(self.model, q)
            droop = g / self.stiffness
            positions = np.clip(q + droop, self.lower, self.upper)
            info["planned_positions"] = q
        return Trajectory(name, t, self.joints, positions, qd, info)

    # --- plain-parameter shortcuts ---------------------------------------------------------

    def move_to(self, x: float, y: float, z: float, **orientation: float) -> Trajectory:
        """``positioning`` to (x, y, z) m, base frame (6-DOF: optional roll, pitch, yaw)."""
        return self.run("positioning", x=x, y=y, z=z, **orientation)

    def pick_and_place(
        self, pick: Sequence[float], place: Sequence[float], **options: float
    ) -> Trajectory:
        """``pick-and-place`` from ``pick`` (3,) m to ``place`` (3,) m, base frame."""
        px, py, pz = pick
        qx, qy, qz = place
        return self.run(
            "pick-and-place",
            pick_x=px,
            pick_y=py,
            pick_z=pz,
            place_x=qx,
            place_y=qy,
            place_z=qz,
            **options,
        )

    def peak_torques(self, traj: Trajectory) -> dict[str, float]:
        """:func:`peak_torques` of ``traj`` on this controller's dynamics model."""
        return peak_torques(traj, self.model)
