"""Which rule grew: run after a time or memory limit stopped the grounding (issue 11).

clingo grounds a program in one call that says nothing until it is done, so when the time
or memory limit kills the grounding worker, nothing tells which rule was being grounded.
:func:`culprit` finds out with a bounded second grounding in a forked process: the same
program, one statement at a time, each in its own program part grounded on what the parts
before it derived (clingo's multi-shot grounding), the process reporting each statement
before grounding it. The statement it is in when its budget (``PROBE_S`` seconds, the
same memory limit) ends, is the one that grew.

The order is the program's: the knowledge base's facts and the taxonomy (one part), each
KIF rule form (file:line:col, translated again on its own), parmor's encodings (one part),
then each statement of each rule file (file:line:col). When the probe is stopped in
parmor's encodings, they grew on what a rule of the user's gave them: the KIF rule or rule
file statement of the user's that added the most atoms before them is named, with its count
(none when no statement of the user's added any: nothing of theirs is blamed). Grounding a
statement once, on what the statements before it derived, is an approximation of the
whole grounding (a rule is not grounded again with atoms derived after it), good for the
rules that blow up on their own (a huge interval, a cross product, many variables). When
the probe ends within its budget without blowing up, no rule is named.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import Pipe

from adron.kb import builtin_files, read_user_file
from adron.kif import MAX_DEPTH, parse
from adron.translate import translate
from synth.limits import address_space_kb

#: Seconds the probe may take after the limit was reached: it is added to the limit.
PROBE_S = 3.0
ENCODINGS = "parmor's encodings"


def pieces(
    kb,
    taxonomy: str,
    rules: Sequence,
    encodings: str,
    parse: Callable[[str], Sequence],
    program: str | None = None,
) -> list[tuple[str, str]]:
    """(place, program text) of each piece, in grounding order (see the module);
    ``encodings``: parmor's encodings as one text, ``parse``: the solver's parser of a rule
    file into statements (``synth.reasoning.solver`` hands both over: this module imports nothing
    of it); ``program``: the translation as it went to the grounder (default: all of it)."""
    program = kb.translation.program if program is None else program
    lines = program.splitlines()
    facts = [taxonomy] + [line for line in lines if ":-" not in line]
    out: list[tuple[str, str]] = [("the knowledge base's facts and taxonomy", "\n".join(facts))]
    grounded = set(lines)
    out += [
        (place, text)
        for place, text in kif_rules(kb)
        if all(x in grounded for x in text.splitlines() if ":-" in x)
    ]
    out.append((ENCODINGS, encodings))
    for r in rules:
        try:
            stmts = parse(r.text)
        except RuntimeError:
            continue
        for stmt in stmts:
            loc = stmt.location.begin
            if str(stmt).startswith("#program"):
                continue
            out.append((f"the rule at {r.name}:{loc.line}:{loc.column}", str(stmt)))
    return out


def kif_rules(kb) -> list[tuple[str, str]]:
    """(place, ASP rules) of each KIF rule form (``=>``, ``<=>``) of ``kb``'s files, read
    and translated again one form at a time (the translation does not locate rules)."""

    shipped = builtin_files()
    n = len(shipped) if tuple(kb.files[: len(shipped)]) == tuple(x for x, _ in shipped) else 0
    out = []
    for i, name in enumerate(kb.files):
        text = shipped[i][1] if i < n else read_user_file(name)[1]
        for form in parse(text, name, MAX_DEPTH):
            items = getattr(form, "items", ())
            if not items or items[0] not in ("=>", "<=>"):
                continue
            with contextlib.suppress(Exception):
                program = translate([form]).program
                if ":-" in program:
                    out.append((f"the rule at {name}:{form.line}:{form.col}", program))
    return out


def culprit(
    kb,
    taxonomy: str,
    rules: Sequence,
    memory_mb: int | None,
    encodings: str,
    parse: Callable[[str], Sequence],
    budget_s: float = PROBE_S,
    program: str | None = None,
) -> str:
    """The place of the statement that grew (see the module), or '' when none did
    within ``budget_s`` seconds and ``memory_mb`` (None: no memory cap); ``encodings``
    and ``parse`` as for :func:`pieces`."""

    parts = pieces(kb, taxonomy, rules, encodings, parse, program)
    read, write = Pipe(duplex=False)
    pid = os.fork()
    if pid == 0:  # the probe
        code = 0
        try:
            read.close()
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.setitimer(signal.ITIMER_REAL, 0)
            _ground(parts, write, memory_mb)
        except BaseException:  # noqa: BLE001 - a forked probe never returns into the caller
            code = 1
        finally:
            os._exit(code)
    write.close()
    last, done = -1, False
    added: dict[int, int] = {}  # part -> atoms it added
    deadline = time.monotonic() + budget_s
    try:
        while (left := deadline - time.monotonic()) > 0 and read.poll(left):
            try:
                msg = read.recv()
            except EOFError:  # the probe died (out of memory) in the last part it named
                break
            if msg == "done":
                done = True
                break
            if isinstance(msg, tuple):
                added[msg[0]] = msg[1]
            else:
                last = msg
    finally:
        read.close()
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
        with contextlib.suppress(ChildProcessError):
            os.waitpid(pid, 0)
    if done or last < 0:
        return ""
    return blamed([place for place, _ in parts], added, last, {n for n, _ in builtin_files()})


def blamed(places: Sequence[str], added: dict[int, int], last: int, shipped: set[str]) -> str:
    """What grew, of pieces at ``places``, the probe stopped in piece ``last`` having seen
    piece ``i`` add ``added[i]`` atoms: that piece; or, stopped in parmor's encodings, the
    user's statement before them that added the most atoms (a KIF rule of a ``shipped``
    file is parmor's own, and a statement that added none fed the encodings nothing), and
    '' when there is none: then nothing of the user's is to blame."""
    if places[last] != ENCODINGS:
        return places[last]
    users = {
        i: n
        for i, n in added.items()
        if 0 < i < last and n > 0 and _file_of(places[i]) not in shipped
    }
    if not users:
        return ""
    i = max(users, key=lambda k: (users[k], -k))
    return f"{places[i]} (its {users[i]} atoms, on which parmor's encodings ground)"


def _file_of(place: str) -> str | None:
    """The file of a piece's place ``the rule at FILE:LINE:COL``; None for other pieces."""
    if not place.startswith("the rule at "):
        return None
    return place.removeprefix("the rule at ").rsplit(":", 2)[0]


def _ground(parts: list[tuple[str, str]], conn, memory_mb: int | None) -> None:
    import clingo

    if memory_mb is not None:
        cap = (address_space_kb() + memory_mb * 1024) * 1024
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_AS, (cap, resource.getrlimit(resource.RLIMIT_AS)[1]))
    ctl = clingo.Control(["--warn=none"], logger=lambda c, m: None)
    for i, (_, text) in enumerate(parts):
        conn.send(i)
        name = f"parmor_probe_{i}"
        before = len(ctl.symbolic_atoms)
        try:
            ctl.add(name, [], text)
            ctl.ground([(name, [])])
        except RuntimeError as e:
            if "bad_alloc" in str(e):
                return  # out of memory in part i: the parent names it
            continue  # a piece that does not ground alone (a syntax the whole one reports)
        conn.send((i, len(ctl.symbolic_atoms) - before))
    conn.send("done")
