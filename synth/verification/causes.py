"""One protocol for a cause of failed perturbed runs: what the strengthening loop
(:mod:`synth.verification.loop`) asks each cause it knows.

A perturbed run that failed with an actuator at its limit is answered by the loop itself
(a stronger actuator: a torque floor for the next sizing). Every other failure is put to
the causes, each an object that measures, by replays of the round's failed runs with its
part of the perturbation changed, whether it explains them, and says what answers it
(:class:`Remedy`):

- the joints' play (:class:`synth.verification.play.Play`): servos with less play for the
  joints whose play breaks the runs (a new sizing);
- the wheels' servos (:class:`synth.verification.wheels.Wheels`): stiffer wheel servos (a
  new sizing);
- a closed loop's gains (:class:`synth.verification.gains.Gains`): the loop's gains
  scaled (no new sizing: the plan's ``info["feedback"]`` changes);
- the servos' command hold (:class:`synth.verification.hold.Hold`): a slower pace of the
  behaviours it breaks (no new sizing: the record's ``paces`` change), where the request
  left the speed to the design.

Each cause also words what it measured and tried for a refusal (:meth:`Cause.note`) and
gives what the record keeps of what it changed (:meth:`Cause.record`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import synth.verification.runs

if TYPE_CHECKING:
    from adron.catalog import Catalog
    from synth.verification.results import RobustRuns
    from synth.verification.source import Bundle


@dataclass
class Round:
    """What a cause reads of one round of the loop: its number (1: the first sizing), the
    design's record and its joints' actuators (``models``: joint -> model), the catalog,
    the round's perturbed runs (``robust``) and bundle (``bundle()``: built on first use),
    the actuator models each joint may no longer have (``excluded``), a sizer to try a
    structure with other exclusions (``sizer``: a ``synth.sizing.structure.StructureDesigner``
    with the round's torque floors, or None), the gains chosen for closed loops so far
    (``gains``: behaviour -> scale) and the behaviours that serve a demanded ability
    (``demanded``), and the paces chosen so far (``paces``: behaviour -> pace)."""

    number: int
    record: Mapping[str, Any]
    models: Mapping[str, str]
    catalog: Catalog
    robust: RobustRuns | None
    bundle_of: Any  # () -> Bundle
    excluded: Mapping[str, frozenset[str]] = field(default_factory=dict)
    sizer: Any = None
    gains: Mapping[str, float] = field(default_factory=dict)
    demanded: frozenset[str] = frozenset()
    paces: Mapping[str, float] = field(default_factory=dict)

    def bundle(self) -> Bundle:
        return self.bundle_of()


@dataclass(frozen=True)
class Remedy:
    """What answers a cause: sizings to try in turn (``sizings``: each joint -> the
    actuator models it may no longer have; the first that sizes is taken), and/or gains
    for closed loops (``gains``: behaviour -> the scale of its loop's gains, no sizing),
    and/or paces (``paces``: behaviour -> the value of its pace parameter, no sizing)."""

    sizings: tuple[Mapping[str, frozenset[str]], ...] = ()
    gains: Mapping[str, float] | None = None
    paces: Mapping[str, float] | None = None

    def __bool__(self) -> bool:
        return bool(self.sizings) or bool(self.gains) or bool(self.paces)


class Cause(Protocol):
    """A cause of failed perturbed runs (module docstring)."""

    #: the cause's name in the record and in messages
    name: str

    def explains(self, now: Round) -> Remedy | None:
        """Measured by replays of ``now``'s failed perturbed runs: what answers them when
        this cause explains them, else None (it does not, or nothing answers it)."""
        ...

    def taken(self, now: Round, sizing: Mapping[str, frozenset[str]]) -> None:
        """The loop sized the design with ``sizing`` of this cause's remedy: remember what
        changed for the record."""
        ...

    def note(self, behavior: str, final: int) -> str:
        """What a refusal of ``behavior`` adds: what this cause measured and tried on the
        design as it stands (round ``final``); "" when nothing."""
        ...

    def record(self, models: Mapping[str, str]) -> dict | None:
        """What ``design.json`` keeps of what this cause changed (``models``: each joint's
        actuator in the end); None when it changed nothing."""
        ...


def with_record(bundle: Bundle, key: str, values: Mapping[str, float]) -> Bundle:
    """``bundle`` whose record's ``key`` (``feedback_gains``, ``paces``: behaviour -> value)
    is ``values``: what a cause that changes no sizing tries."""
    import json

    record = dict(bundle.record)
    record[key] = dict(sorted(values.items()))
    return bundle.with_files({"design.json": json.dumps(record)})


def trial_passes(
    trial: Bundle, robust: RobustRuns, behavior: str, entry: dict
) -> tuple[bool, dict]:
    """Does ``behavior`` of ``trial`` (a bundle with one cause's change) pass nominally and
    in every perturbed run of ``robust``'s table (the same seeds; the worst-looking first,
    stopping at the first run that fails)? With ``entry`` completed by what it gave: its
    ``nominal`` verdict ("ok" or the failed criteria, or why it does not plan), ``passed``
    of ``runs`` made ``of`` K, and the ``failed_seed``."""

    try:
        nominal = synth.verification.runs.verify_nominal(trial, [behavior])[0]
    except ValueError as e:  # (the change does not plan on the nominal model)
        return False, entry | {"nominal": [str(e)], "passed": 0, "runs": 0}
    if not nominal.ok:
        return False, entry | {"nominal": nominal.verdict, "passed": 0, "runs": 0}
    runs = synth.verification.runs.verify_robust(
        trial, robust.k, robust.table, [behavior], sensing=False, decisive={behavior}
    )
    got = runs.behaviors[0]
    failed = [f.seed for f in got.failures]
    entry = entry | {"nominal": "ok", "passed": got.passed, "runs": got.runs, "of": robust.k}
    entry |= {"failed_seed": failed[0]} if failed else {}
    return got.passed == got.runs == robust.k, entry
