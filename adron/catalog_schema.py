"""The schema of a module catalog (``adron/catalog.toml``, ``adron/catalogs/*.toml``,
``--catalog FILE.toml``): the one place its rules live.

:class:`CatalogFile` is a complete catalog: every table and key it needs, each quantity
with its unit (``"34 g"``), converted to SI and held to its range (:data:`CATALOG_MAX`,
costs to :data:`MAX_COST`), and the rules that tie keys of one file together (a battery's
keys only on a battery, a printed part's mass from its size, the printed parts' sizes
fitting each other and the printer's bed, a tyre thinner than the smallest wheel, the
bus's addresses in order, unique models, a main module and a battery). A catalog that
extends another (``[catalog] extends``) is first checked on its own as
:class:`CatalogExtension` (its tables merged key by key may give some keys only), then
merged and checked as a complete catalog. ``adron.catalog`` builds its dataclasses from
the validated model; what one file cannot say is left to it: the catalog it extends (the
file, a cycle, the chain's depth), a currency that must be its parent's, a ``remove``
naming a model the parent has, and the classes the ontology knows
(``Catalog.check_classes``).

The JSON Schema (``adron/schemas/catalog.schema.json``) is a complete catalog, or an
extension when ``[catalog]`` has ``extends``; it checks a quantity's form (a number and
a unit), not its dimension or range, which the model does.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    Field,
    PlainValidator,
    WithJsonSchema,
    create_model,
    model_validator,
)

from adron.catalog import BATTERY_CLASS, MAIN_CLASS, TORQUE_CLASSES
from adron.errors import InputError
from adron.schema import MAX_NAME, At, Closed, _keys_checked, described, validate
from adron.units import DIMENSIONS
from adron.units import quantity as read

PART_SOURCES = ("printed", "bought")
ADDRESS_FORMATS = ("hex", "decimal")
#: the arrays a catalog that extends another may ``replace``
MERGED_ARRAYS = ("actuator", "module", "part", "printer")
#: Largest address (ID) a bus may name; any real bus is far below.
MAX_ADDRESS = 65535
#: Largest catalog quantity of each dimension parmor accepts, with its unit. Beyond them no
#: module of a modular robot makes sense, and the ASP facts (integers: milligrams, cents,
#: mN*m, mrad/s, mA; clingo's are 32-bit) of a few tens of modules would overflow; the
#: material's and the design's figures are bounded far above any printable material and
#: any robot's environment.
CATALOG_MAX: dict[str, str] = {
    "mass": "50 kg",
    "length": "10 m",
    "torque": "1000 N*m",
    "angular_speed": "1000 rad/s",
    "current": "1000 A",
    "voltage": "1000 V",
    "charge": "1000 Ah",
    "pressure": "1000 GPa",
    "density": "30000 kg/m^3",
    "acceleration": "100 m/s^2",
    "angular_acceleration": "10000 rad/s^2",
    "volume_flow": "0.001 m^3/s",
}
#: Smallest catalog quantity of the dimensions the ASP facts count in integers (mg, mN*m,
#: mrad/s, mA): anything less is 0 there (a zero current is written 0 A and allowed).
CATALOG_MIN: dict[str, str] = {
    "mass": "1 mg",
    "torque": "1 mN*m",
    "angular_speed": "0.001 rad/s",
    "current": "1 mA",
}
#: Largest cost of one module (and of a metre of tyre), in the catalog's currency (cents
#: must fit clingo's integers).
MAX_COST = 100_000.0
#: Largest factor (safety factors, stress concentration, a battery's C rating).
MAX_FACTOR = 1000.0
_QUANTITY_TEXT = 100


def _si(text: str, dimension: str) -> float:
    return read(text, dimension, "CATALOG_MAX")


def _text(v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise ValueError("not a non-empty string")
    bad = next((c for c in v if not c.isprintable()), None)
    if bad is not None:  # a newline or NUL breaks the ASP facts, the BOM's CSV, the URDF
        raise ValueError(f"holds the control character U+{ord(bad):04X}: one line of text")
    if len(v) > MAX_NAME:
        raise ValueError(f"longer than {MAX_NAME} characters")
    return v


#: one line of printable text (a model, a name)
Text = Annotated[
    str,
    PlainValidator(_text),
    WithJsonSchema({"type": "string", "minLength": 1, "maxLength": MAX_NAME, "pattern": "\\S"}),
]


#: an ontology class's name
def _pattern(regex: str, what: str, doc: str) -> Any:
    import re

    compiled = re.compile(regex)

    def check(v: Any) -> str:
        if not isinstance(v, str) or not compiled.fullmatch(v):
            raise ValueError(f"not {what}")
        return v

    schema = {"type": "string", "pattern": f"^{regex}$", "description": doc}
    return Annotated[str, PlainValidator(check), WithJsonSchema(schema)]


ClassName = _pattern(
    f"[A-Z][A-Za-z0-9]{{0,{MAX_NAME - 1}}}",
    "an ontology class name (like 'MainModule')",
    "an ontology class (like 'MainModule')",
)
#: a currency's code
Currency = _pattern("[A-Z]{3}", "a currency code such as 'EUR'", "an ISO 4217 code")


def quantity(
    dimension: str,
    *,
    zero: bool = False,
    top: str | None = None,
    below: str | None = None,
    doc: str = "",
) -> Any:
    """A quantity of ``dimension`` with its unit, as SI float: more than 0 (or ``zero``:
    at least 0; at least :data:`CATALOG_MIN` of the dimension), at most ``top`` (default
    :data:`CATALOG_MAX` of the dimension), or less than ``below``."""

    top = top if top is not None or below is not None else CATALOG_MAX.get(dimension)
    low = None if zero else CATALOG_MIN.get(dimension)

    def check(v: Any) -> float:
        try:
            x = read(v, dimension, "", allow_zero=zero)
        except InputError as e:
            raise ValueError(str(e).removeprefix(": ")) from None
        if top is not None and x > _si(top, dimension):
            raise ValueError(f"above {top}, the largest accepted")
        if low is not None and x < _si(low, dimension):
            raise ValueError(f"below {low}, the smallest accepted")
        if below is not None and x >= _si(below, dimension):
            raise ValueError(f"not less than {below}")
        return x

    example = DIMENSIONS[dimension].example
    bound = f", at most {top}" if top else f", less than {below}" if below else ""
    bound = f", at least {low}{bound}" if low else bound
    schema = {
        "type": "string",
        "maxLength": _QUANTITY_TEXT,
        "pattern": "^\\s*[+]?([0-9]+\\.?[0-9]*|\\.[0-9]+)([eE][-+]?[0-9]+)?\\s*[^\\s0-9.]",
        "description": (doc + "; " if doc else "")
        + f"{dimension.replace('_', ' ')} with its unit, such as '{example}'"
        + (", 0 or more" if zero else ", more than 0" if not low else "")
        + bound,
    }
    return Annotated[float, PlainValidator(check), WithJsonSchema(schema)]


def number(
    low: float, high: float, *, open_low: bool = False, open_high: bool = False, doc: str = ""
) -> Any:
    """A bare number (or a number's text, ``"25"``) from ``low`` to ``high``."""

    def check(v: Any) -> float:
        if isinstance(v, str):
            try:
                v = read(v, "dimensionless", "", allow_negative=True)
            except InputError as e:
                raise ValueError(str(e).removeprefix(": ")) from None
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ValueError("not a number")
        try:
            x = float(v)
        except OverflowError:
            raise ValueError("too large") from None
        if not math.isfinite(x):
            raise ValueError("not a finite number")
        if x < low or (open_low and x == low) or x > high or (open_high and x == high):
            lo = f"more than {low:g}" if open_low else f"at least {low:g}"
            hi = f"less than {high:g}" if open_high else f"at most {high:g}"
            raise ValueError(f"out of range: must be {lo} and {hi}")
        return x

    limits: dict[str, Any] = {"exclusiveMinimum" if open_low else "minimum": low}
    limits["exclusiveMaximum" if open_high else "maximum"] = high
    schema = {
        "anyOf": [
            {"type": "number", **limits},
            {"type": "string", "maxLength": _QUANTITY_TEXT, "pattern": "^\\s*[-+.0-9]"},
        ],
        "description": doc or "a number",
    }
    return Annotated[float, PlainValidator(check), WithJsonSchema(schema)]


def integer(low: int, high: int, doc: str = "") -> Any:
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise ValueError("not an integer")
        if not low <= v <= high:
            raise ValueError(f"out of range: must be within {low} and {high}")
        return v

    schema = {"type": "integer", "minimum": low, "maximum": high, "description": doc}
    return Annotated[int, PlainValidator(check), WithJsonSchema(schema)]


Length = quantity("length")
Mass = quantity("mass")
Cost = number(0.0, MAX_COST, doc=f"in the catalog's currency, 0 to {MAX_COST:,.0f}")
Size = Annotated[
    list[Length],
    Field(min_length=3, max_length=3, description="x, y, z with their units ('50 mm')"),
]


# ---- the tables -------------------------------------------------------------------------------


class Header(Closed):
    """``[catalog]``: its name, currency and version; ``extends`` another catalog."""

    name: Text
    currency: Currency = described(doc="an ISO 4217 code such as 'EUR'")
    version: Annotated[str, Field(max_length=MAX_NAME, min_length=1)] | integer(
        0, 10**9
    ) = described(doc="a version string (or number)")
    extends: Text | None = described(
        None, "a shipped catalog's name ('default', 'dynamixel') or a file, relative to this one"
    )
    replace: list[Literal[MERGED_ARRAYS]] | None = described(
        None, "arrays of the extended catalog dropped: actuator, module, part, printer"
    )
    remove: list[Text] | None = described(None, "models of the extended catalog dropped")

    @model_validator(mode="after")
    def _extending(self) -> Header:
        for key in ("replace", "remove"):
            if getattr(self, key) is not None and self.extends is None:
                raise At(key, "only for a catalog that extends another", getattr(self, key))
        return self


class Actuator(Closed):
    """``[[actuator]]``: a servo in its printed housing, as it goes into a robot."""

    model: Text
    cls: ClassName = Field(alias="class", description="its ontology class")
    torque_class: Literal[TORQUE_CLASSES]
    mass: Mass
    size: Size
    stall_torque: quantity("torque")
    no_load_speed: quantity("angular_speed")
    stall_current: quantity("current")
    cost: Cost
    travel_deg: number(
        0, 360, open_low=True, doc="degrees the shaft turns end to end (360: continuous)"
    )


class Module(Closed):
    """``[[module]]``: an active module that is no actuator (main, battery, sensor); a
    battery (class BatteryModule) also has ``capacity``, ``voltage`` and ``c_rating``."""

    model: Text
    cls: ClassName = Field(alias="class", description="its ontology class")
    mass: Mass
    size: Size
    cost: Cost
    current: quantity("current", zero=True, doc="its typical draw from the 5 V rail")
    capacity: quantity("charge") | None = None
    voltage: quantity("voltage") | None = None
    c_rating: number(0, MAX_FACTOR, open_low=True, doc="continuous discharge, C") | None = None

    @model_validator(mode="after")
    def _battery(self) -> Module:
        keys = ("capacity", "voltage", "c_rating")
        if self.cls == BATTERY_CLASS:
            for key in keys:
                if getattr(self, key) is None:
                    raise At(key, f"missing (a module of class '{BATTERY_CLASS}' needs it)")
        else:
            for key in keys:
                if key in self.model_fields_set:
                    raise At(key, f"only for modules of class '{BATTERY_CLASS}'")
        return self


class Part(Closed):
    """``[[part]]``: a passive part that is no printed link, printed (its mass is its
    size's box of the material) or bought (its ``mass`` given)."""

    model: Text
    cls: ClassName = Field(alias="class", description="its ontology class")
    source: Literal[PART_SOURCES]
    size: Size
    cost: Cost
    mass: Mass | None = described(None, "a bought part's")

    @model_validator(mode="after")
    def _mass(self) -> Part:
        if self.source == "printed" and self.mass is not None:
            raise At("mass", "a printed part's mass is its size's box of the material: give none")
        if self.source == "bought" and self.mass is None:
            raise At("mass", "missing (a bought part needs it)")
        return self


class Printer(Closed):
    """``[[printer]]``: a printer larger than ``[passive] printer_bed``."""

    model: Text
    bed: Size


_PASSIVE_DOC = {
    "dovetail_face": "the dovetail face of a module's housing",
    "face_thickness": "a printed face's thickness",
    "min_wall": "a printed tube's thinnest wall",
    "max_outer_radius": "a printed tube's largest outer radius",
    "fillet_radius": "the fillet where a tube meets a face",
    "min_link_length": "the shortest printed link",
    "max_link_length": "the longest printed link",
    "wheel_min_radius": "the smallest printed wheel",
    "wheel_max_radius": "the largest printed wheel",
    "wheel_width": "a printed wheel's width",
    "foot_min_side": "the smallest printed foot plate's side",
    "foot_max_side": "the largest printed foot plate's side",
    "foot_thickness": "a printed foot plate's thickness",
    "print_clearance": "left on every side between a printed dovetail pin and its rail",
}


class Passive(Closed):
    """``[passive]``: the printed parts' dimensions and limits."""

    dovetail_face: quantity("length", doc=_PASSIVE_DOC["dovetail_face"])
    face_thickness: quantity("length", doc=_PASSIVE_DOC["face_thickness"])
    min_wall: quantity("length", doc=_PASSIVE_DOC["min_wall"])
    max_outer_radius: quantity("length", doc=_PASSIVE_DOC["max_outer_radius"])
    fillet_radius: quantity("length", doc=_PASSIVE_DOC["fillet_radius"])
    min_link_length: quantity("length", doc=_PASSIVE_DOC["min_link_length"])
    max_link_length: quantity("length", doc=_PASSIVE_DOC["max_link_length"])
    wheel_min_radius: quantity("length", doc=_PASSIVE_DOC["wheel_min_radius"])
    wheel_max_radius: quantity("length", doc=_PASSIVE_DOC["wheel_max_radius"])
    wheel_width: quantity("length", doc=_PASSIVE_DOC["wheel_width"])
    foot_min_side: quantity("length", doc=_PASSIVE_DOC["foot_min_side"])
    foot_max_side: quantity("length", doc=_PASSIVE_DOC["foot_max_side"])
    foot_thickness: quantity("length", doc=_PASSIVE_DOC["foot_thickness"])
    print_clearance: quantity("length", doc=_PASSIVE_DOC["print_clearance"])
    stress_concentration: number(1, MAX_FACTOR, doc="the stress concentration factor Kt")
    printer_bed: Size = described(doc="the catalog's printer's build volume x, y, z")
    print_speed: quantity("volume_flow") | None = described(
        None, "an older catalog's average extrusion rate (unused)"
    )

    @model_validator(mode="after")
    def _fits(self) -> Passive:
        def mm(x: float) -> str:
            return f"{x * 1e3:g} mm"

        if self.min_wall >= self.max_outer_radius:
            raise At(
                "min_wall",
                f"leaves no hole in a tube of outer radius {mm(self.max_outer_radius)}",
                mm(self.min_wall),
            )
        if 2 * (self.max_outer_radius + self.fillet_radius) > self.dovetail_face:
            raise At(
                "max_outer_radius",
                f"a tube of this radius with its {mm(self.fillet_radius)} fillet does not fit "
                f"the {mm(self.dovetail_face)} dovetail face",
                mm(self.max_outer_radius),
            )
        for low, high in (
            ("min_link_length", "max_link_length"),
            ("wheel_min_radius", "wheel_max_radius"),
            ("foot_min_side", "foot_max_side"),
        ):
            if getattr(self, low) > getattr(self, high):
                raise At(
                    low, f"more than {high} = {mm(getattr(self, high))}", mm(getattr(self, low))
                )
        bed = self.printer_bed
        if self.max_link_length > max(bed):
            raise At(
                "max_link_length",
                f"does not fit the printer bed ({' x '.join(mm(b) for b in bed)})",
                mm(self.max_link_length),
            )
        flat = min(bed[0], bed[1])
        if 2 * self.wheel_max_radius > flat:
            raise At(
                "wheel_max_radius",
                "a wheel this large does not fit the printer bed",
                mm(self.wheel_max_radius),
            )
        if self.foot_max_side > flat:
            raise At("foot_max_side", "does not fit the printer bed", mm(self.foot_max_side))
        return self


class Material(Closed):
    """``[material]``: the printing material."""

    name: Text
    youngs_modulus: quantity("pressure")
    yield_strength: quantity("pressure")
    density: quantity("density")


class Design(Closed):
    """``[design]``: safety factors and the design's environment."""

    torque_safety_factor: number(1, MAX_FACTOR, doc="usable torque: stall torque / this")
    stress_safety_factor: number(1, MAX_FACTOR)
    max_tip_deflection: quantity("length")
    max_joint_acceleration: quantity("angular_acceleration")
    gravity: quantity("acceleration")
    max_slope: quantity("angle", zero=True, below="90 deg", doc="the steepest slope designed for")
    rolling_resistance: number(0, 1, open_high=True)
    behaviour_torque_factor: number(1, MAX_FACTOR) | None = described(
        None, "torque safety factor on the behaviours' own inverse dynamics"
    )
    i2c_first_address: integer(0x08, 0x77, "a catalog without [bus]: its first I2C address") | (
        None
    ) = None


class Tyre(Closed):
    """``[tyre]``: the rubber band of a printed wheel."""

    name: Text
    thickness: Length
    density: quantity("density")
    cost_per_m: number(0, MAX_COST, doc="per metre of band, in the catalog's currency")


class Bus(Closed):
    """``[bus]``: the bus the active modules share, its addresses and its limit."""

    name: Text
    protocol: Text
    first_address: integer(0, MAX_ADDRESS)
    last_address: integer(0, MAX_ADDRESS)
    device_limit: integer(2, MAX_ADDRESS + 2, "active modules at most, the master included") | (
        None
    ) = None
    address_word: Text = described("address", "what the bus calls an address ('ID')")
    address_format: Literal[ADDRESS_FORMATS] = "hex"

    @model_validator(mode="after")
    def _order(self) -> Bus:
        if self.last_address < self.first_address:
            raise At(
                "last_address",
                f"below first_address = {self.first_address}",
                self.last_address,
            )
        return self


def _perturbation() -> Any:
    from adron.formats import PerturbationOverrides

    return PerturbationOverrides


class CatalogFile(Closed):
    """A module catalog (adron/catalog.toml, --catalog FILE.toml): complete."""

    catalog: Header
    actuator: Annotated[list[Actuator], Field(min_length=1)]
    module: Annotated[list[Module], Field(min_length=1)]
    part: list[Part] = []
    tyre: Tyre | None = None
    printer: list[Printer] = []
    passive: Passive
    material: Material
    design: Design
    bus: Bus | None = described(None, "default: the paper's I2C bus")
    perturbation: _perturbation() | None = described(
        None, "overrides of synth/verification/perturb.toml's ranges"
    )

    @model_validator(mode="after")
    def _whole(self) -> CatalogFile:
        _unique_models(self)
        for cls, what in ((MAIN_CLASS, "the main module"), (BATTERY_CLASS, "a battery")):
            if not any(m.cls == cls for m in self.module):
                raise At("module", f"no module of class '{cls}'; every design needs {what}")
        if self.tyre is not None and self.tyre.thickness >= self.passive.wheel_min_radius:
            raise At(
                "tyre.thickness",
                f"leaves no rim in the smallest wheel (radius "
                f"{self.passive.wheel_min_radius * 1e3:g} mm)",
                f"{self.tyre.thickness * 1e3:g} mm",
            )
        if self.bus is not None and self.design.i2c_first_address is not None:
            raise At(
                "design.i2c_first_address",
                "the catalog has a [bus] table; give bus.first_address instead",
                self.design.i2c_first_address,
            )
        return self


def _unique_models(cat: Any) -> None:
    seen: dict[str, str] = {}
    for key in ("actuator", "module", "part", "printer"):
        for i, e in enumerate(getattr(cat, key) or ()):
            label = f"{key}[{i}]"
            if key != "printer" and e.model in seen:
                raise At(f"{label}.model", f"repeats the model of {seen[e.model]}", e.model)
            if key != "printer":
                seen[e.model] = label
    names: dict[str, int] = {}
    for i, p in enumerate(getattr(cat, "printer", None) or ()):
        if p.model in names:
            raise At(f"printer[{i}].model", f"repeats printer[{names[p.model]}]", p.model)
        names[p.model] = i


def optional(field: Any) -> Any:
    """The type of a model's field (its validators kept: pydantic keeps an ``Annotated``
    type's metadata apart from its annotation), or None."""
    if field.metadata:
        return Annotated[(field.annotation, *field.metadata)] | None
    return field.annotation | None


def _partial(model: type[Closed]) -> type[Closed]:
    """``model``'s keys, each optional and checked on its own (a table merged key by key
    into the extended catalog's: the rules that tie keys together are checked after)."""
    fields = {
        n: (optional(f), Field(None, alias=f.alias, description=f.description))
        for n, f in model.model_fields.items()
    }
    return create_model(f"{model.__name__}Keys", __base__=Closed, __doc__=model.__doc__, **fields)


class CatalogExtension(Closed):
    """A catalog that extends another (``[catalog] extends``): what it adds, replaces and
    removes. Its ``[passive]``, ``[material]``, ``[design]`` and ``[tyre]`` are merged key
    by key (any of their keys); its entries and ``[bus]`` are whole."""

    catalog: Header
    actuator: list[Actuator] = []
    module: list[Module] = []
    part: list[Part] = []
    tyre: _partial(Tyre) | None = None
    printer: list[Printer] = []
    passive: _partial(Passive) | None = None
    material: _partial(Material) | None = None
    design: _partial(Design) | None = None
    bus: Bus | None = None
    perturbation: _perturbation() | None = None

    @model_validator(mode="after")
    def _extends(self) -> CatalogExtension:
        if self.catalog.extends is None:
            raise At("catalog.extends", "missing (only a catalog that extends another is partial)")
        _unique_models(self)
        return self


def check(doc: Any, source: str, extension: bool = False) -> Any:
    """``doc`` (a parsed catalog file, or a merged one) as :class:`CatalogFile` (or, with
    ``extension``, as :class:`CatalogExtension`); InputError naming ``source``, the key
    path (entries with their model: ``actuator[1] (MG996R).mass``) and the value."""

    model = CatalogExtension if extension else CatalogFile
    return validate(model, doc, source, labels=("model",))


def json_schema() -> dict:
    """The catalog's JSON Schema: a complete catalog, or an extension when ``[catalog]``
    has ``extends``."""
    from pydantic.json_schema import models_json_schema

    refs, defs = models_json_schema(
        [(CatalogFile, "validation"), (CatalogExtension, "validation")], by_alias=True
    )
    full = refs[(CatalogFile, "validation")]
    ext = refs[(CatalogExtension, "validation")]
    return _keys_checked(
        {
            "$schema": "https://json-schema.org/draft/2020-12/schema",
            "$id": "https://parmor.invalid/schemas/catalog.schema.json",
            "title": "catalog",
            "description": "A module catalog (adron/catalog.toml, --catalog FILE): complete, or "
            "one that extends another ([catalog] extends)",
            "type": "object",
            "if": {
                "properties": {"catalog": {"type": "object", "required": ["extends"]}},
                "required": ["catalog"],
            },
            "then": ext,
            "else": full,
            **defs,
        }
    )
