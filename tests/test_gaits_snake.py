"""Snake gaits: the wave generators of the paper's eqs. 7-9, the gait parameter sets, and
(issue 5) the rolling and rectilinear gaits moving the designed snakes in MuJoCo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from adron.catalog import load_catalog
from export.bundle import bundle_files, write_bundle
from export.record import design_record
from export.simulate import load_bundle_model, simulate
from gaits.base import DesignGeometry, Trajectory
from gaits.snake import (
    GAITS,
    SPEED_SHARE,
    SnakeController,
    WaveParams,
    gait_params,
    joint_waves,
    wave_amplitude,
    wave_phase_step,
)
from synth.conceptual import Design, Request
from synth.structure import design_structure

ALL = tuple(GAITS)


def _geometry(modules: int, abilities: tuple[str, ...] = ALL, speed: float = 6.0):
    """A synthetic snake design: template defaults, ``speed`` rad/s modules."""
    joints = [f"joint_{i}" for i in range(1, modules + 1)]
    return DesignGeometry(
        robot_type="SnakeRobot",
        template="SnakeRobot",
        lengths={},
        modules=modules,
        wheel_radius=0.03,
        params={},
        abilities=abilities,
        joint_speed=dict.fromkeys(joints, speed),
    )


# --- eqs. 7-9 ------------------------------------------------------------------------------


def test_eqs_8_9() -> None:
    assert wave_amplitude(0.3, 1, 8) == pytest.approx(2 * 0.3 * math.sin(math.pi / 4))
    assert wave_phase_step(1, 8) == pytest.approx(math.pi / 2)
    assert wave_phase_step(2, 6) == pytest.approx(4 * math.pi / 3)
    with pytest.raises(ValueError):
        wave_amplitude(0.3, 1, 0)


def test_joint_waves_are_eq_7_on_alternating_modules() -> None:
    p = WaveParams(0.4, 0.3, 0.7, -0.5, 1.1, 0.05, -0.2)
    phase = np.linspace(0, 7, 23)
    q = joint_waves(phase, 7, p)
    for i in range(1, 5):  # vertical modules: joint_1, 3, 5, 7
        expect = p.o_v + p.a_v * np.sin(phase + (i - 1) * p.dphi_v)
        assert np.allclose(q[:, 2 * i - 2], expect)
    for i in range(1, 4):  # horizontal modules: joint_2, 4, 6
        expect = p.o_h + p.a_h * np.sin(phase + (i - 1) * p.dphi_h + p.dphi_vh)
        assert np.allclose(q[:, 2 * i - 1], expect)
    assert np.allclose(joint_waves(phase, 7, p, 0.0), 0)


def test_gait_parameter_sets() -> None:
    deg = math.radians
    for m in (3, 5, 8, 14):
        roll = gait_params("rolling", m)
        assert roll.a_v == roll.a_h and roll.dphi_v == roll.dphi_h == 0
        assert abs(roll.dphi_vh) == pytest.approx(math.pi / 2)
        rect = gait_params("rectilinear", m)
        assert rect.a_h == 0 and abs(rect.dphi_v) == pytest.approx(deg(120))
        side = gait_params("sidewinding", m)
        assert side.dphi_v == side.dphi_h != 0 and abs(side.dphi_vh) == pytest.approx(deg(90))
        assert side.a_v < side.a_h
        rot = gait_params("rotating", m)  # different k: twice the phase step vertically
        assert rot.dphi_v == pytest.approx(2 * rot.dphi_h)
        circ = gait_params("circular-path", m, bend=0.3)
        assert circ.o_h == 0.3 and circ.a_v == rect.a_v
        for g in GAITS:
            assert gait_params(g, m).peak() <= math.pi / 2
            assert gait_params(g, m, -1).peak() == gait_params(g, m, 1).peak()
    # the rolling arc's bend is shared by the joints: bigger amplitudes on short snakes
    assert gait_params("rolling", 3).a_v > gait_params("rolling", 8).a_v >= deg(30)
    assert gait_params("rectilinear", 5, -1).dphi_v == -gait_params("rectilinear", 5).dphi_v
    with pytest.raises(ValueError, match="unknown gait"):
        gait_params("slithering", 8)
    with pytest.raises(ValueError, match="direction"):
        gait_params("rolling", 8, 0)
    with pytest.raises(ValueError, match="bend"):
        gait_params("circular-path", 14, bend=1.5)


# --- the controller -----------------------------------------------------------------------


@pytest.mark.parametrize(
    "modules, abilities, expect",
    [
        (3, ("rolling",), ("rolling",)),
        (5, ("rectilinear", "rolling"), ("rolling", "rectilinear")),
        (14, ALL + ("line-tracking",), ALL),
    ],
)
def test_behaviours_are_the_designs_gaits(modules, abilities, expect) -> None:
    c = SnakeController(_geometry(modules, abilities))
    assert tuple(c.behaviors) == expect
    for spec in c.behaviors.values():
        assert {p.name for p in spec.params} >= {"frequency", "cycles", "direction"}


@pytest.mark.parametrize("gait", ALL)
def test_trajectories_are_smooth_and_within_limits(gait: str) -> None:
    c = SnakeController(_geometry(14, speed=5.0))
    traj = c.run(gait, cycles=4)
    f = traj.info["frequency_hz"]
    assert traj.duration == pytest.approx(4 / f)
    assert traj.joints == tuple(f"joint_{i}" for i in range(1, 15))
    # starts and ends straight and at rest
    assert np.allclose(traj.positions[[0, -1]], 0) and np.allclose(traj.velocities[[0, -1]], 0)
    assert np.abs(traj.positions).max() <= math.pi / 2
    assert np.abs(traj.velocities).max() <= c.max_speed * (1 + 1e-9)
    # the velocities are the positions' derivative (central differences)
    t, q, v = traj.times, traj.positions, traj.velocities
    numeric = (q[2:] - q[:-2]) / (t[2:] - t[:-2])[:, None]
    assert np.abs(numeric - v[1:-1]).max() < 0.01 * np.abs(v).max()
    # in the middle cycles the waves are eq. 7 at full amplitude
    mid = np.argmin(np.abs(t - 2 / f))
    expect = joint_waves(np.array([2 * math.pi * f * t[mid]]), 14, traj.info["waves"])
    assert np.allclose(q[mid], expect[0])


def test_bad_parameters_raise() -> None:
    c = SnakeController(_geometry(5, ("rolling", "rectilinear"), speed=3.0))
    top = c.max_frequency("rectilinear")
    c.run("rectilinear", frequency=top)
    with pytest.raises(ValueError, match=f"at most {top:.3g} Hz"):
        c.run("rectilinear", frequency=1.05 * top)
    with pytest.raises(ValueError, match="direction"):
        c.run("rolling", direction=0)
    with pytest.raises(ValueError, match="outside"):
        c.run("rolling", cycles=1)
    with pytest.raises(ValueError, match="no behaviour 'sidewinding'"):
        c.run("sidewinding")
    with pytest.raises(ValueError, match="no parameter 'bend'"):
        c.run("rolling", bend=0.2)
    with pytest.raises(ValueError, match="no speed"):
        SnakeController(_geometry(3, speed=0.0))


def test_info_declares_what_each_gait_promises() -> None:
    c = SnakeController(_geometry(14))
    for gait in ALL:
        for direction in (1, -1):
            info = c.run(gait, direction=direction, cycles=2).info
            assert info["locomotion"] == "snake"
            assert info["body_length_m"] == pytest.approx(14 * 0.06)
            if gait == "rotating":
                assert info["motion"] == "rotate" and info["turn"] == direction
                assert "direction" not in info
            else:
                assert info["motion"] == "crawl"
                assert np.hypot(*info["direction"]) == pytest.approx(1.0)


def test_default_frequency_keeps_torque_for_the_load() -> None:
    """At the default frequency no joint runs faster than SPEED_SHARE of its no-load
    speed; slower modules get a slower wave."""
    fast, slow = SnakeController(_geometry(8, speed=10.0)), SnakeController(_geometry(8, speed=3.0))
    for gait in ("rolling", "rectilinear", "rotating"):
        traj = slow.run(gait)
        assert np.abs(traj.velocities).max() <= SPEED_SHARE * 3.0 * (1 + 1e-2)
        assert traj.info["frequency_hz"] < fast.run(gait).info["frequency_hz"]


# --- MuJoCo: every gait of the paper's snakes moves as its info promises --------------------

#: The paper's snakes (section 4.3.2): the gaits asked for; each lists every gait its M allows.
PAPER = {3: ("rolling",), 5: ("rectilinear",), 6: ("sidewinding",), 8: ("rotating",)}
PAPER[14] = ("rolling", "circular-path")
#: Issue 8's thresholds: crawl >= 0.25 body length, rotate >= 45 degrees per 10 s; at most
#: 5 % of the samples with an actuator at its torque limit.
LEAST_CRAWL, LEAST_TURN, MOST_SATURATED = 0.25, math.radians(45), 0.05
#: Known shortfalls (measured, default parameters, payload 0).
SHORT = {
    (5, "rectilinear"): "0.17 body length per 10 s: three vertical modules make a short stride",
    (8, "rectilinear"): "6 % of the samples at the torque limit (MG996R lifting the humps)",
    (6, "sidewinding"): "turns instead (1.5-3.5 rad in a run): its heavy head (battery and "
    "main module) takes the lateral shift's thrust off-centre",
}


@pytest.fixture(scope="module")
def snakes(kb, designer, tmp_path_factory):
    """M -> (controller, model) of the paper's snakes, designed with default parameters."""
    catalog = load_catalog()
    out = {}
    for m, asked in PAPER.items():
        cand = designer.step(Request(abilities=asked)).chosen
        s = design_structure(kb, cand, catalog, {})
        rec = design_record(
            Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
        )
        folder = tmp_path_factory.mktemp("snake") / f"m{rec['dof']}"
        write_bundle(folder, bundle_files(rec, s, catalog))
        c = SnakeController(DesignGeometry.from_record(rec))
        assert c.modules == m
        out[m] = (c, load_bundle_model(folder))
    return out


def _yaws(root: np.ndarray) -> np.ndarray:
    w, x, y, z = root[:, 3:7].T
    return np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def judge(c: SnakeController, model, gait: str, **params) -> tuple[float, float]:
    """(progress per 10 s: body lengths along info["direction"], or rad in info["turn"]'s
    sense; share of samples with an actuator at its torque limit) of a run of ``gait``."""
    traj = c.run(gait, **params)
    r = simulate(model, traj, can_fall=False)
    limit = np.abs(model.actuator_forcerange).max(axis=1)
    saturated = float(np.mean(np.any(np.abs(r.series["force"]) >= limit * (1 - 1e-3), axis=1)))
    root = r.series["root"]
    if traj.info["motion"] == "rotate":
        yaw = _yaws(root)
        done = float(yaw[-1] - yaw[0]) * traj.info["turn"]
    else:
        moved = root[-1, :2] - root[0, :2]
        done = float(moved @ np.asarray(traj.info["direction"])) / traj.info["body_length_m"]
    return done * 10.0 / traj.duration, saturated


@pytest.mark.parametrize(
    "modules, gait",
    [
        pytest.param(m, g, marks=pytest.mark.xfail(strict=True, reason=SHORT.get((m, g), "")))
        if (m, g) in SHORT
        else (m, g)
        for m in PAPER
        for g in GAITS[: {3: 1, 5: 2, 6: 3, 8: 4, 14: 5}[m]]
    ],
)
def test_every_listed_gait_of_the_paper_snakes_moves(snakes, modules: int, gait: str) -> None:
    c, model = snakes[modules]
    assert gait in c.gaits
    done, saturated = judge(c, model, gait)
    assert saturated <= MOST_SATURATED
    assert done >= (LEAST_TURN if gait == "rotating" else LEAST_CRAWL)


@pytest.mark.parametrize("modules, gait", [(3, "rolling"), (8, "rotating"), (14, "circular-path")])
def test_the_other_sense_goes_the_other_way(snakes, modules: int, gait: str) -> None:
    c, model = snakes[modules]
    done, saturated = judge(c, model, gait, direction=-1)
    assert saturated <= MOST_SATURATED
    assert done >= (LEAST_TURN if gait == "rotating" else LEAST_CRAWL)


def test_judge_fails_a_gait_that_goes_the_wrong_way(snakes) -> None:
    """A case built to fail: rotating with its sense declared backwards scores negative."""
    c, model = snakes[8]
    real = c._run

    def backwards(name, params):
        t = real(name, params)
        return Trajectory(
            t.behavior,
            t.times,
            t.joints,
            t.positions,
            t.velocities,
            {**t.info, "turn": -t.info["turn"]},
        )

    c._run = backwards
    try:
        done, _ = judge(c, model, "rotating", cycles=3)
    finally:
        c._run = real
    assert done < 0


# --- sizing: every listed gait, and the payload ----------------------------------------------


def _torque(designer, kb, abilities: tuple[str, ...], payload: float = 0.0) -> float:
    cand = designer.step(Request(abilities=abilities)).chosen
    s = design_structure(kb, cand, load_catalog(), {"payload": payload})
    return max(j.required_torque_Nm for j in s.joints)


def test_the_snake_is_sized_for_every_gait_it_lists(designer, kb) -> None:
    """``design circular-path`` lists rolling: it is sized as ``design rolling
    circular-path``, which is buildable."""
    assert _torque(designer, kb, ("circular-path",)) == _torque(
        designer, kb, ("rolling", "circular-path")
    )
    assert _torque(designer, kb, ("rolling",)) > 0


def test_the_payload_loads_the_snake(designer, kb) -> None:
    light = _torque(designer, kb, ("rolling",), 0.01)
    assert _torque(designer, kb, ("rolling",), 0.3) > light + 0.3 * 9.81 * 0.06 * 0.9
