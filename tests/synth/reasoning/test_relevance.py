"""Relevance before grounding (adron/relevance.py): what cannot reach the robot vocabulary
is filtered, what can is kept, and the answer does not change."""

from __future__ import annotations

from pathlib import Path

import pytest

from adron.kb import load, materialised
from adron.relevance import Relevance
from synth.reasoning import solver
from synth.reasoning.solver import Query, Reasoner, relevant
from tests.conftest import require_shared

WALK = Query(requests=("RobotWalking",))

#: a robot type two subclass facts below the vocabulary, an axiom giving it a part kind that
#: reaches RobotLeg only through a chain, and things nothing reaches
MINE = """
(subclass MyGroundThing LeggedRobot)
(subclass MyWalker MyGroundThing)
(instance MyWalker BaseConfiguration)
(subclass MyLeg MyLimb)
(subclass MyLimb RobotLeg)
(=> (instance ?R MyWalker)
    (exists (?A ?B ?C ?D ?T)
      (and (instance ?A MyLeg) (instance ?B MyLeg) (instance ?C MyLeg) (instance ?D MyLeg)
           (instance ?T RobotTrunk)
           (robotPart ?A ?R) (robotPart ?B ?R) (robotPart ?C ?R) (robotPart ?D ?R)
           (robotPart ?T ?R))))
(subclass Banana Fruit)
(disjoint Banana Apple)
(=> (instance ?X Banana) (exists (?P) (and (instance ?P Peel) (part ?P ?X))))
"""


@pytest.fixture(autouse=True)
def _no_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    """No cached relevant program: these tests replace the filter."""
    monkeypatch.setenv("PARMOR_CACHE", "")


def _kif(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "mine.kif"
    p.write_text(text, encoding="utf-8")
    return p


def _units(kb, rel: Relevance, keep: bool) -> list[str]:
    return [
        "\n".join(u.lines) for u, k in zip(kb.translation.units, rel.kept, strict=True) if k == keep
    ]


def _unfiltered(monkeypatch: pytest.MonkeyPatch) -> None:
    def off(kb, focus=None, rules=(), grounded=False):
        n = len(kb.translation.units)
        return Relevance((True,) * n, ("",) * n, "off for the test")

    monkeypatch.setattr(solver, "relevant", off)


def _answer(kb) -> list[tuple]:
    sol = Reasoner(kb).solve(WALK)
    return [(c.robot_type, c.parts, c.modules, c.abilities, c.preference) for c in sol.candidates]


def test_chains_to_the_vocabulary_are_kept_and_the_rest_filtered(tmp_path: Path) -> None:
    kb = load([_kif(tmp_path, MINE)])
    rel = relevant(kb)
    assert rel.off is None
    kept, dropped = _units(kb, rel, True), _units(kb, rel, False)
    for name in ("MyWalker", "MyGroundThing", "MyLeg", "MyLimb"):
        assert any(f'"{name}"' in line for line in kept), name
    assert any('"Banana","Fruit"' in line for line in dropped)
    assert any('"disjoint"' in line for line in dropped)
    assert any('"Peel"' in line for line in dropped)
    # with the shipped ontology's own: e.g. defaultLength and defaultParameter facts (read
    # by Python only: synth/reasoning/plans.py, synth/params.py), the part classes no rule reads
    # (62 since CarRobot and TricycleRobot: their defaultLength, structuralLimit and
    # steered-driving's abilityVerb facts; 63 with pointing's abilityVerb)
    assert rel.counts == {"relation": 63, "class": 9, "axiom": 1}


def test_the_answer_is_unchanged_by_the_filter(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    kb = load([_kif(tmp_path, MINE)])
    filtered = _answer(kb)
    assert "MyWalker" in [c[0] for c in filtered]
    _unfiltered(monkeypatch)
    assert _answer(kb) == filtered


def test_filtering_too_much_changes_the_answer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The case built to fail: a filter that cut the chain MyLeg < MyLimb < RobotLeg (as
    one that kept only forms naming the vocabulary directly would) loses MyWalker's legs,
    and with them its walking; the real filter keeps the chain."""
    kb = load([_kif(tmp_path, MINE)])
    rel = relevant(kb)
    chain = [i for i, u in enumerate(kb.translation.units) if '"MyLeg","MyLimb"' in u.lines[-1]]
    assert chain and all(rel.kept[i] for i in chain)
    kept = list(rel.kept)
    for i in chain:
        kept[i] = False
    too_much = Relevance(tuple(kept), rel.reasons)
    monkeypatch.setattr(solver, "relevant", lambda *a, **k: too_much)
    assert "MyWalker" not in [c.robot_type for c in Reasoner(kb).solve(WALK).candidates]


def test_a_rule_the_filter_cannot_follow_turns_it_off(tmp_path: Path) -> None:
    """(=> (foo ?X) (subclass ?X Robot)) makes anything named by foo a robot type: the
    filter cannot tell which, so it filters nothing and says why."""
    text = MINE + "(=> (foo ?X) (subclass ?X Robot))\n(foo Banana)\n"
    rel = relevant(load([_kif(tmp_path, text)]))
    assert rel.off is not None and "reach Robot" in rel.off
    assert all(rel.kept)


def test_rule_files_turn_it_off(tmp_path: Path) -> None:
    rel = relevant(load([_kif(tmp_path, MINE)]), rules=['p :- holds("disjoint", X, Y).'])
    assert rel.off is not None and all(rel.kept)


def test_sumo_gives_the_same_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    sumo = require_shared("kif/sumo")
    kb = load([sumo / "Merge.kif"])
    filtered = _answer(kb)
    assert filtered == _answer(load())
    _unfiltered(monkeypatch)
    assert _answer(kb) == filtered


def test_ontology_check_reports_what_is_filtered(cli, tmp_path: Path) -> None:
    r = cli("ontology", "check", str(_kif(tmp_path, MINE)))
    assert r.code == 0
    assert "6 of 9 translated forms" in r.out
    assert "1 a relation no rule reads" in r.out
    assert "1 an axiom over a class that does not reach the robot vocabulary" in r.out


def test_many_candidates_read_by_robot_give_the_same_solution(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past solver._INDEXED candidates each model is read through an index by robot; the
    solution must equal the one read from all shown atoms."""
    text = "".join(
        f"(subclass Extra{i} LeggedRobot)\n(instance Extra{i} BaseConfiguration)\n"
        f"(=> (instance ?R Extra{i}) (exists (?A ?B ?T) (and (instance ?A RobotLeg) "
        f"(instance ?B RobotLeg) (instance ?T RobotTrunk) (robotPart ?A ?R) (robotPart ?B ?R) "
        f"(robotPart ?T ?R) (not (equal ?A ?B)))))\n"
        for i in range(solver._INDEXED + 6)
    )
    kb = load([_kif(tmp_path, text)])
    indexed = Reasoner(kb).solve(WALK)
    assert len(indexed.candidates) > solver._INDEXED
    monkeypatch.setattr(solver, "_INDEXED", 10**9)
    assert Reasoner(kb).solve(WALK) == indexed


def test_a_pass_reading_what_the_last_one_read_reuses_its_result(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The filter runs its passes until no deferred relation becomes active; a pass whose
    steps 2 and 3 read what an earlier pass's read reuses its result. Worked out again
    each time, the result is the same."""
    import adron.relevance as rel
    from synth.reasoning.solver import relevant

    kb = materialised(load())
    calls = {"pass": 0, "reached": 0}
    passes, reached = rel._relevance, rel._reached

    def count(name, f):
        def wrapped(*a, **k):
            calls[name] += 1
            return f(*a, **k)

        return wrapped

    monkeypatch.setattr(rel, "_relevance", count("pass", passes))
    monkeypatch.setattr(rel, "_reached", count("reached", reached))
    reused = relevant(kb, grounded=True)
    assert calls == {"pass": 2, "reached": 1}

    class Forgetful(dict):
        def __setitem__(self, key, value) -> None:
            pass

    real_init = rel._Index.__init__

    def forgetful_init(self, tr) -> None:
        real_init(self, tr)
        self.results = Forgetful()

    monkeypatch.setattr(rel._Index, "__init__", forgetful_init)
    calls.update({"pass": 0, "reached": 0})
    again = relevant(kb, grounded=True)
    assert calls == {"pass": 2, "reached": 2}
    assert again == reused
