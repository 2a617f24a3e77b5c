"""Serial arms of 3 to 7 joints over a grid of requests (issue 21): each one designed and
verified in MuJoCo by ``parmor design pick-and-place --param dof=N`` (payload, reach and
object shape varied), then every listed behaviour run again by ``parmor simulate``.

A request passes when the design exits 0 and every behaviour's verdict is ``ok``. The
object shapes are those that ask for the abilities an arm of N joints has (a rotationally
symmetric object needs no orienting: 3 to 5 joints; an asymmetric one does: 6 and 7).

    python bench/arm_grid.py [--out FOLDER] [--quick]

prints one line per request and the pass rate.
"""

from __future__ import annotations

import argparse
import itertools
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DOFS = (3, 4, 5, 6, 7)
PAYLOADS = ("0.05 kg", "0.15 kg")
REACHES = ("0.2 m", "0.3 m")
SHAPES = {3: ("cylinder", "sphere"), 4: ("cylinder", "sphere"), 5: ("cylinder", "sphere"),
          6: ("oval", "box"), 7: ("oval", "box")}  # fmt: skip


def parmor(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "synth.commands.cli", *args],
        capture_output=True,
        text=True,
        check=False,
    )


def one(folder: Path, dof: int, payload: str, reach: str, shape: str) -> tuple[bool, str]:
    out = folder / f"arm{dof}-{shape}-{payload.split()[0]}-{reach.split()[0]}"
    r = parmor(
        "design", "pick-and-place", "--param", f"object_shape={shape}", "--param",
        f"dof={dof}", "--param", f"payload={payload}", "--param", f"reach={reach}",
        "--no-input", "--out", str(out),
    )  # fmt: skip
    if r.returncode != 0:
        return False, f"design exit {r.returncode}: {r.stderr.strip().splitlines()[-1]}"
    record = json.loads((out / "design.json").read_text())
    bad = []
    names = sorted(p.stem for p in (out / "trajectories").glob("*.csv"))
    for name in names:
        s = parmor("simulate", str(out), "--behavior", name, "--json")
        verdict = json.loads(s.stdout).get("verdict") if s.returncode == 0 else None
        if verdict != "ok":
            bad.append(f"{name}: {verdict or s.stderr.strip()[-200:]}")
    what = f"{record['robot_type']}, {len(names)} behaviours"
    return not bad, what + ("" if not bad else "; " + "; ".join(bad))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=None, help="folder of the bundles")
    ap.add_argument("--quick", action="store_true", help="one payload and one reach")
    ap.add_argument("--dof", type=int, action="append", help="only these joint counts")
    a = ap.parse_args()
    folder = a.out or Path(tempfile.mkdtemp(prefix="arm-grid-"))
    payloads, reaches = (PAYLOADS[:1], REACHES[:1]) if a.quick else (PAYLOADS, REACHES)
    cases = [
        (d, p, r, s) for d in (a.dof or DOFS) for p, r in itertools.product(payloads, reaches)
        for s in SHAPES[d]
    ]  # fmt: skip
    passed = 0
    for d, p, r, s in cases:
        t0 = time.monotonic()
        ok, why = one(folder, d, p, r, s)
        passed += ok
        print(
            f"dof={d} payload={p} reach={r} shape={s}: {'pass' if ok else 'FAIL'} "
            f"({why}; {time.monotonic() - t0:.0f} s)",
            flush=True,
        )
    print(f"{passed}/{len(cases)} passed ({100 * passed / len(cases):.0f} %)")
    return 0 if passed == len(cases) else 1


if __name__ == "__main__":
    raise SystemExit(main())
