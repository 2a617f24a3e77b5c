"""Tests of the ``parmor`` command line (synth.commands.cli), run in-process through ``main(argv)``.

Exit codes (docs/architecture.md): 0 done; 1 the request cannot be met; 2 bad input; 3 an answer is
needed and input is off.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from adron.kb import builtin_files
from synth.reasoning.conceptual import Request

REPO = Path(__file__).resolve().parents[3]
LEGGED = {"HumanoidRobot", "QuadrupedRobot", "HexapodRobot"}
DESIGN_KEYS = {
    "status",
    "robot_type",
    "candidates",
    "questions",
    "conflict",
    "parts",
    "modules",
    "dof",
    "abilities",
}
GRASP_QUESTION = "Does the robot need to grasp?"


def enumerated(text: str) -> dict:
    """``enumerate --json`` prints JSON lines: candidates, then a summary; as one dict."""
    lines = [json.loads(line) for line in text.splitlines()]
    assert lines and lines[-1]["type"] == "summary"
    assert all(x["type"] == "candidate" for x in lines[:-1])
    return {**lines[-1], "candidates": lines[:-1]}


def counts(rows: list[dict]) -> dict[str, int]:
    """[{"kind": K, "count": N}, ...] -> {K: total N} (a kind may come in several models)."""
    out: dict[str, int] = {}
    for r in rows:
        out[r["kind"]] = out.get(r["kind"], 0) + r["count"]
    return out


def no_traceback(r) -> None:
    assert "Traceback" not in r.err
    assert "Traceback" not in r.out


def legged_robot_kif(name: str, legs: int) -> str:
    """A base configuration on ``legs`` MultipedLegs and a trunk, in robots.kif's style."""
    ls = [f"?L{i}" for i in range(1, legs + 1)]
    inst = " ".join(f"(instance {v} MultipedLeg)" for v in ls)
    parts = " ".join(f"(robotPart {v} ?ROB)" for v in ls)
    conn = " ".join(f"(connectedTo {v} ?TRUNK)" for v in ls)
    return (
        f"(subclass {name} LeggedRobot)\n"
        f"(instance {name} BaseConfiguration)\n"
        "(=>\n"
        f"  (instance ?ROB {name})\n"
        f"  (exists ({' '.join(ls)} ?TRUNK)\n"
        "    (and\n"
        f"      {inst}\n"
        "      (instance ?TRUNK RobotTrunk)\n"
        f"      {parts}\n"
        "      (robotPart ?TRUNK ?ROB)\n"
        f"      {conn})))\n"
    )


# --- help ------------------------------------------------------------------------------


def test_help_mentions_every_command(cli) -> None:
    r = cli("--help")
    assert r.code == 0
    for command in ("abilities", "design", "enumerate", "explain", "ontology", "regress"):
        assert re.search(rf"^\s+{command}\b", r.out, re.M), command


def test_design_help(cli) -> None:
    r = cli("design", "--help")
    assert r.code == 0
    for option in ("--answer", "--param", "--no-input", "--out", "--force", "--json"):
        assert option in r.out


def test_usage_error_exits_2(cli) -> None:
    r = cli("design")  # no ABILITY
    assert r.code == 2
    assert "ABILITY" in r.err  # argparse's usage message, on the err stream given to main
    no_traceback(r)


# --- abilities ---------------------------------------------------------------------------


def test_abilities_lists_every_declared_ability(cli, kb) -> None:
    r = cli("abilities")
    assert r.code == 0
    listed = [line.split()[0] for line in r.out.splitlines() if line.strip()]
    assert listed == [a.name for a in kb.abilities]
    assert len(kb.abilities) >= 10


def test_abilities_json(cli, kb) -> None:
    r = cli("abilities", "--json")
    assert r.code == 0
    rows = json.loads(r.out)
    assert [row["ability"] for row in rows] == [a.name for a in kb.abilities]
    for row, a in zip(rows, kb.abilities, strict=True):
        assert {"ability", "kif", "question", "robot_types"} <= set(row)
        assert row["kif"] == a.kif
        assert row["question"] == a.question
        assert row["question"].startswith("Does the robot need to ")
        assert isinstance(row["robot_types"], list)
    by_name = {row["ability"]: row for row in rows}
    assert set(by_name["walking"]["robot_types"]) == LEGGED
    assert by_name["rough-terrain-walking"]["robot_types"] == ["HexapodRobot"]
    assert by_name["grasping"]["question"] == GRASP_QUESTION


# --- design: the question ------------------------------------------------------------------


def test_design_no_input_needs_an_answer(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--no-input")
    assert r.code == 3
    for t in LEGGED:
        assert t in r.out
    assert GRASP_QUESTION in r.err
    assert "--answer grasping=yes" in r.err
    no_traceback(r)


def test_design_no_input_json(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--no-input", "--json")
    assert r.code == 3
    d = json.loads(r.out)
    assert d["status"] == "ambiguous"
    assert set(d["candidates"]) == LEGGED
    assert len(d["candidates"]) == 3
    assert d["questions"][-1] == {"ability": "grasping", "text": GRASP_QUESTION, "answer": None}
    assert d["robot_type"] is None
    assert d["parts"] == []


def test_design_non_terminal_stdin_needs_an_answer(cli) -> None:
    r = cli("design", "--no-verify", "walking", stdin="y\n", tty=False)
    assert r.code == 3
    assert GRASP_QUESTION in r.err


def test_design_answered(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--json")
    assert r.code == 0, r.err
    d = json.loads(r.out)
    assert set(d) >= DESIGN_KEYS
    assert d["status"] == "designed"
    assert d["robot_type"] == "HumanoidRobot"
    assert d["candidates"] == ["HumanoidRobot"]
    assert d["conflict"] == []
    assert d["questions"] == [{"ability": "grasping", "text": GRASP_QUESTION, "answer": "yes"}]
    parts = counts(d["parts"])
    assert parts["BipedLeg"] == 2  # inherited from BipedalRobot
    # named by both BipedalRobot (RobotTrunk) and HumanoidRobot (HumanoidTorso, refining it): one
    assert parts["HumanoidTorso"] == 1 and "RobotTrunk" not in parts
    assert parts["HumanoidArm"] == 2
    modules = counts(d["modules"])
    # 2 legs x 6 joints + 2 arms x 2 joints; gripper actuators are not degrees of freedom
    assert modules["PositionServomotor"] == 16
    assert modules["GripperServomotor"] == 2
    joints = sum(
        n for k, n in modules.items() if k.endswith("Servomotor") and k != "GripperServomotor"
    )
    assert d["dof"] == joints == 16
    assert {"grasping", "walking"} <= set(d["abilities"])
    assert d["abilities"] == sorted(d["abilities"])


def test_design_text(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes")
    assert r.code == 0
    assert "HumanoidRobot" in r.out
    assert "BipedLeg x2" in r.out
    assert "dof:        16" in r.out


# --- design: interactive dialogue ------------------------------------------------------------


@pytest.mark.parametrize(
    ("replies", "robot"),
    [("n\nn\n", "QuadrupedRobot"), ("n\ny\n", "HexapodRobot"), ("y\n", "HumanoidRobot")],
)
def test_dialogue(cli, replies: str, robot: str) -> None:
    r = cli("design", "--no-verify", "walking", "--json", stdin=replies, tty=True)
    assert r.code == 0, r.err
    d = json.loads(r.out)
    assert d["status"] == "designed"
    assert d["robot_type"] == robot
    assert GRASP_QUESTION in r.err
    asked = [q["ability"] for q in d["questions"]]
    assert asked[0] == "grasping"
    assert len(asked) == replies.count("\n")
    assert all(q["answer"] in ("yes", "no") for q in d["questions"])


def test_dialogue_second_question_is_rough_terrain(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--json", stdin="n\nn\n", tty=True)
    d = json.loads(r.out)
    assert [(q["ability"], q["answer"]) for q in d["questions"]] == [
        ("grasping", "no"),
        ("rough-terrain-walking", "no"),
    ]


def test_dialogue_reasks_after_invalid_reply(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--json", stdin="maybe\nyes\n", tty=True)
    assert r.code == 0, r.err
    assert json.loads(r.out)["robot_type"] == "HumanoidRobot"
    assert r.err.count(GRASP_QUESTION) == 2
    assert "please answer y or n" in r.err


@pytest.mark.parametrize("stdin", ["", "n\n"])
def test_dialogue_eof_needs_an_answer(cli, stdin: str) -> None:
    r = cli("design", "--no-verify", "walking", stdin=stdin, tty=True)
    assert r.code == 3
    no_traceback(r)


def test_dialogue_not_used_with_no_input(cli) -> None:
    r = cli("design", "--no-verify", "walking", "--no-input", stdin="y\n", tty=True)
    assert r.code == 3


# --- bad input: exit 2 with a suggestion -------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "expect"),
    [
        (["design", "walkin"], ["walkin", "walking"]),
        (["enumerate", "walkin"], ["walking"]),
        (["design", "walking", "--answer", "graspin=yes"], ["grasping"]),
        (["design", "walking", "--param", "object_shap=oval"], ["object_shape"]),
        (["design", "pick-and-place", "--param", "object_shape=ovall"], ["oval"]),
        (["design", "walking", "--answer", "grasping"], ["grasping", "yes"]),
        (["design", "walking", "--answer", "grasping=maybe"], ["grasping=maybe"]),
        (["design", "walking", "--param", "x"], ["NAME=VALUE"]),
        (["explain", "HexapodRobt"], ["HexapodRobt", "HexapodRobot"]),
        (
            ["design", "walking", "--answer", "grasping=yes", "--answer", "grasping=no"],
            ["grasping"],
        ),
        (["enumerate", "walking", "--limit", "-1"], ["--limit"]),
    ],
)
def test_bad_input_exits_2(cli, argv: list[str], expect: list[str]) -> None:
    r = cli(*argv)
    assert r.code == 2
    assert r.out == ""
    for word in expect:
        assert word in r.err
    assert r.err.startswith("parmor: error: ")
    no_traceback(r)


def test_suggestions_are_did_you_mean(cli) -> None:
    assert "did you mean: walking" in cli("design", "--no-verify", "walkin").err
    r = cli("design", "--no-verify", "walking", "--param", "object_shap=a")
    assert "did you mean: object_shape" in r.err
    r = cli("design", "--no-verify", "pick-and-place", "--param", "object_shape=ovall")
    assert "did you mean: oval" in r.err
    assert "did you mean: HexapodRobot" in cli("explain", "HexapodRobt").err


# --- cannot be met: exit 1 ---------------------------------------------------------------------


@pytest.mark.parametrize("order", [("rolling", "grasping"), ("grasping", "rolling")])
def test_unsatisfiable_names_the_conflict(cli, order: tuple[str, str]) -> None:
    r = cli("design", "--no-verify", *order, "--json")
    assert r.code == 1
    d = json.loads(r.out)
    assert d["status"] == "unsatisfiable"
    assert d["conflict"] == list(order)
    assert d["candidates"] == []
    assert d["robot_type"] is None
    for a in order:
        assert a in r.err


def test_unsatisfiable_conflict_is_minimal(cli) -> None:
    r = cli("design", "--no-verify", "rolling", "grasping", "line-tracking", "--json")
    assert r.code == 1
    assert json.loads(r.out)["conflict"] == ["rolling", "grasping"]
    assert "rolling" in r.err and "grasping" in r.err
    assert "line-tracking" not in r.err


def test_unsatisfiable_answer_is_part_of_the_conflict(cli) -> None:
    r = cli("design", "--no-verify", "rough-terrain-walking", "--answer", "walking=no", "--json")
    assert r.code == 1
    assert json.loads(r.out)["conflict"] == ["rough-terrain-walking", "walking=no"]


# --- --out -------------------------------------------------------------------------------------


def test_out_writes_design_json(cli, tmp_path: Path) -> None:
    out = tmp_path / "bundle"
    r = cli(
        "design", "--no-verify", "walking", "--answer", "grasping=yes", "--json", "--out", str(out)
    )
    assert r.code == 0, r.err
    assert (out / "design.json").read_text(encoding="utf-8") == r.out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle"]  # no temp folders left
    assert sorted(p.name for p in out.iterdir()) == [
        ".parmor",
        "README.md",
        "bom.csv",
        "design.json",
        "meshes",
        "pictures",
        "print",
        "robot.urdf",
        "robot.xml",
        "trajectories",
    ]
    walks = sorted(p.name for p in (out / "trajectories").iterdir())
    # a biped carries an IMU (KIF), so it can keep its balance: that behaviour is listed too
    assert walks == ["balancing.csv", "grasping.csv", "running.csv", "walking.csv"]
    assert all(p.suffix == ".stl" for p in (out / "meshes").iterdir())
    r = cli(
        "design",
        "walking",
        "--answer",
        "grasping=yes",
        "--json",
        "--conceptual",
        "--out",
        str(tmp_path / "conceptual"),
    )
    assert r.code == 0, r.err
    assert sorted(p.name for p in (tmp_path / "conceptual").iterdir()) == [".parmor", "design.json"]


def test_out_text_mode_writes_the_json_record(cli, tmp_path: Path) -> None:
    out = tmp_path / "bundle"
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--out", str(out))
    assert r.code == 0
    want = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--json").out
    assert (out / "design.json").read_text(encoding="utf-8") == want


def test_out_existing_needs_force(cli, tmp_path: Path) -> None:
    out = tmp_path / "bundle"
    out.mkdir()
    (out / "mine.txt").write_text("keep me", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--out", str(out))
    assert r.code == 2
    assert "--force" in r.err
    assert r.out == ""
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]
    assert (out / "mine.txt").read_text(encoding="utf-8") == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle"]
    # --force replaces only a folder parmor wrote: not this one
    argv = ["design", "--no-verify", "walking", "--answer", "grasping=yes", "--json"]
    r = cli(*argv, "--out", str(out), "--force")
    assert r.code == 2 and "not a folder parmor wrote" in r.err, r.err
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]

    ours = tmp_path / "ours"
    assert cli(*argv, "--conceptual", "--out", str(ours)).code == 0
    (ours / "mine.txt").write_text("added", encoding="utf-8")
    r = cli(*argv, "--out", str(ours), "--force")
    assert r.code == 0, r.err
    assert (ours / "mine.txt").read_text(encoding="utf-8") == "added"  # not parmor's: kept
    assert (ours / "design.json").read_text(encoding="utf-8") == r.out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bundle", "ours"]


@pytest.mark.parametrize(
    ("argv", "code"),
    [(["rolling", "grasping"], 1), (["walking", "--no-input"], 3), (["walking"], 3)],
)
def test_out_not_written_unless_designed(cli, tmp_path: Path, argv: list[str], code: int) -> None:
    out = tmp_path / "bundle"
    r = cli("design", "--no-verify", *argv, "--out", str(out), "--force")
    assert r.code == code
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


# --- enumerate ---------------------------------------------------------------------------------


def test_enumerate_text(cli, designer) -> None:
    r = cli("enumerate", "walking")
    assert r.code == 0
    listed = re.findall(r"^\d+\. (\w+)$", r.out, re.M)
    sol = designer.reasoner.solve(designer.query(Request(abilities=("walking",))))
    assert listed == [c.robot_type for c in sol.candidates]
    assert set(listed) == LEGGED
    assert listed[0] == "QuadrupedRobot"  # fewest active modules (14)
    assert r.out.rstrip().endswith("3 candidate(s)")


def test_enumerate_json(cli) -> None:
    r = cli("enumerate", "walking", "--json")
    assert r.code == 0
    d = enumerated(r.out)
    assert d["status"] == "enumerated"
    assert d["count"] == 3
    assert [c["robot_type"] for c in d["candidates"]] == [
        "QuadrupedRobot",
        "HexapodRobot",
        "HumanoidRobot",
    ]
    actives = [c["active_modules"] for c in d["candidates"]]
    assert actives == sorted(actives)
    hexapod = d["candidates"][1]
    assert counts(hexapod["parts"])["MultipedLeg"] == 6
    assert "rough-terrain-walking" in hexapod["abilities"]


def test_enumerate_limit(cli) -> None:
    r = cli("enumerate", "walking", "--limit", "1")
    assert r.code == 0
    assert re.findall(r"^\d+\. (\w+)$", r.out, re.M) == ["QuadrupedRobot"]
    assert "1 of 3 candidate(s)" in r.out
    d = enumerated(cli("enumerate", "walking", "--limit", "1", "--json").out)
    assert d["count"] == 3
    assert [c["robot_type"] for c in d["candidates"]] == ["QuadrupedRobot"]


def test_enumerate_sizes_candidates_on_the_cores_with_the_same_output(cli, monkeypatch) -> None:
    """By default ``enumerate`` sizes its candidates in one process per core (at most one
    per candidate); the output is the one of a single process, byte for byte."""
    import synth.commands.backend as backend

    used: list[int] = []
    real = backend.tasks

    def spy(engine, *a, **k):
        used.append(engine.jobs)
        return real(engine, *a, **k)

    monkeypatch.setattr(backend, "tasks", spy)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    default = cli("enumerate", "driving", "--json")
    one = cli("enumerate", "driving", "--json", "--jobs", "1")
    assert default.code == one.code == 0
    assert default.out == one.out
    assert used == [2, 1]


def test_enumerate_unsatisfiable(cli) -> None:
    r = cli("enumerate", "rolling", "grasping")
    assert r.code == 1
    assert "rolling" in r.err and "grasping" in r.err
    d = enumerated(cli("enumerate", "rolling", "grasping", "--json").out)
    assert d["status"] == "unsatisfiable"
    assert d["count"] == 0
    assert d["conflict"] == ["rolling", "grasping"]


# --- explain -----------------------------------------------------------------------------------


def _builtin_line(location: str) -> tuple[str, str]:
    """The line a ``file:LINE:COL`` location points at (shipped files), and the next one."""
    name, line, col = location.split(":")
    text = dict(builtin_files())[name].split("\n")
    return text[int(line) - 1][int(col) - 1 :], text[int(line)]


def test_explain_hexapod_text(cli) -> None:
    r = cli("explain", "HexapodRobot")
    assert r.code == 0
    m = re.search(r"^\s*MultipedLeg x6\s+\(HexapodRobot at (robots\.kif:\d+:\d+)\)", r.out, re.M)
    assert m, r.out
    start, nxt = _builtin_line(m.group(1))
    assert start.startswith("(=>")
    assert "(instance ?ROB HexapodRobot)" in nxt
    assert re.search(r"rough-terrain-walking: has 6 RobotLeg, needs 6", r.out)


def test_explain_hexapod_json(cli) -> None:
    r = cli("explain", "HexapodRobot", "--json")
    assert r.code == 0
    d = json.loads(r.out)
    assert d["robot_type"] == "HexapodRobot"
    legs = next(p for p in d["parts"] if p["kind"] == "MultipedLeg")
    assert legs["count"] == 6
    assert [(s["class"], s["inherited"]) for s in legs["declared_by"]] == [("HexapodRobot", False)]
    assert re.fullmatch(r"robots\.kif:\d+:\d+", legs["declared_by"][0]["location"])
    abilities = {a["ability"]: a for a in d["abilities"]}
    assert abilities["rough-terrain-walking"]["requires"] == [
        {"part": "RobotLeg", "needs": 6, "has": 6}
    ]
    assert d["dof"] == 18


def test_explain_humanoid_inheritance(cli) -> None:
    d = json.loads(cli("explain", "HumanoidRobot", "--json").out)
    parts = {p["kind"]: p for p in d["parts"]}
    assert parts["BipedLeg"]["count"] == 2
    assert [(s["class"], s["inherited"]) for s in parts["BipedLeg"]["declared_by"]] == [
        ("BipedalRobot", True)
    ]
    assert [(s["class"], s["inherited"]) for s in parts["HumanoidArm"]["declared_by"]] == [
        ("HumanoidRobot", False)
    ]
    start, nxt = _builtin_line(parts["BipedLeg"]["declared_by"][0]["location"])
    assert start.startswith("(=>")
    assert "(instance ?ROB BipedalRobot)" in nxt


# --- ontology check ----------------------------------------------------------------------------

SAMPLE_KIF = """\
(subclass Gizmo Device)
(instance Gizmo Artifact)
(documentation Gizmo EnglishLanguage "A test class.")
(=> (instance ?X Gizmo) (exists (?P) (and (instance ?P Device) (part ?P ?X))))
(=> (attribute ?X Shiny) (attribute ?X Bright))
(forall (?X) (p ?X))
"""


def test_ontology_check_counts(cli, tmp_path: Path) -> None:
    f = tmp_path / "sample.kif"
    f.write_text(SAMPLE_KIF, encoding="utf-8")
    r = cli("ontology", "check", str(f))
    assert r.code == 0, r.err
    assert (
        "6 forms in 1 file(s): 5 translated (2 facts, 1 rules, 1 existential axioms, "
        "1 metadata), 1 untranslated"
    ) in r.out
    assert f"{f}:6:1:" in r.out
    assert "forall" in r.out


def test_ontology_check_json(cli, tmp_path: Path) -> None:
    f = tmp_path / "sample.kif"
    f.write_text(SAMPLE_KIF, encoding="utf-8")
    r = cli("ontology", "check", str(f), "--json")
    assert r.code == 0
    d = json.loads(r.out)
    assert d["files"] == [str(f)]
    assert (d["forms"], d["translated"], d["untranslated"]) == (6, 5, 1)
    assert (d["facts"], d["rules"], d["existential_axioms"], d["metadata"]) == (2, 1, 1, 1)
    [u] = d["untranslated_forms"]
    assert (u["file"], u["line"], u["col"]) == (str(f), 6, 1)
    assert "forall" in u["reason"]
    assert u["text"] == "(forall (?X) (p ?X))"


def test_ontology_check_syntax_error(cli, tmp_path: Path) -> None:
    f = tmp_path / "bad.kif"
    f.write_text("(subclass A B)\n\n  (instance A (C)\n", encoding="utf-8")
    r = cli("ontology", "check", str(f))
    assert r.code == 2
    assert f"{f}:3:3" in r.err
    no_traceback(r)


def test_ontology_check_missing_file(cli, tmp_path: Path) -> None:
    r = cli("ontology", "check", str(tmp_path / "nope.kif"))
    assert r.code == 2
    assert "nope.kif" in r.err
    no_traceback(r)


# --- --rules ------------------------------------------------------------------------------------

NO_GRASP_NO_ROUGH = ["--answer", "grasping=no", "--answer", "rough-terrain-walking=no"]


def test_rules_file_changes_the_result(cli, tmp_path: Path) -> None:
    r = cli("design", "--no-verify", "walking", *NO_GRASP_NO_ROUGH, "--json")
    assert r.code == 0
    assert json.loads(r.out)["robot_type"] == "QuadrupedRobot"
    rules = tmp_path / "no-quadruped.lp"
    rules.write_text(':- chosen("QuadrupedRobot").\n', encoding="utf-8")
    r = cli("design", "--no-verify", "walking", *NO_GRASP_NO_ROUGH, "--rules", str(rules), "--json")
    assert r.code == 1
    assert json.loads(r.out)["status"] == "unsatisfiable"


def test_rules_file_with_script_is_refused(cli, tmp_path: Path) -> None:
    rules = tmp_path / "script.lp"
    rules.write_text("#script (python)\ndef f():\n    return 1\n#end.\n", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--rules", str(rules))
    assert r.code == 2
    assert "--allow-scripts" in r.err
    assert f"{rules}:1:1" in r.err
    no_traceback(r)


def test_rules_file_mentioning_script_anywhere_is_refused(cli, tmp_path: Path) -> None:
    # a comment is refused too: parmor does not guess where clingo's lexer sees comments
    rules = tmp_path / "comment.lp"
    rules.write_text("% #script (python) is not used here\n", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--rules", str(rules))
    assert r.code == 2 and "comment.lp:1:3" in r.err
    r = cli(
        "design",
        "walking",
        "--answer",
        "grasping=yes",
        "--rules",
        str(rules),
        "--allow-scripts",
        "--conceptual",
    )
    assert r.code == 0, r.err


def test_rules_file_syntax_error(cli, tmp_path: Path) -> None:
    rules = tmp_path / "broken.lp"
    rules.write_text("foo( :- .\n", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--rules", str(rules))
    assert r.code == 2
    assert r.err.startswith("parmor: error: ")
    no_traceback(r)


def test_rules_file_syntax_error_names_the_file(cli, tmp_path: Path) -> None:
    rules = tmp_path / "broken.lp"
    rules.write_text("a.\nfoo( :- .\n", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--rules", str(rules))
    assert r.code == 2
    assert "broken.lp:2" in r.err


def test_rules_file_missing(cli, tmp_path: Path) -> None:
    r = cli("design", "--no-verify", "walking", "--rules", str(tmp_path / "none.lp"))
    assert r.code == 2
    assert "none.lp" in r.err


# --- --ontology --------------------------------------------------------------------------------


def test_user_ontology_adds_a_base_configuration(cli, tmp_path: Path) -> None:
    f = tmp_path / "pentapod.kif"
    f.write_text(legged_robot_kif("PentapodRobot", 5), encoding="utf-8")
    r = cli("enumerate", "walking", "--ontology", str(f), "--json", "--conceptual")
    assert r.code == 0, r.err
    d = enumerated(r.out)
    assert d["count"] == 4
    cands = {c["robot_type"]: c for c in d["candidates"]}
    assert set(cands) == LEGGED | {"PentapodRobot"}
    penta = cands["PentapodRobot"]
    assert counts(penta["parts"]) == {"MultipedLeg": 5, "RobotTrunk": 1}
    assert penta["active_modules"] == 5 * 3 + 2
    assert penta["dof"] == 15
    # preference order: 14 (quadruped) < 17 (pentapod) < 20
    assert [c["robot_type"] for c in d["candidates"]][:2] == ["QuadrupedRobot", "PentapodRobot"]
    assert r.err == ""  # every form of the file translates: no note

    r = cli("design", "--no-verify", "walking", *NO_GRASP_NO_ROUGH, "--ontology", str(f), "--json")
    assert r.code == 0, r.err
    d = json.loads(r.out)
    assert d["status"] == "designed"
    assert d["candidates"] == ["QuadrupedRobot", "PentapodRobot"]
    assert d["robot_type"] == "QuadrupedRobot"
    assert d["chosen_by"] == "preference"
    assert "PentapodRobot" in d["note"]


def test_user_ontology_over_the_bus_limit_is_excluded(cli, tmp_path: Path) -> None:
    f = tmp_path / "octopod.kif"
    f.write_text(legged_robot_kif("OctopodRobot", 8), encoding="utf-8")
    # 8 legs x 3 servos + main + battery = 26 active modules > 24
    r = cli("explain", "OctopodRobot", "--ontology", str(f), "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["active_modules"] == 26
    r = cli("enumerate", "walking", "--ontology", str(f), "--json", "--conceptual")
    assert r.code == 0
    d = enumerated(r.out)
    assert "OctopodRobot" not in [c["robot_type"] for c in d["candidates"]]
    assert d["count"] == 3
    r = cli("design", "--no-verify", "rough-terrain-walking", "--ontology", str(f), "--json")
    assert r.code == 0
    assert json.loads(r.out)["candidates"] == ["HexapodRobot"]


def test_user_ontology_untranslated_note(cli, tmp_path: Path) -> None:
    f = tmp_path / "extra.kif"
    f.write_text("(subclass Gizmo Device)\n\n(forall (?X) (p ?X))\n", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--answer", "grasping=yes", "--ontology", str(f))
    assert r.code == 0
    assert f"{f}:3:1" in r.err
    assert "not translated" in r.err
    # the shipped ontology's own untranslated forms are never reported
    assert "robots.kif" not in r.err and "actions.kif" not in r.err


def test_user_ontology_named_like_a_shipped_file_still_gets_the_note(
    cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    Path("robots.kif").write_text("(forall (?X) (p ?X))\n", encoding="utf-8")
    r = cli("enumerate", "walking", "--ontology", "robots.kif")
    assert r.code == 0
    assert "not translated" in r.err


def test_user_ontology_syntax_error(cli, tmp_path: Path) -> None:
    f = tmp_path / "bad.kif"
    f.write_text("(subclass A B\n", encoding="utf-8")
    r = cli("design", "--no-verify", "walking", "--ontology", str(f))
    assert r.code == 2
    assert f"{f}:1:1" in r.err
    no_traceback(r)


# --- determinism -------------------------------------------------------------------------------

DETERMINISM_ARGV = ["design", "walking", "--answer", "grasping=yes", "--json"]


def test_same_output_in_process(cli) -> None:
    a = cli(*DETERMINISM_ARGV)
    b = cli(*DETERMINISM_ARGV)
    assert a.code == b.code == 0
    assert a.out == b.out
    c = cli("enumerate", "walking", "--json")
    assert c.out == cli("enumerate", "walking", "--json").out


@pytest.mark.parametrize(
    "argv", [DETERMINISM_ARGV, ["enumerate", "walking", "--json"]], ids=["design", "enumerate"]
)
def test_same_bytes_across_hash_seeds(argv: list[str]) -> None:
    """The two seeds' runs at once (each is one process): on two cores, the time of one."""
    from concurrent.futures import ThreadPoolExecutor

    def run(seed: str) -> subprocess.CompletedProcess:
        env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONHASHSEED": seed}
        return subprocess.run(
            [sys.executable, "-m", "synth.commands.cli", *argv],
            cwd=REPO,
            env=env,
            capture_output=True,
            timeout=120,
            check=False,
        )

    outs = []
    with ThreadPoolExecutor(2) as pool:
        for p in pool.map(run, ("1", "2")):
            assert p.returncode == 0, p.stderr.decode()
            outs.append(p.stdout)
    assert outs[0] == outs[1]
    assert enumerated(outs[0].decode()) if argv[0] == "enumerate" else json.loads(outs[0])


def test_prefetched_imports_finish_before_any_fork(tmp_path, monkeypatch) -> None:
    """The imports a full design needs are done when ``_prefetch`` returns (on the calling
    thread: tests/synth/commands/test_exit_paths.py), so no later fork (a worker, a process
    pool) starts
    with an import half done; a module that cannot be imported is left to where it is
    used."""
    import os
    import sys
    import time

    from synth.commands.cli import _prefetch

    (tmp_path / "parmor_slow_import.py").write_text(
        "import time\ntime.sleep(0.5)\nDONE = True\n", encoding="utf-8"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "parmor_slow_import", raising=False)
    start = time.perf_counter()
    _prefetch(["parmor_no_such_module", "parmor_slow_import"])
    pid = os.fork()
    if pid == 0:
        os._exit(0 if "parmor_slow_import" in sys.modules else 1)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0  # the child had the module whole
    assert sys.modules["parmor_slow_import"].DONE
    assert time.perf_counter() - start >= 0.5
