"""Benchmark of printed-part generation: manifold3d (``export.meshes``) against OpenSCAD.

Usage: ``python bench/bench_stl.py``. ``bench_stl`` returns the report lines for
``bench/bench.py``.

The parts are the three links (L1, L2, L3) of the default 3-DOF manipulator design, with
the catalog's dovetail faces and fillets. Both sides build the same solid from the same
numbers: the revolution of the same half-section (``export.meshes.link_profile_mm``) with
the same number of segments, whose plate discs become the faces' squares; manifold3d moves
the discs' rims onto the square (``Manifold.warp_batch``), OpenSCAD, which has no warp,
intersects the revolution with the square prism (its cheapest construction). OpenSCAD
(Debian's ``openscad``, CGAL booleans) reads a ``.scad`` file the benchmark writes to a
temporary folder and writes an STL; it is timed as a user runs it, one process per part
(its start-up time, measured on an empty file, is reported too). manifold3d is timed from
the dimensions to the STL bytes in memory, best of several runs. Volumes are compared
between the two meshes and with the analytic volume.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from adron.catalog import load_catalog  # noqa: E402
from export import meshes  # noqa: E402
from kinematics.spatial import link_part_volume  # noqa: E402

RUNS = 20  # manifold3d
SCAD_RUNS = 1  # OpenSCAD (seconds per part)
SCAD_TIMEOUT = 600.0
T = TypeVar("T")


def best_of(fn: Callable[[], T], runs: int) -> tuple[float, T]:
    """Best wall time in seconds over ``runs`` calls, and the last result."""
    best = float("inf")
    result = None
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result  # type: ignore[return-value]


def default_links() -> list[tuple[str, tuple[float, ...]]]:
    """(name, (length, r_outer, r_inner, face_side, face_thickness, fillet) m) of the default
    Manipulator3DOF design's links."""
    from adron.kb import load
    from synth.reasoning.solver import Query, Reasoner
    from synth.sizing.structure import design_structure

    kb = load()
    catalog = load_catalog()
    candidates = {c.robot_type: c for c in Reasoner(kb).solve(Query()).candidates}
    s = design_structure(kb, candidates["Manipulator3DOF"], catalog, {})
    p = catalog.passive
    faces = (p.dovetail_face_m, p.face_thickness_m, p.fillet_radius_m)
    return [(ld.name, (ld.length_m, ld.r_outer_m, ld.r_inner_m, *faces)) for ld in s.links]


def scad_source(dims: tuple[float, ...], segments: int = meshes.SEGMENTS) -> str:
    """OpenSCAD source (mm) of the link part ``link_mesh(*dims, segments)`` builds: the same
    half-section revolved, intersected with the square prism of the faces."""
    length, side = meshes.MM * dims[0], meshes.MM * dims[3]
    profile = meshes.link_profile_mm(*dims, segments)
    points = ", ".join(f"[{r:.9g}, {z:.9g}]" for r, z in profile)
    return (
        f"$fn = {segments};\n"
        "intersection() {\n"
        f"  rotate_extrude() polygon([{points}]);\n"
        f"  translate([0, 0, {length / 2:.9g}]) "
        f"cube([{side:.9g}, {side:.9g}, {length + 2:.9g}], center=true);\n"
        "}\n"
    )


def _openscad(exe: str, scad: Path, out: Path) -> float:
    """Seconds for ``openscad -o out scad`` (raises on failure)."""
    t0 = time.perf_counter()
    subprocess.run(
        [exe, "-o", str(out), str(scad)],
        check=True,
        capture_output=True,
        timeout=SCAD_TIMEOUT,
    )
    return time.perf_counter() - t0


def bench_stl() -> list[str]:
    """Time manifold3d and OpenSCAD on the default 3-DOF manipulator's link parts."""
    import trimesh

    links = default_links()
    lines = [f"Printed link parts: manifold3d (best of {RUNS}) vs OpenSCAD"]
    ours: dict[str, tuple[float, trimesh.Trimesh]] = {}
    for name, dims in links:
        seconds, _ = best_of(lambda dims=dims: meshes.stl_bytes(meshes.link_mesh(*dims)), RUNS)
        mesh = meshes.link_mesh(*dims)
        ours[name] = (seconds, mesh)
        vol = meshes.mesh_volume(mesh)
        ana = link_part_volume(*dims)
        lines.append(
            f"  {name:<4} L={dims[0] * 1e3:5.1f} mm r2={dims[1] * 1e3:4.1f} r1={dims[2] * 1e3:4.1f}"
            f"  manifold3d {seconds * 1e3:7.2f} ms  {len(mesh.faces):5d} triangles  "
            f"volume {vol * 1e6:7.3f} cm^3 (analytic {ana * 1e6:7.3f}, "
            f"{(vol / ana - 1) * 100:+.2f} %)"
        )
    total_ours = sum(s for s, _ in ours.values())
    exe = shutil.which("openscad")
    if exe is None:
        lines.append("  openscad not installed: comparison skipped")
        lines.append(f"  manifold3d: {total_ours / len(links) * 1e3:.2f} ms per part")
        return lines
    version = subprocess.run([exe, "--version"], capture_output=True, text=True)
    lines.append(f"  {(version.stderr or version.stdout).strip()}")
    with tempfile.TemporaryDirectory(prefix="parmor-bench-stl-") as tmp:
        folder = Path(tmp)
        empty = folder / "empty.scad"
        empty.write_text("cube(1);\n", encoding="utf-8")
        startup = min(_openscad(exe, empty, folder / "empty.stl") for _ in range(3))
        total_scad = 0.0
        for name, dims in links:
            scad = folder / f"{name}.scad"
            scad.write_text(scad_source(dims), encoding="utf-8")
            out = folder / f"{name}.stl"
            seconds = min(_openscad(exe, scad, out) for _ in range(SCAD_RUNS))
            total_scad += seconds
            theirs = trimesh.load(out, file_type="stl")
            v_scad = float(theirs.volume) / meshes.MM**3
            mine_s, mine = ours[name]
            v_ours = meshes.mesh_volume(mine)
            lines.append(
                f"  {name:<4} OpenSCAD {seconds * 1e3:9.1f} ms  ({seconds / mine_s:7.0f}x "
                f"manifold3d)  volume {v_scad * 1e6:7.3f} cm^3, "
                f"{(v_scad / v_ours - 1) * 100:+.4f} % vs manifold3d, "
                f"watertight {theirs.is_watertight}"
            )
    n = len(links)
    lines.append(
        f"  per part: manifold3d {total_ours / n * 1e3:.2f} ms, OpenSCAD {total_scad / n * 1e3:.1f}"
        f" ms (start-up {startup * 1e3:.0f} ms of it): {total_scad / total_ours:.0f}x "
        f"({(total_scad - n * startup) / total_ours:.0f}x without OpenSCAD's start-up); "
        "target >= 100x"
    )
    return lines


if __name__ == "__main__":
    print("\n".join(bench_stl()))
