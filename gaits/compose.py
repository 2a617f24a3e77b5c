"""Compositions: a design whose body plan holds a locomotion base and an arm (a mobile
manipulator) offers the behaviours of both, and a ``pick-and-place`` that drives to the
object, picks it, drives on and places it.

Any number of chains (arms, heads: chains of joints and links, whatever ends them) on any
base compose so (issue 31, item 4): on wheels (``mobile_manipulator``), on a multiped's
legs (``legged_manipulator``: the legs' behaviours with the chains held, a chain's with
the legs standing as the design starts, at zero) or on a stationary base (``multi_arm``).
With several chains each is planned by a view of this controller focused on it (the
others held in their ready poses, in its tipping checks too), and its behaviours carry
its name: ``left-grasping``, ``right-pick-and-place`` (the assembler's place: l, r of a
pair or of two chains side by side across a serial mount; ``ARM_NAMES``); the base's
behaviours (``driving``, ``walking`` ...) hold every chain. A single chain's behaviours
keep their names. A chain on a root part the root carries (arms on a torso on a chassis)
is split off the carried part as it is off the root.

The body plan is split into its sub-structures (:func:`split`): the root's children whose
subtree is a serial chain ending in an end effector (roles ``joint``/``link``/
``end_effector`` of the part kinds) make the arm, the rest the base. The arm becomes a body
plan of its own, rooted at the part kind that the part kinds give for a stationary base
of such a chain (a ``root`` kind mounting the chain's first part with the same layout,
its links named ``L1``, ``L2`` ...), so that the arm's lengths are those a stationary arm
of the same chain has. Each sub-structure gets the controller of its structure
(``gaits.CONTROLLERS`` by ``kinematics.assemble.structure_of``; no type is named):

- the base's on the whole design (it carries the whole robot: its load model weighs the
  arm and the payload); its behaviours drive the wheels while the arm holds its ready
  pose (``home``, the servos' droop compensated as in the arm's own trajectories);
- the arm's on the arm's plan, its base frame where the arm's first joint stands on the
  base at the start (world frame: the base's spawn position plus the mount's offset); its
  behaviours move the arm joints while the wheels stand still.

``pick-and-place`` (parameters and ``info["target"]`` in the world frame: the floor is
z = 0, the robot starts at the origin facing +x) plans legs one after another: the base
drives straight along its heading (a minimum-jerk distance profile through the drive's
load model, :meth:`ComposedController._drive`) until the object is ``STANDOFFS`` of the
arm's reach from the arm's first joint, the arm's yaw reaching aside; only an object
farther aside than that makes the base turn in place to face it first (``turning``). The
arm grasps it (``grasping``), goes back to its ready pose with the gripper closed (the
reverse of ``positioning``), the base drives to the place target likewise, and the arm
puts the object down: ``positioning`` above it, then the reverse of ``grasping`` (down
onto the target, open, up and back). A target the arm reaches from where the base stands
needs no drive. The arm accelerates gently (``ARM_ACCELERATION``): the wheels only hold
their speed, and a quick arm's reaction turns the base under it. ``info["placed_at_s"]``
is when the gripper has opened on the target: :mod:`synth.verification.verdict` measures the
gripper's distance from the world target there, on the outcome, so a base that slipped or
drove short fails ``placing``.

Calibration: the drive's load model leaves out the caster's and the tyres' rolling
resistance, so an open-loop drive falls short (5-6 % at the default speed); the design
measures how far its base travels and turns on probe runs (``travel`` over two distances,
``turning`` by six angles, :meth:`ComposedController.calibrate`, kept in the record's
``calibration``), and ``travel``, ``turning`` and ``pick-and-place`` command what reaches
the asked distance and heading; a pick-and-place also allows for where a turn in place
moves the wheels' middle (a few millimetres: the caster drags it).

Tipping: every arm configuration a behaviour plans is checked with the whole robot's
centre of mass (the template's masses scaled to the design's, the payload in the gripper)
against the support polygon of the wheels' and casters' contacts
(:meth:`ComposedController.tip_margin`); a plan that brings it within ``TIP_MARGIN`` of an
edge (0: over it, the static tipping limit) is refused, naming the pose and the figure. The
estimate lies within 4 mm of MuJoCo's centre of mass on the designs measured (on the
safe side); the simulation decides the rest (``fell``).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from functools import cached_property

import numpy as np

from gaits import CONTROLLERS, controller_for
from gaits.base import (
    BehaviorSpec,
    Controller,
    DesignGeometry,
    Parameter,
    Trajectory,
    min_jerk,
    quat_yaw,
)
from kinematics.assemble import structure_of
from kinematics.bodyplan import BodyPlan, PartNode
from kinematics.dynamics import forward_kinematics
from kinematics.partkinds import in_use
from kinematics.templates import TemplateParams, build, plan_of, register_plan

__all__ = ["ComposedController", "split"]

#: Trajectory sample period, s (the base's and the arm's own).
SAMPLE_DT = 0.01
#: Roles of the part kinds that make a serial arm (a chain ending in an end effector).
ARM_ROLES = frozenset({"joint", "link", "end_effector"})
#: The name an arm's behaviours carry on a design with several, by the prefix of where it
#: stands (``kinematics.assemble``: l, r of a pair or of two chains side by side; l, m, r
#: of three); other prefixes (c1, c2 ...) as they are.
ARM_NAMES = {"l": "left", "r": "right", "m": "middle"}
#: Fraction of the base's top speed that a pick-and-place drive peaks at: slow enough for
#: the drive's load model to be accurate (the arm places within millimetres of where the
#: base was planned to stand).
DRIVE_SPEED_FRACTION = 0.25
#: Where the base stops: the object this fraction of the arm's reach ahead of the arm's
#: first joint (then the nearer and farther ones tried in turn, ``STANDOFFS``).
STANDOFF = 0.6
STANDOFFS = (0.6, 0.5, 0.7, 0.4, 0.8, 0.3)
#: Turns smaller than this are not made, rad.
MIN_TURN = 1e-4
#: Drives shorter than this are not made, m.
MIN_DRIVE = 1e-4
#: Smallest distance m the whole robot's centre of mass keeps from the edges of its
#: support polygon in a planned arm configuration (0: the static tipping limit; the
#: simulation judges the dynamics).
TIP_MARGIN = 0.0
#: The calibration's probes: ``travel`` distances m and ``turning`` angles rad.
PROBE_DISTANCES = (0.1, 0.3)
PROBE_ANGLES = (0.25, 0.5, 0.875, 1.5, 2.25, 3.1)
#: The calibration's key of a turn's ratio at an angle: ``turn_ratio_at_<angle>_rad``.
TURN_KEY = "turn_ratio_at_"
#: ... and of where it moved the wheels' middle: ``turn_shift_x_at_<angle>_m`` (and y).
SHIFT_KEY = "turn_shift_"
#: Shortest turn of a pick-and-place, s (see ``ComposedController._turn_seconds``).
TURN_MIN_S = 1.0
#: Peak joint acceleration of the arm, rad/s^2: gentler than a bolted arm's (3), so that
#: its reaction does not turn the base on its wheels (which only hold their speed).
ARM_ACCELERATION = 1.0
#: Least distance m of an object lower than the base's top from the base's outline (the
#: gripper's half-size: ``gaits.manipulator.FLOOR_CLEARANCE`` keeps as much from the floor).
BODY_CLEARANCE = 0.04
#: Least height m above the floor of the arm's parts while it grasps or puts down: the
#: wheels only hold their speed, and a gripper's jaw dragging on the floor turns the base.
FLOOR_GAP = 0.005
#: Largest step rad between the arm's legs of a pick-and-place (they meet at one pose).
MAX_JUMP = 1e-3
#: Largest distance m a pick-and-place target may lie from the start.
FIELD = 5.0
#: s a ``travel`` stands still after its drive, its feedback loop settling on the distance
#: (:mod:`gaits.wheel_feedback`)
TRAVEL_SETTLE_S = 1.0


def _role(kinds, node: PartNode) -> str:
    k = kinds.of(node.kinds)
    return k.role if k is not None else ""


def _is_arm(kinds, node: PartNode) -> bool:
    """Whether ``node`` starts a chain of joints and links (an arm, a head), whatever ends
    it (a gripper, a tool, nothing)."""
    roles = {_role(kinds, n) for n in node.walk()}
    return _role(kinds, node) in ("joint", "link") and roles <= ARM_ROLES | {""}


def split(plan: BodyPlan, kinds) -> tuple[BodyPlan, list[tuple[BodyPlan, int]]]:
    """(the base's plan, [(an arm's plan, the index among the root's children of the part
    it hangs on)]) of a composed body plan: the chains of joints and links on the root
    part or on a root part it carries (a torso on a chassis) are arms, each rooted at a
    stationary root kind that mounts its first part with a serial mount (links without a
    prefix); the rest is the base. ValueError when an arm has no such root kind."""
    root = plan.root
    arms: list[tuple[BodyPlan, int]] = []

    def arm(child: PartNode, parent: PartNode, i: int) -> None:
        stand = [
            k
            for k in kinds.kinds.values()
            if k.root
            and any(
                m.child in child.kinds and m.layout == "serial" and not m.links for m in k.mounts
            )
        ]
        if not stand:
            raise ValueError(
                f"{plan.robot_type}: no stationary root part kind mounts its arm's "
                f"{child.kind} (a 'root' kind with a serial mount of it)"
            )
        k = sorted(stand, key=lambda k: k.cls)[0]
        arm_root = PartNode(k.cls, (k.cls,), (child,))
        arms.append((BodyPlan(f"{plan.robot_type}.arm{len(arms) + 1}", arm_root), i))

    base_children = []
    for i, child in enumerate(root.children):
        ck = kinds.of(child.kinds)
        if _is_arm(kinds, child):
            arm(child, root, i)
        elif ck is not None and ck.root:  # a part it carries: its arms are the robot's
            keep = []
            for g in child.children:
                if _is_arm(kinds, g):
                    arm(g, child, i)
                else:
                    keep.append(g)
            base_children.append(replace(child, children=tuple(keep)))
        else:
            base_children.append(child)
    base = BodyPlan(
        f"{plan.robot_type}.base",
        replace(root, children=tuple(base_children)),
        plan.lengths,
        plan.extensible,
    )
    return base, arms


class _Chain:
    """One arm of a composition: its controller (on its own plan, joints named as a
    stationary arm's), its joints' names in the design (``joints``; its own: ``own``), the
    name its behaviours carry (``name``: "" for a design's only arm; left, right, middle
    or the assembler's prefix), where its first joint stands on the base (``mount``, root
    frame) and the design's name of each of its bodies (``body``)."""

    def __init__(self, controller, own, joints, prefix: str, mount: np.ndarray) -> None:
        self.controller = controller
        self.own = tuple(own)
        self.joints = tuple(joints)
        self.prefix = prefix
        self.name = ARM_NAMES.get(prefix, prefix)
        self.mount = mount

    def body(self, own: str) -> str:
        return f"{self.prefix}_{own}" if self.prefix else own


class ComposedController(Controller):
    """The behaviours of chains of joints (arms, heads) on a base: a locomotion base
    (wheels, legs) or a stationary one (see the module docstring).

    ``base_position`` (3,) m: where the base's root stands in the world at the start (the
    MJCF's root body position; default: at the origin, standing on its wheels or feet);
    ``stiffness``: joint -> servo stiffness N m/rad (the MJCF's ``kp``), passed on to the
    arms' controllers for their droop compensation."""

    def __init__(
        self,
        geometry: DesignGeometry,
        base_position: Sequence[float] | None = None,
        stiffness: Mapping[str, float] | None = None,
    ) -> None:
        super().__init__(geometry)

        kinds = in_use()
        plan = plan_of(geometry.template)
        base_plan, arms = split(plan, kinds)
        if not arms:
            raise ValueError(f"{geometry.robot_type}: a composition drives arms, it has none")
        kind = structure_of(base_plan, kinds)
        fixed = not kind and not any(
            _role(kinds, n) for n in base_plan.root.walk() if n is not base_plan.root
        )
        if not fixed and (
            kind in ("mobile_manipulator", "legged_manipulator") or kind not in CONTROLLERS
        ):
            raise ValueError(
                f"{geometry.robot_type}: its base's structure {kind!r} has no controller"
            )
        #: how the base moves: "wheels" (it drives), "legs" (it walks) or "" (it stands)
        self.locomotion = "" if fixed else ("legs" if self.template.feet else "wheels")
        if base_position is None:  # standing on its wheels or feet at the origin (as the MJCF)
            base_position = (0.0, 0.0, _standing_height(self.template))
        self.base_position = np.array(base_position, dtype=float)
        # the base's controller on the whole design: it carries the arms and the payload
        self.base = None
        if not fixed:
            from importlib import import_module

            module, name = CONTROLLERS[kind]
            self.base = getattr(import_module(module), name)(geometry)
            if self.locomotion == "wheels" and not hasattr(self.base, "drive"):
                raise ValueError(
                    f"{geometry.robot_type}: its base ({kind}) has no drive to carry an arm with"
                )
        q_names = self.template.model.q_names
        chains: list[_Chain] = []
        used: set[str] = set()
        for arm_plan, _ in arms:
            register_plan(arm_plan)
            probe = build(arm_plan.robot_type)
            own = probe.model.q_names
            # its joints in the design: the same names, or with the prefix of where it
            # stands (two arms of one mount: l_base_yaw, r_base_yaw)
            prefixes = [
                q[: -len(own[0]) - 1] if q != own[0] else ""
                for q in q_names
                if (q == own[0] or q.endswith("_" + own[0]))
                and all(
                    (f"{q[: -len(own[0]) - 1]}_{j}" if q != own[0] else j) in q_names for j in own
                )
            ]
            free = [p for p in prefixes if p not in used]
            if not free:
                raise ValueError(f"{geometry.robot_type}: cannot find its arm's joints {own}")
            prefix = free[0]
            used.add(prefix)
            design = tuple(f"{prefix}_{j}" if prefix else j for j in own)
            # the arm's lengths: its links' as the design names them
            segs = {s.body: s.length_name for s in self.template.segments}
            bodies = {
                s.length_name: f"{prefix}_{s.body}" if prefix else s.body for s in probe.segments
            }
            if any(b not in segs for b in bodies.values()):
                raise ValueError(f"{geometry.robot_type}: cannot match its arm's links")
            rename = {own_name: segs[b] for own_name, b in bodies.items()}
            lengths = {k: float(geometry.lengths[v]) for k, v in rename.items()}
            arm_geometry = replace(
                geometry,
                robot_type=arm_plan.robot_type,
                template=arm_plan.robot_type,
                lengths=lengths,
                modules=1,
                calibration={},
                joint_speed={
                    j: geometry.joint_speed[d]
                    for j, d in zip(own, design, strict=True)
                    if d in geometry.joint_speed
                },
                joint_torque={
                    j: geometry.joint_torque[d]
                    for j, d in zip(own, design, strict=True)
                    if d in geometry.joint_torque
                },
            )
            arm_template = build(arm_plan.robot_type, _params(arm_geometry))
            mount = _joint_origin(self.template, design[0]) - _joint_origin(arm_template, own[0])
            options: dict[str, object] = {"base_position": tuple(self.base_position + mount)}
            if self.locomotion:  # gentle: its reaction must not move the base under it
                options["max_acceleration"] = ARM_ACCELERATION
            if stiffness is not None:
                options["stiffness"] = {
                    j: float(stiffness[d])
                    for j, d in zip(own, design, strict=True)
                    if d in stiffness
                }
            arm_kind = structure_of(arm_plan, kinds)
            if arm_kind != "serial_arm":
                raise ValueError(
                    f"{geometry.robot_type}: its arm's structure {arm_kind!r} has no controller"
                )
            chains.append(
                _Chain(controller_for(arm_geometry, **options), own, design, prefix, mount)
            )
        # in the design's joint order
        chains.sort(key=lambda c: q_names.index(c.joints[0]))
        if len(chains) > 1 and len({c.name for c in chains}) != len(chains):
            raise ValueError(f"{geometry.robot_type}: two of its arms have one name")
        self.chains = tuple(chains)
        mine = {j for c in chains for j in c.joints}
        if self.locomotion == "wheels":
            self.base_joints = tuple(self.base.joints)
        else:  # the legs' joints (a legged plan lists every movable joint), or none
            self.base_joints = tuple(j for j in self.movable_joints() if j not in mine)
        self.wheels = self.base_joints
        self.all_joints = (*self.base_joints, *(j for c in chains for j in c.joints))
        missing = set(self.all_joints) - set(q_names)
        if missing:
            raise ValueError(
                f"{geometry.robot_type}: joints {sorted(missing)} are not the design's"
            )
        self.loaded = build(
            geometry.template,
            _params(geometry, float(geometry.params.get("payload", 0.0))),
        )
        self._focus(chains[0])
        #: one view of this controller per arm (each plans with its own arm, the others
        #: held): the behaviours of a design with several arms
        self.views: tuple[ComposedController, ...] = (self,)
        #: the whole of a design with several arms (its behaviours: each arm's, each planned
        #: by the view of that arm, the others held; the base's by the first view)
        self.whole = False
        if len(chains) > 1:
            self.views = tuple(self._view(c) for c in chains)
            for view in self.views:
                view.views = self.views
            self.joints = self.all_joints
            self.whole = True

    def _focus(self, chain: _Chain) -> None:
        """Plan with ``chain``'s arm (the others held in their ready poses)."""
        self.chain = chain
        self.arm = chain.controller
        self.arm_joints = chain.joints
        self.arm_own = chain.own
        self.mount = chain.mount
        self.joints = (
            (*self.base_joints, *chain.joints) if len(self.chains) > 1 else self.all_joints
        )

    def _view(self, chain: _Chain) -> ComposedController:
        view = copy.copy(self)
        for cached in ("hold", "_behaviors", "rest"):
            view.__dict__.pop(cached, None)
        view._focus(chain)
        view.identity = None  # its plans are remembered by the whole's (``run``)
        return view

    @cached_property
    def rest(self) -> np.ndarray:
        """(nv,) rad: the design's configuration with every other arm in its ready pose
        (planned) and the base at zero: where :meth:`tip_margin` puts what this arm's plan
        does not move."""
        m = self.template.model
        q = np.zeros(m.nv)
        for view in self.views:
            if view.chain is not self.chain:
                q[[m.q_names.index(j) for j in view.chain.joints]] = view.hold[1]
        return q

    # --- the pieces ------------------------------------------------------------------

    def calibration_probes(self) -> list[tuple[str, dict[str, object]]]:
        """The base's own probes, then (a base on wheels) ``travel`` over two distances and
        ``turning`` by two angles at the defaults (:meth:`calibrate`)."""
        if self.locomotion != "wheels":
            return list(self.base.calibration_probes()) if self.base is not None else []
        return [*self.base.calibration_probes(), *self._probes()]

    def _probes(self) -> list[tuple[str, dict[str, object]]]:
        return [
            *(("travel", {"distance": d}) for d in PROBE_DISTANCES),
            *(
                ("turning", {"angle": a, "seconds": self._turn_seconds(a, self._default_speed)})
                for a in PROBE_ANGLES
            ),
        ]

    @property
    def _default_speed(self) -> float:
        return float(self._speed_parameter().default)  # type: ignore[arg-type]

    def _turn_seconds(self, angle: float, speed: float) -> float:
        """How long a pick-and-place turn by ``angle`` rad takes: its wheels' rims peak at
        the drive's ``speed`` m/s, and it lasts ``TURN_MIN_S`` at least (a quick small turn
        springs back on the tyres: it ends off the heading that a gentle one reaches)."""
        half = self.base.drive.effective_track / 2
        return round(max(TURN_MIN_S, 1.875 * abs(angle) * half / speed), 2)

    def calibrate(self, runs: Sequence[tuple[Trajectory, Mapping[str, np.ndarray]]]) -> dict:
        """The base's calibration, and how far the base really goes: ``travel_ratio``, the
        distance travelled per distance commanded at ``travel_speed_m_s`` (least squares
        over the probes), and ``turn_ratio_at_<angle>_rad``, the heading change per angle
        commanded of a turn in place by each probe's angle (:meth:`_turn_command`
        interpolates them). MuJoCo's caster and tyres resist the base with a nearly
        constant force that the drive's load model leaves out: a slow drive falls short by
        a nearly constant speed, which ``travel_ratio`` measures at one speed
        (:meth:`_travel_command` scales it to others), as Mandow et al. calibrate a real
        base."""
        if self.locomotion != "wheels":
            return dict(self.base.calibrate(runs)) if self.base is not None and runs else {}
        nb = len(runs) - len(self._probes())
        # the base's own probes, seen as the base planned them: its wheels' columns
        nw = len(self.wheels)
        own = [
            (
                Trajectory(
                    t.behavior,
                    t.times,
                    t.joints[:nw],
                    t.positions[:, :nw],
                    t.velocities[:, :nw],
                    t.info,
                ),
                dict(series) | {"q": np.asarray(series["q"])[:, :nw]},
            )
            for t, series in runs[:nb]
        ]
        out = dict(self.base.calibrate(own)) if own else {}
        num = den = 0.0
        speed = None
        for traj, series in runs[nb:]:
            root = np.asarray(series["root"])
            if traj.behavior == "travel":
                cmd = float(traj.info["planned_pose"][0])  # type: ignore[index]
                got = float(root[-1, 0] - root[0, 0])
                num, den = num + got * cmd, den + cmd * cmd
                speed = float(traj.info["speed_m_s"])  # type: ignore[arg-type]
            elif traj.behavior == "turning":
                cmd = float(traj.info["heading_rad"])  # type: ignore[arg-type]
                yaw = np.unwrap([quat_yaw(q) for q in root[:, 3:7]])
                ratio = float(yaw[-1] - yaw[0]) / cmd
                if ratio > 0:
                    out[f"{TURN_KEY}{abs(cmd):g}_rad"] = round(ratio, 5)
                    # where the wheels' middle went, in the start's frame (a left turn;
                    # a right one mirrors it)
                    c, s = math.cos(yaw[0]), math.sin(yaw[0])
                    d = root[-1, :2] - root[0, :2]
                    side = math.copysign(1.0, cmd)
                    ahead, aside = float(c * d[0] + s * d[1]), float(c * d[1] - s * d[0])
                    out[f"{SHIFT_KEY}x_at_{abs(cmd):g}_m"] = round(ahead, 6)
                    out[f"{SHIFT_KEY}y_at_{abs(cmd):g}_m"] = round(side * aside, 6)
        if den > 0 and num > 0 and speed:
            out["travel_ratio"] = round(num / den, 5)
            out["travel_speed_m_s"] = round(speed, 6)
        return out

    def _travel_command(self, distance: float, speed: float) -> float:
        """The distance m to command for the base to travel ``distance`` m at peak
        ``speed`` m/s: the calibrated shortfall taken out, as a constant speed deficit
        while moving (``(1 - travel_ratio) x travel_speed_m_s`` of peak speed: the same
        fraction of the mean speed, the profile being the same); ``distance`` without a
        calibration."""
        cal = self.geometry.calibration
        ratio, at = cal.get("travel_ratio"), cal.get("travel_speed_m_s")
        if not ratio or not at:
            return distance
        deficit = (1.0 - float(ratio)) * float(at)
        keep = 1.0 - deficit / speed
        if keep <= 0.2:
            raise ValueError(
                f"driving at {speed:g} m/s: the base loses {deficit:.3g} m/s to its "
                "rolling resistance (measured); drive faster"
            )
        return distance / keep

    def _turn_shift(self, angle: float) -> np.ndarray:
        """(2,) m: where a turn in place by ``angle`` rad moves the wheels' middle, in the
        frame the turn starts in (the calibration's probes interpolated in the angle; a
        right turn mirrors a left one); zero without a calibration."""
        cal = self.geometry.calibration
        out = np.zeros(2)
        for k, axis in enumerate("xy"):
            key = f"{SHIFT_KEY}{axis}_at_"
            table = sorted(
                (float(n[len(key) : -2]), float(v))
                for n, v in cal.items()
                if n.startswith(key) and n.endswith("_m")
            )
            if table:
                at, shift = np.array(table).T
                out[k] = float(
                    np.interp(
                        abs(angle), np.concatenate([[0.0], at]), np.concatenate([[0.0], shift])
                    )
                )
        out[1] *= math.copysign(1.0, angle) if angle else 0.0
        return out

    def _turn_command(self, angle: float) -> float:
        """The angle rad to command for the base to turn in place by ``angle`` rad: the
        calibrated ratios (heading change per angle commanded) interpolated linearly in
        the angle commanded (held beyond the probes) and inverted by fixed-point
        iteration; ``angle`` without a calibration."""
        table = sorted(
            (float(k[len(TURN_KEY) : -4]), float(v))
            for k, v in self.geometry.calibration.items()
            if k.startswith(TURN_KEY) and k.endswith("_rad")
        )
        if not table or angle == 0:
            return angle
        at, ratio = np.array(table).T
        cmd = angle
        for _ in range(50):
            cmd = angle / float(np.interp(abs(cmd), at, ratio))
        return cmd

    @cached_property
    def hold(self) -> tuple[np.ndarray, np.ndarray]:
        """The arm's ready pose (commanded: droop compensated, as its trajectories command
        it; planned): the first sample of its ``positioning`` (of a chain that only points
        its tool: of its first behaviour)."""
        behaviours = self.arm.behaviors
        t = self.arm.run("positioning" if "positioning" in behaviours else min(behaviours))
        return self._arm_block(t)[0], self._arm_block(t, "planned")[0]

    @cached_property
    def support(self) -> np.ndarray:
        """(k, 2) m: the support polygon's corners (counter-clockwise, root frame): the
        wheels' and casters' contact points under their centres."""
        t = self.template
        m = t.model
        T = forward_kinematics(m, np.zeros(m.nv))
        pts = np.array([T[m.body(b), :2, 3] for b in (*t.wheels, *t.casters)])
        return _hull(pts)

    def tip_margin(self, q_arm: np.ndarray) -> np.ndarray:
        """(N,) m: the distance of the whole robot's centre of mass inside the support
        polygon, the arm at ``q_arm`` (N, na) rad (negative: outside, the robot tips). The
        masses are the template's stand-ins scaled to the design's mass less its payload
        (``DesignGeometry.mass_kg``; unscaled without it), the payload in the gripper, as
        the drive's load model lays them out (``gaits.wheeled``)."""
        q_arm = np.atleast_2d(q_arm)

        def moments(model) -> tuple[float, np.ndarray]:
            Q = np.tile(self.rest, (len(q_arm), 1))  # the other arms held
            Q[:, [model.q_names.index(j) for j in self.arm_joints]] = q_arm
            T = forward_kinematics(model, Q)  # (N, nb, 4, 4)
            mass = np.array([b.mass for b in model.bodies])
            com = np.array([np.asarray(b.com, dtype=float) for b in model.bodies])
            world = np.einsum("nbij,bj->nbi", T[:, :, :3, :3], com) + T[:, :, :3, 3]
            return float(mass.sum()), np.einsum("b,nbi->ni", mass, world)[:, :2]

        m0, h0 = moments(self.template.model)
        m1, h1 = moments(self.loaded.model)
        payload = m1 - m0
        scale = (self.geometry.mass_kg - payload) / m0 if self.geometry.mass_kg > payload else 1.0
        c = (scale * h0 + (h1 - h0)) / (scale * m0 + payload)
        poly = self.support
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        # inward distance to each edge (counter-clockwise polygon: inward is left)
        d = -np.einsum("ek,nek->ne", normals, c[:, None, :] - poly[None])
        return d.min(axis=1)

    def _check_tip(self, name: str, arm_positions: np.ndarray) -> float:
        step = max(1, len(arm_positions) // 200)
        margin = self.tip_margin(arm_positions[::step])
        worst = float(margin.min())
        if worst < TIP_MARGIN:
            k = int(np.argmin(margin)) * step
            raise ValueError(
                f"{name}: the robot would tip: with the arm at "
                f"({', '.join(f'{x:.3f}' for x in arm_positions[k])}) rad its centre of mass "
                f"is {abs(worst) * 1000:.1f} mm {'inside' if worst >= 0 else 'outside'} its "
                f"support polygon (needs {TIP_MARGIN * 1000:g} mm inside); a lighter payload, "
                "a longer base or a target nearer the base"
            )
        return worst

    # --- behaviours ------------------------------------------------------------------

    @cached_property
    def _behaviors(self) -> dict[str, BehaviorSpec]:
        if self.whole:  # several arms: each its own behaviours
            out: dict[str, BehaviorSpec] = {}
            self._route: dict[str, tuple[ComposedController, str]] = {}
            for view in self.views:
                mine = set(view.arm.behaviors) | {"pick-and-place"}
                for n, spec in view._behaviors.items():
                    if n not in mine:  # the base's: with every arm held
                        if view is self.views[0]:
                            out[n], self._route[n] = spec, (view, n)
                        continue
                    name = f"{view.chain.name}-{n}"
                    alias = spec.alias_of
                    out[name] = replace(
                        spec,
                        name=name,
                        doc=f"{spec.doc} ({view.chain.name} arm)",
                        ability=spec.realises,
                        alias_of=f"{view.chain.name}-{alias}" if alias in mine else alias,
                    )
                    self._route[name] = (view, n)
            return out
        if self.locomotion != "wheels":  # the base's (if any) with the arm held, the arm's
            return {**self.arm.behaviors, **(self.base.behaviors if self.base else {})}
        out = {**self.arm.behaviors, **self.base.behaviors}
        if "pick-and-place" in out:
            out["pick-and-place"] = self._pick_and_place_spec()
        out["travel"] = BehaviorSpec(
            "travel",
            "drive straight a distance and stop (minimum-jerk), the arm in its ready pose",
            (
                Parameter(
                    "distance",
                    "float",
                    round(float(self.base.body_length) * 2, 4),
                    "distance, negative backwards",
                    "m",
                    low=-FIELD,
                    high=FIELD,
                ),
                self._speed_parameter(),
            ),
            ability="driving",
        )
        return out

    def _speed_parameter(self) -> Parameter:
        return Parameter(
            "speed",
            "float",
            round(DRIVE_SPEED_FRACTION * self.base.v_max, 4),
            "the base's peak speed while driving",
            "m/s",
            low=0.001,
            high=round(self.base.v_max, 4),
        )

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        return self._behaviors

    @cached_property
    def forward(self) -> float:
        """m: the arm's first joint ahead of the base's root (x, root frame)."""
        return float(self.mount[0])

    def _pick_and_place_spec(self) -> BehaviorSpec:
        reach = float(self.arm.reach)
        # the arm's own default height, or above the base's top: a target clear of the
        # robot wherever the arm stands on it
        z = float(self.arm.behaviors["grasping"].resolve({})["z"]) + float(
            self.arm.base_position[2]
        )
        clear_of_base = float(self.base_position[2]) + self.footprint[1] + BODY_CLEARANCE
        z = max(z, math.ceil((clear_of_base + FLOOR_GAP) * 1e3) / 1e3)
        clear = self.arm.behaviors["grasping"].resolve({})["clearance"]
        ahead = self.forward + 2.0 * reach  # beyond the arm's reach from the start
        # the highest point the gripper reaches: its shoulder on the base, + the reach
        top = float(self.arm.base_position[2]) + float(self.arm._shoulder[2]) + reach
        top = max(math.ceil(top * 1e4) / 1e4, round(z, 4))

        def xyz(prefix: str, where: str, x: float, y: float) -> tuple[Parameter, ...]:
            return tuple(
                Parameter(
                    f"{prefix}{c}",
                    "float",
                    round(v, 4),
                    f"{where} {c} in the world frame (start: root at the origin, facing +x)",
                    "m",
                    low=0.0 if c == "z" else -FIELD,
                    high=top if c == "z" else FIELD,
                )
                for c, v in (("x", x), ("y", y), ("z", z))
            )

        return BehaviorSpec(
            "pick-and-place",
            "drive to the object, pick it, drive to the place target and put it down "
            "(the base turns and drives, the arm stands by; world frame)",
            (
                # in front of the arm (one of several stands aside on the base)
                *xyz("pick_", "object", ahead, 0.0 + float(self.mount[1])),
                *xyz(
                    "place_",
                    "place target",
                    ahead + 1.5 * reach,
                    0.5 * reach + float(self.mount[1]),
                ),
                Parameter(
                    "clearance",
                    "float",
                    float(clear),
                    "height above the object of the approach and the lift",
                    "m",
                    low=0.0,
                    high=reach,
                ),
                self._speed_parameter(),
            ),
        )

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        if self.whole:  # one arm's, or the base's
            _ = self._behaviors
            view, own = self._route[name]
            return self._widen(view._run(own, params), name)
        if self.locomotion != "wheels":
            return self._standing(name, params)
        if name == "pick-and-place":
            return self._pick_and_place(params)
        if name == "travel":
            d = float(params["distance"])  # type: ignore[arg-type]
            held, planned = self.hold
            plan = _Legs(self.wheels, self.arm_joints, held, planned)
            speed = float(params["speed"])  # type: ignore[arg-type]
            profile: dict[str, float] = {}
            if abs(d) > 0:
                cmd = self._travel_command(d, speed)
                t, q, v = self._drive(cmd, speed)
                plan.base(t, q, v, self.hold)
                profile = {"distance": cmd, "seconds": float(t[-1])}
                # the base stands still while its loop settles on the distance (as a
                # pick-and-place's base does before its arm moves): a probe measures where
                # the base comes to rest
                n = int(round(TRAVEL_SETTLE_S / SAMPLE_DT)) + 1
                plan.arm(
                    np.linspace(0.0, TRAVEL_SETTLE_S, n),
                    *(np.tile(x, (n, 1)) for x in (held, held * 0, planned, held * 0)),
                )
            else:
                plan.arm(
                    np.array([0.0, 2 * SAMPLE_DT]),
                    *(np.tile(x, (2, 1)) for x in (held, held * 0, planned, held * 0)),
                )
            t, pos, vel, pl, acc = plan.arrays()
            info = {
                "motion": "straight" if d else "hold",
                "planned_pose": (d, 0.0, 0.0),
                "path_length_m": abs(d),
                "speed_m_s": speed,
                "direction": (math.copysign(1.0, d), 0.0),
                "locomotion": "wheeled",
                "body_length_m": self.base.body_length,
                "planned_positions": pl,
                "accelerations": acc,
            }
            info.update(self._base_feedback(profile) if profile else self._hold_feedback())
            return Trajectory(name, t, self.joints, pos, vel, info)
        if name == "turning":  # as calibrated; the promise the angle asked
            angle = float(params["angle"])  # type: ignore[arg-type]
            t = self.base.run(name, **(dict(params) | {"angle": self._turn_command(angle)}))
            info = dict(t.info) | {"heading_rad": angle, "planned_pose": (0.0, 0.0, angle)}
            t = replace(t, info=info)
        elif name in self.base.behaviors:
            t = self.base.run(name, **params)
        if name in self.base.behaviors:
            n = len(t.times)
            held, planned = self.hold
            pos = np.hstack([self._wheel_block(t), np.tile(held, (n, 1))])
            vel = np.hstack([self._wheel_block(t, "velocities"), np.zeros((n, len(held)))])
            info = dict(t.info)
            info["planned_positions"] = np.hstack([self._wheel_block(t), np.tile(planned, (n, 1))])
            return Trajectory(name, t.times, self.joints, pos, vel, info)
        t = self.arm.run(name, **params)
        self._check_tip(name, self._arm_block(t, "planned"))
        n = len(t.times)
        still = np.zeros((n, len(self.wheels)))
        info = dict(t.info) | {"locomotion": "wheeled", "body_length_m": self.base.body_length}
        if "tool_body" in info:
            info["tool_body"] = self.chain.body(str(info["tool_body"]))
        # the arm's own per-joint series, widened to the design's joints (wheels still)
        for key in ("planned_positions", "accelerations"):
            if key in info:
                info[key] = np.hstack([still, self._arm_block(t, key)])
        pos = np.hstack([still, self._arm_block(t)])
        vel = np.hstack([still, self._arm_block(t, "velocities")])
        info.update(self._hold_feedback())
        return Trajectory(name, t.times, self.joints, pos, vel, info)

    def _standing(self, name: str, params: Mapping[str, object]) -> Trajectory:
        """A behaviour of a design whose base walks or stands: the base's (its legs') with
        the arm held in its ready pose, or the arm's with the legs standing (at zero, as
        the design stands when it starts) or on a stationary base."""
        held, planned = self.hold
        if self.base is not None and name in self.base.behaviors:
            t = self.base.run(name, **params)
            cols = {j: i for i, j in enumerate(t.joints)}
            mine = dict(zip(self.arm_joints, zip(held, planned, strict=True), strict=True))
            n = len(t.times)
            pos = np.column_stack(
                [
                    np.full(n, mine[j][0]) if j in mine else t.positions[:, cols[j]]
                    for j in self.joints
                ]
            )
            vel = np.column_stack(
                [np.zeros(n) if j in mine else t.velocities[:, cols[j]] for j in self.joints]
            )
            info = dict(t.info)
            info["planned_positions"] = np.column_stack(
                [
                    np.full(n, mine[j][1]) if j in mine else t.positions[:, cols[j]]
                    for j in self.joints
                ]
            )
            return Trajectory(name, t.times, self.joints, pos, vel, info)
        t = self.arm.run(name, **params)
        n = len(t.times)
        still = np.zeros((n, len(self.base_joints)))
        info = dict(t.info)
        for key in ("planned_positions", "accelerations"):
            if key in info:
                info[key] = np.hstack([still, self._arm_block(t, key)])
        if "tool_body" in info:
            info["tool_body"] = self.chain.body(str(info["tool_body"]))
        if self.base is not None:
            info |= {"locomotion": "legged", "body_length_m": self.base.body_length}
        pos = np.hstack([still, self._arm_block(t)])
        vel = np.hstack([still, self._arm_block(t, "velocities")])
        return Trajectory(name, t.times, self.joints, pos, vel, info)

    def _widen(self, t: Trajectory, name: str) -> Trajectory:
        """``t`` (the base's and one arm's joints) as behaviour ``name`` of the whole design:
        every other arm held in its ready pose."""
        cols = {j: i for i, j in enumerate(t.joints)}
        held: dict[str, tuple[float, float]] = {}
        for view in self.views:
            cmd, planned = view.hold
            held |= dict(zip(view.chain.joints, zip(cmd, planned, strict=True), strict=True))
        n = len(t.times)

        def widen(src: np.ndarray, fill: int | None) -> np.ndarray:
            return np.column_stack(
                [
                    src[:, cols[j]]
                    if j in cols
                    else (np.zeros(n) if fill is None else np.full(n, held[j][fill]))
                    for j in self.all_joints
                ]
            )

        info = dict(t.info)
        info["planned_positions"] = widen(np.asarray(info.get("planned_positions", t.positions)), 1)
        if "accelerations" in info:
            info["accelerations"] = widen(np.asarray(info["accelerations"]), None)
        return Trajectory(
            name, t.times, self.all_joints, widen(t.positions, 0), widen(t.velocities, None), info
        )

    def _hold_feedback(self) -> dict[str, object]:
        """``info["feedback"]`` of a plan whose base stands still while the arm works (or
        between its drives): the base's wheels hold their encoder angles
        (:class:`gaits.wheel_feedback.WheelHold`), so the arm's reaction and a slope do not
        roll it away; empty for a base whose controller offers no wheel loop."""
        spec = getattr(self.base, "feedback_spec", None)
        return {"feedback": spec({}, kind="wheel-hold")} if spec is not None else {}

    def _base_feedback(self, profile: Mapping[str, object]) -> dict[str, object]:
        """``info["feedback"]`` of a plan whose base drives (``profile``: its heading and
        distance reference, :func:`gaits.wheel_feedback.reference`): heading and distance
        closed on the wheels (and the IMU where the design carries one), held between the
        drives; empty for a base whose controller offers no wheel loop."""
        spec = getattr(self.base, "feedback_spec", None)
        return {"feedback": spec(profile)} if spec is not None else {}

    def _wheel_block(self, t: Trajectory, what: str = "positions") -> np.ndarray:
        src = t.velocities if what == "velocities" else t.positions
        return np.column_stack([src[:, t.joints.index(j)] for j in self.wheels])

    def _arm_block(self, t: Trajectory, what: str = "positions") -> np.ndarray:
        """The arm's columns of ``t``'s ``what``: positions, velocities,
        planned_positions (the positions without droop compensation), accelerations
        (differentiated where the trajectory carries none)."""
        if what == "velocities":
            src = t.velocities
        elif what == "planned":
            src = np.asarray(t.info.get("planned_positions", t.positions))
        elif what in t.info:
            src = np.asarray(t.info[what])
        elif what == "accelerations":
            src = np.gradient(t.velocities, t.times, axis=0)
        else:
            src = t.positions
        return np.column_stack([src[:, t.joints.index(j)] for j in self.arm_own])

    # --- pick-and-place ------------------------------------------------------------------

    def _drive(self, distance: float, speed: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times, wheel positions, wheel velocities) of a straight drive of ``distance`` m
        (negative: backwards) with a minimum-jerk profile peaking at ``speed`` m/s or
        slower, starting and ending at rest; the wheels' commands are the drive's load
        model's (``DriveGeometry.commands``). ValueError when the wheels cannot."""
        d = self.base.drive
        T = max(1.875 * abs(distance) / speed, 4 * SAMPLE_DT)
        for _ in range(400):
            t, left, right = self._drive_profile(distance, T)
            if max(np.max(np.abs(left)), np.max(np.abs(right))) <= d.max_speed:
                break
            T *= 1.01
        else:
            raise ValueError(f"the wheels cannot drive {distance:g} m: their servos stall")
        T = math.ceil(T / SAMPLE_DT - 1e-9) * SAMPLE_DT
        t, left, right = self._drive_profile(distance, T)
        d.check_commands(left, right, f"driving {distance:g} m")
        side = {n: left for n in d.left} | {n: right for n in d.right}
        vel = np.column_stack([d.sign[n] * side[n] for n in self.wheels])
        return t, _integral(t, vel), vel

    def _drive_profile(self, distance: float, T: float):
        n = max(3, int(math.ceil(T / SAMPLE_DT - 1e-9)) + 1)
        t = np.linspace(0.0, T, n)
        _, ds, dds = min_jerk(t / T)
        v, a = distance * ds / T, distance * dds / T**2
        zero = np.zeros_like(t)
        left, right = self.base.drive.commands(v, zero, a, zero)
        return t, left, right

    def _arm_frame(self, pose: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``target`` (world, m) in the arm's base frame with the base's root at ``pose``
        (x, y, yaw; world)."""
        x, y, th = pose
        c, s = math.cos(th), math.sin(th)
        d = target[:2] - np.array([x, y]) - self.base_position[:2]
        local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        return np.array(
            [
                local[0] - self.mount[0],
                local[1] - self.mount[1],
                target[2] - self.base_position[2] - self.mount[2],
            ]
        )

    @cached_property
    def footprint(self) -> tuple[np.ndarray, float]:
        """(the base's outline (k, 2) m, counter-clockwise, root frame; its top m above the
        root): the convex hull of its parts' boxes (a cylinder's as its box), the root's,
        the wheels' and the casters' (what the arm does not move)."""
        t = self.template
        m = t.model
        T = forward_kinematics(m, np.zeros(m.nv))
        corners = []
        for body in (m.bodies[0].name, *t.wheels, *t.casters):
            for part in t.parts.get(body, ()):
                dims = tuple(float(d) for d in part.dims)
                if len(dims) == 2:  # a cylinder: radius, length along its z
                    dims = (2 * dims[0], 2 * dims[0], dims[1])
                if len(dims) != 3:
                    continue
                half = np.array(dims) / 2
                for sx in (-1, 1):
                    for sy in (-1, 1):
                        for sz in (-1, 1):
                            local = np.append(half * (sx, sy, sz), 1.0)
                            corners.append((T[m.body(body)] @ part.placement @ local)[:3])
        pts = np.array(corners)
        return _hull(pts[:, :2]), float(pts[:, 2].max())

    def _over_base(self, pose: np.ndarray, target: np.ndarray) -> bool:
        """Whether ``target`` (world) lies over or beside the base at ``pose`` within
        ``BODY_CLEARANCE``, lower than its top: the gripper would touch the robot."""
        outline, top = self.footprint
        if target[2] > self.base_position[2] + top + BODY_CLEARANCE:
            return False
        x, y, th = pose
        c, s = math.cos(th), math.sin(th)
        d = target[:2] - np.array([x, y]) - self.base_position[:2]
        local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        edges = np.roll(outline, -1, axis=0) - outline
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        outside = float(np.max(np.einsum("ek,ek->e", normals, local[None] - outline)))
        return outside < BODY_CLEARANCE

    def _grasp_from(self, pose: np.ndarray, target: np.ndarray, clearance: float):
        """The arm's ``grasping`` of ``target`` (world) with the base at ``pose``, or the
        reason it cannot (out of reach, over the base itself, or the robot would tip)."""
        if self._over_base(pose, target):
            return None, (
                f"it would lie within {BODY_CLEARANCE} m of the base, lower than its top: "
                "the gripper would touch the robot"
            )
        p = self._arm_frame(pose, target)
        try:
            grasp = self.arm.run("grasping", x=p[0], y=p[1], z=p[2], clearance=clearance)
            self._check_tip("grasping there", self._arm_block(grasp, "planned"))
        except ValueError as e:
            return None, str(e)
        low = float(self.lowest(self._arm_block(grasp, "planned")).min())
        if low < FLOOR_GAP:
            return None, (
                f"the arm's parts would come down to {low:.4f} m above the floor (needs "
                f"{FLOOR_GAP} m): on a base that only holds its wheels' speed, touching the "
                "floor turns the robot"
            )
        return grasp, None

    @cached_property
    def _arm_corners(self) -> list[tuple[int, np.ndarray]]:
        """(body index, (8, 4) homogeneous corners in the body's frame) of every part box of
        the arm's moving bodies (a cylinder's as its box)."""
        t = self.arm.template
        m = t.model
        out = []
        for k, body in enumerate(m.bodies):
            if k == 0:
                continue
            for part in t.parts.get(body.name, ()):
                dims = tuple(float(d) for d in part.dims)[:3]
                if len(dims) == 2:
                    dims = (2 * dims[0], 2 * dims[0], dims[1])
                if len(dims) != 3 or part.kind == "link":
                    continue  # a link's tube lies along its joints' line, above the jaws
                half = np.array(dims) / 2
                box = np.array(
                    [
                        (*(half * (sx, sy, sz)), 1.0)
                        for sx in (-1, 1)
                        for sy in (-1, 1)
                        for sz in (-1, 1)
                    ]
                )
                out.append((k, (part.placement @ box.T).T))
        return out

    def lowest(self, q_arm: np.ndarray) -> np.ndarray:
        """(N,) m: the lowest point above the floor of the arm's parts (actuators, gripper
        jaws) with the arm at ``q_arm`` (N, na) rad and the base standing level."""
        m = self.arm.template.model
        q_arm = np.atleast_2d(q_arm)[:: max(1, len(np.atleast_2d(q_arm)) // 100)]
        Q = np.zeros((len(q_arm), m.nv))
        Q[:, [m.q_names.index(j) for j in self.arm_own]] = q_arm
        T = forward_kinematics(m, Q)
        z = np.full(len(q_arm), np.inf)
        for k, corners in self._arm_corners:
            z = np.minimum(z, np.einsum("nj,cj->nc", T[:, k, 2, :], corners).min(axis=1))
        return z + float(self.arm.base_position[2])

    def _go_to(
        self, pose: np.ndarray, target: np.ndarray, clearance: float, speed: float, what: str
    ):
        """Legs that bring the base from ``pose`` to where the arm grasps ``target``: ([base
        legs], the new pose, the arm's grasping there). The base does not move when the
        arm reaches the target from ``pose``."""
        here, why = self._grasp_from(pose, target, clearance)
        if here is not None:
            return [], pose, here
        reasons = []
        # first along the heading the base has (no turn: its odometry's weakest part), the
        # arm's yaw reaching aside
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rel = target[:2] - self.base_position[:2] - pose[:2]
        ahead, aside = c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]
        aside -= float(self.mount[1])
        for f in STANDOFFS:
            r = f * float(self.arm.reach)
            if abs(aside) >= r:
                continue
            drive = ahead - self.forward - math.sqrt(r * r - aside * aside)
            new = np.array([pose[0] + drive * c, pose[1] + drive * s, pose[2]])
            grasp, why_not = self._grasp_from(new, target, clearance)
            if grasp is None:
                reasons.append(why_not)
                continue
            return ([("drive", drive)] if abs(drive) > MIN_DRIVE else []), new, grasp
        # else turn to face it, then drive
        dist = float(np.hypot(*rel))
        heading = math.atan2(rel[1], rel[0]) if dist > 1e-9 else float(pose[2])
        turn = (heading - pose[2] + math.pi) % (2 * math.pi) - math.pi
        # the turn moves the wheels' middle a little (calibrated): face the target from
        # where it ends (a few rounds: the shift depends on the turn)
        turned = pose[:2].copy()
        for _ in range(3):
            shift = self._turn_shift(turn)
            turned = pose[:2] + np.array([c * shift[0] - s * shift[1], s * shift[0] + c * shift[1]])
            rel = target[:2] - self.base_position[:2] - turned
            dist = float(np.hypot(*rel))
            heading = math.atan2(rel[1], rel[0]) if dist > 1e-9 else float(pose[2])
            turn = (heading - pose[2] + math.pi) % (2 * math.pi) - math.pi
        for f in STANDOFFS:
            drive = dist - (self.forward + f * float(self.arm.reach))
            new = np.array(
                [
                    turned[0] + drive * math.cos(heading),
                    turned[1] + drive * math.sin(heading),
                    pose[2] + turn,
                ]
            )
            grasp, why_not = self._grasp_from(new, target, clearance)
            if grasp is None:
                reasons.append(why_not)
                continue
            legs = []
            if abs(turn) > MIN_TURN:
                legs.append(("turn", turn))
            if abs(drive) > MIN_DRIVE:
                legs.append(("drive", drive))
            return legs, new, grasp
        raise ValueError(
            f"the {what} at ({', '.join(f'{c:.4f}' for c in target)}) m (world) is out of "
            f"reach: the arm reaches {float(self.arm.reach):.4f} m and cannot grasp it from "
            f"where the base can stand ({'; '.join(dict.fromkeys(reasons or [why]))})"
        )

    def _pick_and_place(self, params: Mapping[str, object]) -> Trajectory:
        P = {k: float(v) for k, v in params.items()}  # type: ignore[arg-type]
        pick = np.array([P["pick_x"], P["pick_y"], P["pick_z"]])
        place = np.array([P["place_x"], P["place_y"], P["place_z"]])
        clear, speed = P["clearance"], P["speed"]
        pose = np.zeros(3)
        plan = _Legs(self.wheels, self.arm_joints, *self.hold)
        segments: list[tuple[str, float, float]] = []

        profile: list[dict[str, float]] = []  # the base's legs, for its feedback loop

        def base_legs(legs: list, arm_q: np.ndarray) -> None:
            for kind, amount in legs:
                t0 = plan.now
                if kind == "turn":
                    cmd = self._turn_command(amount)
                    try:
                        tr = self.base.run(
                            "turning", angle=cmd, seconds=self._turn_seconds(cmd, speed)
                        )
                    except ValueError:  # too quick for the wheels: their own shortest
                        tr = self.base.run("turning", angle=cmd)
                    wv = self._wheel_block(tr, "velocities")
                    plan.base(tr.times, self._wheel_block(tr), wv, arm_q)
                    own = tr.info.get("feedback") or {}
                    profile.append(dict(own.get("profile") or {}) | {"t0": t0})
                else:
                    cmd = self._travel_command(amount, speed)
                    t, q, v = self._drive(cmd, speed)
                    plan.base(t, q, v, arm_q)
                    profile.append({"t0": t0, "distance": cmd, "seconds": float(t[-1])})
                segments.append((kind, t0, plan.now))

        def arm_leg(name: str, traj: Trajectory, reverse: bool = False, gripper=None) -> None:
            q, v = self._arm_block(traj), self._arm_block(traj, "velocities")
            qp, a = self._arm_block(traj, "planned"), self._arm_block(traj, "accelerations")
            t = traj.times
            if reverse:  # time reversed: velocities change sign, accelerations do not
                t, q, v, qp, a = t[-1] - t[::-1], q[::-1], -v[::-1], qp[::-1], a[::-1]
            if gripper is not None:
                q, v, qp, a = q.copy(), v.copy(), qp.copy(), a.copy()
                q[:, -1], qp[:, -1] = gripper
                v[:, -1] = a[:, -1] = 0.0
            self._check_tip(f"pick-and-place ({name})", qp)
            jump = float(np.max(np.abs(qp[0, :-1] - plan.arm_now[1][:-1])))
            if jump > MAX_JUMP:  # the arm's solutions of one pose differ: no leg joins them
                raise ValueError(
                    f"pick-and-place ({name}): the arm would jump {jump:.3g} rad between "
                    "two legs (its solutions of one pose differ); choose other targets"
                )
            t0 = plan.now
            plan.arm(t, q, v, qp, a)
            segments.append((name, t0, plan.now))

        legs, pose, grasp = self._go_to(pose, pick, clear, speed, "object")
        base_legs(legs, self.hold)
        arm_leg("grasp", grasp)
        closed = (
            float(self._arm_block(grasp)[-1, -1]),
            float(self._arm_block(grasp, "planned")[-1, -1]),
        )
        lifted = self._arm_frame(pose, pick) + np.array([0.0, 0.0, clear])
        back = self.arm.run("positioning", x=lifted[0], y=lifted[1], z=lifted[2])
        arm_leg("stow", back, reverse=True, gripper=closed)
        carry = plan.arm_now
        legs, pose, put = self._go_to(pose, place, clear, speed, "place target")
        base_legs(legs, carry)
        above = self._arm_frame(pose, place) + np.array([0.0, 0.0, clear])
        out = self.arm.run("positioning", x=above[0], y=above[1], z=above[2])
        arm_leg("reach", out, gripper=closed)
        start = plan.now
        arm_leg("put", put, reverse=True)
        # the reverse of grasping: the gripper has opened on the target where grasping
        # began to close it
        close = next(s for s in put.info["segments"] if s[0] == "close")  # type: ignore[union-attr]
        placed_at = start + put.duration - float(close[1])
        t, pos, vel, planned, acc = plan.arrays()
        info: dict[str, object] = {
            "motion": "place",
            "target": tuple(float(c) for c in place),
            "pick": tuple(float(c) for c in pick),
            "placed_at_s": round(placed_at, 9),
            "tool_body": self.chain.body(str(put.info.get("tool_body", "gripper_link"))),
            "segments": tuple(segments),
            "base_end_pose": tuple(float(c) for c in pose),
            "locomotion": "wheeled",
            "body_length_m": self.base.body_length,
            "min_tip_margin_m": round(
                float(self.tip_margin(planned[:, len(self.wheels) :]).min()), 6
            ),
            "planned_positions": planned,
            "accelerations": acc,
        }
        info.update(self._base_feedback({"legs": profile}))
        return Trajectory("pick-and-place", t, self.joints, pos, vel, info)


class _Legs:
    """Samples of a composed trajectory, the wheels' columns then the arm's: times s,
    positions and velocities as commanded, the planned positions (no droop compensation)
    and the accelerations."""

    def __init__(
        self, wheels: Sequence[str], arm: Sequence[str], hold: np.ndarray, planned: np.ndarray
    ) -> None:
        self.nw = len(wheels)
        n = self.nw + len(hold)
        self.t = [np.zeros(1)]
        self.q = [np.concatenate([np.zeros(self.nw), hold])[None]]
        self.v = [np.zeros((1, n))]
        self.p = [np.concatenate([np.zeros(self.nw), planned])[None]]
        self.a = [np.zeros((1, n))]

    @property
    def now(self) -> float:
        return float(self.t[-1][-1])

    @property
    def arm_now(self) -> tuple[np.ndarray, np.ndarray]:
        """The arm's last (commanded, planned) positions."""
        return self.q[-1][-1, self.nw :].copy(), self.p[-1][-1, self.nw :].copy()

    def _add(self, t, q, v, p, a) -> None:
        self.t.append(self.now + t[1:])
        for series, x in ((self.q, q), (self.v, v), (self.p, p), (self.a, a)):
            series.append(x[1:])

    def base(self, t, wq, wv, arm_q: tuple[np.ndarray, np.ndarray]) -> None:
        """A leg of the wheels (positions from 0) with the arm held at ``arm_q``
        (commanded, planned)."""
        w0 = self.q[-1][-1, : self.nw]
        n = len(t)
        held, planned = arm_q
        still = np.zeros((n, len(held)))
        wa = np.gradient(wv, t, axis=0)
        self._add(
            t,
            np.hstack([w0 + wq, np.tile(held, (n, 1))]),
            np.hstack([wv, still]),
            np.hstack([w0 + wq, np.tile(planned, (n, 1))]),
            np.hstack([wa, still]),
        )

    def arm(self, t, aq, av, ap, aa) -> None:
        """A leg of the arm with the wheels standing still."""
        w0 = self.q[-1][-1, : self.nw]
        n = len(t)
        still = np.zeros((n, self.nw))
        wheels = np.tile(w0, (n, 1))
        self._add(
            t,
            np.hstack([wheels, aq]),
            np.hstack([still, av]),
            np.hstack([wheels, ap]),
            np.hstack([still, aa]),
        )

    def arrays(self):
        return tuple(np.concatenate(x) for x in (self.t, self.q, self.v, self.p, self.a))


def _standing_height(template) -> float:
    """m: the root's height above the floor when the wheels (or the feet) stand on it
    (their lowest rim points, or the foot points, on z = 0, as the MJCF spawns the robot);
    0 for a stationary base."""
    m = template.model
    T = forward_kinematics(m, np.zeros(m.nv))
    r = float(template.params.wheel_radius)
    if template.feet and not template.wheels:
        return max(
            -float((T[m.body(f)] @ np.append(p, 1.0))[2])
            for f, p in zip(template.feet, template.foot_points, strict=True)
        )
    return max((r - float(T[m.body(w), 2, 3]) for w in template.wheels), default=0.0)


def _params(geometry: DesignGeometry, payload: float = 0.0):
    return TemplateParams(
        lengths=geometry.lengths,
        modules=geometry.modules,
        wheel_radius=geometry.wheel_radius,
        payload=payload,
    )


def _joint_origin(template, joint: str) -> np.ndarray:
    """(3,) m: where ``joint`` sits in the template's root frame at q = 0."""
    m = template.model
    j = m.joints[m.joint(joint)]
    T = forward_kinematics(m, np.zeros(m.nv))
    return (T[j.parent] @ j.origin)[:3, 3]


def _integral(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    steps = (v[1:] + v[:-1]) / 2 * np.diff(t)[:, None]
    return np.vstack([np.zeros((1, v.shape[1])), np.cumsum(steps, axis=0)])


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull (k, 2), counter-clockwise, of ``points`` (n, 2) (monotone chain)."""
    pts = sorted({(round(float(x), 12), round(float(y), 12)) for x, y in points})
    if len(pts) < 3:
        raise ValueError("the base stands on fewer than three points: no support polygon")

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])
