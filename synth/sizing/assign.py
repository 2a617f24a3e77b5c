"""Actuator assignment that scales with the catalog (issue 12).

Every joint of a kinematic template gets one catalog actuator that serves its ontology
class and is capable for it (meets its torque and speed requirement); alike joints (one
symmetry group) get alike actuators when ``symmetric``; the design stays within its robot
class's active module limit; the objective is the total mass, then the total cost (or the
other way round), ties broken by the models in joint order. ``asp/actuators.lp`` states
exactly that as an ASP program; grounding it is quadratic in the catalog (the symmetry
constraint pairs every two models of a group), so here clingo grounds only
``asp/serving.lp`` (which models serve which joint: the ontology's taxonomy; the limit),
once per robot type, and the rest is solved per *unit*, the joints that must share a model:

- the joints interact only through symmetry (the module count is the same for every
  assignment), so the optimum is each unit's best capable model (``best``), the number of
  assignments is the product of the units' capable counts (``count``), and the k best come
  lazily from a best-first merge of the units' sorted options (``ranked``);
- ``count_feasible`` counts the assignments that stay capable when the torques move with
  the chosen actuators' own masses (``synth.sizing.structure.alternatives``): a branch and bound
  over boxes of group masses, exact (its leaves check every assignment with the same float
  operations as ``synth.sizing.structure._TorqueModel.feasible``).

``dominated`` discards actuators that can never be the best choice for a joint (the
design loop checks capability only on the others); counts and ranked lists use the whole
catalog.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import weakref
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import clingo
import numpy as np

from adron.errors import InputError
from adron.kb import KnowledgeBase
from adron.translate import IsaIndex, asp_string
from synth.reasoning.solver import encoding_dir, taxonomy_program


@dataclass(frozen=True, slots=True)
class JointSlot:
    """A movable joint to be given an actuator: name, symmetry group, ontology class."""

    name: str
    group: str
    module_class: str


@dataclass(frozen=True)
class Assignment:
    """One actuator model per joint, and its objective figures (catalog units)."""

    models: tuple[tuple[str, str], ...]  # (joint, model) in joint order
    cost: tuple[int, ...]  # clingo's cost vector, highest priority first

    def model_of(self, joint: str) -> str:
        return dict(self.models)[joint]


#: What the serving program needs of the knowledge base, per knowledge base (by identity:
#: id -> a weak reference to it and its entries): under None the index of its taxonomy
#: (``adron.translate.IsaIndex``, or None where it cannot be used), and per set of classes
#: the ``isa/2`` and limit facts, or the whole translation with the taxonomy rules (when a
#: rule can derive taxonomy facts). Computed once per request (the enumerated candidates,
#: the verification's resizings and the refusal hints reuse it).
_KNOWN: dict[int, tuple[weakref.ref, dict[tuple[str, ...] | None, object]]] = {}
_KNOWN_LOCK = threading.Lock()  # prepare_knowledge may run on a thread
LIMIT_RELATIONS = ("activeModuleLimit",)


def _entries(kb: KnowledgeBase) -> dict[tuple[str, ...] | None, object]:
    entry = _KNOWN.get(id(kb))
    if entry is None or entry[0]() is not kb:
        key = id(kb)
        entry = (weakref.ref(kb, lambda _, key=key: _KNOWN.pop(key, None)), {})
        _KNOWN[key] = entry
    return entry[1]


def prepare_knowledge(kb: KnowledgeBase) -> IsaIndex | None:
    """Index ``kb``'s taxonomy for :func:`_knowledge` (once per knowledge base; the CLI
    calls it on a thread while the reasoner grounds: it reads every line of the
    translation, ~0.3 s for a 100,000-class one)."""
    with _KNOWN_LOCK:
        per_kb = _entries(kb)
        if None not in per_kb:
            per_kb[None] = IsaIndex.of(kb.translation.program, LIMIT_RELATIONS)
        return per_kb[None]  # type: ignore[return-value]


def _knowledge(kb: KnowledgeBase, classes: tuple[str, ...], others: Sequence[str]) -> str:
    """The program text ``asp/serving.lp`` needs of ``kb`` for these classes (ASP strings)."""

    index = prepare_knowledge(kb)
    with _KNOWN_LOCK:
        per_kb = _entries(kb)
        if classes not in per_kb:
            if index is not None:
                per_kb[classes] = index.facts(classes)
            else:  # what serving.lp asks of the KB, without grounding it
                taxonomy = (encoding_dir() / "taxonomy.lp").read_text(encoding="utf-8")
                per_kb[classes] = "\n".join([*taxonomy_program(kb, others, ()), taxonomy])
        return per_kb[classes]  # type: ignore[return-value]


class ActuatorAssigner:
    """Actuator assignment for one robot type's joints (see the module docstring).

    ``catalog_facts``: ``adron.catalog.catalog_facts`` (integers: mass in mg, cost in
    cents, as clingo would weigh them); ``objective``: an order of "mass" and "cost".
    """

    def __init__(
        self,
        kb: KnowledgeBase,
        catalog_facts: str,
        robot_type: str,
        joints: Sequence[JointSlot],
        other_active: int,
        objective: Sequence[str] = ("mass", "cost"),
    ) -> None:
        if sorted(objective) != ["cost", "mass"]:
            raise InputError(f"objective {list(objective)}: expected an order of mass and cost")
        self.objective = tuple(objective)
        self.joints = tuple(joints)
        self._messages: list[str] = []
        ctl = clingo.Control(
            [], logger=lambda code, msg: self._messages.append(msg.strip()), message_limit=20
        )
        facts = [f"robot({asp_string(robot_type)}).", f"other_active({other_active})."]
        facts += [
            f"joint({asp_string(j.name)},{asp_string(j.group)},{asp_string(j.module_class)})."
            for j in self.joints
        ]
        classes = tuple(
            sorted({asp_string(robot_type), *(asp_string(j.module_class) for j in self.joints)})
        )
        ctl.add("base", [], catalog_facts)
        ctl.add("base", [], "\n".join(facts))
        ctl.add("base", [], _knowledge(kb, classes, [catalog_facts, *facts]))
        ctl.load(str(encoding_dir() / "serving.lp"))
        ctl.ground([("base", [])])
        atoms = ctl.symbolic_atoms
        #: model -> (mass mg, cost cents) as the objective weighs them
        self.weights: dict[str, tuple[int, int]] = {}
        for a in atoms.by_signature("actuator", 7):
            m, _, mg, cents = a.symbol.arguments[:4]
            self.weights[m.string] = (mg.number, cents.number)
        by_class: dict[str, list[str]] = {}
        for a in atoms.by_signature("serves_class", 2):
            m, c = (x.string for x in a.symbol.arguments)
            by_class.setdefault(c, []).append(m)
        #: joint -> the models that serve its ontology class (before any requirement)
        self.serving: dict[str, tuple[str, ...]] = {
            j.name: tuple(sorted(by_class[j.module_class]))
            for j in self.joints
            if j.module_class in by_class
        }
        #: False: the design has more active modules than its robot class allows
        self.within_limit = not any(a.is_fact for a in atoms.by_signature("over_limit", 0))

    # -- the units --------------------------------------------------------------------
    def units(self, symmetric: bool) -> list[list[int]]:
        """Indices (in joint order) of the joints that share one model: a symmetry group
        when ``symmetric`` (its joints in order), else each joint alone; in the order of
        their first joints."""
        by_group: dict[str, list[int]] = {}
        out: list[list[int]] = []
        for i, j in enumerate(self.joints):
            if symmetric and j.group:
                if j.group not in by_group:
                    by_group[j.group] = []
                    out.append(by_group[j.group])
                by_group[j.group].append(i)
            else:
                out.append([i])
        return out

    def key(self, model: str) -> tuple[int, int]:
        """A model's weights in objective order (highest priority first)."""
        mg, cents = self.weights[model]
        return (mg, cents) if self.objective[0] == "mass" else (cents, mg)

    def options(
        self, capable: Mapping[str, Iterable[str]], symmetric: bool
    ) -> list[tuple[list[int], list[str]]]:
        """Per unit, its joints and the models capable for all of them that serve them,
        best first (objective, then name); empty when over the module limit."""
        if not self.within_limit:
            return []
        out = []
        for unit in self.units(symmetric):
            ok: set[str] | None = None
            for i in unit:
                name = self.joints[i].name
                here = set(capable.get(name, ())) & set(self.serving.get(name, ()))
                ok = here if ok is None else ok & here
            out.append((unit, sorted(ok or (), key=lambda m: (self.key(m), m))))
        return out

    def _assignment(self, units: Sequence[list[int]], chosen: Sequence[str]) -> Assignment:
        models = [""] * len(self.joints)
        total = [0, 0]
        for unit, m in zip(units, chosen, strict=True):
            k = self.key(m)
            for i in unit:
                models[i] = m
                total[0] += k[0]
                total[1] += k[1]
        return Assignment(
            tuple((j.name, m) for j, m in zip(self.joints, models, strict=True)), tuple(total)
        )

    # -- queries ----------------------------------------------------------------------
    def best(
        self, capable: Mapping[str, Iterable[str]], symmetric: bool = True
    ) -> Assignment | None:
        """The optimal assignment (ties: the first in joint and model name order), or None
        when there is none: each unit's first option (the objective is a sum over units)."""
        opts = self.options(capable, symmetric)
        if not opts or any(not ms for _, ms in opts):
            return None
        return self._assignment([u for u, _ in opts], [ms[0] for _, ms in opts])

    def count(self, capable: Mapping[str, Iterable[str]], symmetric: bool) -> int:
        """The number of assignments: the product of the units' option counts."""
        return self.count_options(self.options(capable, symmetric))

    @staticmethod
    def count_options(opts: Sequence[tuple[object, Sequence[str]]]) -> int:
        """The number of assignments of units ``opts`` (``options``): the product of their
        option counts (0 without units: the limit is exceeded)."""
        if not opts:
            return 0
        total = 1
        for _, ms in opts:
            total *= len(ms)
        return total

    def ranked(
        self, capable: Mapping[str, Iterable[str]], symmetric: bool, k: int
    ) -> list[Assignment]:
        """The ``k`` best assignments, best first (objective, then the models in joint
        order), from a best-first merge of the units' sorted options."""
        opts = self.options(capable, symmetric)
        if not opts or any(not ms for _, ms in opts):
            return []
        units = [u for u, _ in opts]
        lists = [ms for _, ms in opts]

        def make(idx: tuple[int, ...]) -> Assignment:
            return self._assignment(units, [ms[i] for ms, i in zip(lists, idx, strict=True)])

        def order(idx: tuple[int, ...]) -> tuple:
            a = make(idx)
            return (a.cost, tuple(m for _, m in a.models))

        found = best_first([len(ms) for ms in lists], order)
        return [make(idx) for idx in itertools.islice(found, k)]

    def all(self, capable: Mapping[str, Iterable[str]], symmetric: bool) -> list[Assignment]:
        """Every assignment (for small spaces: --pareto, tests), in no particular order."""
        opts = self.options(capable, symmetric)
        if not opts:
            return []
        units = [u for u, _ in opts]
        return [
            self._assignment(units, chosen) for chosen in itertools.product(*(ms for _, ms in opts))
        ]


def best_first(
    sizes: Sequence[int], key: Callable[[tuple[int, ...]], tuple]
) -> Iterator[tuple[int, ...]]:
    """Index vectors into lists of ``sizes`` in ascending ``key``, lazily (a best-first
    merge: each vector's successors raise one index by one). Exact when ``key`` never
    falls as an index rises (each list sorted by its share of an additive objective)."""
    if not sizes or any(n == 0 for n in sizes):
        return
    start = (0,) * len(sizes)
    heap = [(key(start), start)]
    seen = {start}
    while heap:
        _, idx = heapq.heappop(heap)
        yield idx
        for u, n in enumerate(sizes):
            if idx[u] + 1 < n:
                nxt = idx[:u] + (idx[u] + 1,) + idx[u + 1 :]
                if nxt not in seen:
                    seen.add(nxt)
                    heapq.heappush(heap, (key(nxt), nxt))


# -- dominance ----------------------------------------------------------------------------


def dominated(
    models: Sequence[str],
    torque: Mapping[str, float],
    speed: Mapping[str, float],
    weights: Mapping[str, tuple[int, int]],
    among: Iterable[str] | None = None,
) -> set[str]:
    """The ``models`` that can never be a joint's best choice: some model of ``among``
    (default: ``models``) is at least as strong (stall torque, N m) and as fast (no-load
    speed, rad/s), at most as heavy and as dear (``weights``: mass mg and cost cents, as
    the objective weighs them), and lighter, cheaper or first by name.

    Capability looks only at stall torque and no-load speed (a servo's usable torque is its
    stall torque over the catalog's safety factor; its speed falls linearly to zero at
    stall), so whenever a dominated model is capable for a joint its dominator is too, and
    the dominator comes first in either objective order and on ties (the objective weighs
    mass and cost; the module count, the bus and the symmetry do not depend on which model
    a joint gets). Nothing else about an actuator (size, stall current, travel) enters the
    choice. ``among`` lets a symmetry group's dominators be only models that serve all of
    its joints."""
    names = list(models)
    if not names:
        return set()
    doms = sorted(set(names if among is None else among) & set(weights))
    if not doms:
        return set()
    t_b = np.array([torque[m] for m in names])
    w_b = np.array([speed[m] for m in names])
    mg_b = np.array([weights[m][0] for m in names])
    c_b = np.array([weights[m][1] for m in names])
    t_a = np.array([torque[m] for m in doms])[:, None]
    w_a = np.array([speed[m] for m in doms])[:, None]
    mg_a = np.array([weights[m][0] for m in doms])[:, None]
    c_a = np.array([weights[m][1] for m in doms])[:, None]
    order = {m: i for i, m in enumerate(sorted(set(names) | set(doms)))}
    o_a = np.array([order[m] for m in doms])[:, None]
    o_b = np.array([order[m] for m in names])
    better = (mg_a < mg_b) | (c_a < c_b) | ((mg_a == mg_b) & (c_a == c_b) & (o_a < o_b))
    dom = (t_a >= t_b) & (w_a >= w_b) & (mg_a <= mg_b) & (c_a <= c_b) & better
    hit = dom.any(axis=0)
    return {m for m, h in zip(names, hit, strict=True) if h}


# -- counting with the torques moving with the actuators' masses --------------------------


@dataclass(frozen=True)
class Points:
    """Operating points of a unit's joints. Linear ones: torque ``F |C + sum_g (M_g -
    base_g) S[:, g]|`` (N m; M_g the mass of group g's actuators, kg; the sum taken in
    group order, as ``_TorqueModel`` does) at speed ``W`` (rad/s); fixed ones: torque
    ``T`` at speed ``V``."""

    C: np.ndarray  # (P,)
    S: np.ndarray  # (P, G)
    F: np.ndarray  # (P,)
    W: np.ndarray  # (P,)
    T: np.ndarray  # (Q,)
    V: np.ndarray  # (Q,)


@dataclass(frozen=True)
class Coupled:
    """The assignments whose actuators stay capable at the torques their own masses give.

    ``group``: per unit, its mass group (index into ``base``, kg: the masses the
    sensitivities were taken at); a group's mass is the largest of its units' actuators.
    ``options``: per unit, indices of its candidate models into the per-model arrays
    ``mass`` (kg), ``stall`` (N m), ``usable`` (N m: stall over the safety factor) and
    ``w0`` (no-load speed, rad/s). ``points``: per unit."""

    group: tuple[int, ...]
    base: np.ndarray
    options: tuple[np.ndarray, ...]
    mass: np.ndarray
    stall: np.ndarray
    usable: np.ndarray
    w0: np.ndarray
    points: tuple[Points, ...]


def distinct_points(pts: Points) -> Points:
    """``pts`` without repeats: a linear point and its negative (a mirrored joint's) give
    the same torque exactly (IEEE negation is exact), so each is kept once."""
    flip = (pts.C < 0) | ((pts.C == 0) & (pts.S.sum(axis=1) < 0))
    sign = np.where(flip, -1.0, 1.0)
    rows = np.column_stack([pts.C * sign, pts.S * sign[:, None], pts.F, pts.W])
    lin = np.unique(rows, axis=0) if len(rows) else rows.reshape(0, pts.S.shape[1] + 3)
    fixed = np.unique(np.column_stack([pts.T, pts.V]), axis=0) if len(pts.T) else None
    g = pts.S.shape[1]
    return Points(
        lin[:, 0],
        lin[:, 1 : 1 + g],
        lin[:, 1 + g],
        lin[:, 2 + g],
        pts.T if fixed is None else fixed[:, 0],
        pts.V if fixed is None else fixed[:, 1],
    )


def _meets(p: Coupled, a: np.ndarray, tt: np.ndarray, w: np.ndarray | float) -> np.ndarray:
    """``synth.sizing.structure.meets`` elementwise: models ``a`` at torques ``tt`` and speeds
    ``w`` (the same float operations)."""
    speed = np.maximum(0.0, p.w0[a] * (1.0 - tt / p.stall[a]))
    return (p.usable[a] >= tt) & (speed >= w)


def _fixed_ok(p: Coupled, pts: Points, models: np.ndarray) -> np.ndarray:
    """Per model, whether it meets every fixed point of ``pts`` (torque ``T`` at speed
    ``V``, whatever the masses)."""
    ok = np.ones(len(models), bool)
    for t, v in zip(pts.T, pts.V, strict=True):
        ok &= _meets(p, models, np.full(len(models), t), v)
    return ok


def feasible_mask(p: Coupled, choice: np.ndarray) -> np.ndarray:
    """Which rows of ``choice`` ((N, units) model indices) are feasible."""
    n = choice.shape[0]
    masses = np.full((n, len(p.base)), -np.inf)
    for u, g in enumerate(p.group):
        masses[:, g] = np.maximum(masses[:, g], p.mass[choice[:, u]])
    d = masses - p.base
    ok = np.ones(n, bool)
    for u, pts in enumerate(p.points):
        a = choice[:, u][:, None]
        if len(pts.C):
            lin = np.broadcast_to(pts.C, (n, len(pts.C)))
            for g in range(len(p.base)):  # in group order: ``_TorqueModel._tau``'s sums
                lin = lin + d[:, g : g + 1] * pts.S[:, g]
            ok &= _meets(p, a, np.abs(lin) * pts.F, pts.W).all(axis=1)
        if len(pts.T):
            ok &= _meets(p, a, np.broadcast_to(pts.T, (n, len(pts.T))), pts.V).all(axis=1)
    return ok


def product_rows(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The rows of the Cartesian product of ``arrays`` ((N, len(arrays)))."""
    grids = np.meshgrid(*arrays, indexing="ij")
    return np.stack([g.ravel() for g in grids], axis=1) if arrays else np.zeros((1, 0), int)


def count_by_enumeration(p: Coupled, chunk: int = 50_000) -> int:
    """The number of feasible assignments, checking every one (in chunks)."""
    sizes = [len(o) for o in p.options]
    total = int(np.prod(sizes, dtype=object)) if sizes else 1
    count = 0
    for start in range(0, total, chunk):
        idx = np.arange(start, min(total, start + chunk))
        cols = []
        for u in reversed(range(len(sizes))):
            cols.append(p.options[u][idx % sizes[u]])
            idx = idx // sizes[u]
        count += int(feasible_mask(p, np.stack(cols[::-1], axis=1)).sum())
    return count


#: The count by intervals runs where the two largest units' model pairs times the other
#: units' model combinations are at most this many (~1 s on one core at the most), and
#: the combinations times the units at most INTERVAL_STEPS (each unit of a combination is
#: a few numpy calls, ~0.1 ms: a humanoid's 9 units on 20 actuators made 10^5 of them).
INTERVAL_PAIRS = 60_000_000
INTERVAL_STEPS = 4_000
#: Relative margin within which a pair is checked one by one (``feasible_mask``) rather
#: than decided by the intervals (float rounding of their bounds is ~1e-15).
INTERVAL_TOL = 1e-9


def _torque_limits(p: Coupled, pts: Points, models: np.ndarray) -> np.ndarray:
    """Per model and linear point, the largest ``|C + sum_g d_g S_g|`` the model meets
    there ((models, points)): its usable torque, and with a positive speed its torque at
    that speed on the line to stall, over the point's factor ``F``; -inf where it meets
    no torque, +inf where ``F`` is 0 and it meets the point."""
    usable = p.usable[models][:, None]
    stall = p.stall[models][:, None]
    w0 = p.w0[models][:, None]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        at_speed = np.where(pts.W[None, :] > 0, stall * (1.0 - pts.W[None, :] / w0), np.inf)
        cap = np.minimum(usable, at_speed)
        k = np.where(pts.F[None, :] > 0, cap / pts.F[None, :], np.nan)
    zero = _meets(p, models[:, None], np.zeros((len(models), len(pts.F))), pts.W[None, :])
    k = np.where(np.isnan(k), np.where(zero, np.inf, -np.inf), k)
    return np.where(k < 0, -np.inf, k)


def _near(ordered: np.ndarray, bounds: np.ndarray, pads: np.ndarray) -> np.ndarray:
    """Per bound, whether some of the values ``ordered`` (sorted) lies within its pad."""
    with np.errstate(invalid="ignore"):
        first = np.searchsorted(ordered, bounds - pads, side="left")
        last = np.searchsorted(ordered, bounds + pads, side="right")
    return np.isfinite(bounds) & (last > first)


class _Bounds:
    """The intervals that some units' linear points put on one unit's mass (``y``, group
    ``gy``) for each model of another (the *row* unit, group ``gx``, masses ``dx``), with
    the masses of the ``outer`` groups given per combination: a point's ``-k <= C +
    sum_g d_g S_g <= k`` is ``y`` between ``(+-k - C - o - dx t) / s`` (``s``, ``t`` its
    sensitivities to ``gy`` and ``gx``, ``o`` the outer groups' share), so all but ``o``
    is worked out once and a combination costs one subtraction and one max (or min) per
    row and point. Points with ``s`` 0 are checked whole per combination. ``pad``: per
    row, a margin above the bounds' rounding over every combination."""

    def __init__(
        self,
        p: Coupled,
        sources: Sequence[tuple[int, Points, np.ndarray, bool]],
        dx: np.ndarray,
        gx: int,
        gy: int,
        outer_groups: Sequence[int],
        dmax: np.ndarray,
    ) -> None:
        """``sources``: (unit, points, k, per_row): ``k`` (rows, points) when ``per_row``
        (the row unit's own points), else (models of that outer unit, points)."""
        self.parts = []
        rows = len(dx)
        pad = np.zeros(rows)
        og = list(outer_groups)
        for unit, pts, k, per_row in sources:
            if not len(pts.C):
                continue
            s, t = pts.S[:, gy], pts.S[:, gx]
            flat = s == 0
            nf = ~flat
            so = pts.S[:, og]  # (points, outer groups)
            reach = np.abs(pts.C) + (np.abs(so) * dmax[og][None, :]).sum(axis=1)
            kfin = np.where(np.isfinite(k), np.abs(k), 0.0)
            kmax = kfin if per_row else kfin.max(axis=0)[None, :]
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                scale = kmax + reach[None, :] + np.abs(dx[:, None] * t[None, :]) + 1e-300
                margin = np.where(flat[None, :], 0.0, INTERVAL_TOL * scale / np.abs(s)[None, :])
                pad = np.maximum(pad, margin.max(axis=1) if margin.shape[1] else 0.0)
                sp = np.where(flat, 1.0, s)
                shift = dx[:, None] * (t / sp)[None, :]  # (rows, points)
                if per_row:
                    a = (-k - pts.C[None, :]) / sp[None, :] - shift
                    b = (k - pts.C[None, :]) / sp[None, :] - shift
                    lo = np.where(s[None, :] > 0, a, b)[:, nf]
                    hi = np.where(s[None, :] > 0, b, a)[:, nf]
                else:
                    lo = hi = -shift[:, nf]
            self.parts.append((unit, pts, k, per_row, s, t, flat, nf, so, sp, lo, hi))
        self.pad = pad
        self.dx, self.rows = dx, rows

    def at(self, o_masses: np.ndarray, pick: Mapping[int, int]):
        """(low, high, unsure) per row for the outer masses ``o_masses`` (by outer group)
        and the outer units' models ``pick`` (unit -> model row in its k)."""
        low = np.full(self.rows, -np.inf)
        high = np.full(self.rows, np.inf)
        unsure = np.zeros(self.rows, bool)
        for unit, pts, k, per_row, s, t, flat, nf, so, sp, lo, hi in self.parts:
            o = so @ o_masses  # (points,)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                if per_row:
                    kk = k
                    lo_c = lo - (o / sp)[None, nf]
                    hi_c = hi - (o / sp)[None, nf]
                else:
                    kk = k[pick[unit]][None, :]
                    a = ((-kk[0] - pts.C - o) / sp)[nf]
                    b = ((kk[0] - pts.C - o) / sp)[nf]
                    sn = s[nf] > 0
                    lo_c = np.where(sn, a, b)[None, :] + lo
                    hi_c = np.where(sn, b, a)[None, :] + hi
                if lo_c.shape[1]:
                    low = np.maximum(low, lo_c.max(axis=1))
                    high = np.minimum(high, hi_c.min(axis=1))
                if flat.any():
                    r = (pts.C + o)[None, flat] + self.dx[:, None] * t[None, flat]
                    kf = np.broadcast_to(kk, (self.rows, len(s)))[:, flat]
                    inside = np.abs(r) <= kf
                    high = np.where(inside.all(axis=1), high, -np.inf)
                    edge = np.isfinite(kf) & (
                        np.abs(np.abs(r) - kf) <= INTERVAL_TOL * (np.abs(kf) + np.abs(r) + 1e-300)
                    )
                    unsure |= edge.any(axis=1)
        return low, high, unsure


def count_by_intervals(p: Coupled, max_pairs: int = INTERVAL_PAIRS) -> int | None:
    """The exact number of feasible assignments of ``p`` (one unit per mass group), or
    None when it would check more than ``max_pairs`` model pairs.

    For each combination of the models of all units but the two with the most models
    (i and j), every constraint ``-k <= C + sum_g d_g S_g <= k`` is linear in the two
    masses left: for each model of i, the points of i and of the other units bound j's
    mass to one interval; for each model of j, j's points bound i's mass to one
    (:class:`_Bounds`). A pair is feasible when each mass is in the other's interval, so
    each combination counts an (i models x j models) table of comparisons. Rows and
    columns with a bound within a rounding margin of a mass are checked one by one
    (``feasible_mask``), so the count is exact."""
    n = len(p.options)
    if n < 2 or len(set(p.group)) != n:
        return None
    # models that fail a fixed point fail everywhere
    opts = [
        np.asarray(o)[_fixed_ok(p, pts, np.asarray(o))]
        for o, pts in zip(p.options, p.points, strict=True)
    ]
    if any(len(o) == 0 for o in opts):
        return 0
    order = sorted(range(n), key=lambda u: (-len(opts[u]), u))
    i, j = order[0], order[1]
    outer = sorted(order[2:])
    combos = 1
    for u in outer:
        combos *= len(opts[u])
    if combos * len(opts[i]) * len(opts[j]) > max_pairs or combos * n > INTERVAL_STEPS:
        return None
    d = [p.mass[o] - p.base[p.group[u]] for u, o in enumerate(opts)]
    k = [_torque_limits(p, pts, opts[u]) for u, pts in enumerate(p.points)]
    gi, gj = p.group[i], p.group[j]
    og = [p.group[u] for u in outer]
    dmax = np.zeros(len(p.base))
    for u in range(n):
        dmax[p.group[u]] = np.abs(d[u]).max()
    srcs_i = [(i, p.points[i], k[i], True)] + [(u, p.points[u], k[u], False) for u in outer]
    rows_i = _Bounds(p, srcs_i, d[i], gi, gj, og, dmax)
    rows_j = _Bounds(p, [(j, p.points[j], k[j], True)], d[j], gj, gi, og, dmax)
    sorted_i, sorted_j = np.sort(d[i]), np.sort(d[j])
    count = 0
    for combo in itertools.product(*(range(len(opts[u])) for u in outer)):
        pick = dict(zip(outer, combo, strict=True))
        om = np.array([d[u][c] for u, c in pick.items()])
        lo_i, hi_i, un_i = rows_i.at(om, pick)
        lo_j, hi_j, un_j = rows_j.at(om, pick)
        pad_i, pad_j = rows_i.pad, rows_j.pad
        # rows and columns with a bound within its margin of some mass: checked one by one
        near_i = un_i | _near(sorted_j, lo_i, pad_i) | _near(sorted_j, hi_i, pad_i)
        near_j = un_j | _near(sorted_i, lo_j, pad_j) | _near(sorted_i, hi_j, pad_j)
        rows = np.flatnonzero(~near_i & (lo_i <= hi_i))
        cols = np.flatnonzero(~near_j & (lo_j <= hi_j))
        if len(rows) and len(cols):
            dj, di = d[j][cols][None, :], d[i][rows][:, None]
            ok = (dj >= lo_i[rows, None]) & (dj <= hi_i[rows, None])
            ok &= (di >= lo_j[None, cols]) & (di <= hi_j[None, cols])
            count += int(ok.sum())
        if near_i.any() or near_j.any():
            grid = near_i[:, None] | near_j[None, :]
            at_i, at_j = np.nonzero(grid)
            choice = np.empty((len(at_i), n), int)
            for u, c in pick.items():
                choice[:, u] = opts[u][c]
            choice[:, i] = opts[i][at_i]
            choice[:, j] = opts[j][at_j]
            count += int(feasible_mask(p, choice).sum())
    return count


#: Branch and bound: a box whose assignments are at most this many is checked one by one.
LEAF = 4096
#: Branch and bound: boxes examined, and assignments checked one by one in them, before it
#: gives up (deterministic bounds on its time: a few seconds at most on one core).
MAX_BOXES = 200
MAX_CHECKED = 200_000
#: ... and model-point pairs classified in the boxes (a box's cost: each unit's models
#: times its operating points) plus assignment-point pairs checked one by one (~0.2 s
#: on one core): a 9-unit humanoid on a 1000-actuator catalog reaches it early, where
#: the other budgets took 1.5 s to tighten its bounds by nothing.
MAX_WORK = 20_000_000
#: Relative margin of the interval bounds on a torque (far above the float error of the
#: sums, so that a model classed as always or never capable in a box is so exactly).
BOUND_MARGIN = 1e-9


def _classify(p: Coupled, alive: Sequence[np.ndarray]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per unit, whether each alive option is capable for every mass in the box the alive
    options span (``always``) and whether it is capable for none (``never``). (For a
    unit's own options its own group's mass is the option's, not the box's range: one unit
    per group.)"""
    lo = np.empty(len(p.base))
    hi = np.empty(len(p.base))
    for u, g in enumerate(p.group):
        lo[g] = p.mass[alive[u][0]] - p.base[g]
        hi[g] = p.mass[alive[u][-1]] - p.base[g]
    always, never = [], []
    for u, pts in enumerate(p.points):
        a = alive[u]
        ok_all = np.ones(len(a), bool)
        bad = np.zeros(len(a), bool)
        if len(pts.C):
            g = p.group[u]
            others = np.ones(len(p.base), bool)
            others[g] = False
            S, Sg = pts.S[:, others], pts.S[:, g]
            lo_o, hi_o = lo[others], hi[others]
            own = (p.mass[a] - p.base[g])[:, None] * Sg[None, :]  # (options, points)
            low = (pts.C + np.minimum(S * lo_o, S * hi_o).sum(axis=1))[None, :] + own
            high = (pts.C + np.maximum(S * lo_o, S * hi_o).sum(axis=1))[None, :] + own
            pad = (
                BOUND_MARGIN * (np.abs(pts.C) + (np.abs(pts.S) * np.maximum(-lo, hi)).sum(axis=1))
                + 1e-300
            )
            low, high = low - pad, high + pad
            amax = np.maximum(np.abs(low), np.abs(high)) * pts.F * (1 + BOUND_MARGIN)
            amin = (
                np.where((low <= 0) & (high >= 0), 0.0, np.minimum(np.abs(low), np.abs(high)))
                * pts.F
                * (1 - BOUND_MARGIN)
            )
            A = a[:, None]
            ok_all &= _meets(p, A, amax, pts.W[None, :]).all(axis=1)
            bad |= ~_meets(p, A, amin, pts.W[None, :]).all(axis=1)
        fixed = _fixed_ok(p, pts, a)
        ok_all &= fixed
        bad |= ~fixed
        always.append(ok_all & ~bad)
        never.append(bad)
    return always, never


def count_feasible(p: Coupled, **budgets: int | bool) -> int | None:
    """The exact number of feasible assignments of ``p``, or None when it could not be
    found within the budgets of :func:`count_bounds` (its keyword arguments)."""
    low, high = count_bounds(p, **budgets)  # type: ignore[arg-type]
    return low if low == high else None


def _box_size(alive: Sequence[np.ndarray]) -> int:
    size = 1
    for a in alive:
        size *= len(a)
    return size


def _box_bounds(p: Coupled, alive: Sequence[np.ndarray]) -> tuple[int, int]:
    """Bounds on the feasible assignments of a box not examined further: every model
    capable throughout the box in each unit (each such assignment is feasible: its masses
    are in the box), and every model capable somewhere in it."""
    always, never = _classify(p, alive)
    low = high = 1
    for al, nv in zip(always, never, strict=True):
        low *= int(al.sum())
        high *= int((~nv).sum())
    return low, high


def count_bounds(
    p: Coupled,
    leaf: int = LEAF,
    max_boxes: int = MAX_BOXES,
    max_checked: int = MAX_CHECKED,
    max_work: int = MAX_WORK,
    intervals: bool = True,
) -> tuple[int, int]:
    """Lower and upper bounds on the number of feasible assignments of ``p``, equal when
    it is exact: by :func:`count_by_intervals` where its table is small enough (with
    ``intervals``: up to three units on any catalog), else found within ``max_boxes``
    boxes, ``max_work`` model-point pairs classified in them and ``max_checked``
    assignments checked one by one. Past any budget, each box left is bounded by
    :func:`_box_bounds`.

    Where every mass group has one unit (alike joints alike), a branch and bound over the
    units' mass ranges: in a box (each unit's options between two masses) a model whose
    torques' bounds over the box it meets is capable everywhere in it, one that misses the
    bounds' lower end nowhere; a box with no model in between counts as the product of the
    capable ones; otherwise the box is split at the middle option of the unit whose mass
    range moves the torques most, down to boxes of at most ``leaf`` assignments, which are
    checked one by one (``feasible_mask``); units that are capable throughout a box and
    move no unsure unit's torques are a plain factor there. Otherwise every assignment is
    checked, up to ``max_checked`` of them."""
    if any(len(o) == 0 for o in p.options):
        return 0, 0
    exact = count_by_intervals(p) if intervals else None
    if exact is not None:
        return exact, exact
    single = len(set(p.group)) == len(p.group)
    if not single:
        total = _box_size(p.options)
        if total <= max_checked:
            n = count_by_enumeration(p)
            return n, n
        return 0, total
    start = [np.array(sorted(o.tolist(), key=lambda i: (p.mass[i], i))) for o in p.options]
    stack = [start]
    boxes = checked = 0
    count = 0
    # |sensitivity| of each unit's points to each group's mass
    reach = np.array([np.abs(pts.S).sum(axis=0) for pts in p.points]).reshape(
        len(p.points), len(p.base)
    )

    def give_up(pending: list[list[np.ndarray]]) -> tuple[int, int]:
        low = high = count
        for box in pending:
            lo, hi = _box_bounds(p, box)
            low, high = low + lo, high + hi
        return low, high

    points = [len(pts.C) + len(pts.T) for pts in p.points]
    work = 0
    while stack:
        boxes += 1
        work += sum(len(a) * n for a, n in zip(stack[-1], points, strict=True))
        if boxes > max_boxes or work > max_work:
            return give_up(stack)
        alive = stack.pop()
        always, never = _classify(p, alive)
        alive = [a[~nv] for a, nv in zip(alive, never, strict=True)]
        if any(len(a) == 0 for a in alive):
            continue
        unsure = [not al[~nv].all() for al, nv in zip(always, never, strict=True)]
        if not any(unsure):
            count += _box_size(alive)
            continue
        # units neither unsure nor moving an unsure unit's torques are a plain factor
        moves = reach[np.array(unsure)].sum(axis=0)
        keep = [u for u in range(len(alive)) if unsure[u] or moves[p.group[u]] > 0]
        factor = 1
        for u in range(len(alive)):
            if u not in keep:
                factor *= len(alive[u])
        size = _box_size([alive[u] for u in keep])
        if size <= leaf:
            if checked + size > max_checked or work + size * sum(points) > max_work:
                return give_up([*stack, alive])
            checked += size
            work += size * sum(points)
            rows = product_rows([alive[u] for u in keep])
            choice = np.zeros((len(rows), len(alive)), int)
            for u in range(len(alive)):
                choice[:, u] = alive[u][0]
            for j, u in enumerate(keep):
                choice[:, u] = rows[:, j]
            count += factor * int(feasible_mask(p, choice).sum())
            continue
        spread = [
            (
                (p.mass[alive[u][-1]] - p.mass[alive[u][0]]) * moves[p.group[u]]
                if len(alive[u]) > 1
                else -1.0,
                len(alive[u]),
            )
            for u in keep
        ]
        u = keep[max(range(len(keep)), key=lambda i: spread[i])]
        half = len(alive[u]) // 2
        for part in (alive[u][:half], alive[u][half:]):
            stack.append([*alive[:u], part, *alive[u + 1 :]])
    return count, count
