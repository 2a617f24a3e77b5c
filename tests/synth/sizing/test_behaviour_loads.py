"""Sizing from the behaviours: inverse dynamics with contact forces along every trajectory a
design runs (``synth.sizing.behaviour_loads``), checked against MuJoCo and on built cases."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from export.record import to_json
from gaits.base import Trajectory
from kinematics.dynamics import center_of_mass, rnea
from kinematics.templates import build
from synth.sizing import behaviour_loads as bl
from synth.sizing.families import support_shares
from synth.sizing.structure import (
    StructureDesigner,
    alternatives,
    design_structure,
    operating_points,
    upper_hull,
)

#: MuJoCo's peak |actuator force| of a leg's femur and tibia along the default quadruped's
#: walk, over the torque predicted here: between these. The inverse dynamics matches the
#: simulated stance torques closely (the femur's to a few per cent); the position servos
#: add transients at touchdown and lift-off that it does not see (up to about 2x; 2.2-2.6x
#: for the tibias since the crawl's sway keeps a 25 mm margin: they carry 0.17-0.19 N m
#: and get MG996R servos, whose stiffer gain peaks at 0.43-0.44 N m at touchdown).
SIM_OVER_PREDICTED = (0.7, 2.8)


@pytest.fixture(scope="module")
def quadruped(kb, bases, catalog):
    return design_structure(kb, bases["QuadrupedRobot"], catalog, {})


def test_the_quadruped_tibia_is_sized_for_its_walk(quadruped) -> None:
    """The zero-pose hand case asked 0.001-0.003 N m of the tibias (SG90s that stalled in
    MuJoCo); the walk asks a realistic torque, named by its trajectory sample."""
    tibia = next(j for j in quadruped.joints if j.name == "lf_tibia")
    assert tibia.required_torque_Nm > 0.05  # the hand case gave 0.003
    assert re.fullmatch(r"(walking|turning|running)@\d+\.\d\ds", tibia.load_case)
    assert tibia.usable_torque_Nm >= tibia.required_torque_Nm


def test_predicted_torques_agree_with_mujoco(cli, tmp_path) -> None:
    from synth.verification.runs import controller_for_model, run_behavior
    from synth.verification.source import Bundle

    folder = tmp_path / "quad"
    run = cli(
        "design",
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=no",
        "--no-input",
        "--no-verify",
        "--out",
        str(folder),
    )
    assert run.code == 0, run.err
    rec = json.loads((folder / "design.json").read_text())
    model = Bundle(folder=folder).model()
    _, res = run_behavior(model, controller_for_model(rec, model), "walking")
    assert not res.fell
    assert res.saturated_fraction <= 0.05
    force = np.abs(res.series["force"]).max(axis=0)
    need = {j["name"]: j["required_torque_Nm"] for j in rec["joints"]}
    lo, hi = SIM_OVER_PREDICTED
    for k in range(model.nu):
        name = model.actuator(k).name
        if name.endswith(("femur", "tibia")):
            assert lo <= force[k] / need[name] <= hi, (name, force[k], need[name])


def _quadruped_template():
    return build("QuadrupedRobot")


def _standing(tmpl, lifted: tuple[str, ...]) -> Trajectory:
    """Three samples of the quadruped standing still, the legs ``lifted`` (femur up)."""
    m = tmpl.model
    q = np.zeros(m.nv)
    for leg in lifted:
        q[m.q_names.index(f"{leg}_femur")] = -0.5
    Q = np.tile(q, (3, 1))
    return Trajectory("standing", np.array([0.0, 0.01, 0.02]), m.q_names, Q, np.zeros_like(Q))


def test_weight_on_one_leg_loads_it_more_than_the_static_share_over_all() -> None:
    """A case built to fail a sizing that shares the weight over every foot: a sample on
    one leg must load it with the whole weight."""
    tmpl = _quadruped_template()
    m = tmpl.model
    weight = m.total_mass * 9.81
    all_feet = bl.behaviour_case(tmpl, bl.motion(tmpl, _standing(tmpl, ())))
    one_foot = bl.behaviour_case(tmpl, bl.motion(tmpl, _standing(tmpl, ("lh", "rf", "rh"))))
    k = m.q_names.index("lf_femur")
    tau_all = np.abs(bl.analyse(tmpl, all_feet)[0][0, k])
    tau_one = np.abs(bl.analyse(tmpl, one_foot)[0][0, k])
    assert tau_one > 3 * tau_all
    foot = m.body(next(f for f in tmpl.feet if f.startswith("lf")))
    assert one_foot.fext[0, foot, 2] == pytest.approx(weight, rel=1e-9)  # foot frame: z up
    # standing on all four, each foot carries its static share and the weld nothing
    W = bl.analyse(tmpl, all_feet)[1]
    assert np.abs(W[:, 0]).max() < 1e-9
    com = center_of_mass(m, np.zeros(m.nv))
    motion = bl.motion(tmpl, _standing(tmpl, ()))
    shares = support_shares(motion.points[0, :, :2], com[:2])
    forces = np.array([all_feet.fext[0, m.body(f), 2] for f in tmpl.feet])
    assert np.allclose(forces / weight, shares, atol=1e-9)


def test_batched_support_shares_agree_with_the_single_one() -> None:
    rng = np.random.default_rng(1)
    points = rng.uniform(-0.1, 0.1, (50, 5, 2))
    mask = rng.uniform(size=(50, 5)) < 0.8
    mask[:, :3] = True
    cop = points[:, :3].mean(axis=1)  # inside the triangle of the first three
    got = bl.support_shares_batch(points, mask, cop)
    for b in range(50):
        want = np.zeros(5)
        want[mask[b]] = support_shares(points[b][mask[b]], cop[b])
        assert np.allclose(got[b], want, atol=1e-9)


def test_joint_torques_from_the_wrenches_are_rnea(quadruped) -> None:
    tmpl = quadruped.template
    geometry = _geometry_of(quadruped)
    (mo, *_), _ = bl.motions_for(geometry, tmpl)
    case = bl.behaviour_case(tmpl, mo)
    tau, _ = bl.analyse(tmpl, case)
    assert np.allclose(tau, rnea(tmpl.model, case.q, case.v, case.a, case.fext), atol=1e-9)


def _geometry_of(s):
    return bl.design_geometry(
        s.robot_type,
        s.template.robot_type,
        s.lengths,
        1,
        s.wheel_radius_m,
        s.params,
        ("running", "walking"),
        {j.name: j.no_load_speed_rad_s for j in s.joints},
    )


def test_speeds_come_from_the_trajectories(quadruped) -> None:
    """The required joint speed is the trajectory's peak when it exceeds the hand estimate
    (the walk is paced by the chosen actuators' speeds)."""
    trajs, notes = bl.behaviour_trajectories(_geometry_of(quadruped))
    assert not notes and set(trajs) >= {"walking"}
    for j in quadruped.joints:
        peak = max(
            float(np.abs(t.velocities[:, t.joints.index(j.name)]).max()) for t in trajs.values()
        )
        assert j.required_speed_rad_s >= peak - 1e-9
    femur = next(j for j in quadruped.joints if j.name == "lf_femur")
    assert femur.required_speed_rad_s == pytest.approx(
        max(np.abs(t.velocities[:, t.joints.index("lf_femur")]).max() for t in trajs.values())
    )


def test_operating_points_keep_what_can_bind_a_servo_line() -> None:
    """A servo whose speed falls linearly with torque meets every sample when it meets the
    hull points; the corner (largest torque at the largest speed) is not asked."""
    rng = np.random.default_rng(3)
    t, w = rng.uniform(0, 1, 400), rng.uniform(0, 5, 400)
    hull = operating_points(t, w)
    assert len(hull) < 20 and (float(t.max()), float(w[t.argmax()])) in hull
    for _ in range(200):
        ts, w0 = rng.uniform(0.5, 3), rng.uniform(3, 20)
        ok_hull = all(w0 * (1 - a / ts) >= b for a, b in hull)
        ok_all = bool(np.all(w0 * (1 - t / ts) >= w))
        assert ok_hull == ok_all
    assert upper_hull([(1.0, 0.0), (0.0, 1.0), (0.4, 0.4)]) == [(0.0, 1.0), (1.0, 0.0)]


def test_designs_are_deterministic_and_the_cache_changes_nothing(kb, bases, catalog) -> None:
    def record(c):
        s = design_structure(kb, c, catalog, {})
        return to_json({"joints": [vars(j) for j in s.joints], "links": [vars(x) for x in s.links]})

    c = bases["HexapodRobot"]
    first = record(c)
    bl._TRAJECTORIES.clear()
    assert record(c) == first


def test_alternatives_check_the_behaviours_too(kb, bases, catalog) -> None:
    """Every assignment that ``enumerate`` counts meets the behaviours' torques."""
    sd = StructureDesigner(kb, bases["QuadrupedRobot"], catalog, {})
    s = sd.run()
    alts = alternatives(sd, 50)
    need = {j.name: j.required_torque_Nm for j in s.joints}
    stall = {a.model: a.stall_torque_Nm for a in catalog.actuators}
    sf = catalog.design.torque_safety_factor
    for alt in alts.ranked:
        for joint, model in alt.models:
            assert stall[model] / sf >= need[joint] * 0.95, (joint, model)


def test_manipulators_and_wheels_are_analysed_snakes_left_to_their_family(kb, bases, catalog):
    sd = StructureDesigner(kb, bases["Manipulator3DOF"], catalog, {})
    sd.run()
    cases = sd._behaviour_cases(sd.analysis, sd.converged[0], sd.actuator_sets)
    assert {c.behaviour for c in cases} == {
        "grasping",
        "move_to_pose",
        "pick-and-place",
        "positioning",
    }
    assert all(not c.fext.any() for c in cases)  # bolted down: no contact forces
    cart = build("DifferentialDriveRobot")
    kinds = [c.kind for c in bl.contacts(cart)]
    assert kinds == ["wheel", "wheel", "caster"]
    snake = build("SnakeRobot")
    assert not bl.contacts(snake) and not bl.fixed_base(snake)
    s = design_structure(kb, bases["SnakeRobot"], catalog, {})
    assert not any("@" in j.load_case for j in s.joints)
