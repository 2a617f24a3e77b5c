"""The structure generator (issue 3): every base configuration sized with its defaults
meets every limit; the paper's Fig. 8 behaviour; infeasible requests name the limit."""

from __future__ import annotations

import json
import re

import pytest

from adron.errors import InfeasibleError
from synth.sizing.structure import (
    StructureDesigner,
    _TorqueModel,
    alternatives,
    design_structure,
    speed_at,
)


@pytest.fixture(scope="module")
def defaults(kb, bases, catalog):
    return {t: design_structure(kb, c, catalog, {}) for t, c in bases.items()}


def test_every_base_configuration_designs_with_its_defaults(defaults, bases, catalog) -> None:
    assert set(defaults) == set(bases)  # one per base configuration of the ontology
    by_model = {a.model: a for a in catalog.actuators}
    for t, s in defaults.items():
        assert 1 <= s.iterations < 50, t
        for j in s.joints:
            a = by_model[j.actuator]
            assert j.usable_torque_Nm >= j.required_torque_Nm, (t, j.name)
            assert j.usable_torque_Nm == pytest.approx(
                a.stall_torque_Nm / catalog.design.torque_safety_factor
            )
            # the behaviours' torque and speed peaks need not coincide: each operating
            # point is met (the hand cases' one at the family's speed among them)
            assert j.operating_points, (t, j.name)
            for torque, speed in j.operating_points:
                assert speed_at(a, torque) >= speed * (1 - 1e-12), (t, j.name)
            assert max(w for _, w in j.operating_points) == j.required_speed_rad_s
            if j.hold:  # the second operating point (gripping, turning in place)
                assert j.usable_torque_Nm >= j.hold_torque_Nm, (t, j.name)
                assert speed_at(a, j.hold_torque_Nm) >= j.hold_speed_rad_s, (t, j.name)
        for link in s.links:
            assert link.tip_deflection_m <= link.max_deflection_m * (1 + 1e-9), (t, link.name)
            assert link.max_stress_Pa <= link.allowed_stress_Pa * (1 + 1e-9), (t, link.name)
            assert link.r_outer_m <= catalog.passive.max_outer_radius_m + 1e-12
            assert link.r_outer_m - link.r_inner_m >= catalog.passive.min_wall_m - 1e-12
            assert link.mass_kg == pytest.approx(
                link.part_volume_m3 * catalog.material.density_kg_m3
            )
            assert link.part_volume_m3 > link.volume_m3  # the tube plus faces and fillets
        active = sum(m.count for m in s.modules)
        assert active == bases[t].active_total <= bases[t].module_limit == 24
        assert len(s.joints) == active - sum(
            m.count for m in s.modules if "Servomotor" not in m.kind
        )


def test_i2c_addresses_are_unique_and_the_main_module_is_the_master(defaults, catalog) -> None:
    for t, s in defaults.items():
        addrs = [a for m in s.modules for a in m.i2c_addresses]
        assert len(addrs) == len(set(addrs)) == sum(m.count for m in s.modules) - 1, t
        assert min(addrs) == catalog.bus.first_address
        main = [m for m in s.modules if m.kind == "MainModule"]
        assert len(main) == 1 and main[0].i2c_addresses == ()


def test_mass_cost_power_and_metrics_add_up(defaults, bases, catalog) -> None:
    price = {a.model: a.cost for a in catalog.actuators} | {
        m.model: m.cost for m in catalog.modules
    }
    for t, s in defaults.items():
        assert s.cost == pytest.approx(sum(price[m.model] * m.count for m in s.modules)), t
        assert s.mass_kg == pytest.approx(s.template.model.total_mass)
        modules_mass = sum(
            m.count
            * next(x.mass_kg for x in (*catalog.actuators, *catalog.modules) if x.model == m.model)
            for m in s.modules
        )
        assert s.mass_kg > modules_mass  # plus printed parts and the payload
        assert 0 < s.power.peak_current_A <= s.power.stall_current_A
        assert s.power.ok == (s.power.peak_current_A <= s.power.battery_max_current_A)
        assert s.metrics.hierarchy == 2  # robot -> structural parts -> modules
        passive = sum(n for _, n in bases[t].passive)  # links, feet, wheels, plates...
        assert s.metrics.modularity == sum(m.count for m in s.modules) + passive


def test_fig8_a_larger_workspace_gets_longer_links_and_stronger_actuators(
    kb, bases, catalog
) -> None:
    small = design_structure(
        kb, bases["Manipulator3DOF"], catalog, {"reach": 0.16, "payload": 0.15}
    )
    large = design_structure(
        kb, bases["Manipulator3DOF"], catalog, {"reach": 0.32, "payload": 0.15}
    )
    stall = {a.model: a.stall_torque_Nm for a in catalog.actuators}
    for name in ("L2", "L3"):
        assert large.lengths[name] > small.lengths[name]
    weak = [stall[j.actuator] for j in small.joints]
    strong = [stall[j.actuator] for j in large.joints]
    assert all(b >= a for a, b in zip(weak, strong, strict=True))
    assert sum(strong) > sum(weak)


def test_a_heavier_payload_never_gets_weaker_actuators(kb, bases, catalog) -> None:
    stall = {a.model: a.stall_torque_Nm for a in catalog.actuators}
    last = None
    for payload in (0.0, 0.05, 0.1, 0.15):
        s = design_structure(kb, bases["Manipulator6DOF"], catalog, {"payload": payload})
        now = [stall[j.actuator] for j in s.joints]
        if last is not None:
            assert all(b >= a for a, b in zip(last, now, strict=True))
        last = now


def test_an_impossible_payload_names_the_joint_and_the_largest_payload(kb, bases, catalog) -> None:
    with pytest.raises(InfeasibleError) as e:
        design_structure(kb, bases["Manipulator3DOF"], catalog, {"reach": 0.3, "payload": 5.0})
    msg = str(e.value)
    assert "shoulder_pitch" in msg and "strongest actuator" in msg
    best = float(msg.rsplit("is ", 1)[1].split(" kg")[0])
    assert 0 < best < 5.0
    ok = design_structure(
        kb, bases["Manipulator3DOF"], catalog, {"reach": 0.3, "payload": best * 0.99}
    )
    assert ok.params["payload"] == pytest.approx(best * 0.99)
    with pytest.raises(InfeasibleError):
        design_structure(
            kb, bases["Manipulator3DOF"], catalog, {"reach": 0.3, "payload": best * 1.05}
        )


def test_a_reach_beyond_the_printable_links_is_infeasible(kb, bases, catalog) -> None:
    with pytest.raises(InfeasibleError, match="longest printable link"):
        design_structure(kb, bases["Manipulator3DOF"], catalog, {"reach": 0.6})


def test_wheels_grow_with_speed_until_the_largest_printable(kb, bases, catalog) -> None:
    slow = design_structure(kb, bases["SkidSteerRobot"], catalog, {"speed": 0.1})
    fast = design_structure(kb, bases["SkidSteerRobot"], catalog, {"speed": 0.3})
    assert fast.wheel_radius_m >= slow.wheel_radius_m
    with pytest.raises(InfeasibleError, match="printable wheel"):
        design_structure(kb, bases["SkidSteerRobot"], catalog, {"speed": 2.0})


def test_hexapod_legs_follow_the_obstacle_height(kb, bases, catalog) -> None:
    low = design_structure(kb, bases["HexapodRobot"], catalog, {"obstacle_height": 0.02})
    high = design_structure(kb, bases["HexapodRobot"], catalog, {"obstacle_height": 0.05})
    for name in ("femur", "tibia", "La1"):
        assert high.lengths[name] > low.lengths[name]
    assert high.mass_kg > low.mass_kg


def test_exact_count_matches_clingo_enumeration(kb, bases, catalog) -> None:
    for symmetric in (True, False):
        sd = StructureDesigner(kb, bases["Manipulator3DOF"], catalog, {}, symmetric)
        sd.run()
        capable = sd.capable(sd.requirements)
        everything = sd.assigner.all(capable, symmetric)
        assert sd.assigner.count(capable, symmetric) == len(everything) > 1
        alts = alternatives(sd, 5, pareto=True)
        assert alts.count == len(everything) == alts.capable  # too light to move a torque
        masses = [(a.mass_kg, a.cost) for a in alts.ranked]
        assert masses == sorted(masses)
        front = alts.pareto
        for p in front:  # nothing dominates a point of the front
            assert not any(
                a.mass_kg <= p.mass_kg
                and a.cost <= p.cost
                and (a.mass_kg, a.cost) != (p.mass_kg, p.cost)
                for a in front
            )


def test_capable_counts_the_encoding_and_feasible_the_masses(kb, bases, catalog) -> None:
    """The hexapod's capable assignments (clingo's answers of the encoding) include some
    whose own actuators' masses overload a joint: feasible < capable, each brute-forced."""
    sd = StructureDesigner(kb, bases["HexapodRobot"], catalog, {})
    sd.run()
    capable = sd.capable(sd.requirements)
    everything = sd.assigner.all(capable, True)
    alts = alternatives(sd, len(everything))
    model = _TorqueModel(sd)
    feasible = [a for a in everything if model.feasible(dict(a.models))]
    assert alts.capable == len(everything)
    assert alts.exact and alts.count == len(feasible) < alts.capable
    assert len(alts.ranked) == len(feasible)


def test_symmetry_gives_alike_legs_alike_actuators(defaults) -> None:
    hexa = defaults["HexapodRobot"]
    for group in ("leg_coxa", "leg_femur", "leg_tibia"):
        assert len({j.actuator for j in hexa.joints if j.group == group}) == 1


def test_design_json_has_the_structural_fields(cli, tmp_path) -> None:
    r = cli(
        "design",
        "pick-and-place",
        "--param",
        "object_shape=cylinder",
        "--param",
        "reach=25cm",
        "--param",
        "payload=150g",
        "--json",
    )
    assert r.code == 0, r.err
    d = json.loads(r.out)
    for key in ("links", "joints", "modules", "mass_kg", "cost", "power", "metrics", "iterations"):
        assert key in d, key
    link = d["links"][0]
    assert set(link) >= {
        "name",
        "length_m",
        "r_outer_m",
        "r_inner_m",
        "volume_m3",
        "mass_kg",
        "tip_deflection_m",
        "max_deflection_m",
        "max_stress_Pa",
        "allowed_stress_Pa",
    }
    joint = d["joints"][0]
    assert set(joint) >= {
        "name",
        "actuator",
        "required_torque_Nm",
        "actuator_torque_Nm",
        "required_speed_rad_s",
    }
    assert all({"model", "count", "bus_addresses"} <= set(m) for m in d["modules"])
    assert d["params"]["reach"] == 0.25 and d["params"]["payload"] == 0.15


def test_infeasible_design_exits_1_and_writes_nothing(cli, tmp_path) -> None:
    out = tmp_path / "bundle"
    r = cli(
        "design",
        "pick-and-place",
        "--param",
        "object_shape=cylinder",
        "--param",
        "payload=5kg",
        "--out",
        str(out),
    )
    assert r.code == 1
    assert "largest payload" in r.err and "shoulder_pitch" in r.err
    assert not out.exists() and list(tmp_path.iterdir()) == []
    r = cli(
        "design",
        "pick-and-place",
        "--param",
        "object_shape=cylinder",
        "--param",
        "payload=5kg",
        "--json",
    )
    assert r.code == 1 and json.loads(r.out)["status"] == "infeasible"


@pytest.mark.parametrize(
    ("param", "message"),
    [
        ("reach=30kg", "expected a length"),
        ("payload=2", "expected a mass"),
        ("reech=30cm", "did you mean: reach"),
        ("payload=-1kg", "payload"),
    ],
)
def test_bad_parameters_exit_2(cli, param, message) -> None:
    r = cli("design", "pick-and-place", "--param", "object_shape=box", "--param", param)
    assert r.code == 2 and message in r.err and "Traceback" not in r.err


def test_a_parameter_the_type_does_not_use_is_reported(cli) -> None:
    r = cli("design", "rolling", "--param", "reach=30cm", "--json")
    assert r.code == 0
    assert json.loads(r.out)["ignored_params"] == ["reach"]


def test_differential_drive_gives_way_to_skid_steer_above_its_payload_limit(cli) -> None:
    small = json.loads(cli("design", "driving", "--param", "payload=0.5kg", "--json").out)
    large = json.loads(cli("design", "driving", "--param", "payload=2kg", "--json").out)
    assert small["robot_type"] == "DifferentialDriveRobot"
    assert large["robot_type"] == "SkidSteerRobot"
    assert "DifferentialDriveRobot is not built for payload above 1 kg" in large["note"]


def test_enumerate_lists_sized_candidates_with_assignments(cli) -> None:
    r = cli(
        "enumerate",
        "pick-and-place",
        "--param",
        "object_shape=cylinder",
        "--json",
        "--assignments",
        "2",
        "--pareto",
    )
    assert r.code == 0, r.err
    lines = [json.loads(x) for x in r.out.splitlines()]
    cand = lines[0]
    assert cand["robot_type"] == "Manipulator3DOF"
    a = cand["assignments"]
    assert a["count"] >= len(a["ranked"]) == 2 and a["symmetric"] is True
    assert a["pareto"] and cand["structure"]["mass_kg"] > 0
    assert lines[-1] == {
        "type": "summary",
        "status": "enumerated",
        "count": 1,
        "shown": 1,
        "conflict": [],
        "excluded": {},
    }


def test_every_counted_assignment_is_feasible_with_its_own_masses(kb, bases, catalog) -> None:
    """Re-derive feasibility of each assignment from scratch (template with its masses,
    RNEA, the capability rule) and compare with the count and the ranked list."""
    from dataclasses import replace

    sd = StructureDesigner(kb, bases["Manipulator3DOF"], catalog, {"payload": 0.28})
    sd.run()
    sizing, tubes, act_mass = sd.converged
    superset = sd.assigner.all(sd.capable(sd.requirements), True)

    def really_feasible(models: dict[str, str]) -> bool:
        masses = {s.group: catalog_mass[models[s.name]] for s in sd.slots}
        tp = sd._params(sizing, tubes, {**act_mass, **masses}, sd.modules)
        req, _ = sd._requirements(replace(tp), sizing)
        return all(models[s.name] in sd.capable(req)[s.name] for s in sd.slots)

    catalog_mass = {a.model: a.mass_kg for a in catalog.actuators}
    feasible = [a for a in superset if really_feasible(dict(a.models))]
    alts = alternatives(sd, 50)
    assert alts.exact and alts.count == len(feasible) < len(superset)
    assert {x.models for x in alts.ranked} == {a.models for a in feasible}


def test_every_snake_gait_designs_with_defaults(designer, kb, catalog) -> None:
    """The lifted segment follows the gaits asked for (the ontology's liftedModuleShare),
    so even the 14-module circular-path snake is buildable with the default catalog."""
    from synth.reasoning.conceptual import Request

    for gait in ("rolling", "rectilinear", "sidewinding", "rotating", "circular-path"):
        cand = designer.step(Request(abilities=(gait,))).chosen
        s = design_structure(kb, cand, catalog, {})
        assert len(s.joints) == cand.dof


def test_a_refusal_names_the_largest_speed_that_works(cli) -> None:
    r = cli("design", "driving", "--param", "speed=0.5m/s", "--no-verify", "--json")
    assert r.code == 1
    m = re.search(r"the largest speed that works here is (\d+\.\d+) m/s", r.err)
    assert m, r.err
    best = m.group(1)
    assert 0.05 < float(best) < 0.5
    ok = cli("design", "driving", "--param", f"speed={best}m/s", "--no-verify", "--json")
    assert ok.code == 0, ok.err
