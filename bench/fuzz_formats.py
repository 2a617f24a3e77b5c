"""Fuzz every user file format (issue 34): seeded, deterministic mutations of the shipped
part kinds, catalogs (complete and extending another), perturbation table, studies,
suites, design records, programs (checked against a design's behaviours), the ``.parmor``
list of a bundle's files and KIF facts, each read by parmor's own reader (and a share
through the command line with ``--out``). Counts tracebacks (an exception that is not
parmor's InputError, or ExportError for ``.parmor``), hangs (a case over its time budget),
refusals that do not name the file and a key (or line:col), and files written by a refused
run (an ``--out`` folder, or a bundle's folder changed by a refused ``--force``).

    python bench/fuzz_formats.py [--cases 2400] [--seed 34] [--cli-share 0.05]

tests/adron/test_schema_fuzz.py runs a few hundred of the same cases.
"""

from __future__ import annotations

import argparse
import copy
import io
import json
import math
import random
import re
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: seconds one case may take before it counts as a hang
BUDGET_S = 60

HOSTILE: tuple[Any, ...] = (
    1e308,
    -1e308,
    -1,
    0,
    -0.03,
    1e6,
    1e-300,
    "",
    " ",
    "x",
    "1e308 m",
    "1e308 kg",
    "-5 mm",
    "nan",
    "-pi",
    "9**9**9",
    "a" * 300,
    "☃\u202e",
    True,
    False,
    [],
    {},
    [1, 2, 3],
    {"x": 1},
    [[[[]]]],
    10**299,
)


# ---- a TOML writer (inline tables: any nesting the data has) ---------------------------------


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return (
            "{" + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + "}"
        )
    raise TypeError(type(v))


def toml_text(data: dict) -> str:
    return "".join(f"{json.dumps(str(k))} = {_toml_value(v)}\n" for k, v in data.items())


# ---- mutations -------------------------------------------------------------------------------


def _paths(data: Any, path: tuple = ()) -> list[tuple]:
    out = [path]
    if isinstance(data, dict):
        for k, v in data.items():
            out += _paths(v, (*path, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out += _paths(v, (*path, i))
    return out


def _get(data: Any, path: tuple) -> Any:
    for p in path:
        data = data[p]
    return data


def mutate(data: Any, rng: random.Random) -> tuple[Any, str]:
    """A copy of ``data`` with one to three random changes; and what they were."""
    data = copy.deepcopy(data)
    told = []
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = rng.choice(paths)
        parent, key = _get(data, path[:-1]), path[-1]
        what = rng.random()
        if what < 0.55:
            parent[key] = copy.deepcopy(rng.choice(HOSTILE))
            told.append(f"{path} = {parent[key]!r:.40}")
        elif what < 0.7:
            del parent[key]
            told.append(f"del {path}")
        elif what < 0.8 and isinstance(parent, dict):
            parent[rng.choice(("colour", "extra", "Format", "x y"))] = 1
            told.append(f"unknown key beside {path}")
        elif what < 0.9 and isinstance(parent, list):
            parent.append(copy.deepcopy(parent[key]))
            told.append(f"{path} repeated")
        else:
            v = parent[key]
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                parent[key] = rng.choice((-v, v * 1e6, -abs(v) - 1, 0))
            elif isinstance(v, str):
                parent[key] = rng.choice((v[::-1], v + v, v.upper(), "-" + v))
            elif isinstance(v, list) and len(v) > 1:
                parent[key] = list(reversed(v))
            told.append(f"{path} perturbed")
    return data, "; ".join(told)


# ---- the formats -----------------------------------------------------------------------------


@dataclass
class Outcome:
    cases: int = 0
    accepted: int = 0
    refused: int = 0
    tracebacks: list[str] = field(default_factory=list)
    hangs: list[str] = field(default_factory=list)
    unnamed: list[str] = field(default_factory=list)
    written: list[str] = field(default_factory=list)
    by_format: Counter = field(default_factory=Counter)
    refused_by_format: Counter = field(default_factory=Counter)

    def figures(self) -> dict:
        return {
            "cases": self.cases,
            "accepted": self.accepted,
            "refused (exit 2)": self.refused,
            "tracebacks": len(self.tracebacks),
            "hangs": len(self.hangs),
            "refusals not naming file and key": len(self.unnamed),
            "files written by a refused run": len(self.written),
            "by format (cases, refused)": {
                k: (n, self.refused_by_format[k]) for k, n in sorted(self.by_format.items())
            },
        }


class _Hang(BaseException):
    pass


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (relative name -> bytes; a link by its target)."""
    import os

    out = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if p.is_symlink():
            out[rel] = os.readlink(p).encode()
        elif p.is_file():
            out[rel] = p.read_bytes()
    return out


def _alarm(signum, frame):
    raise _Hang()


_NAMED = re.compile(r"(:\d+:\d+:|: [^\s:]+.*|\.\w+|\[\d+\])")


def _names_file_and_key(message: str, source: str) -> bool:
    """Whether a refusal names the file and then a key (or line:col, or the bound)."""
    i = message.find(source)
    return i >= 0 and bool(_NAMED.search(message[i + len(source) :]))


class Fuzzer:
    def __init__(self, seed: int, cli_share: float, folder: Path) -> None:
        self.rng = random.Random(seed)
        self.cli_share = cli_share
        self.folder = folder
        self.outcome = Outcome()
        self.n = 0
        self.bases = self._bases()

    # the valid files each format starts from
    def _bases(self) -> dict[str, Any]:
        import tomllib

        def toml(p: str) -> dict:
            return tomllib.loads((ROOT / p).read_text(encoding="utf-8"))

        small_parts = {
            "constants": {"trunk_thickness": 0.03},
            "kind": [
                k
                for k in toml("kinematics/partkinds.toml")["kind"]
                if k["class"] in ("RobotTrunk", "MultipedLeg")
            ],
            "serial": {
                "default_lengths": {"first": 0.1, "rest": 0.15},
                "3": toml("kinematics/partkinds.toml")["serial"]["3"],
            },
        }
        dyn = toml("adron/catalogs/dynamixel.toml")
        return {
            "partkinds": toml("kinematics/partkinds.toml"),
            "partkinds-small": small_parts,
            "catalog": toml("adron/catalog.toml"),
            "catalog-extending": {
                "catalog": {
                    "name": "mine",
                    "currency": "EUR",
                    "version": "1",
                    "extends": "default",
                    "replace": ["printer"],
                    "remove": ["MPU-6050"],
                },
                "design": {"torque_safety_factor": 1.6, "gravity": "9.7 m/s^2"},
                "passive": {"min_wall": "1.5 mm", "printer_bed": ["250 mm", "210 mm", "220 mm"]},
                "printer": [{"model": "Big", "bed": ["1 m", "1 m", "1 m"]}],
                "module": [
                    {
                        "model": "LiPo-2S",
                        "class": "BatteryModule",
                        "mass": "120 g",
                        "size": ["100 mm", "50 mm", "30 mm"],
                        "cost": 15.0,
                        "current": "0 A",
                        "capacity": "1 Ah",
                        "voltage": "7.4 V",
                        "c_rating": 25,
                    }
                ],
            },
            "perturbation": dyn.get("perturbation") or {"floor": {"max_slope": "2 deg"}},
            "study": toml("studies/parameter-range.toml"),
            "suite": {
                "conceptual": True,
                "query": [
                    {"name": "walk", "abilities": ["walking"], "answers": {"grasping": "no"}},
                    {
                        "name": "arm",
                        "abilities": ["pick-and-place"],
                        "params": {"object_shape": "oval"},
                    },
                ],
            },
            "program": {
                "program": [
                    {
                        "repeat": 2,
                        "body": [{"do": "driving", "params": {"v": 0.1, "seconds": 1}}],
                    },
                    {"do": "turning", "params": {"angle": 0.5}},
                    {
                        "if": {"report": "x_m", "op": ">", "value": 0.01},
                        "then": [{"wait": 0.1}],
                        "else": [],
                    },
                ]
            },
            "kif": [
                ["defaultLength", "HexapodRobot", '"tibia"', '"12 cm"'],
                ["defaultParameter", "HexapodRobot", '"payload"', '"0.1 kg"'],
                ["requiredPartCount", "RobotWalking", "MultipedLeg", "4"],
                ["instance", "MyThing", "Robot"],
                ["connectedTo", "A", "B"],
            ],
        }

    def _file(self, name: str, text: str) -> Path:
        self.n += 1
        p = self.folder / f"{self.n:05d}-{name}"
        p.write_text(text, encoding="utf-8")
        return p

    def _run(self, fmt: str, what: str, call: Callable[[], tuple[str, str | None]]) -> None:
        """``call`` -> ('ok'|'refused', message); anything else raised is a traceback."""
        from adron.errors import InputError

        o = self.outcome
        o.cases += 1
        o.by_format[fmt] += 1
        old = signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(BUDGET_S)
        try:
            status, message = call()
        except _Hang:
            o.hangs.append(f"{fmt}: {what}")
            return
        except (InputError, ValueError) as e:  # PartKindError is a ValueError: named below
            from kinematics.partkinds import PartKindError

            if not isinstance(e, InputError | PartKindError):
                o.tracebacks.append(f"{fmt}: {what}: {traceback.format_exc(limit=-4)}")
                return
            status, message = "refused", str(e)
        except BaseException:
            o.tracebacks.append(f"{fmt}: {what}: {traceback.format_exc(limit=-4)}")
            return
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)
        if status == "ok":
            o.accepted += 1
        elif status == "refused":
            o.refused += 1
            o.refused_by_format[fmt] += 1
            if message is not None and not message.startswith("\x00"):
                src = message.split("\x01")[0] if "\x01" in message else None
                text = message.split("\x01")[-1]
                if src is not None and not _names_file_and_key(text, src):
                    o.unnamed.append(f"{fmt}: {what}: {text[:200]}")
        elif status == "traceback":
            o.tracebacks.append(f"{fmt}: {what}: {message}")
        elif status == "written":
            o.written.append(f"{fmt}: {what}: {message}")

    # -- one case of each format -------------------------------------------------------------

    def _cli(self, argv: list[str], source: str, out: Path | None) -> tuple[str, str | None]:
        from synth.commands.cli import main

        err = io.StringIO()
        code = main(argv, out=io.StringIO(), err=err)
        text = err.getvalue()
        if "Traceback" in text or code not in (0, 1, 2, 3):
            return "traceback", text[-500:]
        if code == 2:
            if out is not None and out.exists():
                return "written", str(out)
            said = [x for x in text.splitlines() if x.startswith("parmor") and "note:" not in x]
            return "refused", f"{source}\x01{said[-1] if said else text}"
        return "ok", None

    def partkinds(self, base: str) -> None:
        from kinematics.partkinds import load

        data, what = mutate(self.bases[base], self.rng)
        try:
            text = toml_text(data)
        except TypeError:
            return
        f = self._file("parts.toml", text)
        if self.rng.random() < self.cli_share:
            out = self.folder / f"out{self.n}"
            argv = [
                "design",
                "walking",
                "--answer",
                "grasping=no",
                "--answer",
                "rough-terrain-walking=no",
                "--no-input",
                "--no-verify",
                "--parts",
                str(f),
                "--out",
                str(out),
            ]
            self._run("partkinds (cli)", what, lambda: self._cli(argv, str(f), out))
            return

        def call():
            try:
                load([f])
            except ValueError as e:
                return "refused", f"{f}\x01{e}"
            return "ok", None

        self._run("partkinds", what, call)

    def catalog(self, base: str) -> None:
        from adron.catalog import load_catalog

        data, what = mutate(self.bases[base], self.rng)
        f = self._file("catalog.toml", toml_text(data))

        def call():
            try:
                load_catalog(f)
            except Exception as e:
                from adron.errors import InputError

                if isinstance(e, InputError):
                    return "refused", f"{f}\x01{e}"
                raise
            return "ok", None

        self._run("catalog", what, call)

    def perturbation(self) -> None:
        from synth.verification.perturb import ranges

        data, what = mutate({"perturbation": self.bases["perturbation"]}, self.rng)
        table = data.get("perturbation")

        def call():
            if not isinstance(table, dict):
                return "ok", None  # the catalog's reader refuses it: not a table
            try:
                ranges(table, where="mine.toml")
            except Exception as e:
                from adron.errors import InputError

                if isinstance(e, InputError):
                    return "refused", f"mine.toml\x01{e}"
                raise
            return "ok", None

        self._run("perturbation", what, call)

    def study_or_suite(self, kind: str) -> None:
        from synth.commands.regress import load_suite
        from synth.commands.sweep import load_study

        data, what = mutate(self.bases[kind], self.rng)
        f = self._file(f"{kind}.toml", toml_text(data))
        read = load_study if kind == "study" else load_suite

        def call():
            try:
                read(f)
            except Exception as e:
                from adron.errors import InputError

                if isinstance(e, InputError):
                    return "refused", f"{f}\x01{e}"
                raise
            return "ok", None

        self._run(kind, what, call)

    def record(self, folder: Path) -> None:
        """A mutated design.json read as simulate, run, blocks and ros read it."""
        import shutil

        from synth.verification.runs import controller_for_model
        from synth.verification.source import Bundle

        base = json.loads((folder / "design.json").read_text(encoding="utf-8"))
        data, what = mutate(base, self.rng)
        b = self.folder / f"bundle{self.n}"
        self.n += 1
        shutil.copytree(folder, b)
        (b / "design.json").write_text(json.dumps(data), encoding="utf-8")
        src = str(b / "design.json")
        if self.rng.random() < self.cli_share * 4:
            argv = ["simulate", str(b), "--behavior", "driving", "--seconds", "0.1"]
            self._run("design record (cli)", what, lambda: self._cli(argv, src, None))
            shutil.rmtree(b, ignore_errors=True)
            return

        def call():
            from adron.errors import InputError

            try:
                bundle = Bundle.read(b)
                controller_for_model(bundle.record, bundle.model())
            except InputError as e:
                return "refused", f"{src}\x01{e}" if "design.json" in str(e) else "\x00"
            return "ok", None

        self._run("design record", what, call)
        shutil.rmtree(b, ignore_errors=True)

    def program(self, folder: Path) -> None:
        """A mutated JSON program, read as ``parmor run`` reads it (the file's schema) and
        checked against the bundle's behaviours; a share run through the command line."""
        from program.script import read_file, validate

        data, what = mutate(self.bases["program"], self.rng)
        try:
            text = json.dumps(data, allow_nan=True)
        except (TypeError, ValueError):
            return
        f = self._file("program.json", text)
        if self.rng.random() < self.cli_share:
            argv = ["run", str(f), str(folder), "--time-limit", "30"]
            self._run("program (cli)", what, lambda: self._cli(argv, str(f), None))
            return

        def call():
            from adron.errors import InputError

            try:
                form, program = read_file(f)
                validate(program, self.behaviors(folder), str(f))
            except InputError as e:
                return "refused", f"{f}\x01{e}"
            return "ok", None

        self._run("program", what, call)

    def behaviors(self, folder: Path) -> dict:
        """The behaviours a program may call on the bundle (as the block server has them)."""
        if not hasattr(self, "_behaviors"):
            from program.blocks import bundle_controller, read_record
            from program.session import program_behaviors

            record = read_record(folder)
            controller = bundle_controller(folder, record)
            self._behaviors = program_behaviors(controller, record.get("abilities", ()))
        return self._behaviors

    def manifest(self, folder: Path) -> None:
        """A mutated ``.parmor`` in a copy of the bundle, replaced with ``--force`` as
        ``parmor design --out DIR --force`` does: refused (naming ``.parmor`` and a key)
        with the folder untouched, or accepted."""
        import shutil

        from export.bundle import MARKER, write_bundle

        base = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        data, what = mutate(base, self.rng)
        b = self.folder / f"bundle{self.n}"
        self.n += 1
        shutil.copytree(folder, b)
        (b / MARKER).write_text(json.dumps(data), encoding="utf-8")
        before = _tree(b)
        src = str(b)  # .parmor's key, or a file it lists that was changed since

        def call():
            from adron.errors import ExportError

            try:
                write_bundle(b, {"design.json": "{}", "new.txt": "new"}, force=True)
            except ExportError as e:
                if _tree(b) != before:
                    return "written", f"{b} changed by a refused --force"
                return "refused", f"{src}\x01{e}"
            return "ok", None

        self._run(".parmor", what, call)
        shutil.rmtree(b, ignore_errors=True)

    def kif(self) -> None:
        """Facts parmor reads by position, with arguments dropped, added or made hostile,
        loaded as a user's ontology and designed (conceptually for most)."""
        facts = copy.deepcopy(self.bases["kif"])
        fact = self.rng.choice(facts)
        what = self.rng.random()
        if what < 0.3 and len(fact) > 1:
            del fact[self.rng.randrange(1, len(fact))]
        elif what < 0.45:
            fact.append(self.rng.choice(('"x"', "Foo", "3")))
        else:
            i = self.rng.randrange(1, len(fact))
            fact[i] = self.rng.choice(
                (
                    '"1e308 m"',
                    '"1e308 kg"',
                    '"-3 cm"',
                    '"0 m"',
                    '"nolength"',
                    '"3 cm"',
                    "Nothing",
                    '""',
                    "1e308",
                )
            )
        text = "(" + " ".join(fact) + ")\n"
        f = self._file("mine.kif", text)
        out = self.folder / f"out{self.n}"
        argv = [
            "design",
            "walking",
            "--answer",
            "grasping=no",
            "--answer",
            "rough-terrain-walking=yes",
            "--no-input",
            "--no-verify",
            "--ontology",
            str(f),
            "--out",
            str(out),
        ]
        self._run("kif facts", text.strip(), lambda: self._cli(argv, str(f), out))


def run(
    cases: int,
    seed: int = 34,
    cli_share: float = 0.05,
    record_share: float = 0.12,
    progress: Callable[[str], None] | None = None,
) -> Outcome:
    """Run ``cases`` seeded cases over every format; their Outcome."""
    import io as _io

    from synth.commands.cli import main

    with tempfile.TemporaryDirectory(prefix="parmor-fuzz-") as d:
        folder = Path(d)
        fz = Fuzzer(seed, cli_share, folder)
        bundle = folder / "cart"
        err = _io.StringIO()
        code = main(["design", "driving", "--no-verify", "--out", str(bundle)], _io.StringIO(), err)
        if code != 0:
            raise RuntimeError(err.getvalue())
        weights = [
            ("partkinds", 0.17),
            ("partkinds-small", 0.10),
            ("catalog", 0.12),
            ("catalog-extending", 0.06),
            ("perturbation", 0.08),
            ("study", 0.09),
            ("suite", 0.08),
            ("record", record_share),
            ("program", 0.08),
            ("manifest", 0.05),
            ("kif", 0.07),
        ]
        names = [n for n, _ in weights]
        w = [x for _, x in weights]
        t0 = time.monotonic()
        for i in range(cases):
            kind = fz.rng.choices(names, w)[0]
            if kind.startswith("partkinds"):
                fz.partkinds(kind)
            elif kind.startswith("catalog"):
                fz.catalog(kind)
            elif kind == "perturbation":
                fz.perturbation()
            elif kind in ("study", "suite"):
                fz.study_or_suite(kind)
            elif kind == "record":
                fz.record(bundle)
            elif kind == "program":
                fz.program(bundle)
            elif kind == "manifest":
                fz.manifest(bundle)
            else:
                fz.kif()
            if progress is not None and (i + 1) % 100 == 0:
                progress(f"{i + 1} cases, {time.monotonic() - t0:.0f} s")
        return fz.outcome


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=2400)
    ap.add_argument("--seed", type=int, default=34)
    ap.add_argument("--cli-share", type=float, default=0.05)
    args = ap.parse_args(argv)
    o = run(args.cases, args.seed, args.cli_share, progress=lambda s: print(s, file=sys.stderr))
    print(json.dumps(o.figures(), indent=2))
    for kind in ("tracebacks", "hangs", "unnamed", "written"):
        for line in getattr(o, kind)[:10]:
            print(f"{kind}: {line}")
    return 1 if (o.tracebacks or o.hangs or o.unnamed or o.written) else 0


if __name__ == "__main__":
    sys.exit(main())
