#!/usr/bin/env python3
"""The ROS node of a package written by ``parmor ros``: one service per behaviour.

It runs under the system's ROS Python (rospy), which does not see parmor's environment,
so it plans nothing itself: it starts a parmor worker (``PYTHON -m program.rosworker
PACKAGE_DIR``) and speaks JSON lines with it over the worker's stdin and stdout. PYTHON
and the folder parmor is imported from are, in this order: the private parameters
``~python`` and ``~pythonpath`` (the launch arguments ``python`` and ``pythonpath``), the
environment variables ``PARMOR_PYTHON`` and ``PARMOR_PYTHONPATH``, and the ones recorded
in ``interface.json`` when the package was written (the recorded folder only goes with the
recorded interpreter).

Each service call is passed to the worker; the node publishes the planned trajectory on
``<robot>/joint_trajectory`` (trajectory_msgs/JointTrajectory, latched, stamped with the
start of its playback), plays it back on ``<robot>/joint_states`` (sensor_msgs/JointState
at ``~rate`` Hz, each stamped with the start plus its time, the last at the end), drives
the servos on ``<robot>/joint_commands`` (sensor_msgs/JointState every control period:
the plan's command plus, when the plan carries a feedback loop, the loop's correction,
which the worker computes from the servos' read-back on ``<robot>/measured_joint_states``
and, where the design has an IMU, ``<robot>/imu``, sensor_msgs/Imu), and
answers at once with the worker's response: ``ok``, ``message``, ``duration_s`` and what
the behaviour promises. A refused call (a value out of range) publishes nothing, and the
node keeps serving; a plan that takes longer than ``~plan_timeout`` s restarts the worker.
When the ``python3`` that ``#!/usr/bin/env`` finds has no rospy (a virtualenv or pyenv
comes first on PATH), the node runs itself again with the interpreter of the ROS tools
(the ``#!`` line of ``roslaunch`` or ``rosmaster`` on PATH). Written by parmor; the same
file for every robot.
"""

import bisect
import json
import os
import queue
import subprocess
import sys
import threading


def ros_python():
    """The interpreter named by the ``#!`` line of the ROS tools on PATH, or None."""
    import shutil

    for tool in ("roslaunch", "rosmaster"):
        path = shutil.which(tool)
        if path is None:
            continue
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                first = f.readline()
        except OSError:
            continue
        words = first[2:].split() if first.startswith("#!") else []
        if words and os.path.isabs(words[0]) and os.path.basename(words[0]) != "env":
            return words[0]
    return None


try:
    import rospy
except ImportError:
    _python = ros_python()
    if _python is None or os.path.realpath(_python) == os.path.realpath(sys.executable):
        raise
    os.execv(_python, [_python, os.path.realpath(__file__), *sys.argv[1:]])

from sensor_msgs.msg import Imu, JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
sys.path.insert(0, os.path.join(PACKAGE_DIR, "src"))


class WorkerError(Exception):
    pass


#: Longest wait for a starting worker to say it is ready, s (it imports numpy and parmor).
START_TIMEOUT_S = 120.0


class Worker:
    """The parmor worker process: one request at a time. One that gives no answer within
    ``timeout`` s is killed; one that failed in any way (ended while idle or during a
    call, answered garbage) is replaced by a new one at the next call."""

    def __init__(self, command, env, timeout):
        self.command, self.env, self.timeout = command, env, timeout
        self.lock = threading.Lock()
        self.proc = None
        self.lines = None

    def _start(self):
        self.proc = subprocess.Popen(
            self.command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=self.env,
            text=True,
            bufsize=1,
        )
        self.lines = queue.Queue()
        threading.Thread(target=self._read, args=(self.proc, self.lines), daemon=True).start()
        try:
            hello = self._line(START_TIMEOUT_S)
        except Exception:
            self.stop(kill=True)
            raise
        if not hello.get("ready"):
            self.stop()
            raise WorkerError(
                "the parmor worker refused the package: {}".format(hello.get("message"))
            )
        return hello

    @staticmethod
    def _read(proc, lines):
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    def _line(self, timeout):
        try:
            line = self.lines.get(timeout=timeout)
        except queue.Empty:
            self.stop(kill=True)
            raise WorkerError(f"the parmor worker gave no answer within {timeout:g} s") from None
        if line is None:
            code = self.proc.wait()
            self.proc = None
            raise WorkerError(f"the parmor worker ended (exit code {code})")
        return json.loads(line)

    def start(self):
        with self.lock:
            return self._start()

    def call(self, request):
        """The worker's reply to ``request``. A worker that ended since the last call
        (killed, out of memory) is replaced before the request goes out; one that fails
        during the call (ends, answers garbage, or gives no answer in time) is stopped and
        the error raised: the next call starts a new one."""
        line = json.dumps(request) + "\n"
        with self.lock:
            for attempt in (1, 2):
                if self.proc is not None and self.proc.poll() is not None:
                    self.stop(kill=True)  # it ended while idle
                if self.proc is None:
                    self._start()
                try:
                    self.proc.stdin.write(line)
                    self.proc.stdin.flush()
                    break
                except OSError:  # it ended between the check and the write
                    self.stop(kill=True)
                    if attempt == 2:
                        raise
            try:
                return self._line(self.timeout)
            except Exception:
                self.stop(kill=True)
                raise

    def stop(self, kill=False):
        """End the worker: close its input (it ends at EOF), or kill it."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        if not kill:
            try:
                proc.stdin.close()
                proc.wait(timeout=5)
                return
            except (OSError, subprocess.TimeoutExpired):
                pass
        proc.kill()
        proc.wait()


def interp(times, column, t):
    """``column`` at ``t`` by linear interpolation in ``times`` (held at the ends)."""
    if t <= times[0]:
        return column[0]
    if t >= times[-1]:
        return column[-1]
    k = bisect.bisect_right(times, t)
    t0, t1 = times[k - 1], times[k]
    return column[k - 1] + (column[k] - column[k - 1]) * (t - t0) / (t1 - t0)


class Sensors:
    """The latest readings of the robot's sensors: the servos' read-back (``measured``
    joint states: position and velocity by joint name) and, where the design carries an
    IMU, its rates and specific force (``imu``)."""

    def __init__(self, robot, topics):
        self.lock = threading.Lock()
        self.joints = {}
        self.gyro = self.accel = None
        rospy.Subscriber("{}/{}".format(robot, topics["measured"]), JointState, self._joints)
        self.imu = "imu" in topics
        if self.imu:
            rospy.Subscriber("{}/{}".format(robot, topics["imu"]), Imu, self._imu)

    def _joints(self, msg):
        with self.lock:
            for k, name in enumerate(msg.name):
                q = msg.position[k] if k < len(msg.position) else None
                qd = msg.velocity[k] if k < len(msg.velocity) else 0.0
                if q is not None:
                    self.joints[name] = (float(q), float(qd))

    def _imu(self, msg):
        w, a = msg.angular_velocity, msg.linear_acceleration
        with self.lock:
            self.gyro, self.accel = [w.x, w.y, w.z], [a.x, a.y, a.z]

    def reading(self, joints, t):
        """The reading of ``joints`` (in the plan's order) at ``t`` s into the plan, or None
        while a joint has no read-back (or the IMU no reading, where there is one)."""
        with self.lock:
            if any(j not in self.joints for j in joints):
                return None
            if self.imu and self.gyro is None:
                return None
            return {
                "t": t,
                "q": [self.joints[j][0] for j in joints],
                "qd": [self.joints[j][1] for j in joints],
                "gyro": self.gyro,
                "accel": self.accel,
            }


class Player:
    """Publishes a trajectory, plays it back as joint states (a new one replaces it) and
    drives the servos with it: every control period its commands on ``commands``, with
    the correction of the plan's feedback loop (run by the worker on the sensors'
    readings) when the plan has one."""

    def __init__(self, robot, topics, rate, feedback=None, worker=None):
        self.trajectory = rospy.Publisher(
            "{}/{}".format(robot, topics["trajectory"]), JointTrajectory, queue_size=1, latch=True
        )
        self.states = rospy.Publisher(
            "{}/{}".format(robot, topics["joint_states"]), JointState, queue_size=10
        )
        self.commands = rospy.Publisher(
            "{}/{}".format(robot, topics["commands"]), JointState, queue_size=10
        )
        self.rate = rate
        self.feedback = feedback or {"period_s": 0.02, "velocity_joints": []}
        self.worker = worker
        self.sensors = Sensors(robot, topics)
        self.lock = threading.Lock()
        self.current = None
        self.wake = threading.Event()
        self.control_wake = threading.Event()
        self.said_open = False
        threading.Thread(target=self._play, daemon=True).start()
        threading.Thread(target=self._control, daemon=True).start()

    def _command(self, start, traj, columns, t, offsets):
        """The servos' command at ``t`` s into the plan, with the loop's ``offsets``."""
        msg = self._state(start, traj, columns, t)
        wheels = set(self.feedback.get("velocity_joints", ()))
        position, velocity = list(msg.position), list(msg.velocity)
        for k, name in enumerate(msg.name):
            if name in wheels:
                velocity[k] += offsets[k]
            else:
                position[k] += offsets[k]
        msg.position, msg.velocity = position, velocity
        return msg

    def _control(self):
        """Every control period while a plan plays: the loop's correction (when the plan
        has a loop and the sensors have been read) added to the plan's command."""
        period = float(self.feedback.get("period_s", 0.02))
        while not rospy.is_shutdown():
            with self.lock:
                current = self.current
            if current is None:
                self.control_wake.wait(0.5)
                self.control_wake.clear()
                continue
            start, traj, columns = current
            t = (rospy.Time.now() - start).to_sec()
            end = traj["times"][-1]
            offsets = [0.0] * len(traj["joints"])
            if traj.get("feedback") and self.worker is not None:
                reading = self.sensors.reading(traj["joints"], max(0.0, t))
                if reading is None:
                    if not self.said_open:
                        rospy.logwarn(
                            "parmor: no read-back on the measured topics yet: the plan "
                            "is sent open loop"
                        )
                        self.said_open = True
                else:
                    try:
                        reply = self.worker.call({"correct": reading})
                        if reply.get("ok"):
                            offsets = reply["offsets"]
                    except (OSError, WorkerError, ValueError) as e:
                        rospy.logerr(f"parmor: feedback: {e}")
            with self.lock:
                if self.current is current:
                    self.commands.publish(self._command(start, traj, columns, min(t, end), offsets))
            if t >= end:  # the last command sent: until the next plan
                self.control_wake.wait(0.5)
            else:
                self.control_wake.wait(period)
            self.control_wake.clear()

    def publish(self, traj):
        msg = JointTrajectory()
        msg.joint_names = list(traj["joints"])
        for t, q, v in zip(traj["times"], traj["positions"], traj["velocities"]):  # noqa: B905 (Python 3.8)
            msg.points.append(
                JointTrajectoryPoint(
                    positions=list(q),
                    velocities=list(v),
                    time_from_start=rospy.Duration.from_sec(t),
                )
            )
        columns = (list(zip(*traj["positions"])), list(zip(*traj["velocities"])))  # noqa: B905
        with self.lock:  # every joint state of the previous trajectory is stamped before this
            start = rospy.Time.now()
            msg.header.stamp = start
            self.current = (start, traj, columns)
            self.trajectory.publish(msg)
        self.wake.set()
        self.control_wake.set()

    def _state(self, start, traj, columns, t):
        msg = JointState()
        msg.header.stamp = start + rospy.Duration.from_sec(t)
        msg.name = list(traj["joints"])
        times = traj["times"]
        msg.position = [interp(times, c, t) for c in columns[0]]
        msg.velocity = [interp(times, c, t) for c in columns[1]]
        return msg

    def _play(self):
        period = 1.0 / self.rate
        while not rospy.is_shutdown():
            with self.lock:
                current = self.current
                if current is not None:
                    start, traj, columns = current
                    t = (rospy.Time.now() - start).to_sec()
                    end = traj["times"][-1]
                    self.states.publish(self._state(start, traj, columns, min(t, end)))
                    if t >= end:
                        self.current = None
            if current is None or t >= end:
                self.wake.wait(0.5)
            else:
                self.wake.wait(min(period, end - t))
            self.wake.clear()


def worker_command(iface):
    """(command, environment) of the parmor worker (see the module docstring)."""
    recorded = iface["worker"]
    python = rospy.get_param("~python", "") or os.environ.get("PARMOR_PYTHON", "")
    pythonpath = rospy.get_param("~pythonpath", "") or os.environ.get("PARMOR_PYTHONPATH", "")
    if not python:
        python = recorded["python"]
        pythonpath = pythonpath or recorded.get("pythonpath", "")
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath + (
            os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else ""
        )
    return [python, "-m", recorded.get("module", "program.rosworker"), PACKAGE_DIR], env


def main():
    with open(os.path.join(PACKAGE_DIR, "interface.json"), encoding="utf-8") as f:
        iface = json.load(f)
    rospy.init_node(iface["package"])
    srv = __import__(iface["package"] + ".srv", fromlist=["*"])
    command, env = worker_command(iface)
    worker = Worker(command, env, float(rospy.get_param("~plan_timeout", iface["plan_timeout_s"])))
    rospy.on_shutdown(worker.stop)
    try:
        hello = worker.start()
    except (OSError, WorkerError, ValueError) as e:
        rospy.logfatal("parmor: cannot start the worker {}: {}".format(" ".join(command), e))
        sys.exit(1)
    rospy.loginfo(
        "parmor worker ready for {}: {}".format(hello["robot"], ", ".join(hello["services"]))
    )
    player = Player(
        iface["robot"],
        iface["topics"],
        float(rospy.get_param("~rate", iface["playback_rate_hz"])),
        iface.get("feedback"),
        worker,
    )

    def handler_for(service, response_class):
        def handle(request):
            fields = {name: getattr(request, name) for name in request.__slots__}
            try:
                reply = worker.call({"service": service["service"], "fields": fields})
            except (OSError, WorkerError, ValueError) as e:
                rospy.logerr("parmor: {}: {}".format(service["service"], e))
                return response_class(ok=False, message="{}: {}".format(service["service"], e))
            if reply.get("ok"):
                player.publish(reply["trajectory"])
            else:
                rospy.logwarn("parmor: {}".format(reply["response"].get("message")))
            return response_class(**reply["response"])

        return handle

    for service in iface["services"]:
        cls = getattr(srv, service["type"])
        response_class = getattr(srv, service["type"] + "Response")
        rospy.Service(
            "{}/{}".format(iface["robot"], service["service"]),
            cls,
            handler_for(service, response_class),
        )
    rospy.spin()


if __name__ == "__main__":
    main()
