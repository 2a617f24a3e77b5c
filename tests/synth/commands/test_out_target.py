"""The ``--out`` target of every writer (``export.bundle.write_bundle``): names that are not
a folder of their own, links, folders parmor did not write, folders appearing while the
bundle is written, failing renames and ``kill -9`` at every step leave the user's files
alone, and leave no temporary folder behind once the next write to the same target ran."""

from __future__ import annotations

import errno
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import export.bundle as bundle
from adron.errors import ExportError
from export.bundle import MARKER, write_bundle

REPO = Path(__file__).resolve().parents[3]
OLD = {"a.txt": "old", "meshes/x.stl": b"old"}
NEW = {"a.txt": "new", "b.txt": "new", "meshes/x.stl": b"new"}


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def contents(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != MARKER
    }


def foreign(folder: Path) -> Path:
    """A folder of the user's, with a file and a .git inside."""
    (folder / ".git").mkdir(parents=True)
    (folder / ".git" / "HEAD").write_text("ref: refs/heads/main\n")
    (folder / "notes.txt").write_text("keep me")
    return folder


@pytest.mark.parametrize("name", ["", " ", ".", "./", "..", "/", "a/..", "a/."])
def test_names_that_are_no_folder_of_their_own_are_refused(tmp_path, monkeypatch, name) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a").mkdir()
    with pytest.raises(ExportError, match="expected the name of a folder"):
        write_bundle(name, NEW, force=True)
    assert listing(tmp_path) == ["a"] and listing(tmp_path / "a") == []


def test_the_working_folder_and_those_above_it_are_refused(tmp_path, monkeypatch) -> None:
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    for out in (work, tmp_path, "../work"):
        with pytest.raises(ExportError, match="working folder"):
            write_bundle(out, NEW, force=True)
    assert listing(tmp_path) == ["work"] and listing(work) == []


def test_a_link_is_never_written_through(tmp_path) -> None:
    elsewhere = write_bundle(tmp_path / "elsewhere", OLD)  # ours, yet behind a link
    empty = tmp_path / "empty"
    empty.mkdir()
    for link, dest in ((tmp_path / "l1", elsewhere), (tmp_path / "l2", empty)):
        link.symlink_to(dest)
        for force in (False, True):
            with pytest.raises(ExportError, match="symbolic link"):
                write_bundle(link, NEW, force=force)
        assert link.is_symlink()
    assert contents(elsewhere) == {"a.txt": b"old", "meshes/x.stl": b"old"}
    assert listing(empty) == []
    assert listing(tmp_path) == ["elsewhere", "empty", "l1", "l2"]


def test_force_replaces_only_a_folder_parmor_wrote(tmp_path) -> None:
    mine = foreign(tmp_path / "mine")
    with pytest.raises(ExportError, match="not empty; pass --force"):
        write_bundle(mine, NEW)
    with pytest.raises(ExportError, match="not a folder parmor wrote"):
        write_bundle(mine, NEW, force=True)
    repo = foreign(tmp_path / "repo")
    with pytest.raises(ExportError, match="not a folder parmor wrote"):
        write_bundle(repo / ".git", NEW, force=True)
    assert listing(mine) == [".git", "notes.txt"] and listing(repo / ".git") == ["HEAD"]
    # ours: the marker listing parmor's files; a design record (or a folder inside one) is
    # no sign of ours (tests/synth/commands/test_force.py has the rest)
    ours = write_bundle(tmp_path / "ours", OLD)
    assert (ours / MARKER).is_file()
    write_bundle(ours, NEW, force=True)
    assert contents(ours) == {"a.txt": b"new", "b.txt": b"new", "meshes/x.stl": b"new"}
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    (legacy / "design.json").write_text(json.dumps({"robot_type": "X", "abilities": []}))
    (legacy / "ros" / "pkg").mkdir(parents=True)
    (legacy / "ros" / "pkg" / "package.xml").write_text("<package/>")
    for inside in (legacy / "ros" / "pkg", legacy):
        with pytest.raises(ExportError, match="not a folder parmor wrote"):
            write_bundle(inside, NEW, force=True)
    assert listing(legacy) == ["design.json", "ros"] and listing(legacy / "ros" / "pkg") == [
        "package.xml"
    ]
    not_a_record = foreign(tmp_path / "json")
    (not_a_record / "design.json").write_text("[]")
    with pytest.raises(ExportError, match="not a folder parmor wrote"):
        write_bundle(not_a_record, NEW, force=True)
    assert listing(tmp_path) == ["json", "legacy", "mine", "ours", "repo"]


@pytest.mark.parametrize("force", [False, True])
def test_a_folder_appearing_while_writing_is_left_alone(tmp_path, monkeypatch, force) -> None:
    out = tmp_path / "b"
    write_files = bundle._write_files

    def meanwhile(tmp, files, modes) -> None:
        write_files(tmp, files, modes)
        foreign(out)

    monkeypatch.setattr(bundle, "_write_files", meanwhile)
    with pytest.raises(ExportError, match="appeared there while"):
        write_bundle(out, NEW, force=force)
    assert listing(out) == [".git", "notes.txt"]
    assert listing(tmp_path) == ["b"]


def test_a_foreign_folder_swapped_in_while_writing_is_left_alone(tmp_path, monkeypatch) -> None:
    out = write_bundle(tmp_path / "b", OLD)
    write_files = bundle._write_files

    def meanwhile(tmp, files, modes) -> None:
        write_files(tmp, files, modes)
        os.rename(out, tmp_path / "moved")
        foreign(out)

    monkeypatch.setattr(bundle, "_write_files", meanwhile)
    with pytest.raises(ExportError, match="appeared there while"):
        write_bundle(out, NEW, force=True)
    assert listing(out) == [".git", "notes.txt"]
    assert listing(tmp_path) == ["b", "moved"]


@pytest.mark.parametrize("exchange", [True, False])
def test_a_failing_rename_leaves_nothing_behind(tmp_path, monkeypatch, exchange) -> None:
    def fail(*args) -> None:
        raise OSError(errno.EXDEV, os.strerror(errno.EXDEV))

    monkeypatch.setattr(bundle.os, "rename", fail)
    with pytest.raises(ExportError, match="cannot write"):
        write_bundle(tmp_path / "new" / "deeper" / "b", NEW)
    assert listing(tmp_path) == []  # the folders made for it are gone too
    monkeypatch.undo()
    out = write_bundle(tmp_path / "b", OLD)
    if exchange:
        monkeypatch.setattr(bundle, "_exchange", fail)
    else:
        monkeypatch.setattr(bundle, "_exchange", lambda a, b: False)
        monkeypatch.setattr(bundle.os, "rename", fail)
    with pytest.raises(ExportError, match="cannot write"):
        write_bundle(out, NEW, force=True)
    assert contents(out) == {"a.txt": b"old", "meshes/x.stl": b"old"}
    assert listing(tmp_path) == ["b"]


def test_without_the_exchange_the_replacement_still_works(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(bundle, "_exchange", lambda a, b: False)
    out = write_bundle(tmp_path / "b", OLD)
    write_bundle(out, NEW, force=True)
    assert contents(out) == {"a.txt": b"new", "b.txt": b"new", "meshes/x.stl": b"new"}
    assert listing(tmp_path) == ["b"]


# --- kill -9 ---------------------------------------------------------------------------------

#: The child: replaces ``out`` (written before with OLD) by many files, killing itself with
#: SIGKILL at the named step (or running on until the parent kills it).
CHILD = """
import os, signal, sys
import export.bundle as b

out, step = sys.argv[1], sys.argv[2]
def die():
    os.kill(os.getpid(), signal.SIGKILL)
def after(name):
    real = getattr(b, name)
    def wrapped(*args):
        result = real(*args)
        die()
    setattr(b, name, wrapped)
if step == "written":
    after("_write_files")
elif step == "swapped":
    after("_exchange")
elif step == "aside":  # the fallback without the exchange: after its first rename
    b._exchange = lambda x, y: False
    real = os.rename
    def rename(src, dst):
        real(src, dst)
        if ".parmor-old-" in str(dst):
            die()
    b.os.rename = rename
elif step == "half":  # half of the files written
    real = b.Path.write_bytes
    count = [0]
    def write_bytes(self, data):
        count[0] += 1
        if count[0] == 100:
            die()
        return real(self, data)
    b.Path.write_bytes = write_bytes
files = {f"meshes/{i:03d}.stl": bytes([i % 256]) * 20000 for i in range(200)}
files["a.txt"] = "new"
b.write_bundle(out, files, force=True)
"""


def _old_or_new(out: Path) -> str:
    """'old' or 'new': ``out`` holds one whole set of files, never a mix."""
    got = contents(out)
    if got == {"a.txt": b"old", "meshes/x.stl": b"old"}:
        return "old"
    assert got["a.txt"] == b"new" and len(got) == 201, sorted(got)[:5]
    return "new"


def _child(out: Path, step: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen([sys.executable, "-c", CHILD, str(out), step], env=env)


@pytest.mark.parametrize("step", ["written", "half", "swapped", "aside"])
def test_kill_at_each_step(tmp_path, step) -> None:
    out = write_bundle(tmp_path / "b", OLD)
    p = _child(out, step)
    assert p.wait() == -signal.SIGKILL
    if step == "aside":  # the fallback's one gap: absent until the next write puts it back
        assert not out.exists()
    else:
        assert _old_or_new(out) == ("new" if step == "swapped" else "old")
    assert len(listing(tmp_path)) == 2  # the killed run's temporary folder
    with pytest.raises(ExportError, match="not empty"):
        write_bundle(out, NEW)  # the next write to the same target cleans up first
    assert listing(tmp_path) == ["b"]
    assert _old_or_new(out) == ("new" if step == "swapped" else "old")


def test_kill_at_any_moment(tmp_path) -> None:
    """Killed after seeded random delays (whatever the machine's speed, the target holds
    one whole set of files and the next write leaves no temporary folder)."""
    rng = random.Random(11)
    out = write_bundle(tmp_path / "b", OLD)
    seen = set()
    for _ in range(6):
        p = _child(out, "run")
        time.sleep(rng.uniform(0.05, 0.6))
        p.send_signal(signal.SIGKILL)
        p.wait()
        seen.add(_old_or_new(out))
        write_bundle(out, OLD, force=True)  # cleans the leftovers, back to the old files
        assert listing(tmp_path) == ["b"]
    assert seen <= {"old", "new"}


@pytest.mark.parametrize("out", ["", ".", "/", ".."])
def test_the_command_line_refuses_those_names_before_any_work(tmp_path, monkeypatch, out) -> None:
    import io

    from synth.commands.cli import main

    monkeypatch.chdir(tmp_path)
    err = io.StringIO()
    argv = ["design", "pick-and-place", "--param", "object_shape=oval", "--conceptual"]
    assert main([*argv, "--out", out, "--force"], out=io.StringIO(), err=err) == 2
    assert "expected the name of a folder" in err.getvalue()
    assert listing(tmp_path) == []
