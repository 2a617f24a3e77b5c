"""Tests of synth/sizing/chain_links.py: a serial chain's links sized as one convex program.

Everything the program claims is checked with the beam formulas of ``synth.sizing.links``
(``beam_check``: one frame element per link) and the closed form ``optimal_tube``, not
with the program's own numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from adron.errors import InfeasibleError, ParmorError
from kinematics.model import Body, Joint, Model
from synth.sizing.chain_links import (
    Chain,
    ChainLink,
    _Problem,
    _within_budgets,
    chain_tubes,
    clamp_sections,
    deflection_coefficient,
    per_link_tubes,
    serial_chains,
    stress_floor,
    tube_stress,
)
from synth.sizing.links import Tube, TubeLimits, beam_check, optimal_tube, stiffness_constant

# the shipped catalog's material and passive section (adron/catalog.toml)
E = 2.3e9  # Pa, PLA
ALLOWED = 40e6 / 2.0  # Pa, yield / stress safety factor
KT = 1.8
R_MAX, WALL = 0.020, 0.0012  # m
GRID = 240  # random chains in the grid test (>= 200)


def limits(length: float, r_max: float = R_MAX, wall: float = WALL) -> TubeLimits:
    return TubeLimits(r_max, wall, length, length)


def random_load(rng: np.random.Generator, force: float, moment: float) -> np.ndarray:
    """A free-end load [Fx Fy Fz Mx My Mz] of about ``force`` N and ``moment`` N m."""
    f = rng.normal(size=3) * force
    m = rng.normal(size=3) * moment
    return np.concatenate([f, m])


def chain_tip_deflection(
    chain: Chain, links: dict[str, ChainLink], tubes: dict[str, Tube]
) -> float:
    """The chain's tip deflection from ``beam_check``: per link, the worst over its loads
    of its free end's transverse displacement plus its rotation (about y and z) times
    the lever (the lengths after it)."""
    lengths = [links[n].length for n in chain.links]
    total = 0.0
    for i, name in enumerate(chain.links):
        lever = chain.levers_m[i] if chain.levers_m is not None else sum(lengths[i + 1 :])
        worst = 0.0
        for load in links[name].loads:
            r = beam_check(tubes[name], load, E)
            turn = math.hypot(r.tip_rotation_rad[1], r.tip_rotation_rad[2])
            worst = max(worst, r.tip_deflection_m + turn * lever)
        total += worst
    return total


def check_design(
    sized, links: list[ChainLink], chains: list[Chain], allowed: float = ALLOWED
) -> None:
    """Every chain within its budget, every link within its stress and printable."""
    by_name = {link.name: link for link in links}
    for chain in chains:
        tip = chain_tip_deflection(chain, by_name, sized.tubes)
        assert tip <= chain.budget_m * (1.0 + 1e-12), (chain.label, tip / chain.budget_m)
    for link in links:
        tube = sized.tubes[link.name]
        lim = link.limits
        assert tube.r_outer <= lim.r_outer_max * (1.0 + 1e-12)
        assert tube.r_outer - tube.r_inner >= lim.min_wall * (1.0 - 1e-9)
        assert tube.r_inner >= 0.0
        assert tube.length == lim.length_min
        for load in link.loads:
            stress = beam_check(tube, load, E, KT).max_stress_Pa
            assert stress <= allowed * (1.0 + 1e-9), (link.name, stress / allowed)


# --------------------------------------------------------------------------- one link


@pytest.mark.parametrize("branch", ["solid", "wall", "stiffness"])
def test_one_link_is_the_closed_form(branch: str) -> None:
    """One link with no lever: the program gives optimal_tube's tube for the stiffness
    constant of its equivalent tip force, to 1e-6, on each branch."""
    rng = np.random.default_rng({"solid": 1, "wall": 2, "stiffness": 3}[branch])
    for _ in range(12):
        length = rng.uniform(0.05, 0.3)
        r_max = rng.uniform(0.006, 0.025)
        wall = r_max * rng.uniform(0.05, 0.3)
        lim = limits(length, r_max, wall)
        if branch == "solid":
            c = wall**4 * rng.uniform(0.01, 0.9)
        elif branch == "wall":
            c = wall**4 + (r_max**4 - (r_max - wall) ** 4 - wall**4) * rng.uniform(0.05, 0.95)
        else:
            edge = r_max**4 - (r_max - wall) ** 4
            c = edge + (r_max**4 - edge) * rng.uniform(0.05, 0.95)
        k0 = c / length**3
        load = random_load(rng, 5.0, 0.3)
        force = math.hypot(load[1], load[2]) + 1.5 * math.hypot(load[4], load[5]) / length
        budget = 4.0 * force / (3.0 * math.pi * E * k0)  # so that stiffness_constant = k0
        assert stiffness_constant(force, E, budget) == pytest.approx(k0, rel=1e-12)
        link = ChainLink("L1", lim, (load,))
        chain = Chain(("L1",), budget)
        closed = optimal_tube(k0, lim)
        assert closed.active == branch
        for sized in (
            chain_tubes([link], [chain], E, 1e12),
            per_link_tubes([link], [chain], E, 1e12),
        ):
            tube = sized.tubes["L1"]
            assert tube.active == closed.active
            assert tube.volume == pytest.approx(closed.volume, rel=1e-6)
            assert tube.r_outer == pytest.approx(closed.r_outer, rel=1e-6)
            assert abs(tube.r_inner - closed.r_inner) <= 1e-6 * closed.r_outer
            assert sized.governed["L1"] == "deflection"
            check_design(sized, [link], [chain], allowed=1e12)


def test_deflection_coefficient_is_the_cantilever() -> None:
    """c / I is the cantilever's tip deflection (lever 0) and adds the tip rotation times
    the lever, as beam_check gives them."""
    rng = np.random.default_rng(4)
    tube = optimal_tube(3e-5, limits(0.12))
    for _ in range(20):
        load = random_load(rng, 3.0, 0.2)
        load[[2, 5]] = 0.0  # one bending plane: the magnitudes add exactly
        lever = rng.uniform(0.0, 0.4)
        r = beam_check(tube, load, E)
        expected = r.tip_deflection_m + abs(r.tip_rotation_rad[2]) * lever
        if np.sign(load[1]) != np.sign(load[5]):  # opposed force and moment: an upper bound
            assert deflection_coefficient(load, 0.12, lever, E) / tube.second_moment >= expected
        else:
            c = deflection_coefficient(load, 0.12, lever, E)
            assert c / tube.second_moment == pytest.approx(expected, rel=1e-9)


def test_stress_matches_beam_check_and_the_floor_is_tight() -> None:
    """tube_stress is beam_check's stress; the stress floor's tube meets the allowed
    stress (beam_check) and one a little less stiff does not; the floor agrees with a
    bisection on beam_check like the structure generator's."""
    rng = np.random.default_rng(5)
    for _ in range(25):
        length = rng.uniform(0.05, 0.3)
        lim = limits(length)
        loads = tuple(random_load(rng, 20.0, 1.5) for _ in range(3))
        link = ChainLink("L", lim, loads)
        k = stress_floor(link, ALLOWED, KT)
        tube = optimal_tube(k, lim)
        sections = clamp_sections(loads, length)
        worst = max(beam_check(tube, ld, E, KT).max_stress_Pa for ld in loads)
        assert tube_stress(tube, sections, KT) == pytest.approx(worst, rel=1e-12)
        assert worst <= ALLOWED * (1.0 + 1e-12)
        if k == 0.0:
            continue
        weaker = optimal_tube(k * (1.0 - 1e-9), lim)
        assert max(beam_check(weaker, ld, E, KT).max_stress_Pa for ld in loads) > ALLOWED
        lo, hi = WALL**4 / length**3, R_MAX**4 / length**3
        for _ in range(80):
            mid = math.sqrt(lo * hi)
            if (
                max(beam_check(optimal_tube(mid, lim), ld, E, KT).max_stress_Pa for ld in loads)
                > ALLOWED
            ):
                lo = mid
            else:
                hi = mid
        assert k == pytest.approx(hi, rel=1e-9)


# --------------------------------------------------------------------------- the grid


def random_chain(rng: np.random.Generator, n: int) -> tuple[list[ChainLink], Chain]:
    """``n`` links with random lengths, limits and 1-3 loads each (none overstressed in
    its strongest tube), and a budget the per-link sizing can meet (at least ``n`` times
    the largest stiffest-tube share)."""
    links: list[ChainLink] = []
    while len(links) < n:
        length = rng.uniform(0.04, 0.3)
        r_max = rng.uniform(0.008, 0.025)
        wall = rng.uniform(0.0008, 0.002)
        force, moment = 10 ** rng.uniform(-1.0, 1.3), 10 ** rng.uniform(-2.0, 0.3)
        loads = tuple(random_load(rng, force, moment) for _ in range(rng.integers(1, 4)))
        link = ChainLink(f"L{len(links) + 1}", limits(length, r_max, wall), loads)
        try:
            stress_floor(link, ALLOWED, KT)
        except InfeasibleError:
            continue  # overstressed whatever its tube: draw another
        links.append(link)
    lengths = [link.length for link in links]
    best = max(
        max(deflection_coefficient(ld, link.length, sum(lengths[i + 1 :]), E) for ld in link.loads)
        / (math.pi / 4.0 * link.limits.r_outer_max**4)
        for i, link in enumerate(links)
    )
    budget = n * best * 10 ** rng.uniform(0.02, 1.5)
    return links, Chain(tuple(link.name for link in links), budget)


def test_joint_program_is_never_heavier_and_always_feasible() -> None:
    """Over a seeded grid of chains of 2-6 links: the joint program meets every chain's
    budget and every stress limit (beam_check) and is never heavier than per-link
    sizing; it saves on average."""
    rng = np.random.default_rng(2024)
    savings, governed = [], {"stress": 0, "deflection": 0}
    for _ in range(GRID):
        links, chain = random_chain(rng, int(rng.integers(2, 7)))
        joint = chain_tubes(links, [chain], E, ALLOWED, KT)
        alone = per_link_tubes(links, [chain], E, ALLOWED, KT)
        check_design(joint, links, [chain])
        check_design(alone, links, [chain])
        assert joint.volume_m3 <= alone.volume_m3 * (1.0 + 1e-9)
        volume = sum(t.volume for t in joint.tubes.values())
        assert joint.volume_m3 == pytest.approx(volume, rel=1e-12)
        savings.append(1.0 - joint.volume_m3 / alone.volume_m3)
        for g in joint.governed.values():
            governed[g] += 1
    mean, top = float(np.mean(savings)), float(np.max(savings))
    print(f"\njoint vs per-link over {GRID} chains: mean saving {mean:.1%}, max {top:.1%}")
    assert mean > 0.05 and top > 0.3
    assert governed["stress"] > 0 and governed["deflection"] > 0  # both kinds of link met


def test_joint_program_where_even_shares_fail() -> None:
    """A chain whose first link cannot take an even share of the budget: per-link sizing
    fails naming it, the joint program gives that link more and meets the budget."""
    links = [
        ChainLink("L1", limits(0.25), (np.array([0.0, 6.0, 0.0, 0.0, 0.0, 0.0]),)),
        ChainLink("L2", limits(0.1), (np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0]),)),
        ChainLink("L3", limits(0.1), (np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0]),)),
    ]
    best = deflection_coefficient(links[0].loads[0], 0.25, 0.2, E) / (math.pi / 4 * R_MAX**4)
    chain = Chain(("L1", "L2", "L3"), 2.0 * best)  # L1 needs half; an even share is a third
    with pytest.raises(InfeasibleError, match="link 'L1' .* share") as err:
        per_link_tubes(links, [chain], E, ALLOWED, KT)
    assert err.value.reachable > err.value.required
    sized = chain_tubes(links, [chain], E, ALLOWED, KT)
    check_design(sized, links, [chain])
    tip = chain_tip_deflection(chain, {lk.name: lk for lk in links}, sized.tubes)
    assert tip == pytest.approx(chain.budget_m, rel=1e-6)  # the budget binds


def test_shared_links_and_counts() -> None:
    """Two chains sharing their root link (each with its own levers) both meet their
    budgets; a link printed five times is made lighter than when printed once (the
    shared root thicker). Its twin in the other chain, with the same load and budget,
    is as light: with the root given, each chain's last link is the thinnest that keeps
    its chain within budget, so the two are equal at the optimum."""
    load = np.array([0.0, 2.0, 1.0, 0.0, 0.1, 0.0])
    links = [
        ChainLink("hip", limits(0.1), (load,)),
        ChainLink("a", limits(0.15), (load,), count=5),
        ChainLink("b", limits(0.15), (load,), count=1),
    ]
    chains = [
        Chain(("hip", "a"), 4e-4, levers_m=(0.2, 0.0)),
        Chain(("hip", "b"), 4e-4, levers_m=(0.2, 0.0)),
    ]
    sized = chain_tubes(links, chains, E, ALLOWED, KT)  # they share "hip": the program
    assert sized.iterations >= 1
    check_design(sized, links, chains)
    once = [links[0], ChainLink("a", limits(0.15), (load,)), links[2]]
    single = chain_tubes(once, chains, E, ALLOWED, KT)
    assert sized.tubes["a"].volume < single.tubes["a"].volume * (1.0 - 1e-3)
    assert sized.tubes["hip"].volume > single.tubes["hip"].volume * (1.0 + 1e-3)
    assert sized.tubes["a"].volume == pytest.approx(sized.tubes["b"].volume, rel=1e-9)
    weighted = sum(lk.count * sized.tubes[lk.name].volume for lk in links)
    assert sized.volume_m3 == pytest.approx(weighted, rel=1e-12)
    alone = per_link_tubes(links, chains, E, ALLOWED, KT)
    assert sized.volume_m3 <= alone.volume_m3


def test_unloaded_link_is_the_thinnest_rod_and_results_repeat() -> None:
    """A link with no load gets the thinnest printable rod; the same inputs give the
    same bits, whatever was solved before (the compiled problem is shared)."""
    rng = np.random.default_rng(9)
    links, chain = random_chain(rng, 4)
    links.append(ChainLink("idle", limits(0.1), ()))
    first = chain_tubes(links, [chain], E, ALLOWED, KT)
    idle = first.tubes["idle"]
    assert (idle.r_outer, idle.r_inner) == (WALL, 0.0)
    other, other_chain = random_chain(rng, 4)
    chain_tubes([*other, ChainLink("idle", limits(0.1), ())], [other_chain], E, ALLOWED, KT)
    again = chain_tubes(links, [chain], E, ALLOWED, KT)
    assert again.tubes == first.tubes
    assert again.tip_deflection_m == first.tip_deflection_m


# --------------------------------------------------------------------------- errors


def test_infeasible_budget_names_the_chain_and_the_link() -> None:
    """A budget that even solid tubes of the largest radius cannot meet."""
    links = [
        ChainLink("L1", limits(0.3), (np.array([0.0, 50.0, 0.0, 0.0, 0.0, 0.0]),)),
        ChainLink("L2", limits(0.1), (np.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0]),)),
    ]
    chain = Chain(("L1", "L2"), 1e-5)
    with pytest.raises(InfeasibleError) as err:
        chain_tubes(links, [chain], E, ALLOWED, KT)
    text = str(err.value)
    assert "chain 'L1 -> L2'" in text and "0.01 mm" in text and "link 'L1'" in text
    assert "r_outer_max 20 mm" in text
    assert err.value.reachable > err.value.required == 1e-5
    assert isinstance(err.value, ParmorError) and err.value.exit_code == 1


def test_overstressed_link_is_named() -> None:
    """A load that overstresses even the solid rod of the largest radius."""
    links = [ChainLink("L1", limits(0.3), (np.array([0.0, 400.0, 0.0, 0.0, 0.0, 0.0]),))]
    with pytest.raises(
        InfeasibleError, match=r"link 'L1' \(300 mm\).* exceeds the allowed 20.0 MPa"
    ):
        chain_tubes(links, [Chain(("L1",), 1.0)], E, ALLOWED, KT)


def test_wall_thicker_than_the_radius_is_infeasible() -> None:
    link = ChainLink("L1", limits(0.1, r_max=0.001, wall=0.002), ())
    with pytest.raises(InfeasibleError, match="minimum wall"):
        chain_tubes([link], [Chain(("L1",), 1e-3)], E, ALLOWED, KT)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: ChainLink("L1", limits(0.1), ([1.0, 2.0],)), "load 0 must be a finite 6-vector"),
        (lambda: ChainLink("L1", limits(0.1), ([math.nan] * 6,)), "finite 6-vector"),
        (lambda: ChainLink("", limits(0.1), ()), "non-empty name"),
        (lambda: ChainLink("L1", limits(0.1), (), count=0), "count must be an integer >= 1"),
        (lambda: ChainLink("L1", limits(0.1), (), min_stiffness_m=-1.0), "min_stiffness_m"),
        (lambda: Chain((), 1e-3), "at least one link"),
        (lambda: Chain(("L1",), 0.0), "budget_m must be positive"),
        (lambda: Chain(("L1", "L2"), 1e-3, levers_m=(0.1,)), "1 levers for 2 links"),
        (lambda: Chain(("L1",), 1e-3, levers_m=(-0.1,)), "lever of 'L1'"),
    ],
)
def test_bad_inputs_are_named(build, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        build()


def test_bad_problems_are_named() -> None:
    link = ChainLink("L1", limits(0.1), ())
    with pytest.raises(ValueError, match="no link 'L9'"):
        chain_tubes([link], [Chain(("L1", "L9"), 1e-3)], E, ALLOWED)
    with pytest.raises(ValueError, match="'L1' is given twice"):
        chain_tubes([link, link], [], E, ALLOWED)
    with pytest.raises(ValueError, match="youngs_modulus_Pa"):
        per_link_tubes([link], [], -1.0, ALLOWED)
    with pytest.raises(ValueError, match="allowed_stress_Pa"):
        per_link_tubes([link], [], E, 0.0)
    with pytest.raises(ValueError, match="stress_concentration"):
        per_link_tubes([link], [], E, ALLOWED, 0.5)
    with pytest.raises(ValueError, match="no links"):
        chain_tubes([], [], E, ALLOWED)


def test_solver_residual_is_removed() -> None:
    """Stiffnesses that leave a chain over its budget by a solver-sized residual are
    raised until the tubes meet it (the links at their stiffest tube kept)."""
    rng = np.random.default_rng(10)
    links, chain = random_chain(rng, 3)
    sized = chain_tubes(links, [chain], E, 1e12, KT)
    k = np.array([sized.tubes[lk.name].stiffness for lk in links])
    coeff = np.array(
        [
            max(deflection_coefficient(ld, lk.length, lv, E) for ld in lk.loads)
            for lk, lv in zip(
                links, [links[1].length + links[2].length, links[2].length, 0.0], strict=True
            )
        ]
    )
    prob = _Problem(tuple(links), (chain,), coeff[None, :], np.zeros(3), np.zeros(3), (), 1.0)
    short = k * (1.0 - 1e-7)  # the tip now deflects ~1e-7 too much
    inertia = [optimal_tube(s, lk.limits).second_moment for s, lk in zip(short, links, strict=True)]
    assert coeff @ (1.0 / np.array(inertia)) > chain.budget_m
    fixed = _within_budgets(prob, short)
    tubes = {lk.name: optimal_tube(s, lk.limits) for s, lk in zip(fixed, links, strict=True)}
    assert chain_tip_deflection(chain, {lk.name: lk for lk in links}, tubes) <= chain.budget_m
    model = coeff @ (1.0 / np.array([t.second_moment for t in tubes.values()]))
    assert model <= chain.budget_m
    assert model == pytest.approx(chain.budget_m, rel=1e-9)  # raised just enough
    assert np.all(fixed >= short)


# --------------------------------------------------------------------------- chains


@dataclass(frozen=True)
class Seg:
    """The attributes of kinematics.templates.Segment that serial_chains reads."""

    name: str
    body: str
    start: np.ndarray
    direction: np.ndarray
    length: float
    length_name: str = ""


def _frame(x: float, y: float = 0.0) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = (x, y, 0.0)
    return out


def test_serial_chains_of_a_tree() -> None:
    """A base with two alike arms (L1, L2, a gripper) and a leg (L1 then a foot): the
    arms merge into one chain, levers the path lengths through the joint points."""
    i3 = np.zeros((3, 3))
    names = ["base", "a1", "a2", "grip_a", "b1", "b2", "grip_b", "leg", "foot"]
    bodies = [Body(n, 0.1, np.zeros(3), i3) for n in names]
    joints = [
        Joint("j_base", -1, 0, "fixed", np.eye(4)),
        Joint("ja1", 0, 1, "revolute", _frame(0.0, 0.05)),
        Joint("ja2", 1, 2, "revolute", _frame(0.10)),
        Joint("jga", 2, 3, "fixed", _frame(0.16)),  # 1 cm past the end of L2
        Joint("jb1", 0, 4, "revolute", _frame(0.0, -0.05)),
        Joint("jb2", 4, 5, "revolute", _frame(0.10)),
        Joint("jgb", 5, 6, "fixed", _frame(0.16)),
        Joint("jleg", 0, 7, "revolute", _frame(0.05)),
        Joint("jfoot", 7, 8, "fixed", _frame(0.2)),
    ]
    model = Model(bodies, joints)
    x = np.array([1.0, 0.0, 0.0])
    segs = [
        Seg("a_L1", "a1", np.zeros(3), x, 0.10, "L1"),
        Seg("a_L2", "a2", np.zeros(3), x, 0.15, "L2"),
        Seg("b_L1", "b1", np.zeros(3), x, 0.10, "L1"),
        Seg("b_L2", "b2", np.zeros(3), x, 0.15, "L2"),
        Seg("leg", "leg", np.zeros(3), x, 0.2, "L3"),
    ]
    got = serial_chains(model, segs)
    assert [names for names, _ in got] == [("L1", "L2"), ("L3",)]
    levers = dict(got)
    assert levers[("L1", "L2")] == pytest.approx((0.16, 0.01))
    assert levers[("L3",)] == pytest.approx((0.0,))
    # tips given: the leg's foot touches 3 cm below its origin
    got = serial_chains(model, segs, {"foot": (0.0, 0.0, -0.03), "grip_a": (0.02, 0.0, 0.0)})
    assert dict(got) == {("L3",): pytest.approx((0.03,)), ("L1", "L2"): pytest.approx((0.18, 0.03))}


def test_a_failed_solve_keeps_the_feasible_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """When Clarabel returns no solution the program (run explicitly: one chain takes the
    separable solve) keeps its start, the per-link sizing (feasible), instead of failing
    or returning nothing: never heavier (the polish may improve it, or give up from so
    far), and without the polish the per-link sizing itself."""
    from types import SimpleNamespace

    import synth.sizing.chain_links as chain_links

    def failing(n: int, m: int):
        params = {
            k: SimpleNamespace(value=None)
            for k in ("weight", "coeff", "lo", "hi", "t_hi", "a", "b", "slope", "icpt")
        }
        problem = SimpleNamespace(status="solver_error", solve=lambda *a, **k: None)
        return problem, SimpleNamespace(value=None), params

    rng = np.random.default_rng(11)
    links, chain = random_chain(rng, 3)
    monkeypatch.setattr(chain_links, "_program", failing)
    polished = chain_tubes(links, [chain], E, ALLOWED, KT, method="program")
    alone = per_link_tubes(links, [chain], E, ALLOWED, KT)
    assert polished.iterations == 1
    assert polished.volume_m3 <= alone.volume_m3 * (1.0 + 1e-12)
    check_design(polished, links, [chain])
    monkeypatch.setattr(chain_links, "_polish", lambda *a: None)
    kept = chain_tubes(links, [chain], E, ALLOWED, KT, method="program")
    assert kept.iterations == 1
    assert kept.volume_m3 == pytest.approx(alone.volume_m3, rel=1e-12)
    check_design(kept, links, [chain])
