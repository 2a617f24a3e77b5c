"""The measured support margin on a slope: the centre of mass is projected onto the feet's
plane along gravity (``synth.verification.perturb`` turns gravity by the floor's slope), so a tilt
towards the nearest edge takes height x tan(slope) off the margin."""

from __future__ import annotations

import math

import mujoco
import pytest

from synth.verification.simulate import support_margin_of

#: A 0.3 m high body on four feet at x, y = +-0.1 m: margin 0.1 m with gravity straight down.
XML = """<mujoco><option gravity="{g}"/><worldbody><geom type="plane" size="1 1 .1"/>
<body name="robot" pos="0 0 0"><freejoint/>
<geom type="sphere" size=".01" pos=".1 .1 .01" mass=".001"/>
<geom type="sphere" size=".01" pos="-.1 .1 .01" mass=".001"/>
<geom type="sphere" size=".01" pos=".1 -.1 .01" mass=".001"/>
<geom type="sphere" size=".01" pos="-.1 -.1 .01" mass=".001"/>
<geom type="box" size=".02 .02 .02" pos="0 0 .3" mass="5"/></body></worldbody></mujoco>"""


def _margin(slope_deg: float, towards_deg: float) -> float:
    a, d = math.radians(slope_deg), math.radians(towards_deg)
    g = (9.81 * math.sin(a) * math.cos(d), 9.81 * math.sin(a) * math.sin(d), -9.81 * math.cos(a))
    model = mujoco.MjModel.from_xml_string(XML.format(g=" ".join(f"{v:.9f}" for v in g)))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon == 4
    return support_margin_of(model, data)


def test_level_floor_margin_is_the_straight_drop() -> None:
    assert _margin(0.0, 0.0) == pytest.approx(0.1, abs=1e-3)


@pytest.mark.parametrize("slope", [1.0, 3.0, 10.0])
@pytest.mark.parametrize("towards", [0.0, 90.0, 180.0])
def test_tilt_towards_an_edge_takes_height_tan_slope_off(slope: float, towards: float) -> None:
    h = 0.3 - 0.0  # the body's centre of mass over the contacts' plane (the feet touch z = 0)
    expected = 0.1 - h * math.tan(math.radians(slope))
    # a straight drop would give 0.1 whatever the tilt: built to fail on it
    assert _margin(slope, towards) == pytest.approx(expected, abs=2e-3)
    assert _margin(slope, towards) < 0.1 - 1e-3


def test_a_steep_enough_slope_tips_the_com_out() -> None:
    assert _margin(25.0, 0.0) < 0  # 0.3 x tan 25 deg = 0.14 m > 0.1 m
