"""The humanoid under robust verification (issue 22): which perturbation breaks its
behaviours, and how its requests fare with ``--robustness K``.

``isolate``: one humanoid request designed (nominal verification), then each listed
behaviour replayed under perturbations 1..K of the design's table with one perturbation
kept at a time and the others at their neutral values (``KEEP``: the servos' play alone,
the bus latency alone, ...; ``all``: the whole draw, what ``--robustness`` runs), and the
play of one joint group at a time (``GROUPS``). ``--servo MODEL=GEARS:DEADBAND`` overrides
the perturbation table's servo entry (e.g. ``SG90=metal:5us``: what a metal-geared servo
with a smaller dead band would give), ``--play-stop-steps N`` the play hinges' end-stop
time constant (``synth.verification.perturb.PLAY_STOP_STEPS``; 10 is MuJoCo's default 0.02 s);
``--walk robust``: walking is ``gaits.humanoid.ROBUST_WALK`` (tuned for the perturbed
runs) instead of the default walk, in the designs' sizing too.

``seeds``: walking replayed under each perturbation 1..K of the whole draw, one line per
seed: the floor's slope along and across the walk, the friction, the latency, the
distance walked over the planned one, the heading error, the saturated share and its
most saturated joint (``--no-play REGEX``: the play of the joints matching it removed;
``--yaw-as-pitch``: the hip yaws' actuators given their hip pitch's torque and gains).
What it showed (the default design, ``--walk robust``, K = 24): the distance grows with
the slope along the walk (about 15 % per degree) and the lateral slope saturates the hip
yaw's SG90 while both feet are down; without the hip yaws' play the distance stays
within 0.96-1.26 x.

``grid``: the humanoid requests (walking with grasping; payload default, 0, 0.1 and
0.3 kg) designed as ``bench/robust_grid.py`` does, nominal and with ``--robustness K``:
accepted before -> after and the perturbed runs that passed. ``--floors needed``: the
robust loop's torque floors from the demanded behaviours' runs only, and only for joints
saturated 1 % of a run or more (:func:`needed_floors`).

    python bench/robust_humanoid.py isolate [K] [--servo M=G:D] [--play-stop-steps N]
        [--walk robust] [ARGS..]
    python bench/robust_humanoid.py seeds [K] [--walk robust] [--no-play REGEX] [--yaw-as-pitch]
        [ARGS..]
    python bench/robust_humanoid.py grid [K] [--play-stop-steps N] [--walk robust]
        [--floors needed]
"""

from __future__ import annotations

import copy
import re
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

#: One perturbation kept at a time (the others neutral); "all": the whole draw.
KEEP = ("all", "play", "latency", "slope", "friction", "mass", "battery", "all-but-play")
#: Joint groups whose play is kept alone (a regular expression on the joint's name).
GROUPS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll", "arm")
GROUP_RE = {"arm": "shoulder|elbow|gripper"}
#: The humanoid requests of the grid (walking without grasping is a quadruped's request:
#: not here) and their payloads.
REQUESTS = (("walking", "--answer", "grasping=yes"),)
PAYLOADS = (
    (),
    ("--param", "payload=0kg"),
    ("--param", "payload=0.1kg"),
    ("--param", "payload=0.3kg"),
)


def neutral(p: dict, keep: str, joints: str | None = None) -> dict:
    """Perturbation ``p`` (``synth.verification.perturb.draw``) with all but ``keep`` at their
    neutral values; ``joints``: only the play of joints matching it is kept."""
    p = copy.deepcopy(p)
    kept = set(KEEP[1:7]) if keep == "all" else {keep}
    if keep == "all-but-play":
        kept = set(KEEP[2:7])
    if "play" not in kept:
        p["play_rad"] = dict.fromkeys(p["play_rad"], 0.0)
    elif joints is not None:
        p["play_rad"] = {j: v if re.search(joints, j) else 0.0 for j, v in p["play_rad"].items()}
    if "latency" not in kept:
        p["latency_s"] = p["control_period_s"] = 0.0
    if "slope" not in kept:
        p["slope_rad"] = 0.0
    if "friction" not in kept:
        p["friction_scale"] = 1.0
    if "mass" not in kept:
        p["mass_scale"] = dict.fromkeys(p["mass_scale"], 1.0)
    if "battery" not in kept:
        p["battery_scale"] = 1.0
    return p


def _design(argv: list[str]) -> tuple[int, str]:
    import io

    from synth.commands.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main(["design", *argv, "--no-input"], out, err)
    return code, err.getvalue().strip()


def isolate(k: int, argv: list[str], servo: dict | None = None) -> list[str]:
    """Lines: per behaviour and kept perturbation, the runs of 1..k that passed and the
    criteria the others failed."""
    from adron.catalog import load_catalog
    from export.mjcf import load_mjcf
    from synth.verification.perturb import design_table, draw, perturbed_model
    from synth.verification.runs import _simulate, controller_for_model
    from synth.verification.source import Bundle

    with tempfile.TemporaryDirectory() as tmp:
        code, why = _design([*argv, "--out", tmp])
        if code:
            return [f"{' '.join(argv)}: not designed: {why.splitlines()[-1]}"]
        files = Bundle.read(tmp)
    record, xml, meshes = files.record, files.xml, files.meshes
    table = design_table(record, xml, load_catalog(), {"servo": servo} if servo else None)
    nominal = load_mjcf(xml, meshes)
    ctl = controller_for_model(record, nominal)
    names = ctl.listed(record.get("abilities", ()))
    plays = sorted(
        {
            (s["model"], f"{s['backlash_rad'][0]:.4f}", f"{s['deadband_rad']:.4f}")
            for s in table["servos"].values()
        }
    )
    lines = [
        f"{' '.join(argv)}: behaviours {', '.join(names)}; servos (model, backlash low, "
        f"dead band, rad) {plays}"
    ]
    print(lines[0], flush=True)
    draws = {s: draw(table, s) for s in range(1, k + 1)}
    models: dict = {}
    cases = [(keep, None) for keep in KEEP] + [(f"play:{g}", GROUP_RE.get(g, g)) for g in GROUPS]
    for name in names:
        traj = ctl.run(name)
        for label, joints in cases:
            keep = "play" if joints is not None else label
            passed, failed = 0, {}
            for s, p0 in draws.items():
                p = neutral(p0, keep, joints)
                key = (label, s)
                if key not in models:
                    models[key] = perturbed_model(xml, meshes, table, p)
                verdict = _simulate(models[key], ctl, traj, None, None, p).verdict
                passed += not verdict
                for v in verdict:
                    failed[v] = failed.get(v, 0) + 1
            why = ", ".join(f"{v} {n}" for v, n in sorted(failed.items()))
            lines.append(f"  {name:<10} {label:<18} passed {passed} of {k}  {why}")
            print(lines[-1], flush=True)
    return lines


def seeds(
    k: int, argv: list[str], no_play: str | None = None, yaw_as_pitch: bool = False
) -> list[str]:
    """Lines: walking under each perturbation 1..k (the whole draw; ``no_play``: without
    the play of the joints matching it; ``yaw_as_pitch``: the hip yaws' actuators given
    their hip pitch's force range and gains, as perturbed), with the floor's slope resolved
    along the walk (x) and across it (y) and the run's figures."""
    import math

    from adron.catalog import load_catalog
    from export.mjcf import load_mjcf
    from synth.verification.perturb import design_table, draw, perturbed_model
    from synth.verification.runs import _simulate, controller_for_model
    from synth.verification.source import Bundle

    with tempfile.TemporaryDirectory() as tmp:
        code, why = _design([*argv, "--out", tmp])
        if code:
            return [f"{' '.join(argv)}: not designed: {why.splitlines()[-1]}"]
        files = Bundle.read(tmp)
    record, xml, meshes = files.record, files.xml, files.meshes
    table = design_table(record, xml, load_catalog())
    ctl = controller_for_model(record, load_mjcf(xml, meshes))
    traj = ctl.run("walking")
    lines, passed = [], 0
    for seed in range(1, k + 1):
        p = draw(table, seed)
        if no_play:
            p["play_rad"] = {
                j: 0.0 if re.search(no_play, j) else v for j, v in p["play_rad"].items()
            }
        model = perturbed_model(xml, meshes, table, p)
        if yaw_as_pitch:
            for side in ("l", "r"):
                a = model.actuator(f"{side}_hip_yaw").id
                b = model.actuator(f"{side}_hip_pitch").id
                model.actuator_forcerange[a] = model.actuator_forcerange[b]
                model.actuator_gainprm[a] = model.actuator_gainprm[b]
                model.actuator_biasprm[a] = model.actuator_biasprm[b]
        r = _simulate(model, ctl, traj, None, None, p)
        passed += r.ok
        slope, towards = math.degrees(p["slope_rad"]), p["slope_direction_rad"]
        worst = max(r.saturated_joints.items(), key=lambda kv: kv[1], default=("-", 0.0))
        lines.append(
            f"  seed {seed:2d} slope x {slope * math.cos(towards):+.1f} y "
            f"{slope * math.sin(towards):+.1f} deg, friction x{p['friction_scale']:.2f}, "
            f"latency {p['latency_s'] * 1000:2.0f} ms: distance "
            f"{r.distance_m / (r.planned_distance_m or 1e-9):.3f} x, heading "
            f"{r.heading_rad - (r.planned_heading_rad or 0.0):+.3f} rad, saturated "
            f"{r.saturated_fraction:.3f} ({worst[0]} {worst[1]:.3f})  "
            f"{', '.join(r.verdict) or 'ok'}"
        )
        print(lines[-1], flush=True)
    lines.append(f"  passed {passed} of {k}")
    print(lines[-1], flush=True)
    return lines


#: ``--floors needed``: a joint whose share of saturated samples in a failed run is below
#: this gets no torque floor from it (it did not break the run: the verdict allows 5 %).
FLOOR_SHARE = 0.01


def needed_floors() -> None:
    """The robust loop's torque floors (``synth.verification.loop._floors``) taken only from the
    runs of behaviours that serve a demanded ability (a bonus one that fails is dropped, not
    sized for) and only for the joints saturated at least ``FLOOR_SHARE`` of a run: what
    ``--floors needed`` measures (the shipped loop floors every saturated joint of every
    failed run, and the bonus ``running`` saturates joints no catalog servo strengthens,
    so the sizing is infeasible and the hip yaw never gets its stronger servo)."""
    import synth.verification.loop
    from gaits import controller_for
    from gaits.base import DesignGeometry

    plain = synth.verification.loop._floors

    def floors(results: list[dict], record: dict) -> dict[str, float]:
        ctl = controller_for(DesignGeometry.from_record(record))
        needed = set(record.get("needed") or record.get("abilities", ()))
        served = {s for a in needed if (s := ctl.serving(a)) is not None}
        realises = {name: spec.realises for name, spec in ctl.behaviors.items()}
        kept = []
        for r in results:
            if realises.get(r.get("behavior"), next(iter(served), None)) not in served:
                continue
            shares = r.get("saturated_joints") or {}
            kept.append(
                {**r, "saturated_joints": {j: v for j, v in shares.items() if v >= FLOOR_SHARE}}
            )
        return plain(kept, record)

    synth.verification.loop._floors = floors


def grid(k: int) -> list[str]:
    from robust_grid import design

    import synth.verification.loop

    synth.verification.loop.best_value = lambda *a, **kw: None  # no hint search
    lines = [f"Humanoid requests, K = {k}: accepted nominal -> robust, perturbed runs passed"]
    for req in REQUESTS:
        for payload in PAYLOADS:
            args = [*req, *payload]
            code0, rec0, _ = design(args)
            code1, rec1, why = design([*args, "--robustness", str(k)])
            robust = ((rec1 or {}).get("verified") or {}).get("robust") or {}
            runs = {
                b["behavior"]: f"{b['passed']}/{b['runs']}" for b in robust.get("behaviors", ())
            }
            lines.append(
                f"  {' '.join(args):<52} {'ok' if code0 == 0 else 'refused'} -> "
                f"{'ok' if code1 == 0 else 'refused'}  {runs}"
                + (f"  ({why.splitlines()[-1][:160]})" if code1 else "")
            )
            print(lines[-1], flush=True)
    return lines


if __name__ == "__main__":
    args = sys.argv[1:]
    what = args.pop(0) if args else "isolate"
    servo = {}
    while "--servo" in args:
        i = args.index("--servo")
        model, spec = args[i + 1].split("=")
        gears, dead = spec.split(":")
        servo[model] = {"gears": gears, "deadband": dead.replace("us", " us")}
        del args[i : i + 2]
    if "--play-stop-steps" in args:
        import synth.verification.perturb

        i = args.index("--play-stop-steps")
        synth.verification.perturb.PLAY_STOP_STEPS = float(args[i + 1])
        del args[i : i + 2]
    if "--walk" in args:
        i = args.index("--walk")
        if args[i + 1] != "robust":
            sys.exit(f"--walk {args[i + 1]}: the only alternative walk is 'robust'")
        import gaits.humanoid

        gaits.humanoid.WALK = gaits.humanoid.ROBUST_WALK
        del args[i : i + 2]
    no_play = None
    if "--no-play" in args:
        i = args.index("--no-play")
        no_play = args[i + 1]
        del args[i : i + 2]
    if "--floors" in args:
        i = args.index("--floors")
        if args[i + 1] != "needed":
            sys.exit(f"--floors {args[i + 1]}: the only alternative is 'needed'")
        needed_floors()
        del args[i : i + 2]
    yaw_as_pitch = "--yaw-as-pitch" in args
    if yaw_as_pitch:
        args.remove("--yaw-as-pitch")
    k = int(args.pop(0)) if args and args[0].isdigit() else 8
    if what == "grid":
        grid(k)
    elif what == "seeds":
        seeds(k, args or list(REQUESTS[0]), no_play, yaw_as_pitch)
    else:
        isolate(k, args or list(REQUESTS[0]), servo or None)
