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
from export.mjcf import load_mjcf
from export.record import design_record
from synth.conceptual import Design, Request
from synth.solver import Query
from synth.structure import design_structure
from tests.conftest import CI


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
    assert len(bundles) == 8
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
        assert len(movable) == len(rec["joints"])
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


def test_meshes_are_watertight_and_match_the_optimiser(bundles, catalog) -> None:
    bed = sorted(catalog.passive.printer_bed_m)
    for t, (rec, files) in bundles.items():
        links = {f"link_{x['name'].lower()}": x for x in rec["links"]}
        rows = {r["name"]: r for r in csv.DictReader(io.StringIO(files["bom.csv"]))}
        for name, data in files.items():
            if not name.startswith("meshes/"):
                continue
            mesh = trimesh.load(io.BytesIO(data), file_type="stl")
            assert mesh.is_watertight and mesh.is_volume, (t, name)
            stem = name[len("meshes/") : -len(".stl")]
            if stem in links:
                assert mesh.volume == pytest.approx(links[stem]["part_volume_m3"], rel=0.01)
            fits = all(a <= b + 1e-9 for a, b in zip(sorted(mesh.extents), bed, strict=True))
            assert rows[stem]["fits_bed"] == ("yes" if fits else "NO"), (t, stem)


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
        assert f"Joint `{j['name']}`: {j['actuator']} at {j['i2c_address']}" in readme
    rows = list(csv.DictReader(io.StringIO((out / "bom.csv").read_text(encoding="utf-8"))))
    assert rows[-1]["type"] == "total"
    assert float(rows[-1]["unit_cost"]) == pytest.approx(rec["cost"])
