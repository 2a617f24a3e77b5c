"""The block page speaks to a novice (issue 24): angles in degrees, units written out,
the design's ranges shown, and a value beyond its range refused in the page before it is
sent. The page's conversions are checked in Chromium (Playwright) against the toolbox the
Python side writes; the Python text and the program stay in SI units."""

from __future__ import annotations

import io
import math

import pytest

from program.blocks import DISPLAY_UNITS, display, toolbox
from synth.commands.cli import main
from tests.program.test_blocks import _open, chromium  # noqa: F401  (a fixture)


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


# --- the design's own defaults and ranges on the page (issue 24) ---------------------------


def _bundle(folder, args: list[str]):
    out, err = io.StringIO(), io.StringIO()
    args = ["design", *args, "--no-input", "--no-verify", "--out", str(folder)]
    assert main(args, out, err) == 0, err.getvalue()
    assert main(["blocks", str(folder)], out, err) == 0, err.getvalue()
    return folder


@pytest.fixture(scope="module")
def snake(tmp_path_factory):
    return _bundle(tmp_path_factory.mktemp("novice") / "snake", ["sidewinding", "rolling"])


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    folder = tmp_path_factory.mktemp("novice") / "arm"
    return _bundle(folder, ["pick-and-place", "--param", "object_shape=cylinder"])


#: A behaviour block in the program: each numeric field's row as shown, the value the
#: program sends for it untouched, then for one field set to ``beyond`` (shown units)
#: what Run answers. ``nudge`` (shown units) is added to field ``near`` first.
_BLOCK = """async ([behaviour, field, beyond, near, nudge]) => {
  const ws = parmor.workspace;
  const start = ws.getTopBlocks(false).find((t) => t.type === 'parmor_program');
  const b = ws.newBlock('parmor_do:' + behaviour); b.initSvg(); b.render();
  start.getInput('BODY').connection.connect(b.previousConnection);
  const rows = {};
  for (const input of b.inputList) {
    if (input.name.startsWith('P_')) {
      rows[input.name.slice(2)] = input.fieldRow.map((f) => f.getText()).join(' ').trim();
    }
  }
  if (near) b.setFieldValue(Number(b.getFieldValue(near)) + nudge, near);
  const sent = parmor.programJson().program[0].params;
  const python = parmor.python();
  b.setFieldValue(beyond, field);
  const reply = await parmor.run();
  return {rows, sent, python, error: reply.error};
}"""


def _page_block(chromium, folder, behaviour, field, beyond, near=None, nudge=0.0):  # noqa: F811
    page = _open(chromium, (folder / "blocks" / "index.html").as_uri())
    try:
        got = page.evaluate("(a) => (" + _BLOCK + ")(a)", [behaviour, field, beyond, near, nudge])
        assert not page.errors, page.errors
        return got
    finally:
        page.close()


def _spec(folder, behaviour):
    from program.blocks import bundle_controller, read_record

    record = read_record(folder)
    return {p.name: p for p in bundle_controller(folder, record).behaviors[behaviour].params}


def _shown_range(row: str) -> tuple[float, float]:
    lo, hi = row.rsplit("[", 1)[1].rstrip("]").split(",")
    return float(lo), float(hi)


def test_the_hexapods_page_shows_its_own_speeds_in_range_and_refuses_beyond(
    chromium,  # noqa: F811
    hexapod,
) -> None:
    """walking: its speed, stride and lift with the design's defaults (positive) and
    ranges (the speed well under 1 m/s); untouched, the block sends the defaults exactly
    (they plan as the design does); beyond the range, Run refuses."""
    ps = _spec(hexapod, "walking")
    got = _page_block(chromium, hexapod, "walking", "speed", 5)
    speed = got["rows"]["speed"]
    assert speed.startswith(f"speed {ps['speed'].default:g} metres per second ["), speed
    lo, hi = _shown_range(speed)
    assert 0 < lo < ps["speed"].default <= hi < 1
    assert hi == pytest.approx(ps["speed"].high, rel=1e-3)
    for name in ("stride", "step_height"):
        assert ps[name].default > 0
        assert float(got["rows"][name].split()[1]) == pytest.approx(ps[name].default)
        assert _shown_range(got["rows"][name])[1] == pytest.approx(ps[name].high, rel=1e-3)
    assert got["sent"]["speed"] == ps["speed"].default
    assert got["sent"]["stride"] == ps["stride"].default
    assert f"speed={ps['speed'].default!r}" in got["python"]
    assert got["error"].startswith("not sent: walking: speed 5 is outside metres per second ["), got


def test_turning_shows_degrees_and_sends_its_own_rate_exactly(chromium, hexapod) -> None:  # noqa: F811
    """turning: angle and yaw rate in degrees; the rate's default (the design's, in rad/s)
    is sent as it is, not rounded to the field's 0.1 degree; a rate moved by 0.1 degree is
    the user's (a case built to fail the exact default)."""
    ps = _spec(hexapod, "turning")
    got = _page_block(chromium, hexapod, "turning", "speed", 1000)
    assert got["rows"]["angle"].startswith("angle 90 degrees [-720, 720]"), got["rows"]
    rate = got["rows"]["speed"]
    assert " degrees per second [" in rate and "rad" not in rate, rate
    assert float(rate.split()[1]) == pytest.approx(math.degrees(ps["speed"].default), abs=0.05)
    assert got["sent"]["speed"] == ps["speed"].default  # exactly the declared rad/s
    assert got["error"].startswith("not sent: turning: speed 1000 is outside degrees per second")
    moved = _page_block(chromium, hexapod, "turning", "speed", 1000, "speed", 0.1)
    shown = float(rate.split()[1]) + 0.1
    assert moved["sent"]["speed"] != ps["speed"].default
    assert moved["sent"]["speed"] == pytest.approx(math.radians(shown), rel=1e-9)


def test_the_snakes_page_shows_its_own_frequency(chromium, snake) -> None:  # noqa: F811
    ps = _spec(snake, "sidewinding")
    got = _page_block(chromium, snake, "sidewinding", "frequency", 50)
    row = got["rows"]["frequency"]
    assert row.startswith(f"frequency {ps['frequency'].default:g} times per second ["), row
    lo, hi = _shown_range(row)
    assert 0 < ps["frequency"].default <= hi < 10  # the modules' speed, not 10 Hz
    assert hi == pytest.approx(ps["frequency"].high, rel=1e-3)
    assert got["rows"]["roll"].startswith("roll 0 degrees [-180, 180]"), got["rows"]
    assert got["error"].startswith("not sent: sidewinding: frequency 50 is outside times per")


def test_the_arms_page_shows_its_reach(chromium, arm) -> None:  # noqa: F811
    ps = _spec(arm, "positioning")
    got = _page_block(chromium, arm, "positioning", "x", 3)
    for c in "xyz":
        row = got["rows"][c]
        assert float(row.split()[1]) == pytest.approx(ps[c].default), row
        assert _shown_range(row) == pytest.approx((ps[c].low, ps[c].high), rel=1e-3)
        assert ps[c].high < 1  # the arm's reach, in metres
    assert got["sent"] == {c: ps[c].default for c in "xyz"}
    assert got["error"].startswith("not sent: positioning: x 3 is outside metres ["), got
