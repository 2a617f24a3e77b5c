"""The paper's cases (section 4.1, Procedure 1; section 4.3.2; section 6), end to end
through the Designer on the shipped ADROn ontology."""

from __future__ import annotations

import pytest

from synth.reasoning.conceptual import Request


def design(designer, *abilities: str, answers=(), params=()):
    return designer.step(Request(tuple(abilities), tuple(answers), tuple(params)))


def test_walking_gives_three_candidates_and_asks_about_grasping(designer) -> None:
    d = design(designer, "walking")
    assert d.status == "ambiguous"
    assert {c.robot_type for c in d.candidates} == {
        "HumanoidRobot",
        "QuadrupedRobot",
        "HexapodRobot",
    }
    q = d.questions[-1]
    assert (q.ability, q.text) == ("grasping", "Does the robot need to grasp?")


def test_grasping_yes_gives_a_humanoid_with_inherited_parts(designer) -> None:
    d = design(designer, "walking", answers=[("grasping", True)])
    assert d.status == "designed" and d.chosen.robot_type == "HumanoidRobot"
    parts = dict(d.chosen.parts)
    assert parts["BipedLeg"] == 2  # inherited from BipedalRobot
    # named by both axioms, counted once: HumanoidRobot's HumanoidTorso refines
    # BipedalRobot's RobotTrunk
    assert parts["HumanoidTorso"] == 1 and "RobotTrunk" not in parts
    assert parts["HumanoidArm"] == 2 and parts["RoboticGripper"] == 2
    assert d.chosen.dof <= 19  # the paper's largest robot: 19 DOF
    assert {"walking", "grasping"} <= {designer.short(a) for a in d.chosen.abilities}


def test_grasping_no_then_rough_terrain_separates_quadruped_and_hexapod(designer) -> None:
    d = design(designer, "walking", answers=[("grasping", False)])
    assert {c.robot_type for c in d.candidates} == {"QuadrupedRobot", "HexapodRobot"}
    assert d.questions[-1].ability == "rough-terrain-walking"
    yes = design(
        designer, "walking", answers=[("grasping", False), ("rough-terrain-walking", True)]
    )
    no = design(
        designer, "walking", answers=[("grasping", False), ("rough-terrain-walking", False)]
    )
    assert yes.chosen.robot_type == "HexapodRobot"
    assert dict(yes.chosen.parts)["MultipedLeg"] == 6
    assert no.chosen.robot_type == "QuadrupedRobot"


@pytest.mark.parametrize(
    ("gaits", "modules"),
    [
        (["rolling"], 3),
        (["rectilinear"], 5),
        (["sidewinding"], 6),
        (["rotating"], 8),
        (["circular-path"], 14),
        (["rolling", "sidewinding"], 6),
        (["rotating", "rectilinear"], 8),
    ],
)
def test_snake_module_count_is_the_largest_minimum_of_its_gaits(designer, gaits, modules):
    d = design(designer, *gaits)
    assert d.chosen.robot_type == "SnakeRobot"
    assert dict(d.chosen.parts) == {"SnakeHead": 1, "SnakeModule": modules}
    assert d.chosen.dof == modules


def test_snake_with_six_modules_can_roll_move_forward_and_sideways(designer) -> None:
    d = design(designer, "sidewinding")
    assert {designer.short(a) for a in d.chosen.abilities} >= {
        "rolling",
        "rectilinear",
        "sidewinding",
    }
    assert "rotating" not in {designer.short(a) for a in d.chosen.abilities}


@pytest.mark.parametrize(
    ("shape", "robot", "gripper"),
    [
        ("cylinder", "Manipulator3DOF", "VGrooveGripper"),
        ("sphere", "Manipulator3DOF", "ThreeFingerGripper"),
        ("oval", "Manipulator6DOF", "CompliantJawGripper"),
        ("box", "Manipulator6DOF", "ParallelJawGripper"),
    ],
)
def test_pick_and_place_follows_the_object_shape(designer, shape, robot, gripper) -> None:
    d = design(designer, "pick-and-place", params=[("object_shape", shape)])
    assert d.status == "designed" and d.chosen.robot_type == robot
    assert dict(d.chosen.parts) == {"ArmBase": 1, gripper: 1}


def test_pick_and_place_without_a_shape_asks_about_orienting(designer) -> None:
    d = design(designer, "pick-and-place")
    assert {c.robot_type for c in d.candidates} == {"Manipulator3DOF", "Manipulator6DOF"}
    assert d.questions[-1].ability == "orienting"


def test_sensing_abilities_add_sensor_modules(designer) -> None:
    d = design(designer, "rolling", "line-tracking", "obstacle-avoidance")
    mods = dict(d.chosen.modules)
    assert mods["InfraredSensorModule"] == 2 and mods["UltrasonicSensorModule"] == 1
    d = design(designer, "walking", "balancing", answers=[("grasping", True)])
    assert dict(d.chosen.modules)["IMUSensorModule"] == 1


def test_conflict_names_the_smallest_conflicting_set(designer) -> None:
    d = design(designer, "rolling", "grasping")
    assert d.status == "unsatisfiable" and d.conflict == ("rolling", "grasping")
    d = design(designer, "line-tracking", "rolling", "obstacle-avoidance", "grasping")
    assert d.conflict == ("rolling", "grasping")
    d = design(designer, "walking", answers=[("walking", False)])
    assert d.conflict == ("walking", "walking=no")
    d = design(
        designer,
        "pick-and-place",
        answers=[("orienting", False)],
        params=[("object_shape", "oval")],
    )
    assert d.conflict == ("orienting=no", "object_shape=oval")


def test_look_alikes_are_chosen_by_the_documented_preference(designer) -> None:
    d = design(designer, "driving")
    assert d.status == "designed" and d.chosen_by == "preference"
    assert d.chosen.robot_type == "DifferentialDriveRobot"
    assert "fewest active modules" in d.note and "SkidSteerRobot" in d.note


def test_every_base_configuration_stays_within_the_bus_limit(designer) -> None:
    from synth.reasoning.solver import Query

    sol = designer.reasoner.solve(Query())
    assert len(sol.candidates) == 10  # the paper's eight and the two steered ones
    for c in sol.candidates:
        assert c.active_total <= c.module_limit == 24
