"""The ParMoR module catalog: actuators, active modules, passive templates, material, rules.

The catalog is a TOML file (the shipped one is ``adron/catalog.toml``; a user passes their
own with ``--catalog``). :func:`load_catalog` validates it and returns frozen dataclasses
of SI floats; every problem is an InputError that names the file and the key path, e.g.
``my.toml: actuator[2] (MG996R): missing key 'stall_torque'``. Entry numbers count the
``[[actuator]]`` / ``[[module]]`` tables from 1, in file order.

:func:`catalog_facts` writes the actuators and modules as integer ASP facts for clingo.

Module mass, size and cost describe the whole module as it goes into a robot: the part,
its ATtiny85 board and its printed housing with dovetail faces (see catalog.toml).
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Collection, Iterable
from dataclasses import dataclass, replace
from decimal import ROUND_HALF_UP, Decimal
from importlib.resources import files
from pathlib import Path
from typing import Any

from adron import readers
from adron.errors import InputError
from adron.translate import asp_string
from adron.units import quantity

__all__ = [
    "BATTERY_CLASS",
    "MAIN_CLASS",
    "TORQUE_CLASSES",
    "SHIPPED",
    "Actuator",
    "Bus",
    "Catalog",
    "DesignRules",
    "Material",
    "Module",
    "Part",
    "Passive",
    "Printer",
    "Tyre",
    "catalog_facts",
    "load_catalog",
    "parse_catalog",
    "recorded_catalog",
    "shipped_catalogs",
]

TORQUE_CLASSES = ("low", "medium", "high")
BATTERY_CLASS = "BatteryModule"
MAIN_CLASS = "MainModule"

Size = tuple[float, float, float]


@dataclass(frozen=True)
class Actuator:
    """A servo actuator module. SI: kg, m, N*m, rad/s, A; cost in the catalog currency."""

    model: str
    ontology_class: str
    torque_class: str
    mass_kg: float
    size_m: Size
    stall_torque_Nm: float
    no_load_speed_rad_s: float
    stall_current_A: float
    cost: float
    #: rad: how far the output shaft turns end to end (2 pi: continuous rotation)
    travel_rad: float = 2 * math.pi

    @property
    def continuous(self) -> bool:
        """True when the servo turns without an end stop."""
        return self.travel_rad >= 2 * math.pi - 1e-9


@dataclass(frozen=True)
class Part:
    """A passive part that is not a printed link: a gripper's jaw (printed), a caster
    (bought). ``source``: "printed" (its mass is ``size_m``'s box times the material's
    density) or "bought" (the catalog's mass). SI: kg, m; cost in the catalog currency."""

    model: str
    ontology_class: str
    source: str
    mass_kg: float
    size_m: Size
    cost: float


@dataclass(frozen=True)
class Printer:
    """A printer larger than ``[passive] printer_bed`` (its build volume x, y, z in m)."""

    model: str
    bed_m: Size


@dataclass(frozen=True)
class Tyre:
    """The rubber tyre of a printed wheel (m, kg/m^3, currency per metre of band)."""

    name: str
    thickness_m: float
    density_kg_m3: float
    cost_per_m: float

    def mass_kg(self, radius: float, width: float) -> float:
        """kg of the tyre ring of a wheel of outer ``radius`` m and ``width`` m."""
        inner = radius - self.thickness_m
        return math.pi * (radius**2 - inner**2) * width * self.density_kg_m3

    def cost(self, radius: float) -> float:
        """Cost of the band for a wheel of outer ``radius`` m (the rim's circumference)."""
        return 2 * math.pi * (radius - self.thickness_m) * self.cost_per_m


@dataclass(frozen=True)
class Module:
    """A non-actuator active module (main board, battery, sensor). SI: kg, m, A, V.

    ``current_A`` is the module's typical draw from the 5 V rail. Battery modules also
    have ``capacity_Ah`` (ampere-hours), ``voltage_V`` (nominal) and ``max_current_A``
    (continuous: C-rating x capacity); these are None for other modules.
    """

    model: str
    ontology_class: str
    mass_kg: float
    size_m: Size
    cost: float
    current_A: float
    capacity_Ah: float | None = None
    voltage_V: float | None = None
    max_current_A: float | None = None


@dataclass(frozen=True)
class Passive:
    """Templates of the printed passive modules (m, dimensionless, m^3/s)."""

    dovetail_face_m: float
    face_thickness_m: float
    min_wall_m: float
    max_outer_radius_m: float
    fillet_radius_m: float
    stress_concentration: float
    min_link_length_m: float
    max_link_length_m: float
    wheel_min_radius_m: float
    wheel_max_radius_m: float
    wheel_width_m: float
    foot_min_side_m: float
    foot_max_side_m: float
    foot_thickness_m: float
    printer_bed_m: Size
    #: m^3/s: an older catalog's average extrusion rate (optional, unused: the BOM's print
    #: time is an estimate calibrated against PrusaSlicer, ``export.slicer``); 0 when absent
    print_speed_m3_s: float = 0.0
    #: m left on every side between a printed dovetail pin and its rail
    print_clearance_m: float = 0.0


@dataclass(frozen=True)
class Material:
    """The printing material (Pa, Pa, kg/m^3)."""

    name: str
    youngs_modulus_Pa: float
    yield_strength_Pa: float
    density_kg_m3: float


@dataclass(frozen=True)
class Bus:
    """The bus the active modules share: its name ("I2C"), protocol, the addresses (IDs)
    it hands out, from ``first_address`` to ``last_address``, and how many active modules
    it carries at most, the bus master (the main module, which needs no address) included.

    ``module_limit`` is the smaller of ``device_limit`` (an electrical limit, e.g. the
    paper's I2C capacitance limit of 24) and what the addresses allow (one each, plus the
    master). ``address_format`` "hex" writes addresses as 0x09, "decimal" as 9.
    """

    name: str
    protocol: str
    first_address: int
    last_address: int
    device_limit: int | None = None
    address_word: str = "address"  # what the bus calls an address ("address", "ID")
    address_format: str = "hex"

    @property
    def module_limit(self) -> int:
        """Active modules the bus carries at most, the master included."""
        by_address = self.last_address - self.first_address + 2
        return by_address if self.device_limit is None else min(self.device_limit, by_address)

    def address_text(self, address: int) -> str:
        """``address`` as the bus's documents write it: 0x09 (hex) or 9 (decimal)."""
        return f"0x{address:02x}" if self.address_format == "hex" else str(address)


#: The bus of a catalog without a [bus] table: the paper's I2C bus (7-bit addresses,
#: 0x00-0x07 and 0x78-0x7F reserved), at most 24 active modules: the paper's measured limit
#: of the bus capacitance (400 pF), as ADROn's activeModuleLimit states it.
I2C_DEFAULT = Bus("I2C", "I2C, 7-bit addresses", 0x08, 0x77, 24)


@dataclass(frozen=True)
class DesignRules:
    """Defaults of the structure generator (dimensionless, m, rad/s^2, m/s^2, rad)."""

    torque_safety_factor: float
    stress_safety_factor: float
    max_tip_deflection_m: float
    max_joint_acceleration_rad_s2: float
    gravity_m_s2: float
    max_slope_rad: float
    rolling_resistance: float
    # torque safety factor on the behaviours' own inverse dynamics (optional key; default:
    # torque_safety_factor)
    behaviour_torque_factor: float = 0.0

    @property
    def behaviour_scale(self) -> float:
        """Factor on a behaviour's peak torque that makes it comparable with usable torque
        (stall / torque_safety_factor)."""
        f = self.behaviour_torque_factor or self.torque_safety_factor
        return f / self.torque_safety_factor


@dataclass(frozen=True)
class Catalog:
    """A validated catalog. ``source`` is the file it came from (for messages)."""

    name: str
    currency: str
    version: str
    actuators: tuple[Actuator, ...]
    modules: tuple[Module, ...]
    passive: Passive
    material: Material
    design: DesignRules
    source: str
    parts: tuple[Part, ...] = ()
    tyre: Tyre | None = None
    printers: tuple[Printer, ...] = ()
    bus: Bus = I2C_DEFAULT
    #: sha256 of the catalog's text and of the texts it extends (hex): which catalog a
    #: design used, whatever the file is called
    sha256: str = ""
    #: the shipped catalog's name ("default", "dynamixel"), or "" for a user's file
    shipped: str = ""
    #: the catalog's [perturbation] table as JSON text ("" when it has none): overrides of
    #: synth/verification/perturb.toml's ranges, read and checked by synth.verification.perturb
    perturbation: str = ""

    def printer_bed(self, printer: str) -> Size | None:
        """The build volume (x, y, z) m of ``printer``: "" is the catalog's own printer
        (``passive.printer_bed_m``), else one of ``printers`` by model; None for another
        name (e.g. "split": none holds the part)."""
        if printer == "":
            return self.passive.printer_bed_m
        return next((p.bed_m for p in self.printers if p.model == printer), None)

    def part_of(self, ontology_class: str) -> Part:
        """The first passive part of ``ontology_class``; InputError naming the file if none."""
        for p in self.parts:
            if p.ontology_class == ontology_class:
                return p
        raise InputError(f"{self.source}: no [[part]] of class '{ontology_class}'")

    def wheel_mass_kg(self, radius: float, bore: float, width: float | None = None) -> float:
        """kg of a wheel of outer ``radius`` m: the printed rim (``width`` m, default the
        catalog's wheel width, a hub bore of ``bore`` m, the tyre's thickness less than
        the radius) and its tyre."""
        w = self.passive.wheel_width_m if width is None else width
        t = self.tyre.thickness_m if self.tyre is not None else 0.0
        rim = math.pi * ((radius - t) ** 2 - bore**2) * w * self.material.density_kg_m3
        return rim + (self.tyre.mass_kg(radius, w) if self.tyre is not None else 0.0)

    def actuators_of(self, ontology_class: str) -> tuple[Actuator, ...]:
        """The actuators whose class is exactly ``ontology_class``, in file order.

        (Subclass reasoning is the ontology's job: the ASP encodings match with isa/2.)
        """
        return tuple(a for a in self.actuators if a.ontology_class == ontology_class)

    def modules_of(self, ontology_class: str) -> tuple[Module, ...]:
        """The modules whose class is exactly ``ontology_class``, in file order."""
        return tuple(m for m in self.modules if m.ontology_class == ontology_class)

    def module_of(self, ontology_class: str) -> Module:
        """The first module of ``ontology_class``; InputError naming the file if none."""
        found = self.modules_of(ontology_class)
        if not found:
            raise InputError(f"{self.source}: no [[module]] of class '{ontology_class}'")
        return found[0]

    @property
    def battery(self) -> Module:
        """The battery module (the first of class BatteryModule)."""
        return self.module_of(BATTERY_CLASS)

    @property
    def main_module(self) -> Module:
        """The main module (the first of class MainModule)."""
        return self.module_of(MAIN_CLASS)

    def check_classes(self, known: Collection[str]) -> None:
        """InputError if an entry names an ontology class not in ``known``.

        The catalog cannot see the ontology (adron.catalog imports no knowledge base);
        the caller passes the class names of the loaded ontology.
        """
        entries = [
            (f"actuator[{i}] ({a.model})", a.ontology_class)
            for i, a in enumerate(self.actuators, 1)
        ]
        entries += [
            (f"module[{i}] ({m.model})", m.ontology_class) for i, m in enumerate(self.modules, 1)
        ]
        entries += [
            (f"part[{i}] ({p.model})", p.ontology_class) for i, p in enumerate(self.parts, 1)
        ]
        for path, cls in entries:
            if cls not in known:
                raise InputError(
                    f"{self.source}: {path}.class: '{cls}' is not a class of the ontology"
                    + _suggest(cls, known)
                )


# ---- Loading -----------------------------------------------------------------------------

_ACTUATOR_KEYS = (
    "model",
    "class",
    "torque_class",
    "mass",
    "size",
    "stall_torque",
    "no_load_speed",
    "stall_current",
    "cost",
    "travel_deg",
)
_MODULE_KEYS = ("model", "class", "mass", "size", "cost", "current")
_BATTERY_KEYS = ("capacity", "voltage", "c_rating")
_PASSIVE_LENGTHS = (
    "dovetail_face",
    "face_thickness",
    "min_wall",
    "max_outer_radius",
    "fillet_radius",
    "min_link_length",
    "max_link_length",
    "wheel_min_radius",
    "wheel_max_radius",
    "wheel_width",
    "foot_min_side",
    "foot_max_side",
    "foot_thickness",
    "print_clearance",
)
_PASSIVE_KEYS = (*_PASSIVE_LENGTHS, "stress_concentration", "printer_bed")
_MATERIAL_KEYS = ("name", "youngs_modulus", "yield_strength", "density")
_DESIGN_KEYS = (
    "torque_safety_factor",
    "stress_safety_factor",
    "max_tip_deflection",
    "max_joint_acceleration",
    "gravity",
    "max_slope",
    "rolling_resistance",
)
_PART_KEYS = ("model", "class", "source", "size", "cost")
_PART_SOURCES = ("printed", "bought")
_TYRE_KEYS = ("name", "thickness", "density", "cost_per_m")
_TOP_KEYS = (
    "catalog",
    "actuator",
    "module",
    "part",
    "tyre",
    "printer",
    "passive",
    "material",
    "design",
    "bus",
    "perturbation",
)
_BUS_KEYS = ("name", "protocol", "first_address", "last_address")
_BUS_OPTIONAL = ("device_limit", "address_word", "address_format")
_ADDRESS_FORMATS = ("hex", "decimal")
#: Largest address (ID) a bus may name; any real bus is far below.
MAX_ADDRESS = 65535
#: Tables merged key by key and arrays of tables merged by model when a catalog extends
#: another (see :func:`parse_catalog`).
_MERGED_TABLES = ("passive", "material", "design", "tyre")  # [bus] is replaced whole
_MERGED_ARRAYS = ("actuator", "module", "part", "printer")
#: Longest chain of catalogs extending one another.
MAX_EXTENDS = 8
_CLASS_NAME = re.compile(r"[A-Z][A-Za-z0-9]*")
_CURRENCY = re.compile(r"[A-Z]{3}")

#: Largest catalog quantity of each dimension parmor accepts, with its unit. Beyond them no
#: module of a modular robot makes sense, and the ASP facts (integers: milligrams, cents,
#: mN*m, mrad/s, mA; clingo's are 32-bit) of a few tens of modules would overflow.
CATALOG_MAX: dict[str, str] = {
    "mass": "50 kg",
    "length": "10 m",
    "torque": "1000 N*m",
    "angular_speed": "1000 rad/s",
    "current": "1000 A",
    "voltage": "1000 V",
    "charge": "1000 Ah",
}
#: Largest cost of one module, in the catalog's currency (cents must fit clingo's integers).
MAX_COST = 100_000.0


def _suggest(word: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, str):
        return f"the string '{value}'"
    return f"the number {value}"


class _Table:
    """One TOML table being read: its data, its key path, and typed getters."""

    def __init__(self, data: dict[str, Any], path: str, file: str) -> None:
        self.data, self.path, self.file = data, path, file

    def fail(self, message: str, key: str | None = None) -> InputError:
        where = self.path if key is None else f"{self.path}.{key}"
        return InputError(f"{self.file}: {where}: {message}")

    def where(self, key: str) -> str:
        return f"{self.file}: {self.path}.{key}"

    def check_keys(self, required: Iterable[str], optional: Iterable[str] = ()) -> None:
        required = tuple(required)
        allowed = (*required, *optional)
        for key in self.data:
            if key not in allowed:
                raise self.fail(f"unknown key '{key}'{_suggest(key, allowed)}")
        for key in required:
            if key not in self.data:
                raise self.fail(f"missing key '{key}'")

    def text(self, key: str) -> str:
        value = self.data[key]
        if not isinstance(value, str) or not value.strip():
            raise self.fail(f"expected a non-empty string, got {_kind(value)}", key)
        bad = next((c for c in value if not c.isprintable()), None)
        if bad is not None:
            # A newline or NUL in a name breaks the ASP facts, the BOM's CSV and the URDF.
            raise self.fail(
                f"{value!r} contains the control character U+{ord(bad):04X}; expected one line "
                "of printable text",
                key,
            )
        return value

    def class_name(self, key: str = "class") -> str:
        value = self.text(key)
        if not _CLASS_NAME.fullmatch(value):
            raise self.fail(f"'{value}' is not an ontology class name (like 'MainModule')", key)
        return value

    def q(self, key: str, dimension: str, **flags: bool) -> float:
        value = quantity(self.data[key], dimension, self.where(key), **flags)
        if dimension in CATALOG_MAX:
            top = CATALOG_MAX[dimension]
            if value > quantity(top, dimension, "CATALOG_MAX"):
                raise self.fail(f"'{self.data[key]}' is above {top}, the largest accepted", key)
        return value

    def number(
        self,
        key: str,
        *,
        minimum: float = 0.0,
        allow_equal: bool = True,
        maximum: float = math.inf,
    ) -> float:
        value = self.data[key]
        if isinstance(value, str):
            value = quantity(value, "dimensionless", self.where(key), allow_negative=True)
        elif isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"expected a number, got {_kind(value)}", key)
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(f"expected a finite number, got {value}", key)
        if value < minimum or (value == minimum and not allow_equal):
            bound = "at least" if allow_equal else "greater than"
            raise self.fail(f"must be {bound} {minimum:g}, got {value:g}", key)
        if value > maximum:
            raise self.fail(f"must be at most {maximum:g}, got {value:g}", key)
        return value

    def integer(self, key: str, low: int, high: int) -> int:
        value = self.data[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"expected an integer, got {_kind(value)}", key)
        if not low <= value <= high:
            raise self.fail(f"must be between {low} and {high}, got {value}", key)
        return value

    def lengths(self, key: str) -> Size:
        value = self.data[key]
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(
                f"expected an array of 3 lengths such as ['50 mm', '50 mm', '40 mm'], "
                f"got {_kind(value)}" + (f" of {len(value)}" if isinstance(value, list) else ""),
                key,
            )
        x, y, z = (quantity(v, "length", f"{self.where(key)}[{i}]") for i, v in enumerate(value, 1))
        if max(x, y, z) > quantity(CATALOG_MAX["length"], "length", "CATALOG_MAX"):
            raise self.fail(f"a side is above {CATALOG_MAX['length']}, the largest accepted", key)
        return (x, y, z)


def _section(doc: dict[str, Any], key: str, file: str) -> _Table:
    if key not in doc:
        raise InputError(f"{file}: missing table [{key}]")
    value = doc[key]
    if not isinstance(value, dict):
        raise InputError(f"{file}: {key}: expected a table [{key}], got {_kind(value)}")
    return _Table(value, key, file)


def _entries(doc: dict[str, Any], key: str, file: str, required: bool = True) -> list[_Table]:
    value = doc.get(key)
    if not required and value is None:
        return []
    if value is None or value == []:
        raise InputError(f"{file}: no [[{key}]] entries; the catalog needs at least one")
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise InputError(f"{file}: {key}: expected an array of tables [[{key}]]")
    tables = []
    for i, data in enumerate(value, 1):
        model = data.get("model")
        named = isinstance(model, str) and model and model.isprintable()
        label = f"{key}[{i}] ({model})" if named else f"{key}[{i}]"
        tables.append(_Table(data, label, file))
    return tables


def _actuator(t: _Table) -> Actuator:
    t.check_keys(_ACTUATOR_KEYS)
    torque_class = t.text("torque_class")
    if torque_class not in TORQUE_CLASSES:
        raise t.fail(
            f"'{torque_class}' is not one of {', '.join(TORQUE_CLASSES)}"
            + _suggest(torque_class, TORQUE_CLASSES),
            "torque_class",
        )
    return Actuator(
        model=t.text("model"),
        ontology_class=t.class_name(),
        torque_class=torque_class,
        mass_kg=t.q("mass", "mass"),
        size_m=t.lengths("size"),
        stall_torque_Nm=t.q("stall_torque", "torque"),
        no_load_speed_rad_s=t.q("no_load_speed", "angular_speed"),
        stall_current_A=t.q("stall_current", "current"),
        cost=t.number("cost", maximum=MAX_COST),
        travel_rad=math.radians(_travel(t)),
    )


def _travel(t: _Table) -> float:
    """Degrees the servo turns end to end: more than 0, at most 360 (continuous)."""
    deg = t.number("travel_deg", allow_equal=False)
    if deg > 360:
        raise t.fail(f"must be at most 360 (continuous rotation), got {deg:g}", "travel_deg")
    return deg


def _part(t: _Table, density: float) -> Part:
    source = t.data.get("source")
    if source not in _PART_SOURCES:
        t.check_keys(_PART_KEYS, ("mass",))
        raise t.fail(f"expected one of {', '.join(_PART_SOURCES)}, got {_kind(source)}", "source")
    t.check_keys((*_PART_KEYS, "mass") if source == "bought" else _PART_KEYS)
    size = t.lengths("size")
    # printed solid: the box's volume times the material's density
    mass = size[0] * size[1] * size[2] * density if source == "printed" else t.q("mass", "mass")
    return Part(
        model=t.text("model"),
        ontology_class=t.class_name(),
        source=source,
        mass_kg=mass,
        size_m=size,
        cost=t.number("cost", maximum=MAX_COST),
    )


def _tyre(t: _Table) -> Tyre:
    t.check_keys(_TYRE_KEYS)
    return Tyre(
        name=t.text("name"),
        thickness_m=t.q("thickness", "length"),
        density_kg_m3=t.q("density", "density"),
        cost_per_m=t.number("cost_per_m"),
    )


def _module(t: _Table) -> Module:
    cls = t.data.get("class")
    battery = cls == BATTERY_CLASS
    if battery:
        t.check_keys((*_MODULE_KEYS, *_BATTERY_KEYS))
    else:
        for key in _BATTERY_KEYS:
            if key in t.data:
                raise t.fail(f"'{key}' is only for modules of class '{BATTERY_CLASS}'", key)
        t.check_keys(_MODULE_KEYS)
    capacity = voltage = max_current = None
    if battery:
        capacity = t.q("capacity", "charge") / 3600.0  # C -> Ah
        voltage = t.q("voltage", "voltage")
        max_current = t.number("c_rating", allow_equal=False) * capacity  # (1/h) * Ah = A
    return Module(
        model=t.text("model"),
        ontology_class=t.class_name(),
        mass_kg=t.q("mass", "mass"),
        size_m=t.lengths("size"),
        cost=t.number("cost", maximum=MAX_COST),
        current_A=t.q("current", "current", allow_zero=True),
        capacity_Ah=capacity,
        voltage_V=voltage,
        max_current_A=max_current,
    )


def _passive(t: _Table) -> Passive:
    t.check_keys(_PASSIVE_KEYS, ("print_speed",))
    v = {key: t.q(key, "length") for key in _PASSIVE_LENGTHS}
    bed = t.lengths("printer_bed")
    p = Passive(
        dovetail_face_m=v["dovetail_face"],
        face_thickness_m=v["face_thickness"],
        min_wall_m=v["min_wall"],
        max_outer_radius_m=v["max_outer_radius"],
        fillet_radius_m=v["fillet_radius"],
        stress_concentration=t.number("stress_concentration", minimum=1.0),
        min_link_length_m=v["min_link_length"],
        max_link_length_m=v["max_link_length"],
        wheel_min_radius_m=v["wheel_min_radius"],
        wheel_max_radius_m=v["wheel_max_radius"],
        wheel_width_m=v["wheel_width"],
        foot_min_side_m=v["foot_min_side"],
        foot_max_side_m=v["foot_max_side"],
        foot_thickness_m=v["foot_thickness"],
        printer_bed_m=bed,
        print_speed_m3_s=t.q("print_speed", "volume_flow") if "print_speed" in t.data else 0.0,
        print_clearance_m=v["print_clearance"],
    )

    def mm(x: float) -> str:
        return f"{x * 1e3:g} mm"

    if p.min_wall_m >= p.max_outer_radius_m:
        raise t.fail(
            f"min_wall {mm(p.min_wall_m)} leaves no hole in a tube of outer radius "
            f"{mm(p.max_outer_radius_m)}",
            "min_wall",
        )
    if 2 * (p.max_outer_radius_m + p.fillet_radius_m) > p.dovetail_face_m:
        raise t.fail(
            f"a tube of radius {mm(p.max_outer_radius_m)} with its "
            f"{mm(p.fillet_radius_m)} fillet does not fit the {mm(p.dovetail_face_m)} "
            "dovetail face",
            "max_outer_radius",
        )
    for low, high in (
        ("min_link_length", "max_link_length"),
        ("wheel_min_radius", "wheel_max_radius"),
        ("foot_min_side", "foot_max_side"),
    ):
        if v[low] > v[high]:
            raise t.fail(f"{mm(v[low])} is more than {high} = {mm(v[high])}", low)
    if p.max_link_length_m > max(bed):
        raise t.fail(
            f"{mm(p.max_link_length_m)} does not fit the printer bed "
            f"({' x '.join(mm(b) for b in bed)})",
            "max_link_length",
        )
    flat = min(bed[0], bed[1])
    if 2 * p.wheel_max_radius_m > flat:
        raise t.fail(
            f"a wheel of radius {mm(p.wheel_max_radius_m)} does not fit the printer bed",
            "wheel_max_radius",
        )
    if p.foot_max_side_m > flat:
        raise t.fail(f"{mm(p.foot_max_side_m)} does not fit the printer bed", "foot_max_side")
    return p


def _material(t: _Table) -> Material:
    t.check_keys(_MATERIAL_KEYS)
    return Material(
        name=t.text("name"),
        youngs_modulus_Pa=t.q("youngs_modulus", "pressure"),
        yield_strength_Pa=t.q("yield_strength", "pressure"),
        density_kg_m3=t.q("density", "density"),
    )


def _bus(t: _Table) -> Bus:
    t.check_keys(_BUS_KEYS, _BUS_OPTIONAL)
    first = t.integer("first_address", 0, MAX_ADDRESS)
    last = t.integer("last_address", first, MAX_ADDRESS)
    limit = t.integer("device_limit", 2, MAX_ADDRESS + 2) if "device_limit" in t.data else None
    fmt = t.text("address_format") if "address_format" in t.data else "hex"
    if fmt not in _ADDRESS_FORMATS:
        raise t.fail(f"'{fmt}' is not one of {', '.join(_ADDRESS_FORMATS)}", "address_format")
    return Bus(
        name=t.text("name"),
        protocol=t.text("protocol"),
        first_address=first,
        last_address=last,
        device_limit=limit,
        address_word=t.text("address_word") if "address_word" in t.data else "address",
        address_format=fmt,
    )


def _legacy_bus(t: _Table) -> Bus:
    """The bus of a catalog without [bus]: I2C, from [design] i2c_first_address if given
    (catalogs before [bus] existed)."""
    if "i2c_first_address" not in t.data:
        return I2C_DEFAULT
    # 7-bit I2C: 0x00-0x07 and 0x78-0x7F are reserved.
    first = t.integer("i2c_first_address", 0x08, 0x77)
    return replace(I2C_DEFAULT, first_address=first)


def _design(t: _Table) -> DesignRules:
    t.check_keys(_DESIGN_KEYS, ("behaviour_torque_factor", "i2c_first_address"))
    slope = t.q("max_slope", "angle", allow_zero=True)
    if slope >= math.pi / 2:
        raise t.fail(f"'{t.data['max_slope']}' is not less than 90 deg", "max_slope")
    rolling = t.number("rolling_resistance")
    if rolling >= 1:
        raise t.fail(f"must be less than 1, got {rolling:g}", "rolling_resistance")
    return DesignRules(
        torque_safety_factor=t.number("torque_safety_factor", minimum=1.0),
        stress_safety_factor=t.number("stress_safety_factor", minimum=1.0),
        max_tip_deflection_m=t.q("max_tip_deflection", "length"),
        max_joint_acceleration_rad_s2=t.q("max_joint_acceleration", "angular_acceleration"),
        gravity_m_s2=t.q("gravity", "acceleration"),
        max_slope_rad=slope,
        rolling_resistance=rolling,
        behaviour_torque_factor=(
            t.number("behaviour_torque_factor", minimum=1.0)
            if "behaviour_torque_factor" in t.data
            else 0.0
        ),
    )


def _header(t: _Table) -> tuple[str, str, str]:
    t.check_keys(("name", "currency", "version"), ("extends", "replace", "remove"))
    currency = t.text("currency")
    if not _CURRENCY.fullmatch(currency):
        raise t.fail(f"'{currency}' is not a currency code such as 'EUR'", "currency")
    version = t.data["version"]
    if isinstance(version, int) and not isinstance(version, bool):
        version = str(version)
    else:
        version = t.text("version")
    return t.text("name"), currency, version


#: The catalogs shipped with parmor, by the name ``--catalog NAME`` takes: file names
#: inside the ``adron`` package.
SHIPPED: dict[str, str] = {
    "default": "catalog.toml",
    "dynamixel": "catalogs/dynamixel.toml",
}


def shipped_catalogs() -> tuple[str, ...]:
    """The names of the shipped catalogs (``--catalog NAME``)."""
    return tuple(SHIPPED)


def _shipped_text(name: str) -> tuple[str, str]:
    """(text, source) of the shipped catalog ``name``."""
    resource = files("adron").joinpath(*SHIPPED[name].split("/"))
    return resource.read_text(encoding="utf-8"), str(resource)


def _read_text(path: Path, source: str) -> str:
    from adron.userfiles import check_regular

    check_regular(path, source)  # a FIFO or a device: refused at once, not waited on
    return readers.read_text(path, source, "catalog file")  # a byte order mark is dropped


def _toml(text: str, source: str) -> dict[str, Any]:
    doc = readers.parse_toml(text, source)  # nesting and numbers bounded
    for key in doc:
        if key not in _TOP_KEYS:
            raise InputError(f"{source}: unknown key '{key}'{_suggest(key, _TOP_KEYS)}")
    return doc


def _merge(parent: dict[str, Any], child: dict[str, Any], source: str) -> dict[str, Any]:
    """``child`` over ``parent`` (see :func:`parse_catalog` for the rules)."""
    header = child.get("catalog", {})
    replaced = header.get("replace", [])
    if not isinstance(replaced, list) or not all(r in _MERGED_ARRAYS for r in replaced):
        raise InputError(
            f"{source}: catalog.replace: expected an array of {', '.join(_MERGED_ARRAYS)}"
        )
    removed = header.get("remove", [])
    if not isinstance(removed, list) or not all(isinstance(r, str) for r in removed):
        raise InputError(f"{source}: catalog.remove: expected an array of model names")
    out = {k: v for k, v in parent.items() if k != "catalog"}
    for model in removed:
        found = False
        for key in _MERGED_ARRAYS:
            kept = [
                e for e in out.get(key, []) if not (isinstance(e, dict) and e.get("model") == model)
            ]
            found = found or len(kept) != len(out.get(key, []))
            if key in out:
                out[key] = kept
        if not found:
            raise InputError(
                f"{source}: catalog.remove: the catalog it extends has no model '{model}'"
            )
    for key, value in child.items():
        if key in _MERGED_TABLES and isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = {**out[key], **value}
        elif key in _MERGED_ARRAYS and isinstance(value, list) and key not in replaced:
            entries = list(out.get(key, []))
            index = {
                e.get("model"): i
                for i, e in enumerate(entries)
                if isinstance(e, dict) and isinstance(e.get("model"), str)
            }
            for e in value:
                model = e.get("model") if isinstance(e, dict) else None
                if isinstance(model, str) and model in index:
                    entries[index[model]] = e  # same model: the child's entry in its place
                else:
                    entries.append(e)
            out[key] = entries
        else:
            out[key] = value
    for key in replaced:
        if key not in child:
            out.pop(key, None)
    if "catalog" in child:  # the child's own header, without the merge instructions
        out["catalog"] = {
            k: v for k, v in header.items() if k not in ("extends", "replace", "remove")
        }
    design = out.get("design")
    if "bus" in out and isinstance(design, dict) and "i2c_first_address" in design:
        del out["design"]["i2c_first_address"]  # the parent's legacy key: [bus] rules
    return out


def _file_key(source: str) -> str:
    """What identifies a catalog file in a chain of ``extends``: its resolved path (two
    spellings of one file are the same file), or ``source`` as given."""
    try:
        return str(Path(source).resolve())
    except (OSError, RuntimeError, ValueError):
        return source


def _resolve(
    text: str, source: str, folder: Path | None, chain: tuple[tuple[str, str], ...]
) -> tuple[dict[str, Any], str]:
    """The merged TOML document of ``text`` and every catalog it extends, and the sha256
    of those texts; each parent is validated on its own first (its errors name it).
    ``chain``: (key, name) of the catalogs that extend this one, this one last."""
    import hashlib

    doc = _toml(text, source)
    digest = hashlib.sha256(text.encode("utf-8"))
    header = doc.get("catalog")
    parent_name = header.get("extends") if isinstance(header, dict) else None
    if parent_name is None:
        for key in ("replace", "remove"):
            if isinstance(header, dict) and key in header:
                raise InputError(
                    f"{source}: catalog.{key}: only for a catalog that extends another"
                )
        return doc, digest.hexdigest()
    if not isinstance(parent_name, str) or not parent_name.strip():
        raise InputError(f"{source}: catalog.extends: expected a catalog name or a file path")
    if parent_name in SHIPPED:
        ptext, psource = _shipped_text(parent_name)
        pfolder: Path | None = None
    else:
        path = Path(parent_name)
        if not path.is_absolute() and folder is not None:
            path = folder / path
        psource = str(path)
        ptext, pfolder = _read_text(path, f"{source}: catalog.extends: {psource}"), path.parent
    key = psource if pfolder is None else _file_key(psource)
    keys = [k for k, _ in chain]
    if key in keys:
        if key == keys[-1]:
            raise InputError(
                f"{source}: catalog.extends: '{parent_name}' extends itself (it is this file)"
            )
        cycle = [name for _, name in chain[keys.index(key) :]] + [psource]
        raise InputError(
            f"{source}: catalog.extends: '{parent_name}' closes a cycle of catalogs that "
            f"extend each other ({' -> '.join(cycle)})"
        )
    if len(chain) > MAX_EXTENDS:
        raise InputError(
            f"{source}: catalog.extends: '{parent_name}' is more than {MAX_EXTENDS} levels deep"
        )
    parent_doc, parent_digest = _resolve(ptext, psource, pfolder, (*chain, (key, psource)))
    parent = _build(parent_doc, psource)  # the parent must be a valid catalog on its own
    currency = header.get("currency")
    if isinstance(currency, str) and currency != parent.currency:
        raise InputError(
            f"{source}: catalog.currency: '{currency}' differs from '{parent.currency}' of the "
            f"catalog it extends ({parent_name}); costs of both are added up"
        )
    digest.update(parent_digest.encode())
    return _merge(parent_doc, doc, source), digest.hexdigest()


def parse_catalog(text: str, source: str, folder: Path | None = None, shipped: str = "") -> Catalog:
    """Validate catalog TOML ``text``; ``source`` names it in messages.

    ``[catalog] extends = "NAME"`` (a shipped catalog, ``default`` or ``dynamixel``) or
    ``= "FILE"`` (relative to ``folder``, the extending file's folder) starts from that
    catalog: the tables [passive], [material], [design] and [tyre] are merged key by key
    (this file's keys win), a [bus] table replaces the parent's whole (another bus shares
    none of its figures); in the arrays [[actuator]], [[module]], [[part]] and
    [[printer]] an entry of a model the parent has replaces the parent's entry in its place,
    and other entries are added after the parent's. ``[catalog] replace = ["actuator"]``
    drops the parent's entries of the arrays named, ``remove = ["MODEL", ...]`` the parent's
    entries of those models (each must exist). [catalog] itself (name, currency,
    version) is this file's; its currency must be the parent's, costs being summed.
    """
    path = _cache_path(text, source, folder, shipped)
    cat = _cached_catalog(path)
    if cat is None:
        root = source if folder is None else _file_key(source)
        doc, digest = _resolve(text, source, folder, ((root, source),))
        cat = replace(_build(doc, source), sha256=digest, shipped=shipped)
        from adron.formats import check  # the file's schema: what the checks above miss

        check("catalog", _toml(text, source), source)
        if path is not None:
            import pickle

            from adron.units import prune_cache, write_cache_file

            data = _CATALOG_CACHE + pickle.dumps(cat, pickle.HIGHEST_PROTOCOL)
            if write_cache_file(path, data):
                prune_cache(path.parent, ("catalog-*.pickle",), CATALOG_CACHE_ENTRIES)
    return cat


#: Catalogs the cache keeps (the least recently used beyond are removed on a write).
CATALOG_CACHE_ENTRIES = 16


#: First bytes of a cached catalog (a new layout gets a new tag).
_CATALOG_CACHE = b"parmor-catalog-1\n"


def _cache_path(text: str, source: str, folder: Path | None, shipped: str) -> Path | None:
    """Where the validated catalog of ``text`` is cached (``$PARMOR_CACHE/catalog-KEY.pickle``:
    parsing and checking a 1000-actuator catalog takes ~0.25 s, reading it back ~0.01 s).
    KEY hashes the text, its name, folder and shipped name, and this module's and the units
    module's code, so an entry is never stale. None (no cache) for a catalog that extends
    another (its parent's text would have to be in the key too), or with the cache off."""
    import hashlib

    from adron import units

    folder_ = units.cache_folder()
    if folder_ is None or "extends" in text:
        return None
    h = hashlib.sha256(_CATALOG_CACHE)
    for part in (text, source, str(folder), shipped):
        b = part.encode("utf-8", "surrogatepass")
        h.update(len(b).to_bytes(8, "little") + b)
    for module in (__file__, units.__file__):
        h.update(Path(module).read_bytes())
    return folder_ / f"catalog-{h.hexdigest()[:32]}.pickle"


def _cached_catalog(path: Path | None) -> Catalog | None:
    """The catalog cached at ``path``, or None (absent, cut short, foreign)."""
    from adron.units import read_cache_pickle

    cat = read_cache_pickle(path, _CATALOG_CACHE, Catalog)
    return cat if isinstance(cat, Catalog) else None


def _perturbation(doc: dict[str, Any], source: str) -> str:
    """The [perturbation] table as JSON text ("" without one); its keys and values are
    synth.verification.perturb's to check (``ranges``)."""
    if "perturbation" not in doc:
        return ""
    table = doc["perturbation"]
    if not isinstance(table, dict):
        raise InputError(f"{source}: perturbation: expected a table, got {_kind(table)}")
    return json.dumps(table, sort_keys=True)


def _build(doc: dict[str, Any], source: str) -> Catalog:
    """The validated catalog of a (merged) TOML document."""
    name, currency, version = _header(_section(doc, "catalog", source))
    actuators = tuple(_actuator(t) for t in _entries(doc, "actuator", source))
    modules = tuple(_module(t) for t in _entries(doc, "module", source))
    seen: dict[str, str] = {}
    labelled = [(f"actuator[{i}]", a.model) for i, a in enumerate(actuators, 1)]
    labelled += [(f"module[{i}]", m.model) for i, m in enumerate(modules, 1)]
    for label, model in labelled:
        if model in seen:
            raise InputError(
                f"{source}: {label} ({model}): duplicate model '{model}' (also {seen[model]})"
            )
        seen[model] = label
    material = _material(_section(doc, "material", source))
    passive = _passive(_section(doc, "passive", source))
    parts = tuple(
        _part(t, material.density_kg_m3) for t in _entries(doc, "part", source, required=False)
    )
    labelled += [(f"part[{i}]", p.model) for i, p in enumerate(parts, 1)]
    for label, model in labelled[len(actuators) + len(modules) :]:
        if model in seen:
            raise InputError(
                f"{source}: {label} ({model}): duplicate model '{model}' (also {seen[model]})"
            )
        seen[model] = label
    tyre = _tyre(_section(doc, "tyre", source)) if "tyre" in doc else None
    printers = []
    for t in _entries(doc, "printer", source, required=False):
        t.check_keys(("model", "bed"))
        printers.append(Printer(t.text("model"), t.lengths("bed")))
    if tyre is not None and tyre.thickness_m >= passive.wheel_min_radius_m:
        raise InputError(
            f"{source}: tyre.thickness: {tyre.thickness_m * 1e3:g} mm leaves no rim in the "
            f"smallest wheel (radius {passive.wheel_min_radius_m * 1e3:g} mm)"
        )
    if "bus" in doc:
        design_data = doc.get("design")
        if isinstance(design_data, dict) and "i2c_first_address" in design_data:
            raise InputError(
                f"{source}: design.i2c_first_address: the catalog has a [bus] table; give "
                "bus.first_address instead"
            )
        bus = _bus(_section(doc, "bus", source))
    else:
        bus = _legacy_bus(_section(doc, "design", source))
    catalog = Catalog(
        name=name,
        currency=currency,
        version=version,
        actuators=actuators,
        modules=modules,
        passive=passive,
        material=material,
        design=_design(_section(doc, "design", source)),
        source=source,
        parts=parts,
        tyre=tyre,
        printers=tuple(printers),
        bus=bus,
        perturbation=_perturbation(doc, source),
    )
    for cls, what in ((MAIN_CLASS, "the main module"), (BATTERY_CLASS, "a battery")):
        if not catalog.modules_of(cls):
            raise InputError(f"{source}: no [[module]] of class '{cls}'; every design needs {what}")
    return catalog


def load_catalog(path: str | Path | None = None) -> Catalog:
    """The catalog ``path`` names: None or "default" the shipped ParMoR one, another name
    of :data:`SHIPPED` ("dynamixel") that shipped catalog, anything else a file.

    A name wins over a file of the same name in the working folder; write ``./dynamixel``
    for the file. A value without a folder or a ``.toml`` suffix that is neither is
    refused with the list of shipped names."""
    if path is None:
        path = "default"
    source = str(path)
    if isinstance(path, str) and path in SHIPPED:
        text, source = _shipped_text(path)
        return parse_catalog(text, source, None, shipped=path)
    p = Path(path)
    if isinstance(path, str) and not p.suffix and p.parent == Path(".") and not p.exists():
        raise InputError(
            f"--catalog {source}: neither a shipped catalog ({', '.join(SHIPPED)}) nor a file"
            + _suggest(source, SHIPPED)
        )
    return parse_catalog(_read_text(p, source), source, p.parent)


def recorded_catalog(entry: object, path: str | Path | None = None) -> Catalog:
    """The catalog a design record's ``catalog`` entry names (``export.record.
    catalog_record``): its shipped catalog by name, or the file ``path`` for a user's one;
    InputError when that catalog's content is not the one the design used (its sha256
    differs: the catalog changed since) or the entry is not a catalog entry."""
    if not isinstance(entry, dict) or not isinstance(entry.get("sha256"), str):
        raise InputError("the design record names no catalog (designs before records did)")
    shipped = entry.get("shipped") or ""
    if path is None and not shipped:
        raise InputError(f"the design used the user's catalog '{entry.get('name')}': give its file")
    cat = load_catalog(path if path is not None else shipped)
    if cat.sha256 != entry["sha256"]:
        raise InputError(
            f"{cat.source}: not the catalog the design used (its content changed: sha256 "
            f"{cat.sha256[:12]}, the design's {entry['sha256'][:12]})"
        )
    return cat


# ---- ASP facts ---------------------------------------------------------------------------


def _scaled(value: float, scale: int) -> int:
    """``value * scale`` rounded half up, from the shortest decimal form of ``value``."""
    return int((Decimal(repr(value)) * scale).to_integral_value(rounding=ROUND_HALF_UP))


def catalog_facts(cat: Catalog) -> str:
    """The actuators and modules as ASP facts in integers (clingo has no floats).

    ``actuator(Model, Class, MassMg, CostCents, StallTorqueMilliNm, NoLoadSpeedMilliRadPerS,
    StallCurrentMilliA).``, ``module(Model, Class, MassMg, CostCents, CurrentMilliA).`` and
    ``bus_limit(N).`` (the bus's :attr:`Bus.module_limit`)
    with Model and Class as strings; mass in milligrams, cost in hundredths of the catalog
    currency, torque in mN*m, speed in mrad/s, current in mA, each rounded half up.
    Sorted by model: the same catalog gives the same text.
    """
    lines = [
        f"% Catalog facts: {cat.name}, version {cat.version}, cost in {cat.currency} cents.",
        "% actuator(Model, Class, MassMg, CostCents, StallTorqueMilliNm, "
        "NoLoadSpeedMilliRadPerS, StallCurrentMilliA).",
        "% module(Model, Class, MassMg, CostCents, CurrentMilliA).",
        f"% bus_limit(N): at most N active modules on the {cat.bus.name} bus, master included.",
        f"bus_limit({cat.bus.module_limit}).",
    ]
    for a in sorted(cat.actuators, key=lambda a: a.model):
        fields = [
            asp_string(a.model),
            asp_string(a.ontology_class),
            _scaled(a.mass_kg, 1_000_000),
            _scaled(a.cost, 100),
            _scaled(a.stall_torque_Nm, 1000),
            _scaled(a.no_load_speed_rad_s, 1000),
            _scaled(a.stall_current_A, 1000),
        ]
        lines.append(f"actuator({','.join(map(str, fields))}).")
    for m in sorted(cat.modules, key=lambda m: m.model):
        fields = [
            asp_string(m.model),
            asp_string(m.ontology_class),
            _scaled(m.mass_kg, 1_000_000),
            _scaled(m.cost, 100),
            _scaled(m.current_A, 1000),
        ]
        lines.append(f"module({','.join(map(str, fields))}).")
    return "\n".join(lines) + "\n"
