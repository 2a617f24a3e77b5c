"""Perturbed runs that the servos' command hold breaks (issue 22), measured, and the speed
that answers them.

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
still fails without it): a lower speed is.

:func:`hold_attribution` tells, by replays of the failed run's very perturbation, whether
the hold breaks it (it passes with the control period at 0) and the largest share of the
behaviour's default speed (``SPEED_SHARES``) at which it passes as perturbed;
:func:`hold_blame` does so for the failed runs of the behaviours that are not robust;
:func:`hold_note` words it for a refusal (the perturbation, the joints' step against the
servo's band, the speed that passes).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from synth.verification.causes import Remedy, Round

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
    SPEED_SHARES x the default speed at which the run passes as perturbed (None: none
    does, or the behaviour has no speed), "default_speed", "unit"}``."""
    from synth.verification.runs import Replay

    replay = Replay(bundle, table, behavior, seed)
    controller, traj, p, run = replay.controller, replay.plan, replay.perturbation, replay.run
    frame = float(p.get("control_period_s") or 0.0)

    before = run() if failed is None else failed
    if frame <= 0 or "saturated" not in before.verdict:
        return None
    if not run({"control_period_s": 0.0}, stop_on_failure=True).ok:
        return None
    spec = controller.behaviors[behavior]
    speed = next((x for x in spec.params if x.name == "speed"), None)
    default = float(traj.info.get("speed") or 0.0)
    found = None
    if speed is not None and default > 0:
        for share in SPEED_SHARES:
            value = float(f"{share * default:.3g}")
            try:
                plan = controller.run(behavior, speed=value)
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
        "speed": found,
        "default_speed": default,
        "unit": speed.unit if speed is not None else "",
    }


def hold_blame(bundle: Bundle, robust: RobustRuns | None) -> list[dict]:
    """:func:`hold_attribution` of the failed perturbed runs (up to ``HOLD_BLAMED_RUNS`` a
    behaviour, the worst first) of the behaviours that are not robust, each with its
    ``behavior`` and ``seed``: those the command hold breaks."""
    from synth.verification.robust import replayed_blame

    return replayed_blame(bundle, robust, hold_attribution, HOLD_BLAMED_RUNS)


def hold_note(blamed: list[dict], behavior: str) -> str:
    """What a refusal adds when the command hold broke ``behavior`` (:func:`hold_blame`):
    the joints' largest reference step a frame against the servo's band, and the speed at
    which the run passes; "" when the hold did not break it."""
    from export.mjcf import SERVO_BAND

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
        out += (
            f"; at speed {min(speeds):g} {unit} (the default {default:g} {unit}) "
            f"{'they pass' if len(runs) > 1 else 'it passes'} as perturbed"
        )
    return out


class Hold:
    """The servos' command hold as a cause of the loop (:class:`synth.verification.causes.
    Cause`): measured on the design the loop ends with (:func:`hold_blame`), for a refusal
    to name; no sizing answers it (a lower speed does, which the design's plans do not
    choose), so it changes nothing."""

    name = "command hold"

    def __init__(self) -> None:
        self.at = 0
        self.held: list[dict] = []

    def explains(self, now: Round) -> Remedy | None:
        self.held, self.at = hold_blame(now.bundle(), now.robust), now.number
        return None

    def taken(self, now: Round, sizing: Mapping[str, frozenset[str]]) -> None:
        return None

    def note(self, behavior: str, final: int) -> str:
        return hold_note(self.held, behavior) if self.at == final else ""

    def record(self, models: Mapping[str, str]) -> dict | None:
        return None
