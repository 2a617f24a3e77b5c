"""Wheeled robots' kinematics (paper eqs. 5-6) and the driving behaviours, checked
analytically and in MuJoCo on the default differential-drive and skid-steer designs
(issue 5: the differential robot follows a commanded (v, w) within 10 %)."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

from adron.catalog import load_catalog
from export.bundle import bundle_files, write_bundle
from export.record import design_record
from gaits.base import DesignGeometry, min_jerk_integral
from gaits.wheeled import (
    CASTER_FRICTION,
    TURN_SETTLE_S,
    TYRE_FRICTION,
    WHEEL_MOTOR_TIME_CONSTANT,
    DriveGeometry,
    WheeledController,
    body_velocity,
    creep_speed,
    integrate_odometry,
    min_jerk,
    skid_steer_chi,
    turning_radius,
    wheel_speeds,
)
from kinematics.templates import TemplateParams, build
from synth.reasoning.conceptual import Design, Request
from synth.reasoning.solver import Query
from synth.sizing.families import Wheeled
from synth.sizing.structure import design_structure
from synth.verification.loop import calibrate
from synth.verification.simulate import simulate
from synth.verification.source import Bundle


def _geometry(robot_type: str, speed: float = 6.0) -> DesignGeometry:
    """A synthetic design record's geometry (template defaults, 3 cm wheels)."""
    wheels = {
        "DifferentialDriveRobot": ("left_wheel", "right_wheel"),
        "SkidSteerRobot": (
            "front_left_wheel",
            "front_right_wheel",
            "rear_left_wheel",
            "rear_right_wheel",
        ),
    }[robot_type]
    return DesignGeometry(
        robot_type=robot_type,
        template=robot_type,
        lengths={},
        modules=len(wheels),
        wheel_radius=0.03,
        params={},
        abilities=("driving",),
        joint_speed=dict.fromkeys(wheels, speed),
    )


# --- kinematics --------------------------------------------------------------------------


@pytest.mark.parametrize("v, w", [(0.3, 0.0), (0.2, 1.0), (0.0, -2.0), (-0.1, 0.4)])
def test_wheel_speeds_and_body_velocity_are_inverse(v: float, w: float) -> None:
    ql, qr = wheel_speeds(v, w, 0.05, 0.2)
    assert body_velocity(ql, qr, 0.05, 0.2) == pytest.approx((v, w), abs=1e-12)
    # eq. 5 directly
    assert w == pytest.approx((0.05 * qr - 0.05 * ql) / 0.2, abs=1e-12)


def test_turning_radius_is_eq_6() -> None:
    r, l_ = 0.05, 0.2
    ql, qr = wheel_speeds(0.3, 0.6, r, l_)
    assert turning_radius(ql, qr, r, l_) == pytest.approx(0.3 / 0.6)
    assert turning_radius(ql, qr, r, l_) == pytest.approx(
        l_ * (r * qr + r * ql) / (2 * (r * qr - r * ql))
    )
    assert turning_radius(2.0, 2.0, r, l_) == math.inf
    assert turning_radius(-1.0, 1.0, r, l_) == 0.0
    assert turning_radius(*wheel_speeds(0.3, -0.6, r, l_), r, l_) == pytest.approx(-0.5)


def test_odometry_of_constant_wheel_speeds_is_a_circle_arc() -> None:
    r, l_, v, w = 0.04, 0.15, 0.2, 0.8
    t = np.linspace(0, 3, 31)
    ql, qr = wheel_speeds(v, w, r, l_)
    poses = integrate_odometry(t, np.full_like(t, ql), np.full_like(t, qr), r, l_)
    radius = v / w
    expect = np.column_stack(
        [radius * np.sin(w * t), radius * (1 - np.cos(w * t)), w * t]
    )  # exact, even with coarse steps
    assert np.allclose(poses, expect, atol=1e-12)
    straight = integrate_odometry(t, np.ones_like(t), np.ones_like(t), r, l_, (1, 2, math.pi))
    assert np.allclose(straight[-1], (1 - 3 * r, 2, math.pi))


def test_skid_steer_chi() -> None:
    assert skid_steer_chi(0.0, 0.2) == 1.0
    # Pioneer 3-AT (wheel base 0.268 m, track 0.394 m): Mandow et al. measured chi = 1.5
    assert skid_steer_chi(0.268, 0.394) == pytest.approx(1.46, abs=0.01)


def test_min_jerk_ramp() -> None:
    tau = np.linspace(0, 1, 2001)
    s, ds, _ = min_jerk(tau)
    integral = min_jerk_integral(tau)
    assert (s[0], s[-1], ds[0], ds[-1]) == (0, 1, 0, 0)
    assert np.all(np.diff(s) >= 0)
    assert np.allclose(np.gradient(s, tau), ds, atol=1e-5)
    trapz = np.concatenate([[0], np.cumsum((s[1:] + s[:-1]) / 2 * np.diff(tau))])
    assert np.allclose(trapz, integral, atol=1e-6)


@pytest.mark.parametrize("bad", [(0.0, 0.2), (0.05, 0.0), (-1.0, 0.2), (math.nan, 0.2)])
def test_bad_geometry_raises(bad) -> None:
    with pytest.raises(ValueError):
        wheel_speeds(0.1, 0.0, *bad)


# --- drive geometry and the controller ---------------------------------------------------


def test_drive_geometry_from_the_templates() -> None:
    dd = WheeledController(_geometry("DifferentialDriveRobot")).drive
    assert (dd.left, dd.right) == (("left_wheel",), ("right_wheel",))
    assert dd.radius == 0.03 and dd.track == pytest.approx(0.12)  # default L2
    assert dd.wheel_base == 0 and dd.effective_track == pytest.approx(0.12)
    assert not dd.skid and set(dd.sign.values()) == {1.0}
    ss = WheeledController(_geometry("SkidSteerRobot")).drive
    assert ss.skid and ss.track == pytest.approx(0.16) and ss.wheel_base == pytest.approx(0.20)
    assert ss.effective_track == pytest.approx(0.16 * (1 + (0.20 / 0.16) ** 2))


def test_drive_geometry_refuses_what_it_cannot_drive() -> None:
    snake = build("SnakeRobot")
    with pytest.raises(ValueError, match="no wheels"):
        DriveGeometry.from_template(snake, {})
    with pytest.raises(ValueError, match="no speed for the wheel"):
        DriveGeometry.from_template(build("DifferentialDriveRobot"), {"left_wheel": 5.0})


def test_driving_trajectory_is_smooth_and_integrates_to_the_commanded_arc() -> None:
    c = WheeledController(_geometry("DifferentialDriveRobot"))
    v, w, seconds, ramp = 0.1, 0.5, 4.0, 0.8
    traj = c.run("driving", v=v, w=w, seconds=seconds, ramp=ramp)
    assert traj.joints == ("left_wheel", "right_wheel")
    assert traj.info["command"] == (v, w)
    assert traj.duration == pytest.approx(seconds)
    ql, qr = wheel_speeds(v, w, 0.03, 0.12)
    assert np.allclose(traj.velocities[0], 0) and np.allclose(traj.positions[0], 0)
    assert np.allclose(traj.velocities[traj.times >= ramp], (ql, qr))
    # continuous: no jump between samples larger than the ramp's peak acceleration allows
    dt = np.diff(traj.times)[:, None]
    assert np.max(np.abs(np.diff(traj.velocities, axis=0)) / dt) <= 1.875 * abs(qr) / ramp + 1e-6
    # positions are the integral of the velocities
    trapz = np.cumsum((traj.velocities[1:] + traj.velocities[:-1]) / 2 * dt, axis=0)
    assert np.allclose(traj.positions[1:], trapz, atol=1e-4)
    # odometry: the heading changes by w (T - ramp / 2)
    pose = integrate_odometry(traj.times, *traj.velocities.T, 0.03, 0.12)
    assert pose[-1, 2] == pytest.approx(w * (seconds - ramp / 2), rel=1e-4)


def test_turning_trajectory_ends_at_rest_with_the_heading_asked() -> None:
    c = WheeledController(_geometry("SkidSteerRobot"))
    traj = c.run("turning", angle=-math.pi / 2)
    assert np.allclose(traj.velocities[[0, -1]], 0)
    assert np.abs(traj.velocities).max() <= c.drive.max_speed * (1 + 1e-6)
    left = traj.velocities[:, traj.joints.index("front_left_wheel")]
    right = traj.velocities[:, traj.joints.index("front_right_wheel")]
    pose = integrate_odometry(traj.times, left, right, c.drive.radius, c.drive.effective_track)
    assert pose[-1, 2] == pytest.approx(-math.pi / 2, rel=1e-4)
    assert np.allclose(pose[-1, :2], 0, atol=1e-9)
    slow = c.run("turning", angle=math.pi, seconds=20)
    assert slow.duration == pytest.approx(20 + TURN_SETTLE_S)  # and its settling tail


def test_bad_commands_raise() -> None:
    c = WheeledController(_geometry("DifferentialDriveRobot", speed=5.0))
    assert c.v_max == pytest.approx(0.15)
    with pytest.raises(ValueError, match="v alone up to 0.15"):
        c.run("driving", v=0.14, w=1.0)  # the outer wheel would need more than 5 rad/s
    with pytest.raises(ValueError, match="outside"):
        c.run("driving", v=0.2)
    with pytest.raises(ValueError, match="ramp"):
        c.run("driving", v=0.1, seconds=1.0, ramp=2.0)
    with pytest.raises(ValueError, match="no parameter 'speed'"):
        c.run("driving", speed=0.1)
    with pytest.raises(ValueError, match="no behaviour 'walking'"):
        c.run("walking")
    with pytest.raises(ValueError, match="at least"):
        c.run("turning", angle=math.pi, seconds=0.1)
    with pytest.raises(ValueError, match="expected a number"):
        c.run("driving", v="fast")


# --- MuJoCo, on the default designs ---------------------------------------------------------


@pytest.fixture(scope="module")
def designs(kb, designer, tmp_path_factory):
    """Default design of each wheeled type, calibrated as ``parmor design`` calibrates it
    (``synth.verification.loop.calibrate``: none for the differential drive): (controller, MuJoCo
    model)."""
    catalog = load_catalog()
    out = {}
    candidates = designer.reasoner.solve(Query()).candidates
    for robot_type in ("DifferentialDriveRobot", "SkidSteerRobot"):
        cand = next(c for c in candidates if c.robot_type == robot_type)
        s = design_structure(kb, cand, catalog, {})
        rec = design_record(
            Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
        )
        files = bundle_files(rec, s, catalog, with_payload=True, pictures=False)
        calibration = calibrate(Bundle(files))  # a skid-steer's, measured as `parmor design` does
        if calibration:
            rec["calibration"] = calibration
            files = bundle_files(rec, s, catalog, with_payload=True, pictures=False)
        folder = tmp_path_factory.mktemp("wheeled") / robot_type
        write_bundle(folder, files)
        out[robot_type] = (
            WheeledController(DesignGeometry.from_record(rec)),
            Bundle(folder=folder).model(),
        )
    return out


def _run(designs, robot_type: str, behavior: str, **params):
    """Simulate a behaviour for its duration: (controller, trajectory, SimResult)."""
    c, model = designs[robot_type]
    traj = c.run(behavior, **params)
    return c, traj, simulate(model, traj)


def _pose(r) -> tuple[np.ndarray, float]:
    """(displacement (2,) m, yaw change rad, unwrapped) of the root over a simulation."""
    root = r.series["root"]
    yaws = np.unwrap(
        [math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)) for w, x, y, z in root[:, 3:7]]
    )
    return root[-1, :2] - root[0, :2], float(yaws[-1] - yaws[0])


def test_differential_drive_follows_a_straight_command(designs) -> None:
    c, traj, r = _run(designs, "DifferentialDriveRobot", "driving", w=0.0)
    v = traj.info["command"][0]
    assert v == pytest.approx(c.v_max / 2, abs=1e-3)  # the default speed
    assert traj.info["motion"] == "straight" and traj.info["direction"] == (1.0, 0.0)
    d, yaw = _pose(r)
    planned = traj.info["planned_pose"]
    assert planned == pytest.approx((v * (traj.duration - 0.25), 0, 0))
    assert not r.fell and 0.9 < d[0] / planned[0] < 1.05  # measured 0.97
    assert abs(d[1]) < 0.01 and abs(yaw) < 0.01
    assert r.max_torque_ratio < 1.0


@pytest.mark.parametrize("v, w", [(0.15, 0.5), (0.08, -1.5)])
def test_differential_drive_follows_an_arc(designs, v: float, w: float) -> None:
    c, traj, r = _run(designs, "DifferentialDriveRobot", "driving", v=v, w=w, seconds=4.0)
    assert traj.info["motion"] == "arc"
    d, yaw = _pose(r)
    dx, dy, dyaw = traj.info["planned_pose"]
    # issue 8: end position within 10 % of the path, heading within 10 % of the turn
    assert np.hypot(d[0] - dx, d[1] - dy) < 0.10 * traj.info["path_length_m"]
    assert abs(yaw - dyaw) < 0.10 * abs(dyaw)  # measured 3-5 %


@pytest.mark.parametrize("angle", [math.pi / 2, -math.pi])
def test_differential_drive_turns_in_place(designs, angle: float) -> None:
    c, traj, r = _run(designs, "DifferentialDriveRobot", "turning", angle=angle)
    assert traj.info["motion"] == "turn" and traj.info["planned_pose"] == (0.0, 0.0, angle)
    d, yaw = _pose(r)
    assert yaw == pytest.approx(angle, rel=0.10)  # measured 97-99 %
    assert np.hypot(*d) < 0.10 * traj.info["body_length_m"]


def test_skid_steer_drives_forward(designs) -> None:
    c, traj, r = _run(designs, "SkidSteerRobot", "driving", w=0.0)
    d, yaw = _pose(r)
    assert 0.9 < d[0] / traj.info["planned_pose"][0] < 1.05
    assert abs(d[1]) < 0.01 and abs(yaw) < 0.01
    assert not r.fell


@pytest.mark.parametrize("angle", [math.pi / 2, -2.0])
def test_skid_steer_turns_in_place(designs, angle: float) -> None:
    """The wheels skid: the effective track and the scrubbing torque's droop (fed forward)
    make the turn; without them it reached 28-45 % of the angle (issue 8)."""
    c, traj, r = _run(designs, "SkidSteerRobot", "turning", angle=angle)
    d, yaw = _pose(r)
    assert yaw == pytest.approx(angle, rel=0.10)  # measured 100-101 % (calibrated)
    assert np.hypot(*d) < 0.10 * traj.info["body_length_m"]


@pytest.mark.parametrize(
    "v, w",
    [
        (0.12, 0.2),  # measured 0.97 of the planned turn (calibrated)
        (0.12, 0.4),  # 0.99; 0.89 with the Coulomb model's effective track
    ],
)
def test_skid_steer_follows_an_arc(designs, v: float, w: float) -> None:
    c, traj, r = _run(designs, "SkidSteerRobot", "driving", v=v, w=w, seconds=4.0)
    d, yaw = _pose(r)
    dx, dy, dyaw = traj.info["planned_pose"]
    assert np.hypot(d[0] - dx, d[1] - dy) < 0.10 * traj.info["path_length_m"]
    assert abs(yaw - dyaw) < 0.10 * abs(dyaw)


# --- the model: only the wheels (and the caster) touch the ground ---------------------------


def test_the_wheel_radius_lifts_the_servo_off_the_ground() -> None:
    """The sizing rule: the radius clears the servo case centred on the axle (case built
    to fail: the catalog's smallest wheel, 20 mm, under a 50 mm case)."""
    catalog = load_catalog()
    servos = catalog.actuators_of("ContinuousRotationServomotor")
    rule = Wheeled.servo_clearance_radius(servos)
    assert rule == pytest.approx(0.025 + Wheeled.GROUND_CLEARANCE)

    def lowest_servo_point(r: float) -> float:
        """Lowest z (m) of a wheel servo's case; the ground is at z = -r."""
        size = tuple(max(a.size_m[i] for a in servos) for i in range(3))
        t = build("DifferentialDriveRobot", TemplateParams(wheel_radius=r, actuator_size=size))
        low = np.inf
        for lp in t.parts["chassis"]:
            if lp.kind == "actuator":
                corners = np.array(list(itertools.product(*[(-h / 2, h / 2) for h in lp.dims])))
                low = min(
                    low, float((corners @ lp.placement[:3, :3].T)[:, 2].min() + lp.placement[2, 3])
                )
        assert not any(lp.kind == "actuator" for w in t.wheels for lp in t.parts[w])
        return low + r  # height above the ground

    assert lowest_servo_point(rule) == pytest.approx(Wheeled.GROUND_CLEARANCE)
    assert lowest_servo_point(0.02) < 0  # the old 20 mm wheel: the robot stands on its servos


@pytest.fixture(scope="module")
def small_wheels(kb, designer, tmp_path_factory):
    """The smallest wheels parmor designs (slow, light, small, flat): (controller, model)."""
    catalog = load_catalog()
    candidates = designer.reasoner.solve(Query()).candidates
    params = {"payload": 0.1, "speed": 0.05, "load_area": 0.01, "slope": 0.0}
    out = {}
    for robot_type in ("DifferentialDriveRobot", "SkidSteerRobot"):
        cand = next(c for c in candidates if c.robot_type == robot_type)
        s = design_structure(kb, cand, catalog, params)
        assert s.wheel_radius_m == pytest.approx(
            Wheeled.servo_clearance_radius(catalog.actuators_of("ContinuousRotationServomotor"))
        )
        rec = design_record(
            Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
        )
        folder = tmp_path_factory.mktemp("small") / robot_type
        write_bundle(folder, bundle_files(rec, s, catalog, with_payload=True, pictures=False))
        out[robot_type] = (
            WheeledController(DesignGeometry.from_record(rec)),
            Bundle(folder=folder).model(),
        )
    return out


@pytest.mark.parametrize("robot_type", ["DifferentialDriveRobot", "SkidSteerRobot"])
def test_only_wheels_and_casters_touch_the_floor(small_wheels, robot_type: str) -> None:
    import mujoco

    c, model = small_wheels[robot_type]
    traj = c.run("driving", v=c.v_max / 4, w=c.w_max / 8, seconds=1.0)
    data = mujoco.MjData(model)
    act = [model.actuator(j).id for j in traj.joints]
    floor = model.geom("floor").id
    bodies = set()
    for i in range(500):
        data.ctrl[act] = traj.at(i * model.opt.timestep)[1]
        mujoco.mj_step(model, data)
        for con in data.contact[: data.ncon]:
            if floor in (con.geom1, con.geom2):
                other = con.geom2 if con.geom1 == floor else con.geom1
                bodies.add(model.body(model.geom_bodyid[other]).name)
    wheels = set(c.template.wheels)
    assert wheels <= bodies <= wheels | set(c.template.casters)


# --- what the behaviours promise ----------------------------------------------------------


def test_driving_states_its_motion_and_exact_end_pose() -> None:
    c = WheeledController(_geometry("DifferentialDriveRobot"))
    assert c.behaviors["turning"].realises == "driving"
    assert c.behaviors["driving"].realises == "driving"
    v, w, seconds, ramp = 0.1, 0.8, 4.0, 0.7
    traj = c.run("driving", v=v, w=w, seconds=seconds, ramp=ramp)
    info = traj.info
    assert info["motion"] == "arc" and info["locomotion"] == "wheeled"
    # no mass in the geometry: no load feed-forward, the commands are the wheel speeds,
    # whose odometry (fine steps) ends where planned_pose says
    fine = np.linspace(0, seconds, 40001)
    left = np.interp(fine, traj.times, traj.velocities[:, 0])
    right = np.interp(fine, traj.times, traj.velocities[:, 1])
    pose = integrate_odometry(fine, left, right, 0.03, 0.12)[-1]
    assert pose == pytest.approx(info["planned_pose"], abs=2e-4)
    assert info["path_length_m"] == pytest.approx(v * (seconds - ramp / 2))
    back = c.run("driving", v=-0.1).info
    assert back["motion"] == "straight" and back["direction"] == (-1.0, 0.0)
    assert back["planned_pose"] == pytest.approx((-0.1 * 4.75, 0, 0))
    spin = c.run("driving", v=0.0, w=1.0).info
    assert spin["motion"] == "turn" and spin["planned_pose"] == pytest.approx((0, 0, 4.75))
    assert c.run("driving", v=0.0).info["motion"] == "hold"
    turn = c.run("turning", angle=-1.0).info
    assert turn["motion"] == "turn" and turn["planned_pose"] == (0.0, 0.0, -1.0)


def test_commands_feed_forward_the_load() -> None:
    """With the design's mass and stall torques, each wheel is commanded its speed plus
    the droop of its motor line under the load (a skid-steer's scrubbing while it turns);
    a command whose loaded speed exceeds the servo's no-load speed is refused."""
    g = _geometry("SkidSteerRobot")
    wheels = tuple(g.joint_speed)
    loaded = replace(g, mass_kg=2.0, joint_torque=dict.fromkeys(wheels, 1.0))
    c = WheeledController(loaded)
    d = c.drive
    assert d.kv == pytest.approx(1.0 / 6.0)
    a, l_ = 0.20, 0.16
    assert d.skid_torque() == pytest.approx(1.0 * 2.0 * 9.81 / 4 * 0.03 * a / math.hypot(a, l_))
    left, right = d.commands(np.array([0.0]), np.array([1.0]), np.zeros(1), np.zeros(1))
    ql, qr = d.wheel_speeds(0.0, 1.0)
    # the wheels scrub sideways (skid torque) and each tyre across its width (scrub moment)
    scrub = d.radius * d.scrub_moment() / d.track / 2
    droop = (d.skid_torque() + scrub) / d.kv  # at 1 rad/s the contacts slide (Coulomb)
    assert d.scrub_moment() == pytest.approx(2.0 * 9.81 * 0.01 / 4)
    assert 0 < d.creep < 1.0 * d.skid_slip()
    assert (left[0], right[0]) == pytest.approx((ql - droop, qr + droop))
    # below the creep speed MuJoCo's friction is viscous: the load grows with the slip
    w = 0.25 * d.creep / d.skid_slip()
    left, right = d.commands(np.array([0.0]), np.array([w]), np.zeros(1), np.zeros(1))
    ql, qr = d.wheel_speeds(0.0, w)
    assert right[0] - qr == pytest.approx(0.25 * droop)
    # straight and steady on flat ground: no load, no droop
    left, right = d.commands(np.array([0.1]), np.zeros(1), np.zeros(1), np.zeros(1))
    assert left[0] == right[0] == pytest.approx(0.1 / 0.03)
    # unloaded it fits the wheels; loaded with the scrubbing it does not
    w = 0.9 * c.w_max
    WheeledController(g).drive.check(0.0, w)
    with pytest.raises(ValueError, match="needs a wheel speed"):
        d.check(0.0, w)
    # the droop leaves less speed to turn with: the shortest unloaded turn is refused
    fast = 1.01 * 1.875 * math.pi / c.w_max
    WheeledController(g).run("turning", angle=math.pi, seconds=fast)
    with pytest.raises(ValueError, match="at least"):
        c.run("turning", angle=math.pi, seconds=fast)
    slow = c.run("turning", angle=math.pi)
    assert np.abs(slow.velocities).max() <= d.max_speed * (1 + 1e-9)


def test_wheeled_constants_agree_with_sizing_and_the_mjcf() -> None:
    from export import mjcf
    from export.mjcf import CONTACT_CLASSES
    from synth.sizing import families as sizing

    assert TYRE_FRICTION == sizing.TYRE_FRICTION
    assert WHEEL_MOTOR_TIME_CONSTANT == mjcf.WHEEL_MOTOR_TIME_CONSTANT
    friction = {name: f[0] for name, _, f in CONTACT_CLASSES}
    assert (friction["wheel"], friction["caster"]) == (TYRE_FRICTION, CASTER_FRICTION)


def test_creep_speed_is_mujocos_regularised_friction() -> None:
    """The slip speed at which a tyre's friction saturates: MuJoCo's soft contact (default
    solref/solimp) gives f = b v / R below it. A contact that creeps at a tenth of it
    carries a tenth of mu N; one pushed at twice the saturating force slides."""
    import mujoco

    xml = """<mujoco><option timestep="0.002" cone="elliptic"/><worldbody>
      <geom type="plane" size="1 1 0.1"/>
      <body pos="0 0 0.05"><freejoint/><geom type="box" size="0.05 0.05 0.05" mass="1"
        friction="1 0.005 0.0001"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(200):
        mujoco.mj_step(model, data)
    weight = 9.81
    vc = creep_speed(1.0, weight / 4, float(model.body_invweight0[1, 0]))  # 4 corners
    # a steady horizontal push of 0.1 mu m g creeps at about 0.1 vc (the box's own weight
    # rides on the four corner contacts)
    data.xfrc_applied[1, 0] = 0.1 * weight
    for _ in range(500):
        mujoco.mj_step(model, data)
    assert data.qvel[0] == pytest.approx(0.1 * vc, rel=0.15)
    # and a push beyond mu m g accelerates it: the friction has saturated
    data.xfrc_applied[1, 0] = 2.0 * weight
    for _ in range(50):
        mujoco.mj_step(model, data)
    assert data.qvel[0] > 10 * vc


def test_every_wheeled_model_has_the_elliptic_cone(designs) -> None:
    """MuJoCo's pyramidal cone is anisotropic in the world's x/y (a caster's drag changes
    with the heading); every wheeled model, with or without caster, uses the elliptic one."""
    import mujoco

    for robot_type in ("DifferentialDriveRobot", "SkidSteerRobot"):
        _, model = designs[robot_type]
        assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC, robot_type


def test_differential_tyres_scrub_at_their_edges() -> None:
    """A differential robot's tyre touches MuJoCo's floor at its rim's two edges: turning
    drags them +-width / 2 (lever width / 2); the load grows linearly up to the creep
    speed, so a slow turn loads the wheels less than a fast one."""
    g = _geometry("DifferentialDriveRobot")
    wheels = tuple(g.joint_speed)
    d = WheeledController(replace(g, mass_kg=2.0, joint_torque=dict.fromkeys(wheels, 1.0))).drive
    assert not d.skid and d.creep > 0
    load = 2.0 * 9.81 * (1 - d.caster_share)
    assert d.scrub_moment() == pytest.approx(1.0 * load * 0.01 / 2)
    d = replace(d, com_x=0.0)  # no centripetal load
    zero = np.zeros(1)
    slow, fast = 0.5 * d.creep / 0.005, 4 * d.creep / 0.005  # edge slip 0.5 and 4 x creep
    slow_r = d.wheel_torques(zero, np.array([slow]), zero, zero)[1][0]
    fast_r = d.wheel_torques(zero, np.array([fast]), zero, zero)[1][0]
    # (the caster's Coulomb drag is the same at both rates; the scrub half of it at slow)
    assert fast_r - slow_r == pytest.approx(d.radius * 0.5 * d.scrub_moment() / d.track)


def test_load_model_scales_the_parts_not_the_payload() -> None:
    """The template's stand-in masses are scaled to the design's mass less its payload; the
    payload keeps its own mass where the template puts it. Scaling everything alike would
    shrink the chassis' yaw inertia as the payload grows."""
    g = _geometry("SkidSteerRobot")
    torque = dict.fromkeys(g.joint_speed, 1.0)
    bare = WheeledController(replace(g, mass_kg=1.0, joint_torque=torque)).drive
    loaded = WheeledController(
        replace(g, mass_kg=3.0, joint_torque=torque, params={"payload": 2.0})
    ).drive
    # the payload sits at the chassis' middle: it adds (almost) no yaw inertia
    assert loaded.yaw_inertia == pytest.approx(bare.yaw_inertia, rel=0.05)
    assert loaded.mass == 3.0


# --- calibration: a skid-steer's effective track measured on a run ---------------------------


def test_skid_steer_calibration_fits_the_measured_track_and_load(designs) -> None:
    """Synthetic measurements: wheels at known speeds, the chassis yawing at a known rate;
    the fit gives back ``r (q_r - q_l) / w`` and the load scale the droop implies."""
    c, _ = designs["SkidSteerRobot"]
    probes = c.calibration_probes()
    assert [name for name, _ in probes] == ["driving", "driving"]
    assert probes[0][1]["v"] == 0.0 and probes[1][1]["v"] > 0
    d, runs = c.drive, []
    for name, params in probes:
        traj = c.run(name, **params)
        v, w = traj.info["command"]
        t = np.linspace(0.0, traj.duration, 200)
        track = 1.3 * d.effective_track  # what "MuJoCo" needs
        left, right = (v - w * track / 2) / d.radius, (v + w * track / 2) / d.radius
        side = {n: left for n in d.left} | {n: right for n in d.right}
        q = np.column_stack([d.sign[n] * side[n] * t for n in traj.joints])
        yaw = w * t  # the commanded rate reached
        root = np.column_stack(
            [np.zeros((len(t), 3)), np.cos(yaw / 2), 0 * t, 0 * t, np.sin(yaw / 2)]
        )
        runs.append((traj, {"t": t, "q": q, "root": root}))
    cal = c.calibrate(runs)
    assert cal["effective_track_m"] == pytest.approx(1.3 * d.effective_track, rel=1e-3)
    assert cal["turn_load_scale"] > 0
    # a run that does not turn gives nothing to fit
    still = [
        (traj, s | {"root": np.tile([0, 0, 0, 1.0, 0, 0, 0], (len(s["t"]), 1))}) for traj, s in runs
    ]
    assert c.calibrate(still) == {}


def test_uncalibrated_skid_steer_under_turns_an_arc(designs) -> None:
    """The case built to fail: the same design with the Coulomb model's effective track (no
    ``calibration`` in its record) turns 0.89 of a w = 0.6 rad/s arc (0.91 of a 0.4 rad/s
    one since the tyres and jaws are the catalog's), and the verdict says so; calibrated
    (the fixture) it passes (test_skid_steer_follows_an_arc). Open loop: the plan's own
    figures; closed on the IMU's yaw rate (the skid-steer carries one) the heading is the
    planned one whatever the model's track (gaits.wheel_feedback)."""
    c, model = designs["SkidSteerRobot"]
    geometry = replace(c.geometry, calibration={})
    bare = WheeledController(geometry)
    assert bare.drive.effective_track < c.drive.effective_track
    traj = bare.run("driving", v=0.12, w=0.6, seconds=4.0)
    r = simulate(model, traj, feedback=False)
    assert "turn" in r.verdict
    assert r.heading_rad < 0.9 * traj.info["planned_pose"][2]
    closed = simulate(model, traj)
    assert "turn" not in closed.verdict
    assert closed.heading_rad == pytest.approx(traj.info["planned_pose"][2], rel=0.05)


def test_driving_plans_every_value_its_ranges_declare(designs) -> None:
    """The declared v and w ranges are what driving plans alone (the other 0) with its
    default ramp, the servos' droop under load included: the bounds plan, 1 % beyond them
    does not."""
    for robot in ("DifferentialDriveRobot", "SkidSteerRobot"):
        c = designs[robot][0]
        ps = {p.name: p for p in c.behaviors["driving"].params}
        base = {p: q.default for p, q in ps.items()} | {"v": 0.0, "w": 0.0}
        for name in ("v", "w"):
            for bound in (ps[name].low, ps[name].high):
                c._run("driving", base | {name: bound})
                with pytest.raises(ValueError):
                    c._run("driving", base | {name: 1.01 * bound})
