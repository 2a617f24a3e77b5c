"""The bill of materials (``bom.csv``): every physical part of the robot's model, from the
assembly the URDF and MJCF are written from, so that the BOM's masses add up to the
model's: the catalog's active modules (actuators, main module, battery, sensors), the
printed parts (file, count, volume, mass, print time and filament estimated for the
bundle's PrusaSlicer settings, ``export.slicer``; the printer that fits it) and the bought
parts (ball caster, tyres), with totals. The payload is not a part of the robot and is not
listed. Pure: returns the CSV text."""

from __future__ import annotations

import csv
import io

from export.model3d import Assembly

COLUMNS = (
    "type",
    "name",
    "kind",
    "count",
    "unit_cost",
    "unit_mass_kg",
    "unit_volume_m3",
    "unit_print_time_s",
    "unit_filament_m3",
    "fits_bed",
    "printer",
    "file",
)

#: BOM row types, in the order they are listed (pieces and joints under their printed part).
TYPES = ("module", "printed", "piece", "joint", "bought")


def _num(x: float) -> str:
    """Stable number text: 6 significant digits, no exponent noise for zeros."""
    return "0" if x == 0 else f"{x:.6g}"


def bom_rows(asm: Assembly) -> list[dict]:
    """One dict per BOM line (COLUMNS keys, numbers as floats): modules and bought parts
    counted from the assembly's bodies, printed parts from its printed designs."""
    grouped: dict[tuple[str, str], dict] = {}
    for body in asm.bodies:
        for u in body.parts:
            if u.source not in ("module", "bought"):
                continue
            row = grouped.setdefault(
                (u.source, u.name),
                {"kind": u.kind, "count": 0, "masses": [], "costs": []},
            )
            row["count"] += 1
            row["masses"].append(u.mass)
            row["costs"].append(u.cost)
    rows: list[dict] = []
    for (source, name), g in sorted(grouped.items()):
        n = g["count"]
        rows.append(
            {
                "type": source,
                "name": name,
                "kind": g["kind"],
                "count": n,
                "unit_cost": sum(g["costs"]) / n,
                "unit_mass_kg": sum(g["masses"]) / n,
                "unit_volume_m3": None,
                "unit_print_time_s": None,
                "unit_filament_m3": None,
                "fits_bed": None,
                "printer": "",
                "file": "",
            }
        )
    printed = [
        {
            "type": "printed",
            "name": p.name,
            "kind": p.kind,
            "count": p.count,
            "unit_cost": None,
            "unit_mass_kg": p.mass_kg,
            "unit_volume_m3": p.volume_m3,
            "unit_print_time_s": p.print_time_s,
            "unit_filament_m3": p.filament_m3,
            "fits_bed": p.fits_bed or p.printer not in ("", "split"),
            "printer": p.printer,
            "file": f"meshes/{p.name}.stl",
        }
        for p in sorted(asm.printed, key=lambda p: p.name)
    ]
    printed = [r for row in printed for r in (row, *_piece_rows(asm, row["name"]))]
    modules = [r for r in rows if r["type"] == "module"]
    bought = [r for r in rows if r["type"] == "bought"]
    return [*modules, *printed, *bought]


def _piece_rows(asm: Assembly, name: str) -> list[dict]:
    """The rows under a printed part made to fit the user's bed (``export.split``): its
    pieces (or the part turned: ``print/<part>.stl``), then the joints between them. Not in
    the totals: the part's row counts their print time and filament, and its mass is the
    models' (the pieces' less the clearance gaps: ``export.split.gap_mass``)."""
    p = next(p for p in asm.printed if p.name == name)
    rows = [
        {
            "type": "piece",
            "name": x.name,
            "kind": p.kind if p.joints else f"{p.kind} (turned)",
            "count": p.count,
            "unit_cost": None,
            "unit_mass_kg": x.mass_kg,
            "unit_volume_m3": x.volume_m3,
            "unit_print_time_s": x.print_time_s,
            "unit_filament_m3": x.filament_m3,
            "fits_bed": True,
            "printer": p.printer,
            "file": f"print/{x.name}.stl",
        }
        for x in p.pieces
    ]
    rows += [
        {
            "type": "joint",
            "name": f"{j.low} + {j.high}",
            "kind": f"{j.kind} across {j.axis} = {j.at_m * 1000:.1f} mm, slides along "
            f"{j.slide}, {j.fasteners or 'no fastener'}",
            "count": p.count,
            "unit_cost": None,
            "unit_mass_kg": 0.0,
            "unit_volume_m3": None,
            "unit_print_time_s": None,
            "unit_filament_m3": None,
            "fits_bed": None,
            "printer": "",
            "file": "",
        }
        for j in p.joints
    ]
    return rows


def bom_csv(asm: Assembly) -> str:
    """CSV text of the BOM of ``asm`` (see :func:`bom_rows`), a ``total`` line last.

    ``printer`` names the catalog's larger printer that takes a printed part too big for the
    catalog's ``printer_bed`` (its skirt included); empty: the catalog's printer. ``fits_bed``
    says whether the part fits the bed of that printer: "NO" only for a part no catalog
    printer holds (``printer`` "split": it must be split). On the user's bed (``--bed``)
    ``printer`` is that bed and a part too big for it as it lies is followed by its
    ``piece`` rows (``print/<piece>.stl``) and ``joint`` rows, outside the totals.
    Masses kg, volumes m^3, times s, costs in the catalog currency (printed parts: none).
    """
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(COLUMNS)
    cost = mass = volume = time = filament = 0.0
    n = 0
    all_fit = True
    for r in bom_rows(asm):
        k = r["count"]
        w.writerow(
            [
                r["type"],
                r["name"],
                r["kind"],
                k,
                "" if r["unit_cost"] is None else _num(r["unit_cost"]),
                _num(r["unit_mass_kg"]),
                "" if r["unit_volume_m3"] is None else _num(r["unit_volume_m3"]),
                "" if r["unit_print_time_s"] is None else _num(round(r["unit_print_time_s"])),
                "" if r["unit_filament_m3"] is None else _num(r["unit_filament_m3"]),
                "" if r["fits_bed"] is None else ("yes" if r["fits_bed"] else "NO"),
                r["printer"],
                r["file"],
            ]
        )
        if r["type"] in ("piece", "joint"):  # under their part, which counts them
            continue
        n += k
        mass += r["unit_mass_kg"] * k
        cost += (r["unit_cost"] or 0.0) * k
        volume += (r["unit_volume_m3"] or 0.0) * k
        time += (r["unit_print_time_s"] or 0.0) * k
        filament += (r["unit_filament_m3"] or 0.0) * k
        if r["fits_bed"] is False:
            all_fit = False
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
            _num(filament),
            "yes" if all_fit else "NO",
            "",
            "",
        ]
    )
    return out.getvalue()
