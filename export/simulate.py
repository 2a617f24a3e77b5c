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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaits.base import Trajectory

FALL_HEIGHT = 0.5  # of the start height
FALL_TILT = math.radians(60)


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
    series: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        def r(x):
            return None if x is None else float(f"{x:.6g}")

        return {
            "behavior": self.behavior,
            "seconds": r(self.seconds),
            "distance_m": r(self.distance_m),
            "heading_rad": r(self.heading_rad),
            "fell": self.fell,
            "fell_at_s": r(self.fell_at_s),
            "max_torque_ratio": r(self.max_torque_ratio),
            "tracking_error": r(self.tracking_error),
            "placing_error_m": r(self.placing_error_m),
        }


def load_bundle_model(folder: str | Path):
    """The MuJoCo model of a bundle folder (robot.xml with its meshes)."""
    from export.mjcf import load_mjcf

    folder = Path(folder)
    meshes = {p.name: p.read_bytes() for p in sorted((folder / "meshes").glob("*.stl"))}
    return load_mjcf((folder / "robot.xml").read_text(encoding="utf-8"), meshes)


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _tilt(quat: np.ndarray) -> float:
    w, x, y, z = quat
    up = 1 - 2 * (x * x + y * y)  # z component of the body's z axis
    return math.acos(max(-1.0, min(1.0, up)))


def simulate(
    model,
    traj: Trajectory,
    seconds: float | None = None,
    can_fall: bool = True,
    end_effector: str | None = None,
    progress: Callable[[float], None] | None = None,
) -> SimResult:
    """Run ``traj`` on ``model`` (a mujoco.MjModel) for ``seconds`` (default: the
    trajectory's duration; the trajectory holds its last value after its end)."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    seconds = traj.duration if seconds is None else seconds
    free = model.njnt > 0 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    act = {model.actuator(k).name: k for k in range(model.nu)}
    columns = []
    for k, name in enumerate(traj.joints):
        if name not in act:
            raise ValueError(f"the model has no actuator for joint {name!r}")
        a = act[name]  # a velocity servo has no position term in its bias
        velocity = model.actuator_biasprm[a, 1] == 0 and model.actuator_biasprm[a, 2] != 0
        columns.append((k, a, bool(velocity)))
    q0 = traj.positions[0]
    for k, a, _ in columns:  # start in the trajectory's first pose
        jid = model.actuator_trnid[a, 0]
        data.qpos[model.jnt_qposadr[jid]] = q0[k]
    mujoco.mj_forward(model, data)
    start = data.qpos[:3].copy() if free else np.zeros(3)
    yaw0 = _yaw(data.qpos[3:7]) if free else 0.0
    steps = int(round(seconds / model.opt.timestep))
    fell_at = None
    ratio = 0.0
    limit = np.maximum(np.abs(model.actuator_forcerange).max(axis=1), 1e-12)
    times, roots, qs, refs, forces = [], [], [], [], []
    every = max(1, steps // 500)
    placed_at = traj.info.get("placed_at_s")
    placed_step = None if placed_at is None else int(round(float(placed_at) / model.opt.timestep))
    placed_where = None
    grid = np.arange(steps) * model.opt.timestep
    # the references at every step, resampled once (held at the trajectory's ends)
    ctrl = np.empty((steps, len(columns)))
    ref = np.empty((steps, len(columns)))
    for n, (k, _, velocity) in enumerate(columns):
        ref[:, n] = np.interp(grid, traj.times, traj.positions[:, k])
        ctrl[:, n] = np.interp(grid, traj.times, traj.velocities[:, k]) if velocity else ref[:, n]
    idx = np.array([a for _, a, _ in columns], dtype=int)
    for i in range(steps):
        t = grid[i]
        q = ref[i]
        data.ctrl[idx] = ctrl[i]
        mujoco.mj_step(model, data)
        if i == placed_step and end_effector is not None:
            placed_where = data.xpos[model.body(end_effector).id].copy()
        ratio = max(ratio, float(np.max(np.abs(data.actuator_force) / limit)))
        if (
            free
            and can_fall
            and fell_at is None
            and (data.qpos[2] < FALL_HEIGHT * start[2] or _tilt(data.qpos[3:7]) > FALL_TILT)
        ):
            fell_at = t
        if i % every == 0:
            times.append(t)
            roots.append(data.qpos[:7].copy() if free else np.zeros(7))
            qs.append(
                [data.qpos[model.jnt_qposadr[model.actuator_trnid[a, 0]]] for _, a, _ in columns]
            )
            refs.append(q)
            forces.append(data.actuator_force.copy())
        if progress and i % 500 == 0:
            progress(t / seconds)
    end = data.qpos[:3] if free else np.zeros(3)
    result = SimResult(
        traj.behavior,
        seconds,
        float(np.hypot(*(end[:2] - start[:2]))),
        (_yaw(data.qpos[3:7]) - yaw0 + math.pi) % (2 * math.pi) - math.pi if free else 0.0,
        fell_at is not None,
        fell_at,
        ratio,
        series={
            "t": np.array(times),
            "root": np.array(roots),
            "q": np.array(qs),
            "q_ref": np.array(refs),
            "force": np.array(forces),
        },
    )
    command = traj.info.get("command")
    if command is not None and free:
        result.tracking_error = _tracking_error(result, command)
    target = traj.info.get("target")
    if target is not None and end_effector is not None:
        # where the gripper let go (info "placed_at_s"), else where it ends
        where = placed_where if placed_where is not None else data.xpos[model.body(end_effector).id]
        result.placing_error_m = float(np.linalg.norm(where - np.asarray(target)))
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
