"""``make bench``: the figures of the performance budget (docs/architecture.md), printed.

Timings are wall-clock, best (and median) of several runs, on whatever machine runs
them; nothing here is asserted. Sections that need ``../shared`` say so and skip.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from bench_assign import bench_assign  # noqa: E402
from bench_chain import bench_chain  # noqa: E402
from bench_links import bench_chain_links, bench_links  # noqa: E402
from bench_onto import bench_onto  # noqa: E402
from bench_parse import bench_parse  # noqa: E402
from bench_ray import bench_ray  # noqa: E402
from bench_rnea import bench_rnea  # noqa: E402
from bench_robust import bench_robust  # noqa: E402
from bench_sim import bench_sim  # noqa: E402
from bench_simspeed import bench_simspeed  # noqa: E402
from bench_sizing import bench_sizing  # noqa: E402
from bench_startup import bench_startup  # noqa: E402
from bench_stl import bench_stl  # noqa: E402

from adron.kb import load  # noqa: E402
from synth.reasoning.conceptual import Designer, Request  # noqa: E402
from synth.reasoning.solver import Query, Reasoner  # noqa: E402

SUMO = REPO.parent / "shared" / "kif" / "sumo"


def timed(fn, runs: int) -> tuple[float, float]:
    """(best, median) wall time in milliseconds over ``runs`` calls."""
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000)
    return min(times), statistics.median(times)


def mark(ok: bool) -> str:
    return "ok  " if ok else "MISS"


def bench_translation() -> list[str]:
    best, med = timed(load, 20)
    kb = load()
    t = kb.translation
    return [
        "ADRON load = parse + translate (best/median of 20)",
        f"  {t.forms} forms -> {t.facts} facts, {t.rules} rules, {t.axioms} axioms: "
        f"{best:.1f} / {med:.1f} ms",
    ]


def bench_queries() -> list[str]:
    """Ground + solve of one design query per base configuration.

    Each query asks for every ability the robot type has by its declared parts (read from
    the ontology through ``explain``), so the type is among the candidates.
    """
    kb = load()
    designer = Designer(kb, Reasoner(kb))
    lines = ["ground + solve of a design query per robot type (best/median of 20; target < 20 ms)"]
    for cand in designer.reasoner.solve(Query()).candidates:
        abilities = tuple(designer.short(a) for a in designer.describe(cand.robot_type).abilities)
        req = Request(abilities)

        def run(req: Request = req) -> None:
            d = Designer(kb, Reasoner(kb))
            d.step(req)

        best, med = timed(run, 20)
        got = Designer(kb, Reasoner(kb)).step(req)
        outcome = got.chosen.robot_type if got.chosen else got.status
        lines.append(
            f"  {mark(best < 20)} {cand.robot_type:<24} {best:6.1f} / {med:6.1f} ms  "
            f"({len(abilities)} abilities -> {outcome})"
        )
    return lines


def bench_structures() -> list[str]:
    """The whole structural design (co-design loop) of each base configuration."""
    from adron.catalog import load_catalog
    from synth.sizing.structure import design_structure

    kb = load()
    designer = Designer(kb, Reasoner(kb))
    catalog = load_catalog()
    lines = ["structure generator with default parameters (best/median of 5)"]
    for cand in designer.reasoner.solve(Query()).candidates:
        best, med = timed(lambda c=cand: design_structure(kb, c, catalog, {}), 5)
        s = design_structure(kb, cand, catalog, {})
        lines.append(
            f"  {cand.robot_type:<24} {best:7.1f} / {med:7.1f} ms  ({s.iterations} "
            f"iterations, {s.mass_kg:.3f} kg, {len(s.joints)} joints, "
            f"{len(s.links)} link designs)"
        )
    return lines


def bench_process() -> list[str]:
    """Whole-process time of the command line (python -m synth.commands.cli), best of 10."""
    lines = ["whole process (best/median of 10; target: conceptual design < 500 ms)"]
    for argv in (
        ["--help"],
        ["design", "walking", "--answer", "grasping=yes", "--json", "--conceptual"],
        ["design", "walking", "--answer", "grasping=yes", "--json"],
    ):
        cmd = [sys.executable, "-m", "synth.commands.cli", *argv]

        def run(cmd: list[str] = cmd) -> None:
            subprocess.run(cmd, cwd=REPO, check=True, capture_output=True)

        best, med = timed(run, 10)
        target = "" if "--json" in argv and "--conceptual" not in argv else mark(best < 500)
        lines.append(f"  {target:<4} parmor {' '.join(argv):<58} {best:6.1f} / {med:6.1f} ms")
    return lines


#: One request per base configuration (as in studies/ and the README's examples).
TYPE_REQUESTS = {
    "HexapodRobot": ["rough-terrain-walking"],
    "QuadrupedRobot": [
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=no",
    ],
    "HumanoidRobot": ["walking", "--answer", "grasping=yes"],
    "SnakeRobot": ["sidewinding"],
    "DifferentialDriveRobot": ["driving"],
    "SkidSteerRobot": ["driving", "--param", "payload=2kg"],
    "Manipulator3DOF": ["pick-and-place", "--param", "object_shape=cylinder"],
    "Manipulator6DOF": ["pick-and-place", "--param", "object_shape=oval"],
}


def bench_verified() -> list[str]:
    """``parmor design`` per type as a process, three ways in the same run: without
    simulation (``--no-verify``), verified on the nominal model (``--robustness 0``) and
    with the default robust verification (K = 8, the environment's PARMOR_ROBUSTNESS
    removed); best of 2 for the first two, one run of the third (it is the long one)."""
    lines = [
        "design per type as a process: --no-verify | --robustness 0 | default (K = 8; "
        "target < 10 s), and the default's ratio to --no-verify"
    ]
    env = {k: v for k, v in os.environ.items() if k != "PARMOR_ROBUSTNESS"}
    for name, argv in TYPE_REQUESTS.items():
        times = []
        for extra, runs in ((["--no-verify"], 2), (["--robustness", "0"], 2), ([], 1)):
            cmd = [
                sys.executable,
                "-m",
                "synth.commands.cli",
                "design",
                *argv,
                "--no-input",
                "--json",
            ]

            def run(cmd: list[str] = cmd + extra) -> None:
                subprocess.run(cmd, cwd=REPO, capture_output=True, env=env)

            times.append(timed(run, runs)[0] / 1000)
        bare, nominal, full = times
        lines.append(
            f"  {mark(full < 10):<4} {name:<24} {bare:6.2f} s | {nominal:6.2f} s | "
            f"{full:6.2f} s  ({full / bare:4.1f} x --no-verify)"
        )
        print(lines[-1], flush=True)
    return lines


def main() -> int:
    """Every section in turn, each printed as soon as it is measured (with its own time).
    Sections other than ``bench_verified`` time designs on the nominal model
    (PARMOR_ROBUSTNESS=0, set here for them and their subprocesses): what they measure
    predates robust verification by default, whose cost ``bench_verified`` and
    ``bench_robust`` measure."""
    os.environ["PARMOR_ROBUSTNESS"] = "0"
    sections = [
        (
            "KIF reader",
            lambda: (
                bench_parse(SUMO) if SUMO.is_dir() else [f"KIF reader: {SUMO} is absent, skipped"]
            ),
        ),
        ("translation", bench_translation),
        ("ontology", bench_onto),
        ("chain", bench_chain),
        ("queries", bench_queries),
        ("RNEA", bench_rnea),
        ("links", bench_links),
        ("chain links", bench_chain_links),
        ("structures", bench_structures),
        ("assignment", bench_assign),
        ("sizing", bench_sizing),
        ("STL", bench_stl),
        ("simulation", bench_sim),
        ("simulation speed", bench_simspeed),
        ("process", bench_process),
        ("start-up", bench_startup),
        ("verified designs", bench_verified),
        ("robust verification", bench_robust),
        ("Ray", bench_ray),
    ]
    start = time.perf_counter()
    for title, section in sections:
        print(f"== {title}", flush=True)
        t0 = time.perf_counter()
        lines = section()
        print("\n".join(lines))
        print(
            f"   ({time.perf_counter() - t0:.1f} s; {time.perf_counter() - start:.0f} s so far)\n",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
