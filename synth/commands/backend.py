"""Where the independent work of a study runs: local processes or a Ray cluster.

``parmor sweep`` (one task a request) and ``parmor enumerate`` (one task a candidate) hand
their tasks to :func:`tasks`, which runs them on local worker processes (the default; one
process runs them in-process) or on Ray (``--backend ray [--address HEAD:PORT]``) and hands
back each result as it finishes. A task is ``work(state, item)``; ``state = init(arg)`` is
built once per worker process (the grounded knowledge base, the catalog), so both must be
module-level functions and ``arg``, ``item`` and the results picklable.

Ray is optional (``pip install 'parmor[ray]'``) and imported only here, only when asked.
Without ``--address`` a throwaway local Ray instance is started (``RAY_ADDRESS`` is honoured
as Ray does); a Ray session the caller already opened (``ray.init`` in Python) is used as
it is and left open. Ray workers import the parmor installed on their node; nothing is
shipped through Ray's ``runtime_env``, because the dependencies parmor needs there
(clingo, MuJoCo, numpy...) must be installed on each node anyway. A worker whose parmor
files, or study files (ontology, rules, catalog at the same paths), differ from the
driver's refuses the work (:class:`BackendError`), so a result is never computed by other
code than the one its stored key names.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import signal
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from adron.catalog import load_catalog
from adron.errors import InputError, ParmorError

BACKENDS = ("local", "ray")
RAY_INSTALL = "pip install 'parmor[ray]'"
#: Ray's own messages (connecting, starting an instance) at this level and above only
RAY_LOG_LEVEL = logging.WARNING


class BackendError(ParmorError):
    """The distributed engine cannot run the work (unreachable cluster, a node whose
    parmor differs from the driver's, a worker lost)."""

    exit_code = 2


@dataclass(frozen=True)
class Backend:
    """``name``: local or ray; ``jobs``: worker processes (local; default the machine's
    cores) or tasks running at once (ray; default the cluster's CPUs); ``address``: the
    Ray cluster to join (None: a new local instance, or ``RAY_ADDRESS``)."""

    name: str = "local"
    jobs: int | None = None
    address: str | None = None

    def __post_init__(self) -> None:
        if self.name not in BACKENDS:
            raise InputError(f"--backend {self.name}: expected one of {', '.join(BACKENDS)}")
        if self.jobs is not None and self.jobs < 1:
            raise InputError(f"--jobs {self.jobs}: expected 1 or more")
        if self.address is not None and self.name != "ray":
            raise InputError("--address is the Ray cluster's: give it with --backend ray")
        if self.address is not None and not self.address.strip():
            raise InputError("--address: expected HOST:PORT of the Ray cluster's head")


# --- digests: which files a result depends on ---------------------------------------------

#: The packages whose files decide a design: a change to any of them designs everything again.
CODE_PACKAGES = ("adron", "asp", "synth", "kinematics", "gaits", "export")
CODE_SUFFIXES = (".py", ".lp", ".kif", ".toml")


def code_files() -> list[Path]:
    """parmor's own source and data files (the packages are located, not imported)."""
    import importlib.util

    out = []
    for pkg in CODE_PACKAGES:
        spec = importlib.util.find_spec(pkg)
        roots = (spec.submodule_search_locations or ()) if spec is not None else ()
        for root in roots:
            out += sorted(
                f for f in Path(root).rglob("*") if f.suffix in CODE_SUFFIXES and f.is_file()
            )
    return out


def digest(paths: Iterable[str | Path | None]) -> str:
    """A hash of the contents of ``paths`` (None: a file not given)."""
    h = hashlib.sha256()
    for p in paths:
        h.update(b"\0" if p is None else Path(p).read_bytes())
        h.update(b"\1")
    return h.hexdigest()


def files_digest(catalog: str | None, ontology: Sequence[str], rules: Sequence[str]) -> str:
    """The digest of a study's files (catalog, ontology, rules) and of parmor's own. The
    catalog counts by its content hash (adron.catalog: its text and those it extends; a
    shipped catalog's name works as well as a path)."""

    head = "-" if catalog is None else load_catalog(catalog).sha256
    rest = digest([*ontology, *rules, *code_files()])
    return hashlib.sha256(f"{head}|{rest}".encode()).hexdigest()


# --- running tasks -------------------------------------------------------------------------

_STATE: dict[str, Any] = {}  # in a worker process: token -> init(arg)


def _token(arg: Any) -> str:
    import pickle

    return hashlib.sha256(pickle.dumps(arg)).hexdigest()


def _pool_init(init: Callable, arg: Any, token: str) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the driver, which stops us
    _STATE[token] = init(arg)


def _pool_work(job: tuple[Callable, str, Any, Any]) -> tuple[Any, Any]:
    work, token, key, item = job
    return key, work(_STATE[token], item)


def _ray_work(
    init: Callable, arg: Any, token: str, check: tuple | None, work: Callable, key: Any, item: Any
) -> tuple[Any, Any]:
    """One Ray task: the worker's state built on its first task of this study (after
    checking its files against the driver's), then ``work``."""
    if token not in _STATE:
        if check is not None:
            files, expected = check
            import socket

            try:
                got = files_digest(*files)
            except OSError as e:
                raise BackendError(
                    f"node {socket.gethostname()}: cannot read {e.filename}: {e.strerror} "
                    "(every node needs the study's files at the same paths)"
                ) from None
            if got != expected:
                raise BackendError(
                    f"node {socket.gethostname()}: its parmor or the study's files differ "
                    "from those of the machine that runs the command; install the same parmor "
                    "on every node and give them the same study files"
                )
        _STATE[token] = init(arg)
    return key, work(_STATE[token], item)


def _import_ray():
    try:
        import ray
    except ImportError:
        raise InputError(
            f"--backend ray needs Ray, which is not installed: {RAY_INSTALL}"
        ) from None
    return ray


PROBE_TIMEOUT = 10.0  # s: how long the head of --address HOST:PORT may take to accept


def _probe(address: str) -> None:
    """Fail at once when HOST:PORT accepts no connection (Ray itself retries for minutes).
    Other forms Ray knows (auto, ray://...) are left to Ray."""
    import socket

    host, sep, port = address.rpartition(":")
    if not sep or "/" in address or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), PROBE_TIMEOUT).close()
    except OSError as e:
        raise BackendError(
            f"--address {address}: no Ray cluster answers there ({e.strerror or e}); start "
            "one with 'ray start --head' and give its address"
        ) from None


@contextlib.contextmanager
def tasks(
    backend: Backend,
    init: Callable[[Any], Any],
    arg: Any,
    work: Callable[[Any, Any], Any],
    items: Sequence[tuple[Any, Any]],
    files: tuple[str | None, Sequence[str], Sequence[str]] | None = None,
    here: Any = None,
) -> Iterator[Iterator[tuple[Any, Any]]]:
    """Run ``work(init(arg), item)`` for each ``(key, item)``; yields an iterator of
    ``(key, result)`` in the order they finish. Leaving the block early (Ctrl-C, an error)
    stops every worker at once and cancels the tasks not done. ``files``: the study's
    (catalog, ontology, rules), checked on every Ray node against the driver's. ``here``:
    the state to use when the work runs in this process (instead of ``init(arg)``)."""
    if backend.name == "ray":
        with _ray_tasks(backend, init, arg, work, items, files) as done:
            yield done
        return
    import os

    jobs = min(backend.jobs or os.cpu_count() or 1, max(len(items), 1))
    if jobs == 1 or not items:
        state = here if here is not None or not items else init(arg)
        yield ((key, work(state, item)) for key, item in items)
        return
    import multiprocessing

    token = _token(arg)
    pool = multiprocessing.Pool(jobs, _pool_init, (init, arg, token))
    ok = False
    try:
        yield pool.imap_unordered(_pool_work, [(work, token, k, x) for k, x in items], chunksize=1)
        ok = True
    finally:
        if ok:
            pool.close()
        else:
            pool.terminate()
        pool.join()


@contextlib.contextmanager
def _ray_tasks(backend, init, arg, work, items, files) -> Iterator[Iterator[tuple[Any, Any]]]:
    ray = _import_ray()
    started = not ray.is_initialized()
    if started and items:
        kwargs: dict[str, Any] = {
            "log_to_driver": False,
            "logging_level": RAY_LOG_LEVEL,
            "configure_logging": True,
        }
        if backend.address is None:
            kwargs["include_dashboard"] = False
        else:
            _probe(backend.address)
        try:
            ray.init(address=backend.address, **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as e:
            where = f"--address {backend.address}" if backend.address else "Ray"
            raise BackendError(f"{where}: cannot start or reach a Ray cluster: {e}") from None
    inflight: dict = {}
    try:
        if not items:
            yield iter(())
            return
        check = (files, files_digest(*files)) if files is not None else None
        token = _token(arg)
        arg_ref = ray.put(arg)
        remote = ray.remote(_ray_work).options(num_cpus=1, max_retries=1)
        width = backend.jobs or max(1, int(ray.cluster_resources().get("CPU", 1)))
        yield _ray_results(ray, remote, (init, arg_ref, token, check, work), items, width, inflight)
    finally:
        for ref in inflight:  # not done: cancelled, their workers killed
            with contextlib.suppress(Exception):
                ray.cancel(ref, force=True)
        if started and ray.is_initialized():
            ray.shutdown()


def _ray_results(ray, remote, head: tuple, items, width: int, inflight: dict):
    """Keep ``width`` tasks running; yield each result as it finishes."""
    todo = list(items)
    todo.reverse()
    while todo or inflight:
        while todo and len(inflight) < width:
            key, item = todo.pop()
            inflight[remote.remote(*head, key, item)] = key
        ready, _ = ray.wait(list(inflight), num_returns=1)
        ref = ready[0]
        del inflight[ref]
        try:
            result = ray.get(ref)
        except ray.exceptions.RayTaskError as e:
            cause = getattr(e, "cause", None)
            if isinstance(cause, ParmorError):
                raise cause from None
            raise BackendError(f"a Ray task failed: {cause or e}") from None
        except ray.exceptions.RayError as e:
            raise BackendError(f"a Ray worker was lost: {e}") from None
        yield result
