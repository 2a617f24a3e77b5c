"""Benchmark of the link sizing: closed form (KKT) against the SLSQP cross-check.

Usage: ``python bench/bench_links.py [N]`` (default N = 400 random cases, a quarter per
branch). ``bench_links`` returns the report lines for ``bench/bench.py``, and so does
``bench_chain_links``: a serial chain's links sized one by one (even shares of the tip
deflection budget) against ``synth.sizing.chain_links``' joint sizing, its separable solve and
its convex program (cvxpy + Clarabel).

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

from synth.sizing.links import Tube, TubeLimits, optimal_tube, optimal_tube_numeric  # noqa: E402

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


CHAIN_E, CHAIN_ALLOWED, CHAIN_KT = 2.3e9, 20e6, 1.8  # the shipped catalog: PLA, 40 MPa / 2


def chain_cases(n: int, seed: int = SEED) -> list[tuple[list, list]]:
    """``n`` seeded serial chains of 2-6 links for ``chain_links``: the shipped catalog's
    section (r2max 20 mm, wall 1.2 mm, PLA, Kt 1.8), lengths 40-300 mm, 1-3 random loads a
    link (none overstressed in its strongest tube) and a budget the per-link sizing can
    meet (1.05-30 times n x the largest share of a stiffest tube)."""
    from synth.sizing.chain_links import Chain, ChainLink, deflection_coefficient, stress_floor

    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        links: list = []
        size = int(rng.integers(2, 7))
        while len(links) < size:
            length = rng.uniform(0.04, 0.3)
            force, moment = 10 ** rng.uniform(-1.0, 1.3), 10 ** rng.uniform(-2.0, 0.3)
            loads = tuple(
                np.concatenate([rng.normal(size=3) * force, rng.normal(size=3) * moment])
                for _ in range(rng.integers(1, 4))
            )
            link = ChainLink(f"L{len(links) + 1}", TubeLimits(0.02, 0.0012, length, length), loads)
            try:
                stress_floor(link, CHAIN_ALLOWED, CHAIN_KT)
            except Exception:  # overstressed whatever its tube: draw another
                continue
            links.append(link)
        lengths = [lk.length for lk in links]
        best = max(
            max(
                deflection_coefficient(ld, lk.length, sum(lengths[i + 1 :]), CHAIN_E)
                for ld in lk.loads
            )
            / (np.pi / 4.0 * 0.02**4)
            for i, lk in enumerate(links)
        )
        budget = size * best * 10 ** rng.uniform(0.02, 1.5)
        out.append((links, [Chain(tuple(lk.name for lk in links), budget)]))
    return out


def bench_chain_links(n: int = 100) -> list[str]:
    """Time a chain for per-link sizing (even shares of the tip budget, then stress), the
    separable solve (what ``chain_tubes`` does for chains that share no link: exact, no
    cvxpy) and the convex program (cvxpy + Clarabel, polished: what chains that share a
    link get), best of 3 over ``n`` seeded chains, each as a ratio to per-link; their
    largest disagreement, and the joint sizing's saving; the program's first call
    (cvxpy's import, compiling) apart."""
    from functools import partial

    work = chain_cases(n)
    from synth.sizing.chain_links import chain_tubes, per_link_tubes

    t0 = time.perf_counter()
    chain_tubes(*work[0], CHAIN_E, CHAIN_ALLOWED, CHAIN_KT, method="program")
    cold = time.perf_counter() - t0
    for links, chains in work:  # compile every shape once (2-6 links) before timing
        chain_tubes(links, chains, CHAIN_E, CHAIN_ALLOWED, CHAIN_KT, method="program")
    how = {
        "per-link": per_link_tubes,
        "separable": partial(chain_tubes, method="separable"),
        "program": partial(chain_tubes, method="program"),
    }
    best, got = {}, {}
    for name, fn in how.items():
        best[name] = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            got[name] = [fn(lk, ch, CHAIN_E, CHAIN_ALLOWED, CHAIN_KT) for lk, ch in work]
            best[name] = min(best[name], time.perf_counter() - t0)
    alone, fast, program = got["per-link"], got["separable"], got["program"]
    saving = [1.0 - j.volume_m3 / a.volume_m3 for j, a in zip(fast, alone, strict=True)]
    gap = max(
        max(abs(f.tubes[k].area / p.tubes[k].area - 1.0) for k in f.tubes)
        for f, p in zip(fast, program, strict=True)
    )
    its = [j.iterations for j in program]
    steps = [j.iterations for j in fast]
    per, sep, cvx = (best[k] / n * 1e3 for k in ("per-link", "separable", "program"))
    return [
        f"chain link sizing, {n} random chains of 2-6 links (seed {SEED})",
        f"  per-link (even shares)   {per:8.2f} ms a chain",
        f"  separable (no cvxpy)     {sep:8.2f} ms a chain  ({sep / per:.1f}x per-link; "
        f"{min(steps)}-{max(steps)} multiplier steps, mean {np.mean(steps):.1f})",
        f"  program (Clarabel)       {cvx:8.2f} ms a chain  ({cvx / per:.1f}x per-link; "
        f"{min(its)}-{max(its)} solves, mean {np.mean(its):.1f}); first call {cold:.2f} s "
        "(cvxpy import, compile)",
        f"  separable vs program: areas agree to {gap:.1e}; volume saved by sizing a chain "
        f"together: mean {np.mean(saving):.1%}, max {max(saving):.1%}, min {min(saving):.1e}",
    ]


def main(argv: list[str]) -> int:
    """Print the benchmark lines (``argv[1]``: number of cases)."""
    n = int(argv[1]) if len(argv) > 1 else 400
    for line in bench_links(n):
        print(line)
    for line in bench_chain_links():
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
