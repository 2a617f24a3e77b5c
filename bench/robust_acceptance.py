"""Issue 22's acceptance grid: requests across every robot type parmor designs (the shipped
ones and types written in KIF alone, as a user writes them) over their documented ranges,
each designed once as ``parmor design`` does with ``--robustness K`` (default 8). Per
request: accepted or refused and why; for an accepted design, whether every behaviour of
the abilities it keeps passed every perturbed run; for a refusal, whether it names the
breaking perturbation (a robust refusal) or another cause (sizing, the catalog...).

Nominal acceptance is read from the same run: a request refused as "not robust" passed the
nominal verification (the refusal happens after it), one accepted passed it too.

    python bench/robust_acceptance.py [K] [--jobs N] [--jsonl FILE] [--only SUBSTRING] [--fine]

``--fine``: every accepted design's perturbed runs of the behaviours it keeps made again
from its bundle at the model's own time step (``parmor simulate DIR --perturb SEED
--fine``, here all seeds at once), where the verification ran them at the coarse step:
whether the coarse physics decided any of them.

The KIF types are this file's own (like tests/kinematics/test_bodyplan.py's generators, which
they mirror), so that the grid does not depend on the tests folder.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def _kifs() -> dict[str, str]:
    from tests.kinematics.test_bodyplan import HEAVY, MOBILE, arm_kif, legged_kif

    return {
        "arm4": arm_kif(4),
        "arm5": arm_kif(5),
        "arm7": arm_kif(7),
        "pentapod": legged_kif("Pentapod", 5, "five-leg-walking"),
        "heptapod": legged_kif("Heptapod", 7, "seven-leg-walking"),
        "octopod": legged_kif("Octopod", 8, "eight-leg-walking"),
        "heavy": HEAVY,
        "mobile": MOBILE,
        "six-wheels": (REPO / "tests" / "data" / "six_wheel_rover.kif").read_text(),
        "six-wheels-imu": (REPO / "tests" / "data" / "six_wheel_rover_imu.kif").read_text(),
    }


def _pay(*kg: str) -> list[list[str]]:
    return [["--param", f"payload={k}kg"] for k in kg]


#: (label, kif key or None, argv, variants): each variant appended to argv is one request.
REQUESTS: list[tuple[str, str | None, list[str], list[list[str]]]] = [
    ("HexapodRobot", None, ["rough-terrain-walking"], [*_pay("0", "0.1", "0.3"),
        ["--param", "obstacle_height=1cm"], ["--param", "obstacle_height=3cm"]]),
    ("QuadrupedRobot", None, ["walking", "--answer", "grasping=no", "--answer",
        "rough-terrain-walking=no"], [*_pay("0", "0.1", "0.3"), ["--param", "speed=0.03m/s"]]),
    ("HumanoidRobot", None, ["walking", "--answer", "grasping=yes"], _pay("0", "0.1", "0.3")),
    ("HumanoidRobot", None, ["walking", "grasping"], _pay("0", "0.1")),
    ("SnakeRobot", None, ["sidewinding"], _pay("0", "0.1", "0.3")),
    ("SnakeRobot", None, ["sidewinding", "obstacle-avoidance"], [[]]),
    ("DifferentialDriveRobot", None, ["driving"], [*_pay("0", "0.5", "1"),
        ["--param", "speed=0.1m/s"], ["--param", "speed=0.3m/s"]]),
    ("DifferentialDriveRobot", None, ["driving", "line-tracking", "obstacle-avoidance"], [[]]),
    ("SkidSteerRobot", None, ["driving"], _pay("1", "2", "3")),
    ("Manipulator3DOF", None, ["pick-and-place", "--param", "object_shape=cylinder"],
        [*_pay("0.05", "0.1", "0.2"), ["--param", "reach=0.2m"], ["--param", "reach=0.3m"]]),
    ("Manipulator6DOF", None, ["pick-and-place", "--param", "object_shape=oval"],
        [*_pay("0.05", "0.1", "0.2"), ["--param", "reach=0.2m"]]),
    ("steered", None, ["steered-driving"], [*_pay("0.1", "0.5", "1"),
        ["--param", "speed=0.2m/s"]]),
    ("arm4", "arm4", ["positioning-4", "--answer", "orienting=no"], _pay("0.05", "0.1")),
    ("arm5", "arm5", ["positioning-5", "--answer", "orienting=no"], _pay("0.05", "0.1")),
    ("arm7", "arm7", ["positioning-7", "--answer", "orienting=yes"], _pay("0.05", "0.1")),
    ("dof-arms", None, ["pick-and-place", "--param", "object_shape=cylinder"],
        [["--param", "dof=4"], ["--param", "dof=5"]]),
    ("pentapod", "pentapod", ["five-leg-walking"], [*_pay("0", "0.2"),
        ["--param", "obstacle_height=2cm"]]),
    ("heptapod", "heptapod", ["seven-leg-walking"], _pay("0", "0.2")),
    ("octopod", "octopod", ["eight-leg-walking", "--catalog", "dynamixel"], _pay("0", "0.2")),
    ("heavy", "heavy", ["heavy-walking"], _pay("0", "0.2")),
    ("mobile", "mobile", ["driving", "pick-and-place", "--param", "object_shape=cylinder"],
        [*_pay("0.05", "0.1"), ["--param", "speed=0.2m/s"]]),
    ("six-wheels", "six-wheels", ["six-wheel-driving"], _pay("0", "0.5", "1")),
    ("six-wheels-imu", "six-wheels-imu", ["six-wheel-imu-driving"], _pay("0", "0.5", "1")),
]  # fmt: skip


def requests() -> list[tuple[str, str | None, list[str]]]:
    return [(label, kif, [*argv, *v]) for label, kif, argv, vs in REQUESTS for v in vs]


def design(job: tuple) -> dict:
    """One request designed with ``--robustness k``, in-process (no hint search); with
    ``fine``, an accepted design's perturbed runs made again at the model's own step."""
    import synth.verification.loop
    from synth.commands.cli import main

    label, kif, argv, k, *more = job
    fine = bool(more and more[0])
    synth.verification.loop.best_value = lambda *a, **kw: (
        None
    )  # a refusal's hint only names a value
    with tempfile.TemporaryDirectory() as tmp:
        extra = []
        if kif:
            src = Path(tmp) / f"{kif}.kif"
            src.write_text(_kifs()[kif])
            extra = ["--ontology", str(src)]
        out, err = io.StringIO(), io.StringIO()
        folder = Path(tmp) / "bundle"
        extra += ["--out", str(folder)] if fine else []
        code = main(
            ["design", *argv, *extra, "--no-input", "--json", "--robustness", str(k)], out, err
        )
        text = out.getvalue()
        rec = json.loads(text) if code == 0 and text.strip() else {}
        robust = (rec.get("verified") or {}).get("robust") or {}
        kept = set(rec.get("abilities", ()))
        again = _fine(folder, robust, kept) if fine and code == 0 and robust else {}
    why = err.getvalue().strip().splitlines()
    return again | {
        "label": label,
        "argv": argv,
        "robot_type": rec.get("robot_type"),
        "accepted": code == 0,
        "nominal_ok": code == 0 or any("not robust" in line for line in why),
        "all_runs_pass": bool(robust)
        and all(b["passed"] == b["runs"] for b in robust["behaviors"] if b["ability"] in kept),
        "runs_passed": sum(b["passed"] for b in robust.get("behaviors", [])),
        "runs": sum(b["runs"] for b in robust.get("behaviors", [])),
        "dropped": sorted((rec.get("verified") or {}).get("dropped") or {}),
        "refusal": why[-1] if code and why else "",
    }


def _fine(folder: Path, robust: dict, kept: set) -> dict:
    """The recorded perturbed runs of the kept behaviours made again at the model's own
    step: ``fine_runs_passed`` of ``fine_runs`` (none when they ran at it already)."""
    from synth.verification.runs import verify_robust
    from synth.verification.source import Bundle

    table = {key: v for key, v in robust["table"].items() if key != "timestep_s"}
    if table == robust["table"]:
        return {"fine_step": "own"}
    names = [b["behavior"] for b in robust["behaviors"] if b["ability"] in kept]
    again = verify_robust(Bundle.read(folder), int(robust["k"]), table, behaviors=names)
    failed = [
        f"{b.behavior} seed {f.seed}: {', '.join(f.verdict)}"
        for b in again.behaviors
        for f in b.failures
    ]
    return {
        "fine_step": "coarse",
        "fine_runs_passed": sum(b.passed for b in again.behaviors),
        "fine_runs": sum(b.runs for b in again.behaviors),
        "fine_failed": failed,
    }


def grid(
    k: int = 8, jobs: int = 1, jsonl: str | None = None, only: str = "", fine: bool = False
) -> list[str]:
    todo = [(label, kif, argv, k, fine) for label, kif, argv in requests() if only in label]
    rows: list[dict] = []
    pool = ProcessPoolExecutor(jobs) if jobs > 1 else None
    with contextlib.ExitStack() as stack:
        sink = stack.enter_context(open(jsonl, "w")) if jsonl else None  # noqa: SIM115
        if pool is not None:
            stack.enter_context(pool)
        for row in (pool.map if pool is not None else map)(design, todo):
            rows.append(row)
            if sink:
                sink.write(json.dumps(row) + "\n")
                sink.flush()
    return report(rows, k)


def report(rows: list[dict], k: int) -> list[str]:
    per: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        per[r["label"]].append(r)
    lines = [
        f"Robust acceptance grid, K = {k}: {len(rows)} requests",
        f"  {'type':<24} requests  nominal ok  robust ok  perturbed runs passed",
    ]
    for t, rs in per.items():
        lines.append(
            f"  {t:<24} {len(rs):>8}  {sum(r['nominal_ok'] for r in rs):>10}  "
            f"{sum(r['accepted'] for r in rs):>9}  "
            f"{sum(r['runs_passed'] for r in rs)} of {sum(r['runs'] for r in rs)}"
        )
    acc = [r for r in rows if r["accepted"]]
    ok = sum(r["all_runs_pass"] for r in acc)
    lines.append(
        f"  accepted {len(acc)} of {len(rows)}; of them passing every perturbed run: "
        f"{ok} ({100 * ok / max(1, len(acc)):.0f} %)"
    )
    coarse = [r for r in acc if r.get("fine_step") == "coarse"]
    if coarse:
        passed = sum(r["fine_runs_passed"] for r in coarse)
        lines.append(
            f"  at the model's own step: {len(coarse)} accepted designs ran their perturbed "
            f"runs coarse; made again fine, {passed} of {sum(r['fine_runs'] for r in coarse)} "
            "pass"
        )
        for r in coarse:
            for f in r["fine_failed"]:
                lines.append(f"  fine: {r['label']} {' '.join(r['argv'])}: {f}")
    for r in rows:
        if not r["accepted"]:
            lines.append(f"  refused {r['label']} {' '.join(r['argv'])}: {r['refusal'][:300]}")
    return lines


if __name__ == "__main__":
    args = sys.argv[1:]
    fine = "--fine" in args
    args = [a for a in args if a != "--fine"]
    opts = {"--jsonl": None, "--jobs": "1", "--only": ""}
    for key in opts:
        if key in args:
            i = args.index(key)
            opts[key] = args[i + 1]
            del args[i : i + 2]
    print(
        "\n".join(
            grid(
                int(args[0]) if args else 8,
                int(opts["--jobs"] or 1),
                opts["--jsonl"],
                opts["--only"] or "",
                fine,
            )
        )
    )
