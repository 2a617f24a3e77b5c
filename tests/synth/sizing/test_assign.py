"""Actuator assignment per unit (synth.sizing.assign): the same answers as the ASP encoding
(asp/actuators.lp) solved by clingo, dominance, and exact counts against brute force."""

from __future__ import annotations

import itertools
import random
import sys
from pathlib import Path

import clingo
import numpy as np
import pytest

from adron.catalog import catalog_facts, parse_catalog
from synth.reasoning.solver import encoding_dir
from synth.sizing.assign import (
    ActuatorAssigner,
    Coupled,
    JointSlot,
    Points,
    count_bounds,
    count_by_intervals,
    count_feasible,
    distinct_points,
    dominated,
    feasible_mask,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "bench"))
from synthetic_catalog import synthetic_catalog_text  # noqa: E402


def legs(n: int) -> list[JointSlot]:
    return [
        JointSlot(f"leg{i}_{p}", f"leg_{p}", "PositionServomotor")
        for i in range(n)
        for p in ("coxa", "femur", "tibia")
    ]


def reference(kb, facts: str, joints, capable, symmetric: bool, objective=("mass", "cost")):
    """Every assignment of asp/actuators.lp with its cost, best first (what the clingo
    assigner before issue 12 ranked: cost vector, then models in joint order)."""
    prio = {name: len(objective) - i for i, name in enumerate(objective)}
    ctl = clingo.Control(
        [
            "--models=0",
            "--opt-mode=ignore",
            f"-c mass_priority={prio['mass']}",
            f"-c cost_priority={prio['cost']}",
        ]
    )
    text = [facts, 'robot("HexapodRobot").', "other_active(2)."]
    text += [f'joint("{j.name}","{j.group}","{j.module_class}").' for j in joints]
    text += [f'capable("{j}","{m}").' for j, ms in capable.items() for m in ms]
    text += ["symmetric." if symmetric else ""]
    text += ['isa("PositionServomotor","PositionServomotor").']
    ctl.add("base", [], "\n".join(text))
    src = (encoding_dir() / "actuators.lp").read_text(encoding="utf-8")
    src = src.replace('#include "serving.lp".', (encoding_dir() / "serving.lp").read_text())
    src = src.replace("#external capable(J, M) : serves(M, J).", "")
    src = src.replace("#external symmetric.", "")
    ctl.add("base", [], src)
    ctl.ground([("base", [])])
    weight = {}
    for atom in ctl.symbolic_atoms.by_signature("actuator", 7):
        m, _, mg, cents = atom.symbol.arguments[:4]
        weight[m.string] = (mg.number, cents.number)
    first = 0 if objective[0] == "mass" else 1
    found = []
    with ctl.solve(yield_=True) as h:
        for m in h:
            got = {s.arguments[0].string: s.arguments[1].string for s in m.symbols(shown=True)}
            models = tuple((j.name, got[j.name]) for j in joints)
            cost = tuple(
                sum(weight[x][i] for _, x in models) for i in (first, 1 - first)
            )  # the #minimize statements' sums, highest priority first
            found.append((cost, models))
    return sorted(found)


def random_capable(rng: random.Random, joints, models) -> dict[str, tuple[str, ...]]:
    return {j.name: tuple(m for m in models if rng.random() < 0.7) for j in joints}


@pytest.mark.parametrize("n", [6, 8, 10])
def test_best_ranked_and_count_equal_the_encoding(kb, n) -> None:
    """On the shipped catalog (n = 6) and small synthetic ones, with random capability:
    the best, the ranked list and the count are those of asp/actuators.lp by clingo."""
    cat = parse_catalog(synthetic_catalog_text(n, seed=n), f"synthetic{n}")
    facts = catalog_facts(cat)
    joints = legs(2)
    pos = sorted(a.model for a in cat.actuators_of("PositionServomotor"))
    rng = random.Random(n)
    for objective in (("mass", "cost"), ("cost", "mass")):
        a = ActuatorAssigner(kb, facts, "HexapodRobot", joints, 2, objective)
        for _ in range(3):
            capable = random_capable(rng, joints, pos)
            for symmetric in (True, False):
                ref = reference(kb, facts, joints, capable, symmetric, objective)
                assert a.count(capable, symmetric) == len(ref)
                ranked = a.ranked(capable, symmetric, 7)
                assert [(r.cost, r.models) for r in ranked] == ref[:7]
                best = a.best(capable, symmetric)
                if ref:
                    assert (best.cost, best.models) == ref[0]
                else:
                    assert best is None


def test_dominated_models_are_never_best_and_ties_keep_the_first_name() -> None:
    torque = {"A": 1.0, "B": 1.0, "C": 2.0, "D": 0.5, "E": 1.0}
    speed = {"A": 5.0, "B": 5.0, "C": 4.0, "D": 9.0, "E": 5.0}
    weights = {"A": (10, 10), "B": (10, 10), "C": (20, 5), "D": (30, 30), "E": (10, 11)}
    drop = dominated(sorted(torque), torque, speed, weights)
    # B ties A and comes later by name; E is dearer than A; C is stronger, D faster
    assert drop == {"B", "E"}
    # a dominator must be among the allowed ones (serving every joint of the group)
    assert dominated(sorted(torque), torque, speed, weights, among={"C", "D"}) == set()


def brute_count(p: Coupled) -> int:
    """Plain Python: every assignment, the same arithmetic as _TorqueModel.feasible."""
    n = 0
    for choice in itertools.product(*(o.tolist() for o in p.options)):
        masses = [-np.inf] * len(p.base)
        for u, g in enumerate(p.group):
            masses[g] = max(masses[g], float(p.mass[choice[u]]))
        ok = True
        for u, pts in enumerate(p.points):
            a = choice[u]
            tw = []
            for k in range(len(pts.C)):
                lin = float(pts.C[k])
                for g in range(len(p.base)):
                    lin = lin + (masses[g] - float(p.base[g])) * float(pts.S[k, g])
                tw.append((abs(lin) * float(pts.F[k]), float(pts.W[k])))
            tw += [(float(t), float(v)) for t, v in zip(pts.T, pts.V, strict=True)]
            for t, w in tw:
                speed = max(0.0, float(p.w0[a]) * (1.0 - t / float(p.stall[a])))
                if not (float(p.usable[a]) >= t and speed >= w):
                    ok = False
        n += ok
    return n


def random_problem(seed: int, units: int, shared: bool = False) -> Coupled:
    rng = np.random.default_rng(seed)
    models = 14
    stall = rng.uniform(0.5, 2.0, models)
    groups = tuple(range(units)) if not shared else tuple(u // 2 for u in range(units))
    g = max(groups) + 1
    points = []
    for _ in range(units):
        p, q = int(rng.integers(1, 6)), int(rng.integers(0, 2))
        pts = Points(
            rng.uniform(-0.8, 0.8, p),
            rng.uniform(-4, 4, (p, g)) * (rng.random((p, g)) < 0.7),
            np.full(p, 1 - 1e-12),
            rng.uniform(0, 3, p),
            rng.uniform(0, 0.3, q),
            rng.uniform(0, 2, q),
        )
        points.append(distinct_points(pts))
    return Coupled(
        group=groups,
        base=rng.uniform(0.03, 0.09, g),
        options=tuple(
            np.sort(rng.choice(models, int(rng.integers(1, 7)), replace=False))
            for _ in range(units)
        ),
        mass=rng.uniform(0.03, 0.1, models),
        stall=stall,
        usable=stall / 1.5,
        w0=rng.uniform(3, 12, models),
        points=tuple(points),
    )


@pytest.mark.parametrize("seed", range(12))
def test_count_is_exact_against_brute_force(seed) -> None:
    """Random seeded problems (2-4 units, up to 6 models each): the branch and bound with
    tiny leaves (so that it bounds and splits) and with the default ones, and the plain
    check of every assignment (groups shared by two units), equal brute force."""
    p = random_problem(seed, 2 + seed % 3)
    want = brute_count(p)
    assert count_feasible(p, leaf=1, max_boxes=10**6, max_checked=10**6, intervals=False) == want
    assert count_feasible(p) == want
    shared = random_problem(seed, 4, shared=True)
    assert count_feasible(shared) == brute_count(shared)


def test_count_gives_up_rather_than_guess() -> None:
    """Over its budget the count is None (the caller then reports an upper bound, marked
    not exact), never a wrong number."""
    gave_up = 0
    for seed in range(12):
        p = random_problem(seed, 2 + seed % 3)
        got = count_feasible(p, leaf=1, max_boxes=2, intervals=False)
        gave_up += got is None
        assert got is None or got == brute_count(p)
    assert gave_up > 0


def test_bounds_are_printed_as_bounds() -> None:
    """enumerate's text gives the bounds when the count is not exact (count_exact false)."""
    from synth.commands.cli import _Sizer

    rec = {
        "structure": {"mass_kg": 1.0, "cost": 2.0},
        "assignments": {
            "count": 12,
            "count_exact": True,
            "count_capable": 40,
            "symmetric": True,
            "ranked": [],
        },
    }
    assert "assignments: 12 feasible of 40 capable" in _Sizer.text(rec, "")
    rec["assignments"]["count_exact"] = False
    rec["assignments"]["count_lower"] = 5
    assert "assignments: between 5 and 12 feasible of 40 capable" in _Sizer.text(rec, "")
    # counts past 10^9 in three digits, bounds rounded outwards
    rec["assignments"].update(
        count_lower=125366914606500452095,
        count=2277560092257815953019,
        count_capable=3055317477523290000000,
    )
    text = _Sizer.text(rec, "")
    assert "between 1.25e+20 and 2.28e+21 feasible of about 3.06e+21 capable" in text
    rec["assignments"].update(count_lower=1999999999, count=1000000001)
    assert "between 1.99e+09 and 1.01e+09" in _Sizer.text(rec, "")


@pytest.mark.parametrize("boxes", [1, 2, 3, 5, 8])
def test_bounds_bracket_the_count_at_any_budget(boxes) -> None:
    """Stopped after any number of boxes, the bounds hold the brute-force count (and meet
    it when the budget suffices); a bound shifted by one misses it in some problem (the
    check can fail)."""
    tight = missed = 0
    for seed in range(16):
        p = random_problem(seed, 2 + seed % 3)
        want = brute_count(p)
        low, high = count_bounds(p, leaf=1, max_boxes=boxes, intervals=False)
        assert low <= want <= high
        tight += low == high
        missed += not (low + 1 <= want <= high) or not (low <= want <= high - 1)
        full = count_bounds(p, leaf=1, max_boxes=10**6, max_checked=10**6, intervals=False)
        assert full == (want, want)
    assert missed > 0
    if boxes >= 8:
        assert tight > 0


@pytest.mark.parametrize("units", [2, 3, 4])
def test_intervals_count_equals_brute_force(units) -> None:
    """The count by intervals (the masses of the two largest units bound each other to
    intervals) equals brute force on random problems, mirrored points and fixed points
    included."""
    for seed in range(40):
        p = random_problem(seed, units)
        assert count_by_intervals(p) == brute_count(p)
    assert count_by_intervals(random_problem(0, 4, shared=True)) is None  # groups shared


def test_intervals_decide_a_pair_on_a_bound_one_by_one() -> None:
    """A model whose usable torque is exactly the torque one assignment asks of it: the
    assignment is feasible; one ulp less, it is not. The intervals' rounding would decide
    either way; the pair is checked one by one and the count follows brute force."""
    from dataclasses import replace

    for seed in range(6):
        p = random_problem(seed, 3)
        choice = np.array([[o[0] for o in p.options]])
        pts = p.points[0]
        if not len(pts.C):
            continue
        d = p.mass[choice[0]] - p.base
        lin = pts.C.copy()
        for g in range(len(p.base)):
            lin = lin + d[g] * pts.S[:, g]
        tt = float((np.abs(lin) * pts.F).max())
        m = choice[0, 0]
        counts = []
        for usable in (tt, np.nextafter(tt, 0.0)):
            u = p.usable.copy()
            u[m] = usable
            w0 = p.w0.copy()
            w0[m] = 1e9  # speed never binds for this model
            q = replace(p, usable=u, w0=w0)
            assert count_by_intervals(q) == brute_count(q)
            counts.append(bool(feasible_mask(q, choice)[0]))
        assert counts[1] is False


def test_intervals_leave_many_combinations_to_the_branch_and_bound() -> None:
    """Where the other units' combinations times the units pass INTERVAL_STEPS (a
    humanoid's 9 units), the count by intervals declines (None) and count_bounds still
    brackets the brute-force count."""
    from synth.sizing.assign import INTERVAL_STEPS

    p = random_problem(0, 9)  # 17,280 assignments
    sizes = sorted(len(o) for o in p.options)
    combos = int(np.prod(sizes[:-2]))
    assert combos * 9 > INTERVAL_STEPS
    assert count_by_intervals(p) is None
    low, high = count_bounds(p)
    want = brute_count(p)
    assert low <= want <= high
