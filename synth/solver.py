"""The one owner of ``clingo.Control``: grounds the knowledge base once, then answers
queries by assigning externals (multi-shot), returning frozen dataclasses.

The program is the KIF translation, the encodings of ``asp/conceptual.lp`` and any user
rule files. A query sets the externals ``request/1``, ``answer/2`` and ``param/2``
and enumerates all answer sets: one per candidate robot type.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path

import clingo

from adron.errors import InputError, OntologyError
from adron.kb import KnowledgeBase, read_user_file
from adron.translate import asp_string

_SCRIPT = re.compile(r"#\s*script", re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class Query:
    """A request in KIF terms. ``answers`` maps action class to True (yes) / False (no);
    ``params`` holds (relation, term) pairs."""

    requests: tuple[str, ...] = ()
    answers: tuple[tuple[str, bool], ...] = ()
    params: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True, slots=True, order=True)
class Reason:
    """Why a robot can do an action: it has ``have`` parts of ``kind``, it needs ``need``."""

    action: str
    kind: str
    need: int
    have: int


@dataclass(frozen=True, slots=True)
class PartSource:
    """A part count and the axioms (by id) that declare it."""

    kind: str
    count: int
    axioms: tuple[int, ...]


@dataclass(frozen=True)
class Candidate:
    """One answer set: a robot type and its conceptual design under the query."""

    robot_type: str
    active_total: int
    dof: int
    parts: tuple[tuple[str, int], ...]
    modules: tuple[tuple[str, int], ...]
    passive: tuple[tuple[str, int], ...]
    abilities: tuple[str, ...]
    potential: tuple[str, ...]
    reasons: tuple[Reason, ...] = ()
    sources: tuple[PartSource, ...] = ()
    module_limit: int | None = None
    hierarchy: int = 1  # depth of the part tree (robot -> parts -> modules: 2)
    declared: tuple[str, ...] = ()  # abilities its declared parts give (no growth, add-ons)
    ancestors: tuple[str, ...] = ()  # robot classes it is (itself included)
    preference: tuple[int, ...] = ()  # asp/preference.lp's cost of choosing it
    needed: tuple[str, ...] = ()  # the abilities the query demands of it (KIF classes)


@dataclass(frozen=True)
class Solution:
    """All candidates of a query (preference order) and the demands as the solver saw them."""

    candidates: tuple[Candidate, ...]
    needed: tuple[str, ...] = ()
    excluded: tuple[str, ...] = ()
    satisfiable: bool = True


def encoding_dir() -> Path:
    """The folder of the shipped encodings (package data of ``asp``)."""
    return Path(str(resources.files("asp")))


def check_rules_file(path: str | Path, allow_scripts: bool) -> str:
    """Read a user's .lp file; refuse one with ``#script`` unless scripts are allowed.

    (Files it includes are not read: clingo would resolve them. A user who includes
    scripts indirectly has chosen to run them.)"""
    name, text = read_user_file(path)
    check_lexable(name, text)
    if not allow_scripts:
        # anywhere in the text, comments and strings included: refusing too much is safe,
        # guessing where clingo's lexer sees a comment is not
        for lineno, line in enumerate(text.splitlines(), 1):
            m = _SCRIPT.search(line)
            if m:
                raise InputError(
                    f"{name}:{lineno}:{m.start() + 1}: refusing a rule file that contains "
                    "#script (clingo would run its code); pass --allow-scripts to trust it"
                )
    return text


#: Outside strings and comments clingo's lexer reads ASCII only, and its message about any
#: other byte is cut mid-character, which aborts the process inside clingo's Python logger.
# Only closed strings and comments are skipped: clingo echoes an unclosed one's text.
_ASP_TOKEN = re.compile(r'"(?:[^"\\\n]|\\.)*"|%\*.*?\*%|%[^\n]*|[^"%]+|.', re.S)
_UNLEXABLE = re.compile(r"[^\t\n\r\x20-\x7e]")


def check_lexable(name: str, text: str) -> None:
    """InputError (file:line:col) for a character clingo cannot read outside strings and
    comments: non-ASCII (a byte order mark too) or a control character."""
    for m in _ASP_TOKEN.finditer(text):
        if m.group()[0] in '"%':
            continue
        bad = _UNLEXABLE.search(m.group())
        if bad:
            at = m.start() + bad.start()
            line = text.count("\n", 0, at) + 1
            col = at - (text.rfind("\n", 0, at) + 1) + 1
            raise InputError(
                f"{name}:{line}:{col}: character U+{ord(bad.group()):04X} outside a string or "
                "comment (ASP reads ASCII there)"
            )


def _str(sym: clingo.Symbol) -> str:
    return sym.string if sym.type == clingo.SymbolType.String else str(sym)


class Reasoner:
    """Grounds once; :meth:`solve` and :meth:`satisfiable` re-solve under new externals."""

    def __init__(
        self,
        kb: KnowledgeBase,
        rules: Sequence[str | Path] = (),
        allow_scripts: bool = False,
        focus: str | None = None,
    ) -> None:
        """Ground ``kb`` with the encodings and ``rules``. With ``focus`` (a robot class),
        the program describes that class instead of choosing among candidates."""
        self.kb = kb
        self._rules, self._allow_scripts = tuple(rules), allow_scripts
        self._messages: list[str] = []
        self._ctl = clingo.Control(
            ["--models=0", "--opt-mode=enum"], logger=self._log, message_limit=20
        )
        self._externals: set[clingo.Symbol] = set()
        try:
            self._ctl.add("base", [], kb.translation.program)
            self._ctl.load(str(encoding_dir() / "conceptual.lp"))
            if focus is not None:
                self._ctl.add("base", [], f"focus({asp_string(focus)}).")
            for path in rules:
                check_rules_file(path, allow_scripts)
                self._ctl.load(str(path))
            self._ctl.ground([("base", [])])
        except RuntimeError as e:
            detail = "; ".join(self._messages) or str(e)
            raise OntologyError(f"the rules do not ground: {detail}") from None
        atoms = self._ctl.symbolic_atoms
        self._externals = {
            a.symbol
            for sig in (("request", 1), ("answer", 2), ("param", 2))
            for a in atoms.by_signature(*sig)
            if a.is_external
        }
        #: every subclass of Robot, as the taxonomy closure found them
        self.robot_types: tuple[str, ...] = tuple(
            sorted(a.symbol.arguments[0].string for a in atoms.by_signature("robot_class", 1))
        )

    def focused(self, robot_type: str) -> Reasoner:
        """A reasoner over the same program that describes ``robot_type`` (explain)."""
        return Reasoner(self.kb, self._rules, self._allow_scripts, focus=robot_type)

    def _log(self, code: clingo.MessageCode, message: str) -> None:
        self._messages.append(message.strip().replace("\n", " "))

    def _assign(self, query: Query) -> None:
        on: set[clingo.Symbol] = set()
        S, F = clingo.String, clingo.Function
        for a in query.requests:
            on.add(F("request", [S(a)]))
        for a, yes in query.answers:
            on.add(F("answer", [S(a), F("yes" if yes else "no")]))
        for rel, term in query.params:
            on.add(F("param", [S(rel), S(term)]))
        missing = on - self._externals
        if missing:
            raise InputError(
                "not known to the knowledge base: " + ", ".join(sorted(map(str, missing)))
            )
        for sym in self._externals:
            self._ctl.assign_external(sym, sym in on)

    def satisfiable(self, query: Query) -> bool:
        """True when at least one candidate meets ``query`` (stops at the first model)."""
        self._assign(query)
        with self._ctl.solve(yield_=True) as handle:
            for _ in handle:
                return True
        return False

    def answer_sets(
        self, query: Query, predicates: Iterable[str] | None = None
    ) -> frozenset[frozenset[str]]:
        """The shown atoms of every answer set (as text), optionally only ``predicates``."""
        self._assign(query)
        keep = set(predicates) if predicates is not None else None
        models = set()
        with self._ctl.solve(yield_=True) as handle:
            for model in handle:
                models.add(
                    frozenset(
                        str(s) for s in model.symbols(shown=True) if keep is None or s.name in keep
                    )
                )
        return frozenset(models)

    def solve(self, query: Query) -> Solution:
        """Every candidate of ``query``, in preference order: the cost asp/preference.lp
        gives each answer set (fewest active modules), then the type name."""
        self._assign(query)
        found: dict[str, Candidate] = {}
        needed: set[str] = set()
        excluded: set[str] = set()
        with self._ctl.solve(yield_=True) as handle:
            for model in handle:
                cand, need, excl = self._read(model.symbols(shown=True))
                needed |= need
                excluded |= excl
                if cand is not None:
                    found[cand.robot_type] = replace(cand, preference=tuple(model.cost))
        demanded = tuple(sorted(needed))
        found = {t: replace(c, needed=demanded) for t, c in found.items()}
        order = sorted(found.values(), key=lambda c: (c.preference, c.robot_type))
        return Solution(
            tuple(order), tuple(sorted(needed)), tuple(sorted(excluded)), satisfiable=bool(order)
        )

    @staticmethod
    def _read(symbols: Iterable[clingo.Symbol]) -> tuple[Candidate | None, set, set]:
        by: dict[str, list[list]] = {}
        for s in symbols:
            by.setdefault(s.name, []).append(
                [_str(a) if a.type != clingo.SymbolType.Number else a.number for a in s.arguments]
            )
        need = {a[0] for a in by.get("need", [])}
        excl = {a[0] for a in by.get("excluded", [])}
        robots = [a[0] for a in by.get("chosen", [])]
        if not robots:
            # focus mode: the described robot is the one with parts
            robots = sorted({a[0] for a in by.get("structural", []) + by.get("active", [])})
        if not robots:
            return None, need, excl
        r = robots[0]

        def triples(name: str) -> tuple[tuple[str, int], ...]:
            return tuple(sorted((k, n) for rr, k, n in by.get(name, []) if rr == r and n > 0))

        def single(name: str) -> int | None:
            vals = [a[1] for a in by.get(name, []) if a[0] == r]
            return vals[0] if vals else None

        sources: dict[tuple[str, int], list[int]] = {}
        for rr, k, n, i in by.get("source", []):
            if rr == r:
                sources.setdefault((k, n), []).append(i)
        cand = Candidate(
            robot_type=r,
            active_total=sum(n for rr, _, n in by.get("active", []) if rr == r),
            dof=sum(n for rr, _, n in by.get("actuator", []) if rr == r),
            parts=triples("structural"),
            modules=triples("active"),
            passive=triples("passive"),
            abilities=tuple(sorted(a for rr, a in by.get("has_ability", []) if rr == r)),
            potential=tuple(sorted(a for rr, a in by.get("potential", []) if rr == r)),
            reasons=tuple(
                sorted(Reason(a, k, n, s) for rr, a, k, n, s in by.get("reason", []) if rr == r)
            ),
            sources=tuple(
                PartSource(k, n, tuple(sorted(ids))) for (k, n), ids in sorted(sources.items())
            ),
            module_limit=single("limit"),
            hierarchy=max((d for rr, d in by.get("level", []) if rr == r), default=1),
            declared=tuple(sorted(a for rr, a in by.get("declared", []) if rr == r)),
            ancestors=tuple(sorted(c for rr, c in by.get("ancestor", []) if rr == r)),
        )
        return cand, need, excl


@dataclass(frozen=True, slots=True)
class JointSlot:
    """A movable joint to be given an actuator: name, symmetry group, ontology class."""

    name: str
    group: str
    module_class: str


@dataclass(frozen=True)
class Assignment:
    """One actuator model per joint, and its objective figures (catalog units)."""

    models: tuple[tuple[str, str], ...]  # (joint, model) in joint order
    cost: tuple[int, ...]  # clingo's cost vector, highest priority first

    def model_of(self, joint: str) -> str:
        return dict(self.models)[joint]


class ActuatorAssigner:
    """Actuator assignment by clingo over ``asp/actuators.lp``, grounded once per design.

    Each iteration of the co-design loop only changes which models are capable for each
    joint: those are externals, so re-solving needs no regrounding (multi-shot). The
    k-best list blocks each answer found with a small added program part.
    """

    def __init__(
        self,
        kb: KnowledgeBase,
        catalog_facts: str,
        robot_type: str,
        joints: Sequence[JointSlot],
        other_active: int,
        objective: Sequence[str] = ("mass", "cost"),
    ) -> None:
        if sorted(objective) != ["cost", "mass"]:
            raise InputError(f"objective {list(objective)}: expected an order of mass and cost")
        prio = {name: len(objective) - i for i, name in enumerate(objective)}
        self._messages: list[str] = []
        self.joints = tuple(joints)
        self._ctl = clingo.Control(
            [
                "--opt-mode=optN",
                f"-c mass_priority={prio['mass']}",
                f"-c cost_priority={prio['cost']}",
            ],
            logger=lambda code, msg: self._messages.append(msg.strip()),
            message_limit=20,
        )
        facts = [f"robot({asp_string(robot_type)}).", f"other_active({other_active})."]
        facts += [
            f"joint({asp_string(j.name)},{asp_string(j.group)},{asp_string(j.module_class)})."
            for j in self.joints
        ]
        self._ctl.add("base", [], kb.translation.program)
        self._ctl.add("base", [], catalog_facts)
        self._ctl.add("base", [], "\n".join(facts))
        self._ctl.load(str(encoding_dir() / "taxonomy.lp"))
        self._ctl.load(str(encoding_dir() / "actuators.lp"))
        self._ctl.ground([("base", [])])
        self._blocks = 0
        atoms = self._ctl.symbolic_atoms
        #: joint -> the models that serve its ontology class (before any requirement)
        self.serving: dict[str, tuple[str, ...]] = {}
        for a in atoms.by_signature("serves", 2):
            m, j = (x.string for x in a.symbol.arguments)
            self.serving.setdefault(j, ())
            self.serving[j] = tuple(sorted((*self.serving[j], m)))

    def _assign(self, capable: Mapping[str, Iterable[str]], symmetric: bool) -> None:
        S, F = clingo.String, clingo.Function
        self._ctl.assign_external(F("symmetric", []), symmetric)
        for j, models in self.serving.items():
            ok = set(capable.get(j, ()))
            for m in models:
                self._ctl.assign_external(F("capable", [S(j), S(m)]), m in ok)

    def _read(self, model: clingo.Model) -> Assignment:
        got = {s.arguments[0].string: s.arguments[1].string for s in model.symbols(shown=True)}
        return Assignment(tuple((j.name, got[j.name]) for j in self.joints), tuple(model.cost))

    def best(
        self, capable: Mapping[str, Iterable[str]], symmetric: bool = True
    ) -> Assignment | None:
        """The optimal assignment (ties: the first in joint and model name order)."""
        found = self.ranked(capable, symmetric, 1)
        return found[0] if found else None

    def ranked(
        self, capable: Mapping[str, Iterable[str]], symmetric: bool, k: int
    ) -> list[Assignment]:
        """The ``k`` best assignments, best first (each found by re-optimising with the
        previous ones blocked)."""
        self._assign(capable, symmetric)
        out: list[Assignment] = []
        blocked: list[str] = []
        while len(out) < k:
            optimal: list[Assignment] = []
            with self._ctl.solve(yield_=True) as handle:
                for m in handle:
                    if m.optimality_proven:
                        optimal.append(self._read(m))
            if not optimal:
                break
            optimal.sort(key=lambda a: (a.cost, a.models))
            for a in optimal:
                if len(out) < k:
                    out.append(a)
                name = f"block_{self._blocks}"
                self._blocks += 1
                body = ", ".join(f"assign({asp_string(j)},{asp_string(m)})" for j, m in a.models)
                self._ctl.add(name, [], f"#external {name}.\n:- {name}, {body}.")
                self._ctl.ground([(name, [])])
                self._ctl.assign_external(clingo.Function(name, []), True)
                blocked.append(name)
        for name in blocked:  # unblock for the next query
            self._ctl.release_external(clingo.Function(name, []))
        return out

    def all(self, capable: Mapping[str, Iterable[str]], symmetric: bool) -> list[Assignment]:
        """Every feasible assignment, in objective order (for small spaces: --pareto)."""
        self._assign(capable, symmetric)
        found: list[Assignment] = []
        self._ctl.configuration.solve.opt_mode = "ignore"
        self._ctl.configuration.solve.models = "0"
        try:
            with self._ctl.solve(yield_=True) as handle:
                for m in handle:
                    found.append(self._read(m))
        finally:
            self._ctl.configuration.solve.opt_mode = "optN"
        return found
