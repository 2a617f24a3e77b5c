"""Perturbed runs that the servos' command hold breaks (issue 22, ``synth.verification.hold``):
a position servo gives its stall torque ``export.mjcf.SERVO_BAND`` off its reference, and
a command held for the bus's control period makes a fast joint's reference jump further
than that at every frame: the servo saturates with no stronger actuator to answer it.
The robot is a KIF-only walker of the tests' own (tests/kinematics/test_bodyplan.py's
``legged_kif``); the perturbation tables close every range but the one a case is about,
so a failure is reproduced by its seed."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from export.mjcf import SERVO_BAND
from synth.commands.cli import main
from synth.verification import perturb
from synth.verification.hold import hold_attribution, hold_blame, hold_note
from synth.verification.runs import run_perturbed, verify_robust
from synth.verification.source import Bundle
from tests.kinematics.test_bodyplan import legged_kif


def _closed(period: str, rated: str = "1 V") -> dict:
    """Every perturbation closed but the command hold of ``period`` (and a battery whose
    servos are rated at ``rated``: "1 V" is a full battery)."""
    return {
        "mass": {"spread": 0.0},
        "floor": {"friction_low": 1.0, "friction_high": 1.0, "max_slope": "0 deg"},
        "bus": {"latency_low": "0 ms", "latency_high": "0 ms", "control_period": period},
        "battery": {"supply": "direct", "rated_voltage": rated},
        "compliance": {"scale": 0.0},
        "gears": {"plastic": ["0 deg", "0 deg"], "metal": ["0 deg", "0 deg"]},
    }


@pytest.fixture(scope="module")
def walker(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("hold")
    kif = tmp / "walker.kif"
    kif.write_text(legged_kif("HoldWalker4", 4, "hold-4-walking"))
    folder = tmp / "bundle"
    out, err = io.StringIO(), io.StringIO()
    argv = ["design", "hold-4-walking", "--ontology", str(kif), "--no-input", "--no-verify"]
    assert main([*argv, "--out", str(folder)], out, err) == 0, err.getvalue()
    return folder


def _table(folder: Path, ranges: dict) -> dict:
    from adron.catalog import load_catalog

    bundle = Bundle.read(folder)

    record, xml, _ = bundle.record, bundle.xml, bundle.meshes
    return json.loads(json.dumps(perturb.design_table(record, xml, load_catalog(), ranges)))


def test_a_long_hold_saturates_the_walk_and_a_lower_speed_answers_it(walker) -> None:
    """Built to fail: held 40 ms, every joint's reference steps further than the servo's
    band a frame and the walk fails saturated; replayed with the commands applied as sent
    it passes, and the speed named makes the same perturbed run pass."""
    files = Bundle.read(walker)
    table = _table(walker, _closed("40 ms"))
    traj, result, p = run_perturbed(files, "walking", 1, table=table)
    assert p["control_period_s"] == pytest.approx(0.04)
    assert "saturated" in result.verdict, result.verdict
    found = hold_attribution(files, table, "walking", 1)
    assert found is not None
    assert found["frame_s"] == pytest.approx(0.04) and found["unit"] == "m/s"
    assert max(found["joints"].values()) > SERVO_BAND
    assert found["speed"] is not None and found["speed"] < found["default_speed"]
    _, slower, _ = run_perturbed(files, "walking", 1, {"speed": found["speed"]}, table=table)
    assert not slower.verdict, slower.verdict
    note = hold_note([{"behavior": "walking", "seed": 1} | found], "walking")
    assert "40 ms command hold breaks it" in note and f"{found['speed']:g} m/s" in note


def test_what_the_hold_does_not_break_is_not_blamed_on_it(walker) -> None:
    """A run that passes, a run with no hold, and a run that a weak battery breaks with or
    without the hold (its servos at a quarter of their torque) are not the hold's."""
    files = Bundle.read(walker)
    assert hold_attribution(files, _table(walker, _closed("10 ms")), "walking", 1) is None
    assert hold_attribution(files, _table(walker, _closed("0 ms")), "walking", 1) is None
    weak = _table(walker, _closed("20 ms", "40 V"))
    _, result, p = run_perturbed(files, "walking", 1, table=weak)
    assert p["battery_scale"] < 0.3 and "saturated" in result.verdict
    assert hold_attribution(files, weak, "walking", 1) is None
    assert hold_note([], "walking") == ""


def test_hold_blame_reads_the_robust_record(walker) -> None:
    """On ``verify_robust``'s record: the failed runs of the behaviour that is not robust,
    each with its seed, and none for a record of runs that all passed."""
    files = Bundle.read(walker)
    robust = verify_robust(files, 2, _table(walker, _closed("40 ms")), behaviors=["walking"])
    assert not robust.behaviors[0].robust
    blamed = hold_blame(files, robust)
    assert [(r["behavior"], r["seed"]) for r in blamed] == [("walking", 1), ("walking", 2)]
    fine = verify_robust(files, 1, _table(walker, _closed("10 ms")), behaviors=["walking"])
    assert fine.behaviors[0].robust and hold_blame(files, fine) == []


# --- the pace that answers it (issue 30): chosen by the robust loop, kept in the record ----


def _round(files: Bundle, robust, demanded=("walking",)):
    from adron.catalog import load_catalog
    from synth.verification.causes import Round

    record = files.record
    models = {j["name"]: j["actuator"] for j in record["joints"]}
    return Round(1, record, models, load_catalog(), robust, lambda: files,
                 demanded=frozenset(demanded))  # fmt: skip


def test_the_hold_cause_chooses_a_pace_every_perturbed_run_passes_at(walker) -> None:
    """Built to fail first: held 40 ms the walk fails every run saturated; the cause's pace
    is below the design's own and, kept in the record, every perturbed run passes with it
    (replayed from the bundle as ``parmor simulate --perturb`` does)."""
    from synth.verification.hold import Hold, with_paces

    files = Bundle.read(walker)
    table = _table(walker, _closed("40 ms"))
    robust = verify_robust(files, 3, table, behaviors=["walking"])
    assert robust.behaviors[0].passed == 0
    hold = Hold()
    remedy = hold.explains(_round(files, robust))
    assert remedy is not None and set(remedy.paces) == {"walking"}
    pace = remedy.paces["walking"]
    assert 0 < pace < hold.tried[0]["from"] and hold.tried[-1]["passed"] == 3
    paced = with_paces(files, remedy.paces)
    again = verify_robust(paced, 3, table, behaviors=["walking"])
    assert again.behaviors[0].passed == 3
    traj, result, _ = run_perturbed(paced, "walking", 2, table=table)
    assert not result.verdict and traj.info["speed"] == pytest.approx(pace)
    hold.chose(remedy.paces)
    rec = hold.record()
    assert rec["chosen"] == {"walking": pace} and rec["tried"][-1]["parameter"] == "speed"
    assert hold.note("walking", 1) == ""  # chosen: nothing for a refusal to add


def test_no_pace_is_chosen_where_the_request_gave_the_speed_or_the_walk_is_a_bonus(
    walker,
) -> None:
    """The user's ``--param speed`` is theirs: the refusal names the pace that would pass
    instead; a behaviour no demanded ability needs gets none either (it is dropped)."""
    from synth.verification.hold import Hold

    files = Bundle.read(walker)
    robust = verify_robust(files, 2, _table(walker, _closed("40 ms")), behaviors=["walking"])
    fixed = Hold(given={"speed": 0.05})
    assert fixed.explains(_round(files, robust)) is None and not fixed.tried
    note = fixed.note("walking", 1)
    assert "command hold breaks it" in note and "--param speed" in note
    bonus = Hold()
    assert bonus.explains(_round(files, robust, demanded=())) is None and not bonus.tried


def test_a_recorded_pace_is_what_every_runner_plans_with(walker) -> None:
    """The record's ``paces`` is the behaviour's default pace for the controller (a
    caller's own value wins) and what a program is offered; a bad one is refused naming
    the key."""
    from gaits import controller_for
    from gaits.base import DesignGeometry, pace_parameter
    from program.session import program_behaviors

    record = Bundle.read(walker).record
    plain = controller_for(DesignGeometry.from_record(record))
    own = plain.run("walking").info["speed"]
    paced = controller_for(DesignGeometry.from_record(record | {"paces": {"walking": own / 2}}))
    assert paced.run("walking").info["speed"] == pytest.approx(own / 2)
    assert paced.run("walking", speed=own).info["speed"] == pytest.approx(own)
    assert paced.run("turning").info["speed"] == plain.run("turning").info["speed"]
    spec = program_behaviors(paced, record["abilities"])["walking"]
    assert pace_parameter(spec) == "speed"
    assert next(p for p in spec.params if p.name == "speed").default == pytest.approx(own / 2)
    from export.record_schema import check_record

    with pytest.raises(Exception, match="paces.walking"):
        check_record(record | {"paces": {"walking": -1}}, "design.json")


# --- a round that probes (issue 32): the worst-looking run first, stopped once it saturates ---


def test_a_probe_stops_at_a_saturated_worst_looking_run_and_changes_nothing_else(walker) -> None:
    """Built to fail first: held 40 ms the worst-looking run saturates, so the round stops
    there (one run a plan, ``stopped["probe"]``), and what saturated is what the loop
    strengthens. Held 10 ms nothing saturates: every run is made and the result is the
    one without the probe, to the bit."""
    files = Bundle.read(walker)
    held = _table(walker, _closed("40 ms"))
    probed = verify_robust(files, 3, held, behaviors=["walking"], probe=True)
    assert probed.stopped is not None and probed.stopped["probe"] is True
    (walking,) = probed.behaviors
    assert walking.runs == 1 and walking.passed == 0 and not walking.robust
    assert probed.failing_runs()[0].saturated_joints
    full = verify_robust(files, 3, held, behaviors=["walking"])
    assert full.behaviors[0].runs == 3 and full.stopped is None
    fine = _table(walker, _closed("10 ms"))
    a = verify_robust(files, 3, fine, behaviors=["walking", "turning"], probe=True)
    b = verify_robust(files, 3, fine, behaviors=["walking", "turning"])
    assert a.stopped is None and a.to_dict() == b.to_dict()


def test_a_round_a_repair_may_follow_stops_at_its_first_failed_batch(walker) -> None:
    """Built to fail first: held 40 ms every run fails, so a round a repair may follow
    (``repair``) stops after its first batch of runs (the worst-looking perturbation
    first, each run whole: its figures are the full run's), listing only what failed.
    Held 10 ms nothing fails: every run is made and the result is the one without
    ``repair``, to the bit."""
    from synth.verification.perturb import worst_first

    files = Bundle.read(walker)
    held = _table(walker, _closed("40 ms"))
    cut = verify_robust(files, 3, held, behaviors=["walking", "turning"], repair=True)
    assert cut.stopped is not None and cut.stopped["repair"] is True
    assert cut.stopped["order"][0] == worst_first(held, [1, 2, 3])[0]
    assert cut.stopped["runs"] < 2 * 3
    assert all(r.figures["complete"] for b in cut.behaviors for r in b.figures)
    assert {b.behavior for b in cut.behaviors} == set(cut.stopped["decided"])
    fine = _table(walker, _closed("10 ms"))
    a = verify_robust(files, 3, fine, behaviors=["walking", "turning"], repair=True)
    b = verify_robust(files, 3, fine, behaviors=["walking", "turning"])
    assert a.stopped is None and a.to_dict() == b.to_dict()


def test_runs_made_before_are_taken_only_for_the_same_robot(walker, monkeypatch) -> None:
    """The runs a call made (``RobustRuns.made``) are taken by the next call on the same
    robot, table and plans (none made again, the same result to the bit); built to fail:
    on another table they are not taken (every run made again)."""
    from synth.verification.runs import Perturbed

    files = Bundle.read(walker)
    fine = _table(walker, _closed("10 ms"))
    first = verify_robust(files, 2, fine, behaviors=["walking"])
    assert len(first.made) == 2
    made = []
    real = Perturbed.simulate
    monkeypatch.setattr(
        Perturbed, "simulate", lambda self, *a, **k: made.append(self.seed) or real(self, *a, **k)
    )
    again = verify_robust(files, 2, fine, behaviors=["walking"], made=first.made)
    assert made == [] and again.to_dict() == first.to_dict()
    other = _table(walker, _closed("20 ms"))
    verify_robust(files, 2, other, behaviors=["walking"], made=first.made)
    assert sorted(made) == [1, 2]


def test_a_probed_round_no_stronger_actuator_answers_is_made_whole(
    walker, tmp_path: Path, monkeypatch
) -> None:
    """Built to fail: every servo held 40 ms (the catalog's [perturbation]) and no stronger
    actuator to be had: the probed round is made again with every run, so the refusal
    counts every perturbed run, never the probe's one. (The refusal's hint bisects the
    asked speed from 1 % of it: it used to try 0.5 mm/s, below --param speed's range, and
    the request ended on exit 2 naming params.speed; the search now starts at the range.)"""
    from synth.verification.loop import Strengthening

    monkeypatch.setattr(Strengthening, "_stronger", lambda self, now: None)
    catalog = tmp_path / "held.toml"
    catalog.write_text(
        '[catalog]\nname = "held"\ncurrency = "EUR"\nversion = "1"\nextends = "default"\n\n'
        '[perturbation.bus]\ncontrol_period = "40 ms"\n'
    )
    kif = tmp_path / "walker.kif"
    kif.write_text(legged_kif("HoldWalker4", 4, "hold-4-walking"))
    out, err = io.StringIO(), io.StringIO()
    argv = ["design", "hold-4-walking", "--ontology", str(kif), "--no-input", "--json"]
    argv += ["--catalog", str(catalog), "--robustness", "3", "--param", "speed=0.05m/s"]
    assert main(argv, out, err) == 1, err.getvalue()
    record = json.loads(out.getvalue())
    runs = {b["behavior"]: b["runs"] for b in record["verified"]["robust"]["behaviors"]}
    assert runs and all(n == 3 for n in runs.values()), runs
    assert "probe" not in (record["verified"]["robust"].get("stopped") or {})
    assert "passed 0 of 3 perturbed runs" in record["infeasible"]


# --- the coarse step's guard band: a run near its limit is decided at the model's own step ---


def test_a_figure_within_the_steps_agreement_of_its_limit_is_near() -> None:
    """Placing is judged at 5 mm and the coarse step agrees within 1.5 mm: 4.9 and 5.8 mm
    are near the limit (either way), 2 and 8 mm are not (built to fail both ways)."""
    from synth.verification.runs import near_limit

    info = {"motion": "place"}

    def fig(mm: float) -> dict:
        return {"seconds": 5.0, "saturated_fraction": 0.0, "placing_error_m": mm / 1000}

    assert near_limit(fig(4.9), info, False) and near_limit(fig(5.8), info, False)
    assert not near_limit(fig(2.0), info, False) and not near_limit(fig(8.0), info, False)
    # a support margin 1 mm inside the polygon is near; 20 mm is not
    walk = {"motion": "straight", "min_stability_margin_m": 0.01}
    base = {"seconds": 10.0, "distance_m": 1.0, "planned_distance_m": 1.0, "heading_rad": 0.0}
    assert near_limit(base | {"support_margin_m": 0.001}, walk, True)
    assert not near_limit(base | {"support_margin_m": 0.02}, walk, True)


def test_a_coarse_run_near_its_limit_is_made_again_at_the_models_own_step(
    walker, monkeypatch
) -> None:
    """At the coarse step a run near its limit is the run at the model's own step (the
    same figures, ``fine_step`` said); one that is not near stays coarse."""
    import synth.verification.runs as runs
    from synth.verification.runs import Perturbed

    files = Bundle.read(walker)
    fine = _table(walker, _closed("10 ms"))
    coarse = dict(fine, timestep_s=0.004)
    plan = files.controller().run("walking")
    at_own = Perturbed(files, fine, 1).simulate(plan).to_dict()
    monkeypatch.setattr(runs, "near_limit", lambda *a: False)
    kept = Perturbed(files, coarse, 1).simulate(plan).to_dict()
    assert "fine_step" not in kept and kept != at_own
    monkeypatch.setattr(runs, "near_limit", lambda *a: True)
    again = Perturbed(files, coarse, 1).simulate(plan).to_dict()
    assert again.pop("fine_step") is True and again == at_own
