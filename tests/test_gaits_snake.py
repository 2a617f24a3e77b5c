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
from gaits.base import DesignGeometry
from gaits.snake import (
    GAITS,
    SnakeController,
    WaveParams,
    gait_params,
    joint_waves,
    wave_amplitude,
    wave_phase_step,
)
from synth.conceptual import Design, Request
from synth.solver import Query
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


# --- MuJoCo: the rolling and rectilinear gaits move the designed snakes ----------------------


@pytest.fixture(scope="module")
def snakes(kb, designer, tmp_path_factory):
    """M -> (controller, model): the default snake (M = 3, rolling only) and those designed
    for rolling and rectilinear motion (M = 5), sidewinding (M = 6) and rotating and
    sidewinding (M = 8: sized for both gaits the tests run on it)."""
    catalog = load_catalog()
    default = next(
        c for c in designer.reasoner.solve(Query()).candidates if c.robot_type == "SnakeRobot"
    )
    asked = [("rolling", "rectilinear"), ("sidewinding",), ("rotating", "sidewinding")]
    out = {}
    for cand in [default] + [designer.step(Request(abilities=a)).chosen for a in asked]:
        s = design_structure(kb, cand, catalog, {})
        rec = design_record(
            Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
        )
        folder = tmp_path_factory.mktemp("snake") / f"m{rec['dof']}"
        write_bundle(folder, bundle_files(rec, s, catalog))
        c = SnakeController(DesignGeometry.from_record(rec))
        out[c.modules] = (c, load_bundle_model(folder))
    assert set(out) == {3, 5, 6, 8}
    assert out[8][0].gaits == ("rolling", "rectilinear", "sidewinding", "rotating")
    return out


def _travel(snakes, modules: int, gait: str, **params):
    """(displacement (2,) m, the trajectory, the SimResult) of 10 s of ``gait``."""
    c, model = snakes[modules]
    traj = c.run(gait, cycles=4, **params)  # 4 cycles at the default 0.4 Hz: 10 s
    assert traj.duration == pytest.approx(10.0)
    r = simulate(model, traj, can_fall=False)
    root = r.series["root"]
    return root[-1, :2] - root[0, :2], traj, r


def _along(snakes, modules: int, gait: str, **params):
    """(displacement m along the intended direction, the SimResult) of 10 s of ``gait``."""
    moved, traj, r = _travel(snakes, modules, gait, **params)
    return float(moved @ np.asarray(traj.info["direction"])), r


def _max_roll(r) -> float:
    """Largest |rotation| rad of the base about its own long axis (x) in the run."""
    w, x, y, z = r.series["root"][:, 3:7].T
    return float(np.max(np.abs(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))))


@pytest.mark.parametrize("modules", [3, 5])
@pytest.mark.parametrize("direction", [1, -1])
def test_rolling_moves_the_snake_sideways(snakes, modules: int, direction: int) -> None:
    along, r = _along(snakes, modules, "rolling", direction=direction)
    # one roll of the ~5 cm square body covers ~0.2 m; measured 0.42 m (M = 3), 0.65 (M = 5)
    assert along > 0.2
    assert _max_roll(r) > 2.5  # it really rolls over


@pytest.mark.parametrize("direction, least", [(1, 0.05), (-1, 0.01)])
def test_rectilinear_moves_the_snake_along_its_axis(snakes, direction, least) -> None:
    along, r = _along(snakes, 5, "rectilinear", direction=direction)
    # measured 7.1 cm head first, 2.6 cm tail first (the heavy head drags): at least the
    # module pitch's 6 cm less a margin, and clearly tail first
    assert along > least
    assert abs(r.heading_rad) < 0.05
    assert _max_roll(r) < math.radians(5)  # statically stable: never tips over


def test_sidewinding_and_rotating_on_the_eight_module_snake(snakes) -> None:
    for direction in (1, -1):
        along, r = _along(snakes, 8, "sidewinding", direction=direction)
        assert along > 0.1 and abs(r.heading_rad) < 0.2  # measured 0.21 m, 0.02 rad
        moved, traj, r = _travel(snakes, 8, "rotating", direction=direction)
        assert r.heading_rad * traj.info["turn"] > 0.2  # measured 0.41 rad in 10 s
        assert np.hypot(*moved) < 0.05  # in place: measured 1 cm


@pytest.mark.xfail(
    strict=True,
    reason="the 6-module snake designed for sidewinding turns instead (measured: 2.5 cm "
    "the wrong way and 1.8 rad of heading in 10 s): its heavy head (base with battery and "
    "main module, 0.23 kg of 0.92) takes the lateral shift's thrust off-centre",
)
def test_sidewinding_on_the_six_module_snake(snakes) -> None:
    along, r = _along(snakes, 6, "sidewinding")
    assert along > 0.1 and abs(r.heading_rad) < 0.3
