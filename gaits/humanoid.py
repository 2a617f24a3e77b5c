"""Humanoid behaviours: the paper's synthetic locomotion (section 4.3.5, Figs. 22-24).

The paper took the joint trajectories of a stable gait of a reference robot, kept a few
frequency components per joint (FFT), and found empirically "conversion maps" from the
length of the leg's passive modules to scale factors of those components, so that any
printed size gets its gait as ``A_j(t) = (a x + b) sum_i a_i sin(w_i t + phi_i)``. Here:

1. **Reference gait** (:func:`reference_gait`): one stride of a periodic walk of the
   reference humanoid (the part kinds' default biped scaled geometrically to
   femur = tibia = ``x``, as parmor sizes humanoids in proportion to their height). The
   zero-moment point (ZMP) rests under the stance ankle (laterally ``sway`` of the way)
   and moves to the next foot in double support; the centre of mass (COM) is the exact
   periodic solution of the linear inverted pendulum ``c - (z_c / g) c'' = p`` (solved
   per Fourier component); the pelvis is placed so that the whole-body COM of the
   multibody model (``kinematics.center_of_mass``) follows it; swing feet follow
   minimum-jerk paths with a C2 lift; :func:`leg_ik` (closed form) gives the angles.
2. **Synthetic locomotion** (:func:`synthesize`): each joint's trajectory over one stride
   (two steps) through an FFT, keeping its mean and ``HARMONICS`` stride harmonics.
3. **Conversion maps** (:class:`ConversionMaps`, :func:`fit_maps`): reference gaits for
   the leg module lengths ``MAP_SIZES`` and the step ratios ``MAP_RATIOS`` (step length
   over its default); each component's scale factor against the reference size (an
   in-phase and a quadrature one: a component's phase drifts a little with the step
   length) is fitted by least squares as ``(a x + b) + r (c x + d) + r^2 (e x + f)``:
   for a given step, the paper's linear map in x. :func:`conversion_maps` fits them on
   first use (deterministic; about half a second per gait). The maps reproduce the 20
   reference gaits they were fitted on to within 0.01 rad, and gaits between them too.
4. A designed humanoid (:class:`HumanoidController`) gets its joint trajectories from the
   maps alone, with ``x`` = (femur + tibia) / 2 of the design: a crouch from q = 0, the
   weight shift and foot lift faded in while stepping in place, the step length grown
   and shrunk only while a foot is in the air (:class:`GaitPlan`), then a fade out.

Open loop on the MJCF's position servos (no feedback from the trunk's attitude), and
with SG90 servos (0.18 N m stall) at the default design's hip and ankle pitch joints, the
sagittal balance is marginal: in single support the ankle holds the COM only within
about 11 mm of the ankle. The gait shapes (``WALK``, ``RUN``) were therefore tuned by a
parameter search in MuJoCo on the default design (40 cm tall): a shallow crouch
(hip-ankle 96 % of the leg, knees near 0.6 rad as in the sizing's load case), small
steps (12 % of the leg), a high foot lift, and 80 % of the lateral sway to the stance
ankle (a full sway rolls the ankle's actuator box onto the floor). The standing
behaviours (grasping, balancing) use that crouch.

The walk under perturbation (``parmor design --robustness``, ``synth.verification.perturb``): it
fell in 34 of 48 perturbed runs of the default design and passed 3. Replayed one
perturbation at a time (``bench/robust_humanoid.py``), the servos' play alone broke it;
a high foot lift and a fast step rocked the robot sideways over its ankles' and hips'
play until it fell. A lower lift stopped the falls, but then the hip pitch's play cost
distance: the trunk's weight loads the stance hip about zero, so each landing took up
its play the other way, about 4 mm a step (0.77 x the planned distance, whatever the
seed). ``ROBUST_WALK`` is tuned for the perturbed runs (a parameter search on seeds
11-26, checked on seeds 1-48): the arms held back (``arms``, 0.6 rad at the shoulders,
in the plan's COM) keep the stance hips' load one-sided, so their play stays taken up; a
foot lift of 8 % of the leg (soft landings), a slower step (1.1 s at the reference leg)
with a longer double support (45 %), a lower hip (92 %) and 75 % of the sway. Its
perturbed runs passed 38 of 48 on the same design, none fell (the trunk
tilted at most 8 deg); the 10 failed runs failed distance (8: short of 0.8 x the plan;
3 of them also progress), heading (1) or saturation (1). With the SG90s' play as metal
gears' (0.3-0.6 deg and a 5 us dead band) it passed 21 of seeds 1-24 (22 with the
plastic play): the play left is not what limits it. It is not the default walk: on an
arc (``curvature``) it turned 84-90 % of the plan (the verdict allows 10 % off; the
hips' yaw fights itself while both feet are down, 45 % of the time), and the steered
loops of bench/sensing_humanoid.py, whose straight strides it would walk between arcs
of this gait, passed 19 of 24 (24 with this gait alone).

Measured again once the perturbed floors used MuJoCo's no-slip solver (the feet no
longer creep; ``bench/robust_humanoid.py seeds 48 --walk robust``): ``ROBUST_WALK``
passes 24 of seeds 1-48 on the default design (the default walk 1 of seeds 1-24), and
what breaks it is the hips' yaw. While both feet are down the legs and the floor close a
loop that the perturbations (a lateral slope, the joints' play) twist: the rear leg's hip
yaw, an SG90 (the gaits plan it 0.04 N m), is driven past its stall torque, the trunk
yaws up to 8 deg, and the run fails saturated (the hip yaw the most saturated joint in
each), short or off its heading; its distance also grows with the slope along the walk
(about 15 % a degree: 0.64-1.41 x). Without the hip yaws' play it passes 33 of 48
(0.74-1.39 x, the SG90 still saturated): their torque is what is missing first. The same
design with the hip yaws given the hip pitch's torque and gains
(``--yaw-as-pitch``) passes 39 of 48 (with 0.3 kg, 43; the rest: downhill distance up to
1.38 x, heading 0.28-0.32 rad on lateral slopes: the SG90's play), with an MG996R at the
hip yaws (the bundle edited by hand: its torque and its metal gears' play) 48 of 48
(``tests/synth/verification/test_humanoid_hip_yaw.py`` pins seeds 6 and 8).
Arcs of this gait turn 0.87-0.92 x on that robot (0.91-0.94 x with the arms hanging,
0.94-0.96 x with 0.75 s steps; holding both hips' yaw while both feet are down, turning
only in single support, gave 0.88-1.07 x). It therefore measures its turn on the design
(``measured_turn``: a probe arc at 10 rad/m, :meth:`HumanoidController.calibrate`, the
gain 1.13-1.15): calibrated, its arcs turn 0.95-1.04 x from 2 to 30 rad/m, but from 10
rad/m on they end 15-26 mm off their planned pose (the verdict allows 10 % of the 0.15 m
path), their heading right. The sensing loops are the other obstacle: on the nominal
model, line-tracking with this walk loses the line for 0.75 s (allowed 0.5; the default
walk 0.2 s), its slower steps swaying the sensors farther; with 65 % of the sway 0.15 s
(and 47 of 48 perturbed runs on the MG996R hip yaws), with 70 % 0.65 s (48 of 48).

The servos' give. A position servo is a spring (``kp``, N m/rad) with a velocity gain
(``kv`` plus the motor's back-EMF, N m s/rad): it settles ``tau / kp`` short of its
reference under a load ``tau`` and lags a moving reference by ``(kv + damping) / kp`` s
(15-35 ms here, different per joint). Measured in MuJoCo on the default design, the walk
then went 1.31 x the distance its joint angles command (its stance foot rolled forward
about 3 mm per step and its steps landed long; the joints' tracking error was mostly
that lag, 30 mrad rms at the hip pitch); with 20 x stiffer servos it went 1.02 x. Given the
servos' ``stiffness`` and ``damping`` (``synth.verification.runs`` passes the MJCF's), the
controller commands ``q + (tau + damping q') / kp`` with ``tau`` the stance loads of
:func:`stance_torques` (the template's masses with the design's payload): 1.02 x. The
plan (``planned_pose``, ``info["planned_positions"]``) stays the bare angles ``q``.

Balance (issue 30): a design with an IMU on its trunk (every biped: ``BipedalRobot`` in
the KIF) runs every behaviour closed on it (:mod:`gaits.balance`: the stance ankles turn the
trunk back upright, the swing foot is kept parallel to the floor, the steps shortened
downhill), and walks ``ROBUST_WALK`` (``WALK`` when other sensors steer its walk); a design
without one walks ``WALK`` open loop. With the loop, the default humanoid's walk passes 24
of seeds 1-24 (distance 0.94-1.21 x); measured in ``docs/feedback-balance.md``.

Units: m, s, rad. Frames: trunk frame at the pelvis centre, x forward, z up (the
template's); a reference gait's world frame has the ground at z = 0.
"""

from __future__ import annotations

import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache, partial
from math import pi
from pathlib import Path

import numpy as np

from gaits.balance import balance_spec
from gaits.base import (  # noqa: F401 - CACHE_ENV: the cache folder's variable, for callers
    CACHE_ENV,
    BehaviorSpec,
    Controller,
    DesignGeometry,
    Parameter,
    Trajectory,
    cache_folder,
    cache_write,
    quat_yaw,
)
from gaits.feedback import IMU_CLASS, has_imu
from gaits.steering import SteerableSpec
from kinematics.bodyplan import BodyPlan, PartNode
from kinematics.dynamics import center_of_mass, external_force_at, forward_kinematics, rnea
from kinematics.model import GRAVITY
from kinematics.templates import (
    FOOT_WIDTH_RATIO,
    Template,
    TemplateParams,
    build,
    default_lengths,
)

__all__ = [
    "ARM_JOINTS",
    "GRIPPER_OPEN",
    "HARMONICS",
    "LEG_JOINTS",
    "MAP_RATIOS",
    "MAP_SIZES",
    "REACH_SHOULDER",
    "ROBUST_WALK",
    "RUN",
    "WALK",
    "ConversionMaps",
    "GaitPlan",
    "GaitShape",
    "HumanoidController",
    "ReferenceGait",
    "Synthetic",
    "conversion_maps",
    "fit_maps",
    "leg_ik",
    "leg_module_range",
    "odometry",
    "reference_gait",
    "reference_template",
    "stability_margin",
    "stance_height",
    "stance_loads",
    "stance_torques",
    "synthesize",
]

SIDES = ("l", "r")  # left (+y), right (-y)
LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee_pitch", "ankle_pitch", "ankle_roll")
ARM_JOINTS = ("shoulder_pitch", "elbow_pitch", "gripper")
#: Leg module lengths x (m, femur = tibia = x) of the reference gaits the maps are fitted on:
#: every link length the reference catalog prints (40-200 mm), so that no design's gait is
#: extrapolated; a leg outside them is refused (:func:`leg_module_range`).
MAP_SIZES = (0.04, 0.06, 0.08, 0.10, 0.12, 0.15, 0.20)
#: Step lengths (fractions of the gait's default) of the reference gaits of the maps.
MAP_RATIOS = (0.0, 0.5, 1.0, 1.25)
#: The reference size of the synthetic locomotion (m): the template's default femur.
REFERENCE_SIZE = 0.09
#: Leg length (femur + tibia, m) at which a ``GaitShape``'s step period is given.
REFERENCE_LEG = 2 * REFERENCE_SIZE
#: Harmonics of the stride frequency kept per joint (besides the mean).
HARMONICS = 8
SAMPLES = 256  # samples of one stride of a reference gait
CROUCH_TIME = 1.0  # s from q = 0 to the gait's mean pose
SAMPLE_DT = 0.01  # s between trajectory samples
SETTLE_TIME = 0.5  # s of standing still at the end of a behaviour
#: ``calibration`` key: the arcs' hip yaw over the plan's (:meth:`HumanoidController.calibrate`)
TURN_GAIN = "walking_turn_gain"
#: rad/m: the probe arc's curvature, the first the design's hips turn
PROBE_CURVATURES = (10.0, 5.0, 2.0)
#: the calibrated gain's bounds (a probe outside them measured something else)
TURN_GAIN_RANGE = (0.5, 2.0)
#: The balance loop's gains (:data:`gaits.balance.GAINS` overridden) of the gaits and of
#: the standing behaviours (grasping, balancing): measured in MuJoCo on the default design
#: under its perturbations (``docs/feedback-balance.md``)
BALANCE_GAINS: dict[str, dict[str, float]] = {
    "gait": {"kp_ankle": 0.3, "kd_ankle": 0.05, "k_slope": 4.0, "k_level": 0.5},
    "stand": {"kp_ankle": 0.15, "kd_ankle": 0.02},
    # ``WALK`` of a design whose other sensors steer it: its arcs end within 10 mm of their
    # planned pose only with a gentler loop (the plan's own sway, 1 deg, left to it)
    "steered": {
        "kp_ankle": 0.3,
        "kd_ankle": 0.02,
        "deadband_rad": 0.02,
        "k_slope": 4.0,
        "k_level": 0.5,
    },
}
#: relative change of the step length of the stride derivative (``info["feedback"]["stride"]``)
STRIDE_EPS = 0.05
#: Default full steps of a walk or run: enough that the starting and stopping half steps
#: and the crouch take under half of the behaviour's time.
DEFAULT_STEPS = 6
#: rad/m: the bounds of walking's ``curvature`` parameter; the tightest arc a design walks
#: is its hip yaw's range over its ankles' swing (:meth:`HumanoidController.max_curvature`)
CURVATURE_LIMIT = 50.0
#: columns of the hip yaw (left, right) and of the hip pitch (the knee follows it) in
#: the leg angles (``_joint_names(LEG_JOINTS)``)
YAW = [LEG_JOINTS.index("hip_yaw"), len(LEG_JOINTS) + LEG_JOINTS.index("hip_yaw")]
PITCH = [LEG_JOINTS.index("hip_pitch"), len(LEG_JOINTS) + LEG_JOINTS.index("hip_pitch")]
KNEE = [LEG_JOINTS.index("knee_pitch"), len(LEG_JOINTS) + LEG_JOINTS.index("knee_pitch")]


# --- leg kinematics ------------------------------------------------------------------------------


def leg_ik(ankle: np.ndarray, femur: float, tibia: float) -> np.ndarray:
    """Joint angles (..., 6) rad of one leg, in ``LEG_JOINTS`` order, that put the ankle at
    ``ankle`` (..., 3) m with the foot parallel to the trunk and hip yaw 0.

    ``ankle`` is relative to the leg's hip point (where hip yaw, roll and pitch axes meet)
    in trunk axes. Closed form: the hip roll turns the leg's plane through the ankle, the
    knee angle follows from the hip-ankle distance (law of cosines, knee bent forward,
    ``knee >= 0``), the hip pitch aims the femur-tibia triangle, and the ankle pitch and
    roll undo the leg's pitch and roll. ValueError when the ankle is out of reach.
    """
    p = np.asarray(ankle, dtype=float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"ankle positions must have shape (..., 3), got {p.shape}")
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    if np.any(z >= 0):
        raise ValueError("the ankle must be below the hip (z < 0)")
    roll = np.arctan2(y, -z)
    zp = -np.hypot(y, z)  # ankle z in the rolled leg plane
    c = (x * x + zp * zp - femur**2 - tibia**2) / (2 * femur * tibia)
    if np.any(c > 1 + 1e-9) or np.any(c < -1 - 1e-9):
        raise ValueError(
            f"ankle out of reach: hip-ankle distance must be within "
            f"[{abs(femur - tibia):.4f}, {femur + tibia:.4f}] m"
        )
    knee = np.arccos(np.clip(c, -1.0, 1.0))
    hip = np.arctan2(-x, -zp) - np.arctan2(tibia * np.sin(knee), femur + tibia * np.cos(knee))
    return np.stack([np.zeros_like(x), roll, hip, knee, -(hip + knee), -roll], axis=-1)


def _with_arms(
    model_names: tuple[str, ...], names: tuple[str, ...], q: np.ndarray, arms: float
) -> np.ndarray:
    """:func:`_q_full` of the leg angles ``q`` with both shoulders' pitch at ``arms`` rad."""
    shoulders = _joint_names(ARM_JOINTS[:1])
    held = np.full((q.shape[0], len(shoulders)), arms)
    return _q_full(model_names, names + shoulders, np.concatenate([q, held], axis=1))


def _joint_names(part: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(f"{s}_{j}" for s in SIDES for j in part)


def _q_full(model_names: tuple[str, ...], names: tuple[str, ...], q: np.ndarray) -> np.ndarray:
    """(n, nq) model coordinates with ``q`` (n, len(names)) placed by name, others 0."""
    out = np.zeros((q.shape[0], len(model_names)))
    index = {n: k for k, n in enumerate(model_names)}
    for k, n in enumerate(names):
        out[:, index[n]] = q[:, k]
    return out


# --- the reference gait --------------------------------------------------------------------------


@dataclass(frozen=True)
class GaitShape:
    """A periodic gait in proportions of the leg length ``L = femur + tibia``.

    ``step_period`` s per step (a stride is two steps) of legs of ``REFERENCE_LEG`` m; other
    legs step with the same Froude number (:meth:`period`); ``double_support`` fraction of a
    step with both feet down; ``height`` hip-ankle distance / L with the COM over the
    stance ankle (< 1: crouched); ``step`` default step length / L; ``lift`` swing foot
    lift / L; ``sway`` lateral ZMP position in single support as a fraction of half the
    hip width (1: under the stance ankle); ``arms`` the shoulders' pitch rad held through
    the gait (positive: the arms back), part of the whole-body COM the gait is planned
    with (see :data:`ROBUST_WALK`); ``measured_turn``: its arcs' hip yaw is scaled by the
    turn measured on the design (:meth:`HumanoidController.calibrate`).
    """

    name: str
    step_period: float
    double_support: float
    height: float
    step: float
    lift: float
    sway: float
    arms: float = 0.0
    measured_turn: bool = False

    def period(self, leg: float) -> float:
        """Step period s of legs of length ``leg`` m: ``step_period`` scaled with
        ``sqrt(leg / REFERENCE_LEG)``, so that every size walks with the same Froude number
        (a pendulum's period grows with the square root of its length). The crouched
        inverted pendulum's dynamics ``zc / g`` then scale with the period squared, and the
        gait's joint angles are the same at every size up to the actuators' fixed size."""
        return self.step_period * float(np.sqrt(leg / REFERENCE_LEG))


#: The walking gait: tuned in MuJoCo on the default design (see the module docstring).
WALK = GaitShape("walking", 0.75, 0.25, 0.96, 0.12, 0.12, 0.8)
#: A walk tuned for the perturbed runs (the module docstring), not the default: on an arc
#: it turns 10-16 % short, and steered loops that mix it with walking on arcs lose their
#: line or touch their obstacle (``bench/robust_humanoid.py --walk robust`` runs it).
ROBUST_WALK = GaitShape("walking", 1.1, 0.45, 0.92, 0.12, 0.08, 0.75, 0.6, measured_turn=True)
#: The faster gait (``running``): a shorter period and double support, longer steps. Its
#: period is bounded by the servos' speed at the smallest legs: the same Froude number gives
#: short legs fast joints (``1 / sqrt(leg)``), and at the 40 mm leg modules a 0.5 s step
#: needs the knee at 6.6 rad/s, beyond the catalog's stronger servos' no-load 6.2-6.5 rad/s
#: (measured in MuJoCo: saturated); 0.6 s steps peak at 5.5 rad/s and pass at every size.
RUN = GaitShape("running", 0.6, 0.15, 0.96, 0.15, 0.12, 0.8)


@dataclass(frozen=True)
class ReferenceGait:
    """One stride of a periodic reference gait, sampled uniformly.

    ``t`` (n,) s over ``[0, period)``; ``joints`` the 12 leg joint names; ``q`` (n, 12)
    rad; ``com`` (n, 3), ``pelvis`` (n, 3) m, ``zmp`` (n, 2) m and ``ankles`` (2, n, 3) m
    (left, right) in the world (ground z = 0); ``step_length`` m advance per step.
    """

    shape: GaitShape
    size: float
    step_length: float
    period: float
    t: np.ndarray
    joints: tuple[str, ...]
    q: np.ndarray
    com: np.ndarray
    pelvis: np.ndarray
    zmp: np.ndarray
    ankles: np.ndarray


def _smooth(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk blend 0 -> 1 of s in [0, 1] (clipped)."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10 - 15 * s + 6 * s * s)


def stance_height(shape: GaitShape, leg: float, half_hip: float) -> float:
    """Hip-ankle height m of ``shape`` for legs of length ``leg`` m: the hip-ankle distance
    is ``shape.height * leg`` with the COM swayed over the stance ankle."""
    reach = shape.height * leg
    lateral = shape.sway * half_hip
    if lateral >= reach:
        raise ValueError(f"legs of {leg:.3f} m cannot sway {lateral:.3f} m sideways")
    return float(np.sqrt(reach * reach - lateral * lateral))


def _reference_plan() -> BodyPlan:
    """The synthetic locomotion's reference humanoid (the paper's Fig. 21): an upright
    torso, two biped legs, two arms with grippers, as the part kinds build them (not a
    robot type of the ontology: the gait method's own model)."""
    arm = PartNode("HumanoidArm", children=(PartNode("RoboticGripper"),))
    legs = (PartNode("BipedLeg"),) * 2
    return BodyPlan("ReferenceHumanoid", PartNode("HumanoidTorso", children=(*legs, arm, arm)))


@cache
def reference_template(size: float) -> Template:
    """The reference humanoid of leg module length ``size`` m: the part kinds' default
    humanoid scaled geometrically (every length times ``size / REFERENCE_SIZE``, as parmor
    sizes humanoids in proportion to their height), femur = tibia = ``size``. Built once
    per size (a template is immutable; the conversion maps ask for each size per ratio)."""
    plan = _reference_plan()
    k = size / REFERENCE_SIZE
    lengths = {name: k * v for name, v in default_lengths(plan).items()}
    lengths.update(femur=size, tibia=size)
    return build(plan, TemplateParams(lengths=lengths))


def _lipm_periodic(p: np.ndarray, period: float, zc: float) -> np.ndarray:
    """The periodic COM (n,) of a linear inverted pendulum of height ``zc`` m whose ZMP is
    the periodic ``p`` (n,) sampled over ``period`` s: ``c - zc/g c'' = p``, exactly, per
    Fourier component."""
    n = len(p)
    w = 2 * pi * np.fft.rfftfreq(n, period / n)
    return np.fft.irfft(np.fft.rfft(p) / (1 + w * w * zc / GRAVITY), n)


def reference_gait(
    size: float,
    shape: GaitShape = WALK,
    ratio: float = 1.0,
    samples: int = SAMPLES,
    template: Template | None = None,
    com_model: Callable[[np.ndarray], np.ndarray] | None = None,
) -> ReferenceGait:
    """The periodic gait ``shape`` of the reference humanoid of leg module length ``size``
    m, with steps of ``ratio`` times the default step length (forward, x).

    Timing of one stride (``T`` = step period, ``d`` = double support): [0, dT) weight to
    the left foot; [dT, T) left support, right foot swings forward; [T, T + dT) weight to
    the right; [T + dT, 2T) right support, left foot swings. ``template`` overrides the
    reference humanoid (its own femur and tibia are used); ``com_model`` maps leg angles
    (n, 12) to the whole-body COM (n, 3) m relative to the pelvis (default: the template's
    multibody model), e.g. to plan with a measured mass distribution.
    """
    if not size > 0:
        raise ValueError(f"size must be positive, got {size!r}")
    if ratio < 0:
        raise ValueError(f"ratio must be >= 0, got {ratio!r}")
    tmpl = template if template is not None else reference_template(size)
    femur, tibia = tmpl.lengths["femur"], tmpl.lengths["tibia"]
    leg = femur + tibia
    T, d = shape.period(leg), shape.double_support
    period = 2 * T
    n = samples
    t = np.arange(n) * period / n
    s = shape.step * leg * ratio
    sole = tmpl.params.actuator_size[2] / 2
    hw = tmpl.lengths["hip_width"] / 2
    h = stance_height(shape, leg, hw)
    lift = shape.lift * leg

    # feet (ankles, world): left lands at x = 0 at t = 0, the right one is at -s then
    ankles = np.zeros((2, n, 3))
    ankles[0, :, 1], ankles[1, :, 1] = hw, -hw
    ankles[:, :, 2] = sole
    right_swing = _smooth((t - d * T) / ((1 - d) * T))  # right: -s -> +s in [dT, T)
    left_swing = _smooth((t - T - d * T) / ((1 - d) * T))  # left: 0 -> 2s in [T + dT, 2T)
    ankles[1, :, 0] = -s + 2 * s * right_swing
    ankles[0, :, 0] = 2 * s * left_swing

    def bump(u: np.ndarray) -> np.ndarray:  # 0 -> 1 -> 0, C2, peak at u = 1/2
        inside = (u > 0) & (u < 1)
        return np.where(inside, 64 * u**3 * (1 - u) ** 3, 0.0)

    ankles[1, :, 2] += lift * bump((t - d * T) / ((1 - d) * T))
    ankles[0, :, 2] += lift * bump((t - T - d * T) / ((1 - d) * T))

    # ZMP: at the stance ankle, moved smoothly between the feet in double support
    to_left = _smooth(t / (d * T)) - _smooth((t - T) / (d * T))  # 1 on the left foot
    zx = -s + s * _smooth(t / (d * T)) + s * _smooth((t - T) / (d * T))
    zy = shape.sway * hw * (2 * to_left - 1)
    zmp = np.stack([zx, zy], axis=1)

    # pelvis such that the whole-body COM follows the periodic LIPM solution
    names = _joint_names(LEG_JOINTS)
    model = tmpl.model
    q_names = model.q_names
    hips = np.array([[0.0, hw, 0.0], [0.0, -hw, 0.0]])
    pelvis_z = h + sole
    v = s / T  # mean forward speed, m/s
    offset = np.zeros((n, 3))
    com = np.zeros((n, 3))
    zc = pelvis_z
    for _ in range(6):  # the COM's offset from the pelvis depends on the pose: iterate
        pelvis = np.zeros((n, 3))
        pelvis[:, 2] = pelvis_z
        com[:, 0] = v * t + _lipm_periodic(zx - v * t, period, zc)
        com[:, 1] = _lipm_periodic(zy, period, zc)
        pelvis[:, :2] = com[:, :2] - offset[:, :2]
        q = np.concatenate(
            [leg_ik(ankles[k] - pelvis - hips[k], femur, tibia) for k in range(2)], axis=1
        )
        offset = (
            center_of_mass(model, _with_arms(q_names, names, q, shape.arms))
            if com_model is None
            else com_model(q)
        )
        zc = pelvis_z + float(offset[:, 2].mean())
    com[:, 2] = pelvis_z + offset[:, 2]
    return ReferenceGait(shape, float(size), s, period, t, names, q, com, pelvis, zmp, ankles)


# --- synthetic locomotion ------------------------------------------------------------------------


@dataclass(frozen=True)
class Synthetic:
    """Sum-of-sines joint trajectories ``q_j(t) = sum_i a_ji sin(w_ji t + phi_ji)``.

    ``joints`` names; ``harmonics`` (J, K) int multiples of the stride frequency
    ``2 pi / period`` (0: the joint's mean, with ``phi = pi / 2``); ``amplitudes`` (J, K)
    rad; ``phases`` (J, K) rad.
    """

    period: float
    joints: tuple[str, ...]
    harmonics: np.ndarray
    amplitudes: np.ndarray
    phases: np.ndarray

    @property
    def omegas(self) -> np.ndarray:
        """(J, K) angular frequencies rad/s."""
        return self.harmonics * (2 * pi / self.period)

    def __call__(
        self, t: np.ndarray, scale: np.ndarray | None = None, quadrature: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(positions rad, velocities rad/s) (n, J) at times ``t`` (n,) s.

        ``scale`` (J, K) multiplies each component (default 1); ``quadrature`` (J, K) adds
        ``quadrature * a sin(w t + phi + pi / 2)`` per component (default 0).
        """
        t = np.asarray(t, dtype=float)[:, None, None]
        w = self.omegas
        arg = w * t + self.phases
        s = np.ones_like(self.amplitudes) if scale is None else np.asarray(scale)
        c = np.zeros_like(self.amplitudes) if quadrature is None else np.asarray(quadrature)
        sin, cos = np.sin(arg), np.cos(arg)
        a_in, a_q = self.amplitudes * s, self.amplitudes * c
        q = (a_in * sin + a_q * cos).sum(-1)
        v = (w * (a_in * cos - a_q * sin)).sum(-1)
        return q, v


def _coefficients(q: np.ndarray) -> np.ndarray:
    """Complex Fourier coefficients (n // 2 + 1, J) of periodic samples q (n, J): q(t) =
    c_0 + sum_h 2 Re(c_h exp(i h w t))."""
    return np.fft.rfft(q, axis=0) / q.shape[0]


def _pick(c: np.ndarray, harmonics: np.ndarray) -> np.ndarray:
    """(J, K) coefficients of ``c`` (H, J) at each joint's ``harmonics`` (J, K)."""
    return c[harmonics, np.arange(harmonics.shape[0])[:, None]]


def _largest(magnitudes: np.ndarray, k: int) -> np.ndarray:
    """(J, k + 1): harmonic 0 and the ``k`` largest of ``magnitudes`` (H, J) (harmonics
    1.., ties: the lower), ascending."""
    order = np.argsort(-magnitudes[1:].T, axis=1, kind="stable")[:, :k] + 1
    J = magnitudes.shape[1]
    return np.concatenate([np.zeros((J, 1), dtype=int), np.sort(order, axis=1)], axis=1)


def synthesize(
    gait: ReferenceGait, harmonics: int = HARMONICS, select: np.ndarray | None = None
) -> Synthetic:
    """The synthetic locomotion of a reference gait: per joint, its mean and its
    ``harmonics`` largest stride harmonics from an FFT (or the harmonics ``select`` (J, K)
    names)."""
    c = _coefficients(gait.q)
    hs = _largest(np.abs(c), harmonics) if select is None else np.asarray(select, dtype=int)
    coef = _pick(c, hs)
    amp = np.where(hs == 0, coef.real, 2 * np.abs(coef))
    phase = np.where(hs == 0, pi / 2, np.angle(coef) + pi / 2)
    return Synthetic(gait.period, gait.joints, hs, amp, phase)


def _basis(x: float, r: float) -> np.ndarray:
    return np.array([x, 1.0, r * x, r, r * r * x, r * r])


@dataclass(frozen=True)
class ConversionMaps:
    """Scale factors of the synthetic locomotion's components as functions of the leg
    module length ``x`` (m) and the step ratio ``r`` (step length / the default one).

    Each component ``a sin(w t + phi)`` of ``reference`` (the synthetic locomotion of the
    reference size) gets an in-phase scale ``s`` and a quadrature scale ``s_q`` (the
    component's phase drifts with the step length):
    ``s a sin(w t + phi) + s_q a sin(w t + phi + pi / 2)``; each scale is
    ``(a x + b) + r (c x + d) + r^2 (e x + f)`` with ``coef[j, i, {0: s, 1: s_q}] =
    (a, b, c, d, e, f)``: linear in x for a given step, as the paper's maps.
    ``sizes``, ``ratios``: the grid of reference gaits it was fitted on; ``residual``: the
    largest joint-angle error (rad) of the maps against those gaits.
    """

    shape: GaitShape
    reference: Synthetic
    coef: np.ndarray
    sizes: tuple[float, ...]
    ratios: tuple[float, ...]
    residual: float

    def stride(self, x: float) -> float:
        """Stride period s (two steps) of the mapped gait at leg module length ``x`` m."""
        return 2 * self.shape.period(2 * x)

    def covers(self, x: float) -> bool:
        """Whether ``x`` m is within the sizes the maps were fitted on (no extrapolation)."""
        return self.sizes[0] - 1e-12 <= x <= self.sizes[-1] + 1e-12

    def scale(self, x: float, r: float) -> tuple[np.ndarray, np.ndarray]:
        """(in-phase, quadrature) scale factors (J, K) at leg module length ``x`` m and step
        ratio ``r``."""
        s = self.coef @ _basis(x, r)
        return s[..., 0], s[..., 1]

    def trajectory(self, x: float, r: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(positions rad, velocities rad/s) (n, J) of the mapped gait at times ``t`` (n,) s
        (its stride lasts :meth:`stride` s: the reference's time is scaled)."""
        k = self.reference.period / self.stride(x)
        q, v = self.reference(np.asarray(t, dtype=float) * k, *self.scale(x, r))
        return q, v * k

    def components(self, x: float, r: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mean, oscillation) (n, J) rad of the mapped gait at times ``t`` (n,) s with a
        step ratio ``r`` (n,) that may change along the way."""
        r = np.asarray(r, dtype=float)
        basis = np.stack([np.full_like(r, x), np.ones_like(r), r * x, r, r * r * x, r * r], 1)
        s = np.einsum("jkcb,nb->njkc", self.coef, basis)  # (n, J, K, 2)
        ref = self.reference
        k = ref.period / self.stride(x)  # the reference's time per second of this size
        arg = ref.omegas * (k * np.asarray(t, dtype=float))[:, None, None] + ref.phases
        terms = ref.amplitudes * (s[..., 0] * np.sin(arg) + s[..., 1] * np.cos(arg))
        mean = ref.harmonics == 0
        return (terms * mean).sum(-1), (terms * ~mean).sum(-1)


def fit_maps(
    shape: GaitShape,
    sizes: tuple[float, ...] = MAP_SIZES,
    ratios: tuple[float, ...] = MAP_RATIOS,
    harmonics: int = HARMONICS,
) -> ConversionMaps:
    """Conversion maps of ``shape`` fitted (least squares) on the reference gaits of every
    size in ``sizes`` (m) and step ratio in ``ratios``; the kept harmonics are each
    joint's largest over all of them."""
    grid = [(x, r, reference_gait(x, shape, r)) for x in sizes for r in ratios]
    coefs = [_coefficients(g.q) for _, _, g in grid]
    hs = _largest(np.abs(np.array(coefs)).sum(0), harmonics)
    base = reference_gait(REFERENCE_SIZE, shape, 1.0)
    reference = synthesize(base, select=hs)
    ref = _pick(_coefficients(base.q), hs)
    tiny = np.abs(ref) < 1e-12
    safe = np.where(tiny, 1.0, ref)
    A = np.array([_basis(x, r) for x, r, _ in grid])  # (N, 6)
    Y = []
    for c in coefs:
        z = np.where(tiny, 1.0, _pick(c, hs) / safe)  # complex scale of each component
        Y.append(np.stack([z.real, z.imag], axis=-1))
    Y = np.array(Y).reshape(len(grid), -1)
    coef, *_ = np.linalg.lstsq(A, Y, rcond=None)
    J, K = hs.shape
    coef = coef.T.reshape(J, K, 2, A.shape[1])
    maps = ConversionMaps(shape, reference, coef, tuple(sizes), tuple(ratios), 0.0)
    worst = max(float(np.abs(maps.trajectory(x, r, g.t)[0] - g.q).max()) for x, r, g in grid)
    return ConversionMaps(shape, reference, coef, tuple(sizes), tuple(ratios), worst)


@cache
def conversion_maps(gait: str | GaitShape = "walking") -> ConversionMaps:
    """The conversion maps of ``gait`` ("walking" or "running": ``WALK``, ``RUN``; or a
    :class:`GaitShape`, e.g. ``ROBUST_WALK``), fitted on first use (the same numbers every
    time: the fit is deterministic), kept on disk between processes (:func:`_maps_file`)."""
    if isinstance(gait, GaitShape):
        return _shape_maps(gait)
    shapes = {WALK.name: WALK, RUN.name: RUN}
    if gait not in shapes:
        raise ValueError(f"no gait {gait!r}; gaits: {', '.join(shapes)}")
    return _shape_maps(shapes[gait])


@cache
def _shape_maps(shape: GaitShape) -> ConversionMaps:
    path = _maps_file(shape)
    maps = _read_maps(path, shape) if path is not None else None
    if maps is None:
        maps = fit_maps(shape)
        if path is not None:
            _write_maps(path, maps)
    return maps


#: What the fitted maps depend on besides the constants of this file: the templates and
#: the multibody code they are planned with (paths relative to the package root).
_MAPS_SOURCES = (
    "gaits/humanoid.py",
    "kinematics/model.py",
    "kinematics/spatial.py",
    "kinematics/dynamics.py",
    "kinematics/templates.py",
)


def _maps_file(shape: GaitShape) -> Path | None:
    """Where the conversion maps of ``shape`` are cached:
    ``$PARMOR_CACHE/gait-maps-NAME-KEY.npz`` (default ``$XDG_CACHE_HOME/parmor``, else
    ``~/.cache/parmor``; ``PARMOR_CACHE=""``: no cache). Fitting them takes about half a
    second a gait; they are a pure function of the code, so KEY hashes the files of
    ``_MAPS_SOURCES`` and numpy's version and build: a change of either starts a new file
    and an entry is never stale. None when there is no cache folder."""
    import hashlib

    folder = cache_folder()
    if folder is None:
        return None
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(repr(shape).encode())
    try:
        for name in _MAPS_SOURCES:
            h.update((root / name).read_bytes())
        core = Path(np._core._multiarray_umath.__file__).stat()
    except (OSError, AttributeError):
        return None
    h.update(f"{np.__version__}|{np.__file__}|{core.st_size}|{core.st_mtime_ns}".encode())
    return folder / f"gait-maps-{shape.name}-{h.hexdigest()[:20]}.npz"


def _read_maps(path: Path, shape: GaitShape) -> ConversionMaps | None:
    """The maps cached in ``path``; None when absent, unreadable or not as written."""
    try:
        with np.load(path, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
        harmonics, amplitudes, phases = d["harmonics"], d["amplitudes"], d["phases"]
        # the fit's layout (a view of lstsq's (6, J K 2) solution): products with the maps
        # then sum in the same order, to the bit
        coef, joints = d["coef_basis_first"].transpose(1, 2, 3, 0), tuple(map(str, d["joints"]))
        J, K = harmonics.shape
        ok = (
            harmonics.dtype.kind == "i"
            and amplitudes.shape == phases.shape == (J, K)
            and coef.shape[:3] == (J, K, 2)
            and len(joints) == J
        )
        if not ok:
            return None
        reference = Synthetic(float(d["period"]), joints, harmonics, amplitudes, phases)
        sizes = tuple(float(x) for x in d["sizes"])
        ratios = tuple(float(x) for x in d["ratios"])
        return ConversionMaps(shape, reference, coef, sizes, ratios, float(d["residual"]))
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile):
        return None


def _write_maps(path: Path, maps: ConversionMaps) -> None:
    """Cache ``maps`` in ``path`` (``gaits.base.cache_write``); a folder that cannot be
    written only means the maps are fitted again next time."""

    ref = maps.reference
    cache_write(
        path,
        lambda f: np.savez(
            f,
            period=np.float64(ref.period),
            joints=np.array(ref.joints, dtype=str),
            harmonics=ref.harmonics,
            amplitudes=ref.amplitudes,
            phases=ref.phases,
            coef_basis_first=np.ascontiguousarray(maps.coef.transpose(3, 0, 1, 2)),
            sizes=np.array(maps.sizes, dtype=float),
            ratios=np.array(maps.ratios, dtype=float),
            residual=np.float64(maps.residual),
        ),
        "gait-maps-",
    )


# --- stability -----------------------------------------------------------------------------------


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    """z of the cross product of two planar vectors."""
    return float(a[0] * b[1] - a[1] * b[0])


def _support_margin(point: np.ndarray, corners: np.ndarray) -> float:
    """Signed distance m of ``point`` (2,) inside the convex hull of ``corners`` (m, 2)
    (negative outside)."""
    pts = np.unique(np.round(corners, 12), axis=0)
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]

    def half(seq):
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-1] - out[-2], p - out[-2]) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    hull = np.array(lower[:-1] + upper[:-1])
    margin = np.inf
    for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True):
        e = b - a
        normal = np.array([-e[1], e[0]]) / np.linalg.norm(e)  # inward for a CCW hull
        margin = min(margin, float(normal @ (point - a)))
    return margin


def _hull_edges(pts: list[tuple[float, float]]) -> list[tuple[tuple[float, float], ...]]:
    """Counter-clockwise edges (a, b) of the convex hull of distinct points ``pts`` sorted
    by (x, y) (monotone chain; collinear points dropped), with the arithmetic of
    :func:`_support_margin`."""

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    if len(pts) == 4:  # one sole: an axis-aligned rectangle, what the chain gives for it
        (x0, y0), (x0b, y1), (x1, y0b), (x1b, y1b) = pts
        if x0 == x0b < x1 == x1b and y0 == y0b < y1 == y1b:
            hull = [pts[0], pts[2], pts[3], pts[1]]
            return list(zip(hull, hull[1:] + hull[:1], strict=True))
    hull = half(pts)[:-1] + half(pts[::-1])[:-1]
    return list(zip(hull, hull[1:] + hull[:1], strict=True))


def _support_margins(points: np.ndarray, valid: np.ndarray, com: np.ndarray) -> np.ndarray:
    """:func:`_support_margin` of many samples at once, to the bit: ``points`` (n, k, 2)
    m of which ``valid`` (n, k) count, centres of mass ``com`` (n, 2) -> (n,) m. The hulls
    are found per sample (a few points each), the distances to every edge at once."""
    pts = np.round(points, 12)
    hulls: dict[tuple, list] = {}  # the same support polygon recurs along a gait
    starts, ends, owner = [], [], []
    for i, (rows, ok) in enumerate(zip(pts.tolist(), valid.tolist(), strict=True)):
        key = tuple(sorted({tuple(r) for r, v in zip(rows, ok, strict=True) if v}))
        edges = hulls.get(key)
        if edges is None:
            edges = hulls[key] = _hull_edges(list(key))
        for a, b in edges:
            starts.append(a)
            ends.append(b)
            owner.append(i)
    a = np.array(starts)
    e = np.array(ends) - a
    norm = np.sqrt(np.vecdot(e, e))  # as np.linalg.norm of one edge (the BLAS dot)
    normal = np.stack([-e[:, 1], e[:, 0]], axis=1) / norm[:, None]
    d = np.vecdot(normal, com[owner] - a)  # as ``normal @ (point - a)`` per edge
    out = np.full(len(points), np.inf)
    np.minimum.at(out, np.array(owner), d)
    return out


def _soles(
    template: Template, names: tuple[str, ...], q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(COM (n, 3), sole centres (feet, n, 3), sole corner offsets (4, 2)) m, with the
    trunk upright and the feet flat (as the gaits keep them)."""
    model = template.model
    Q = _q_full(model.q_names, names, np.atleast_2d(q))
    frames = forward_kinematics(model, Q)
    com = center_of_mass(model, Q)
    feet = [model.body(f) for f in template.feet]
    soles = np.array(
        [
            frames[:, b, :3, 3] + frames[:, b, :3, :3] @ p
            for b, p in zip(feet, template.foot_points, strict=True)
        ]
    )  # (2, n, 3)
    half = template.lengths["foot"] / 2
    width = FOOT_WIDTH_RATIO * half
    corners = np.array([[sx * half, sy * width] for sx in (-1, 1) for sy in (-1, 1)])
    return com, soles, corners


def stability_margin(
    template: Template, names: tuple[str, ...], q: np.ndarray, contact: float = 0.002
) -> np.ndarray:
    """Static stability margin (n,) m: distance of the COM's ground projection inside the
    support polygon (the sole plates of the feet within ``contact`` m of the lowest one),
    with the trunk upright and the feet flat (as the gaits keep them)."""
    com, soles, corners = _soles(template, names, q)
    low = soles[:, :, 2].min(axis=0)
    touching = soles[:, :, 2] <= low + contact  # (feet, n)
    points = soles[:, :, None, :2] + corners  # (feet, n, 4, 2)
    n = len(com)
    points = points.transpose(1, 0, 2, 3).reshape(n, -1, 2)
    valid = np.repeat(touching.T, len(corners), axis=1)
    return _support_margins(points, valid, np.ascontiguousarray(com[:, :2]))


# --- the controller ------------------------------------------------------------------------------


@dataclass(frozen=True)
class GaitPlan:
    """When a mapped gait does what, in s from the start of the oscillation (after the
    ``CROUCH_TIME`` crouch from q = 0).

    The oscillation fades in over ``ramp`` s while stepping in place (the weight shift
    and the foot lift grow; r = 0), starting in mid double support. The step ratio r
    then grows from 0 to its target during one single-support window starting at
    ``up`` (a half step), stays for ``steps`` full steps, and returns to 0 during the
    window starting at ``down`` (a half step: the feet end side by side); r only changes
    while one foot is in the air, so the feet never slide against each other. The
    oscillation then fades out over ``ramp`` s from ``fade``; ``end``: all done.
    """

    swing: float  # s, length of a single-support window
    ramp: float
    up: float
    down: float
    fade: float
    end: float

    @classmethod
    def of(cls, shape: GaitShape, steps: int, leg: float = REFERENCE_LEG) -> GaitPlan:
        """The plan of ``steps`` full steps of ``shape`` for legs of ``leg`` m."""
        T, d = shape.period(leg), shape.double_support
        ramp = 2 * T
        first = d * T / 2  # the first single-support window starts after half a DS
        up = first + T * np.ceil((ramp - first) / T - 1e-9)
        down = up + (steps + 1) * T
        fade = down + (1 - d) * T + d * T / 2
        return cls((1 - d) * T, ramp, float(up), float(down), float(fade), float(fade + ramp))

    def envelope(self, tau: np.ndarray) -> np.ndarray:
        """Oscillation amplitude (n,) in [0, 1] at times ``tau`` s."""
        return _smooth(tau / self.ramp) - _smooth((tau - self.fade) / self.ramp)

    def ratio(self, tau: np.ndarray, target: float) -> np.ndarray:
        """Step ratio (n,) at times ``tau`` s."""
        return target * (
            _smooth((tau - self.up) / self.swing) - _smooth((tau - self.down) / self.swing)
        )


def leg_module_range() -> tuple[float, float]:
    """(shortest, longest) leg module length x m (femur = tibia) whose gaits the conversion
    maps give without extrapolation (``MAP_SIZES``); the design refuses other legs."""
    return MAP_SIZES[0], MAP_SIZES[-1]


def odometry(template: Template, names: tuple[str, ...], q: np.ndarray) -> np.ndarray:
    """(n, 3) m: the trunk's displacement in the world along joint trajectories ``q`` (n,
    len(names)), with the trunk upright and the lower foot (the stance foot) never sliding:
    at each sample the trunk moves by minus the stance ankle's motion in the trunk frame.
    What a gait commands, from its joint angles alone."""
    model = template.model
    frames = forward_kinematics(model, _q_full(model.q_names, names, np.atleast_2d(q)))
    feet = np.array([frames[:, model.body(f), :3, 3] for f in template.feet])  # (2, n, 3)
    stance = np.argmin(feet[:, :, 2], axis=0)  # (n,)
    step = (
        feet[stance[1:], np.arange(1, len(stance))] - feet[stance[1:], np.arange(len(stance) - 1)]
    )
    out = np.zeros((len(stance), 3))
    out[1:] = -np.cumsum(step, axis=0)
    return out


#: m: a foot's share of the weight fades out smoothly as its sole rises this high over the
#: lowest one (a foot lifting off or setting down, or one a hair higher, loads the servos
#: continuously).
CONTACT = 0.002


def stance_torques(
    template: Template, names: tuple[str, ...], q: np.ndarray, dt: float
) -> np.ndarray:
    """(n, len(names)) N m: the joint torques that carry the robot along the joint
    trajectories ``q`` (n, len(names)) rad sampled every ``dt`` s, with ``template``'s
    masses: RNEA with the ground's forces of :func:`stance_loads` and gravity."""
    model = template.model
    Q, fext = stance_loads(template, names, q, dt)
    tau = rnea(model, Q, np.zeros_like(Q), np.zeros_like(Q), fext)
    index = {name: k for k, name in enumerate(model.q_names)}
    return tau[:, [index[name] for name in names]]


def stance_loads(
    template: Template, names: tuple[str, ...], q: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """(model coordinates (n, nq) rad, the ground's wrenches on the feet (n, nbodies, 6) in
    :func:`kinematics.dynamics.rnea`'s ``fext`` form) along the joint trajectories ``q``
    (n, len(names)) rad sampled every ``dt`` s, with ``template``'s masses.

    The trunk stays upright and moves as :func:`odometry` says (the stance foot does not
    slide); the centre of mass (COM) then moves along ``c(t)`` and the ground pushes with
    ``M (c'' + g)`` at the zero-moment point ``c - z c'' / (z'' + g)`` (z: the COM's height
    over the ground). The feet share that force by the lever rule along the line between
    their soles (both pressure points shifted alike, so that the force stays at the
    zero-moment point), a foot's share fading out as it rises ``CONTACT`` m over the lowest
    one. The bodies' own accelerations relative to the trunk are left out (slow gaits)."""
    model = template.model
    Q = _q_full(model.q_names, names, np.atleast_2d(q))
    n = len(Q)
    frames = forward_kinematics(model, Q)
    feet = [model.body(f) for f in template.feet]
    soles = np.array(
        [
            frames[:, b, :3, 3] + frames[:, b, :3, :3] @ p
            for b, p in zip(feet, template.foot_points, strict=True)
        ]
    )  # (2, n, 3), trunk frame
    ground = soles[:, :, 2].min(axis=0)
    trunk = odometry(template, names, q)
    trunk[:, 2] = -ground  # the trunk's height over the ground
    com = trunk + center_of_mass(model, Q)  # world (ground at z = 0)
    acc = np.zeros_like(com)
    if n >= 3:  # the COM's acceleration, m/s^2
        acc = np.gradient(np.gradient(com, dt, axis=0), dt, axis=0)
    force = model.total_mass * (acc + np.array([0.0, 0.0, GRAVITY]))  # (n, 3), world = trunk axes
    zmp = com[:, :2] - com[:, 2:3] * acc[:, :2] / force[:, 2:3] * model.total_mass
    world = soles + trunk[None]  # (2, n, 3)
    down = _smooth(1 - (soles[:, :, 2] - ground[None]) / CONTACT)  # (2, n): 1 on the ground
    a, b = world[0, :, :2], world[1, :, :2]
    ab = b - a
    s = np.einsum("ij,ij->i", zmp - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    s = np.clip(s, 0.0, 1.0)
    lever = np.stack([(1 - s) * down[0], s * down[1]])  # (2, n)
    total = lever.sum(axis=0)
    share = np.where(total > 1e-9, lever / np.maximum(total, 1e-9), down / down.sum(axis=0))
    # both pressure points shifted alike, so that the resultant acts at the ZMP
    offset = zmp - (share[0, :, None] * a + share[1, :, None] * b)
    fext = np.zeros((n, len(model.bodies), 6))
    for k, body in enumerate(feet):
        cop = world[k].copy()
        cop[:, :2] += offset
        fext[:, body] = external_force_at(model, Q, body, cop - trunk, share[k, :, None] * force)
    return Q, fext


#: Grasping: the arms reach forward (shoulder and elbow pitch, rad; negative turns forward)
#: with the grippers open, close both grippers, and hold.
REACH_SHOULDER = -pi / 4
REACH_ELBOW = -pi / 4
GRIPPER_OPEN = pi / 2  # rad: the gripper joint's open end (0: closed)
REACH_TIME = 1.5  # s to raise the arms
#: s to close the grippers. Closed in 0.5 s (5.9 rad/s at the peak) and opened in the
#: crouch alone, an SG90 gripper was at its limit 2 % of every perturbed run
#: (``tests/synth/verification/test_humanoid_grasp.py``).
GRIP_TIME = 1.0
HOLD_TIME = 1.5  # s holding


class HumanoidController(Controller):
    """Behaviours of a designed humanoid, from the synthetic locomotion's conversion maps.

    ``walking`` (steerable: a ``curvature`` rad/m, each hip's yaw the curvature times how
    far its ankle is ahead of the mean pose's) and ``running``: ``steps`` full steps of
    ``step_length`` m (default: a
    fixed fraction of the leg length, ``GaitShape.step``) between a half step that starts
    and one that ends the walk, ``direction`` forward or backward (the pendulum gait is
    time-symmetric: backward is the forward gait played in reverse), with the step period
    scaled with the legs (``GaitShape.period``). ``grasping``: the arms reach forward with
    the grippers open, both grippers close and hold, the pelvis shifted back so that the
    centre of mass stays over the feet. ``balancing`` (the ability a humanoid gains with a
    sensor): standing crouched, shifting the weight from foot to foot. Arms hang still
    (q = 0) but in grasping. Every trajectory starts at q = 0 and ends standing crouched.

    ``info`` follows the shared contract: ``motion`` ("straight" for the gaits, "hold"
    otherwise), ``planned_pose`` (the trunk's displacement the joint angles command, by
    :func:`odometry` of the planned angles; along the arc with its yaw when walking is
    given a ``curvature``, motion "arc", ``curvature_rad_m``, ``path_length_m``),
    ``direction``,
    ``locomotion`` "legged" and ``body_length_m``: the leg length (femur + tibia), the
    humanoid's natural unit of stride (its walking speed scales with it); plus
    ``stability_margin_m`` (COM inside the planned support polygon; the pendulum gait
    leaves it by a few mm while the weight moves between the feet). A leg module outside
    the maps' sizes is refused (ValueError), never extrapolated.

    ``stiffness`` (joint -> N m/rad) and ``damping`` (joint -> N m s/rad, may be left
    out): the servos' ``kp`` and velocity gain; given them, the positions sent are the
    planned angles plus the servos' give (module docstring), and
    ``info["planned_positions"]`` keeps the planned angles.
    """

    PLAN_IGNORES = frozenset({"mass_kg", "joint_torque", "joint_speed"})

    def __init__(
        self,
        geometry: DesignGeometry,
        stiffness: Mapping[str, float] | None = None,
        damping: Mapping[str, float] | None = None,
    ) -> None:
        super().__init__(geometry)
        L = self.template.lengths
        self.femur, self.tibia = float(L["femur"]), float(L["tibia"])
        self.leg = self.femur + self.tibia
        self.size = self.leg / 2  # the maps' x, m
        # the arms when the body plan has them (a biped without arms walks on its legs
        # alone: it has no grasping)
        arms = _joint_names(ARM_JOINTS)
        self.has_arms = set(arms) <= set(self.template.model.q_names)
        self.joints = _joint_names(LEG_JOINTS) + (arms if self.has_arms else ())
        #: the template with the design's payload on the trunk: its masses
        self.masses = build(
            geometry.template,
            TemplateParams(
                lengths=geometry.lengths,
                modules=geometry.modules,
                payload=float(geometry.params.get("payload", 0.0)),
            ),
        )
        self.stiffness = None if stiffness is None else self._per_joint(stiffness, "stiffness")
        #: the arcs' hip yaw over the plan's (the design's ``calibration``, measured)
        self.turn_gain = float(geometry.calibration.get(TURN_GAIN, 1.0))
        self.damping = None if damping is None else self._per_joint(damping, "damping", zero=True)
        #: the walk: a design that feels its tilt (an IMU) walks ``ROBUST_WALK`` with its
        #: balance loop (:mod:`gaits.balance`); one without, the open-loop ``WALK``; the
        #: balance loop runs on every behaviour of a design with an IMU
        self.balanced = has_imu(geometry.sensors)
        # a design whose walk its other sensors steer (program.sensing: line-tracking,
        # obstacle-avoidance, stride by stride) keeps ``WALK``: its loops were tuned on its
        # faster, narrower steps (ROBUST_WALK's slower ones sway the line sensors off the
        # line for 0.65-0.8 s, over the 0.5 s allowed, measured with the balance loop)
        steered = any(s != IMU_CLASS for s in geometry.sensors)
        self.walk = ROBUST_WALK if self.balanced and not steered else WALK

    def _per_joint(self, values: Mapping[str, float], what: str, zero: bool = False) -> np.ndarray:
        """(len(joints),) ``values`` by joint name; ValueError when one is missing or not
        positive (negative with ``zero``)."""
        missing = sorted(set(self.joints) - set(values))
        if missing:
            raise ValueError(f"{what}: no value for {', '.join(missing)}")
        out = np.array([float(values[j]) for j in self.joints])
        if not np.all((out >= 0) if zero else (out > 0)):
            raise ValueError(f"{what} values must be {'>= 0' if zero else '> 0'}")
        return out

    def default_step(self, shape: GaitShape = WALK) -> float:
        """Default step length m of ``shape`` for this design's legs."""
        return shape.step * self.leg

    @property
    def behaviors(self) -> Mapping[str, BehaviorSpec]:
        def gait(shape: GaitShape, doc: str, steered: bool = False) -> BehaviorSpec:
            s0 = self.default_step(shape)
            turn = (
                Parameter(
                    "curvature",
                    "float",
                    0.0,
                    "turn per metre walked forward, counter-clockwise positive (0: straight)",
                    "rad/m",
                    low=-CURVATURE_LIMIT,
                    high=CURVATURE_LIMIT,
                ),
            )
            spec = partial(
                SteerableSpec,
                steer=(("speed", "step_length"), ("turn", "curvature"), ("steps", "steps")),
            )
            return (spec if steered else BehaviorSpec)(
                shape.name,
                doc,
                (
                    Parameter(
                        "steps",
                        "int",
                        DEFAULT_STEPS,
                        "full steps between the starting and the stopping half step",
                        low=1,
                        high=200,
                    ),
                    Parameter(
                        "step_length",
                        "float",
                        round(s0, 4),
                        "advance per full step",
                        unit="m",
                        low=0.0,
                        high=round(MAP_RATIOS[-1] * s0, 4),
                    ),
                    Parameter(
                        "direction",
                        "choice",
                        "forward",
                        "travel direction",
                        choices=("forward", "backward"),
                    ),
                    *(turn if steered else ()),
                ),
                ability=shape.name,
            )

        out = {
            WALK.name: gait(
                self.walk,
                "a slow crouched walk (the paper's synthetic locomotion), straight or on an "
                "arc of `curvature` (the hips' yaw turns each foot as it swings)",
                steered=True,
            ),
            RUN.name: gait(
                RUN,
                "a faster gait: shorter step period and double support, "
                "longer steps (no flight phase)",
            ),
            "grasping": BehaviorSpec(
                "grasping",
                "stand crouched, reach forward with both arms, close both grippers, hold, "
                "bring the arms back",
                (
                    Parameter(
                        "hold",
                        "float",
                        HOLD_TIME,
                        "time holding with the grippers closed",
                        unit="s",
                        low=0.0,
                        high=60.0,
                    ),
                ),
                ability="grasping",
            ),
            "balancing": BehaviorSpec(
                "balancing",
                "stand crouched and shift the weight from foot to foot, feet flat",
                (
                    Parameter("shifts", "int", 2, "left-right weight shifts", low=1, high=100),
                    Parameter(
                        "amount",
                        "float",
                        0.8,
                        "pelvis shift as a fraction of half the hip width",
                        low=0.0,
                        high=1.0,
                    ),
                    Parameter(
                        "period",
                        "float",
                        2.0,
                        "duration of one left-right shift",
                        unit="s",
                        low=0.5,
                        high=20.0,
                    ),
                ),
                ability="balancing",
            ),
        }
        if not self.has_arms:
            del out["grasping"]
        return out

    def _run(self, name: str, params: Mapping[str, object]) -> Trajectory:
        if name == "balancing":
            return self._balancing(
                int(params["shifts"]), float(params["amount"]), float(params["period"])
            )
        if name == "grasping":
            return self._grasping(float(params["hold"]))
        shape = self.walk if name == WALK.name else RUN
        return self._gait(
            shape,
            int(params["steps"]),
            float(params["step_length"]),
            str(params["direction"]),
            float(params.get("curvature") or 0.0),  # type: ignore[arg-type]
        )

    def _gait(
        self, shape: GaitShape, steps: int, step: float, direction: str, curvature: float = 0.0
    ) -> Trajectory:
        lo, hi = leg_module_range()
        if not lo - 1e-12 <= self.size <= hi + 1e-12:
            raise ValueError(
                f"{shape.name}: leg module {self.size * 1000:.1f} mm is outside the conversion "
                f"maps' sizes {lo * 1000:.0f}-{hi * 1000:.0f} mm (not extrapolated)"
            )
        maps = conversion_maps(shape)
        plan = GaitPlan.of(shape, steps, self.leg)
        sign = 1.0 if direction == "forward" else -1.0
        ratio = step / self.default_step(shape)
        period = shape.period(self.leg)
        start = shape.double_support * period / 2  # mid double support

        def legs(t: np.ndarray, ratio: float = ratio) -> np.ndarray:
            tau = t - CROUCH_TIME
            mean, osc = maps.components(self.size, plan.ratio(tau, ratio), start + sign * tau)
            crouch = _smooth(t / CROUCH_TIME)[:, None]  # r = 0 and no oscillation meanwhile
            q = crouch * mean + plan.envelope(tau)[:, None] * osc
            if curvature:
                gain = self.turn_gain if shape.measured_turn else 1.0
                q[:, YAW] = (
                    gain * curvature * (self._ankle_ahead(q) - self._ankle_ahead(crouch * mean))
                )
            return q

        info: dict[str, object] = {
            "motion": "straight",
            "direction": (sign, 0.0),
            "locomotion": "legged",
            "body_length_m": self.leg,
            "steps": steps,
            "step_length_m": step,
            "step_period_s": period,
            "leg_module_m": self.size,
        }
        if curvature:
            tightest = self.max_curvature(legs, CROUCH_TIME + plan.end, curvature)
            if abs(curvature) > tightest:
                raise ValueError(
                    f"curvature: {curvature:g} rad/m is tighter than this design's hips turn "
                    f"its feet at step length {step:.4g} m (the hip yaw's range: at most "
                    f"{tightest:g} rad/m)"
                )
            info.update(motion="arc", curvature_rad_m=curvature)
        return self._trajectory(
            shape.name,
            CROUCH_TIME + plan.end,
            legs,
            info,
            partial(self._held_arms, shape=shape),
            BALANCE_GAINS["gait" if shape in (ROBUST_WALK, RUN) else "steered"],
            # the leg angles' change per relative change of the step length: the balance
            # loop's stride correction (gaits.balance: shorter steps downhill)
            lambda t: (
                (legs(t, ratio * (1 + STRIDE_EPS)) - legs(t, ratio * (1 - STRIDE_EPS)))
                / (2 * STRIDE_EPS)
            ),
            sign,
        )

    def calibration_probes(self) -> list[tuple[str, dict[str, object]]]:
        """When the walking gait's arcs are measured (``GaitShape.measured_turn``): one arc
        of ``DEFAULT_STEPS`` steps at the first of ``PROBE_CURVATURES`` this design's hips
        turn; none otherwise."""
        if not self.walk.measured_turn:
            return []
        for k in PROBE_CURVATURES:
            try:
                self.run(WALK.name, curvature=k)  # plans (or refuses) it
            except ValueError:
                continue
            return [(WALK.name, {"curvature": k})]
        return []

    def calibrate(self, runs) -> dict:
        """``walking_turn_gain``: the hips' yaw on an arc over the plan's, so that the
        robot turns as planned: the gain the probe ran with times the planned change of
        heading over the measured one (the trunk's yaw, first sample to last), within
        ``TURN_GAIN_RANGE``. Empty when no probe ran or it did not turn its way."""
        import math

        gains = []
        for traj, series in runs:
            planned = float(traj.info["planned_pose"][2])  # type: ignore[index]
            yaw = np.unwrap([quat_yaw(q) for q in np.asarray(series["root"])[:, 3:7]])
            turned = float(yaw[-1] - yaw[0])
            if planned == 0 or turned * planned <= 0:
                continue
            gains.append(self.turn_gain * planned / turned)
        if not gains:
            return {}
        lo, hi = TURN_GAIN_RANGE
        gain = min(max(float(np.mean(gains)), lo), hi)
        return {TURN_GAIN: float(f"{gain:.4f}")} if math.isfinite(gain) else {}

    @staticmethod
    def _held_arms(t: np.ndarray, shape: GaitShape) -> np.ndarray:
        """(n, 6) arm angles of a gait: the shoulders' pitch ``shape.arms`` reached with the
        crouch and held, the elbows and grippers at 0."""
        s = shape.arms * _smooth(t / CROUCH_TIME)
        zero = np.zeros_like(t)
        one = np.stack([s, zero, zero], axis=1)
        return np.concatenate([one, one], axis=1)

    def max_curvature(
        self, legs: Callable[[np.ndarray], np.ndarray], duration: float, curvature: float
    ) -> float:
        """The tightest curvature rad/m of the gait whose leg angles at ``curvature`` are
        ``legs(t)``: its hip yaw is the curvature times how far each ankle is ahead of
        (behind) its mean pose's, which the yaw joints' range bounds (floored to 0.01)."""
        t = np.arange(0.0, duration + SETTLE_TIME, SAMPLE_DT)
        reach = float(np.abs(legs(t)[:, YAW]).max()) / abs(curvature)  # m: the ankles' swing
        model = self.template.model
        index = {n: k for k, n in enumerate(model.q_names)}
        yaw = [index[self.joints[k]] for k in YAW]
        room = min(min(float(model.upper[i]), -float(model.lower[i])) for i in yaw)
        return float(np.floor(room / max(reach, 1e-12) * 100) / 100)

    def _ankle_ahead(self, q: np.ndarray) -> np.ndarray:
        """(n, 2) m: how far each ankle (left, right) is ahead of its hip in the leg's
        sagittal plane, from the leg angles ``q`` (n, 12) (hip pitch and knee; the inverse
        of :func:`leg_ik`'s)."""
        hip, knee = q[:, PITCH], q[:, KNEE]
        return -(self.femur * np.sin(hip) + self.tibia * np.sin(hip + knee))

    def _stance(self, dx: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(n, 12) leg angles: both ankles ``dx`` (n,) m ahead of their hips and ``-y`` (n,)
        m beside them (the pelvis moved back and sideways), at the walking gait's stance
        height."""
        hw = self.template.lengths["hip_width"] / 2
        height = stance_height(WALK, self.leg, hw)
        ankle = np.stack([dx, -y, np.full_like(dx, -height)], axis=1)
        one = leg_ik(ankle, self.femur, self.tibia)  # both legs alike, side by side
        return np.concatenate([one, one], axis=1)

    def _balancing(self, shifts: int, amount: float, period: float) -> Trajectory:
        """Crouch (this design's leg IK), sway the pelvis ``shifts`` times left and right
        by ``amount`` times half the hip width under a smooth envelope, stand still."""
        hw = self.template.lengths["hip_width"] / 2
        duration = shifts * period

        def legs(t: np.ndarray) -> np.ndarray:
            tau = np.clip(t - CROUCH_TIME, 0.0, duration)
            y = amount * hw * np.sin(2 * pi * tau / period) * np.sin(pi * tau / duration) ** 2
            # the crouch from q = 0 (y = 0 then)
            return self._stance(np.zeros_like(t), y) * _smooth(t / CROUCH_TIME)[:, None]

        info: dict[str, object] = {"motion": "hold", "body_length_m": self.leg}
        return self._trajectory(
            "balancing", CROUCH_TIME + duration, legs, info, gains=BALANCE_GAINS["stand"]
        )

    @staticmethod
    def _arms(t: np.ndarray, hold: float) -> np.ndarray:
        """(n, 6) arm angles of grasping (``ARM_JOINTS`` per side): the grippers open while
        crouching and reaching (2.5 s: at most 1.2 rad/s) as the arms reach forward, the
        grippers close (``GRIP_TIME``: at most 2.9 rad/s, what an SG90 still gives at the
        battery's cut-off) and stay closed, the arms come
        back down after the hold."""
        back = CROUCH_TIME + REACH_TIME + GRIP_TIME + hold
        reach = _smooth((t - CROUCH_TIME) / REACH_TIME) - _smooth((t - back) / REACH_TIME)
        close = CROUCH_TIME + REACH_TIME  # the grippers open while crouching and reaching
        opened = _smooth(t / close) - _smooth((t - close) / GRIP_TIME)
        one = np.stack([REACH_SHOULDER * reach, REACH_ELBOW * reach, GRIPPER_OPEN * opened], 1)
        return np.concatenate([one, one], axis=1)

    def _grasping(self, hold: float) -> Trajectory:
        """Crouch with the grippers opening, reach forward with both arms while the pelvis
        moves back so that the centre of mass stays over the ankles (this design's
        geometry with the template's masses and the design's payload on the trunk), close
        both grippers, hold ``hold`` s, bring the arms back down holding (the trunk back
        over its start: a hold stays put)."""
        arms = partial(self._arms, hold=hold)
        duration = CROUCH_TIME + REACH_TIME + GRIP_TIME + hold + REACH_TIME
        model = self.masses.model
        index = {n: k for k, n in enumerate(model.q_names)}
        cols = [index[n] for n in self.joints]

        def legs(t: np.ndarray) -> np.ndarray:
            crouch = _smooth(t / CROUCH_TIME)[:, None]
            dx = np.zeros_like(t)
            Q = np.zeros((len(t), model.nq))
            Q[:, cols[12:]] = arms(t)
            for _ in range(4):  # the legs' pose moves the COM a little too: iterate
                q = self._stance(dx, np.zeros_like(t)) * crouch
                Q[:, cols[:12]] = q
                com = center_of_mass(model, Q)
                ankle = forward_kinematics(model, Q)[:, model.body(self.template.feet[0]), 0, 3]
                dx = dx + (com[:, 0] - ankle)
            return q

        info: dict[str, object] = {"motion": "hold", "body_length_m": self.leg}
        return self._trajectory("grasping", duration, legs, info, arms, BALANCE_GAINS["stand"])

    def _trajectory(
        self,
        name: str,
        duration: float,
        legs: Callable[[np.ndarray], np.ndarray],
        info: dict[str, object],
        arms: Callable[[np.ndarray], np.ndarray] | None = None,
        gains: Mapping[str, float] | None = None,
        stride: Callable[[np.ndarray], np.ndarray] | None = None,
        travel: float = 0.0,
    ) -> Trajectory:
        """The trajectory of leg angles ``legs(t)`` (n, 12) rad and arm angles ``arms(t)``
        (n, 6) rad (default: hanging, 0) over ``duration`` s and ``SETTLE_TIME`` s more,
        velocities by central differences, its stability margin and its ``planned_pose``
        (:func:`odometry`); ValueError if it leaves a joint's limits."""
        t = np.arange(0.0, duration + SETTLE_TIME, SAMPLE_DT)
        h = 1e-6  # s
        q = np.zeros((len(t), len(self.joints)))
        v = np.zeros_like(q)
        q[:, :12] = legs(t)
        v[:, :12] = (legs(t + h) - legs(t - h)) / (2 * h)
        if arms is not None and self.has_arms:
            q[:, 12:] = arms(t)
            v[:, 12:] = (arms(t + h) - arms(t - h)) / (2 * h)
        model = self.template.model
        index = {n: k for k, n in enumerate(model.q_names)}
        low, high = model.lower, model.upper
        for k, joint in enumerate(self.joints):
            i = index[joint]
            if q[:, k].min() < low[i] - 1e-9 or q[:, k].max() > high[i] + 1e-9:
                raise ValueError(
                    f"{name}: joint {joint} would leave its limits [{low[i]:.3f}, "
                    f"{high[i]:.3f}] rad (reaching [{q[:, k].min():.3f}, "
                    f"{q[:, k].max():.3f}]); leg module {self.size:.3f} m"
                )
        info["stability_margin_m"] = stability_margin(self.template, self.joints, q)
        kappa = float(info.get("curvature_rad_m", 0.0))  # type: ignore[arg-type]
        flat = q.copy()
        flat[:, YAW] = 0.0  # the hips' yaw turns the trunk, the rest of the gait moves it
        odo = odometry(self.template, self.joints, flat)
        moved = odo[-1]
        if kappa:  # along an arc: the hips' yaw turns kappa per metre walked
            # the crouch moves the trunk over the feet (the arms held back: forward) before
            # any step: that shift is not walked, and it ends turned with the trunk
            shift = float(odo[int(round(CROUCH_TIME / SAMPLE_DT)), 0])
            path = float(moved[0]) - shift
            turn = kappa * path
            info["planned_pose"] = (
                float(np.sin(turn) / kappa + shift * np.cos(turn)),
                float((1 - np.cos(turn)) / kappa + shift * np.sin(turn)),
                turn,
            )
            info["path_length_m"] = abs(path)
        else:
            info["planned_pose"] = (float(moved[0]), float(moved[1]), 0.0)
        if info.get("motion") == "straight":
            info["expected_distance_m"] = float(np.hypot(moved[0], moved[1]))
        if self.balanced:  # balance on the trunk's IMU (gaits.balance)
            info["feedback"] = balance_spec(
                self.template.model, self.template.feet, self.joints, q, **(gains or {})
            )
            if stride is not None and travel:
                per = np.zeros_like(q)
                per[:, :12] = stride(t)
                info["feedback"].update(stride=per, travel=travel)  # type: ignore[union-attr]
        positions = q
        if self.stiffness is not None:  # the servos' give under the stance loads
            tau = stance_torques(self.masses, self.joints, q, SAMPLE_DT)
            if self.damping is not None:  # what the servo's velocity gain holds back
                tau = tau + self.damping * v
            droop = tau / self.stiffness
            lo = np.array([low[index[j]] for j in self.joints])
            hi = np.array([high[index[j]] for j in self.joints])
            positions = np.clip(q + droop, lo, hi)
            v = v + np.gradient(positions - q, SAMPLE_DT, axis=0)
            info["planned_positions"] = q
        return Trajectory(name, t, self.joints, positions, v, info)
