"""``parmor regress``: named design queries and their stored results.

A suite is a TOML file (format in ``parmor regress --help``). Each query runs as
``parmor design --no-input --json`` would; the records are stored in
``<suite>.snapshot.json`` beside the suite by ``--update`` and compared otherwise.
"""

from __future__ import annotations

import contextlib
import difflib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TextIO

import synth.pipeline
from adron import readers
from adron.catalog import SHIPPED
from adron.errors import ExportError, InputError
from adron.formats import check
from adron.kb import load
from adron.userfiles import check_regular
from synth import limits
from synth.pipeline import StructureOptions, bus_limit
from synth.reasoning.conceptual import Designer, Request, parse_answer
from synth.reasoning.solver import Reasoner


def snapshot_path(suite: Path) -> Path:
    return suite.with_name(suite.stem + ".snapshot.json")


def read_toml(path: Path) -> dict:
    """The TOML table of a user's file (a suite or a study), read within bounds; its
    format's schema checks it (adron/formats.py)."""
    check_regular(path)  # a FIFO or a device: refused at once, not waited on
    return readers.read_toml(path)  # nesting and numbers bounded, a byte order mark dropped


def confined(path: Path, key: str, given: str) -> str:
    """The file ``given`` (relative to the suite or study ``path``) of its ``key``, which
    must lie in the suite's folder or below it: a path that leaves it (``..``, an absolute
    path elsewhere, a symbolic link pointing out) is an InputError naming the key. A suite
    or study can come from anywhere; it must not make parmor read (and quote in its
    messages) files of the user's it does not ship with."""
    base = path.parent
    target = base / given
    try:
        inside = target.resolve().is_relative_to(base.resolve())
    except (OSError, RuntimeError, ValueError):  # a symbolic link loop, a NUL
        inside = False
    if not inside:
        raise InputError(
            f"{path}: {key}: {given!r} is outside the folder of {path.name}; a suite or "
            "study reads only files in its own folder or below it"
        )
    return str(target)


def kb_options(data: Mapping[str, Any], path: Path) -> dict:
    """The ``ontology``, ``rules`` and ``catalog`` of a suite or study file (validated by
    its schema; paths relative to it, inside its folder: :func:`confined`);
    ``allow_scripts`` is False."""
    opts = {
        "suite": str(path),
        "ontology": [confined(path, "ontology", p) for p in data.get("ontology", [])],
        "rules": [confined(path, "rules", p) for p in data.get("rules", [])],
        # running a rule file's scripts is the user's call on the command line, never the
        # suite file's (a suite can come from anywhere)
        "allow_scripts": False,
    }
    catalog = data.get("catalog")

    if catalog in SHIPPED:  # a shipped catalog's name ("dynamixel"), not a path
        opts["catalog"] = catalog
    else:
        opts["catalog"] = confined(path, "catalog", catalog) if catalog else None
    return opts


def load_suite(path: Path) -> tuple[dict, list[dict]]:
    """The suite's options and its queries. The file is checked against its schema
    (:class:`adron.formats.SuiteFile`: keys, types, unique names; errors name the file,
    the key and the value); the files it names must lie in its folder (:func:`confined`);
    its abilities, answers and parameters are checked against the knowledge base when
    the queries run."""

    suite = check("suite", read_toml(path), str(path))
    opts = kb_options(suite.model_dump(), path)
    opts["conceptual"] = suite.conceptual
    # simulating every behaviour makes a suite slow and its snapshot hold simulator
    # figures; a suite asks for it with verify = true
    opts["verify"] = suite.verify
    out = [
        {
            "name": q.name,
            "abilities": tuple(q.abilities),
            "answers": dict(q.answers),
            "params": dict(q.params),
        }
        for q in suite.query
    ]
    return opts, out


def designer_for(opts: dict) -> Designer:
    """The Designer of a suite's (or study's) ``ontology``, ``rules``, ``allow_scripts``."""
    kb = load(opts["ontology"])
    try:
        limit = bus_limit(opts.get("catalog"), bool(opts.get("conceptual")))
    except InputError as e:  # named by the suite or study that gives the catalog
        raise InputError(f"{opts['suite']}: catalog: {e}") from None
    return Designer(kb, Reasoner(kb, opts["rules"], opts["allow_scripts"], bus_limit=limit))


def request_for(q: dict) -> Request:
    """The Request of a query table (``abilities``, ``answers`` yes/no, ``params``)."""
    return Request(
        abilities=tuple(q["abilities"]),
        answers=tuple(parse_answer(f"{k}={v}") for k, v in q["answers"].items()),
        params=tuple(q["params"].items()),
    )


def run_queries(
    opts: dict, queries: list[dict], lim: limits.Limits | None = None
) -> dict[str, dict]:
    """name -> design record, for every query of a suite (one grounding for all). With
    ``lim``, the grounding and each query get its limits, with a deadline each."""

    def bounded(what: str):
        return limits.bounded(lim, what) if lim is not None else contextlib.nullcontext()

    with bounded(f"grounding the knowledge base of {opts['suite']}"):
        designer = designer_for(opts)
    sopts = StructureOptions(opts["catalog"], opts["conceptual"], verify=opts["verify"])
    results = {}
    for i, q in enumerate(queries):
        try:
            with bounded(f"{opts['suite']}: query[{i}] ({q['name']})"):
                outcome = synth.pipeline.run(designer, request_for(q), sopts)
                results[q["name"]] = outcome.record(designer)
        except InputError as e:
            raise InputError(f"{opts['suite']}: query[{i}] ({q['name']}): {e}") from None
    return results


def _dump(obj: object) -> str:
    return json.dumps(obj, indent=2, ensure_ascii=False) + "\n"


def temp_beside(path: Path) -> tuple[int, str]:
    """(open descriptor, name) of a new temporary file beside ``path``, to be renamed over
    it: made with the mode any new file gets (0666 less the umask, usually 0644), not
    ``tempfile.mkstemp``'s 0600, so the file it becomes is as readable as one written
    in place. OSError when the folder cannot be written."""
    import secrets

    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = os.path.join(path.parent, f".{path.name}.{secrets.token_hex(6)}.tmp")
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name beside {path}")


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file in the same folder and a
    rename: the old file stays whole on any failure (full disk, no permission, a kill); the
    new one has the mode a new file gets (:func:`temp_beside`). ExportError (exit 2) naming
    the file otherwise."""
    tmp = None
    try:
        fd, tmp = temp_beside(path)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        tmp = None
    except OSError as e:
        raise ExportError(f"{path}: cannot write: {e.strerror or e}") from None
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def run_suite(
    suite: str | Path,
    update: bool,
    out: TextIO,
    err: TextIO,
    allow_scripts: bool = False,
    lim: limits.Limits | None = None,
) -> int:
    """Run a suite; 0 when all match (or updated), 1 with a diff when any changed."""
    path = Path(suite)
    opts, queries = load_suite(path)
    opts["allow_scripts"] = allow_scripts
    results = run_queries(opts, queries, lim)
    snap = snapshot_path(path)
    if update:
        write_atomic(snap, _dump(results))
        out.write(f"stored {len(results)} result(s) in {snap}\n")
        return 0
    if not snap.exists():
        raise InputError(f"{snap}: no snapshot; run 'parmor regress {suite} --update' first")
    check_regular(snap)
    stored = readers.read_json(snap)  # nesting and numbers bounded
    if not isinstance(stored, dict) or not all(isinstance(v, dict) for v in stored.values()):
        raise InputError(
            f"{snap}: not a snapshot (expected an object of query name -> record); "
            f"rewrite it with 'parmor regress {suite} --update'"
        )
    changed = matched = 0
    for name, rec in results.items():
        if name not in stored:
            out.write(f"NEW      {name} (not in the snapshot)\n")
            changed += 1
        elif stored[name] != rec:
            changed += 1
            out.write(f"CHANGED  {name}\n")
            diff = difflib.unified_diff(
                _dump(stored[name]).splitlines(),
                _dump(rec).splitlines(),
                f"{snap.name}:{name}",
                f"now:{name}",
                lineterm="",
            )
            out.writelines(line + "\n" for line in diff)
        else:
            matched += 1
            out.write(f"ok       {name}\n")
    for name in sorted(set(stored) - set(results)):
        out.write(f"GONE     {name} (in the snapshot, not in the suite)\n")
        changed += 1
    out.write(f"{matched} matched, {changed} changed\n")
    return 1 if changed else 0
