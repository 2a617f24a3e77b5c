"""Programs of behaviour calls (program/script.py) and their chained simulation
(program/session.py, ``parmor run``)."""

from __future__ import annotations

import io
import json
import math
import os
import random
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaits.base import BehaviorSpec, Parameter
from program import script
from program.script import LIMITS, ProgramError, execute, number_text, to_python, validate
from tests.conftest import REPO

SPECS = {
    "walking": BehaviorSpec(
        "walking",
        "walk",
        (
            Parameter("steps", "int", 4, "steps", low=1, high=20),
            Parameter("speed", "float", 0.0, "speed", "m/s", low=0.0, high=1.0),
            Parameter("gait", "choice", "tripod", "gait", choices=("tripod", "wave")),
        ),
    ),
    "turning": BehaviorSpec(
        "turning", "turn", (Parameter("angle", "float", 1.57, "angle", "rad", low=-6.3, high=6.3),)
    ),
}


def walk(**params) -> dict:
    return {"do": "walking", "params": params}


GOOD = {
    "program": [
        {"repeat": 3, "body": [walk(steps=2, gait="wave")]},
        {"do": "turning", "params": {"angle": -0.5}},
        {
            "if": {"report": "heading_deg", "op": ">=", "value": 45.5},
            "then": [{"wait": 1.0}],
            "else": [],
        },
    ]
}


def test_a_program_validates_and_reads_as_python() -> None:
    validate(GOOD, SPECS)
    assert to_python(GOOD) == (
        '"""A parmor program.  Run it with: parmor run PROGRAM.py BUNDLE_DIR"""\n'
        "\n\n"
        "def main(robot):\n"
        "    for _ in range(3):\n"
        '        robot.do("walking", steps=2, gait="wave")\n'
        '    robot.do("turning", angle=-0.5)\n'
        '    if robot.report("heading_deg") >= 45.5:\n'
        "        robot.wait(1)\n"
        "    else:\n"
        "        pass\n"
    )


@pytest.mark.parametrize(
    "program, where",
    [
        ([], "(the top level) = []: not a program (an object"),
        ({"program": {}}, "program = an empty table: not a list"),
        ({"program": [walk()], "x": 1}, "x: unknown key (keys: program)"),
        ({"program": [{"jump": 1}]}, "program[0] = a table: not a statement"),
        ({"program": [{"do": "flying"}]}, "program[0].do = 'flying': the design has no such"),
        ({"program": [walk(legs=3)]}, "program[0].params.legs = 3: walking has no parameter"),
        ({"program": [walk(steps=21)]}, "program[0].params.steps = 21: 21 is outside [1, 20]"),
        ({"program": [walk(steps=2.5)]}, "program[0].params.steps = 2.5: expected a whole"),
        ({"program": [walk(steps=True)]}, "program[0].params.steps = True: not a number"),
        ({"program": [walk(speed="fast")]}, "program[0].params.speed = 'fast': expected a"),
        ({"program": [walk(gait="gallop")]}, "program[0].params.gait = 'gallop': expected one"),
        ({"program": [{**walk(), "body": []}]}, "program[0].body: unknown key"),
        ({"program": [{"wait": -1}]}, "program[0].wait = -1: out of range"),
        ({"program": [{"wait": 61}]}, "program[0].wait = 61: out of range"),
        ({"program": [{"repeat": 51, "body": []}]}, "program[0].repeat = 51: out of range"),
        ({"program": [{"repeat": 2, "body": walk()}]}, "program[0].body = a table: not a list"),
        (
            {"program": [{"if": {"report": "speed", "op": ">", "value": 1}}]},
            "program[0].if.report = 'speed': not one of 'x_m'",
        ),
        (
            {"program": [{"if": {"report": "x_m", "op": "=>", "value": 1}}]},
            "program[0].if.op = '=>': not one of",
        ),
        (
            {"program": [{"if": {"report": "x_m", "op": ">", "value": math.inf}}]},
            "program[0].if.value = inf: not a number",
        ),
        (
            {"program": [{"repeat": 20, "body": [{"repeat": 20, "body": [walk()]}]}]},
            "program: runs 400 behaviours",
        ),
        ({"program": [{"wait": 0}] * 201}, "program[200]: more than 200 statements"),
    ],
)
def test_a_bad_program_is_refused_where_it_is_wrong(program, where: str) -> None:
    with pytest.raises(ProgramError) as e:
        validate(program, SPECS)
    assert str(e.value).startswith(where), str(e.value)


def test_nesting_is_bounded() -> None:
    body: list = [walk()]
    for _ in range(int(LIMITS["depth"])):
        body = [{"repeat": 1, "body": body}]
    with pytest.raises(ProgramError, match="nested deeper than"):
        validate({"program": body}, SPECS)
    validate({"program": body[0]["body"]}, SPECS)


@pytest.mark.parametrize(
    "x, text", [(90.0, "90"), (-2, "-2"), (0.3, "0.3"), (-0.0, "0"), (1e-3, "0.001")]
)
def test_numbers_read_as_the_page_writes_them(x: float, text: str) -> None:
    assert number_text(x) == text and float(text) == x


class Recorder:
    """A robot that records what it is asked and reports from a seeded stream."""

    def __init__(self, seed: int) -> None:
        self.calls: list = []
        self.rng = random.Random(seed)

    def do(self, behavior: str, **params) -> None:
        self.calls.append(("do", behavior, params))

    def wait(self, seconds: float) -> None:
        self.calls.append(("wait", seconds))

    def report(self, name: str) -> float:
        value = self.rng.choice([-1.0, 0.0, 1.0, 45.0])
        self.calls.append(("report", name, value))
        return value


def _random_body(rng: random.Random, depth: int) -> list:
    out = []
    for _ in range(rng.randint(0, 3)):
        kind = rng.choice(["do", "do", "wait", "repeat", "if"] if depth < 3 else ["do", "wait"])
        if kind == "do":
            name = rng.choice(sorted(SPECS))
            params = {}
            for p in SPECS[name].params:
                if rng.random() < 0.5:
                    params[p.name] = (
                        rng.choice(p.choices)
                        if p.kind == "choice"
                        else rng.randint(1, 5)
                        if p.kind == "int"
                        else round(rng.uniform(0, 1), rng.randint(0, 3))
                    )
            out.append({"do": name, "params": params})
        elif kind == "wait":
            out.append({"wait": rng.choice([0, 0.5, 2])})
        elif kind == "repeat":
            out.append({"repeat": rng.randint(0, 3), "body": _random_body(rng, depth + 1)})
        else:
            cond = {"report": rng.choice(sorted(script.REPORTS)), "op": rng.choice(script.OPS)}
            cond["value"] = rng.choice([0, 1, 45])
            out.append(
                {
                    "if": cond,
                    "then": _random_body(rng, depth + 1),
                    "else": _random_body(rng, depth + 1),
                }
            )
    return out


def test_the_python_text_does_what_the_program_does() -> None:
    """Property: for 200 random programs, running the Python text makes the same calls (and
    takes the same branches on the same reports) as interpreting the JSON."""
    rng = random.Random(7)
    for seed in range(200):
        program = {"program": _random_body(rng, 0)}
        validate(program, SPECS)
        a, b = Recorder(seed), Recorder(seed)
        execute(program, a)
        namespace: dict = {}
        exec(compile(to_python(program), "<program>", "exec"), namespace)
        namespace["main"](b)
        assert a.calls == b.calls, to_python(program)


# -- chained simulation ---------------------------------------------------------------


def _design(folder: Path, *argv: str) -> Path:
    from synth.commands.cli import main

    err = io.StringIO()
    code = main(["design", *argv, "--no-verify", "--out", str(folder)], out=io.StringIO(), err=err)
    assert code == 0, err.getvalue()
    return folder


@pytest.fixture(scope="module")
def hexapod(tmp_path_factory) -> Path:
    return _design(
        tmp_path_factory.mktemp("prog") / "hexapod",
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=yes",
    )


@pytest.fixture(scope="module")
def cart(tmp_path_factory) -> Path:
    # the cart as it was sized and verified: carrying its payload (robot.xml is the robot
    # alone unless asked)
    return _design(tmp_path_factory.mktemp("prog") / "cart", "driving", "--with-payload")


def test_behaviours_chain_from_where_the_last_ended(hexapod) -> None:
    """Walk, turn a quarter, walk: the second walk goes along y, and the robot ends where
    the commanded poses composed put it."""
    from program.session import run_program

    program = {
        "program": [
            {"repeat": 2, "body": [walk(steps=2)]},
            {"do": "turning", "params": {"angle": math.pi / 2}},
            walk(steps=2),
        ]
    }
    r = run_program(hexapod, program)
    assert r["verdict"] == "ok", r["verdict"]
    assert [s["behavior"] for s in r["steps"]] == ["walking", "walking", "turning", "walking"]
    assert all(s["verdict"] == "ok" for s in r["steps"])
    ex, ey, eyaw = r["expected_pose"]
    x, y, yaw = r["final_pose"]
    one = r["steps"][0]["figures"]["planned_distance_m"]
    assert (
        ex == pytest.approx(2 * one, rel=1e-5)
        and ey == pytest.approx(one, rel=1e-5)
        and eyaw == pytest.approx(math.pi / 2, rel=1e-5)
    )
    assert math.hypot(x - ex, y - ey) <= 0.1 * 3 * one and abs(yaw - eyaw) < math.radians(10)
    # each step starts where the last ended, later in time
    starts = [s["start_s"] for s in r["steps"]]
    assert starts == sorted(starts) and starts[0] == 0
    path = r["path"]
    assert len(path["t"]) == len(path["x"]) > 20 and path["t"] == sorted(path["t"])


def test_a_robot_that_cannot_do_it_fails_the_program(cart, tmp_path) -> None:
    """Built to fail: the cart with motors of a thousandth of a newton metre cannot drive,
    so the program's end pose and its behaviours fail; exit 1 from ``parmor run``."""
    from synth.commands.cli import main

    weak = tmp_path / "weak"
    shutil.copytree(cart, weak)
    xml = (weak / "robot.xml").read_text(encoding="utf-8")
    (weak / "robot.xml").write_text(
        re.sub(r'forcerange="[^"]*"', 'forcerange="-0.001 0.001"', xml), encoding="utf-8"
    )
    prog = tmp_path / "go.py"
    prog.write_text('def main(robot):\n    robot.do("driving")\n    robot.do("turning")\n')
    out, err = io.StringIO(), io.StringIO()
    assert main(["run", str(prog), str(cart), "--json"], out=out, err=err) == 0, err.getvalue()
    assert json.loads(out.getvalue())["verdict"] == "ok"
    out, err = io.StringIO(), io.StringIO()
    assert main(["run", str(prog), str(weak), "--json"], out=out, err=err) == 1
    r = json.loads(out.getvalue())
    assert any(v.startswith("end pose") for v in r["verdict"]), r["verdict"]
    assert r["steps"][0]["verdict"] != "ok" and "failed its verdict" in err.getvalue()
    assert "animation" not in r


def test_the_animation_places_the_mesh_files_where_mujoco_has_them(hexapod) -> None:
    """A page draws each mesh file at the frame's pose: its vertices must land where
    MuJoCo's compiled mesh is (MuJoCo moves a mesh to its inertial frame)."""
    import mujoco
    import trimesh

    from program.session import Session

    s = Session(hexapod)
    s.do("walking", steps=1)
    frame = s._frame(s.time, s.data)
    m, d = s.model, s.data
    checked = 0
    for geom, g, pos, quat in zip(s._geoms, s._geom_ids, frame["pos"], frame["quat"], strict=True):
        if geom["type"] != "mesh":
            continue
        raw = trimesh.load(hexapod / geom["mesh"]).vertices * np.array(geom["scale"])
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, np.array(quat))
        placed = raw @ rot.reshape(3, 3).T + np.array(pos)
        k = m.geom_dataid[g]
        v = m.mesh_vert[m.mesh_vertadr[k] : m.mesh_vertadr[k] + m.mesh_vertnum[k]]
        world = v @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
        assert np.allclose(np.sort(placed, axis=0), np.sort(world, axis=0), atol=2e-5)
        checked += 1
    assert checked >= 5


def test_parmor_run_explains_bad_programs(cli, cart, tmp_path, monkeypatch) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("def main(robot):\n    robot.do('driving'\n")
    r = cli("run", str(bad), str(cart))
    assert r.code == 2 and re.search(r"bad\.py:2:\d+: ", r.err) and "Traceback" not in r.err
    bad.write_text("def main(robot):\n    robot.do('driving')\n    robot.fly()\n")
    r = cli("run", str(bad), str(cart))
    assert r.code == 2 and "bad.py:3: AttributeError" in r.err
    bad.write_text("def main(robot):\n    robot.do('flying')\n")
    r = cli("run", str(bad), str(cart))
    assert r.code == 2 and "no behaviour of that name" in r.err and "driving" in r.err
    bad.write_text("x = 1\n")
    assert "defines no main(robot)" in cli("run", str(bad), str(cart)).err
    js = tmp_path / "p.json"
    js.write_text('{"program": [\n  {"do": "driving", "params": {"v": 99}}]}')
    r = cli("run", str(js), str(cart))
    assert r.code == 2 and f"{js}: program[0].params.v = 99: " in r.err
    js.write_text('{"program": [\n  {"do": }]}')
    r = cli("run", str(js), str(cart))
    assert r.code == 2 and "p.json:2:" in r.err
    js.write_text('{"program": []}')
    r = cli("run", str(js), str(tmp_path))
    assert r.code == 2 and "no design.json" in r.err
    monkeypatch.setitem(LIMITS, "sim_s", 3.0)
    js.write_text('{"program": [{"do": "driving"}, {"do": "driving"}]}')
    r = cli("run", str(js), str(cart))
    assert r.code == 2 and "would simulate more than 3 s" in r.err


def test_the_shipped_example_drives_a_square(cli, cart) -> None:
    """examples/square.py (run by make demo) comes back where it started."""
    example = Path(__file__).resolve().parents[2] / "examples" / "square.py"
    r = cli("run", str(example), str(cart), "--json")
    assert r.code == 0, r.err
    res = json.loads(r.out)
    assert res["verdict"] == "ok" and len(res["steps"]) == 8
    assert math.hypot(*res["final_pose"][:2]) < 0.05 and res["end_pose_error_m"] < 0.05


# -- reading programs: bounded JSON, the form of a file, wrong values ------------------


def _refusal(text: str) -> str:
    with pytest.raises(ProgramError) as e:
        validate(script.parse(text), SPECS)
    return str(e.value)


@pytest.mark.parametrize(
    "text, where",
    [
        ('{"program": [{"wait": %s}]}' % ("9" * 400), "program[0].wait = "),
        ('{"program": [{"wait": %s}]}' % ("9" * 5000), "program[0].wait = "),
        (json.dumps({"program": [walk(steps=int("1" * 400))]}), "program[0].params.steps = "),
        ('{"program": [{"repeat": %s, "body": []}]}' % ("5" * 5000), "program[0].repeat = "),
        ('{"program": [{"wait": 1e400}]}', "program[0].wait = "),
        ('{"program": [{"wait": NaN}]}', "program[0].wait = "),
        ('{"program": [{"wait": -Infinity}]}', "program[0].wait = "),
        ('{"program": [{"if": {"report": ["x_m"], "op": ">", "value": 1}}]}', ".if.report"),
        ('{"program": [{"if": {"report": {}, "op": ">", "value": 1}}]}', ".if.report"),
        ('{"program": [{"if": {"report": "x_m", "op": [">"], "value": 1}}]}', ".if.op"),
        ('{"program": [{"if": {"report": "x_m", "op": ">", "value": "1"}}]}', ".if.value"),
        ('{"program": [{"do": ["walking"]}]}', "program[0].do = "),
        ('{"program": [{"do": "walking", "params": {"gait": ["wave"]}}]}', ".params.gait"),
        ('{"program": [{"do": "walking", "params": {"speed": {"a": 1}}}]}', ".params.speed"),
        ('{"program": [{"do": "walking", "params": {"steps": null}}]}', ".params.steps"),
    ],
)
def test_huge_numbers_and_wrong_types_are_refused_by_their_key(text: str, where: str) -> None:
    """Cases built to fail: each was a traceback (OverflowError, ValueError, TypeError)."""
    message = _refusal(text)
    assert where in message, message
    assert len(message) < 400  # a 5000-digit number is described, not quoted
    if "9999" in text or "5555" in text:
        assert "digits" in message


def test_json_nesting_is_bounded_with_its_place() -> None:
    deep = "[" * 30_000 + "]" * 30_000
    with pytest.raises(script.JsonError) as e:
        script.parse(deep)
    assert (e.value.line, e.value.col) == (1, script.JSON_DEPTH + 1) and not e.value.syntax
    text = '{"program": [\n' + '{"repeat": 1, "body": [' * 40 + "]}" * 40 + "]}"
    with pytest.raises(script.JsonError) as e:
        script.parse(text)
    assert e.value.line == 2 and "nested deeper than 64" in str(e.value)
    # brackets inside strings do not count; a program nested as deep as LIMITS allow parses
    assert script.parse('{"a": "' + "[" * 1000 + '"}') == {"a": "[" * 1000}
    body: list = [walk()]
    for _ in range(int(LIMITS["depth"])):
        body = [{"repeat": 1, "body": body}]
    validate(script.parse(json.dumps({"program": body[0]["body"]})), SPECS)
    with pytest.raises(script.JsonError, match="Expecting"):
        script.parse('{"program": [')


PROGRAM_JSON = '{"program": [{"do": "driving", "params": {"seconds": 1}}]}'
PROGRAM_PY = "def main(robot):\n    robot.do('driving', seconds=1)\n"


@pytest.mark.parametrize(
    "name, text, form",
    [
        ("p.json", PROGRAM_JSON, "json"),
        ("p.JSON", PROGRAM_JSON, "json"),
        ("p.Json", "  \n" + PROGRAM_JSON, "json"),
        ("p.txt", PROGRAM_JSON, "json"),
        ("p", PROGRAM_JSON, "json"),
        ("p.py", PROGRAM_JSON, "json"),  # the content says JSON program
        ("p.PY", PROGRAM_PY, "python"),
        ("p.txt", PROGRAM_PY, "python"),
        ("p", PROGRAM_PY, "python"),
        ("p.py", '{"a": 1}\ndef main(robot):\n    pass\n', "python"),  # not a program's shape
    ],
)
def test_the_form_of_a_program_file_is_chosen_by_content_and_suffix(
    tmp_path, name: str, text: str, form: str
) -> None:
    path = tmp_path / name
    path.write_text(text)
    got, program = script.read_file(path)
    assert got == form
    if form == "json":
        assert program == json.loads(text)


def test_a_program_file_that_cannot_be_read_is_named(tmp_path) -> None:
    cases = {
        "p.JSON": ("def main(robot):\n    pass\n", "p.JSON:1:1: Expecting value"),
        "p.txt": ('{"program": [\n  {"do": }]}', "p.txt:2:10: Expecting value"),
        "deep.json": ("[" * 30_000, "deep.json:1:65: arrays and objects nested deeper"),
        "big.json": ('{"program": [' + " " * script.FILE_BYTES + "]}", "larger than"),
        "latin.json": (b'{"program": ["\xe9"]}', "not UTF-8"),
    }
    for name, (text, message) in cases.items():
        path = tmp_path / name
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text)
        with pytest.raises(script.InputError) as e:
            script.read_file(path)
        assert message in str(e.value), (name, str(e.value))
    with pytest.raises(script.InputError, match="no such program file"):
        script.read_file(tmp_path / "missing.json")
    with pytest.raises(script.InputError, match="a folder"):
        script.read_file(tmp_path)


def test_parmor_run_refuses_bad_json_programs_by_key_without_a_traceback(cli, cart, tmp_path):
    cases = {
        "huge.json": ('{"program": [{"wait": %s}]}' % ("9" * 5000), "program[0].wait = "),
        "big.json": ('{"program": [{"wait": %s}]}' % ("9" * 400), "program[0].wait = "),
        "report.JSON": (
            '{"program": [{"if": {"report": ["x_m"], "op": ">", "value": 1}}]}',
            "program[0].if.report = ",
        ),
        "param.txt": (
            '{"program": [{"do": "driving", "params": {"seconds": [1]}}]}',
            "program[0].params.seconds = ",
        ),
        "deep.json": ("[" * 30_000 + "]" * 30_000, "deep.json:1:65: "),
    }
    for name, (text, message) in cases.items():
        path = tmp_path / name
        path.write_text(text)
        r = cli("run", str(path), str(cart))
        assert r.code == 2 and message in r.err, (name, r.err)
        assert f"{path}:" in r.err  # the file, then its line:col or the key path
        assert "Traceback" not in r.err and len(r.err) < 1000


THREADED = """
import os, sys, threading, time

def main(robot):
    threading.Thread(target=time.sleep, args=(3600,)).start()  # a non-daemon thread
    print("the program printed this", flush=False)
    robot.do("driving", seconds=1)
    if os.environ.get("FAIL_AFTER"):
        raise RuntimeError("failed after starting a thread")
"""


def _parmor_process(*argv: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """``parmor ARGV`` as its own process (a thread left running would keep it alive)."""
    return subprocess.run(
        [sys.executable, "-m", "synth.commands.cli", *argv],
        capture_output=True,
        text=True,
        timeout=600,  # a loaded machine runs this in seconds; a wait on the thread is 3600 s
        cwd=REPO,
        env=dict(os.environ, PYTHONPATH=str(REPO), **(env or {})),
    )


def test_parmor_run_does_not_wait_for_the_programs_threads(cart, tmp_path) -> None:
    """A case built to fail: the program leaves a non-daemon thread sleeping an hour; parmor
    exits with its code when main returns (it waited on the thread for the hour before)."""
    program = tmp_path / "threads.py"
    program.write_text(THREADED)
    r = _parmor_process("run", str(program), str(cart))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("the program printed this\n")  # before the results
    assert "verdict: ok" in r.stdout
    r = _parmor_process("run", str(program), str(cart), env={"FAIL_AFTER": "1"})
    assert r.returncode == 2 and "threads.py:9: RuntimeError: failed after" in r.stderr
    assert "Traceback" not in r.stderr


def test_parmor_run_stops_a_program_at_its_time_limit_and_reports_odd_exits(
    cli, cart, tmp_path
) -> None:
    forever = tmp_path / "forever.py"
    forever.write_text("def main(robot):\n    while True:\n        pass\n")
    r = cli("run", str(forever), str(cart), "--time-limit", "3")
    assert r.code == 1 and "time limit (3 s, --time-limit) reached" in r.err, r.err
    quits = tmp_path / "quits.py"
    quits.write_text("import os\n\ndef main(robot):\n    os._exit(5)\n")
    r = cli("run", str(quits), str(cart))
    assert r.code == 2 and "ended without a result (exit code 5)" in r.err, r.err
    exits = tmp_path / "exits.py"
    exits.write_text("import sys\n\ndef main(robot):\n    sys.exit(3)\n")
    r = cli("run", str(exits), str(cart))
    assert r.code == 2 and "exits.py:4: SystemExit: 3" in r.err, r.err


def test_a_behaviour_that_cannot_run_names_the_file_and_the_statement(cli, cart, tmp_path):
    """A case built to fail: each value is within its range, but the drive is shorter than
    its ramp; the refusal (exit 2) named neither the program nor the statement."""
    js = tmp_path / "p.json"
    js.write_text(
        '{"program": [{"wait": 0.1}, {"repeat": 2, "body": '
        '[{"do": "driving", "params": {"seconds": 0.2}}]}]}'
    )
    r = cli("run", str(js), str(cart))
    assert r.code == 2, r.err
    assert f"{js}: program[1].body[0]: driving: ramp" in r.err, r.err
    assert "Traceback" not in r.err
