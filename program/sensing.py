"""Sensing abilities simulated: following a line on the floor with two downward infrared
sensors, and passing an obstacle with a forward ultrasonic ranger.

A sensing ability is a closed loop over a locomotion behaviour the design already has,
the first (by name) whose spec says which of its parameters steer it
(:class:`gaits.steering.SteerableSpec`: speed, turn, period; :func:`steering`), continuing
from where the robot is (:class:`program.session.Session`). Designs without one give no
sensing behaviour, and the ability stays ``not_simulated``.

- A yaw rate steered for any short time (wheels' ``driving``): at :data:`CONTROL_HZ` the
  robot reads its sensors, picks a forward speed and a turn rate and runs the behaviour
  for the next 1 / :data:`CONTROL_HZ` s (:func:`_line`, :func:`_avoid`).
- A gait that starts and ends at rest, steered by a curvature (legs' ``walking``) or a
  bias whose effect the loop learns (a snake's ``sidewinding``): the sensors are still
  read at :data:`CONTROL_HZ` while it goes, but it decides once a control period of
  :data:`PERIOD_CYCLES` gait cycle(s) (:class:`_Strider`, :func:`_line_strides`,
  :func:`_avoid_strides`). Earlier, a legged gait stepped one step at a time, turning in
  place between steps, covered 0.21 m of 1 m of line in 175 s; walking arcs, the
  four-legged walker covers 0.5 m of a 1 m circle in 79 s.

The sensors, as the ontology's sensing abilities and the catalog's modules give them:

- two TCRT5000 infrared modules side by side (:data:`IR_SPACING_M` apart) at the front
  edge of the trunk, looking down; each reads 1 over the line (black tape
  :data:`LINE_WIDTH_M` wide), else 0 (the module's comparator output);
- an HC-SR04 ultrasonic ranger at the front edge, looking forward: the nearest obstacle
  within its beam (three rays, the axis and +-:data:`RANGER_HALF_ANGLE`), between
  :data:`RANGER_MIN_M` and :data:`RANGER_MAX_M` (its datasheet's range).

The trunk's front edge is the furthest point of its geoms along the direction the
steerable behaviour drives forward.

What each promises, judged on the outcome (:func:`synth.verification.verdict.judge`):

- ``line-tracking`` (motion ``follow-line``): the line never leaves the span of the two
  sensors for longer than ``LINE_LOST_S``, and the robot covers ``LINE_PROGRESS`` of the
  commanded length along the line in the time it has (1.5 x what the speed needs, + 2 s).
- ``obstacle-avoidance`` (motion ``avoid``): the robot reaches the goal line ``distance``
  ahead (an obstacle across its straight path halfway) without touching the obstacle,
  within 3 x what the speed needs + 10 s.

For a gait, "what the speed needs" is at its speed on a straight line, stops between
periods included (one straight period's planned travel over its duration, or measured on
calibration periods when the gait plans no pose), and no loop runs past the session's
simulated time (``program.script.LIMITS["sim_s"]``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from gaits.base import BehaviorSpec, Parameter, serving
from gaits.steering import SteerableSpec

if TYPE_CHECKING:
    from program.session import Session

CONTROL_HZ = 20  # sensor reads and steering decisions per second (a microcontroller loop)
LINE_WIDTH_M = 0.019  # black electrical tape
IR_SPACING_M = 0.05  # two 50 mm infrared modules side by side (the modules' face)
RANGER_MIN_M, RANGER_MAX_M = 0.02, 4.0  # HC-SR04 datasheet
RANGER_HALF_ANGLE = math.radians(15)  # HC-SR04: an effective beam of about 30 degrees
TURN_GAIN = 1.0  # x (the tightest curve's rate + the rate that swings the sensors back)
OBSTACLE_DEPTH_M, OBSTACLE_HEIGHT_M = 0.10, 0.25  # the box set across the path
CLEARANCE_M = 0.05  # what the avoiding robot keeps from the obstacle, beyond its corners
HEADING_GAIN = 1.5  # 1/s: steering back to the start heading once past the obstacle
OBSTACLE = "parmor_obstacle"  # the scene's obstacle body and geom
_SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)

#: The sensing abilities this module simulates, with the motion each promises.
SENSING = {"line-tracking": "follow-line", "obstacle-avoidance": "avoid"}

#: time allowed: (x the time the forward speed needs for the distance, + s), per motion
BUDGET = {"follow-line": (1.5, 2.0), "avoid": (3.0, 10.0)}

#: Gait cycles in one control period of a behaviour steered stride by stride (its steps
#: role; at least the role's own lowest): every plan of a gait starts and ends at rest,
#: so the loop decides once a period. Measured on the four-legged walker: two cycles (17
#: cm a period) lose 0.5 and 1 m circles between decisions; one (6 cm) follows them, the
#: start and stop making it half as fast.
PERIOD_CYCLES = 1
#: Obstacle-avoidance by arcs: the turn past the obstacle's edge is done within this
#: (rad), or after this many periods (a learnt bias turns only roughly).
TURN_TOLERANCE, TURN_TRIES = math.radians(5), 8
#: Control periods one sideways step lasts (legs go sideways several times slower than
#: forward: a shorter stride for the same start and stop).
SIDESTEP_PERIODS = 4
#: A stride-steered robot's default line length, goal distance and tightest curve, m:
#: shorter and gentler than a wheeled one's (2.0, 1.5, 0.5), its gaits being ten times
#: slower and its first period blind (it learns which way the line bends only as it goes).
GAIT_LENGTH_M, GAIT_DISTANCE_M, GAIT_RADIUS_M = 0.5, 1.0, 1.0
#: A turn bias's calibration: the periods run before the task at these shares of its
#: largest value (its effect on the heading is learnt from them, then from every period).
BIAS_PROBES = (0.0, 0.5, -0.5)
#: Line estimate: the readings within this many periods' travel of the sensors are
#: weighed (:func:`_locate_line`),
LINE_MEMORY_PERIODS = 3.0
#: ... and the robot closes the line's offset and angle over this many periods' travel,
LOOKAHEAD_PERIODS = 2.0
#: about the curvature its trunk followed over this many periods (measured).
FF_PERIODS = 3


@dataclass(frozen=True)
class Steering:
    """How a design is steered: its steerable behaviour, the parameters playing the roles
    (:class:`gaits.steering.SteerableSpec`), and the speed role's parameter.

    ``kind``: ``rate`` (the turn is a yaw rate, rad/s: steered continuously at
    :data:`CONTROL_HZ`), ``curvature`` (rad/m) or ``bias`` (no unit: its effect on the
    heading is learnt), both steered once a control period of :data:`PERIOD_CYCLES` gait
    cycles (``steps`` role)."""

    behavior: str
    roles: Mapping[str, str]  # role (speed, turn, seconds or steps) -> the parameter
    fixed: Mapping[str, object]
    speed: Parameter  # the behaviour's parameter playing the speed role
    turn: Parameter
    kind: str

    @property
    def v_max(self) -> float:
        return float(self.speed.high or 0)

    @property
    def strides(self) -> bool:
        """Steered once a control period of whole gait cycles (not continuously)."""
        return "steps" in self.roles


def steering(behaviors: Mapping[str, BehaviorSpec]) -> Steering | None:
    """The design's steerable behaviour (the first, by name, whose spec declares its
    steering roles: :class:`gaits.steering.SteerableSpec`), or None."""

    for name in sorted(behaviors):
        spec = behaviors[name]
        if not isinstance(spec, SteerableSpec) or spec.alias_of is not None:
            continue
        ps = {p.name: p for p in spec.params}
        roles = spec.roles
        turn = ps[roles["turn"]]
        kind = {"rad/s": "rate", "rad/m": "curvature"}.get(turn.unit, "bias")
        if kind == "rate" and "seconds" not in roles:
            continue  # a rate needs a period of any length
        return Steering(name, roles, dict(spec.fixed), ps[roles["speed"]], turn, kind)
    return None


def sensing_behaviors(
    behaviors: Mapping[str, BehaviorSpec], abilities: tuple[str, ...] | list[str]
) -> dict[str, BehaviorSpec]:
    """The sensing behaviours of a design with these (locomotion) ``behaviors`` and
    ``abilities``: name -> spec; none when nothing can be steered."""
    steer = steering(behaviors)
    if steer is None:
        return {}
    if steer.strides:
        # the speed role's own parameter (a gait's default: the design's speed, or the
        # waves' frequency), its range
        sp = steer.speed
        speed: tuple[Parameter, ...] = (replace(sp, name="speed"),)  # own default too
        length, distance, radius = GAIT_LENGTH_M, GAIT_DISTANCE_M, GAIT_RADIUS_M
    else:
        top = round(steer.v_max, 3)
        speed = (
            Parameter(
                "speed", "float", round(top / 2, 3), "forward speed", "m/s", low=0.01, high=top
            ),
        )
        length, distance, radius = 2.0, 1.5, 0.5
    out: dict[str, BehaviorSpec] = {}
    # a line is followed with a turn of known effect (a rate or a curvature); a bias whose
    # effect is only learnt steers too loosely for it (measured on the 6-module
    # sidewinder: mapped over its whole range, 21 calibration periods, its bias turns the
    # sensors' path from -0.75 to 12 rad/m, not monotonically, and by what the previous
    # period's bias was (-0.25 turned it -13 degrees after -0.1, which turned it +12);
    # the sensors swing 3 cm across their path within a period; steered through that map
    # it drifts off 0.5-2 m circles, lost 17-42 s of 26-48)
    if "line-tracking" in abilities and steer.kind != "bias":
        out["line-tracking"] = BehaviorSpec(
            "line-tracking",
            "Follow a line on the floor with the two infrared sensors.",
            (
                Parameter(
                    "course",
                    "choice",
                    "circle",
                    "the line: a circle turning left, or a wave",
                    choices=("circle", "wave"),
                ),
                Parameter(
                    "radius", "float", radius, "tightest curve of the line", "m", low=0.2, high=10
                ),
                Parameter("length", "float", length, "how far to follow it", "m", low=0.2, high=20),
                *speed,
            ),
        )
    if "obstacle-avoidance" in abilities:
        out["obstacle-avoidance"] = BehaviorSpec(
            "obstacle-avoidance",
            "Reach a goal line ahead, passing an obstacle set across the way halfway.",
            (
                Parameter("distance", "float", distance, "to the goal line", "m", low=0.5, high=10),
                Parameter("width", "float", 0.15, "the obstacle's width", "m", low=0.02, high=1.0),
                *speed,
            ),
        )
    return out


def scene_xml(xml: str) -> str:
    """``robot.xml`` with the scene's obstacle: a mocap box parked out of the way (it
    collides with nothing until a behaviour sets it up), and a ``contact`` sensor that
    tells at every step whether anything touches it (the session counts those steps from
    what MuJoCo recorded, without a Python call per step)."""
    body = (
        f'<body name="{OBSTACLE}" mocap="true" pos="0 0 -10">'
        f'<geom name="{OBSTACLE}" type="box" size="0.05 0.05 0.05" group="3" '
        'contype="0" conaffinity="0" rgba="0.8 0.2 0.2 1" /></body>'
    )
    sensor = (
        f'<sensor><contact name="{OBSTACLE}_contact" geom1="{OBSTACLE}" num="1" '
        'data="found" /></sensor>'
    )
    at = xml.rfind("</worldbody>")
    end = xml.rfind("</mujoco>")
    if at < 0 or end < at:
        raise ValueError("robot.xml has no worldbody")
    return xml[:at] + body + "\n  " + xml[at:end] + sensor + "\n" + xml[end:]


# -- the sensors -------------------------------------------------------------------------


class SensorNoise:
    """What the sensing loops' sensors read on a perturbed robot
    (``synth/verification/perturb.toml``'s ``[infrared]`` and ``[ultrasonic]``, a perturbation's
    ``sensing`` draws): an infrared sensor sees the line when it is within the tape's half width
    moved by that sensor's edge offset and a fresh jitter; the ranger reads the distance x the
    run's scale plus a fresh noise, rounded to its resolution. The fresh draws come from a
    generator seeded with (stream, seed, 2) in the order the loop reads: a run is replayed to the
    bit. ``None`` (the nominal robot): exact readings, nothing drawn."""

    def __init__(self, drawn: Mapping | None) -> None:
        drawn = drawn or {}
        self.ir = drawn.get("infrared")
        self.us = drawn.get("ultrasonic")
        self.rng = (
            np.random.default_rng([int(drawn["stream"]), int(drawn["seed"]), 2])
            if (self.ir or self.us)
            else None
        )

    def sees(self, k: int, offset: float) -> bool:
        half = LINE_WIDTH_M / 2
        if self.ir is None:
            return abs(offset) <= half
        edge = half + float(self.ir["edge_offset_m"][k])
        edge += float(self.rng.normal(0.0, float(self.ir["edge_jitter_m"])))  # type: ignore[union-attr]
        return abs(offset) <= edge

    def range(self, distance: float) -> float:
        if self.us is None:
            return distance
        r = distance * float(self.us["scale"])
        r += float(self.rng.normal(0.0, float(self.us["noise_m"])))  # type: ignore[union-attr]
        step = float(self.us["resolution_m"])
        return round(r / step) * step if step > 0 else r


class Rig:
    """The sensors on a session's robot: where they sit on the trunk (body frame, m)."""

    def __init__(self, session: Session, forward: np.ndarray) -> None:
        self.session = session
        fwd = np.array([forward[0], forward[1], 0.0])
        self.forward = fwd / np.linalg.norm(fwd)
        self.left = np.array([-self.forward[1], self.forward[0], 0.0])
        trunk = self._corners(trunk_only=True)
        reach = float(np.max(trunk @ self.forward))
        low, high = float(trunk[:, 2].min()), float(trunk[:, 2].max())
        self.front = reach
        #: body-frame points: the infrared pair (left, right) and the ranger
        self.ir = [
            self.forward * reach + side * self.left * IR_SPACING_M / 2 + np.array([0, 0, low])
            for side in (1, -1)
        ]
        self.ranger = self.forward * reach + np.array([0, 0, (low + high) / 2])

    def _corners(self, trunk_only: bool) -> np.ndarray:
        """Corners (N, 3) m of the bounding boxes of the robot's parts (the trunk's only,
        or all), now, in the trunk's frame."""
        m, d = self.session.model, self.session.data
        rot0, pos0 = d.xmat[1].reshape(3, 3), d.xpos[1]
        out = []
        for g in range(m.ngeom):
            b = m.geom_bodyid[g]
            if b == 0 or m.body_mocapid[b] >= 0 or (trunk_only and b != 1):
                continue
            box = m.geom_aabb[g, :3] + m.geom_aabb[g, 3:] * _SIGNS
            world = d.geom_xpos[g] + box @ d.geom_xmat[g].reshape(3, 3).T
            out.append((world - pos0) @ rot0)
        return np.concatenate(out)

    def extent(self) -> tuple[float, float]:
        """(reach m of the robot's parts from the trunk's origin in the ground plane, half
        width m across the forward direction), from every part's bounding box now."""
        pts = self._corners(trunk_only=False)
        return float(np.hypot(pts[:, 0], pts[:, 1]).max()), float(np.abs(pts @ self.left).max())

    def world(self, p: np.ndarray) -> np.ndarray:
        d = self.session.data
        return d.xpos[1] + d.xmat[1].reshape(3, 3) @ p

    def heading(self) -> float:
        """The forward direction's yaw in the world (rad)."""
        f = self.session.data.xmat[1].reshape(3, 3) @ self.forward
        return math.atan2(f[1], f[0])

    def range(self) -> float:
        """The ranger's reading (m): the nearest obstacle in its beam, clipped to its range."""
        import mujoco

        m, d = self.session.model, self.session.data
        rot = d.xmat[1].reshape(3, 3)
        origin = self.world(self.ranger)
        groups = np.zeros(6, dtype=np.uint8)
        groups[3] = 1
        best = RANGER_MAX_M
        geom = np.zeros(1, dtype=np.int32)
        # three rays across the beam, level, and one down its lower edge straight ahead (a
        # ranger mounted above an obstacle's top still sees it from a little way off; the
        # level middle ray is nearer wherever both hit)
        for a, e in (
            (-RANGER_HALF_ANGLE, 0.0),
            (0.0, 0.0),
            (RANGER_HALF_ANGLE, 0.0),
            (0.0, -RANGER_HALF_ANGLE),
        ):
            v = rot @ (math.cos(a) * self.forward + math.sin(a) * self.left)
            v[2] = 0.0
            v /= np.linalg.norm(v)
            v = math.cos(e) * v + np.array([0.0, 0.0, math.sin(e)])
            dist = mujoco.mj_ray(m, d, origin, v, groups, 1, -1, geom)
            if dist >= 0:
                best = min(best, dist)
        best = self.session.noise.range(best)
        return float(min(max(best, RANGER_MIN_M), RANGER_MAX_M))

    def sees(self, k: int, offset: float) -> bool:
        """Infrared sensor ``k``'s reading (0 left, 1 right) ``offset`` m across from the
        line's middle: whether it sees the line (:class:`SensorNoise`)."""
        return self.session.noise.sees(k, offset)


class Course:
    """A line on the floor: a polyline (N, 2) m with arc length ``s`` along it."""

    def __init__(self, points: np.ndarray) -> None:
        self.points = points
        seg = np.diff(points, axis=0)
        self.s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
        self._seg = seg
        self._len2 = np.maximum((seg**2).sum(axis=1), 1e-18)

    @classmethod
    def make(
        cls,
        shape: str,
        radius: float,
        length: float,
        start: np.ndarray,
        heading: float,
        tangent: bool = False,
    ) -> Course:
        """The ``shape`` line ('circle' turning left, or 'wave' of tightest curve
        ``radius``) from ``start`` (x, y) m along ``heading`` rad, ``length`` + 1 m long.
        ``tangent``: the wave starts along ``heading`` (at a trough, bending left as the
        circle does) rather than at its mean, atan(1 / (radius k)) (32-36 degrees) off
        it, which a robot deciding once a gait period loses before it can turn."""
        total = length + 1.0
        s = np.arange(0.0, total + 0.005, 0.005)
        if shape == "circle":
            a = s / radius
            x, y = radius * np.sin(a), radius * (1 - np.cos(a))
        else:  # a sine whose tightest curve has the given radius: A k^2 = 1 / radius
            wavelength = max(4 * radius, 1.0)
            k = 2 * math.pi / wavelength
            amp = 1 / (radius * k * k)
            x = s  # (arc length is recomputed from the points)
            y = amp * (1 - np.cos(k * x)) if tangent else amp * np.sin(k * x)
        c, sn = math.cos(heading), math.sin(heading)
        pts = np.stack([start[0] + c * x - sn * y, start[1] + sn * x + c * y], axis=1)
        return cls(pts)

    def locate(self, p: np.ndarray, near_s: float, window: float = 0.3) -> tuple[float, float]:
        """(arc length s m, signed distance m, + to the left of the line) of the point of
        the line nearest ``p`` within ``window`` of ``near_s``."""
        i0 = max(0, int(np.searchsorted(self.s, near_s - window)) - 1)
        i1 = min(len(self._seg), int(np.searchsorted(self.s, near_s + window)) + 1)
        a, seg, l2 = self.points[i0:i1], self._seg[i0:i1], self._len2[i0:i1]
        t = np.clip(((p - a) * seg).sum(axis=1) / l2, 0.0, 1.0)
        q = a + seg * t[:, None]
        d2 = ((q - p) ** 2).sum(axis=1)
        k = int(np.argmin(d2))
        cross = seg[k, 0] * (p[1] - a[k, 1]) - seg[k, 1] * (p[0] - a[k, 0])
        s = float(self.s[i0 + k] + t[k] * math.sqrt(l2[k]))
        return s, math.copysign(math.sqrt(float(d2[k])), cross)


# -- the behaviours --------------------------------------------------------------------


def run(session: Session, name: str, params: Mapping[str, object]) -> tuple[dict, dict]:
    """Run sensing behaviour ``name`` on ``session`` from where the robot is: (figures,
    info) for :func:`synth.verification.verdict.judge`."""
    steer = steering(session.controller.behaviors)
    assert steer is not None
    if steer.strides:
        from program.script import ProgramError

        try:  # (a speed the gait cannot reach: said like a behaviour's own parameter)
            strider = _Strider(session, steer, params["speed"])
        except ValueError as exc:
            raise ProgramError(f"{name}: {exc}") from None
        rig = Rig(session, strider.forward)
        if name == "line-tracking":
            return _line_strides(session, strider, rig, params)
        return _avoid_strides(session, strider, rig, params)
    mover = _Driver(session, steer, float(params["speed"]))
    rig = Rig(session, mover.forward_axis())
    if name == "line-tracking":
        return _line(session, mover, rig, params)
    return _avoid(session, mover, rig, params)


#: Plans a driven loop remembers (:class:`_Driver`): a few turn rates, asked again and again.
PLAN_MEMO = 256


class _Driver:
    """Runs the steerable behaviour one control period at a time: forward while turning
    (``go``, curvature rad/m) or turning in place (``spin``) at rates that fit the drive
    (a drive that cannot turn in place, steered wheels, spins on its tightest arc).
    ``speed`` m/s: its forward speed."""

    def __init__(self, session: Session, steer: Steering, speed: float) -> None:
        self.session, self.steer = session, steer
        self.period = 1.0 / CONTROL_HZ
        #: the tightest curvature 1/m the drive takes (None: any the wheels' speed allows;
        #: a steered drive's is its steering limit, found by ``fit``)
        self.k_cap: float | None = None
        #: a drive that rolls on from its last turn (a ``turn_from`` role: steered wheels,
        #: whose steering turns only so fast): the curvature 1/m its last period ended on
        self.k_now = 0.0
        #: the plans asked for so far (a loop asks for the same few again and again; the
        #: controller plans the same for the same ask): ask -> plan, or the error it gave
        self._plans: dict[tuple, object] = {}
        self.speed = self.fit(speed, 0.0)[0]
        self.w_spin = 0.0

    def _plan(self, v: float, w: float):
        r = self.steer.roles
        ask = {r["speed"]: v, r["turn"]: w, r["seconds"]: self.period, **self.steer.fixed}
        if "turn_from" in r:
            ask[r["turn_from"]] = self.k_now * v
        key = tuple(sorted((k, repr(x)) for k, x in ask.items()))
        got = self._plans.get(key)
        if got is None:
            try:
                got = self.session.controller.run(self.steer.behavior, **ask)
            except ValueError as e:
                got = e
            if len(self._plans) < PLAN_MEMO:
                self._plans[key] = got
        if isinstance(got, ValueError):
            raise got
        return got

    def forward_axis(self) -> np.ndarray:
        """The body-frame direction the robot goes forward in."""
        traj = self._plan(self.steer.v_max / 2, 0.0)
        dx, dy, _ = (float(c) for c in traj.info["planned_pose"])  # type: ignore[union-attr]
        return np.array([dx, dy]) / math.hypot(dx, dy)

    def fit(self, v: float, w: float) -> tuple[float, float]:
        """(v, w) scaled down together until the behaviour accepts them; a curve that no
        speed takes (a steered drive's, tighter than its steering allows) is opened to the
        tightest it takes at ``v`` (``k_cap``, remembered)."""
        if self.k_cap is not None and abs(w) > self.k_cap * abs(v):
            w = math.copysign(self.k_cap * abs(v), w)
        v0, w0 = v, w
        for _ in range(40):
            try:
                self._plan(v, w)
                return v, w
            except ValueError:
                v, w = 0.9 * v, 0.9 * w
        if v0 == 0 or w0 == 0:
            return 0.0, 0.0
        low, high = 0.0, abs(w0)  # the largest |w| planned at v0
        for _ in range(30):
            mid = (low + high) / 2
            try:
                self._plan(v0, math.copysign(mid, w0))
                low = mid
            except ValueError:
                high = mid
        if low == 0:
            return 0.0, 0.0
        self.k_cap = low / abs(v0)
        return v0, math.copysign(low, w0)

    def step(self, v: float, w: float) -> None:
        """One control period at (v, w), both scaled down if the wheels cannot."""
        try:
            traj = self._plan(v, w)
        except ValueError:
            v, w = self.fit(v, w)
            traj = self._plan(v, w)
        if "turn_from" in self.steer.roles:
            end = float(traj.info.get("turn_end", w))  # type: ignore[arg-type]
            self.k_now = end / v if v else 0.0
        self.session._play(traj.joints, traj.positions, traj.velocities, self.period, plan=traj)

    def go(self, curvature: float) -> None:
        self.step(self.speed, curvature * self.speed)

    def spin(self, sense: float) -> None:
        if self.w_spin == 0 and self.k_cap is not None:  # no turn in place: the tightest arc
            self.step(self.speed, sense * self.k_cap * self.speed)
            return
        self.step(0.0, sense * self.w_spin)

    def tightest(self) -> float:
        """The radius m of the tightest arc at the forward speed when the drive cannot turn
        in place (it turns by arcs, a steered drive), else 0."""
        if self.fit(0.0, 1.0)[1] != 0:
            return 0.0
        self.fit(self.speed, 1e3 * self.speed)  # finds k_cap
        return 1.0 / self.k_cap if self.k_cap else 0.0


def _line(session: Session, mover: _Driver, rig: Rig, params: Mapping) -> tuple[dict, dict]:
    if "turn_from" in mover.steer.roles:
        return _line_rolling(session, mover, rig, params)
    radius, length = (float(params[k]) for k in ("radius", "length"))
    # turn hard enough to follow the tightest curve and to swing the sensors, a lever
    # ``front`` ahead of the turning axis, back over the line within a sensor's span
    lever = max(rig.front, IR_SPACING_M)
    curve = TURN_GAIN * (1 / radius + 1 / lever)
    v, w = mover.fit(mover.speed, curve * mover.speed)
    mover.speed, curve = v, (w / v if v > 0 else 0.0)
    mid, start, course, budget, state = _line_course(session, rig, params, mover.speed)
    t0 = state["next"]
    state["turn"] = 0.0
    half_span = IR_SPACING_M / 2 + LINE_WIDTH_M / 2

    def read(t: float) -> None:
        """The sensors read at CONTROL_HZ while the robot moves: the side the line was
        last seen on, and how long it has been outside the sensors' span."""
        if t < state["next"] - 1e-9:
            return
        state["next"] = t + 1.0 / CONTROL_HZ
        on = [
            rig.sees(k, course.locate(rig.world(p)[:2], state["s"])[1])
            for k, p in enumerate(rig.ir)
        ]
        if on[0] and not on[1]:
            state["turn"] = 1.0  # the line is under the left sensor: turn left
        elif on[1] and not on[0]:
            state["turn"] = -1.0
        elif on[0] and on[1]:
            state["turn"] = 0.0
        # neither: keep turning the way the line went last (or straight on)
        state["s"], off = course.locate(rig.world(mid)[:2], state["s"])
        state["worst"] = max(state["worst"], abs(off))
        state["lost"] = state["lost"] + 1.0 / CONTROL_HZ if abs(off) > half_span else 0.0
        state["longest"] = max(state["longest"], state["lost"])

    session.on_step = read
    try:
        read(session.time)
        while session.time - t0 < budget and state["s"] < length:
            mover.go(state["turn"] * curve)
    finally:
        session.on_step = None
    return _line_outcome(session.time - t0, state, length, params)


def _line_course(
    session: Session, rig: Rig, params: Mapping, speed: float, tangent: bool = False
) -> tuple[np.ndarray, np.ndarray, Course, float, dict]:
    """A line-tracking run set up: the sensors' midpoint (in the trunk) and where it starts
    (world x, y), the course laid from there along the heading (shown in the scene;
    ``tangent``: see :meth:`Course.make`), the time allowed at ``speed`` m/s
    (:data:`BUDGET`), and the reader's fresh ``state`` (:func:`_line_reader`; its
    ``next`` read is now)."""
    radius, length = (float(params[k]) for k in ("radius", "length"))
    mid = (rig.ir[0] + rig.ir[1]) / 2
    start = rig.world(mid)[:2]
    kind = str(params["course"])
    course = Course.make(kind, radius, length, start, rig.heading(), tangent=tangent)
    session.scene_line = course.points
    factor, extra = BUDGET["follow-line"]
    budget = factor * length / max(speed, 1e-6) + extra
    state = {"s": 0.0, "next": session.time, "lost": 0.0, "longest": 0.0, "worst": 0.0}
    return mid, start, course, budget, state


def _obstacle_course(
    session: Session, rig: Rig, distance: float, width: float, speed: float
) -> tuple[float, np.ndarray, np.ndarray, float]:
    """An obstacle-avoidance run set up: the heading it starts with, its unit vector, the
    ranger's start (world x, y), the obstacle placed across the way halfway along
    ``distance`` (``width`` m wide), and the time allowed at ``speed`` m/s
    (:data:`BUDGET`)."""
    heading0 = rig.heading()
    fwd = np.array([math.cos(heading0), math.sin(heading0)])
    origin = rig.world(rig.ranger)[:2]
    _place_obstacle(session, origin + fwd * distance / 2, heading0, width)
    factor, extra = BUDGET["avoid"]
    return heading0, fwd, origin, factor * distance / max(speed, 1e-6) + extra


def _line_outcome(
    seconds: float, state: Mapping, length: float, params: Mapping
) -> tuple[dict, dict]:
    """A line-tracking run's figures (from the reader's ``state``, :func:`_line_reader`)
    and what it promised, for :func:`synth.verification.verdict.judge`."""
    fig = {
        "seconds": seconds,
        "line_progress_m": state["s"],
        "planned_distance_m": length,
        "line_lost_s": state["longest"],
        "max_line_offset_m": state["worst"],
    }
    return fig, {"motion": SENSING["line-tracking"], "course": str(params["course"])}


def _line_reader(
    course: Course, rig: Rig, mid: np.ndarray, state: dict, reads: list
) -> Callable[[float], None]:
    """The sensors read at :data:`CONTROL_HZ` while the robot moves (a session's
    ``on_step``): every infrared reading appended to ``reads`` as (x, y, 1 if it saw the
    line else 0), and in ``state`` how far along the line the sensors' midpoint ``mid`` is
    (``s``), its largest offset (``worst``) and how long it has been, and at most was,
    outside the sensors' span (``lost``, ``longest``); ``state["next"]`` is the next read."""
    half_span = IR_SPACING_M / 2 + LINE_WIDTH_M / 2

    def read(t: float) -> None:
        if t < state["next"] - 1e-9:
            return
        state["next"] = t + 1.0 / CONTROL_HZ
        for k, p in enumerate(rig.ir):
            w = rig.world(p)[:2]
            on = rig.sees(k, course.locate(w, state["s"])[1])
            reads.append((float(w[0]), float(w[1]), 1.0 if on else 0.0))
        state["s"], off = course.locate(rig.world(mid)[:2], state["s"])
        state["worst"] = max(state["worst"], abs(off))
        state["lost"] = state["lost"] + 1.0 / CONTROL_HZ if abs(off) > half_span else 0.0
        state["longest"] = max(state["longest"], state["lost"])

    return read


#: A drive that rolls on from its last turn (steered wheels) follows the line this far
#: ahead of its sensors' midpoint (m, at least): it closes the line's offset and angle
#: over it (:func:`_pursue`), and the loop's estimate weighs the readings within 1.5 x it.
ROLLING_LOOKAHEAD_M = 0.15


def _line_rolling(session: Session, mover: _Driver, rig: Rig, params: Mapping) -> tuple[dict, dict]:
    """Line-tracking for a drive that rolls on from its last turn (steered wheels, whose
    steering servo turns only so fast): the sensors are read at :data:`CONTROL_HZ` and
    every reading kept (where the sensor was, whether it saw the line); every period the
    robot locates the line near its sensors from them (:func:`_locate_line`, about the
    curvature it rolls on) and asks for the arc that brings the sensors' midpoint onto it
    (:func:`_pursue`, within the steering limit); the behaviour turns the steering toward
    it while rolling, as fast as the servo turns under load."""
    radius, length = (float(params[k]) for k in ("radius", "length"))
    mover.tightest()  # the steering limit's curvature, k_cap
    k_cap = mover.k_cap if mover.k_cap else math.inf
    mid, start, course, budget, state = _line_course(session, rig, params, mover.speed)
    t0 = state["next"]
    reads: list[tuple[float, float, float]] = [(*start, 1.0)]
    look = max(ROLLING_LOOKAHEAD_M, 2 * mover.speed / CONTROL_HZ)
    est: dict = {}  # the line as last located

    read = _line_reader(course, rig, mid, state, reads)

    session.on_step = read
    try:
        read(session.time)
        while session.time - t0 < budget and state["s"] < length:
            k = _pursue(rig, np.array(reads), mid, look / LOOKAHEAD_PERIODS, mover.k_now, est)
            mover.go(float(np.clip(k, -k_cap, k_cap)))
    finally:
        session.on_step = None
    return _line_outcome(session.time - t0, state, length, params)


def _avoid(session: Session, mover: _Driver, rig: Rig, params: Mapping) -> tuple[dict, dict]:
    distance, width = (float(params[k]) for k in ("distance", "width"))
    m = session.model
    # the robot's reach from its turning axis (what sweeps when it turns in place) and its
    # half width across the way it goes, from its parts' boxes
    corner, half = rig.extent()
    corner = max(corner, rig.front)
    ahead = 2 * mover.speed / CONTROL_HZ  # what it covers before it reacts
    mover.w_spin = mover.fit(0.0, 2 * mover.speed / max(corner, 0.05))[1]
    safe = corner - rig.front + CLEARANCE_M + ahead
    if mover.w_spin == 0:  # it turns by arcs (steered wheels): it swerves from further off
        safe += mover.tightest()
    heading0, fwd, origin, budget = _obstacle_course(session, rig, distance, width, mover.speed)
    t0 = session.time
    state, min_range, seen = "go", RANGER_MAX_M, RANGER_MAX_M
    passed_from = origin
    cleared: tuple[float, float] | None = None
    progress = 0.0
    contacts0 = session._counts["contacts"]
    try:
        while session.time - t0 < budget and progress < distance:
            r = rig.range()
            min_range = min(min_range, r)
            here = rig.world(rig.ranger)[:2]
            if state == "go" and r < safe:
                state, seen = "turn", r
            if state == "turn":
                if r < 2 * safe:
                    seen = r  # the obstacle's edge is still in the beam
                elif cleared is None:
                    # the beam has just passed the edge, seen ``seen`` ahead at about the
                    # beam's half angle: turn on until the body's half width clears it
                    need = math.asin(min(1.0, (half + CLEARANCE_M) / max(seen, 1e-3)))
                    cleared = (rig.heading(), max(0.0, need - RANGER_HALF_ANGLE))
                if cleared is not None and _turned(rig.heading(), cleared[0]) >= cleared[1]:
                    state, passed_from, cleared = "pass", here.copy(), None
                    mover.go(0.0)
                else:
                    mover.spin(1.0)
            elif state == "pass":
                mover.go(0.0)
                # on past the obstacle's depth and the robot's own length
                if float(np.hypot(*(here - passed_from))) > safe + 2 * corner + OBSTACLE_DEPTH_M:
                    state = "go"
            else:
                err = (heading0 - rig.heading() + math.pi) % (2 * math.pi) - math.pi
                # back to the first heading: a curve that turns by err over 1 / HEADING_GAIN s
                mover.go(HEADING_GAIN * err / max(mover.speed, 1e-6))
            progress = float((rig.world(rig.ranger)[:2] - origin) @ fwd)
    finally:
        _park_obstacle(session)
    contact_s = (session._counts["contacts"] - contacts0) * m.opt.timestep
    fig = {
        "seconds": session.time - t0,
        "distance_m": progress,
        "planned_distance_m": distance,
        "obstacle_contact_s": contact_s,
        "min_range_m": min_range,
    }
    return fig, {"motion": SENSING["obstacle-avoidance"]}


# -- stride by stride: gaits that start and end at rest -----------------------------------


class _Strider:
    """Runs a stride-steered behaviour (:attr:`Steering.strides`) one control period of
    :data:`PERIOD_CYCLES` gait cycles at a time, from where the robot stands, turning at a
    curvature (rad/m) of the trunk's path: given as it is to a ``curvature`` turn, turned
    into a bias for a ``bias`` turn through what the loop has learnt of the bias's effect
    on the heading (:meth:`calibrate`, then every period). A curvature or bias the
    behaviour refuses (a foot out of reach, a joint too fast) is eased until it accepts.

    ``travel`` m and ``duration`` s: how far one straight period goes and how long it
    takes (planned, or measured by :meth:`calibrate` when the behaviour plans no pose)."""

    def __init__(self, session: Session, steer: Steering, speed: object) -> None:
        from program.script import LIMITS

        self.session, self.steer = session, steer
        self.speed = speed
        self.limit = float(LIMITS["sim_s"])
        spec = session.controller.behaviors[steer.behavior]
        steps = {p.name: p for p in spec.params}[steer.roles["steps"]]
        self.cycles = max(PERIOD_CYCLES, int(steps.low or 1))
        self.k_max = {1.0: math.inf, -1.0: math.inf}  # tightest curvature accepted so far
        self.seen: list[tuple[float, float]] = []  # (bias, heading change rad) per period
        self.path: list[tuple[float, float]] = []  # (heading change rad, m moved) per period
        straight = self._plan(0.0)
        self.duration = straight.duration
        pose = straight.info.get("planned_pose")
        way = pose[:2] if pose is not None else straight.info.get("direction", (1.0, 0.0))
        way = np.array([float(c) for c in way])  # type: ignore[union-attr]
        self.forward = way / np.linalg.norm(way)
        self.travel = float(np.hypot(*pose[:2])) if pose is not None else 0.0  # type: ignore[index]

    def _plan(self, turn: float, periods: int = 1):
        r = self.steer.roles
        return self.session.controller.run(
            self.steer.behavior,
            **{
                r["speed"]: self.speed,
                r["turn"]: turn,
                r["steps"]: periods * self.cycles,
                **self.steer.fixed,
            },
        )

    def travel_of(self, periods: int) -> float:
        """How far ``periods`` periods run as one straight plan go, m (planned; else
        ``periods`` x :attr:`travel`)."""
        pose = self._plan(0.0, periods).info.get("planned_pose")
        return float(np.hypot(*pose[:2])) if pose is not None else periods * self.travel  # type: ignore[index]

    @property
    def v(self) -> float:
        """The robot's speed m/s on a straight line, stops between periods included."""
        return self.travel / max(self.duration, 1e-9)

    def calibrate(self, rig: Rig) -> None:
        """For a ``bias`` turn: run one period at each of :data:`BIAS_PROBES` of the
        largest bias, measuring the heading change (learnt) and the travel (its mean)."""
        if self.steer.kind != "bias":
            return
        top = float(self.steer.turn.high or 1.0)
        moved = []
        for share in BIAS_PROBES:
            start = rig.world(rig.ranger)[:2]
            h0 = rig.heading()
            self._run(share * top, rig)
            moved.append(float(np.hypot(*(rig.world(rig.ranger)[:2] - start))))
            self.seen.append((share * top, _turned(rig.heading(), h0)))
        self.travel = float(np.mean(moved))

    def _bias(self, dyaw: float) -> float:
        """The bias that turns the heading by ``dyaw`` rad in a period: dyaw = a + b bias
        fitted by least squares on every period seen."""
        top = float(self.steer.turn.high or 1.0)
        x = np.array([[1.0, b] for b, _ in self.seen])
        y = np.array([t for _, t in self.seen])
        (a, b), *_ = np.linalg.lstsq(x, y, rcond=None)
        if abs(b) < 1e-6:
            return 0.0
        return float(np.clip((dyaw - a) / b, -top, top))

    def tightest(self, side: float) -> float:
        """For a bias: the tightest curvature rad/m it turns toward ``side`` (+1 left) at
        its largest bias, as learnt (0 when it does not turn that way)."""
        top = float(self.steer.turn.high or 1.0)
        x = np.array([[1.0, b] for b, _ in self.seen])
        y = np.array([t for _, t in self.seen])
        (a, b), *_ = np.linalg.lstsq(x, y, rcond=None)
        turn = side * max(a + b * top, a - b * top, key=lambda t: side * t)
        return max(turn, 0.0) / max(self.travel, 1e-6)

    def room(self) -> bool:
        """Whether one more period fits in the session's simulated time."""
        return self.session.time + self.duration * 1.5 <= self.limit

    @property
    def aside(self) -> bool:
        """Whether the behaviour also goes sideways (a ``direction`` role, rad)."""
        return "direction" in self.steer.roles

    def sidestep(self, side: float) -> None:
        """:data:`SIDESTEP_PERIODS` periods straight to the left (``side`` +1) or right
        (-1), not turning."""
        r = self.steer.roles
        ask = {
            r["turn"]: 0.0,
            r["steps"]: SIDESTEP_PERIODS * self.cycles,
            r["direction"]: side * math.pi / 2,
            **self.steer.fixed,
        }
        run = self.session.controller.run
        try:
            traj = run(self.steer.behavior, **ask, **{r["speed"]: self.speed})
        except ValueError:  # sideways may not reach the speed forward does: its default
            traj = run(self.steer.behavior, **ask)
        self._follow(traj)

    def step(self, curvature: float, rig: Rig, periods: int = 1) -> float:
        """One period (or ``periods`` as one plan: a curvature turn) turning at
        ``curvature`` rad/m (eased until the behaviour accepts it); the curvature it was
        asked with."""
        if self.steer.kind == "curvature":
            k = float(np.clip(curvature, -self.k_max[-1.0], self.k_max[1.0]))
            for _ in range(12):
                k = round(k, 2)  # (plans of the same arc are remembered)
                try:
                    traj = self._plan(k, periods)
                    break
                except ValueError:
                    sense = math.copysign(1.0, k)
                    self.k_max[sense] = 0.7 * abs(k)
                    k = 0.7 * k
            else:
                traj = self._plan(0.0)
                k = 0.0
            self._follow(traj)
            return k
        bias = self._bias(curvature * self.travel)
        self._run(bias, rig)
        return curvature

    def _run(self, bias: float, rig: Rig) -> None:
        h0 = rig.heading()
        for _ in range(12):
            try:
                traj = self._plan(round(bias, 3))
                break
            except ValueError:
                bias *= 0.7
        else:
            traj = self._plan(0.0)
            bias = 0.0
        self._follow(traj)
        self.seen.append((round(bias, 3), _turned(rig.heading(), h0)))

    def _follow(self, traj) -> None:
        self.duration = max(self.duration, traj.duration)
        d = self.session.data
        p0, f0 = d.xpos[1][:2].copy(), d.xmat[1].reshape(3, 3)[:2, 0].copy()
        self.session.follow(traj)
        f1 = d.xmat[1].reshape(3, 3)[:2, 0]
        turn = math.atan2(f0[0] * f1[1] - f0[1] * f1[0], f0 @ f1)
        self.path.append((turn, float(np.hypot(*(d.xpos[1][:2] - p0)))))

    def path_curvature(self, periods: int) -> float:
        """The curvature rad/m of the trunk's path over the last ``periods`` periods (its
        heading change over the distance it moved), 0 before any."""
        last = self.path[-periods:]
        moved = sum(m for _, m in last)
        return sum(t for t, _ in last) / moved if moved > 1e-6 else 0.0


def _line_strides(
    session: Session, mover: _Strider, rig: Rig, params: Mapping
) -> tuple[dict, dict]:
    """Line-tracking stride by stride: the sensors are read at :data:`CONTROL_HZ` while the
    robot walks; every reading (where the sensor was, as the robot's odometry gives it, and
    whether it saw the line) is kept, and once a period the robot locates the line near
    its sensors from them (:func:`_locate_line`) and walks the arc that brings the
    sensors' midpoint onto it (:func:`_pursue`)."""
    radius, length = (float(params[k]) for k in ("radius", "length"))
    mover.calibrate(rig)
    # (a wave starts along the heading: the robot decides once a period, see Course.make)
    mid, start, course, budget, state = _line_course(session, rig, params, mover.v, True)
    t0 = state["next"]
    # it starts on the line, along it
    # every reading: (x, y) m where the sensor was, and whether it saw the line; it starts
    # with the line under the sensors' midpoint (which way it goes, it learns)
    reads: list[tuple[float, float, float]] = [(*start, 1.0)]

    read = _line_reader(course, rig, mid, state, reads)

    session.on_step = read
    try:
        read(session.time)
        while session.time - t0 < budget and state["s"] < length and mover.room():
            bend = mover.path_curvature(FF_PERIODS)
            mover.step(_pursue(rig, np.array(reads), mid, mover.travel, bend), rig)
    finally:
        session.on_step = None
    return _line_outcome(session.time - t0, state, length, params)


#: The line hypotheses a line follower weighs (:func:`_locate_line`): its offset from
#: the sensors' midpoint (m), its angle from the heading (rad) and its curvature about the
#: trunk's recent one (rad/m): (largest, step) each.
LINE_OFFSETS, LINE_ANGLES, LINE_CURVES = (0.08, 0.002), (0.6, 0.02), (1.0, 0.25)


def _locate_line(
    reads: np.ndarray,
    here: np.ndarray,
    heading: float,
    bend: float,
    prior: tuple[float, float, float] | None = None,
) -> tuple[float, float, float]:
    """The line near the sensors as the readings tell it: (offset m, + to the left, of the
    line from ``here`` across ``heading``; its angle rad from the heading; its curvature
    rad/m), the mean of the hypotheses (y = offset + tan(angle) x + curvature x^2 / 2 in
    the frame at ``here`` along ``heading``; the curvature ``bend`` +- :data:`LINE_CURVES`)
    that the most readings agree with: a sensor that saw the line within half its width
    of it, one that did not farther (readings (x, y, seen) in the world)."""
    f = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-f[1], f[0]])
    rel = reads[:, :2] - here
    x, y, seen = rel @ f, rel @ left, reads[:, 2] > 0.5
    grid = [np.arange(-top, top + step / 2, step) for top, step in (LINE_OFFSETS, LINE_ANGLES)]
    curves = bend + np.arange(-LINE_CURVES[0], LINE_CURVES[0] + 1e-9, LINE_CURVES[1])
    a, t, c = np.meshgrid(grid[0], np.tan(grid[1]), curves, indexing="ij")
    a, t, c = a.ravel(), t.ravel(), c.ravel()
    score = np.zeros(len(a))
    half = LINE_WIDTH_M / 2
    for k in range(0, len(x), 64):  # (in chunks: hypotheses x readings)
        xs, ys, on = x[k : k + 64], y[k : k + 64], seen[k : k + 64]
        d = np.abs(ys[None, :] - (a[:, None] + t[:, None] * xs + c[:, None] * xs * xs / 2))
        score += np.where(on[None, :], d <= half, d >= half).sum(axis=1)
    best = score >= score.max() - 0.5
    if prior is not None:  # (tracking: of the best, the nearest to the last estimate)
        ang = np.arctan(t[best])
        gap = (
            np.abs(a[best] - prior[0]) / LINE_OFFSETS[1]
            + np.abs(ang - prior[1]) / LINE_ANGLES[1]
            + np.abs(c[best] - prior[2]) / LINE_CURVES[1]
        )
        i = int(np.argmin(gap))
        return float(a[best][i]), float(ang[i]), float(c[best][i])
    return float(a[best].mean()), float(np.arctan(t[best]).mean()), float(c[best].mean())


def _pursue(
    rig: Rig,
    reads: np.ndarray,
    mid: np.ndarray,
    travel: float,
    bend: float,
    track: dict | None = None,
) -> float:
    """The curvature rad/m of the trunk's next arc: the line near the sensors' midpoint
    (``mid``, trunk frame) as the readings within :data:`LINE_MEMORY_PERIODS` periods'
    ``travel`` tell it (:func:`_locate_line`, about the trunk's recent curvature
    ``bend``); the arc closes its offset and its angle over :data:`LOOKAHEAD_PERIODS`
    periods' travel (pure pursuit, linearised) and follows its curve."""
    h = rig.heading()
    here = rig.world(mid)[:2]
    near = reads[np.hypot(*(reads[:, :2] - here).T) <= max(LINE_MEMORY_PERIODS * travel, 0.05)]
    prior = None if track is None else track.get("line")
    offset, angle, curve = _locate_line(near if len(near) else reads[-2:], here, h, bend, prior)
    if track is not None:
        track["line"] = (offset, angle, curve)
    # the midpoint, ``front`` ahead of the trunk, after ``look`` m of an arc k moves
    # across by about k (look^2 / 2 + front look); the line there, ahead of it, by
    # offset + angle look + bend look^2 / 2
    look = max(LOOKAHEAD_PERIODS * travel, 0.02)
    front = float(mid @ rig.forward)
    return (offset + angle * look + curve * look * look / 2) / (look * look / 2 + front * look)


def _avoid_strides(
    session: Session, mover: _Strider, rig: Rig, params: Mapping
) -> tuple[dict, dict]:
    """Obstacle-avoidance stride by stride: the ranger is read at :data:`CONTROL_HZ` while
    the robot goes; once a period it decides. It goes on steering back to its first
    heading until the obstacle is nearer than it can swerve from (two periods' travel,
    its turning radius and the clearance); then it turns, period by period, toward the
    side its body reaches least beyond the ranger (a sidewinding snake's body trails on
    one side), until the beam has passed the obstacle's edge and its own reach on that
    side clears it too; goes straight past it by its distance, the obstacle's depth and
    its own length; and steers back to its first heading."""
    distance, width = (float(params[k]) for k in ("distance", "width"))
    mover.calibrate(rig)
    pts = rig._corners(trunk_only=False)
    lateral, along = pts @ rig.left, pts @ rig.forward
    r_lat, r_fwd = float(rig.ranger @ rig.left), float(rig.ranger @ rig.forward)
    reach = {1.0: r_lat - float(lateral.min()), -1.0: float(lateral.max()) - r_lat}
    side = 1.0 if reach[1.0] <= reach[-1.0] + 1e-9 else -1.0  # to the left on a tie
    behind = r_fwd - float(along.min())
    sweep = float(np.hypot(lateral, along).max())  # its parts' reach from the trunk's origin
    travel = max(mover.travel, 1e-3)
    heading0, fwd, origin, budget = _obstacle_course(session, rig, distance, width, mover.v)
    t0 = session.time
    contacts0 = session._counts["contacts"]
    reads = {"next": t0, "min": RANGER_MAX_M, "period": RANGER_MAX_M}

    def read(t: float) -> None:
        if t < reads["next"] - 1e-9:
            return
        reads["next"] = t + 1.0 / CONTROL_HZ
        r = rig.range()
        reads["min"] = min(reads["min"], r)
        reads["period"] = min(reads["period"], r)
        path.append(rig.world(rig.ranger)[:2])

    # how far the ranger swings across its way within a period (a snake's head wiggles
    # with the waves): added to the clearance
    path: list[np.ndarray] = []
    swing = 0.0

    def swung() -> float:
        if len(path) < 3:
            return 0.0
        a, b = path[0], path[-1]
        chord = b - a
        n = float(np.hypot(*chord))
        if n < 1e-6:
            return 0.0
        across = np.array([-chord[1], chord[0]]) / n
        return float(np.abs((np.array(path) - a) @ across).max())

    turn_k = side * (math.pi / 4) / travel  # up to an eighth of a turn a period
    state, seen, progress, tries = "go", RANGER_MAX_M, 0.0, 0
    cleared: tuple[float, float] | None = None
    passed_from = origin
    session.on_step = read
    if mover.aside:
        ahead = float(along.max()) - r_fwd  # parts reaching beyond the ranger (feet)
        try:
            read(session.time)
            progress = _sidestep_past(
                session, mover, rig, budget, distance, reach, ahead, heading0, origin, read
            )
        finally:
            session.on_step = None
            _park_obstacle(session)
        contact_s = (session._counts["contacts"] - contacts0) * session.model.opt.timestep
        return {
            "seconds": session.time - t0,
            "distance_m": progress,
            "planned_distance_m": distance,
            "obstacle_contact_s": contact_s,
            "min_range_m": reads["min"],
        }, {"motion": SENSING["obstacle-avoidance"]}
    try:
        read(session.time)
        while session.time - t0 < budget and progress < distance and mover.room():
            here = rig.world(rig.ranger)[:2]
            r = min(reads["period"], rig.range())
            reads["period"] = RANGER_MAX_M
            swing = max(swing, swung())
            path.clear()
            # what it needs to swerve: the travel before it reacts, the radius it turns on
            radius = 1.0 / max(
                mover.tightest(side)
                if mover.steer.kind == "bias"
                else min(abs(turn_k), mover.k_max[side]),
                1e-3,
            )
            trigger = 2 * travel + min(radius, distance / 2) / 2 + CLEARANCE_M
            if radius < sweep:  # it turns about a point within its reach: its parts sweep
                # up to their reach plus the radius ahead of the turn's centre
                trigger = max(trigger, 2 * travel + sweep + radius - r_fwd + CLEARANCE_M)
            if state == "go" and r < trigger:
                state, seen = "turn", r
            if state == "turn":
                now = rig.range()
                if now < 2 * trigger:
                    seen = min(seen, now)
                    cleared = None
                    mover.step(turn_k, rig)
                    continue
                if cleared is None:
                    tries = 0
                    clear = reach[side] + CLEARANCE_M + swing
                    need = math.asin(min(1.0, clear / max(seen, 1e-3)))
                    cleared = (rig.heading(), max(0.0, need - RANGER_HALF_ANGLE))
                left = cleared[1] - side * _turned(rig.heading(), cleared[0])
                if left > TURN_TOLERANCE and tries < TURN_TRIES:
                    tries += 1
                    mover.step(side * left / travel, rig)
                    continue
                state, passed_from, cleared = "pass", here.copy(), None
            if state == "pass":
                if float(np.hypot(*(here - passed_from))) > seen + OBSTACLE_DEPTH_M + behind:
                    state = "go"
                else:
                    mover.step(0.0, rig)
            if state == "go":
                err = _turned(heading0, rig.heading())
                mover.step(0.5 * err / travel, rig)  # back to it over about two periods
            progress = float((rig.world(rig.ranger)[:2] - origin) @ fwd)
    finally:
        session.on_step = None
        _park_obstacle(session)
    contact_s = (session._counts["contacts"] - contacts0) * session.model.opt.timestep
    fig = {
        "seconds": session.time - t0,
        "distance_m": progress,
        "planned_distance_m": distance,
        "obstacle_contact_s": contact_s,
        "min_range_m": reads["min"],
    }
    return fig, {"motion": SENSING["obstacle-avoidance"]}


def _sidestep_past(
    session: Session,
    mover: _Strider,
    rig: Rig,
    budget: float,
    distance: float,
    reach: Mapping[float, float],
    ahead: float,
    heading0: float,
    origin: np.ndarray,
    read,
) -> float:
    """Obstacle-avoidance for a behaviour that also goes sideways (legs): it goes on,
    holding its first heading, until the obstacle is nearer than the parts that reach
    beyond the ranger, two periods' travel and the clearance; then steps sideways (to the
    left, or to the side its body reaches least beyond the ranger), period by period,
    until the beam has passed the obstacle's edge and, by odometry, its own reach on the
    other side clears it too; then goes on to the goal line. Far from the obstacle, and
    past it, it goes :data:`SIDESTEP_PERIODS` periods at a time. Its progress, m."""
    t0 = session.time
    travel = max(mover.travel, 1e-3)
    fwd = np.array([math.cos(heading0), math.sin(heading0)])
    left0 = np.array([-fwd[1], fwd[0]])
    side = 1.0 if reach[1.0] <= reach[-1.0] + 1e-9 else -1.0
    trigger = ahead + 2 * travel + CLEARANCE_M
    # away from the obstacle it goes SIDESTEP_PERIODS periods at a time (one start and
    # stop for all: faster)
    far = mover.travel_of(SIDESTEP_PERIODS)
    state, seen, progress, passed = "go", RANGER_MAX_M, 0.0, False
    start = origin
    remaining = 0.0
    while session.time - t0 < budget and progress < distance and mover.room():
        here = rig.world(rig.ranger)[:2]
        now = rig.range()
        if state == "go" and now < trigger:
            state, seen = "aside", now
        if state == "aside":
            if now < seen + OBSTACLE_DEPTH_M + CLEARANCE_M:  # the beam still sees it
                seen = min(seen, now)
                mover.sidestep(side)
                continue
            # the beam's edge has passed the obstacle's: on until the reach on the other
            # side clears it too
            state, start = "clear", here.copy()
            remaining = reach[side] + CLEARANCE_M - seen * math.tan(RANGER_HALF_ANGLE)
        if state == "clear":
            if side * float((here - start) @ left0) < remaining:
                mover.sidestep(side)
                continue
            state, passed = "go", True
        err = _turned(heading0, rig.heading())
        if passed or now > trigger + far + CLEARANCE_M:
            mover.step(0.5 * err / far, rig, SIDESTEP_PERIODS)
        else:
            mover.step(0.5 * err / travel, rig)  # holding the first heading
        progress = float((rig.world(rig.ranger)[:2] - origin) @ fwd)
    return progress


def _place_obstacle(session: Session, centre: np.ndarray, heading: float, width: float) -> int:
    """Set the scene's obstacle up: a box ``width`` m wide across ``heading`` at
    ``centre`` (x, y) m, colliding with the robot and watched; its geom id."""
    import mujoco

    m, d = session.model, session.data
    bid = m.body(OBSTACLE).mocapid[0]
    gid = m.geom(OBSTACLE).id
    d.mocap_pos[bid] = [centre[0], centre[1], OBSTACLE_HEIGHT_M / 2]
    quat = np.empty(4)
    mujoco.mju_axisAngle2Quat(quat, np.array([0.0, 0.0, 1.0]), heading)
    d.mocap_quat[bid] = quat
    m.geom_size[gid] = [OBSTACLE_DEPTH_M / 2, width / 2, OBSTACLE_HEIGHT_M / 2]
    m.geom_rbound[gid] = float(np.linalg.norm(m.geom_size[gid]))
    m.geom_aabb[gid, 3:] = m.geom_size[gid]
    body = m.body(OBSTACLE).id  # (MuJoCo filters pairs by the bodies' types too)
    m.geom_contype[gid], m.geom_conaffinity[gid] = 1, 3
    m.body_contype[body], m.body_conaffinity[body] = 1, 3
    mujoco.mj_forward(m, d)
    session.watched_geom = gid
    return int(gid)


def _park_obstacle(session: Session) -> None:
    """Park the obstacle out of the way again (colliding with nothing, unwatched)."""
    m, d = session.model, session.data
    gid, body = m.geom(OBSTACLE).id, m.body(OBSTACLE).id
    session.watched_geom = None
    d.mocap_pos[m.body(OBSTACLE).mocapid[0]] = [0.0, 0.0, -10.0]
    m.geom_contype[gid], m.geom_conaffinity[gid] = 0, 0
    m.body_contype[body], m.body_conaffinity[body] = 0, 0


def _turned(now: float, then: float) -> float:
    """Counter-clockwise turn (rad) from heading ``then`` to ``now``, in (-pi, pi]."""
    return (now - then + math.pi) % (2 * math.pi) - math.pi


def run_sensing(
    files: Mapping[str, str | bytes],
    name: str,
    params: Mapping[str, object] | None = None,
    perturb: tuple[Mapping, int] | None = None,
) -> dict:
    """Sensing behaviour ``name`` of the design in ``files`` run on a fresh robot (under
    perturbation ``perturb`` = (table, seed) of :mod:`synth.verification.perturb` when given) and
    judged: its figures (``verdict`` and the loop's figures)."""
    from program.session import Session

    session = Session(files=files, perturb=perturb, animate=False)
    return session.do(name, **dict(params or {}))["figures"]


def verify_sensing(files: Mapping[str, str | bytes]) -> list[dict]:
    """Every sensing behaviour of the design in ``files`` (a bundle held in memory) run
    with its default parameters on a fresh robot and judged: one dict each (``behavior``,
    ``ability`` and the figures), in name order; none when the design has none."""
    from program.session import Session

    probe = Session(files=files, animate=False)
    out = []
    for name in sorted(probe.sensing):
        session = probe if not probe.started else Session(files=files, animate=False)
        fig = session.do(name)["figures"]
        out.append({"behavior": name, "ability": name, **fig})
    return out


def simulated_abilities(record: Mapping, behaviors: Mapping[str, BehaviorSpec]) -> list[str]:
    """The sensing abilities of ``record`` that this module simulates for a controller
    with these ``behaviors``, and the abilities they serve: those whose nearest ancestor
    with a sensing loop is one (the record's ``ability_ancestors``, ``gaits.base.serving``)."""

    abilities = tuple(record.get("abilities", ()))
    sensed = sensing_behaviors(behaviors, abilities)
    ancestors = record.get("ability_ancestors") or {}
    return sorted(a for a in abilities if serving(a, ancestors, sensed) is not None)
