"""The ROS node closes the plan's feedback loop on the robot's read-back (issue 30, item 4),
under the real ROS 1 (rosmaster, rospy): a plan that asks for a loop gets the loop's
corrections on ``joint_commands`` once the servos' read-back arrives on
``measured_joint_states``; a plan without one is sent as it is."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import REPO
from tests.program.test_ros import Ros, parmor, ros_python, wait_for

#: A worker whose plans all ask for the example loop (joint-hold, a strong integral).
LOOP_WORKER = """
import dataclasses

import program.rosworker as w

_init = w.Worker.__init__


def _with_loop(self, *args, **kwargs):
    _init(self, *args, **kwargs)
    run = self.controller.run

    def run_with_loop(name, **params):
        traj = run(name, **params)
        loop = {"loop": "joint-hold", "ki": 20.0, "moving_rad_s": 100.0}
        return dataclasses.replace(traj, info={**traj.info, "feedback": loop})

    self.controller.run = run_with_loop


w.Worker.__init__ = _with_loop
raise SystemExit(w.main())
"""

CLIENT = r"""
import json, sys, threading, time
import rospy
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

job = json.load(sys.stdin)
srv = __import__(job["package"] + ".srv", fromlist=["*"])
rospy.init_node("parmor_closed_client", anonymous=True)
lock = threading.Lock()
commands, plans = [], []
def on_command(m):
    with lock: commands.append(m)
def on_plan(m):
    with lock: plans.append(m)
rospy.Subscriber("/%s/joint_commands" % job["robot"], JointState, on_command)
rospy.Subscriber("/%s/joint_trajectory" % job["robot"], JointTrajectory, on_plan)
measured = rospy.Publisher("/%s/measured_joint_states" % job["robot"], JointState, queue_size=10)
stop = threading.Event()
def feed():  # the servos' read-back: every joint held at zero
    while not stop.is_set() and job["measured"]:
        m = JointState(); m.header.stamp = rospy.Time.now()
        m.name = job["joints"]; m.position = [0.0] * len(job["joints"])
        m.velocity = [0.0] * len(job["joints"])
        measured.publish(m); time.sleep(0.01)
threading.Thread(target=feed, daemon=True).start()
time.sleep(1.0)  # the subscriptions connect
name = "/%s/%s" % (job["robot"], job["service"])
rospy.wait_for_service(name, timeout=90)
proxy = rospy.ServiceProxy(name, getattr(srv, job["type"]))
defaults = {f["field"]: (float("nan") if f["ros"] == "float64" else "")
            for f in job["request"] if f["ros"] in ("float64", "string")}
reply = proxy(getattr(srv, job["type"] + "Request")(**defaults))
end = time.monotonic() + 60
while time.monotonic() < end:
    with lock:
        if len(commands) >= 25 and plans:
            break
    time.sleep(0.05)
stop.set()
if not plans:
    print(json.dumps({"ok": reply.ok, "message": reply.message}), flush=True)
    sys.exit(0)
with lock:
    plan = plans[-1]
    start = plan.header.stamp
    out = {
        "ok": reply.ok,
        "joints": list(plan.joint_names),
        "times": [p.time_from_start.to_sec() for p in plan.points],
        "positions": [list(p.positions) for p in plan.points],
        "commands": [
            {"t": (m.header.stamp - start).to_sec(), "name": list(m.name),
             "position": list(m.position)}
            for m in commands if m.header.stamp >= start
        ],
    }
print(json.dumps(out), flush=True)
"""


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> tuple[Path, dict]:
    root = tmp_path_factory.mktemp("closed")
    code, _, err = parmor(
        "design", "pick-and-place", "--param", "object_shape=cylinder", "--no-verify",
        "--no-input", "--out", str(root / "arm"),
    )  # fmt: skip
    assert code == 0, err
    code, text, err = parmor("ros", str(root / "arm"), "--json")
    assert code == 0, err
    path = Path(json.loads(text)["package"])
    return path, json.loads((path / "interface.json").read_text())


def _run(tmp_path: Path, package: tuple[Path, dict], loop: bool, measured: bool) -> dict:
    import sys

    path, iface = package
    iface = json.loads(json.dumps(iface))
    tmp_path.mkdir(parents=True, exist_ok=True)
    if loop:  # the worker of this test: every plan asks for joint-hold
        (tmp_path / "loopworker.py").write_text(LOOP_WORKER)
        iface["worker"] = {
            "python": sys.executable,
            "module": "loopworker",
            "pythonpath": f"{tmp_path}:{REPO}",
        }
    else:
        iface["worker"] = {"python": sys.executable, "pythonpath": str(REPO)}
    (path / "interface.json").write_text(json.dumps(iface))
    python = ros_python()
    home = tmp_path / "roshome"
    (home / "log").mkdir(parents=True)
    ros = Ros(python, home)
    try:
        node = ros.start(
            [python, str(path / "nodes" / "parmor_node")], "node", ros.package_env(path)
        )
        service = next(s for s in iface["services"] if s["behavior"] == "positioning")
        name = f"/{iface['robot']}/{service['service']}"
        wait_for(name, lambda: ros.has_service(name), node, home / "node.log")
        job = {
            "package": iface["package"],
            "robot": iface["robot"],
            "service": service["service"],
            "type": service["type"],
            "joints": service["joints"],
            "request": service["request"],
            "measured": measured,
        }
        (home / "client.py").write_text(CLIENT)
        proc = subprocess.run(
            [python, str(home / "client.py")],
            input=json.dumps(job),
            capture_output=True,
            text=True,
            env=ros.package_env(path),
            timeout=300,
        )
        log = (home / "node.log").read_text(errors="replace")[-3000:]
        assert proc.returncode == 0, proc.stderr[-3000:] + log
        (line,) = [x for x in proc.stdout.splitlines() if x.startswith("{")]
        out = json.loads(line)
        assert "commands" in out, (out, log)
        return out
    finally:
        ros.close()


def _offsets(out: dict) -> np.ndarray:
    """The commands less the plan at their times: the loop's corrections."""
    times, positions = np.array(out["times"]), np.array(out["positions"])
    rows = []
    for c in out["commands"]:
        assert c["name"] == out["joints"]
        plan = [np.interp(c["t"], times, positions[:, k]) for k in range(len(out["joints"]))]
        rows.append(np.array(c["position"]) - plan)
    return np.array(rows)


def test_the_node_closes_the_plans_loop_on_the_read_back(tmp_path, package) -> None:
    closed = _run(tmp_path / "closed", package, loop=True, measured=True)
    assert closed["ok"] and len(closed["commands"]) >= 20
    off = _offsets(closed)
    # the read-back says every servo sits at zero: the integral pulls the commands away
    # from the plan, towards where it should be, and grows
    assert np.abs(off[-1]).max() > 1e-3
    assert np.abs(off[-1]).max() > np.abs(off[0]).max()


def test_a_plan_without_a_loop_is_sent_as_it_is(tmp_path, package) -> None:
    plain = _run(tmp_path / "plain", package, loop=False, measured=True)
    assert plain["ok"] and len(plain["commands"]) >= 20
    assert np.abs(_offsets(plain)).max() < 1e-9
