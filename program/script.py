"""Programs of behaviour calls: what a block page sends, what ``parmor run`` runs.

A program is JSON data, never code: ``{"program": [STATEMENT, ...]}`` with each statement
one of

- ``{"do": BEHAVIOUR, "params": {NAME: VALUE, ...}}``: run one of the design's behaviours
  (omitted parameters take their defaults);
- ``{"repeat": N, "body": [STATEMENT, ...]}``;
- ``{"wait": SECONDS}``: hold the current pose;
- ``{"if": {"report": NAME, "op": OP, "value": NUMBER}, "then": [...], "else": [...]}``:
  branch on what the robot reports (:data:`REPORTS`) after the statements before it.

:func:`validate` checks a program against a design's behaviours and the :data:`LIMITS`,
naming the place of the first problem as a JSON path (``program[1].body[0].params.distance``).
:func:`parse` reads a program's JSON text within bounds (nesting, numbers), and
:func:`read_file` reads a program file of either form (``parmor run``).
:func:`to_python` writes the Python text the program stands for (what the block page
shows); :func:`execute` runs a program on anything with ``do``, ``wait`` and ``report``
(a :class:`program.session.Session`). The same Python text runs with ``parmor run``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from adron.errors import InputError

#: What a robot reports to a program: name -> (unit, meaning). Flags are 1 or 0.
REPORTS: dict[str, tuple[str, str]] = {
    "x_m": ("m", "position of the robot's trunk along x, from where the program started"),
    "y_m": ("m", "position of the robot's trunk along y, from where the program started"),
    "heading_deg": ("deg", "change of the trunk's heading since the program started"),
    "distance_m": ("m", "how far the trunk moved during the last behaviour"),
    "ok": ("", "1 if the last behaviour kept its promise (its verdict), else 0"),
    "fell": ("", "1 if the robot has fallen or collapsed, else 0"),
    "time_s": ("s", "simulated time since the program started"),
}

#: Comparison operators of an ``if`` condition.
OPS = ("<", "<=", ">", ">=", "==", "!=")

#: Bounds on a program, so that a block page cannot ask for unbounded work.
LIMITS: dict[str, float] = {
    "statements": 200,  # statements written, in all bodies
    "repeat": 50,  # times one repeat runs its body
    "depth": 8,  # nesting of repeat / if
    "calls": 200,  # behaviour runs, repeats unrolled (the longer branch of an if)
    "wait_s": 60.0,  # one wait
    "sim_s": 300.0,  # simulated seconds of the whole run (checked as it runs)
}

#: Bounds on a program's JSON text: arrays and objects inside each other (a program nested
#: LIMITS["depth"] deep needs 2 x 8 + 3), digits of an integer read as a number (more are
#: no value a behaviour takes, and Python refuses to read more than 4300), bytes of a file.
JSON_DEPTH = 64
INT_DIGITS = 30
FILE_BYTES = 1024 * 1024

_KEYS = {"do": {"do", "params"}, "repeat": {"repeat", "body"}, "wait": {"wait"}}
_KEYS["if"] = {"if", "then", "else"}


class ProgramError(InputError):
    """A program that is malformed, asks for what the design cannot do, or exceeds the
    :data:`LIMITS`; the message starts with the JSON path of the problem."""


class JsonError(ProgramError):
    """A program text that is not JSON, or JSON beyond :data:`JSON_DEPTH`: ``line`` and
    ``col`` (1-based) of the problem, ``reason``, and whether it is a ``syntax`` error."""

    def __init__(self, reason: str, line: int, col: int, syntax: bool = True) -> None:
        self.reason, self.line, self.col, self.syntax = reason, line, col, syntax
        super().__init__(f"{line}:{col}: {reason}")


class Unreadable:
    """A JSON number no behaviour can take, kept (instead of failing the whole parse) so
    that :func:`validate` names its place: NaN or Infinity, an integer of more than
    :data:`INT_DIGITS` digits, a number beyond the float range."""

    def __init__(self, text: str, why: str) -> None:
        self.text, self.why = text, why

    def __repr__(self) -> str:
        return self.why


def _int(text: str) -> int | Unreadable:
    digits = len(text.lstrip("-"))
    if digits > INT_DIGITS:
        return Unreadable(text, f"an integer of {digits} digits (too large)")
    return int(text)


def _float(text: str) -> float | Unreadable:
    x = float(text)
    if not math.isfinite(x):
        return Unreadable(text, f"{_cut(text)} (beyond the range of numbers)")
    return x


def _constant(text: str) -> Unreadable:
    return Unreadable(text, f"{text} (not a number JSON allows)")


def _cut(text: str, n: int = 24) -> str:
    return text if len(text) <= n else f"{text[: n // 2]}...{text[-n // 2 :]}"


#: What the depth scan steps over: strings (brackets inside them do not count), brackets.
_SCAN = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"|[\[\]{}]')


def _position(text: str, offset: int) -> tuple[int, int]:
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def parse(text: str) -> object:
    """``text`` (a program as JSON) parsed; JsonError (line, column) when it is not JSON or
    nests arrays and objects deeper than :data:`JSON_DEPTH`. Numbers no behaviour can take
    (NaN, Infinity, huge integers, beyond the float range) come back as
    :class:`Unreadable`, for :func:`validate` to refuse by their place in the program."""
    depth = 0
    for m in _SCAN.finditer(text):
        c = m.group()[0]
        if c in "[{":
            depth += 1
            if depth > JSON_DEPTH:
                line, col = _position(text, m.start())
                raise JsonError(
                    f"arrays and objects nested deeper than {JSON_DEPTH}", line, col, syntax=False
                )
        elif c in "]}":
            depth -= 1
    try:
        return json.loads(text, parse_int=_int, parse_float=_float, parse_constant=_constant)
    except json.JSONDecodeError as e:
        raise JsonError(e.msg, e.lineno, e.colno) from None
    except RecursionError:  # the scan bounds the nesting; this is a fence behind it
        raise JsonError(f"nested too deep (at most {JSON_DEPTH})", 1, 1, syntax=False) from None


def read_file(path: str | Path) -> tuple[str, object]:
    """``("json", program)`` for a JSON program file, ``("python", None)`` for a Python one.

    The form is chosen by the content, and the suffix in any case: a ``.json`` file is
    JSON; a ``.py`` file is Python unless it parses as a JSON object holding ``program``;
    any other file is JSON when its text starts with ``{`` (after white space), else
    Python. A JSON file larger than :data:`FILE_BYTES` is refused. InputError naming the
    file (and line:column) otherwise."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(FILE_BYTES + 1)
    except FileNotFoundError:
        raise InputError(f"{path}: no such program file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: a folder, not a program file") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read it: {e.strerror or e}") from None
    suffix = path.suffix.lower()
    python = ("python", None)
    if suffix != ".json" and not head.removeprefix(b"\xef\xbb\xbf").lstrip().startswith(b"{"):
        return python
    try:
        if len(head) > FILE_BYTES:
            raise InputError(f"{path}: a JSON program larger than {FILE_BYTES} bytes")
        try:
            text = head.decode("utf-8-sig")
        except UnicodeDecodeError as e:
            raise InputError(f"{path}: not UTF-8 text (byte {e.start})") from None
        try:
            program = parse(text)
        except JsonError as e:
            raise InputError(f"{path}:{e.line}:{e.col}: {e.reason}") from None
    except InputError:
        if suffix == ".py":
            return python
        raise
    if suffix == ".py" and not (isinstance(program, dict) and "program" in program):
        return python
    return ("json", program)


class Robot(Protocol):
    """What :func:`execute` drives."""

    def do(self, behavior: str, **params: Any) -> Any: ...

    def wait(self, seconds: float) -> Any: ...

    def report(self, name: str) -> float: ...


def _number(value: object) -> bool:
    """Whether ``value`` is a number a behaviour can take: finite as a float."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:  # an integer beyond the float range
        return False


def _shown(value: object) -> str:
    """``value`` for a message: its repr, a huge integer by its digits, anything long cut."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**INT_DIGITS:
        digits = int(abs(value).bit_length() * math.log10(2)) + 1  # str() refuses > 4300
        return f"an integer of about {digits} digits (too large)"
    return _cut(repr(value), 60)


def _need_number(value: object, path: str) -> None:
    if not _number(value):
        raise ProgramError(f"{path}: expected a number, got {_shown(value)}")


def validate(program: object, behaviors: Mapping[str, Any]) -> None:
    """Check ``program`` (parsed JSON) against ``behaviors`` (name -> the design's
    :class:`gaits.base.BehaviorSpec` it may call) and the :data:`LIMITS`; ProgramError
    naming the first problem's JSON path otherwise."""
    if not isinstance(program, Mapping) or set(program) != {"program"}:
        raise ProgramError('program: expected an object {"program": [statement, ...]}')
    count = [0]
    calls = _body(program["program"], "program", behaviors, 1, count)
    if calls > LIMITS["calls"]:
        raise ProgramError(
            f"program: runs {calls} behaviours with its repeats; at most {LIMITS['calls']:g}"
        )


def _body(
    body: object, path: str, behaviors: Mapping[str, Any], depth: int, count: list[int]
) -> int:
    """Validate a list of statements; the behaviour runs it makes, repeats unrolled."""
    if not isinstance(body, list):
        raise ProgramError(f"{path}: expected a list of statements")
    if depth > LIMITS["depth"]:
        raise ProgramError(f"{path}: nested deeper than {LIMITS['depth']:g}")
    calls = 0
    for i, st in enumerate(body):
        here = f"{path}[{i}]"
        count[0] += 1
        if count[0] > LIMITS["statements"]:
            raise ProgramError(f"{here}: more than {LIMITS['statements']:g} statements")
        calls += _statement(st, here, behaviors, depth, count)
    return calls


def _statement(
    st: object, path: str, behaviors: Mapping[str, Any], depth: int, count: list[int]
) -> int:
    if not isinstance(st, Mapping):
        raise ProgramError(f"{path}: expected a statement object")
    kind = next((k for k in _KEYS if k in st), None)
    if kind is None:
        raise ProgramError(f"{path}: expected one of {', '.join(_KEYS)} in a statement")
    extra = sorted(set(st) - _KEYS[kind])
    if extra:
        raise ProgramError(f"{path}: unexpected key {extra[0]!r} in a {kind!r} statement")
    if kind == "do":
        name = st["do"]
        if not isinstance(name, str) or name not in behaviors:
            raise ProgramError(
                f"{path}.do: the design has no behaviour {_shown(name)} "
                f"(behaviours: {', '.join(sorted(behaviors))})"
            )
        params = st.get("params", {})
        if not isinstance(params, Mapping):
            raise ProgramError(f"{path}.params: expected an object of parameter values")
        specs = {p.name: p for p in behaviors[name].params}
        for key, value in params.items():
            if key not in specs:
                raise ProgramError(
                    f"{path}.params.{key}: {name} has no parameter {key!r} "
                    f"(parameters: {', '.join(specs) or 'none'})"
                )
            spec = specs[key]
            if spec.kind == "choice" and not isinstance(value, str):
                raise ProgramError(
                    f"{path}.params.{key}: expected one of {', '.join(spec.choices)}, "
                    f"got {_shown(value)}"
                )
            if spec.kind != "choice":
                _need_number(value, f"{path}.params.{key}")
            if spec.kind == "int" and float(value) != int(value):
                raise ProgramError(f"{path}.params.{key}: expected a whole number, got {value}")
            try:
                spec.check(value)
            except ValueError as exc:
                reason = str(exc).split(": ", 1)[-1]
                raise ProgramError(f"{path}.params.{key}: {reason}") from None
        return 1
    if kind == "wait":
        s = st["wait"]
        if not _number(s) or not 0 <= float(s) <= LIMITS["wait_s"]:
            raise ProgramError(
                f"{path}.wait: expected seconds in [0, {LIMITS['wait_s']:g}], got {_shown(s)}"
            )
        return 0
    if kind == "repeat":
        n = st["repeat"]
        if not _number(n) or float(n) != int(n) or not 0 <= int(n) <= LIMITS["repeat"]:
            raise ProgramError(
                f"{path}.repeat: expected a whole number in [0, {LIMITS['repeat']:g}], "
                f"got {_shown(n)}"
            )
        return int(n) * _body(st.get("body", []), f"{path}.body", behaviors, depth + 1, count)
    cond = st["if"]
    if not isinstance(cond, Mapping) or set(cond) != {"report", "op", "value"}:
        raise ProgramError(f'{path}.if: expected {{"report": NAME, "op": OP, "value": NUMBER}}')
    if not isinstance(cond["report"], str) or cond["report"] not in REPORTS:
        raise ProgramError(
            f"{path}.if.report: unknown report {_shown(cond['report'])} "
            f"(reports: {', '.join(REPORTS)})"
        )
    if not isinstance(cond["op"], str) or cond["op"] not in OPS:
        raise ProgramError(
            f"{path}.if.op: expected one of {' '.join(OPS)}, got {_shown(cond['op'])}"
        )
    _need_number(cond["value"], f"{path}.if.value")
    a = _body(st.get("then", []), f"{path}.then", behaviors, depth + 1, count)
    b = _body(st.get("else", []), f"{path}.else", behaviors, depth + 1, count)
    return max(a, b)


def holds(value: float, op: str, than: float) -> bool:
    """Whether ``value OP than`` holds."""
    return {
        "<": value < than,
        "<=": value <= than,
        ">": value > than,
        ">=": value >= than,
        "==": value == than,
        "!=": value != than,
    }[op]


def execute(program: Mapping, robot: Robot) -> None:
    """Run a validated program on ``robot``, statement by statement."""
    _run(program["program"], robot)


def _run(body: Sequence[Mapping], robot: Robot) -> None:
    for st in body:
        if "do" in st:
            robot.do(st["do"], **dict(st.get("params", {})))
        elif "wait" in st:
            robot.wait(float(st["wait"]))
        elif "repeat" in st:
            for _ in range(int(st["repeat"])):
                _run(st.get("body", []), robot)
        else:
            c = st["if"]
            taken = holds(robot.report(c["report"]), c["op"], float(c["value"]))
            _run(st.get("then" if taken else "else", []), robot)


def number_text(x: float) -> str:
    """A number as the program's Python text writes it: integral values below 1e21 as
    integers, others as Python's ``repr`` (the shortest text that reads back the same; the
    block page's generator writes exactly this, exponents included: ``1e-05``)."""
    x = float(x)
    if x == int(x) and abs(x) < 1e21:
        return str(int(x))
    return repr(x)


def _value_text(value: object) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    return number_text(value)  # type: ignore[arg-type]


HEADER = '''"""A parmor program.  Run it with: parmor run PROGRAM.py BUNDLE_DIR"""


def main(robot):
'''


def to_python(program: Mapping) -> str:
    """The Python text ``program`` stands for: a ``main(robot)`` function calling
    ``robot.do``, ``robot.wait`` and ``robot.report``; byte for byte what the block page
    writes."""
    lines: list[str] = []
    _text(program["program"], 1, lines)
    return HEADER + "\n".join(lines) + "\n"


def _text(body: Sequence[Mapping], level: int, lines: list[str]) -> None:
    pad = "    " * level
    if not body:
        lines.append(pad + "pass")
    for st in body:
        if "do" in st:
            args = "".join(f", {k}={_value_text(v)}" for k, v in st.get("params", {}).items())
            lines.append(f"{pad}robot.do({json.dumps(st['do'])}{args})")
        elif "wait" in st:
            lines.append(f"{pad}robot.wait({number_text(st['wait'])})")
        elif "repeat" in st:
            lines.append(f"{pad}for _ in range({number_text(st['repeat'])}):")
            _text(st.get("body", []), level + 1, lines)
        else:
            c = st["if"]
            lines.append(
                f"{pad}if robot.report({json.dumps(c['report'])}) {c['op']} "
                f"{number_text(c['value'])}:"
            )
            _text(st.get("then", []), level + 1, lines)
            lines.append(f"{pad}else:")
            _text(st.get("else", []), level + 1, lines)
