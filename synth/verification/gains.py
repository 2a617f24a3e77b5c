"""A closed loop's gains as a cause of failed perturbed runs, and other gains that answer
it (:class:`Gains`, a :class:`synth.verification.causes.Cause`).

A behaviour whose plan asks for a feedback loop (``info["feedback"]``: the wheels'
odometry, a base's hold, a biped's balance, an arm's read-back hold; :mod:`gaits.feedback`)
runs its loop with the gains its controller gives. When its perturbed runs fail and no
stronger actuator, stiffer wheel servo or servo of less play answers them, the loop tries
the same loop with its gains scaled by each of :data:`GAIN_SCALES` in turn, a stiffer and
a softer one: the behaviour runs again, nominally and under every perturbation of the
round (the same table and seeds; the worst-looking perturbations first, stopping at the
first run that fails), on the design as it stands with that scale (:func:`with_gains`).
The first scale with which the nominal run and every perturbed run
pass is kept: the record's ``feedback_gains`` (behaviour -> scale) gives it to the
design's controller, which puts it in the behaviour's plans
(``info["feedback"]["gain_scale"]``, :class:`gaits.feedback.Loop`), so ``parmor
simulate``, ``parmor run``, the ROS node and the block page run the same gains from the
bundle; ``verified.robust.gains`` records the scales tried and what each gave. The design
is then verified again with it (a round without a new sizing). When no scale passes, the
refusal names the scales tried and what they gave.

Gains are tried only for behaviours that serve a demanded ability (a bonus one is dropped
as before) and once per behaviour; the gains of a loop are those its class names
(:attr:`gaits.feedback.Loop.GAINS`: proportional, integral and derivative gains, not its
limits or timing).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from synth.verification.causes import Remedy, Round, trial_passes, with_record

if TYPE_CHECKING:
    from synth.verification.source import Bundle

#: The scales of a closed loop's gains tried, in this order: stiffer (x2), then softer (x0.5).
GAIN_SCALES = (2.0, 0.5)


def with_gains(bundle: Bundle, gains: Mapping[str, float]) -> Bundle:
    """``bundle`` whose record gives its behaviours' loops the gain scales ``gains``
    (behaviour -> scale; the record's ``feedback_gains``)."""
    return with_record(bundle, "feedback_gains", gains)


class Gains:
    """The gains cause of the loop (module docstring). ``scales``: the scales tried (default
    :data:`GAIN_SCALES`)."""

    name = "gains"

    def __init__(self, scales: tuple[float, ...] | None = None) -> None:
        self.scales = tuple(GAIN_SCALES if scales is None else scales)
        self.tried: list[dict] = []  # each scale tried: behaviour, loop, scale, what it gave
        self.chosen: dict[str, float] = {}
        self.done: set[str] = set()  # behaviours whose gains were tried
        self.at = 0

    def explains(self, now: Round) -> Remedy | None:
        """For each behaviour of ``now`` that is not robust, serves a demanded ability and
        runs a feedback loop: the first scale of its loop's gains with which its nominal
        run and every perturbed run pass. A remedy with every scale found (and those
        chosen before); None when none was."""
        robust = now.robust
        if robust is None:
            return None
        self.at = now.number
        bundle = now.bundle()
        controller = bundle.controller()
        gains = dict(now.gains)
        found: dict[str, float] = {}
        for b in robust.not_robust():
            if b.loop == "sensing" or b.behavior in self.done or b.behavior not in now.demanded:
                continue
            feedback = controller.run(b.behavior).info.get("feedback")
            if not feedback:
                continue  # open loop: no gains to choose
            self.done.add(b.behavior)
            base = gains.get(b.behavior, 1.0)
            for s in self.scales:
                scale = float(f"{base * s:.6g}")
                trial = with_gains(bundle, {**gains, **found, b.behavior: scale})
                entry = {"behavior": b.behavior, "loop": str(feedback.get("loop")), "scale": scale}
                # a failed run rejects the scale (the worst-looking perturbations first)
                ok, entry = trial_passes(trial, robust, b.behavior, entry)
                self.tried.append(entry)
                if ok:
                    found[b.behavior] = scale
                    break
        if not found:
            return None
        return Remedy(gains={**gains, **found})

    def taken(self, now: Round, sizing: Mapping[str, frozenset[str]]) -> None:
        return None

    def chose(self, gains: Mapping[str, float]) -> None:
        """The loop verifies the design again with ``gains``."""
        self.chosen = dict(gains)

    def note(self, behavior: str, final: int) -> str:
        """``; its wheel-odometry loop's gains x2 (perturbed run 6 failed: stopped there, 1 of
        8 runs made),
        x0.5 (...) do not make it pass``; "" when none were tried for ``behavior`` on this
        design."""
        tried = [t for t in self.tried if t["behavior"] == behavior]
        if self.at != final or not tried or behavior in self.chosen:
            return ""
        parts = []
        for t in tried:
            if t["nominal"] != "ok":
                got = f"failed nominally: {', '.join(t['nominal'])}"
            elif t["runs"] < t["of"]:
                got = (
                    f"perturbed run {t['failed_seed']} failed: stopped there, "
                    f"{t['runs']} of {t['of']} runs made"
                )
            else:
                got = f"passed {t['passed']} of {t['runs']}"
            parts.append(f"x{t['scale']:g} ({got})")
        return f"; its {tried[0]['loop']} loop's gains {', '.join(parts)} do not make it pass"

    def record(self, models: Mapping[str, str] | None = None) -> dict | None:
        """``verified.robust.gains``: the scales tried, each with what it gave, and those
        chosen; None when none were tried."""
        if not self.tried:
            return None
        return {
            "scales": list(self.scales),
            "chosen": dict(sorted(self.chosen.items())),
            "tried": list(self.tried),
        }
