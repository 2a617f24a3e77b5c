"""The ROS package drives the verified feedback loops (issue 30, item 4): the worker runs the
plan's loop (gaits.feedback) on the readings the node sends, and the package documents the
topics the controller reads (the servos' read-back; the IMU where the design has one)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from program.ros import interface, launch_xml, readme
from program.rosworker import Worker


@pytest.fixture(scope="module")
def cart(designs) -> Path:
    return designs("driving", "line-tracking", "obstacle-avoidance", "--no-verify").folder


@pytest.fixture(scope="module")
def arm(designs) -> Path:
    return designs("pick-and-place", "--param", "object_shape=cylinder", "--no-verify").folder


def _record(folder: Path) -> dict:
    return json.loads((folder / "design.json").read_text())


def test_the_package_documents_what_the_controller_reads(cart, humanoid) -> None:
    plain = interface(_record(cart))
    assert plain["topics"]["measured"] == "measured_joint_states"
    assert plain["topics"]["commands"] == "joint_commands"
    assert "imu" not in plain["topics"] and plain["feedback"]["imu"] is False
    assert plain["feedback"]["velocity_joints"] == ["left_wheel", "right_wheel"]
    text = readme(plain)
    assert "measured_joint_states" in text and "sensor_msgs/Imu" not in text
    # a biped carries an IMU (its KIF): the node reads it, the package says so
    withimu = interface(_record(humanoid))
    assert withimu["topics"]["imu"] == "imu" and withimu["feedback"]["imu"] is True
    assert withimu["feedback"]["velocity_joints"] == []
    for text in (readme(withimu), launch_xml(withimu)):
        assert "sensor_msgs/Imu" in text and "measured_joint_states" in text


def test_the_worker_runs_the_plans_loop_on_the_robots_readings(arm, monkeypatch) -> None:
    from gaits.feedback import JointHold, Reading

    record = _record(arm)
    worker = Worker(interface(record), record)
    assert worker.call({"correct": {"t": 0.0, "q": []}})["ok"] is False  # no plan yet
    service = worker.iface["services"][0]
    plain = worker.call({"service": service["service"], "fields": {}})
    assert plain["ok"] and plain["trajectory"]["feedback"] is None
    n = len(plain["trajectory"]["joints"])
    zero = worker.call({"correct": {"t": 0.0, "q": [0.0] * n}})
    assert zero == {"ok": True, "offsets": [0.0] * n}  # no loop: the plan alone

    run = worker.controller.run

    def with_loop(name, **params):
        traj = run(name, **params)  # (a copy: plans are remembered)
        loop = {"loop": "joint-hold", "ki": 4.0}
        return dataclasses.replace(traj, info={**traj.info, "feedback": loop})

    monkeypatch.setattr(worker.controller, "run", with_loop)
    reply = worker.call({"service": service["service"], "fields": {}})
    assert reply["trajectory"]["feedback"] == {"loop": "joint-hold", "ki": 4.0}
    plan = with_loop(service["behavior"])
    same = JointHold(plan, {"loop": "joint-hold", "ki": 4.0})
    q0 = np.asarray(plan.positions[-1]) - 0.01  # a servo 0.01 rad short, the plan at rest
    t_end = float(plan.times[-1])
    for k, t in enumerate((t_end, t_end + 0.02, t_end + 0.04)):
        got = worker.call({"correct": {"t": t, "q": q0.tolist(), "qd": [0.0] * n}})
        r = Reading(t=t, q=q0, qd=np.zeros(n))
        if k == 0:
            same.reset(r)
        assert got["ok"] and got["offsets"] == pytest.approx(same.correct(r).tolist(), abs=0)
    assert max(got["offsets"]) > 0  # the integral pushes the short servos on
    bad = worker.call({"correct": {"t": "soon", "q": q0.tolist()}})
    assert bad["ok"] is False and "malformed" in bad["message"]
    short = worker.call({"correct": {"t": 0.1, "q": [0.0]}})
    assert short["ok"] is False
