"""Part kinds as data: what each structural part (an ontology class) is made of.

The shipped kinds are ``kinematics/partkinds.toml``; a user's file in the same format adds
kinds or replaces shipped ones of the same class (``load(extra)``). Every problem is a
:class:`PartKindError` naming the file and the key (``kind[3].joints[0].axis``).

A kind (``[[kind]]``):

- ``class``: the ontology class it realises (also any subclass without a kind of its own);
- ``root = true``: a part the others hang on (its body is welded to the world for
  analysis): ``body`` (name), ``box`` (x, y, z expressions, m) centred at ``at`` (or at
  ``at_with[C]`` when a child of class C is mounted), ``faces`` (up, down or back: where
  its modules go), ``payload`` ("root": the payload rides on it; "end_effector": in the
  gripper; a serial arm's gripper holds it on any root: a mobile manipulator's);
- ``lengths``: the named lengths it uses with their defaults (m);
- ``joints``: its joints from where it attaches, each at the end of the previous one's
  tube (or at the previous joint): ``name``, ``kind`` (revolute, continuous, fixed),
  ``axis`` (x, y, z, -x..., "across": the gripper's, across its jaws), ``axes`` (cycled
  along a chain of such parts), ``limits`` (expressions, rad), ``group`` (actuator group,
  default the name), ``module`` (the catalog class that drives it, default
  PositionServomotor; ContinuousRotationServomotor for a continuous joint),
  ``actuator_on_parent`` (the servo's case sits on the parent body: a wheel's beside it,
  a steering joint's above it), ``passive = true`` (the joint turns freely on a bearing:
  no actuator, no ``module``, ``group`` or ``actuator_on_parent``; a free wheel), ``tube``
  (``length`` name, ``along`` direction in the joint frame), ``body`` (body name, default
  ``<joint>_link``); ``name = "serial"``: one joint of a serial arm, named from
  ``[serial]``;
- ``end``: what the last joint's body ends in: point_foot, foot_plate, gripper, wheel,
  caster; or ``tool``: a part without joints at the tip of an arm (a probe, a spray
  nozzle, a camera), a ``box`` [length along the chain, width, height] (m) of ``mass``
  (kg) fixed on the chain's end, the point it places or points with at its far end;
- ``role``: leg, arm, end_effector, wheel, caster, module, joint, link (what a template
  counts: legs, arms, wheels ...);
- ``mounts``: how its children of a class attach: ``layout`` bilateral (even counts
  along both sides over ``span``, ``track`` apart; odd counts: radial), radial (around
  the part on the ellipse span x track), pair (left and right at ``at``, y mirrored),
  axle (wheels in axles over ``span``, ``track`` apart), trailing (behind the plate at
  ground level), front (one wheel on the middle line or a pair ``track`` apart at the
  plate's front edge, ``span`` its length: steered wheels), serial (a chain of joints
  and links starting at ``at`` on a root part, its printed links named ``links`` 1, 2
  ... instead of L1, L2 ...: an arm on a chassis whose own lengths are L1 and L2;
  several chains side by side across the part, ``track`` apart from the first to the
  last; a pair layout puts two chains at its mirrored ``at``), tip (at the end of the
  part's chain) or top (another root part standing on this one at ``at``: a torso on a
  chassis; the body plan's root is the root part whose kind mounts the others);
- ``naming = "index"``: joints and bodies of a chain of such parts are numbered
  (``joint_1``, ``module_1``);
- ``order = "side"``: children of pair mounts are joined side by side (left leg, left
  arm, right leg, right arm), not mount by mount;
- ``link``: the part is a printed tube on the joint before it (a serial arm's
  LinkModule): ``first`` / ``rest`` directions, ``names`` the length names' prefix;
- ``wheel`` (a kind whose ``end`` is a wheel): ``radius`` and ``width`` (expressions, m,
  e.g. a name of its ``lengths``): the wheel's own size, which sizing then keeps (it is
  checked, not chosen) and the bundle and the simulation use.
"""

from __future__ import annotations

import ast
import math
import operator
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, PlainValidator, WithJsonSchema, model_validator

from adron.errors import InputError
from adron.schema import (
    MAX_ANGLE_RAD,
    MAX_LENGTH_M,
    At,
    Closed,
    Length,
    Mass,
    Name,
    StrictBool,
    StrictStr,
    _name,
    described,
    number,
    validate,
)

__all__ = [
    "PartKind",
    "PartKindError",
    "PartKinds",
    "evaluate",
    "in_use",
    "load",
    "load_texts",
    "shipped_text",
    "use",
]

AXES = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}
JOINT_KINDS = ("revolute", "continuous", "fixed")
ENDS = ("point_foot", "foot_plate", "gripper", "wheel", "caster", "tool")
LAYOUTS = ("bilateral", "radial", "pair", "axle", "trailing", "front", "serial", "tip", "top")
ROLES = ("leg", "arm", "end_effector", "wheel", "caster", "module", "joint", "link", "")
FACES = ("up", "down", "back")
PAYLOAD = ("root", "end_effector")


class PartKindError(ValueError):
    """A part kinds file that cannot be used: the message names the file and the key."""


_OPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
}
_PI = re.compile(r"(\d+(?:\.\d+)?)\s*pi\b")


def _check_expression(text: str) -> ast.AST:
    tree = ast.parse(_PI.sub(r"\1*pi", text), mode="eval")
    for node in ast.walk(tree):
        if not isinstance(
            node,
            (
                ast.Expression,
                ast.BinOp,
                ast.UnaryOp,
                ast.USub,
                ast.UAdd,
                ast.Name,
                ast.Load,
                ast.Constant,
                *_OPS,
            ),
        ) or (isinstance(node, ast.Constant) and not isinstance(node.value, (int, float))):
            raise ValueError(f"{text!r} is not an arithmetic expression of names and numbers")
    return tree


def evaluate(value: float | str, names: Mapping[str, float]) -> float:
    """A number, or an expression (``"La1/2"``, ``"-5pi/6"``) of ``names`` and ``pi``;
    evaluated left to right as Python would (``-pi/3`` is ``(-pi)/3``). KeyError for an
    unknown name."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)

    def ev(node: ast.AST) -> float:
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant):
            return node.value
        if isinstance(node, ast.Name):
            if node.id == "pi":
                return math.pi
            return names[node.id]
        if isinstance(node, ast.UnaryOp):
            x = ev(node.operand)
            return -x if isinstance(node.op, ast.USub) else x
        if isinstance(node, ast.BinOp):
            return _OPS[type(node.op)](ev(node.left), ev(node.right))
        raise ValueError(value)

    return float(ev(_check_expression(str(value))))


def _names(text: float | str) -> set[str]:
    if not isinstance(text, str):
        return set()
    return {n.id for n in ast.walk(_check_expression(text)) if isinstance(n, ast.Name)} - {"pi"}


@dataclass(frozen=True)
class KindJoint:
    """A joint of a part kind as its file declares it (``joints = [...]``): names, an axis
    or axes, limits as expressions; the assembler turns it into the built robot's joint
    (``kinematics.model.Joint``; the exporters' ``export.model3d.JointSpec``)."""

    name: str
    kind: str = "revolute"
    axis: str = "z"
    axes: tuple[str, ...] = ()
    limits: tuple[float | str, float | str] = ("-pi", "pi")
    group: str = ""
    module: str = ""
    actuator_on_parent: bool = False
    tube_length: str = ""
    tube_along: str = "x"
    body: str = ""
    passive: bool = False


@dataclass(frozen=True)
class Mount:
    child: str
    layout: str
    span: str = ""
    track: str = ""
    at: tuple[float | str, float | str, float | str] = (0.0, 0.0, 0.0)
    links: str = ""  # a chain's printed links are named links1, links2 ... (default: L)


@dataclass(frozen=True)
class PartKind:
    """One part kind (see the module's docstring); ``where``: file and key it came from."""

    cls: str
    where: str
    doc: str = ""
    root: bool = False
    body: str = ""
    box: tuple[float | str, ...] = ()
    at: tuple[float | str, ...] = (0.0, 0.0, 0.0)
    at_with: Mapping[str, tuple[float | str, ...]] = field(default_factory=dict)
    faces: str = "up"
    payload: str = "root"
    order: str = ""
    lengths: Mapping[str, float] = field(default_factory=dict)
    joints: tuple[KindJoint, ...] = ()
    end: str = ""
    role: str = ""
    mounts: tuple[Mount, ...] = ()
    naming: str = ""
    link: Mapping[str, str] = field(default_factory=dict)
    mass: float = 0.0  # kg: a tool's (end = "tool")
    wheel: Mapping[str, float | str] = field(default_factory=dict)


@dataclass(frozen=True)
class PartKinds:
    """Every known part kind by class, the serial arms' joint table (N -> rows of (name,
    axis, limit, limit, whether a printed link follows the joint in an arm composed for N
    joints)), the serial arms' default link lengths and the constants."""

    kinds: Mapping[str, PartKind]
    serial: Mapping[int, tuple[tuple[str, str, str, str, bool], ...]]
    serial_lengths: Mapping[str, float]
    constants: Mapping[str, float]
    sources: tuple[str, ...] = ()
    #: (file name, text) of each file read after the shipped one (``--parts``): what a
    #: design record carries so that its bundle is rebuilt without them (:func:`load_texts`)
    texts: tuple[tuple[str, str], ...] = ()

    def of(self, kinds: Sequence[str]) -> PartKind | None:
        """The kind of a part whose class and ancestors are ``kinds`` (most specific
        first): the first one with data."""
        for k in kinds:
            if k in self.kinds:
                return self.kinds[k]
        return None


def shipped_text() -> tuple[str, str]:
    """(display name, text) of the shipped part kinds."""
    path = resources.files("kinematics") / "partkinds.toml"
    return "kinematics/partkinds.toml", path.read_text(encoding="utf-8")


_CACHE: dict[tuple, PartKinds] = {}


def load(extra: Sequence[str | Path] = ()) -> PartKinds:
    """The shipped part kinds, then each file of ``extra`` in order (a kind of a class
    already known replaces it; ``[serial]`` rows and constants are merged)."""
    sources = [shipped_text()]
    for path in extra:
        p = Path(path)
        if not p.is_file():
            raise PartKindError(f"{path}: not a readable file of part kinds")
        try:
            sources.append((str(path), p.read_text(encoding="utf-8")))
        except (OSError, UnicodeDecodeError) as e:
            raise PartKindError(f"{path}: cannot read it ({e})") from None
    return _cached(sources)


def load_texts(extra: Sequence[tuple[str, str]]) -> PartKinds:
    """As :func:`load` with the user's files given as (name, text): a design record's
    ``part_kinds``."""
    return _cached([shipped_text(), *((str(n), str(t)) for n, t in extra)])


def _cached(sources: list[tuple[str, str]]) -> PartKinds:
    key = tuple(sources)
    if key not in _CACHE:
        _CACHE[key] = _parse(sources)
        while len(_CACHE) > 8:
            _CACHE.pop(next(iter(_CACHE)))
    return _CACHE[key]


#: The part kinds this process assembles with (None: the shipped ones): ``use`` sets it.
_IN_USE: list[PartKinds | None] = [None]


def use(kinds: PartKinds | None) -> None:
    """Assemble with ``kinds`` from now on (None: the shipped ones)."""
    _IN_USE[0] = kinds


def in_use() -> PartKinds:
    """The part kinds this process assembles with (``use``; the shipped ones)."""
    return _IN_USE[0] or load()


# ---- the schema of a part kinds file -------------------------------------------------------

_MAX_EXPRESSION = 200


def _expression(v: object) -> float | str:
    """A finite number, or the text of an arithmetic expression of names and numbers."""
    if isinstance(v, str):
        if len(v) > _MAX_EXPRESSION:
            raise ValueError(f"longer than {_MAX_EXPRESSION} characters")
        try:
            _names(v)
            evaluate(v, _Unknown())
        except _NameSeen:
            return v
        except (ValueError, SyntaxError, RecursionError, MemoryError, ZeroDivisionError):
            raise ValueError("not an arithmetic expression of names and numbers") from None
        except OverflowError:
            raise ValueError("too large") from None
        return v
    return number(v)


class _NameSeen(Exception):
    pass


class _Unknown(dict):
    """Names of an expression that only checks its form: any name stops the evaluation."""

    def __getitem__(self, key):
        raise _NameSeen(key)


def _fixed(v: float | str) -> float | None:
    """The value of a number or an expression of numbers and ``pi`` alone, else None."""
    try:
        return evaluate(v, _Unknown())
    except (_NameSeen, ZeroDivisionError, OverflowError, ValueError, SyntaxError):
        return None


_EXPR_SCHEMA = {
    "anyOf": [
        {"type": "number"},
        {
            "type": "string",
            "maxLength": _MAX_EXPRESSION,
            "description": "an expression of names, numbers, pi and + - * / ('La1/2', '-5pi/6')",
        },
    ]
}
#: a number or an expression (``"La1/2"``, ``"-5pi/6"``)
Expr = Annotated[float | str, PlainValidator(_expression), WithJsonSchema(_EXPR_SCHEMA)]
Axis = Literal["x", "y", "z", "-x", "-y", "-z"]
Vec3 = Annotated[list[Expr], Field(min_length=3, max_length=3)]


def _check_range(key: str, v: float | str, low: float, high: float, unit: str) -> None:
    """At ``key`` when ``v`` is known now (no names) and outside [low, high]."""
    x = _fixed(v)
    if x is not None and not low <= x <= high:
        raise At(key, f"out of range: must be within {low:g} and {high:g} {unit}", v)


class TubeSchema(Closed):
    """The printed tube from a joint to the next: its length's name and direction."""

    length: Name = described(doc="the name of a length of the kind's 'lengths'")
    along: Axis = described("x", "its direction in the joint's frame")


class JointSchema(Closed):
    """One joint of a part kind, at the end of the previous one's tube."""

    name: Name = described(doc="the joint's name ('serial': a serial arm's, from [serial])")
    kind: Literal["revolute", "continuous", "fixed"] = "revolute"
    axis: Literal["x", "y", "z", "-x", "-y", "-z", "across"] = described(
        "z", "its axis ('across': a gripper's, across its jaws)"
    )
    axes: list[Axis] = described([], "axes cycled along a chain of such parts")
    limits: Annotated[list[Expr], Field(min_length=2, max_length=2)] = described(
        ["-pi", "pi"],
        f"lower and upper limit (rad, expressions), ordered, within +-{MAX_ANGLE_RAD:.4g}",
    )
    group: StrictStr = described("", "actuator group (default: the joint's name)")
    module: StrictStr = described("", "the catalog class that drives it")
    actuator_on_parent: StrictBool = described(False, "the servo's case sits on the parent")
    tube: TubeSchema | None = None
    body: StrictStr = described("", "its body's name (default <joint>_link)")
    passive: StrictBool = described(False, "turns freely on a bearing: no actuator")

    @model_validator(mode="after")
    def _consistent(self) -> JointSchema:
        for i, v in enumerate(self.limits):
            _check_range(f"limits[{i}]", v, -MAX_ANGLE_RAD, MAX_ANGLE_RAD, "rad")
        lower, upper = (_fixed(v) for v in self.limits)
        if lower is not None and upper is not None and lower >= upper:
            raise At("limits", "the lower limit is not below the upper one", self.limits)
        if self.passive and self.kind == "fixed":
            raise At("passive", "a fixed joint does not move: it cannot be passive", True)
        if self.passive:
            given = [
                k for k in ("module", "group", "actuator_on_parent") if k in self.model_fields_set
            ]
            if given:
                raise At(
                    given[0],
                    f"joint {self.name!r} is passive (it turns freely on a bearing, no actuator "
                    f"drives it): it takes no {given[0]!r}",
                )
        return self


class MountSchema(Closed):
    """How a root part's children of a class attach."""

    child: Name = described(doc="the children's class")
    layout: Literal[LAYOUTS] = described(
        doc="bilateral, radial, pair, axle, trailing, front, serial, tip, top"
    )
    span: Expr | None = None
    track: Expr | None = None
    at: Vec3 = [0.0, 0.0, 0.0]
    links: Name | None = described(None, "a chain's printed links' name prefix (default L)")

    @model_validator(mode="after")
    def _needs(self) -> MountSchema:
        if self.layout in ("bilateral", "radial", "axle") and not (
            self.span is not None and self.track is not None
        ):
            raise At("", f"layout {self.layout} needs 'span' and 'track'")
        if self.layout in ("trailing", "front") and self.span is None:
            raise At("", f"layout {self.layout} needs 'span'")
        for i, v in enumerate(self.at):
            _check_range(f"at[{i}]", v, -MAX_LENGTH_M, MAX_LENGTH_M, "m")
        for k in ("span", "track"):
            if getattr(self, k) is not None:
                _check_range(k, getattr(self, k), 1e-9, MAX_LENGTH_M, "m")
        return self


class LinkSchema(Closed):
    """A printed tube on the joint before it (a serial arm's LinkModule)."""

    first: Axis | None = None
    rest: Axis | None = None
    names: Name | None = None


class WheelSchema(Closed):
    """A wheel kind's own size (``end = "wheel"``), kept by the sizing."""

    radius: Expr | None = described(None, "the wheel's radius (m, an expression)")
    width: Expr | None = described(None, "the tyre's width (m, an expression)")


class KindSchema(Closed):
    """One part kind: how a structural part (an ontology class) is built."""

    cls: Name = described(alias="class", doc="the ontology class it realises")
    doc: StrictStr = ""
    root: StrictBool = described(False, "a part the others hang on")
    body: Name | None = None
    box: Vec3 | None = described(None, "x, y, z of the root's box (m, expressions)")
    at: Vec3 = [0.0, 0.0, 0.0]
    at_with: dict[Name, Vec3] = {}
    faces: Literal[FACES] = "up"
    payload: Literal[PAYLOAD] = "root"
    order: Literal["", "side"] = ""
    lengths: dict[Name, Length] = described({}, "its named lengths with their defaults (m)")
    joints: list[JointSchema] = []
    end: Literal["", *ENDS] = ""
    role: Literal[ROLES] = ""
    mounts: list[MountSchema] = []
    naming: Literal["", "index"] = ""
    link: LinkSchema | None = None
    mass: Mass | None = described(None, "kg: a tool's (end = 'tool'), more than 0")
    wheel: WheelSchema | None = described(None, "a wheel kind's own radius and width (m)")

    @model_validator(mode="after")
    def _consistent(self) -> KindSchema:
        cls = self.cls
        if self.wheel is not None and self.end != "wheel":
            raise At("wheel", 'only a kind whose end is "wheel" has a wheel size')
        for k in ("radius", "width"):
            v = getattr(self.wheel, k, None) if self.wheel is not None else None
            if v is not None:
                _check_range(f"wheel.{k}", v, 1e-9, MAX_LENGTH_M, "m")
        if self.root and not (self.body and self.box):
            raise At("", f"root part kind {cls} needs a 'body' name and a 'box' [x, y, z]")
        if self.root and not self.mounts:
            raise At("mounts", f"root part kind {cls} has no 'mounts': nothing can hang on it")
        tool = self.end == "tool"
        if tool and (self.joints or self.root or not self.box or self.mass is None):
            raise At(
                "",
                f"tool part kind {cls} (end = 'tool') has no joints and is not a root; it "
                "needs a 'box' [length along the chain, width, height] (m) and a 'mass' (kg)",
            )
        if self.mass is not None and not tool:
            raise At("mass", "only a tool (end = 'tool') has a mass of its own", self.mass)
        if tool and self.mass <= 0:
            raise At("mass", "out of range: a tool's mass is more than 0 kg", self.mass)
        if not self.root and not self.joints and self.link is None and not tool:
            raise At("", f"part kind {cls} has no joints, no link and is not a root")
        for i, v in enumerate(self.box or ()):
            _check_range(f"box[{i}]", v, 1e-9, MAX_LENGTH_M, "m")
        for key, vec in [("at", self.at), *((f"at_with.{c}", v) for c, v in self.at_with.items())]:
            for i, v in enumerate(vec):
                _check_range(f"{key}[{i}]", v, -MAX_LENGTH_M, MAX_LENGTH_M, "m")
        seen: dict[str, int] = {}
        for i, j in enumerate(self.joints):
            if j.name in seen:
                raise At(f"joints[{i}].name", f"repeats the name of joints[{seen[j.name]}]", j.name)
            seen[j.name] = i
            if j.tube is not None and j.tube.length not in self.lengths:
                known = ", ".join(sorted(self.lengths)) or "none"
                raise At(
                    f"joints[{i}].tube.length",
                    f"names no length of this kind's 'lengths' (they are: {known})",
                    j.tube.length,
                )
        return self


def _serial_row(v: object) -> tuple:
    """A ``[serial]`` row: [name, axis, lower, upper] or [..., "link"]."""
    if not isinstance(v, list) or len(v) not in (4, 5):
        raise ValueError('must be [name, axis, lower, upper] or [..., "link"]')
    name, axis, lower, upper, *mark = v
    if mark and mark[0] != "link":
        raise At("[4]", 'the fifth item may only be "link"', mark[0])
    try:
        name = _name(name)
    except ValueError as e:
        raise At("[0]", str(e), name) from None
    if not isinstance(axis, str) or axis not in AXES:
        raise At("[1]", f"not one of {', '.join(map(repr, AXES))}", axis)
    limits = []
    for i, x in ((2, lower), (3, upper)):
        try:
            limits.append(_expression(x))
        except ValueError as e:
            raise At(f"[{i}]", str(e), x) from None
        _check_range(f"[{i}]", x, -MAX_ANGLE_RAD, MAX_ANGLE_RAD, "rad")
    a, b = (_fixed(x) for x in limits)
    if a is not None and b is not None and a >= b:
        raise At("", "the lower limit is not below the upper one", v)
    return (name, axis, limits[0], limits[1], bool(mark))


_ROW_SCHEMA = {
    "type": "array",
    "minItems": 4,
    "maxItems": 5,
    "prefixItems": [
        {"type": "string", "minLength": 1, "description": "joint name (its actuator group)"},
        {"enum": list(AXES)},
        {**_EXPR_SCHEMA, "description": "lower limit (rad)"},
        {**_EXPR_SCHEMA, "description": "upper limit (rad)"},
        {"const": "link", "description": "a printed link follows the joint"},
    ],
}
SerialRow = Annotated[tuple, PlainValidator(_serial_row), WithJsonSchema(_ROW_SCHEMA)]


class DefaultLengthsSchema(Closed):
    first: Length | None = None
    rest: Length | None = None


class SerialSchema(BaseModel):
    """The serial arms' joint table by joint count 1 to 12, and their links' lengths."""

    model_config = ConfigDict(
        extra="allow",
        frozen=True,
        json_schema_extra={"propertyNames": {"pattern": "^(default_lengths|[1-9]|1[0-2])$"}},
    )
    __pydantic_extra__: dict[str, list[SerialRow]]
    default_lengths: DefaultLengthsSchema | None = None

    @model_validator(mode="after")
    def _rows(self) -> SerialSchema:
        for k, rows in (self.__pydantic_extra__ or {}).items():
            if not k.isdigit() or not 1 <= int(k) <= 12:
                raise At(k, "keys are joint counts 1 to 12 (and default_lengths)")
            if len(rows) != int(k):
                raise At(k, f"must list {k} joints [name, axis, lower, upper]", rows)
            names = [r[0] for r in rows]
            for i, n in enumerate(names):
                if n in names[:i]:
                    raise At(f"{k}[{i}]", "joint names repeat", n)
            # an arm's sizing needs its column (the printed link on the first joint) and a
            # link that reaches out (synth/sizing/families.py: the column, then the reach)
            if not rows[0][4]:
                raise At(
                    f"{k}[0]",
                    'the first joint needs the "link" mark: the arm\'s column stands on it',
                    list(rows[0][:4]),
                )
            if sum(r[4] for r in rows) < 2:
                raise At(
                    k,
                    'marks fewer than 2 joints "link": an arm needs its column and a link '
                    "that reaches out",
                )
        return self


class PartKindsFile(Closed):
    """A file of part kinds (kinematics/partkinds.toml, ``--parts FILE.toml``)."""

    format: Literal[1] = described(1, "the format's version")
    constants: dict[Name, Length] = described(
        {},
        f"named constants of the expressions (m or a ratio; more than 0, at most {MAX_LENGTH_M:g})",
    )
    kind: list[KindSchema] = []
    serial: SerialSchema | None = None

    @model_validator(mode="after")
    def _unique(self) -> PartKindsFile:
        seen: dict[str, int] = {}
        for i, k in enumerate(self.kind):
            if k.cls in seen:
                raise At(
                    f"kind[{i}].class",
                    f"repeats the class of kind[{seen[k.cls]}]: which one is used is not said",
                    k.cls,
                )
            seen[k.cls] = i
        return self


def _parse(sources: Sequence[tuple[str, str]]) -> PartKinds:
    from adron.readers import parse_toml

    kinds: dict[str, PartKind] = {}
    serial: dict[int, tuple] = {}
    serial_lengths: dict[str, float] = {}
    constants: dict[str, float] = {}
    for name, text in sources:
        try:
            data = parse_toml(text, name)
        except InputError as e:
            raise PartKindError(str(e)) from None
        f = validate(PartKindsFile, data, name, PartKindError)
        constants.update(f.constants)
        for i, k in enumerate(f.kind):
            kinds[k.cls] = _kind_of(k, f"{name}: kind[{i}] ({k.cls})")
        if f.serial is not None:
            if f.serial.default_lengths is not None:
                given = f.serial.default_lengths.model_dump(exclude_none=True)
                serial_lengths.update(given)
            for k, rows in (f.serial.__pydantic_extra__ or {}).items():
                serial[int(k)] = tuple(rows)
    return PartKinds(
        MappingProxyType(kinds),
        MappingProxyType(serial),
        MappingProxyType(serial_lengths),
        MappingProxyType(constants),
        tuple(n for n, _ in sources),
        tuple(sources[1:]),
    )


def _kind_of(k: KindSchema, where: str) -> PartKind:
    """The PartKind of a validated kind."""
    return PartKind(
        cls=k.cls,
        where=where,
        doc=k.doc,
        root=k.root,
        body=k.body or "",
        box=tuple(k.box) if k.box else (),
        at=tuple(k.at),
        at_with={c: tuple(v) for c, v in k.at_with.items()},
        faces=k.faces,
        payload=k.payload,
        order=k.order,
        lengths=dict(k.lengths),
        joints=tuple(
            KindJoint(
                name=j.name,
                kind=j.kind,
                axis=j.axis,
                axes=tuple(j.axes),
                limits=(j.limits[0], j.limits[1]),
                group=j.group,
                module=j.module
                or (
                    "ContinuousRotationServomotor"
                    if j.kind == "continuous" and not j.passive
                    else ""
                ),
                actuator_on_parent=j.actuator_on_parent,
                tube_length=j.tube.length if j.tube else "",
                tube_along=j.tube.along if j.tube else "x",
                body=j.body,
                passive=j.passive,
            )
            for j in k.joints
        ),
        end=k.end,
        role=k.role,
        mounts=tuple(
            Mount(
                child=m.child,
                layout=m.layout,
                span="" if m.span is None else str(m.span),
                track="" if m.track is None else str(m.track),
                at=tuple(m.at),
                links=m.links or "",
            )
            for m in k.mounts
        ),
        naming=k.naming,
        link=k.link.model_dump(exclude_none=True) if k.link else {},
        mass=k.mass or 0.0,
        wheel=k.wheel.model_dump(exclude_none=True) if k.wheel else {},
    )
