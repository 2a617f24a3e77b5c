"""Verdicts judged on the simulated outcome: every criterion with a case built to fail it.

Simulated cases use a tiny MJCF of their own (a trunk on a sliding leg held by a position
servo), so that an overloaded servo and a collapse happen for sure; the thresholds of
``synth.verification.verdict`` are checked with figures on both sides of each.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaits.base import Trajectory
from synth.verification.verdict import judge

mujoco = pytest.importorskip("mujoco")

# A 1 kg trunk on a vertical sliding leg with a wide foot: the leg's position servo holds the
# trunk up against gravity (9.81 N) when its force range allows it.
STAND = """
<mujoco>
  <option timestep="0.002" integrator="implicitfast"/>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body name="trunk" pos="0 0 0.30">
      <freejoint/>
      <geom type="box" size="0.10 0.10 0.02" mass="1.0"/>
      <body name="foot" pos="0 0 -0.25">
        <joint name="lift" type="slide" axis="0 0 1" range="-0.2 0.2" damping="5"/>
        <geom type="box" size="0.15 0.15 0.02" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="lift" joint="lift" kp="2000" kv="40" forcerange="-{f} {f}"/>
  </actuator>
</mujoco>
"""


def _stand(force: float, seconds: float = 2.0, info: dict | None = None):
    from synth.verification.simulate import simulate

    model = mujoco.MjModel.from_xml_string(STAND.format(f=force))
    t = np.array([0.0, seconds])
    traj = Trajectory("hold", t, ("lift",), np.zeros((2, 1)), np.zeros((2, 1)), info or {})
    return simulate(model, traj)


HOLD = {"motion": "hold", "body_length_m": 0.2}


def test_a_strong_servo_holds_the_trunk_up():
    r = _stand(force=100.0, info=HOLD)
    assert not r.fell and r.demand_ratio_max < 1 and r.saturated_fraction == 0
    assert r.ok, r.verdict


def test_an_overloaded_servo_reads_above_one_and_a_collapse_is_a_fall():
    r = _stand(force=3.0, info=HOLD)  # 3 N against 9.8 N: the trunk sinks onto its foot
    assert r.max_torque_ratio <= 1.0 + 1e-9  # the clamped force can never say more
    assert r.demand_ratio_max > 1.5  # the servo law asked for much more
    assert r.saturated_fraction > 0.5
    # the trunk stays level: only its height tells the collapse
    assert r.max_tilt_rad < math.radians(5)
    assert r.min_height_ratio < 0.7 and r.fell and r.fell_at_s is not None
    assert "fell" in r.verdict and "saturated" in r.verdict


def test_a_free_robot_that_promises_nothing_fails():
    r = _stand(force=100.0)
    assert r.verdict == ["unplanned"]


def _fig(**kw):
    base = {"seconds": 10.0, "fell": False, "saturated_fraction": 0.0, "heading_rad": 0.0}
    return base | kw


@pytest.mark.parametrize(
    ("fig", "info", "failed"),
    [
        # straight: 0.8-1.25 x the planned distance, heading within 15 deg, legged progress
        (_fig(distance_m=1.0, planned_distance_m=1.0), {"motion": "straight"}, []),
        (_fig(distance_m=0.79, planned_distance_m=1.0), {"motion": "straight"}, ["distance"]),
        (_fig(distance_m=1.26, planned_distance_m=1.0), {"motion": "straight"}, ["distance"]),
        (
            _fig(distance_m=1.0, planned_distance_m=1.0, heading_rad=math.radians(16)),
            {"motion": "straight"},
            ["heading"],
        ),
        (
            _fig(distance_m=0.2, planned_distance_m=0.2),
            {"motion": "straight", "locomotion": "legged", "body_length_m": 0.5},
            ["progress"],  # 0.4 body length per 10 s
        ),
        # a turn in place: a 23 % turn fails; a 95 % turn with little drift passes
        (
            _fig(heading_rad=0.23 * math.pi / 2, planned_heading_rad=math.pi / 2),
            {"motion": "turn", "body_length_m": 0.3},
            ["turn"],
        ),
        (
            _fig(
                heading_rad=0.95 * math.pi / 2,
                planned_heading_rad=math.pi / 2,
                final_pose_error_m=0.02,
            ),
            {"motion": "turn", "body_length_m": 0.3},
            [],
        ),
        (
            _fig(heading_rad=math.pi / 2, planned_heading_rad=math.pi / 2, final_pose_error_m=0.05),
            {"motion": "turn", "body_length_m": 0.3},
            ["pose"],
        ),
        # an arc: 10 % of the path length
        (
            _fig(
                heading_rad=1.0, planned_heading_rad=1.0, final_pose_error_m=0.09, path_length_m=1.0
            ),
            {"motion": "arc"},
            [],
        ),
        (
            _fig(
                heading_rad=0.8, planned_heading_rad=1.0, final_pose_error_m=0.11, path_length_m=1.0
            ),
            {"motion": "arc"},
            ["turn", "pose"],
        ),
        # snake crawl and rotation
        (_fig(distance_m=0.26), {"motion": "crawl", "body_length_m": 1.0}, []),
        (_fig(distance_m=0.24), {"motion": "crawl", "body_length_m": 1.0}, ["progress"]),
        (_fig(heading_rad=math.radians(50)), {"motion": "rotate", "turn": 1}, []),
        (_fig(heading_rad=math.radians(50)), {"motion": "rotate", "turn": -1}, ["progress"]),
        (_fig(heading_rad=math.radians(40)), {"motion": "rotate", "turn": 1}, ["progress"]),
        # holding still
        (_fig(drift_m=0.05), {"motion": "hold", "body_length_m": 0.2}, ["drift"]),
        # manipulators: 5 mm, 5 deg
        (_fig(placing_error_m=0.0049), {"motion": "place"}, []),
        (_fig(placing_error_m=0.0051), {"motion": "place"}, ["placing"]),
        (_fig(), {"motion": "place"}, ["placing"]),  # nothing measured is no success
        (
            _fig(placing_error_m=0.001, orientation_error_rad=math.radians(6)),
            {"motion": "orient", "orientation_rpy": (0, 0, 0)},
            ["orientation"],
        ),
        # static stability: a promised smallest margin, judged on the measured one
        (
            _fig(distance_m=1.0, planned_distance_m=1.0, support_margin_m=0.004),
            {"motion": "straight", "min_stability_margin_m": 0.02},
            [],
        ),
        (
            _fig(distance_m=1.0, planned_distance_m=1.0, support_margin_m=-0.001),
            {"motion": "straight", "min_stability_margin_m": 0.02},
            ["stability"],
        ),
        (  # nothing measured is no support
            _fig(distance_m=1.0, planned_distance_m=1.0),
            {"motion": "straight", "min_stability_margin_m": 0.02},
            ["stability"],
        ),
        (  # no promise (the humanoid's pendulum gait): not judged
            _fig(distance_m=1.0, planned_distance_m=1.0, support_margin_m=-0.01),
            {"motion": "straight"},
            [],
        ),
        # falling and saturating fail whatever the motion
        (_fig(fell=True, placing_error_m=0.0), {"motion": "place"}, ["fell"]),
        (_fig(saturated_fraction=0.051, placing_error_m=0.0), {"motion": "place"}, ["saturated"]),
        (_fig(), {"motion": "somersault"}, ["unplanned"]),
    ],
)
def test_judge(fig, info, failed):
    assert judge(fig, info, free=True) == failed


def test_a_fixed_base_needs_no_plan_but_a_free_robot_does():
    assert judge(_fig(), {}, free=False) == []
    assert judge(_fig(), {}, free=True) == ["unplanned"]
