"""Humanoid behaviours (gaits/humanoid.py): leg IK, the reference gait (LIPM + ZMP), the
synthetic locomotion and its conversion maps, the controller, and MuJoCo acceptance on the
default HumanoidRobot design."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gaits.base import DesignGeometry
from gaits.humanoid import (
    GRIPPER_OPEN,
    HARMONICS,
    LEG_JOINTS,
    MAP_SIZES,
    REACH_SHOULDER,
    REFERENCE_SIZE,
    RUN,
    WALK,
    GaitPlan,
    HumanoidController,
    conversion_maps,
    fit_maps,
    leg_ik,
    leg_module_range,
    odometry,
    reference_gait,
    reference_template,
    stance_torques,
    synthesize,
)
from kinematics.dynamics import center_of_mass, external_force_at, forward_kinematics, rnea
from kinematics.model import GRAVITY as G
from kinematics.templates import DEFAULTS, TemplateParams, build

LEGS = tuple(f"{s}_{j}" for s in "lr" for j in LEG_JOINTS)


def _full(model, names, q):
    """(n, nq) model coordinates with q (n, len(names)) placed by name."""
    out = np.zeros((len(q), model.nq))
    index = {n: k for k, n in enumerate(model.q_names)}
    for k, n in enumerate(names):
        out[:, index[n]] = q[:, k]
    return out


def _ankles(template, names, q):
    """(2, n, 3) ankle positions (left, right) and (2, n, 3, 3) foot rotations in the trunk
    frame, by the model's forward kinematics."""
    model = template.model
    F = forward_kinematics(model, _full(model, names, np.atleast_2d(q)))
    feet = [model.body(f"{s}_ankle_roll_link") for s in "lr"]
    return np.array([F[:, b, :3, 3] for b in feet]), np.array([F[:, b, :3, :3] for b in feet])


def _geometry(lengths=None) -> DesignGeometry:
    return DesignGeometry(
        robot_type="HumanoidRobot",
        template="HumanoidRobot",
        lengths=dict(lengths or DEFAULTS["HumanoidRobot"]),
        modules=1,
        wheel_radius=0.03,
        params={},
        abilities=("walking", "balancing", "running"),
        joint_speed={},
    )


# --- leg IK ----------------------------------------------------------------------------------


@pytest.mark.parametrize("femur, tibia", [(0.09, 0.09), (0.088, 0.088), (0.07, 0.11)])
def test_leg_ik_round_trips_through_forward_kinematics(femur, tibia):
    tmpl = build("HumanoidRobot", TemplateParams(lengths={"femur": femur, "tibia": tibia}))
    hw = tmpl.lengths["hip_width"] / 2
    rng = np.random.default_rng(7)
    n = 200
    leg = femur + tibia
    # ankles within reach, in front of/behind and beside the hip, below it
    d = rng.uniform(abs(femur - tibia) + 0.02, 0.99 * leg, n)
    pitch = rng.uniform(-0.6, 0.6, n)
    roll = rng.uniform(-0.4, 0.4, n)
    target = np.stack(
        [-d * np.sin(pitch), d * np.cos(pitch) * np.sin(roll), -d * np.cos(pitch) * np.cos(roll)],
        axis=1,
    )
    q_leg = leg_ik(target, femur, tibia)
    assert q_leg.shape == (n, 6)
    assert np.all(q_leg[:, 0] == 0) and np.all(q_leg[:, 3] >= 0)  # no yaw, knee forward
    q = np.concatenate([q_leg, q_leg], axis=1)
    ankles, rotations = _ankles(tmpl, LEGS, q)
    for k, side in enumerate((1.0, -1.0)):
        hip = np.array([0.0, side * hw, 0.0])
        np.testing.assert_allclose(ankles[k] - hip, target, atol=1e-12)
        np.testing.assert_allclose(rotations[k], np.broadcast_to(np.eye(3), (n, 3, 3)), atol=1e-12)


def test_leg_ik_straight_leg_is_zero():
    np.testing.assert_allclose(leg_ik(np.array([0.0, 0.0, -0.18]), 0.09, 0.09), 0.0, atol=1e-7)


@pytest.mark.parametrize(
    "ankle", [(0.0, 0.0, -0.2), (0.19, 0.0, -0.01), (0.0, 0.0, 0.05), (0.0, 0.0, 0.0)]
)
def test_leg_ik_rejects_unreachable_ankles(ankle):
    with pytest.raises(ValueError):
        leg_ik(np.array(ankle), 0.09, 0.09)


def test_leg_ik_rejects_bad_shapes():
    with pytest.raises(ValueError, match="shape"):
        leg_ik(np.zeros((4, 2)), 0.09, 0.09)


# --- the reference gait ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def gait():
    return reference_gait(REFERENCE_SIZE, WALK, 1.0)


def test_reference_gait_com_is_the_inverted_pendulum_of_its_zmp(gait):
    n = len(gait.t)
    w = 2 * np.pi * np.fft.rfftfreq(n, gait.period / n)
    zc = float(gait.com[:, 2].mean())
    v = gait.step_length / WALK.step_period
    for axis in (0, 1):
        c = gait.com[:, axis] - (v * gait.t if axis == 0 else 0.0)  # the periodic part
        acc = np.fft.irfft(-(w**2) * np.fft.rfft(c), n)
        zmp = gait.zmp[:, axis] - (v * gait.t if axis == 0 else 0.0)
        np.testing.assert_allclose(c - zc / G * acc, zmp, atol=2e-3)


def test_reference_gait_zmp_stays_under_the_stance_foot(gait):
    T, d = WALK.step_period, WALK.double_support
    single_left = (gait.t >= d * T) & (gait.t < T)
    single_right = gait.t >= T + d * T
    for mask, k in ((single_left, 0), (single_right, 1)):
        offset = gait.zmp[mask] - gait.ankles[k, mask, :2]
        assert np.abs(offset[:, 0]).max() < 1e-9  # under the ankle
        hw = reference_template(REFERENCE_SIZE).lengths["hip_width"] / 2
        np.testing.assert_allclose(np.abs(offset[:, 1]), (1 - WALK.sway) * hw, atol=1e-9)


def test_reference_gait_joint_angles_put_the_feet_on_the_planned_path(gait):
    tmpl = reference_template(REFERENCE_SIZE)
    ankles, rotations = _ankles(tmpl, gait.joints, gait.q)
    for k in range(2):
        np.testing.assert_allclose(ankles[k], gait.ankles[k] - gait.pelvis, atol=1e-9)
    np.testing.assert_allclose(rotations, np.broadcast_to(np.eye(3), rotations.shape), atol=1e-9)
    # the multibody COM follows the pendulum's (pelvis placed by iteration)
    com = center_of_mass(tmpl.model, _full(tmpl.model, gait.joints, gait.q)) + gait.pelvis
    np.testing.assert_allclose(com[:, :2], gait.com[:, :2], atol=2e-4)
    # one foot at a time leaves the ground, by the planned lift
    lift = gait.ankles[:, :, 2] - gait.ankles[:, :, 2].min()
    assert np.isclose(lift.max(), WALK.lift * 2 * REFERENCE_SIZE, rtol=1e-3)
    assert not np.any((lift[0] > 1e-9) & (lift[1] > 1e-9))


def test_reference_gait_closes_over_a_stride(gait):
    assert gait.step_length == pytest.approx(WALK.step * 2 * REFERENCE_SIZE)
    assert gait.period == pytest.approx(2 * WALK.step_period)
    # the last sample leads into the first one as smoothly as any two samples follow
    steps = np.abs(np.diff(np.vstack([gait.q, gait.q[:1]]), axis=0))
    assert steps[-1].max() <= 1.01 * steps[:-1].max()
    # and the feet advance by two steps per stride, which the joint angles do not see
    advance = gait.ankles[0, -1, 0] - gait.ankles[0, 0, 0]  # the swing ends at 2T
    assert advance == pytest.approx(2 * gait.step_length, rel=1e-4)


def test_reference_gait_rejects_bad_arguments():
    with pytest.raises(ValueError):
        reference_gait(0.0)
    with pytest.raises(ValueError):
        reference_gait(0.09, WALK, -1.0)


# --- synthetic locomotion and conversion maps ------------------------------------------------


def test_synthetic_locomotion_keeps_a_few_components_per_joint(gait):
    syn = synthesize(gait)
    assert syn.harmonics.shape == (12, HARMONICS + 1)
    q, v = syn(gait.t)
    assert np.abs(q - gait.q).max() < 0.02  # a few components are enough
    coarse, _ = synthesize(gait, 3)(gait.t)
    assert np.abs(coarse - gait.q).max() > np.abs(q - gait.q).max()
    exact, _ = synthesize(gait, len(gait.t) // 2 - 1)(gait.t)  # all but the Nyquist one
    np.testing.assert_allclose(exact, gait.q, atol=1e-6)
    # velocities are the derivative of the positions
    dt = 1e-6
    q2, _ = syn(gait.t + dt)
    np.testing.assert_allclose((q2 - q) / dt, v, atol=1e-3)


@pytest.fixture(scope="module")
def maps():
    return conversion_maps("walking")


def test_maps_reproduce_the_reference_gaits_at_the_fitted_sizes(maps):
    assert maps.sizes == MAP_SIZES and maps.residual < 0.01
    for x in MAP_SIZES:
        for r in (0.0, 1.0):
            g = reference_gait(x, WALK, r)
            q, _ = maps.trajectory(x, r, g.t)
            assert np.abs(q - g.q).max() < 0.01, (x, r)


def test_maps_cover_every_printable_leg_module(maps):
    from adron.catalog import load_catalog

    passive = load_catalog().passive
    lo, hi = leg_module_range()
    assert (lo, hi) == (MAP_SIZES[0], MAP_SIZES[-1]) == (maps.sizes[0], maps.sizes[-1])
    assert lo <= passive.min_link_length_m and passive.max_link_length_m <= hi
    assert maps.covers(0.05) and not maps.covers(0.5 * lo) and not maps.covers(1.1 * hi)


@pytest.mark.parametrize(
    "x, r", [(0.0675, 0.25), (0.088, 1.0), (0.1125, 0.75), (0.1, 1.1), (0.045, 1.0), (0.18, 0.5)]
)
def test_maps_interpolate_between_the_fitted_sizes(maps, x, r):
    g = reference_gait(x, WALK, r)
    q, _ = maps.trajectory(x, r, g.t)
    assert np.abs(q - g.q).max() < 0.012


def test_map_scales_are_one_at_the_reference_and_linear_in_size(maps):
    s, sq = maps.scale(REFERENCE_SIZE, 1.0)
    big = maps.reference.amplitudes > 1e-3
    np.testing.assert_allclose(s[big], 1.0, atol=0.05)  # a least-squares fit of 20 gaits
    np.testing.assert_allclose(sq[big], 0.0, atol=0.05)
    a, b, c = (maps.scale(x, 0.8)[0] for x in (0.07, 0.09, 0.11))
    np.testing.assert_allclose(b - a, c - b, atol=1e-12)  # the paper's (a x + b) per step


def test_maps_are_deterministic(maps):
    again = fit_maps(WALK)
    assert np.array_equal(again.coef, maps.coef)
    assert np.array_equal(again.reference.amplitudes, maps.reference.amplitudes)


def test_unknown_gait_has_no_maps():
    with pytest.raises(ValueError, match="walking"):
        conversion_maps("hopping")


# --- the controller ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def controller():
    return HumanoidController(_geometry())


def _check_smooth_and_limited(controller, traj, speed=None):
    model = controller.template.model
    index = {n: k for k, n in enumerate(model.q_names)}
    assert traj.joints == controller.joints
    planned = traj.info.get("planned_positions", traj.positions)
    np.testing.assert_allclose(planned[0], 0.0, atol=1e-12)  # starts from q = 0
    # starting still (the servos' give may change a little as the crouch starts)
    still = 1e-9 if planned is traj.positions else 0.02
    np.testing.assert_allclose(traj.velocities[0], 0.0, atol=still)
    for k, name in enumerate(traj.joints):
        i = index[name]
        assert model.lower[i] <= traj.positions[:, k].min()
        assert traj.positions[:, k].max() <= model.upper[i]
    dt = np.diff(traj.times)
    q, v = traj.positions, traj.velocities
    # the velocities are the positions' derivative, and neither jumps
    central = (q[2:] - q[:-2]) / (dt[1:] + dt[:-1])[:, None]
    assert np.abs(central - v[1:-1]).max() < 0.05
    assert np.abs(np.diff(q, axis=0)).max() < 0.06  # rad per 10 ms
    assert (np.abs(np.diff(v, axis=0)) / dt[:, None]).max() < 150.0  # rad/s^2
    if speed is not None:  # the actuators' no-load speeds
        limit = np.array([speed[n] for n in traj.joints])
        assert np.all(np.abs(v).max(axis=0) <= 0.9 * limit)


def test_behaviours_and_their_parameters(controller):
    specs = controller.behaviors
    assert set(specs) == {"walking", "running", "balancing", "grasping"}
    # each realises its own ability: balancing only with the sensor that gives the ability
    assert {n: s.realises for n, s in specs.items()} == {n: n for n in specs}
    walk = {p.name: p for p in controller.behaviors["walking"].params}
    assert walk["step_length"].default == pytest.approx(WALK.step * 0.18, abs=1e-4)
    assert walk["direction"].choices == ("forward", "backward")


@pytest.mark.parametrize(
    "name, params",
    [
        ("walking", {"steps": 0}),
        ("walking", {"steps": "many"}),
        ("walking", {"step_length": -0.01}),
        ("walking", {"step_length": 1.0}),
        ("walking", {"direction": "sideways"}),
        ("walking", {"speed": 1}),
        ("running", {"steps": 0}),
        ("balancing", {"amount": 1.5}),
        ("balancing", {"period": 0.0}),
        ("flying", {}),
    ],
)
def test_bad_parameters_raise(controller, name, params):
    with pytest.raises(ValueError):
        controller.run(name, **params)


def _landings(controller, traj):
    """At each planned touchdown (by FK; a foot more than 3 mm above the other lifts):
    (which foot landed: +1 left, -1 right, how far it is in front of the other, m)."""
    ankles, _ = _ankles(controller.template, traj.joints, traj.positions)
    up = ankles[:, :, 2] - ankles[:, :, 2].min(axis=0) > 0.003  # (2, n)
    out = []
    for foot, sign in ((0, 1.0), (1, -1.0)):
        for k in np.flatnonzero(up[foot, :-1] & ~up[foot, 1:]):
            ahead = ankles[foot, k + 1, 0] - ankles[1 - foot, k + 1, 0]
            out.append((k, sign, ahead))
    out.sort()
    return np.array([(sign, ahead) for _, sign, ahead in out])


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_walking_takes_the_steps_it_promises(controller, direction):
    traj = controller.run("walking", steps=4, direction=direction)
    _check_smooth_and_limited(controller, traj)
    sign = 1.0 if direction == "forward" else -1.0
    s = traj.info["step_length_m"]
    assert traj.info["direction"] == (sign, 0.0)
    info = traj.info
    assert info["motion"] == "straight" and info["locomotion"] == "legged"
    assert info["body_length_m"] == pytest.approx(controller.leg)
    # the planned pose is the joints' own odometry: about the 5 steps, straight ahead
    dx, dy, dyaw = info["planned_pose"]
    assert dx == pytest.approx(sign * 5 * s, rel=0.1) and abs(dy) < 0.05 * s and dyaw == 0
    assert info["expected_distance_m"] == pytest.approx(abs(dx), rel=1e-3)
    landings = _landings(controller, traj)
    ahead = landings[:, 1]
    # stepping in place while the sway grows, a half step, 4 full steps, a half step
    stepping = np.abs(ahead) > 0.5 * s
    assert stepping.sum() == 5 and len(landings) >= 7
    np.testing.assert_allclose(ahead[stepping], sign * s, rtol=0.1)  # in the travel direction
    assert np.all(np.abs(ahead[~stepping]) < 0.1 * s)  # in place; the feet end side by side
    assert np.all(landings[1:, 0] != landings[:-1, 0])  # left and right alternate
    margin = traj.info["stability_margin_m"]
    assert margin.shape == traj.times.shape and margin.min() > -0.015


def test_walking_backward_plays_the_forward_gait_in_reverse(controller):
    fwd = controller.run("walking", steps=2)
    bwd = controller.run("walking", steps=2, direction="backward")
    assert fwd.duration == bwd.duration
    ankles_f, _ = _ankles(controller.template, fwd.joints, fwd.positions)
    ankles_b, _ = _ankles(controller.template, bwd.joints, bwd.positions)
    # mirror images in x, swapping which foot goes first
    sep_f = ankles_f[0, :, 0] - ankles_f[1, :, 0]
    sep_b = ankles_b[0, :, 0] - ankles_b[1, :, 0]
    assert sep_f.max() == pytest.approx(-sep_b.min(), rel=0.05)
    assert sep_f.min() == pytest.approx(-sep_b.max(), rel=0.05)


def test_running_is_faster_than_walking(controller):
    walk = controller.run("walking", steps=6)
    run = controller.run("running", steps=6)
    _check_smooth_and_limited(controller, run)
    v_walk = walk.info["step_length_m"] / walk.info["step_period_s"]
    v_run = run.info["step_length_m"] / run.info["step_period_s"]
    assert v_run > 1.5 * v_walk
    assert run.info["step_period_s"] == pytest.approx(RUN.period(controller.leg))


def test_balancing_keeps_the_feet_and_the_com_over_them(controller):
    traj = controller.run("balancing", shifts=2, amount=0.8)
    _check_smooth_and_limited(controller, traj)
    ankles, rotations = _ankles(controller.template, traj.joints, traj.positions)
    gap = ankles[0] - ankles[1]  # the feet do not move against each other
    np.testing.assert_allclose(gap, np.broadcast_to(gap[0], gap.shape), atol=1e-9)
    np.testing.assert_allclose(rotations, np.broadcast_to(np.eye(3), rotations.shape), atol=1e-9)
    sway = ankles[0, :, 1] - ankles[0, 0, 1]  # the pelvis over the feet, sideways
    hw = controller.template.lengths["hip_width"] / 2
    assert 0.6 * hw < np.abs(sway).max() <= 0.8 * hw + 1e-12
    assert traj.info["stability_margin_m"].min() > 0.005


def test_behaviours_are_deterministic(controller):
    a = controller.run("walking", steps=3, step_length=0.02)
    b = HumanoidController(_geometry()).run("walking", steps=3, step_length=0.02)
    assert np.array_equal(a.positions, b.positions) and a.csv() == b.csv()


def test_other_sizes_get_scaled_gaits():
    small = {k: 0.75 * v for k, v in DEFAULTS["HumanoidRobot"].items()}
    ctl = HumanoidController(_geometry(small))
    traj = ctl.run("walking", steps=2)
    _check_smooth_and_limited(ctl, traj)
    assert traj.info["leg_module_m"] == pytest.approx(0.0675)
    # the same Froude number: the step period scales with the square root of the leg
    assert traj.info["step_period_s"] == pytest.approx(WALK.step_period * np.sqrt(0.75))
    tiny = {k: 0.2 * v for k, v in DEFAULTS["HumanoidRobot"].items()}
    assert HumanoidController(_geometry(tiny)).run("balancing").duration > 0
    with pytest.raises(ValueError, match="outside the conversion maps"):  # never extrapolated
        HumanoidController(_geometry(tiny)).run("walking")


def test_grasping_reaches_closes_holds_and_keeps_the_com_over_the_feet(controller):
    traj = controller.run("grasping", hold=1.0)
    _check_smooth_and_limited(controller, traj)
    info = traj.info
    assert info["motion"] == "hold" and info["body_length_m"] == pytest.approx(controller.leg)
    col = {n: k for k, n in enumerate(traj.joints)}
    q = traj.positions
    for side in "lr":
        shoulder, grip = q[:, col[f"{side}_shoulder_pitch"]], q[:, col[f"{side}_gripper"]]
        reached = np.argmin(shoulder)
        assert shoulder[reached] == pytest.approx(REACH_SHOULDER)  # the arm forward
        assert grip.max() == pytest.approx(GRIPPER_OPEN)  # opened on the way
        assert grip[reached:].min() == pytest.approx(0.0, abs=1e-9)  # closed, and stays so
        assert grip[-1] == pytest.approx(0.0, abs=1e-9)
        assert shoulder[-1] == pytest.approx(0.0, abs=1e-9)  # the arms back down at the end
    # the pelvis moves back to keep the COM over the feet: the margin stays large
    assert info["stability_margin_m"].min() > 0.01
    assert abs(info["planned_pose"][0]) < 0.05 * controller.leg  # and back: it holds


def test_odometry_follows_the_stance_foot():
    tmpl = reference_template(REFERENCE_SIZE)
    traj = reference_gait(REFERENCE_SIZE, WALK, 1.0)
    moved = odometry(tmpl, traj.joints, traj.q)
    # one stride: the pelvis advances two steps (the gait's own pelvis path)
    np.testing.assert_allclose(moved[-1, 0], traj.pelvis[-1, 0] - traj.pelvis[0, 0], atol=2e-3)
    assert abs(moved[-1, 1]) < 2e-3


def test_gait_plan_changes_the_step_only_in_single_support():
    plan = GaitPlan.of(WALK, 3)
    T, d = WALK.step_period, WALK.double_support
    tau = np.linspace(0, plan.end, 5001)
    r = plan.ratio(tau, 1.0)
    for k in range(int(plan.end / T) + 1):  # double support k: both feet on the ground
        a = d * T / 2 + k * T + (1 - d) * T
        both = plan.ratio(np.linspace(a, a + d * T, 50), 1.0)
        assert np.ptp(both) < 1e-12
    assert plan.envelope(tau)[0] == 0 and plan.envelope(tau[-1:])[0] == pytest.approx(0, abs=1e-12)
    assert r.max() == pytest.approx(1.0)


# --- the servos' give: stance loads and lag ------------------------------------------------


def test_stance_torques_put_the_weight_on_the_feet_that_touch_the_ground(controller):
    tmpl = reference_template(REFERENCE_SIZE)
    model = tmpl.model
    foot = tmpl.feet[0]
    y = np.zeros(40)
    for _ in range(8):  # standing still, the pelvis moved until the COM is over the left sole
        legs = controller._stance(np.zeros(40), y)
        q = np.concatenate([legs, np.zeros((40, 6))], axis=1)
        Q = _full(model, controller.joints, q[:1])
        ankle = forward_kinematics(model, Q)[0, model.body(foot), :3, 3]
        y = y + (ankle[1] - center_of_mass(model, Q)[0, 1])
    tau = stance_torques(tmpl, controller.joints, q, 0.01)
    # as the weight under the COM on the left foot: RNEA with that force alone
    sole = forward_kinematics(model, Q)[0, model.body(foot), :3, 3] + tmpl.foot_points[0]
    com = center_of_mass(model, Q)[0]
    fext = np.zeros((len(model.bodies), 6))
    weight = np.array([0.0, 0.0, model.total_mass * G])
    fext[model.body(foot)] = external_force_at(
        model, Q[0], foot, np.array([com[0], com[1], sole[2]]), weight
    )
    want = rnea(model, Q[0], np.zeros(model.nv), np.zeros(model.nv), fext)
    index = {n: k for k, n in enumerate(model.q_names)}
    np.testing.assert_allclose(tau[20], want[[index[n] for n in controller.joints]], atol=1e-4)
    # the right foot, beside the COM, carries nothing: its leg holds only itself
    right = [controller.joints.index(n) for n in LEGS[6:]]
    alone = rnea(model, Q[0], np.zeros(model.nv), np.zeros(model.nv))
    np.testing.assert_allclose(tau[20, right], alone[[index[n] for n in LEGS[6:]]], atol=1e-4)
    # the left knee carries the robot (a case the right one must not match)
    knee = controller.joints.index("l_knee_pitch")
    assert abs(tau[20, knee]) > 5 * abs(tau[20, controller.joints.index("r_knee_pitch")])
    # standing evenly (COM midway), both feet carry half
    legs = controller._stance(np.zeros(40), np.zeros(40))
    q = np.concatenate([legs, np.zeros((40, 6))], axis=1)
    even = stance_torques(tmpl, controller.joints, q, 0.01)
    assert even[20, knee] == pytest.approx(even[20, controller.joints.index("r_knee_pitch")])


def test_stiffness_and_damping_add_the_servos_give_to_the_command():
    geometry = _geometry()
    plain = HumanoidController(geometry)
    names = plain.joints
    kp = {n: 4.0 + k for k, n in enumerate(names)}
    kd = {n: 0.05 for n in names}
    stiff = HumanoidController(geometry, stiffness=kp, damping=kd)
    a, b = plain.run("walking", steps=1), stiff.run("walking", steps=1)
    np.testing.assert_allclose(b.info["planned_positions"], a.positions)
    assert b.info["planned_pose"] == a.info["planned_pose"]  # what the joints command
    k = np.array([kp[n] for n in names])
    tau = stance_torques(stiff.masses, names, a.positions, a.times[1] - a.times[0])
    want = a.positions + (tau + 0.05 * a.velocities) / k
    model = plain.template.model
    index = {n: i for i, n in enumerate(model.q_names)}
    lo = np.array([model.lower[index[n]] for n in names])
    hi = np.array([model.upper[index[n]] for n in names])
    np.testing.assert_allclose(b.positions, np.clip(want, lo, hi), atol=1e-12)
    assert np.abs(b.positions - a.positions).max() > 1e-3
    with pytest.raises(ValueError, match="stiffness: no value for l_gripper"):
        HumanoidController(geometry, stiffness={n: 1.0 for n in names if n != "l_gripper"})
    with pytest.raises(ValueError, match="damping values"):
        HumanoidController(geometry, stiffness=kp, damping={n: -1.0 for n in names})


# --- MuJoCo acceptance on the default HumanoidRobot design -----------------------------------


@pytest.fixture(scope="module")
def design(kb, designer, tmp_path_factory):
    from adron.catalog import load_catalog
    from export.bundle import bundle_files, write_bundle
    from export.record import design_record
    from synth.reasoning.conceptual import Design, Request
    from synth.reasoning.solver import Query
    from synth.sizing.structure import design_structure
    from synth.verification.source import Bundle

    cand = next(
        c for c in designer.reasoner.solve(Query()).candidates if c.robot_type == "HumanoidRobot"
    )
    s = design_structure(kb, cand, load_catalog(), {})
    rec = design_record(
        Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
    )
    folder = tmp_path_factory.mktemp("humanoid") / "bundle"
    write_bundle(folder, bundle_files(rec, s, load_catalog(), with_payload=True, pictures=False))
    return DesignGeometry.from_record(rec), Bundle(folder=folder).model(), rec


def _verdict(design, name, compensated=True, **params):
    from synth.verification.runs import controller_for_model, figures, run_behavior

    geometry, model, record = design
    if not compensated:  # the open-loop walk of a biped without an IMU (no balance loop)
        geometry = dataclasses.replace(geometry, sensors=())
    ctl = controller_for_model(record, model) if compensated else HumanoidController(geometry)
    assert isinstance(ctl, HumanoidController)
    traj, result = run_behavior(model, ctl, name, params)
    _check_smooth_and_limited(ctl, traj, geometry.joint_speed)
    return figures(traj, result)


@pytest.mark.parametrize("name", ["walking", "running", "grasping", "balancing"])
def test_default_design_keeps_every_promise(design, name):
    fig = _verdict(design, name)
    assert fig["verdict"] == "ok", fig


def test_default_design_walks_too_far_when_the_servos_give(design):
    """The servos lag their references (velocity gain) and give under the stance loads:
    commanded the bare angles, the default design walks about 1.3 x its plan (its open-loop
    walk, without the IMU's balance loop)."""
    fig = _verdict(design, "walking", compensated=False)
    assert "distance" in fig["verdict"], fig
    assert fig["distance_m"] > 1.25 * fig["planned_distance_m"]


# --- sizing (synth.sizing.families.Humanoid) ------------------------------------------------------


def test_sizing_refuses_legs_outside_the_maps_naming_the_height_that_works():
    from adron.catalog import load_catalog
    from adron.errors import InfeasibleError
    from synth.sizing.families import HUMANOID, Humanoid

    catalog = load_catalog()
    lo, hi = leg_module_range()
    short = {k: f * 0.15 for k, f in HUMANOID.items()}
    short.update(femur=0.5 * lo, tibia=0.5 * lo)
    with pytest.raises(InfeasibleError, match=r"smallest height that works is [\d.]+ cm"):
        Humanoid._check_gait_range(0.15, short, catalog)
    long = dict(short, femur=1.2 * hi, tibia=1.2 * hi)
    with pytest.raises(InfeasibleError, match="largest height that works"):
        Humanoid._check_gait_range(1.2, long, catalog)
    ok = dict(short, femur=lo, tibia=lo)
    Humanoid._check_gait_range(0.2, ok, catalog)  # at the limit: accepted


def test_sizing_holds_the_centre_of_pressure_off_the_ankle():
    from adron.catalog import load_catalog
    from kinematics.dynamics import rnea
    from synth.sizing.families import ANKLE_COP_REACH, HUMANOID, Humanoid

    catalog = load_catalog()
    tmpl = build("HumanoidRobot", TemplateParams({k: f * 0.4 for k, f in HUMANOID.items()}))
    cases = Humanoid().load_cases(tmpl, {"height": 0.4, "payload": 0.0}, catalog)
    model = tmpl.model
    ankle = model.q_index[model.joint("l_ankle_pitch")]
    held = [c for c in cases if c.name.endswith("holding")]
    assert len(held) == 3
    tau = [abs(float(rnea(model, c.q, c.v, c.a, c.fext)[ankle])) for c in held]
    weight = model.total_mass * catalog.design.gravity_m_s2
    lever = ANKLE_COP_REACH * tmpl.lengths["foot"] / 2
    # the pressure under the COM loads the ankle little; at the toe or heel, weight x lever
    assert tau[0] < 0.2 * weight * lever
    assert min(tau[1:]) > 0.8 * weight * lever
    # the stance: the COM swayed over the stance (left) foot
    com = center_of_mass(model, held[0].q)
    left = forward_kinematics(model, held[0].q)[model.body(tmpl.feet[0]), :3, 3]
    hw = tmpl.lengths["hip_width"] / 2
    assert abs(com[1] - left[1]) < 0.5 * hw


def test_sizing_takes_each_joints_peak_load_of_the_gaits():
    from adron.catalog import load_catalog
    from synth.sizing.families import HUMANOID, Humanoid

    catalog = load_catalog()
    tmpl = build("HumanoidRobot", TemplateParams({k: f * 0.4 for k, f in HUMANOID.items()}))
    model = tmpl.model
    cases = Humanoid().load_cases(tmpl, {"height": 0.4, "payload": 0.0}, catalog)
    gait = [c for c in cases if c.name.startswith(("walking at", "running at"))]
    stance = [c for c in cases if c not in gait]
    assert gait and stance

    def peak(cs, joint):
        k = model.q_index[model.joint(joint)]
        return max(abs(float(rnea(model, c.q, c.v, c.a, c.fext)[k])) for c in cs)

    # the gaits' own peaks, by the controller's stance loads on the planned angles
    plans = Humanoid.gait_plans(tmpl)
    for _, t, joints, q, _ in plans:
        tau = np.abs(stance_torques(tmpl, joints, q, float(t[1] - t[0])))
        for j in ("l_hip_roll", "l_knee_pitch", "l_ankle_roll"):
            assert peak(gait, j) >= tau[:, joints.index(j)].max() - 1e-9
    # the walking stance alone misses the ankle roll's load while the weight moves between
    # the feet (the case the gait cases were added for: an SG90 ankle roll saturated)
    assert peak(gait, "l_ankle_roll") > 1.5 * peak(stance, "l_ankle_roll")


def test_sizing_holds_each_joints_fastest_instant_of_the_gaits():
    from adron.catalog import load_catalog
    from synth.sizing.families import HUMANOID, Humanoid

    catalog = load_catalog()
    tmpl = build("HumanoidRobot", TemplateParams({k: f * 0.2 for k, f in HUMANOID.items()}))
    holds = Humanoid().holds(tmpl, {"height": 0.2, "payload": 0.0}, catalog)
    fastest = {}
    for _, _, joints, _, v in Humanoid.gait_plans(tmpl):
        for k, j in enumerate(joints):
            fastest[j] = max(fastest.get(j, 0.0), float(np.abs(v[:, k]).max()))
    torque, speed, what = holds["l_knee_pitch"]
    assert speed == pytest.approx(fastest["l_knee_pitch"])
    assert "running" in what  # the faster gait
    assert speed > 4.0  # short legs swing fast (1 / sqrt(leg)): a slow servo fails it
    assert torque < 0.1  # the swinging knee carries its shank only
    assert "l_gripper" not in holds  # still in both gaits


def _stability_margin_one_by_one(tmpl, names, q, contact: float = 0.002) -> np.ndarray:
    """``stability_margin`` sample by sample with ``_support_margin``: the reference the
    batched one is tested against."""
    import gaits.humanoid as H

    com, soles, corners = H._soles(tmpl, names, q)
    out = np.empty(len(com))
    for i in range(len(com)):
        low = soles[:, i, 2].min()
        pts = [
            soles[k, i, :2] + corners for k in range(len(soles)) if soles[k, i, 2] <= low + contact
        ]
        out[i] = H._support_margin(com[i, :2], np.concatenate(pts))
    return out


def test_batched_stability_margin_equals_the_one_by_one_margin_to_the_bit():
    """The walking and turning gaits' samples (one foot, two feet, feet apart) and a case
    built to differ: a COM outside the support (negative margins) and a foot in the air."""
    import gaits.humanoid as H

    tmpl = H.reference_template(0.08)
    gait = H.reference_gait(0.08, H.WALK, 1.0, samples=96, template=tmpl)
    q = gait.q.copy()
    got = H.stability_margin(tmpl, gait.joints, q)
    want = _stability_margin_one_by_one(tmpl, gait.joints, q)
    assert np.array_equal(got, want)
    q[:, gait.joints.index("l_hip_roll")] += 0.6  # leans: some samples fall outside
    got = H.stability_margin(tmpl, gait.joints, q)
    want = _stability_margin_one_by_one(tmpl, gait.joints, q)
    assert np.array_equal(got, want) and got.min() < 0 < got.max()
    # the points of one sample: a square and a point outside it, then two coincident feet
    pts = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 0], [0, 0], [2, 0], [0, 2]]], float)
    valid = np.ones((2, 4), dtype=bool)
    com = np.array([[0.25, 0.5], [3.0, 3.0]])
    got = H._support_margins(pts, valid, com)
    assert got[0] == H._support_margin(com[0], pts[0]) == 0.25
    assert got[1] == H._support_margin(com[1], pts[1]) < 0


def test_conversion_maps_come_back_from_the_disk_cache_bit_for_bit(tmp_path, monkeypatch):
    """A second process reads the maps the first fitted; a damaged file is fitted again."""
    import gaits.humanoid as H

    monkeypatch.setenv(H.CACHE_ENV, str(tmp_path))
    fitted = H.fit_maps(H.WALK)
    path = H._maps_file(H.WALK)
    assert path is not None and path.parent == tmp_path
    H._write_maps(path, fitted)
    again = H._read_maps(path, H.WALK)
    assert again is not None
    for a, b in ((fitted, again), (fitted.reference, again.reference)):
        for k, v in vars(a).items():
            w = getattr(b, k)
            if isinstance(v, np.ndarray):  # the layout too: it decides the sums' order
                assert v.dtype == w.dtype and v.strides == w.strides, k
                assert np.array_equal(v, w), k
            elif k != "reference":
                assert v == w, k
    x, r, t = 0.07, 0.8, np.linspace(0.0, 1.0, 50)
    assert np.array_equal(fitted.trajectory(x, r, t)[0], again.trajectory(x, r, t)[0])
    assert np.array_equal(fitted.components(x, t, t)[1], again.components(x, t, t)[1])
    path.write_bytes(b"not a zip")
    assert H._read_maps(path, H.WALK) is None
    monkeypatch.setenv(H.CACHE_ENV, "")  # no cache
    assert H._maps_file(H.WALK) is None


def test_load_cases_like_holds_the_gait_instants_as_the_masses_move():
    """The torque model's finite steps compare one case at two sets of masses: re-picking
    each joint's peak instant would pair different instants (torques jumping by most of a
    N m: a sensitivity of tens of N m per kg); the held instants give torques linear in
    the masses."""
    from adron.catalog import load_catalog
    from synth.sizing.families import HUMANOID, Humanoid

    catalog = load_catalog()
    p = {"height": 0.4, "payload": 0.0}
    lengths = {k: f * 0.4 for k, f in HUMANOID.items()}
    fam = Humanoid()

    def tmpl(group: str, extra: float):
        return build("HumanoidRobot", TemplateParams(lengths, actuator_mass={group: 0.055 + extra}))

    def torques(t, cases):
        m = t.model
        return np.array([rnea(m, c.q, c.v, c.a, c.fext) for c in cases])

    base = fam.load_cases(tmpl("knee_pitch", 0.0), p, catalog)
    repicked = 0
    for group in ("knee_pitch", "shoulder_pitch", "hip_pitch"):
        steps = [tmpl(group, s) for s in (0.0, 0.03, 0.06)]
        held = [fam.load_cases_like(t, p, catalog, base) for t in steps]
        assert all([c.name for c in h] == [c.name for c in base] for h in held)
        tau = [torques(t, h) for t, h in zip(steps, held, strict=True)]
        assert np.abs(tau[2] - 2 * tau[1] + tau[0]).max() < 2e-3  # linear in the mass
        picked = fam.load_cases(steps[2], p, catalog)
        repicked += [c.name for c in picked] != [c.name for c in base]
    assert repicked  # the masses do move the peaks: the case guarded against occurs


def test_a_family_that_picks_its_cases_by_the_masses_must_hold_them():
    from adron.catalog import load_catalog
    from synth.sizing.families import LoadCase, Multipeds

    class ByMass(Multipeds):
        def load_cases(self, tmpl, p, catalog):
            z = np.zeros(tmpl.model.nv)
            return [LoadCase(f"heaviest {tmpl.model.total_mass:.3f}", z, z, z)]

    catalog = load_catalog()
    light = build("QuadrupedRobot", TemplateParams())
    heavy = build("QuadrupedRobot", TemplateParams(actuator_mass={"leg_femur": 0.2}))
    fam = ByMass()
    like = fam.load_cases(light, {}, catalog)
    assert fam.load_cases_like(light, {}, catalog, like)[0].name == like[0].name
    with pytest.raises(RuntimeError, match="override load_cases_like"):
        fam.load_cases_like(heavy, {}, catalog, like)
