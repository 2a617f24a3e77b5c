"""The local server of ``parmor blocks DIR --serve``: the block page and its Run button.

It listens on 127.0.0.1 only (a thread per connection, at most :data:`MAX_CONNECTIONS`
at once, each closed after :data:`SOCKET_TIMEOUT_S` s without traffic or when a request
takes more than :data:`REQUEST_TIMEOUT_S` s to arrive, its line, headers and body
together: a client that sends a header line now and then cannot hold a connection),
serves the page
(``DIR/blocks/``) and the meshes it animates (``DIR/meshes/``), and answers ``POST /run``:
the body is a program as JSON (``{"program": [...]}``, see :mod:`program.script`), never
code, read within bounds (:func:`program.script.parse`). The program is validated against
the design's behaviours and their limits (:func:`program.script.validate`), then run
(:func:`program.session.run_program`) in a child process that is killed when it exceeds
the time limit; at most :func:`run_slots` run at once (the CPUs, and the memory available
for :data:`RUN_MEMORY_MB` each). The reply is JSON: ``{"result": {...}}`` (the run's path,
verdict figures and animation) or ``{"error": "..."}`` with a 4xx/5xx status; the server
keeps serving after every error.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import mimetypes
import multiprocessing
import os
import socket
import sys
import threading
import time
from collections.abc import Mapping
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import TextIO
from urllib.parse import unquote, urlsplit

from adron.errors import InputError
from program.blocks import bundle_controller, read_record
from program.script import JsonError, ProgramError, parse, validate
from program.session import program_behaviors

#: The only address the server listens on.
HOST = "127.0.0.1"
#: The port when none is given.
DEFAULT_PORT = 8765
#: Largest request body accepted, bytes (a program of the largest size LIMITS allows is a
#: few kilobytes).
MAX_BODY = 64 * 1024
#: Largest body read and dropped to answer 413 cleanly; beyond it the connection is closed.
MAX_DRAIN = 4 * 1024 * 1024
#: Wall-clock seconds a run may take (its child process is killed then), by default, and
#: the range accepted: below it a run cannot even start its process; above it the waits
#: would overflow the system's timers (a run simulates at most 300 s anyway).
DEFAULT_TIME_LIMIT = 120.0
TIME_LIMIT_RANGE = (0.1, 86_400.0)
#: Memory one run takes, MB: measured, a 300-s program (the most a program may simulate)
#: on the hexapod (56 drawn parts, the most of the shipped designs) peaks at 290 MB in its
#: process, and its 25 MB reply passes through the server; with room to spare.
RUN_MEMORY_MB = 400
#: Connections served at once (a thread each); more are answered 503 and closed.
MAX_CONNECTIONS = 32
#: Seconds a connection may stay silent (a request not sent, a reply not read) before the
#: server closes it.
SOCKET_TIMEOUT_S = 30.0
#: Seconds a whole request (its line, its headers and its body) may take to arrive, from
#: the moment the server waits for it; a keep-alive connection's wait for its next request
#: counts too.
REQUEST_TIMEOUT_S = 30.0
#: Folders of the bundle the server serves files from (read-only).
SERVED_DIRS = ("blocks", "meshes")


def check_time_limit(seconds: float) -> float:
    """``seconds`` when a run's time limit can be honoured (:data:`TIME_LIMIT_RANGE`);
    InputError naming the value and the range otherwise."""
    low, high = TIME_LIMIT_RANGE
    if not (math.isfinite(seconds) and low <= seconds <= high):
        raise InputError(
            f"--time-limit {seconds:g}: expected seconds in [{low:g}, {high:g}] "
            "(the wall-clock time one run may take)"
        )
    return seconds


def available_memory_mb() -> float | None:
    """Memory a run could still take, MB: the system's available memory (``MemAvailable``),
    or less when this process's control group (v2 ``memory.max``, v1
    ``memory.limit_in_bytes``) leaves less room; None when neither can be read."""
    found: list[float] = []
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) / 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    room = _cgroup_room_mb()
    if room is not None:
        found.append(room)
    return min(found) if found else None


def _cgroup_room_mb() -> float | None:
    """What this process's memory control group leaves, MB; None without a limit."""
    try:
        lines = Path("/proc/self/cgroup").read_text(encoding="utf-8").splitlines()
    except OSError:
        return None
    root = Path("/sys/fs/cgroup")
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, group = parts
        if controllers == "":  # v2
            dirs, names = (root / group.lstrip("/"), root), ("memory.max", "memory.current")
        elif "memory" in controllers.split(","):  # v1
            mem = root / "memory"
            dirs, names = (
                (mem / group.lstrip("/"), mem),
                (
                    "memory.limit_in_bytes",
                    "memory.usage_in_bytes",
                ),
            )
        else:
            continue
        for d in dirs:
            try:
                limit = (d / names[0]).read_text().strip()
                if limit == "max" or int(limit) >= 2**60:  # no limit
                    break
                return (int(limit) - int((d / names[1]).read_text())) / 2**20
            except (OSError, ValueError):
                continue
    return None


def run_slots(cpus: int | None = None, available_mb: float | None = None) -> int:
    """Runs at once: one per CPU, and no more than the available memory holds at
    :data:`RUN_MEMORY_MB` each; at least one. Without arguments, this machine's now."""
    cpus = (os.cpu_count() or 1) if cpus is None else cpus
    if available_mb is None:
        available_mb = available_memory_mb()
    by_memory = cpus if available_mb is None else int(available_mb // RUN_MEMORY_MB)
    return max(1, min(cpus, by_memory))


class RunFailed(Exception):
    """A run that ended without a result: ``status`` is the HTTP status of the reply."""

    def __init__(self, status: HTTPStatus, message: str) -> None:
        super().__init__(message)
        self.status = status


def _child(conn, bundle: str, program: dict) -> None:
    """Run ``program`` on the bundle in this (child) process; send back JSON bytes:
    ``{"result": ...}`` (the reply the server forwards as it is) or ``{"error": ...,
    "input": bool}``. A Ctrl-C at the terminal
    reaches the whole process group: the server stops its runs itself, so a run ignores
    it (no KeyboardInterrupt traceback from a child)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        from program.session import run_program
        from synth.reasoning.plans import install

        install()  # a spawned process: the shipped ontology's body plans (older bundles)

        result = run_program(bundle, program)
        reply = {"result": result}
    except InputError as e:
        reply = {"error": str(e), "input": True}
    except Exception as e:  # a bug or a failed simulation: the message, not the traceback
        reply = {"error": f"the run failed: {type(e).__name__}: {e}", "input": False}
    try:
        data = json.dumps(reply, allow_nan=False).encode()
    except ValueError as e:
        data = json.dumps({"error": f"the result is not JSON: {e}", "input": False}).encode()
    try:
        conn.send_bytes(data)
        conn.close()
    except OSError:  # the server gave up on this run (its time limit) and closed its end
        pass


class Runner:
    """Runs programs in child processes, at most ``max_runs`` at once, each killed after
    ``time_limit`` s of wall-clock time."""

    def __init__(self, bundle: Path, time_limit: float, max_runs: int) -> None:
        self.bundle = bundle
        self.time_limit = check_time_limit(time_limit)
        self.max_runs = max_runs
        self.slots = threading.BoundedSemaphore(max_runs)
        self.ctx = multiprocessing.get_context("spawn")  # the server has threads: no fork
        self.children: set = set()
        self.lock = threading.Lock()

    def run(self, program: dict) -> bytes:
        """The reply of a run that ended with a result: ``{"result": ...}`` as JSON bytes;
        RunFailed otherwise."""
        t0 = time.monotonic()
        if not self.slots.acquire(timeout=self.time_limit):
            raise RunFailed(
                HTTPStatus.SERVICE_UNAVAILABLE,
                f"the server is busy with other runs; try again (waited {self.time_limit:g} s)",
            )
        try:
            recv, send = self.ctx.Pipe(duplex=False)
            proc = self.ctx.Process(
                target=_child, args=(send, str(self.bundle), program), daemon=True
            )
            with self.lock:
                self.children.add(proc)
            try:
                proc.start()
            except (OSError, RuntimeError) as e:
                with self.lock:
                    self.children.discard(proc)
                recv.close()
                send.close()
                raise RunFailed(
                    HTTPStatus.INTERNAL_SERVER_ERROR, f"cannot start the run: {e}"
                ) from None
            send.close()
            try:
                left = max(0.0, self.time_limit - (time.monotonic() - t0))
                if not recv.poll(left):
                    raise RunFailed(
                        HTTPStatus.GATEWAY_TIMEOUT,
                        f"the program ran longer than the time limit of {self.time_limit:g} s "
                        "and was stopped; make it shorter (fewer repeats, shorter behaviours)",
                    )
                try:
                    data = recv.recv_bytes()
                except EOFError:
                    raise RunFailed(
                        HTTPStatus.INTERNAL_SERVER_ERROR,
                        f"the run stopped without a result (exit code {proc.exitcode})",
                    ) from None
            finally:
                recv.close()
                if proc.is_alive():  # over its time limit, or its result is in: no grace
                    proc.join(0.2)
                if proc.is_alive():
                    proc.kill()
                proc.join()
                with self.lock:
                    self.children.discard(proc)
        finally:
            self.slots.release()
        if data.startswith(b'{"result"'):
            return data
        reply = json.loads(data)
        bad_input = reply.get("input")
        status = HTTPStatus.UNPROCESSABLE_ENTITY if bad_input else HTTPStatus.INTERNAL_SERVER_ERROR
        raise RunFailed(status, reply["error"])

    def stop(self) -> None:
        """Kill every run still going."""
        with self.lock:
            children = list(self.children)
        for proc in children:
            if proc.is_alive():
                proc.kill()
            proc.join()


class BlocksServer(ThreadingHTTPServer):
    """The page, the meshes and ``POST /run`` of one bundle."""

    daemon_threads = True
    #: connections the system queues until they are accepted (served or answered 503)
    request_queue_size = 64

    def __init__(
        self,
        bundle: Path,
        port: int,
        time_limit: float = DEFAULT_TIME_LIMIT,
        max_runs: int | None = None,
        log: TextIO | None = None,
        max_connections: int = MAX_CONNECTIONS,
        socket_timeout: float = SOCKET_TIMEOUT_S,
        request_timeout: float = REQUEST_TIMEOUT_S,
    ) -> None:
        """``max_runs`` None: :func:`run_slots`."""

        check_time_limit(time_limit)
        self.bundle = bundle.resolve()
        self.record = read_record(self.bundle)
        self.controller = bundle_controller(self.bundle, self.record)
        #: the behaviours a program may call (as program.session.Session offers them)
        self.behaviors = program_behaviors(self.controller, self.record.get("abilities", ()))
        self.runner = Runner(self.bundle, time_limit, run_slots() if max_runs is None else max_runs)
        self.log = log
        self.socket_timeout = socket_timeout
        self.request_timeout = request_timeout
        self.connections = threading.BoundedSemaphore(max_connections)
        self.max_connections = max_connections
        #: the server's state, for whoever waits on it (tests: no guess at how long the
        #: server takes): connections being served now, refused (503) and timed out so far
        self.state = threading.Condition()
        self.serving_now = 0
        self.refused = 0
        self.timed_out = 0
        super().__init__((HOST, port), Handler)

    def validate(self, program: object) -> None:
        """ProgramError (an InputError) when ``program`` is not one the design can run."""

        validate(program, self.behaviors)

    def count(self, name: str, by: int = 1) -> None:
        """Change the counter ``name`` of :attr:`state` and wake whoever waits on it."""
        with self.state:
            setattr(self, name, getattr(self, name) + by)
            self.state.notify_all()

    def wait_until(self, predicate, timeout: float | None = None) -> bool:
        """Wait until ``predicate(self)`` holds (it is checked each time a counter
        changes); False when ``timeout`` s passed first."""
        with self.state:
            return self.state.wait_for(lambda: predicate(self), timeout)

    def process_request(self, request: socket.socket, client_address: tuple) -> None:
        """A thread for the connection, or 503 and close when MAX_CONNECTIONS are open."""
        if not self.connections.acquire(blocking=False):
            self._refuse(request)
            return
        self.count("serving_now")
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.connections.release()
            self.count("serving_now", -1)
            raise

    def process_request_thread(self, request: socket.socket, client_address: tuple) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.connections.release()
            self.count("serving_now", -1)

    def _refuse(self, request: socket.socket) -> None:
        body = json.dumps(
            {
                "error": f"the server has {self.max_connections} connections open, the most it "
                "serves at once; try again"
            }
        ).encode()
        head = (
            "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
            f"Content-Length: {len(body)}\r\nRetry-After: 1\r\nConnection: close\r\n\r\n"
        )
        try:
            request.settimeout(0)  # never wait on this client: the accepting thread is ours
            with contextlib.suppress(BlockingIOError):
                request.recv(65536)  # what it sent already: closing on unread data resets
            request.sendall(head.encode() + body)
        except OSError:
            pass
        self.shutdown_request(request)
        self.count("refused")

    def handle_error(self, request: object, client_address: tuple) -> None:
        """A connection that failed (reset, timed out): one line in the log, no traceback."""
        exc = sys.exc_info()[1]
        if self.log is not None:
            self.log.write(
                f"parmor blocks: {client_address[0]} connection failed: "
                f"{type(exc).__name__}: {exc}\n"
            )
            self.log.flush()

    def server_close(self) -> None:
        self.runner.stop()
        super().server_close()


class Handler(BaseHTTPRequestHandler):
    server: BlocksServer
    server_version = "parmor-blocks"
    protocol_version = "HTTP/1.1"

    def setup(self) -> None:
        self.timeout = self.server.socket_timeout  # StreamRequestHandler sets it on the socket
        super().setup()
        self.deadline = math.inf
        self.rfile = io.BufferedReader(_Deadline(self), 65536)

    def handle_one_request(self) -> None:
        # the whole request (line, headers, body) arrives within request_timeout s
        self.deadline = time.monotonic() + self.server.request_timeout
        try:
            super().handle_one_request()
        finally:
            self.deadline = math.inf

    def late(self) -> bool:
        """Whether the request's time is up (not only one read's silence)."""
        return time.monotonic() >= self.deadline

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 (the base's name)
        log = self.server.log
        if log is not None:
            log.write(f"parmor blocks: {self.address_string()} {format % args}\n")
            log.flush()

    def _send(self, status: HTTPStatus, body: bytes, ctype: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: HTTPStatus, obj: Mapping) -> None:
        self._send(status, json.dumps(obj).encode(), "application/json")

    def _error(self, status: HTTPStatus, message: str) -> None:
        self._json(status, {"error": message})

    def _foreign(self) -> bool:
        """Answer 403 and True for a request another site's page makes through the
        browser (its Host or Origin is not this server's: DNS rebinding, cross-site posts)."""
        port = self.server.server_address[1]
        ours = {f"{HOST}:{port}", f"localhost:{port}"}
        host = self.headers.get("Host", "")
        origin = self.headers.get("Origin")
        if host in ours and (origin is None or urlsplit(origin).netloc in ours):
            return False
        self._drain()
        self._error(HTTPStatus.FORBIDDEN, "requests from other sites are refused")
        return True

    # -- files ---------------------------------------------------------------------------

    def do_GET(self) -> None:
        if self._foreign():
            return
        path = unquote(urlsplit(self.path).path)
        if path in ("/", "/index.html"):
            self.send_response(HTTPStatus.FOUND)
            self.send_header("Location", "/blocks/index.html")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        parts = [p for p in path.split("/") if p]
        if len(parts) < 2 or parts[0] not in SERVED_DIRS or any(p in (".", "..") for p in parts):
            self._error(HTTPStatus.NOT_FOUND, f"no such page: {path}")
            return
        root = (self.server.bundle / parts[0]).resolve()
        file = root.joinpath(*parts[1:]).resolve()
        if not file.is_relative_to(root) or not file.is_file():
            self._error(HTTPStatus.NOT_FOUND, f"no such file: {path}")
            return
        ctype = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        if file.suffix in (".js", ".mjs"):
            ctype = "text/javascript"
        self._send(HTTPStatus.OK, file.read_bytes(), ctype)

    do_HEAD = do_GET

    # -- runs ----------------------------------------------------------------------------

    def do_POST(self) -> None:
        if self._foreign():
            return
        if urlsplit(self.path).path != "/run":
            self._drain()
            self._error(HTTPStatus.NOT_FOUND, f"no such action: {self.path}")
            return
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            self.close_connection = True
            self._error(HTTPStatus.LENGTH_REQUIRED, "the request has no Content-Length")
            return
        if length < 0 or length > MAX_BODY:
            self._drain(length)
            self._error(
                HTTPStatus.REQUEST_ENTITY_TOO_LARGE,
                f"the program is too large: {length} bytes (at most {MAX_BODY})",
            )
            return
        try:
            raw = self.rfile.read(length)
        except TimeoutError:
            self.close_connection = True
            limit = self.server.request_timeout if self.late() else self.server.socket_timeout
            self._error(
                HTTPStatus.REQUEST_TIMEOUT, f"the program did not arrive within {limit:g} s"
            )
            return
        if len(raw) < length:
            self.close_connection = True
            return  # the client closed the connection before sending it all: nobody to answer

        try:
            program = parse(raw.decode("utf-8"))
        except UnicodeDecodeError as e:
            self._error(HTTPStatus.BAD_REQUEST, f"the program is not UTF-8 text (byte {e.start})")
            return
        except JsonError as e:
            what = "the program is not JSON" if e.syntax else "the program"
            self._error(HTTPStatus.BAD_REQUEST, f"{what}: line {e.line} column {e.col}: {e.reason}")
            return
        try:
            self.server.validate(program)
        except ProgramError as e:
            self._error(HTTPStatus.UNPROCESSABLE_ENTITY, str(e))
            return
        except Exception as e:  # a bug in the validation: say so, keep serving
            self.log_message("validation failed: %s: %s", type(e).__name__, e)
            self._error(
                HTTPStatus.INTERNAL_SERVER_ERROR,
                f"the program could not be checked: {type(e).__name__}: {e}",
            )
            return
        try:
            reply = self.server.runner.run(program)
        except RunFailed as e:
            self._error(e.status, str(e))
            return
        except Exception as e:  # a bug: an error reply, and the server keeps serving
            self.log_message("run failed: %s: %s", type(e).__name__, e)
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"the run failed: {e}")
            return
        self._send(HTTPStatus.OK, reply, "application/json")

    def _drain(self, length: int | None = None) -> None:
        """Read and drop the request body (so the client gets the reply), or close the
        connection when it is larger than MAX_DRAIN."""
        if length is None:
            try:
                length = int(self.headers.get("Content-Length", "0"))
            except ValueError:
                length = -1
        if length < 0 or length > MAX_DRAIN:
            self.close_connection = True
            return
        while length > 0:
            chunk = self.rfile.read(min(length, 65536))
            if not chunk:
                break
            length -= len(chunk)


class _Deadline(io.RawIOBase):
    """The connection's socket read within the handler's deadline: each read waits for
    the socket timeout at most, and never past the deadline (then TimeoutError, as a
    silent socket gives); writes keep the socket timeout."""

    def __init__(self, handler: Handler) -> None:
        self.handler = handler
        self.sock: socket.socket = handler.connection

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        h = self.handler
        left = h.deadline - time.monotonic()
        if left <= 0:
            h.server.count("timed_out")
            raise TimeoutError("the request took too long to arrive")
        self.sock.settimeout(min(left, h.server.socket_timeout))
        try:
            return self.sock.recv_into(buffer)
        except TimeoutError:
            h.server.count("timed_out")
            raise
        finally:
            with contextlib.suppress(OSError):
                self.sock.settimeout(h.server.socket_timeout)


def serve(
    bundle: str | Path,
    port: int = DEFAULT_PORT,
    time_limit: float = DEFAULT_TIME_LIMIT,
    max_runs: int | None = None,
    out: TextIO | None = None,
    log: TextIO | None = None,
) -> None:
    """Serve the bundle's block page on 127.0.0.1:``port`` (0: a free port) until Ctrl-C.
    Prints the page's address on ``out`` once it listens."""
    out = out or sys.stdout
    check_time_limit(time_limit)
    try:
        server = BlocksServer(Path(bundle), port, time_limit, max_runs, log)
    except OSError as e:
        raise InputError(f"cannot listen on {HOST}:{port}: {e.strerror or e}") from None
    try:
        host, real_port = server.server_address[:2]
        out.write(f"serving the block page on http://{host}:{real_port}/ (Ctrl-C stops)\n")
        out.flush()
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
