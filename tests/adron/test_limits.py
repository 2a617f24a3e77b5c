"""Limits (time, memory, ground size), Ctrl-C at any stage, and the taxonomy at scale.

No timing thresholds: a limit case asserts the exit code and the message; the Ctrl-C test
allows 10 s where the issue asks for 1 s (measured figures: README "Limits").
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from adron.kb import load
from adron.translate import taxonomy_closure
from synth import limits
from synth.reasoning.solver import Query, Reasoner

REPO = Path(__file__).resolve().parents[2]
CONCEPTUAL = ["design", "walking", "--answer", "grasping=no", "--conceptual"]
NO_ROUGH = ["--answer", "rough-terrain-walking=no"]
#: grounds for minutes and to gigabytes: what the limits must stop
BLOW_UP = "p(X) :- X = 1..100000000.\n"


def rules(tmp_path: Path, text: str, name: str = "r.lp") -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def one_line(err: str) -> None:
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err


# --- Ctrl-C ---------------------------------------------------------------------------------


def test_ctrl_c_during_grounding_exits_130_and_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "bundle"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    args = [*CONCEPTUAL, "--rules", rules(tmp_path, BLOW_UP), "--out", str(out)]
    p = subprocess.Popen(
        [sys.executable, "-m", "synth.commands.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        cwd=tmp_path,
    )
    time.sleep(3.0)  # past parsing (about 0.3 s), well into grounding
    assert p.poll() is None, p.communicate()
    p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        p.kill()
        pytest.fail("parmor did not stop within 10 s of Ctrl-C while grounding")
    assert p.returncode == 130, err
    assert b"interrupted" in err and b"Traceback" not in err
    assert not out.exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["r.lp"]


# --- limits -------------------------------------------------------------------------------------


def test_memory_limit_during_grounding(cli, tmp_path: Path) -> None:
    r = cli(*CONCEPTUAL, "--rules", rules(tmp_path, BLOW_UP), "--memory-limit", "150")
    assert r.code == 1, r.err
    assert "memory limit (150 MB, --memory-limit)" in r.err
    assert "stage ground" in r.err and "r.lp" in r.err
    one_line(r.err)


def test_time_limit_during_grounding(cli, tmp_path: Path) -> None:
    r = cli(*CONCEPTUAL, "--rules", rules(tmp_path, BLOW_UP), "--time-limit", "1")
    assert r.code == 1, r.err
    assert "time limit (1 s, --time-limit)" in r.err and "stage ground" in r.err
    one_line(r.err)


def test_time_limit_during_solving(cli, tmp_path: Path) -> None:
    # 2^40 answer sets: enumeration never ends
    r = cli(*CONCEPTUAL, "--rules", rules(tmp_path, "{ a(1..40) }.\n"), "--time-limit", "1")
    assert r.code == 1, r.err
    assert "time limit" in r.err and "stage solve" in r.err
    one_line(r.err)


def test_size_limit_names_the_predicate_and_the_rule(cli, tmp_path: Path) -> None:
    text = "ok.\nbig(X) :- X = 1..300000.\n"
    r = cli(*CONCEPTUAL, "--rules", rules(tmp_path, text), "--size-limit", "50000")
    assert r.code == 1, r.err
    assert "size limit (50000 atoms, --size-limit)" in r.err and "stage size" in r.err
    assert "big/1" in r.err and "r.lp:2:1" in r.err
    one_line(r.err)


def test_limits_off_and_within_give_the_design(cli) -> None:
    base = [*CONCEPTUAL, *NO_ROUGH, "--json"]
    for extra in ([], ["--time-limit", "0", "--memory-limit", "0", "--size-limit", "0"]):
        r = cli(*base, *extra)
        assert r.code == 0, r.err
        assert '"robot_type": "QuadrupedRobot"' in r.out


@pytest.mark.parametrize("value", ["-1", "nan", "inf", "1e309", "x", ""])
@pytest.mark.parametrize("option", ["--time-limit", "--memory-limit", "--size-limit"])
def test_bad_limit_values_are_refused(cli, option: str, value: str) -> None:
    r = cli(*CONCEPTUAL, option, value)
    assert r.code == 2
    assert option in r.err and "Traceback" not in r.err


def test_library_limits_and_reuse(tmp_path: Path) -> None:
    kb = load()
    limits.configure(limits.Limits(size_atoms=1000), arm=False)
    try:
        with pytest.raises(limits.LimitExceeded) as e:
            Reasoner(kb)
        assert e.value.stage == "size" and e.value.exit_code == 1
    finally:
        limits.configure(limits.Limits(), arm=False)
    r = Reasoner(kb)
    first = r.solve(Query())
    assert r.solve(Query()) == first  # the worker answers many queries
    r.close()
    with pytest.raises(Exception, match="stopped"):
        r.solve(Query())


# --- the taxonomy at scale ----------------------------------------------------------------------


def chain(n: int, top: str) -> str:
    return (
        "".join(f"(subclass C{i} C{i + 1})\n" for i in range(n - 1))
        + f"(subclass C{n - 1} {top})\n"
    )


@pytest.mark.parametrize(
    "kif",
    [
        chain(20_000, "Entity"),  # recursive ASP: 2e8 pairs (it hung at 3,000)
        chain(5_000, "Robot"),  # 5,000 robot classes, none of them a base configuration
        "".join(f"(subclass W{i} Robot)\n" for i in range(20_000)),
    ],
    ids=["deep", "deep-robots", "wide-robots"],
)
def test_deep_and_wide_taxonomies_design_as_before(cli, tmp_path: Path, kif: str) -> None:
    path = tmp_path / "big.kif"
    path.write_text(kif, encoding="utf-8")
    r = cli(*CONCEPTUAL, *NO_ROUGH, "--json", "--ontology", str(path))
    assert r.code == 0, r.err
    assert '"robot_type": "QuadrupedRobot"' in r.out


def test_closure_pairs_reach_every_anchor() -> None:
    prog = "".join(f'holds("subclass","c{i}","c{i + 1}").\n' for i in range(5))
    facts = taxonomy_closure(prog, ['x("c0"). y("c5"). z(X) :- isa(X, "c5").'])
    assert facts is not None
    assert 'holds("subclass","c0",("c1";"c2";"c3";"c4";"c5")).' in facts
    assert 'holds("subclass",("c1";"c2";"c3";"c4"),"c5").' in facts
    assert "c2" not in facts.replace('"c2";', "")  # no pair between two non-anchors
    # no rule reads c5's descendants by a variable: the unnamed ones' pairs are left out,
    # a translated rule that does read them keeps them
    alone = taxonomy_closure(prog, ['x("c0"). y("c5").'])
    assert alone is not None and '"c5").' not in alone.replace('class("c5").', "")
    # and c0's pairs upwards go to the anchors only (no rule reads c0's ancestors freely)
    assert 'holds("subclass","c0",("c5")).' in alone
    read = taxonomy_closure(prog + 'z(V_X) :- holds("subclass",V_X,"c5").\n', ['x("c0").'])
    assert read is not None and 'holds("subclass",("c1";"c2";"c3";"c4"),"c5").' in read
    up = taxonomy_closure(prog + 'z(V_Y) :- holds("subclass","c0",V_Y).\n', ['y("c5").'])
    assert up is not None and 'holds("subclass","c0",("c1";"c2";"c3";"c4";"c5")).' in up
    # a rule that derives taxonomy facts, or a rule file that mentions it: exact fallback
    assert taxonomy_closure(prog + 'holds("subclass","a","b") :- q.\n') is None
    assert taxonomy_closure(prog, user=[':- isa("c0", X), bad(X).']) is None


def test_closure_program_drops_only_edges_nothing_names() -> None:
    """The program the closure returns leaves out the direct edges between two classes
    that no other line names, keeps every other line in order, and names as class/1 only
    the named classes; a rule reading the taxonomy with both arguments free keeps it all
    (the recursive fallback)."""
    from adron.translate import closed_taxonomy

    edges = [f'holds("subclass","c{i}","c{i + 1}").' for i in range(5)]
    prog = "\n".join([edges[0], 'p("c0").', *edges[1:], 'q("c5").']) + "\n"
    found = closed_taxonomy(prog)
    assert found is not None
    kept, facts = found
    # c0-c1 and c4-c5 touch a named class; c1-c2, c2-c3, c3-c4 do not
    assert kept.splitlines() == [edges[0], 'p("c0").', edges[4], 'q("c5").']
    assert sorted(ln for ln in facts.splitlines() if ln.startswith("class(")) == [
        'class("c0").',
        'class("c5").',
    ]
    # what the dropped edges gave is still in the closure: c0 reaches c5
    assert 'holds("subclass","c0",("c5")).' in facts
    free = prog + 'r(X,Y) :- holds("subclass",V_X,V_Y), s(V_X), t(V_Y).\n'
    assert closed_taxonomy(free) is None


def _hung_below_every_class() -> str:
    """KIF: below every class of the shipped ontology a chain of two classes nothing else
    names, above each base configuration a class between it and its parent, above every
    top class (and above Robot) classes nothing names; plus a rule that reads RobotLeg's
    descendants by a variable (a leg becomes its refinement)."""
    kb = load()
    out = []
    for n, (sub, sup) in enumerate(kb.translation.relation("subclass")):
        out.append(f"(subclass Hung{n}a {sub})\n(subclass Hung{n}b Hung{n}a)")
        if (sub,) in {(b,) for b, c in kb.translation.relation("instance")}:
            out.append(f"(subclass {sub} Mid{n})\n(subclass Mid{n} {sup})")
    out.append("(=> (subclass ?X RobotLeg) (refinedPart RobotLeg ?X))")
    subs = {a for a, _ in kb.translation.relation("subclass")}
    tops = sorted({b for _, b in kb.translation.relation("subclass")} - subs)
    for n, top in enumerate(tops):  # two classes nothing names above every top class
        out.append(f"(subclass {top} Above{n}a)\n(subclass Above{n}a Above{n}b)")
    out.append("(subclass Robot AboveRobot)")
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("hung", [False, True], ids=["shipped", "hung-below-every-class"])
def test_python_closure_answers_as_the_recursive_one(tmp_path: Path, hung: bool) -> None:
    """Every base configuration's design, with the closure computed once and with the
    recursive rules (a rule file that mentions the taxonomy forces them); also with
    classes that nothing names hung below every class and between each base configuration
    and its parent (the closure leaves out their pairs where no rule reads them)."""
    files = []
    if hung:
        files = [tmp_path / "hung.kif"]
        files[0].write_text(_hung_below_every_class(), encoding="utf-8")
    kb = load(files)
    forced = rules(tmp_path, '% reads "subclass" pairs: the exact recursive closure\n')
    fast, exact = Reasoner(kb), Reasoner(kb, [forced])
    assert fast.robot_types == exact.robot_types
    assert fast.answer_sets(Query()) == exact.answer_sets(Query())
    for t in fast.robot_types:
        if hung and t.startswith("Hung") and not t.endswith(("0a", "0b")):
            continue  # every other hung robot class is alike
        a, b = fast.focused(t), exact.focused(t)
        assert a.answer_sets(Query()) == b.answer_sets(Query()), t


def test_a_derived_subclass_is_closed(tmp_path: Path) -> None:
    """A KIF rule that concludes a subclass fact: the closure must see it (fallback)."""
    path = tmp_path / "derived.kif"
    path.write_text(
        "(instance Switch Entity)\n(=> (instance Switch Entity) (subclass Walker9 LeggedRobot))\n",
        encoding="utf-8",
    )
    kb = load([path])
    assert "Walker9" in Reasoner(kb).robot_types


def test_actuator_assignment_isa_facts_match_the_grounded_taxonomy() -> None:
    """The actuator assignment takes isa/2 from Python (isa_facts); the same pairs as
    grounding the whole knowledge base with the exact recursive closure, for every class."""
    import clingo

    from adron.translate import asp_string, isa_facts
    from synth.reasoning.solver import encoding_dir

    kb = load()
    ctl = clingo.Control(["--warn=none"])
    ctl.add("base", [], kb.translation.program)
    ctl.load(str(encoding_dir() / "closure.lp"))
    ctl.load(str(encoding_dir() / "taxonomy.lp"))
    ctl.ground([("base", [])])
    grounded = {str(a.symbol) for a in ctl.symbolic_atoms.by_signature("isa", 2)}
    names = sorted({c for args in kb.translation.relation("subclass") for c in args} | {"Nope"})
    facts = isa_facts(kb.translation.program, [asp_string(c) for c in names], ["activeModuleLimit"])
    assert facts is not None
    mine = {line[:-1] for line in facts.splitlines() if line.startswith("isa(")}
    assert mine == grounded  # every class of ADROn (and one that is none) asked
    assert 'holds("activeModuleLimit",' in facts
    derived = kb.translation.program + 'holds("activeModuleLimit","X",1) :- q.\n'
    assert isa_facts(derived, ['"Robot"'], ["activeModuleLimit"]) is None
