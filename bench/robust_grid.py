"""Nominal and robust pass rates per robot type (issue 22): each base configuration's
request of ``bench.TYPE_REQUESTS`` and its variants (``VARIANTS``), designed twice in this
process: as ``parmor design`` does by default (nominal verification) and with
``--robustness K``. Per type: requests accepted before and after, behaviours passing on
the nominal model, perturbed runs passing, and why the refused ones were refused. The
refusals' hint search (the largest payload that works) is left out: it only names a value.

    python bench/robust_grid.py [K] [--jsonl FILE] [--arms]

``--arms``: the arms' grid instead (``ARM_KINDS`` x ``ARM_PAYLOADS`` x ``ARM_REACHES``):
the 3-joint arm (a cylinder), the 6-joint arm (an oval) and KIF-only arms of 4, 5 and 7
joints (``tests/kinematics/test_bodyplan.py``'s ``arm_kif``), each payload and reach.
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
    from synth.commands.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main(["design", *argv, "--no-input", "--json"], out, err)
    text = out.getvalue()
    return code, json.loads(text) if text.strip() else None, err.getvalue().strip()


#: The arms' grid (``--arms``): (name, request, KIF arm joints or 0 for a shipped type).
ARM_KINDS = (
    ("Manipulator3DOF", ["pick-and-place", "--param", "object_shape=cylinder"], 0),
    ("Manipulator6DOF", ["pick-and-place", "--param", "object_shape=oval"], 0),
    ("Arm4Joints", ["positioning-4", "--answer", "orienting=no"], 4),
    ("Arm5Joints", ["positioning-5", "--answer", "orienting=no"], 5),
    ("Arm7Joints", ["positioning-7", "--answer", "orienting=yes"], 7),
)
ARM_PAYLOADS = ("0.05kg", "0.1kg", "0.2kg")
ARM_REACHES = ("0.2m", "0.3m")


def arm_requests(folder: Path) -> dict[str, list[list[str]]]:
    """The arms' grid: name -> its requests (the KIF arms' ontologies written in
    ``folder``)."""
    import importlib.util

    where = REPO / "tests" / "kinematics" / "test_bodyplan.py"
    spec = importlib.util.spec_from_file_location("bodyplan", where)
    mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    out: dict[str, list[list[str]]] = {}
    for name, argv, joints in ARM_KINDS:
        extra: list[str] = []
        if joints:
            kif = folder / f"{name}.kif"
            kif.write_text(mod.arm_kif(joints))
            extra = ["--ontology", str(kif)]
        out[name] = [
            [*argv, *extra, "--param", f"payload={m}", "--param", f"reach={r}"]
            for m in ARM_PAYLOADS
            for r in ARM_REACHES
        ]
    return out


def grid(k: int = 8, jsonl: str | None = None, arms: bool = False) -> list[str]:
    import tempfile

    import synth.verification.loop
    from bench import TYPE_REQUESTS

    synth.verification.loop.best_value = lambda *a, **kw: None  # no hint search
    rows = []
    sink = open(jsonl, "w") if jsonl else None  # noqa: SIM115
    tmp = tempfile.TemporaryDirectory()
    if arms:
        requests = arm_requests(Path(tmp.name))
    else:
        requests = {
            t: [[*argv, *variant] for variant in VARIANTS] for t, argv in TYPE_REQUESTS.items()
        }
    for robot_type, variants in requests.items():
        for args in variants:
            params = [args[i + 1].split("=")[0] for i, a in enumerate(args) if a == "--param"]
            if len(params) != len(set(params)):
                continue  # a variant of a parameter the request sets already
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
                "swapped": ((rec1 or {}).get("verified") or {}).get("play", {}).get("swapped", {}),
            }
            rows.append(row)
            if sink:
                sink.write(json.dumps(row) + "\n")
                sink.flush()
    if sink:
        sink.close()
    tmp.cleanup()
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
    arms = "--arms" in args
    args = [a for a in args if a != "--arms"]
    print("\n".join(grid(int(args[0]) if args else 8, path, arms)))
