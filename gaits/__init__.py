"""Behaviour (gait) generators: a controller per design.

``controller_for(geometry)`` picks the controller of the design's structure (what its body
plan contains: ``kinematics.assemble.structure_of``), never by its type's name; the modules
are imported on demand.
"""

from __future__ import annotations

import dataclasses
import inspect
from importlib import import_module

from gaits.base import Controller, DesignGeometry, _plain
from kinematics.assemble import structure_of
from kinematics.partkinds import in_use
from kinematics.templates import plan_of

#: structure -> (module, controller class)
CONTROLLERS: dict[str, tuple[str, str]] = {
    "wheeled": ("gaits.wheeled", "WheeledController"),
    "steered": ("gaits.steered", "SteeredController"),
    "module_chain": ("gaits.snake", "SnakeController"),
    "serial_arm": ("gaits.manipulator", "ManipulatorController"),
    "multiped": ("gaits.legged", "LeggedController"),
    "biped": ("gaits.humanoid", "HumanoidController"),
    "mobile_manipulator": ("gaits.compose", "ComposedController"),
    "legged_manipulator": ("gaits.compose", "ComposedController"),
    "multi_arm": ("gaits.compose", "ComposedController"),
}


def structure(geometry: DesignGeometry) -> str:
    """The structure of a design (``kinematics.assemble.structure_of`` of its body plan)."""

    return structure_of(plan_of(geometry.template), in_use())


def controller_for(geometry: DesignGeometry, **options: object) -> Controller:
    """The controller of a sized design (ValueError when its template has none).

    ``options`` that the controller's constructor accepts are passed on (e.g.
    ``base_position``: where a fixed base stands in the world); others are ignored.
    """
    kind = structure(geometry)
    entry = CONTROLLERS.get(kind)
    if entry is None:
        raise ValueError(
            f"no controller for {geometry.template}: its structure is {kind or 'none known'} "
            f"(controllers serve: {', '.join(sorted(CONTROLLERS))})"
        )
    module, name = entry
    cls = getattr(import_module(module), name)
    accepted = inspect.signature(cls).parameters
    given = {k: v for k, v in sorted(options.items()) if k in accepted}
    controller = cls(geometry, **given)
    # the plans' key: what the controller reads of the geometry, and the options given
    read = {k: v for k, v in dataclasses.asdict(geometry).items() if k not in cls.PLAN_IGNORES}
    key = _plain({"geometry": read, "options": given})
    controller.identity = None if key is None else (module, name, key)
    return controller
