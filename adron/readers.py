"""Reading a user's TOML and JSON files within bounds: the one way parmor reads catalogs,
regression suites, studies, snapshots and design records.

Python's readers fail on hostile input in ways that are not input errors: ``tomllib`` and
``json`` recurse per level of nesting (``RecursionError`` at ~1000 levels), ``int()``
refuses more than 4300 digits (``ValueError``) and a 400-digit integer overflows every
float it meets later (``OverflowError``). Here nesting is bounded by :data:`MAX_DEPTH`
(checked by a scan of the text before parsing, and of the parsed value: TOML's dotted keys
nest without brackets), integers by :data:`MAX_DIGITS` and TOML's floats must be finite;
every failure is an :class:`~adron.errors.InputError` that names the file and the line and
column, or the key.
"""

from __future__ import annotations

import math
import re
from itertools import accumulate
from pathlib import Path
from typing import Any

from adron.errors import InputError

#: containers inside containers: no input of parmor's nests deeper than ~10
MAX_DEPTH = 64
#: digits of an integer: more is larger than any float (1.8e308), than any quantity
MAX_DIGITS = 300

_OPEN, _CLOSE = "[{", "]}"
#: JSON: a string (closed or not), or a bracket
_JSON_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"?|[\[\]{}]', re.S)
#: JSON: a number, group 1 its integer digits, 2 a fraction or exponent (then a float)
_JSON_NUMBER = re.compile(r'"(?:[^"\\]|\\.)*"?|-?(\d+)(\.\d*(?:[eE][-+]?\d*)?|[eE][-+]?\d*)?', re.S)
#: TOML: a string of any of its four kinds or a comment (closed or not), or a bracket
_TOML_TOKEN = re.compile(
    r'"""(?:[^\\]|\\.)*?(?:"""|\Z)|\'\'\'.*?(?:\'\'\'|\Z)|"(?:[^"\\\n]|\\.)*"?|\'[^\'\n]*\'?'
    r"|#[^\n]*|[\[\]{}]",
    re.S,
)
#: TOML: a run of digits and underscores outside strings and comments (an integer, a
#: float's part, a date's part or a bare key)
_TOML_NUMBER = re.compile(
    r'"""(?:[^\\]|\\.)*?(?:"""|\Z)|\'\'\'.*?(?:\'\'\'|\Z)|"(?:[^"\\\n]|\\.)*"?|\'[^\'\n]*\'?'
    r"|#[^\n]*|[A-Za-z_-][\w-]*|(\d[\d_]*)",
    re.S,
)
#: tomllib's "message (at line L, column C)"
_TOML_AT = re.compile(r"(?s)(.*) \(at line (\d+), column (\d+)\)")


class _LongInteger(ValueError):
    """Raised from ``json``'s ``parse_int`` for an integer of too many digits."""


def _position(text: str, offset: int) -> str:
    """``line:col`` (1-based) of ``offset`` in ``text``."""
    line = text.count("\n", 0, offset) + 1
    return f"{line}:{offset - (text.rfind(chr(10), 0, offset) + 1) + 1}"


def _depth_error(text: str, source: str, token: re.Pattern[str], max_depth: int) -> InputError:
    """The error for the first bracket of ``text`` nested deeper than ``max_depth``."""
    depth = 0
    for m in token.finditer(text):
        c = m.group()
        if c in _OPEN:
            depth += 1
            if depth > max_depth:
                return InputError(
                    f"{source}:{_position(text, m.start())}: nested deeper than {max_depth} "
                    "levels of arrays and tables"
                )
        elif c in _CLOSE:
            depth -= 1
    return InputError(f"{source}: nested deeper than {max_depth} levels of arrays and tables")


def _check_depth(text: str, source: str, token: re.Pattern[str], max_depth: int) -> None:
    """InputError when brackets outside strings (and comments) nest deeper than
    ``max_depth``: counted without a Python loop per bracket unless the text has many."""
    if sum(text.count(c) for c in _OPEN) <= max_depth:
        return
    brackets = "".join(
        m.group() for m in token.finditer(text) if len(m.group()) == 1 and m.group() in "[]{}"
    )
    steps = accumulate(1 if c in _OPEN else -1 for c in brackets)
    if max(steps, default=0) > max_depth:
        raise _depth_error(text, source, token, max_depth)


def _check_digits(text: str, source: str, number: re.Pattern[str], max_digits: int) -> None:
    """InputError for the first integer literal outside strings with too many digits."""
    if not re.search(rf"\d{{{max_digits + 1}}}", text.replace("_", "")):
        return
    for m in number.finditer(text):
        digits = m.group(1)
        if digits is not None and (number.groups < 2 or m.group(2) is None):
            n = len(digits.replace("_", ""))
            if n > max_digits:
                raise InputError(
                    f"{source}:{_position(text, m.start(1))}: a number of {n} digits "
                    f"(at most {max_digits})"
                )


_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _key(path: tuple[str | int, ...]) -> str:
    """``a.b[2]."c d"`` for messages: one line, the middle of a long path elided."""
    if len(path) > 8:
        return f"{_key(path[:4])}...({len(path) - 6} more)...{_key(path[-2:]).lstrip('.')}"
    out = ""
    for p in path:
        if isinstance(p, int):
            out += f"[{p}]"
        else:
            name = p if _BARE.fullmatch(p) else '"' + p.encode("unicode_escape").decode() + '"'
            out += f".{name}" if out else name
    return out or "(the top level)"


def _check_value(value: Any, source: str, max_depth: int, max_digits: int) -> None:
    """InputError naming the key of a container nested deeper than ``max_depth``, an
    integer of more than ``max_digits`` digits or a float that is not finite. Iterative."""
    limit = 10**max_digits
    todo: list[tuple[Any, tuple[str | int, ...], int]] = [(value, (), 0)]
    while todo:
        v, path, depth = todo.pop()
        if isinstance(v, dict | list):
            if depth >= max_depth:
                raise InputError(
                    f"{source}: key {_key(path)}: nested deeper than {max_depth} levels of "
                    "arrays and tables"
                )
            items = v.items() if isinstance(v, dict) else enumerate(v)
            todo.extend((x, (*path, k), depth + 1) for k, x in items)
        elif isinstance(v, bool):
            continue
        elif isinstance(v, int) and not -limit < v < limit:
            raise InputError(
                f"{source}: key {_key(path)}: an integer of more than {max_digits} digits"
            )
        elif isinstance(v, float) and not math.isfinite(v):
            raise InputError(f"{source}: key {_key(path)}: {v} is not a finite number")


def read_text(path: str | Path, source: str | None = None, what: str = "file") -> str:
    """The UTF-8 text of ``path`` (a leading byte order mark dropped); InputError naming
    ``source`` (default: the path) when it is missing, a folder, unreadable or not UTF-8.
    ``what`` names what was expected (``a folder, not a catalog file``)."""
    source = str(path) if source is None else source
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise InputError(f"{source}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{source}: is a folder, not a {what}") from None
    except OSError as error:
        raise InputError(f"{source}: cannot read: {error.strerror or error}") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InputError(f"{source}: not UTF-8 text (byte {error.start})") from None


def parse_toml(
    text: str, source: str, max_depth: int = MAX_DEPTH, max_digits: int = MAX_DIGITS
) -> dict[str, Any]:
    """The table of the TOML ``text``; InputError ``source:line:col: why`` for a syntax
    error, nesting deeper than ``max_depth``, an integer of more than ``max_digits`` digits,
    or (``source: key K: why``) a float that is not finite."""
    import tomllib

    text = text.removeprefix("\ufeff")
    _check_depth(text, source, _TOML_TOKEN, max_depth)
    _check_digits(text, source, _TOML_NUMBER, max_digits)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        at = _TOML_AT.fullmatch(message)
        if at:
            raise InputError(f"{source}:{at[2]}:{at[3]}: {at[1]}") from None
        if message.endswith(" (at end of document)"):
            raise InputError(f"{source}:{_position(text, len(text))}: {message}") from None
        raise InputError(f"{source}: {message}") from None
    except RecursionError:  # the scan above missed a kind of nesting: still an input error
        raise InputError(f"{source}: nested too deeply") from None
    except ValueError as error:  # an integer Python will not convert
        raise InputError(f"{source}: {str(error).splitlines()[0]}") from None
    _check_value(data, source, max_depth, max_digits)
    return data


def parse_json(
    text: str, source: str, max_depth: int = MAX_DEPTH, max_digits: int = MAX_DIGITS
) -> Any:
    """The value of the JSON ``text``; InputError ``source:line:col: why`` for a syntax
    error, nesting deeper than ``max_depth`` or an integer of more than ``max_digits``
    digits. Floats are Python's (``NaN``, ``Infinity`` and ``1e400`` included: parmor's
    records may hold them)."""
    import json

    text = text.removeprefix("\ufeff")
    _check_depth(text, source, _JSON_TOKEN, max_depth)

    def integer(s: str) -> int:
        if len(s) - s.startswith("-") > max_digits:
            raise _LongInteger(s)
        return int(s)

    try:
        return json.loads(text, parse_int=integer)
    except _LongInteger:
        _check_digits(text, source, _JSON_NUMBER, max_digits)
        raise InputError(f"{source}: a number of more than {max_digits} digits") from None
    except json.JSONDecodeError as error:
        raise InputError(f"{source}:{error.lineno}:{error.colno}: {error.msg}") from None
    except RecursionError:
        raise InputError(f"{source}: nested too deeply") from None


def read_toml(path: str | Path, source: str | None = None, what: str = "TOML file") -> dict:
    """:func:`parse_toml` of the file ``path`` (:func:`read_text`)."""
    source = str(path) if source is None else source
    return parse_toml(read_text(path, source, what), source)


def read_json(path: str | Path, source: str | None = None, what: str = "JSON file") -> Any:
    """:func:`parse_json` of the file ``path`` (:func:`read_text`)."""
    source = str(path) if source is None else source
    return parse_json(read_text(path, source, what), source)
