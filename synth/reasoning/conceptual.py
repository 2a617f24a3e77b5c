"""Conceptual design: the paper's Procedure 1 over the clingo reasoner.

1. The requested abilities (and answers, and conceptual parameters) select the candidate
   base configurations (one answer set each).
2. While several candidates remain, ask "Does the robot need to ...?" about an ability
   that some candidates could have and others could not, the one that splits them most
   evenly (ties: the ability's short name in alphabetical order). "yes" adds it to the
   demands; "no" drops the candidates whose declared parts give it.
3. When no ability separates the rest, choose by the documented preference of
   ``asp/preference.lp`` (fewest active modules; then type name) and say so.
4. When no candidate remains, name the smallest set of demands that conflict.
"""

from __future__ import annotations

import difflib
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

from adron.errors import InputError, OntologyError
from adron.kb import KnowledgeBase
from synth.params import BY_NAME as STRUCTURAL
from synth.params import exceeded_limits, parse_structural
from synth.reasoning.plans import ancestors, arm_joints, parameter_defaults
from synth.reasoning.solver import Candidate, Query, Reasoner


@dataclass(frozen=True, slots=True)
class Request:
    """A user's request in command-line terms (short ability names, parameter names)."""

    abilities: tuple[str, ...] = ()
    answers: tuple[tuple[str, bool], ...] = ()
    params: tuple[tuple[str, str], ...] = ()

    def answer(self, ability: str, yes: bool) -> Request:
        return replace(self, answers=(*self.answers, (ability, yes)))


@dataclass(frozen=True, slots=True)
class Question:
    ability: str
    text: str
    answer: bool | None = None


@dataclass(frozen=True)
class Design:
    """The outcome of one step of the procedure."""

    status: str  # "designed" | "ambiguous" | "unsatisfiable"
    request: Request
    candidates: tuple[Candidate, ...] = ()
    chosen: Candidate | None = None
    chosen_by: str | None = None  # "only candidate" | "preference"
    note: str | None = None
    questions: tuple[Question, ...] = ()
    conflict: tuple[str, ...] = ()
    needed: tuple[str, ...] = ()
    #: ability -> the abilities it is a subclass of, nearest first (short names), for the
    #: chosen robot's abilities and the needed ones that have any: which behaviours serve
    #: an ability (``gaits.base.serving``), written into the record for the bundle
    ancestors: tuple[tuple[str, tuple[str, ...]], ...] = ()
    #: the robots that would meet an unsatisfiable request but for their active module
    #: limit: (robot type, its active modules, its limit)
    over_limit: tuple[tuple[str, int, int | None], ...] = ()


def suggest(word: str, options: Sequence[str]) -> str:
    """' (did you mean: a, b?)' for close matches of ``word``, else ''."""
    close = difflib.get_close_matches(word, options, n=3, cutoff=0.5)
    return f" (did you mean: {', '.join(close)}?)" if close else ""


def parse_answer(text: str) -> tuple[str, bool]:
    """'grasping=yes' -> ('grasping', True); raises InputError on anything else."""
    name, sep, value = text.rpartition("=")  # the ability's name may hold an '='
    v = value.strip().lower()
    if not sep or not name.strip() or v not in ("yes", "no", "y", "n", "true", "false"):
        raise InputError(f"--answer {text!r}: expected ABILITY=yes or ABILITY=no")
    return name.strip(), v in ("yes", "y", "true")


def parse_param(text: str) -> tuple[str, str]:
    """'object_shape=oval' -> ('object_shape', 'oval'); raises InputError when malformed."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise InputError(f"--param {text!r}: expected NAME=VALUE")
    return name.strip(), value.strip()


def ability_kif(kb: KnowledgeBase, name: str) -> str:
    """The KIF name of the ability ``name``; InputError (with a suggestion) if unknown."""
    a = kb.ability(name)
    if a is None:
        names = [x.name for x in kb.abilities]
        raise InputError(
            f"unknown ability {name!r}{suggest(name, names)}; 'parmor abilities' lists them"
        )
    return a.kif


def query_for(kb: KnowledgeBase, req: Request) -> Query:
    """The solver query of ``req``, every name checked against ``kb`` (it needs no
    grounding: a command builds it for its Reasoner's ``first`` query)."""
    requests = tuple(dict.fromkeys(ability_kif(kb, a) for a in req.abilities))
    answers: dict[str, bool] = {}
    for name, yes in req.answers:
        kif = ability_kif(kb, name)
        if answers.get(kif, yes) != yes:
            raise InputError(f"--answer {name}: answered both yes and no")
        answers[kif] = yes
    params: dict[str, tuple[str, str]] = {}
    for name, value in req.params:
        p = kb.parameter(name)
        if p is None and name in STRUCTURAL:
            continue  # a physical parameter: see structural()
        if p is None:
            names = sorted([x.name for x in kb.parameters] + list(STRUCTURAL))
            raise InputError(
                f"unknown parameter {name!r}{suggest(name, names)}; known: {', '.join(names)}"
            )
        term = p.term(value)
        if term is None:
            vals = [v for v, _ in p.values]
            raise InputError(
                f"--param {name}={value}: unknown value{suggest(value, vals)}; "
                f"one of: {', '.join(vals)}"
            )
        if name in params and params[name][1] != term:
            raise InputError(f"--param {name} given twice with different values")
        params[name] = (p.relation, term)
    return Query(requests, tuple(sorted(answers.items())), tuple(sorted(params.values())))


def ability_ancestors(kb: KnowledgeBase, abilities: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """Each of ``abilities`` (short names) that has ability classes above it in the
    ontology's taxonomy -> their short names, nearest first (``synth.reasoning.plans.ancestors``:
    breadth first; classes that are no ability are passed through, not named): which
    behaviours serve an ability with none of its own (``gaits.base.serving``)."""

    out: dict[str, tuple[str, ...]] = {}
    for name in sorted(set(abilities)):
        a = kb.ability(name)
        if a is None:
            continue
        up = [kb.ability_of_kif(c) for c in ancestors(kb, a.kif)[1:]]
        named = tuple(x.name for x in up if x is not None)
        if named:
            out[name] = named
    return out


def limit_note(over: Sequence[tuple[str, int, int | None]], bus: str | None = None) -> str:
    """``"Octopod has 26 active modules, over the limit of 24 on the I2C bus"``: why the
    robots ``over`` (``Designer.over_limit``) are no candidates; ``bus`` says where the
    limit comes from (``pipeline.limit_source``; None: not known here)."""
    where = f" {bus}" if bus else ""
    return "; ".join(
        f"{t} has {n} active modules, over the limit of {limit}{where}" for t, n, limit in over
    )


class Designer:
    """Runs the procedure on one grounded knowledge base; queries re-use the grounding."""

    def __init__(self, kb: KnowledgeBase, reasoner: Reasoner) -> None:
        self.kb = kb
        self.reasoner = reasoner
        self._unlimited: Reasoner | None = None  # the reasoner without a module limit

    # -- names ------------------------------------------------------------------------
    def short(self, kif: str) -> str:
        a = self.kb.ability_of_kif(kif)
        return a.name if a else kif

    def robot_type(self, name: str) -> str:
        types = self.reasoner.robot_types
        if name not in types:
            raise InputError(f"unknown robot type {name!r}{suggest(name, types)}")
        return name

    def query(self, req: Request) -> Query:
        """Check every name of ``req`` against the ontology and build the solver query."""
        return query_for(self.kb, req)

    def structural(self, req: Request) -> dict[str, float]:
        """The physical parameters of ``req`` in SI units (units are required)."""
        given: dict[str, str] = {}
        for name, value in req.params:
            if self.kb.parameter(name) is None and name in STRUCTURAL:
                if given.get(name, value) != value:
                    raise InputError(f"--param {name} given twice with different values")
                given[name] = value
        return parse_structural(given) if given else {}

    def with_dof(
        self, cands: Sequence[Candidate], physical: Mapping[str, float]
    ) -> tuple[Candidate, ...]:
        """The candidates that are serial arms of ``--param dof`` joints (all without it)."""
        if "dof" not in physical:
            return tuple(cands)

        n = int(physical["dof"])
        return tuple(c for c in cands if arm_joints(self.kb, c.robot_type) == n)

    def within_limits(
        self, cands: Sequence[Candidate], physical: Mapping[str, float]
    ) -> tuple[tuple[Candidate, ...], dict[str, list[str]]]:
        """The candidates whose ontology ``structuralLimit`` facts the physical parameters
        do not exceed, and the exceeded limits of the others (type -> phrases)."""
        limits = self.kb.translation.located("structuralLimit")
        if not limits:
            return tuple(cands), {}

        over = {
            c.robot_type: exceeded_limits(
                c, limits, physical, lambda c=c: parameter_defaults(self.kb, c.robot_type)
            )
            for c in cands
        }
        over = {t: w for t, w in over.items() if w}
        return tuple(c for c in cands if c.robot_type not in over), over

    @staticmethod
    def limit_conflict(req: Request, over: Mapping[str, list[str]]) -> tuple[str, ...]:
        """The demands behind "every candidate exceeds a structural limit": the requested
        abilities and the parameters named by the exceeded limits."""
        names = {phrase.split(" above ")[0] for phrases in over.values() for phrase in phrases}
        return tuple(req.abilities) + tuple(f"{n}={v}" for n, v in req.params if n in names)

    def ability_ancestors(self, abilities: Sequence[str]) -> dict[str, tuple[str, ...]]:
        """:func:`ability_ancestors` in this designer's knowledge base."""
        return ability_ancestors(self.kb, abilities)

    def over_limit(self, req: Request) -> tuple[tuple[str, int, int | None], ...]:
        """The robots that meet ``req`` but carry more active modules than their limit (the
        catalog bus's, else the ontology's ``activeModuleLimit``) allows: (type, active
        modules, limit), fewest modules first. The reasoner excludes them; one without the
        limit finds them, and each one's limit is read as ``parmor explain`` reads it."""
        if self._unlimited is None:  # grounded once, on the first refusal
            self._unlimited = self.reasoner.unlimited()
        sol = self._unlimited.solve(self.query(req))
        out = []
        for c in sol.candidates:
            limit = self.describe(c.robot_type).module_limit
            if limit is not None and c.active_total > limit:
                out.append((c.robot_type, c.active_total, limit))
        return tuple(out)

    # -- the procedure ----------------------------------------------------------------
    def step(self, req: Request) -> Design:
        """Solve ``req``: designed, ambiguous (with the next question) or unsatisfiable.
        A designed robot's record carries its abilities' ancestors (``ancestors``); an
        unsatisfiable request names the robots its module limit alone excludes."""
        d = self._step(req)
        if d.chosen is not None:
            names = [self.short(a) for a in d.chosen.abilities] + list(d.needed)
            return replace(d, ancestors=tuple(self.ability_ancestors(names).items()))
        if d.status == "unsatisfiable" and d.note is None:
            over = self.over_limit(req)
            if over:
                return replace(d, over_limit=over, note=limit_note(over))
        return d

    def _step(self, req: Request) -> Design:
        q = self.query(req)
        physical = self.structural(req)
        sol = self.reasoner.solve(q)
        asked = tuple(Question(n, self._question(n), yes) for n, yes in req.answers)
        needed = tuple(self.short(a) for a in sol.needed)
        if not sol.candidates:
            return Design(
                "unsatisfiable", req, questions=asked, conflict=self.conflict(req), needed=needed
            )
        arms = self.with_dof(sol.candidates, physical)
        if not arms:
            n = int(physical["dof"])
            return Design(
                "unsatisfiable",
                req,
                questions=asked,
                conflict=(*req.abilities, f"dof={n}"),
                needed=needed,
                note=f"no candidate is a serial arm of {n} joints (candidates: "
                + ", ".join(f"{c.robot_type} ({c.dof} joints)" for c in sol.candidates)
                + ")",
            )
        cands, over = self.within_limits(arms, physical)
        excluded = "; ".join(f"{t} is not built for {', '.join(ws)}" for t, ws in over.items())
        if not cands:
            conflict = self.limit_conflict(req, over)
            return Design(
                "unsatisfiable",
                req,
                questions=asked,
                conflict=conflict,
                needed=needed,
                note=excluded,
            )
        if len(cands) == 1:
            return Design(
                "designed",
                req,
                cands,
                cands[0],
                "only candidate",
                excluded or None,
                asked,
                needed=needed,
            )
        nxt = self.next_question(
            cands, set(sol.needed) | set(sol.excluded) | {a for a, _ in q.answers}
        )
        if nxt is None:
            best = cands[0]
            others = ", ".join(c.robot_type for c in cands[1:])
            note = (
                f"no ability separates {best.robot_type} from {others}; chose "
                f"{best.robot_type} by preference: fewest active modules "
                f"({best.active_total})"
            )
            if excluded:
                note = f"{excluded}; {note}"
            return Design("designed", req, cands, best, "preference", note, asked, needed=needed)
        return Design(
            "ambiguous", req, cands, questions=(*asked, nxt), needed=needed, note=excluded or None
        )

    def _question(self, name: str) -> str:
        a = self.kb.ability(name)
        return a.question if a else f"Does the robot need to {name}?"

    def next_question(self, cands: Sequence[Candidate], settled: set[str]) -> Question | None:
        """The ability whose answer narrows ``cands`` most, or None when none does.

        "yes" keeps the candidates that could have the ability (``potential``: with grown
        parts or added modules); "no" keeps those whose declared parts do not give it. An
        ability is asked only when either answer drops someone; the best one leaves the
        fewest candidates in its worse case (ties: the short name's alphabetical order).
        """
        best: tuple[int, str] | None = None
        n = len(cands)
        for kif in sorted({a for c in cands for a in c.potential} - settled):
            yes = sum(kif in c.potential for c in cands)
            no = n - sum(kif in c.declared for c in cands)
            if yes < n and no < n:
                key = (max(yes, no), self.short(kif))
                best = key if best is None or key < best else best
        if best is None:
            return None
        return Question(best[1], self._question(best[1]))

    def conflict(self, req: Request) -> tuple[str, ...]:
        """The smallest set of demands (abilities, answers, parameters) that no robot meets.

        Tries subsets by size, each a re-solve under new externals (no regrounding).
        """
        if not self.reasoner.satisfiable(Query()):
            raise OntologyError(
                "the knowledge base admits no robot at all (no instance of BaseConfiguration, "
                "or rules that contradict each other)"
            )
        demands: list[tuple[str, Request]] = []
        demands += [(a, Request(abilities=(a,))) for a in dict.fromkeys(req.abilities)]
        demands += [
            (f"{a}={'yes' if y else 'no'}", Request(answers=((a, y),))) for a, y in req.answers
        ]
        # physical parameters never change what the reasoner admits: only the ontology's
        demands += [
            (f"{p}={v}", Request(params=((p, v),)))
            for p, v in req.params
            if self.kb.parameter(p) is not None
        ]
        for size in range(1, len(demands) + 1):
            for combo in itertools.combinations(demands, size):
                merged = Request(
                    abilities=tuple(x for _, r in combo for x in r.abilities),
                    answers=tuple(x for _, r in combo for x in r.answers),
                    params=tuple(x for _, r in combo for x in r.params),
                )
                if not self.reasoner.satisfiable(self.query(merged)):
                    return tuple(name for name, _ in combo)
        return tuple(name for name, _ in demands)

    def describe(self, robot_type: str) -> Candidate:
        """The parts and abilities of any robot class, as declared (explain)."""
        focused = self.reasoner.focused(self.robot_type(robot_type))
        sol = focused.solve(Query())
        if not sol.candidates:
            raise OntologyError(f"{robot_type}: the reasoner found no model to describe it")
        return sol.candidates[0]
