"""Nominal and robust pass rates per robot type (issue 22): each base configuration's
request of ``bench.TYPE_REQUESTS`` and its variants (``VARIANTS``), designed twice in this
process: as ``parmor design`` does by default (nominal verification) and with
``--robustness K``. Per type: requests accepted before and after, behaviours passing on
the nominal model, perturbed runs passing, and why the refused ones were refused. The
refusals' hint search (the largest payload that works) is left out: it only names a value.

    python bench/robust_grid.py [K] [--jsonl FILE]
"""

from __future__ import annotations

import io
import json
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

#: Parameter variants of each type's request (none: its defaults).
VARIANTS = ((), ("--param", "payload=0kg"), ("--param", "payload=0.3kg"))


def design(argv: list[str]) -> tuple[int, dict | None, str]:
    from synth.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main(["design", *argv, "--no-input", "--json"], out, err)
    text = out.getvalue()
    return code, json.loads(text) if text.strip() else None, err.getvalue().strip()


def grid(k: int = 8, jsonl: str | None = None) -> list[str]:
    import synth.verify
    from bench import TYPE_REQUESTS

    synth.verify.best_value = lambda *a, **kw: None  # no hint search
    rows = []
    sink = open(jsonl, "w") if jsonl else None  # noqa: SIM115
    for robot_type, argv in TYPE_REQUESTS.items():
        for variant in VARIANTS:
            args = [a for a in argv]
            if variant and "--param" in args and variant[1].split("=")[0] in " ".join(args):
                continue  # the request sets it already
            args += list(variant)
            code0, rec0, _ = design(args)
            code1, rec1, why = design([*args, "--robustness", str(k)])
            nominal = (rec0 or {}).get("verified", {}).get("behaviors", [])
            robust = (rec1 or {}).get("verified", {}).get("robust") or {}
            kept = set((rec1 or {}).get("abilities", ()))  # dropped ones are not claimed
            row = {
                "type": robot_type,
                "args": args,
                "accepted_before": code0 == 0,
                "accepted_after": code1 == 0,
                "nominal_ok": sum(b["verdict"] == "ok" for b in nominal),
                "nominal_runs": len(nominal),
                "robust_ok": sum(b["passed"] for b in robust.get("behaviors", [])),
                "robust_runs": sum(b["runs"] for b in robust.get("behaviors", [])),
                "all_runs_pass": bool(robust)
                and all(
                    b["passed"] == b["runs"]
                    for b in robust.get("behaviors", [])
                    if b["ability"] in kept
                ),
                "behaviors": {
                    b["behavior"]: [b["passed"], b["runs"], b["ability"] in kept]
                    for b in robust.get("behaviors", [])
                },
                "dropped": sorted(((rec1 or {}).get("verified") or {}).get("dropped", {})),
                "refusal": why.splitlines()[-1] if code1 else "",
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
    lines = [
        f"Robust verification grid, K = {k}: accepted before (nominal) and after (robust), "
        "behaviours passing nominally, perturbed runs passing"
    ]
    for t, rs in per.items():
        lines.append(
            f"  {t:<24} accepted {sum(r['accepted_before'] for r in rs)}/{len(rs)} -> "
            f"{sum(r['accepted_after'] for r in rs)}/{len(rs)}; nominal "
            f"{sum(r['nominal_ok'] for r in rs)}/{sum(r['nominal_runs'] for r in rs)}; "
            f"perturbed {sum(r['robust_ok'] for r in rs)}/{sum(r['robust_runs'] for r in rs)}"
        )
    accepted = [r for r in rows if r["accepted_after"]]
    lines.append(
        f"  accepted after: {len(accepted)} of {len(rows)}; of them passing every perturbed "
        f"run of the abilities they keep: {sum(r['all_runs_pass'] for r in accepted)}"
    )
    return lines


if __name__ == "__main__":
    args = sys.argv[1:]
    path = None
    if "--jsonl" in args:
        i = args.index("--jsonl")
        path = args[i + 1]
        del args[i : i + 2]
    print("\n".join(grid(int(args[0]) if args else 8, path)))
