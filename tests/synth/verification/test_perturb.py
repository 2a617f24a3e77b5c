"""Verification under the variation a printed robot meets (issue 22): seeded perturbations
of the MuJoCo model (synth/verification/perturb.py), the robust verification
(synth.verification.runs. verify_robust), its acceptance rule in the design loop
(synth/verification/robust.py) and the replay (``parmor simulate DIR --perturb SEED``). Cases built
to fail: a design that passes nominally and fails with backlash, one that fails at the low battery
voltage, a seed that reproduces a failure. The robot is an arm of the tests' own KIF (no shipped
type)."""

from __future__ import annotations

import io
import json
import math
import shutil
from pathlib import Path

import pytest

from adron.errors import InputError
from synth.commands.cli import main
from synth.verification import perturb
from synth.verification.results import RobustRuns, Run
from synth.verification.runs import (
    controller_for_model,
    figures,
    required_passes,
    verify_nominal,
    verify_robust,
)
from synth.verification.source import Bundle

#: A stationary arm of three position servos, each followed by a printed link, ending in a
#: gripper (the manipulator axiom's shape), with an ability only it has.
ARM_KIF = """
(subclass TestArmThree IndustrialRobot)
(instance TestArmThree BaseConfiguration)
(documentation TestArmThree EnglishLanguage "A stationary arm of 3 joints.")
(subclass TestArmLink LinkModule)
(subclass RobotPositioningThree RobotPositioning)
(abilityName RobotPositioningThree "positioning-three")
(abilityVerb RobotPositioningThree "position with three test links")
(requiredPartCount RobotPositioningThree TestArmLink 3)
(=> (instance ?ROB TestArmThree)
  (exists (?BASE ?GRIP ?S1 ?S2 ?S3 ?K1 ?K2 ?K3)
    (and (instance ?BASE ArmBase) (instance ?GRIP RoboticGripper)
      (instance ?S1 PositionServomotor) (instance ?S2 PositionServomotor)
      (instance ?S3 PositionServomotor)
      (instance ?K1 TestArmLink) (instance ?K2 TestArmLink) (instance ?K3 TestArmLink)
      (robotPart ?BASE ?ROB) (robotPart ?GRIP ?ROB) (robotPart ?S1 ?ROB) (robotPart ?S2 ?ROB)
      (robotPart ?S3 ?ROB) (robotPart ?K1 ?ROB) (robotPart ?K2 ?ROB) (robotPart ?K3 ?ROB)
      (connectedTo ?BASE ?S1) (connectedTo ?S1 ?K1) (connectedTo ?K1 ?S2)
      (connectedTo ?S2 ?K2) (connectedTo ?K2 ?S3) (connectedTo ?S3 ?K3)
      (connectedTo ?K3 ?GRIP))))
"""
REQUEST = ("positioning-three", "pick-and-place", "--no-input")

#: Overrides that leave the robot nominal: every range closed at its neutral value.
NO_PLAY = {"gears": "plastic", "deadband": "0 us"}
NEUTRAL = {
    "mass": {"spread": 0.0},
    "floor": {"friction_low": 1.0, "friction_high": 1.0, "max_slope": "0 deg"},
    "bus": {"latency_low": "0 ms", "latency_high": "0 ms", "control_period": "0 ms"},
    "battery": {"supply": "direct", "rated_voltage": "1 V"},
    "compliance": {"scale": 0.0},
    "gears": {"plastic": ["0 deg", "0 deg"], "metal": ["0 deg", "0 deg"]},
    "servo": {m: NO_PLAY for m in ("default", "SG90", "MG996R", "DS3218")},
}


def with_(**tables) -> dict:
    """NEUTRAL with some tables replaced."""
    return {**NEUTRAL, **tables}


def _main(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main(list(argv), out, err)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def kif(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("kif") / "arm.kif"
    path.write_text(ARM_KIF)
    return path


@pytest.fixture(scope="module")
def arm(tmp_path_factory, kif) -> Path:
    """The arm designed (not verified) as a bundle folder."""
    folder = tmp_path_factory.mktemp("arm") / "bundle"
    code, _, err = _main(
        "design", *REQUEST, "--ontology", str(kif), "--no-verify", "--out", str(folder)
    )
    assert code == 0, err
    return folder


@pytest.fixture(scope="module")
def parts(arm):
    bundle = Bundle.read(arm)
    return bundle, bundle.record, bundle.xml, bundle.meshes


def table_of(parts, overrides) -> dict:
    from adron.catalog import load_catalog

    files, record, xml, _ = parts
    return json.loads(json.dumps(perturb.design_table(record, xml, load_catalog(), overrides)))


# --- the draws ------------------------------------------------------------------------


def test_draws_are_seeded_and_within_their_ranges(parts) -> None:
    """A grid of 60 seeds: every drawn value in its documented range, the same seed the
    same perturbation (and the same MJCF text, byte for byte), other seeds others."""
    table = table_of(parts, None)
    _, _, xml, meshes = parts
    seen = set()
    inside = 0
    for seed in range(60):
        p = perturb.draw(table, seed)
        assert p == perturb.draw(table, seed)
        ok = (
            0.6 <= p["friction_scale"] <= 1.2
            and 0 <= p["slope_rad"] <= math.radians(3)
            and 0.010 <= p["latency_s"] <= 0.040
            and all(0.9 <= f <= 1.1 for f in p["mass_scale"].values())
        )
        for joint, play in p["play_rad"].items():
            servo = table["servos"][joint]
            lo, hi = servo["backlash_rad"]
            ok = ok and lo + servo["deadband_rad"] <= play <= hi + servo["deadband_rad"]
        inside += ok
        seen.add(p["friction_scale"])
    assert inside == 60  # pass rate 60 of 60
    assert len(seen) == 60
    p = perturb.draw(table, 7)
    assert perturb.perturbed_xml(xml, table, p) == perturb.perturbed_xml(xml, table, p)
    assert perturb.perturbed_xml(xml, table, p) != perturb.perturbed_xml(
        xml, table, perturb.draw(table, 8)
    )


def test_the_perturbed_model_carries_the_draw(parts) -> None:
    """Masses within +-10 % body by body, gravity's size kept and turned by the slope, one
    play hinge per position servo limited to +-play/2, torque limits x the battery."""
    import numpy as np

    from export.mjcf import load_mjcf

    table = table_of(parts, None)
    _, _, xml, meshes = parts
    nominal = load_mjcf(xml, meshes)
    for seed in (1, 2, 3):
        p = perturb.draw(table, seed)
        model = perturb.perturbed_model(xml, meshes, table, p)
        ratio = model.body_mass[1:].sum() / nominal.body_mass[1:].sum()
        assert 0.9 <= ratio <= 1.1
        g = model.opt.gravity
        assert np.linalg.norm(g) == pytest.approx(np.linalg.norm(nominal.opt.gravity))
        assert math.acos(-g[2] / np.linalg.norm(g)) == pytest.approx(p["slope_rad"])
        for joint, play in p["play_rad"].items():
            hinge = model.joint(joint + perturb.PLAY_SUFFIX)
            assert hinge.range[1] == pytest.approx(play / 2)
        scale = table["battery_scale"]
        assert np.allclose(model.actuator_forcerange, nominal.actuator_forcerange * scale)
    assert 0 < table["battery_scale"] <= 1


def test_the_battery_scale_follows_the_supply() -> None:
    r = perturb.ranges()
    # a 3S pack's cut-off (9.9 V) behind a 5 V regulator: the rail holds, less its sag
    assert perturb.battery_scale(r, 11.1, 0.0) == pytest.approx(1.0)
    assert perturb.battery_scale(r, 11.1, 5.0) == pytest.approx((5.0 - 0.5) / 4.8)
    direct = perturb.ranges({"battery": {"supply": "direct", "rated_voltage": "12 V"}})
    assert perturb.battery_scale(direct, 11.1, 0.0) == pytest.approx(9.9 / 12)
    # a 1S pack behind the regulator: under its dropout, the rail falls
    assert perturb.battery_scale(r, 3.7, 0.0) == pytest.approx((3.3 - 1.0) / 4.8)


def test_required_passes() -> None:
    assert required_passes(8, 0.875) == 7
    assert required_passes(1, 0.875) == 1
    assert required_passes(3, 1.0) == 3
    assert required_passes(0, 0.875) == 0


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"flor": {}}, "unknown key 'flor'"),
        ({"floor": {"frictionlow": 1}}, "unknown key floor.frictionlow"),
        ({"floor": {"max_slope": "3 kg"}}, "floor.max_slope"),
        ({"floor": {"friction_low": 2.0}}, "the low end is above the high end"),
        ({"battery": {"supply": "solar"}}, "battery.supply = 'solar'"),
        ({"servo": {"SG90": {"gears": "wood", "deadband": "1 us"}}}, "servo.SG90.gears"),
        ({"gears": {"plastic": ["1 deg"]}}, "gears.plastic"),
        ({"mass": "x"}, "mass: expected a table"),
    ],
)
def test_bad_ranges_are_named(overrides, message) -> None:
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(".", r"\.")):
        perturb.ranges(overrides, "my.toml")


# --- the runs -------------------------------------------------------------------------


def test_a_neutral_perturbation_is_the_nominal_run(parts) -> None:
    """Every range closed: the perturbed run is the nominal one, figure for figure (the
    hooks change nothing at their neutral values)."""
    from export.mjcf import load_mjcf
    from synth.verification.runs import run_behavior

    files, record, xml, meshes = parts
    table = table_of(parts, NEUTRAL)
    robust = verify_robust(files, 1, table, ["pick-and-place"]).to_dict()
    model = load_mjcf(xml, meshes)
    traj, result = run_behavior(model, controller_for_model(record, model), "pick-and-place")
    assert robust["behaviors"][0]["figures"][0] == {"seed": 1} | figures(traj, result)


def test_backlash_breaks_a_design_that_passes_nominally(parts) -> None:
    files = parts[0]
    assert all(r.ok for r in verify_nominal(files))
    names = ["pick-and-place", "positioning"]
    tight = verify_robust(files, 2, table_of(parts, NEUTRAL), names).to_dict()
    assert all(b["robust"] and b["passed"] == 2 for b in tight["behaviors"])
    play = {"plastic": ["5 deg", "6 deg"], "metal": ["5 deg", "6 deg"]}
    got = verify_robust(files, 2, table_of(parts, with_(gears=play)), names)
    loose = got.to_dict()
    for b in loose["behaviors"]:
        assert not b["robust"] and b["passed"] == 0
        assert all("placing" in f["verdict"] for f in b["failures"])
        assert b["worst"]["placing_error_m"]["value"] > 0.005
    why = got.behavior("pick-and-place").why_not(got.required)
    assert why.startswith("pick-and-place is not robust: passed 0 of 2 perturbed runs (needs 2)")
    assert "play up to" in why and "placing (placing error" in why


def test_the_low_battery_breaks_a_design_that_passes_nominally(parts) -> None:
    files = parts[0]
    names = ["pick-and-place"]
    full = verify_robust(files, 1, table_of(parts, NEUTRAL), names).to_dict()
    assert full["behaviors"][0]["robust"]
    # the servos straight on a 3S pack, their figures rated at 30 V: a third of the torque
    low = with_(battery={"supply": "direct", "rated_voltage": "30 V"})
    table = table_of(parts, low)
    peak = parts[1]["power"]["peak_current_A"]
    assert table["battery_scale"] == pytest.approx((9.9 - 0.1 * peak) / 30)
    weak = verify_robust(files, 1, table, names).to_dict()
    b = weak["behaviors"][0]
    assert not b["robust"]
    assert {"saturated", "placing"} & set(b["failures"][0]["verdict"])


def test_latency_shifts_the_commands(parts) -> None:
    """Zero latency is the nominal run to the bit; half a second of it leaves the gripper
    short of the target when the move ends."""
    from export.mjcf import load_mjcf
    from synth.verification.simulate import simulate

    _, record, xml, meshes = parts
    model = load_mjcf(xml, meshes)
    ctl = controller_for_model(record, model)
    traj = ctl.run("positioning")
    body = traj.info.get("tool_body") or ctl.template.end_effectors[0]
    base = simulate(model, traj, end_effector=body, can_fall=False).to_dict()
    same = simulate(model, traj, end_effector=body, can_fall=False, latency_s=0.0).to_dict()
    assert base == same and base["verdict"] == "ok"
    late = simulate(model, traj, end_effector=body, can_fall=False, latency_s=0.5)
    assert "placing" in late.verdict


# --- the replay and the command line ----------------------------------------------------


def test_a_seed_reproduces_a_failure(arm, parts, tmp_path: Path, cli) -> None:
    """The record's figures of a failed perturbed run are what ``parmor simulate --perturb
    SEED --json`` gives, from the bundle alone."""
    files = parts[0]
    play = {"plastic": ["3 deg", "7 deg"], "metal": ["3 deg", "7 deg"]}
    robust = verify_robust(files, 3, table_of(parts, with_(gears=play)), ["positioning"]).to_dict()
    folder = tmp_path / "bundle"
    shutil.copytree(arm, folder)
    record = json.loads((folder / "design.json").read_text())
    record["verified"] = {"simulated": True, "robust": robust}
    (folder / "design.json").write_text(json.dumps(record, indent=2))
    b = robust["behaviors"][0]
    failed = [f for f in b["figures"] if f["verdict"] != "ok"]
    assert failed
    for fig in b["figures"]:
        seed = str(fig["seed"])
        r = cli("simulate", str(folder), "--behavior", "positioning", "--perturb", seed, "--json")
        assert r.code == (0 if fig["verdict"] == "ok" else 1), r.err
        replay = json.loads(r.out)
        assert replay.pop("perturbation")["seed"] == fig["seed"]
        assert {"seed": fig["seed"]} | replay == fig


def test_design_refuses_a_design_that_is_not_robust(kif, tmp_path: Path, cli) -> None:
    catalog = tmp_path / "loose.toml"
    catalog.write_text(
        '[catalog]\nname = "loose"\ncurrency = "EUR"\nversion = "1"\nextends = "default"\n\n'
        '[perturbation.gears]\nplastic = ["3 deg", "4 deg"]\nmetal = ["3 deg", "4 deg"]\n'
    )
    r = cli("design", *REQUEST, "--ontology", str(kif), "--catalog", str(catalog), "--robustness=2")
    assert r.code == 1, r.err
    assert "cannot build it: " in r.err and " is not robust: passed 0 of 2 perturbed runs" in r.err
    assert "broke it: placing (placing error" in r.err and "seed 1 (friction x" in r.err


def test_design_records_a_robust_design_byte_for_byte(kif, tmp_path: Path, cli) -> None:
    catalog = tmp_path / "tight.toml"
    body = "".join(
        f"[perturbation.{t}]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in vals.items())
        for t, vals in NEUTRAL.items()
        if t not in ("servo", "gears")
    )
    catalog.write_text(
        '[catalog]\nname = "tight"\ncurrency = "EUR"\nversion = "1"\nextends = "default"\n\n'
        + body
        + '[perturbation.gears]\nplastic = ["0 deg", "0.2 deg"]\nmetal = ["0 deg", "0.1 deg"]\n'
    )
    outs = []
    for n in (1, 2):
        out = tmp_path / f"b{n}"
        opts = ("--catalog", str(catalog), "--robustness", "2", "--out", str(out))
        r = cli("design", *REQUEST, "--ontology", str(kif), *opts)
        assert r.code == 0, r.err
        outs.append(out)
    assert (outs[0] / "design.json").read_bytes() == (outs[1] / "design.json").read_bytes()
    rec = json.loads((outs[0] / "design.json").read_text())
    robust = rec["verified"]["robust"]
    assert robust["k"] == 2 and robust["required"] == 2
    assert all(b["robust"] for b in robust["behaviors"])
    assert "robust:     2 perturbed runs per behaviour" in r.out
    readme = (outs[0] / "README.md").read_text()
    assert "## Verified in simulation" in readme and "| pick-and-place | ok | 2 of 2 |" in readme


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (("design", "driving", "--robustness", "-1"), "--robustness: '-1': expected a number"),
        (("design", "driving", "--robustness", "abc"), "'abc': expected a whole number"),
        (("design", "driving", "--robustness", "65"), "from 0 to 64"),
        (("design", "driving", "--robustness", "--no-verify"), "drop --no-verify"),
    ],
)
def test_bad_robustness_is_exit_2(cli, argv, message) -> None:
    r = cli(*argv)
    assert r.code == 2 and message in r.err and "Traceback" not in r.err


def test_perturb_needs_a_robust_record(arm, cli) -> None:
    r = cli("simulate", str(arm), "--behavior", "positioning", "--perturb", "1")
    assert r.code == 2
    assert "design.json: verified.robust.table is missing" in r.err
    r = cli("simulate", str(arm), "--behavior", "positioning", "--perturb", "-2")
    assert r.code == 2 and "expected a seed from 0" in r.err


def test_a_bad_perturbation_table_in_the_catalog_is_exit_2(kif, tmp_path: Path, cli) -> None:
    catalog = tmp_path / "bad.toml"
    catalog.write_text(
        '[catalog]\nname = "bad"\ncurrency = "EUR"\nversion = "1"\nextends = "default"\n\n'
        '[perturbation.floor]\nmax_slope = "3 m"\n'
    )
    out = tmp_path / "never"
    opts = ("--catalog", str(catalog), "--robustness", "1", "--out", str(out))
    r = cli("design", *REQUEST, "--ontology", str(kif), *opts)
    assert r.code == 2, r.err
    assert "[perturbation]: floor.max_slope" in r.err and "Traceback" not in r.err
    assert not out.exists()


# --- the design loop's use of the perturbed runs (synth/verification/robust.py), the runs faked
# --------


def _robust(behaviors: list[tuple[str, str, list[dict]]]) -> RobustRuns:
    """A verify_robust answer: (behaviour, ability, each run's figures) -> its record."""
    out = []
    for name, ability, runs in behaviors:
        failed = [r for r in runs if r["verdict"] != "ok"]
        out.append(
            {
                "behavior": name,
                "ability": ability,
                "passed": len(runs) - len(failed),
                "runs": len(runs),
                "robust": not failed,
                "worst": {},
                "failures": [
                    {
                        "seed": r["seed"],
                        "verdict": r["verdict"],
                        "why": ", ".join(r["verdict"]),
                        "perturbation": f"seed {r['seed']} (...)",
                    }
                    for r in failed
                ],
                "figures": runs,
            }
        )
    return RobustRuns.of(
        {"k": 2, "required": 2, "share": 1.0, "perturbations": [], "behaviors": out}
    )


def _run(seed: int, verdict="ok", **kw) -> dict:
    return {"seed": seed, "verdict": verdict, "saturated_fraction": 0.0} | kw


def test_a_saturated_perturbed_run_gets_a_stronger_actuator(kif, parts, cli, monkeypatch):
    """The sizing loop strengthens a joint that saturated in a perturbed run, as it does
    for a nominal one, and verifies again."""
    import synth.verification.runs

    joint = next(j["name"] for j in parts[1]["joints"] if j["group"] != "gripper")
    answers = [
        _robust(
            [
                (
                    "pick-and-place",
                    "pick-and-place",
                    [
                        _run(
                            1, ["saturated"], saturated_fraction=0.3, saturated_joints={joint: 0.3}
                        ),
                        _run(2),
                    ],
                )
            ]
        ),  # fmt: skip
        _robust([("pick-and-place", "pick-and-place", [_run(1), _run(2)])]),
    ]
    calls = []

    def fake(files, k, table, behaviors=None, only=None, sensing=True, **early):
        calls.append(k)
        return answers[min(len(calls), len(answers)) - 1]

    monkeypatch.setattr(synth.verification.runs, "verify_robust", fake)
    r = cli("design", *REQUEST, "--ontology", str(kif), "--robustness", "2", "--json")
    assert r.code == 0, r.err
    rec = json.loads(r.out)
    assert calls == [2, 2] and rec["verified"]["rounds"] == 2
    assert set(rec["verified"]["strengthened"]) == {joint}
    assert rec["verified"]["robust"]["behaviors"][0]["passed"] == 2


def test_a_bonus_ability_not_robust_is_dropped(kif, cli, monkeypatch):
    import synth.verification.runs

    answer = _robust(
        [
            ("pick-and-place", "pick-and-place", [_run(1), _run(2)]),
            ("grasping", "grasping", [_run(1), _run(2, ["placing"])]),
        ]
    )
    monkeypatch.setattr(synth.verification.runs, "verify_robust", lambda *a, **kw: answer)
    r = cli("design", *REQUEST, "--ontology", str(kif), "--robustness", "2", "--json")
    assert r.code == 0, r.err
    rec = json.loads(r.out)
    assert "grasping" not in rec["abilities"] and "pick-and-place" in rec["abilities"]
    assert "dropped grasping: grasping is not robust: passed 1 of 2 perturbed runs" in (
        " ".join(rec["notes"])
    )


# --- parmor sweep with robustness = K ---------------------------------------------------


def _nominal_ok(bundle, behaviors=None) -> list[Run]:
    return [Run.of({"behavior": "pick-and-place", "ability": "pick-and-place", "verdict": "ok"})]


def _study(folder: Path, kif: Path, robustness: object) -> Path:
    shutil.copy(kif, folder / "arm.kif")
    study = folder / "s.toml"
    study.write_text(
        f'ontology = ["arm.kif"]\nrobustness = {robustness}\n\n[[request]]\nname = "arm"\n'
        'abilities = ["positioning-three", "pick-and-place"]\n'
        'params = { payload = ["0.01kg", "0.02kg"] }\n'
    )
    return study


def test_sweep_reports_nominal_and_robust_pass_rates(kif, tmp_path: Path, cli, monkeypatch):
    """A study's ``robustness = K`` verifies each design under K perturbations as
    ``parmor design --robustness K`` does: a request whose demanded behaviour is not
    robust (built to fail: its second run fails) is refused and counted as nominal ok,
    robust not; the other is both."""
    import synth.verification.runs

    calls = []

    def fake(bundle, k, table, behaviors=None, only=None, sensing=True, **early):
        calls.append(k)
        record = bundle.record
        bad = record["request"]["params"].get("payload") == "0.02kg"
        return _robust(
            [("pick-and-place", "pick-and-place", [_run(1), _run(2, ["placing"] if bad else "ok")])]
        )

    monkeypatch.setattr(synth.verification.runs, "verify_robust", fake)
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", _nominal_ok)
    study = _study(tmp_path, kif, 2)
    r = cli("sweep", str(study), "--jobs", "1", "--json")
    assert r.code == 0, r.err
    s = json.loads(r.out)
    assert set(calls) == {2} and len(calls) >= 2 and s["robustness"] == 2
    (t,) = s["types"].values()
    assert (t["requests"], t["accepted"], t["nominal_ok"], t["robust_ok"]) == (2, 1, 2, 1)
    assert t["robust_runs"] == [3, 4]
    out = tmp_path / "s.sweep"
    summary = (out / "summary.md").read_text()
    assert "## Robustness" in summary and "under 2 seeded perturbations" in summary
    assert "| 2 | 2 (100 %) | 1 (50 %) | 3 of 4 |" in summary
    assert "pick-and-place is not robust: passed 1 of 2 perturbed runs" in summary
    text = cli("sweep", str(study), "--jobs", "1").out
    assert "nominal ok 2, robust ok 1" in text


def test_sweep_without_robustness_runs_no_perturbation(kif, tmp_path: Path, cli, monkeypatch):
    import synth.verification.runs

    def fail(*a, **kw):
        raise AssertionError("perturbed runs in a study without robustness")

    monkeypatch.setattr(synth.verification.runs, "verify_robust", fail)
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", _nominal_ok)
    study = _study(tmp_path, kif, 0)
    r = cli("sweep", str(study), "--jobs", "1", "--json")
    assert r.code == 0, r.err
    s = json.loads(r.out)
    assert s["robustness"] == 0 and "nominal_ok" not in next(iter(s["types"].values()))
    assert "## Robustness" not in (tmp_path / "s.sweep" / "summary.md").read_text()


def test_the_sweep_key_follows_robustness() -> None:
    from synth.commands.sweep import request_key

    q = {"abilities": ["driving"], "answers": {}, "params": {}}
    assert request_key(q, True, "d") == request_key(q, True, "d", 0)
    assert request_key(q, True, "d", 2) != request_key(q, True, "d", 3)
    assert request_key(q, True, "d", 2) != request_key(q, True, "d")
    assert request_key(q, False, "d", 2) == request_key(q, False, "d")  # nothing simulated


@pytest.mark.parametrize("value", ["-1", "65", '"8"', "true", "2.5"])
def test_a_bad_study_robustness_is_exit_2(kif, tmp_path: Path, cli, value) -> None:
    study = _study(tmp_path, kif, value)
    r = cli("sweep", str(study), "--no-simulate")
    assert r.code == 2 and "Traceback" not in r.err
    assert f"{study}: robustness = " in r.err and "not a whole number from 0 to 64" in r.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.kif", "s.toml"]


def test_a_real_sweep_with_robustness(tmp_path: Path, cli) -> None:
    """The real harness (no fake): a wheeled design's behaviours under 2 perturbations;
    the figures add up (robust ok <= nominal ok <= requests, runs passed <= runs)."""
    study = tmp_path / "s.toml"
    study.write_text('robustness = 2\n\n[[request]]\nabilities = ["driving"]\n')
    r = cli("sweep", str(study), "--jobs", "1", "--json")
    assert r.code == 0, r.err
    (t,) = json.loads(r.out)["types"].values()
    passed, runs = t["robust_runs"]
    assert t["robust_ok"] <= t["nominal_ok"] <= t["requests"] == 1
    assert runs == 2 * 2 and 0 <= passed <= runs
    stored = json.loads(next((tmp_path / "s.sweep" / "requests").glob("*.json")).read_text())
    assert {b["runs"] for b in stored["result"]["robust"]} == {2}


# --- a certification (--certify N) asks its runs to show what the default K runs show ---------


def test_a_certification_needs_the_passes_that_show_the_default_claim() -> None:
    """``certified_share``: the fewest passes of N whose lower bound reaches what K of K
    shows (0.1^(1/8) with the shipped K = 8), for every N; N at most K needs every run."""
    from synth.verification.results import required_passes
    from synth.verification.robust import certified_share, success_bound

    claim = success_bound(8, 8)
    assert certified_share(8, 1.0, 8) == 1.0 and certified_share(3, 1.0, 8) == 1.0
    assert required_passes(30, certified_share(30, 1.0, 8)) == 26
    for n in range(1, 201):
        need = required_passes(n, certified_share(n, 1.0, 8))
        if n < 8:  # fewer runs than K cannot show as much: every run
            assert need == n and success_bound(n, n) < claim, n
            continue
        assert success_bound(need, n) >= claim > success_bound(need - 1, n), n
    # a catalog that accepts 7 of 8 claims less, and so does its certification
    assert required_passes(30, certified_share(30, 0.875, 8)) < 26


def test_certify_records_the_share_its_runs_need_and_robustness_keeps_every_run(
    kif, cli, monkeypatch
):
    """``--certify 20`` verifies with 18 of 20 needed (the table's share, recorded with
    it); built to fail: ``--robustness 20`` asks the same runs for all 20."""
    import synth.verification.runs

    shares = []

    def fake(bundle, k, table, behaviors=None, only=None, sensing=True, **early):
        shares.append((k, table["share"]))
        return _robust([("pick-and-place", "pick-and-place", [_run(s) for s in range(1, k + 1)])])

    monkeypatch.setattr(synth.verification.runs, "verify_robust", fake)
    r = cli("design", *REQUEST, "--ontology", str(kif), "--certify", "20", "--json")
    assert r.code == 0, r.err
    assert shares[-1] == (20, pytest.approx(0.9))
    r = cli("design", *REQUEST, "--ontology", str(kif), "--robustness", "20", "--json")
    assert r.code == 0, r.err
    assert shares[-1] == (20, 1.0)
