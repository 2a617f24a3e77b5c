"""PNG plots of a simulated behaviour: joint positions against their references, actuator
torques, and (legged gaits) the static stability margin. matplotlib, imported here only."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaits.base import Trajectory

if TYPE_CHECKING:  # the result's type only: export sits below the verification
    from synth.verification.simulate import SimResult


def write_plots(folder: Path, traj: Trajectory, result: SimResult) -> list[str]:
    """Write the plots into ``folder``; returns their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    s = result.series
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for k, name in enumerate(traj.joints):
        (line,) = ax.plot(s["t"], s["q"][:, k], label=name)
        ax.plot(s["t"], s["q_ref"][:, k], "--", color=line.get_color(), linewidth=0.8)
    ax.set(
        xlabel="time (s)",
        ylabel="joint angle (rad)",
        title=f"{traj.behavior}: joints (dashed: reference)",
    )
    if len(traj.joints) <= 12:
        ax.legend(fontsize=6, ncol=2)
    written.append(_save(fig, folder / f"{traj.behavior}_joints.png"))
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(s["t"], np.abs(s["force"]))
    ax.set(xlabel="time (s)", ylabel="|actuator torque| (N m)", title=f"{traj.behavior}: torques")
    written.append(_save(fig, folder / f"{traj.behavior}_torques.png"))
    margin = traj.info.get("stability_margin_m")
    if margin is not None:
        fig, ax = plt.subplots(figsize=(8, 3.5))
        ax.plot(traj.times, np.asarray(margin) * 1000)
        ax.axhline(0, color="red", linewidth=0.8)
        ax.set(
            xlabel="time (s)",
            ylabel="stability margin (mm)",
            title=f"{traj.behavior}: static stability margin",
        )
        written.append(_save(fig, folder / f"{traj.behavior}_stability.png"))
    return written


def _save(fig, path: Path) -> str:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)
    return path.name
