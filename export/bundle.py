"""The output bundle: every file of a design (``bundle_files``), and writing a folder
atomically (``write_bundle``): all files appear together or none do."""

from __future__ import annotations

import re
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from adron.errors import ExportError

if TYPE_CHECKING:
    from adron.catalog import Catalog
    from synth.structure import Structure

_SAFE_STEM = re.compile(r"[a-z0-9_]+")


def bundle_files(
    record: dict, structure: Structure, catalog: Catalog, documentation: str = ""
) -> dict[str, str | bytes]:
    """Every file of the bundle of a sized design: design.json, robot.urdf, robot.xml,
    meshes/*.stl, bom.csv and README.md (relative name -> content)."""
    from export.assembly import build_assembly
    from export.bom import bom_csv
    from export.guide import guide_markdown
    from export.mjcf import mjcf_string
    from export.record import to_json
    from export.urdf import urdf_string

    asm = build_assembly(structure, catalog)
    for p in asm.printed:
        if not _SAFE_STEM.fullmatch(p.name):
            raise ExportError(f"printed part name {p.name!r} is not a safe file name")
    figures = {a.model: (a.cost, a.mass_kg) for a in catalog.actuators}
    figures |= {m.model: (m.cost, m.mass_kg) for m in catalog.modules}
    files: dict[str, str | bytes] = {
        "design.json": to_json(record),
        "robot.urdf": urdf_string(asm),
        "robot.xml": mjcf_string(asm),
        "bom.csv": bom_csv(record["modules"], asm.printed, figures),
        "README.md": guide_markdown(record, asm.printed, documentation),
    }
    for p in asm.printed:
        files[f"meshes/{p.name}.stl"] = p.stl
    files.update(trajectory_files(record))
    return files


def trajectory_files(record: dict) -> dict[str, str]:
    """``trajectories/<behaviour>.csv``: each behaviour of the design's controller that
    realises one of its abilities (``turning`` of a walking robot too; aliases left out),
    with default parameters (joint angles over time)."""
    from gaits import controller_for
    from gaits.base import DesignGeometry

    controller = controller_for(DesignGeometry.from_record(record))
    out = {}
    for name in controller.listed(record.get("abilities", ())):
        if not _SAFE_BEHAVIOR.fullmatch(name):
            raise ExportError(f"behaviour name {name!r} is not a safe file name")
        out[f"trajectories/{name}.csv"] = controller.run(name).csv()
    return out


_SAFE_BEHAVIOR = re.compile(r"[a-z0-9_-]+")


def write_bundle(out: str | Path, files: Mapping[str, str | bytes], force: bool = False) -> Path:
    """Write ``files`` (relative name -> content) into the folder ``out``.

    The files are written to a temporary sibling folder that is then renamed into place,
    so an error leaves nothing half-written. An existing non-empty ``out`` is an error
    unless ``force``, in which case it is replaced whole; an empty one is replaced.
    """
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
        for name, content in sorted(files.items()):
            target = tmp / name
            target.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, str):
                target.write_text(content, encoding="utf-8", newline="\n")
            else:
                target.write_bytes(content)
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
