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
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from adron import readers
from adron.errors import InfeasibleError, InputError

if TYPE_CHECKING:
    from export.simulate import SimResult
    from gaits.base import Controller, Trajectory


def check_record(record: object, source: str) -> None:
    """InputError naming ``source``, the key and the value when ``record`` is not a design
    record of this parmor's format (:mod:`export.record_schema`)."""
    from export.record_schema import check_record as check

    check(record, source)


def bundle_record(folder: str | Path, structure: bool = True) -> dict:
    """The design record (``design.json``) of a bundle folder; InputError naming the file
    when it is missing, unreadable or not a record (or, with ``structure``, a conceptual
    design with no structure to run)."""
    folder = Path(folder)
    path = folder / "design.json"
    if not path.exists():
        raise InputError(f"{folder}: no design.json (write one with 'parmor design ... --out DIR')")
    record = readers.read_json(path, what="design record")  # nesting and numbers bounded
    check_record(record, str(path))  # the fields readers use, typed (export/record_schema)
    if structure and record.get("template") is None:
        raise InputError(f"{path}: the design has no structure (designed with --conceptual?)")
    if structure:
        check_geometry(record, str(path))
    return record


def check_geometry(record: Mapping, source: str) -> None:
    """InputError naming ``source`` when the record's ``template``, ``body_plan`` and
    ``lengths_m`` do not make a robot (the one its controller is built for): each field is
    typed on its own (:func:`check_record`), this is how they fit together."""
    from gaits import CONTROLLERS, structure
    from gaits.base import DesignGeometry

    try:
        geometry = DesignGeometry.from_record(record)
        template = geometry.build()
        kind = structure(geometry)
        if kind not in CONTROLLERS:  # (a record whose parts no controller drives)
            raise ValueError(f"its structure is {kind or 'none known'}: no controller drives it")
    except (ValueError, KeyError, TypeError) as e:
        why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise InputError(
            f"{source}: template, body_plan, lengths_m: they do not make the design's robot: {why}"
        ) from None
    listed = {j["name"] for j in record.get("joints") or ()}
    listed |= set(record.get("passive_joints") or ())
    passive = set(getattr(template, "passive", ()) or ())
    moving = [j.name for j in template.model.joints if j.kind != "fixed" and j.name not in passive]
    missing = [n for n in moving if n not in listed]
    if missing:
        raise InputError(
            f"{source}: joints: the robot's joint(s) {', '.join(missing[:6])} are not listed "
            "(a joint's actuator and speed come from its entry)"
        )


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
    perturbation: Mapping | None = None,
) -> SimResult:
    """``traj`` of ``controller`` run on ``model`` and judged (``export.simulate.simulate``
    told whether the robot can fall and where its gripper is; for a ``perturbation`` of
    :mod:`export.perturb`, its command latency and control period)."""
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
        latency_s=float(perturbation["latency_s"]) if perturbation else 0.0,
        command_period_s=float(perturbation["control_period_s"]) if perturbation else 0.0,
        sensor_noise=perturbation.get("imu") if perturbation else None,
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


class UnplannedError(InfeasibleError):
    """A behaviour of the design that cannot be planned with its default parameters on
    the simulated robot: ``behavior``, the ``ability`` it realises and ``why`` (the
    planner's reason, without its advice to choose other targets, which no option of a
    design sets). :mod:`synth.verify` drops a bonus ability for it; a demanded one
    refuses the request with this message."""

    def __init__(self, record: Mapping, behavior: str, ability: str, error: Exception) -> None:
        self.behavior, self.ability = behavior, ability
        self.why = re.sub(r";\s*choose other targets\b", "", str(error))
        super().__init__(
            f"{record.get('robot_type')}: its behaviour {behavior!r} cannot be planned with "
            f"its default parameters on the simulated robot: {self.why}"
        )


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
    trajs = []
    for n in names:
        try:
            trajs.append(controller.run(n))
        except ValueError as e:  # planned on the simulated model (its base where it stands)
            raise UnplannedError(record, n, controller.behaviors[n].realises, e) from None
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
    check_record(record, "design.json")
    return verify_model(record, load_files_model(files), behaviors)


def verify_bundle(folder: str | Path, behaviors: Sequence[str] | None = None) -> list[dict]:
    """:func:`verify_model` on a bundle folder written by ``parmor design --out``."""
    record, model = load_bundle(folder)
    return verify_model(record, model, behaviors)


# --- robust verification: the behaviours under seeded perturbations (export.perturb) -------

#: Figures of a run whose worst value over the perturbed runs a record keeps: key -> "max"
#: (larger is worse) or "min"; ``distance_ratio`` (distance / planned, worst: farthest from
#: 1) and ``heading_error_rad`` (|heading - planned|) are derived (:func:`_criteria`).
WORST = {
    "saturated_fraction": "max",
    "demand_ratio_max": "max",
    "max_torque_ratio": "max",
    "min_height_ratio": "min",
    "max_tilt_rad": "max",
    "distance_ratio": "dev",
    "heading_error_rad": "max",
    "final_pose_error_m": "max",
    "drift_m": "max",
    "tracking_error": "max",
    "placing_error_m": "max",
    "orientation_error_rad": "max",
    "line_lost_s": "max",
    "line_progress_m": "min",
    "obstacle_contact_s": "max",
}


def _criteria(fig: Mapping) -> dict[str, float]:
    """The :data:`WORST` figures of one run (those it has)."""
    out = {k: float(fig[k]) for k in WORST if fig.get(k) is not None}
    planned = fig.get("planned_distance_m")
    if planned and fig.get("distance_m") is not None:
        out["distance_ratio"] = float(fig["distance_m"]) / float(planned)
    if fig.get("planned_heading_rad") is not None and fig.get("heading_rad") is not None:
        out["heading_error_rad"] = abs(
            float(fig["heading_rad"]) - float(fig["planned_heading_rad"])
        )
    return out


#: The perturbed runs' time step as a multiple of the model's (2 ms -> 4 ms), used for a
#: design only where its nominal runs at that step agree with the fine ones
#: (:func:`physics_check`); a perturbed run then costs about 0.55 of a fine one.
COARSE_STEP = 2
#: How far a figure of a coarse nominal run may be from the fine run's (absolute, in the
#: figure's unit) for the coarse step to be used: a tenth or less of each verdict's margin
#: (export/verdict.py: saturation 5 % of the run, placing 5 mm, ...), so a verdict the fine
#: physics gives is not turned by the step. Figures not listed must be equal to 10 %.
AGREE = {
    "saturated_fraction": 0.005,
    "demand_ratio_max": 0.1,
    "max_torque_ratio": 0.05,
    "min_height_ratio": 0.02,
    "max_tilt_rad": 0.02,
    "distance_ratio": 0.03,
    "heading_error_rad": 0.03,
    "final_pose_error_m": 0.003,
    "drift_m": 0.003,
    "tracking_error": 0.03,
    "placing_error_m": 0.0015,
    "orientation_error_rad": 0.01,
    "line_lost_s": 0.05,
    "obstacle_contact_s": 0.02,
}


def coarse_xml(xml: str, factor: int = COARSE_STEP) -> tuple[str, float]:
    """(MJCF text with its time step ``factor`` x longer, that step in s)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml)
    option = root.find("option")
    if option is None:
        option = ET.SubElement(root, "option")
    step = float(option.get("timestep") or 0.002) * factor
    option.set("timestep", f"{step:.12g}")
    return ET.tostring(root, encoding="unicode"), step


def physics_check(
    files: Mapping[str, str | bytes],
    fine: Sequence[Mapping] | None = None,
    behaviors: Sequence[str] | None = None,
) -> dict:
    """Whether this design's perturbed runs may use the coarse step (:data:`COARSE_STEP`):
    its behaviours run nominally at that step give the verdicts of the fine step (``fine``:
    :func:`verify_model`'s figures when the caller has them) with every figure within
    :data:`AGREE`. Returns ``{"timestep_s": step or None (the model's own), "coarse_s":
    the coarse step, "largest": {figure: (difference, behaviour)}, "why": text}``."""
    from export.mjcf import load_mjcf

    record, xml, meshes = bundle_parts(files)
    if fine is None:
        fine = verify_model(record, load_mjcf(xml, meshes), behaviors)
    wanted = [str(f["behavior"]) for f in fine]
    text, step = coarse_xml(xml)
    coarse = verify_model(record, load_mjcf(text, meshes), wanted)
    largest: dict[str, list] = {}
    why = agreement(fine, coarse, largest)
    return {
        "timestep_s": None if why else step,
        "coarse_s": step,
        "largest": dict(sorted(largest.items())),
        "why": why or "every figure of the nominal runs agrees",
    }


def agreement(fine: Sequence[Mapping], coarse: Sequence[Mapping], largest: dict) -> str:
    """Why the runs ``coarse`` (figures by behaviour) do not give the verdicts and figures
    of ``fine`` within :data:`AGREE` ("" when they do); ``largest`` gets each figure's
    largest difference and its behaviour."""
    by_name = {str(c["behavior"]): c for c in coarse}
    why = ""
    for f in fine:
        name = str(f["behavior"])
        c = by_name.get(name)
        if c is None:
            why = why or f"{name}: not run at the coarse step"
            continue
        if (f["verdict"] == "ok") != (c["verdict"] == "ok"):
            why = why or f"{name}: verdict {f['verdict']} at the fine step, {c['verdict']} coarse"
        a, b = _criteria(f), _criteria(c)
        for key in sorted(set(a) | set(b)):
            if key not in a or key not in b:
                why = why or f"{name}: {key} measured at one step only"
                continue
            d = abs(a[key] - b[key])
            tol = AGREE.get(key, 0.1 * max(abs(a[key]), 1e-9))
            if d > largest.get(key, [-1.0, ""])[0]:
                largest[key] = [float(f"{d:.4g}"), name]
            if d > tol:
                why = why or f"{name}: {key} {a[key]:.4g} at the fine step, {b[key]:.4g} coarse"
    return why


def _worse(kind: str, a: float, b: float) -> bool:
    """Is ``a`` worse than ``b`` for a figure of kind ``kind`` (:data:`WORST`)?"""
    if kind == "min":
        return a < b
    if kind == "dev":
        return abs(a - 1.0) > abs(b - 1.0)
    return a > b


def required_passes(k: int, share: float) -> int:
    """Perturbed runs of K a behaviour must pass: ceil(share x K) (at least 1 when K > 0)."""
    import math

    return min(k, max(1 if k else 0, math.ceil(share * k - 1e-9)))


def bundle_parts(files: Mapping[str, str | bytes]) -> tuple[dict, str, dict[str, bytes]]:
    """(record, robot.xml text carrying the payload as ``export.simulate`` loads it, mesh
    file name -> bytes) of a bundle held in memory."""
    from export.simulate import carrying_payload, check_agrees

    def text(v: str | bytes) -> str:
        return v.decode("utf-8") if isinstance(v, bytes) else v

    record = readers.parse_json(text(files["design.json"]), "design.json")
    xml = text(files["robot.xml"])
    check_agrees(xml, record)
    xml = carrying_payload(xml, record)
    meshes = {
        Path(k).name: (v.encode() if isinstance(v, str) else v)
        for k, v in sorted(files.items())
        if k.endswith(".stl")
    }
    return record, xml, meshes


def folder_files(folder: str | Path) -> dict[str, bytes]:
    """design.json, robot.xml and meshes/*.stl of a bundle folder (what a run reads)."""
    folder = Path(folder)
    files = {f"meshes/{p.name}": p.read_bytes() for p in sorted((folder / "meshes").glob("*.stl"))}
    for name in ("design.json", "robot.xml"):
        files[name] = (folder / name).read_bytes()
    return files


def recorded_table(record: Mapping) -> dict:
    """The perturbation table a design was verified with (``verified.robust.table``);
    InputError when the record has none (designed with --robustness 0 or --no-verify)."""
    robust = (record.get("verified") or {}).get("robust") if isinstance(record, Mapping) else None
    table = robust.get("table") if isinstance(robust, Mapping) else None
    if not isinstance(table, Mapping):
        raise InputError(
            "design.json: verified.robust.table is missing: the design was not verified under "
            "perturbation (design it with 'parmor design ... --robustness K --out DIR')"
        )
    return dict(table)


def run_perturbed(
    files: Mapping[str, str | bytes],
    name: str,
    seed: int,
    params: Mapping[str, object] | None = None,
    seconds: float | None = None,
    table: Mapping | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[Trajectory, SimResult, dict]:
    """Behaviour ``name`` of a bundle run under its perturbation ``seed`` (the record's
    table unless ``table`` is given): (trajectory, judged result, the perturbation). The
    controller and its plan are the nominal model's (what the robot's program knows); the
    robot it drives is perturbed."""
    from export.mjcf import load_mjcf
    from export.perturb import draw, perturbed_model

    record, xml, meshes = bundle_parts(files)
    table = recorded_table(record) if table is None else table
    try:
        p = draw(table, seed)
        model = perturbed_model(xml, meshes, table, p)
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"design.json: verified.robust.table: cannot be applied: {e}") from None
    controller = controller_for_model(record, load_mjcf(xml, meshes))
    traj = controller.run(name, **dict(params or {}))
    return traj, _simulate(model, controller, traj, seconds, progress, p), p


def verify_robust(
    files: Mapping[str, str | bytes],
    k: int,
    table: Mapping,
    behaviors: Sequence[str] | None = None,
    only: Collection[str] | None = None,
    sensing: bool = True,
) -> dict:
    """Every listed behaviour of a bundle (default parameters; ``behaviors`` when given,
    the listed ones named in ``only``) run under the perturbations 1..``k`` of ``table``
    (:mod:`export.perturb`) and judged: the record's ``verified.robust``. A behaviour is
    robust when it passes at least :func:`required_passes` of its runs.

    The sensing loops (``line-tracking``, ``obstacle-avoidance``: :mod:`program.sensing`,
    as :func:`program.sensing.verify_sensing` runs them nominally) run on each perturbed
    robot too, from a fresh start, with the perturbation's bus and their sensors' noise
    (:class:`program.session.Session` ``perturb``); their entries say ``"loop":
    "sensing"`` and their failures name the sensors' draws as well (``sensing``: false
    leaves them out).

    The plans are the nominal model's, made once; behaviours with the same plan are run
    once per perturbation (as :func:`verify_model`); the K x runs go on
    ``VERIFY_THREADS`` threads (MuJoCo steps without Python's lock), the sensing loops'
    on as many forked processes (:func:`_sensing_runs`). The results do not depend on
    the threads or processes."""
    import dataclasses
    from concurrent.futures import ThreadPoolExecutor

    from export.mjcf import load_mjcf
    from export.perturb import describe, draw, perturbed_model, summary
    from export.verdict import explain
    from program.sensing import sensing_behaviors

    record, xml, meshes = bundle_parts(files)
    controller = controller_for_model(record, load_mjcf(xml, meshes))
    # the sensing loops (program.sensing) the design's verification runs, by name
    sensed = sorted(sensing_behaviors(controller.behaviors, tuple(record.get("abilities", ()))))
    if behaviors is None:
        names = controller.listed(record.get("abilities", ()))
    else:
        names = [n for n in behaviors if n not in sensed]
        sensed = [n for n in sensed if n in behaviors]
    if only is not None:
        names = [n for n in names if n in only]
        sensed = [n for n in sensed if n in only]
    if not sensing:
        sensed = []
    trajs = []
    for n in names:
        try:
            trajs.append(controller.run(n))
        except ValueError as e:  # planned on the simulated model (its base where it stands)
            raise UnplannedError(record, n, controller.behaviors[n].realises, e) from None
    same: dict[bytes, int] = {}
    first = [same.setdefault(_plan_digest(t), i) for i, t in enumerate(trajs)]
    runs = sorted(set(first))
    seeds = list(range(1, k + 1))
    perturbations = {s: draw(table, s) for s in seeds}
    models = {s: perturbed_model(xml, meshes, table, perturbations[s]) for s in seeds}
    # the sensing loops on the perturbed robots, from a fresh start: Python most of their
    # time, so on processes of their own (threads would wait on each other's lock)
    sensing_jobs = [(s, n) for s in seeds for n in sensed]
    workers = min(VERIFY_THREADS, len(sensing_jobs), os.cpu_count() or 1)
    sensing = _sensing_runs(files, table, sensing_jobs, workers)
    jobs: list[tuple] = [(s, r) for s in seeds for r in runs]

    def one(job: tuple) -> SimResult:
        s, r = job
        return _simulate(models[s], controller, trajs[r], None, None, perturbations[s])

    threads = min(VERIFY_THREADS, len(jobs), os.cpu_count() or 1)
    try:
        if threads > 1:
            with ThreadPoolExecutor(threads) as pool:
                done: dict = dict(zip(jobs, pool.map(one, jobs), strict=True))
        else:
            done = {job: one(job) for job in jobs}
    except BaseException:  # (a time limit, Ctrl-C): the sensing runs are not waited for
        sensing(cancel=True)
        raise
    done |= sensing()
    need = required_passes(k, float(table["share"]))
    out = []
    for i, n in enumerate([*names, *sensed]):
        figs = []
        loop = i >= len(names)  # a sensing loop
        for s in seeds:
            if loop:
                figs.append({"seed": s} | done[(s, n)])  # type: ignore[operator]
                continue
            result = dataclasses.replace(done[(s, first[i])], behavior=trajs[i].behavior)  # type: ignore[arg-type]
            figs.append({"seed": s} | figures(trajs[i], result))
        worst: dict[str, dict] = {}
        for fig in figs:
            for key, value in _criteria(fig).items():
                w = worst.get(key)
                if w is None or _worse(WORST[key], value, w["value"]):
                    worst[key] = {"value": float(f"{value:.6g}"), "seed": fig["seed"]}
        failed = [f for f in figs if f["verdict"] != "ok"]
        passed = len(figs) - len(failed)
        entry = {
            "behavior": n,
            "ability": n if loop else controller.behaviors[n].realises,
            **({"loop": "sensing"} if loop else {}),
            "passed": passed,
            "runs": len(figs),
            "robust": passed >= need,
            "worst": dict(sorted(worst.items())),
            "failures": [
                {
                    "seed": f["seed"],
                    "verdict": f["verdict"],
                    "why": explain(f, f["verdict"]),
                    "perturbation": describe(perturbations[f["seed"]], sensors=loop),
                }
                for f in failed
            ],
            "figures": figs,
        }
        out.append(entry)
    return {
        "k": k,
        "required": need,
        "share": float(table["share"]),
        "perturbations": [summary(perturbations[s]) for s in seeds],
        "behaviors": out,
        "table": dict(table),
    }


def _sensing_run(job: tuple) -> dict:
    """One perturbed sensing run (:func:`_sensing_runs`): (files, name, table, seed) ->
    its figures."""
    from program.sensing import run_sensing

    files, name, table, seed = job
    return run_sensing(files, name, perturb=(table, seed))


def _sensing_runs(
    files: Mapping[str, str | bytes], table: Mapping, jobs: list[tuple[int, str]], workers: int
) -> Callable[..., dict]:
    """The sensing loops' perturbed runs ``jobs`` ((seed, name) each) started on up to
    ``workers`` forked processes (run here, one after another, where the system cannot
    fork or one worker is all there is): a function that waits for them and gives
    (seed, name) -> figures (called with ``cancel=True``: stops them). The figures do not
    depend on where they ran."""
    import multiprocessing

    args = [(dict(files), name, dict(table), seed) for seed, name in jobs]
    if workers <= 1 or "fork" not in multiprocessing.get_all_start_methods():

        def here(cancel: bool = False) -> dict:
            if cancel:
                return {}
            return {job: _sensing_run(a) for job, a in zip(jobs, args, strict=True)}

        return here
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))
    futures = [pool.submit(_sensing_run, a) for a in args]

    def stop() -> None:
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.terminate()
        pool.shutdown(wait=False, cancel_futures=True)

    def wait(cancel: bool = False) -> dict:
        """The runs' figures; with ``cancel``, the runs stopped instead (nothing)."""
        if cancel:
            stop()
            return {}
        try:
            out = {job: f.result() for job, f in zip(jobs, futures, strict=True)}
        except BaseException:  # (a time limit, Ctrl-C): the runs left are not waited for
            stop()
            raise
        pool.shutdown()
        return out

    return wait


def robust_missing(record: Mapping) -> list[str]:
    """The behaviours a verified record lists (``verified.behaviors``, the sensing loops
    included) that passed on the nominal model but are missing from its perturbed runs
    (``verified.robust.behaviors``), name order; none when the record was not verified
    under perturbation. Every behaviour the design lists must have been run under them."""
    verified = record.get("verified") if isinstance(record, Mapping) else None
    robust = verified.get("robust") if isinstance(verified, Mapping) else None
    if not isinstance(robust, Mapping):
        return []
    ran = {b.get("behavior") for b in robust.get("behaviors", ())}
    return sorted(
        {
            b["behavior"]
            for b in verified.get("behaviors", ())
            if b.get("verdict") == "ok" and b["behavior"] not in ran
        }
    )


def robust_failure(robust: Mapping) -> dict[str, str]:
    """Behaviour -> why it is not robust (``verify_robust``'s record): passed k of K, the
    perturbation that broke it worst (most criteria failed, then the lowest seed) and its
    figures against the thresholds."""
    out = {}
    for b in robust.get("behaviors", ()):
        if b["robust"]:
            continue
        worst = max(b["failures"], key=lambda f: (len(f["verdict"]), -f["seed"]))
        out[b["behavior"]] = (
            f"{b['behavior']} is not robust: passed {b['passed']} of {b['runs']} perturbed runs "
            f"(needs {robust['required']}); {worst['perturbation']} broke it: {worst['why']}"
        )
    return out


class Replay:
    """A failed perturbed run of a bundle set up to be replayed with one cause changed:
    the record, the nominal model's controller and its plan of ``behavior`` (what the
    robot's program knows), and perturbation ``seed`` of ``table`` drawn
    (``perturbation``). :meth:`run` simulates a variant of that perturbation on the
    perturbed robot and gives the run's :func:`figures`."""

    def __init__(
        self, files: Mapping[str, str | bytes], table: Mapping, behavior: str, seed: int
    ) -> None:
        from export.mjcf import load_mjcf
        from export.perturb import draw

        self.record, self._xml, self._meshes = bundle_parts(files)
        self.table = table
        self.controller = controller_for_model(self.record, load_mjcf(self._xml, self._meshes))
        self.plan = self.controller.run(behavior)
        self.perturbation = draw(table, seed)

    def run(self, perturbation: Mapping, plan: Trajectory | None = None) -> dict:
        """The figures of ``plan`` (default: the behaviour's default plan) run under
        ``perturbation``."""
        from export.perturb import perturbed_model

        plan = self.plan if plan is None else plan
        model = perturbed_model(self._xml, self._meshes, self.table, perturbation)
        return figures(plan, _simulate(model, self.controller, plan, None, None, perturbation))


def play_attribution(
    files: Mapping[str, str | bytes],
    table: Mapping,
    behavior: str,
    seed: int,
    failed: Mapping | None = None,
) -> dict | None:
    """Does the joints' play break behaviour ``behavior`` of a bundle under perturbation
    ``seed`` of ``table``? ``failed``: that run's figures when they are known already
    (:func:`verify_robust`'s, to the bit: the run is not simulated again). Measured by
    replays of that very perturbation: with every
    position servo's play removed (the rest unchanged) the run must pass, else None (the
    play alone does not break it; None too when the run passes as it is). Then the play
    of each symmetry group of joints (the record's ``group``: alike joints get alike
    servos) is put back, the smallest play first, and kept when the run still passes: the
    groups left are those whose play must go. ``{"verdict": [...], "joints": [...],
    "figures": {"with": ..., "without": ...}}`` (the failed criteria, the joints whose
    play breaks it, the :func:`_criteria` figures of the run with and without play)."""
    replay = Replay(files, table, behavior, seed)
    record, p = replay.record, replay.perturbation
    full = dict(p["play_rad"])

    def run(removed: set[str]) -> dict:
        return replay.run(
            dict(p, play_rad={j: (0.0 if j in removed else v) for j, v in full.items()})
        )

    before = run(set()) if failed is None else failed
    if before["verdict"] == "ok":
        return None
    without = run(set(full))
    if without["verdict"] != "ok":
        return None
    group_of = {j["name"]: j.get("group") or j["name"] for j in record.get("joints", ())}
    groups: dict[str, list[str]] = {}
    for j in full:
        groups.setdefault(group_of.get(j, j), []).append(j)
    order = sorted(groups, key=lambda g: (max(full[j] for j in groups[g]), g))
    removed = set(full)
    for g in order:
        trial = removed - set(groups[g])
        if run(trial)["verdict"] == "ok":
            removed = trial
    return {
        "verdict": list(before["verdict"]),
        "joints": sorted(removed),
        "figures": {"with": _criteria(before), "without": _criteria(without)},
    }
