"""Rule files: parmor resolves #include itself (confined, checked for #script) and refuses
rule files that define a predicate the encodings derive (chosen/1 and the rest)."""

from __future__ import annotations

from pathlib import Path

import pytest

from synth.reasoning.solver import protected_predicates

DESIGN = ["design", "--no-verify", "walking", "--answer", "grasping=no", "--conceptual"]
NO_ROUGH = ["--answer", "rough-terrain-walking=no", "--json"]


def write(path: Path, text: str) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return str(path)


def test_an_included_rule_applies(cli, tmp_path: Path) -> None:
    write(tmp_path / "sub" / "no-quadruped.lp", ':- chosen("QuadrupedRobot").\n')
    main = write(tmp_path / "main.lp", '% see sub/\n#include "sub/no-quadruped.lp".\n')
    r = cli(*DESIGN, *NO_ROUGH)
    assert r.code == 0 and "QuadrupedRobot" in r.out
    r = cli(*DESIGN, *NO_ROUGH, "--rules", main)
    assert r.code == 1, r.err
    assert '"status": "unsatisfiable"' in r.out


def test_an_included_script_is_refused(cli, tmp_path: Path) -> None:
    write(tmp_path / "s.lp", "a.\n#script (python)\ndef f():\n    return 1\n#end.\n")
    main = write(tmp_path / "main.lp", '#include "s.lp".\n')
    r = cli(*DESIGN, "--rules", main)
    assert r.code == 2
    assert f"{tmp_path / 's.lp'}:2:1" in r.err and "--allow-scripts" in r.err
    assert "Traceback" not in r.err


@pytest.mark.parametrize("target", ["../outside.lp", "/etc/passwd", "sub/../../outside.lp"])
def test_an_include_outside_the_folder_is_refused(cli, tmp_path: Path, target: str) -> None:
    write(tmp_path / "outside.lp", "secret_line_of_text.\n")
    main = write(tmp_path / "rules" / "main.lp", f'a.\n  #include "{target}".\n')
    (tmp_path / "rules" / "sub").mkdir()
    r = cli(*DESIGN, "--rules", main)
    assert r.code == 2
    assert f"{main}:2:3" in r.err and "leaves the folder" in r.err
    assert "secret" not in r.err and "root:" not in r.err
    if not target.startswith("/"):
        r = cli(*DESIGN, *NO_ROUGH, "--rules", main, "--allow-scripts")
        assert r.code == 0, r.err


def test_a_commented_include_is_not_followed(cli, tmp_path: Path) -> None:
    main = write(
        tmp_path / "main.lp",
        '% #include "/etc/passwd".\n%* #include "none.lp". *%\nq("#include \\"x.lp\\".").\n',
    )
    r = cli(*DESIGN, *NO_ROUGH, "--rules", main)
    assert r.code == 0, r.err


def test_a_missing_include_names_the_directive(cli, tmp_path: Path) -> None:
    main = write(tmp_path / "main.lp", "\n#include <none.lp>.\n")
    r = cli(*DESIGN, "--rules", main)
    assert r.code == 2
    assert f"{main}:2:1" in r.err and "none.lp" in r.err


def test_a_syntax_error_in_an_included_file_names_it(cli, tmp_path: Path) -> None:
    write(tmp_path / "broken.lp", "a.\nfoo( :- .\n")
    main = write(tmp_path / "main.lp", '#include "broken.lp".\n')
    r = cli(*DESIGN, "--rules", main)
    assert r.code == 2
    assert "broken.lp:2" in r.err and "Traceback" not in r.err


def test_include_cycles_are_read_once(cli, tmp_path: Path) -> None:
    write(tmp_path / "a.lp", '#include "b.lp".\nmine(1).\n')
    main = write(tmp_path / "b.lp", '#include "a.lp".\nmine(2).\n')
    r = cli(*DESIGN, *NO_ROUGH, "--rules", main)
    assert r.code == 0, r.err


@pytest.mark.parametrize(
    ("text", "where", "pred"),
    [
        ('chosen("WheeledRobot").\n', "1:1", "chosen/1"),
        ("a.\n{ chosen(R) : robot_class(R) } = 1.\n", "2:3", "chosen/1"),
        ('focus("QuadrupedRobot").\n', "1:1", "focus/1"),
        ('x.\n  isa("Leg", "Robot").\n', "2:3", "isa/2"),
        ('#external has_ability("a", "b").\n', "1:11", "has_ability/2"),
        ("#show chosen(X) : base(X).\n", "1:7", "chosen/1"),
        ("need(A) | excluded(A) :- action(A).\n", "1:1", "need/1"),
    ],
)
def test_a_rule_file_may_not_define_a_derived_predicate(
    cli, tmp_path: Path, text: str, where: str, pred: str
) -> None:
    path = write(tmp_path / "forge.lp", text)
    r = cli(*DESIGN, "--rules", path)
    assert r.code == 2, r.err
    assert f"{path}:{where}: a rule file may not define {pred}" in r.err
    # included, it is refused just the same
    main = write(tmp_path / "main.lp", '#include "forge.lp".\n')
    assert cli(*DESIGN, "--rules", main).code == 2


def test_knowledge_and_constraints_are_allowed(cli, tmp_path: Path) -> None:
    path = write(
        tmp_path / "ok.lp",
        'holds("unneededAbility", "RobotGrasping").\nmine(R) :- chosen(R).\n:- chosen("X").\n',
    )
    r = cli(*DESIGN, *NO_ROUGH, "--rules", path)
    assert r.code == 0, r.err


def test_the_protected_predicates_are_the_derived_ones() -> None:
    p = protected_predicates()
    for sig in [("chosen", 1), ("candidate", 1), ("need", 1), ("isa", 2), ("focus", 1)]:
        assert sig in p
    assert not any(name == "holds" for name, _ in p)


def test_files_in_the_working_folder_do_not_replace_the_encodings(
    cli, tmp_path: Path, monkeypatch
) -> None:
    """clingo looks for an ``#include``d file in the working folder first: parmor inlines
    its own encodings' includes, so a user's ``choice.lp`` there changes nothing."""
    monkeypatch.chdir(tmp_path)
    for name in ("choice.lp", "taxonomy.lp", "show.lp"):
        write(tmp_path / name, "{ a(1..40) }.\n:- not a(1).\n")
    r = cli("design", "driving", "--no-input", "--conceptual", "--json", "--time-limit", "20")
    assert r.code == 0, r.err
    assert '"robot_type": "DifferentialDriveRobot"' in r.out
