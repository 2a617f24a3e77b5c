"""Robust verification in the design loop: a sized design's behaviours run under K seeded
perturbations (:mod:`synth.verification.perturb`, :func:`synth.verification.runs.verify_robust`)
once they pass on the nominal model, and judged by the acceptance rule: every behaviour passes in at
least ``share`` x K of its runs (``synth/verification/perturb.toml``, ``[acceptance]``).

:mod:`synth.verification.loop` calls :func:`robust_check` where it judges the nominal results: a
perturbed run that failed with an actuator at its limit feeds the same loop as a nominal
one (:func:`failing_runs`: each saturated joint gets a stronger actuator, the design is
sized again); a behaviour still not robust then fails a demanded ability (the request is
refused naming the behaviour, the perturbation that broke it and its figures against the
thresholds) or drops a bonus one (:func:`not_robust`). A failed perturbed run that the
joints' play breaks (:func:`play_blame`, measured by replays) gets servos of less play for
those joints (:func:`less_play`); a refusal then names them (:func:`play_note`).

The runs use the bundle as the user gets it (robot.xml without the payload, which
design.json places as ``parmor simulate`` does), so that ``parmor simulate DIR --perturb
SEED`` replays each recorded run to the bit.
"""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from synth.conceptual import Designer
    from synth.pipeline import Outcome


def robust_check(
    designer: Designer,
    outcome: Outcome,
    k: int,
    only: Collection[str] | None = None,
    files: Mapping[str, str | bytes] | None = None,
    nominal: Sequence[Mapping] | None = None,
    sensing: bool = True,
    sensed: Sequence[Mapping] | None = None,
    table: Mapping | None = None,
) -> dict | None:
    """``verified.robust`` of ``outcome`` (a sized design) under perturbations 1..``k`` of
    its table (of its listed behaviours, those named in ``only`` when given; its sensing
    loops unless ``sensing`` is false); None when ``k`` is 0. ``files``: its
    :func:`robust_files` when the caller has them already; ``nominal``, ``sensed``: the
    figures of its nominal runs (``verify_files``, ``verify_sensing``) when the caller has
    them. The runs use the coarse time step where the nominal runs, sensing loops
    included, agree at it (:func:`physics`; ``table["timestep_s"]``, recorded with the
    table, so a replay uses it too); ``verified.robust.physics`` says which and why.
    ``table``: a table already chosen (the sensing loops' runs after the plans')."""
    if k <= 0 or outcome.structure is None or outcome.catalog is None:
        return None
    from synth.verification.perturb import design_table
    from synth.verification.runs import bundle_parts, verify_robust

    files = robust_files(designer, outcome) if files is None else files
    checked = None
    if table is None:
        record, xml, _ = bundle_parts(files)
        table = design_table(record, xml, outcome.catalog)
        # the coarse step where this design's nominal runs agree with the fine ones
        checked = physics(files, nominal, sensed)
        if checked["timestep_s"]:
            table["timestep_s"] = checked["timestep_s"]
    # through JSON as design.json keeps it: the replay draws from the very same numbers
    table = json.loads(json.dumps(table))
    robust = verify_robust(files, k, table, only=only, sensing=sensing)
    if checked is not None:
        robust["physics"] = checked
    robust["shows"] = shows(robust)
    return robust


def physics(
    files: Mapping[str, str | bytes],
    nominal: Sequence[Mapping] | None = None,
    sensed: Sequence[Mapping] | None = None,
) -> dict:
    """:func:`synth.verification.runs.physics_check` of the plans (``nominal``: their fine runs when
    known), and where they agree at the coarse step, the sensing loops' too (``sensed``:
    their fine nominal runs, ``program.sensing.verify_sensing``; each run again on the
    bundle at the coarse step): one step for every perturbed run of the design."""
    from synth.verification.runs import agreement, coarse_xml, physics_check

    checked = physics_check(files, nominal)
    loops = [r for r in sensed or () if r.get("verdict") is not None]
    if not checked["timestep_s"] or not loops:
        return checked
    from program.sensing import verify_sensing

    raw = files["robot.xml"]
    text, _ = coarse_xml(raw.decode("utf-8") if isinstance(raw, bytes) else raw)
    coarse = verify_sensing({**files, "robot.xml": text})
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
    from scipy.stats import beta

    return float(beta.ppf(alpha, passed, runs - passed + 1))


def shows(robust: Mapping) -> dict:
    """What the perturbed runs show (``verified.robust.shows``): for the behaviour with the
    fewest passes, the lower bound of its success probability over the table's
    perturbations at :data:`CONFIDENCE` (each behaviour's own is at least that)."""
    rows = robust.get("behaviors") or []
    if not rows:
        return {}
    worst = min(rows, key=lambda b: (b["passed"] / max(b["runs"], 1), b["behavior"]))
    bound = success_bound(int(worst["passed"]), int(worst["runs"]))
    return {
        "method": "Clopper-Pearson, one-sided",
        "confidence": CONFIDENCE,
        "passed": int(worst["passed"]),
        "runs": int(worst["runs"]),
        "behavior": worst["behavior"],
        "success_lower_bound": float(f"{bound:.4g}"),
    }


def with_sensing(robust: dict, more: Mapping | None) -> dict:
    """``robust`` (the plans' perturbed runs) with the sensing loops' of ``more`` (the same
    table and seeds) after them."""
    if not more:
        return robust
    out = dict(robust, behaviors=[*robust["behaviors"], *more["behaviors"]])
    out["shows"] = shows(out)
    return out


def robust_files(designer: Designer, outcome: Outcome) -> dict[str, str | bytes]:
    """The bundle the perturbed runs use (as the user gets it: robot.xml without the
    payload, which design.json places)."""
    from export.bundle import bundle_files

    return bundle_files(
        outcome.record(designer),
        outcome.structure,
        outcome.catalog,
        with_payload=outcome.with_payload,
        pictures=False,
        simulated_only=True,
    )


#: Failed perturbed runs of a behaviour that are replayed to tell whether the joints' play
#: breaks it (the worst first: most criteria failed, then the lowest seed).
BLAMED_RUNS = 3


def play_blame(files: Mapping[str, str | bytes], robust: Mapping | None) -> list[dict]:
    """The failed perturbed runs of the behaviours that are not robust which the joints'
    play breaks, measured (:func:`synth.verification.runs.play_attribution`: each run replayed with
    the same perturbation less the play): per run its behaviour, seed, failed criteria and
    the joints whose play must go for it to pass (up to ``BLAMED_RUNS`` runs a
    behaviour). A run that still fails without any play is not the play's (none listed)."""
    from synth.verification.runs import play_attribution

    return replayed_blame(files, robust, play_attribution, BLAMED_RUNS)


def replayed_blame(
    files: Mapping[str, str | bytes], robust: Mapping | None, attribution, most: int
) -> list[dict]:
    """The failed perturbed runs of the behaviours that are not robust (up to ``most`` a
    behaviour, the worst first: most criteria failed, then the lowest seed) for which
    ``attribution(files, table, behavior, seed, figures)`` (a replay of that run with one
    cause taken away, given the run's recorded figures) finds the cause: each its
    ``behavior`` and ``seed`` with what ``attribution`` returned; none without a table."""
    if not robust or not isinstance(robust.get("table"), Mapping):
        return []  # no table: nothing to replay
    out = []
    for behavior, seed, figures in worst_failures(robust, most):
        found = attribution(files, robust["table"], behavior, seed, figures)
        if found is not None:
            out.append({"behavior": behavior, "seed": seed} | found)
    return out


def worst_failures(robust: Mapping, most: int) -> list[tuple[str, int, dict | None]]:
    """(behaviour, seed, the run's recorded figures or None) of the failed perturbed runs
    of each behaviour that is not robust, up to ``most`` a behaviour, the worst first (most
    criteria failed, then the lowest seed): the runs the loop replays for a cause."""
    out = []
    for b in robust.get("behaviors", ()):
        if b["robust"] or b.get("loop") == "sensing":
            continue  # (a sensing loop is no plan to replay with one cause taken away)
        worst = sorted(b["failures"], key=lambda f: (-len(f["verdict"]), f["seed"]))
        runs = {fig.get("seed"): fig for fig in b.get("figures", ())}
        out += [(b["behavior"], f["seed"], runs.get(f["seed"])) for f in worst[:most]]
    return out


def less_play(
    blamed: list[dict],
    models: Mapping[str, str],
    serving: Mapping[str, tuple[str, ...]],
    play: Mapping[str, float],
    excluded: Mapping[str, frozenset[str]],
) -> tuple[dict[str, frozenset[str]], list[str]]:
    """The play feedback of the verification loop: for each joint whose play broke a run
    (``blamed``, :func:`play_blame`), the models it may no longer have: its actuator
    (``models``: joint -> model) and every one with as much play (``play``: model -> the
    largest play, :func:`synth.verification.perturb.catalog_play`), when a model that serves it
    (``serving``) has less. (joint -> models excluded, new entries only; the blamed joints
    that no model with less play serves)."""
    out: dict[str, frozenset[str]] = {}
    stuck = []
    for joint in sorted({j for run in blamed for j in run["joints"]}):
        model = models.get(joint)
        if model not in play:
            continue
        worse = frozenset(m for m in play if play[m] >= play[model])
        better = [m for m in serving.get(joint, ()) if m not in worse]
        if not better:
            stuck.append(joint)
            continue
        ex = excluded.get(joint, frozenset()) | worse
        if ex != excluded.get(joint):
            out[joint] = ex
    return out, stuck


def play_note(
    blamed: list[dict],
    behavior: str,
    stuck: list[str],
    play: Mapping[str, float],
    models: Mapping[str, str],
) -> str:
    """What a refusal adds when the play broke ``behavior``: the joints whose play it is
    (measured), their actuators and play, and that the catalog has none with less play
    that holds their torque; "" when the play did not break it."""
    import math

    runs = [r for r in blamed if r["behavior"] == behavior]
    if not runs:
        return ""
    joints = sorted({j for r in runs for j in r["joints"]})
    seeds = ", ".join(str(r["seed"]) for r in runs)
    servos = ", ".join(
        f"{j} ({models.get(j)}, up to {math.degrees(play.get(models.get(j), 0.0)):.2g} deg)"
        for j in joints
    )
    left = [j for j in joints if j in stuck]
    tail = (
        f"; the catalog has no actuator with less play for {', '.join(left)}"
        if left
        else "; no actuator of the catalog with less play holds their torque and makes it pass"
    )
    which = f"seeds {seeds} pass" if len(runs) > 1 else f"seed {seeds} passes"
    return f"; the play of {servos} breaks it ({which} with their play removed){tail}"


def failing_runs(robust: Mapping | None) -> list[dict]:
    """The failed perturbed runs of the behaviours that are not robust (figures with
    ``verdict`` and ``saturated_joints``, as the nominal results)."""
    if not robust:
        return []
    return [
        f
        for b in robust["behaviors"]
        if not b["robust"]
        for f in b["figures"]
        if f["verdict"] != "ok"
    ]


def not_robust(robust: Mapping | None) -> list[tuple[str, str]]:
    """(ability, why) of each behaviour that is not robust (:func:`synth.verification.runs.
    robust_failure`), the worst first: the smallest share of its perturbed runs passed,
    then name order (a refusal names the first that serves a demand)."""
    if not robust:
        return []
    from synth.verification.runs import robust_failure

    why = robust_failure(robust)
    bad = [b for b in robust["behaviors"] if not b["robust"]]
    bad.sort(key=lambda b: (b["passed"] / max(b["runs"], 1), b["behavior"]))
    return [(b["ability"], why[b["behavior"]]) for b in bad]
