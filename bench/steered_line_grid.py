"""Steered line-tracking over a grid (issue 21): the two KIF-only steered types of
tests/gaits/test_steered.py x circle/wave x line radius 0.5/1/2 m x a quarter and half of the top
speed (24 runs, about 7 min on 2 cores); prints the pass rate and the worst steering-servo
saturation, and exits 1 below the measured floor (10 of 24 when written: see the README).

    PYTHONPATH=. python bench/steered_line_grid.py
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

#: The share of the grid that passed when this was written; a regression below it fails.
GRID_FLOOR = 0.4


def main() -> int:
    import io

    from synth.commands.cli import main as parmor
    from tests.program.test_sensing_steered import TYPES, _follow

    root = Path(tempfile.mkdtemp(prefix="steerline-"))
    runs, passed, worst_sat, failed = 0, 0, 0.0, []
    for case, (kif, ability, extra) in sorted(TYPES.items()):
        src = root / f"{case}.kif"
        src.write_text(kif)
        folder = root / case
        argv = ["design", ability, "line-tracking", "--ontology", str(src), "--no-input"]
        argv += ["--no-verify", "--out", str(folder), *extra]
        err = io.StringIO()
        if parmor(argv, out=io.StringIO(), err=err) != 0:
            print(err.getvalue(), file=sys.stderr)
            return 2
        for course in ("circle", "wave"):
            for radius in (0.5, 1.0, 2.0):
                for share in (0.25, 0.5):
                    f = _follow(folder, course, radius, share)
                    runs += 1
                    worst_sat = max(worst_sat, f["saturated_fraction"])
                    ok = f["verdict"] == "ok"
                    passed += ok
                    if not ok:
                        failed.append((case, course, radius, share, f["line_lost_s"]))
                    print(f"{case:5} {course:6} r={radius:<4} {share:.2f} x top: {f['verdict']}")
    print(
        f"steered line-tracking grid: {passed}/{runs} passed; worst saturation "
        f"{worst_sat:.3f}; failed {failed}"
    )
    return 0 if passed >= math.ceil(GRID_FLOOR * runs) and worst_sat <= 0.05 + 1e-9 else 1


if __name__ == "__main__":
    sys.exit(main())
