"""A controller for any serial arm of 3 to 7 joints (issue 21): the numerical IK of
``gaits.arm_ik`` against the closed forms and the chain's forward kinematics, joint limits,
refusals, redundancy kept off the limits, what a chain declares it can orient, and arms of
4, 5 and 7 joints written only in KIF designed and verified in MuJoCo."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from gaits.arm_ik import chain_rank, limit_cost, serial_chain, solve_ik
from gaits.base import DesignGeometry
from gaits.manipulator import ManipulatorController, ik_3dof, ik_6dof
from kinematics.dynamics import forward_kinematics
from kinematics.templates import build, register_plan
from tests.kinematics.test_bodyplan import arm_kif

COUNTS = (3, 4, 5, 6, 7)


def _kif_arm(n: int, links: tuple[int, ...], name: str) -> str:
    """An arm of ``n`` position servos with a printed link after the joints ``links``
    (1-based), written like ``tests.kinematics.test_bodyplan.arm_kif``."""
    chain, lits = ["?BASE"], ["(instance ?BASE ArmBase)", "(instance ?GRIP RoboticGripper)"]
    for i in range(1, n + 1):
        chain.append(f"?S{i}")
        lits.append(f"(instance ?S{i} PositionServomotor)")
        if i in links:
            chain.append(f"?K{i}")
            lits.append(f"(instance ?K{i} LinkModule)")
    chain.append("?GRIP")
    lits += [f"(robotPart {v} ?ROB)" for v in chain]
    lits += [f"(connectedTo {a} {b})" for a, b in zip(chain, chain[1:], strict=False)]
    return f"""
(subclass {name} IndustrialRobot)
(instance {name} BaseConfiguration)
(documentation {name} EnglishLanguage "An arm of {n} joints.")
(=> (instance ?ROB {name})
  (exists ({" ".join(v for v in chain)})
    (and {" ".join(lits)})))
"""


def _plan(tmp_path_factory, kif: str, name: str):
    from adron.kb import load as load_kb
    from kinematics.partkinds import load
    from synth.reasoning.plans import plan_of

    f = tmp_path_factory.mktemp(name) / f"{name}.kif"
    f.write_text(kif)
    return register_plan(plan_of(load_kb([f]), name, load()))


@pytest.fixture(scope="module")
def arms(tmp_path_factory) -> dict[int, str]:
    """Joint count -> the registered template name of the part kinds' composed arm."""
    from kinematics.partkinds import load
    from synth.reasoning.composition import arm_type_name, serial_arm_kif

    out = {}
    for n in COUNTS:
        name = arm_type_name(n)
        _plan(tmp_path_factory, serial_arm_kif(n, load()), name)
        out[n] = name
    return out


#: the lengths the designer gives an arm of 25 cm reach (design.json of dof=4..7)
DESIGNED = {"L1": 0.1, "L2": 0.09375, "L3": 0.09375, "L4": 0.0625}


def _geometry(template: str, speed: float = 6.0) -> DesignGeometry:
    t = build(template)
    lengths = dict(t.lengths)
    if set(lengths) == set(DESIGNED):
        lengths.update(DESIGNED)
    elif set(lengths) == {"L1", "L2", "L3"}:  # the reach in two links
        lengths.update(L2=0.125, L3=0.125)
    return DesignGeometry(
        template,
        template,
        lengths,
        1,
        0.03,
        {"payload": 0.1},
        (),
        {j: speed for j in t.model.q_names},
    )


def _chain(template: str):
    return serial_chain(build(template).model, "gripper_link")


def _random_q(chain, rng, shrink: float = 0.9) -> np.ndarray:
    lo = np.where(np.isfinite(chain.lower), chain.lower, -math.pi)
    hi = np.where(np.isfinite(chain.upper), chain.upper, math.pi)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * shrink
    return mid - half + 2 * half * rng.random(chain.n)


# --- the chain -------------------------------------------------------------------------------


def test_the_chain_is_the_models_path_to_the_gripper(arms) -> None:
    rng = np.random.default_rng(0)
    for n, name in arms.items():
        m = build(name).model
        chain = serial_chain(m, "gripper_link")
        assert len(chain.joints) == n and "gripper" not in chain.joints
        for _ in range(5):
            q = _random_q(chain, rng)
            full = np.zeros(m.nq)
            full[list(chain.q_index)] = q
            T = forward_kinematics(m, full)
            p, R = chain.forward(q)
            np.testing.assert_allclose(p, T[m.body("gripper_link"), :3, 3], atol=1e-12)
            np.testing.assert_allclose(R, T[m.body(chain.tool_body), :3, :3], atol=1e-12)


def test_what_a_chain_orients_is_read_from_it(arms) -> None:
    """The Jacobian's rank, not the joint count, decides: 3 joints place the gripper, a
    pitching wrist adds one orientation freedom and a tool roll another, 6 and 7 joints
    orient the tool every way; only those offer ``orienting`` and (roll, pitch, yaw)."""
    ranks = {n: chain_rank(_chain(name)) for n, name in arms.items()}
    assert ranks == {3: 3, 4: 4, 5: 5, 6: 6, 7: 6}
    for n, name in arms.items():
        c = ManipulatorController(_geometry(name))
        full = ranks[n] == 6
        assert ("orienting" in c.behaviors) is full
        assert (
            {"roll", "pitch", "yaw"} <= {p.name for p in c.behaviors["positioning"].params}
        ) is full
        assert c.closed == (n if n in (3, 6) else None)  # the closed forms fit their chains
    # a chain whose joints all pitch about parallel axes cannot leave its plane
    planar = _chain(arms[4])
    steps = tuple(
        (o, None if a is None else np.array([0.0, 1.0, 0.0]), i) for o, a, i in planar.steps
    )
    assert chain_rank(dataclasses.replace(planar, steps=steps, _cache={}), True) == 2


# --- agreement with the closed forms ---------------------------------------------------------


@pytest.mark.parametrize("n", [3, 6])
def test_numerical_ik_agrees_with_the_closed_forms(arms, n) -> None:
    """Over 40 configurations drawn inside the limits: started near the closed form's
    solution, the numerical IK converges onto it (the same branch); started from the
    middle of the ranges it reaches the same gripper pose. Pass rate 100 %."""
    t = build(arms[n])
    chain = serial_chain(t.model, "gripper_link")
    limits = {j: (lo, hi) for j, lo, hi in zip(chain.joints, chain.lower, chain.upper, strict=True)}
    rng = np.random.default_rng(n)
    agree = 0
    for _ in range(40):
        q = 0.6 * _random_q(chain, rng)
        p, R = chain.forward(q)
        elbow = "up" if q[2] >= 0 else "down"
        if n == 3:
            qc = ik_3dof(t.lengths, p, elbow, float(q[0]), limits)
            rot = None
        else:
            qc = ik_6dof(t.lengths, p, R, elbow, q, limits)
            rot = R
        qn = solve_ik(chain, p, rot, q0=qc + 0.05 * np.sin(np.arange(n) + 1.0))
        qm = solve_ik(chain, p, rot)
        pm, Rm = chain.forward(qm)
        ok = np.allclose(qn, qc, atol=1e-6) and np.allclose(pm, p, atol=1e-6)
        ok = ok and (rot is None or np.allclose(Rm, R, atol=1e-6))
        agree += ok
    assert agree == 40


@pytest.mark.parametrize("n", [3, 6])
def test_numeric_and_closed_form_plans_agree(arms, n) -> None:
    """The same controller planned by its closed form and by the numerical IK: the
    pick-and-place trajectories agree within 1e-5 rad."""
    g = _geometry(arms[n])
    closed = ManipulatorController(g)
    numeric = ManipulatorController(g)
    numeric.closed = None
    a, b = closed.run("pick-and-place"), numeric.run("pick-and-place")
    assert a.positions.shape == b.positions.shape
    assert float(np.max(np.abs(a.positions - b.positions))) < 1e-5


# --- limits, refusals, redundancy ------------------------------------------------------------


@pytest.mark.parametrize("n", [4, 5, 7])
def test_solutions_respect_the_joint_limits(arms, n) -> None:
    """20 poses of each chain drawn inside its limits (position, and the whole tool frame
    where the chain orients it): every one solved, inside the limits, on the pose."""
    chain = _chain(arms[n])
    full = chain_rank(chain) == 6
    rng = np.random.default_rng(10 + n)
    solved = 0
    for _ in range(20):
        p, R = chain.forward(_random_q(chain, rng))
        q = solve_ik(chain, p, R if full else None)
        p2, R2 = chain.forward(q)
        assert np.all(q >= chain.lower - 1e-12) and np.all(q <= chain.upper + 1e-12)
        solved += np.allclose(p2, p, atol=1e-6) and (not full or np.allclose(R2, R, atol=1e-6))
    assert solved == 20


def test_a_target_only_past_a_joint_limit_is_refused(arms) -> None:
    """5 cm from the shoulder of the 3-joint arm: within its reach, but the elbow would
    have to fold past its 150 degrees; with the elbow's limits widened it is reached."""
    chain = _chain(arms[3])
    target = (0.03, 0.0, 0.1 - 0.04)
    with pytest.raises(ValueError, match=r"no configuration inside the joint limits.*mm from"):
        solve_ik(chain, target)
    wide = dataclasses.replace(
        chain, lower=np.array([-math.pi, -math.pi / 2, -math.pi]),
        upper=np.array([math.pi, math.pi / 2, math.pi]), _cache={},
    )  # fmt: skip
    p, _ = wide.forward(solve_ik(wide, target))
    np.testing.assert_allclose(p, target, atol=1e-6)


def test_an_unreachable_target_is_refused_with_the_reach(arms) -> None:
    chain = _chain(arms[5])
    with pytest.raises(
        ValueError, match=r"cannot reach \(0\.6000, 0\.0000, 0\.1000\) m.*reaches 0\.4500 m"
    ):
        solve_ik(chain, (0.6, 0.0, 0.1))
    c = ManipulatorController(_geometry(arms[5]))
    with pytest.raises(ValueError, match="reaches"):
        # inside the parameter ranges (each coordinate within the shoulder +- the reach),
        # out of reach together
        c.run("positioning", x=0.24, y=0.24, z=0.1)
    with pytest.raises(ValueError, match="cannot choose its tool orientation"):
        c.ik((0.2, 0, 0.1), rotation=np.eye(3))


def test_redundancy_keeps_the_joints_off_their_limits(arms) -> None:
    """The 7-joint arm holding the whole tool frame has one joint to spare: started with
    joints near their limits, the null-space gradient ends lower on the limit-distance
    cost than the same solver without it, in every pose where the latter ends with a
    joint near a limit (and both on the pose)."""
    chain = _chain(arms[7])
    lo, hi = chain.lower, chain.upper
    mid = (lo + hi) / 2
    rng = np.random.default_rng(7)
    near_limits = better = 0
    for _ in range(25):
        q = _random_q(chain, rng, 0.5)
        p, R = chain.forward(q)
        near = np.clip(q + 0.45 * np.sign(q - mid) * (hi - lo) / 2, lo, hi)
        kept = solve_ik(chain, p, R, q0=near)
        free = solve_ik(chain, p, R, q0=near, avoid_limits=False)
        for x in (kept, free):
            p2, R2 = chain.forward(x)
            assert np.allclose(p2, p, atol=1e-6) and np.allclose(R2, R, atol=1e-6)
        if limit_cost(chain, free) > 1e-9:
            near_limits += 1
            better += limit_cost(chain, kept) < limit_cost(chain, free) - 1e-9
    assert near_limits >= 8 and better == near_limits


def test_same_input_same_bytes(arms) -> None:
    chain = _chain(arms[7])
    p, R = chain.forward(np.full(7, 0.3))
    a = solve_ik(chain, p, R)
    b = solve_ik(chain, p, R)
    assert a.tobytes() == b.tobytes()
    csv = {ManipulatorController(_geometry(arms[5])).run("grasping").csv() for _ in range(2)}
    assert len(csv) == 1


# --- behaviours of any arm -------------------------------------------------------------------


@pytest.mark.parametrize("n", COUNTS)
def test_every_behaviour_of_every_arm_plans_onto_its_target(arms, n) -> None:
    """Default parameters: the gripper (the tool body where it orients) is on the
    promised target at the promised time, within the limits; the named poses end on
    their joint configurations."""
    c = ManipulatorController(_geometry(arms[n]), base_position=(0, 0, 0.05))
    m = c.template.model
    for name in sorted(c.behaviors):
        traj = c.run(name)
        t = float(traj.info.get("placed_at_s", traj.duration))
        k = int(np.argmin(np.abs(traj.times - t)))
        q = traj.positions[k]
        body = m.body(str(traj.info["tool_body"]))
        at = forward_kinematics(m, q)[body, :3, 3] + c.base_position
        assert np.linalg.norm(at - np.array(traj.info["target"])) < 1e-6, name
        assert np.all(traj.positions >= c.lower - 1e-9) and np.all(traj.positions <= c.upper + 1e-9)
    home = c.run("move_to_pose", pose="home")
    np.testing.assert_allclose(home.positions[-1, :-1], 0.0, atol=1e-12)
    assert c.behaviors["move_to_pose"].params[0].choices == ("ready", "home")


def test_a_chain_with_the_closed_forms_names_but_other_links_goes_numeric(tmp_path_factory) -> None:
    """Three joints named like the closed form's, but the shoulder at the base and the
    column after it: the closed form does not fit, the numerical IK serves the chain and
    its gripper lands on the targets. With the upper arm's link left out instead, the
    shoulder and the elbow pitch about one axis: refused, it cannot reach in 3-D."""
    plan = _plan(tmp_path_factory, _kif_arm(3, (2, 3), "LowArm3"), "LowArm3")
    c = ManipulatorController(_geometry(plan.robot_type), base_position=(0, 0, 0.05))
    assert c.arm == ("base_yaw", "shoulder_pitch", "elbow_pitch") and c.closed is None
    traj = c.run("pick-and-place")
    k = int(np.argmin(np.abs(traj.times - traj.info["placed_at_s"])))
    at = c.gripper_position(traj.positions[k]) + c.base_position
    assert np.linalg.norm(at - np.array(traj.info["target"])) < 1e-6
    flat = _plan(tmp_path_factory, _kif_arm(3, (1, 3), "FoldArm3"), "FoldArm3")
    with pytest.raises(ValueError, match="cannot move the gripper in three dimensions"):
        ManipulatorController(_geometry(flat.robot_type))


# --- designed and verified in MuJoCo ---------------------------------------------------------


def verified_arm_request(n: int) -> tuple[str, ...]:
    """``parmor design`` arguments of ``arm_kif(n)`` (KIF:arm<n>), verified."""
    extra = ("--param", "payload=0.1 kg") if n == 7 else ("--answer", "orienting=no")
    return (f"positioning-{n}", *extra, "--ontology", f"KIF:arm{n}")


@pytest.mark.parametrize("n", [4, 5, 7])
def test_kif_only_arms_design_verify_and_simulate(cli, designs, n) -> None:
    """``tests.kinematics.test_bodyplan.arm_kif(n)``: designed with verification (exit 0, every
    listed behaviour ok), then every behaviour run again by ``parmor simulate --json``
    (the 7-joint arm with a 0.1 kg payload: at the default 0.2 kg no servo of the catalog
    holds it stretched). The session's design (tests/conftest.py): test_bodyplan's
    verified 5-joint arm is the same request."""
    out = designs(*verified_arm_request(n), kif={f"arm{n}": arm_kif(n)}).folder
    rec = json.loads((out / "design.json").read_text())
    runs = rec["verified"]["behaviors"] if isinstance(rec["verified"], dict) else rec["verified"]
    names = sorted(p.stem for p in (out / "trajectories").glob("*.csv"))
    assert {"grasping", "move_to_pose", "pick-and-place", "positioning"} <= set(names)
    assert ("orienting" in names) is (n == 7)
    assert runs
    for name in names:
        s = cli("simulate", str(out), "--behavior", name, "--json")
        assert s.code == 0, s.err
        fig = json.loads(s.out)
        assert fig["verdict"] == "ok", (name, fig)
        assert fig["placing_error_m"] <= 0.005
    s = cli("simulate", str(out), "--behavior", "move_to_pose", "--set", "pose=home", "--json")
    assert s.code == 0 and json.loads(s.out)["verdict"] == "ok", s.err


def test_a_tool_off_its_last_joint_is_measured_on_its_own_body(tmp_path_factory) -> None:
    """Six joints with a printed link after the tool roll: the gripper sits a link away
    from the tool body's origin. The chain still orients the tool every way (numerical
    IK); a behaviour that promises an orientation promises the tool body's origin where
    the gripper is on its target, and the plan puts it there. (Its default targets, the
    tool pointing down, would need the wrist to fold past its limits: refused.)"""
    plan = _plan(tmp_path_factory, _kif_arm(6, (1, 2, 3, 5, 6), "ToolArm6"), "ToolArm6")
    c = ManipulatorController(_geometry(plan.robot_type), base_position=(0, 0, 0.05))
    assert c.closed is None and c.six and np.linalg.norm(c.chain.tool_offset) > 0.1
    with pytest.raises(ValueError, match="no configuration inside the joint limits"):
        c.run("positioning")
    m = c.template.model
    ahead = {"x": 0.5, "y": 0.05, "z": 0.15, "roll": 0.2, "yaw": 0.1}  # the tool forward
    for name, params in (
        ("positioning", {**ahead, "pitch": 0.0}),
        ("orienting", {**ahead, "pitch": 0.3}),
        ("move_to_pose", {"pose": "home"}),
    ):
        traj = c.run(name, **params)
        q = traj.positions[-1]
        assert traj.info["tool_body"] == c.chain.tool_body == "tool_roll_link"
        T = forward_kinematics(m, q)
        at = T[m.body("tool_roll_link"), :3, 3] + c.base_position
        np.testing.assert_allclose(at, traj.info["target"], atol=1e-6)
        grip = T[m.body("gripper_link"), :3, 3]
        np.testing.assert_allclose(grip, traj.info["target_base"], atol=1e-6)


def test_an_arm_whose_default_behaviour_cannot_be_planned_is_refused(cli, tmp_path) -> None:
    """The six joints with a printed link after the tool roll, designed: its default grasp
    (the tool pointing down onto the object) would need the wrist past its limits. The
    design is refused with the behaviour, the target and why (exit 1, no traceback,
    nothing written)."""
    src = tmp_path / "tool6.kif"
    src.write_text(
        _kif_arm(6, (1, 2, 3, 5, 6), "ToolArm6")
        + """
(subclass RobotPositioningTool RobotPositioning)
(abilityName RobotPositioningTool "positioning-tool")
(abilityVerb RobotPositioningTool "position with a long tool")
(requiredPartCount RobotPositioningTool LinkModule 5)
"""
    )
    out = tmp_path / "bundle"
    r = cli("design", "positioning-tool", "--ontology", str(src), "--no-input", "--out", str(out))
    assert r.code == 1 and "Traceback" not in r.err, r.err
    assert "ToolArm6: its behaviour" in r.err and "cannot be planned" in r.err
    assert "no configuration inside the joint limits" in r.err
    assert not out.exists()
