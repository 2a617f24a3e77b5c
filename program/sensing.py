"""Sensing abilities simulated: following a line on the floor with two downward infrared
sensors, and passing an obstacle with a forward ultrasonic ranger.

A sensing ability is a closed loop over a locomotion behaviour the design already has:
at :data:`CONTROL_HZ` the robot reads its sensors in the simulated world, picks a forward
speed and a turn rate, and runs the steerable behaviour (:data:`STEERABLE`) for one control
period, continuing from where it is (:class:`program.session.Session`). Behaviours that
cannot be steered that way (a legged gait's walking takes a direction, not a turn rate)
give no sensing behaviour, and the ability stays ``not_simulated``.

The sensors, as the ontology's sensing abilities and the catalog's modules give them:

- two TCRT5000 infrared modules side by side (:data:`IR_SPACING_M` apart) at the front
  edge of the trunk, looking down; each reads 1 over the line (black tape
  :data:`LINE_WIDTH_M` wide), else 0 (the module's comparator output);
- an HC-SR04 ultrasonic ranger at the front edge, looking forward: the nearest obstacle
  within its beam (three rays, the axis and +-:data:`RANGER_HALF_ANGLE`), between
  :data:`RANGER_MIN_M` and :data:`RANGER_MAX_M` (its datasheet's range).

The trunk's front edge is the furthest point of its geoms along the direction the
steerable behaviour drives forward.

What each promises, judged on the outcome (:func:`export.verdict.judge`):

- ``line-tracking`` (motion ``follow-line``): the line never leaves the span of the two
  sensors for longer than ``LINE_LOST_S``, and the robot covers ``LINE_PROGRESS`` of the
  commanded length along the line in the time it has (1.5 x what the speed needs, + 2 s).
- ``obstacle-avoidance`` (motion ``avoid``): the robot reaches the goal line ``distance``
  ahead (an obstacle across its straight path halfway) without touching the obstacle,
  within 3 x what the speed needs + 10 s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gaits.base import BehaviorSpec, Parameter

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

#: Behaviours a sensing loop can steer at a forward speed and a turn rate for a short
#: period: behaviour -> the parameters playing those roles, and the values fixed for short
#: periods. (A legged gait stepped one step at a time, turning in place between steps, was
#: measured and left out: the hexapod covered 0.21 m of 1 m of line in 175 s.)
STEERABLE: dict[str, dict] = {
    "driving": {"speed": "v", "turn": "w", "seconds": "seconds", "fixed": {"ramp": 0.0}},
}

#: The sensing abilities this module simulates, with the motion each promises.
SENSING = {"line-tracking": "follow-line", "obstacle-avoidance": "avoid"}

#: time allowed: (x the time the forward speed needs for the distance, + s), per motion
BUDGET = {"follow-line": (1.5, 2.0), "avoid": (3.0, 10.0)}


@dataclass(frozen=True)
class Steering:
    """How a design is steered: its steerable behaviour, the parameters playing the roles
    (:data:`STEERABLE`), and its top speed m/s."""

    behavior: str
    roles: Mapping[str, str]  # role (speed, turn, seconds) -> the behaviour's parameter
    fixed: Mapping[str, object]
    v_max: float


def steering(behaviors: Mapping[str, BehaviorSpec]) -> Steering | None:
    """The design's steerable behaviour (:data:`STEERABLE`), or None."""
    for name, how in STEERABLE.items():
        spec = behaviors.get(name)
        if spec is None:
            continue
        ps = {p.name: p for p in spec.params}
        roles = {k: v for k, v in how.items() if k != "fixed"}
        if set(roles.values()) <= set(ps):
            return Steering(name, roles, dict(how["fixed"]), float(ps[how["speed"]].high or 0))
    return None


def sensing_behaviors(
    behaviors: Mapping[str, BehaviorSpec], abilities: tuple[str, ...] | list[str]
) -> dict[str, BehaviorSpec]:
    """The sensing behaviours of a design with these (locomotion) ``behaviors`` and
    ``abilities``: name -> spec; none when nothing can be steered."""
    steer = steering(behaviors)
    if steer is None:
        return {}
    top = round(steer.v_max, 3)
    speed = (
        Parameter("speed", "float", round(top / 2, 3), "forward speed", "m/s", low=0.01, high=top),
    )
    length, distance = 2.0, 1.5
    out: dict[str, BehaviorSpec] = {}
    if "line-tracking" in abilities:
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
                    "radius", "float", 0.5, "tightest curve of the line", "m", low=0.2, high=10
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
        for a in (-RANGER_HALF_ANGLE, 0.0, RANGER_HALF_ANGLE):
            v = rot @ (math.cos(a) * self.forward + math.sin(a) * self.left)
            v[2] = 0.0
            v /= np.linalg.norm(v)
            dist = mujoco.mj_ray(m, d, origin, v, groups, 1, -1, geom)
            if dist >= 0:
                best = min(best, dist)
        return float(min(max(best, RANGER_MIN_M), RANGER_MAX_M))


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
        cls, shape: str, radius: float, length: float, start: np.ndarray, heading: float
    ) -> Course:
        """The ``shape`` line ('circle' turning left, or 'wave' of tightest curve
        ``radius``) from ``start`` (x, y) m along ``heading`` rad, ``length`` + 1 m long."""
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
            y = amp * np.sin(k * x)
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
    info) for :func:`export.verdict.judge`."""
    steer = steering(session.controller.behaviors)
    assert steer is not None
    mover = _Driver(session, steer, float(params["speed"]))
    rig = Rig(session, mover.forward_axis())
    if name == "line-tracking":
        return _line(session, mover, rig, params)
    return _avoid(session, mover, rig, params)


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
        self.speed = self.fit(speed, 0.0)[0]
        self.w_spin = 0.0

    def _plan(self, v: float, w: float):
        r = self.steer.roles
        return self.session.controller.run(
            self.steer.behavior,
            **{r["speed"]: v, r["turn"]: w, r["seconds"]: self.period, **self.steer.fixed},
        )

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
            traj = self._plan(*self.fit(v, w))
        self.session._play(traj.joints, traj.positions, traj.velocities, self.period)

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
    radius, length = (float(params[k]) for k in ("radius", "length"))
    # turn hard enough to follow the tightest curve and to swing the sensors, a lever
    # ``front`` ahead of the turning axis, back over the line within a sensor's span
    lever = max(rig.front, IR_SPACING_M)
    curve = TURN_GAIN * (1 / radius + 1 / lever)
    v, w = mover.fit(mover.speed, curve * mover.speed)
    mover.speed, curve = v, (w / v if v > 0 else 0.0)
    mid = (rig.ir[0] + rig.ir[1]) / 2
    start = rig.world(mid)[:2]
    course = Course.make(str(params["course"]), radius, length, start, rig.heading())
    session.scene_line = course.points
    factor, extra = BUDGET["follow-line"]
    budget = factor * length / max(mover.speed, 1e-6) + extra
    t0 = session.time
    state = {"s": 0.0, "turn": 0.0, "next": t0, "lost": 0.0, "longest": 0.0, "worst": 0.0}
    half_span = IR_SPACING_M / 2 + LINE_WIDTH_M / 2

    def read(t: float) -> None:
        """The sensors read at CONTROL_HZ while the robot moves: the side the line was
        last seen on, and how long it has been outside the sensors' span."""
        if t < state["next"] - 1e-9:
            return
        state["next"] = t + 1.0 / CONTROL_HZ
        on = [
            abs(course.locate(rig.world(p)[:2], state["s"])[1]) <= LINE_WIDTH_M / 2 for p in rig.ir
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
    s, longest, worst = state["s"], state["longest"], state["worst"]
    fig = {
        "seconds": session.time - t0,
        "line_progress_m": s,
        "planned_distance_m": length,
        "line_lost_s": longest,
        "max_line_offset_m": worst,
    }
    return fig, {"motion": SENSING["line-tracking"], "course": str(params["course"])}


def _avoid(session: Session, mover: _Driver, rig: Rig, params: Mapping) -> tuple[dict, dict]:
    import mujoco

    distance, width = (float(params[k]) for k in ("distance", "width"))
    m, d = session.model, session.data
    # the robot's reach from its turning axis (what sweeps when it turns in place) and its
    # half width across the way it goes, from its parts' boxes
    corner, half = rig.extent()
    corner = max(corner, rig.front)
    ahead = 2 * mover.speed / CONTROL_HZ  # what it covers before it reacts
    mover.w_spin = mover.fit(0.0, 2 * mover.speed / max(corner, 0.05))[1]
    safe = corner - rig.front + CLEARANCE_M + ahead
    if mover.w_spin == 0:  # it turns by arcs (steered wheels): it swerves from further off
        safe += mover.tightest()
    heading0 = rig.heading()
    fwd = np.array([math.cos(heading0), math.sin(heading0)])
    origin = rig.world(rig.ranger)[:2]
    # the obstacle: across the straight path, halfway
    bid = m.body(OBSTACLE).mocapid[0]
    gid = m.geom(OBSTACLE).id
    centre = origin + fwd * distance / 2
    d.mocap_pos[bid] = [centre[0], centre[1], OBSTACLE_HEIGHT_M / 2]
    quat = np.empty(4)
    mujoco.mju_axisAngle2Quat(quat, np.array([0.0, 0.0, 1.0]), heading0)
    d.mocap_quat[bid] = quat
    m.geom_size[gid] = [OBSTACLE_DEPTH_M / 2, width / 2, OBSTACLE_HEIGHT_M / 2]
    m.geom_rbound[gid] = float(np.linalg.norm(m.geom_size[gid]))
    m.geom_aabb[gid, 3:] = m.geom_size[gid]
    body = m.body(OBSTACLE).id  # (MuJoCo filters pairs by the bodies' types too)
    m.geom_contype[gid], m.geom_conaffinity[gid] = 1, 3
    m.body_contype[body], m.body_conaffinity[body] = 1, 3
    mujoco.mj_forward(m, d)
    factor, extra = BUDGET["avoid"]
    budget = factor * distance / max(mover.speed, 1e-6) + extra
    t0 = session.time
    state, min_range, seen = "go", RANGER_MAX_M, RANGER_MAX_M
    passed_from = origin
    cleared: tuple[float, float] | None = None
    progress = 0.0
    contacts0 = session._counts["contacts"]
    session.watched_geom = gid
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
    finally:  # park the obstacle again
        session.watched_geom = None
        d.mocap_pos[bid] = [0.0, 0.0, -10.0]
        m.geom_contype[gid], m.geom_conaffinity[gid] = 0, 0
        m.body_contype[body], m.body_conaffinity[body] = 0, 0
    contact_s = (session._counts["contacts"] - contacts0) * m.opt.timestep
    fig = {
        "seconds": session.time - t0,
        "distance_m": progress,
        "planned_distance_m": distance,
        "obstacle_contact_s": contact_s,
        "min_range_m": min_range,
    }
    return fig, {"motion": SENSING["obstacle-avoidance"]}


def _turned(now: float, then: float) -> float:
    """Counter-clockwise turn (rad) from heading ``then`` to ``now``, in (-pi, pi]."""
    return (now - then + math.pi) % (2 * math.pi) - math.pi


def verify_sensing(files: Mapping[str, str | bytes]) -> list[dict]:
    """Every sensing behaviour of the design in ``files`` (a bundle held in memory) run
    with its default parameters on a fresh robot and judged: one dict each (``behavior``,
    ``ability`` and the figures), in name order; none when the design has none."""
    from program.session import Session

    probe = Session(files=files)
    out = []
    for name in sorted(probe.sensing):
        session = probe if not probe.started else Session(files=files)
        fig = session.do(name)["figures"]
        out.append({"behavior": name, "ability": name, **fig})
    return out


def simulated_abilities(record: Mapping, behaviors: Mapping[str, BehaviorSpec]) -> list[str]:
    """The sensing abilities of ``record`` that this module simulates for a controller
    with these ``behaviors``, and the abilities they serve: those whose nearest ancestor
    with a sensing loop is one (the record's ``ability_ancestors``, ``gaits.base.serving``)."""
    from gaits.base import serving

    abilities = tuple(record.get("abilities", ()))
    sensed = sensing_behaviors(behaviors, abilities)
    ancestors = record.get("ability_ancestors") or {}
    return sorted(a for a in abilities if serving(a, ancestors, sensed) is not None)
