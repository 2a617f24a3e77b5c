"""Sensing abilities on gaits steered stride by stride (program/sensing.py): a legged robot
walking arcs follows a line and steps around an obstacle, a sidewinding snake steered by
its turn bias passes an obstacle. The robot types are written in KIF here (legged) or
chosen by abilities (snake); no test names a shipped type."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import pytest

from gaits.base import BehaviorSpec, Parameter
from gaits.steering import SteerableSpec
from program import sensing
from tests.kinematics.test_bodyplan import legged_kif


def _bundle(folder: Path, *argv: str) -> Path:
    from synth.commands.cli import main

    err = io.StringIO()
    code = main([*argv, "--no-input", "--no-verify", "--out", str(folder)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    return folder


@pytest.fixture(scope="module")
def walker(tmp_path_factory) -> Path:
    """A four-legged robot type of our own, with both sensing abilities."""
    root = tmp_path_factory.mktemp("walker")
    kif = root / "walker.kif"
    kif.write_text(legged_kif("Walker4", 4, "four-leg-walking"))
    return _bundle(
        root / "bundle",
        "design",
        "four-leg-walking",
        "line-tracking",
        "obstacle-avoidance",
        "--ontology",
        str(kif),
    )


@pytest.fixture(scope="module")
def snake(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("snake")
    return _bundle(root / "bundle", "design", "sidewinding", "obstacle-avoidance")


# -- the roles are data ---------------------------------------------------------------


def _spec(turn_unit: str, period: str = "seconds", **extra) -> SteerableSpec:
    return SteerableSpec(
        "go",
        "",
        (
            Parameter("v", "float", 0.1, "", "m/s", low=0, high=0.3),
            Parameter("w", "float", 0.0, "", turn_unit, low=-3, high=3),
            Parameter(period, "float", 1.0, ""),
        ),
        steer=(("speed", "v"), ("turn", "w"), (period, period)),
        **extra,
    )


def test_steering_reads_the_roles_from_the_spec() -> None:
    rate = sensing.steering({"go": _spec("rad/s")})
    assert rate is not None and rate.kind == "rate" and not rate.strides
    arc = sensing.steering({"go": _spec("rad/m", "steps")})
    assert arc is not None and arc.kind == "curvature" and arc.strides
    bias = sensing.steering({"go": _spec("", "steps")})
    assert bias is not None and bias.kind == "bias"
    # a plain spec declares nothing, a rate needs a period of any length
    assert sensing.steering({"go": BehaviorSpec("go", "", _spec("rad/s").params)}) is None
    assert sensing.steering({"go": _spec("rad/s", "steps")}) is None
    # a learnt bias steers no line follower; an obstacle avoider it does
    got = sensing.sensing_behaviors(
        {"go": _spec("", "steps")}, ["line-tracking", "obstacle-avoidance"]
    )
    assert list(got) == ["obstacle-avoidance"]


@pytest.mark.parametrize(
    "steer",
    [
        (("speed", "v"), ("turn", "w")),  # no period
        (("speed", "v"), ("turn", "w"), ("seconds", "seconds"), ("steps", "seconds")),
        (("speed", "v"), ("turn", "nope"), ("seconds", "seconds")),
        (("speed", "v"), ("yaw", "w"), ("seconds", "seconds")),
    ],
)
def test_a_spec_with_bad_roles_is_refused(steer) -> None:
    params = _spec("rad/s").params
    with pytest.raises(ValueError, match="go"):
        SteerableSpec("go", "", params, steer=steer)


# -- the steerable gaits --------------------------------------------------------------


def test_walking_follows_an_arc_and_refuses_one_too_tight(walker) -> None:
    from gaits import controller_for
    from gaits.base import DesignGeometry

    rec = json.loads((walker / "design.json").read_text())
    c = controller_for(DesignGeometry.from_record(rec))
    straight = c.run("walking", steps=1)
    assert straight.info["motion"] == "straight"  # curvature 0: walking as it was
    for k in (-2.0, 1.0, 3.0):
        arc = c.run("walking", steps=1, curvature=k)
        dx, dy, dyaw = arc.info["planned_pose"]
        assert arc.info["motion"] == "arc"
        assert dyaw == pytest.approx(k * arc.info["path_length_m"], rel=0.02)
        assert math.copysign(1, dy) == math.copysign(1, k)
    with pytest.raises(ValueError, match="curvature: 40 rad/m is tighter"):
        c.run("walking", steps=1, curvature=40.0)


def test_the_turn_bias_grades_the_sidewinding_wave(snake) -> None:
    import numpy as np

    from gaits import controller_for
    from gaits.base import DesignGeometry
    from gaits.snake import turn_scale

    rec = json.loads((snake / "design.json").read_text())
    c = controller_for(DesignGeometry.from_record(rec))
    plain = c.run("sidewinding", cycles=2)
    assert np.array_equal(plain.positions, c.run("sidewinding", cycles=2, turn=0.0).positions)
    graded = c.run("sidewinding", cycles=2, turn=0.5)
    m = c.modules
    yaw = slice(1, None, 2)  # the horizontal modules
    ratio = np.abs(graded.positions[:, yaw]).max(axis=0) / np.abs(plain.positions[:, yaw]).max(
        axis=0
    )
    assert ratio == pytest.approx(turn_scale(m, 0.5)[yaw], rel=1e-6)
    assert np.array_equal(graded.positions[:, 0::2], plain.positions[:, 0::2])  # lift kept


# -- the closed loops -----------------------------------------------------------------


def test_a_legged_robot_follows_a_line(walker) -> None:
    from program.session import Session

    s = Session(walker)
    assert set(s.sensing) == {"line-tracking", "obstacle-avoidance"}
    f = s.do("line-tracking")["figures"]
    assert f["verdict"] == "ok", f
    assert f["line_lost_s"] <= 0.5 and f["line_progress_m"] >= 0.9 * f["planned_distance_m"]


def test_a_line_tighter_than_the_legs_can_walk_is_lost(walker) -> None:
    """Built to fail: the walker's arcs are no tighter than about 4.5 rad/m; a circle of
    0.2 m (5 rad/m, and 0.2 m of it passed blind before the sensors tell which way it
    bends) leaves the sensors' span."""
    from program.session import Session

    f = Session(walker).do("line-tracking", radius=0.2, length=0.4)["figures"]
    assert "lost" in f["verdict"] and f["line_lost_s"] > 0.5


def test_a_legged_robot_steps_around_an_obstacle(walker) -> None:
    from program.session import Session

    f = Session(walker).do("obstacle-avoidance")["figures"]
    assert f["verdict"] == "ok", f
    assert f["obstacle_contact_s"] == 0 and f["distance_m"] >= f["planned_distance_m"]
    assert f["min_range_m"] < 0.5  # it did see the obstacle


def test_a_sidewinding_snake_passes_an_obstacle(snake) -> None:
    from program.session import Session

    s = Session(snake)
    assert set(s.sensing) == {"obstacle-avoidance"}
    f = s.do("obstacle-avoidance")["figures"]
    assert f["verdict"] == "ok", f
    assert f["obstacle_contact_s"] == 0 and f["distance_m"] >= f["planned_distance_m"]


def test_a_blind_snake_hits_the_obstacle(snake, monkeypatch) -> None:
    """Built to fail: a ranger that never sees anything sidewinds into the box."""
    from program.session import Session

    monkeypatch.setattr(sensing.Rig, "range", lambda self: sensing.RANGER_MAX_M)
    f = Session(snake).do("obstacle-avoidance", width=0.6)["figures"]
    assert "collision" in f["verdict"] and f["obstacle_contact_s"] > 0


def test_the_wave_starts_along_the_heading_only_for_stride_loops() -> None:
    """The stride loop's wave starts tangent to the heading and bends left at its tightest
    curve; the wheeled loop's (``tangent`` off) is the sine it always was."""
    import numpy as np

    start = np.array([0.3, -0.2])
    for radius in (0.5, 1.0, 2.0):
        c = sensing.Course.make("wave", radius, 0.5, start, 0.7, tangent=True)
        d = c.points[1] - c.points[0]
        assert abs(math.atan2(d[1], d[0]) - 0.7) < 0.01
        old = sensing.Course.make("wave", radius, 0.5, start, 0.7)
        d = old.points[1] - old.points[0]
        assert math.degrees(abs(math.atan2(d[1], d[0]) - 0.7)) > 30  # the old start
        circle = sensing.Course.make("circle", radius, 0.5, start, 0.7, tangent=True)
        assert np.array_equal(
            circle.points, sensing.Course.make("circle", radius, 0.5, start, 0.7).points
        )


def test_a_legged_robot_follows_a_wave(walker) -> None:
    from program.session import Session

    f = Session(walker).do("line-tracking", course="wave", radius=1.0)["figures"]
    assert f["verdict"] == "ok", f


def test_a_wave_starting_off_the_heading_is_lost(walker, monkeypatch) -> None:
    """Built to fail: the wave as the wheeled loop lays it (32-36 degrees off the heading
    at the start) loses a robot that decides once a gait period."""
    from program.session import Session

    make = sensing.Course.make.__func__

    def untangent(cls, *a, tangent=False, **k):
        return make(cls, *a, **k)

    monkeypatch.setattr(sensing.Course, "make", classmethod(untangent))
    f = Session(walker).do("line-tracking", course="wave", radius=1.0)["figures"]
    assert f["verdict"] != "ok" and f["line_lost_s"] > 0, f
