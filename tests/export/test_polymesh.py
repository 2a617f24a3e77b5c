"""export.polymesh against trimesh, whose formulas it takes without its import: the same
welded meshes, facets, mass properties and print orientation on parmor's printed parts;
and the cases built to fail (an open mesh, a mirroring transform)."""

from __future__ import annotations

import numpy as np
import pytest

from export import meshes
from export.polymesh import Mesh

trimesh = pytest.importorskip("trimesh")

PARTS = {
    "link with dovetails": lambda: meshes.link_mesh(
        0.08, 0.012, 0.009, 0.05, 0.004, 0.003, clearance=0.0002
    ),
    "link tip": lambda: meshes.link_mesh(
        0.06, 0.01, 0.007, 0.05, 0.004, 0.002, clearance=0.0002, pin=False
    ),
    "plate": lambda: meshes.plate_mesh(0.2, 0.12, 0.004),
    "foot": lambda: meshes.foot_mesh(0.03, 0.004),
    "wheel": lambda: meshes.wheel_mesh(0.04, 0.02),
}


def _trimesh_weld(raw: Mesh, digits: int, height: float):
    """What export.meshes did with trimesh before export.polymesh."""
    t = trimesh.Trimesh(vertices=raw.vertices, faces=raw.faces, process=False)
    t.merge_vertices(digits_vertex=digits)
    t.update_faces(t.nondegenerate_faces(height=height))
    t.remove_unreferenced_vertices()
    return t


@pytest.mark.parametrize("name", sorted(PARTS))
def test_figures_agree_with_trimesh(name: str) -> None:
    mine = PARTS[name]()
    theirs = trimesh.Trimesh(vertices=mine.vertices, faces=mine.faces, process=False)
    assert mine.is_volume and theirs.is_volume
    assert mine.is_watertight == theirs.is_watertight
    np.testing.assert_allclose(mine.bounds, theirs.bounds, rtol=0, atol=0)
    a, b = mine.mass_properties, theirs.mass_properties
    assert a["volume"] == pytest.approx(b["volume"], rel=1e-12)
    np.testing.assert_allclose(a["center_mass"], b["center_mass"], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(a["inertia"], b["inertia"], rtol=1e-9, atol=1e-18)
    assert [f.tolist() for f in mine.facets] == [sorted(f.tolist()) for f in theirs.facets]
    np.testing.assert_allclose(mine.facets_area, theirs.facets_area, rtol=1e-12)
    np.testing.assert_allclose(mine.facets_normal, theirs.facets_normal, atol=1e-12)
    placed = mine.copy().apply_transform(meshes.print_orientation(mine))
    moved = theirs.copy().apply_transform(meshes.print_orientation(mine))
    np.testing.assert_array_equal(placed.vertices, moved.vertices)


def test_welding_agrees_with_trimesh() -> None:
    """Vertices a few nanometres apart merged into their first occurrence, the faces
    between them dropped, unused vertices removed: the same arrays as trimesh's."""
    rng = np.random.default_rng(0)
    base = PARTS["link with dovetails"]()
    jitter = base.vertices + rng.normal(0, 1e-12, base.vertices.shape)
    # every vertex twice (a copy a few picometres away), faces spread over both copies
    vertices = np.vstack([base.vertices, jitter])
    pick = rng.integers(0, 2, base.faces.shape) * len(base.vertices)
    raw = Mesh(vertices, base.faces + pick)
    digits, height = 9, 1e-13
    mine = raw.welded(digits, height)
    theirs = _trimesh_weld(raw, digits, height)
    np.testing.assert_array_equal(mine.vertices, theirs.vertices)
    np.testing.assert_array_equal(mine.faces, theirs.faces)
    assert mine.is_watertight


def test_an_open_mesh_and_a_mirror_are_caught() -> None:
    closed = PARTS["plate"]()
    open_ = Mesh(closed.vertices, closed.faces[1:])
    assert closed.is_watertight and not open_.is_watertight and not open_.is_volume
    flipped = Mesh(closed.vertices, closed.faces[:, ::-1])
    assert flipped.is_watertight and not flipped.is_volume  # inside out: negative volume
    with pytest.raises(ValueError, match="mirroring"):
        closed.copy().apply_transform(np.diag([1.0, 1.0, -1.0, 1.0]))
