"""The block page speaks to a novice (issue 24): angles in degrees, units written out,
the design's ranges shown, and a value beyond its range refused in the page before it is
sent. The page's conversions are checked in Chromium (Playwright) against the toolbox the
Python side writes; the Python text and the program stay in SI units."""

from __future__ import annotations

import io
import math

import pytest

from program.blocks import DISPLAY_UNITS, display, toolbox
from synth.cli import main
from tests.test_blocks import _open, chromium  # noqa: F401  (a fixture)


def test_units_are_written_out_and_angles_shown_in_degrees() -> None:
    assert display("rad") == {"unit": "degrees", "scale": 180 / math.pi, "step": 0.1}
    assert display("m/s")["unit"] == "metres per second"
    assert display("furlong") == {"unit": "furlong", "scale": 1.0, "step": None}
    # every written-out unit is a word a child reads, never the SI symbol
    for unit, (written, scale, _) in DISPLAY_UNITS.items():
        assert written != unit and scale > 0


@pytest.fixture(scope="module")
def hexapod(tmp_path_factory):
    folder = tmp_path_factory.mktemp("novice") / "hexapod"
    out, err = io.StringIO(), io.StringIO()
    args = ["design", "rough-terrain-walking", "--no-input", "--no-verify", "--out", str(folder)]
    assert main(args, out, err) == 0, err.getvalue()
    assert main(["blocks", str(folder)], out, err) == 0, err.getvalue()
    return folder


def test_toolbox_carries_how_each_parameter_is_shown(hexapod) -> None:
    from program.blocks import bundle_controller, read_record

    record = read_record(hexapod)
    tools = {t["name"]: t for t in toolbox(bundle_controller(hexapod, record), record["abilities"])}
    angle = {p["name"]: p for p in tools["turning"]["params"]}["angle"]
    assert angle["unit"] == "rad" and angle["display"]["unit"] == "degrees"


_FIELDS = """() => {
  const ws = parmor.workspace;
  const b = ws.newBlock('parmor_do:turning'); b.initSvg(); b.render();
  const start = ws.getTopBlocks(false).find((t) => t.type === 'parmor_program');
  start.getInput('BODY').connection.connect(b.previousConnection);
  const row = b.getInput('P_angle').fieldRow.map((f) => f.getText()).join(' ');
  const shown = Number(b.getFieldValue('angle'));
  b.setFieldValue(90, 'angle');
  const sent = parmor.programJson().program[0].params.angle;
  const python = parmor.python();
  b.setFieldValue(100000, 'angle');
  return {row, shown, sent, python, id: b.id};
}"""


def test_the_page_shows_degrees_and_sends_radians(chromium, hexapod) -> None:  # noqa: F811
    from program.blocks import bundle_controller, read_record

    record = read_record(hexapod)
    default = bundle_controller(hexapod, record).behaviors["turning"].params
    default = {p.name: p.default for p in default}["angle"]
    page = _open(chromium, (hexapod / "blocks" / "index.html").as_uri())
    try:
        got = page.evaluate(_FIELDS)
        assert "degrees [" in got["row"], got["row"]
        assert "rad" not in got["row"]
        # the default angle shown in degrees to the field's 0.1 step
        assert got["shown"] == pytest.approx(round(math.degrees(default), 1))
        assert got["sent"] == pytest.approx(math.pi / 2, abs=1e-12)  # 90 degrees, in rad
        assert "angle=1.5707963267948966" in got["python"]
        # 100000 degrees is beyond the range: warned, and Run refuses it before sending
        page.wait_for_function(
            "(id) => parmor.workspace.getBlockById(id).hasIcon(Blockly.icons.IconType.WARNING)",
            arg=got["id"],
        )
        reply = page.evaluate("parmor.run()")
        assert reply["error"].startswith("not sent: turning: angle 100000 is outside degrees ["), (
            reply
        )
        assert not page.errors
    finally:
        page.close()
