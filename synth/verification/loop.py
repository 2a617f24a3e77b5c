"""Closing the loop: a sized design's behaviours simulated, and failures fed back.

After the structure generator, every behaviour the design will list (its abilities'
behaviours, default parameters) runs in MuJoCo on the bundle's own model
(:mod:`synth.verification.runs`) and is judged on its outcome (:mod:`synth.verification.verdict`).
A behaviour that failed because an actuator sat at its torque limit feeds back: every joint that
saturated must get an actuator stronger than the one it had (a torque floor for the
structure generator, which sizes again, links included), then everything is simulated
again, up to ``MAX_ROUNDS`` sizings. What still fails then:

- a behaviour of an ability the request demands (``needed``) fails the request: the
  design is infeasible, naming the behaviour, the criterion and the figure;
- a behaviour of an ability the design only has as a bonus drops that ability from the
  design's ``abilities``, with a note.

Under ``--robustness K`` the behaviours that passed run under K perturbations too
(:mod:`synth.verification.robust`): a perturbed run with an actuator at its limit feeds the same
torque floors; one that the joints' play breaks (measured: replayed with the same perturbation
less the play, it passes; :func:`synth.verification.robust.play_blame`) excludes, for the joints
whose play it is, their servo and every servo of the catalog with as much play
(:func:`synth.verification.robust.less_play`), and the structure is sized again (the servo with less
play must still hold the joint's torque), up to ``PLAY_ROUNDS`` sizings more; the record's
``verified.play`` names each swap and the runs that called for it.
A failed perturbed run with no actuator saturated on a robot with wheels is replayed with
stiffer wheel servos (:func:`synth.verification.wheels.wheel_exclusions`): the first with which
the runs pass is the answer, the wheels may have no less stiff servo in the next sizing.

The sensing loops (:mod:`program.sensing`: line-tracking, obstacle-avoidance) that passed
nominally run under the same K perturbations once the repairs are done, on the design as
it stands (their runs feed no repair: they have no saturated joint to point at), unless
the plans' perturbed runs refuse the design already; a loop not robust refuses a demanded
ability or drops a bonus one like any behaviour, and one that passed nominally but was
not run perturbed refuses the design (:func:`robust_skipped`).

Before each round's verification, a controller whose open-loop model needs figures only a
run can give (:meth:`gaits.base.Controller.calibration_probes`: a skid-steer's effective
track and turning load) has its probe runs simulated and the design's ``calibration``
measured (:func:`calibrate`); the behaviours are then planned with it and verified. The
verdicts judge the outcome with it, unchanged.

Feedback other than stronger actuators (a larger wheel, a slower or lower gait, more
modules lifting) is each family's sizing rule, not this loop's: no failure class was found
that such a remedy fixes (measured on 96 requests off the shipped study's grid and on its
51 wheeled ones: none refused by simulation once a skid-steer is calibrated; the failures
left, a snake's bonus ``rolling`` with 0.3-0.5 kg on its strongest servos, which no
rolling frequency fixes either, and a skid-steer under 0.5 kg drifting while it turns in
place, worse when slower, have no remedy in that list), so there is no remedy table.

The record keeps each behaviour's figures (``verified``). This module runs the simulator,
so it imports ``export`` and ``gaits`` (lazily): it is the one place where ``synth`` looks
downstream, because the pipeline's last step is to check what it built.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

from adron.errors import InfeasibleError
from synth.verification.results import RobustRuns, Run

if TYPE_CHECKING:
    from synth.conceptual import Designer, Request
    from synth.pipeline import Outcome, StructureOptions
    from synth.verification.source import Bundle

#: What a refusal for robustness adds: the design did pass on the nominal model.
ROBUST_OFF = (
    "it passes on the nominal model: --robustness 0 gives that design (not verified under "
    "perturbations)"
)
#: Sizings tried in all (the first one included) before a failure is final.
MAX_ROUNDS = 3
#: A saturated joint's next actuator must give at least this much more usable torque.
STRONGER = 1.0001
#: Sizings beyond ``MAX_ROUNDS`` that answer a perturbed run broken by the joints' play
#: with servos of less play (``synth.verification.robust.less_play``).
PLAY_ROUNDS = 2
#: A refusal's hint (:func:`best_value`): sizings with verification at most, and the
#: bisection steps after the floor's test.
HINT_ROUNDS = 7
HINT_BISECTIONS = 4


@dataclass(frozen=True)
class Verification:
    """What the simulation found: each behaviour's figures (with ``ability``), the sizings
    it took, the joints it strengthened (joint -> N m floor), the abilities it dropped
    (ability -> why) and, when a demanded ability failed, why the design is infeasible."""

    behaviors: tuple[Run, ...]
    rounds: int
    strengthened: dict[str, float]
    dropped: dict[str, str]
    unsimulated: tuple[str, ...]  # abilities no behaviour serves (so none simulated)
    failure: str | None = None
    #: demanded abilities that no behaviour serves, accepted with --allow-unverified
    accepted_unsimulated: tuple[str, ...] = ()
    robust: RobustRuns | None = None  # the perturbed runs (robust.py), None when not run
    #: the servos swapped for less play (joint -> from, to) and the runs the play broke
    play: dict | None = None
    #: the wheels given stiffer servos (joint -> from, to) and the runs that called for it
    wheels: dict | None = None

    def record(self) -> dict:
        out = {
            "simulated": True,
            "rounds": self.rounds,
            "strengthened": {k: round(v, 6) for k, v in sorted(self.strengthened.items())},
            "dropped": dict(sorted(self.dropped.items())),
            "not_simulated": list(self.unsimulated),
            "behaviors": [r.to_dict() for r in self.behaviors],
        }
        if self.accepted_unsimulated:
            out["accepted_unsimulated"] = list(self.accepted_unsimulated)
        if self.robust is not None:
            out["robust"] = self.robust.to_dict()
        if self.play is not None:
            out["play"] = self.play
        if self.wheels is not None:
            out["wheels"] = self.wheels
        return out


def _floors(results: list[Run], record: dict) -> dict[str, float]:
    """Joint -> torque floor for every joint that saturated in a failing behaviour."""
    usable = {j["name"]: float(j["usable_torque_Nm"]) for j in record.get("joints", ())}
    out: dict[str, float] = {}
    for r in results:
        if r.ok:
            continue
        for joint in r.saturated_joints:
            if joint in usable:
                out[joint] = max(out.get(joint, 0.0), usable[joint] * STRONGER)
    return out


def calibrate(bundle: Bundle) -> dict[str, float]:
    """The design's ``calibration`` measured on its controller's probe runs in MuJoCo
    (:meth:`gaits.base.Controller.calibration_probes`; a skid-steer's effective track and
    turning load); empty when its controller needs none (no model is compiled then)."""
    from gaits import controller_for
    from gaits.base import DesignGeometry
    from synth.verification.runs import run_behavior

    if not controller_for(DesignGeometry.from_record(bundle.record)).calibration_probes():
        return {}
    model, controller = bundle.model(), bundle.controller()
    runs = []
    for name, params in controller.calibration_probes():
        traj, result = run_behavior(model, controller, name, params)
        runs.append((traj, result.series))
    return controller.calibrate(runs)


def verify(designer: Designer, req: Request, opts: StructureOptions, outcome: Outcome) -> Outcome:
    """``outcome`` (a sized design) simulated, repaired where it can be, and judged; a
    refusal also names the largest value of a parameter that designs and verifies
    (:func:`best_value`)."""
    params = designer.structural(req)
    missing = _no_controller(designer, outcome)
    if missing is not None:
        return replace(outcome, infeasible=missing)
    unserved = _unserved(designer, outcome)
    if unserved and not opts.allow_unverified:
        robot = outcome.design.chosen.robot_type if outcome.design.chosen else "the design"
        return replace(outcome, infeasible=unserved_message(robot, unserved))
    out = _verified(designer, params, opts, outcome)
    if unserved and out.verification is not None:
        accepted = tuple(sorted(unserved))
        out = replace(out, verification=replace(out.verification, accepted_unsimulated=accepted))
    if out.infeasible is None:
        return out
    hint = best_value(designer, params, opts, outcome)
    return out if hint is None else replace(out, infeasible=f"{out.infeasible}; {hint}")


def _no_controller(designer: Designer, outcome: Outcome) -> str | None:
    """Why the design's behaviours cannot be simulated (no controller serves its
    structure yet), or None: such a design is refused rather than claimed verified; with
    --no-verify it is sized and exported unverified."""
    from export.record import design_record
    from gaits import controller_for
    from gaits.base import DesignGeometry

    record = design_record(outcome.design, designer.short, outcome.structure)
    try:
        controller_for(DesignGeometry.from_record(record))
    except ValueError as e:
        return (
            f"{outcome.design.chosen.robot_type}: its abilities cannot be simulated: {e}; "
            "design it with --no-verify for the sized bundle, unverified"
        )
    return None


def served_abilities(record: Mapping, controller) -> dict[str, str | None]:
    """Each ability of the design ``record`` (its ``abilities`` and ``needed``) -> the
    ability whose simulated behaviour serves it (``gaits.base.serving`` over the record's
    ``ability_ancestors``): a behaviour of ``controller``, or a sensing loop that
    :mod:`program.sensing` simulates for it; None when nothing does."""
    from gaits.base import serving
    from program.sensing import simulated_abilities

    offered = {spec.realises for spec in controller.behaviors.values()}
    ancestors = record.get("ability_ancestors") or {}
    # the sensing loops: those of the simulated sensing abilities with no simulated ancestor
    sensed = set(simulated_abilities(record, controller.behaviors))
    offered |= {a for a in sensed if not sensed.intersection(ancestors.get(a, ()))}
    names = {*record.get("abilities", ()), *(record.get("needed") or ())}
    return {a: serving(a, ancestors, offered) for a in sorted(names)}


def demanded(record: Mapping) -> list[str]:
    """The abilities a design must be able to do, so each must be simulated: the request's
    ``needed`` ones (its abilities, the answers yes, and what the ontology's
    ``requiredAbility`` rules add, e.g. orienting for an oval object); an ability the
    chosen robot only has besides (a bonus) is not demanded."""
    return sorted(set(record.get("needed") or record.get("request", {}).get("abilities", ())))


def _unserved(designer: Designer, outcome: Outcome) -> dict[str, tuple[tuple[str, ...], list]]:
    """The demanded abilities of ``outcome`` (:func:`demanded`) that no behaviour serves ->
    (what would serve them: the ability and its ancestor abilities, the abilities that the
    design's behaviours serve)."""
    from export.record import design_record
    from gaits import controller_for
    from gaits.base import DesignGeometry

    record = design_record(outcome.design, designer.short, outcome.structure)
    controller = controller_for(DesignGeometry.from_record(record))
    served = served_abilities(record, controller)
    offered = sorted(
        {s for s in served.values() if s}
        | {spec.realises for spec in controller.behaviors.values()}
    )
    ancestors = record.get("ability_ancestors") or {}
    return {
        a: ((a, *ancestors.get(a, ())), offered) for a in demanded(record) if served.get(a) is None
    }


def unserved_message(robot: str, unserved: Mapping[str, tuple[tuple[str, ...], list]]) -> str:
    """Why the design of ``robot`` is refused: the demanded abilities no behaviour serves,
    each with what would serve it."""
    parts = []
    for a, (would, offered) in sorted(unserved.items()):
        kinds = (
            f", or for an ability it is a kind of ({', '.join(would[1:])})," if would[1:] else ""
        )
        parts.append(
            f"{a} is demanded but no behaviour serves it, so it cannot be simulated "
            f"({robot}'s behaviours are for {', '.join(offered) or 'nothing'}); "
            f"a behaviour for {a}{kinds} would serve it"
        )
    return "; ".join(parts) + (
        "; design with --allow-unverified to accept it unsimulated"
        if len(parts) == 1
        else "; design with --allow-unverified to accept them unsimulated"
    )


def best_value(
    designer: Designer, params: Mapping[str, float], opts: StructureOptions, outcome: Outcome
) -> str | None:
    """``"the largest payload that works here is 1.400 kg"``: the largest value of the
    first parameter in ``synth.structure.EASIER_WHEN_SMALLER`` (payload always; speed and
    slope where the request gives them) with which the design is sized and every
    behaviour verified, all else equal (``synth.structure.bisect_largest``; each test a
    full sizing and verification); None when none works even at its floor.

    At most ``HINT_ROUNDS`` sizings with verification in all: each takes one to a few
    seconds (every behaviour simulated, maybe resized); the floor's test and
    ``HINT_BISECTIONS`` halvings bound the value within 1/16 of the asked one. Each
    midpoint is rounded down to the decimals the hint shows, so the value named is one
    that was tested: it designs and verifies (the predicate need not be monotone: near a
    verdict's threshold it often is not). That is five tests for the parameter that is
    the limit and one for each parameter before it whose floor failed; out of rounds, a
    value counts as failing."""
    from synth.structure import (
        EASIER_WHEN_SMALLER,
        StructureDesigner,
        bisect_largest,
        rounded_down,
        shown_value,
    )

    budget = [HINT_ROUNDS]

    def sizer(values: Mapping[str, float]) -> StructureDesigner:
        return StructureDesigner(
            designer.kb,
            outcome.design.chosen,
            outcome.catalog,
            dict(values),
            opts.symmetric,
            opts.objective,
        )

    asked_values = sizer(params).values  # the parameters with the type's defaults

    for name, (*_, floor, always) in EASIER_WHEN_SMALLER.items():
        asked = asked_values.get(name)
        if not (always or name in params) or not asked or asked <= 0:
            continue

        def ok(x: float, name: str = name) -> bool:
            if budget[0] <= 0:
                return False  # out of rounds: not shown to work
            budget[0] -= 1
            values = {**params, name: x}
            try:
                structure = sizer(values).run()
            except InfeasibleError:
                return False
            trial = replace(outcome, structure=structure, calibration=None, bundle=None)
            return _verified(designer, values, opts, trial).infeasible is None

        low = floor * asked
        if not ok(low):
            continue
        # midpoints on the grid of the decimals shown: the value named is one that was tested
        snap = partial(rounded_down, name)
        best = bisect_largest(ok, low, asked, HINT_BISECTIONS, snap)
        if best == low:  # the floor: maybe off the grid, shown rounded down
            return f"the largest {name} that works here is {shown_value(name, best)}"
        unit, scale, digits, *_ = EASIER_WHEN_SMALLER[name]
        return f"the largest {name} that works here is {best * scale:.{digits}f} {unit}"
    return None


def _verified(
    designer: Designer, params: Mapping[str, float], opts: StructureOptions, outcome: Outcome
) -> Outcome:
    """The loop of the module docstring on ``outcome``, sized for ``params`` (SI)."""
    from gaits import controller_for
    from gaits.base import DesignGeometry
    from program.sensing import verify_sensing
    from synth.structure import StructureDesigner
    from synth.verification.hold import hold_blame, hold_note
    from synth.verification.robust import (
        less_play,
        play_blame,
        play_note,
        robust_bundle,
        robust_check,
        with_sensing,
    )
    from synth.verification.runs import UnplannedError, verify_nominal
    from synth.verification.source import Bundle
    from synth.verification.verdict import explain
    from synth.verification.wheels import wheel_exclusions, wheel_joints, wheel_note

    floors: dict[str, float] = {}
    excluded: dict[str, frozenset[str]] = {}  # joint -> models too loose (their play)
    first_model: dict[str, str] = {}  # joint -> its actuator before its play was answered
    blamed: list[
        dict
    ] = []  # the perturbed runs the play broke (synth.verification.robust.play_blame)
    history: list[dict] = []  # and those of every round, for the record
    blamed_at = 0  # the round (sizing) they were measured on
    torque_done = False  # a stronger actuator was asked for and none could be had
    stuck: list[str] = []  # joints the play broke that no model with less play serves
    play = None
    wheels_at: tuple[int, dict | None] = (
        0,
        None,
    )  # the stiffer wheels tried (synth.verification.wheels)
    first_wheel: dict[str, str] = {}  # wheel joint -> its servo before a stiffer one
    wheel_runs: list[dict] = []  # the perturbed runs that called for the stiffer wheels
    bundles: dict[int, Bundle] = {}  # the round's bundle as the user gets it (robust_bundle)

    def round_bundle() -> Bundle:
        """The perturbed runs' bundle of the design as it stands, built once a round."""
        if rounds not in bundles:
            bundles.clear()
            bundles[rounds] = robust_bundle(designer, outcome)
        return bundles[rounds]

    rounds = 0
    while True:
        rounds += 1
        files = outcome.files(designer)
        calibration = calibrate(Bundle(files))
        if calibration:
            outcome = replace(outcome, calibration=calibration)
            files = outcome.files(designer)
        record = outcome.record(designer)
        models = {j["name"]: j["actuator"] for j in record.get("joints", ())}
        # the behaviours' trajectories, then the sensing abilities' closed loops
        try:
            planned = verify_nominal(Bundle(files))
            sensed = [Run.of(r) for r in verify_sensing(files)]
        except UnplannedError as e:  # a bonus ability's plan: dropped, and this round again
            outcome = _drop_unplanned(designer, outcome, record, e)
            bundles.clear()
            rounds -= 1
            continue
        results = planned + sensed
        failing = [r for r in results if not r.ok]
        # nominally passed: under the perturbations of synth.verification.robust (--robustness K)
        robust = (
            None
            if failing or opts.robustness <= 0
            else robust_check(
                designer,
                outcome,
                opts.robustness,
                bundle=round_bundle(),
                nominal=planned,
                sensing=False,
                sensed=sensed,
            )
        )
        more = _floors(results + (robust.failing_runs() if robust else []), record)
        new = {j: f for j, f in more.items() if f > floors.get(j, 0.0)}
        grow = new if rounds < MAX_ROUNDS and not torque_done else {}
        stiffer: dict[str, frozenset[str]] = {}
        if (
            not (grow or failing)
            and robust is not None
            and robust.not_robust()
            and rounds < MAX_ROUNDS + PLAY_ROUNDS
            and wheel_joints(record, outcome.catalog)
        ):
            # no actuator saturated: does a stiffer wheel servo answer it? (measured)
            stiffer, wheels = wheel_exclusions(round_bundle(), robust, outcome.catalog, excluded)
            wheels_at = (rounds, wheels)
        if not (failing or (robust is not None and robust.not_robust())):
            break
        sizer = StructureDesigner(
            designer.kb,
            outcome.design.chosen,
            outcome.catalog,
            dict(params),
            opts.symmetric,
            opts.objective,
        )
        structure = None
        if grow or stiffer:
            floors |= grow
            sizer.torque_floor = dict(floors)
            sizer.excluded = dict(excluded) | stiffer
            try:
                structure = sizer.run()
                excluded |= stiffer
                if stiffer:  # synth.verification.wheels: what called for it
                    wheel_runs += wheels_at[1]["runs"]  # type: ignore[index]
                    for j in stiffer:
                        first_wheel.setdefault(j, models[j])
            except InfeasibleError:
                torque_done = True  # no stronger actuator: is it the play? (below)
        if structure is None and not failing and rounds < MAX_ROUNDS + PLAY_ROUNDS:
            # no stronger actuator answers it: does the joints' play break it? (measured)
            if play is None:
                from synth.verification.perturb import catalog_play

                play = catalog_play(outcome.catalog)
            runs = play_blame(round_bundle(), robust)
            blamed, blamed_at = runs, rounds
            history += runs
            looser, stuck = less_play(runs, models, sizer.assigner.serving, play, excluded)
            sizer.torque_floor = dict(floors)
            structure, trial = _size_with_less_play(sizer, looser, runs, excluded)
            for j in trial:
                first_model.setdefault(j, models[j])
            excluded |= trial
        if structure is None:
            break  # no stronger actuator, none with less play: the failure below stands
        outcome = replace(outcome, structure=structure, calibration=None)
    if robust is None and failing and opts.robustness > 0:
        # what failed nominally drops its bonus abilities or refuses the request (below);
        # what passed must pass under the perturbations too, or no perturbed run is claimed
        passed = {r.behavior for r in results if r.ok}
        robust = robust_check(
            designer,
            outcome,
            opts.robustness,
            passed,
            round_bundle(),
            [r for r in planned if r.behavior in passed],
            sensed=[r for r in sensed if r.behavior in passed],
        )
    # which abilities no behaviour serves: the controller alone tells (no model needed)
    controller = controller_for(DesignGeometry.from_record(record))
    served = served_abilities(record, controller)
    unsimulated = tuple(a for a in record.get("abilities", ()) if served.get(a) is None)
    needed = set(record.get("needed") or record.get("abilities", ()))
    if robust is not None and not failing:
        # the sensing loops under the perturbations: once, on the design as it stands (a
        # repair answers the plans' runs; a loop's run has no saturated joint to feed
        # it), unless a plan's perturbed runs refuse the design already
        refused = any(
            ({b.ability} | {x for x, s in served.items() if s == b.ability}) & needed
            for b in robust.not_robust()
        )
        loops = [r.behavior for r in sensed if r.ok]
        if loops and not refused:
            more = robust_check(
                designer,
                outcome,
                opts.robustness,
                set(loops),
                round_bundle(),
                table=robust.table,
            )
            robust = with_sensing(robust, more)
    # a behaviour fails the request when it serves a demanded ability (walking serves a
    # demanded heavy-walking); else the abilities it serves are dropped
    dropped: dict[str, str] = {}
    failure = None
    for r in failing:
        mine = {r.ability} | {a for a, s in served.items() if s == r.ability}
        through = sorted(mine & needed) if r.ability not in needed else []
        serving = f" (serving {', '.join(through)})" if through else ""  # which demand
        why = f"{r.behavior}{serving} failed in simulation: {explain(r.figures, r.verdict)}"
        if mine & needed:
            failure = failure or why
        else:
            for a in sorted(mine):
                dropped.setdefault(a, why)
    also = []  # the other demanded behaviours that are not robust, named after the worst
    nominal_failure = failure is not None
    bad = robust.not_robust() if robust is not None else []
    held = hold_blame(round_bundle(), robust) if bad else []
    for b in bad:
        ability, behavior = b.ability, b.behavior
        why = b.why_not(robust.required)  # type: ignore[union-attr]
        if blamed_at == rounds:  # measured on the design as it stands
            why += play_note(blamed, behavior, stuck, play or {}, models)
        if wheels_at[0] == rounds:
            why += wheel_note(wheels_at[1], behavior)
        why += hold_note(held, behavior)
        mine = {ability} | {a for a, s in served.items() if s == ability}
        if mine & needed:
            if failure is None:
                failure = why
            else:
                also.append(f"{behavior} (passed {b.passed} of {b.runs})")
        else:
            for a in sorted(mine):
                dropped.setdefault(a, why)
    if also:
        failure += f"; also not robust: {', '.join(also)}"
    skipped = robust_skipped(sensed, robust)
    if skipped and failure is None:  # (a bug, never a design's fault: said, not passed)
        failure = (
            f"{', '.join(skipped)} passed on the nominal model but did not run under the "
            "perturbations: every behaviour the design lists must"
        )
    if failure is not None and not nominal_failure:  # it passed on the nominal model
        failure += f"; {ROBUST_OFF}"
    v = Verification(
        tuple(results),
        rounds,
        {j: floors[j] for j in sorted(floors)},
        dropped,
        unsimulated,
        failure,
        robust=robust,
        play=_play_record(first_model, models, play or {}, history) if history else None,
        wheels={
            "swapped": {
                j: {"from": m, "to": models.get(j)} for j, m in sorted(first_wheel.items())
            },
            "runs": wheel_runs,
        }
        if first_wheel
        else None,
    )
    out = replace(outcome, verification=v, bundle=files)
    if failure is not None:
        return replace(out, infeasible=failure)
    return out


def _drop_unplanned(designer: Designer, outcome: Outcome, record: Mapping, e) -> Outcome:
    """``outcome`` without the bonus abilities that the behaviour of ``e`` (an
    ``synth.verification.runs.UnplannedError``: it cannot be planned on the simulated robot) serves,
    with a note; ``e`` itself when it serves a demanded ability (the request is refused)."""
    from gaits import controller_for
    from gaits.base import DesignGeometry

    served = served_abilities(record, controller_for(DesignGeometry.from_record(record)))
    needed = set(record.get("needed") or record.get("abilities", ()))
    mine = {e.ability} | {a for a, s in served.items() if s == e.ability}
    if mine & needed:
        raise e
    d, c = outcome.design, outcome.design.chosen
    why = f"its behaviour {e.behavior} cannot be planned with its default parameters ({e.why})"
    keep = tuple(a for a in c.abilities if designer.short(a) not in mine)
    notes = "; ".join(f"dropped the bonus ability {a}: {why}" for a in sorted(mine))
    d = replace(
        d, chosen=replace(c, abilities=keep), note=f"{d.note}; {notes}" if d.note else notes
    )
    return replace(
        outcome,
        design=d,
        unplanned=(*outcome.unplanned, *((a, why) for a in sorted(mine))),
        calibration=None,
    )


def robust_skipped(results: list[Run], robust: RobustRuns | None) -> list[str]:
    """The behaviours of ``results`` (nominal runs: :func:`_verified` gives it the sensing
    loops', which run by another path than the plans, :class:`program.session.Session`)
    that passed but that the perturbed runs ``robust`` do not list (:func:`synth.verification.runs.
    robust_missing`); none when no perturbed run was made."""
    from synth.verification.runs import robust_missing

    verified = {
        "behaviors": [r.to_dict() for r in results],
        "robust": None if robust is None else robust.to_dict(),
    }
    return robust_missing({"verified": verified})


def _size_with_less_play(
    sizer, looser: Mapping[str, frozenset[str]], blamed: list[dict], excluded: Mapping
) -> tuple[object | None, dict[str, frozenset[str]]]:
    """The structure ``sizer`` gives with the looser models of the joints the play broke
    (``looser``, :func:`synth.verification.robust.less_play`) excluded: all of them at once; when no
    assignment holds them all, one joint at a time, the one blamed in most runs first.
    (The structure, None when none sizes; the exclusions it was sized with.)"""
    blame = {j: sum(j in r["joints"] for r in blamed) for j in looser}
    tries = [dict(looser)] if looser else []
    if len(looser) > 1:
        tries += [{j: looser[j]} for j in sorted(looser, key=lambda j: (-blame[j], j))]
    for trial in tries:
        sizer.excluded = {**excluded, **trial}
        try:
            return sizer.run(), trial
        except InfeasibleError:
            continue
    return None, {}


def _play_record(
    first: Mapping[str, str],
    models: Mapping[str, str],
    play: Mapping[str, float],
    blamed: list[dict],
) -> dict:
    """``verified.play``: each joint whose servo was swapped for one of less play (from,
    to, their largest play in deg) and the perturbed runs the play broke (behaviour, seed,
    failed criteria, the joints whose play broke it, the figures with and without play)."""
    import math

    def deg(m: str) -> float:
        return round(math.degrees(play.get(m, 0.0)), 4)

    return {
        "swapped": {
            j: {"from": m, "to": models.get(j), "play_deg": [deg(m), deg(models.get(j, ""))]}
            for j, m in sorted(first.items())
        },
        "blamed": blamed,
    }
