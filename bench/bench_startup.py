"""Start-up of parmor as a process: `--help`, and the default request of each base
configuration (``bench.TYPE_REQUESTS``) designed with and without `--out`, next to the
interpreter alone and `import numpy, clingo`, measured in the same run (best of N after a
warm-up run; the machine is shared, so the load average is printed). Each figure is given
as wall time and as the CPU time (user + sys) of the process and the children it waited
for: parmor's work is sequential, so on an idle machine the two nearly agree, and on a
shared one the CPU time is the steadier figure.

Targets (issue 12): the full design without `--out` under 0.4 s, with `--out` under 1.2 s;
`--help` import-light. The "full design" is read as the issue measured it: sizing with the
behaviours' loads, no simulation (`--no-verify`); with every behaviour simulated (the
default since the verification loop) no start-up work can bring it near 0.4 s
(``simulated=True`` times that too).

The processes run as an installed parmor runs: with compiled bytecode (a
``PYTHONDONTWRITEBYTECODE`` of the calling environment is dropped; the bytecode goes to a
temporary ``PYTHONPYCACHEPREFIX``, not into the repository) and with parmor's caches
(units, the humanoid's gait maps) filled by the warm-up run, in a temporary
``PARMOR_CACHE``.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: The issue's own measurement: the humanoid that grasps.
DESIGN = ["design", "walking", "--answer", "grasping=yes", "--no-input"]


def _env(repo: Path, scratch: Path) -> dict[str, str]:
    """The environment of the timed processes (see the module doc)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(
        PYTHONPATH=str(repo),
        PYTHONPYCACHEPREFIX=str(scratch / "pycache"),
        PARMOR_CACHE=str(scratch / "cache"),
    )
    return env


def _best(cmd: list[str], runs: int, repo: Path, env: dict[str, str]) -> tuple[float, float]:
    """Best wall time and best CPU time (user + sys) s of ``runs`` runs of ``cmd`` (a
    warm-up run first: file caches, bytecode, parmor's caches). The CPU time is what the
    process itself costs: on a shared machine its wall time mostly measures the others."""
    subprocess.run(cmd, cwd=repo, env=env, capture_output=True)
    wall, cpu = [], []
    for _ in range(runs):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=repo, env=env, capture_output=True)
        wall.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr[-300:]!r}")
    return min(wall), min(cpu)


def _type_requests() -> dict[str, list[str]]:
    """``bench.TYPE_REQUESTS`` (from ``bench.py`` when it is the running script)."""
    main = sys.modules.get("__main__")
    if main is not None and hasattr(main, "TYPE_REQUESTS"):
        return dict(main.TYPE_REQUESTS)
    if str(REPO / "bench") not in sys.path:
        sys.path.insert(0, str(REPO / "bench"))
    from bench import TYPE_REQUESTS

    return dict(TYPE_REQUESTS)


def bench_startup(runs: int = 2, repo: Path = REPO, simulated: bool = False) -> list[str]:
    """The start-up figures as lines (``repo``: the checkout to time, e.g. an older one
    for a before/after comparison)."""
    py = sys.executable
    parmor = [py, "-m", "synth.commands.cli"]
    load = os.getloadavg()[0]
    requests = _type_requests()
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        env = _env(repo, scratch)
        out = str(scratch / "b")
        cases: list[tuple[str, list[str], float | None]] = [
            ("python -c pass", [py, "-c", "pass"], None),
            ("import numpy, clingo", [py, "-c", "import numpy, clingo"], None),
            ("parmor --help", [*parmor, "--help"], 0.4),
        ]
        for name, argv in requests.items():
            design = [*parmor, "design", *argv, "--no-input", "--no-verify"]
            cases.append((f"{name} --no-verify", design, 0.4))
            cases.append((f"{name} --no-verify --out", [*design, "--out", out, "--force"], 1.2))
        if simulated:
            cases.append(("HumanoidRobot simulated (default)", [*parmor, *DESIGN], None))
        times = {name: _best(cmd, runs, repo, env) for name, cmd, _ in cases}
    ref, ref_cpu = times["import numpy, clingo"]
    met = sum(1 for name, _, target in cases if target is not None and times[name][0] < target)
    met_cpu = sum(1 for n, _, target in cases if target is not None and times[n][1] < target)
    total = sum(1 for _, _, target in cases if target is not None)
    lines = [
        f"start-up as a process (best of {runs}; load average {load:.2f}; bytecode and "
        f"parmor's caches warm; wall s and x `import numpy, clingo` = {ref:.3f} s, then CPU "
        f"s and x its {ref_cpu:.3f} s); `design` = sizing without simulation (--no-verify): "
        f"{met}/{total} wall targets met, {met_cpu}/{total} in CPU time"
    ]
    for name, _, target in cases:
        t, c = times[name]
        goal = "" if target is None else f"target < {target:g} s ({target / ref:4.1f} x)"
        mark = "    " if target is None else ("ok  " if t < target else "MISS")
        cmark = "    " if target is None else ("ok  " if c < target else "MISS")
        lines.append(
            f"  {mark} {name:<44} {t:6.3f} s {t / ref:5.1f} x | {cmark} cpu {c:6.3f} s "
            f"{c / ref_cpu:5.1f} x  {goal}"
        )
    return lines


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--repo", type=Path, default=REPO, help="checkout to time")
    ap.add_argument("--simulated", action="store_true", help="also the simulated humanoid")
    a = ap.parse_args()
    print("\n".join(bench_startup(a.runs, a.repo.resolve(), a.simulated)))
