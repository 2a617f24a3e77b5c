"""Programs of behaviour calls: what a block page sends, what ``parmor run`` runs.

A program is JSON data, never code: ``{"program": [STATEMENT, ...]}`` with each statement
one of

- ``{"do": BEHAVIOUR, "params": {NAME: VALUE, ...}}``: run one of the design's behaviours
  (omitted parameters take their defaults);
- ``{"repeat": N, "body": [STATEMENT, ...]}``;
- ``{"wait": SECONDS}``: hold the current pose;
- ``{"if": {"report": NAME, "op": OP, "value": NUMBER}, "then": [...], "else": [...]}``:
  branch on what the robot reports (:data:`REPORTS`) after the statements before it.

The format is one schema, :class:`ProgramFile` (pydantic; published as
``adron/schemas/program.schema.json``): the statements' keys and types, the ranges of
``wait`` and ``repeat``, the reports and operators of a condition, and the :data:`LIMITS`
of the whole program (statements, nesting, behaviour runs). :func:`check` validates a
parsed program against it; :func:`validate` does, then checks what no schema of the file
can know, the design it runs on: each ``do`` names one of the design's behaviours and each
parameter one of that behaviour's, within its range. Every refusal names the place of the
first problem as a JSON path and its value (``program[1].body[0].params.distance = 9``),
after the file's name when there is one. :func:`parse` reads a program's JSON text within
bounds (nesting, numbers), and :func:`read_file` reads a program file of either form
(``parmor run``), a JSON one checked against the schema.
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
from typing import Annotated, Any, Literal, Protocol

from pydantic import Discriminator, Field, PlainValidator, Tag, WithJsonSchema, model_validator

from adron.errors import InputError
from adron.schema import At, Closed, Name, _show, described
from adron.schema import validate as against

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

#: the statements, by the key that makes each (the first of these a statement holds)
_KEYS = ("do", "repeat", "wait", "if")


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
    Python. A JSON file larger than :data:`FILE_BYTES` is refused, and a JSON program is
    checked against :class:`ProgramFile`. InputError naming the file (and line:column, or
    the key path and value) otherwise."""
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
    check(program, str(path))  # the schema; the design's behaviours are checked by the run
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


# ---- the schema of a program (one model: ProgramFile) ----------------------------------------


def _finite(v: object) -> float | int:
    """A JSON number a behaviour can take (not a boolean, finite); ints stay ints."""
    if isinstance(v, Unreadable):
        raise ValueError("not a number a behaviour can take")
    if not _number(v):
        raise ValueError("not a number")
    return v  # type: ignore[return-value]


def _ranged(low: float, high: float, unit: str, whole: bool = False):
    def check(v: object) -> float | int:
        x = _finite(v)
        if whole and float(x) != int(x):
            raise ValueError(f"not a whole number from {low:g} to {high:g}")
        if not low <= float(x) <= high:
            raise ValueError(f"out of range: must be within {low:g} and {high:g}{unit}")
        return x

    kind = "integer" if whole else "number"
    return Annotated[
        float | int,
        PlainValidator(check),
        WithJsonSchema({"type": kind, "minimum": low, "maximum": high}),
    ]


def _param_value(v: object) -> float | int | str:
    if isinstance(v, str):
        if len(v) > 200:
            raise ValueError("a choice of at most 200 characters")
        return v
    return _finite(v)


#: a number
Finite = Annotated[float | int, PlainValidator(_finite), WithJsonSchema({"type": "number"})]
#: a parameter's value: a number, or a choice's name
ParamValue = Annotated[
    float | int | str,
    PlainValidator(_param_value),
    WithJsonSchema(
        {
            "anyOf": [{"type": "number"}, {"type": "string", "maxLength": 200}],
            "description": "a number (in the parameter's unit) or one of a choice's names",
        }
    ),
]
Seconds = _ranged(0.0, LIMITS["wait_s"], " s")
Times = _ranged(0, LIMITS["repeat"], " times", whole=True)


def _statement_kind(v: object) -> str | None:
    """The tag of a statement: the first of :data:`_KEYS` it holds (None: no statement)."""
    if isinstance(v, Mapping):
        kind = next((k for k in _KEYS if k in v), None)
        return None if kind is None else f"statement[{kind}]"
    return None


class DoStatement(Closed):
    """Run one of the design's behaviours (omitted parameters take their defaults)."""

    do: Name = described(doc="the behaviour (parmor simulate DIR --behavior help lists them)")
    params: dict[Name, ParamValue] = described({}, "parameter name -> value")


class WaitStatement(Closed):
    """Hold the current pose."""

    wait: Seconds = described(doc=f"seconds, 0 to {LIMITS['wait_s']:g}")


class RepeatStatement(Closed):
    """Run ``body`` ``repeat`` times."""

    repeat: Times = described(doc=f"how many times, 0 to {LIMITS['repeat']:g}")
    body: list[Statement] = []


class Condition(Closed):
    """What the robot reports, compared with a number."""

    report: Literal[tuple(REPORTS)] = described(doc="a report (x_m, heading_deg, ok ...)")
    op: Literal[OPS]
    value: Finite


class IfStatement(Closed):
    """``then`` when the condition holds after the statements before it, else ``else``."""

    cond: Condition = Field(alias="if")
    then: list[Statement] = []
    otherwise: list[Statement] = Field([], alias="else")


Statement = Annotated[
    Annotated[DoStatement, Tag("statement[do]")]
    | Annotated[RepeatStatement, Tag("statement[repeat]")]
    | Annotated[WaitStatement, Tag("statement[wait]")]
    | Annotated[IfStatement, Tag("statement[if]")],
    Discriminator(
        _statement_kind,
        custom_error_type="statement",
        custom_error_message="not a statement: an object holding one of do, repeat, wait, if",
    ),
]
RepeatStatement.model_rebuild()
IfStatement.model_rebuild()


class ProgramFile(Closed):
    """A program: behaviour calls, waits, repeats and conditions (``parmor run
    PROGRAM.json DIR``, the block page's requests)."""

    program: list[Statement] = described(
        doc=f"the statements, run in order; at most {LIMITS['statements']:g} in all, nested "
        f"at most {LIMITS['depth']:g} deep, {LIMITS['calls']:g} behaviour runs with the "
        "repeats unrolled"
    )

    @model_validator(mode="after")
    def _limits(self) -> ProgramFile:
        count = [0]
        calls = _walk(self.program, "program", 1, count)
        if calls > LIMITS["calls"]:
            raise At(
                "program",
                f"runs {calls} behaviours with its repeats; at most {LIMITS['calls']:g}",
            )
        return self


def _walk(body: Sequence[Any], path: str, depth: int, count: list[int]) -> int:
    """The behaviour runs of ``body`` (repeats unrolled, the longer branch of an if); At
    the first statement past the :data:`LIMITS` of statements and nesting."""
    if depth > LIMITS["depth"]:
        raise At(path, f"nested deeper than {LIMITS['depth']:g}")
    calls = 0
    for i, st in enumerate(body):
        here = f"{path}[{i}]"
        count[0] += 1
        if count[0] > LIMITS["statements"]:
            raise At(here, f"more than {LIMITS['statements']:g} statements")
        if isinstance(st, DoStatement):
            calls += 1
        elif isinstance(st, RepeatStatement):
            calls += int(st.repeat) * _walk(st.body, f"{here}.body", depth + 1, count)
        elif isinstance(st, IfStatement):
            a = _walk(st.then, f"{here}.then", depth + 1, count)
            b = _walk(st.otherwise, f"{here}.else", depth + 1, count)
            calls += max(a, b)
    return calls


def check(program: object, source: str = "") -> ProgramFile:
    """``program`` (parsed JSON) checked against :class:`ProgramFile`; ProgramError naming
    ``source`` (when given), the JSON path of the first problem and its value."""

    if not isinstance(program, Mapping):
        raise ProgramError(
            f"{source + ': ' if source else ''}(the top level) = {_show(program)}: not a "
            'program (an object {"program": [statement, ...]})'
        )
    return against(ProgramFile, program, source, ProgramError)


def validate(program: object, behaviors: Mapping[str, Any], source: str = "") -> None:
    """Check ``program`` (parsed JSON) against its schema (:func:`check`) and then against
    ``behaviors`` (name -> the design's :class:`gaits.base.BehaviorSpec` it may call),
    which is what no schema of the file can say: each ``do`` names one of the design's
    behaviours, each parameter one of its parameters, of the parameter's kind and within
    its range. ProgramError naming ``source`` (when given), the first problem's JSON path
    and its value otherwise."""
    _design_checks(check(program, source), behaviors, f"{source}: " if source else "")


def _design_checks(model: ProgramFile, behaviors: Mapping[str, Any], where: str) -> None:
    todo: list[tuple[str, Sequence[Any]]] = [("program", model.program)]
    while todo:
        path, body = todo.pop(0)
        for i, st in enumerate(body):
            here = f"{path}[{i}]"
            if isinstance(st, RepeatStatement):
                todo.append((f"{here}.body", st.body))
            elif isinstance(st, IfStatement):
                todo += [(f"{here}.then", st.then), (f"{here}.else", st.otherwise)]
            elif isinstance(st, DoStatement):
                _do_checks(st, behaviors, f"{where}{here}")


def _do_checks(st: DoStatement, behaviors: Mapping[str, Any], here: str) -> None:
    name = st.do
    if name not in behaviors:
        raise ProgramError(
            f"{here}.do = {_shown(name)}: the design has no such behaviour "
            f"(behaviours: {', '.join(sorted(behaviors))})"
        )
    specs = {p.name: p for p in behaviors[name].params}
    for key, value in st.params.items():
        at = f"{here}.params.{key} = {_shown(value)}"
        if key not in specs:
            raise ProgramError(
                f"{at}: {name} has no parameter {key!r} (parameters: {', '.join(specs) or 'none'})"
            )
        spec = specs[key]
        if spec.kind == "choice" and not isinstance(value, str):
            raise ProgramError(f"{at}: expected one of {', '.join(spec.choices)}")
        if spec.kind != "choice" and not _number(value):
            raise ProgramError(f"{at}: expected a number")
        if spec.kind == "int" and float(value) != int(value):
            raise ProgramError(f"{at}: expected a whole number")
        try:
            spec.check(value)
        except ValueError as exc:
            reason = str(exc).split(": ", 1)[-1]
            raise ProgramError(f"{at}: {reason}") from None


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


def execute(program: Mapping, robot: Robot, source: str = "") -> None:
    """Run a validated program on ``robot``, statement by statement. A ProgramError the
    robot raises (a behaviour that cannot run with these values together, the simulated
    time used up) names ``source`` (when given) and the statement's JSON path."""
    _run(program["program"], robot, "program", f"{source}: " if source else "")


def _run(body: Sequence[Mapping], robot: Robot, path: str, where: str) -> None:
    for i, st in enumerate(body):
        here = f"{path}[{i}]"
        try:
            if "do" in st:
                robot.do(st["do"], **dict(st.get("params", {})))
            elif "wait" in st:
                robot.wait(float(st["wait"]))
            elif "if" in st:
                c = st["if"]
                taken = holds(robot.report(c["report"]), c["op"], float(c["value"]))
        except ProgramError as e:
            raise ProgramError(f"{where}{here}: {e}") from None
        if "repeat" in st:
            for _ in range(int(st["repeat"])):
                _run(st.get("body", []), robot, f"{here}.body", where)
        elif "if" in st:
            branch = "then" if taken else "else"
            _run(st.get(branch, []), robot, f"{here}.{branch}", where)


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
