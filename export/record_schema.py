"""The schema of a design record (``design.json``, ``parmor design --json``).

Only the fields the readers use (``simulate``, ``run``, ``blocks``, ``ros``, the
verification and the bundle's guide) are typed here; every other key, and every key of
the sub-objects others extend (``verified``, ``notes``, ``power`` ...), passes as it is. A
record of a newer ``format`` than :data:`RECORD_FORMAT` is refused naming the field (a
record without one is of the current format: records written before it had none).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import PlainValidator, WithJsonSchema, field_validator

from adron.schema import (
    MAX_MASS_KG,
    At,
    Length,
    Mass,
    Name,
    Open,
    StrictBool,
    described,
    json_schema,
    number,
    validate,
)
from export.record import RECORD_FORMAT  # the number, kept with the writer


def _non_negative(v: Any) -> float:
    f = number(v)
    if f < 0:
        raise ValueError("out of range: must be at least 0")
    return f


def _count(v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 10_000:
        raise ValueError("not a count (a whole number from 0 to 10000)")
    return v


Finite = Annotated[float, PlainValidator(number), WithJsonSchema({"type": "number"})]
NonNegative = Annotated[
    float, PlainValidator(_non_negative), WithJsonSchema({"type": "number", "minimum": 0})
]


def _positive(v: Any) -> float:
    f = number(v)
    if f <= 0:
        raise ValueError("out of range: must be more than 0")
    return f


Positive = Annotated[
    float, PlainValidator(_positive), WithJsonSchema({"type": "number", "exclusiveMinimum": 0})
]
Count = Annotated[
    int,
    PlainValidator(_count),
    WithJsonSchema({"type": "integer", "minimum": 0, "maximum": 10_000}),
]


class HeldByRecord(Open):
    """A body that holds (part of) the payload."""

    body: Name
    mass_kg: Mass = 0.0
    position_m: Annotated[list[Finite], described(doc="in the body's frame (m)")] = [
        0.0,
        0.0,
        0.0,
    ]

    @field_validator("position_m")
    @classmethod
    def _three(cls, v: list[float]) -> list[float]:
        if len(v) != 3:
            raise ValueError("must be a list of 3 numbers (m)")
        return v


class PayloadRecord(Open):
    """The load the design was sized and simulated with."""

    mass_kg: Mass | None = None
    held_by: list[HeldByRecord] = []
    in_models: StrictBool = False


class JointRecord(Open):
    """One actuated joint of the design."""

    name: Name
    no_load_speed_rad_s: Positive = described(doc="its actuator's (a wheel's top speed)")
    actuator_torque_Nm: NonNegative | None = None


class LinkRecord(Open):
    name: Name


class ModuleRecord(Open):
    """A module of the design (its class; a sensor module gives the controller a sensor)."""

    kind: Name
    count: Count | None = None


class VerifiedRecord(Open):
    """The verification's outcome (others add keys to it)."""

    simulated: StrictBool | None = None
    robust: dict[str, Any] | None = None
    accepted_unsimulated: list[Name] | None = None


class DesignRecord(Open):
    """A design record (``design.json``): the fields parmor's readers use."""

    format: Any = described(
        RECORD_FORMAT, f"the record's format (this parmor writes and reads {RECORD_FORMAT})"
    )
    status: Name | None = None
    robot_type: Name | None = None
    template: Name | None = described(None, "the kinematic template (None: conceptual)")
    body_plan: dict[str, Any] | None = None
    lengths_m: dict[Name, Length] = {}
    dof: Count | None = None
    wheel_radius_m: Length | None = None
    params: dict[Name, Any] = {}
    abilities: list[Name] = []
    ability_ancestors: dict[Name, list[Name]] = {}
    joints: list[JointRecord] = []
    passive_joints: list[Name] | None = None
    links: list[LinkRecord] = []
    modules: list[ModuleRecord] = []
    mass_kg: NonNegative | None = None
    loaded_mass_kg: NonNegative | None = None
    calibration: dict[Name, Finite] | None = None
    feedback_gains: dict[Name, Positive] | None = described(
        None, "behaviour -> the scale of its feedback loop's gains (robust verification)"
    )
    power: dict[str, Any] | None = None
    bus: dict[str, Any] | None = None
    payload: PayloadRecord | None = None
    verified: VerifiedRecord | None = None
    notes: list[Any] | dict[str, Any] | None = None

    @field_validator("body_plan")
    @classmethod
    def _plan(cls, v: dict[str, Any] | None) -> dict[str, Any] | None:
        if v is not None:
            from kinematics.bodyplan import BodyPlan

            BodyPlan.from_dict(v)  # ValueError naming the part: the message
        return v

    @field_validator("format", mode="plain")
    @classmethod
    def _format(cls, v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise At("", f"not a record format (this parmor reads format {RECORD_FORMAT})", v)
        if v != RECORD_FORMAT:
            raise At(
                "",
                f"a record of format {v}: this parmor reads format {RECORD_FORMAT} "
                "(written by another version of parmor?)",
                v,
            )
        return v


def check_record(record: Any, source: str) -> DesignRecord:
    """``record`` (a parsed ``design.json``) checked against :class:`DesignRecord`;
    InputError naming ``source``, the key and the value otherwise."""
    if not isinstance(record, dict):
        from adron.errors import InputError

        raise InputError(f"{source}: not a design record (expected an object)")
    return validate(DesignRecord, record, source)


def schema() -> dict:
    return json_schema(
        DesignRecord,
        "design-record",
        "A parmor design record (design.json): the fields parmor's readers use; "
        f"payload masses up to {MAX_MASS_KG:g} kg.",
    )
