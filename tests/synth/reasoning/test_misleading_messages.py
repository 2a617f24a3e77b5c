"""Messages that named the wrong thing (issue 23, item 9): a catalog cycle reported as a
file that "extends itself", a memory limit blaming a rule that added 0 atoms, a time limit
of `parmor run` reported "in stage parse"."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from adron.errors import InputError
from synth.reasoning.ground_probe import ENCODINGS, blamed

REPO = Path(__file__).resolve().parents[3]
HEADER = '[catalog]\nname = "{name}"\nversion = "1"\ncurrency = "EUR"\nextends = "{parent}"\n'


def catalogs(folder: Path, links: dict[str, str]) -> None:
    """Catalog files ``name.toml`` in ``folder``, each extending ``links[name]``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, parent in links.items():
        (folder / f"{name}.toml").write_text(HEADER.format(name=name, parent=parent))


def load_error(path: Path) -> str:
    from adron.catalog import load_catalog

    with pytest.raises(InputError) as e:
        load_catalog(path)
    return str(e.value)


def test_a_cycle_of_two_catalogs_is_named_as_a_cycle(tmp_path: Path) -> None:
    catalogs(tmp_path, {"a": "b.toml", "b": "a.toml"})
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    message = load_error(a)
    assert "extends itself" not in message
    assert message == (
        f"{b}: catalog.extends: 'a.toml' closes a cycle of catalogs that extend each other "
        f"({a} -> {b} -> {a})"
    )


def test_a_cycle_of_three_reached_from_outside_it(tmp_path: Path) -> None:
    catalogs(tmp_path, {"top": "a.toml", "a": "b.toml", "b": "sub/c.toml"})
    catalogs(tmp_path / "sub", {"c": "../a.toml"})
    message = load_error(tmp_path / "top.toml")
    a, b, c = tmp_path / "a.toml", tmp_path / "b.toml", tmp_path / "sub" / "c.toml"
    assert message.startswith(f"{c}: catalog.extends: '../a.toml' closes a cycle")
    assert message.endswith(f"({a} -> {b} -> {c} -> {tmp_path / 'sub' / '../a.toml'})")
    assert "top.toml" not in message.split("(", 1)[1]  # not part of the cycle


@pytest.mark.parametrize("spelling", ["self.toml", "./self.toml", "../x/self.toml"])
def test_a_catalog_extending_itself_says_so(tmp_path: Path, spelling: str) -> None:
    catalogs(tmp_path / "x", {"self": spelling})
    path = tmp_path / "x" / "self.toml"
    assert load_error(path) == (
        f"{path}: catalog.extends: '{spelling}' extends itself (it is this file)"
    )


def test_a_long_chain_is_still_refused_by_depth(tmp_path: Path) -> None:
    from adron.catalog import MAX_EXTENDS, load_catalog

    links = {f"c{i}": f"c{i + 1}.toml" for i in range(MAX_EXTENDS + 1)}
    links[f"c{MAX_EXTENDS + 1}"] = "default"
    catalogs(tmp_path, links)
    assert f"is more than {MAX_EXTENDS} levels deep" in load_error(tmp_path / "c0.toml")
    # MAX_EXTENDS catalogs above a file load (as before: the limit did not move)
    assert load_catalog(tmp_path / "c2.toml").name == "c2"
    assert "levels deep" in load_error(tmp_path / "c1.toml")


# --- which rule grew ------------------------------------------------------------------------

PLACES = [
    "the knowledge base's facts and taxonomy",
    "the rule at shapes.kif:42:1",  # a shipped ontology file's rule: parmor's own
    "the rule at /home/u/mine.kif:3:1",
    ENCODINGS,
    "the rule at r.lp:2:1",
]
SHIPPED = {"shapes.kif", "robots.kif"}


def test_a_rule_that_added_no_atoms_is_not_blamed() -> None:
    # the case: the probe ran out of memory in the encodings; no rule of the
    # user's added anything: nothing of theirs is named
    assert blamed(PLACES, {0: 900, 1: 0, 2: 0}, 3, SHIPPED) == ""
    # a shipped rule's atoms are not the user's doing
    assert blamed(PLACES, {0: 900, 1: 500, 2: 0}, 3, SHIPPED) == ""


def test_the_users_rule_that_added_most_is_blamed() -> None:
    assert blamed(PLACES, {0: 900, 1: 500, 2: 7}, 3, SHIPPED) == (
        "the rule at /home/u/mine.kif:3:1 (its 7 atoms, on which parmor's encodings ground)"
    )
    # stopped in a statement of its own: that one, whatever it added
    assert blamed(PLACES, {0: 900, 1: 500, 2: 7, 3: 40}, 4, SHIPPED) == "the rule at r.lp:2:1"
    assert blamed(PLACES, {0: 9}, 1, SHIPPED) == "the rule at shapes.kif:42:1"


def parmor(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``parmor ARGS`` as its own process (a limit acts on the whole process)."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "PARMOR_CACHE": ""}
    return subprocess.run(
        [sys.executable, "-m", "synth.commands.cli", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_a_tiny_memory_limit_blames_no_rule_with_0_atoms(tmp_path: Path) -> None:
    rules = tmp_path / "r.lp"
    rules.write_text("mine(1).\nq(X) :- mine(X).\n", encoding="utf-8")
    r = parmor(
        "design", "walking", "--conceptual", "--memory-limit", "1", "--rules", "r.lp", cwd=tmp_path
    )
    assert r.returncode == 1, r.stderr
    # (where 1 MB runs out depends on what was imported before the limit was set: the
    # grounding of the ontology or of the request, never a rule's own place)
    assert re.search(
        r"memory limit \(1 MB, --memory-limit\) reached while in stage (ground|solve: grounding)",
        r.stderr,
    ), r.stderr
    assert "0 atoms" not in r.stderr and "shapes.kif" not in r.stderr
    assert "Traceback" not in r.stderr


# --- the stage a time limit names ---------------------------------------------------------


def test_a_time_limit_in_a_programs_run_names_the_run_stage(cli, tmp_path: Path) -> None:
    import io

    from synth.commands.cli import main

    bundle = tmp_path / "cart"
    err = io.StringIO()
    code = main(["design", "driving", "--no-verify", "--out", str(bundle)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    program = tmp_path / "loop.py"
    program.write_text("def main(robot):\n    while True:\n        pass\n", encoding="utf-8")
    r = cli("run", str(program), str(bundle), "--time-limit", "1")
    assert r.code == 1, r.err
    assert r.err == "parmor: error: time limit (1 s, --time-limit) reached while in stage run\n"
    # a JSON program too: its behaviours run in the same stage (200 drives of 5 s each,
    # 1000 s simulated: minutes of work, far past the limit on any machine)
    looping = tmp_path / "p.json"
    looping.write_text(
        '{"program": [{"repeat": 4, "body": [{"repeat": 50, "body": [{"do": "driving"}]}]}]}',
        encoding="utf-8",
    )
    r = cli("run", str(looping), str(bundle), "--time-limit", "1")
    assert r.code == 1, r.err
    assert r.err == "parmor: error: time limit (1 s, --time-limit) reached while in stage run\n"
