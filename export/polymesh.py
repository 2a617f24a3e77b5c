"""A closed triangle mesh in numpy: what parmor's printed parts need of a mesh.

trimesh did this, but importing it costs about a second on every ``parmor design`` (its
``trimesh.bounds`` imports ``scipy.spatial``), which the design's verification paid only
to weld manifold3d's output, find its flat faces and integrate its mass. The formulas are
trimesh's (version 4), so the figures agree with it to rounding (tests compare them with
trimesh's on every shipped part):

- welding (:meth:`Mesh.welded`): vertices equal once rounded to ``digits`` decimals are
  merged into their first occurrence, degenerate faces (an oriented bounding box side of at
  most ``height``) dropped, unreferenced vertices removed (``trimesh.Trimesh.
  merge_vertices``, ``nondegenerate_faces``, ``remove_unreferenced_vertices``);
- mass properties: the polyhedral integrals of Eberly, "Polyhedral Mass Properties"
  (``trimesh.triangles.mass_properties``);
- facets: groups of two or more edge-adjacent faces that are parallel by trimesh's rule
  (``trimesh.graph.facets``: the radius/span ratio of the pair squared above 5000, i.e.
  within about 0.4 degrees), in the order of their smallest face, each with the normal of
  its largest face.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: trimesh's tolerances: ``tol.merge`` (an edge no longer than this is degenerate),
#: ``tol.zero`` and ``tol.facet_threshold``.
MERGE = 1e-8
ZERO = np.finfo(np.float64).resolution * 100
FACET_THRESHOLD = 5000


@dataclass(eq=False)
class Mesh:
    """Triangles ``faces`` (m, 3) int64 over ``vertices`` (n, 3) float64, counter-clockwise
    seen from outside. Derived figures are cached until :meth:`apply_transform`."""

    vertices: np.ndarray
    faces: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)

    # --- building -----------------------------------------------------------------------

    def welded(self, digits: int, height: float) -> Mesh:
        """This mesh with vertices equal to ``digits`` decimals merged, faces whose oriented
        bounding box has a side of at most ``height`` dropped and unused vertices removed."""
        v, f = self.vertices, self.faces
        referenced = np.zeros(len(v), dtype=bool)
        referenced[f] = True
        stacked = (v * (10**digits)).round().astype(np.int64)[referenced]
        _, first, inverse = np.unique(stacked, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first, kind="stable")  # first occurrences, in their order
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        full = np.zeros(len(v), dtype=np.int64)
        full[referenced] = rank[inverse.reshape(-1)]
        mesh = Mesh(v[np.nonzero(referenced)[0][first[order]]], full[f])
        mesh = Mesh(mesh.vertices, mesh.faces[mesh._nondegenerate(height)])
        used = np.zeros(len(mesh.vertices), dtype=bool)
        used[mesh.faces] = True
        index = np.zeros(len(mesh.vertices), dtype=np.int64)
        index[used] = np.arange(used.sum())
        return Mesh(mesh.vertices[used], index[mesh.faces])

    def copy(self) -> Mesh:
        return Mesh(self.vertices.copy(), self.faces.copy())

    def apply_transform(self, matrix: np.ndarray) -> Mesh:
        """Moved by the rigid transform ``matrix`` (4, 4), in place; returns itself."""
        m = np.asarray(matrix, dtype=np.float64)
        if np.linalg.det(m[:3, :3]) < 0:
            raise ValueError("a mirroring transform would turn the mesh inside out")
        if np.abs(m - np.eye(4)).max() >= 1e-8:
            stack = np.column_stack((self.vertices, np.ones(len(self.vertices))))
            self.vertices = np.ascontiguousarray(np.dot(m, stack.T).T[:, :3])
            self._cache = {}
        return self

    # --- figures ------------------------------------------------------------------------

    def _cached(self, key: str, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    @property
    def triangles(self) -> np.ndarray:
        """(m, 3, 3) the corners of each face."""
        return self._cached("triangles", lambda: self.vertices[self.faces])

    @property
    def crosses(self) -> np.ndarray:
        """(m, 3) each face's edge cross product (twice its area along its normal)."""

        def make() -> np.ndarray:
            t = self.triangles
            vectors = t[:, 1:, :] - t[:, :2, :]
            return np.cross(vectors[:, 0], vectors[:, 1])

        return self._cached("crosses", make)

    @property
    def area_faces(self) -> np.ndarray:
        return self._cached("area", lambda: np.sqrt((self.crosses**2).sum(axis=1)) / 2.0)

    @property
    def face_normals(self) -> np.ndarray:
        """(m, 3) unit normals (zero for a face without area)."""

        def make() -> np.ndarray:
            c = self.crosses
            norm = np.sqrt((c**2).sum(axis=1))
            out = np.zeros_like(c)
            ok = norm > ZERO
            out[ok] = c[ok] / norm[ok, None]
            return out

        return self._cached("normals", make)

    def _nondegenerate(self, height: float) -> np.ndarray:
        t = self.triangles
        areas = self.area_faces
        a = t[:, 1] - t[:, 0]
        b = t[:, 2] - t[:, 0]
        length_a = (a**2).sum(axis=1) ** 0.5
        length_b = (b**2).sum(axis=1) ** 0.5
        box = np.zeros((len(t), 2))
        ok_a, ok_b = length_a > MERGE, length_b > MERGE
        box[:, 0][ok_a] = (areas[ok_a] * 2) / length_a[ok_a]
        box[:, 1][ok_b] = (areas[ok_b] * 2) / length_b[ok_b]
        return (box > height).all(axis=1)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) the lowest and highest corner of the used vertices' bounding box."""
        used = self.vertices[np.unique(self.faces)] if len(self.faces) else self.vertices
        return np.array([used.min(axis=0), used.max(axis=0)])

    @property
    def extents(self) -> np.ndarray:
        lo, hi = self.bounds
        return hi - lo

    def _edges(self) -> tuple[np.ndarray, np.ndarray]:
        """(every face's three edges (3m, 2), each sorted; the face of each)."""
        f = self.faces
        edges = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        return np.sort(edges, axis=1), np.repeat(np.arange(len(f)), 3)

    @property
    def is_watertight(self) -> bool:
        """Every edge is shared by exactly two faces."""
        if not len(self.faces):
            return False
        edges, _ = self._edges()
        _, counts = np.unique(edges, axis=0, return_counts=True)
        return bool((counts == 2).all())

    @property
    def is_winding_consistent(self) -> bool:
        """Each edge is run once in each direction by its two faces."""
        f = self.faces
        directed = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        _, counts = np.unique(directed, axis=0, return_counts=True)
        return bool(self.is_watertight and (counts == 1).all())

    @property
    def is_volume(self) -> bool:
        """Watertight, consistently wound, outward (positive volume)."""
        return self.is_watertight and self.is_winding_consistent and self.volume > 0

    @property
    def mass_properties(self) -> dict:
        """Unit density: ``volume``/``mass`` m^3, ``center_mass`` (3,) m, ``inertia`` (3, 3)
        about the centre of mass."""
        return self._cached("mass", lambda: mass_properties(self.triangles, self.crosses))

    @property
    def volume(self) -> float:
        return float(self.mass_properties["volume"])

    @property
    def facets(self) -> list[np.ndarray]:
        return self._cached("facets", self._facets)

    @property
    def facets_area(self) -> np.ndarray:
        area = self.area_faces
        return np.array([sum(area[i]) for i in self.facets], dtype=np.float64)

    @property
    def facets_normal(self) -> np.ndarray:
        if not self.facets:
            return np.array([])
        area = self.area_faces
        return self.face_normals[np.array([i[area[i].argmax()] for i in self.facets])]

    def _facets(self) -> list[np.ndarray]:
        edges, face = self._edges()
        order = np.lexsort((edges[:, 1], edges[:, 0]))
        e, fo = edges[order], face[order]
        same = (e[1:] == e[:-1]).all(axis=1)
        # an edge shared by exactly two faces: a pair of adjacent faces
        starts = np.flatnonzero(same)
        counts = np.diff(np.flatnonzero(np.r_[True, ~same, True]))
        twice = np.repeat(counts == 2, counts)[:-1][starts]
        pairs = np.sort(np.column_stack([fo[starts], fo[starts + 1]])[twice], axis=1)
        shared = e[starts][twice]
        pairs_ok = pairs[:, 0] != pairs[:, 1]
        pairs, shared = pairs[pairs_ok], shared[pairs_ok]
        if not len(pairs):
            return []
        n = self.face_normals
        angles = np.arccos(np.clip((n[pairs[:, 0]] * n[pairs[:, 1]]).sum(axis=1), -1.0, 1.0))
        # the span: the two unshared corners' distance across the shared edge
        fa, fb = self.faces[pairs[:, 0]], self.faces[pairs[:, 1]]

        def unshared(faces: np.ndarray) -> np.ndarray:
            mask = (faces != shared[:, :1]) & (faces != shared[:, 1:])
            return faces[np.arange(len(faces)), mask.argmax(axis=1)]

        v = self.vertices
        vectors = v[unshared(fb)] - v[unshared(fa)]
        along = v[shared[:, 1]] - v[shared[:, 0]]
        along = along / np.maximum(np.linalg.norm(along, axis=1), ZERO)[:, None]
        span = np.linalg.norm(vectors - (vectors * along).sum(axis=1)[:, None] * along, axis=1)
        nonzero = angles > np.radians(0.01)
        radii = np.full(len(pairs), np.inf)
        radii[nonzero] = span[nonzero] / np.abs(2.0 * np.sin(angles[nonzero]))
        parallel = np.ones(len(pairs), dtype=bool)
        big = np.abs(span) > ZERO
        parallel[big] = (radii[big] / span[big]) ** 2 > FACET_THRESHOLD
        return _components(pairs[parallel], len(self.faces))


def _components(pairs: np.ndarray, count: int) -> list[np.ndarray]:
    """Connected groups (two or more) of ``count`` nodes joined by ``pairs``, ordered by
    their smallest node, each ascending."""
    parent = np.arange(count)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in pairs.tolist():
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    labels = np.array([root(i) for i in range(count)])
    groups: dict[int, list[int]] = {}
    for i, r in enumerate(labels.tolist()):
        groups.setdefault(r, []).append(i)
    return [np.array(g, dtype=np.int64) for _, g in sorted(groups.items()) if len(g) >= 2]


def mass_properties(triangles: np.ndarray, crosses: np.ndarray) -> dict:
    """Volume, centre of mass and inertia about it (unit density) of the closed surface
    ``triangles`` (n, 3, 3) with edge cross products ``crosses``: Eberly's polyhedral
    integrals, as ``trimesh.triangles.mass_properties`` computes them."""
    t = triangles
    f1 = t[:, 0, :] + t[:, 1, :] + t[:, 2, :]
    f2 = t[:, 0, :] ** 2 + t[:, 1, :] ** 2 + t[:, 0, :] * t[:, 1, :] + t[:, 2, :] * f1
    f3 = (
        (t[:, 0, :] ** 3)
        + (t[:, 0, :] ** 2) * (t[:, 1, :])
        + (t[:, 0, :]) * (t[:, 1, :] ** 2)
        + (t[:, 1, :] ** 3)
        + (t[:, 2, :] * f2)
    )
    g0 = f2 + (t[:, 0, :] + f1) * t[:, 0, :]
    g1 = f2 + (t[:, 1, :] + f1) * t[:, 1, :]
    g2 = f2 + (t[:, 2, :] + f1) * t[:, 2, :]
    integral = np.zeros((10, len(f1)))
    integral[0] = crosses[:, 0] * f1[:, 0]
    integral[1:4] = (crosses * f2).T
    integral[4:7] = (crosses * f3).T
    for i in range(3):
        j = (i + 1) % 3
        integral[i + 7] = crosses[:, i] * (
            (t[:, 0, j] * g0[:, i]) + (t[:, 1, j] * g1[:, i]) + (t[:, 2, j] * g2[:, i])
        )
    integrated = integral.sum(axis=1) / np.array(
        [6, 24, 24, 24, 60, 60, 60, 120, 120, 120], dtype=np.float64
    )
    volume = integrated[0]
    com = integrated[1:4] / volume
    inertia = np.zeros((3, 3))
    inertia[0, 0] = integrated[5] + integrated[6] - (volume * (com[[1, 2]] ** 2).sum())
    inertia[1, 1] = integrated[4] + integrated[6] - (volume * (com[[0, 2]] ** 2).sum())
    inertia[2, 2] = integrated[4] + integrated[5] - (volume * (com[[0, 1]] ** 2).sum())
    inertia[0, 1] = -(integrated[7] - (volume * np.prod(com[[0, 1]])))
    inertia[1, 2] = -(integrated[8] - (volume * np.prod(com[[1, 2]])))
    inertia[0, 2] = -(integrated[9] - (volume * np.prod(com[[0, 2]])))
    inertia[2, 0] = inertia[0, 2]
    inertia[2, 1] = inertia[1, 2]
    inertia[1, 0] = inertia[0, 1]
    return {"volume": volume, "mass": volume, "center_mass": com, "inertia": inertia}
