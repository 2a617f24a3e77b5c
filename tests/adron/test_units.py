"""adron.units: text with units -> SI floats, and clear errors for everything else."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adron.errors import InputError
from adron.units import DIMENSIONS, quantity, registry

REPO = Path(__file__).resolve().parents[2]
KGF_CM = 9.80665 * 0.01  # N*m

GOOD = [
    ("30cm", "length", 0.3),
    ("30 cm", "length", 0.3),
    ("1e3 mm", "length", 1.0),
    ("20 µm", "length", 20e-6),
    ("0.5 kg", "mass", 0.5),
    ("9 g", "mass", 0.009),
    ("1.8 N*m", "torque", 1.8),
    ("1.8 N m", "torque", 1.8),
    ("1.8 N·m", "torque", 1.8),
    ("2 kgf*cm", "torque", 2 * KGF_CM),
    ("1 kg*m^2*s⁻²", "torque", 1.0),
    ("5 N", "force", 5.0),
    ("0.2m/s", "speed", 0.2),
    ("9.81 m/s^2", "acceleration", 9.81),
    ("9.81 m s^-2", "acceleration", 9.81),
    ("9.81 m/s²", "acceleration", 9.81),
    ("300cm2", "area", 0.03),
    ("300 cm^2", "area", 0.03),
    ("300 cm**2", "area", 0.03),
    ("300 cm²", "area", 0.03),
    ("12 cm3", "volume", 12e-6),
    ("12 mm^3/s", "volume_flow", 12e-9),
    ("60 rpm", "angular_speed", 2 * math.pi),
    ("360 deg/s", "angular_speed", 2 * math.pi),
    ("5 rad/s", "angular_speed", 5.0),
    ("3 rad/s^2", "angular_acceleration", 3.0),
    ("10 deg", "angle", math.radians(10)),
    ("10°", "angle", math.radians(10)),
    ("0.5 rad", "angle", 0.5),
    ("2 min", "time", 120.0),
    ("1500 mA", "current", 1.5),
    ("11.1 V", "voltage", 11.1),
    ("1500 mAh", "charge", 1.5 * 3600),
    ("3.5 GPa", "pressure", 3.5e9),
    ("40 MPa", "pressure", 40e6),
    ("1240 kg/m^3", "density", 1240.0),
    ("1.24 g/cm3", "density", 1240.0),
    ("0.02", "dimensionless", 0.02),
    (0.02, "dimensionless", 0.02),
    (2, "dimensionless", 2.0),
    ("1.5 percent", "dimensionless", 0.015),
]


@pytest.mark.parametrize(("text", "dimension", "si"), GOOD)
def test_good_inputs_give_si_values(text: str | float, dimension: str, si: float) -> None:
    assert quantity(text, dimension, "w") == pytest.approx(si, rel=1e-12)


BAD = [
    ("0.5 kg", "length", "got '0.5 kg'"),  # wrong dimension
    ("30 s", "length", "got '30 s'"),
    ("30", "length", "'30' has no unit"),  # bare number
    (30, "length", "'30' has no unit"),
    (0.5, "mass", "'0.5' has no unit"),
    ("10", "angle", "'10' has no unit"),
    ("garbage", "length", "cannot read 'garbage'"),
    ("m", "length", "cannot read 'm'"),
    ("nan m", "length", "cannot read 'nan m'"),
    ("", "length", "empty value"),
    ("   ", "length", "empty value"),
    ("1 foo", "length", "unknown unit 'foo'"),
    ("1 m@", "length", "cannot read the unit of '1 m@'"),
    ("1 m**x", "length", "cannot read the unit of '1 m**x'"),
    ("30 cm 2", "area", "cannot read the unit of '30 cm 2'"),
    ("1e999 m", "length", "is not finite"),
    ("1 degC", "length", "got '1 degC'"),
    ("10 Hz", "angular_speed", "got '10 Hz'"),  # pint would read it as 10 rad/s
    ("10 deg", "dimensionless", "got '10 deg'"),
    ("1 N*m/rad", "torque", "got '1 N*m/rad'"),
    (True, "length", "a boolean"),
    ([1, 2], "length", "an array"),
    ({"x": 1}, "length", "a table"),
]


@pytest.mark.parametrize(("text", "dimension", "fragment"), BAD)
def test_bad_inputs_name_where_and_example(text: object, dimension: str, fragment: str) -> None:
    where = "cat.toml: actuator[2] (MG996R).mass"
    with pytest.raises(InputError) as info:
        quantity(text, dimension, where)  # type: ignore[arg-type]
    message = str(info.value)
    assert message.startswith(where + ": ")
    assert f"such as '{DIMENSIONS[dimension].example}'" in message
    assert fragment in message


def test_wrong_dimension_message_reads_well() -> None:
    with pytest.raises(InputError) as info:
        quantity("60 kg", "angular_speed", "f: design.speed")
    assert str(info.value) == (
        "f: design.speed: expected an angular speed such as '60 rpm', got '60 kg'"
    )


def test_sign_rules() -> None:
    with pytest.raises(InputError, match="w: must be positive, got '0 m'"):
        quantity("0 m", "length", "w")
    with pytest.raises(InputError, match="w: must not be negative, got '-1 m'"):
        quantity("-1 m", "length", "w")
    with pytest.raises(InputError, match="must not be negative"):
        quantity("-1 m", "length", "w", allow_zero=True)
    assert quantity("0 m", "length", "w", allow_zero=True) == 0.0
    assert quantity("-2 deg", "angle", "w", allow_negative=True) == pytest.approx(
        -math.radians(2), rel=1e-12
    )
    assert quantity("0 rad", "angle", "w", allow_negative=True) == 0.0


def test_unknown_dimension_is_a_programming_error() -> None:
    with pytest.raises(ValueError, match="unknown dimension 'lenght'"):
        quantity("1 m", "lenght", "w")


@pytest.mark.parametrize("name", sorted(DIMENSIONS))
def test_dimension_table_is_consistent(name: str) -> None:
    dim = DIMENSIONS[name]
    ureg = registry()
    stored = dim.dimensionality
    want = ureg.dimensionless.dimensionality if stored == "dimensionless" else stored
    assert ureg.Unit(dim.si_unit).dimensionality == ureg.get_dimensionality(want)
    # The example parses as its own dimension, and "1 <si_unit>" is exactly 1.
    assert quantity(dim.example, name, "w") > 0
    assert quantity(f"1 {dim.si_unit}", name, "w") == pytest.approx(1.0, rel=1e-12)


def test_registry_is_cached() -> None:
    assert registry() is registry()


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=20))
def test_any_text_gives_a_positive_length_or_input_error(text: str) -> None:
    try:
        value = quantity(text, "length", "w")
    except InputError as error:
        assert str(error).startswith("w: ")
    else:
        assert math.isfinite(value) and value > 0


@settings(max_examples=100, deadline=None)
@given(
    st.floats(min_value=1e-6, max_value=1e6, allow_nan=False),
    st.sampled_from([("mm", 1e-3), ("cm", 1e-2), ("m", 1.0), ("km", 1e3), ("inch", 0.0254)]),
)
def test_lengths_scale_by_their_unit(number: float, unit: tuple[str, float]) -> None:
    name, factor = unit
    assert quantity(f"{number!r} {name}", "length", "w") == pytest.approx(
        number * factor, rel=1e-12
    )


@pytest.mark.parametrize("module", ["adron.units", "adron.catalog"])
def test_import_does_not_load_pint(module: str) -> None:
    code = f"import sys, {module}; print('pint' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "False"


# ---- The unit cache on disk -------------------------------------------------------------


def _fresh(monkeypatch, folder) -> None:
    """A new process's state: no unit answered yet, the cache in ``folder``."""
    import adron.units as u

    monkeypatch.setenv(u.CACHE_ENV, str(folder))
    u._scale.cache_clear()
    monkeypatch.setattr(u, "_DISK", u._DiskCache())


def test_units_are_cached_on_disk_and_read_back(monkeypatch, tmp_path: Path) -> None:
    import adron.units as u

    _fresh(monkeypatch, tmp_path)
    assert quantity("2 kgf*cm", "torque", "x") == pytest.approx(2 * KGF_CM)
    with pytest.raises(InputError):
        quantity("2 kgf", "torque", "x")
    (file,) = tmp_path.glob("units-*.json")
    assert '"torque|kgf^1 cm^1"' in file.read_text(encoding="utf-8")
    # A new process reads the factor from the file: pint is not asked.
    _fresh(monkeypatch, tmp_path)
    monkeypatch.setattr(u, "_pint_scale", lambda *a: pytest.fail("pint asked"))
    assert quantity("3 kgf*cm", "torque", "x") == pytest.approx(3 * KGF_CM)
    # A refusal is cached as well: the same message without pint.
    with pytest.raises(InputError, match="expected a torque such as .*, got '3 kgf'"):
        quantity("3 kgf", "torque", "x")


def test_a_corrupt_or_foreign_cache_file_is_ignored(monkeypatch, tmp_path: Path) -> None:
    import adron.units as u

    _fresh(monkeypatch, tmp_path)
    quantity("1 cm", "length", "x")
    (file,) = tmp_path.glob("units-*.json")
    for junk in ("not json", '{"length|cm^1": [-5, null]}', '{"length|cm^1": "x"}', "[1]"):
        file.write_text(junk, encoding="utf-8")
        _fresh(monkeypatch, tmp_path)
        assert quantity("30 cm", "length", "x") == pytest.approx(0.3), junk
    assert u._DiskCache._read(file)  # rewritten valid by the last run


def test_a_cache_folder_that_cannot_be_written_only_means_no_cache(
    monkeypatch, tmp_path: Path
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file where the folder would be")  # no folder, even for root
    _fresh(monkeypatch, blocker / "cache")
    assert quantity("1.5 A", "current", "x") == 1.5
    assert quantity("2.5 A", "current", "x") == 2.5
    assert blocker.read_text() == "a file where the folder would be"
    _fresh(monkeypatch, "")  # PARMOR_CACHE="" turns the cache off
    assert quantity("9 g", "mass", "x") == pytest.approx(0.009)
    assert not list(tmp_path.glob("**/units-*.json"))


def test_the_cache_file_is_keyed_by_code_and_pint(monkeypatch, tmp_path: Path) -> None:
    import adron.units as u

    key = u._cache_key()
    assert key is not None and len(key) == 20
    monkeypatch.setattr(u, "__file__", str(tmp_path / "other.py"))
    (tmp_path / "other.py").write_text("# another version of units.py\n")
    assert u._cache_key() != key
