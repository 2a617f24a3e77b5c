"""Feedback around a planned motion: the loops a design's firmware closes on what it senses.

A behaviour's plan (:class:`gaits.base.Trajectory`) sizes the actuators and gives ROS and the
block page their parameters; the robot follows it through a *loop* that, at the design's
control rate, reads what the design can measure and corrects the commands around the plan
(ros_control's split: the controller reads the hardware's state interfaces, writes its
command interfaces). The loop is data in the plan (``Trajectory.info["feedback"]``, a plain
mapping: ``{"loop": KIND, ...its gains}``), so a cached or re-planned trajectory carries it,
and every runner of a plan (``parmor design``'s verification, ``parmor simulate``,
``parmor run``, the ROS node and the block page through :mod:`program.session`) runs the
same loop: :func:`loop_for` builds it, :mod:`synth.verification.simulate` feeds it.

What a loop may read (:class:`Reading`), as the hardware gives it:

- the servos' positions and speeds (``q``, ``qd``: each joint of the plan, in its order; a
  wheel's continuous rotation is its encoder);
- where the design carries an IMU (an ``IMUSensorModule`` of the catalog, required by the
  ontology for the abilities that need it), the gyro's rates and the accelerometer's
  specific force in the IMU's frame, with the datasheet's noise and a per-run bias in a
  perturbed run, and the attitude the firmware estimates from them (:class:`Attitude`, a
  complementary filter: the gyro integrated, its tilt pulled towards the accelerometer's
  gravity direction). No loop reads the simulator's true pose.

What it writes: offsets (rad for position servos, rad/s for wheels) added to the plan's
commands for the next control period; they reach the servos after the bus's latency. The
period, the latency and the noise are the runner's (:func:`synth.verification.simulate.simulate`).

A loop kind is a class registered with :func:`register`; the controllers (chosen by the
design's structure, never by a type's name) put the kind and its gains in their plans. Pure
numpy: gaits import nothing of MuJoCo.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

#: s: the main module's control loop (50 Hz), the period at which a loop reads and corrects
#: when the runner has no other (the perturbation table's ``[bus] control_period``)
CONTROL_PERIOD_S = 0.02
#: the catalog class whose modules are inertial measurement units
IMU_CLASS = "IMUSensorModule"


@dataclass(frozen=True)
class Reading:
    """What the design measures at time ``t`` (s since the behaviour began)."""

    t: float
    q: np.ndarray  # (nj,) rad: the plan's joints, in its order (servo read-back, encoders)
    qd: np.ndarray  # (nj,) rad/s
    gyro: np.ndarray | None = None  # (3,) rad/s in the IMU frame; None without an IMU
    accel: np.ndarray | None = None  # (3,) m/s^2 specific force in the IMU frame
    attitude: np.ndarray | None = None  # (4,) w x y z: the firmware's estimate, world <- IMU


class Attitude:
    """The firmware's attitude estimate from a gyro and an accelerometer: a complementary
    filter (Mahony et al. 2008 without the integral term). The gyro's rate is integrated;
    the tilt is pulled towards the accelerometer's gravity direction with gain ``k`` (1/s)
    while the measured specific force is within ``trust`` of 1 g. Yaw is the gyro's alone
    (an MPU-6050 has no magnetometer), so it drifts with the gyro's bias."""

    def __init__(self, k: float = 2.0, trust: float = 0.25) -> None:
        self.k, self.trust = k, trust
        self.q: np.ndarray | None = None

    def reset(self, quat: np.ndarray) -> None:
        """Start from ``quat`` (w x y z): the pose the robot is switched on in, levelled by the
        firmware's start-up calibration."""
        self.q = np.asarray(quat, dtype=float) / float(np.linalg.norm(quat))

    def update(self, gyro: np.ndarray, accel: np.ndarray, dt: float) -> np.ndarray:
        q = self.q if self.q is not None else np.array([1.0, 0.0, 0.0, 0.0])
        w = np.asarray(gyro, dtype=float).copy()
        a = np.asarray(accel, dtype=float)
        na = float(np.linalg.norm(a))
        if na > 0 and abs(na / 9.81 - 1.0) < self.trust:
            # gravity's direction ("up" in the IMU frame) as the estimate predicts it
            up = _rotate_inv(q, np.array([0.0, 0.0, 1.0]))
            w = w + self.k * np.cross(a / na, up)
        q = q + 0.5 * dt * _qmul(q, np.array([0.0, *w]))
        self.q = q / float(np.linalg.norm(q))
        return self.q


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def _rotate_inv(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` (world) in the frame of the rotation ``q`` (w x y z)."""
    w, x, y, z = q
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    return r.T @ v


def roll_pitch_yaw(q: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) rad of a w x y z quaternion (z-y-x Euler angles)."""
    w, x, y, z = (float(c) for c in q)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


class Loop(ABC):
    """One feedback loop around one plan. ``joints`` are the plan's joints, ``spec`` its
    ``info["feedback"]``; ``times``/``positions``/``velocities`` the plan's samples.

    ``spec["gain_scale"]`` (default 1) multiplies every gain the loop names in
    :attr:`GAINS` (:meth:`gain`): the scale a design's robust verification chose for it
    (``design.json`` ``feedback_gains``, :mod:`synth.verification.gains`), put in the plan
    by its controller so that every runner of the plan runs the same gains."""

    #: True when the loop reads the IMU: a design without one is refused it
    needs_imu: bool = False
    #: the spec keys that are the loop's gains (what ``gain_scale`` multiplies)
    GAINS: tuple[str, ...] = ()

    def __init__(self, traj, spec: Mapping[str, object]) -> None:
        self.traj = traj
        self.spec = spec
        self.joints: tuple[str, ...] = tuple(traj.joints)
        self.gain_scale = float(spec.get("gain_scale", 1.0))  # type: ignore[arg-type]

    def gain(self, key: str, default: float) -> float:
        """The spec's ``key`` (``default`` when it has none), times ``gain_scale`` for a
        key of :attr:`GAINS`."""
        value = float(self.spec.get(key, default))  # type: ignore[arg-type]
        return value * self.gain_scale if key in self.GAINS else value

    def reset(self, first: Reading) -> None:  # noqa: B027 (optional hook)
        """Called once with the first reading, before any correction."""

    @abstractmethod
    def correct(self, r: Reading) -> np.ndarray:
        """(nj,) offsets to add to the plan's commands from now until the next reading."""

    def sample(self, t: float, table: np.ndarray) -> np.ndarray:
        """``table`` (samples x joints, on the plan's times) at ``t`` s, held after its end."""
        times = self.traj.times
        t = min(max(t, 0.0), float(times[-1]))
        return np.array([np.interp(t, times, table[:, k]) for k in range(len(self.joints))])

    def planned(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The plan's (positions, velocities) at ``t`` s (held after its end)."""
        return self.sample(t, self.traj.positions), self.sample(t, self.traj.velocities)


_LOOPS: dict[str, type[Loop]] = {}


def register(kind: str) -> Callable[[type[Loop]], type[Loop]]:
    """Class decorator: ``kind`` is built by this class."""

    def deco(cls: type[Loop]) -> type[Loop]:
        _LOOPS[kind] = cls
        return cls

    return deco


def loop_for(traj) -> Loop | None:
    """The feedback loop a plan asks for (``info["feedback"]``), or None for a plan run open
    loop. ValueError for a kind no module registers."""
    spec = traj.info.get("feedback")
    if not spec:
        return None
    _load_loops()
    kind = spec.get("loop")
    cls = _LOOPS.get(str(kind))
    if cls is None:
        raise ValueError(
            f"trajectory {traj.behavior!r}: unknown feedback loop {kind!r} "
            f"(known: {', '.join(sorted(_LOOPS))})"
        )
    return cls(traj, spec)


#: modules that register loop kinds (imported when a plan asks for a loop)
LOOP_MODULES: tuple[str, ...] = ("gaits.feedback", "gaits.wheel_feedback", "gaits.balance")


def _load_loops() -> None:
    from importlib import import_module

    for m in LOOP_MODULES:
        import_module(m)


def has_imu(sensors: tuple[str, ...] | list[str]) -> bool:
    """Whether a design whose sensor modules are of the classes ``sensors`` has an IMU."""
    return IMU_CLASS in sensors


@register("joint-hold")
class JointHold(Loop):
    """Servo read-back on position joints: an integral on each joint's measured error (plan -
    read-back) adds what the servo's proportional band loses under a steady load (a payload,
    gravity, a spring), bounded by ``limit_rad``. ``ki`` 1/s; ``joints`` (optional) names
    the joints it acts on (default: every position joint of the plan). A joint that moves
    fast (|planned speed| above ``moving_rad_s``) is left to its servo: the integral is
    frozen so it does not wind up on the servo's lag.

    The plan the error is taken against is where the joints should be: the plan's
    ``info["planned_positions"]`` when it has them (an arm's commands carry its servos'
    droop compensation, ``q + g / kp``: held to the commands, the integral would add the
    droop a second time and the tool would end off by as much)."""

    GAINS = ("ki",)

    def __init__(self, traj, spec: Mapping[str, object]) -> None:
        super().__init__(traj, spec)
        self.ki = self.gain("ki", 4.0)
        self.limit = float(spec.get("limit_rad", 0.15))  # type: ignore[arg-type]
        self.moving = float(spec.get("moving_rad_s", 0.5))  # type: ignore[arg-type]
        names = spec.get("joints")
        self.mask = np.array(
            [names is None or j in names for j in self.joints],  # type: ignore[operator]
            dtype=bool,
        )
        self.acc = np.zeros(len(self.joints))
        self.last_t: float | None = None

    def correct(self, r: Reading) -> np.ndarray:
        where = self.traj.info.get("planned_positions")  # where the joints should be
        q_plan = self.sample(r.t, np.asarray(self.traj.positions if where is None else where))
        v_plan = self.sample(r.t, self.traj.velocities)
        dt = 0.0 if self.last_t is None else r.t - self.last_t
        self.last_t = r.t
        still = np.abs(v_plan) < self.moving
        err = np.where(self.mask & still, q_plan - r.q, 0.0)
        self.acc = np.clip(self.acc + self.ki * err * dt, -self.limit, self.limit)
        return self.acc.copy()
