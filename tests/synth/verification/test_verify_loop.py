"""The verification loop of ``parmor design`` (synth/verification/loop.py).

The loop's decisions are checked with the simulator's answers replaced (a saturated joint,
a failing bonus ability, a failing demanded one); one design is verified for real.
"""

from __future__ import annotations

import json

import pytest

import synth.verification.loop
import synth.verification.runs
from synth.pipeline import StructureOptions, run
from synth.reasoning.conceptual import Request
from synth.verification.results import RobustRuns, Run

ARM = Request(abilities=("pick-and-place",), params=(("object_shape", "cylinder"),))


def _fake(results_by_round):
    """A stand-in for synth.verification.runs.verify_nominal answering round by round."""
    calls = []

    def verify_nominal(bundle, behaviors=None):
        record = bundle.record
        calls.append(record)
        return results_by_round[min(len(calls), len(results_by_round)) - 1]

    return verify_nominal, calls


def _result(behavior, ability, verdict="ok", **kw):
    return Run.of(
        {"behavior": behavior, "ability": ability, "verdict": verdict, "seconds": 1.0} | kw
    )


def _saturated(joint, fraction):
    """pick-and-place failing with ``joint`` at its torque limit ``fraction`` of the time."""
    return _result(
        "pick-and-place",
        "pick-and-place",
        ["saturated"],
        saturated_fraction=fraction,
        saturated_joints={joint: fraction},
    )


def test_a_real_arm_is_verified_in_mujoco(designer):
    out = run(designer, ARM, StructureOptions())
    rec = out.record(designer)
    v = rec["verified"]
    assert v["simulated"] and v["rounds"] == 1 and not v["dropped"]
    assert sorted(b["behavior"] for b in v["behaviors"]) == [
        "grasping",
        "move_to_pose",
        "pick-and-place",
        "positioning",
    ]
    assert all(b["verdict"] == "ok" and b["placing_error_m"] < 0.005 for b in v["behaviors"])
    # the written bundle's record is the one that says so
    assert json.loads(out.files(designer)["design.json"])["verified"] == v


def test_no_verify_says_so(designer):
    rec = run(designer, ARM, StructureOptions(verify=False)).record(designer)
    assert rec["verified"] == {"simulated": False, "note": "not simulated (--no-verify)"}


def test_a_saturated_joint_gets_a_stronger_actuator(designer, monkeypatch):
    base = run(designer, ARM, StructureOptions(verify=False)).record(designer)
    before = {j["name"]: j for j in base["joints"]}
    sat = _saturated("elbow_pitch", 0.3)
    fake, calls = _fake([[sat], [_result("pick-and-place", "pick-and-place")]])
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    out = run(designer, ARM, StructureOptions())
    rec = out.record(designer)
    after = {j["name"]: j for j in rec["joints"]}
    assert len(calls) == 2 and rec["verified"]["rounds"] == 2 and out.infeasible is None
    assert after["elbow_pitch"]["usable_torque_Nm"] > before["elbow_pitch"]["usable_torque_Nm"]
    assert after["elbow_pitch"]["load_case"] == "simulation"
    assert set(rec["verified"]["strengthened"]) == {"elbow_pitch"}


def test_a_failing_demanded_ability_fails_the_request(designer, monkeypatch):
    monkeypatch.setattr(
        synth.verification.loop, "HINT_ROUNDS", 0
    )  # the loop's own simulations only
    bad = _result("pick-and-place", "pick-and-place", ["placing"], placing_error_m=0.012)
    fake, calls = _fake([[bad]])
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    out = run(designer, ARM, StructureOptions())
    assert len(calls) == 1  # nothing saturated: nothing to strengthen
    assert out.status == "infeasible"
    assert "pick-and-place failed in simulation: placing (placing error 12 mm > 5)" in (
        out.infeasible
    )


def test_a_failing_bonus_ability_is_dropped_with_a_note(designer, monkeypatch):
    # the arm has positioning without being asked for it
    bad = _result("positioning", "positioning", ["placing"], placing_error_m=0.02)
    ok = _result("pick-and-place", "pick-and-place")
    fake, _ = _fake([[ok, bad]])
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    out = run(designer, ARM, StructureOptions())
    rec = out.record(designer)
    assert out.infeasible is None
    assert "positioning" not in rec["abilities"] and "pick-and-place" in rec["abilities"]
    assert any(n.startswith("dropped positioning: positioning failed") for n in rec["notes"])
    # the bundle is rebuilt without it: no trajectory of a dropped ability
    files = out.files(designer)
    assert "trajectories/positioning.csv" not in files


def test_no_stronger_actuator_leaves_the_failure_standing(designer, monkeypatch):
    monkeypatch.setattr(
        synth.verification.loop, "HINT_ROUNDS", 0
    )  # the loop's own simulations only
    # the shoulder already has the catalog's strongest servo
    sat = _saturated("shoulder_pitch", 0.2)
    fake, calls = _fake([[sat]])
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    out = run(designer, ARM, StructureOptions())
    assert len(calls) == 1 and out.status == "infeasible"


@pytest.mark.parametrize("rounds", [3])
def test_the_loop_stops_after_its_rounds(designer, monkeypatch, rounds):
    monkeypatch.setattr(
        synth.verification.loop, "HINT_ROUNDS", 0
    )  # the loop's own simulations only

    def sat(k):  # every round a different joint saturates: the loop must still stop
        joint = ["base_yaw", "elbow_pitch", "base_yaw", "elbow_pitch"][k]
        return [_saturated(joint, 0.5)]

    fake, calls = _fake([sat(0), sat(1), sat(2), sat(3)])
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    out = run(designer, ARM, StructureOptions())
    assert len(calls) == rounds and out.status == "infeasible"
    assert "saturated (saturated_fraction 0.5 > 0.05)" in out.infeasible


def _fails_above(limit_kg):
    """A stand-in simulator under which pick-and-place misses its target when the design
    carries more than ``limit_kg`` of payload (the case built to fail), and passes below."""
    calls = []

    def verify_nominal(bundle, behaviors=None):
        record = bundle.record
        payload = record["params"]["payload"]
        calls.append(payload)
        if payload > limit_kg:
            return [_result("pick-and-place", "pick-and-place", ["placing"], placing_error_m=0.02)]
        return [_result("pick-and-place", "pick-and-place")]

    return verify_nominal, calls


def test_a_refusal_by_simulation_names_the_largest_payload_that_verifies(designer, monkeypatch):
    fake, calls = _fails_above(0.12)
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    req = Request(ARM.abilities, params=(*ARM.params, ("payload", "0.2kg")))
    out = run(designer, req, StructureOptions())
    assert out.status == "infeasible"
    msg = out.infeasible
    assert msg.startswith("pick-and-place failed in simulation: placing (placing error 20 mm")
    assert (
        synth.verification.loop.ROBUST_OFF not in msg
    )  # failed on the nominal model: no such design
    # on the grid of the grams shown: 0.1 ok, 0.15 and 0.125 fail, 0.112 ok
    assert msg.endswith("; the largest payload that works here is 0.112 kg")
    assert calls[-1] == pytest.approx(0.112)  # the value named was tested
    # bounded: the request, the floor (0 kg) and HINT_BISECTIONS halvings
    assert (
        len(calls)
        == 1 + 1 + synth.verification.loop.HINT_BISECTIONS
        <= 1 + synth.verification.loop.HINT_ROUNDS
    )
    # the named value designs and verifies
    named = Request(ARM.abilities, params=(*ARM.params, ("payload", "0.112kg")))
    assert run(designer, named, StructureOptions()).status == "designed"


def test_a_refusal_without_a_working_value_names_none(designer, monkeypatch):
    fake, calls = _fails_above(-1.0)  # fails whatever the payload
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    out = run(designer, ARM, StructureOptions())
    assert out.status == "infeasible" and "largest" not in out.infeasible
    assert len(calls) == 2  # the request and the floor: the payload is not the limit


def test_a_skid_steer_is_calibrated_before_it_is_verified(designer):
    """Its probe runs measure the effective track its skidding wheels turn it with; the
    record keeps it, the bundle's trajectories and its controller use it."""
    from export.bundle import trajectory_files
    from gaits import controller_for
    from gaits.base import DesignGeometry

    req = Request(("driving",), params=(("payload", "2kg"),))
    out = run(designer, req, StructureOptions())
    rec = json.loads(out.files(designer)["design.json"])
    cal = rec["calibration"]
    drive = controller_for(DesignGeometry.from_record(rec)).drive
    bare = {k: v for k, v in rec.items() if k != "calibration"}
    model = controller_for(DesignGeometry.from_record(bare)).drive
    assert drive.effective_track == cal["effective_track_m"] > model.effective_track
    assert 0 < cal["turn_load_scale"] == drive.turn_load_scale
    assert all(b["verdict"] == "ok" for b in rec["verified"]["behaviors"])
    turning = out.files(designer)["trajectories/turning.csv"]
    assert turning == trajectory_files(rec)["trajectories/turning.csv"]
    assert turning != trajectory_files(bare)["trajectories/turning.csv"]
    # not simulated: nothing measured
    assert "calibration" not in run(designer, req, StructureOptions(verify=False)).record(designer)


def test_a_dropped_bonus_ability_does_not_skip_the_robust_runs(designer, monkeypatch):
    """A design whose bonus behaviour failed nominally still has its other behaviours run
    under perturbation (a design accepted with no perturbed run was the bug), and one
    that is not robust there refuses the request."""
    import synth.verification.play

    monkeypatch.setattr(synth.verification.loop, "HINT_ROUNDS", 0)
    bad = _result("positioning", "positioning", ["placing"], placing_error_m=0.02)
    ok = _result("pick-and-place", "pick-and-place")
    fake, _ = _fake([[ok, bad]])
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", fake)
    asked = []

    def robust(bundle, k, table, behaviors=None, only=None, sensing=True):
        asked.append(sorted(only or ()))
        passed = 0 if asked_to_fail else k
        fig = {"seed": 1, "verdict": [] if passed else ["placing"], "placing_error_m": 0.02}
        failure = {"seed": 1, "verdict": ["placing"], "why": "placing", "perturbation": "p"}
        return RobustRuns.of(
            {
                "k": k,
                "required": k,
                "behaviors": [
                    {
                        "behavior": "pick-and-place",
                        "ability": "pick-and-place",
                        "passed": passed,
                        "runs": k,
                        "robust": bool(passed),
                        "worst": {},
                        "failures": [] if passed else [failure],
                        "figures": [fig | {"verdict": "ok"}] if passed else [fig],
                    }
                ],
                "table": table,
            }
        )

    monkeypatch.setattr(synth.verification.runs, "verify_robust", robust)
    monkeypatch.setattr(synth.verification.play, "play_blame", lambda bundle, r: [])
    asked_to_fail = False
    out = run(designer, ARM, StructureOptions(robustness=2))
    assert out.infeasible is None
    assert asked == [["pick-and-place"]]  # the nominal failure's behaviour is not run
    rec = out.record(designer)
    assert rec["verified"]["robust"]["behaviors"][0]["passed"] == 2
    assert "positioning" not in rec["abilities"]
    asked.clear()
    asked_to_fail = True  # built to fail: not robust -> the demanded ability refuses it
    out = run(designer, ARM, StructureOptions(robustness=2))
    assert out.infeasible is not None and "pick-and-place is not robust" in out.infeasible
    assert (
        synth.verification.loop.ROBUST_OFF in out.infeasible
    )  # it passed nominally: say how to get it
