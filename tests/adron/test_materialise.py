"""Materialising the ontology's rules (adron/materialise.py) and caching the knowledge base
(adron/kb.py): the same answer, a cache that is never stale."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest

from adron import kb as kbmod
from adron import materialise as mat
from adron.errors import ParmorError
from adron.kb import load as _load_kb
from adron.kb import materialised
from synth.reasoning.solver import Query, Reasoner, encoding_dir


def load(*args, **kwargs):
    """A knowledge base with its rules materialised, as the reasoner's worker has it (load
    leaves that to the worker, where a limit or Ctrl-C can stop clingo's grounding)."""
    return materialised(_load_kb(*args, **kwargs))


PICK = Query(requests=("RobotPickAndPlace",), params=(("handledObjectShape", "BoxObject"),))
WALK = Query(requests=("RobotWalking",))

#: rules over the ontology only: a robot type derived through a rule chain
RULES = """
(subclass MyWalker LeggedRobot)
(instance MyWalker BaseConfiguration)
(fastKind MyWalker)
(=> (fastKind ?X) (speedy ?X))
(=> (speedy ?X) (subclass ?X WalkingRobotKind))
"""


def _kif(tmp_path: Path, text: str, name: str = "mine.kif") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _answer(kb, query: Query = WALK) -> list[tuple]:
    r = Reasoner(kb)
    try:
        sol = r.solve(query)
    finally:
        r.close()
    return [(c.robot_type, c.parts, c.modules, c.abilities, c.preference) for c in sol.candidates]


@pytest.fixture(autouse=True)
def _no_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PARMOR_CACHE", "")


def test_kif_taxonomy_is_the_encodings_taxonomy() -> None:
    """The encodings derive holds atoms by KIF_TAXONOMY's rules and by the request's
    parameters only: what materialise() assumes."""
    ours = {re.sub(r"\s+", "", ln) for ln in mat.KIF_TAXONOMY.splitlines()}
    theirs = set()
    for lp in sorted(encoding_dir().glob("*.lp")):
        for ln in lp.read_text(encoding="utf-8").splitlines():
            if ln.startswith("holds(") and ":-" in ln:
                theirs.add(re.sub(r"\s+", "", ln))
    assert theirs == ours | {"holds(Rel,T):-param(Rel,T)."}


def test_a_rule_deriving_parameter_values_stops_materialisation(tmp_path: Path) -> None:
    text = RULES + "(=> (speedy ?X) (parameterValue handledObjectShape fast ?X))\n"
    kb = load([_kif(tmp_path, text)])
    assert kb.grounded is kb.translation and "parameterValue" in (kb.why_not or "")


def test_ontology_rules_are_replaced_by_their_facts(tmp_path: Path) -> None:
    kb = load([_kif(tmp_path, RULES)])
    assert kb.why_not is None
    rules = [u for u in kb.grounded.units if u.kind == "rule"]
    assert all(u.where.startswith("shapes.kif") for u in rules)  # they read the request
    derived = {(u.relation, u.args) for u in kb.grounded.units if u.where == mat.DERIVED}
    assert ("subclass", ("MyWalker", "WalkingRobotKind")) in derived
    assert ("speedy", ("MyWalker",)) in derived
    plain = dataclasses.replace(kb, grounded=None)
    assert _answer(kb) == _answer(plain)


def test_rules_reading_the_request_are_kept() -> None:
    kb = load()
    assert kb.grounded is kb.translation
    assert "request" in (kb.why_not or "")


def test_materialising_a_rule_that_reads_the_request_would_change_the_answer(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The case built to fail: forcing the shipped shape rules (they read the request's
    ``handledObjectShape``) into facts loses what they derive from the request."""
    kb = load()
    good = _answer(kb, PICK)
    monkeypatch.setattr(mat, "_open_rules", lambda tr, pairs: ([False] * 4, None))
    forced, why = mat.materialise(kb.translation)
    assert why is None and not any(u.kind == "rule" for u in forced.units)
    bad = _answer(dataclasses.replace(kb, grounded=forced), PICK)
    assert bad != good


def test_cache_hit_miss_corrupt_and_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cache = tmp_path / "cache"
    monkeypatch.setenv("PARMOR_CACHE", str(cache))
    src = _kif(tmp_path, RULES)
    first = load([src])
    files = list(cache.glob("kb-*.pickle"))
    assert len(files) == 1
    hit = load([src])
    assert hit == first and hit is not first
    assert _answer(hit) == _answer(first)
    # a changed file misses
    src.write_text(RULES + "(subclass OtherWalker LeggedRobot)\n", encoding="utf-8")
    changed = load([src])
    assert changed != first and len(list(cache.glob("kb-*.pickle"))) == 2
    # a corrupt file is ignored (and replaced)
    src.write_text(RULES, encoding="utf-8")
    files[0].write_bytes(b"parmor-kb-1 not a pickle")
    assert load([src]) == first
    # PARMOR_CACHE= turns it off
    monkeypatch.setenv("PARMOR_CACHE", "")
    for f in cache.glob("kb-*.pickle"):
        f.unlink()
    assert load([src]) == first
    assert not list(cache.glob("kb-*.pickle"))


def test_an_error_is_reported_again_and_never_cached(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cache = tmp_path / "cache"
    monkeypatch.setenv("PARMOR_CACHE", str(cache))
    src = _kif(tmp_path, RULES + "(subclass Broken\n")
    messages = []
    for _ in range(2):
        with pytest.raises(ParmorError) as e:
            load([src])
        messages.append(str(e.value))
    assert messages[0] == messages[1] and "mine.kif:" in messages[0]
    assert not list(cache.glob("kb-*.pickle"))


def test_an_unwritable_cache_only_costs_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x", encoding="utf-8")
    monkeypatch.setenv("PARMOR_CACHE", str(blocker / "sub"))
    assert load([_kif(tmp_path, RULES)]).why_not is None


@pytest.mark.parametrize("name", ["Merge.kif", "engineering.kif", "tinySUMO.kif"])
def test_sumo_materialised_gives_the_same_answer(name: str) -> None:
    from tests.conftest import require_shared

    sumo = require_shared("kif/sumo")
    files = [sumo / "Merge.kif"] if name != "tinySUMO.kif" else []
    if name != "Merge.kif":
        files.append(sumo / name)
    kb = load(files)
    assert _answer(kb) == _answer(dataclasses.replace(kb, grounded=None))


def test_cache_key_covers_the_code() -> None:
    assert "materialise.py" in kbmod._CODE and "translate.py" in kbmod._CODE


def test_relevant_program_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The cached relevant program is the one computed; a cut-short file is ignored."""
    from synth.reasoning import solver

    monkeypatch.setenv("PARMOR_CACHE", str(tmp_path / "cache"))
    kb = load([_kif(tmp_path, RULES)])
    assert kb.key is not None
    fresh = solver._relevant_program(kb, None, (), kb.grounded)
    (path,) = (tmp_path / "cache").glob("relevant-*.lp")
    assert solver._relevant_program(kb, None, (), kb.grounded) == fresh
    path.write_text(path.read_text(encoding="utf-8")[:-10], encoding="utf-8")
    calls = []
    real = solver.relevant
    monkeypatch.setattr(solver, "relevant", lambda *a: calls.append(1) or real(*a))
    assert solver._relevant_program(kb, None, (), kb.grounded) == fresh and calls
    # another focus is another entry; rule files are never cached
    solver._relevant_program(kb, "MyWalker", (), kb.grounded)
    solver._relevant_program(kb, None, ("p.",), kb.translation)
    assert len(list((tmp_path / "cache").glob("relevant-*.lp"))) == 2


def test_ontology_check_reports_materialised_rules(cli, tmp_path: Path) -> None:
    r = cli("ontology", "check", str(_kif(tmp_path, RULES)), "--json")
    assert r.code == 0
    rec = json.loads(r.out)["relevance"]
    assert rec["materialised_rules"] == 2 and rec["derived_facts"] >= 2
    assert rec["unfiltered_because"] is None
    r = cli("ontology", "check", str(_kif(tmp_path, RULES)))
    assert "2 rule(s) read only the ontology" in r.out


def test_prune_keeps_the_most_recently_used(tmp_path: Path) -> None:
    import os

    for i in range(5):
        p = tmp_path / f"kb-{i}.pickle"
        p.write_bytes(b"x")
        os.utime(p, ns=(i * 10**9, i * 10**9))
    (tmp_path / "units-x.json").write_text("{}", encoding="utf-8")
    kbmod.prune(tmp_path, keep=2)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "kb-3.pickle",
        "kb-4.pickle",
        "units-x.json",
    ]


def test_a_large_knowledge_base_is_cached_by_a_detached_process(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past ``BACKGROUND_STORE_UNITS`` forms the cache file is written by a grandchild
    process while ``load`` returns: it appears whole (never a partial file under its
    name) and a later load reads it; an unwritable cache folder costs nothing."""
    import time

    cache = tmp_path / "cache"
    monkeypatch.setenv("PARMOR_CACHE", str(cache))
    monkeypatch.setattr(kbmod, "BACKGROUND_STORE_UNITS", 0)
    src = _kif(tmp_path, RULES)
    first = _load_kb([src])
    # the grandchild's write: waited for (the loop ends when it appears), with a bound far
    # above any machine's load, not a guess at how long it takes (20 s failed under load)
    for _ in range(6000):
        if list(cache.glob("kb-*.pickle")):
            break
        time.sleep(0.1)
    (hit,) = cache.glob("kb-*.pickle")
    assert _load_kb([src]) == first
    assert kbmod._cached(hit, first.files) == first  # read from the file itself
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("PARMOR_CACHE", str(blocked))
    assert _load_kb([src]) == first


def test_ontology_check_counts_only_the_users_files(cli, tmp_path: Path) -> None:
    """``ontology check`` reads one load of the shipped ontology with the user's files;
    its counts are those of the user's files alone (``Translation.by_file``), as a
    translation of those files by themselves counts them."""
    import json

    from adron.kif import parse
    from adron.translate import translate

    a = _kif(tmp_path, RULES)
    b = tmp_path / "b.kif"
    b.write_text('(subclass B1 Robot)\n(documentation B1 EnglishLanguage "b")\n(foo ?X)\n')
    r = cli("ontology", "check", str(a), str(b), "--json")
    assert r.code == 0, r.err
    rec = json.loads(r.out)
    alone = translate([f for p in (a, b) for f in parse(p.read_text(encoding="utf-8"), str(p))])
    assert rec["files"] == [str(a), str(b)]
    assert (rec["forms"], rec["facts"], rec["rules"], rec["metadata"]) == (
        alone.forms,
        alone.facts,
        alone.rules,
        alone.metadata,
    )
    assert rec["untranslated"] == len(alone.untranslated) == 1
    assert sum(sum(c) for c in alone.by_file.values()) - alone.forms == alone.translated
