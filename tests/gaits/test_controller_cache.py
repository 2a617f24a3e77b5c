"""Plans are reused within a process only for the same controller, behaviour and
parameters (gaits.base: a design plans each behaviour to size, bundle and simulate it)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gaits import controller_for
from gaits.base import DesignGeometry


def _geometry(**kw) -> DesignGeometry:
    g = DesignGeometry(
        robot_type="DifferentialDriveRobot",
        template="DifferentialDriveRobot",
        lengths={},
        modules=2,
        wheel_radius=0.04,
        params={"payload": 0.5},
        abilities=("driving",),
        joint_speed={"left_wheel": 6.0, "right_wheel": 6.0},
        mass_kg=1.0,
        joint_torque={"left_wheel": 0.5, "right_wheel": 0.5},
    )
    return dataclasses.replace(g, **kw)


def test_the_same_controller_reuses_its_plan_read_only() -> None:
    a = controller_for(_geometry()).run("driving", v=0.1)
    b = controller_for(_geometry()).run("driving", v=0.1)
    assert a is b
    with pytest.raises(ValueError):
        a.positions[0, 0] = 1.0


def test_another_parameter_or_geometry_plans_again() -> None:
    a = controller_for(_geometry()).run("driving", v=0.1)
    assert controller_for(_geometry()).run("driving", v=0.12) is not a
    other = controller_for(_geometry(wheel_radius=0.05)).run("driving", v=0.1)
    assert other is not a and not np.array_equal(other.velocities, a.velocities)


def test_a_controller_given_a_function_never_shares_its_plans() -> None:
    c = controller_for(_geometry(), base_position=(0.0, 0.0, 0.1))
    assert c.identity is not None  # plain data identifies it
    c = controller_for(_geometry())
    c.identity = None  # e.g. given a gravity function: not plain data
    assert c.run("driving", v=0.1) is not c.run("driving", v=0.1)
