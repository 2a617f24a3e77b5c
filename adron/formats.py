"""The registry of every user file format with a schema (:func:`formats`, :func:`check`,
:func:`schemas`, which ``python -m adron.write_schemas`` writes into ``adron/schemas/``),
and the schemas of the formats that have no module of their own: studies
(``synth/commands/sweep.py``), regression suites (``synth/commands/regress.py``) and
perturbation tables (``synth/verification/perturb.py``, a catalog's ``[perturbation]``).

The other formats' models live beside their readers: module catalogs in
``adron/catalog_schema.py``, part kinds in ``kinematics/partkinds.py``, design records in
``export/record_schema.py``, programs in ``program/script.py`` and the ``.parmor`` list in
``export/manifest.py``. Each reader validates a file with its model before it uses it;
the model holds the rules (types, ranges, the rules that tie keys together) and the
documentation, and what no schema of one file can say (another file, the knowledge base,
the design a program runs on) is the reader's, said in its docstring.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import Field, PlainValidator, WithJsonSchema, create_model, model_validator

from adron.schema import (
    MAX_NAME,
    At,
    Closed,
    Name,
    StrictBool,
    described,
    json_schema,
    number,
    validate,
    within,
)
from kinematics.partkinds import PartKindsFile

MAX_QUANTITY = 100


def _quantity(v: Any) -> float | str:
    """A quantity: a number (a ratio), or a number with its unit (``"34 g"``)."""
    if isinstance(v, str):
        text = v.strip()
        if not text or len(text) > MAX_QUANTITY or not (text[0].isdigit() or text[0] in "+-."):
            raise ValueError('not a quantity (a number with its unit, such as "34 g")')
        return v
    return number(v)


Quantity = Annotated[
    float | str,
    PlainValidator(_quantity),
    WithJsonSchema(
        {
            "anyOf": [
                {"type": "number"},
                {"type": "string", "maxLength": MAX_QUANTITY, "pattern": "^\\s*[-+.0-9]"},
            ],
            "description": 'a number with its unit ("34 g", "1.8 kgf*cm") or a bare ratio',
        }
    ),
]
Size = Annotated[list[Quantity], Field(min_length=3, max_length=3)]


def _integer(low: int, high: int):
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
            raise ValueError(f"not a whole number from {low} to {high}")
        return v

    return Annotated[
        int,
        PlainValidator(check),
        WithJsonSchema({"type": "integer", "minimum": low, "maximum": high}),
    ]


Cost = within(0.0, 100_000.0)
Ratio = within(0.0, 1e6)


# ---- perturbation tables --------------------------------------------------------------------


class Draw(Closed):
    stream: _integer(0, 2**63 - 1) = described(doc="the seed stream")


class MassSpread(Closed):
    spread: within(0.0, 0.9) = described(doc="each body's mass scaled by 1 + u, |u| <= spread")


class Floor(Closed):
    friction_low: within(0.0, 10.0)
    friction_high: within(0.0, 10.0)
    max_slope: Quantity


class BusLatency(Closed):
    latency_low: Quantity
    latency_high: Quantity
    control_period: Quantity


class Battery(Closed):
    supply: Literal["regulated", "direct"]
    nominal_per_cell: Quantity
    cutoff_per_cell: Quantity
    rail_voltage: Quantity
    dropout: Quantity
    rail_resistance_ohm: within(0.0, 10.0)
    rated_voltage: Quantity


class ServoEntry(Closed):
    gears: Name
    deadband: Quantity


Backlash = Annotated[list[Quantity], Field(min_length=2, max_length=2)]


class Compliance(Closed):
    scale: within(0.0, 1e6)


class Imu(Closed):
    """The simulated IMU's noise and bias (a design whose model has one)."""

    gyro_noise: Quantity
    gyro_bias: Quantity
    accel_noise: Quantity


class Infrared(Closed):
    """The line sensors' readings in a perturbed run (program/sensing.py)."""

    edge_offset: Quantity
    edge_jitter: Quantity


class Ultrasonic(Closed):
    """The forward ranger's readings in a perturbed run (program/sensing.py)."""

    noise: Quantity
    resolution: Quantity
    scale: within(0.0, 0.5)


class Acceptance(Closed):
    share: within(0.0, 1.0)
    default_k: _integer(0, 1000)


class PerturbationTable(Closed):
    """The ranges a robust verification draws from (synth/verification/perturb.toml)."""

    draw: Draw
    mass: MassSpread
    floor: Floor
    bus: BusLatency
    battery: Battery
    gears: dict[Name, Backlash] = described(doc="backlash [low, high] by gear material")
    servo: dict[Name, ServoEntry | Quantity] = described(
        doc="pulse_span, then per actuator model (and 'default'): gears and dead band"
    )
    compliance: Compliance
    imu: Imu
    infrared: Infrared
    ultrasonic: Ultrasonic
    acceptance: Acceptance


def _partial(model: type[Closed]) -> type[Closed]:
    """``model`` with every field optional (a catalog overrides some keys)."""
    from adron.catalog_schema import optional

    fields = {n: (optional(f), None) for n, f in model.model_fields.items()}
    return create_model(f"{model.__name__}Override", __base__=Closed, **fields)


class PerturbationOverrides(Closed):
    """A catalog's ``[perturbation]``: any keys of the perturbation table."""

    draw: _partial(Draw) | None = None
    mass: _partial(MassSpread) | None = None
    floor: _partial(Floor) | None = None
    bus: _partial(BusLatency) | None = None
    battery: _partial(Battery) | None = None
    gears: dict[Name, Backlash] | None = None
    servo: dict[Name, ServoEntry | Quantity] | None = None
    compliance: _partial(Compliance) | None = None
    imu: _partial(Imu) | None = None
    infrared: _partial(Infrared) | None = None
    ultrasonic: _partial(Ultrasonic) | None = None
    acceptance: _partial(Acceptance) | None = None


# ---- studies and regression suites --------------------------------------------------------

Ability = Name
#: the answers --answer takes (any case)
ANSWERS = ("yes", "no", "y", "n", "true", "false")


def _answer(v: Any) -> str:
    if not isinstance(v, str) or v.strip().lower() not in ANSWERS:
        raise ValueError("not yes or no (y, n, true, false; any case), as --answer takes")
    return v


#: an answer: yes or no, as ``--answer`` takes it
Answer = Annotated[
    str,
    PlainValidator(_answer),
    WithJsonSchema(
        {
            "type": "string",
            "pattern": "^\\s*([Yy]([Ee][Ss])?|[Nn][Oo]?|[Tt][Rr][Uu][Ee]"
            "|[Ff][Aa][Ll][Ss][Ee])\\s*$",
            "description": "yes or no (y, n, true, false; any case), as --answer takes",
        }
    ),
]
#: a parameter's value as ``--param`` takes it, with its unit (``"0.2kg"``)
ParamValue = Annotated[str, Field(max_length=MAX_NAME)]
#: the most perturbed runs per behaviour (``--robustness``): the same number as
#: synth.limits.MAX_ROBUSTNESS, which the command line reads without importing pydantic
#: (tests/adron/test_schema.py holds the two together)
MAX_ROBUSTNESS = 64
#: The most requests a study may expand to: counted before anything is expanded, a larger
#: study is refused (exit 2). Checking a request costs about 1 ms and designing one with
#: simulation seconds to a minute, so 10,000 is already hours of a 2-core machine's work
#: (a day's on a small Ray cluster); a larger range is split into several studies.
MAX_STUDY_REQUESTS = 10_000


class Query(Closed):
    """A regression suite's query: a design request and its expected outcome's name."""

    name: Name = described(doc="the query's name (unique in the suite)")
    abilities: list[Ability] = []
    answers: dict[Ability, Answer] = {}
    params: dict[Name, ParamValue] = described({}, "name -> value with its unit, as --param")


class SuiteFile(Closed):
    """A regression suite (``parmor regress SUITE.toml``).

    What the schema cannot say is checked by the reader (synth/commands/regress.py): the files
    ``ontology``, ``rules`` and ``catalog`` name exist inside the suite's folder, and each
    query's abilities, answers and parameters are the knowledge base's."""

    ontology: list[Name] = described([], "KIF files, relative to the suite")
    rules: list[Name] = described([], "ASP rule files, relative to the suite")
    catalog: Name | None = described(None, "a shipped catalog's name or a file")
    conceptual: StrictBool = False
    verify: StrictBool = described(False, "simulate every behaviour of each design")
    query: Annotated[list[Query], Field(min_length=1)] = described(
        doc="the queries, each designed and compared"
    )

    @model_validator(mode="after")
    def _unique(self) -> SuiteFile:
        seen: dict[str, int] = {}
        for i, q in enumerate(self.query):
            if q.name in seen:
                raise At(f"query[{i}].name", f"repeats the name of query[{seen[q.name]}]", q.name)
            seen[q.name] = i
        return self


def _values(v: Any) -> str | list[str]:
    """A study's ``params`` entry: a value, or a non-empty list of distinct values."""
    if isinstance(v, list) and v and all(isinstance(x, str) for x in v):
        seen: dict[str, int] = {}
        for i, x in enumerate(v):
            if len(x) > MAX_NAME:
                raise At(f"[{i}]", f"longer than {MAX_NAME} characters", x)
            if x in seen:
                raise At(f"[{i}]", f"listed twice (also [{seen[x]}])", x)
            seen[x] = i
        return list(v)
    if isinstance(v, str) and len(v) <= MAX_NAME:
        return v
    raise ValueError('not a value with its unit ("0.2kg") or a non-empty list of them')


Values = Annotated[
    str | list[str],
    PlainValidator(_values),
    WithJsonSchema(
        {
            "anyOf": [
                {"type": "string", "maxLength": MAX_NAME},
                {
                    "type": "array",
                    "items": {"type": "string", "maxLength": MAX_NAME},
                    "minItems": 1,
                    "uniqueItems": True,
                },
            ],
            "description": 'a value with its unit ("0.2kg"), or a list of them: one request '
            "for each",
        }
    ),
]


class StudyRequest(Closed):
    """A study's request: lists of parameter values expand into their product."""

    name: Name | None = described(None, "default: its abilities joined by '+'")
    abilities: Annotated[list[Ability], Field(min_length=1)]
    answers: dict[Ability, Answer] = {}
    params: dict[Name, Values] = described(
        {}, "name -> a value with its unit, or a list of values (their product is studied)"
    )


class StudyFile(Closed):
    """A parameter study (``parmor sweep STUDY.toml``).

    Beyond what the JSON Schema says, the model holds the study's size: its requests,
    counted from the lists' lengths before anything is expanded, are at most
    :data:`MAX_STUDY_REQUESTS`. What no schema can say is checked by the reader
    (synth/commands/sweep.py): the files it names exist inside its folder, and each request's
    abilities, answers and parameters are the knowledge base's (and no request is given
    twice, its values compared in SI units)."""

    ontology: list[Name] = described([], "KIF files, relative to the study")
    rules: list[Name] = described([], "ASP rule files, relative to the study")
    catalog: Name | None = described(None, "a shipped catalog's name or a file")
    robustness: _integer(0, MAX_ROBUSTNESS) = described(
        0, "perturbed runs per behaviour (as parmor design --robustness)"
    )
    request: Annotated[list[StudyRequest], Field(min_length=1)]

    @model_validator(mode="after")
    def _size(self) -> StudyFile:
        sizes = [
            _study_size([len(v) for v in r.params.values() if isinstance(v, list)])
            for r in self.request
        ]
        total = _total(sizes)
        if total is not None and total <= MAX_STUDY_REQUESTS:
            return self
        k = max(range(len(sizes)), key=lambda i: sizes[i][1])
        lists = " x ".join(
            f"{name} {len(v)}" for name, v in self.request[k].params.items() if isinstance(v, list)
        )
        raise At(
            "request",
            f"the study expands to {_size_text(sizes)} requests, more than the "
            f"{MAX_STUDY_REQUESTS:,} a study may have (the most from request[{k}]: params "
            f"{lists} = {_size_text([sizes[k]])}); split it into smaller studies",
        )


#: Sizes up to this are written exactly in messages, larger ones as a power of ten.
_EXACT = 10**15


def _study_size(lengths: list[int]) -> tuple[int | None, float]:
    """(the product of ``lengths`` when at most :data:`_EXACT`, else None; its log10),
    without making a huge integer (a 1 KB study can name 10^300 requests)."""
    if 0 in lengths:
        return 0, -math.inf
    lg = sum(math.log10(n) for n in lengths)
    return (math.prod(lengths) if lg <= 15.5 else None), lg


def _total(sizes: list[tuple[int | None, float]]) -> int | None:
    """The sum of ``sizes`` (see :func:`_study_size`), None past :data:`_EXACT`."""
    total = 0
    for n, _ in sizes:
        if n is None or total + n > _EXACT:
            return None
        total += n
    return total


def _size_text(sizes: list[tuple[int | None, float]]) -> str:
    """``1,000,000``, or ``about 10^40`` past :data:`_EXACT`, for the sum of ``sizes``."""
    total = _total(sizes)
    if total is not None:
        return f"{total:,}"
    return f"about 10^{int(max(lg for _, lg in sizes))}"


#: format name -> (model, description) of every user file format with a schema
def formats() -> dict[str, tuple[type, str]]:
    from adron.catalog_schema import CatalogFile
    from export.manifest import Manifest
    from export.record_schema import DesignRecord
    from program.script import ProgramFile

    return {
        "partkinds": (PartKindsFile, "Part kinds (kinematics/partkinds.toml, --parts FILE.toml)"),
        "catalog": (CatalogFile, "A module catalog (adron/catalog.toml, --catalog FILE)"),
        "perturb": (PerturbationTable, "Perturbation ranges (synth/verification/perturb.toml)"),
        "study": (StudyFile, "A parameter study (parmor sweep STUDY.toml)"),
        "suite": (SuiteFile, "A regression suite (parmor regress SUITE.toml)"),
        "design-record": (DesignRecord, "A design record (design.json)"),
        "program": (ProgramFile, "A program (parmor run PROGRAM.json DIR, the block page's)"),
        "manifest": (Manifest, "The files parmor wrote into a folder (.parmor)"),
    }


def schemas() -> dict[str, dict]:
    """format name -> its JSON Schema."""
    from adron import catalog_schema

    out = {name: json_schema(model, name, doc) for name, (model, doc) in formats().items()}
    out["catalog"] = catalog_schema.json_schema()  # complete, or extending another
    return out


def check(name: str, data: Any, source: str) -> Any:
    """``data`` (a parsed file of the format ``name``) checked against its schema;
    InputError naming ``source``, the key and the value."""
    return validate(formats()[name][0], data, source)
