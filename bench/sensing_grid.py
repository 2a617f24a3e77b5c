"""Sensing abilities on gaits over a grid (program/sensing.py, stride by stride): a
four- and a six-legged robot type written in KIF follow lines (circle and wave, tightest
curve 0.5-2 m, the design's speed and 0.6 x it) and step around obstacles (goal 1-1.5 m,
obstacle 10-30 cm wide); a sidewinding snake passes the same obstacles at its default
wave frequency and 0.6 x it. Prints one line per run and the pass rate.

    PYTHONPATH=. python bench/sensing_grid.py [--quick]
"""

from __future__ import annotations

import io
import itertools
import json
import sys
import tempfile
import time
from pathlib import Path


def _legged_kif(name: str, legs: int, ability: str) -> str:
    from tests.kinematics.test_bodyplan import legged_kif

    return legged_kif(name, legs, ability)


def _bundle(root: Path, name: str, *argv: str) -> Path:
    from synth.commands.cli import main

    out = root / name
    err = io.StringIO()
    code = main([*argv, "--no-input", "--no-verify", "--out", str(out)], io.StringIO(), err)
    if code != 0:
        raise SystemExit(err.getvalue())
    return out


def designs(root: Path) -> dict[str, Path]:
    out = {}
    for legs in (4, 6):
        kif = root / f"walker{legs}.kif"
        kif.write_text(_legged_kif(f"Walker{legs}", legs, f"walking-on-{legs}"))
        out[f"walker{legs}"] = _bundle(
            root,
            f"walker{legs}",
            "design",
            f"walking-on-{legs}",
            "line-tracking",
            "obstacle-avoidance",
            "--ontology",
            str(kif),
        )
    out["sidewinder"] = _bundle(root, "sidewinder", "design", "sidewinding", "obstacle-avoidance")
    return out


def runs(bundles: dict[str, Path], quick: bool):
    from program import sensing
    from program.session import Session

    for name, folder in bundles.items():
        probe = Session(folder)
        speed = {p.name: p for p in probe.sensing["obstacle-avoidance"].params}["speed"]
        if speed.default:  # a wave frequency
            top = float(speed.default)
        else:  # legs: the design's speed, as walking plans it
            steer = sensing.steering(probe.controller.behaviors)
            top = float(probe.controller.run(steer.behavior).info["speed"])  # type: ignore[union-attr]
        speeds = (0.0 if not speed.default else top, round(0.6 * top, 4))
        if "line-tracking" in probe.sensing:
            grid = itertools.product(("circle", "wave"), (0.5, 1.0, 2.0), speeds)
            for course, radius, v in list(grid)[: 2 if quick else None]:
                yield (
                    name,
                    folder,
                    "line-tracking",
                    {"course": course, "radius": radius, "speed": v},
                )
        grid = itertools.product((1.0, 1.5), (0.1, 0.3), speeds)
        for distance, width, v in list(grid)[: 2 if quick else None]:
            yield (
                name,
                folder,
                "obstacle-avoidance",
                {"distance": distance, "width": width, "speed": v},
            )


def main() -> None:
    from program.session import Session

    quick = "--quick" in sys.argv
    with tempfile.TemporaryDirectory() as tmp:
        bundles = designs(Path(tmp))
        passed = total = 0
        for name, folder, behavior, params in runs(bundles, quick):
            t = time.perf_counter()
            f = Session(folder).do(behavior, **params)["figures"]
            total += 1
            passed += f["verdict"] == "ok"
            keys = ("line_lost_s", "max_line_offset_m", "line_progress_m", "obstacle_contact_s")
            keys += ("distance_m", "seconds")
            shown = {k: f[k] for k in keys if k in f}
            print(
                f"{name} {behavior} {json.dumps(params)} -> {f['verdict']} {json.dumps(shown)} "
                f"({time.perf_counter() - t:.0f} s)",
                flush=True,
            )
        print(f"{passed} of {total} pass")


if __name__ == "__main__":
    main()
