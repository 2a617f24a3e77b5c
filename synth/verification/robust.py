"""Robust verification in the design loop: a sized design's behaviours run under K seeded
perturbations (:mod:`synth.verification.perturb`, :func:`synth.verification.runs.
verify_robust`) once they pass on the nominal model, and judged by the acceptance rule:
every behaviour passes in at least ``share`` x K of its runs
(``synth/verification/perturb.toml``, ``[acceptance]``).

:mod:`synth.verification.loop` calls :func:`robust_check` where it judges the nominal
results: a perturbed run that failed with an actuator at its limit feeds the same loop as
a nominal one (each saturated joint gets a stronger actuator, the design is sized again);
the other failures are put to the causes (:mod:`synth.verification.causes`), which
replay the worst failed runs (:func:`worst_failures`, :func:`replayed_blame`) with one
cause taken away. A behaviour still not robust then fails a demanded ability (the request
is refused naming the behaviour, the perturbation that broke it and its figures against
the thresholds) or drops a bonus one. :func:`shows` states what K of K shows.

The runs use the bundle as the user gets it (robot.xml without the payload, which
design.json places as ``parmor simulate`` does), so that ``parmor simulate DIR --perturb
SEED`` replays each recorded run to the bit.
"""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import synth.verification.runs
from export.bundle import bundle_files
from program.sensing import verify_sensing
from synth.verification.perturb import default_k, design_table
from synth.verification.results import RobustRuns, Run, required_passes
from synth.verification.runs import agreement, coarse_xml, physics_check
from synth.verification.source import Bundle

if TYPE_CHECKING:
    from synth.pipeline import Outcome
    from synth.reasoning.conceptual import Designer


def robust_check(
    designer: Designer,
    outcome: Outcome,
    k: int,
    only: Collection[str] | None = None,
    bundle: Bundle | None = None,
    nominal: Sequence[Run] | None = None,
    sensing: bool = True,
    sensed: Sequence[Run] | None = None,
    table: Mapping | None = None,
    decisive: Collection[str] | None = None,
    probe: bool = False,
    repair: bool = False,
    checked: Mapping | None = None,
    made: Mapping | None = None,
    certify: bool = False,
) -> RobustRuns | None:
    """``verified.robust`` of ``outcome`` (a sized design) under perturbations 1..``k`` of
    its table (of its listed behaviours, those named in ``only`` when given; its sensing
    loops unless ``sensing`` is false); None when ``k`` is 0. ``bundle``: its
    :func:`robust_bundle` when the caller has it already; ``nominal``, ``sensed``: its
    nominal runs (``verify_nominal``, ``verify_sensing``) when the caller has them. The
    runs use the coarse time step where the nominal runs, sensing loops included, agree
    at it (:func:`physics`; ``table["timestep_s"]``, recorded with the table, so a replay
    uses it too); ``verified.robust.physics`` says which and why. ``table``: a table
    already chosen (the sensing loops' runs after the plans', a probed round made again),
    with ``checked``, the physics chosen with it (None: not said again). ``decisive``: the
    behaviours whose failure refuses the design when no repair can follow: the runs stop
    once one of them cannot pass; ``probe``: they stop at the worst-looking run of each
    plan when one of those saturates, ``repair``: at the first batch of runs in which one
    fails (:func:`synth.verification.runs.verify_robust`); ``made``: runs made before, taken
    where they are the same runs. ``certify`` (``--certify``): the K runs are a
    certification, and a behaviour passes when its runs show what the default K runs show
    (:func:`certified_share`, the table's ``share``)."""
    if k <= 0 or outcome.structure is None or outcome.catalog is None:
        return None

    bundle = robust_bundle(designer, outcome) if bundle is None else bundle
    if table is None:
        table = design_table(bundle.record, bundle.xml, outcome.catalog)
        if certify:
            table["share"] = certified_share(k, float(table["share"]), default_k(outcome.catalog))
        # the coarse step where this design's nominal runs agree with the fine ones
        checked = physics(bundle, nominal, sensed)
        if checked["timestep_s"]:
            table["timestep_s"] = checked["timestep_s"]
    # through JSON as design.json keeps it: the replay draws from the very same numbers
    table = json.loads(json.dumps(table))
    early = {} if decisive is None else {"decisive": decisive}
    early |= {"probe": True} if probe else {}
    early |= {"repair": True} if repair else {}
    early |= {"made": made} if made else {}
    robust = synth.verification.runs.verify_robust(
        bundle, k, table, only=only, sensing=sensing, **early
    )
    return replace(robust, physics=checked, shows=shows(robust))


def physics(
    bundle: Bundle,
    nominal: Sequence[Run] | None = None,
    sensed: Sequence[Run] | None = None,
) -> dict:
    """:func:`synth.verification.runs.physics_check` of the plans (``nominal``: their fine runs when
    known), and where they agree at the coarse step, the sensing loops' too (``sensed``:
    their fine nominal runs, ``program.sensing.verify_sensing``; each run again on the
    bundle at the coarse step): one step for every perturbed run of the design."""

    checked = physics_check(bundle, nominal)
    loops = [r.to_dict() for r in sensed or () if r.figures.get("verdict") is not None]
    if not checked["timestep_s"] or not loops:
        return checked

    raw = bundle.files["robot.xml"]
    text, _ = coarse_xml(raw.decode("utf-8") if isinstance(raw, bytes) else raw)
    coarse = verify_sensing({**bundle.files, "robot.xml": text})
    largest = dict(checked["largest"])
    why = agreement(loops, coarse, largest)
    return dict(
        checked,
        largest=dict(sorted(largest.items())),
        timestep_s=None if why else checked["timestep_s"],
        why=why or checked["why"],
    )


#: The confidence of the bound :func:`shows` states.
CONFIDENCE = 0.9


def success_bound(passed: int, runs: int, confidence: float = CONFIDENCE) -> float:
    """The one-sided Clopper-Pearson lower bound of a success probability after ``passed``
    successes in ``runs`` independent runs: the p below which so many successes would
    happen with probability under 1 - ``confidence`` ((1 - c)^(1/n) when all passed)."""
    if runs <= 0 or passed <= 0:
        return 0.0
    alpha = 1.0 - confidence
    if passed == runs:
        return alpha ** (1.0 / runs)
    # the beta distribution's quantile, from scipy.special (scipy.stats costs ~1 s to import)
    from scipy.special import betaincinv

    return float(betaincinv(passed, runs - passed + 1, alpha))


def shows(robust: RobustRuns) -> dict:
    """What the perturbed runs show (``verified.robust.shows``): for the behaviour with the
    fewest passes, the lower bound of its success probability over the table's
    perturbations at :data:`CONFIDENCE` (each behaviour's own is at least that)."""
    rows = robust.behaviors
    if not rows:
        return {}
    worst = min(rows, key=lambda b: (b.share, b.behavior))
    bound = success_bound(worst.passed, worst.runs)
    return {
        "method": "Clopper-Pearson, one-sided",
        "confidence": CONFIDENCE,
        "passed": worst.passed,
        "runs": worst.runs,
        "behavior": worst.behavior,
        "success_lower_bound": float(f"{bound:.4g}"),
    }


def certified_share(n: int, share: float, k: int) -> float:
    """The share of a certification's ``n`` runs a behaviour must pass (``--certify N``):
    the fewest passes whose lower bound (:func:`success_bound`) is at least the one the
    default verification's ``k`` runs show when they pass as the table's ``share``
    requires, as a share of ``n``. So a certification never shows less than an accepted
    default design claims, and a rare failed run among many does not refuse a design that
    K of K would accept: with K = 8 (8 of 8, above 74.99 %), 26 of 30 (above 75.1 %);
    with ``n`` at most ``k``, every run."""
    claim = success_bound(required_passes(k, share), k)
    for p in range(n + 1):
        if success_bound(p, n) >= claim:
            return p / n
    return 1.0


def with_sensing(robust: RobustRuns, more: RobustRuns | None) -> RobustRuns:
    """``robust`` (the plans' perturbed runs) with the sensing loops' of ``more`` (the same
    table and seeds) after them."""
    if not more:
        return robust
    out = robust.with_behaviors(more.behaviors)
    return replace(out, shows=shows(out))


def robust_bundle(designer: Designer, outcome: Outcome) -> Bundle:
    """The bundle the perturbed runs use (as the user gets it: robot.xml without the
    payload, which design.json places)."""
    return Bundle(
        bundle_files(
            outcome.record(designer),
            outcome.structure,
            outcome.catalog,
            with_payload=outcome.with_payload,
            pictures=False,
            simulated_only=True,
        )
    )


#: Failed perturbed runs of a behaviour that are replayed to tell whether the joints' play
#: breaks it (the worst first: most criteria failed, then the lowest seed).
BLAMED_RUNS = 3


def replayed_blame(bundle: Bundle, robust: RobustRuns | None, attribution, most: int) -> list[dict]:
    """The failed perturbed runs of the behaviours that are not robust (up to ``most`` a
    behaviour, the worst first: most criteria failed, then the lowest seed) for which
    ``attribution(bundle, table, behavior, seed, run)`` (a replay of that run with one
    cause taken away, given the run as recorded) finds the cause: each its ``behavior``
    and ``seed`` with what ``attribution`` returned; none without a table."""
    if not robust or not isinstance(robust.table, Mapping) or not robust.table:
        return []  # no table: nothing to replay
    out = []
    for behavior, seed, run in worst_failures(robust, most):
        found = attribution(bundle, robust.table, behavior, seed, run)
        if found is not None:
            out.append({"behavior": behavior, "seed": seed} | found)
    return out


def worst_failures(robust: RobustRuns, most: int) -> list[tuple[str, int, Run | None]]:
    """(behaviour, seed, the run as recorded or None) of the failed perturbed runs of each
    behaviour that is not robust, up to ``most`` a behaviour, the worst first (most
    criteria failed, then the lowest seed): the runs the loop replays for a cause."""
    out = []
    for b in robust.behaviors:
        if b.robust or b.loop == "sensing":
            continue  # (a sensing loop is no plan to replay with one cause taken away)
        out += [(b.behavior, f.seed, b.run(f.seed)) for f in b.worst_failures(most)]
    return out
