"""The controller API: behaviours with plain parameters that return joint trajectories.

A :class:`Controller` belongs to one design. It lists its behaviours (named by the
ontology's ability short names: ``walking``, ``rolling``, ``driving``, ``pick-and-place``
...) with typed, documented parameters (:class:`BehaviorSpec`), so that command-line
options, ROS services and drag-and-drop blocks can all be generated from the same
description; ``run(name, **params)`` returns a :class:`Trajectory`.

Controllers read the design from its record (``design.json``) through
:class:`DesignGeometry` and rebuild its kinematic template; ``gaits`` imports nothing of
parmor but ``kinematics``.
"""

from __future__ import annotations

import io
import math
import os
from abc import ABC, abstractmethod
from collections import OrderedDict
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import BinaryIO

import numpy as np

from kinematics.bodyplan import BodyPlan
from kinematics.partkinds import PartKindError, load_texts, use
from kinematics.templates import Template, TemplateParams, build, register_plan


def use_recorded_kinds(entries) -> None:
    """Assemble with the shipped part kinds and the user's ones a design record carries
    (``part_kinds``: ``{"file", "toml"}`` each): its bundle needs no ``--parts`` file.
    ValueError (a ``PartKindError``) when they cannot be read."""

    try:
        texts = [(str(e["file"]), str(e["toml"])) for e in entries]
    except (TypeError, KeyError):
        raise PartKindError(
            "design.json: part_kinds must be a list of {file, toml} tables"
        ) from None
    use(load_texts(texts))


def quat_yaw(quat) -> float:
    """Yaw rad of a (w, x, y, z) quaternion (a free body's ``qpos[3:7]``): the heading every
    controller and verdict measures a robot's turn by."""
    w, x, y, z = (float(c) for c in quat)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def min_jerk(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk profile ``s = 10 t^3 - 15 t^4 + 6 t^5`` on ``tau`` in [0, 1] (clipped)
    and its first and second derivatives: s rises from 0 to 1 with s' and s'' zero at both
    ends. Every behaviour's smooth segments use it."""
    t = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    s = t**3 * (10 - 15 * t + 6 * t * t)
    ds = 30 * t * t * (1 - t) ** 2
    dds = 60 * t * (1 - t) * (1 - 2 * t)
    return s, ds, dds


def min_jerk_integral(tau: np.ndarray) -> np.ndarray:
    """The integral of the minimum-jerk profile from 0 to ``tau`` (clipped to [0, 1])."""
    t = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    return t**4 * (2.5 - 3 * t + t * t)


@dataclass(frozen=True)
class Trajectory:
    """Joint references over time for one behaviour.

    ``times`` (N,) s from 0, increasing; ``positions`` and ``velocities`` (N, nj) in rad and
    rad/s for ``joints``; position servos follow ``positions``, wheels (continuous joints)
    follow ``velocities``. ``info`` carries what the behaviour promises and a simulation
    can check: ``command`` ((v m/s, w rad/s) for driving), ``target`` ((x, y, z) m, where
    a manipulator places its payload), ``stability_margin_m`` ((N,) for legged gaits),
    ``direction`` ((x, y) unit vector of the intended travel)...

    What the behaviour promises, judged by :mod:`synth.verification.verdict` on the simulated
    outcome:

    - ``motion``: ``"straight"`` (travel a line), ``"arc"`` (drive an arc), ``"turn"``
      (turn in place), ``"crawl"`` (a snake gait: progress along ``direction``),
      ``"rotate"`` (turn in the sense ``turn``, +1 counter-clockwise from above),
      ``"hold"`` (stay up and stay put), ``"place"`` (bring the gripper to ``target``,
      measured at ``placed_at_s``) or ``"orient"`` (``target`` and ``orientation_rpy``).
    - ``planned_pose``: (dx m, dy m, dyaw rad), the root's commanded displacement in the
      world frame from its start position and its commanded change of yaw (straight, arc,
      turn).
    - ``path_length_m``: length of the commanded path (arc; default |(dx, dy)|).
    - ``body_length_m``: the robot's body length (crawl, rotate, legged travel).
    - ``locomotion``: ``"legged"``, ``"snake"`` or ``"wheeled"``.
    """

    behavior: str
    times: np.ndarray
    joints: tuple[str, ...]
    positions: np.ndarray
    velocities: np.ndarray
    info: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n, nj = len(self.times), len(self.joints)
        if self.positions.shape != (n, nj) or self.velocities.shape != (n, nj):
            raise ValueError(
                f"trajectory {self.behavior!r}: positions and velocities must be ({n}, {nj})"
            )
        if n < 2 or np.any(np.diff(self.times) <= 0) or self.times[0] != 0:
            raise ValueError(f"trajectory {self.behavior!r}: times must start at 0 and rise")

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(positions, velocities) at time ``t`` s (linear interpolation, held at the ends)."""
        q = np.array(
            [np.interp(t, self.times, self.positions[:, k]) for k in range(len(self.joints))]
        )
        v = np.array(
            [np.interp(t, self.times, self.velocities[:, k]) for k in range(len(self.joints))]
        )
        return q, v

    def csv(self) -> str:
        """Deterministic CSV: ``t`` then one position column per joint (rad)."""
        out = io.StringIO()
        out.write(",".join(["t", *self.joints]) + "\n")
        line = ",".join(["%.6f"] * (1 + len(self.joints))) + "\n"  # as f"{x:.6f}" writes
        rows = np.column_stack([self.times, self.positions]).tolist()
        out.write("".join(line % tuple(row) for row in rows))
        return out.getvalue()


#: The value an ``own`` parameter (:class:`Parameter`) is planned with when it is at its
#: default: "work it out" (the controllers' plans read 0 so). Programs written before the
#: defaults were the design's values carry it too (``speed=0.0``): it is still accepted for
#: an ``own`` parameter, outside its range, and means the same; the block page never shows
#: it (its field shows the default and refuses values outside [low, high]).
AUTO = 0.0


def significant(x: float, digits: int = 3, down: bool = False, up: bool = False) -> float:
    """``x`` to ``digits`` significant digits (the nearest; towards -inf when ``down``,
    towards +inf when ``up``): how a design's own value or limit is declared (``0.0497``
    m/s, not ``0.04973261``; a highest value down, a lowest up, so that they stay
    feasible)."""
    if x == 0 or not math.isfinite(x):
        return float(x)
    if not (down or up):
        return float(f"{x:.{digits}g}")
    e = math.floor(math.log10(abs(x))) - digits + 1
    m = x / 10.0**e
    k = math.floor(m * (1 + 1e-12)) if down else math.ceil(m * (1 - 1e-12))
    if x < 0:
        k = math.floor(m * (1 - 1e-12)) if down else math.ceil(m * (1 + 1e-12))
    return float(f"{k}e{e}")


@dataclass(frozen=True)
class Parameter:
    """A behaviour parameter: name, kind ("float" | "int" | "choice"), default, unit, doc,
    and its range [``low``, ``high``] (None: unbounded).

    ``own``: the default is the design's own value, which the plan works out from the
    other parameters' values (the design's speed slowed down to what its actuators reach
    with the asked gait and direction, the legs' automatic stride, a turn's duration for
    the asked angle...); it is declared as the value the plan uses with every other
    parameter at its default. A value equal to the default, or :data:`AUTO` (0: what
    programs of earlier versions carry), plans as when the parameter is not given
    (:meth:`BehaviorSpec.planned`), so that a block left at its default, a ROS call and the
    Python API plan the same; any other value is the user's own (a speed beyond what the
    actuators reach is refused, not slowed down)."""

    name: str
    kind: str
    default: object
    doc: str
    unit: str = ""
    choices: tuple[str, ...] = ()
    low: float | None = None
    high: float | None = None
    own: bool = False

    def check(self, value: object) -> object:
        """The value converted to the parameter's kind; ValueError naming it otherwise
        (a value outside [low, high] with the bound it passes)."""
        if self.kind == "choice":
            if value not in self.choices:
                raise ValueError(
                    f"{self.name}: expected one of {', '.join(self.choices)}, got {value!r}"
                )
            return value
        try:
            x = int(value) if self.kind == "int" else float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{self.name}: expected a number, got {value!r}") from None
        if x != x:  # NaN passes every comparison below
            raise ValueError(f"{self.name}: expected a number, got {value!r}")
        if self.own and x == AUTO:
            return x
        if (self.low is not None and x < self.low) or (self.high is not None and x > self.high):
            lo = "-inf" if self.low is None else f"{self.low:g}"
            hi = "inf" if self.high is None else f"{self.high:g}"
            raise ValueError(f"{self.name}: {x:g} is outside [{lo}, {hi}]")
        return x


@dataclass(frozen=True)
class BehaviorSpec:
    """A behaviour a controller offers: the ability it realises and its parameters.

    ``ability`` is the ability short name the behaviour realises or belongs to (None: its
    own name); e.g. a legged robot's ``turning`` belongs to ``walking``. A behaviour serves
    its ability and every subclass of it in the ontology's action taxonomy (:func:`serving`):
    a design lists and verifies the behaviours of the abilities that serve its own.
    ``alias_of`` names the behaviour this one repeats under another name (not verified
    twice)."""

    name: str
    doc: str
    params: tuple[Parameter, ...] = ()
    ability: str | None = None
    alias_of: str | None = None

    @property
    def realises(self) -> str:
        """The ability this behaviour realises."""
        return self.ability or self.name

    def resolve(self, given: Mapping[str, object]) -> dict[str, object]:
        known = {p.name: p for p in self.params}
        unknown = sorted(set(given) - set(known))
        if unknown:
            raise ValueError(
                f"behaviour {self.name!r} has no parameter {unknown[0]!r} "
                f"(parameters: {', '.join(known) or 'none'})"
            )
        return {
            p.name: p.check(given[p.name]) if p.name in given else p.default for p in self.params
        }

    def planned(self, resolved: Mapping[str, object]) -> dict[str, object]:
        """What the controller plans with for ``resolved`` values (:meth:`resolve`'s): an
        ``own`` parameter at its default (or at :data:`AUTO`) becomes :data:`AUTO`, "the
        design's own for the other values"; every other value as it is."""
        out = dict(resolved)
        for p in self.params:
            if p.own and p.name in out and out[p.name] in (p.default, AUTO):
                out[p.name] = 0 if p.kind == "int" else AUTO
        return out


def pace_parameter(spec: BehaviorSpec) -> str | None:
    """The parameter of ``spec`` that sets how fast the behaviour goes: the one a sensing
    loop steers as its ``speed`` (``gaits.steering.SteerableSpec``: a legged robot's
    ``speed``, a humanoid's ``step_length``, a snake's wave ``frequency``...), else one
    named ``speed``; None when it has none. Lowering it slows the joints down (the pace a
    robust verification may choose, :attr:`DesignGeometry.paces`)."""
    names = {p.name: p for p in spec.params}
    name = dict(getattr(spec, "steer", ())).get("speed") or ("speed" if "speed" in names else None)
    p = names.get(name) if name else None
    return name if p is not None and p.kind == "float" else None


def serving(
    ability: str, ancestors: Mapping[str, Sequence[str]], offered: Collection[str]
) -> str | None:
    """The ability whose behaviours serve ``ability``: itself when it is ``offered``, else
    the nearest of its ``ancestors`` (ability -> the abilities it is a subclass of, nearest
    first: the design record's ``ability_ancestors``) that is; None when none is (no
    behaviour serves it). E.g. a KIF ``heavy-walking`` under ``walking`` is served by the
    walking behaviours."""
    for a in (ability, *ancestors.get(ability, ())):
        if a in offered:
            return a
    return None


@dataclass(frozen=True)
class DesignGeometry:
    """What a controller needs of a sized design, read from its record (design.json)."""

    robot_type: str  # the design's type (maybe a user's subclass)
    template: str  # the kinematic template it was sized with
    lengths: Mapping[str, float]
    modules: int
    wheel_radius: float
    params: Mapping[str, float]  # the structural parameters used (SI)
    abilities: tuple[str, ...]
    joint_speed: Mapping[str, float]  # rad/s the chosen actuator reaches (no load)
    mass_kg: float = 0.0  # the whole robot's mass with its payload, kg (0: unknown)
    joint_torque: Mapping[str, float] = field(default_factory=dict)  # stall torque, N m
    #: figures of the design measured on a run, not derivable from its geometry (the
    #: record's ``calibration``, e.g. a skid-steer's ``effective_track_m``): see
    #: :meth:`Controller.calibrate`
    calibration: Mapping[str, float] = field(default_factory=dict)
    #: ability -> the abilities it is a subclass of, nearest first (the record's
    #: ``ability_ancestors``, from the ontology's action taxonomy): which behaviours serve
    #: an ability that has none of its own (:func:`serving`); gaits read no ontology
    ancestors: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    #: the catalog classes of the design's sensor modules (the record's ``modules`` whose
    #: kind is a ``...SensorModule``), sorted: what its feedback loops may read
    #: (:mod:`gaits.feedback`; an IMU only where the ontology made the design carry one)
    sensors: tuple[str, ...] = ()
    #: behaviour -> the scale of its feedback loop's gains (the record's ``feedback_gains``:
    #: chosen by the robust verification, :mod:`synth.verification.gains`); a plan of that
    #: behaviour carries it in ``info["feedback"]["gain_scale"]``
    feedback_gains: Mapping[str, float] = field(default_factory=dict)
    #: behaviour -> the default of its pace parameter (:func:`pace_parameter`: how fast it
    #: goes) that the robust verification chose because the servos' command hold
    #: saturated it at the design's own (the record's ``paces``,
    #: :mod:`synth.verification.hold`); a caller's own value still wins
    paces: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_record(cls, record: Mapping) -> DesignGeometry:
        """From a design record with a structure (``parmor design --json``); the record's
        body plan becomes its type's plan in this process (``register_plan``), so that a
        bundle is rebuilt without the ontology that made it."""
        if record.get("template") is None:
            raise ValueError("the design record has no structure (designed with --conceptual?)")
        if record.get("part_kinds"):  # the user's part kinds it was designed with
            use_recorded_kinds(record["part_kinds"])
        if record.get("body_plan"):
            register_plan(BodyPlan.from_dict(record["body_plan"]))
        return cls(
            robot_type=record["robot_type"],
            template=record["template"],
            lengths=dict(record["lengths_m"]),
            modules=int(record.get("dof") or 1),
            wheel_radius=float(record.get("wheel_radius_m") or 0.03),
            params=dict(record.get("params", {})),
            abilities=tuple(record.get("abilities", ())),
            joint_speed={
                j["name"]: float(j.get("no_load_speed_rad_s", 0.0))
                for j in record.get("joints", [])
            },
            # the loaded mass: what the motors move (older records kept it in mass_kg)
            mass_kg=float(record.get("loaded_mass_kg") or record.get("mass_kg") or 0.0),
            joint_torque={
                j["name"]: float(j.get("actuator_torque_Nm") or 0.0)
                for j in record.get("joints", [])
            },
            calibration={k: float(v) for k, v in (record.get("calibration") or {}).items()},
            feedback_gains={
                str(k): float(v) for k, v in (record.get("feedback_gains") or {}).items()
            },
            paces={str(k): float(v) for k, v in (record.get("paces") or {}).items()},
            ancestors={
                str(k): tuple(str(a) for a in v)
                for k, v in (record.get("ability_ancestors") or {}).items()
            },
            sensors=tuple(
                sorted(
                    {
                        str(m["kind"])
                        for m in record.get("modules") or ()
                        if str(m.get("kind", "")).endswith("SensorModule")
                    }
                )
            ),
        )

    def build(self) -> Template:
        """The design's kinematic template (geometry; masses do not matter to gaits)."""
        return build(
            self.template,
            TemplateParams(
                lengths=self.lengths, modules=self.modules, wheel_radius=self.wheel_radius
            ),
        )


#: Environment variable naming the folder of parmor's caches ("" turns them off); the
#: same as ``adron.units.CACHE_ENV`` (gaits import nothing of adron).
CACHE_ENV = "PARMOR_CACHE"


def cache_write(
    path: Path, write: Callable[[BinaryIO], None], prefix: str, keep: int | None = None
) -> None:
    """``write`` (into a binary file) made the cache entry ``path``: a temporary file
    renamed over it (concurrent writers write the same bytes, no reader sees half a file),
    then the oldest ``prefix*`` entries beyond ``keep`` deleted; a folder that cannot be
    written only means no cache. (``adron.units.write_cache_file`` and ``prune_cache`` do
    the same for adron and synth: docs/architecture.md has gaits import nothing of adron, and adron
    nothing of ours.)"""
    import contextlib
    import tempfile

    tmp = None
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)  # private: cache_folder
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{prefix}", suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, path)
        tmp = None
        if keep is not None:
            old = sorted(path.parent.glob(f"{prefix}*"), key=lambda p: p.stat().st_mtime_ns)
            for p in old[: max(0, len(old) - keep)]:
                with contextlib.suppress(OSError):
                    p.unlink()
    except OSError:
        pass
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def cache_folder() -> Path | None:
    """The folder of parmor's caches: ``$PARMOR_CACHE``, else ``$XDG_CACHE_HOME/parmor``,
    else ``~/.cache/parmor``; None when ``PARMOR_CACHE`` is set empty (no cache), or when
    another user owns the folder or may write it (a one-line warning; the same rule and
    words as ``adron.units.cache_folder``, which gaits may not import: a test holds them
    equal)."""
    env = os.environ.get(CACHE_ENV)
    if env is not None:
        if not env.strip():
            return None
        folder = Path(env)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        folder = Path(base) / "parmor"
    why = unsafe_cache_folder(folder)
    if why is not None:
        import contextlib
        import sys

        # once per process: adron.units warns with the same words (read, not imported)
        other = getattr(sys.modules.get("adron.units"), "_WARNED", set())
        if str(folder) not in _WARNED | other:
            _WARNED.add(str(folder))
            with contextlib.suppress(OSError, ValueError):
                sys.stderr.write(
                    f"parmor: warning: not using the cache folder {folder} ({CACHE_ENV}): {why}\n"
                )
        return None
    return folder


_WARNED: set[str] = set()


def unsafe_cache_folder(folder: Path) -> str | None:
    """Why ``folder`` must not hold parmor's caches (another user owns it or may write
    it), or None when it may (absent: made 0700 when first written); see
    ``adron.units.unsafe_cache_folder``."""
    import stat

    getuid = getattr(os, "getuid", None)
    if getuid is None:
        return None
    try:
        st = os.stat(folder)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode):
        return None
    if st.st_uid != getuid():
        return f"it belongs to another user (uid {st.st_uid})"
    if st.st_mode & 0o022:
        who = (
            "its group and others"
            if st.st_mode & 0o002 and st.st_mode & 0o020
            else ("others" if st.st_mode & 0o002 else "its group")
        )
        return f"{who} may write it (mode {stat.S_IMODE(st.st_mode):04o}; chmod go-w fixes it)"
    return None


#: Trajectories already planned in this process, by (controller identity, behaviour,
#: resolved parameters): a design plans each behaviour to size it, to write it into the
#: bundle and to simulate it, with the same geometry; the gaits are deterministic.
_PLANNED: OrderedDict[tuple, Trajectory] = OrderedDict()
_PLANNED_MAX = 64


class _NotPlain(Exception):
    pass


def _plain(value: object) -> object:
    """``value`` as a hashable key if it is plain data (numbers, strings, sequences and
    mappings of them), else None."""
    try:
        return _key(value)
    except _NotPlain:
        return None


def _key(value: object) -> object:
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, Mapping):
        return tuple(sorted((str(k), _key(v)) for k, v in value.items()))
    if isinstance(value, (tuple, list, np.ndarray)):
        return tuple(_key(v) for v in value)
    raise _NotPlain


class Controller(ABC):
    """The behaviours of one design."""

    #: Fields of ``DesignGeometry`` that this controller never reads: designs that differ
    #: only in them share their plans (``gaits.controller_for`` leaves them out of the
    #: controller's ``identity``), e.g. a design sized, then its record with its masses.
    PLAN_IGNORES: frozenset[str] = frozenset()

    def __init__(self, geometry: DesignGeometry) -> None:
        self.geometry = geometry
        self.template = geometry.build()
        #: what identifies this controller's plans (set by ``gaits.controller_for``): None
        #: when it was given something that is not plain data (e.g. a function)
        self.identity: tuple | None = None

    @property
    @abstractmethod
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        """Behaviour name -> its description (names are ability short names)."""

    @abstractmethod
    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        """The trajectory of behaviour ``name`` with resolved parameters."""

    def run(self, name: str, **params: object) -> Trajectory:
        """The joint trajectory of behaviour ``name``; ValueError for unknown names or
        parameters (the message lists the valid ones)."""
        spec = self.behaviors.get(name)
        if spec is None:
            raise ValueError(
                f"{self.geometry.robot_type} has no behaviour {name!r} "
                f"(behaviours: {', '.join(sorted(self.behaviors))})"
            )
        pace = self.geometry.paces.get(name)
        if pace is not None and (key := pace_parameter(spec)) and key not in params:
            # the pace the design's verification chose (a caller's own value wins)
            params = {**params, key: pace}
        traj = self._planned(name, spec.planned(spec.resolve(params)))
        scale = self.geometry.feedback_gains.get(name)
        feedback = traj.info.get("feedback")
        if scale is None or not feedback:
            return traj
        # the loop's gains the design's verification chose: in the plan, so that every
        # runner of it (simulate, run, the ROS node, the block page) runs them
        return replace(traj, info={**traj.info, "feedback": {**feedback, "gain_scale": scale}})

    def offered(self, name: str) -> BehaviorSpec:
        """Behaviour ``name``'s description as a program sees it: its pace parameter's
        default is the pace the design's verification chose, where it chose one
        (:attr:`DesignGeometry.paces`; what :meth:`run` plans when none is given)."""
        spec = self.behaviors[name]
        pace = self.geometry.paces.get(name)
        key = pace_parameter(spec) if pace is not None else None
        if key is None:
            return spec
        params = tuple(replace(p, default=pace) if p.name == key else p for p in spec.params)
        return replace(spec, params=params)

    def _planned(self, name: str, resolved: Mapping[str, object]) -> Trajectory:
        """The trajectory of behaviour ``name`` with ``resolved`` values (``own``
        parameters at their defaults already :data:`AUTO`), remembered in this process by
        the controller's identity: :meth:`run` and a controller working out its own
        defaults (from the plans at :data:`AUTO`) share the plans."""
        if self.identity is None:
            return self._run(name, resolved)
        key = (self.identity, name, _plain(resolved))
        traj = _PLANNED.get(key)
        if traj is None:
            traj = self._run(name, resolved)
            for a in (traj.times, traj.positions, traj.velocities):
                a.setflags(write=False)  # shared by every caller of the cache
            _PLANNED[key] = traj
            while len(_PLANNED) > _PLANNED_MAX:
                _PLANNED.popitem(last=False)
        else:
            _PLANNED.move_to_end(key)
        return traj

    def calibration_probes(self) -> list[tuple[str, dict[str, object]]]:
        """Behaviour runs ``(name, params)`` whose measured outcome :meth:`calibrate` turns
        into the design's ``calibration``: empty for a controller whose open-loop model
        needs none (the default)."""
        return []

    def calibrate(self, runs: Sequence[tuple[Trajectory, Mapping[str, np.ndarray]]]) -> dict:
        """The ``calibration`` (name -> number) that the measured ``runs`` of
        :meth:`calibration_probes` give: each its trajectory and the simulation's series
        (``t`` s, ``q`` joint positions rad in the trajectory's joint order, ``root`` the
        free base's position and quaternion). Empty by default."""
        return {}

    def serving(self, ability: str) -> str | None:
        """The ability whose behaviours serve ``ability`` (:func:`serving` over the
        design's ``ancestors``): itself, its nearest ancestor that a behaviour realises, or
        None."""
        offered = {spec.realises for spec in self.behaviors.values()}
        return serving(ability, self.geometry.ancestors, offered)

    def listed(self, abilities: Sequence[str]) -> list[str]:
        """The behaviours that serve one of ``abilities`` (realise it or the nearest
        ancestor ability that has behaviours; aliases left out), by name: what a design
        with those abilities lists, bundles and verifies."""
        have = {s for a in abilities if (s := self.serving(a)) is not None}
        return sorted(
            name
            for name, spec in self.behaviors.items()
            if spec.realises in have and spec.alias_of is None
        )

    def unbehaved(self, abilities: Sequence[str]) -> list[str]:
        """The abilities among ``abilities`` that no behaviour serves, sorted."""
        return sorted(a for a in set(abilities) if self.serving(a) is None)

    def movable_joints(self) -> tuple[str, ...]:
        m = self.template.model
        return tuple(j.name for j in m.joints if m.q_index[m.joint(j.name)] >= 0)
