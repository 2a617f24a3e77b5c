"""A rule file may not define, declare external, show, project or steer a predicate the
encodings derive in any syntactic form clingo accepts (issue 23, item 5): pools in heads
and in arguments, choices, conditional heads, disjunctions, head aggregates, double
negation, classical negation, ``#external``, ``#show``, ``#project`` and ``#heuristic``.
Each case below forged an answer (or changed the dialogue) before the check walked the
whole parse tree; each is refused with exit 2 and file:line:col."""

from __future__ import annotations

from pathlib import Path

import pytest

from adron.errors import InputError
from synth.reasoning.solver import read_rule_files

DESIGN = ["design", "--no-verify", "walking", "--answer", "grasping=no", "--conceptual"]
NO_ROUGH = ["--answer", "rough-terrain-walking=no", "--json"]

#: (case, rule file text, where it is refused, what the message names)
FORMS = [
    ("pool in a fact", 'chosen("A";"B").\n', "1:1", "define chosen/1"),
    ("pool in an argument", 'chosen(("A";"B")).\n', "1:1", "define chosen/1"),
    ("pool in a choice", '{ chosen("A";"B") }.\n', "1:3", "define chosen/1"),
    ("pool in an external", '#external chosen("A";"B").\n', "1:11", "define chosen/1"),
    ("pool of isa", 'isa(("Leg";"Arm"), "Robot").\n', "1:1", "define isa/2"),
    ("pool of isa pairs", 'isa("Leg","Robot";"Arm","Robot").\n', "1:1", "define isa/2"),
    (
        "pool of has_ability",
        'x.\nhas_ability("A","Walking";"B","Walking").\n',
        "2:1",
        "define has_ability/2",
    ),
    ("pool of count", 'count("A","Leg",4;"B","Leg",4).\n', "1:1", "define count/3"),
    ("pool of candidate", 'candidate("FakeBot";"FakeBot2").\n', "1:1", "define candidate/1"),
    ("pool of focus", 'focus("A";"B").\n', "1:1", "define focus/1"),
    ("pool in a rule head", 'mine(1).\nchosen("A";"B") :- mine(1).\n', "2:1", "define chosen/1"),
    ("conditional head", "chosen(X) : mine(X).\n", "1:1", "define chosen/1"),
    ("second disjunct", 'mine(1) | chosen("A").\n', "1:11", "define chosen/1"),
    ("semicolon disjunction", 'mine(1) ; chosen("A") :- mine(2).\n', "1:11", "define chosen/1"),
    ("bounded choice", '1 { mine(1); chosen("B") } 1.\n', "1:14", "define chosen/1"),
    ("head aggregate", '#count { 1 : chosen("A") } = 1.\n', "1:14", "define chosen/1"),
    ("double negation", 'not not chosen("A").\n', "1:9", "define chosen/1"),
    ("classical negation", '-chosen("A").\n', "1:1", "define chosen/1"),
    ("conditional external", "#external chosen(X) : mine(X). [true]\n", "1:11", "define chosen/1"),
    ("another program part", '#program extra.\nchosen("A").\n', "2:1", "define chosen/1"),
    ("show a term", '#show chosen("A").\n', "1:7", "define chosen/1"),
    ("show a pool", '#show chosen("A";"B").\n', "1:7", "define chosen/1"),
    ("show a parenthesised pool", '#show (mine(1);chosen("B")).\n', "1:16", "define chosen/1"),
    ("show a signature", "#show candidate/1.\n", "1:1", "define candidate/1"),
    ("show a variable", '#show X : X = chosen("A").\n', "1:7", "may not show the term X"),
    ("show a negated variable", '#show -X : X = chosen("A").\n', "1:8", "may not show the term"),
    ("show another arity", '#show chosen("A", 1).\n', "1:7", "may not show chosen/2"),
    (
        "show another arity's signature",
        'chosen("A", 1).\n#show chosen/2.\n',
        "2:1",
        "show chosen/2",
    ),
    ("heuristic", '#heuristic chosen("A"). [10, true]\n', "1:12", "define chosen/1"),
    ("project an atom", '#project chosen("A";"B").\n', "1:10", "define chosen/1"),
    ("project a signature", "#project chosen/1.\n", "1:1", "define chosen/1"),
]


@pytest.mark.parametrize(
    ("text", "where", "what"), [f[1:] for f in FORMS], ids=[f[0] for f in FORMS]
)
def test_every_form_of_a_protected_predicate_is_refused(
    cli, tmp_path: Path, text: str, where: str, what: str
) -> None:
    path = tmp_path / "forge.lp"
    path.write_text(text, encoding="utf-8")
    r = cli(*DESIGN, "--rules", str(path))
    assert r.code == 2, (r.out, r.err)
    assert f"{path}:{where}: a rule file may not " in r.err, r.err
    assert what in r.err and "Traceback" not in r.err
    assert r.out == ""


#: uses of protected predicates that define nothing: constraints, bodies, conditions,
#: a choice of their negation, their name at another arity (not shown), own #show terms
ALLOWED = [
    ':- chosen("X").\n',
    'not chosen("X").\n',
    "mine(R) : chosen(R).\n",
    "mine(R) :- chosen(R), #count { A : has_ability(R, A) } > 0.\n",
    "count(1, 2).\nchosen(1, 2).\n",
    "#show mine/1.\n#show mine(R) : chosen(R).\n#show (R, 1) : chosen(R).\n",
    '#edge (a, b) : chosen("A").\n',
    "#heuristic mine(1). [1, true]\n",
    "#show.\n",
]


@pytest.mark.parametrize("text", ALLOWED)
def test_what_defines_nothing_protected_is_read(tmp_path: Path, text: str) -> None:
    path = tmp_path / "ok.lp"
    path.write_text(text, encoding="utf-8")
    (rule,) = read_rule_files([path], allow_scripts=False)
    assert rule.text == text


def test_allowed_forms_leave_the_answer_alone(cli, tmp_path: Path) -> None:
    path = tmp_path / "ok.lp"
    path.write_text("".join(t for t in ALLOWED if ":- chosen" not in t and "not chosen" not in t))
    r = cli(*DESIGN, *NO_ROUGH, "--rules", str(path))
    assert r.code == 0, r.err
    plain = cli(*DESIGN, *NO_ROUGH)
    assert r.out == plain.out


def test_a_forged_pool_never_reaches_the_solver(tmp_path: Path) -> None:
    path = tmp_path / "forge.lp"
    path.write_text('% a forged answer\ncandidate("FakeBot";"FakeBot2").\n', encoding="utf-8")
    with pytest.raises(InputError, match=r"forge\.lp:2:1: a rule file may not define candidate/1"):
        read_rule_files([path], allow_scripts=False)
