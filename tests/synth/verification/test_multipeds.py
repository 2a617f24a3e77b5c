"""Multipeds of 4 to 8 legs on a trunk, written in KIF alone (issue 21): gaits by leg count
and placement, each statically stable at its neutral stance; every count designed and
verified in MuJoCo (walking, turning, running, rough-terrain walking where the type has
it); the static stability margin judged on the simulated outcome, with a statically
unstable gait built to fail it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gaits.hexapod import (
    GAITS,
    STANCE_NAMES,
    _ring,
    gait_pattern,
    legs_of,
    support_margin,
)
from tests.kinematics.test_bodyplan import legged_kif

WORDS = {4: "four", 5: "five", 6: "six", 7: "seven", 8: "eight"}
STUDIES = Path(__file__).resolve().parents[3] / "studies"


def _kif(n: int) -> str:
    return legged_kif(f"Walker{n}", n, f"{WORDS[n]}-leg-walking")


@pytest.fixture(scope="module")
def templates(tmp_path_factory) -> dict:
    """The assembled templates of the KIF-only walkers of 4 to 8 legs."""
    from adron.kb import load as load_kb
    from kinematics.partkinds import load
    from kinematics.templates import build
    from synth.reasoning.plans import plan_of

    folder = tmp_path_factory.mktemp("walkers")
    out = {}
    for n in WORDS:
        f = folder / f"walker{n}.kif"
        f.write_text(_kif(n))
        out[n] = build(plan_of(load_kb([f]), f"Walker{n}", load()))
    return out


def test_gaits_by_count() -> None:
    assert GAITS[4] == ("crawl",)
    assert GAITS[6] == ("tripod", "ripple", "wave")  # the hexapod's, unchanged
    assert GAITS[5] == ("tripod", "wave")
    assert GAITS[7] == ("tripod", "tetrapod", "ripple", "wave")
    assert GAITS[8] == ("tetrapod", "tripod", "ripple", "wave")  # alternate halves first
    assert GAITS[9] == ("tripod", "tetrapod", "ripple", "wave")
    with pytest.raises(KeyError):
        GAITS[3]


def _standing(pattern, legs, phase: float) -> list:
    """The legs on the ground at ``phase`` of a cycle."""
    out = []
    for leg in legs:
        into = (phase - pattern.phases[leg.name]) % 1.0
        if into >= 1 - pattern.duty:  # past its swing
            out.append(leg)
    return out


@pytest.mark.parametrize("n", [5, 6, 7, 8])
def test_every_gait_stands_on_its_named_feet_around_the_centre(n, templates) -> None:
    """At every instant of a cycle each gait keeps its named count of feet on the ground
    (tripod 3, tetrapod 4, ripple all but two, wave all but one) and, in the gaits spread
    around the trunk (all but the hexapod's and the side waves of the ripple and wave),
    the mounts' centre over the polygon of their neutral points, whatever the direction
    of travel."""
    legs = legs_of(templates[n])
    centre = np.mean([leg.mount[:2] for leg in legs], axis=0)
    names = {v: k for k, v in STANCE_NAMES.items()}
    for name in GAITS[n]:
        feet = names.get(name, n - 2 if name == "ripple" else n - 1)
        spread = n != 6 and (name in names or (name == "ripple" and n % 2 == 1))
        for direction in np.linspace(-math.pi, math.pi, 8, endpoint=False):
            pattern = gait_pattern(name, legs, float(direction))
            assert sorted(pattern.phases) == sorted(leg.name for leg in legs)
            for phase in np.linspace(0.0, 1.0, 240, endpoint=False) + 1e-6:
                standing = _standing(pattern, legs, phase)
                assert len(standing) >= feet, (name, phase)
                if not (n == 6 and name != "tripod"):  # the hexapod's side waves: n - 2
                    assert len(standing) == feet, (name, phase)
                if spread:
                    points = np.array([leg.neutral[:2] for leg in standing])
                    assert support_margin(points, centre) > 0.01, (name, direction, phase)


def test_the_pentapod_tripod_lifts_every_other_leg(templates) -> None:
    """Five legs: one lifts every fifth of a cycle, two legs around the trunk from the one
    before (a five-pointed star), starting with a trailing leg; three stand."""
    legs = legs_of(templates[5])
    ring = [leg.name for leg in _ring(legs)]
    pattern = gait_pattern("tripod", legs)
    assert pattern.duty == pytest.approx(0.6)
    order = sorted(pattern.phases, key=pattern.phases.get)
    steps = {(ring.index(b) - ring.index(a)) % 5 for a, b in zip(order, order[1:], strict=False)}
    assert steps in ({2}, {3})
    first = next(leg for leg in legs if leg.name == order[0])
    assert first.mount[0] == pytest.approx(min(leg.mount[0] for leg in legs))


def test_running_is_the_tripod_where_the_count_has_one() -> None:
    from gaits.legged import run_gait

    assert run_gait(4) == ("crawl", pytest.approx(0.8))
    assert run_gait(6) == ("tripod", None)
    for n in (5, 7, 8, 9):
        assert run_gait(n) == ("tripod", None)


@pytest.mark.parametrize("n", [4, 5, 6, 7, 8])
def test_every_count_walks_turns_and_runs_in_mujoco(cli, tmp_path, n) -> None:
    """``parmor design`` (verified) keeps every behaviour the type lists, and ``parmor
    simulate --json`` passes each, with the measured static margin positive."""
    src = tmp_path / f"walker{n}.kif"
    src.write_text(_kif(n))
    out = tmp_path / "bundle"
    extra = ["--catalog", "dynamixel"] if n == 8 else []
    r = cli(
        "design", f"{WORDS[n]}-leg-walking", "--ontology", str(src), "--no-input",
        "--out", str(out), *extra,
    )  # fmt: skip
    assert r.code == 0, r.err
    assert "dropped" not in r.out, r.out
    rec = json.loads((out / "design.json").read_text())
    wanted = {"walking", "running"} | ({"rough-terrain-walking"} if n >= 6 else set())
    assert wanted <= set(rec["abilities"])
    behaviours = ["walking", "turning", "running"] + (["rough-terrain-walking"] if n >= 6 else [])
    for b in behaviours:
        s = cli("simulate", str(out), "--behavior", b, "--json")
        assert s.code == 0, s.err
        fig = json.loads(s.out)
        assert fig["verdict"] == "ok", (b, fig)
        assert fig["support_margin_m"] > 0, (b, fig)


def test_a_statically_unstable_gait_fails_only_the_stability_verdict(cli, tmp_path) -> None:
    """Built to fail: the quadruped's crawl planned without its trunk sway keeps its
    support triangle's diagonal through the centre of mass (planned margin 0); in MuJoCo
    the trunk tips onto the swinging foot, yet travels, keeps its heading and does not
    fall: only the measured margin tells (the same crawl with its sway passes)."""
    from gaits.hexapod import MIN_MARGIN
    from synth.verification.runs import controller_for_model
    from synth.verification.simulate import simulate
    from synth.verification.source import Bundle

    src = tmp_path / "walker4.kif"
    src.write_text(_kif(4))
    out = tmp_path / "bundle"
    r = cli(
        "design", "four-leg-walking", "--ontology", str(src), "--no-input", "--no-verify",
        "--out", str(out),
    )  # fmt: skip
    assert r.code == 0, r.err
    bundle = Bundle.read(out)
    record, model = bundle.record, bundle.model()
    c = controller_for_model(record, model)
    good = c.run("walking", steps=2)
    assert good.info["min_stability_margin_m"] >= MIN_MARGIN
    ok = simulate(model, good)
    assert ok.verdict == [] and ok.support_margin_m > 0, ok.to_dict()

    pattern = gait_pattern("crawl", c.legs)
    twist = (good.info["speed"], 0.0, 0.0)
    plan = c._plan(pattern, 2, good.info["cycle_s"], twist, c.step_height, c.height, sway=False)
    assert plan.margin.min() < MIN_MARGIN
    info = {"motion": "straight", "direction": (1.0, 0.0)}
    bad = c._trajectory("walking", plan, pattern, info | {"planned_distance_m": 0.0})
    result = simulate(model, bad)
    assert result.verdict == ["stability"], result.to_dict()
    assert result.support_margin_m < 0 and not result.fell
    from synth.verification.verdict import explain

    why = explain(result.to_dict(), result.verdict)
    assert "left the feet's support polygon" in why and "-" in why


def test_no_contact_is_no_support() -> None:
    """A robot in the air has no support polygon: its margin is minus infinity, reported as
    None, and a promise of static stability then fails."""
    mujoco = pytest.importorskip("mujoco")
    from synth.verification.simulate import support_margin_of
    from synth.verification.verdict import judge

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom type="plane" size="1 1 0.1"/><body pos="0 0 1">'
        '<freejoint/><geom type="sphere" size="0.1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert support_margin_of(model, data) == -math.inf
    fig = {"seconds": 1.0, "fell": False, "support_margin_m": None}
    promise = {"motion": "hold", "min_stability_margin_m": 0.02}
    assert judge(fig, promise, free=True) == ["stability"]


def test_the_studies_cover_every_count_with_at_least_30_requests() -> None:
    """studies/multipeds.toml and studies/octopod.toml: the grid of the README's figures."""
    from synth.commands.sweep import load_study

    total, counts = 0, set()
    for name in ("multipeds.toml", "octopod.toml"):
        _, requests = load_study(STUDIES / name)
        total += len(requests)
        counts |= {q["name"] for q in requests}
    assert total >= 30
    assert counts == {f"walker{n}" for n in WORDS}


@pytest.mark.parametrize("n", [5, 7, 8])
def test_the_spread_gaits_walk_every_way_in_mujoco(cli, tmp_path, n) -> None:
    """Each gait spread around the trunk (tripod, tetrapod) keeps every verdict walking
    forward, backward, sideways and at an angle (three cycles), and turning both ways."""
    from synth.verification.runs import controller_for_model, figures, run_behavior
    from synth.verification.source import Bundle

    src = tmp_path / f"walker{n}.kif"
    src.write_text(_kif(n))
    out = tmp_path / "bundle"
    extra = ["--catalog", "dynamixel"] if n == 8 else []
    r = cli(
        "design", f"{WORDS[n]}-leg-walking", "--ontology", str(src), "--no-input",
        "--no-verify", "--out", str(out), *extra,
    )  # fmt: skip
    assert r.code == 0, r.err
    bundle = Bundle.read(out)
    record, model = bundle.record, bundle.model()
    c = controller_for_model(record, model)
    spread = [g for g in c.gaits if g in STANCE_NAMES.values()]
    assert spread
    for gait in spread:
        for direction in ("forward", "backward", "left", 0.7):
            params = {"gait": gait, "direction": direction, "steps": 3}
            traj, result = run_behavior(model, c, "walking", params)
            fig = figures(traj, result)
            assert fig["verdict"] == "ok", (gait, direction, fig)
        for angle in (2.0, -1.0):
            traj, result = run_behavior(model, c, "turning", {"gait": gait, "angle": angle})
            assert result.verdict == [], (gait, angle, result.to_dict())
