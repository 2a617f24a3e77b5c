"""Running a behaviour on a design's MJCF model in MuJoCo, and measuring what it did.

The model comes from a bundle (``robot.xml`` and ``meshes/``); actuators are limited to the
catalog's stall torques by the MJCF itself. Position servos follow the trajectory's
positions, wheel servos its velocities (linear interpolation at every physics step).

Measured (keys of ``SimResult.to_dict``): ``distance_m`` (planar displacement of the root
body), ``heading_rad`` (change of its yaw), ``fell`` / ``fell_at_s`` (the root dropped
below ``COLLAPSE_HEIGHT`` of its start height or tilted past ``COLLAPSE_TILT``, see
:mod:`synth.verification.verdict`; never for the snake, whose rolling turns its body over, nor for a
fixed base), ``max_torque_ratio`` (largest
|actuator force| / stall torque), ``tracking_error`` (driving: relative error of the mean
(v, w) over the second half against the commanded ones), ``placing_error_m``
(manipulators: distance of the gripper from the trajectory's ``target`` when it let go,
``info["placed_at_s"]``, else at the end), ``support_margin_m`` (a behaviour that
promises a smallest static stability margin, ``info["min_stability_margin_m"]``: the
smallest measured one at the sampled states, :func:`support_margin_of`; None when an
instant had no contact; absent when not measured).

How a run is made (no Python per physics step):

- **The servo law is MuJoCo's own actuators**, as :mod:`export.mjcf` writes them: a
  ``<position>`` servo (``kp``, ``kv``, ``forcerange`` = the stall torque) per revolute
  joint, a ``<velocity>`` servo (``kv``, ``ctrlrange`` = the no-load speed) per wheel.
  The servo's torque-speed droop is the joint's passive ``damping`` (effort / no-load
  speed, the motor's back-EMF), outside the actuator, so MuJoCo's built-in types express
  the whole law exactly and no control callback is needed: the only inputs are the
  references.
- **The references are precomputed**: the trajectory is resampled once at every physics
  step into a control array (steps, nu) (the actuators the trajectory does not drive keep
  their controls), and :func:`step_through` feeds it to ``mujoco.rollout``, which calls
  ``mj_step`` in C and records the state after every step. It is the same physics as a
  Python loop of ``mj_step`` to the bit (same start state, warm start and controls; a run
  that the rollout stops at a MuJoCo warning is finished with ``mj_step``, as the loop
  would go on); a test checks it.
- **The verdict's figures come from the outcome, after the run**, vectorised in numpy
  over the recorded states: the actuators' effort before the clamp (``demand_ratio_max``)
  and the force they gave (``max_torque_ratio``, ``saturated_fraction``,
  ``saturated_joints``) by :class:`ServoLaw`, MuJoCo's actuator arithmetic applied to
  the recorded positions, velocities and controls of each step (equal to
  ``MjData.actuator_force`` to the bit, tested; an actuator it cannot reproduce is
  refused); the fall from the root's recorded height and tilt; the gripper's pose at
  ``placed_at_s`` by MuJoCo's kinematics of the recorded state. Against the former
  per-step loop the 22 behaviours of the base configurations' default designs give the
  same figures; only the demand series differ, by at most 4e-15 (summation order).
- **Chained and observed runs** (a program's session at 20 Hz, :mod:`program.session`):
  the rollout runs in chunks of ``observe_every`` s, and ``observe(t, data)`` is called
  after each with ``data`` exactly as after that many ``mj_step`` calls. Unobserved runs
  go in chunks of :data:`CHUNK_STEPS` (progress reports).

Cost (``bench/bench_simspeed.py``): ``simulate`` takes 0.9-1.2 x a bare ``mj_step`` loop
running the same controls on the same model (was 1.3-3.9 x).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from adron.errors import InputError
from gaits.base import Trajectory, quat_yaw
from gaits.feedback import CONTROL_PERIOD_S, Attitude, Reading, _qmul, loop_for
from gaits.hexapod import support_margin
from kinematics.spatial import matrix_from_rpy


@dataclass
class SimResult:
    behavior: str
    seconds: float
    distance_m: float
    heading_rad: float
    fell: bool
    fell_at_s: float | None
    max_torque_ratio: float
    tracking_error: float | None = None
    placing_error_m: float | None = None
    demand_ratio_max: float = 0.0
    saturated_fraction: float = 0.0
    planned_distance_m: float | None = None
    planned_heading_rad: float | None = None
    path_length_m: float | None = None
    final_pose_error_m: float | None = None
    orientation_error_rad: float | None = None
    drift_m: float | None = None
    min_height_ratio: float | None = None
    max_tilt_rad: float | None = None
    support_margin_m: float | None = None
    saturated_joints: dict[str, float] = field(default_factory=dict)  # actuator -> share
    verdict: list[str] = field(default_factory=list)
    complete: bool = True  # ran to the behaviour's end: its promise was judged too
    #: made again at the model's own step: at the coarse one a figure lay within the step's
    #: agreement of its limit (synth.verification.runs.near_limit)
    fine_step: bool = False
    series: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def ok(self) -> bool:
        return not self.verdict

    def to_dict(self) -> dict:
        def r(x):
            return None if x is None else float(f"{x:.6g}")

        out = {
            "behavior": self.behavior,
            "seconds": r(self.seconds),
            "verdict": "ok" if self.ok else list(self.verdict),
            "complete": self.complete,
            "distance_m": r(self.distance_m),
            "planned_distance_m": r(self.planned_distance_m),
            "heading_rad": r(self.heading_rad),
            "planned_heading_rad": r(self.planned_heading_rad),
            "path_length_m": r(self.path_length_m),
            "final_pose_error_m": r(self.final_pose_error_m),
            "drift_m": r(self.drift_m),
            "fell": self.fell,
            "fell_at_s": r(self.fell_at_s),
            "min_height_ratio": r(self.min_height_ratio),
            "max_tilt_rad": r(self.max_tilt_rad),
            "max_torque_ratio": r(self.max_torque_ratio),
            "demand_ratio_max": r(self.demand_ratio_max),
            "saturated_fraction": r(self.saturated_fraction),
            "saturated_joints": {k: r(v) for k, v in sorted(self.saturated_joints.items())},
            "tracking_error": r(self.tracking_error),
            "placing_error_m": r(self.placing_error_m),
            "orientation_error_rad": r(self.orientation_error_rad),
        }
        if self.support_margin_m is not None:  # measured (None then: no contact, no support)
            m = self.support_margin_m
            out["support_margin_m"] = r(m) if math.isfinite(m) else None
        if self.fine_step:
            out["fine_step"] = True
        return out


def check_agrees(xml: str, record: object) -> None:
    """InputError (exit 2) when ``design.json``'s ``record`` and the ``robot.xml`` text are
    not of one design: another robot type (the MJCF model's name), or other joint names
    (the MJCF's joints but the free one; each joint of the record is a joint there and each
    of the model's is in the record). Files of two designs in one folder would otherwise be
    simulated as one: the record's controller driving another robot's model. A record
    or model too malformed to compare is left to the checks that read them."""
    import xml.etree.ElementTree as ET

    if not isinstance(record, Mapping):
        return
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return  # load_mjcf says what is wrong with it
    fix = "the two files are of different designs; write both with 'parmor design ... --out DIR'"
    robot_type, model = record.get("robot_type"), root.get("model")
    if isinstance(robot_type, str) and robot_type != model:
        raise InputError(
            f"design.json: robot_type {robot_type!r}, but robot.xml is a model of {model!r}: " + fix
        )
    joints = record.get("joints")
    if not isinstance(joints, list):
        return
    named = {j.get("name") for j in joints if isinstance(j, Mapping)}
    passive = record.get("passive_joints")  # hinges no actuator drives (free wheels)
    if isinstance(passive, list):
        named |= {n for n in passive if isinstance(n, str)}
    modelled = {j.get("name") for j in root.iter("joint") if j.get("type", "hinge") != "free"}
    if named != modelled:

        def shown(names: set) -> str:
            listed = sorted(str(n) for n in names)
            return ", ".join(listed[:6]) + (
                f" and {len(listed) - 6} more" if len(listed) > 6 else ""
            )

        only = [
            f"{shown(named - modelled)} only in design.json" if named - modelled else "",
            f"{shown(modelled - named)} only in robot.xml" if modelled - named else "",
        ]
        raise InputError(
            f"design.json: its joints and robot.xml's differ ({'; '.join(o for o in only if o)}): "
            + fix
        )


def carrying_payload(xml: str, record: Mapping) -> str:
    """``robot.xml`` text with the design's payload (``record["payload"]``) as a point mass
    in each body that holds it, unless the models already carry it (``in_models``,
    ``parmor design --with-payload``): the robot is simulated as it was sized and verified,
    loaded."""
    import xml.etree.ElementTree as ET

    payload = record.get("payload") if isinstance(record, Mapping) else None
    if not isinstance(payload, Mapping) or payload.get("in_models"):
        return xml
    given = list(enumerate(payload.get("held_by") or ()))
    held = [(i, h) for i, h in given if float(h.get("mass_kg") or 0) > 0]
    if not held:
        return xml
    root = ET.fromstring(xml)
    bodies = {b.get("name"): b for b in root.iter("body")}
    for k, (i, h) in enumerate(held):
        body = bodies.get(h["body"])
        if body is None:  # (a reference to robot.xml: no schema of the record can check it)
            raise InputError(
                f"design.json: payload.held_by[{i}].body = {h['body']!r}: no body of robot.xml"
            )
        load = ET.Element(
            "body",
            name=f"payload_{k}",
            pos=" ".join(f"{float(x):.9g}" for x in h["position_m"]),
        )
        ET.SubElement(
            load,
            "inertial",
            pos="0 0 0",
            mass=f"{float(h['mass_kg']):.9g}",
            diaginertia=" ".join([f"{PAYLOAD_INERTIA * float(h['mass_kg']):.9g}"] * 3),
        )
        body.append(load)
    return ET.tostring(root, encoding="unicode")


#: m^2: a point payload's inertia per kg (a 3 cm radius of gyration: MuJoCo needs some)
PAYLOAD_INERTIA = 0.03**2
#: Physics steps per ``mujoco.rollout`` call when nobody observes the run: progress is
#: reported this often (1 s simulated at 2 ms), and a call's own cost (tens of
#: microseconds) is under 1 % of the stepping it does.
CHUNK_STEPS = 500
#: Physics steps between two looks at a run that may stop at its failure (``simulate``'s
#: ``stop_on_failure``): half a second at 2 ms.
STOP_CHECK_STEPS = 250
#: Physics steps measured at a time (20 s at 2 ms): the recorded states of a block (a few
#: MB) are all a run holds, whatever its duration.
BLOCK_STEPS = 10_000


def _tilt(quat: np.ndarray) -> float:
    w, x, y, z = quat
    up = 1 - 2 * (x * x + y * y)  # z component of the body's z axis
    return math.acos(max(-1.0, min(1.0, up)))


def support_margin_of(model, data) -> float:
    """The measured static stability margin m of ``data`` (contacts and centres of mass
    computed, as after ``mj_forward``): the signed distance of the robot's centre of mass
    (the root's subtree) over the ground to the nearest edge of the convex hull of the
    robot's contacts with the world (``gaits.hexapod.support_margin``; negative outside,
    minus infinity with no contact). The centre of mass is projected onto the contacts'
    plane along gravity: with the gravity turned by a floor's slope (``synth.verification.perturb``)
    the point it stands over moves downhill by its height x tan(slope), which a straight
    drop ignores (5 mm for a 10 cm high body on 3 deg); with gravity straight down the two
    are the same number."""

    n = data.ncon
    if n == 0:
        return -math.inf
    world = model.geom_bodyid[data.contact.geom[:n]] == 0
    touch = world[:, 0] != world[:, 1]
    if not touch.any():
        return -math.inf
    feet = data.contact.pos[:n][touch]
    com = data.subtree_com[1]
    g = model.opt.gravity
    if g[2] < 0 and (g[0] or g[1]):
        t = (float(feet[:, 2].mean()) - com[2]) / g[2]
        com = com + t * g
    return support_margin(feet[:, :2], com[:2])


def _rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) of the rotation between two rotation matrices."""
    c = (float(np.trace(a.T @ b)) - 1) / 2
    return math.acos(max(-1.0, min(1.0, c)))


class ServoLaw:
    """MuJoCo's actuator law of ``model``, vectorised over recorded states: the effort its
    actuators were asked for before the clamp to ``forcerange`` (:meth:`efforts`) and the
    force they gave (:meth:`forces`), from positions, velocities and controls.

    The same arithmetic, in the same order, as MuJoCo's ``mj_transmission`` and
    ``mj_fwdActuation`` for joint actuators without activation dynamics (what
    :mod:`export.mjcf` writes: ``<position>`` and ``<velocity>`` servos): ``ctrl`` clamped to
    ``ctrlrange``, ``length = gear q``, ``velocity = gear qdot``, ``effort = gain ctrl +
    (b0 + b1 length + b2 velocity)`` (an affine gain likewise), ``force = clip(effort,
    forcerange)``; equal to ``MjData.actuator_force`` to the bit (a test checks it).
    ValueError for other actuators."""

    def __init__(self, model) -> None:
        import mujoco

        affine_gain = model.actuator_gaintype == mujoco.mjtGain.mjGAIN_AFFINE
        no_bias = model.actuator_biastype == mujoco.mjtBias.mjBIAS_NONE
        ok = (
            (model.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT)
            & (model.actuator_dyntype == mujoco.mjtDyn.mjDYN_NONE)
            & (affine_gain | (model.actuator_gaintype == mujoco.mjtGain.mjGAIN_FIXED))
            & (no_bias | (model.actuator_biastype == mujoco.mjtBias.mjBIAS_AFFINE))
        )
        if not ok.all():
            bad = ", ".join(model.actuator(k).name for k in np.flatnonzero(~ok))
            raise ValueError(
                f"actuators {bad}: only joint actuators without activation dynamics and with "
                "a fixed or affine gain and bias can be simulated"
            )
        joint = model.actuator_trnid[:, 0]
        self.qadr = model.jnt_qposadr[joint]
        self.vadr = model.jnt_dofadr[joint]
        self.gear = model.actuator_gear[:, 0].copy()
        self.gain = model.actuator_gainprm[:, :3].copy()
        self.gain[~affine_gain, 1:] = 0.0
        self.affine_gain = bool(affine_gain.any())
        self.bias = model.actuator_biasprm[:, :3].copy()
        self.bias[no_bias] = 0.0
        clamp = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
        limited = model.actuator_ctrllimited.astype(bool) & clamp
        self.ctrl_lo = np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf)
        self.ctrl_hi = np.where(limited, model.actuator_ctrlrange[:, 1], np.inf)
        limited = model.actuator_forcelimited.astype(bool)
        self.force_lo = np.where(limited, model.actuator_forcerange[:, 0], -np.inf)
        self.force_hi = np.where(limited, model.actuator_forcerange[:, 1], np.inf)
        #: N m: what an actuator's |force| is measured against (its larger force bound)
        self.limit = np.maximum(np.abs(model.actuator_forcerange).max(axis=1), 1e-12)

    def efforts(self, qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray) -> np.ndarray:
        """(N, nu) N m asked of each actuator before its clamp, in states qpos (N, nq) and
        qvel (N, nv) under controls ctrl (N, nu)."""
        length = self.gear * qpos[:, self.qadr]
        velocity = self.gear * qvel[:, self.vadr]
        c = np.clip(ctrl, self.ctrl_lo, self.ctrl_hi)
        b, g = self.bias, self.gain
        bias = b[:, 0] + b[:, 1] * length + b[:, 2] * velocity
        gain = g[:, 0] + g[:, 1] * length + g[:, 2] * velocity if self.affine_gain else g[:, 0]
        return gain * c + bias

    def forces(self, effort: np.ndarray) -> np.ndarray:
        """(N, nu) N m the actuators gave: ``effort`` clamped to their force ranges."""
        return np.clip(effort, self.force_lo, self.force_hi)


def _user_inputs(model, data) -> int:
    """The ``mjtState`` bits of the inputs a rollout must be given at each step to keep what
    ``data`` holds (a rollout resets those it is not given): the controls, the mocap bodies'
    poses (a program's obstacle), and the applied forces and equality switches where they
    are not MuJoCo's defaults."""
    import mujoco

    s = mujoco.mjtState
    spec = int(s.mjSTATE_CTRL)
    if model.nmocap:
        spec |= int(s.mjSTATE_MOCAP_POS) | int(s.mjSTATE_MOCAP_QUAT)
    if data.qfrc_applied.any():
        spec |= int(s.mjSTATE_QFRC_APPLIED)
    if data.xfrc_applied.any():
        spec |= int(s.mjSTATE_XFRC_APPLIED)
    if model.neq and not np.array_equal(data.eq_active, model.eq_active0):
        spec |= int(s.mjSTATE_EQ_ACTIVE)
    return spec


def step_through(
    model,
    data,
    ctrl: np.ndarray,
    every: int = CHUNK_STEPS,
    after: Callable[[int], None] | None = None,
    sensed: np.ndarray | None = None,
) -> np.ndarray:
    """Step ``data`` ``len(ctrl)`` times under the controls ``ctrl`` (steps, nu), inside
    MuJoCo (``mujoco.rollout``) in runs of ``every`` steps, calling ``after(i)`` after each
    run (``i`` steps done; ``data`` is then as after ``i`` calls of ``mj_step``). Returns the
    state after each step, (steps, nstate) in ``mjSTATE_FULLPHYSICS`` layout; ``sensed``
    (steps, nsensordata), when given, receives ``data.sensordata`` after each step.

    The same physics as a loop of ``mj_step`` to the bit: each run starts from ``data``'s
    full state and its warm start. A run that MuJoCo stops at a warning (a rollout does,
    a plain loop goes on: a diverged state is reset) is finished with ``mj_step``."""
    import mujoco
    from mujoco import rollout

    steps = len(ctrl)
    full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    nstate = mujoco.mj_stateSize(model, full)
    states = np.empty((steps, nstate))
    state0 = np.empty((1, nstate))
    spec = _user_inputs(model, data)
    extra = spec & ~int(mujoco.mjtState.mjSTATE_CTRL)
    tail = np.empty(mujoco.mj_stateSize(model, extra)) if extra else None
    runner = rollout.Rollout(nthread=0)
    try:
        for a in range(0, steps, every):
            b = min(steps, a + every)
            mujoco.mj_getState(model, data, state0[0], full)
            controls = np.ascontiguousarray(ctrl[a:b], dtype=float)
            if tail is not None:
                mujoco.mj_getState(model, data, tail, extra)
                controls = np.hstack([controls, np.broadcast_to(tail, (b - a, len(tail)))])
            runner.rollout(
                [model],
                [data],
                state0,
                controls[None],
                control_spec=spec,
                skip_checks=True,
                nstep=b - a,
                initial_warmstart=data.qacc_warmstart[None].copy(),
                state=states[None, a:b],
                sensordata=None if sensed is None else sensed[None, a:b],
            )
            done = int(round((data.time - state0[0, 0]) / model.opt.timestep))
            for i in range(a + done, b):  # stopped at a warning: on as mj_step goes on
                data.ctrl[:] = ctrl[i]
                mujoco.mj_step(model, data)
                mujoco.mj_getState(model, data, states[i], full)
                if sensed is not None:
                    sensed[i] = data.sensordata
            if after is not None:
                after(b)
    finally:
        runner.close()
    return states


def simulate(
    model,
    traj: Trajectory,
    seconds: float | None = None,
    can_fall: bool = True,
    end_effector: str | None = None,
    progress: Callable[[float], None] | None = None,
    data=None,
    observe: Callable[[float, object], None] | None = None,
    observe_every: float | None = None,
    latency_s: float = 0.0,
    command_period_s: float = 0.0,
    sensor_noise: Mapping[str, object] | None = None,
    feedback: bool = True,
    stop_on_failure: bool = False,
) -> SimResult:
    """Run ``traj`` on ``model`` (a mujoco.MjModel) for ``seconds`` (default: the
    trajectory's duration; past its end the robot holds its final commanded state: its
    servos the last pose, its wheels stopped), measure what the robot did (the tracking
    error over the plan's time) and judge it against what ``traj.info`` promises
    (:func:`synth.verification.verdict.judge`; ``SimResult.verdict`` lists the failed criteria).

    ``data``: a ``mujoco.MjData`` to continue from (a program chaining behaviours): the
    robot is not reset to the trajectory's first pose, and the promise (planned pose,
    direction), given for a start at yaw 0, is turned by the yaw the robot starts with.
    ``observe(t, data)`` is called every ``observe_every`` s (rounded to whole physics
    steps; default: after every step) and after the last step, ``t`` s since this run
    began. ``progress(fraction)`` is called every :data:`CHUNK_STEPS` steps.

    ``latency_s``, ``command_period_s`` (a perturbed run, :mod:`synth.verification.perturb`): the
    servos get the references of ``latency_s`` earlier, held for each command period.

    A plan that asks for a feedback loop (``traj.info["feedback"]``, :mod:`gaits.feedback`)
    runs closed: every control period (``command_period_s``, else
    :data:`gaits.feedback.CONTROL_PERIOD_S`) the loop reads the design's sensors (servo
    read-back, wheel encoders, the IMU's gyro and accelerometer where the model carries
    them, with ``sensor_noise``: :func:`imu_noise`) and its correction reaches the servos
    ``latency_s`` later. ``feedback=False`` runs the plan open loop (what the plan alone
    does: the comparison the tests make).

    ``stop_on_failure``: the run stops as soon as its verdict is known to fail: the robot
    fell, or more than the verdict's share of the whole run's steps had an actuator at its
    limit (checked every :data:`STOP_CHECK_STEPS` steps); it is then judged on what it
    did up to there (``complete`` false: falling and saturation, the latter over the
    steps run). Only a run whose failure is all that is asked of it (a replay with one
    cause changed, a run that can only refuse) is stopped: a run that passes is the same
    to the bit either way."""
    import mujoco

    from synth.verification.verdict import (
        COLLAPSE_HEIGHT,
        COLLAPSE_TILT,
        MAX_SATURATED_FRACTION,
        SATURATION_LEVEL,
        judge,
    )

    chained = data is not None
    if data is None:
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
    seconds = traj.duration if seconds is None else seconds
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive finite number, got {seconds}")
    law = ServoLaw(model)
    free = model.njnt > 0 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    act = {model.actuator(k).name: k for k in range(model.nu)}
    columns = []
    for k, name in enumerate(traj.joints):
        if name not in act:
            raise ValueError(f"the model has no actuator for joint {name!r}")
        a = act[name]  # a velocity servo has no position term in its bias
        velocity = model.actuator_biasprm[a, 1] == 0 and model.actuator_biasprm[a, 2] != 0
        columns.append((k, a, bool(velocity)))
    if not chained:
        q0 = traj.positions[0]
        for k, a, _ in columns:  # start in the trajectory's first pose
            jid = model.actuator_trnid[a, 0]
            data.qpos[model.jnt_qposadr[jid]] = q0[k]
        mujoco.mj_forward(model, data)
    start = data.qpos[:3].copy() if free else np.zeros(3)
    com0 = data.subtree_com[1].copy() if free else np.zeros(3)
    yaw0 = quat_yaw(data.qpos[3:7]) if free else 0.0
    dt = model.opt.timestep
    steps = max(1, int(round(seconds / dt)))
    idx = np.array([a for _, a, _ in columns], dtype=int)
    qadr = model.jnt_qposadr[model.actuator_trnid[idx, 0]]
    held = data.ctrl.copy()  # the actuators the trajectory does not drive keep these
    placed_at = traj.info.get("placed_at_s")
    placed_step = None if placed_at is None else int(round(float(placed_at) / dt))
    placed_step = None if placed_step is None else min(placed_step, steps - 1)
    every = CHUNK_STEPS
    if observe is not None:
        every = 1 if observe_every is None else max(1, int(round(observe_every / dt)))
    closed = (
        _ClosedLoop.of(model, data, traj, columns, latency_s, command_period_s, sensor_noise)
        if feedback
        else None
    )
    if closed is not None:
        every = math.gcd(every, closed.period)
        start_closed(closed, data)
    observe_steps = 1 if observe_every is None else max(1, int(round(observe_every / dt)))
    # the run goes in blocks of whole observation periods, each measured once it is done:
    # memory stays that of a block whatever the duration
    block = max(1, (STOP_CHECK_STEPS if stop_on_failure else BLOCK_STEPS) // every) * every
    limit_steps = MAX_SATURATED_FRACTION * steps  # more saturated steps: it has failed
    done = steps
    full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    last = np.empty(mujoco.mj_stateSize(model, full))  # the state before the next step
    mujoco.mj_getState(model, data, last, full)
    nq, nv = model.nq, model.nv
    sample = np.arange(0, steps, max(1, steps // 500))  # and the last step
    if sample[-1] != steps - 1:  # (np.unique would import numpy.ma: 20-50 ms of start-up)
        sample = np.append(sample, steps - 1)
    judge_fall = free and can_fall
    # a behaviour that promises a static stability margin has it measured at the samples
    support = None
    if free and traj.info.get("min_stability_margin_m") is not None:
        support, support_min = mujoco.MjData(model), math.inf
    fell_at = min_height = max_tilt = None
    ratio = demand = 0.0
    saturated_steps = 0
    saturated_each = np.zeros(model.nu, dtype=int)
    placed_where = placed_rot = None
    series: dict[str, list[np.ndarray]] = {k: [] for k in ("t", "root", "q", "q_ref", "force")}
    series["demand"] = []
    if progress is not None:
        progress(0.0)
    for start_step in range(0, steps, block):
        n = min(block, steps - start_step)
        grid = (start_step + np.arange(n)) * dt
        # the references at every step; past the plan's end the robot holds its final
        # commanded state: the last pose, its wheels stopped
        ref = np.empty((n, len(columns)))
        ctrl = np.tile(held, (n, 1))
        sent = grid - latency_s  # when the command a servo acts on was sent
        if command_period_s > 0:
            sent = np.floor(sent / command_period_s + 1e-9) * command_period_s
        past = sent >= traj.times[-1]
        for c, (k, a, velocity) in enumerate(columns):
            ref[:, c] = np.interp(grid, traj.times, traj.positions[:, k])
            if velocity:
                ctrl[:, a] = np.interp(sent, traj.times, traj.velocities[:, k])
                ctrl[past, a] = 0.0
            elif latency_s or command_period_s:
                ctrl[:, a] = np.interp(sent, traj.times, traj.positions[:, k])
            else:
                ctrl[:, a] = ref[:, c]

        if closed is not None:
            closed.begin_block(ctrl, start_step, every)

        def after(i: int, offset: int = start_step, rows: np.ndarray = ctrl) -> None:
            done = offset + i
            if closed is not None:
                closed.after(data, done, rows)
            if observe is not None and (
                closed is None or done % observe_steps == 0 or done == steps
            ):
                observe(done * dt, data)
            if progress is not None and done // CHUNK_STEPS > (done - every) // CHUNK_STEPS:
                progress(done * dt / seconds)

        states = step_through(model, data, ctrl, every, after)
        before = np.vstack([last[None], states[:-1]])
        last = states[-1].copy()
        qpos_after = states[:, 1 : 1 + nq]

        # what the actuators were asked and gave at each step, from the recorded states
        effort = law.efforts(before[:, 1 : 1 + nq], before[:, 1 + nq : 1 + nq + nv], ctrl)
        demand_each = np.abs(effort) / law.limit
        force = law.forces(effort)
        force_each = np.abs(force) / law.limit
        at_limit = force_each >= SATURATION_LEVEL
        ratio = max(ratio, float(force_each.max(initial=0.0)))
        demand = max(demand, float(demand_each.max(initial=0.0)))
        saturated_steps += int(at_limit.any(axis=1).sum())
        saturated_each += at_limit.sum(axis=0)
        if judge_fall:
            height = qpos_after[:, 2] / start[2] if start[2] > 0 else np.ones(n)
            w, x, y, z = qpos_after[:, 3:7].T
            tilt = np.arccos(np.clip(1 - 2 * (x * x + y * y), -1.0, 1.0))
            down = np.flatnonzero((height < COLLAPSE_HEIGHT) | (tilt > COLLAPSE_TILT))
            if fell_at is None and len(down):
                fell_at = float(grid[down[0]])
            min_height = min(float(height.min()), math.inf if min_height is None else min_height)
            max_tilt = max(float(tilt.max()), 0.0 if max_tilt is None else max_tilt)
        let_go = None if placed_step is None else placed_step - start_step
        if end_effector is not None and let_go is not None and 0 <= let_go < n:
            # the gripper's pose in the state it let go from (MuJoCo's kinematics of it)
            pose = mujoco.MjData(model)
            mujoco.mj_setState(model, pose, before[let_go], full)
            mujoco.mj_kinematics(model, pose)
            eid = model.body(end_effector).id
            placed_where = pose.xpos[eid].copy()
            placed_rot = pose.xmat[eid].reshape(3, 3).copy()
        rows = sample[(sample >= start_step) & (sample < start_step + n)] - start_step
        if support is not None:
            for i in rows:
                # what the margin reads (the bodies' poses, the subtree centres of mass,
                # the contacts) to the bit as after mj_forward, at less than half its cost
                mujoco.mj_setState(model, support, states[i], full)
                mujoco.mj_kinematics(model, support)
                mujoco.mj_comPos(model, support)
                mujoco.mj_collision(model, support)
                support_min = min(support_min, support_margin_of(model, support))
        series["t"].append(grid[rows])
        series["root"].append(qpos_after[rows, :7] if free else np.zeros((len(rows), 7)))
        series["q"].append(qpos_after[np.ix_(rows, qadr)])
        series["q_ref"].append(ref[rows])
        series["force"].append(force[rows])
        series["demand"].append(demand_each[rows])
        if stop_on_failure and (fell_at is not None or saturated_steps > limit_steps):
            done = start_step + n  # the verdict is known: it failed
            break
    if done < steps:
        seconds = done * dt
    root = np.concatenate(series["root"])
    end = data.qpos[:3].copy() if free else np.zeros(3)
    heading = 0.0
    if free:  # unwrapped over the samples, so turns past 180 degrees count whole
        heading = float(np.unwrap([quat_yaw(r[3:7]) for r in root])[-1] - yaw0)
    result = SimResult(
        traj.behavior,
        seconds,
        float(np.hypot(*(end[:2] - start[:2]))),
        heading,
        fell_at is not None,
        fell_at,
        ratio,
        demand_ratio_max=demand,
        saturated_fraction=saturated_steps / done,
        saturated_joints={
            model.actuator(k).name: float(saturated_each[k] / done)
            for k in range(model.nu)
            if saturated_each[k]
        },
        min_height_ratio=min_height,
        max_tilt_rad=max_tilt,
        support_margin_m=None if support is None else support_min,
        series={k: np.concatenate(v) for k, v in series.items()},
    )
    info = traj.info
    motion = info.get("motion")
    turn = np.eye(2)
    if chained and free:  # the promise is given for a start at yaw 0
        turn = np.array([[math.cos(yaw0), -math.sin(yaw0)], [math.sin(yaw0), math.cos(yaw0)]])
    if free:
        plan = info.get("planned_pose")
        if plan is not None:
            dx, dy, dyaw = (float(c) for c in plan)  # type: ignore[union-attr]
            dx, dy = (float(c) for c in turn @ np.array([dx, dy]))
            result.planned_distance_m = math.hypot(dx, dy)
            result.planned_heading_rad = dyaw
            result.final_pose_error_m = float(
                np.hypot(end[0] - start[0] - dx, end[1] - start[1] - dy)
            )
            result.path_length_m = float(info.get("path_length_m") or math.hypot(dx, dy))  # type: ignore[arg-type]
            if motion == "straight" and result.planned_distance_m > 0:
                u = np.array([dx, dy]) / result.planned_distance_m
                result.distance_m = float((end[:2] - start[:2]) @ u)
        if motion == "crawl" and info.get("direction") is not None:
            # the whole body's progress: a snake's head swings with its wave
            u = turn @ np.asarray(info["direction"], dtype=float)[:2]
            u = u / max(float(np.linalg.norm(u)), 1e-12)
            result.distance_m = float((data.subtree_com[1][:2] - com0[:2]) @ u)
        if motion == "hold":
            result.drift_m = result.distance_m
    command = info.get("command")
    if command is not None and free:
        result.tracking_error = _tracking_error(result, command, traj.duration)
    target = info.get("target")
    if target is not None and end_effector is not None:
        # where the gripper let go (info "placed_at_s"), else where it ends
        eid = model.body(end_effector).id
        where = placed_where if placed_where is not None else data.xpos[eid]
        goal = np.array(target, dtype=float)
        if chained and free:  # given for a start at the spawn pose: moved with the robot
            spawn = model.body(1).pos[:2]
            goal[:2] = start[:2] + turn @ (goal[:2] - spawn)
        result.placing_error_m = float(np.linalg.norm(where - goal))
        rpy = info.get("orientation_rpy")
        if rpy is not None:
            rot = placed_rot if placed_rot is not None else data.xmat[eid].reshape(3, 3)
            base = data.xmat[1].reshape(3, 3)  # parameters are in the base frame
            result.orientation_error_rad = _rotation_angle(
                base @ matrix_from_rpy(tuple(float(c) for c in rpy)), rot
            )
    # a run stopped before the behaviour's end is judged on falling and saturation only
    result.complete = seconds >= traj.duration - 1e-9
    promise = info if result.complete else {}
    result.verdict = judge(result.to_dict(), promise, free and result.complete)
    return result


#: the MuJoCo sensors :mod:`export.mjcf` writes for a design's IMU (``IMUSensorModule``)
IMU_SENSORS = ("imu_gyro", "imu_accel")


def imu_sensors(model) -> tuple[int, int] | None:
    """The sensordata addresses of the model's IMU gyro and accelerometer, or None when the
    design carries no IMU."""
    names = {model.sensor(k).name: int(model.sensor_adr[k]) for k in range(model.nsensor)}
    if not all(n in names for n in IMU_SENSORS):
        return None
    return names[IMU_SENSORS[0]], names[IMU_SENSORS[1]]


def _level_quat(quat: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """The root's attitude (w x y z) in a frame whose z is up against ``gravity``: what the
    firmware's start-up levelling finds on a tilted floor (the world's yaw kept)."""
    g = -np.asarray(gravity, dtype=float)
    n = float(np.linalg.norm(g))
    if n == 0:
        return np.asarray(quat, dtype=float)
    g = g / n
    axis = np.cross(g, [0.0, 0.0, 1.0])
    s, c = float(np.linalg.norm(axis)), float(g[2])
    if s < 1e-12:
        return np.asarray(quat, dtype=float)
    half = math.atan2(s, c) / 2
    tilt = np.array([math.cos(half), *(math.sin(half) * axis / s)])

    return _qmul(tilt, np.asarray(quat, dtype=float))


class _ClosedLoop:
    """A plan's feedback loop (:mod:`gaits.feedback`) wired to a MuJoCo run: it reads the
    sensors every ``period`` steps and writes the corrected commands into the block's
    control rows ahead of the stepping, ``delay`` steps after the reading (the bus)."""

    def __init__(self, model, loop, columns, period: int, delay: int, imu, noise) -> None:
        self.model, self.loop, self.period, self.delay = model, loop, period, delay
        self.columns = columns
        idx = np.array([a for _, a, _ in columns], dtype=int)
        self.acts = idx
        joints = model.actuator_trnid[idx, 0]
        self.qadr = model.jnt_qposadr[joints]
        self.vadr = model.jnt_dofadr[joints]
        self.imu = imu
        self.noise = noise
        self.rng = None
        if noise:
            self.rng = np.random.default_rng([int(noise.get("stream", 0)), int(noise["seed"]), 1])
        self.attitude = None
        self.pending: list[tuple[int, np.ndarray]] = []  # (first step it acts, offsets)
        self.now = np.zeros(len(columns))
        self.base: np.ndarray | None = None
        self.offset = self.every = 0

    @classmethod
    def of(cls, model, data, traj, columns, latency_s, command_period_s, noise):
        loop = loop_for(traj)
        if loop is None:
            return None
        imu = imu_sensors(model)
        if loop.needs_imu and imu is None:
            raise ValueError(
                f"{traj.behavior}: its feedback loop reads an IMU the design does not carry"
            )
        dt = model.opt.timestep
        period = max(1, int(round((command_period_s or CONTROL_PERIOD_S) / dt)))
        delay = max(0, int(round(latency_s / dt)))
        return cls(model, loop, columns, period, delay, imu, noise)

    def reading(self, data, t: float):
        gyro = accel = att = None
        if self.imu is not None:
            g, a = self.imu
            gyro = data.sensordata[g : g + 3].copy()
            accel = data.sensordata[a : a + 3].copy()
            if self.noise:
                gyro += np.asarray(self.noise["gyro_bias_rad_s"], dtype=float)
                gyro += self.rng.normal(0.0, float(self.noise["gyro_std_rad_s"]), 3)
                accel += self.rng.normal(0.0, float(self.noise["accel_std_m_s2"]), 3)
            if self.attitude is None:
                self.attitude = Attitude()
                self.attitude.reset(_level_quat(data.qpos[3:7], self.model.opt.gravity))
                att = self.attitude.q
            else:
                att = self.attitude.update(gyro, accel, self.period * self.model.opt.timestep)
        return Reading(
            t=t,
            q=data.qpos[self.qadr].copy(),
            qd=data.qvel[self.vadr].copy(),
            gyro=gyro,
            accel=accel,
            attitude=None if att is None else att.copy(),
        )

    def begin_block(self, ctrl: np.ndarray, start: int, every: int) -> None:
        """A new block of controls (the plan's) from step ``start``, run in chunks of
        ``every`` steps: its first chunk's rows corrected."""
        self.base = ctrl.copy()
        self.offset, self.every = start, every
        self._fill(ctrl, 0, min(len(ctrl), every))

    def _fill(self, ctrl: np.ndarray, a: int, b: int) -> None:
        """Rows a..b of the block's controls: the plan's plus the offsets in force (rows
        between two changes of the offsets at once)."""
        acts = self.acts
        row = a
        while row < b:
            step = self.offset + row
            while self.pending and self.pending[0][0] <= step:
                self.now = self.pending.pop(0)[1]
            end = b if not self.pending else min(b, self.pending[0][0] - self.offset)
            ctrl[row:end, acts] = self.base[row:end, acts] + self.now
            row = end

    def after(self, data, done: int, ctrl: np.ndarray) -> None:
        dt = self.model.opt.timestep
        if done % self.period == 0:
            r = self.reading(data, done * dt)
            self.pending.append((done + self.delay, np.asarray(self.loop.correct(r), dtype=float)))
        a = done - self.offset
        self._fill(ctrl, a, min(len(ctrl), a + self.every))


def start_closed(closed, data) -> None:
    """The loop's first reading, before the first step."""
    if closed is None:
        return
    r = closed.reading(data, 0.0)
    closed.loop.reset(r)
    closed.pending.append((closed.delay, np.asarray(closed.loop.correct(r), dtype=float)))


TRACK_SCALE = 0.1  # m: turns a yaw-rate error into a speed error (half a track width)


def _tracking_error(result: SimResult, command, until: float = math.inf) -> float:
    """Relative error of the achieved mean (v, w) over the second half of the run, up to
    the plan's end ``until`` s (after it the robot holds still):
    |(v - v_cmd, b (w - w_cmd))| / |(v_cmd, b w_cmd)| with b = TRACK_SCALE."""
    v_cmd, w_cmd = command
    t, root = result.series["t"], result.series["root"]
    planned = t <= until + 1e-9
    t, root = t[planned], root[planned]
    if len(t) < 2:
        return float("inf")
    half = t >= t[-1] / 2
    if half.sum() < 2:
        return float("inf")
    dt = t[half][-1] - t[half][0]
    yaws = np.unwrap([quat_yaw(qq[3:7]) for qq in root[half]])
    dx = root[half][-1, :2] - root[half][0, :2]
    heading = np.array([math.cos(yaws.mean()), math.sin(yaws.mean())])
    v = float(dx @ heading) / dt
    w = float(yaws[-1] - yaws[0]) / dt
    b = TRACK_SCALE
    want = math.hypot(v_cmd, b * w_cmd)
    return math.hypot(v - v_cmd, b * (w - w_cmd)) / max(want, 1e-9)
