"""Pictures for the bundle's README: each printed part as printed, and the assembled robot
at its zero pose (PNG bytes, matplotlib's Agg canvas: no display, deterministic: fixed
size, fixed view, no metadata that changes from run to run).

Shapes are drawn as flat-shaded triangles (a fixed light from the viewer's upper left),
sorted back to front by matplotlib's 3-D projection.
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Sequence

import numpy as np

from export.model3d import Assembly, Geometry

__all__ = ["assembly_png", "mesh_png", "pieces_png", "triangles_of"]

#: Picture size (inches) and resolution (dots per inch): 480 x 480 pixels.
SIZE_IN = 4.0
DPI = 120
#: View: elevation and azimuth (degrees) of matplotlib's 3-D axes.
VIEW = (25.0, -60.0)
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


def _png(items: Iterable[tuple[np.ndarray, Sequence[float]]], title: str) -> bytes:
    """PNG of triangle sets (each (n, 3, 3) m with an RGBA colour)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = Figure(figsize=(SIZE_IN, SIZE_IN), dpi=DPI)
    ax = fig.add_subplot(projection="3d")
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for tri, rgba in items:
        if not len(tri):
            continue
        tri = tri * 1000.0  # mm
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
        shade = 0.45 + 0.55 * np.clip(n @ _LIGHT, 0.0, 1.0)
        colours = np.clip(np.outer(shade, rgba[:3]), 0, 1)
        colours = np.column_stack([colours, np.full(len(colours), rgba[3])])
        ax.add_collection3d(Poly3DCollection(tri, facecolors=colours, linewidths=0))
        lo = np.minimum(lo, tri.reshape(-1, 3).min(axis=0))
        hi = np.maximum(hi, tri.reshape(-1, 3).max(axis=0))
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1.0)
    for k, setter in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
        setter(centre[k] - half, centre[k] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(*VIEW)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title, fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
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
