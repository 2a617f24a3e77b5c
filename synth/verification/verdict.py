"""The verdict on a simulated behaviour: judged on what the robot did, never on its plan.

A behaviour declares what it promises in its trajectory's ``info`` (see
:class:`gaits.base.Trajectory`: ``motion``, ``planned_pose``, ``direction``,
``body_length_m``, ``target``...); :func:`judge` compares the figures measured in MuJoCo
(:func:`synth.verification.simulate.simulate`) with that promise and returns the criteria that
failed. Every threshold is here and in the README's *Verdicts* table.

Criteria (names as they appear in ``verdict``):

- ``fell``: the trunk fell or collapsed: below ``COLLAPSE_HEIGHT`` of its standing height
  or tilted past ``COLLAPSE_TILT`` at any sample (robots that stand on feet or wheels).
- ``saturated``: more than ``MAX_SATURATED_FRACTION`` of the samples had an actuator at its
  torque limit.
- ``stability``: a behaviour that promises static stability (a smallest planned margin,
  ``min_stability_margin_m``: the multipeds' gaits; the humanoid's pendulum gait promises
  none) let the robot's centre of mass leave the support polygon of its
  contacts with the ground by more than ``SUPPORT_MARGIN`` at a sampled instant, or had
  no contact (``support_margin_m``, measured in MuJoCo, see
  :func:`synth.verification.simulate.support_margin_of`).
- ``unplanned``: a free-moving robot's behaviour that does not say what it promises.
- ``distance``, ``heading``: straight travel covered ``STRAIGHT_DISTANCE`` x the planned
  distance along the planned direction, and kept its heading within ``STRAIGHT_HEADING``.
- ``pose``: an arc ended within ``POSE_FRACTION`` of the path length of its planned
  position; a turn in place drifted at most ``POSE_FRACTION`` of the body length.
- ``turn``: an arc or a turn reached its planned change of heading within
  ``TURN_FRACTION`` of it (at least ``TURN_FLOOR``).
- ``progress``: a crawl moved at least ``CRAWL_RATE`` body lengths per 10 s along its
  direction; legged travel at least ``LEGGED_RATE``; a rotation turned at least
  ``ROTATE_RATE`` per 10 s in its sense.
- ``drift``: a robot asked to hold moved more than ``HOLD_DRIFT`` of its body length.
- ``placing``, ``orientation``: a manipulator brought the gripper within ``PLACING`` of the
  target and the tool within ``ORIENTATION`` of the commanded orientation.
- ``lost``: a line follower let the line leave the span of its two sensors for longer
  than ``LINE_LOST_S`` at a time; ``progress``: it covered less than ``LINE_PROGRESS`` of
  the commanded length along the line.
- ``collision``: an obstacle avoider touched the obstacle; ``progress``: it did not reach
  the goal line.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

COLLAPSE_HEIGHT = 0.70  # of the standing height
COLLAPSE_TILT = math.radians(45)
SATURATION_LEVEL = 0.999  # |force| / limit at which an actuator counts as saturated
MAX_SATURATED_FRACTION = 0.05
SUPPORT_MARGIN = 0.0  # m: the measured static stability margin may not go below this
STRAIGHT_DISTANCE = (0.8, 1.25)  # x planned distance
STRAIGHT_HEADING = math.radians(15)
POSE_FRACTION = 0.10  # of the path length (arcs) or of the body length (turns)
TURN_FRACTION = 0.10  # of the planned change of heading
TURN_FLOOR = math.radians(3)
CRAWL_RATE = 0.25  # body lengths per 10 s
LEGGED_RATE = 0.5  # body lengths per 10 s
ROTATE_RATE = math.radians(45)  # per 10 s
HOLD_DRIFT = 0.10  # of the body length
PLACING = 0.005  # m
ORIENTATION = math.radians(5)
LINE_LOST_S = 0.5  # s the line may be outside the sensors' span at a time
LINE_PROGRESS = 0.9  # of the commanded length along the line

MOTIONS = (
    "straight",
    "arc",
    "turn",
    "crawl",
    "rotate",
    "hold",
    "place",
    "orient",
    "follow-line",
    "avoid",
)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def judge(fig: Mapping[str, object], info: Mapping[str, object], free: bool) -> list[str]:
    """The criteria ``fig`` (a simulation's figures, :meth:`SimResult.to_dict` keys) fails
    against the promise in ``info``; empty when the behaviour kept it. ``free``: the robot
    moves freely (not welded to the world)."""
    failed: list[str] = []
    if fig.get("fell"):
        failed.append("fell")
    if float(fig.get("saturated_fraction") or 0.0) > MAX_SATURATED_FRACTION:
        failed.append("saturated")
    if free and info.get("min_stability_margin_m") is not None:
        measured = fig.get("support_margin_m")
        if measured is None or float(measured) < SUPPORT_MARGIN:  # type: ignore[arg-type]
            failed.append("stability")
    motion = info.get("motion")
    if motion is None:
        if free:
            failed.append("unplanned")
        return failed
    seconds = max(float(fig["seconds"]), 1e-9)  # type: ignore[arg-type]
    body = info.get("body_length_m")
    heading = float(fig.get("heading_rad") or 0.0)
    if motion == "straight":
        planned = float(fig.get("planned_distance_m") or 0.0)
        ratio = float(fig.get("distance_m") or 0.0) / max(planned, 1e-9)
        if not STRAIGHT_DISTANCE[0] <= ratio <= STRAIGHT_DISTANCE[1]:
            failed.append("distance")
        if abs(_wrap(heading - float(fig.get("planned_heading_rad") or 0.0))) > STRAIGHT_HEADING:
            failed.append("heading")
        if info.get("locomotion") == "legged" and body is not None:
            rate = float(fig.get("distance_m") or 0.0) / float(body) * 10 / seconds
            if rate < LEGGED_RATE:
                failed.append("progress")
    elif motion in ("arc", "turn"):
        planned_yaw = float(fig.get("planned_heading_rad") or 0.0)
        if abs(heading - planned_yaw) > max(TURN_FRACTION * abs(planned_yaw), TURN_FLOOR):
            failed.append("turn")
        scale = fig.get("path_length_m") if motion == "arc" else body
        if scale is None:
            failed.append("unplanned")
        elif float(fig.get("final_pose_error_m") or 0.0) > POSE_FRACTION * float(scale):
            failed.append("pose")
    elif motion == "crawl":
        if body is None:
            failed.append("unplanned")
        else:
            rate = float(fig.get("distance_m") or 0.0) / float(body) * 10 / seconds
            if rate < CRAWL_RATE:
                failed.append("progress")
    elif motion == "rotate":
        sense = float(info.get("turn") or 0.0)  # type: ignore[arg-type]
        if sense == 0 or heading * math.copysign(1.0, sense) * 10 / seconds < ROTATE_RATE:
            failed.append("progress")
    elif motion == "hold":
        if body is not None and float(fig.get("drift_m") or 0.0) > HOLD_DRIFT * float(body):
            failed.append("drift")
    elif motion in ("place", "orient"):
        err = fig.get("placing_error_m")
        if err is None or float(err) > PLACING:
            failed.append("placing")
        if motion == "orient" or info.get("orientation_rpy") is not None:
            o = fig.get("orientation_error_rad")
            if o is None or float(o) > ORIENTATION:
                failed.append("orientation")
    elif motion == "follow-line":
        if float(fig.get("line_lost_s") or 0.0) > LINE_LOST_S:
            failed.append("lost")
        planned = float(fig.get("planned_distance_m") or 0.0)
        if float(fig.get("line_progress_m") or 0.0) < LINE_PROGRESS * planned:
            failed.append("progress")
    elif motion == "avoid":
        if float(fig.get("obstacle_contact_s") or 0.0) > 0:
            failed.append("collision")
        planned = float(fig.get("planned_distance_m") or 0.0)
        if float(fig.get("distance_m") or 0.0) < planned:
            failed.append("progress")
    else:
        failed.append("unplanned")
    return failed


def explain(fig: Mapping[str, object], failed: list[str]) -> str:
    """The failed criteria of ``fig`` with the figure and the threshold of each, e.g.
    ``saturated (saturated_fraction 0.25 > 0.05)``."""

    def f(key: str, scale: float = 1.0, unit: str = "") -> str:
        x = fig.get(key)
        return "none" if x is None else f"{float(x) * scale:.3g}{unit}"  # type: ignore[arg-type]

    deg = 180 / math.pi
    what = {
        "fell": lambda: (
            f"fell at {f('fell_at_s')} s (height {f('min_height_ratio')} of standing, "
            f"limit {COLLAPSE_HEIGHT}; tilt {f('max_tilt_rad', deg)} deg, "
            f"limit {COLLAPSE_TILT * deg:.0f})"
        ),
        "saturated": lambda: (
            f"saturated_fraction {f('saturated_fraction')} > {MAX_SATURATED_FRACTION}"
        ),
        "distance": lambda: (
            f"distance {f('distance_m')} m of {f('planned_distance_m')} m planned, "
            f"needs {STRAIGHT_DISTANCE[0]}-{STRAIGHT_DISTANCE[1]} x"
        ),
        "heading": lambda: (
            f"heading {f('heading_rad', deg)} deg, planned {f('planned_heading_rad', deg)}"
            f" +- {STRAIGHT_HEADING * deg:.0f}"
        ),
        "turn": lambda: (
            f"turned {f('heading_rad', deg)} deg of {f('planned_heading_rad', deg)} planned "
            f"(+- {TURN_FRACTION:.0%})"
        ),
        "pose": lambda: f"ended {f('final_pose_error_m')} m from the planned pose",
        "progress": lambda: (
            f"followed the line {f('line_progress_m')} m of {f('planned_distance_m')} m"
            if fig.get("line_progress_m") is not None
            else f"moved {f('distance_m')} m / turned {f('heading_rad', deg)} deg in "
            f"{f('seconds')} s (too slow)"
        ),
        "drift": lambda: f"drifted {f('drift_m')} m",
        "stability": lambda: (
            "an instant without contact with the ground"
            if fig.get("support_margin_m") is None
            else f"support_margin {f('support_margin_m', 1000)} mm < {SUPPORT_MARGIN * 1000:g}:"
            " the centre of mass left the feet's support polygon"
        ),
        "placing": lambda: f"placing error {f('placing_error_m', 1000)} mm > {PLACING * 1000:g}",
        "orientation": lambda: (
            f"orientation error {f('orientation_error_rad', deg)} deg > {ORIENTATION * deg:g}"
        ),
        "unplanned": lambda: "the behaviour does not say what it promises",
        "lost": lambda: f"lost the line for {f('line_lost_s')} s > {LINE_LOST_S:g}",
        "collision": lambda: f"touched the obstacle for {f('obstacle_contact_s')} s",
    }
    return "; ".join(f"{c} ({what[c]()})" if c in what else c for c in failed)
