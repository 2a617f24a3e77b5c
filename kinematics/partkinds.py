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
  ... instead of L1, L2 ...: an arm on a chassis whose own lengths are L1 and L2) or tip
  (at the end of the part's chain);
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
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType

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
LAYOUTS = ("bilateral", "radial", "pair", "axle", "trailing", "front", "serial", "tip")
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
class JointSpec:
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
    joints: tuple[JointSpec, ...] = ()
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


def _parse(sources: Sequence[tuple[str, str]]) -> PartKinds:
    kinds: dict[str, PartKind] = {}
    serial: dict[int, tuple] = {}
    serial_lengths: dict[str, float] = {}
    constants: dict[str, float] = {}
    for name, text in sources:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise PartKindError(f"{name}: not valid TOML: {e}") from None
        except RecursionError:
            raise PartKindError(f"{name}: nested too deeply") from None
        _Reader(name, data, kinds, serial, serial_lengths, constants).read()
    return PartKinds(
        MappingProxyType(kinds),
        MappingProxyType(serial),
        MappingProxyType(serial_lengths),
        MappingProxyType(constants),
        tuple(n for n, _ in sources),
        tuple(sources[1:]),
    )


class _Reader:
    """Reads one file into the tables, checking every key."""

    def __init__(self, name, data, kinds, serial, serial_lengths, constants) -> None:
        self.name, self.data = name, data
        self.kinds, self.serial = kinds, serial
        self.serial_lengths, self.constants = serial_lengths, constants

    def fail(self, key: str, why: str):
        raise PartKindError(f"{self.name}: {key}: {why}")

    def read(self) -> None:
        d = self.data
        known = {"format", "constants", "kind", "serial"}
        self.only("", d, known)
        if d.get("format", 1) != 1:
            self.fail("format", f"format {d.get('format')!r} is not 1")
        consts = d.get("constants", {})
        if not isinstance(consts, dict):
            self.fail("constants", "must be a table of numbers")
        for k, v in consts.items():
            self.constants[k] = self.number(f"constants.{k}", v, positive=False)
        kinds = d.get("kind", [])
        if not isinstance(kinds, list):
            self.fail("kind", "must be an array of tables ([[kind]])")
        for i, k in enumerate(kinds):
            kind = self.kind(f"kind[{i}]", k)
            self.kinds[kind.cls] = kind
        if "serial" in d:
            self.read_serial(d["serial"])

    def only(self, key: str, d: dict, allowed: set[str]) -> None:
        """Refuse a key of table ``d`` (at ``key``) not in ``allowed``."""
        for k in d:
            if k not in allowed:
                where = f"{key}.{k}" if key else k
                self.fail(where, f"unknown key (keys: {', '.join(sorted(allowed))})")

    def number(self, key: str, v, positive: bool = True) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(key, f"{v!r} is not a finite number")
        if positive and v <= 0:
            self.fail(key, f"{v!r} must be positive")
        return float(v)

    def expr(self, key: str, v) -> float | str:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return self.number(key, v, positive=False)
        if not isinstance(v, str):
            self.fail(key, f"{v!r} is not a number or an expression")
        try:
            _names(v)
        except (ValueError, SyntaxError):
            self.fail(key, f"{v!r} is not an arithmetic expression of names and numbers")
        return v

    def word(self, key: str, v, choices: Sequence[str]) -> str:
        if v not in choices:
            self.fail(key, f"{v!r} is not one of {', '.join(repr(c) for c in choices)}")
        return v

    def text(self, key: str, v) -> str:
        if not isinstance(v, str) or not v:
            self.fail(key, f"{v!r} is not a non-empty string")
        return v

    def vec(self, key: str, v, n: int = 3) -> tuple:
        if not isinstance(v, list) or len(v) != n:
            self.fail(key, f"must be a list of {n} numbers or expressions")
        return tuple(self.expr(f"{key}[{i}]", x) for i, x in enumerate(v))

    def kind(self, key: str, d) -> PartKind:
        if not isinstance(d, dict):
            self.fail(key, "must be a table")
        allowed = {
            "class",
            "doc",
            "root",
            "body",
            "box",
            "at",
            "at_with",
            "faces",
            "payload",
            "order",
            "lengths",
            "joints",
            "end",
            "role",
            "mounts",
            "naming",
            "link",
            "mass",
            "wheel",
        }
        self.only(key, d, allowed)
        cls = self.text(f"{key}.class", d.get("class"))
        where = f"{self.name}: {key} ({cls})"
        root = d.get("root", False)
        if not isinstance(root, bool):
            self.fail(f"{key}.root", "must be true or false")
        lengths = d.get("lengths", {})
        if not isinstance(lengths, dict):
            self.fail(f"{key}.lengths", "must be a table of lengths (m)")
        lengths = {k: self.number(f"{key}.lengths.{k}", v) for k, v in lengths.items()}
        joints = d.get("joints", [])
        if not isinstance(joints, list):
            self.fail(f"{key}.joints", "must be a list of joint tables")
        specs = tuple(self.joint(f"{key}.joints[{i}]", j) for i, j in enumerate(joints))
        mounts = d.get("mounts", [])
        if not isinstance(mounts, list):
            self.fail(f"{key}.mounts", "must be a list of mount tables")
        at_with = d.get("at_with", {})
        if not isinstance(at_with, dict):
            self.fail(f"{key}.at_with", "must be a table: child class -> [x, y, z]")
        link = d.get("link", {})
        if not isinstance(link, dict):
            self.fail(f"{key}.link", "must be a table")
        for k in ("first", "rest"):
            if k in link:
                self.word(f"{key}.link.{k}", link[k], tuple(AXES))
        kind = PartKind(
            cls=cls,
            where=where,
            doc=str(d.get("doc", "")),
            root=root,
            body=self.text(f"{key}.body", d["body"]) if "body" in d else "",
            box=self.vec(f"{key}.box", d["box"]) if "box" in d else (),
            at=self.vec(f"{key}.at", d["at"]) if "at" in d else (0.0, 0.0, 0.0),
            at_with={c: self.vec(f"{key}.at_with.{c}", v) for c, v in at_with.items()},
            faces=self.word(f"{key}.faces", d.get("faces", "up"), FACES),
            payload=self.word(f"{key}.payload", d.get("payload", "root"), PAYLOAD),
            order=self.word(f"{key}.order", d.get("order", ""), ("", "side")),
            lengths=lengths,
            joints=specs,
            end=self.word(f"{key}.end", d.get("end", ""), ("", *ENDS)) if "end" in d else "",
            role=self.word(f"{key}.role", d.get("role", ""), ROLES),
            mounts=tuple(self.mount(f"{key}.mounts[{i}]", m) for i, m in enumerate(mounts)),
            naming=self.word(f"{key}.naming", d.get("naming", ""), ("", "index")),
            link={k: str(v) for k, v in link.items()},
            mass=self.number(f"{key}.mass", d["mass"]) if "mass" in d else 0.0,
            wheel=self.wheel(f"{key}.wheel", d.get("wheel", {}), d.get("end", "")),
        )
        if root and not (kind.body and len(kind.box) == 3):
            self.fail(key, f"root part kind {cls} needs a 'body' name and a 'box' [x, y, z]")
        tool = kind.end == "tool"
        if tool and (specs or root or len(kind.box) != 3 or "mass" not in d):
            self.fail(
                key,
                f"tool part kind {cls} (end = 'tool') has no joints and is not a root; it "
                "needs a 'box' [length along the chain, width, height] (m) and a 'mass' (kg)",
            )
        if "mass" in d and not tool:
            self.fail(f"{key}.mass", "only a tool (end = 'tool') has a mass of its own")
        if not root and not specs and not link and not tool:
            self.fail(key, f"part kind {cls} has no joints, no link and is not a root")
        return kind

    def wheel(self, key: str, d, end: str) -> Mapping[str, float | str]:
        if not isinstance(d, dict):
            self.fail(key, "must be a table: radius, width (expressions, m)")
        self.only(key, d, {"radius", "width"})
        if d and end != "wheel":
            self.fail(key, 'only a kind whose end is "wheel" has a wheel size')
        return {k: self.expr(f"{key}.{k}", v) for k, v in d.items()}

    def joint(self, key: str, d) -> JointSpec:
        if not isinstance(d, dict):
            self.fail(key, "must be a table")
        allowed = {
            "name",
            "kind",
            "axis",
            "axes",
            "limits",
            "group",
            "module",
            "actuator_on_parent",
            "tube",
            "body",
            "passive",
        }
        self.only(key, d, allowed)
        name = self.text(f"{key}.name", d.get("name"))
        kind = self.word(f"{key}.kind", d.get("kind", "revolute"), JOINT_KINDS)
        axis = self.word(f"{key}.axis", d.get("axis", "z"), (*AXES, "across"))
        axes = d.get("axes", [])
        if not isinstance(axes, list):
            self.fail(f"{key}.axes", "must be a list of axes")
        axes = tuple(self.word(f"{key}.axes[{i}]", a, tuple(AXES)) for i, a in enumerate(axes))
        limits = self.vec(f"{key}.limits", d["limits"], 2) if "limits" in d else ("-pi", "pi")
        tube = d.get("tube", {})
        if not isinstance(tube, dict) or (tube and "length" not in tube):
            self.fail(f"{key}.tube", "must be a table with a 'length' name and 'along'")
        aop = d.get("actuator_on_parent", False)
        if not isinstance(aop, bool):
            self.fail(f"{key}.actuator_on_parent", "must be true or false")
        passive = d.get("passive", False)
        if not isinstance(passive, bool):
            self.fail(f"{key}.passive", "must be true or false")
        if passive and kind == "fixed":
            self.fail(f"{key}.passive", "a fixed joint does not move: it cannot be passive")
        if passive:
            given = [k for k in ("module", "group", "actuator_on_parent") if k in d]
            if given:
                self.fail(
                    f"{key}.{given[0]}",
                    f"joint {name!r} is passive (it turns freely on a bearing, no actuator "
                    f"drives it): it takes no {given[0]!r}",
                )
        default_module = (
            "ContinuousRotationServomotor" if kind == "continuous" and not passive else ""
        )
        return JointSpec(
            name=name,
            kind=kind,
            axis=axis,
            axes=axes,
            limits=limits,
            group=str(d.get("group", "")),
            module=str(d.get("module", default_module)),
            actuator_on_parent=aop,
            tube_length=self.text(f"{key}.tube.length", tube["length"]) if tube else "",
            tube_along=self.word(f"{key}.tube.along", tube.get("along", "x"), tuple(AXES))
            if tube
            else "x",
            body=str(d.get("body", "")),
            passive=passive,
        )

    def mount(self, key: str, d) -> Mount:
        if not isinstance(d, dict):
            self.fail(key, "must be a table")
        allowed = {"child", "layout", "span", "track", "at", "links"}
        self.only(key, d, allowed)
        layout = self.word(f"{key}.layout", d.get("layout"), LAYOUTS)
        span = str(self.expr(f"{key}.span", d["span"])) if "span" in d else ""
        track = str(self.expr(f"{key}.track", d["track"])) if "track" in d else ""
        if layout in ("bilateral", "radial", "axle") and not (span and track):
            self.fail(key, f"layout {layout} needs 'span' and 'track'")
        if layout in ("trailing", "front") and not span:
            self.fail(key, f"layout {layout} needs 'span'")
        return Mount(
            child=self.text(f"{key}.child", d.get("child")),
            layout=layout,
            span=span,
            track=track,
            at=self.vec(f"{key}.at", d["at"]) if "at" in d else (0.0, 0.0, 0.0),
            links=self.text(f"{key}.links", d["links"]) if "links" in d else "",
        )

    def read_serial(self, d) -> None:
        if not isinstance(d, dict):
            self.fail("serial", "must be a table")
        for k, v in d.items():
            if k == "default_lengths":
                if not isinstance(v, dict) or set(v) - {"first", "rest"}:
                    self.fail("serial.default_lengths", "must be {first = m, rest = m}")
                for kk, x in v.items():
                    self.serial_lengths[kk] = self.number(f"serial.default_lengths.{kk}", x)
                continue
            if not k.isdigit() or not 1 <= int(k) <= 12:
                self.fail(f"serial.{k}", "keys are joint counts 1 to 12 (and default_lengths)")
            if not isinstance(v, list) or len(v) != int(k):
                self.fail(f"serial.{k}", f"must list {k} joints [name, axis, lower, upper]")
            rows = []
            for i, row in enumerate(v):
                rk = f"serial.{k}[{i}]"
                if not isinstance(row, list) or len(row) not in (4, 5):
                    self.fail(rk, 'must be [name, axis, lower, upper] or [..., "link"]')
                if len(row) == 5 and row[4] != "link":
                    self.fail(rk, f'the fifth item may only be "link", got {row[4]!r}')
                rows.append(
                    (
                        self.text(rk, row[0]),
                        self.word(rk, row[1], tuple(AXES)),
                        self.expr(rk, row[2]),
                        self.expr(rk, row[3]),
                        len(row) == 5,
                    )
                )
            names = [r[0] for r in rows]
            if len(set(names)) != len(names):
                self.fail(f"serial.{k}", "joint names repeat")
            self.serial[int(k)] = tuple(rows)
