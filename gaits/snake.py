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
are not in the paper's eq. 7; they bend the snake into a fixed arc (Gonzalez-Gomez's
turning gait, here ``circular-path``).

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
  body and the snake inches along its axis.
- ``sidewinding``: both waves travel with the same k, 90 degrees apart, a low vertical
  wave lifting the body where the horizontal wave sweeps it sideways. (Simulated, the
  M = 8 snake sidewinds; the M = 6 one turns instead, pushed off-centre by its heavy
  head: a known limitation, see tests/test_gaits_snake.py.)
- ``rotating``: both waves travel with different k (k_v = 2 k_h), 90 degrees apart: the
  snake turns about its vertical axis.
- ``circular-path``: the rectilinear wave on a body bent into an arc by a constant
  horizontal offset O_h, so the rectilinear motion follows a circle.

Trajectories start and end straight and at rest: the amplitudes (and offsets) fade in and
out with a minimum-jerk envelope over ``FADE_CYCLES`` cycles, so positions and velocities
are continuous.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from gaits.base import BehaviorSpec, Controller, DesignGeometry, Parameter, Trajectory

__all__ = [
    "GAITS",
    "SnakeController",
    "WaveParams",
    "gait_params",
    "joint_waves",
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
) -> np.ndarray:
    """Joint angles (N, M) rad of eq. 7 at ``phase`` (N,) rad; column j is ``joint_{j+1}``
    (odd joints vertical, even horizontal). ``envelope`` (N,) in [0, 1] scales amplitudes
    and offsets (fading in and out)."""
    _check_modules(modules)
    ph = np.atleast_1d(np.asarray(phase, dtype=float))
    env = np.broadcast_to(np.asarray(envelope, dtype=float), ph.shape)
    out = np.empty((len(ph), modules))
    for j in range(modules):
        i = j // 2  # (i - 1) of eq. 7: index of the module among those of its orientation
        if j % 2 == 0:  # joint_1, joint_3, ...: vertical
            out[:, j] = env * (p.o_v + p.a_v * np.sin(ph + i * p.dphi_v))
        else:
            out[:, j] = env * (p.o_h + p.a_h * np.sin(ph + i * p.dphi_h + p.dphi_vh))
    return out


def _joint_wave_rates(
    phase: np.ndarray,
    phase_rate: float,
    modules: int,
    p: WaveParams,
    envelope: np.ndarray,
    envelope_rate: np.ndarray,
) -> np.ndarray:
    """Time derivative (N, M) rad/s of ``joint_waves`` for d(phase)/dt = ``phase_rate``
    rad/s and the envelope's rate (N,) 1/s."""
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
SIDEWINDING_ALPHA = (math.radians(6), math.radians(20))  # A_v = 10, A_h = 35 degrees
ROTATING_ALPHA = (math.radians(5), math.radians(32))  # M = 8: A_v = 10, A_h = 45 degrees
#: Horizontal undulations k_h of ``rotating`` along the body whatever M (k_v = 2 k_h).
#: Simulated on the designed snakes (M = 8, 10, 14, payload 0-0.5 kg): k_h = 0.75 turns
#: them 130-170 degrees per 10 s, the horizontal wave lagging the vertical one by 90
#: degrees turning counter-clockwise; k_h = M / 8 (one undulation at M = 8) turns M = 8
#: at 45 degrees per 10 s and M = 10 and 14 hardly, M = 14 the wrong way.
ROTATING_WAVES = 0.75
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
        p = WaveParams(a_v, 0.0, direction * wave_phase_step(k, modules))
        if gait == "circular-path":
            if not abs(bend) <= BEND_MAX:
                raise ValueError(f"bend must be within +-{BEND_MAX:.3g} rad, got {bend!r}")
            p = replace(p, o_h=bend)
        return p
    if gait == "sidewinding":
        step = -wave_phase_step(k, modules)
        a_v = wave_amplitude(SIDEWINDING_ALPHA[0], k, modules)
        a_h = wave_amplitude(SIDEWINDING_ALPHA[1], k, modules)
        return WaveParams(a_v, a_h, step, step, direction * math.pi / 2)
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
    first and last of which fade in and out) and ``direction`` (+1 / -1);
    ``circular-path`` also takes ``bend`` rad. Senses, in the frame of the snake's base
    at the start (the base is the head: the modules extend from it along +x):

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
    no-load speed raises ValueError naming the highest feasible one.
    """

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

    def max_frequency(self, gait: str, direction: int = 1, bend: float = 0.0) -> float:
        """Highest wave frequency Hz of ``gait`` within the modules' usable speed (joint
        rates scale with the frequency, fade included)."""
        _, _, v, _ = self._trajectory(gait, 1.0, 3, direction, bend)
        return self.max_speed / float(np.abs(v).max())

    def default_frequency(self, gait: str) -> float:
        """Default wave frequency Hz of ``gait``: ``DEFAULT_FREQUENCY``, lower when the waves
        would ask a joint for more than ``SPEED_SHARE`` of its no-load speed."""
        share = SPEED_SHARE / SPEED_MARGIN
        return float(f"{min(DEFAULT_FREQUENCY, share * self.max_frequency(gait)):.3g}")

    @property
    def body_length(self) -> float:
        """Length m of the module chain (M module pitches)."""
        return self.modules * float(self.template.lengths["module"])

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        out = {}
        for gait in self.gaits:
            f = self.default_frequency(gait)
            params = [
                Parameter("frequency", "float", f, "wave frequency", "Hz", low=1e-3, high=10),
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
            ]
            if gait == "circular-path":
                params.append(
                    Parameter(
                        "bend",
                        "float",
                        round(CIRCLE_BEND / (self.modules // 2), 4),
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
        freq, cycles = float(params["frequency"]), int(params["cycles"])
        t, q, v, p = self._trajectory(name, freq, cycles, direction, bend)
        top = float(np.abs(v).max())
        if top > self.max_speed * (1 + 1e-9):
            raise ValueError(
                f"{name} at {freq:g} Hz needs {top:.3g} rad/s, above the usable "
                f"{self.max_speed:.3g} rad/s of the modules ({SPEED_MARGIN:.0%} of their "
                f"no-load speed); at most {freq * self.max_speed / top:.3g} Hz"
            )
        if np.any(q < self.lower - 1e-9) or np.any(q > self.upper + 1e-9):
            raise ValueError(f"{name}: the waves leave the joints' range")
        info: dict[str, object] = {
            "motion": "rotate" if name == "rotating" else "crawl",
            "locomotion": "snake",
            "body_length_m": self.body_length,
            "waves": p,
            "frequency_hz": freq,
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
        self, gait: str, freq: float, cycles: int, direction: int, bend: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, WaveParams]:
        """(t (N,) s, q (N, M) rad, v (N, M) rad/s, waves) of ``cycles`` waves at ``freq``
        Hz with minimum-jerk fades over the first and last ``FADE_CYCLES``."""
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
        q = joint_waves(w * t, self.modules, p, env)
        v = _joint_wave_rates(w * t, w, self.modules, p, env, env_rate)
        return t, q, v, p


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
