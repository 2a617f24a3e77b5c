"""The biped's behaviours under perturbed runs, open loop against closed loop (the balance
loop of :mod:`gaits.balance`): one line per behaviour and seed with the floor's slope along
and across the walk, the latency, the verdict, the trunk's largest tilt, the distance over
the plan's, the heading error and the most saturated joint.

    python bench/balance_seeds.py DIR [K] [--seeds S,S..] [--behavior NAME]... [--open] [--closed]

``DIR`` a bundle (``parmor design ... --out DIR``; its ``verified.robust.table`` when it
has one, else the design's table); ``K`` seeds 1..K (default 8); both modes unless one is
named.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def main(argv: list[str]) -> None:
    from adron.catalog import load_catalog
    from export.mjcf import load_mjcf
    from synth.verification.perturb import design_table, draw, perturbed_model
    from synth.verification.runs import controller_for_model, recorded_table
    from synth.verification.simulate import simulate
    from synth.verification.source import Bundle

    folder = argv.pop(0)
    if os.environ.get("BALANCE_WALK") == "robust":  # the walk tuned for perturbed runs
        import gaits.humanoid

        gaits.humanoid.WALK = gaits.humanoid.ROBUST_WALK
    names: list[str] = []
    while "--behavior" in argv:
        i = argv.index("--behavior")
        names.append(argv[i + 1])
        del argv[i : i + 2]
    only = None
    if "--seeds" in argv:
        i = argv.index("--seeds")
        only = [int(x) for x in argv[i + 1].split(",")]
        del argv[i : i + 2]
    modes = [m for m in ("open", "closed") if f"--{m}" in argv] or ["open", "closed"]
    argv = [a for a in argv if not a.startswith("--")]
    k = int(argv[0]) if argv else 8
    bundle = Bundle.read(folder)
    record, xml, meshes = bundle.record, bundle.xml, bundle.meshes
    try:
        table = recorded_table(record)
    except Exception:  # noqa: BLE001 - a nominal bundle: the design's table
        table = None
    if not table:
        table = design_table(record, xml, load_catalog())
    ctl = controller_for_model(record, load_mjcf(xml, meshes))
    names = names or list(ctl.listed(record.get("abilities", ())))
    tmpl = ctl.template
    for name in names:
        traj = ctl.run(name)
        gains = os.environ.get("BALANCE_GAINS")
        if gains and traj.info.get("feedback"):
            traj.info["feedback"] = {**traj.info["feedback"], **json.loads(gains)}
        for mode in modes:
            passed = 0
            seeds = only or range(1, k + 1)
            for seed in seeds:
                p = draw(table, seed)
                model = perturbed_model(xml, meshes, table, p)
                body = traj.info.get("tool_body") or (
                    tmpl.end_effectors[0] if tmpl.end_effectors else None
                )
                r = simulate(
                    model,
                    traj,
                    can_fall=bool(tmpl.feet or tmpl.wheels),
                    end_effector=str(body) if body else None,
                    latency_s=float(p["latency_s"]),
                    command_period_s=float(p["control_period_s"]),
                    sensor_noise=p.get("imu"),
                    feedback=mode == "closed",
                )
                passed += r.ok
                slope, towards = math.degrees(p["slope_rad"]), p["slope_direction_rad"]
                worst = max(r.saturated_joints.items(), key=lambda kv: kv[1], default=("-", 0))
                tilt = math.degrees(r.max_tilt_rad or 0.0)
                ratio = r.distance_m / (r.planned_distance_m or 1e-9)
                print(
                    f"{name:<10} {mode:<6} seed {seed:2d} slope x "
                    f"{slope * math.cos(towards):+.1f} y {slope * math.sin(towards):+.1f} deg "
                    f"lat {p['latency_s'] * 1000:2.0f} ms: tilt {tilt:4.1f} deg, dist "
                    f"{ratio:.2f} x ({r.distance_m:.3f} m), heading "
                    f"{r.heading_rad - (r.planned_heading_rad or 0.0):+.3f}, sat "
                    f"{r.saturated_fraction:.3f} ({worst[0]} {worst[1]:.3f})  "
                    f"{', '.join(r.verdict) or 'ok'}",
                    flush=True,
                )
            print(f"{name:<10} {mode:<6} passed {passed} of {len(seeds)}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
