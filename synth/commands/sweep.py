"""``parmor sweep``: a parameter study, many design requests designed and simulated.

A study is a TOML file of ``[[request]]`` tables (``abilities``, optional ``name``,
``answers`` and ``params``, as in regression suites) whose ``params`` values may be lists:
a table expands into the product of its lists. Each expanded request is designed as
``parmor design --no-input`` would: sized and (unless ``--no-simulate``, which designs
as ``--no-verify`` does) every behaviour it lists simulated with default parameters and fed
back (``synth.verification``). The figures of each simulated behaviour (``synth.verification``, the
records of ``parmor simulate --json``) become the rows of ``results.csv``.

The requests run on local worker processes, or on a Ray cluster with ``--backend ray``
(``synth.commands.backend``); the results are the same either way. Each finished request is
stored as
``DIR/requests/<key>.json``, ``key`` a hash of the request, the mode (simulated or not)
and the contents of the study's ontology, rules and catalog files and of parmor's own
source and data files; a rerun designs only
the requests without a stored result and rebuilds ``results.csv``, ``summary.md`` and
``plots/*.png`` from the stored results alone, so they are byte-identical to those of an
uninterrupted run. Requests that raised an unexpected error are not stored (a rerun tries
them again).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import itertools
import json
import os
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TextIO

import synth.pipeline
from adron import readers
from adron.errors import ExportError, InputError
from adron.formats import MAX_STUDY_REQUESTS as MAX_STUDY_REQUESTS  # (re-exported)
from adron.formats import check
from synth import limits
from synth.commands.backend import Backend, files_digest, tasks
from synth.commands.backend import code_files as code_files  # re-exported: the files keys depend on
from synth.commands.regress import (
    designer_for,
    kb_options,
    read_toml,
    request_for,
    temp_beside,
)
from synth.params import BY_NAME, parse_structural
from synth.pipeline import StructureOptions, load_checked_catalog

RESULT_FORMAT = 2  # of the stored per-request results; part of their key
KEY_LENGTH = 16  # hex digits of the request key (64 bits)
NO_TYPE = "(none)"  # the robot type column of a request no robot type met
# CSV columns before the parameters, between parameters and figures, and last
HEAD_COLUMNS = ("request", "id", "robot_type")
MIDDLE_COLUMNS = ("status", "reason", "abilities", "mass_kg", "sizings", "behavior", "listed")
TAIL_COLUMNS = ("verdict",)


# --- the study file ------------------------------------------------------------------------


def default_out(study: Path) -> Path:
    """``parameter-range.toml`` -> ``parameter-range.sweep`` beside it."""
    return study.with_name(study.stem + ".sweep")


def load_study(path: Path) -> tuple[dict, list[dict]]:
    """The study's options and its expanded requests, in file order (each list expanded
    in the order of its ``params`` keys, the last varying fastest). Each request:
    ``name``, ``abilities``, ``answers`` (name -> "yes"/"no"), ``params`` (name -> value
    string), ``where`` (file and table, for messages).

    The file is checked against its schema (:class:`adron.formats.StudyFile`: keys,
    types, ranges, values listed once, and the study's size, at most
    :data:`MAX_STUDY_REQUESTS` requests counted before anything is expanded; errors name
    the file, the key and the value); the files it names must lie in its folder
    (:func:`synth.commands.regress.confined`). What only the knowledge base can say is
    :func:`validate`'s."""

    study = check("study", read_toml(path), str(path))
    opts = kb_options(study.model_dump(), path)
    opts["robustness"] = study.robustness
    out = []
    for i, t in enumerate(study.request):
        name = t.name or "+".join(t.abilities)
        where = f"{path}: request[{i}] ({name})"
        lists = {k: [v] if isinstance(v, str) else list(v) for k, v in t.params.items()}
        for values in itertools.product(*lists.values()):
            out.append(
                {
                    "name": name,
                    "abilities": list(t.abilities),
                    "answers": dict(t.answers),
                    "params": dict(zip(lists, values, strict=True)),
                    "where": where,
                }
            )
    return opts, out


def request_key(
    q: dict, simulate: bool, files_digest: str, robustness: int = 0, certify: bool = False
) -> str:
    """The stable key of a request's result: abilities, answers, params, mode (simulated
    or not, perturbed runs per behaviour, a certification's or not: they need other
    passes), and the digest of the study's files and parmor's own."""
    ident = {
        "format": RESULT_FORMAT,
        "simulate": simulate,
        "files": files_digest,
        "abilities": q["abilities"],
        "answers": sorted(q["answers"].items()),
        "params": sorted(q["params"].items()),
    }
    if robustness and simulate:  # (keys of studies without robustness stay as they were)
        ident["robustness"] = robustness
        if certify:
            ident["certify"] = True
    text = json.dumps(ident, sort_keys=True, ensure_ascii=False)
    return hashlib.sha256(text.encode()).hexdigest()[:KEY_LENGTH]


#: Significant digits two parameter values in SI units must share to be the same value
#: ("0.3m" and "30cm" differ in the last bit of their floats).
SI_DIGITS = 12


def validate(opts: dict, requests: Sequence[dict]) -> None:
    """Check every name and value of every request against the knowledge base and the
    catalog before anything runs, and refuse a request given twice (its parameters
    compared in SI units: ``1kg`` is ``1000g``); an InputError names the file and the
    request."""

    designer = designer_for(opts)
    try:
        load_checked_catalog(opts["catalog"], designer)
    except InputError as e:
        raise InputError(f"{opts['suite']}: catalog: {e}") from None
    seen: dict[tuple, dict] = {}
    for q in requests:
        try:
            req = request_for(q)
            designer.query(req)
            physical = designer.structural(req)
        except InputError as e:
            raise InputError(f"{q['where']}: {e}") from None
        params = {
            k: float(f"{physical[k]:.{SI_DIGITS}g}") if k in physical else v
            for k, v in q["params"].items()
        }
        ident = (req.abilities, tuple(sorted(req.answers)), tuple(sorted(params.items())))
        first = seen.setdefault(ident, q)
        if first is not q:
            given = json.dumps(q["params"], ensure_ascii=False)
            if first["params"] != q["params"]:
                given += (
                    f" and {json.dumps(first['params'], ensure_ascii=False)}, the same in SI units"
                )
            raise InputError(f"{q['where']}: the same request as {first['where']} (params {given})")


# --- designing and simulating one request (in a worker process) ---------------------------


def _init_worker(arg: tuple[dict, bool, limits.Limits | None]) -> tuple:
    """The state of a worker: the study's knowledge base grounded (within the limits, with
    a deadline of its own), the structure options."""

    opts, simulate, lim = arg
    with _bounded(lim, "grounding the study's knowledge base"):
        designer = designer_for(opts)
    k = int(opts.get("robustness", 0)) if simulate else 0
    certify = bool(opts.get("certify")) and k > 0
    sopts = StructureOptions(opts["catalog"], verify=simulate, robustness=k, certify=certify)
    return designer, sopts, simulate, lim


def _bounded(lim: limits.Limits | None, what: str = ""):
    return limits.bounded(lim, what) if lim is not None else contextlib.nullcontext()


def _work(state: tuple, q: dict) -> dict:
    """One request within the limits (``--time-limit`` is each request's): one that
    reaches one is an error of the sweep, tried again on its next run."""
    designer, sopts, simulate, lim = state
    try:
        with _bounded(lim), limits.stage("structure/simulate"):  # as 'parmor design' says
            return design_one(q, designer, sopts, simulate)
    except limits.LimitExceeded as e:  # the alarm after design_one caught the rest
        res: dict = {"status": "error", "reason": f"LimitExceeded: {e}", "robot_type": None}
        res.update(abilities=[], mass_kg=None, behaviors=None, dropped={}, sizings=None)
        return res


def design_one(q: dict, designer, sopts, simulate: bool) -> dict:
    """The stored result of one request: status (accepted, refused, ambiguous; error for
    an unexpected exception), reason, robot type, abilities, mass, and what the design's
    verification found: the simulation record of each behaviour (None when not simulated),
    the abilities it dropped (ability -> why) and the sizings it took."""

    res: dict = {"status": "error", "reason": "", "robot_type": None, "abilities": []}
    res.update(mass_kg=None, behaviors=None, dropped={}, sizings=None)
    try:
        outcome = synth.pipeline.run(designer, request_for(q), sopts)
        d = outcome.design
        rec = outcome.record(designer)
        res["robot_type"] = d.chosen.robot_type if d.chosen else None
        res["abilities"] = list(rec.get("abilities") or [])
        res["mass_kg"] = rec.get("mass_kg")
        if outcome.status == "designed" and outcome.structure is None:
            # stayed conceptual: nothing was sized (or simulated), so nothing is accepted
            res["status"] = "refused"
            res["reason"] = "no structure: " + (outcome.note or "the design was not sized")
        elif outcome.status == "designed":
            res["status"] = "accepted"
            res["reason"] = "; ".join(n for n in (d.note, outcome.note) if n)
        elif outcome.status == "ambiguous":
            pending = d.questions[-1]
            res["status"] = "ambiguous"
            res["reason"] = (
                f'an answer is needed: {pending.text} (add {pending.ability} = "yes" or '
                f'"no" to the request\'s answers; candidates '
                f"{', '.join(c.robot_type for c in d.candidates)})"
            )
        else:
            res["status"] = "refused"
            res["reason"] = outcome.infeasible or (
                "no robot can meet the request: "
                + " + ".join(d.conflict)
                + (f" ({d.note})" if d.note else "")
            )
        v = outcome.verification
        if simulate and v is not None:
            res["behaviors"] = [b.to_dict() for b in v.behaviors]
            res["dropped"] = dict(sorted(v.dropped.items()))
            res["sizings"] = v.rounds
            if v.robust is not None:  # each behaviour's perturbed runs (synth.verification)
                res["robust"] = [
                    {k: getattr(b, k) for k in ("behavior", "ability", "passed", "runs", "robust")}
                    for b in v.robust.behaviors
                ]
                if v.robust.shows:  # what the runs show (Clopper-Pearson), as design prints
                    res["shows"] = dict(v.robust.shows)
    except Exception as e:  # noqa: BLE001 - a sweep records a crash and goes on
        res["status"], res["reason"] = "error", f"{type(e).__name__}: {e}"
    return res


# --- running the study ---------------------------------------------------------------------


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``path`` through a temporary sibling renamed into place (all or nothing), with
    the mode a new file gets (``synth.commands.regress.temp_beside``)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = temp_beside(path)
    except OSError as e:
        raise ExportError(f"{path}: cannot write: {e.strerror}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise ExportError(f"{path}: cannot write: {e.strerror}") from None
        raise


def _stored(path: Path) -> dict | None:
    """A stored result, or None when absent or unreadable (then it is designed again)."""
    try:
        rec = readers.read_json(path)  # nesting and numbers bounded
    except InputError:
        return None
    if not isinstance(rec, dict) or rec.get("format") != RESULT_FORMAT:
        return None
    return rec.get("result")


def _store(path: Path, q: dict, result: dict) -> None:
    rec = {
        "format": RESULT_FORMAT,
        "request": {k: q[k] for k in ("name", "abilities", "answers", "params")},
        "result": result,
    }
    write_atomic(path, (json.dumps(rec, indent=1, sort_keys=True) + "\n").encode())


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / "requests").is_dir():
        raise InputError(
            f"{out}: exists, is not empty and holds no sweep (no requests/ folder); "
            "choose another --out"
        )


def _progress(err: TextIO, total: int, done: int) -> Callable[[str | None], None]:
    """A rich progress bar on stderr: call with the name of each finished request, then
    with None to remove it."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    bar = Progress(
        TextColumn("sweep {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        transient=True,
        console=Console(file=err),
    )
    task = bar.add_task("", total=total, completed=done)
    bar.start()

    def step(name: str | None) -> None:
        if name is None:
            bar.stop()
        else:
            bar.update(task, advance=1, description=name)

    return step


def run_study(
    study: str | Path,
    out_dir: str | Path | None = None,
    jobs: int | None = None,
    simulate: bool = True,
    err: TextIO | None = None,
    allow_scripts: bool = False,
    backend: str = "local",
    address: str | None = None,
    lim: limits.Limits | None = None,
    certify: int = 0,
) -> dict:
    """Run a study: design (and simulate) the requests without a stored result on the
    ``backend`` (local processes, or Ray: ``synth.commands.backend``), then write the outputs from
    every stored result; returns the summary object (``--json``).

    ``certify`` N (``--certify``): the study's finalists, its accepted requests, are
    designed again as ``parmor design --certify N`` does (N perturbed runs per behaviour,
    stored under their own key, so a certification resumes too), and each row gets
    ``certified``: the runs, the outcome and what they show (the lower bound of each
    behaviour's success probability at 90 % confidence, Clopper-Pearson). A finalist may
    fail its certification: more perturbations may strengthen it or refuse it."""
    path = Path(study)
    engine = Backend(backend, jobs, address)
    opts, requests = load_study(path)
    opts["allow_scripts"] = allow_scripts
    out = Path(out_dir) if out_dir is not None else default_out(path)
    _check_out(out)
    with _bounded(lim, f"checking the study {path}"):
        validate(opts, requests)
    files = (opts["catalog"], opts["ontology"], opts["rules"])
    digest = files_digest(*files)  # reads and hashes every file: once per study
    keys = {i: request_key(q, simulate, digest, opts["robustness"]) for i, q in enumerate(requests)}
    store = out / "requests"
    run = (store, engine, err, requests)
    results, reused = _results(run, keys, (opts, simulate, lim))
    computed = len(results) - reused
    rows = [_merged(q, results[i], keys[i]) for i, q in enumerate(requests)]
    if certify:  # the finalists again, with N perturbed runs (stored under their own keys)
        finalists = [i for i, r in enumerate(rows) if r["status"] == "accepted"]
        ckeys = {i: request_key(requests[i], simulate, digest, certify, True) for i in finalists}
        copts = dict(opts, robustness=certify, certify=True)
        certified, more = _results(run, ckeys, (copts, simulate, lim))
        reused, computed = reused + more, computed + len(certified) - more
        for i in finalists:
            rows[i]["certified"] = certificate(certified[i], certify)
    written = write_outputs(out, path, rows, simulate, opts["robustness"])
    summary = summary_object(rows, simulate, opts["robustness"])
    summary.update(study=str(path), out=str(out), computed=computed, reused=reused)
    summary["files"] = written
    return summary


def _results(
    run: tuple[Path, Backend, TextIO | None, list[dict]],
    keys: dict[int, str],
    arg: tuple[dict, bool, limits.Limits | None],
) -> tuple[dict[int, dict], int]:
    """The result of each request ``keys`` names (index -> its key): stored ones as they
    are, the others designed on the engine with ``arg`` (and stored); with how many were
    stored. ``run``: the store folder, the engine, the progress stream, the requests."""
    store, engine, err, requests = run
    results: dict[int, dict] = {}
    for i, k in keys.items():
        r = _stored(store / f"{k}.json")
        if r is not None and r.get("status") != "error":
            results[i] = r
    reused = len(results)
    pending = [(i, requests[i]) for i in keys if i not in results]
    _compute(pending, results, keys, store, arg, engine, err, len(keys))
    return results, reused


def _compute(
    pending: list[tuple[int, dict]],
    results: dict[int, dict],
    keys: dict[int, str],
    store: Path,
    arg: tuple[dict, bool, limits.Limits | None],
    engine: Backend,
    err: TextIO | None,
    total: int,
) -> None:
    """Design the pending requests on the engine, storing each as it finishes."""
    if not pending:
        return
    store.mkdir(parents=True, exist_ok=True)
    opts = arg[0]
    files = (opts["catalog"], opts["ontology"], opts["rules"])
    step = _progress(err, total, total - len(pending)) if err is not None and err.isatty() else None
    todo = dict(pending)
    try:
        with tasks(engine, _init_worker, arg, _work, pending, files) as done:
            for i, res in done:
                if res["status"] != "error":
                    _store(store / f"{keys[i]}.json", todo[i], res)
                results[i] = res
                if step:
                    step(todo[i]["name"])
    except KeyboardInterrupt:  # the workers are stopped, what finished is stored
        if err is not None:
            if step:
                step(None)
                step = None
            n = sum(1 for r in results.values() if r["status"] != "error")
            err.write(
                f"parmor: sweep interrupted: {n} of {total} requests stored in {store}; "
                "run the same command again to continue\n"
            )
        raise
    finally:
        if step:
            step(None)


def _merged(q: dict, res: dict, key: str) -> dict:
    return {"request": q, "id": key, **res}


def certificate(res: dict, runs: int) -> dict:
    """A finalist's certification (``run_study``'s ``certify``) from its result with
    ``runs`` perturbed runs per behaviour: its status, its reason when not accepted, and
    the lower bound its runs show (None when they show none: refused, or an error)."""
    shows = res.get("shows") or {}
    return {
        "runs": runs,
        "status": res["status"],
        "reason": res["reason"] if res["status"] != "accepted" else "",
        "success_lower_bound": shows.get("success_lower_bound"),
        "confidence": shows.get("confidence"),
        "behavior": shows.get("behavior"),
    }


# --- outputs -------------------------------------------------------------------------------


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    return json.dumps(value, ensure_ascii=False, separators=(",", ":"))


def verdict_text(b: dict) -> str:
    v = b.get("verdict")
    if v is None:
        return ""
    return v if isinstance(v, str) else ";".join(str(x) for x in v)


def results_csv(rows: Sequence[dict]) -> str:
    """One row per request and behaviour (one row for a request without behaviours):
    the request, its parameters, its status and reason, and every figure of the
    behaviour's simulation record (the sorted union of their keys)."""
    params = sorted({p for r in rows for p in r["request"]["params"]})
    figures = sorted(
        {k for r in rows for b in r["behaviors"] or () for k in b} - {"behavior", "verdict"}
    )
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*HEAD_COLUMNS, *params, *MIDDLE_COLUMNS, *figures, *TAIL_COLUMNS])
    for r in rows:
        q = r["request"]
        head = [q["name"], r["id"], r["robot_type"] or ""]
        head += [q["params"].get(p, "") for p in params]
        head += [r["status"], r["reason"], " ".join(r["abilities"]), _cell(r["mass_kg"])]
        head.append(_cell(r["sizings"]))
        for b in r["behaviors"] or [{}]:
            listed = _cell(_listed(r, b)) if b else ""
            w.writerow(
                [
                    *head,
                    b.get("behavior", ""),
                    listed,
                    *(_cell(b.get(f)) for f in figures),
                    verdict_text(b),
                ]
            )
    return buf.getvalue()


def _listed(r: dict, b: dict) -> bool:
    """Whether the design lists behaviour ``b`` (its ability was not dropped)."""
    return b.get("ability", b.get("behavior")) not in r["dropped"]


def _failed(b: dict) -> list[str]:
    """The failed criteria of a behaviour's record (empty when ok)."""
    v = b.get("verdict")
    if v == "ok":
        return []
    return [v] if isinstance(v, str) else [str(c) for c in v or ["(no verdict)"]]


def _all_ok(r: dict) -> bool:
    """An accepted request whose every listed behaviour was simulated and kept its promise."""
    bs = [b for b in r["behaviors"] or () if _listed(r, b)]
    return r["status"] == "accepted" and bool(bs) and not any(_failed(b) for b in bs)


def _nominal_ok(r: dict) -> bool:
    """A sized design (accepted, or refused by its perturbed runs) whose every listed
    behaviour kept its promise on the nominal model."""
    bs = [b for b in r["behaviors"] or () if _listed(r, b)]
    return r["status"] in ("accepted", "refused") and bool(bs) and not any(_failed(b) for b in bs)


def _robust_ok(r: dict) -> bool:
    """An accepted design whose every listed behaviour passed the required share of its
    perturbed runs (``robust`` of :func:`design_one`)."""
    bs = [b for b in r.get("robust") or () if _listed(r, b)]
    return _all_ok(r) and bool(bs) and all(b["robust"] for b in bs)


def summary_object(rows: Sequence[dict], simulate: bool, robustness: int = 0) -> dict:
    """Counts per status, and per robot type: requests, accepted, accepted with every
    listed behaviour ok, refused (and how many of them by a simulated behaviour), abilities
    dropped, and the simulated behaviours failing each criterion (of every design). With
    ``robustness`` K (the study's key), per type also the designs whose every listed
    behaviour passed nominally (``nominal_ok``: accepted, or refused by the perturbed
    runs) and the accepted ones that also passed the perturbed runs (``robust_ok``), and
    the runs passed of those simulated (``robust_runs``: [passed, runs])."""
    status = Counter(r["status"] for r in rows)
    types: dict[str, dict] = {}
    for t in sorted({r["robot_type"] or NO_TYPE for r in rows}):
        mine = [r for r in rows if (r["robot_type"] or NO_TYPE) == t]
        acc = [r for r in mine if r["status"] == "accepted"]
        refused = [r for r in mine if r["status"] == "refused"]
        crit: Counter = Counter(c for r in mine for b in r["behaviors"] or () for c in _failed(b))
        types[t] = {
            "requests": len(mine),
            "accepted": len(acc),
            "all_ok": sum(_all_ok(r) for r in acc) if simulate else None,
            "refused": len(refused),
            "refused_by_simulation": sum(bool(r["behaviors"]) for r in refused),
            "dropped": dict(sorted(Counter(a for r in acc for a in r["dropped"]).items())),
            "failures": dict(sorted(crit.items())),
        }
        if simulate and robustness:
            runs = [b for r in mine for b in r.get("robust") or ()]
            types[t] |= {
                "nominal_ok": sum(_nominal_ok(r) for r in mine),
                "robust_ok": sum(_robust_ok(r) for r in mine),
                "robust_runs": [sum(b["passed"] for b in runs), sum(b["runs"] for b in runs)],
            }
    out = {
        "simulated": simulate,
        "robustness": robustness if simulate else 0,
        "requests": len(rows),
        "status": {s: status.get(s, 0) for s in ("accepted", "refused", "ambiguous", "error")},
        "types": types,
    }
    certified = [r for r in rows if r.get("certified")]
    if certified:  # --certify: each finalist's certification, in the study's order
        out["certified"] = [
            {"request": _describe(r["request"], r["request"]["name"]), "id": r["id"]}
            | r["certified"]
            for r in certified
        ]
    return out


def _describe(q: dict, name: str) -> str:
    """``name: abilities answers params`` of a request."""
    bits = [f"{name}: " + ", ".join(q["abilities"])]
    bits += [f"{k}={v}" for k, v in q["answers"].items()]
    bits += [f"{k}={v}" for k, v in q["params"].items()]
    return " ".join(bits)


def _md(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def summary_md(
    study: Path, rows: Sequence[dict], simulate: bool, plots: Sequence[str], robustness: int = 0
) -> str:
    """The study's pass rates per robot type (nominal and robust with ``robustness``), the
    behaviours and their failures by criterion, the abilities dropped, the requests not
    accepted with their reasons, the plots."""
    s = summary_object(rows, simulate, robustness)
    st = s["status"]
    lines = [
        f"# Sweep of {study.name}",
        "",
        f"{s['requests']} requests: {st['accepted']} accepted, {st['refused']} refused, "
        f"{st['ambiguous']} waiting for an answer"
        + (f", {st['error']} failed with an error" if st["error"] else "")
        + ". "
        + (
            "Designed as `parmor design` does: every behaviour a design lists simulated with "
            "its default parameters, failures fed back, a demanded ability that still fails "
            "refuses the request and a bonus one is dropped."
            if simulate
            else "Designed only (--no-simulate, as `parmor design --no-verify`): no behaviour "
            "was simulated."
        ),
        "",
        "## Pass rates per robot type",
        "",
    ]
    if simulate:
        lines += [
            "| robot type | requests | accepted | every listed behaviour ok | share of accepted "
            "| refused (of them by simulation) | abilities dropped |",
            "|---|---|---|---|---|---|---|",
        ]
    else:
        lines += ["| robot type | requests | accepted | refused |", "|---|---|---|---|"]
    for t, v in s["types"].items():
        if simulate:
            share = f"{100 * v['all_ok'] / v['accepted']:.0f} %" if v["accepted"] else "-"
            dropped = ", ".join(f"{a} {n}" for a, n in v["dropped"].items()) or "-"
            lines.append(
                f"| {t} | {v['requests']} | {v['accepted']} | {v['all_ok']} | {share} | "
                f"{v['refused']} ({v['refused_by_simulation']}) | {dropped} |"
            )
        else:
            lines.append(f"| {t} | {v['requests']} | {v['accepted']} | {v['refused']} |")
    if s["robustness"]:
        lines += _robust_md(s)
    if s.get("certified"):
        lines += ["", "## Certified finalists", ""]
        lines += [f"- {_md(c['request'])}: {_md(certified_text(c))}" for c in s["certified"]]
    if simulate:
        lines += _behaviors_md(rows)
    dropped = [(r, a, why) for r in rows for a, why in r["dropped"].items()]
    if dropped:
        lines += [
            "",
            "## Abilities dropped",
            "",
            "| request | robot type | ability | why |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {_md(_describe(r['request'], r['request']['name']))} | {r['robot_type']} | "
            f"{a} | {_md(why)} |"
            for r, a, why in dropped
        ]
    refused = [r for r in rows if r["status"] != "accepted"]
    if refused:
        lines += [
            "",
            "## Requests not accepted",
            "",
            "| request | robot type | status | reason |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {_md(_describe(r['request'], r['request']['name']))} | "
            f"{r['robot_type'] or '-'} | {r['status']} | {_md(r['reason'])} |"
            for r in refused
        ]
    if plots:
        lines += [
            "",
            "## Plots",
            "",
            "Outcome over each pair of parameters that vary for a robot type (each cell: "
            + (
                "accepted requests whose every listed behaviour passed / accepted requests"
                if simulate
                else "accepted / requested"
            )
            + "; x: every request there was refused, red where a simulated behaviour "
            "refused one).",
            "",
        ]
        lines += [f"![{Path(p).stem}]({p})" for p in plots]
    return "\n".join(lines) + "\n"


def _pct(n: int, of: int) -> str:
    return f"{100 * n / of:.0f} %" if of else "-"


def _robust_md(s: dict) -> list[str]:
    """The nominal and robust pass rates per robot type (a study with ``robustness``)."""
    lines = [
        "",
        "## Robustness",
        "",
        f"Every behaviour of a design that passed on the nominal model was run under "
        f"{s['robustness']} seeded perturbations (`parmor design --robustness "
        f"{s['robustness']}`); a behaviour not robust refuses the request (a demanded "
        "ability) or drops its ability. Nominal ok: sized designs whose every listed "
        "behaviour passed nominally; robust ok: accepted designs whose every listed "
        "behaviour also passed the perturbed runs (shares of the requests).",
        "",
        "| robot type | requests | nominal ok | robust ok | perturbed runs passed |",
        "|---|---|---|---|---|",
    ]
    for t, v in s["types"].items():
        n, passed, runs = v["requests"], *v["robust_runs"]
        lines.append(
            f"| {t} | {n} | {v['nominal_ok']} ({_pct(v['nominal_ok'], n)}) | {v['robust_ok']} "
            f"({_pct(v['robust_ok'], n)}) | {passed} of {runs} |"
        )
    return lines


def _behaviors_md(rows: Sequence[dict]) -> list[str]:
    """Each behaviour's simulations and passes, and the failures by criterion, over every
    simulated behaviour (of accepted designs, dropped abilities included, and of refused
    requests)."""
    per: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0])
    crit: Counter = Counter()
    for r in rows:
        for b in r["behaviors"] or ():
            key = (r["robot_type"] or NO_TYPE, b.get("behavior", ""))
            per[key][0] += 1
            failed = _failed(b)
            per[key][1] += not failed
            crit.update((*key, c) for c in failed)
    lines = [
        "",
        "## Behaviours",
        "",
        "Every simulation counts: those of accepted designs (of dropped abilities too) and "
        "those that made a request refused.",
        "",
        "| robot type | behaviour | simulated | ok |",
        "|---|---|---|---|",
    ]
    lines += [f"| {t} | {b} | {n} | {ok} |" for (t, b), (n, ok) in sorted(per.items())]
    lines += ["", "## Failures by criterion", ""]
    if not crit:
        lines.append("None: every simulated behaviour kept its promise.")
    else:
        lines += ["| robot type | behaviour | criterion | failed |", "|---|---|---|---|"]
        lines += [f"| {t} | {b} | {c} | {n} |" for (t, b, c), n in sorted(crit.items())]
    return lines


def _axis_order(values: Iterable[str], name: str) -> list[str]:
    """Distinct parameter values in axis order: physical ones by their SI value."""

    distinct = sorted(set(values))
    if name not in BY_NAME:
        return distinct
    return sorted(distinct, key=lambda v: (parse_structural({name: v})[name], v))


def plot_files(rows: Sequence[dict], simulate: bool) -> dict[str, bytes]:
    """``plots/<type>-<a>-<b>.png``: per robot type, the outcome over each pair of
    parameters that take more than one value among its requests (one parameter: over
    that one). matplotlib (Agg) is imported only here."""
    by_type: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        if r["robot_type"] and r["status"] in ("accepted", "refused"):
            by_type[r["robot_type"]].append(r)
    jobs = []
    for t, mine in sorted(by_type.items()):
        names = sorted({p for r in mine for p in r["request"]["params"]})
        swept = [n for n in names if len({r["request"]["params"].get(n, "") for r in mine}) > 1]
        pairs: list[tuple[str, str | None]] = list(itertools.combinations(swept, 2))
        if len(swept) == 1:
            pairs = [(swept[0], None)]
        jobs += [(t, mine, a, b) for a, b in pairs]
    if not jobs:
        return {}
    import matplotlib

    matplotlib.use("Agg")
    out = {}
    for t, mine, a, b in jobs:
        name = f"plots/{t}-{a}" + (f"-{b}" if b else "") + ".png"
        out[name] = _plot(t, mine, a, b, simulate)
    return out


def _plot(t: str, rows: Sequence[dict], a: str, b: str | None, simulate: bool) -> bytes:
    import matplotlib.pyplot as plt

    default = "(default)"

    def val(r: dict, n: str) -> str:
        return r["request"]["params"].get(n, default)

    def order(n: str) -> list[str]:
        vals = {val(r, n) for r in rows}
        given = _axis_order(vals - {default}, n)
        return ([default] if default in vals else []) + given

    xs = order(a)
    ys = order(b) if b else [""]
    cells: dict[tuple[int, int], list[dict]] = defaultdict(list)
    for r in rows:
        cells[(xs.index(val(r, a)), ys.index(val(r, b)) if b else 0)].append(r)
    fig, ax = plt.subplots(figsize=(max(4.0, 0.9 * len(xs) + 2), max(2.5, 0.6 * len(ys) + 2)))
    cmap = plt.get_cmap("RdYlGn")
    for (x, y), rs in sorted(cells.items()):
        acc = [r for r in rs if r["status"] == "accepted"]
        if not acc:  # red: refused because a simulated behaviour failed
            simulated = any(r["behaviors"] for r in rs)
            ax.scatter([x], [y], marker="x", s=120, color="tab:red" if simulated else "0.4")
            continue
        good = sum(_all_ok(r) for r in acc) if simulate else len(acc)
        whole = len(acc) if simulate else len(rs)
        ax.scatter(
            [x], [y], marker="o", s=320, color=cmap(0.15 + 0.7 * good / whole), edgecolors="0.2"
        )
        ax.annotate(f"{good}/{whole}", (x, y), ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(xs)), xs)
    ax.set_yticks(range(len(ys)), ys)
    ax.set_xlim(-0.6, len(xs) - 0.4)
    ax.set_ylim(-0.6, len(ys) - 0.4)
    ax.set_xlabel(a)
    ax.set_ylabel(b or "")
    what = "every listed behaviour ok / accepted" if simulate else "accepted / requests"
    ax.set_title(f"{t}: {what}", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def write_outputs(
    out: Path, study: Path, rows: Sequence[dict], simulate: bool, robustness: int = 0
) -> list[str]:
    """Write results.csv, summary.md and plots/*.png (each atomically; plots of an earlier
    run that this one does not draw are removed). Returns the names written."""
    plots = plot_files(rows, simulate)
    files: dict[str, bytes] = {
        "results.csv": results_csv(rows).encode(),
        "summary.md": summary_md(study, rows, simulate, sorted(plots), robustness).encode(),
        **plots,
    }
    for name, data in sorted(files.items()):
        write_atomic(out / name, data)
    for old in sorted((out / "plots").glob("*.png")):
        if f"plots/{old.name}" not in files:
            old.unlink()
    return sorted(files)


# --- the command ---------------------------------------------------------------------------


def summary_text(s: dict) -> str:
    st = s["status"]
    lines = [
        f"{s['requests']} requests ({s['computed']} designed now, {s['reused']} stored): "
        f"{st['accepted']} accepted, {st['refused']} refused, {st['ambiguous']} ambiguous"
        + (f", {st['error']} errors" if st["error"] else "")
    ]
    for t, v in s["types"].items():
        ok = f", every behaviour ok {v['all_ok']}" if s["simulated"] else ""
        if s.get("robustness"):
            ok = f", nominal ok {v['nominal_ok']}, robust ok {v['robust_ok']}" + ok
        lines.append(f"  {t:<24} accepted {v['accepted']}/{v['requests']}{ok}")
    for c in s.get("certified", ()):
        lines.append(f"  certified {c['request']}: {certified_text(c)}")
    lines.append(f"wrote {s['out']}: {', '.join(f for f in s['files'] if '/' not in f)}")
    return "\n".join(lines) + "\n"


def certified_text(c: dict) -> str:
    """One finalist's certification in words (the summary's lines)."""
    if c["status"] != "accepted":
        return f"{c['status']} with {c['runs']} perturbed runs per behaviour: {c['reason']}"
    if c["success_lower_bound"] is None:
        return f"accepted with {c['runs']} perturbed runs per behaviour"
    return (
        f"{c['runs']} of {c['runs']} perturbed runs per behaviour passed: each behaviour "
        f"succeeds with probability above {100 * c['success_lower_bound']:.0f} % at "
        f"{100 * c['confidence']:.0f} % confidence (Clopper-Pearson)"
    )


def cmd_sweep(args, out: TextIO, err: TextIO) -> int:
    """``parmor sweep``: 0 when the sweep ran (whatever its pass rates), 2 on bad input."""
    certify = limits.certify_runs(args.certify, args.no_simulate, "--no-simulate")
    s = run_study(
        args.study,
        args.out,
        args.jobs,
        simulate=not args.no_simulate,
        err=err,
        allow_scripts=args.allow_scripts,
        backend=args.backend,
        address=args.address,
        lim=getattr(args, "limits", None),
        certify=certify,
    )
    if args.json:
        out.write(json.dumps(s, indent=2, ensure_ascii=False) + "\n")
    else:
        out.write(summary_text(s))
    if s["status"]["error"]:
        err.write(
            f"parmor: note: {s['status']['error']} request(s) failed with an error "
            "(see summary.md); they are tried again on the next run\n"
        )
    return 0
