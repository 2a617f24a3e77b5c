"""Start-up of parmor as a process: `--help`, and `design walking --answer grasping=yes` with
and without `--out`, next to the interpreter alone and `import numpy, clingo`, measured in
the same run (best of N wall times; the machine is shared, so the load average is printed).

Targets (issue 12): the full design without `--out` under 0.4 s, with `--out` under 1.2 s;
`--help` import-light. The "full design" is timed twice: as the issue measured it (sizing,
no simulation: `--no-verify`) and with every behaviour simulated (the default since the
verification loop), which no start-up work can bring near 0.4 s.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DESIGN = ["design", "walking", "--answer", "grasping=yes", "--no-input"]


def _best(cmd: list[str], runs: int) -> float:
    """Best wall time (s) of ``runs`` runs of ``cmd`` (a warm-up run first: file caches,
    parmor's unit cache)."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    subprocess.run(cmd, cwd=REPO, env=env, capture_output=True)
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True)
        times.append(time.perf_counter() - t0)
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr[-300:]!r}")
    return min(times)


def bench_startup(runs: int = 3) -> list[str]:
    py = sys.executable
    parmor = [py, "-m", "synth.cli"]
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "b")
        cases: list[tuple[str, list[str], float | None]] = [
            ("python -c pass", [py, "-c", "pass"], None),
            ("import numpy, clingo", [py, "-c", "import numpy, clingo"], None),
            ("parmor --help", [*parmor, "--help"], 0.4),
            ("design (sizing, --no-verify)", [*parmor, *DESIGN, "--no-verify"], 0.4),
            (
                "design --out (sizing, --no-verify)",
                [*parmor, *DESIGN, "--no-verify", "--out", out, "--force"],
                1.2,
            ),
            ("design (simulated, the default)", [*parmor, *DESIGN], None),
        ]
        times = {name: _best(cmd, runs) for name, cmd, _ in cases}
    ref = times["import numpy, clingo"]
    lines = [
        f"start-up as a process (best of {runs}; load average {load:.2f}; "
        f"ratios to `import numpy, clingo` = {ref:.3f} s)"
    ]
    for name, _, target in cases:
        t = times[name]
        goal = "" if target is None else f"target < {target:g} s"
        mark = "    " if target is None else ("ok  " if t < target else "MISS")
        lines.append(f"  {mark} {name:<36} {t:6.3f} s  {t / ref:5.1f} x  {goal}")
    return lines


if __name__ == "__main__":
    print("\n".join(bench_startup()))
