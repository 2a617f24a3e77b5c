"""The schema of a design record (``design.json``, ``parmor design --json``).

Only the fields the readers use (``simulate``, ``run``, ``blocks``, ``ros``, the
verification and the bundle's guide) are typed here; every other key, and every key of
the sub-objects others extend (``verified``, ``notes``, ``power`` ...), passes as it is. A
record of a newer ``format`` than :data:`RECORD_FORMAT` is refused naming the field (a
record without one is of the current format: records written before it had none).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import PlainValidator, WithJsonSchema, field_validator, model_validator

from adron.errors import InputError
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
    within,
)
from export.record import RECORD_FORMAT  # the number, kept with the writer
from kinematics.bodyplan import BodyPlan
from synth.params import BY_NAME, bounds


def _count(v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 10_000:
        raise ValueError("not a count (a whole number from 0 to 10000)")
    return v


Finite = Annotated[float, PlainValidator(number), WithJsonSchema({"type": "number"})]
Count = Annotated[
    int,
    PlainValidator(_count),
    WithJsonSchema({"type": "integer", "minimum": 0, "maximum": 10_000}),
]


#: a robot's mass: a milligram (the catalog facts' unit) to a tonne (far above what a bus
#: of 253 modules and a 50 kg payload weigh)
RobotMass = within(1e-6, 1000.0, "kg", "a milligram to a tonne")
#: an actuator's torque: the catalog's bounds (1 mN*m, its facts' unit, to 1000 N*m)
Torque = within(1e-3, 1000.0, "N*m", "the catalog's bounds")
#: an actuator's no-load speed: the catalog's bounds (1 mrad/s to 1000 rad/s)
Speed = within(1e-3, 1000.0, "rad/s", "the catalog's bounds")
#: a feedback loop's gain scale (the robust loop tries x2 and x0.5 of the default)
GainScale = within(1e-3, 1000.0, "x the default", "a loop's gains scaled")
#: a behaviour's pace chosen by the robust verification, in its pace parameter's unit
#: (m/s, a snake's Hz, a humanoid's step m): more than nothing, far below any servo's reach
Pace = within(1e-6, 1000.0, "its pace parameter's unit", "a behaviour's pace")


def _param(v: Any) -> float | str:
    if isinstance(v, str):
        if len(v) > 200:
            raise ValueError("longer than 200 characters")
        return v
    return number(v)


#: a design parameter's value: a number (SI) or a choice
ParamValue = Annotated[
    float | str,
    PlainValidator(_param),
    WithJsonSchema({"anyOf": [{"type": "number"}, {"type": "string", "maxLength": 200}]}),
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
    no_load_speed_rad_s: Speed = described(doc="its actuator's (a wheel's top speed)")
    actuator_torque_Nm: Torque | None = None


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
    params: dict[Name, ParamValue] = described(
        {}, "the design's parameters (SI), each within the range of --param of its name"
    )
    abilities: list[Name] = []
    ability_ancestors: dict[Name, list[Name]] = {}
    joints: list[JointRecord] = []
    passive_joints: list[Name] | None = None
    links: list[LinkRecord] = []
    modules: list[ModuleRecord] = []
    mass_kg: RobotMass | None = None
    loaded_mass_kg: RobotMass | None = described(None, "with the payload: at least mass_kg")
    calibration: dict[Name, Finite] | None = None
    feedback_gains: dict[Name, GainScale] | None = described(
        None, "behaviour -> the scale of its feedback loop's gains (robust verification)"
    )
    paces: dict[Name, Pace] | None = described(
        None,
        "behaviour -> the default of its pace parameter the robust verification chose "
        "(the servos' command hold saturated it at the design's own)",
    )
    power: dict[str, Any] | None = None
    bus: dict[str, Any] | None = None
    payload: PayloadRecord | None = None
    verified: VerifiedRecord | None = None
    notes: list[Any] | dict[str, Any] | None = None

    @field_validator("params")
    @classmethod
    def _ranges(cls, v: dict[str, float | str]) -> dict[str, float | str]:
        for name, x in v.items():
            spec = BY_NAME.get(name)
            if spec is None or isinstance(x, str):
                continue
            low, high = bounds(spec)
            slack = 1e-9 * max(abs(low), abs(high))  # the record's 9 significant digits
            if not low - slack <= x <= high + slack:
                raise At(
                    name,
                    f"outside {spec.range[0]} to {spec.range[1]} (the range of --param {name})",
                    x,
                )
        return v

    @model_validator(mode="after")
    def _loaded(self) -> DesignRecord:
        mass, loaded = self.mass_kg, self.loaded_mass_kg
        if mass is not None and loaded is not None and loaded < mass * (1 - 1e-9):
            raise At(
                "loaded_mass_kg",
                f"below mass_kg = {mass:g} (the robot without its payload)",
                loaded,
            )
        return self

    @field_validator("body_plan")
    @classmethod
    def _plan(cls, v: dict[str, Any] | None) -> dict[str, Any] | None:
        if v is not None:
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
        raise InputError(f"{source}: not a design record (expected an object)")
    return validate(DesignRecord, record, source)


def schema() -> dict:
    return json_schema(
        DesignRecord,
        "design-record",
        "A parmor design record (design.json): the fields parmor's readers use; "
        f"payload masses up to {MAX_MASS_KG:g} kg.",
    )
