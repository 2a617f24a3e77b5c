"""Multiped gaits (gaits/hexapod.py, gaits/legged.py): leg kinematics against the template's forward
kinematics, gait structure, the static stability margin, the generated trajectories'
properties, bad parameters, and the issue's MuJoCo acceptance on the default hexapod and
quadruped designs."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from gaits.base import DesignGeometry, Trajectory
from gaits.hexapod import (
    CRAWL_DUTY,
    LEG_CLEARANCE,
    MIN_CRAWL_DUTY,
    MIN_MARGIN,
    SWAY_MAX,
    gait_pattern,
    leg_fk,
    leg_ik,
    legs_of,
    stance_inset,
    support_margin,
)
from gaits.legged import (
    MIN_PACE,
    RUN_SPEED_FACTOR,
    SPEED_MARGIN,
    STEP_MARGIN,
    LeggedController,
)
from kinematics.dynamics import center_of_mass, forward_kinematics
from kinematics.templates import build, default_lengths

TYPES = ("HexapodRobot", "QuadrupedRobot")


@dataclass
class Designed:
    geometry: DesignGeometry
    template: object  # the sized template (design masses)
    folder: object

    def controller(self) -> LeggedController:
        return LeggedController(self.geometry, template=self.template)

    def model(self):
        from synth.verification.source import Bundle

        return Bundle(folder=self.folder).model()


@pytest.fixture(scope="module")
def designs(kb, designer, tmp_path_factory) -> dict[str, Designed]:
    """The default hexapod and quadruped designs, with their bundles."""
    from adron.catalog import load_catalog
    from export.bundle import bundle_files, write_bundle
    from export.record import design_record
    from synth.reasoning.conceptual import Design, Request
    from synth.reasoning.solver import Query
    from synth.sizing.structure import design_structure

    catalog = load_catalog()
    cands = designer.reasoner.solve(Query()).candidates
    out = {}
    for rt in TYPES:
        cand = next(c for c in cands if c.robot_type == rt)
        s = design_structure(kb, cand, catalog, {})
        rec = design_record(
            Design("designed", Request(), (cand,), cand, "only candidate"), designer.short, s
        )
        folder = tmp_path_factory.mktemp(rt) / "bundle"
        write_bundle(folder, bundle_files(rec, s, catalog, with_payload=True, pictures=False))
        out[rt] = Designed(DesignGeometry.from_record(rec), s.template, folder)
    return out


@pytest.fixture(scope="module")
def walks(designs) -> dict[tuple[str, str], Trajectory]:
    """Two cycles of every gait of both default designs."""
    out = {}
    for rt in TYPES:
        c = designs[rt].controller()
        for gait in c.gaits:
            out[rt, gait] = c.run("walking", gait=gait, steps=2)
    return out


def _geometry(rt: str, **params: float) -> DesignGeometry:
    """A design of the template's default lengths (no record, no actuator speeds)."""
    return DesignGeometry(
        rt,
        rt,
        default_lengths(rt),
        1,
        0.03,
        {"obstacle_height": 0.03, "speed": 0.05, **params},
        (),
        {},
    )


def _feet_trunk(tmpl, legs, q: np.ndarray) -> np.ndarray:
    """Feet (N, legs, 3) in the trunk frame by the template's forward kinematics."""
    T = forward_kinematics(tmpl.model, q)
    out = []
    for leg in legs:
        b = tmpl.model.body(leg.foot_body)
        k = tmpl.feet.index(leg.foot_body)
        out.append(T[:, b, :3, :3] @ tmpl.foot_points[k] + T[:, b, :3, 3])
    return np.stack(out, axis=1)


def _legs_q(tmpl, leg, q: np.ndarray) -> np.ndarray:
    m = tmpl.model
    return q[:, [m.q_index[m.joint(j)] for j in leg.joints]]


# --- leg kinematics --------------------------------------------------------------------------


@pytest.mark.parametrize("rt", TYPES)
def test_leg_fk_matches_template_and_ik_round_trips(rt, designs):
    rng = np.random.default_rng(7)
    for tmpl in (build(rt), designs[rt].template):
        legs = legs_of(tmpl)
        assert len(legs) == tmpl.legs
        n = 200
        q = np.zeros((n, tmpl.model.nv))
        for leg in legs:
            lo, hi = leg.lower.copy(), leg.upper.copy()
            hi[2], lo[2] = min(hi[2], 1.5), max(lo[2], -1.5)  # the knee-up branch
            qs = rng.uniform(lo, hi, size=(n, 3))
            m = tmpl.model
            for j, name in enumerate(leg.joints):
                q[:, m.q_index[m.joint(name)]] = qs[:, j]
        feet = _feet_trunk(tmpl, legs, q)
        for k, leg in enumerate(legs):
            qk = _legs_q(tmpl, leg, q)
            np.testing.assert_allclose(leg_fk(leg, qk), feet[:, k], atol=1e-12)
            # the inverse covers feet outward of the coxa axis (r > 0)
            d = feet[:, k, :2] - leg.mount[:2]
            radial = np.column_stack([np.cos(leg.yaw + qk[:, 0]), np.sin(leg.yaw + qk[:, 0])])
            out = np.einsum("ij,ij->i", d, radial) > 1e-3
            assert out.sum() > n / 2
            np.testing.assert_allclose(leg_ik(leg, feet[out, k]), qk[out], atol=1e-9)


def test_leg_geometry_read_from_the_template(designs):
    tmpl = designs["HexapodRobot"].template
    L = tmpl.lengths
    legs = {leg.name: leg for leg in legs_of(tmpl)}
    assert set(legs) == {"lf", "lm", "lh", "rf", "rm", "rh"}
    lf = legs["lf"]
    np.testing.assert_allclose(lf.mount, (L["La1"] / 2, L["La2"] / 2, 0), atol=1e-12)
    assert lf.yaw == pytest.approx(math.pi / 2)
    assert legs["rh"].yaw == pytest.approx(-math.pi / 2)
    assert (lf.coxa, lf.femur, lf.tibia) == pytest.approx((L["coxa"], L["femur"], L["tibia"]))
    # zero pose: femur horizontal, tibia vertical, foot straight out and tibia below
    np.testing.assert_allclose(
        lf.neutral, (L["La1"] / 2, L["La2"] / 2 + L["coxa"] + L["femur"], -L["tibia"]), atol=1e-12
    )


def test_leg_ik_out_of_reach_raises():
    leg = legs_of(build("HexapodRobot"))[0]
    with pytest.raises(ValueError, match="out of reach"):
        leg_ik(leg, leg.mount + (0.0, 1.0, 0.0))


def test_legs_of_rejects_non_legged_templates():
    with pytest.raises(ValueError, match="not a legged robot"):
        legs_of(build("Manipulator3DOF"))


# --- support polygon ---------------------------------------------------------------------------


def test_support_margin_geometry():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    assert support_margin(square, (0.5, 0.5)) == pytest.approx(0.5)
    assert support_margin(square, (0.9, 0.5)) == pytest.approx(0.1)
    assert support_margin(square, (1.2, 0.5)) == pytest.approx(-0.2)
    tri = np.array([[0, 0], [2, 0], [0, 2]])
    assert support_margin(tri, (0.5, 0.5)) == pytest.approx(0.5)
    assert support_margin(tri[:2], (1.0, 0.3)) == pytest.approx(-0.3)  # two feet: unstable
    assert support_margin(tri[:1], (0.0, 0.4)) == pytest.approx(-0.4)


# --- gaits ------------------------------------------------------------------------------------


def test_gait_patterns():
    legs = legs_of(build("HexapodRobot"))
    tripod = gait_pattern("tripod", legs)
    assert tripod.duty == 0.5
    groups = {p: {n for n, q in tripod.phases.items() if q == p} for p in (0.0, 0.5)}
    assert sorted(map(sorted, groups.values())) == [["lf", "lh", "rm"], ["lm", "rf", "rh"]]
    assert gait_pattern("wave", legs).duty == pytest.approx(5 / 6)
    assert sorted(gait_pattern("wave", legs).phases.values()) == pytest.approx(
        [k / 6 for k in range(6)]
    )
    assert gait_pattern("ripple", legs).duty == pytest.approx(2 / 3)
    crawl = gait_pattern("crawl", legs_of(build("QuadrupedRobot")))
    assert crawl.duty >= 0.75
    # forward crawl: a hind leg, then the front leg of its side, then the other side
    order = sorted(crawl.phases, key=crawl.phases.get)
    assert order == ["lh", "lf", "rh", "rf"]
    back = gait_pattern("crawl", legs_of(build("QuadrupedRobot")), math.pi)
    assert sorted(back.phases, key=back.phases.get) == ["rf", "rh", "lf", "lh"]
    with pytest.raises(ValueError, match="crawl"):
        gait_pattern("tripod", legs_of(build("QuadrupedRobot")))
    quad = legs_of(build("QuadrupedRobot"))
    assert gait_pattern("crawl", quad, duty=MIN_CRAWL_DUTY).duty == MIN_CRAWL_DUTY
    for bad in (0.75, CRAWL_DUTY + 0.01):
        with pytest.raises(ValueError, match="duty"):
            gait_pattern("crawl", quad, duty=bad)
    with pytest.raises(ValueError, match="duty"):
        gait_pattern("tripod", legs, duty=0.6)


@pytest.mark.parametrize(
    ("rt", "gait", "most"),
    [
        ("HexapodRobot", "tripod", 3),
        ("HexapodRobot", "ripple", 2),
        ("HexapodRobot", "wave", 1),
        ("QuadrupedRobot", "crawl", 1),
    ],
)
def test_legs_in_swing(rt, gait, most, walks):
    info = walks[rt, gait].info
    swing = ~info["stance"]
    assert swing.sum(axis=1).max() == most
    assert info["duty"] >= (0.75 if gait in ("crawl", "wave") else 0.5)
    legs = info["legs"]
    if gait == "tripod":  # the legs of a tripod swing together
        for group in (("lf", "rm", "lh"), ("rf", "lm", "rh")):
            cols = swing[:, [legs.index(g) for g in group]]
            assert np.all(cols.all(axis=1) == cols.any(axis=1))
    if gait == "ripple":  # never two legs of one side
        for side in "lr":
            cols = swing[:, [k for k, n in enumerate(legs) if n[0] == side]]
            assert cols.sum(axis=1).max() == 1


# --- generated trajectories ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("rt", "gait"),
    [
        ("HexapodRobot", "tripod"),
        ("HexapodRobot", "ripple"),
        ("HexapodRobot", "wave"),
        ("QuadrupedRobot", "crawl"),
    ],
)
def test_walking_trajectory_properties(rt, gait, walks, designs):
    traj = walks[rt, gait]
    d = designs[rt]
    tmpl = d.template
    legs = legs_of(tmpl)
    info = traj.info
    q, t = traj.positions, traj.times
    m = tmpl.model
    assert traj.joints == tuple(m.joints[i].name for i in m.q_joints)
    # within the joint limits and the actuators' speeds
    assert np.all(q >= m.lower) and np.all(q <= m.upper)
    speeds = np.array([d.geometry.joint_speed[n] for n in traj.joints])
    assert np.all(np.abs(traj.velocities) <= SPEED_MARGIN * speeds + 1e-9)
    # smooth: continuous positions and velocities, starting and ending standing at q = 0
    dt = np.diff(t)[0]
    assert np.abs(np.diff(q, axis=0)).max() < 10 * dt
    assert np.abs(np.diff(traj.velocities, axis=0)).max() < 50 * dt
    np.testing.assert_allclose(q[0], 0, atol=1e-9)
    np.testing.assert_allclose(q[-1], 0, atol=1e-6)
    # statically stable at every sample
    margin = np.asarray(info["stability_margin_m"])
    assert margin.shape == t.shape
    assert margin.min() >= MIN_MARGIN > 0
    assert info["min_stability_margin_m"] == pytest.approx(margin.min())
    # the feet: stance on the ground and fixed in the world (the stance foot moves back at
    # the trunk's speed), swing above the obstacle, neighbours apart
    feet = _feet_trunk(tmpl, legs, q)
    stance = info["stance"]
    height = info["stance_height_m"]
    np.testing.assert_allclose(feet[..., 2][stance], -height, atol=1e-9)
    body = info["body_path"]
    c, s = np.cos(body[:, 2]), np.sin(body[:, 2])
    world_x = body[:, None, 0] + c[:, None] * feet[..., 0] - s[:, None] * feet[..., 1]
    world_y = body[:, None, 1] + s[:, None] * feet[..., 0] + c[:, None] * feet[..., 1]
    both = stance[1:] & stance[:-1]
    assert np.abs(np.diff(world_x, axis=0)[both]).max() < 1e-6
    assert np.abs(np.diff(world_y, axis=0)[both]).max() < 1e-6
    obstacle = d.geometry.params["obstacle_height"]
    lift = feet[..., 2] + height
    assert info["step_height_m"] >= obstacle + STEP_MARGIN
    assert lift.max() == pytest.approx(info["step_height_m"], abs=1e-9)
    _check_swings_clear(world_x, world_y, lift, stance, obstacle)
    gaps = np.linalg.norm(feet[:, :, None, :2] - feet[:, None, :, :2], axis=3)
    gaps[:, np.arange(len(legs)), np.arange(len(legs))] = np.inf
    assert gaps.min() >= LEG_CLEARANCE
    # the trunk clears the obstacle standing, and moved forward
    assert height - 0.015 >= obstacle
    assert info["direction"] == (1.0, 0.0)
    assert body[-1, 0] == pytest.approx(info["planned_distance_m"], rel=1e-6)
    assert abs(body[-1, 1]) < 1e-9


def _check_swings_clear(wx, wy, lift, stance, obstacle):
    """Every swing lifts the foot above the obstacle for at least 90 % of its way."""
    for k in range(stance.shape[1]):
        swing = ~stance[:, k]
        edges = np.flatnonzero(np.diff(swing.astype(int)))
        for a, b in zip(edges[::2] + 1, edges[1::2] + 1, strict=False):
            x, y = wx[a - 1 : b + 1, k], wy[a - 1 : b + 1, k]
            way = np.hypot(x - x[0], y - y[0])
            low = lift[a - 1 : b + 1, k] < obstacle
            rising = way[low & (way < way[-1] / 2)].max(initial=0)
            falling = way[-1] - way[low & (way >= way[-1] / 2)].min(initial=way[-1])
            assert rising + falling <= 0.1 * way[-1] + 1e-9


def test_stability_margin_is_the_com_distance_to_the_support_polygon(walks, designs):
    traj = walks["QuadrupedRobot", "crawl"]
    tmpl = designs["QuadrupedRobot"].template
    legs = legs_of(tmpl)
    idx = np.linspace(0, len(traj.times) - 1, 40).astype(int)
    q = traj.positions[idx]
    feet = _feet_trunk(tmpl, legs, q)
    com = center_of_mass(tmpl.model, q)
    for j, i in enumerate(idx):
        pts = feet[j, traj.info["stance"][i], :2]
        hull = ConvexHull(pts)
        # hull.equations: n.x + c <= 0 inside, n outward unit
        dist = -(hull.equations[:, :2] @ com[j, :2] + hull.equations[:, 2])
        assert traj.info["stability_margin_m"][i] == pytest.approx(dist.min(), abs=1e-9)


def test_default_masses_without_the_sized_template(designs):
    c = LeggedController(designs["HexapodRobot"].geometry)
    assert c.com_masses == "template defaults"
    assert designs["HexapodRobot"].controller().com_masses == "design"
    traj = c.run("walking", steps=1)
    assert traj.info["com_masses"] == "template defaults"
    assert np.min(traj.info["stability_margin_m"]) >= MIN_MARGIN
    with pytest.raises(ValueError, match="not the design's"):
        LeggedController(
            designs["HexapodRobot"].geometry, template=designs["QuadrupedRobot"].template
        )


@pytest.mark.parametrize(
    ("direction", "expect"),
    [("backward", (-1.0, 0.0)), ("left", (0.0, 1.0)), (-math.pi / 4, (0.7071, -0.7071))],
)
def test_walking_directions(direction, expect, designs):
    traj = designs["HexapodRobot"].controller().walk(steps=1, direction=direction, gait="ripple")
    assert traj.info["direction"] == pytest.approx(expect, abs=1e-4)
    end = traj.info["body_path"][-1]
    assert end[:2] / np.linalg.norm(end[:2]) == pytest.approx(expect, abs=1e-4)
    assert end[2] == 0
    assert np.min(traj.info["stability_margin_m"]) >= MIN_MARGIN


@pytest.mark.parametrize(
    ("rt", "gait", "angle"),
    [("HexapodRobot", "tripod", math.pi / 2), ("QuadrupedRobot", "crawl", -1.0)],
)
def test_turning(rt, gait, angle, designs):
    traj = designs[rt].controller().turn(angle, gait=gait)
    body = traj.info["body_path"]
    assert body[-1, 2] == pytest.approx(angle, abs=1e-6)
    assert traj.info["heading_rad"] == pytest.approx(angle, abs=1e-6)
    assert np.abs(body[:, :2]).max() <= SWAY_MAX * math.sqrt(2)  # in place, but for sway
    assert np.min(traj.info["stability_margin_m"]) >= MIN_MARGIN
    np.testing.assert_allclose(traj.positions[-1], 0, atol=1e-6)


def test_rough_terrain_walking_steps_higher(designs, walks):
    hexa = designs["HexapodRobot"].controller()
    assert "rough-terrain-walking" in hexa.behaviors
    rough = hexa.run("rough-terrain-walking", steps=2)
    assert rough.info["step_height_m"] > walks["HexapodRobot", "tripod"].info["step_height_m"]
    assert np.min(rough.info["stability_margin_m"]) >= MIN_MARGIN
    # the default quadruped was not designed for rough terrain
    assert "rough-terrain-walking" not in designs["QuadrupedRobot"].controller().behaviors


def test_seconds_and_a_higher_stance():
    c = LeggedController(_geometry("HexapodRobot"))
    traj = c.run("walking", seconds=6)
    assert traj.duration == pytest.approx(6, abs=0.011)
    # an obstacle higher than the zero pose lets the trunk clear: rise from q = 0 first
    high = LeggedController(_geometry("HexapodRobot", obstacle_height=0.1))
    t2 = high.run("walking", steps=1)
    assert t2.info["stance_height_m"] > default_lengths("HexapodRobot")["tibia"]
    np.testing.assert_allclose(t2.positions[0], 0, atol=1e-9)
    assert np.min(t2.info["stability_margin_m"]) >= MIN_MARGIN
    assert np.abs(np.diff(t2.positions, axis=0)).max() < 0.1


@pytest.mark.parametrize(
    ("behavior", "params", "match"),
    [
        ("walking", {"gait": "tripod"}, "crawl"),
        ("walking", {"steps": 0}, "steps"),
        ("walking", {"direction": "sideways"}, "direction"),
        ("walking", {"direction": 4.0}, "direction"),
        # beyond the design's own ranges (issue 24): refused naming the bound
        ("walking", {"step_height": 0.02}, r"step_height: 0.02 is outside \[0.035, "),
        ("walking", {"stride": 0.5}, r"stride: 0.5 is outside \[\S+, "),
        ("walking", {"speed": 0.5}, r"speed: 0.5 is outside \[\S+, "),
        ("walking", {"seconds": 1.0}, "seconds"),
        ("walking", {"pace": 1}, "pace"),
        ("turning", {"angle": 0}, "angle"),
        ("flying", {}, "behaviour"),
    ],
)
def test_bad_parameters(behavior, params, match, designs):
    c = designs["QuadrupedRobot"].controller()
    with pytest.raises(ValueError, match=match):
        c.run(behavior, **params)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"step_height": 0.02}, "obstacle"),
        ({"stride": 0.5}, "reach"),
        ({"speed": 0.5}, "at most"),
    ],
)
def test_the_plan_says_why_past_the_declared_ranges(params, match, designs):
    """The plan's own reasons for what the declared ranges keep out (a value given to
    the planner as it is, past ``Parameter.check``)."""
    c = designs["QuadrupedRobot"].controller()
    spec = c.behaviors["walking"]
    with pytest.raises(ValueError, match=match):
        c._run("walking", {**spec.planned(spec.resolve({})), **params})


def test_a_hexapod_does_not_crawl():
    with pytest.raises(ValueError, match="tripod, ripple, wave"):
        LeggedController(_geometry("HexapodRobot")).run("walking", gait="crawl")


def test_string_parameters_as_the_command_line_gives_them():
    c = LeggedController(_geometry("HexapodRobot"))
    traj = c.run("walking", steps="1", direction="1.5707963", gait="wave", speed="0.02")
    assert traj.info["direction"] == pytest.approx((0.0, 1.0), abs=1e-6)
    assert traj.info["speed"] == pytest.approx(0.02)
    assert traj.info["cycles"] == 1


# --- MuJoCo acceptance ---------------------------------------------------------------------------


def test_hexapod_tripod_walks_a_body_length_in_10_s(designs):
    """Issue 5: the default hexapod's tripod gait moves forward at least one body length
    (La1, the trunk's length between the front and rear leg mounts) in 10 s without
    falling."""
    from synth.verification.simulate import simulate

    d = designs["HexapodRobot"]
    traj = d.controller().run("walking", gait="tripod", seconds=10)
    result = simulate(d.model(), traj, 10.0)
    assert not result.fell
    length = traj.info["body_length_m"]
    assert length == pytest.approx(d.geometry.lengths["La1"])
    forward = result.series["root"][-1, 0] - result.series["root"][0, 0]
    assert result.distance_m >= length
    assert forward >= 0.95 * result.distance_m


def test_quadruped_crawls_forward(designs):
    """Issue 5: the default quadruped crawls forward without falling."""
    from synth.verification.simulate import simulate

    d = designs["QuadrupedRobot"]
    traj = d.controller().run("walking", gait="crawl", steps=2)
    result = simulate(d.model(), traj)
    assert not result.fell
    forward = result.series["root"][-1, 0] - result.series["root"][0, 0]
    assert forward >= 0.5 * traj.info["planned_distance_m"] > 0
    assert abs(result.heading_rad) < 0.1
    assert result.verdict == [], result.to_dict()


# --- what the behaviours promise; running ----------------------------------------------------


@pytest.mark.parametrize("rt", TYPES)
def test_info_contract_and_abilities(rt, designs):

    c = designs[rt].controller()
    abilities = designs[rt].geometry.abilities
    assert "running" in abilities
    assert c.unbehaved(abilities) == []
    assert c.behaviors["turning"].realises == "walking"
    assert {"walking", "running", "turning"} <= set(c.listed(abilities))
    for name in c.behaviors:
        traj = c.run(name, steps=1) if name != "turning" else c.run(name)
        info = traj.info
        assert info["locomotion"] == "legged"
        assert info["body_length_m"] == pytest.approx(designs[rt].geometry.lengths["La1"])
        np.testing.assert_allclose(info["planned_pose"], info["body_path"][-1], atol=1e-12)
        if name == "turning":
            assert info["motion"] == "turn"
            assert info["planned_pose"][2] == pytest.approx(math.pi / 2)
            assert "direction" not in info
        else:
            assert info["motion"] == "straight"
            dx, dy, dyaw = info["planned_pose"]
            assert (dx, dy) == pytest.approx(
                tuple(info["planned_distance_m"] * np.asarray(info["direction"]))
            )
            assert dyaw == 0


def test_running_is_faster_and_statically_stable(designs):
    for rt in TYPES:
        c = designs[rt].controller()
        walk, run = c.run("walking", steps=2), c.run("running", steps=2)
        assert run.info["duty"] <= walk.info["duty"]
        assert run.info["speed"] > walk.info["speed"]
        assert run.info["speed"] <= RUN_SPEED_FACTOR * walk.info["speed"] + 1e-9
        assert np.min(run.info["stability_margin_m"]) >= MIN_MARGIN
        speeds = np.array([designs[rt].geometry.joint_speed[n] for n in run.joints])
        assert np.all(np.abs(run.velocities) <= SPEED_MARGIN * speeds + 1e-9)
    assert "duty 0.80" in designs["QuadrupedRobot"].controller().behaviors["running"].doc
    with pytest.raises(ValueError, match="gait"):
        designs["QuadrupedRobot"].controller().run("running", gait="crawl")


def test_a_slow_design_still_walks_its_pace():
    """A design speed too slow for the verdict's progress floor walks at MIN_PACE body
    lengths a second; an explicit speed is obeyed."""
    c = LeggedController(_geometry("HexapodRobot", speed=0.001))
    length = default_lengths("HexapodRobot")["La1"]
    assert c.run("walking", steps=1).info["speed"] == pytest.approx(MIN_PACE * length)
    assert c.run("walking", steps=1, speed=0.005).info["speed"] == pytest.approx(0.005)


def test_stance_inset_centres_the_tibia_tilt():
    leg = legs_of(build("QuadrupedRobot"))[0]
    out = leg.neutral[:2] - leg.mount[:2]
    across = np.array([-out[1], out[0]]) / np.linalg.norm(out) * 0.1
    r0 = np.linalg.norm(out)
    bulge = math.hypot(r0, 0.05) - r0
    assert stance_inset(leg, across) == pytest.approx(bulge / 2, rel=1e-6)
    assert stance_inset(leg, out / np.linalg.norm(out) * 0.1) == pytest.approx(0, abs=1e-12)
    assert stance_inset(leg, np.zeros(2)) == 0


@pytest.mark.parametrize("rt", TYPES)
def test_running_keeps_its_promise(rt, designs):
    """Issue 8: the default designs run (two cycles) by the verdict's criteria in MuJoCo:
    upright, no servo at its limit for more than 5 % of the time, the planned distance
    and heading, half a body length per 10 s."""
    from synth.verification.runs import run_behavior

    d = designs[rt]
    _, result = run_behavior(d.model(), d.controller(), "running", {"steps": 2})
    assert result.verdict == [], result.to_dict()


def test_batched_support_margins_equal_the_one_by_one_margins() -> None:
    """Random feet (0-6 of them, with repeated feet, a foot between two others, all in a
    line) and centres of mass inside and outside their hull."""
    from gaits.hexapod import support_margin, support_margins

    rng = np.random.default_rng(7)
    for k in range(7):
        for trial in range(60):
            feet = rng.uniform(-1, 1, (4, k, 2))
            if trial % 5 == 0 and k >= 2:
                feet[:, 1] = feet[:, 0]
            if trial % 7 == 0 and k >= 3:
                feet[:, 2] = 0.5 * (feet[:, 0] + feet[:, 1])
            if trial % 11 == 0:
                feet[:, :, 1] = 0.3 * feet[:, :, 0]
            com = rng.uniform(-1.5, 1.5, (4, 2))
            got = support_margins(feet, com)
            want = [support_margin(feet[i], com[i]) for i in range(4)]
            np.testing.assert_allclose(got, want, atol=1e-9)


def test_batched_segment_distances_equal_the_one_by_one_distances() -> None:
    """Random segment pairs, crossing ones (distance 0) and a pair with a zero-length
    segment, to the bit."""
    from gaits.hexapod import _segment_distance, _segment_distances

    rng = np.random.default_rng(11)
    a = rng.uniform(-0.3, 0.3, (200, 2, 2))
    b = rng.uniform(-0.3, 0.3, (200, 2, 2))
    a[0] = [[-1.0, 0.0], [1.0, 0.0]]
    b[0] = [[0.0, -1.0], [0.0, 1.0]]  # crossing at a sample of both
    b[1, 1] = b[1, 0]
    got = _segment_distances(a, b)
    want = [_segment_distance(x[0], x[1], y[0], y[1]) for x, y in zip(a, b, strict=True)]
    assert np.array_equal(got, want)
    assert got[0] == 0.0 and got.max() > 0.0
