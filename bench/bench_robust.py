"""Robust verification's cost: each base configuration's default design verified on its
nominal model (``synth.verification.runs.verify_nominal``, what ``parmor design`` simulates) and
under K = 8 perturbations (``synth.verification.runs.verify_robust``; the issue's target: at most
2.5 x the nominal verification's time). Wall time and the process's CPU time (all threads) of
each, best of ``runs``; on a machine other processes load, the CPU ratio is the steadier
figure.

Both verifications run their simulations on ``VERIFY_THREADS`` threads, so the robust one
does K x the nominal one's runs on the same cores: its floor is K x the nominal time (8 x
for K = 8), whatever the threads, and each perturbed run costs more than a nominal one by
the play model's factor (a passive hinge per position servo: the robot's degrees of
freedom grow, e.g. a hexapod's 24 -> 42). Printed per type: both ratios, the floor
(K x) and the measured cost of one perturbed run over one nominal run (``per run``:
robust CPU / (K x nominal CPU)), so that a ratio over the target says why."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

#: The issue's budget: robust verification (K = 8) / nominal verification.
TARGET = 2.5


def _timed(fn, runs: int) -> tuple[float, float, object]:
    """(best wall s, best CPU s, last result) of ``runs`` calls."""
    walls, cpus, out = [], [], None
    for _ in range(runs):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return min(walls), min(cpus), out


def bench_robust(k: int = 8, runs: int = 1, only: str | None = None) -> list[str]:
    from bench_sim import default_bundles

    from adron.catalog import load_catalog
    from synth.verification.perturb import design_table
    from synth.verification.runs import physics_check, verify_nominal, verify_robust
    from synth.verification.source import Bundle

    catalog = load_catalog()
    lines = [
        f"Robust verification, K = {k} perturbed runs per behaviour vs the nominal "
        f"verification (target <= {TARGET:g} x; floor {k} x: K x the runs on the same "
        f"threads), best of {runs}"
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for robot_type, _, folder, _, _ in default_bundles(Path(tmp)):
            if only and robot_type != only:
                continue
            files = Bundle.read(folder)
            record, xml, _ = files.record, files.xml, files.meshes
            table = design_table(record, xml, catalog)
            wn, cn, nominal = _timed(lambda f=files: verify_nominal(f), runs)
            # the perturbed runs' step as parmor design chooses it (the check's cost counted)
            wc, cc, check = _timed(lambda f=files, n=nominal: physics_check(f, n), 1)
            if check["timestep_s"]:
                table["timestep_s"] = check["timestep_s"]
            wr, cr, robust = _timed(lambda f=files, t=table: verify_robust(f, k, t), runs)
            wr, cr = wr + wc, cr + cc
            step = (
                f"coarse {check['timestep_s'] * 1000:g} ms: nominal verdicts agree"
                if check["timestep_s"]
                else f"fine step: {check['why']}"
            )
            passed = sum(b.passed for b in robust.behaviors)
            total = sum(b.runs for b in robust.behaviors)
            lines.append(
                f"  {'ok  ' if wr / wn <= TARGET else 'MISS'} {robot_type:<24} nominal "
                f"{wn:6.2f} s, robust {wr:6.2f} s: {wr / wn:5.2f} x wall, {cr / cn:5.2f} x CPU "
                f"(floor {k} x; per run {cr / cn / k:4.2f} x a nominal run; runs passed "
                f"{passed} of {total}; {step})"
            )
            print(lines[-1], flush=True)
    return lines


if __name__ == "__main__":
    args = sys.argv[1:]
    print("\n".join(bench_robust(only=args[0] if args else None)))
