"""Knowledge lives in the ontology: edit the .kif text and the designs change, with no
Python change."""

from __future__ import annotations

import re
from pathlib import Path

from adron.kb import builtin_files, load
from synth.reasoning.conceptual import Designer, Request
from synth.reasoning.solver import Reasoner


def edited(
    tmp_path: Path, name: str | None, old: str | re.Pattern = "", new: str = ""
) -> list[Path]:
    """The shipped ontology copied to ``tmp_path``, with one edit in file ``name``."""
    paths = []
    for fname, text in builtin_files():
        if fname == name:
            changed = (
                re.sub(old, new, text) if isinstance(old, re.Pattern) else text.replace(old, new)
            )
            assert changed != text, f"edit of {name} did not apply"
            text = changed
        (tmp_path / fname).write_text(text, encoding="utf-8")
        paths.append(tmp_path / fname)
    return paths


def designer_for(paths: list[Path]) -> Designer:
    kb = load(paths, builtin=False)
    return Designer(kb, Reasoner(kb))


def test_copied_ontology_gives_the_same_designs(tmp_path, designer) -> None:
    copy = designer_for(edited(tmp_path, None))
    req = Request(("walking",), (("grasping", False), ("rough-terrain-walking", True)))
    assert copy.step(req).chosen == designer.step(req).chosen


def test_a_hexapod_with_four_legs_loses_rough_terrain(tmp_path) -> None:
    four = re.compile(r"\(instance \?L5 MultipedLeg\) \(instance \?L6 MultipedLeg\)")
    d = designer_for(edited(tmp_path, "robots.kif", four, ""))
    hexa = d.describe("HexapodRobot")
    assert dict(hexa.parts)["MultipedLeg"] == 4
    assert "RobotRoughTerrainWalking" not in hexa.abilities
    out = d.step(Request(("rough-terrain-walking",)))
    assert out.status == "unsatisfiable" and out.conflict == ("rough-terrain-walking",)


def test_a_gait_minimum_edited_in_kif_changes_the_snake(tmp_path) -> None:
    d = designer_for(
        edited(
            tmp_path,
            "actions.kif",
            "(requiredPartCount RobotSidewinding SnakeModule 6)",
            "(requiredPartCount RobotSidewinding SnakeModule 7)",
        )
    )
    parts = dict(d.step(Request(("sidewinding",))).chosen.parts)
    assert parts == {"SnakeHead": 1, "SnakeModule": 7}


def test_a_users_ontology_adds_an_ability_and_a_robot(tmp_path) -> None:
    mine = tmp_path / "swim.kif"
    mine.write_text(
        """
(subclass Fin LocomotionPart)
(subclass RobotSwimming RobotMotion)
(abilityName RobotSwimming "swimming")
(abilityVerb RobotSwimming "swim")
(requiredPartCount RobotSwimming Fin 2)
(subclass FishRobot Robot)
(instance FishRobot BaseConfiguration)
(=> (instance ?F Fin) (exists (?S) (and (instance ?S PositionServomotor) (part ?S ?F))))
(=> (instance ?R FishRobot)
    (exists (?F1 ?F2) (and (instance ?F1 Fin) (instance ?F2 Fin)
                           (robotPart ?F1 ?R) (robotPart ?F2 ?R))))
""",
        encoding="utf-8",
    )
    kb = load([mine])
    d = Designer(kb, Reasoner(kb))
    assert kb.ability("swimming").question == "Does the robot need to swim?"
    out = d.step(Request(("swimming", "obstacle-avoidance")))
    assert out.status == "designed" and out.chosen.robot_type == "FishRobot"
    assert dict(out.chosen.parts) == {"Fin": 2}
    assert dict(out.chosen.modules)["PositionServomotor"] == 2
    assert dict(out.chosen.modules)["UltrasonicSensorModule"] == 1
