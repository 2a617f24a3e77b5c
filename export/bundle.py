"""The output bundle: every file of a design (``bundle_files``), and writing a folder
atomically (``write_bundle``): all files appear together or none do."""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import json
import os
import re
import secrets
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from adron.errors import ExportError

if TYPE_CHECKING:
    from adron.catalog import Catalog
    from export.model3d import Assembly
    from synth.structure import Structure

_SAFE_STEM = re.compile(r"[a-z0-9_]+")


def picture_files(asm: Assembly, title: str) -> dict[str, bytes]:
    """``pictures/robot.png`` (the robot at its zero pose) and ``pictures/<part>.png`` (each
    printed part as it lies on the bed)."""
    from export.assembly import PRINTED_RGBA
    from export.meshes import read_stl
    from export.render import assembly_png, mesh_png

    vertices = {}
    out: dict[str, bytes] = {}
    for p in asm.printed:
        v, f = read_stl(p.stl)
        v = v / 1000.0
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
    simulated_only: bool = False,
) -> dict[str, str | bytes]:
    """Every file of the bundle of a sized design: design.json, robot.urdf, robot.xml,
    meshes/*.stl, bom.csv and README.md (relative name -> content). The models carry the
    payload only ``with_payload``; design.json says where it is (``payload``).
    ``simulated_only``: just what a simulation reads (design.json, robot.xml, meshes), for
    the verification's own bundle."""
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
    if simulated_only:
        return {
            "design.json": to_json(record),
            "robot.xml": mjcf_string(asm, with_payload=with_payload),
            **{f"meshes/{p.name}.stl": p.stl for p in asm.printed},
        }
    files: dict[str, str | bytes] = {
        "design.json": to_json(record),
        "robot.urdf": urdf_string(asm, with_payload=with_payload),
        "robot.xml": mjcf_string(asm, with_payload=with_payload),
        "bom.csv": bom_csv(asm),
        "README.md": guide_markdown(record, asm, documentation, pictures),
        "print/prusaslicer.ini": prusa_config(
            [b * 1000 for b in ini_bed(asm, catalog)], catalog.material.density_kg_m3 / 1000
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


def ini_bed(asm: Assembly, catalog: Catalog) -> tuple[float, float, float]:
    """The build volume (m) of ``print/prusaslicer.ini``: the catalog's printer
    (``passive.printer_bed_m``) or, when a part needs a larger one (the BOM's ``printer``
    column), the largest bed the design uses, so that every part in ``meshes/`` slices with
    that one file; each part's ``print/<part>.3mf`` holds its own printer's bed."""
    beds = [catalog.passive.printer_bed_m]
    beds += [b for p in asm.printed if (b := catalog.printer_bed(p.printer)) is not None]
    return max(beds, key=lambda b: (b[0] * b[1], b))


def print_projects(asm: Assembly, catalog: Catalog) -> dict[str, bytes]:
    """``print/<part>.3mf``: a PrusaSlicer project of each printed part on the bed of the
    printer the BOM names for it (none for a part no catalog printer holds), supports on
    only for a part with overhangs as it lies (``export.threemf``)."""
    from export.threemf import part_3mf

    density = catalog.material.density_kg_m3 / 1000
    out: dict[str, bytes] = {}
    for p in asm.printed:
        bed_m = catalog.printer_bed(p.printer)  # "" when it fits the catalog's printer
        if bed_m is None:
            continue
        bed = [b * 1000 for b in bed_m]
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
#: The file ``write_bundle`` leaves in every folder it writes: ``force`` replaces only a
#: folder holding it (or a bundle of ours from before it, see ``_ours``), so that a typo
#: in ``--out DIR --force`` cannot delete a folder of the user's.
MARKER = ".parmor"
MARKER_TEXT = (
    "This folder was written by parmor; 'parmor ... --force' may replace it whole.\n"
    "Remove this file to keep parmor from replacing it.\n"
)


def write_bundle(
    out: str | Path,
    files: Mapping[str, str | bytes],
    force: bool = False,
    modes: Mapping[str, int] | None = None,
) -> Path:
    """Write ``files`` (relative name -> content) into the folder ``out``; returns it.

    The files are written to a temporary sibling folder that then takes ``out``'s place in
    one atomic step, so that ``out`` holds the old files or the new ones, never a mix or
    nothing, whenever the process is killed:

    - ``out`` absent or empty: ``rename`` (which fails, rather than replace it, when a
      non-empty folder or a file appeared at ``out`` meanwhile);
    - ``out`` a non-empty folder of ours (``force``): on Linux ``renameat2`` with
      ``RENAME_EXCHANGE`` swaps the two folders, then the old one is deleted; where the
      exchange is not available, ``out`` is renamed aside, the new folder into place and
      the old one deleted (a kill between the two renames leaves ``out`` absent: the next
      write to ``out`` puts the old one back first).

    Temporary folders are named ``.<out>.<hash>.parmor-new|old-<pid>-<random>`` beside
    ``out``; one left by a killed run (its process gone) is deleted by the next write to
    the same ``out``. Refused (ExportError, nothing written): an ``out`` of '', '.', '..'
    or '/', the working folder or one above it, a symbolic link (never followed: the link
    is not a folder of ours), a file, a non-empty folder without ``force`` or, with it,
    one parmor did not write (``MARKER`` absent, ``_ours``). Every folder written holds
    ``MARKER``. Files get ``FILE_MODE``, or their mode in ``modes`` (an executable
    script), folders ``DIR_MODE``.
    """
    modes = modes or {}
    for name in files:
        parts = Path(name).parts
        if Path(name).is_absolute() or ".." in parts or not parts or name == MARKER:
            raise ExportError(f"{name!r}: a bundle file must stay inside the folder")
    _clean_leftovers(_target(out))
    target = check_out(out, force)
    shown = str(out)
    made = _make_parents(target.parent, shown)
    tmp = None
    try:
        tmp = _temp_dir(target, "new")
        _write_files(tmp, anchor_urdfs(files, target), modes)
        _commit(tmp, target, shown, force)
        tmp = None
    except OSError as e:
        raise ExportError(f"{shown}: cannot write: {e.strerror or e}") from None
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
            for d in reversed(made):
                with contextlib.suppress(OSError):
                    d.rmdir()
    return Path(out)


def anchor_urdfs(files: Mapping[str, str | bytes], folder: Path) -> Mapping[str, str | bytes]:
    """``files`` with every ``*.urdf``'s relative mesh paths made absolute ``file://`` URIs
    under ``folder`` (the bundle's final place), so that pinocchio's ``buildGeomFromUrdf``
    and RViz load the meshes with no package directory (``export.urdf.anchor_meshes``);
    MuJoCo and yourdfpy find them in ``meshes/`` whatever the folder (the URDF's
    ``<mujoco><compiler meshdir>``), so a moved bundle still loads there."""
    from export.urdf import anchor_meshes

    if not any(n.endswith(".urdf") for n in files):
        return files
    return {
        n: anchor_meshes(t, folder / Path(n).parent) if n.endswith(".urdf") else t
        for n, t in files.items()
    }


def check_out(out: str | Path, force: bool = False) -> Path:
    """Refuse ``out`` as ``write_bundle`` would, before any work (ExportError); returns
    it as an absolute path (its folder resolved, its last name not)."""
    target = _target(out)
    shown = os.fspath(out)
    state = _state(target, shown)
    if state == "full" and not force:
        raise ExportError(f"{shown}: already exists and is not empty; pass --force to replace it")
    if state == "full" and not _ours(target):
        raise ExportError(
            f"{shown}: not a folder parmor wrote (no {MARKER} file, no design.json of ours); "
            "--force replaces only those: remove it yourself or choose another folder"
        )
    return target


def _target(out: str | Path) -> Path:
    """``out`` as an absolute path whose folder is resolved and whose last name is not
    (a link there stays a link); refuses names that are not a folder of its own."""
    text = os.fspath(out)
    name = Path(text).name
    if not text.strip() or name in ("", ".", "..") or text.rstrip("/").endswith(("/.", "/..")):
        raise ExportError(
            f"--out {text!r}: expected the name of a folder to write (not '', '.', '..' or '/')"
        )
    try:
        target = Path(text).parent.resolve() / name
        here = Path.cwd().resolve()
    except (OSError, RuntimeError) as e:
        raise ExportError(f"{text}: cannot resolve: {e}") from None
    if target == here or target in here.parents:
        raise ExportError(f"{text}: is the working folder or holds it; choose another folder")
    return target


def _state(target: Path, shown: str) -> str:
    """'absent', 'empty' or 'full'; refuses a link or a file."""
    try:
        st = target.lstat()
    except FileNotFoundError:
        return "absent"
    except OSError as e:
        raise ExportError(f"{shown}: cannot use: {e.strerror}") from None
    import stat

    if stat.S_ISLNK(st.st_mode):
        raise ExportError(
            f"{shown}: is a symbolic link; parmor does not write through links: give the "
            "folder it points to, or another name"
        )
    if not stat.S_ISDIR(st.st_mode):
        raise ExportError(f"{shown}: exists and is not a folder")
    try:
        with os.scandir(target) as it:
            return "full" if any(True for _ in it) else "empty"
    except OSError as e:
        raise ExportError(f"{shown}: cannot read: {e.strerror}") from None


def _ours(folder: Path) -> bool:
    """Whether parmor wrote ``folder``: it holds ``MARKER``, or (a bundle written before
    the marker) a design.json that is a design record; or it lies one or two levels inside
    such a folder (the ROS package in ``DIR/ros/``, the block page in ``DIR/blocks/``)."""
    for d in (folder, folder.parent, folder.parent.parent):
        if (d / MARKER).is_file() and not (d / MARKER).is_symlink():
            return True
        try:
            rec = json.loads((d / "design.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(rec, dict) and "robot_type" in rec and "abilities" in rec:
            return True
    return False


def _prefix(target: Path) -> str:
    """The name every temporary folder of ``target`` starts with (short: a long name
    plus the suffix would pass the file system's limit)."""
    raw = os.fsencode(target.name)
    digest = hashlib.sha1(raw).hexdigest()[:8]
    short = os.fsdecode(raw[:60]) if len(raw) > 60 else target.name
    return f".{short}.{digest}.parmor-"


def _temp_dir(target: Path, kind: str) -> Path:
    path = target.parent / f"{_prefix(target)}{kind}-{os.getpid()}-{secrets.token_hex(4)}"
    path.mkdir(mode=0o700)
    path.chmod(DIR_MODE)
    return path


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # another user's: alive
    return True


def _clean_leftovers(target: Path) -> None:
    """Delete the temporary folders of ``target`` whose process is gone (a run killed
    before its end); put an old folder back where ``target`` is absent (killed between
    the two renames of the fallback)."""
    prefix = _prefix(target)
    try:
        with os.scandir(target.parent) as it:
            names = sorted(e.name for e in it if e.name.startswith(prefix))
    except OSError:
        return
    for name in names:
        kind, _, rest = name[len(prefix) :].partition("-")
        pid = rest.partition("-")[0]
        if kind not in ("new", "old") or not pid.isdigit() or _alive(int(pid)):
            continue
        path = target.parent / name
        if kind == "old" and not os.path.lexists(target):
            with contextlib.suppress(OSError):
                os.rename(path, target)
                continue
        shutil.rmtree(path, ignore_errors=True)


def _make_parents(parent: Path, shown: str) -> list[Path]:
    """Create ``parent`` and the folders above it that are missing; returns those made
    (removed again when the write fails)."""
    missing = []
    d = parent
    while not os.path.lexists(d) and d != d.parent:
        missing.append(d)
        d = d.parent
    made = []
    try:
        for d in reversed(missing):
            d.mkdir()
            made.append(d)
    except OSError as e:
        for d in reversed(made):
            with contextlib.suppress(OSError):
                d.rmdir()
        raise ExportError(f"{shown}: cannot create: {e.strerror}") from None
    if not parent.is_dir():
        raise ExportError(f"{shown}: {parent} is not a folder")
    return made


def _write_files(tmp: Path, files: Mapping[str, str | bytes], modes: Mapping[str, int]) -> None:
    """Write ``files`` and ``MARKER`` into the fresh folder ``tmp``."""
    for name, content in sorted({**files, MARKER: MARKER_TEXT}.items()):
        path = tmp / name
        for d in reversed(path.relative_to(tmp).parents[:-1]):
            (tmp / d).mkdir(exist_ok=True)
            (tmp / d).chmod(DIR_MODE)
        if isinstance(content, str):
            path.write_text(content, encoding="utf-8", newline="\n")
        else:
            path.write_bytes(content)
        path.chmod(modes.get(name, FILE_MODE))


def _commit(tmp: Path, target: Path, shown: str, force: bool) -> None:
    """Put the written folder ``tmp`` in ``target``'s place (see write_bundle)."""
    appeared = ExportError(
        f"{shown}: a folder or file appeared there while the bundle was written; it was "
        "left alone and nothing was written (run again to replace it)"
    )
    state = _state(target, shown)
    if state != "full":
        try:
            os.rename(tmp, target)
        except OSError as e:
            if e.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
                raise appeared from None
            raise
        return
    if not force or not _ours(target):
        raise appeared
    if _exchange(tmp, target):
        if not _ours(tmp):  # swapped in between for a folder that is not ours: swap back
            _exchange(tmp, target)
            raise appeared
        shutil.rmtree(tmp, ignore_errors=True)
        return
    old = target.parent / f"{_prefix(target)}old-{os.getpid()}-{secrets.token_hex(4)}"
    os.rename(target, old)
    try:
        os.rename(tmp, target)
    except OSError:
        with contextlib.suppress(OSError):
            os.rename(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


#: renameat2's flag that swaps two paths atomically (Linux 3.15; glibc 2.28 has the call)
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap the folders ``a`` and ``b`` in one step (renameat2 RENAME_EXCHANGE); False
    where that is not available (not Linux, an old C library, a file system without it)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [
        ctypes.c_int,
        ctypes.c_char_p,
        ctypes.c_int,
        ctypes.c_char_p,
        ctypes.c_uint,
    ]
    renameat2.restype = ctypes.c_int
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))
