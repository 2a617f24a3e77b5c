"""Body plans from the ontology, part kinds as data, one assembler (issue 20).

Robot types written only in KIF (no Python) are designed, exported and loaded by the tools
their users use; a body plan the part kinds cannot assemble is refused with the axiom's
location; the shipped types keep their templates.
"""

from __future__ import annotations

import csv
import io
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from kinematics.assemble import structure_of
from kinematics.bodyplan import BodyPlan
from kinematics.partkinds import PartKindError, load
from kinematics.templates import TemplateParams, build, plan_of
from tests.conftest import TEMPLATES, need

# --- KIF-only robot types, in the paper's style ---------------------------------------------

#: where each serial arm of N joints has a printed link after a joint (1-based), as the
#: part kinds' [serial] table names its joints (a wrist's roll sits at the joint before)
ARM_LINKS = {4: (1, 2, 3, 4), 5: (1, 2, 3, 4), 7: (1, 2, 4, 6)}


def arm_kif(n: int) -> str:
    """A stationary arm of ``n`` position servos written like the paper's manipulator
    axiom (servos and links in a connectedTo chain from a base, ending in a gripper), and
    an ability only an arm of at least ``n`` joints has (so that it is the one chosen)."""
    name = f"Arm{n}Joints"
    servos = [f"?S{i}" for i in range(1, n + 1)]
    links = [f"?K{i}" for i in ARM_LINKS[n]]
    chain = ["?BASE"]
    for i in range(1, n + 1):
        chain.append(f"?S{i}")
        if i in ARM_LINKS[n]:
            chain.append(f"?K{i}")
    chain.append("?GRIP")
    lits = ["(instance ?BASE ArmBase)", "(instance ?GRIP RoboticGripper)"]
    lits += [f"(instance {s} PositionServomotor)" for s in servos]
    lits += [f"(instance {k} LinkModule)" for k in links]
    lits += [f"(robotPart {v} ?ROB)" for v in ["?BASE", "?GRIP", *servos, *links]]
    lits += [f"(connectedTo {a} {b})" for a, b in zip(chain, chain[1:], strict=False)]
    return f"""
(subclass {name} IndustrialRobot)
(instance {name} BaseConfiguration)
(documentation {name} EnglishLanguage "A stationary arm of {n} joints.")
(subclass RobotPositioning{n} RobotPositioning)
(abilityName RobotPositioning{n} "positioning-{n}")
(abilityVerb RobotPositioning{n} "position with {n} joints")
(requiredPartCount RobotPositioning{n} PositionServomotor {n})
(=> (instance ?ROB {name})
  (exists (?BASE ?GRIP {" ".join(servos)} {" ".join(links)})
    (and {" ".join(lits)})))
"""


def legged_kif(name: str, legs: int, ability: str) -> str:
    """A robot on ``legs`` three-joint legs around a trunk, and an ability that needs
    that many legs of its own leg class."""
    leg = f"{name}Leg"
    vs = [f"?L{i}" for i in range(1, legs + 1)]
    lits = [f"(instance {v} {leg})" for v in vs] + ["(instance ?T RobotTrunk)"]
    lits += [f"(robotPart {v} ?ROB)" for v in [*vs, "?T"]]
    lits += [f"(connectedTo {v} ?T)" for v in vs]
    return f"""
(subclass {name} LeggedRobot)
(instance {name} BaseConfiguration)
(subclass {leg} MultipedLeg)
(subclass Robot{name}Walking RobotWalking)
(abilityName Robot{name}Walking "{ability}")
(abilityVerb Robot{name}Walking "walk on {legs} legs")
(requiredPartCount Robot{name}Walking {leg} {legs})
(=> (instance ?ROB {name})
  (exists ({" ".join(vs)} ?T)
    (and {" ".join(lits)})))
"""


HEAVY = """
(subclass HeavyHexapod HexapodRobot)
(instance HeavyHexapod BaseConfiguration)
(subclass RobotHeavyWalking RobotWalking)
(abilityName RobotHeavyWalking "heavy-walking")
(abilityVerb RobotHeavyWalking "walk with heavy loads")
(requiredPartCount RobotHeavyWalking HeavyLeg 6)
(subclass HeavyLeg MultipedLeg)
(=> (instance ?ROB HeavyHexapod)
  (exists (?L1 ?L2 ?L3 ?L4 ?L5 ?L6)
    (and (instance ?L1 HeavyLeg) (instance ?L2 HeavyLeg) (instance ?L3 HeavyLeg)
         (instance ?L4 HeavyLeg) (instance ?L5 HeavyLeg) (instance ?L6 HeavyLeg)
         (robotPart ?L1 ?ROB) (robotPart ?L2 ?ROB) (robotPart ?L3 ?ROB)
         (robotPart ?L4 ?ROB) (robotPart ?L5 ?ROB) (robotPart ?L6 ?ROB))))
"""

#: A differential-drive base carrying a 3-DOF arm and a gripper on its chassis, written
#: like the paper's manipulator axiom: a composition of two structures.
MOBILE = """(subclass MobileManipulator WheeledRobot)
(instance MobileManipulator BaseConfiguration)
(documentation MobileManipulator EnglishLanguage "A base on two wheels carrying an arm.")
(=>
  (instance ?ROB MobileManipulator)
  (exists (?LEFT ?RIGHT ?CASTER ?CHASSIS ?S1 ?S2 ?S3 ?C ?U ?F ?GRIP)
    (and
      (instance ?LEFT DriveWheel) (instance ?RIGHT DriveWheel)
      (instance ?CASTER CasterWheel) (instance ?CHASSIS RobotChassis)
      (instance ?S1 PositionServomotor) (instance ?S2 PositionServomotor)
      (instance ?S3 PositionServomotor)
      (instance ?C LinkModule) (instance ?U LinkModule) (instance ?F LinkModule)
      (instance ?GRIP RoboticGripper)
      (robotPart ?LEFT ?ROB) (robotPart ?RIGHT ?ROB) (robotPart ?CASTER ?ROB)
      (robotPart ?CHASSIS ?ROB) (robotPart ?S1 ?ROB) (robotPart ?S2 ?ROB) (robotPart ?S3 ?ROB)
      (robotPart ?C ?ROB) (robotPart ?U ?ROB) (robotPart ?F ?ROB) (robotPart ?GRIP ?ROB)
      (connectedTo ?LEFT ?CHASSIS) (connectedTo ?RIGHT ?CHASSIS) (connectedTo ?CASTER ?CHASSIS)
      (connectedTo ?CHASSIS ?S1) (connectedTo ?S1 ?C) (connectedTo ?C ?S2) (connectedTo ?S2 ?U)
      (connectedTo ?U ?S3) (connectedTo ?S3 ?F) (connectedTo ?F ?GRIP))))
"""

#: (case, KIF, abilities, extra options, robot type, actuated joints besides grippers)
CASES = [
    ("arm4", arm_kif(4), "positioning-4", ["--answer", "orienting=no"], "Arm4Joints", 4),
    ("arm5", arm_kif(5), "positioning-5", ["--answer", "orienting=no"], "Arm5Joints", 5),
    (
        "arm7",
        arm_kif(7),
        "positioning-7",
        ["--answer", "orienting=yes", "--param", "payload=0.1kg"],
        "Arm7Joints",
        7,
    ),
    (
        "pentapod",
        legged_kif("Pentapod", 5, "five-leg-walking"),
        "five-leg-walking",
        [],
        "Pentapod",
        15,
    ),
    (
        "octopod",
        legged_kif("Octopod", 8, "eight-leg-walking"),
        "eight-leg-walking",
        ["--catalog", "dynamixel"],
        "Octopod",
        24,
    ),
    ("heavy", HEAVY, "heavy-walking", [], "HeavyHexapod", 18),
    (
        "mobile",
        MOBILE,
        "driving pick-and-place",
        ["--param", "object_shape=cylinder"],
        "MobileManipulator",
        5,
    ),
]


def _bom_mass(folder: Path) -> float:
    rows = list(csv.DictReader(io.StringIO((folder / "bom.csv").read_text())))
    return float(rows[-1]["unit_mass_kg"])


@pytest.mark.parametrize(("case", "kif", "ability", "extra", "rtype", "joints"), CASES)
def test_a_kif_only_type_is_designed_exported_and_loads(
    cli, tmp_path, case, kif, ability, extra, rtype, joints
) -> None:
    src = tmp_path / f"{case}.kif"
    src.write_text(kif)
    out = tmp_path / "bundle"
    r = cli(
        "design", *ability.split(), "--ontology", str(src), "--no-input", "--no-verify",
        "--out", str(out), *extra,
    )  # fmt: skip
    assert r.code == 0, r.err
    import json

    rec = json.loads((out / "design.json").read_text())
    assert rec["robot_type"] == rtype
    assert BodyPlan.from_dict(rec["body_plan"]).robot_type == rtype
    moving = [j for j in rec["joints"] if j["group"] != "gripper"]
    assert len(moving) == joints
    assert all(j["actuator"] for j in rec["joints"])  # every joint sized with a catalog model

    import mujoco
    import pinocchio as pin

    urdf, mjcf = out / "robot.urdf", out / "robot.xml"
    m_urdf = mujoco.MjModel.from_xml_path(str(urdf))
    m_mjcf = mujoco.MjModel.from_xml_path(str(mjcf))
    pin_model = pin.buildModelFromUrdf(str(urdf))
    mass_urdf = float(sum(m_urdf.body_mass))
    mass_mjcf = float(sum(m_mjcf.body_mass))
    mass_pin = float(sum(i.mass for i in pin_model.inertias))
    bom = _bom_mass(out)
    for other in (mass_mjcf, mass_pin, bom):
        assert abs(other - mass_urdf) <= 0.005 * mass_urdf, (bom, mass_urdf, mass_mjcf, mass_pin)
    need(shutil.which("check_urdf") is not None, "check_urdf (liburdfdom-tools) is not installed")
    done = subprocess.run(["check_urdf", str(urdf)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "Successfully Parsed" in done.stdout, done.stderr


def test_a_same_shape_subtype_assembles_like_its_parent(kb) -> None:
    """A user's hexapod subclass inherits the whole body plan: the same joints, frames
    and masses as the hexapod's."""
    from adron.kb import load as load_kb
    from synth.reasoning.plans import plan_of as ontology_plan

    del kb
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "heavy.kif"
        f.write_text(HEAVY)
        kb2 = load_kb([f])
    kinds = load()
    mine = build(ontology_plan(kb2, "HeavyHexapod", kinds))
    parent = build("HexapodRobot")
    assert [j.name for j in mine.model.joints] == [j.name for j in parent.model.joints]
    for a, b in zip(mine.model.joints, parent.model.joints, strict=True):
        assert np.allclose(a.origin, b.origin) and np.allclose(a.axis, b.axis)
    assert abs(mine.model.total_mass - parent.model.total_mass) < 1e-12


# --- refusals: the body plan the part kinds cannot assemble --------------------------------

LOOP = legged_kif("LoopBot", 4, "loop-walking").replace(
    "(connectedTo ?L1 ?T)", "(connectedTo ?L1 ?T) (connectedTo ?L1 ?L2)"
)
FLOAT = legged_kif("FloatBot", 4, "float-walking").replace(
    "(instance ?T RobotTrunk)", "(instance ?T BodyPlateModule)"
)
TENTACLE = (
    legged_kif("TentacleBot", 4, "tentacle-walking")
    + """
(subclass Tentacle RobotLimb)
(=> (instance ?ROB TentacleBot)
  (exists (?X) (and (instance ?X Tentacle) (robotPart ?X ?ROB))))
"""
)


@pytest.mark.parametrize(
    ("kif", "ability", "message"),
    [
        (LOOP, "loop-walking", "close a cycle through LoopBotLeg"),
        (FLOAT, "float-walking", "has no root"),
        (TENTACLE, "tentacle-walking", "class Tentacle, but no part kind describes it"),
    ],
)
def test_a_body_plan_that_cannot_be_assembled_is_refused_with_its_location(
    cli, tmp_path, kif, ability, message
) -> None:
    src = tmp_path / "bad.kif"
    src.write_text(kif)
    out = tmp_path / "out"
    r = cli(
        "design", ability, "--ontology", str(src), "--no-input", "--no-verify", "--out", str(out)
    )
    assert r.code == 2, r.err
    assert message in r.err
    assert f"{src}:" in r.err  # file:line:col of the axiom
    assert "Traceback" not in r.err
    assert not out.exists()  # nothing written


def test_the_control_case_of_the_refusals_is_designed(cli, tmp_path) -> None:
    """The refused plans above differ from this one by the defect alone."""
    src = tmp_path / "ok.kif"
    src.write_text(legged_kif("FineBot", 4, "fine-walking"))
    r = cli("design", "fine-walking", "--ontology", str(src), "--no-input", "--no-verify")
    assert r.code == 0, r.err


# --- part kinds as data ------------------------------------------------------------------


def test_the_shipped_types_assemble_from_their_ontology_body_plans() -> None:
    kinds = load()
    expect = {
        "Manipulator3DOF": ("ArmBase", "serial_arm", 4),
        "Manipulator6DOF": ("ArmBase", "serial_arm", 7),
        "HexapodRobot": ("RobotTrunk", "multiped", 18),
        "QuadrupedRobot": ("RobotTrunk", "multiped", 12),
        "HumanoidRobot": ("HumanoidTorso", "biped", 18),
        "SnakeRobot": ("SnakeHead", "module_chain", 3),
        "DifferentialDriveRobot": ("RobotChassis", "wheeled", 2),
        "SkidSteerRobot": ("RobotChassis", "wheeled", 4),
        "CarRobot": ("RobotChassis", "steered", 6),  # 2 steering, 2 driven, 2 free wheels
        "TricycleRobot": ("RobotChassis", "steered", 4),  # 1 steering, 1 driven, 2 free
    }
    assert set(expect) == set(TEMPLATES)
    for rtype, (root, structure, movable) in expect.items():
        plan = plan_of(rtype)
        assert plan.root.kind == root
        assert structure_of(plan, kinds) == structure
        assert build(rtype).model.nv == movable


def test_a_plan_survives_its_record() -> None:
    for rtype in TEMPLATES:
        plan = plan_of(rtype)
        again = BodyPlan.from_dict(plan.to_dict())
        assert again == plan
        a, b = build(plan, TemplateParams(modules=4)), build(again, TemplateParams(modules=4))
        assert [j.name for j in a.model.joints] == [j.name for j in b.model.joints]


def test_a_users_part_kind_replaces_the_shipped_one(tmp_path, cli) -> None:
    """The data decides: a MultipedLeg kind whose coxa turns +-30 degrees gives legs with
    those limits (and the default is the shipped +-60)."""
    from kinematics.partkinds import shipped_text

    text = shipped_text()[1]
    start = text.index('class = "MultipedLeg"')
    mine = "[[kind]]\n" + text[start : text.index("[[kind]]", start)].replace(
        'limits = ["-pi/3", "pi/3"], group = "leg_coxa"',
        'limits = ["-pi/6", "pi/6"], group = "leg_coxa"',
    )
    f = tmp_path / "legs.toml"
    f.write_text(mine)
    from kinematics.partkinds import use

    try:
        use(load([f]))
        t = build("QuadrupedRobot")
        coxa = t.model.joints[t.model.joint("lf_coxa")]
        assert coxa.upper == pytest.approx(np.pi / 6)
    finally:
        use(None)
    t = build("QuadrupedRobot")
    assert t.model.joints[t.model.joint("lf_coxa")].upper == pytest.approx(np.pi / 3)


@pytest.mark.parametrize(
    ("text", "key"),
    [
        (
            '[[kind]]\nclass = "X"\njoints = [{ name = "a", axis = "w" }]\n',
            "kind[0].joints[0].axis",
        ),
        ('[[kind]]\nclass = "X"\ncolour = 1\n', "kind[0].colour"),
        ('[[kind]]\nclass = "X"\nroot = true\n', "needs a 'body' name and a 'box'"),
        ('[serial]\n3 = [["a", "z", "-pi", "pi"]]\n', "serial.3"),
        ('[serial]\n1 = [["a", "z", "-pi", "pi", "tube"]]\n', "serial.1[0]"),
        (
            '[[kind]]\nclass = "X"\njoints = [{ name = "a", limits = ["import os", 1] }]\n',
            "limits[0]",
        ),
    ],
)
def test_a_bad_part_kinds_file_names_the_file_and_the_key(tmp_path, cli, text, key) -> None:
    f = tmp_path / "mine.toml"
    f.write_text(text)
    with pytest.raises(PartKindError, match=key.replace("[", r"\[").replace("]", r"\]")):
        load([f])
    r = cli("design", "walking", "--parts", str(f), "--no-input")
    assert r.code == 2 and str(f) in r.err and "Traceback" not in r.err


def test_a_serial_chain_longer_than_the_table_is_refused() -> None:
    """An arm of 9 joints: the [serial] table has no row for it (the message says which
    it has)."""
    from kinematics.assemble import AssemblyError
    from kinematics.bodyplan import PartNode

    node = PartNode("RoboticGripper", ("RoboticGripper",))
    for _ in range(9):
        node = PartNode("PositionServomotor", ("PositionServomotor",), (node,))
    plan = BodyPlan("LongArm", PartNode("ArmBase", ("ArmBase", "RobotTrunk"), (node,)))
    with pytest.raises(AssemblyError, match="serial chain of 9 joints.*3, 4, 5, 6, 7"):
        build(plan)


# --- the manipulator's degrees of freedom as a parameter -----------------------------------


@pytest.mark.parametrize(
    ("shape", "dof", "robot", "joints"),
    [
        (
            "cylinder",
            "4",
            "SerialArm4DOF",
            ("base_yaw", "shoulder_pitch", "elbow_pitch", "wrist_pitch"),
        ),
        (
            "cylinder",
            "5",
            "SerialArm5DOF",
            ("base_yaw", "shoulder_pitch", "elbow_pitch", "wrist_pitch", "tool_roll"),
        ),
        ("cylinder", "3", "Manipulator3DOF", ("base_yaw", "shoulder_pitch", "elbow_pitch")),
        (
            "oval",
            "6",
            "Manipulator6DOF",
            ("base_yaw", "shoulder_pitch", "elbow_pitch", "wrist_roll", "wrist_pitch", "tool_roll"),
        ),
    ],
)
def test_dof_composes_or_picks_an_arm_of_that_many_joints(cli, shape, dof, robot, joints) -> None:
    import json

    r = cli(
        "design", "pick-and-place", "--param", f"object_shape={shape}", "--param", f"dof={dof}",
        "--no-input", "--no-verify", "--json",
    )  # fmt: skip
    assert r.code == 0, r.err
    rec = json.loads(r.out)
    assert rec["robot_type"] == robot
    names = tuple(j["name"] for j in rec["joints"] if j["group"] != "gripper")
    assert names == joints
    assert "dof" not in rec.get("ignored_params", [])


@pytest.mark.parametrize("dof", ["2", "8", "five", "4.5"])
def test_dof_outside_the_arms_parmor_composes_is_refused(cli, dof) -> None:
    r = cli("design", "pick-and-place", "--param", f"dof={dof}", "--no-input", "--no-verify")
    assert r.code == 2 and "3 to 7 joints" in r.err and "Traceback" not in r.err


def test_dof_on_a_request_no_arm_meets_is_refused(cli) -> None:
    """A walking robot is no serial arm: dof=4 leaves no candidate (exit 1)."""
    r = cli("design", "walking", "--param", "dof=4", "--no-input", "--no-verify")
    assert r.code == 1 and "dof=4" in r.err


def test_an_arm_of_5_joints_is_verified(cli, designs, tmp_path) -> None:
    """A serial arm of 5 joints written only in KIF is served by the manipulator's
    numerical IK (issue 21): designed and verified (tests/gaits/test_arm_ik.py runs its
    behaviours again in MuJoCo: the session's one design of the request, tests/conftest.py);
    --no-verify sizes and exports it unverified."""
    from tests.gaits.test_arm_ik import verified_arm_request

    r = designs(*verified_arm_request(5), kif={"arm5": arm_kif(5)})
    assert r.code == 0, r.err
    assert "pick-and-place" in r.out and "cannot be simulated" not in r.err
    src = tmp_path / "arm5.kif"
    src.write_text(arm_kif(5))
    r = cli(
        "design", "positioning-5", "--answer", "orienting=no", "--ontology", str(src),
        "--no-input", "--no-verify",
    )  # fmt: skip
    assert r.code == 0, r.err


def test_a_mobile_manipulator_is_sized_as_its_base_and_its_arm(tmp_path) -> None:
    """The composition: its arm's links are named apart from the chassis' (arm_L1 ...),
    the arm stands on the plate, the wheels are sized for the whole robot's traction and
    the arm's joints for the arm's reach, each with its own speeds."""
    from adron.kb import load as load_kb
    from kinematics.assemble import serial_links
    from synth.reasoning.plans import plan_of as ontology_plan

    f = tmp_path / "mm.kif"
    f.write_text(MOBILE)
    kinds = load()
    plan = ontology_plan(load_kb([f]), "MobileManipulator", kinds)
    assert structure_of(plan, kinds) == "mobile_manipulator"
    assert serial_links(plan, kinds) == [["arm_L1", "arm_L2", "arm_L3"]]
    t = build(plan)
    assert {"L1", "L2", "arm_L1", "arm_L2", "arm_L3"} == set(t.length_names)
    assert t.wheels and t.casters and t.end_effectors == ("gripper_link",)
    base_yaw = t.model.joints[t.model.joint("base_yaw")]
    assert t.model.bodies[base_yaw.parent].name == "chassis"
    from synth.sizing.families import FAMILIES

    fam = FAMILIES["mobile_manipulator"]
    speeds = fam.speeds(t, {"speed": 0.2, "reach": 0.25}, None)
    assert speeds["left_wheel"] == pytest.approx(0.2 / t.params.wheel_radius)
    assert speeds["shoulder_pitch"] == pytest.approx(0.2 / 0.30)  # arm_L2 + arm_L3


def test_a_mobile_manipulators_gripper_holds_the_payload(tmp_path) -> None:
    """Where an arm is, its gripper holds the payload (the object it picks), on a chassis
    as on an arm's base; a chassis without an arm carries it on its plate."""
    from adron.kb import load as load_kb
    from synth.reasoning.plans import plan_of as ontology_plan

    f = tmp_path / "mm.kif"
    f.write_text(MOBILE)
    t = build(ontology_plan(load_kb([f]), "MobileManipulator", load()), TemplateParams(payload=0.4))
    held = [b for b, ps in t.parts.items() for p in ps if p.kind == "payload" and p.mass > 0]
    assert held == ["gripper_link"]
    cart = build("DifferentialDriveRobot", TemplateParams(payload=0.4))
    held = [b for b, ps in cart.parts.items() for p in ps if p.kind == "payload" and p.mass > 0]
    assert held == ["chassis"]
