"""Robust verification of wheeled robots (issue 22): the replay that finds which
perturbation breaks a run (``bench/robust_isolate.py``), checked on a differential drive
whose straight drive a cross slope turns (its wheel servos droop unequally under the
slope's yaw moment: README *Robust verification*)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import robust_isolate  # noqa: E402

#: A differential drive, its perturbation seed whose cross slope turns its straight drive.
REQUEST = ("driving", "--param", "payload=1kg", "--param", "speed=0.1m/s")
SEED = 6


@pytest.fixture(scope="module")
def bundle(tmp_path_factory) -> Path:
    import io

    from synth.cli import main

    out = tmp_path_factory.mktemp("robwheel") / "dd"
    err = io.StringIO()
    code = main(["design", *REQUEST, "--no-input", "--out", str(out)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    return out


def test_the_nominal_case_neutralises_every_component() -> None:
    from export.perturb import draw

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
    import json

    from export.verify import verify_bundle

    p, runs = robust_isolate.replays(str(bundle), "driving", SEED)
    nominal = {r["behavior"]: r for r in verify_bundle(bundle, ["driving"])}["driving"]
    # every component nominal: the nominal run, figure for figure
    for key in ("heading_rad", "distance_m", "final_pose_error_m", "verdict"):
        assert runs["none"][key] == nominal[key], key
    assert runs["all"]["verdict"] != "ok"
    # the whole perturbation breaks it; the cross slope alone does, nothing else does
    broke = [c for c in robust_isolate.COMPONENTS if runs[c]["verdict"] != "ok"]
    assert broke == ["slope"], json.dumps({c: runs[c]["verdict"] for c in runs})
    assert abs(runs["slope"]["heading_rad"]) > abs(runs["none"]["heading_rad"]) + 0.2
    assert p["seed"] == SEED
