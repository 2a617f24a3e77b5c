"""The parmor side of a generated ROS node: it plans the behaviours the node serves.

``python -m program.rosworker PACKAGE_DIR`` reads the package's ``interface.json`` and
``design.json`` (written by ``parmor ros``), builds the design's controller as the
bundle's trajectories are planned (``gaits.controller_for``), and talks JSON lines over
stdin and stdout:

- first it writes ``{"ready": true, "robot": ..., "services": [...]}``, or
  ``{"ready": false, "message": ...}`` when the controller no longer offers what the
  package serves (parmor changed since: run ``parmor ros`` again);
- then, for each request line ``{"service": NAME, "fields": {FIELD: VALUE}}`` (the
  service request's fields), one reply line ``{"ok": bool, "response": {FIELD: VALUE},
  "trajectory": {"joints", "times", "positions", "velocities"}}`` (``trajectory`` only
  when ok; ``response`` holds every response field of the service, ``message`` the
  reason of a refusal: the field, its value and its range); the trajectory's
  ``feedback`` is the plan's feedback loop (``info["feedback"]``, :mod:`gaits.feedback`)
  or null;
- for each request line ``{"correct": {"t", "q", "qd", "gyro", "accel"}}`` (what the
  robot measured, ``t`` s into the last plan served), one reply line ``{"ok": true,
  "offsets": [...]}``: what that plan's loop adds to its commands (:meth:`Worker.correct`;
  the node sends one every control period while it plays a plan with a loop).

It ends at the end of its input, so it never outlives the node, and quietly when the node
is gone (its output closed). It ignores SIGINT: roslaunch sends it to the node's whole
process group on shutdown, and the node ends its worker itself (closes its input, or kills
it). A float field that is NaN and a string field that is empty take the parameter's
default.
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING

from gaits import controller_for
from gaits.base import DesignGeometry
from gaits.feedback import Attitude, Reading, loop_for
from program.ros import INTERFACE_FORMAT, MAX_POINTS
from synth.reasoning.plans import install

if TYPE_CHECKING:
    from gaits.base import Controller, Trajectory

#: Address space the worker may use, bytes (a plan beyond it is refused, not swapped).
MEMORY_LIMIT_BYTES = 4 * 1024**3

_EMPTY = {"string": "", "bool": False, "int64": 0, "float64": 0.0}


def _value(ros: str, value: object) -> object:
    """An info value as the response field type ``ros`` (its empty value if it is not)."""
    import numpy as np

    try:
        if ros.endswith("[]"):
            items = list(np.ravel(np.asarray(value, dtype=object)))
            return [str(v) for v in items] if ros == "string[]" else [float(v) for v in items]
        if ros == "string":
            return str(value)
        if ros == "bool":
            return bool(value)
        if ros == "int64":
            return int(value)  # type: ignore[call-overload]
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return [] if ros.endswith("[]") else _EMPTY[ros]


class Worker:
    """Plans the services of one generated package."""

    def __init__(self, iface: Mapping, record: Mapping) -> None:
        self.iface = iface
        self.services = {s["service"]: s for s in iface["services"]}
        self.controller: Controller = controller_for(DesignGeometry.from_record(record))
        #: the last plan served and its feedback loop (gaits.feedback), None when it has none
        self.plan: Trajectory | None = None
        self.loop = None
        self.attitude = None  # the IMU's attitude estimate, once the loop has read the IMU
        self.last_t: float | None = None

    @classmethod
    def load(cls, package: str | Path) -> Worker:
        package = Path(package)
        iface = json.loads((package / "interface.json").read_text(encoding="utf-8"))
        record = json.loads((package / "design.json").read_text(encoding="utf-8"))
        return cls(iface, record)

    def mismatch(self) -> str | None:
        """Why the controller does not offer what the package serves, or None."""
        if self.iface.get("format") != INTERFACE_FORMAT:
            return f"interface format {self.iface.get('format')!r}, expected {INTERFACE_FORMAT}"
        for s in self.iface["services"]:
            spec = self.controller.behaviors.get(s["behavior"])
            if spec is None:
                return f"the controller has no behaviour {s['behavior']!r} any more"
            have = [(p.name, p.kind) for p in spec.params]
            want = [(f["param"], f["kind"]) for f in s["request"]]
            if have != want:
                return f"{s['behavior']}: parameters {have} differ from the package's {want}"
        return None

    def params(self, service: Mapping, fields: Mapping[str, object]) -> dict[str, object]:
        """The behaviour's parameters from the request's fields (NaN and "": default)."""
        out: dict[str, object] = {}
        for f in service["request"]:
            v = fields.get(f["field"])
            if v is None or (isinstance(v, float) and math.isnan(v)):
                continue
            if f["ros"] == "string" and v == "":
                continue
            out[f["param"]] = v
        return out

    def response(self, service: Mapping, traj: Trajectory) -> dict[str, object]:
        rec: dict[str, object] = {"ok": True, "message": "", "duration_s": traj.duration}
        for f in service["response"]:
            if f["key"] in traj.info:
                rec[f["field"]] = _value(f["ros"], traj.info[f["key"]])
            else:
                rec[f["field"]] = [] if f["ros"].endswith("[]") else _EMPTY[f["ros"]]
        return rec

    def refusal(self, service: Mapping | None, message: str) -> dict:
        rec: dict[str, object] = {"ok": False, "message": message, "duration_s": 0.0}
        for f in service["response"] if service else ():
            rec[f["field"]] = [] if f["ros"].endswith("[]") else _EMPTY[f["ros"]]
        return {"ok": False, "response": rec}

    def correct(self, reading: object) -> dict:
        """The offsets the last plan's feedback loop adds to its commands for one reading of
        the robot's sensors (``{"t", "q", "qd", "gyro", "accel"}``: s since the plan's
        start, the plan's joints in its order, the IMU's rates and specific force or null):
        ``{"ok": true, "offsets": [...]}`` (zeros for a plan without a loop), the same
        :mod:`gaits.feedback` loop the verification ran, its attitude estimated by the
        same filter. A malformed reading is refused."""
        import numpy as np

        plan = self.plan
        if plan is None:
            return {"ok": False, "message": "no plan to correct: call a service first"}
        if not isinstance(reading, Mapping):
            return {"ok": False, "message": "correct: expected an object"}
        n = len(plan.joints)
        try:
            t = float(reading["t"])  # type: ignore[arg-type]
            q = np.asarray(reading["q"], dtype=float).reshape(n)
            qd = np.asarray(reading.get("qd") or np.zeros(n), dtype=float).reshape(n)
            gyro = reading.get("gyro")
            accel = reading.get("accel")
            gyro = None if gyro is None else np.asarray(gyro, dtype=float).reshape(3)
            accel = None if accel is None else np.asarray(accel, dtype=float).reshape(3)
        except (KeyError, TypeError, ValueError) as e:
            return {"ok": False, "message": f"correct: malformed reading: {e}"}
        if not (math.isfinite(t) and np.isfinite(q).all() and np.isfinite(qd).all()):
            return {"ok": False, "message": "correct: a reading is not finite"}
        if self.loop is None:
            return {"ok": True, "offsets": [0.0] * n}
        att = None
        if gyro is not None and accel is not None:
            if self.attitude is None:  # switched on level (the firmware's start-up levelling)
                self.attitude = Attitude()
                self.attitude.reset(np.array([1.0, 0.0, 0.0, 0.0]))
                att = self.attitude.q
            else:
                dt = max(0.0, t - (self.last_t if self.last_t is not None else t))
                att = self.attitude.update(gyro, accel, dt)
        r = Reading(t=t, q=q, qd=qd, gyro=gyro, accel=accel, attitude=att)
        if self.last_t is None:
            self.loop.reset(r)
        self.last_t = t
        return {"ok": True, "offsets": [float(x) for x in self.loop.correct(r)]}

    def call(self, request: Mapping) -> dict:
        """One reply (see the module docstring); never raises for a bad request."""
        if "correct" in request:
            return self.correct(request["correct"])
        service = self.services.get(str(request.get("service")))
        if service is None:
            return self.refusal(None, f"no service {request.get('service')!r}")
        fields = request.get("fields") or {}
        if not isinstance(fields, Mapping):
            return self.refusal(service, "fields: expected an object")
        try:
            traj = self.controller.run(service["behavior"], **self.params(service, fields))
        except ValueError as e:
            return self.refusal(service, f"{service['service']}: {e}")
        except MemoryError:
            return self.refusal(service, f"{service['service']}: the plan is too large")
        if len(traj.times) > MAX_POINTS:
            return self.refusal(
                service,
                f"{service['service']}: the trajectory has {len(traj.times)} points, more "
                f"than the {MAX_POINTS} one call may publish; ask for a shorter one",
            )

        try:
            loop = loop_for(traj)
        except ValueError as e:
            return self.refusal(service, f"{service['service']}: {e}")
        self.plan, self.loop, self.attitude, self.last_t = traj, loop, None, None
        feedback = traj.info.get("feedback")
        return {
            "ok": True,
            "response": self.response(service, traj),
            "trajectory": {
                "joints": list(traj.joints),
                "times": traj.times.tolist(),
                "positions": traj.positions.tolist(),
                "velocities": traj.velocities.tolist(),
                # the loop the node closes around it (None: the plan alone, open loop)
                "feedback": dict(feedback) if loop is not None else None,  # type: ignore[arg-type]
            },
        }


def serve(worker: Worker, lines: IO[str], out: IO[str]) -> None:
    """Answer each request line of ``lines`` with one line on ``out`` until EOF."""
    for line in lines:
        if not line.strip():
            continue
        try:
            request = json.loads(line)
            if not isinstance(request, dict):
                raise ValueError("expected an object")
        except ValueError as e:
            reply = worker.refusal(None, f"malformed request: {e}")
        else:
            try:
                reply = worker.call(request)
            except Exception as e:  # noqa: BLE001 - the node must get an answer and go on
                reply = worker.refusal(
                    worker.services.get(str(request.get("service"))),
                    f"internal error: {type(e).__name__}: {e}",
                )
        out.write(json.dumps(reply) + "\n")
        out.flush()


def _limit_memory() -> None:
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = (
            MEMORY_LIMIT_BYTES if hard == resource.RLIM_INFINITY else min(hard, MEMORY_LIMIT_BYTES)
        )
        if soft == resource.RLIM_INFINITY or soft > limit:
            resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    out = sys.stdout
    sys.stdout = sys.stderr  # only protocol lines go to the node
    if len(args) != 1:
        out.write(json.dumps({"ready": False, "message": "usage: rosworker PACKAGE_DIR"}) + "\n")
        return 2
    _quiet_signals()
    _limit_memory()

    install()  # the shipped ontology's body plans (a bundle older than recorded plans)
    try:
        worker = Worker.load(args[0])
        why = worker.mismatch()
    except (OSError, KeyError, TypeError, ValueError) as e:
        why = f"cannot load the package {args[0]}: {type(e).__name__}: {e}"
    if why is not None:
        out.write(json.dumps({"ready": False, "message": why}) + "\n")
        out.flush()
        return 2
    hello = {"ready": True, "robot": worker.iface["robot"], "services": sorted(worker.services)}
    try:
        out.write(json.dumps(hello) + "\n")
        out.flush()
        serve(worker, sys.stdin, out)
    except BrokenPipeError:  # the node is gone: nobody to answer; end without a word
        _drop_output(out)
    return 0


def _quiet_signals() -> None:
    """SIGINT ignored (the node ends its worker; see the module docstring), SIGTERM the
    default (end at once, no traceback)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _drop_output(out: IO[str]) -> None:
    """Point ``out``'s descriptor at /dev/null, so that the interpreter's last flush of
    what is still buffered for a closed pipe does not print an error."""
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, out.fileno())
        os.close(null)
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())
