"""Benchmark of the batched RNEA (kinematics.dynamics.rnea) against pinocchio.

Usage: ``python bench/bench_rnea.py [N]`` (default N = 10,000 configurations).
``bench_rnea`` returns the report lines for ``bench/bench.py``.

Fairness: both sides get the same model (the template converted by ``tests/pin_ref.py``)
and the same random configurations, velocities and accelerations, already in memory as
float64 arrays in each side's own layout (pinocchio's q also holds the locked fixed joints).
Ours is one call on the (N, nv) batch; pinocchio is ``pinocchio.rnea`` called once per
configuration from a Python loop, which is how Python code uses it. Best of 5 runs each.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import synth.reasoning.plans  # noqa: E402 (the shipped types' body plans, found by name below)
from kinematics.dynamics import rnea  # noqa: E402
from kinematics.templates import build  # noqa: E402

synth.reasoning.plans.install()

RUNS = 5
TYPES = ("HexapodRobot", "HumanoidRobot")


def best_of(fn: Callable[[], object], runs: int = RUNS) -> float:
    """Best wall time in seconds over ``runs`` calls."""
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_rnea(n: int = 10_000, seed: int = 0) -> list[str]:
    """Per-configuration RNEA time, ours batched vs pinocchio per call, and the largest
    torque difference, for the Hexapod and Humanoid templates."""
    lines = [f"RNEA over {n} random configurations (best of {RUNS}; target: ours <= pinocchio)"]
    try:
        import pinocchio as pin

        from tests.pin_ref import PinRef
    except ImportError as e:
        return [*lines, f"  pinocchio not importable ({e}): comparison skipped"]
    rng = np.random.default_rng(seed)
    for robot_type in TYPES:
        model = build(robot_type).model
        ref = PinRef(model)
        q, v, a = (rng.uniform(-np.pi, np.pi, (n, model.nv)) for _ in range(3))
        pq, pv, pa = (np.array([ref.expand(x) for x in arr]) for arr in (q, v, a))
        pm, pd, cols = ref.pin_model, ref.data, ref.cols

        def theirs(pq=pq, pv=pv, pa=pa, pm=pm, pd=pd) -> None:
            for i in range(n):
                pin.rnea(pm, pd, pq[i], pv[i], pa[i])

        def ours(model=model, q=q, v=v, a=a) -> None:
            rnea(model, q, v, a)

        t_ours, t_pin = best_of(ours), best_of(theirs)
        tau = rnea(model, q, v, a)
        check = np.array([pin.rnea(pm, pd, pq[i], pv[i], pa[i])[cols] for i in range(n)])
        diff = float(np.abs(tau - check).max())
        us_ours, us_pin = t_ours / n * 1e6, t_pin / n * 1e6
        ok = "ok  " if us_ours <= us_pin and diff < 1e-9 else "MISS"
        lines.append(
            f"  {ok} {robot_type:<14} nv={model.nv:2d}  ours {us_ours:5.2f} us/config  "
            f"pinocchio {us_pin:5.2f} us/config  ratio {us_ours / us_pin:4.2f}  "
            f"max |dtau| {diff:.1e} N m"
        )
    return lines


def main(argv: list[str]) -> int:
    """Print the benchmark lines."""
    n = int(argv[1]) if len(argv) > 1 else 10_000
    for line in bench_rnea(n):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
