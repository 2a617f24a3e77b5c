"""Meshes of parmor's printed parts (manifold3d CSG), their STL bytes and print figures.

Every function is pure and deterministic: identical inputs give identical vertices and
identical STL bytes. Lengths in metres; the STL files hold millimetres (what every slicer
expects; the URDF and MJCF scale them by 0.001). Meshes are ``export.polymesh.Mesh``
objects (numpy; trimesh's formulas without its import), watertight volumes.

Each part is built in its *print frame*: standing on z = 0, centred on the z axis, z up as
it is printed:

- ``link_mesh``: the printed link module (paper Fig. 10), the tube's axis along z from 0 to
  ``length``; the geometry of ``kinematics.spatial.link_part_volume`` (tube, two square
  face plates with a bore of the tube's inner radius, concave fillet rings), built as the
  revolution of one half-section (the bored tube, the fillets and, over the plates'
  thickness, discs) whose discs' rims are then moved onto the faces' square. Faces' edges
  along x and y.
- ``foot_mesh``: a square foot pad; ``plate_mesh``: a rectangular plate (trunk, chassis,
  base plates, a humanoid's foot plate); z is the thickness.
- ``wheel_mesh``: a disc wheel with a hub bore, its axle along z.

No separate bracket mesh: the snake template models each module's bracket as a printed
tube segment (length name ``module``) between two actuator modules, i.e. a link module with
two dovetail faces, so ``link_mesh`` builds it.

Round surfaces are polygons of ``segments`` sides inscribed in the circles (volumes come out
a little smaller than the analytic ones: 0.16 % for 64 sides).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from math import cos, pi, sin

import numpy as np

from export.polymesh import Mesh
from kinematics import templates as _templates
from kinematics.spatial import check_link_part
from kinematics.templates import WHEEL_BORE

__all__ = [
    "STL_HEADER",
    "WHEEL_BORE",
    "extents",
    "fits_bed",
    "foot_mesh",
    "link_mesh",
    "dovetail_profile_mm",
    "dovetail_solid_mm",
    "dovetail_volume",
    "link_profile_mm",
    "mesh_mass_properties",
    "mesh_volume",
    "orientation_figures",
    "plate_mesh",
    "print_orientation",
    "ranked_orientations",
    "print_features",
    "stl_bytes",
    "support_measure",
    "wheel_mesh",
]

#: The fixed 80-byte header of every binary STL parmor writes.
STL_HEADER = b"parmor binary STL, units: mm".ljust(80, b"\0")
#: Circular segments of round surfaces by default.
SEGMENTS = 64
MM = 1000.0  # mm per m
#: Vertices closer than this share of the part's size are welded (an STL's float32 keeps
#: about 1e-7 of it; a printer about 1e-4).
STL_RESOLUTION = 1e-6


def _to_mesh(solid) -> Mesh:
    """The manifold ``solid`` as a :class:`export.polymesh.Mesh` (manifold3d's output is
    closed and oriented by construction: its status is checked here; the tests check
    ``is_volume``, and trimesh's figures against ours)."""
    import manifold3d as mf

    if solid.status() != mf.Error.NoError or solid.is_empty():
        raise ValueError(f"internal error: a printed part's CSG failed ({solid.status()})")
    m = solid.to_mesh64()
    vertices = np.asarray(m.vert_properties, dtype=float)[:, :3]
    faces = np.asarray(m.tri_verts, dtype=np.int64)
    # booleans can leave vertices a few nanometres apart, which an STL's float32
    # millimetres cannot keep apart: weld them (and drop the slivers between them)
    scale = float(np.abs(vertices).max()) if len(vertices) else 1.0
    mesh = Mesh(vertices, faces).welded(
        int(np.ceil(-np.log10(STL_RESOLUTION * scale))), 1e-12 * scale
    )
    if not mesh.is_watertight:
        raise ValueError("internal error: a printed part's mesh is not watertight once welded")
    return mesh


def _positive(name: str, x: float, allow_zero: bool = False) -> float:
    x = float(x)
    if not (np.isfinite(x) and (x >= 0 if allow_zero else x > 0)):
        raise ValueError(f"{name} must be {'>= 0' if allow_zero else 'positive'}, got {x}")
    return x


def _arc(cx: float, cz: float, r: float, a0: float, a1: float, n: int) -> list[tuple]:
    """``n + 1`` points (r, z) of the arc of radius ``r`` about (cx, cz) from a0 to a1 rad."""
    return [
        (cx + r * cos(a0 + (a1 - a0) * k / n), cz + r * sin(a0 + (a1 - a0) * k / n))
        for k in range(n + 1)
    ]


def link_profile_mm(
    length: float,
    r_outer: float,
    r_inner: float,
    face_side: float = 0.0,
    face_thickness: float = 0.0,
    fillet: float = 0.0,
    segments: int = SEGMENTS,
) -> list[tuple[float, float]]:
    """The half-section (r, z), mm, that ``link_mesh`` revolves about z (dimensions in m,
    as ``link_mesh``; checked there): the tube from r_inner, the fillet arcs
    (``segments // 8`` chords each, at least 4) and, over each plate's thickness, a disc of
    radius ``face_side`` (more than the square's half-diagonal): the square plate is that
    disc trimmed to the face's square (``link_mesh`` moves the disc's rim onto the square;
    an intersection with the square prism gives the same solid)."""
    plates = face_side > 0 and face_thickness > 0
    L, ro, ri, a, t, f = (
        MM * float(x) for x in (length, r_outer, r_inner, face_side, face_thickness, fillet)
    )
    if not plates:
        return [(ri, 0.0), (ro, 0.0), (ro, L), (ri, L)]
    if f > 0:
        k = max(4, int(segments) // 8)
        bottom = _arc(ro + f, t + f, f, -pi / 2, -pi, k)
        top = _arc(ro + f, L - t - f, f, pi, pi / 2, k)
    else:
        bottom, top = [(ro, t)], [(ro, L - t)]
    return [(ri, 0.0), (a, 0.0), (a, t), *bottom, *top, (a, L - t), (a, L), (ri, L)]


def _square_rim(vertices: np.ndarray, rim: float, half: float) -> np.ndarray:
    """``vertices`` (n, 3) with those at radius ``rim`` moved radially onto the square of
    half-side ``half`` (exactly onto its sides: the larger coordinate becomes +-half)."""
    v = np.array(vertices, dtype=float)
    x, y = v[:, 0], v[:, 1]
    on = np.abs(np.hypot(x, y) - rim) <= 1e-9 * rim
    ax, ay = np.abs(x), np.abs(y)
    along_x = on & (ax >= ay)
    along_y = on & (ax < ay)
    v[along_x, 1] = y[along_x] * (half / ax[along_x])
    v[along_x, 0] = np.copysign(half, x[along_x])
    v[along_y, 0] = x[along_y] * (half / ay[along_y])
    v[along_y, 1] = np.copysign(half, y[along_y])
    return v


def link_mesh(
    length: float,
    r_outer: float,
    r_inner: float,
    face_side: float = 0.0,
    face_thickness: float = 0.0,
    fillet: float = 0.0,
    segments: int = SEGMENTS,
    clearance: float | None = None,
    pin: bool = True,
) -> Mesh:
    """The printed link module (m): tube along z over [0, length], plates at both ends.

    ``clearance`` (m; None: flat faces): the faces join their neighbours with a dovetail
    (paper Fig. 10): a pin (``dovetail_solid_mm``) stands on the far face (z = length)
    and the near face (z = 0) has the rail's slot that takes a neighbour's pin with
    ``clearance`` on every side. Neither changes the link's length (face to face).
    ``pin`` False: the far face is a free end (a leg's tip, under its foot): no pin.

    Same dimensions and checks as ``kinematics.spatial.link_part_volume`` (face_side =
    face_thickness = fillet = 0: a bare tube). One revolution of ``link_profile_mm`` with
    ``segments`` sides (a multiple of 8 with plates); the plates' rims are then moved
    radially onto the square (``Manifold.warp_batch``): the revolution has a vertex at every
    multiple of 45 degrees, i.e. at the square's corners, so every rim edge lands on a
    side of the square and the plates are exact squares. No boolean operation: no
    slivers, and fast.
    """
    import manifold3d as mf

    plates = check_link_part(length, r_outer, r_inner, face_side, face_thickness, fillet)
    n = int(segments)
    if n < 8 or (plates and n % 8):
        raise ValueError(f"segments must be a multiple of 8 (at least 8), got {segments}")
    # built in mm (manifold3d's 2-D cross-sections round to 1e-8 units), scaled to m at the end
    profile = link_profile_mm(length, r_outer, r_inner, face_side, face_thickness, fillet, n)
    solid = mf.Manifold.revolve(mf.CrossSection([np.array(profile, dtype=float)]), n)
    if plates:
        a = MM * float(face_side)
        solid = solid.warp_batch(lambda v: _square_rim(v, a, a / 2))
        if clearance is not None:
            c = MM * _positive("clearance", clearance, allow_zero=True)
            if DOVETAIL_HEIGHT + c >= MM * float(face_thickness):
                raise ValueError(
                    f"a {DOVETAIL_HEIGHT + c:g} mm deep dovetail slot does not fit a "
                    f"{MM * float(face_thickness):g} mm face plate"
                )
            if pin:
                solid = solid + dovetail_solid_mm(a).translate((0, 0, MM * float(length)))
            solid = solid - dovetail_solid_mm(a, c)
    return _to_mesh(solid.scale((1 / MM, 1 / MM, 1 / MM)))


#: Dovetail profile (mm; ``kinematics.templates``' figures): the pin's width where it stands
#: on its face, its height, and the flank angle from the face's normal. The pin runs across
#: the whole face along y, centred on x.
DOVETAIL_ROOT = MM * _templates.DOVETAIL_ROOT
DOVETAIL_HEIGHT = MM * _templates.DOVETAIL_HEIGHT
DOVETAIL_FLANK = _templates.DOVETAIL_FLANK


def dovetail_profile_mm(grow: float = 0.0) -> list[tuple[float, float]]:
    """The pin's cross-section (x across the pin, z out of the face), mm, counter-
    clockwise: the trapezoid of ``DOVETAIL_ROOT`` at z = 0 widening by the flank angle to
    z = ``DOVETAIL_HEIGHT``, grown by ``grow`` mm on every side (a mitred offset: the rail
    that takes it with ``grow`` clearance; z from -grow)."""
    import manifold3d as mf

    w0, h = DOVETAIL_ROOT / 2, DOVETAIL_HEIGHT
    w1 = w0 + h * np.tan(DOVETAIL_FLANK)
    pts = [(-w0, 0.0), (w0, 0.0), (w1, h), (-w1, h)]
    if grow == 0:
        return pts
    cs = mf.CrossSection([np.array(pts)]).offset(grow, mf.JoinType.Miter, 4.0)
    return [tuple(map(float, p)) for p in cs.to_polygons()[0]]


def dovetail_solid_mm(face_side_mm: float, grow: float = 0.0):
    """The pin (``grow`` = 0) or the rail's slot (``grow`` = clearance) as a manifold, mm:
    its profile (``dovetail_profile_mm``) in the x-z plane, standing on z = 0, running
    along y over the face's side (the slot a little beyond, so that it opens both ends)."""
    import manifold3d as mf

    length = face_side_mm + (2.0 if grow > 0 else 0.0)
    cs = mf.CrossSection([np.array(dovetail_profile_mm(grow))])
    # the profile's (x, y) is the pin's (x, z): extrude along z, then turn z into -y
    return mf.Manifold.extrude(cs, length).rotate((90.0, 0.0, 0.0)).translate((0, length / 2, 0))


def dovetail_volume(face_side: float, r_inner: float, clearance: float, pin: bool) -> float:
    """m^3 the dovetail adds to a link of ``link_mesh`` (negative: removes): the pin on
    its far face (``pin``) less the rail's slot cut in its near face
    (``kinematics.templates.dovetail_volumes``, which the structure's template weighs)."""
    (pin_v, _, _), (slot_v, _, _) = _templates.dovetail_volumes(face_side, r_inner, clearance, pin)
    return pin_v - slot_v


def plate_mesh(lx: float, ly: float, thickness: float) -> Mesh:
    """A rectangular plate ``lx`` x ``ly`` m, ``thickness`` m thick over z in [0, thickness]."""
    import manifold3d as mf

    size = (_positive("lx", lx), _positive("ly", ly), _positive("thickness", thickness))
    box = mf.Manifold.cube(size, center=True).translate((0, 0, size[2] / 2))
    return _to_mesh(box)


def foot_mesh(side: float, thickness: float) -> Mesh:
    """A square printed foot pad of ``side`` m, ``thickness`` m (sole on z = 0)."""
    return plate_mesh(side, side, thickness)


def wheel_mesh(
    radius: float, width: float, bore: float = WHEEL_BORE, segments: int = 2 * SEGMENTS
) -> Mesh:
    """A printed disc wheel of ``radius`` m and ``width`` m, axle along z over [0, width],
    with a hub bore of radius ``bore`` m (0: none) for the servo horn screw."""
    import manifold3d as mf

    r, w = _positive("radius", radius), _positive("width", width)
    b = _positive("bore", bore, allow_zero=True)
    if b >= r:
        raise ValueError(f"bore ({b}) must be smaller than radius ({r})")
    n = int(segments)
    disc = mf.Manifold.cylinder(w, r, circular_segments=n)
    if b > 0:
        hole = mf.Manifold.cylinder(w + 0.002, b, circular_segments=max(16, n // 4))
        disc = disc - hole.translate((0, 0, -0.001))
    return _to_mesh(disc)


# --- printing orientation ------------------------------------------------------------------

#: A downward face steeper than this from the vertical (rad) needs support when printed:
#: the usual 45 degree rule of FDM printing (PrusaSlicer's default support threshold too).
OVERHANG_ANGLE = np.pi / 4
#: A face counts as that steep up to this much less (cos of the angle): a face at exactly
#: 45 degrees gets support in the slicer too.
OVERHANG_SLACK = 0.02
#: Flat faces smaller than this share of the largest are not tried as the face down.
MIN_FACE_SHARE = 0.10
#: Faces within this height (m) of the lowest point lie on the bed.
BED_TOLERANCE = 1e-6


def _down(n: np.ndarray) -> np.ndarray:
    """Rotation (3,3) that turns the unit vector ``n`` to -z (a half turn about x for +z)."""
    n = n / np.linalg.norm(n)
    target = np.array([0.0, 0.0, -1.0])
    c = float(n @ target)
    if c > 1 - 1e-12:
        return np.eye(3)
    if c < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    v = np.cross(n, target)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1 + c)


def orientation_figures(mesh: Mesh, R: np.ndarray) -> tuple[float, float]:
    """(overhang m^2, area on the bed m^2) of ``mesh`` turned by ``R`` (3,3): the area of
    the downward faces steeper than ``OVERHANG_ANGLE`` from the vertical that do not lie
    on the bed (they need support), and the area of the faces that do."""
    v = np.asarray(mesh.vertices, dtype=float) @ R.T
    faces = np.asarray(mesh.faces, dtype=np.int64)
    tri = v[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    nz = np.divide(cross[:, 2], 2 * area, out=np.zeros_like(area), where=area > 0)
    on_bed = np.all(tri[:, :, 2] <= v[:, 2].min() + BED_TOLERANCE, axis=1)
    steep = nz < -np.cos(OVERHANG_ANGLE) + OVERHANG_SLACK
    return float(area[steep & ~on_bed].sum()), float(area[on_bed].sum())


def print_orientation(mesh: Mesh) -> np.ndarray:
    """The rigid transform (4,4) that puts ``mesh`` on the bed in its best printing
    orientation: of the orientations that lay one of its flat faces (its planar facets of
    at least ``MIN_FACE_SHARE`` of the largest one's area) or one of the six axis
    directions down, the one
    that needs the least support (``support_measure``, rounded to 1 mm^3: the overhangs'
    area times their height), then the least overhang area (``orientation_figures``,
    rounded to 1 mm^2), then the largest area on the bed; lowest point on z = 0, bounding
    box centred on the z axis."""
    R = ranked_orientations(mesh)[0]
    v = np.asarray(mesh.vertices, dtype=float) @ R.T
    lo, hi = v.min(axis=0), v.max(axis=0)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = (-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2])
    return T


def ranked_orientations(mesh: Mesh) -> list[np.ndarray]:
    """The rotations (3,3) :func:`print_orientation` chooses from, best first (its
    ranking): one per candidate face down, a rotation already tried left out."""
    normals = [np.array(x, dtype=float) for x in np.vstack([np.eye(3), -np.eye(3)])]
    if len(mesh.facets):
        areas = np.asarray(mesh.facets_area, dtype=float)
        keep = np.flatnonzero(areas >= MIN_FACE_SHARE * areas.max())
        for i in keep[np.argsort(-areas[keep], kind="stable")][:24]:
            normals.append(np.asarray(mesh.facets_normal[i], dtype=float))
    ranked = []
    for k, n in enumerate(normals):
        R = _down(n)
        overhang, bed = orientation_figures(mesh, R)
        support = _support(np.asarray(mesh.vertices, dtype=float) @ R.T, mesh.faces)
        key = (round(support * 1e9), round(overhang * 1e6), -round(bed * 1e6), k)
        ranked.append((key, R))
    ranked.sort(key=lambda kr: kr[0])
    out: list[np.ndarray] = []
    for _, R in ranked:
        if not any(np.allclose(R, Q, atol=1e-9) for Q in out):
            out.append(R)
    return out


def support_measure(mesh: Mesh) -> float:
    """m^3: the volume of the columns under the part's overhangs as it stands
    (``mesh`` on the bed): each downward face steeper than ``OVERHANG_ANGLE`` from the
    vertical and not on the bed, its area projected on the bed times its height above it.
    The support a slicer builds is a fraction of it (``SUPPORT_FILL``)."""
    return _support(np.asarray(mesh.vertices, dtype=float), mesh.faces)


def _support(v: np.ndarray, faces) -> float:
    """``support_measure`` of the triangles ``faces`` of vertices ``v`` (n, 3) m."""
    tri = v[np.asarray(faces, dtype=np.int64)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    nz = np.divide(cross[:, 2], 2 * area, out=np.zeros_like(area), where=area > 0)
    on_bed = np.all(tri[:, :, 2] <= v[:, 2].min() + BED_TOLERANCE, axis=1)
    steep = (nz < -np.cos(OVERHANG_ANGLE) + OVERHANG_SLACK) & ~on_bed
    height = tri[:, :, 2].mean(axis=1) - v[:, 2].min()
    return float((area * -nz * height)[steep].sum())


def print_features(mesh: Mesh) -> dict[str, float]:
    """What a print's time and filament depend on, for ``mesh`` as printed (on the bed):
    ``volume`` m^3, ``side_area`` m^2 (faces steeper than 60 degrees from the horizontal:
    walls, printed as perimeters), ``flat_area`` m^2 (the others: top and bottom skins),
    ``support`` m^3 (``support_measure``) and ``height`` m."""
    v = np.asarray(mesh.vertices, dtype=float)
    tri = v[np.asarray(mesh.faces, dtype=np.int64)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    nz = np.abs(np.divide(cross[:, 2], 2 * area, out=np.zeros_like(area), where=area > 0))
    side = nz < 0.5
    return {
        "volume": float(mesh.volume),
        "side_area": float(area[side].sum()),
        "flat_area": float(area[~side].sum()),
        "support": support_measure(mesh),
        "height": float(v[:, 2].max() - v[:, 2].min()),
    }


# --- figures -----------------------------------------------------------------------------


def stl_bytes(mesh: Mesh) -> bytes:
    """Binary STL of ``mesh`` (vertices in metres) in millimetres, with the fixed header
    ``STL_HEADER``; deterministic."""
    v = np.asarray(mesh.vertices, dtype=float) * MM
    tri = v[np.asarray(mesh.faces, dtype=np.int64)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, norm, out=np.zeros_like(normals), where=norm > 0)
    record = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    data = np.zeros(len(tri), dtype=record)
    data["n"] = normals
    data["v"] = tri
    return STL_HEADER + struct.pack("<I", len(tri)) + data.tobytes()


def read_stl(stl: bytes) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) float, in the file's unit (mm for :func:`stl_bytes`), triangles
    (m, 3) int) of a binary STL, coincident corners merged: the reverse of
    :func:`stl_bytes`, for the 3MF projects and the pictures."""
    if len(stl) < 84:
        raise ValueError("not a binary STL: shorter than its header")
    n = int(np.frombuffer(stl, "<u4", 1, 80)[0])
    if len(stl) < 84 + 50 * n:
        raise ValueError(f"not a binary STL: {n} triangles announced, fewer stored")
    rec = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    tri = np.frombuffer(stl, rec, n, 84)["v"].reshape(-1, 3)
    vertices, index = np.unique(tri, axis=0, return_inverse=True)
    return vertices.astype(float), index.reshape(-1, 3)


def mesh_volume(mesh: Mesh) -> float:
    """Enclosed volume m^3 of a closed mesh."""
    return float(mesh.volume)


def mesh_mass_properties(mesh: Mesh, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass kg, COM (3,) m and inertia (3,3) kg m^2 about the COM (mesh axes) of a solid
    ``mesh`` of uniform ``density`` kg/m^3."""
    props = mesh.mass_properties  # unit density
    rho = _positive("density", density)
    return (
        float(props["mass"] * rho),
        np.array(props["center_mass"], dtype=float),
        np.array(props["inertia"], dtype=float) * rho,
    )


def extents(mesh: Mesh) -> tuple[float, float, float]:
    """Axis-aligned bounding box sizes (x, y, z) m of ``mesh`` in its print frame."""
    lo, hi = np.asarray(mesh.bounds, dtype=float)
    x, y, z = (float(d) for d in hi - lo)
    return x, y, z


def fits_bed(size: Sequence[float], bed: Sequence[float], margin: float = 0.0) -> bool:
    """True if a part of extents ``size`` (m, x y z as it is printed: ``print_orientation``)
    fits the printer's build volume ``bed`` (m) with ``margin`` m free around its footprint
    (the skirt): its footprint in either of the two right-angle turns about z, its height
    as it is."""
    s, b = [float(x) for x in size], [float(x) for x in bed]
    if len(s) != 3 or len(b) != 3:
        raise ValueError(f"need three extents and three bed sizes, got {size!r}, {bed!r}")
    x, y = s[0] + 2 * margin, s[1] + 2 * margin
    flat = (x <= b[0] and y <= b[1]) or (y <= b[0] and x <= b[1])
    return flat and s[2] <= b[2]
