"""KIF -> ASP translation: table of patterns, the untranslated report, determinism, SUMO."""

from __future__ import annotations

import clingo
import pytest

from adron.kb import builtin_files, load
from adron.kif import parse, parse_file
from adron.translate import translate
from tests.conftest import require_shared

TRANSLATED = [
    (
        "class fact",
        "(subclass HexapodRobot LeggedRobot)",
        ['holds("subclass","HexapodRobot","LeggedRobot").'],
    ),
    ("numbers and strings", '(p "a\\b; (c" -3 0.5)', ['holds("p","a\\\\b; (c",-3,"0.5").']),
    (
        "function term",
        "(weight Robot1 (MeasureFn 3 Kilogram))",
        ['holds("weight","Robot1",fn("MeasureFn",3,"Kilogram")).'],
    ),
    (
        "horn rule",
        "(=> (and (p ?X) (q ?X ?Y)) (r ?Y))",
        ['holds("r",V_Y) :- holds("p",V_X), holds("q",V_X,V_Y).'],
    ),
    (
        "default negation and equality",
        "(=> (and (p ?X) (q ?Y) (not (s ?X)) (not (equal ?X ?Y))) (r ?X))",
        ['holds("r",V_X) :- holds("p",V_X), holds("q",V_Y), not holds("s",V_X), V_X != V_Y.'],
    ),
    (
        "conjunctive head",
        "(=> (p ?X) (and (q ?X) (r ?X)))",
        ['holds("q",V_X) :- holds("p",V_X).', 'holds("r",V_X) :- holds("p",V_X).'],
    ),
    (
        "biconditional",
        "(<=> (p ?X) (q ?X))",
        ['holds("q",V_X) :- holds("p",V_X).', 'holds("p",V_X) :- holds("q",V_X).'],
    ),
    (
        "variable names with dashes",
        "(=> (p ?leg-1) (q ?leg-1))",
        ['holds("q",V_leg_2d_1) :- holds("p",V_leg_2d_1).'],
    ),
    (
        "variable names stay distinct after escaping",
        "(=> (and (p ?X-1) (q ?X_1)) (r ?X-1 ?X_1))",
        ['holds("r",V_X_2d_1,V_X__1) :- holds("p",V_X_2d_1), holds("q",V_X__1).'],
    ),
    (
        "existential part axiom",
        "(=> (instance ?R Biped) (exists (?L1 ?L2) (and (instance ?L1 Leg) (instance ?L2 Leg)"
        " (robotPart ?L1 ?R) (robotPart ?L2 ?R) (connectedTo ?L1 Trunk) (not (equal ?L1 ?L2)))))",
        [
            'exists_axiom(1,"Biped").',
            'witness(1,"?L1","Leg").',
            'witness(1,"?L2","Leg").',
            'link(1,"robotPart","?L1",self).',
            'link(1,"robotPart","?L2",self).',
            'link(1,"connectedTo","?L1",c("Trunk")).',
        ],
    ),
    (
        "the paper's (not (equal (?a ?b))) form",
        "(=> (instance ?R B) (exists (?a ?b) (and (instance ?a L) (instance ?b L)"
        " (robotPart ?a ?R) (robotPart ?b ?R) (not (equal (?a ?b))))))",
        ['witness(1,"?a","L").', 'witness(1,"?b","L").'],
    ),
    (
        "untyped witness",
        "(=> (instance ?R B) (exists (?a) (part ?a ?R)))",
        ['witness(1,"?a","Entity").', 'link(1,"part","?a",self).'],
    ),
]


@pytest.mark.parametrize(("case", "kif", "lines"), TRANSLATED, ids=[c[0] for c in TRANSLATED])
def test_translates(case: str, kif: str, lines: list[str]) -> None:
    tr = translate(parse(kif, "t.kif"))
    assert tr.untranslated == ()
    program = tr.program.splitlines()
    for line in lines:
        assert line in program
    clingo.Control().add("base", [], tr.program)  # the output is valid ASP


UNTRANSLATED = [
    ("unsafe head variable", "(=> (p ?X) (q ?Y))", "unsafe variable ?Y"),
    ("unsafe negated variable", "(=> (and (p ?X) (not (q ?Z))) (r ?X))", "unsafe variable ?Z"),
    ("top-level forall", "(forall (?X) (p ?X))", "top-level 'forall'"),
    ("disjunction in a body", "(=> (or (p ?X) (q ?X)) (r ?X))", "'or' in a rule body"),
    (
        "existential in a rule head",
        "(=> (p ?X) (exists (?Y) (q ?X ?Y)))",
        "'exists' in a rule head",
    ),
    ("free variable in a fact", "(p ?X)", "free variables"),
    ("row variable", "(=> (p @ROW) (q @ROW))", "row variable"),
    ("variable predicate", "(=> (and (p ?R) (?R a b)) (q ?R))", "variable in predicate position"),
    ("negated conclusion", "(=> (p ?X) (not (q ?X)))", "'not' in a rule head"),
    (
        "disjunction in an existential axiom",
        "(=> (instance ?R B) (exists (?a) (or (part ?a ?R) (connected ?a ?R))))",
        "literal",
    ),
]


@pytest.mark.parametrize(("case", "kif", "reason"), UNTRANSLATED, ids=[c[0] for c in UNTRANSLATED])
def test_reports_untranslated(case: str, kif: str, reason: str) -> None:
    tr = translate(parse("(subclass A B)\n\n  " + kif, "u.kif"))
    assert tr.facts == 1 and tr.translated == 1
    assert len(tr.untranslated) == 1
    u = tr.untranslated[0]
    assert (u.file, u.line, u.col) == ("u.kif", 3, 3)
    assert reason in u.reason
    assert u.location == "u.kif:3:3"


def test_metadata_is_kept_for_explain_not_sent_to_the_solver() -> None:
    tr = translate(parse('(documentation Leg EnglishLanguage "A limb; (with parens")', "d.kif"))
    assert tr.metadata == 1 and tr.program.strip() == ""
    assert tr.documentation == {"Leg": "A limb; (with parens"}


def test_translation_is_deterministic(kb) -> None:
    again = load()
    assert again.translation.program == kb.translation.program
    assert again.translation.sources == kb.translation.sources


def test_adron_translates_completely(kb) -> None:
    t = kb.translation
    assert t.untranslated == ()
    assert t.translated == t.forms
    assert t.axioms >= 20
    assert {f for f, _ in builtin_files()} == set(kb.files)


def test_axiom_sources_point_at_the_kif_text(kb) -> None:
    texts = dict(builtin_files())
    for src in kb.translation.sources:
        line = texts[src.file].splitlines()[src.line - 1]
        assert line[src.col - 1] == "("
        assert line[src.col - 1 :].startswith("(=>")


def test_sumo_merge_translates_with_a_full_report() -> None:
    sumo = require_shared("kif/sumo")
    forms = parse_file(sumo / "Merge.kif")
    tr = translate(forms)
    assert tr.forms == 5504
    assert tr.translated + len(tr.untranslated) == 5504
    assert tr.facts > 3000 and tr.rules > 0 and len(tr.untranslated) > 100
    assert all(u.file.endswith("Merge.kif") and u.line > 0 for u in tr.untranslated)
    clingo.Control().add("base", [], tr.program)  # syntactically valid ASP


@pytest.mark.parametrize(
    ("kif", "where"),
    [
        ("(abilityName RobotWalking)", "bad.kif:2:1"),
        ("(parameterName objSize)", "bad.kif:2:1"),
        ("(abilityName FooAct 3)", "bad.kif:2:1"),
        ('(structuralLimit SkidSteerRobot "payload")', "bad.kif:2:1"),
    ],
)
def test_malformed_vocabulary_facts_are_ontology_errors(tmp_path, kif, where) -> None:
    from adron.errors import OntologyError

    f = tmp_path / "bad.kif"
    f.write_text("(subclass A B)\n" + kif + "\n", encoding="utf-8")
    with pytest.raises(OntologyError, match=where.replace("bad.kif", ".*bad.kif")):
        load([f])
