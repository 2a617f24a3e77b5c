"""The simulation steps inside MuJoCo (``synth.verification.simulate.step_through``,
``mujoco.rollout``) and measures the run afterwards (``ServoLaw``): both must be what a plain
``mj_step`` loop reading ``MjData`` at every step gives, to the bit."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from gaits.base import Trajectory
from synth.verification.simulate import ServoLaw, simulate, step_through

# a free two-link body on a floor, one servo of each kind parmor writes and two it does not
XML = """
<mujoco>
  <option timestep="0.002" integrator="implicitfast"/>
  <default><joint armature="0.001" damping="0.002"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.05"/>
    <body name="trunk" pos="0 0 0.1">
      <freejoint/>
      <geom type="box" size="0.05 0.03 0.02" mass="0.3"/>
      <body name="arm" pos="0.05 0 0">
        <joint name="hip" type="hinge" axis="0 1 0" range="-1 1" damping="0.01"/>
        <geom type="capsule" size="0.01" fromto="0 0 0 0.08 0 0" mass="0.05"/>
        <body name="tip" pos="0.08 0 0">
          <joint name="knee" type="hinge" axis="0 1 0" range="-1.5 1.5"/>
          <geom type="capsule" size="0.01" fromto="0 0 0 0 0 -0.06" mass="0.03"/>
        </body>
      </body>
      <body name="wheel" pos="-0.05 0 0">
        <joint name="wheel" type="hinge" axis="0 1 0"/>
        <geom type="cylinder" size="0.03 0.01" euler="1.5708 0 0" mass="0.02"/>
      </body>
      <body name="tail" pos="0 0.03 0">
        <joint name="tail" type="hinge" axis="1 0 0" range="-1 1"/>
        <geom type="capsule" size="0.005" fromto="0 0 0 0 0.05 0" mass="0.01"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="hip" joint="hip" kp="4" kv="0.05" ctrlrange="-1 1" forcerange="-0.2 0.2"/>
    <position name="knee" joint="knee" kp="2" ctrlrange="-1.5 1.5" forcerange="-0.1 0.1"/>
    <velocity name="wheel" joint="wheel" kv="0.05" ctrlrange="-6 6" forcerange="-0.1 0.1"/>
    <general name="tail" joint="tail" gaintype="affine" gainprm="1 0.5 0.1"
             biastype="affine" biasprm="0.01 -1 -0.02" gear="2" forcerange="-0.05 0.08"/>
  </actuator>
</mujoco>
"""


def _model():
    return mujoco.MjModel.from_xml_string(XML)


def _controls(model, steps: int) -> np.ndarray:
    """Controls that swing every actuator past its ranges and into its force limits."""
    t = np.arange(steps)[:, None] * model.opt.timestep
    amp = np.array([1.4, 2.0, 8.0, 0.5])  # beyond each ctrlrange: the law must clamp
    return amp * np.sin(2 * np.pi * (1.5 + np.arange(model.nu)) * t)


def _plain_loop(model, ctrl: np.ndarray):
    """States after each step, and MuJoCo's actuator force at each step."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    states = np.empty((len(ctrl), mujoco.mj_stateSize(model, full)))
    forces = np.empty((len(ctrl), model.nu))
    for i, row in enumerate(ctrl):
        data.ctrl[:] = row
        mujoco.mj_step(model, data)
        forces[i] = data.actuator_force
        mujoco.mj_getState(model, data, states[i], full)
    return states, forces


def test_the_servo_law_gives_mujocos_actuator_force_to_the_bit():
    model = _model()
    ctrl = _controls(model, 600)
    states, forces = _plain_loop(model, ctrl)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    first = np.empty(states.shape[1])
    mujoco.mj_getState(model, data, first, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    before = np.vstack([first[None], states[:-1]])
    nq, nv = model.nq, model.nv
    law = ServoLaw(model)
    effort = law.efforts(before[:, 1 : 1 + nq], before[:, 1 + nq : 1 + nq + nv], ctrl)
    assert np.array_equal(law.forces(effort), forces)
    # the case is built to saturate: the demand before the clamp exceeds every limit
    assert (np.abs(effort).max(axis=0) > law.limit).all()
    assert (np.abs(forces).max(axis=0) <= law.limit + 1e-15).all()


def test_an_actuator_with_dynamics_is_refused():
    xml = XML.replace('<general name="tail"', '<general name="tail" dyntype="filter" dynprm="0.1"')
    with pytest.raises(ValueError, match="tail"):
        ServoLaw(mujoco.MjModel.from_xml_string(xml))


@pytest.mark.parametrize("every", [1, 7, 250, 10_000])
def test_stepping_inside_mujoco_is_a_plain_mj_step_loop(every, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT here
    model = _model()
    ctrl = _controls(model, 500)
    ctrl[123] = np.nan  # a warning: a rollout stops there, a plain loop goes on
    want, _ = _plain_loop(model, ctrl)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    calls = []
    got = step_through(model, data, ctrl, every, calls.append)
    assert np.array_equal(got, want, equal_nan=True)
    assert calls == [*range(every, len(ctrl), every), len(ctrl)]
    assert data.time == pytest.approx(len(ctrl) * model.opt.timestep)


def test_what_data_holds_besides_the_controls_is_kept():
    """A rollout resets applied forces and mocap poses it is not given: step_through
    gives them (a program's obstacle is a mocap body moved into the robot's way)."""
    xml = XML.replace(
        "</worldbody>",
        '<body name="wall" mocap="true" pos="0 0 -10"><geom type="box" size="0.02 0.2 0.2"/>'
        "</body></worldbody>",
    )
    model = mujoco.MjModel.from_xml_string(xml)
    ctrl = _controls(model, 200)

    def setup(data) -> None:
        data.xfrc_applied[1, 2] = 2.0  # lifts the trunk
        data.mocap_pos[0] = [0.12, 0.0, 0.1]  # the wall in the arm's way
        mujoco.mj_forward(model, data)

    data = mujoco.MjData(model)
    setup(data)
    got = step_through(model, data, ctrl, 50)
    ref = mujoco.MjData(model)
    setup(ref)
    for row in ctrl:
        ref.ctrl[:] = row
        mujoco.mj_step(model, ref)
    assert np.array_equal(got[-1, 1 : 1 + model.nq], ref.qpos)
    assert np.array_equal(data.mocap_pos, ref.mocap_pos)
    free = mujoco.MjData(model)  # the wall and the lift matter: without them, elsewhere
    mujoco.mj_forward(model, free)
    assert not np.array_equal(step_through(model, free, ctrl)[-1], got[-1])


def _trajectory(model) -> Trajectory:
    times = np.linspace(0.0, 1.0, 21)
    joints = ("hip", "knee", "wheel")
    pos = np.stack([0.8 * np.sin(3 * times), 1.2 * np.sin(5 * times), 4 * times], axis=1)
    vel = np.gradient(pos, times, axis=0)
    return Trajectory("wiggle", times, joints, pos, vel, info={})


def test_an_observed_run_is_the_same_run_and_is_deterministic():
    model = _model()
    traj = _trajectory(model)
    plain = simulate(model, traj, can_fall=False)
    again = simulate(model, traj, can_fall=False)
    seen: list[float] = []
    observed = simulate(
        model,
        traj,
        can_fall=False,
        data=None,
        observe=lambda t, d: seen.append(round(t, 9)),
        observe_every=0.05,
    )
    for other in (again, observed):
        assert other.to_dict() == plain.to_dict()
        for key, series in plain.series.items():
            assert np.array_equal(other.series[key], series)
    assert seen == [round(0.05 * k, 9) for k in range(1, 21)]
    assert plain.saturated_fraction > 0  # the knee's 0.1 N m cannot follow this swing
    assert plain.demand_ratio_max > 1


def test_a_run_measured_block_by_block_is_the_same_run(monkeypatch):
    """Long runs are stepped and measured in blocks (memory): the blocks' seams do not show."""
    import synth.verification.simulate as sim

    model = _model()
    traj = _trajectory(model)
    whole = simulate(model, traj, can_fall=True)
    monkeypatch.setattr(sim, "BLOCK_STEPS", 70)  # 500 steps in 8 blocks, one of 10
    pieces = simulate(model, traj, can_fall=True)
    assert pieces.to_dict() == whole.to_dict()
    for key, series in whole.series.items():
        assert np.array_equal(pieces.series[key], series)
