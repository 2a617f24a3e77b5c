"""Humanoid walking steered by a curvature (gaits/humanoid.py: the hips' yaw turns each
foot as it swings) and the sensing loops on it (program/sensing.py, stride by stride).
The humanoid is the one the abilities pick (walking, grasping, both sensing abilities);
no test names a robot type."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from program import sensing

ASK = ("design", "walking", "grasping", "line-tracking", "obstacle-avoidance")


def _design(folder: Path, *flags: str) -> tuple[int, str, str]:
    from synth.commands.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main([*ASK, "--no-input", *flags, "--out", str(folder)], out, err)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def humanoid(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("humanoid") / "bundle"
    code, _, err = _design(folder, "--no-verify")
    assert code == 0, err
    rec = json.loads((folder / "design.json").read_text())
    assert {"grasping", "walking"} <= set(rec["abilities"])
    return folder


def _controller(folder: Path):
    from gaits import controller_for
    from gaits.base import DesignGeometry

    return controller_for(
        DesignGeometry.from_record(json.loads((folder / "design.json").read_text()))
    )


# -- the steerable walk --------------------------------------------------------------


def test_walking_is_steerable_by_curvature_running_is_not(humanoid) -> None:
    from gaits.steering import SteerableSpec

    b = _controller(humanoid).behaviors
    assert isinstance(b["walking"], SteerableSpec)
    assert b["walking"].roles == {"speed": "step_length", "turn": "curvature", "steps": "steps"}
    assert not isinstance(b["running"], SteerableSpec)
    steer = sensing.steering(b)
    assert steer is not None and steer.kind == "curvature" and steer.strides


def test_an_arc_turns_the_hips_and_plans_the_turn(humanoid) -> None:
    c = _controller(humanoid)
    straight = c.run("walking", steps=2)
    assert np.array_equal(straight.positions, c.run("walking", steps=2, curvature=0.0).positions)
    assert straight.info["planned_pose"][2] == 0.0 and straight.info["motion"] == "straight"
    yaw = [c.joints.index("l_hip_yaw"), c.joints.index("r_hip_yaw")]
    assert np.abs(straight.positions[:, yaw]).max() == 0.0
    amplitude = {}
    for k in (-8.0, 4.0, 8.0):
        arc = c.run("walking", steps=2, curvature=k)
        dx, dy, dyaw = arc.info["planned_pose"]
        assert arc.info["motion"] == "arc" and arc.info["curvature_rad_m"] == k
        assert dyaw == pytest.approx(k * arc.info["path_length_m"], rel=1e-9)
        assert math.copysign(1, dy) == math.copysign(1, k)
        amplitude[k] = np.abs(arc.info.get("planned_positions", arc.positions)[:, yaw]).max()
        # every other joint is the straight walk's
        others = [j for j in range(len(c.joints)) if j not in yaw]
        plan = arc.info.get("planned_positions", arc.positions)
        base = straight.info.get("planned_positions", straight.positions)
        assert np.allclose(plan[:, others], base[:, others])
    assert amplitude[8.0] == pytest.approx(2 * amplitude[4.0], rel=1e-6)
    assert amplitude[-8.0] == pytest.approx(amplitude[8.0], rel=1e-6)


def test_a_curvature_beyond_the_hips_range_is_refused(humanoid) -> None:
    """Built to fail: past the hip yaw's range over the ankles' swing the walk is refused,
    naming the tightest; a longer step lowers it."""
    c = _controller(humanoid)
    top = c.run("walking", steps=1, curvature=1.0)  # any arc: the bound is the same
    with pytest.raises(ValueError, match=r"curvature: 45 rad/m is tighter .* at most ([\d.]+)"):
        c.run("walking", steps=1, curvature=45.0)
    try:
        c.run("walking", steps=1, curvature=45.0)
    except ValueError as exc:
        tightest = float(str(exc).rsplit("at most ", 1)[1].split()[0])
    assert 10 < tightest < 45
    c.run("walking", steps=1, curvature=tightest)  # the bound itself walks
    with pytest.raises(ValueError, match="tighter"):
        c.run("walking", steps=1, curvature=-(tightest + 0.05))
    longer = float(top.info["step_length_m"]) * 1.2
    with pytest.raises(ValueError, match="tighter"):
        c.run("walking", steps=1, step_length=longer, curvature=tightest)


@pytest.mark.parametrize("k", [-10.0, 5.0, 20.0])
def test_arcs_turn_the_robot_in_simulation(humanoid, k) -> None:
    from program.session import Session

    f = Session(humanoid).do("walking", steps=4, curvature=k)["figures"]
    assert f["verdict"] == "ok", f
    assert not f["fell"]
    assert f["heading_rad"] == pytest.approx(f["planned_heading_rad"], rel=0.15)


# -- the closed loops ------------------------------------------------------------------


def test_a_humanoid_follows_a_line(humanoid) -> None:
    from program.session import Session

    s = Session(humanoid)
    assert set(s.sensing) == {"line-tracking", "obstacle-avoidance"}
    f = s.do("line-tracking", radius=1.0)["figures"]
    assert f["verdict"] == "ok", f
    assert f["line_lost_s"] <= 0.5 and f["line_progress_m"] >= 0.9 * f["planned_distance_m"]


def test_a_line_too_tight_is_lost(humanoid) -> None:
    """Built to fail: a 0.2 m circle bends away from the sensors within the period the
    humanoid walks blind (4 cm) before it can turn."""
    from program.session import Session

    f = Session(humanoid).do("line-tracking", radius=0.2, length=0.4)["figures"]
    assert "lost" in f["verdict"] and f["line_lost_s"] > 0.5


def test_a_humanoid_walks_around_an_obstacle(humanoid) -> None:
    from program.session import Session

    f = Session(humanoid).do("obstacle-avoidance")["figures"]
    assert f["verdict"] == "ok", f
    assert f["obstacle_contact_s"] == 0 and f["distance_m"] >= f["planned_distance_m"]
    assert f["min_range_m"] < 0.5  # it did see the obstacle (below its ranger)


def test_a_blind_humanoid_walks_into_the_obstacle(humanoid, monkeypatch) -> None:
    """Built to fail: a ranger that never sees anything walks into the box."""
    from program.session import Session

    monkeypatch.setattr(sensing.Rig, "range", lambda self: sensing.RANGER_MAX_M)
    f = Session(humanoid).do("obstacle-avoidance")["figures"]
    assert "collision" in f["verdict"] and f["obstacle_contact_s"] > 0


def test_a_ranger_above_the_box_sees_it_by_its_beams_lower_edge(humanoid) -> None:
    """The humanoid's ranger sits above the box's top: only the beam's lower edge sees it
    (a level beam would not)."""
    from program.session import Session

    s = Session(humanoid)
    s.follow(s.controller.run("walking", steps=1))  # standing crouched
    rig = sensing.Rig(s, np.array([1.0, 0.0]))
    assert rig.world(rig.ranger)[2] > sensing.OBSTACLE_HEIGHT_M
    here = rig.world(rig.ranger)[:2]
    sensing._place_obstacle(s, here + np.array([0.5, 0.0]), rig.heading(), 0.3)
    front = 0.5 - sensing.OBSTACLE_DEPTH_M / 2
    assert rig.range() == pytest.approx(front / math.cos(sensing.RANGER_HALF_ANGLE), abs=0.02)


def test_the_design_verifies_both_abilities(tmp_path) -> None:
    """The acceptance: the request demanding both sensing abilities is built, verified."""
    code, out, err = _design(tmp_path / "bundle")
    assert code == 0, err
    for ability in ("line-tracking", "obstacle-avoidance"):
        line = next(x for x in out.splitlines() if x.strip().startswith(ability))
        assert " ok " in line, line
