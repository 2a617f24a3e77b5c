"""Perturbed runs that the servos' command hold breaks (issue 22), measured, and the pace
that answers them (issue 30).

A position servo in the MuJoCo model gives its stall torque ``export.mjcf.SERVO_BAND``
(0.05 rad) off its reference (``kp = effort / SERVO_BAND``), less what the load already
takes. The perturbations hold each command for the bus's control period (``[bus]
control_period``: 20 ms, a hobby servo's 50 Hz frame), so a joint's reference moves in
steps of its speed x 20 ms: a joint planned at 60 % of a DS3218's no-load speed (3.9
rad/s) steps 0.078 rad a frame and its servo saturates at every step of the fast part of
each swing. The KIF heptapod with 0.2 kg walks with its femurs on DS3218, the catalog's
strongest servo: its seven femurs each saturate about 1 % of the time, 6.2 % together
(limit 5 %); replayed with the commands applied as sent (the latency kept) every run
passes, and with the latency alone too (0 %). A stronger actuator is not the answer
(there is none: the sizing loop's torque floors cannot rise), less play neither (the run
still fails without it): a slower pace is.

:func:`hold_attribution` tells, by replays of the failed run's very perturbation, whether
the hold breaks it (it passes with the control period at 0) and the largest share of the
behaviour's pace (``SPEED_SHARES`` of its pace parameter, :func:`gaits.base.
pace_parameter`: a legged robot's ``speed``, a humanoid's ``step_length``...) at which it
passes as perturbed; :func:`hold_blame` does so for the failed runs of the behaviours that
are not robust; :func:`hold_note` words it for a refusal (the perturbation, the joints'
step against the servo's band, the pace that passes).

:class:`Hold`, the cause of the strengthening loop, answers it when no sizing and no
gains do: for each behaviour that serves a demanded ability and that the hold breaks, the
slowest pace its blamed runs need is verified like a gain scale (the nominal run and every
perturbed run of the round's table, the worst-looking first, stopping at the first that
fails); the first that passes them all is kept as the record's ``paces`` (behaviour ->
pace), which the design's controller plans with when a caller gives no pace of its own
(``parmor simulate``, ``parmor run``, the ROS node and the block page alike), and
``verified.robust.paces`` records what was tried. A pace is chosen only where the request
left the speed to the design: a request that gives ``--param speed`` gets a refusal naming
the pace that would pass instead (the user asked for that speed).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from export.mjcf import SERVO_BAND
from gaits.base import pace_parameter
from synth.verification.causes import Remedy, Round, trial_passes, with_record
from synth.verification.robust import replayed_blame
from synth.verification.runs import Replay

if TYPE_CHECKING:
    from synth.verification.results import RobustRuns, Run
    from synth.verification.source import Bundle

#: Failed runs of a behaviour replayed (the worst first, as ``robust.BLAMED_RUNS``).
HOLD_BLAMED_RUNS = 2
#: Shares of a behaviour's default speed tried, fastest first.
SPEED_SHARES = (0.9, 0.8, 0.7, 0.6, 0.5)


def _steps(traj, joints, frame: float) -> dict[str, float]:
    """The largest step rad of each of ``joints``' reference over one ``frame`` s of the
    plan ``traj``."""
    import numpy as np

    out = {}
    for j in joints:
        if j not in traj.joints:
            continue
        k = list(traj.joints).index(j)
        q = np.interp(
            np.arange(traj.times[0], traj.times[-1], frame), traj.times, traj.positions[:, k]
        )
        out[j] = float(np.abs(np.diff(q)).max()) if len(q) > 1 else 0.0
    return out


def hold_attribution(
    bundle: Bundle,
    table: Mapping,
    behavior: str,
    seed: int,
    failed: Run | None = None,
) -> dict | None:
    """Does the command hold break behaviour ``behavior`` of a bundle under perturbation
    ``seed`` of ``table``? ``failed``: the run's figures when known (``synth.verification.runs.
    verify_robust``'s). The run must fail saturated and pass replayed with the control
    period at 0 (everything else as drawn), else None. Then ``{"verdict", "frame_s",
    "joints": {joint: its largest reference step rad a frame}, "speed": the largest of
    SPEED_SHARES x the behaviour's pace (its ``parameter``, :func:`gaits.base.pace_parameter`)
    at which the run passes as perturbed (None: none does, or the behaviour has no pace),
    "default_speed": the pace it had, "unit"}``."""

    replay = Replay(bundle, table, behavior, seed)
    controller, traj, p, run = replay.controller, replay.plan, replay.perturbation, replay.run
    frame = float(p.get("control_period_s") or 0.0)

    before = run() if failed is None else failed
    if frame <= 0 or "saturated" not in before.verdict:
        return None
    if not run({"control_period_s": 0.0}, stop_on_failure=True).ok:
        return None

    spec = controller.offered(behavior)  # its pace: the one the design plans with now
    key = pace_parameter(spec)
    pace = next((x for x in spec.params if x.name == key), None)
    default = float(pace.default) if pace is not None and pace.default else 0.0  # type: ignore[arg-type]
    found = None
    if key is not None and default > 0:
        for share in SPEED_SHARES:
            value = float(f"{share * default:.3g}")
            try:
                plan = controller.run(behavior, **{key: value})
            except ValueError:
                continue
            if run(plan=plan, stop_on_failure=True).ok:
                found = value
                break
    saturated = sorted(before.saturated_joints)
    return {
        "verdict": before.verdict,
        "frame_s": frame,
        "joints": _steps(traj, saturated, frame),
        "parameter": key,
        "speed": found,
        "default_speed": default,
        "unit": pace.unit if pace is not None else "",
    }


def hold_blame(bundle: Bundle, robust: RobustRuns | None) -> list[dict]:
    """:func:`hold_attribution` of the failed perturbed runs (up to ``HOLD_BLAMED_RUNS`` a
    behaviour, the worst first) of the behaviours that are not robust, each with its
    ``behavior`` and ``seed``: those the command hold breaks."""

    return replayed_blame(bundle, robust, hold_attribution, HOLD_BLAMED_RUNS)


def hold_note(blamed: list[dict], behavior: str) -> str:
    """What a refusal adds when the command hold broke ``behavior`` (:func:`hold_blame`):
    the joints' largest reference step a frame against the servo's band, and the speed at
    which the run passes; "" when the hold did not break it."""

    runs = [r for r in blamed if r["behavior"] == behavior]
    if not runs:
        return ""
    steps: dict[str, float] = {}
    for r in runs:
        for j, s in r["joints"].items():
            steps[j] = max(steps.get(j, 0.0), s)
    top = sorted(steps, key=lambda j: (-steps[j], j))[:3]
    seeds = ", ".join(str(r["seed"]) for r in runs)
    which = f"seeds {seeds} pass" if len(runs) > 1 else f"seed {seeds} passes"
    frame = runs[0]["frame_s"] * 1000
    out = (
        f"; the servos' {frame:g} ms command hold breaks it ({which} with each command "
        f"applied as sent): {', '.join(f'{j} steps up to {steps[j]:.3f} rad' for j in top)} "
        f"a frame (a servo gives its stall torque {SERVO_BAND:g} rad off its reference)"
    )
    speeds = [r["speed"] for r in runs]
    if all(s is not None for s in speeds):
        unit, default = runs[0]["unit"], float(f"{runs[0]['default_speed']:.3g}")
        key = runs[0].get("parameter") or "speed"
        out += (
            f"; at {key} {min(speeds):g} {unit} (the design's {default:g} {unit}) "
            f"{'they pass' if len(runs) > 1 else 'it passes'} as perturbed"
        )
    return out


def with_paces(bundle: Bundle, paces: Mapping[str, float]) -> Bundle:
    """``bundle`` whose record gives its behaviours the paces ``paces`` (behaviour -> the
    value of its pace parameter; the record's ``paces``)."""
    return with_record(bundle, "paces", paces)


class Hold:
    """The servos' command hold as a cause of the loop (:class:`synth.verification.causes.
    Cause`, module docstring): measured by replays of the failed runs (:func:`hold_blame`);
    answered by a slower pace of the behaviours it breaks (:meth:`explains`, where the
    request left the speed to the design: ``given``, the request's own parameters, has no
    ``speed``), verified on every perturbed run before it is kept."""

    name = "command hold"

    def __init__(self, given: Mapping[str, object] | None = None) -> None:
        self.at = 0
        self.held: list[dict] = []
        #: the request gave the speed: the paces are the user's, none is chosen
        self.fixed = "speed" in (given or {})
        self.tried: list[dict] = []  # each pace tried: behaviour, parameter, pace, outcome
        self.chosen: dict[str, float] = {}
        self.done: set[str] = set()  # behaviours whose pace was tried

    def measure(self, now: Round) -> None:
        """The failed runs of ``now`` the hold breaks (for :meth:`note`), once a round."""
        if self.at != now.number:
            self.held, self.at = hold_blame(now.bundle(), now.robust), now.number

    def explains(self, now: Round) -> Remedy | None:
        """For each behaviour of ``now`` that is not robust, serves a demanded ability and
        whose blamed runs the hold breaks, each passing at a slower pace: the slowest of
        those paces, kept when its nominal run and every perturbed run pass with it. A
        remedy with the paces found (and those chosen before); None when none was."""
        self.measure(now)
        robust = now.robust
        if robust is None or self.fixed:
            return None
        bundle = now.bundle()
        paces = dict(now.paces)
        found: dict[str, float] = {}
        for behavior in sorted({r["behavior"] for r in self.held}):
            if behavior in self.done or behavior not in now.demanded:
                continue
            mine = [r for r in self.held if r["behavior"] == behavior]
            if any(r["speed"] is None for r in mine):
                continue  # a blamed run no slower pace makes pass
            self.done.add(behavior)
            # the slowest pace the blamed runs need, then (if another run fails at it) the
            # next share slower
            value, was = min(float(r["speed"]) for r in mine), float(mine[0]["default_speed"])
            slower = [float(f"{x * was:.3g}") for x in SPEED_SHARES if x * was < value * 0.999]
            for pace in [value, *slower[:1]]:
                if self._passes(
                    bundle, robust, behavior, {**paces, **found, behavior: pace}, mine[0]
                ):
                    found[behavior] = pace
                    break
        if not found:
            return None
        return Remedy(paces={**paces, **found})

    def _passes(
        self, bundle: Bundle, robust: RobustRuns, behavior: str, paces: dict, blamed: dict
    ) -> bool:
        """Does ``behavior`` pass nominally and in every perturbed run of ``robust``'s table
        with ``paces``? (The worst-looking perturbations first, stopping at the first run
        that fails; what it gave is kept in :attr:`tried`.)"""
        entry = {
            "behavior": behavior,
            "parameter": blamed["parameter"],
            "pace": paces[behavior],
            "unit": blamed["unit"],
            "from": blamed["default_speed"],
        }
        ok, entry = trial_passes(with_paces(bundle, paces), robust, behavior, entry)
        self.tried.append(entry)
        return ok

    def chose(self, paces: Mapping[str, float]) -> None:
        """The loop verifies the design again with ``paces``."""
        self.chosen = dict(paces)

    def taken(self, now: Round, sizing: Mapping[str, frozenset[str]]) -> None:
        return None

    def note(self, behavior: str, final: int) -> str:
        """What a refusal of ``behavior`` adds: the hold's share of its failed runs and the
        pace at which they pass (:func:`hold_note`), what a pace tried gave, and why none
        was chosen when the request gave the speed; "" when the hold did not break it."""
        out = hold_note(self.held, behavior) if self.at == final else ""
        if not out or behavior in self.chosen:
            return ""
        for t in self.tried:
            if t["behavior"] != behavior:
                continue
            if t["nominal"] != "ok":
                got = f"failed nominally: {', '.join(t['nominal'])}"
            else:
                got = f"perturbed run {t.get('failed_seed')} failed, {t['runs']} of {t['of']} made"
            out += f"; at {t['parameter']} {t['pace']:g} {t['unit']} it {got}"
        if self.fixed:
            out += " (the request gives --param speed: no other pace is chosen)"
        return out

    def record(self, models: Mapping[str, str] | None = None) -> dict | None:
        """``verified.robust.paces``: the paces tried, each with what it gave, and those
        chosen; None when none was tried."""
        if not self.tried:
            return None
        return {"chosen": dict(sorted(self.chosen.items())), "tried": list(self.tried)}
