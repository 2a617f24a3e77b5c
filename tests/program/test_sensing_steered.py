"""Line-tracking on steered wheels (issue 21 item 4): ``driving`` rolls on from the turn
its last period ended on (``rolling``, ``w0``: no steering at rest, the steering turning
while the wheels roll, no faster than its servo turns under load), and the line follower
(program/sensing.py ``_line_rolling``) asks each period for the arc that brings its
sensors onto the line as located from their readings. KIF-only steered types of the
tests' own (tests/gaits/test_steered.py), never a shipped type's name."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from tests.gaits.test_steered import CART, FWD

#: case -> (KIF, ability, options)
TYPES = {
    "cart": (CART, "cart-driving", []),
    "fwd": (FWD, "front-driving", ["--param", "payload=0.3kg"]),
}


@pytest.fixture(scope="module")
def bundles(tmp_path_factory) -> dict[str, Path]:
    """Each KIF-only steered type with line-tracking, designed (not verified: its runs
    are judged here)."""
    from synth.commands.cli import main

    out = {}
    root = tmp_path_factory.mktemp("steerline")
    for case, (kif, ability, extra) in TYPES.items():
        src = root / f"{case}.kif"
        src.write_text(kif)
        folder = root / case
        o, e = io.StringIO(), io.StringIO()
        argv = ["design", ability, "line-tracking", "--ontology", str(src), "--no-input"]
        argv.append("--no-verify")  # (the loop is judged here, run by run)
        code = main([*argv, "--out", str(folder), *extra], out=o, err=e)
        assert code == 0, e.getvalue() + o.getvalue()
        out[case] = folder
    return out


def _controller(folder: Path):
    from program.session import Session

    return Session(folder).controller


@pytest.mark.parametrize("case", sorted(TYPES))
def test_driving_rolls_on_from_its_last_turn(bundles, case) -> None:
    """rolling = 1: the steering starts where w0 left it and turns toward w no faster than
    ROLL_STEER_FRACTION of its servo's speed; a change too large for the period is made
    in part (turn_end), the wheels never stop; rolling = 0 is the drive it was."""
    from gaits import steered

    c = _controller(bundles[case])
    g = c.steer
    v = round(c.v_max / 2, 3)
    k = 0.8 * g.k_max
    top = steered.ROLL_STEER_FRACTION * g.steer_speed
    for k0, k1, seconds in [(0.0, k, 0.05), (-k, k, 0.05), (0.3 * k, 0.35 * k, 0.05), (0, k, 3)]:
        traj = c.run("driving", v=v, w=k1 * v, seconds=seconds, rolling=1, w0=k0 * v)
        ns = len(c.steer_joints)
        angles, wheels = traj.positions[:, :ns], traj.velocities[:, ns:]
        start = np.array([g.angles(k0)[j] for j in c.steer_joints])
        assert np.allclose(angles[0], start)
        rate = np.abs(np.diff(angles, axis=0)) / np.diff(traj.times)[:, None]
        assert rate.max() <= top * 1.01
        assert np.all(np.abs(wheels) > 0)  # rolling, not steering at rest
        end = float(traj.info["turn_end"]) / v
        reach = (end - k0) / (k1 - k0)
        assert 0 < reach <= 1 + 1e-9
        assert np.allclose(angles[-1], [g.angles(end)[j] for j in c.steer_joints])
        assert traj.info["steer_s"] == 0.0
    # a long enough period reaches the arc; an arc held is the plain one's pose
    held = c.run("driving", v=v, w=k * v, seconds=1.0, rolling=1, w0=k * v)
    plain = c.run("driving", v=v, w=k * v, seconds=1.0, ramp=0.0)
    assert np.allclose(held.info["planned_pose"], plain.info["planned_pose"], atol=1e-6)
    # rolling = 0 (the default) steers at rest first, as before
    rest = c.run("driving", v=v, w=k * v, seconds=2.0)
    assert rest.info["steer_s"] > 0 and "turn_end" not in rest.info
    with pytest.raises(ValueError, match="tighter than the steering|outside"):
        c.run("driving", v=v, w=k * v, seconds=0.05, rolling=1, w0=1.5 * g.k_max * v)


def test_the_steering_may_not_jump_built_to_fail(bundles, monkeypatch) -> None:
    """Built to fail the rate check above: a servo asked for ten times the fraction turns
    faster than the rolling steering allows."""
    from gaits import steered

    c = _controller(bundles["cart"])
    v, k = round(c.v_max / 2, 3), 0.8 * c.steer.k_max
    allowed = steered.ROLL_STEER_FRACTION * c.steer.steer_speed
    monkeypatch.setattr(steered, "ROLL_STEER_FRACTION", 10 * steered.ROLL_STEER_FRACTION)
    # (a period of its own: plans are remembered)
    traj = c.run("driving", v=v, w=k * v, seconds=0.07, rolling=1, w0=-k * v)
    rate = np.abs(np.diff(traj.positions[:, 0])) / np.diff(traj.times)
    assert rate.max() > allowed * 1.01


def _follow(folder: Path, course: str, radius: float, share: float, length: float = 2.0):
    from program.session import Session

    s = Session(folder)
    top = {p.name: p for p in s.sensing["line-tracking"].params}["speed"].high
    return s.do(
        "line-tracking", course=course, radius=radius, length=length, speed=round(share * top, 3)
    )["figures"]


@pytest.mark.parametrize(
    ("case", "course", "radius", "share"),
    [
        ("cart", "circle", 0.5, 0.5),
        ("cart", "wave", 1.0, 0.25),
        ("fwd", "circle", 0.5, 0.25),
        ("fwd", "wave", 1.0, 0.5),
    ],
)
def test_a_steered_robot_follows_a_line(bundles, case, course, radius, share) -> None:
    f = _follow(bundles[case], course, radius, share)
    assert f["verdict"] == "ok", f
    assert f["line_lost_s"] <= 0.5 and f["line_progress_m"] >= 0.9 * 2.0
    assert f["saturated_fraction"] <= 0.05


def test_a_circle_tighter_than_the_steering_is_lost(bundles, monkeypatch) -> None:
    """Built to fail: a steering limit that allows no tighter a radius than 1 m (the
    curvature limit halved and halved again) on a 0.3 m circle: the robot runs wide of
    it and loses it."""
    from gaits.steered import SteerGeometry

    k_max = SteerGeometry.k_max.fget
    monkeypatch.setattr(SteerGeometry, "k_max", property(lambda g: min(k_max(g), 1.0)))
    f = _follow(bundles["cart"], "circle", 0.3, 0.5, length=1.0)
    assert "lost" in f["verdict"] and f["line_lost_s"] > 0.5, f
