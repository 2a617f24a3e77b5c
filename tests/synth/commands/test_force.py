"""``--force`` replaces only what parmor wrote (issue 23, item 4): ``.parmor`` lists the
files parmor wrote with their SHA-256; every other file in the folder (a ``.git``, a user's
program in ``DIR/blocks/``, the block page inside a bundle) is kept, through the atomic
swap, ``kill -9`` at each step and at random moments; a changed file of parmor's, a kept
file where a new one goes, and folders parmor did not write (a ``design.json`` beside or
above them is no sign of parmor's) are refused, named, exit 2."""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

import export.bundle as bundle
from adron.errors import ExportError
from export.bundle import MARKER, manifest_text, write_bundle
from program.blocks import PAGE_FILES, VENDOR_DIRS, VENDOR_FILES, WEB_ENV
from tests.conftest import REPO, need

OLD = {"a.txt": "old", "meshes/x.stl": b"old", "gone.txt": "only in the old bundle"}
NEW = {"a.txt": "new", "b.txt": "new", "meshes/x.stl": b"new"}
CONCEPTUAL = ["design", "pick-and-place", "--param", "object_shape=oval", "--conceptual"]


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def tree(folder: Path) -> dict[str, object]:
    """Relative name -> bytes (file), ('link', target), 'dir'; with the mode of each."""
    out: dict[str, object] = {}
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        rel = p.relative_to(folder).as_posix()
        if stat.S_ISLNK(st.st_mode):
            out[rel] = ("link", os.readlink(p))
        elif stat.S_ISDIR(st.st_mode):
            out[rel] = ("dir", stat.S_IMODE(st.st_mode))
        else:
            out[rel] = (p.read_bytes(), stat.S_IMODE(st.st_mode))
    return out


def parmors(folder: Path) -> dict[str, bytes]:
    """The files of ``folder`` but the user's (``.git``, ``notes.txt``) and the marker."""
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
        and not p.is_symlink()
        and p.name not in (MARKER, "notes.txt")
        and ".git" not in p.relative_to(folder).parts
    }


def as_bytes(files: dict) -> dict[str, bytes]:
    return {k: v.encode() if isinstance(v, str) else v for k, v in files.items()}


def git_dir(folder: Path, objects: int = 3) -> dict[str, object]:
    """A .git of the user's in ``folder``: files, a read-only object, a symbolic link, an
    empty folder, a read-only folder; returns its tree."""
    g = folder / ".git"
    (g / "refs" / "heads").mkdir(parents=True)
    (g / "HEAD").write_text("ref: refs/heads/main\n")
    (g / "refs" / "heads" / "main").write_text("0123abcd\n")
    for i in range(objects):
        obj = g / "objects" / f"{i % 7:02x}" / f"{i:038x}"
        obj.parent.mkdir(parents=True, exist_ok=True)
        obj.write_bytes(bytes([i % 256]) * 300)
        obj.chmod(0o444)
    (g / "branches").mkdir()  # empty
    (g / "info").mkdir()
    (g / "info" / "exclude").write_text("# none\n")
    (g / "info").chmod(0o555)
    (g / "current").symlink_to("refs/heads/main")
    (folder / "notes.txt").write_text("mine")
    return tree(g)


def inodes(folder: Path) -> dict[str, int]:
    """The inode of every file (links included) below ``folder``."""
    return {
        p.relative_to(folder).as_posix(): p.lstat().st_ino
        for p in folder.rglob("*")
        if p.is_symlink() or not p.is_dir()
    }


@pytest.fixture(autouse=True)
def _writable(tmp_path):
    """Give the read-only folders the tests make their write bit back (tmp_path cleanup)."""
    yield
    for p in tmp_path.rglob("*"):
        if p.is_dir() and not p.is_symlink():
            p.chmod(0o755)


# --- the manifest ---------------------------------------------------------------------------


def test_the_marker_lists_every_file_with_its_hash_and_is_byte_identical(tmp_path) -> None:
    a = write_bundle(tmp_path / "a", NEW)
    b = write_bundle(tmp_path / "b", dict(reversed(NEW.items())))
    raw = (a / MARKER).read_bytes()
    assert raw == (b / MARKER).read_bytes() == manifest_text(NEW).encode()
    import hashlib

    listed = json.loads(raw)["files"]
    assert listed == {
        n: "sha256:" + hashlib.sha256(c).hexdigest() for n, c in as_bytes(NEW).items()
    }


@pytest.mark.parametrize(
    ("marker", "says"),
    [
        (bundle.LEGACY_MARKER_TEXT, "older parmor"),
        ("", "not parmor's list"),
        ("{not json", "not parmor's list"),
        ('{"format": "parmor-files-1", "files": {"a.txt": "md5:00"}}', "not parmor's list"),
        ('{"format": "other", "files": {}}', "not parmor's list"),
        ('["a.txt"]', "not parmor's list"),
        (None, "a link or a folder"),  # a link to a real marker
    ],
)
def test_a_marker_that_is_no_list_of_parmors_files_is_refused(tmp_path, marker, says) -> None:
    out = tmp_path / "b"
    out.mkdir()
    before = git_dir(out)
    if marker is None:
        real = write_bundle(tmp_path / "real", OLD)
        (out / MARKER).symlink_to(real / MARKER)
    else:
        (out / MARKER).write_text(marker)
    for adopt in (False, True):
        with pytest.raises(ExportError, match=says) as e:
            write_bundle(out, NEW, force=True, adopt=adopt)
        assert MARKER in str(e.value)
    assert git_dir_tree(out) == before and (out / "notes.txt").read_text() == "mine"


def git_dir_tree(folder: Path) -> dict[str, object]:
    return tree(folder / ".git")


# --- what --force keeps, replaces, refuses ----------------------------------------------------


@pytest.mark.parametrize("exchange", [True, False])
def test_force_keeps_a_git_and_the_users_files(tmp_path, monkeypatch, exchange) -> None:
    if not exchange:  # the fallback: renamed aside, then into place
        monkeypatch.setattr(bundle, "_exchange", lambda a, b: False)
    out = write_bundle(tmp_path / "b", OLD)
    before = git_dir(out)
    (out / "meshes" / "mine.stl").write_bytes(b"a mesh of mine")  # in a folder of parmor's
    (out / "empty").mkdir()
    ino = inodes(out / ".git")
    write_bundle(out, NEW, force=True)
    assert parmors(out) == {**as_bytes(NEW), "meshes/mine.stl": b"a mesh of mine"}
    assert git_dir_tree(out) == before  # contents, links, modes, empty folders
    assert inodes(out / ".git") == ino  # the user's files themselves, not copies
    assert (out / "notes.txt").read_text() == "mine" and (out / "empty").is_dir()
    assert listing(tmp_path) == ["b"]  # nothing left beside it
    assert json.loads((out / MARKER).read_text())["files"].keys() == NEW.keys()
    write_bundle(out, OLD, force=True)  # and back: b.txt was parmor's, it goes
    assert parmors(out) == {**as_bytes(OLD), "meshes/mine.stl": b"a mesh of mine"}
    assert git_dir_tree(out) == before and listing(tmp_path) == ["b"]


def test_a_parmor_file_changed_since_is_refused_named(tmp_path) -> None:
    out = write_bundle(tmp_path / "b", OLD)
    git_dir(out)
    (out / "meshes" / "x.stl").write_bytes(b"edited")
    with pytest.raises(ExportError, match=r"meshes/x\.stl: parmor wrote this file and it was ch"):
        write_bundle(out, NEW, force=True)
    assert (out / "meshes" / "x.stl").read_bytes() == b"edited"
    (out / "meshes" / "x.stl").unlink()
    (out / "meshes" / "x.stl").symlink_to("../a.txt")  # a link in its place: changed too
    with pytest.raises(ExportError, match=r"x\.stl: parmor wrote this file"):
        write_bundle(out, NEW, force=True)
    (out / "meshes" / "x.stl").unlink()  # deleted: nothing of the user's there
    write_bundle(out, NEW, force=True)
    assert parmors(out) == as_bytes(NEW) and listing(tmp_path) == ["b"]


@pytest.mark.parametrize(
    ("mine", "says"),
    [
        ("b.txt", "new file goes at 'b.txt'"),  # a file of the user's where a new file goes
        ("b.txt/inside", "new file goes at 'b.txt'"),  # a folder of the user's there
        ("c", "new folder goes at 'c'"),  # a file of the user's where a new folder goes
    ],
)
def test_a_kept_file_where_a_new_one_goes_is_refused_named(tmp_path, mine, says) -> None:
    out = write_bundle(tmp_path / "b", OLD)
    new = {**NEW, "c/x": "new"}
    (out / mine).parent.mkdir(parents=True, exist_ok=True)
    (out / mine).write_text("mine")
    before = tree(out)
    with pytest.raises(ExportError, match=f"{mine}: parmor did not write it, and a {says}"):
        write_bundle(out, new, force=True)
    assert tree(out) == before and listing(tmp_path) == ["b"]


def test_an_empty_folder_of_the_users_where_a_folder_goes_is_kept(tmp_path) -> None:
    out = write_bundle(tmp_path / "b", {"a.txt": "old"})
    (out / "meshes").mkdir()
    write_bundle(out, NEW, force=True)
    assert parmors(out) == as_bytes(NEW)


def test_the_manifest_never_reaches_outside_the_folder(tmp_path) -> None:
    """A crafted .parmor listing files outside (by '..' or through a link) with their
    hashes deletes none of them: a name that leaves the folder is refused by the list's
    schema (naming it), and only the folder's own files are ever looked at."""
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "f.txt").write_text("precious")
    out = write_bundle(tmp_path / "b", OLD)
    (out / "link").symlink_to(victim)
    import hashlib

    digest = "sha256:" + hashlib.sha256(b"precious").hexdigest()
    body = json.loads((out / MARKER).read_text())
    for name in ("../victim/f.txt", "/abs/f.txt", "a/./b", "a//b"):
        crafted = {**body, "files": {**body["files"], name: digest}}
        (out / MARKER).write_text(json.dumps(crafted))
        with pytest.raises(ExportError) as e:
            write_bundle(out, NEW, force=True)
        assert f"{MARKER}: files." in str(e.value) and repr(name) in str(e.value)
        assert (victim / "f.txt").read_text() == "precious"
    body["files"] |= {"link/f.txt": digest}
    (out / MARKER).write_text(json.dumps(body))
    write_bundle(out, NEW, force=True)
    assert (victim / "f.txt").read_text() == "precious"
    assert (out / "link").is_symlink() and os.readlink(out / "link") == str(victim)


@pytest.mark.parametrize("inside", [False, True])
def test_a_design_json_is_no_sign_of_parmors(tmp_path, inside) -> None:
    """The issue's cases: a folder holding (or inside one holding) a design.json, even a
    design record, is not parmor's: refused with --force, nothing deleted."""
    repo = tmp_path / "repo"
    (repo / "src").mkdir(parents=True)
    (repo / "design.json").write_text(json.dumps({"robot_type": "x", "abilities": []}))
    (repo / "src" / "main.py").write_text("print('mine')\n")
    (repo / ".git").mkdir()
    if inside:  # and the marker of an older parmor there
        (repo / MARKER).write_text(bundle.LEGACY_MARKER_TEXT)
    before = tree(tmp_path)
    with pytest.raises(ExportError, match="not a folder parmor wrote"):
        write_bundle(repo / "src" if inside else repo, NEW, force=True)
    assert tree(tmp_path) == before


def test_adopt_keeps_every_file_of_a_folder_without_a_marker(tmp_path) -> None:
    out = tmp_path / "blocks"
    (out / "lib").mkdir(parents=True)
    (out / "my_program.py").write_text("print(1)\n")
    (out / "lib" / "util.py").write_text("x = 1\n")
    with pytest.raises(ExportError, match="not a folder parmor wrote"):
        write_bundle(out, NEW, force=True)  # without adopt: refused
    write_bundle(out, NEW, force=True, adopt=True)
    assert parmors(out) == {
        **as_bytes(NEW),
        "my_program.py": b"print(1)\n",
        "lib/util.py": b"x = 1\n",
    }
    assert json.loads((out / MARKER).read_text())["files"].keys() == NEW.keys()
    write_bundle(out, OLD, force=True, adopt=True)
    assert parmors(out) == {
        **as_bytes(OLD),
        "my_program.py": b"print(1)\n",
        "lib/util.py": b"x = 1\n",
    }
    (out / "b.txt").write_text("mine")  # where NEW writes one
    with pytest.raises(ExportError, match="b.txt: parmor did not write it"):
        write_bundle(out, NEW, force=True, adopt=True)
    assert listing(tmp_path) == ["blocks"]


# --- races: what appears in the old folder while the two are swapped -------------------------


@pytest.mark.parametrize("adopt", [False, True])
def test_files_written_into_the_old_folder_during_the_swap_are_moved_not_deleted(
    tmp_path, monkeypatch, adopt
) -> None:
    """Also into a folder adopted (given an empty marker first: else the old folder would
    look like a new one killed before its marker, deleted whole)."""
    out = tmp_path / "b"
    if adopt:
        out.mkdir()
    else:
        write_bundle(out, OLD)
    git_dir(out)
    (out / ".git" / "index").write_text("index 1")
    real = bundle._exchange

    def exchange(a: Path, b: Path) -> bool:
        done = real(a, b)
        # the old folder is at a now: a program still writing there (its old name)
        (a / ".git" / "objects" / "new").mkdir()
        (a / ".git" / "objects" / "new" / "obj").write_text("a new object")
        (a / ".git" / "index.lock").write_text("index 2")
        os.replace(a / ".git" / "index.lock", a / ".git" / "index")  # git's way: replaced
        (a / "both.txt").write_text("old side")  # also written in the new folder: kept aside
        (b / "both.txt").write_text("new side")
        return done

    monkeypatch.setattr(bundle, "_exchange", exchange)
    write_bundle(out, NEW, force=True, adopt=adopt)
    assert (out / ".git" / "objects" / "new" / "obj").read_text() == "a new object"
    assert (out / ".git" / "index").read_text() == "index 2"  # the newer one
    assert (out / "both.txt").read_text() == "new side"
    (left,) = [p for p in tmp_path.iterdir() if p.name != "b"]  # never deleted: left aside
    assert (left / "both.txt").read_text() == "old side"
    assert sorted(p.name for p in left.iterdir()) == [MARKER, "both.txt"]


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", ""])
    p.wait()
    return p.pid


def test_a_killed_runs_folder_gives_the_users_files_back(tmp_path) -> None:
    """A leftover holding a file of the user's that the target lacks moves it there; one
    whose marker is not parmor's list is left alone."""
    out = write_bundle(tmp_path / "b", OLD)
    prefix = bundle._prefix(out)
    pid = _dead_pid()
    left = tmp_path / f"{prefix}old-{pid}-0000"
    (left / ".git").mkdir(parents=True)
    (left / ".git" / "HEAD").write_text("ref: mine")
    (left / "a.txt").write_text("old")
    (left / MARKER).write_text(manifest_text({"a.txt": "old"}))
    odd = tmp_path / f"{prefix}new-{pid}-0001"
    odd.mkdir()
    (odd / "mine.txt").write_text("mine")
    (odd / MARKER).write_text("not a list")
    write_bundle(out, NEW, force=True)
    assert (out / ".git" / "HEAD").read_text() == "ref: mine" and parmors(out) == as_bytes(NEW)
    assert listing(tmp_path) == sorted(["b", odd.name])
    assert (odd / "mine.txt").read_text() == "mine"


# --- kill -9 with files of the user's in the folder --------------------------------------------

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
if step in ("written", "carried", "swapped"):
    after({"written": "_write_files", "carried": "_carry", "swapped": "_exchange"}[step])
elif step == "aside":  # the fallback without the exchange: after its first rename
    b._exchange = lambda x, y: False
    real = os.rename
    def rename(src, dst):
        real(src, dst)
        if ".parmor-old-" in str(dst):
            die()
    b.os.rename = rename
elif step == "linking":  # half of the user's files linked into the new folder
    real = b.os.link
    count = [0]
    def link(*args, **kw):
        count[0] += 1
        if count[0] == 40:
            die()
        return real(*args, **kw)
    b.os.link = link
elif step == "discarding":  # half of the old folder deleted
    real = b.Path.unlink
    count = [0]
    def unlink(self, *args):
        count[0] += 1
        if count[0] == 100:
            die()
        return real(self, *args)
    b.Path.unlink = unlink
files = {f"meshes/{i:03d}.stl": bytes([i % 256]) * 20000 for i in range(200)}
files["a.txt"] = "new"
b.write_bundle(out, files, force=True)
"""

KILL_OLD = {"a.txt": "old", **{f"meshes/{i:03d}.stl": b"old" for i in range(150)}}


def _old_or_new(out: Path) -> str:
    got = parmors(out)
    if got == as_bytes(KILL_OLD):
        return "old"
    assert got["a.txt"] == b"new" and len(got) == 201, sorted(got)[:5]
    return "new"


def _child(out: Path, step: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen([sys.executable, "-c", CHILD, str(out), step], env=env)


@pytest.mark.parametrize("step", ["linking", "carried", "swapped", "discarding", "aside"])
def test_kill_at_each_step_keeps_the_git(tmp_path, step) -> None:
    out = write_bundle(tmp_path / "b", KILL_OLD)
    before = git_dir(out, objects=80)
    p = _child(out, step)
    assert p.wait() == -signal.SIGKILL
    if step == "aside":  # the fallback's one gap: absent until the next write puts it back
        assert not out.exists()
    else:
        assert git_dir_tree(out) == before and (out / "notes.txt").read_text() == "mine"
        _old_or_new(out)
    assert len(listing(tmp_path)) == 2  # the killed run's temporary folder
    with pytest.raises(ExportError, match="not empty"):
        write_bundle(out, NEW)  # the next write to the same target cleans up first
    assert listing(tmp_path) == ["b"]
    assert git_dir_tree(out) == before and (out / "notes.txt").read_text() == "mine"
    assert _old_or_new(out) == ("new" if step in ("swapped", "discarding") else "old")


def test_kill_at_any_moment_keeps_the_git(tmp_path) -> None:
    """Killed after seeded random delays: the target holds one whole set of parmor's files
    and every file of the user's, and the next write leaves no temporary folder."""
    rng = random.Random(23)
    out = write_bundle(tmp_path / "b", KILL_OLD)
    before = git_dir(out, objects=300)
    for _ in range(6):
        p = _child(out, "run")
        time.sleep(rng.uniform(0.05, 0.8))
        p.send_signal(signal.SIGKILL)
        p.wait()
        _old_or_new(out)  # the exchange: never absent
        assert git_dir_tree(out) == before and (out / "notes.txt").read_text() == "mine"
        write_bundle(out, KILL_OLD, force=True)  # cleans the leftovers, back to the old
        assert listing(tmp_path) == ["b"] and git_dir_tree(out) == before


# --- the command line ----------------------------------------------------------------------------


def test_design_force_keeps_the_bundles_git(cli, tmp_path) -> None:
    out = tmp_path / "b"
    assert cli(*CONCEPTUAL, "--out", str(out)).code == 0
    before = git_dir(out)
    r = cli(*CONCEPTUAL, "--out", str(out), "--force")
    assert r.code == 0, r.err
    assert git_dir_tree(out) == before and (out / "notes.txt").read_text() == "mine"
    assert listing(out) == [".git", MARKER, "design.json", "notes.txt"]
    (out / "design.json").write_text("{}")  # the user's edit of a file parmor wrote
    r = cli(*CONCEPTUAL, "--out", str(out), "--force")
    assert r.code == 2 and f"{out / 'design.json'}: parmor wrote this file" in r.err
    assert "Traceback" not in r.err and (out / "design.json").read_text() == "{}"


def test_design_force_keeps_a_real_git_repository(cli, tmp_path) -> None:
    git = shutil.which("git")
    need(git is not None, "git is absent (apt-get install git)")
    out = tmp_path / "b"
    assert cli(*CONCEPTUAL, "--out", str(out)).code == 0
    env = {
        **os.environ,
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@t",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@t",
        "GIT_CONFIG_GLOBAL": os.devnull,
        "GIT_CONFIG_NOSYSTEM": "1",
    }

    def run(*argv: str) -> str:
        return subprocess.run(
            [git, *argv], cwd=out, env=env, check=True, capture_output=True, text=True, timeout=120
        ).stdout

    run("init", "-q")
    run("add", "-A")
    run("commit", "-q", "-m", "first")
    head = run("rev-parse", "HEAD")
    assert cli(*CONCEPTUAL, "--out", str(out), "--force").code == 0
    assert run("rev-parse", "HEAD") == head
    assert run("status", "--porcelain") == ""  # the same files, byte for byte
    run("fsck", "--no-progress")


@pytest.mark.parametrize("where", ["repo/src", "repo"])
def test_design_force_refuses_a_folder_parmor_did_not_write(cli, tmp_path, where) -> None:
    """The issue's two cases: ``--out repo/src --force`` and ``--out repo --force`` where
    repo holds a design.json of a design record's shape."""
    repo = tmp_path / "repo"
    (repo / "src").mkdir(parents=True)
    (repo / ".git").mkdir()
    (repo / ".git" / "HEAD").write_text("ref: refs/heads/main\n")
    (repo / "design.json").write_text('{"robot_type": "x", "abilities": []}')
    (repo / "src" / "main.py").write_text("print('mine')\n")
    before = tree(tmp_path)
    r = cli(*CONCEPTUAL, "--out", str(tmp_path / where), "--force")
    assert r.code == 2, r.err
    assert f"{tmp_path / where}: not a folder parmor wrote" in r.err
    assert "Traceback" not in r.err and r.out == ""
    assert tree(tmp_path) == before


# --- parmor blocks DIR ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sized(tmp_path_factory) -> Path:
    """A sized bundle (the differential drive, not simulated)."""
    import io

    from synth.commands.cli import main

    out = tmp_path_factory.mktemp("sized") / "cart"
    err = io.StringIO()
    code = main(
        ["design", "driving", "--no-input", "--no-verify", "--out", str(out)],
        out=io.StringIO(),
        err=err,
    )
    assert code == 0, err.getvalue()
    return out


@pytest.fixture
def web(tmp_path, monkeypatch) -> Path:
    """A web folder of stand-ins for the page's files and the npm files ($PARMOR_WEB)."""
    w = tmp_path / "web"
    for f in PAGE_FILES:
        (w / "page").mkdir(parents=True, exist_ok=True)
        (w / "page" / f).write_text(f"page {f}\n")
    for src in VENDOR_FILES:
        (w / "node_modules" / src).parent.mkdir(parents=True, exist_ok=True)
        (w / "node_modules" / src).write_text(f"npm {src}\n")
    for src in VENDOR_DIRS:
        (w / "node_modules" / src).mkdir(parents=True, exist_ok=True)
        (w / "node_modules" / src / "click.mp3").write_bytes(b"sound")
    monkeypatch.setenv(WEB_ENV, str(w))
    return w


def test_blocks_keeps_a_users_program_in_the_page_folder(cli, sized, tmp_path, web) -> None:
    folder = tmp_path / "cart"
    shutil.copytree(sized, folder)
    assert cli("blocks", str(folder)).code == 0
    page = folder / "blocks"
    (page / "my_program.py").write_text("def main(robot):\n    pass\n")
    (page / "programs").mkdir()
    (page / "programs" / "square.json").write_text('{"program": []}')
    first = tree(page)
    r = cli("blocks", str(folder))
    assert r.code == 0, r.err
    assert tree(page) == first  # the page's own files again, byte for byte, and the user's
    assert (page / "my_program.py").read_text() == "def main(robot):\n    pass\n"
    (web / "page" / "style.css").write_text("a newer style\n")  # a newer parmor's page
    assert cli("blocks", str(folder)).code == 0
    assert (page / "style.css").read_text() == "a newer style\n"
    assert (page / "programs" / "square.json").read_text() == '{"program": []}'
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == [MARKER]


def test_blocks_adopts_a_page_folder_the_user_made(cli, sized, tmp_path, web) -> None:
    folder = tmp_path / "cart"
    shutil.copytree(sized, folder)
    (folder / "blocks").mkdir()
    (folder / "blocks" / "my_program.py").write_text("mine")
    assert cli("blocks", str(folder)).code == 0
    assert (folder / "blocks" / "my_program.py").read_text() == "mine"
    assert (folder / "blocks" / "index.html").read_text() == "page index.html\n"


@pytest.mark.parametrize("case", ["mine", "edited"])
def test_blocks_refuses_to_overwrite_a_users_file(cli, sized, tmp_path, web, case) -> None:
    """A file of the user's where a page file goes, or a page file the user edited: exit
    2 naming it, the folder as it was."""
    folder = tmp_path / "cart"
    shutil.copytree(sized, folder)
    page = folder / "blocks"
    if case == "mine":
        page.mkdir()
        (page / "index.html").write_text("my own page")
        says = "parmor did not write it, and a new file goes at 'index.html'"
    else:
        assert cli("blocks", str(folder)).code == 0
        (page / "index.html").write_text("my own page")
        says = "parmor wrote this file and it was changed since"
    before = tree(folder)
    r = cli("blocks", str(folder))
    assert r.code == 2 and f"{page / 'index.html'}: {says}" in r.err, r.err
    assert "Traceback" not in r.err and tree(folder) == before


def test_design_force_keeps_the_page_and_the_users_program(cli, sized, tmp_path, web) -> None:
    """Replacing a bundle keeps its block page (written by 'parmor blocks', not by the
    design), the user's program in it included."""
    folder = tmp_path / "cart"
    shutil.copytree(sized, folder)
    assert cli("blocks", str(folder)).code == 0
    (folder / "blocks" / "my_program.py").write_text("mine")
    page = tree(folder / "blocks")
    argv = ["design", "driving", "--no-input", "--no-verify", "--out", str(folder), "--force"]
    r = cli(*argv)
    assert r.code == 0, r.err
    assert tree(folder / "blocks") == page
    bundle_files = {k for k in parmors(folder) if not k.startswith("blocks/")}
    assert bundle_files == set(parmors(sized))
    assert (folder / "design.json").read_bytes() == (sized / "design.json").read_bytes()
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == [MARKER]
