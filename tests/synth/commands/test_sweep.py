"""Tests of ``parmor sweep`` (synth.commands.sweep): study files whose parameter lists expand into
their product, designed on worker processes, stored per request (resumable) and summarised
in results.csv, summary.md and plots."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

import synth.commands.sweep
from synth.commands.sweep import code_files, default_out, load_study, request_key
from synth.verification.results import Run

# cheap designs: a snake, a differential drive, one too fast to size, a request no robot can
# meet and one that needs an answer
TINY = """\
[[request]]
name = "snake"
abilities = ["rolling"]
params = { payload = ["0kg", "0.05kg"] }

[[request]]
name = "cart"
abilities = ["driving"]
params = { payload = "0.5kg", speed = ["0.1m/s", "0.2m/s"] }

[[request]]
name = "fast-cart"
abilities = ["driving"]
params = { payload = "0.5kg", speed = "0.6m/s" }

[[request]]
abilities = ["rolling", "grasping"]

[[request]]
abilities = ["walking"]
"""
N_TINY = 7


def write(path: Path, text: str = TINY) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def outputs(folder: Path) -> dict[str, bytes]:
    """Every output file of a sweep folder (the stored requests left out)."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and "requests" not in p.parts
    }


def rows(folder: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO((folder / "results.csv").read_text())))


# --- the study file ------------------------------------------------------------------------


def test_lists_expand_into_their_product_in_file_order(tmp_path: Path) -> None:
    study = write(
        tmp_path / "s.toml",
        """\
[[request]]
name = "arm"
abilities = ["pick-and-place"]
answers = { orienting = "no" }
[request.params]
reach = ["20cm", "30cm"]
object_shape = "cylinder"
speed = ["0.1m/s", "0.2m/s", "0.3m/s"]

[[request]]
abilities = ["rolling"]
""",
    )
    opts, reqs = load_study(study)
    assert len(reqs) == 7
    assert [(r["params"]["reach"], r["params"]["speed"]) for r in reqs[:6]] == [
        ("20cm", "0.1m/s"),
        ("20cm", "0.2m/s"),
        ("20cm", "0.3m/s"),
        ("30cm", "0.1m/s"),
        ("30cm", "0.2m/s"),
        ("30cm", "0.3m/s"),
    ]
    assert all(r["params"]["object_shape"] == "cylinder" for r in reqs[:6])
    assert all(r["answers"] == {"orienting": "no"} and r["name"] == "arm" for r in reqs[:6])
    assert reqs[6]["name"] == "rolling" and reqs[6]["params"] == {}
    assert opts["catalog"] is None and opts["ontology"] == []
    assert default_out(study) == tmp_path / "s.sweep"


BAD = {
    "unknown top-level key": ("colour = 1\n" + TINY, "colour: unknown key"),
    "no requests": ('catalog = "c.toml"\n', "request: missing"),
    "unknown request key": (
        '[[request]]\nabilities = ["rolling"]\nparam = { payload = "1kg" }\n',
        "request[0].param: unknown key",
    ),
    "no abilities": ('[[request]]\nname = "x"\n', "request[0].abilities: missing"),
    "a number for a value": (
        '[[request]]\nabilities = ["rolling"]\nparams = { payload = [0.1, 0.2] }\n',
        "request[0].params.payload = [0.1, 0.2]: not a value with its unit",
    ),
    "an empty list": (
        '[[request]]\nabilities = ["rolling"]\nparams = { payload = [] }\n',
        "request[0].params.payload = []: not a value",
    ),
    "a value listed twice": (
        '[[request]]\nabilities = ["rolling"]\nparams = { payload = ["1kg", "1kg"] }\n',
        "request[0].params.payload[1] = '1kg': listed twice",
    ),
    "a value without its unit": (
        TINY + '\n[[request]]\nname = "bare"\nabilities = ["driving"]\n'
        'params = { speed = ["0.2m/s", "0.3"] }\n',
        "request[5] (bare): --param speed",
    ),
    "unknown ability": (
        TINY + '\n[[request]]\nabilities = ["rollin"]\n',
        "request[5] (rollin): unknown ability 'rollin' (did you mean: rolling",
    ),
    "an answer that is not yes or no": (
        '[[request]]\nabilities = ["walking"]\nanswers = { grasping = "maybe" }\n',
        "request[0].answers.grasping = 'maybe': not yes or no",
    ),
    "the same request twice": (
        TINY + '\n[[request]]\nname = "again"\nabilities = ["rolling"]\n'
        'params = { payload = "0.05kg" }\n',
        "request[5] (again): the same request as",
    ),
    "a catalog that is not there": ('catalog = "none.toml"\n' + TINY, "none.toml"),
    "bad TOML": ("[[request]\n", "s.toml"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_names_file_and_key_exits_2_and_writes_nothing(
    cli, tmp_path: Path, case: str
) -> None:
    text, message = BAD[case]
    study = write(tmp_path / "s.toml", text)
    r = cli("sweep", str(study), "--no-simulate")
    assert r.code == 2, r.err
    assert message in r.err and str(study) in r.err
    assert "Traceback" not in r.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_bad_jobs_and_a_foreign_out_folder_are_bad_input(cli, tmp_path: Path) -> None:
    study = write(tmp_path / "s.toml")
    r = cli("sweep", str(study), "--jobs", "0", "--no-simulate")
    assert r.code == 2 and "--jobs 0" in r.err
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    r = cli("sweep", str(study), "--out", str(foreign), "--no-simulate")
    assert r.code == 2 and "holds no sweep" in r.err
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]
    assert not default_out(study).exists()


# --- running it ----------------------------------------------------------------------------


def test_rows_statuses_and_reasons(cli, tmp_path: Path) -> None:
    study = write(tmp_path / "s.toml")
    r = cli("sweep", str(study), "--no-simulate", "--jobs", "1")
    assert r.code == 0, r.err
    out = default_out(study)
    assert "wrote" in r.out and str(out) in r.out
    got = rows(out)
    assert len(got) == N_TINY  # one row per request: nothing simulated
    assert list(got[0])[:5] == ["request", "id", "robot_type", "payload", "speed"]
    by = {(g["request"], g["payload"], g["speed"]): g for g in got}
    snake = by[("snake", "0.05kg", "")]
    assert snake["robot_type"] == "SnakeRobot" and snake["status"] == "accepted"
    assert float(snake["mass_kg"]) > 0 and snake["abilities"] == "rolling"
    assert by[("cart", "0.5kg", "0.2m/s")]["robot_type"] == "DifferentialDriveRobot"
    fast = by[("fast-cart", "0.5kg", "0.6m/s")]
    assert fast["status"] == "refused" and fast["robot_type"] == "DifferentialDriveRobot"
    assert "0.60 m/s" in fast["reason"] and fast["mass_kg"] == ""
    none = by[("rolling+grasping", "", "")]
    assert none["status"] == "refused" and none["robot_type"] == ""
    assert none["reason"] == "no robot can meet the request: rolling + grasping"
    asks = by[("walking", "", "")]
    assert asks["status"] == "ambiguous" and "Does the robot need to grasp?" in asks["reason"]
    assert 'add grasping = "yes" or "no"' in asks["reason"]
    summary = (out / "summary.md").read_text()
    assert "| SnakeRobot | 2 | 2 | 0 |" in summary
    assert "| DifferentialDriveRobot | 3 | 2 | 1 |" in summary
    assert "## Requests not accepted" in summary
    assert "rolling + grasping" in summary and "0.60 m/s" in summary
    assert "plots/SnakeRobot-payload.png" in summary
    assert (out / "plots" / "SnakeRobot-payload.png").read_bytes()[:4] == b"\x89PNG"
    assert len(list((out / "requests").glob("*.json"))) == N_TINY


def test_same_files_with_one_or_two_jobs(cli, tmp_path: Path) -> None:
    study = write(tmp_path / "s.toml")
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli("sweep", str(study), "--no-simulate", "--jobs", "1", "--out", str(a)).code == 0
    assert cli("sweep", str(study), "--no-simulate", "--jobs", "2", "--out", str(b)).code == 0
    assert outputs(a) == outputs(b)
    assert sorted(p.name for p in (a / "requests").iterdir()) == sorted(
        p.name for p in (b / "requests").iterdir()
    )


def test_an_interrupted_sweep_resumes_to_the_same_bytes(
    cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    study = write(tmp_path / "s.toml")
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert cli("sweep", str(study), "--no-simulate", "--jobs", "1", "--out", str(whole)).code == 0
    real = synth.commands.sweep.design_one
    calls = []

    def interrupted(*args, **kwargs):
        if len(calls) == 3:
            raise KeyboardInterrupt  # Ctrl-C while the fourth request is designed
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(synth.commands.sweep, "design_one", interrupted)
    r = cli("sweep", str(study), "--no-simulate", "--jobs", "1", "--out", str(cut))
    assert r.code == 130 and "3 of 7 requests stored" in r.err and "run the same" in r.err
    assert len(list((cut / "requests").glob("*.json"))) == 3
    assert not (cut / "results.csv").exists()
    monkeypatch.setattr(synth.commands.sweep, "design_one", real)
    r = cli("sweep", str(study), "--no-simulate", "--jobs", "2", "--out", str(cut), "--json")
    assert r.code == 0, r.err
    s = json.loads(r.out)
    assert (s["computed"], s["reused"]) == (4, 3)
    assert outputs(cut) == outputs(whole)
    # a third run designs nothing and rewrites the same files
    r = cli("sweep", str(study), "--no-simulate", "--out", str(cut), "--json")
    assert json.loads(r.out)["computed"] == 0
    assert outputs(cut) == outputs(whole)


def fake_verify(bundle) -> list[Run]:
    """Two behaviours of every design: one ok, one built to fail two criteria, with a figure
    the real records do not have. The failing one realises a bonus ability (dropped from the
    design) unless the payload is 50 g, where it realises the demanded one (the request is
    refused)."""
    record = bundle.record
    assert "robot.xml" in bundle.files
    demanded = record["request"]["params"].get("payload") == "0.05kg"
    runs = [
        {"behavior": "a-ok", "ability": "rolling", "verdict": "ok", "saturated_fraction": 0.0},
        {
            "behavior": "b-bad",
            "ability": "rolling" if demanded else "bonus",
            "verdict": ["fell", "saturated"],
            "fell": True,
            "saturated_fraction": 0.5,
            "new_figure": 1.5,
        },
    ]
    return [Run.of(r) for r in runs]


def test_summary_counts_failures_by_criterion(
    cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import synth.verification.runs

    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake_verify)
    study = write(
        tmp_path / "s.toml",
        '[[request]]\nname = "snake"\nabilities = ["rolling"]\n'
        'params = { payload = ["0kg", "0.01kg", "0.05kg"] }\n\n'
        '[[request]]\nabilities = ["rolling", "grasping"]\n',
    )
    r = cli("sweep", str(study), "--jobs", "1", "--json")
    assert r.code == 0, r.err
    s = json.loads(r.out)
    assert s["types"]["SnakeRobot"] == {
        "requests": 3,
        "accepted": 2,
        "all_ok": 2,  # the failing behaviour's ability was dropped: the design does not list it
        "refused": 1,
        "refused_by_simulation": 1,
        "dropped": {"bonus": 2},
        "failures": {"fell": 3, "saturated": 3},
    }
    out = default_out(study)
    got = rows(out)
    assert [(g["payload"], g["status"], g["behavior"], g["listed"], g["verdict"]) for g in got] == [
        ("0kg", "accepted", "a-ok", "true", "ok"),
        ("0kg", "accepted", "b-bad", "false", "fell;saturated"),
        ("0.01kg", "accepted", "a-ok", "true", "ok"),
        ("0.01kg", "accepted", "b-bad", "false", "fell;saturated"),
        ("0.05kg", "refused", "a-ok", "true", "ok"),
        ("0.05kg", "refused", "b-bad", "true", "fell;saturated"),
        ("", "refused", "", "", ""),
    ]
    assert got[4]["reason"].startswith("b-bad failed in simulation: fell")
    assert got[1]["new_figure"] == "1.5" and got[0]["new_figure"] == ""
    assert got[1]["fell"] == "true" and got[1]["saturated_fraction"] == "0.5"
    assert got[1]["ability"] == "bonus" and got[0]["sizings"] == "1"
    summary = (out / "summary.md").read_text()
    assert "| SnakeRobot | 3 | 2 | 2 | 100 % | 1 (1) | bonus 2 |" in summary
    assert "| SnakeRobot | b-bad | fell | 3 |" in summary
    assert "| SnakeRobot | b-bad | saturated | 3 |" in summary
    assert "| SnakeRobot | a-ok | 3 | 3 |" in summary
    assert "## Abilities dropped" in summary and "| SnakeRobot | bonus | b-bad failed" in summary


def test_a_crash_is_reported_not_stored_and_tried_again(
    cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import synth.verification.runs

    def broken(bundle):
        raise RuntimeError("simulator exploded")

    monkeypatch.setattr(synth.verification.runs, "verify_nominal", broken)
    study = write(tmp_path / "s.toml", '[[request]]\nabilities = ["rolling"]\n')
    r = cli("sweep", str(study), "--jobs", "1")
    assert r.code == 0 and "1 request(s) failed with an error" in r.err
    out = default_out(study)
    assert rows(out)[0]["status"] == "error"
    assert "RuntimeError: simulator exploded" in rows(out)[0]["reason"]
    assert not list((out / "requests").glob("*.json"))
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake_verify)
    r = cli("sweep", str(study), "--jobs", "1")
    assert r.code == 0 and [g["status"] for g in rows(out)] == ["accepted", "accepted"]
    assert [g["listed"] for g in rows(out)] == ["true", "false"]


def test_simulated_sweep_of_a_differential_drive(cli, tmp_path: Path) -> None:
    """The real harness: every figure of the behaviour's simulation record is a column."""
    from synth.verification.runs import verify_nominal  # noqa: F401 (the harness this test runs)

    study = write(tmp_path / "s.toml", '[[request]]\nabilities = ["driving"]\n')
    r = cli("sweep", str(study), "--jobs", "1", "--json")
    assert r.code == 0, r.err
    out = default_out(study)
    got = rows(out)
    assert [g["behavior"] for g in got] == ["driving", "turning"]
    stored = json.loads(next((out / "requests").glob("*.json")).read_text())
    record = stored["result"]["behaviors"][0]
    assert set(record) <= set(got[0])
    v = record["verdict"]
    assert got[0]["verdict"] == (v if v == "ok" else ";".join(v))
    assert got[0]["saturated_fraction"] == json.dumps(record["saturated_fraction"])
    # the default differential drive keeps both promises
    assert [(g["status"], g["verdict"]) for g in got] == [("accepted", "ok")] * 2
    assert json.loads(r.out)["types"]["DifferentialDriveRobot"]["requests"] == 1


def test_the_key_follows_request_mode_and_files() -> None:
    q = {"abilities": ["walking"], "answers": {"a": "yes", "b": "no"}, "params": {"x": "1kg"}}
    same = {"abilities": ["walking"], "answers": {"b": "no", "a": "yes"}, "params": {"x": "1kg"}}
    key = request_key(q, True, "d")
    assert key == request_key(same, True, "d") and len(key) == 16
    assert key != request_key(q, False, "d")  # simulated or not
    assert key != request_key(q, True, "e")  # the study's files or parmor's own changed
    assert key != request_key({**q, "params": {"x": "2kg"}}, True, "d")
    names = {p.name for p in code_files()}
    assert {"sweep.py", "catalog.toml", "loop.py", "perturb.toml"} <= names and any(
        n.endswith(".kif") for n in names
    )


# --- the engine: local processes or Ray (synth.commands.backend; test_ray.py runs Ray) ---


@pytest.mark.parametrize("command", ["sweep", "enumerate"])
def test_ray_absent_is_bad_input_naming_the_extra(
    cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str
) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    study = write(tmp_path / "s.toml", '[[request]]\nabilities = ["driving"]\n')
    argv = [str(study), "--no-simulate"] if command == "sweep" else ["driving"]
    r = cli(command, *argv, "--backend", "ray")
    assert r.code == 2 and "pip install 'parmor[ray]'" in r.err, r.err
    assert "Traceback" not in r.err
    if command == "sweep":  # nothing stored, nothing written
        assert not list((default_out(study) / "requests").glob("*.json"))


def test_backend_options_are_checked(cli, tmp_path: Path) -> None:
    study = write(tmp_path / "s.toml")
    r = cli("sweep", str(study), "--no-simulate", "--address", "head:6379")
    assert r.code == 2 and "--address" in r.err and "--backend ray" in r.err
    r = cli("enumerate", "driving", "--jobs", "0")
    assert r.code == 2 and "--jobs 0" in r.err
    r = cli("enumerate", "driving", "--backend", "spark")
    assert r.code == 2 and "invalid choice" in r.err
    assert not default_out(study).exists()


def test_start_up_does_not_import_ray() -> None:
    import subprocess
    import sys

    code = (
        "import sys, io; from synth.commands.cli import main; "
        "main(['sweep', '--help'], io.StringIO(), io.StringIO()); "
        "main(['enumerate', 'driving', '--conceptual'], io.StringIO(), io.StringIO()); "
        "print('ray' in sys.modules)"
    )
    repo = Path(__file__).resolve().parents[3]
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=repo, timeout=120
    )
    assert r.stdout.strip() == "False", r.stderr


def test_enumerate_on_two_local_processes_prints_the_same_lines(cli) -> None:
    one = cli("enumerate", "driving", "--assignments", "2", "--json")
    two = cli("enumerate", "driving", "--assignments", "2", "--json", "--jobs", "2")
    assert one.code == two.code == 0 and one.out == two.out
    assert one.out.count('"type": "candidate"') == 2


def test_a_node_whose_files_differ_refuses_the_work(tmp_path: Path) -> None:
    """The check a Ray worker makes before its first task (built to fail: a digest of other
    files, a study file missing on the node)."""
    from synth.commands.backend import BackendError, _ray_work, files_digest

    mine = tmp_path / "mine.kif"
    mine.write_text("(subclass Gizmo Robot)\n")
    files = (None, [str(mine)], [])

    def init(arg):
        return arg

    def work(state, item):
        return state + item

    good = (files, files_digest(*files))
    assert _ray_work(init, 1, "t-good", good, work, "k", 2) == ("k", 3)
    with pytest.raises(BackendError, match="differ"):
        _ray_work(init, 1, "t-other", (files, "0" * 64), work, "k", 2)
    mine.unlink()
    with pytest.raises(BackendError, match="mine.kif.*same paths"):
        _ray_work(init, 1, "t-missing", good, work, "k", 2)


# --- certifying the finalists (--certify N) --------------------------------------------------

CERTIFY = """\
[[request]]
name = "cart"
abilities = ["driving"]

[[request]]
name = "skid"
abilities = ["driving"]
params = { payload = "2kg" }

[[request]]
abilities = ["rolling", "grasping"]
"""


def test_certify_designs_the_finalists_again_with_n_perturbed_runs(cli, tmp_path: Path) -> None:
    """The accepted requests (a nominal study's) are designed again with N perturbed runs
    and each states what they show; built to fail: the 2 kg skid-steer, accepted on the
    nominal model, is refused by its certification (its turn slides on the slope), and the
    request no robot meets is not certified at all."""
    study = write(tmp_path / "s.toml", CERTIFY)
    r = cli("sweep", str(study), "--jobs", "1", "--certify", "3", "--json")
    assert r.code == 0, r.err
    s = json.loads(r.out)
    assert s["status"]["accepted"] == 2  # the study's own verdicts: nominal
    got = {c["request"]: c for c in s["certified"]}
    assert set(got) == {"cart: driving", "skid: driving payload=2kg"}
    cart, skid = got["cart: driving"], got["skid: driving payload=2kg"]
    assert cart["status"] == "accepted" and cart["runs"] == 3
    assert cart["success_lower_bound"] == pytest.approx(0.1 ** (1 / 3), abs=1e-3)
    assert skid["status"] == "refused" and "turning is not robust" in skid["reason"]
    summary = (default_out(study) / "summary.md").read_text()
    assert "## Certified finalists" in summary and "above 46 % at 90 % confidence" in summary
    # stored: the same command again designs nothing
    again = json.loads(cli("sweep", str(study), "--jobs", "1", "--certify", "3", "--json").out)
    assert again["computed"] == 0 and again["certified"] == s["certified"]


@pytest.mark.parametrize(
    "extra, why",
    [
        (["--certify", "3", "--no-simulate"], "drop --no-simulate"),
        (["--certify", "0"], "--certify"),
    ],
)
def test_certify_needs_the_verification_and_a_run(cli, tmp_path: Path, extra, why) -> None:
    study = write(tmp_path / "s.toml", CERTIFY)
    r = cli("sweep", str(study), "--jobs", "1", *extra)
    assert r.code == 2 and why in r.err, r.err
    assert not default_out(study).exists()


def test_a_certification_is_stored_apart_from_a_study_with_as_many_runs() -> None:
    """A study with ``robustness = 30`` needs every run, a certification of 30 needs 26:
    their results are not the same, so their keys differ (else one was taken for the
    other)."""
    from synth.commands.sweep import request_key

    q = {"abilities": ["walking"], "answers": {}, "params": {}}
    assert request_key(q, True, "d", 30) != request_key(q, True, "d", 30, True)
    assert request_key(q, True, "d", 30) == request_key(q, True, "d", 30, False)
