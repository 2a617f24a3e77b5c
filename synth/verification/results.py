"""What the runs found, typed: one judged run (:class:`Run`), one behaviour's perturbed runs
(:class:`BehaviorRuns`) and a design's (:class:`RobustRuns`, the record's
``verified.robust``). The loop reads their fields; each is turned into the plain mapping
``design.json`` keeps exactly once, by ``to_dict`` (key order as recorded), and read back
from one by ``of`` (a recorded ``verified`` section, a test's stand-in).

The figures of a run are those ``parmor simulate --json`` prints
(:func:`synth.verification.runs.figures`): ``verdict`` (``"ok"`` or the failed criteria)
and the measured figures; :data:`WORST` names those whose worst value over the perturbed
runs a record keeps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

#: Figures of a run whose worst value over the perturbed runs a record keeps: key -> "max"
#: (larger is worse) or "min"; ``distance_ratio`` (distance / planned, worst: farthest from
#: 1) and ``heading_error_rad`` (|heading - planned|) are derived (:func:`criteria`).
WORST = {
    "saturated_fraction": "max",
    "demand_ratio_max": "max",
    "max_torque_ratio": "max",
    "min_height_ratio": "min",
    "max_tilt_rad": "max",
    "distance_ratio": "dev",
    "heading_error_rad": "max",
    "final_pose_error_m": "max",
    "drift_m": "max",
    "tracking_error": "max",
    "placing_error_m": "max",
    "orientation_error_rad": "max",
    "line_lost_s": "max",
    "line_progress_m": "min",
    "obstacle_contact_s": "max",
}


def criteria(fig: Mapping) -> dict[str, float]:
    """The :data:`WORST` figures of one run's figures ``fig`` (those it has)."""
    out = {k: float(fig[k]) for k in WORST if fig.get(k) is not None}
    planned = fig.get("planned_distance_m")
    if planned and fig.get("distance_m") is not None:
        out["distance_ratio"] = float(fig["distance_m"]) / float(planned)
    if fig.get("planned_heading_rad") is not None and fig.get("heading_rad") is not None:
        out["heading_error_rad"] = abs(
            float(fig["heading_rad"]) - float(fig["planned_heading_rad"])
        )
    return out


def worse(kind: str, a: float, b: float) -> bool:
    """Is ``a`` worse than ``b`` for a figure of kind ``kind`` (:data:`WORST`)?"""
    if kind == "min":
        return a < b
    if kind == "dev":
        return abs(a - 1.0) > abs(b - 1.0)
    return a > b


def required_passes(k: int, share: float) -> int:
    """Perturbed runs of K a behaviour must pass: ceil(share x K) (at least 1 when K > 0)."""
    return min(k, max(1 if k else 0, math.ceil(share * k - 1e-9)))


@dataclass(frozen=True)
class Run:
    """One judged run of ``behavior``: nominal (``seed`` None; the record names its
    ``ability``) or under perturbation ``seed``. ``figures``: as ``parmor simulate --json``
    prints them (their own ``behavior`` first, then ``verdict`` ...)."""

    behavior: str
    figures: Mapping[str, Any]
    ability: str | None = None
    seed: int | None = None

    @classmethod
    def of(cls, d: Mapping[str, Any]) -> Run:
        """The run a recorded mapping (:meth:`to_dict`'s) describes."""
        figures = {k: v for k, v in d.items() if k not in ("ability", "seed")}
        seed = d.get("seed")
        return cls(
            str(d["behavior"]), figures, d.get("ability"), None if seed is None else int(seed)
        )

    @property
    def verdict(self) -> list[str]:
        """The failed criteria (none when it passed)."""
        v = self.figures.get("verdict")
        return [] if v in (None, "ok") else list(v)

    @property
    def ok(self) -> bool:
        return not self.verdict

    @property
    def saturated_joints(self) -> dict[str, float]:
        return dict(self.figures.get("saturated_joints") or {})

    def criteria(self) -> dict[str, float]:
        """Its :data:`WORST` figures (:func:`criteria`)."""
        return criteria(self.figures)

    def to_dict(self) -> dict[str, Any]:
        if self.seed is not None:
            return {"seed": self.seed} | dict(self.figures)
        return {"behavior": self.behavior, "ability": self.ability} | dict(self.figures)


@dataclass(frozen=True)
class Failure:
    """A failed perturbed run as a record names it: its seed, failed criteria, why (the
    figures against the thresholds) and the perturbation in one line."""

    seed: int
    verdict: list[str]
    why: str
    perturbation: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "seed": self.seed,
            "verdict": list(self.verdict),
            "why": self.why,
            "perturbation": self.perturbation,
        }


@dataclass(frozen=True)
class BehaviorRuns:
    """One behaviour's perturbed runs: ``passed`` of ``runs``, ``robust`` (at least the
    required passes), the worst value of each :data:`WORST` figure with its seed, the
    failures and every run. ``loop``: ``"sensing"`` for a sensing loop's runs
    (:mod:`program.sensing`)."""

    behavior: str
    ability: str
    passed: int
    runs: int
    robust: bool
    worst: Mapping[str, Mapping[str, float]]
    failures: tuple[Failure, ...]
    figures: tuple[Run, ...]
    loop: str | None = None

    @classmethod
    def judged(
        cls,
        behavior: str,
        ability: str,
        runs: Sequence[Run],
        need: int,
        failure: Any,
        loop: str | None = None,
    ) -> BehaviorRuns:
        """The entry of ``runs`` (one per seed, in seed order), robust when at least
        ``need`` passed; ``failure(run)`` words a failed run (a :class:`Failure`)."""
        worst: dict[str, dict] = {}
        for run in runs:
            for key, value in run.criteria().items():
                w = worst.get(key)
                if w is None or worse(WORST[key], value, w["value"]):
                    worst[key] = {"value": float(f"{value:.6g}"), "seed": run.seed}
        failed = [r for r in runs if not r.ok]
        passed = len(runs) - len(failed)
        return cls(
            behavior,
            ability,
            passed,
            len(runs),
            passed >= need,
            dict(sorted(worst.items())),
            tuple(failure(r) for r in failed),
            tuple(runs),
            loop,
        )

    @classmethod
    def of(cls, d: Mapping[str, Any]) -> BehaviorRuns:
        return cls(
            str(d["behavior"]),
            str(d.get("ability", d["behavior"])),
            int(d["passed"]),
            int(d["runs"]),
            bool(d["robust"]),
            dict(d.get("worst") or {}),
            tuple(
                Failure(int(f["seed"]), list(f["verdict"]), str(f["why"]), str(f["perturbation"]))
                for f in d.get("failures") or ()
            ),
            tuple(Run.of({"behavior": d["behavior"]} | dict(f)) for f in d.get("figures") or ()),
            d.get("loop"),
        )

    @property
    def share(self) -> float:
        """The share of its runs that passed."""
        return self.passed / max(self.runs, 1)

    def failed_runs(self) -> list[Run]:
        return [r for r in self.figures if not r.ok]

    def worst_failures(self, most: int) -> list[Failure]:
        """Up to ``most`` of its failures, the worst first: most criteria failed, then the
        lowest seed (the runs the loop replays for a cause)."""
        return sorted(self.failures, key=lambda f: (-len(f.verdict), f.seed))[:most]

    def run(self, seed: int) -> Run | None:
        """Its run under perturbation ``seed``."""
        return next((r for r in self.figures if r.seed == seed), None)

    def why_not(self, required: int, k: int | None = None) -> str:
        """Why it is not robust: passed k of K, the perturbation that broke it worst (most
        criteria failed, then the lowest seed) and its figures against the thresholds;
        for runs that stopped once it could no longer pass (fewer than ``k``), the runs
        made."""
        worst = max(self.failures, key=lambda f: (len(f.verdict), -f.seed))
        made = f"{self.runs} perturbed runs"
        if k is not None and self.runs < k:
            made = (
                f"the {self.runs} perturbed runs made before it could not pass (the "
                "worst-looking first)"
            )
        return (
            f"{self.behavior} is not robust: passed {self.passed} of {made} "
            f"(needs {required}); {worst.perturbation} broke it: {worst.why}"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "behavior": self.behavior,
            "ability": self.ability,
            **({"loop": self.loop} if self.loop else {}),
            "passed": self.passed,
            "runs": self.runs,
            "robust": self.robust,
            "worst": {k: dict(v) for k, v in self.worst.items()},
            "failures": [f.to_dict() for f in self.failures],
            "figures": [r.to_dict() for r in self.figures],
        }


@dataclass(frozen=True)
class RobustRuns:
    """A design's perturbed runs (``verified.robust``): ``k`` perturbations, each behaviour
    must pass ``required`` (``share`` x K), the perturbations' summaries, each behaviour's
    runs, the table they were drawn from; the physics they ran at (``physics``, where it
    was chosen: :func:`synth.verification.robust.physics`), what they show (``shows``)
    the gains the loop tried and chose (``gains``, :mod:`synth.verification.gains`), the
    paces it tried and chose (``paces``, :mod:`synth.verification.hold`) and,
    for runs that stopped once their verdict was known, how (``stopped``:
    :func:`synth.verification.runs.verify_robust`'s ``decisive``)."""

    k: int
    required: int
    share: float
    perturbations: tuple[Mapping[str, Any], ...]
    behaviors: tuple[BehaviorRuns, ...]
    table: Mapping[str, Any]
    physics: Mapping[str, Any] | None = None
    shows: Mapping[str, Any] | None = None
    gains: Mapping[str, Any] | None = None
    paces: Mapping[str, Any] | None = None
    stopped: Mapping[str, Any] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)
    #: the runs as made (``verify_robust``'s ``made``: a later call on the same robot takes
    #: them rather than making them again); not recorded
    made: Mapping[tuple, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def of(cls, d: Mapping[str, Any]) -> RobustRuns:
        """A recorded ``verified.robust`` (missing counts: those of its behaviours)."""
        known = {"k", "required", "share", "perturbations", "behaviors", "table", "physics"}
        known |= {"shows", "gains", "paces", "stopped"}
        k = int(d["k"])
        return cls(
            k,
            int(d.get("required", k)),
            float(d.get("share", 1.0)),
            tuple(d.get("perturbations") or ()),
            tuple(BehaviorRuns.of(b) for b in d.get("behaviors") or ()),
            dict(d.get("table") or {}),
            d.get("physics"),
            d.get("shows"),
            d.get("gains"),
            d.get("paces"),
            d.get("stopped"),
            {key: v for key, v in d.items() if key not in known},
        )

    def not_robust(self) -> list[BehaviorRuns]:
        """The behaviours that are not robust, the worst first: the smallest share of its
        runs passed, then name order (a refusal names the first that serves a demand)."""
        bad = [b for b in self.behaviors if not b.robust]
        return sorted(bad, key=lambda b: (b.share, b.behavior))

    def failing_runs(self) -> list[Run]:
        """The failed runs of the behaviours that are not robust."""
        return [r for b in self.behaviors if not b.robust for r in b.failed_runs()]

    def behavior(self, name: str) -> BehaviorRuns | None:
        return next((b for b in self.behaviors if b.behavior == name), None)

    def with_behaviors(self, more: Sequence[BehaviorRuns]) -> RobustRuns:
        """These runs with ``more`` behaviours' after them (the same table and seeds)."""
        return replace(self, behaviors=(*self.behaviors, *more))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "k": self.k,
            "required": self.required,
            "share": self.share,
            "perturbations": [dict(p) for p in self.perturbations],
            "behaviors": [b.to_dict() for b in self.behaviors],
            "table": dict(self.table),
        }
        if self.physics is not None:
            out["physics"] = dict(self.physics)
        if self.shows is not None:
            out["shows"] = dict(self.shows)
        if self.gains is not None:
            out["gains"] = dict(self.gains)
        if self.paces is not None:
            out["paces"] = dict(self.paces)
        if self.stopped is not None:
            out["stopped"] = dict(self.stopped)
        return out | dict(self.extra)
