"""Pictures for the bundle's README: each printed part as printed, and the assembled robot
at its zero pose (PNG bytes; deterministic: fixed size, fixed view, no metadata).

Shapes are drawn as flat-shaded triangles (a fixed light from the viewer's upper left) in an
orthographic view from ``VIEW`` (elevation, azimuth: matplotlib's 3-D convention), back to
front (the painter's algorithm: each triangle at its centroid's depth, faces turned away
culled), with Pillow's polygon fill at twice the size and a Lanczos reduction (smooth
edges), the title and the shape's extent in millimetres written above. Pillow rather
than matplotlib's 3-D axes: the same picture costs ~0.05 s instead of ~0.5 s, plus ~1 s of
importing matplotlib, which made ``parmor design --out`` seconds slower than without.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterable, Sequence

import numpy as np

from export.model3d import Assembly, Geometry

__all__ = ["assembly_png", "mesh_png", "pieces_png", "triangles_of"]

#: Picture size, pixels (square).
SIZE_PX = 480
#: Pixels above the drawing for the title and the extent.
HEADER_PX = 34
#: View: elevation and azimuth (degrees; matplotlib's 3-D convention).
VIEW = (25.0, -60.0)
#: Drawn at this many times the size, then reduced (anti-aliasing).
SUPERSAMPLE = 2
BACKGROUND = (255, 255, 255)
_LIGHT = np.array([-0.4, -0.6, 0.7]) / np.linalg.norm([-0.4, -0.6, 0.7])


def triangles_of(g: Geometry, mesh_vertices: dict[str, tuple[np.ndarray, np.ndarray]]):
    """(n, 3, 3) triangles (m) of geometry ``g`` in its body frame. ``mesh_vertices``:
    mesh file name -> (vertices m, faces). Boxes, spheres and cylinders are tessellated by
    manifold3d (as the printed parts are; no trimesh import for a picture)."""
    import manifold3d as mf

    if g.kind == "mesh":
        v, f = mesh_vertices[g.mesh]
    else:
        if g.kind == "box":
            solid = mf.Manifold.cube(tuple(g.size), center=True)
        elif g.kind == "sphere":
            solid = mf.Manifold.sphere(g.size[0], circular_segments=16)
        elif g.kind == "cylinder":
            solid = mf.Manifold.cylinder(g.size[1], g.size[0], circular_segments=24, center=True)
        else:
            raise ValueError(f"no picture for geometry kind {g.kind!r}")
        m = solid.to_mesh64()
        v, f = m.vert_properties[:, :3], m.tri_verts
    v = np.asarray(v, dtype=float) @ g.origin[:3, :3].T + g.origin[:3, 3]
    return v[np.asarray(f, dtype=np.int64)]


def _view() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, towards the viewer) unit vectors of the picture in the world frame."""
    elev, azim = (math.radians(x) for x in VIEW)
    eye = np.array(
        [math.cos(elev) * math.cos(azim), math.cos(elev) * math.sin(azim), math.sin(elev)]
    )
    right = np.array([-math.sin(azim), math.cos(azim), 0.0])
    return right, np.cross(eye, right), eye


def _png(items: Iterable[tuple[np.ndarray, Sequence[float]]], title: str) -> bytes:
    """PNG of triangle sets (each (n, 3, 3) m with an RGBA colour)."""
    from PIL import Image, ImageDraw

    right, up, eye = _view()
    tris, colours = [], []
    for tri, rgba in items:
        if not len(tri):
            continue
        tri = np.asarray(tri, dtype=float) * 1000.0  # mm
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
        shade = 0.45 + 0.55 * np.clip(n @ _LIGHT, 0.0, 1.0)
        rgb = np.clip(np.outer(shade, rgba[:3]), 0, 1)
        alpha = float(rgba[3]) if len(rgba) > 3 else 1.0
        rgb = rgb * alpha + (1 - alpha) * np.array(BACKGROUND) / 255.0
        front = n @ eye >= 0  # faces turned away are hidden behind the solid's others
        tris.append(tri[front])
        colours.append(rgb[front])
    size = SIZE_PX * SUPERSAMPLE
    image = Image.new("RGB", (size, size), BACKGROUND)
    draw = ImageDraw.Draw(image)
    extent = ""
    if tris:
        tri = np.concatenate(tris)
        rgb = np.concatenate(colours)
        pts = tri.reshape(-1, 3)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        extent = " x ".join(f"{d:.0f}" for d in hi - lo) + " mm"
        x, y, depth = tri @ right, tri @ up, (tri @ eye).mean(axis=1)
        x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
        room = size - 2 * 12 * SUPERSAMPLE
        top = HEADER_PX * SUPERSAMPLE
        scale = min(room / max(x1 - x0, 1e-9), (room - top) / max(y1 - y0, 1e-9))
        px = size / 2 + (x - (x0 + x1) / 2) * scale
        py = (size + top) / 2 - (y - (y0 + y1) / 2) * scale
        fill = np.rint(rgb * 255).astype(int)
        for k in np.argsort(depth, kind="stable"):  # far ones first
            draw.polygon(
                [(px[k, 0], py[k, 0]), (px[k, 1], py[k, 1]), (px[k, 2], py[k, 2])],
                fill=tuple(fill[k]),
            )
    image = image.resize((SIZE_PX, SIZE_PX), Image.Resampling.LANCZOS)
    text = ImageDraw.Draw(image)
    text.text((8, 4), title, fill=(0, 0, 0))
    if extent:
        text.text((8, 18), f"extent x, y, z: {extent}", fill=(90, 90, 90))
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=False)
    return buf.getvalue()


def mesh_png(vertices: np.ndarray, faces: np.ndarray, rgba: Sequence[float], title: str) -> bytes:
    """PNG of one mesh (vertices m, as printed: on the bed)."""
    tri = np.asarray(vertices, dtype=float)[np.asarray(faces, dtype=np.int64)]
    return _png([(tri, rgba)], title)


def assembly_png(
    asm: Assembly, mesh_vertices: dict[str, tuple[np.ndarray, np.ndarray]], title: str
) -> bytes:
    """PNG of the assembled robot at its zero pose (every body's shapes; the massless
    contact shapes left out)."""
    frames: dict[str, np.ndarray] = {asm.root: np.eye(4)}
    for j in asm.joints:
        frames[j.child] = frames[j.parent] @ j.origin
    items = []
    for body in asm.bodies:
        T = frames.get(body.name, np.eye(4))
        for part in body.parts:
            g = part.geometry
            if g is None or part.source == "contact":
                continue
            tri = triangles_of(g, mesh_vertices)
            items.append((tri @ T[:3, :3].T + T[:3, 3], g.rgba))
    return _png(items, title)


#: Colours of a split part's pieces in turn (printed orange, then blue, green, grey).
PIECE_RGBA = (
    (0.95, 0.55, 0.15, 1.0),
    (0.25, 0.5, 0.85, 1.0),
    (0.35, 0.7, 0.35, 1.0),
    (0.6, 0.6, 0.62, 1.0),
)
#: An exploded view moves each piece away from the part's centre by this share of its
#: distance from it.
EXPLODE = 0.12


def pieces_png(pieces: Sequence[tuple[np.ndarray, np.ndarray]], title: str) -> bytes:
    """PNG of a split part's pieces (vertices m and faces of each, where it sits in the
    part) drawn apart (``EXPLODE``), each in a colour of its own: where they join."""
    tris = [np.asarray(v, dtype=float)[np.asarray(f, dtype=np.int64)] for v, f in pieces]
    centre = np.concatenate([t.reshape(-1, 3) for t in tris]).mean(axis=0)
    items = []
    for k, tri in enumerate(tris):
        shift = EXPLODE * (tri.reshape(-1, 3).mean(axis=0) - centre)
        items.append((tri + shift, PIECE_RGBA[k % len(PIECE_RGBA)]))
    return _png(items, title)
