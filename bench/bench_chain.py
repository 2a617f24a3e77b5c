"""A long subclass chain as ``--ontology`` (issue 11): ``(subclass C{i+1} C{i})`` for
3,000 and 100,000 classes under ``Robot``, with a cold cache (a new empty
``PARMOR_CACHE`` per run, the gaits' own caches warmed first so that only the
ontology's work is cold), for ``ontology check``, ``design --conceptual`` and the full
``design`` (sized and simulated), and the full ``design`` once more with every cache
cold (a first design on a new machine: the quadruped's sway programmes solved too); wall
time (best of ``runs``) against the 5 s target and as a ratio to the same command with a
one-class chain in the same run."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from cli_timing import best_time

REPO = Path(__file__).resolve().parents[1]
TARGET = 5.0  # s (issue 11)
LENGTHS = (3_000, 100_000)
REQUEST = ["walking", "--answer", "grasping=no", "--answer", "rough-terrain-walking=no"]
COMMANDS = {
    "ontology check": lambda kif: ["ontology", "check", *kif],
    "design --conceptual": lambda kif: [
        "design",
        *REQUEST,
        "--conceptual",
        *(a for k in kif for a in ("--ontology", k)),
    ],
    "design": lambda kif: ["design", *REQUEST, *(a for k in kif for a in ("--ontology", k))],
    "design, all cold": lambda kif: [
        "design",
        *REQUEST,
        *(a for k in kif for a in ("--ontology", k)),
    ],
}
#: commands timed with no cache at all (not even the gaits')
ALL_COLD = {"design, all cold"}


def chain(n: int) -> str:
    """The KIF text of an ``n``-long subclass chain below ``Robot``."""
    lines = [f"(subclass C{i + 1} C{i})" for i in range(n)]
    return "\n".join([*lines, "(subclass C0 Robot)"]) + "\n"


def _time(args: list[str], runs: int, warm: Path | None) -> float:
    """Best wall-clock time of ``args`` with a cold cache holding only ``warm``'s gaits'
    files (not the ontology's); every cache cold when ``warm`` is None."""

    def seed(cold: Path) -> None:
        for p in warm.glob("*") if warm is not None else ():
            if not p.name.startswith(("kb-", "relevant-")):
                shutil.copy(p, cold)

    return best_time(args, runs, seed=seed)


def bench_chain(runs: int = 2) -> list[str]:
    lines = [
        f"Subclass chains, cold ontology cache, best of {runs} (target < {TARGET:g} s; "
        f"load {os.getloadavg()[0]:.1f})"
    ]
    with tempfile.TemporaryDirectory(prefix="parmor-bench-chain-") as tmp:
        warm = Path(tmp) / "warm"
        env = {**os.environ, "PYTHONPATH": str(REPO), "PARMOR_CACHE": str(warm)}
        subprocess.run(  # the gaits' caches (sway, gait maps) as a user's machine has them
            [sys.executable, "-m", "synth.commands.cli", "design", *REQUEST],
            env=env,
            capture_output=True,
            cwd=REPO,
            check=False,
        )
        files = {}
        for n in (1, *LENGTHS):
            files[n] = Path(tmp) / f"chain{n}.kif"
            files[n].write_text(chain(n), encoding="utf-8")
        for name, make in COMMANDS.items():
            caches = None if name in ALL_COLD else warm
            ref = _time(make([str(files[1])]), runs, caches)
            lines.append(f"  ref  {name:<20} {1:>7,}-class chain {ref:6.2f} s")
            for n in LENGTHS:
                t = _time(make([str(files[n])]), runs, caches)
                mark = "ok  " if t < TARGET else "MISS"
                lines.append(
                    f"  {mark} {name:<20} {n:>7,}-class chain {t:6.2f} s  {t / ref:5.1f} x ref"
                )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_chain(int(sys.argv[1]) if sys.argv[1:] else 2)))
