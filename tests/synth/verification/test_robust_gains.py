"""A closed loop's gains as an answer of the robust loop (synth/verification/gains.py): when
a perturbed run of a closed-loop behaviour fails and no sizing answers it, the loop tries
the loop's gains scaled (``GAIN_SCALES``: x2, then x0.5) and keeps the first with which
the nominal run and every perturbed run pass; the record's ``feedback_gains`` gives it to
the controller, so a replay from the bundle runs the same gains; a refusal names the
scales tried.

The cases are built by weakening the wheels' loop (gaits/wheel_feedback.py's gains x0.02,
or x0) on a 1 kg differential drive whose open-loop drive veers on the table's cross
slopes (tests/synth/verification/test_stiffer_wheels.py); its wheels' own answer, a
stiffer servo, is turned
off so that the gains are what is left.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

REQUEST = ("driving", "--param", "payload=1kg", "--param", "speed=0.1m/s", "--no-input")
GAINS = ("KP_HEADING", "KI_HEADING", "KP_DISTANCE", "KI_DISTANCE", "KI_STILL")


@pytest.fixture
def weak_loop(monkeypatch):
    """The wheels' loop with its gains scaled by a factor (the returned setter), and no
    stiffer wheel servo to answer a failure."""
    import gaits.wheel_feedback as wf
    import synth.verification.wheels

    monkeypatch.setattr(synth.verification.wheels, "wheel_exclusions", lambda *a, **k: ({}, None))

    def weaken(factor: float) -> None:
        for name in GAINS:
            monkeypatch.setattr(wf, name, getattr(wf, name) * factor)

    return weaken


def test_a_loop_scales_the_gains_it_names() -> None:
    """``gain_scale`` multiplies a loop's gains (``Loop.GAINS``), not its limits."""
    from types import SimpleNamespace

    from gaits.balance import Balance
    from gaits.feedback import JointHold
    from gaits.wheel_feedback import WheelHold

    traj = SimpleNamespace(joints=("a", "b"), behavior="x")
    hold = JointHold(traj, {"loop": "joint-hold", "ki": 4.0, "limit_rad": 0.1, "gain_scale": 2})
    assert (hold.ki, hold.limit) == (8.0, 0.1)
    assert JointHold(traj, {"loop": "joint-hold", "ki": 4.0}).ki == 4.0  # no scale: as given
    wheels = {"sign": {}, "left": [], "right": [], "radius_m": 0.03, "track_m": 0.1}
    held = WheelHold(traj, wheels | {"max_speed_rad_s": 5.0, "k": 6.0, "gain_scale": 0.5})
    assert (held.k, held.top) == (3.0, 5.0)
    balance = Balance(traj, {"loop": "balance", "gain_scale": 2.0})
    assert balance.g["kp_ankle"] == pytest.approx(0.6) and balance.g["limit_rad"] == 0.2


def test_the_record_gives_the_controller_its_gains(cli, tmp_path: Path) -> None:
    """The record's ``feedback_gains`` reach the behaviour's plans (and only its)."""
    from gaits import controller_for
    from gaits.base import DesignGeometry

    r = cli("design", *REQUEST, "--no-verify", "--json")
    assert r.code == 0, r.err
    rec = json.loads(r.out)
    plain = controller_for(DesignGeometry.from_record(rec))
    assert "gain_scale" not in plain.run("driving").info["feedback"]
    tuned = controller_for(DesignGeometry.from_record(rec | {"feedback_gains": {"driving": 2.0}}))
    assert tuned.run("driving").info["feedback"]["gain_scale"] == 2.0
    assert "gain_scale" not in tuned.run("turning").info["feedback"]
    bad = rec | {"feedback_gains": {"driving": -1}}
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / "design.json").write_text(json.dumps(bad))
    r = cli("simulate", str(folder), "--behavior", "driving")
    assert r.code == 2 and "feedback_gains.driving" in r.err and "Traceback" not in r.err


def test_gains_answer_a_loop_too_weak_and_replay_from_the_bundle(
    cli, weak_loop, monkeypatch, tmp_path: Path
) -> None:
    """Built to fail with the loop's own gains (x0.02 of the shipped ones): its perturbed
    runs veer; scaled x50 (the set passed here) every run passes, the design is accepted
    with that scale, and ``parmor simulate --perturb`` replays the recorded runs with it."""
    import synth.verification.gains

    weak_loop(0.02)
    monkeypatch.setattr(synth.verification.gains, "GAIN_SCALES", (50.0,))
    out = tmp_path / "drive"
    r = cli("design", *REQUEST, "--robustness", "8", "--out", str(out))
    assert r.code == 0, r.err
    rec = json.loads((out / "design.json").read_text())
    assert rec["feedback_gains"] == {"driving": 50.0, "turning": 50.0}
    gains = rec["verified"]["robust"]["gains"]
    assert gains["chosen"] == rec["feedback_gains"] and gains["scales"] == [50.0]
    assert {(t["behavior"], t["passed"], t["runs"]) for t in gains["tried"]} == {
        ("driving", 8, 8),
        ("turning", 8, 8),
    }
    assert rec["verified"]["rounds"] == 1  # no new sizing: the same structure
    assert "gains driving: its wheel-odometry loop's gains x50" in r.out
    entry = next(b for b in rec["verified"]["robust"]["behaviors"] if b["behavior"] == "driving")
    assert entry["passed"] == entry["runs"] == 8
    for seed in (1, 3):
        r = cli("simulate", str(out), "--behavior", "driving", "--perturb", str(seed), "--json")
        assert r.code == 0, r.err
        replay = json.loads(r.out)
        replay.pop("perturbation")
        assert {"seed": seed} | replay == entry["figures"][seed - 1]
    # the same bundle without its gains: the weak loop's own, which fail a seed
    rec.pop("feedback_gains")
    (out / "design.json").write_text(json.dumps(rec))
    codes = [
        cli("simulate", str(out), "--behavior", "driving", "--perturb", str(s), "--json").code
        for s in range(1, 9)
    ]
    assert 1 in codes


def test_gains_that_do_not_answer_are_named(cli, weak_loop, monkeypatch) -> None:
    """Built to fail whatever the scale: the loop's gains at 0. The refusal names the
    scales tried and what each gave (a scale's runs stop at the first that fails, the
    worst-looking perturbations first); the record keeps them, none chosen."""
    import synth.verification.loop

    weak_loop(0.0)
    monkeypatch.setattr(synth.verification.loop, "HINT_ROUNDS", 0)
    r = cli("design", *REQUEST, "--robustness", "8", "--json")
    assert r.code == 1
    assert "loop's gains x2 (perturbed run " in r.err and ", x0.5 (" in r.err, r.err
    assert "do not make it pass" in r.err
    rec = json.loads(r.out)
    gains = rec["verified"]["robust"]["gains"]
    assert gains["chosen"] == {} and "feedback_gains" not in rec
    tried = [(t["behavior"], t["scale"]) for t in gains["tried"]]
    assert ("driving", 2.0) in tried and ("driving", 0.5) in tried
    for t in gains["tried"]:  # each stopped at its first failed run (a batch of them)
        assert t["nominal"] != "ok" or t["passed"] < t["runs"] < t["of"] == 8


def test_no_gains_for_an_open_loop_or_a_bonus_behaviour() -> None:
    """The cause passes over a behaviour that serves no demand, and a plan with no loop."""
    from synth.verification.causes import Round
    from synth.verification.gains import Gains
    from synth.verification.results import RobustRuns

    robust = RobustRuns.of(
        {
            "k": 2,
            "behaviors": [
                {
                    "behavior": "driving",
                    "passed": 0,
                    "runs": 2,
                    "robust": False,
                    "failures": [
                        {"seed": 1, "verdict": ["heading"], "why": "w", "perturbation": "p"}
                    ],
                }
            ],
        }
    )

    class Plan:
        info: dict = {}

    class Bundle:
        def controller(self):
            return type("C", (), {"run": lambda self, name: Plan()})()

    open_loop = Round(1, {}, {}, None, robust, Bundle, demanded=frozenset({"driving"}))
    assert Gains().explains(open_loop) is None
    bonus = Round(1, {}, {}, None, robust, Bundle, demanded=frozenset())
    cause = Gains()
    assert cause.explains(bonus) is None and cause.tried == [] and cause.record() is None
