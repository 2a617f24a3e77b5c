"""Behaviour (gait) generators for each robot type: a controller per design.

``controller_for(geometry)`` picks the controller of the design's kinematic template; the
modules are imported on demand.
"""

from __future__ import annotations

import dataclasses
import inspect
from importlib import import_module

from gaits.base import Controller, DesignGeometry, _plain

#: template -> (module, controller class)
CONTROLLERS: dict[str, tuple[str, str]] = {
    "DifferentialDriveRobot": ("gaits.wheeled", "WheeledController"),
    "SkidSteerRobot": ("gaits.wheeled", "WheeledController"),
    "SnakeRobot": ("gaits.snake", "SnakeController"),
    "Manipulator3DOF": ("gaits.manipulator", "ManipulatorController"),
    "Manipulator6DOF": ("gaits.manipulator", "ManipulatorController"),
    "HexapodRobot": ("gaits.legged", "LeggedController"),
    "QuadrupedRobot": ("gaits.legged", "LeggedController"),
    "HumanoidRobot": ("gaits.humanoid", "HumanoidController"),
}


def controller_for(geometry: DesignGeometry, **options: object) -> Controller:
    """The controller of a sized design (ValueError when its template has none).

    ``options`` that the controller's constructor accepts are passed on (e.g.
    ``base_position``: where a fixed base stands in the world); others are ignored.
    """
    entry = CONTROLLERS.get(geometry.template)
    if entry is None:
        raise ValueError(
            f"no controller for {geometry.template} (controllers: {', '.join(sorted(CONTROLLERS))})"
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
