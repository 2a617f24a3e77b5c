"""``regress --update`` and a sweep write their files with the mode any new file gets
(0666 less the umask), not the 0600 of a temporary file (issue 23, item 9)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from synth.commands.regress import snapshot_path, temp_beside, write_atomic

SUITE = 'conceptual = true\n[[query]]\nname = "snake"\nabilities = ["rolling"]\n'


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.fixture
def umask():
    """Set the umask for one test (restored after)."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


@pytest.mark.parametrize("mask", [0o022, 0o027, 0o077, 0o002])
def test_update_writes_the_snapshot_with_the_umask_mode(
    cli, tmp_path: Path, umask, mask: int
) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text(SUITE, encoding="utf-8")
    umask(mask)
    r = cli("regress", str(suite), "--update")
    assert r.code == 0, r.err
    snap = snapshot_path(suite)
    assert mode(snap) == 0o666 & ~mask
    # rewritten: the same again (not kept at an older file's mode, nor 0600)
    os.chmod(snap, 0o600)
    assert cli("regress", str(suite), "--update").code == 0
    assert mode(snap) == 0o666 & ~mask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.snapshot.json", "s.toml"]


def test_write_atomic_keeps_the_old_file_whole_and_leaves_no_temporary(
    tmp_path: Path, umask
) -> None:
    target = tmp_path / "x.json"
    write_atomic(target, "one\n")
    assert target.read_text() == "one\n" and mode(target) == 0o644
    fd, name = temp_beside(target)
    os.close(fd)
    assert Path(name).parent == tmp_path and Path(name).name.startswith(".x.json.")
    assert mode(Path(name)) == 0o644
    os.unlink(name)
    os.chmod(tmp_path, 0o500)  # the folder cannot be written: the old file stays
    try:
        if os.access(tmp_path, os.W_OK):  # root writes anyway: nothing to test there
            return
        from adron.errors import ExportError

        with pytest.raises(ExportError, match="x.json: cannot write"):
            write_atomic(target, "two\n")
        assert target.read_text() == "one\n"
    finally:
        os.chmod(tmp_path, 0o700)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.json"]


def test_sweep_outputs_have_the_umask_mode(cli, tmp_path: Path, umask) -> None:
    study = tmp_path / "s.toml"
    study.write_text(
        '[[request]]\nabilities = ["rolling", "grasping"]\n', encoding="utf-8"
    )  # refused
    umask(0o027)
    r = cli("sweep", str(study), "--no-simulate", "--jobs", "1")
    assert r.code == 0, r.err
    out = tmp_path / "s.sweep"
    files = [p for p in out.rglob("*") if p.is_file()]
    assert {p.name for p in files} >= {"results.csv", "summary.md"}
    assert any(p.parent.name == "requests" for p in files)
    assert all(mode(p) == 0o640 for p in files), {str(p): oct(mode(p)) for p in files}
