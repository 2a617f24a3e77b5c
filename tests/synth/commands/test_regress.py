"""Tests of ``parmor regress`` (synth.commands.regress): suites of named design queries compared
with a snapshot stored beside the suite."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from synth.commands.regress import snapshot_path

QUERIES = {
    "humanoid": """\
[[query]]
name = "humanoid"
abilities = ["walking"]
answers = { grasping = "yes" }
""",
    "walk-ambiguous": """\
[[query]]
name = "walk-ambiguous"
abilities = ["walking"]
""",
    "snake-grasp": """\
[[query]]
name = "snake-grasp"
abilities = ["rolling", "grasping"]
""",
}

PENTAPOD = """\
(subclass PentapodRobot LeggedRobot)
(instance PentapodRobot BaseConfiguration)
(=>
  (instance ?ROB PentapodRobot)
  (exists (?L1 ?L2 ?L3 ?L4 ?L5 ?TRUNK)
    (and
      (instance ?L1 MultipedLeg) (instance ?L2 MultipedLeg) (instance ?L3 MultipedLeg)
      (instance ?L4 MultipedLeg) (instance ?L5 MultipedLeg)
      (instance ?TRUNK RobotTrunk)
      (robotPart ?L1 ?ROB) (robotPart ?L2 ?ROB) (robotPart ?L3 ?ROB)
      (robotPart ?L4 ?ROB) (robotPart ?L5 ?ROB)
      (robotPart ?TRUNK ?ROB))))
"""


def write_suite(path: Path, names: list[str] | None = None, header: str = "") -> Path:
    body = "\n".join(QUERIES[n] for n in (names or list(QUERIES)))
    path.write_text(header + "\n" + body, encoding="utf-8")
    return path


@pytest.fixture
def suite(tmp_path: Path) -> Path:
    return write_suite(tmp_path / "s.toml")


def status_lines(out: str) -> dict[str, str]:
    """name -> OK/CHANGED/NEW/GONE from the per-query lines of a run."""
    found = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0] in ("ok", "CHANGED", "NEW", "GONE"):
            found[parts[1]] = parts[0]
    return found


def no_traceback(r) -> None:
    assert "Traceback" not in r.err


# --- update and compare ------------------------------------------------------------------------


def test_update_writes_the_snapshot_beside_the_suite(cli, suite: Path) -> None:
    snap = suite.with_name("s.snapshot.json")
    assert snapshot_path(suite) == snap
    r = cli("regress", str(suite), "--update")
    assert r.code == 0, r.err
    assert snap.exists()
    assert "3 result(s)" in r.out
    data = json.loads(snap.read_text(encoding="utf-8"))
    assert list(data) == ["humanoid", "walk-ambiguous", "snake-grasp"]
    assert data["humanoid"]["status"] == "designed"
    assert data["humanoid"]["robot_type"] == "HumanoidRobot"
    assert data["walk-ambiguous"]["status"] == "ambiguous"
    assert data["walk-ambiguous"]["questions"][-1]["ability"] == "grasping"
    assert data["snake-grasp"]["status"] == "unsatisfiable"
    assert data["snake-grasp"]["conflict"] == ["rolling", "grasping"]
    assert sorted(p.name for p in suite.parent.iterdir()) == ["s.snapshot.json", "s.toml"]


def test_snapshot_records_are_what_design_json_prints(cli, suite: Path) -> None:
    assert cli("regress", str(suite), "--update").code == 0
    data = json.loads(snapshot_path(suite).read_text(encoding="utf-8"))
    for name, argv in [
        ("humanoid", ["walking", "--answer", "grasping=yes"]),
        ("walk-ambiguous", ["walking"]),
        ("snake-grasp", ["rolling", "grasping"]),
    ]:
        # a suite does not simulate unless it says verify = true: as design --no-verify
        printed = cli("design", *argv, "--no-input", "--no-verify", "--json").out
        assert data[name] == json.loads(printed), name


def test_update_is_deterministic(cli, suite: Path) -> None:
    assert cli("regress", str(suite), "--update").code == 0
    first = snapshot_path(suite).read_bytes()
    assert cli("regress", str(suite), "--update").code == 0
    assert snapshot_path(suite).read_bytes() == first


def test_rerun_matches(cli, suite: Path) -> None:
    assert cli("regress", str(suite), "--update").code == 0
    r = cli("regress", str(suite))
    assert r.code == 0, r.out + r.err
    assert status_lines(r.out) == {n: "ok" for n in QUERIES}
    assert "3 matched, 0 changed" in r.out


def test_edited_snapshot_shows_a_diff(cli, suite: Path) -> None:
    assert cli("regress", str(suite), "--update").code == 0
    snap = snapshot_path(suite)
    data = json.loads(snap.read_text(encoding="utf-8"))
    data["humanoid"]["robot_type"] = "QuadrupedRobot"
    snap.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    r = cli("regress", str(suite))
    assert r.code == 1
    assert status_lines(r.out) == {
        "humanoid": "CHANGED",
        "walk-ambiguous": "ok",
        "snake-grasp": "ok",
    }
    lines = r.out.splitlines()
    assert "--- s.snapshot.json:humanoid" in lines
    assert "+++ now:humanoid" in lines
    assert '-  "robot_type": "QuadrupedRobot",' in lines
    assert '+  "robot_type": "HumanoidRobot",' in lines
    assert any(line.startswith("@@ ") for line in lines)
    assert "2 matched, 1 changed" in r.out


def test_ontology_change_shows_a_diff(cli, tmp_path: Path, monkeypatch) -> None:
    suite = write_suite(tmp_path / "s.toml")
    assert cli("regress", str(suite), "--update").code == 0
    (tmp_path / "mine.kif").write_text(PENTAPOD, encoding="utf-8")
    write_suite(suite, header='ontology = ["mine.kif"]\n')
    # paths in the suite are relative to the suite, not to the working folder
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    r = cli("regress", str(suite))
    assert r.code == 1, r.err
    assert status_lines(r.out) == {
        "humanoid": "ok",
        "walk-ambiguous": "CHANGED",
        "snake-grasp": "ok",
    }
    assert "--- s.snapshot.json:walk-ambiguous" in r.out
    assert '+    "PentapodRobot",' in r.out.splitlines()


def test_removed_query_is_gone(cli, suite: Path) -> None:
    assert cli("regress", str(suite), "--update").code == 0
    write_suite(suite, ["humanoid", "walk-ambiguous"])
    r = cli("regress", str(suite))
    assert r.code == 1
    assert status_lines(r.out) == {
        "humanoid": "ok",
        "walk-ambiguous": "ok",
        "snake-grasp": "GONE",
    }


def test_removed_query_summary_counts_the_matches(cli, suite: Path) -> None:
    assert cli("regress", str(suite), "--update").code == 0
    write_suite(suite, ["humanoid", "walk-ambiguous"])
    r = cli("regress", str(suite))
    assert r.code == 1
    # both remaining queries match; one stored result is gone
    assert "2 matched, 1 changed" in r.out


def test_new_query_is_new(cli, tmp_path: Path) -> None:
    suite = write_suite(tmp_path / "s.toml", ["humanoid", "snake-grasp"])
    assert cli("regress", str(suite), "--update").code == 0
    write_suite(suite)
    r = cli("regress", str(suite))
    assert r.code == 1
    assert status_lines(r.out) == {
        "humanoid": "ok",
        "walk-ambiguous": "NEW",
        "snake-grasp": "ok",
    }
    assert "2 matched, 1 changed" in r.out
    # --update accepts the new result; the next run matches again
    assert cli("regress", str(suite), "--update").code == 0
    assert cli("regress", str(suite)).code == 0


# --- bad suites: exit 2 --------------------------------------------------------------------------

Q = '[[query]]\nname = "a"\nabilities = ["walking"]\n'


@pytest.mark.parametrize(
    ("text", "expect"),
    [
        ("[[query]\nname = 'a'\n", ["s.toml"]),  # TOML syntax error
        ('colour = "red"\n' + Q, ["colour"]),
        ('[[query]]\nname = "a"\nabilities = ["walking"]\nanwsers = {}\n', ["anwsers"]),
        (Q + Q, ["query[1].name = 'a'", "repeats the name"]),
        ("", ["query: missing"]),
        ('ontology = ["x.kif"]\n', ["query: missing"]),
        ('[[query]]\nabilities = ["walking"]\n', ["name"]),
        ('[[query]]\nname = "a"\nabilities = "walking"\n', ["abilities"]),
        (
            '[[query]]\nname = "a"\nabilities = ["walking"]\nanswers = { grasping = true }\n',
            ["query[0].answers.grasping = True", "not yes or no"],
        ),
        (
            '[[query]]\nname = "a"\nabilities = ["walking"]\nanswers = ["grasping"]\n',
            ["query[0].answers = ['grasping']", "not a table"],
        ),
        (
            '[[query]]\nname = "a"\nabilities = ["walking"]\nparams = { object_shape = 1 }\n',
            ["params"],
        ),
        ('[[query]]\nname = "a"\nabilities = ["walkin"]\n', ["walkin", "walking"]),
        (
            '[[query]]\nname = "a"\nabilities = ["walking"]\nanswers = { grasping = "maybe" }\n',
            ["grasping"],
        ),
        ('ontology = ["missing.kif"]\n' + Q, ["missing.kif"]),
        ('rules = "x.lp"\n' + Q, ["rules"]),
    ],
    ids=[
        "toml-syntax",
        "unknown-top-level-key",
        "unknown-query-key",
        "duplicate-name",
        "empty",
        "no-queries",
        "missing-name",
        "abilities-not-a-list",
        "answers-not-strings",
        "answers-not-a-table",
        "params-not-strings",
        "unknown-ability",
        "bad-answer",
        "missing-ontology",
        "rules-not-a-list",
    ],
)
def test_bad_suite_exits_2(cli, tmp_path: Path, text: str, expect: list[str]) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text(text, encoding="utf-8")
    for update in ([], ["--update"]):
        r = cli("regress", str(suite), *update)
        assert r.code == 2, (update, r.out, r.err)
        assert r.err.startswith("parmor: error: ")
        for word in expect:
            assert word in r.err
        no_traceback(r)
    assert not snapshot_path(suite).exists()


def test_unknown_ability_names_the_query(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text(Q + '[[query]]\nname = "second"\nabilities = ["walkin"]\n', encoding="utf-8")
    r = cli("regress", str(suite), "--update")
    assert r.code == 2
    assert "second" in r.err


def test_missing_suite_file(cli, tmp_path: Path) -> None:
    r = cli("regress", str(tmp_path / "none.toml"))
    assert r.code == 2
    assert "none.toml" in r.err
    no_traceback(r)


def test_missing_snapshot_says_to_update(cli, suite: Path) -> None:
    r = cli("regress", str(suite))
    assert r.code == 2
    assert "--update" in r.err
    assert "s.snapshot.json" in r.err
    no_traceback(r)


def test_malformed_snapshot(cli, suite: Path) -> None:
    snapshot_path(suite).write_text('{\n  "humanoid": \n', encoding="utf-8")
    r = cli("regress", str(suite))
    assert r.code == 2
    assert "s.snapshot.json:" in r.err
    no_traceback(r)


def test_query_table_that_is_not_a_table(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text("query = [1]\n", encoding="utf-8")
    r = cli("regress", str(suite))
    assert r.code == 2
    assert "query" in r.err


def test_suite_that_is_a_folder(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    suite.mkdir()
    r = cli("regress", str(suite))
    assert r.code == 2
    assert "s.toml" in r.err


def test_suite_that_is_not_utf8(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_bytes(b"\xff\xfe[[query]]\n")
    r = cli("regress", str(suite))
    assert r.code == 2
    assert "s.toml" in r.err


def test_a_suite_cannot_allow_scripts_itself(cli, tmp_path: Path) -> None:
    (tmp_path / "s.lp").write_text("#script (python)\ndef f():\n    return 1\n#end.\n")
    suite = tmp_path / "s.toml"
    suite.write_text('allow_scripts = true\nrules = ["s.lp"]\n' + Q, encoding="utf-8")
    r = cli("regress", str(suite), "--update")
    assert r.code == 2 and "allow_scripts: unknown key" in r.err
    suite.write_text('rules = ["s.lp"]\n' + Q, encoding="utf-8")
    r = cli("regress", str(suite), "--update")
    assert r.code == 2 and "--allow-scripts" in r.err


def test_script_hidden_after_a_percent_in_a_string_is_refused(cli, tmp_path: Path) -> None:
    rules = tmp_path / "r.lp"
    rules.write_text('p("%"). #script (lua) x = 1 #end.\n', encoding="utf-8")
    r = cli("design", "walking", "--rules", str(rules), "--no-input")
    assert r.code == 2 and "--allow-scripts" in r.err


def test_a_file_name_cannot_inject_rules(cli, tmp_path: Path) -> None:
    name = tmp_path / "x\n#script (lua) y = 1 #end.\n%.kif"
    name.write_text("(=> (instance ?R A) (exists (?p) (part ?p ?R)))\n", encoding="utf-8")
    r = cli(
        "design", "walking", "--answer", "grasping=yes", "--ontology", str(name), "--conceptual"
    )
    assert r.code == 0, r.err


def test_rules_file_with_script_is_refused(cli, tmp_path: Path) -> None:
    (tmp_path / "s.lp").write_text("#script (python)\ndef f():\n    return 1\n#end.\n")
    suite = tmp_path / "s.toml"
    suite.write_text('rules = ["s.lp"]\n' + Q, encoding="utf-8")
    r = cli("regress", str(suite), "--update")
    assert r.code == 2
    assert "--allow-scripts" in r.err
    assert not snapshot_path(suite).exists()


def test_rules_change_the_result(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    query = (
        '[[query]]\nname = "quad"\nabilities = ["walking"]\n'
        'answers = { grasping = "no", rough-terrain-walking = "no" }\n'
    )
    suite.write_text(query, encoding="utf-8")
    assert cli("regress", str(suite), "--update").code == 0
    stored = json.loads(snapshot_path(suite).read_text(encoding="utf-8"))
    assert stored["quad"]["robot_type"] == "QuadrupedRobot"
    (tmp_path / "r.lp").write_text(':- chosen("QuadrupedRobot").\n', encoding="utf-8")
    suite.write_text('rules = ["r.lp"]\n' + query, encoding="utf-8")
    r = cli("regress", str(suite))
    assert r.code == 1
    assert status_lines(r.out) == {"quad": "CHANGED"}
    assert '+  "status": "unsatisfiable",' in r.out.splitlines()


def test_a_suite_that_asks_for_it_simulates_every_behaviour(cli, tmp_path: Path) -> None:
    suite = tmp_path / "arm.toml"
    suite.write_text(
        'verify = true\n[[query]]\nname = "arm"\nabilities = ["pick-and-place"]\n'
        'params = { object_shape = "cylinder" }\n',
        encoding="utf-8",
    )
    assert cli("regress", str(suite), "--update").code == 0
    rec = json.loads(snapshot_path(suite).read_text(encoding="utf-8"))["arm"]
    assert rec["verified"]["simulated"] is True
    assert {b["verdict"] for b in rec["verified"]["behaviors"]} == {"ok"}
    suite.write_text("verify = 1\n", encoding="utf-8")
    r = cli("regress", str(suite))
    assert r.code == 2 and "verify = 1: not true or false" in r.err
