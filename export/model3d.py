"""The physical assembly of a sized design: what the exporters (URDF, MJCF, STL, BOM) share.

An :class:`Assembly` is the design's kinematic tree with, on every body, the parts that
make it up: printed parts (meshes, placed in the body frame) and catalog modules (boxes
of the catalog's size and mass). Mass properties of each body are the sum of its parts:
printed parts from their meshes and the material density, modules from the catalog.
SI units; transforms are 4x4 homogeneous matrices (parent frame -> child frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Geometry:
    """A visual/collision shape in a body frame.

    ``kind``: "mesh" (``mesh`` is the file name under ``meshes/``, vertices in metres),
    "box" (``size`` = full extents x, y, z), "cylinder" (``size`` = radius, length; axis
    along the local z) or "sphere" (``size`` = radius,).
    """

    kind: str
    origin: np.ndarray  # (4, 4) body frame -> shape frame
    size: tuple[float, ...] = ()
    mesh: str | None = None
    rgba: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)
    name: str = ""
    contact: bool = True  # False: seen, but never touches the ground in simulation


@dataclass(frozen=True)
class PartUse:
    """One physical part on a body: a printed part or a catalog module."""

    name: str  # printed: the part design's name (its STL stem); module: the catalog model
    # "printed" | "module" (catalog active module) | "bought" (catalog part, tyre) |
    # "payload" | "contact" (massless contact shape)
    source: str
    mass: float  # kg
    com: np.ndarray  # (3,) in the body frame
    inertia: np.ndarray  # (3, 3) about com, body axes
    geometry: Geometry | None = None
    kind: str = ""  # modules and bought parts: the catalog class (or "Tyre")
    cost: float = 0.0  # modules and bought parts: unit cost, catalog currency


@dataclass(frozen=True)
class BodySpec:
    name: str
    parts: tuple[PartUse, ...]
    mass: float
    com: np.ndarray  # (3,)
    inertia: np.ndarray  # (3, 3) about com, body axes

    @property
    def visuals(self) -> tuple[Geometry, ...]:
        return tuple(p.geometry for p in self.parts if p.geometry is not None)


@dataclass(frozen=True)
class JointSpec:
    name: str
    parent: str  # body name
    child: str  # body name
    kind: str  # "revolute" | "continuous" | "fixed"
    origin: np.ndarray  # (4, 4) parent body frame -> joint/child frame at q = 0
    axis: np.ndarray  # (3,)
    lower: float = 0.0
    upper: float = 0.0
    effort: float = 0.0  # N m: the actuator's stall torque
    velocity: float = 0.0  # rad/s: the actuator's no-load speed
    actuator: str = ""  # catalog model
    passive: bool = False  # turns freely on a bearing (a free wheel): no actuator


@dataclass(frozen=True)
class PrintPiece:
    """What is printed of a part too big for the user's bed (``export.split``): one piece
    of it, or the whole part turned to fit; its STL lies on that bed as it prints."""

    name: str  # safe file stem: <part>_piece<k>, or the part's own name when turned whole
    stl: bytes
    volume_m3: float
    mass_kg: float
    extents_m: tuple[float, float, float]
    print_time_s: float
    filament_m3: float
    overhang_m2: float
    in_part: bytes = b""  # a piece's STL where it sits in the part (its meshes/ STL's frame)


@dataclass(frozen=True)
class PieceJoint:
    """Where two pieces of a split part join: a dovetail across the part's print-frame
    ``axis`` ("x", "y" or "z") at ``at_m`` (m, in the part's STL), its tongue on ``low``
    (sliding into ``high`` along ``slide``) with ``clearance_m`` on every side."""

    low: str
    high: str
    axis: str
    at_m: float
    slide: str
    clearance_m: float
    kind: str = "dovetail"
    fasteners: str = ""  # none for a dovetail


@dataclass(frozen=True)
class PrintedPart:
    """A printed part design: its mesh (binary STL) and what the BOM needs."""

    name: str  # safe file stem: [a-z0-9_]+
    kind: str  # "link" | "foot" | "wheel" | "plate" | "bracket" | "finger"
    stl: bytes
    count: int
    volume_m3: float  # of the mesh
    analytic_volume_m3: float  # of the part's analytic model (optimiser + faces/fillets)
    mass_kg: float
    extents_m: tuple[float, float, float]  # bounding box of the part as printed
    fits_bed: bool
    print_time_s: float  # estimated for the bundle's slicer settings (export.slicer)
    overhang_m2: float = 0.0  # area printed over nothing (needs support) as oriented
    printer: str = ""  # "": the catalog's printer_bed; else the larger printer that fits it
    filament_m3: float = 0.0  # estimated filament, supports included (0: not estimated)
    #: on a user's bed (``--bed``): what is printed in its place when it does not fit as it
    #: lies (``export.split``): the part turned (one piece of its own name) or its pieces
    pieces: tuple[PrintPiece, ...] = ()
    joints: tuple[PieceJoint, ...] = ()


@dataclass(frozen=True)
class Assembly:
    robot_type: str
    root: str  # the root body (base, trunk, chassis)
    bodies: tuple[BodySpec, ...]
    joints: tuple[JointSpec, ...]  # topological order, parents first
    printed: tuple[PrintedPart, ...]
    feet: tuple[str, ...] = ()  # bodies that touch the ground with a foot
    wheels: tuple[str, ...] = ()
    casters: tuple[str, ...] = ()
    spawn_height: float = 0.0  # m: root height so the robot stands on z = 0
    fixed_base: bool = True  # manipulators are bolted down; mobile robots float
    notes: tuple[str, ...] = field(default=())
    #: the payload, not in the bodies: (body name, its point mass) (``with_payload``)
    payload: tuple[tuple[str, PartUse], ...] = field(default=())

    @property
    def total_mass(self) -> float:
        """kg of the bodies (the payload included only once added to them)."""
        return float(sum(b.mass for b in self.bodies))

    @property
    def payload_mass(self) -> float:
        """kg of the payload kept aside (0 once ``with_payload`` added it)."""
        return float(sum(u.mass for _, u in self.payload))

    def body(self, name: str) -> BodySpec:
        return next(b for b in self.bodies if b.name == name)
