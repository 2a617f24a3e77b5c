"""One schema per user file format, validated the one way: :func:`validate`.

Each format parmor reads (part kinds, catalogs, studies, regression suites, perturbation
tables, bundle records) has its pydantic models in one module (``kinematics/partkinds.py``
and the others' ``schema`` sections); this module holds what they share: the bounds of the
quantities a file may give (:data:`MAX_LENGTH_M` ...), the small types built on them
(:data:`Length`, :data:`Name` ...), and :func:`validate`, which turns pydantic's first
complaint into one :class:`~adron.errors.InputError` naming the file, the key path
(``kind[2].joints[1].limits``) and the value. ``python -m adron.schema`` (or
``make schemas``) writes the JSON Schema of every format into ``adron/schemas/`` (see
docs/formats-schemas.md).

Checks that need more than one field (limits ordered, names unique, references resolved)
raise :class:`At` from a model validator: its key is appended to the model's, so the
message still names the exact key.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable
from typing import Annotated, Any, TypeVar

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PlainValidator,
    Strict,
    ValidationError,
    WithJsonSchema,
)

from adron.errors import InputError

# ---- bounds (documented in docs/formats-schemas.md) ----------------------------------------

#: the longest length a file may give (m): a part, a link, a default length, a constant; a
#: printed part longer than a printer's bed is split into dovetailed pieces, but a robot of
#: hobby servos (the catalog's modules) carries no link longer than this
MAX_LENGTH_M = 2.0
#: a joint limit (rad): at most one full turn either way from the zero position
MAX_ANGLE_RAD = 2 * math.pi
#: the heaviest mass a file may give (kg): what the strongest bus of the catalogs carries
#: with margin (the same bound as ``--param payload``'s range, synth/params.py)
MAX_MASS_KG = 50.0
#: a name (of a joint, a length, a class): a short word
MAX_NAME = 200

Model = TypeVar("Model", bound=BaseModel)


class Closed(BaseModel):
    """A table of a user's file: unknown keys are refused (a typo is not ignored)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True, frozen=True)


class Open(BaseModel):
    """A table others extend (a record's ``verified``, ``notes``): unknown keys pass."""

    model_config = ConfigDict(extra="allow", populate_by_name=True, frozen=True)


class At(ValueError):
    """A failure of a model validator at ``key`` below the model (``"joints[1].limits"``,
    ``"[2]"``); ``value`` is shown in the message."""

    def __init__(self, key: str, message: str, value: Any = ...) -> None:
        super().__init__(message)
        self.key, self.message, self.value = key, message, value


def number(v: Any) -> float:
    """``v`` as a finite float: a TOML/JSON number that is not a boolean."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ValueError("not a number")
    try:
        f = float(v)
    except OverflowError:
        raise ValueError("too large") from None
    if not math.isfinite(f):
        raise ValueError("not a finite number")
    return f


def _bounded(low: float, high: float, unit: str, open_low: bool = True) -> Callable[[Any], float]:
    def check(v: Any) -> float:
        f = number(v)
        if f < low or (open_low and f == low) or f > high:
            side = f"more than {low:g}" if open_low else f"at least {low:g}"
            raise ValueError(f"out of range: must be {side} and at most {high:g} {unit}")
        return f

    return check


def within(low: float, high: float, unit: str = "", why: str = ""):
    """A finite number from ``low`` to ``high`` (closed), in ``unit``, ``why`` these bounds
    (both said in the message and the JSON Schema's description when given)."""
    said = f" {unit}" if unit else ""
    said += f" ({why})" if why else ""

    def check(v: Any) -> float:
        f = number(v)
        if not low <= f <= high:
            raise ValueError(f"out of range: must be within {low:g} and {high:g}{said}")
        return f

    schema: dict[str, Any] = {"type": "number", "minimum": low, "maximum": high}
    if unit or why:
        schema["description"] = f"{unit}: {why}" if why else unit
    return Annotated[float, PlainValidator(check), WithJsonSchema(schema)]


#: a length (m): more than 0, at most :data:`MAX_LENGTH_M`
Length = Annotated[
    float,
    PlainValidator(_bounded(0.0, MAX_LENGTH_M, "m")),
    WithJsonSchema(
        {"type": "number", "exclusiveMinimum": 0, "maximum": MAX_LENGTH_M, "description": "m"}
    ),
]
#: a mass (kg): 0 to :data:`MAX_MASS_KG`
Mass = Annotated[
    float,
    PlainValidator(_bounded(0.0, MAX_MASS_KG, "kg", open_low=False)),
    WithJsonSchema({"type": "number", "minimum": 0, "maximum": MAX_MASS_KG, "description": "kg"}),
]


def _name(v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise ValueError("not a non-empty string")
    if len(v) > MAX_NAME or any(c in v for c in "\n\r\x00"):
        raise ValueError(f"not a name (one line of at most {MAX_NAME} characters)")
    return v


#: a non-empty one-line name
Name = Annotated[
    str,
    PlainValidator(_name),
    WithJsonSchema({"type": "string", "minLength": 1, "maxLength": MAX_NAME, "pattern": "\\S"}),
]
StrictBool = Annotated[bool, Strict()]
StrictStr = Annotated[str, Strict()]


def described(default: Any = ..., doc: str = "", **kw: Any) -> Any:
    """``Field`` with its documentation (the JSON Schema's ``description``)."""
    return Field(default, description=doc, **kw)


# ---- validation ---------------------------------------------------------------------------


def _show(value: Any, limit: int = 60) -> str:
    """``value`` for a message: its repr, long ones cut, containers summarised."""
    if isinstance(value, dict):
        return "a table" if value else "an empty table"
    if isinstance(value, list | tuple):
        text = repr(list(value))
        if len(text) <= limit:
            return text
        return f"a list of {len(value)}" if value else "an empty list"
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**20:
        return f"an integer of {len(str(abs(value)))} digits"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 5] + "...'"


def _data_path(data: Any, loc: tuple) -> tuple[tuple[str | int, ...], Any]:
    """The part of pydantic's ``loc`` that indexes ``data`` (a union's or a validator's
    tags dropped, an alias kept) and the value found there (... when it is missing)."""
    path: list[str | int] = []
    here = data
    for part in loc:
        in_dict = isinstance(here, dict) and isinstance(part, str) and part in here
        in_list = isinstance(here, list) and isinstance(part, int) and 0 <= part < len(here)
        if in_dict or in_list:
            here = here[part]
            path.append(part)
        elif isinstance(here, dict) and isinstance(part, str) and not path_is_tag(part):
            path.append(part)  # a missing key
            here = ...
        # else: a tag of pydantic's (a union member, a function): skipped
    return tuple(path), here


def path_is_tag(part: str) -> bool:
    """Whether a ``loc`` part is pydantic's tag, not a key (``function-after[...]``)."""
    return "[" in part or part in ("float", "int", "str", "bool", "list", "dict", "tuple")


def key_of(path: tuple[str | int, ...], data: Any = None, labels: tuple[str, ...] = ()) -> str:
    """``kind[2].joints[1].limits``: a key path as messages write it; with ``labels``,
    each list entry of ``data`` on the path that is a table holding one of those keys as a
    string is followed by it: ``actuator[1] (MG996R).mass``."""
    from adron.readers import _key

    if not labels:
        return _key(path)
    out = ""
    here = data
    for part in path:
        out += _key((part,)) if isinstance(part, int) or not out else "." + _key((part,))
        try:
            here = here[part]
        except (KeyError, IndexError, TypeError):
            here = None
        if isinstance(part, int) and isinstance(here, dict):
            label = next((here[k] for k in labels if isinstance(here.get(k), str)), None)
            if label and label.isprintable() and len(label) <= MAX_NAME:
                out += f" ({label})"
        if len(out) > 300:
            return _key(path)
    return out or "(the top level)"


#: pydantic's type errors said as parmor says them
_TYPES = {
    "model_type": "not a table (an object)",
    "model_attributes_type": "not a table (an object)",
    "dict_type": "not a table (an object)",
    "list_type": "not a list",
    "tuple_type": "not a list",
    "string_type": "not a string",
    "bool_type": "not true or false",
    "int_type": "not an integer",
    "float_type": "not a number",
    "too_short": "too few items",
    "too_long": "too many items",
}


def _message(error: dict, data: Any, labels: tuple[str, ...] = ()) -> str:
    """``key = value: why`` for one pydantic error of ``data``."""
    path, value = _data_path(data, tuple(error["loc"]))
    if error["loc"] and error["loc"][-1] == "[key]":  # a table's key: the key is the value
        value = error.get("input", value)
    ctx = error.get("ctx") or {}
    cause = ctx.get("error")
    kind = error["type"]
    suffix = ""
    if isinstance(cause, At):
        suffix, why, value = cause.key, cause.message, cause.value
    elif kind == "extra_forbidden":
        keys = ctx.get("keys", "")
        close = difflib.get_close_matches(str(path[-1]) if path else "", keys.split(", "), 1, 0.6)
        why = "unknown key" + (
            f" (did you mean '{close[0]}'?)" if close else f" (keys: {keys})" if keys else ""
        )
        value = ...
    elif kind == "missing":
        why = "missing (it is required)"
        value = ...
    elif kind == "literal_error":
        why = f"not one of {ctx.get('expected', '')}"
    elif isinstance(cause, ValueError):
        why = str(cause)
    elif kind in _TYPES:
        why = _TYPES[kind]
    else:
        why = error["msg"][0].lower() + error["msg"][1:]
        why = why.replace("input should", "should")
    key = key_of(path, data, labels) if path else ""
    if suffix:
        key = f"{key}{suffix}" if suffix.startswith("[") or not key else f"{key}.{suffix}"
    key = key or "(the top level)"
    shown = "" if value is ... else f" = {_show(value)}"
    return f"{key}{shown}: {why}"


def _allowed(model: type[BaseModel], loc: tuple) -> str:
    """The keys of the table at ``loc`` (for an unknown key's message), or ''."""
    import typing

    here: Any = model
    for part in loc[:-1]:
        origin = typing.get_origin(here)
        if isinstance(here, type) and issubclass(here, BaseModel):
            field = next((f for n, f in here.model_fields.items() if part in (n, f.alias)), None)
            if field is None:
                return ""
            here = field.annotation
        elif origin in (list, dict, tuple):
            here = typing.get_args(here)[-1]
            if isinstance(part, str) and origin is list:
                return ""
        else:
            return ""
        while typing.get_origin(here) in (typing.Union, Annotated) or (
            type(here).__name__ == "UnionType"
        ):
            args = [a for a in typing.get_args(here) if a is not type(None)]
            here = args[0]
    if isinstance(here, type) and issubclass(here, BaseModel):
        return ", ".join(sorted(f.alias or n for n, f in here.model_fields.items()))
    return ""


def validate(
    model: type[Model],
    data: Any,
    source: str,
    error: Callable[[str], Exception] = InputError,
    labels: tuple[str, ...] = (),
) -> Model:
    """``data`` (a parsed file) as ``model``; ``error("source: key = value: why")`` raised
    for the first violation (with how many more there are). ``source`` '' leaves the
    file out (a program sent to the block server). ``labels``: keys whose string value
    names a list entry in the key path (``actuator[1] (MG996R)``: its ``model``)."""
    try:
        return model.model_validate(data)
    except ValidationError as e:
        errors = e.errors(include_url=False)
        # an unknown key first: a misspelt key is also a missing one, and explains it
        first = next((x for x in errors if x["type"] == "extra_forbidden"), errors[0])
        if first["type"] == "extra_forbidden":
            keys = _allowed(model, tuple(first["loc"]))
            if keys:
                first = {**first, "ctx": {**(first.get("ctx") or {}), "keys": keys}}
        n = len(errors) - 1
        more = f" (and {n} more problem{'s' if n > 1 else ''})" if n else ""
        where = f"{source}: " if source else ""
        raise error(f"{where}{_message(first, data, labels)}{more}") from None


def _keys_checked(node: Any) -> Any:
    """``node`` (a JSON Schema) with every table whose keys have a pattern (pydantic writes
    a ``dict[Name, X]`` as ``patternProperties``, which lets a key that does not match pass
    unchecked) written as ``propertyNames`` holding the pattern and
    ``additionalProperties`` the values' schema: a key that breaks the pattern fails."""
    if isinstance(node, list):
        return [_keys_checked(x) for x in node]
    if not isinstance(node, dict):
        return node
    out = {k: _keys_checked(v) for k, v in node.items()}
    patterns = out.get("patternProperties")
    if isinstance(patterns, dict) and len(patterns) == 1 and "additionalProperties" not in out:
        (pattern, values), *_ = patterns.items()
        del out["patternProperties"]
        out["propertyNames"] = {**out.get("propertyNames", {}), "pattern": pattern}
        out["additionalProperties"] = values
    return out


def json_schema(model: type[BaseModel], title: str, doc: str) -> dict:
    """The JSON Schema (draft 2020-12) of ``model`` as a file of its own."""
    schema = _keys_checked(model.model_json_schema(by_alias=True, mode="validation"))
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": f"https://parmor.invalid/schemas/{title}.schema.json",
        "title": title,
        "description": doc,
        **{k: v for k, v in schema.items() if k not in ("title", "description")},
    }
