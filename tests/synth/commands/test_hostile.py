"""Hostile input: every option of every command and every kind of input file, given values
a careless or hostile user might give, must end with an exit code of 1-3 (or 0 where the
value is in fact fine), one line of error message and never a traceback.

The option walk is driven by the argparse parser itself (a new option is walked without
editing this file); files are mutated with a seeded generator (deterministic). Designs are
kept cheap (--conceptual, --no-input, --no-simulate, a 0.1 s simulation) and everything
runs in-process through ``synth.commands.cli.main``, but for the broken-pipe cases, which need a
real pipe.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from synth.commands.cli import build_parser, main

#: Hostile values for any option or positional argument.
HOSTILE = (
    "1e308",
    "1e-300",
    "0",
    "-1",
    "nan",
    "inf",
    "☃é\u202eא",
    "",
    "a\x00b",
    "a\nb",
    "x=y=z",
    "..",
)

#: Hostile magnitudes for a physical parameter (a unit of the right kind is appended).
MAGNITUDES = ("1e308", "1e-300", "0", "-1", "nan", "inf")

KIF = """\
; a small user ontology
(subclass MyRobot Robot)
(documentation MyRobot EnglishLanguage "A robot of mine.")
(=> (instance ?R MyRobot) (exists (?W) (and (instance ?W Wheel) (part ?W ?R))))
(subclass MyWheel Wheel)
"""

RULES = """\
% a small user rule file
mine(X) :- candidate(X).
:- mine(X), X = "nothing".
"""

SUITE = """\
conceptual = true
[[query]]
name = "ambiguous walking"
abilities = ["walking"]
[[query]]
name = "arm"
abilities = ["pick-and-place"]
params = { object_shape = "oval" }
"""

# An ambiguous request: the sweep records that an answer is needed, without sizing.
STUDY = """\
[[request]]
name = "walker"
abilities = ["walking"]
params = { payload = ["0.1kg", "0.2kg"] }
"""

PROGRAM_JSON = (
    '{"program": [{"do": "driving", "params": {"v": 0.1, "seconds": 0.2}}, {"wait": 0.1}]}\n'
)
PROGRAM_PY = """\
def main(robot):
    robot.do("driving", v=0.1)
    if robot.report("x_m") > 1:
        robot.wait(0.1)
"""

SEED = 11

#: A cheap request that is designed (conceptually): hostile values meet every stage.
DESIGN = ["design", "pick-and-place", "--param", "object_shape=oval", "--conceptual", "--no-input"]


# ---- helpers ------------------------------------------------------------------------------


def run(argv: list[str]) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of the CLI run in-process; any exception fails the test."""
    out, err = io.StringIO(), io.StringIO()
    code = main(argv, out=out, err=err)
    return code, out.getvalue(), err.getvalue()


def check(argv: list[str]) -> int:
    """Run ``argv`` and hold it to the rules; returns the exit code."""
    code, _, err = run(argv)
    assert "Traceback" not in err, err
    assert code in (0, 1, 2, 3), (code, err)
    if code:
        # one line says why; besides it only notes and argparse's usage (indented lines)
        said = [
            line
            for line in err.splitlines()
            if line.strip() and not line.startswith(("parmor: note:", "usage:", " "))
        ]
        assert len(said) == 1, err
        assert said[0].startswith(("parmor: ", "parmor ")), said[0]
    return code


def value_options(parser: argparse.ArgumentParser) -> Iterator[tuple[str, argparse.Action]]:
    """(command words, action) of every option and positional that takes a value."""

    def walk(p: argparse.ArgumentParser, words: str) -> Iterator[tuple[str, argparse.Action]]:
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    yield from walk(sub, f"{words} {name}".strip())
            elif action.nargs != 0 and not isinstance(action, argparse._HelpAction) and words:
                yield words, action

    yield from walk(parser, "")


def mutate(text: str, rng: random.Random) -> str:
    """One seeded mutation of a text file: a hostile insertion, deletion, duplication,
    truncation, deep nesting or byte-order mark."""
    kind = rng.randrange(9)
    i = rng.randrange(len(text) + 1)
    j = min(len(text), i + rng.randrange(1, 40))
    if kind == 0:
        return text[:i] + rng.choice('()"[]{}=#;.\x00\ufeff\n\\%:-?@é☃') + text[i:]
    if kind == 1:
        return text[:i] + text[j:]
    if kind == 2:
        return text[:j] + text[i:j] * rng.randrange(2, 50) + text[j:]
    if kind == 3:
        return text[:i]
    if kind == 4:
        depth = rng.choice((50, 200, 5000))
        return text[:i] + "(" * depth + "x" + ")" * depth + text[i:]
    if kind == 5:
        return "\ufeff" + text
    if kind == 6:
        return text[:i] + rng.choice(("1e308", "-1", "nan", "inf", '""', "0")) + text[j:]
    if kind == 7:
        return text[:i] + "\n" + text[i:j].upper() + text[j:]
    return text[:i] + rng.choice(("\x00", "\u202e", "\r", "\t", "\x1b[2J")) + text[j:]


def mutations(text: str, n: int, salt: int) -> list[str]:
    rng = random.Random(SEED * 1000 + salt)
    out = []
    for _ in range(n):
        t = text
        for _ in range(rng.randrange(1, 3)):
            t = mutate(t, rng)
        out.append(t)
    return out


# ---- fixtures -----------------------------------------------------------------------------


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch) -> None:
    """Every case runs in its own folder: an accepted --out, a sweep's output or MuJoCo's
    log lands there, never in the working folder."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    """Valid input files of every kind, and a small bundle (an unverified cart)."""
    d = tmp_path_factory.mktemp("hostile")
    paths = {}
    for name, text in (
        ("kif", KIF),
        ("lp", RULES),
        ("suite", SUITE),
        ("study", STUDY),
        ("json", PROGRAM_JSON),
        ("py", PROGRAM_PY),
    ):
        ext = {"suite": "toml", "study": "toml"}.get(name, name)
        paths[name] = d / f"{name}.{ext}"
        paths[name].write_text(text, encoding="utf-8")
    bundle = d / "cart"
    code, _, err = run(["design", "driving", "--no-input", "--no-verify", "--out", str(bundle)])
    assert code == 0, err
    paths["bundle"] = bundle
    paths["dir"] = d
    return paths


def base_argv(command: str, f: dict[str, Path]) -> list[str]:
    """A cheap, valid command line of ``command`` to put one hostile value into."""
    sweep_out = str(f["dir"] / "sweep-out")
    return {
        "abilities": ["abilities"],
        "design": DESIGN,
        "enumerate": ["enumerate", "walking", "--conceptual"],
        "explain": ["explain", "HexapodRobot"],
        "ontology check": ["ontology", "check", str(f["kif"])],
        "regress": ["regress", str(f["suite"])],
        "simulate": ["simulate", str(f["bundle"]), "--behavior", "driving", "--seconds", "0.1"],
        "sweep": ["sweep", str(f["study"]), "--no-simulate", "--jobs", "1", "--out", sweep_out],
        "run": ["run", str(f["json"]), str(f["bundle"])],
        "blocks": ["blocks", str(f["bundle"])],
        "ros": ["ros", str(f["bundle"]), "--force"],
    }[command]


def _values_for(command: str, action: argparse.Action) -> list[str]:
    dest = action.dest
    if dest == "param":
        from adron.units import DIMENSIONS
        from synth.params import PARAMS

        out = []
        # every parameter through design; enumerate parses them with the same code
        for spec in PARAMS if command == "design" else PARAMS[:2]:
            if spec.dimension == "count":  # a whole number (dof): no unit
                out += [f"{spec.name}={m}" for m in MAGNITUDES]
                out += [f"{spec.name}=", f"{spec.name}=☃", f"{spec.name}=5 kg"]
                continue
            unit = DIMENSIONS[spec.dimension].example.split(" ", 1)[1]
            out += [f"{spec.name}={m} {unit}" for m in MAGNITUDES]
            out += [f"{spec.name}=", f"{spec.name}=☃", f"{spec.name}=5"]
        return out + [f"{h}=1" for h in HOSTILE[6:]]
    if dest in ("answer", "set"):
        name = "grasping" if dest == "answer" else "v"
        return [f"{name}={h}" for h in HOSTILE] + [f"{h}=yes" for h in HOSTILE[6:]]
    return list(HOSTILE)


def _option_cases() -> list[tuple[str, str, str]]:
    cases = []
    for words, action in value_options(build_parser()):
        name = action.option_strings[0] if action.option_strings else action.dest
        for v in _values_for(words, action):
            cases.append((words, name, v))
    return cases


OPTION_CASES = _option_cases()


def _with_value(argv: list[str], action_name: str, value: str, command: str) -> list[str] | None:
    """``argv`` with ``value`` given to the option (or put in place of the positional)."""
    if action_name.startswith("-"):
        argv = list(argv)
        if action_name in argv:  # replace the base's own value
            k = argv.index(action_name)
            del argv[k : k + 2]
        return [*argv, f"{action_name}={value}"]
    # a positional: the first one after the command words
    n = len(command.split())
    return [*argv[:n], value, *argv[n + 1 :]] if len(argv) > n else [*argv, value]


@pytest.mark.parametrize(("command", "option", "value"), OPTION_CASES)
def test_every_option_with_hostile_values(files, command, option, value) -> None:
    argv = _with_value(base_argv(command, files), option, value, command)
    check(argv)


# ---- files -------------------------------------------------------------------------------

N = 30  # mutations per file kind


def _file_cases() -> list[tuple[str, int]]:
    return [(kind, i) for kind in ("kif", "lp", "suite", "study", "json", "py") for i in range(N)]


def _catalog_text() -> str:
    from importlib.resources import files as res

    return (res("adron") / "catalog.toml").read_text(encoding="utf-8")


@pytest.mark.parametrize(("kind", "i"), _file_cases())
def test_mutated_input_files(files, tmp_path, kind, i) -> None:
    base = {
        "kif": KIF,
        "lp": RULES,
        "suite": SUITE,
        "study": STUDY,
        "json": PROGRAM_JSON,
        "py": PROGRAM_PY,
    }
    text = mutations(base[kind], N, salt=hash_of(kind))[i]
    ext = {"suite": "toml", "study": "toml"}.get(kind, kind)
    path = tmp_path / f"mutated.{ext}"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    if kind == "kif":
        check(["ontology", "check", str(path)])
        if i % 8 == 0:  # the shipped ontology too, through the reasoner
            check([*DESIGN, "--ontology", str(path)])
    elif kind == "lp":
        check([*DESIGN, "--rules", str(path)])
    elif kind == "suite":
        path.with_name("mutated.snapshot.json").unlink(missing_ok=True)
        check(["regress", str(path), "--update"])
        check(["regress", str(path)])
    elif kind == "study":
        check(["sweep", str(path), "--no-simulate", "--jobs", "1", "--out", str(tmp_path / "o")])
    elif kind in ("json", "py"):
        check(["run", str(path), str(files["bundle"])])


def hash_of(text: str) -> int:
    """A stable small number of ``text`` (Python's hash() is salted per process)."""
    return sum(ord(c) * (k + 1) for k, c in enumerate(text)) % 1000


@pytest.mark.parametrize("i", range(40))
def test_mutated_catalogs(tmp_path, i) -> None:
    from adron.catalog import load_catalog
    from adron.errors import InputError

    text = mutations(_catalog_text(), 40, salt=7)[i]
    path = tmp_path / "catalog.toml"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        load_catalog(path)
    except InputError as e:
        assert "\n" not in str(e), str(e)
        # refused before any sizing: the command line says so in one line
        code = check(["enumerate", "walking", "--catalog", str(path), "--answer", "grasping=no"])
        assert code == 2
    # a catalog that still loads is a valid catalog: sizing it is not this test's business


BUNDLE_MUTATIONS = (
    ("robot.xml", None),
    ("robot.xml", "hello"),
    ("robot.xml", "<mujoco/>"),
    ("robot.xml", '<mujoco><worldbody><body><geom size="1"/></body></worldbody></mujoco>'),
    ("design.json", None),
    ("design.json", "[]"),
    ("design.json", "null"),
    ("design.json", '{"template": 5}'),
    ("design.json", '{"template": "x", "robot_type": 5, "lengths_m": 3}'),
    ("design.json", "\ufeff{"),
    ("meshes", None),
)


@pytest.mark.parametrize(("name", "content"), BUNDLE_MUTATIONS)
def test_mutated_bundles(files, tmp_path, name, content) -> None:
    import shutil

    bundle = tmp_path / "cart"
    shutil.copytree(files["bundle"], bundle)
    target = bundle / name
    if content is None:
        shutil.rmtree(target) if target.is_dir() else target.unlink()
    else:
        target.write_text(content, encoding="utf-8")
    for argv in (
        ["simulate", str(bundle), "--behavior", "driving", "--seconds", "0.1"],
        ["run", str(files["json"]), str(bundle)],
    ):
        assert check(argv) != 0
    for argv in (["blocks", str(bundle)], ["ros", str(bundle), "--force"]):
        check(argv)  # these read only design.json: a missing mesh is not their concern


def test_regress_snapshot_that_is_not_an_object(tmp_path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text(SUITE, encoding="utf-8")
    for bad in ("5", "null", '{"arm": 5}'):
        (tmp_path / "s.snapshot.json").write_text(bad, encoding="utf-8")
        code, _, err = run(["regress", str(suite)])
        assert code == 2 and "not a snapshot" in err


def test_regress_update_keeps_the_old_snapshot_when_it_cannot_write(tmp_path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text(SUITE, encoding="utf-8")
    snap = tmp_path / "s.snapshot.json"
    snap.mkdir()  # a folder where the snapshot goes: the rename fails
    code, _, err = run(["regress", str(suite), "--update"])
    assert code == 2 and "cannot write" in err and err.count("\n") == 1
    assert {p.name for p in tmp_path.iterdir()} == {"s.toml", "s.snapshot.json"}  # no temp left
    snap.rmdir()
    snap.write_text('{"old": {}}', encoding="utf-8")
    assert run(["regress", str(suite), "--update"])[0] == 0
    assert set(json.loads(snap.read_text(encoding="utf-8"))) == {"ambiguous walking", "arm"}
    assert {p.name for p in tmp_path.iterdir()} == {"s.toml", "s.snapshot.json"}


# ---- broken pipe and full output (real processes) --------------------------------------------


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "synth.commands.cli", *args]


@pytest.mark.parametrize("args", [("abilities", "--json"), ("explain", "HexapodRobot", "--json")])
def test_broken_pipe_and_full_output(args, tmp_path) -> None:
    root = str(Path(__file__).resolve().parents[3])
    env = {"PYTHONPATH": root, "PATH": "/usr/bin:/bin"}
    # the reader is gone before the command starts: its first write gets EPIPE
    read, write = os.pipe()
    os.close(read)
    try:
        r = subprocess.run(_cli(*args), stdout=write, stderr=subprocess.PIPE, env=env)
    finally:
        os.close(write)
    err = r.stderr.decode()
    assert r.returncode == 2 and "Traceback" not in err
    assert re.fullmatch(r"parmor: error: cannot write the output: [^\n]*\n", err), err
    if Path("/dev/full").exists():
        with open("/dev/full", "w") as full:
            r = subprocess.run(_cli(*args), stdout=full, stderr=subprocess.PIPE, env=env)
        err = r.stderr.decode()
        assert r.returncode == 2 and "No space left" in err and err.count("\n") == 1, err
