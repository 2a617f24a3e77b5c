"""The caches are read back into the process (the knowledge base and the catalog are
pickles: unpickling runs code), so a cache folder another user owns or may write is not
used (a one-line warning, nothing read or written), and a cache file that is not the
user's own is never read (issue 23, item 9)."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import pytest

import adron.units
import gaits.base
from adron import kb as kb_module
from adron.catalog import _cache_path, _cached_catalog, load_catalog
from adron.units import cache_folder, read_cache_bytes, unsafe_cache_folder

ROOT = os.getuid() == 0
NOBODY = 65534


class Planted:
    """A pickle that makes the folder ``marker`` when it is loaded (as a planted file
    would run anything)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.mkdir, (str(self.marker),))


@pytest.fixture(autouse=True)
def fresh_warnings(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(adron.units, "_WARNED", set())
    monkeypatch.setattr(gaits.base, "_WARNED", set())


def private(path: Path) -> Path:
    path.mkdir(mode=0o700)
    os.chmod(path, 0o700)
    return path


def kb_entry(folder: Path) -> tuple[Path, bytes]:
    """Where ``load()`` of the shipped ontology looks in ``folder``, and the tag its file
    starts with."""
    path = kb_module._cache_file(kb_module.builtin_files())
    assert path is not None and path.parent == folder
    return path, kb_module._CACHE_FORMAT


def catalog_entry(folder: Path) -> tuple[Path, bytes]:
    """Where the catalog file ``folder/../mine.toml`` is cached, and its tag."""
    from adron import catalog

    mine = folder.parent / "mine.toml"
    text = (Path(catalog.__file__).parent / "catalog.toml").read_text(encoding="utf-8")
    mine.write_text(text, encoding="utf-8")
    path = _cache_path(text, str(mine), mine.parent, "")
    assert path is not None and path.parent == folder
    return path, catalog._CATALOG_CACHE


def load_kb() -> object:
    return kb_module.load()


def load_mine(folder: Path) -> object:
    return load_catalog(folder.parent / "mine.toml")


CACHES = {"knowledge base": (kb_entry, lambda f: load_kb()), "catalog": (catalog_entry, load_mine)}


def plant(folder: Path, case: str, tmp_path: Path) -> tuple[Path, Path]:
    """A file in the cache folder, where ``case``'s load reads, that runs code; (it, the
    folder its code makes)."""
    entry, _ = CACHES[case]
    path, tag = entry(folder)
    marker = tmp_path / "planted-code-ran"
    path.write_bytes(tag + pickle.dumps(Planted(marker)))
    os.chmod(path, 0o600)
    return path, marker


@pytest.mark.parametrize("case", sorted(CACHES))
def test_the_users_own_private_file_is_read(
    case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The control: a file in the user's own private folder is trusted (this is what the
    checks below stop), so the planted code runs."""
    folder = private(tmp_path / "cache")
    monkeypatch.setenv("PARMOR_CACHE", str(folder))
    _, marker = plant(folder, case, tmp_path)
    CACHES[case][1](folder)
    assert marker.is_dir()


@pytest.mark.parametrize("mode", [0o777, 0o770, 0o757, 0o1777])
@pytest.mark.parametrize("case", sorted(CACHES))
def test_a_folder_others_may_write_is_not_used(
    case: str, mode: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    folder = private(tmp_path / "cache")
    monkeypatch.setenv("PARMOR_CACHE", str(folder))
    path, marker = plant(folder, case, tmp_path)
    os.chmod(folder, mode)
    before = sorted(p.name for p in folder.iterdir())
    got = CACHES[case][1](folder)
    assert not marker.exists()  # the planted code did not run
    assert got is not None
    assert sorted(p.name for p in folder.iterdir()) == before  # nothing written there
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "cache folder" in line]
    assert lines == [
        f"parmor: warning: not using the cache folder {folder} (PARMOR_CACHE): "
        + unsafe_cache_folder(folder)
    ]
    assert f"mode {mode:04o}" in lines[0] and "chmod go-w" in lines[0]
    assert cache_folder() is None and gaits.base.cache_folder() is None
    assert capsys.readouterr().err == ""  # once per process, by both modules


def test_a_folder_of_another_user_is_not_used(tmp_path: Path, monkeypatch, capsys) -> None:
    if ROOT:
        folder = private(tmp_path / "cache")
        os.chown(folder, NOBODY, NOBODY)
        owner = NOBODY
    else:  # a folder of root's that this user cannot change
        folder = Path("/usr/share")
        owner = 0
    monkeypatch.setenv("PARMOR_CACHE", str(folder))
    assert cache_folder() is None and gaits.base.cache_folder() is None
    err = capsys.readouterr().err
    assert f"not using the cache folder {folder}" in err
    assert f"belongs to another user (uid {owner})" in err and err.count("\n") == 1


@pytest.mark.parametrize("case", sorted(CACHES))
def test_a_file_that_is_not_the_users_own_is_not_unpickled(
    case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = private(tmp_path / "cache")
    monkeypatch.setenv("PARMOR_CACHE", str(folder))
    path, marker = plant(folder, case, tmp_path)
    os.chmod(path, 0o666)  # others may write it: anyone could have
    CACHES[case][1](folder)
    assert not marker.exists()
    if ROOT:  # a file of another user's (only root can make one here)
        path, marker = plant(folder, case, tmp_path)
        os.chown(path, NOBODY, NOBODY)
        CACHES[case][1](folder)
        assert not marker.exists()
    # a symbolic link to a file elsewhere is not followed either
    elsewhere = tmp_path / "elsewhere"
    path.unlink(missing_ok=True)
    _, marker = plant(folder, case, tmp_path)
    os.replace(path, elsewhere)
    path.symlink_to(elsewhere)
    CACHES[case][1](folder)
    assert not marker.exists()


def test_read_cache_bytes(tmp_path: Path) -> None:
    f = tmp_path / "f"
    f.write_bytes(b"x")
    os.chmod(f, 0o600)
    assert read_cache_bytes(f) == b"x"
    os.chmod(f, 0o644)
    assert read_cache_bytes(f) == b"x"  # others may read it: that is not a risk
    os.chmod(f, 0o620)
    assert read_cache_bytes(f) is None
    assert read_cache_bytes(tmp_path / "absent") is None
    assert read_cache_bytes(tmp_path) is None  # a folder
    os.mkfifo(tmp_path / "fifo")
    assert read_cache_bytes(tmp_path / "fifo") is None  # at once, not blocked


def test_a_folder_made_by_parmor_is_private(tmp_path: Path, monkeypatch) -> None:
    old = os.umask(0o002)  # a umask that leaves folders group-writable
    try:
        folder = tmp_path / "a" / "cache"
        monkeypatch.setenv("PARMOR_CACHE", str(folder))
        kb_module.load()
        assert os.stat(folder).st_mode & 0o777 == 0o700
        assert any(folder.glob("kb-*.pickle"))
        assert cache_folder() == folder  # still usable: the next process reads it
        gfolder = tmp_path / "b" / "cache"
        gaits.base.cache_write(gfolder / "x.npy", lambda f: f.write(b"x"), "x")
        assert os.stat(gfolder).st_mode & 0o777 == 0o700
    finally:
        os.umask(old)


def test_a_safe_folder_is_used_and_absent_one_is_made(tmp_path: Path, monkeypatch, capsys) -> None:
    folder = private(tmp_path / "cache")
    os.chmod(folder, 0o755)  # others may read and enter: no risk
    monkeypatch.setenv("PARMOR_CACHE", str(folder))
    assert cache_folder() == folder == gaits.base.cache_folder()
    monkeypatch.setenv("PARMOR_CACHE", str(tmp_path / "absent"))
    assert cache_folder() == tmp_path / "absent"
    assert capsys.readouterr().err == ""


def test_gaits_and_adron_judge_folders_alike(tmp_path: Path) -> None:
    folder = private(tmp_path / "cache")
    for mode in (0o700, 0o755, 0o775, 0o757, 0o777, 0o1777, 0o720):
        os.chmod(folder, mode)
        assert unsafe_cache_folder(folder) == gaits.base.unsafe_cache_folder(folder)
        assert (unsafe_cache_folder(folder) is None) == (mode & 0o022 == 0)


def test_a_catalog_cache_read_refuses_a_foreign_file(tmp_path: Path) -> None:
    path = tmp_path / "catalog-x.pickle"
    from adron import catalog

    path.write_bytes(catalog._CATALOG_CACHE + pickle.dumps(load_catalog()))
    os.chmod(path, 0o600)
    assert _cached_catalog(path) == load_catalog()
    os.chmod(path, 0o660)
    assert _cached_catalog(path) is None
