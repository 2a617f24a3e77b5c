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


@dataclass(frozen=True)
class PartNode:
    """One part of a body plan.

    ``kind``: the part's ontology class; ``kinds``: that class and its ancestors, most
    specific first (the part kinds' data is matched along it). ``children``: the parts
    connected to it away from the root, in the ontology's order. ``where``: the
    file:line:col of the axiom that declares the part ("" when none).
    """

    kind: str
    kinds: tuple[str, ...] = ()
    children: tuple[PartNode, ...] = ()
    where: str = ""

    def __post_init__(self) -> None:
        if not self.kinds:
            object.__setattr__(self, "kinds", (self.kind,))

    def to_dict(self) -> dict:
        out: dict = {"kind": self.kind}
        if self.kinds != (self.kind,):
            out["kinds"] = list(self.kinds)
        if self.children:
            out["children"] = [c.to_dict() for c in self.children]
        if self.where:
            out["where"] = self.where
        return out

    @classmethod
    def from_dict(cls, d: Mapping) -> PartNode:
        if not isinstance(d, Mapping) or not isinstance(d.get("kind"), str):
            raise ValueError(f"a body plan part needs a 'kind' string, got {d!r}")
        kinds = d.get("kinds", [d["kind"]])
        children = d.get("children", [])
        if not isinstance(kinds, list) or not all(isinstance(k, str) for k in kinds):
            raise ValueError(f"part {d['kind']}: 'kinds' must be a list of class names")
        if not isinstance(children, list):
            raise ValueError(f"part {d['kind']}: 'children' must be a list")
        return cls(
            d["kind"],
            tuple(kinds),
            tuple(cls.from_dict(c) for c in children),
            str(d.get("where", "")),
        )

    def walk(self):
        """This part and every part below it, depth first."""
        yield self
        for c in self.children:
            yield from c.walk()


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
        return repr(self.to_dict())


#: Where a robot type's body plan comes from when none is registered in this process
#: (``kinematics.templates.plan_of``): set by ``synth.bodyplan.install`` to the shipped
#: ontology's; kept here, in a module that imports nothing heavy, so that installing it
#: costs nothing on the command line's start-up path.
PLAN_SOURCE: list[Callable[[str], BodyPlan | None]] = []
