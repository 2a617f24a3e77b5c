"""Simulated seconds per wall-clock second of each base configuration's default design
running one of its behaviours in MuJoCo (target: at least 50x real time)."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def default_bundles(tmp: Path):
    """Each base configuration's default design written as a bundle under ``tmp``:
    yields (robot type, design record, bundle folder, its MuJoCo model, its controller)."""
    from adron.catalog import load_catalog
    from adron.kb import load
    from export.bundle import bundle_files, write_bundle
    from export.record import design_record
    from synth.reasoning.conceptual import Design, Designer, Request
    from synth.reasoning.solver import Query, Reasoner
    from synth.sizing.structure import design_structure
    from synth.verification.runs import controller_for_model
    from synth.verification.source import Bundle

    kb = load()
    designer = Designer(kb, Reasoner(kb))
    catalog = load_catalog()
    for cand in designer.reasoner.solve(Query()).candidates:
        s = design_structure(kb, cand, catalog, {})
        rec = design_record(
            Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
        )
        folder = Path(tmp) / cand.robot_type
        write_bundle(folder, bundle_files(rec, s, catalog))
        model = Bundle(folder=folder).model()
        yield cand.robot_type, rec, folder, model, controller_for_model(rec, model)


def bench_sim(seconds: float = 5.0) -> list[str]:
    from synth.verification.simulate import simulate

    lines = [f"MuJoCo, {seconds:g} simulated s of a default behaviour (target >= 50x real time)"]
    with tempfile.TemporaryDirectory() as tmp:
        for robot_type, rec, _, model, ctl in default_bundles(Path(tmp)):
            names = sorted(set(ctl.behaviors) & set(rec["abilities"])) or sorted(ctl.behaviors)
            traj = ctl.run(names[0])
            t0 = time.perf_counter()
            simulate(model, traj, seconds)
            wall = time.perf_counter() - t0
            ratio = seconds / wall
            mark = "ok  " if ratio >= 50 else "MISS"
            lines.append(
                f"  {mark} {robot_type:<24} {names[0]:<16} {ratio:7.1f}x real time "
                f"({wall * 1000:.0f} ms)"
            )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_sim()))
