"""Abilities reach behaviours through the ontology's action taxonomy, and no demanded ability
is accepted unsimulated (issue 21, items 2 and 3); a refusal by the module limit names the
count, the limit and the bus, and a sweep accepts only designs with a structure (issue 24,
item 4).

The abilities here are KIF-only: subclasses of shipped abilities (served by their nearest
ancestor's behaviours), and new abilities that no behaviour serves (refused).
"""

from __future__ import annotations

import json

import pytest

import synth.commands.sweep
import synth.verification.loop
import synth.verification.runs
from adron.kb import load
from gaits import controller_for
from gaits.base import DesignGeometry, serving
from synth.pipeline import Outcome, StructureOptions, run
from synth.reasoning.conceptual import Designer, Request
from synth.reasoning.solver import Reasoner
from tests.adron.test_bus_limit import _catalog
from tests.kinematics.test_bodyplan import legged_kif

#: abilities under shipped ones (two levels under walking), and ones no behaviour serves
KIF = """
(subclass RobotHeavyWalking RobotWalking)
(abilityName RobotHeavyWalking "heavy-walking")
(abilityVerb RobotHeavyWalking "walk with heavy loads")
(requiredPartCount RobotHeavyWalking RobotLeg 6)
(subclass RobotVeryHeavyWalking RobotHeavyWalking)
(abilityName RobotVeryHeavyWalking "very-heavy-walking")
(abilityVerb RobotVeryHeavyWalking "walk with very heavy loads")
(requiredPartCount RobotVeryHeavyWalking RobotLeg 6)
(subclass RobotSteepWalking RobotRoughTerrainWalking)
(abilityName RobotSteepWalking "steep-walking")
(abilityVerb RobotSteepWalking "walk up steep ground")
(requiredPartCount RobotSteepWalking RobotLeg 6)
(subclass RobotSprinting RobotRunning)
(abilityName RobotSprinting "sprinting")
(abilityVerb RobotSprinting "sprint")
(requiredPartCount RobotSprinting RobotLeg 2)
(subclass RobotCargoDriving RobotDriving)
(abilityName RobotCargoDriving "cargo-driving")
(abilityVerb RobotCargoDriving "drive with cargo")
(requiredPartCount RobotCargoDriving DriveWheel 2)
(subclass RobotSpinRolling RobotLateralRolling)
(abilityName RobotSpinRolling "spin-rolling")
(abilityVerb RobotSpinRolling "roll sideways fast")
(requiredPartCount RobotSpinRolling SnakeModule 3)
(subclass RobotCanPlacing RobotPickAndPlace)
(abilityName RobotCanPlacing "can-placing")
(abilityVerb RobotCanPlacing "place cans")
(requiredPartCount RobotCanPlacing RoboticGripper 1)
(requiredPartCount RobotCanPlacing PositionServomotor 3)
(subclass RobotFastLineTracking RobotLineTracking)
(abilityName RobotFastLineTracking "fast-line-tracking")
(abilityVerb RobotFastLineTracking "track a line fast")
(requiredPartCount RobotFastLineTracking InfraredSensorModule 2)
(subclass RobotWaving RobotMotion)
(abilityName RobotWaving "waving")
(abilityVerb RobotWaving "wave an arm")
(requiredPartCount RobotWaving RobotArm 1)
(subclass RobotGreeting RobotWaving)
(abilityName RobotGreeting "greeting")
(abilityVerb RobotGreeting "greet people")
(requiredPartCount RobotGreeting RobotArm 1)
(subclass RobotSweeping RobotAction)
(abilityName RobotSweeping "sweeping")
(abilityVerb RobotSweeping "sweep the floor")
(requiredPartCount RobotSweeping DriveWheel 2)
"""

WAVING = """
(subclass RobotWaving RobotMotion)
(abilityName RobotWaving "waving")
(abilityVerb RobotWaving "wave an arm")
(requiredPartCount RobotWaving RobotArm 1)
"""


@pytest.fixture(scope="module")
def grid_designer(tmp_path_factory) -> Designer:
    path = tmp_path_factory.mktemp("kif") / "abilities.kif"
    path.write_text(KIF, encoding="utf-8")
    kb = load([str(path)])
    return Designer(kb, Reasoner(kb, (), False, bus_limit=24))


# --- the mapping ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("ability", "ancestors", "offered", "expected"),
    [
        ("walking", {}, {"walking"}, "walking"),
        ("heavy-walking", {"heavy-walking": ("walking",)}, {"walking"}, "walking"),
        # the nearest ancestor with behaviours, not a farther one
        ("x", {"x": ("heavy-walking", "walking")}, {"walking", "heavy-walking"}, "heavy-walking"),
        ("x", {"x": ("heavy-walking", "walking")}, {"walking"}, "walking"),
        # its own behaviours first
        ("y", {"y": ("walking",)}, {"walking", "y"}, "y"),
        # built to fail: no behaviour for it or any ancestor; ancestors of another ability
        ("waving", {"waving": ("gesturing",)}, {"walking"}, None),
        ("heavy-walking", {"other": ("walking",)}, {"walking"}, None),
    ],
)  # fmt: skip
def test_serving_is_the_ability_or_its_nearest_ancestor_with_behaviours(
    ability, ancestors, offered, expected
) -> None:
    assert serving(ability, ancestors, offered) == expected


def test_ancestors_come_from_the_ontology_nearest_first(grid_designer) -> None:
    got = grid_designer.ability_ancestors(
        ["very-heavy-walking", "steep-walking", "walking", "greeting", "sweeping", "nonesuch"]
    )
    assert got == {
        "very-heavy-walking": ("heavy-walking", "walking"),
        "steep-walking": ("rough-terrain-walking", "walking"),
        "greeting": ("waving",),
    }


def _sized(designer: Designer, req: Request) -> tuple[dict, object, Outcome]:
    out = run(designer, req, StructureOptions(verify=False))
    assert out.structure is not None, (out.status, out.infeasible, out.design.questions)
    rec = out.record(designer)
    return rec, controller_for(DesignGeometry.from_record(rec)), out


def test_a_subclass_ability_lists_its_ancestors_behaviours_from_the_record_alone(
    grid_designer,
) -> None:
    rec, controller, _ = _sized(grid_designer, Request(("very-heavy-walking",)))
    assert rec["ability_ancestors"]["very-heavy-walking"] == ["heavy-walking", "walking"]
    # the record through JSON (a bundle read without the ontology) serves it the same way
    again = controller_for(DesignGeometry.from_record(json.loads(json.dumps(rec))))
    for c in (controller, again):
        assert c.serving("very-heavy-walking") == "walking"
        assert {"walking", "turning"} <= set(c.listed(["very-heavy-walking"]))
        assert c.unbehaved(["very-heavy-walking"]) == []
    # built to fail: without the ancestry no behaviour serves it
    bare = controller_for(DesignGeometry.from_record({**rec, "ability_ancestors": {}}))
    assert bare.listed(["very-heavy-walking"]) == []
    assert bare.unbehaved(["very-heavy-walking"]) == ["very-heavy-walking"]


#: (abilities, answers, params) -> {demanded ability: the ability that serves it, or None}
GRID = [
    (("heavy-walking",), (), (), {"heavy-walking": "walking"}),
    (("very-heavy-walking",), (), (), {"very-heavy-walking": "walking"}),
    (("steep-walking",), (), (), {"steep-walking": "rough-terrain-walking"}),
    (("sprinting",), (("grasping", True),), (), {"sprinting": "running"}),
    (
        ("sprinting",),
        (("grasping", False), ("rough-terrain-walking", False)),
        (),
        {"sprinting": "running"},
    ),
    (("cargo-driving",), (), (), {"cargo-driving": "driving"}),
    (
        ("cargo-driving",),
        (),
        (("payload", "2kg"), ("speed", "0.2m/s")),
        {"cargo-driving": "driving"},
    ),
    (("spin-rolling",), (), (), {"spin-rolling": "rolling"}),
    (("can-placing",), (), (("object_shape", "cylinder"),), {"can-placing": "pick-and-place"}),
    (
        ("can-placing",),
        (),
        (("object_shape", "oval"),),
        {"can-placing": "pick-and-place", "orienting": "orienting"},
    ),
    (
        ("fast-line-tracking", "driving"),
        (),
        (),
        {"fast-line-tracking": "line-tracking", "driving": "driving"},
    ),
    (("heavy-walking",), (), (("payload", "0.3kg"),), {"heavy-walking": "walking"}),
    (("waving",), (), (), {"waving": None}),
    (("greeting",), (), (), {"greeting": None}),
    (("sweeping",), (), (), {"sweeping": None}),
    (("sweeping", "cargo-driving"), (), (), {"sweeping": None, "cargo-driving": "driving"}),
    (("walking",), (("grasping", True),), (), {"walking": "walking", "grasping": "grasping"}),
    (("rough-terrain-walking",), (), (), {"rough-terrain-walking": "rough-terrain-walking"}),
    (("driving",), (), (), {"driving": "driving"}),
    (("rolling",), (), (), {"rolling": "rolling"}),
    (
        ("pick-and-place",),
        (),
        (("object_shape", "cylinder"),),
        {"pick-and-place": "pick-and-place"},
    ),
    (("walking", "balancing"), (("grasping", True),), (), {"balancing": "balancing"}),
]


@pytest.mark.parametrize(("abilities", "answers", "params", "expected"), GRID)
def test_each_demanded_ability_is_served_or_refused(
    grid_designer, abilities, answers, params, expected
) -> None:
    """Over the grid (KIF subclasses of every shipped family's abilities, new abilities no
    behaviour serves, shipped requests): which behaviour serves each demanded ability, and
    the refusal exactly for those none serves."""
    rec, controller, out = _sized(grid_designer, Request(abilities, answers, params))
    served = synth.verification.loop.served_abilities(rec, controller)
    assert {a: served[a] for a in expected} == expected
    unserved = synth.verification.loop._unserved(grid_designer, out)
    assert sorted(unserved) == sorted(a for a, s in expected.items() if s is None)
    for a, s in expected.items():
        if s is not None and s in {b.realises for b in controller.behaviors.values()}:
            assert controller.listed([a]), a  # its server's behaviours are listed


# --- refusing what no behaviour serves -----------------------------------------------------


def test_a_demanded_ability_without_behaviour_is_refused(cli, tmp_path) -> None:
    src = tmp_path / "waving.kif"
    src.write_text(WAVING, encoding="utf-8")
    out = tmp_path / "bundle"
    r = cli("design", "waving", "--ontology", str(src), "--no-input", "--out", str(out))
    assert r.code == 1, r.err
    assert "waving is demanded but no behaviour serves it" in r.err
    assert "a behaviour for waving would serve it" in r.err
    assert "--allow-unverified" in r.err
    assert "Traceback" not in r.err and not out.exists()  # nothing half-written


def test_allow_unverified_accepts_it_and_says_so(cli, tmp_path) -> None:
    src = tmp_path / "waving.kif"
    src.write_text(WAVING, encoding="utf-8")
    out = tmp_path / "bundle"
    r = cli(
        "design", "waving", "--ontology", str(src), "--no-input", "--allow-unverified",
        "--out", str(out),
    )  # fmt: skip
    assert r.code == 0, r.err
    rec = json.loads((out / "design.json").read_text())
    assert rec["verified"]["accepted_unsimulated"] == ["waving"]
    assert rec["verified"]["not_simulated"] == ["waving"]
    assert any("waving is not simulated" in n for n in rec["notes"])
    assert "**Not simulated: waving.**" in (out / "README.md").read_text()
    assert "accepted unsimulated (--allow-unverified): waving" in r.out
    # the abilities served were simulated all the same
    assert {b["ability"] for b in rec["verified"]["behaviors"]} >= {"walking"}


def test_no_verify_does_not_refuse_it(cli, tmp_path) -> None:
    src = tmp_path / "waving.kif"
    src.write_text(WAVING, encoding="utf-8")
    r = cli("design", "waving", "--ontology", str(src), "--no-input", "--no-verify", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["verified"]["note"] == "not simulated (--no-verify)"


def _result(behavior, ability, verdict="ok", **kw):
    from synth.verification.results import Run

    return Run.of(
        {"behavior": behavior, "ability": ability, "verdict": verdict, "seconds": 1.0} | kw
    )


def _fake(results):
    def verify_nominal(bundle, behaviors=None):
        return results

    return verify_nominal


CANS = Request(("can-placing",), params=(("object_shape", "cylinder"),))


def test_a_failing_behaviour_that_serves_a_demanded_subclass_fails_the_request(
    grid_designer, monkeypatch
) -> None:
    monkeypatch.setattr(synth.verification.loop, "HINT_ROUNDS", 0)
    bad = _result("pick-and-place", "pick-and-place", ["placing"], placing_error_m=0.012)
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", _fake([bad]))
    out = run(grid_designer, CANS, StructureOptions())
    assert out.status == "infeasible"
    assert out.infeasible.startswith("pick-and-place (serving can-placing) failed in simulation")


def test_a_failing_bonus_behaviour_is_dropped_not_refused(grid_designer, monkeypatch) -> None:
    """Built to pass where the one above fails: positioning serves no demanded ability."""
    bad = _result("positioning", "positioning", ["placing"], placing_error_m=0.02)
    ok = _result("pick-and-place", "pick-and-place")
    monkeypatch.setattr(synth.verification.runs, "verify_nominal", _fake([ok, bad]))
    out = run(grid_designer, CANS, StructureOptions())
    rec = out.record(grid_designer)
    assert out.infeasible is None
    assert "positioning" not in rec["abilities"] and "can-placing" in rec["abilities"]


# --- the module limit ----------------------------------------------------------------------


def test_a_refusal_by_the_module_limit_names_count_limit_and_bus(cli, tmp_path) -> None:
    src = tmp_path / "octopod.kif"
    src.write_text(legged_kif("Octopod", 8, "fault-tolerant-walking"), encoding="utf-8")
    r = cli("design", "fault-tolerant-walking", "--ontology", str(src), "--no-input", "--json")
    assert r.code == 1
    assert (
        "no robot can meet the request: fault-tolerant-walking (Octopod has 26 active "
        "modules, over the limit of 24 on the I2C bus (catalog 'ParMoR reference modules'))"
    ) in r.err
    rec = json.loads(r.out)
    assert rec["over_limit"] == [
        {"robot_type": "Octopod", "active_modules": 26, "module_limit": 24}
    ]
    r = cli(
        "design", "fault-tolerant-walking", "--ontology", str(src), "--no-input", "--conceptual"
    )
    assert r.code == 1 and "over the limit of 24 set by the ontology (activeModuleLimit)" in r.err
    # built to pass: a bus of 40 carries it
    r = cli(
        "design", "fault-tolerant-walking", "--ontology", str(src), "--no-input", "--conceptual",
        "--catalog", _catalog(tmp_path, 40), "--json",
    )  # fmt: skip
    assert r.code == 0, r.err
    assert json.loads(r.out)["robot_type"] == "Octopod"


def test_enumerate_names_the_limit_too(cli, tmp_path) -> None:
    src = tmp_path / "octopod.kif"
    src.write_text(legged_kif("Octopod", 8, "fault-tolerant-walking"), encoding="utf-8")
    r = cli("enumerate", "fault-tolerant-walking", "--ontology", str(src))
    assert r.code == 1 and "Octopod has 26 active modules, over the limit of 24" in r.err
    r = cli("enumerate", "rolling", "grasping")  # a conflict: no robot to name
    assert r.code == 1 and r.err == "parmor: no robot can meet the request: rolling + grasping\n"


def test_a_small_bus_names_itself(cli, tmp_path) -> None:
    r = cli(
        "design", "rough-terrain-walking", "--no-input", "--conceptual",
        "--catalog", _catalog(tmp_path, 10),
    )  # fmt: skip
    assert r.code == 1
    assert "HexapodRobot has 20 active modules, over the limit of 10 on the test bus" in r.err


def test_a_conflict_of_abilities_names_no_limit(cli) -> None:
    r = cli("design", "rolling", "grasping", "--no-input", "--conceptual")
    assert r.code == 1 and "active modules" not in r.err


# --- the sweep -----------------------------------------------------------------------------


def test_a_sweep_accepts_only_designs_with_a_structure(designer, monkeypatch) -> None:
    import synth.pipeline

    req = {"abilities": ["driving"], "answers": {}, "params": {}, "where": "t"}
    real = synth.pipeline.run

    def conceptual(designer, request, opts):
        out = real(designer, request, StructureOptions(conceptual=True))
        return Outcome(out.design, note="stopped after the conceptual design")

    monkeypatch.setattr(synth.pipeline, "run", conceptual)
    res = synth.commands.sweep.design_one(req, designer, StructureOptions(verify=False), False)
    assert res["status"] == "refused"
    assert res["reason"] == "no structure: stopped after the conceptual design"
    monkeypatch.setattr(synth.pipeline, "run", real)
    res = synth.commands.sweep.design_one(req, designer, StructureOptions(verify=False), False)
    assert res["status"] == "accepted" and res["mass_kg"]


def test_the_sizing_plans_the_behaviours_that_serve_a_subclass(grid_designer) -> None:
    """The behaviour loads a design is sized for come from the same serving: a design whose
    only walking ability were the subclass is still sized for walking."""
    import dataclasses

    from synth.sizing.behaviour_loads import behaviour_trajectories

    rec, _, _ = _sized(grid_designer, Request(("very-heavy-walking",)))
    geometry = DesignGeometry.from_record(rec)
    only = dataclasses.replace(geometry, abilities=("very-heavy-walking",))
    trajs, _ = behaviour_trajectories(only)
    assert {"walking", "turning"} <= set(trajs)
    # built to fail: without the ancestry nothing serves it, so nothing is planned
    bare = dataclasses.replace(only, ancestors={})
    assert behaviour_trajectories(bare)[0] == {}
