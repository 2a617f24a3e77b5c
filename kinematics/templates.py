"""Parametric kinematic models of robots (the paper's section 4.3): the template data model
and its building blocks; ``kinematics.assemble`` builds every template from a body plan
and the part kinds' data (no robot type is built by code of its own).

``build(robot_type_or_plan, params)`` returns a :class:`Template`: a
:class:`~kinematics.model.Model` whose link lengths, tube radii and masses come from
``params``, plus what the designer needs to analyse it (the printed tubes, feet, grippers,
wheels). A type's name finds its body plan (``plan_of``: registered, e.g. from a design's
record, or from the shipped ontology once ``synth.reasoning.plans.install()`` ran). The fixed root
body (base, trunk or chassis) is welded to the world: a worst-case static or dynamic
analysis of the limbs needs exactly that.

Conventions (all templates): z up, x forward, SI units. Every joint ``J`` moves the body
``J_link``; the root body hangs on the fixed joint ``root``. A movable joint's body holds
the actuator module of that joint (a box of ``params.actuator_size`` and the mass of the
joint's group, centred on the joint, aligned with the body frame) plus the printed tube
that starts at the joint (a hollow cylinder of ``params.density``) plus what ends there
(a foot, a gripper and the payload, a wheel). Pitch joints turn about +y, so a positive
angle turns a link that points along +x downwards (right-hand rule). Position limits are
listed per template; effort and velocity limits are left 0 for the designer to fill in.

The printed tube is a bare hollow cylinder unless ``params.face_side``, ``face_thickness``
and ``fillet`` are set: then it is the whole printed link module (paper Fig. 10: the tube,
a square dovetail face plate at each end and a fillet between each plate and the tube;
``kinematics.spatial.link_part_mass_properties``), of the same overall length.
``Template.parts`` keeps every body's parts, labelled, with their placement and
dimensions (:class:`LabelledPart`), so that exporters can rebuild each body from them.

What the part kinds (``kinematics/partkinds.toml``, where every axis, limit and mount is
data) give, by structure:

- a serial arm: the base plate under ``base_yaw`` (z); a column ``L1`` up, then links
  ``L2`` ... along +x after each pitch joint; roll joints sit at the end of the link before
  them; ``gripper`` at the chain's tip, holding the payload. Zero pose: stretched along +x;
- legs on a trunk plate ``La1`` (x, between the front and rear mounts) by ``La2`` (y):
  ``lf lm lh rf rm rh`` along both sides (an odd count: ``leg1`` ... around it), each
  ``X_coxa`` (z), ``X_femur`` and ``X_tibia`` (y), the tibia along -z to a point foot.
  Zero pose: standing, femur horizontal, tibia vertical;
- a biped torso (trunk frame at the pelvis): legs ``l``/``r`` of six joints ending in a
  foot plate, arms of two pitch joints and a gripper at its shoulders;
- a module chain: ``joint_i`` with body ``module_i``, pitch and yaw alternating, from a
  head box;
- wheels on a chassis (frame origin at the wheels' centre, ROS's base_link, at axle
  height): wheels in axles (``left_wheel`` ... or ``front_left_wheel`` ...), a trailing
  ball caster ``caster`` at ground level; each wheel's servo case is on the chassis,
  beside its wheel (``_servos_on_chassis``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from math import isfinite, pi
from types import MappingProxyType

import numpy as np

from kinematics.bodyplan import PLAN_SOURCE, BodyPlan
from kinematics.model import Body, Joint, Model
from kinematics.partkinds import in_use
from kinematics.spatial import (
    Part,
    box_inertia,
    link_part_mass_properties,
    point_inertia,
    rot_x,
    sphere_inertia,
    transform,
    transform_from,
    tube_inertia,
    tube_mass,
)

__all__ = [
    "DEFAULTS",
    "PART_KINDS",
    "PLANS",
    "LabelledPart",
    "Segment",
    "Template",
    "TemplateParams",
    "build",
    "default_lengths",
    "plan_of",
    "register_plan",
    "dovetail_volumes",
]

#: Tube radii (r_outer, r_inner) m used when ``TemplateParams.tubes`` names none.
DEFAULT_TUBE = (0.012, 0.009)
#: Actuator module mass kg used when ``TemplateParams.actuator_mass`` names none.
DEFAULT_ACTUATOR_MASS = 0.055

BASE_SIZE = (0.10, 0.10, 0.02)  # manipulator base plate, m, under the base_yaw joint
TRUNK_THICKNESS = 0.03  # legged trunk and snake base box height, m
HUMANOID_TRUNK_DEPTH = 0.06  # m (x)
CHASSIS_THICKNESS = 0.005  # m
#: Jaw plate (x along the jaw, y its width, z its thickness), m, when the params name none.
FINGER_SIZE = (0.05, 0.02, 0.012)
#: Gap between a gripper's open jaws, m (the jaws' inner faces are this far apart).
GRIPPER_OPENING = 0.03
FOOT_WIDTH_RATIO = 0.6  # humanoid foot plate width / length
FOOT_PLATE = 0.004  # humanoid foot plate thickness, m
WHEEL_WIDTH = 0.01  # m
#: Dovetail joining printed link modules (paper Fig. 10), m and rad: the pin's width where
#: it stands on its face, its height, and the flank angle from the face's normal (45 deg:
#: the pin and the rail's overhang print without support). The pin runs across the face.
DOVETAIL_ROOT = 0.006
DOVETAIL_HEIGHT = 0.002
DOVETAIL_FLANK = pi / 4
#: Hub bore radius of a printed wheel, m: the clearance hole of an M3 servo-horn screw.
WHEEL_BORE = 0.0017
CASTER_RADIUS = 0.01  # m, the ball's radius when the params name none
#: Gap between a steered wheel's top and its steering servo's case over it, m.
STEER_CLEARANCE = 0.005

#: Trunk part frames (columns: the part's x, y, z in the body frame): modules go up, down
#: (under a manipulator's base) or to the back (a humanoid's trunk, part x along y).
_UP = np.eye(3)
_DOWN = np.diag([1.0, -1.0, -1.0])
_BACK = np.column_stack([(0.0, 1.0, 0.0), (0.0, 0.0, -1.0), (-1.0, 0.0, 0.0)])

#: Body plans known to this process, by robot type (``register_plan``): the ontology's
#: types as ``synth`` reads them, and a bundle's own as its record keeps it.
PLANS: dict[str, BodyPlan] = {}


def register_plan(plan: BodyPlan) -> BodyPlan:
    """Make ``plan`` the body plan of its robot type in this process; returns it."""
    PLANS[plan.robot_type] = plan
    return plan


def plan_of(robot_type: str) -> BodyPlan:
    """The body plan of ``robot_type``: registered, or from
    ``kinematics.bodyplan.PLAN_SOURCE``; ValueError when there is none."""

    plan = PLANS.get(robot_type)
    if plan is None and PLAN_SOURCE:
        plan = PLAN_SOURCE[0](robot_type)
        if plan is not None:
            register_plan(plan)
    if plan is None:
        known = ", ".join(sorted(PLANS)) or "none registered"
        hint = (
            "" if PLAN_SOURCE else "; synth.reasoning.plans.install() finds the shipped ontology's"
        )
        raise ValueError(f"unknown robot type {robot_type!r}: no body plan (known: {known}){hint}")
    return plan


class _Defaults(Mapping[str, Mapping[str, float]]):
    """robot type -> its length names and defaults (m), read-only, from its body plan."""

    def __getitem__(self, robot_type: str) -> Mapping[str, float]:
        return MappingProxyType(default_lengths(robot_type))

    def __iter__(self):
        return iter(sorted(PLANS))

    def __len__(self) -> int:
        return len(PLANS)


#: Length names and defaults (m) of each known robot type (``default_lengths`` copies).
DEFAULTS: Mapping[str, Mapping[str, float]] = _Defaults()


@dataclass(frozen=True)
class TemplateParams:
    """Parameters of a template; every length, radius and mass in SI units.

    ``lengths``: named lengths (m), see ``DEFAULTS``; ``tubes``: (r_outer, r_inner) m per
    length name of a tube (default ``DEFAULT_TUBE``); ``actuator_mass``: kg per joint group
    (default ``DEFAULT_ACTUATOR_MASS``); ``payload``: kg, at the gripper of a manipulator,
    at the trunk otherwise; ``trunk_mass``: kg of the root body (plate, main module,
    battery); ``modules``: the snake's M. ``gripper_mass``: kg of a gripper's ``fingers``
    jaws together (each a plate of ``finger_size`` m); ``caster_mass`` kg and
    ``caster_radius`` m: the ball caster; ``bearing_mass`` kg: the bearing hub of a passive
    joint (a free wheel's), in place of an actuator, on the joint's parent (the axle's
    side). The structure generator passes the catalog's
    figures (kinematics imports nothing of parmor's); the defaults serve a template built
    alone.

    ``face_side``, ``face_thickness``, ``fillet`` (m): the printed link module's square
    dovetail face plates and the fillets between them and the tube (paper Fig. 10; geometry
    in ``kinematics.spatial.link_part_volume``). All 0 (the default): every link is a bare
    tube. When set, every link's mass properties are those of the whole printed part, with
    its dovetail (``dovetail_volumes``: a pin on the far face unless the link ends free,
    the rail's slot in the near face) when ``dovetail_clearance`` (m) is set.
    """

    lengths: Mapping[str, float] = field(default_factory=dict)
    tubes: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    density: float = 1240.0
    actuator_mass: Mapping[str, float] = field(default_factory=dict)
    actuator_size: tuple[float, float, float] = (0.040, 0.020, 0.040)
    payload: float = 0.0
    trunk_mass: float = 0.25
    modules: int = 3
    #: build only the first ``lifted`` modules of a module chain (0: all), extensible or
    #: written out: the unsupported segment its sizing analyses
    lifted: int = 0
    wheel_radius: float = 0.03
    #: the wheels' width m when their part kind gives it (None: the catalog's)
    wheel_width: float | None = None
    foot_mass: float = 0.01
    gripper_mass: float = 0.03
    fingers: int = 2
    finger_size: tuple[float, float, float] = FINGER_SIZE
    wheel_mass: float = 0.03
    caster_mass: float = 0.02
    caster_radius: float = CASTER_RADIUS
    bearing_mass: float = 0.006
    face_side: float = 0.0
    face_thickness: float = 0.0
    fillet: float = 0.0
    dovetail_clearance: float | None = None


def dovetail_volumes(
    face_side: float, r_inner: float, clearance: float, pin: bool
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The dovetail of a printed link: ((pin m^3, its centroid's height m above the far
    face, its mean width m), (slot m^3, its centroid's depth m into the near face, its
    mean width m)). The pin (none unless ``pin``) stands on the far face; the rail's slot,
    the pin's profile grown by ``clearance`` m on every side, is cut into the near face and
    removes nothing where it crosses the bore (radius ``r_inner``). Exact but for the
    integral over the slot's depth (Simpson's rule, 64 intervals)."""
    a, ri, c = float(face_side), float(r_inner), float(clearance)
    w0, h, th = DOVETAIL_ROOT / 2, DOVETAIL_HEIGHT, DOVETAIL_FLANK
    w1 = w0 + h * np.tan(th)
    pin_v = (w0 + w1) * h * a if pin else 0.0
    pin_z = h * (w0 + 2 * w1) / (3 * (w0 + w1))
    z = np.linspace(0.0, h + c, 65)
    w = w0 + c / np.cos(th) + z * np.tan(th)  # the slot's half-width at depth z (mitred)
    inside = np.minimum(w, ri)
    bore = 2 * inside * np.sqrt(np.maximum(ri * ri - inside * inside, 0.0))
    if ri > 0:
        bore = bore + 2 * ri * ri * np.arcsin(np.clip(inside / ri, -1.0, 1.0))
    area = 2 * w * a - bore
    step = z[1] - z[0]

    def simpson(f: np.ndarray) -> float:
        return float(step / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum()))

    slot_v = simpson(area)
    slot_z = simpson(area * z) / slot_v if slot_v > 0 else 0.0
    return (pin_v, pin_z, w0 + w1), (slot_v, slot_z, float(2 * w.mean()))


def _with_dovetail(
    part: tuple[float, np.ndarray, np.ndarray],
    p: TemplateParams,
    start: np.ndarray,
    d: np.ndarray,
    length: float,
    r_inner: float,
    pin: bool,
) -> tuple[float, np.ndarray, np.ndarray]:
    """A link part's (mass, com, inertia) with its dovetail pin added and its slot removed
    (each a box of its mean width, the face's side and its height)."""
    (pv, pz, pw), (sv, sz, sw) = dovetail_volumes(
        p.face_side, r_inner, p.dovetail_clearance or 0.0, pin
    )
    R = _tube_frame(d)
    m0, c0, i0 = part
    items = [(m0, c0, i0, 1.0)]
    if pv > 0:
        mp = p.density * pv
        ip = R @ box_inertia(mp, (pw, p.face_side, DOVETAIL_HEIGHT)) @ R.T
        items.append((mp, start + (length + pz) * d, ip, 1.0))
    ms = p.density * sv
    depth = DOVETAIL_HEIGHT + (p.dovetail_clearance or 0.0)
    items.append((ms, start + sz * d, R @ box_inertia(ms, (sw, p.face_side, depth)) @ R.T, -1.0))
    mass = sum(k * m for m, _, _, k in items)
    com = sum(k * m * c for m, c, _, k in items) / mass
    inertia = np.zeros((3, 3))
    for m, c, i, k in items:
        r = c - com
        inertia += k * (i + m * (float(r @ r) * np.eye(3) - np.outer(r, r)))
    return mass, com, inertia


@dataclass(frozen=True, eq=False)
class Segment:
    """One printed tube (a LinkModule) of the design, in the frame of its body.

    ``name`` is unique in the template (the length name, prefixed by the limb when several
    limbs share it); ``length_name`` is the length (and tube radii) it uses.
    ``distal_joint``: the joint at its far end, whose wrench loads it; None for a free end
    or a foot.
    """

    name: str
    body: str
    start: np.ndarray
    direction: np.ndarray
    length: float
    r_outer: float
    r_inner: float
    distal_joint: str | None
    length_name: str = ""

    def __post_init__(self) -> None:
        for attr in ("start", "direction"):
            a = np.array(getattr(self, attr), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, attr, a)

    @property
    def end(self) -> np.ndarray:
        """(3,) far end of the tube in the body frame, m."""
        return self.start + self.length * self.direction


#: Kinds of :class:`LabelledPart`.
PART_KINDS = (
    "actuator",
    "link",
    "trunk",
    "foot",
    "gripper",
    "payload",
    "wheel",
    "caster",
    "bearing",
    "tool",
    "plate",
)


@dataclass(frozen=True, eq=False)
class LabelledPart:
    """One rigid part of a template body, with what an exporter needs to rebuild it.

    ``mass`` kg, ``com`` (3,) m and ``inertia`` (3,3) kg m^2 about the COM, body axes:
    exactly the Part the body's mass properties combine. ``placement`` (4,4): body frame
    <- part frame. ``label``: the joint name (actuator), the segment name (link), the body
    name (other kinds). ``dims`` (m) and the part frame by ``kind``:

    - "actuator": (x, y, z) box (``params.actuator_size``) centred on the joint, body axes
      (a wheel's: on the chassis beside the wheel, its frame's z along the axle);
    - "link": (length, r_outer, r_inner, face_side, face_thickness, fillet); frame origin
      at the tube's start, z along the tube, x and y along the face plates' edges;
    - "trunk": (x, y, z) box of the root body centred on the frame origin; the frame's z
      points to the side where the trunk's modules go (manipulator base: down, humanoid:
      back, others: up) and its x is the box's long side;
    - "foot": () a point foot, or (x, y, z) a foot plate whose sole is the frame's z = 0
      plane; the frame origin is the contact point, body axes;
    - "gripper": one jaw of a gripper, an (x, y, z) plate centred on the frame origin: x
      along the jaw (away from the joint), z across the gap between the jaws;
    - "payload": () a point mass at the frame origin;
    - "wheel": (radius, width) disc centred on the frame origin, its axis the frame's z;
    - "caster": (radius,) ball centred on the frame origin;
    - "bearing": (radius, width) the hub of a passive joint, on the joint's parent at the
      joint's origin, its frame the joint's;
    - "tool": (x, y, z) box of a tool without joints (a probe, a nozzle, a camera) centred
      on the frame origin, x along the tool;
    - "plate": (x, y, z) box of a root part carried by another (a torso on a chassis),
      framed as a "trunk": a printed plate of its mass over the box's x-y face, with no
      modules (the carrier's root part holds them).
    """

    label: str
    kind: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    placement: np.ndarray
    dims: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in PART_KINDS:
            raise ValueError(f"part kind {self.kind!r} is not one of {PART_KINDS}")
        for attr in ("com", "inertia", "placement"):
            a = np.array(getattr(self, attr), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, attr, a)
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "dims", tuple(float(x) for x in self.dims))

    @property
    def part(self) -> Part:
        """(mass, com, inertia) as ``Body.from_parts`` takes it."""
        return self.mass, self.com, self.inertia


@dataclass(frozen=True, eq=False)
class Template:
    """A built template: its model and the parts the designer analyses.

    ``feet``: bodies that touch the ground at ``foot_points`` (body frame, m);
    ``wheels``: driven wheel bodies (centre at the body origin, contact ``wheel_radius``
    below it); ``casters``: passive support bodies touching the ground at their origin;
    ``end_effectors``: gripper bodies. ``lengths``: the lengths used (defaults filled in).
    ``parts``: body name -> its labelled parts; the body's mass, COM and inertia are
    exactly ``combine_parts`` of them, in order.
    """

    robot_type: str
    model: Model
    segments: tuple[Segment, ...]
    end_effectors: tuple[str, ...]
    feet: tuple[str, ...]
    foot_points: tuple[np.ndarray, ...]
    wheels: tuple[str, ...]
    legs: int
    arms: int
    length_names: tuple[str, ...]
    casters: tuple[str, ...] = ()
    lengths: Mapping[str, float] = field(default_factory=dict)
    params: TemplateParams = field(default_factory=TemplateParams)
    parts: Mapping[str, tuple[LabelledPart, ...]] = field(default_factory=dict)
    #: joint -> the catalog class that drives it, where the part kinds name one
    modules: Mapping[str, str] = field(default_factory=dict)
    #: the body plan it was assembled from
    plan: BodyPlan | None = None
    #: movable joints that no actuator drives (a free wheel's: it turns on a bearing)
    passive: tuple[str, ...] = ()

    @property
    def wheel_joints(self) -> tuple[str, ...]:
        """The joints that turn the driven wheels (``wheels``), in their order."""
        m = self.model
        return tuple(m.joints[m.body(w)].name for w in self.wheels)

    @property
    def groups(self) -> dict[str, tuple[str, ...]]:
        """Joint names of each actuator group, in joint order (passive joints have none)."""
        out: dict[str, list[str]] = {}
        for j in self.model.joints:
            if j.movable and j.name not in self.passive:
                out.setdefault(j.group, []).append(j.name)
        return {g: tuple(names) for g, names in out.items()}


def default_lengths(robot_type: str | BodyPlan) -> dict[str, float]:
    """The length names of a robot type (or body plan) with their default values, m."""
    from kinematics.assemble import length_defaults

    plan = robot_type if isinstance(robot_type, BodyPlan) else plan_of(robot_type)
    return length_defaults(plan, in_use())


# --- building blocks ---------------------------------------------------------------------------


class _Builder:
    """Collects bodies, joints and segments of one template."""

    def __init__(self, robot_type: str, params: TemplateParams, lengths: dict[str, float]):
        self.robot_type = robot_type
        self.p = params
        self.L = lengths
        self.bodies: list[Body] = []
        self.joints: list[Joint] = []
        self.segments: list[Segment] = []
        self.parts: dict[str, tuple[LabelledPart, ...]] = {}

    def index(self, body: str | None) -> int:
        if body is None:
            return -1
        for i, b in enumerate(self.bodies):
            if b.name == body:
                return i
        raise KeyError(body)

    def add(
        self,
        joint: str,
        parent: str | None,
        kind: str,
        origin: np.ndarray,
        parts: list[LabelledPart],
        axis: tuple[float, float, float] = (0.0, 0.0, 1.0),
        limits: tuple[float, float] = (-pi, pi),
        group: str = "",
        body: str | None = None,
        passive: bool = False,
    ) -> str:
        """Add joint ``joint`` and its body (default ``joint + "_link"``); the body's name.
        A movable joint's body carries its actuator, a ``passive`` one's a bearing hub."""
        name = body or f"{joint}_link"
        if passive:
            parts = [self.bearing(joint), *parts]
        elif kind != "fixed":
            parts = [self.actuator(group, joint), *parts]
        i = len(self.bodies)
        self.bodies.append(Body.from_parts(name, [lp.part for lp in parts]))
        self.parts[name] = tuple(parts)
        self.joints.append(
            Joint(
                joint,
                self.index(parent),
                i,
                kind,
                origin,
                np.array(axis, dtype=float),
                lower=limits[0],
                upper=limits[1],
                group=group,
            )
        )
        return name

    def actuator(self, group: str, joint: str) -> LabelledPart:
        m = float(self.p.actuator_mass.get(group, DEFAULT_ACTUATOR_MASS))
        size = tuple(self.p.actuator_size)
        return LabelledPart(
            joint, "actuator", m, np.zeros(3), box_inertia(m, size), np.eye(4), size
        )

    def bearing(self, joint: str) -> LabelledPart:
        """The bearing hub of a passive joint: ``bearing_mass`` at the joint, the inertia of
        a ball of radius 3 x WHEEL_BORE (the bearings' size; it is negligible)."""
        m = float(self.p.bearing_mass)
        r = 3 * WHEEL_BORE
        return LabelledPart(
            joint, "bearing", m, np.zeros(3), sphere_inertia(m, r), np.eye(4), (r, WHEEL_WIDTH)
        )

    def tube(
        self,
        name: str,
        length_name: str,
        body: str,
        direction: tuple[float, float, float],
        distal: str | None,
        start: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> LabelledPart:
        """Record a segment on ``body`` and return its printed link part."""
        p = self.p
        length = self.L[length_name]
        ro, ri = self.p.tubes.get(length_name, DEFAULT_TUBE)
        d = np.array(direction, dtype=float)
        s = np.array(start, dtype=float)
        self.segments.append(
            Segment(name, body, s, d, length, float(ro), float(ri), distal, length_name)
        )
        faces = (p.face_side, p.face_thickness, p.fillet)
        if any(faces):
            m, c, inertia = link_part_mass_properties(p.density, length, ro, ri, *faces, axis=d)
            com = s + c
            if p.dovetail_clearance is not None and p.face_side > 0:
                m, com, inertia = _with_dovetail(
                    (m, com, inertia), p, s, d, length, float(ri), distal is not None
                )
        else:  # the bare tube, computed as it always was
            m = tube_mass(p.density, length, ro, ri)
            com, inertia = s + 0.5 * length * d, tube_inertia(m, length, ro, ri, d)
        dims = (length, float(ro), float(ri), *(float(x) for x in faces))
        return LabelledPart(name, "link", m, com, inertia, transform_from(_tube_frame(d), s), dims)

    def model(self) -> Model:
        return Model(tuple(self.bodies), tuple(self.joints))


def _frozen(x) -> np.ndarray:
    a = np.array(x, dtype=float)
    a.setflags(write=False)
    return a


def _tube_frame(direction: np.ndarray) -> np.ndarray:
    """Rotation (3,3) whose z column is ``direction`` and whose x column is the body's z
    (or, for a tube along z, the body's x) made perpendicular to it."""
    z = direction / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _point(label: str, kind: str, mass: float, at=(0.0, 0.0, 0.0)) -> LabelledPart:
    return LabelledPart(
        label, kind, mass, np.array(at, dtype=float), point_inertia(mass), transform(at)
    )


def _box(label: str, kind: str, mass: float, size, at=(0.0, 0.0, 0.0)) -> LabelledPart:
    return LabelledPart(
        label,
        kind,
        mass,
        np.array(at, dtype=float),
        box_inertia(mass, size),
        transform(at),
        tuple(size),
    )


def _trunk(label: str, mass: float, size, at, R: np.ndarray) -> LabelledPart:
    """The root body's box: ``size`` (body axes) centred at ``at``; ``R`` (a signed axis
    permutation) turns the part frame into the body frame (its z: where modules go)."""
    dims = tuple(float(size[int(np.argmax(np.abs(R[:, k])))]) for k in range(3))
    return LabelledPart(
        label,
        "trunk",
        mass,
        np.array(at, dtype=float),
        box_inertia(mass, size),
        transform_from(R, at),
        dims,
    )


def _gripper_parts(
    p: TemplateParams, payload: float, body: str, forward=(1.0, 0.0, 0.0), side=(0.0, 1.0, 0.0)
) -> list[LabelledPart]:
    """The jaws of a gripper (``p.fingers`` plates of ``p.finger_size``, the gripper's mass
    shared equally) reaching along ``forward`` from the body origin, spread around it from
    ``side`` (two jaws: on either side, ``GRIPPER_OPENING`` apart), and the payload, held
    at the body origin."""
    n = int(p.fingers)
    if n < 1:
        raise ValueError(f"fingers must be at least 1, got {p.fingers!r}")
    size = tuple(float(x) for x in p.finger_size)
    x = np.asarray(forward, dtype=float)
    out = []
    for k in range(n):
        turn = 2 * pi * k / n
        # ``side`` turned about ``forward`` by ``turn`` (Rodrigues; side is perpendicular)
        z = np.cos(turn) * np.asarray(side, dtype=float) + np.sin(turn) * np.cross(x, side)
        R = np.column_stack([x, np.cross(z, x), z])
        centre = x * size[0] / 2 + z * (GRIPPER_OPENING / 2 + size[2] / 2)
        m = p.gripper_mass / n
        out.append(
            LabelledPart(
                body,
                "gripper",
                m,
                centre,
                R @ box_inertia(m, size) @ R.T,
                transform_from(R, centre),
                size,
            )
        )
    return [*out, _point(body, "payload", payload)]


def _servos_on_chassis(b: _Builder, chassis: str, wheels: tuple[str, ...]) -> None:
    """Move each wheel's actuator module from the wheel's body to the chassis: the servo's
    case is fixed to the chassis and only its shaft turns with the wheel, so nothing but
    the wheel turns or touches the ground. The case sits beside the wheel on the inner
    side (a wheel on the middle line: on its right), its frame's z (the shaft) along the
    axle, centred on the axle's height. A steering joint's (a joint about the vertical)
    sits over the wheel, its shaft down along the steering axis, the case's bottom
    ``STEER_CLEARANCE`` above the wheel's top."""
    moved: list[LabelledPart] = []
    for body in wheels:
        i = b.index(body)
        joint = next(j for j in b.joints if j.child == i)
        act = next(lp for lp in b.parts[body] if lp.kind == "actuator")
        rest = tuple(lp for lp in b.parts[body] if lp is not act)
        b.parts[body] = rest
        b.bodies[i] = Body.from_parts(body, [lp.part for lp in rest])
        pos = joint.origin[:3, 3]
        size = act.dims
        axis = joint.origin[:3, :3] @ joint.axis
        if abs(abs(axis[2]) - 1.0) < 1e-9:  # a steering joint: over the wheel
            R = joint.origin[:3, :3]
            lift = b.p.wheel_radius + STEER_CLEARANCE + size[2] / 2
            centre = pos + np.array([0.0, 0.0, lift])
        else:
            inboard = -(np.sign(pos[1]) or 1.0) * (WHEEL_WIDTH / 2 + size[2] / 2)
            R = joint.origin[:3, :3] @ rot_x(-pi / 2)  # part z along the wheel's axle
            centre = pos + np.array([0.0, inboard, 0.0])
        inertia = R @ box_inertia(act.mass, size) @ R.T
        moved.append(
            LabelledPart(
                act.label, "actuator", act.mass, centre, inertia, transform_from(R, centre), size
            )
        )
    k = b.index(chassis)
    b.parts[chassis] = (*b.parts[chassis], *moved)
    b.bodies[k] = Body.from_parts(chassis, [lp.part for lp in b.parts[chassis]])


def _bearing_on_parent(b: _Builder, body: str) -> None:
    """Move the bearing hub of passive joint's ``body`` to its parent: the hub's axle is
    fixed to the parent (a chassis, a steering fork) and the wheel turns on it."""
    i = b.index(body)
    joint = next(j for j in b.joints if j.child == i)
    hub = next(lp for lp in b.parts[body] if lp.kind == "bearing")
    rest = tuple(lp for lp in b.parts[body] if lp is not hub)
    b.parts[body] = rest
    b.bodies[i] = Body.from_parts(body, [lp.part for lp in rest])
    R, p = joint.origin[:3, :3], joint.origin[:3, 3]
    moved = LabelledPart(
        hub.label,
        "bearing",
        hub.mass,
        R @ hub.com + p,
        R @ hub.inertia @ R.T,
        joint.origin @ hub.placement,
        hub.dims,
    )
    parent = b.bodies[joint.parent].name
    b.parts[parent] = (*b.parts[parent], moved)
    b.bodies[joint.parent] = Body.from_parts(parent, [lp.part for lp in b.parts[parent]])


# --- checking and the entry point ----------------------------------------------------------------


def _nonneg(name: str, x: float) -> None:
    if not (isinstance(x, (int, float, np.floating, np.integer)) and isfinite(x) and x >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {x!r}")


def check_params(
    robot_type: str, p: TemplateParams, defaults: Mapping[str, float]
) -> dict[str, float]:
    """Validated lengths with ``defaults`` filled in; ValueError naming the valid choices."""
    names = ", ".join(defaults)
    unknown = sorted(set(p.lengths) - set(defaults))
    if unknown:
        raise ValueError(f"{robot_type} has no length {', '.join(unknown)}; lengths: {names}")
    lengths = dict(defaults)
    for k, x in p.lengths.items():
        if not (isinstance(x, (int, float, np.floating, np.integer)) and isfinite(x) and x > 0):
            raise ValueError(f"{robot_type} length {k} must be a positive number, got {x!r}")
        lengths[k] = float(x)
    for k, radii in p.tubes.items():
        try:
            ro, ri = (float(r) for r in radii)
        except (TypeError, ValueError):
            raise ValueError(f"tube {k}: expected (r_outer, r_inner), got {radii!r}") from None
        if not (isfinite(ro) and isfinite(ri) and 0 <= ri < ro):
            raise ValueError(f"tube {k}: need 0 <= r_inner < r_outer, got ({ro}, {ri})")
    for name in ("density",):
        x = getattr(p, name)
        _nonneg(name, x)
        if x == 0:
            raise ValueError(f"{name} must be positive")
    for name in (
        "payload",
        "trunk_mass",
        "foot_mass",
        "gripper_mass",
        "wheel_mass",
        "caster_mass",
        "bearing_mass",
    ):
        _nonneg(name, getattr(p, name))
    for name in ("face_side", "face_thickness", "fillet", "caster_radius"):
        _nonneg(name, getattr(p, name))
    if (p.face_side > 0) != (p.face_thickness > 0) or (p.fillet > 0 and p.face_side == 0):
        raise ValueError(
            "face_side and face_thickness are both set (printed links with face plates) or "
            f"both 0 (bare tubes), and a fillet needs them; got face_side={p.face_side}, "
            f"face_thickness={p.face_thickness}, fillet={p.fillet}"
        )
    for g, m in p.actuator_mass.items():
        _nonneg(f"actuator_mass[{g!r}]", m)
    size = tuple(p.actuator_size)
    if len(size) != 3 or not all(isfinite(s) and s > 0 for s in size):
        raise ValueError(f"actuator_size must be three positive lengths, got {p.actuator_size!r}")
    return lengths


#: Templates built last, newest last: ((plan key, part kinds), repr of the params, repr of the
#: template's lengths, template). The structure generator builds the same template several
#: times an iteration (for the sizing update, the analysis, the record).
_BUILT: list[tuple[str, str, str, Template]] = []
#: How many recent templates ``build`` keeps.
BUILD_CACHE_SIZE = 8


def build(robot_type: str | BodyPlan, params: TemplateParams | None = None) -> Template:
    """The parametric model of a robot type (its registered body plan, ``plan_of``) or of
    a body plan, assembled from the part kinds (``kinematics.assemble``).

    ValueError for an unknown type, unknown or non-positive lengths, bad radii, negative
    masses, or actuator masses for groups the template does not have (the message lists the
    valid names); ``kinematics.assemble.AssemblyError`` (a ValueError) for a plan the part
    kinds cannot assemble.

    A template is immutable, so the same one is returned for parameters whose ``repr`` is
    the same as one of the last ``BUILD_CACHE_SIZE`` builds' (``repr`` tells every float
    apart, -0.0 from 0.0 too), unless the caller has since changed that template's
    parameters or lengths in place.
    """
    from kinematics.assemble import assemble

    plan = robot_type if isinstance(robot_type, BodyPlan) else plan_of(robot_type)
    p = params if params is not None else TemplateParams()
    kinds = in_use()
    key = repr(p)
    pk = (plan.key(), id(kinds))  # the part kinds are loaded once per set of files
    for k, (rt, ck, lk, t) in enumerate(_BUILT):
        if rt == pk and ck == key and repr(t.params) == key and repr(t.lengths) == lk:
            _BUILT.append(_BUILT.pop(k))
            return t
    t = assemble(plan, p, kinds)
    _BUILT.append((pk, key, repr(t.lengths), t))
    del _BUILT[:-BUILD_CACHE_SIZE]
    return t
