"""Sensing abilities simulated as closed loops (program/sensing.py): a line follower and an
obstacle avoider, judged on what the robot did."""

from __future__ import annotations

from pathlib import Path

import pytest

from program import sensing
from synth.verification.verdict import judge

#: A cart with both sensing abilities, not verified (its runs are judged here).
SENSING_CART = ("driving", "line-tracking", "obstacle-avoidance", "--no-verify")


@pytest.fixture(scope="module")
def cart(designs) -> Path:
    """The session's design (tests/conftest.py): tests/synth/commands/test_simulate_cli.py
    asks the same."""
    return designs(*SENSING_CART).folder


def test_a_cart_follows_a_line_and_passes_an_obstacle(cart) -> None:
    from program.session import Session

    s = Session(cart)
    assert set(s.sensing) == {"line-tracking", "obstacle-avoidance"}
    line = s.do("line-tracking", course="wave", radius=0.5, length=1.5)["figures"]
    assert line["verdict"] == "ok", line
    assert line["line_lost_s"] <= 0.5 and line["line_progress_m"] >= 0.9 * 1.5
    # from where the line follower ended, in whatever heading it has
    avoid = s.do("obstacle-avoidance", distance=1.2, width=0.3)["figures"]
    assert avoid["verdict"] == "ok", avoid
    assert avoid["obstacle_contact_s"] == 0 and avoid["distance_m"] >= 1.2
    assert avoid["min_range_m"] < 1.0  # it did see the obstacle


def test_a_robot_that_cannot_turn_loses_the_line(cart, monkeypatch) -> None:
    """Built to fail: with no turn gain the cart drives straight off a circle."""
    from program.session import Session

    monkeypatch.setattr(sensing, "TURN_GAIN", 0.0)
    f = Session(cart).do("line-tracking", radius=0.3, length=1.0)["figures"]
    assert "lost" in f["verdict"] and f["line_lost_s"] > 0.5


def test_a_blind_robot_hits_the_obstacle(cart, monkeypatch) -> None:
    """Built to fail: a ranger that never sees anything drives into the box."""
    from program.session import Session

    monkeypatch.setattr(sensing.Rig, "range", lambda self: sensing.RANGER_MAX_M)
    f = Session(cart).do("obstacle-avoidance", distance=1.0, width=0.4)["figures"]
    assert "collision" in f["verdict"] and f["obstacle_contact_s"] > 0


@pytest.mark.parametrize(
    "fig, motion, failed",
    [
        (
            {"line_lost_s": 0.6, "line_progress_m": 2.0, "planned_distance_m": 2.0},
            "follow-line",
            ["lost"],
        ),
        (
            {"line_lost_s": 0.0, "line_progress_m": 1.7, "planned_distance_m": 2.0},
            "follow-line",
            ["progress"],
        ),
        (
            {"line_lost_s": 0.5, "line_progress_m": 1.8, "planned_distance_m": 2.0},
            "follow-line",
            [],
        ),
        (
            {"obstacle_contact_s": 0.002, "distance_m": 1.5, "planned_distance_m": 1.5},
            "avoid",
            ["collision"],
        ),
        (
            {"obstacle_contact_s": 0.0, "distance_m": 1.4, "planned_distance_m": 1.5},
            "avoid",
            ["progress"],
        ),
        ({"obstacle_contact_s": 0.0, "distance_m": 1.5, "planned_distance_m": 1.5}, "avoid", []),
    ],
)
def test_sensing_verdicts(fig: dict, motion: str, failed: list) -> None:
    assert judge({"seconds": 10.0, **fig}, {"motion": motion}, True) == failed


def test_sensing_needs_a_steerable_behaviour() -> None:
    """A behaviour is steered when its spec declares which parameters play the roles
    (gaits.steering.SteerableSpec): a plain spec gives no sensing behaviour, and the
    ability stays not simulated; a driving robot gets one per sensing ability."""
    from gaits.base import BehaviorSpec, Parameter
    from gaits.steering import SteerableSpec

    params = (
        Parameter("v", "float", 0.1, "", "m/s", low=-0.4, high=0.4),
        Parameter("w", "float", 0.0, "", "rad/s", low=-3, high=3),
        Parameter("seconds", "float", 1.0, ""),
    )
    plain = {"driving": BehaviorSpec("driving", "", params)}
    assert sensing.sensing_behaviors(plain, ["driving", "line-tracking"]) == {}
    roles = (("speed", "v"), ("turn", "w"), ("seconds", "seconds"))
    drive = {"driving": SteerableSpec("driving", "", params, steer=roles)}
    got = sensing.sensing_behaviors(drive, ["driving", "line-tracking"])
    assert list(got) == ["line-tracking"]
    speed = {p.name: p for p in got["line-tracking"].params}["speed"]
    assert speed.high == 0.4 and speed.default == 0.2


def test_design_verifies_sensing_abilities_where_it_can(cli) -> None:
    """A wheeled design's sensing abilities are simulated and recorded like its behaviours;
    so are a legged one's (walking arcs stride by stride, tests/program/test_sensing_gaits.py)."""
    import json

    r = cli("design", "driving", "line-tracking", "--json")
    assert r.code == 0, r.err
    v = json.loads(r.out)["verified"]
    line = {b["behavior"]: b for b in v["behaviors"]}["line-tracking"]
    assert line["verdict"] == "ok" and line["ability"] == "line-tracking"
    assert line["line_progress_m"] >= 0.9 * line["planned_distance_m"]
    assert "line-tracking" not in v["not_simulated"]
    r = cli(
        "design",
        "walking",
        "line-tracking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=no",
        "--json",
    )
    assert r.code == 0, r.err
    v = json.loads(r.out)["verified"]
    assert v["not_simulated"] == []
    line = {b["behavior"]: b for b in v["behaviors"]}["line-tracking"]
    assert line["verdict"] == "ok" and line["line_lost_s"] <= 0.5
