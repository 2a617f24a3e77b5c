"""The humanoid's arcs with a measured turn (issue 22): a gait whose shape asks for it
(``GaitShape.measured_turn``: ``ROBUST_WALK``) gets its hips' yaw on an arc scaled by the
turn a probe arc measured on the design (``HumanoidController.calibration_probes`` and
``calibrate``, run by the verification as a skid-steer's are). The tuned walk turns about
0.88 x its planned heading (its hips' yaw fights itself while both feet are down, 45 % of
each step); calibrated, 0.95-1.04 x. Case built to fail: the same arc uncalibrated. The
default walk asks for no probe (its arcs turn as planned)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ARC = 5.0  # rad/m


def _parts(folder: Path, calibration: dict | None = None):
    from export.mjcf import load_mjcf
    from synth.verification.runs import controller_for_model
    from synth.verification.source import Bundle

    bundle = Bundle.read(folder)

    record, xml, meshes = bundle.record, bundle.xml, bundle.meshes
    if calibration is not None:
        record = {**record, "calibration": calibration}
    model = load_mjcf(xml, meshes)
    return record, model, controller_for_model(record, model)


def _turn(yaw: float) -> dict[str, np.ndarray]:
    """A series whose trunk turns from 0 to ``yaw`` rad about the vertical."""
    a = np.linspace(0.0, yaw, 50)
    root = np.zeros((50, 7))
    root[:, 3], root[:, 6] = np.cos(a / 2), np.sin(a / 2)
    return {"t": np.linspace(0.0, 5.0, 50), "root": root}


def test_the_default_walk_asks_for_no_probe(humanoid, without_imu) -> None:
    """The default walk (a biped without an IMU: ``WALK``, open loop) asks for no probe; the
    design with its IMU walks ``ROBUST_WALK`` and asks for one."""

    from export.mjcf import load_mjcf
    from synth.verification.runs import controller_for_model
    from synth.verification.source import Bundle

    bundle = Bundle.read(humanoid)

    record, xml, meshes = bundle.record, bundle.xml, bundle.meshes
    bare = controller_for_model(without_imu(record), load_mjcf(xml, meshes))
    assert bare.calibration_probes() == []
    _, _, ctl = _parts(humanoid)
    assert ctl.calibration_probes() == [("walking", {"curvature": 10.0})]


def test_the_gain_is_the_planned_turn_over_the_measured_one(humanoid, robust_walk) -> None:
    from gaits.humanoid import TURN_GAIN, TURN_GAIN_RANGE

    _, _, ctl = _parts(humanoid, {TURN_GAIN: 1.1})
    probe = SimpleNamespace(info={"planned_pose": (0.1, 0.1, 1.5)})
    assert ctl.calibrate([(probe, _turn(1.2))]) == {TURN_GAIN: pytest.approx(1.1 * 1.5 / 1.2)}
    assert ctl.calibrate([(probe, _turn(-0.3))]) == {}  # turned the other way: not a turn
    assert ctl.calibrate([]) == {}
    assert ctl.calibrate([(probe, _turn(0.1))]) == {TURN_GAIN: TURN_GAIN_RANGE[1]}


def test_a_calibrated_arc_turns_as_planned(humanoid, robust_walk) -> None:
    from synth.verification.runs import run_behavior

    record, model, ctl = _parts(humanoid)
    probes = ctl.calibration_probes()
    assert probes and probes[0][0] == "walking"
    runs = [(t, r.series) for t, r in (run_behavior(model, ctl, n, p) for n, p in probes)]
    calibration = ctl.calibrate(runs)
    _, model, calibrated = _parts(humanoid, calibration)
    assert calibrated.turn_gain > 1.05
    traj, r = run_behavior(model, calibrated, "walking", {"curvature": ARC})
    assert r.verdict == [], (r.verdict, r.heading_rad, r.planned_heading_rad)
    assert abs(r.heading_rad / r.planned_heading_rad - 1) < 0.05


def test_an_uncalibrated_arc_turns_short(humanoid, robust_walk) -> None:
    """Built to fail: the tuned walk's arc without the measured gain."""
    from synth.verification.runs import run_behavior

    _, model, ctl = _parts(humanoid)
    _, r = run_behavior(model, ctl, "walking", {"curvature": ARC})
    assert "turn" in r.verdict
    assert r.heading_rad / r.planned_heading_rad < 0.9
