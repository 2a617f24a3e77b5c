"""Which perturbation breaks a run (issue 22): a bundle's behaviour replayed under its
perturbation SEED with one component at a time (the others nominal: friction x1, no slope,
no latency, full battery, masses x1, no play), and with all of them.

    python bench/robust_isolate.py DIR BEHAVIOR SEED [SEED ...]

DIR is a bundle designed with ``--robustness K --out DIR`` (its record keeps the table).
"""

from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: component -> the keys of a perturbation (synth.verification.perturb.draw) it sets.
COMPONENTS = {
    "friction": ("friction_scale",),
    "slope": ("slope_rad", "slope_direction_rad"),
    "latency": ("latency_s", "control_period_s"),
    "battery": ("battery_scale",),
    "masses": ("mass_scale",),
    "play": ("play_rad",),
}


def nominal(p: dict) -> dict:
    """``p`` with every component at its nominal value."""
    return p | {
        "friction_scale": 1.0,
        "slope_rad": 0.0,
        "slope_direction_rad": 0.0,
        "latency_s": 0.0,
        "control_period_s": 0.0,
        "battery_scale": 1.0,
        "mass_scale": {},
        "play_rad": {},
    }


def replays(
    folder: str, behavior: str, seed: int, open_loop: bool = False
) -> tuple[dict, dict[str, dict]]:
    """(perturbation ``seed`` of the bundle's table, case -> the run's judged figures):
    the cases ``none`` (every component nominal), ``all`` (the whole perturbation) and one
    per :data:`COMPONENTS` (that component alone). A bundle without a recorded table
    (designed without --robustness) uses the shipped catalog's. ``open_loop``: the plan
    without its feedback loop (what the plan alone does)."""
    from dataclasses import replace

    from adron.errors import InputError
    from export.mjcf import load_mjcf
    from synth.verification.perturb import draw, perturbed_model
    from synth.verification.runs import _simulate, controller_for_model, figures, recorded_table
    from synth.verification.source import Bundle

    files = Bundle.read(folder)
    record, xml, meshes = files.record, files.xml, files.meshes
    try:
        table = recorded_table(record)
    except InputError:  # designed without --robustness: the catalog's table
        from adron.catalog import load_catalog
        from synth.verification.perturb import design_table

        table = design_table(record, xml, load_catalog())
    p = draw(table, seed)
    controller = controller_for_model(record, load_mjcf(xml, meshes))
    traj = controller.run(behavior)
    if open_loop:
        traj = replace(traj, info={k: v for k, v in traj.info.items() if k != "feedback"})
    cases = {"none": nominal(p), "all": p}
    for name, keys in COMPONENTS.items():
        cases[name] = nominal(p) | {k: p[k] for k in keys}
    out = {}
    for name, q in cases.items():
        model = perturbed_model(xml, meshes, table, q)
        out[name] = figures(traj, _simulate(model, controller, traj, None, None, q))
    return p, out


def isolate(folder: str, behavior: str, seed: int) -> list[str]:
    """:func:`replays` as lines: each case's heading, distance, pose error and verdict."""
    from synth.verification.perturb import describe
    from synth.verification.verdict import explain

    p, runs = replays(folder, behavior, seed)
    lines = [f"{behavior} under {describe(p)}"]
    for name, r in runs.items():
        why = explain(r, r["verdict"]) if r["verdict"] != "ok" else "ok"
        lines.append(
            f"  {name:<9} heading {r['heading_rad']:+.3f} (plan {r['planned_heading_rad']}) "
            f"distance {r['distance_m']:.3f} pose err {r['final_pose_error_m']}: {why}"
        )
    return lines


if __name__ == "__main__":
    folder, behavior, *seeds = sys.argv[1:]
    for s in seeds:
        print("\n".join(isolate(folder, behavior, int(s))), flush=True)
