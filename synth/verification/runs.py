"""The design's behaviours run in MuJoCo: the harness shared by ``parmor simulate``,
``parmor design``'s verification and ``parmor sweep``.

A bundle (:class:`synth.verification.source.Bundle`, on disk or in memory) gives the record
(``design.json``) and the MuJoCo model (``robot.xml`` with its meshes). The controller is
built from the record as a user's program would build it, told where a fixed base stands,
its position servos' stiffness (``stiffness``: joint -> N m/rad, the MJCF's ``kp``;
``damping``: joint -> N m s/rad, its ``kv`` plus the joint's damping) and, on a fixed base
(manipulators), the simulated model's own gravity torques, so that it can compensate the
servos' droop (controllers that take neither are given neither). Every behaviour whose
ability the design lists is run with its default parameters and judged by
:mod:`synth.verification.verdict`: nominally (:func:`verify_nominal`) and under the
perturbations of :mod:`synth.verification.perturb` (:func:`verify_robust`), each perturbed
robot set up once by :class:`Perturbed` (the replay of a recorded run, ``parmor simulate
--perturb``, a program's perturbed session and the loop's replays with one cause changed
all go through it). The results are typed (:mod:`synth.verification.results`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from adron.errors import InfeasibleError, InputError
from gaits import controller_for
from gaits.base import DesignGeometry
from synth.verification.perturb import describe, draw, perturbed_xml, summary, worst_first
from synth.verification.results import (
    BehaviorRuns,
    Failure,
    RobustRuns,
    Run,
    criteria,
    required_passes,
)
from synth.verification.simulate import simulate
from synth.verification.verdict import explain, judge

if TYPE_CHECKING:
    from gaits.base import Controller, Trajectory
    from synth.verification.simulate import SimResult
    from synth.verification.source import Bundle


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
    stop_on_failure: bool = False,
) -> SimResult:
    """``traj`` of ``controller`` run on ``model`` and judged
    (``synth.verification.simulate.simulate`` told whether the robot can fall and where its gripper
    is; for a ``perturbation`` of
    :mod:`synth.verification.perturb`, its command latency and control period)."""

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
        stop_on_failure=stop_on_failure,
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
    design sets). :mod:`synth.verification.loop` drops a bonus ability for it; a demanded one
    refuses the request with this message."""

    def __init__(self, record: Mapping, behavior: str, ability: str, error: Exception) -> None:
        self.behavior, self.ability = behavior, ability
        self.why = re.sub(r";\s*choose other targets\b", "", str(error))
        super().__init__(
            f"{record.get('robot_type')}: its behaviour {behavior!r} cannot be planned with "
            f"its default parameters on the simulated robot: {self.why}"
        )


def _plans(record: Mapping, controller: Controller, names: Sequence[str]) -> list[Trajectory]:
    """The default plans of behaviours ``names`` (:class:`UnplannedError` for one that
    cannot be planned on the simulated robot, its base where it stands)."""
    out = []
    for n in names:
        try:
            out.append(controller.run(n))
        except ValueError as e:
            raise UnplannedError(record, n, controller.behaviors[n].realises, e) from None
    return out


def verify_nominal(bundle: Bundle, behaviors: Sequence[str] | None = None) -> list[Run]:
    """Every listed behaviour of the design (default parameters; ``behaviors`` when given)
    run on its nominal model and judged: one :class:`Run` each, in name order
    (:func:`nominal_runs`)."""
    return nominal_runs(bundle.record, bundle.model(), behaviors, bundle.controller())


def nominal_runs(
    record: Mapping, model, behaviors: Sequence[str] | None = None, controller=None
) -> list[Run]:
    """Every listed behaviour of the design in ``record`` (``behaviors`` when given) run on
    ``model`` (the nominal one, or another build of it: at the coarse step) with
    ``controller`` (default: the one set up for ``model``) and judged.

    The behaviours are planned one after another, then simulated on up to
    ``VERIFY_THREADS`` threads; behaviours with the same plan (the same trajectory and
    promise under another name, e.g. running that the actuators hold to walking's pace)
    are simulated once (a run depends on nothing else: the figures are the same)."""
    import dataclasses
    from concurrent.futures import ThreadPoolExecutor

    if controller is None:
        controller = controller_for_model(record, model)
    names = controller.listed(record.get("abilities", ())) if behaviors is None else list(behaviors)
    trajs = _plans(record, controller, names)
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
        out.append(Run(n, figures(trajs[k], result), controller.behaviors[n].realises))
    return out


def _plan_digest(traj: Trajectory) -> bytes:
    """A digest of everything of ``traj`` a simulation reads (samples, joints, promise),
    its name left out."""
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


#: The perturbed runs' time step as a multiple of the model's (2 ms -> 4 ms), used for a
#: design only where its nominal runs at that step agree with the fine ones
#: (:func:`physics_check`); a perturbed run then costs about 0.55 of a fine one.
COARSE_STEP = 2
#: How far a figure of a coarse nominal run may be from the fine run's (absolute, in the
#: figure's unit) for the coarse step to be used: a tenth or less of each verdict's margin
#: (verdict.py: saturation 5 % of the run, placing 5 mm, ...), so a verdict the fine
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


#: How far a coarse run's support margin may be from the fine run's for the guard band of
#: :func:`near_limit` (m; the margins are not among the nominal runs' compared figures): as
#: a pose's.
SUPPORT_AGREE = 0.003


def near_limit(fig: Mapping, info: Mapping, free: bool) -> bool:
    """Whether a run's verdict could turn within the coarse step's agreement: some figure
    it is judged on (:func:`synth.verification.verdict.judge`), moved by its :data:`AGREE`
    tolerance either way, changes what the verdict says. A perturbed run at the coarse step
    for which this holds is made again at the model's own step, which decides it
    (:meth:`Perturbed.simulate`)."""
    shifts = {
        key: AGREE[key]
        for key in (
            "saturated_fraction", "final_pose_error_m", "drift_m", "placing_error_m",
            "orientation_error_rad", "line_lost_s",
        )
    }  # fmt: skip
    shifts["heading_rad"] = AGREE["heading_error_rad"]
    shifts["support_margin_m"] = SUPPORT_AGREE
    planned = fig.get("planned_distance_m")
    if planned:
        shifts["distance_m"] = AGREE["distance_ratio"] * abs(float(planned))
    before = judge(fig, info, free)
    for key, tol in shifts.items():
        value = fig.get(key)
        if value is None:
            continue
        for sign in (-1.0, 1.0):
            if judge({**fig, key: float(value) + sign * tol}, info, free) != before:
                return True
    return False


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
    bundle: Bundle,
    fine: Sequence[Run] | None = None,
    behaviors: Sequence[str] | None = None,
) -> dict:
    """Whether this design's perturbed runs may use the coarse step (:data:`COARSE_STEP`):
    its behaviours run nominally at that step give the verdicts of the fine step (``fine``:
    :func:`verify_nominal`'s runs when the caller has them) with every figure within
    :data:`AGREE`. Returns ``{"timestep_s": step or None (the model's own), "coarse_s":
    the coarse step, "largest": {figure: (difference, behaviour)}, "why": text}``."""
    if fine is None:
        fine = verify_nominal(bundle, behaviors)
    wanted = [f.behavior for f in fine]
    text, step = coarse_xml(bundle.xml)
    coarse = nominal_runs(bundle.record, bundle.compile(text), wanted)
    largest: dict[str, list] = {}
    why = agreement([f.to_dict() for f in fine], [c.to_dict() for c in coarse], largest)
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
        a, b = criteria(f), criteria(c)
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


class Perturbed:
    """The robot of ``bundle`` under perturbation ``seed`` of ``table`` (or the variant
    ``perturbation`` of it: a replay with one cause changed): the perturbation drawn, its
    MuJoCo model (:meth:`xml`, :meth:`model`: compiled once) and runs of the nominal
    model's plans on it (:meth:`run`: the controller is the nominal model's, what the
    robot's program knows). The one set-up of a perturbed run: the robust verification,
    ``parmor simulate --perturb``, a program's perturbed session and the loop's replays.
    InputError when the table cannot be applied."""

    def __init__(
        self, bundle: Bundle, table: Mapping, seed: int, perturbation: Mapping | None = None
    ) -> None:
        self.bundle, self.table, self.seed = bundle, table, seed
        if perturbation is None:
            try:
                perturbation = draw(table, seed)
            except (KeyError, TypeError, ValueError) as e:
                raise _unapplicable(e) from None
        self.perturbation: dict = dict(perturbation)
        self._model = None

    def varied(self, **changes: object) -> Perturbed:
        """The same robot with some of the perturbation's draws changed (``play_rad``,
        ``control_period_s``...)."""
        return Perturbed(self.bundle, self.table, self.seed, {**self.perturbation, **changes})

    def xml(self) -> str:
        """The perturbed robot's MJCF text."""

        try:
            return perturbed_xml(self.bundle.xml, self.table, self.perturbation)
        except (KeyError, TypeError, ValueError) as e:
            raise _unapplicable(e) from None

    def model(self):
        if self._model is None:
            self._model = self.bundle.compile(self.xml())
        return self._model

    def simulate(
        self,
        plan: Trajectory,
        seconds: float | None = None,
        progress: Callable[[float], None] | None = None,
        stop_on_failure: bool = False,
    ) -> SimResult:
        """``plan`` run on this robot and judged (stopped as soon as it has failed, with
        ``stop_on_failure``: :func:`synth.verification.simulate.simulate`). At the table's
        coarse step (``timestep_s``), a whole run whose verdict could turn within the step's
        agreement (:func:`near_limit`) is made again at the model's own step, which decides
        it (``fine_step`` true)."""
        controller = self.bundle.controller()
        p = self.perturbation
        model = self.model()
        result = _simulate(model, controller, plan, seconds, progress, p, stop_on_failure)
        if not (self.table.get("timestep_s") and result.complete):
            return result
        if not near_limit(result.to_dict(), plan.info, not _fixed_base(model)):
            return result
        own = {k: v for k, v in self.table.items() if k != "timestep_s"}
        fine = Perturbed(self.bundle, own, self.seed, self.perturbation)
        result = fine.simulate(plan, seconds, progress, stop_on_failure)
        result.fine_step = True
        return result

    def run(self, plan: Trajectory, stop_on_failure: bool = False) -> Run:
        """``plan`` run on this robot: its judged figures (with this run's seed)."""
        result = self.simulate(plan, stop_on_failure=stop_on_failure)
        return Run(plan.behavior, figures(plan, result), seed=self.seed)


def _unapplicable(e: Exception) -> InputError:
    return InputError(f"design.json: verified.robust.table: cannot be applied: {e}")


class Replay:
    """A perturbed run of a bundle set up to be replayed with one cause changed: the
    nominal model's controller and its plan of ``behavior`` (what the robot's program
    knows), and the robot of perturbation ``seed`` of ``table`` (``robot``, its draws
    ``perturbation``). :meth:`run` simulates a variant of that perturbation (and of the
    plan) and gives the run."""

    def __init__(self, bundle: Bundle, table: Mapping, behavior: str, seed: int) -> None:
        self.bundle = bundle
        self.record = bundle.record
        self.controller = bundle.controller()
        self.plan = self.controller.run(behavior)
        self.robot = Perturbed(bundle, table, seed)
        self.perturbation = self.robot.perturbation

    def run(
        self,
        perturbation: Mapping | None = None,
        plan: Trajectory | None = None,
        stop_on_failure: bool = False,
    ) -> Run:
        """The run of ``plan`` (default: the behaviour's default plan) under
        ``perturbation`` (default: the run's own changed by these draws); with
        ``stop_on_failure`` (a replay asked only whether it passes), stopped as soon as it
        has failed."""
        robot = self.robot if perturbation is None else self.robot.varied(**perturbation)
        return robot.run(self.plan if plan is None else plan, stop_on_failure)


def run_perturbed(
    bundle: Bundle,
    name: str,
    seed: int,
    params: Mapping[str, object] | None = None,
    seconds: float | None = None,
    table: Mapping | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[Trajectory, SimResult, dict]:
    """Behaviour ``name`` of a bundle run under its perturbation ``seed`` (the record's
    table unless ``table`` is given): (trajectory, judged result, the perturbation)."""
    robot = Perturbed(bundle, recorded_table(bundle.record) if table is None else table, seed)
    robot.model()  # a table that cannot be applied is said before the plan is made
    traj = bundle.controller().run(name, **dict(params or {}))
    return traj, robot.simulate(traj, seconds, progress), robot.perturbation


def verify_robust(
    bundle: Bundle,
    k: int,
    table: Mapping,
    behaviors: Sequence[str] | None = None,
    only: Collection[str] | None = None,
    sensing: bool = True,
    decisive: Collection[str] | None = None,
    probe: bool = False,
    repair: bool = False,
    made: Mapping[tuple, SimResult] | None = None,
) -> RobustRuns:
    """Every listed behaviour of a bundle (default parameters; ``behaviors`` when given,
    the listed ones named in ``only``) run under the perturbations 1..``k`` of ``table``
    (:mod:`synth.verification.perturb`) and judged: the record's ``verified.robust``. A
    behaviour is robust when it passes at least :func:`required_passes` of its runs.

    The sensing loops (``line-tracking``, ``obstacle-avoidance``: :mod:`program.sensing`,
    as :func:`program.sensing.verify_sensing` runs them nominally) run on each perturbed
    robot too, from a fresh start, with the perturbation's bus and their sensors' noise
    (:class:`program.session.Session` ``perturb``); their entries say ``"loop":
    "sensing"`` and their failures name the sensors' draws as well (``sensing``: false
    leaves them out).

    The plans are the nominal model's, made once; behaviours with the same plan are run
    once per perturbation (as :func:`verify_nominal`); the K x runs go on
    ``VERIFY_THREADS`` threads (MuJoCo steps without Python's lock), the sensing loops'
    on as many forked processes (:func:`_sensing_runs`). The results do not depend on
    the threads or processes.

    ``decisive``: the behaviours whose failure decides what is asked of these runs (a
    refusal, a gain scale rejected). Then the runs go a batch at a time, the
    worst-looking perturbations first (:func:`synth.verification.perturb.worst_first`),
    a run of a decisive behaviour stops as soon as it has failed, and they all stop once
    a decisive behaviour has failed more runs than it may (K less the required passes):
    only the behaviours so decided are listed, with the runs made (``stopped`` says the
    order, the runs made and those behaviours). When none is decided, every run is made
    and the result is the one without ``decisive``, to the bit.

    ``probe`` (a round after which a stronger actuator may still be sized): every plan
    runs first under the worst-looking perturbation; when one of those runs fails
    saturated (an actuator at its limit more than the verdict allows), a new sizing
    follows whatever the other runs give, so they stop there: only the plans whose run
    so failed are listed (``stopped["probe"]`` true). Otherwise the other runs are made
    and the result is the one without ``probe``, to the bit.

    ``repair`` (a round after which a repair may follow: a cause of
    :mod:`synth.verification.causes` answers a failed run with a new sizing, gains or a
    pace, and the next round makes every run again): the runs go a batch at a time, the
    worst-looking perturbations first, each run whole, and stop after the first batch after
    which a plan has failed more runs than it may (K less the passes needed: with every run
    needed, its first failure): only those plans are listed (``stopped["repair"]`` true).
    A round whose every run passes makes them all, and the result is the one without
    ``repair``, to the bit.

    ``made``: runs made before (an earlier call's ``RobustRuns.made``): a run of the same
    robot (model text and table), perturbation and plan is taken from there rather than
    made again (the same result to the bit: the physics is deterministic); runs stopped
    before their end are not kept."""
    import dataclasses
    from concurrent.futures import ThreadPoolExecutor

    from program.sensing import sensing_behaviors

    record = bundle.record
    controller = bundle.controller()
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
    trajs = _plans(record, controller, names)
    same: dict[bytes, int] = {}
    digests = [_plan_digest(t) for t in trajs]
    first = [same.setdefault(d, i) for i, d in enumerate(digests)]
    made = made or {}
    robot_key = hashlib.sha256(
        json.dumps([bundle.xml, table], sort_keys=True, default=str).encode()
    ).digest()
    runs = sorted(set(first))
    seeds = list(range(1, k + 1))
    robots = {s: Perturbed(bundle, table, s) for s in seeds}
    for s, robot in robots.items():  # compiled here, not on the threads (where run)
        if any((robot_key, s, digests[r]) not in made for r in runs):
            robot.model()
    need = required_passes(k, float(table["share"]))
    # the sensing loops on the perturbed robots, from a fresh start: Python most of their
    # time, so on processes of their own (threads would wait on each other's lock)
    sensing_jobs = [(s, n) for s in seeds for n in sensed]
    workers = min(VERIFY_THREADS, len(sensing_jobs), os.cpu_count() or 1)
    early = decisive is not None
    repair = repair and not early
    order = worst_first(table, seeds) if early or repair else seeds
    jobs: list[tuple] = [(s, r) for s in order for r in runs]
    deciding = {first[i] for i, n in enumerate(names) if n in (decisive or ())}

    def one(job: tuple) -> SimResult:
        s, r = job
        before = made.get((robot_key, s, digests[r]))
        if before is not None:
            return before
        return robots[s].simulate(trajs[r], stop_on_failure=r in deciding)

    def beyond(runs: Mapping[tuple, SimResult], plans: Collection[int] | None = None) -> set[int]:
        """The plans (of ``plans``, default all) that failed more of ``runs`` than they may
        (K less the passes needed)."""
        failed: dict[int, int] = {}
        for (_, r), res in runs.items():
            if plans is None or r in plans:
                failed[r] = failed.get(r, 0) + (not res.ok)
        return {r for r, f in failed.items() if f > k - need}

    def in_batches(plans: Collection[int] | None) -> set[int]:
        """The runs of ``jobs`` not made yet, a batch (one run a thread) at a time in their
        order, until one of ``plans`` (default all) has failed more runs than it may: those
        plans; when none has, the sensing loops' runs too and the empty set."""
        n = max(threads, 1)
        with ThreadPoolExecutor(n) as pool:
            for a in range(0, len(jobs), n):
                batch = jobs[a : a + n]
                done.update(zip(batch, pool.map(one, batch), strict=True))
                decided = beyond(done, plans)
                if decided:
                    return decided
        if sensing_jobs:
            done.update(_sensing_runs(bundle.files, table, sensing_jobs, workers)())
        return set()

    threads = min(VERIFY_THREADS, len(jobs), os.cpu_count() or 1)
    done: dict = {}
    decided: set[int] = set()  # the plans that can no longer pass (early only)
    probed = repaired = False
    if probe and not early:
        # the worst-looking perturbation of every plan first: a run of it that saturates
        # calls for a stronger actuator whatever the other runs give
        lead_seed = worst_first(table, seeds)[0]
        lead = [(lead_seed, r) for r in runs]
        with ThreadPoolExecutor(max(min(threads, len(lead)), 1)) as pool:
            done = dict(zip(lead, pool.map(one, lead), strict=True))
        # (failed saturated: a run failing on its pose or turn with an actuator touching
        # its limit on the way is left to the whole round, as every other failure)
        decided = {r for (_, r), res in done.items() if "saturated" in res.verdict}
        if not decided and repair:  # failed otherwise: a repair answers it
            decided = beyond(done)
            repaired = bool(decided)
        probed = bool(decided) and not repaired
        order = [lead_seed] if decided else order
        jobs = [j for j in jobs if j not in done]
    if repair and not decided:
        # the worst-looking perturbations first, until a plan fails more runs than it may
        decided = in_batches(None)
        if decided:
            order = list(dict.fromkeys(s for s, _ in done))
            repaired = True
    elif not early and not probed and not repaired:
        wait = _sensing_runs(bundle.files, table, sensing_jobs, workers)
        try:
            if threads > 1 and jobs:
                with ThreadPoolExecutor(threads) as pool:
                    done |= dict(zip(jobs, pool.map(one, jobs), strict=True))
            else:
                done |= {job: one(job) for job in jobs}
        except BaseException:  # (a time limit, Ctrl-C): the sensing runs are not waited for
            wait(cancel=True)
            raise
        done |= wait()
    elif early:
        # the worst-looking perturbations first, until a deciding plan fails more runs
        # than it may
        decided = in_batches(deciding)
    out = []
    for i, n in enumerate([*names, *sensed]):
        loop = i >= len(names)  # a sensing loop
        if decided and (loop or first[i] not in decided):
            continue  # stopped before its verdict was known
        figs = []
        for s in seeds:
            if decided and (s, first[i]) not in done:
                continue
            if loop:
                figs.append(Run(n, done[(s, n)], seed=s))
                continue
            result = dataclasses.replace(done[(s, first[i])], behavior=trajs[i].behavior)
            figs.append(Run(n, figures(trajs[i], result), seed=s))

        def failure(run: Run, loop: bool = loop) -> Failure:
            fig = run.figures
            p = robots[run.seed].perturbation  # type: ignore[index]
            return Failure(
                run.seed, fig["verdict"], explain(fig, fig["verdict"]), describe(p, sensors=loop)
            )  # type: ignore[arg-type]

        ability = n if loop else controller.behaviors[n].realises
        out.append(
            BehaviorRuns.judged(n, ability, figs, need, failure, "sensing" if loop else None)
        )
    return RobustRuns(
        k,
        need,
        float(table["share"]),
        tuple(summary(robots[s].perturbation) for s in seeds),
        tuple(out),
        dict(table),
        stopped=None
        if not decided
        else {
            "order": list(order),
            "runs": len(done),
            "decided": sorted(names[i] for i in range(len(names)) if first[i] in decided),
        }
        | ({"probe": True} if probed else {})
        | ({"repair": True} if repaired else {}),
        made={
            (robot_key, s, digests[r]): res
            for (s, r), res in done.items()
            if isinstance(r, int) and res.complete
        },
    )


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
