"""Behaviours a closed loop can steer (:mod:`program.sensing`): a :class:`BehaviorSpec`
that also says, as data, which of its parameters play the loop's roles.

Roles (``SteerableSpec.steer``, role -> parameter name):

- ``speed``: how fast it goes (its parameter's unit says in what: m/s for wheels and
  legs, Hz of the waves for a snake);
- ``turn``: how it turns while it goes: a yaw rate (unit ``rad/s``), a curvature
  (``rad/m``), or a bias without a unit (a snake's wave gradient, -1..1, whose effect on
  the heading the loop learns from what it measures);
- ``seconds``: how long one control period runs (a behaviour that runs any short time,
  from where it is: wheels), or ``steps``: how many whole gait cycles one period is (a
  gait that starts and ends at rest: legs, a snake's waves);
- ``direction`` (optional): the direction of travel, rad from forward (a behaviour that
  also goes sideways without turning: legs);
- ``turn_from`` (optional): the turn the behaviour rolls on from, in the turn's unit (a
  steered drive's steering, which turns only so fast: the loop passes the turn the last
  period ended on, its plan's ``info["turn_end"]``).

``fixed``: parameters held at these values in every period (e.g. no ramp). The roles
are data of the controller's behaviour; no loop names a behaviour or a robot type.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from gaits.base import BehaviorSpec

__all__ = ["STEER_ROLES", "SteerableSpec"]

#: The roles a steerable behaviour's parameters may play.
STEER_ROLES = ("speed", "turn", "seconds", "steps", "direction", "turn_from")


@dataclass(frozen=True)
class SteerableSpec(BehaviorSpec):
    """A behaviour a sensing loop can steer: ``steer`` (role, parameter) pairs (roles of
    :data:`STEER_ROLES`: ``speed``, ``turn`` and one of ``seconds`` / ``steps``) and
    ``fixed`` (parameter, value) pairs held in every control period."""

    steer: tuple[tuple[str, str], ...] = ()
    fixed: tuple[tuple[str, object], ...] = ()

    def __post_init__(self) -> None:
        roles = dict(self.steer)
        names = {p.name for p in self.params}
        bad = [r for r in roles if r not in STEER_ROLES]
        if (
            bad
            or not {"speed", "turn"} <= set(roles)
            or len({"seconds", "steps"} & set(roles)) != 1
        ):
            raise ValueError(
                f"behaviour {self.name!r}: steering roles {sorted(roles)} are not valid"
            )
        missing = sorted(set(roles.values()) - names)
        if missing:
            raise ValueError(f"behaviour {self.name!r}: no parameter {missing[0]!r} to steer")

    @property
    def roles(self) -> Mapping[str, str]:
        """role -> parameter name."""
        return dict(self.steer)
