"""The output bundle: every file of a design (``bundle_files``), and writing a folder
atomically (``write_bundle``): all files appear together or none do."""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import errno
import hashlib
import json
import os
import re
import secrets
import shutil
import stat
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from adron import readers
from adron.errors import ExportError, InfeasibleError, InputError
from export.record import to_json
from gaits import controller_for
from gaits.base import DesignGeometry

if TYPE_CHECKING:
    from adron.catalog import Catalog
    from export.model3d import Assembly
    from export.split import Bed
    from synth.sizing.structure import Structure

_SAFE_STEM = re.compile(r"[a-z0-9_]+")


def picture_files(asm: Assembly, title: str) -> dict[str, bytes]:
    """``pictures/robot.png`` (the robot at its zero pose), ``pictures/<part>.png`` (each
    printed part as it lies on the bed) and ``pictures/<part>_pieces.png`` (a part split
    for the user's bed: its pieces drawn apart)."""
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
    for p in asm.printed:
        if p.joints:  # split for the user's bed: its pieces drawn apart
            from export.render import pieces_png

            parts = [read_stl(x.in_part) for x in p.pieces]
            out[f"pictures/{p.name}_pieces.png"] = pieces_png(
                [(v / 1000.0, f) for v, f in parts], f"{p.name}: {len(parts)} pieces"
            )
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
    bed: Bed | None = None,
) -> dict[str, str | bytes]:
    """Every file of the bundle of a sized design: design.json, robot.urdf, robot.xml,
    meshes/*.stl, bom.csv and README.md (relative name -> content). The models carry the
    payload only ``with_payload``; design.json says where it is (``payload``).
    ``simulated_only``: just what a simulation reads (design.json, robot.xml, meshes), for
    the verification's own bundle. ``bed``: the user's printer (``--bed``): every printed
    part is made to fit it, turned or split (``export.split``; ``print/<piece>.stl``)."""
    from export.bom import bom_csv
    from export.guide import guide_markdown
    from export.mjcf import mjcf_string
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
    if bed is not None:
        from export.split import fit_assembly

        asm = fit_assembly(
            asm,
            bed,
            catalog.passive.print_clearance_m,
            catalog.material.density_kg_m3,
        )
    files: dict[str, str | bytes] = {
        "design.json": to_json(record),
        "robot.urdf": urdf_string(asm, with_payload=with_payload),
        "robot.xml": mjcf_string(asm, with_payload=with_payload),
        "bom.csv": bom_csv(asm),
        "README.md": guide_markdown(record, asm, documentation, pictures),
        "print/prusaslicer.ini": prusa_config(
            [b * 1000 for b in (bed.size_m if bed else ini_bed(asm, catalog))],
            catalog.material.density_kg_m3 / 1000,
        ),
    }
    if pictures:
        files |= picture_files(asm, record["robot_type"])
    for p in asm.printed:
        files[f"meshes/{p.name}.stl"] = p.stl
        files |= {f"print/{x.name}.stl": x.stl for x in p.pieces}
    files |= print_projects(asm, catalog, bed)
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


def print_projects(asm: Assembly, catalog: Catalog, bed: Bed | None = None) -> dict[str, bytes]:
    """``print/<part>.3mf``: a PrusaSlicer project of each printed part on the bed of the
    printer the BOM names for it (none for a part no catalog printer holds), supports on
    only for a part with overhangs as it lies (``export.threemf``). On the user's ``bed``:
    a project of each part, or of each of its pieces (``print/<piece>.3mf``), on that bed."""
    from export.threemf import part_3mf

    density = catalog.material.density_kg_m3 / 1000
    out: dict[str, bytes] = {}
    if bed is not None:
        size = [b * 1000 for b in bed.size_m]
        for p in asm.printed:
            for x in p.pieces or (p,):
                out[f"print/{x.name}.3mf"] = part_3mf(
                    x.name, x.stl, p.count, size, density, x.overhang_m2 > 0
                )
        return out
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
    serves one of its abilities (``turning`` of a walking robot too, ``walking`` of a KIF
    ``heavy-walking`` under it: the record's ``ability_ancestors``; aliases left out), with
    default parameters (joint angles over time)."""
    return {f"trajectories/{n}.csv": t.csv() for n, t in _trajectories(record).items()}


def _trajectories(record: dict) -> dict:
    """Behaviour name -> its Trajectory with default parameters, for every behaviour the
    design lists (``Controller.listed``), in name order."""

    try:
        controller = controller_for(DesignGeometry.from_record(record))
    except ValueError:  # no controller serves this structure yet: no trajectories to write
        return {}
    out = {}
    for name in controller.listed(record.get("abilities", ())):
        if not _SAFE_BEHAVIOR.fullmatch(name):
            raise ExportError(f"behaviour name {name!r} is not a safe file name")
        try:
            out[name] = controller.run(name)
        except ValueError as e:  # e.g. a default target this arm cannot reach: exit 1
            # no option of a design sets a behaviour's default targets: no such advice
            why = re.sub(r";\s*choose other targets\b", "", str(e)).strip()
            raise InfeasibleError(
                f"{record.get('robot_type')}: its behaviour {name!r} cannot be planned with "
                f"its default parameters: {why}"
            ) from None
    return out


_SAFE_BEHAVIOR = re.compile(r"[a-z0-9_-]+")
#: Modes of the bundle's folders and files: everyone may read them (a shared machine, a
#: web server), whatever the umask; ``tempfile.mkdtemp`` alone would leave 0700.
DIR_MODE = 0o755
FILE_MODE = 0o644
#: The file ``write_bundle`` leaves in every folder it writes: the list of the files it
#: wrote there, each with its SHA-256 (``manifest_text``). ``force`` replaces only those
#: files, and only as parmor wrote them, in a folder holding it; every other file there
#: (``.git``, a user's program, the block page of a bundle) is kept.
MARKER = ".parmor"
MANIFEST_NOTE = (
    "The files parmor wrote into this folder, with their SHA-256. 'parmor ... --force' "
    "replaces these files when they are unchanged and keeps every other file here."
)
#: The marker of folders written before the manifest: it lists no files, so parmor cannot
#: tell its files from a user's there (such a folder is refused, as a foreign one is).
LEGACY_MARKER_TEXT = (
    "This folder was written by parmor; 'parmor ... --force' may replace it whole.\n"
    "Remove this file to keep parmor from replacing it.\n"
)


def manifest_text(files: Mapping[str, str | bytes]) -> str:
    """``MARKER``'s text for a folder holding ``files`` (relative name -> content; a str is
    written as UTF-8): each name with ``sha256:<hex>`` of its bytes, in name order."""
    from export.manifest import MANIFEST_FORMAT  # (its schema's pydantic: only when written)

    listed = {
        Path(name).as_posix(): "sha256:" + hashlib.sha256(_bytes(content)).hexdigest()
        for name, content in files.items()
    }
    body = {"format": MANIFEST_FORMAT, "note": MANIFEST_NOTE, "files": listed}
    return json.dumps(body, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


def _bytes(content: str | bytes) -> bytes:
    return content.encode("utf-8") if isinstance(content, str) else content


def write_bundle(
    out: str | Path,
    files: Mapping[str, str | bytes],
    force: bool = False,
    modes: Mapping[str, int] | None = None,
    adopt: bool = False,
) -> Path:
    """Write ``files`` (relative name -> content) into the folder ``out``; returns it.

    The files are written to a temporary sibling folder that then takes ``out``'s place in
    one atomic step, so that ``out`` holds the old files or the new ones, never a mix or
    nothing, whenever the process is killed:

    - ``out`` absent or empty: ``rename`` (which fails, rather than replace it, when a
      non-empty folder or a file appeared at ``out`` meanwhile);
    - ``out`` a non-empty folder holding ``MARKER`` (``force``): every file there that
      ``MARKER`` does not list (or a folder of them) is hard-linked into the new folder at
      the same place (``_plan``, ``_carry``); on Linux ``renameat2`` with
      ``RENAME_EXCHANGE`` swaps the two folders; where the exchange is not available,
      ``out`` is renamed aside and the new folder into place (a kill between the two
      renames leaves ``out`` absent: the next write to ``out`` puts the old one back
      first). The old folder is then emptied of parmor's files and of the links' other
      names (``_discard``): what the new folder does not hold is moved there, never
      deleted.

    Refused (ExportError naming the value, nothing written): an ``out`` of '', '.', '..'
    or '/', the working folder or one above it, a symbolic link (never followed: the link
    is not a folder of ours), a file, a non-empty folder without ``force`` or, with it,
    one without ``MARKER`` (unless ``adopt``: the block page's folder, whose files are all
    kept), a file ``MARKER`` lists that was changed since, and a kept file where a new
    file or folder goes. Every folder written holds ``MARKER`` (``manifest_text``). Files
    get ``FILE_MODE``, or their mode in ``modes`` (an executable script), folders
    ``DIR_MODE``.

    Temporary folders are named ``.<out>.<hash>.parmor-new|old-<pid>-<random>`` beside
    ``out``; one left by a killed run (its process gone) is emptied as the old folder is
    (``_discard``) by the next write to the same ``out``.
    """
    modes = modes or {}
    names = set()
    for name in files:
        parts = Path(name).parts
        if Path(name).is_absolute() or ".." in parts or not parts or parts == (MARKER,):
            raise ExportError(f"{name!r}: a bundle file must stay inside the folder")
        names.add(Path(name).as_posix())
    target = _target(out)
    _clean_leftovers(target)
    shown = os.fspath(out)
    plan = _plan(target, shown, names, force, adopt)
    made = _make_parents(target.parent, shown)
    tmp = None
    try:
        tmp = _temp_dir(target, "new")
        _write_files(tmp, anchor_urdfs(files, target), modes)
        _commit(tmp, target, shown, plan, names, force, adopt)
        tmp = None
    except OSError as e:
        raise ExportError(f"{shown}: cannot write: {e.strerror or e}") from None
    finally:
        if tmp is not None:
            _rmtree(tmp)
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
    _plan(target, os.fspath(out), set(), force, adopt=False)
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


def _read_manifest(folder: Path, shown: str) -> tuple[bytes | None, dict[str, str]]:
    """(``MARKER``'s bytes, relative name -> ``sha256:<hex>``) of ``folder``; (None, {})
    when it holds no ``MARKER``. ExportError naming it when it is not a list of parmor's
    files (a link, a folder, the marker of an older parmor, malformed)."""
    path = folder / MARKER
    where = os.path.join(shown, MARKER)
    try:
        st = path.lstat()
    except FileNotFoundError:
        return None, {}
    except OSError as e:
        raise ExportError(f"{where}: cannot read: {e.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise ExportError(f"{where}: is not a file parmor wrote (a link or a folder)")
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise ExportError(f"{where}: cannot read: {e.strerror}") from None
    if raw == LEGACY_MARKER_TEXT.encode():
        raise ExportError(
            f"{where}: written by an older parmor, which did not list the files it wrote, so "
            "parmor cannot tell them from yours: move your files out and remove the folder "
            "yourself, or choose another folder"
        )
    try:
        body = readers.parse_json(raw.decode("utf-8"), where)  # nesting and numbers bounded
    except UnicodeDecodeError as e:
        raise ExportError(f"{where}: not parmor's list of its files ({e})") from None
    except InputError as e:
        raise ExportError(f"{e} (not parmor's list of its files)") from None
    from export.manifest import check_manifest

    listed = dict(check_manifest(body, where, ExportError).files)
    return raw, listed


def _entries(root: Path) -> list[tuple[str, os.stat_result]]:
    """Every entry below ``root``: (relative name with '/', its lstat), a folder right
    before what it holds, names in order; links are entries, never followed."""
    out: list[tuple[str, os.stat_result]] = []
    stack: list[tuple[Path, str]] = [(root, "")]
    while stack:  # no recursion: a deep tree is no error
        d, prefix = stack.pop()
        with os.scandir(d) as it:
            for e in it:
                st = e.stat(follow_symlinks=False)
                out.append((prefix + e.name, st))
                if stat.S_ISDIR(st.st_mode):
                    stack.append((d / e.name, prefix + e.name + "/"))
    return sorted(out, key=lambda e: e[0].split("/"))


def _sha(path: Path) -> str:
    with path.open("rb") as f:
        return "sha256:" + hashlib.file_digest(f, "sha256").hexdigest()


@dataclasses.dataclass
class _Plan:
    """What replacing the target involves: its state ('absent', 'empty', 'full'), its
    ``MARKER``'s bytes (None: none there), what is kept (relative names: every file that
    is not parmor's and every empty folder, each below the folders holding it) and the
    lstat of every entry."""

    state: str
    raw: bytes | None = None
    keep: list[str] = dataclasses.field(default_factory=list)
    stats: dict[str, os.stat_result] = dataclasses.field(default_factory=dict)


def _plan(target: Path, shown: str, names: set[str], force: bool, adopt: bool) -> _Plan:
    """The target's ``_Plan``; ExportError naming what is refused: a non-empty folder
    without ``force``, one without ``MARKER`` (unless ``adopt``), a file ``MARKER`` lists
    that was changed since, a kept entry where one of the new ``names`` (or a folder of
    them) goes."""
    state = _state(target, shown)
    if state != "full":
        return _Plan(state)
    if not force:
        raise ExportError(
            f"{shown}: already exists and is not empty; pass --force to replace it (the "
            "files parmor wrote there; other files are kept)"
        )
    raw, listed = _read_manifest(target, shown)
    if raw is None and not adopt:
        raise ExportError(
            f"{shown}: not a folder parmor wrote (it holds no {MARKER} listing parmor's files); "
            "--force replaces only those: remove it yourself or choose another folder"
        )
    try:
        entries = _entries(target)
    except OSError as e:
        raise ExportError(f"{shown}: cannot read {e.filename}: {e.strerror}") from None
    folders = {p.as_posix() for n in names for p in Path(n).parents} - {"."}
    entries_st = dict(entries)
    keep = []
    holding: set[str] = set()  # folders holding something
    for rel, st in entries:
        holding.add(rel.rpartition("/")[0])
        if rel == MARKER or stat.S_ISDIR(st.st_mode):
            continue
        digest = listed.get(rel)
        if digest is None:
            keep.append(rel)
            continue
        try:
            same = stat.S_ISREG(st.st_mode) and _sha(target / rel) == digest
        except OSError as e:
            raise ExportError(f"{os.path.join(shown, rel)}: cannot read: {e.strerror}") from None
        if not same:
            raise ExportError(
                f"{os.path.join(shown, rel)}: parmor wrote this file and it was changed "
                "since; --force replaces only parmor's files as parmor wrote them: move "
                "yours out of the folder (or delete it) and run again"
            )
    keep += [rel for rel, st in entries if stat.S_ISDIR(st.st_mode) and rel not in holding]
    keep.sort(key=lambda r: r.split("/"))
    for rel in keep:
        parts = rel.split("/")
        last = not stat.S_ISDIR(entries_st[rel].st_mode)  # a kept file where a folder goes
        for i in range(1, len(parts) + 1):
            p = "/".join(parts[:i])
            if p in names or (last and i == len(parts) and p in folders):
                what = "file" if p in names else "folder"
                raise ExportError(
                    f"{os.path.join(shown, rel)}: parmor did not write it, and a new {what} "
                    f"goes at {p!r}; move it out of the folder and run again"
                )
    return _Plan(state, raw, keep, entries_st)


def _carry(target: Path, tmp: Path, plan: _Plan, shown: str) -> dict[str, tuple[int, int]]:
    """Hard-link every kept entry of ``target`` into ``tmp`` at the same place (folders
    made, with their modes at the end); returns relative name -> (device, inode) of each
    link made. ExportError naming an entry that cannot be linked."""
    made: list[tuple[Path, int]] = []
    ready: set[str] = set()  # folders of tmp known to exist
    carried = {}
    for rel in plan.keep:
        parts = rel.split("/")
        try:
            for i in range(1, len(parts) + 1):
                sub = "/".join(parts[:i])
                st = plan.stats[sub]
                if i < len(parts) or stat.S_ISDIR(st.st_mode):
                    if sub not in ready:
                        d = tmp / sub
                        if not os.path.lexists(d):
                            d.mkdir()
                            made.append((d, stat.S_IMODE(st.st_mode)))
                        ready.add(sub)
                    continue
                os.link(target / rel, tmp / rel, follow_symlinks=False)
                got = os.lstat(tmp / rel)
                carried[rel] = (got.st_dev, got.st_ino)
        except OSError as e:
            raise ExportError(
                f"{os.path.join(shown, rel)}: cannot keep it (a hard link in the new folder "
                f"failed: {e.strerror}); nothing was written"
            ) from None
    for d, mode in reversed(made):
        d.chmod(mode)
    return carried


def _prefix(target: Path) -> str:
    """The name every temporary folder of ``target`` starts with (short: a long name
    plus the suffix would pass the file system's limit)."""
    raw = os.fsencode(target.name)
    digest = hashlib.sha1(raw).hexdigest()[:8]
    short = os.fsdecode(raw[:60]) if len(raw) > 60 else target.name
    return f".{short}.{digest}.parmor-"


def _temp_name(target: Path, kind: str) -> Path:
    return target.parent / f"{_prefix(target)}{kind}-{os.getpid()}-{secrets.token_hex(4)}"


def _temp_dir(target: Path, kind: str) -> Path:
    path = _temp_name(target, kind)
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
    """Empty the temporary folders of ``target`` whose process is gone (a run killed
    before its end; ``_discard``); put an old folder back where ``target`` is absent
    (killed between the two renames of the fallback) first."""
    prefix = _prefix(target)
    try:
        with os.scandir(target.parent) as it:
            names = sorted(e.name for e in it if e.name.startswith(prefix))
    except OSError:
        return
    dead = []
    for name in names:
        kind, _, rest = name[len(prefix) :].partition("-")
        pid = rest.partition("-")[0]
        if kind in ("new", "old", "mark") and pid.isdigit() and not _alive(int(pid)):
            dead.append((kind, target.parent / name))
    for kind, path in dead:
        if kind == "old" and not os.path.lexists(target):
            with contextlib.suppress(OSError):
                os.rename(path, target)
    for kind, path in dead:
        if kind == "mark":
            with contextlib.suppress(OSError):
                if stat.S_ISREG(path.lstat().st_mode):
                    path.unlink()
        elif os.path.lexists(path):
            _discard(path, target)


def _discard(
    folder: Path, target: Path, carried: Mapping[str, tuple[int, int]] | None = None
) -> None:
    """Delete the replaced folder (or a killed run's temporary one) ``folder`` whose
    successor is ``target``, deleting only what is parmor's or held by ``target`` too:
    files its ``MARKER`` lists, unchanged; files ``target`` holds at the same place
    (the other name of a link ``_carry`` made). Any other file (written there while the
    folders were swapped) is moved into ``target`` where that place is free or holds the
    link made of it (``carried``), and kept here otherwise. A folder with no ``MARKER``
    is a new folder killed before its end (only parmor's files): deleted whole; one whose
    ``MARKER`` is not parmor's list is left alone."""
    try:
        raw, listed = _read_manifest(folder, str(folder))
        entries = _entries(folder) if raw is not None else []
    except (ExportError, OSError):
        return
    if raw is None:
        _rmtree(folder)
        return
    carried = carried or {}
    there_st = _lstat(target)
    into = there_st is not None and stat.S_ISDIR(there_st.st_mode)
    for rel, st in reversed(entries):  # what a folder holds before the folder
        if rel == MARKER:
            continue
        path = folder / rel
        with contextlib.suppress(OSError):
            if stat.S_ISDIR(st.st_mode):
                path.rmdir()  # only when emptied
                continue
            if rel in listed and stat.S_ISREG(st.st_mode) and _sha(path) == listed[rel]:
                path.unlink()
                continue
            there = _lstat(target / rel) if into else None
            ident = (st.st_dev, st.st_ino)
            if there is not None and (there.st_dev, there.st_ino) == ident:
                path.unlink()
                continue
            free = there is None or carried.get(rel) == (there.st_dev, there.st_ino)
            if into and free and _folders_inside(target, rel):
                os.rename(path, target / rel)
    with contextlib.suppress(OSError):
        if [p.name for p in folder.iterdir()] == [MARKER]:
            (folder / MARKER).unlink()
            folder.rmdir()


def _lstat(path: Path) -> os.stat_result | None:
    try:
        return path.lstat()
    except OSError:
        return None


def _folders_inside(root: Path, rel: str) -> bool:
    """Make the folders of ``rel`` below ``root`` that are missing; False when one of
    them is a link or a file."""
    d = root
    for part in rel.split("/")[:-1]:
        d = d / part
        st = _lstat(d)
        if st is None:
            d.mkdir()
        elif not stat.S_ISDIR(st.st_mode):
            return False
    return True


def _rmtree(path: Path) -> None:
    """Delete the folder ``path`` (a temporary folder of parmor's), its read-only folders
    (a kept folder's mode) included."""

    def retry(func, p, _exc) -> None:
        with contextlib.suppress(OSError):
            os.chmod(os.path.dirname(p), DIR_MODE | 0o200)
            func(p)

    shutil.rmtree(path, onerror=retry)


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
    """Write ``files`` into the fresh folder ``tmp``, then ``MARKER`` listing them (a
    folder killed before its end has none: ``_discard`` deletes it whole)."""
    for name, content in sorted(files.items()):
        path = tmp / name
        for d in reversed(path.relative_to(tmp).parents[:-1]):
            (tmp / d).mkdir(exist_ok=True)
            (tmp / d).chmod(DIR_MODE)
        if isinstance(content, str):
            path.write_text(content, encoding="utf-8", newline="\n")
        else:
            path.write_bytes(content)
        path.chmod(modes.get(name, FILE_MODE))
    (tmp / MARKER).write_text(manifest_text(files), encoding="utf-8", newline="\n")
    (tmp / MARKER).chmod(FILE_MODE)


def _mark(target: Path, shown: str) -> bytes:
    """Give the adopted folder ``target`` an empty ``MARKER`` (parmor wrote nothing there
    yet), so that a killed run's old folder is never taken for a new one; returns it."""
    raw = manifest_text({}).encode()
    path = _temp_name(target, "mark")
    path.write_bytes(raw)
    path.chmod(FILE_MODE)
    try:
        os.link(path, target / MARKER)
    except FileExistsError:
        raise ExportError(
            f"{os.path.join(shown, MARKER)}: appeared while the files were written; nothing "
            "was written (run again)"
        ) from None
    finally:
        path.unlink()
    return raw


def _commit(
    tmp: Path, target: Path, shown: str, plan: _Plan, names: set[str], force: bool, adopt: bool
) -> None:
    """Put the written folder ``tmp`` in ``target``'s place (see write_bundle); ``plan``
    is what ``target`` was before the files were written."""
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
    if plan.state != "full" or _manifest_raw(target) != plan.raw:
        raise appeared
    now = _plan(target, shown, names, force, adopt)  # a file changed meanwhile: named
    if now.raw is None:
        now.raw = _mark(target, shown)
    carried = _carry(target, tmp, now, shown)
    if _exchange(tmp, target):
        if _manifest_raw(tmp) != now.raw:  # swapped in meanwhile: not that folder, swap back
            _exchange(tmp, target)
            raise appeared
        _discard(tmp, target, carried)
        return
    old = _temp_name(target, "old")
    os.rename(target, old)
    try:
        os.rename(tmp, target)
    except OSError:
        with contextlib.suppress(OSError):
            os.rename(old, target)
        raise
    _discard(old, target, carried)


def _manifest_raw(folder: Path) -> bytes | None:
    """``MARKER``'s bytes in ``folder`` (None: none, or not a readable file)."""
    path = folder / MARKER
    st = _lstat(path)
    if st is None or not stat.S_ISREG(st.st_mode):
        return None
    try:
        return path.read_bytes()
    except OSError:
        return None


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
