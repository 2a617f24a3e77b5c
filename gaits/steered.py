"""Steered wheeled robots (structure ``steered``): wheels turned about the vertical by
steering joints, driven by traction wheels, on a chassis; the ``driving`` and ``turning``
behaviours of the ability ``steered-driving``.

Kinematics (rigid wheels rolling without side slip; the bicycle model generalised to any
wheels). The reference point P is the middle of the unsteered wheels' axle (they all stand
on one line across the chassis: their common x, the root frame's origin in the shipped
part kinds). The chassis drives at forward speed ``v`` m/s of P and yaw rate ``w`` rad/s,
on an arc of curvature ``k = w / v`` 1/m (radius ``R = v / w``, centre on the axle's line,
positive: on the left). A wheel at ``(x, y)`` (root frame, ``dx = x - x_P``) then moves
with the velocity ``v (1 - k y, k dx)``, so

    steering angle   delta = atan2(k dx, 1 - k y)       (rad, Ackermann's condition:
                                                         every wheel's axle through the
                                                         centre of the turn)
    rolling speed    q = v hypot(1 - k y, k dx) / r      (rad/s, r the wheel radius)

A car's (two steered front wheels) inner wheel steers more than its outer one, its rear
wheels roll at ``v (1 -+ k l / 2) / r`` (track l); a tricycle's front wheel (y = 0) steers
``atan(k L)`` (wheel base L) and rolls at ``v sqrt(1 + (k L)^2) / r``. Only driven wheels
are commanded; free wheels (passive joints) roll as the ground turns them.

The steering limit (the steering joints' limits) bounds the curvature: the largest
``|k|`` at which no steered wheel steers past its limit (:attr:`SteerGeometry.k_max`);
the smallest radius of P is ``1 / k_max`` (a tricycle's: ``L / tan(limit)``, a car's:
``L / tan(limit) + l / 2``). A steered robot cannot turn in place: ``driving`` refuses
``w`` without ``v`` and an arc tighter than the limit, naming the smallest radius;
``turning`` changes the heading by an arc of the smallest radius (``points = 1``), or by a
manoeuvre of ``points`` arcs at full lock, forward and back in turn (reversing with the
steering the other way turns the same way), each turning ``angle / points``: a
three-point turn needs about a third of the room of one arc.

Calibration. Simulated, a steered robot keeps to the commanded arc (its yaw rate over its
speed is the commanded curvature within 1 %) but goes slower than commanded, the more the
tighter the arc: its driven wheels' servos slow down under the load of the turn (the
tyres' scrub about the vertical as the chassis yaws, their creep) as a DC motor's line
says. Measured on the shipped tricycle: 0.98 of the speed straight, 0.96, 0.92 and 0.885 at
0.3, 0.6 and 0.9 of the steering limit. As a skid-steer's effective track is, this is
measured on the design (:meth:`SteeredController.calibration_probes`: ``driving``
straight and on the turning arc both ways; :meth:`calibrate`: the speed of the reference
point over the commanded one on each) and kept in the design record (``calibration``:
``speed_ratio`` straight, ``speed_ratio_turn`` at ``probe_curvature`` 1/m); the wheels are
then commanded ``1 / ratio(k)`` faster, the ratio linear in ``|k|`` between the two.

Every motion starts and ends at rest: the steering turns first (a minimum-jerk move of
each steering joint at ``STEER_SPEED_FRACTION`` of its servo's speed) with the wheels
still, then the wheels roll (a minimum-jerk ramp); ``info["planned_pose"]`` is P's
commanded displacement and heading, exact for the profile (each segment is one arc).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gaits.base import (
    BehaviorSpec,
    Controller,
    DesignGeometry,
    Parameter,
    Trajectory,
    min_jerk,
    min_jerk_integral,
)
from gaits.steering import SteerableSpec
from kinematics.dynamics import forward_kinematics
from kinematics.templates import Template

__all__ = [
    "SteerGeometry",
    "SteeredController",
    "steering_joints",
    "wheel_loads",
]

#: Trajectory sample period, s.
SAMPLE_DT = 0.01
#: Fraction of a steering servo's no-load speed a steering move peaks at.
STEER_SPEED_FRACTION = 0.5
#: Fraction of a steering servo's no-load speed the steering turns at while rolling on
#: (``driving`` with ``rolling = 1``): the servo's own damping (its derivative gain and
#: its motor's back-EMF) and the tyre's scrub hold it at its stall torque when it is asked
#: to turn faster (measured: the shipped tricycle's SG90 following lines, saturated 5-7 %
#: of the time at 0.5, 1-3 % at 0.35, never at 0.2).
ROLL_STEER_FRACTION = 0.2
#: Rest after a steering move before the wheels roll, s (the servo settles in its band).
STEER_SETTLE = 0.1
#: ``turning``'s arcs use this fraction of the steering limit's curvature (the steering
#: servo's band under the tyre's scrub keeps it a little short of the commanded angle).
LOCK_FRACTION = 0.9
#: ``turning``'s arcs peak at this fraction of the top speed: the driven wheels' droop on a
#: slope (uphill; downhill they run ahead), which no open-loop command knows, is then the
#: smallest share of their speed (0.5 before: the default turns of tricycles, cars and two
#: KIF-only steered types passed 67 of 104 perturbed runs over a grid of payloads and
#: speeds, 82 at 0.9; ``bench/robust_wheel_grid.py``).
TURN_SPEED_FRACTION = 0.9
#: Default minimum-jerk ramp of ``driving``, s.
RAMP = 0.5
#: Calibration runs (:meth:`SteeredController.calibration_probes`): ``driving`` on the
#: turning arc (``LOCK_FRACTION`` of the limit) both ways at this fraction of the top
#: speed, holding it this long after the ramp, measured from this long after the ramp.
PROBE_SPEED_FRACTION = 0.25
PROBE_SECONDS = 2.0
PROBE_SETTLE = 0.5
#: A measured speed ratio outside this range is no calibration (something else went wrong).
SPEED_RATIO_RANGE = (0.7, 1.3)


def steering_joints(template: Template) -> tuple[tuple[str, str], ...]:
    """(steering joint, the wheel body it steers) of each steered wheel, in model order: a
    revolute joint about the vertical (root frame, q = 0) that carries a wheel's joint."""
    m = template.model
    T = forward_kinematics(m, np.zeros(m.nv))
    out = []
    for w in template.wheels:
        parent = m.joints[m.body(w)].parent
        if parent < 0:
            continue
        j = m.joints[parent]  # the inbound joint of the wheel's parent body
        if j.kind != "revolute" or j.parent < 0:
            continue
        axis = T[parent, :3, :3] @ np.asarray(j.axis, dtype=float)
        if abs(abs(axis[2]) - 1.0) < 1e-9:
            out.append((j.name, w))
    return tuple(out)


def _centre_of_mass(template: Template) -> np.ndarray:
    m = template.model
    T = forward_kinematics(m, np.zeros(m.nv))
    total, first = 0.0, np.zeros(3)
    for k, b in enumerate(m.bodies):
        total += b.mass
        first += b.mass * (T[k, :3, :3] @ np.asarray(b.com) + T[k, :3, 3])
    return first / total


def wheel_loads(template: Template, weight: float) -> dict[str, float]:
    """The share N of ``weight`` N each wheel carries standing still on flat ground: the
    lever rule between the front-most and the rear-most wheels about the centre of mass
    (x, root frame; the centre of mass at q = 0 with the template's masses), each line's
    share split evenly among its wheels; equal shares when all wheels stand on one line."""
    m = template.model
    T = forward_kinematics(m, np.zeros(m.nv))
    x = {w: float(T[m.body(w), 0, 3]) for w in template.wheels}
    front, rear = max(x.values()), min(x.values())
    if front - rear < 1e-9:
        return dict.fromkeys(x, weight / len(x))
    share = min(max((float(_centre_of_mass(template)[0]) - rear) / (front - rear), 0.0), 1.0)
    nf = sum(1 for v in x.values() if abs(v - front) < 1e-9)
    nr = sum(1 for v in x.values() if abs(v - rear) < 1e-9)
    out = {}
    for w, v in x.items():
        if abs(v - front) < 1e-9:
            out[w] = weight * share / nf
        elif abs(v - rear) < 1e-9:
            out[w] = weight * (1 - share) / nr
        else:
            out[w] = 0.0
    return out


@dataclass(frozen=True)
class Wheel:
    """One wheel: its joint, body, position (x, y) m in the root frame, its steering joint
    ("" for none) and its limit rad, whether it is driven, and the sign of its joint speed
    that rolls it forward."""

    joint: str
    body: str
    x: float
    y: float
    steer: str
    limit: float
    driven: bool
    sign: float


@dataclass(frozen=True)
class SteerGeometry:
    """A steered design's wheels, the reference point's x (``x_ref``, m), the wheel radius
    m, the driven wheels' usable speed (``max_speed`` rad/s: the slowest one's no-load
    speed) and the steering servos' (``steer_speed`` rad/s)."""

    wheels: tuple[Wheel, ...]
    x_ref: float
    radius: float
    max_speed: float
    steer_speed: float

    @classmethod
    def from_template(cls, template: Template, joint_speed: Mapping[str, float]):
        m = template.model
        T = forward_kinematics(m, np.zeros(m.nv))
        steered = dict((w, j) for j, w in steering_joints(template))
        if not steered:
            raise ValueError(f"{template.robot_type} has no steered wheel")
        passive = set(template.passive)
        wheels = []
        for w in template.wheels:
            j = m.joints[m.body(w)]
            pos = T[m.body(w), :3, 3]
            axis = T[m.body(w), :3, :3] @ np.asarray(j.axis, dtype=float)
            forward = float(np.cross(axis, (0.0, 0.0, 1.0))[0])
            if abs(forward) < 1e-9:
                raise ValueError(f"wheel {j.name!r} does not roll along x")
            s = steered.get(w, "")
            limit = 0.0
            if s:
                sj = m.joints[m.joint(s)]
                limit = min(-sj.lower, sj.upper)
                if limit <= 0:
                    raise ValueError(f"steering joint {s!r} cannot steer both ways")
            wheels.append(
                Wheel(
                    j.name,
                    w,
                    float(pos[0]),
                    float(pos[1]),
                    s,
                    limit,
                    j.name not in passive,
                    float(np.sign(forward)),
                )
            )
        fixed = [w for w in wheels if not w.steer]
        if not fixed:
            raise ValueError(
                f"{template.robot_type}: every wheel is steered; the steered kinematics need "
                "unsteered wheels on one axle"
            )
        xs = {round(w.x, 9) for w in fixed}
        if len(xs) > 1:
            raise ValueError(
                f"{template.robot_type}: the unsteered wheels stand at x = "
                f"{', '.join(f'{x:g}' for x in sorted(xs))} m; they must share one axle"
            )
        driven = [w for w in wheels if w.driven]
        if not driven:
            raise ValueError(f"{template.robot_type} has no driven wheel")
        speeds = {w.joint: joint_speed.get(w.joint, 0.0) for w in driven}
        speeds |= {w.steer: joint_speed.get(w.steer, 0.0) for w in wheels if w.steer}
        missing = [n for n, s in speeds.items() if s <= 0]
        if missing:
            raise ValueError(f"no speed for the joint(s) {', '.join(missing)} in the design")
        return cls(
            tuple(wheels),
            fixed[0].x,
            float(template.params.wheel_radius),
            min(speeds[w.joint] for w in driven),
            min(speeds[w.steer] for w in wheels if w.steer),
        )

    @property
    def k_max(self) -> float:
        """The largest curvature 1/m (either sense) at which no steered wheel steers past
        its limit: for a wheel at (dx, y), ``tan(limit) / (dx + |y| tan(limit))`` (the
        inner side's), the least of them."""
        out = math.inf
        for w in self.wheels:
            if not w.steer:
                continue
            dx, t = abs(w.x - self.x_ref), math.tan(w.limit)
            if dx < 1e-9:
                continue
            out = min(out, t / (dx + abs(w.y) * t))
        return out

    @property
    def r_min(self) -> float:
        """The smallest turning radius m of the reference point."""
        return 1.0 / self.k_max

    def angles(self, k: float) -> dict[str, float]:
        """Steering joint -> its angle rad on an arc of curvature ``k`` 1/m."""
        return {
            w.steer: math.atan2(k * (w.x - self.x_ref), 1 - k * w.y) for w in self.wheels if w.steer
        }

    def rolling(self, k: float) -> dict[str, float]:
        """Driven wheel joint -> its forward rolling speed rad/s per m/s of the reference
        point on an arc of curvature ``k`` 1/m."""
        return {
            w.joint: math.hypot(1 - k * w.y, k * (w.x - self.x_ref)) / self.radius
            for w in self.wheels
            if w.driven
        }

    def check_curvature(self, k: float, what: str) -> None:
        """ValueError when an arc of curvature ``k`` is tighter than the steering allows."""
        if abs(k) > self.k_max * (1 + 1e-9):
            limits = sorted({round(math.degrees(w.limit), 1) for w in self.wheels if w.steer})
            raise ValueError(
                f"{what} is an arc of radius {1 / abs(k):.3g} m, tighter than the steering "
                f"allows: the smallest radius is {self.r_min:.3g} m (steering limit "
                f"{', '.join(f'{x:g}' for x in limits)} deg), so |w| <= {self.k_max:.3g} |v| "
                "(1/m); a steered robot cannot turn in place: use turning"
            )


def _grid(seconds: float) -> np.ndarray:
    n = max(2, int(math.ceil(seconds / SAMPLE_DT - 1e-9)) + 1)
    return np.linspace(0.0, seconds, n)


def _arc(pose: tuple[float, float, float], k: float, d: float) -> tuple[float, float, float]:
    """The pose after travelling ``d`` m on an arc of curvature ``k`` from ``pose``."""
    x, y, th = pose
    dth = k * d
    if abs(dth) < 1e-12:
        fx, fy = d, 0.0
    else:
        fx, fy = math.sin(dth) / k, (1 - math.cos(dth)) / k
    return (
        x + fx * math.cos(th) - fy * math.sin(th),
        y + fx * math.sin(th) + fy * math.cos(th),
        th + dth,
    )


class SteeredController(Controller):
    """Behaviours of a steered design (see the module docstring).

    - ``driving(v, w, seconds, ramp)``: steer to the arc of curvature ``w / v`` at rest,
      then reach the speed ``v`` m/s with a minimum-jerk ramp of ``ramp`` s and hold it
      until ``seconds`` after the steering; the wheels keep the speed after the end (run
      ``driving`` with v = 0 to stop). ``|w| <= k_max |v|``; motion ``"straight"`` or
      ``"arc"``, ``info["command"] = (v, w)``. With ``ramp = 0`` (a closed loop's short
      periods) the steering angles and wheel speeds are commanded at once.
    - ``turning(angle, points, seconds)``: change the heading by ``angle`` rad with
      ``points`` arcs at ``LOCK_FRACTION`` of the steering limit, forward and back in
      turn, starting and ending at rest with the steering straight; motion ``"arc"``.
    """

    #: plans read the geometry, the servos' speeds and the calibration, not the masses
    PLAN_IGNORES = frozenset({"mass_kg", "joint_torque"})

    def __init__(self, geometry: DesignGeometry) -> None:
        super().__init__(geometry)
        self.steer = SteerGeometry.from_template(self.template, geometry.joint_speed)
        #: the measured speed over the commanded one straight and at ``k_probe`` (the
        #: calibration; 1 without one)
        cal = geometry.calibration
        self.ratio0 = float(cal.get("speed_ratio", 1.0))
        self.ratio1 = float(cal.get("speed_ratio_turn", self.ratio0))
        self.k_probe = float(cal.get("probe_curvature", 0.0))
        g = self.steer
        self.steer_joints = tuple(w.steer for w in g.wheels if w.steer)
        self.wheel_joints = tuple(w.joint for w in g.wheels if w.driven)
        self.joints = (*self.steer_joints, *self.wheel_joints)

    def ratio(self, k: float) -> float:
        """The speed the robot makes over the commanded one on an arc of curvature ``k``
        (the calibration's, linear in |k|; 1 without one)."""
        if self.k_probe <= 0:
            return self.ratio0
        return self.ratio0 + (self.ratio1 - self.ratio0) * abs(k) / self.k_probe

    @property
    def v_max(self) -> float:
        """Top straight speed m/s of the reference point (the slowest driven wheel's; its
        commands compensate the calibration's ratio)."""
        return self.steer.max_speed * self.steer.radius * min(1.0, self.ratio(0.0))

    @property
    def body_length(self) -> float:
        xs = [w.x for w in self.steer.wheels]
        span = max(xs) - min(xs) + 2 * self.steer.radius
        return max(float(self.template.lengths.get("L1", 0.0)), span)

    def _top_speed(self, k: float) -> float:
        """The largest |v| m/s on an arc of curvature ``k`` within the wheels' speed."""
        fastest = max(self.steer.rolling(k).values())
        return self.steer.max_speed / fastest * min(1.0, self.ratio(k))

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        v_top = self.v_max
        w_top = self.steer.k_max * self._top_speed(self.steer.k_max)
        _, arc_own = self.arc_seconds(math.pi / 2, 1)  # the default turn's
        return {
            "driving": SteerableSpec(
                "driving",
                "Steer to the arc of yaw rate w at speed v (|w| <= k_max |v|: the steering "
                "limit), then drive it, ramping up smoothly (rolling on, with rolling = 1).",
                (
                    Parameter(
                        "v",
                        "float",
                        round(v_top / 2, 3),
                        "forward speed of the rear axle's middle",
                        "m/s",
                        low=-v_top,
                        high=v_top,
                    ),
                    Parameter(
                        "w",
                        "float",
                        0.0,
                        f"yaw rate, counter-clockwise positive (|w| <= {self.steer.k_max:.3g} |v|)",
                        "rad/s",
                        low=-w_top,
                        high=w_top,
                    ),
                    Parameter(
                        "seconds", "float", 5.0, "duration of the drive", "s", low=0.05, high=3600
                    ),
                    Parameter(
                        "ramp", "float", RAMP, "minimum-jerk ramp-up time", "s", low=0.0, high=60
                    ),
                    Parameter(
                        "rolling",
                        "int",
                        0,
                        "1: the robot already rolls at v with its steering on the arc of w0: "
                        "it steers while rolling, no steering at rest, no ramp",
                        "",
                        low=0,
                        high=1,
                    ),
                    Parameter(
                        "w0",
                        "float",
                        0.0,
                        "rolling: the yaw rate whose arc the steering is on at the start",
                        "rad/s",
                        low=-w_top,
                        high=w_top,
                    ),
                ),
                ability="steered-driving",
                steer=(
                    ("speed", "v"),
                    ("turn", "w"),
                    ("seconds", "seconds"),
                    ("turn_from", "w0"),
                ),
                fixed=(("ramp", 0.0), ("rolling", 1)),
            ),
            "turning": BehaviorSpec(
                "turning",
                "Change the heading by arcs of the smallest radius: one forward (points = 1) "
                "or a manoeuvre of points arcs forward and back in turn.",
                (
                    Parameter(
                        "angle",
                        "float",
                        math.pi / 2,
                        "heading change, counter-clockwise positive",
                        "rad",
                        low=-2 * math.pi,
                        high=2 * math.pi,
                    ),
                    Parameter(
                        "points",
                        "int",
                        1,
                        "arcs of the manoeuvre, forward and back in turn",
                        "",
                        low=1,
                        high=9,
                    ),
                    Parameter(
                        "seconds",
                        "float",
                        arc_own,
                        "duration of each arc (default: the design's own for the angle and "
                        f"points asked: peak speed {TURN_SPEED_FRACTION:g} of the top speed)",
                        "s",
                        low=2 * SAMPLE_DT,
                        high=600,
                        own=True,
                    ),
                ),
                ability="steered-driving",
            ),
        }

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        if name == "driving":
            if params.get("rolling"):
                return self._rolling(
                    float(params["v"]),
                    float(params["w"]),
                    float(params["seconds"]),
                    float(params["w0"]),
                )
            return self._driving(
                float(params["v"]),
                float(params["w"]),
                float(params["seconds"]),
                float(params["ramp"]),
            )
        points = params["points"]
        assert isinstance(points, int)
        return self._turning(float(params["angle"]), points, float(params["seconds"]))

    def calibration_probes(self) -> list[tuple[str, dict[str, object]]]:
        """``driving`` straight and on the turning arc (``LOCK_FRACTION`` of the limit)
        left and right, at ``PROBE_SPEED_FRACTION`` of the top speed, ``PROBE_SECONDS``
        after the ramp."""
        v = round(PROBE_SPEED_FRACTION * self.v_max, 4)
        w = round(LOCK_FRACTION * self.steer.k_max * v, 4)
        return [
            ("driving", {"v": v, "w": sense * w, "seconds": PROBE_SECONDS + RAMP})
            for sense in (0.0, 1.0, -1.0)
        ]

    def calibrate(self, runs) -> dict:
        """From the probe runs: the speed of the reference point (the root's origin)
        measured over the steady part of each (after its steering, its ramp and
        ``PROBE_SETTLE`` s) over the commanded one: ``speed_ratio`` straight,
        ``speed_ratio_turn`` the arcs' mean at ``probe_curvature``. Empty when a run is
        too short or a ratio is out of ``SPEED_RATIO_RANGE``."""
        straight, turns, k_probe = [], [], 0.0
        for traj, series in runs:
            t = np.asarray(series["t"])
            info = traj.info
            start = float(info["steer_s"]) + float(info["ramp_s"]) + PROBE_SETTLE  # type: ignore[arg-type]
            steady = t >= start
            v, w = (float(x) for x in info["command"])  # type: ignore[union-attr]
            if steady.sum() < 3 or v == 0:
                return {}
            xy = np.asarray(series["root"])[:, :2]
            speed = np.hypot(*np.gradient(xy, t, axis=0).T)
            ratio = float(np.mean(speed[steady])) / abs(v)
            if not SPEED_RATIO_RANGE[0] <= ratio <= SPEED_RATIO_RANGE[1]:
                return {}
            if w == 0:
                straight.append(ratio)
            else:
                turns.append(ratio)
                k_probe = abs(w / v)
        if not straight or not turns:
            return {}
        return {
            "speed_ratio": round(float(np.mean(straight)), 4),
            "speed_ratio_turn": round(float(np.mean(turns)), 4),
            "probe_curvature": round(k_probe, 4),
        }

    # -- building blocks ------------------------------------------------------------------
    def _steer_move(self, start: Mapping[str, float], end: Mapping[str, float]):
        """(t, steering angles (n, ns), wheel speeds (n, nw)) of a steering move at rest
        from ``start`` to ``end`` angles, then STEER_SETTLE s still; None when nothing
        turns."""
        delta = max(abs(end[j] - start[j]) for j in self.steer_joints)
        if delta < 1e-12:
            return None
        move = 1.875 * delta / (STEER_SPEED_FRACTION * self.steer.steer_speed)
        move = max(round(math.ceil(move / SAMPLE_DT) * SAMPLE_DT, 9), 2 * SAMPLE_DT)
        t = _grid(move + STEER_SETTLE)
        s, _, _ = min_jerk(t / move)
        a = np.array([start[j] for j in self.steer_joints])
        b = np.array([end[j] for j in self.steer_joints])
        angles = a + np.outer(s, b - a)
        return t, angles, np.zeros((len(t), len(self.wheel_joints)))

    def _roll(self, k: float, speed: np.ndarray) -> np.ndarray:
        """Driven wheels' forward speed commands (n, nw) rad/s for the reference point's
        ``speed`` (n,) m/s on an arc of curvature ``k``: the rolling speeds over the
        calibration's ratio."""
        per = {j: x / self.ratio(k) for j, x in self.steer.rolling(k).items()}
        return np.column_stack([speed * per[j] for j in self.wheel_joints])

    def _check_speeds(self, wheels: np.ndarray, what: str) -> None:
        top = float(np.max(np.abs(wheels))) if wheels.size else 0.0
        if top > self.steer.max_speed * (1 + 1e-9):
            raise ValueError(
                f"{what} needs a wheel speed of {top:.3g} rad/s, above the usable "
                f"{self.steer.max_speed:.3g} rad/s of the driven wheels (their no-load speed)"
            )

    def _trajectory(
        self,
        name: str,
        pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
        info: Mapping[str, object],
    ) -> Trajectory:
        """Join pieces (t from 0, steering angles, forward wheel speeds) end to end; the
        wheels' positions are the integral of their joint speeds (trapezoidal)."""
        ts, angles, speeds = [], [], []
        t0 = 0.0
        for k, (t, a, w) in enumerate(pieces):
            if k:  # the first sample of a piece repeats the previous piece's last
                t, a, w = t[1:], a[1:], w[1:]
            ts.append(t + t0)
            angles.append(a)
            speeds.append(w)
            t0 = float(ts[-1][-1])
        t = np.concatenate(ts)
        sign = np.array([w.sign for w in self.steer.wheels if w.driven])
        vel_w = np.vstack(speeds) * sign
        steps = (vel_w[1:] + vel_w[:-1]) / 2 * np.diff(t)[:, None]
        pos_w = np.vstack([np.zeros((1, vel_w.shape[1])), np.cumsum(steps, axis=0)])
        pos_s = np.vstack(angles)
        vel_s = np.gradient(pos_s, t, axis=0) if len(t) > 1 else np.zeros_like(pos_s)
        info = dict(info) | {
            "locomotion": "wheeled",
            "body_length_m": self.body_length,
            "radius_m": self.steer.radius,
            "min_turn_radius_m": self.steer.r_min,
        }
        return Trajectory(
            name,
            t,
            self.joints,
            np.hstack([pos_s, pos_w]),
            np.hstack([vel_s, vel_w]),
            info,
        )

    # -- behaviours -----------------------------------------------------------------------
    def _driving(self, v: float, w: float, seconds: float, ramp: float) -> Trajectory:
        what = f"driving at (v, w) = ({v:g} m/s, {w:g} rad/s)"
        if v == 0 and w != 0:
            raise ValueError(
                f"{what}: a steered robot cannot turn in place (w without v); drive an arc "
                f"(|w| <= {self.steer.k_max:.3g} |v|) or use turning"
            )
        k = w / v if v != 0 else 0.0
        self.steer.check_curvature(k, what)
        if ramp > seconds:
            raise ValueError(f"ramp ({ramp} s) is longer than the drive ({seconds} s)")
        straight = dict.fromkeys(self.steer_joints, 0.0)
        pieces = []
        # without a ramp (a closed loop's short periods, program.sensing) the steering is
        # commanded at once: the servo turns to it from wherever the last period left it
        steer = self._steer_move(straight, self.steer.angles(k)) if ramp > 0 else None
        if steer is not None:
            pieces.append(steer)
        t = _grid(seconds)
        if ramp > 0:
            s, _, _ = min_jerk(t / ramp)
            dist = np.where(t < ramp, ramp * min_jerk_integral(t / ramp), ramp / 2 + (t - ramp))
        else:
            s, dist = np.ones_like(t), t
        wheels = self._roll(k, v * s)
        self._check_speeds(wheels, what)
        held = np.tile([self.steer.angles(k)[j] for j in self.steer_joints], (len(t), 1))
        pieces.append((t, held, wheels))
        d = v * float(dist[-1])
        pose = _arc((0.0, 0.0, 0.0), k, d)
        info: dict[str, object] = {
            "command": (v, w),
            "ramp_s": ramp,
            "steer_s": float(steer[0][-1]) if steer is not None else 0.0,
            "planned_pose": pose,
            "path_length_m": abs(d),
        }
        if v == 0:
            info["motion"] = "hold"
        elif w == 0:
            info["motion"] = "straight"
            info["direction"] = (math.copysign(1.0, v), 0.0)
        else:
            info["motion"] = "arc"
        return self._trajectory("driving", pieces, info)

    def _rolling(self, v: float, w: float, seconds: float, w0: float) -> Trajectory:
        """``driving`` rolling on (a closed loop's short periods, :mod:`program.sensing`):
        the robot already rolls at ``v`` with its steering on the arc of ``w0``; the steering
        turns toward the arc of ``w``, no joint of it faster than ``ROLL_STEER_FRACTION`` of
        its servo's speed, while the wheels roll at ``v`` on the arc they are on. A
        change the servo cannot make within ``seconds`` is made in part:
        ``info["turn_end"]`` is the yaw rate whose arc the steering ends on (the next
        period's ``w0``); ``planned_pose`` integrates the curvature's profile."""
        what = f"driving at (v, w) = ({v:g} m/s, {w:g} rad/s) from w0 = {w0:g} rad/s"
        if v == 0 and (w != 0 or w0 != 0):
            raise ValueError(
                f"{what}: a steered robot cannot turn in place (w without v); drive an arc "
                f"(|w| <= {self.steer.k_max:.3g} |v|) or use turning"
            )
        k1 = w / v if v != 0 else 0.0
        k0 = w0 / v if v != 0 else 0.0
        self.steer.check_curvature(k1, what)
        self.steer.check_curvature(k0, what)
        # the curvature as the steering turns: its joints' largest angle turned so far
        # grows at ROLL_STEER_FRACTION of the servo's speed (the angles are not linear in
        # the curvature: a car's inner wheel turns faster than its outer one)
        fine = np.linspace(k0, k1, 201)
        path = np.array([[self.steer.angles(float(k))[j] for j in self.steer_joints] for k in fine])
        turned = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(path, axis=0)).max(axis=1))])
        rate = ROLL_STEER_FRACTION * self.steer.steer_speed
        t = _grid(seconds)
        if turned[-1] > 1e-12:
            ks = np.interp(np.minimum(t * rate, turned[-1]), turned, fine)
        else:
            ks = np.full_like(t, k1)
        k_end = float(ks[-1])
        angles = np.array([[self.steer.angles(float(k))[j] for j in self.steer_joints] for k in ks])
        wheels = np.vstack([self._roll(float(k), np.array([v]))[0] for k in ks])
        self._check_speeds(wheels, what)
        # the pose: arcs between samples at their mean curvature
        pose = (0.0, 0.0, 0.0)
        for i in range(1, len(t)):
            pose = _arc(pose, float(ks[i - 1] + ks[i]) / 2, v * float(t[i] - t[i - 1]))
        d = v * seconds
        info: dict[str, object] = {
            "command": (v, w),
            "ramp_s": 0.0,
            "steer_s": 0.0,
            "turn_end": k_end * v,
            "planned_pose": pose,
            "path_length_m": abs(d),
        }
        if v == 0:
            info["motion"] = "hold"
        elif w == 0 and w0 == 0:
            info["motion"] = "straight"
            info["direction"] = (math.copysign(1.0, v), 0.0)
        else:
            info["motion"] = "arc"
        return self._trajectory("driving", [(t, angles, wheels)], info)

    def arc_seconds(self, angle: float, points: int) -> tuple[float, float]:
        """(the shortest, the design's own) duration s of each arc of turning by ``angle``
        rad in ``points`` arcs at the smallest radius: the shortest the wheels' top speed
        allows (min-jerk: peak speed 1.875 leg / T), and the own one, whose peak speed is
        ``TURN_SPEED_FRACTION`` of it (on the sample grid, at least 0.1 s)."""
        k_turn = LOCK_FRACTION * self.steer.k_max
        leg = abs(angle) / points / k_turn  # m each arc travels
        cap = TURN_SPEED_FRACTION * self._top_speed(k_turn)
        shortest = 1.875 * leg / self._top_speed(k_turn)
        own = max(round(math.ceil(1.875 * leg / cap / SAMPLE_DT) * SAMPLE_DT, 9), 0.1)
        return shortest, own

    def _turning(self, angle: float, points: int, seconds: float) -> Trajectory:
        if angle == 0:
            raise ValueError("turning by 0 rad: nothing to do")
        k_turn = LOCK_FRACTION * self.steer.k_max
        turn = math.copysign(1.0, angle)
        leg = abs(angle) / points / k_turn  # m each arc travels
        shortest, own = self.arc_seconds(angle, points)
        if seconds == 0:  # the design's own (gaits.base.AUTO)
            seconds = own
        elif seconds < shortest * (1 - 1e-9):
            raise ValueError(
                f"seconds: an arc of {leg:.3g} m in {seconds:g} s needs a wheel faster than "
                f"the usable {self.steer.max_speed:.3g} rad/s; each arc takes at least "
                f"{shortest:.3g} s"
            )
        pieces = []
        angles = dict.fromkeys(self.steer_joints, 0.0)
        pose = (0.0, 0.0, 0.0)
        for p in range(points):
            direction = 1.0 if p % 2 == 0 else -1.0
            k = turn * direction * k_turn
            target = self.steer.angles(k)
            steer = self._steer_move(angles, target)
            if steer is not None:
                pieces.append(steer)
            angles = target
            t = _grid(seconds)
            _, ds, _ = min_jerk(t / seconds)
            speed = direction * leg * ds / seconds
            wheels = self._roll(k, speed)
            self._check_speeds(wheels, f"turning {angle:g} rad")
            held = np.tile([target[j] for j in self.steer_joints], (len(t), 1))
            pieces.append((t, held, wheels))
            pose = _arc(pose, k, direction * leg)
        back = self._steer_move(angles, dict.fromkeys(self.steer_joints, 0.0))
        if back is not None:
            pieces.append(back)
        info = {
            "heading_rad": angle,
            "motion": "arc",
            "points": points,
            "planned_pose": pose,
            "path_length_m": points * leg,
            "turn_radius_m": 1 / k_turn,
        }
        return self._trajectory("turning", pieces, info)
