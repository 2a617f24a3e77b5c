"""The bundle pieces that need no geometry: BOM, the bundle README, atomic writing."""

from __future__ import annotations

import csv
import dataclasses
import io

import numpy as np
import pytest

from adron.errors import ExportError
from export.bom import COLUMNS, bom_csv
from export.bundle import write_bundle
from export.guide import guide_markdown
from export.model3d import Assembly, BodySpec, JointSpec, PartUse, PrintedPart


def part(name: str, count: int, fits: bool = True) -> PrintedPart:
    return PrintedPart(
        name, "link", b"solid", count, 1e-5, 1e-5, 0.0124, (0.1, 0.05, 0.05), fits, 600.0
    )


def use(name: str, source: str, mass: float, kind: str = "", cost: float = 0.0) -> PartUse:
    return PartUse(name, source, mass, np.zeros(3), np.zeros((3, 3)), None, kind, cost)


def assembly(printed: list[PrintedPart], extra: tuple[PartUse, ...] = ()) -> Assembly:
    """Bodies holding 3 SG90, an IntelEdison, each printed part's uses and ``extra``."""
    uses = [use("SG90", "module", 0.034, "PositionServomotor", 5.0)] * 3
    uses += [use("IntelEdison", "module", 0.041, "MainModule", 62.4)]
    uses += [use(p.name, "printed", p.mass_kg) for p in printed for _ in range(p.count)]
    uses += list(extra)
    mass = sum(u.mass for u in uses)
    body = BodySpec("base", tuple(uses), mass, np.zeros(3), np.zeros((3, 3)))
    return Assembly("Arm", "base", (body,), (), tuple(printed))


def test_bom_lists_modules_parts_and_bought_parts_with_totals() -> None:
    tyre = use("tyre band", "bought", 0.004, "Tyre", 0.3)
    asm = assembly([part("link_l2", 2)], (tyre, tyre))
    rows = list(csv.reader(io.StringIO(bom_csv(asm))))
    assert tuple(rows[0]) == COLUMNS
    by_name = {r[1]: r for r in rows[1:-1]}
    assert by_name["SG90"][3] == "3" and by_name["SG90"][4] == "5"
    assert by_name["link_l2"][11] == "meshes/link_l2.stl" and by_name["link_l2"][9] == "yes"
    assert by_name["tyre band"][:4] == ["bought", "tyre band", "Tyre", "2"]
    total = rows[-1]
    assert total[0] == "total" and total[3] == str(3 + 1 + 2 + 2)
    assert float(total[4]) == pytest.approx(3 * 5.0 + 62.4 + 2 * 0.3)
    assert float(total[5]) == pytest.approx(asm.total_mass)
    assert float(total[7]) == pytest.approx(1200)


def test_bom_leaves_the_payload_out() -> None:
    """A payload is a load, not a part: added to a body by mistake, the BOM does not list
    it, and its total then disagrees with the model's mass (what the bundle tests catch)."""
    asm = assembly([part("link_l2", 1)], (use("payload", "payload", 0.2),))
    rows = list(csv.reader(io.StringIO(bom_csv(asm))))
    assert "payload" not in {r[1] for r in rows}
    assert float(rows[-1][5]) == pytest.approx(asm.total_mass - 0.2)


def test_bom_flags_a_part_too_big_for_the_bed() -> None:
    rows = list(csv.reader(io.StringIO(bom_csv(assembly([part("plate", 1, fits=False)])))))
    assert rows[-2][9] == "NO" and rows[-1][9] == "NO"


def record() -> dict:
    return {
        "robot_type": "Arm|<x>",
        "request": {"abilities": ["grasping"]},
        "abilities": ["grasping"],
        "mass_kg": 0.5,
        "cost": 10.0,
        "dof": 3,
        "active_modules": 6,
        "module_limit": 24,
        "params": {"reach": 0.25},
        "bus": {"name": "I2C", "address_word": "address", "module_limit": 24},
        "modules": [
            {"kind": "MainModule", "model": "IntelEdison", "count": 1, "bus_addresses": []},
            {"kind": "PositionServomotor", "model": "SG90", "count": 1, "bus_addresses": ["0x09"]},
        ],
        "joints": [
            {
                "name": "base_yaw",
                "module_class": "PositionServomotor",
                "actuator": "SG90",
                "bus_address": "0x09",
                "required_torque_Nm": 0.05,
                "usable_torque_Nm": 0.12,
            }
        ],
    }


def test_guide_tells_files_printing_and_assembly_order() -> None:
    base = assembly([part("link_l2", 2, fits=False)])
    servo = use("SG90", "module", 0.034, "PositionServomotor", 5.0)
    arm = BodySpec("arm", (servo, use("jaw", "printed", 0.01)), 0.044, np.zeros(3), np.eye(3))
    joint = JointSpec("base_yaw", "base", "arm", "revolute", np.eye(4), np.array([0, 0, 1.0]))
    joint = dataclasses.replace(joint, actuator="SG90")
    asm = dataclasses.replace(base, bodies=(*base.bodies, arm), joints=(joint,))
    text = guide_markdown(record(), asm, "An arm.", pictures=True)
    assert text.startswith("# Arm\\|<x>: a parmor design")
    for f in ("design.json", "robot.urdf", "robot.xml", "meshes/*.stl", "bom.csv"):
        assert f"`{f}`" in text
    assert "`meshes/link_l2.stl` | 2 |" in text and "split it" in text
    assert "![link_l2](pictures/link_l2.png)" in text and "pictures/robot.png" in text
    root = text.index("1. The root body `base`: SG90 x3, IntelEdison, `meshes/link_l2.stl` x2.")
    step = text.index("2. Joint `base_yaw`: the SG90 servo module (I2C 0x09) onto `base`")
    assert root < step and "on its output: `meshes/jaw.stl`." in text


def test_write_bundle_is_atomic_and_refuses_non_empty_folders(tmp_path) -> None:
    out = tmp_path / "b"
    write_bundle(out, {"a.txt": "1", "meshes/x.stl": b"2"})
    assert (out / "a.txt").read_text() == "1" and (out / "meshes" / "x.stl").read_bytes() == b"2"
    with pytest.raises(ExportError, match="not empty"):
        write_bundle(out, {"a.txt": "new"})
    assert (out / "a.txt").read_text() == "1"
    write_bundle(out, {"c.txt": "3"}, force=True)
    assert sorted(p.name for p in out.iterdir()) == [".parmor", "c.txt"]  # MARKER: ours
    empty = tmp_path / "empty"
    empty.mkdir()
    write_bundle(empty, {"a.txt": "1"})  # an empty folder is fine
    assert (empty / "a.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "empty"]  # no temporaries


def test_bundle_folder_and_files_are_readable_by_everyone(tmp_path) -> None:
    """0755 folders and 0644 files whatever the umask (mkdtemp alone makes 0700)."""
    import os

    old = os.umask(0o077)
    try:
        out = write_bundle(tmp_path / "b", {"a.txt": "1", "meshes/x.stl": b"2"})
    finally:
        os.umask(old)
    assert (out.stat().st_mode & 0o777) == 0o755
    assert ((out / "meshes").stat().st_mode & 0o777) == 0o755
    assert ((out / "a.txt").stat().st_mode & 0o777) == 0o644
    assert ((out / "meshes" / "x.stl").stat().st_mode & 0o777) == 0o644


@pytest.mark.parametrize("name", ["../x.txt", "/abs.txt", "meshes/../../x"])
def test_write_bundle_keeps_files_inside(tmp_path, name) -> None:
    with pytest.raises(ExportError, match="inside"):
        write_bundle(tmp_path / "b", {name: "x"})
    assert list(tmp_path.iterdir()) == []
