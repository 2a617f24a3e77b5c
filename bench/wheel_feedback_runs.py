"""Wheeled bases' behaviours of a bundle under perturbations 1..K, closed loop and open loop
(``docs/feedback-wheels.md``): per run the heading reached, the pose error, the drift and
the placing error, and the verdict.

    python bench/wheel_feedback_runs.py DIR [K] [--behaviors a,b] [--open]

The bundle may be designed with ``--robustness 0``: the table is then the design's own
(:func:`synth.verification.perturb.design_table` over the bundle's record and the shipped catalog).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main(argv: list[str]) -> None:
    from adron.catalog import load_catalog
    from synth.verification.perturb import design_table, draw, perturbed_model
    from synth.verification.runs import controller_for_model
    from synth.verification.simulate import simulate
    from synth.verification.source import Bundle

    opts = {"--behaviors": ""}
    for key in opts:
        if key in argv:
            i = argv.index(key)
            opts[key] = argv[i + 1]
            del argv[i : i + 2]
    modes = [True, False] if "--open" in argv else [True]
    argv = [a for a in argv if a != "--open"]
    folder = argv[0]
    k = int(argv[1]) if len(argv) > 1 else 8
    files = Bundle.read(folder)
    record, xml, meshes = files.record, files.xml, files.meshes
    table = ((record.get("verified") or {}).get("robust") or {}).get("table")
    if not table:
        table = design_table(record, xml, load_catalog())
    controller = controller_for_model(record, Bundle(folder=folder).model())
    names = (
        opts["--behaviors"].split(",")
        if opts["--behaviors"]
        else controller.listed(record.get("abilities", ()))
    )
    tmpl = controller.template
    for name in names:
        traj = controller.run(name)
        body = traj.info.get("tool_body") or (tmpl.end_effectors[0] if tmpl.end_effectors else None)
        for fb in modes:
            rows = []
            for seed in range(1, k + 1):
                p = draw(table, seed)
                model = perturbed_model(xml, meshes, table, p)
                r = simulate(
                    model,
                    traj,
                    can_fall=True,
                    end_effector=body,
                    latency_s=float(p["latency_s"]),
                    command_period_s=float(p["control_period_s"]),
                    sensor_noise=p.get("imu"),
                    feedback=fb,
                ).to_dict()
                rows.append(r)
                plan = r.get("planned_heading_rad") or 0.0
                print(
                    json.dumps(
                        {
                            "behavior": name,
                            "feedback": fb,
                            "seed": seed,
                            "heading_deg": round(math.degrees(r["heading_rad"] or 0), 1),
                            "planned_deg": round(math.degrees(plan), 1),
                            "pose_err_m": r["final_pose_error_m"],
                            "distance_m": r["distance_m"],
                            "drift_m": r["drift_m"],
                            "placing_mm": None
                            if r["placing_error_m"] is None
                            else round(1000 * r["placing_error_m"], 2),
                            "verdict": r["verdict"],
                        }
                    ),
                    flush=True,
                )
            ok = sum(r["verdict"] == "ok" for r in rows)
            print(f"# {name} feedback={fb}: {ok} of {k} pass", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
