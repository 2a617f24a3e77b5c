"""Limits on every command (issue 11): regress and sweep bound their grounding and each
query or request, simulate and the other commands the whole run and this process's memory;
reaching one ends with exit 1 and one line naming the limit and the stage. No timing
thresholds: the cases never end without the limit."""

from __future__ import annotations

import io
import time
from pathlib import Path

import pytest

from synth import limits
from synth.commands.cli import build_parser, main

BLOW_UP = "p(X) :- X = 1..100000000.\n"
SUITE = """\
rules = ["r.lp"]
conceptual = true
[[query]]
name = "arm"
abilities = ["pick-and-place"]
params = { object_shape = "oval" }
"""
STUDY = """\
rules = ["r.lp"]
[[request]]
name = "arm"
abilities = ["pick-and-place"]
params = { object_shape = "oval" }
"""


def run(*argv: str) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main(list(argv), out=out, err=err)
    assert "Traceback" not in err.getvalue()
    return code, err.getvalue()


def one_line(err: str) -> str:
    lines = [x for x in err.strip().splitlines() if not x.startswith("parmor: note:")]
    assert len(lines) == 1, err
    return lines[0]


def test_every_command_has_the_limit_options() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        if name == "ontology":
            p = next(a for a in p._actions if a.dest == "ontology_command").choices["check"]
        options = {o for a in p._actions for o in a.option_strings}
        assert "--time-limit" in options, name
        if name != "blocks":  # its --time-limit is each served run's
            assert "--memory-limit" in options, name


@pytest.mark.parametrize("command", ["regress", "sweep"])
def test_a_blowing_up_rule_file_stops_regress_and_sweep(tmp_path: Path, command: str) -> None:
    (tmp_path / "r.lp").write_text(BLOW_UP)
    path = tmp_path / "s.toml"
    path.write_text(SUITE if command == "regress" else STUDY)
    extra = ["--out", str(tmp_path / "o")] if command == "sweep" else []
    code, err = run(command, str(path), *extra, "--time-limit", "1")
    assert code == 1, err
    line = one_line(err)
    assert "time limit (1 s, --time-limit)" in line and "stage ground" in line
    assert "r.lp" in line and str(path) in line  # the file and the suite or study
    assert not (tmp_path / "o").exists()


def test_a_sweep_request_that_reaches_the_time_limit_is_an_error_of_the_sweep(
    monkeypatch,
) -> None:
    """Each request has its own deadline; one that reaches it is recorded as an error
    (tried again on the next run), the sweep goes on."""
    import synth.commands.sweep as sweep

    def forever(*args) -> dict:
        while True:
            time.sleep(0.01)

    monkeypatch.setattr(sweep, "design_one", forever)
    state = (None, None, False, limits.Limits(time_s=0.2))
    res = sweep._work(state, {"name": "x"})
    assert res["status"] == "error"
    assert res["reason"].startswith("LimitExceeded: time limit (0.2 s, --time-limit)")
    assert limits.remaining() is None  # the outer limits (none) again


@pytest.fixture(scope="module")
def cart(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("lim") / "cart"
    code, err = run("design", "driving", "--no-verify", "--out", str(folder))
    assert code == 0, err
    return folder


def test_simulate_time_limit(cart: Path) -> None:
    code, err = run(
        "simulate", str(cart), "--behavior", "driving", "--seconds", "600", "--time-limit", "0.5"
    )
    line = one_line(err)
    assert code == 1 and "time limit (0.5 s, --time-limit)" in line, err
    assert "stage simulate" in line or "stage parse" in line


def test_simulate_memory_limit_names_the_stage(cart: Path, monkeypatch) -> None:
    import synth.verification.runs

    def hungry(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(synth.verification.runs, "run_behavior", hungry)
    code, err = run("simulate", str(cart), "--behavior", "driving", "--seconds", "1")
    assert code == 1
    assert "memory limit (4096 MB, --memory-limit) reached while in stage simulate" in one_line(err)


def test_cap_memory_turns_a_huge_allocation_into_memory_error() -> None:
    if not limits.data_bytes():
        pytest.skip("no /proc/self/status here (not Linux)")
    import resource

    before = resource.getrlimit(resource.RLIMIT_DATA)
    restore = limits.cap_memory(1)
    try:
        assert resource.getrlimit(resource.RLIMIT_DATA) != before
        with pytest.raises(MemoryError):
            bytearray(4 * limits.MIN_PROCESS_MB * 1024 * 1024)
    finally:
        restore()
    assert resource.getrlimit(resource.RLIMIT_DATA) == before


def test_plot_into_a_folder_that_cannot_be_written_is_refused_before_work(
    cart: Path, tmp_path: Path, monkeypatch
) -> None:
    import shutil

    copy = tmp_path / "cart"
    shutil.copytree(cart, copy)
    (copy / "plots").write_text("a file where the plots go")
    code, err = run("simulate", str(copy), "--behavior", "driving", "--plot")
    assert code == 2 and "is not a folder" in one_line(err)
    (copy / "plots").unlink()
    monkeypatch.setattr("os.access", lambda path, mode: False)  # read-only (root ignores modes)
    code, err = run("simulate", str(copy), "--behavior", "driving", "--plot")
    assert code == 2 and "--plot" in one_line(err) and "not writable" in err
    assert not (copy / "plots").exists()


# --- the rule that grew, on a time or memory limit while grounding ---------------------------


@pytest.mark.parametrize("limit", [["--time-limit", "1"], ["--memory-limit", "150"]])
def test_a_time_or_memory_limit_names_the_rule_that_grew(tmp_path: Path, limit) -> None:
    rules = tmp_path / "r.lp"
    rules.write_text("ok.\na(1..1000).\nb(X, Y, Z) :- a(X), a(Y), a(Z).\nc :- ok.\n")
    base = ["design", "walking", "--answer", "grasping=no", "--conceptual"]
    code, err = run(*base, "--rules", str(rules), *limit)
    line = one_line(err)
    assert code == 1 and "stage ground" in line, err
    assert f"the rule at {rules}:3:1 grew" in line


def test_a_kif_rule_with_many_variables_is_named(tmp_path: Path) -> None:
    kif = tmp_path / "many.kif"
    kif.write_text(
        "(subclass MyRobot Robot)\n"
        "(=> (and (subclass ?A ?B) (subclass ?C ?D) (subclass ?E ?F) (subclass ?G ?H))\n"
        "    (related ?A ?B ?C ?D ?E ?F ?G ?H))\n"
    )
    # a rule file turns the relevance filter off (adron/relevance.py): the rule is grounded
    (tmp_path / "r.lp").write_text("mine(R) :- chosen(R).\n")
    base = ["design", "walking", "--answer", "grasping=no", "--conceptual"]
    base += ["--rules", str(tmp_path / "r.lp")]
    code, err = run(*base, "--ontology", str(kif), "--time-limit", "1")
    line = one_line(err)
    assert code == 1 and "time limit" in line and "stage ground" in line, err
    assert f"the rule at {kif}:2:1 grew" in line


def test_enumerate_with_a_thousand_actuators_stops_at_its_time_limit(tmp_path: Path) -> None:
    """Issue 11: ``enumerate walking`` with a 1000-actuator catalog ran past 300 s."""
    import re

    text = (Path(__file__).resolve().parents[3] / "adron" / "catalog.toml").read_text()
    first, end = text.index("[[actuator]]"), text.index("[[module]]")
    copies = [
        re.sub(r'model = "([^"]+)"', rf'model = "\1-{i}"', text[first:end]) for i in range(167)
    ]
    catalog = tmp_path / "c.toml"
    catalog.write_text(text[:first] + "".join(copies) + text[end:])
    code, err = run("enumerate", "walking", "--catalog", str(catalog), "--time-limit", "2")
    assert code == 1 and "time limit (2 s, --time-limit) reached" in one_line(err), err
