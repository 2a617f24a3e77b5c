"""The feedback framework (gaits/feedback.py, synth/verification/simulate.py's closed loop): the
attitude filter, a loop's corrections reaching the servos after the bus latency, the IMU read only
where the design carries one, and the servo read-back loop removing a steady error that the
open-loop plan leaves."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gaits import feedback
from gaits.feedback import Attitude, Loop, Reading, register, roll_pitch_yaw


def test_attitude_levels_on_the_accelerometer_and_drifts_with_the_gyro_bias() -> None:
    tilt = math.radians(3.0)
    # a robot at rest rolled by 3 degrees: the accelerometer reads gravity's reaction
    accel = 9.81 * np.array([0.0, math.sin(tilt), math.cos(tilt)])
    f = Attitude()
    f.reset(np.array([1.0, 0.0, 0.0, 0.0]))
    bias = math.radians(0.5)
    for _ in range(200):  # 4 s at 50 Hz
        q = f.update(np.array([0.0, 0.0, bias]), accel, 0.02)
    roll, pitch, yaw = roll_pitch_yaw(q)
    assert roll == pytest.approx(tilt, abs=math.radians(0.2))
    assert abs(pitch) < math.radians(0.2)
    assert yaw == pytest.approx(bias * 4.0, rel=0.05)  # no magnetometer: yaw drifts
    # built to fail: without the accelerometer's pull the tilt is never found
    g = Attitude(k=0.0)
    g.reset(np.array([1.0, 0.0, 0.0, 0.0]))
    for _ in range(200):
        q = g.update(np.zeros(3), accel, 0.02)
    assert abs(roll_pitch_yaw(q)[0]) < 1e-9


class _Push(Loop):
    """A test loop: a constant offset on every joint from the start."""

    needs_imu = False

    def correct(self, r: Reading) -> np.ndarray:
        return np.full(len(self.joints), float(self.spec["offset"]))


class _NeedsImu(_Push):
    needs_imu = True

    def correct(self, r: Reading) -> np.ndarray:
        assert r.gyro is not None and r.attitude is not None
        return np.zeros(len(self.joints))


register("test-push")(_Push)
register("test-needs-imu")(_NeedsImu)


@pytest.fixture(scope="module")
def arm(designs):
    from synth.verification.runs import controller_for_model
    from synth.verification.source import Bundle

    folder = designs("positioning", "--answer", "orienting=no", "--no-verify").folder
    bundle = Bundle.read(folder)
    record, model = bundle.record, bundle.model()
    return model, controller_for_model(record, model)


def _with(traj, spec):
    return dataclasses.replace(traj, info={**traj.info, "feedback": spec})


def test_corrections_reach_the_servos_after_the_latency(arm) -> None:
    import mujoco

    from synth.verification.simulate import simulate

    model, controller = arm
    traj = controller.run(controller.listed(["positioning"])[0])
    controls = []
    data = mujoco.MjData(model)
    for k, name in enumerate(traj.joints):  # the plan's first pose, as simulate starts
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = traj.positions[0, k]
    mujoco.mj_forward(model, data)

    def watch(t, d):
        controls.append(d.ctrl.copy())

    latency = 0.03
    simulate(
        model,
        _with(traj, {"loop": "test-push", "offset": 0.05}),
        seconds=0.1,
        data=data,
        observe=watch,
        observe_every=model.opt.timestep,
        latency_s=latency,
    )
    a = model.actuator(traj.joints[0]).id
    plan = np.interp(
        np.arange(1, len(controls) + 1) * model.opt.timestep - latency,
        traj.times,
        traj.positions[:, 0],
    )
    got = np.array([c[a] for c in controls])
    late = int(round(latency / model.opt.timestep))
    # the step that acts at t uses the control set before it: offsets from step `late` on
    assert np.allclose(got[: late - 1] - plan[: late - 1], 0.0, atol=1e-9)
    assert np.allclose(got[late + 1 :] - plan[late + 1 :], 0.05, atol=1e-9)


def test_an_imu_loop_needs_an_imu(arm, humanoid) -> None:
    from synth.verification.runs import controller_for_model
    from synth.verification.simulate import imu_sensors, simulate
    from synth.verification.source import Bundle

    model, controller = arm
    assert imu_sensors(model) is None  # an arm carries no IMU
    traj = controller.run(controller.listed(["positioning"])[0])
    with pytest.raises(ValueError, match="IMU the design does not carry"):
        simulate(model, _with(traj, {"loop": "test-needs-imu"}), seconds=0.1)
    bundle = Bundle.read(humanoid)
    record, hmodel = bundle.record, bundle.model()
    assert imu_sensors(hmodel) is not None  # a biped carries one (KIF)
    hc = controller_for_model(record, hmodel)
    assert feedback.has_imu(hc.geometry.sensors)
    assert not feedback.has_imu(controller.geometry.sensors)
    walk = hc.run("walking")
    r = simulate(hmodel, _with(walk, {"loop": "test-needs-imu"}), seconds=0.2)
    assert r.seconds == pytest.approx(0.2)


def test_servo_read_back_removes_a_steady_error(arm) -> None:
    """A steady torque on the first joint (a payload's, a spring's) leaves the open-loop servo
    off by torque / kp; the read-back loop brings it back (the case built to fail is the
    open loop)."""
    import mujoco

    from synth.verification.simulate import simulate

    model, controller = arm
    traj = controller.run(controller.listed(["positioning"])[0])
    name = traj.joints[0]
    j = model.joint(name).id
    a = model.actuator(name).id
    kp = float(model.actuator_gainprm[a, 0])
    stall = float(model.actuator_forcerange[a, 1])
    push = 0.5 * stall  # half the stall torque: 0.025 rad of proportional band
    seconds = traj.duration + 2.0

    def run(spec):
        data = mujoco.MjData(model)
        for k, n in enumerate(traj.joints):
            data.qpos[model.jnt_qposadr[model.joint(n).id]] = traj.positions[0, k]
        data.qfrc_applied[model.jnt_dofadr[j]] = push
        mujoco.mj_forward(model, data)
        t = _with(traj, spec) if spec else traj
        simulate(model, t, seconds=seconds, data=data)
        return abs(float(data.qpos[model.jnt_qposadr[j]]) - float(traj.positions[-1, 0]))

    open_loop = run(None)
    closed = run({"loop": "joint-hold", "ki": 4.0, "limit_rad": 0.15})
    assert open_loop > 0.5 * push / kp  # the servo's proportional band gives way
    assert closed < 0.2 * open_loop


def test_the_read_back_holds_the_joints_where_the_plan_wants_them_not_the_commands() -> None:
    """An arm's commands carry its servos' droop compensation (positions = planned + g/kp):
    a servo that settles at the planned position under its load reads back the planned
    position, and the loop must leave it there. Built to fail: held to the commands (a plan
    without ``planned_positions``), the integral pushes it past by the compensation."""
    from gaits.base import Trajectory

    times = np.linspace(0.0, 1.0, 11)
    planned = np.tile([0.3, -0.5], (11, 1))
    droop = np.array([0.02, -0.01])
    spec = {"loop": "joint-hold", "ki": 4.0}

    def hold(info):
        traj = Trajectory(
            "pointing", times, ("a", "b"), planned + droop, np.zeros_like(planned), info
        )
        loop = feedback.loop_for(traj)
        out = np.zeros(2)
        for t in np.arange(0.0, 3.0, 0.02):  # the joints sit where they should
            out = loop.correct(Reading(t=float(t), q=planned[0], qd=np.zeros(2)))
        return out

    assert np.allclose(hold({"feedback": spec, "planned_positions": planned}), 0.0)
    pushed = hold({"feedback": spec})  # the commands as the reference: it winds up
    assert np.all(np.sign(pushed) == np.sign(droop)) and np.all(abs(pushed) >= abs(droop))
