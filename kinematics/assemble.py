"""One assembler for every robot: a body plan (the ontology's parts and how they connect)
and the part kinds' data (``kinematics/partkinds.toml``) -> a kinematic :class:`Template`.

The walk starts at the plan's root part (its body is welded to the world: the fixed joint
``root``) and attaches each child where its parent's mount pattern puts it (legs along both
sides of a trunk, wheels in axles, an arm's joints one after the other). A part's joints
follow each other, each at the end of the previous one's printed tube (or at the previous
joint when it has none). Names are made from the part kinds' joint names with the prefix
the layout gives (``lf_coxa``, ``l_hip_yaw``, ``front_left_wheel``) or the chain index
(``joint_3``); a serial arm's joints are named from the ``[serial]`` table. Nothing here
knows a robot type by its name.

Errors are :class:`AssemblyError` (a ValueError) naming the part and the ontology location
(``where``) of the axiom that declared it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np

from kinematics.bodyplan import BodyPlan, PartNode
from kinematics.partkinds import AXES, KindJoint, Mount, PartKind, PartKinds, _names, evaluate
from kinematics.spatial import (
    box_inertia,
    rot_x,
    rot_z,
    sphere_inertia,
    transform,
    transform_from,
    tube_inertia,
)
from kinematics.templates import (
    _BACK,
    _DOWN,
    _UP,
    WHEEL_WIDTH,
    LabelledPart,
    Template,
    TemplateParams,
    _bearing_on_parent,
    _Builder,
    _frozen,
    _gripper_parts,
    _point,
    _servos_on_chassis,
    _trunk,
    check_params,
)

__all__ = ["AssemblyError", "assemble", "length_defaults"]

_FACES = {"up": _UP, "down": _DOWN, "back": _BACK}
_SIDE_WORDS = {1: "l", -1: "r"}
_POSITIONS = {1: ("m",), 2: ("f", "h"), 3: ("f", "m", "h")}
_AXLES = {1: ("",), 2: ("front", "rear"), 3: ("front", "middle", "rear")}
#: Roles of the parts that form chains (one joint or one printed link each).
_CHAIN = ("joint", "link", "module")
#: Roles of limbs placed by a mount of another class of the same role when no mount names
#: their own class.
_BY_ROLE = ("leg", "wheel", "arm")


class AssemblyError(ValueError):
    """A body plan the part kinds cannot assemble."""


def _where(node: PartNode) -> str:
    return f" ({node.where})" if node.where else ""


@dataclass
class _Rec:
    """One joint (and its body) to add, in order."""

    name: str
    body: str
    parent: int | None  # index of the parent record; None: the root body
    kind: str
    origin: np.ndarray
    axis: np.ndarray
    limits: tuple[float, float]
    group: str
    tube: tuple[str, str, np.ndarray] | None = None  # (segment name, length name, direction)
    end: str = ""
    forward: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    on_parent: bool = False
    module: str = ""
    passive: bool = False
    tool: tuple[float, tuple[float, float, float], float] | None = None  # length, box, kg
    wheel_width: float | None = None  # the wheel kind's own width, m
    plate: LabelledPart | None = None  # a carried root part's plate (end "plate")


@dataclass
class _Tip:
    """Where a child attaches: the record of the body (None: the root), the frame there
    (body frame), the prefix of names and the direction the chain points."""

    rec: int | None
    frame: np.ndarray
    prefix: str
    forward: np.ndarray


def _kind(kinds: PartKinds, node: PartNode) -> PartKind:
    k = kinds.of(node.kinds)
    if k is None:
        raise AssemblyError(
            f"part {node.kind}{_where(node)}: no part kind describes it (neither it nor a "
            f"class above it: {', '.join(node.kinds)}); add one to a part kinds file "
            "(--parts) or use a part class that has one"
        )
    return k


def _ordered_children(
    node: PartNode, kind: PartKind, kinds: PartKinds
) -> list[tuple[PartNode, Mount | None]]:
    """The children of ``node`` with the mount that places each, in assembly order: by
    the kind's mounts in order (children of a kind with no mount: last, at the tip)."""
    out: list[tuple[PartNode, Mount | None]] = []
    rest = list(node.children)
    for m in kind.mounts:
        mine = [c for c in rest if m.child in c.kinds]
        rest = [c for c in rest if m.child not in c.kinds]
        out += [(c, m) for c in mine]
    # a limb of a class no mount names (a user's own leg class beside MultipedLeg) goes
    # where the first mount of a limb of its role goes (its layout, span and track)
    for m in kind.mounts:
        mk = kinds.of((m.child,))
        if mk is None or mk.role not in _BY_ROLE:
            continue
        mine = [c for c in rest if (k := kinds.of(c.kinds)) is not None and k.role == mk.role]
        rest = [c for c in rest if c not in mine]
        out += [(c, m) for c in mine]
    out += [(c, None) for c in rest]
    return out


def wheel_size(
    plan: BodyPlan, kinds: PartKinds, lengths: dict[str, float], what: str = "radius"
) -> tuple[float | None, str]:
    """(the wheel ``what`` (radius or width) m its wheel kinds give, where: the kind's
    file and key), or (None, "") when none gives one; AssemblyError when two wheel kinds
    give different values (a design has one wheel size)."""
    found: dict[float, str] = {}

    def visit(node: PartNode) -> None:
        kind = _kind(kinds, node)
        if kind.end == "wheel" and what in kind.wheel:
            names = {**kinds.constants, **lengths, "pi": math.pi}
            try:
                r = evaluate(kind.wheel[what], names)
            except (KeyError, ValueError, ZeroDivisionError) as e:
                raise AssemblyError(f"{kind.where}: wheel.{what}: unknown length {e}") from None
            if not (math.isfinite(r) and r > 0):
                raise AssemblyError(f"{kind.where}: wheel.{what}: {r} m must be positive")
            found.setdefault(r, f"{kind.where}: wheel.{what}")
        for c in node.children:
            visit(c)

    visit(plan.root)
    if len(found) > 1:
        raise AssemblyError(
            f"{plan.robot_type}: its wheel kinds give different wheel {what}s ("
            + "; ".join(f"{w} = {r * 1000:.1f} mm" for r, w in found.items())
            + f"); a design has one wheel {what}"
        )
    return next(iter(found.items()), (None, ""))


def unused_lengths(plan: BodyPlan, kinds: PartKinds) -> tuple[str, ...]:
    """The named lengths of the plan's part kinds (``lengths``) and of its ontology
    (``defaultLength``) that nothing of its kinds uses: no box, place, limit, tube or wheel
    size names them (a ``foot_plate`` end uses ``foot``; a serial arm, its links). A value
    given and not used is reported, never dropped in silence."""

    used: set[str] = set()
    given: list[str] = []

    def names(*xs) -> None:
        for x in xs:
            if x != "":
                used.update(_names(x))

    def visit(node: PartNode) -> None:
        kind = _kind(kinds, node)
        given.extend(k for k in kind.lengths if k not in given)
        names(*kind.box, *kind.at, *(x for v in kind.at_with.values() for x in v))
        names(*kind.wheel.values())
        for j in kind.joints:
            names(*j.limits)
            if j.tube_length:
                used.add(j.tube_length)
        for m in kind.mounts:
            names(m.span, m.track, *m.at)
        if kind.end == "foot_plate":
            used.add("foot")
        for c in node.children:
            visit(c)

    visit(plan.root)
    for chain in serial_links(plan, kinds):
        used.update(chain)
    given.extend(k for k in plan.lengths if k not in given)
    return tuple(k for k in given if k not in used)


def length_defaults(plan: BodyPlan, kinds: PartKinds) -> dict[str, float]:
    """The plan's named lengths with their defaults (m), in the order a template lists
    them: the root's, then each part's in assembly order; the ontology's
    ``defaultLength`` values (``plan.lengths``) win."""
    out: dict[str, float] = {}
    stack = [plan.root]  # depth first, iterative: a chain of parts is as deep as it is long
    while stack:
        node = stack.pop()
        kind = _kind(kinds, node)
        for k, v in kind.lengths.items():
            out.setdefault(k, v)
        for j in kind.joints:
            if j.tube_length and j.tube_length not in out:
                out[j.tube_length] = kind.lengths.get(j.tube_length, 0.0)
        stack.extend(reversed([c for c, _ in _ordered_children(node, kind, kinds)]))
    for chain in serial_links(plan, kinds):  # a serial arm's links, after the parts'
        for k, name in enumerate(chain):
            pick = "first" if k == 0 else "rest"
            out.setdefault(name, kinds.serial_lengths.get(pick, 0.1))
    for k in out:
        if k in plan.lengths:
            out[k] = float(plan.lengths[k])
    return out


class _Walk:
    def __init__(self, plan: BodyPlan, kinds: PartKinds, p: TemplateParams, lengths: dict):
        self.plan, self.kinds, self.p, self.L = plan, kinds, p, lengths
        self.names = {
            **kinds.constants,
            **lengths,
            "actuator_x": float(p.actuator_size[0]),
            "actuator_y": float(p.actuator_size[1]),
            "actuator_z": float(p.actuator_size[2]),
            "wheel_radius": float(p.wheel_radius),
        }
        self.recs: list[_Rec] = []
        self.legs = 0
        self.payload_at_effector = False
        self.grips = False
        self.link_index = 0

    def ev(self, x, node: PartNode, what: str) -> float:
        try:
            return evaluate(x, self.names)
        except KeyError as e:
            kind = self.kinds.of(node.kinds)  # the file and the kind that give the value
            given = f"{kind.where}: " if kind is not None and kind.where else ""
            raise AssemblyError(
                f"{given}part {node.kind}{_where(node)}: its {what} names {e.args[0]!r}, "
                "which is no length of this design nor a constant of the part kinds"
            ) from None

    # -- the root -----------------------------------------------------------------------
    def centre_and_box(self, node: PartNode, kind) -> tuple[tuple, tuple]:
        """A root part's body centre (its kind's ``at``, or ``at_with`` the class of a part
        it carries) and box, evaluated for this design."""
        at = kind.at
        for c in node.children:
            for cls, v in kind.at_with.items():
                if cls in c.kinds:
                    at = v
        centre = tuple(self.ev(x, node, "at") for x in at)
        return centre, tuple(self.ev(x, node, "box") for x in kind.box)

    def root(self) -> list[LabelledPart]:
        node = self.plan.root
        kind = _kind(self.kinds, node)
        if not kind.root:
            raise AssemblyError(
                f"{self.plan.robot_type}: its body plan's root {node.kind}{_where(node)} is "
                "not a part the others can hang on (no root part kind)"
            )
        self.root_at, box = self.centre_and_box(node, kind)
        parts = [_trunk(kind.body, self.p.trunk_mass, box, self.root_at, _FACES[kind.faces])]
        # an arm's gripper holds the payload wherever the arm stands (each gripper of a
        # plan with several); a chain ending in a tool or nothing (a head) carries it only
        # on a base that says so (an arm's base), else it rides on the root
        found = [k for n in node.walk() if (k := self.kinds.of(n.kinds)) is not None]
        chains = any(k.role == "joint" for k in found)
        #: the plan's chains hold grippers: they hold the payload (a tool's tip does not)
        self.grips = chains and any(k.end == "gripper" for k in found)
        if kind.payload == "root" and not self.grips:
            parts.append(_point(kind.body, "payload", self.p.payload, self.root_at))
        else:
            self.payload_at_effector = True
        self.root_body = kind.body
        tip = _Tip(None, np.eye(4), "", np.array([1.0, 0.0, 0.0]))
        self.children(node, kind, tip, placed=True)
        return parts

    # -- children -----------------------------------------------------------------------
    def children(self, node: PartNode, kind: PartKind, tip: _Tip, placed: bool) -> None:
        """Attach ``node``'s children: by its mounts when ``placed`` (the layouts), else
        at ``tip``."""
        ordered = _ordered_children(node, kind, self.kinds)
        chain = [c for c, _ in ordered if _kind(self.kinds, c).role in _CHAIN]
        others = [(c, m) for c, m in ordered if c not in chain]
        jobs: list[tuple[int, int, PartNode, _Tip]] = []  # (side, order, node, tip)
        by_mount: dict[int, list[PartNode]] = {}
        mounts: dict[int, Mount | None] = {}
        for c, m in others:
            key = id(m) if m is not None else 0
            by_mount.setdefault(key, []).append(c)
            mounts[key] = m
        order = 0
        riders: list[tuple[PartNode, Mount]] = []  # root parts standing on this one
        for key, group in by_mount.items():
            m = mounts[key]
            if placed and m is not None and m.layout == "top":
                riders += [(c, m) for c in group]
                continue
            if placed and m is not None and m.layout not in ("serial", "tip"):
                places = self.layout(m, group, node)
            else:
                places = [(0, tip.prefix, tip.frame) for _ in group]
            for c, (side, prefix, frame) in zip(group, places, strict=True):
                jobs.append((side, order, c, _Tip(tip.rec, frame, prefix, tip.forward)))
                order += 1
        if kind.order == "side":
            jobs.sort(key=lambda j: (-j[0], j[1]))
        for _, _, c, t in jobs:
            self.part(c, t)
        for c, m in riders:
            self.rider(c, m, node, tip)
        # the chains, by the mount that places them: one chain where the mount's ``at``
        # says; several spread across the part (a serial mount) or where its layout puts
        # them (a pair: at the shoulders), each named with its place's prefix
        groups: dict[int, tuple[Mount | None, list[PartNode]]] = {}
        for c in chain:
            m = next((m for c2, m in ordered if c2 is c), None)
            groups.setdefault(id(m) if m is not None else 0, (m, []))[1].append(c)
        for m, group in groups.values():
            if not (placed and m is not None):
                self.serial(node, group, tip, m.links if m is not None else "")
                continue
            if m.layout == "serial":
                places = self.spread(m, group, node)
            else:
                places = [(prefix, frame) for _, prefix, frame in self.layout(m, group, node)]
            for c, (prefix, frame) in zip(group, places, strict=True):
                name = f"{tip.prefix}_{prefix}" if tip.prefix and prefix else prefix or tip.prefix
                self.serial(node, [c], _Tip(tip.rec, tip.frame @ frame, name, tip.forward), m.links)

    def spread(self, m: Mount, group: list[PartNode], parent: PartNode):
        """(name prefix, frame on the parent) of each chain a serial mount carries: one at
        the mount's ``at``; several side by side across the part (y), the first on the
        left, ``track`` apart from the first to the last, named l, r (two), l, m, r (three)
        or c1, c2 ... (more)."""
        at = tuple(self.ev(x, parent, "mount at") for x in m.at)
        n = len(group)
        if n == 1:
            return [("", transform(at))]
        if not m.track:
            raise AssemblyError(
                f"part {group[1].kind}{_where(group[1])}: {parent.kind} carries {n} chains "
                f"on one serial mount of {m.child}, which has no `track` to spread them "
                "across the part; give the mount a track (m) in a part kinds file (--parts)"
            )
        track = self.ev(m.track, parent, "mount track")
        words = {2: ("l", "r"), 3: ("l", "m", "r")}.get(n, tuple(f"c{i + 1}" for i in range(n)))
        out = []
        for i in range(n):
            y = track / 2 - track * i / (n - 1)
            out.append((words[i], transform((at[0], at[1] + y, at[2]))))
        return out

    def layout(self, m: Mount, group: list[PartNode], parent: PartNode):
        """(side, name prefix, frame on the parent) of each child of a mount."""
        n = len(group)
        span = self.ev(m.span, parent, "mount span") if m.span else 0.0
        track = self.ev(m.track, parent, "mount track") if m.track else 0.0
        out = []
        if m.layout == "bilateral" and n % 2 == 0:
            k = n // 2
            letters = _POSITIONS.get(k, tuple(str(i + 1) for i in range(k)))
            for side in (1, -1):
                for i in range(k):
                    fx = 1 - 2 * i / (k - 1) if k > 1 else 0.0
                    xyz = (fx * span / 2, side * track / 2, 0)
                    frame = transform_from(rot_z(side * math.pi / 2), xyz)
                    out.append((side, f"{_SIDE_WORDS[side]}{letters[i]}", frame))
        elif m.layout in ("bilateral", "radial"):
            for i in range(n):
                th = 2 * math.pi * i / n
                xyz = (span / 2 * math.cos(th), track / 2 * math.sin(th), 0.0)
                side = 1 if math.sin(th) > 1e-12 else (-1 if math.sin(th) < -1e-12 else 0)
                out.append((side, f"leg{i + 1}", transform_from(rot_z(th), xyz)))
        elif m.layout == "pair":
            if n != 2:
                raise AssemblyError(
                    f"part {group[0].kind}{_where(group[0])}: a pair layout takes 2, got {n}"
                )
            at = [self.ev(x, parent, "mount at") for x in m.at]
            for side in (1, -1):
                out.append((side, _SIDE_WORDS[side], transform((at[0], side * at[1], at[2]))))
        elif m.layout == "axle":
            if n % 2:
                raise AssemblyError(
                    f"part {group[0].kind}{_where(group[0])}: wheels on axles come in pairs, "
                    f"got {n}"
                )
            a = n // 2
            words = _AXLES.get(a, tuple(f"axle{i + 1}" for i in range(a)))
            for i in range(a):
                fx = 1 - 2 * i / (a - 1) if a > 1 else 0
                for side in (1, -1):
                    name = "left" if side > 0 else "right"
                    prefix = f"{words[i]}_{name}" if words[i] else name
                    out.append((side, prefix, transform((fx * span / 2, side * track / 2, 0))))
        elif m.layout == "front":
            if n > 2:
                raise AssemblyError(
                    f"part {group[0].kind}{_where(group[0])}: a front layout takes one wheel "
                    f"or a pair, got {n}"
                )
            x = self.root_at[0] + span / 2
            if n == 1:
                out.append((0, "front", transform((x, 0, 0))))
            else:
                for side in (1, -1):
                    name = "left" if side > 0 else "right"
                    out.append((side, f"front_{name}", transform((x, side * track / 2, 0))))
        elif m.layout == "trailing":
            rear = (self.root_at[0] - span / 2, 0, -float(self.p.wheel_radius))
            for i in range(n):
                out.append((0, "" if n == 1 else f"rear{i + 1}", transform(rear)))
        else:  # pragma: no cover (LAYOUTS is checked when the data is read)
            raise AssertionError(m.layout)
        return out

    # -- a root part carried by another (a torso on a chassis) -------------------------
    def rider(self, node: PartNode, m: Mount, parent: PartNode, tip: _Tip) -> None:
        """A root part standing on its carrier at the ``top`` mount's ``at``: its body fixed
        there (a printed plate of its box's face, as the root's: ``faces`` says which),
        its children attached by its own mounts."""
        kind = _kind(self.kinds, node)
        if not kind.root:
            raise AssemblyError(
                f"part {node.kind}{_where(node)}: a top mount carries a root part (a torso "
                "on a chassis); this one has no root part kind"
            )
        centre, box = self.centre_and_box(node, kind)
        R = _FACES[kind.faces]
        plate = _trunk(kind.body, 0.0, box, centre, R)
        dims = plate.dims
        mass = float(dims[0] * dims[1] * self.p.face_thickness * self.p.density)
        plate = replace(_trunk(kind.body, mass, box, centre, R), kind="plate")
        frame = tip.frame @ transform(tuple(self.ev(x, parent, "mount at") for x in m.at))
        self.recs.append(
            _Rec(
                name=f"{kind.body}_mount",
                body=kind.body,
                parent=tip.rec,
                kind="fixed",
                origin=frame,
                axis=np.array([0.0, 0.0, 1.0]),
                limits=(0.0, 0.0),
                group="",
                end="plate",
                forward=tip.forward,
                plate=plate,
            )
        )
        here = _Tip(len(self.recs) - 1, np.eye(4), tip.prefix, tip.forward)
        self.children(node, kind, here, placed=True)

    # -- a part with joints -----------------------------------------------------------
    def part(self, node: PartNode, tip: _Tip) -> None:
        kind = _kind(self.kinds, node)
        if kind.root:
            raise AssemblyError(
                f"part {node.kind}{_where(node)}: a second root part in the body plan of "
                f"{self.plan.robot_type}; one part (a trunk, chassis or base) carries the rest"
            )
        if kind.role == "leg":
            self.legs += 1
        if kind.end == "tool":  # no joints: fixed on the chain's end, its origin the tip
            if node.children:
                raise AssemblyError(
                    f"part {node.children[0].kind}{_where(node.children[0])}: it is connected "
                    f"to the tool {node.kind}, which ends its chain (a tool has no joints; "
                    "nothing is mounted on it)"
                )
            self.fixed_end(tip, "tool", node, kind)
            return
        here = tip
        for j in kind.joints:
            here = self.joint(node, kind, j, here, index=None)
        self.children(node, kind, here, placed=False)

    def joint(
        self,
        node: PartNode,
        kind: PartKind,
        j: KindJoint,
        tip: _Tip,
        index: int | None,
        serial: tuple[str, str, float | str, float | str] | None = None,
        link: tuple[str, np.ndarray] | None = None,
        axis_index: int = 0,
    ) -> _Tip:
        """Add joint ``j`` of ``node`` at ``tip``; the tip after it."""
        base = serial[0] if serial else j.name
        if index is not None:
            name = f"{base}_{index}"
            body = f"{j.body or base}_{index}" if j.body else f"{name}_link"
        else:
            name = f"{tip.prefix}_{base}" if tip.prefix else base
            body = f"{name}_link"
        if j.axes:
            axis = np.array(AXES[j.axes[axis_index % len(j.axes)]])
        elif serial:
            axis = np.array(AXES[serial[1]])
        elif j.axis == "across":
            side = np.array([0.0, 1.0, 0.0])
            axis = np.cross(tip.forward, side)
            if np.linalg.norm(axis) < 1e-9:
                axis = np.cross(tip.forward, np.array([0.0, 0.0, 1.0]))
            axis = axis / np.linalg.norm(axis) + 0.0
        else:
            axis = np.array(AXES[j.axis])
        lim = (serial[2], serial[3]) if serial else j.limits
        limits = (self.ev(lim[0], node, "joint limit"), self.ev(lim[1], node, "joint limit"))
        tube = None
        forward = tip.forward
        if j.tube_length:
            d = np.array(AXES[j.tube_along])
            seg = (
                body
                if index is not None
                else (f"{tip.prefix}_{j.tube_length}" if tip.prefix else j.tube_length)
            )
            tube = (seg, j.tube_length, d)
            forward = d
        elif link is not None:  # a chain's printed link: its length shared by alike chains
            tube = (f"{tip.prefix}_{link[0]}" if tip.prefix else link[0], link[0], link[1])
            forward = link[1]
        rec = _Rec(
            name=name,
            body=body,
            parent=tip.rec,
            kind=j.kind,
            origin=tip.frame,
            axis=axis,
            limits=limits,
            group=j.group or base,
            tube=tube,
            end=kind.end if j is kind.joints[-1] else "",
            forward=forward,
            on_parent=j.actuator_on_parent,
            passive=j.passive,
        )
        rec.module = j.module
        if rec.end == "wheel" and "width" in kind.wheel:
            rec.wheel_width = self.ev(kind.wheel["width"], node, "wheel width")
        self.recs.append(rec)
        k = len(self.recs) - 1
        frame = transform(self.L[tube[1]] * tube[2]) if tube else np.eye(4)
        return _Tip(k, frame, tip.prefix, forward)

    def fixed_end(
        self, tip: _Tip, end: str, node: PartNode | None = None, kind: PartKind | None = None
    ) -> None:
        """A body fixed on the chain's end at ``tip``: a tool (``end`` "tool": its box
        reaching along the chain, the body's origin at its far end, the point it places)
        or the bare end of an arm with nothing at its tip ("tip": the end of its last
        link)."""
        frame, tool = tip.frame, None
        if kind is not None and node is not None:
            dims = tuple(self.ev(x, node, "box") for x in kind.box)
            if not all(d > 0 for d in dims):
                raise AssemblyError(f"part {node.kind}{_where(node)}: its box must be positive")
            tool = (dims[0], (dims[0], dims[1], dims[2]), kind.mass)
            frame = frame @ transform(tuple(dims[0] * tip.forward))
        name = f"{tip.prefix}_{end}" if tip.prefix else end
        self.recs.append(
            _Rec(
                name=name,
                body=f"{name}_link",
                parent=tip.rec,
                kind="fixed",
                origin=frame,
                axis=np.array([0.0, 0.0, 1.0]),
                limits=(0.0, 0.0),
                group="",
                end=end,
                forward=tip.forward,
                tool=tool,
            )
        )

    # -- chains of one-joint parts (a snake's modules, an arm's servos and links) -------
    def serial(self, parent: PartNode, first: list[PartNode], tip: _Tip, names: str = "") -> None:
        if len(first) > 1:
            raise AssemblyError(
                f"part {first[1].kind}{_where(first[1])}: {parent.kind} has more than one "
                "chain of modules connected to it; a chain starts at one connector (only a "
                "root part's mount carries several chains: a serial mount with a track, or "
                "a pair)"
            )
        chain: list[PartNode] = []
        node = first[0]
        while True:
            chain.append(node)
            nxt = [c for c in node.children if _kind(self.kinds, c).role in _CHAIN]
            if len(nxt) > 1:
                raise AssemblyError(
                    f"part {nxt[1].kind}{_where(nxt[1])}: {node.kind} connects to two "
                    "modules of a chain; a serial chain has no branches"
                )
            if not nxt:
                break
            node = nxt[0]
        joints = [n for n in chain if not _kind(self.kinds, n).link]
        ext = [n for n in joints if any(k in self.plan.extensible for k in n.kinds)]
        if ext:
            m = self.p.modules
            if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
                raise ValueError(f"modules must be an integer >= 1, got {m!r}")
            chain = [joints[0]] * int(m)
            joints = chain
        lifted = self.p.lifted
        if 0 < lifted < len(chain) and all(_kind(self.kinds, n).role == "module" for n in chain):
            chain = joints = chain[:lifted]  # the lifted segment of a module chain
        serial_rows = None
        if any(
            _kind(self.kinds, n).joints[0].name == "serial"
            for n in joints
            if _kind(self.kinds, n).joints
        ):
            n = len(joints)
            serial_rows = self.kinds.serial.get(n)
            if serial_rows is None:
                have = ", ".join(str(k) for k in sorted(self.kinds.serial))
                raise AssemblyError(
                    f"part {joints[0].kind}{_where(joints[0])}: a serial chain of {n} joints, "
                    f"but the part kinds' [serial] table has chains of {have} joints"
                )
        here = tip
        i = 0
        links = 0
        pos = 0
        # a chain of servos that names no printed link (the paper's manipulators): its
        # links go where the [serial] row marks them, as in an arm composed for N joints
        implied = _implied_link_kind(self.kinds, serial_rows, chain)
        hung = False
        while pos < len(chain):
            node = chain[pos]
            kind = _kind(self.kinds, node)
            if kind.link and not kind.joints:
                raise AssemblyError(
                    f"part {node.kind}{_where(node)}: a link with no joint before it "
                    f"(connected straight to {parent.kind})"
                )
            link = None
            row = serial_rows[i] if serial_rows is not None else None
            named = pos + 1 < len(chain) and bool(_kind(self.kinds, chain[pos + 1]).link)
            lk = _kind(self.kinds, chain[pos + 1]) if named else implied
            if lk is not None and (named or (row is not None and row[4])):
                links += 1
                d = np.array(AXES[lk.link.get("first" if links == 1 else "rest", "x")])
                link = (f"{names or lk.link.get('names', 'L')}{links}", d)
            spec = kind.joints[0]
            index = i + 1 if kind.naming == "index" else None
            here = self.joint(node, kind, spec, here, index, row, link, axis_index=i)
            i += 1
            pos += 2 if named else 1
            # what else hangs on this module (a gripper at the end of an arm)
            rest = [c for c in node.children if _kind(self.kinds, c).role not in _CHAIN]
            if named:
                rest += [
                    c for c in chain[pos - 1].children if _kind(self.kinds, c).role not in _CHAIN
                ]
            for c in rest:
                self.part(c, here)
            hung = bool(rest)
        if serial_rows is not None and not hung:  # an arm with nothing at its tip
            self.fixed_end(here, "tip")


def _check_unique(plan: BodyPlan, recs: list[_Rec]) -> None:
    """AssemblyError when two joints or bodies got one name: limbs that no mount of their
    parent places (each would hang at the same place, named alike)."""
    seen: set[str] = set()
    for r in recs:
        for name in (r.name, r.body):
            if name in seen:
                raise AssemblyError(
                    f"{plan.robot_type}: two parts would make the joint or body {name!r}: "
                    "several limbs hang on one part that has no mount for them (a part "
                    "kind's `mounts` places limbs by their class or their role: leg, wheel, "
                    "arm); give the parent part a mount for them in a part kinds file (--parts)"
                )
            seen.add(name)


def assemble(plan: BodyPlan, params: TemplateParams, kinds: PartKinds) -> Template:
    """The kinematic template of ``plan`` with ``params`` (see ``kinematics.templates``)."""
    p = params
    defaults = length_defaults(plan, kinds)
    lengths = check_params(plan.robot_type, p, defaults)
    w = _Walk(plan, kinds, p, lengths)
    root_parts = w.root()
    recs = w.recs
    _check_unique(plan, recs)
    b = _Builder(plan.robot_type, p, lengths)
    b.add("root", None, "fixed", np.eye(4), root_parts, body=w.root_body)
    feet: list[str] = []
    points: list[np.ndarray] = []
    wheels: list[str] = []
    casters: list[str] = []
    effectors: list[str] = []
    moved: dict[str, list[str]] = {}
    for k, r in enumerate(recs):
        parent = w.root_body if r.parent is None else recs[r.parent].body
        parts: list[LabelledPart] = []
        if r.tube is not None:
            distal = next((c.name for c in recs[k + 1 :] if c.parent == k), None)
            parts.append(b.tube(r.tube[0], r.tube[1], r.body, tuple(r.tube[2]), distal))
        end_point = r.tube[2] * lengths[r.tube[1]] if r.tube is not None else np.zeros(3)
        if r.end == "point_foot":
            foot = tuple(float(x) + 0.0 for x in end_point)
            parts.append(_point(r.body, "foot", p.foot_mass, foot))
            feet.append(r.body)
            points.append(_frozen(foot))
        elif r.end == "foot_plate":
            if "foot" not in lengths:
                raise AssemblyError(
                    f"{plan.robot_type}: a foot_plate end is a plate of the named length "
                    "`foot` (its width foot_width_ratio x it), but its part kinds have no "
                    "length `foot`; add `foot` to the leg kind's `lengths`"
                )
            sole = p.actuator_size[2] / 2
            c = kinds.constants
            plate = (lengths["foot"], c["foot_width_ratio"] * lengths["foot"], c["foot_plate"])
            parts.append(
                LabelledPart(
                    r.body,
                    "foot",
                    p.foot_mass,
                    np.array([0.0, 0.0, -sole + c["foot_plate"] / 2]),
                    box_inertia(p.foot_mass, plate),
                    transform((0, 0, -sole)),
                    plate,
                )
            )
            feet.append(r.body)
            points.append(_frozen((0.0, 0.0, -sole)))
        elif r.end == "gripper":
            payload = p.payload if w.payload_at_effector else 0.0
            parts += _gripper_parts(p, payload, r.body, tuple(r.forward), (0.0, 1.0, 0.0))
            effectors.append(r.body)
        elif r.end in ("tool", "tip"):
            if r.tool is not None:
                length, dims, mass = r.tool
                x = np.asarray(r.forward, dtype=float)
                side = np.array([0.0, 1.0, 0.0])
                if abs(float(x @ side)) > 0.9:
                    side = np.array([0.0, 0.0, 1.0])
                z = np.cross(x, side)
                z = z / np.linalg.norm(z)
                R = np.column_stack([x, np.cross(z, x), z])
                centre = -x * length / 2
                parts.append(
                    LabelledPart(
                        r.body,
                        "tool",
                        mass,
                        centre,
                        R @ box_inertia(mass, dims) @ R.T,
                        transform_from(R, centre),
                        dims,
                    )
                )
            if w.payload_at_effector and not w.grips:  # held at the tip
                parts.append(_point(r.body, "payload", p.payload, (0.0, 0.0, 0.0)))
            effectors.append(r.body)
        elif r.end == "plate" and r.plate is not None:
            parts.append(r.plate)
        elif r.end == "wheel":
            rr = p.wheel_radius
            if not (math.isfinite(rr) and rr > 0):
                raise ValueError(f"wheel_radius must be positive, got {rr}")
            ww = r.wheel_width or p.wheel_width or WHEEL_WIDTH
            inertia = tube_inertia(p.wheel_mass, ww, rr, 0, tuple(r.axis))
            frame = transform_from(rot_x(-math.pi / 2), (0, 0, 0))
            parts.append(
                LabelledPart(r.body, "wheel", p.wheel_mass, np.zeros(3), inertia, frame, (rr, ww))
            )
            wheels.append(r.body)
        elif r.end == "caster":
            rc = p.caster_radius
            parts.append(
                LabelledPart(
                    r.body,
                    "caster",
                    p.caster_mass,
                    np.array([0, 0, rc]),
                    sphere_inertia(p.caster_mass, rc),
                    transform((0, 0, rc)),
                    (rc,),
                )
            )
            casters.append(r.body)
        b.add(
            r.name,
            parent,
            r.kind,
            r.origin,
            parts,
            axis=tuple(r.axis),
            limits=r.limits,
            group=r.group if r.kind != "fixed" and not r.passive else "",
            body=r.body,
            passive=r.passive,
        )
        if r.on_parent:
            moved.setdefault(parent, []).append(r.body)
    for parent, bodies in moved.items():
        _servos_on_chassis(b, parent, tuple(bodies))
    for r in recs:
        if r.passive:
            _bearing_on_parent(b, r.body)
    model = b.model()
    tubes = sorted({s.length_name for s in b.segments})
    unknown = sorted(set(p.tubes) - set(tubes))
    if unknown:
        raise ValueError(
            f"{plan.robot_type} has no tube {', '.join(unknown)}; "
            f"tubes: {', '.join(tubes) or 'none'}"
        )
    passive = tuple(r.name for r in recs if r.passive)
    groups = {j.group for j in model.joints if j.movable and j.name not in passive}
    unknown = sorted(set(p.actuator_mass) - groups)
    if unknown:
        raise ValueError(
            f"{plan.robot_type} has no joint group {', '.join(unknown)}; "
            f"groups: {', '.join(sorted(groups))}"
        )
    modules = {r.name: r.module for r in recs}
    return Template(
        robot_type=plan.robot_type,
        model=model,
        segments=tuple(b.segments),
        end_effectors=tuple(effectors),
        feet=tuple(feet),
        foot_points=tuple(points),
        wheels=tuple(wheels),
        legs=w.legs,
        arms=len(effectors),
        length_names=tuple(defaults),
        casters=tuple(casters),
        lengths=lengths,
        params=p,
        parts=MappingProxyType(dict(b.parts)),
        modules=MappingProxyType({k: v for k, v in modules.items() if v}),
        plan=plan,
        passive=passive,
    )


#: The structures a body plan can have (what sizing and controllers are chosen by).
STRUCTURES = (
    "serial_arm",
    "multiped",
    "biped",
    "module_chain",
    "wheeled",
    "steered",
    "mobile_manipulator",
    "legged_manipulator",
    "multi_arm",
)


def structure_of(plan: BodyPlan, kinds: PartKinds) -> str:
    """What a body plan is, by the roles of its parts (never by its type's name): wheels
    on a chassis ("wheeled"; "steered" when a wheel part turns on a joint that is no
    wheel's: a steering joint), three or more legs ("multiped"), two legs ("biped"), a chain
    of modules ("module_chain"), a chain of joints on a fixed base ending in a gripper, a
    tool or nothing ("serial_arm"; several such chains: "multi_arm"), such chains on
    wheels ("mobile_manipulator") or on three or more legs ("legged_manipulator": a head
    or an arm on a multiped's trunk); "" for none of these (chains on two legs or on a
    module chain, arm parts of role "arm" anywhere but on a biped's torso)."""
    found = [kinds.of(n.kinds) for n in plan.root.walk()]
    roles = [(k.role if k is not None else "") for k in found]
    legs = roles.count("leg")
    chains = "joint" in roles  # arms, heads, tails: chains of joints, whatever ends them
    if "arm" in roles and legs != 2:  # a limb part of role arm (a HumanoidArm): only a
        return ""  # biped's torso carries one (its controller swings them)
    if "wheel" in roles and chains:  # arms on wheels
        return "mobile_manipulator"
    if "wheel" in roles:
        steered = any(
            k is not None and k.role == "wheel" and any(j.kind == "revolute" for j in k.joints)
            for k in found
        )
        return "steered" if steered else "wheeled"
    if legs >= 3:
        return "legged_manipulator" if chains else "multiped"
    if legs == 2:
        return "" if chains else "biped"
    if "module" in roles:
        return "" if chains else "module_chain"
    if chains:  # chains of joints on a fixed base, ending in a gripper, a tool or nothing
        return "multi_arm" if len(chain_starts(plan, kinds)) > 1 else "serial_arm"
    return ""


def chain_starts(plan: BodyPlan, kinds: PartKinds) -> list[PartNode]:
    """The first part of each chain of joints and links (an arm, a head, a tail), in the
    plan's depth-first order: a part of role joint or link whose parent has neither."""
    out: list[PartNode] = []
    stack: list[tuple[PartNode, bool]] = [(plan.root, False)]
    while stack:
        node, inside = stack.pop()
        k = kinds.of(node.kinds)
        here = k is not None and k.role in ("joint", "link")
        if here and not inside:
            out.append(node)
        stack.extend((c, here) for c in reversed(node.children))
    return out


def serial_links(plan: BodyPlan, kinds: PartKinds) -> list[list[str]]:
    """The length names of each serial chain's printed links, root to tip (an arm's
    column first), in assembly order."""
    return [c for c in _chains(plan, kinds) if c]


def _implied_link_kind(
    kinds: PartKinds, rows: tuple | None, chain: list[PartNode]
) -> PartKind | None:
    """The part kind of a printed link (one with a ``link`` table) to put where the
    ``[serial]`` ``rows`` mark a link, for a serial ``chain`` that names no link part of
    its own (the paper's manipulators: servos connectedTo servos); None otherwise."""
    if rows is None or any(_kind(kinds, n).link for n in chain):
        return None
    return next((k for k in kinds.kinds.values() if k.link and not k.joints), None)


def _chains(plan: BodyPlan, kinds: PartKinds) -> list[list[str]]:
    out: list[list[str]] = []
    nodes: list[list[PartNode]] = []  # the parts of each chain
    prefixes: list[str] = []
    # depth first, iterative (a chain of parts is as deep as it is long): each entry is a
    # part, the index of its chain (None: none; _NEW: a chain starts at it, as a recursive
    # walk would start it when it reaches the part) and the chain's link prefix
    stack: list[tuple[PartNode, int | None, str]] = [(plan.root, None, "")]
    while stack:
        node, at, prefix = stack.pop()
        if at == _NEW:
            out.append([])
            nodes.append([])
            prefixes.append(prefix)
            at = len(out) - 1
        kind = _kind(kinds, node)
        chain = out[at] if at is not None else None
        if chain is not None:
            nodes[at].append(node)
        if kind.link and chain is not None:
            chain.append(f"{prefix or kind.link.get('names', 'L')}{len(chain) + 1}")
        todo: list[tuple[PartNode, int | None, str]] = []
        for c, m in _ordered_children(node, kind, kinds):
            if _kind(kinds, c).role in _CHAIN:
                if chain is None or kind.role not in _CHAIN:
                    todo.append((c, _NEW, m.links if m is not None else ""))
                else:
                    todo.append((c, at, prefix))
            else:
                todo.append((c, None, ""))
        stack.extend(reversed(todo))
    for chain, parts, prefix in zip(out, nodes, prefixes, strict=True):
        joints = [n for n in parts if _kind(kinds, n).joints and not _kind(kinds, n).link]
        serial = any(_kind(kinds, n).joints[0].name == "serial" for n in joints)
        rows = kinds.serial.get(len(joints)) if serial else None
        lk = _implied_link_kind(kinds, rows, parts)
        if lk is not None and rows is not None:
            marked = sum(1 for r in rows if r[4])
            chain += [f"{prefix or lk.link.get('names', 'L')}{k + 1}" for k in range(marked)]
    return out


#: a part that starts a chain (``_chains``)
_NEW = -1
