"""The catalog bus's module limit governs the conceptual step as well as the sizing: a
robot with more active modules than the bus carries is no candidate (issue 12: the I2C
limit of 24 is the default catalog's bus, another bus is data)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from adron.errors import InputError
from synth.pipeline import bus_limit


def _catalog(tmp_path, limit: int) -> str:
    """A catalog like the default with a bus of ``limit`` active modules."""
    path = tmp_path / f"bus{limit}.toml"
    path.write_text(
        '[catalog]\nname = "test"\ncurrency = "EUR"\nversion = "1"\nextends = "default"\n\n'
        '[bus]\nname = "test bus"\nprotocol = "test"\n'
        f"first_address = 1\nlast_address = 200\ndevice_limit = {limit}\n"
        'address_word = "ID"\naddress_format = "decimal"\n',
        encoding="utf-8",
    )
    return str(path)


def _design(*argv: str) -> tuple[int, dict]:
    r = subprocess.run(
        [sys.executable, "-m", "synth.commands.cli", "design", *argv, "--no-input", "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    return r.returncode, json.loads(r.stdout) if r.stdout.strip() else {}


def test_the_bus_limit_is_the_catalogs() -> None:
    assert bus_limit(None) == 24
    assert bus_limit("dynamixel") == 253
    with pytest.raises(InputError, match="no such catalog"):
        bus_limit("no such catalog")


@pytest.mark.parametrize("limit", [10, 40])
def test_a_bus_too_small_for_the_hexapod_leaves_no_candidate(tmp_path, limit) -> None:
    """Built to fail at 10: the hexapod needs 20 active modules (18 servos, battery,
    main); at 40 it designs as with the default bus, and says the bus's limit."""
    code, out = _design(
        "rough-terrain-walking", "--conceptual", "--catalog", _catalog(tmp_path, limit)
    )
    if limit == 10:
        assert code != 0 and out.get("status") != "designed", out
    else:
        assert code == 0 and out["robot_type"] == "HexapodRobot", out
        assert out["module_limit"] == 40
