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
:func:`to_python` writes the Python text the program stands for (what the block page
shows); :func:`execute` runs a program on anything with ``do``, ``wait`` and ``report``
(a :class:`program.session.Session`). The same Python text runs with ``parmor run``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
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

_KEYS = {"do": {"do", "params"}, "repeat": {"repeat", "body"}, "wait": {"wait"}}
_KEYS["if"] = {"if", "then", "else"}


class ProgramError(InputError):
    """A program that is malformed, asks for what the design cannot do, or exceeds the
    :data:`LIMITS`; the message starts with the JSON path of the problem."""


class Robot(Protocol):
    """What :func:`execute` drives."""

    def do(self, behavior: str, **params: Any) -> Any: ...

    def wait(self, seconds: float) -> Any: ...

    def report(self, name: str) -> float: ...


def _number(value: object) -> bool:
    return (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


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
                f"{path}.do: the design has no behaviour {name!r} "
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
            if spec.kind != "choice" and not _number(value):
                raise ProgramError(f"{path}.params.{key}: expected a number, got {value!r}")
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
                f"{path}.wait: expected seconds in [0, {LIMITS['wait_s']:g}], got {s!r}"
            )
        return 0
    if kind == "repeat":
        n = st["repeat"]
        if not _number(n) or float(n) != int(n) or not 0 <= int(n) <= LIMITS["repeat"]:
            raise ProgramError(
                f"{path}.repeat: expected a whole number in [0, {LIMITS['repeat']:g}], got {n!r}"
            )
        return int(n) * _body(st.get("body", []), f"{path}.body", behaviors, depth + 1, count)
    cond = st["if"]
    if not isinstance(cond, Mapping) or set(cond) != {"report", "op", "value"}:
        raise ProgramError(f'{path}.if: expected {{"report": NAME, "op": OP, "value": NUMBER}}')
    if cond["report"] not in REPORTS:
        raise ProgramError(
            f"{path}.if.report: unknown report {cond['report']!r} (reports: {', '.join(REPORTS)})"
        )
    if cond["op"] not in OPS:
        raise ProgramError(f"{path}.if.op: expected one of {' '.join(OPS)}, got {cond['op']!r}")
    if not _number(cond["value"]):
        raise ProgramError(f"{path}.if.value: expected a number, got {cond['value']!r}")
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
