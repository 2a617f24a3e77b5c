"""Table tests of the ASP encodings: case -> KIF facts -> query -> the exact answer sets.

Each case is a tiny ontology on its own (no ADROn), so a failure points at one rule.
"""

from __future__ import annotations

import pytest

from adron.kb import KnowledgeBase
from adron.kif import parse
from adron.translate import translate
from synth.reasoning.solver import Query, Reasoner

# The upper vocabulary the encodings reason with, and nothing more.
UPPER = """
(subclass StructuralRobotPart Device) (subclass Module Artifact)
(subclass ActiveModule Module) (subclass PassiveModule Module)
(subclass AttachableModule Module) (subclass ActuatorModule ActiveModule)
(subclass EndEffectorActuator ActuatorModule)
(subclass Servo ActuatorModule) (subclass Link PassiveModule)
(subclass Main ActiveModule)
(subclass Leg StructuralRobotPart) (subclass Arm StructuralRobotPart)
(subclass Trunk StructuralRobotPart) (subclass Gripper StructuralRobotPart)
(subclass VGripper Gripper)
(subclass IR ActiveModule) (subclass IR AttachableModule)
(subclass RobotAction Process)
(subrelation robotPart part)
(subclass BaseConfiguration Class)
"""


def axiom(cls: str, parts: dict[str, int], rel: str = "robotPart") -> str:
    """A part axiom in the paper's style: ``cls`` has ``n`` parts of each kind."""
    names, lits = [], []
    for kind, n in parts.items():
        for i in range(n):
            v = f"?{kind}{i}"
            names.append(v)
            lits += [f"(instance {v} {kind})", f"({rel} {v} ?X)"]
    return f"(=> (instance ?X {cls}) (exists ({' '.join(names)}) (and {' '.join(lits)})))"


def needs(action: str, parts: dict[str, int], name: str | None = None) -> str:
    """An action with a short name and a StructuralRequirement axiom."""
    names, lits = [], []
    for kind, n in parts.items():
        for i in range(n):
            v = f"?{kind}{i}"
            names.append(v)
            lits += [f"(instance {v} {kind})", f"(StructuralRequirement ?A {v})"]
    return (
        f'(subclass {action} RobotAction) (abilityName {action} "{name or action.lower()}")\n'
        f"(=> (instance ?A {action}) (exists ({' '.join(names)}) (and {' '.join(lits)})))"
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


CASES = [
    (
        "every candidate is an answer set",
        robot("Biped", {"Leg": 2}) + robot("Quad", {"Leg": 4}) + needs("Walk", {"Leg": 2}),
        Query(requests=("Walk",)),
        {"chosen"},
        fs({'chosen("Biped")'}, {'chosen("Quad")'}),
    ),
    (
        "a requirement no robot meets is unsatisfiable",
        robot("Biped", {"Leg": 2}) + needs("Climb", {"Leg": 3}),
        Query(requests=("Climb",)),
        {"chosen"},
        fs(),
    ),
    (
        "requirements are inherited and the largest count wins",
        robot("Biped", {"Leg": 2})
        + robot("Hexa", {"Leg": 6})
        + needs("Walk", {"Leg": 2})
        + "(subclass RoughWalk Walk) "
        + needs("RoughWalk", {"Leg": 6}, "rough"),
        Query(requests=("RoughWalk",)),
        {"chosen"},
        fs({'chosen("Hexa")'}),
    ),
    (
        "parts are inherited: the largest count of each kind over the ancestors",
        robot("Bipedal", {"Leg": 2, "Trunk": 1}, base=False)
        + robot("Humanoid", {"Arm": 2, "Trunk": 1}, parent="Bipedal"),
        Query(),
        {"structural"},
        fs(
            {
                'structural("Humanoid","Arm",2)',
                'structural("Humanoid","Leg",2)',
                'structural("Humanoid","Trunk",1)',
            }
        ),
    ),
    (
        "modules inside parts are multiplied out; connectedTo is not a part relation",
        robot("Quad", {"Leg": 4, "Main": 1})
        + axiom("Leg", {"Servo": 3, "Link": 2}, "part")
        + axiom("Leg", {"Servo": 5}, "connectedTo"),
        Query(),
        {"active", "passive", "actuator"},
        fs(
            {
                'active("Quad","Servo",12)',
                'active("Quad","Main",1)',
                'passive("Quad","Link",8)',
                'actuator("Quad","Servo",12)',
            }
        ),
    ),
    (
        "end-effector actuators are not degrees of freedom",
        "(subclass GripServo Servo) (subclass GripServo EndEffectorActuator)"
        + robot("Arm3", {"Servo": 3, "Gripper": 1})
        + axiom("Gripper", {"GripServo": 1}, "part"),
        Query(),
        {"actuator"},
        fs({'actuator("Arm3","Servo",3)'}),
    ),
    (
        "an extensible part grows to the largest minimum of the needed actions",
        robot("Snake", {"Leg": 3})
        + "(extensiblePart Snake Leg)"
        + '(subclass Roll RobotAction) (abilityName Roll "roll") (requiredPartCount Roll Leg 3)'
        + '(subclass Side RobotAction) (abilityName Side "side") (requiredPartCount Side Leg 6)'
        + '(subclass Circ RobotAction) (abilityName Circ "circ") (requiredPartCount Circ Leg 14)',
        Query(requests=("Roll", "Side")),
        {"structural", "has_ability"},
        fs(
            {
                'structural("Snake","Leg",6)',
                'has_ability("Snake","Roll")',
                'has_ability("Snake","Side")',
            }
        ),
    ),
    (
        "attachable modules are added to whichever robot is chosen",
        robot("Cart", {"Trunk": 1}) + needs("Track", {"IR": 2}),
        Query(requests=("Track",)),
        {"active", "has_ability"},
        fs({'active("Cart","IR",2)', 'has_ability("Cart","Track")'}),
    ),
    (
        "answering no drops the robots whose declared parts give the ability",
        robot("Humanoid", {"Leg": 2, "Gripper": 1})
        + robot("Biped", {"Leg": 2})
        + needs("Walk", {"Leg": 2})
        + needs("Grasp", {"Gripper": 1}),
        Query(requests=("Walk",), answers=(("Grasp", False),)),
        {"chosen"},
        fs({'chosen("Biped")'}),
    ),
    (
        "answering yes adds a demand",
        robot("Humanoid", {"Leg": 2, "Gripper": 1})
        + robot("Biped", {"Leg": 2})
        + needs("Walk", {"Leg": 2})
        + needs("Grasp", {"Gripper": 1}),
        Query(requests=("Walk",), answers=(("Grasp", True),)),
        {"chosen"},
        fs({'chosen("Humanoid")'}),
    ),
    (
        "a design over the active module limit is no candidate",
        robot("Centipede", {"Servo": 25})
        + robot("Ant", {"Servo": 18})
        + "(activeModuleLimit Robot 24)",
        Query(),
        {"chosen"},
        fs({'chosen("Ant")'}),
    ),
    (
        "a parameter drives translated KIF rules: needs and part refinement",
        robot("Arm3", {"Gripper": 1, "Servo": 3})
        + robot("Arm6", {"Gripper": 1, "Servo": 6})
        + needs("Orient", {"Servo": 6})
        + '(subclass Oval Object) (parameterName shape "shape") '
        + '(parameterValue shape "oval" Oval)'
        + "(=> (shape ?S) (requiredAbility Orient))"
        + "(=> (shape ?S) (refinedPart Gripper VGripper))",
        Query(params=(("shape", "Oval"),)),
        {"chosen", "structural"},
        fs({'chosen("Arm6")', 'structural("Arm6","VGripper",1)'}),
    ),
    (
        "a demand both needed and answered no is a contradiction",
        robot("Biped", {"Leg": 2}) + needs("Walk", {"Leg": 2}),
        Query(requests=("Walk",), answers=(("Walk", False),)),
        {"chosen"},
        fs(),
    ),
]


@pytest.mark.parametrize(
    ("case", "kif", "query", "preds", "expected"), CASES, ids=[c[0] for c in CASES]
)
def test_encoding(case: str, kif: str, query: Query, preds: set[str], expected) -> None:
    assert reasoner(kif).answer_sets(query, preds) == expected


def test_preference_orders_candidates_by_active_modules() -> None:
    r = reasoner(
        robot("Big", {"Servo": 9}) + robot("Small", {"Servo": 2}) + robot("Also", {"Servo": 2})
    )
    sol = r.solve(Query())
    assert [c.robot_type for c in sol.candidates] == ["Also", "Small", "Big"]
    assert [c.active_total for c in sol.candidates] == [2, 2, 9]


def test_unknown_external_is_an_input_error() -> None:
    from adron.errors import InputError

    r = reasoner(robot("Biped", {"Leg": 2}))
    with pytest.raises(InputError, match="not known"):
        r.solve(Query(requests=("Fly",)))
