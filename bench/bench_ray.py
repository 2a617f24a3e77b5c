"""A study of 100 requests on both engines (issue 12): ``parmor sweep`` with simulation, once
on local processes (``--jobs 2``) and once on a throwaway Ray instance on this machine
(``--backend ray --jobs 2``), each as a process; the wall times (Ray's as a ratio to the
local run's) and whether the outputs are byte-identical: ``results.csv``, ``summary.md``,
the plots and every stored request.

The study mixes cheap designs (carts, skid-steers, snakes, 3- and 6-DOF arms), one that no
robot can meet and one that waits for an answer: a hundred requests in a few minutes on
two cores. Ray is optional (``pip install 'parmor[ray]'``); without it the section says so.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: 20 + 12 + 12 + 12 + 9 + 20 + 6 + 6 + 2 + 1 = 100 requests once the lists expand
STUDY = """\
[[request]]
name = "differential-drive"
abilities = ["driving"]
[request.params]
payload = ["0.1kg", "0.3kg", "0.5kg", "0.8kg", "1kg"]
speed = ["0.1m/s", "0.2m/s", "0.3m/s", "0.5m/s"]

[[request]]
name = "differential-drive"
abilities = ["driving"]
[request.params]
load_area = ["150cm2", "300cm2", "600cm2"]
slope = ["0deg", "5deg", "10deg", "15deg"]

[[request]]
name = "snake-rolling"
abilities = ["rolling"]
[request.params]
payload = ["0kg", "0.05kg", "0.1kg", "0.2kg"]
deflection = ["0.5mm", "1mm", "2mm"]

[[request]]
name = "snake-sidewinding"
abilities = ["sidewinding"]
[request.params]
payload = ["0kg", "0.05kg", "0.1kg", "0.2kg"]
deflection = ["0.5mm", "1mm", "2mm"]

[[request]]
name = "skid-steer"
abilities = ["driving"]
[request.params]
payload = ["1.5kg", "2kg", "3kg"]
speed = ["0.1m/s", "0.2m/s", "0.3m/s"]

[[request]]
name = "arm-3dof"
abilities = ["pick-and-place"]
[request.params]
object_shape = "cylinder"
reach = ["15cm", "20cm", "25cm", "30cm", "35cm"]
payload = ["0.05kg", "0.1kg", "0.2kg", "0.3kg"]

[[request]]
name = "arm-3dof"
abilities = ["pick-and-place"]
[request.params]
object_shape = "sphere"
reach = ["20cm", "25cm", "30cm"]
deflection = ["0.5mm", "2mm"]

[[request]]
name = "arm-6dof"
abilities = ["pick-and-place"]
[request.params]
object_shape = "box"
reach = ["20cm", "25cm", "30cm"]
deflection = ["0.5mm", "2mm"]

[[request]]
name = "snake-rolling-circular-path"
abilities = ["rolling", "circular-path"]
[request.params]
payload = ["0kg", "0.1kg"]

[[request]]
name = "rolling-and-grasping"
abilities = ["rolling", "grasping"]
"""
N_REQUESTS = 100
JOBS = 2
TIME_LIMIT = 1800  # s per sweep


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
    cmd = [sys.executable, "-m", "synth.cli", "sweep", str(study), "--out", str(out)]
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
        study.write_text(STUDY, encoding="utf-8")
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
