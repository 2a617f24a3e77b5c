"""The perturbed runs' coarse time step (synth.verification.runs.physics_check): used only where the
design's nominal runs agree at it, recorded with the table (so a replay uses it), and
``simulate --perturb SEED --fine`` runs the model's own step."""

from __future__ import annotations

import pytest

from synth.verification import runs as verify
from synth.verification.results import RobustRuns
from synth.verification.source import Bundle


@pytest.fixture(scope="module")
def arm(designs):
    return designs("positioning", "--answer", "orienting=no", "--no-verify").folder


def test_the_coarse_step_is_used_where_the_nominal_runs_agree(arm) -> None:
    files = Bundle.read(arm)
    check = verify.physics_check(files)
    assert check["timestep_s"] == pytest.approx(0.002 * verify.COARSE_STEP)
    assert check["largest"]  # what was compared is reported
    assert check["why"] == "every figure of the nominal runs agrees"


def test_a_disagreeing_figure_keeps_the_fine_step(arm, monkeypatch) -> None:
    """Built to fail: with no tolerance at all on the placing error, the two steps' last
    digits disagree and the fine step is kept, naming the figure."""
    files = Bundle.read(arm)
    monkeypatch.setattr(verify, "AGREE", {**verify.AGREE, "placing_error_m": 0.0})
    check = verify.physics_check(files)
    assert check["timestep_s"] is None
    assert "placing_error_m" in check["why"]


def test_the_table_carries_the_step_into_the_perturbed_model(arm) -> None:
    from adron.catalog import load_catalog
    from synth.verification.perturb import design_table, draw, perturbed_model

    bundle = Bundle.read(arm)
    record, xml, meshes = bundle.record, bundle.xml, bundle.meshes
    table = design_table(record, xml, load_catalog())
    p = draw(table, 1)
    assert perturbed_model(xml, meshes, table, p).opt.timestep == pytest.approx(0.002)
    table["timestep_s"] = 0.004
    assert perturbed_model(xml, meshes, table, p).opt.timestep == pytest.approx(0.004)


def test_fine_needs_a_perturbed_run(cli, arm) -> None:
    r = cli("simulate", str(arm), "--behavior", "positioning", "--fine")
    assert r.code == 2
    assert "--perturb" in r.err


def test_what_k_of_k_shows() -> None:
    from synth.verification.robust import shows, success_bound

    assert success_bound(8, 8) == pytest.approx(0.1 ** (1 / 8))  # 0.7499: "> 74 %"
    assert success_bound(30, 30) > 0.92
    # the bound is of the outcome: a failed run lowers it (beta quantile, scipy's)
    assert success_bound(7, 8) == pytest.approx(0.5938, abs=1e-4)
    assert success_bound(0, 8) == 0.0
    s = shows(
        RobustRuns.of(
            {
                "k": 8,
                "behaviors": [
                    {"behavior": "walking", "passed": 8, "runs": 8, "robust": True},
                    {"behavior": "turning", "passed": 7, "runs": 8, "robust": False},
                ],
            }
        )
    )
    assert s["behavior"] == "turning" and s["success_lower_bound"] == pytest.approx(0.5938)


def test_certify_takes_the_place_of_robustness(cli) -> None:
    r = cli("design", "walking", "--certify", "30", "--robustness", "4")
    assert r.code == 2 and "--certify" in r.err
    r = cli("design", "walking", "--certify", "0")
    assert r.code == 2
