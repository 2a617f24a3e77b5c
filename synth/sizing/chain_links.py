"""A serial chain's printed links sized as one convex program (issue 20, item 5).

:func:`synth.sizing.links.optimal_tube` sizes one tube for its own stiffness. Here the links of
a serial chain (root -> tip) share the chain's tip deflection budget: least printed
volume (mass, for one material) subject to

* the tip deflection of every chain within its budget ``b``;
* every link's clamped-end stress (von Mises with the fillet's ``Kt``) within the allowed
  stress, and any other stiffness floor the caller has (Euler buckling);
* the printable limits of :class:`~synth.sizing.links.TubeLimits` (wall >= ``e``, outer radius
  <= ``r2max``, length ``Lmin``).

:func:`chain_tubes` solves it with cvxpy and the Clarabel solver; :func:`per_link_tubes`
is the per-link sizing it replaces (each link an even share ``b / n`` of the budget, then
thickened for stress), always feasible for the program when it exists, so the program
is never heavier. When the chains share no link (every shipped robot: alike limbs give
one chain) it solves the program's optimality conditions directly, exactly and without
cvxpy (see "The separable case"); chains that share a link are solved with cvxpy and the
Clarabel solver, then polished to the same exactness.

Load model (the structure generator's, ``synth.sizing.structure._equivalent_force``): each link
is a cantilever clamped at its root end and loaded at its free end by the wrench the
generator computes (``free_end_load``), transverse force ``F`` and bending moment ``M``
(magnitudes, N and N m). Its free end then deflects ``d = (F L^3/3 + M L^2/2) / (E I)``
and turns ``theta = (F L^2/2 + M L) / (E I)``; the rest of the chain moves rigidly with
it, so the chain tip moves ``d + theta * lever``, ``lever`` the distance (m) from the
link's free end to the tip. The tip deflection is the sum over the links::

    delta_tip = sum_k c_k / I_k,   c_k = max over the link's loads of
                (F (L^3/3 + L^2 lever/2) + M (L^2/2 + L lever)) / E     (m^5)

an upper bound at any pose (magnitudes added, levers bounded by the path length to the
tip, each link's worst load). One link with ``lever = 0`` is exactly today's
``stiffness_constant(F + 1.5 M / L, E, b)``.

Why the program is convex, and what it is exact for
----------------------------------------------------
At a given section area ``a`` the stiffest printable tube is also the least stressed one
(see the end), so the design of link k reduces to its area. With ``x = a / (pi r2max^2)``
and ``I~ = I / (pi r2max^4 / 4)`` (both in ``(0, 1]``), the stiffest tube of area ``x``
is the thinnest-walled one:

* outer radius ``r2max`` (``"stiffness"`` branch of ``optimal_tube``):
  ``I~_R(x) = 2x - x^2``, concave;
* wall ``e`` (``"wall"`` and ``"solid"`` branches), ``eps = e / r2max``,
  ``rho = (x + eps^2) / (2 eps)``: ``I~_W(x) = rho^4 - (rho - eps)^4``, a convex cubic;

and ``I~_max(x) = min(I~_W(x), I~_R(x))`` for ``eps^2 <= x <= 1`` (the thin-walled tube of
area ``x`` is infeasible exactly where it is the stiffer of the two). The program::

    minimise    sum_k count_k L_k r2max_k^2 x_k
    subject to  sum_k W_jk t_k <= 1                       for every chain j
                t_k >= 1 / I~_R(x_k),  t_k >= 1 / I~_W(x_k)
                lo_k <= x_k <= 1

with ``W_jk = 4 c_jk / (pi r2max_k^4 b_j)`` is convex: a linear objective, a linear
budget, and ``1 / I~_R`` (the reciprocal of a positive concave function) and
``1 / I~_W`` are convex (``(1/g)'' = (2 g'^2 - g g'') / g^3 > 0`` for the cubic ``g``).
The stress and buckling limits are lower bounds ``lo_k`` on the area: along the least-area
path of ``optimal_tube`` the area grows with the stiffness while ``r2 / I`` and ``1 / a``
fall, so the stress only falls (the bound is found by a bracketing search on that path,
as the structure generator bisects today).

``1 / I~_R`` is written for cvxpy exactly (``inv_pos`` of a concave quadratic). ``1 / I~_W``
is convex but has no disciplined (DCP) form. It is majorised by ``l(x)^-3``, ``l`` the
tangent at the current ``x0`` of ``I~_W^(1/3)``, which is convex on the wall branch (with
the mid-radius ``m``, ``I ~ g(m) = c1 m^3 + c2 m`` and ``(g^(1/3))''`` has the sign of
``2 c1 c2 m^2 - 2 c2^2 / 3``, >= 0 for ``m >= e / sqrt(12)``; the branch has ``m >= e/2``),
so ``l <= I~_W^(1/3)``, equal at ``x0``, and exact for the cubic's leading term: the
convex-concave procedure. Each solve is a convex restriction of the program, feasible
at ``x0``, so every iterate is a feasible design and the volume only falls; a fixed point
is a KKT point of the convex program (the majorant touches with its gradient), hence its
optimum. It takes 2-6 solves (to a volume change below ``V_TOL``). The problem is
compiled once per number of links and chains (DPP: the data are parameters) and
re-solved; it is scaled about the start (areas relative to the start's, ``t`` relative
to the start's ``1 / I~``), without which Clarabel stalls at ~1e-7.

The solver meets the volume to ~1e-10, but the volume is flat at the optimum: the areas
are ~1e-5 off. :func:`_polish` then solves the KKT conditions by Newton's method on the
active set read off the solution (links at a floor, at the kink between the branches or
free on one; chains at their budget), corrects that set until every condition holds
(each held link's one-sided slopes included), and so certifies the optimum to ~1e-12.

The separable case
------------------
When no link is in two chains (a chain implied by another entry by entry dropped first),
the program is separable with one coupling constraint per chain: its objective is a sum
of one term per link, its bounds are per link, and link k appears in the one budget
``sum_k W_k / I~_max(x_k) <= 1`` of its chain. It is convex and strictly feasible (the
stiffest tubes leave some budget: checked first; if they leave none they are the only
solution), so the KKT conditions are necessary and sufficient: with the chain's
multiplier ``lam >= 0`` every ``x_k`` minimises ``w_k x_k + lam W_k / I~_max(x_k)`` on
``[lo_k, 1]``, and ``lam = 0`` with the floors within the budget or the budget met with
equality. Each link's minimiser is unique (strictly convex) and found exactly
(:func:`_link_area`: a quartic on the ``r2max`` branch, a monotone equation on the wall
branch, both by Newton's method from above, or the kink between them); it grows
continuously with ``lam``, so the chain's deflection falls continuously and ``lam`` is the
root of ``deflection(lam) = budget``, bracketed and found to 1e-14 (:func:`_chain_areas`).
No solver, no start, no tolerance but rounding: it agrees with the polished program to
~1e-12 and sizes a chain about five times as fast (1.3 against 7 ms with the stress
floors both need: ``make bench``), without cvxpy's 0.6-1 s import.

Either way the result is exact (to rounding, then made exactly feasible: see
:func:`chain_tubes`) for the model above: tubes of given length, on any branch. It is
conservative where the model is: loads of different links that never act together (each
link takes its worst one), levers at their longest; it does not shorten links
(``L = Lmin`` as in ``optimal_tube``).

Why the stiffest tube of an area is the least stressed: with ``r1^2 = r2^2 - a / pi`` the
bending and torsion stresses go as ``r2 / I = 4 r2 / (a (2 r2^2 - a / pi))``, which falls as
``r2`` grows, and the axial stress is ``N / a``; the stiffest tube of area ``a`` has the
largest ``r2`` allowed.

Everything is in SI units: metres, newtons, pascals. cvxpy is imported only when the
program is solved: for chains that share a link, or when asked (``method="program"``).
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from adron.errors import InfeasibleError
from synth.sizing.links import Tube, TubeLimits, optimal_tube

__all__ = [
    "Chain",
    "ChainLink",
    "ChainSizing",
    "chain_tubes",
    "clamp_sections",
    "deflection_coefficient",
    "per_link_tubes",
    "serial_chains",
    "stress_floor",
    "tube_stress",
]

#: The stress floor is found to STRESS_RTOL (relative) in at most STRESS_STEPS steps.
STRESS_RTOL = 1e-13
STRESS_STEPS = 200
#: The convex-concave iterations stop when no area moves by more than X_TOL (relative),
#: when the volume changes by less than V_TOL (relative: the solver's noise is ~1e-10)
#: or after MAX_ITERATIONS.
X_TOL = 1e-10
V_TOL = 1e-9
#: An area within this (relative) of its lower bound is taken as on it.
FLOOR_RTOL = 1e-9
MAX_ITERATIONS = 60
#: The separable solve: a chain's multiplier to LAMBDA_RTOL (relative) in at most
#: LAMBDA_STEPS evaluations; a link's Newton solves in at most NEWTON_STEPS steps.
LAMBDA_RTOL = 1e-14
LAMBDA_STEPS = 300
NEWTON_STEPS = 100
#: The program's polish: at most POLISH_STEPS Newton steps; a link or a budget within
#: ACTIVE_RTOL (relative) of a bound is taken as on it.
POLISH_STEPS = 40
POLISH_ROUNDS = 4  # changes of the active set, times (links + chains + 1)
ACTIVE_RTOL = 1e-6
#: How chain_tubes solves: see its docstring.
METHODS = ("auto", "separable", "program")
#: Clarabel's tolerances (its defaults are 1e-8).
SOLVER_OPTIONS = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10}


# --------------------------------------------------------------------------- inputs


def _vector6(load: ArrayLike, what: str) -> np.ndarray:
    a = np.asarray(load, dtype=float)
    if a.shape != (6,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be a finite 6-vector [Fx Fy Fz Mx My Mz], got {load!r}")
    a = a.copy()
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class ChainLink:
    """One printed link design (a length name) of the chains.

    ``limits``: its tube limits (its length is ``limits.length_min``, as in
    ``optimal_tube``); ``loads``: its free-end loads ``[Fx Fy Fz Mx My Mz]`` (N, N m) in the
    tube frame (x along the tube from the clamped end), as the structure generator's
    ``free_end_load`` gives them; ``count``: how many printed copies (the volume's
    weight); ``min_stiffness_m``: any other lower bound on ``(r2^4 - r1^4) / L^3`` (m), e.g.
    Euler buckling.
    """

    name: str
    limits: TubeLimits
    loads: tuple[np.ndarray, ...]
    count: int = 1
    min_stiffness_m: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"a link needs a non-empty name, got {self.name!r}")
        loads = tuple(
            _vector6(ld, f"link {self.name!r} load {i}") for i, ld in enumerate(self.loads)
        )
        object.__setattr__(self, "loads", loads)
        if not isinstance(self.count, int) or self.count < 1:
            raise ValueError(
                f"link {self.name!r}: count must be an integer >= 1, got {self.count!r}"
            )
        k = float(self.min_stiffness_m)
        if not math.isfinite(k) or k < 0.0:
            raise ValueError(
                f"link {self.name!r}: min_stiffness_m must be finite and >= 0, got {k!r}"
            )
        object.__setattr__(self, "min_stiffness_m", k)

    @property
    def length(self) -> float:
        """The link's length, m (``limits.length_min``)."""
        return self.limits.length_min


@dataclass(frozen=True)
class Chain:
    """A serial chain: link names from the root to the tip, the tip's deflection budget
    (m), and each link's lever (m, distance from its free end to the tip); ``levers_m``
    None: the links are taken end to end, each lever the sum of the lengths after it (an
    upper bound of the distance at any pose when nothing lies between the links)."""

    links: tuple[str, ...]
    budget_m: float
    levers_m: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        links = tuple(self.links)
        if not links:
            raise ValueError("a chain needs at least one link")
        object.__setattr__(self, "links", links)
        b = float(self.budget_m)
        if not math.isfinite(b) or b <= 0.0:
            raise ValueError(
                f"chain {self.label}: budget_m must be positive, got {self.budget_m!r}"
            )
        object.__setattr__(self, "budget_m", b)
        if self.levers_m is not None:
            levers = tuple(float(x) for x in self.levers_m)
            if len(levers) != len(links):
                raise ValueError(f"chain {self.label}: {len(levers)} levers for {len(links)} links")
            for name, x in zip(links, levers, strict=True):
                if not math.isfinite(x) or x < 0.0:
                    raise ValueError(
                        f"chain {self.label}: lever of {name!r} must be finite and >= 0, got {x!r}"
                    )
            object.__setattr__(self, "levers_m", levers)

    @property
    def label(self) -> str:
        """The chain as text: ``'L1 -> L2 -> L3'``."""
        return "'" + " -> ".join(self.links) + "'"


@dataclass(frozen=True)
class ChainSizing:
    """Sized links. ``tubes``: link name -> tube; ``governed``: link name -> ``"stress"``
    (its stress or other stiffness floor binds) or ``"deflection"``; ``stress_Pa``: link
    name -> its largest clamped-end stress over its loads; ``share_m``: link name -> the
    largest tip deflection it causes in a chain (``c / I``); ``tip_deflection_m``: per
    chain, in order; ``volume_m3``: ``sum count * tube volume``; ``iterations``: solves of
    the convex program, or evaluations of the chains' deflections at a multiplier in the
    separable solve (0 for per-link sizing, or when every link is at its floor)."""

    tubes: Mapping[str, Tube]
    governed: Mapping[str, str]
    stress_Pa: Mapping[str, float]
    share_m: Mapping[str, float]
    tip_deflection_m: tuple[float, ...]
    volume_m3: float
    iterations: int = 0
    allowed_stress_Pa: float = field(default=math.inf)


# --------------------------------------------------------------------------- load model


def deflection_coefficient(
    load: ArrayLike, length_m: float, lever_m: float, youngs_modulus_Pa: float
) -> float:
    """``c`` (m^5) of one free-end load: the chain tip moves ``c / I`` (m, ``I`` in m^4).

    ``(F (L^3/3 + L^2 lever/2) + M (L^2/2 + L lever)) / E`` with ``F = hypot(Fy, Fz)`` and
    ``M = hypot(My, Mz)`` (the transverse force and bending moment at the free end).
    """
    ld = _vector6(load, "load")
    f, m = math.hypot(ld[1], ld[2]), math.hypot(ld[4], ld[5])
    L, lv = float(length_m), float(lever_m)
    return (f * (L**3 / 3.0 + L * L * lv / 2.0) + m * (L * L / 2.0 + L * lv)) / youngs_modulus_Pa


def clamp_sections(loads: Sequence[np.ndarray], length_m: float) -> np.ndarray:
    """(B, 3) section forces at the clamped end of a cantilever of ``length_m`` under
    free-end loads (B, 6): axial force ``N`` (N, tension positive), bending moment ``|M|``
    and torque ``|T|`` (N m). Statics only: they do not depend on the tube."""
    w = np.asarray(loads, dtype=float).reshape(-1, 6)
    L = float(length_m)
    bend = np.hypot(w[:, 4] - L * w[:, 2], w[:, 5] + L * w[:, 1])
    return np.column_stack([w[:, 0], bend, np.abs(w[:, 3])])


def tube_stress(tube: Tube, sections: np.ndarray, stress_concentration: float = 1.0) -> float:
    """The largest clamped-end von Mises stress (Pa, times ``Kt``) of ``tube`` over the
    ``sections`` of :func:`clamp_sections`; ``beam_check``'s ``max_stress_Pa``."""
    if len(sections) == 0:
        return 0.0
    r2, r1 = tube.r_outer, tube.r_inner
    area = math.pi * (r2 - r1) * (r2 + r1)
    inertia = math.pi / 4.0 * (r2**4 - r1**4)
    sigma = np.abs(sections[:, 0]) / area + sections[:, 1] * r2 / inertia
    tau = sections[:, 2] * r2 / (2.0 * inertia)
    return float(stress_concentration * np.sqrt(sigma * sigma + 3.0 * tau * tau).max())


def stress_floor(link: ChainLink, allowed_Pa: float, stress_concentration: float = 1.0) -> float:
    """The least stiffness ``(r2^4 - r1^4) / L^3`` (m) on ``optimal_tube``'s path whose tube
    keeps the link's stress within ``allowed_Pa`` under all its loads (0: the thinnest rod
    already does). Raises InfeasibleError when the strongest printable tube does not."""
    lim, L = link.limits, link.length
    sections = clamp_sections(link.loads, L)
    k_max = lim.r_outer_max**4 / L**3
    strongest = optimal_tube(k_max, lim, link.name)
    top = tube_stress(strongest, sections, stress_concentration)
    if top > allowed_Pa:
        err = InfeasibleError(
            f"link '{link.name}' ({L * 1000:.0f} mm): the clamped-end stress "
            f"{top / 1e6:.1f} MPa of the strongest printable tube exceeds the allowed "
            f"{allowed_Pa / 1e6:.1f} MPa (yield / safety factor); carry less or use a "
            "stronger material"
        )
        err.required, err.reachable = allowed_Pa, top
        raise err

    def excess(k: float) -> float:  # log(stress / allowed) of the path's tube at k
        tube = optimal_tube(k, lim, link.name)
        return math.log(tube_stress(tube, sections, stress_concentration) / allowed_Pa)

    lo = min(lim.min_wall, lim.r_outer_max) ** 4 / L**3  # the thinnest rod: r2 = e, solid
    if tube_stress(optimal_tube(lo, lim, link.name), sections, stress_concentration) <= allowed_Pa:
        return 0.0
    f_lo = excess(lo)
    # Illinois regula falsi in log k on the bracket (lo overstressed, hi not): the stress
    # falls along the path, so one root; returns the bracket's end that holds
    hi, f_hi = k_max, math.log(top / allowed_Pa)
    side = 0
    for _ in range(STRESS_STEPS):
        if hi <= lo * (1.0 + STRESS_RTOL):
            break
        a, b = math.log(lo), math.log(hi)
        mid = math.exp(b - f_hi * (b - a) / (f_hi - f_lo)) if f_hi < f_lo else math.sqrt(lo * hi)
        if not lo < mid < hi:
            mid = math.sqrt(lo * hi)
        f_mid = excess(mid)
        if f_mid > 0.0:
            lo, f_lo = mid, f_mid
            f_hi = f_hi * 0.5 if side == -1 else f_hi
            side = -1
        else:
            hi, f_hi = mid, f_mid
            f_lo = f_lo * 0.5 if side == 1 else f_lo
            side = 1
    return hi


# --------------------------------------------------------------------------- chains


def serial_chains(
    model, segments: Sequence, tip_points: Mapping[str, ArrayLike] | None = None
) -> list[tuple[tuple[str, ...], tuple[float, ...]]]:
    """The serial chains of the printed tubes of a kinematic tree, root to tip.

    ``model``: a ``kinematics.model.Model``; ``segments``: its tubes (``Segment``: ``name``,
    ``body``, ``start``, ``direction``, ``length``, ``length_name``, in the body's frame);
    ``tip_points``: tip body name -> tip point (3,) in its frame (a foot's contact point,
    a gripper's origin); None: every leaf body, at the end of its last tube or else at its
    origin. Returns ``(length names, levers)`` per chain with at least one tube, chains of
    the same names merged (largest lever of each), in the order first met; a lever (m)
    is the length of the path from the tube's free end to the tip through the joint
    points, an upper bound of their distance at any pose (a joint turns its child about
    the child frame's origin). Tubes are taken in body order, then in ``segments`` order.
    """
    by_body: dict[int, list] = {}
    for seg in segments:
        by_body.setdefault(model.body(seg.body), []).append(seg)
    if tip_points is None:
        parents = {j.parent for j in model.joints}
        tips = {}
        for i, body in enumerate(model.bodies):
            if i not in parents:
                own = by_body.get(i)
                end = own[-1].start + own[-1].length * np.asarray(own[-1].direction) if own else 0
                tips[body.name] = np.zeros(3) + end
    else:
        tips = {name: np.asarray(p, dtype=float).reshape(3) for name, p in tip_points.items()}
    out: dict[tuple[str, ...], list[float]] = {}
    for tip, point in tips.items():
        path = model.ancestors(model.body(tip))
        exits = [model.joints[path[i + 1]].origin[:3, 3] for i in range(len(path) - 1)]
        exits.append(point)
        after = np.cumsum([float(np.linalg.norm(x)) for x in exits[::-1]])[::-1]  # from origin
        names: list[str] = []
        levers: list[float] = []
        for i, body in enumerate(path):
            rest = float(after[i + 1]) if i + 1 < len(path) else 0.0
            for seg in by_body.get(body, []):
                end = np.asarray(seg.start, float) + seg.length * np.asarray(seg.direction, float)
                names.append(seg.length_name or seg.name)
                levers.append(float(np.linalg.norm(exits[i] - end)) + rest)
        if names:
            key = tuple(names)
            old = out.get(key)
            out[key] = (
                levers if old is None else [max(a, b) for a, b in zip(old, levers, strict=True)]
            )
    return [(names, tuple(levers)) for names, levers in out.items()]


# --------------------------------------------------------------------------- the problem


@dataclass(frozen=True)
class _Problem:
    """The data both sizings share: links (in order), chains, their coefficients."""

    links: tuple[ChainLink, ...]
    chains: tuple[Chain, ...]
    coeff: np.ndarray  # (m, n) c_jk in m^5: chain j's tip moves sum_k c_jk / I_k
    floor: np.ndarray  # (n,) least stiffness (r2^4 - r1^4) / L^3 of each link, m
    stress_floor: np.ndarray  # (n,) the part of ``floor`` the stress asks, m
    sections: tuple[np.ndarray, ...]  # per link, clamp_sections of its loads
    kt: float


def _prepare(
    links: Sequence[ChainLink],
    chains: Sequence[Chain],
    youngs_modulus_Pa: float,
    allowed_stress_Pa: float,
    stress_concentration: float,
) -> _Problem:
    e_mod = float(youngs_modulus_Pa)
    if not math.isfinite(e_mod) or e_mod <= 0.0:
        raise ValueError(f"youngs_modulus_Pa must be positive, got {youngs_modulus_Pa!r}")
    allowed = float(allowed_stress_Pa)
    if not math.isfinite(allowed) or allowed <= 0.0:
        raise ValueError(f"allowed_stress_Pa must be positive, got {allowed_stress_Pa!r}")
    kt = float(stress_concentration)
    if not math.isfinite(kt) or kt < 1.0:
        raise ValueError(f"stress_concentration must be >= 1, got {stress_concentration!r}")
    links, chains = tuple(links), tuple(chains)
    if not links:
        raise ValueError("no links to size")
    index: dict[str, int] = {}
    for i, link in enumerate(links):
        if link.name in index:
            raise ValueError(f"link {link.name!r} is given twice")
        index[link.name] = i
    coeff = np.zeros((len(chains), len(links)))
    for j, chain in enumerate(chains):
        for name in chain.links:
            if name not in index:
                raise ValueError(
                    f"chain {chain.label}: no link {name!r} (links: {', '.join(index)})"
                )
        levers = chain.levers_m
        if levers is None:
            lengths = [links[index[n]].length for n in chain.links]
            levers = tuple(float(sum(lengths[i + 1 :])) for i in range(len(lengths)))
        for name, lever in zip(chain.links, levers, strict=True):
            link = links[index[name]]
            if link.loads:
                coeff[j, index[name]] += max(
                    deflection_coefficient(ld, link.length, lever, e_mod) for ld in link.loads
                )
    sections = tuple(clamp_sections(link.loads, link.length) for link in links)
    stress = np.array([stress_floor(link, allowed, kt) for link in links])
    floor = np.maximum(stress, [link.min_stiffness_m for link in links])
    return _Problem(links, chains, coeff, floor, stress, sections, kt)


def _result(prob: _Problem, stiffness: np.ndarray, allowed: float, iterations: int) -> ChainSizing:
    """Tubes of the given stiffnesses (m; at least the floors), with their figures."""
    tubes: dict[str, Tube] = {}
    governed: dict[str, str] = {}
    stress: dict[str, float] = {}
    inertia = np.empty(len(prob.links))
    for k, link in enumerate(prob.links):
        s = max(float(stiffness[k]), float(prob.floor[k]))
        tube = optimal_tube(s, link.limits, link.name)
        tubes[link.name] = tube
        inertia[k] = tube.second_moment
        binds = prob.stress_floor[k] > 0.0 and s <= prob.stress_floor[k]
        governed[link.name] = "stress" if binds else "deflection"
        stress[link.name] = tube_stress(tube, prob.sections[k], prob.kt)
    shares = prob.coeff / inertia
    share = {
        link.name: float(shares[:, k].max()) if len(prob.chains) else 0.0
        for k, link in enumerate(prob.links)
    }
    volume = sum(link.count * tubes[link.name].volume for link in prob.links)
    return ChainSizing(
        tubes=tubes,
        governed=governed,
        stress_Pa=stress,
        share_m=share,
        tip_deflection_m=tuple(float(x) for x in shares.sum(axis=1)),
        volume_m3=float(volume),
        iterations=iterations,
        allowed_stress_Pa=allowed,
    )


def _share_error(prob: _Problem, j: int, k: int, share: float) -> InfeasibleError:
    chain, link = prob.chains[j], prob.links[k]
    lim = link.limits
    best = prob.coeff[j, k] / (math.pi / 4.0 * lim.r_outer_max**4)
    err = InfeasibleError(
        f"link '{link.name}' ({link.length * 1000:.0f} mm) cannot keep its share "
        f"{share * 1000:.3g} mm of the tip deflection budget {chain.budget_m * 1000:.3g} mm "
        f"of chain {chain.label}: the stiffest printable tube (solid, r = "
        f"{lim.r_outer_max * 1000:.3g} mm) moves the tip {best * 1000:.3g} mm; allow a larger "
        "deflection, a larger r_outer_max, or carry less"
    )
    err.required, err.reachable = share, best
    return err


def per_link_tubes(
    links: Sequence[ChainLink],
    chains: Sequence[Chain],
    youngs_modulus_Pa: float,
    allowed_stress_Pa: float,
    stress_concentration: float = 1.0,
) -> ChainSizing:
    """Per-link sizing: every link of a chain of ``n`` distinct links keeps the tip
    deflection it causes within ``budget / n`` (in every chain it is part of), then is
    thickened until its stress is within ``allowed_stress_Pa`` (and its other floor met):
    ``optimal_tube`` of the largest stiffness asked. With every lever 0 and a chain's
    budget ``n * dmax`` this is today's sizing (each link's own tip deflection within
    ``dmax``).

    Raises InfeasibleError naming the link, its share and what its stiffest tube gives,
    or (stress) what ``stress_floor`` raises.
    """
    prob = _prepare(links, chains, youngs_modulus_Pa, allowed_stress_Pa, stress_concentration)
    return _result(prob, _per_link_stiffness(prob), float(allowed_stress_Pa), 0)


def _per_link_stiffness(prob: _Problem) -> np.ndarray:
    """The stiffness (m) of every link sized on its own (see ``per_link_tubes``)."""
    stiffness = prob.floor.copy()
    for j, chain in enumerate(prob.chains):
        share = chain.budget_m / len(set(chain.links))
        for k, link in enumerate(prob.links):
            if prob.coeff[j, k] <= 0.0:
                continue
            need = 4.0 * prob.coeff[j, k] / (math.pi * share * link.length**3)
            if need * link.length**3 > link.limits.r_outer_max**4 * (1.0 + 1e-12):
                raise _share_error(prob, j, k, share)
            stiffness[k] = max(stiffness[k], need)
    return stiffness


# --------------------------------------------------------------------------- the program


def _inertia_max(x: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """``I~_max(x) = min(I~_W(x), I~_R(x))``: the largest scaled second moment of a
    printable tube of scaled area ``x`` (``eps^2 <= x <= 1``)."""
    rho = (x + eps * eps) / (2.0 * eps)
    wall = rho**4 - (rho - eps) ** 4
    return np.minimum(wall, x * (2.0 - x))


def _wall_tangent(x0: np.ndarray, eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Slope and intercept of the tangent at ``x0`` of ``I~_W^(1/3)``, convex in ``x``."""
    rho = (x0 + eps * eps) / (2.0 * eps)
    value = rho**4 - (rho - eps) ** 4
    derivative = 2.0 * (rho**3 - (rho - eps) ** 3) / eps
    root = np.cbrt(value)
    slope = derivative / (3.0 * root * root)
    return slope, root - slope * x0


@functools.lru_cache(maxsize=64)
def _program(n: int, m: int):
    """The convex restriction for ``n`` links and ``m`` chains, compiled once per shape
    (DPP: every datum is a parameter, each multiplying a variable at most)."""
    import cvxpy as cp  # lazy: ~1 s of imports, only where a chain is sized

    y, t, w = cp.Variable(n), cp.Variable(n), cp.Variable(n)
    par = {
        "weight": cp.Parameter(n, nonneg=True),
        "coeff": cp.Parameter((m, n), nonneg=True),
        "lo": cp.Parameter(n, nonneg=True),
        "hi": cp.Parameter(n, nonneg=True),
        "t_hi": cp.Parameter(n, nonneg=True),
        "a": cp.Parameter(n, nonneg=True),
        "b": cp.Parameter(n, nonneg=True),
        "slope": cp.Parameter(n, nonneg=True),
        "icpt": cp.Parameter(n),
    }
    constraints = [
        y >= par["lo"],
        y <= par["hi"],
        t <= par["t_hi"],
        w >= cp.square(y),
        # the outer radius r2max: a y - b y^2 = I~_R / sigma (w = y^2 at a solution)
        t >= cp.inv_pos(cp.multiply(par["a"], y) - cp.multiply(par["b"], w)),
        # the wall e: the cube of the tangent of (I~_W / sigma)^(1/3)
        t >= cp.power(cp.multiply(par["slope"], y) + par["icpt"], -3),
    ]
    if m:
        constraints.append(par["coeff"] @ t <= 1.0)
    problem = cp.Problem(cp.Minimize(par["weight"] @ y), constraints)
    return problem, y, par


def chain_tubes(
    links: Sequence[ChainLink],
    chains: Sequence[Chain],
    youngs_modulus_Pa: float,
    allowed_stress_Pa: float,
    stress_concentration: float = 1.0,
    *,
    method: str = "auto",
) -> ChainSizing:
    """The least-volume tubes of ``links`` that keep every chain's tip deflection within
    its budget and every link's stress within ``allowed_stress_Pa`` (Pa, with
    ``stress_concentration`` = Kt), as one convex program (see the module's docstring).

    ``youngs_modulus_Pa``: the material's E. ``method``: ``"separable"`` solves the
    optimality conditions directly (:func:`_chain_areas`: one multiplier per chain, each
    link's area in closed form of it up to a monotone Newton solve), exact and without
    cvxpy, for chains that share no link (a chain implied by another, entry by entry,
    is dropped first: alike limbs give identical chains); ``"program"`` solves the
    program with cvxpy and Clarabel from the per-link sizing (or, when that has no
    solution, the stiffest tubes), then polished to its KKT point (:func:`_polish`);
    ``"auto"`` (the default): the first when it applies, else the second. The solution
    is then made exactly feasible: the stiffnesses of a chain's links are raised by the
    residual (rounding; ~1e-10 from the solver when the polish gives up) when its
    deflection exceeds the budget, and never fall below the stress floors. One link
    gives ``optimal_tube``'s tube. Links already at their floors (stress, buckling:
    nothing is deflection-governed) are the optimum and are returned without a solve (0
    iterations).

    Raises InfeasibleError when a chain's tip deflection exceeds its budget even with the
    stiffest printable tubes (naming the chain, the link that contributes most and the
    limit), or when a link's strongest tube is overstressed (as ``stress_floor``);
    ValueError for ``method="separable"`` with chains that share a link.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    prob = _prepare(links, chains, youngs_modulus_Pa, allowed_stress_Pa, stress_concentration)
    allowed = float(allowed_stress_Pa)
    n, m = len(prob.links), len(prob.chains)
    big_r = np.array([link.limits.r_outer_max for link in prob.links])
    wall = np.array([link.limits.min_wall for link in prob.links])
    length = np.array([link.length for link in prob.links])
    eps = np.minimum(wall / big_r, 1.0)
    scale = math.pi / 4.0 * big_r**4  # I of the solid rod of r2max, m^4
    for j, chain in enumerate(prob.chains):
        best = prob.coeff[j] / scale
        if best.sum() > chain.budget_m:
            k = int(np.argmax(best))
            err = InfeasibleError(
                f"chain {chain.label} cannot keep its tip deflection within "
                f"{chain.budget_m * 1000:.3g} mm: with the stiffest printable tubes (solid, "
                f"r = r_outer_max) it deflects {best.sum() * 1000:.3g} mm, link "
                f"'{prob.links[k].name}' ({length[k] * 1000:.0f} mm, r_outer_max "
                f"{big_r[k] * 1000:.3g} mm) alone {best[k] * 1000:.3g} mm; allow a larger "
                "deflection, a larger r_outer_max, or carry less"
            )
            err.required, err.reachable = chain.budget_m, float(best.sum())
            # for a caller's own message: the chain, its worst link and that link's part
            err.chain, err.link, err.link_reachable = chain.links, prob.links[k].name, best[k]
            raise err
    # scaled: x = area / (pi r2max^2), I~ = I / scale, t = 1 / I~
    lo = np.array(
        [
            optimal_tube(f, link.limits, link.name).area / (math.pi * r * r) if f > 0 else 0.0
            for f, link, r in zip(prob.floor, prob.links, big_r, strict=True)
        ]
    )
    lo = np.clip(np.maximum(lo, eps * eps), 0.0, 1.0)
    budgets = np.array([c.budget_m for c in prob.chains])
    coeff = prob.coeff / scale / budgets[:, None] if m else np.zeros((0, n))
    weight = np.array([link.count for link in prob.links]) * length * big_r**2
    weight = weight / weight.max()
    rows, shared = _binding_rows(coeff)
    if method == "auto":
        method = "separable" if shared is None else "program"
    if method == "separable":
        if shared is not None:
            k, i, j = shared
            raise ValueError(
                f"method 'separable' needs chains that share no link: link "
                f"'{prob.links[k].name}' is in chains {prob.chains[i].label} and "
                f"{prob.chains[j].label}"
            )
        x0, iterations = lo.copy(), 0
        for j in rows:
            used = np.flatnonzero(coeff[j] > 0.0)
            x0[used], steps = _chain_areas(coeff[j, used], weight[used], lo[used], eps[used])
            iterations += steps
        return _finish(prob, x0, lo, eps, big_r, wall, length, allowed, iterations)
    try:
        start = _per_link_stiffness(prob)
        x0 = np.array(
            [optimal_tube(k, link.limits).area for k, link in zip(start, prob.links, strict=True)]
        ) / (math.pi * big_r**2)
    except InfeasibleError:  # some link cannot take an even share: see _slack_start
        x0 = _slack_start(prob, scale)
    else:
        if np.all(start <= prob.floor):  # every link at its least area: nothing to share
            return _result(prob, start, allowed, 0)
    x0 = np.clip(x0, lo, 1.0)

    # scaled for the solver about the start: y = x / start and t = sigma / I~ with
    # sigma = I~_max(start), both about 1 near a solution
    problem, y, par = _program(n, m)
    start = x0
    sigma = _inertia_max(start, eps)
    root = np.cbrt(sigma)
    par["weight"].value = weight * start / float(weight @ start)
    par["lo"].value, par["hi"].value = lo / start, 1.0 / start
    # t has no cost: bounded, lest the interior point drift off with it (twice its value
    # at the thinnest tube allowed, out of reach of any solution)
    par["t_hi"].value = 2.0 * sigma / _inertia_max(lo, eps)
    par["a"].value, par["b"].value = 2.0 * start / sigma, start * start / sigma
    if m:
        par["coeff"].value = coeff / sigma
    iterations = 0
    volume = float(weight @ x0)
    for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (reported)
        slope, icpt = _wall_tangent(x0, eps)
        par["slope"].value = np.maximum(slope, 0.0) * start / root
        par["icpt"].value = icpt / root
        with warnings.catch_warnings():  # "may be inaccurate": the status says it
            warnings.simplefilter("ignore", UserWarning)
            # no warm start: a solver updated from an earlier problem's factorisation
            # differs in the last digits, and identical inputs must give identical tubes
            problem.solve(solver="CLARABEL", warm_start=False, **SOLVER_OPTIONS)
        if problem.status not in ("optimal", "optimal_inaccurate") or y.value is None:
            break  # x0 is feasible: keep it
        x1 = np.clip(np.asarray(y.value, dtype=float) * start, lo, 1.0)
        x1[x1 <= lo * (1.0 + FLOOR_RTOL)] = lo[x1 <= lo * (1.0 + FLOOR_RTOL)]
        step = float(np.max(np.abs(x1 - x0) / x0))
        gain = volume - float(weight @ x1)
        x0, volume = x1, float(weight @ x1)
        if step <= X_TOL or abs(gain) <= V_TOL * volume:
            break
    polished = _polish(x0, lo, eps, coeff, weight)
    if polished is not None:
        x0 = polished
    return _finish(prob, x0, lo, eps, big_r, wall, length, allowed, iterations)


def _compliance(x: np.ndarray, eps: np.ndarray, wall: np.ndarray) -> tuple[np.ndarray, ...]:
    """``1 / I~`` of scaled areas ``x`` and its first two derivatives in ``x``, on the wall
    branch where ``wall`` (``I~_W``) and on the outer radius's elsewhere (``I~_R``): the
    formulas of :func:`_inertia_max`, differentiated."""
    rho = (x + eps * eps) / (2.0 * eps)
    inner = rho - eps
    inertia = np.where(wall, rho**4 - inner**4, x * (2.0 - x))
    d1 = np.where(wall, 2.0 * (rho**3 - inner**3) / eps, 2.0 - 2.0 * x)
    d2 = np.where(wall, 3.0 * (2.0 * rho - eps) / eps, -2.0)
    f = 1.0 / inertia
    return f, -d1 * f * f, (2.0 * d1 * d1 - inertia * d2) * f**3


def _polish(
    x: np.ndarray, lo: np.ndarray, eps: np.ndarray, coeff: np.ndarray, weight: np.ndarray
) -> np.ndarray | None:
    """The program's solution ``x`` (scaled areas, ~1e-5 from the optimum: the volume is
    flat there, and Clarabel meets it to ~1e-10) made exact: Newton's method on the KKT
    conditions, the active set read off ``x`` and corrected until it is certified.

    A link within ACTIVE_RTOL of its floor, of 1 or of the kink ``xc`` is held there, the
    others keep the branch they are on; a chain within ACTIVE_RTOL of its budget keeps it
    with equality, its multiplier ``lam_j``. The free links solve ``w_k + p_k f'(x_k) = 0``
    (``p_k = sum_j lam_j W_jk``, ``f = 1 / I~``, the derivatives of :func:`_compliance`)
    and the held budgets ``sum_k W_jk f(x_k) = 1``. A Newton step that would take a free
    link out of its branch's interval stops where the first one meets an end, which then
    holds it; after the solve a chain over its budget is held (its links at their floors
    freed), one whose multiplier is negative let go; with neither, the held link whose
    one-sided slope of ``w_k x + p_k f(x)`` points most steeply inwards (at its floor
    ``< 0`` to the right, at the kink ``> 0`` to the left or ``< 0`` to the right, at 1
    ``> 0`` to the left) is freed on that side, and the system solved again. When
    nothing is left to change, the point meets the KKT conditions of the convex program:
    it is the optimum. None (keep ``x``) when Newton's method does not converge in
    POLISH_STEPS steps or the active set does not settle in POLISH_ROUNDS x (links +
    chains + 1) changes: from the program's solutions it settles (every seeded case of
    the tests), from starts 1e-3 off not always."""
    with np.errstate(all="ignore"):  # a start it cannot settle from overflows: None
        return _settle(x, lo, eps, coeff, weight)


def _settle(
    x: np.ndarray, lo: np.ndarray, eps: np.ndarray, coeff: np.ndarray, weight: np.ndarray
) -> np.ndarray | None:
    """:func:`_polish`'s active-set and Newton loop."""
    n, m = len(x), coeff.shape[0]
    xc = eps * (2.0 - eps)
    near = np.abs(x - xc) <= ACTIVE_RTOL * xc
    held = np.where(near, xc, np.nan)  # the value a link is held at, NaN: free
    held[x >= 1.0 - ACTIVE_RTOL] = 1.0
    floor = x <= lo * (1.0 + ACTIVE_RTOL)
    held[floor] = lo[floor]
    wall = x < xc
    active = coeff @ (1.0 / _inertia_max(x, eps)) >= 1.0 - ACTIVE_RTOL
    z = x.copy()
    for _ in range(POLISH_ROUNDS * (n + m + 1)):
        # a link in no held budget is at its floor (nothing asks more of it); a budget
        # with no free link left cannot be held
        idle = np.isnan(held) & ~coeff[active].any(axis=0)
        active &= (coeff[:, np.isnan(held) & ~idle] > 0.0).any(axis=1)
        idle = np.isnan(held) & ~coeff[active].any(axis=0)
        free, rows = np.flatnonzero(np.isnan(held) & ~idle), np.flatnonzero(active)
        # each free link's interval: its branch's, above its floor
        bottom = np.where(wall, lo, np.maximum(lo, xc))
        top = np.where(wall, np.minimum(xc, 1.0), 1.0)
        z = np.where(np.isnan(held), np.clip(z, bottom, top), held)  # idle: kept to restart
        c = coeff[np.ix_(rows, free)]
        lam = np.zeros(len(rows))
        crossed = np.zeros(n, dtype=bool)
        if len(free):
            _, d1, _ = _compliance(z[free], eps[free], wall[free])
            lam = np.linalg.lstsq((c * d1).T, -weight[free], rcond=None)[0]
            for _step in range(POLISH_STEPS):
                _, d1, d2 = _compliance(z[free], eps[free], wall[free])
                pull = lam @ c
                resid = np.concatenate(
                    [weight[free] + pull * d1, coeff[rows] @ (1.0 / _inertia_max(z, eps)) - 1.0]
                )
                jac = np.zeros((len(free) + len(rows),) * 2)
                jac[: len(free), : len(free)] = np.diag(pull * d2)
                jac[: len(free), len(free) :] = (c * d1).T
                jac[len(free) :, : len(free)] = c * d1
                try:
                    step = np.linalg.solve(jac, -resid)
                except np.linalg.LinAlgError:
                    return None
                if not np.all(np.isfinite(step)):
                    return None
                dx = step[: len(free)]
                moved = z[free] + dx
                out = (moved < bottom[free]) | (moved > top[free])
                if out.any():  # up to the first end met, held there, and solved again
                    end = np.where(dx < 0.0, bottom[free], top[free])
                    frac = np.where(out, (end - z[free]) / np.where(out, dx, 1.0), 1.0)
                    first = out & (frac <= frac.min())
                    z[free] = np.where(first, end, z[free] + frac.min() * dx)
                    crossed[free[first]] = True
                    break
                z[free], lam = moved, lam + step[len(free) :]
                if np.all(np.abs(step[: len(free)]) <= 1e-14 * z[free]):
                    break
            else:
                return None
        z_idle = np.where(idle, lo, z)
        over = ~active & (coeff @ (1.0 / _inertia_max(z_idle, eps)) > 1.0)
        if crossed.any() or over.any() or np.any(lam < 0.0):
            held[crossed] = z[crossed]
            active[rows[lam < 0.0]] = False
            active |= over
            # a budget held again asks its links at their floors for more
            again = over[:, None] & (coeff > 0.0) & (held == lo)[None, :]
            held[again.any(axis=0)] = np.nan
            wall[again.any(axis=0)] = lo[again.any(axis=0)] < xc[again.any(axis=0)]
            continue
        # the held links: is either side downhill? (one-sided slopes of w x + p f)
        pull = lam @ coeff[rows] if len(rows) else np.zeros(n)
        _, left, _ = _compliance(z, eps, np.ones(n, dtype=bool))
        _, right, _ = _compliance(z, eps, np.zeros(n, dtype=bool))
        rises = weight + pull * np.where(z < xc, left, right)  # to the right
        falls = weight + pull * np.where(z <= xc, left, right)  # to the left
        pinned = ~np.isnan(held)
        up = np.where(pinned & (z < 1.0) & ((z == lo) | (z == xc)), -rises, 0.0)
        down = np.where(pinned & (z > lo) & ((z == xc) | (z == 1.0)), falls, 0.0)
        if max(up.max(), down.max()) <= 0.0:
            return z_idle
        # the steepest one freed (one at a time: freeing several at once can cycle)
        k = int(np.argmax(np.maximum(up, down)))
        held[k], wall[k] = np.nan, bool(z[k] < xc[k] if up[k] >= down[k] else z[k] <= xc[k])
    return None


def _finish(
    prob: _Problem,
    x0: np.ndarray,
    lo: np.ndarray,
    eps: np.ndarray,
    big_r: np.ndarray,
    wall: np.ndarray,
    length: np.ndarray,
    allowed: float,
    iterations: int,
) -> ChainSizing:
    """The tubes of the scaled areas ``x0`` (``lo``: their floors), made exactly feasible."""
    n, m = len(prob.links), len(prob.chains)
    stiffness = _inertia_max(x0, eps) * big_r**4 / length**3
    # a link at its floor takes the floor itself: its stress floor, else (loaded) just
    # under the thinnest rod's stiffness, as optimal_tube's "solid" branch, else none
    pinned = x0 <= lo
    loaded = prob.coeff.any(axis=0) if m else np.zeros(n, dtype=bool)
    thinnest = np.minimum(wall, big_r) ** 4 / length**3 * (1.0 - 1e-12)
    at_floor = np.where(prob.floor > 0.0, prob.floor, np.where(loaded, thinnest, 0.0))
    stiffness = np.where(pinned, at_floor, stiffness)
    return _result(prob, _within_budgets(prob, stiffness, pinned), allowed, iterations)


# --------------------------------------------------------------------------- separable


def _binding_rows(coeff: np.ndarray) -> tuple[list[int], tuple[int, int, int] | None]:
    """The chains (rows of the scaled coefficients) whose budgets can bind, and the first
    link two of them share (link, chain, chain), None when they share none.

    A row that is zero, or at most another row entry by entry (equal rows: all but the
    first), is implied by the other: ``t >= 0``, so ``sum_k W_ik t_k <= 1`` gives
    ``sum_k W_jk t_k <= 1`` when ``W_jk <= W_ik`` for every k. The rest must share no
    link (no column with two nonzero entries) for the separable solve."""
    m = coeff.shape[0]
    rows = []
    for j in range(m):
        row = coeff[j]
        if not np.any(row > 0.0):
            continue
        implied = any(
            i != j and np.all(coeff[i] >= row) and (i < j or np.any(coeff[i] > row))
            for i in range(m)
        )
        if not implied:
            rows.append(j)
    owner: dict[int, int] = {}
    for j in rows:
        for k in np.flatnonzero(coeff[j] > 0.0):
            if int(k) in owner:
                return rows, (int(k), owner[int(k)], j)
            owner[int(k)] = j
    return rows, None


def _chain_areas(
    W: np.ndarray, w: np.ndarray, lo: np.ndarray, eps: np.ndarray
) -> tuple[np.ndarray, int]:
    """The optimal scaled areas of one chain's links that no other chain shares, and the
    number of multiplier steps taken (0: no step, the floors or the stiffest tubes).

    ``W``: their scaled coefficients (the chain's deflection is ``sum W_k / I~(x_k)``
    budgets, all > 0); ``w``: their volume weights (> 0); ``lo``: their least areas;
    ``eps``: wall / r2max. The program is ``min sum w_k x_k`` subject to ``sum W_k /
    I~_max(x_k) <= 1``, ``lo_k <= x_k <= 1``: convex (module docstring) with one coupling
    constraint, so its KKT conditions are necessary and sufficient: with the budget's
    multiplier ``lam >= 0`` each ``x_k`` minimises ``w_k x_k + lam W_k / I~_max(x_k)`` on
    its bounds (:func:`_link_area`, of ``a_k = lam W_k / w_k``), and either ``lam = 0`` and
    the floors meet the budget, or the budget holds with equality. The deflection
    ``g(lam)`` falls continuously as ``lam`` grows (each ``x_k`` grows), so ``lam`` is its
    root, bracketed in ``log lam`` and found by the Illinois method to LAMBDA_RTOL;
    the areas are those of the bracket's feasible end (``g <= 1``)."""
    W, w, lo, eps = (np.asarray(v, dtype=float) for v in (W, w, lo, eps))

    def deflection(x: np.ndarray) -> float:
        return float(np.sum(W / _inertia_max(x, eps)))

    if deflection(lo) <= 1.0:
        return lo.copy(), 0
    stiffest = np.ones_like(lo)
    if deflection(stiffest) >= 1.0:  # the budget is met by the stiffest tubes alone
        return stiffest, 0
    ratio = W / w
    steps = 0

    def excess(mu: float) -> tuple[float, np.ndarray]:  # log(deflection / budget) at e^mu
        nonlocal steps
        steps += 1
        lam = math.exp(min(mu, 700.0))  # beyond, every x_k is 1 to the last bit
        x = np.array([_link_area(lam * r, a, e) for r, a, e in zip(ratio, lo, eps, strict=True)])
        return math.log(deflection(x)), x

    # a_k about 1 for the links of average share; widen by doubling steps of log lam
    mu = math.log(float(W.sum() / w.sum()) ** -1)
    f_mu, x_mu = excess(mu)
    span = math.log(8.0)
    if f_mu > 0.0:
        a, f_a = mu, f_mu
        b, (f_b, x_b) = mu + span, excess(mu + span)
        while f_b > 0.0 and steps < LAMBDA_STEPS:
            a, f_a, span = b, f_b, 2.0 * span
            b, (f_b, x_b) = b + span, excess(b + span)
    else:
        b, f_b, x_b = mu, f_mu, x_mu
        a, (f_a, x_a) = mu - span, excess(mu - span)
        while f_a <= 0.0 and steps < LAMBDA_STEPS:
            b, f_b, x_b, span = a, f_a, x_a, 2.0 * span
            a, (f_a, x_a) = a - span, excess(a - span)
    # Illinois regula falsi on [a, b]: excess(a) > 0 >= excess(b), one root
    side = 0
    while b - a > LAMBDA_RTOL * max(1.0, abs(b)) and f_b != 0.0 and steps < LAMBDA_STEPS:
        mid = b - f_b * (b - a) / (f_b - f_a)
        if not a < mid < b:
            mid = 0.5 * (a + b)
        f_mid, x_mid = excess(mid)
        if f_mid > 0.0:
            a, f_a = mid, f_mid
            f_b = f_b * 0.5 if side == -1 else f_b
            side = -1
        else:
            b, f_b, x_b = mid, f_mid, x_mid
            f_a = f_a * 0.5 if side == 1 else f_a
            side = 1
    return x_b, steps


def _link_area(a: float, lo: float, eps: float) -> float:
    """The scaled area ``x`` in ``[lo, 1]`` that minimises ``x + a / I~_max(x)`` (``a >=
    0``; ``eps = e / r2max``, ``eps^2 <= lo``): one link's part of the Lagrangian.

    Convex (module docstring), with a kink at ``xc = eps (2 - eps)``, the tube of wall
    ``e`` and outer radius ``r2max``, where ``I~_max`` changes branch; each branch's
    stationary point solves a monotone equation by Newton's method from its upper end,
    which converges from above (the functions are increasing and convex), so no iterate
    leaves the bracket [root, end] and the solve stops when a step no longer falls: the
    root to the last bit or two.

    * outer radius ``r2max`` (``xc <= x <= 1``): with ``q = r1 / r2max``, ``x = 1 - q^2``,
      ``I~ = 1 - q^4``; the stationarity ``1 = 2 a q^2 / (1 - q^4)^2`` is the quartic
      ``q^4 + sqrt(2a) q - 1 = 0``, one root in ``(0, 1)``.
    * wall ``e`` (``eps^2 <= x <= xc``): with the mid-radius ``m`` (``/ r2max``), ``x = 2 eps
      m`` and ``I~ = eps m (4 m^2 + eps^2)``; the stationarity is
      ``P(m) = m^2 (4 m^2 + eps^2)^2 / (12 m^2 + eps^2) = a / (2 eps^2)``, solved in
      ``log m``: ``log P`` is increasing and convex there (its slope
      ``2 + 16 u / (4u + eps^2) - 24 u / (12 u + eps^2)``, ``u = m^2``, grows from 2.5 at
      ``m = eps / 2`` to 4).

    If the first branch's root is at ``x >= xc`` it is the minimum; else, if the wall
    branch still falls at ``xc``, the kink is; else the wall branch's root. Then at least
    ``lo``.
    """
    if a <= 0.0:
        return lo
    xc = eps * (2.0 - eps)
    s = math.sqrt(2.0 * a)
    q = min(1.0, 1.0 / s)  # right of the root: q^4 + s q - 1 >= 0 there
    for _ in range(NEWTON_STEPS):
        q2 = q * q
        nxt = q - (q2 * q2 + s * q - 1.0) / (4.0 * q2 * q + s)
        if not nxt < q:
            break
        q = nxt
    if q <= 1.0 - eps:
        return max(1.0 - q * q, lo)
    e2 = eps * eps
    target = math.log(a / (2.0 * e2))

    def log_p(u: float) -> float:
        return math.log(u * (4.0 * u + e2) ** 2 / (12.0 * u + e2))

    top = 1.0 - 0.5 * eps  # the mid-radius at xc
    if log_p(top * top) <= target:
        return max(xc, lo)  # the wall branch still falls at the kink
    tau, bottom = math.log(top), math.log(0.5 * eps)
    for _ in range(NEWTON_STEPS):
        u = math.exp(2.0 * tau)
        slope = 2.0 + 16.0 * u / (4.0 * u + e2) - 24.0 * u / (12.0 * u + e2)
        nxt = tau - (log_p(u) - target) / slope
        if not nxt < tau:
            break
        if nxt <= bottom:  # the root is below the thinnest rod: it is at most lo
            tau = bottom
            break
        tau = nxt
    return max(2.0 * eps * math.exp(tau), lo)


def _slack_start(prob: _Problem, scale: np.ndarray) -> np.ndarray:
    """A feasible start (scaled areas) when an even share is too little for some link:
    each link of a chain gets the deflection of its stiffest tube plus an even share of
    what the chain's budget leaves over (the chains were checked to leave some)."""
    n = len(prob.links)
    inertia = np.zeros(n)  # I~ asked of each link
    for j, chain in enumerate(prob.chains):
        best = prob.coeff[j] / scale  # m, the tip deflection of each stiffest tube
        spare = (chain.budget_m - best.sum()) / max(int(np.count_nonzero(best)), 1)
        used = best > 0.0
        inertia[used] = np.maximum(inertia[used], best[used] / (best[used] + spare))
    x = np.ones(n)
    for k, link in enumerate(prob.links):
        need = max(inertia[k] * scale[k] * 4.0 / math.pi / link.length**3, prob.floor[k])
        x[k] = optimal_tube(need, link.limits, link.name).area / (
            math.pi * link.limits.r_outer_max**2
        )
    return x


def _within_budgets(
    prob: _Problem, stiffness: np.ndarray, pinned: np.ndarray | None = None
) -> np.ndarray:
    """``stiffness`` (m, at least the floors) raised so that the tubes ``optimal_tube``
    gives for it keep every chain within its budget: a chain over it (by the solver's
    residual, ~1e-10) has its links that are not the stiffest tube stiffened by the
    factor that brings it back, a little inside; ``pinned`` links (at their floor) only
    when the others cannot."""
    out = np.maximum(stiffness, prob.floor)
    k_max = np.array([link.limits.r_outer_max**4 / link.length**3 for link in prob.links])
    out = np.minimum(out, k_max)
    budgets = np.array([c.budget_m for c in prob.chains])
    for _ in range(4):
        inertia = np.array(
            [
                optimal_tube(k, link.limits, link.name).second_moment
                for k, link in zip(out, prob.links, strict=True)
            ]
        )
        over = prob.coeff @ (1.0 / inertia) / budgets if len(budgets) else np.zeros(0)
        if not len(over) or over.max() <= 1.0:
            break
        j = int(np.argmax(over))
        row = prob.coeff[j] / inertia / budgets[j]  # each link's part of the ratio
        free = (row > 0.0) & (out < k_max)
        if pinned is not None and np.any(free & ~pinned):
            free &= ~pinned  # links at their floor stay there when the others suffice
        fixed, spare = float(row[~free].sum()), float(row[free].sum())
        if spare <= 0.0 or fixed >= 1.0:
            break  # cannot happen for a feasible chain
        factor = spare / (1.0 - fixed) * (1.0 + 1e-13)
        out[free] = np.minimum(out[free] * factor, k_max[free])
    return out
