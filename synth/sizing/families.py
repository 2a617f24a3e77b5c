"""Sizing rules of the structure generator, one family per structure (the paper's sections
4.2.1 and 4.3):
tentative link lengths from the requirements, and the worst-case load cases.

Each family turns the resolved parameters (SI, see ``synth.params``) into
1. the template's named lengths and the extra template inputs (wheel radius, M), and
2. load cases: configurations, velocities, accelerations and external forces whose RNEA
   torques and joint wrenches bound what the actuators and links must carry, plus the
   joint speeds the behaviours need. These hand-made cases are joined by the design's
   own behaviours (``Family.behaviour_cases``: inverse dynamics with contact forces along
   every trajectory it will run, ``synth.sizing.behaviour_loads``).

Constants below are documented design choices, not knowledge about robot types (which
lives in the ontology) nor module data (which lives in the catalog).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

import gaits.humanoid
from adron.catalog import Catalog
from adron.errors import InfeasibleError, InputError
from gaits.base import DesignGeometry
from gaits.humanoid import (
    HumanoidController,
    leg_ik,
    leg_module_range,
    stance_height,
    stance_loads,
)
from kinematics.assemble import AssemblyError, _ordered_children, serial_links, wheel_size
from kinematics.dynamics import center_of_mass, external_force_at, forward_kinematics, rnea
from kinematics.partkinds import in_use
from kinematics.templates import Template, TemplateParams, build, default_lengths, plan_of
from synth.sizing.behaviour_loads import behaviour_case, motions_for

if TYPE_CHECKING:
    from synth.sizing.behaviour_loads import BehaviourCase

#: Lift of a foot above an obstacle, m; and clearance between neighbouring legs' reach, m.
STEP_MARGIN = 0.01
LEG_CLEARANCE = 0.02
#: Height the standing trunk keeps above an obstacle, m.
TRUNK_CLEARANCE = 0.03
#: Largest coxa swing used for a stride (rad): below the template's +-pi/3 limit.
COXA_SWING = math.pi / 4
#: Duty factor of the tripod (hexapod) and trot (quadruped) gaits.
DUTY = 0.5
#: Peak / mean joint speed of a smooth (minimum-jerk) swing.
PEAK_FACTOR = 1.875
#: Wheeled robots: time to reach the travel speed, s; chassis aspect L1 : L2.
ACCELERATION_TIME = 1.0
CHASSIS_ASPECT = 4 / 3
#: Tyre-on-floor friction (the MJCF's wheel contact class uses the same value).
TYRE_FRICTION = 1.0
#: Turning in place is done at this fraction of the travel speed (rim speed).
TURN_SPEED_FRACTION = 0.25
#: Headroom on the wheel speed when choosing the radius (the wheel's own inertia).
SPEED_MARGIN = 1.1
#: Gripper closing speed (rad/s); snake joint speed of its gaits (rad/s): amplitude 0.5 rad
#: at 0.5 Hz. Gripping: friction between jaws and object, and the jaw's lever (m).
GRIP_FRICTION = 0.5
JAW_LEVER = 0.03
GRIPPER_SPEED = 1.0
SNAKE_SPEED = 0.5 * 2 * math.pi * 0.5  # the peak of a sinusoid: amplitude x frequency
#: Share of the snake's head (base: main module, battery, sensors, payload) a lifted segment
#: carries at its free end. Simulated, the rolling gait of 3 and 4 SG90 modules saturates
#: with half the head counted (the square head rolls over its edge): the whole head.
HEAD_SHARE = 1.0
#: Humanoid proportions of the standing height (Fig. 21).
HUMANOID = {
    "femur": 0.22,
    "tibia": 0.22,
    "foot": 0.25,
    "trunk_height": 0.35,
    "hip_width": 0.2,
    "shoulder_width": 0.4,
    "upper_arm": 0.17,
    "forearm": 0.19,
}
#: The lengths a biped's sizing and its gait (the humanoid gait's maps, fitted on the
#: shipped BipedLeg and HumanoidTorso) read: the thigh and shank tubes, the foot plate,
#: the torso's height and hip width.
BIPED_LENGTHS = ("femur", "tibia", "foot", "trunk_height", "hip_width")
#: Humanoid: share of the half foot length ahead of and behind the centre of mass over
#: which the ankle must move the centre of pressure (the open-loop gait's balance margin).
ANKLE_COP_REACH = 0.5


@dataclass
class LoadCase:
    """One worst case: q, v, a (nv,) and external wrenches (nbodies, 6) for RNEA."""

    name: str
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    fext: np.ndarray | None = None
    #: where a family picked the case among others by its load (a gait's instant: (gait,
    #: sample index)), so that ``Family.load_cases_like`` can pick the same one again
    instant: tuple[str, int] | None = None


@dataclass
class Sizing:
    """What a family decides for one iteration."""

    lengths: dict[str, float]
    modules: int = 3
    wheel_radius: float = 0.03
    notes: list[str] = field(default_factory=list)
    #: the wheels' width m when their part kind gives it (None: the catalog's)
    wheel_width: float | None = None


def _clamp_length(name: str, value: float, catalog: Catalog, why: str) -> float:
    lo, hi = catalog.passive.min_link_length_m, catalog.passive.max_link_length_m
    if value > hi:
        raise InfeasibleError(
            f"{why} needs a link '{name}' of {value * 1000:.0f} mm, but the longest printable "
            f"link is {hi * 1000:.0f} mm (catalog passive.max_link_length)"
        )
    return max(lo, value)


def _joint_q(tmpl: Template, values: Mapping[str, float]) -> np.ndarray:
    """A configuration with the named joints (by suffix) set, others at zero."""
    model = tmpl.model
    q = np.zeros(model.nv)
    for j in model.joints:
        idx = model.q_index[model.joint(j.name)]
        if idx < 0:
            continue
        for suffix, angle in values.items():
            if j.name.endswith(suffix):
                q[idx] = angle
    return q


def _movable(tmpl: Template) -> list[str]:
    """The joints an actuator moves: the movable ones but the passive (a free wheel's)."""
    m = tmpl.model
    passive = set(tmpl.passive)
    return [j.name for j in m.joints if m.q_index[m.joint(j.name)] >= 0 and j.name not in passive]


def _accel_cases(
    tmpl: Template,
    q: np.ndarray,
    v: np.ndarray,
    accel: float,
    fext: np.ndarray | None,
    name: str,
    mask: np.ndarray | None = None,
) -> list[LoadCase]:
    """The case at rest plus all joints (those of ``mask``) accelerating one way and the
    other."""
    nv = tmpl.model.nv
    ones = np.ones(nv) * accel if mask is None else mask * accel
    return [
        LoadCase(f"{name}, holding", q, np.zeros(nv), np.zeros(nv), fext),
        LoadCase(f"{name}, accelerating", q, v, ones, fext),
        LoadCase(f"{name}, decelerating", q, v, -ones, fext),
    ]


def support_shares(points: np.ndarray, com: np.ndarray) -> np.ndarray:
    """Vertical ground forces (fractions of the weight) on feet at ``points`` (n, 2) that
    hold a body whose centre of mass is over ``com`` (2,) in static equilibrium: total 1
    and no moment about the centre of mass (least norm when the feet are more than
    three; feet that would have to pull are dropped)."""
    active = np.ones(len(points), dtype=bool)
    shares = np.zeros(len(points))
    while active.any():
        p = points[active] - com
        A = np.vstack([np.ones(len(p)), p[:, 0], p[:, 1]])
        f, *_ = np.linalg.lstsq(A, np.array([1.0, 0.0, 0.0]), rcond=None)
        if (f >= -1e-12).all():
            shares[active] = np.clip(f, 0.0, None)
            return shares / shares.sum()
        idx = np.flatnonzero(active)
        active[idx[np.argmin(f)]] = False
    raise InfeasibleError("no foot can carry the robot: its centre of mass is outside them")


def _support(
    tmpl: Template, q: np.ndarray, feet: list[str], weight: float, under_com: bool = False
) -> np.ndarray:
    """fext: the ground carries ``weight`` N on ``feet`` (upward, at the foot points,
    shared for static equilibrium about the centre of mass; with ``under_com`` a single
    foot's force acts under the centre of mass, as when the robot has shifted its weight
    over that foot)."""
    model = tmpl.model
    fext = np.zeros((len(model.bodies), 6))
    T = forward_kinematics(model, q)
    com = center_of_mass(model, q)
    points = []
    for foot in feet:
        k = tmpl.feet.index(foot)
        point = (T[model.body(foot)] @ np.append(tmpl.foot_points[k], 1.0))[:3]
        points.append(np.array([com[0], com[1], point[2]]) if under_com else point)
    shares = support_shares(np.array([p[:2] for p in points]), com[:2])
    for foot, point, share in zip(feet, points, shares, strict=True):
        b = model.body(foot)
        fext[b] += external_force_at(model, q, b, point, (0.0, 0.0, weight * share))
    return fext


def stride_length(reach: float) -> float:
    """The longest stride (m) of a leg whose foot is ``reach`` m from the coxa axis."""
    return 2 * reach * math.sin(COXA_SWING)


def alternate_feet(tmpl: Template) -> list[str]:
    """Every other foot around the trunk: a tripod of a hexapod, the diagonal pair of a
    quadruped's trot (feet ordered by their angle about the trunk's vertical axis)."""
    model = tmpl.model
    T = forward_kinematics(model, np.zeros(model.nv))
    angle = {f: math.atan2(T[model.body(f), 1, 3], T[model.body(f), 0, 3]) for f in tmpl.feet}
    ring = sorted(tmpl.feet, key=lambda f: (angle[f], f))
    return ring[::2]


def _arm_links(tmpl_or_type) -> list[str]:
    """The length names of a design's serial arm's printed links, column first (its first
    chain's)."""
    chains = _arm_chains(tmpl_or_type)
    return chains[0] if chains else []


def _arm_chains(tmpl_or_type) -> list[list[str]]:
    """The length names of the printed links of each of a design's chains (arms, heads),
    column first; alike chains (two arms of one mount share their lengths) once."""

    plan = tmpl_or_type.plan if isinstance(tmpl_or_type, Template) else plan_of(tmpl_or_type)
    out: list[list[str]] = []
    for chain in serial_links(plan, in_use()):
        if chain not in out:
            out.append(chain)
    return out


def _chain_reach(tmpl: Template, joint: str, chains: Sequence[Sequence[str]]) -> float:
    """m: the reach of the chain ``joint`` moves (its links after the column), the first
    chain's for a joint that moves none of them."""
    m = tmpl.model
    below = set(m.subtree(m.joints[m.joint(joint)].child)) if len(chains) > 1 else set()
    names = {s.length_name for s in tmpl.segments if m.body(s.body) in below}
    chain = next((c for c in chains if names & set(c)), chains[0])
    return sum(tmpl.lengths[k] for k in tmpl.lengths if k in chain[1:])


class Family(ABC):
    """Sizing of one kind of base configuration.

    ``joints``: when the family sizes one part of a composition (an arm on a wheeled
    base), a function of the template giving the joints it moves; None: all."""

    joints = None

    def movable(self, tmpl: Template) -> list[str]:
        """The joints this family moves: ``joints(tmpl)``, or every movable joint."""
        every = _movable(tmpl)
        if self.joints is None:
            return every
        mine = set(self.joints(tmpl))
        return [j for j in every if j in mine]

    def mask(self, tmpl: Template) -> np.ndarray | None:
        """(nv,) 1 for this family's joints, 0 elsewhere; None when it moves them all."""
        if self.joints is None:
            return None
        m = tmpl.model
        out = np.zeros(m.nv)
        for j in self.movable(tmpl):
            out[m.q_index[m.joint(j)]] = 1.0
        return out

    @abstractmethod
    def size(self, robot_type: str, p: Mapping[str, float], catalog: Catalog) -> Sizing:
        """Tentative lengths and template inputs from the parameters."""

    @abstractmethod
    def load_cases(
        self, tmpl: Template, p: Mapping[str, float], catalog: Catalog
    ) -> list[LoadCase]:
        """The worst cases to analyse on the analysis template."""

    @abstractmethod
    def speeds(
        self, tmpl: Template, p: Mapping[str, float], sizing: Sizing | None
    ) -> dict[str, float]:
        """Required speed (rad/s) of each movable joint."""

    def load_cases_like(
        self, tmpl: Template, p: Mapping[str, float], catalog: Catalog, like: Sequence[LoadCase]
    ) -> list[LoadCase]:
        """The cases ``like`` (``load_cases`` of a template with other masses) on ``tmpl``:
        the same poses, motions and instants with ``tmpl``'s masses, so that the torques
        of one case with two sets of masses can be compared (``synth.sizing.structure``'s
        torque model; ``load_cases`` itself may pick other instants as the masses move).
        Default: ``load_cases``, whose choices must not depend on the masses."""
        cases = self.load_cases(tmpl, p, catalog)
        if [c.name for c in cases] != [c.name for c in like]:
            raise RuntimeError(
                f"{type(self).__name__}.load_cases picks its cases by the masses; "
                "override load_cases_like"
            )
        return cases

    def analysis_modules(self, modules: int, lifted_share: float = 0.5) -> int:
        """Snake modules in the analysed chain (others: unused)."""
        return modules

    def analysis_params(self, tp: TemplateParams, lifted_share: float = 0.5) -> TemplateParams:
        """The template parameters of the analysed template (a snake: its lifted segment)."""
        return replace(tp, modules=self.analysis_modules(tp.modules, lifted_share))

    def holds(
        self, tmpl: Template, p: Mapping[str, float], catalog: Catalog
    ) -> dict[str, tuple[float, float, str]]:
        """A second operating point per joint beyond the RNEA load cases: (torque N m,
        speed rad/s it must keep under that torque, what it is). Default: none."""
        return {}

    def update(
        self, sizing: Sizing, tmpl: Template, p: Mapping[str, float], catalog: Catalog
    ) -> Sizing:
        """Sizing decisions that depend on the current masses (default: none)."""
        return sizing

    def behaviour_cases(
        self, tmpl: Template, geometry: DesignGeometry
    ) -> tuple[list[BehaviourCase], tuple[str, ...]]:
        """Load cases from the behaviours the design will run (``geometry``: the design as
        its controllers see it) on the analysis template ``tmpl`` with its masses, and
        notes on behaviours left out; default: every behaviour of the design's abilities,
        inverse dynamics with contact forces (``synth.sizing.behaviour_loads``)."""

        motions, notes = motions_for(geometry, tmpl)
        return [behaviour_case(tmpl, m) for m in motions], notes


class Manipulators(Family):
    """A serial arm on a fixed base (structure serial_arm): links from the reach; worst
    case stretched
    horizontally at full reach with the payload, every joint at the required speed and the
    catalog's maximum joint acceleration."""

    def size(self, robot_type, p, catalog):
        """The column keeps its default; the reach is shared by the other links: evenly
        by two, or with three or more the last (the wrist) gets its default up to a
        quarter of the reach and the rest share what remains."""
        d = default_lengths(robot_type)
        reach = p["reach"]
        why = f"reach {reach * 100:.0f} cm"
        lengths: dict[str, float] = {}
        for links in _arm_chains(robot_type):  # each chain (arm, head) reaches as far
            column, rest = links[0], links[1:]
            lengths.setdefault(column, d[column])
            if len(rest) >= 3:
                wrist = min(d[rest[-1]], reach / 4)
                arm = (reach - wrist) / (len(rest) - 1)
                for k in rest[:-1]:
                    lengths.setdefault(k, arm)
                lengths.setdefault(rest[-1], wrist)
            else:
                for k in rest:
                    lengths.setdefault(k, reach / len(rest))
        return Sizing({k: _clamp_length(k, v, catalog, why) for k, v in lengths.items()})

    def load_cases(self, tmpl, p, catalog):
        q = np.zeros(tmpl.model.nv)
        v = self._speed_vector(tmpl, p)
        return _accel_cases(
            tmpl,
            q,
            v,
            catalog.design.max_joint_acceleration_rad_s2,
            None,
            "stretched at full reach",
            self.mask(tmpl),
        )

    def _speed_vector(self, tmpl, p):
        speeds = self.speeds(tmpl, p, None)
        m = tmpl.model
        v = np.zeros(m.nv)
        for name, w in speeds.items():
            v[m.q_index[m.joint(name)]] = w
        return v

    def holds(self, tmpl, p, catalog):
        """The gripper holds the payload by friction: two jaws squeeze it with m g / (2 mu)
        each, at the jaw's lever, while the gripper stands still."""
        g = catalog.design.gravity_m_s2
        squeeze = p.get("payload", 0.0) * g / (2 * GRIP_FRICTION)
        return {
            j: (squeeze * JAW_LEVER, 0.0, "gripping the payload")
            for j in self.movable(tmpl)
            if tmpl.modules.get(j) == "GripperServomotor"
        }

    def speeds(self, tmpl, p, sizing):
        chains = _arm_chains(tmpl)
        grip = "GripperServomotor"
        return {
            j: (
                GRIPPER_SPEED
                if tmpl.modules.get(j) == grip
                else p["speed"] / _chain_reach(tmpl, j, chains)
            )
            for j in self.movable(tmpl)
        }


class Multipeds(Family):
    """Legs on a trunk (structure multiped): legs from the obstacle height h (the foot lifts
    h + STEP_MARGIN with the femur at 45 degrees; the trunk clears h standing); body links
    La1, La2 so that neighbouring legs' reachable strides do not overlap; worst case on the
    minimum support (hexapod: a tripod; quadruped: the two legs of a trot) carrying the
    whole robot and payload, the swing legs accelerating."""

    def size(self, robot_type, p, catalog):
        d = default_lengths(robot_type)
        h = p["obstacle_height"]
        why = f"obstacle height {h * 100:.1f} cm"
        shape = leg_shape(robot_type)
        lengths: dict[str, float] = {}
        # the lifting tube (the femur of a coxa-femur-tibia leg): the foot lifts h +
        # STEP_MARGIN with it at 45 degrees; the tubes hanging down (the tibia) clear h
        # standing and are at least 1.25 x it; the tubes before the first pitch joint (the
        # coxa) keep their lengths
        lift = (h + STEP_MARGIN) / math.sin(math.pi / 4) if shape.lift else 0.0
        down = max(h + TRUNK_CLEARANCE, 1.25 * lift)
        if not shape.lift:  # a leg that lifts its foot by swinging the tubes hanging down
            down = max(down, sum(d[k] for k in shape.down))
        for k in shape.order:
            if k == shape.lift:
                lengths[k] = lift
            elif k in shape.down:
                lengths[k] = down * d[k] / sum(d[j] for j in shape.down)
            else:
                lengths[k] = d[k]
        reach = sum(lengths[k] for k in shape.across)
        stride = stride_length(reach)
        spacing = stride + LEG_CLEARANCE
        legs_per_side = build(robot_type).legs // 2
        if shape.span:
            lengths[shape.span] = spacing * (legs_per_side - 1)
        if shape.track:
            lengths[shape.track] = max(d[shape.track], catalog.passive.dovetail_face_m * 2)
        out = {}
        for k, v in lengths.items():
            out[k] = v if k in (shape.span, shape.track) else _clamp_length(k, v, catalog, why)
        return Sizing(out, notes=[f"stride {stride * 100:.1f} cm"])

    def load_cases(self, tmpl, p, catalog):
        q = np.zeros(tmpl.model.nv)
        weight = tmpl.model.total_mass * catalog.design.gravity_m_s2
        support = alternate_feet(tmpl)
        fext = _support(tmpl, q, support, weight)
        v = np.zeros(tmpl.model.nv)
        return _accel_cases(
            tmpl,
            q,
            v,
            catalog.design.max_joint_acceleration_rad_s2,
            fext,
            f"standing on {len(support)} legs",
            self.mask(tmpl),
        )

    def speeds(self, tmpl, p, sizing):
        L = tmpl.lengths
        shape = leg_shape(tmpl.plan)
        reach = sum(L[k] for k in shape.across)
        stride = stride_length(reach)
        swing_time = stride / p["speed"] * (1 - DUTY) / DUTY
        rise = p["obstacle_height"] + STEP_MARGIN
        if shape.lift:
            lift = math.asin(min(1.0, rise / L[shape.lift]))
        else:  # the tubes hanging down swing out to lift the foot
            down = sum(L[k] for k in shape.down)
            lift = math.acos(max(-1.0, 1.0 - rise / down)) if down > 0 else math.pi / 2
        sweep = 2 * COXA_SWING
        w = PEAK_FACTOR * max(sweep, 2 * lift) / swing_time
        return dict.fromkeys(self.movable(tmpl), w)


def _biped_refusal(robot_type, missing: Sequence[str]) -> str:
    """Why a biped whose kinds lack ``missing`` of BIPED_LENGTHS is not sized: its kinds'
    files and what is supported."""

    kinds = in_use()
    plan = robot_type if hasattr(robot_type, "root") else plan_of(robot_type)
    where: list[str] = []

    legs = {"femur", "tibia", "foot"} & set(missing)

    def visit(node) -> None:
        k = kinds.of(node.kinds)
        mine = (k.role == "leg" and legs) or (k.root and set(missing) - legs) if k else False
        if mine and f"{k.where}: lengths" not in where:
            where.append(f"{k.where}: lengths")
        for c in node.children:
            visit(c)

    visit(plan.root)
    return (
        f"{'; '.join(where) or plan.robot_type}: a biped is sized and walked by the humanoid "
        "gait, fitted on legs of thigh and shank tubes named femur and tibia over a foot "
        f"plate `foot`, under a torso of trunk_height and hip_width; these kinds have no "
        f"{', '.join(missing)}"
    )


def _kind_wheel(
    robot_type, lengths: dict[str, float], what: str = "radius"
) -> tuple[float | None, str]:
    """(the radius (``what``: or width) m the design's wheel kinds give, where) or
    (None, "") (:func:`kinematics.assemble.wheel_size`)."""

    plan = robot_type if hasattr(robot_type, "root") else plan_of(robot_type)
    try:
        return wheel_size(plan, in_use(), lengths, what)
    except AssemblyError as e:
        raise InfeasibleError(str(e)) from None


@dataclass(frozen=True)
class LegShape:
    """The tubes of a multiped's leg read off its part kind's chain (never by their
    names): ``order``: every tube's length name, root first; ``across``: the tubes that
    reach out level from the trunk (along x or y at q = 0: the foot's distance from the
    first joint's axis); ``lift``: the last level tube after the first pitch joint (a
    horizontal axis across the leg, y), which lifts the foot ("" when none: a leg whose
    tubes after that joint hang down); ``down``: the tubes hanging down (along -z: the
    height the trunk stands at); ``span``, ``track``: the length names of the trunk's
    mount that spaces the legs (along x, across), "" when it has none."""

    order: tuple[str, ...]
    across: tuple[str, ...]
    lift: str
    down: tuple[str, ...]
    span: str = ""
    track: str = ""


def leg_shape(robot_type) -> LegShape:
    """The :class:`LegShape` of a multiped (robot type or body plan): its first leg part's
    kind; InfeasibleError naming the kind's file when its chain has no joint with a tube
    hanging down (no foot under the trunk)."""

    kinds = in_use()
    plan = robot_type if hasattr(robot_type, "root") else plan_of(robot_type)
    root_kind = kinds.of(plan.root.kinds)
    found = None
    for child, mount in _ordered_children(plan.root, root_kind, kinds):
        k = kinds.of(child.kinds)
        if k is not None and k.role == "leg":
            found = (k, mount)
            break
    if found is None:
        raise InfeasibleError(f"{plan.robot_type}: no leg part on its root part")
    kind, mount = found
    order, across, down = [], [], []
    lift = ""
    pitched = False
    for j in kind.joints:
        if j.axis in ("y", "-y") or any(a in ("y", "-y") for a in j.axes):
            pitched = True
        t = j.tube_length
        if not t:
            continue
        if t not in order:
            order.append(t)
        if j.tube_along in ("-z", "z"):
            down.append(t)
        else:
            across.append(t)
            if pitched:
                lift = t
    if not down:
        raise InfeasibleError(
            f"{plan.robot_type}: its leg kind {kind.cls} ({kind.where}, key `joints`) has "
            'no tube hanging down (a joint\'s tube `along = "-z"`): parmor sizes and walks '
            "legs whose last tubes hang down to a point foot, after level tubes reaching out "
            "from the trunk"
        )
    return LegShape(
        tuple(order),
        tuple(across),
        lift if lift not in down else "",
        tuple(down),
        mount.span if mount is not None else "",
        mount.track if mount is not None else "",
    )


class Humanoid(Family):
    """Two legs and two arms on an upright torso (structure biped): limb lengths in
    proportion to the standing height, within the leg
    module lengths whose gaits the conversion maps give (``gaits.humanoid``); worst cases
    on one foot in the walking gait's stance (crouched, the pelvis swayed over the stance
    ankle), the ground force under the centre of mass and at ``ANKLE_COP_REACH`` of the
    half foot ahead of and behind it (the ankle and the hip pitch move the centre of
    pressure to catch the open-loop gait's errors); and the gaits themselves (``GAITS``,
    default parameters): each joint's most loaded instant of each gait (the ground's force
    at the zero-moment point of the planned motion, ``gaits.humanoid.stance_loads``), and,
    as a second operating point, its fastest instant (that speed under that torque)."""

    #: The behaviours whose own loads and speeds a humanoid is sized for.
    GAITS = ("walking", "running")
    #: (lengths) -> per gait (name, times s, joint names, positions rad, velocities rad/s):
    #: the planned gaits depend on the lengths only (the sizing iterates on masses).
    _plans: dict[tuple, list[tuple[str, np.ndarray, tuple[str, ...], np.ndarray, np.ndarray]]]
    _plans = {}

    @classmethod
    def gait_plans(
        cls, tmpl: Template
    ) -> list[tuple[str, np.ndarray, tuple[str, ...], np.ndarray, np.ndarray]]:
        """Per gait of ``GAITS``: (name, times s, joint names, planned positions rad (n, J),
        velocities rad/s (n, J)) of its default run on ``tmpl``'s legs."""
        key = tuple(sorted((k, round(float(v), 12)) for k, v in tmpl.lengths.items()))
        if key not in cls._plans:
            geometry = DesignGeometry(
                robot_type=tmpl.robot_type,
                template=tmpl.robot_type,
                lengths=dict(tmpl.lengths),
                modules=1,
                wheel_radius=0.03,
                params={},
                abilities=(),
                joint_speed={},
            )
            controller = HumanoidController(geometry)
            runs = [controller.run(name) for name in cls.GAITS]
            cls._plans[key] = [
                (r.behavior, r.times, r.joints, r.positions, r.velocities) for r in runs
            ]
        return cls._plans[key]

    def _gait_loads(
        self, tmpl: Template
    ) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Per gait: (name, times s, model coordinates (n, nq) rad, joint speeds (n, nq)
        rad/s, the ground's wrenches (n, nbodies, 6)) with ``tmpl``'s masses; kept for the
        last template asked (``load_cases`` and ``holds`` ask for the same one in turn; a
        template is immutable, the arrays are only read)."""

        last = getattr(self, "_last_gait_loads", None)
        if last is not None and last[0] is tmpl:
            return last[1]
        model = tmpl.model
        index = {n: k for k, n in enumerate(model.q_names)}
        out = []
        for name, t, joints, q, v in self.gait_plans(tmpl):
            Q, fext = stance_loads(tmpl, joints, q, float(t[1] - t[0]))
            V = np.zeros_like(Q)
            V[:, [index[j] for j in joints]] = v
            out.append((name, t, Q, V, fext))
        self._last_gait_loads = (tmpl, out)
        return out

    def holds(self, tmpl, p, catalog):
        """Each joint's fastest instant of the gaits: (the torque then, that speed)."""

        model = tmpl.model
        best: dict[str, tuple[float, float, str]] = {}
        zero = np.zeros(model.nv)
        for name, _, Q, V, fext in self._gait_loads(tmpl):
            for j in _movable(tmpl):
                k = model.q_index[model.joint(j)]
                i = int(np.argmax(np.abs(V[:, k])))
                speed = float(abs(V[i, k]))
                if speed > best.get(j, (0.0, 0.0, ""))[1]:
                    tau = float(abs(rnea(model, Q[i], zero, zero, fext[i])[k]))
                    best[j] = (tau, speed, f"{name}, its fastest instant")
        return best

    def size(self, robot_type, p, catalog):
        H = p["height"]
        why = f"height {H * 100:.0f} cm"
        # the proportions of the lengths this body plan has (a biped without arms has no
        # upper_arm or forearm)
        have = default_lengths(robot_type)
        missing = [k for k in BIPED_LENGTHS if k not in have]
        if missing:
            raise InputError(_biped_refusal(robot_type, missing))
        lengths = {k: f * H for k, f in HUMANOID.items() if k in have}
        out = {}
        for k, v in lengths.items():
            tube = k in ("femur", "tibia", "upper_arm", "forearm")
            out[k] = _clamp_length(k, v, catalog, why) if tube else v
        self._check_gait_range(H, lengths, catalog)  # as asked, not clamped to printable
        return Sizing(out)

    @staticmethod
    def _check_gait_range(H: float, lengths: Mapping[str, float], catalog: Catalog) -> None:
        """InfeasibleError when the legs' module length is outside the sizes the gait's
        conversion maps were fitted on (never extrapolated), naming the nearest height
        that works."""

        lo, hi = leg_module_range()
        x = (lengths["femur"] + lengths["tibia"]) / 2
        if lo - 1e-12 <= x <= hi + 1e-12:
            return
        f = (HUMANOID["femur"] + HUMANOID["tibia"]) / 2
        lo_h = max(lo, catalog.passive.min_link_length_m) / f
        hi_h = min(hi, catalog.passive.max_link_length_m) / f
        best = lo_h if x < lo else hi_h
        raise InfeasibleError(
            f"height {H * 100:.0f} cm gives leg modules of {x * 1000:.0f} mm, outside the "
            f"{lo * 1000:.0f}-{hi * 1000:.0f} mm the walking gait's conversion maps were "
            f"fitted for (not extrapolated); the {'smallest' if x < lo else 'largest'} "
            f"height that works is {best * 100:.1f} cm"
        )

    @staticmethod
    def stance(tmpl: Template) -> np.ndarray:
        """The walking gait's single-support pose (nv,): crouched to the gait's stance
        height, the pelvis swayed over the left ankle by the gait's sway, arms hanging."""

        L = tmpl.lengths
        hw = L["hip_width"] / 2
        leg = L["femur"] + L["tibia"]
        walk = gaits.humanoid.WALK  # (read at call time: a test may replace it)
        y = walk.sway * hw
        ankle = np.array([0.0, -y, -stance_height(walk, leg, hw)])
        angles = leg_ik(ankle, L["femur"], L["tibia"])
        names = ("hip_yaw", "hip_roll", "hip_pitch", "knee_pitch", "ankle_pitch", "ankle_roll")
        return _joint_q(tmpl, dict(zip(names, (float(a) for a in angles), strict=True)))

    def load_cases(self, tmpl, p, catalog):
        return self._cases(tmpl, catalog, None)

    def load_cases_like(self, tmpl, p, catalog, like):
        """The stance cases, and the gaits at the instants of ``like``."""
        return self._cases(tmpl, catalog, [c.instant for c in like if c.instant is not None])

    def _cases(self, tmpl, catalog, instants: Sequence[tuple[str, int]] | None) -> list[LoadCase]:
        """The stance cases, then the gaits' cases: each joint's peak instant, or the
        ``instants`` (gait, sample index) given."""

        q = self.stance(tmpl)
        model = tmpl.model
        weight = model.total_mass * catalog.design.gravity_m_s2
        foot = [f for f in tmpl.feet if f.startswith("l")][0]
        T = forward_kinematics(model, q)
        com = center_of_mass(model, q)
        sole = (T[model.body(foot)] @ np.append(tmpl.foot_points[tmpl.feet.index(foot)], 1.0))[:3]
        reach = ANKLE_COP_REACH * tmpl.lengths["foot"] / 2
        v = np.zeros(model.nv)
        cases = []
        for where, dx in (("under the centre of mass", 0.0), ("toe", reach), ("heel", -reach)):
            fext = np.zeros((len(model.bodies), 6))
            point = np.array([com[0] + dx, com[1], sole[2]])
            fext[model.body(foot)] = external_force_at(
                model, q, foot, point, np.array([0.0, 0.0, weight])
            )
            cases += _accel_cases(
                tmpl,
                q,
                v,
                catalog.design.max_joint_acceleration_rad_s2,
                fext,
                f"on one foot in the walking stance, pressure {where}",
            )
        zero = np.zeros(model.nv)
        for name, t, Q, _, fext in self._gait_loads(tmpl):
            if instants is None:  # each joint's peak
                tau = np.abs(rnea(model, Q, np.zeros_like(Q), np.zeros_like(Q), fext))
                picked = sorted({int(i) for i in np.argmax(tau, axis=0)})
            else:
                picked = [i for gait, i in instants if gait == name]
            for i in picked:
                cases.append(
                    LoadCase(f"{name} at {t[i]:.2f} s", Q[i], zero, zero, fext[i], (name, i))
                )
        return cases

    def speeds(self, tmpl, p, sizing):
        L = tmpl.lengths
        leg = L["femur"] + L["tibia"]
        step = 0.5 * leg
        step_time = step / p["speed"]
        sweep = 2 * math.asin(min(1.0, step / 2 / leg))
        w = PEAK_FACTOR * sweep / (step_time * (1 - DUTY))
        return {j: (GRIPPER_SPEED if j.endswith("gripper") else w) for j in _movable(tmpl)}


class Snake(Family):
    """A chain of modules (structure module_chain): M from the ontology (the conceptual
    design); worst case lifting the
    longest unsupported segment of the gaits the robot lists (the largest of the ontology's
    ``liftedModuleShare`` over them), straight and horizontal, accelerating, its free end
    carrying ``HEAD_SHARE`` of the head (the base: main module, battery, sensors and the
    payload)."""

    def size(self, robot_type, p, catalog):
        return Sizing(default_lengths(robot_type))

    def analysis_modules(self, modules: int, lifted_share: float = 0.5) -> int:
        return max(1, math.ceil(modules * lifted_share))

    def analysis_params(self, tp, lifted_share=0.5):
        # the lifted segment of the chain, whether its modules are extensible (built
        # ``modules`` long) or written out in the body plan (cut to ``lifted``)
        k = self.analysis_modules(tp.modules, lifted_share)
        return replace(tp, modules=k, lifted=k)

    def load_cases(self, tmpl, p, catalog):
        model = tmpl.model
        q = np.zeros(model.nv)
        v = np.full(model.nv, SNAKE_SPEED)
        head = HEAD_SHARE * (tmpl.params.trunk_mass + p.get("payload", 0.0))
        tip = model.bodies[-1].name
        # the free end of the last module's tube (whatever its kind calls its length)
        seg = next((s for s in reversed(tmpl.segments) if s.body == tip), None)
        end = seg.start + seg.direction * seg.length if seg is not None else np.zeros(3)
        point = forward_kinematics(model, q)[model.body(tip)] @ np.array([*end, 1.0])
        fext = np.zeros((len(model.bodies), 6))
        weight = head * catalog.design.gravity_m_s2
        fext[model.body(tip)] = external_force_at(model, q, tip, point[:3], (0.0, 0.0, -weight))
        return _accel_cases(
            tmpl,
            q,
            v,
            catalog.design.max_joint_acceleration_rad_s2,
            fext,
            f"lifting {model.nv} modules and {head:.3f} kg of the head",
        )

    def speeds(self, tmpl, p, sizing):
        return dict.fromkeys(_movable(tmpl), SNAKE_SPEED)


class Wheeled(Family):
    """Wheels on a chassis (structure wheeled): chassis L1 x L2 from the load area
    (aspect 4:3); the wheel radius is the smallest with which some catalog
    continuous-rotation servo both holds the wheel's share of the traction force and turns
    fast enough under it (its speed falls linearly with torque) for the travel speed; worst
    case climbing the slope with the payload while accelerating to the travel speed in
    ACCELERATION_TIME. The wheel also lifts its servo off the ground: the servo's case is
    on the chassis, centred on the axle (``kinematics.templates``), so the radius is at
    least half the case's largest side across the shaft plus GROUND_CLEARANCE."""

    #: Ground clearance under a wheel servo's case, m: floor bumps, thresholds and cable
    #: covers of an indoor floor (about 1 cm) pass under it, and only the wheels touch.
    GROUND_CLEARANCE = 0.01
    #: The other load case a refusal names.
    ALSO_LOADED = ", or turning in place"

    def size(self, robot_type, p, catalog):
        area = p["load_area"]
        l1 = math.sqrt(area * CHASSIS_ASPECT)
        lengths = {"L1": l1, "L2": area / l1}
        names = {**default_lengths(robot_type), **lengths}
        own, _ = _kind_wheel(robot_type, names)
        width, _ = _kind_wheel(robot_type, names, "width")
        r = own if own is not None else catalog.passive.wheel_min_radius_m
        return Sizing(lengths, wheel_radius=r, wheel_width=width)

    @staticmethod
    def traction(mass: float, p: Mapping[str, float], catalog: Catalog) -> float:
        """Total traction force (N) to climb the slope while accelerating."""
        g, slope = catalog.design.gravity_m_s2, p["slope"]
        return mass * (
            g * (math.sin(slope) + catalog.design.rolling_resistance * math.cos(slope))
            + p["speed"] / ACCELERATION_TIME
        )

    def update(self, sizing, tmpl, p, catalog):
        n = len(tmpl.wheels)
        rho, width = catalog.material.density_kg_m3, catalog.passive.wheel_width_m
        width = sizing.wheel_width or width
        wheel_mass = lambda r: math.pi * r * r * width * rho  # noqa: E731 (solid printed disc)
        rest = tmpl.model.total_mass - n * wheel_mass(tmpl.params.wheel_radius)
        r = sizing.wheel_radius
        driven = len(self.driven(tmpl))
        # a wheel kind that gives its own radius keeps it: checked, not chosen
        own = _kind_wheel(tmpl.plan, dict(tmpl.lengths))
        for _ in range(50):  # the wheels' own mass depends on their radius: a fixed point
            mass = rest + n * wheel_mass(r)
            new = self._radius(
                [
                    (self.traction(mass, p, catalog) / driven, p["speed"]),
                    (self.turning_drag(tmpl, mass, catalog), TURN_SPEED_FRACTION * p["speed"]),
                ],
                p,
                catalog,
                own,
            )
            if abs(new - r) <= 1e-12:
                break
            r = new
        return replace(sizing, wheel_radius=r)

    def _radius(
        self,
        points: list[tuple[float, float]],
        p: Mapping[str, float],
        catalog: Catalog,
        own: tuple[float | None, str] = (None, ""),
    ) -> float:
        """The smallest printable wheel radius with which one servo meets every operating
        point (rim force N, ground speed m/s; speeds with SPEED_MARGIN); ``own``: (the
        radius m the wheel kind gives, where), which is returned when one servo meets them
        with it (InfeasibleError naming it and the radii that would work, otherwise)."""
        sf = catalog.design.torque_safety_factor
        r_min, r_max = catalog.passive.wheel_min_radius_m, catalog.passive.wheel_max_radius_m
        servos = catalog.actuators_of("ContinuousRotationServomotor")
        # whichever servo the assignment picks, its case clears the ground
        r_min = max(r_min, self.servo_clearance_radius(servos))
        if own[0] is not None:
            return self._own_radius(points, p, catalog, own, servos, r_min)
        best: float | None = None
        for a in servos:
            # at each point, the speed under load w0 (1 - F r / Ts) r must reach v: r at
            # least the smaller root of -(w0 F / Ts) r^2 + w0 r - v = 0; F r <= Ts / sf
            w0, ts = a.no_load_speed_rad_s, a.stall_torque_Nm
            lo, hi = r_min, r_max
            for force, speed in points:
                v = speed * SPEED_MARGIN
                k = w0 * force / ts
                disc = w0 * w0 - 4 * k * v
                if disc < 0:
                    lo = math.inf
                    break
                lo = max(lo, 2 * v / (w0 + math.sqrt(disc)))
                if force > 0:
                    hi = min(hi, ts / sf / force)
            if lo <= hi and (best is None or lo < best):
                best = lo
        if best is None:
            force, _ = max(points)
            raise InfeasibleError(
                "no catalog wheel servo drives a printable wheel clearing its servo "
                f"({r_min * 1000:.0f}-{r_max * 1000:.0f} mm) at {p['speed']:.2f} m/s while "
                f"pushing {force:.2f} N "
                f"(climbing a {math.degrees(p['slope']):.0f} deg slope{self.ALSO_LOADED}); "
                "ask for less speed, payload or slope"
            )
        return best

    def _own_radius(self, points, p, catalog, own, servos, r_min) -> float:
        """:meth:`_radius` for a wheel kind's own radius: that radius when a catalog
        servo meets every point with it and its case clears the ground."""
        r, where = own
        sf = catalog.design.torque_safety_factor
        for a in servos:
            w0, ts = a.no_load_speed_rad_s, a.stall_torque_Nm
            clear = r >= self.servo_clearance_radius([a]) - 1e-12
            ok = all(
                f * r <= ts / sf + 1e-12 and w0 * (1 - f * r / ts) * r >= s * SPEED_MARGIN - 1e-12
                for f, s in points
            )
            if clear and ok:
                return r
        force, _ = max(points)
        try:
            works = f"; {self._radius(points, p, catalog) * 1000:.1f} mm works"
        except InfeasibleError:
            works = ""
        raise InfeasibleError(
            f"{where}: no catalog wheel servo drives a wheel of radius {r * 1000:.1f} mm "
            f"(clearing its case by {self.GROUND_CLEARANCE * 1000:.0f} mm) at "
            f"{p['speed']:.2f} m/s while pushing {force:.2f} N (climbing a "
            f"{math.degrees(p['slope']):.0f} deg slope{self.ALSO_LOADED}){works}"
        )

    @classmethod
    def servo_clearance_radius(cls, servos) -> float:
        """The smallest wheel radius (m) that keeps every one of ``servos`` (catalog
        actuators; the case's size z is its shaft) GROUND_CLEARANCE above the ground when
        its case is centred on the axle: half the case's largest side across the shaft."""
        half = max((max(a.size_m[0], a.size_m[1]) / 2 for a in servos), default=0.0)
        return half + cls.GROUND_CLEARANCE

    def load_cases(self, tmpl, p, catalog):
        g = catalog.design.gravity_m_s2
        mass = tmpl.model.total_mass
        accel = p["speed"] / ACCELERATION_TIME
        traction = self.traction(mass, p, catalog)
        wheels = list(tmpl.wheels)
        m = tmpl.model
        q = np.zeros(m.nv)
        fext = np.zeros((len(m.bodies), 6))
        r = tmpl.params.wheel_radius
        T = forward_kinematics(m, q)
        driven = self.driven(tmpl)
        for w in wheels:
            # the ground pushes each driven wheel forward (and up) at its contact point
            b = m.body(w)
            contact = T[b, :3, 3] + np.array([0.0, 0.0, -r])
            push = traction / len(driven) if w in driven else 0.0
            force = (push, 0.0, mass * g / (len(wheels) + len(tmpl.casters)))
            fext[b] += external_force_at(m, q, b, contact, force)
        v = np.full(m.nv, p["speed"] / r)
        a = np.full(m.nv, accel / r)
        mask = self.mask(tmpl)
        if mask is not None:  # an arm on the base stands still meanwhile
            v, a = v * mask, a * mask
        return [
            LoadCase(
                f"climbing {math.degrees(p['slope']):.0f} deg while accelerating", q, v, a, fext
            )
        ]

    def speeds(self, tmpl, p, sizing):
        return dict.fromkeys(self.movable(tmpl), p["speed"] / tmpl.params.wheel_radius)

    @staticmethod
    def driven(tmpl: Template) -> list[str]:
        """The wheel bodies an actuator turns (a free wheel's joint is passive)."""
        m = tmpl.model
        passive = set(tmpl.passive)
        return [w for w in tmpl.wheels if m.joints[m.body(w)].name not in passive]

    @staticmethod
    def turning_drag(tmpl: Template, mass: float, catalog: Catalog) -> float:
        """The force (N) at each wheel's rim to turn in place. A robot without a caster
        (skid-steer) drags its wheels sideways: mu N a / sqrt(a^2 + b^2) per wheel (a:
        wheel base, b: track, N: its share of the weight, mu: tyre friction); 0 with a
        caster (differential drive turns by rolling)."""
        if tmpl.casters:
            return 0.0
        m = tmpl.model
        T = forward_kinematics(m, np.zeros(m.nv))
        xy = np.array([T[m.body(w), :2, 3] for w in tmpl.wheels])
        a = xy[:, 0].max() - xy[:, 0].min()
        b = xy[:, 1].max() - xy[:, 1].min()
        if a <= 0 or b <= 0:
            return 0.0
        share = mass * catalog.design.gravity_m_s2 / len(tmpl.wheels)
        return TYRE_FRICTION * share * a / math.hypot(a, b)

    def holds(self, tmpl, p, catalog):
        drag = self.turning_drag(tmpl, tmpl.model.total_mass, catalog)
        if drag <= 0:
            return {}
        r = tmpl.params.wheel_radius
        speed = TURN_SPEED_FRACTION * p["speed"] / r
        return {j: (float(drag * r), float(speed), "turning in place") for j in self.movable(tmpl)}


class Steered(Wheeled):
    """Wheels on a chassis, some of them steered (structure steered): sized as ``Wheeled``
    (chassis, wheel radius, the traction of climbing while accelerating) but for three
    things. Only the traction wheels push (a free wheel turns on its bearing and carries
    its share of the weight). The robot turns by rolling along arcs, so its wheels never
    drag sideways (no turning drag). And each steering joint turns its wheel about the
    vertical through the wheel's centre, twisting the tyre's contact on the floor: at
    rest (the worst case, steering before driving off) a Coulomb moment ``mu N l``, N the
    wheel's share of the weight (the lever rule between the front and rear wheels about
    the centre of mass), mu the tyre's friction (TYRE_FRICTION) and l the contact's lever
    about the steering axis: half the tyre's width (a narrow tyre's contact patch is
    about as long as it is wide, its radius half the width; MuJoCo touches the tyre at its
    two edges, +-width / 2, the same lever). The steering servo holds it while it turns
    the wheel lock to lock in STEER_TIME (the speed ``|limit| / STEER_TIME`` rad/s)."""

    #: Time to steer from straight to full lock, s.
    STEER_TIME = 0.5
    ALSO_LOADED = ""  # it never turns in place

    @staticmethod
    def steering(tmpl: Template) -> list[str]:
        """The steering joints (``gaits.steered.steering_joints``)."""
        from gaits.steered import steering_joints

        return [j for j, _ in steering_joints(tmpl)]

    def turning_drag(self, tmpl, mass, catalog):  # rolls along arcs, never scrubs sideways
        return 0.0

    def scrub_torque(self, tmpl: Template, mass: float, catalog: Catalog) -> dict[str, float]:
        """The scrub moment N m on each steering joint at rest (see the class docstring)."""
        from gaits.steered import wheel_loads

        loads = wheel_loads(tmpl, mass * catalog.design.gravity_m_s2)
        lever = (tmpl.params.wheel_width or catalog.passive.wheel_width_m) / 2
        return {j: TYRE_FRICTION * loads[w] * lever for j, w in self.steering_wheels(tmpl).items()}

    @staticmethod
    def steering_wheels(tmpl: Template) -> dict[str, str]:
        """Steering joint -> the wheel body it steers."""
        from gaits.steered import steering_joints

        return dict(steering_joints(tmpl))

    def steer_speed(self, tmpl: Template, joint: str) -> float:
        """The speed (rad/s) that steers ``joint`` lock to lock in STEER_TIME."""
        j = tmpl.model.joints[tmpl.model.joint(joint)]
        return max(abs(j.lower), abs(j.upper)) / self.STEER_TIME

    def load_cases(self, tmpl, p, catalog):
        cases = super().load_cases(tmpl, p, catalog)
        m = tmpl.model
        for k in self.steering(tmpl):  # the steering stands still while climbing
            i = m.q_index[m.joint(k)]
            for c in cases:
                c.v[i] = c.a[i] = 0.0
        return cases

    def speeds(self, tmpl, p, sizing):
        out = super().speeds(tmpl, p, sizing)
        for k in self.steering(tmpl):
            out[k] = self.steer_speed(tmpl, k)
        return out

    def holds(self, tmpl, p, catalog):
        out = super().holds(tmpl, p, catalog)
        for k, tau in self.scrub_torque(tmpl, tmpl.model.total_mass, catalog).items():
            out[k] = (float(tau), float(self.steer_speed(tmpl, k)), "steering at rest")
        return out

    def behaviour_cases(self, tmpl, geometry):
        # the hand cases bound a steered robot's behaviours: it drives along arcs at most
        # at the travel speed (traction) and steers at most at the steering speed (scrub)
        return [], ()


class _BaseWithChains(Family):
    """A base family's joints (``on_base``) and serial chains on the rest of one template:
    each sized on its own joints, the other's standing still; their lengths are apart."""

    def __init__(self, base: Family, on_base) -> None:
        self.base = base
        self.arm = Manipulators()
        self.base.joints = lambda t: [j for j in _movable(t) if on_base(t, j)]
        self.arm.joints = lambda t: [j for j in _movable(t) if not on_base(t, j)]

    def size(self, robot_type, p, catalog):
        b, a = self.base.size(robot_type, p, catalog), self.arm.size(robot_type, p, catalog)
        return replace(b, lengths={**b.lengths, **a.lengths}, notes=[*b.notes, *a.notes])

    def load_cases(self, tmpl, p, catalog):
        return [*self.base.load_cases(tmpl, p, catalog), *self.arm.load_cases(tmpl, p, catalog)]

    def speeds(self, tmpl, p, sizing):
        return {**self.base.speeds(tmpl, p, sizing), **self.arm.speeds(tmpl, p, sizing)}

    def holds(self, tmpl, p, catalog):
        return {**self.base.holds(tmpl, p, catalog), **self.arm.holds(tmpl, p, catalog)}


class MobileManipulator(_BaseWithChains):
    """A serial arm on a wheeled base: the base sized as ``Wheeled`` (the traction of the
    whole robot, the arm standing still) and the arm as ``Manipulators`` (stretched at
    full reach, the wheels standing still), each on its own joints of the one template;
    the chassis' lengths (L1, L2) and the arm's (arm_L1 ...) are apart."""

    def __init__(self) -> None:
        super().__init__(Wheeled(), lambda t, j: _wheel_joint(t, j))

    def update(self, sizing, tmpl, p, catalog):
        return self.base.update(sizing, tmpl, p, catalog)


class LeggedManipulator(_BaseWithChains):
    """Chains of joints (a head, an arm) on a multiped's trunk: the legs sized as
    ``Multipeds`` (the whole robot on its minimum support, the chains standing still) and
    each chain as ``Manipulators`` (stretched at full reach, the legs standing still), each
    on its own joints of the one template; the legs' lengths and the chains' (head_L1 ...)
    are apart."""

    def __init__(self) -> None:
        super().__init__(Multipeds(), lambda t, j: _leg_joint(t, j))


def _leg_joint(tmpl: Template, joint: str) -> bool:
    """Whether ``joint`` moves one of ``tmpl``'s feet."""
    m = tmpl.model
    below = set(m.subtree(m.joints[m.joint(joint)].child))
    return any(m.body(f) in below for f in tmpl.feet)


def _wheel_joint(tmpl: Template, joint: str) -> bool:
    """Whether ``joint`` turns one of ``tmpl``'s wheels."""
    m = tmpl.model
    return m.bodies[m.joints[m.joint(joint)].child].name in tmpl.wheels


#: The sizing rules of each structure (``kinematics.assemble.structure_of``): chosen by what
#: the design contains, never by its type's name.
FAMILIES: dict[str, Family] = {
    "serial_arm": Manipulators(),
    "multiped": Multipeds(),
    "biped": Humanoid(),
    "module_chain": Snake(),
    "wheeled": Wheeled(),
    "steered": Steered(),
    "mobile_manipulator": MobileManipulator(),
    "legged_manipulator": LeggedManipulator(),
    "multi_arm": Manipulators(),
}
