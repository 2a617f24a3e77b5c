"""Wheeled bases' feedback loops (``docs/feedback-wheels.md``): heading and distance closed
on the wheels' encoders and, where the design carries an IMU, on its yaw rate; a base told
to stand still holds its wheels where they stood.

A wheeled plan (:mod:`gaits.wheeled`, :mod:`gaits.compose`) commands each wheel a speed:
the wheel's share of the chassis' planned (v, w) plus its servo's predicted droop. What
the plan cannot know (a floor's slope across the path, a floor of other friction, a
heavier robot, the scrub of a skid-steer's tyres, which follows the friction) turns the
wheels, or the chassis over them, by another amount. These loops read it and correct the
wheel commands (rad/s offsets on each side, the convention of diff_drive_controller's
odometry: eq. 5 of :mod:`gaits.wheeled`).

``wheel-odometry`` (:class:`WheelOdometry`): the plan's reference, the chassis' planned
heading and distance over time (``spec["profile"]``: a drive's ``v``, ``w`` and ramp, a
turn's ``angle`` and duration, a straight ``distance``, all minimum-jerk as the plans', or
``legs`` of them: :func:`reference`), against the measured ones:

- heading: the IMU's yaw (the firmware's attitude estimate, :class:`gaits.feedback.Attitude`:
  the gyro's yaw rate integrated, drifting with its bias) where ``spec["imu"]`` is true
  (the design carries an IMU: ``needs_imu``); else the wheels' odometry, ``r (theta_R -
  theta_L) / l_eff``, which sees the servos' droop but not a skid-steer's scrub (its
  effective track is the calibrated one, on the catalog's floor);
- distance along the path: the wheels' odometry, ``r (theta_R + theta_L) / 2``.

A PI law on each error gives a yaw-rate and a speed correction, turned into wheel-speed
offsets through eq. 5; each side's command stays within the servos' no-load speed (the
offset is clipped there, and the integrals stop growing while it is). After the plan's end
the loop keeps correcting towards the plan's final heading and distance (the plan holds
still: a turn's plan carries a settling tail, so a turn ends on the measured heading).

``wheel-hold`` (:class:`WheelHold`): while the plan holds the wheels still (every wheel's
planned speed below ``still_rad_s``), each wheel is held at the encoder angle it had when
the hold began: ``offset = -k (angle - angle at start) - ki integral`` (a position loop on
a velocity servo), clipped to the no-load speed. A mobile manipulator's base under its arm's
reaction, on a slope, keeps its place. While the plan drives the wheels, no offset.

Gains (1/s): the loop runs at the control period (20 ms) behind the bus latency (10-40 ms)
and the wheel motor's time constant (50 ms); with ~0.1 s of lag in the loop a
proportional gain of 4 1/s keeps ~25 deg of phase margin on the yaw integrator and halves
an error in ~0.2 s; the integral (6 1/s^2) takes out a steady load's share; at rest it runs
at ``KI_STILL`` and is dropped once the error changes sign (the breakaway friction's dead
band, see there).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from gaits.base import min_jerk, min_jerk_integral
from gaits.feedback import Loop, Reading, register, roll_pitch_yaw

#: 1/s, 1/s^2: the heading loop's proportional and integral gains (module docstring)
KP_HEADING = 4.0
KI_HEADING = 6.0
#: 1/s, 1/s^2: the distance loop's
KP_DISTANCE = 4.0
KI_DISTANCE = 6.0
#: 1/s^2: both integrals' gain while the plan holds the wheels still (a turn's settling
#: tail, between a pick-and-place's drives): a wheel at rest sees the breakaway friction of
#: its tyres and the caster, a dead band that only the integral crosses, and no motion to
#: make it oscillate (measured: with the moving gains a differential drive's turn stopped
#: 0.02 rad short of its reference through a 0.6 s tail)
KI_STILL = 24.0
#: 1/s, 1/s^2: the hold's proportional and integral gains on each wheel's angle (the
#: integral takes out what a steady load, a slope's pull, leaves of the proportional band)
K_HOLD = 6.0
KI_HOLD = 6.0
#: rad/s: a planned wheel speed below this is "still" (the hold acts)
STILL_RAD_S = 1e-6


def _min_jerk_pos(x: float) -> float:
    return float(min_jerk(np.array([x]))[0][0])


def reference(profile: Mapping[str, object], t: float) -> tuple[float, float]:
    """(heading rad, distance m) the plan's ``profile`` reaches at ``t`` s: a turn in place
    (``angle`` rad in ``seconds`` s, minimum jerk), a straight drive (``distance`` m in
    ``seconds`` s, minimum jerk) or a drive (``v`` m/s, ``w`` rad/s, reached with a
    minimum-jerk ``ramp`` s, held until ``seconds``), each held where it ends; a hold (none
    of them) stays at (0, 0); ``legs``: a list of such profiles, each with its start
    ``t0`` s, one after another (a pick-and-place's drives and turns between its arm's
    legs: the reference holds still between them)."""
    legs = profile.get("legs")
    if legs is not None:  # one leg after another: each adds its own from its start
        h = d = 0.0
        for leg in legs:  # type: ignore[attr-defined]
            dh, dd = reference(leg, t - float(leg.get("t0", 0.0)))
            h, d = h + dh, d + dd
        return h, d
    seconds = float(profile.get("seconds", 0.0))  # type: ignore[arg-type]
    t = min(max(t, 0.0), seconds)
    if "distance" in profile:  # a straight drive, minimum jerk
        return 0.0, float(profile["distance"]) * _min_jerk_pos(t / max(seconds, 1e-9))  # type: ignore[arg-type]
    if "angle" in profile:  # a skid-steer's turn drives its measured centre's offset out
        h = float(profile["angle"]) * _min_jerk_pos(t / max(seconds, 1e-9))  # type: ignore[arg-type]
        return h, -float(profile.get("centre_y", 0.0)) * h  # type: ignore[arg-type]
    v = float(profile.get("v", 0.0))  # type: ignore[arg-type]
    w = float(profile.get("w", 0.0))  # type: ignore[arg-type]
    ramp = float(profile.get("ramp", 0.0))  # type: ignore[arg-type]
    if ramp > 0 and t < ramp:  # as the plan's (gaits.wheeled._driving)
        d = ramp * float(min_jerk_integral(np.array([t / ramp]))[0])
    else:
        d = ramp / 2 + (t - ramp)
    return w * d, v * d


class _Wheels(Loop):
    """The sides of a wheeled plan, from its spec: ``left``/``right`` joint names,
    ``sign`` (joint -> +-1: the joint speed that rolls forward), ``radius_m``,
    ``track_m`` (effective), ``max_speed_rad_s`` (no-load speed)."""

    def __init__(self, traj, spec: Mapping[str, object]) -> None:
        super().__init__(traj, spec)
        sign = spec["sign"]
        left, right = spec["left"], spec["right"]
        self.sign = np.array([float(sign.get(j, 0.0)) for j in self.joints])  # type: ignore[union-attr]
        self.is_left = np.array([j in left for j in self.joints])  # type: ignore[operator]
        self.is_right = np.array([j in right for j in self.joints])  # type: ignore[operator]
        self.wheel = self.is_left | self.is_right
        self.r = float(spec["radius_m"])  # type: ignore[arg-type]
        self.track = float(spec["track_m"])  # type: ignore[arg-type]
        self.top = float(spec["max_speed_rad_s"])  # type: ignore[arg-type]
        self.q0: np.ndarray | None = None

    def reset(self, first: Reading) -> None:
        self.q0 = np.asarray(first.q, dtype=float).copy()

    def forward(self, q: np.ndarray) -> tuple[float, float]:
        """(left, right) mean forward rotation rad of each side since the start."""
        assert self.q0 is not None
        a = self.sign * (np.asarray(q, dtype=float) - self.q0)
        return float(a[self.is_left].mean()), float(a[self.is_right].mean())

    def clip(self, t: float, left: float, right: float) -> tuple[np.ndarray, bool]:
        """(nj,) joint offsets of the sides' forward offsets, each command kept within the
        no-load speed; and whether any was clipped."""
        _, v_plan = self.planned(t)
        if t >= float(self.traj.times[-1]):
            v_plan = np.zeros_like(v_plan)  # past the plan's end its wheels are stopped
        want = np.where(self.is_left, left, np.where(self.is_right, right, 0.0)) * self.sign
        lo, hi = -self.top - v_plan, self.top - v_plan
        out = np.where(self.wheel, np.clip(want, lo, hi), 0.0)
        return out, bool(np.any(np.abs(out - np.where(self.wheel, want, 0.0)) > 1e-12))


@register("wheel-odometry")
class WheelOdometry(_Wheels):
    """Heading (IMU or odometry) and distance (odometry) closed on the plan's reference
    (module docstring). Spec keys besides :class:`_Wheels`': ``profile`` (see
    :func:`reference`), ``imu`` (bool: the heading from the IMU), gains ``kp_heading``,
    ``ki_heading``, ``kp_distance``, ``ki_distance``."""

    GAINS = ("kp_heading", "ki_heading", "kp_distance", "ki_distance", "ki_still")

    def __init__(self, traj, spec: Mapping[str, object]) -> None:
        super().__init__(traj, spec)
        self.needs_imu = bool(spec.get("imu", False))
        self.profile: Mapping[str, object] = spec["profile"]  # type: ignore[assignment]
        self.kp_h = self.gain("kp_heading", KP_HEADING)
        self.ki_h = self.gain("ki_heading", KI_HEADING)
        self.kp_d = self.gain("kp_distance", KP_DISTANCE)
        self.ki_d = self.gain("ki_distance", KI_DISTANCE)
        self.ki_still = self.gain("ki_still", KI_STILL)
        self.int_h = self.int_d = 0.0
        self.yaw0 = self.last_yaw = 0.0
        self.turns = 0.0
        self.last_t: float | None = None

    def reset(self, first: Reading) -> None:
        super().reset(first)
        if self.needs_imu and first.attitude is not None:
            self.yaw0 = self.last_yaw = roll_pitch_yaw(first.attitude)[2]

    def heading(self, r: Reading, left: float, right: float) -> float:
        """The measured heading change rad since the start."""
        if self.needs_imu and r.attitude is not None:
            yaw = roll_pitch_yaw(r.attitude)[2]
            step = yaw - self.last_yaw  # unwrapped: turns past 180 degrees count whole
            self.turns += (step + math.pi) % (2 * math.pi) - math.pi - step
            self.last_yaw = yaw
            return yaw + self.turns - self.yaw0
        return self.r * (right - left) / self.track

    def correct(self, r: Reading) -> np.ndarray:
        dt = 0.0 if self.last_t is None else r.t - self.last_t
        self.last_t = r.t
        left, right = self.forward(r.q)
        psi_ref, d_ref = reference(self.profile, r.t)
        e_h = psi_ref - self.heading(r, left, right)
        e_d = d_ref - self.r * (left + right) / 2
        _, v_plan = self.planned(r.t)
        still = r.t >= float(self.traj.times[-1]) or not np.any(
            np.abs(v_plan[self.wheel]) > STILL_RAD_S
        )
        boost = max(self.ki_still / max(self.ki_h, 1e-9), 1.0) if still else 1.0
        if still:  # a wheel that broke free stops at the reference, not past it: the
            # integral that crossed the dead band is dropped once the error changes sign
            self.int_h = 0.0 if e_h * self.int_h < 0 else self.int_h
            self.int_d = 0.0 if e_d * self.int_d < 0 else self.int_d
        gain_h, gain_d = self.ki_h * boost, self.ki_d * boost
        u_w = self.kp_h * e_h + self.ki_h * self.int_h + gain_h * e_h * dt
        u_v = self.kp_d * e_d + self.ki_d * self.int_d + gain_d * e_d * dt
        half = self.track / 2
        out, clipped = self.clip(r.t, (u_v - u_w * half) / self.r, (u_v + u_w * half) / self.r)
        if not clipped:  # anti-windup: the integrals stop while a command is at its limit
            self.int_h += gain_h / self.ki_h * e_h * dt if self.ki_h else 0.0
            self.int_d += gain_d / self.ki_d * e_d * dt if self.ki_d else 0.0
        return out


@register("wheel-hold")
class WheelHold(_Wheels):
    """Each wheel held at its encoder angle while the plan holds the wheels still (module
    docstring). Spec keys besides :class:`_Wheels`': ``k`` 1/s, ``still_rad_s``."""

    GAINS = ("k", "ki")

    def __init__(self, traj, spec: Mapping[str, object]) -> None:
        super().__init__(traj, spec)
        self.k = self.gain("k", K_HOLD)
        self.ki = self.gain("ki", KI_HOLD)
        self.still = float(spec.get("still_rad_s", STILL_RAD_S))  # type: ignore[arg-type]
        self.anchor: np.ndarray | None = None
        self.acc = np.zeros(len(self.joints))
        self.last_t: float | None = None

    def correct(self, r: Reading) -> np.ndarray:
        _, v_plan = self.planned(r.t)
        dt = 0.0 if self.last_t is None else r.t - self.last_t
        self.last_t = r.t
        past = r.t >= float(self.traj.times[-1])
        q = np.asarray(r.q, dtype=float)
        if not past and np.any(np.abs(v_plan[self.wheel]) > self.still):
            self.anchor = None  # the plan drives the wheels: no hold
            self.acc[:] = 0.0
            return np.zeros(len(self.joints))
        if self.anchor is None:
            self.anchor = q.copy()
        err = np.where(self.wheel, q - self.anchor, 0.0)
        want = -self.k * err - self.ki * (self.acc + err * dt)
        lo, hi = -self.top - v_plan, self.top - v_plan
        out = np.where(self.wheel, np.clip(want, lo, hi), 0.0)
        free = np.abs(out - np.where(self.wheel, want, 0.0)) <= 1e-12
        self.acc = np.where(free, self.acc + err * dt, self.acc)  # anti-windup
        return out
