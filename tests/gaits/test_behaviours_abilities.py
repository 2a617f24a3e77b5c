"""Every listed ability has a behaviour and every behaviour an ability (issue 8).

For one design of each base configuration: each ability the design lists is realised by a
behaviour of its controller (sensing abilities, given by sensor modules, are not among
these designs' abilities), and each behaviour realises an ability the ontology knows.
"""

from __future__ import annotations

import pytest

from gaits import controller_for
from gaits.base import DesignGeometry
from synth.pipeline import StructureOptions, run
from synth.reasoning.conceptual import Request

REQUESTS = {
    "HexapodRobot": Request(("rough-terrain-walking",)),
    "QuadrupedRobot": Request(
        ("walking",), (("grasping", False), ("rough-terrain-walking", False))
    ),
    "HumanoidRobot": Request(("walking",), (("grasping", True),)),
    "SnakeRobot": Request(("circular-path",)),
    "DifferentialDriveRobot": Request(("driving",)),
    "SkidSteerRobot": Request(("driving",), (), (("payload", "2kg"),)),
    "Manipulator3DOF": Request(("pick-and-place",), (), (("object_shape", "cylinder"),)),
    "Manipulator6DOF": Request(("pick-and-place",), (), (("object_shape", "oval"),)),
}


@pytest.mark.parametrize("robot", sorted(REQUESTS))
def test_abilities_and_behaviours_match(designer, robot) -> None:
    out = run(designer, REQUESTS[robot], StructureOptions(verify=False))
    rec = out.record(designer)
    assert rec["robot_type"] == robot
    controller = controller_for(DesignGeometry.from_record(rec))
    assert controller.unbehaved(rec["abilities"]) == []
    known = {designer.short(a) for a in designer.kb.translation.documentation} | set(
        rec["abilities"]
    )
    realised = {s.realises for s in controller.behaviors.values()}
    assert realised <= known, realised - known
    listed = controller.listed(rec["abilities"])
    assert {controller.behaviors[b].realises for b in listed} == set(rec["abilities"])


def test_a_behaviour_outside_the_abilities_is_not_listed(designer) -> None:
    out = run(designer, REQUESTS["HumanoidRobot"], StructureOptions(verify=False))
    rec = out.record(designer)
    # a biped carries an IMU (KIF) and so can balance; the same design without the module
    # (a record of a biped whose ontology gives it none) does not list the behaviour
    assert "balancing" in rec["abilities"]
    rec = {
        **rec,
        "abilities": [a for a in rec["abilities"] if a != "balancing"],
        "modules": [m for m in rec["modules"] if m["kind"] != "IMUSensorModule"],
    }
    controller = controller_for(DesignGeometry.from_record(rec))
    assert "balancing" in controller.behaviors and "balancing" not in rec["abilities"]
    assert "balancing" not in controller.listed(rec["abilities"])
    assert controller.unbehaved([*rec["abilities"], "line-tracking"]) == ["line-tracking"]
