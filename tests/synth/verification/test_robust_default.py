"""``parmor design`` verifies robustly by default: K = the perturbation table's
``default_k`` (8) when ``--robustness`` is not given, ``PARMOR_ROBUSTNESS`` sets another K
(the test suite sets 0 in conftest.py so that its many designs stay nominal), 0 or
``--no-verify`` turn it off, and a bad value of the variable is an input error."""

from __future__ import annotations

import json

import pytest

from synth.commands.cli import ROBUSTNESS_ENV, _robustness


def test_without_the_option_the_tables_default(monkeypatch) -> None:
    from synth.verification.perturb import ranges

    monkeypatch.delenv(ROBUSTNESS_ENV, raising=False)
    k = int(ranges()["default_k"])
    assert k == 8
    assert _robustness(None) == k  # the default: on
    assert _robustness(-1) == k  # --robustness alone
    assert _robustness(3) == 3 and _robustness(0) == 0
    assert _robustness(None, no_verify=True) == 0  # nothing simulated: no perturbed runs


def test_the_environment_sets_the_default_only(monkeypatch) -> None:
    monkeypatch.setenv(ROBUSTNESS_ENV, "2")
    assert _robustness(None) == 2
    assert _robustness(5) == 5 and _robustness(-1) == 8  # the option wins


@pytest.mark.parametrize("value", ["x", "-1", "65", "2.5"])
def test_a_bad_environment_value_is_an_input_error(cli, monkeypatch, value) -> None:
    monkeypatch.setenv(ROBUSTNESS_ENV, value)
    r = cli("design", "driving", "--no-input")
    assert r.code == 2 and ROBUSTNESS_ENV in r.err and repr(value) in r.err
    assert "Traceback" not in r.err


def test_a_default_design_records_its_perturbed_runs(cli, monkeypatch, tmp_path) -> None:
    monkeypatch.delenv(ROBUSTNESS_ENV, raising=False)
    r = cli("design", "driving", "--no-input", "--json")
    assert r.code == 0, r.err
    robust = json.loads(r.out)["verified"]["robust"]
    assert robust["k"] == 8 and all(b["runs"] == 8 for b in robust["behaviors"])
    # built to fail the other way: with the variable at 0 no perturbed run is recorded
    monkeypatch.setenv(ROBUSTNESS_ENV, "0")
    r = cli("design", "driving", "--no-input", "--json")
    assert r.code == 0 and "robust" not in json.loads(r.out)["verified"]
