"""Behaviours of multiped designs (paper section 4.3.4; issue 5's hexapod and quadruped):
``walking``, ``rough-terrain-walking``, ``running`` and ``turning``, built on the gait
generator of ``gaits.hexapod`` (leg kinematics, gaits, foot trajectories, stability margin).

**Stance height**: the zero pose (tibia vertical, the trunk ``tibia`` m up) unless the
trunk's underside (``TRUNK_THICKNESS`` / 2 below its frame) would be less than
``STEP_MARGIN`` above the design's obstacle (``params["obstacle_height"]``); a higher
stance starts with a rise from q = 0.

**Step height**: the obstacle height + ``STEP_MARGIN`` (at least ``MIN_STEP``), times
``ROUGH_STEP_FACTOR`` on rough terrain.

**Stride**: ``STRIDE_FRACTION`` of the longest feasible (``gaits.hexapod.max_stride``) in
the direction of travel; plans whose margin falls below ``MIN_MARGIN`` or that leave the
joint limits are retried with a shorter stride.

**Timing**: the cycle time is stride / (duty x speed); the default speed is the design's
(``params["speed"]``) or ``DEFAULT_SPEED``, at least ``MIN_PACE`` body lengths a second,
slowed down when a joint would exceed ``SPEED_MARGIN`` of its actuator's no-load speed; an
explicit speed that needs faster joints raises ValueError with the largest feasible one.

**Turning** in place ends each swing with a slow approach of ``TURN_APPROACH`` rad about
the coxa (``gaits.hexapod``'s module docstring): without it the play of plastic-geared
hip servos (about 3-4 deg with their dead band) ratchets a quadruped's turn in place 10-14
% past its angle on every perturbed run (``parmor design ... --robustness``); with it the
same runs end within 4 % of the angle. A turn's joints use at most ``TURN_PACE`` of the
usable speed walking's may (``SPEED_MARGIN``): a quadruped's crawl lifts a foot off a
diagonal it then balances on, and at walking's pace the lift-off rocked the trunk so
that a stance foot left the ground for 15-30 ms (the measured margin then below 0 against
the other two) in 1 of 8 perturbed runs with a 3 deg slope; slower, none.

**Running** is not a run (no flight phase: the servos are too slow for one) but the
fastest statically stable travel: the gait of ``run_gait`` (the fewest feet on the
ground that keeps the centre of mass over its support: the tripod of any count that has
one, the quadruped's crawl at its shortest duty; the count's other gaits, shortest duty
first, when it finds no stable plan) at ``RUN_SPEED_FACTOR`` times the walking speed,
slowed down to the actuators' speeds like walking.

**Masses**: the stability margins use the sized template with the design's masses when
the controller is given it (``LeggedController(geometry, template=structure.template)``);
otherwise the template rebuilt from the record with its default masses
(``DesignGeometry`` carries no masses; the geometry, which alone decides the gaits, is the
same).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gaits.base import (
    AUTO,
    BehaviorSpec,
    Controller,
    DesignGeometry,
    Parameter,
    Trajectory,
    significant,
)
from gaits.hexapod import (
    GAITS,
    MIN_CRAWL_DUTY,
    MIN_MARGIN,
    SWAY_LEAD,
    SWAY_MAX,
    SWAY_TARGET_MARGIN,
    TRANSITION_S,
    GaitPattern,
    GaitPlan,
    gait_pattern,
    gait_timing,
    legs_key,
    legs_of,
    max_stride,
    model_key,
    pattern_key,
    plan_gait,
    standing_height,
)
from gaits.steering import SteerableSpec
from kinematics.templates import TRUNK_THICKNESS, Template

__all__ = ["DIRECTIONS", "DirectionParameter", "LeggedController"]

#: Lift of a swinging foot above the design's obstacle, and of the trunk's underside, m.
STEP_MARGIN = 0.01
#: Smallest step height, m (designs without an obstacle height).
MIN_STEP = 0.02
#: Rough-terrain step: this times the walking step height.
ROUGH_STEP_FACTOR = 1.5
#: Fraction of the longest feasible stride a gait uses (room for sway and start/stop).
STRIDE_FRACTION = 0.8
#: Fraction of an actuator's no-load speed a trajectory may ask for.
SPEED_MARGIN = 0.6
#: Body speed when the design names none, m/s.
DEFAULT_SPEED = 0.05
#: Slowest default trunk speed, body lengths per s: twice the verdict's floor of 0.5 per
#: 10 s, leaving room for the start and stop ramps and the standing lead-in and -out.
MIN_PACE = 0.1
#: Turning: each swing's slow final approach to its foothold, rad about the coxa (covers
#: the play of plastic-geared hobby servos, 1-2 deg of backlash plus their dead band).
TURN_APPROACH = 0.1
#: Turning: the share of ``SPEED_MARGIN`` a turn's joints may use (module docstring,
#: **Turning**): its swings are slower than walking's.
TURN_PACE = 0.7
#: The narrower sway (``gaits.hexapod.plan_gait``'s ``sway_limits``: m per axis, the
#: margin it keeps; the previous release's): a design with ``line-tracking`` sways no
#: more (its line sensors ride on the trunk, and the two 50 mm modules of
#: ``program.sensing``, the line within 34.5 mm of their midpoint, lost it for 1.9 s at a
#: 30 mm sway: 43 mm off it, 32.5 mm at 20 mm), keeping the crawl's smaller margin under
#: perturbation; and a plan whose wider sway takes a joint out of its limits is planned
#: again with it (the quadruped's run over a 1 cm obstacle with 0.1 kg).
LINE_SWAY = (0.02, 0.015)
#: Walking on an arc: the shortest stride it takes, as a share of the straight walk's (a
#: tighter arc is refused rather than walked in steps of millimetres: with the crawl's
#: 30 mm sway a 4-legged walker's arcs of up to 45 rad/m planned at 3 % of its stride,
#: and a line-following loop that steered them crawled on, 0.55 m in 79 s).
ARC_SHORTEST = 0.5
#: The declared ranges of a design's own values (``LeggedController._own``): the slowest
#: speed offered, as a fraction of the default; the shortest stride, as a fraction of the
#: longest the legs reach; the lowest lift above the design's obstacle, m.
SLOW_FRACTION = 0.1
SHORT_FRACTION = 0.1
LOW_LIFT = 0.005
#: Fastest speed declared: plans tried, each this much slower than the last.
OWN_TRIES = 6
OWN_BACKOFF = 0.95
#: Halvings of the highest lift's search (a leg of 0.2 m: to 0.8 mm).
LIFT_BISECTIONS = 8
#: The highest lift declared: the legs still reach this share of their stride at the
#: design's step (``LeggedController._highest_step``).
LIFT_STRIDE_SHARE = 0.5
#: Running: this times the walking speed (slowed down to the actuators' speeds).
RUN_SPEED_FACTOR = 2.0
#: Running's gait by leg count: (gait, duty; None: the gait's own).
RUN_GAITS: dict[int, tuple[str, float | None]] = {
    6: ("tripod", None),
    4: ("crawl", MIN_CRAWL_DUTY),
}


def run_gait(legs: int) -> tuple[str, float | None]:
    """Running's gait for ``legs`` legs: ``RUN_GAITS``, else the count's tripod (three
    feet standing, the fewest that hold the centre of mass over a support polygon: the
    longest swings, so the fastest travel the actuators allow) or, without one, its first
    gait (``GAITS``), with its own duty."""
    if legs in RUN_GAITS:
        return RUN_GAITS[legs]
    gaits = GAITS[legs]
    return ("tripod" if "tripod" in gaits else gaits[0], None)


#: Duties tried for running, from the shortest to the gait's own.
RUN_DUTY_STEPS = 3
#: Gait plans kept in memory (see ``LeggedController._plan``).
PLAN_MEMO = 32
#: Named directions of travel, rad (counter-clockwise from the trunk's +x).
DIRECTIONS = {"forward": 0.0, "backward": math.pi, "left": math.pi / 2, "right": -math.pi / 2}


#: Walking's ``curvature`` (rad/m): the trunk follows an arc, turning by this much per metre
#: travelled, counter-clockwise positive (0: a straight line). Arcs tighter than the legs
#: reach raise ValueError naming the tightest feasible one.
CURVATURE = Parameter(
    "curvature",
    "float",
    0.0,
    "turn per metre walked, counter-clockwise positive (0: straight)",
    "rad/m",
    low=-50.0,
    high=50.0,
)

# --- the controller ---------------------------------------------------------------------------

#: Gait plans by what decides them (``LeggedController._plan``): a plan, or why none.
_PLANS: OrderedDict[tuple, GaitPlan | str] = OrderedDict()


@dataclass(frozen=True)
class DirectionParameter(Parameter):
    """A direction of travel: an angle in rad (counter-clockwise from the trunk's +x) or
    one of ``DIRECTIONS`` (forward, backward, left, right)."""

    def check(self, value: object) -> object:
        if isinstance(value, str) and value.strip().lower() in DIRECTIONS:
            return DIRECTIONS[value.strip().lower()]
        try:
            return super().check(value)
        except ValueError:
            raise ValueError(
                f"{self.name}: expected an angle in rad in [{self.low:.4g}, {self.high:.4g}] "
                f"or one of {', '.join(DIRECTIONS)}, got {value!r}"
            ) from None


class LeggedController(Controller):
    """Behaviours of a multiped design (legs on a trunk: a hexapod, a quadruped, any
    count of at least four legs; see the module docstring).

    - ``walking(gait, steps, seconds, direction, speed, stride, step_height)``: walk
      ``steps`` gait cycles (every leg steps once a cycle), or about ``seconds`` s when
      that is > 0 (whole cycles then fill the time: the cycle is shortened so that the
      trunk is at least as fast as asked, when the actuators allow), towards
      ``direction`` (rad, or forward/backward/left/right), trunk speed ``speed`` m/s (the
      design's, slowed down to the actuators' speeds), ``stride`` m (``STRIDE_FRACTION``
      of the longest feasible), feet lifted ``step_height`` m (the design's obstacle
      height + ``STEP_MARGIN``). These three are the design's own (``Parameter.own``):
      declared with the values the plan at every default uses and the design's ranges
      (:meth:`_own`); given at their default, or as 0 (``gaits.base.AUTO``: programs of
      earlier versions), they are worked out for the other values (the speed for the
      direction asked...), as when not given.
    - ``rough-terrain-walking``: the same with a step ``ROUGH_STEP_FACTOR`` times higher
      (offered when the design has that ability, or names no abilities).
    - ``running(steps, seconds, direction, speed, stride, step_height)``: like walking with
      the gait of ``RUN_GAITS`` at ``RUN_SPEED_FACTOR`` times the walking speed (see the
      module docstring: a fast statically stable walk, not a run).
    - ``turning(angle, gait, speed, step_height)``: turn in place by ``angle`` rad
      (counter-clockwise positive) at up to ``speed`` rad/s (the design's own: its trunk
      speed at the farthest foot, within ``TURN_PACE`` of the actuators' usable speeds).

    ``Trajectory.info``: ``motion`` ("straight" for walking, rough-terrain walking and
    running; "turn" for turning), ``planned_pose`` (dx m, dy m, dyaw rad: the trunk's
    planned displacement in the world frame, which is the trunk's at the start),
    ``locomotion`` ("legged"), ``direction`` (x, y) unit vector of the travel (not when
    turning), ``stability_margin_m`` (N,), ``min_stability_margin_m``,
    ``gait``, ``duty``, ``cycle_s``, ``cycles``, ``stride_m``, ``step_height_m``,
    ``stance_height_m``,
    ``speed`` (m/s, or rad/s when turning), ``planned_distance_m`` (walking) or
    ``heading_rad`` (turning), ``body_path`` (N, 3) planned trunk (x m, y m, yaw rad),
    ``legs`` (leg names) and ``stance`` (N, legs) bool (the feet on the ground),
    ``obstacle_height_m``, ``body_length_m`` (the trunk's length between the front and rear
    leg mounts: La1), ``com_masses`` ("design" or "template defaults").

    ``template``: the sized template with the design's masses (``Structure.template``) for
    the stability margins; by default the template rebuilt from the record, with its
    default masses (the geometry, which alone decides the gaits, is the same).
    """

    PLAN_IGNORES = frozenset({"mass_kg", "joint_torque", "calibration"})

    def __init__(self, geometry: DesignGeometry, template: Template | None = None) -> None:
        super().__init__(geometry)
        if template is not None:
            if template.robot_type != self.template.robot_type or any(
                abs(template.lengths[k] - v) > 1e-9 for k, v in self.template.lengths.items()
            ):
                raise ValueError("the template given is not the design's (type or lengths)")
            self.template = template
        self.com_masses = "design" if template is not None else "template defaults"
        self.legs = legs_of(self.template)
        self._context: tuple | None = None  # what identifies the plans' template and legs
        sensing = set(geometry.abilities) | {
            b for a in geometry.abilities for b in geometry.ancestors.get(a, ())
        }
        self.sway_limits = (
            LINE_SWAY if "line-tracking" in sensing else (SWAY_MAX, SWAY_TARGET_MARGIN)
        )
        self._behaviors: dict[str, BehaviorSpec] | None = None  # worked out when first asked
        self.gaits = GAITS.get(len(self.legs), ())
        if not self.gaits:
            raise ValueError(
                f"no gait for a {len(self.legs)}-legged robot "
                f"(gaits for {', '.join(map(str, GAITS))} legs)"
            )
        self.obstacle = float(geometry.params.get("obstacle_height", 0.0))
        self.step_height = max(self.obstacle + STEP_MARGIN, MIN_STEP)
        self.height = max(
            standing_height(self.legs), self.obstacle + STEP_MARGIN + TRUNK_THICKNESS / 2
        )
        self.body_length = float(np.ptp([leg.mount[0] for leg in self.legs]))
        self.speed = max(
            float(geometry.params.get("speed") or DEFAULT_SPEED), MIN_PACE * self.body_length
        )
        m = self.template.model
        self._limits = np.array(
            [
                SPEED_MARGIN * geometry.joint_speed.get(m.joints[i].name, 0.0) or math.inf
                for i in m.q_joints
            ]
        )

    # -- behaviours ----------------------------------------------------------------------------

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        """The behaviours (see the class), their ``speed``, ``stride`` and ``step_height``
        declared with the design's own values and ranges (:meth:`_own`), worked out once."""
        if self._behaviors is None:
            self._behaviors = self._specs(self._own())
        return self._behaviors

    def _own(self) -> dict[str, dict[str, tuple[float, float, float]]]:
        """behaviour -> parameter -> (default, low, high) of its ``own`` parameters: the
        values the plan at every default uses (:data:`gaits.base.AUTO` planned, as
        ``_run`` works them out) and the design's ranges:

        - ``speed``: up to the fastest the actuators allow (the default plan's speed over
          its largest share of ``SPEED_MARGIN`` of a joint's no-load speed, checked by a
          plan at that speed, lowered by ``OWN_BACKOFF`` steps until one plans), down to
          ``SLOW_FRACTION`` of the default;
        - ``stride``: up to the longest the legs reach (``max_stride`` forward, with the
          default step), down to ``SHORT_FRACTION`` of it;
        - ``step_height``: from ``LOW_LIFT`` above the obstacle up to the highest lift
          with which the legs still reach a stride (:meth:`_highest_step`).

        A behaviour that does not plan at its defaults keeps the nominal values (the
        design's speed, ``STRIDE_FRACTION`` of the longest stride, the step height)."""
        specs = self._specs(None)
        forward = {leg.name: np.array([1.0, 0.0]) for leg in self.legs}
        reach = max(float(np.hypot(*leg.neutral[:2])) for leg in self.legs)
        around = {
            leg.name: np.array([-leg.neutral[1], leg.neutral[0]]) / reach for leg in self.legs
        }
        out: dict[str, dict[str, tuple[float, float, float]]] = {}
        lifts: dict[bool, float] = {}  # turning or not -> the highest step
        for name, spec in specs.items():
            base = spec.planned(spec.resolve({}))
            turning = name == "turning"
            travel = around if turning else forward
            step = self.step_height * (ROUGH_STEP_FACTOR if "rough" in name else 1.0)
            rate = self.speed / reach if turning else self.speed
            rate *= RUN_SPEED_FACTOR if name == "running" else 1.0
            s_max = max_stride(self.legs, travel, self.height, step)
            stride = STRIDE_FRACTION * s_max
            try:
                traj = self._planned(name, base)
            except ValueError:
                traj = None
            if traj is not None:
                rate = float(traj.info["speed"])  # type: ignore[arg-type]
                stride = float(traj.info["stride_m"])  # type: ignore[arg-type]
                step = float(traj.info["step_height_m"])  # type: ignore[arg-type]
            top = self._fastest(name, base, traj, rate)
            rate = significant(rate)
            if turning not in lifts:
                lifts[turning] = self._highest_step(travel)
            lift = lifts[turning]
            values = {
                "speed": (
                    rate,
                    min(rate, significant(SLOW_FRACTION * rate, down=True)),
                    max(rate, top),
                ),
                "step_height": (
                    significant(step),
                    min(significant(step), significant(self.obstacle + LOW_LIFT)),
                    max(significant(step), lift),
                ),
            }
            if not turning:
                longest = significant(s_max, down=True)
                stride = significant(stride)
                values["stride"] = (
                    stride,
                    min(stride, significant(SHORT_FRACTION * s_max, down=True)),
                    max(stride, longest),
                )
            out[name] = values
        return out

    def _fastest(
        self, name: str, base: Mapping[str, object], traj: Trajectory | None, rate: float
    ) -> float:
        """The fastest ``speed`` (m/s, rad/s turning) a plan of behaviour ``name`` takes
        with the other parameters of ``base``: the default plan's speed over its joints'
        largest share of their usable speed (joint rates scale with the trunk's speed),
        to 3 significant digits down, checked by planning it; ``rate`` when the default
        does not plan or the design gives no actuator speeds."""
        if traj is None:
            return rate
        ratio = self._ratio(traj.positions, traj.times, TURN_PACE if name == "turning" else 1.0)
        if not ratio > 0:  # no actuator speeds known (a bare geometry): no bound to scale
            return rate
        top = significant(rate / ratio, down=True)
        for _ in range(OWN_TRIES):
            if top <= rate:
                return rate
            try:
                self._planned(name, {**base, "speed": top})
                return top
            except ValueError:
                top = significant(top * OWN_BACKOFF, down=True)
        return rate

    def _highest_step(self, travel: Mapping[str, np.ndarray]) -> float:
        """The highest foot lift m (to the millimetre, down) with which the legs still
        reach ``LIFT_STRIDE_SHARE`` of the stride along ``travel`` that they reach with
        the design's step (``max_stride``; higher lifts leave too short a stride to
        plan), by ``LIFT_BISECTIONS`` halvings between the design's step and the leg's
        length; the design's step when none is higher."""
        lo = self.step_height
        hi = max(self.step_height, max(leg.femur + leg.tibia for leg in self.legs))
        need = max(LIFT_STRIDE_SHARE * max_stride(self.legs, travel, self.height, lo), 1e-4)

        def reaches(step: float) -> bool:
            return max_stride(self.legs, travel, self.height, step) >= need

        for _ in range(LIFT_BISECTIONS):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if reaches(mid) else (lo, mid)
        return max(self.step_height, math.floor(lo * 1000 + 1e-9) / 1000)

    def _specs(
        self, own: Mapping[str, Mapping[str, tuple[float, float, float]]] | None
    ) -> dict[str, BehaviorSpec]:
        """The behaviours with ``own`` values (None: placeholders, every own parameter at
        :data:`gaits.base.AUTO`, to plan the defaults with)."""

        def mine(behaviour: str, name: str, doc: str, unit: str) -> Parameter:
            if own is None:
                return Parameter(name, "float", AUTO, doc, unit, low=0.0, high=None, own=True)
            default, low, high = own[behaviour][name]
            return Parameter(name, "float", default, doc, unit, low=low, high=high, own=True)

        gait = Parameter("gait", "choice", self.gaits[0], "gait", choices=self.gaits)

        def step(behaviour: str) -> Parameter:
            return mine(
                behaviour,
                "step_height",
                "foot lift (default: the design's obstacle height + margin"
                + (f", x {ROUGH_STEP_FACTOR:g} on rough terrain)" if "rough" in behaviour else ")"),
                "m",
            )

        def walk(behaviour: str) -> tuple[Parameter, ...]:
            return (
                gait,
                Parameter(
                    "steps",
                    "int",
                    4,
                    "gait cycles (every leg steps once a cycle)",
                    low=1,
                    high=10000,
                ),
                Parameter(
                    "seconds",
                    "float",
                    0.0,
                    "walk for about this long instead of `steps` (0: use steps)",
                    "s",
                    low=0.0,
                    high=36000.0,
                ),
                DirectionParameter(
                    "direction",
                    "float",
                    0.0,
                    "direction of travel: rad from forward, counter-clockwise, "
                    "or forward/backward/left/right",
                    "rad",
                    low=-math.pi,
                    high=math.pi,
                ),
                mine(
                    behaviour,
                    "speed",
                    "trunk speed (default: the design's"
                    + (f" x {RUN_SPEED_FACTOR:g}" if behaviour == "running" else "")
                    + ", within the actuators' speeds for the gait and direction asked)",
                    "m/s",
                ),
                mine(
                    behaviour,
                    "stride",
                    f"stride (default: {STRIDE_FRACTION:g} of the longest the legs reach "
                    "in the direction asked)",
                    "m",
                ),
                step(behaviour),
            )

        run_name, run_duty = run_gait(len(self.legs))
        duty = run_duty or gait_pattern(run_name, self.legs).duty
        own_duty = gait_pattern(run_name, self.legs).duty
        duties = (
            f"{duty:.2f}" if abs(duty - own_duty) < 1e-9 else f"{duty:.2f} (up to {own_duty:.2f})"
        )
        out = {
            "walking": SteerableSpec(
                "walking",
                "Walk a straight line, or an arc of `curvature`, with a statically stable gait.",
                (*walk("walking"), CURVATURE),
                steer=(
                    ("speed", "speed"),
                    ("turn", "curvature"),
                    ("steps", "steps"),
                    ("direction", "direction"),
                ),
            ),
            "running": BehaviorSpec(
                "running",
                f"Travel a straight line fast: a {run_name} of duty {duties} at "
                f"{RUN_SPEED_FACTOR:g}x the walking speed within the actuators' speeds "
                "(statically stable, no flight phase).",
                tuple(p for p in walk("running") if p.name != "gait"),
            ),
            "turning": BehaviorSpec(
                "turning",
                "Turn in place by an angle with a statically stable gait.",
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
                    gait,
                    mine(
                        "turning",
                        "speed",
                        "yaw rate (default: the design's trunk speed at the farthest foot, "
                        "within the actuators' speeds)",
                        "rad/s",
                    ),
                    step("turning"),
                ),
                ability="walking",
            ),
        }
        abilities = self.geometry.abilities
        if not abilities or "rough-terrain-walking" in abilities:
            out["rough-terrain-walking"] = BehaviorSpec(
                "rough-terrain-walking",
                f"Walk like `walking` with a {ROUGH_STEP_FACTOR:g}x higher step.",
                walk("rough-terrain-walking"),
            )
        return out

    def walk(self, steps: int = 4, direction: float | str = 0.0, **params: object) -> Trajectory:
        """``walking`` for ``steps`` cycles towards ``direction`` (see the class)."""
        return self.run("walking", steps=steps, direction=direction, **params)

    def turn(self, angle: float, **params: object) -> Trajectory:
        """``turning`` by ``angle`` rad, counter-clockwise positive."""
        return self.run("turning", angle=angle, **params)

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        if name == "turning":
            return self._turning(params)
        rough = name == "rough-terrain-walking"
        step = float(params["step_height"]) or self.step_height * (  # type: ignore[arg-type]
            ROUGH_STEP_FACTOR if rough else 1.0
        )
        if name == "running":
            gait, duty = run_gait(len(self.legs))
            own = gait_pattern(gait, self.legs).duty
            # the shortest duty first; longer ones (up to the gait's own) when a design's
            # trunk cannot sway far enough for it; then, when the gait finds no stable
            # plan, the count's other gaits from the shortest duty
            duties = [None] if duty is None else list(np.linspace(duty, own, RUN_DUTY_STEPS))
            tries = [(gait, d) for d in duties]
            others = sorted(
                (g for g in self.gaits if g != gait),
                key=lambda g: (gait_pattern(g, self.legs).duty, self.gaits.index(g)),
            )
            tries += [(g, None) for g in others]
            first: ValueError | None = None
            for g, d in tries:
                try:
                    return self._walking(
                        name, {**params, "gait": g}, step, d, RUN_SPEED_FACTOR * self.speed
                    )
                except ValueError as e:
                    if g != gait:
                        continue
                    first = e  # the running gait's own reason (its longest duty's)
            assert first is not None
            raise first
        if float(params.get("curvature") or 0.0):  # type: ignore[arg-type]
            return self._arc(name, params, step)
        return self._walking(name, params, step)

    # -- planning ------------------------------------------------------------------------------

    def _check_step(self, step: float) -> None:
        if step <= self.obstacle:
            raise ValueError(
                f"step_height: {step:g} m does not clear the design's obstacle "
                f"height of {self.obstacle:g} m"
            )

    def _stride(self, travel: Mapping[str, np.ndarray], step: float) -> float:
        s_max = max_stride(self.legs, travel, self.height, step)
        if s_max <= 1e-4:
            raise ValueError(
                f"step_height: the legs cannot lift {step:g} m and keep walking "
                "within their joint limits"
            )
        return s_max

    def _ratio(self, q: np.ndarray, times: np.ndarray, pace: float = 1.0) -> float:
        """Largest joint speed of ``q`` as a share of ``pace`` x the usable actuator
        speed."""
        v = np.gradient(q, times, axis=0)
        return float(np.max(np.abs(v) / self._limits)) / pace

    def _accept(self, plan: GaitPlan) -> bool:
        """Whether a plan keeps every joint inside its limits and the robot stable."""
        m = self.template.model
        inside = np.all(plan.q >= m.lower - 1e-9) and np.all(plan.q <= m.upper + 1e-9)
        return bool(inside and plan.margin.min() >= MIN_MARGIN)

    def _progress(self, pattern: GaitPattern, cycles: int, period: float) -> float:
        """Time s at full speed of ``cycles`` cycles of ``period`` s (ramps discounted)."""
        return float(gait_timing(pattern, self.legs, cycles, period, 0.0, 0.0).progress[-1])

    def _rise(self) -> float:
        return TRANSITION_S if abs(self.height - standing_height(self.legs)) > 1e-6 else 0.0

    def _walking(
        self,
        name: str,
        params: Mapping[str, object],
        step: float,
        duty: float | None = None,
        speed: float | None = None,
    ) -> Trajectory:
        """Straight travel with ``params["gait"]`` (of ``duty``; None: the gait's own) at
        ``params["speed"]`` or else ``speed`` m/s (None: the walking speed)."""
        self._check_step(step)
        direction = float(params["direction"])  # type: ignore[arg-type]
        u = np.array([math.cos(direction), math.sin(direction)])
        pattern = gait_pattern(str(params["gait"]), self.legs, direction, duty=duty)
        default_speed = self.speed if speed is None else speed
        s_max = self._stride({leg.name: u for leg in self.legs}, step)
        asked_stride = float(params["stride"])  # type: ignore[arg-type]
        if asked_stride > s_max:
            raise ValueError(
                f"stride: {asked_stride:g} m is beyond the legs' reach in this "
                f"direction (at most {s_max:.3g} m with a {step:g} m step)"
            )
        stride = asked_stride or STRIDE_FRACTION * s_max
        asked_speed = float(params["speed"])  # type: ignore[arg-type]
        for _ in range(12):
            plan = self._fit(
                pattern,
                stride,
                step,
                u,
                0.0,
                asked_speed or default_speed,
                bool(asked_speed),
                int(params["steps"]),  # type: ignore[call-overload]
                float(params["seconds"]),
            )  # type: ignore[arg-type]
            if plan is not None:
                break
            if asked_stride:
                raise ValueError(
                    f"stride: {asked_stride:g} m leaves the gait without a "
                    f"static stability margin of {MIN_MARGIN:g} m or outside its "
                    "joint limits; try a shorter one"
                )
            stride *= 0.85
        else:
            raise ValueError(f"no stable {pattern.name} gait found for this design")
        return self._trajectory(
            name,
            plan,
            pattern,
            {
                "motion": "straight",
                "direction": (float(u[0]), float(u[1])),
                "planned_distance_m": plan.speed * plan.progress,
            },
        )

    def _turning(self, params: Mapping[str, object]) -> Trajectory:
        angle = float(params["angle"])  # type: ignore[arg-type]
        if angle == 0:
            raise ValueError("angle: must not be 0")
        step = float(params["step_height"]) or self.step_height  # type: ignore[arg-type]
        self._check_step(step)
        reach = max(float(np.hypot(*leg.neutral[:2])) for leg in self.legs)
        travel = {
            leg.name: np.array([-leg.neutral[1], leg.neutral[0]]) / reach for leg in self.legs
        }
        turn = STRIDE_FRACTION * self._stride(travel, step) / reach  # rad per stance
        asked = float(params["speed"])  # type: ignore[arg-type]
        # leg order: groups of the turn (rear/front halves) or of forward walking, whichever
        # keeps the larger margin without sway
        best = -math.inf
        for candidate in (
            gait_pattern(str(params["gait"]), self.legs, 0.0, turn=angle),
            gait_pattern(str(params["gait"]), self.legs, 0.0),
        ):
            period = turn / (candidate.duty * (asked or self.speed / reach))
            try:
                trial = self._plan(
                    candidate,
                    2,
                    period,
                    (0.0, 0.0, math.copysign(turn / (candidate.duty * period), angle)),
                    step,
                    self.height,
                    sway=False,
                    stand=True,
                    approach=TURN_APPROACH,
                )
            except ValueError:
                continue
            if trial.margin.min() > best:
                best, pattern = float(trial.margin.min()), candidate
        if best == -math.inf:
            raise ValueError("no turning step is within the legs' reach")
        for _ in range(12):
            plan = self._fit(
                pattern,
                turn,
                step,
                None,
                angle,
                asked or self.speed / reach,
                bool(asked),
                0,
                0.0,
                TURN_APPROACH,
                TURN_PACE,
            )
            if plan is not None:
                break
            turn *= 0.85
        else:
            raise ValueError(f"no stable {pattern.name} turn found for this design")
        return self._trajectory(
            "turning", plan, pattern, {"motion": "turn", "heading_rad": float(plan.body[-1, 2])}
        )

    def _plan(
        self,
        pattern: GaitPattern,
        cycles: int,
        period: float,
        twist: tuple[float, float, float],
        step: float,
        height: float,
        sway: bool | None = None,
        stand: bool = False,
        approach: float = 0.0,
        limits: tuple[float, float] | None = None,
    ) -> GaitPlan:
        """``plan_gait`` on this design's template and legs (its sway within ``limits``,
        default ``self.sway_limits``), remembered by what decides
        it (the template's content, legs, gait and arguments; read-only arrays): walking,
        running and rough-terrain walking, the same design planned with other actuators
        and the same plan asked again while a timing settles reuse it."""
        if self._context is None:
            self._context = (model_key(self.template), legs_key(self.legs))
        limits = self.sway_limits if limits is None else limits
        key = (
            self._context,
            tuple(limits),
            pattern_key(pattern),
            int(cycles),
            float(period),
            tuple(float(x) for x in twist),
            float(step),
            float(height),
            sway,
            bool(stand),
            float(approach),
        )
        hit = _PLANS.get(key)
        if hit is None:
            try:
                hit = plan_gait(
                    self.template,
                    self.legs,
                    pattern,
                    cycles,
                    period,
                    twist,
                    step,
                    height,
                    sway=sway,
                    stand=stand,
                    approach=approach,
                    sway_limits=limits,
                )
            except ValueError as e:
                hit = str(e)
            else:
                for a in vars(hit).values():
                    if isinstance(a, np.ndarray):
                        a.setflags(write=False)
            _PLANS[key] = hit
            while len(_PLANS) > PLAN_MEMO:
                _PLANS.popitem(last=False)
        else:
            _PLANS.move_to_end(key)
        if isinstance(hit, str):
            raise ValueError(hit)
        return hit

    def _swayed(
        self,
        pattern: GaitPattern,
        cycles: int,
        period: float,
        twist: tuple[float, float, float],
        step: float,
        approach: float,
        sway: bool | None = True,
    ) -> GaitPlan:
        """The plan with the trunk's sway (``sway``: True, or None to sway when needed) of
        this design (``sway_limits``); when that takes a foot out of reach, a joint out of
        its limits or the margin below ``MIN_MARGIN``, the plan with the narrower
        ``LINE_SWAY`` if that one keeps them (else the first, or its ValueError)."""
        tries = [tuple(self.sway_limits)]
        if tries[0] != LINE_SWAY:
            tries.append(LINE_SWAY)
        planned: list[GaitPlan] = []  # those not accepted, in the order tried
        error = None
        for limits in tries:
            try:
                plan = self._plan(
                    pattern, cycles, period, twist, step, self.height, sway=sway,
                    approach=approach, limits=limits,
                )  # fmt: skip
            except ValueError as e:
                error = e
                continue
            if self._accept(plan):
                return plan
            planned.append(plan)
        if planned:
            return planned[0]
        raise error  # type: ignore[misc]

    def _fit(
        self,
        pattern: GaitPattern,
        per_stance: float,
        step: float,
        u: np.ndarray | None,
        angle: float,
        rate: float,
        explicit: bool,
        steps: int,
        seconds: float,
        approach: float = 0.0,
        pace: float = 1.0,
    ) -> GaitPlan | None:
        """A plan of ``pattern`` whose stances each cover ``per_stance`` (m along ``u``, or
        rad of a turn by ``angle`` when ``u`` is None) at ``rate`` (m/s or rad/s), for
        ``steps`` cycles or about ``seconds`` s, each swing ending with a slow ``approach``
        (rad, ``plan_gait``); slower than ``rate`` when a joint would exceed ``pace`` x its
        usable speed (ValueError instead when ``explicit``). None when the plan leaves the joint
        limits or the stability margin.

        The timing is settled on sway-free plans (cheap); a gait that needs the trunk to
        sway is then planned once more with it."""
        duty = pattern.duty
        span = max(pattern.phases.values()) + 1 - duty  # cycles from first lift to last landing
        rise = self._rise()
        period = per_stance / (duty * rate)
        fastest = 0.0  # shortest cycle the actuators allow, s (0: not known yet)
        sway: bool | None = None
        for _ in range(12):
            extra = span - 1 + (2 * SWAY_LEAD if sway else 0.0)
            if u is None:
                cycles = 1
                while abs(angle) > rate * (1 + 1e-9) * self._progress(pattern, cycles, period):
                    cycles += 1
            elif seconds > 0:
                avail = (seconds - rise) / period - extra
                if explicit:
                    cycles = max(1, math.floor(avail + 1e-9))
                else:  # whole cycles fill the time, at least as fast as asked if possible
                    cycles = max(1, math.ceil(avail - 1e-9))
                    while cycles > 1 and (seconds - rise) / (cycles + extra) < fastest:
                        cycles -= 1
                    period = max((seconds - rise) / (cycles + extra), fastest)
                if rise + (cycles + extra) * period > seconds + 1e-6:
                    need = rise + (1 + extra) * period
                    raise ValueError(f"seconds: one {pattern.name} cycle takes {need:.3g} s")
            else:
                cycles = steps
            if u is None:
                tm = gait_timing(pattern, self.legs, cycles, period, 0.0, 0.0)
                twist = (0.0, 0.0, angle / float(tm.progress[-1]))
            else:
                v = per_stance / (duty * period)
                twist = (v * float(u[0]), v * float(u[1]), 0.0)
            try:
                plan = self._plan(
                    pattern,
                    cycles,
                    period,
                    twist,
                    step,
                    self.height,
                    sway=False,
                    stand=bool(sway),
                    approach=approach,
                )
                if sway is None:
                    sway = bool(plan.margin.min() < MIN_MARGIN)
                    if sway:
                        continue  # the timing again, with the standing lead-in and -out
                ratio = self._ratio(plan.q, plan.times, pace)
                if ratio <= 1 + 1e-6 and sway:
                    plan = self._swayed(pattern, cycles, period, twist, step, approach)
                    ratio = self._ratio(plan.q, plan.times, pace)
            except ValueError:  # a foot out of reach, or no sway: a shorter stride may do
                return None
            if ratio <= 1 + 1e-6:
                return plan if self._accept(plan) else None
            if explicit:
                unit = "m/s" if u is not None else "rad/s"
                raise ValueError(
                    f"speed: {rate:g} {unit} needs joints faster than {pace * SPEED_MARGIN:.0%} of "
                    f"their actuators' no-load speed; at most about {rate / ratio:.3g} {unit} "
                    f"with the {pattern.name} gait"
                )
            fastest = period * ratio * 1.02
            period = fastest
            rate = per_stance / (duty * period)
        raise ValueError(f"no {pattern.name} timing within the actuators' speeds")

    # -- steering: walking along an arc ---------------------------------------------------------

    def _arc(self, name: str, params: Mapping[str, object], step: float) -> Trajectory:
        """Walking whose every stride combines the translation with a yaw: the trunk follows
        an arc of ``params["curvature"]`` rad/m (counter-clockwise positive) towards
        ``direction``. The straight walk's gait, cycles and timing are planned first; the arc
        keeps them and turns the trunk by ``curvature`` x the distance as it goes. Each
        stance's sweep then differs leg by leg (the outer legs sweep further): when a foot
        leaves its reach, the joint limits or the stability margin, the stride is shortened
        (``_arc_fit``); when a joint would be too fast, the cycle lengthened. Like every
        walk it starts and ends standing, so a closed loop (:mod:`program.sensing`) runs it
        a few cycles at a time from where the robot stands."""
        kappa = float(params["curvature"])  # type: ignore[arg-type]
        straight = self._walking(name, {**params, "curvature": 0.0}, step)
        info = straight.info
        direction = float(params["direction"])  # type: ignore[arg-type]
        u = np.array([math.cos(direction), math.sin(direction)])
        pattern = gait_pattern(str(params["gait"]), self.legs, direction)  # as walking's
        period, cycles = float(info["cycle_s"]), int(info["cycles"])  # type: ignore[arg-type]
        v = float(info["speed"])  # type: ignore[arg-type]
        plan = self._arc_fit(pattern, cycles, period, v, u, kappa, step)
        if plan is None:
            raise ValueError(
                f"curvature: {kappa:g} rad/m is tighter than this design's legs can walk "
                f"with the {pattern.name} gait (tightest feasible about "
                f"{self.max_curvature(pattern, cycles, period, v, u, step, kappa):.3g} rad/m)"
            )
        path = float(plan.speed * plan.progress)
        return self._trajectory(
            name,
            plan,
            pattern,
            {
                "motion": "arc",
                "direction": (float(u[0]), float(u[1])),
                "curvature_rad_m": kappa,
                "planned_distance_m": path,
                "path_length_m": path,
            },
        )

    def _arc_fit(
        self,
        pattern: GaitPattern,
        cycles: int,
        period: float,
        v: float,
        u: np.ndarray,
        kappa: float,
        step: float,
    ) -> GaitPlan | None:
        """A plan of ``cycles`` cycles of ``pattern`` on an arc of ``kappa`` rad/m at up to
        ``v`` m/s, the stride shortened until the feet stay in reach, the joints in their
        limits and the trunk stable, the cycle lengthened while a joint is too fast; None
        when no stride does."""
        shortest = ARC_SHORTEST * v
        for _ in range(16):
            twist = (v * float(u[0]), v * float(u[1]), v * kappa)
            try:
                plan = self._swayed(pattern, cycles, period, twist, step, 0.0, sway=None)
            except ValueError:
                plan = None
            if plan is not None and self._accept(plan):
                ratio = self._ratio(plan.q, plan.times)
                if ratio <= 1 + 1e-6:
                    return plan
                period *= ratio * 1.02  # the same stride, slower
                continue
            v *= 0.8  # a shorter stride in the same cycle
            if v < shortest:
                break
        return None

    def max_curvature(
        self,
        pattern: GaitPattern,
        cycles: int,
        period: float,
        v: float,
        u: np.ndarray,
        step: float,
        upto: float,
    ) -> float:
        """The tightest curvature rad/m (at most ``|upto|``) whose arc ``_arc_fit`` plans,
        by bisection."""
        lo, hi = 0.0, abs(upto)
        for _ in range(8):
            mid = 0.5 * (lo + hi)
            ok = self._arc_fit(pattern, cycles, period, v, u, math.copysign(mid, upto), step)
            lo, hi = (mid, hi) if ok is not None else (lo, mid)
        return lo

    def _trajectory(
        self, name: str, plan: GaitPlan, pattern: GaitPattern, extra: Mapping[str, object]
    ) -> Trajectory:
        velocities = np.gradient(plan.q, plan.times, axis=0)
        info: dict[str, object] = {
            "stability_margin_m": plan.margin,
            "min_stability_margin_m": float(plan.margin.min()),
            "gait": pattern.name,
            "duty": pattern.duty,
            "cycle_s": plan.period,
            "cycles": plan.cycles,
            "stride_m": plan.stride,
            "step_height_m": plan.step_height,
            "stance_height_m": plan.height,
            "speed": plan.speed,
            "obstacle_height_m": self.obstacle,
            "body_length_m": self.body_length,
            "locomotion": "legged",
            "planned_pose": tuple(float(x) for x in plan.body[-1]),
            "body_path": plan.body,
            "legs": tuple(leg.name for leg in self.legs),
            "stance": plan.stance,
            "com_masses": self.com_masses,
            **extra,
        }
        return Trajectory(name, plan.times, self.movable_joints(), plan.q, velocities, info)
