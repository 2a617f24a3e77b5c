"""Sizing with the behaviours' loads and the verification's simulations (issue 12): the
hexapod's ``parmor design rough-terrain-walking`` with the shipped catalog and a synthetic
one of 1000 actuators (``bench/synthetic_catalog.py``) and the quadruped's ``design walking``
without simulation (start-up), as processes, each as wall time (best of ``runs``) and as a
ratio to ``import numpy, clingo`` in the same run; then, in process on the 1000-actuator
hexapod, the sizing (its behaviours planned from nothing) and the verification run as
``parmor design`` runs it (plans simulated once each, on threads) against the same
simulations one after another; last, the 3-DOF arm's and the hexapod's structure loop with
their chains' links sized together (the separable solve, and the convex program) as a
ratio to each link on its own (issue 20)."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from synthetic_catalog import write_synthetic_catalog  # noqa: E402

#: Targets, s (issue 12): the 1000-actuator design, the design without simulation.
TARGET_DESIGN = 2.0
TARGET_STARTUP = 0.4
QUADRUPED = ["walking", "--answer", "grasping=no", "--answer", "rough-terrain-walking=no"]


def _best(cmd: list[str], runs: int) -> float:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    subprocess.run(cmd, cwd=REPO, env=env, capture_output=True)  # warm-up: caches, bytecode
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True)
        best = min(best, time.perf_counter() - t0)
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr[-300:]!r}")
    return best


def _forget_plans() -> None:
    """Empty the in-process memos of plans, so that a sizing plans from nothing."""
    from gaits import base, hexapod, legged
    from synth.sizing import behaviour_loads

    for memo in (
        base._PLANNED,
        hexapod._STRIDES,
        hexapod._TIMINGS,
        legged._PLANS,
        behaviour_loads._TRAJECTORIES,
    ):
        memo.clear()


def _in_process(catalog: Path, runs: int) -> list[str]:
    from adron.catalog import load_catalog
    from adron.kb import load
    from export.bundle import bundle_files
    from export.record import design_record
    from synth.reasoning.conceptual import Design, Designer, Request
    from synth.reasoning.solver import Query, Reasoner
    from synth.sizing.structure import design_structure
    from synth.verification import runs as verify
    from synth.verification.source import Bundle

    kb = load()
    designer = Designer(kb, Reasoner(kb))
    cat = load_catalog(str(catalog))
    cand = next(
        c for c in designer.reasoner.solve(Query()).candidates if c.robot_type == "HexapodRobot"
    )
    design_structure(kb, cand, cat, {})  # warm-up: imports
    sizing = float("inf")
    for _ in range(runs):
        _forget_plans()
        t0 = time.perf_counter()
        s = design_structure(kb, cand, cat, {})
        sizing = min(sizing, time.perf_counter() - t0)
    rec = design_record(
        Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
    )
    files = bundle_files(rec, s, cat, pictures=False)
    verify.verify_nominal(Bundle(files))  # warm-up: the model compiled once, the plans made
    timings = {}
    for threads in (verify.VERIFY_THREADS, 1):
        best = float("inf")
        for _ in range(runs):
            old, verify.VERIFY_THREADS = verify.VERIFY_THREADS, threads
            try:
                t0 = time.perf_counter()
                if threads == 1:  # the old way: every behaviour simulated, one by one
                    m = Bundle(files).model()
                    c = verify.controller_for_model(rec, m)
                    for n in c.listed(rec["abilities"]):
                        verify.run_behavior(m, c, n)
                else:
                    verify.verify_nominal(Bundle(files))
                best = min(best, time.perf_counter() - t0)
            finally:
                verify.VERIFY_THREADS = old
        timings[threads] = best
    fast, slow = timings[verify.VERIFY_THREADS], timings[1]
    return [
        f"       in process, 1000 actuators: sizing (plans made from nothing) {sizing:6.2f} s",
        f"       verification {fast:6.2f} s ({verify.VERIFY_THREADS} threads, alike plans once)"
        f" = {fast / slow:4.2f} x every behaviour simulated one by one ({slow:.2f} s)",
    ]


def _chain_sizing(runs: int) -> list[str]:
    """The structure loop with a serial chain's links sized together (``chain_tubes``: the
    separable solve, no cvxpy) and with the same chains through the convex program
    (cvxpy + Clarabel, ``method="program"``, after a warm-up: cvxpy imported, the program
    compiled; that first-use cost is the subprocess line), each as a ratio to each link
    on its own (the closed form they replaced), for the 3-DOF arm and the hexapod."""
    from functools import partial

    import synth.sizing.structure as structure
    from adron.catalog import load_catalog
    from adron.kb import load
    from synth.reasoning.conceptual import Designer
    from synth.reasoning.solver import Query, Reasoner
    from synth.sizing.chain_links import chain_tubes
    from synth.sizing.structure import StructureDesigner

    def per_link(self, lengths, loads, counts, analysis):
        return {n: self._size_link(n, lengths[n], loads[n]) for n in lengths}

    kb = load()
    cat = load_catalog()
    cands = {c.robot_type: c for c in Designer(kb, Reasoner(kb)).reasoner.solve(Query()).candidates}
    py = sys.executable
    first = _best([py, "-c", "import cvxpy"], runs) - _best([py, "-c", "import numpy"], runs)
    lines = [
        f"  chain sizing (best of {runs}; importing cvxpy, for chains that share a link "
        f"only: {first:.2f} s)"
    ]
    wired = StructureDesigner._size_links
    ways = (
        ("separable", wired, chain_tubes),
        ("program", wired, partial(chain_tubes, method="program")),
        ("per link", per_link, chain_tubes),
    )
    for t in ("Manipulator3DOF", "HexapodRobot"):
        out = {}
        for how, fn, solve in ways:
            StructureDesigner._size_links, structure.chain_tubes = fn, solve
            try:
                best, mass = float("inf"), 0.0
                for i in range(runs + 1):  # the first a warm-up
                    t0 = time.perf_counter()
                    s = StructureDesigner(kb, cands[t], cat, {}).run()
                    if i:
                        best = min(best, time.perf_counter() - t0)
                    mass = sum(link.count * link.mass_kg for link in s.links)
            finally:
                StructureDesigner._size_links, structure.chain_tubes = wired, chain_tubes
            out[how] = (best, mass)
        (ts, ms), (tc, _), (tp, mp) = out["separable"], out["program"], out["per link"]
        lines.append(
            f"       {t:<16} {ts * 1000:7.1f} ms = {ts / tp:4.2f} x per link ({tp * 1000:.1f} ms;"
            f" program {tc * 1000:.1f} ms = {tc / tp:4.2f} x); printed links {ms * 1000:.2f} g"
            f" vs {mp * 1000:.2f} g"
        )
    return lines


def bench_sizing(runs: int = 3) -> list[str]:
    py = sys.executable
    parmor = [py, "-m", "synth.commands.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "catalog1000.toml"
        write_synthetic_catalog(big, 1000, seed=0)
        ref = _best([py, "-c", "import numpy, clingo"], runs)
        cases = [
            ("design rough-terrain-walking", [*parmor, "design", "rough-terrain-walking"], None),
            (
                "  the same, 1000 actuators",
                [*parmor, "design", "rough-terrain-walking", "--catalog", str(big)],
                TARGET_DESIGN,
            ),
            (
                "design walking (quadruped) --no-verify",
                [*parmor, "design", *QUADRUPED, "--no-verify"],
                TARGET_STARTUP,
            ),
        ]
        lines = [
            f"Sizing and verification (best of {runs}; load {os.getloadavg()[0]:.1f}; "
            f"x `import numpy, clingo` = {ref:.3f} s)"
        ]
        for name, cmd, target in cases:
            t = _best([*cmd, "--no-input"], runs)
            mark = "    " if target is None else ("ok  " if t < target else "MISS")
            goal = "" if target is None else f"  target < {target:g} s"
            lines.append(f"  {mark} {name:<40} {t:6.2f} s {t / ref:6.1f} x{goal}")
        lines += _in_process(big, runs)
    lines += _chain_sizing(runs)
    return lines


if __name__ == "__main__":
    print("\n".join(bench_sizing(int(sys.argv[1]) if sys.argv[1:] else 3)))
