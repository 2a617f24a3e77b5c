"""The separable solve of synth/sizing/chain_links.py (issue 20, item 5, speed): chains that
share no link sized from the program's optimality conditions, without cvxpy, against
the cvxpy + Clarabel program run explicitly; chains that share a link still go through
the program; a design does not import cvxpy.

The program's own result is polished to the KKT point (``_polish``); what is compared is
two solutions found independently: the separable one from one multiplier per chain and
each link's closed-form minimiser, the program's from Clarabel's solution and Newton's
method on the KKT system in the areas. Budgets and stresses are checked with the beam
formulas (``check_design``: ``beam_check``).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import synth.sizing.chain_links as chain_links
from adron.errors import InfeasibleError
from synth.sizing.chain_links import (
    ACTIVE_RTOL,
    Chain,
    ChainLink,
    _chain_areas,
    _inertia_max,
    _link_area,
    _polish,
    chain_tubes,
    deflection_coefficient,
    stress_floor,
)
from tests.conftest import REPO
from tests.synth.sizing.test_chain_links import ALLOWED, KT, E, check_design, limits, random_load

SETS = 240  # random chain sets compared with the program (>= 200)


def random_chain_set(rng: np.random.Generator) -> tuple[list[ChainLink], list[Chain]]:
    """1-3 chains of 1-6 links that share no link: random lengths, outer radii (6-25 mm)
    and walls (3-50 % of it: both branches and the kink between them), 1-3 loads a link
    (1 in 10 links none, unloaded), counts 1-6, 1 in 5 links with a buckling floor, the
    levers given or end to end, each budget 1.005-30 times what the stiffest tubes give
    (tight budgets put links at r2max, loose ones leave links at their floors)."""
    links: list[ChainLink] = []
    chains: list[Chain] = []
    for c in range(int(rng.integers(1, 4))):
        mine: list[ChainLink] = []
        size = int(rng.integers(1, 7))
        while len(mine) < size:
            length = rng.uniform(0.04, 0.3)
            r_max = rng.uniform(0.006, 0.025)
            wall = r_max * rng.uniform(0.03, 0.5)
            force, moment = 10 ** rng.uniform(-1.0, 1.3), 10 ** rng.uniform(-2.0, 0.3)
            count = int(rng.integers(0, 4)) if rng.uniform() < 0.1 else int(rng.integers(1, 4))
            loads = tuple(random_load(rng, force, moment) for _ in range(count))
            buckle = 10 ** rng.uniform(-9.0, -6.0) if rng.uniform() < 0.2 else 0.0
            lim = limits(length, r_max, wall)
            if buckle > r_max**4 / length**3:
                continue
            link = ChainLink(f"C{c}L{len(mine) + 1}", lim, loads, int(rng.integers(1, 7)), buckle)
            try:
                stress_floor(link, ALLOWED, KT)
            except InfeasibleError:
                continue  # overstressed whatever its tube: draw another
            mine.append(link)
        levers = tuple(rng.uniform(0.0, 0.4) for _ in mine) if rng.uniform() < 0.5 else None
        ends = levers or tuple(sum(lk.length for lk in mine[i + 1 :]) for i in range(len(mine)))
        best = sum(
            max((deflection_coefficient(ld, lk.length, lv, E) for ld in lk.loads), default=0.0)
            / (math.pi / 4.0 * lk.limits.r_outer_max**4)
            for lk, lv in zip(mine, ends, strict=True)
        )
        budget = max(best, 1e-9) * 10 ** rng.uniform(0.002, 1.5)
        links += mine
        chains.append(Chain(tuple(lk.name for lk in mine), budget, levers))
    return links, chains


def relative_gap(a, b) -> float:
    """The largest relative difference of two sizings' tube areas and volumes."""
    gaps = [abs(a.tubes[n].area / b.tubes[n].area - 1.0) for n in a.tubes]
    return max([*gaps, abs(a.volume_m3 / b.volume_m3 - 1.0)])


def test_separable_is_the_program_on_random_chain_sets() -> None:
    """On 240 seeded sets of chains without shared links the separable solve and the
    cvxpy program (run explicitly) give the same areas and mass to 1e-6 (measured:
    ~1e-12); the default takes the separable solve, bit for bit; every design meets its
    budgets and stresses (beam_check); the sets meet every kind of link."""
    rng = np.random.default_rng(20)
    kinds: dict[str, int] = {}
    worst = 0.0
    for _ in range(SETS):
        links, chains = random_chain_set(rng)
        fast = chain_tubes(links, chains, E, ALLOWED, KT, method="separable")
        program = chain_tubes(links, chains, E, ALLOWED, KT, method="program")
        gap = relative_gap(fast, program)
        assert gap <= 1e-6, ([c.label for c in chains], gap)
        worst = max(worst, gap)
        assert chain_tubes(links, chains, E, ALLOWED, KT) == fast
        check_design(fast, links, chains)
        for name, tube in fast.tubes.items():
            kinds[tube.active] = kinds.get(tube.active, 0) + 1
            kinds[fast.governed[name]] = kinds.get(fast.governed[name], 0) + 1
    print(f"\nseparable vs program over {SETS} chain sets: largest relative gap {worst:.1e}")
    for kind in ("stiffness", "wall", "solid", "minimum", "stress", "deflection"):
        assert kinds.get(kind, 0) > 0, (kind, kinds)


def test_link_area_minimises_its_term() -> None:
    """``_link_area`` is the minimum of ``x + a / I~_max(x)`` on ``[lo, 1]``: no point of a
    fine grid about it nor either neighbour (1e-6 away) is lower, on both branches, at the
    kink and at the floor; a point 1e-3 off is higher (the check can fail)."""
    rng = np.random.default_rng(3)
    where = {"floor": 0, "kink": 0, "wall": 0, "radius": 0}
    for _ in range(2000):
        eps = rng.uniform(0.02, 0.6)
        lo = eps * eps * 10 ** rng.uniform(0.0, 1.5) if rng.uniform() < 0.5 else eps * eps
        lo = min(lo, 0.99)
        a = 10 ** rng.uniform(-6.0, 3.0)
        x = _link_area(a, lo, eps)

        def term(z: float, a: float = a, eps: float = eps) -> float:
            return z + a / float(_inertia_max(np.array(z), np.array(eps)))

        assert lo <= x <= 1.0
        xc = eps * (2.0 - eps)
        kind = "floor" if x == lo else "kink" if x == xc else "wall" if x < xc else "radius"
        where[kind] += 1
        best = term(x)
        grid = [z for z in np.linspace(lo, 1.0, 41) if z != x]
        near = [z for z in (x * (1 - 1e-6), x * (1 + 1e-6)) if lo <= z <= 1.0]
        for z in (*grid, *near):
            assert term(z) >= best * (1.0 - 1e-15), (a, lo, eps, x, z)
        far = [z for z in (x * (1 - 1e-3), x * (1 + 1e-3)) if lo <= z <= 1.0]
        assert any(term(z) > best for z in far)
    assert min(where.values()) > 20, where


def test_kink_and_stiffest_tubes() -> None:
    """A link whose best section is the tube of wall e at r2max (the kink: the wall branch
    still falls there, the r2max branch already rises) stays on it for a range of the
    multiplier; a chain whose stiffest tubes just meet its budget gets them (no step)."""
    eps = 0.1
    xc = eps * (2.0 - eps)
    hits = [a for a in np.geomspace(1e-4, 10.0, 400) if _link_area(a, eps * eps, eps) == xc]
    assert len(hits) > 5
    w, lo, e = np.array([1.0, 0.5]), np.array([0.01, 0.01]), np.array([0.1, 0.2])
    x, steps = _chain_areas(np.array([0.5, 0.5]), w, lo, e)  # sum W = 1: only x = 1
    assert steps == 0 and np.all(x == 1.0)
    x, steps = _chain_areas(np.array([1e-6, 1e-6]), w, lo, e)  # the floors suffice
    assert steps == 0 and np.all(x == lo)


def test_multiplier_meets_the_budget_with_equality() -> None:
    """The separable solve puts a deflection-governed chain exactly on its budget (the
    model's deflection to 1e-13), and every link's multiplier ``w_k I~^2 / (W_k I~')`` is
    the same (the KKT condition, measured with finite differences of _inertia_max)."""
    rng = np.random.default_rng(8)
    for _ in range(30):
        n = int(rng.integers(2, 7))
        eps = rng.uniform(0.03, 0.3, n)
        W = rng.uniform(0.02, 1.0, n)
        W *= rng.uniform(0.3, 0.9) / W.sum()  # the stiffest tubes leave 10-70 %
        w = rng.uniform(0.05, 1.0, n)
        x, steps = _chain_areas(W, w, eps * eps, eps)
        assert steps > 0
        inertia = _inertia_max(x, eps)
        assert float(np.sum(W / inertia)) == pytest.approx(1.0, abs=1e-13)
        assert float(np.sum(W / inertia)) <= 1.0
        h = 1e-6
        slope = (_inertia_max(x * (1 + h), eps) - _inertia_max(x * (1 - h), eps)) / (2 * h * x)
        lam = w * inertia**2 / (W * slope)
        inside = (x > eps * eps) & (np.abs(x - eps * (2 - eps)) > 1e-9)
        assert np.ptp(lam[inside]) <= 1e-6 * lam[inside].mean()


# --------------------------------------------------------------------------- shared


def _shared() -> tuple[list[ChainLink], list[Chain]]:
    """A hip shared by two legs, each with its own levers."""
    load = np.array([0.0, 2.0, 1.0, 0.0, 0.1, 0.0])
    links = [
        ChainLink("hip", limits(0.1), (load,)),
        ChainLink("a", limits(0.15), (load,), count=5),
        ChainLink("b", limits(0.15), (load * 1.5,), count=1),
    ]
    chains = [
        Chain(("hip", "a"), 4e-4, levers_m=(0.2, 0.0)),
        Chain(("hip", "b"), 5e-4, levers_m=(0.25, 0.0)),
    ]
    return links, chains


def test_shared_links_go_through_the_program(monkeypatch: pytest.MonkeyPatch) -> None:
    """Chains that share a link are solved by the program (built once here, and
    polished), meet both budgets (beam_check) and repeat bit for bit; the separable
    solve refuses them, naming the link and both chains."""
    built = []
    program = chain_links._program

    def spy(n: int, m: int):
        built.append((n, m))
        return program(n, m)

    monkeypatch.setattr(chain_links, "_program", spy)
    links, chains = _shared()
    sized = chain_tubes(links, chains, E, ALLOWED, KT)
    assert built == [(3, 2)] and sized.iterations >= 1
    check_design(sized, links, chains)
    tips = sized.tip_deflection_m
    assert max(t / c.budget_m for t, c in zip(tips, chains, strict=True)) == pytest.approx(1.0)
    other, other_chains = _shared()
    chain_tubes(other[:2], other_chains[:1], E, ALLOWED, KT, method="program")
    assert chain_tubes(links, chains, E, ALLOWED, KT) == sized
    with pytest.raises(ValueError, match=r"share no link: link 'hip' is in chains 'hip -> a'"):
        chain_tubes(links, chains, E, ALLOWED, KT, method="separable")
    with pytest.raises(ValueError, match="method must be one of auto, separable, program"):
        chain_tubes(links, chains, E, ALLOWED, KT, method="cvxpy")


def test_implied_chains_are_dropped() -> None:
    """Alike limbs give the same chain twice, and a chain whose every coefficient is at
    most another's is implied by it: both still take the separable solve (the program is
    not built), with the tubes of the one binding chain alone."""
    links, chains = _shared()
    legs = [Chain(("hip", "a"), 4e-4, (0.2, 0.0))] * 2
    looser = [*legs, Chain(("hip", "a"), 6e-4, (0.1, 0.0))]
    alone = chain_tubes(links[:2], legs[:1], E, ALLOWED, KT, method="separable")
    for group in (legs, looser):
        sized = chain_tubes(links[:2], group, E, ALLOWED, KT, method="separable")
        assert sized.tubes == alone.tubes
        assert sized.tip_deflection_m[0] == pytest.approx(4e-4, rel=1e-12)
        check_design(sized, links[:2], group)
    crossed = [Chain(("hip", "a"), 4e-4, (0.2, 0.0)), Chain(("hip", "a"), 6e-4, (0.1, 0.5))]
    with pytest.raises(ValueError, match="share no link"):  # neither implies the other
        chain_tubes(links[:2], crossed, E, ALLOWED, KT, method="separable")


# --------------------------------------------------------------------------- polish


def _scaled_sets(rng: np.random.Generator):
    """Scaled data of 1-3 chains of 1-4 links sharing none (``W`` coefficients leaving
    0.5-80 % of each budget to the stiffest tubes, ``w`` weights, floors ``lo``, 4 in 10
    above the thinnest rod, ``eps``) and their optimum by the separable solve."""
    m = int(rng.integers(1, 4))
    sizes = rng.integers(1, 5, m)
    n = int(sizes.sum())
    eps = rng.uniform(0.03, 0.5, n)
    lo = eps**2 * np.where(rng.uniform(size=n) < 0.4, 10 ** rng.uniform(0.0, 1.5, n), 1.0)
    lo = np.minimum(lo, 0.9)
    w = rng.uniform(0.05, 1.0, n)
    coeff = np.zeros((m, n))
    best = lo.copy()
    k = 0
    for j, size in enumerate(sizes):
        W = rng.uniform(0.01, 1.0, size)
        coeff[j, k : k + size] = W * rng.uniform(0.2, 0.995) / W.sum()
        best[k : k + size], _ = _chain_areas(
            coeff[j, k : k + size], w[k : k + size], lo[k : k + size], eps[k : k + size]
        )
        k += size
    return coeff, w, lo, eps, best


def test_polish_from_near_the_optimum() -> None:
    """From 400 starts 1e-7 to 3e-5 off the separable optimum (as the program's), a
    quarter of them with an interior link's floor just under it and the start on that
    floor, the polish reaches the optimum to 1e-10; the starts need every correction of
    the active set: links held at the floor or the kink that they are not on, links on
    them not held, chains slack that are at their budget."""
    rng = np.random.default_rng(1)
    needs = {"hold floor": 0, "free floor": 0, "hold kink": 0, "hold budget": 0}
    for _ in range(400):
        coeff, w, lo, eps, best = _scaled_sets(rng)
        start = np.clip(
            best * (1.0 + rng.normal(size=len(w)) * 10 ** rng.uniform(-7, -4.5)), lo, 1.0
        )
        inside = np.flatnonzero(best > lo * 1.01)
        if rng.uniform() < 0.25 and len(inside):
            k = int(rng.choice(inside))
            lo = lo.copy()
            lo[k] = start[k] = best[k] * (1.0 - 1e-7)  # the optimum is just off its floor
        got = _polish(start, lo, eps, coeff, w)
        assert got is not None
        np.testing.assert_allclose(got, best, rtol=1e-10, atol=0.0)
        xc = eps * (2.0 - eps)
        near = ACTIVE_RTOL
        needs["hold floor"] += bool(np.any((best == lo) & (start > lo * (1 + near))))
        needs["free floor"] += bool(np.any((best > lo) & (start <= lo * (1 + near))))
        needs["hold kink"] += bool(np.any((best == xc) & (np.abs(start - xc) > near * xc)))
        tight = coeff @ (1.0 / _inertia_max(best, eps)) >= 1.0 - 1e-12
        needs["hold budget"] += bool(
            np.any(tight & (coeff @ (1.0 / _inertia_max(start, eps)) < 1.0 - near))
        )
    assert min(needs.values()) >= 20, needs


def test_polish_lets_a_slack_budget_go() -> None:
    """A budget read as held that the optimum leaves (by 1e-7) gets a negative multiplier
    and is let go: a link h shared by chain A (h, a) and chain B (h alone, the looser)."""
    eps = np.array([0.1, 0.15, 0.2])
    lo = eps**2
    w = np.array([0.6, 1.0, 0.5])
    W_a = np.array([0.3, 0.4])
    best = lo.copy()
    best[:2], _ = _chain_areas(W_a, w[:2], lo[:2], eps[:2])  # b in no binding chain
    coeff = np.array([[W_a[0], W_a[1], 0.0], [0.0, 0.0, 0.0]])
    coeff[1, 0] = (1.0 - 1e-7) * float(_inertia_max(best[:1], eps[:1])[0])  # B: slack by 1e-7
    assert coeff[1, 0] > coeff[0, 0]  # B is not implied by A
    got = _polish(best.copy(), lo, eps, coeff, w)
    assert got is not None
    np.testing.assert_allclose(got, best, rtol=1e-12, atol=0.0)


def test_polish_that_cannot_settle_keeps_the_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """Newton's method given one step from a start 30 % off: None (the program's own
    solution is kept)."""
    coeff, w, lo, eps, best = _scaled_sets(np.random.default_rng(2))
    monkeypatch.setattr(chain_links, "POLISH_STEPS", 1)
    assert _polish(np.minimum(best * 1.3, 1.0), lo, eps, coeff, w) is None


def test_a_failed_polish_keeps_the_solution(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the polish the program's tubes are Clarabel's (areas ~1e-5 off, still
    within every budget and stress): the polish only refines."""
    links, chains = _shared()
    polished = chain_tubes(links, chains, E, ALLOWED, KT)
    monkeypatch.setattr(chain_links, "_polish", lambda *a: None)
    raw = chain_tubes(links, chains, E, ALLOWED, KT)
    check_design(raw, links, chains)
    assert raw.volume_m3 >= polished.volume_m3 * (1.0 - 1e-9)
    assert relative_gap(raw, polished) <= 1e-3


# --------------------------------------------------------------------------- imports


def _fresh(code: str, tmp_path) -> str:
    env = {**os.environ, "PYTHONPATH": str(REPO), "PARMOR_CACHE": str(tmp_path / "cache")}
    r = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout.strip().splitlines()[-1]


@pytest.mark.parametrize(
    "request_args",
    [
        ["pick-and-place", "--param", "object_shape=cylinder"],
        ["rough-terrain-walking"],
    ],
    ids=["arm", "hexapod"],
)
def test_a_design_does_not_import_cvxpy(request_args: list[str], tmp_path) -> None:
    """``parmor design ... --no-verify`` in a fresh interpreter sizes its chains (the arm's
    L1 -> L2 -> L3, the hexapod's coxa -> femur -> tibia) without importing cvxpy."""
    argv = ["design", *request_args, "--no-verify", "--no-input"]
    code = (
        "import io, sys\n"
        "from synth.commands.cli import main\n"
        f"code = main({argv!r}, out=io.StringIO(), err=sys.stderr)\n"
        "assert code == 0, code\n"
        "print('cvxpy' in sys.modules)\n"
    )
    assert _fresh(code, tmp_path) == "False"


def test_chains_sharing_a_link_import_cvxpy(tmp_path) -> None:
    """The control: chain_tubes on chains that share a link imports cvxpy."""
    code = (
        "import sys\n"
        "from tests.synth.sizing.test_chain_separable import _shared\n"
        "from synth.sizing.chain_links import chain_tubes\n"
        "assert 'cvxpy' not in sys.modules\n"
        "chain_tubes(*_shared(), 2.3e9, 20e6, 1.8)\n"
        "print('cvxpy' in sys.modules)\n"
    )
    assert _fresh(code, tmp_path) == "True"


def test_identical_inputs_give_identical_bits() -> None:
    """The separable solve keeps no state: the same chains sized before and after others
    give equal tubes, shares and deflections."""
    rng = np.random.default_rng(77)
    sets = [random_chain_set(rng) for _ in range(6)]
    first = [chain_tubes(lk, ch, E, ALLOWED, KT) for lk, ch in sets]
    again = [chain_tubes(lk, ch, E, ALLOWED, KT) for lk, ch in reversed(sets)][::-1]
    assert again == first
    assert [s.iterations for s in first] == [s.iterations for s in again]
