"""adron.catalog: the shipped catalog, its ASP facts, and validation of a user's catalog."""

from __future__ import annotations

import dataclasses
import json
import math
from importlib.resources import files
from pathlib import Path

import clingo
import pytest

from adron.catalog import (
    BATTERY_CLASS,
    MAIN_CLASS,
    TORQUE_CLASSES,
    Bus,
    Catalog,
    catalog_facts,
    load_catalog,
    parse_catalog,
)
from adron.errors import InputError
from adron.kb import KnowledgeBase

SHIPPED = (files("adron") / "catalog.toml").read_text(encoding="utf-8")
KGF_CM = 9.80665 * 0.01  # N*m
SERVO_CLASSES = ("PositionServomotor", "ContinuousRotationServomotor")
SENSOR_CLASSES = (
    "ContactSensorModule",
    "UltrasonicSensorModule",
    "InfraredSensorModule",
    "IMUSensorModule",
)


@pytest.fixture(scope="module")
def cat() -> Catalog:
    return load_catalog()


# ---- The shipped catalog -----------------------------------------------------------------


def test_six_actuators_two_classes_three_torque_classes(cat: Catalog) -> None:
    assert len(cat.actuators) == 6
    pairs = sorted((a.ontology_class, a.torque_class) for a in cat.actuators)
    assert pairs == sorted((c, t) for c in SERVO_CLASSES for t in TORQUE_CLASSES)


@pytest.mark.parametrize("cls", SERVO_CLASSES)
def test_torque_classes_are_ordered(cat: Catalog, cls: str) -> None:
    by_class = {a.torque_class: a for a in cat.actuators_of(cls)}
    low, medium, high = (by_class[t] for t in TORQUE_CLASSES)
    assert low.stall_torque_Nm < medium.stall_torque_Nm < high.stall_torque_Nm
    assert low.mass_kg < medium.mass_kg < high.mass_kg
    assert low.cost < medium.cost < high.cost


def test_datasheet_conversions(cat: Catalog) -> None:
    sg90 = cat.actuators_of("PositionServomotor")[0]
    assert sg90.model == "SG90"
    assert sg90.stall_torque_Nm == pytest.approx(1.8 * KGF_CM, rel=1e-12)
    assert sg90.no_load_speed_rad_s == pytest.approx(math.radians(60) / 0.1, rel=1e-12)
    assert sg90.mass_kg == pytest.approx(0.034, rel=1e-12)
    assert sg90.size_m == pytest.approx((0.05, 0.05, 0.04), rel=1e-12)


def test_every_actuator_is_plausible_hobby_hardware(cat: Catalog) -> None:
    for a in cat.actuators:
        assert 0.01 < a.mass_kg < 0.3, a
        assert 0.05 < a.stall_torque_Nm < 5, a
        assert 1 < a.no_load_speed_rad_s < 20, a
        assert 0.1 < a.stall_current_A < 5, a
        assert all(0.01 < s < 0.2 for s in a.size_m), a


def test_battery_is_the_papers_1500mAh_3s_lipo(cat: Catalog) -> None:
    battery = cat.battery
    assert battery.ontology_class == BATTERY_CLASS
    assert battery.capacity_Ah == pytest.approx(1.5, rel=1e-12)
    assert battery.voltage_V == pytest.approx(11.1, rel=1e-12)
    assert battery.max_current_A == pytest.approx(30.0, rel=1e-12)  # 20 C x 1.5 Ah


def test_main_module_and_four_sensor_classes(cat: Catalog) -> None:
    assert cat.main_module.ontology_class == MAIN_CLASS
    assert cat.main_module.capacity_Ah is None
    sensors = {m.ontology_class for m in cat.modules} - {MAIN_CLASS, BATTERY_CLASS}
    assert sensors == set(SENSOR_CLASSES)
    for cls in SENSOR_CLASSES:
        module = cat.module_of(cls)
        assert 0 < module.current_A < 0.1
        assert module.voltage_V is None and module.max_current_A is None


def test_pla_figures_in_printed_ranges(cat: Catalog) -> None:
    pla = cat.material
    assert pla.name == "PLA"
    assert 2.0e9 <= pla.youngs_modulus_Pa <= 3.6e9
    assert 30e6 <= pla.yield_strength_Pa <= 65e6
    assert pla.density_kg_m3 == pytest.approx(1240.0)


def test_passive_templates_and_rules(cat: Catalog) -> None:
    p, d = cat.passive, cat.design
    assert 2 * (p.max_outer_radius_m + p.fillet_radius_m) <= p.dovetail_face_m
    assert p.min_wall_m < p.max_outer_radius_m
    assert p.min_link_length_m < p.max_link_length_m <= max(p.printer_bed_m)
    assert p.printer_bed_m == pytest.approx((0.22, 0.22, 0.25))
    assert p.print_speed_m3_s == 0.0  # optional, unused: the BOM's estimate is the slicer's
    assert p.print_clearance_m == pytest.approx(0.0002, rel=1e-12)
    assert p.stress_concentration >= 1
    assert cat.bus == Bus("I2C", "I2C, 7-bit addresses", 0x08, 0x77, 24, "address", "hex")
    assert cat.bus.module_limit == 24 and cat.bus.address_text(9) == "0x09"
    assert d.max_slope_rad == pytest.approx(math.radians(10), rel=1e-12)
    assert d.gravity_m_s2 == pytest.approx(9.81)


def test_catalog_classes_are_ontology_modules(cat: Catalog, kb: KnowledgeBase) -> None:
    parents: dict[str, set[str]] = {}
    for sub, sup, *_ in kb.translation.relation("subclass"):
        parents.setdefault(str(sub), set()).add(str(sup))

    def ancestors(cls: str) -> set[str]:
        seen, todo = set(), [cls]
        while todo:
            for parent in parents.get(todo.pop(), ()):
                if parent not in seen:
                    seen.add(parent)
                    todo.append(parent)
        return seen

    for a in cat.actuators:
        assert "ActuatorModule" in ancestors(a.ontology_class), a
    for m in cat.modules:
        assert "ActiveModule" in ancestors(m.ontology_class), m
    cat.check_classes(parents.keys())


def test_check_classes_names_file_and_entry(cat: Catalog) -> None:
    known = {"PositionServomotor", "ContinuousRotationServomotor", "MainModule"}
    with pytest.raises(InputError) as info:
        cat.check_classes(known | {"BateryModule"})
    assert str(info.value) == (
        f"{cat.source}: module[1] (LiPo-3S-1500).class: 'BatteryModule' is not a class of "
        "the ontology (did you mean 'BateryModule'?)"
    )


def test_module_of_a_missing_class_names_the_file(cat: Catalog) -> None:
    with pytest.raises(InputError, match=r"catalog\.toml: no \[\[module\]\] of class 'Lidar'"):
        cat.module_of("Lidar")


def test_loading_is_deterministic(cat: Catalog, tmp_path: Path) -> None:
    assert load_catalog() == cat
    assert catalog_facts(load_catalog()) == catalog_facts(cat)
    path = tmp_path / "copy.toml"
    path.write_text(SHIPPED, encoding="utf-8")
    copy = load_catalog(path)
    assert dataclasses.replace(copy, source=cat.source, shipped=cat.shipped) == cat
    # Facts do not depend on the file's location or the order of its entries.
    assert catalog_facts(copy) == catalog_facts(cat)
    shuffled = dataclasses.replace(cat, actuators=cat.actuators[::-1], modules=cat.modules[::-1])
    assert catalog_facts(shuffled) == catalog_facts(cat)


# ---- ASP facts ---------------------------------------------------------------------------


def _ground(facts: str) -> list[clingo.Symbol]:
    ctl = clingo.Control(["--warn=none"])
    ctl.add("base", [], facts)
    ctl.ground([("base", [])])
    return sorted(a.symbol for a in ctl.symbolic_atoms)


def test_facts_parse_in_clingo_and_round_trip(cat: Catalog) -> None:
    atoms = _ground(catalog_facts(cat))
    actuators = {s.arguments[0].string: s for s in atoms if s.name == "actuator"}
    modules = {s.arguments[0].string: s for s in atoms if s.name == "module"}
    assert set(actuators) == {a.model for a in cat.actuators}
    assert set(modules) == {m.model for m in cat.modules}
    for a in cat.actuators:
        args = actuators[a.model].arguments
        assert args[1].string == a.ontology_class
        numbers = [x.number for x in args[2:]]
        expected = [
            a.mass_kg * 1e6,
            a.cost * 100,
            a.stall_torque_Nm * 1e3,
            a.no_load_speed_rad_s * 1e3,
            a.stall_current_A * 1e3,
        ]
        for got, want in zip(numbers, expected, strict=True):
            assert abs(got - want) <= 0.5 + 1e-9, (a.model, got, want)
    for m in cat.modules:
        args = modules[m.model].arguments
        assert args[1].string == m.ontology_class
        expected = [m.mass_kg * 1e6, m.cost * 100, m.current_A * 1e3]
        for got, want in zip((x.number for x in args[2:]), expected, strict=True):
            assert abs(got - want) <= 0.5 + 1e-9, (m.model, got, want)


def test_facts_are_sorted_and_documented(cat: Catalog) -> None:
    lines = catalog_facts(cat).splitlines()
    comments = [line for line in lines if line.startswith("%")]
    facts = [line for line in lines if not line.startswith("%")]
    assert any("actuator(Model, Class, MassMg, CostCents" in c for c in comments)
    assert any("module(Model, Class, MassMg, CostCents, CurrentMilliA)" in c for c in comments)
    actuators = [f for f in facts if f.startswith("actuator(")]
    assert actuators == sorted(actuators) and len(actuators) == 6
    assert 'actuator("SG90","PositionServomotor",34000,500,177,10472,650).' in facts


def test_facts_round_half_up_and_escape_strings(cat: Catalog) -> None:
    sg90 = cat.actuators[0]
    odd = dataclasses.replace(
        sg90, model='Odd "quoted" \\ servo', cost=0.125, stall_current_A=0.0025, mass_kg=0.0015
    )
    facts = catalog_facts(dataclasses.replace(cat, actuators=(odd,)))
    (atom,) = [s for s in _ground(facts) if s.name == "actuator"]
    assert atom.arguments[0].string == 'Odd "quoted" \\ servo'
    mass, cost, _, _, current = (x.number for x in atom.arguments[2:])
    assert (mass, cost, current) == (1500, 13, 3)  # 12.5 -> 13 and 2.5 -> 3: half up


# ---- Validation of a user's catalog ------------------------------------------------------


def _edit(old: str, new: str, text: str = SHIPPED) -> str:
    assert text.count(old) == 1, f"{old!r} must occur once in the shipped catalog"
    return text.replace(old, new)


def _drop(model: str, text: str = SHIPPED) -> str:
    """The text without the [[actuator]] / [[module]] table of ``model``."""
    at = text.index(f'model = "{model}"')
    start = text.rindex("\n[[", 0, at)
    end = text.index("\n[", at)
    return text[:start] + text[end:]


def _drop_bus(text: str = SHIPPED) -> str:
    """The text without its [bus] table (the last table of the shipped catalog)."""
    at = text.index("\n[bus]")
    assert "\n[" not in text[at + 1 :], "[bus] must be the last table"
    return text[:at] + "\n"


def _drop_all(kind: str, text: str = SHIPPED) -> str:
    while f"\n[[{kind}]]" in text:
        at = text.index(f"\n[[{kind}]]")
        end = text.index("\n[", at + 1)
        text = text[:at] + text[end:]
    return text


CASES = {
    "missing key": (
        _edit('stall_torque = "9.4 kgf*cm"\n', ""),
        "actuator[1] (MG996R).stall_torque: missing (it is required)",
    ),
    "misspelled key": (
        _edit('stall_torque = "9.4 kgf*cm"', 'stal_torque = "9.4 kgf*cm"'),
        "actuator[1] (MG996R).stal_torque: unknown key (did you mean 'stall_torque'?)",
    ),
    "wrong unit": (
        _edit('mass = "88 g"', 'mass = "88 mm"'),
        "actuator[1] (MG996R).mass = '88 mm': expected a mass such as '0.5 kg', got '88 mm'",
    ),
    "bare number": (
        _edit('stall_torque = "9.4 kgf*cm"', "stall_torque = 9.4"),
        "actuator[1] (MG996R).stall_torque = 9.4: '9.4' has no unit; expected a torque such as",
    ),
    "negative mass": (
        _edit('mass = "88 g"', 'mass = "-88 g"'),
        "actuator[1] (MG996R).mass = '-88 g': must not be negative, got '-88 g'",
    ),
    "zero torque": (
        _edit('stall_torque = "9.4 kgf*cm"', 'stall_torque = "0 N*m"'),
        "actuator[1] (MG996R).stall_torque = '0 N*m': must be positive",
    ),
    "duplicate model": (
        _edit('model = "DS3218"', 'model = "MG996R"'),
        "actuator[2].model = 'MG996R': repeats the model of actuator[1]",
    ),
    "duplicate across lists": (
        _edit('model = "MPU-6050"', 'model = "SG90"'),
        "module[5].model = 'SG90': repeats the model of actuator[0]",
    ),
    "bad torque class": (
        _edit('torque_class = "medium"\nmass = "88 g"', 'torque_class = "meduim"\nmass = "88 g"'),
        "actuator[1] (MG996R).torque_class = 'meduim': not one of 'low', 'medium' or 'high'",
    ),
    "size not an array": (
        _edit('size = ["115 mm", "50 mm", "40 mm"]', 'size = "115 mm"'),
        "module[1] (LiPo-3S-1500).size = '115 mm': not a list",
    ),
    "size of two": (
        _edit('size = ["115 mm", "50 mm", "40 mm"]', 'size = ["115 mm", "50 mm"]'),
        "module[1] (LiPo-3S-1500).size = ['115 mm', '50 mm']: too few items",
    ),
    "size element": (
        _edit('size = ["115 mm", "50 mm", "40 mm"]', 'size = ["115 mm", "50 mm", "40"]'),
        "module[1] (LiPo-3S-1500).size[2] = '40': '40' has no unit",
    ),
    "cost as a string": (
        _edit("cost = 8.7", 'cost = "8.7 EUR"'),
        "actuator[1] (MG996R).cost = '8.7 EUR': unknown unit 'EUR'",
    ),
    "negative cost": (
        _edit("cost = 8.7", "cost = -8.7"),
        "actuator[1] (MG996R).cost = -8.7: out of range: must be at least 0",
    ),
    "class not a name": (
        _edit('class = "MainModule"', 'class = "main module"'),
        "module[0] (IntelEdison).class = 'main module': not an ontology class name",
    ),
    "battery key on a sensor": (
        _edit('model = "HC-SR04"', 'model = "HC-SR04"\ncapacity = "1 Ah"'),
        "module[3] (HC-SR04).capacity: only for modules of class 'BatteryModule'",
    ),
    "battery without capacity": (
        _edit('capacity = "1500 mAh"\n', ""),
        "module[1] (LiPo-3S-1500).capacity: missing (a module of class 'BatteryModule'",
    ),
    "capacity in volts": (
        _edit('capacity = "1500 mAh"', 'capacity = "1500 V"'),
        "module[1] (LiPo-3S-1500).capacity = '1500 V': expected a charge such as '1500 mAh', "
        "got '1500 V'",
    ),
    "no battery": (
        _drop("LiPo-3S-1500"),
        "module: no module of class 'BatteryModule'; every design needs a battery",
    ),
    "no main module": (
        _drop("IntelEdison"),
        "module: no module of class 'MainModule'; every design needs the main module",
    ),
    "no actuator": (
        _drop_all("actuator"),
        "actuator: missing (it is required)",
    ),
    "actuator as a table": (
        _drop_all("actuator") + '\n[actuator]\nmodel = "X"\n',
        "actuator = a table: not a list",
    ),
    "misspelled table": (
        _edit("\n[design]\n", "\n[desing]\n"),
        "desing: unknown key (did you mean 'design'?)",
    ),
    "missing table": (
        SHIPPED[: SHIPPED.index("\n[material]")] + SHIPPED[SHIPPED.index("\n[design]") :],
        "material: missing (it is required)",
    ),
    "passive tube too wide": (
        _edit('max_outer_radius = "20 mm"', 'max_outer_radius = "30 mm"'),
        "passive.max_outer_radius = '30 mm': a tube of this radius with its 3 mm fillet does "
        "not fit the 50 mm dovetail face",
    ),
    "link longer than the bed": (
        _edit('max_link_length = "200 mm"', 'max_link_length = "30 cm"'),
        "passive.max_link_length = '300 mm': does not fit the printer bed",
    ),
    "link range reversed": (
        _edit('min_link_length = "40 mm"', 'min_link_length = "210 mm"'),
        "passive.min_link_length = '210 mm': more than max_link_length = 200 mm",
    ),
    "kt below one": (
        _edit("stress_concentration = 1.8", "stress_concentration = 0.8"),
        "passive.stress_concentration = 0.8: out of range: must be at least 1",
    ),
    "modulus in metres": (
        _edit('youngs_modulus = "2.3 GPa"', 'youngs_modulus = "2.3 m"'),
        "material.youngs_modulus = '2.3 m': expected a pressure such as '3.5 GPa', got '2.3 m'",
    ),
    "bus address as text": (
        _edit("first_address = 0x08", 'first_address = "8"'),
        "bus.first_address = '8': not an integer",
    ),
    "bus last address below the first": (
        _edit("last_address = 0x77", "last_address = 0x07"),
        "bus.last_address = 7: below first_address = 8",
    ),
    "bus address format": (
        _edit('address_format = "hex"', 'address_format = "octal"'),
        "bus.address_format = 'octal': not one of 'hex' or 'decimal'",
    ),
    "bus and legacy address": (
        _edit("rolling_resistance = 0.02", "rolling_resistance = 0.02\ni2c_first_address = 8"),
        "design.i2c_first_address = 8: the catalog has a [bus] table; give bus.first_address",
    ),
    "legacy i2c address out of range": (
        _edit(
            "rolling_resistance = 0.02",
            "rolling_resistance = 0.02\ni2c_first_address = 0x80",
            _drop_bus(),
        ),
        "design.i2c_first_address = 128: out of range: must be within 8 and 119",
    ),
    "slope too steep": (
        _edit('max_slope = "10 deg"', 'max_slope = "90 deg"'),
        "design.max_slope = '90 deg': not less than 90 deg",
    ),
    "currency": (
        _edit('currency = "EUR"', 'currency = "euro"'),
        "catalog.currency = 'euro': not a currency code such as 'EUR'",
    ),
    "no servo travel": (
        _edit("(about 90 deg each way).\ntravel_deg = 180\n", "(about 90 deg each way).\n"),
        "actuator[0] (SG90).travel_deg: missing (it is required)",
    ),
    "servo travel past a turn": (
        _edit("(about 90 deg each way).\ntravel_deg = 180", "(x).\ntravel_deg = 400"),
        "actuator[0] (SG90).travel_deg = 400: out of range: must be more than 0 and at most 360",
    ),
    "part source": (
        _edit(
            'class = "CasterModule"\nsource = "bought"',
            'class = "CasterModule"\nsource = "borrowed"',
        ),
        "part[1] (BallCaster-20).source = 'borrowed': not one of 'printed' or 'bought'",
    ),
    "printed part with a mass": (
        _edit('source = "printed"', 'source = "printed"\nmass = "15 g"'),
        "part[0] (Jaw-50x20x12).mass: a printed part's mass is its size's box",
    ),
    "tyre thicker than the smallest wheel": (
        _edit('thickness = "2 mm"', 'thickness = "25 mm"'),
        "tyre.thickness = '25 mm': leaves no rim in the smallest wheel (radius 20 mm)",
    ),
    "printer bed of two": (
        _edit('bed = ["360 mm", "360 mm", "360 mm"]', 'bed = ["360 mm", "360 mm"]'),
        "printer[0] (Prusa XL).bed = ['360 mm', '360 mm']: too few items",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_invalid_catalog_names_file_and_key(case: str, tmp_path: Path) -> None:
    text, expected = CASES[case]
    path = tmp_path / "my catalog.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as info:
        load_catalog(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ")
    assert expected in message
    assert info.value.exit_code == 2


def test_toml_syntax_error_gives_file_line_col(tmp_path: Path) -> None:
    lines = SHIPPED.split("\n")
    lineno = lines.index('model = "MG996R"') + 1
    lines[lineno - 1] = 'model = "MG996R'  # unterminated string
    path = tmp_path / "broken.toml"
    path.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError) as info:
        load_catalog(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{lineno}:"), message
    _, line, col, reason = message.rsplit(":", 3)
    assert int(line) == lineno and int(col) >= 9
    assert "(at line" not in reason and reason.strip()


def test_toml_error_at_end_of_document_still_has_a_position() -> None:
    with pytest.raises(InputError) as info:
        parse_catalog('x = "open', "end.toml")
    assert str(info.value).startswith("end.toml:1:10: Unterminated string")


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.toml"
    with pytest.raises(InputError) as info:
        load_catalog(path)
    assert str(info.value) == f"{path}: no such file"


def test_folder_and_binary_files_are_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="is a folder"):
        load_catalog(tmp_path)
    path = tmp_path / "latin1.toml"
    path.write_bytes(SHIPPED.replace("Li-Po", "Li-Po \xe9").encode("latin-1"))
    with pytest.raises(InputError, match=r"latin1\.toml: not UTF-8 text"):
        load_catalog(path)


def test_a_users_catalog_may_differ_from_the_shipped_one(tmp_path: Path) -> None:
    # A cheaper second battery and plain-number strings for dimensionless keys.
    extra = """
[[module]]
model = "LiPo-3S-2200"
class = "BatteryModule"
mass = "0.19 kg"
size = ["120 mm", "50 mm", "40 mm"]
cost = 0
current = "0 A"
capacity = "2.2 Ah"
voltage = "11.1 V"
c_rating = "25"
"""
    text = _edit("\n[passive]\n", extra + "\n[passive]\n")
    path = tmp_path / "mine.toml"
    path.write_text(text, encoding="utf-8")
    mine = load_catalog(path)
    assert mine.source == str(path)
    assert mine.battery.model == "LiPo-3S-1500"  # the first battery
    second = mine.modules_of(BATTERY_CLASS)[1]
    assert second.capacity_Ah == pytest.approx(2.2, rel=1e-12)
    assert second.max_current_A == pytest.approx(55.0, rel=1e-12)
    assert second.cost == 0 and second.current_A == 0


def test_shipped_catalog_has_servo_travel_parts_tyre_and_printers(cat: Catalog) -> None:
    from math import pi

    travel = {a.model: a.travel_rad for a in cat.actuators}
    assert travel["SG90"] == pytest.approx(pi) and travel["FS90R"] == pytest.approx(2 * pi)
    assert all(
        a.continuous == (a.ontology_class == "ContinuousRotationServomotor") for a in cat.actuators
    )
    jaw = cat.part_of("FingerModule")
    assert jaw.source == "printed"
    assert jaw.mass_kg == pytest.approx(0.05 * 0.02 * 0.012 * cat.material.density_kg_m3)
    assert cat.part_of("CasterModule").mass_kg == pytest.approx(0.020)
    assert cat.tyre is not None and cat.tyre.mass_kg(0.03, 0.01) > 0
    assert [p.model for p in cat.printers] == ["Prusa XL", "Creality CR-10 S5"]
    with pytest.raises(InputError, match="no \\[\\[part\\]\\] of class 'Gear'"):
        cat.part_of("Gear")


# ---- The bus, catalogs that extend another, shipped catalogs by name ------------------------


def test_a_catalog_without_bus_is_the_papers_i2c_bus() -> None:
    cat = parse_catalog(_drop_bus(), "old.toml")
    assert cat.bus == parse_catalog(SHIPPED, "new.toml").bus
    legacy = _drop_bus().replace(
        "rolling_resistance = 0.02", "rolling_resistance = 0.02\ni2c_first_address = 0x10"
    )
    assert parse_catalog(legacy, "old.toml").bus.first_address == 0x10


def test_bus_limit_is_the_smaller_of_device_limit_and_addresses() -> None:
    assert Bus("b", "p", 1, 252).module_limit == 253  # 252 IDs and the master
    assert Bus("b", "p", 8, 0x77, 24).module_limit == 24
    assert Bus("b", "p", 1, 3, 24).module_limit == 4
    assert Bus("b", "p", 1, 3, address_format="decimal").address_text(3) == "3"


def test_facts_carry_the_bus_limit(cat: Catalog) -> None:
    atoms = _ground(catalog_facts(cat))
    assert [s.arguments[0].number for s in atoms if s.name == "bus_limit"] == [24]
    dxl = load_catalog("dynamixel")
    atoms = _ground(catalog_facts(dxl))
    assert [s.arguments[0].number for s in atoms if s.name == "bus_limit"] == [253]


def test_actuator_assignment_uses_the_catalogs_bus_limit(cat: Catalog) -> None:
    """actuators.lp: the catalog's bus_limit bounds the active modules (a bus of 3 refuses
    a robot of 2 joints and 2 other modules; one of 4 takes it)."""
    from importlib.resources import files as res

    rules = res("asp") / "actuators.lp"  # loaded as a file: it includes serving.lp
    base = (
        'actuator("S","C",1,1,1,1,1). joint("a","","C"). joint("b","","C"). isa("C","C").'
        'robot("R"). other_active(2). #external capable("a","S"). #external capable("b","S").'
    )

    def solve(limit: int) -> bool:
        ctl = clingo.Control(["--warn=none"])
        ctl.add("base", [], base + f"bus_limit({limit}).")
        ctl.load(str(rules))
        ctl.ground([("base", [])])
        for j in ("a", "b"):
            ctl.assign_external(
                clingo.Function("capable", [clingo.String(j), clingo.String("S")]), True
            )
        return ctl.solve().satisfiable

    assert solve(4) and not solve(3)


def test_shipped_catalogs_by_name() -> None:
    from adron.catalog import shipped_catalogs

    assert shipped_catalogs() == ("default", "dynamixel")
    default = load_catalog("default")
    assert default.shipped == "default" and dataclasses.replace(default, source="x") == (
        dataclasses.replace(load_catalog(), source="x")
    )
    with pytest.raises(InputError, match="neither a shipped catalog .* nor a file.*'dynamixel'"):
        load_catalog("dynamixl")


def test_dynamixel_catalog_extends_the_default(cat: Catalog, kb: KnowledgeBase) -> None:
    dxl = load_catalog("dynamixel")
    assert dxl.currency == cat.currency and dxl.shipped == "dynamixel"
    assert {a.model for a in dxl.actuators}.isdisjoint(a.model for a in cat.actuators)
    assert dxl.main_module.model == "Edison-U2D2"
    assert dxl.battery == cat.battery and dxl.passive == cat.passive and dxl.tyre == cat.tyre
    assert dxl.modules_of("InfraredSensorModule") == cat.modules_of("InfraredSensorModule")
    assert dxl.bus.name == "DYNAMIXEL TTL" and dxl.bus.module_limit == 253
    assert dxl.bus.address_text(12) == "12" and dxl.bus.address_word == "ID"
    for cls in SERVO_CLASSES:
        assert {a.torque_class for a in dxl.actuators_of(cls)} == set(TORQUE_CLASSES), cls
    xm540 = next(a for a in dxl.actuators if a.model == "XM540-W270")
    assert xm540.stall_torque_Nm == pytest.approx(10.0)
    assert xm540.no_load_speed_rad_s == pytest.approx(28 * 2 * math.pi / 60)
    known = {n for pair in kb.translation.relation("subclass") for n in pair[:2]}
    dxl.check_classes(known)
    assert len(dxl.sha256) == 64 and dxl.sha256 != cat.sha256


def _child(tmp_path: Path, body: str, parent: str = "default") -> Path:
    path = tmp_path / "child.toml"
    head = f'[catalog]\nname = "c"\ncurrency = "EUR"\nversion = "1"\nextends = "{parent}"\n'
    path.write_text(head + body, encoding="utf-8")
    return path


def test_extends_merges_tables_by_key_and_entries_by_model(cat: Catalog, tmp_path: Path) -> None:
    body = (
        "[design]\ntorque_safety_factor = 2.0\n"
        '[[actuator]]\nmodel = "SG90"\nclass = "PositionServomotor"\ntorque_class = "low"\n'
        'mass = "40 g"\nsize = ["50 mm", "50 mm", "40 mm"]\nstall_torque = "2 kgf*cm"\n'
        'no_load_speed = "100 rpm"\nstall_current = "0.7 A"\ncost = 6.0\ntravel_deg = 180\n'
    )
    child = load_catalog(_child(tmp_path, body))
    assert child.design.torque_safety_factor == 2.0
    assert child.design.stress_safety_factor == cat.design.stress_safety_factor
    assert [a.model for a in child.actuators] == [a.model for a in cat.actuators]
    assert child.actuators[0].mass_kg == pytest.approx(0.040)
    assert child.actuators[1:] == cat.actuators[1:] and child.bus == cat.bus
    assert child.shipped == "" and child.sha256 != cat.sha256
    # a file parent, relative to the child's folder
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "base.toml").write_text(SHIPPED, encoding="utf-8")
    grand = tmp_path / "sub" / "g.toml"
    grand.write_text(_child(tmp_path, "").read_text().replace('"default"', '"base.toml"'))
    assert load_catalog(grand).actuators == cat.actuators


EXTEND_CASES = {
    "unknown parent": ("", "nope.toml", "catalog.extends: .*nope.toml: no such file"),
    "currency differs": ("", "default", "catalog.currency: 'USD' differs from 'EUR'"),
    "remove unknown model": (
        "",
        "default",
        "catalog.remove: the catalog it extends has no model 'XX'",
    ),
    "replace bad array": ("", "default", r"catalog.replace\[0\] = 'tyre': not one of"),
    "self": ("", "child.toml", "catalog.extends: 'child.toml' extends itself"),
}


@pytest.mark.parametrize("case", sorted(EXTEND_CASES))
def test_extends_errors_name_the_file(case: str, tmp_path: Path) -> None:
    body, parent, message = EXTEND_CASES[case]
    path = _child(tmp_path, body, parent)
    text = path.read_text()
    if case == "currency differs":
        text = text.replace('currency = "EUR"', 'currency = "USD"')
    if case == "remove unknown model":
        text = text.replace('extends = "default"', 'extends = "default"\nremove = ["XX"]')
    if case == "replace bad array":
        text = text.replace('extends = "default"', 'extends = "default"\nreplace = ["tyre"]')
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        load_catalog(path)


def test_remove_and_replace_only_when_extending() -> None:
    text = SHIPPED.replace('version = "1"', 'version = "1"\nremove = ["SG90"]')
    with pytest.raises(InputError, match="catalog.remove = .*: only for a catalog that extends"):
        parse_catalog(text, "x.toml")


def test_a_recorded_catalog_is_reloaded_and_a_changed_one_refused(tmp_path: Path) -> None:
    from adron.catalog import recorded_catalog
    from export.record import catalog_record

    dxl = load_catalog("dynamixel")
    assert recorded_catalog(catalog_record(dxl)) == dxl
    path = tmp_path / "mine.toml"
    path.write_text(SHIPPED, encoding="utf-8")
    entry = catalog_record(load_catalog(path))
    assert entry["shipped"] == "" and recorded_catalog(entry, path).sha256 == entry["sha256"]
    with pytest.raises(InputError, match="give its file"):
        recorded_catalog(entry)
    path.write_text(SHIPPED.replace("cost = 5.0", "cost = 5.5"), encoding="utf-8")
    with pytest.raises(InputError, match="not the catalog the design used"):
        recorded_catalog(entry, path)
    with pytest.raises(InputError, match="names no catalog"):
        recorded_catalog(None)


def test_design_with_the_dynamixel_catalog_names_its_bus(cli) -> None:
    r = cli("design", "driving", "--catalog", "dynamixel", "--no-verify", "--json")
    assert r.code == 0, r.err
    rec = json.loads(r.out)
    assert rec["bus"]["name"] == "DYNAMIXEL TTL" and rec["bus"]["module_limit"] == 253
    assert rec["catalog"]["shipped"] == "dynamixel"
    assert rec["catalog"]["sha256"] == load_catalog("dynamixel").sha256
    ids = [a for m in rec["modules"] for a in m["bus_addresses"]]
    assert sorted(ids, key=int) == [str(i) for i in range(1, len(ids) + 1)]
    assert {j["actuator"] for j in rec["joints"]} <= {
        a.model for a in load_catalog("dynamixel").actuators
    }
    bad = cli("design", "driving", "--catalog", "dynamixl", "--no-verify")
    assert bad.code == 2 and "did you mean 'dynamixel'" in bad.err


def test_suites_and_studies_take_a_shipped_catalogs_name(tmp_path: Path) -> None:
    from synth.commands.backend import files_digest
    from synth.commands.regress import kb_options

    suite = tmp_path / "s.toml"
    assert kb_options({"catalog": "dynamixel"}, suite)["catalog"] == "dynamixel"
    assert kb_options({"catalog": "mine.toml"}, suite)["catalog"] == str(tmp_path / "mine.toml")
    # a study's digest follows the catalog's content, whatever names it
    (tmp_path / "mine.toml").write_text(SHIPPED, encoding="utf-8")
    same = files_digest(str(tmp_path / "mine.toml"), [], [])
    assert same != files_digest("dynamixel", [], [])
    assert files_digest(str(tmp_path / "mine.toml"), [], []) == same
    (tmp_path / "mine.toml").write_text(SHIPPED.replace("cost = 5.0", "cost = 5.5"))
    assert files_digest(str(tmp_path / "mine.toml"), [], []) != same


def test_guide_words_follow_the_bus() -> None:
    from export.guide import _plural

    assert _plural("address") == "addresses" and _plural("ID") == "IDs"


def test_printer_bed_by_name(cat: Catalog) -> None:
    """ "" is the catalog's own printer, a model one of its larger printers, else None."""
    assert cat.printer_bed("") == cat.passive.printer_bed_m
    for p in cat.printers:
        assert cat.printer_bed(p.model) == p.bed_m
    assert cat.printer_bed("split") is None


def test_validated_catalogs_are_cached(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A catalog file is parsed and checked once; later loads read the validated catalog
    back (equal to a fresh parse), a changed file is parsed again, a corrupt entry is a
    miss, an invalid catalog is never cached (its error comes again), a catalog that
    extends another and ``PARMOR_CACHE=`` are not cached."""
    from adron.catalog import load_catalog

    cache = tmp_path / "cache"
    monkeypatch.setenv("PARMOR_CACHE", str(cache))
    text = files("adron").joinpath("catalog.toml").read_text(encoding="utf-8")
    mine = tmp_path / "mine.toml"
    mine.write_text(text, encoding="utf-8")
    first = load_catalog(mine)
    (entry,) = cache.glob("catalog-*.pickle")
    assert load_catalog(mine) == first
    entry.write_bytes(b"parmor-catalog-1\nnot a pickle")
    assert load_catalog(mine) == first
    mine.write_text(text.replace('version = "', 'version = "x', 1), encoding="utf-8")
    changed = load_catalog(mine)
    assert changed != first and len(list(cache.glob("catalog-*.pickle"))) == 2
    bad = tmp_path / "bad.toml"
    assert 'dovetail_face = "50 mm"' in text
    bad_text = text.replace('dovetail_face = "50 mm"', 'dovetail_face = "-50 mm"', 1)
    bad.write_text(bad_text, encoding="utf-8")
    for _ in range(2):
        with pytest.raises(InputError, match="dovetail_face"):
            load_catalog(bad)
    assert len(list(cache.glob("catalog-*.pickle"))) == 2
    child = tmp_path / "child.toml"
    child.write_text(
        '[catalog]\nname = "c"\ncurrency = "EUR"\nversion = "1"\nextends = "default"\n',
        encoding="utf-8",
    )
    load_catalog(child)
    assert len(list(cache.glob("catalog-*.pickle"))) == 2
    monkeypatch.setenv("PARMOR_CACHE", "")
    for f in cache.glob("catalog-*.pickle"):
        f.unlink()
    assert load_catalog(mine) == changed
    assert not list(cache.glob("catalog-*.pickle"))
