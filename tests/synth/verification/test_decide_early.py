"""Deciding early (synth/verification): a run stops as soon as its verdict is known to fail
when its failure is all that is asked of it, and runs that can only refuse a design stop
at the first that fails, the worst-looking perturbations first. A run that passes, and a
set of runs that all pass, are the same to the bit either way: an accepted design's record
does not change.

Cases built on the 3-joint test arm of tests/synth/verification/test_perturb.py: play of
5-6 deg breaks every
run, a closed table breaks none, a battery at a third of the servos' voltage saturates them.
"""

from __future__ import annotations

import json
import math

import pytest

from synth.verification.perturb import draw, severity, worst_first
from synth.verification.runs import Perturbed, verify_robust
from tests.synth.verification.test_perturb import NEUTRAL, REQUEST, arm, kif, parts, table_of, with_  # noqa: F401

LOOSE = {"plastic": ["5 deg", "6 deg"], "metal": ["5 deg", "6 deg"]}
NAMES = ["pick-and-place", "positioning"]


def test_a_run_stops_once_it_has_failed_and_one_that_passes_does_not(parts) -> None:  # noqa: F811
    """At a third of the servos' voltage the arm saturates: stopped, it ends well before its
    plan with the same failed verdict (judged on saturation, ``complete`` false); on the
    closed table the run passes and is the same to the bit with or without the stop."""
    bundle = parts[0]
    weak = table_of(parts, with_(battery={"supply": "direct", "rated_voltage": "30 V"}))
    plan = bundle.controller().run("pick-and-place")
    full = Perturbed(bundle, weak, 1).run(plan)
    stopped = Perturbed(bundle, weak, 1).run(plan, stop_on_failure=True)
    assert "saturated" in full.verdict and stopped.verdict == ["saturated"]
    assert stopped.figures["complete"] is False
    assert stopped.figures["seconds"] < full.figures["seconds"] / 2
    assert stopped.figures["saturated_fraction"] > 0.05
    neutral = table_of(parts, NEUTRAL)
    ok = Perturbed(bundle, neutral, 1).run(plan)
    assert ok.ok and Perturbed(bundle, neutral, 1).run(plan, stop_on_failure=True) == ok


def test_runs_that_can_only_refuse_stop_at_the_first_failure(parts) -> None:  # noqa: F811
    """With ``decisive`` the runs go a batch at a time, the worst-looking first, and stop
    once a decisive behaviour cannot pass: only it is listed, with the runs made."""
    bundle = parts[0]
    table = table_of(parts, with_(gears=LOOSE))
    full = verify_robust(bundle, 4, table, NAMES)
    assert all(not b.robust for b in full.behaviors)  # built to fail: every run
    early = verify_robust(bundle, 4, table, NAMES, decisive={"positioning"})
    assert [b.behavior for b in early.behaviors] == ["positioning"]
    (b,) = early.behaviors
    assert 1 <= b.runs < 4 and b.passed == 0 and not b.robust
    assert early.stopped["decided"] == ["positioning"]
    assert early.stopped["order"] == worst_first(table, [1, 2, 3, 4])
    made = {r.seed for r in b.figures}
    assert made == set(early.stopped["order"][: b.runs])  # the worst-looking ones
    why = b.why_not(early.required, early.k)
    assert f"passed 0 of the {b.runs} perturbed runs made before it could not pass" in why
    assert "stopped" in early.to_dict() and "stopped" not in full.to_dict()


def test_runs_that_all_pass_are_the_same_decided_early_or_not(parts) -> None:  # noqa: F811
    bundle = parts[0]
    table = table_of(parts, NEUTRAL)
    full = verify_robust(bundle, 2, table, NAMES)
    early = verify_robust(bundle, 2, table, NAMES, decisive=set(NAMES))
    assert early.to_dict() == full.to_dict() and early.stopped is None


def test_the_worst_looking_perturbations_go_first(parts) -> None:  # noqa: F811
    """``severity`` puts each draw where it lies in its range, adverse end 1: the corner
    of every range's adverse end scores 1, the benign corner 0, and seeds sort by it."""
    _, record, xml, _ = parts
    table = json.loads(json.dumps(table_of(parts, with_(gears=LOOSE))))
    table |= {"friction": [0.6, 1.2], "max_slope_rad": math.radians(3), "mass_spread": 0.1}
    table |= {"latency_s": [0.01, 0.04]}
    p = draw(table, 1)
    servos = table["servos"]
    adverse = dict(p, friction_scale=0.6, slope_rad=math.radians(3), latency_s=0.04)
    adverse["mass_scale"] = {b: 1.1 for b in p["mass_scale"]}
    adverse["play_rad"] = {j: s["backlash_rad"][1] + s["deadband_rad"] for j, s in servos.items()}
    benign = dict(p, friction_scale=1.2, slope_rad=0.0, latency_s=0.01)
    benign["mass_scale"] = {b: 0.9 for b in p["mass_scale"]}
    benign["play_rad"] = {j: s["backlash_rad"][0] + s["deadband_rad"] for j, s in servos.items()}
    assert severity(table, adverse) == pytest.approx(1.0)
    assert severity(table, benign) == pytest.approx(0.0)
    seeds = list(range(1, 9))
    order = worst_first(table, seeds)
    scores = [severity(table, draw(table, s)) for s in order]
    assert sorted(order) == seeds and scores == sorted(scores, reverse=True)


def test_the_loop_stops_the_runs_of_a_request_refused_nominally(designer, monkeypatch) -> None:
    """A demanded behaviour failed on the nominal model: the request is refused whatever
    the perturbed runs of the others give, so they are asked to stop at the first failure;
    a bonus behaviour's nominal failure refuses nothing, and its runs are all made."""
    import synth.verification.loop
    import synth.verification.runs
    from synth.pipeline import StructureOptions, run
    from synth.reasoning.conceptual import Request
    from synth.verification.results import RobustRuns, Run

    monkeypatch.setattr(synth.verification.loop, "HINT_ROUNDS", 0)
    request = Request(abilities=("pick-and-place",), params=(("object_shape", "cylinder"),))
    asked: list = []

    def nominal(failing: str):
        def verify_nominal(bundle, behaviors=None):
            names = ["pick-and-place", "positioning"]
            return [
                Run.of(
                    {"behavior": n, "ability": n, "verdict": ["placing"] if n == failing else "ok"}
                )
                for n in names
            ]

        return verify_nominal

    def robust(bundle, k, table, behaviors=None, only=None, sensing=True, decisive=None):
        asked.append(decisive)
        return RobustRuns.of({"k": k, "behaviors": [], "table": table})

    monkeypatch.setattr(synth.verification.runs, "verify_robust", robust)
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", nominal("pick-and-place"))
    out = run(designer, request, StructureOptions(robustness=2))
    assert out.status == "infeasible" and asked[-1] == {"positioning"}
    asked.clear()
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", nominal("positioning"))
    run(designer, request, StructureOptions(robustness=2))
    assert asked and asked[-1] is None
