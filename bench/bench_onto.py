"""Ontology size: `parmor design walking --conceptual` as a process with the project ontology
alone (the reference), with SUMO's Merge.kif and Mid-level-ontology.kif as `--ontology`
(target: at most 1.5x the reference, with the knowledge base cached: adron/kb.py; the
first, cold-cache run is printed too), and with 1000 extra robot types or 1000 extra abilities
generated into a temporary folder (target: under 1 s). Best of ``runs`` wall-clock times."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from cli_timing import best_time

REPO = Path(__file__).resolve().parents[1]
SUMO = REPO.parent / "shared" / "kif" / "sumo"

#: the targets of issue 12
SUMO_RATIO = 1.5  # x the project ontology alone
EXTRA_SECONDS = 1.0  # s, 1000 extra robot types (or abilities)
EXTRA = 1000


def extra_types(n: int) -> str:
    """``n`` base configurations below LeggedRobot, each with its own part axiom."""
    out = []
    for i in range(n):
        out.append(
            f"(subclass ExtraRobot{i} LeggedRobot)\n(instance ExtraRobot{i} BaseConfiguration)"
        )
        out.append(
            f"(=> (instance ?R ExtraRobot{i}) (exists (?L1 ?L2 ?T) (and (instance ?L1 RobotLeg)"
            " (instance ?L2 RobotLeg) (instance ?T RobotTrunk) (robotPart ?L1 ?R)"
            " (robotPart ?L2 ?R) (robotPart ?T ?R) (not (equal ?L1 ?L2)))))"
        )
    return "\n".join(out) + "\n"


def extra_abilities(n: int) -> str:
    """``n`` named abilities below RobotWalking, each requiring four legs."""
    out = []
    for i in range(n):
        out.append(
            f'(subclass ExtraAction{i} RobotWalking)\n(abilityName ExtraAction{i} "extra-{i}")\n'
            f'(abilityVerb ExtraAction{i} "do extra {i}")'
        )
        legs = " ".join(f"?L{j}" for j in range(4))
        out.append(
            f"(=> (instance ?A ExtraAction{i}) (exists ({legs}) (and "
            + " ".join(
                f"(instance ?L{j} RobotLeg) (StructuralRequirement ?A ?L{j})" for j in range(4)
            )
            + ")))"
        )
    return "\n".join(out) + "\n"


def _time(args: list[str], runs: int, cache: str | None = None) -> float:
    """Best wall-clock time of ``design walking --conceptual`` with ``args``; ``cache``:
    the PARMOR_CACHE folder (a new empty one per run when None: a cold cache)."""
    cmd = ["design", "walking", "--conceptual", "--no-input", *args]
    return best_time(cmd, runs, cache, ok=(0, 3))


def bench_onto(runs: int = 3) -> list[str]:
    lines = [
        f"Ontology size, design walking --conceptual as a process, best of {runs} "
        f"(load {os.getloadavg()[0]:.1f})"
    ]
    ref = _time([], runs)
    lines.append(f"  ref  project ontology alone, cold cache  {ref:6.2f} s")
    with tempfile.TemporaryDirectory(prefix="parmor-bench-cache-") as warm:
        t = _time([], runs, warm)
        lines.append(f"       project ontology alone, cached      {t:6.2f} s  {t / ref:4.1f} x ref")
        if (SUMO / "Merge.kif").is_file():
            merge = ["--ontology", str(SUMO / "Merge.kif")]
            mid = [*merge, "--ontology", str(SUMO / "Mid-level-ontology.kif")]
            for name, args in (("+ Merge.kif", merge), ("+ Merge + Mid-level", mid)):
                cold = _time(args, runs)
                lines.append(
                    f"       {name + ', cold cache':<34} {cold:6.2f} s  {cold / ref:4.1f} x ref"
                )
                t = _time(args, runs, warm)
                mark = "ok  " if t <= SUMO_RATIO * ref else "MISS"
                lines.append(
                    f"  {mark} {name + ', cached':<34} {t:6.2f} s  {t / ref:4.1f} x ref "
                    f"(target <= {SUMO_RATIO} x)"
                )
        else:
            lines.append("  skip SUMO (../shared/kif/sumo is absent)")
    with tempfile.TemporaryDirectory(prefix="parmor-bench-onto-") as tmp:  # cold cache
        for name, text in (("robot types", extra_types), ("abilities", extra_abilities)):
            path = Path(tmp) / f"{name.replace(' ', '-')}.kif"
            path.write_text(text(EXTRA), encoding="utf-8")
            t = _time(["--ontology", str(path)], runs)
            mark = "ok  " if t < EXTRA_SECONDS else "MISS"
            lines.append(
                f"  {mark} {EXTRA} extra {name:<19} {t:6.2f} s  {t / ref:4.1f} x ref "
                f"(target < {EXTRA_SECONDS:g} s)"
            )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_onto()))
