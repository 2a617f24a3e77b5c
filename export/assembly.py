"""The physical assembly of a sized design: ``build_assembly(structure, catalog)``.

It rebuilds every body of the structure's kinematic template from the template's labelled
parts (``Template.parts``), with the real parts in place of the template's stand-ins:

- printed parts become meshes (``export.meshes``) placed in the body frame, their mass
  properties computed from the mesh with the catalog material's density:
  - links: the printed link module (tube + two dovetail face plates + fillets) with the
    sized tube and the catalog's ``dovetail_face_m``, ``face_thickness_m`` and
    ``fillet_radius_m``, whatever the template was built with (a note says so when the
    template's links leave the faces out), a dovetail pin on its far face (unless it is a
    free end: a leg's tip) and a rail's slot in its near face sized with the catalog's
    ``print_clearance_m`` (``meshes.link_mesh``; ``meshes.dovetail_volume`` adds them to
    the analytic volume; the structure generator weighs the link without them: up to
    5 % of a link's plates and tube, about 1 g);
  - feet: a square pad of the catalog's ``foot_min_side_m`` and ``foot_thickness_m`` (the
    figures the structure generator weighs) whose sole is the template's foot point, so
    the pad fills the last ``foot_thickness_m`` of the tibia's length; a humanoid's foot is
    a plate of the template's foot length and width, ``foot_thickness_m`` thick;
  - wheels: a disc of the wheel radius and the catalog's ``wheel_width_m`` with a hub bore;
  - the root body's plate (trunk, chassis, manipulator base plate): the template's root
    part is the structure's ``trunk_mass`` = the trunk's catalog modules (main module,
    battery, sensors) + a printed plate. The plate is what the modules leave of that mass:
    a plate of the catalog's ``face_thickness_m`` with the footprint of the template's
    root box scaled to that area (for the structure generator's figures: La1 x La2 for
    legged trunks, L1 x L2 for chassis, shoulder width x trunk height for a humanoid, a
    dovetail face for a manipulator base or a snake's head).
- catalog modules become boxes of the catalog's size and mass: each joint's chosen
  actuator centred on the joint with its shaft (the catalog size's z) along the joint axis;
  the trunk's modules in rows on the plate, on the side the template's root part frame
  points to (up; down under a manipulator's base; behind a humanoid's trunk);
- a gripper's jaws are the catalog's FingerModule (printed plates of its size, placed where
  the template puts each jaw); a ball caster is the catalog's bought CasterModule (a sphere
  of its mass); a wheel is a printed rim inside the catalog's tyre (bought); a passive
  joint's bearing hub (a free wheel's) is the catalog's bought BearingModule;
- the payload is not part of the robot: ``build_assembly`` keeps it aside
  (``Assembly.payload``: where the template puts it) and :func:`with_payload` adds it to
  its body for a model that carries it (the verification's, or ``--with-payload``).
- revolute joints turn no further than their servo: the template's range is cut to a
  window of the catalog's ``travel_deg`` (:func:`servo_range`), placed over the span the
  design's behaviours use (``used``) or else about the range's middle.

Body mass, COM and inertia are the combination of the body's parts (parallel axis
theorem). Alike parts share one printed design (one STL, counted once per use).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from adron.catalog import Catalog, Module
from adron.errors import ExportError
from export import meshes
from export.model3d import (
    Assembly,
    BodySpec,
    Geometry,
    JointSpec,
    PartUse,
    PrintedPart,
)
from export.slicer import SKIRT_MARGIN, estimate
from kinematics.spatial import (
    box_inertia,
    combine_parts,
    link_part_volume,
    rotate_inertia,
    transform,
    transform_from,
    tube_inertia,
)
from kinematics.templates import LabelledPart, Template

if TYPE_CHECKING:
    from export.polymesh import Mesh
    from synth.sizing.structure import Structure

__all__ = [
    "PRINTED_RGBA",
    "MODULE_RGBA",
    "build_assembly",
    "safe_name",
    "servo_range",
    "with_payload",
]

PRINTED_RGBA = (0.95, 0.55, 0.15, 1.0)  # printed PLA
MODULE_RGBA = (0.25, 0.25, 0.28, 1.0)  # catalog modules
CASTER_RGBA = (0.7, 0.7, 0.72, 1.0)
TYRE_RGBA = (0.1, 0.1, 0.1, 1.0)
_MIN_PLATE_KG = 1e-9


def safe_name(name: str) -> str:
    """A file stem of [a-z0-9_] from ``name``."""
    return re.sub(r"_+", "_", re.sub(r"[^a-z0-9_]", "_", name.lower())).strip("_") or "part"


def _frame_z(axis: np.ndarray) -> np.ndarray:
    """Rotation (3,3) whose z column is ``axis`` (x: the body's z or x made perpendicular)."""
    z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


@dataclass
class _Design:
    """One printed part design while the assembly is built."""

    name: str
    kind: str
    mesh: Mesh  # as printed: on the bed in its best orientation
    analytic_volume: float
    props: tuple[float, np.ndarray, np.ndarray]  # mass kg, com, inertia (part frame)
    to_bed: np.ndarray  # (4, 4): part frame -> print frame (``meshes.print_orientation``)
    count: int = 0


@dataclass
class _Builder:
    structure: Structure
    catalog: Catalog
    designs: dict[tuple, _Design] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    payload: list[tuple[str, PartUse]] = field(default_factory=list)

    @property
    def rho(self) -> float:
        return self.catalog.material.density_kg_m3

    def design(self, key: tuple, name: str, kind: str, build, analytic: float) -> _Design:
        """The printed design for ``key`` (built once), with one more use counted."""
        d = self.designs.get(key)
        if d is None:
            taken = {x.name for x in self.designs.values()}
            stem, k = safe_name(name), 2
            unique = stem
            while unique in taken:
                unique, k = f"{stem}_{k}", k + 1
            mesh = build()
            to_bed = meshes.print_orientation(mesh)
            props = meshes.mesh_mass_properties(mesh, self.rho)
            on_bed = mesh.copy().apply_transform(to_bed)
            d = _Design(unique, kind, on_bed, analytic, props, to_bed)
            self.designs[key] = d
        d.count += 1
        return d

    def printed(self, d: _Design, placement: np.ndarray) -> PartUse:
        """A use of design ``d`` with its part frame at ``placement`` (body frame); the
        mesh, as printed, sits at ``placement`` times the inverse of ``d.to_bed``."""
        m, c, inertia = d.props
        R, p = placement[:3, :3], placement[:3, 3]
        at = placement @ np.linalg.inv(d.to_bed)
        geom = Geometry("mesh", at, mesh=f"{d.name}.stl", rgba=PRINTED_RGBA, name=d.name)
        return PartUse(d.name, "printed", m, R @ c + p, rotate_inertia(R, inertia), geom)


def _module_use(m, placement: np.ndarray) -> PartUse:
    """A catalog module (actuator or active module ``m``): a box of its size and mass."""
    R = placement[:3, :3]
    size = tuple(float(s) for s in m.size_m)
    geom = Geometry("box", placement, size, rgba=MODULE_RGBA, name=m.model)
    inertia = rotate_inertia(R, box_inertia(m.mass_kg, m.size_m))
    return PartUse(
        m.model,
        "module",
        float(m.mass_kg),
        placement[:3, 3].copy(),
        inertia,
        geom,
        m.ontology_class,
        float(m.cost),
    )


# --- the parts of each kind ----------------------------------------------------------------


def _actuator(
    b: _Builder, lp: LabelledPart, body: str, axis: np.ndarray, models: dict, tmpl: Template
) -> PartUse:
    """The joint's catalog module, shaft (size z) along the joint axis. It sits on the
    joint's own body (``axis``, body frame), or on its parent (a wheel's servo is on the
    chassis): then the axis is the joint's, turned into the parent's frame."""
    a = models.get(lp.label)
    if a is None:
        raise ExportError(f"joint '{lp.label}' has no actuator in the structure")
    m = tmpl.model
    j = m.joints[m.joint(lp.label)]
    if m.bodies[j.child].name != body:
        axis = j.origin[:3, :3] @ j.axis
    placement = transform_from(_frame_z(axis), lp.placement[:3, 3])
    return _module_use(a, placement)


def _link(b: _Builder, lp: LabelledPart, tmpl: Template) -> PartUse:
    seg = next(s for s in tmpl.segments if s.name == lp.label)
    p = b.catalog.passive
    length, ro, ri = lp.dims[:3]
    faces = (p.dovetail_face_m, p.face_thickness_m, p.fillet_radius_m)
    dims = (length, ro, ri, *faces)
    design_name = seg.length_name or seg.name
    pin = seg.distal_joint is not None  # a free end (a foot's, a tip) has no neighbour
    d = b.design(
        ("link", design_name, *dims, pin),
        f"link_{design_name}",
        "link",
        lambda: meshes.link_mesh(*dims, clearance=p.print_clearance_m, pin=pin),
        link_part_volume(*dims)
        + meshes.dovetail_volume(p.dovetail_face_m, ri, p.print_clearance_m, pin),
    )
    return b.printed(d, lp.placement)


def _foot(b: _Builder, lp: LabelledPart) -> PartUse:
    p = b.catalog.passive
    t = p.foot_thickness_m
    if lp.dims:  # a foot plate (humanoid)
        lx, ly = lp.dims[0], lp.dims[1]
        d = b.design(
            ("foot_plate", lx, ly, t),
            "foot_plate",
            "foot",
            lambda: meshes.plate_mesh(lx, ly, t),
            lx * ly * t,
        )
    else:
        s = p.foot_min_side_m
        d = b.design(("foot", s, t), "foot", "foot", lambda: meshes.foot_mesh(s, t), s * s * t)
    return b.printed(d, lp.placement)


#: Radius (m) of the rounded contact of a leg's foot pad with the ground.
FOOT_CONTACT_RADIUS = 0.01


def _point_foot(uses: list[PartUse], sole: np.ndarray) -> list[PartUse]:
    """A leg's foot touches the ground at one rounded point, the sole's centre: the pad and
    the tube are seen but do not collide (a flat 5 cm pad twisted and tipped on the floor
    would load the coxa and tibia servos with friction a rubber-tipped leg does not have)."""
    out = [
        replace(u, geometry=replace(u.geometry, contact=False)) if u.geometry else u for u in uses
    ]
    centre = transform((sole[0], sole[1], sole[2] + FOOT_CONTACT_RADIUS))
    ball = Geometry(
        "sphere", centre, (FOOT_CONTACT_RADIUS,), rgba=PRINTED_RGBA, name="foot_contact"
    )
    out.append(
        PartUse("foot_contact", "contact", 0.0, centre[:3, 3].copy(), np.zeros((3, 3)), ball)
    )
    return out


def _wheel(b: _Builder, lp: LabelledPart) -> list[PartUse]:
    """The printed rim (seen, not touching: its mesh is a polygon that would roll
    bumpily), the catalog's tyre around it (bought: a ring of its mass, no shape of its
    own) and the contact with the ground: a cylinder of the wheel's radius and width."""
    # the wheel kind's own width when it gives one (the template's), else the catalog's
    own = b.structure.template.params.wheel_width
    r, w = lp.dims[0], own or b.catalog.passive.wheel_width_m
    tyre = b.catalog.tyre
    t = tyre.thickness_m if tyre is not None else 0.0
    rim_r, bore = r - t, meshes.WHEEL_BORE
    d = b.design(
        ("wheel", rim_r, w),
        "wheel_rim" if tyre is not None else "wheel",
        "wheel",
        lambda: meshes.wheel_mesh(rim_r, w),
        np.pi * (rim_r * rim_r - bore * bore) * w,
    )
    use = b.printed(d, lp.placement @ transform((0.0, 0.0, -w / 2)))
    seen = replace(use, geometry=replace(use.geometry, contact=False))
    tread = Geometry("cylinder", lp.placement, (r, w), rgba=TYRE_RGBA, name="wheel_contact")
    centre = lp.placement[:3, 3].copy()
    out = [seen, PartUse("wheel_contact", "contact", 0.0, centre, np.zeros((3, 3)), tread)]
    if tyre is not None:
        m = tyre.mass_kg(r, w)
        inertia = rotate_inertia(lp.placement[:3, :3], tube_inertia(m, w, r, rim_r, (0, 0, 1)))
        cost = tyre.cost(r)
        out.append(PartUse(tyre.name, "bought", m, centre, inertia, None, "Tyre", cost))
    return out


def _jaw(b: _Builder, lp: LabelledPart) -> PartUse:
    """One jaw of a gripper: the catalog's printed FingerModule (a plate of its size, the
    template's jaw frame: x along the jaw, z across the gap), printed flat."""
    lx, ly, t = lp.dims
    jaws = [q for q in b.catalog.parts if q.ontology_class == "FingerModule"]
    name = jaws[0].model if jaws else "jaw"
    d = b.design(
        ("jaw", lx, ly, t), name, "finger", lambda: meshes.plate_mesh(lx, ly, t), lx * ly * t
    )
    return b.printed(d, lp.placement @ transform((0.0, 0.0, -t / 2)))


def _caster(b: _Builder, lp: LabelledPart) -> PartUse:
    """The ball caster: the catalog's bought CasterModule (a sphere of the template's
    radius and mass, which the structure took from the catalog)."""
    balls = [q for q in b.catalog.parts if q.ontology_class == "CasterModule"]
    name, cost = (balls[0].model, balls[0].cost) if balls else ("ball caster", 0.0)
    geom = Geometry("sphere", lp.placement, lp.dims, rgba=CASTER_RGBA, name="ball_caster")
    com, inertia = lp.com.copy(), lp.inertia.copy()
    return PartUse(name, "bought", lp.mass, com, inertia, geom, "CasterModule", cost)


def _bearing(b: _Builder, lp: LabelledPart) -> PartUse:
    """The bearing hub of a passive joint (a free wheel's): the catalog's bought
    BearingModule, of the template's mass (which the structure took from the catalog),
    inside the wheel's rim (no shape of its own)."""
    hubs = [q for q in b.catalog.parts if q.ontology_class == "BearingModule"]
    name, cost = (hubs[0].model, hubs[0].cost) if hubs else ("bearing hub", 0.0)
    com, inertia = lp.com.copy(), lp.inertia.copy()
    return PartUse(name, "bought", lp.mass, com, inertia, None, "BearingModule", cost)


def _tool(lp: LabelledPart) -> PartUse:
    """A tool without joints at an arm's tip (a probe, a nozzle, a camera): bought, a box
    of the part kind's size and mass (its price is not in the catalog)."""
    geom = Geometry("box", lp.placement, lp.dims, name=f"{lp.label}_box")
    com, inertia = lp.com.copy(), lp.inertia.copy()
    return PartUse(f"tool on {lp.label}", "bought", lp.mass, com, inertia, geom, "RobotTool")


def _trunk_modules(b: _Builder) -> list[Module]:
    """The catalog modules of the root body: the structure's modules that are not joint
    actuators (main module, battery, sensors), one entry per unit, in the record's order."""
    actuators = {a.model for a in b.catalog.actuators}
    by_model = {m.model: m for m in b.catalog.modules}
    out = []
    for use in b.structure.modules:
        if use.model in actuators:
            continue
        if use.model not in by_model:
            raise ExportError(f"module '{use.model}' is not in the catalog {b.catalog.source}")
        out += [by_model[use.model]] * use.count
    return out


def _rows(sizes: list[tuple[float, float, float]], lx: float, ly: float) -> list[np.ndarray]:
    """Centres (part frame, z from 0 up) of boxes laid out in rows along x (at most ``lx``
    long, or the longest box) stacked along y (at most ``ly``), then in layers up z."""
    width = max([lx, *(s[0] for s in sizes)])
    depth = max([ly, *(s[1] for s in sizes)])
    layers: list[list[list[int]]] = [[[]]]
    for i, (sx, sy, _) in enumerate(sizes):
        row = layers[-1][-1]
        if row and sum(sizes[k][0] for k in row) + sx > width + 1e-12:
            rows_y = sum(max(sizes[k][1] for k in r) for r in layers[-1])
            if rows_y + sy > depth + 1e-12:
                layers.append([[]])
            else:
                layers[-1].append([])
        layers[-1][-1].append(i)
    centres: list[np.ndarray] = [np.zeros(3)] * len(sizes)
    z0 = 0.0
    for layer in layers:
        rows = [r for r in layer if r]
        total_y = sum(max(sizes[k][1] for k in r) for r in rows)
        y = -total_y / 2
        for r in rows:
            dy = max(sizes[k][1] for k in r)
            x = -sum(sizes[k][0] for k in r) / 2
            for k in r:
                sx, _, sz = sizes[k]
                centres[k] = np.array([x + sx / 2, y + dy / 2, z0 + sz / 2])
                x += sx
            y += dy
        z0 += max((sizes[k][2] for r in rows for k in r), default=0.0)
    return centres


def _trunk(b: _Builder, lp: LabelledPart, body: str) -> list[PartUse]:
    """The root body's printed plate and catalog modules (see the module docstring)."""
    modules = _trunk_modules(b)
    out: list[PartUse] = []
    plate_mass = lp.mass - sum(m.mass_kg for m in modules)
    t = b.catalog.passive.face_thickness_m
    top = 0.0
    lx, ly = lp.dims[0], lp.dims[1]
    if plate_mass > _MIN_PLATE_KG:
        area = plate_mass / (b.rho * t)
        px = float(np.sqrt(area * lx / ly))
        py = area / px
        name = f"{body}_plate"
        d = b.design(
            ("plate", name, px, py, t),
            name,
            "plate",
            lambda: meshes.plate_mesh(px, py, t),
            px * py * t,
        )
        out.append(b.printed(d, lp.placement @ transform((0.0, 0.0, -t / 2))))
        top = t / 2
        lx, ly = px, py
    else:
        b.notes.append(
            f"{body}: the catalog modules ({lp.mass - plate_mass:.3f} kg) weigh at least the "
            f"template's root part ({lp.mass:.3f} kg): no printed plate"
        )
    centres = _rows([m.size_m for m in modules], lx, ly)
    for m, c in zip(modules, centres, strict=True):
        placement = lp.placement @ transform((c[0], c[1], c[2] + top))
        out.append(_module_use(m, placement))
    return out


def _plate(b: _Builder, lp: LabelledPart, body: str) -> list[PartUse]:
    """A root part carried by another (a torso on a chassis): a printed plate of the
    template's mass, ``face_thickness_m`` thick, its footprint the part's box face scaled
    to that area (as a root body's plate; its modules are the carrier's)."""
    t = b.catalog.passive.face_thickness_m
    if lp.mass <= _MIN_PLATE_KG:
        return []
    area = lp.mass / (b.rho * t)
    lx, ly = lp.dims[0], lp.dims[1]
    px = float(np.sqrt(area * lx / ly))
    py = area / px
    name = f"{body}_plate"
    d = b.design(
        ("plate", name, px, py, t), name, "plate", lambda: meshes.plate_mesh(px, py, t), px * py * t
    )
    return [b.printed(d, lp.placement @ transform((0.0, 0.0, -t / 2)))]


def _part_uses(
    b: _Builder, lp: LabelledPart, body: str, axis: np.ndarray, models: dict, tmpl: Template
) -> list[PartUse]:
    if lp.kind == "actuator":
        return [_actuator(b, lp, body, axis, models, tmpl)]
    if lp.kind == "link":
        return [_link(b, lp, tmpl)]
    if lp.kind == "foot":
        return [_foot(b, lp)]
    if lp.kind == "wheel":
        return _wheel(b, lp)
    if lp.kind == "trunk":
        return _trunk(b, lp, body)
    if lp.kind == "plate":
        return _plate(b, lp, body)
    if lp.mass <= 0.0:
        return []
    if lp.kind == "payload":
        b.payload.append((body, PartUse("payload", "payload", lp.mass, lp.com.copy(), lp.inertia)))
        return []
    if lp.kind == "gripper":
        return [_jaw(b, lp)]
    if lp.kind == "caster":
        return [_caster(b, lp)]
    if lp.kind == "bearing":
        return [_bearing(b, lp)]
    if lp.kind == "tool":
        return [_tool(lp)]
    raise ExportError(f"body '{body}': no exporter for a part of kind '{lp.kind}'")


# --- geometry helpers -----------------------------------------------------------------------


def _geometry_points(g: Geometry, mesh_of: dict[str, np.ndarray]) -> np.ndarray:
    """Points (n, 3) in the body frame that bound ``g`` from below (exactly, for its kind)."""
    T = g.origin
    if g.kind == "mesh":
        local = mesh_of[g.mesh]
    elif g.kind == "box":
        h = np.asarray(g.size) / 2
        local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = local * h
    elif g.kind == "sphere":
        c = T[:3, 3]
        return np.array([c - [0.0, 0.0, g.size[0]]])
    elif g.kind == "cylinder":  # the lowest point of each end's circle (a wheel's contact)
        r, length = g.size
        axis = T[:3, 2]
        down = np.array([0.0, 0.0, 1.0]) - axis[2] * axis
        norm = float(np.linalg.norm(down))
        off = r * down / norm if norm > 1e-12 else np.zeros(3)
        ends = [T[:3, 3] + k * length / 2 * axis for k in (-1, 1)]
        return np.array([e - off for e in ends])
    else:
        raise ExportError(f"no bounds for geometry kind '{g.kind}'")
    return local @ T[:3, :3].T + T[:3, 3]


def _zero_pose_frames(tmpl: Template) -> list[np.ndarray]:
    frames: list[np.ndarray] = []
    for j in tmpl.model.joints:
        parent = np.eye(4) if j.parent < 0 else frames[j.parent]
        frames.append(parent @ j.origin)
    return frames


# --- the entry point ------------------------------------------------------------------------


def build_assembly(
    structure: Structure,
    catalog: Catalog,
    used: Mapping[str, tuple[float, float]] | None = None,
) -> Assembly:
    """The assembly of a sized ``structure`` with the parts of ``catalog`` (SI units).
    ``used``: joint -> (lowest, highest) rad its behaviours command, where the servo's
    travel is placed (see :func:`servo_range`).

    ExportError if the structure names an actuator or module the catalog lacks.
    """
    tmpl: Template = structure.template
    model = tmpl.model
    by_model = {a.model: a for a in catalog.actuators}
    models = {}
    for j in structure.joints:
        if j.actuator not in by_model:
            raise ExportError(f"actuator '{j.actuator}' is not in the catalog {catalog.source}")
        models[j.name] = by_model[j.actuator]
    b = _Builder(structure, catalog)
    p = tmpl.params
    faces = (catalog.passive.dovetail_face_m, catalog.passive.face_thickness_m)
    faces += (catalog.passive.fillet_radius_m,)
    if tmpl.segments and (p.face_side, p.face_thickness, p.fillet) != faces:
        b.notes.append(
            "the structure's links were weighed without the catalog's face plates and "
            "fillets; the printed links have them"
        )
    bodies: list[BodySpec] = []
    for i, body in enumerate(model.bodies):
        joint = model.joints[i]
        uses: list[PartUse] = []
        for lp in tmpl.parts[body.name]:
            uses += _part_uses(b, lp, body.name, joint.axis, models, tmpl)
        if body.name in tmpl.feet and not any(
            lp.kind == "foot" and lp.dims for lp in tmpl.parts[body.name]
        ):
            uses = _point_foot(uses, tmpl.foot_points[tmpl.feet.index(body.name)])
        mass, com, inertia = combine_parts((u.mass, u.com, u.inertia) for u in uses)
        bodies.append(BodySpec(body.name, tuple(uses), mass, com, inertia))

    joints: list[JointSpec] = []
    root = ""
    for j in model.joints:
        if j.parent < 0:
            root = model.bodies[j.child].name
            continue
        a = models.get(j.name)
        limited = j.kind == "revolute"
        lower, upper = (j.lower, j.upper) if limited else (0.0, 0.0)
        if limited and a is not None and j.movable:
            span = (used or {}).get(j.name)
            lower, upper = servo_range(lower, upper, a.travel_rad, span)
            if span is not None and (span[0] < lower - 1e-9 or span[1] > upper + 1e-9):
                b.notes.append(
                    f"joint {j.name}: the behaviours use {np.degrees(span[1] - span[0]):.0f} "
                    f"deg, more than the {a.model}'s travel ({np.degrees(a.travel_rad):.0f} deg)"
                )
        joints.append(
            JointSpec(
                j.name,
                model.bodies[j.parent].name,
                model.bodies[j.child].name,
                j.kind,
                np.array(j.origin),
                np.array(j.axis),
                lower,
                upper,
                a.stall_torque_Nm if a is not None and j.movable else 0.0,
                a.no_load_speed_rad_s if a is not None and j.movable else 0.0,
                a.model if a is not None and j.movable else "",
                j.name in tmpl.passive,
            )
        )

    passive = catalog.passive
    margin = SKIRT_MARGIN / 1000.0  # m around a part's footprint: its skirt
    printed = []
    mesh_points: dict[str, np.ndarray] = {}
    for d in sorted(b.designs.values(), key=lambda d: d.name):
        size = meshes.extents(d.mesh)
        volume = meshes.mesh_volume(d.mesh)
        fits = meshes.fits_bed(size, passive.printer_bed_m, margin)
        printer = "" if fits else _printer_for(size, catalog, margin)
        time, filament = estimate(meshes.print_features(d.mesh))
        mesh_points[f"{d.name}.stl"] = np.asarray(d.mesh.vertices, dtype=float)
        printed.append(
            PrintedPart(
                d.name,
                d.kind,
                meshes.stl_bytes(d.mesh),
                d.count,
                volume,
                float(d.analytic_volume),
                d.props[0],
                size,
                fits,
                time,
                meshes.orientation_figures(d.mesh, np.eye(3))[0],
                printer,
                filament,
            )
        )

    # zero pose: the lowest point of what touches the ground sits on z = 0
    frames = _zero_pose_frames(tmpl)
    contact = set(tmpl.feet) | set(tmpl.wheels) | set(tmpl.casters)
    lowest = np.inf
    for i, spec in enumerate(bodies):
        if contact and spec.name not in contact:
            continue
        for g in spec.visuals:
            pts = _geometry_points(g, mesh_points)
            world = pts @ frames[i][:3, :3].T + frames[i][:3, 3]
            lowest = min(lowest, float(world[:, 2].min()))
    spawn = -lowest if np.isfinite(lowest) else 0.0

    total = sum(s.mass for s in bodies) + sum(u.mass for _, u in b.payload)
    if structure.mass_kg > 0 and abs(total - structure.mass_kg) > 0.01 * structure.mass_kg:
        b.notes.append(
            f"the assembly weighs {total:.3f} kg, the structure {structure.mass_kg:.3f} kg"
        )
    fixed = bool(tmpl.end_effectors) and tmpl.legs == 0 and not tmpl.wheels
    return Assembly(
        robot_type=structure.robot_type,
        root=root,
        bodies=tuple(bodies),
        joints=tuple(joints),
        printed=tuple(printed),
        feet=tuple(tmpl.feet),
        wheels=tuple(tmpl.wheels),
        casters=tuple(tmpl.casters),
        spawn_height=float(spawn),
        fixed_base=fixed,
        notes=tuple(b.notes),
        payload=tuple(b.payload),
    )


def _printer_for(size: tuple[float, float, float], catalog: Catalog, margin: float) -> str:
    """The first of the catalog's larger printers that fits a part of ``size`` m as it is
    printed (with ``margin`` m of skirt), or "split" when none does."""
    for p in catalog.printers:
        if meshes.fits_bed(size, p.bed_m, margin):
            return p.model
    return "split"


def servo_range(
    lower: float, upper: float, travel: float, used: tuple[float, float] | None = None
) -> tuple[float, float]:
    """The part of the joint range [lower, upper] rad a servo of ``travel`` rad end to end
    can turn (the servo is mounted with the middle of its travel at the window's middle):
    the whole range when it fits; else a window of ``travel`` centred on the ``used`` span
    (the behaviours' lowest and highest command, rad) or, without one, on the range's
    middle, moved inside the range."""
    if upper - lower <= travel:
        return lower, upper
    mid = 0.5 * (lower + upper) if used is None else 0.5 * (used[0] + used[1])
    mid = min(max(mid, lower + travel / 2), upper - travel / 2)
    return mid - travel / 2, mid + travel / 2


def with_payload(asm: Assembly) -> Assembly:
    """``asm`` with its payload (``Assembly.payload``) added to the bodies that hold it: the
    model a simulation of the loaded robot needs. Unchanged when there is none."""
    extra: dict[str, list[PartUse]] = {}
    for body, use in asm.payload:
        if use.mass > 0:
            extra.setdefault(body, []).append(use)
    if not extra:
        return asm
    bodies = []
    for spec in asm.bodies:
        if spec.name not in extra:
            bodies.append(spec)
            continue
        parts = (*spec.parts, *extra[spec.name])
        mass, com, inertia = combine_parts((u.mass, u.com, u.inertia) for u in parts)
        bodies.append(BodySpec(spec.name, parts, mass, com, inertia))
    return replace(asm, bodies=tuple(bodies), payload=())
