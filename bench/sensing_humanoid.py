"""Humanoid walking steered (gaits/humanoid.py: a ``curvature``, the hips' yaw turning
each foot as it swings) and the sensing loops on it (program/sensing.py, stride by
stride), on the humanoid the abilities pick (walking, grasping and both sensing
abilities), unloaded and with a 0.3 kg payload:

- arcs: four steps of walking at each curvature of a sweep up to the tightest the hips'
  yaw range allows, judged by the simulation (fall, heading, saturation): the heading
  change measured against the planned one;
- sensing: circles of radius 1-2 m at the default and the longest step, obstacles 10-30
  cm wide 1 m ahead at both steps.

Prints one line per run and the pass rates. ``--walk robust``: walking is
``gaits.humanoid.ROBUST_WALK`` (tuned for the perturbed runs), the bundles verified so
that its arcs' turn is measured (their ``calibration``).

    PYTHONPATH=. python bench/sensing_humanoid.py [--quick] [--walk robust]
"""

from __future__ import annotations

import io
import itertools
import json
import sys
import tempfile
import time
from pathlib import Path

CURVATURES = (-1.0, 1.0, 2.0, -5.0, 5.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0)


#: Whether the bundles are verified (their calibration measured): ``--walk robust``.
VERIFY = False


def _bundle(root: Path, name: str, *argv: str) -> Path:
    from synth.commands.cli import main

    out = root / name
    err = io.StringIO()
    verify = () if VERIFY else ("--no-verify",)
    code = main([*argv, "--no-input", *verify, "--out", str(out)], io.StringIO(), err)
    if code != 0:
        raise SystemExit(err.getvalue())
    return out


def designs(root: Path) -> dict[str, Path]:
    ask = ("design", "walking", "grasping", "line-tracking", "obstacle-avoidance")
    return {
        "humanoid": _bundle(root, "plain", *ask),
        "humanoid+0.3kg": _bundle(root, "loaded", *ask, "--param", "payload=0.3kg"),
    }


def arcs(name: str, folder: Path, quick: bool) -> tuple[int, int]:
    from program.session import Session

    passed = total = 0
    for k in CURVATURES[: 3 if quick else None]:
        f = Session(folder).do("walking", steps=4, curvature=k)["figures"]
        total += 1
        passed += f["verdict"] == "ok"
        print(
            f"{name} walking curvature={k:g} rad/m -> {f['verdict']} heading "
            f"{f['heading_rad']:.3f} of {f['planned_heading_rad']:.3f} rad, fell {f['fell']}, "
            f"saturated {f['saturated_fraction']:.3f}",
            flush=True,
        )
    return passed, total


def runs(folder: Path, quick: bool):
    from program.session import Session

    probe = Session(folder)
    speed = {p.name: p for p in probe.sensing["line-tracking"].params}["speed"]
    steps = (float(speed.default), float(speed.high))
    lines = itertools.product((1.0, 1.5, 2.0), steps)
    for radius, v in list(lines)[: 1 if quick else None]:
        yield "line-tracking", {"course": "circle", "radius": radius, "speed": v}
    obstacles = itertools.product((0.1, 0.2, 0.3), steps)
    for width, v in list(obstacles)[: 1 if quick else None]:
        yield "obstacle-avoidance", {"distance": 1.0, "width": width, "speed": v}


def main() -> None:
    from program.session import Session

    global VERIFY
    quick = "--quick" in sys.argv
    if "--walk" in sys.argv:
        if sys.argv[sys.argv.index("--walk") + 1] != "robust":
            sys.exit("--walk: the only alternative walk is 'robust'")
        import gaits.humanoid

        gaits.humanoid.WALK = gaits.humanoid.ROBUST_WALK
        VERIFY = True
    with tempfile.TemporaryDirectory() as tmp:
        bundles = designs(Path(tmp))
        arc_pass = arc_total = passed = total = 0
        for name, folder in bundles.items():
            p, n = arcs(name, folder, quick)
            arc_pass, arc_total = arc_pass + p, arc_total + n
            for behavior, params in runs(folder, quick):
                t = time.perf_counter()
                f = Session(folder).do(behavior, **params)["figures"]
                total += 1
                passed += f["verdict"] == "ok"
                keys = ("line_lost_s", "max_line_offset_m", "line_progress_m")
                keys += ("obstacle_contact_s", "distance_m", "seconds")
                shown = {k: f[k] for k in keys if k in f}
                print(
                    f"{name} {behavior} {json.dumps(params)} -> {f['verdict']} "
                    f"{json.dumps(shown)} ({time.perf_counter() - t:.0f} s)",
                    flush=True,
                )
        print(f"arcs: {arc_pass} of {arc_total} pass")
        print(f"sensing: {passed} of {total} pass")


if __name__ == "__main__":
    main()
