"""The design's behaviours run in MuJoCo: the harness shared by ``parmor simulate``,
``parmor design``'s verification and ``parmor sweep``.

A bundle (on disk or in memory) gives the record (``design.json``) and the MuJoCo model
(``robot.xml`` with its meshes). The controller is built from the record as a user's
program would build it, told where a fixed base stands, its position servos' stiffness
(``stiffness``: joint -> N m/rad, the MJCF's ``kp``; ``damping``: joint -> N m s/rad, its
``kv`` plus the joint's damping) and, on a fixed base (manipulators),
the simulated model's own gravity torques, so that it can compensate the servos' droop
(controllers that take neither are given neither). Every behaviour whose ability the design lists is
run with its default parameters and judged by :mod:`export.verdict`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from adron import readers
from adron.errors import InputError

if TYPE_CHECKING:
    from export.simulate import SimResult
    from gaits.base import Controller, Trajectory


def bundle_record(folder: str | Path, structure: bool = True) -> dict:
    """The design record (``design.json``) of a bundle folder; InputError naming the file
    when it is missing, unreadable or not a record (or, with ``structure``, a conceptual
    design with no structure to run)."""
    folder = Path(folder)
    path = folder / "design.json"
    if not path.exists():
        raise InputError(f"{folder}: no design.json (write one with 'parmor design ... --out DIR')")
    record = readers.read_json(path, what="design record")  # nesting and numbers bounded
    if not isinstance(record, dict):
        raise InputError(f"{path}: not a design record (expected an object)")
    if structure and record.get("template") is None:
        raise InputError(f"{path}: the design has no structure (designed with --conceptual?)")
    return record


def load_bundle(folder: str | Path) -> tuple[dict, object]:
    """(record, MuJoCo model) of a bundle folder; InputError when either cannot be read."""
    record = bundle_record(folder)
    return record, load_model(folder)


def load_model(folder: str | Path):
    """The MuJoCo model of a bundle folder (robot.xml and its meshes), checked to hold a
    robot; InputError naming the folder when it cannot be read or holds none."""
    from export.simulate import load_bundle_model

    try:
        model = load_bundle_model(folder)
    except InputError as e:  # its design.json
        raise InputError(f"{Path(folder) / str(e)}") from None
    except (OSError, ValueError, KeyError, SyntaxError) as e:  # xml.etree's ParseError too
        why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise InputError(f"{folder}: cannot load the MuJoCo model robot.xml: {why}") from None
    if model.nbody < 2:
        raise InputError(f"{folder}/robot.xml: no robot body (not a model parmor wrote)")
    return model


def _fixed_base(model) -> bool:
    import mujoco

    return not (model.njnt > 0 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE)


def _joint_actuators(model) -> dict[str, int]:
    return {model.actuator(k).name: k for k in range(model.nu)}


def mujoco_gravity(model, joints: Sequence[str]) -> Callable[[np.ndarray], np.ndarray]:
    """(N, nj) positions of ``joints`` -> (N, nj) torques N m that hold the model still there
    (MuJoCo's bias forces at zero velocity: gravity), the other joints at 0."""
    import mujoco

    data = mujoco.MjData(model)
    qadr = [model.jnt_qposadr[model.joint(j).id] for j in joints]
    dadr = [model.jnt_dofadr[model.joint(j).id] for j in joints]

    def gravity(q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty_like(q)
        data.qvel[:] = 0
        for n, row in enumerate(q):
            data.qpos[qadr] = row
            mujoco.mj_forward(model, data)
            out[n] = data.qfrc_bias[dadr]
        return out

    return gravity


def controller_for_model(record: Mapping, model) -> Controller:
    """The controller of the design in ``record``, set up for the MuJoCo ``model``."""
    from gaits import controller_for
    from gaits.base import DesignGeometry

    try:
        geometry = DesignGeometry.from_record(record)
    except KeyError as e:
        raise InputError(f"design.json: missing key {e} (not a record parmor wrote)") from None
    except (TypeError, ValueError, AttributeError) as e:
        raise InputError(f"design.json: malformed design record: {e}") from None
    options: dict[str, object] = {"base_position": tuple(float(x) for x in model.body(1).pos)}
    acts = _joint_actuators(model)
    stiffness = {
        name: float(model.actuator_gainprm[a, 0])
        for name, a in acts.items()
        if model.actuator_biasprm[a, 1] != 0  # position servos
    }
    # every controller that takes them gets its servos' stiffness (N m/rad) and velocity
    # gain (N m s/rad: kv plus the joint's damping; a servo lags a moving reference by
    # damping / kp s); a fixed base also the simulated model's gravity torques, for the droop
    options["stiffness"] = stiffness
    options["damping"] = {
        name: float(
            -model.actuator_biasprm[a, 2]
            + model.dof_damping[model.jnt_dofadr[model.actuator_trnid[a, 0]]]
        )
        for name, a in acts.items()
        if name in stiffness
    }
    if _fixed_base(model):
        options["gravity"] = mujoco_gravity(model, list(stiffness))
    return controller_for(geometry, **options)


def run_behavior(
    model,
    controller: Controller,
    name: str,
    params: Mapping[str, object] | None = None,
    seconds: float | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[Trajectory, SimResult]:
    """Run behaviour ``name`` of ``controller`` on ``model``: (trajectory, judged result).
    ValueError for an unknown behaviour or parameter (the message lists the valid ones)."""
    traj = controller.run(name, **dict(params or {}))
    return traj, _simulate(model, controller, traj, seconds, progress)


def _simulate(
    model,
    controller: Controller,
    traj: Trajectory,
    seconds: float | None = None,
    progress: Callable[[float], None] | None = None,
) -> SimResult:
    """``traj`` of ``controller`` run on ``model`` and judged (``export.simulate.simulate``
    told whether the robot can fall and where its gripper is)."""
    from export.simulate import simulate

    tmpl = controller.template
    body = traj.info.get("tool_body")
    if body is None and tmpl.end_effectors:
        body = tmpl.end_effectors[0]
    return simulate(
        model,
        traj,
        seconds,
        can_fall=bool(tmpl.feet or tmpl.wheels),
        end_effector=str(body) if body is not None else None,
        progress=progress,
    )


def figures(traj: Trajectory, result: SimResult) -> dict:
    """The judged figures of one run (``parmor simulate --json``)."""
    rec = result.to_dict()
    margin = traj.info.get("stability_margin_m")
    if margin is not None:
        rec["min_stability_margin_m"] = float(f"{min(margin):.6g}")  # type: ignore[call-overload]
    return rec


#: Simulations of one verification run at once, each on a thread of its own (MuJoCo steps
#: without Python's lock); the results do not depend on it.
VERIFY_THREADS = 2


def verify_model(record: Mapping, model, behaviors: Sequence[str] | None = None) -> list[dict]:
    """Every listed behaviour of the design (default parameters) run and judged: one
    :func:`figures` dict each, in name order.

    The behaviours are planned one after another, then simulated on up to
    ``VERIFY_THREADS`` threads; behaviours with the same plan (the same trajectory and
    promise under another name, e.g. running that the actuators hold to walking's pace)
    are simulated once (a run depends on nothing else: the figures are the same)."""
    import dataclasses
    from concurrent.futures import ThreadPoolExecutor

    controller = controller_for_model(record, model)
    names = controller.listed(record.get("abilities", ())) if behaviors is None else list(behaviors)
    trajs = [controller.run(n) for n in names]
    same: dict[bytes, int] = {}
    first = [same.setdefault(_plan_digest(t), k) for k, t in enumerate(trajs)]
    runs = sorted(set(first))
    threads = min(VERIFY_THREADS, len(runs), os.cpu_count() or 1)
    if threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            done = list(pool.map(lambda k: _simulate(model, controller, trajs[k]), runs))
    else:
        done = [_simulate(model, controller, trajs[k]) for k in runs]
    results = dict(zip(runs, done, strict=True))
    out = []
    for k, n in enumerate(names):
        result = dataclasses.replace(results[first[k]], behavior=trajs[k].behavior)
        fig = figures(trajs[k], result)
        out.append({"behavior": n, "ability": controller.behaviors[n].realises} | fig)
    return out


def _plan_digest(traj: Trajectory) -> bytes:
    """A digest of everything of ``traj`` a simulation reads (samples, joints, promise),
    its name left out."""
    import hashlib

    h = hashlib.blake2b(digest_size=20)

    def feed(x: object) -> None:
        if isinstance(x, np.ndarray):
            h.update(f"a{x.dtype.str}{x.shape}".encode())
            h.update(np.ascontiguousarray(x).tobytes())
        elif isinstance(x, Mapping):
            h.update(b"m%d" % len(x))
            for k in sorted(x, key=str):
                feed(str(k))
                feed(x[k])
        elif isinstance(x, (list, tuple)):
            h.update(b"s%d" % len(x))
            for v in x:
                feed(v)
        else:
            h.update(f"{type(x).__name__}:{x!r};".encode())

    feed([traj.times, traj.joints, traj.positions, traj.velocities, traj.info])
    return h.digest()


def verify_files(
    files: Mapping[str, str | bytes], behaviors: Sequence[str] | None = None
) -> list[dict]:
    """:func:`verify_model` on a bundle held in memory (``Outcome.files``)."""
    from export.simulate import load_files_model

    raw = files["design.json"]
    text = raw.decode("utf-8") if isinstance(raw, bytes) else raw
    record = readers.parse_json(text, "design.json")
    return verify_model(record, load_files_model(files), behaviors)


def verify_bundle(folder: str | Path, behaviors: Sequence[str] | None = None) -> list[dict]:
    """:func:`verify_model` on a bundle folder written by ``parmor design --out``."""
    record, model = load_bundle(folder)
    return verify_model(record, model, behaviors)
