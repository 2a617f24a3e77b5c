"""Benchmark of the SUO-KIF reader against the ``sexpdata`` package on SUMO files.

Usage: ``python bench/bench_parse.py [SUMO_DIR]`` (default: ``../shared/kif/sumo`` next to
the repository). ``bench_parse`` returns the report lines for ``bench/bench.py``.

Fairness: sexpdata reads SUMO's ``;`` comments and double-quoted strings itself (its default
``line_comment=";"``), so it gets the same text. It parses one expression, so the text is
wrapped as ``"(" + text + "\\n)"`` once, before timing (the newline ends a final comment).
Both sides read the text from memory; file reading is not timed. Best of 5 runs each.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from adron.kif import parse  # noqa: E402

RUNS = 5
T = TypeVar("T")


def best_of(fn: Callable[[], T], runs: int = RUNS) -> tuple[float, T]:
    """Best wall time in seconds over ``runs`` calls, and the last result."""
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def bench_parse(sumo_dir: Path) -> list[str]:
    """Time adron.kif.parse on Merge.kif and Mid-level-ontology.kif (and sexpdata on Merge)."""
    lines = [f"KIF reader (best of {RUNS})"]
    for name in ("Merge.kif", "Mid-level-ontology.kif"):
        path = Path(sumo_dir) / name
        if not path.is_file():
            lines.append(f"  {name}: not found in {sumo_dir}, skipped")
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        ours, forms = best_of(lambda text=text, name=name: parse(text, name))
        n = len(forms)
        lines.append(
            f"  {name:<24} {len(text) / 1e3:7.0f} kchar  {n:6d} forms  "
            f"adron.kif {ours * 1e3:7.1f} ms  {n / ours:9.0f} forms/s"
        )
        if name != "Merge.kif":
            continue
        try:
            import sexpdata
        except ImportError:
            lines.append("  sexpdata not installed: comparison skipped")
            continue
        wrapped = "(" + text + "\n)"
        theirs, result = best_of(lambda wrapped=wrapped: sexpdata.loads(wrapped))
        lines.append(
            f"  {'':<24} {'':>13}  {len(result):6d} forms  "
            f"sexpdata  {theirs * 1e3:7.1f} ms  -> adron.kif is {theirs / ours:.1f}x as fast"
        )
    return lines


def main(argv: list[str]) -> int:
    """Print the benchmark lines for the SUMO folder given (or the default one)."""
    sumo_dir = Path(argv[1]) if len(argv) > 1 else REPO.parent / "shared" / "kif" / "sumo"
    for line in bench_parse(sumo_dir):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
