"""Closing the loop: a sized design's behaviours simulated, and failures fed back
(:class:`Strengthening`, a round at a time).

After the structure generator, every behaviour the design will list (its abilities'
behaviours, default parameters) runs in MuJoCo on the bundle's own model
(:mod:`synth.verification.runs`) and is judged on its outcome
(:mod:`synth.verification.verdict`). A behaviour that failed because an actuator sat at
its torque limit feeds back: every joint that saturated must get an actuator stronger than
the one it had (a torque floor for the structure generator, which sizes again, links
included), then everything is simulated again, up to ``MAX_ROUNDS`` sizings. What still
fails then:

- a behaviour of an ability the request demands (``needed``) fails the request: the
  design is infeasible, naming the behaviour, the criterion and the figure;
- a behaviour of an ability the design only has as a bonus drops that ability from the
  design's ``abilities``, with a note.

Under ``--robustness K`` the behaviours that passed run under K perturbations too
(:mod:`synth.verification.robust`): a perturbed run with an actuator at its limit feeds
the same torque floors. One with none at its limit is put to the causes of
:mod:`synth.verification.causes`, each measured by replays of the failed runs with its
part of the perturbation changed, in this order:

- on a robot with wheels, the wheels' servos (:class:`synth.verification.wheels.Wheels`):
  the first stiffer servo with which the runs pass is the answer, the wheels may have no
  less stiff servo in the next sizing;
- when no stronger actuator answers it, the joints' play
  (:class:`synth.verification.play.Play`): the joints whose play breaks it may have no
  servo with as much play (a new sizing; the servo with less play must still hold the
  joint's torque), up to ``PLAY_ROUNDS`` sizings more; ``verified.play`` names each swap
  and the runs that called for it;
- when no sizing answers it, a closed loop's gains (:class:`synth.verification.gains.
  Gains`), then the servos' command hold (:class:`synth.verification.hold.Hold`): a slower
  pace of the behaviours it breaks, where the request left the speed to the design; each
  verified on every perturbed run before it is kept (a round without a new sizing).

A refusal names what each cause measured and tried on the design as it stands.

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

Feedback other than stronger actuators and the causes' answers (a larger wheel, a slower
or lower gait, more modules lifting) is each family's sizing rule, not this loop's: no
failure class was found that such a remedy fixes (measured on 96 requests off the shipped
study's grid and on its 51 wheeled ones: none refused by simulation once a skid-steer is
calibrated; the failures left, a snake's bonus ``rolling`` with 0.3-0.5 kg on its
strongest servos, which no rolling frequency fixes either, and a skid-steer under 0.5 kg
drifting while it turns in place, worse when slower, have no remedy in that list), so
there is no remedy table.

The record keeps each behaviour's figures (``verified``). This package runs the
simulator, so it imports ``export`` and ``gaits`` (lazily): it is where ``synth`` looks
downstream, because the pipeline's last step is to check what it built.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

from adron.errors import InfeasibleError
from export.record import design_record
from gaits import controller_for
from gaits.base import DesignGeometry, serving
from program.sensing import simulated_abilities, verify_sensing
from synth.params import lowest
from synth.sizing.structure import (
    EASIER_WHEN_SMALLER,
    StructureDesigner,
    bisect_largest,
    rounded_down,
    shown_value,
)
from synth.verification.results import RobustRuns, Run

if TYPE_CHECKING:
    from synth.pipeline import Outcome, StructureOptions
    from synth.reasoning.conceptual import Designer, Request
    from synth.verification.causes import Round
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
#: with servos of less play (``synth.verification.play.less_play``).
PLAY_ROUNDS = 2
#: What :meth:`Strengthening.answer` gives for a probed round that no stronger actuator
#: answers: the round is made again, every perturbed run made.
_WHOLE = object()
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


def _at_least(floors: Mapping[str, float], unmet: Mapping[str, float]) -> bool:
    """Whether ``floors`` ask at least what ``unmet`` (floors no sizing met) asks of every
    joint: then no sizing meets them either (a higher floor leaves fewer actuators)."""
    return bool(unmet) and all(floors.get(j, 0.0) >= f for j, f in unmet.items())


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
    out = Strengthening(designer, params, opts, outcome).run()
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


def structure_designer(
    designer: Designer, outcome: Outcome, params: Mapping[str, float], opts: StructureOptions
):
    """The structure generator (``synth.sizing.structure.StructureDesigner``) of
    ``outcome``'s chosen type and catalog, for the parameters ``params``."""

    c = outcome.design.chosen
    return StructureDesigner(
        designer.kb, c, outcome.catalog, dict(params), opts.symmetric, opts.objective
    )


def best_value(
    designer: Designer, params: Mapping[str, float], opts: StructureOptions, outcome: Outcome
) -> str | None:
    """``"the largest payload that works here is 1.400 kg"``: the largest value of the
    first parameter in ``synth.sizing.structure.EASIER_WHEN_SMALLER`` (payload always; speed and
    slope where the request gives them) with which the design is sized and every
    behaviour verified, all else equal (``synth.sizing.structure.bisect_largest``; each test a
    full sizing and verification); None when none works even at its floor.

    At most ``HINT_ROUNDS`` sizings with verification in all: each takes one to a few
    seconds (every behaviour simulated, maybe resized); the floor's test and
    ``HINT_BISECTIONS`` halvings bound the value within 1/16 of the asked one. Each
    midpoint is rounded down to the decimals the hint shows, so the value named is one
    that was tested: it designs and verifies (the predicate need not be monotone: near a
    verdict's threshold it often is not). That is five tests for the parameter that is
    the limit and one for each parameter before it whose floor failed; out of rounds, a
    value counts as failing."""

    budget = [HINT_ROUNDS]
    sizer = partial(structure_designer, designer, outcome, opts=opts)

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
            return Strengthening(designer, values, opts, trial).run().infeasible is None

        low = lowest(name, floor * asked)
        if low > asked or not ok(low):
            continue
        # midpoints on the grid of the decimals shown: the value named is one that was tested
        snap = partial(rounded_down, name)
        best = bisect_largest(ok, low, asked, HINT_BISECTIONS, snap)
        if best == low:  # the floor: maybe off the grid, shown rounded down
            return f"the largest {name} that works here is {shown_value(name, best)}"
        unit, scale, digits, *_ = EASIER_WHEN_SMALLER[name]
        return f"the largest {name} that works here is {best * scale:.{digits}f} {unit}"
    return None


@dataclass(frozen=True)
class Simulated:
    """One round's simulation of the design as it stands: its bundle's files and record,
    each joint's actuator, the nominal runs (the plans' and the sensing loops'), those
    that failed, and the perturbed runs (None when not run: a nominal failure, or K = 0)."""

    files: dict
    record: dict
    models: dict[str, str]
    planned: list[Run]
    sensed: list[Run]
    failing: list[Run]
    robust: RobustRuns | None

    @property
    def results(self) -> list[Run]:
        return self.planned + self.sensed

    def not_robust(self) -> list:
        return self.robust.not_robust() if self.robust is not None else []


class Strengthening:
    """The loop of the module docstring on ``outcome``, sized for ``params`` (SI): each
    round simulates the design as it stands (:meth:`simulate`), answers what failed
    (:meth:`answer`: a stronger actuator for each joint that saturated, then the causes of
    :mod:`synth.verification.causes` in turn) and sizes it again, until everything passes
    or nothing answers what fails; :meth:`judge` then gives the outcome."""

    def __init__(
        self,
        designer: Designer,
        params: Mapping[str, float],
        opts: StructureOptions,
        outcome: Outcome,
    ) -> None:
        from synth.verification.gains import Gains
        from synth.verification.hold import Hold
        from synth.verification.play import Play
        from synth.verification.wheels import Wheels

        self.designer, self.params, self.opts, self.outcome = designer, params, opts, outcome
        self.rounds = 0  # rounds of simulation
        self.regains = 0  # of them, rounds that verified other gains or paces (no sizing)
        #: of them, rounds whose perturbed runs stopped at a saturated worst-looking run
        #: (:meth:`simulate`'s probe): they do not count against ``MAX_ROUNDS``
        self.probes = 0
        self.probing = True  # a round may probe (off to make a probed round again whole)
        #: torque floors a probe's sizing found no actuators for (floors asking at least
        #: as much fail too: the sizing is not tried again)
        self.unmet: dict[str, float] = {}
        #: a probed round to make again whole (:meth:`simulate` keeps its nominal runs)
        self._again: Simulated | None = None
        self.floors: dict[str, float] = {}  # joint -> the torque it must be sized for
        self.excluded: dict[str, frozenset[str]] = {}  # joint -> models it may not have
        self.torque_done = False  # a stronger actuator was asked for and none could be had
        self.wheels, self.play, self.gains = Wheels(), Play(), Gains()
        self.hold = Hold(given=params)
        self._bundle: tuple[int, Bundle] | None = None
        self._made: Mapping = {}  # the last round's perturbed runs (verify_robust's made)

    @property
    def sizings(self) -> int:
        """The sizings so far (the rounds less those that only changed gains or paces)."""
        return self.rounds - self.regains

    @property
    def counted(self) -> int:
        """The sizings that count against ``MAX_ROUNDS`` (and ``PLAY_ROUNDS``): those that
        followed a round whose every perturbed run was made (a probed round's stronger
        actuator is a sizing too, but costs a few runs)."""
        return self.sizings - self.probes

    def bundle(self) -> Bundle:
        """The perturbed runs' bundle of the design as it stands (as the user gets it),
        built once a round."""
        from synth.verification.robust import robust_bundle

        if self._bundle is None or self._bundle[0] != self.rounds:
            self._bundle = (self.rounds, robust_bundle(self.designer, self.outcome))
        return self._bundle[1]

    def run(self) -> Outcome:
        while True:
            self.rounds += 1
            now = self.simulate()
            if now is None:  # a bonus ability's plan was dropped: this round again
                self.rounds -= 1
                self._bundle = None
                continue
            structure = self.answer(now)
            if structure is _WHOLE:  # a probe no stronger actuator answers: every run
                self.rounds -= 1
                self.probing = False
                self._again = now  # (its nominal runs and table kept: the same design)
                continue
            if self._probed(now):
                self.probes += 1
            if structure is None:
                break  # everything passed, or nothing answers what fails
            if structure is self.outcome.structure:  # other gains or paces, the same structure
                continue
            self.outcome = replace(self.outcome, structure=structure, calibration=None)
        return self.judge(now)

    def simulate(self) -> Simulated | None:
        """The round's runs: the calibration probes where the controller has them, the
        behaviours' plans and the sensing loops nominally, and, when they all passed, the
        plans under the perturbations; None when a bonus ability's behaviour cannot be
        planned (it is dropped: :func:`_drop_unplanned`)."""
        from synth.verification.robust import robust_check
        from synth.verification.runs import UnplannedError, verify_nominal
        from synth.verification.source import Bundle

        designer = self.designer
        again, self._again = self._again, None
        if again is not None and again.robust is not None:
            # a probed round again, every perturbed run made: the same design, its nominal
            # runs, calibration, table and physics as they were
            robust = robust_check(
                designer,
                self.outcome,
                self.opts.robustness,
                bundle=self.bundle(),
                nominal=again.planned,
                sensing=False,
                sensed=again.sensed,
                decisive=self._decisive(again.record, again.results),
                table=again.robust.table,
                checked=again.robust.physics,
                made=again.robust.made,  # (the runs the probe made: not made again)
            )
            return replace(again, robust=robust)
        files = self.outcome.files(designer)
        calibration = calibrate(Bundle(files))
        if calibration:
            self.outcome = replace(self.outcome, calibration=calibration)
            files = self.outcome.files(designer)
        record = self.outcome.record(designer)
        models = {j["name"]: j["actuator"] for j in record.get("joints", ())}
        # the behaviours' trajectories, then the sensing abilities' closed loops
        try:
            planned = verify_nominal(Bundle(files))
            sensed = [Run.of(r) for r in verify_sensing(files)]
        except UnplannedError as e:
            self.outcome = _drop_unplanned(designer, self.outcome, record, e)
            return None
        failing = [r for r in planned + sensed if not r.ok]
        k = self.opts.robustness
        decisive = None if failing or k <= 0 else self._decisive(record, planned + sensed)
        # nominally passed: under the perturbations (robust.py, --robustness K)
        robust = (
            None
            if failing or k <= 0
            else robust_check(
                designer,
                self.outcome,
                k,
                bundle=self.bundle(),
                nominal=planned,
                sensing=False,
                sensed=sensed,
                decisive=decisive,
                probe=decisive is None and self._may_probe(),
                repair=decisive is None and self.probing,
                made=self._made,  # (the same robot and plans after other gains or paces)
                certify=self.opts.certify,
            )
        )
        self._made = robust.made if robust is not None else {}
        return Simulated(files, record, models, planned, sensed, failing, robust)

    def _may_probe(self) -> bool:
        """Whether this round's perturbed runs may stop at the first worst-looking run that
        saturates (``verify_robust``'s ``probe``): a stronger actuator may still be sized
        (the sizings left, none refused yet) and fewer than ``MAX_ROUNDS`` rounds probed."""
        return (
            self.probing
            and self.counted < MAX_ROUNDS
            and not self.torque_done
            and self.probes < MAX_ROUNDS
        )

    @staticmethod
    def _repaired(now: Simulated) -> bool:
        """Whether round ``now``'s perturbed runs stopped at the first batch in which one
        failed (``verify_robust``'s ``repair``): what failed there is answered, and when
        nothing answers it the round is made again whole."""
        stopped = now.robust.stopped if now.robust is not None else None
        return bool(stopped and stopped.get("repair"))

    @staticmethod
    def _probed(now: Simulated) -> bool:
        """Whether round ``now``'s perturbed runs stopped at a saturated probe."""
        stopped = now.robust.stopped if now.robust is not None else None
        return bool(stopped and stopped.get("probe"))

    def _round(self, now: Simulated) -> Round:
        from synth.verification.causes import Round

        return Round(
            self.rounds,
            now.record,
            now.models,
            self.outcome.catalog,
            now.robust,
            self.bundle,
            dict(self.excluded),
            gains=dict(self.outcome.feedback_gains or {}),
            demanded=self._demanded(now),
            paces=dict(self.outcome.paces or {}),
        )

    def _demanded(self, now: Simulated) -> frozenset[str]:
        """The behaviours of round ``now`` that serve a demanded ability."""
        return _demanded(now.record, now.results)

    def _decisive(self, record: dict, results: list[Run]) -> frozenset[str] | None:
        """When no repair can follow this round's perturbed runs (the sizings the loop may
        make are made, and no closed loop serving a demand has gains left to try): the
        behaviours whose failure refuses the design (their runs may then stop at the
        first that fails; the command hold's pace is measured on those that failed);
        None while a repair may follow."""
        if self.counted < MAX_ROUNDS + PLAY_ROUNDS:
            return None
        demanded = _demanded(record, results)
        controller = self.bundle().controller()
        for name in demanded - self.gains.done:
            if name in controller.behaviors and controller.run(name).info.get("feedback"):
                return None
        return demanded

    def answer(self, now: Simulated):
        """The structure sized again to answer what failed in round ``now``; None when
        everything passed or nothing answers it. A joint that saturated (nominally or in a
        perturbed run) must get a stronger actuator (up to ``MAX_ROUNDS`` sizings); a
        perturbed failure with none saturated is put to the wheels (a robot with wheels),
        then, when no stronger actuator answers it, to the play (up to ``PLAY_ROUNDS``
        sizings more), then, when no sizing answers it, to a closed loop's gains, then to
        the command hold's slower pace (the same structure returned: the outcome has the
        gains or the paces)."""

        if self._probed(now):
            # the worst-looking runs saturated: a stronger actuator for what saturated, or
            # (none to be had) this round again with every run made
            return self._stronger(now) or _WHOLE
        if not (now.failing or now.not_robust()):
            return None
        structure = self._answered(now)
        # stopped at the first failed runs and nothing answers them: every run made, for
        # the verdict (and the causes' answers to every failure)
        return _WHOLE if structure is None and self._repaired(now) else structure

    def _answered(self, now: Simulated):
        """:meth:`answer` of a round in which something failed."""
        sizer = self._sizer()
        new = self._new_floors(now)
        grow = new if self.counted < MAX_ROUNDS and not self.torque_done else {}
        state = self._round(now)
        causes_left = self.counted < MAX_ROUNDS + PLAY_ROUNDS
        stiffer: Mapping[str, frozenset[str]] = {}
        wheels = not (grow or now.failing) and now.not_robust() and causes_left
        if wheels and self.wheels.applies(state):  # none saturated: a stiffer wheel servo?
            remedy = self.wheels.explains(state)
            stiffer = remedy.sizings[0] if remedy else {}
        state.sizer = sizer
        structure = None
        if grow or stiffer:
            floors = self.floors | grow
            sizer.torque_floor = dict(floors)
            sizer.excluded = dict(self.excluded) | dict(stiffer)
            try:
                if not stiffer and _at_least(floors, self.unmet):
                    # a probe's floors found no actuator and these ask as much or more
                    raise InfeasibleError("no stronger actuator (as the probe found)")
                structure = sizer.run()
                self.floors = floors  # (floors no sizing met are not kept: the play's
                # trials below are sized without them, and the record names only floors met)
                self.excluded |= stiffer
                if stiffer:
                    self.wheels.taken(state, stiffer)
            except InfeasibleError:
                self.torque_done = True  # no stronger actuator: is it the play? (below)
        if structure is None and not now.failing and causes_left:
            # no stronger actuator answers it: does the joints' play break it? (measured)
            state.excluded = dict(self.excluded)
            remedy = self.play.explains(state)
            sizer.torque_floor = dict(self.floors)
            for trial in remedy.sizings if remedy else ():
                sizer.excluded = {**self.excluded, **trial}
                try:
                    structure = sizer.run()
                except InfeasibleError:
                    continue
                self.play.taken(state, trial)
                self.excluded |= trial
                break
        if structure is None and not now.failing:
            # no sizing answers it: do other gains of a closed loop? (measured)
            # then a slower pace, where the command hold breaks it (measured)
            for cause, field in ((self.gains, "gains"), (self.hold, "paces")):
                remedy = cause.explains(state)
                values = getattr(remedy, field) if remedy else None
                if values:
                    cause.chose(values)
                    key = "feedback_gains" if field == "gains" else field
                    self.outcome = replace(self.outcome, **{key: dict(values)})
                    self.regains += 1
                    return self.outcome.structure
        return structure

    def _sizer(self):
        """The structure generator of the design's type, sized for the request's
        parameters (its torque floors and exclusions set by the caller)."""
        return structure_designer(self.designer, self.outcome, self.params, self.opts)

    def _new_floors(self, now: Simulated) -> dict[str, float]:
        """Joint -> torque floor for each joint that saturated in round ``now`` (nominally
        or in a failing perturbed run) beyond the floor it has."""
        more = _floors(now.results + (now.robust.failing_runs() if now.robust else []), now.record)
        return {j: f for j, f in more.items() if f > self.floors.get(j, 0.0)}

    def _stronger(self, now: Simulated):
        """The structure sized again with a stronger actuator for every joint that
        saturated in round ``now`` (nominally or in its perturbed runs); None when none
        is stronger than it has or the catalog has none (the loop's state unchanged)."""
        new = self._new_floors(now)
        if not new:
            return None
        sizer = self._sizer()
        sizer.excluded = dict(self.excluded)
        sizer.torque_floor = dict(self.floors | new)
        try:
            structure = sizer.run()
        except InfeasibleError:
            # none to be had: the loop's state as before the probe, the round made again
            # whole (its answer then sees every saturated joint, as without the probe;
            # floors asking as much as these are known to fail: ``unmet``)
            self.unmet = dict(self.floors | new)
            return None
        self.floors |= new
        return structure

    def judge(self, now: Simulated) -> Outcome:
        """The outcome of the last round ``now``: what failed nominally drops a bonus
        ability or refuses the request, as does a behaviour not robust under the
        perturbations (its refusal names what each cause measured and tried)."""
        from synth.verification.robust import robust_check, with_sensing
        from synth.verification.verdict import explain

        designer, opts, outcome = self.designer, self.opts, self.outcome
        record, results, failing, robust = now.record, now.results, now.failing, now.robust
        sensed = now.sensed
        if robust is None and failing and opts.robustness > 0:
            # what failed nominally drops its bonus abilities or refuses the request (below);
            # what passed must pass under the perturbations too, or no perturbed run is claimed
            passed = {r.behavior for r in results if r.ok}
            # a demanded behaviour failed: the request is refused whatever these runs give,
            # so they stop at the first that fails (the worst-looking first)
            refused = bool(_demanded(record, failing))
            robust = robust_check(
                designer,
                outcome,
                opts.robustness,
                passed,
                self.bundle(),
                [r for r in now.planned if r.behavior in passed],
                sensed=[r for r in sensed if r.behavior in passed],
                decisive=passed if refused else None,
                certify=opts.certify,
            )
        # which abilities no behaviour serves: the controller alone tells (no model needed)
        controller = controller_for(DesignGeometry.from_record(record))
        served = served_abilities(record, controller)
        unsimulated = tuple(a for a in record.get("abilities", ()) if served.get(a) is None)
        needed = set(record.get("needed") or record.get("abilities", ()))

        def serves(ability: str) -> set[str]:
            return {ability} | {a for a, s in served.items() if s == ability}

        if robust is not None and not failing:
            # the sensing loops under the perturbations: once, on the design as it stands (a
            # repair answers the plans' runs; a loop's run has no saturated joint to feed
            # it), unless a plan's perturbed runs refuse the design already
            refused = any(serves(b.ability) & needed for b in robust.not_robust())
            loops = [r.behavior for r in sensed if r.ok]
            if loops and not refused:
                more = robust_check(
                    designer,
                    outcome,
                    opts.robustness,
                    set(loops),
                    self.bundle(),
                    table=robust.table,
                )
                robust = with_sensing(robust, more)
        # a behaviour fails the request when it serves a demanded ability (walking serves a
        # demanded heavy-walking); else the abilities it serves are dropped
        dropped: dict[str, str] = {}
        failure = None
        for r in failing:
            mine = serves(r.ability)  # type: ignore[arg-type]
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
        if bad:  # the command hold: measured on the design as it stands, for the refusal
            self.hold.measure(replace(self._round(now), robust=robust))
        for b in bad:
            why = b.why_not(robust.required, robust.k)  # type: ignore[union-attr]
            for cause in (self.play, self.wheels, self.gains, self.hold):
                why += cause.note(b.behavior, self.rounds)
            if serves(b.ability) & needed:
                if failure is None:
                    failure = why
                else:
                    made = (
                        f"{b.runs} made before it could not pass, of {robust.k}"  # type: ignore[union-attr]
                        if b.runs < robust.k  # type: ignore[union-attr]
                        else f"{b.runs}"
                    )
                    also.append(f"{b.behavior} (passed {b.passed} of {made})")
            else:
                for a in sorted(serves(b.ability)):
                    dropped.setdefault(a, why)
        if also:
            failure += f"; also not robust: {', '.join(also)}"  # type: ignore[operator]
        skipped = robust_skipped(sensed, robust)
        if skipped and failure is None:  # (a bug, never a design's fault: said, not passed)
            failure = (
                f"{', '.join(skipped)} passed on the nominal model but did not run under the "
                "perturbations: every behaviour the design lists must"
            )
        if failure is not None and not nominal_failure:  # it passed on the nominal model
            failure += f"; {ROBUST_OFF}"
        if robust is not None and dropped:  # what the runs show of the behaviours it keeps
            from synth.verification.robust import shows

            kept = tuple(b for b in robust.behaviors if not serves(b.ability) & set(dropped))
            robust = replace(robust, shows=shows(replace(robust, behaviors=kept)))
        gains, paces = self.gains.record(), self.hold.record()
        if robust is not None and gains is not None:  # what was tried, in verified.robust
            robust = replace(robust, gains=gains)
        if robust is not None and paces is not None:
            robust = replace(robust, paces=paces)
        v = Verification(
            tuple(results),
            self.sizings,
            {j: self.floors[j] for j in sorted(self.floors)},
            dropped,
            unsimulated,
            failure,
            robust=robust,
            play=self.play.record(now.models),
            wheels=self.wheels.record(now.models),
        )
        out = replace(outcome, verification=v, bundle=now.files)
        if failure is not None:
            return replace(out, infeasible=failure)
        return out


def _demanded(record: Mapping, results: list[Run]) -> frozenset[str]:
    """The behaviours of ``results`` that serve a demanded ability of the design in
    ``record`` (:func:`served_abilities`)."""
    served = served_abilities(record, controller_for(DesignGeometry.from_record(record)))
    needed = set(record.get("needed") or record.get("abilities", ()))
    out = set()
    for r in results:
        if r.ability is None:
            continue
        if ({r.ability} | {a for a, s in served.items() if s == r.ability}) & needed:
            out.add(r.behavior)
    return frozenset(out)


def _drop_unplanned(designer: Designer, outcome: Outcome, record: Mapping, e) -> Outcome:
    """``outcome`` without the bonus abilities that the behaviour of ``e`` (an
    ``synth.verification.runs.UnplannedError``: it cannot be planned on the simulated robot) serves,
    with a note; ``e`` itself when it serves a demanded ability (the request is refused)."""
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
    """The behaviours of ``results`` (nominal runs: :meth:`Strengthening.judge` gives it
    the sensing loops', which run by another path than the plans, :class:`program.session.
    Session`) that passed but that the perturbed runs ``robust`` do not list
    (:func:`synth.verification.runs.robust_missing`); none when no perturbed run was made."""
    from synth.verification.runs import robust_missing

    verified = {
        "behaviors": [r.to_dict() for r in results],
        "robust": None if robust is None else robust.to_dict(),
    }
    return robust_missing({"verified": verified})
