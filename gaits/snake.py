"""Snake robots (paper section 4.3.2): the wave generators of eqs. 7-9 and the gaits of a
pitch-yaw snake.

The snake's M modules alternate pitch joints (``joint_1``, ``joint_3``, ...: the vertical
modules, moving in the vertical plane) and yaw joints (``joint_2``, ``joint_4``, ...: the
horizontal modules). Vertical module i (1-based, i = 1..ceil(M/2)) and horizontal module
i (i = 1..floor(M/2)) follow (eq. 7, angles in rad, ``phase`` = 2 pi f t)::

    phi_v_i = O_v + A_v sin(phase + (i - 1) dphi_v)
    phi_h_i = O_h + A_h sin(phase + (i - 1) dphi_h + dphi_vh)

where a travelling wave of k undulations along the snake with winding angle alpha (the
serpenoid curve sampled by the modules) has (eqs. 8, 9)::

    A = 2 alpha sin(2 pi k / M),   |dphi| = 4 pi k / M

(two modules apart: the vertical modules are every other module). The offsets O_v, O_h
are not in the paper's eq. 7; O_h bends the snake into a fixed arc (Gonzalez-Gomez's
turning gait, here ``circular-path``), O_v arches it (``rectilinear``).

The gaits follow Gonzalez-Gomez et al. ("Locomotion capabilities of a modular robot with
eight pitch-yaw-connecting modules", CLAWAR 2006, and the same authors' minimal PYP
configurations); each keeps the snake lying on several modules at all times (statically
stable: it never balances on a hump). Parameters (constants below) were checked in MuJoCo
on the designed snakes (M = 3, 5, 6, 8), see the tests.

- ``rolling`` (lateral rolling): vertical and horizontal waves of equal amplitude, no
  travelling (dphi_v = dphi_h = 0) and 90 degrees between them: the body bends into an
  arc whose plane turns about the snake's axis, so the arc rolls sideways. The total
  bend is shared by the joints (A = ROLL_BEND / (M / 2), at most ROLL_MAX; the PYP snake
  needs A >= 60 degrees).
- ``rectilinear`` (1D sinusoidal): only the vertical wave travels, 120 degrees between
  consecutive vertical modules, the horizontal modules straight: humps travel along the
  body and the snake inches along its axis. A small constant vertical offset arches the
  body (``RECTILINEAR_ARCH``), which short snakes with a heavy head need to move.
- ``sidewinding``: both waves travel with the same k, a vertical wave lifting the body
  where the horizontal wave sweeps it sideways, 90 degrees apart *where they bend the
  body*: a horizontal module sits one module behind its vertical one, half a phase step
  of the travelling wave, so dphi_vh = +-90 degrees + dphi / 2 (see ``SIDEWINDING_LIFT``).
- ``rotating``: both waves travel with different k (k_v = 2 k_h), 90 degrees apart: the
  snake turns about its vertical axis.
- ``circular-path``: the rectilinear wave on a body bent into an arc by a constant
  horizontal offset O_h, so the rectilinear motion follows a circle.

Trajectories start and end straight and at rest: the amplitudes (and offsets) fade in and
out with a minimum-jerk envelope over ``FADE_CYCLES`` cycles, so positions and velocities
are continuous.

A snake may lie rolled about its long axis (``rolling`` leaves it on its side): then its
pitch joints no longer bend it vertically. Every gait takes the body's ``roll`` at the
start and turns the waves by it (:func:`rolled_waves`): the desired vertical wave V and
horizontal wave H, evaluated at every joint's place along the body (the continuous form of
eq. 7), are shared between the pitch and yaw joints by their axes' directions, so that the
gait bends the body in the world as it does from an upright start. ``roll`` = 0 is eq. 7
exactly. Simulated on the designed snakes (M = 5, 8, 14) lying on their side, every gait
then keeps its promise but two: M = 5's rectilinear, whose side leaves floor(M / 2) = 2
joints to bend it vertically (the gait needs 3), and M = 8's sidewinding away from the
side its head's main module and battery stick out to, which saturates a lifting joint at
the default frequency (not at 0.25 Hz).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from gaits.base import BehaviorSpec, Controller, DesignGeometry, Parameter, Trajectory
from gaits.steering import SteerableSpec

__all__ = [
    "GAITS",
    "SnakeController",
    "WaveParams",
    "gait_params",
    "joint_waves",
    "rolled_waves",
    "wave_amplitude",
    "wave_phase_step",
]

#: The gaits, by ability short name, in the order of their minimum M in the ontology.
GAITS = ("rolling", "rectilinear", "sidewinding", "rotating", "circular-path")
#: Trajectory samples per wave cycle (the simulation interpolates linearly between them).
SAMPLES_PER_CYCLE = 100
#: Fraction of a joint's no-load speed the waves may ask for (a position servo tracking
#: a sine at its no-load speed would lag and shrink the wave).
SPEED_MARGIN = 0.8
#: Fraction of the no-load speed the default frequency asks of the joints at the waves'
#: peak: a servo's torque falls linearly with speed (the motor line), so at this speed it
#: keeps 1 - SPEED_SHARE = 2/3 of its stall torque for the body's loads, which the
#: structure generator sizes to at most stall / 1.5 (the catalog's torque safety factor).
SPEED_SHARE = 1 / 3
#: Cycles over which the waves fade in at the start and out at the end.
FADE_CYCLES = 0.5
#: Default wave frequency Hz (lower when the modules are too slow for it).
DEFAULT_FREQUENCY = 0.4
#: The ``roll`` parameter of every gait (rad): which angle it is (see ``SnakeController``).
ROLL_DOC = (
    "the body's roll about its long axis at the start, as the head's IMU reads it: the "
    "waves are turned by it (right-handed about the base's +x, the modules' direction; 0 "
    "upright as the model starts: atan2(R[2,1], R[2,2]) of the base's rotation matrix R)"
)


def wave_amplitude(alpha: float, k: float, modules: int) -> float:
    """Eqs. 8, 9: joint amplitude rad ``2 alpha sin(2 pi k / M)`` of a serpenoid wave of
    winding angle ``alpha`` rad and ``k`` undulations on ``M`` modules."""
    _check_modules(modules)
    return 2.0 * alpha * math.sin(2.0 * math.pi * k / modules)


def wave_phase_step(k: float, modules: int) -> float:
    """Eqs. 8, 9: phase difference rad ``4 pi k / M`` between consecutive modules of one
    orientation (two modules apart) for ``k`` undulations on ``M`` modules."""
    _check_modules(modules)
    return 4.0 * math.pi * k / modules


def _check_modules(modules: int) -> None:
    if isinstance(modules, bool) or not isinstance(modules, (int, np.integer)) or modules < 1:
        raise ValueError(f"modules must be an integer >= 1, got {modules!r}")


@dataclass(frozen=True)
class WaveParams:
    """Parameters of eq. 7 (rad): amplitudes ``a_v``, ``a_h``; phase steps between
    consecutive vertical (``dphi_v``) and horizontal (``dphi_h``) modules; phase
    ``dphi_vh`` of the horizontal wave against the vertical one; offsets ``o_v``, ``o_h``.
    """

    a_v: float
    a_h: float
    dphi_v: float = 0.0
    dphi_h: float = 0.0
    dphi_vh: float = 0.0
    o_v: float = 0.0
    o_h: float = 0.0

    def peak(self) -> float:
        """Largest |joint angle| rad the waves reach."""
        return max(abs(self.o_v) + abs(self.a_v), abs(self.o_h) + abs(self.a_h))


def joint_waves(
    phase: np.ndarray,
    modules: int,
    p: WaveParams,
    envelope: np.ndarray | float = 1.0,
    roll: float = 0.0,
) -> np.ndarray:
    """Joint angles (N, M) rad of eq. 7 at ``phase`` (N,) rad; column j is ``joint_{j+1}``
    (odd joints vertical, even horizontal). ``envelope`` (N,) in [0, 1] scales amplitudes
    and offsets (fading in and out).

    ``roll`` rad: the body's roll about its long axis (see :func:`rolled_waves`); 0 is
    eq. 7 itself."""
    _check_modules(modules)
    ph = np.atleast_1d(np.asarray(phase, dtype=float))
    env = np.broadcast_to(np.asarray(envelope, dtype=float), ph.shape)
    if roll != 0:
        v, h = _body_waves(ph, modules, p, env)
        return rolled_waves(v, h, roll)
    out = np.empty((len(ph), modules))
    for j in range(modules):
        i = j // 2  # (i - 1) of eq. 7: index of the module among those of its orientation
        if j % 2 == 0:  # joint_1, joint_3, ...: vertical
            out[:, j] = env * (p.o_v + p.a_v * np.sin(ph + i * p.dphi_v))
        else:
            out[:, j] = env * (p.o_h + p.a_h * np.sin(ph + i * p.dphi_h + p.dphi_vh))
    return out


def _body_waves(
    phase: np.ndarray, modules: int, p: WaveParams, envelope: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The continuous form of eq. 7: the vertical wave V and the horizontal wave H (N, M)
    rad evaluated at every joint's place along the body. Joint column j sits at j / 2
    vertical modules' spacing from ``joint_1`` (the horizontal modules lie between the
    vertical ones), so V there has the phase ``(j / 2) dphi_v`` and H ``((j - 1) / 2)
    dphi_h + dphi_vh``: on the vertical joints V is eq. 7's, on the horizontal ones H."""
    arg_v, arg_h = _body_phases(phase, modules, p)
    env = envelope[:, None]
    return env * (p.o_v + p.a_v * np.sin(arg_v)), env * (p.o_h + p.a_h * np.sin(arg_h))


def _body_phases(phase: np.ndarray, modules: int, p: WaveParams) -> tuple[np.ndarray, np.ndarray]:
    """The arguments (N, M) rad of the sines of V and H at every joint's place."""
    place = np.arange(modules) / 2.0
    arg_v = phase[:, None] + place[None, :] * p.dphi_v
    arg_h = phase[:, None] + (place[None, :] - 0.5) * p.dphi_h + p.dphi_vh
    return arg_v, arg_h


def rolled_waves(v: np.ndarray, h: np.ndarray, roll: float) -> np.ndarray:
    """Joint angles (N, M) rad that bend a body rolled by ``roll`` rad about its long axis
    (right-handed about the modules' +x, see ``SnakeController``) by the vertical wave
    ``v`` and the horizontal wave ``h`` (N, M) of the world: every joint bends by the
    component of the desired bend (``v`` about the world's horizontal axis across the
    body, ``h`` about the vertical) along its own axis. Rolled by ``roll``, a pitch joint's
    axis (the base's y) is cos(roll) y_w + sin(roll) z_w and a yaw joint's (the base's z)
    -sin(roll) y_w + cos(roll) z_w, so::

        q_pitch = v cos(roll) + h sin(roll),   q_yaw = -v sin(roll) + h cos(roll)

    (odd columns pitch, even yaw, as in ``joint_waves``)."""
    c, s = math.cos(roll), math.sin(roll)
    out = np.empty(np.shape(v))
    out[:, 0::2] = c * v[:, 0::2] + s * h[:, 0::2]
    out[:, 1::2] = -s * v[:, 1::2] + c * h[:, 1::2]
    return out


def _joint_wave_rates(
    phase: np.ndarray,
    phase_rate: float,
    modules: int,
    p: WaveParams,
    envelope: np.ndarray,
    envelope_rate: np.ndarray,
    roll: float = 0.0,
) -> np.ndarray:
    """Time derivative (N, M) rad/s of ``joint_waves`` for d(phase)/dt = ``phase_rate``
    rad/s, the envelope's rate (N,) 1/s and the body's ``roll`` rad."""
    if roll != 0:
        arg_v, arg_h = _body_phases(phase, modules, p)
        env, rate = envelope[:, None], envelope_rate[:, None]
        dv = rate * (p.o_v + p.a_v * np.sin(arg_v)) + env * p.a_v * phase_rate * np.cos(arg_v)
        dh = rate * (p.o_h + p.a_h * np.sin(arg_h)) + env * p.a_h * phase_rate * np.cos(arg_h)
        return rolled_waves(dv, dh, roll)
    out = np.empty((len(phase), modules))
    for j in range(modules):
        i = j // 2
        if j % 2 == 0:
            arg, a, o = phase + i * p.dphi_v, p.a_v, p.o_v
        else:
            arg, a, o = phase + i * p.dphi_h + p.dphi_vh, p.a_h, p.o_h
        out[:, j] = envelope_rate * (o + a * np.sin(arg)) + envelope * a * phase_rate * np.cos(arg)
    return out


#: Total bend rad of the rolling arc, shared by the joints: A = ROLL_BEND / (M / 2),
#: at most ROLL_MAX. Gonzalez-Gomez's PYP rolls with A >= 60 degrees; simulated, the
#: designed snakes roll steadily with 80 (M = 3), 48 (M = 5), 40 (M = 6), 30 (M = 8).
ROLL_BEND = math.radians(120)
ROLL_MAX = math.radians(80)
#: Travelling waves have 120 degrees between consecutive modules of one orientation (the
#: best coordination for the 1D sinusoidal gait, Gonzalez-Gomez), i.e. k = M / 6
#: undulations in eqs. 8-9, so that A = 2 alpha sin(60 degrees) whatever M.
TRAVEL_STEP = 2 * math.pi / 3
#: Winding angles alpha (rad) of eqs. 8-9 per gait: (vertical, horizontal).
RECTILINEAR_ALPHA = math.radians(45)  # A_v = 78 degrees: humps tall enough to lift the head
#: Total vertical offset rad of ``rectilinear`` (and ``circular-path``), shared by the
#: vertical joints, each bending the tail down, so that the body arches and the head is
#: tilted nose up: O_v = RECTILINEAR_ARCH * min(1, (ARCH_MODULES / M)^2) / ceil(M / 2).
#: The arch is for the heavy head (main module, battery, payload) of the short snakes; a
#: long snake holds its arched ends up as cantilevers, whose torque grows as M^2, so
#: beyond ARCH_MODULES its arch shrinks as 1 / M^2. Simulated on the designed snakes
#: (M = 5-14, payload 0-0.5 kg): without the arch the head rocks back and forth with the
#: humps and the short snakes hardly move (M = 5: 0.17, M = 6 with 0.25 kg: 0.24 body
#: length per 10 s); with 30 degrees M = 5-8 crawl 0.28-0.64; 30 degrees at M = 14
#: saturate a module 7 % of the time tail first, 10 degrees 2 %.
RECTILINEAR_ARCH = math.radians(30)
ARCH_MODULES = 8
SIDEWINDING_ALPHA = math.radians(20)  # horizontal: A_h = 35 degrees
#: Total vertical bend rad of ``sidewinding``, shared by the vertical joints: A_v =
#: SIDEWINDING_LIFT / (M / 2). The lifted parts must leave the ground although the heavy
#: head (main module, battery, payload) presses the front down; the fewer the modules the
#: more each must lift. Simulated on the designed snakes (M = 6-14, payload 0-0.5 kg): a
#: fixed A_v = 10 degrees leaves M = 6-8 dragging and turning about the head (0.0-0.2
#: body length per 10 s); 20-30 degrees at M = 6-8 sidewind at 0.4-0.7, but at M = 12 with
#: 0.25 kg 20 degrees saturates a module sized near its limit, 10-15 degrees do not.
SIDEWINDING_LIFT = math.radians(100)
ROTATING_ALPHA = (math.radians(5), math.radians(32))  # M = 8: A_v = 10, A_h = 45 degrees
#: Horizontal undulations k_h of ``rotating`` along the body whatever M (k_v = 2 k_h).
#: Simulated on the designed snakes (M = 8, 10, 14, payload 0-0.5 kg): k_h = 0.75 turns
#: them 130-170 degrees per 10 s, the horizontal wave lagging the vertical one by 90
#: degrees turning counter-clockwise; k_h = M / 8 (one undulation at M = 8) turns M = 8
#: at 45 degrees per 10 s and M = 10 and 14 hardly, M = 14 the wrong way.
ROTATING_WAVES = 0.75
#: Gaits a closed loop can steer (:mod:`program.sensing`) by their ``turn`` bias: the
#: horizontal wave graded along the body, 1 + turn at the tail's end and 1 - turn at the
#: head's (:func:`turn_scale`). Simulated on the designed 6-module snake (2-cycle runs at
#: 0.4 Hz), sidewinding to the left turns its heading by about -8 (turn -1), +5 (-0.6), +9
#: (0) and +25 (+0.6) degrees a run: which turn goes straight differs from snake to snake
#: (the heavy head, the ground), so the loop learns it from the headings it measures.
STEERED = ("sidewinding",)
TURN_MAX = 1.0
TURN_DOC = (
    "steering bias: the horizontal wave grows by this share towards the tail (+) or "
    "the head (-); how it turns the heading depends on the snake"
)
#: Largest horizontal offset rad of ``circular-path`` (the horizontal joints hold it).
BEND_MAX = math.radians(60)
#: Default total bend rad of ``circular-path``, shared by the horizontal joints: a circle
#: of a few body lengths, so that a run of a few wave cycles follows an arc of it.
CIRCLE_BEND = math.radians(30)


def gait_params(gait: str, modules: int, direction: int = 1, bend: float = 0.0) -> WaveParams:
    """The wave parameters of ``gait`` (one of ``GAITS``) for an M-module snake.

    ``direction`` +1 or -1 chooses the sense of travel (see ``SnakeController``);
    ``bend`` rad: the horizontal offset of ``circular-path`` (positive curls the tail to
    the left, +y). Amplitudes follow eqs. 8-9 from the winding angles above; the rolling wave
    does not travel (k = 0), so its amplitude is set directly.
    """
    _check_modules(modules)
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction!r}")
    if gait == "rolling":
        a = min(ROLL_MAX, ROLL_BEND / (modules / 2))
        return WaveParams(a, a, 0.0, 0.0, -direction * math.pi / 2)
    k = modules * TRAVEL_STEP / (4 * math.pi)  # undulations giving the 120 degree step
    if gait in ("rectilinear", "circular-path"):
        a_v = wave_amplitude(RECTILINEAR_ALPHA, k, modules)
        # (within the joints' +-90 degrees on snakes too short for the gait, M < 5)
        arch = RECTILINEAR_ARCH * min(1.0, (ARCH_MODULES / modules) ** 2)
        o_v = min(arch / math.ceil(modules / 2), math.pi / 2 - a_v)
        p = WaveParams(a_v, 0.0, direction * wave_phase_step(k, modules), o_v=o_v)
        if gait == "circular-path":
            if not abs(bend) <= BEND_MAX:
                raise ValueError(f"bend must be within +-{BEND_MAX:.3g} rad, got {bend!r}")
            p = replace(p, o_h=bend)
        return p
    if gait == "sidewinding":
        # the horizontal module i is one module behind the vertical one: the vertical wave
        # there has the phase of module i plus half a step; 90 degrees from that
        step = -wave_phase_step(k, modules)
        a_v = min(SIDEWINDING_LIFT / (modules / 2), ROLL_MAX)
        a_h = wave_amplitude(SIDEWINDING_ALPHA, k, modules)
        return WaveParams(a_v, a_h, step, step, direction * math.pi / 2 + step / 2)
    if gait == "rotating":
        k_h = ROTATING_WAVES  # horizontal undulations; the vertical wave has twice as many
        a_v = wave_amplitude(ROTATING_ALPHA[0], 2 * k_h, modules)
        a_h = wave_amplitude(ROTATING_ALPHA[1], k_h, modules)
        return WaveParams(
            a_v,
            a_h,
            wave_phase_step(2 * k_h, modules),
            wave_phase_step(k_h, modules),
            -direction * math.pi / 2,
        )
    raise ValueError(f"unknown gait {gait!r}; gaits: {', '.join(GAITS)}")


class SnakeController(Controller):
    """Behaviours of a pitch-yaw snake: the gaits its design's M allows (its abilities).

    Every behaviour takes ``frequency`` Hz (of the waves), ``cycles`` (whole waves, the
    first and last of which fade in and out), ``direction`` (+1 / -1) and ``roll`` rad;
    ``circular-path`` also takes ``bend`` rad.

    ``roll`` is the body's roll about its long axis at the start (:data:`ROLL_DOC`): the
    angle, right-handed about the base's +x axis (the modules extend from the base, the
    head, along +x), from the upright base (its z axis up, as the model starts) to the base
    as it lies, i.e. the roll of the base's yaw-pitch-roll (z-y-x) Euler angles relative to
    the model's initial orientation: ``atan2(R[2, 1], R[2, 2])`` of the base's rotation
    matrix R (base to world; ``atan2(2 (w x + y z), 1 - 2 (x^2 + y^2))`` of its unit
    quaternion (w, x, y, z)). After ``rolling`` the body lies rolled; the waves are then
    turned by ``roll`` (:func:`rolled_waves`) so that every gait does in the world what it
    does from an upright start.

    Senses, in the snake's heading frame at the start (the base's frame turned back about
    +x by ``roll``: x along the body from the head, z up):

    - ``rectilinear``, ``circular-path``: +1 head first (-x), -1 tail first (+x);
    - ``rolling``, ``sidewinding``: +1 to the left (+y), -1 to the right;
    - ``rotating``: +1 counter-clockwise, -1 clockwise;
    - ``circular-path``: ``bend`` > 0 curls the tail to the left (+y), so the heading
      turns clockwise head first and counter-clockwise tail first.

    ``info``: ``direction`` the intended (x, y) unit vector of travel at the start
    (not for ``rotating``), ``turn`` the sense of the heading change (+1
    counter-clockwise, -1 clockwise, 0 none; ``rotating`` and ``circular-path``),
    ``waves`` the :class:`WaveParams` used, ``frequency_hz``.

    A frequency whose waves need a joint faster than ``SPEED_MARGIN`` of the modules'
    no-load speed raises ValueError naming the highest feasible one; a roll that turns the
    waves beyond the joints' range raises ValueError naming the joint. (A roll shares the
    vertical and horizontal waves' rates among the joints, at most sqrt(2) times the
    upright peak: the default frequency, at most ``SPEED_SHARE`` of the no-load speed
    upright, stays within ``SPEED_MARGIN`` whatever the roll.)
    """

    PLAN_IGNORES = frozenset({"mass_kg", "joint_torque", "calibration"})

    def __init__(self, geometry: DesignGeometry) -> None:
        super().__init__(geometry)
        m = self.template.model
        self.joints = tuple(f"joint_{i}" for i in range(1, geometry.modules + 1))
        if tuple(m.q_names) != self.joints:
            raise ValueError(
                f"expected the snake's joints {', '.join(self.joints)}, the "
                f"template has {', '.join(m.q_names)}"
            )
        self.lower, self.upper = m.lower, m.upper
        speeds = [geometry.joint_speed.get(j, 0.0) for j in self.joints]
        if min(speeds) <= 0:
            raise ValueError("the design gives no speed for its snake modules")
        self.max_speed = SPEED_MARGIN * min(speeds)

    @property
    def modules(self) -> int:
        """The design's M."""
        return len(self.joints)

    @property
    def gaits(self) -> tuple[str, ...]:
        """The gaits of this design: those of ``GAITS`` among its abilities."""
        return tuple(g for g in GAITS if g in self.geometry.abilities)

    def max_frequency(
        self, gait: str, direction: int = 1, bend: float = 0.0, roll: float = 0.0
    ) -> float:
        """Highest wave frequency Hz of ``gait`` within the modules' usable speed (joint
        rates scale with the frequency, fade included)."""
        _, _, v, _ = self._trajectory(gait, 1.0, 3, direction, bend, roll)
        return self.max_speed / float(np.abs(v).max())

    def default_frequency(self, gait: str) -> float:
        """Default wave frequency Hz of ``gait``: ``DEFAULT_FREQUENCY``, lower when the waves
        would ask a joint for more than ``SPEED_SHARE`` of its no-load speed."""
        share = SPEED_SHARE / SPEED_MARGIN
        return float(f"{min(DEFAULT_FREQUENCY, share * self.max_frequency(gait)):.3g}")

    @property
    def _default_bend(self) -> float:
        """circular-path's default ``bend`` rad: ``CIRCLE_BEND`` shared by half the modules."""
        return round(CIRCLE_BEND / (self.modules // 2), 4)

    @property
    def body_length(self) -> float:
        """Length m of the module chain (M module pitches: its first module's tube, however
        its part kind names that length)."""
        pitch = self.template.segments[0].length if self.template.segments else 0.0
        return self.modules * float(pitch)

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        """The gaits (``gaits``) with their parameters: ``frequency`` from the default
        (``default_frequency``) up to the highest the modules' speed allows
        (``max_frequency`` upright, with the default ``bend``); worked out once."""
        cached = self.__dict__.get("_behaviors")
        if cached is None:
            cached = self.__dict__["_behaviors"] = self._specs()
        return cached

    def _specs(self) -> dict[str, BehaviorSpec]:
        out: dict[str, BehaviorSpec] = {}
        for gait in self.gaits:
            f = self.default_frequency(gait)
            # up to the highest the modules' speed allows (upright, default bend)
            bend = self._default_bend if gait == "circular-path" else 0.0
            top = max(f, self.max_frequency(gait, bend=bend))
            params = [
                Parameter("frequency", "float", f, "wave frequency", "Hz", low=1e-3, high=top),
                Parameter(
                    "cycles",
                    "int",
                    6,
                    "waves; the first fades in, the last out",
                    "",
                    low=2,
                    high=100000,
                ),
                Parameter("direction", "int", 1, _SENSE[gait], "", low=-1, high=1),
                Parameter("roll", "float", 0.0, ROLL_DOC, "rad", low=-math.pi, high=math.pi),
            ]
            if gait in STEERED:
                params.append(
                    Parameter("turn", "float", 0.0, TURN_DOC, "", low=-TURN_MAX, high=TURN_MAX)
                )
                out[gait] = SteerableSpec(
                    gait,
                    _DOCS[gait],
                    tuple(params),
                    steer=(("speed", "frequency"), ("turn", "turn"), ("steps", "cycles")),
                )
                continue
            if gait == "circular-path":
                params.append(
                    Parameter(
                        "bend",
                        "float",
                        self._default_bend,
                        "horizontal offset of the arc, positive curls the tail left",
                        "rad",
                        low=-BEND_MAX,
                        high=BEND_MAX,
                    )
                )
            out[gait] = BehaviorSpec(gait, _DOCS[gait], tuple(params))
        return out

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        direction = int(params["direction"])
        if direction not in (1, -1):
            raise ValueError(f"direction must be +1 or -1, got {direction}")
        bend = float(params.get("bend", 0.0))
        roll = float(params.get("roll", 0.0))
        if not abs(roll) <= math.pi:
            raise ValueError(f"roll must be within +-pi rad, got {roll!r}")
        freq, cycles = float(params["frequency"]), int(params["cycles"])
        turn = float(params.get("turn", 0.0))
        t, q, v, p = self._trajectory(name, freq, cycles, direction, bend, roll, turn)
        top = float(np.abs(v).max())
        if top > self.max_speed * (1 + 1e-9):
            raise ValueError(
                f"frequency: {name} at {freq:g} Hz needs {top:.3g} rad/s, above the usable "
                f"{self.max_speed:.3g} rad/s of the modules ({SPEED_MARGIN:.0%} of their "
                f"no-load speed); at most {freq * self.max_speed / top:.3g} Hz"
            )
        low = q < self.lower - 1e-9
        high = q > self.upper + 1e-9
        if np.any(low) or np.any(high):
            k = int(np.argmax(np.max(np.maximum(self.lower - q, q - self.upper), axis=0)))
            reach = float(q[:, k].min() if np.any(low[:, k]) else q[:, k].max())
            rolled = f" rolled by {roll:.3g} rad" if roll else ""
            raise ValueError(
                f"{name}: the waves{rolled} leave the joints' range: {self.joints[k]} would "
                f"reach {reach:.3g} rad, its range is [{self.lower[k]:.3g}, "
                f"{self.upper[k]:.3g}] rad"
            )
        info: dict[str, object] = {
            "motion": "rotate" if name == "rotating" else "crawl",
            "locomotion": "snake",
            "body_length_m": self.body_length,
            "waves": p,
            "frequency_hz": freq,
            "roll_rad": roll,
        }
        if name in ("rectilinear", "circular-path"):
            info["direction"] = (-float(direction), 0.0)
        elif name in ("rolling", "sidewinding"):
            info["direction"] = (0.0, float(direction))
        if name == "rotating":
            info["turn"] = direction
        elif name == "circular-path":
            info["turn"] = -direction * int(np.sign(bend))
        return Trajectory(name, t, self.joints, q, v, info)

    def _trajectory(
        self,
        gait: str,
        freq: float,
        cycles: int,
        direction: int,
        bend: float,
        roll: float = 0.0,
        turn: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, WaveParams]:
        """(t (N,) s, q (N, M) rad, v (N, M) rad/s, waves) of ``cycles`` waves at ``freq``
        Hz with minimum-jerk fades over the first and last ``FADE_CYCLES``, for a body
        rolled by ``roll`` rad; ``turn`` grades the horizontal wave along the body
        (:func:`turn_scale`)."""
        if freq <= 0 or cycles < 2 * FADE_CYCLES:
            raise ValueError(f"need frequency > 0 and cycles >= {2 * FADE_CYCLES:g}")
        p = gait_params(gait, self.modules, direction, bend)
        seconds = cycles / freq
        t = np.linspace(0.0, seconds, cycles * SAMPLES_PER_CYCLE + 1)
        w = 2 * math.pi * freq
        fade = FADE_CYCLES / freq
        s_in, ds_in = _ramp(t / fade)
        s_out, ds_out = _ramp((seconds - t) / fade)
        env = s_in * s_out
        env_rate = (ds_in * s_out - s_in * ds_out) / fade
        if turn:
            q, v = _graded_waves(w * t, w, self.modules, p, env, env_rate, roll, turn)
            return t, q, v, p
        q = joint_waves(w * t, self.modules, p, env, roll)
        v = _joint_wave_rates(w * t, w, self.modules, p, env, env_rate, roll)
        return t, q, v, p


def turn_scale(modules: int, turn: float) -> np.ndarray:
    """Scale (M,) of the horizontal wave at every joint's place for a ``turn`` bias: 1 +
    ``turn`` x the place along the body from -1 (``joint_1``, the head's end) to +1 (the
    tail's), so that ``turn`` > 0 sweeps the tail wider than the head and < 0 the head
    wider."""
    place = np.arange(modules, dtype=float)
    rel = (2 * place / (modules - 1) - 1) if modules > 1 else np.zeros(1)
    return 1.0 + turn * rel


def _graded_waves(
    phase: np.ndarray,
    phase_rate: float,
    modules: int,
    p: WaveParams,
    env: np.ndarray,
    env_rate: np.ndarray,
    roll: float,
    turn: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles and rates (N, M) of the body waves (:func:`_body_waves`) with the
    horizontal wave scaled along the body by :func:`turn_scale`, turned by ``roll``."""
    arg_v, arg_h = _body_phases(phase, modules, p)
    scale = turn_scale(modules, turn)[None, :]
    e, r = env[:, None], env_rate[:, None]
    v = e * (p.o_v + p.a_v * np.sin(arg_v))
    h = scale * e * (p.o_h + p.a_h * np.sin(arg_h))
    dv = r * (p.o_v + p.a_v * np.sin(arg_v)) + e * p.a_v * phase_rate * np.cos(arg_v)
    dh = scale * (r * (p.o_h + p.a_h * np.sin(arg_h)) + e * p.a_h * phase_rate * np.cos(arg_h))
    return rolled_waves(v, h, roll), rolled_waves(dv, dh, roll)


def _ramp(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-jerk step s(x) clipped to [0, 1] and ds/dx."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10 - 15 * x + 6 * x**2), 30 * x**2 * (1 - x) ** 2


_SENSE = {
    "rolling": "+1 roll to the left (+y), -1 to the right",
    "rectilinear": "+1 head first (-x), -1 tail first",
    "sidewinding": "+1 to the left (+y), -1 to the right",
    "rotating": "+1 counter-clockwise, -1 clockwise",
    "circular-path": "+1 head first (-x), -1 tail first",
}
_DOCS = {
    "rolling": "Lateral rolling: equal vertical and horizontal waves 90 degrees apart.",
    "rectilinear": "Rectilinear (1D sinusoidal): a vertical travelling wave.",
    "sidewinding": "Sidewinding (lateral shift): both waves travel, 90 degrees apart.",
    "rotating": "Rotating in place: both waves travel, the horizontal one with twice the k.",
    "circular-path": "Circular path: the rectilinear wave on a body bent into an arc.",
}
