"""Wheeled robots (paper section 4.3.1): differential-drive and skid-steer kinematics and
the ``driving`` behaviour.

Kinematics (the paper's eqs. 5 and 6, for wheel radius ``r`` m, track ``l`` m and wheel
speeds ``q_l``, ``q_r`` rad/s, positive forward)::

    v = r (q_r + q_l) / 2          (m/s, forward speed of the chassis frame)
    w = r (q_r - q_l) / l          (rad/s, yaw rate, counter-clockwise positive; eq. 5)
    R = v / w = l (r q_r + r q_l) / (2 (r q_r - r q_l))   (m, turning radius; eq. 6)

A skid-steer robot drives each side's wheels at one speed and obeys the same equations
with an *effective* track ``l_eff = chi l`` (Mandow et al. 2007, "Experimental kinematics
for wheeled skid-steer mobile robots"): turning scrubs its wheels sideways, so it needs
more wheel-speed difference than a differential robot of the same track. For four wheels
at (+-a/2, +-l/2) with equal loads and isotropic Coulomb friction, the yaw moments of the
wheels' friction forces balance (steady turn in place) when the wheels roll at
``w (l/2) (1 + (a/l)^2)``, so ``chi = 1 + (a/l)^2`` (:func:`skid_steer_chi`); Mandow et al.
measured chi = 1.5 on a Pioneer 3-AT, whose wheel base and track give 1.46 by this formula.

The same balance holds on an arc (v, w) with front and rear wheels equally loaded: the
sides' longitudinal slips are then +-w a^2 / (2 l), so eq. 5 with ``l_eff`` gives the wheel
speeds of any (v, w), and each wheel carries the Coulomb torque ``mu N r a / sqrt(a^2 +
l^2)`` (driving on the outer side, braking on the inner) once its contact slides, at
``|w| a sqrt(a^2 + l^2) / (2 l)`` m/s, faster than the friction's creep speed
(:func:`creep_speed`: MuJoCo's soft contacts are viscous below it, so a gentle arc loads the
wheels in proportion to w, not with the full Coulomb torque).

Calibration. MuJoCo's skidding contacts do not follow the Coulomb balance: a skid-steer
turns as if its effective track were 1.1-1.35 x ``l_eff`` (and its wheels carry ~0.95 x the
load model's turning torque), so open-loop arcs and turns reached 0.83-1.3 of the command
over a grid of designs, depending on the design and the yaw rate. As Mandow et al. do on a
real robot, ``parmor design`` therefore measures it: the controller's probe runs
(:meth:`WheeledController.calibration_probes`: ``driving`` in place and on an arc) are
simulated, and the wheels' speeds (the joints' encoders), their servos' droop and the
chassis' yaw rate give the effective track and the load scale
(:meth:`WheeledController.calibrate`), which the design record keeps (``calibration``:
``effective_track_m``, ``turn_load_scale``) and the controller then uses instead of the
model's. A differential drive needs none.

Load feed-forward. A wheel servo is a DC motor line (MJCF velocity servo): under a load
torque tau it turns ``tau / kv`` slower than commanded (kv = stall torque / no-load speed).
The commands are therefore the wheel speeds plus that droop, from a quasi-static load
model of the design (:meth:`DriveGeometry.wheel_torques`): the chassis' inertia (with
its centre of mass off the wheels' middle: centripetal terms), the rotor's inertia
(``WHEEL_MOTOR_TIME_CONSTANT``), the caster sliding, each tyre scrubbing across its width
while the chassis turns, and a skid-steer's wheels scrubbing sideways. Without the
design's mass and stall torques (a bare geometry) the commands are the wheel speeds.

Everything is read from the design's template: the wheel radius, and the track and wheel
base from the wheel joints' positions on the chassis (``DriveGeometry.from_template``).
The root frame is the wheels' middle (a differential drive's axle centre), the point the
equations describe, so ``info["planned_pose"]`` is the root's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from gaits.base import (
    BehaviorSpec,
    Controller,
    DesignGeometry,
    Parameter,
    Trajectory,
    min_jerk,
    min_jerk_integral,
    quat_yaw,
)
from gaits.feedback import has_imu
from gaits.steering import SteerableSpec
from kinematics.dynamics import forward_kinematics
from kinematics.model import GRAVITY
from kinematics.templates import WHEEL_WIDTH, Template, TemplateParams, build

__all__ = [
    "DriveGeometry",
    "WheeledController",
    "body_velocity",
    "integrate_odometry",
    "min_jerk",
    "creep_speed",
    "skid_steer_chi",
    "turning_radius",
    "wheel_speeds",
]

#: Trajectory sample period, s (the simulation interpolates linearly between samples).
SAMPLE_DT = 0.01
#: Fraction of a wheel's no-load speed a command may ask for. The wheel servo is the DC
#: motor line (MJCF velocity servo, ``kv = stall torque / no-load speed``, commands within
#: +-no-load speed): under a load torque tau the wheel turns tau / kv slower than
#: commanded whatever the command, so the whole range is usable; on flat ground the
#: designed differential robot tracks 99 % of its top speed within 1 % (measured).
SPEED_MARGIN = 1.0
#: The load model's floor: tyre-on-floor Coulomb friction (the MJCF's wheel contact class and
#: the sizing use the same value) and the ball caster's (modelled as a low-friction slider,
#: as in the MJCF); gravity is the models' (kinematics.model.GRAVITY).
TYRE_FRICTION = 1.0
CASTER_FRICTION = 0.05
#: A turn in place of default duration peaks at this fraction of the wheels' top speed (at
#: their rims): slow enough for the chassis' inertia to stay a small load, fast enough
#: that the load model's error, and the droop a floor's slope or friction adds to the
#: servos' (which no open-loop command knows), stay small against the speed (0.25 before:
#: a differential drive's default turn passed 38 of 48 perturbed runs over a grid of
#: payloads and speeds, 46 at 0.5; ``bench/robust_wheel_grid.py``).
TURN_SPEED_FRACTION = 0.5
#: Lever of a tyre's scrub, as a fraction of the wheel's width: MuJoCo touches a level
#: cylinder on a plane at the two ends of its lowest line, each carrying half the wheel's
#: load, so a wheel turning about the vertical drags them +-width / 2 from its middle and
#: the Coulomb moment is mu N (width / 2).
SCRUB_LEVER = 0.5
#: The same for a skid-steer's wheels, whose contacts already slide across the wheel:
#: measured, not derived (the uncalibrated model's guess; a design's ``calibration`` scales
#: it with the rest of the turning load, see the module docstring).
SKID_SCRUB_LEVER = 0.25
#: Contacts of a wheel's rim with the floor (the cylinder's two ends, see SCRUB_LEVER).
CONTACTS_PER_WHEEL = 2
#: MuJoCo's default contact softness, which the MJCF keeps (``export.mjcf``): ``solref``'s
#: time constant s, ``solimp``'s impedance at zero penetration and its maximum, and the
#: cone's ``impratio``. They set the friction's regularised region (see :func:`creep_speed`).
SOLREF_TIMECONST = 0.02
SOLIMP_D0 = 0.9
SOLIMP_DMAX = 0.95
IMPRATIO = 1.0
#: Mechanical time constant (s) of a wheel servo's geared motor (``export.mjcf``'s
#: ``WHEEL_MOTOR_TIME_CONSTANT``, equal; a test checks it): accelerating the rotor by
#: ``alpha`` takes ``kv * tau alpha``, a droop of ``tau alpha`` rad/s.
WHEEL_MOTOR_TIME_CONSTANT = 0.05
#: Default minimum-jerk ramp of ``driving``, s (longer where the servos need it).
RAMP = 0.5
#: A skid-steer's calibration runs (:meth:`WheeledController.calibration_probes`): their
#: rim speed of turning, as fractions of the top speed tried in turn (the first the wheels
#: can drive with their load), how long each holds its speeds after the ramp, s, and how
#: long after the ramp the measurement starts, s (the yaw rate settles within ~0.3 s).
PROBE_RIM_FRACTIONS = (0.25, 0.15, 0.08)
PROBE_SECONDS = 2.0
PROBE_SETTLE = 0.5
#: s a turn's plan holds still after its heading profile ends, its feedback loop
#: (:mod:`gaits.wheel_feedback`) bringing the measured heading onto the angle asked
TURN_SETTLE_S = 1.0


def wheel_speeds(v: float, w: float, radius: float, track: float) -> tuple[float, float]:
    """(left, right) wheel speeds rad/s that drive the chassis at ``v`` m/s and yaw rate
    ``w`` rad/s (inverse of eq. 5); ``radius`` and ``track`` m (for a skid-steer robot
    pass its effective track)."""
    _check_geometry(radius, track)
    return (v - w * track / 2) / radius, (v + w * track / 2) / radius


def body_velocity(left: float, right: float, radius: float, track: float) -> tuple[float, float]:
    """(v m/s, w rad/s) of the chassis from the (left, right) wheel speeds rad/s (eq. 5)."""
    _check_geometry(radius, track)
    return radius * (right + left) / 2, radius * (right - left) / track


def turning_radius(left: float, right: float, radius: float, track: float) -> float:
    """Eq. 6: the signed radius m of the chassis frame's circle (positive: the centre is on
    the left); ``inf`` for equal wheel speeds (straight line), 0 for a turn in place."""
    _check_geometry(radius, track)
    diff = radius * right - radius * left
    if diff == 0:
        return math.inf
    return track * (radius * right + radius * left) / (2 * diff)


def integrate_odometry(
    times: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    radius: float,
    track: float,
    pose0: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Dead-reckoned poses (N, 3) ``(x m, y m, theta rad)`` from wheel speeds (N,) rad/s
    sampled at ``times`` (N,) s, starting at ``pose0``.

    Each interval moves the chassis along the exact arc of its mean (v, w) (trapezoidal
    wheel speeds), so piecewise-constant commands are integrated without error.
    """
    t = np.asarray(times, dtype=float)
    ql, qr = np.asarray(left, dtype=float), np.asarray(right, dtype=float)
    if t.ndim != 1 or ql.shape != t.shape or qr.shape != t.shape:
        raise ValueError("times, left and right must be 1-D arrays of one length")
    if len(t) and np.any(np.diff(t) <= 0):
        raise ValueError("times must rise")
    _check_geometry(radius, track)
    out = np.empty((len(t), 3))
    x, y, th = (float(c) for c in pose0)
    for k in range(len(t)):
        if k:
            dt = t[k] - t[k - 1]
            v, w = body_velocity((ql[k] + ql[k - 1]) / 2, (qr[k] + qr[k - 1]) / 2, radius, track)
            dth = w * dt
            # chord of the arc: length v dt sinc(dth / 2), along the mean heading
            chord = v * dt * (math.sin(dth / 2) / (dth / 2) if abs(dth) > 1e-12 else 1.0)
            x += chord * math.cos(th + dth / 2)
            y += chord * math.sin(th + dth / 2)
            th += dth
        out[k] = (x, y, th)
    return out


def skid_steer_chi(wheel_base: float, track: float) -> float:
    """Track expansion factor chi = l_eff / l of a skid-steer robot with wheel base ``a``
    and track ``l`` (m): ``1 + (a / l)^2`` (see the module docstring); 1 for a = 0 (a
    differential robot)."""
    _check_geometry(1.0, track)
    if wheel_base < 0:
        raise ValueError(f"wheel base must be >= 0, got {wheel_base}")
    return 1.0 + (wheel_base / track) ** 2


def creep_speed(friction: float, normal: float, inverse_weight: float) -> float:
    """The slip speed m/s below which MuJoCo's soft friction stays in its regularised
    (viscous) region: a contact of ``friction`` coefficient carrying ``normal`` N on a body
    of MuJoCo's ``body_invweight0`` ``inverse_weight`` 1/kg.

    A sliding contact's friction force satisfies ``R f = -b v`` in steady state (MuJoCo's
    soft constraints: ``b = 2 / (dmax timeconst)``, ``R = (1 - d) / d x`` the row's
    diagonal, the inverse weight; elliptic cone: the friction rows' R is the normal's over
    ``impratio``), so it grows linearly with the slip v up to the cone's ``mu N`` at
    ``v = mu N R / b``. A pyramidal cone's edge rows (diagonal ``(1 + mu^2)`` x) saturate
    at ``N R_edge / (2 mu b)``: the same for mu = 1 (tyres)."""
    d = SOLIMP_D0
    r = (1 - d) / d * inverse_weight / IMPRATIO
    b = 2 / (SOLIMP_DMAX * SOLREF_TIMECONST)
    return friction * normal * r / b


def _check_geometry(radius: float, track: float) -> None:
    if not (math.isfinite(radius) and radius > 0 and math.isfinite(track) and track > 0):
        raise ValueError(f"wheel radius and track must be positive, got {radius}, {track}")


@dataclass(frozen=True)
class DriveGeometry:
    """A wheeled design's drive: wheel joints per side, their sign, radius and tracks.

    ``left``/``right``: wheel joint names on each side (y > 0 is left); ``sign``: joint name
    -> +1 or -1, the sign of the joint speed that rolls the wheel forward (+x);
    ``radius`` m; ``track`` m between the side's wheel centres; ``wheel_base`` m between
    the front and rear wheels of a side (0 for one wheel a side); ``effective_track`` m,
    ``track * skid_steer_chi(wheel_base, track)`` (a calibrated design: the measured one);
    ``max_speed`` rad/s: the slowest wheel's usable speed (``SPEED_MARGIN`` times its
    no-load speed). The load model
    (:meth:`wheel_torques`) uses ``mass`` kg (0: unknown, no load feed-forward), ``kv``
    N m s (the wheel servo's motor line: stall torque / no-load speed), ``yaw_inertia``
    kg m^2 about the root's z, ``caster_x`` m (root frame; None without a caster),
    ``caster_share`` (of the weight on the caster), ``com_x`` m and ``creep`` m/s, the slip
    speed up to which a tyre's friction grows linearly (:func:`creep_speed`), and
    ``turn_load_scale``, the factor on the load of turning (scrub and skid; 1 but where a
    measured run calibrated it, see :meth:`WheeledController.calibrate`).
    """

    left: tuple[str, ...]
    right: tuple[str, ...]
    sign: Mapping[str, float]
    radius: float
    track: float
    wheel_base: float
    effective_track: float
    max_speed: float
    mass: float = 0.0
    kv: float = 0.0
    yaw_inertia: float = 0.0
    caster_x: float | None = None
    caster_share: float = 0.0
    com_x: float = 0.0
    creep: float = 0.0
    turn_load_scale: float = 1.0

    @classmethod
    def from_template(
        cls,
        template: Template,
        joint_speed: Mapping[str, float],
        mass: float = 0.0,
        joint_torque: Mapping[str, float] | None = None,
        layout: Template | None = None,
        payload: float = 0.0,
    ) -> DriveGeometry:
        """Read the drive off the template's wheel joints (positions in the chassis frame);
        ``mass`` kg and ``joint_torque`` (stall torques N m) enable the load model, whose
        mass layout is that of ``template`` with ``payload`` kg where ``layout`` (the
        template built with it) puts it."""
        m = template.model
        wheels = [j for j in m.joints if j.kind == "continuous"]
        if not wheels:
            raise ValueError(f"{template.robot_type} has no wheels")
        root = wheels[0].parent
        if any(j.parent != root for j in wheels):
            raise ValueError("the wheels must all hang on the chassis")
        pos = {j.name: j.origin[:3, 3] for j in wheels}
        sign = {}
        for j in wheels:
            axis = j.origin[:3, :3] @ j.axis  # chassis frame
            forward = np.cross(axis, (0.0, 0.0, 1.0))[0]  # hub speed along x per rad/s / r
            if abs(forward) < 1e-9:
                raise ValueError(f"wheel {j.name!r} does not roll along x")
            sign[j.name] = float(np.sign(forward))
        left = tuple(n for n, p in pos.items() if p[1] > 0)
        right = tuple(n for n, p in pos.items() if p[1] < 0)
        if not left or not right or len(left) + len(right) != len(wheels):
            raise ValueError("a wheeled robot needs wheels on both sides (y > 0 and y < 0)")
        track = float(np.mean([pos[n][1] for n in left]) - np.mean([pos[n][1] for n in right]))
        base = max(float(np.ptp([pos[n][0] for n in side])) for side in (left, right))
        speeds = [joint_speed.get(n, 0.0) for n in pos]
        if min(speeds) <= 0:
            missing = [n for n in pos if joint_speed.get(n, 0.0) <= 0]
            raise ValueError(f"no speed for the wheel(s) {', '.join(missing)} in the design")
        radius = float(template.params.wheel_radius)
        torque = joint_torque or {}
        stall = min((torque.get(n, 0.0) for n in pos), default=0.0)
        if mass <= 0 or stall <= 0:
            mass, kv, inertia, caster_x, share, com_x, creep = 0.0, 0.0, 0.0, None, 0.0, 0.0, 0.0
        else:
            kv = stall / min(speeds)
            inertia, caster_x, share, com_x, inv_weight = _mass_layout(
                template, mass, np.array([pos[n] for n in pos]), layout, payload
            )
            normal = mass * GRAVITY * (1 - share) / len(pos) / CONTACTS_PER_WHEEL
            creep = creep_speed(TYRE_FRICTION, normal, inv_weight)
        return cls(
            left,
            right,
            sign,
            radius,
            track,
            base,
            track * skid_steer_chi(base, track),
            SPEED_MARGIN * min(speeds),
            mass,
            kv,
            inertia,
            caster_x,
            share,
            com_x,
            creep,
        )

    @property
    def skid(self) -> bool:
        """True when a side has more than one wheel (the robot turns by skidding)."""
        return len(self.left) > 1 or len(self.right) > 1

    def wheel_speeds(self, v: float, w: float) -> tuple[float, float]:
        """(left, right) wheel speeds rad/s (forward positive) for (v m/s, w rad/s)."""
        return wheel_speeds(v, w, self.radius, self.effective_track)

    def body_velocity(self, left: float, right: float) -> tuple[float, float]:
        """(v m/s, w rad/s) from the sides' wheel speeds rad/s (forward positive)."""
        return body_velocity(left, right, self.radius, self.effective_track)

    def skid_torque(self) -> float:
        """The torque N m each wheel of a skid-steer robot exerts while it turns (Coulomb
        friction, equal loads): ``mu (m g / n) r a / sqrt(a^2 + l^2)``, driving on the outer
        side and braking on the inner (see the module docstring); 0 without skidding."""
        if not self.skid or self.mass <= 0:
            return 0.0
        n = len(self.left) + len(self.right)
        a, l_ = self.wheel_base, self.track
        return TYRE_FRICTION * self.mass * GRAVITY / n * self.radius * a / math.hypot(a, l_)

    def skid_slip(self) -> float:
        """Slip speed m/s of a skid-steer's wheel contact per rad/s of yaw (any v, equal
        loads): across the wheel ``w a / 2``, along it ``w a^2 / (2 l)`` (module
        docstring), together ``w a sqrt(a^2 + l^2) / (2 l)``; 0 without skidding."""
        if not self.skid:
            return 0.0
        a, l_ = self.wheel_base, self.track
        return a * math.hypot(a, l_) / (2 * l_)

    def scrub_moment(self) -> float:
        """The yaw moment N m all tyres' scrubbing resists a turn with (Coulomb): each wheel
        mu N_i SCRUB_LEVER WHEEL_WIDTH (a skid-steer's: SKID_SCRUB_LEVER), N_i its share of
        the weight (the caster's share off)."""
        load = self.mass * GRAVITY * (1 - self.caster_share)
        lever = SKID_SCRUB_LEVER if self.skid else SCRUB_LEVER
        return TYRE_FRICTION * load * lever * WHEEL_WIDTH

    def wheel_torques(
        self, v: np.ndarray, w: np.ndarray, accel: np.ndarray, alpha: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) torque N m on each wheel of a side (forward positive) to drive the
        chassis at ``v`` m/s and ``w`` rad/s while accelerating by ``accel`` m/s^2 and
        ``alpha`` rad/s^2 (arrays of one shape), on flat ground: the chassis' inertia, the
        caster's sliding friction and a skid-steer's scrubbing. Zero without a mass."""
        v, w = np.asarray(v, dtype=float), np.asarray(w, dtype=float)
        zero = np.zeros_like(v)
        if self.mass <= 0:
            return zero, zero
        # the chassis' equations of motion in its own frame, the root at the wheels' middle
        # (no side slip there) and the centre of mass at (com_x, 0): forward force
        # m (dv/dt - w^2 com_x), yaw moment I dw/dt + m com_x v w (I about the root)
        xg = self.com_x
        fx = self.mass * (np.asarray(accel, dtype=float) - w * w * xg)  # sides' forces, N
        mz = self.yaw_inertia * np.asarray(alpha, dtype=float) + self.mass * xg * v * w
        if self.caster_x is not None and self.caster_share > 0:
            # the caster slides where the chassis carries it: velocity (v, w x_c)
            cx, cy = v, w * self.caster_x
            speed = np.hypot(cx, cy)
            f = CASTER_FRICTION * self.caster_share * self.mass * GRAVITY
            scale = np.divide(f, speed, out=np.zeros_like(speed), where=speed > 1e-9)
            fx = fx + scale * cx
            mz = mz - self.caster_x * (-scale * cy)
        # each tyre's scrub while the chassis turns: mu N (SCRUB_LEVER x width) per wheel
        # (each rim contact slides +-w width / 2 along the wheel, a skid-steer's faster across
        # it; MuJoCo's friction is viscous below the creep speed)
        slip = w * max(WHEEL_WIDTH / 2, self.skid_slip())
        turn = self.turn_load_scale
        mz = mz + turn * self.scrub_moment() * np.clip(slip / (self.creep or 1e-12), -1, 1)
        left_f = fx / 2 - mz / self.track
        right_f = fx / 2 + mz / self.track
        skid = (
            turn * self.skid_torque() * np.clip(w * self.skid_slip() / (self.creep or 1e-12), -1, 1)
        )
        r = self.radius
        return (
            r * left_f / len(self.left) - skid,
            r * right_f / len(self.right) + skid,
        )

    def commands(
        self, v: np.ndarray, w: np.ndarray, accel: np.ndarray, alpha: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) servo commands rad/s (forward positive): the wheel speeds of eq. 5
        plus the droop of each servo's motor line under its load, ``torque / kv``, and
        while accelerating its rotor, ``WHEEL_MOTOR_TIME_CONSTANT`` x the wheel's
        acceleration."""
        v, w = np.asarray(v, dtype=float), np.asarray(w, dtype=float)
        half = self.effective_track / 2
        left = (v - w * half) / self.radius
        right = (v + w * half) / self.radius
        if self.kv > 0:
            tl, tr = self.wheel_torques(v, w, accel, alpha)
            a, al = np.asarray(accel, dtype=float), np.asarray(alpha, dtype=float)
            tau = WHEEL_MOTOR_TIME_CONSTANT
            left = left + tl / self.kv + tau * (a - al * half) / self.radius
            right = right + tr / self.kv + tau * (a + al * half) / self.radius
        return left, right

    def check_commands(self, left: np.ndarray, right: np.ndarray, what: str) -> None:
        """ValueError when a command exceeds ``max_speed``."""
        top = float(max(np.max(np.abs(left)), np.max(np.abs(right))))
        if top > self.max_speed * (1 + 1e-9):
            raise ValueError(
                f"{what} needs a wheel command of {top:.3g} rad/s (its speed plus the droop "
                f"of the servo under the load), above the usable {self.max_speed:.3g} rad/s "
                f"of the wheels ({SPEED_MARGIN:.0%} of their no-load speed)"
            )

    def check(self, v: float, w: float) -> None:
        """ValueError when (v, w) needs a wheel faster than ``max_speed`` (steady, loaded)."""
        left, right = self.commands(np.array([v]), np.array([w]), np.zeros(1), np.zeros(1))
        top = float(max(abs(left[0]), abs(right[0])))
        if top > self.max_speed * (1 + 1e-9):
            scale = self.max_speed / top
            raise ValueError(
                f"(v, w) = ({v:g} m/s, {w:g} rad/s) needs a wheel speed of {top:.3g} rad/s, "
                f"above the usable {self.max_speed:.3g} rad/s of the wheels "
                f"({SPEED_MARGIN:.0%} of their no-load speed); at most about "
                f"({v * scale:.3g}, {w * scale:.3g}) in this direction, v alone up to "
                f"{self.max_speed * self.radius:.3g} m/s"
            )


def _moments(template: Template) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass kg, first moment (3,) kg m, inertia (3, 3) kg m^2 about the root's origin) of
    the template's bodies at q = 0, in the root frame."""
    m = template.model
    T = forward_kinematics(m, np.zeros(m.nv))
    total, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    for k, b in enumerate(m.bodies):
        R, p = T[k, :3, :3], T[k, :3, 3]
        c = R @ np.asarray(b.com) + p
        total += b.mass
        first += b.mass * c
        second += R @ np.asarray(b.inertia) @ R.T + b.mass * (
            float(c @ c) * np.eye(3) - np.outer(c, c)
        )
    return total, first, second


def _mass_layout(
    template: Template,
    mass: float,
    wheels: np.ndarray,
    loaded: Template | None = None,
    payload: float = 0.0,
) -> tuple[float, float | None, float, float, float]:
    """(yaw inertia kg m^2 about the root's z, caster x m or None, the caster's share of
    the weight, the centre of mass' x m, the wheels' mean inverse weight 1/kg) of a robot
    of ``mass`` kg laid out as ``template``, whose masses are stand-ins: they are scaled to
    the design's ``mass`` less its ``payload`` kg, which sits where ``loaded`` (the template
    with the payload) puts it; ``wheels`` (n, 3) m: the wheel centres in the root frame.

    The inverse weight is MuJoCo's ``body_invweight0`` of a wheel on the free-floating
    robot taken as one rigid body: ``1 / m + trace(S I_c^-1 S^T) / 3``, ``S`` the cross
    product matrix of the wheel's offset from the centre of mass, ``I_c`` the inertia
    about it."""
    m0, h0, J0 = _moments(template)
    if loaded is not None and payload > 0:
        m1, h1, J1 = _moments(loaded)
        mp, hp, Jp = m1 - m0, h1 - h0, J1 - J0  # the payload's share
        scale = max(mass - mp, 0.0) / m0
    else:
        mp, hp, Jp = 0.0, np.zeros(3), np.zeros((3, 3))
        scale = mass / m0
    h, J = scale * h0 + hp, scale * J0 + Jp
    total = scale * m0 + mp
    com = h / total
    inertia = float(J[2, 2])
    I_c = J - total * (float(com @ com) * np.eye(3) - np.outer(com, com))
    inv = np.linalg.inv(I_c)
    weights = []
    for pw in np.asarray(wheels, dtype=float):
        S = _skew(pw - com)
        weights.append(1 / total + float(np.trace(S @ inv @ S.T)) / 3)
    inv_weight = float(np.mean(weights))
    com_x = float(com[0])
    axle_x = float(np.mean(np.asarray(wheels)[:, 0]))
    if not template.casters:
        return inertia, None, 0.0, com_x, inv_weight
    T = forward_kinematics(template.model, np.zeros(template.model.nv))
    caster_x = float(T[template.model.body(template.casters[0]), 0, 3])
    share = min(max((axle_x - com_x) / (axle_x - caster_x), 0.0), 1.0)
    return inertia, caster_x, share, com_x, inv_weight


def _skew(d: np.ndarray) -> np.ndarray:
    """The cross product matrix of ``d`` (3,)."""
    return np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])


class WheeledController(Controller):
    """Behaviours of a differential-drive or skid-steer design.

    - ``driving(v, w, seconds, ramp)``: reach the chassis speed ``v`` m/s and yaw rate
      ``w`` rad/s with a minimum-jerk ramp of ``ramp`` s, then hold them until ``seconds``;
      the wheels keep the commanded speeds after the trajectory's end (a velocity command
      stays in force until the next one, as with ROS's diff_drive_controller; run
      ``driving`` with v = w = 0 to stop). ``info["command"] = (v, w)``; motion
      ``"straight"`` (w = 0), ``"arc"`` or, for v = 0, ``"turn"``.
    - ``turning(angle, seconds)``: turn in place by ``angle`` rad (counter-clockwise
      positive) with a minimum-jerk heading profile, starting and ending at rest (ability
      ``driving``). ``info["heading_rad"] = angle``; motion ``"turn"``.

    ``info["planned_pose"]`` is the exact end pose of the commanded profile (the root is
    the point eq. 5 describes), ``info["path_length_m"]`` its arc length. The wheel
    velocities are servo commands: each wheel's speed plus the droop of its motor line
    under the predicted load (:meth:`DriveGeometry.wheel_torques`). Commands that need a
    wheel faster than the usable speed raise ValueError with the largest feasible command:
    clipping would silently drive a different path than the one asked.

    A design record's ``calibration`` (``effective_track_m``, ``turn_load_scale``; measured
    by :meth:`calibrate` on the runs of :meth:`calibration_probes`) replaces the model's
    effective track and scales its turning load, for a skid-steer.
    """

    def __init__(self, geometry: DesignGeometry) -> None:
        super().__init__(geometry)
        # the load model's mass layout: the template with the design's payload on the chassis
        layout = build(
            geometry.template,
            TemplateParams(
                lengths=geometry.lengths,
                modules=geometry.modules,
                wheel_radius=geometry.wheel_radius,
                payload=float(geometry.params.get("payload", 0.0)),
            ),
        )
        self.drive = DriveGeometry.from_template(
            self.template,
            geometry.joint_speed,
            geometry.mass_kg,
            geometry.joint_torque,
            layout=layout,
            payload=float(geometry.params.get("payload", 0.0)),
        )
        cal = geometry.calibration
        if self.drive.skid and cal:
            # measured on a run of this design (:meth:`calibrate`), it replaces the model's
            self.drive = replace(
                self.drive,
                effective_track=float(cal.get("effective_track_m", self.drive.effective_track)),
                turn_load_scale=float(cal.get("turn_load_scale", 1.0)),
            )
        #: m: where a skid-steer turning in place turns about, left of the wheels' middle
        #: (measured: :func:`_turn_centre`); its turns and arcs drive the chassis forward
        #: at ``-w centre_y`` more, so that the wheels' middle goes where eq. 5 says
        self.centre_y = float(cal.get("turn_centre_y_m", 0.0)) if self.drive.skid else 0.0
        self.joints = (*self.drive.left, *self.drive.right)

    def calibration_probes(self) -> list[tuple[str, dict[str, object]]]:
        """A skid-steer's calibration runs: ``driving`` in place and on an arc at one yaw
        rate (``PROBE_RIM_FRACTION`` of the top speed at the rims; the arc's forward speed
        as much again), ``PROBE_SECONDS`` long; none for a differential drive, whose
        kinematics hold (its wheels roll without skidding) or without the load model."""
        if not self.drive.skid or self.drive.kv <= 0:
            return []
        out: list[tuple[str, dict[str, object]]] = []
        for fraction in PROBE_RIM_FRACTIONS:  # the first that the wheels can drive
            w = 2 * fraction * self.v_max / self.drive.effective_track
            seconds = PROBE_SECONDS + self.default_ramp
            runs = [
                ("driving", {"v": v, "w": w, "seconds": seconds})
                for v in (0.0, fraction * self.v_max)
            ]
            try:
                for name, params in runs:
                    self.run(name, **params)  # plans (or refuses) it
            except ValueError:
                continue
            out = runs
            break
        return out

    def calibrate(self, runs: Sequence[tuple[Trajectory, Mapping[str, np.ndarray]]]) -> dict:
        """A skid-steer's ``effective_track_m`` and ``turn_load_scale`` from its measured
        probe runs (:meth:`calibration_probes`), as Mandow et al. calibrate a real one.

        Over each run's steady part (after the ramp and ``PROBE_SETTLE`` s) the measured
        yaw rate ``w`` and the sides' wheel speeds (the joints' encoders) give the track
        that eq. 5 needs, ``l_eff = r (q_r - q_l) / w`` (least squares over the runs), and
        each side's servo droop (command less speed) the torque it carried, ``kv x
        droop``; ``turn_load_scale`` fits the load model's turning part (scrub and skid)
        to those torques (least squares), its other part (caster, centripetal) kept.
        Empty when the runs do not turn (nothing to fit)."""
        d = self.drive
        if not d.skid or d.kv <= 0 or not runs:
            return {}
        num = den = t_num = t_den = 0.0
        for traj, series in runs:
            t = np.asarray(series["t"])
            ramp = float(traj.info.get("ramp_s", self.default_ramp))  # type: ignore[arg-type]
            steady = t >= ramp + PROBE_SETTLE
            if steady.sum() < 3:
                continue
            sign = np.array([d.sign[n] for n in traj.joints])
            speeds = np.polyfit(t[steady], np.asarray(series["q"])[steady], 1)[0] * sign
            cmd = traj.velocities[-1] * sign
            nl = len(d.left)
            left, right = float(np.mean(speeds[:nl])), float(np.mean(speeds[nl:]))
            root = np.asarray(series["root"])
            yaw = np.unwrap([quat_yaw(quat) for quat in root[:, 3:7]])
            w = float(np.polyfit(t[steady], yaw[steady], 1)[0])
            num += d.radius * (right - left) * w
            den += w * w
            v, w_cmd = (float(x) for x in traj.info["command"])  # type: ignore[union-attr]
            one = replace(d, turn_load_scale=1.0)
            zero = replace(d, turn_load_scale=0.0)
            t1 = one.wheel_torques(np.array([v]), np.array([w_cmd]), np.zeros(1), np.zeros(1))
            t0 = zero.wheel_torques(np.array([v]), np.array([w_cmd]), np.zeros(1), np.zeros(1))
            for k, got in enumerate((left, right)):
                side = cmd[:nl] if k == 0 else cmd[nl:]
                measured = d.kv * (float(np.mean(side)) - got)
                turn = float(t1[k][0] - t0[k][0])
                t_num += (measured - float(t0[k][0])) * turn
                t_den += turn * turn
        if den <= 0 or num <= 0 or t_den <= 0:
            return {}
        out = {
            "effective_track_m": round(num / den, 4),
            "turn_load_scale": round(max(t_num / t_den, 0.0), 3),
        }
        centre = _turn_centre(runs)
        if centre is not None:
            out["turn_centre_y_m"] = round(centre, 5)
        return out

    @property
    def v_max(self) -> float:
        """Top straight speed m/s within the usable wheel speed."""
        return self.drive.max_speed * self.drive.radius

    @property
    def w_max(self) -> float:
        """Top yaw rate rad/s of a turn in place within the usable wheel speed (unloaded)."""
        return 2 * self.v_max / self.drive.effective_track

    @cached_property
    def reach(self) -> tuple[float, float]:
        """(v m/s, w rad/s): the declared ranges of ``driving``: the largest straight speed
        and turn rate in place (either sense) that ``driving`` plans with its default ramp,
        the servos' droop under load and while accelerating included (bisection)."""

        def fits(v: float, w: float) -> bool:
            try:
                self._driving(v, w, max(1.0, 1.5 * self.default_ramp), self.default_ramp)
            except ValueError:
                return False
            return True

        def top(v: float, w: float) -> float:
            low, high = 0.0, 1.0
            while fits(high * v, high * w):
                low, high = high, 2 * high
            for _ in range(30):
                mid = (low + high) / 2
                low, high = (mid, high) if fits(mid * v, mid * w) else (low, mid)
            return low

        return (
            min(top(1.0, 0.0), top(-1.0, 0.0)),
            min(top(0.0, 1.0), top(0.0, -1.0)),
        )

    @cached_property
    def default_ramp(self) -> float:
        """The default ramp s: RAMP, or longer (by 25 % steps) until the servos can
        accelerate the robot to the default speed (their droop under the chassis' inertia
        fits within their no-load speed)."""
        v = round(self.v_max / 2, 3)
        ramp = RAMP
        for _ in range(30):
            t = _grid(2 * ramp)
            s, ds, _ = min_jerk(t / ramp)
            left, right = self.drive.commands(v * s, 0 * s, v * ds / ramp, 0 * s)
            if max(np.max(np.abs(left)), np.max(np.abs(right))) <= self.drive.max_speed:
                break
            ramp = round(ramp * 1.25, 2)
        return ramp

    @property
    def body_length(self) -> float:
        """The robot's length m: the chassis, or the wheels' span if longer."""
        d = self.drive
        return max(float(self.template.lengths.get("L1", 0.0)), d.wheel_base + 2 * d.radius)

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        v_max = self.v_max
        v_top, w_top = self.reach
        return {
            "driving": SteerableSpec(
                "driving",
                "Drive at forward speed v and yaw rate w (eqs. 5-6), ramping up smoothly.",
                (
                    Parameter(
                        "v",
                        "float",
                        round(v_max / 2, 3),
                        "forward speed",
                        "m/s",
                        low=-v_top,
                        high=v_top,
                    ),
                    Parameter(
                        "w",
                        "float",
                        0.0,
                        "yaw rate, counter-clockwise positive",
                        "rad/s",
                        low=-w_top,
                        high=w_top,
                    ),
                    Parameter("seconds", "float", 5.0, "duration", "s", low=0.05, high=3600),
                    Parameter(
                        "ramp",
                        "float",
                        self.default_ramp,
                        "minimum-jerk ramp-up time",
                        "s",
                        low=0.0,
                        high=60,
                    ),
                ),
                steer=(("speed", "v"), ("turn", "w"), ("seconds", "seconds")),
                fixed=(("ramp", 0.0),),
            ),
            "turning": BehaviorSpec(
                "turning",
                "Turn in place by an angle, starting and ending at rest.",
                (
                    Parameter(
                        "angle",
                        "float",
                        math.pi / 2,
                        "heading change, counter-clockwise positive",
                        "rad",
                        low=-4 * math.pi,
                        high=4 * math.pi,
                    ),
                    self._turn_seconds_parameter(),
                ),
                ability="driving",
            ),
        }

    def _turn_seconds_parameter(self) -> Parameter:
        """turning's ``seconds``: the design's own duration for the angle asked
        (:meth:`turn_seconds`), declared for the default quarter turn; from two samples
        (a smaller angle turns faster; a duration too short for the angle asked is refused
        with the shortest one) up to an hour."""
        try:
            _, own = self.turn_seconds(math.pi / 2)
        except ValueError:  # the servos cannot turn it: turning refuses every value
            own = 1.0
        return Parameter(
            "seconds",
            "float",
            own,
            f"duration (default: the design's own for the angle asked: peak rim speed "
            f"{TURN_SPEED_FRACTION:g} of the wheels' top speed)",
            "s",
            low=2 * SAMPLE_DT,
            high=3600,
            own=True,
        )

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        if name == "driving":
            return self._driving(
                float(params["v"]),
                float(params["w"]),
                float(params["seconds"]),
                float(params["ramp"]),
            )
        return self._turning(float(params["angle"]), float(params["seconds"]))

    def _driving(self, v: float, w: float, seconds: float, ramp: float) -> Trajectory:
        self.drive.check(v, w)
        if ramp > seconds:
            raise ValueError(f"ramp ({ramp} s) is longer than the drive ({seconds} s)")
        t = _grid(seconds)
        if ramp > 0:
            s, ds, _ = min_jerk(t / ramp)
            ds = ds / ramp
            dist = np.where(t < ramp, ramp * min_jerk_integral(t / ramp), ramp / 2 + (t - ramp))
        else:
            s, ds, dist = np.ones_like(t), np.zeros_like(t), t
        # a skid-steer's wheels drive its measured turn centre's offset out (0: none)
        u = v - self.centre_y * w
        left, right = self.drive.commands(u * s, w * s, u * ds, w * ds)
        self.drive.check_commands(left, right, f"driving at ({v:g} m/s, {w:g} rad/s)")
        # the exact end pose: the path is one circle (curvature w / v), travelled for the
        # integral of the profile, D = seconds - ramp / 2
        D = float(dist[-1])
        yaw = w * D
        if w == 0:
            pose = (v * D, 0.0, 0.0)
        else:
            pose = (v / w * math.sin(yaw), v / w * (1 - math.cos(yaw)), yaw)
        info: dict[str, object] = {
            "command": (v, w),
            "ramp_s": ramp,
            "planned_pose": pose,
            "path_length_m": abs(v) * D,
            "feedback": self.feedback_spec({"v": u, "w": w, "ramp": ramp, "seconds": seconds}),
        }
        if v == 0 and w == 0:
            info["motion"] = "hold"
        elif v == 0:
            info["motion"] = "turn"
        elif w == 0:
            info["motion"] = "straight"
            info["direction"] = (math.copysign(1.0, v), 0.0)
        else:
            info["motion"] = "arc"
        return self._trajectory("driving", t, left, right, info)

    def _turn_profile(self, angle: float, seconds: float):
        t = _grid(seconds)
        s, ds, dds = min_jerk(t / seconds)
        w = angle * ds / seconds
        alpha = angle * dds / seconds**2
        c = self.centre_y  # the measured turn centre's offset, taken out (0: none)
        return t, s, *self.drive.commands(-c * w, w, -c * alpha, alpha)

    def turn_seconds(self, angle: float) -> tuple[float, float]:
        """(the shortest, the design's own) duration s of turning in place by ``angle``
        rad: the shortest whose loaded wheel commands fit the wheels (peak rate 1.875
        angle / T, min-jerk; on a 1 % grid), and the own one, at least as long, whose peak
        rim speed is ``TURN_SPEED_FRACTION`` of the wheels' top speed (on the sample grid).
        ValueError when the servos cannot turn the robot at all."""
        shortest = max(1.875 * abs(angle) / self.w_max, SAMPLE_DT * 2)
        if angle != 0:
            for _ in range(400):
                _, _, left, right = self._turn_profile(angle, shortest)
                if max(np.max(np.abs(left)), np.max(np.abs(right))) <= self.drive.max_speed:
                    break
                shortest *= 1.01
            else:
                raise ValueError(
                    f"the wheels cannot turn the robot in place: their servos stall under "
                    f"the scrubbing torque ({self.drive.skid_torque():.3g} N m)"
                )
        rim = TURN_SPEED_FRACTION * self.v_max  # the peak rim speed
        own = max(shortest, 1.875 * abs(angle) * self.drive.effective_track / 2 / rim)
        own = max(round(math.ceil(own / SAMPLE_DT) * SAMPLE_DT, 9), SAMPLE_DT * 2)
        return shortest, own

    def _turning(self, angle: float, seconds: float) -> Trajectory:
        shortest, own = self.turn_seconds(angle)
        if seconds == 0:  # the design's own (gaits.base.AUTO)
            seconds = own
        elif seconds < shortest * (1 - 1e-9):
            raise ValueError(
                f"seconds: turning {angle:g} rad in {seconds:g} s needs a wheel speed above "
                f"the usable {self.drive.max_speed:.3g} rad/s; it takes at least {shortest:.3g} s"
            )
        t, _, left, right = self._turn_profile(angle, seconds)
        self.drive.check_commands(left, right, f"turning {angle:g} rad in {seconds:g} s")
        # the settling tail: the wheels' plan stands still, the loop ends the turn on the
        # measured heading
        tail = seconds + SAMPLE_DT * np.arange(1, int(round(TURN_SETTLE_S / SAMPLE_DT)) + 1)
        t = np.concatenate([t, tail])
        left = np.concatenate([left, np.zeros(len(tail))])
        right = np.concatenate([right, np.zeros(len(tail))])
        info = {
            "heading_rad": angle,
            "motion": "turn",
            "planned_pose": (0.0, 0.0, angle),
            "path_length_m": 0.0,
            "feedback": self.feedback_spec(
                {"angle": angle, "seconds": seconds}
                | ({"centre_y": self.centre_y} if self.centre_y else {})
            ),
        }
        return self._trajectory("turning", t, left, right, info)

    def feedback_spec(self, profile: Mapping[str, float], kind: str = "wheel-odometry") -> dict:
        """The plan's feedback loop (:mod:`gaits.wheel_feedback`): ``kind`` on the drive's
        wheels, for a ``profile`` (its heading and distance reference); the heading from
        the IMU where the design carries one (``DesignGeometry.sensors``), else from the
        wheels' odometry."""

        d = self.drive
        spec: dict[str, object] = {
            "loop": kind,
            "left": list(d.left),
            "right": list(d.right),
            "sign": {n: d.sign[n] for n in (*d.left, *d.right)},
            "radius_m": d.radius,
            "track_m": d.effective_track,
            "max_speed_rad_s": d.max_speed / SPEED_MARGIN,
        }
        if kind == "wheel-odometry":
            spec["profile"] = dict(profile)
            spec["imu"] = has_imu(self.geometry.sensors)
        return spec

    def _trajectory(
        self,
        name: str,
        t: np.ndarray,
        left: np.ndarray,
        right: np.ndarray,
        info: Mapping[str, object],
    ) -> Trajectory:
        """Wheel commands per side (forward positive) -> joint velocities with each joint's
        forward sign; positions are their integral (trapezoidal)."""
        side = {n: left for n in self.drive.left} | {n: right for n in self.drive.right}
        vel = np.column_stack([self.drive.sign[n] * side[n] for n in self.joints])
        steps = (vel[1:] + vel[:-1]) / 2 * np.diff(t)[:, None]
        pos = np.vstack([np.zeros((1, len(self.joints))), np.cumsum(steps, axis=0)])
        info = dict(info) | {
            "locomotion": "wheeled",
            "body_length_m": self.body_length,
            "radius_m": self.drive.radius,
            "effective_track_m": self.drive.effective_track,
        }
        return Trajectory(name, t, self.joints, pos, vel, info)


def _turn_centre(runs: Sequence[tuple[Trajectory, Mapping[str, np.ndarray]]]) -> float | None:
    """m: how far left of the wheels' middle (the root) a skid-steer turns about, from its
    calibration probe in place (``command`` v = 0): the root's path is a circle about that
    point, ``p(t) - p(0) = (I - R(yaw(t) - yaw(0))) c`` (c in the start's frame; least
    squares over the probe). Its ``y`` is what eq. 5's common mode can take out (the wheels
    drive the chassis along x; a centre ahead or behind would need a sideways push). None
    without an in-place probe that turned."""
    for traj, series in runs:
        v, w = (float(x) for x in traj.info.get("command", (1.0, 0.0)))  # type: ignore[union-attr]
        if v != 0 or w == 0:
            continue
        root = np.asarray(series["root"])
        yaw = np.unwrap([quat_yaw(q) for q in root[:, 3:7]])
        c0, s0 = math.cos(yaw[0]), math.sin(yaw[0])
        d = root[:, :2] - root[0, :2]
        d = np.column_stack([c0 * d[:, 0] + s0 * d[:, 1], -s0 * d[:, 0] + c0 * d[:, 1]])
        a = yaw - yaw[0]
        if float(np.ptp(a)) < 0.5:
            continue
        ca, sa = np.cos(a), np.sin(a)
        # rows: x = (1 - cos) cx + sin cy ; y = -sin cx + (1 - cos) cy
        m = np.vstack([np.column_stack([1 - ca, sa]), np.column_stack([-sa, 1 - ca])])
        c, *_ = np.linalg.lstsq(m, np.concatenate([d[:, 0], d[:, 1]]), rcond=None)
        return float(c[1])
    return None


def _grid(seconds: float) -> np.ndarray:
    """Sample times 0..seconds s at ``SAMPLE_DT`` (the last one exactly ``seconds``)."""
    n = max(2, int(math.ceil(seconds / SAMPLE_DT - 1e-9)) + 1)
    return np.linspace(0.0, seconds, n)
