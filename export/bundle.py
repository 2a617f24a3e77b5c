"""The output bundle: every file of a design (``bundle_files``), and writing a folder
atomically (``write_bundle``): all files appear together or none do."""

from __future__ import annotations

import re
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from adron.errors import ExportError

if TYPE_CHECKING:
    from adron.catalog import Catalog
    from export.model3d import Assembly
    from synth.structure import Structure

_SAFE_STEM = re.compile(r"[a-z0-9_]+")


def picture_files(asm: Assembly, title: str) -> dict[str, bytes]:
    """``pictures/robot.png`` (the robot at its zero pose) and ``pictures/<part>.png`` (each
    printed part as it lies on the bed)."""
    import io

    import trimesh

    from export.assembly import PRINTED_RGBA
    from export.render import assembly_png, mesh_png

    vertices = {}
    out: dict[str, bytes] = {}
    for p in asm.printed:
        m = trimesh.load(io.BytesIO(p.stl), file_type="stl", process=False)
        v, f = np.asarray(m.vertices) / 1000.0, np.asarray(m.faces)
        vertices[f"{p.name}.stl"] = (v, f)
        out[f"pictures/{p.name}.png"] = mesh_png(v, f, PRINTED_RGBA, f"{p.name} (as printed)")
    out["pictures/robot.png"] = assembly_png(asm, vertices, title)
    return out


def payload_record(structure: Structure, with_payload: bool) -> dict:
    """design.json's ``payload``: the load the robot was sized and simulated with, kept
    out of the robot's own model (kg, the body holding it, its position m in that body's
    frame, whether robot.urdf and robot.xml carry it)."""
    uses = [
        (body, lp)
        for body, parts in sorted(structure.template.parts.items())
        for lp in parts
        if lp.kind == "payload" and lp.mass > 0
    ]
    return {
        "mass_kg": round(sum(lp.mass for _, lp in uses), 9),
        "held_by": [
            {
                "body": body,
                "mass_kg": round(lp.mass, 9),
                "position_m": [round(float(x), 9) for x in lp.com],
            }
            for body, lp in uses
        ],
        "in_models": bool(with_payload and uses),
        "note": "a load, not a part of the robot: not in bom.csv; robot.urdf and robot.xml "
        "carry it only when asked (parmor design --with-payload); the verification simulated "
        "the robot with it",
    }


def bundle_files(
    record: dict,
    structure: Structure,
    catalog: Catalog,
    documentation: str = "",
    with_payload: bool = False,
    pictures: bool = True,
) -> dict[str, str | bytes]:
    """Every file of the bundle of a sized design: design.json, robot.urdf, robot.xml,
    meshes/*.stl, bom.csv and README.md (relative name -> content). The models carry the
    payload only ``with_payload``; design.json says where it is (``payload``)."""
    from export.bom import bom_csv
    from export.guide import guide_markdown
    from export.mjcf import mjcf_string
    from export.record import to_json
    from export.slicer import prusa_config
    from export.urdf import urdf_string

    asm, trajectories = assembly_of(structure, catalog, record)
    for p in asm.printed:
        if not _SAFE_STEM.fullmatch(p.name):
            raise ExportError(f"printed part name {p.name!r} is not a safe file name")
    record = {**record, "payload": payload_record(structure, with_payload)}
    files: dict[str, str | bytes] = {
        "design.json": to_json(record),
        "robot.urdf": urdf_string(asm, with_payload=with_payload),
        "robot.xml": mjcf_string(asm, with_payload=with_payload),
        "bom.csv": bom_csv(asm),
        "README.md": guide_markdown(record, asm, documentation, pictures),
        "print/prusaslicer.ini": prusa_config(
            [b * 1000 for b in catalog.passive.printer_bed_m], catalog.material.density_kg_m3 / 1000
        ),
    }
    if pictures:
        files |= picture_files(asm, record["robot_type"])
    for p in asm.printed:
        files[f"meshes/{p.name}.stl"] = p.stl
    files |= print_projects(asm, catalog)
    for name, t in trajectories.items():
        files[f"trajectories/{name}.csv"] = t.csv()
    return files


def print_projects(asm: Assembly, catalog: Catalog) -> dict[str, bytes]:
    """``print/<part>.3mf``: a PrusaSlicer project of each printed part on the bed of the
    printer the BOM names for it (none for a part no catalog printer holds), supports on
    only for a part with overhangs as it lies (``export.threemf``)."""
    from export.threemf import part_3mf

    beds = {"": catalog.passive.printer_bed_m} | {p.model: p.bed_m for p in catalog.printers}
    density = catalog.material.density_kg_m3 / 1000
    out: dict[str, bytes] = {}
    for p in asm.printed:
        printer = "" if p.fits_bed else p.printer
        if printer not in beds:
            continue
        bed = [b * 1000 for b in beds[printer]]
        out[f"print/{p.name}.3mf"] = part_3mf(
            p.name, p.stl, p.count, bed, density, p.overhang_m2 > 0
        )
    return out


#: The last assembly built (structure, catalog, assembly): a bundle and its models without
#: the payload come from one design, whose meshes are built once.
_LAST: list[tuple] = []


def assembly_of(structure: Structure, catalog: Catalog, record: dict):
    """The assembly of a sized design (``build_assembly``), its servos' travel placed over
    the joint spans its behaviours use (default parameters) and its trajectories
    (behaviour -> Trajectory); reused for the same structure and catalog objects and the
    same record but for its verdicts (the verification may drop an ability or calibrate)."""
    import json

    from export.assembly import build_assembly

    # the trajectories follow the record (abilities, calibration...), not its verdicts
    key = json.dumps(
        {k: v for k, v in record.items() if k not in ("verified", "payload")},
        sort_keys=True,
        default=str,
    )
    last = _LAST[0] if _LAST else None
    if last and last[2] == key and last[3] is structure and last[4] is catalog:
        return last[5], last[6]
    trajectories = _trajectories(record)
    used: dict[str, tuple[float, float]] = {}
    for t in trajectories.values():
        for k, joint in enumerate(t.joints):
            lo, hi = float(t.positions[:, k].min()), float(t.positions[:, k].max())
            old = used.get(joint, (lo, hi))
            used[joint] = (min(lo, old[0]), max(hi, old[1]))
    asm = build_assembly(structure, catalog, used)
    _LAST[:] = [(id(structure), id(catalog), key, structure, catalog, asm, trajectories)]
    return asm, trajectories


def model_files(
    record: dict, structure: Structure, catalog: Catalog, with_payload: bool
) -> dict[str, str]:
    """robot.urdf and robot.xml of a sized design, carrying the payload or not."""
    from export.mjcf import mjcf_string
    from export.urdf import urdf_string

    asm, _ = assembly_of(structure, catalog, record)
    return {
        "robot.urdf": urdf_string(asm, with_payload=with_payload),
        "robot.xml": mjcf_string(asm, with_payload=with_payload),
    }


def trajectory_files(record: dict) -> dict[str, str]:
    """``trajectories/<behaviour>.csv``: each behaviour of the design's controller that
    realises one of its abilities (``turning`` of a walking robot too; aliases left out),
    with default parameters (joint angles over time)."""
    return {f"trajectories/{n}.csv": t.csv() for n, t in _trajectories(record).items()}


def _trajectories(record: dict) -> dict:
    """Behaviour name -> its Trajectory with default parameters, for every behaviour the
    design lists (``Controller.listed``), in name order."""
    from gaits import controller_for
    from gaits.base import DesignGeometry

    controller = controller_for(DesignGeometry.from_record(record))
    out = {}
    for name in controller.listed(record.get("abilities", ())):
        if not _SAFE_BEHAVIOR.fullmatch(name):
            raise ExportError(f"behaviour name {name!r} is not a safe file name")
        out[name] = controller.run(name)
    return out


_SAFE_BEHAVIOR = re.compile(r"[a-z0-9_-]+")
#: Modes of the bundle's folders and files: everyone may read them (a shared machine, a
#: web server), whatever the umask; ``tempfile.mkdtemp`` alone would leave 0700.
DIR_MODE = 0o755
FILE_MODE = 0o644


def write_bundle(
    out: str | Path,
    files: Mapping[str, str | bytes],
    force: bool = False,
    modes: Mapping[str, int] | None = None,
) -> Path:
    """Write ``files`` (relative name -> content) into the folder ``out``.

    The files are written to a temporary sibling folder that is then renamed into place,
    so an error leaves nothing half-written. An existing non-empty ``out`` is an error
    unless ``force``, in which case it is replaced whole; an empty one is replaced. Files
    get ``FILE_MODE``, or their mode in ``modes`` (an executable script), folders
    ``DIR_MODE``.
    """
    modes = modes or {}
    out = Path(out)
    for name in files:
        parts = Path(name).parts
        if Path(name).is_absolute() or ".." in parts or not parts:
            raise ExportError(f"{name!r}: a bundle file must stay inside the folder")
    if out.exists() and not out.is_dir():
        raise ExportError(f"{out}: exists and is not a folder")
    if out.exists() and any(out.iterdir()) and not force:
        raise ExportError(f"{out}: already exists and is not empty; pass --force to replace it")
    parent = out.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    except OSError as e:
        raise ExportError(f"{out}: cannot create: {e.strerror}") from None
    try:
        tmp.chmod(DIR_MODE)
        for name, content in sorted(files.items()):
            target = tmp / name
            for d in reversed(target.relative_to(tmp).parents[:-1]):
                (tmp / d).mkdir(exist_ok=True)
                (tmp / d).chmod(DIR_MODE)
            if isinstance(content, str):
                target.write_text(content, encoding="utf-8", newline="\n")
            else:
                target.write_bytes(content)
            target.chmod(modes.get(name, FILE_MODE))
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=parent))
            out.rename(old / "x")
            tmp.rename(out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(out)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        raise ExportError(f"{out}: cannot write: {e.strerror}") from None
    return out
