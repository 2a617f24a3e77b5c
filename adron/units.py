"""Physical quantities written with units ("30 cm", "1.8 kgf*cm", "60 rpm") -> SI floats.

Every value that reaches parmor from a file or the command line carries its unit; inside,
everything is an SI float (metres, kilograms, seconds, radians, ...). A bare number is
refused for any dimension but ``dimensionless``: "30" for a length could be millimetres or
centimetres, and guessing wrong builds the wrong robot.

The unit text is read by a small strict grammar of our own (``name[exponent]`` factors
joined by ``*``, ``·``, ``/`` or a space; exponents as ``**2``, ``^2``, ``²`` or the ``cm2``
shorthand for 2 and 3); pint only looks up single unit names and converts. That keeps
pint's lenient expression parser (which reads "m@" as metres) away from user text.

pint is imported lazily, on first use, so that importing this module costs nothing.
"""

from __future__ import annotations

import functools
import math
import re
from typing import TYPE_CHECKING, Any, NamedTuple

from adron.errors import InputError

if TYPE_CHECKING:
    import pint

__all__ = ["DIMENSIONS", "Dimension", "quantity", "registry"]


class Dimension(NamedTuple):
    """A kind of quantity parmor reads.

    ``dimensionality`` is pint's dimensionality of the SI unit (as text); ``si_unit`` is
    the unit the returned floats are in (pint syntax, also shown in messages);
    ``example`` is shown in error messages; ``angle_power`` is the power of the radian
    the unit must carry (pint treats angles as dimensionless, so "10 Hz" would otherwise
    pass as an angular speed of 10 rad/s).
    """

    dimensionality: str
    si_unit: str
    example: str
    angle_power: int = 0


DIMENSIONS: dict[str, Dimension] = {
    "length": Dimension("[length]", "m", "30 cm"),
    "area": Dimension("[length] ** 2", "m**2", "300 cm^2"),
    "volume": Dimension("[length] ** 3", "m**3", "12 cm^3"),
    "volume_flow": Dimension("[length] ** 3 / [time]", "m**3/s", "12 mm^3/s"),
    "mass": Dimension("[mass]", "kg", "0.5 kg"),
    "force": Dimension("[mass] * [length] / [time] ** 2", "N", "5 N"),
    "torque": Dimension("[mass] * [length] ** 2 / [time] ** 2", "N*m", "1.8 kgf*cm"),
    "speed": Dimension("[length] / [time]", "m/s", "0.2 m/s"),
    "acceleration": Dimension("[length] / [time] ** 2", "m/s**2", "9.81 m/s^2"),
    "angle": Dimension("dimensionless", "rad", "10 deg", angle_power=1),
    "angular_speed": Dimension("1 / [time]", "rad/s", "60 rpm", angle_power=1),
    "angular_acceleration": Dimension("1 / [time] ** 2", "rad/s**2", "3 rad/s^2", 1),
    "time": Dimension("[time]", "s", "2 s"),
    "current": Dimension("[current]", "A", "1.5 A"),
    "voltage": Dimension("[mass] * [length] ** 2 / [time] ** 3 / [current]", "V", "11.1 V"),
    # SI: coulombs (1 Ah = 3600 C); battery capacities are usually written in mAh.
    "charge": Dimension("[current] * [time]", "C", "1500 mAh"),
    # Moduli and strengths.
    "pressure": Dimension("[mass] / [length] / [time] ** 2", "Pa", "3.5 GPa"),
    "density": Dimension("[mass] / [length] ** 3", "kg/m**3", "1240 kg/m^3"),
    "dimensionless": Dimension("dimensionless", "dimensionless", "0.02"),
}

_NUMBER = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*", re.S)
# One factor of a unit expression: a name, then an optional exponent.
_NAME = r"[A-Za-z_µμΩ°]+"
_EXPONENT = r"(?:\s*(?:\*\*|\^)\s*(?P<exp>[+-]?\d{1,2})|(?P<sup>⁻?[¹²³⁴⁵⁶⁷⁸⁹]+)|(?P<short>[23]))?"
_FACTOR = re.compile(rf"(?P<name>{_NAME}){_EXPONENT}")
# Between factors: an explicit operator (with optional spaces) or plain whitespace.
_OPERATOR = re.compile(r"\s*([*·⋅/])\s*|\s+")
_SUPERSCRIPTS = str.maketrans("⁻¹²³⁴⁵⁶⁷⁸⁹", "-123456789")


@functools.cache
def registry() -> pint.UnitRegistry:
    """The one pint registry of parmor (created on first use: pint is slow to import).

    pint's own definition cache (in the user's cache folder) cuts the registry's start-up
    from about 0.3 s to 0.02 s; where that folder cannot be written, it starts uncached.
    """
    import pint

    try:
        return pint.UnitRegistry(cache_folder=":auto:")
    except OSError:
        return pint.UnitRegistry()


def _label(dimension: str) -> str:
    """'angular_speed' -> 'an angular speed' (for messages)."""
    if dimension == "dimensionless":
        return "a plain number"
    words = dimension.replace("_", " ")
    return ("an " if words[0] in "aeiou" else "a ") + words


def _factors(unit_text: str) -> list[tuple[str, int]] | None:
    """``"kg/m^3"`` -> ``[("kg", 1), ("m", -3)]``; None when the text is not a unit."""
    factors: list[tuple[str, int]] = []
    pos, sign = 0, 1
    while True:
        match = _FACTOR.match(unit_text, pos)
        if match is None:
            return None
        if match["exp"] is not None:
            power = int(match["exp"])
        elif match["sup"] is not None:
            power = int(match["sup"].translate(_SUPERSCRIPTS))
        elif match["short"] is not None:
            power = int(match["short"])
        else:
            power = 1
        factors.append((match["name"], sign * power))
        pos = match.end()
        if pos == len(unit_text):
            return factors
        op = _OPERATOR.match(unit_text, pos)
        if op is None:
            return None
        sign = -1 if op.group(1) == "/" else 1
        pos = op.end()


class _Scale(NamedTuple):
    factor: float | None  # SI value of one unit; None when the dimension is wrong
    unknown: str | None  # a name pint does not know


@functools.cache
def _scale(factors: tuple[tuple[str, int], ...], dimension: str) -> _Scale:
    """The SI value of one ``factors`` unit as ``dimension``, cached per unit text."""
    import pint

    ureg = registry()
    dim = DIMENSIONS[dimension]
    unit = ureg.dimensionless
    for name, power in factors:
        try:
            unit = unit * ureg.Unit(name) ** power
        except (pint.UndefinedUnitError, ValueError):
            return _Scale(None, name)
    try:
        one = ureg.Quantity(1.0, unit)
        base = dict(one.to_base_units().unit_items())
        if base.get("radian", 0) != dim.angle_power:
            return _Scale(None, None)
        return _Scale(float(one.to(dim.si_unit).magnitude), None)
    except pint.PintError:  # DimensionalityError, offset units (degC) and the like
        return _Scale(None, None)


def quantity(
    text: str | int | float,
    dimension: str,
    where: str,
    *,
    allow_zero: bool = False,
    allow_negative: bool = False,
) -> float:
    """The SI value of ``text``, a number with a unit of ``dimension`` (a DIMENSIONS key).

    ``where`` names the value in messages ("catalog.toml: actuator[2] (MG996R).mass").
    By default the value must be > 0; ``allow_zero`` accepts >= 0, ``allow_negative``
    any finite value. Angles come back in radians, charges in coulombs. Raises
    InputError for a bare number (unless dimensionless), an unknown unit, the wrong
    dimension, unreadable text, a non-finite value or a value of the wrong sign.
    """
    if dimension not in DIMENSIONS:
        raise ValueError(f"unknown dimension {dimension!r}; one of {sorted(DIMENSIONS)}")
    dim = DIMENSIONS[dimension]
    expected = f"expected {_label(dimension)} such as '{dim.example}'"
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise InputError(f"{where}: {expected}, got {_describe(text)}")
    if isinstance(text, str):
        match = _NUMBER.fullmatch(text)
        if not text.strip():
            raise InputError(f"{where}: empty value; {expected}")
        if match is None:
            raise InputError(f"{where}: cannot read '{text}'; {expected}")
        number, unit_text = float(match.group(1)), match.group(2)
    else:
        number, unit_text = float(text), ""
    if unit_text:
        factors = _factors(unit_text)
        if factors is None:
            raise InputError(f"{where}: cannot read the unit of '{text}'; {expected}")
        scale = _scale(tuple(factors), dimension)
        if scale.unknown is not None:
            raise InputError(f"{where}: unknown unit '{scale.unknown}' in '{text}'; {expected}")
        if scale.factor is None:
            raise InputError(f"{where}: {expected}, got '{text}'")
        value = number * scale.factor
    elif dimension == "dimensionless":
        value = number
    else:
        raise InputError(f"{where}: '{text}' has no unit; {expected}")
    if not math.isfinite(value):
        raise InputError(f"{where}: '{text}' is not finite; {expected}")
    if value < 0 and not allow_negative:
        raise InputError(f"{where}: must not be negative, got '{text}'")
    if value == 0 and not (allow_zero or allow_negative):
        raise InputError(f"{where}: must be positive, got '{text}'")
    return value


def _describe(value: Any) -> str:
    """A short description of a value of the wrong type, for messages."""
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return f"{type(value).__name__} {value!r}"
