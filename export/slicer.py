"""Print settings of the printed parts, and PrusaSlicer run on them where it is installed.

The parts are printed solid (``FILL_DENSITY`` 100 %): the models weigh them as solid
material (mesh volume x density), so the slicer's filament is the BOM's mass. The settings
are written as a PrusaSlicer config (:func:`prusa_config`, shipped in the bundle as
``print/prusaslicer.ini``) and :func:`slice_stl` slices one part with them and reads the
slicer's own estimate of time and filament from the G-code. The BOM's print time is the
estimate of :func:`estimate`, calibrated against this slicer with these settings (see its
constants).
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from export.meshes import OVERHANG_ANGLE

__all__ = [
    "FILL_DENSITY",
    "LAYER_HEIGHT",
    "SKIRT_MARGIN",
    "SliceResult",
    "estimate",
    "prusa_config",
    "prusa_slicer",
    "slice_3mf",
    "slice_stl",
    "slice_with_ini",
]

#: mm: layer height (and first layer height) of every part.
LAYER_HEIGHT = 0.2
#: Perimeters: the thinnest printable wall of the catalog (``min_wall`` 1.2 mm) is three
#: lines of a 0.4 mm nozzle.
PERIMETERS = 3
#: Parts are printed solid: the models weigh them as solid material.
FILL_DENSITY = 100
#: mm: nozzle and filament diameters; g/cm^3 is taken from the catalog material.
NOZZLE = 0.4
FILAMENT_DIAMETER = 1.75
#: One skirt loop ``SKIRT_DISTANCE`` mm from the part: the bed must hold the part and
#: ``SKIRT_MARGIN`` mm around it (the distance plus the loop's width, rounded up).
SKIRTS = 1
SKIRT_DISTANCE = 2.0
SKIRT_MARGIN = 3.0
#: mm/s: print speeds of PrusaSlicer's "0.20mm QUALITY @MK3" system profile (its defaults
#: without a profile print solid infill at 20 mm/s, far slower than any printer's profile),
#: and its generic PLA's volumetric limit (mm^3/s).
SPEEDS = {
    "perimeter_speed": 45,
    "small_perimeter_speed": 25,
    "external_perimeter_speed": 25,
    "infill_speed": 80,
    "solid_infill_speed": 80,
    "top_solid_infill_speed": 40,
    "support_material_speed": 50,
    "support_material_interface_speed": "100%",
    "bridge_speed": 30,
    "gap_fill_speed": 40,
    "travel_speed": 180,
    "first_layer_speed": 20,
    "max_volumetric_speed": 15,
}
#: Supports where the slicer finds overhangs steeper than 45 degrees from the vertical
#: (``export.meshes.OVERHANG_ANGLE``; PrusaSlicer's threshold is from the horizontal).
SUPPORT_THRESHOLD_DEG = round(math.degrees(OVERHANG_ANGLE))


# --- the BOM's estimate, calibrated against the slicer -------------------------------------
#
# Fitted (least squares on the relative error, 3 significant digits, no intercept) to
# PrusaSlicer 2.5.0's own estimates for the 28 distinct printed parts of the 8 default
# designs, sliced with the settings above: plates, wheels, feet, jaws and links lying in
# their print orientation. Largest error there: time 2.4 %, filament 2.1 %; on the 10 parts
# of 3 non-default designs (not in the fit): 2.4 % and 2.2 %. Features: ``meshes.
# print_features`` (volume, wall and skin areas, support columns, height).

#: Support filament per volume of the columns under the overhangs (``support``).
SUPPORT_FILL = 0.193
#: mm^3: support filament of a part with any support, beyond ``SUPPORT_FILL`` (the dense
#: interface layers and the support's own base).
SUPPORT_BASE_MM3 = 1450.0
#: s per mm^3 of solid part, per mm^3 of support filament, per mm^2 of wall (its
#: perimeters), per mm^2 of top and bottom skin, per mm of height (layer changes).
TIME_PER_MM3 = 0.154
TIME_PER_SUPPORT_MM3 = 0.293
TIME_PER_WALL_MM2 = 0.423
TIME_PER_SKIN_MM2 = 0.074
TIME_PER_MM_HEIGHT = 10.4


def estimate(features: dict[str, float]) -> tuple[float, float]:
    """(print time s, filament m^3) of a part from its ``meshes.print_features`` (SI):
    the calibrated model above, for the settings of :func:`prusa_config`."""
    volume = features["volume"] * 1e9  # mm^3
    support = SUPPORT_FILL * features["support"] * 1e9
    if features["support"] > 0:
        support += SUPPORT_BASE_MM3
    time = (
        TIME_PER_MM3 * volume
        + TIME_PER_SUPPORT_MM3 * support
        + TIME_PER_WALL_MM2 * features["side_area"] * 1e6
        + TIME_PER_SKIN_MM2 * features["flat_area"] * 1e6
        + TIME_PER_MM_HEIGHT * features["height"] * 1e3
    )
    return time, (volume + support) * 1e-9


def prusa_config(bed_mm: Sequence[float], density_g_cm3: float, supports: bool = True) -> str:
    """PrusaSlicer config text (ini) of the parts' print settings for a printer whose build
    volume is ``bed_mm`` (x, y, z mm), filament of ``density_g_cm3``; supports where the
    slicer finds overhangs, or none (a part that has none as it lies)."""
    x, y, z = (float(b) for b in bed_mm)
    lines = {
        "bed_shape": f"0x0,{x:g}x0,{x:g}x{y:g},0x{y:g}",
        "max_print_height": f"{z:g}",
        "nozzle_diameter": f"{NOZZLE:g}",
        "filament_diameter": f"{FILAMENT_DIAMETER:g}",
        "filament_density": f"{density_g_cm3:g}",
        "layer_height": f"{LAYER_HEIGHT:g}",
        "first_layer_height": f"{LAYER_HEIGHT:g}",
        "perimeters": str(PERIMETERS),
        "top_solid_layers": "5",
        "bottom_solid_layers": "4",
        "fill_density": f"{FILL_DENSITY}%",
        "fill_pattern": "rectilinear",
        "top_fill_pattern": "monotonic",
        "bottom_fill_pattern": "monotonic",
        "support_material": "1" if supports else "0",
        "support_material_auto": "1",
        "support_material_threshold": f"{90 - SUPPORT_THRESHOLD_DEG}",
        "skirts": str(SKIRTS),
        "skirt_distance": f"{SKIRT_DISTANCE:g}",
        "brim_width": "0",
        "gcode_comments": "0",
        **{k: str(v) for k, v in SPEEDS.items()},
    }
    head = "# parmor print settings for PrusaSlicer (prusa-slicer --load this.ini part.stl)\n"
    return head + "".join(f"{k} = {v}\n" for k, v in lines.items())


@dataclass(frozen=True)
class SliceResult:
    """What the slicer says of one part: time s, filament mm^3 and g, the extents of the
    extruding moves (x0, y0, x1, y1) mm and the bed (x, y) mm."""

    time_s: float
    filament_mm3: float
    filament_g: float
    extrusion_box: tuple[float, float, float, float]
    bed: tuple[float, float]

    @property
    def on_bed(self) -> bool:
        """Every extruding move (skirt and supports included) inside the bed."""
        x0, y0, x1, y1 = self.extrusion_box
        return x0 >= 0 and y0 >= 0 and x1 <= self.bed[0] and y1 <= self.bed[1]


def prusa_slicer() -> str | None:
    """The prusa-slicer executable on the PATH, or None."""
    return shutil.which("prusa-slicer") or shutil.which("prusa-slicer-console")


_TIME = re.compile(r"; estimated printing time \(normal mode\) = (.+)")
_CM3 = re.compile(r"; filament used \[cm3\] = ([0-9.]+)")
_G = re.compile(r"; (?:total )?filament used \[g\] = ([0-9.]+)")


def _seconds(text: str) -> float:
    units = {"d": 86400, "h": 3600, "m": 60, "s": 1}
    return float(sum(int(n) * units[u] for n, u in re.findall(r"(\d+)([dhms])", text)))


def slice_stl(
    stl: bytes, bed_mm: Sequence[float], density_g_cm3: float, exe: str | None = None
) -> SliceResult:
    """Slice one part (binary STL, mm, as parmor writes it: on the bed in its print
    orientation) with :func:`prusa_config`, centred on the bed, no scaling. RuntimeError
    with the slicer's message when it fails or finds no layers."""
    bed = tuple(float(b) for b in bed_mm)
    config = prusa_config(bed, density_g_cm3)
    centre = f"{bed[0] / 2:g},{bed[1] / 2:g}"
    return _slice("part.stl", stl, ["--load", "print.ini", "--center", centre], config, exe)


def slice_with_ini(stl: bytes, ini: str, exe: str | None = None) -> SliceResult:
    """Slice one part (binary STL, mm, as it lies) with the PrusaSlicer config text ``ini``
    (a bundle's ``print/prusaslicer.ini``), centred on the bed that config names."""
    m = re.search(r"^bed_shape = (.+)$", ini, re.M)
    if m is None:
        raise ValueError("the print settings name no bed_shape")
    corners = [tuple(float(v) for v in c.split("x")) for c in m.group(1).split(",")]
    centre = f"{max(c[0] for c in corners) / 2:g},{max(c[1] for c in corners) / 2:g}"
    return _slice("part.stl", stl, ["--load", "print.ini", "--center", centre], ini, exe)


def slice_3mf(project: bytes, exe: str | None = None) -> SliceResult:
    """Slice a 3MF project (``print/<part>.3mf``) as it is: its own settings and bed, its
    copies where they are placed (no arranging). The bed is the one the G-code says."""
    return _slice("part.3mf", project, ["--dont-arrange"], None, exe)


_BED = re.compile(r"; bed_shape = (.+)")


def _slice(
    name: str, data: bytes, args: list[str], config: str | None, exe: str | None
) -> SliceResult:
    exe = exe or prusa_slicer()
    if exe is None:
        raise RuntimeError("prusa-slicer is not installed")
    with tempfile.TemporaryDirectory(prefix="parmor-slice-") as tmp:
        d = Path(tmp)
        (d / name).write_bytes(data)
        if config is not None:
            (d / "print.ini").write_text(config, encoding="utf-8")
        cmd = [exe, "--export-gcode", *args, "--output", "part.gcode", name]
        r = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=600, cwd=d)
        out = d / "part.gcode"
        if r.returncode != 0 or not out.exists():
            raise RuntimeError(f"prusa-slicer failed ({r.returncode}): {r.stderr or r.stdout}")
        text = out.read_text(encoding="utf-8", errors="replace")
    m_time, m_cm3, m_g = _TIME.search(text), _CM3.search(text), _G.search(text)
    m_bed = _BED.search(text)
    if not (m_time and m_cm3 and m_g and m_bed):
        raise RuntimeError("prusa-slicer wrote no time, filament or bed figures")
    corners = [tuple(float(v) for v in c.split("x")) for c in m_bed.group(1).split(",")]
    bed = (max(c[0] for c in corners), max(c[1] for c in corners))
    xs, ys = [], []
    x = y = 0.0
    for line in text.splitlines():
        if not line.startswith(("G1 ", "G0 ")):
            continue
        words = dict((w[0], w[1:]) for w in line.split(";")[0].split()[1:] if len(w) > 1)
        x = float(words.get("X", x))
        y = float(words.get("Y", y))
        if "E" in words and float(words["E"]) > 0 and ("X" in words or "Y" in words):
            xs.append(x)
            ys.append(y)
    box = (min(xs), min(ys), max(xs), max(ys)) if xs else (0.0, 0.0, 0.0, 0.0)
    return SliceResult(
        _seconds(m_time.group(1)),
        1000.0 * float(m_cm3.group(1)),
        float(m_g.group(1)),
        box,
        bed,
    )
