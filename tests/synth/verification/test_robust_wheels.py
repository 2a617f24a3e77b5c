"""Robust verification of wheeled robots (issue 22): the replay that finds which
perturbation breaks a run (``bench/robust_isolate.py``), checked on a differential drive
whose straight drive a cross slope turns (its wheel servos droop unequally under the
slope's yaw moment: README *Robust verification*)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "bench"))

import robust_isolate  # noqa: E402

#: A differential drive, its perturbation seed whose cross slope turns its straight drive.
REQUEST = ("driving", "--param", "payload=1kg", "--param", "speed=0.1m/s")
SEED = 6


@pytest.fixture(scope="module")
def bundle(tmp_path_factory) -> Path:
    import io

    from synth.commands.cli import main

    out = tmp_path_factory.mktemp("robwheel") / "dd"
    err = io.StringIO()
    code = main(["design", *REQUEST, "--no-input", "--out", str(out)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    return out


def test_the_nominal_case_neutralises_every_component() -> None:
    from synth.verification.perturb import draw

    table = {
        "stream": 1,
        "friction": [0.6, 1.2],
        "max_slope_rad": 0.05,
        "latency_s": [0.01, 0.04],
        "control_period_s": 0.02,
        "battery_scale": 0.9,
        "mass_spread": 0.1,
        "bodies": ["a", "b"],
        "servos": {"j": {"backlash_rad": [0.01, 0.02], "deadband_rad": 0.001}},
    }
    p = draw(table, 3)
    q = robust_isolate.nominal(p)
    assert set(q) == set(p)  # a component draw() adds must be neutralised here too
    covered = {k for keys in robust_isolate.COMPONENTS.values() for k in keys}
    assert covered == set(p) - {"seed"}
    assert q["friction_scale"] == 1 and q["slope_rad"] == 0 and q["latency_s"] == 0
    assert q["battery_scale"] == 1 and not q["mass_scale"] and not q["play_rad"]
    # built to fail: the perturbation itself is not nominal
    assert p["friction_scale"] != 1 and p["play_rad"]


def test_the_replay_names_the_component_that_breaks_the_run(bundle) -> None:
    """Open loop (the plan alone) the cross slope breaks the drive; closed on the wheels'
    odometry (gaits.wheel_feedback, what the design runs) the same perturbation passes."""
    import json

    from synth.verification.runs import verify_nominal

    _, closed = robust_isolate.replays(str(bundle), "driving", SEED)
    assert closed["all"]["verdict"] == "ok", closed["all"]
    assert abs(closed["all"]["heading_rad"]) < 0.05
    from synth.verification.source import Bundle

    runs = verify_nominal(Bundle.read(bundle), ["driving"])
    nominal = {r.behavior: r.to_dict() for r in runs}["driving"]
    for key in ("heading_rad", "distance_m", "final_pose_error_m", "verdict"):
        assert closed["none"][key] == nominal[key], key
    p, runs = robust_isolate.replays(str(bundle), "driving", SEED, open_loop=True)
    assert runs["all"]["verdict"] != "ok"
    # the whole perturbation breaks it; the cross slope alone does, nothing else does
    broke = [c for c in robust_isolate.COMPONENTS if runs[c]["verdict"] != "ok"]
    assert broke == ["slope"], json.dumps({c: runs[c]["verdict"] for c in runs})
    assert abs(runs["slope"]["heading_rad"]) > abs(runs["none"]["heading_rad"]) + 0.2
    assert p["seed"] == SEED


def _design(*argv: str) -> tuple[int, dict | None, str]:
    import io
    import json

    from synth.commands.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main(["design", *argv, "--no-input", "--json"], out, err)
    return code, json.loads(out.getvalue()) if out.getvalue().strip() else None, err.getvalue()


def test_a_steered_turn_at_its_default_speed_is_robust(monkeypatch) -> None:
    """A tricycle's turn by an arc at 0.9 of its top speed passes all 8 perturbed runs; at
    0.5 (the former default: a slope's droop a larger share of the speed) seed 6's 2.9 deg
    slope puts it 3.1 cm off its planned pose (the case built to fail)."""
    import gaits.base
    import gaits.steered

    request = ("steered-driving", "--param", "payload=0kg", "--param", "speed=0.3m/s")
    code, rec, err = _design(*request, "--robustness", "8")
    assert code == 0, err
    assert rec["robot_type"] == "TricycleRobot"
    runs = {b["behavior"]: (b["passed"], b["runs"]) for b in rec["verified"]["robust"]["behaviors"]}
    assert runs == {"driving": (8, 8), "turning": (8, 8)}
    monkeypatch.setattr(gaits.steered, "TURN_SPEED_FRACTION", 0.5)
    monkeypatch.setattr(gaits.base, "_PLANNED", type(gaits.base._PLANNED)())  # no old plans
    code, _, err = _design(*request, "--robustness", "8")
    assert code == 1 and "turning is not robust" in err, err


def test_a_turn_in_place_at_its_default_speed_is_robust(tmp_path, monkeypatch) -> None:
    """A differential drive (payload 0.5 kg, 0.1 m/s) turning in place with its rims at 0.5
    of the wheels' top speed passes all 8 perturbed runs; at 0.25 (the former default)
    too, closed on its wheels' odometry; open loop at 0.25 the slopes of seeds 1, 3 and 6
    turn it off by more than 10 % or off its pose (the case built to fail)."""
    import io

    import gaits.base
    import gaits.wheeled
    from adron.catalog import load_catalog
    from synth.commands.cli import main
    from synth.verification.perturb import design_table
    from synth.verification.runs import verify_robust
    from synth.verification.source import Bundle

    out = tmp_path / "dd"
    argv = ["design", "driving", "--param", "payload=0.5kg", "--param", "speed=0.1m/s"]
    err = io.StringIO()
    assert main([*argv, "--no-input", "--out", str(out)], io.StringIO(), err) == 0, err.getvalue()
    files = Bundle.read(out)
    record, xml, _ = files.record, files.xml, files.meshes
    table = design_table(record, xml, load_catalog())

    def passed() -> int:
        return verify_robust(files, 8, table, ["turning"]).behaviors[0].passed

    assert passed() == 8
    monkeypatch.setattr(gaits.wheeled, "TURN_SPEED_FRACTION", 0.25)
    monkeypatch.setattr(gaits.base, "_PLANNED", type(gaits.base._PLANNED)())  # no old plans
    # closed on the wheels' odometry (gaits.wheel_feedback) the slow turn holds too
    assert passed() == 8
    # open loop (the plan alone, its feedback spec left out) it does not
    monkeypatch.setattr(gaits.wheeled.WheeledController, "feedback_spec", lambda *a, **k: {})
    monkeypatch.setattr(gaits.base, "_PLANNED", type(gaits.base._PLANNED)())
    assert passed() < 8
