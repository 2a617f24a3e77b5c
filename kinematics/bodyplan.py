"""A robot type's body plan: its structural parts as a tree rooted at the part the rest
hangs on (a trunk, a chassis, an arm's base), as the ontology gives them (the parts of
the type's existential axioms, their counts and ``connectedTo`` links; ``adron.bodyplan``
reads them). ``kinematics.assemble`` turns a plan and the part kinds' data into a
kinematic template. A plan is plain data: it is kept in a design's record so that a
bundle can be rebuilt without the ontology that made it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = ["PLAN_SOURCE", "BodyPlan", "PartNode"]


@dataclass(frozen=True, eq=False, repr=False)
class PartNode:
    """One part of a body plan.

    ``kind``: the part's ontology class; ``kinds``: that class and its ancestors, most
    specific first (the part kinds' data is matched along it). ``children``: the parts
    connected to it away from the root, in the ontology's order. ``where``: the
    file:line:col of the axiom that declares the part ("" when none).

    Every walk of a tree (comparing, hashing, writing and reading it) is iterative: a
    chain of thousands of parts is as deep as it is long, deeper than Python's recursion.
    """

    kind: str
    kinds: tuple[str, ...] = ()
    children: tuple[PartNode, ...] = ()
    where: str = ""

    def __post_init__(self) -> None:
        if not self.kinds:
            object.__setattr__(self, "kinds", (self.kind,))

    def flat(self) -> tuple[tuple[int, str, tuple[str, ...], str], ...]:
        """(depth, kind, kinds, where) of every part, depth first: the tree as a list."""
        out = []
        stack: list[tuple[PartNode, int]] = [(self, 0)]
        while stack:
            n, depth = stack.pop()
            out.append((depth, n.kind, n.kinds, n.where))
            stack.extend((c, depth + 1) for c in reversed(n.children))
        return tuple(out)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PartNode):
            return NotImplemented
        return self is other or self.flat() == other.flat()

    def __hash__(self) -> int:
        return hash(self.flat())

    def __repr__(self) -> str:
        n = len(self.flat())
        return f"PartNode({self.kind!r}, {n} part{'s' if n != 1 else ''})"

    def _own(self) -> dict:
        out: dict = {"kind": self.kind}
        if self.kinds != (self.kind,):
            out["kinds"] = list(self.kinds)
        if self.where:
            out["where"] = self.where
        return out

    def to_dict(self) -> dict:
        top = self._own()
        stack: list[tuple[PartNode, dict]] = [(self, top)]
        while stack:
            n, d = stack.pop()
            if n.children:
                kids = [c._own() for c in n.children]
                # keys in the order they always had: kind, kinds, children, where
                where = d.pop("where", None)
                d["children"] = kids
                if where is not None:
                    d["where"] = where
                stack.extend(zip(n.children, kids, strict=True))
        return top

    @classmethod
    def from_dict(cls, d: Mapping) -> PartNode:
        def check(d) -> tuple[tuple[str, ...], list]:
            if not isinstance(d, Mapping) or not isinstance(d.get("kind"), str):
                raise ValueError(f"a body plan part needs a 'kind' string, got {d!r:.200}")
            kinds = d.get("kinds", [d["kind"]])
            children = d.get("children", [])
            if not isinstance(kinds, list) or not all(isinstance(k, str) for k in kinds):
                raise ValueError(f"part {d['kind']}: 'kinds' must be a list of class names")
            if not isinstance(children, list):
                raise ValueError(f"part {d['kind']}: 'children' must be a list")
            return tuple(kinds), children

        # parents before children (depth first), then built leaves first
        order: list[tuple[Mapping, tuple[str, ...]]] = []
        kids: list[list[int]] = []
        stack: list[tuple[Mapping, int]] = [(d, -1)]
        while stack:
            x, parent = stack.pop()
            kinds, children = check(x)
            if parent >= 0:
                kids[parent].append(len(order))
            order.append((x, kinds))
            kids.append([])
            stack.extend((c, len(order) - 1) for c in reversed(children))
        built: list[PartNode | None] = [None] * len(order)
        for i in range(len(order) - 1, -1, -1):
            x, kinds = order[i]
            built[i] = cls(
                x["kind"], kinds, tuple(built[k] for k in kids[i]), str(x.get("where", ""))
            )
        return built[0]

    def walk(self):
        """This part and every part below it, depth first."""
        stack: list[PartNode] = [self]
        while stack:
            n = stack.pop()
            yield n
            stack.extend(reversed(n.children))


@dataclass(frozen=True)
class BodyPlan:
    """A robot type's parts as a tree (``root``), the default lengths its ontology names
    (m, ``defaultLength``), and the part classes it may grow (``extensiblePart``: a
    snake's modules; a chain of them gets ``TemplateParams.modules`` elements)."""

    robot_type: str
    root: PartNode
    lengths: Mapping[str, float] = field(default_factory=dict)
    extensible: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "lengths", MappingProxyType(dict(self.lengths)))

    def to_dict(self) -> dict:
        out: dict = {"robot_type": self.robot_type, "root": self.root.to_dict()}
        if self.lengths:
            out["lengths"] = dict(sorted(self.lengths.items()))
        if self.extensible:
            out["extensible"] = list(self.extensible)
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> BodyPlan:
        if not isinstance(d, Mapping) or not isinstance(d.get("robot_type"), str):
            raise ValueError("a body plan needs a 'robot_type' string and a 'root' part")
        lengths = d.get("lengths", {})
        if not isinstance(lengths, Mapping) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in lengths.values()
        ):
            raise ValueError("a body plan's 'lengths' must map names to numbers (m)")
        ext = d.get("extensible", [])
        if not isinstance(ext, list) or not all(isinstance(k, str) for k in ext):
            raise ValueError("a body plan's 'extensible' must be a list of class names")
        return cls(
            d["robot_type"],
            PartNode.from_dict(d.get("root")),
            {str(k): float(v) for k, v in lengths.items()},
            tuple(ext),
        )

    def key(self) -> str:
        """A text that tells plans apart (the template cache's key)."""
        head = {k: v for k, v in self.to_dict().items() if k != "root"}
        return repr((head, self.root.flat()))


#: Where a robot type's body plan comes from when none is registered in this process
#: (``kinematics.templates.plan_of``): set by ``synth.reasoning.plans.install`` to the shipped
#: ontology's; kept here, in a module that imports nothing heavy, so that installing it
#: costs nothing on the command line's start-up path.
PLAN_SOURCE: list[Callable[[str], BodyPlan | None]] = []
