"""The fast path (asp/every.lp: every candidate in one answer set; the first query's
externals grounded as facts) gives what the choice of one candidate per answer set gives,
for every kind of query: abilities, answers, the bus limit excluding some candidates,
conflicts, and queries after the first."""

from __future__ import annotations

import itertools

import pytest

import synth.reasoning.solver as solver
from adron.kb import load
from synth.reasoning.solver import Query, Reasoner


def _kif(n: int) -> str:
    """``n`` robot types with 1-7 legs (1-7 x 3 actuators: some over a small bus limit),
    every third with a gripper arm."""
    out = []
    for i in range(n):
        legs = 1 + i % 7
        names = [f"?L{j}" for j in range(legs)]
        parts = " ".join(f"(instance {v} RobotLeg) (robotPart {v} ?R)" for v in names)
        if i % 3 == 0:
            names.append("?G")
            parts += " (instance ?G RobotGripper) (robotPart ?G ?R)"
        out.append(f"(subclass Gen{i} LeggedRobot)\n(instance Gen{i} BaseConfiguration)")
        out.append(
            f"(=> (instance ?R Gen{i}) (exists ({' '.join(names)} ?T) (and {parts} "
            "(instance ?T RobotTrunk) (robotPart ?T ?R))))"
        )
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def kbs(tmp_path_factory):
    path = tmp_path_factory.mktemp("every") / "gen.kif"
    path.write_text(_kif(14), encoding="utf-8")
    return {"shipped": load(), "generated": load([path])}


def _both(kb, bus_limit, monkeypatch) -> tuple[Reasoner, Reasoner]:
    fast = Reasoner(kb, bus_limit=bus_limit)
    monkeypatch.setattr(solver, "EVERY_IN_ONE", False)
    choice = Reasoner(kb, bus_limit=bus_limit)
    monkeypatch.setattr(solver, "EVERY_IN_ONE", True)
    return fast, choice


def _queries(kb) -> list[Query]:
    names = sorted(a.kif for a in kb.abilities)
    out = [Query()]
    out += [Query(requests=(a,)) for a in names]
    out += [Query(requests=pair) for pair in itertools.combinations(names[:6], 2)]
    out += [Query(answers=((a, yes),)) for a in names for yes in (True, False)]
    out += [Query(requests=(names[0],), answers=((names[0], False),))]  # a conflict
    return out


@pytest.mark.parametrize("which", ["shipped", "generated"])
@pytest.mark.parametrize("bus_limit", [None, 8, 14])
def test_every_in_one_answers_as_the_choice_does(kbs, which, bus_limit, monkeypatch) -> None:
    kb = kbs[which]
    fast, choice = _both(kb, bus_limit, monkeypatch)
    try:
        seen = set()
        for q in _queries(kb):
            a, b = fast.solve(q), choice.solve(q)
            assert a == b, q
            assert fast.satisfiable(q) == choice.satisfiable(q) == a.satisfiable
            assert fast.answer_sets(q) == choice.answer_sets(q)
            seen.add(len(a.candidates))
        assert 0 in seen and len(seen) > 2  # conflicts, and several sizes of answer
    finally:
        fast.close()
        choice.close()


def test_the_bus_limit_drops_candidates_on_the_fast_path(kbs) -> None:
    """A case built to fail if the fast path ignored the limit: a small bus drops the
    many-legged types."""
    kb = kbs["generated"]
    wide, narrow = Reasoner(kb), Reasoner(kb, bus_limit=8)
    try:
        many = {c.robot_type for c in wide.solve(Query()).candidates}
        few = {c.robot_type for c in narrow.solve(Query()).candidates}
        assert few < many
        assert all(c.active_total <= 8 for c in narrow.solve(Query()).candidates)
    finally:
        wide.close()
        narrow.close()


@pytest.mark.parametrize("which", ["shipped", "generated"])
def test_the_first_query_as_facts_answers_as_the_choice_does(kbs, which, monkeypatch) -> None:
    """A reasoner grounded for its first query (as facts) answers it, and then any other
    query (on a program with externals, grounded then), as the choice does."""
    kb = kbs[which]
    queries = _queries(kb)[::3]
    fast, choice = _both(kb, 14, monkeypatch)
    fast.close()
    try:
        for k, q in enumerate(queries):
            first = Reasoner(kb, bus_limit=14, first=q)
            try:
                other = queries[(k + 1) % len(queries)]
                for asked in (q, other, q):
                    assert first.solve(asked) == choice.solve(asked), asked
                assert first.satisfiable(q) == choice.satisfiable(q)
                assert first.answer_sets(q) == choice.answer_sets(q)
            finally:
                first.close()
    finally:
        choice.close()


def test_a_first_query_unknown_to_the_knowledge_base_is_refused(kbs) -> None:
    from adron.errors import InputError

    bogus = Query(requests=("NoSuchAction",))
    r = Reasoner(kbs["shipped"], first=bogus)
    try:
        with pytest.raises(InputError, match="not known to the knowledge base"):
            r.solve(bogus)
        assert r.solve(Query()).candidates
    finally:
        r.close()


def test_shown_atoms_read_from_their_text_as_from_the_symbol() -> None:
    """The reader takes strings and integers from an atom's text, and anything it cannot
    read safely (commas, quotes, escapes in strings, nested terms) from the symbol."""
    import clingo
    from clingo import Function as F
    from clingo import Number as N
    from clingo import String as S

    from synth.reasoning.solver import _read_symbol, _str

    cases = [
        F("p"),
        F("p", [S("a"), S("b"), N(3)]),
        F("p", [S("a,b"), N(1)]),
        F("p", [S('a"b')]),
        F("p", [F("f", [N(1), N(2)]), S("x")]),
        F("p", [F("", [N(1), N(2)])]),
        F("p", [N(-3), S("")]),
        F("p", [S("x"), F("c"), N(1)]),
        F("p", [S("("), S(")")]),
        F("p", [S("a\\")]),
        F("p", [S('",')]),
        F("p", [S('","')]),
        F("p", [S('"')]),
    ]
    for sym in cases:
        ref = tuple(
            _str(a) if a.type != clingo.SymbolType.Number else a.number for a in sym.arguments
        )
        assert _read_symbol(str(sym), sym) == (sym.name, ref), str(sym)
