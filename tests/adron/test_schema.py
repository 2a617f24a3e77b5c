"""Issue 34: every user file through one schema.

The inputs the issue lists (part kinds, KIF defaults and facts, design records, beds, a
body plan of hundreds of parts) end with exit 2 naming the file, the key and the value,
never a traceback, and nothing is written to ``--out``; the JSON Schemas in
``adron/schemas/`` are the models' (regenerated: ``python -m adron.write_schemas``) and
validate every file parmor ships with a standard validator (``check-jsonschema``).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# ---- the schema files ---------------------------------------------------------------------


def test_the_committed_schemas_are_the_models() -> None:
    from adron.write_schemas import FOLDER, rendered

    files = rendered()
    assert sorted(p.name for p in FOLDER.glob("*.schema.json")) == sorted(files)
    for name, text in files.items():
        assert (FOLDER / name).read_text(encoding="utf-8") == text, (
            f"adron/schemas/{name} is stale: run python -m adron.write_schemas"
        )


def _check_jsonschema() -> str:
    exe = Path(sys.executable).parent / "check-jsonschema"
    if not exe.is_file():
        found = shutil.which("check-jsonschema")
        if found is None:
            pytest.skip("check-jsonschema is not installed (pip install '.[test]')")
        return found
    return str(exe)


@pytest.fixture(scope="module")
def written_record(tmp_path_factory) -> Path:
    """The design.json of a quick ``parmor design ... --out``."""
    import io

    from synth.commands.cli import main

    folder = tmp_path_factory.mktemp("schema") / "cart"
    err = io.StringIO()
    code = main(["design", "driving", "--no-verify", "--out", str(folder)], io.StringIO(), err)
    assert code == 0, err.getvalue()
    return folder / "design.json"


def _shipped() -> list[tuple[str, list[Path]]]:
    return [
        (
            "catalog",
            [ROOT / "adron/catalog.toml", *sorted((ROOT / "adron/catalogs").glob("*.toml"))],
        ),
        (
            "partkinds",
            [
                ROOT / "kinematics/partkinds.toml",
                ROOT / "docs/examples/stilt_leg.toml",
                ROOT / "docs/examples/balloon_wheel.toml",
                ROOT / "docs/examples/camera.toml",
                *sorted((ROOT / "tests/data/any_part_kind").glob("*.toml")),
            ],
        ),
        ("perturb", [ROOT / "synth/verification/perturb.toml"]),
        (
            "study",
            [
                *sorted((ROOT / "studies").glob("*.toml")),
                ROOT / "docs/examples/wheels.toml",
                ROOT / "docs/examples/finalists.toml",
            ],
        ),
        ("program", [ROOT / "examples/square.json", ROOT / "docs/examples/walk.json"]),
    ]


def test_every_data_file_parmor_ships_has_its_schema_here() -> None:
    """A new catalog, part kinds file, study or program in the tree is validated below
    (or this test names it)."""
    covered = {p for _, paths in _shipped() for p in paths}
    folders = ("adron", "kinematics", "export", "synth", "studies", "examples", "docs/examples")
    found = {
        p
        for folder in folders
        for pattern in ("*.toml", "*.json")
        for p in (ROOT / folder).rglob(pattern)
        if "schemas" not in p.parts
    }
    assert found - covered == set()


@pytest.mark.parametrize(("schema", "paths"), _shipped(), ids=[s for s, _ in _shipped()])
def test_every_shipped_file_passes_its_schema_with_a_standard_validator(
    schema: str, paths: list[Path]
) -> None:
    assert paths
    exe = _check_jsonschema()
    r = subprocess.run(
        [exe, "--schemafile", str(ROOT / f"adron/schemas/{schema}.schema.json"), *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout + r.stderr


def test_a_written_design_record_passes_its_schema(written_record: Path) -> None:
    record = json.loads(written_record.read_text(encoding="utf-8"))
    assert record["format"] == 1
    exe = _check_jsonschema()
    r = subprocess.run(
        [
            exe,
            "--schemafile",
            str(ROOT / "adron/schemas/design-record.schema.json"),
            str(written_record),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout + r.stderr


def _validates(schema: str, *paths: Path) -> subprocess.CompletedProcess:
    """``check-jsonschema`` of ``paths`` (JSON unless their suffix says TOML) against the
    format ``schema``."""
    return subprocess.run(
        [
            _check_jsonschema(),
            "--default-filetype",
            "json",
            "--schemafile",
            str(ROOT / f"adron/schemas/{schema}.schema.json"),
            *map(str, paths),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_every_manifest_of_a_written_bundle_passes_its_schema(written_record: Path) -> None:
    """``.parmor`` (no suffix: read as JSON), in the bundle and in each folder below that
    holds one."""
    manifests = sorted(written_record.parent.rglob(".parmor"))
    assert manifests
    r = _validates("manifest", *manifests)
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_block_pages_folder_passes_its_schemas(written_record: Path, tmp_path: Path) -> None:
    """What ``make demo`` writes after the design: ``parmor blocks DIR`` (the page's own
    ``.parmor``), and the programs the page shows run as JSON."""
    from program.blocks import MAKE_TARGET, web_dir, write_page
    from tests.conftest import need

    need(web_dir() is not None, f"the npm files are absent ({MAKE_TARGET})")
    folder = tmp_path / "cart"
    shutil.copytree(written_record.parent, folder)
    page = write_page(folder)
    r = _validates("manifest", *sorted(folder.rglob(".parmor")))
    assert r.returncode == 0 and (page.parent / ".parmor").is_file(), r.stdout + r.stderr
    r = _validates("design-record", folder / "design.json")
    assert r.returncode == 0, r.stdout + r.stderr


BAD = {
    "partkinds": ("bad.toml", "[constants]\ntrunk_thickness = -0.03\n"),
    "program": ("bad.json", '{"program": [{"wait": 61}]}'),
    "manifest": (".parmor", '{"format": "parmor-files-1", "files": {"../x": "sha256:00"}}'),
    "catalog": ("bad.toml", '[catalog]\nname = "x"\ncurrency = "euro"\nversion = "1"\n'),
    "study": ("bad.toml", "[[request]]\nabilities = []\n"),
}


@pytest.mark.parametrize("schema", sorted(BAD))
def test_the_schemas_refuse_what_the_readers_refuse(tmp_path: Path, schema: str) -> None:
    """The control cases: the validator is not one that passes anything."""
    name, text = BAD[schema]
    bad = tmp_path / name
    bad.write_text(text, encoding="utf-8")
    r = _validates(schema, bad)
    assert r.returncode == 1, r.stdout + r.stderr


# ---- part kinds -----------------------------------------------------------------------------

TRUNK = """[[kind]]
class = "RobotTrunk"
root = true
body = "trunk"
lengths = {{ La1 = {la1}, La2 = 0.10 }}
box = ["La1", "La2", "trunk_thickness"]
mounts = [{{ child = "MultipedLeg", layout = "bilateral", span = "La1", track = "La2" }}]
"""
LEG = """[[kind]]
class = "MultipedLeg"
role = "leg"
end = "point_foot"
lengths = {{ coxa = 0.05, femur = 0.08, tibia = 0.1 }}
joints = [
  {{ name = "coxa", axis = "z", limits = [{lo}, {hi}], tube = {{ length = "{tube}" }} }},
  {{ name = "{second}", axis = "y", tube = {{ length = "femur" }} }},
  {{ name = "tibia", axis = "y", tube = {{ length = "tibia" }} }},
]
"""


def leg(lo='"-pi/3"', hi='"pi/3"', tube="coxa", second="femur") -> str:
    return LEG.format(lo=lo, hi=hi, tube=tube, second=second)


CHASSIS = """[[kind]]
class = "RobotChassis"
root = true
body = "chassis"
lengths = { L1 = 0.16, L2 = 0.12 }
box = ["L1", "L2", "chassis_thickness"]
"""
ROWS = '["b","y","-pi/2","pi/2","link"],["c","y","-pi/2","pi/2","link"]'

#: (a part kinds file, the key its message names, the value or words it shows)
PARTS = {
    "length 1e308": (TRUNK.format(la1="1e308"), "kind[0].lengths.La1", "1e+308"),
    "400 digits": (TRUNK.format(la1="4" * 400), ":5:", "400 digits"),
    "1000 km trunk": (TRUNK.format(la1="1e6"), "kind[0].lengths.La1", "at most 2 m"),
    "limits reversed": (leg('"pi/3"', '"-pi/3"'), "kind[0].joints[0].limits", "lower limit"),
    "limits 1e308": (leg("-1e308", "1e308"), "kind[0].joints[0].limits[0]", "-1e+308"),
    "joint names repeat": (leg(second="coxa"), "kind[0].joints[1].name", "'coxa'"),
    "tube undefined": (leg(tube="nope"), "kind[0].joints[0].tube.length", "'nope'"),
    "chassis without mounts": (CHASSIS, "kind[0].mounts", "no 'mounts'"),
    "serial row reversed": (
        f'[serial]\n3 = [["a","z","pi","-pi","link"],{ROWS}]\n',
        "serial.3[0]",
        "lower limit",
    ),
    "serial row mark": (
        f'[serial]\n3 = [["a","z","-pi","pi","tube"],{ROWS}]\n',
        "serial.3[0][4]",
        "'tube'",
    ),
    "serial column without link": (
        f'[serial]\n3 = [["a","z","-pi","pi"],{ROWS}]\n',
        "serial.3[0]",
        '"link" mark',
    ),
    "serial rows with one link": (
        '[serial]\n3 = [["a","z","-pi","pi","link"],["b","y","-1","1"],["c","y","-1","1"]]\n',
        "serial.3",
        "fewer than 2",
    ),
    "default_lengths 1e308": (
        "[serial]\ndefault_lengths = { first = 1e308, rest = 0.1 }\n",
        "serial.default_lengths.first",
        "1e+308",
    ),
    "trunk_thickness 1e308": (
        "[constants]\ntrunk_thickness = 1e308\n",
        "constants.trunk_thickness",
        "1e+308",
    ),
    "trunk_thickness -0.03": (
        "[constants]\ntrunk_thickness = -0.03\n",
        "constants.trunk_thickness",
        "-0.03",
    ),
    "class no ontology has": (
        '[[kind]]\nclass = "NoSuchClass"\nrole = "leg"\njoints = [{ name = "a" }]\n',
        "kind[0].class",
        "'NoSuchClass'",
    ),
    "two kinds of one class": (leg() + leg(), "kind[1].class", "'MultipedLeg'"),
    # found by a fresh fuzzing (seed 3434): a limit naming what no file defines (the
    # constants may come from another file: checked when the robot is assembled)
    "a limit naming PI": (leg('"-PI/3"'), "kind[0] (MultipedLeg)", "'PI'"),
}
WALKING = ["design", "walking", "--answer", "grasping=no", "--answer", "rough-terrain-walking=no"]


def refused(r, *words: str) -> None:
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err
    lines = [x for x in r.err.strip().splitlines() if not x.startswith(("parmor: note:", " "))]
    assert len(lines) == 1 and lines[0].startswith("parmor"), r.err
    for w in words:
        assert w in lines[0], (w, lines[0])


@pytest.mark.parametrize("case", sorted(PARTS))
def test_a_hostile_part_kinds_file_is_refused_naming_file_key_and_value(
    cli, tmp_path: Path, case: str
) -> None:
    text, key, shown = PARTS[case]
    f = tmp_path / "mine.toml"
    f.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    r = cli(*WALKING, "--no-input", "--no-verify", "--parts", str(f), "--out", str(out))
    refused(r, str(f), key, shown)
    assert not out.exists()


# ---- KIF facts and defaults -----------------------------------------------------------------

KIF = {
    "requiredPartCount of 1": ("(requiredPartCount RobotWalking)", "3 arguments, not 1"),
    "connectedTo of 1": ("(connectedTo Foo)", "2 arguments, not 1"),
    "instance of 1": ("(instance Foo)", "2 arguments, not 1"),
    "defaultParameter of 2": ('(defaultParameter HexapodRobot "payload")', "3 arguments, not 2"),
    "requiredPartCount of a string": (
        '(requiredPartCount RobotWalking MultipedLeg "x")',
        "argument 3 (N) is a whole number",
    ),
    "connectedTo of a number": ("(connectedTo 3 Foo)", "argument 1 (PART) is a name"),
    "defaultParameter dof 99": ('(defaultParameter HexapodRobot "dof" "99")', "3 to 7 joints"),
    "defaultLength 1e308 m": ('(defaultLength HexapodRobot "coxa" "1e308 m")', "at most 2 m"),
    "defaultParameter 1e308 kg": (
        '(defaultParameter HexapodRobot "payload" "1e308 kg")',
        "the range of --param payload",
    ),
    "defaultLength unused": ('(defaultLength HexapodRobot "nolength" "3 cm")', "no part of"),
    "defaultLength contradicted": ('(defaultLength HexapodRobot "tibia" "3 cm")', "contradicts"),
}


@pytest.mark.parametrize("case", sorted(KIF))
def test_kif_facts_and_defaults_are_checked_like_files(cli, tmp_path: Path, case: str) -> None:
    fact, words = KIF[case]
    f = tmp_path / "mine.kif"
    f.write_text(fact + "\n", encoding="utf-8")
    hexapod = [
        "design",
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=yes",
    ]
    out = tmp_path / "out"
    r = cli(*hexapod, "--ontology", str(f), "--no-input", "--no-verify", "--out", str(out))
    refused(r, f"{f}:1:1", words)
    assert not out.exists()


# ---- design records -------------------------------------------------------------------------

RECORDS = {
    "template {}": (lambda r: r.__setitem__("template", {}), "template"),
    "joint name a list": (lambda r: r["joints"][0].__setitem__("name", ["a"]), "joints[0].name"),
    "verified 1e308": (lambda r: r.__setitem__("verified", 1e308), "verified"),
    "held_by x": (lambda r: r["payload"].__setitem__("held_by", "x"), "payload.held_by"),
    "joints empty": (lambda r: r.__setitem__("joints", ""), "joints"),
    "format 2": (lambda r: r.__setitem__("format", 2), "format"),
    # found by a fresh fuzzing (seed 3434): each was a traceback or an unnamed refusal
    "params.payload a table": (lambda r: r["params"].__setitem__("payload", {"x": 1}), "params"),
    "params.payload 1e6": (lambda r: r["params"].__setitem__("payload", 1e6), "params.payload"),
    "loaded_mass_kg 1e-300": (lambda r: r.__setitem__("loaded_mass_kg", 1e-300), "loaded_mass"),
    "actuator torque 1e-300": (
        lambda r: r["joints"][0].__setitem__("actuator_torque_Nm", 1e-300),
        "joints[0].actuator_torque_Nm",
    ),
    "a body plan no controller drives": (
        lambda r: r["body_plan"]["root"].__setitem__("children", []),
        "body_plan",
    ),
    "format text": (lambda r: r.__setitem__("format", "1"), "format"),
}


@pytest.mark.parametrize("case", sorted(RECORDS))
@pytest.mark.parametrize("command", ["simulate", "simulate --perturb", "run", "ros", "blocks"])
def test_a_record_of_the_wrong_type_is_refused_naming_the_field(
    cli, written_record: Path, tmp_path: Path, case: str, command: str
) -> None:
    change, key = RECORDS[case]
    folder = tmp_path / "cart"
    shutil.copytree(written_record.parent, folder)
    record = json.loads(written_record.read_text(encoding="utf-8"))
    change(record)
    path = folder / "design.json"
    path.write_text(json.dumps(record), encoding="utf-8")
    program = tmp_path / "p.json"
    program.write_text('{"program": [{"do": "driving", "params": {"v": 0.1}}]}', encoding="utf-8")
    argv = {
        "simulate": ["simulate", str(folder), "--behavior", "driving", "--seconds", "0.2"],
        "simulate --perturb": [
            "simulate",
            str(folder),
            "--behavior",
            "driving",
            "--seconds",
            "0.2",
            "--perturb",
            "1",
        ],
        "run": ["run", str(program), str(folder)],
        "ros": ["ros", str(folder), "--force"],
        "blocks": ["blocks", str(folder)],
    }[command]
    before = sorted(p.name for p in folder.iterdir())
    refused(cli(*argv), str(path), key)
    assert sorted(p.name for p in folder.iterdir()) == before


def test_unknown_keys_of_a_record_pass(written_record: Path) -> None:
    """Others extend ``verified`` and ``notes``: keys this parmor does not know pass."""
    from export.record_schema import check_record

    record = json.loads(written_record.read_text(encoding="utf-8"))
    record["verified"]["a_new_figure"] = {"x": [1, 2]}
    record["notes"] = [{"anything": True}]
    record["a_new_field"] = "x"
    del record["format"]  # records written before it had none: the current format
    check_record(record, "design.json")


# ---- beds, streams, body plans --------------------------------------------------------------


@pytest.mark.parametrize(
    "bed", ["1e308x1e308x1e308m", "3x3x3m", "1e308x100x100mm", "2001x100x100mm"]
)
def test_an_absurd_bed_is_refused_with_its_bound(cli, tmp_path: Path, bed: str) -> None:
    out = tmp_path / "out"
    r = cli("design", "driving", "--no-verify", "--no-input", "--bed", bed, "--out", str(out))
    refused(r, "--bed", "at most 2000 mm")
    assert not out.exists()


def test_a_full_stderr_keeps_the_exit_code_of_bad_input() -> None:
    with open("/dev/full", "w") as full:
        r = subprocess.run(
            [sys.executable, "-m", "synth.commands.cli", "design", "flying", "--no-input"],
            stderr=full,
            stdout=subprocess.DEVNULL,
            cwd=ROOT,
            timeout=600,
        )
    assert r.returncode == 2


def long_snake(n: int) -> str:
    ms = [f"?M{i}" for i in range(1, n + 1)]
    lits = ["(instance ?HEAD SnakeHead)"] + [f"(instance {m} SnakeModule)" for m in ms]
    lits += [f"(robotPart {v} ?ROB)" for v in ["?HEAD", *ms]]
    chain = ["?HEAD", *ms]
    lits += [f"(connectedTo {a} {b})" for a, b in zip(chain, chain[1:], strict=False)]
    return f"""(subclass LongSnake SnakeRobot)
(instance LongSnake BaseConfiguration)
(subclass RobotLongRolling RobotLateralRolling)
(abilityName RobotLongRolling "long-rolling")
(abilityVerb RobotLongRolling "roll long")
(requiredPartCount RobotLongRolling SnakeModule {n})
(=> (instance ?ROB LongSnake) (exists (?HEAD {" ".join(ms)}) (and {" ".join(lits)})))
"""


def test_a_body_plan_of_thousands_of_parts_is_built_iteratively(tmp_path: Path) -> None:
    """A chain of 2000 modules is 2000 levels deep: twice Python's recursion limit."""
    from adron.kb import load
    from kinematics.bodyplan import BodyPlan
    from kinematics.partkinds import load as load_kinds
    from synth.reasoning.plans import plan_of

    f = tmp_path / "long.kif"
    f.write_text(long_snake(2000), encoding="utf-8")
    plan = plan_of(load([f]), "LongSnake", load_kinds())
    parts = list(plan.root.walk())
    assert len(parts) == 2001 and parts[-1].kind == "SnakeModule"
    again = BodyPlan.from_dict(plan.to_dict())  # (its JSON: 2000 levels, beyond any reader)
    assert again == plan and again.key() == plan.key() and hash(again.root) == hash(plan.root)


def test_a_body_plan_of_600_parts_is_refused_by_the_bus_not_a_traceback(cli, tmp_path) -> None:
    f = tmp_path / "long.kif"
    f.write_text(long_snake(600), encoding="utf-8")
    r = cli("design", "long-rolling", "--ontology", str(f), "--no-input", "--no-verify")
    assert r.code == 1 and "Traceback" not in r.err
    assert "602 active modules, over the limit" in r.err


# ---- studies and suites: the schema is where their rules live ----------------------------


def test_the_study_schemas_bound_is_the_command_lines() -> None:
    from adron.formats import MAX_ROBUSTNESS
    from synth.commands.cli import MAX_ROBUSTNESS as CLI_MAX

    assert MAX_ROBUSTNESS == CLI_MAX


STUDIES = {
    "robustness 65": ("robustness = 65\n[[request]]\nabilities = ['driving']\n", "robustness = 65"),
    "answer maybe": (
        "[[request]]\nabilities = ['walking']\nanswers = { grasping = 'maybe' }\n",
        "request[0].answers.grasping = 'maybe'",
    ),
    "a value twice": (
        "[[request]]\nabilities = ['rolling']\nparams = { payload = ['1kg', '2kg', '1kg'] }\n",
        "request[0].params.payload[2] = '1kg'",
    ),
    "a name of 300 characters": (
        f"[[request]]\nname = '{'n' * 300}'\nabilities = ['rolling']\n",
        "request[0].name = ",
    ),
    "ontology not a list": ("ontology = 'a.kif'\n[[request]]\nabilities = ['x']\n", "ontology = "),
}


@pytest.mark.parametrize("case", sorted(STUDIES))
def test_a_study_is_refused_by_its_schema_naming_file_key_and_value(
    tmp_path: Path, case: str
) -> None:
    """Cases built to fail the schema alone (nothing of the knowledge base is read)."""
    from adron.errors import InputError
    from synth.commands.sweep import load_study

    text, key = STUDIES[case]
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as e:
        load_study(path)
    assert str(e.value).startswith(f"{path}: {key}"), str(e.value)


# ---- catalogs: the schema is where their rules live --------------------------------------

CATALOG = (ROOT / "adron/catalog.toml").read_text(encoding="utf-8")


def _catalog(old: str, new: str) -> str:
    assert CATALOG.count(old) == 1, old
    return CATALOG.replace(old, new)


HEAD = '[catalog]\nname = "c"\ncurrency = "EUR"\nversion = "1"\nextends = "{parent}"\n'

#: (catalog text, the key path and value its refusal names); each was accepted (or a
#: traceback in the sizing) before the bound, or is a rule only the schema now holds
CATALOGS = {
    "gravity 1e300": (
        _catalog('gravity = "9.81 m/s^2"', 'gravity = "1e300 m/s^2"'),
        "design.gravity = '1e300 m/s^2': above 100 m/s^2",
    ),
    "modulus 1e290 GPa": (
        _catalog('youngs_modulus = "2.3 GPa"', 'youngs_modulus = "1e290 GPa"'),
        "material.youngs_modulus = '1e290 GPa': above 1000 GPa",
    ),
    "c rating 1e9": (
        _catalog("c_rating = 20", "c_rating = 1e9"),
        "module[1] (LiPo-3S-1500).c_rating = 1000000000.0: out of range",
    ),
    "safety factor 1e9": (
        _catalog("torque_safety_factor = 1.5", "torque_safety_factor = 1e9"),
        "design.torque_safety_factor = 1000000000.0: out of range",
    ),
    "version a list": (_catalog('version = "1"', "version = [1]"), "catalog.version = [1]"),
    "model with a newline": (
        _catalog('model = "SG90"', 'model = "SG\\n90"'),
        "actuator[0].model = 'SG\\n90': holds the control character U+000A",
    ),
    "perturbation spread 5": (
        CATALOG + "\n[perturbation.mass]\nspread = 5\n",
        "perturbation.mass.spread = 5: out of range",
    ),
    "extension: a wrong unit, its parent absent": (
        HEAD.format(parent="nowhere.toml") + '[passive]\nmin_wall = "1 kg"\n',
        "passive.min_wall = '1 kg': expected a length",
    ),
    "extension: rules after the merge": (
        HEAD.format(parent="default") + '[passive]\nmin_wall = "25 mm"\n',
        "passive.min_wall = '25 mm': leaves no hole",
    ),
    "a partial catalog that extends nothing": (
        '[catalog]\nname = "c"\ncurrency = "EUR"\nversion = "1"\n[design]\ngravity = "9 m/s^2"\n',
        "actuator: missing",
    ),
    "a torque below the facts' unit": (
        _catalog('stall_torque = "1.8 kgf*cm"', 'stall_torque = "1e-300 N*m"'),
        "actuator[0] (SG90).stall_torque = '1e-300 N*m': below 1 mN*m",
    ),
    "replace without extends": (
        _catalog('version = "1"', 'version = "1"\nreplace = ["actuator"]'),
        "catalog.replace = ['actuator']: only for a catalog that extends another",
    ),
}


@pytest.mark.parametrize("case", sorted(CATALOGS))
def test_a_catalog_is_refused_by_its_schema_naming_file_key_and_value(
    tmp_path: Path, case: str
) -> None:
    from adron.catalog import load_catalog
    from adron.errors import InputError

    text, words = CATALOGS[case]
    path = tmp_path / "mine.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as e:
        load_catalog(path)
    assert str(e.value).startswith(f"{path}: {words}"), str(e.value)


def test_an_extending_catalog_passes_its_json_schema_and_a_partial_one_does_not(
    tmp_path: Path,
) -> None:
    child = tmp_path / "child.toml"
    child.write_text(HEAD.format(parent="default") + "[design]\ngravity = '9 m/s^2'\n")
    assert _validates("catalog", child).returncode == 0
    alone = tmp_path / "alone.toml"
    alone.write_text(child.read_text().replace('extends = "default"\n', ""))
    assert _validates("catalog", alone).returncode == 1


def test_one_limit_of_perturbed_runs() -> None:
    """The study schema's bound and the command line's are one number."""
    from adron.formats import MAX_ROBUSTNESS as schema
    from synth.limits import MAX_ROBUSTNESS as cli

    assert schema == cli
