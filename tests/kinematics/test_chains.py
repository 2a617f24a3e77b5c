"""Several chains on one root, and roots on roots (issue 31, item 4).

The KIF types are test data written in the paper's style (``tests/data/chains/``): two
arms on a fixed base, two arms on a wheeled chassis, a torso carrying two arms on a
wheeled chassis (``connectedTo`` torso-chassis: one tree), a quadruped with a pan-tilt
head carrying a camera. Each chain is sized with its own loads, each arm has its own
behaviours (``left-grasping``, ``right-grasping`` ...), the base's behaviours run with
the arms held; a plan parmor cannot say how to build is refused naming why (exit 2).
"""

from __future__ import annotations

import csv
import io
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import need

DATA = Path(__file__).resolve().parents[1] / "data" / "chains"
STATION = str(DATA / "two_arm_station.kif")
DUAL = str(DATA / "dual_arm_mobile.kif")
TORSO = str(DATA / "torso_on_wheels.kif")
HEAD = str(DATA / "headed_quadruped.kif")


def _plan(kif: str, robot: str, extra: str | None = None):
    from adron.kb import load as load_kb
    from kinematics.partkinds import in_use
    from synth.reasoning.plans import plan_of

    files = [Path(kif)] + ([Path(extra)] if extra else [])
    return plan_of(load_kb(files), robot, in_use())


def _design(cli, tmp_path: Path, *args: str, out: str = "bundle"):
    folder = tmp_path / out
    r = cli("design", *args, "--no-input", "--out", str(folder))
    assert "Traceback" not in r.out + r.err
    return r, folder


def _record(folder: Path) -> dict:
    return json.loads((folder / "design.json").read_text())


def _bundle_loads(folder: Path) -> None:
    """The bundle loads in MuJoCo (URDF and MJCF) and pinocchio with the BOM's mass, and
    in check_urdf."""
    import mujoco
    import pinocchio as pin

    rows = list(csv.DictReader(io.StringIO((folder / "bom.csv").read_text())))
    bom = float(rows[-1]["unit_mass_kg"])
    urdf, mjcf = str(folder / "robot.urdf"), str(folder / "robot.xml")
    masses = (
        float(sum(mujoco.MjModel.from_xml_path(urdf).body_mass)),
        float(sum(mujoco.MjModel.from_xml_path(mjcf).body_mass)),
        float(sum(i.mass for i in pin.buildModelFromUrdf(urdf).inertias)),
    )
    assert np.allclose(masses, bom, atol=1e-6), (bom, masses)
    need(shutil.which("check_urdf") is not None, "check_urdf (liburdfdom-tools) is not installed")
    done = subprocess.run(["check_urdf", urdf], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "Successfully Parsed" in done.stdout, done.stderr


# --- body plans: roots on roots ------------------------------------------------------------


def test_a_torso_connected_to_a_chassis_is_one_tree_rooted_at_the_chassis() -> None:
    plan = _plan(TORSO, "WheeledTorso")
    assert plan.root.kind == "RobotChassis"
    torso = [c for c in plan.root.children if c.kind == "HumanoidTorso"]
    assert len(torso) == 1
    assert [c.kind for c in torso[0].children] == ["PositionServomotor"] * 2


#: two root parts the part kinds mount neither on the other (an arm's base and a torso)
NO_CARRIER = """
(subclass Stacked IndustrialRobot)
(instance Stacked BaseConfiguration)
(=> (instance ?ROB Stacked)
  (exists (?BASE ?T ?S1 ?S2 ?S3 ?G)
    (and (instance ?BASE ArmBase) (instance ?T HumanoidTorso)
      (instance ?S1 PositionServomotor) (instance ?S2 PositionServomotor)
      (instance ?S3 PositionServomotor) (instance ?G RoboticGripper)
      (robotPart ?BASE ?ROB) (robotPart ?T ?ROB) (robotPart ?S1 ?ROB) (robotPart ?S2 ?ROB)
      (robotPart ?S3 ?ROB) (robotPart ?G ?ROB)
      (connectedTo ?T ?BASE) (connectedTo ?BASE ?S1) (connectedTo ?S1 ?S2)
      (connectedTo ?S2 ?S3) (connectedTo ?S3 ?G))))
"""


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (NO_CARRIER, "do not say which carries the others"),
        (NO_CARRIER.replace("(connectedTo ?T ?BASE) ", ""), "that no connectedTo joins"),
    ],
)
def test_two_roots_that_no_kind_mounts_on_the_other_are_refused(tmp_path, text, words):
    from adron.errors import OntologyError

    src = tmp_path / "stacked.kif"
    src.write_text(text)
    with pytest.raises(OntologyError, match=words) as e:  # exit 2, at the axiom
        _plan(str(src), "Stacked")
    assert "stacked.kif:" in str(e.value)


# --- assembly: several chains on one part --------------------------------------------------


def test_two_arms_on_one_serial_mount_stand_track_apart_and_share_their_lengths() -> None:
    from kinematics.templates import build

    t = build(_plan(STATION, "TwoArmStation"))
    assert t.model.q_names == (
        *("l_base_yaw", "l_shoulder_pitch", "l_elbow_pitch", "l_gripper"),
        *("r_base_yaw", "r_shoulder_pitch", "r_elbow_pitch", "r_gripper"),
    )
    m = t.model
    left, right = (m.joints[m.joint(j)].origin[:3, 3] for j in ("l_base_yaw", "r_base_yaw"))
    assert left[1] - right[1] == pytest.approx(0.10)  # ArmBase's mount: track 0.10
    assert left[0] == right[0] and left[2] == right[2]
    assert {s.length_name for s in t.segments} == {"L1", "L2", "L3"}
    assert len(t.segments) == 6 and t.end_effectors == ("l_gripper_link", "r_gripper_link")


def test_two_chains_on_a_serial_mount_without_a_track_are_refused(cli, tmp_path) -> None:
    parts = tmp_path / "base.toml"
    parts.write_text(
        '[[kind]]\nclass = "ArmBase"\nroot = true\nbody = "base"\nbox = [0.1, 0.1, 0.02]\n'
        'faces = "down"\npayload = "end_effector"\n'
        'mounts = [{ child = "PositionServomotor", layout = "serial" }]\n'
    )
    r = cli(
        "design", "two-handed-grasping", "pick-and-place", "--ontology", STATION,
        "--parts", str(parts),
        "--no-input", "--no-verify",
    )  # fmt: skip
    assert r.code == 2, r.err
    assert "carries 2 chains on one serial mount" in r.err and "no `track`" in r.err


def test_a_carried_torso_is_a_printed_plate_without_modules() -> None:
    from kinematics.templates import TemplateParams, build

    plan = _plan(TORSO, "WheeledTorso")
    t = build(plan, TemplateParams(face_side=0.05, face_thickness=0.004, density=1240.0))
    plate = [p for p in t.parts["trunk"] if p.kind == "plate"]
    assert len(plate) == 1
    L = t.lengths
    area = L["shoulder_width"] * L["trunk_height"]
    assert plate[0].mass == pytest.approx(area * 0.004 * 1240.0)
    m = t.model
    assert m.joints[m.body("trunk")].kind == "fixed"
    assert m.bodies[m.joints[m.body("trunk")].parent].name == "chassis"


# --- structures and the conceptual count -----------------------------------------------------


@pytest.mark.parametrize(
    ("kif", "robot", "structure"),
    [
        (STATION, "TwoArmStation", "multi_arm"),
        (DUAL, "DualArmMobile", "mobile_manipulator"),
        (TORSO, "WheeledTorso", "mobile_manipulator"),
        (HEAD, "HeadedQuadruped", "legged_manipulator"),
    ],
)
def test_the_structure_is_read_off_the_plan(kif, robot, structure) -> None:
    from kinematics.assemble import structure_of
    from kinematics.partkinds import in_use

    assert structure_of(_plan(kif, robot), in_use()) == structure


#: a biped carrying a chain of joints: no controller walks a biped with an arm of servos
BIPED_ARM = """
(subclass ArmedBiped BipedalRobot)
(instance ArmedBiped BaseConfiguration)
(=> (instance ?ROB ArmedBiped)
  (exists (?T ?S1 ?S2 ?S3 ?K1 ?G)
    (and (instance ?T HumanoidTorso) (instance ?S1 PositionServomotor)
      (instance ?S2 PositionServomotor) (instance ?S3 PositionServomotor)
      (instance ?K1 LinkModule) (instance ?G RoboticGripper)
      (robotPart ?T ?ROB) (robotPart ?S1 ?ROB) (robotPart ?S2 ?ROB) (robotPart ?S3 ?ROB)
      (robotPart ?K1 ?ROB) (robotPart ?G ?ROB) (connectedTo ?T ?S1)
      (connectedTo ?S1 ?K1) (connectedTo ?K1 ?S2) (connectedTo ?S2 ?S3) (connectedTo ?S3 ?G))))
"""


#: a torso on a chassis with the humanoid's arm parts (role arm: its controller swings them)
ARMED_CART = """
(subclass ArmedCart WheeledRobot)
(instance ArmedCart BaseConfiguration)
(=> (instance ?ROB ArmedCart)
  (exists (?L ?R ?C ?CH ?T ?A1 ?A2 ?H1 ?H2)
    (and (instance ?L DriveWheel) (instance ?R DriveWheel) (instance ?C CasterWheel)
      (instance ?CH RobotChassis) (instance ?T HumanoidTorso)
      (instance ?A1 HumanoidArm) (instance ?A2 HumanoidArm)
      (instance ?H1 RoboticGripper) (instance ?H2 RoboticGripper)
      (robotPart ?L ?ROB) (robotPart ?R ?ROB) (robotPart ?C ?ROB) (robotPart ?CH ?ROB)
      (robotPart ?T ?ROB) (robotPart ?A1 ?ROB) (robotPart ?A2 ?ROB) (robotPart ?H1 ?ROB)
      (robotPart ?H2 ?ROB)
      (connectedTo ?L ?CH) (connectedTo ?R ?CH) (connectedTo ?C ?CH) (connectedTo ?T ?CH)
      (connectedTo ?A1 ?T) (connectedTo ?A2 ?T) (connectedTo ?H1 ?A1) (connectedTo ?H2 ?A2))))
"""


@pytest.mark.parametrize(
    ("text", "robot", "abilities"),
    [
        (BIPED_ARM, "ArmedBiped", ("walking", "pick-and-place")),
        (ARMED_CART, "ArmedCart", ("driving", "grasping")),
    ],
)
def test_a_shape_parmor_does_not_size_is_refused_naming_what_it_sizes(
    cli, tmp_path, text, robot, abilities
) -> None:
    src = tmp_path / "robot.kif"
    src.write_text(text)
    r = cli("design", *abilities, "--ontology", str(src), "--no-input", "--no-verify")
    assert r.code == 2, r.err
    assert f"{robot} has no sizing rules" in r.err and "legged_manipulator" in r.err
    assert "on three or more legs" in r.err and "Traceback" not in r.err


def test_two_three_joint_arms_are_not_a_six_joint_chain(cli) -> None:
    """The robot's own joints in two connectedTo chains count as the larger chain: two
    3-joint arms position, they do not orient (which needs six joints in one chain)."""
    r = cli("explain", "TwoArmStation", "--ontology", STATION)
    assert r.code == 0, r.err
    assert "positioning: has 3 PositionServomotor, needs 3" in r.out
    assert "orienting" not in r.out.split("abilities:")[1].split("can gain")[0]
    six = cli("explain", "Manipulator6DOF")
    assert "orienting: has 6 PositionServomotor, needs 6" in six.out


def test_a_head_without_a_gripper_leaves_the_payload_on_the_trunk() -> None:
    from kinematics.templates import TemplateParams, build

    t = build(_plan(HEAD, "HeadedQuadruped"), TemplateParams(payload=0.1))
    where = [b for b, parts in t.parts.items() for p in parts if p.kind == "payload"]
    assert where == ["trunk"]
    s = build(_plan(STATION, "TwoArmStation"), TemplateParams(payload=0.1))
    where = sorted(b for b, parts in s.parts.items() for p in parts if p.kind == "payload")
    assert where == ["l_gripper_link", "r_gripper_link"]  # each gripper holds it


# --- each chain sized with its loads, each arm its own controller ----------------------------


def test_each_arm_has_its_own_behaviours_and_the_others_hold(cli, tmp_path) -> None:
    from gaits import controller_for
    from gaits.base import DesignGeometry

    r, out = _design(cli, tmp_path, "driving", "pick-and-place", "--ontology", DUAL, "--no-verify")
    assert r.code == 0, r.err
    rec = _record(out)
    c = controller_for(DesignGeometry.from_record(rec))
    names = set(c.behaviors)
    assert {"driving", "turning", "travel"} <= names
    for arm in ("left", "right"):
        assert {f"{arm}-grasping", f"{arm}-positioning", f"{arm}-pick-and-place"} <= names
        assert c.behaviors[f"{arm}-grasping"].realises == "grasping"
    assert "grasping" not in names and "pick-and-place" not in names
    left = c.run("left-grasping")
    right_cols = [left.joints.index(j) for j in left.joints if j.startswith("r_")]
    left_cols = [left.joints.index(j) for j in left.joints if j.startswith("l_")]
    assert np.ptp(left.positions[:, right_cols], axis=0).max() == 0  # the right arm holds
    assert np.ptp(left.positions[:, left_cols], axis=0).max() > 0.1
    assert left.info["tool_body"] == "l_gripper_link"
    drive = c.run("driving")
    arms = [drive.joints.index(j) for j in drive.joints if j[:2] in ("l_", "r_")]
    assert np.ptp(drive.positions[:, arms], axis=0).max() == 0  # both arms held
    # the bundle lists every arm's behaviours
    listed = {p.stem for p in (out / "trajectories").glob("*.csv")}
    assert {"left-pick-and-place", "right-pick-and-place", "driving"} <= listed


def test_the_ros_package_addresses_each_arm(cli, tmp_path) -> None:
    r, out = _design(
        cli, tmp_path, "two-handed-grasping", "pick-and-place", "--ontology", STATION, "--no-verify"
    )
    assert r.code == 0, r.err
    ros = cli("ros", str(out), "--json")
    assert ros.code == 0, ros.err
    text = ros.out
    for name in ("left_grasping", "right_grasping", "left_positioning", "right_positioning"):
        assert name in text


def test_two_arms_on_a_fixed_base_are_designed_and_robust(cli, tmp_path) -> None:
    r, out = _design(
        cli, tmp_path, "two-handed-grasping", "pick-and-place", "--ontology", STATION,
        "--robustness", "8",
    )  # fmt: skip
    assert r.code == 0, r.err
    rec = _record(out)
    assert rec["robot_type"] == "TwoArmStation"
    assert "orienting" not in rec["abilities"]
    verified = {b["behavior"]: b for b in rec["verified"]["behaviors"]}
    assert {"left-pick-and-place", "right-pick-and-place"} <= set(verified)
    assert all(b["verdict"] == "ok" for b in verified.values())
    assert all(b["robust"] for b in rec["verified"]["robust"]["behaviors"])
    _bundle_loads(out)
    for extra in ((), ("--perturb", "5")):
        s = cli("simulate", str(out), "--behavior", "right-pick-and-place", "--json", *extra)
        assert s.code == 0, s.err
        fig = json.loads(s.out)
        assert fig["verdict"] == "ok" and fig["placing_error_m"] <= 0.005


def test_a_quadruped_with_a_head_walks_with_it_held_and_points_its_camera(cli, tmp_path):
    r, out = _design(cli, tmp_path, "walking", "pointing", "--ontology", HEAD, "--robustness", "8")
    assert r.code == 0, r.err
    rec = _record(out)
    joints = [j["name"] for j in rec["joints"]]
    assert joints[-2:] == ["pan", "tilt"] and len(joints) == 14
    verified = {b["behavior"]: b for b in rec["verified"]["behaviors"]}
    assert {"walking", "turning", "pointing", "scanning"} <= set(verified)
    assert all(b["verdict"] == "ok" for b in verified.values())
    assert all(b["robust"] for b in rec["verified"]["robust"]["behaviors"])
    _bundle_loads(out)
    # the head's lengths are sized from its reach (KIF defaultParameter 6 cm)
    assert rec["lengths_m"]["head_L2"] == pytest.approx(0.06)
    for name, extra in (("walking", ("--perturb", "2")), ("pointing", ("--perturb", "4"))):
        s = cli("simulate", str(out), "--behavior", name, "--json", *extra)
        assert s.code == 0, s.err
        assert json.loads(s.out)["verdict"] == "ok"
