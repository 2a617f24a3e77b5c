"""What ``simulate`` adds to MuJoCo's own stepping, and how fast ``parmor simulate`` starts.

For each base configuration's default design and one of its behaviours:

- reference: a plain loop of ``mujoco.mj_step`` over the same model, the same duration and
  the same controls (the trajectory resampled at every step, set before each step, from the
  trajectory's first pose): the least Python can do to run this simulation;
- ``simulate``: the same run in-process (references precomputed, stepped inside MuJoCo by
  ``mujoco.rollout``, measured and judged after the run); target at most
  ``TARGET_RATIO`` x the reference;
- ``parmor simulate DIR --behavior X --seconds S`` as a process, less the simulation's
  share (the in-process ``simulate`` time): imports, loading the bundle, planning and the
  output; target under ``TARGET_STARTUP_S``.

Best of ``RUNS`` each (the machine is shared); the load average is printed.
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

TARGET_RATIO = 1.2  # simulate / raw mj_step loop
TARGET_STARTUP_S = 1.0  # parmor simulate as a process, the simulation excluded
RUNS = 7
SECONDS = 5.0  # simulated per run


def _raw_loop(model, traj, seconds: float) -> float:
    """Wall time (s) of a plain mj_step loop running ``traj`` on ``model``."""
    import mujoco
    import numpy as np

    data = mujoco.MjData(model)
    act = {model.actuator(k).name: k for k in range(model.nu)}
    dt = model.opt.timestep
    steps = max(1, int(round(seconds / dt)))
    grid = np.arange(steps) * dt
    ctrl = np.zeros((steps, model.nu))
    for k, name in enumerate(traj.joints):
        a = act[name]
        velocity = model.actuator_biasprm[a, 1] == 0 and model.actuator_biasprm[a, 2] != 0
        source = traj.velocities if velocity else traj.positions
        ctrl[:, a] = np.interp(grid, traj.times, source[:, k])
        data.qpos[model.jnt_qposadr[model.actuator_trnid[a, 0]]] = traj.positions[0, k]
    mujoco.mj_forward(model, data)
    t0 = time.perf_counter()
    for i in range(steps):
        data.ctrl[:] = ctrl[i]
        mujoco.mj_step(model, data)
    return time.perf_counter() - t0


def bench_simspeed(seconds: float = SECONDS, runs: int = RUNS) -> list[str]:
    from bench_sim import default_bundles

    from gaits.base import _PLANNED
    from synth.verification.runs import controller_for_model
    from synth.verification.simulate import simulate

    load_avg = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    lines = [
        f"simulate's overhead over raw mj_step, {seconds:g} simulated s of a default behaviour "
        f"(best of {runs}; target <= {TARGET_RATIO} x; load average {load_avg})"
    ]
    startup = []
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    with tempfile.TemporaryDirectory() as tmp:
        for robot_type, rec, folder, model, ctl in default_bundles(Path(tmp)):
            names = sorted(ctl.listed(rec.get("abilities", ()))) or sorted(ctl.behaviors)
            name = names[0]
            traj = ctl.run(name)
            raw, sim = [], []
            tmpl = ctl.template
            body = traj.info.get("tool_body") or (tmpl.end_effectors or [None])[0]
            for _ in range(runs):  # as synth.verification.runs.run_behavior calls it
                raw.append(_raw_loop(model, traj, seconds))
                t0 = time.perf_counter()
                simulate(
                    model,
                    traj,
                    seconds,
                    can_fall=bool(tmpl.feet or tmpl.wheels),
                    end_effector=None if body is None else str(body),
                )
                sim.append(time.perf_counter() - t0)
            ratio = min(sim) / min(raw)
            mark = "ok  " if ratio <= TARGET_RATIO else "MISS"
            lines.append(
                f"  {mark} {robot_type:<24} {name:<22} simulate {min(sim) * 1000:6.1f} ms, "
                f"raw {min(raw) * 1000:6.1f} ms: {ratio:4.2f} x ({seconds / min(sim):4.0f} x "
                "real time)"
            )
            cmd = [sys.executable, "-m", "synth.commands.cli", "simulate", str(folder)]
            cmd += ["--behavior", name, "--seconds", f"{seconds:g}", "--json"]
            walls = []
            for _ in range(max(2, runs // 2)):
                t0 = time.perf_counter()
                subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, check=False)
                walls.append(time.perf_counter() - t0)
            plans = []
            for _ in range(max(2, runs // 2)):  # the process's plans forgotten
                _PLANNED.clear()
                fresh = controller_for_model(rec, model)
                t0 = time.perf_counter()
                fresh.run(name)
                plans.append(time.perf_counter() - t0)
            startup.append((robot_type, name, min(walls), min(sim), min(plans)))
    lines.append(
        f"parmor simulate DIR --behavior X --seconds {seconds:g} as a process, less the "
        f"in-process simulation (target < {TARGET_STARTUP_S:g} s)"
    )
    for robot, name, wall, sim_s, plan in startup:
        rest = wall - sim_s
        mark = "ok  " if rest < TARGET_STARTUP_S else "MISS"
        lines.append(
            f"  {mark} {robot:<24} {name:<22} {rest:5.2f} s start-up, of which planning "
            f"{plan:4.2f} s in-process ({wall:5.2f} s in all, {seconds / wall:4.1f} x real time)"
        )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_simspeed()))
