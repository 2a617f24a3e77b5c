"""The joints' play as a cause of failed perturbed runs, measured, and the servos of less
play that answer it (:class:`Play`, a :class:`synth.verification.causes.Cause`).

A position servo's play (its gears' backlash and its pulse dead band, the perturbation
table's: :mod:`synth.verification.perturb`) is a passive hinge in series with it in a
perturbed model. :func:`play_attribution` replays a failed run with the same perturbation
less every servo's play: when that passes, it puts the play of each group of alike joints
back, the smallest first, keeping it where the run still passes: the groups left are the
ones whose play breaks it. :func:`play_blame` does so for the worst failed runs of each
behaviour that is not robust; :func:`less_play` excludes, for the joints whose play it is,
their servo and every servo of the catalog with as much play, and the loop sizes the
design again (the servo with less play must still hold the joint's torque; all the joints
at once, else one at a time, the one blamed in most runs first). :func:`play_note` words
it for a refusal; ``verified.play`` records each swap and the runs that called for it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from synth.verification.causes import Remedy, Round
from synth.verification.perturb import catalog_play
from synth.verification.robust import BLAMED_RUNS, replayed_blame, worst_failures
from synth.verification.runs import Replay

if TYPE_CHECKING:
    from synth.verification.results import RobustRuns, Run
    from synth.verification.source import Bundle


class Play:
    """The play cause of the loop (module docstring)."""

    name = "play"

    def __init__(self) -> None:
        self.play: dict[str, float] | None = None  # model -> its largest play (the catalog's)
        self.blamed: list[dict] = []  # the runs the play broke, measured on round ``at``
        self.unexplained: dict[str, list[int]] = {}  # behaviour -> seeds failing without it
        self.at = 0
        self.history: list[dict] = []  # and those of every round, for the record
        self.stuck: list[str] = []  # joints the play broke that no model with less play serves
        self.models: Mapping[str, str] = {}  # the joints' actuators when it was measured
        self.first: dict[str, str] = {}  # joint -> its actuator before its play was answered

    def explains(self, now: Round) -> Remedy | None:
        if self.play is None:
            self.play = catalog_play(now.catalog)
        runs = play_blame(now.bundle(), now.robust)
        self.blamed, self.at, self.models = runs, now.number, now.models
        # the runs replayed that fail without the play too: not the play's (the note says so)
        blamed = {(r["behavior"], r["seed"]) for r in runs}
        self.unexplained = {}
        for behavior, seed, _ in worst_failures(now.robust, BLAMED_RUNS) if now.robust else ():
            if (behavior, seed) not in blamed:
                self.unexplained.setdefault(behavior, []).append(seed)
        self.history += runs
        serving = now.sizer.assigner.serving if now.sizer is not None else {}
        looser, self.stuck = less_play(runs, now.models, serving, self.play, now.excluded)
        # all the joints at once; when no assignment holds them all, one joint at a time,
        # the one blamed in most runs first
        blame = {j: sum(j in r["joints"] for r in runs) for j in looser}
        tries = [dict(looser)] if looser else []
        if len(looser) > 1:
            tries += [{j: looser[j]} for j in sorted(looser, key=lambda j: (-blame[j], j))]
        return Remedy(tuple(tries)) if tries else None

    def taken(self, now: Round, sizing: Mapping[str, frozenset[str]]) -> None:
        for j in sizing:
            self.first.setdefault(j, now.models[j])

    def note(self, behavior: str, final: int) -> str:
        if self.at != final:  # measured on another design than the one refused
            return ""
        return play_note(
            self.blamed,
            behavior,
            self.stuck,
            self.play or {},
            self.models,
            self.unexplained.get(behavior, ()),
        )

    def record(self, models: Mapping[str, str]) -> dict | None:
        """``verified.play``: each joint whose servo was swapped for one of less play (from,
        to, their largest play in deg) and the perturbed runs the play broke (behaviour,
        seed, failed criteria, the joints whose play broke it, the figures with and
        without play); None when the play was never measured."""
        if not self.history:
            return None
        import math

        play = self.play or {}

        def deg(m: str) -> float:
            return round(math.degrees(play.get(m, 0.0)), 4)

        return {
            "swapped": {
                j: {"from": m, "to": models.get(j), "play_deg": [deg(m), deg(models.get(j, ""))]}
                for j, m in sorted(self.first.items())
            },
            "blamed": self.history,
        }


def play_blame(bundle: Bundle, robust: RobustRuns | None) -> list[dict]:
    """The failed perturbed runs of the behaviours that are not robust which the joints'
    play breaks, measured (:func:`play_attribution`: each run replayed with
    the same perturbation less the play): per run its behaviour, seed, failed criteria and
    the joints whose play must go for it to pass (up to ``BLAMED_RUNS`` runs a
    behaviour). A run that still fails without any play is not the play's (none listed)."""
    return replayed_blame(bundle, robust, play_attribution, BLAMED_RUNS)


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
    unexplained: Sequence[int] = (),
) -> str:
    """What a refusal adds when the play broke ``behavior``: the joints whose play it is
    (measured), their actuators and play, the seeds replayed that fail without it too
    (``unexplained``), and that the catalog has none with less play that holds their
    torque; "" when the play did not break it."""
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
    which += " with their play removed"
    if unexplained:
        others = ", ".join(str(s) for s in sorted(unexplained))
        which += f"; seed{'s' if len(unexplained) > 1 else ''} {others} "
        which += f"fail{'' if len(unexplained) > 1 else 's'} without it too"
    return f"; the play of {servos} breaks it ({which}){tail}"


def play_attribution(
    bundle: Bundle,
    table: Mapping,
    behavior: str,
    seed: int,
    failed: Run | None = None,
) -> dict | None:
    """Does the joints' play break behaviour ``behavior`` of a bundle under perturbation
    ``seed`` of ``table``? ``failed``: that run when it is known already
    (:func:`synth.verification.runs.verify_robust`'s, to the bit: it is not simulated
    again). Measured by replays of that very perturbation: with every position servo's
    play removed (the rest unchanged) the run must pass, else None (the
    play alone does not break it; None too when the run passes as it is). Then the play
    of each symmetry group of joints (the record's ``group``: alike joints get alike
    servos) is put back, the smallest play first, and kept when the run still passes: the
    groups left are those whose play must go. ``{"verdict": [...], "joints": [...],
    "figures": {"with": ..., "without": ...}}`` (the failed criteria, the joints whose
    play breaks it, the :func:`_criteria` figures of the run with and without play)."""

    replay = Replay(bundle, table, behavior, seed)
    record, p = replay.record, replay.perturbation
    full = dict(p["play_rad"])

    def run(removed: set[str]) -> Run:
        play = {"play_rad": {j: (0.0 if j in removed else v) for j, v in full.items()}}
        return replay.run(play, stop_on_failure=bool(removed) and removed != set(full))

    before = run(set()) if failed is None else failed
    if before.ok:
        return None
    without = run(set(full))
    if not without.ok:
        return None
    group_of = {j["name"]: j.get("group") or j["name"] for j in record.get("joints", ())}
    groups: dict[str, list[str]] = {}
    for j in full:
        groups.setdefault(group_of.get(j, j), []).append(j)
    order = sorted(groups, key=lambda g: (max(full[j] for j in groups[g]), g))
    removed = set(full)
    for g in order:
        trial = removed - set(groups[g])
        if run(trial).ok:
            removed = trial
    return {
        "verdict": before.verdict,
        "joints": sorted(removed),
        "figures": {"with": before.criteria(), "without": without.criteria()},
    }
