"""`parmor simulate` (and run, blocks, the verification) refuse a bundle whose design.json
and robot.xml are not of one design: another robot type or other joint names (issue 23,
item 9)."""

from __future__ import annotations

import io
import re
import shutil
from pathlib import Path

import pytest

from adron.errors import InputError
from synth.commands.cli import main
from synth.verification.simulate import check_agrees


def design(folder: Path, *args: str) -> Path:
    err = io.StringIO()
    code = main(["design", *args, "--no-verify", "--out", str(folder)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    return folder


@pytest.fixture(scope="module")
def bundles(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("agree")
    return {
        "cart": design(root / "cart", "driving"),
        "snake": design(root / "snake", "rolling"),
        "snake5": design(root / "snake5", "rectilinear"),
    }


def mixed(tmp_path: Path, record_of: Path, model_of: Path) -> Path:
    """A folder with one bundle's design.json and another's robot.xml and meshes."""
    folder = tmp_path / "mixed"
    shutil.copytree(record_of, folder)
    shutil.copy(model_of / "robot.xml", folder / "robot.xml")
    for mesh in (model_of / "meshes").iterdir():
        shutil.copy(mesh, folder / "meshes" / mesh.name)
    return folder


def test_the_files_of_two_designs_are_refused(cli, bundles, tmp_path: Path) -> None:
    folder = mixed(tmp_path, bundles["cart"], bundles["snake"])
    r = cli("simulate", str(folder), "--behavior", "driving")
    assert r.code == 2, r.err
    assert r.err == (
        f"parmor: error: {folder}/design.json: robot_type 'DifferentialDriveRobot', but "
        "robot.xml is a model of 'SnakeRobot': the two files are of different designs; write "
        "both with 'parmor design ... --out DIR'\n"
    )
    r = cli("simulate", str(folder), "--behavior", "help")
    assert r.code == 2 and "robot.xml is a model of 'SnakeRobot'" in r.err


def test_other_joint_names_are_refused(cli, bundles, tmp_path: Path) -> None:
    folder = tmp_path / "renamed"
    shutil.copytree(bundles["cart"], folder)
    xml = (folder / "robot.xml").read_text(encoding="utf-8")
    (folder / "robot.xml").write_text(xml.replace("left_wheel", "front_wheel"), encoding="utf-8")
    r = cli("simulate", str(folder), "--behavior", "driving")
    assert r.code == 2, r.err
    assert (
        "design.json: its joints and robot.xml's differ (left_wheel only in design.json; "
        "front_wheel only in robot.xml)"
    ) in r.err


def test_a_snake_of_other_module_count_is_refused(bundles, tmp_path: Path, cli) -> None:
    import json

    few = json.loads((bundles["snake"] / "design.json").read_text())["joints"]
    more = json.loads((bundles["snake5"] / "design.json").read_text())["joints"]
    assert len(few) != len(more)  # the same robot type, another joint count
    folder = mixed(tmp_path, bundles["snake"], bundles["snake5"])
    r = cli("simulate", str(folder), "--behavior", "rolling")
    assert r.code == 2 and "only in robot.xml" in r.err, r.err


def test_one_designs_files_agree_and_simulate(cli, bundles) -> None:
    r = cli("simulate", str(bundles["cart"]), "--behavior", "driving", "--seconds", "0.5")
    assert r.code == 0, r.err


def test_every_base_configurations_bundle_agrees(kb, designer, catalog) -> None:
    """No false alarm: the default design of each of the eight robot types."""
    import json

    from export.bundle import bundle_files
    from export.record import design_record
    from synth.reasoning.conceptual import Design, Request
    from synth.reasoning.solver import Query
    from synth.sizing.structure import design_structure

    seen = set()
    for cand in designer.reasoner.solve(Query()).candidates:
        s = design_structure(kb, cand, catalog, {})
        d = Design("designed", Request(), (cand,), cand, "only candidate")
        files = bundle_files(design_record(d, designer.short, s), s, catalog, "doc")
        record = json.loads(files["design.json"])
        xml = files["robot.xml"]
        check_agrees(xml.decode() if isinstance(xml, bytes) else xml, record)
        seen.add(cand.robot_type)
    assert len(seen) == 10  # the paper's eight and the two steered ones


XML = """<mujoco model="{model}"><worldbody><body name="b"><freejoint/>
<body name="c"><joint name="j1"/><joint name="j2" type="hinge"/></body></body></worldbody>
</mujoco>"""

CASES = {
    "agree": ("R", ["j1", "j2"], None),
    "another type": ("Q", ["j1", "j2"], "robot_type 'Q', but robot.xml is a model of 'R'"),
    "a joint missing from the model": ("R", ["j1", "j2", "j3"], "j3 only in design.json"),
    "a joint missing from the record": ("R", ["j1"], "j2 only in robot.xml"),
    "renamed": ("R", ["j1", "k2"], "k2 only in design.json; j2 only in robot.xml"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_check_agrees(case: str) -> None:
    robot_type, joints, message = CASES[case]
    record = {"robot_type": robot_type, "joints": [{"name": n} for n in joints]}
    xml = XML.format(model="R")
    if message is None:
        check_agrees(xml, record)
    else:
        with pytest.raises(InputError, match=re.escape(message)):
            check_agrees(xml, record)


def test_many_names_are_cut_short() -> None:
    record = {"robot_type": "R", "joints": [{"name": f"x{i:02d}"} for i in range(20)]}
    with pytest.raises(InputError) as e:
        check_agrees(XML.format(model="R"), record)
    assert "x00, x01, x02, x03, x04, x05 and 14 more only in design.json" in str(e.value)
