"""The block page of a design bundle (``parmor blocks DIR``).

The page (``DIR/blocks/index.html``) is built on Blockly: its toolbox has one block per
behaviour the design lists (``Controller.listed`` of the record's abilities), with a field
per parameter (its unit and limits shown; a choice is a dropdown), and the blocks repeat,
wait and if/else on what the robot reports (``program.script.REPORTS``). A Blockly
generator in the page writes the Python program the blocks stand for (the text of
``program.script.to_python``); with ``parmor blocks DIR --serve`` the page's Run button
sends the program as JSON to the local server (:mod:`program.server`) and shows the reply:
the path travelled, the verdict figures and the robot moving (three.js).

Everything here is generic: the toolbox is read from the controller's typed behaviours
(:class:`gaits.base.BehaviorSpec`), never from the robot type.

Where the JavaScript comes from: the page's own files are ``web/page/`` and Blockly and
three.js are the npm packages pinned by ``web/package.json`` (``make web`` installs them
into ``web/node_modules``). ``web/`` is found from the environment variable
``PARMOR_WEB`` when set (a folder holding ``page/`` and ``node_modules/``), otherwise
beside the source tree (``<repository>/web``). Every file the page needs is copied into
``DIR/blocks/``, so the page works offline from the bundle (``file://``) and the bundle can
be moved.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from adron.errors import ExportError, InputError
from export.bundle import write_bundle
from program.script import LIMITS, REPORTS, to_python
from program.session import program_behaviors
from synth.verification.runs import controller_for_model
from synth.verification.source import Bundle

if TYPE_CHECKING:
    from gaits.base import Controller

#: Environment variable naming the web folder (``page/`` and ``node_modules/``).
WEB_ENV = "PARMOR_WEB"
#: The make target that installs the npm packages.
MAKE_TARGET = "make web"
#: The folder of the page inside a bundle.
PAGE_DIR = "blocks"
#: The page's own files (in ``web/page/``), copied as they are.
PAGE_FILES = ("index.html", "parmor.js", "style.css")
#: npm files the page needs: path in ``node_modules`` -> path in ``DIR/blocks/vendor``.
#: Blockly's UMD build loads from ``file://`` with a plain script tag; three.js is an ES
#: module, imported only when a reply is shown (served pages, never ``file://``).
VENDOR_FILES: dict[str, str] = {
    "blockly/blockly_compressed.js": "blockly_compressed.js",
    "blockly/msg/en.js": "blockly_msg_en.js",
    "blockly/package.json": "blockly.package.json",
    "three/build/three.module.min.js": "three.module.min.js",
    "three/build/three.core.min.js": "three.core.min.js",
    "three/LICENSE": "three.LICENSE",
    "three/package.json": "three.package.json",
}
#: Folders of npm files the page needs (Blockly's cursors, icons and sounds).
VENDOR_DIRS: dict[str, str] = {"blockly/media": "media"}


def web_dir() -> Path:
    """The web folder: ``$PARMOR_WEB`` or ``web/`` beside the source tree."""
    env = os.environ.get(WEB_ENV)
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1] / "web"


def _require_web(web: Path) -> None:
    """InputError (exit 2) naming what to run when the page's files are absent."""
    page = web / "page"
    missing = [page / f for f in PAGE_FILES if not (page / f).is_file()]
    nm = web / "node_modules"
    missing += [nm / f for f in VENDOR_FILES if not (nm / f).is_file()]
    missing += [nm / d for d in VENDOR_DIRS if not (nm / d).is_dir()]
    if missing:
        raise InputError(
            f"the block page's JavaScript is not installed ({missing[0]} is missing): run "
            f"'{MAKE_TARGET}' in the parmor source tree (it installs Blockly and three.js with "
            f"npm into web/node_modules), or set {WEB_ENV} to a folder holding page/ and "
            "node_modules/"
        )


def read_record(folder: Path) -> dict:
    """The design record of a bundle folder; InputError when it is not a sized one."""

    return Bundle.read(folder).record


def bundle_controller(folder: Path, record: Mapping) -> Controller:
    """The design's controller, set up for the bundle's MuJoCo model as a run sets it up."""

    model = Bundle(folder=folder, record=dict(record)).model()
    try:
        return controller_for_model(record, model)
    except ValueError as e:
        raise InputError(f"{folder}: {e}") from None


def _limit(x: float | None) -> float | None:
    """A parameter limit as JSON (None: unbounded)."""
    return None if x is None or not math.isfinite(float(x)) else float(x)


def _value(x: object) -> object:
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return x
    if isinstance(x, int):
        return x
    return float(x)  # type: ignore[arg-type]


#: How the page shows a unit to a novice: the API's unit -> (the unit written out, the
#: factor from the API's value to the shown one, the step the field rounds to; None: as
#: typed). Angles are shown in degrees, as every block language for children (Scratch,
#: Bitbloq, Open Roberta) does; the program, its Python text and the API stay in SI
#: units (the page converts both ways). Units not listed are shown as they are.
DISPLAY_UNITS: dict[str, tuple[str, float, float | None]] = {
    "rad": ("degrees", 180.0 / math.pi, 0.1),
    "rad/s": ("degrees per second", 180.0 / math.pi, 0.1),
    "m": ("metres", 1.0, None),
    "m/s": ("metres per second", 1.0, None),
    "s": ("seconds", 1.0, None),
    "Hz": ("times per second", 1.0, None),
    "kg": ("kilograms", 1.0, None),
}


def display(unit: str) -> dict:
    """How the page shows a parameter of ``unit`` (:data:`DISPLAY_UNITS`): ``unit``
    written out, ``scale`` (shown = value x scale) and ``step`` (None: any)."""
    written, scale, step = DISPLAY_UNITS.get(unit, (unit, 1.0, None))
    return {"unit": written, "scale": scale, "step": step}


def toolbox(controller: Controller, abilities: Sequence[str]) -> list[dict]:
    """One entry per behaviour a program may call (name order; the listed ones and the
    sensing ones, :func:`program.session.program_behaviors`): name, doc, and its
    parameters (name, kind, default, unit, low, high, choices, doc, and how the page shows
    them: :func:`display`). Depends only on the
    controller's behaviour descriptions, so two designs whose controllers describe their
    behaviours alike get identical toolboxes."""

    out = []
    for name, spec in program_behaviors(controller, abilities).items():
        out.append(
            {
                "name": name,
                "doc": spec.doc,
                "params": [
                    {
                        "name": p.name,
                        "kind": p.kind,
                        "default": _value(p.default),
                        "unit": p.unit,
                        "low": _limit(p.low),
                        "high": _limit(p.high),
                        "choices": list(p.choices),
                        "doc": p.doc,
                        "display": display(p.unit),
                    }
                    for p in spec.params
                ],
            }
        )
    return out


def python_header() -> str:
    """What the Python text of every program starts with (before ``def main(robot):``),
    taken from :func:`program.script.to_python` so that the page writes the same text."""

    text = to_python({"program": []})
    head, sep, _ = text.partition("def main(robot):")
    if not sep:
        raise ExportError("program.script.to_python wrote no 'def main(robot):'")
    return head


def page_config(folder: Path, record: Mapping, controller: Controller) -> dict:
    """What the page is generated from: the robot, its toolbox, the reports the if block
    can test, the program limits and the Python header."""

    return {
        "robot_type": record["robot_type"],
        "bundle": folder.resolve().name,
        "toolbox": toolbox(controller, record.get("abilities", ())),
        "reports": [
            {"name": name, "unit": unit, "doc": doc} for name, (unit, doc) in REPORTS.items()
        ],
        "limits": dict(LIMITS),
        "python_header": python_header(),
    }


def page_files(config: Mapping, web: Path | None = None) -> dict[str, bytes]:
    """Every file of ``DIR/blocks/`` (relative path -> bytes); InputError when the npm
    files are absent."""
    web = web_dir() if web is None else web
    _require_web(web)
    files: dict[str, bytes] = {}
    for f in PAGE_FILES:
        files[f] = (web / "page" / f).read_bytes()
    nm = web / "node_modules"
    for src, dst in VENDOR_FILES.items():
        files[f"vendor/{dst}"] = (nm / src).read_bytes()
    for src, dst in VENDOR_DIRS.items():
        for path in sorted((nm / src).rglob("*")):
            if path.is_file():
                files[f"vendor/{dst}/{path.relative_to(nm / src).as_posix()}"] = path.read_bytes()
    body = json.dumps(config, indent=1, sort_keys=True, ensure_ascii=False)
    files["config.js"] = (
        "// Generated by 'parmor blocks': the design's behaviours, reports and limits.\n"
        f"window.PARMOR_CONFIG = {body};\n"
    ).encode()
    return files


def write_page(folder: str | Path) -> Path:
    """Write the block page of the bundle ``folder`` into ``folder/blocks/``; returns the
    page. The page's files replace those parmor wrote there before, all at once (a
    temporary folder beside it takes its place, ``export.bundle.write_bundle``); every
    other file there (a user's program) is kept, and one where a page file goes is refused
    (ExportError naming it)."""
    folder = Path(folder)
    record = read_record(folder)
    controller = bundle_controller(folder, record)
    files = page_files(page_config(folder, record, controller))

    target = write_bundle(folder / PAGE_DIR, files, force=True, adopt=True)
    return target / "index.html"
