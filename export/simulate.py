"""Running a behaviour on a design's MJCF model in MuJoCo, and measuring what it did.

The model comes from a bundle (``robot.xml`` and ``meshes/``); actuators are limited to the
catalog's stall torques by the MJCF itself. Position servos follow the trajectory's
positions, wheel servos its velocities (linear interpolation at every physics step).

Measured (keys of ``SimResult.to_dict``): ``distance_m`` (planar displacement of the root
body), ``heading_rad`` (change of its yaw), ``fell`` / ``fell_at_s`` (the root dropped
below half of its start height or tilted more than 60 degrees; never for the snake, whose
rolling turns its body over, nor for a fixed base), ``max_torque_ratio`` (largest
|actuator force| / stall torque), ``tracking_error`` (driving: relative error of the mean
(v, w) over the second half against the commanded ones), ``placing_error_m``
(manipulators: distance of the gripper from the trajectory's ``target`` when it let go,
``info["placed_at_s"]``, else at the end).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaits.base import Trajectory


@dataclass
class SimResult:
    behavior: str
    seconds: float
    distance_m: float
    heading_rad: float
    fell: bool
    fell_at_s: float | None
    max_torque_ratio: float
    tracking_error: float | None = None
    placing_error_m: float | None = None
    demand_ratio_max: float = 0.0
    saturated_fraction: float = 0.0
    planned_distance_m: float | None = None
    planned_heading_rad: float | None = None
    path_length_m: float | None = None
    final_pose_error_m: float | None = None
    orientation_error_rad: float | None = None
    drift_m: float | None = None
    min_height_ratio: float | None = None
    max_tilt_rad: float | None = None
    saturated_joints: dict[str, float] = field(default_factory=dict)  # actuator -> share
    verdict: list[str] = field(default_factory=list)
    complete: bool = True  # ran to the behaviour's end: its promise was judged too
    series: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def ok(self) -> bool:
        return not self.verdict

    def to_dict(self) -> dict:
        def r(x):
            return None if x is None else float(f"{x:.6g}")

        return {
            "behavior": self.behavior,
            "seconds": r(self.seconds),
            "verdict": "ok" if self.ok else list(self.verdict),
            "complete": self.complete,
            "distance_m": r(self.distance_m),
            "planned_distance_m": r(self.planned_distance_m),
            "heading_rad": r(self.heading_rad),
            "planned_heading_rad": r(self.planned_heading_rad),
            "path_length_m": r(self.path_length_m),
            "final_pose_error_m": r(self.final_pose_error_m),
            "drift_m": r(self.drift_m),
            "fell": self.fell,
            "fell_at_s": r(self.fell_at_s),
            "min_height_ratio": r(self.min_height_ratio),
            "max_tilt_rad": r(self.max_tilt_rad),
            "max_torque_ratio": r(self.max_torque_ratio),
            "demand_ratio_max": r(self.demand_ratio_max),
            "saturated_fraction": r(self.saturated_fraction),
            "saturated_joints": {k: r(v) for k, v in sorted(self.saturated_joints.items())},
            "tracking_error": r(self.tracking_error),
            "placing_error_m": r(self.placing_error_m),
            "orientation_error_rad": r(self.orientation_error_rad),
        }


def load_bundle_model(folder: str | Path):
    """The MuJoCo model of a bundle folder (robot.xml with its meshes), carrying the
    design's payload (:func:`carrying_payload`)."""
    folder = Path(folder)
    files = {p.name: p.read_bytes() for p in sorted((folder / "meshes").glob("*.stl"))}
    files["robot.xml"] = (folder / "robot.xml").read_bytes()
    if (folder / "design.json").is_file():
        files["design.json"] = (folder / "design.json").read_bytes()
    return load_files_model(files)


def carrying_payload(xml: str, record: Mapping) -> str:
    """``robot.xml`` text with the design's payload (``record["payload"]``) as a point mass
    in each body that holds it, unless the models already carry it (``in_models``,
    ``parmor design --with-payload``): the robot is simulated as it was sized and verified,
    loaded."""
    import xml.etree.ElementTree as ET

    payload = record.get("payload") if isinstance(record, Mapping) else None
    if not isinstance(payload, Mapping) or payload.get("in_models"):
        return xml
    held = [h for h in payload.get("held_by") or () if float(h.get("mass_kg") or 0) > 0]
    if not held:
        return xml
    root = ET.fromstring(xml)
    bodies = {b.get("name"): b for b in root.iter("body")}
    for k, h in enumerate(held):
        body = bodies.get(h["body"])
        if body is None:
            raise ValueError(f"design.json: the payload's body {h['body']!r} is not in robot.xml")
        load = ET.Element(
            "body",
            name=f"payload_{k}",
            pos=" ".join(f"{float(x):.9g}" for x in h["position_m"]),
        )
        ET.SubElement(
            load,
            "inertial",
            pos="0 0 0",
            mass=f"{float(h['mass_kg']):.9g}",
            diaginertia=" ".join([f"{PAYLOAD_INERTIA * float(h['mass_kg']):.9g}"] * 3),
        )
        body.append(load)
    return ET.tostring(root, encoding="unicode")


#: m^2: a point payload's inertia per kg (a 3 cm radius of gyration: MuJoCo needs some)
PAYLOAD_INERTIA = 0.03**2


def load_files_model(files: Mapping[str, str | bytes]):
    """The MuJoCo model of a bundle held in memory: ``robot.xml`` and ``meshes/*.stl`` (keys
    relative to the bundle folder; bare mesh names are accepted too), carrying the payload
    of ``design.json`` where it is given (:func:`carrying_payload`)."""
    from export.mjcf import load_mjcf

    xml = files["robot.xml"]
    text = xml.decode("utf-8") if isinstance(xml, bytes) else xml
    raw = files.get("design.json")
    if raw is not None:
        import json

        text = carrying_payload(
            text, json.loads(raw.decode("utf-8") if isinstance(raw, bytes) else raw)
        )
    meshes = {
        Path(k).name: (v.encode() if isinstance(v, str) else v)
        for k, v in sorted(files.items())
        if k.endswith(".stl")
    }
    return load_mjcf(text, meshes)


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _tilt(quat: np.ndarray) -> float:
    w, x, y, z = quat
    up = 1 - 2 * (x * x + y * y)  # z component of the body's z axis
    return math.acos(max(-1.0, min(1.0, up)))


def _rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) of the rotation between two rotation matrices."""
    c = (float(np.trace(a.T @ b)) - 1) / 2
    return math.acos(max(-1.0, min(1.0, c)))


def simulate(
    model,
    traj: Trajectory,
    seconds: float | None = None,
    can_fall: bool = True,
    end_effector: str | None = None,
    progress: Callable[[float], None] | None = None,
    data=None,
    observe: Callable[[float, object], None] | None = None,
) -> SimResult:
    """Run ``traj`` on ``model`` (a mujoco.MjModel) for ``seconds`` (default: the
    trajectory's duration; the trajectory holds its last value after its end), measure what
    the robot did and judge it against what ``traj.info`` promises
    (:func:`export.verdict.judge`; ``SimResult.verdict`` lists the failed criteria).

    ``data``: a ``mujoco.MjData`` to continue from (a program chaining behaviours): the
    robot is not reset to the trajectory's first pose, and the promise (planned pose,
    direction), given for a start at yaw 0, is turned by the yaw the robot starts with.
    ``observe(t, data)`` is called after every physics step (``t`` s since this run began)."""
    import mujoco

    from export.verdict import COLLAPSE_HEIGHT, COLLAPSE_TILT, SATURATION_LEVEL, judge

    chained = data is not None
    if data is None:
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
    seconds = traj.duration if seconds is None else seconds
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive finite number, got {seconds}")
    free = model.njnt > 0 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    act = {model.actuator(k).name: k for k in range(model.nu)}
    columns = []
    for k, name in enumerate(traj.joints):
        if name not in act:
            raise ValueError(f"the model has no actuator for joint {name!r}")
        a = act[name]  # a velocity servo has no position term in its bias
        velocity = model.actuator_biasprm[a, 1] == 0 and model.actuator_biasprm[a, 2] != 0
        columns.append((k, a, bool(velocity)))
    if not chained:
        q0 = traj.positions[0]
        for k, a, _ in columns:  # start in the trajectory's first pose
            jid = model.actuator_trnid[a, 0]
            data.qpos[model.jnt_qposadr[jid]] = q0[k]
        mujoco.mj_forward(model, data)
    start = data.qpos[:3].copy() if free else np.zeros(3)
    com0 = data.subtree_com[1].copy() if free else np.zeros(3)
    yaw0 = _yaw(data.qpos[3:7]) if free else 0.0
    steps = max(1, int(round(seconds / model.opt.timestep)))
    fell_at = None
    ratio = 0.0
    limit = np.maximum(np.abs(model.actuator_forcerange).max(axis=1), 1e-12)
    # the servo law before the actuator's clamp: gain * ctrl + b0 + b1 * length + b2 * velocity
    gain = model.actuator_gainprm[:, 0].copy()
    bias = model.actuator_biasprm[:, :3].copy()
    demand = 0.0
    saturated_steps = 0
    saturated_each = np.zeros(model.nu, dtype=int)
    min_height = math.inf
    max_tilt = 0.0
    times, roots, qs, refs, forces, demands = [], [], [], [], [], []
    every = max(1, steps // 500)
    placed_at = traj.info.get("placed_at_s")
    placed_step = None if placed_at is None else int(round(float(placed_at) / model.opt.timestep))
    placed_step = None if placed_step is None else min(placed_step, steps - 1)
    placed_where = placed_rot = None
    grid = np.arange(steps) * model.opt.timestep
    # the references at every step, resampled once (held at the trajectory's ends)
    ctrl = np.empty((steps, len(columns)))
    ref = np.empty((steps, len(columns)))
    for n, (k, _, velocity) in enumerate(columns):
        ref[:, n] = np.interp(grid, traj.times, traj.positions[:, k])
        ctrl[:, n] = np.interp(grid, traj.times, traj.velocities[:, k]) if velocity else ref[:, n]
    idx = np.array([a for _, a, _ in columns], dtype=int)
    judge_fall = free and can_fall
    for i in range(steps):
        t = grid[i]
        q = ref[i]
        data.ctrl[idx] = ctrl[i]
        mujoco.mj_step(model, data)
        if observe is not None:
            observe(t + model.opt.timestep, data)
        if i == placed_step and end_effector is not None:
            placed_where = data.xpos[model.body(end_effector).id].copy()
            placed_rot = data.xmat[model.body(end_effector).id].reshape(3, 3).copy()
        force = np.abs(data.actuator_force) / limit
        ratio = max(ratio, float(force.max()))
        at_limit = force >= SATURATION_LEVEL
        if at_limit.any():
            saturated_steps += 1
            saturated_each += at_limit
        effort = (
            gain * data.ctrl
            + bias[:, 0]
            + bias[:, 1] * data.actuator_length
            + bias[:, 2] * data.actuator_velocity
        )
        demand = max(demand, float(np.max(np.abs(effort) / limit)))
        if judge_fall:
            height = data.qpos[2] / start[2] if start[2] > 0 else 1.0
            tilt = _tilt(data.qpos[3:7])
            min_height = min(min_height, height)
            max_tilt = max(max_tilt, tilt)
            if fell_at is None and (height < COLLAPSE_HEIGHT or tilt > COLLAPSE_TILT):
                fell_at = t
        if i % every == 0 or i == steps - 1:
            times.append(t)
            roots.append(data.qpos[:7].copy() if free else np.zeros(7))
            qs.append(
                [data.qpos[model.jnt_qposadr[model.actuator_trnid[a, 0]]] for _, a, _ in columns]
            )
            refs.append(q)
            forces.append(data.actuator_force.copy())
            demands.append(np.abs(effort) / limit)
        if progress and i % 500 == 0:
            progress(t / seconds)
    end = data.qpos[:3].copy() if free else np.zeros(3)
    root = np.array(roots)
    heading = 0.0
    if free:  # unwrapped over the samples, so turns past 180 degrees count whole
        heading = float(np.unwrap([_yaw(r[3:7]) for r in root])[-1] - yaw0)
    result = SimResult(
        traj.behavior,
        seconds,
        float(np.hypot(*(end[:2] - start[:2]))),
        heading,
        fell_at is not None,
        fell_at,
        ratio,
        demand_ratio_max=demand,
        saturated_fraction=saturated_steps / steps,
        saturated_joints={
            model.actuator(k).name: float(saturated_each[k] / steps)
            for k in range(model.nu)
            if saturated_each[k]
        },
        min_height_ratio=min_height if judge_fall else None,
        max_tilt_rad=max_tilt if judge_fall else None,
        series={
            "t": np.array(times),
            "root": root,
            "q": np.array(qs),
            "q_ref": np.array(refs),
            "force": np.array(forces),
            "demand": np.array(demands),
        },
    )
    info = traj.info
    motion = info.get("motion")
    turn = np.eye(2)
    if chained and free:  # the promise is given for a start at yaw 0
        turn = np.array([[math.cos(yaw0), -math.sin(yaw0)], [math.sin(yaw0), math.cos(yaw0)]])
    if free:
        plan = info.get("planned_pose")
        if plan is not None:
            dx, dy, dyaw = (float(c) for c in plan)  # type: ignore[union-attr]
            dx, dy = (float(c) for c in turn @ np.array([dx, dy]))
            result.planned_distance_m = math.hypot(dx, dy)
            result.planned_heading_rad = dyaw
            result.final_pose_error_m = float(
                np.hypot(end[0] - start[0] - dx, end[1] - start[1] - dy)
            )
            result.path_length_m = float(info.get("path_length_m") or math.hypot(dx, dy))  # type: ignore[arg-type]
            if motion == "straight" and result.planned_distance_m > 0:
                u = np.array([dx, dy]) / result.planned_distance_m
                result.distance_m = float((end[:2] - start[:2]) @ u)
        if motion == "crawl" and info.get("direction") is not None:
            # the whole body's progress: a snake's head swings with its wave
            u = turn @ np.asarray(info["direction"], dtype=float)[:2]
            u = u / max(float(np.linalg.norm(u)), 1e-12)
            result.distance_m = float((data.subtree_com[1][:2] - com0[:2]) @ u)
        if motion == "hold":
            result.drift_m = result.distance_m
    command = info.get("command")
    if command is not None and free:
        result.tracking_error = _tracking_error(result, command)
    target = info.get("target")
    if target is not None and end_effector is not None:
        # where the gripper let go (info "placed_at_s"), else where it ends
        eid = model.body(end_effector).id
        where = placed_where if placed_where is not None else data.xpos[eid]
        result.placing_error_m = float(np.linalg.norm(where - np.asarray(target)))
        rpy = info.get("orientation_rpy")
        if rpy is not None:
            from kinematics.spatial import matrix_from_rpy

            rot = placed_rot if placed_rot is not None else data.xmat[eid].reshape(3, 3)
            base = data.xmat[1].reshape(3, 3)  # parameters are in the base frame
            result.orientation_error_rad = _rotation_angle(
                base @ matrix_from_rpy(tuple(float(c) for c in rpy)), rot
            )
    # a run stopped before the behaviour's end is judged on falling and saturation only
    result.complete = seconds >= traj.duration - 1e-9
    promise = info if result.complete else {}
    result.verdict = judge(result.to_dict(), promise, free and result.complete)
    return result


TRACK_SCALE = 0.1  # m: turns a yaw-rate error into a speed error (half a track width)


def _tracking_error(result: SimResult, command) -> float:
    """Relative error of the achieved mean (v, w) over the second half of the run:
    |(v - v_cmd, b (w - w_cmd))| / |(v_cmd, b w_cmd)| with b = TRACK_SCALE."""
    v_cmd, w_cmd = command
    t, root = result.series["t"], result.series["root"]
    half = t >= t[-1] / 2
    if half.sum() < 2:
        return float("inf")
    dt = t[half][-1] - t[half][0]
    yaws = np.unwrap([_yaw(qq[3:7]) for qq in root[half]])
    dx = root[half][-1, :2] - root[half][0, :2]
    heading = np.array([math.cos(yaws.mean()), math.sin(yaws.mean())])
    v = float(dx @ heading) / dt
    w = float(yaws[-1] - yaws[0]) / dt
    b = TRACK_SCALE
    want = math.hypot(v_cmd, b * w_cmd)
    return math.hypot(v - v_cmd, b * (w - w_cmd)) / max(want, 1e-9)
