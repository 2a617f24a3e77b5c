"""The multiped planner's shortcuts give what the plain computations give, to the bit:
the batched stride search against the one-by-one bisection, and the memos of strides,
timings and plans against fresh computations (gaits/hexapod.py); a trajectory's CSV."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaits import hexapod
from gaits.hexapod import (
    COXA_SWING,
    LEG_CLEARANCE,
    _bisect_stride,
    _segment_distances,
    _segment_gaps,
    _segment_ok,
    legs_of,
)
from kinematics.templates import TemplateParams, build, default_lengths


def _reference_stride(legs, travel, height, step, coxa_swing=COXA_SWING) -> float:
    """``max_stride`` as it was: one test per halving, leg by leg."""

    def ok(s: float) -> bool:
        segs = {}
        for leg in legs:
            n = leg.neutral[:2]
            half = 0.5 * s * np.asarray(travel[leg.name], dtype=float)
            pts = n + np.linspace(-1.0, 1.0, 21)[:, None] * half
            if not _segment_ok(leg, pts, height, step, coxa_swing):
                return False
            segs[leg.name] = (n - half, n + half)
        first, second = np.triu_indices(len(segs), 1)
        ends = np.array([segs[n] for n in segs])
        return bool(np.all(_segment_distances(ends[first], ends[second]) >= LEG_CLEARANCE))

    if not ok(0.0):
        return 0.0
    lo, hi = 0.0, 4 * max(leg.coxa + leg.femur + leg.tibia for leg in legs)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def _legs(robot_type: str, obstacle: float):
    """Legs of a multiped sized for an obstacle height (m), as ``Multipeds.size`` does."""
    d = dict(default_lengths(robot_type))
    femur = (obstacle + 0.01) / math.sin(math.pi / 4)
    d.update(femur=femur, tibia=max(obstacle + 0.03, 1.25 * femur))
    return legs_of(build(robot_type, TemplateParams(lengths=d)))


CASES = [
    (rt, h, direction, step)
    for rt in ("HexapodRobot", "QuadrupedRobot")
    for h in (0.01, 0.03, 0.05)
    for direction in (0.0, math.pi / 2, 0.7, None)  # None: the turn's travel
    for step in (0.02, 0.06)
]


@pytest.mark.parametrize(("robot_type", "obstacle", "direction", "step"), CASES)
def test_batched_stride_search_is_the_bisection_to_the_bit(
    robot_type, obstacle, direction, step
) -> None:
    legs = _legs(robot_type, obstacle)
    if direction is None:
        reach = max(float(np.hypot(*leg.neutral[:2])) for leg in legs)
        travel = {leg.name: np.array([-leg.neutral[1], leg.neutral[0]]) / reach for leg in legs}
    else:
        u = np.array([math.cos(direction), math.sin(direction)])
        travel = {leg.name: u for leg in legs}
    height = max(float(-leg.neutral[2]) for leg in legs) + 0.01
    want = _reference_stride(legs, travel, height, step)
    assert _bisect_stride(legs, travel, height, step, COXA_SWING) == want
    hexapod._STRIDES.clear()
    assert hexapod.max_stride(legs, travel, height, step) == want
    assert hexapod.max_stride(legs, travel, height, step) == want  # remembered


def test_a_stride_no_leg_can_take_is_zero() -> None:
    legs = _legs("HexapodRobot", 0.03)
    travel = {leg.name: np.array([1.0, 0.0]) for leg in legs}
    assert _bisect_stride(legs, travel, 5.0, 0.02, COXA_SWING) == 0.0  # feet far below reach


def test_exact_segment_gaps_bound_the_sampled_distances() -> None:
    rng = np.random.default_rng(3)
    a = rng.uniform(-0.1, 0.1, (2000, 2, 2))
    b = rng.uniform(-0.1, 0.1, (2000, 2, 2))
    b[:10] = a[:10]  # identical segments
    b[10:20, 1] = b[10:20, 0]  # points
    gaps, sampled = _segment_gaps(a, b), _segment_distances(a, b)
    assert np.all(gaps <= sampled + 1e-15)
    assert np.all(sampled - gaps <= 0.2 / 40)  # within a sample step of the exact one
    crossing = np.array([[[0.0, -1.0], [0.0, 1.0]]]), np.array([[[-1.0, 0.0], [1.0, 0.0]]])
    assert _segment_gaps(*crossing)[0] == 0.0


def test_trajectory_csv_writes_each_number_as_the_fixed_point_format_does() -> None:
    from gaits.base import Trajectory

    t = np.linspace(0.0, 1.0, 5)
    q = np.array(
        [[-0.0, 1e300], [np.nan, -np.inf], [1 / 3, -2.5e-7], [0.0000005, 123456.7890125], [1, 2]]
    )
    got = Trajectory("x", t, ("a", "b"), q, np.zeros_like(q)).csv()
    want = "t,a,b\n" + "".join(
        ",".join(f"{x:.6f}" for x in (ti, *row)) + "\n" for ti, row in zip(t, q, strict=True)
    )
    assert got == want


def _hexapod(**kw):
    import dataclasses

    from gaits.base import DesignGeometry

    tmpl = build("HexapodRobot")
    g = DesignGeometry(
        robot_type="HexapodRobot",
        template="HexapodRobot",
        lengths=dict(tmpl.lengths),
        modules=18,
        wheel_radius=0.03,
        params={"obstacle_height": 0.03, "speed": 0.05},
        abilities=("walking",),
        joint_speed={j.name: 6.0 for j in tmpl.model.joints if j.kind == "revolute"},
    )
    return dataclasses.replace(g, **kw)


def test_remembered_plans_are_the_fresh_ones_and_read_only() -> None:
    from gaits import legged
    from gaits.legged import LeggedController

    def fresh(name: str):
        hexapod._STRIDES.clear()
        hexapod._TIMINGS.clear()
        legged._PLANS.clear()
        return LeggedController(_hexapod()).run(name)

    for name in ("walking", "turning"):
        a = fresh(name)
        b = LeggedController(_hexapod()).run(name)  # its plan remembered: shared, read-only
        assert b.positions is a.positions
        with pytest.raises(ValueError):
            b.info["body_path"][0, 0] = 1.0
        c = fresh(name)  # planned again from nothing: the same, to the bit
        for x, y in ((a.times, c.times), (a.positions, c.positions), (a.velocities, c.velocities)):
            assert x.tobytes() == y.tobytes()
        assert a.info["stability_margin_m"].tobytes() == c.info["stability_margin_m"].tobytes()


def test_plans_are_shared_across_what_a_controller_does_not_read() -> None:
    from gaits import controller_for

    a = controller_for(_hexapod()).run("walking")
    assert controller_for(_hexapod(mass_kg=2.0, joint_torque={"x": 1.0})).run("walking") is a
    slower = {k: 3.0 for k in _hexapod().joint_speed}
    assert controller_for(_hexapod(joint_speed=slower)).run("walking") is not a


def _reference_ramp(swings, t0: float, t1: float, budget: float) -> float:
    """``_ramp_for`` as it was: the envelope and its progress rebuilt for every ramp."""
    grid = np.linspace(t0, t1, 4001)

    def worst(ramp: float) -> float:
        prog = hexapod._progress(grid, hexapod._envelope(grid, t0, t1, ramp))
        w = 0.0
        for iv in swings.values():
            w = max(
                w,
                float(np.interp(iv[0, 0], grid, prog)),
                float(prog[-1] - np.interp(iv[-1, 1], grid, prog)),
            )
        return w

    lo, hi = 0.0, 0.5 * (t1 - t0)
    if worst(lo) <= budget:
        return lo
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if worst(mid) <= budget else (mid, hi)
    return hi


@pytest.mark.parametrize("robot_type", ["HexapodRobot", "QuadrupedRobot"])
def test_the_ramp_search_is_the_one_by_one_search_to_the_bit(robot_type) -> None:
    legs = _legs(robot_type, 0.03)
    for gait in hexapod.GAITS[len(legs)]:
        for cycles, period, lead, share in (
            (1, 0.7, 0.0, 0.5),
            (4, 1.3, 0.3, 0.5),
            (2, 2.0, 0.5, 0.2),
        ):
            pattern = hexapod.gait_pattern(gait, legs)
            t_start = 1.0 + lead
            sw = hexapod._swings(pattern, legs, cycles, t_start, period)
            t_stop = max(float(iv[-1, 1]) for iv in sw.values())
            budget = share * pattern.duty * period
            want = _reference_ramp(sw, t_start, t_stop, budget)
            assert hexapod._ramp_for(sw, t_start, t_stop, budget) == want


def _sway_plan():
    tmpl = build("QuadrupedRobot")
    legs = legs_of(tmpl)
    pattern = hexapod.gait_pattern("crawl", legs)
    h = hexapod.standing_height(legs)
    return hexapod.plan_gait(tmpl, legs, pattern, 1, 2.0, (0.02, 0.0, 0.0), 0.03, h, sway=True)


def test_sway_solutions_are_kept_on_disk_and_read_back_to_the_bit(monkeypatch, tmp_path):
    monkeypatch.setenv("PARMOR_CACHE", str(tmp_path))
    first = _sway_plan()
    files = sorted(tmp_path.glob("sway-*.npy"))
    assert files  # solved, then written
    assert np.any(first.sway != 0)

    def unsolved(*args, **kwargs):
        raise AssertionError("solved again")

    monkeypatch.setattr(hexapod, "_sway_lp", unsolved)
    again = _sway_plan()  # read back
    assert again.sway.tobytes() == first.sway.tobytes()
    assert again.q.tobytes() == first.q.tobytes()
    monkeypatch.undo()
    monkeypatch.setenv("PARMOR_CACHE", str(tmp_path))
    for f in files:
        f.write_bytes(b"not an array")  # unreadable: solved again, the same
    assert _sway_plan().sway.tobytes() == first.sway.tobytes()
    monkeypatch.setenv("PARMOR_CACHE", "")  # no cache: solved, nothing written
    for f in tmp_path.glob("sway-*.npy"):
        f.unlink()
    assert _sway_plan().sway.tobytes() == first.sway.tobytes()
    assert not list(tmp_path.glob("sway-*.npy"))
