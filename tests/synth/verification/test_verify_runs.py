"""The verification's runs (synth/verification/runs.py: nominal_runs): behaviours with the same
plan are simulated once, the others on threads, and the figures are those of one run each, in
name order."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from gaits.base import BehaviorSpec, Trajectory
from synth.verification import runs as verify
from synth.verification.simulate import SimResult


def _traj(name: str, scale: float = 1.0) -> Trajectory:
    t = np.linspace(0.0, 1.0, 11)
    q = scale * np.column_stack([t, -t])
    info = {"motion": "straight", "planned_pose": (scale, 0.0, 0.0), "margin": np.ones(3)}
    return Trajectory(name, t, ("a", "b"), q, np.gradient(q, t, axis=0), info)


class _Controller:
    """Three behaviours: walking and running plan alike, turning does not."""

    plans = {
        "walking": _traj("walking"),
        "running": _traj("running"),
        "turning": _traj("turning", 2),
    }
    behaviors = {n: BehaviorSpec(n, "") for n in plans}
    template = SimpleNamespace(end_effectors=(), feet=("f",), wheels=())

    def listed(self, abilities):
        return sorted(self.plans)

    def run(self, name):
        return self.plans[name]


@pytest.mark.parametrize("threads", [1, 2])
def test_alike_plans_are_simulated_once_and_the_figures_keep_their_names(
    monkeypatch, threads
) -> None:
    seen: list[str] = []

    def fake(model, controller, traj, seconds=None, progress=None):
        seen.append(traj.behavior)
        d = float(traj.positions[-1, 0])
        return SimResult(traj.behavior, 1.0, d, 0.0, False, None, 0.1)

    monkeypatch.setattr(verify, "controller_for_model", lambda record, model: _Controller())
    monkeypatch.setattr(verify, "_simulate", fake)
    monkeypatch.setattr(verify, "VERIFY_THREADS", threads)
    out = verify.nominal_runs({"abilities": []}, model=None)
    assert [r.behavior for r in out] == ["running", "turning", "walking"]
    assert sorted(seen) == ["running", "turning"]  # walking planned as running: not run again
    assert [r.figures["distance_m"] for r in out] == [1.0, 2.0, 1.0]


def test_a_plan_differing_in_its_promise_only_is_simulated_again() -> None:
    a, b = _traj("x"), _traj("y")
    assert verify._plan_digest(a) == verify._plan_digest(b)  # the name is not the plan
    c = Trajectory("x", a.times, a.joints, a.positions, a.velocities, {**a.info, "speed": 1})
    assert verify._plan_digest(c) != verify._plan_digest(a)
    d = Trajectory("x", a.times, a.joints, a.positions + 1e-12, a.velocities, a.info)
    assert verify._plan_digest(d) != verify._plan_digest(a)
