"""A robot type's body plan read off the ontology (``kinematics.bodyplan.BodyPlan``).

The parts are the witnesses of the type's existential axioms and its ancestors' that are a
``part`` (or ``robotPart``, any subrelation of part) of the robot, with the counts the
ASP encoding gives them (``asp/parts.lp``): of each part class the largest count any
axiom declares, and a more specific class (``MyLeg`` where an ancestor says
``BipedLeg``) refines the general one. Witnesses of the same class in different axioms
are the same parts, in order (the humanoid's trunk, named by ``HumanoidRobot`` and by
``BipedalRobot``, is one trunk). ``connectedTo`` between witnesses joins parts; the tree
is rooted at the one part whose part kind is a root (a trunk, a chassis, an arm's base)
and grows away from it. A plan with several root parts joined by ``connectedTo`` (a torso
on a chassis) is one tree rooted at the one whose part kind mounts the others (a ``top``
mount) and none of theirs it. Parts the axioms do not connect to anything hang on the root (the
part kinds' mount patterns place them). Only parts with a part kind (or structural parts,
which must have one) enter the plan: the main module, the battery and sensors ride on
the root and are counted by the conceptual design.

``(defaultLength ROBOT "name" "quantity")`` gives a length's default for a type and its
subclasses (the nearest class's wins); ``extensiblePart`` marks the classes whose chains
grow with the design (a snake's modules).

Refusals (``OntologyError``, exit 2) name the part and the axiom's file:line:col: a part
kind no data describes, a ``connectedTo`` cycle, a body plan with no root, root parts
that no ``connectedTo`` joins or whose kinds do not say which carries the others, parts
not connected to the root.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from adron.errors import InputError, OntologyError
from adron.kb import load
from adron.schema import MAX_LENGTH_M
from adron.units import quantity
from kinematics.bodyplan import PLAN_SOURCE, BodyPlan, PartNode
from kinematics.partkinds import in_use
from kinematics.partkinds import load as load_kinds
from synth.params import ontology_defaults, structure_defaults

if TYPE_CHECKING:  # imported where used: importing this module stays cheap (install())
    from adron.kb import KnowledgeBase
    from kinematics.partkinds import PartKinds

__all__ = ["ancestors", "plan_of"]


#: (translation, parents, axioms) of the last few knowledge bases read (kept by identity)
_MEMO: list[tuple[object, dict, dict]] = []


def _memo(kb: KnowledgeBase) -> tuple[dict, dict]:
    """(class -> its parents, class -> its existential axioms) of ``kb``, read once."""
    tr = kb.translation
    for t, up, axioms in _MEMO:
        if t is tr:
            return up, axioms
    up: dict[str, list[str]] = {}
    for args in tr.relation("subclass"):
        if len(args) == 2 and isinstance(args[0], str) and isinstance(args[1], str):
            up.setdefault(args[0], []).append(args[1])
    _MEMO.append((tr, up, _read_axioms(kb)))
    del _MEMO[:-4]
    return _MEMO[-1][1], _MEMO[-1][2]


def ancestors(kb: KnowledgeBase, cls: str) -> tuple[str, ...]:
    """``cls`` and every class above it, nearest first (breadth first, file order)."""
    up = _memo(kb)[0]
    out, seen, queue = [], {cls}, deque([cls])
    while queue:
        c = queue.popleft()
        out.append(c)
        for p in up.get(c, ()):
            if p not in seen:
                seen.add(p)
                queue.append(p)
    return tuple(out)


@dataclass
class _Axiom:
    id: int
    cls: str
    where: str
    witnesses: dict[str, str]  # variable -> class, in order
    links: list[tuple[str, str, str]]  # (relation, a, b): "self", "?V" or a constant


def _read_axioms(kb: KnowledgeBase) -> dict[str, list[_Axiom]]:
    """The existential axioms by the class they quantify over."""
    import clingo

    where = {s.id: s.location for s in kb.translation.sources}
    out: dict[int, _Axiom] = {}
    for unit in kb.translation.units:
        if unit.kind != "axiom":
            continue
        for line in unit.lines:
            if not line.startswith(("exists_axiom(", "witness(", "link(")):
                continue
            t = clingo.parse_term(line.rstrip(".").strip())
            a = t.arguments
            i = a[0].number
            if t.name == "exists_axiom":
                out[i] = _Axiom(i, a[1].string, where.get(i, unit.where), {}, [])
            elif t.name == "witness" and i in out:
                out[i].witnesses[a[1].string] = a[2].string
            elif t.name == "link" and i in out:

                def ref(x) -> str:
                    if x.type == clingo.SymbolType.String:
                        return x.string
                    if x.type == clingo.SymbolType.Function and x.name == "self":
                        return "self"
                    return f"c:{x.arguments[0].string}" if x.arguments else str(x)

                out[i].links.append((a[1].string, ref(a[2]), ref(a[3])))
    by_cls: dict[str, list[_Axiom]] = {}
    for ax in out.values():
        by_cls.setdefault(ax.cls, []).append(ax)
    return by_cls


def _part_relations(kb: KnowledgeBase) -> set[str]:
    """``part`` and its subrelations (robotPart)."""
    down: dict[str, list[str]] = {}
    for args in kb.translation.relation("subrelation"):
        if len(args) == 2:
            down.setdefault(str(args[1]), []).append(str(args[0]))
    out, queue = {"part"}, deque(["part"])
    while queue:
        for r in down.get(queue.popleft(), ()):
            if r not in out:
                out.add(r)
                queue.append(r)
    return out


def plan_of(kb: KnowledgeBase, robot_type: str, kinds: PartKinds) -> BodyPlan:
    """The body plan of ``robot_type`` (see the module's docstring)."""
    lineage = ancestors(kb, robot_type)
    axioms = _memo(kb)[1]
    part_rel = _part_relations(kb)
    mine = [ax for c in lineage for ax in axioms.get(c, ())]
    # the part witnesses of each axiom, by class, in order
    per_axiom: list[tuple[_Axiom, dict[str, list[str]]]] = []
    for ax in mine:
        parts = [v for r, v, s in ax.links if s == "self" and r in part_rel and v in ax.witnesses]
        by_kind: dict[str, list[str]] = {}
        for v in ax.witnesses:
            if v in parts:
                by_kind.setdefault(ax.witnesses[v], []).append(v)
        per_axiom.append((ax, by_kind))
    counts: dict[str, int] = {}
    first_where: dict[str, str] = {}
    for ax, by_kind in per_axiom:
        for k, vs in by_kind.items():
            counts[k] = max(counts.get(k, 0), len(vs))
            first_where.setdefault(k, ax.where)
    lineage_of = {k: ancestors(kb, k) for k in counts}
    refined = {
        k: next((k2 for k2 in counts if k2 != k and k in lineage_of[k2]), None) for k in counts
    }

    def final(k: str) -> str:
        seen = set()
        while refined.get(k) and k not in seen:
            seen.add(k)
            k = refined[k]  # type: ignore[assignment]
        return k

    structural = {k for k in counts if "StructuralRobotPart" in lineage_of[k]}
    wanted = [k for k in counts if final(k) == k and (kinds.of(lineage_of[k]) or k in structural)]
    for k in wanted:
        if kinds.of(lineage_of[k]) is None:
            raise OntologyError(
                f"{first_where[k]}: {robot_type} has a part of class {k}, but no part kind "
                f"describes it (nor a class above it: {', '.join(lineage_of[k][1:]) or 'none'});"
                " add one with --parts FILE.toml (README: Part kinds)"
            )
    # the parts: (class, index)
    nodes: list[tuple[str, int]] = [(k, i) for k in wanted for i in range(counts[k])]
    where = {n: first_where[n[0]] for n in nodes}
    edges: list[tuple[tuple[str, int], tuple[str, int], str]] = []
    for ax, by_kind in per_axiom:
        index = {v: (final(k), i) for k, vs in by_kind.items() for i, v in enumerate(vs)}
        for r, a, b in ax.links:
            if r != "connectedTo" or a not in index or b not in index:
                continue
            na, nb = index[a], index[b]
            if na in where and nb in where:
                for n in (na, nb):
                    where[n] = where.get(n) or ax.where
                if na == nb:
                    raise OntologyError(f"{ax.where}: {a} ({na[0]}) is connectedTo itself")
                edges.append((na, nb, ax.where))
    roots = [n for n in nodes if (k := kinds.of(lineage_of[n[0]])) is not None and k.root]
    here = (axioms.get(robot_type) or mine or [None])[0]
    at = here.where if here is not None else robot_type
    if not roots:  # an arm as the paper writes it: a chain of servos from its first joint
        base = _arm_base(kb, kinds, nodes, edges, lineage_of)
        if base is not None:
            cls, first = base
            lineage_of[cls] = ancestors(kb, cls)
            root_node = (cls, 0)
            nodes.insert(0, root_node)
            where[root_node] = where[first]
            edges.append((root_node, first, where[first]))
            roots = [root_node]
    if not roots:
        named = ", ".join(sorted({n[0] for n in nodes})) or "no structural parts"
        raise OntologyError(
            f"{at}: the body plan of {robot_type} has no root: none of its parts ({named}) is "
            "a part the others hang on (a trunk, a chassis, an arm's base: a part kind with "
            "root = true)"
        )
    if len(roots) > 1:
        roots = [_carrier(robot_type, kinds, roots, nodes, edges, lineage_of, where)]
    adj: dict[tuple[str, int], list[tuple[tuple[str, int], str]]] = {n: [] for n in nodes}
    seen_edges = set()
    for a, b, w in edges:
        key = frozenset((a, b))
        if key in seen_edges:
            continue
        seen_edges.add(key)
        adj[a].append((b, w))
        adj[b].append((a, w))
    root = roots[0]
    parent: dict[tuple[str, int], tuple[str, int] | None] = {root: None}
    order = [root]
    queue = deque([root])
    while queue:
        n = queue.popleft()
        for m, w in adj[n]:
            if m == parent[n]:
                continue
            if m in parent:
                raise OntologyError(
                    f"{w}: the connectedTo links of {robot_type} close a cycle through "
                    f"{m[0]} #{m[1] + 1} and {n[0]} #{n[1] + 1}; a body plan is a tree"
                )
            parent[m] = n
            order.append(m)
            queue.append(m)
    for n in nodes:
        if n in parent:
            continue
        if adj[n]:
            raise OntologyError(
                f"{where[n]}: part {n[0]} of {robot_type} is connected to other parts but not "
                f"to its root {root[0]}"
            )
        parent[n] = root
        order.append(n)

    # built leaves first, each node once: linear in the parts and no recursion (a plan of
    # thousands of parts is as deep as it is long)
    kids: dict[tuple[str, int], list[tuple[str, int]]] = {n: [] for n in order}
    for m in order:
        if parent[m] is not None:
            kids[parent[m]].append(m)
    built: dict[tuple[str, int], PartNode] = {}
    for n in reversed(order):
        built[n] = PartNode(n[0], lineage_of[n[0]], tuple(built.pop(m) for m in kids[n]), where[n])

    plan = BodyPlan(
        robot_type,
        built[root],
        _default_lengths(kb, lineage),
        tuple(
            str(args[1])
            for args in kb.translation.relation("extensiblePart")
            if len(args) == 2 and args[0] in lineage
        ),
    )
    _check_lengths_used(kb, plan, kinds, lineage)
    return plan


def _check_lengths_used(
    kb: KnowledgeBase, plan: BodyPlan, kinds: PartKinds, lineage: Sequence[str]
) -> None:
    """OntologyError (file:line:col) for a ``defaultLength`` of the type's classes that
    names a length none of its parts' kinds uses (a typo would pass in silence)."""
    if not plan.lengths:
        return
    from kinematics.assemble import AssemblyError, length_defaults

    try:
        used = length_defaults(plan, kinds)
    except AssemblyError:
        return  # the plan is refused where it is assembled, with its own message
    for args, where in kb.translation.located("defaultLength"):
        if len(args) == 3 and args[0] in lineage and args[1] not in used:
            raise OntologyError(
                f"{where}: defaultLength {args[1]}: no part of {plan.robot_type} has a length "
                f"of this name (its lengths: {', '.join(used) or 'none'})"
            )


def _carrier(robot_type, kinds, roots, nodes, edges, lineage_of, where) -> tuple[str, int]:
    """The root part that carries the plan's other root parts (a chassis carrying a torso):
    they must be joined to it through ``connectedTo`` (one tree), and its part kind must
    mount each of them (a mount whose child is their class or a class above it) while
    none of theirs mounts it. OntologyError (file:line:col) naming the parts otherwise."""
    adj: dict[tuple[str, int], set[tuple[str, int]]] = {n: set() for n in nodes}
    for a, b, _ in edges:
        adj[a].add(b)
        adj[b].add(a)
    seen, queue = {roots[0]}, deque([roots[0]])
    while queue:
        for m in adj[queue.popleft()]:
            if m not in seen:
                seen.add(m)
                queue.append(m)
    names = ", ".join(f"{r[0]} #{r[1] + 1}" if r[1] else r[0] for r in roots)
    apart = [r for r in roots if r not in seen]
    if apart:
        raise OntologyError(
            f"{where[apart[0]]}: the body plan of {robot_type} has {len(roots)} root parts "
            f"({names}) that no connectedTo joins; one part carries the rest (connect the "
            "others to it)"
        )

    def mounts(a: tuple[str, int], b: tuple[str, int]) -> bool:
        k = kinds.of(lineage_of[a[0]])
        return k is not None and any(m.child in lineage_of[b[0]] for m in k.mounts)

    carriers = [r for r in roots if all(mounts(r, o) and not mounts(o, r) for o in roots if o != r)]
    if len(carriers) != 1:
        raise OntologyError(
            f"{where[roots[1]]}: the body plan of {robot_type} has {len(roots)} root parts "
            f"({names}) connected to each other, but the part kinds do not say which carries "
            "the others: the carrier's part kind needs a mount of the others' class (layout "
            "top), and theirs none of it"
        )
    return carriers[0]


def _arm_base(kb, kinds, nodes, edges, lineage_of) -> tuple[str, tuple[str, int]] | None:
    """(the class of the root part an arm's chain stands on, the chain's first joint) for
    a body plan with no root part whose parts are one serial chain of joints and printed
    links that may end in an end effector (the paper's manipulator axioms name no base):
    the arm is fixed to the world at its first joint, on the root part kind that mounts
    nothing but a serial chain of that joint's class (the shipped ``ArmBase``: the plate
    under the first joint carrying the main module and battery). The first joint is the
    joint no ``connectedTo`` leads to (the chain written from its base), else the one
    end of the chain that is a joint. None when the plan is no such chain."""
    roles = {n: (k.role if (k := kinds.of(lineage_of[n[0]])) is not None else "") for n in nodes}
    if not nodes or "joint" not in roles.values():
        return None
    if any(r not in ("joint", "link", "end_effector") for r in roles.values()):
        return None
    degree = dict.fromkeys(nodes, 0)
    targets = set()
    pairs = {frozenset((a, b)) for a, b, _ in edges}
    for pair in pairs:
        for n in pair:
            degree[n] += 1
    for _, b, _ in edges:
        targets.add(b)
    if len(pairs) != len(nodes) - 1 or any(d > 2 for d in degree.values()):
        return None  # not one unbranched chain
    ends = [n for n in nodes if degree[n] <= 1 and roles[n] == "joint"]
    heads = [n for n in ends if n not in targets]
    first = heads[0] if len(heads) == 1 else (ends[0] if len(ends) == 1 else None)
    if first is None:
        return None
    bases = [
        k
        for k in kinds.kinds.values()
        if k.root
        and k.mounts
        and all(m.layout == "serial" for m in k.mounts)
        and any(m.child in lineage_of[first[0]] for m in k.mounts)
    ]
    return (bases[0].cls, first) if bases else None


def _default_lengths(kb: KnowledgeBase, lineage: Sequence[str]) -> dict[str, float]:
    rank = {c: i for i, c in enumerate(lineage)}
    best: dict[str, tuple[int, float]] = {}
    for args, where in kb.translation.located("defaultLength"):
        if len(args) != 3 or args[0] not in rank:
            continue
        name, text = args[1], args[2]
        if not isinstance(name, str) or not isinstance(text, str):
            raise OntologyError(f"{where}: defaultLength takes a class, a name and a quantity")
        try:
            value = quantity(text, "length", f"{where}: defaultLength {name}")
        except InputError as e:
            raise OntologyError(str(e)) from None
        if not 0 < value <= MAX_LENGTH_M:
            raise OntologyError(
                f"{where}: defaultLength {name} {text!r}: out of range: a length is more "
                f"than 0 and at most {MAX_LENGTH_M:g} m"
            )
        r = rank[args[0]]
        if name in best and r == best[name][0] and value != best[name][1]:
            raise OntologyError(
                f"{where}: defaultLength {name} {text!r} contradicts another defaultLength "
                f"of {args[0]} for {name} ({best[name][1]:g} m): which one holds is not said"
            )
        if name not in best or r < best[name][0]:
            best[name] = (r, value)
    return {k: v for k, (_, v) in sorted(best.items())}


def shipped_plan(robot_type: str) -> BodyPlan | None:
    """The body plan of a class of the shipped ontology (None for a class that is no robot
    there): ``kinematics.bodyplan.PLAN_SOURCE`` once ``install`` ran."""

    kb = load()
    if "Robot" not in ancestors(kb, robot_type)[1:]:
        return None
    return plan_of(kb, robot_type, load_kinds())


def install() -> None:
    """Let ``kinematics.templates.build`` find the shipped ontology's robot types by name
    (``kinematics.bodyplan.PLAN_SOURCE``; nothing heavy is imported): what a bundle
    written before design records kept their body plan needs. Called by the entry points
    (``synth.commands.cli`` before a command runs, ``program.rosworker.main``, the block server's
    runs), never as a side effect of an import; calling it again does nothing."""

    if not PLAN_SOURCE:
        PLAN_SOURCE.append(shipped_plan)


def structure_of_type(kb: KnowledgeBase, robot_type: str) -> tuple[BodyPlan, str]:
    """(body plan, structure) of ``robot_type`` with the part kinds in use."""
    from kinematics.assemble import structure_of

    kinds = in_use()
    plan = plan_of(kb, robot_type, kinds)
    return plan, structure_of(plan, kinds)


def parameter_defaults(kb: KnowledgeBase, robot_type: str) -> dict[str, float | None]:
    """The structural parameters' defaults of ``robot_type`` (its structure's, with the
    ontology's ``defaultParameter`` over them); {} when its body plan cannot be made (the
    design step says why)."""

    try:
        _, structure = structure_of_type(kb, robot_type)
    except InputError:
        return {}
    if not structure:
        return {}
    return structure_defaults(structure, ontology_defaults(kb, ancestors(kb, robot_type)))


def arm_joints(kb: KnowledgeBase, robot_type: str) -> int | None:
    """The joints of ``robot_type``'s serial arm (its body plan's parts of role "joint"),
    None when it is no serial arm on a fixed base or its plan cannot be made."""

    try:
        plan, structure = structure_of_type(kb, robot_type)
    except InputError:
        return None
    if structure != "serial_arm":
        return None
    kinds = in_use()
    return sum(1 for p in plan.root.walk() if (k := kinds.of(p.kinds)) and k.role == "joint")
