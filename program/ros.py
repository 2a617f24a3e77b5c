"""``parmor ros DIR``: a ROS 1 package that serves a design's behaviours.

The package (``DIR/ros/parmor_<robot>/``) has one service per behaviour the design lists
(``/<robot>/<behaviour>``, hyphens as underscores), generated from the controller's typed
description alone (:class:`gaits.base.BehaviorSpec`, :class:`gaits.base.Parameter`) and
from what its trajectories promise (:attr:`gaits.base.Trajectory.info`), so a new robot
type needs no code here:

- request fields: the behaviour's parameters (float -> ``float64``, int -> ``int64``,
  choice -> ``string``), with unit, range, default and choices in the ``.srv`` comments
  and as constants (``<FIELD>_DEFAULT``, ``_MIN``, ``_MAX``, ``_CHOICES``); a float field
  set to NaN and a choice field left empty take the parameter's default;
- response fields: ``ok``, ``message`` (the error: field, value and range), ``duration_s``
  and every scalar, string or short vector the behaviour's ``info`` holds (``motion``,
  ``planned_pose``, ``path_length_m``, ``target`` ...), found by planning the behaviour
  with its defaults and with each value of its choice parameters when the package is
  written; per-sample arrays and nested structures stay out.

How the node gets trajectories: the node (``nodes/parmor_node``, run by the system's ROS
Python, which does not see parmor's environment) starts a worker from the parmor
installation that wrote the package, ``PYTHON -m program.rosworker PACKAGE_DIR``, and
speaks JSON lines with it over its stdin and stdout (:mod:`program.rosworker`). PYTHON
and the folder parmor was imported from are recorded in the package's ``interface.json``
when it is written; the ``python`` and ``pythonpath`` launch arguments (the node's
private parameters ``~python``, ``~pythonpath``) or the environment variables
``PARMOR_PYTHON`` and ``PARMOR_PYTHONPATH`` replace them. The worker plans with the
design's controller as the bundle's ``trajectories/*.csv`` are planned
(``gaits.controller_for(DesignGeometry.from_record(record))``: the plan, without a
simulator's servo compensation).

The service classes: ``src/parmor_<robot>/srv/__init__.py`` generates them at import
with genpy (which every rospy installation has) from the package's ``srv/*.srv``, the
same modules ``catkin_make`` writes, so ``rosservice`` and rospy clients load them with
no build: ``source DIR/ros/parmor_<robot>/setup.bash`` puts the package on
``ROS_PACKAGE_PATH`` and ``PYTHONPATH``. In a catkin workspace the package builds as usual.
"""

from __future__ import annotations

import json
import numbers
import re
import sys
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape

import program
from adron.errors import ExportError, InputError
from export.bundle import write_bundle
from export.urdf import relative_meshes
from gaits import controller_for
from gaits.base import DesignGeometry
from gaits.feedback import CONTROL_PERIOD_S, has_imu
from synth.verification.source import Bundle

if TYPE_CHECKING:
    from gaits.base import BehaviorSpec, Controller, Parameter, Trajectory

#: Version of ``interface.json``; the node and the worker refuse another.
INTERFACE_FORMAT = 1
#: ROS type of each parameter kind.
REQUEST_TYPES = {"float": "float64", "int": "int64", "choice": "string"}
#: Response fields every service has (an info key of the same name is left out).
FIXED_RESPONSE = (
    ("ok", "bool", "true: the trajectory is being published; false: see message"),
    ("message", "string", "why the call was refused (the field, its value and range)"),
    ("duration_s", "float64", "duration of the published trajectory, s"),
)
#: Names of the node's topics, relative to ``<robot>/``: what it publishes (the plan,
#: its playback, the commands for the servos) and what its feedback loops read (the
#: servos' read-back; ``imu`` only where the design carries an IMU, :data:`IMU_TOPIC`).
TOPICS = {
    "trajectory": "joint_trajectory",
    "joint_states": "joint_states",
    "commands": "joint_commands",
    "measured": "measured_joint_states",
}
#: The topic of the IMU's readings (``sensor_msgs/Imu``), where the design carries one.
IMU_TOPIC = "imu"
#: Rate at which the node plays the trajectory back on ``joint_states``, Hz (default).
PLAYBACK_RATE_HZ = 50.0
#: Longest the node waits for one plan before it restarts the worker, s (default).
PLAN_TIMEOUT_S = 60.0
#: Most trajectory points one call may publish (a longer plan is refused).
MAX_POINTS = 100_000
#: The worker's module (run with ``python -m``).
WORKER_MODULE = "program.rosworker"

_ROS_NAME = re.compile(r"[a-z][a-z0-9_]*")
_FIELD = re.compile(r"[a-zA-Z][a-zA-Z0-9_]*")


class RosInputError(InputError):
    """A bundle that cannot become a ROS package (no record, no structure...)."""


# --- names --------------------------------------------------------------------------------


def robot_name(robot_type: str) -> str:
    """A ROS name for a robot type: ``HexapodRobot`` -> ``hexapod_robot``,
    ``Manipulator3DOF`` -> ``manipulator_3dof``."""
    s = re.sub(r"(?<=[a-z])(?=[A-Z])|(?<=[A-Za-z])(?=[0-9])", "_", robot_type)
    s = re.sub(r"[^a-z0-9_]+", "_", s.lower()).strip("_")
    s = re.sub(r"_+", "_", s)
    return s if _ROS_NAME.fullmatch(s) else f"robot_{s}".rstrip("_")


def field_name(name: str) -> str:
    """A ROS field or service name for a parameter, info key or behaviour name: hyphens
    and other characters ROS names do not allow become underscores."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return s if _FIELD.fullmatch(s) else f"f_{s}"


def type_name(behavior: str) -> str:
    """The service type of a behaviour: ``pick-and-place`` -> ``PickAndPlace``."""
    words = [w for w in re.split(r"[^A-Za-z0-9]+", behavior) if w]
    s = "".join(w[:1].upper() + w[1:] for w in words)
    return s if s[:1].isalpha() else f"Behavior{s}"


# --- the interface ------------------------------------------------------------------------


def _ros_value_type(value: object, samples: int) -> str | None:
    """The ROS type of an info value, or None when it stays out of the reply (per-sample
    arrays, nested structures, objects)."""
    import numpy as np

    if isinstance(value, str):
        return "string"
    if isinstance(value, (bool, np.bool_)):
        return "bool"
    if isinstance(value, numbers.Integral):
        return "int64"
    if isinstance(value, numbers.Real):
        return "float64"
    if isinstance(value, (list, tuple, np.ndarray)):
        if isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
            return "string[]"
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return None
        if a.ndim == 1 and len(a) != samples:
            return "float64[]"
    return None


def _merge(a: str | None, b: str | None) -> str | None:
    if a is None or a == b:
        return b
    if {a, b} == {"int64", "float64"}:
        return "float64"
    return "conflict"


def response_fields(trajectories: Sequence[Trajectory]) -> tuple[list[dict], list[str]]:
    """The response fields beyond ``FIXED_RESPONSE`` for a behaviour whose plans are
    ``trajectories``: ({"field", "key", "ros"}, sorted by key; the info keys left out)."""
    types: dict[str, str | None] = {}
    for traj in trajectories:
        for key, value in traj.info.items():
            t = _ros_value_type(value, len(traj.times))
            types[key] = _merge(types[key], t) if key in types else t
    fixed = {name for name, _, _ in FIXED_RESPONSE}
    fields, left, seen = [], [], set(fixed)
    for key in sorted(types):
        t, name = types[key], field_name(key)
        if t in (None, "conflict") or name in seen:
            left.append(key)
            continue
        seen.add(name)
        fields.append({"field": name, "key": key, "ros": t})
    return fields, left


def _request_field(p: Parameter) -> dict:
    ros = REQUEST_TYPES.get(p.kind)
    if ros is None:
        raise ExportError(f"parameter {p.name!r}: kind {p.kind!r} has no ROS field type")
    return {
        "field": field_name(p.name),
        "param": p.name,
        "kind": p.kind,
        "ros": ros,
        "default": p.default,
        "unit": p.unit,
        "low": p.low,
        "high": p.high,
        "choices": list(p.choices),
        "doc": p.doc,
        "own": p.own,
    }


def _plans(controller: Controller, spec: BehaviorSpec) -> list[Trajectory]:
    """The behaviour planned with its defaults and with each value of each choice
    parameter (the others at their defaults); those the controller refuses are left out,
    and ExportError when it refuses them all."""
    tries: list[dict[str, object]] = [{}]
    tries += [{p.name: c} for p in spec.params for c in p.choices if c != p.default]
    plans, why = [], ""
    for params in tries:
        try:
            plans.append(controller.run(spec.name, **params))
        except ValueError as e:
            why = why or str(e)
    if not plans:
        raise ExportError(f"{spec.name}: cannot be planned with its defaults: {why}")
    return plans


def interface(record: Mapping, name: str | None = None) -> dict:
    """The package's interface (``interface.json`` without its ``worker`` section): the
    robot's ROS name, and for each behaviour the design lists its service, request
    fields and response fields. RosInputError when the record has no structure, no
    controller or no behaviour."""

    try:
        geometry = DesignGeometry.from_record(record)
        controller = controller_for(geometry)
    except (KeyError, TypeError, ValueError) as e:
        raise RosInputError(f"the design cannot be programmed: {str(e).strip(chr(39))}") from None
    robot = name or robot_name(str(record.get("robot_type", "robot")))
    if not _ROS_NAME.fullmatch(robot):
        raise RosInputError(f"--name {robot!r}: expected a ROS name ([a-z][a-z0-9_]*)")
    names = controller.listed(record.get("abilities", ()))
    if not names:
        raise RosInputError(
            f"{geometry.robot_type}: the design lists no behaviour (abilities: "
            f"{', '.join(record.get('abilities', ())) or 'none'}), so there is nothing to serve"
        )
    services, seen, types = [], {}, {}
    for behavior in names:
        spec = controller.behaviors[behavior]
        service, srv = field_name(behavior), type_name(behavior)
        for key, table in ((service, seen), (srv, types)):
            if key in table:
                raise ExportError(f"behaviours {table[key]!r} and {behavior!r} get one name {key}")
            table[key] = behavior
        request = [_request_field(p) for p in spec.params]
        if len({f["field"] for f in request}) != len(request):
            raise ExportError(f"{behavior}: two parameters get one field name")
        plans = _plans(controller, spec)
        response, left = response_fields(plans)
        services.append(
            {
                "service": service,
                "behavior": behavior,
                "type": srv,
                "doc": spec.doc,
                "request": request,
                "response": response,
                "left_out": left,
                "joints": list(plans[0].joints),
            }
        )
    return {
        "format": INTERFACE_FORMAT,
        "robot": robot,
        "package": f"parmor_{robot}",
        "robot_type": geometry.robot_type,
        "topics": dict(TOPICS) | ({"imu": IMU_TOPIC} if has_imu(geometry.sensors) else {}),
        # what the node's feedback loops read and at which period (gaits.feedback); the
        # wheels' offsets are speeds (their servos take a velocity)
        "feedback": {
            "period_s": CONTROL_PERIOD_S,
            "imu": has_imu(geometry.sensors),
            "velocity_joints": _wheel_joints(controller.template, record),
        },
        "playback_rate_hz": PLAYBACK_RATE_HZ,
        "plan_timeout_s": PLAN_TIMEOUT_S,
        "max_points": MAX_POINTS,
        "services": services,
    }


def _wheel_joints(template, record: Mapping) -> list[str]:
    """The driven wheels' joints (velocity servos: a loop's offset for them is a speed)."""
    driven = {j.get("name") for j in record.get("joints", ())}
    return sorted(name for name in template.wheel_joints if name in driven)


# --- the package's files ------------------------------------------------------------------


def _num(x: object) -> str:
    return f"{x:.6g}" if isinstance(x, float) else str(x)


def _comment(text: str) -> str:
    return " ".join(str(text).split())


def srv_text(service: Mapping) -> str:
    """The ``.srv`` definition of one service: request fields with their unit, range,
    default and choices (comments and constants), ``---``, the response fields."""
    lines = [
        f"# {service['behavior']}: {_comment(service['doc'])}",
        "# A float field set to NaN, or a string field left empty, takes its default.",
    ]
    for f in service["request"]:
        unit = f" [{f['unit']}]" if f["unit"] else ""
        what = [f"# {f['field']}{unit}: {_comment(f['doc'])}"]
        upper = f["field"].upper()
        consts = []
        if f["kind"] == "choice":
            what.append(f"#   one of: {', '.join(f['choices'])}; default {f['default']}")
            consts.append(f"string {upper}_DEFAULT={f['default']}")
            consts.append(f"string {upper}_CHOICES={','.join(f['choices'])}")
        else:
            lo = "-inf" if f["low"] is None else _num(f["low"])
            hi = "inf" if f["high"] is None else _num(f["high"])
            kind = "integer" if f["kind"] == "int" else "number"
            what.append(f"#   {kind} in [{lo}, {hi}]; default {_num(f['default'])}")
            if f.get("own"):
                what.append(
                    "#   the default is the design's own, worked out for the other fields "
                    "(0, or the field left out, means the same)"
                )
            consts.append(f"{f['ros']} {upper}_DEFAULT={f['default']!r}")
            if f["low"] is not None:
                consts.append(f"{f['ros']} {upper}_MIN={f['low']!r}")
            if f["high"] is not None:
                consts.append(f"{f['ros']} {upper}_MAX={f['high']!r}")
        lines += [*what, f"{f['ros']} {f['field']}", *consts]
    lines.append("---")
    for name, ros, doc in FIXED_RESPONSE:
        lines += [f"# {doc}", f"{ros} {name}"]
    lines.append("# what the behaviour promises (its trajectory's info)")
    lines += [f"{f['ros']} {f['field']}" for f in service["response"]]
    if service["left_out"]:
        lines.append(f"# not in the reply (per-sample or nested): {', '.join(service['left_out'])}")
    return "\n".join(lines) + "\n"


def _template(name: str) -> str:
    return (resources.files("program") / "ros_templates" / name).read_text(encoding="utf-8")


def package_xml(iface: Mapping) -> str:
    names = ", ".join(f"/{iface['robot']}/{s['service']}" for s in iface["services"])
    deps = ("rospy", "std_msgs", "sensor_msgs", "trajectory_msgs")
    return "\n".join(
        [
            '<?xml version="1.0"?>',
            '<package format="2">',
            f"  <name>{iface['package']}</name>",
            "  <version>0.1.0</version>",
            f"  <description>Services of a {escape(iface['robot_type'])} designed by parmor: "
            f"{escape(names)}</description>",
            '  <maintainer email="parmor@example.org">parmor</maintainer>',
            "  <license>MIT</license>",
            "  <buildtool_depend>catkin</buildtool_depend>",
            "  <build_depend>message_generation</build_depend>",
            *(f"  <depend>{d}</depend>" for d in deps),
            "  <exec_depend>message_runtime</exec_depend>",
            "</package>",
            "",
        ]
    )


def cmakelists(iface: Mapping) -> str:
    srvs = " ".join(f"{s['type']}.srv" for s in iface["services"])
    return "\n".join(
        [
            "cmake_minimum_required(VERSION 3.0.2)",
            f"project({iface['package']})",
            "find_package(catkin REQUIRED COMPONENTS",
            "  rospy std_msgs sensor_msgs trajectory_msgs message_generation)",
            f"add_service_files(FILES {srvs})",
            "generate_messages(DEPENDENCIES std_msgs)",
            "catkin_package(CATKIN_DEPENDS rospy std_msgs sensor_msgs trajectory_msgs "
            "message_runtime)",
            "",
        ]
    )


def launch_xml(iface: Mapping) -> str:
    pkg = iface["package"]
    return "\n".join(
        [
            "<launch>",
            "  <!-- the parmor worker: interpreter and import folder (empty: PARMOR_PYTHON and",
            "       PARMOR_PYTHONPATH, else those recorded in interface.json) -->",
            '  <arg name="python" default=""/>',
            '  <arg name="pythonpath" default=""/>',
            f'  <arg name="rate" default="{PLAYBACK_RATE_HZ:g}"/>',
            f'  <arg name="plan_timeout" default="{PLAN_TIMEOUT_S:g}"/>',
            f'  <param name="robot_description" textfile="$(find {pkg})/urdf/robot.urdf"/>',
            "  <!-- the controller publishes the servos' commands on joint_commands and, while a",
            "       plan has a feedback loop, reads the servos' read-back on",
            f"       measured_joint_states (sensor_msgs/JointState){_imu_comment(iface)} -->",
            f'  <node name="{pkg}" pkg="{pkg}" type="parmor_node" output="screen" required="true">',
            '    <param name="python" value="$(arg python)"/>',
            '    <param name="pythonpath" value="$(arg pythonpath)"/>',
            '    <param name="rate" value="$(arg rate)"/>',
            '    <param name="plan_timeout" value="$(arg plan_timeout)"/>',
            "  </node>",
            "</launch>",
            "",
        ]
    )


def _imu_comment(iface: Mapping) -> str:
    if "imu" not in iface["topics"]:
        return ""
    return f" and the IMU on {iface['topics']['imu']} (sensor_msgs/Imu)"


def readme(iface: Mapping) -> str:
    r, pkg = iface["robot"], iface["package"]
    lines = [
        f"# {pkg}",
        "",
        f"ROS 1 services of a {iface['robot_type']} designed by parmor (`parmor ros`).",
        "",
        "```",
        f"source {pkg}/setup.bash          # this package on ROS_PACKAGE_PATH and PYTHONPATH",
        f"roslaunch {pkg} parmor.launch    # with a rosmaster running (or: roscore)",
        f"rossrv show {pkg}/{iface['services'][0]['type']}",
        "```",
        "",
        "| service | type | behaviour |",
        "|---|---|---|",
    ]
    for s in iface["services"]:
        lines.append(f"| `/{r}/{s['service']}` | `{pkg}/{s['type']}` | {_comment(s['doc'])} |")
    t = iface["topics"]
    lines += [
        "",
        f"Each call plans the behaviour, publishes it on `/{r}/{t['trajectory']}`",
        "(`trajectory_msgs/JointTrajectory`, latched) and plays it back on",
        f"`/{r}/{t['joint_states']}`",
        f"(`sensor_msgs/JointState`, {PLAYBACK_RATE_HZ:g} Hz, stamped at the trajectory's",
        "start plus its time), and answers at once with `ok`, `message`, `duration_s` and what",
        "the behaviour promises. A value out of its range gets `ok: False` and a message",
        "naming the field, the value and the range; the node keeps serving.",
        "",
        "## What the controller reads and writes",
        "",
        f"The node drives the servos through `/{r}/{t['commands']}` (`sensor_msgs/JointState`:",
        "`position` for position servos, `velocity` for the wheels' velocity servos, every",
        f"{iface['feedback']['period_s'] * 1000:g} ms). When a plan carries a feedback loop (the",
        "one the design was verified with: parmor's `gaits.feedback`, run by its worker), the",
        "node reads, every period:",
        "",
        f"- `/{r}/{t['measured']}` (`sensor_msgs/JointState`): the servos' read-back,",
        "  position and velocity of each joint (a wheel's encoder), published by the hardware",
        "  driver;",
    ]
    if "imu" in t:
        lines += [
            f"- `/{r}/{t['imu']}` (`sensor_msgs/Imu`): the design's IMU module,"
            " `angular_velocity` rad/s and `linear_acceleration` m/s^2 (specific force) in its",
            "  own frame, as its driver publishes them;",
        ]
    lines += [
        "",
        "and adds the loop's correction to the plan's commands. Until the read-back arrives,",
        "the plan is sent as it is (open loop) and the node says so once.",
        "",
        "The node runs under the system's ROS Python and starts a parmor worker",
        "(`python -m program.rosworker` on this folder); its interpreter and import folder",
        "are recorded in `interface.json` and can be replaced with the launch arguments",
        "`python:=...` and `pythonpath:=...` or the environment variables `PARMOR_PYTHON`",
        "and `PARMOR_PYTHONPATH`.",
        "",
    ]
    return "\n".join(lines)


SETUP_BASH = """\
# Source this file (bash) to use the package without a catkin build: it puts the package
# on ROS_PACKAGE_PATH (roslaunch, rosservice find it) and its src/ on PYTHONPATH (the
# service classes, generated with genpy when they are imported).
_parmor_pkg="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
export ROS_PACKAGE_PATH="$(dirname "$_parmor_pkg")${ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}"
export PYTHONPATH="$_parmor_pkg/src${PYTHONPATH:+:$PYTHONPATH}"
unset _parmor_pkg
"""


def worker_defaults() -> dict:
    """The worker as this parmor installation runs it: its interpreter and the folder
    ``program`` was imported from (recorded in the generated package, never here)."""

    return {
        "python": sys.executable,
        "pythonpath": str(Path(program.__file__).resolve().parents[1]),
        "module": WORKER_MODULE,
    }


_MESH_REF = re.compile(r'filename="([^":]+)"')


def package_urdf(urdf: str, package: str) -> tuple[str, list[str]]:
    """The URDF with its relative mesh paths as ``package://<package>/...`` URIs, and
    those relative paths (the files to copy into the package)."""
    refs: list[str] = []

    def swap(m: re.Match) -> str:
        rel = m.group(1)
        if Path(rel).is_absolute() or ".." in Path(rel).parts:
            return m.group(0)
        if rel not in refs:
            refs.append(rel)
        return f'filename="package://{package}/{rel}"'

    return _MESH_REF.sub(swap, urdf), sorted(refs)


def package_files(
    record: Mapping,
    urdf: str,
    meshes: Mapping[str, bytes],
    name: str | None = None,
    worker: Mapping | None = None,
) -> dict[str, tuple[str | bytes, int]]:
    """Every file of the package: relative name -> (content, mode). ``urdf`` is the
    bundle's, ``meshes`` its mesh files by the relative path the URDF names them with."""
    iface = interface(record, name)
    iface["worker"] = dict(worker if worker is not None else worker_defaults())
    pkg = iface["package"]
    files: dict[str, tuple[str | bytes, int]] = {
        "package.xml": (package_xml(iface), 0o644),
        "CMakeLists.txt": (cmakelists(iface), 0o644),
        "README.md": (readme(iface), 0o644),
        "setup.bash": (SETUP_BASH, 0o644),
        "interface.json": (json.dumps(iface, indent=2, sort_keys=True) + "\n", 0o644),
        "design.json": (json.dumps(record, indent=2, sort_keys=True) + "\n", 0o644),
        "urdf/robot.urdf": (package_urdf(urdf, pkg)[0], 0o644),
        "launch/parmor.launch": (launch_xml(iface), 0o644),
        "nodes/parmor_node": (_template("parmor_node.py"), 0o755),
        f"src/{pkg}/__init__.py": (f'"""Python side of {pkg} (generated by parmor)."""\n', 0o644),
        f"src/{pkg}/srv/__init__.py": (_template("srv_init.py"), 0o644),
    }
    for s in iface["services"]:
        files[f"srv/{s['type']}.srv"] = (srv_text(s), 0o644)
    for rel, content in meshes.items():
        files[rel] = (content, 0o644)
    return files


def read_bundle(folder: Path) -> tuple[dict, str, dict[str, bytes]]:
    """(design record, URDF text, the meshes it names) of a bundle folder; RosInputError
    naming what is wrong."""

    record = Bundle.read(folder).record
    try:
        urdf = relative_meshes((folder / "robot.urdf").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise RosInputError(f"{folder}: no readable robot.urdf ({e})") from None
    meshes = {}
    for rel in package_urdf(urdf, "x")[1]:
        try:
            meshes[rel] = (folder / rel).read_bytes()
        except OSError as e:
            raise RosInputError(
                f"{folder}: robot.urdf names {rel}, which cannot be read: {e.strerror}"
            ) from None
    return record, urdf, meshes


def ros_package(
    folder: str | Path, name: str | None = None, force: bool = False, worker: Mapping | None = None
) -> tuple[Path, dict]:
    """Write the ROS package of the bundle in ``folder`` into
    ``folder/ros/parmor_<robot>/``: (its path, its interface)."""

    folder = Path(folder)
    record, urdf, meshes = read_bundle(folder)
    files = package_files(record, urdf, meshes, name, worker)
    iface = json.loads(str(files["interface.json"][0]))
    out = write_bundle(
        folder / "ros" / iface["package"],
        {rel: content for rel, (content, _) in files.items()},
        force,
        modes={rel: mode for rel, (_, mode) in files.items()},
    )
    return out, iface
