"""Structural design parameters: names, dimensions, which structures use them, defaults.

The 6-DOF arm's payload default is the ontology's ``defaultParameter``. Conceptual
parameters (``object_shape``) are declared in the ontology (``parameterName``);
the physical ones below size the structure. Values take units (``--param reach=30cm``)
and are SI floats inside. A default of ``None`` means "from the catalog's [design]
section" (``deflection``, ``slope``).

| name | dimension | used by | default | range |
|---|---|---|---|---|
| payload | mass | all | kg: arm 0.2 (6-DOF 0.1); multiped 0.1; biped 0.05; wheels 0.5 | 0-50 kg |
| reach | length | serial_arm | 0.25 m | 5 cm-2 m |
| speed | speed | all but module_chain | m/s: arm 0.2 (tip), legs 0.05, wheels 0.3 | 1 mm/s-10 m/s |
| obstacle_height | length | multiped | 0.03 m | 1 mm-1 m |
| load_area | area | wheeled, steered | 0.03 m^2 (300 cm^2) | 25 cm^2-1 m^2 |
| height | length | biped | 0.40 m | 5 cm-2 m |
| deflection | length | every structure | catalog max_tip_deflection | 0.01 mm-10 cm |
| slope | angle | wheeled, steered | catalog max_slope | 0-45 deg |
| (mobile_manipulator) | | payload, reach, speed, load_area, deflection, slope | | |
| (legged_manipulator) | | payload, reach, speed, obstacle_height, deflection | | |
| (multi_arm) | | as serial_arm | | |
| dof | count | serial_arm (synth/reasoning/composition.py makes it) | the arm's own | 3-7 |

The range is where a design of ParMoR-like modules makes sense (see RANGES); a value
outside it is refused (InputError, exit 2) before any work. Inside it, sizing may still
find the request infeasible (exit 1, naming the limit and the best value that works).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from adron.errors import InputError, OntologyError
from adron.units import quantity

# Parameters apply by the design's structure (``kinematics.assemble.structure_of``), never
# by a robot type's name; a type may change a default with the ontology's
# ``(defaultParameter TYPE "name" "quantity")`` (the nearest class's wins).
MANIPULATORS = ("serial_arm", "multi_arm")
LEGGED = ("multiped",)
WHEELED = ("wheeled", "steered")
#: a serial arm on a wheeled base takes the parameters of both
MOBILE = ("mobile_manipulator",)
#: chains (a head, an arm) on a multiped's trunk: the legs' parameters and the reach
LEGGED_ARM = ("legged_manipulator",)
ALL = (*MANIPULATORS, *LEGGED, "biped", "module_chain", *WHEELED, *MOBILE, *LEGGED_ARM)


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """A structural parameter: its dimension (adron.units) and per-type defaults (SI)."""

    name: str
    dimension: str
    doc: str
    defaults: Mapping[str, float | None]

    @property
    def range(self) -> tuple[str, str]:
        """(low, high) with units, inclusive: where designs make sense (RANGES)."""
        return RANGES[self.name][0], RANGES[self.name][1]

    @property
    def range_why(self) -> str:
        """Why the range stops where it does (shown when a value is refused)."""
        return RANGES[self.name][2]

    def applies_to(self, structure: str) -> bool:
        return structure in self.defaults


#: The joint counts ``--param dof`` takes (the part kinds' [serial] rows may offer more).
DOF_RANGE = (3, 7)


def parse_dof(text: str) -> int:
    """The joint count of ``--param dof=TEXT``; InputError (exit 2) naming the range."""
    try:
        n = int(str(text).strip())
    except ValueError:
        n = -1
    lo, hi = DOF_RANGE
    if not lo <= n <= hi:
        raise InputError(
            f"--param dof={text}: a serial arm has {lo} to {hi} joints besides its gripper "
            "(a whole number)"
        )
    return n


def _for(types: tuple[str, ...], value: float | None) -> dict[str, float | None]:
    return dict.fromkeys(types, value)


#: Ranges of the physical parameters: (low, high, why). The module system bounds them:
#: modules have a 50 mm dovetail face and printed links of 40-200 mm (the shipped catalog's
#: passive section) driven by hobby servos of at most ~2 N m and ~10 rad/s. The bounds are
#: wide (user catalogs may have other modules; sizing refuses what a catalog cannot meet,
#: with exit 1), but exclude values no module robot can mean: a 1e-300 m reach, a load
#: platform smaller than one module face, a 1 mm humanoid, a 1e308 kg payload.
RANGES: dict[str, tuple[str, str, str]] = {
    # The strongest shipped servo holds ~5 kg at the shortest link; 10x that leaves room
    # for stronger catalogs.
    "payload": ("0 kg", "50 kg", "10x what the strongest hobby servo holds at a 4 cm link"),
    # At least one module face; at most ten of the longest printable links.
    "reach": ("5 cm", "2 m", "one 50 mm module face to ten 200 mm printed links"),
    # Slower than a millimetre a second is standing still; the fastest servo (~10 rad/s)
    # on the largest wheel (10 cm) gives ~1 m/s, 10x that leaves room.
    "speed": ("1 mm/s", "10 m/s", "from standing still to 10x a fast servo on a large wheel"),
    # A printer's layer is ~0.25 mm; the longest legs of printed links are 2 x 200 mm.
    "obstacle_height": ("1 mm", "1 m", "a few printed layers to far above any printed leg"),
    # One module face (50 mm x 50 mm) to a square metre.
    "load_area": ("25 cm^2", "1 m^2", "one 50 mm module face to a square metre"),
    # One module face tall to ten of the longest printable links.
    "height": ("5 cm", "2 m", "one 50 mm module face to ten 200 mm printed links"),
    # A printed part is not accurate below 0.01 mm; 10 cm bends a link out of shape.
    "deflection": ("0.01 mm", "10 cm", "printing accuracy to a link bent out of shape"),
    # A rubber tyre's friction coefficient is about 1: on a steeper slope the wheels slip.
    "slope": ("0 deg", "45 deg", "a tyre's grip (friction ~1) ends at 45 deg"),
    # The part kinds' serial arms (synth/reasoning/composition.py): a yaw and two pitch
    # joints position what the gripper holds; a wrist of three more orients it; a seventh
    # is redundant.
    "dof": ("3", "7", "three joints position a gripper, six orient it, a seventh is redundant"),
}


PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec(
        "payload",
        "mass",
        "mass carried: at the gripper (manipulators), on the trunk (mobile robots)",
        {
            **_for(MANIPULATORS, 0.2),
            **_for(MOBILE, 0.2),
            **_for((*LEGGED, *LEGGED_ARM), 0.1),
            "biped": 0.05,
            "module_chain": 0.0,
            **_for(WHEELED, 0.5),
        },
    ),
    ParamSpec(
        "reach",
        "length",
        "horizontal reach from the shoulder axis to the gripper",
        _for((*MANIPULATORS, *MOBILE, *LEGGED_ARM), 0.25),
    ),
    ParamSpec(
        "speed",
        "speed",
        "tip speed (manipulators) or travel speed (mobile robots)",
        {
            **_for(MANIPULATORS, 0.2),
            **_for(MOBILE, 0.2),
            **_for((*LEGGED, *LEGGED_ARM), 0.05),
            "biped": 0.05,
            **_for(WHEELED, 0.3),
        },
    ),
    ParamSpec(
        "obstacle_height",
        "length",
        "height of the obstacles the legs must step over",
        _for((*LEGGED, *LEGGED_ARM), 0.03),
    ),
    ParamSpec(
        "load_area", "area", "area of the load platform (L1 x L2)", _for((*WHEELED, *MOBILE), 0.03)
    ),
    ParamSpec("height", "length", "standing height of the humanoid", {"biped": 0.40}),
    ParamSpec(
        "deflection", "length", "allowed tip deflection of each printed link", _for(ALL, None)
    ),
    ParamSpec(
        "slope",
        "angle",
        "steepest slope to climb while accelerating",
        _for((*WHEELED, *MOBILE), None),
    ),
    # not a sizing parameter: it composes the arm (synth/reasoning/composition.py) and picks it
    ParamSpec("dof", "count", "joints of a serial arm besides its gripper (3 to 7)", {}),
)
BY_NAME = {p.name: p for p in PARAMS}


def bounds(spec: ParamSpec) -> tuple[float, float]:
    """The (low, high) range of ``spec`` in SI units."""

    low, high = spec.range
    where = f"synth/params.py: range of {spec.name}"
    return (
        quantity(low, spec.dimension, where, allow_zero=True),
        quantity(high, spec.dimension, where),
    )


def lowest(name: str, value: float) -> float:
    """``value`` (SI), raised to parameter ``name``'s range where it is below it: the
    smallest value a search over the parameter may try (a value out of the range is no
    design at all: its record is refused)."""
    spec = BY_NAME.get(name)
    return value if spec is None else max(value, bounds(spec)[0])


def check_range(spec: ParamSpec, value: float, text: str) -> None:
    """InputError (exit 2) when ``value`` (SI, read from ``text``) is outside ``spec``'s range."""
    low, high = bounds(spec)
    if not low <= value <= high:
        raise InputError(
            f"--param {spec.name}={text}: outside {spec.range[0]} to {spec.range[1]}, the "
            f"range where designs make sense ({spec.range_why})"
        )


def exceeded_limits(
    candidate,
    limits: Iterable[tuple[tuple, str]],
    given: Mapping[str, float],
    defaults=None,
) -> list[str]:
    """The ontology's ``structuralLimit`` facts ((type, name, quantity), "file:line:col") on
    ``candidate``'s class or any robot class above it that its parameters exceed (the given
    values, else ``defaults``: its structure's, a mapping or a function that gives it, asked
    only when a limit applies), as readable phrases."""

    out = []
    for (rtype, name, text), where in limits:
        if rtype not in candidate.ancestors:
            continue
        if name not in BY_NAME:
            raise OntologyError(
                f"{where}: structuralLimit names {name!r}, not a parameter "
                f"(known: {', '.join(sorted(BY_NAME))})"
            )
        spec = BY_NAME[name]
        if callable(defaults):
            defaults = defaults()
        value = given.get(name, (defaults or {}).get(name))
        if value is None:
            continue
        limit = quantity(text, spec.dimension, f"{where}: structuralLimit", allow_zero=True)
        if value > limit:
            out.append(f"{name} above {text}")
    return out


def parse_structural(items: Mapping[str, str]) -> dict[str, float]:
    """``{"reach": "30cm"}`` -> ``{"reach": 0.3}``; raises InputError for a wrong unit or a
    value outside the parameter's range (RANGES)."""

    out = {}
    for name, text in items.items():
        spec = BY_NAME[name]
        if spec.dimension == "count":
            out[name] = float(parse_dof(text))
            continue
        zero_ok = name in ("payload", "slope")
        out[name] = quantity(text, spec.dimension, f"--param {name}", allow_zero=zero_ok)
        check_range(spec, out[name], text)
    return out


def structure_defaults(
    structure: str, overrides: Mapping[str, float] | None = None
) -> dict[str, float | None]:
    """The defaults (SI; None: from the catalog) of the parameters a structure uses, with
    the ontology's ``defaultParameter`` values (``overrides``) over them."""
    out = {s.name: s.defaults[structure] for s in PARAMS if s.applies_to(structure)}
    out.update({k: v for k, v in (overrides or {}).items() if k in out})
    return out


def ontology_defaults(kb, lineage) -> dict[str, float]:
    """The ``(defaultParameter TYPE "name" "quantity")`` values for a type whose classes,
    nearest first, are ``lineage``: the nearest class's wins; OntologyError for a name
    that is no parameter or a quantity of the wrong dimension."""

    rank = {c: i for i, c in enumerate(lineage)}
    best: dict[str, tuple[int, float]] = {}
    for args, where in kb.translation.located("defaultParameter"):
        if len(args) != 3 or args[0] not in rank:
            continue
        name, text = args[1], args[2]
        if name not in BY_NAME:
            raise OntologyError(
                f"{where}: defaultParameter names {name!r}, not a parameter "
                f"(known: {', '.join(sorted(BY_NAME))})"
            )
        spec = BY_NAME[name]
        if spec.dimension == "count":  # dof: a whole number of joints, as --param dof
            try:
                value = float(parse_dof(str(text)))
            except InputError as e:
                raise OntologyError(f"{where}: defaultParameter {e}") from None
        else:
            value = quantity(text, spec.dimension, f"{where}: defaultParameter", allow_zero=True)
        if (
            name in RANGES and spec.dimension != "count"
        ):  # the range of --param NAME holds for the ontology's default
            low, high = bounds(spec)
            if not low <= value <= high:
                raise OntologyError(
                    f"{where}: defaultParameter {name} {text!r}: outside {spec.range[0]} to "
                    f"{spec.range[1]}, the range where designs make sense ({spec.range_why}; "
                    f"the range of --param {name})"
                )
        if name not in best or rank[args[0]] < best[name][0]:
            best[name] = (rank[args[0]], value)
    return {k: v for k, (_, v) in best.items()}


def resolve(
    structure: str,
    given: Mapping[str, float],
    design_defaults: Mapping[str, float],
    overrides: Mapping[str, float] | None = None,
) -> tuple[dict[str, float], tuple[str, ...]]:
    """The parameters of a design of ``structure``: given values over defaults (the
    ontology's ``overrides`` over the structure's).

    Returns (values, ignored): the names given that this structure does not use.
    ``design_defaults`` supplies the catalog-driven defaults (``deflection``, ``slope``).
    """
    values: dict[str, float] = {}
    defaults = structure_defaults(structure, overrides)
    for spec in PARAMS:
        if not spec.applies_to(structure):
            continue
        if spec.name in given:
            values[spec.name] = given[spec.name]
        else:
            default = defaults[spec.name]
            values[spec.name] = design_defaults[spec.name] if default is None else default
    ignored = tuple(
        sorted(n for n in given if n not in values and n in BY_NAME and BY_NAME[n].defaults)
    )
    for name, v in values.items():
        if v < 0 or (v == 0 and name not in ("payload", "slope")):
            raise InputError(f"--param {name}: must be positive")
    return values, ignored
