"""The user's printer (``parmor design --bed``, ``export.split``, issue 24 item 2): a
printed part too big for the bed is turned to fit it or split into pieces joined by
dovetails with the catalog's print clearance; the pieces reassemble the part with exactly
that clearance and no overlap (manifold3d), each fits the bed, and PrusaSlicer slices every
one with the bundle's profile."""

from __future__ import annotations

import csv
import io
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from adron.errors import InputError
from export import meshes, split
from export.polymesh import Mesh
from tests.conftest import need

C = 0.0002  # m: the shipped catalog's print clearance
MARGIN = 0.003  # m: the skirt around a part


def _fits(mesh: Mesh, bed: tuple[float, float, float]) -> bool:
    x, y, z = meshes.extents(mesh)
    return x + 2 * MARGIN <= bed[0] + 1e-9 and y + 2 * MARGIN <= bed[1] + 1e-9 and z <= bed[2]


def _cube(bed_mm: float) -> tuple[float, float, float]:
    return (bed_mm / 1000,) * 3


# --- the option's value ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "size"),
    [
        ("180x180x180mm", (0.18, 0.18, 0.18)),
        ("250 x 210 x 200 mm", (0.25, 0.21, 0.2)),
        ("25x21x20cm", (0.25, 0.21, 0.2)),
        ("0.3X0.3X0.4m", (0.3, 0.3, 0.4)),
        ("220x220x250", (0.22, 0.22, 0.25)),
        ("Prusa XL", None),  # a printer's name: looked up in the catalog
        ("abc", None),
    ],
)
def test_parse_bed(text, size) -> None:
    got = split.parse_bed(text)
    assert got == (None if size is None else pytest.approx(size))


@pytest.mark.parametrize("text", ["0x5x5", "-1x100x100mm", "nanx100x100", "1x2xqmm", "20x20x20mm"])
def test_parse_bed_refuses_bad_sizes_naming_the_value(text) -> None:
    with pytest.raises(ValueError, match=repr(text).replace("(", r"\(").replace(")", r"\)")):
        split.parse_bed(text)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("0x5x5", "--bed '0x5x5': '0' must be a positive length"),
        ("abc", "--bed 'abc': neither a build volume WxDxH"),
        ("180x180", "--bed '180x180': neither a build volume WxDxH"),
        ("10x10x10mm", "--bed '10x10x10mm': a bed side of 10 mm holds no printed piece"),
    ],
)
def test_design_refuses_a_bad_bed_with_exit_2(cli, tmp_path, value, message) -> None:
    out = tmp_path / "out"
    r = cli("design", "driving", "--no-verify", "--bed", value, "--out", str(out))
    assert r.code == 2 and message in r.err and "Traceback" not in r.err, r.err
    assert not out.exists()


def test_a_bed_too_small_for_a_part_refuses_and_writes_nothing(cli, tmp_path) -> None:
    """30 mm: the links' 50 mm face plates need splitting, their thin tubes hold no
    dovetail: refused naming the part, exit 2, no bundle."""
    out = tmp_path / "out"
    r = cli(
        "design", "rough-terrain-walking", "--no-verify", "--bed", "30x30x30mm", "--out", str(out)
    )
    assert r.code == 2 and "--bed 30 x 30 x 30 mm: the printed part" in r.err, r.err
    assert "Traceback" not in r.err and not out.exists()


# --- turning a part to fit --------------------------------------------------------------------


def test_a_part_that_fits_as_it_lies_is_left_as_it_is() -> None:
    plate = meshes.plate_mesh(0.1, 0.05, 0.004)
    assert split.place(plate, _cube(180)) is plate


def test_a_long_part_fits_across_the_diagonal() -> None:
    bar = meshes.plate_mesh(0.2, 0.02, 0.005)
    placed = split.place(bar, _cube(180))
    assert placed is not None and _fits(placed, _cube(180))
    x, y, z = meshes.extents(placed)
    assert z == pytest.approx(0.005) and 0.03 < x < 0.174 and 0.03 < y < 0.174  # turned
    assert placed.volume == pytest.approx(bar.volume)


def test_a_tall_part_is_laid_on_another_face_but_a_plate_is_not_stood_on_its_edge() -> None:
    post = meshes.plate_mesh(0.05, 0.05, 0.15)  # 150 mm tall, the bed 120 mm high: lay it down
    placed = split.place(post, (0.18, 0.18, 0.12))
    assert placed is not None and meshes.extents(placed)[2] == pytest.approx(0.05)
    plate = meshes.plate_mesh(0.3, 0.11, 0.004)  # fits only on its edge: split instead
    assert split.place(plate, _cube(120)) is None


# --- splitting ----------------------------------------------------------------------------------


def _parts() -> dict[str, Mesh]:
    out = {
        f"plate {x}x{y}": meshes.plate_mesh(x / 1000, y / 1000, 0.004)
        for x in (150, 250, 313, 400)
        for y in (60, 120, 200)
    }
    out["wheel r100"] = meshes.wheel_mesh(0.1, 0.01)
    out["wheel r70"] = meshes.wheel_mesh(0.07, 0.01)
    out["link 200"] = meshes.link_mesh(0.2, 0.02, 0.017, 0.05, 0.004, 0.003, clearance=C)
    out["bar 300x30x20"] = meshes.plate_mesh(0.3, 0.03, 0.02)
    return out


def test_split_parts_fit_every_bed_and_reassemble_with_exactly_the_clearance() -> None:
    """The property over a grid: plates 150-400 x 60-200 mm, wheels, a 200 mm link and a
    bar, on 120, 180 and 220 mm cubes and two beds of unequal sides. Every part either
    fits (as it lies or turned) or is split; every piece fits the bed and the pieces
    reassemble the part: no overlap, none outside it, the clearance between every two,
    nothing else missing; the pieces weigh the part less under 1 %. Prints the pass
    rate."""
    cases = passed = split_count = 0
    failures = []
    for bed_mm in (120, 180, 220, (250, 210, 210), (200, 120, 100)):
        bed = _cube(bed_mm) if isinstance(bed_mm, int) else tuple(b / 1000 for b in bed_mm)
        for name, mesh in _parts().items():
            cases += 1
            placed = split.place(mesh, bed)
            if placed is not None:
                assert _fits(placed, bed), (name, bed_mm)
                passed += 1
                continue
            s = split.split_part(mesh, bed, C, name)
            split_count += 1
            problems = split.reassembly_problems(mesh, s.pieces, s.joints, C)
            fit = all(_fits(p, bed) for p in s.placed)
            same = all(
                p.volume == pytest.approx(q.volume, rel=1e-6)
                for p, q in zip(s.pieces, s.placed, strict=True)
            )
            lost = (mesh.volume - sum(p.volume for p in s.pieces)) / mesh.volume
            problems += _tongueless(s)
            if problems or not fit or not same or not (0 < lost < 0.01):
                failures.append((name, bed_mm, problems, fit, lost))
            else:
                passed += 1
    print(f"\nsplit grid: {passed}/{cases} parts printable on their bed ({split_count} split)")
    assert failures == [] and passed == cases
    assert split_count >= 25


def _tongueless(s: split.Split) -> list[str]:
    """The joints of ``s`` whose low piece has no tongue past the cut (over 1 mm)."""
    out = []
    for low, high, axis, at, _ in s.joints:
        k = "xyz".index(axis)
        if np.asarray(s.pieces[low].vertices)[:, k].max() < at + 0.001:
            out.append(f"pieces {low + 1} and {high + 1}: no tongue across {axis} = {at}")
    return out


def _frame(lx: float, ly: float, rail: float, thickness: float) -> Mesh:
    """A rectangular frame: a plate with a window, ``rail`` m wide all round."""
    import manifold3d as mf

    outer = mf.Manifold.cube((lx, ly, thickness), center=True)
    window = mf.Manifold.cube((lx - 2 * rail, ly - 2 * rail, 2 * thickness), center=True)
    return meshes._to_mesh(outer - window)


def test_a_tongue_is_never_put_in_a_hole_of_the_section() -> None:
    """A frame cut across its middle has a window where the section's middle is: that grid
    is refused (built to fail), and the split found instead gives every joint a tongue of
    material."""
    frame = _frame(0.3, 0.1, 0.012, 0.004)
    part = split._manifold(frame)
    lo, hi = (np.asarray(x, dtype=float) for x in split._bbox(part))
    assert split._build(part, lo, hi, (2, 1, 1), C * 1000) is None
    s = split.split_part(frame, _cube(180), C, "frame")
    assert len(s.pieces) >= 4 and _tongueless(s) == []
    assert split.reassembly_problems(frame, s.pieces, s.joints, C) == []


def test_the_reassembly_check_catches_bad_pieces() -> None:
    """Built to fail: a piece overlapping its neighbour, two pieces joined too loose, one
    joined with no clearance, a piece missing a chunk, a piece leaving the part."""
    plate = meshes.plate_mesh(0.25, 0.1, 0.004)
    s = split.split_part(plate, _cube(180), C, "plate")
    assert len(s.pieces) == 2 and split.reassembly_problems(plate, s.pieces, s.joints, C) == []
    a, b = s.pieces
    axis = "xyz".index(s.joints[0][2])
    low, high = (a, b) if s.joints[0][0] == 0 else (b, a)

    def moved(m: Mesh, d: float) -> Mesh:
        T = np.eye(4)
        T[axis, 3] = d
        return m.copy().apply_transform(T)

    def problems(pieces) -> str:
        return " ".join(split.reassembly_problems(plate, pieces, ((0, 1, "x", 0.0, "z"),), C))

    assert "overlap" in problems([low, moved(high, -2 * C)])
    loose = split.split_part(plate, _cube(180), 2 * C, "plate")  # cut with twice the gap
    assert "more than the 0.2 mm clearance" in " ".join(
        split.reassembly_problems(plate, loose.pieces, loose.joints, C)
    )
    tight = split.split_part(plate, _cube(180), 0.0, "plate")
    assert "less than the 0.2 mm clearance" in " ".join(
        split.reassembly_problems(plate, tight.pieces, tight.joints, C)
    )
    import manifold3d as mf

    bitten = split._manifold(high) - mf.Manifold.cube((10.0, 10.0, 10.0), center=True).translate(
        tuple(float(x) for x in np.asarray(high.vertices).mean(axis=0) * 1000)
    )
    assert "lack" in problems([low, split._to_mesh_m(bitten)])
    assert "leaves the part" in problems([low, moved(high, 0.01)])


def test_a_split_is_deterministic() -> None:
    plate = meshes.plate_mesh(0.313, 0.12, 0.004)
    one = split.split_part(plate, _cube(120), C, "plate")
    two = split.split_part(plate, _cube(120), C, "plate")
    assert [meshes.stl_bytes(m) for m in one.placed] == [meshes.stl_bytes(m) for m in two.placed]
    assert one.joints == two.joints


def test_no_grid_fits_refuses_naming_the_part() -> None:
    # a 100 mm plate on a 27 mm bed: 21 mm inside the skirt, less than a 20 mm piece and
    # its tongue
    plate = meshes.plate_mesh(0.1, 0.1, 0.004)
    with pytest.raises(
        InputError,
        match="'plate' .* cannot be cut into pieces that fit it .pieces of at least 20 mm",
    ):
        split.split_part(plate, _cube(27), C, "plate")


# --- the bundle on the user's bed -----------------------------------------------------------------

DESIGNS = {
    "hexapod": ("rough-terrain-walking",),
    "arm6": ("pick-and-place", "--param", "object_shape=oval"),
    "skid": ("driving", "--param", "payload=2kg"),
}


def _printed_files(files: dict[str, bytes]) -> list[str]:
    """What is printed: each piece's STL, and each part that has none as it lies."""
    rows = list(csv.DictReader(io.StringIO(files["bom.csv"].decode())))
    out = [r["file"] for r in rows if r["type"] == "piece"]
    whole = {r["name"].rsplit("_piece", 1)[0] for r in rows if r["type"] == "piece"}
    whole |= {r["name"] for r in rows if r["type"] == "piece" and "_piece" not in r["name"]}
    out += [r["file"] for r in rows if r["type"] == "printed" and r["name"] not in whole]
    return out


@pytest.fixture(scope="module")
def on_180(tmp_path_factory) -> dict[str, dict[str, bytes]]:
    from synth.commands.cli import main

    out = {}
    for key, args in DESIGNS.items():
        folder = tmp_path_factory.mktemp("bed") / key
        err = io.StringIO()
        code = main(
            ["design", *args, "--no-verify", "--bed", "180x180x180mm", "--out", str(folder)],
            out=io.StringIO(),
            err=err,
        )
        assert code == 0, err.getvalue()
        out[key] = {
            str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()
        }
    return out


def test_bundles_on_a_180_mm_bed_list_pieces_and_keep_the_models_mass(on_180) -> None:
    from tests.export.test_bundle_designs import bom_disagreements

    split_any = False
    for key, files in on_180.items():
        text = {
            k: v.decode() for k, v in files.items() if k.endswith((".csv", ".urdf", ".md", ".ini"))
        }
        assert "bed_shape = 0x0,180x0,180x180,0x180" in text["print/prusaslicer.ini"], key
        assert "max_print_height = 180" in text["print/prusaslicer.ini"], key
        assert bom_disagreements(text) == [], key
        rows = list(csv.DictReader(io.StringIO(text["bom.csv"])))
        for r in rows:
            if r["type"] == "printed":
                assert r["fits_bed"] == "yes" and r["printer"] == "180 x 180 x 180 mm", (key, r)
            if r["type"] == "piece":
                stem = r["file"].removeprefix("print/").removesuffix(".stl")
                assert r["file"] in files and f"print/{stem}.3mf" in files, (key, r)
        pieces = [r for r in rows if r["type"] == "piece" and "_piece" in r["name"]]
        for part in {r["name"].rsplit("_piece", 1)[0] for r in pieces}:
            split_any = True
            whole = next(r for r in rows if r["type"] == "printed" and r["name"] == part)
            mass = sum(
                float(r["unit_mass_kg"]) for r in pieces if r["name"].startswith(part + "_piece")
            )
            # the pieces are the part less the clearance gaps
            assert 0.99 * float(whole["unit_mass_kg"]) < mass < float(whole["unit_mass_kg"])
            assert any(r["type"] == "joint" and r["name"].startswith(part) for r in rows)
            assert f"`{part}_piece1`" in text["README.md"] and "### Pieces" in text["README.md"]
            assert f"pictures/{part}_pieces.png" in files and files[
                f"pictures/{part}_pieces.png"
            ].startswith(b"\x89PNG")
    assert split_any  # the hexapod's 313 mm trunk plate at least


def test_every_printed_piece_slices_on_the_bundles_180_mm_profile(on_180) -> None:
    """The acceptance: PrusaSlicer slices each piece (and each part printed whole) of the
    hexapod, the 6-DOF arm and the 2 kg skid-steer with the bundle's own
    print/prusaslicer.ini, every extrusion on its 180 mm bed."""
    from export.slicer import prusa_slicer, slice_with_ini

    exe = prusa_slicer()
    need(exe is not None, "prusa-slicer is not installed (apt-get install prusa-slicer)")
    jobs = {}
    for key, files in on_180.items():
        ini = files["print/prusaslicer.ini"].decode()
        for f in _printed_files(files):
            jobs.setdefault(files[f], (f"{key}/{f}", ini))
    assert len(jobs) >= 8

    def run(item):
        stl, (label, ini) = item
        return label, slice_with_ini(stl, ini, exe)

    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(run, sorted(jobs.items(), key=lambda kv: kv[1][0])))
    for label, r in results:
        assert r.bed == (180.0, 180.0), label
        assert r.time_s > 0 and r.filament_mm3 > 0 and r.on_bed, (label, r.extrusion_box)
    # a piece's own project: its copies on the same bed
    from export.slicer import slice_3mf

    files = on_180["hexapod"]
    piece = next(f for f in _printed_files(files) if f.startswith("print/"))
    r = slice_3mf(files[piece.removesuffix(".stl") + ".3mf"], exe)
    assert r.bed == (180.0, 180.0) and r.on_bed and r.filament_mm3 > 0, piece


def test_a_piece_off_the_bed_fails_the_slice_check(on_180) -> None:
    """Built to fail: a part that was split (the hexapod's 313 mm trunk plate), sliced
    whole on the 180 mm profile, extrudes off the bed (or PrusaSlicer refuses it)."""
    from export.slicer import prusa_slicer, slice_with_ini

    exe = prusa_slicer()
    need(exe is not None, "prusa-slicer is not installed (apt-get install prusa-slicer)")
    files = on_180["hexapod"]
    rows = list(csv.DictReader(io.StringIO(files["bom.csv"].decode())))
    part = next(r["name"].rsplit("_piece", 1)[0] for r in rows if r["type"] == "piece")
    try:
        r = slice_with_ini(
            files[f"meshes/{part}.stl"], files["print/prusaslicer.ini"].decode(), exe
        )
    except RuntimeError:
        return
    assert not r.on_bed
