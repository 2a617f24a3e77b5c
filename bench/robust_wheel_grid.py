"""Robust verification of wheeled robots over a grid (issue 22): differential drive,
skid-steer, tricycle, car, the KIF-only steered types of ``tests/gaits/test_steered.py`` and the
KIF mobile manipulator of ``tests/kinematics/test_bodyplan.py``, payload x speed, each request
designed as ``parmor design`` does (nominal verification) and with ``--robustness K``.
Prints per type the requests accepted nominal -> robust and the perturbed runs passed;
``--jsonl FILE`` keeps one row per request (the failures' seeds, criteria and
perturbations). The refusals' hint search is left out. ``--no-stiffer-wheels``: the
sizing loop without its stiffer wheel servos (``synth/verification/wheels.py``), for the
figures before it.

    python bench/robust_wheel_grid.py [K] [--jsonl FILE] [--only TYPE] [--no-stiffer-wheels]
"""

from __future__ import annotations

import json
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def requests(kif_dir: Path) -> list[tuple[str, list[str]]]:
    """(label, design argv) of the grid: 27 requests over the wheeled types."""
    from tests.gaits.test_steered import TYPES
    from tests.kinematics.test_bodyplan import MOBILE

    out: list[tuple[str, list[str]]] = []
    for payload in ("0kg", "0.5kg", "1kg"):
        for speed in ("0.1m/s", "0.3m/s"):
            p = ["--param", f"payload={payload}", "--param", f"speed={speed}"]
            out.append(("driving", ["driving", *p]))
    for payload in ("1.5kg", "2kg"):
        for speed in ("0.1m/s", "0.3m/s"):
            p = ["--param", f"payload={payload}", "--param", f"speed={speed}"]
            out.append(("driving", ["driving", *p]))
    for payload in ("0kg", "0.2kg", "0.5kg", "1kg", "2kg"):
        for speed in ("0.1m/s", "0.3m/s"):
            p = ["--param", f"payload={payload}", "--param", f"speed={speed}"]
            out.append(("steered-driving", ["steered-driving", *p]))
    for case, (kif, ability, *_) in sorted(TYPES.items()):
        src = kif_dir / f"{case}.kif"
        src.write_text(kif)
        for payload in ("0kg", "0.3kg"):
            p = ["--param", f"payload={payload}"]
            out.append((case, [ability, "--ontology", str(src), *p]))
    # tests/kinematics/test_bodyplan.py's KIF mobile manipulator: a differential drive, an arm
    src = kif_dir / "mobile.kif"
    src.write_text(MOBILE)
    for payload in ("0kg", "0.05kg", "0.1kg"):
        p = ["--param", "object_shape=cylinder", "--param", f"payload={payload}"]
        out.append(("mobile", ["driving", "pick-and-place", "--ontology", str(src), *p]))
    return out


def run(
    k: int = 8, jsonl: str | None = None, only: str | None = None, stiffer: bool = True
) -> list[str]:
    from robust_grid import design

    import synth.verification.loop
    import synth.verification.wheels

    synth.verification.loop.best_value = lambda *a, **kw: None  # no hint search
    if not stiffer:  # the loop without the stiffer wheels' answer (the figures before it)
        synth.verification.wheels.wheel_exclusions = lambda *a, **kw: ({}, None)
    rows = []
    sink = open(jsonl, "w") if jsonl else None  # noqa: SIM115
    with tempfile.TemporaryDirectory() as tmp:
        for label, args in requests(Path(tmp)):
            code0, rec0, why0 = design(args)
            rtype = (rec0 or {}).get("robot_type") or label
            if only and only not in (rtype, label):
                continue
            code1, rec1, why1 = design([*args, "--robustness", str(k)])
            nominal = (rec0 or {}).get("verified", {}).get("behaviors", [])
            robust = (rec1 or {}).get("verified", {}).get("robust") or {}
            row = {
                "type": rtype if rec0 else f"{label} (refused)",
                "args": [a if not a.endswith(".kif") else Path(a).name for a in args],
                "accepted_before": code0 == 0,
                "accepted_after": code1 == 0,
                "nominal": {b["behavior"]: b["verdict"] for b in nominal},
                "runs": {
                    b["behavior"]: [b["passed"], b["runs"]] for b in robust.get("behaviors", [])
                },
                "failures": {
                    b["behavior"]: [[f["seed"], f["why"], f["perturbation"]] for f in b["failures"]]
                    for b in robust.get("behaviors", [])
                    if b["failures"]
                },
                "refusal": (why1.splitlines() or [""])[-1] if code1 else "",
                "refusal_nominal": (why0.splitlines() or [""])[-1] if code0 else "",
            }
            rows.append(row)
            if sink:
                sink.write(json.dumps(row) + "\n")
                sink.flush()
    if sink:
        sink.close()
    per: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        per[r["type"]].append(r)
    lines = [f"Wheeled robust grid, K = {k}: accepted nominal -> robust, perturbed runs passed"]
    for t, rs in per.items():
        passed = sum(p for r in rs for p, _ in r["runs"].values())
        total = sum(n for r in rs for _, n in r["runs"].values())
        lines.append(
            f"  {t:<28} {len(rs):2d} requests: accepted {sum(r['accepted_before'] for r in rs)} "
            f"-> {sum(r['accepted_after'] for r in rs)}; perturbed runs {passed} of {total}"
        )
    before = sum(r["accepted_before"] for r in rows)
    after = sum(r["accepted_after"] for r in rows)
    lines.append(f"  all: {len(rows)} requests, accepted {before} -> {after}")
    return lines


if __name__ == "__main__":
    args = sys.argv[1:]
    path = only = None
    for flag in ("--jsonl", "--only"):
        if flag in args:
            i = args.index(flag)
            val = args[i + 1]
            del args[i : i + 2]
            if flag == "--jsonl":
                path = val
            else:
                only = val
    stiffer = "--no-stiffer-wheels" not in args
    args = [a for a in args if a != "--no-stiffer-wheels"]
    print("\n".join(run(int(args[0]) if args else 8, path, only, stiffer)))
