"""A suite's or study's files stay in its folder, and an input that is not a regular file (a
named pipe, a device) is refused at once instead of waited on (issue 23, item 9)."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from adron.errors import InputError
from synth.commands.regress import kb_options

QUERY = '[[query]]\nname = "q"\nabilities = ["walking"]\n'
REQUEST = '[[request]]\nabilities = ["rolling"]\n'


def secret(tmp_path: Path) -> Path:
    """A file outside the suite's folder whose text must never be read or shown."""
    path = tmp_path / "outside.kif"
    path.write_text("(secret_line_of_text)\n", encoding="utf-8")
    return path


ESCAPES = {
    "dot-dot": lambda tmp: "../outside.kif",
    "dot-dot below a subfolder": lambda tmp: "sub/../../outside.kif",
    "absolute path elsewhere": lambda tmp: str(tmp / "outside.kif"),
    "system file": lambda tmp: "../../../../../../../../etc/passwd",
    "symbolic link pointing out": lambda tmp: "link.kif",
}


def suite_folder(tmp_path: Path) -> Path:
    secret(tmp_path)
    folder = tmp_path / "suite"
    (folder / "sub").mkdir(parents=True)
    (folder / "link.kif").symlink_to(tmp_path / "outside.kif")
    return folder


@pytest.mark.parametrize("key", ["ontology", "rules", "catalog"])
@pytest.mark.parametrize("case", sorted(ESCAPES))
def test_a_path_out_of_the_suite_folder_is_refused(
    cli, tmp_path: Path, case: str, key: str
) -> None:
    folder = suite_folder(tmp_path)
    given = ESCAPES[case](tmp_path)
    value = f'"{given}"' if key == "catalog" else f'["{given}"]'
    for command, name, tables in (("regress", "s.toml", QUERY), ("sweep", "t.toml", REQUEST)):
        path = folder / name
        path.write_text(f"{key} = {value}\n{tables}", encoding="utf-8")
        r = cli(command, str(path))
        assert r.code == 2, (command, r.err)
        assert f"{path}: {key}: {given!r} is outside the folder of {name}" in r.err
        assert "secret" not in r.err and "root:" not in r.err and "Traceback" not in r.err
        assert sorted(p.name for p in folder.iterdir()) == sorted(["link.kif", name, "sub"])
        path.unlink()


def test_paths_inside_the_folder_are_kept(tmp_path: Path) -> None:
    folder = suite_folder(tmp_path)
    path = folder / "s.toml"
    inside = folder / "sub" / "x.kif"
    data = {
        "ontology": ["sub/x.kif", "sub/../sub/x.kif", str(inside), "./a.kif"],
        "rules": ["sub/r.lp", "not-there-yet.lp"],
        "catalog": "sub/c.toml",
    }
    opts = kb_options(data, path)
    assert opts["ontology"] == [
        str(folder / "sub/x.kif"),
        str(folder / "sub/../sub/x.kif"),
        str(inside),
        str(folder / "a.kif"),
    ]
    assert opts["rules"] == [str(folder / "sub/r.lp"), str(folder / "not-there-yet.lp")]
    assert opts["catalog"] == str(folder / "sub/c.toml")
    assert kb_options({"catalog": "dynamixel"}, path)["catalog"] == "dynamixel"  # shipped
    # a suite in the working folder, named without a folder
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        assert kb_options({"ontology": ["sub/x.kif"]}, Path("s.toml"))["ontology"] == ["sub/x.kif"]
        with pytest.raises(InputError, match="ontology: '../outside.kif' is outside"):
            kb_options({"ontology": ["../outside.kif"]}, Path("s.toml"))
    finally:
        os.chdir(cwd)


# --- inputs that are not regular files ------------------------------------------------------


def fifo(tmp_path: Path, name: str = "pipe.toml") -> Path:
    path = tmp_path / name
    os.mkfifo(path)
    return path


def never_written(path: Path) -> threading.Timer:
    """A guard for a test that regresses: open the pipe for writing after 60 s, so that a
    reader that blocked on it fails the test instead of hanging the suite."""

    def unblock() -> None:
        with open(path, "w", encoding="utf-8") as f:
            f.write("x")

    timer = threading.Timer(60.0, unblock)
    timer.daemon = True
    timer.start()
    return timer


DESIGN = ["design", "walking", "--conceptual", "--no-input"]


@pytest.mark.parametrize("option", ["--catalog", "--ontology", "--rules"])
def test_a_fifo_given_as_an_input_is_refused_at_once(cli, tmp_path: Path, option: str) -> None:
    pipe = fifo(tmp_path)
    timer = never_written(pipe)
    try:
        r = cli(*DESIGN, option, str(pipe))
    finally:
        timer.cancel()
    assert r.code == 2, r.err
    assert r.err == (
        f"parmor: error: {pipe}: is a named pipe (FIFO), not a file; parmor reads input "
        "files whole, so give the path of a regular file\n"
    )


@pytest.mark.parametrize("command", ["regress", "sweep"])
def test_a_fifo_as_a_suite_or_in_one_is_refused(cli, tmp_path: Path, command: str) -> None:
    pipe = fifo(tmp_path)
    timer = never_written(pipe)
    try:
        r = cli(command, str(pipe))
        assert r.code == 2 and f"{pipe}: is a named pipe (FIFO)" in r.err, r.err
        suite = tmp_path / "s.toml"
        tables = QUERY if command == "regress" else REQUEST
        for key in ("ontology", "rules"):
            suite.write_text(f'{key} = ["pipe.toml"]\n{tables}', encoding="utf-8")
            r = cli(command, str(suite))
            assert r.code == 2 and f"{pipe}: is a named pipe (FIFO)" in r.err, r.err
        suite.write_text(f'catalog = "pipe.toml"\n{tables}', encoding="utf-8")
        r = cli(command, str(suite))
        assert r.code == 2 and f"{pipe}: is a named pipe (FIFO)" in r.err, r.err
    finally:
        timer.cancel()


def test_a_fifo_snapshot_is_refused(cli, tmp_path: Path) -> None:
    suite = tmp_path / "s.toml"
    suite.write_text("conceptual = true\n" + QUERY.replace('"walking"', '"rolling"'))
    pipe = fifo(tmp_path, "s.snapshot.json")
    timer = never_written(pipe)
    try:
        r = cli("regress", str(suite))
    finally:
        timer.cancel()
    assert r.code == 2 and f"{pipe}: is a named pipe (FIFO)" in r.err, r.err


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/null"])
def test_a_device_is_refused(cli, device: str) -> None:
    r = cli(*DESIGN, "--catalog", device)
    assert r.code == 2 and f"{device}: is a character device, not a file" in r.err
    r = cli(*DESIGN, "--ontology", device)
    assert r.code == 2 and f"{device}: is a character device, not a file" in r.err


def test_regular_files_folders_and_missing_files_keep_their_messages(cli, tmp_path: Path) -> None:
    r = cli(*DESIGN, "--ontology", str(tmp_path / "none.kif"))
    assert r.code == 2 and "none.kif: no such file" in r.err
    r = cli(*DESIGN, "--catalog", str(tmp_path))
    assert r.code == 2 and "is a folder" in r.err
    link = tmp_path / "link.kif"
    link.symlink_to(fifo(tmp_path, "p.kif"))  # a link to a pipe is a pipe
    r = cli(*DESIGN, "--ontology", str(link))
    assert r.code == 2 and f"{link}: is a named pipe (FIFO)" in r.err
    mine = tmp_path / "mine.kif"
    mine.write_text("(subclass MyThing Robot)\n", encoding="utf-8")
    r = cli(*DESIGN, "--ontology", str(mine), "--answer", "grasping=no")
    assert r.code in (0, 3), r.err
