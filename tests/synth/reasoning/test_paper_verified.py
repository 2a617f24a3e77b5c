"""The paper's cases design and keep every promise in simulation (issue 8's acceptance).

Each request is designed as ``parmor design --no-input`` would, with the verification
loop: every listed behaviour simulated in MuJoCo and judged on its outcome. The record must
be accepted, every behaviour ``ok``, and every listed ability (but sensing ones) simulated.
"""

from __future__ import annotations

import pytest

from synth.pipeline import StructureOptions, run
from synth.reasoning.conceptual import Request

CASES = {
    # Fig. 8: the canning cell's two workspaces, 150 g cans
    "fig8-small-arm": (
        ("pick-and-place",),
        (),
        (("object_shape", "cylinder"), ("reach", "16cm"), ("payload", "150g")),
    ),
    "fig8-large-arm": (
        ("pick-and-place",),
        (),
        (("object_shape", "cylinder"), ("reach", "32cm"), ("payload", "150g")),
    ),
    "oval-cans-6dof": (("pick-and-place",), (), (("object_shape", "oval"),)),
    "walking-humanoid": (("walking",), (("grasping", True),), ()),
    "hexapod": (("rough-terrain-walking",), (), ()),
    "snake-m3": (("rolling",), (), ()),
    "snake-m5": (("rectilinear",), (), ()),
    "snake-m6": (("sidewinding",), (), ()),
    "snake-m8": (("rotating",), (), ()),
    "snake-m14": (("circular-path",), (), ()),
    "snake-rolling-circular-path": (("rolling", "circular-path"), (), ()),
    "differential-drive": (("driving",), (), ()),
    "skid-steer-2kg": (("driving",), (), (("payload", "2kg"), ("speed", "0.2m/s"))),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_papers_case_designs_and_passes_in_simulation(designer, case) -> None:
    abilities, answers, params = CASES[case]
    req = Request(abilities, answers, params)
    out = run(designer, req, StructureOptions())
    assert out.infeasible is None, out.infeasible
    rec = out.record(designer)
    assert rec["status"] == "designed"
    v = rec["verified"]
    failed = {b["behavior"]: b["verdict"] for b in v["behaviors"] if b["verdict"] != "ok"}
    assert not failed and not v["dropped"], (failed, v["dropped"])
    simulated = {b["ability"] for b in v["behaviors"]}
    assert set(rec["abilities"]) - simulated == set(v["not_simulated"]) == set()
    assert set(abilities) <= set(rec["abilities"])
