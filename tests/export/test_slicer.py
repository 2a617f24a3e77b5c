"""PrusaSlicer slices every printed part of the default designs (and three others) as the
bundle ships it: millimetres, in its print orientation, no scaling, with the bundle's
print settings; every extrusion stays on the bed of the printer the BOM names, and the
BOM's print time and filament are within 15 % of the slicer's (issue 10).

Slicing is slow (a link takes tens of seconds): the parts are deduplicated by their STL
bytes and sliced two at a time."""

from __future__ import annotations

import csv
import io
from concurrent.futures import ThreadPoolExecutor

import pytest

from export.bundle import bundle_files
from export.record import design_record
from export.slicer import prusa_slicer, slice_stl
from synth.reasoning.conceptual import Design, Request
from synth.reasoning.solver import Query
from synth.sizing.structure import design_structure
from tests.conftest import need
from tests.export.test_bundle_designs import NON_DEFAULT

#: The BOM's estimates against the slicer's (relative).
TOLERANCE = 0.15


@pytest.fixture(scope="module")
def sliced(kb, designer, catalog):
    exe = prusa_slicer()
    need(exe is not None, "prusa-slicer is not installed (apt-get install prusa-slicer)")
    cands = {c.robot_type: c for c in designer.reasoner.solve(Query()).candidates}
    requests = [(t, {}) for t in sorted(cands)] + list(NON_DEFAULT)
    parts: dict[bytes, tuple[str, dict, tuple[float, float, float]]] = {}
    for t, params in requests:
        s = design_structure(kb, cands[t], catalog, params)
        d = Design("designed", Request(), (cands[t],), cands[t], "only candidate")
        files = bundle_files(design_record(d, designer.short, s), s, catalog, pictures=False)
        for row in csv.DictReader(io.StringIO(files["bom.csv"])):
            if row["type"] != "printed":
                continue
            bed_m = catalog.printer_bed(row["printer"])
            assert bed_m is not None, (t, row["name"], row["printer"])  # never "split"
            bed = tuple(b * 1000 for b in bed_m)
            parts.setdefault(files[row["file"]], (f"{t} {params} {row['name']}", row, bed))
    density = catalog.material.density_kg_m3 / 1000.0

    def run(item):
        stl, (label, row, bed) = item
        return label, row, slice_stl(stl, bed, density, exe)

    with ThreadPoolExecutor(max_workers=2) as pool:
        return list(pool.map(run, sorted(parts.items(), key=lambda kv: kv[1][0])))


def test_every_part_slices_on_its_printers_bed(sliced) -> None:
    assert len(sliced) > 20
    for label, _, r in sliced:
        assert r.time_s > 0 and r.filament_mm3 > 0, label
        assert r.on_bed, (label, r.extrusion_box, r.bed)


def test_bom_print_time_and_filament_within_15_percent_of_the_slicers(sliced) -> None:
    for label, row, r in sliced:
        time = float(row["unit_print_time_s"])
        filament = float(row["unit_filament_m3"]) * 1e9
        assert time == pytest.approx(r.time_s, rel=TOLERANCE), (label, time, r.time_s)
        assert filament == pytest.approx(r.filament_mm3, rel=TOLERANCE), (
            label,
            filament,
            r.filament_mm3,
        )


def test_a_part_off_the_bed_is_caught() -> None:
    """A part built to fail: a plate larger than the bed it is sliced for. PrusaSlicer
    either refuses it or extrudes off the bed; either way the check does not pass it."""
    exe = prusa_slicer()
    need(exe is not None, "prusa-slicer is not installed (apt-get install prusa-slicer)")
    from export import meshes

    stl = meshes.stl_bytes(meshes.plate_mesh(0.12, 0.05, 0.002))
    try:
        r = slice_stl(stl, (100.0, 100.0, 100.0), 1.24, exe)
    except RuntimeError:
        return
    assert not r.on_bed
