"""export.assembly and the templates' labelled parts.

The templates: every body is exactly the combination of its labelled parts, and face
plates and fillets add exactly their analytic mass. The assembly of the default design of
every base configuration: every body equals the combination of its parts recomputed
independently (printed parts from their STL bytes, modules from the catalog); the printed
parts add up to the template's segments, feet and wheels; joints carry the chosen
actuator's figures; the robot stands on z = 0; the total mass is the structure's.
"""

from __future__ import annotations

import dataclasses
import io
import re
from math import pi

import numpy as np
import pytest
import trimesh

from export import meshes
from export.assembly import build_assembly, with_payload
from export.slicer import estimate
from gaits.steered import steering_joints
from kinematics.spatial import box_inertia, combine_parts, sphere_inertia
from kinematics.templates import DEFAULTS, PART_KINDS, TemplateParams, build
from synth.reasoning.solver import Query
from synth.sizing.structure import Structure, design_structure
from tests.conftest import TEMPLATES

FACES = {"face_side": 0.05, "face_thickness": 0.004, "fillet": 0.003}


# --- the templates' labelled parts ------------------------------------------------------------


def _params(robot_type: str, faces: bool) -> TemplateParams:
    lengths = {k: 1.2 * x for k, x in DEFAULTS[robot_type].items()}
    names = sorted({s.length_name for s in build(robot_type).segments})
    tubes = {n: (0.010 + 0.001 * i, 0.008) for i, n in enumerate(names)}
    extra = FACES if faces else {}
    return TemplateParams(lengths=lengths, tubes=tubes, payload=0.2, modules=4, **extra)


@pytest.mark.parametrize("faces", [False, True])
@pytest.mark.parametrize("robot_type", TEMPLATES)
def test_bodies_are_their_labelled_parts(robot_type: str, faces: bool) -> None:
    t = build(robot_type, _params(robot_type, faces))
    m = t.model
    assert set(t.parts) == {b.name for b in m.bodies}
    for i, body in enumerate(m.bodies):
        parts = t.parts[body.name]
        mass, com, inertia = combine_parts(lp.part for lp in parts)
        assert mass == pytest.approx(body.mass, rel=1e-12, abs=1e-15)
        np.testing.assert_allclose(com, body.com, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(inertia, body.inertia, rtol=1e-12, atol=1e-15)
        for lp in parts:
            assert lp.kind in PART_KINDS
            R = lp.placement[:3, :3]
            np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
            assert np.linalg.det(R) == pytest.approx(1.0)
        actuators = [lp for lp in parts if lp.kind == "actuator"]
        # a wheel's servo is on its parent (the chassis, a steering hub), a steering joint's
        # too (over the wheel); a passive joint has none; other joints' on their own body
        steering = {j for j, _ in steering_joints(t)}

        def on_parent(j, steering=steering) -> bool:
            return (j.kind == "continuous" and j.name not in t.passive) or j.name in steering

        own = m.joints[i]
        alone = own.movable and not on_parent(own) and own.name not in t.passive
        mine = [own.name] if alone else []
        held = [j.name for j in m.joints if on_parent(j) and j.parent == i]
        assert [lp.label for lp in actuators] == mine + held
    links = {lp.label: (name, lp) for name, ps in t.parts.items() for lp in ps if lp.kind == "link"}
    assert sorted(links) == sorted(s.name for s in t.segments)
    for s in t.segments:
        body, lp = links[s.name]
        assert body == s.body
        np.testing.assert_allclose(lp.placement[:3, 3], s.start, atol=1e-15)
        np.testing.assert_allclose(lp.placement[:3, 2], s.direction, atol=1e-15)
        assert lp.dims[:3] == (s.length, s.r_outer, s.r_inner)
        assert lp.dims[3:] == ((0.05, 0.004, 0.003) if faces else (0.0, 0.0, 0.0))

    def bodies_of(kind: str) -> list[str]:
        return sorted(n for n, ps in t.parts.items() for lp in ps if lp.kind == kind)

    assert bodies_of("foot") == sorted(t.feet)
    assert bodies_of("wheel") == sorted(t.wheels)
    assert bodies_of("caster") == sorted(t.casters)
    assert len(bodies_of("trunk")) == 1 and bodies_of("trunk")[0] == m.bodies[0].name
    # every gripper has its jaws (two by default), each a part of the gripper's body
    assert bodies_of("gripper") == sorted(e for e in t.end_effectors for _ in range(2))


@pytest.mark.parametrize("robot_type", TEMPLATES)
def test_faces_add_two_plates_and_two_fillet_rings_per_link(robot_type: str) -> None:
    bare = build(robot_type, _params(robot_type, False))
    faced = build(robot_type, _params(robot_type, True))
    a, t, f = FACES["face_side"], FACES["face_thickness"], FACES["fillet"]
    rho = faced.params.density
    extra = 0.0
    for s in faced.segments:
        plates = 2 * t * (a * a - pi * s.r_outer**2)
        centroid = s.r_outer + f * (10 - 3 * pi) / (12 - 3 * pi)
        rings = 2 * 2 * pi * centroid * f * f * (1 - pi / 4)
        extra += rho * (plates + rings)
    assert faced.model.total_mass - bare.model.total_mass == pytest.approx(extra, rel=1e-9)
    assert faced.model.nv == bare.model.nv


def test_face_parameters_are_checked() -> None:
    with pytest.raises(ValueError, match="face_side and face_thickness"):
        build("Manipulator3DOF", TemplateParams(face_side=0.05))
    with pytest.raises(ValueError, match="fillet"):
        build("Manipulator3DOF", TemplateParams(fillet=0.003))
    with pytest.raises(ValueError, match="face_side"):
        build("Manipulator3DOF", TemplateParams(face_side=0.02, face_thickness=0.004, fillet=0.003))


# --- assemblies of the default designs ---------------------------------------------------------


@pytest.fixture(scope="module")
def structures(kb, designer, catalog) -> dict[str, Structure]:
    bases = {c.robot_type: c for c in designer.reasoner.solve(Query()).candidates}
    return {t: design_structure(kb, c, catalog, {}) for t, c in bases.items()}


def with_faces(s: Structure, catalog) -> Structure:
    """``s`` as the structure generator gives it once it weighs the printed links whole:
    the template rebuilt with the catalog's faces and fillets, and a humanoid's foot plate
    weighed as the plate it is (if ``s`` has faces already, ``s`` itself)."""
    tp = s.template.params
    if tp.face_side > 0:
        return s
    p = catalog.passive
    changes = {
        "face_side": p.dovetail_face_m,
        "face_thickness": p.face_thickness_m,
        "fillet": p.fillet_radius_m,
    }
    plates = [lp for ps in s.template.parts.values() for lp in ps if lp.kind == "foot" and lp.dims]
    if plates:
        lx, ly = plates[0].dims[:2]
        changes["foot_mass"] = lx * ly * p.foot_thickness_m * catalog.material.density_kg_m3
    t = build(s.robot_type, dataclasses.replace(tp, **changes))
    return dataclasses.replace(s, template=t, mass_kg=t.model.total_mass)


@pytest.fixture(scope="module")
def faced(structures, catalog) -> dict[str, Structure]:
    return {t: with_faces(s, catalog) for t, s in structures.items()}


@pytest.fixture(scope="module")
def assemblies(faced, catalog):
    return {t: build_assembly(s, catalog) for t, s in faced.items()}


def _recomputed(part, printed: dict, catalog, template) -> tuple[float, np.ndarray, np.ndarray]:
    """A part's mass properties from its STL bytes or the catalog (body frame)."""
    g = part.geometry
    rho = catalog.material.density_kg_m3
    if part.source == "printed":
        stem = g.mesh.removesuffix(".stl")
        mesh = trimesh.load(io.BytesIO(printed[stem].stl), file_type="stl").apply_scale(1e-3)
        assert mesh.is_watertight
        props = mesh.mass_properties
        m, c, inertia = props["mass"] * rho, props["center_mass"], props["inertia"] * rho
    elif part.source == "module":
        entry = {a.model: a for a in (*catalog.actuators, *catalog.modules)}[part.name]
        m, size = entry.mass_kg, entry.size_m
        assert g.kind == "box" and tuple(g.size) == tuple(size)
        inertia = box_inertia(m, size)
        c = np.zeros(3)
    elif part.source == "bought" and part.kind == "CasterModule":
        ball = catalog.part_of("CasterModule")
        assert part.name == ball.model and g.kind == "sphere"
        assert g.size[0] == pytest.approx(ball.size_m[0] / 2)
        m = ball.mass_kg
        inertia, c = sphere_inertia(m, g.size[0]), np.zeros(3)
    elif part.source == "bought" and part.kind == "BearingModule":  # a free wheel's hub
        hub = catalog.part_of("BearingModule")
        assert part.name == hub.model and g is None
        assert part.mass == pytest.approx(hub.mass_kg, rel=1e-12)
        return part.mass, part.com, part.inertia
    elif part.source == "bought":  # a tyre: a ring around the wheel's axle (its z)
        assert part.kind == "Tyre" and g is None
        r, w = template.params.wheel_radius, catalog.passive.wheel_width_m
        m = catalog.tyre.mass_kg(r, w)
        assert part.mass == pytest.approx(m, rel=1e-12)
        return m, part.com, part.inertia
    elif part.source == "contact":  # a leg's massless rounded point, a wheel's rim cylinder
        assert part.mass == 0 and g.kind in ("sphere", "cylinder") and g.contact
        return 0.0, part.com, np.zeros((3, 3))
    else:
        raise AssertionError(f"a part of source {part.source!r} in the robot's model")
    R, p = g.origin[:3, :3], g.origin[:3, 3]
    return m, R @ c + p, R @ inertia @ R.T


def _combine(items) -> tuple[float, np.ndarray, np.ndarray]:
    """Parallel axis theorem, written out independently of kinematics.spatial."""
    total = sum(m for m, _, _ in items)
    com = sum(m * c for m, c, _ in items) / total
    inertia = np.zeros((3, 3))
    for m, c, i in items:
        d = c - com
        inertia += i + m * (d @ d * np.eye(3) - np.outer(d, d))
    return total, com, inertia


def test_every_body_is_its_parts_recomputed_from_stl_and_catalog(
    assemblies, faced, catalog
) -> None:
    for t, asm in assemblies.items():
        printed = {p.name: p for p in asm.printed}
        template = faced[t].template
        for body in asm.bodies:
            items = [_recomputed(u, printed, catalog, template) for u in body.parts]
            m, com, inertia = _combine(items)
            where = f"{t}/{body.name}"
            assert body.mass == pytest.approx(m, rel=0.01), where
            np.testing.assert_allclose(body.com, com, atol=1e-4, err_msg=where)
            scale = np.abs(inertia).max()
            np.testing.assert_allclose(body.inertia, inertia, atol=0.01 * scale, err_msg=where)


def test_total_mass_is_the_structures(assemblies, faced) -> None:
    """The structure is sized with its payload; the assembly keeps it aside."""
    for t, asm in assemblies.items():
        loaded = asm.total_mass + asm.payload_mass
        assert loaded == pytest.approx(faced[t].mass_kg, rel=0.01), t
        assert with_payload(asm).total_mass == pytest.approx(loaded, rel=1e-12), t
        assert not [n for n in asm.notes if "weighs" in n], (t, asm.notes)


def test_printed_parts_add_up_to_the_template(assemblies, faced) -> None:
    for t, asm in assemblies.items():
        tmpl = faced[t].template
        by_kind: dict[str, int] = {}
        for p in asm.printed:
            by_kind[p.kind] = by_kind.get(p.kind, 0) + p.count
        assert by_kind.get("link", 0) == len(tmpl.segments), t
        assert by_kind.get("foot", 0) == len(tmpl.feet), t
        assert by_kind.get("wheel", 0) == len(tmpl.wheels), t
        assert by_kind.get("plate", 0) == 1, t
        per_length: dict[str, int] = {}
        for s in tmpl.segments:
            per_length[s.length_name] = per_length.get(s.length_name, 0) + 1
        links: dict[str, int] = {}
        for p in asm.printed:  # a design per length (and whether its far end has a pin)
            if p.kind == "link":
                stem = re.sub(r"_\d+$", "", p.name)
                links[stem] = links.get(stem, 0) + p.count
        assert links == {f"link_{n.lower()}": k for n, k in per_length.items()}, t
        uses: dict[str, int] = {}
        for b in asm.bodies:
            for u in b.parts:
                if u.source == "printed":
                    uses[u.name] = uses.get(u.name, 0) + 1
        assert uses == {p.name: p.count for p in asm.printed}, t


def load_part(p) -> trimesh.Trimesh:
    """A printed part's mesh from its STL (mm) in metres."""
    return trimesh.load(io.BytesIO(p.stl), file_type="stl").apply_scale(1e-3)


def test_printed_part_figures(assemblies, catalog) -> None:
    rho = catalog.material.density_kg_m3
    passive = catalog.passive
    for t, asm in assemblies.items():
        names = [p.name for p in asm.printed]
        assert len(set(names)) == len(names), t
        for p in asm.printed:
            assert re.fullmatch(r"[a-z0-9_]+", p.name), p.name
            assert p.stl[:80] == meshes.STL_HEADER
            assert p.volume_m3 == pytest.approx(p.analytic_volume_m3, rel=0.01), (t, p.name)
            assert p.mass_kg == pytest.approx(p.volume_m3 * rho, rel=1e-12)
            assert p.fits_bed == meshes.fits_bed(p.extents_m, passive.printer_bed_m, 0.003)
            t, f = estimate(meshes.print_features(load_part(p)))
            assert p.print_time_s == pytest.approx(t) and p.filament_m3 == pytest.approx(f)
            assert p.filament_m3 >= p.volume_m3
            if p.kind == "link":  # two face sides and the length, however it lies
                face = passive.dovetail_face_m
                assert sum(abs(e - face) < 1e-6 for e in p.extents_m) >= 2, (t, p.name)
            # printed as oriented: on the bed (z from 0), no axis turn needs less support
            mesh = trimesh.load(io.BytesIO(p.stl), file_type="stl").apply_scale(1e-3)
            assert mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-9)
            assert p.overhang_m2 == pytest.approx(
                meshes.orientation_figures(mesh, np.eye(3))[0], abs=1e-9
            )
            need = meshes.support_measure(mesh)
            for k in range(3):
                for sign in (1, -1):
                    n = np.zeros(3)
                    n[k] = sign
                    turned = mesh.copy().apply_transform(
                        np.vstack([np.column_stack([meshes._down(n), np.zeros(3)]), [0, 0, 0, 1]])
                    )
                    assert need <= meshes.support_measure(turned) + 1e-9, (t, p.name, k, sign)


def test_joints_carry_the_chosen_actuators(assemblies, faced, catalog) -> None:
    by_model = {a.model: a for a in catalog.actuators}
    for t, asm in assemblies.items():
        s = faced[t]
        model = s.template.model
        assert asm.root == model.bodies[0].name
        assert [b.name for b in asm.bodies] == [b.name for b in model.bodies]
        assert [j.name for j in asm.joints] == [j.name for j in model.joints if j.parent >= 0]
        specs = {j.name: j for j in asm.joints}
        for j in model.joints[1:]:
            spec = specs[j.name]
            assert spec.parent == model.bodies[j.parent].name
            assert spec.child == model.bodies[j.child].name
            assert spec.kind == j.kind
            np.testing.assert_array_equal(spec.origin, j.origin)
            if j.kind == "fixed":
                assert spec.effort == spec.velocity == 0.0
        for jd in s.joints:
            a = by_model[jd.actuator]
            spec = specs[jd.name]
            assert spec.effort == a.stall_torque_Nm and spec.velocity == a.no_load_speed_rad_s
            assert spec.actuator == jd.actuator
            steering = {j for j, _ in steering_joints(s.template)}
            if spec.kind == "continuous" or spec.name in steering:
                # a wheel's servo: on the chassis (or a steering hub) beside the wheel; a
                # steering joint's: on the chassis over the wheel
                axis = spec.origin[:3, :3] @ spec.axis
                boxes = [u for u in asm.body(spec.parent).parts if u.name == jd.actuator]
                box = min(
                    boxes,
                    key=lambda u: np.linalg.norm(u.geometry.origin[:3, 3] - spec.origin[:3, 3]),
                )
                held = [  # servos of the joints that sit on the child (a steered wheel's)
                    k for k in asm.joints if k.parent == spec.child and k.actuator
                ]
                modules = [u for u in asm.body(spec.child).parts if u.source == "module"]
                assert len(modules) == len(held)
            else:
                axis = spec.axis
                box = next(u for u in asm.body(spec.child).parts if u.source == "module")
            assert box.name == jd.actuator and box.mass == a.mass_kg
            np.testing.assert_allclose(box.geometry.origin[:3, 2], axis, atol=1e-12)


def test_the_robot_stands_on_the_ground(assemblies, faced) -> None:
    for t, asm in assemblies.items():
        tmpl = faced[t].template
        L = tmpl.lengths
        assert asm.fixed_base == t.startswith("Manipulator"), t
        assert (asm.feet, asm.wheels, asm.casters) == (tmpl.feet, tmpl.wheels, tmpl.casters)
        if t in ("HexapodRobot", "QuadrupedRobot"):
            assert asm.spawn_height == pytest.approx(L["tibia"], abs=1e-9)
        elif tmpl.wheels:
            assert asm.spawn_height == pytest.approx(tmpl.params.wheel_radius, abs=1e-9)
        elif t == "HumanoidRobot":
            sole = tmpl.params.actuator_size[2] / 2
            assert asm.spawn_height == pytest.approx(L["femur"] + L["tibia"] + sole, abs=1e-9)
        else:
            assert asm.spawn_height > 0


def test_assembly_is_deterministic_and_notes_bare_links(structures, faced, catalog) -> None:
    s = faced["Manipulator3DOF"]
    a, b = build_assembly(s, catalog), build_assembly(s, catalog)
    assert [p.stl for p in a.printed] == [p.stl for p in b.printed]
    assert [x.mass for x in a.bodies] == [x.mass for x in b.bodies]
    bare = structures["Manipulator3DOF"]
    if bare.template.params.face_side == 0:
        notes = build_assembly(bare, catalog).notes
        assert any("face plates" in n for n in notes)


def test_servo_range_is_the_travel_over_the_span_used() -> None:
    from export.assembly import servo_range

    assert servo_range(-1.0, 1.0, pi) == (-1.0, 1.0)  # fits whole
    assert servo_range(-pi, pi, pi) == pytest.approx((-pi / 2, pi / 2))  # about the middle
    lo, hi = servo_range(-5 * pi / 6, 5 * pi / 6, pi, (1.5, 2.3))  # over what is used
    assert hi - lo == pytest.approx(pi) and lo <= 1.5 and hi >= 2.3
    assert hi <= 5 * pi / 6 + 1e-12
    lo, hi = servo_range(-pi, pi, pi / 2, (-1.0, 1.0))  # more than the travel: centred on it
    assert (lo, hi) == pytest.approx((-pi / 4, pi / 4))
