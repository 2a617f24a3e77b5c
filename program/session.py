"""Running a program on a design in MuJoCo: behaviours chained from where the last ended.

A :class:`Session` holds one simulation of a bundle's ``robot.xml``. ``do(behaviour,
**params)`` plans the behaviour with the design's controller, moves the joints from where
they are to the behaviour's first pose (a minimum-jerk blend, :data:`BLEND_SPEED_SHARE`
of each servo's no-load speed, at least :data:`BLEND_MIN_S`), then runs it and judges it
like ``parmor simulate`` does, against its promise turned to the heading the robot
started it with. ``wait(s)`` holds the pose. ``report(name)`` answers
:data:`program.script.REPORTS`.

The program's verdict (:meth:`Session.result`): every behaviour kept its promise, the
robot never fell, and it ended within :data:`END_POSE_FRACTION` of the commanded path
length of where the composed commanded poses put it (the loosest single-behaviour
allowance, straight travel's 1.25 x). Behaviours that promise no end pose (a snake's
crawl, a rotation, holding) are judged on their own criteria, and the commanded pose is
re-anchored where the robot is after them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from adron.errors import InputError, ParmorError
from gaits.base import min_jerk, quat_yaw
from program.script import LIMITS, REPORTS, ProgramError, execute, validate
from synth.verification.simulate import ServoLaw, _ClosedLoop, simulate, start_closed, step_through
from synth.verification.verdict import COLLAPSE_TILT, SATURATION_LEVEL, judge

BLEND_MIN_S = 0.3  # s: shortest move to a behaviour's first pose
BLEND_SPEED_SHARE = 0.3  # of a servo's no-load speed, for that move's peak speed
BLEND_SKIP_RAD = 1e-3  # no move when every joint is this close to the first pose
END_POSE_FRACTION = 0.25  # of the commanded path: how far from the commanded end it may end
ANIMATION_FPS = 20  # frames per simulated second in ``animation``
PATH_HZ = 20  # path samples per simulated second
#: A behaviour parameter of this name is filled, when the program does not set it, with the
#: root body's roll about its own x axis (rad, right-handed) since the start, as an IMU on
#: it would read it: a snake that rolled on its side plans its next gait for that.
SENSED_ROLL = "roll"


def _round(x: float) -> float:
    return float(f"{x:.6g}")


def program_behaviors(controller, abilities) -> dict:
    """The behaviours a program may call on a design with this controller and these
    abilities (name -> BehaviorSpec, name order): those the design lists, and its sensing
    behaviours (:mod:`program.sensing`). The session, the block page's toolbox and its
    server all offer exactly these."""
    from program.sensing import sensing_behaviors

    # (each as a program sees it: at the pace the design's verification chose)
    out = {n: controller.offered(n) for n in controller.listed(abilities)}
    out.update(sensing_behaviors(controller.behaviors, tuple(abilities)))
    return dict(sorted(out.items()))


class Session:
    """One chained simulation of a bundle (a folder written by ``parmor design --out``)."""

    def __init__(
        self,
        folder: str | Path | None = None,
        progress: Callable[[str], None] | None = None,
        files: Mapping[str, str | bytes] | None = None,
        perturb: tuple[Mapping, int] | None = None,
        animate: bool = True,
    ) -> None:
        """The bundle in ``folder``, or held in memory as ``files`` (``Outcome.files``).

        ``perturb``: (table, seed) of :mod:`synth.verification.perturb` (a design's
        ``verified.robust.table``): the robot is that perturbation's (masses, floor,
        battery, play, compliance), its commands reach the servos ``latency`` late and
        held for each control period, its plans' feedback loops read the IMU with its noise
        and its sensing loops their sensors with theirs (:class:`program.sensing.
        SensorNoise`), as a robust verification runs it; the controller is the nominal
        model's (what the robot's program knows). ``animate``: record the animation's
        frames (a verification, which shows none, saves a tenth of a walker's run)."""
        import mujoco

        from program.sensing import SensorNoise, scene_xml, sensing_behaviors
        from synth.verification.runs import controller_for_model
        from synth.verification.source import Bundle

        if files is None:
            if folder is None:
                raise ValueError("a Session needs a bundle folder or its files")
            folder = Path(folder)
            bundle = Bundle.read(folder)
        else:
            bundle = Bundle(files)
        self.record = bundle.record
        try:
            self.model = bundle.compile(scene_xml(bundle.xml))
        except ValueError as e:  # no worldbody
            raise InputError(f"{bundle.source}: cannot load the MuJoCo model: {e}") from None
        self.folder = folder
        self.controller = controller_for_model(self.record, self.model)
        #: the perturbation drawn (``perturb``), None for the nominal robot
        self.perturbation: dict | None = None
        #: what the sensing loops' sensors add to the truth (nothing on the nominal robot)
        self.noise = SensorNoise(None)
        if perturb is not None:
            self.model = self._perturbed(bundle, *perturb)
            self.noise = SensorNoise(self.perturbation.get("sensing"))  # type: ignore[union-attr]
        # the bus (a perturbed robot's): commands reach the servos this many physics steps
        # late, and change once every ``_hold`` steps (the main module's control period)
        p, dt = self.perturbation, self.model.opt.timestep
        self._delay = int(round(p["latency_s"] / dt)) if p else 0
        self._hold = max(1, int(round(p["control_period_s"] / dt))) if p else 1
        self._sent: np.ndarray | None = None  # the last _delay + _hold commands sent
        self._step = 0  # physics steps run so far (the bus's clock)
        abilities = tuple(self.record.get("abilities", ()))
        #: the behaviours a program may call: name -> BehaviorSpec
        self.behaviors = program_behaviors(self.controller, abilities)
        #: the sensing behaviours among them (closed loops, :mod:`program.sensing`)
        self.sensing = sensing_behaviors(self.controller.behaviors, abilities)
        #: the line a line follower follows, (N, 2) m, once one ran
        self.scene_line: np.ndarray | None = None
        self._counts = {"steps": 0, "saturated": 0, "contacts": 0}
        #: a geom whose contacts ``_play`` counts (an obstacle), or None
        self.watched_geom: int | None = None
        #: called after every physics step of ``_play`` with the time (s): a sensing loop
        #: reading its sensors while the robot moves
        self.on_step: Callable[[float], None] | None = None
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        self.free = self.model.njnt > 0 and self.model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
        tmpl = self.controller.template
        #: a robot on feet or wheels can fall; a snake rolls over by design, an arm is fixed
        self.can_fall = self.free and bool(tmpl.feet or tmpl.wheels)
        self.progress = progress
        self.started = False
        self.time = 0.0
        self.steps: list[dict] = []
        self.fell = False
        self._last_distance = 0.0
        self._last_ok = True
        self._yaws: list[float] = []  # unwrapped heading at each path sample
        self._path: dict[str, list[float]] = {"t": [], "x": [], "y": [], "yaw": []}
        self._frames: list[dict] = []
        self.animate = animate
        self._expected = np.zeros(3)  # commanded (x, y, yaw), composed
        self._commanded_path = 0.0
        self._anchored = False
        self._geoms = self._animated_geoms()
        self._origin = np.zeros(3)

    def _perturbed(self, bundle, table: Mapping, seed: int):
        """The robot's model under perturbation ``seed`` of ``table`` (its scene included:
        :class:`synth.verification.runs.Perturbed`); sets :attr:`perturbation`.
        InputError when the table cannot be applied."""
        from program.sensing import scene_xml
        from synth.verification.runs import Perturbed

        robot = Perturbed(bundle, table, seed)
        model = bundle.compile(scene_xml(robot.xml()))
        self.perturbation = robot.perturbation
        return model

    # -- what a program calls --------------------------------------------------------

    def do(self, behavior: str, **params: object) -> dict:
        """Run one behaviour from where the robot is; its judged figures."""
        from synth.verification.runs import figures

        spec = self.behaviors.get(behavior)
        if spec is None:
            raise ProgramError(
                f"{behavior!r}: the design has no behaviour of that name "
                f"(behaviours: {', '.join(sorted(self.behaviors))})"
            )
        if behavior in self.sensing:
            return self._sense(behavior, spec, params)
        params = dict(params)
        if SENSED_ROLL in {p.name for p in spec.params} and SENSED_ROLL not in params:
            params[SENSED_ROLL] = self._roll() if self.started else 0.0
        try:
            traj = self.controller.run(behavior, **params)
        except ValueError as exc:
            raise ProgramError(f"{behavior}: {exc}") from None
        self._note(f"{behavior} {self._params_text(params)}")
        if not self.started:
            self._start(traj.positions[0], traj.joints)
        else:
            self._blend_to(traj.joints, traj.positions[0])
        self._check_time(traj.duration)
        start = self._pose()
        tmpl = self.controller.template
        body = traj.info.get("tool_body")
        if body is None and tmpl.end_effectors:
            body = tmpl.end_effectors[0]
        t0 = self.time
        p = self.perturbation
        result = simulate(
            self.model,
            traj,
            can_fall=self.can_fall,
            end_effector=str(body) if body is not None else None,
            data=self.data,
            observe=lambda t, d: self._observe(t0 + t, d),
            observe_every=1 / max(PATH_HZ, ANIMATION_FPS),
            latency_s=float(p["latency_s"]) if p else 0.0,
            command_period_s=float(p["control_period_s"]) if p else 0.0,
            sensor_noise=p.get("imu") if p else None,
        )
        self.time = t0 + result.seconds
        if p:  # the bus after it: the commands it ended on
            self._step += int(round(result.seconds / self.model.opt.timestep))
            self._sent = np.tile(self.data.ctrl, (self._delay + self._hold, 1))
        end = self._pose()
        self.fell = self.fell or result.fell
        self._last_distance = float(np.hypot(*(end[:2] - start[:2])))
        self._last_ok = result.ok
        self._compose(traj.info, start, end)
        fig = figures(traj, result)
        step = {
            "behavior": behavior,
            "params": spec.resolve(params),
            "start_s": _round(t0),
            "verdict": fig["verdict"],
            "figures": fig,
        }
        self.steps.append(step)
        return step

    def _sense(self, behavior: str, spec, params: Mapping[str, object]) -> dict:
        """Run a sensing behaviour (a closed loop, :mod:`program.sensing`); its figures."""
        from program import sensing

        try:
            resolved = spec.resolve(params)
        except ValueError as exc:
            raise ProgramError(f"{behavior}: {exc}") from None
        self._note(f"{behavior} {self._params_text(params)}")
        if not self.started:
            steer = sensing.steering(self.controller.behaviors)
            traj = self.controller.run(steer.behavior)  # type: ignore[union-attr]
            self._start(traj.positions[0], traj.joints)
        start, t0, fell0 = self._pose(), self.time, self.fell
        before = dict(self._counts)
        fig, info = sensing.run(self, behavior, resolved)
        steps = max(self._counts["steps"] - before["steps"], 1)
        fig["fell"] = self.fell and not fell0
        fig["saturated_fraction"] = (self._counts["saturated"] - before["saturated"]) / steps
        verdict = judge(fig, info, self.free)
        fig = {k: (_round(v) if isinstance(v, float) else v) for k, v in fig.items()}
        fig = {"behavior": behavior, "verdict": verdict or "ok", **fig}
        end = self._pose()
        self._last_distance = float(np.hypot(*(end[:2] - start[:2])))
        self._last_ok = not verdict
        self._compose({}, start, end)
        step = {
            "behavior": behavior,
            "params": resolved,
            "start_s": _round(t0),
            "verdict": fig["verdict"],
            "figures": fig,
        }
        self.steps.append(step)
        return step

    def wait(self, seconds: float) -> None:
        """Hold the current pose for ``seconds``."""
        seconds = float(seconds)
        if not (math.isfinite(seconds) and 0 <= seconds <= LIMITS["wait_s"]):
            raise ProgramError(
                f"wait: expected seconds in [0, {LIMITS['wait_s']:g}], got {seconds}"
            )
        self._note(f"wait {seconds:g} s")
        if not self.started:
            first = next((n for n in self.behaviors if n not in self.sensing), None)
            if first is None:
                self._start(None, ())
            else:
                traj = self.controller.run(first)
                self._start(traj.positions[0], traj.joints)
        self._check_time(seconds)
        joints, q = self._held()
        self._play(joints, q[None, :], np.zeros((1, len(joints))), seconds)

    def report(self, name: str) -> float:
        """What the robot reports (:data:`program.script.REPORTS`)."""
        if name not in REPORTS:
            raise ProgramError(f"report: unknown {name!r} (reports: {', '.join(REPORTS)})")
        x, y, _ = self._pose() - self._origin if self.started else np.zeros(3)
        heading = self._yaws[-1] - self._yaws[0] if self._yaws else 0.0
        return {
            "x_m": float(x),
            "y_m": float(y),
            "heading_deg": math.degrees(heading),
            "distance_m": self._last_distance,
            "ok": 1.0 if self._last_ok else 0.0,
            "fell": 1.0 if self.fell else 0.0,
            "time_s": self.time,
        }[name]

    # -- the outcome -----------------------------------------------------------------

    def result(self) -> dict:
        """The whole run: steps, path, expected and final pose, verdict, animation."""
        failed: list[str] = []
        for i, st in enumerate(self.steps):
            if st["verdict"] != "ok":
                failed.append(f"step {i + 1} ({st['behavior']}): {', '.join(st['verdict'])}")
        if self.fell and not any("fell" in f for f in failed):
            failed.append("fell")
        final = (self._pose() - self._origin) if self.started else np.zeros(3)
        final[2] = (self._yaws[-1] - self._yaws[0]) if self._yaws else 0.0
        expected = None
        error = None
        if self.free:
            expected = [_round(c) for c in self._expected]
            error = float(np.hypot(*(final[:2] - self._expected[:2])))
            allowed = END_POSE_FRACTION * self._commanded_path
            if self._commanded_path > 0 and error > allowed:
                failed.append(
                    f"end pose: {error:.3g} m from where the program says "
                    f"(limit {allowed:.3g} m: {END_POSE_FRACTION:.0%} of the "
                    f"{self._commanded_path:.3g} m commanded)"
                )
        return {
            "robot_type": self.record.get("robot_type"),
            "seconds": _round(self.time),
            "verdict": failed if failed else "ok",
            "steps": self.steps,
            "expected_pose": expected,
            "final_pose": [_round(c) for c in final] if self.free else None,
            "end_pose_error_m": None if error is None else _round(error),
            "path": {k: [_round(v) for v in vals] for k, vals in self._path.items()},
            "animation": {"fps": ANIMATION_FPS, "geoms": self._geoms, "frames": self._frames},
        }

    # -- inside ----------------------------------------------------------------------

    def _note(self, text: str) -> None:
        if self.progress is not None:
            self.progress(text)

    @staticmethod
    def _params_text(params: Mapping[str, object]) -> str:
        return " ".join(f"{k}={v}" for k, v in params.items())

    def _check_time(self, seconds: float) -> None:
        if self.time + seconds > LIMITS["sim_s"] + 1e-9:
            raise ProgramError(
                f"program: would simulate more than {LIMITS['sim_s']:g} s "
                f"({self.time:.1f} s so far, {seconds:.1f} s more asked)"
            )

    def _columns(self, joints) -> list[tuple[int, int, int, bool]]:
        """(joint column, actuator, qpos address, velocity servo) per joint."""
        m = self.model
        act = {m.actuator(k).name: k for k in range(m.nu)}
        out = []
        for k, name in enumerate(joints):
            a = act[name]
            velocity = m.actuator_biasprm[a, 1] == 0 and m.actuator_biasprm[a, 2] != 0
            out.append((k, a, int(m.jnt_qposadr[m.actuator_trnid[a, 0]]), bool(velocity)))
        return out

    def _start(self, q0, joints) -> None:
        import mujoco

        if q0 is not None:
            for k, _, adr, _ in self._columns(joints):
                self.data.qpos[adr] = q0[k]
        mujoco.mj_forward(self.model, self.data)
        self.started = True
        self._origin = self._pose()
        self._origin[2] = 0.0
        self._expected = np.zeros(3)
        self._observe(0.0, self.data)

    def _pose(self) -> np.ndarray:
        """(x, y, yaw) of the root body (zeros for a fixed base)."""
        if not self.free:
            return np.zeros(3)
        q = self.data.qpos
        return np.array([q[0], q[1], quat_yaw(q[3:7])])

    def _roll(self) -> float:
        """Roll (rad) of the root body about its own x axis since the model's start pose:
        atan2 of the z components of its y and z axes, less the same at the start."""
        if not self.free:
            return 0.0
        import mujoco

        def roll(quat: np.ndarray) -> float:
            r = np.empty(9)
            mujoco.mju_quat2Mat(r, quat)
            r = r.reshape(3, 3)
            return math.atan2(r[2, 1], r[2, 2])

        a = roll(self.data.qpos[3:7]) - roll(self.model.qpos0[3:7])
        return (a + math.pi) % (2 * math.pi) - math.pi

    def _held(self) -> tuple[tuple[str, ...], np.ndarray]:
        """Every actuated joint and the position it is at now."""
        m = self.model
        names = tuple(m.actuator(k).name for k in range(m.nu))
        cols = self._columns(names)
        return names, np.array([self.data.qpos[adr] for _, _, adr, _ in cols])

    def follow(self, traj) -> None:
        """Run a trajectory from where the robot is, unjudged (a sensing loop's step)."""
        if not self.started:
            self._start(traj.positions[0], traj.joints)
        else:
            self._blend_to(traj.joints, traj.positions[0])
        self._play(
            traj.joints, traj.positions, traj.velocities, traj.duration, traj.times, plan=traj
        )

    def _blend_to(self, joints, q1: np.ndarray) -> None:
        """Move ``joints`` from where they are to ``q1`` (minimum jerk)."""

        cols = self._columns(joints)
        q0 = np.array([self.data.qpos[adr] for _, _, adr, _ in cols])
        target = np.array(q1, dtype=float)
        for k, _, _, velocity in cols:
            if velocity:  # a wheel: no position to reach, it stops
                target[k] = q0[k]
        speed = np.array(
            [max(self.controller.geometry.joint_speed.get(n, 0.0), 1e-3) for n in joints]
        )
        # a minimum-jerk move peaks at 1.875 x its mean speed
        if float(np.max(np.abs(target - q0), initial=0.0)) < BLEND_SKIP_RAD:
            return  # already there
        need = float(np.max(1.875 * np.abs(target - q0) / (BLEND_SPEED_SHARE * speed), initial=0))
        seconds = max(BLEND_MIN_S, need)
        self._check_time(seconds)
        n = max(2, int(math.ceil(seconds * 100)) + 1)
        tau = np.linspace(0.0, 1.0, n)
        s, ds, _ = min_jerk(tau)
        pos = q0 + np.outer(s, target - q0)
        vel = np.outer(ds / seconds, target - q0)
        self._play(joints, pos, vel, seconds)

    def _play(
        self,
        joints,
        pos: np.ndarray,
        vel: np.ndarray,
        seconds: float,
        times: np.ndarray | None = None,
        plan=None,
    ) -> None:
        """Step the physics for ``seconds`` following ``pos`` with velocity servos
        following ``vel``: rows at ``times`` s (interpolated at every step, as ``simulate``
        does), or without ``times`` spread evenly over the time, the last held.

        ``plan``: the trajectory these rows are of (a sensing loop's period): when it asks
        for a feedback loop (``info["feedback"]``) the loop runs around it as
        :func:`synth.verification.simulate.simulate` runs it (its ``_ClosedLoop``: the same
        readings, control period, latency and IMU noise). On a perturbed robot the commands reach
        the servos through the bus (:meth:`_bus`).

        The steps run inside MuJoCo (:func:`synth.verification.simulate.step_through`) in chunks of
        1 / :data:`PATH_HZ` s, the path, the animation and ``on_step`` (a sensing loop) being
        served after each; the fall, the saturated steps and the watched geom's contacts (a
        ``contact`` sensor on it, :func:`program.sensing.scene_xml`) are counted over every
        step from what was recorded."""
        import mujoco

        m, d = self.model, self.data
        cols = self._columns(joints)
        steps = max(1, int(round(seconds / m.opt.timestep)))
        self._check_time(steps * m.opt.timestep)
        rows = len(pos)
        t0 = self.time
        ctrl = np.tile(d.ctrl, (steps, 1))
        if times is not None:
            grid = np.arange(steps) * m.opt.timestep
            for k, a, _, velocity in cols:
                ctrl[:, a] = np.interp(grid, times, vel[:, k] if velocity else pos[:, k])
        else:
            r = np.minimum(rows - 1, (np.arange(steps) * rows) // steps) if rows > 1 else 0
            for k, a, _, velocity in cols:
                ctrl[:, a] = (vel if velocity else pos)[r, k]
        ctrl = self._bus(ctrl)
        watch = self.watched_geom
        sensor = None if watch is None else self._contact_sensor(watch)
        every = max(1, int(round(1 / max(PATH_HZ, ANIMATION_FPS) / m.opt.timestep)))
        observe_every = every
        contacts = 0
        closed = self._closed(plan, cols)
        if closed is not None:
            every = math.gcd(every, closed.period)
            start_closed(closed, d)
            closed.begin_block(ctrl, 0, every)

        def after(i: int) -> None:
            nonlocal contacts
            t = t0 + i * m.opt.timestep
            if closed is not None:
                closed.after(d, i, ctrl)
            if closed is None or i % observe_every == 0 or i == steps:
                self._observe(t, d)
                if self.on_step is not None:
                    self.on_step(t)
            if watch is not None and sensor is None and d.ncon:  # stepped one at a time
                c = d.contact
                contacts += int(np.any((c.geom1 == watch) | (c.geom2 == watch)))

        sensed = np.empty((steps, m.nsensordata)) if sensor is not None else None
        if watch is not None and sensor is None:
            every = 1
        full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        first = np.empty(mujoco.mj_stateSize(m, full))
        mujoco.mj_getState(m, d, first, full)
        states = step_through(m, d, ctrl, every, after, sensed)
        nq, nv = m.nq, m.nv
        if self.can_fall and not self.fell:
            w, x, y, z = states[:, 4:8].T  # the free joint's quaternion after each step
            up = np.clip(1 - 2 * (x * x + y * y), -1.0, 1.0)
            self.fell = bool(np.any(np.arccos(up) > COLLAPSE_TILT))
        before = np.vstack([first[None], states[:-1]])
        law = ServoLaw(m)
        effort = law.efforts(before[:, 1 : 1 + nq], before[:, 1 + nq : 1 + nq + nv], ctrl)
        at_limit = np.abs(law.forces(effort)) / law.limit >= SATURATION_LEVEL
        self._counts["steps"] += steps
        self._counts["saturated"] += int(at_limit.any(axis=1).sum())
        if sensed is not None:
            contacts = int(np.count_nonzero(sensed[:, sensor] > 0))
        self._counts["contacts"] += contacts
        self.time = t0 + steps * m.opt.timestep

    def _bus(self, ctrl: np.ndarray) -> np.ndarray:
        """The controls the servos act on when the program sends ``ctrl`` (steps, nu) from
        now: on a perturbed robot each step's is the command sent ``_delay`` steps earlier,
        held for each control period of ``_hold`` steps (on the session's clock, so it
        carries over from one call to the next; before the first command, that one), as
        :func:`synth.verification.simulate.simulate` delays a plan's; the nominal robot's are
        ``ctrl``."""
        if self.perturbation is None:
            return ctrl
        d, hold = self._delay, self._hold
        keep = d + hold
        if self._sent is None:
            self._sent = np.tile(ctrl[0], (keep, 1))
        sent = np.vstack([self._sent, ctrl])  # row j: the command of step _step - keep + j
        n = self._step + np.arange(len(ctrl))
        src = ((n - d) // hold) * hold  # the step whose command is in force
        out = sent[np.maximum(src - (self._step - keep), 0)]
        self._sent = sent[-keep:].copy()
        self._step += len(ctrl)
        return out

    def _closed(self, plan, cols):
        """The feedback loop of ``plan`` wired to this session's run
        (``synth.verification.simulate``'s ``_ClosedLoop``), or None for no plan or a plan run open
        loop."""
        if plan is None:
            return None

        p = self.perturbation
        columns = [(k, a, velocity) for k, a, _, velocity in cols]
        return _ClosedLoop.of(
            self.model,
            self.data,
            plan,
            columns,
            float(p["latency_s"]) if p else 0.0,
            float(p["control_period_s"]) if p else 0.0,
            p.get("imu") if p else None,
        )

    def _contact_sensor(self, geom: int) -> int | None:
        """The sensordata address of a ``contact`` sensor counting ``geom``'s contacts
        (``geom1`` only, ``data="found"``), or None."""
        import mujoco

        m = self.model
        for s in range(m.nsensor):
            if (
                m.sensor_type[s] == mujoco.mjtSensor.mjSENS_CONTACT
                and m.sensor_objtype[s] == mujoco.mjtObj.mjOBJ_GEOM
                and m.sensor_objid[s] == geom
                and m.sensor_reftype[s] == mujoco.mjtObj.mjOBJ_UNKNOWN
                and m.sensor_intprm[s, 0] == 1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND)
                and m.sensor_dim[s] == 1
            ):
                return int(m.sensor_adr[s])
        return None

    def _observe(self, t: float, d) -> None:
        """Sample the path and the animation at their rates."""
        if not self._path["t"] or t >= self._path["t"][-1] + 1 / PATH_HZ - 1e-9:
            x, y, yaw = self._pose() - self._origin
            yaw = quat_yaw(d.qpos[3:7]) if self.free else 0.0
            if self._yaws:
                prev = self._yaws[-1]
                yaw = prev + (yaw - prev + math.pi) % (2 * math.pi) - math.pi
            self._yaws.append(yaw)
            for k, v in zip(("t", "x", "y", "yaw"), (t, x, y, yaw), strict=True):
                self._path[k].append(v)
        if not self.animate:
            return
        if not self._frames or t >= self._frames[-1]["t"] + 1 / ANIMATION_FPS - 1e-9:
            self._frames.append(self._frame(t, d))

    def _animated_geoms(self) -> list[dict]:
        """The geoms a page draws: name, body, type, size, mesh file, scale, colour."""
        import mujoco

        m = self.model
        kinds = {
            int(mujoco.mjtGeom.mjGEOM_PLANE): "plane",
            int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
            int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
            int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
            int(mujoco.mjtGeom.mjGEOM_BOX): "box",
            int(mujoco.mjtGeom.mjGEOM_MESH): "mesh",
            int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
        }
        out = []
        self._geom_ids = []
        for g in range(m.ngeom):
            kind = kinds.get(int(m.geom_type[g]))
            if kind is None or kind == "plane" or m.geom_bodyid[g] == 0:
                continue
            mesh = scale = None
            if kind == "mesh":
                k = m.geom_dataid[g]
                mesh = f"meshes/{m.mesh(k).name}.stl"
                scale = [_round(c) for c in m.mesh_scale[k]]
            out.append(
                {
                    "name": m.geom(g).name,
                    "body": m.body(m.geom_bodyid[g]).name,
                    "type": kind,
                    "size": [_round(c) for c in m.geom_size[g]],
                    "mesh": mesh,
                    "scale": scale,
                    "rgba": [_round(c) for c in m.geom_rgba[g]],
                }
            )
            self._geom_ids.append(g)
        return out

    def _frame(self, t: float, d) -> dict:
        """Every drawn geom's world pose; a mesh's pose is its file's frame (MuJoCo moves
        mesh vertices to their inertial frame: file = mesh_quat * compiled + mesh_pos)."""
        import mujoco

        m = self.model
        pos, quat = [], []
        q = np.empty(4)
        for g in self._geom_ids:
            rot = d.geom_xmat[g].reshape(3, 3)
            p = d.geom_xpos[g]
            if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
                k = m.geom_dataid[g]
                r = np.empty(9)
                mujoco.mju_quat2Mat(r, m.mesh_quat[k])
                rot = rot @ r.reshape(3, 3).T
                p = p - rot @ m.mesh_pos[k]
            mujoco.mju_mat2Quat(q, rot.reshape(9).copy())
            pos.append([_round(c) for c in p])
            quat.append([_round(c) for c in q])
        return {"t": _round(t), "pos": pos, "quat": quat}

    def _compose(self, info: Mapping, start: np.ndarray, end: np.ndarray) -> None:
        """Advance the commanded pose by the behaviour's promise, or re-anchor it where the
        robot is when the behaviour promises no end pose."""
        if not self.free:
            return
        plan = info.get("planned_pose")
        if plan is None:
            self._expected = end - self._origin
            self._expected[2] = self._yaws[-1] - self._yaws[0] if self._yaws else 0.0
            self._commanded_path = 0.0
            return
        dx, dy, dyaw = (float(c) for c in plan)
        c, s = math.cos(self._expected[2]), math.sin(self._expected[2])
        self._expected = self._expected + np.array([c * dx - s * dy, s * dx + c * dy, dyaw])
        self._commanded_path += float(info.get("path_length_m") or math.hypot(dx, dy))


def perturbed_session(
    folder: str | Path,
    progress: Callable[[str], None] | None = None,
    perturb: int | None = None,
) -> Session:
    """A session of the bundle in ``folder``; with ``perturb`` (a seed), on that
    perturbation of the table the design was verified with (``verified.robust.table``;
    InputError when it has none): the robot the verification's run of that seed drove."""
    session = Session(folder, progress=progress)
    if perturb is None:
        return session
    from synth.verification.runs import recorded_table

    return Session(folder, progress=progress, perturb=(recorded_table(session.record), perturb))


def run_program(
    folder: str | Path,
    program: Mapping,
    progress: Callable[[str], None] | None = None,
    perturb: int | None = None,
    source: str = "",
) -> dict:
    """Validate ``program`` (JSON data, :mod:`program.script`; from the file ``source``,
    which messages name) against the bundle's design and run it (on perturbation
    ``perturb`` of its table: :func:`perturbed_session`); :meth:`Session.result`."""
    session = perturbed_session(folder, progress, perturb)
    validate(program, session.behaviors, source)
    execute(program, session, source)
    return session.result()


def run_python(
    folder: str | Path,
    path: str | Path,
    progress: Callable[[str], None] | None = None,
    perturb: int | None = None,
) -> dict:
    """Run the ``main(robot)`` of a Python program file (``parmor run``) on the bundle.

    The program is Python run with the user's rights, as any script they run; it runs in
    a forked child process (where the system can fork), which ends as soon as ``main``
    returns and its result is sent: threads the program started end with it, so they keep
    nothing waiting, and a program stopped at the time limit or by Ctrl-C (the child is
    killed) leaves nothing running. What the program prints goes out before the result."""
    import contextlib
    import os

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such program file")
    if not hasattr(os, "fork"):
        return _run_python_here(folder, path, progress, perturb)
    import pickle
    import signal
    import sys

    for stream in (sys.stdout, sys.stderr):  # nothing buffered is written twice
        stream.flush()
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: run, send the outcome, end at once (its threads with it)
        code = 0
        try:
            os.close(read)
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops it
            try:
                reply: tuple = ("ok", _run_python_here(folder, path, progress, perturb))
            except ParmorError as e:
                reply = ("error", e.exit_code, str(e))
            except MemoryError:
                reply = ("memory",)
            except BaseException as e:  # noqa: BLE001 - reported, never a traceback
                reply = ("error", InputError.exit_code, f"{path}: {type(e).__name__}: {e}")
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):  # the program's output is its own
                    stream.flush()
            with os.fdopen(write, "wb") as f:
                f.write(pickle.dumps(reply))
        except BaseException:  # noqa: BLE001 - a child never returns into the caller
            code = 1
        finally:
            os._exit(code)
    os.close(write)
    try:
        with os.fdopen(read, "rb") as f:
            data = f.read()  # until the child ends; a time limit or Ctrl-C interrupts it
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
    if not data:
        how = (
            f"signal {os.WTERMSIG(status)}"
            if os.WIFSIGNALED(status)
            else f"exit code {os.waitstatus_to_exitcode(status)}"
        )
        raise InputError(f"{path}: the program's process ended without a result ({how})")
    reply = pickle.loads(data)
    if reply[0] == "ok":
        return reply[1]
    if reply[0] == "memory":
        raise MemoryError
    _, code, message = reply
    error = InputError(message) if code == InputError.exit_code else ParmorError(message)
    error.exit_code = code
    raise error


def _run_python_here(
    folder: str | Path,
    path: Path,
    progress: Callable[[str], None] | None = None,
    perturb: int | None = None,
) -> dict:
    """:func:`run_python` in this process."""
    import runpy

    try:
        namespace = runpy.run_path(str(path), run_name="parmor_program")
    except SyntaxError as exc:
        raise InputError(f"{path}:{exc.lineno}:{exc.offset}: {exc.msg}") from None
    except (ParmorError, KeyboardInterrupt, MemoryError):
        raise
    except (Exception, SystemExit) as exc:  # its top level failed: where, not a traceback
        raise InputError(f"{_where(exc, path)}: {type(exc).__name__}: {exc}") from None
    main = namespace.get("main")
    if not callable(main):
        raise InputError(f"{path}: defines no main(robot) function")
    session = perturbed_session(folder, progress, perturb)
    try:
        main(session)
    except (ParmorError, KeyboardInterrupt, MemoryError):
        raise
    except (Exception, SystemExit) as exc:  # the program failed: where, not a traceback
        raise InputError(f"{_where(exc, path)}: {type(exc).__name__}: {exc}") from None
    return session.result()


def _where(exc: BaseException, path: Path) -> str:
    """``path:line`` of the program's last frame in ``exc``'s traceback, or ``path``."""
    import traceback

    frames = [f for f in traceback.extract_tb(exc.__traceback__) if f.filename == str(path)]
    return f"{path}:{frames[-1].lineno}" if frames else str(path)
