"""Large synthetic actuator catalogs for the assignment's tests and bench (seeded).

``synthetic_catalog_text(n, seed)`` is the shipped catalog (adron/catalog.toml) with its
actuators replaced by ``n`` of them: the shipped six first (so that n = 6 is the shipped
catalog's actuators), then made-up servos drawn in the shipped ones' ranges: module mass
30-100 g, stall torque growing with mass (1.2-22 kgf*cm, with a spread), no-load speed
40-120 rpm, stall current 0.5-3 A, cost 4-22 (catalog currency) growing with torque, two
housing sizes (the shipped ones, so the largest housing and the printed parts do not
change), position and continuous rotation servos alternately. Each figure is written as
the catalog writes it (a string with its unit), so the catalog is loaded and validated as
a user's would be.
"""

from __future__ import annotations

import random
import re
from importlib import resources

#: The shipped catalog's actuator blocks: from the first ``[[actuator]]`` to the line before
#: the first other table after them.
_BLOCK = re.compile(r"^\[\[actuator\]\]\n.*?(?=^\[|\Z)", re.MULTILINE | re.DOTALL)

CLASSES = ("PositionServomotor", "ContinuousRotationServomotor")


def shipped_text() -> str:
    """The text of the shipped catalog (adron/catalog.toml)."""
    return (resources.files("adron") / "catalog.toml").read_text(encoding="utf-8")


def _made_up(i: int, rng: random.Random) -> str:
    """One made-up servo module (``i``: its index, for its model name and class)."""
    cls = CLASSES[i % 2]
    mass_g = rng.uniform(30.0, 100.0)
    share = (mass_g - 30.0) / 70.0  # 0 (lightest) .. 1 (heaviest)
    torque = 1.2 * (22.0 / 1.2) ** min(1.0, max(0.0, share + rng.uniform(-0.25, 0.25)))
    speed = rng.uniform(40.0, 120.0)
    current = 0.5 + 2.5 * min(1.0, max(0.0, share + rng.uniform(-0.2, 0.2)))
    cost = 4.0 + 18.0 * min(1.0, max(0.0, torque / 22.0 + rng.uniform(-0.2, 0.3)))
    depth = 40 if mass_g < 55.0 else 60
    travel = 360 if cls == "ContinuousRotationServomotor" else rng.choice((180, 270))
    tier = "low" if torque < 4 else ("medium" if torque < 12 else "high")
    return (
        "[[actuator]]\n"
        f'model = "SYN{i:05d}"\n'
        f'class = "{cls}"\n'
        f'torque_class = "{tier}"\n'
        f'mass = "{mass_g:.1f} g"\n'
        f'size = ["50 mm", "50 mm", "{depth} mm"]\n'
        f'stall_torque = "{torque:.2f} kgf*cm"\n'
        f'no_load_speed = "{speed:.1f} rpm"\n'
        f'stall_current = "{current:.2f} A"\n'
        f"cost = {cost:.2f}\n"
        f"travel_deg = {travel}\n\n"
    )


def synthetic_catalog_text(n: int, seed: int = 0) -> str:
    """A catalog (TOML text) with ``n`` >= 6 actuators: the shipped six, then ``n - 6``
    made-up ones drawn with ``seed``."""
    text = shipped_text()
    blocks = list(_BLOCK.finditer(text))
    if n < len(blocks):
        raise ValueError(f"n = {n}: at least the {len(blocks)} shipped actuators")
    rng = random.Random(seed)
    extra = "".join(_made_up(i, rng) for i in range(n - len(blocks)))
    end = blocks[-1].end()
    return text[:end] + extra + text[end:]


def write_synthetic_catalog(path, n: int, seed: int = 0) -> None:
    """``synthetic_catalog_text(n, seed)`` written to ``path`` (a str or Path)."""
    from pathlib import Path

    Path(path).write_text(synthetic_catalog_text(n, seed), encoding="utf-8")


if __name__ == "__main__":
    import sys

    sys.stdout.write(
        synthetic_catalog_text(int(sys.argv[1]), int(sys.argv[2:3][0] if sys.argv[2:] else 0))
    )
