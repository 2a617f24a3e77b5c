"""The export bundle of every base configuration's default design, checked by tools that
someone else wrote: yourdfpy and check_urdf for the URDF, MuJoCo for the MJCF, trimesh for
the meshes (issue 4)."""

from __future__ import annotations

import csv
import io
import json
import shutil
import subprocess

import pytest
import trimesh
import yourdfpy

from export.bundle import bundle_files, write_bundle
from export.meshes import dovetail_volume
from export.mjcf import load_mjcf
from export.record import design_record
from synth.reasoning.conceptual import Design, Request
from synth.reasoning.solver import Query
from synth.sizing.structure import design_structure
from tests.conftest import CI, need


@pytest.fixture(scope="module")
def bundles(kb, designer, catalog):
    out = {}
    for cand in designer.reasoner.solve(Query()).candidates:
        s = design_structure(kb, cand, catalog, {})
        d = Design("designed", Request(), (cand,), cand, "only candidate")
        rec = design_record(d, designer.short, s)
        out[cand.robot_type] = (rec, bundle_files(rec, s, catalog, "doc"))
    return out


def test_every_base_configuration_has_a_bundle(bundles, designer) -> None:
    assert len(bundles) == 10  # the paper's eight and the two steered ones
    for t, (_, files) in bundles.items():
        assert {"design.json", "robot.urdf", "robot.xml", "bom.csv", "README.md"} <= set(files)
        assert any(n.startswith("meshes/") and n.endswith(".stl") for n in files), t
        for name in files:
            assert ".." not in name and not name.startswith("/")


def test_urdf_loads_and_passes_check_urdf(bundles, tmp_path) -> None:
    tool = shutil.which("check_urdf")
    if tool is None and CI:
        pytest.fail("check_urdf is missing (apt-get install liburdfdom-tools)")
    for t, (rec, files) in bundles.items():
        folder = tmp_path / t
        write_bundle(folder, files)
        robot = yourdfpy.URDF.load(str(folder / "robot.urdf"), mesh_dir=str(folder))
        masses = sum(link.inertial.mass for link in robot.robot.links if link.inertial)
        assert masses == pytest.approx(rec["mass_kg"], rel=0.01), t
        movable = [j for j in robot.robot.joints if j.type != "fixed"]
        assert len(movable) == len(rec["joints"]) + len(rec.get("passive_joints", []))
        if tool:
            r = subprocess.run(
                [tool, str(folder / "robot.urdf")], capture_output=True, text=True, check=False
            )
            assert r.returncode == 0, r.stdout + r.stderr


def test_mjcf_loads_in_mujoco_with_the_design_mass(bundles) -> None:
    for t, (rec, files) in bundles.items():
        meshes = {n.split("/", 1)[1]: b for n, b in files.items() if n.startswith("meshes/")}
        model = load_mjcf(files["robot.xml"], meshes)
        assert model.body_mass.sum() == pytest.approx(rec["mass_kg"], rel=0.01), t
        assert model.nu == len(rec["joints"])
        stall = {j["name"]: j["actuator_torque_Nm"] for j in rec["joints"]}
        for k in range(model.nu):
            assert model.actuator_forcerange[k][1] == pytest.approx(
                stall[model.joint(model.actuator_trnid[k][0]).name]
            )


#: Non-default designs (robot type, parameters SI) the BOM is checked on besides the defaults.
NON_DEFAULT = (
    ("Manipulator3DOF", {"reach": 0.30, "payload": 0.15}),
    ("DifferentialDriveRobot", {"payload": 0.3, "load_area": 0.05, "speed": 0.2}),
    ("HexapodRobot", {"obstacle_height": 0.05, "payload": 0.3}),
)


@pytest.fixture(scope="module")
def other_bundles(kb, designer, catalog):
    cands = {c.robot_type: c for c in designer.reasoner.solve(Query()).candidates}
    out = {}
    for t, params in NON_DEFAULT:
        s = design_structure(kb, cands[t], catalog, params)
        d = Design("designed", Request(), (cands[t],), cands[t], "only candidate")
        rec = design_record(d, designer.short, s)
        out[f"{t} {params}"] = (rec, bundle_files(rec, s, catalog, "doc"))
    return out


def bom_disagreements(files: dict) -> list[str]:
    """How bom.csv and robot.urdf disagree: a part the URDF models that bom.csv lacks (a
    printed mesh, a catalog module's box, a bought part's shape), or totals of mass more
    than 0.1 % apart. Empty when they agree."""
    import xml.etree.ElementTree as ET

    rows = list(csv.DictReader(io.StringIO(files["bom.csv"])))
    # a part's pieces and joints (--bed) are listed under it, outside the totals
    parts = [r for r in rows if r["type"] not in ("total", "piece", "joint")]
    names = {r["name"] for r in parts}
    files_listed = {r["file"] for r in parts if r["type"] == "printed"}
    kinds = {r["kind"] for r in parts}
    out = []
    root = ET.fromstring(files["robot.urdf"])
    for link in root.iter("link"):
        for v in link.iter("visual"):
            g = v.find("geometry")
            mesh = g.find("mesh")
            if mesh is not None:
                if mesh.get("filename").split("meshes/")[-1] not in {
                    f.split("meshes/")[-1] for f in files_listed
                }:
                    out.append(f"{link.get('name')}: mesh {mesh.get('filename')} not in bom.csv")
            elif g.find("box") is not None and v.get("name").split("/")[-1] not in names:
                out.append(f"{link.get('name')}: module {v.get('name')} not in bom.csv")
            elif v.get("name").endswith("/ball_caster") and "CasterModule" not in kinds:
                out.append(f"{link.get('name')}: the ball caster is not in bom.csv")
    model = sum(float(m.get("value")) for m in root.iter("mass"))
    bom = sum(float(r["unit_mass_kg"]) * int(r["count"]) for r in parts)
    total = float(rows[-1]["unit_mass_kg"])
    if abs(bom - model) > 1e-3 * model or abs(total - model) > 1e-3 * model:
        out.append(f"bom.csv {bom:.6f} kg (total line {total:.6f}), model {model:.6f} kg")
    return out


def test_bom_lists_every_part_of_the_model_with_its_mass(bundles, other_bundles) -> None:
    """Every default design and three others: bom.csv and the URDF/MJCF agree part by part,
    and their masses to 0.1 % (the payload is in neither)."""
    for t, (rec, files) in {**bundles, **other_bundles}.items():
        assert bom_disagreements(files) == [], t
        meshes = {n.split("/", 1)[1]: b for n, b in files.items() if n.startswith("meshes/")}
        model = load_mjcf(files["robot.xml"], meshes)
        total = float(list(csv.DictReader(io.StringIO(files["bom.csv"])))[-1]["unit_mass_kg"])
        assert model.body_mass.sum() == pytest.approx(total, rel=1e-3), t
        payload = json.loads(files["design.json"])["payload"]
        assert payload["in_models"] is False
        # design.json's mass is the robot's own; the loaded mass adds the payload
        assert total == pytest.approx(rec["mass_kg"], rel=1e-3), t
        assert total + payload["mass_kg"] == pytest.approx(rec["loaded_mass_kg"], rel=1e-3), t
    kinds = {
        r["kind"]
        for _, files in {**bundles, **other_bundles}.values()
        for r in csv.DictReader(io.StringIO(files["bom.csv"]))
    }
    assert {"finger", "CasterModule", "Tyre"} <= kinds


def test_bom_check_finds_a_missing_part_and_a_wrong_mass(bundles) -> None:
    """The check above, on a BOM built to fail it: the caster's row dropped, a mass off."""
    files = dict(bundles["DifferentialDriveRobot"][1])
    lines = files["bom.csv"].splitlines(keepends=True)
    files["bom.csv"] = "".join(x for x in lines if "CasterModule" not in x)
    found = bom_disagreements(files)
    assert any("ball caster" in f for f in found) and any("model" in f for f in found)
    files = dict(bundles["Manipulator3DOF"][1])
    lines = files["bom.csv"].splitlines(keepends=True)
    files["bom.csv"] = "".join(x for x in lines if not x.startswith("printed,jaw"))
    assert any("jaw" in f for f in bom_disagreements(files))


def test_with_payload_puts_the_payload_in_both_models(kb, designer, catalog) -> None:
    cand = next(
        c for c in designer.reasoner.solve(Query()).candidates if c.robot_type == "SkidSteerRobot"
    )
    s = design_structure(kb, cand, catalog, {"payload": 1.0})
    d = Design("designed", Request(), (cand,), cand, "only candidate")
    rec = design_record(d, designer.short, s)
    alone, loaded = (bundle_files(rec, s, catalog, with_payload=w) for w in (False, True))
    meshes = {n.split("/", 1)[1]: b for n, b in alone.items() if n.startswith("meshes/")}
    m0 = load_mjcf(alone["robot.xml"], meshes).body_mass.sum()
    m1 = load_mjcf(loaded["robot.xml"], meshes).body_mass.sum()
    assert m1 - m0 == pytest.approx(1.0)
    assert json.loads(loaded["design.json"])["payload"]["in_models"] is True
    assert alone["bom.csv"] == loaded["bom.csv"]


def test_meshes_are_watertight_and_match_the_optimiser(bundles, catalog) -> None:
    bed_xyz = catalog.passive.printer_bed_m
    face = catalog.passive.dovetail_face_m
    for t, (rec, files) in bundles.items():
        links = {f"link_{x['name'].lower()}": x for x in rec["links"]}
        rows = {r["name"]: r for r in csv.DictReader(io.StringIO(files["bom.csv"]))}
        for name, data in files.items():
            if not name.startswith("meshes/"):
                continue
            mesh = trimesh.load(io.BytesIO(data), file_type="stl").apply_scale(1e-3)
            assert mesh.is_watertight and mesh.is_volume, (t, name)
            stem = name[len("meshes/") : -len(".stl")]
            if stem in links:
                # the structure's part volume, plus the dovetail (with or without the pin:
                # a leg's tip has none)
                x = links[stem]
                ways = [
                    x["part_volume_m3"]
                    + dovetail_volume(face, x["r_inner_m"], catalog.passive.print_clearance_m, pin)
                    for pin in (True, False)
                ]
                assert min(abs(mesh.volume / w - 1) for w in ways) < 0.01, (t, stem)
            # as printed (the STL's own axes), with a 3 mm skirt around the footprint
            x, y, z = mesh.extents + (0.006, 0.006, 0.0)
            fits = (x <= bed_xyz[0] and y <= bed_xyz[1]) or (y <= bed_xyz[0] and x <= bed_xyz[1])
            fits = fits and z <= bed_xyz[2]
            assert (rows[stem]["printer"] == "") == fits, (t, stem)
            assert rows[stem]["fits_bed"] == "yes", (t, stem)  # on the printer it names
            if not fits:  # a larger printer of the catalog takes it
                printer = next(p for p in catalog.printers if p.model == rows[stem]["printer"])
                assert all(e <= b for e, b in zip(mesh.extents, printer.bed_m, strict=True))


def test_bundle_is_byte_identical_for_identical_inputs(kb, designer, catalog) -> None:
    cand = next(
        c for c in designer.reasoner.solve(Query()).candidates if c.robot_type == "HexapodRobot"
    )
    d = Design("designed", Request(), (cand,), cand, "only candidate")
    runs = []
    for _ in range(2):
        s = design_structure(kb, cand, catalog, {})
        rec = design_record(d, designer.short, s)
        runs.append(bundle_files(rec, s, catalog))
    assert runs[0] == runs[1]


def test_cli_bundle_with_readme_and_bom(cli, tmp_path) -> None:
    out = tmp_path / "arm"
    r = cli("design", "pick-and-place", "--param", "object_shape=oval", "--out", str(out))
    assert r.code == 0, r.err
    readme = (out / "README.md").read_text(encoding="utf-8")
    assert readme.startswith("# Manipulator6DOF") and "## Assemble" in readme
    rec = json.loads((out / "design.json").read_text(encoding="utf-8"))
    for j in rec["joints"]:
        assert (
            f"Joint `{j['name']}`: the {j['actuator']} servo module (I2C {j['bus_address']})"
            in readme
        )
    assert "![the assembled robot](pictures/robot.png)" in readme
    assert (out / "pictures" / "robot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader(io.StringIO((out / "bom.csv").read_text(encoding="utf-8"))))
    assert rows[-1]["type"] == "total"
    assert float(rows[-1]["unit_cost"]) == pytest.approx(rec["cost"])


def test_urdf_meshes_load_in_pinocchio_and_mujoco_without_warnings(
    bundles, tmp_path, capfd, monkeypatch
):
    """robot.urdf as written (meshes named by absolute file:// URI of the bundle folder, in
    mm, scale 0.001): MuJoCo loads the URDF file with its meshes and no warning (unique geom
    names) and keeps the whole robot's mass (the root link not fused into the world);
    pinocchio builds its visual and collision geometry with no argument and no
    ``ROS_PACKAGE_PATH``. Moved to another folder, MuJoCo still finds the meshes in
    ``meshes/`` (its compiler extension); pinocchio no longer does (the documented limit)."""
    from importlib.util import find_spec

    import mujoco

    need(find_spec("pinocchio") is not None, "pinocchio is not installed (the test extras)")
    import pinocchio as pin

    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    monkeypatch.chdir(tmp_path)
    for t, (rec, files) in bundles.items():
        folder = write_bundle(tmp_path / t, files).resolve()
        urdf = str(folder / "robot.urdf")
        assert f'filename="file://{folder}/meshes/' in (folder / "robot.urdf").read_text()
        capfd.readouterr()
        model = mujoco.MjModel.from_xml_path(urdf)
        out, err = capfd.readouterr()
        assert "WARNING" not in out + err, (t, out + err)
        assert model.nmesh == len({n for n in files if n.startswith("meshes/")}), t
        assert model.body_mass.sum() == pytest.approx(rec["mass_kg"], rel=1e-3), t
        pm = pin.buildModelFromUrdf(urdf)
        for kind in (pin.GeometryType.VISUAL, pin.GeometryType.COLLISION):
            geom = pin.buildGeomFromUrdf(pm, urdf, kind)
            assert geom.ngeoms > 0, t
            assert all(
                g.meshPath.startswith(str(folder))
                for g in geom.geometryObjects
                if g.meshPath and g.meshPath.endswith(".stl")
            ), t
        names = [g.name for g in geom.geometryObjects]
        assert len(names) == len(set(names)), t
    # a moved bundle: MuJoCo by base name in meshes/; pinocchio's absolute path is gone
    moved = tmp_path / "moved"
    folder.rename(moved)
    urdf = str(moved / "robot.urdf")
    assert mujoco.MjModel.from_xml_path(urdf).nmesh > 0
    pm = pin.buildModelFromUrdf(urdf)
    with pytest.raises(ValueError):  # the old absolute path is gone
        pin.buildGeomFromUrdf(pm, urdf, pin.GeometryType.VISUAL)


def test_joint_ranges_fit_the_servos_travel_and_the_trajectories(bundles, catalog) -> None:
    """Every revolute joint turns no further than its servo's catalog travel, and every
    bundled trajectory stays inside the joint ranges."""
    import xml.etree.ElementTree as ET

    travel = {a.model: a.travel_rad for a in catalog.actuators}
    for t, (rec, files) in bundles.items():
        actuator = {j["name"]: j["actuator"] for j in rec["joints"]}
        limits = {}
        for j in ET.fromstring(files["robot.urdf"]).iter("joint"):
            lim = j.find("limit")
            if j.get("type") == "revolute":
                lo, hi = float(lim.get("lower")), float(lim.get("upper"))
                assert hi - lo <= travel[actuator[j.get("name")]] + 1e-9, (t, j.get("name"))
                limits[j.get("name")] = (lo, hi)
            if j.get("type") != "fixed":
                dyn = j.find("dynamics")
                assert dyn is not None and float(dyn.get("friction")) == 0.0, (t, j.get("name"))
        for name, text in files.items():
            if not name.startswith("trajectories/"):
                continue
            rows = list(csv.reader(io.StringIO(text)))
            for k, joint in enumerate(rows[0]):
                if joint not in limits:
                    continue
                values = [float(r[k]) for r in rows[1:]]
                lo, hi = limits[joint]
                assert lo - 1e-6 <= min(values) and max(values) <= hi + 1e-6, (t, name, joint)


def test_one_trajectory_per_listed_behaviour(bundles) -> None:
    from gaits import controller_for
    from gaits.base import DesignGeometry

    for t, (rec, files) in bundles.items():
        listed = controller_for(DesignGeometry.from_record(rec)).listed(rec["abilities"])
        got = sorted(n[len("trajectories/") : -4] for n in files if n.startswith("trajectories/"))
        assert got == sorted(listed), t


def test_urdf_damping_equals_the_mjcf_joints(bundles) -> None:
    import xml.etree.ElementTree as ET

    for t, (_, files) in bundles.items():
        urdf = {
            j.get("name"): float(j.find("dynamics").get("damping"))
            for j in ET.fromstring(files["robot.urdf"]).iter("joint")
            if j.get("type") != "fixed"
        }
        mjcf = {
            j.get("name"): float(j.get("damping", "0"))
            for j in ET.fromstring(files["robot.xml"]).iter("joint")
            if j.get("name")
        }
        assert urdf == pytest.approx(mjcf, rel=1e-9), t
