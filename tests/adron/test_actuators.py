"""Actuator assignment by clingo (asp/actuators.lp through
synth.reasoning.solver.ActuatorAssigner)."""

from __future__ import annotations

import pytest

from adron.catalog import catalog_facts
from adron.errors import InputError
from synth.sizing.assign import ActuatorAssigner, JointSlot

POS = ("SG90", "MG996R", "DS3218")


def legs(n: int) -> list[JointSlot]:
    return [
        JointSlot(f"leg{i}_{p}", f"leg_{p}", "PositionServomotor")
        for i in range(n)
        for p in ("coxa", "femur", "tibia")
    ]


def assigner(kb, catalog, joints, other=2, robot="HexapodRobot", objective=("mass", "cost")):
    return ActuatorAssigner(kb, catalog_facts(catalog), robot, joints, other, objective)


def test_models_serve_the_ontology_class_of_each_joint(kb, catalog) -> None:
    joints = [
        JointSlot("wheel_l", "wheel", "ContinuousRotationServomotor"),
        JointSlot("grip", "gripper", "GripperServomotor"),
        JointSlot("elbow", "", "PositionServomotor"),
    ]
    a = assigner(kb, catalog, joints, robot="DifferentialDriveRobot")
    cont = {x.model for x in catalog.actuators_of("ContinuousRotationServomotor")}
    pos = {x.model for x in catalog.actuators_of("PositionServomotor")}
    assert set(a.serving["wheel_l"]) == cont
    assert set(a.serving["grip"]) == pos  # a GripperServomotor is a PositionServomotor
    assert set(a.serving["elbow"]) == pos


def test_best_is_lightest_capable_and_alike_legs_get_alike_models(kb, catalog) -> None:
    joints = legs(6)
    a = assigner(kb, catalog, joints)
    capable = {j.name: POS for j in joints}
    capable["leg3_femur"] = ("MG996R", "DS3218")  # one femur needs more torque
    best = a.best(capable)
    femurs = {m for j, m in best.models if j.endswith("femur")}
    assert femurs == {"MG996R"}  # the whole group follows the most demanding leg
    assert {m for j, m in best.models if not j.endswith("femur")} == {"SG90"}
    free = a.best(capable, symmetric=False)
    assert {m for j, m in free.models if j.endswith("femur")} == {"SG90", "MG996R"}
    assert free.cost < best.cost


def test_ranked_is_in_objective_order_and_complete_count_is_the_product(kb, catalog) -> None:
    joints = legs(2)
    a = assigner(kb, catalog, joints)
    capable = {j.name: POS for j in joints}
    capable["leg0_tibia"] = ("DS3218",)
    everything = a.all(capable, symmetric=True)
    assert len(everything) == 3 * 3 * 1  # coxa x femur x tibia groups
    assert len(a.all(capable, symmetric=False)) == 3 * 3 * 3 * 3 * 1 * 3
    ranked = a.ranked(capable, True, 9)
    assert [r.cost for r in ranked] == sorted(r.cost for r in ranked)
    assert {r.models for r in ranked} == {e.models for e in everything}
    assert a.ranked(capable, True, 1)[0] == ranked[0]  # blocking is undone between queries


def test_objective_order_is_configurable(kb, catalog) -> None:
    joints = [JointSlot("j", "", "PositionServomotor")]
    capable = {"j": ("MG996R", "DS3218")}
    by_mass = assigner(kb, catalog, joints).best(capable)
    by_cost = assigner(kb, catalog, joints, objective=("cost", "mass")).best(capable)
    mass = {a.model: a.mass_kg for a in catalog.actuators}
    cost = {a.model: a.cost for a in catalog.actuators}
    assert mass[by_mass.model_of("j")] == min(mass["MG996R"], mass["DS3218"])
    assert cost[by_cost.model_of("j")] == min(cost["MG996R"], cost["DS3218"])
    with pytest.raises(InputError):
        assigner(kb, catalog, joints, objective=("mass", "speed"))


def test_no_capable_model_or_too_many_modules_has_no_assignment(kb, catalog) -> None:
    joints = legs(2)
    a = assigner(kb, catalog, joints)
    capable = {j.name: POS for j in joints}
    capable["leg1_femur"] = ()
    assert a.best(capable) is None
    assert assigner(kb, catalog, legs(8)).best({j.name: POS for j in legs(8)}) is None  # 26 > 24
