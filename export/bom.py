"""The bill of materials (``bom.csv``): every active module (catalog model, count, unit
cost) and every printed part (file, count, volume, mass, print time, printer-bed fit),
with totals. Pure: returns the CSV text."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

from export.model3d import PrintedPart

COLUMNS = (
    "type",
    "name",
    "kind",
    "count",
    "unit_cost",
    "unit_mass_kg",
    "unit_volume_m3",
    "unit_print_time_s",
    "fits_bed",
    "file",
)


def _num(x: float) -> str:
    """Stable number text: 6 significant digits, no exponent noise for zeros."""
    return "0" if x == 0 else f"{x:.6g}"


def bom_csv(
    modules: Sequence[dict],
    printed: Sequence[PrintedPart],
    module_figures: dict[str, tuple[float, float]],
) -> str:
    """CSV text of the BOM.

    ``modules``: the design record's sized modules ({"kind", "model", "count"});
    ``module_figures``: model -> (unit cost, unit mass kg) from the catalog.
    A printed part that does not fit the printer bed says so in ``fits_bed`` ("NO").
    """
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(COLUMNS)
    cost = mass = volume = time = 0.0
    n = 0
    for m in sorted(modules, key=lambda m: (m["kind"], m["model"])):
        unit_cost, unit_mass = module_figures[m["model"]]
        w.writerow(
            [
                "module",
                m["model"],
                m["kind"],
                m["count"],
                _num(unit_cost),
                _num(unit_mass),
                "",
                "",
                "",
                "",
            ]
        )
        cost += unit_cost * m["count"]
        mass += unit_mass * m["count"]
        n += m["count"]
    all_fit = True
    for p in sorted(printed, key=lambda p: p.name):
        w.writerow(
            [
                "printed",
                p.name,
                p.kind,
                p.count,
                "",
                _num(p.mass_kg),
                _num(p.volume_m3),
                _num(round(p.print_time_s)),
                "yes" if p.fits_bed else "NO",
                f"meshes/{p.name}.stl",
            ]
        )
        mass += p.mass_kg * p.count
        volume += p.volume_m3 * p.count
        time += p.print_time_s * p.count
        n += p.count
        all_fit &= p.fits_bed
    w.writerow(
        [
            "total",
            "",
            "",
            n,
            _num(round(cost, 2)),
            _num(mass),
            _num(volume),
            _num(round(time)),
            "yes" if all_fit else "NO",
            "",
        ]
    )
    return out.getvalue()
