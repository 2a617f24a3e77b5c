"""Wall time of ``parmor design REQUEST --no-input`` as a process for each shipped type's
default request, with the default robust verification (K = 8, the environment's
PARMOR_ROBUSTNESS removed) and with ``--no-verify``, for one or two source trees
interleaved (each tree's ``python -m synth.commands.cli`` run with that tree as its current folder):
the table of ``docs/verification.md``'s *How long a verified design takes*.

    python bench/design_times.py [TREE ...] [--json OUT]

(default: this tree). The caches are warmed by one ``--no-verify`` run of each request
first; ``--no-verify`` is the best of two runs, the default one run. The x figures divide
the default by ``--no-verify`` of the same tree and run, which a loaded machine slows alike.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: Each shipped type's default request (bench.py's TYPE_REQUESTS and the steered type's).
REQUESTS = {
    "hexapod, rough-terrain-walking": ["rough-terrain-walking"],
    "quadruped, walking": [
        "walking", "--answer", "grasping=no", "--answer", "rough-terrain-walking=no",
    ],
    "humanoid, walking + grasping": ["walking", "--answer", "grasping=yes"],
    "snake, sidewinding": ["sidewinding"],
    "differential drive, driving": ["driving"],
    "skid-steer, driving (2 kg)": ["driving", "--param", "payload=2kg"],
    "3-DOF arm, pick-and-place": ["pick-and-place", "--param", "object_shape=cylinder"],
    "6-DOF arm, pick-and-place": ["pick-and-place", "--param", "object_shape=oval"],
    "steered, steered-driving": ["steered-driving"],
}  # fmt: skip


def timed(tree: Path, argv: list[str]) -> tuple[float, int]:
    """(wall s, exit code) of ``parmor design ARGV --no-input`` run from ``tree``."""
    env = {k: v for k, v in os.environ.items() if k != "PARMOR_ROBUSTNESS"}
    cmd = [sys.executable, "-m", "synth.commands.cli", "design", *argv, "--no-input"]
    t = time.perf_counter()
    r = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, check=False)
    return time.perf_counter() - t, r.returncode


def main(args: list[str]) -> int:
    out = None
    if "--json" in args:
        k = args.index("--json")
        out, args = Path(args[k + 1]), args[:k] + args[k + 2 :]
    trees = [Path(a).resolve() for a in args] or [REPO]
    table: dict[str, dict] = {}
    for name, argv in REQUESTS.items():
        for tree in trees:  # warm the caches (plans, knowledge base, catalog)
            timed(tree, [*argv, "--no-verify"])
        row = {}
        for tree in trees:
            bare = min(timed(tree, [*argv, "--no-verify"])[0] for _ in range(2))
            full, code = timed(tree, argv)
            row[str(tree)] = {"no_verify_s": round(bare, 2), "default_s": round(full, 2)}
            row[str(tree)]["code"] = code
        table[name] = row
        cells = " | ".join(
            f"{c['no_verify_s']:5.1f} s {c['default_s']:6.1f} s "
            f"({c['default_s'] / c['no_verify_s']:4.1f} x) "
            + ("accepted" if c["code"] == 0 else "refused")
            for c in row.values()
        )
        print(f"{name:<32} {cells}", flush=True)
    if out is not None:
        out.write_text(json.dumps(table, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
