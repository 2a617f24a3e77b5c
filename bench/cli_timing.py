"""Wall time of ``parmor`` commands as processes, for the benchmarks (bench_onto,
bench_chain): best of ``runs``, each with its own ``PARMOR_CACHE``."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def best_time(
    args: Sequence[str],
    runs: int,
    cache: str | None = None,
    seed: Callable[[Path], None] | None = None,
    ok: Sequence[int] = (0,),
) -> float:
    """Best wall-clock seconds of ``runs`` processes ``python -m synth.commands.cli ARGS``.

    ``cache``: the PARMOR_CACHE folder, warmed by one run first; None: a new empty one
    per run (a cold cache), given its files by ``seed(folder)`` first when given. A run
    ending with a code outside ``ok`` raises RuntimeError with its error output."""
    cmd = [sys.executable, "-m", "synth.commands.cli", *args]
    best = float("inf")
    for _ in range(runs):
        with tempfile.TemporaryDirectory(prefix="parmor-bench-cache-") as cold:
            if seed is not None and cache is None:
                seed(Path(cold))
            env = {**os.environ, "PYTHONPATH": str(REPO), "PARMOR_CACHE": cache or cold}
            if cache is not None:  # warm it first
                subprocess.run(cmd, env=env, capture_output=True, cwd=REPO, check=False)
            t0 = time.perf_counter()
            r = subprocess.run(cmd, env=env, capture_output=True, cwd=REPO, check=False)
            best = min(best, time.perf_counter() - t0)
        if r.returncode not in ok:
            raise RuntimeError(r.stderr.decode()[-500:])
    return best
