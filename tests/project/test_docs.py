"""The documentation cannot drift: every ``parmor`` command it shows is run here.

Pages: README.md and docs/*.md. A fenced block whose info string is

- ``console`` is run. Each line ``$ COMMAND`` is a shell command; the lines under it, up
  to the next ``$ ``, are what it prints (standard output and standard error as a
  terminal interleaves them), compared with what it prints now: text exactly once
  whitespace is normalised (runs of blanks as one, line ends stripped, blank lines
  dropped), numbers within 5 % of each other or one unit of the shown number's last
  decimal, whichever is looser (a whole number: 5 % only, so "passed 8 of 8" is exact).
  A line ``...`` stands for any lines (none included), ``...`` inside a line for any text.
  A question answered in the block (``Does the robot need to grasp? [y/n] y``) is answered
  on a terminal (a pseudo-terminal on standard input), as a person would.
- ``console-elided`` is run; its output is not compared ("output elided"), only each
  command's exit code.
- ``console-norun`` is not run; each ``parmor`` command in it (``$ parmor ...``, also
  ``head$ parmor ...``) is still parsed by parmor's parser, so a renamed or removed option
  fails here all the same.

Exit codes: a command must exit 0, unless the output shown has a line ``parmor: error``,
``parmor: cannot ...``, ``parmor: no robot ...`` or ``parmor: an answer ...`` (then it must
not), or the next command is ``echo $?`` (whose shown output is the code).

A page's blocks run in order in one temporary folder, into which ``docs/examples/`` is
copied first: a later block uses the bundle an earlier one wrote, and ``cat FILE`` shows an
example file as it is. parmor runs as installed (the ``parmor`` beside this Python) on this
checkout's sources, with the environment's ``PARMOR_*`` variables removed (the pages show
the defaults; ``PARMOR_CACHE`` is kept).

What is not run (``console-norun``), and why:

- ROS (``parmor ros`` and the ``rosservice`` session): needs a ROS master
  (``tests/program/test_ros.py`` runs it);
- ``parmor blocks --serve``: a server and a browser (``tests/program/test_blocks.py``);
- Ray (``--backend ray``, ``ray start``): a cluster (``tests/synth/commands/test_ray.py``);
- whole studies (``parmor sweep studies/...``) and the bench scripts: minutes to hours;
- the recorded transcripts of designs that take more than ~10 s each to verify under
  perturbation (the humanoid, legged and mobile-manipulator refusals, the DYNAMIXEL arm,
  results.md): the measured results they show are re-measured by the bench scripts that
  results.md names, not by the test suite.

Cost: the pages show cheap commands where the point allows (``--conceptual``,
``--no-verify``, ``--robustness 0``, ``abilities``, ``explain``, ``ontology check``); the full
robust verification is shown on the 3-joint arm and the cart, which take a few seconds.
"""

from __future__ import annotations

import difflib
import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.conftest import need

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
RUN, ELIDED, NORUN = "console", "console-elided", "console-norun"
KINDS = (RUN, ELIDED, NORUN)
#: A parmor command anywhere in a block: ``$ parmor``, ``head$   parmor``.
PARMOR_LINE = re.compile(r"^\S*\$\s+parmor\b")
REFUSAL = re.compile(r"^parmor: (error|cannot|no robot|an answer)")
QUESTION = re.compile(r"^(.*\[y/n\]) (y|n|yes|no)$")
NUMBER = r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"
#: A number standing alone (not part of a name such as MG996R, x0.9 or 0x0c).
FREE_NUMBER = re.compile(rf"(?<![\w.]){NUMBER}(?![\w])")
REL_TOL = 0.05


@dataclass
class Command:
    text: str
    shown: list[str] = field(default_factory=list)


@dataclass
class Block:
    page: Path
    line: int
    kind: str
    lines: list[str]

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    def commands(self) -> list[Command]:
        cmds: list[Command] = []
        for line in self.lines:
            if line.startswith("$ "):
                cmds.append(Command(line[2:]))
            elif cmds:
                cmds[-1].shown.append(line)
            elif line.strip():
                raise AssertionError(f"{self.where}: output before the first '$ ' command")
        return cmds


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of ``page`` (top-level fences of three backticks)."""
    out: list[Block] = []
    lines = page.read_text().splitlines()
    i = 0
    while i < len(lines):
        m = re.match(r"^```(\S*)\s*$", lines[i])
        if m:
            j = i + 1
            while j < len(lines) and lines[j].rstrip() != "```":
                j += 1
            out.append(Block(page, i + 1, m.group(1), lines[i + 1 : j]))
            i = j
        i += 1
    return out


# ----------------------------------------------------------------------- comparing


def _norm(lines: list[str]) -> list[str]:
    return [" ".join(s.split()) for s in lines if s.strip()]


def _close(shown: str, got: str) -> bool:
    a, b = float(shown), float(got)
    tol = REL_TOL * max(abs(a), abs(b))
    mantissa = re.split(r"[eE]", shown)[0]
    if "." in mantissa and not re.search(r"[eE]", shown):
        tol = max(tol, 10.0 ** -len(mantissa.split(".")[1]) * 1.0001)
    return abs(a - b) <= tol


def line_matches(shown: str, got: str) -> bool:
    """``got`` is ``shown``: the same text, numbers within tolerance, ``...`` any text."""
    if shown == got:
        return True
    pattern, numbers = [], []
    for k, piece in enumerate(shown.split("...")):
        if k:
            pattern.append(".*?")
        pos = 0
        for m in FREE_NUMBER.finditer(piece):
            pattern.append(re.escape(piece[pos : m.start()]))
            pattern.append(f"({NUMBER})")
            numbers.append(m.group())
            pos = m.end()
        pattern.append(re.escape(piece[pos:]))
    m = re.fullmatch("".join(pattern), got)
    return bool(m) and all(_close(s, g) for s, g in zip(numbers, m.groups(), strict=True))


def output_matches(shown: list[str], got: list[str]) -> bool:
    """Line by line, a shown ``...`` line standing for any lines."""
    memo: dict[tuple[int, int], bool] = {}

    def match(i: int, j: int) -> bool:
        if (i, j) not in memo:
            if i == len(shown):
                ok = j == len(got)
            elif shown[i] == "...":
                ok = match(i + 1, j) or (j < len(got) and match(i, j + 1))
            else:
                ok = j < len(got) and line_matches(shown[i], got[j]) and match(i + 1, j + 1)
            memo[i, j] = ok
        return memo[i, j]

    return match(0, 0)


# ------------------------------------------------------------------------- running


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PARMOR_")}
    if "PARMOR_CACHE" in os.environ:
        env["PARMOR_CACHE"] = os.environ["PARMOR_CACHE"]
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    env["PYTHONUNBUFFERED"] = "1"  # stdout and stderr interleaved as on a terminal
    env["COLUMNS"] = "100"
    return env


def run_block(block: Block, folder: Path) -> list[str]:
    """Run ``block`` in ``folder``; the problems found (none: it is as shown)."""
    cmds = block.commands()
    answers = [m.group(2) for c in cmds for s in c.shown if (m := QUESTION.match(s.strip()))]
    script = []
    for i, c in enumerate(cmds):
        script.append(f"printf '\\n@@CMD {i}\\n'; (exit ${{__rc:-0}})")  # $? as it was
        script.append(c.text)
        script.append(f"__rc=$?; printf '\\n@@RC {i} %s\\n' $__rc")
    stdin, master = subprocess.DEVNULL, None
    if answers:
        master, slave = os.openpty()
        os.write(master, "".join(f"{a}\n" for a in answers).encode())
        stdin = slave
    try:
        proc = subprocess.run(
            ["bash", "-c", "\n".join(script)],
            cwd=folder,
            stdin=stdin,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            env=_env(),
            text=True,
            timeout=900,
        )
    finally:
        if master is not None:
            os.close(stdin)
            os.close(master)
    text = proc.stdout
    for a in answers:  # the terminal would have echoed the answer after its question
        text = text.replace("[y/n] ", f"[y/n]\x00 {a}\n", 1)
    text = text.replace("[y/n]\x00", "[y/n]")
    outputs: dict[int, list[str]] = {}
    codes: dict[int, int] = {}
    current: int | None = None
    for line in text.splitlines():
        if m := re.fullmatch(r"@@CMD (\d+)", line):
            current = int(m.group(1))
            outputs[current] = []
        elif m := re.fullmatch(r"@@RC (\d+) (\d+)", line):
            codes[int(m.group(1))] = int(m.group(2))
            current = None
        elif current is not None:
            outputs[current].append(line)
    problems = []
    for i, c in enumerate(cmds):
        got = outputs.get(i, [])
        shown = _norm(c.shown)
        if i not in codes:
            problems.append(f"$ {c.text}\n  did not finish (exit status missing)")
            continue
        follows_echo = i + 1 < len(cmds) and cmds[i + 1].text.strip() == "echo $?"
        refusal = any(REFUSAL.match(s) for s in shown)
        if not follows_echo and (codes[i] != 0) != refusal:
            want = "non-zero" if refusal else "0"
            problems.append(
                f"$ {c.text}\n  exited {codes[i]}, the page implies {want}:\n"
                + "\n".join(got[-15:])
            )
        if block.kind == RUN and not output_matches(shown, _norm(got)):
            diff = difflib.unified_diff(shown, _norm(got), "shown", "printed now", lineterm="")
            problems.append(f"$ {c.text}\n" + "\n".join(diff))
    return problems


def _page_id(page: Path) -> str:
    return str(page.relative_to(ROOT))


@pytest.mark.parametrize("page", PAGES, ids=_page_id)
def test_page_commands_print_what_the_page_shows(page: Path, tmp_path: Path) -> None:
    runnable = [b for b in blocks(page) if b.kind in (RUN, ELIDED)]
    if not runnable:
        return
    examples = DOCS / "examples"
    if examples.is_dir():
        shutil.copytree(examples, tmp_path, dirs_exist_ok=True)
    problems, took = [], []
    for b in runnable:
        start = time.monotonic()
        problems += [f"{b.where}:\n{p}" for p in run_block(b, tmp_path)]
        took.append(f"{b.where} {time.monotonic() - start:.1f} s")
    print("\n".join(took))
    assert not problems, "\n\n".join(problems)


def test_every_parmor_command_is_in_a_console_block() -> None:
    """A parmor command shown in any other block would be neither run nor parsed."""
    stray = [
        f"{b.where}: ```{b.kind} holds {line.strip()!r}"
        for page in PAGES
        for b in blocks(page)
        if b.kind not in KINDS
        for line in b.lines
        if PARMOR_LINE.match(line)
    ]
    assert not stray, "use console, console-elided or console-norun:\n" + "\n".join(stray)


def test_commands_not_run_still_parse() -> None:
    from synth.commands.cli import build_parser

    bad = []
    for page in PAGES:
        for b in blocks(page):
            if b.kind != NORUN:
                continue
            for line in b.lines:
                if not PARMOR_LINE.match(line):
                    continue
                argv = shlex.split(line.split("$", 1)[1], comments=True)[1:]
                argv = argv[: argv.index("&")] if "&" in argv else argv
                try:
                    build_parser().parse_args(argv)
                except SystemExit as e:
                    bad.append(f"{b.where}: {line.strip()} (exit {e.code})")
    assert not bad, "\n".join(bad)


def test_the_fence_kinds_are_known() -> None:
    """A misspelt kind (``consle``) would silently leave a block unchecked."""
    odd = [
        f"{b.where}: ```{b.kind}"
        for page in PAGES
        for b in blocks(page)
        if b.kind.startswith("console") and b.kind not in KINDS
    ]
    assert not odd, "\n".join(odd)


# --------------------------------------------------------------- the CLI reference


def _gen_cli():
    spec = importlib.util.spec_from_file_location("gen_cli", DOCS / "gen_cli.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_cli_reference_is_what_the_parser_gives() -> None:
    gen = _gen_cli()
    assert (DOCS / "cli.md").read_text() == gen.render(), (
        "docs/cli.md is not current: run python docs/gen_cli.py"
    )


def test_cli_reference_is_what_help_prints() -> None:
    gen = _gen_cli()
    page = (DOCS / "cli.md").read_text()
    env = _env()
    env["COLUMNS"] = gen.COLUMNS
    for words, _ in gen.commands():
        argv = words.split()[1:]
        got = subprocess.run(
            ["parmor", *argv, "--help"], capture_output=True, text=True, env=env, check=True
        ).stdout
        block = re.search(rf"^## {re.escape(words)}\n\n```text\n(.*?)\n```$", page, re.S | re.M)
        assert block, f"docs/cli.md has no section for {words}"
        assert block.group(1) == got.rstrip(), f"{words} --help differs from docs/cli.md"


# ------------------------------------------------------------------------ the site


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    """The site builds with ``--strict``: a broken link, a missing anchor or a page left
    out of the nav fails (mkdocs.yml's ``validation`` makes those warnings)."""
    need(importlib.util.find_spec("mkdocs") is not None, "mkdocs is not installed")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert (tmp_path / "index.html").is_file()
