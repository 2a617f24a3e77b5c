"""The humanoid's grasping under perturbation (issue 22): the grippers open while the robot
crouches and reaches (2.5 s) and close in ``GRIP_TIME`` = 1 s, so that a gripper servo
at the battery's cut-off follows them (peak 1.2 and 2.9 rad/s). Opened in the 1 s crouch
and closed in 0.5 s (peak 2.9 and 5.9 rad/s) the SG90 grippers were at their limit 2 % of
every perturbed run, and with a 0.3 kg payload seed 8 (the shoulder's 3.7 % added)
saturated 5.6 % (limit 5 %). Case built to fail: the 0.5 s close on the same seed."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from synth.commands.cli import main
from synth.verification import perturb

REQUEST = ("walking", "--answer", "grasping=yes", "--param", "payload=0.3kg")
SEED = 8


@pytest.fixture(scope="module")
def loaded(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("humanoid") / "bundle"
    err = io.StringIO()
    argv = ["design", *REQUEST, "--no-input", "--no-verify", "--out", str(folder)]
    assert main(argv, io.StringIO(), err) == 0, err
    return folder


@pytest.fixture
def fresh_plans():
    from gaits import base

    base._PLANNED.clear()
    yield
    base._PLANNED.clear()


def _grasp(folder: Path, seed: int, open_loop=None):
    from adron.catalog import load_catalog
    from export.mjcf import load_mjcf
    from synth.verification.runs import _simulate, controller_for_model
    from synth.verification.source import Bundle

    bundle = Bundle.read(folder)

    record, xml, meshes = bundle.record, bundle.xml, bundle.meshes
    table = json.loads(json.dumps(perturb.design_table(record, xml, load_catalog())))
    p = perturb.draw(table, seed)
    model = perturb.perturbed_model(xml, meshes, table, p)
    ctl = controller_for_model(record, load_mjcf(xml, meshes))
    traj = ctl.run("grasping")
    if open_loop is not None:  # conftest's: the plan without the trunk's balance loop
        traj = open_loop(traj)
    return _simulate(model, ctl, traj, None, None, p)


def test_the_grippers_follow_their_servos_under_perturbation(loaded, fresh_plans) -> None:
    r = _grasp(loaded, SEED)
    assert r.verdict == [], (r.verdict, r.saturated_joints)
    grippers = {j: v for j, v in r.saturated_joints.items() if j.endswith("gripper")}
    assert grippers and max(grippers.values()) < 0.01, r.saturated_joints


def test_a_fast_close_saturates_the_grippers(loaded, fresh_plans, monkeypatch, open_loop) -> None:
    """Built to fail: the grippers closed in 0.5 s on the same robot and seed, open loop (the
    trunk's balance loop steadies the robot enough that the run's saturated share stays
    under the verdict's 5 % while the grippers still saturate 1.5 % of it: the grippers'
    saturation is what this case is about)."""
    from gaits import humanoid

    monkeypatch.setattr(humanoid, "GRIP_TIME", 0.5)
    r = _grasp(loaded, SEED, open_loop=open_loop)
    assert "saturated" in r.verdict, r.saturated_joints
    assert max(v for j, v in r.saturated_joints.items() if j.endswith("gripper")) > 0.01
