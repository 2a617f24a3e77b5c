"""The structure generator: the paper's co-design loop (sections 4.2.1-4.2.3).

Starting from the conceptual design (a robot type with its parts and modules):

1. tentative link lengths from the requirements (``synth.sizing.families``);
2. worst-case RNEA on the type's kinematic template (``kinematics``): joint torques and
   the wrenches every link carries, for the family's hand-made load cases and along every
   behaviour the design lists, planned with the actuators of the previous pass (none on
   the first), with the ground's contact forces (``synth.sizing.behaviour_loads``); the joint
   speeds too come from both, and a joint's actuator must meet each (torque, speed)
   operating point (its speed falls with torque; a behaviour's torque and speed peaks
   need not coincide);
3. actuator assignment (``synth.sizing.assign.ActuatorAssigner``; the models that can never be
   a joint's best choice discarded first: ``synth.sizing.assign.dominated``): a model is capable
   for a joint
   when its stall torque divided by the catalog's torque safety factor covers the required
   torque and its speed under that torque (a servo's speed falls linearly from no-load
   speed at no torque to zero at stall) covers the required speed;
4. each printed link as the minimum-volume tube that keeps its tip deflection within the
   allowed one (``synth.sizing.links.optimal_tube``), thickened (more stiffness asked of it) until
   its clamped-end stress, with the fillet's stress concentration, is within the
   material's yield over the stress safety factor;
5. again from 2 with the new masses, until the masses change by less than 1e-6
   (relative) and the behaviours were planned with the actuators chosen, or an
   infeasibility error that names the requirement and the best value that can be
   reached.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from adron.catalog import I2C_DEFAULT, Actuator, Bus, Catalog, catalog_facts
from adron.errors import InfeasibleError, InputError, OntologyError
from adron.kb import KnowledgeBase
from kinematics.assemble import STRUCTURES, AssemblyError, unused_lengths
from kinematics.dynamics import joint_wrenches, rnea
from kinematics.partkinds import _names, evaluate, in_use
from kinematics.spatial import link_part_volume
from kinematics.templates import (
    FOOT_WIDTH_RATIO,
    WHEEL_BORE,
    Segment,
    Template,
    TemplateParams,
    build,
    register_plan,
)
from synth.params import lowest, ontology_defaults, resolve
from synth.reasoning.conceptual import ability_ancestors
from synth.reasoning.plans import ancestors, structure_of_type
from synth.reasoning.solver import Candidate
from synth.sizing.assign import (
    ActuatorAssigner,
    Assignment,
    Coupled,
    JointSlot,
    Points,
    best_first,
    count_bounds,
    count_by_enumeration,
    distinct_points,
    dominated,
    feasible_mask,
    product_rows,
)
from synth.sizing.behaviour_loads import BehaviourCase, analyse, design_geometry
from synth.sizing.chain_links import Chain, ChainLink, chain_tubes, serial_chains
from synth.sizing.families import FAMILIES, Family, LoadCase, Sizing
from synth.sizing.links import (
    Tube,
    TubeLimits,
    beam_check,
    max_allowed_stress,
    optimal_tube,
    stiffness_constant,
)

CONVERGENCE = 1e-6
MAX_ITERATIONS = 50
STRESS_BISECTIONS = 40  # relative precision 1e-12 of the stiffness asked of the tube


@dataclass(frozen=True)
class LinkDesign:
    """One printed link design (all segments sharing a length name use it): the optimised
    tube (``volume_m3``: the paper's objective) and the whole printed part with its two
    dovetail faces and fillets (``part_volume_m3``, ``mass_kg``)."""

    name: str
    count: int
    length_m: float
    r_outer_m: float
    r_inner_m: float
    volume_m3: float
    part_volume_m3: float
    mass_kg: float
    tip_deflection_m: float
    max_deflection_m: float
    max_stress_Pa: float
    allowed_stress_Pa: float
    branch: str
    governed_by: str  # "deflection" or "stress"


@dataclass(frozen=True)
class JointDesign:
    name: str
    group: str
    module_class: str
    actuator: str
    required_torque_Nm: float
    actuator_torque_Nm: float  # stall torque
    usable_torque_Nm: float  # stall torque / safety factor
    required_speed_rad_s: float
    load_case: str
    i2c_address: int = 0
    no_load_speed_rad_s: float = 0.0
    hold_torque_Nm: float = 0.0  # a second operating point (0: none): torque ...
    hold_speed_rad_s: float = 0.0  # ... at this speed
    hold: str = ""  # ... while doing this (gripping, turning in place)
    # the (N m, rad/s) points the actuator meets (its speed under each torque): the hand
    # cases' torque at the family's speed and the behaviours' samples that can bind it
    operating_points: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class ModuleUse:
    kind: str
    model: str
    count: int
    i2c_addresses: tuple[int, ...]  # empty for the bus master


@dataclass(frozen=True)
class Power:
    peak_current_A: float  # every actuator at its required torque, plus the modules
    stall_current_A: float  # every actuator stalled, plus the modules
    battery_max_current_A: float
    ok: bool


@dataclass(frozen=True)
class Metrics:
    """The paper's MR&H: modularity (modules), regularity (reuse), hierarchy (depth)."""

    modularity: int
    regularity: float
    hierarchy: int


@dataclass(frozen=True)
class Structure:
    robot_type: str
    params: dict[str, float]
    ignored_params: tuple[str, ...]
    lengths: dict[str, float]
    wheel_radius_m: float | None
    links: tuple[LinkDesign, ...]
    joints: tuple[JointDesign, ...]
    modules: tuple[ModuleUse, ...]
    mass_kg: float
    cost: float
    power: Power
    metrics: Metrics
    iterations: int
    template: Template = field(repr=False, compare=False)
    notes: tuple[str, ...] = ()
    bus: Bus = I2C_DEFAULT  # the catalog's bus the addresses are on

    @property
    def payload_kg(self) -> float:
        """The payload (kg) the structure was sized to carry: a load, not a part."""
        parts = self.template.parts.values()
        return sum(lp.mass for ps in parts for lp in ps if lp.kind == "payload")

    @property
    def robot_mass_kg(self) -> float:
        """The robot's own mass (kg): ``mass_kg`` (sized, loaded) without the payload; the
        BOM's and the models' total."""
        return self.mass_kg - self.payload_kg


def module_class(tmpl: Template, joint: str) -> str:
    """The ontology class of the module that drives a template joint: the part kind's
    ``module`` (a position servo unless the part kinds name another)."""
    return tmpl.modules.get(joint) or "PositionServomotor"


def _slots(tmpl: Template) -> list[JointSlot]:
    """The joints to give actuators: the movable ones but the passive (a free wheel's)."""
    m = tmpl.model
    return [
        JointSlot(j.name, j.group, module_class(tmpl, j.name))
        for j in m.joints
        if m.q_index[m.joint(j.name)] >= 0 and j.name not in tmpl.passive
    ]


def usable_torque(a: Actuator, catalog: Catalog) -> float:
    return a.stall_torque_Nm / catalog.design.torque_safety_factor


def meets(a: Actuator, torque: float, speed: float, catalog: Catalog) -> bool:
    """Whether actuator ``a`` gives ``torque`` (within its usable torque) at ``speed``."""
    return usable_torque(a, catalog) >= torque and speed_at(a, torque) >= speed


def speed_at(a: Actuator, torque: float) -> float:
    """Speed (rad/s) of a servo holding ``torque``: linear from no-load to stall."""
    return max(0.0, a.no_load_speed_rad_s * (1.0 - torque / a.stall_torque_Nm))


def _frame(direction: np.ndarray) -> np.ndarray:
    """Rotation whose x axis is ``direction`` (columns: tube axes in the body frame);
    read-only, remembered per direction (every load case asks it of every tube)."""
    return _frame_of(tuple(float(c) for c in direction))


@functools.lru_cache(maxsize=256)
def _frame_of(direction: tuple[float, ...]) -> np.ndarray:
    x = np.array(direction) / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    out = np.column_stack([x, y, np.cross(x, y)])
    out.setflags(write=False)
    return out


def free_end_load(seg: Segment, wrench: np.ndarray) -> np.ndarray:
    """The load at a tube's free end, in the tube frame (x along the tube), from the wrench
    its joint transmits into the body (body frame, moment about the body origin)."""
    f, m = wrench[:3], wrench[3:]
    end = seg.start + seg.length * seg.direction
    m_end = m - np.cross(end, f)
    R = _frame(seg.direction)
    return -np.concatenate([R.T @ f, R.T @ m_end])


def operating_points(torque: np.ndarray, speed: np.ndarray) -> list[tuple[float, float]]:
    """The (|torque| N m, |speed| rad/s) samples of a joint that can bind a servo whose
    speed falls linearly with torque: the upper hull of the samples (see ``upper_hull``)."""
    t, w = np.abs(np.asarray(torque, float)), np.abs(np.asarray(speed, float))
    return [(float(t[i]), float(w[i])) for i in hull_indices(t, w)]


def hull_indices(torque: np.ndarray, speed: np.ndarray) -> list[int]:
    """Indices of the samples (torque, speed >= 0) on their upper hull (``upper_hull``)."""
    if len(torque) == 0:  # no behaviour samples (a snake is sized by its hand cases only)
        return []
    order = np.lexsort((-speed, -torque))  # by torque, then speed, both descending
    best = np.maximum.accumulate(speed[order])
    keep = np.concatenate([[True], speed[order][1:] > best[:-1]])
    front = order[keep][::-1]  # the Pareto front: torque ascending, speed descending
    hull: list[int] = []
    for i in front.tolist():
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            cross = (torque[b] - torque[a]) * (speed[i] - speed[a]) - (speed[b] - speed[a]) * (
                torque[i] - torque[a]
            )
            if cross >= 0:
                hull.pop()  # b lies on or under the segment a -> i
            else:
                break
        hull.append(i)
    return hull


def upper_hull(points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """The points (torque, speed) that a servo line ``w <= w0 (1 - t / ts)`` can be bound
    by: the vertices of the points' convex hull facing larger torque and speed (any
    other point lies under a segment between two of them, or under and left of one, so
    meeting these meets all)."""
    pts = sorted({(float(t), float(w)) for t, w in points})
    if not pts:
        return []
    t = np.array([p[0] for p in pts])
    w = np.array([p[1] for p in pts])
    return [pts[i] for i in hull_indices(t, w)]


def free_end_loads(seg: Segment, wrenches: np.ndarray) -> np.ndarray:
    """``free_end_load`` of many samples: (B, 6) tube-frame loads from (B, 6) wrenches."""
    f, m = wrenches[:, :3], wrenches[:, 3:]
    m_end = m - np.cross(seg.start + seg.length * seg.direction, f)
    R = _frame(seg.direction)
    return -np.concatenate([f @ R, m_end @ R], axis=1)


def governing_loads(loads: np.ndarray, name: str, tmpl: Template) -> list[np.ndarray]:
    """Of the free-end loads (B, 6) of the tubes ``name`` over the behaviours' samples,
    those that govern them: the largest bending force, bending moment, compression, twist
    and equivalent tip force."""
    length = _segment_length(tmpl, name)
    f_perp = np.hypot(loads[:, 1], loads[:, 2])
    m_perp = np.hypot(loads[:, 4], loads[:, 5])
    measures = (f_perp, m_perp, -loads[:, 0], np.abs(loads[:, 3]), f_perp + 1.5 * m_perp / length)
    return [loads[i] for i in sorted({int(np.argmax(x)) for x in measures})]


def _equivalent_force(load: np.ndarray, length: float) -> float:
    """Tip force that bends a cantilever as much as this free-end force and moment."""
    f_perp = math.hypot(load[1], load[2])
    m_perp = math.hypot(load[4], load[5])
    return f_perp + 1.5 * m_perp / length


@dataclass
class _Requirements:
    torque: dict[str, float]
    case: dict[str, str]
    speed: dict[str, float]
    loads: dict[str, list[np.ndarray]]  # length name -> free-end loads (tube frame)
    holds: dict[str, tuple[float, float, str]]  # joint -> second point (N m, rad/s, what)
    # joint -> the (N m, rad/s) points its actuator must reach: the hand cases' torque at
    # the family's speed, and the behaviours' (upper hull of their samples)
    points: dict[str, list[tuple[float, float]]] = field(default_factory=dict)


def _plate_area(plan, lengths: Mapping[str, float]) -> float | None:
    """The face m^2 of the root part's plate that carries its modules, when its box is
    sized (the two sides of that face are expressions of the design's lengths: a trunk's
    La1 x La2, a torso's shoulder width x height); None for a box of fixed size (numbers,
    the actuator's size: an arm's base, a snake's head)."""

    kind = in_use().of(plan.root.kinds)
    if kind is None or len(kind.box) != 3:
        return None
    sides = kind.box[1:] if kind.faces == "back" else kind.box[:2]
    if not all(isinstance(x, str) and _names(x) and _names(x) <= set(lengths) for x in sides):
        return None
    return evaluate(sides[0], lengths) * evaluate(sides[1], lengths)


class StructureDesigner:
    """One robot type's co-design loop with its own actuator assigner (grounded once)."""

    def __init__(
        self,
        kb: KnowledgeBase,
        candidate: Candidate,
        catalog: Catalog,
        params: Mapping[str, float],
        symmetric: bool = True,
        objective: Sequence[str] = ("mass", "cost"),
    ) -> None:
        plan, structure = structure_of_type(kb, candidate.robot_type)
        if structure not in FAMILIES:
            raise InputError(
                f"{plan.root.where or candidate.robot_type}: {candidate.robot_type} has no "
                "sizing rules: its body plan is none of the structures parmor sizes "
                f"({', '.join(STRUCTURES)}: chains of joints and links on a fixed base, on "
                "wheels or on three or more legs; arm parts of role arm, such as "
                "HumanoidArm, only on a biped's torso); see README 'Extending parmor'"
            )
        register_plan(plan)
        self.plan, self.structure = plan, structure
        self.type = candidate.robot_type  # the template: the type's own body plan
        self.candidate, self.catalog, self.symmetric = candidate, catalog, symmetric
        self.family: Family = FAMILIES[structure]
        shares = [
            n / d
            for gait, n, d in kb.translation.relation("liftedModuleShare")
            if gait in candidate.abilities  # every gait it lists, asked for or not
            and isinstance(n, int)
            and isinstance(d, int)
            and d > 0
        ]
        self.lifted_share = max(shares, default=0.5)
        defaults = {
            "deflection": catalog.design.max_tip_deflection_m,
            "slope": catalog.design.max_slope_rad,
        }
        self.values, ignored = resolve(
            structure, params, defaults, ontology_defaults(kb, ancestors(kb, candidate.robot_type))
        )

        # the request's parameters and the kinds' lengths that nothing uses: said
        self.ignored = tuple(ignored) + unused_lengths(plan, in_use())
        self.modules = max(candidate.dof, 1)

        try:
            probe = build(self.type, TemplateParams(modules=self.modules))
        except AssemblyError as e:
            raise OntologyError(str(e)) from None
        self.slots = _slots(probe)
        # the conceptual design's FingerModules shared among the template's grippers
        fingers = dict(candidate.passive).get("FingerModule", 0)
        grippers = len(probe.end_effectors)
        self.fingers = max(1, fingers // grippers) if grippers and fingers else 2
        self.other_active = candidate.active_total - len(self.slots)
        if self.other_active < 0:
            raise InputError(
                f"{self.candidate.robot_type}: the template has {len(self.slots)} actuated joints "
                f"but the design only {candidate.active_total} active modules"
            )
        declared = dict(candidate.modules)
        for cls in sorted({s.module_class for s in self.slots}):
            joints = sum(s.module_class == cls for s in self.slots)
            if declared.get(cls, 0) != joints:
                raise InputError(
                    f"{candidate.robot_type}: the conceptual design has "
                    f"{declared.get(cls, 0)} {cls} but the {self.type} template {joints} "
                    "joints driven by one; the ontology and the template disagree"
                )
        self.objective = tuple(objective)
        self.assigner = ActuatorAssigner(
            kb,
            catalog_facts(catalog),
            candidate.robot_type,
            self.slots,
            self.other_active,
            objective,
        )
        for s in self.slots:
            if not self.assigner.serving.get(s.name):
                raise InputError(
                    f"{catalog.source}: no actuator of class {s.module_class} "
                    f"(or a class above it) for joint '{s.name}'"
                )
        self.by_model = {a.model: a for a in catalog.actuators}
        #: joint -> its serving models that can be its best choice (``dominated``): the
        #: design loop checks capability on these alone
        self.undominated = self._undominated()
        self.abilities = tuple(
            sorted((a.name if (a := kb.ability_of_kif(k)) else k) for k in candidate.abilities)
        )
        # which behaviours serve them (the record's ability_ancestors)
        self.ancestors = ability_ancestors(kb, self.abilities)
        #: the actuators (joint -> model) the behaviours are planned with (their speeds)
        self.actuator_sets: list[dict[str, str]] = []
        self.behaviour_notes: tuple[str, ...] = ()
        self.behaviours = True  # False: the hand cases alone (a fast bound)
        #: parameters the behaviours are planned with (None: the design's)
        self.plan_values: dict[str, float] | None = None
        #: joint -> torque N m it must be sized for at least (the verification loop's
        #: feedback: a joint that saturated in simulation needs more than its actuator gave)
        self.torque_floor: dict[str, float] = {}
        #: joint -> models it may not have (the verification loop's feedback: a servo whose
        #: play broke a behaviour under perturbation, and those with as much play)
        self.excluded: dict[str, frozenset[str]] = {}

    def _undominated(self) -> dict[str, tuple[str, ...]]:
        """Per joint, its serving models less those dominated among the models that serve
        every joint of its symmetry group (``synth.sizing.assign.dominated``)."""
        torque = {a.model: a.stall_torque_Nm for a in self.catalog.actuators}
        speed = {a.model: a.no_load_speed_rad_s for a in self.catalog.actuators}
        serving = self.assigner.serving
        done: dict[tuple, tuple[str, ...]] = {}
        out = {}
        for s in self.slots:
            mates = [t.name for t in self.slots if s.group and t.group == s.group] or [s.name]
            common = set.intersection(*(set(serving.get(m, ())) for m in mates))
            key = (serving.get(s.name, ()), tuple(sorted(common)))
            if key not in done:
                drop = dominated(key[0], torque, speed, self.assigner.weights, among=common)
                done[key] = tuple(m for m in key[0] if m not in drop)
            out[s.name] = done[key]
        return out

    # -- fixed modules ------------------------------------------------------------------
    def _fixed_modules(self) -> list[tuple[str, str, int, float, float, float]]:
        """(kind, model, count, mass, cost, current) of the active modules that are not
        joint actuators (main module, battery, sensors), from the conceptual design."""
        joint_classes = {s.module_class for s in self.slots}
        out = []
        for kind, n in self.candidate.modules:
            if kind in joint_classes:
                continue
            m = self.catalog.module_of(kind)
            out.append((kind, m.model, n, m.mass_kg, m.cost, m.current_A))
        return out

    def _trunk_mass(self, sizing: Sizing) -> float:
        fixed = sum(n * mass for _, _, n, mass, _, _ in self._fixed_modules())
        p = self.catalog.passive
        L = sizing.lengths
        area = _plate_area(self.plan, L)
        if area is None:
            area = p.dovetail_face_m**2
        return fixed + area * p.face_thickness_m * self.catalog.material.density_kg_m3

    # -- one analysis -------------------------------------------------------------------
    def _params(self, sizing: Sizing, tubes, act_mass, modules: int) -> TemplateParams:
        cat = self.catalog
        rho = cat.material.density_kg_m3
        p = cat.passive
        if "foot" in sizing.lengths:  # a sized foot plate (the humanoid's sole)
            side = sizing.lengths["foot"]
            foot = side * FOOT_WIDTH_RATIO * side * p.foot_thickness_m * rho
        else:  # a printed pad under a leg's tip
            foot = p.foot_min_side_m**2 * p.foot_thickness_m * rho
        wheel = cat.wheel_mass_kg(sizing.wheel_radius, WHEEL_BORE, sizing.wheel_width)
        # the catalog's jaw and ball caster (a catalog without them: the template's own)
        classes = {q.ontology_class for q in cat.parts}
        extra: dict = {"fingers": self.fingers}
        if "FingerModule" in classes:
            jaw = cat.part_of("FingerModule")
            extra |= {"gripper_mass": self.fingers * jaw.mass_kg, "finger_size": jaw.size_m}
        if "CasterModule" in classes:
            ball = cat.part_of("CasterModule")
            extra |= {"caster_mass": ball.mass_kg, "caster_radius": ball.size_m[0] / 2}
        if "BearingModule" in classes:  # the hub of a passive joint (a free wheel's)
            extra |= {"bearing_mass": cat.part_of("BearingModule").mass_kg}
        sizes = [a.size_m for a in cat.actuators]
        return TemplateParams(
            lengths=sizing.lengths,
            tubes=tubes,
            density=rho,
            actuator_mass=act_mass,
            actuator_size=tuple(max(s[i] for s in sizes) for i in range(3)),
            payload=self.values.get("payload", 0.0),
            trunk_mass=self._trunk_mass(sizing),
            modules=modules,
            wheel_radius=sizing.wheel_radius,
            wheel_width=sizing.wheel_width,
            foot_mass=foot,
            wheel_mass=wheel,
            **extra,
            face_side=p.dovetail_face_m,
            face_thickness=p.face_thickness_m,
            fillet=p.fillet_radius_m,
            dovetail_clearance=p.print_clearance_m,
        )

    def _geometry(self, tmpl: Template, sizing: Sizing, speeds: Mapping[str, float]):
        """The gaits' view of the design as its record will give it (``design.json``)."""
        return design_geometry(
            self.candidate.robot_type,
            self.type,
            tmpl.lengths,
            self.modules,
            sizing.wheel_radius if tmpl.wheels else None,
            self.plan_values or self.values,
            self.abilities,
            speeds,
            self.ancestors,
        )

    def _behaviour_cases(
        self, analysis: Template, sizing: Sizing, actuator_sets: Sequence[Mapping[str, str]]
    ) -> list[BehaviourCase]:
        """The behaviours' load cases, planned with each assignment (joint -> actuator
        model) of ``actuator_sets`` (its no-load speeds pace the trajectories)."""
        cases: list[BehaviourCase] = []
        notes: list[str] = []
        for models in actuator_sets:
            speeds = {j: self.by_model[a].no_load_speed_rad_s for j, a in models.items()}
            got, why = self.family.behaviour_cases(
                analysis, self._geometry(analysis, sizing, speeds)
            )
            cases += got
            notes += [n for n in why if n not in notes]
        self.behaviour_notes = tuple(notes)
        return cases

    def _requirements(
        self,
        tp: TemplateParams,
        sizing: Sizing,
        actuator_sets: Sequence[Mapping[str, str]] | None = None,
    ) -> tuple[_Requirements, Template]:
        """Torques, speeds, operating points and link loads of the hand load cases and of
        the behaviours planned with ``actuator_sets`` (default: those the last ``run``
        converged with; none before it)."""
        analysis = build(
            self.type,
            self.family.analysis_params(tp, self.lifted_share),
        )
        cases: list[LoadCase] = self.family.load_cases(analysis, self.values, self.catalog)
        if actuator_sets is None:
            actuator_sets = self.actuator_sets
        m = analysis.model
        torque: dict[str, float] = {}
        case_of: dict[str, str] = {}
        loads: dict[str, list[np.ndarray]] = {}
        for case in cases:
            tau = np.abs(rnea(m, case.q, case.v, case.a, case.fext))
            W = joint_wrenches(m, case.q, case.v, case.a, case.fext)
            for j in m.joints:
                k = m.q_index[m.joint(j.name)]
                if k >= 0 and tau[k] >= torque.get(j.name, -1.0):
                    torque[j.name], case_of[j.name] = float(tau[k]), case.name
            for seg in analysis.segments:
                load = free_end_load(seg, W[m.body(seg.body)])
                loads.setdefault(seg.length_name or seg.name, []).append(load)
        holds = self.family.holds(analysis, self.values, self.catalog)
        speeds = self.family.speeds(analysis, self.values, sizing)
        hand = dict(torque)
        behaviour_points: dict[str, list[tuple[float, float]]] = {}
        tube_loads: dict[str, list[np.ndarray]] = {}  # length name -> (B, 6) free-end loads
        # behaviour peaks count at the catalog's behaviour torque factor, not the hand cases'
        scale = self.catalog.design.behaviour_scale
        for bc in self._behaviour_cases(analysis, sizing, actuator_sets):
            tau_b, W = analyse(analysis, bc)
            tau_b = np.abs(tau_b) * scale
            for k, name in enumerate(m.q_names):
                i = int(np.argmax(tau_b[:, k]))
                if tau_b[i, k] > torque.get(name, -1.0):
                    torque[name], case_of[name] = float(tau_b[i, k]), bc.label(i)
                speeds[name] = max(speeds.get(name, 0.0), float(bc.peak_speed[k]))
                behaviour_points.setdefault(name, []).extend(
                    operating_points(tau_b[:, k], bc.v[:, k])
                )
            for seg in analysis.segments:
                name = seg.length_name or seg.name
                tube_loads.setdefault(name, []).append(free_end_loads(seg, W[:, m.body(seg.body)]))
        for name, got in tube_loads.items():  # the governing samples of every tube alike
            loads.setdefault(name, []).extend(governing_loads(np.concatenate(got), name, analysis))
        # joints beyond the analysed chain (a snake's) take their group's requirement
        group_torque: dict[str, float] = {}
        group_case: dict[str, str] = {}
        group_hand: dict[str, float] = {}
        group_points: dict[str, list[tuple[float, float]]] = {}
        for s in self.slots:
            if s.name in torque and torque[s.name] >= group_torque.get(s.group, -1.0):
                group_torque[s.group], group_case[s.group] = torque[s.name], case_of[s.name]
            if s.name in hand:
                group_hand[s.group] = max(group_hand.get(s.group, 0.0), hand[s.name])
            group_points.setdefault(s.group, []).extend(behaviour_points.get(s.name, []))
        group_speed = {s.group: speeds[s.name] for s in self.slots if s.name in speeds}
        for s in self.slots:
            if s.name not in torque:
                torque[s.name], case_of[s.name] = group_torque[s.group], group_case[s.group]
                hand[s.name] = group_hand[s.group]
                behaviour_points[s.name] = group_points.get(s.group, [])
            speeds.setdefault(s.name, group_speed[s.group])
        for s in self.slots:  # a joint beyond the analysed chain holds like its group
            if s.name not in holds:
                same = [holds[o.name] for o in self.slots if o.group == s.group and o.name in holds]
                if same:
                    holds[s.name] = max(same)
        for name, floor in sorted(self.torque_floor.items()):  # found in simulation
            if floor > torque.get(name, 0.0):
                torque[name], case_of[name] = floor, "simulation"
            hand[name] = max(hand.get(name, 0.0), floor)
        hand_speed = self.family.speeds(analysis, self.values, sizing)
        points = {
            s.name: upper_hull(
                [(hand[s.name], hand_speed.get(s.name, speeds[s.name]))]
                + behaviour_points.get(s.name, [])
            )
            for s in self.slots
        }
        return _Requirements(torque, case_of, speeds, loads, holds, points), analysis

    def capable(self, req: _Requirements, pruned: bool = False) -> dict[str, list[str]]:
        """Per joint, the serving models that meet its operating points: the hand cases'
        (their largest torque at the family's speed), the behaviours' (``req.points``) and
        its hold (torque at its speed). ``pruned``: among the models that are not
        dominated for it (``self.undominated``), enough to find the best assignment."""
        out = {}
        sf = self.catalog.design.torque_safety_factor
        for s in self.slots:
            points = list(req.points.get(s.name) or [(req.torque[s.name], req.speed[s.name])])
            if s.name in req.holds:
                points.append(req.holds[s.name][:2])
            names = (self.undominated if pruned else self.assigner.serving).get(s.name, ())
            if s.name in self.excluded:  # pruning was among the models excluded too
                names = [
                    n
                    for n in self.assigner.serving.get(s.name, ())
                    if n not in self.excluded[s.name]
                ]
            if not names:
                out[s.name] = []
                continue
            acts = [self.by_model[n] for n in names]
            stall = np.array([a.stall_torque_Nm for a in acts])
            w0 = np.array([a.no_load_speed_rad_s for a in acts])
            usable = stall / sf
            ok = np.ones(len(acts), bool)
            for t, w in points:  # ``meets``, elementwise (the same float operations)
                ok &= (usable >= t) & (np.maximum(0.0, w0 * (1.0 - t / stall)) >= w)
            out[s.name] = [n for n, k in zip(names, ok, strict=True) if k]
        return out

    def _link_inputs(
        self, length: float, loads: list[np.ndarray]
    ) -> tuple[list[np.ndarray], TubeLimits, float]:
        """A link's distinct loads, its tube limits and its Euler buckling floor on the
        stiffness ``(r2^4 - r1^4) / L^3`` (m)."""
        cat = self.catalog
        E = cat.material.youngs_modulus_Pa
        # alike segments of alike limbs carry the same loads: check each load once
        loads = list({tuple(np.round(ld, 12)): ld for ld in loads}.values())
        limits = TubeLimits(cat.passive.max_outer_radius_m, cat.passive.min_wall_m, length, length)
        # Euler buckling of a cantilever (effective length 2L) under the axial compression:
        # P sf <= pi^2 E I / (2L)^2, I = pi/4 (r2^4 - r1^4)  =>  a lower bound on K0
        squeeze = max(max(-ld[0], 0.0) for ld in loads)
        k_buckle = 16 * squeeze * cat.design.stress_safety_factor / (math.pi**3 * E * length)
        return loads, limits, k_buckle

    def _size_links(
        self,
        lengths: Mapping[str, float],
        loads: Mapping[str, list[np.ndarray]],
        counts: Mapping[str, int],
        analysis: Template,
    ) -> dict[str, tuple[Tube, dict]]:
        """Every printed link design (length name -> length m, free-end loads): the links
        of a serial chain of two or more of them (root to a foot, an end effector, or a
        leaf when there are neither) as one convex program (``synth.sizing.chain_links``): least
        printed volume (``counts`` copies of each) with the chain's allowance, the
        ``deflection`` parameter times its links, shared among them, each link within its
        stress and buckling floors; every other link on its own (``_size_link``)."""
        tips = {
            **dict(zip(analysis.feet, analysis.foot_points, strict=True)),
            **{b: np.zeros(3) for b in analysis.end_effectors},
        }
        chains = []
        for names, _ in serial_chains(analysis.model, analysis.segments, tips or None):
            distinct = tuple(dict.fromkeys(n for n in names if n in lengths))
            if len(distinct) >= 2:
                chains.append(distinct)
        joint = sorted({n for c in chains for n in c})
        out = {n: self._size_link(n, lengths[n], loads[n]) for n in lengths if n not in joint}
        if joint:
            out.update(self._size_chains(joint, chains, lengths, loads, counts))
        return out

    def _size_chains(
        self,
        names: Sequence[str],
        chains: Sequence[tuple[str, ...]],
        lengths: Mapping[str, float],
        loads: Mapping[str, list[np.ndarray]],
        counts: Mapping[str, int],
    ) -> dict[str, tuple[Tube, dict]]:
        """The links ``names`` of ``chains`` (link names, root to tip) sized together; a
        chain of N links may deflect N times the ``deflection`` parameter, each link's
        part its own tip deflection (no levers: the allowance per link of ``_size_link``,
        pooled)."""
        cat = self.catalog
        dmax = self.values["deflection"]
        allowed = max_allowed_stress(
            cat.material.yield_strength_Pa, cat.design.stress_safety_factor
        )
        links = []
        for n in names:
            own, limits, k_buckle = self._link_inputs(lengths[n], loads[n])
            links.append(ChainLink(n, limits, tuple(own), max(counts.get(n, 1), 1), k_buckle))
        budgets = [len(c) * dmax for c in chains]
        try:
            sized = chain_tubes(
                links,
                [Chain(c, b, (0.0,) * len(c)) for c, b in zip(chains, budgets, strict=True)],
                cat.material.youngs_modulus_Pa,
                allowed,
                cat.passive.stress_concentration,
            )
        except InfeasibleError as e:
            if getattr(e, "chain", None) is None:
                raise  # a link overstressed in its strongest tube: says so
            link = e.link
            raise InfeasibleError(
                f"chain '{' -> '.join(e.chain)}' cannot keep its tip deflection within "
                f"{e.required * 1000:.3g} mm ({len(e.chain)} links x {dmax * 1000:.3g} mm): "
                f"with the stiffest printable tubes (solid, r = "
                f"{cat.passive.max_outer_radius_m * 1000:.0f} mm) it deflects "
                f"{e.reachable * 1000:.3g} mm, link '{link}' ({lengths[link] * 1000:.0f} mm) "
                f"alone {e.link_reachable * 1000:.3g} mm; allow a larger deflection "
                "(--param deflection=...) or carry less"
            ) from None
        out = {}
        for n in names:
            allowance = min(b for c, b in zip(chains, budgets, strict=True) if n in c)
            info = {
                "deflection": sized.share_m[n],
                "max_deflection": allowance,
                "stress": sized.stress_Pa[n],
                "allowed": allowed,
                "governed": sized.governed[n],
            }
            out[n] = (sized.tubes[n], info)
        return out

    def _size_link(self, name: str, length: float, loads: list[np.ndarray]) -> tuple[Tube, dict]:
        cat = self.catalog
        E = cat.material.youngs_modulus_Pa
        dmax = self.values["deflection"]
        loads, limits, k_buckle = self._link_inputs(length, loads)
        allowed = max_allowed_stress(
            cat.material.yield_strength_Pa, cat.design.stress_safety_factor
        )
        force = max(_equivalent_force(ld, length) for ld in loads)
        k0 = stiffness_constant(force, E, dmax)
        k0 = max(k0, k_buckle)
        try:
            tube = optimal_tube(k0, limits, name)
        except InfeasibleError as e:
            best = dmax * e.required / e.reachable if e.reachable else float("inf")
            raise InfeasibleError(
                f"link '{name}' ({length * 1000:.0f} mm) cannot keep its tip deflection within "
                f"{dmax * 1000:.2f} mm under {force:.2f} N: the stiffest printable tube "
                f"(solid, r = {cat.passive.max_outer_radius_m * 1000:.0f} mm) deflects "
                f"{best * 1000:.2f} mm; allow a larger deflection (--param deflection=...) or "
                "carry less"
            ) from None

        def worst(t: Tube, among: list[int] | None = None):
            """The worst check of tube ``t`` over the loads (or those indexed), and its index."""
            idx = range(len(loads)) if among is None else among
            checks = [
                (beam_check(t, loads[i], E, cat.passive.stress_concentration), i) for i in idx
            ]
            return max(checks, key=lambda c: c[0].max_stress_Pa)

        check, first = worst(tube)
        governed = "deflection"
        if check.max_stress_Pa > allowed:
            governed = "stress"
            k_max = cat.passive.max_outer_radius_m**4 / length**3
            strongest = optimal_tube(k_max, limits, name)
            top, other = worst(strongest)
            if top.max_stress_Pa > allowed:
                raise InfeasibleError(
                    f"link '{name}' ({length * 1000:.0f} mm): the clamped-end stress "
                    f"{top.max_stress_Pa / 1e6:.1f} MPa of the strongest printable "
                    f"tube exceeds the allowed {allowed / 1e6:.1f} MPa (yield / safety factor); "
                    "carry less or use a stronger material"
                )
            # bisect on the loads that have governed so far; a load that the result does
            # not hold joins them and the search goes on above (the stress falls as the
            # tube stiffens, so the stiffness asked only grows)
            among = sorted({first, other})
            lo, hi = k0, k_max
            while True:
                for _ in range(STRESS_BISECTIONS):
                    mid = 0.5 * (lo + hi)
                    if worst(optimal_tube(mid, limits, name), among)[0].max_stress_Pa > allowed:
                        lo = mid
                    else:
                        hi = mid
                tube = optimal_tube(hi, limits, name)
                check, i = worst(tube)
                if check.max_stress_Pa <= allowed or i in among:
                    break
                among.append(i)
                lo, hi = hi, k_max
        info = {
            "deflection": max(beam_check(tube, ld, E).tip_deflection_m for ld in loads),
            "stress": check.max_stress_Pa,
            "allowed": allowed,
            "governed": governed,
        }
        return tube, info

    # -- the loop -----------------------------------------------------------------------
    def run(self) -> Structure:
        cat = self.catalog
        sizing = self.family.size(self.type, self.values, cat)
        p = cat.passive
        probe = build(self.type, self._params(sizing, {}, {}, self.modules))
        names = sorted({s.length_name or s.name for s in probe.segments})
        counts: dict[str, int] = {}  # length name -> printed copies (the volume's weight)
        for s in probe.segments:
            counts[s.length_name or s.name] = counts.get(s.length_name or s.name, 0) + 1
        tubes = {n: (p.max_outer_radius_m, p.max_outer_radius_m - p.min_wall_m) for n in names}
        act_mass = {
            s.group: min(self.by_model[m].mass_kg for m in self.assigner.serving[s.name])
            for s in self.slots
        }
        prev: np.ndarray | None = None
        iterations = 0
        # the behaviours are planned with the chosen actuators: none on the first pass (no
        # actuator yet), then those of the last assignment; an assignment seen before (the
        # choice cycles) keeps every one since in the analysis (a superset of the loads:
        # the requirements then only grow, so the loop settles)
        actuator_sets: list[dict[str, str]] = []
        seen: list[dict[str, str]] = []
        cycling = False
        for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (used after the loop)
            sizing = self.family.update(
                sizing,
                build(self.type, self._params(sizing, tubes, act_mass, self.modules)),
                self.values,
                cat,
            )
            tp = self._params(sizing, tubes, act_mass, self.modules)
            req, analysis = self._requirements(tp, sizing, actuator_sets)
            assignment = self.assigner.best(self.capable(req, pruned=True), self.symmetric)
            if assignment is None:
                raise self._no_actuator(req)
            new_mass: dict[str, float] = {}
            for joint, model in assignment.models:
                g = next(s.group for s in self.slots if s.name == joint)
                new_mass[g] = max(new_mass.get(g, 0.0), self.by_model[model].mass_kg)
            sized = self._size_links(
                {
                    n: sizing.lengths.get(n, analysis.lengths.get(n, 0.0))
                    or _segment_length(analysis, n)
                    for n in names
                    if n in req.loads
                },
                req.loads,
                counts,
                analysis,
            )
            tubes = {n: (t.r_outer, t.r_inner) for n, (t, _) in sized.items()}
            act_mass = new_mass
            vector = np.array(
                [
                    *(act_mass[g] for g in sorted(act_mass)),
                    *(sized[n][0].volume for n in sorted(sized)),
                ]
            )
            chosen = dict(sorted(assignment.models))
            planned = chosen in actuator_sets or not self.behaviours
            if (
                planned
                and prev is not None
                and np.all(np.abs(vector - prev) <= CONVERGENCE * np.abs(prev))
            ):
                break
            prev = vector
            if not planned:
                cycling = cycling or chosen in seen
                actuator_sets = [*actuator_sets, chosen] if cycling else [chosen]
                seen.append(chosen)
        else:
            raise InfeasibleError(
                f"{self.candidate.robot_type}: the masses did not converge "
                f"in {MAX_ITERATIONS} iterations"
            )
        final = build(self.type, self._params(sizing, tubes, act_mass, self.modules))
        self.requirements = req  # the converged requirements, for enumerating alternatives
        self.converged = (sizing, tubes, act_mass)
        self.analysis = analysis
        self.actuator_sets = actuator_sets
        return self._record(final, sizing, req, assignment, sized, iterations)

    def _part_volume(self, t: Tube) -> float:
        p = self.catalog.passive
        return link_part_volume(
            t.length, t.r_outer, t.r_inner, p.dovetail_face_m, p.face_thickness_m, p.fillet_radius_m
        )

    def _no_actuator(self, req: _Requirements) -> InfeasibleError:
        """Why no assignment exists: the joint whose requirement no model meets (torque
        first, then speed under that torque), else a symmetry group with no common model."""
        capable = self.capable(req)
        sf = self.catalog.design.torque_safety_factor
        for s in sorted(self.slots, key=lambda s: -req.torque[s.name]):
            if capable[s.name]:
                continue
            models = [self.by_model[m] for m in self.assigner.serving[s.name]]
            t = req.torque[s.name]
            strong = [a for a in models if usable_torque(a, self.catalog) >= t]
            if not strong:
                best = max(models, key=lambda a: a.stall_torque_Nm)
                what = (
                    f"joint '{s.name}' needs {t:.2f} N m ({req.case[s.name]}) but the "
                    f"strongest actuator ({best.model}) gives "
                    f"{usable_torque(best, self.catalog):.2f} N m after the torque safety "
                    f"factor {sf}"
                )
            else:
                points = req.points.get(s.name) or [(t, req.speed[s.name])]
                # the operating point that the fastest strong actuator misses by most
                fast = max(strong, key=lambda a: min(speed_at(a, pt) - pw for pt, pw in points))
                pt, pw = min(points, key=lambda p: speed_at(fast, p[0]) - p[1])
                what = (
                    f"joint '{s.name}' needs {pw:.2f} rad/s at {pt:.2f} N m but the "
                    f"fastest actuator strong enough ({fast.model}) turns at "
                    f"{speed_at(fast, pt):.2f} rad/s under that torque"
                )
            return InfeasibleError(f"{self.candidate.robot_type}: {what}")
        groups = sorted({s.group for s in self.slots if s.group})
        for g in groups:
            common = set.intersection(*(set(capable[s.name]) for s in self.slots if s.group == g))
            if not common:
                return InfeasibleError(
                    f"{self.candidate.robot_type}: the alike joints of group '{g}' have no "
                    "actuator model in common; --no-symmetry lets them differ"
                )
        return InfeasibleError(f"{self.candidate.robot_type}: no actuator assignment")

    def _record(
        self,
        tmpl: Template,
        sizing: Sizing,
        req: _Requirements,
        assignment: Assignment,
        sized: dict,
        iterations: int,
    ) -> Structure:
        cat = self.catalog
        rho = cat.material.density_kg_m3
        counts: dict[str, int] = {}
        for s in tmpl.segments:
            n = s.length_name or s.name
            counts[n] = counts.get(n, 0) + 1
        links = tuple(
            LinkDesign(
                n,
                counts.get(n, 0),
                t.length,
                t.r_outer,
                t.r_inner,
                t.volume,
                self._part_volume(t),
                self._part_volume(t) * rho,
                info["deflection"],
                info.get("max_deflection", self.values["deflection"]),
                info["stress"],
                info["allowed"],
                t.active,
                info["governed"],
            )
            for n, (t, info) in sorted(sized.items())
        )
        modules, cost, peak, stall, address = self._modules(assignment, req)
        joints = tuple(
            JointDesign(
                s.name,
                s.group,
                s.module_class,
                assignment.model_of(s.name),
                req.torque[s.name],
                self.by_model[assignment.model_of(s.name)].stall_torque_Nm,
                usable_torque(self.by_model[assignment.model_of(s.name)], cat),
                req.speed[s.name],
                req.case[s.name],
                address[s.name],
                self.by_model[assignment.model_of(s.name)].no_load_speed_rad_s,
                *req.holds.get(s.name, (0.0, 0.0, "")),
                tuple(req.points.get(s.name, ())),
            )
            for s in self.slots
        )
        battery = cat.battery.max_current_A or 0.0
        power = Power(peak, stall, battery, peak <= battery)
        # every printed module of the conceptual design (links, feet, wheels, plates...)
        n_passive = sum(n for _, n in self.candidate.passive)
        kinds = {m.model for m in modules} | {k for k, _ in self.candidate.passive}
        n_modules = sum(m.count for m in modules) + n_passive
        metrics = Metrics(
            n_modules, round(n_modules / max(len(kinds), 1), 6), self.candidate.hierarchy
        )
        lengths = dict(sorted(tmpl.lengths.items()))
        return Structure(
            self.candidate.robot_type,
            dict(sorted(self.values.items())),
            self.ignored,
            lengths,
            sizing.wheel_radius if tmpl.wheels else None,
            links,
            joints,
            modules,
            float(tmpl.model.total_mass),
            round(cost, 2),
            power,
            metrics,
            iterations,
            tmpl,
            (*sizing.notes, *self.behaviour_notes),
            self.catalog.bus,
        )

    def _modules(
        self, assignment: Assignment, req: _Requirements
    ) -> tuple[tuple[ModuleUse, ...], float, float, float, dict[str, int]]:
        cat = self.catalog
        address = cat.bus.first_address
        out: list[ModuleUse] = []
        cost = peak = stall = 0.0
        for kind, model, n, _, c, current in sorted(
            self._fixed_modules(), key=lambda x: (x[0] != "MainModule", x[0])
        ):
            if kind == "MainModule":
                addrs: tuple[int, ...] = ()
            else:
                addrs = tuple(range(address, address + n))
                address += n
            out.append(ModuleUse(kind, model, n, addrs))
            cost += n * c
            peak += n * current
            stall += n * current
        per_model: dict[tuple[str, str], list[int]] = {}
        by_joint: dict[str, int] = {}
        for s in self.slots:
            a = self.by_model[assignment.model_of(s.name)]
            per_model.setdefault((s.module_class, a.model), []).append(address)
            by_joint[s.name] = address
            address += 1
            cost += a.cost
            torque = max(req.torque[s.name], req.holds.get(s.name, (0.0,))[0])
            peak += a.stall_current_A * min(1.0, torque / a.stall_torque_Nm)
            stall += a.stall_current_A
        out += [
            ModuleUse(k, m, len(addrs), tuple(addrs)) for (k, m), addrs in sorted(per_model.items())
        ]
        if address - 1 > cat.bus.last_address:
            raise InfeasibleError(
                f"{self.candidate.robot_type}: more {cat.bus.name} devices than the bus's "
                f"{cat.bus.address_word}s ({cat.bus.address_text(cat.bus.first_address)}-"
                f"{cat.bus.address_text(cat.bus.last_address)})"
            )
        return tuple(out), cost, peak, stall, by_joint


def _segment_length(tmpl: Template, name: str) -> float:
    return next(s.length for s in tmpl.segments if (s.length_name or s.name) == name)


def design_structure(
    kb: KnowledgeBase,
    candidate: Candidate,
    catalog: Catalog,
    params: Mapping[str, float],
    symmetric: bool = True,
    objective: Sequence[str] = ("mass", "cost"),
) -> Structure:
    """Size ``candidate`` (a conceptual design) for ``params`` (SI) with ``catalog``."""
    designer = StructureDesigner(kb, candidate, catalog, params, symmetric, objective)
    try:
        return designer.run()
    except InfeasibleError as e:
        for name, (*_, floor, always) in EASIER_WHEN_SMALLER.items():
            if not (always or name in params):  # the others only where the user asked
                continue
            best = largest_value(designer, name, floor)
            if best is not None:
                raise InfeasibleError(
                    f"{e}; the largest {name} that works here is {shown_value(name, best)}"
                ) from None
        raise


#: Parameters a design is easier to build with less of, tried in this order when a request
#: is infeasible: name -> (unit shown, factor from SI, decimals shown, the smallest value
#: tried as a share of the asked one, whether tried when the user did not ask for it).
EASIER_WHEN_SMALLER = {
    "payload": ("kg", 1.0, 3, 0.0, True),
    "speed": ("m/s", 1.0, 2, 0.01, False),
    "slope": ("deg", 180 / math.pi, 1, 0.0, False),
}

#: Bisection steps of ``largest_value`` with the behaviours analysed (after those with the
#: hand cases alone, which bound it from above).
BEHAVIOUR_BISECTIONS = 6


def bisect_largest(
    ok: Callable[[float], bool],
    lo: float,
    hi: float,
    steps: int,
    snap: Callable[[float], float] | None = None,
) -> float:
    """The largest x found in [lo, hi] with ``ok(x)`` by ``steps`` bisections (``ok`` is
    taken to hold at ``lo`` and to fail above its limit once it fails): ``lo`` when every
    test failed. ``snap`` moves each midpoint onto a grid (e.g. :func:`rounded_down`), so
    that the value returned is one that was tested (or ``lo``); the bisection stops when the
    grid has no point left between the bounds. One bisection for every refusal hint: the
    sizing's (:func:`largest_value`) and the simulation's (``synth.verification.loop``)."""
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if snap is not None:
            mid = snap(mid)
            if not lo < mid < hi:
                break
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def rounded_down(name: str, value: float) -> float:
    """``value`` (SI) of the ``EASIER_WHEN_SMALLER`` parameter ``name`` rounded down to the
    decimals a refusal shows (SI again): a smaller value, easier to build."""
    _, scale, digits, _, _ = EASIER_WHEN_SMALLER[name]
    step = 10.0**-digits
    return math.floor(value * scale / step) * step / scale


def shown_value(name: str, value: float) -> str:
    """``value`` (SI) of the ``EASIER_WHEN_SMALLER`` parameter ``name`` as a refusal names
    it, rounded down to its decimals (it must still work): ``"1.400 kg"``."""
    unit, scale, digits, _, _ = EASIER_WHEN_SMALLER[name]
    step = 10.0**-digits
    return f"{math.floor(value * scale / step) * step:.{digits}f} {unit}"


def largest_value(
    designer: StructureDesigner, name: str, floor: float = 0.0, steps: int = 24
) -> float | None:
    """The largest value of parameter ``name`` (SI, at most the asked one) with which
    ``designer``'s design succeeds, all else equal (bisection down to ``floor`` x the asked
    value), or None when it fails even there (``name`` is not the limit).

    The hand cases alone bound it from above (``steps`` bisections, fast); below that bound
    ``BEHAVIOUR_BISECTIONS`` more with the behaviours analysed, their trajectories planned
    with the parameters at the bound (planning once per actuator choice keeps the search
    fast; a smaller payload, speed or slope asks less of the same plan)."""
    asked = designer.values.get(name)
    if not asked or asked <= 0:
        return None
    values = designer.values
    low = lowest(name, floor * asked)
    if low > asked:
        return None

    def ok(x: float, behaviours: bool) -> bool:
        designer.values = {**values, name: x}
        designer.behaviours = behaviours
        try:
            designer.run()
            return True
        except InfeasibleError:
            return False

    try:
        if not ok(low, False):
            return None
        bound = bisect_largest(lambda x: ok(x, False), low, asked, steps)
        designer.plan_values = {**values, name: bound}
        if ok(bound, True):
            return bound
        best = bisect_largest(lambda x: ok(x, True), low, bound, BEHAVIOUR_BISECTIONS)
        return best if best > low or ok(low, True) else None
    finally:
        designer.values = values
        designer.behaviours = True
        designer.plan_values = None


@dataclass(frozen=True)
class Alternative:
    """One feasible actuator assignment and the module totals it gives (kg, currency)."""

    models: tuple[tuple[str, str], ...]
    mass_kg: float
    cost: float


@dataclass(frozen=True)
class Alternatives:
    """The feasible assignments of a sized design (at its converged requirements)."""

    count: int
    symmetric: bool
    ranked: tuple[Alternative, ...]
    pareto: tuple[Alternative, ...] | None
    exact: bool = True  # False: count is an upper bound (too many to check one by one)
    lower: int | None = None  # with exact False: a lower bound (else the count)
    #: the assignments that meet the sized design's requirements joint by joint (what
    #: ``asp/actuators.lp`` admits): always exact, and at least ``count``
    capable: int | None = None


ENUMERATE_LIMIT = 200_000
MASS_STEP = 0.01  # kg: finite step of the torque sensitivities (the torques are linear in it)


class _TorqueModel:
    """Joint torques as a function of the actuator masses, around a converged design.

    RNEA torques are linear in the bodies' masses for fixed motion and loads, and so is the
    ground's support force in the total mass: per load case, tau(m) = tau0 + sum over
    actuator groups of (m_g - m0_g) s_g, with s_g from one finite step. The cases are those
    of the converged masses, held (``Family.load_cases_like``: a humanoid's gait instants
    are each joint's peak there, not re-picked as the masses move, which would pair
    different instants in the step). (The share of the weight each foot carries moves
    with the centre of mass; that small effect is not modelled.) A joint's requirement is
    the largest |tau| over the cases; its hold (a gripper's squeeze, a skid-steer's turn)
    is taken from the converged design."""

    def __init__(self, designer: StructureDesigner) -> None:
        self.d = designer
        sizing, tubes, act_mass = designer.converged
        self.base = dict(act_mass)
        self.cases: list[LoadCase] | None = None  # the converged masses' (``_raw``)
        self.names, self.t0, self.b0, self.w = self._raw(sizing, tubes, self.base)
        self.sens, self.bsens = {}, {}
        for g, m in sorted(self.base.items()):
            _, t, b, _ = self._raw(sizing, tubes, {**self.base, g: m + MASS_STEP})
            self.sens[g] = (t - self.t0) / MASS_STEP
            self.bsens[g] = (b - self.b0) / MASS_STEP
        # per joint, the behaviour samples that bind at the converged masses
        self.rows = [
            hull_indices(np.abs(self.b0[:, k]), self.w[:, k]) for k in range(len(self.names))
        ]

    def _raw(self, sizing, tubes, act_mass):
        """Joint names; torques (hand cases, nv) and (behaviour samples, nv); the
        behaviour samples' |speeds| (rad/s)."""
        d = self.d
        tp = d._params(sizing, tubes, act_mass, d.modules)
        analysis = build(d.type, d.family.analysis_params(tp, d.lifted_share))
        m = analysis.model
        if self.cases is None:
            cases = self.cases = d.family.load_cases(analysis, d.values, d.catalog)
        else:
            cases = d.family.load_cases_like(analysis, d.values, d.catalog, self.cases)
        t = np.array([rnea(m, c.q, c.v, c.a, c.fext) for c in cases]).reshape(-1, m.nv)
        b = [np.zeros((0, m.nv))]
        w = [np.zeros((0, m.nv))]
        for bc in d._behaviour_cases(analysis, sizing, d.actuator_sets):
            b.append(analyse(analysis, bc)[0] * d.catalog.design.behaviour_scale)
            w.append(np.abs(bc.v))
        names = [j.name for j in m.joints if m.q_index[m.joint(j.name)] >= 0]
        return names, t, np.concatenate(b), np.concatenate(w)

    def _group_masses(self, models: Mapping[str, str]) -> dict[str, float]:
        group_mass: dict[str, float] = {}
        for s in self.d.slots:
            mass = self.d.by_model[models[s.name]].mass_kg
            group_mass[s.group] = max(group_mass.get(s.group, 0.0), mass)
        return group_mass

    def _by_joint(
        self, points: Mapping[str, list[tuple[float, float]]]
    ) -> dict[str, list[tuple[float, float]]]:
        """Per slot: its own points, or (beyond the analysed chain) its group's."""
        group: dict[str, list[tuple[float, float]]] = {}
        for s in self.d.slots:
            group.setdefault(s.group, []).extend(points.get(s.name, []))
        return {s.name: points.get(s.name, group.get(s.group, [])) for s in self.d.slots}

    def torques(self, models: Mapping[str, str]) -> dict[str, float]:
        """Required torque per joint (N m) with these actuator models."""
        t, b = self._tau(models)
        need = np.abs(np.concatenate([t, b])).max(axis=0)
        out = {n: float(need[k]) for k, n in enumerate(self.names)}
        by_group: dict[str, float] = {}
        for s in self.d.slots:
            if s.name in out:
                by_group[s.group] = max(by_group.get(s.group, 0.0), out[s.name])
        return {s.name: out.get(s.name, by_group.get(s.group, 0.0)) for s in self.d.slots}

    def _tau(self, models: Mapping[str, str]) -> tuple[np.ndarray, np.ndarray]:
        t, b = self.t0.copy(), self.b0.copy()
        for g, mass in self._group_masses(models).items():
            t += (mass - self.base[g]) * self.sens[g]
            b += (mass - self.base[g]) * self.bsens[g]
        return t, b

    def feasible(self, models: Mapping[str, str]) -> bool:
        d = self.d
        t, b = self._tau(models)
        hand_speed = d.family.speeds(d.analysis, d.values, d.converged[0])
        points: dict[str, list[tuple[float, float]]] = {}
        for k, n in enumerate(self.names):
            hand = float(np.abs(t[:, k]).max()) if len(t) else 0.0
            pts = [(hand * (1 - 1e-12), hand_speed.get(n, d.requirements.speed[n]))]
            pts += [(abs(float(b[i, k])) * (1 - 1e-12), float(self.w[i, k])) for i in self.rows[k]]
            points[n] = pts
        per_joint = self._by_joint(points)
        for s in d.slots:
            a = d.by_model[models[s.name]]
            pts = list(per_joint[s.name])
            if s.name in d.requirements.holds:
                pts.append(d.requirements.holds[s.name][:2])
            if not all(meets(a, tt, w, d.catalog) for tt, w in pts):
                return False
        return True

    def coupled(self, units: Sequence[tuple[Sequence[int], Sequence[str]]]) -> Coupled:
        """The feasibility test of ``feasible`` over every assignment of ``units`` (per
        unit: its slots' indices and its candidate models), as arrays (``Coupled``)."""
        d = self.d
        groups = list(dict.fromkeys(s.group for s in d.slots))  # ``_tau``'s order
        gi = {g: i for i, g in enumerate(groups)}
        hand_speed = d.family.speeds(d.analysis, d.values, d.converged[0])
        scale = 1 - 1e-12
        lin: dict[str, list[tuple[float, list[float], float, float]]] = {}
        fixed: dict[str, list[tuple[float, float]]] = {}
        for k, n in enumerate(self.names):
            hs = hand_speed.get(n, d.requirements.speed[n])
            rows = [
                (float(self.t0[c, k]), [float(self.sens[g][c, k]) for g in groups], scale, hs)
                for c in range(len(self.t0))
            ]
            fixed[n] = [] if len(self.t0) else [(0.0, hs)]
            rows += [
                (
                    float(self.b0[i, k]),
                    [float(self.bsens[g][i, k]) for g in groups],
                    scale,
                    float(self.w[i, k]),
                )
                for i in self.rows[k]
            ]
            lin[n] = rows
        lin_of = self._by_joint(lin)  # type: ignore[arg-type]
        fixed_of = self._by_joint(fixed)
        models = sorted({m for _, ms in units for m in ms})
        index = {m: i for i, m in enumerate(models)}
        acts = [d.by_model[m] for m in models]
        sf = d.catalog.design.torque_safety_factor
        stall = np.array([a.stall_torque_Nm for a in acts])
        points = []
        for slots, _ in units:
            rows = [r for i in slots for r in lin_of[d.slots[i].name]]
            held = [p for i in slots for p in fixed_of[d.slots[i].name]]
            held += [
                d.requirements.holds[d.slots[i].name][:2]
                for i in slots
                if d.slots[i].name in d.requirements.holds
            ]
            points.append(
                distinct_points(
                    Points(
                        np.array([r[0] for r in rows]),
                        np.array([r[1] for r in rows]).reshape(len(rows), len(groups)),
                        np.array([r[2] for r in rows]),
                        np.array([r[3] for r in rows]),
                        np.array([h[0] for h in held], float),
                        np.array([h[1] for h in held], float),
                    )
                )
            )
        return Coupled(
            group=tuple(gi[d.slots[slots[0]].group] for slots, _ in units),
            base=np.array([self.base[g] for g in groups]),
            options=tuple(np.array([index[m] for m in ms], int) for _, ms in units),
            mass=np.array([a.mass_kg for a in acts]),
            stall=stall,
            usable=stall / sf,
            w0=np.array([a.no_load_speed_rad_s for a in acts]),
            points=tuple(points),
        )


def alternatives(designer: StructureDesigner, k: int, pareto: bool = False) -> Alternatives:
    """The ``k`` best feasible assignments (and the mass/cost Pareto front) of a design that
    ``designer.run()`` has converged.

    Candidates are the assignments capable at the converged design's torques (the
    lightest actuators: any other assignment only adds mass); an assignment is feasible
    when it stays capable with its own actuator masses (``_TorqueModel``). The count is
    exact (``synth.sizing.assign.count_bounds``, or every candidate checked when there are at
    most ENUMERATE_LIMIT) unless its branch and bound gives up on more: then ``count`` is
    an upper bound and ``lower`` a lower one, from the boxes it left (``exact`` False); the
    best come lazily, candidates in objective order each checked until ``k`` (or all)
    feasible ones are found."""
    req = designer.requirements
    capable = designer.capable(req)
    fixed_mass = sum(n * m for _, _, n, m, _, _ in designer._fixed_modules())
    fixed_cost = sum(n * c for _, _, n, _, c, _ in designer._fixed_modules())
    model = _TorqueModel(designer)
    by_model = designer.by_model

    def alt(a: Assignment) -> Alternative:
        acts = [by_model[m] for _, m in a.models]
        return Alternative(
            a.models,
            round(fixed_mass + sum(x.mass_kg for x in acts), 9),
            round(fixed_cost + sum(x.cost for x in acts), 6),
        )

    key = {"mass": lambda x: x.mass_kg, "cost": lambda x: x.cost}
    order = [key[name] for name in designer.objective]

    def rank(x: Alternative) -> tuple:
        return (*(f(x) for f in order), x.models)

    units = designer.assigner.options(capable, designer.symmetric)
    upper = designer.assigner.count_options(units)
    field = {"mass": lambda m: by_model[m].mass_kg, "cost": lambda m: by_model[m].cost}
    lists = [
        sorted(ms, key=lambda m: (*(field[n](m) for n in designer.objective), m)) for _, ms in units
    ]
    problem = model.coupled([(u, ms) for (u, _), ms in zip(units, lists, strict=True)])
    low, high = count_bounds(problem) if units else (0, 0)
    if low != high and upper <= ENUMERATE_LIMIT:  # small enough to check each
        low = high = count_by_enumeration(problem)
    exact = low == high
    count = high

    def make(idx: tuple[int, ...]) -> Assignment:
        chosen = [ms[i] for ms, i in zip(lists, idx, strict=True)]
        return designer.assigner._assignment([u for u, _ in units], chosen)

    ranked: list[Alternative] = []
    found = best_first([len(ms) for ms in lists], lambda i: rank(alt(make(i))))
    for tried, idx in enumerate(found):
        if len(ranked) >= k or len(ranked) >= count or tried >= ENUMERATE_LIMIT:
            break
        a = make(idx)
        if model.feasible(dict(a.models)):
            ranked.append(alt(a))
    front = None
    if pareto:
        if upper > ENUMERATE_LIMIT:
            raise InputError(
                f"{designer.candidate.robot_type}: {upper} assignments are too many for "
                f"--pareto (at most {ENUMERATE_LIMIT}); keep alike joints alike "
                "(drop --no-symmetry)"
            )
        every = []
        if units:
            choice = product_rows(problem.options)
            names = sorted({m for ms in lists for m in ms})
            ok = feasible_mask(problem, choice)
            every = sorted(
                (
                    alt(
                        designer.assigner._assignment(
                            [u for u, _ in units], [names[i] for i in row]
                        )
                    )
                    for row in choice[ok].tolist()
                ),
                key=rank,
            )
        front_list: list[Alternative] = []
        best_cost = float("inf")
        for x in sorted(every, key=lambda x: (x.mass_kg, x.cost, x.models)):
            if x.cost < best_cost:  # by mass, then cost: on the front if it is cheaper
                front_list.append(x)
                best_cost = x.cost
        front = tuple(front_list)
    return Alternatives(count, designer.symmetric, tuple(ranked), front, exact, low, upper)
