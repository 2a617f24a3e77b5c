"""The biped's balance loop on its trunk's IMU (gaits.balance): what it drives (found by the
template's structure), that its output is bounded, that a design without an IMU gets no IMU
loop, and cases built to fail: the open-loop humanoid falls (or fails) under perturbations
where the closed loop walks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from adron.catalog import load_catalog
from export.mjcf import load_mjcf
from gaits.balance import GAINS, KIND, Balance, balance_joints
from gaits.feedback import Reading, has_imu, loop_for
from synth.verification.perturb import design_table, draw, perturbed_model
from synth.verification.runs import controller_for_model
from synth.verification.simulate import simulate
from synth.verification.source import Bundle


@pytest.fixture(scope="module")
def bundle(humanoid):
    bundle = Bundle.read(humanoid)
    record, xml, meshes = bundle.record, bundle.xml, bundle.meshes
    nominal = load_mjcf(xml, meshes)
    return record, xml, meshes, nominal, design_table(record, xml, load_catalog())


def _run(bundle, ctl, traj, seed: int, feedback: bool = True):
    record, xml, meshes, _, table = bundle
    p = draw(table, seed)
    return simulate(
        perturbed_model(xml, meshes, table, p),
        traj,
        can_fall=True,
        latency_s=float(p["latency_s"]),
        command_period_s=float(p["control_period_s"]),
        sensor_noise=p.get("imu"),
        feedback=feedback,
    )


def test_every_behaviour_asks_for_the_balance_loop(bundle) -> None:
    record, _, _, nominal, _ = bundle
    ctl = controller_for_model(record, nominal)
    assert has_imu(ctl.geometry.sensors)
    for name in ctl.behaviors:
        traj = ctl.run(name)
        spec = traj.info["feedback"]
        assert spec["loop"] == KIND, name
        loop = loop_for(traj)
        assert isinstance(loop, Balance) and loop.needs_imu
        # one support weight per foot at every sample of the plan
        assert np.asarray(spec["support"]).shape == (len(traj.times), 2)
    # the gaits lift a foot (single support), the standing behaviours never do
    assert np.asarray(ctl.run("walking").info["feedback"]["support"]).min() == 0.0
    assert np.asarray(ctl.run("grasping").info["feedback"]["support"]).min() == 1.0


def test_joints_found_by_axis_and_chain_position(bundle) -> None:
    record, _, _, nominal, _ = bundle
    ctl = controller_for_model(record, nominal)
    tmpl = ctl.template
    found = balance_joints(tmpl.model, tmpl.feet, ctl.joints)
    # per foot: the joints nearest it about the trunk's roll (x) and pitch (y) axes...
    ankle = {(e[0], e[1]) for e in found["ankle"]}
    assert ankle == {
        ("l_ankle_roll", 0),
        ("l_ankle_pitch", 0),
        ("r_ankle_roll", 1),
        ("r_ankle_pitch", 1),
    }
    # ...those nearest the trunk, and its yaw; no arm joint (not on a foot's chain)
    assert {e[0] for e in found["hip"]} == {
        "l_hip_roll",
        "l_hip_pitch",
        "r_hip_roll",
        "r_hip_pitch",
    }
    assert {e[0] for e in found["yaw"]} == {"l_hip_yaw", "r_hip_yaw"}
    for e in found["ankle"] + found["hip"] + found["yaw"]:
        assert np.isclose(np.linalg.norm(e[2:5]), 1.0)
    # the names play no part: renamed joints are found all the same
    model = tmpl.model
    renamed = type(model)(
        model.bodies,
        tuple(
            type(j)(**{**j.__dict__, "name": f"j{k}"}) if j.kind == "revolute" else j
            for k, j in enumerate(model.joints)
        ),
    )
    names = tuple(f"j{k}" for k, j in enumerate(model.joints) if j.kind == "revolute")
    again = balance_joints(renamed, tmpl.feet, names)
    assert [e[1:] for e in again["ankle"]] == [e[1:] for e in found["ankle"]]
    by_index = {j.name: f"j{k}" for k, j in enumerate(model.joints)}
    assert [e[0] for e in again["ankle"]] == [by_index[e[0]] for e in found["ankle"]]


def test_output_is_bounded(bundle) -> None:
    record, _, _, nominal, _ = bundle
    ctl = controller_for_model(record, nominal)
    for name in ("walking", "grasping"):
        traj = ctl.run(name)
        loop = loop_for(traj)
        spec = traj.info["feedback"]
        nj = len(traj.joints)
        level = np.array([1.0, 0.0, 0.0, 0.0])
        loop.reset(Reading(0.0, np.zeros(nj), np.zeros(nj), np.zeros(3), np.zeros(3), level))
        rng = np.random.default_rng(0)
        worst = 0.0
        for k in range(1, 200):
            # tilted up to 80 deg, spinning at up to 50 rad/s: far beyond a fall
            half = rng.uniform(-0.7, 0.7, 3)
            att = np.array([np.cos(np.linalg.norm(half)), *np.sin(half)])
            att /= np.linalg.norm(att)
            r = Reading(
                0.02 * k,
                np.zeros(nj),
                np.zeros(nj),
                rng.uniform(-50, 50, 3),
                np.array([0.0, 0.0, 9.81]),
                att,
            )
            out = loop.correct(r)
            assert out.shape == (nj,)
            worst = max(worst, float(np.abs(out).max()))
        assert worst <= float(spec["limit_rad"]) + 1e-12
        assert worst > 0.0
        assert float(spec["limit_rad"]) <= GAINS["limit_rad"]


def test_a_design_without_an_imu_gets_no_imu_loop(bundle, without_imu) -> None:
    record, _, _, nominal, _ = bundle
    bare = without_imu(record)
    ctl = controller_for_model(bare, nominal)
    assert not has_imu(ctl.geometry.sensors)
    for name in ctl.behaviors:
        assert "feedback" not in ctl.run(name).info, name
    # a plan that asks for the IMU loop on a model without an IMU is refused, not run blind
    traj = controller_for_model(record, nominal).run("balancing")
    model = load_mjcf(
        record_xmlwithout_imu(bundle[1]),
        bundle[2],
    )
    with pytest.raises(ValueError, match="IMU"):
        simulate(model, traj, seconds=0.1)


def record_xmlwithout_imu(xml: str) -> str:
    """The MJCF with its IMU sensors taken out (a design built without one)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml)
    for parent in root.iter():
        for child in list(parent):
            if child.get("name", "").startswith("imu"):
                parent.remove(child)
    for sensor in root.findall("sensor"):
        if not len(sensor):
            root.remove(sensor)
    return ET.tostring(root, encoding="unicode")


def test_open_loop_humanoid_falls_where_the_closed_loop_walks(bundle, without_imu) -> None:
    """Seed 1: the humanoid as it walked without its IMU (the open-loop walk) falls; with
    the IMU and its balance loop it walks the plan."""
    record, _, _, nominal, _ = bundle
    blind = controller_for_model(without_imu(record), nominal)
    fell = _run(bundle, blind, blind.run("walking"), 1, feedback=False)
    assert fell.fell and "fell" in fell.verdict
    ctl = controller_for_model(record, nominal)
    walked = _run(bundle, ctl, ctl.run("walking"), 1)
    assert walked.ok, walked.verdict
    assert not walked.fell and math.degrees(walked.max_tilt_rad) < 10


def test_the_loop_is_what_passes(bundle) -> None:
    """Seed 8 (1.5 deg uphill, 21 ms late): the same plan run open loop
    (``feedback=False``) walks short and saturates; closed, it passes."""
    record, _, _, nominal, _ = bundle
    ctl = controller_for_model(record, nominal)
    traj = ctl.run("walking")
    blind = _run(bundle, ctl, traj, 8, feedback=False)
    assert not blind.ok
    closed = _run(bundle, ctl, traj, 8)
    assert closed.ok, closed.verdict
    assert closed.saturated_fraction <= 0.05
    assert 0.9 <= closed.distance_m / closed.planned_distance_m <= 1.1
