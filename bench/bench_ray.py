"""A study of 100 requests on both engines (issue 12): ``parmor sweep`` with simulation, once
on local processes (``--jobs 2``) and once on a throwaway Ray instance on this machine
(``--backend ray --jobs 2``), each as a process; the wall times (Ray's as a ratio to the
local run's) and whether the outputs are byte-identical: ``results.csv``, ``summary.md``,
the plots and every stored request.

The study is the shipped ``studies/parameter-range.toml``'s requests of cheap types (carts,
skid-steers, snakes, 3- and 6-DOF arms), spread evenly to 98, with one request no robot
can meet and one that waits for an answer: a hundred requests in a minute or two on two
cores. Ray is optional (``pip install 'parmor[ray]'``); without it the section says so.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: The shipped parameter study, whose requests of cheap robot types the bench spreads over
#: its 100 requests.
SOURCE = REPO / "studies" / "parameter-range.toml"
#: Robot types left out: the legged ones take seconds each.
COSTLY = ("hexapod", "quadruped", "humanoid")
#: Added to the source's: one request no robot meets, one that waits for an answer.
EXTRA = (
    {"name": "rolling-and-grasping", "abilities": ["rolling", "grasping"]},
    {"name": "walking", "abilities": ["walking"]},
)
N_REQUESTS = 100
JOBS = 2
TIME_LIMIT = 1800  # s per sweep


def study_text() -> str:
    """The bench's study: ``N_REQUESTS`` requests, ``EXTRA`` and the rest spread evenly over
    the source's requests of cheap types (each expanded, one table per request)."""
    import json

    from synth.commands.sweep import load_study

    cheap = [q for q in load_study(SOURCE)[1] if q["name"] not in COSTLY]
    n = N_REQUESTS - len(EXTRA)
    picked = [cheap[i * len(cheap) // n] for i in range(n)]

    def inline(table: dict) -> str:
        return "{" + ", ".join(f"{k} = {json.dumps(v)}" for k, v in table.items()) + "}"

    out = []
    for q in [*picked, *EXTRA]:
        out.append("[[request]]")
        out.append(f"name = {json.dumps(q['name'])}")
        out.append(f"abilities = {json.dumps(q['abilities'])}")
        for key in ("answers", "params"):
            if q.get(key):
                out.append(f"{key} = {inline(q[key])}")
        out.append("")
    return "\n".join(out)


def outputs(folder: Path) -> dict[str, bytes]:
    """Every file a sweep wrote (results.csv, summary.md, plots, stored requests)."""
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _sweep(study: Path, out: Path, *extra: str) -> tuple[float, int, str]:
    """(wall s, exit code, the last line of its errors) of one sweep as a process."""
    env = {
        **os.environ,
        "PYTHONPATH": str(REPO),
        "RAY_AUTH_MODE": "disabled",  # a throwaway instance: no token in the home folder
        "RAY_USAGE_STATS_ENABLED": "0",
    }
    cmd = [sys.executable, "-m", "synth.commands.cli", "sweep", str(study), "--out", str(out)]
    t0 = time.perf_counter()
    try:
        r = subprocess.run(
            [*cmd, "--jobs", str(JOBS), *extra],
            capture_output=True,
            text=True,
            env=env,
            cwd=REPO,
            timeout=TIME_LIMIT,
        )
    except subprocess.TimeoutExpired:
        return float("inf"), -1, f"over {TIME_LIMIT} s"
    last = r.stderr.strip().splitlines()[-1:]
    return time.perf_counter() - t0, r.returncode, last[0] if last else ""


def bench_ray() -> list[str]:
    head = f"A sweep of {N_REQUESTS} requests with simulation, local vs Ray ({JOBS} at once)"
    try:
        import ray  # noqa: F401
    except ImportError:
        return [head, "  ray is not installed (pip install 'parmor[ray]'): skipped"]
    lines = [f"{head}; load {os.getloadavg()[0]:.1f}"]
    with tempfile.TemporaryDirectory() as tmp:
        study = Path(tmp) / "hundred.toml"
        study.write_text(study_text(), encoding="utf-8")
        here, there = Path(tmp) / "local", Path(tmp) / "ray"
        t_local, code_l, err_l = _sweep(study, here)
        t_ray, code_r, err_r = _sweep(study, there, "--backend", "ray")
        if code_l != 0 or code_r != 0:
            return [*lines, f"  MISS a sweep failed: local {code_l} {err_l}, ray {code_r} {err_r}"]
        a, b = outputs(here), outputs(there)
        stored = sum(1 for k in a if k.startswith("requests/"))
        same = a == b
        differ = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
        lines.append(f"  ref  local processes     {t_local:7.1f} s   {stored} requests stored")
        lines.append(f"       Ray (its start too)  {t_ray:7.1f} s   {t_ray / t_local:4.2f} x local")
        csv = a.get("results.csv", b"")
        rows = csv.count(b"\n") - 1
        verdict = "yes" if same else "no: " + ", ".join(differ[:5])
        lines.append(
            f"  {'ok  ' if same and stored == N_REQUESTS else 'MISS'} results.csv "
            f"({len(csv)} bytes, {rows} rows), summary.md, {len(a) - stored - 2} plots and "
            f"every stored request byte-identical: {verdict}"
        )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_ray()))
