"""Snake gaits: the wave generators of the paper's eqs. 7-9, the gait parameter sets, and
(issue 5) the rolling and rectilinear gaits moving the designed snakes in MuJoCo."""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np
import pytest

from adron.catalog import load_catalog
from export.bundle import bundle_files, write_bundle
from export.record import design_record
from gaits.base import DesignGeometry, Trajectory
from gaits.snake import (
    ARCH_MODULES,
    BEND_MAX,
    GAITS,
    RECTILINEAR_ARCH,
    SPEED_MARGIN,
    SPEED_SHARE,
    SnakeController,
    WaveParams,
    gait_params,
    joint_waves,
    rolled_waves,
    wave_amplitude,
    wave_phase_step,
)
from kinematics.dynamics import forward_kinematics
from kinematics.spatial import rot_x
from synth.reasoning.conceptual import Design, Request
from synth.sizing.structure import design_structure
from synth.verification.simulate import simulate
from synth.verification.source import Bundle

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
    for m in (3, 5, 6, 8, 14):
        roll = gait_params("rolling", m)
        assert roll.a_v == roll.a_h and roll.dphi_v == roll.dphi_h == 0
        assert abs(roll.dphi_vh) == pytest.approx(math.pi / 2)
        rect = gait_params("rectilinear", m)
        assert rect.a_h == 0 and abs(rect.dphi_v) == pytest.approx(deg(120))
        # the arch is shared by the vertical joints
        if 5 <= m <= ARCH_MODULES:  # from the gait's least M (ontology)
            assert rect.o_v * math.ceil(m / 2) == pytest.approx(RECTILINEAR_ARCH)
        elif m > ARCH_MODULES:  # long snakes arch less
            assert 0 < rect.o_v * math.ceil(m / 2) < RECTILINEAR_ARCH
        side = gait_params("sidewinding", m)
        assert side.dphi_v == side.dphi_h != 0
        # 90 degrees between the waves where they bend the body: the horizontal module is
        # half a phase step behind its vertical one
        assert side.dphi_vh - side.dphi_v / 2 == pytest.approx(deg(90))
        # the other sense is the mirror image: the horizontal wave half a cycle later
        back = gait_params("sidewinding", m, -1)
        assert side.dphi_vh - back.dphi_vh == pytest.approx(math.pi)
        assert back.a_v == side.a_v and back.dphi_v == side.dphi_v
        rot = gait_params("rotating", m)  # different k: twice the phase step vertically
        assert rot.dphi_v == pytest.approx(2 * rot.dphi_h)
        circ = gait_params("circular-path", m, bend=0.3)
        assert circ.o_h == 0.3 and circ.a_v == rect.a_v
        for g in GAITS:
            assert gait_params(g, m).peak() <= math.pi / 2
            assert gait_params(g, m, -1).peak() == gait_params(g, m, 1).peak()
    # the rolling arc's bend is shared by the joints: bigger amplitudes on short snakes
    assert gait_params("rolling", 3).a_v > gait_params("rolling", 8).a_v >= deg(30)
    # so is the sidewinding lift: short snakes (relatively heavier heads) lift more
    assert gait_params("sidewinding", 6).a_v > gait_params("sidewinding", 14).a_v >= deg(10)
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
    # the declared range ends at the highest frequency (issue 24); beyond it the plan
    # itself says how far it goes
    with pytest.raises(ValueError, match=rf"frequency: \S+ is outside \[0.001, {top:g}\]"):
        c.run("rectilinear", frequency=1.05 * top)
    spec = c.behaviors["rectilinear"]
    with pytest.raises(ValueError, match=f"frequency: .* at most {top:.3g} Hz"):
        c._run("rectilinear", {**spec.resolve({}), "frequency": 1.05 * top})
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


# --- a rolled body: the waves turned by the roll --------------------------------------------

ROLLS = (math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2, math.pi, 0.3)


def test_every_gait_takes_the_roll() -> None:
    c = SnakeController(_geometry(14))
    for spec in c.behaviors.values():
        roll = next(p for p in spec.params if p.name == "roll")
        assert (roll.kind, roll.default, roll.unit) == ("float", 0.0, "rad")
        assert (roll.low, roll.high) == (-math.pi, math.pi)
        assert "long axis" in roll.doc and "+x" in roll.doc
    with pytest.raises(ValueError, match="outside"):
        c.run("rolling", roll=3.2)


def test_no_roll_is_eq_7_exactly() -> None:
    """roll = 0 leaves the trajectories as they were: eq. 7, bit for bit."""
    p = WaveParams(0.4, 0.3, 0.7, -0.5, 1.1, 0.05, -0.2)
    phase = np.linspace(0, 7, 23)
    eq7 = np.empty((23, 7))
    for j in range(7):
        i = j // 2
        if j % 2 == 0:
            eq7[:, j] = 1.0 * (p.o_v + p.a_v * np.sin(phase + i * p.dphi_v))
        else:
            eq7[:, j] = 1.0 * (p.o_h + p.a_h * np.sin(phase + i * p.dphi_h + p.dphi_vh))
    assert np.array_equal(joint_waves(phase, 7, p, roll=0.0), eq7)
    # the rolled form at roll 0 is the same waves (the continuous form samples eq. 7)
    assert np.allclose(joint_waves(phase, 7, p, roll=1e-300), eq7, rtol=0, atol=1e-12)
    c = SnakeController(_geometry(8))
    for gait in ALL:
        a, b = c.run(gait), c.run(gait, roll=0.0)
        assert a.positions.tobytes() == b.positions.tobytes()
        assert a.velocities.tobytes() == b.velocities.tobytes()


def _shape(model, bodies, q: np.ndarray, roll: float) -> np.ndarray:
    """World positions (N, B, 3) m of ``bodies`` with the base rolled by ``roll`` rad."""
    frames = forward_kinematics(model, q)[:, bodies]
    return np.einsum("ab,nkb->nka", rot_x(roll), frames[..., :3, 3])


def test_rolled_waves_bend_the_body_in_the_world_as_upright() -> None:
    """Checked against the template's joint axes: a long snake rolled by ``roll`` with the
    turned waves takes the upright snake's shape in the world (up to sampling the waves on
    the other joints); with the roll's sign reversed, or not turned, it does not."""
    m = 24
    c = SnakeController(_geometry(m, ("rolling",)))
    model = c.template.model
    bodies = [model.body(f"module_{i}") for i in range(1, m + 1)]
    p = WaveParams(0.25, 0.2, math.pi / 6, math.pi / 6, 0.7, 0.05, -0.04)
    phase = np.array([0.3, 1.9, 4.0])
    upright = joint_waves(phase, m, p)
    want = _shape(model, bodies, upright, 0.0)
    straight = np.zeros(3)
    bent = np.abs(want - straight - np.outer(np.arange(m), [0.06, 0, 0])).max()
    for roll in ROLLS:
        good = _shape(model, bodies, joint_waves(phase, m, p, roll=roll), roll)
        assert np.abs(good - want).max() < 0.25 * bent
        if abs(math.sin(roll)) > 0.5:  # the mirrored turn (a case built to fail)
            wrong = _shape(model, bodies, joint_waves(phase, m, p, roll=-roll), roll)
            assert np.abs(wrong - want).max() > 0.5 * bent
        unturned = _shape(model, bodies, upright, roll)
        assert np.abs(unturned - want).max() > 0.25 * bent
    # rolled_waves shares each joint's bend by its axis
    v, h = np.full((1, 2), 0.3), np.full((1, 2), 0.1)
    assert np.allclose(rolled_waves(v, h, math.pi / 2), [[0.1, -0.3]])


def test_a_roll_keeps_ranges_and_speeds() -> None:
    """Turned waves stay within the joints' range and speed, or are refused saying so; the
    default frequency stays feasible at every roll."""
    assert SPEED_SHARE * math.sqrt(2) <= SPEED_MARGIN
    slow = SnakeController(_geometry(14, speed=2.0))
    for gait in ALL:
        for roll in ROLLS + (-math.pi,):
            traj = slow.run(gait, roll=roll, cycles=2)
            assert np.abs(traj.positions).max() <= math.pi / 2
            assert np.abs(traj.velocities).max() <= slow.max_speed * (1 + 1e-9)
            assert traj.info["roll_rad"] == roll
    # a bend the horizontal joints hold upright leaves the range when shared with the
    # vertical wave (a case built to fail)
    slow.run("circular-path", bend=BEND_MAX, cycles=2)
    with pytest.raises(ValueError, match=r"rolled by 0\.785 rad leave the joints' range: joint_"):
        slow.run("circular-path", bend=BEND_MAX, cycles=2, roll=math.pi / 4)
    # a roll shares both waves' rates: where rotating's waves are in phase a joint moves
    # faster than upright, so the highest frequency is lower, and said
    roll = -math.pi / 12
    top, rolled = slow.max_frequency("rotating"), slow.max_frequency("rotating", roll=roll)
    assert rolled < 0.99 * top
    slow.run("rotating", frequency=top)
    with pytest.raises(ValueError, match=f"at most {rolled:.3g} Hz"):
        slow.run("rotating", frequency=top, roll=roll)


def test_the_promise_is_in_the_heading_frame() -> None:
    """A rolled snake promises what the upright one does: the waves are turned, not the
    motion."""
    c = SnakeController(_geometry(14))
    for gait in ALL:
        for roll in ROLLS:
            a, b = c.run(gait, cycles=2).info, c.run(gait, cycles=2, roll=roll).info
            assert (a.get("direction"), a.get("turn")) == (b.get("direction"), b.get("turn"))


# --- MuJoCo: every gait of the paper's snakes moves as its info promises --------------------

#: The paper's snakes (section 4.3.2): the gaits asked for; each lists every gait its M allows.
PAPER = {3: ("rolling",), 5: ("rectilinear",), 6: ("sidewinding",), 8: ("rotating",)}
PAPER[14] = ("rolling", "circular-path")
#: Issue 8's thresholds: crawl >= 0.25 body length, rotate >= 45 degrees per 10 s; at most
#: 5 % of the samples with an actuator at its torque limit.
LEAST_CRAWL, LEAST_TURN, MOST_SATURATED = 0.25, math.radians(45), 0.05


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
        write_bundle(folder, bundle_files(rec, s, catalog, with_payload=True, pictures=False))
        c = SnakeController(DesignGeometry.from_record(rec))
        assert c.modules == m
        out[m] = (c, Bundle(folder=folder).model())
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
        # the whole body's progress along the direction (synth.verification.simulate, as the
        # verdict)
        done = r.distance_m / traj.info["body_length_m"]
    return done * 10.0 / traj.duration, saturated


@pytest.mark.parametrize(
    "modules, gait",
    [(m, g) for m in PAPER for g in GAITS[: {3: 1, 5: 2, 6: 3, 8: 4, 14: 5}[m]]],
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


# --- MuJoCo: a snake lying rolled moves as promised when told its roll ----------------------


def roll_of(model, data) -> float:
    """The ``roll`` parameter's angle rad, measured: the root body's (the head's) roll about
    its long axis relative to the model's initial orientation, right-handed about its +x:
    the z-y-x Euler roll ``atan2(R[2, 1], R[2, 2])`` of R = R0^T R_now (R0 the root's
    orientation in ``qpos0``, identity in the generated MJCF; R_now from the freejoint's
    quaternion ``qpos[3:7]``)."""
    r0, now = np.empty(9), np.empty(9)
    mujoco.mju_quat2Mat(r0, model.qpos0[3:7])
    mujoco.mju_quat2Mat(now, data.qpos[3:7])
    rel = r0.reshape(3, 3).T @ now.reshape(3, 3)
    return math.atan2(rel[2, 1], rel[2, 2])


def _rolled_start(model, c: SnakeController, roll: float):
    """MjData of the snake straight, its freejoint's quaternion turned by ``roll`` rad
    about the body's long axis, lifted clear of the floor and settled for 0.5 s."""
    data = mujoco.MjData(model)
    data.qpos[3:7] = (math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0)
    mujoco.mj_forward(model, data)
    deepest = min((float(con.dist) for con in data.contact[: data.ncon]), default=0.0)
    data.qpos[2] += max(0.0, -deepest) + 0.002
    act = [model.actuator(j).id for j in c.joints]
    data.ctrl[act] = 0.0  # the gaits' first pose: straight
    for _ in range(int(0.5 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return data


def judge_from(c: SnakeController, model, data, gait: str, **params) -> tuple[float, float]:
    """``judge`` for a run that continues from ``data`` (left as it ends)."""
    traj = c.run(gait, **params)
    r = simulate(model, traj, can_fall=False, data=data)
    root = r.series["root"]
    if traj.info["motion"] == "rotate":
        yaw = _yaws(root)
        done = float(yaw[-1] - yaw[0]) * traj.info["turn"]
    else:
        done = r.distance_m / traj.info["body_length_m"]
    return done * 10.0 / traj.duration, r.saturated_fraction


def test_roll_of_measures_the_roll_about_the_long_axis(snakes) -> None:
    c, model = snakes[8]
    data = mujoco.MjData(model)
    for roll in (0.0, 0.4, -1.2, 3.0):
        half = (math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0)
        turn = (math.cos(0.35), 0.0, 0.0, math.sin(0.35))  # and a heading: not a roll
        mujoco.mju_mulQuat(data.qpos[3:7], np.array(turn), np.array(half))
        assert roll_of(model, data) == pytest.approx(roll)


def test_a_snake_on_its_side_moves_when_told_its_roll(snakes) -> None:
    """The M = 8 snake laid on its side: rectilinear and rotating told the measured roll do
    what they promise; rectilinear not told (a case built to fail) does not move."""
    c, model = snakes[8]
    start = _rolled_start(model, c, math.pi / 2)
    roll = roll_of(model, start)
    assert roll == pytest.approx(math.pi / 2, abs=math.radians(5))
    # (rectilinear's saturation is checked upright at its default cycles: at M = 8 it is
    # near the limit, more so on short runs, whose fades weigh more)
    done, _ = judge_from(c, model, copy.copy(start), "rectilinear", roll=roll, cycles=4)
    assert done >= LEAST_CRAWL
    done, _ = judge_from(c, model, copy.copy(start), "rectilinear", cycles=4)
    assert done < LEAST_CRAWL
    done, saturated = judge_from(c, model, start, "rotating", roll=roll, cycles=3)
    assert done >= LEAST_TURN and saturated <= MOST_SATURATED


def test_after_rolling_the_measured_roll_lets_the_next_gait_work(snakes) -> None:
    """A program's chain: rolling leaves the snake on its side; the next gait, told the
    roll measured there, keeps its promise."""
    c, model = snakes[8]
    data = mujoco.MjData(model)
    judge_from(c, model, data, "rolling", direction=-1, cycles=2)
    roll = roll_of(model, data)
    assert abs(roll) > math.radians(45)
    done, saturated = judge_from(c, model, data, "rotating", roll=roll, cycles=3)
    assert done >= LEAST_TURN and saturated <= MOST_SATURATED


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


def test_enumerate_lists_the_snakes_actuator_assignments(cli) -> None:
    """The snake has no behaviour samples (its hand cases size it): its assignments are
    still counted (an empty sample set once crashed the Pareto hull)."""
    r = cli("enumerate", "rotating", "--param", "payload=0.2kg")
    assert r.code == 0, r.err
    assert "feasible" in r.out and "SnakeRobot" in r.out
