"""A design with a payload: ``parmor simulate`` on its bundle reproduces the verification's
figures exactly (the verification simulates the robot carrying the payload as the bundle
places it, not a model of its own that merged it into the holding body)."""

from __future__ import annotations

import json


def test_simulate_reproduces_the_verified_figures_of_a_loaded_design(cli, tmp_path) -> None:
    out = tmp_path / "cart"
    r = cli("design", "driving", "--param", "payload=1kg", "--out", str(out))
    assert r.code == 0, r.err
    rec = json.loads((out / "design.json").read_text(encoding="utf-8"))
    assert rec["payload"]["in_models"] is False and rec["payload"]["mass_kg"] == 1.0
    behaviors = rec["verified"]["behaviors"]
    assert behaviors
    for b in behaviors:
        r = cli("simulate", str(out), "--behavior", b["behavior"], "--json")
        assert r.code == 0, r.err
        got = json.loads(r.out)
        same = [k for k in b if k in got]
        assert {"distance_m", "max_torque_ratio", "min_height_ratio"} <= set(same)
        assert {k: got[k] for k in same} == {k: b[k] for k in same}, b["behavior"]
