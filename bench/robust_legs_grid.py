"""Robust verification of legged designs (issue 22): the shipped quadruped and hexapod and
the KIF-only walkers of 4 to 8 legs (``studies/multipeds.kif``) over payloads and obstacle
heights, each request designed twice in this process: as ``parmor design`` does by
default (nominal verification) and with ``--robustness K``. Per type: requests accepted
before (nominal) and after (robust), perturbed runs passing, and the behaviours that
failed a run. The refusals' hint search is left out (as ``bench/robust_grid.py``).

    python bench/robust_legs_grid.py [K] [--jsonl FILE] [--only TYPE,...] [--noslip]
    python bench/robust_legs_grid.py [K] --summary FILE

``--noslip`` measures a contact model the project does not ship: every MuJoCo model
compiled in the run gets ``<option noslip_iterations="10">`` (MuJoCo's soft contacts let
a robot standing still on the perturbations' 3 deg slope slide about 45 mm in 30 s at a
friction of 0.77; the no-slip solver holds it within a millimetre).
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

KIF = str(REPO / "studies" / "multipeds.kif")
WORDS = {4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight"}

#: Each type's request; the KIF walkers on the ontology of studies/multipeds.kif (the
#: octopod's 24 servos need the Dynamixel catalog's bus, as studies/octopod.toml).
TYPES: dict[str, list[str]] = {
    "QuadrupedRobot": [
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=no",
    ],
    "HexapodRobot": ["rough-terrain-walking"],
    **{
        f"Walker{n}": [f"{WORDS[n]}-leg-walking", "--ontology", KIF]
        + (["--catalog", "dynamixel"] if n == 8 else [])
        for n in range(4, 9)
    },
}

#: The grid's variants, in the order run (every type once per variant).
VARIANTS = (
    ("--param", "payload=0kg"),
    ("--param", "payload=0.1kg"),
    ("--param", "payload=0.3kg"),
    ("--param", "payload=0.1kg", "--param", "obstacle_height=1cm"),
    ("--param", "payload=0.1kg", "--param", "obstacle_height=5cm"),
)


def row(robot_type: str, args: list[str], k: int) -> dict:
    from robust_grid import design

    code0, _, why0 = design(args)
    code1, rec1, why = design([*args, "--robustness", str(k)])
    robust = (rec1 or {}).get("verified", {}).get("robust") or {}
    kept = set((rec1 or {}).get("abilities", ()))
    behaviors = robust.get("behaviors", [])
    return {
        "type": robot_type,
        "args": [a.replace(str(REPO) + "/", "") for a in args],
        "accepted_before": code0 == 0,
        "accepted_after": code1 == 0,
        "robust_ok": sum(b["passed"] for b in behaviors),
        "robust_runs": sum(b["runs"] for b in behaviors),
        "all_runs_pass": bool(robust)
        and all(b["passed"] == b["runs"] for b in behaviors if b["ability"] in kept),
        "behaviors": {
            b["behavior"]: [b["passed"], b["runs"], b["ability"] in kept] for b in behaviors
        },
        "failures": {
            b["behavior"]: [f"seed {f['seed']}: {f['why']}" for f in b["failures"]]
            for b in behaviors
            if b["failures"]
        },
        "dropped": sorted(((rec1 or {}).get("verified") or {}).get("dropped", {})),
        "refusal_before": why0.splitlines()[-1] if code0 else "",
        "refusal": why.splitlines()[-1] if code1 else "",
    }


def noslip() -> None:
    """Compile every MuJoCo model of this process with the no-slip solver (module
    docstring)."""
    import export.mjcf

    load = export.mjcf.load_mjcf

    def patched(xml: str, *args, **kwargs):
        xml = xml.replace("<option ", '<option noslip_iterations="10" ', 1)
        return load(xml, *args, **kwargs)

    export.mjcf.load_mjcf = patched


def grid(k: int = 8, jsonl: str | None = None, only: set[str] | None = None) -> list[str]:
    import synth.verification.loop

    synth.verification.loop.best_value = lambda *a, **kw: None  # no hint search
    rows = []
    sink = open(jsonl, "w") if jsonl else None  # noqa: SIM115
    for variant in VARIANTS:
        for robot_type, argv in TYPES.items():
            if only and robot_type not in only:
                continue
            r = row(robot_type, [*argv, *variant], k)
            rows.append(r)
            if sink:
                sink.write(json.dumps(r) + "\n")
                sink.flush()
    if sink:
        sink.close()
    return summarise(rows, k)


def summarise(rows: list[dict], k: int) -> list[str]:
    per: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        per[r["type"]].append(r)
    lines = [f"Legged robust grid, K = {k}: accepted nominal -> robust, perturbed runs passing"]
    for t, rs in per.items():
        failing = sorted({b for r in rs for b in r["failures"]})
        lines.append(
            f"  {t:<16} accepted {sum(r['accepted_before'] for r in rs)}/{len(rs)} -> "
            f"{sum(r['accepted_after'] for r in rs)}/{len(rs)}; perturbed "
            f"{sum(r['robust_ok'] for r in rs)}/{sum(r['robust_runs'] for r in rs)}"
            + (f"; failing runs in {', '.join(failing)}" if failing else "")
        )
    before = sum(r["accepted_before"] for r in rows)
    accepted = [r for r in rows if r["accepted_after"]]
    lines.append(
        f"  all: accepted {before} -> {len(accepted)} of {len(rows)}; perturbed "
        f"{sum(r['robust_ok'] for r in rows)}/{sum(r['robust_runs'] for r in rows)}; accepted "
        f"designs passing every perturbed run they keep: "
        f"{sum(r['all_runs_pass'] for r in accepted)}/{len(accepted)}"
    )
    return lines


if __name__ == "__main__":
    args = sys.argv[1:]
    path = only = None
    if "--jsonl" in args:
        i = args.index("--jsonl")
        path = args[i + 1]
        del args[i : i + 2]
    if "--summary" in args:  # summarise a JSONL file written before
        i = args.index("--summary")
        rows = [json.loads(x) for x in Path(args[i + 1]).read_text().splitlines() if x.strip()]
        print("\n".join(summarise(rows, int(args[0]) if args[0:1] != ["--summary"] else 8)))
        sys.exit(0)
    if "--noslip" in args:
        args.remove("--noslip")
        noslip()
    if "--only" in args:
        i = args.index("--only")
        only = set(args[i + 1].split(","))
        del args[i : i + 2]
    print("\n".join(grid(int(args[0]) if args else 8, path, only)))
