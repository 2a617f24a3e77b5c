"""Limits of a run: wall time, the reasoner's memory, the ground program's size.

One :class:`Limits` per process (the command line sets it from ``--time-limit``,
``--memory-limit`` and ``--size-limit``; a library user calls :func:`configure`, or
leaves them off). Reaching one raises :class:`LimitExceeded` (exit 1) naming the limit and
the stage (parse, ground, solve, size, simulate, ...) that was running. Import-light: no
clingo here.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from adron.errors import InputError, ParmorError

#: Wall time of one command, s: room for a design with every behaviour simulated (about a
#: minute on a loaded 2-core machine) many times over, short of "hangs".
DEFAULT_TIME_S = 600.0
#: Memory the clingo worker may take beyond the process it forks from, MB: a hundred times
#: what ADROn needs (under 40 MB), within a small laptop.
DEFAULT_MEMORY_MB = 4096
#: Ground program size, atoms: ADROn grounds to about 5,000; a 100,000-class taxonomy to
#: about 2 million. Beyond 10 million, solving (and memory) stop being practical.
DEFAULT_SIZE_ATOMS = 10_000_000
#: Most perturbed runs per behaviour a design may ask for (``parmor design --robustness``,
#: ``PARMOR_ROBUSTNESS``, a study's ``robustness``): 64 runs of each behaviour is minutes
#: to an hour of simulation, and certifying more is ``--certify``'s job.
MAX_ROBUSTNESS = 64


def certify_runs(n: int | None, conflict: bool, option: str) -> int:
    """``--certify N``'s runs (0: not asked), for ``design`` and ``sweep`` alike: N at
    least 1 (the parser bounds it above), and not with ``option`` (given: ``conflict``),
    which turns off what it counts on."""
    if n is None:
        return 0
    if conflict:
        raise InputError(f"--certify N sets the number of perturbed runs: drop {option}")
    if n == 0:
        raise InputError("--certify N: N must be at least 1")
    return n


class LimitExceeded(ParmorError):
    """A time, memory or size limit was reached; the message names it and the stage."""

    exit_code = 1

    def __init__(self, limit: str, stage: str, detail: str = "") -> None:
        self.limit, self.stage, self.detail = limit, stage, detail
        super().__init__(
            f"{limit} reached while in stage {stage}" + (f": {detail}" if detail else "")
        )


@dataclass(frozen=True, slots=True)
class Limits:
    """``time_s`` wall seconds for the run, ``memory_mb`` for the clingo worker,
    ``size_atoms`` for the ground program; None turns one off."""

    time_s: float | None = None
    memory_mb: int | None = None
    size_atoms: int | None = None

    def describe(self, limit: str) -> str:
        """'time limit (600 s)' and the like, for messages."""
        if limit == "time":
            return f"time limit ({self.time_s:g} s, --time-limit)"
        if limit == "memory":
            return f"memory limit ({self.memory_mb} MB, --memory-limit)"
        return f"ground program size limit ({self.size_atoms} atoms, --size-limit)"


_current = Limits()
_deadline: float | None = None
_stage = "run"
_capped: int | None = None  # the process whose memory cap_memory capped


def current() -> Limits:
    """The limits in force."""
    return _current


def stage_name() -> str:
    """The stage that is running (for messages)."""
    return _stage


@contextlib.contextmanager
def stage(name: str) -> Iterator[None]:
    """Mark the code inside as stage ``name``."""
    global _stage
    before, _stage = _stage, name
    try:
        yield
    except MemoryError:
        if _capped != os.getpid():
            raise
        raise memory_exceeded() from None
    finally:
        _stage = before


#: After the time limit, the alarm rings again this often, s, until the run ends: code that
#: swallowed the first LimitExceeded (a broad ``except Exception``) does not run on unbounded.
REPEAT_S = 0.25


def _alarm(signum: int, frame: object) -> None:
    # Python runs a handler at its next instruction: by then the limit may be off again
    # (the run ended, a bounded item gave back the outer deadline): a stale ring, ignored
    if _deadline is None:
        return
    left = _deadline - time.monotonic()
    if left > 1e-3:  # early (a deadline given back or moved on): ring at the right time
        signal.setitimer(signal.ITIMER_REAL, left)
        return
    signal.setitimer(signal.ITIMER_REAL, REPEAT_S)
    raise LimitExceeded(_current.describe("time"), _stage)


def configure(limits: Limits, arm: bool = True) -> None:
    """Put ``limits`` in force from now. With ``arm`` (main thread only), SIGALRM ends the
    Python stages (parse, simulate) at the deadline; the reasoner checks it itself."""
    global _current, _deadline
    _current = limits
    _deadline = None if limits.time_s is None else time.monotonic() + limits.time_s
    if arm and threading.current_thread() is threading.main_thread():
        if limits.time_s is None:
            signal.setitimer(signal.ITIMER_REAL, 0)
        else:
            signal.signal(signal.SIGALRM, _alarm)
            signal.setitimer(signal.ITIMER_REAL, limits.time_s)


def disarm() -> None:
    """Stop the time limit's alarm (the run is over)."""
    if threading.current_thread() is threading.main_thread():
        signal.setitimer(signal.ITIMER_REAL, 0)


def remaining() -> float | None:
    """Seconds left before the time limit, or None without one."""
    return None if _deadline is None else _deadline - time.monotonic()


def check(where: str | None = None) -> None:
    """Raise LimitExceeded when the time limit has passed."""
    left = remaining()
    if left is not None and left <= 0:
        raise LimitExceeded(_current.describe("time"), where or _stage)


@contextlib.contextmanager
def paused() -> Iterator[None]:
    """Stop the clock inside (waiting for a person's answer); the time spent is given back."""
    global _deadline
    if _deadline is None:
        yield
        return
    disarm()
    t0 = time.monotonic()
    try:
        yield
    finally:
        _deadline += time.monotonic() - t0
        if threading.current_thread() is threading.main_thread():
            signal.setitimer(signal.ITIMER_REAL, max(_deadline - time.monotonic(), 1e-3))


@contextlib.contextmanager
def bounded(limits: Limits, what: str = "") -> Iterator[None]:
    """Put ``limits`` in force inside, with a deadline of its own from now (one request of
    a sweep, one query of a suite); the outer limits and deadline again after. A limit
    reached inside names ``what`` (e.g. "request 'hexapod'")."""
    global _current, _deadline
    outer, outer_deadline = _current, _deadline
    configure(limits)
    try:
        yield
    except LimitExceeded as e:
        if not what:
            raise
        detail = "; ".join(x for x in (e.detail, what) if x)
        raise LimitExceeded(e.limit, e.stage, detail) from None
    finally:
        _current, _deadline = outer, outer_deadline
        if threading.current_thread() is threading.main_thread():
            if _deadline is None:
                signal.setitimer(signal.ITIMER_REAL, 0)
            else:
                signal.setitimer(signal.ITIMER_REAL, max(_deadline - time.monotonic(), 1e-3))


def memory_exceeded() -> LimitExceeded:
    """The error for a MemoryError of this process under ``cap_memory``."""
    return LimitExceeded(_current.describe("memory"), _stage, "this process ran out of memory")


#: Least memory this process may take beyond its start under ``cap_memory``, MB: the
#: libraries it imports later (numpy, OpenBLAS's buffers, MuJoCo, trimesh) need about this
#: much before any work; below it an import, not the work, would fail.
MIN_PROCESS_MB = 512


def data_bytes() -> int:
    """This process's data size (Linux: VmData of /proc/self/status, the private writable
    memory ``RLIMIT_DATA`` counts), bytes; 0 where unknown."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmData:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def address_space_kb() -> int:
    """This process's address space (virtual memory), KiB; 0 where it cannot be read. The
    clingo worker and the ground probe cap theirs at this plus their ``memory_mb``."""
    import resource

    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[0]) * resource.getpagesize() // 1024
    except OSError:
        return 0


def cap_memory(memory_mb: int | None) -> Callable[[], None]:
    """Cap this process's data (``RLIMIT_DATA``, Linux: private writable memory, not the
    libraries' code) at its present size plus ``memory_mb``, at least ``MIN_PROCESS_MB``:
    an allocation beyond raises MemoryError (the command line turns it into
    LimitExceeded). Returns the function that puts the old cap back. A stricter cap
    already in force stays. (The clingo worker has its own cap, ``memory_mb`` exactly.)"""
    here = data_bytes()
    if memory_mb is None or not here or not sys.platform.startswith("linux"):
        return lambda: None
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
    cap = here + max(memory_mb, MIN_PROCESS_MB) * 1024 * 1024
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    if soft != resource.RLIM_INFINITY and soft <= cap:
        return lambda: None
    try:
        resource.setrlimit(resource.RLIMIT_DATA, (cap, hard))
    except (ValueError, OSError):
        return lambda: None
    global _capped
    pid = _capped = os.getpid()

    def restore() -> None:
        global _capped
        if os.getpid() == pid:
            _capped = None
            with contextlib.suppress(ValueError, OSError):
                resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))

    return restore
