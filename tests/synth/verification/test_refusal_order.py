"""A refusal for robustness names the worst behaviour first (the smallest share of its
perturbed runs passed), not the alphabetically first, and the other demanded ones after."""

from __future__ import annotations

from synth.verification.results import RobustRuns


def _b(name: str, passed: int, runs: int = 8) -> dict:
    return {
        "behavior": name,
        "ability": name,
        "robust": passed == runs,
        "passed": passed,
        "runs": runs,
        "failures": [
            {"seed": s, "verdict": ["pose"], "perturbation": f"seed {s}", "why": "pose off"}
            for s in range(1, runs - passed + 1)
        ],
    }


def _robust(*behaviors: dict) -> RobustRuns:
    return RobustRuns.of({"k": 8, "required": 8, "behaviors": list(behaviors)})


def test_worst_behaviour_first() -> None:
    robust = _robust(_b("driving", 7), _b("turning", 2), _b("zig", 5))
    order = [b.ability for b in robust.not_robust()]
    # name order would be driving, turning, zig: built to fail on it
    assert order == ["turning", "zig", "driving"]
    worst = robust.not_robust()[0]
    assert worst.why_not(robust.required).startswith("turning is not robust: passed 2 of 8")


def test_ties_in_name_order_and_robust_ones_left_out() -> None:
    robust = _robust(_b("b", 4), _b("a", 4), _b("ok", 8))
    assert [b.ability for b in robust.not_robust()] == ["a", "b"]
