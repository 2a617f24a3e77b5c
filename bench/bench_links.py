"""Benchmark of the link sizing: closed form (KKT) against the SLSQP cross-check.

Usage: ``python bench/bench_links.py [N]`` (default N = 400 random cases, a quarter per
branch). ``bench_links`` returns the report lines for ``bench/bench.py``.

Both solvers get the same seeded cases. Throughput is calls per second over the whole
set, best of 3 runs for the closed form and one run for SLSQP (it is ~1000x slower).
The disagreement is the largest relative difference in volume, r_outer, length, and
r_inner (relative to r_outer, since r_inner is 0 in two branches).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from synth.links import Tube, TubeLimits, optimal_tube, optimal_tube_numeric  # noqa: E402

BRANCHES = ("minimum", "solid", "wall", "stiffness")
SEED = 2024


def cases(n: int, seed: int = SEED) -> list[tuple[float, TubeLimits]]:
    """``n`` seeded (K0, limits) pairs, spread over the four branches in turn."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        big_r = rng.uniform(2e-3, 40e-3)
        e = big_r * rng.uniform(0.02, 0.98)
        lmin = rng.uniform(0.02, 0.5)
        limits = TubeLimits(big_r, e, lmin, lmin * rng.uniform(1.0, 5.0))
        branch = BRANCHES[i % 4]
        if branch == "minimum":
            c = 0.0
        elif branch == "solid":
            c = e**4 * 10 ** rng.uniform(-6.0, -0.001)
        else:
            edge = big_r**4 - (big_r - e) ** 4
            lo, hi = (e**4, edge) if branch == "wall" else (edge, big_r**4)
            c = lo + (hi - lo) * rng.uniform(0.001, 0.999)
        out.append((c / lmin**3, limits))
    return out


def disagreement(a: Tube, b: Tube) -> float:
    """Largest relative difference between two tubes (r_inner relative to r_outer)."""
    return max(
        abs(a.volume - b.volume) / a.volume,
        abs(a.r_outer - b.r_outer) / a.r_outer,
        abs(a.r_inner - b.r_inner) / a.r_outer,
        abs(a.length - b.length) / a.length,
    )


def bench_links(n: int = 400) -> list[str]:
    """Calls/s of optimal_tube vs optimal_tube_numeric on ``n`` cases, and their agreement."""
    work = cases(n)
    closed_best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        closed = [optimal_tube(k0, lim) for k0, lim in work]
        closed_best = min(closed_best, time.perf_counter() - t0)
    t0 = time.perf_counter()
    numeric = [optimal_tube_numeric(k0, lim) for k0, lim in work]
    numeric_time = time.perf_counter() - t0
    errs = [disagreement(a, b) for a, b in zip(closed, numeric, strict=True)]
    per_branch = {b: 0.0 for b in BRANCHES}
    for a, err in zip(closed, errs, strict=True):
        per_branch[a.active] = max(per_branch[a.active], err)
    labels = sum(a.active == b.active for a, b in zip(closed, numeric, strict=True))
    return [
        f"link sizing, {n} random cases (seed {SEED}, {n // 4} per branch)",
        f"  closed form (KKT)   {n / closed_best:12.0f} calls/s  ({closed_best / n * 1e6:.2f} us)",
        f"  numeric (SLSQP)     {n / numeric_time:12.0f} calls/s  ({numeric_time / n * 1e3:.2f} ms)"
        f"  -> closed form is {numeric_time / closed_best:.0f}x as fast",
        f"  max relative disagreement {max(errs):.2e}; by branch: "
        + ", ".join(f"{b} {per_branch[b]:.1e}" for b in BRANCHES),
        f"  same branch label in {labels}/{n} cases",
    ]


def main(argv: list[str]) -> int:
    """Print the benchmark lines (``argv[1]``: number of cases)."""
    n = int(argv[1]) if len(argv) > 1 else 400
    for line in bench_links(n):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
