"""Issue 20: part counts are transitive through part-of (asp/capability.lp, asp/parts.lp).

Table tests in the style of tests/adron/test_encodings.py: case -> tiny ontology -> query -> the
exact answer sets. Each case is built to fail one rule: counting direct parts only, summing
the joints of separate parts into one chain, entering a part that plays a role of its own,
merging two paths that give the same number, counting a part twice. Then the issue's
mobile manipulator on the command line, and the shipped types' abilities unchanged.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from adron.kb import KnowledgeBase
from adron.kif import parse
from adron.translate import translate
from synth.reasoning.solver import Query, Reasoner

# The upper vocabulary the encodings reason with ("ActuatorModule" makes Servo a joint).
UPPER = """
(subclass StructuralRobotPart Device) (subclass Module Artifact)
(subclass ActiveModule Module) (subclass PassiveModule Module)
(subclass AttachableModule Module) (subclass ActuatorModule ActiveModule)
(subclass EndEffectorActuator ActuatorModule)
(subclass Servo ActuatorModule) (subclass Link PassiveModule)
(subclass GripServo Servo) (subclass GripServo EndEffectorActuator)
(subclass Leg StructuralRobotPart) (subclass Arm StructuralRobotPart)
(subclass Hip StructuralRobotPart) (subclass Tail StructuralRobotPart)
(subclass Segment StructuralRobotPart) (subclass Chassis StructuralRobotPart)
(subclass Gripper StructuralRobotPart)
(subclass RobotAction Process)
(subrelation robotPart part)
(subclass BaseConfiguration Class)
"""


def axiom(cls: str, parts: dict[str, int], rel: str = "robotPart") -> str:
    """``cls`` has ``n`` parts of each kind (``rel``: robotPart of a robot, part of a part)."""
    names, lits = [], []
    for kind, n in parts.items():
        for i in range(n):
            v = f"?{kind}{i}"
            names.append(v)
            lits += [f"(instance {v} {kind})", f"({rel} {v} ?X)"]
    return f"(=> (instance ?X {cls}) (exists ({' '.join(names)}) (and {' '.join(lits)})))\n"


def part(cls: str, parts: dict[str, int]) -> str:
    return axiom(cls, parts, "part")


def needs(action: str, kind: str, n: int) -> str:
    """An action with its short name (the class name) that needs ``n`` parts of ``kind``."""
    return (
        f'(subclass {action} RobotAction) (abilityName {action} "{action}") '
        f"(requiredPartCount {action} {kind} {n})\n"
    )


def robot(cls: str, parts: dict[str, int], parent: str = "Robot", base: bool = True) -> str:
    b = f"(instance {cls} BaseConfiguration)" if base else ""
    return f"(subclass {cls} {parent}) {b}\n{axiom(cls, parts)}"


def reasoner(text: str) -> Reasoner:
    tr = translate(parse(UPPER + text, "case.kif"))
    assert not tr.untranslated, tr.untranslated
    return Reasoner(KnowledgeBase(("case.kif",), tr, (), ()))


def fs(*models: set[str]) -> frozenset[frozenset[str]]:
    return frozenset(frozenset(m) for m in models)


def able(robot: str, *actions: str) -> set[str]:
    """``robot``'s abilities as designed (has_ability) and as declared (declared: the
    capability rules, no growth): both count parts inside parts alike."""
    return {f'{p}("{robot}","{a}")' for a in actions for p in ("has_ability", "declared")}


# Walk needs two legs (legs are parts an action requires), Grasp a gripper, Position three
# joints and Orient six (joints: Servo is an ActuatorModule).
ACTIONS = (
    needs("Walk", "Leg", 2)
    + needs("Grasp", "Gripper", 1)
    + needs("Position", "Servo", 3)
    + needs("Orient", "Servo", 6)
    + part("Gripper", {"GripServo": 1})
)

HD = {"has_ability", "declared"}

CASES = [
    (
        "the joints of an arm part give the robot positioning",
        ACTIONS + part("Arm", {"Servo": 3, "Link": 3}) + robot("Mobile", {"Arm": 1, "Gripper": 1}),
        Query(requests=("Position", "Grasp")),
        {"chosen", *HD},
        fs({'chosen("Mobile")'} | able("Mobile", "Position", "Grasp")),
    ),
    (
        "parts nested two levels deep count with the products of the counts",
        ACTIONS
        + part("Segment", {"Servo": 3})
        + part("Arm", {"Segment": 2})
        + robot("Mobile", {"Arm": 1}),
        Query(requests=("Orient",)),
        {"chosen", *HD},
        fs({'chosen("Mobile")'} | able("Mobile", "Position", "Orient")),
    ),
    (
        "the joints of one part's parts are its chain (two routes, the same number)",
        ACTIONS
        + part("Hip", {"Servo": 2})
        + part("Tail", {"Servo": 2})
        + part("Arm", {"Hip": 1, "Tail": 1})
        + robot("Mobile", {"Arm": 1}),
        Query(),
        HD,
        fs(able("Mobile", "Position")),
    ),
    (
        "two two-joint arms are not a three-joint chain",
        ACTIONS + part("Arm", {"Servo": 2}) + robot("TwoArms", {"Arm": 2}),
        Query(),
        HD,
        fs(set()),
    ),
    (
        "two three-joint arms position but do not orient (one chain, not their sum)",
        ACTIONS + part("Arm", {"Servo": 3}) + robot("TwoArms", {"Arm": 2}),
        Query(),
        HD,
        fs(able("TwoArms", "Position")),
    ),
    (
        "joints in parts of different kinds are separate chains: the longest counts",
        ACTIONS
        + part("Arm", {"Servo": 2})
        + part("Tail", {"Servo": 1})
        + robot("TwoChains", {"Arm": 1, "Tail": 1}),
        Query(),
        HD,
        fs(set()),
    ),
    (
        "the robot's own joints and those of one part form one chain",
        ACTIONS + part("Arm", {"Servo": 2}) + robot("Turret", {"Servo": 1, "Arm": 2}),
        Query(),
        HD,
        fs(able("Turret", "Position")),
    ),
    (
        "the joints inside a part an action requires are its own (a leg's walk)",
        ACTIONS + part("Leg", {"Servo": 3}) + robot("Quad", {"Leg": 4}),
        Query(),
        HD,
        fs(able("Quad", "Walk")),
    ),
    (
        "a gripper inside an arm part keeps its servo: no joint of the chain",
        ACTIONS + part("Arm", {"Servo": 2, "Gripper": 1}) + robot("Mobile", {"Arm": 1}),
        Query(),
        HD,
        fs(able("Mobile", "Grasp")),
    ),
    (
        "parts of a required kind count at any depth: legs inside parts are legs",
        ACTIONS
        + part("Hip", {"Leg": 1})
        + part("Tail", {"Leg": 1})
        + robot("Odd", {"Hip": 1, "Tail": 1}),
        Query(),
        HD,
        fs(able("Odd", "Walk")),
    ),
    (
        "two paths that give the same number are two sets of parts (not merged)",
        ACTIONS
        + needs("Trot", "Leg", 4)
        + part("Hip", {"Leg": 2})
        + part("Tail", {"Leg": 2})
        + part("Chassis", {"Hip": 1, "Tail": 1})
        + robot("Odd", {"Chassis": 1}),
        Query(),
        HD,
        fs(able("Odd", "Walk", "Trot")),
    ),
    (
        "a part and the parts of its kind inside it are counted once each",
        ACTIONS
        + needs("Trot", "Leg", 4)
        + needs("Crawl", "Leg", 5)
        + "(subclass BigLeg Leg)\n"
        + part("BigLeg", {"Leg": 1})
        + robot("Odd", {"BigLeg": 2}),
        Query(),
        HD,
        fs(able("Odd", "Walk", "Trot")),
    ),
    (
        "a part declared by the robot and its ancestor is one part, not two",
        ACTIONS
        + needs("Trot", "Leg", 4)
        + part("Hip", {"Leg": 2})
        + robot("Bipedal", {"Hip": 1}, base=False)
        + robot("Biped", {"Hip": 1}, parent="Bipedal"),
        Query(),
        HD,
        fs(able("Biped", "Walk")),
    ),
    (
        "an extensible part grows the parts inside it, to enough for the need",
        ACTIONS
        + needs("Rough", "Leg", 5)
        + part("Segment", {"Leg": 2})
        + robot("Centipede", {"Segment": 1})
        + "(extensiblePart Centipede Segment)",
        Query(requests=("Rough",)),
        {"chosen", "structural", "has_ability", "declared", "potential"},
        fs(
            {
                'chosen("Centipede")',
                'structural("Centipede","Segment",3)',
                'has_ability("Centipede","Walk")',
                'has_ability("Centipede","Rough")',
                'declared("Centipede","Walk")',
                'potential("Centipede","Walk")',
                'potential("Centipede","Rough")',
            }
        ),
    ),
    (
        "an extensible part does not grow a chain: separate parts are separate chains",
        ACTIONS
        + part("Segment", {"Servo": 1})
        + robot("Snake", {"Segment": 3})
        + "(extensiblePart Snake Segment)",
        Query(requests=("Position",)),
        {"chosen"},
        fs(),
    ),
]


@pytest.mark.parametrize(
    ("case", "kif", "query", "preds", "expected"), CASES, ids=[c[0] for c in CASES]
)
def test_parts_inside_parts(case: str, kif: str, query: Query, preds: set[str], expected) -> None:
    assert reasoner(kif).answer_sets(query, preds) == expected


@pytest.mark.parametrize(
    ("kif", "focus", "expected"),
    [
        (
            part("Arm", {"Servo": 3}) + robot("Mobile", {"Arm": 1, "Gripper": 1}),
            "Mobile",
            {'reason("Mobile","Position","Servo",3,3)', 'reason("Mobile","Grasp","Gripper",1,1)'},
        ),
        (
            part("Hip", {"Leg": 2}) + robot("Odd", {"Hip": 1}),
            "Odd",
            {'reason("Odd","Walk","Leg",2,2)'},
        ),
    ],
    ids=["nested joints", "nested legs"],
)
def test_reason_names_the_nested_parts(kif: str, focus: str, expected: set[str]) -> None:
    """explain's reason/5: the parts inside parts are what gives the robot its abilities."""
    assert reasoner(ACTIONS + kif).focused(focus).answer_sets(Query(), {"reason"}) == fs(expected)


MOBILE_MANIPULATOR = """
(subclass ArmPart RobotArm)
(=>
  (instance ?ARM ArmPart)
  (exists (?S1 ?S2 ?S3 ?L1 ?L2 ?L3)
    (and
      (instance ?S1 PositionServomotor) (instance ?S2 PositionServomotor)
      (instance ?S3 PositionServomotor)
      (instance ?L1 LinkModule) (instance ?L2 LinkModule) (instance ?L3 LinkModule)
      (part ?S1 ?ARM) (part ?S2 ?ARM) (part ?S3 ?ARM)
      (part ?L1 ?ARM) (part ?L2 ?ARM) (part ?L3 ?ARM))))
(subclass MobileManipulator WheeledRobot)
(instance MobileManipulator BaseConfiguration)
(=>
  (instance ?ROB MobileManipulator)
  (exists (?W1 ?W2 ?C ?CH ?ARM ?G)
    (and
      (instance ?W1 DriveWheel) (instance ?W2 DriveWheel) (instance ?C CasterWheel)
      (instance ?CH RobotChassis) (instance ?ARM ArmPart) (instance ?G RoboticGripper)
      (robotPart ?W1 ?ROB) (robotPart ?W2 ?ROB) (robotPart ?C ?ROB)
      (robotPart ?CH ?ROB) (robotPart ?ARM ?ROB) (robotPart ?G ?ROB)
      (connectedTo ?ARM ?CH) (connectedTo ?G ?ARM))))
"""


@pytest.fixture
def mobile(tmp_path: Path) -> Path:
    path = tmp_path / "mobile.kif"
    path.write_text(MOBILE_MANIPULATOR, encoding="utf-8")
    return path


def test_mobile_manipulator_drives_and_picks(cli, mobile: Path) -> None:
    """The issue: an arm part's servos count, so driving + pick-and-place is no conflict."""
    r = cli(
        "design", "driving", "pick-and-place", "--ontology", str(mobile), "--conceptual", "--json"
    )
    assert r.code == 0, r.err
    d = json.loads(r.out)
    assert d["status"] == "designed"
    assert d["robot_type"] == "MobileManipulator"
    assert d["candidates"] == ["MobileManipulator"]
    assert set(d["abilities"]) == {"driving", "grasping", "pick-and-place", "positioning"}


def test_mobile_manipulator_explained(cli, mobile: Path) -> None:
    r = cli("explain", "MobileManipulator", "--ontology", str(mobile))
    assert r.code == 0, r.err
    assert "positioning: has 3 PositionServomotor, needs 3" in r.out
    assert "driving: has 2 DriveWheel, needs 2" in r.out


# Every shipped ability's robot types, and every base configuration's abilities, as before
# issue 20: legs, snake modules, wheels and grippers are parts with roles of their own, and
# the humanoid's arms have two joints each (no three-joint chain).
SHIPPED = {
    "balancing": ["HexapodRobot", "HumanoidRobot", "QuadrupedRobot"],
    "circular-path": ["SnakeRobot"],
    "driving": ["DifferentialDriveRobot", "SkidSteerRobot"],
    "grasping": ["HumanoidRobot", "Manipulator3DOF", "Manipulator6DOF"],
    "line-tracking": [
        "CarRobot",
        "DifferentialDriveRobot",
        "HexapodRobot",
        "HumanoidRobot",
        "QuadrupedRobot",
        "SkidSteerRobot",
        "SnakeRobot",
        "TricycleRobot",
    ],
    "obstacle-avoidance": [
        "CarRobot",
        "DifferentialDriveRobot",
        "HexapodRobot",
        "HumanoidRobot",
        "QuadrupedRobot",
        "SkidSteerRobot",
        "SnakeRobot",
        "TricycleRobot",
    ],
    "orienting": ["Manipulator6DOF"],
    "pick-and-place": ["Manipulator3DOF", "Manipulator6DOF"],
    "pointing": [],  # a tool's (RobotTool): no shipped type carries one
    "positioning": ["Manipulator3DOF", "Manipulator6DOF"],
    "rectilinear": ["SnakeRobot"],
    "rolling": ["SnakeRobot"],
    "rotating": ["SnakeRobot"],
    "rough-terrain-walking": ["HexapodRobot"],
    "running": ["HexapodRobot", "HumanoidRobot", "QuadrupedRobot"],
    "sidewinding": ["SnakeRobot"],
    "steered-driving": ["CarRobot", "TricycleRobot"],  # the two steered types' own ability
    "walking": ["HexapodRobot", "HumanoidRobot", "QuadrupedRobot"],
}
DECLARED = {
    "CarRobot": ("RobotSteeredDriving",),
    "DifferentialDriveRobot": ("RobotDriving",),
    "HexapodRobot": ("RobotRoughTerrainWalking", "RobotRunning", "RobotWalking"),
    "HumanoidRobot": ("RobotBalancing", "RobotGrasping", "RobotRunning", "RobotWalking"),
    "Manipulator3DOF": ("RobotGrasping", "RobotPickAndPlace", "RobotPositioning"),
    "Manipulator6DOF": (
        "RobotGrasping",
        "RobotOrienting",
        "RobotPickAndPlace",
        "RobotPositioning",
    ),
    "QuadrupedRobot": ("RobotRunning", "RobotWalking"),
    "SkidSteerRobot": ("RobotDriving",),
    "SnakeRobot": ("RobotLateralRolling",),
    "TricycleRobot": ("RobotSteeredDriving",),
}


def test_shipped_abilities_unchanged(cli) -> None:
    r = cli("abilities", "--json")
    assert r.code == 0, r.err
    assert {a["ability"]: a["robot_types"] for a in json.loads(r.out)} == SHIPPED


def test_shipped_declared_abilities_unchanged(bases: dict) -> None:
    got = {name: (c.declared, c.abilities) for name, c in bases.items()}
    assert got == {name: (a, a) for name, a in DECLARED.items()}
