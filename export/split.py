"""Printing a design on the user's printer (``parmor design --bed``): every printed part
either fits that bed as it lies, or is turned to fit it, or is split into pieces that do,
joined by dovetails.

- **As it lies**: the part's STL (``meshes/<part>.stl``, in its print orientation) fits
  the bed with its skirt (``export.slicer.SKIRT_MARGIN`` around it), untouched.
- **Turned** (:func:`place`): otherwise each orientation the part may print in is tried,
  best first (``meshes.ranked_orientations``: least support), and in each the turns about
  the vertical (0 and 90 degrees first, then the one leaving the most room, in steps of
  ``ANGLE_STEP_DEG``: a long part may fit across the bed's diagonal). The first that fits is
  shipped as ``print/<part>.stl``.
- **Split** (:func:`split_part`): otherwise the part, in its print orientation, is cut by
  planes across its axes into a grid of cells, the axis whose cells are longest cut once
  more until every piece fits (turned as above), no piece shorter than ``MIN_PIECE_MM``
  along a cut and at most ``MAX_PIECES``; a part no such grid fits refuses
  (:class:`adron.errors.InputError`: the bed is too small). At each cut the lower piece
  carries a dovetail tongue (a trapezoid across the cut, widening by ``FLANK_DEG`` away
  from it, centred on the part's section at the cut) that slides, along the part's
  thinnest axis, into the slot of the upper piece; the upper piece is cut back from the
  lower one by the catalog's ``print_clearance`` on every side (the slot's flanks and end,
  the shoulders): the pieces never overlap and, pushed together, reassemble the part with
  exactly that clearance between them (:func:`reassembly_problems` checks it).

Mass: the pieces are the part less the clearance gaps (a band ``print_clearance`` thick
over the cut faces: well under 0.1 % of a part). The models (robot.urdf, robot.xml) and
the BOM's part rows keep the part's own mass; the BOM's piece rows give each piece's, and
:func:`gap_mass` the difference. A dovetail takes no fastener.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from adron.errors import InputError
from export import meshes
from export.model3d import Assembly, PieceJoint, PrintedPart, PrintPiece
from export.polymesh import Mesh
from export.slicer import SKIRT_MARGIN, estimate

__all__ = [
    "MIN_PIECE_MM",
    "Bed",
    "Split",
    "bed_label",
    "fit_assembly",
    "gap_mass",
    "parse_bed",
    "place",
    "reassembly_problems",
    "split_part",
]

MM = 1000.0
AXES = "xyz"
#: mm: no piece is shorter than this along a cut (it must hold a tongue or a slot).
MIN_PIECE_MM = 20.0
#: At most this many pieces of one part.
MAX_PIECES = 64
#: The tongue: its neck is this share of the part's section across the cut, within
#: [TONGUE_MIN_MM, TONGUE_MAX_MM]; its depth this share of the neck, and at most
#: TONGUE_DEPTH_SHARE of the shorter of the two pieces' lengths along the cut; its flanks
#: widen by FLANK_DEG from the cut's normal (what locks it).
TONGUE_SHARE = 0.3
TONGUE_MIN_MM = 4.0
TONGUE_MAX_MM = 20.0
TONGUE_DEPTH = 0.6
TONGUE_DEPTH_SHARE = 0.3
FLANK_DEG = 15.0
#: mm^3: a tongue holds at least this much of the part (not one in a hole of its section).
MIN_TONGUE_MM3 = 1.0
#: A part is turned onto another face only if it then stands no taller than this times
#: its footprint's narrower side (a plate on its edge is split instead).
MAX_ASPECT = 2.0
#: Turns about the vertical tried to fit a part on the bed, degrees apart.
ANGLE_STEP_DEG = 0.5
#: mm: a bed no larger than this (less its skirt margin) holds no piece.
MIN_BED_MM = MIN_PIECE_MM + 2 * SKIRT_MARGIN
#: the largest bed side (mm) ``--bed`` takes: beyond any printer (adron.schema.MAX_LENGTH_M)
MAX_BED_MM = 2000.0

_SIZE = re.compile(r"^\s*([^x×]+?)\s*[x×]\s*([^x×]+?)\s*[x×]\s*([^x×]+?)\s*(mm|cm|m)?\s*$", re.I)
_UNIT = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}


@dataclass(frozen=True)
class Bed:
    """The user's printer: a label for the BOM and guide, its build volume (x, y, z) m."""

    label: str
    size_m: tuple[float, float, float]


def parse_bed(text: str) -> tuple[float, float, float] | None:
    """The build volume (x, y, z) m of ``WxDxH`` (``180x180x180mm``; unit mm, cm or m,
    default mm), None when ``text`` has not that form (a printer's name). ValueError naming
    the value when a figure is not a number, not positive or too small to hold a piece."""
    m = _SIZE.match(text)
    if m is None or not any(ch.isdigit() for ch in text):
        return None
    unit = _UNIT[(m.group(4) or "mm").lower()]
    out = []
    for raw in m.group(1, 2, 3):
        try:
            v = float(raw)
        except ValueError:
            raise ValueError(
                f"{text!r}: {raw!r} is not a number (expected WxDxH, e.g. 180x180x180mm)"
            ) from None
        if not math.isfinite(v) or v <= 0:
            raise ValueError(
                f"{text!r}: {raw!r} must be a positive length (expected WxDxH, e.g. 180x180x180mm)"
            )
        out.append(v * unit)
    for raw, v in zip(m.group(1, 2, 3), out, strict=True):
        if not v * MM <= MAX_BED_MM:  # a bed of 1e308 m is infinite in millimetres
            raise ValueError(
                f"{text!r}: a bed side of {raw}{m.group(4) or 'mm'} is beyond any printer "
                f"(at most {MAX_BED_MM:g} mm; docs/formats-schemas.md)"
            )
    small = [v for v in out if v * MM <= MIN_BED_MM]
    if small:
        raise ValueError(
            f"{text!r}: a bed side of {small[0] * MM:g} mm holds no printed piece "
            f"(at least {MIN_BED_MM:g} mm: a {MIN_PIECE_MM:g} mm piece and its skirt)"
        )
    return out[0], out[1], out[2]


def bed_label(size_m: Sequence[float]) -> str:
    """``180 x 180 x 180 mm``."""
    return " x ".join(f"{v * MM:g}" for v in size_m) + " mm"


# --- placing a part on the bed ------------------------------------------------------------


def _footprint_turn(xy: np.ndarray, bed: Sequence[float], margin: float) -> float | None:
    """The turn (rad) about the vertical that fits the points ``xy`` (n, 2) m inside
    ``bed`` (x, y) m with ``margin`` around them: 0 or a quarter turn when either fits,
    else the one leaving the most room; None when none does."""
    room = np.array([bed[0] - 2 * margin, bed[1] - 2 * margin])
    angles = np.radians(np.arange(0.0, 180.0, ANGLE_STEP_DEG))
    c, s = np.cos(angles), np.sin(angles)
    x = xy[:, :1] * c - xy[:, 1:] * s  # (n, k)
    y = xy[:, :1] * s + xy[:, 1:] * c
    w = x.max(axis=0) - x.min(axis=0)
    h = y.max(axis=0) - y.min(axis=0)
    slack = np.minimum(room[0] - w, room[1] - h)
    eps = 1e-9
    quarter = int(round(90.0 / ANGLE_STEP_DEG))
    for k in (0, quarter):
        if slack[k] >= -eps:
            return float(angles[k])
    k = int(np.argmax(slack))
    return float(angles[k]) if slack[k] >= -eps else None


def place(mesh: Mesh, bed: Sequence[float], margin: float = SKIRT_MARGIN / MM) -> Mesh | None:
    """``mesh`` moved onto ``bed`` (x, y, z m) so that it fits with ``margin`` m around its
    footprint: as it lies when it fits so; else its first orientation
    (``meshes.ranked_orientations``) and turn about the vertical that fits, lowest point on
    z = 0, footprint centred on the origin. None when none fits."""
    v = np.asarray(mesh.vertices, dtype=float)
    lo, hi = v.min(axis=0), v.max(axis=0)
    if (
        hi[0] - lo[0] + 2 * margin <= bed[0] + 1e-9
        and hi[1] - lo[1] + 2 * margin <= bed[1] + 1e-9
        and hi[2] - lo[2] <= bed[2] + 1e-9
    ):
        return mesh
    for k, R in enumerate(meshes.ranked_orientations(mesh)):
        w = v @ R.T
        height = w[:, 2].max() - w[:, 2].min()
        foot = w[:, :2].max(axis=0) - w[:, :2].min(axis=0)
        if height > bed[2] + 1e-9 or (k and height > MAX_ASPECT * foot.min()):
            continue
        turn = _footprint_turn(w[:, :2], bed, margin)
        if turn is None:
            continue
        c, s = math.cos(turn), math.sin(turn)
        Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        Q = Rz @ R
        w = v @ Q.T
        lo, hi = w.min(axis=0), w.max(axis=0)
        T = np.eye(4)
        T[:3, :3] = Q
        T[:3, 3] = (-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2])
        return mesh.copy().apply_transform(T)
    return None


# --- splitting ----------------------------------------------------------------------------


def _manifold(mesh: Mesh):
    """``mesh`` (m) as a manifold3d solid in mm."""
    import manifold3d as mf

    return mf.Manifold(
        mf.Mesh(
            vert_properties=np.ascontiguousarray(mesh.vertices * MM, dtype=np.float32),
            tri_verts=np.ascontiguousarray(mesh.faces, dtype=np.uint32),
        )
    )


def _box(lo: Sequence[float], hi: Sequence[float]):
    import manifold3d as mf

    size = [float(h - lo_) for lo_, h in zip(lo, hi, strict=True)]
    return mf.Manifold.cube(size).translate(tuple(float(x) for x in lo))


@dataclass(frozen=True)
class _Cut:
    """A cut across ``axis`` at ``at`` mm between the cells ``low`` and ``high``: the low
    cell's tongue (a trapezoid in the (axis, across) plane, neck ``neck`` mm wide at the
    cut, ``depth`` mm deep, centred on ``centre`` of ``across``) runs along ``slide`` over
    ``span`` (mm)."""

    axis: int
    at: float
    low: tuple[int, int, int]
    high: tuple[int, int, int]
    slide: int
    across: int
    centre: float
    neck: float
    depth: float
    span: tuple[float, float]


def _prism(cut: _Cut, grow: float):
    """The tongue of ``cut`` grown by ``grow`` mm on every side of its profile (a mitred
    offset; over its whole run along the slide axis), as a manifold in mm."""
    import manifold3d as mf

    w0 = cut.neck / 2
    w1 = w0 + cut.depth * math.tan(math.radians(FLANK_DEG))
    # profile in (u, v) = (along the axis from the cut, across from the centre)
    pts = [(0.0, -w0), (cut.depth, -w1), (cut.depth, w1), (0.0, w0)]  # counter-clockwise
    cs = mf.CrossSection([np.array(pts, dtype=float)])
    if grow > 0:
        cs = cs.offset(grow, mf.JoinType.Miter, 4.0)
    s0, s1 = cut.span
    solid = mf.Manifold.extrude(cs, s1 - s0)  # (u, v, w) with w along the slide
    # map (u, v, w) -> the part's axes: u along axis, v along across, w along slide
    M = np.zeros((3, 4))
    M[cut.axis, 0] = 1.0
    M[cut.across, 1] = 1.0
    M[cut.slide, 2] = 1.0
    M[cut.axis, 3] = cut.at
    M[cut.across, 3] = cut.centre
    M[cut.slide, 3] = s0
    if np.linalg.det(M[:, :3]) < 0:  # a mirror: flip w and start at the far end instead
        M[cut.slide, 2] = -1.0
        M[cut.slide, 3] = s1
    return solid.transform(M)


@dataclass(frozen=True)
class Split:
    """A part split for a bed: its pieces (in the part's print frame, m, and placed on the
    bed), and the cuts joining them."""

    pieces: tuple[Mesh, ...]  # in the part's frame (its STL's), m
    placed: tuple[Mesh, ...]  # each on the bed as it prints
    joints: tuple[tuple[int, int, str, float, str], ...]  # (low, high, axis, at m, slide)
    clearance_m: float


def _cells(lo: np.ndarray, hi: np.ndarray, n: Sequence[int]) -> list[np.ndarray]:
    """Cut positions (mm) along each axis: the part's bounds, ``n`` equal cells."""
    return [np.linspace(lo[k], hi[k], n[k] + 1) for k in range(3)]


def _build(part, lo: np.ndarray, hi: np.ndarray, n: Sequence[int], clearance: float):
    """The pieces (manifolds, mm, non-empty cells in index order, with their cell) and the
    cuts of the grid ``n`` over the part ``part``; None when the grid cannot be joined (a
    section with no room for a tongue, a tongue in a hole of its section, a cell with no
    material at a cut, or a piece in several bits)."""
    grid = _cells(lo, hi, n)
    ext = hi - lo
    pad = 1.0 + clearance
    cells = [(i, j, k) for i in range(n[0]) for j in range(n[1]) for k in range(n[2])]

    def bounds(c):
        a = np.array([grid[d][c[d]] for d in range(3)])
        b = np.array([grid[d][c[d] + 1] for d in range(3)])
        for d in range(3):  # the outer cells reach past the part
            if c[d] == 0:
                a[d] -= pad
            if c[d] == n[d] - 1:
                b[d] += pad
        return a, b

    cuts: list[_Cut] = []
    for c in cells:
        for axis in range(3):
            if c[axis] == n[axis] - 1:
                continue
            high = tuple(c[d] + (1 if d == axis else 0) for d in range(3))
            at = float(grid[axis][c[axis] + 1])
            a, b = bounds(c)
            # the part's section at the cut, within the cell's other two ranges
            sa, sb = a.copy(), b.copy()
            sa[axis], sb[axis] = at - 0.5, at + 0.5
            section = part ^ _box(sa, sb)
            if section.is_empty():
                continue
            slo, shi = (np.asarray(x, dtype=float) for x in _bbox(section))
            others = [d for d in range(3) if d != axis]
            slide = min(others, key=lambda d: (ext[d], d))
            across = next(d for d in others if d != slide)
            width = shi[across] - slo[across]
            cell_len = min(
                grid[axis][c[axis] + 1] - grid[axis][c[axis]],
                grid[axis][high[axis] + 1] - grid[axis][high[axis]],
            )
            neck = min(max(TONGUE_SHARE * width, TONGUE_MIN_MM), TONGUE_MAX_MM)
            depth = min(TONGUE_DEPTH * neck, TONGUE_DEPTH_SHARE * cell_len)
            w1 = neck + 2 * depth * math.tan(math.radians(FLANK_DEG))
            if w1 + 2 * clearance + 2.0 > width or depth < 1.0:
                return None  # no room for a tongue on this section
            # over the section along the slide, past it but not into the next cells
            span = (max(slo[slide] - 1.0, a[slide]), min(shi[slide] + 1.0, b[slide]))
            cuts.append(
                _Cut(
                    axis,
                    at,
                    c,
                    high,
                    slide,
                    across,
                    (slo[across] + shi[across]) / 2,
                    neck,
                    depth,
                    span,
                )
            )
    for cut in cuts:  # a tongue in a hole of the section joins nothing
        if (part ^ _prism(cut, 0.0)).volume() < MIN_TONGUE_MM3:
            return None
    pieces = []
    for c in cells:
        a, b = bounds(c)
        region = _box(a, b)
        for cut in cuts:
            if cut.low == c:
                region = region + _prism(cut, 0.0)
            if cut.high == c:
                # cut back from the low cell (its tongue and its face) by the clearance
                sa, sb = a.copy(), b.copy()
                sb[cut.axis] = cut.at + clearance
                region = region - _box(sa, sb) - _prism(cut, clearance)
        piece = part ^ region
        if piece.is_empty():
            if any(cut.low == c or cut.high == c for cut in cuts):
                return None
            continue
        if len(piece.decompose()) != 1:
            return None
        pieces.append((c, piece))
    return pieces, cuts


def _bbox(solid) -> tuple[tuple[float, ...], tuple[float, ...]]:
    b = solid.bounding_box()
    return tuple(b[:3]), tuple(b[3:])


def _to_mesh_m(solid) -> Mesh:
    return meshes._to_mesh(solid.scale((1 / MM, 1 / MM, 1 / MM)))


def split_part(
    mesh: Mesh,
    bed: Sequence[float],
    clearance: float,
    name: str = "part",
    margin: float = SKIRT_MARGIN / MM,
) -> Split:
    """``mesh`` (a part in its print frame, m) cut into the fewest pieces of the grids tried
    (see the module's doc) that each fit ``bed`` (m) turned as :func:`place` turns them,
    joined by dovetails with ``clearance`` m. InputError naming the part when no grid with
    pieces of at least ``MIN_PIECE_MM`` (at most ``MAX_PIECES``) fits."""
    part = _manifold(mesh)
    lo, hi = (np.asarray(x, dtype=float) for x in _bbox(part))
    ext = hi - lo
    c = clearance * MM
    n = [1, 1, 1]
    tried = set()
    while True:
        tried.add(tuple(n))
        built = _build(part, lo, hi, n, c) if math.prod(n) > 1 else None
        if built is not None:
            pieces, cuts = built
            meshes_m = [_to_mesh_m(p) for _, p in pieces]
            placed = [place(m, bed, margin) for m in meshes_m]
            if all(p is not None for p in placed):
                index = {cell: k for k, (cell, _) in enumerate(pieces)}
                joints = tuple(
                    (index[cut.low], index[cut.high], AXES[cut.axis], cut.at / MM, AXES[cut.slide])
                    for cut in cuts
                )
                return Split(tuple(meshes_m), tuple(placed), joints, clearance)  # type: ignore[arg-type]
        # cut the axis of the longest cells once more
        order = sorted(range(3), key=lambda d: (-ext[d] / n[d], d))
        for d in order:
            m = list(n)
            m[d] += 1
            if (
                ext[d] / m[d] >= MIN_PIECE_MM
                and math.prod(m) <= MAX_PIECES
                and tuple(m) not in tried
            ):
                n = m
                break
        else:
            size = " x ".join(f"{x:.0f}" for x in ext)
            raise InputError(
                f"--bed {bed_label(bed)}: the printed part '{name}' ({size} mm) cannot be cut "
                f"into pieces that fit it (pieces of at least {MIN_PIECE_MM:g} mm, at most "
                f"{MAX_PIECES}, each cut holding a dovetail); choose a larger printer"
            )


def gap_mass(part_mass: float, pieces: Sequence[PrintPiece]) -> float:
    """kg the clearance gaps take from a split part (its mass less its pieces')."""
    return part_mass - sum(p.mass_kg for p in pieces)


# --- checking the pieces -------------------------------------------------------------------


def reassembly_problems(
    part: Mesh,
    pieces: Sequence[Mesh],
    joints: Sequence[tuple[int, int, str, float, str]],
    clearance: float,
    tol_mm: float = 1e-3,
) -> list[str]:
    """How ``pieces`` (m, in the part's frame) fail to reassemble ``part`` with exactly
    ``clearance`` m between them (manifold3d): a piece overlapping another or leaving the
    part, two pieces closer than the clearance, two joined pieces (``joints``) farther
    apart, or more of the part missing than a band of the clearance over the cut faces
    (half the area the pieces' surfaces add to the part's) holds. Empty when they do."""
    P = _manifold(part)
    S = [_manifold(p) for p in pieces]
    c = clearance * MM
    vol_tol = max(1e-3, 1e-6 * P.volume())
    out: list[str] = []
    for i, a in enumerate(S):
        outside = (a - P).volume()
        if outside > vol_tol:
            out.append(f"piece {i + 1} leaves the part by {outside:.3g} mm^3")
        for j in range(i + 1, len(S)):
            b = S[j]
            overlap = (a ^ b).volume()
            if overlap > vol_tol:
                out.append(f"pieces {i + 1} and {j + 1} overlap by {overlap:.3g} mm^3")
                continue
            gap = a.min_gap(b, 2 * c + 1.0)
            if gap < c - tol_mm:
                out.append(
                    f"pieces {i + 1} and {j + 1} are {gap:.4g} mm apart, less than the "
                    f"{c:g} mm clearance"
                )
    for low, high, *_ in joints:
        gap = S[low].min_gap(S[high], 2 * c + 1.0)
        if gap > c + tol_mm:
            out.append(
                f"pieces {low + 1} and {high + 1} join {gap:.4g} mm apart, more than the "
                f"{c:g} mm clearance"
            )
    missing = P.volume() - sum(s.volume() for s in S)
    faces = (sum(s.surface_area() for s in S) - P.surface_area()) / 2
    if missing > 1.1 * c * faces + vol_tol:
        out.append(
            f"the pieces lack {missing:.4g} mm^3 of the part, more than a {c:g} mm band over "
            f"their {faces:.4g} mm^2 of cut faces"
        )
    return out


# --- the assembly on the user's bed -------------------------------------------------------


def _piece(name: str, mesh: Mesh, density: float, in_part: Mesh | None = None) -> PrintPiece:
    time, filament = estimate(meshes.print_features(mesh))
    return PrintPiece(
        name,
        meshes.stl_bytes(mesh),
        meshes.mesh_volume(mesh),
        meshes.mesh_volume(mesh) * density,
        meshes.extents(mesh),
        time,
        filament,
        meshes.orientation_figures(mesh, np.eye(3))[0],
        b"" if in_part is None else meshes.stl_bytes(in_part),
    )


def fit_assembly(asm: Assembly, bed: Bed, clearance: float, density: float) -> Assembly:
    """``asm`` with every printed part made printable on ``bed``: each part's ``printer``
    the bed's label, and its ``pieces`` (``joints``): none when its STL fits as it lies, the
    part turned to fit (one piece of its own name), or its pieces (see the module's doc).
    InputError when a part cannot be split to fit."""
    printed: list[PrintedPart] = []
    for p in asm.printed:
        v, f = meshes.read_stl(p.stl)
        mesh = Mesh(v / MM, f)
        placed = place(mesh, bed.size_m)
        if placed is mesh:
            printed.append(replace(p, fits_bed=True, printer=bed.label))
            continue
        if placed is not None:
            printed.append(
                replace(
                    p, fits_bed=True, printer=bed.label, pieces=(_piece(p.name, placed, density),)
                )
            )
            continue
        s = split_part(mesh, bed.size_m, clearance, p.name)
        names = [f"{p.name}_piece{k + 1}" for k in range(len(s.pieces))]
        pieces = tuple(
            _piece(nm, m, density, q) for nm, m, q in zip(names, s.placed, s.pieces, strict=True)
        )
        joints = tuple(
            PieceJoint(names[a], names[b], axis, at, slide, clearance)
            for a, b, axis, at, slide in s.joints
        )
        printed.append(
            replace(
                p,
                fits_bed=True,
                printer=bed.label,
                pieces=pieces,
                joints=joints,
                print_time_s=sum(x.print_time_s for x in pieces),
                filament_m3=sum(x.filament_m3 for x in pieces),
            )
        )
    return replace(asm, printed=tuple(printed))
