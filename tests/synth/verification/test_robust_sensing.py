"""The sensing loops under perturbation (issue 30, items 3 and 4): the robust verification
runs line-tracking and obstacle-avoidance on every perturbed robot with their sensors'
noise, ``verified.robust`` lists them, a run is replayed to the bit from the bundle
(``parmor simulate --perturb``, ``parmor run --perturb``), and a program runs the very
loops the verification ran."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from program.sensing import SensorNoise, run_sensing
from synth.verification.perturb import design_table, draw
from synth.verification.runs import robust_missing, verify_robust
from synth.verification.source import Bundle

#: The demo cart with both sensing abilities, not verified (its runs are made here).
SENSING_CART = ("driving", "line-tracking", "obstacle-avoidance", "--no-verify")
SENSING = ("line-tracking", "obstacle-avoidance")


@pytest.fixture(scope="module")
def cart(designs) -> Path:
    return designs(*SENSING_CART).folder


@pytest.fixture(scope="module")
def table(cart, catalog) -> dict:
    bundle = Bundle.read(cart)
    record, xml, _ = bundle.record, bundle.xml, bundle.meshes
    return json.loads(json.dumps(design_table(record, xml, catalog)))


@pytest.fixture(scope="module")
def robust(cart, table) -> dict:
    """Two perturbed runs of every behaviour of the cart, its sensing loops included."""
    return verify_robust(Bundle.read(cart), 2, table).to_dict()


@pytest.fixture(scope="module")
def verified(cart, table, robust, tmp_path_factory) -> Path:
    """A copy of the cart whose record holds the perturbed runs (as ``parmor design``
    writes it: ``verified.behaviors`` nominal, ``verified.robust``)."""
    import shutil

    from program.sensing import verify_sensing

    out = tmp_path_factory.mktemp("verified") / "cart"
    shutil.copytree(cart, out)
    record = json.loads((out / "design.json").read_text())
    nominal = [{"behavior": b["behavior"], "verdict": "ok"} for b in robust["behaviors"]]
    assert [r["verdict"] for r in verify_sensing(Bundle.read(cart).files)] == ["ok", "ok"]
    record["verified"] = {"behaviors": nominal, "robust": robust}
    (out / "design.json").write_text(json.dumps(record))
    return out


def test_the_table_carries_the_sensors_noise(table) -> None:
    assert table["infrared"] == {"edge_offset_m": 0.002, "edge_jitter_m": 0.0005}
    assert table["ultrasonic"] == {"noise_m": 0.003, "resolution_m": 0.003, "scale": 0.01}
    p = draw(table, 3)
    edges = p["sensing"]["infrared"]["edge_offset_m"]
    assert len(edges) == 2 and all(abs(e) <= 0.002 for e in edges)
    assert 0.99 <= p["sensing"]["ultrasonic"]["scale"] <= 1.01


def test_sensor_draws_come_after_the_others(table) -> None:
    """A table without the sensors draws every other quantity as before."""
    bare = {k: v for k, v in table.items() if k not in ("infrared", "ultrasonic")}
    for seed in (1, 2, 7):
        with_sensors, without = draw(table, seed), draw(bare, seed)
        assert "sensing" not in without
        assert {k: v for k, v in with_sensors.items() if k != "sensing"} == without


def test_the_nominal_robot_reads_its_sensors_exactly() -> None:
    exact = SensorNoise(None)
    assert exact.rng is None
    assert exact.sees(0, 0.0095) and not exact.sees(1, 0.0096)
    assert exact.range(0.1234) == 0.1234
    noisy = SensorNoise(
        {
            "stream": 1,
            "seed": 1,
            "infrared": {"edge_offset_m": [0.002, -0.002], "edge_jitter_m": 0.0},
            "ultrasonic": {"scale": 1.01, "noise_m": 0.0, "resolution_m": 0.003},
        }
    )
    assert noisy.sees(0, 0.011) and not noisy.sees(1, 0.008)  # the left sees a wider tape
    assert noisy.range(1.0) == pytest.approx(1.011, abs=1e-9)  # x1.01, rounded to 3 mm


def test_verified_robust_lists_the_sensing_loops(robust) -> None:
    entries = {b["behavior"]: b for b in robust["behaviors"]}
    assert set(entries) == {"driving", "turning", *SENSING}
    for name in SENSING:
        b = entries[name]
        assert b["loop"] == "sensing" and b["ability"] == name
        assert (b["passed"], b["runs"], b["robust"], b["failures"]) == (2, 2, True, [])
        assert [f["seed"] for f in b["figures"]] == [1, 2]
        assert b["worst"]  # its worst figures, as for the others
    assert entries["line-tracking"]["worst"]["line_lost_s"]["value"] <= 0.5
    assert entries["obstacle-avoidance"]["worst"]["obstacle_contact_s"]["value"] == 0.0
    assert "sensors" in robust["perturbations"][0]  # the sensors' draws, summed up


def test_a_sensing_loop_missing_from_the_perturbed_runs_is_found(verified) -> None:
    record = json.loads((verified / "design.json").read_text())
    assert robust_missing(record) == []
    broken = copy.deepcopy(record)
    broken["verified"]["robust"]["behaviors"] = [
        b for b in broken["verified"]["robust"]["behaviors"] if b["behavior"] != "line-tracking"
    ]
    assert robust_missing(broken) == ["line-tracking"]
    from synth.verification.loop import robust_skipped
    from synth.verification.results import RobustRuns, Run

    runs = [Run.of(b) for b in broken["verified"]["behaviors"]]
    assert robust_skipped(runs, RobustRuns.of(broken["verified"]["robust"])) == ["line-tracking"]
    assert robust_missing({"verified": {"behaviors": record["verified"]["behaviors"]}}) == []


def test_a_perturbed_sensing_run_is_replayed_exactly(cli, verified, robust) -> None:
    """``parmor simulate --perturb`` and a session on the same seed give the recorded
    figures to the bit."""
    entries = {b["behavior"]: b for b in robust["behaviors"]}
    recorded = {k: v for k, v in entries["line-tracking"]["figures"][1].items() if k != "seed"}
    r = cli("simulate", str(verified), "--behavior", "line-tracking", "--perturb", "2", "--json")
    assert r.code == 0, r.err
    got = json.loads(r.out)
    assert got.pop("perturbation")["seed"] == 2
    assert got == recorded
    again = run_sensing(Bundle.read(verified).files, "line-tracking", perturb=(robust["table"], 2))
    assert again == recorded


def test_parmor_run_ends_where_the_verification_says(cli, verified, robust, tmp_path) -> None:
    """A program of one sensing behaviour run on perturbation 1 by ``parmor run`` drives
    the loop the verification ran on that seed: the same figures."""
    entries = {b["behavior"]: b for b in robust["behaviors"]}
    program = tmp_path / "p.json"
    program.write_text(json.dumps({"program": [{"do": "obstacle-avoidance"}]}))
    r = cli("run", str(program), str(verified), "--perturb", "1", "--json")
    assert r.code == 0, r.err
    step = json.loads(r.out)["steps"][0]["figures"]
    recorded = {k: v for k, v in entries["obstacle-avoidance"]["figures"][0].items()}
    assert {k: v for k, v in step.items()} == {k: v for k, v in recorded.items() if k != "seed"}
    nominal = cli("run", str(program), str(verified), "--json")
    assert json.loads(nominal.out)["steps"][0]["figures"] != step  # the perturbation tells


def test_an_impossible_perturbation_fails_the_line_follower(cart, table) -> None:
    """Sensors whose edge jitters by 3 cm (a tape of 19 mm) lose the line; a floor of
    a twentieth of the friction does too. The failure names the sensors' draws."""
    noisy = dict(table, infrared={"edge_offset_m": 0.0, "edge_jitter_m": 0.03})
    icy = dict(table, friction=[0.05, 0.05])
    files = Bundle.read(cart)
    for bad in (noisy, icy):
        got = verify_robust(files, 1, bad, behaviors=["line-tracking"])
        (b,) = got.to_dict()["behaviors"]
        assert (b["behavior"], b["passed"], b["robust"]) == ("line-tracking", 0, False), b
        (f,) = b["failures"]
        assert "line edges" in f["perturbation"] and f["why"]
        why = got.behavior("line-tracking").why_not(got.required)
        assert why.startswith("line-tracking is not robust: passed 0 of 1")


def test_the_bus_delays_and_holds_the_commands(cart, table) -> None:
    """On a perturbed robot a command reaches the servos ``latency`` late and changes once
    a control period, on the session's clock across calls (as ``simulate`` delays a plan)."""
    from program.session import Session

    s = Session(cart, perturb=(table, 1))
    s._delay, s._hold, s._sent, s._step = 3, 2, None, 0
    sent = np.arange(10.0)[:, None] * np.ones((1, s.model.nu))
    got = s._bus(sent[:6])[:, 0].tolist() + s._bus(sent[6:])[:, 0].tolist()
    # step n acts on the command of step floor((n - 3) / 2) * 2; before the first, the first
    assert got == [0, 0, 0, 0, 0, 2, 2, 4, 4, 6]
    assert Session(cart)._bus(sent) is sent  # the nominal robot: no bus


def test_a_sensing_loops_plans_run_their_feedback_loop(cart, monkeypatch) -> None:
    """A plan that asks for a feedback loop is run closed inside a sensing loop too (the
    session's stepping wires synth.verification.simulate's loop): its loop reads the servos at the
    control rate (every 20 ms) and its offsets reach them."""
    from gaits import feedback
    from program.session import Session

    readings: list[float] = []

    class Count(feedback.Loop):
        def correct(self, r):
            readings.append(r.t)
            return np.zeros(len(self.joints))

    monkeypatch.setitem(feedback._LOOPS, "test-count", Count)
    s = Session(cart)
    plan = s.controller.run

    def with_loop(name, **params):
        traj = plan(name, **params)  # (a copy: plans are remembered)
        return dataclasses.replace(traj, info={**traj.info, "feedback": {"loop": "test-count"}})

    monkeypatch.setattr(s.controller, "run", with_loop)
    fig = s.do("line-tracking", length=0.3)["figures"]
    assert fig["verdict"] == "ok", fig
    # three readings a 50 ms period of the line follower (0, 20 and 40 ms), every period
    periods = round(fig["seconds"] * 20)
    assert len(readings) >= 3 * (periods - 2), (len(readings), periods)
    assert sorted(set(np.round(readings, 6))) == [0.0, 0.02, 0.04]


def test_a_bundle_not_verified_under_perturbation_cannot_be_replayed(cli, cart, tmp_path) -> None:
    """Built to fail: the cart designed with --no-verify has no perturbation table."""
    r = cli("simulate", str(cart), "--behavior", "line-tracking", "--perturb", "1")
    assert r.code == 2 and "verified.robust.table is missing" in r.err
    program = tmp_path / "p.json"
    program.write_text(json.dumps({"program": [{"do": "line-tracking"}]}))
    r = cli("run", str(program), str(cart), "--perturb", "1")
    assert r.code == 2 and "verified.robust.table is missing" in r.err


def test_parmor_design_lists_the_sensing_loops_in_verified_robust(cli) -> None:
    """The design loop (synth/verification/loop.py) runs the loops perturbed once the repairs are
    done: every behaviour the design lists is in ``verified.robust``."""
    r = cli("design", "driving", "line-tracking", "--robustness", "2", "--no-input", "--json")
    assert r.code == 0, r.err
    v = json.loads(r.out)["verified"]
    entries = {b["behavior"]: b for b in v["robust"]["behaviors"]}
    assert set(entries) == {b["behavior"] for b in v["behaviors"]} >= {"line-tracking"}
    assert entries["line-tracking"]["loop"] == "sensing"
    assert (entries["line-tracking"]["passed"], entries["line-tracking"]["runs"]) == (2, 2)
    assert robust_missing({"verified": v}) == []
