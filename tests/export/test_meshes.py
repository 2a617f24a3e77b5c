"""export.meshes: every printed part is a closed volume that matches its analytic model;
STL bytes are deterministic; print-bed and print-time figures.

The analytic model of the link module (kinematics.spatial) is checked here too, against
the mesh's own mass properties and against closed forms written out in the test."""

from __future__ import annotations

import io
from math import pi

import numpy as np
import pytest
import trimesh

from export import meshes
from kinematics.spatial import link_part_mass_properties, link_part_volume, tube_mass

RHO = 1240.0


def random_links(n: int, seed: int) -> list[tuple[float, ...]]:
    """``n`` valid (length, r_outer, r_inner, face_side, face_thickness, fillet), m."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        ro = rng.uniform(0.006, 0.020)
        ri = rng.uniform(0.0, ro - 0.0012)
        f = rng.uniform(0.001, 0.004)
        side = rng.uniform(2 * (ro + f), 0.06)
        t = rng.uniform(0.002, 0.006)
        length = rng.uniform(2 * (t + f) + 0.005, 0.2)
        out.append(tuple(float(x) for x in (length, ro, ri, side, t, f)))
    return out


def closed(mesh: trimesh.Trimesh) -> None:
    assert mesh.is_watertight and mesh.is_volume and mesh.volume > 0


def load(stl: bytes) -> trimesh.Trimesh:
    return trimesh.load(io.BytesIO(stl), file_type="stl").apply_scale(1e-3)


@pytest.mark.parametrize("dims", random_links(6, seed=11))
def test_link_mesh_is_the_analytic_part(dims: tuple[float, ...]) -> None:
    length, ro, ri, side, t, f = dims
    mesh = meshes.link_mesh(*dims)
    closed(mesh)
    assert meshes.mesh_volume(mesh) == pytest.approx(link_part_volume(*dims), rel=0.01)
    np.testing.assert_allclose(meshes.extents(mesh), (side, side, length), rtol=1e-9)
    # mass properties: the analytic model (axis z, from the origin) against the mesh's
    m, com, inertia = meshes.mesh_mass_properties(mesh, RHO)
    ma, ca, ia = link_part_mass_properties(RHO, *dims, axis=(0, 0, 1))
    assert m == pytest.approx(ma, rel=0.01)
    np.testing.assert_allclose(com, ca, atol=1e-6)
    np.testing.assert_allclose(inertia, ia, rtol=0, atol=0.01 * np.abs(ia).max())


def test_link_volume_is_tube_plus_two_plates_plus_two_pappus_rings() -> None:
    for length, ro, ri, side, t, f in random_links(5, seed=3):
        tube = pi * (ro**2 - ri**2) * length
        plates = 2 * t * (side**2 - pi * ro**2)
        centroid = ro + f * (10 - 3 * pi) / (12 - 3 * pi)  # of the fillet's half-section
        rings = 2 * 2 * pi * centroid * f**2 * (1 - pi / 4)
        dims = (length, ro, ri, side, t, f)
        assert link_part_volume(*dims) == pytest.approx(tube + plates + rings, rel=1e-12)
        m, com, inertia = link_part_mass_properties(RHO, *dims)
        assert m == pytest.approx(RHO * (tube + plates + rings), rel=1e-12)
        np.testing.assert_allclose(com, (length / 2, 0, 0))
        assert inertia[1, 1] == inertia[2, 2] and inertia[0, 1] == 0.0


def test_bare_link_is_the_tube() -> None:
    mesh = meshes.link_mesh(0.1, 0.012, 0.009)
    closed(mesh)
    assert meshes.mesh_volume(mesh) == pytest.approx(pi * (0.012**2 - 0.009**2) * 0.1, rel=0.01)
    m, com, inertia = link_part_mass_properties(RHO, 0.1, 0.012, 0.009)
    assert m == tube_mass(RHO, 0.1, 0.012, 0.009)
    solid = meshes.link_mesh(0.05, 0.01, 0.0, 0.04, 0.003, 0.002)  # no bore
    closed(solid)
    assert meshes.mesh_volume(solid) == pytest.approx(
        link_part_volume(0.05, 0.01, 0.0, 0.04, 0.003, 0.002), rel=0.01
    )


def test_pads_plates_and_wheels() -> None:
    rng = np.random.default_rng(5)
    for _ in range(4):
        side, t = rng.uniform(0.04, 0.12), rng.uniform(0.003, 0.008)
        foot = meshes.foot_mesh(side, t)
        closed(foot)
        assert meshes.mesh_volume(foot) == pytest.approx(side * side * t, rel=1e-9)
        np.testing.assert_allclose(meshes.extents(foot), (side, side, t), rtol=1e-9)
        np.testing.assert_allclose(foot.bounds[0], (-side / 2, -side / 2, 0), atol=1e-12)
        lx, ly = rng.uniform(0.05, 0.3, size=2)
        plate = meshes.plate_mesh(lx, ly, t)
        closed(plate)
        assert meshes.mesh_volume(plate) == pytest.approx(lx * ly * t, rel=1e-9)
        r, w = rng.uniform(0.02, 0.1), rng.uniform(0.005, 0.02)
        wheel = meshes.wheel_mesh(r, w)
        closed(wheel)
        b = meshes.WHEEL_BORE
        assert meshes.mesh_volume(wheel) == pytest.approx(pi * (r * r - b * b) * w, rel=0.01)
        np.testing.assert_allclose(meshes.extents(wheel), (2 * r, 2 * r, w), rtol=1e-6)
        solid = meshes.wheel_mesh(r, w, bore=0.0)
        assert meshes.mesh_volume(solid) > meshes.mesh_volume(wheel)


def test_stl_bytes_are_deterministic_and_faithful() -> None:
    dims = random_links(1, seed=99)[0]
    builds = [
        (lambda: meshes.link_mesh(*dims)),
        (lambda: meshes.foot_mesh(0.05, 0.005)),
        (lambda: meshes.plate_mesh(0.2, 0.1, 0.004)),
        (lambda: meshes.wheel_mesh(0.04, 0.01)),
    ]
    for make in builds:
        a, b = make(), make()
        stl = meshes.stl_bytes(a)
        assert stl == meshes.stl_bytes(b)
        assert stl[:80] == meshes.STL_HEADER and len(stl) == 84 + 50 * len(a.faces)
        back = load(stl)
        assert back.is_watertight
        assert back.volume == pytest.approx(a.volume, rel=1e-5)


def test_invalid_parts_are_rejected() -> None:
    with pytest.raises(ValueError, match="face_side/2"):
        meshes.link_mesh(0.1, 0.02, 0.018, 0.045, 0.004, 0.003)  # fillet off the plate
    with pytest.raises(ValueError, match="face_side/2"):
        link_part_volume(2.0, 0.5, 0.25, 1.5, 0.0625, 0.25)  # fillet to the plate's edge
    with pytest.raises(ValueError, match="multiple of 8"):
        meshes.link_mesh(0.1, 0.012, 0.009, 0.05, 0.004, 0.003, segments=60)
    with pytest.raises(ValueError, match="must not overlap"):
        link_part_volume(0.012, 0.01, 0.008, 0.05, 0.004, 0.003)
    with pytest.raises(ValueError, match="both face_side and face_thickness"):
        link_part_volume(0.1, 0.01, 0.008, 0.05, 0.0, 0.0)
    with pytest.raises(ValueError, match="r_inner"):
        meshes.link_mesh(0.1, 0.01, 0.01)
    with pytest.raises(ValueError, match="bore"):
        meshes.wheel_mesh(0.01, 0.01, bore=0.02)
    with pytest.raises(ValueError):
        meshes.plate_mesh(0.1, 0.0, 0.004)


def test_fits_bed_keeps_the_print_orientation_and_the_skirt() -> None:
    bed = (0.22, 0.22, 0.25)
    assert meshes.fits_bed((0.05, 0.05, 0.24), bed)
    assert not meshes.fits_bed((0.24, 0.05, 0.05), bed)  # as printed: too long for the bed
    assert meshes.fits_bed((0.05, 0.21, 0.05), (0.22, 0.20, 0.25))  # turned about z
    assert meshes.fits_bed((0.22, 0.22, 0.25), bed)
    assert not meshes.fits_bed((0.22, 0.22, 0.25), bed, margin=0.003)  # the skirt leaves it
    assert meshes.fits_bed((0.214, 0.1, 0.01), bed, margin=0.003)
    assert not meshes.fits_bed((0.23, 0.23, 0.01), bed)
    assert not meshes.fits_bed((0.05, 0.05, 0.26), bed)


def test_print_orientation_puts_the_largest_flat_face_down() -> None:
    """A mushroom (a wide cap on a narrow stem) built cap up overhangs under its cap; the
    chosen orientation turns it cap down, with no overhang, its cap on the bed."""
    import manifold3d as mf

    stem = mf.Manifold.cylinder(0.03, 0.005, circular_segments=32)
    cap = mf.Manifold.cube((0.04, 0.04, 0.004)).translate((-0.02, -0.02, 0.03))
    mesh = meshes._to_mesh(stem + cap)
    upright = meshes.orientation_figures(mesh, np.eye(3))
    assert upright[0] > 0.04 * 0.04 * 0.9  # the cap's underside, printed over nothing
    T = meshes.print_orientation(mesh)
    R = T[:3, :3]
    overhang, bed = meshes.orientation_figures(mesh, R)
    assert overhang == pytest.approx(0.0, abs=1e-9)
    assert bed == pytest.approx(0.04 * 0.04, rel=1e-6)
    placed = mesh.copy().apply_transform(T)
    assert placed.bounds[0][2] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(placed.bounds[:, :2].sum(axis=0), 0.0, atol=1e-12)


def _manifold(mesh: trimesh.Trimesh):
    import manifold3d as mf

    v = np.asarray(mesh.vertices, dtype=np.float64) * 1000.0  # mm
    return mf.Manifold(
        mf.Mesh(vert_properties=v.astype(np.float32), tri_verts=mesh.faces.astype(np.uint32))
    )


@pytest.mark.parametrize("clearance", [0.0002, 0.0003])
def test_dovetail_pin_slides_in_the_next_links_rail_with_the_clearance(clearance) -> None:
    """Two printed neighbouring links, the second slid onto the first's pin: they
    intersect in nothing, and the pin grown by a little less than the clearance still
    intersects nothing, grown by a little more it does (the gap is the clearance)."""
    face = (0.05, 0.004, 0.003)
    a = meshes.link_mesh(0.1, 0.0104, 0.0092, *face, clearance=clearance)
    b = meshes.link_mesh(0.08, 0.012, 0.0105, *face, clearance=clearance)
    first, second = _manifold(a), _manifold(b).translate((0.0, 0.0, 100.0))
    assert (first ^ second).volume() == pytest.approx(0.0, abs=1e-6)
    c = clearance * 1000.0
    for grow, empty in ((c - 0.02, True), (c + 0.02, False)):
        pin = meshes.dovetail_solid_mm(50.0).translate((0, 0, 100.0))
        grown = meshes.dovetail_solid_mm(50.0, grow).translate((0, 0, 100.0))
        # the grown pin, less the pin's own root and what lies below the face, against b
        shell = grown - pin
        hit = (shell ^ second).volume()
        assert (hit < 1e-6) == empty, (grow, hit)


def test_dovetail_slot_too_deep_for_the_plate_is_refused() -> None:
    with pytest.raises(ValueError, match="does not fit"):
        meshes.link_mesh(0.1, 0.0104, 0.0092, 0.05, 0.002, 0.003, clearance=0.0002)
