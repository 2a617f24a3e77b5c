"""Every way a command ends, run many times at varied moments (issue 23): done, refusal,
bad input, Ctrl-C, time limit, memory limit, closed or full output. Each run must end
with a documented exit code (0, 1, 2, 3, 130), not a signal death, not a hang (allowed:
what the path takes plus ``SLACK_S``), with no traceback on standard error; an `--out`
run that does not end with 0 leaves nothing behind.

Ctrl-C is sent as a terminal sends it, to the command's whole process group (the
reasoner's worker too). No timing thresholds: the moments only spread the signals over
the stages (parse, the imports while the worker grounds, grounding, sizing, writing).

The suite runs each case once (``PARMOR_EXIT_RUNS`` more); as a measurement,
``python tests/synth/commands/test_exit_paths.py N`` runs the battery N times and prints the counts.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
DOCUMENTED = {0, 1, 2, 3, 130}
#: repetitions of each case in the suite (a measurement passes more)
RUNS = max(1, int(os.environ.get("PARMOR_EXIT_RUNS", "1")))
#: beyond what a path takes, s, before a run counts as hung (a loaded 2-core machine)
SLACK_S = 40.0
#: the ground probe's budget after a time or memory limit (synth/reasoning/ground_probe.py)
PROBE_S = 3.0
#: grounds for minutes and to gigabytes
BLOW_UP = "p(X) :- X = 1..100000000.\n"
DESIGN = [
    "design",
    "walking",
    "--answer",
    "grasping=no",
    "--answer",
    "rough-terrain-walking=no",
    "--no-input",
]
#: what a traceback, or a dying interpreter, leaves on standard error
BROKEN = ("Traceback", "Exception ignored", "Fatal Python error", "Segmentation fault")


@dataclass
class Case:
    """One run: ``argv`` of parmor in a folder of its own holding ``explode.lp``;
    ``sigint_at``: Ctrl-C this many seconds after the start; ``stdout``: 'null',
    'closed' (``>&-``) or 'full' (``>/dev/full``); ``codes``: what it may end with;
    ``says``: what standard error must hold for each code; ``bundle``: the --out folder's
    name; ``takes``: s the path takes at most on an idle machine (the hang allowance is
    on top)."""

    name: str
    argv: list[str]
    codes: set[int]
    says: dict[int, str] = field(default_factory=dict)
    sigint_at: float | None = None
    stdout: str = "null"
    bundle: str | None = None
    takes: float = 10.0


@dataclass
class Ended:
    case: Case
    code: int | None  # None: hung (killed)
    err: str
    seconds: float
    left: list[str]  # what the run's folder holds beyond its input

    def problems(self) -> list[str]:
        c, found = self.case, []
        if self.code is None:
            found.append(f"hung (killed after {self.seconds:.1f} s)")
        elif self.code < 0:
            found.append(f"died of signal {-self.code}")
        elif self.code not in DOCUMENTED:
            found.append(f"undocumented exit code {self.code}")
        elif self.code not in c.codes:
            found.append(f"exit code {self.code}, expected one of {sorted(c.codes)}")
        elif c.says.get(self.code, "") not in self.err:
            found.append(f"standard error lacks {c.says[self.code]!r}")
        if any(b in self.err for b in BROKEN):
            found.append("a traceback on standard error")
        if c.bundle is not None and self.code is not None:
            want = [c.bundle] if self.code == 0 else []
            if self.left != want:
                found.append(f"left {self.left} (expected {want})")
        return found

    def describe(self) -> str:
        c = self.case
        at = "" if c.sigint_at is None else f" (Ctrl-C at {c.sigint_at:.2f} s)"
        lines = self.err.strip().splitlines()
        tail = " | ".join(lines if self.code is None else lines[-6:])
        return f"{c.name}{at}: {'; '.join(self.problems())}; stderr: {tail}"


def _command(case: Case) -> list[str]:
    cmd = [sys.executable, "-m", "synth.commands.cli", *case.argv]
    if case.stdout == "closed":  # the shell's >&-: the command starts with no fd 1
        return ["/bin/sh", "-c", 'exec "$0" "$@" >&-', *cmd]
    return cmd


def run_case(case: Case, root: Path) -> Ended:
    """Run ``case`` in a new folder below ``root``; what it ended with."""
    here = root / f"{case.name}-{time.monotonic_ns()}"
    here.mkdir()
    (here / "explode.lp").write_text(BLOW_UP, encoding="utf-8")
    # a hang is ended with SIGABRT first: faulthandler prints where each process was
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONFAULTHANDLER": "1"}
    env.pop("CI", None)  # the command's behaviour does not depend on it
    sink = open("/dev/full" if case.stdout == "full" else os.devnull, "wb")  # noqa: SIM115
    start = time.monotonic()
    with sink:
        p = subprocess.Popen(
            _command(case),
            cwd=here,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=sink,
            stderr=subprocess.PIPE,
            start_new_session=True,  # its own process group: Ctrl-C goes to all of it
        )
    limit = case.takes + SLACK_S
    try:
        if case.sigint_at is not None:
            try:
                p.wait(timeout=case.sigint_at)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGINT)
            limit = case.sigint_at + SLACK_S
        _, err = p.communicate(timeout=max(limit - (time.monotonic() - start), 1.0))
        code: int | None = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGABRT)
        try:
            _, err = p.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            _, err = p.communicate()
        code = None
    seconds = time.monotonic() - start
    left = sorted(x.name for x in here.iterdir() if x.name != "explode.lp")
    return Ended(case, code, err.decode(errors="replace"), seconds, left)


def run_all(cases: Sequence[Case], root: Path, parallel: int = 2) -> list[Ended]:
    """Every case, ``parallel`` at a time (the moments shift under load: no matter)."""
    with ThreadPoolExecutor(parallel) as pool:
        return list(pool.map(lambda c: run_case(c, root), cases))


def assert_clean(ended: list[Ended]) -> None:
    bad = [e.describe() for e in ended if e.problems()]
    assert not bad, f"{len(bad)} of {len(ended)} runs went wrong:\n" + "\n".join(bad)


def spread(lo: float, hi: float, n: int) -> list[float]:
    """``n`` moments from ``lo`` to ``hi``."""
    return [lo + (hi - lo) * i / max(n - 1, 1) for i in range(n)]


# --- the cases ------------------------------------------------------------------------------


def ctrl_c_cases(runs: int) -> list[Case]:
    """Ctrl-C into a full design --out grounding a huge rule file (0.5-1.8 s: start-up,
    the imports done while the worker grounds, grounding), and into a full design --out
    that ends (sizing, simulating, writing the bundle), which may also end first."""
    blow = [
        Case(
            "ctrl-c-grounding",
            [*DESIGN, "--rules", "explode.lp", "--out", "bundle"],
            {130},
            {130: "parmor: interrupted"},
            sigint_at=t,
            bundle="bundle",
        )
        for t in spread(0.5, 1.8, 5 * runs)
    ]
    full = [
        Case(
            "ctrl-c-design",
            [*DESIGN, "--out", "bundle"],
            {0, 130},
            {130: "parmor: interrupted"},
            sigint_at=t,
            bundle="bundle",
        )
        for t in spread(0.8, 4.0, 4 * runs)
    ]
    return blow + full


def time_limit_cases(runs: int) -> list[Case]:
    """The time limit while a huge rule file grounds (0.9-1.1 s), and at any stage of a
    full design --out (1-3 s: it may end first)."""
    blow = [
        Case(
            "time-limit",
            [*DESIGN, "--rules", "explode.lp", "--time-limit", f"{t:.2f}", "--out", "bundle"],
            {1},
            {1: "time limit"},
            bundle="bundle",
            takes=t + PROBE_S + 2.0,
        )
        for t in spread(0.9, 1.1, 3 * runs)
    ]
    full = [
        Case(
            "time-limit-design",
            [*DESIGN, "--time-limit", f"{t:.2f}", "--out", "bundle"],
            {0, 1},
            {1: "time limit"},
            bundle="bundle",
            takes=t + PROBE_S + 2.0,
        )
        for t in spread(1.0, 3.0, 2 * runs)
    ]
    return blow + full


def refusal_cases(runs: int) -> list[Case]:
    """Requests refused early, while the imports a bundle needs would still be going on."""
    quick = ["--no-verify", "--out", "bundle", "--json"]
    cases = [
        Case(
            "answer-needed",
            ["design", "walking", "--no-input", *quick],
            {3},
            {3: "an answer is needed"},
            bundle="bundle",
        ),
        Case(
            "unsatisfiable",
            ["design", "driving", "grasping", "--no-input", *quick],
            {1},
            {1: "no robot can meet"},
            bundle="bundle",
        ),
        Case(
            "infeasible",
            [*DESIGN, "--param", "speed=1m/s", *quick],
            {1},
            {1: "cannot build it"},
            bundle="bundle",
        ),
        Case(
            "bad-input",
            [*DESIGN, "--param", "payload=100kg", *quick],
            {2},
            {2: "parmor: error: --param payload=100kg"},
            bundle="bundle",
        ),
        Case(
            "bad-rules",
            [*DESIGN, "--rules", "missing.lp", *quick],
            {2},
            {2: "missing.lp"},
            bundle="bundle",
        ),
        Case(
            "done",
            [*DESIGN, *quick],
            {0},
            bundle="bundle",
        ),
    ]
    return cases * runs


def output_cases(runs: int) -> list[Case]:
    """Standard output closed (``>&-``) or full (``>/dev/full``)."""
    cannot = {2: "parmor: error: cannot write the output: "}
    cases = []
    for how in ("closed", "full"):
        cases += [
            Case(f"abilities-{how}", ["abilities"], {2}, cannot, stdout=how),
            Case(f"help-{how}", ["--help"], {2}, cannot, stdout=how),
            Case(f"design-{how}", [*DESIGN, "--no-verify", "--json"], {2}, cannot, stdout=how),
        ]
    return cases * runs


def memory_limit_cases(runs: int) -> list[Case]:
    return [
        Case(
            "memory-limit",
            [*DESIGN, "--rules", "explode.lp", "--memory-limit", "300", "--out", "bundle"],
            {1},
            {1: "memory limit"},
            bundle="bundle",
            takes=PROBE_S + 10.0,
        )
    ] * runs


BATTERY: dict[str, Callable[[int], list[Case]]] = {
    "ctrl-c": ctrl_c_cases,
    "time limit": time_limit_cases,
    "refusals": refusal_cases,
    "output": output_cases,
    "memory limit": memory_limit_cases,
}


# --- the tests ------------------------------------------------------------------------------


def test_ctrl_c_at_any_moment_exits_130_and_leaves_nothing(tmp_path: Path) -> None:
    assert_clean(run_all(ctrl_c_cases(RUNS), tmp_path))


def test_time_limit_while_grounding_exits_1(tmp_path: Path) -> None:
    assert_clean(run_all(time_limit_cases(RUNS), tmp_path))


def test_memory_limit_while_grounding_exits_1(tmp_path: Path) -> None:
    assert_clean(run_all(memory_limit_cases(RUNS), tmp_path))


def test_early_refusals_and_done_exit_with_their_codes(tmp_path: Path) -> None:
    assert_clean(run_all(refusal_cases(RUNS), tmp_path))


def test_closed_or_full_output_exits_2(tmp_path: Path) -> None:
    assert_clean(run_all(output_cases(RUNS), tmp_path))


def test_prefetch_imports_on_the_calling_thread(tmp_path: Path, monkeypatch) -> None:
    """The imports done while the worker grounds run on the caller's thread (a thread
    left importing deadlocked a later fork and crashed the exit): done when it returns,
    no thread started; a module that fails is left to where it is used; the idle
    imports stop once the worker has replied."""
    import threading

    from synth.commands import cli

    for name, body in {
        "parmor_t_ok": "DONE = True\n",
        "parmor_t_broken": "raise RuntimeError('broken')\n",
        "parmor_t_idle": "DONE = True\n",
    }.items():
        (tmp_path / f"{name}.py").write_text(body, encoding="utf-8")
        monkeypatch.delitem(sys.modules, name, raising=False)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(cli, "IDLE_MODULES", ("parmor_t_idle",))
    threads = threading.active_count()
    cli._prefetch(["parmor_t_broken", "parmor_t_ok"], ready=lambda: True)
    assert sys.modules["parmor_t_ok"].DONE and threading.active_count() == threads
    assert "parmor_t_broken" not in sys.modules and "parmor_t_idle" not in sys.modules
    cli._prefetch([], ready=lambda: False)
    assert sys.modules["parmor_t_idle"].DONE


class Rang(Exception):
    pass


def _rang(signum: int, frame: object) -> None:
    raise Rang


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGALRM])
def test_ctrl_c_and_the_alarm_wait_for_the_outermost_import(
    tmp_path: Path, monkeypatch, sig: int
) -> None:
    """Run as the program, Ctrl-C or the time limit's alarm during an import acts once
    the outermost import is done (inside an extension's initialisation the exception was
    lost, became an ImportError, or ended the interpreter by signal 2), and at once
    outside an import."""
    import builtins

    from synth.commands import cli

    (tmp_path / "parmor_t_outer.py").write_text(
        "import parmor_t_inner\nDONE = True\n", encoding="utf-8"
    )
    (tmp_path / "parmor_t_inner.py").write_text(
        f"import os\nos.kill(os.getpid(), {int(sig)})\nfor _ in range(10**5): pass\nDONE = True\n",
        encoding="utf-8",
    )
    for m in ("parmor_t_outer", "parmor_t_inner"):
        monkeypatch.delitem(sys.modules, m, raising=False)
    monkeypatch.syspath_prepend(str(tmp_path))
    expected = KeyboardInterrupt if sig == signal.SIGINT else Rang
    alarm = signal.signal(signal.SIGALRM, _rang)
    wait = cli._SignalsWait()
    try:
        wait.hold_alarm(lambda: None)
        with pytest.raises(expected):
            import parmor_t_outer  # noqa: F401
        assert sys.modules["parmor_t_outer"].DONE and sys.modules["parmor_t_inner"].DONE
        with pytest.raises(expected):
            os.kill(os.getpid(), sig)
            for _ in range(10**6):
                pass
    finally:
        wait.remove()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGALRM, alarm)
    assert builtins.__import__ != wait.importing


def test_a_ctrl_c_lost_in_a_finalizer_is_raised_again(capsys) -> None:
    """Python reports a KeyboardInterrupt raised inside ``__del__`` as unraisable and
    drops it (clingo's AST objects are collected at any moment): run as the program, it
    is raised again after the finalizer (by the alarm, 20 ms later), not printed."""
    from synth.commands import cli

    class Collected:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(10**5):  # the handler runs in here
                pass

    alarm = signal.signal(signal.SIGALRM, _rang)
    wait = cli._SignalsWait()
    try:
        wait.hold_alarm(lambda: None)
        with pytest.raises(KeyboardInterrupt):
            x = Collected()
            del x
            time.sleep(5)  # the alarm interrupts it 20 ms after
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        wait.remove()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGALRM, alarm)
    assert "Exception ignored" not in capsys.readouterr().err
    assert sys.unraisablehook is not wait.unraisable


def test_a_time_limit_lost_in_a_finalizer_is_not_printed(monkeypatch) -> None:
    """The alarm's LimitExceeded raised inside a finalizer is not printed (the alarm rings
    again until the run ends); any other unraisable error still is."""
    from types import SimpleNamespace

    from synth import limits
    from synth.commands import cli

    told: list[type] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda info: told.append(info.exc_type))
    wait = cli._SignalsWait()
    try:
        for value in (limits.LimitExceeded("time limit", "ground"), ValueError("x")):
            info = SimpleNamespace(
                exc_type=type(value),
                exc_value=value,
                exc_traceback=None,
                err_msg=None,
                object=None,
            )
            sys.unraisablehook(info)
    finally:
        wait.remove()
        signal.signal(signal.SIGINT, signal.default_int_handler)
    assert told == [ValueError]


def test_an_error_a_stop_caused_is_told_as_the_stop(tmp_path: Path) -> None:
    """An error parmor does not expect, raised because Ctrl-C or the time limit's alarm
    stopped a library mid-way (numpy turned the alarm into a TypeError), is told as the
    stop; one with no stop behind it is raised (a bug's traceback is its report)."""
    import io

    from synth import limits
    from synth.commands import cli

    err = io.StringIO()
    try:
        e = TypeError("cannot compare")
        e.__context__ = KeyboardInterrupt()
        assert cli._unexpected(e, err, limited=False) == 130
        limits.configure(limits.Limits(time_s=0.001), arm=False)
        time.sleep(0.01)
        assert cli._unexpected(TypeError("cannot compare"), err, limited=True) == 1
        limits.configure(limits.Limits(time_s=60), arm=False)
        with pytest.raises(TypeError):
            cli._unexpected(TypeError("a bug"), err, limited=True)
    finally:
        limits.configure(limits.Limits(), arm=False)
    assert err.getvalue().splitlines() == [
        "parmor: interrupted",
        "parmor: error: time limit (0.001 s, --time-limit) reached while in stage run",
    ]


def test_the_program_ends_at_once_when_its_shutdown_is_not_safe(tmp_path: Path) -> None:
    """A program that ends with an error while a thread still runs (simulations the time
    limit left) ends at once with its code, its streams flushed and its atexit functions
    run; one that ended well with no thread left shuts down as usual."""
    code = (
        "import atexit, sys, threading, time\n"
        "from synth.commands import cli\n"
        "atexit.register(lambda: print('atexit ran', flush=True))\n"
        "threading.Thread(target=time.sleep, args=(60,)).start()\n"
        "sys.stdout.write('buffered ')\n"
        "cli._end(1)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    p = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=30
    )
    assert (p.returncode, p.stdout) == (1, "buffered atexit ran\n"), p.stderr
    well = "from synth.commands import cli\ncli._end(0)\nprint('went on')\n"
    p = subprocess.run(
        [sys.executable, "-c", well], env=env, capture_output=True, text=True, timeout=30
    )
    assert (p.returncode, p.stdout) == (0, "went on\n"), p.stderr


@pytest.mark.parametrize("stop", [KeyboardInterrupt, "limit"])
def test_an_interrupted_prefetch_stops_the_grounding_worker(tmp_path: Path, stop) -> None:
    """Ctrl-C or the time limit while this process imports (the worker grounding a huge
    rule file): the worker is killed, and the time limit is told as a grounding's is."""
    from adron.kb import load
    from synth import limits
    from synth.reasoning import solver

    rules = tmp_path / "explode.lp"
    rules.write_text(BLOW_UP, encoding="utf-8")
    seen: list[bool] = []

    def importing(ready: Callable[[], bool]) -> None:
        seen.append(ready())
        if stop == "limit":
            raise limits.LimitExceeded("time limit (1 s, --time-limit)", limits.stage_name())
        raise stop

    expected = KeyboardInterrupt if stop is KeyboardInterrupt else limits.LimitExceeded
    with pytest.raises(expected) as e:
        solver.Reasoner(load(), [str(rules)], while_grounding=importing)
    assert seen == [False]  # still grounding when it was called
    pid = solver._UNREAPED[-1]  # killed, not yet reaped
    with contextlib.suppress(ChildProcessError):
        _, status = os.waitpid(pid, 0)
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL
    if stop == "limit":
        assert e.value.stage == "ground" and "explode.lp" in str(e.value)


def test_the_checks_catch_what_they_check(tmp_path: Path) -> None:
    """Each check fails on a run built to break it: a traceback, a signal death, a hang,
    an undocumented code, a bundle left behind."""
    py = [sys.executable, "-c"]

    def raw(name: str, code: str, **kw) -> Ended:
        case = Case(name, [], {0}, **kw)
        here = tmp_path / name
        here.mkdir()
        if kw.get("bundle"):
            (here / kw["bundle"]).mkdir()
        p = subprocess.Popen([*py, code], cwd=here, stderr=subprocess.PIPE)
        try:
            _, err = p.communicate(timeout=case.takes)
            rc: int | None = p.returncode
        except subprocess.TimeoutExpired:
            p.kill()
            _, err = p.communicate()
            rc = None
        left = sorted(x.name for x in here.iterdir())
        return Ended(case, rc, err.decode(), 0.0, left)

    assert "a traceback" in " ".join(raw("tb", "raise SystemExit(0) from print(1/0)").problems())
    assert "signal 11" in " ".join(
        raw("segv", "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)").problems()
    )
    assert "hung" in " ".join(raw("hang", "import time; time.sleep(30)", takes=0.5).problems())
    assert "undocumented" in " ".join(raw("rc", "raise SystemExit(5)").problems())
    assert "left" in " ".join(raw("left", "raise SystemExit(130)", bundle="b").problems())
    assert not raw("ok", "print('fine')").problems()


if __name__ == "__main__":  # a measurement: python tests/synth/commands/test_exit_paths.py [N]
    import tempfile
    from collections import Counter

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    with tempfile.TemporaryDirectory(prefix="parmor-exit-") as tmp:
        for what, make in BATTERY.items():
            t0 = time.monotonic()
            ended = run_all(make(n), Path(tmp))
            kinds: Counter[str] = Counter()
            for e in ended:
                for p in e.problems():
                    kinds[p.split(" (")[0].split(",")[0]] += 1
            codes = Counter(e.code for e in ended)
            print(
                f"{what}: {len(ended)} runs in {time.monotonic() - t0:.0f} s; exit codes "
                f"{dict(sorted(codes.items(), key=str))}; hangs "
                f"{sum(e.code is None for e in ended)}, signal deaths "
                f"{sum(e.code is not None and e.code < 0 for e in ended)}, tracebacks "
                f"{sum(any(b in e.err for b in BROKEN) for e in ended)}; problems {dict(kinds)}",
                flush=True,
            )
            for e in ended:
                if e.problems():
                    print("   ", e.describe(), flush=True)
