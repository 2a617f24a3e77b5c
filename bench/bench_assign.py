"""Actuator assignment against the catalog's size (issue 12): ``parmor design
rough-terrain-walking`` and ``parmor enumerate walking --assignments 5`` as processes, with
synthetic catalogs of 6 (the shipped actuators), 20, 60, 200 and 1000 actuators
(``bench/synthetic_catalog.py``); wall time (best of ``runs``) with its target and as a
ratio to the 6-actuator catalog in the same run (best of three: a shared 2-core machine varies
by +-0.5 s from run to run), and the counts ``enumerate`` prints:
the assignments capable at the sized design's requirements (exact, by combinatorics) and
those of them feasible with their own actuators' masses (``L..U``: bounds, that exact
count not found in budget)."""

from __future__ import annotations

import json
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

SIZES = (6, 20, 60, 200, 1000)
#: Targets (s) at 1000 actuators (issue 12's acceptance)
TARGETS = {"design": 2.0, "enumerate": 5.0}
COMMANDS = {
    "design": ["design", "rough-terrain-walking"],
    "enumerate": ["enumerate", "walking", "--assignments", "5", "--json"],
}
TIME_LIMIT = 300  # s per process


def _run(args: list[str], catalog: Path) -> tuple[float, str]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    cmd = [sys.executable, "-m", "synth.commands.cli", *args, "--catalog", str(catalog)]
    t0 = time.perf_counter()
    try:
        done = subprocess.run(
            cmd, capture_output=True, text=True, env=env, timeout=TIME_LIMIT, cwd=REPO
        )
    except subprocess.TimeoutExpired:
        return float("inf"), ""
    return time.perf_counter() - t0, done.stdout


def _counts(stdout: str) -> str:
    out = []
    for line in stdout.splitlines():
        rec = json.loads(line)
        a = rec.get("assignments")
        if rec.get("type") == "candidate" and a:
            shown = a["count"] if a["count_exact"] else f"{a['count_lower']:.3g}..{a['count']:.3g}"
            out.append(f"{rec['robot_type']} {a['count_capable']} capable, {shown} feasible")
    return ", ".join(out)


def bench_assign(runs: int = 3, sizes: tuple[int, ...] = SIZES) -> list[str]:
    lines = [
        "Actuator assignment vs catalog size (processes; best of "
        f"{runs}; targets at 1000: design {TARGETS['design']:g} s, "
        f"enumerate {TARGETS['enumerate']:g} s; load {os.getloadavg()[0]:.1f})"
    ]
    with tempfile.TemporaryDirectory() as tmp:
        ref: dict[str, float] = {}
        for n in sizes:
            catalog = Path(tmp) / f"catalog{n}.toml"
            write_synthetic_catalog(catalog, n, seed=0)
            for name, args in COMMANDS.items():
                best, out = float("inf"), ""
                for _ in range(runs):
                    t, o = _run(args, catalog)
                    if t < best:
                        best, out = t, o
                ref.setdefault(name, best)
                ok = best <= TARGETS[name] if n == max(sizes) else best < float("inf")
                mark = "ok  " if ok else "MISS"
                extra = f"  counts: {_counts(out)}" if name == "enumerate" and out else ""
                lines.append(
                    f"  {mark} {name:<9} {n:>5} actuators {best:7.2f} s "
                    f"({best / ref[name]:5.2f}x the 6-actuator catalog){extra}"
                )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_assign(runs=int(sys.argv[1]) if sys.argv[1:] else 3)))
