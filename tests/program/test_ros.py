"""``parmor ros DIR``: the generated ROS 1 package, its worker, and the node run for real.

The first tests need no ROS. The others start ``rosmaster`` on a free loopback port (one
per module), launch the generated node of a hexapod, a snake, a differential drive and a
3-DOF arm (the arm's with ``roslaunch``, the snake's with this interpreter, which has no
rospy, the others directly with the ROS Python), call
every service with ``rosservice call`` and from a rospy client run by the ROS Python, and
compare the published trajectory and joint states with ``Controller.run``'s. They skip
where ROS 1 is absent and fail under CI=true.
"""

from __future__ import annotations

import io
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import xmlrpc.client
from pathlib import Path

import numpy as np
import pytest

from gaits import controller_for
from gaits.base import DesignGeometry
from program.ros import interface, robot_name, srv_text, type_name
from program.rosworker import Worker, serve
from synth.commands.cli import main
from tests.conftest import REPO, need
from tests.synth.verification.test_mobile_manipulator import KIF_DESIGNS, kif_args

#: The acceptance designs: name -> ``parmor design`` arguments (README's requests).
DESIGNS = {
    "hexapod": ["walking", "--answer", "grasping=no", "--answer", "rough-terrain-walking=yes"],
    "snake": ["sidewinding"],
    "cart": ["driving"],
    "arm": ["pick-and-place", "--param", "object_shape=cylinder"],
    **KIF_DESIGNS,  # KIF-only types: a pentapod, a mobile manipulator
}
#: Longest wait for a process to come up or answer, s (a loaded 2-core machine).
WAIT_S = 90.0


def parmor(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main(list(argv), out=out, err=err)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def bundles(tmp_path_factory) -> dict[str, Path]:
    """The four acceptance designs (unverified: the ROS layer does not simulate)."""
    root = tmp_path_factory.mktemp("designs")
    out = {}
    for name, args in DESIGNS.items():
        code, _, err = parmor(
            "design", *kif_args(args, root), "--no-verify", "--no-input", "--out", str(root / name)
        )
        assert code == 0, err
        out[name] = root / name
    return out


@pytest.fixture(scope="module")
def packages(bundles) -> dict[str, tuple[Path, dict]]:
    """name -> (package folder, interface) of ``parmor ros`` on each design."""
    out = {}
    for name, folder in bundles.items():
        code, text, err = parmor("ros", str(folder), "--json")
        assert code == 0, err
        path = Path(json.loads(text)["package"])
        out[name] = (path, json.loads((path / "interface.json").read_text()))
    return out


def controller_of(package: Path):
    record = json.loads((package / "design.json").read_text())
    return controller_for(DesignGeometry.from_record(record))


# --- without ROS ------------------------------------------------------------------------------


def test_names() -> None:
    assert robot_name("HexapodRobot") == "hexapod_robot"
    assert robot_name("Manipulator3DOF") == "manipulator_3dof"
    assert robot_name("DifferentialDriveRobot") == "differential_drive_robot"
    assert type_name("pick-and-place") == "PickAndPlace"
    assert type_name("rough-terrain-walking") == "RoughTerrainWalking"


def test_one_service_per_listed_behaviour_with_typed_fields(packages) -> None:
    for path, iface in packages.values():
        controller = controller_of(path)
        record = json.loads((path / "design.json").read_text())
        listed = controller.listed(record["abilities"])
        assert [s["behavior"] for s in iface["services"]] == listed
        for s in iface["services"]:
            spec = controller.behaviors[s["behavior"]]
            assert s["service"] == s["behavior"].replace("-", "_")
            assert [f["param"] for f in s["request"]] == [p.name for p in spec.params]
            text = (path / "srv" / f"{s['type']}.srv").read_text()
            assert text == srv_text(s)
            request, response = text.split("\n---\n")
            for p in spec.params:
                ros = {"float": "float64", "int": "int64", "choice": "string"}[p.kind]
                assert f"\n{ros} {p.name}\n" in request
                if p.unit:
                    assert f"# {p.name} [{p.unit}]:" in request
                if p.kind == "choice":
                    assert f"one of: {', '.join(p.choices)}" in request
                else:
                    assert f"{p.name.upper()}_DEFAULT={p.default!r}" in request
                    if p.high is not None:
                        assert f"{p.name.upper()}_MAX={p.high!r}" in request
            for line in ("bool ok", "string message", "float64 duration_s"):
                assert line in response
            keys = {f["key"] for f in s["response"]}
            assert "motion" in keys  # every behaviour of these four promises a motion
        assert (path / "nodes" / "parmor_node").stat().st_mode & 0o111
        assert (
            "package://" + iface["package"] + "/meshes/" in (path / "urdf/robot.urdf").read_text()
        )
        for mesh in (path / "meshes").iterdir():
            assert mesh.read_bytes() == (path.parents[1] / "meshes" / mesh.name).read_bytes()


def test_package_is_byte_identical_and_replaced_only_with_force(bundles, tmp_path) -> None:
    folder = tmp_path / "cart"
    shutil.copytree(bundles["cart"], folder, ignore=shutil.ignore_patterns("ros"))
    assert parmor("ros", str(folder))[0] == 0
    pkg = folder / "ros" / "parmor_differential_drive_robot"
    first = {p.relative_to(pkg): p.read_bytes() for p in pkg.rglob("*") if p.is_file()}
    code, _, err = parmor("ros", str(folder))
    assert code == 2 and "--force" in err and "Traceback" not in err
    assert parmor("ros", str(folder), "--force")[0] == 0
    again = {p.relative_to(pkg): p.read_bytes() for p in pkg.rglob("*") if p.is_file()}
    assert again == first
    assert sorted(p.name for p in (folder / "ros").iterdir()) == [pkg.name]  # no temp folder


def test_bad_bundles_exit_2_and_write_nothing(bundles, tmp_path) -> None:
    code, _, err = parmor("ros", str(tmp_path / "nothing"))
    assert code == 2 and "no design.json" in err and "Traceback" not in err
    conceptual = tmp_path / "conceptual"
    assert parmor("design", "driving", "--conceptual", "--out", str(conceptual))[0] == 0
    code, _, err = parmor("ros", str(conceptual))
    assert code == 2 and "no structure" in err and not (conceptual / "ros").exists()
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "design.json").write_text("[1, 2")
    code, _, err = parmor("ros", str(broken))
    assert code == 2 and "design.json" in err
    no_mesh = tmp_path / "no_mesh"
    shutil.copytree(bundles["arm"], no_mesh, ignore=shutil.ignore_patterns("ros"))
    next((no_mesh / "meshes").iterdir()).unlink()
    code, _, err = parmor("ros", str(no_mesh))
    assert code == 2 and "meshes/" in err and not (no_mesh / "ros").exists()
    code, _, err = parmor("ros", str(bundles["cart"]), "--name", "Bad-Name")
    assert code == 2 and "ROS name" in err


def test_a_behaviour_its_controller_cannot_plan_is_an_error(bundles, tmp_path, monkeypatch) -> None:
    """A case built to fail: the controller refuses turning with every value tried."""
    from gaits.base import Controller

    run = Controller.run

    def refusing(self, name, **params):
        if name == "turning":
            raise ValueError("turning refused for the test")
        return run(self, name, **params)

    monkeypatch.setattr(Controller, "run", refusing)
    folder = tmp_path / "cart"
    shutil.copytree(bundles["cart"], folder, ignore=shutil.ignore_patterns("ros"))
    code, _, err = parmor("ros", str(folder))
    assert code == 2 and "turning: cannot be planned" in err and "refused for the test" in err
    assert not (folder / "ros").exists()


def test_worker_answers_plans_refusals_and_malformed_lines(packages) -> None:
    path, iface = packages["arm"]
    worker = Worker.load(path)
    assert worker.mismatch() is None
    controller = controller_of(path)
    service = next(s for s in iface["services"] if s["behavior"] == "positioning")
    fields = {f["field"]: f["default"] for f in service["request"]}
    fields["x"] = float("nan")  # NaN: the default
    reply = worker.call({"service": "positioning", "fields": fields})
    want = controller.run("positioning")
    assert reply["ok"] and reply["response"]["duration_s"] == want.duration
    assert np.array_equal(reply["trajectory"]["positions"], want.positions)
    assert reply["response"]["target"] == [float(v) for v in want.info["target"]]
    bad = worker.call({"service": "positioning", "fields": fields | {"z": 2.0}})
    assert not bad["ok"] and "trajectory" not in bad
    message = bad["response"]["message"]
    assert message.startswith("positioning: z: 2 ") and "[0.04, 0.35]" in message  # issue 24
    assert set(bad["response"]) == set(reply["response"])  # every response field, emptied
    lines = io.StringIO('{"service": "nope"}\nnot json\n\n{"service": "positioning"}\n')
    out = io.StringIO()
    serve(worker, lines, out)
    replies = [json.loads(x) for x in out.getvalue().splitlines()]
    assert [r["ok"] for r in replies] == [False, False, True]
    assert "no service" in replies[0]["response"]["message"]
    assert "malformed" in replies[1]["response"]["message"]


def test_worker_refuses_a_package_the_controller_no_longer_matches(packages) -> None:
    path, iface = packages["cart"]
    record = json.loads((path / "design.json").read_text())
    changed = json.loads(json.dumps(iface))
    changed["services"][0]["request"][0]["param"] = "velocity"
    assert "parameters" in Worker(changed, record).mismatch()
    changed = json.loads(json.dumps(iface)) | {"format": 0}
    assert "format" in Worker(changed, record).mismatch()


def test_response_fields_leave_out_per_sample_arrays(packages) -> None:
    path, iface = packages["hexapod"]
    walking = next(s for s in iface["services"] if s["behavior"] == "walking")
    keys = {f["key"]: f["ros"] for f in walking["response"]}
    assert keys["planned_pose"] == "float64[]" and keys["motion"] == "string"
    assert "stability_margin_m" in walking["left_out"] and "body_path" in walking["left_out"]
    assert (
        interface(json.loads((path / "design.json").read_text())) | {"worker": iface["worker"]}
        == iface
    )


# --- with ROS ---------------------------------------------------------------------------------


def ros_python() -> str:
    """The interpreter of the ROS tools (the shebang of ``rosmaster``); skips without ROS
    (fails under CI=true)."""
    tool = shutil.which("rosmaster")
    why = "rosmaster is absent (apt-get install python3-rosmaster python3-rospy ...)"
    if tool is not None:
        first = Path(tool).read_text(errors="replace").splitlines()[0]
        python = first[2:].strip().split()[-1] if first.startswith("#!") else ""
        if python and shutil.which("rosservice") and shutil.which("roslaunch"):
            check = subprocess.run(
                [python, "-c", "import rospy, genpy, trajectory_msgs.msg, sensor_msgs.msg"],
                capture_output=True,
            )
            if check.returncode == 0:
                return python
        why = "rospy, genpy or the message packages are missing for the ROS Python"
    need(False, why)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(what: str, ready, proc: subprocess.Popen | None = None, log: Path | None = None):
    end = time.monotonic() + WAIT_S
    while time.monotonic() < end:
        value = ready()
        if value:
            return value
        if proc is not None and proc.poll() is not None:
            break
        time.sleep(0.2)
    text = log.read_text(errors="replace")[-3000:] if log and log.exists() else ""
    pytest.fail(f"{what} did not come up\n{text}")


class Ros:
    """A rosmaster on a free loopback port and the processes started against it."""

    def __init__(self, python: str, home: Path) -> None:
        self.python, self.home = python, home
        self.uri = f"http://127.0.0.1:{free_port()}"
        self.env = {k: v for k, v in os.environ.items() if not k.startswith(("ROS", "PYTHON"))}
        self.env |= {
            "ROS_MASTER_URI": self.uri,
            "ROS_HOSTNAME": "127.0.0.1",
            "ROS_HOME": str(home),
            "ROS_LOG_DIR": str(home / "log"),
        }
        self.procs: list[subprocess.Popen] = []
        self.master = self.start(
            ["rosmaster", "--core", "-p", self.uri.rsplit(":", 1)[1]], "master"
        )
        proxy = xmlrpc.client.ServerProxy(self.uri)

        def up() -> bool:
            try:
                return proxy.getPid("/test")[0] == 1
            except OSError:
                return False

        wait_for("rosmaster", up, self.master, home / "master.log")

    def package_env(self, package: Path) -> dict[str, str]:
        """The environment ``source package/setup.bash`` gives."""
        return self.env | {
            "ROS_PACKAGE_PATH": str(package.parent),
            "PYTHONPATH": str(package / "src"),
        }

    def start(self, argv: list[str], log: str, env: dict | None = None) -> subprocess.Popen:
        out = open(self.home / f"{log}.log", "w")  # noqa: SIM115 - closed with the process
        proc = subprocess.Popen(
            argv,
            env=env or self.env,
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        out.close()
        self.procs.append(proc)
        return proc

    def has_service(self, name: str) -> bool:
        try:
            return xmlrpc.client.ServerProxy(self.uri).lookupService("/test", name)[0] == 1
        except OSError:
            return False

    def stop(self, proc: subprocess.Popen) -> None:
        """SIGINT (rospy and roslaunch shut down cleanly), then SIGKILL to its group."""
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()

    def close(self) -> None:
        for proc in reversed(self.procs):
            self.stop(proc)


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (Linux /proc)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                kids = [int(x) for x in (task / "children").read_text().split()]
            except OSError:
                kids = []
            out += kids
            todo += kids
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.fixture(scope="module")
def ros(packages, tmp_path_factory):
    """The master and the four nodes (the arm's through roslaunch), all serving."""
    python = ros_python()
    home = tmp_path_factory.mktemp("roshome")
    (home / "log").mkdir()
    r = Ros(python, home)
    r.nodes = {}
    try:
        for name, (path, iface) in packages.items():
            env = r.package_env(path)
            node = str(path / "nodes" / "parmor_node")
            if name == "arm":
                argv = ["roslaunch", iface["package"], "parmor.launch"]
            elif name == "snake":  # an interpreter without rospy: the node finds the ROS one
                argv = [sys.executable, node]
            else:
                argv = [python, node]
            r.nodes[name] = r.start(argv, f"node-{name}", env)
        for name, (_, iface) in packages.items():
            for s in iface["services"]:
                name_ = f"/{iface['robot']}/{s['service']}"
                wait_for(
                    name_,
                    lambda n=name_: r.has_service(n),
                    r.nodes[name],
                    home / f"node-{name}.log",
                )
        yield r
    finally:
        r.close()


CLIENT = r'''
"""rospy client: calls services, collects the published trajectory and joint states."""
import json, sys, threading, time
import rospy
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

job = json.load(sys.stdin)
srv = __import__(job["package"] + ".srv", fromlist=["*"])
rospy.init_node("parmor_test_client", anonymous=True)
lock = threading.Lock()
trajectories, states = [], []
def on_traj(m):
    with lock: trajectories.append(m)
def on_state(m):
    with lock: states.append(m)
rospy.Subscriber("/%s/joint_trajectory" % job["robot"], JointTrajectory, on_traj)
rospy.Subscriber("/%s/joint_states" % job["robot"], JointState, on_state)
for call in job["calls"]:
    name = "/%s/%s" % (job["robot"], call["service"])
    rospy.wait_for_service(name, timeout=90)
    proxy = rospy.ServiceProxy(name, getattr(srv, call["type"]))
    before = rospy.Time.now()
    request = getattr(srv, call["type"] + "Request")(**call["fields"])
    reply = proxy(request)
    out = {"service": call["service"], "response": {k: getattr(reply, k) for k in reply.__slots__}}
    if reply.ok:
        end = time.monotonic() + 90
        traj = None
        while traj is None and time.monotonic() < end:
            with lock:
                new = [m for m in trajectories if m.header.stamp >= before]
            traj = new[-1] if new else None
            time.sleep(0.05)
        start = traj.header.stamp
        wait = time.monotonic() + 90
        while time.monotonic() < wait:
            with lock:
                got = [m for m in states if m.header.stamp >= start]
            if len(got) >= 3:
                break
            time.sleep(0.05)
        out["trajectory"] = {
            "joints": list(traj.joint_names),
            "times": [p.time_from_start.to_sec() for p in traj.points],
            "positions": [list(p.positions) for p in traj.points],
            "velocities": [list(p.velocities) for p in traj.points],
        }
        out["states"] = [
            {"t": (m.header.stamp - start).to_sec(), "name": list(m.name),
             "position": list(m.position), "velocity": list(m.velocity)}
            for m in got[:3]
        ]
    print(json.dumps(out), flush=True)
'''


def varied(service: dict, controller) -> dict:
    """Request fields off the defaults: another choice, floats at 0.9 x their default."""
    spec = controller.behaviors[service["behavior"]]
    fields = {}
    for f, p in zip(service["request"], spec.params, strict=True):
        if p.kind == "choice":
            fields[f["field"]] = next((c for c in p.choices if c != p.default), p.default)
        elif p.kind == "float" and p.default:
            fields[f["field"]] = 0.9 * float(p.default)
        else:
            fields[f["field"]] = p.default
    return fields


def check_reply(out: dict, service: dict, controller, fields: dict) -> None:
    """The reply and what was published match ``Controller.run`` with those fields."""
    params = {f["param"]: fields[f["field"]] for f in service["request"]}
    try:
        want = controller.run(service["behavior"], **params)
    except ValueError as e:
        assert not out["response"]["ok"] and str(e) in out["response"]["message"]
        return
    response = out["response"]
    assert response["ok"], response["message"]
    assert response["duration_s"] == pytest.approx(want.duration, abs=1e-9)
    for f in service["response"]:
        value = want.info.get(f["key"])
        got = response[f["field"]]
        if f["ros"] in ("float64", "int64") and value is not None:
            assert got == pytest.approx(float(value), abs=1e-9), f["key"]
        elif f["ros"] == "float64[]" and value is not None:
            assert np.allclose(got, np.ravel(value), atol=1e-9), f["key"]
        elif f["ros"] in ("string", "bool") and value is not None:
            assert got == value, f["key"]
    traj = out["trajectory"]
    assert traj["joints"] == list(want.joints)
    assert np.allclose(traj["times"], want.times, atol=1e-6, rtol=0)
    assert np.allclose(traj["positions"], want.positions, atol=1e-6, rtol=0)
    assert np.allclose(traj["velocities"], want.velocities, atol=1e-6, rtol=0)
    assert out["states"], "no joint states"
    for s in out["states"]:
        q, v = want.at(s["t"])
        assert s["name"] == list(want.joints)
        assert np.allclose(s["position"], q, atol=1e-6, rtol=0)
        assert np.allclose(s["velocity"], v, atol=1e-6, rtol=0)


def run_client(ros: Ros, path: Path, iface: dict, calls: list[dict]) -> list[dict]:
    job = {"package": iface["package"], "robot": iface["robot"], "calls": calls}
    script = ros.home / "client.py"
    script.write_text(CLIENT)
    proc = subprocess.run(
        [ros.python, str(script)],
        input=json.dumps(job),
        capture_output=True,
        text=True,
        env=ros.package_env(path),
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]


@pytest.mark.parametrize("name", list(DESIGNS))
def test_rospy_client_gets_the_controllers_trajectories(ros, packages, name) -> None:
    path, iface = packages[name]
    controller = controller_of(path)
    calls, expected = [], []
    for s in iface["services"]:
        fields = varied(s, controller)
        calls.append({"service": s["service"], "type": s["type"], "fields": fields})
        expected.append((s, fields))
    # a value beyond its range: an error reply naming it; the node then still answers
    first = iface["services"][0]
    bad = next(f for f in first["request"] if f["high"] is not None)
    bad_fields = varied(first, controller) | {bad["field"]: bad["high"] + 1}
    calls.append({"service": first["service"], "type": first["type"], "fields": bad_fields})
    calls.append(calls[0])
    outs = run_client(ros, path, iface, calls)
    assert len(outs) == len(calls)
    for out, (s, fields) in zip(outs, expected, strict=False):
        check_reply(out, s, controller, fields)
    refused = outs[len(expected)]["response"]
    assert not refused["ok"] and refused["duration_s"] == 0
    value, high = bad["high"] + 1, bad["high"]
    assert f"{bad['field']}: {value:g} is outside" in refused["message"]
    assert f"{high:g}]" in refused["message"]
    check_reply(outs[-1], first, controller, calls[0]["fields"])
    assert ros.nodes[name].poll() is None


def yaml_scalar(text: str) -> object:
    text = text.strip()
    if text in ("True", "False"):
        return text == "True"
    try:
        return float(text)
    except ValueError:
        return text.strip("'\"")


@pytest.mark.parametrize("name", list(DESIGNS))
def test_rosservice_call_with_defaults(ros, packages, name) -> None:
    """Every service from the command line, every field at its default (floats as NaN,
    choices empty: the defaults the .srv comments name)."""
    path, iface = packages[name]
    controller = controller_of(path)
    calls = {}
    for s in iface["services"]:  # all at once: each waits on the node, not on the others
        fields = {
            f["field"]: (
                ".nan" if f["ros"] == "float64" else "''" if f["ros"] == "string" else f["default"]
            )
            for f in s["request"]
        }
        arg = "{" + ", ".join(f"{k}: {v}" for k, v in fields.items()) + "}"
        calls[s["service"]] = subprocess.Popen(
            ["rosservice", "call", f"/{iface['robot']}/{s['service']}", arg],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=ros.package_env(path),
        )
    for s in iface["services"]:
        out, err = calls[s["service"]].communicate(timeout=120)
        assert calls[s["service"]].returncode == 0, err
        reply = {}
        for line in out.splitlines():
            key, sep, value = line.partition(": ")
            if sep and not line.startswith(" "):
                reply[key] = yaml_scalar(value)
        want = controller.run(s["behavior"])
        assert reply["ok"] is True, out
        assert reply["duration_s"] == pytest.approx(want.duration, abs=1e-9)
        if "motion" in want.info:
            assert reply["motion"] == want.info["motion"]


def test_a_bad_choice_is_refused_from_the_command_line(ros, packages) -> None:
    path, iface = packages["hexapod"]
    proc = subprocess.run(
        ["rosservice", "call", f"/{iface['robot']}/walking", "{gait: galloping, steps: 2}"],
        capture_output=True,
        text=True,
        env=ros.package_env(path),
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "ok: False" in proc.stdout and "gait" in proc.stdout and "tripod" in proc.stdout


def test_stopping_a_node_ends_its_worker(ros) -> None:
    node = ros.nodes["snake"]
    below = descendants(node.pid)
    assert below, "the node started no worker"
    ros.stop(node)
    end = time.monotonic() + WAIT_S
    while any(alive(p) for p in below) and time.monotonic() < end:
        time.sleep(0.1)
    assert not any(alive(p) for p in below)


SLOW_WORKER = '''"""A parmor worker that hangs on turning by 0.5 rad (the node's time limit)."""
import sys
import time

from program import rosworker

_call = rosworker.Worker.call


def call(self, request):
    if request.get("service") == "turning" and request.get("fields", {}).get("angle") == 0.5:
        time.sleep(3600)
    return _call(self, request)


rosworker.Worker.call = call
if __name__ == "__main__":
    sys.exit(rosworker.main())
'''


def test_a_plan_beyond_the_time_limit_restarts_the_worker(ros, bundles, tmp_path) -> None:
    """PARMOR_PYTHON and PARMOR_PYTHONPATH choose the worker; a worker that hangs is killed
    after ``~plan_timeout`` s, the call gets an error reply, and the next call a new worker."""
    folder = tmp_path / "cart"
    shutil.copytree(bundles["cart"], folder, ignore=shutil.ignore_patterns("ros"))
    assert parmor("ros", str(folder), "--name", "slow_cart")[0] == 0
    path = folder / "ros" / "parmor_slow_cart"
    iface = json.loads((path / "interface.json").read_text())
    iface["worker"] = {"python": "/nonexistent/python", "module": "slowworker"}
    (path / "interface.json").write_text(json.dumps(iface))
    (tmp_path / "slowworker.py").write_text(SLOW_WORKER)
    env = ros.package_env(path) | {
        "PARMOR_PYTHON": sys.executable,
        "PARMOR_PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)]),
    }
    node = ros.start(
        [ros.python, str(path / "nodes" / "parmor_node"), "_plan_timeout:=5"], "slow", env
    )
    for s in iface["services"]:
        wait_for(s["service"], lambda s=s: ros.has_service(f"/slow_cart/{s['service']}"), node)
    first = descendants(node.pid)
    assert len(first) == 1
    turning = next(s for s in iface["services"] if s["service"] == "turning")
    calls = [
        {"service": "turning", "type": turning["type"], "fields": {"angle": a, "seconds": 0.0}}
        for a in (0.5, 1.0)
    ]
    hung, answered = run_client(ros, path, iface, calls)
    assert not hung["response"]["ok"] and "no answer within 5 s" in hung["response"]["message"]
    check_reply(answered, turning, controller_of(path), calls[1]["fields"])
    assert not alive(first[0])
    assert len(descendants(node.pid)) == 1 and node.poll() is None
    ros.stop(node)


def test_the_launch_file_runs_the_node(ros, packages) -> None:
    """The arm's node was started by roslaunch: its services answered above; the launch
    set robot_description from the package's URDF."""
    _, iface = packages["arm"]
    proxy = xmlrpc.client.ServerProxy(ros.uri)
    code, _, urdf = proxy.getParam("/test", "/robot_description")
    assert code == 1 and urdf.startswith("<?xml") and f"package://{iface['package']}/" in urdf
    assert ros.nodes["arm"].poll() is None
    assert sys.executable == iface["worker"]["python"]
    assert math.isfinite(iface["plan_timeout_s"])


def worker_pids(root: int) -> list[int]:
    """The parmor workers below process ``root``."""
    out = []
    for pid in descendants(root):
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"program.rosworker" in cmdline and alive(pid):
            out.append(pid)
    return out


def test_a_worker_that_died_is_replaced_and_roslaunch_stops_quietly(ros, bundles, tmp_path):
    """Cases built to fail: the worker killed while idle (SIGKILL), then ended by SIGTERM;
    each next call starts a new worker and is answered. roslaunch's shutdown (SIGINT to the
    node's process group, the worker included) leaves no traceback in the log."""
    folder = tmp_path / "cart"
    shutil.copytree(bundles["cart"], folder, ignore=shutil.ignore_patterns("ros"))
    assert parmor("ros", str(folder), "--name", "phoenix_cart")[0] == 0
    path = folder / "ros" / "parmor_phoenix_cart"
    env = ros.package_env(path)
    launch = ros.start(["roslaunch", "parmor_phoenix_cart", "parmor.launch"], "phoenix", env)
    log = ros.home / "phoenix.log"
    wait_for("turning", lambda: ros.has_service("/phoenix_cart/turning"), launch, log)

    def call() -> str:
        proc = subprocess.run(
            ["rosservice", "call", "/phoenix_cart/turning", "{angle: 0.5, seconds: 0.0}"],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
        return proc.stdout

    assert "ok: True" in call()
    for sig in (signal.SIGKILL, signal.SIGTERM):
        (worker,) = wait_for("the worker", lambda: worker_pids(launch.pid), launch, log)
        os.kill(worker, sig)
        end = time.monotonic() + WAIT_S
        while alive(worker) and time.monotonic() < end:
            time.sleep(0.1)
        assert not alive(worker)
        reply = call()
        assert "ok: True" in reply, reply
        assert worker not in worker_pids(launch.pid)
    assert launch.poll() is None
    ros.stop(launch)
    assert launch.returncode is not None
    text = log.read_text(errors="replace")
    for word in ("Traceback", "KeyboardInterrupt", "Broken pipe", "BrokenPipeError"):
        assert word not in text, text[-3000:]
