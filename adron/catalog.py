"""The ParMoR module catalog: actuators, active modules, passive templates, material, rules.

The catalog is a TOML file (the shipped one is ``adron/catalog.toml``; a user passes their
own with ``--catalog``). :func:`load_catalog` validates it against its schema
(``adron/catalog_schema.py``, where every rule of one file lives) and returns frozen
dataclasses of SI floats; every problem is an InputError that names the file, the key path
and the value, e.g. ``my.toml: actuator[1] (MG996R).stall_torque: missing (it is
required)``. Entries are counted from 0 in file order and named by their model. This
module keeps what one file cannot say: the catalog it extends, and the ontology's
classes (:meth:`Catalog.check_classes`).

:func:`catalog_facts` writes the actuators and modules as integer ASP facts for clingo.

Module mass, size and cost describe the whole module as it goes into a robot: the part,
its ATtiny85 board and its printed housing with dovetail faces (see catalog.toml).
"""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Collection, Iterable
from dataclasses import dataclass, replace
from decimal import ROUND_HALF_UP, Decimal
from importlib.resources import files
from pathlib import Path
from typing import Any

from adron import readers, schema, units
from adron.errors import InputError
from adron.translate import asp_string
from adron.units import prune_cache, read_cache_pickle, write_cache_file

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
        """InputError if an entry names an ontology class not in ``known`` (a reference to
        another file, the ontology, that the catalog's schema cannot check).

        The catalog cannot see the ontology (adron.catalog imports no knowledge base);
        the caller passes the class names of the loaded ontology.
        """
        entries = [
            (f"actuator[{i}] ({a.model})", a.ontology_class) for i, a in enumerate(self.actuators)
        ]
        entries += [
            (f"module[{i}] ({m.model})", m.ontology_class) for i, m in enumerate(self.modules)
        ]
        entries += [(f"part[{i}] ({p.model})", p.ontology_class) for i, p in enumerate(self.parts)]
        for path, cls in entries:
            if cls not in known:
                raise InputError(
                    f"{self.source}: {path}.class: '{cls}' is not a class of the ontology"
                    + _suggest(cls, known)
                )


# ---- Loading -----------------------------------------------------------------------------

#: Tables merged key by key when a catalog extends another (see :func:`parse_catalog`);
#: [bus] is replaced whole, and the arrays of tables are merged by model.
_MERGED_TABLES = ("passive", "material", "design", "tyre")
_MERGED_ARRAYS = ("actuator", "module", "part", "printer")
#: Longest chain of catalogs extending one another.
MAX_EXTENDS = 8


def _suggest(word: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


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
    return readers.parse_toml(text, source)  # nesting and numbers bounded


def _merge(parent: dict[str, Any], child: dict[str, Any], source: str) -> dict[str, Any]:
    """``child`` over ``parent`` (see :func:`parse_catalog` for the rules); ``child`` is
    an extension its schema accepted. InputError when ``remove`` names a model the
    parent does not have (what no schema of the child can know)."""
    header = child["catalog"]  # checked by the extension's schema: replace, remove typed
    replaced = header.get("replace", [])
    removed = header.get("remove", [])
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
    of those texts; each parent is validated on its own first (its errors name it), and a
    file that extends another is checked against the extension's schema first. What no
    schema of one file can say is checked here: the parent exists and is no cycle, the
    chain is at most :data:`MAX_EXTENDS` deep, the currency is the parent's.
    ``chain``: (key, name) of the catalogs that extend this one, this one last."""
    import hashlib

    from adron.catalog_schema import check

    doc = _toml(text, source)
    digest = hashlib.sha256(text.encode("utf-8"))
    header = doc.get("catalog")
    parent_name = header.get("extends") if isinstance(header, dict) else None
    if parent_name is None:  # a complete catalog: its schema is checked by _build
        return doc, digest.hexdigest()
    check(doc, source, extension=True)  # this file's keys, before any other file is read
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
    currency = header["currency"]
    if currency != parent.currency:
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
        if path is not None:
            import pickle

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

    folder_ = units.cache_folder()
    if folder_ is None or "extends" in text:
        return None
    h = hashlib.sha256(_CATALOG_CACHE)
    for part in (text, source, str(folder), shipped):
        b = part.encode("utf-8", "surrogatepass")
        h.update(len(b).to_bytes(8, "little") + b)
    from adron import catalog_schema  # (a circle: catalog_schema reads this module)

    for module in (__file__, units.__file__, catalog_schema.__file__, schema.__file__):
        h.update(Path(module).read_bytes())
    return folder_ / f"catalog-{h.hexdigest()[:32]}.pickle"


def _cached_catalog(path: Path | None) -> Catalog | None:
    """The catalog cached at ``path``, or None (absent, cut short, foreign)."""

    cat = read_cache_pickle(path, _CATALOG_CACHE, Catalog)
    return cat if isinstance(cat, Catalog) else None


def _build(doc: dict[str, Any], source: str) -> Catalog:
    """The catalog of a (merged) TOML document, checked against its schema
    (:class:`adron.catalog_schema.CatalogFile`: InputError naming ``source``, the key and
    the value), in SI units."""
    from adron.catalog_schema import check

    f = check(doc, source)

    def size(v: list[float]) -> Size:
        return (v[0], v[1], v[2])

    density = f.material.density
    p = f.passive
    bus = I2C_DEFAULT
    if f.bus is not None:
        b = f.bus
        bus = Bus(
            b.name,
            b.protocol,
            b.first_address,
            b.last_address,
            b.device_limit,
            b.address_word,
            b.address_format,
        )
    elif f.design.i2c_first_address is not None:  # a catalog from before [bus]
        bus = replace(I2C_DEFAULT, first_address=f.design.i2c_first_address)
    modules = []
    for m in f.module:
        capacity = None if m.capacity is None else m.capacity / 3600.0  # C -> Ah
        modules.append(
            Module(
                model=m.model,
                ontology_class=m.cls,
                mass_kg=m.mass,
                size_m=size(m.size),
                cost=m.cost,
                current_A=m.current,
                capacity_Ah=capacity,
                voltage_V=m.voltage,
                max_current_A=None if capacity is None else m.c_rating * capacity,  # A
            )
        )
    d = f.design
    return Catalog(
        name=f.catalog.name,
        currency=f.catalog.currency,
        version=str(f.catalog.version),
        actuators=tuple(
            Actuator(
                model=a.model,
                ontology_class=a.cls,
                torque_class=a.torque_class,
                mass_kg=a.mass,
                size_m=size(a.size),
                stall_torque_Nm=a.stall_torque,
                no_load_speed_rad_s=a.no_load_speed,
                stall_current_A=a.stall_current,
                cost=a.cost,
                travel_rad=math.radians(a.travel_deg),
            )
            for a in f.actuator
        ),
        modules=tuple(modules),
        passive=Passive(
            dovetail_face_m=p.dovetail_face,
            face_thickness_m=p.face_thickness,
            min_wall_m=p.min_wall,
            max_outer_radius_m=p.max_outer_radius,
            fillet_radius_m=p.fillet_radius,
            stress_concentration=p.stress_concentration,
            min_link_length_m=p.min_link_length,
            max_link_length_m=p.max_link_length,
            wheel_min_radius_m=p.wheel_min_radius,
            wheel_max_radius_m=p.wheel_max_radius,
            wheel_width_m=p.wheel_width,
            foot_min_side_m=p.foot_min_side,
            foot_max_side_m=p.foot_max_side,
            foot_thickness_m=p.foot_thickness,
            printer_bed_m=size(p.printer_bed),
            print_speed_m3_s=p.print_speed or 0.0,
            print_clearance_m=p.print_clearance,
        ),
        material=Material(
            f.material.name, f.material.youngs_modulus, f.material.yield_strength, density
        ),
        design=DesignRules(
            torque_safety_factor=d.torque_safety_factor,
            stress_safety_factor=d.stress_safety_factor,
            max_tip_deflection_m=d.max_tip_deflection,
            max_joint_acceleration_rad_s2=d.max_joint_acceleration,
            gravity_m_s2=d.gravity,
            max_slope_rad=d.max_slope,
            rolling_resistance=d.rolling_resistance,
            behaviour_torque_factor=d.behaviour_torque_factor or 0.0,
        ),
        source=source,
        parts=tuple(
            Part(
                model=x.model,
                ontology_class=x.cls,
                source=x.source,
                # a printed solid: the box's volume times the material's density
                mass_kg=math.prod(x.size) * density if x.source == "printed" else x.mass,
                size_m=size(x.size),
                cost=x.cost,
            )
            for x in f.part
        ),
        tyre=None
        if f.tyre is None
        else Tyre(f.tyre.name, f.tyre.thickness, f.tyre.density, f.tyre.cost_per_m),
        printers=tuple(Printer(x.model, size(x.bed)) for x in f.printer),
        bus=bus,
        # overrides of synth/verification/perturb.toml's ranges, read by synth.verification.perturb
        perturbation=json.dumps(doc["perturbation"], sort_keys=True)
        if "perturbation" in doc
        else "",
    )


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
