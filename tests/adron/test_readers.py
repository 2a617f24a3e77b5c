"""adron/readers.py: every TOML and JSON input is read within bounds (issue 23, item 6):
nesting deeper than 64 levels, integers of more than 300 digits and (TOML) floats that are
not finite are input errors naming the file and the line and column or the key, never a
RecursionError, ValueError or OverflowError; the commands that read catalogs, suites,
studies, snapshots and design records exit 2 on them without a traceback."""

from __future__ import annotations

import json
import tomllib
from importlib.resources import files
from pathlib import Path

import pytest

from adron import readers
from adron.catalog import SHIPPED
from adron.errors import InputError

DEEP_JSON = "[" * 100_000 + "]" * 100_000
DEEP_TOML = "x = " + "[" * 1000 + "]" * 1000 + "\n"
LONG = "7" * 5000


# ---- the reader itself --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (DEEP_JSON, "f.json:1:65: nested deeper than 64 levels"),
        ('{"a": ' * 65 + "1" + "}" * 65, "f.json:1:385: nested deeper than 64 levels"),
        ('{"m": 1.5,\n "n": [1, ' + LONG + "]}", "f.json:2:11: a number of 5000 digits"),
        ('{"n": -' + "1" * 400 + "}", "f.json:1:8: a number of 400 digits"),
        ('{"n": 1,}', "f.json:1:9: Expecting property name"),
        ('{"s": "[[[' + "[" * 100, "f.json:1:7: Unterminated string"),
    ],
)
def test_json_out_of_bounds(text: str, message: str) -> None:
    with pytest.raises(InputError) as info:
        readers.parse_json(text, "f.json")
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (DEEP_TOML, "f.toml:1:69: nested deeper than 64 levels"),
        ("x = " + "{a=" * 1000 + "1" + "}" * 1000, "f.toml:1:197: nested deeper than 64"),
        ("a" + ".a" * 2000 + " = 1\n", "f.toml: key a.a.a.a...(58 more)...a.a: nested"),
        ("[t]\nx = " + LONG + "\n", "f.toml:2:5: a number of 5000 digits"),
        ("x = 1_" + "1" * 400 + "\n", "f.toml:1:5: a number of 401 digits"),
        ("x = 0x" + "f" * 400 + "\n", "f.toml: key x: an integer of more than 300 digits"),
        ("[t]\nx = [1.0, 1e400]\n", "f.toml: key t.x[1]: inf is not a finite number"),
        ('"a b" = nan\n', 'f.toml: key "a b": nan is not a finite number'),
        ("x = 1\ny = \n", "f.toml:2:5: Invalid value"),
        ("x = 1\ny = [\n", "f.toml:3:1: Invalid value (at end of document)"),
    ],
)
def test_toml_out_of_bounds(text: str, message: str) -> None:
    with pytest.raises(InputError) as info:
        readers.parse_toml(text, "f.toml")
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "text",
    [
        '{"s": "' + "[" * 200 + LONG + '", "n": [1, 2.5e10, -3], "t": NaN}',
        '{"a": ' * 64 + "1" + "}" * 64,
        '{"x": 1e400, "y": 1' + "0" * 300 + ".5}",  # floats: Python's (records may hold inf)
    ],
)
def test_json_within_bounds_is_read_as_python_reads_it(text: str) -> None:
    got = readers.parse_json(text, "f.json")
    assert json.dumps(got) == json.dumps(json.loads(text))


@pytest.mark.parametrize(
    "text",
    [
        "# [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[\nx = 1\n",
        "x = '" + "[" * 100 + LONG + "'\ny = '''" + "{" * 100 + "'''\n",
        'x = """\n' + "[" * 100 + '\n"""\n[[t]]\n[[t]]\na.b.c = 1_000\nd = 1979-05-27\n',
        "x = 1" + "0" * 299 + "\ny = -1e300\n",
    ],
)
def test_toml_within_bounds_is_read_as_tomllib_reads_it(text: str) -> None:
    assert readers.parse_toml(text, "f.toml") == tomllib.loads(text)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_the_shipped_catalogs_read_as_before(name: str) -> None:
    text = files("adron").joinpath(*SHIPPED[name].split("/")).read_text(encoding="utf-8")
    assert readers.parse_toml(text, name) == tomllib.loads(text)


def test_files_are_named_when_they_cannot_be_read(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"none\.toml: no such file$"):
        readers.read_toml(tmp_path / "none.toml")
    with pytest.raises(InputError, match=r": is a folder, not a TOML file$"):
        readers.read_toml(tmp_path)
    (tmp_path / "latin1.json").write_bytes(b'{"a": "\xe9"}')
    with pytest.raises(InputError, match=r"latin1\.json: not UTF-8 text \(byte 7\)$"):
        readers.read_json(tmp_path / "latin1.json")
    (tmp_path / "bom.json").write_bytes(b'\xef\xbb\xbf{"a": 1}')
    assert readers.read_json(tmp_path / "bom.json") == {"a": 1}


# ---- the commands that read them ----------------------------------------------------------

#: hostile texts of TOML and JSON files, by name
HOSTILE = {
    "deep": {"toml": DEEP_TOML, "json": DEEP_JSON},
    "long": {"toml": f"x = {LONG}\n", "json": '{"x": ' + LONG + "}"},
}
FOUR_HUNDRED = "4" * 400  # beyond any float: an OverflowError where a float is made of it


def refused(r, path: Path) -> None:
    assert r.code == 2, (r.code, r.err)
    assert str(path) in r.err and "Traceback" not in r.err
    assert len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("hostile", [*sorted(HOSTILE), "400 digits"])
def test_a_hostile_catalog(cli, tmp_path: Path, hostile: str) -> None:
    path = tmp_path / "c.toml"
    if hostile == "400 digits":
        text = files("adron").joinpath("catalog.toml").read_text(encoding="utf-8")
        assert "\ntravel_deg = 180\n" in text
        text = text.replace("\ntravel_deg = 180\n", f"\ntravel_deg = {FOUR_HUNDRED}\n", 1)
    else:
        text = HOSTILE[hostile]["toml"]
    path.write_text(text, encoding="utf-8")
    refused(cli("design", "driving", "--catalog", str(path), "--no-verify", "--json"), path)


@pytest.mark.parametrize("hostile", sorted(HOSTILE))
def test_a_hostile_suite_and_study(cli, tmp_path: Path, hostile: str) -> None:
    path = tmp_path / "s.toml"
    path.write_text(HOSTILE[hostile]["toml"], encoding="utf-8")
    refused(cli("regress", str(path)), path)
    refused(cli("sweep", str(path), "--no-simulate", "--out", str(tmp_path / "o")), path)
    assert not (tmp_path / "o").exists()


@pytest.fixture(scope="module")
def cart(tmp_path_factory) -> Path:
    import io

    from synth.commands.cli import main

    folder = tmp_path_factory.mktemp("readers") / "cart"
    err = io.StringIO()
    code = main(["design", "driving", "--no-verify", "--out", str(folder)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    return folder


@pytest.mark.parametrize("hostile", [*sorted(HOSTILE), "400 digits"])
def test_a_hostile_design_json(cli, cart: Path, tmp_path: Path, hostile: str) -> None:
    import shutil

    folder = tmp_path / "cart"
    shutil.copytree(cart, folder)
    path = folder / "design.json"
    if hostile == "400 digits":
        text = path.read_text(encoding="utf-8")
        radius = json.loads(text)["wheel_radius_m"]
        old = f'"wheel_radius_m": {json.dumps(radius)}'
        assert old in text
        text = text.replace(old, f'"wheel_radius_m": {FOUR_HUNDRED}', 1)
    else:
        text = HOSTILE[hostile]["json"]
    path.write_text(text, encoding="utf-8")
    refused(cli("simulate", str(folder), "--behavior", "driving", "--seconds", "0.2"), path)


def test_a_hostile_snapshot(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text(
        'conceptual = true\n[[query]]\nname = "drive"\nabilities = ["driving"]\n',
        encoding="utf-8",
    )
    snap = tmp_path / "s.snapshot.json"
    for hostile in sorted(HOSTILE):
        snap.write_text(HOSTILE[hostile]["json"], encoding="utf-8")
        refused(cli("regress", str(suite)), snap)


@pytest.mark.parametrize("hostile", sorted(HOSTILE))
def test_a_hostile_marker_of_an_output_folder(cli, tmp_path: Path, hostile: str) -> None:
    """``--out DIR --force`` reads DIR/.parmor, parmor's JSON list of the files it wrote."""
    out = tmp_path / "b"
    out.mkdir()
    marker = out / ".parmor"
    marker.write_text(HOSTILE[hostile]["json"], encoding="utf-8")
    (out / "mine.txt").write_text("mine", encoding="utf-8")
    argv = ["design", "driving", "--conceptual", "--no-input", "--out", str(out), "--force"]
    refused(cli(*argv), marker)
    assert sorted(p.name for p in out.iterdir()) == [".parmor", "mine.txt"]
