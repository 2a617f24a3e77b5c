"""Multiped gait generation (paper section 4.3.4, for the hexapod and, built the same way,
the quadruped): leg kinematics, gait patterns, foot trajectories and the static stability
margin. The behaviours that use them are ``gaits.legged.LeggedController``'s.

**Legs.** A leg of a multiped's template (legs on a trunk) is read off the
template's joints (:func:`legs_of`): the coxa (yaw about the trunk's z) at the mount
``m`` with mount yaw ``psi_m`` (the leg points outward), the femur (pitch) ``c`` further
out, the tibia (pitch) ``f`` beyond it, and the foot ``t`` below the tibia joint at q = 0.
With ``psi = psi_m + q_coxa``, ``s = q_femur + q_tibia`` and pitch turning a +x link down,
the foot in the trunk frame is (:func:`leg_fk`)::

    r = c + f cos(q_femur) - t sin(s)            (m, radial distance from the coxa axis)
    p = m + (r cos(psi), r sin(psi), -f sin(q_femur) - t cos(s))

and the closed-form inverse (:func:`leg_ik`), with ``rho = |p_xy - m_xy| - c``,
``z = p_z - m_z`` and ``D^2 = rho^2 + z^2``::

    q_coxa  = atan2(p_y - m_y, p_x - m_x) - psi_m
    q_tibia = asin((f^2 + t^2 - D^2) / (2 f t))          (the knee-up branch, |q| <= pi/2)
    q_femur = atan2(-z, rho) - atan2(t cos(q_tibia), f - t sin(q_tibia))

Any other leg (issue 31: 2 to 5 revolute joints, whatever their axes and the tubes
between them, as its part kind builds it) is a **chain leg**: its joints from the trunk to
the foot point as a :class:`gaits.arm_ik.SerialChain`, placed by numerical IK on that chain
(:func:`_chain_ik`: damped least squares on every point of a path at once, from the leg's
pose as built, inside the limits; ``solve_ik`` for a point left short). Its reach, stride,
step height and the tilt of its last tube are read from the chain (:func:`leg_tilt`; the
coxa swing bounds a first joint about the vertical); a chain that moves its foot in fewer
than three directions (a yaw and a pitch joint) is refused, naming why: a standing foot
must stay put while the trunk moves over it. The coxa-femur-tibia leg keeps its closed
form (the shipped legs plan exactly as before).

**Gaits** (:func:`gait_pattern`) are phase offsets on the legs ranked in the direction of
travel (left/right of it, rear to front; in a turn, the rear and front halves, each along
its own travel): ``tripod`` (hexapod: two alternating tripods, duty 1/2), ``ripple`` (each
side a back-to-front wave, the other side half a cycle later, duty 1 - 1/rows = 2/3),
``wave`` (one leg at a time, duty 1 - 1/legs = 5/6) and, for the quadruped, ``crawl`` (one
leg at a time, hind then front leg of a side, the other side half a cycle later, duty
``CRAWL_DUTY`` = 5/6 >= 3/4, so that a four-foot phase separates the sides and the trunk
can sway across). Other counts (a pentapod, a heptapod, an octopod...) have gaits named by
the feet they keep standing, spread around the trunk (:func:`_spread_phases`): the
``tripod`` (3), the ``tetrapod`` (4) and, for an odd count, the ``ripple`` (all but two),
besides the wave (and an even count's side-wave ripple): one leg lifts every ``1/n`` of a
cycle, each a fixed number of legs around the trunk from the one before, so that the
standing feet always surround the trunk's centre (duty ``k/n`` for ``k`` standing; two
groups of alternate legs, duty 1/2, when ``k`` is half the legs).

**Feet** (:func:`plan_gait`) stand on world footholds in stance, so each moves backward in
a straight line at the body's speed relative to the trunk; in swing a foot lifts (a
minimum-jerk rise over ``LIFT_FRACTION`` of the swing to ``step_height``, a plateau, and
the mirrored descent) while it moves to the next foothold along a minimum-jerk straight
line that starts and ends ``SWING_EDGE`` of the swing later/earlier, so it is above the
obstacle for most of its way. With an **approach** angle a (``plan_gait(approach=a)``:
the turns of ``gaits.legged``) the straight line stops short of the foothold by a x the
foot's distance from its coxa axis and the foot covers that last bit in a second, slow
minimum-jerk move (the last ``APPROACH_SHARE`` of the swing's horizontal motion, before
the descent). Why: the play of a geared hip servo (``synth/verification/perturb.toml``) is free
about the vertical coxa axis (gravity does not take it up); a single move ends decelerating,
the leg's inertia carries it across the play, and each landing locks in the offset the
play then has: in MuJoCo a quadruped's turn in place drifted 10-14 % past its angle on
every perturbed run, 3-4 % with the slow approach (the hexapod's 5-8 % past it).

Each foothold is the mean of the leg's neutral point (its foot at q = 0) at the
beginning and end of the stance it carries, so a stance sweeps the stride symmetrically
about the neutral point, pulled towards the leg's mount on straight travel by half the
outward bulge of that sweep (:func:`stance_inset`: a sweep across the leg takes the foot
farther from the coxa axis at its ends), so that the stance tibia tilts as far inward as
outward and its servo carries the leg's load at the smallest lever; the robot starts
standing at q = 0 and ends with every foot on its neutral point. The body's speed ramps
up and down with minimum-jerk envelopes just long enough that the first and last stances
stay within half a stride of neutral. A stance higher than the zero pose starts with a
``TRANSITION_S`` minimum-jerk rise from q = 0 with the feet in place.

**Stride** (:func:`max_stride`): the longest stance segment about each neutral point
that keeps the coxa within ``COXA_SWING`` (the designer's working swing), the tibia within
``TIBIA_TILT`` of vertical (the tibia servo holds the leg's load at that lever), every
joint ``JOINT_MARGIN`` inside its limits with the foot down and lifted, and neighbouring
legs' segments ``LEG_CLEARANCE`` apart.

**Static stability margin** (:func:`support_margin`, :func:`stability_margins`): the
signed distance m of the centre of mass's ground projection to the nearest edge of the
convex hull of the stance feet (negative outside), with the centre of mass from
``kinematics.dynamics.center_of_mass`` of the template (its masses) and the feet from
``forward_kinematics``, at every sample. When a gait's margin would fall below
``MIN_MARGIN`` (the quadruped's crawl, whose support triangles' diagonals pass through the
centre), the trunk sways: a clamped cubic B-spline offset of the trunk in the horizontal
plane that a linear programme (scipy HiGHS) chooses to maximise the smallest margin of both
the centre of mass and the cart-table zero-moment point (``COM - z_c / g * acceleration``),
within ``SWAY_MAX`` and ``SWAY_ACCEL``; a second programme then minimises the sway's
acceleration plus ``SWAY_RADIAL_WEIGHT`` times its share along the legs (a sway along a leg
moves its stance foot radially, tilting the tibia) at 95 % of that margin, or at
``SWAY_TARGET_MARGIN`` when that is less: the gait needs ``MIN_MARGIN``, not the most sway.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaits.arm_ik import DAMPING, MAX_STEP, SerialChain, chain_rank, solve_ik
from gaits.base import cache_folder, cache_write
from kinematics.dynamics import center_of_mass, forward_kinematics
from kinematics.templates import Template

__all__ = [
    "GAITS",
    "GaitPattern",
    "GaitPlan",
    "GaitTiming",
    "Leg",
    "gait_pattern",
    "gait_timing",
    "leg_fk",
    "leg_ik",
    "legs_key",
    "legs_of",
    "limit_slack",
    "max_stride",
    "model_key",
    "pattern_key",
    "plan_gait",
    "stability_margins",
    "stance_inset",
    "standing_height",
    "support_margin",
    "tibia_tilt",
]

#: Trajectory sample period, s.
SAMPLE_DT = 0.01
#: Clearance between neighbouring legs' stance segments, m (as the designer's).
LEG_CLEARANCE = 0.02
#: Coxa swing used by a stride, rad (the designer's, inside the template's +-pi/3).
COXA_SWING = math.pi / 4
#: Largest tibia tilt from vertical in stance, rad: the tibia servo carries the leg's load
#: at a lever of tibia x sin(tilt).
TIBIA_TILT = 0.3
#: Share of the outward bulge of a stance sweep taken back by pulling the footholds in
#: (:func:`stance_inset`; 1: the tibia tilts as far out as in).
TIBIA_CENTRING = 1.0
#: Distance kept from every joint limit, rad.
JOINT_MARGIN = 0.05
#: Smallest static stability margin a plan must keep, m.
MIN_MARGIN = 0.01
#: Trunk sway limits: offset per axis m, acceleration per axis m/s^2.
SWAY_MAX = 0.03
SWAY_ACCEL = 0.5
#: The sway keeps the best margin it can reach, but no more than this (m): a larger sway
#: tilts the tibias of the stance legs (see below) for a margin the gait does not need.
#: Why 25 mm (and a 30 mm sway): a crawl's third foot carries the share of the weight
#: that the margin gives it over the diagonal of the other two, and under the
#: perturbations of ``parmor design --robustness`` (a 2-3 deg slope, the servos' play)
#: the shipped quadruped's lightest foot, at a planned 13 mm (15 mm and a 20 mm sway),
#: held 1.4 N of 21 N and lost contact for 20-30 ms in 3-4 of 8 runs of each of its
#: walking, running and turning (the measured margin then -11 to -15 mm against the
#: remaining two feet); at 17-19 mm planned (this target, this sway) it passed 24 of 24.
SWAY_TARGET_MARGIN = 0.025
#: Weight of the sway's radial share (its component along the legs, which tilts the stance
#: tibias: their servos carry the leg's load at that lever) against its smoothness.
SWAY_RADIAL_WEIGHT = 0.2
#: Standing still before the first and after the last swing when the trunk sways, cycles.
SWAY_LEAD = 0.25
#: Duration of the rise from q = 0 to a higher stance, s.
TRANSITION_S = 1.0
#: Swing profile: share of the swing spent rising (and descending); share at each end of
#: the swing before the foot starts (after it stops) moving horizontally.
LIFT_FRACTION = 0.4
SWING_EDGE = 0.15
#: Share of a swing's phase given to the slow final approach of a foot to its foothold
#: (``plan_gait``'s ``approach``), taken from the straight line's, before the descent.
APPROACH_SHARE = 0.15
#: Duty factor of the quadruped's crawl (one leg at a time needs >= 3/4), and the shortest
#: one a crawl may be given (a four-foot phase of 2 x duty - 3/2 cycles must remain between
#: the sides for the trunk to sway across).
CRAWL_DUTY = 5 / 6
MIN_CRAWL_DUTY = 0.8
#: The sway's B-spline knot spans, and the samples its linear programmes constrain, per
#: gait cycle (the plan then checks every sample).
SWAY_KNOTS = 12
LP_SAMPLES = 60


# --- leg kinematics ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Leg:
    """One 3-DOF leg read off a template (lengths m, angles rad, trunk frame).

    ``joints``: (coxa, femur, tibia) joint names; ``mount`` (3,): the coxa joint's origin;
    ``yaw``: the direction the leg points at q = 0; ``lower``/``upper`` (3,): joint limits;
    ``foot_body``: the tibia body holding the foot point (0, 0, -tibia).
    """

    name: str
    joints: tuple[str, str, str]
    mount: np.ndarray
    yaw: float
    coxa: float
    femur: float
    tibia: float
    lower: np.ndarray
    upper: np.ndarray
    foot_body: str
    #: any other leg (2 to 5 revolute joints, axes and tubes as its part kind has them):
    #: its chain from the trunk to the foot point, placed by numerical IK
    #: (:func:`gaits.arm_ik.solve_ik`); None: the coxa-femur-tibia leg of the closed form
    chain: SerialChain | None = field(default=None, repr=False)

    @property
    def neutral(self) -> np.ndarray:
        """(3,) the foot at q = 0, trunk frame, m."""
        return leg_fk(self, np.zeros(len(self.joints)))

    @property
    def foot_offset(self) -> np.ndarray:
        """(3,) the foot point in the foot body's frame, m."""
        if self.chain is None:
            return np.array([0.0, 0.0, -self.tibia])
        return np.array(self.chain.steps[-1][0][:3, 3], dtype=float)

    @property
    def extent(self) -> float:
        """The sum of the leg's lengths, m (a bound of its reach)."""
        return self.coxa + self.femur + self.tibia


def legs_of(template: Template) -> tuple[Leg, ...]:
    """The legs of a multiped template, in the template's foot order.

    ValueError when a foot does not hang on a coxa (z) - femur (y) - tibia (y) chain of the
    template's layout (coxa and femur tubes along the joint frame's x, tibia along -z).
    """
    m = template.model
    if not template.feet or len(template.feet) < 3:
        raise ValueError(f"{template.robot_type} is not a legged robot (feet: {template.feet})")
    legs = []
    for foot, point in zip(template.feet, template.foot_points, strict=True):
        b_tibia = m.body(foot)
        j_tibia = m.joints[b_tibia]
        j_femur = m.joints[j_tibia.parent]
        j_coxa = m.joints[j_femur.parent]
        chain = (j_coxa, j_femur, j_tibia)
        ok = (
            j_coxa.parent >= 0
            and all(j.kind == "revolute" for j in chain)
            and not m.joints[j_coxa.parent].movable
            and np.allclose(j_coxa.axis, (0, 0, 1))
            and np.allclose(j_femur.axis, (0, 1, 0))
            and np.allclose(j_tibia.axis, (0, 1, 0))
            and np.allclose(j_coxa.origin[2, :3], (0, 0, 1))
            and np.allclose(j_femur.origin[:3, :3], np.eye(3))
            and np.allclose(j_tibia.origin[:3, :3], np.eye(3))
            and np.allclose(j_femur.origin[1:3, 3], 0)
            and np.allclose(j_tibia.origin[1:3, 3], 0)
            and np.allclose(point[:2], 0)
            and point[2] < 0
        )
        if not ok:  # any other leg: its own chain
            legs.append(_chain_leg(template, foot, np.asarray(point, dtype=float)))
            continue
        R = j_coxa.origin[:3, :3]
        legs.append(
            Leg(
                name=j_coxa.name.removesuffix("_coxa"),
                joints=(j_coxa.name, j_femur.name, j_tibia.name),
                mount=np.array(j_coxa.origin[:3, 3], dtype=float),
                yaw=math.atan2(R[1, 0], R[0, 0]),
                coxa=float(j_femur.origin[0, 3]),
                femur=float(j_tibia.origin[0, 3]),
                tibia=float(-point[2]),
                lower=np.array([j.lower for j in chain]),
                upper=np.array([j.upper for j in chain]),
                foot_body=foot,
            )
        )
    return tuple(legs)


#: Revolute joints a leg of any other shape may have (the first one on the trunk).
CHAIN_JOINTS = (2, 5)


def _chain_leg(template: Template, foot: str, point: np.ndarray) -> Leg:
    """A leg that is not the closed form's coxa-femur-tibia: the revolute joints from the
    trunk to the foot point ``point`` (foot body frame), read off the template (their
    axes, origins and limits as the part kind built them). ValueError naming why when the
    chain cannot walk: a joint that is not revolute, fewer than 2 or more than 5 joints,
    a foot it cannot place in three dimensions (the trunk moves over a standing foot)."""
    m = template.model
    path = []
    b = m.body(foot)
    while b >= 0:
        path.append(b)
        b = m.joints[b].parent
    path.reverse()
    steps, names, lo, hi = [], [], [], []
    for b in path:
        j = m.joints[b]
        i = -1
        if j.movable:
            if j.kind != "revolute":
                raise ValueError(
                    f"leg of {foot!r}: joint {j.name!r} is {j.kind}; a leg walks on revolute joints"
                )
            i = len(names)
            names.append(j.name)
            lo.append(j.lower)
            hi.append(j.upper)
        steps.append((np.array(j.origin), np.array(j.axis) if i >= 0 else None, i))
    steps.append((_translation(point), None, -1))
    n = len(names)
    if not CHAIN_JOINTS[0] <= n <= CHAIN_JOINTS[1]:
        raise ValueError(
            f"leg of {foot!r} has {n} revolute joints; parmor walks legs of "
            f"{CHAIN_JOINTS[0]} to {CHAIN_JOINTS[1]}"
        )
    qn = m.q_names
    chain = SerialChain(
        tuple(names),
        tuple(qn.index(x) for x in names),
        np.array(lo),
        np.array(hi),
        foot,
        foot,
        np.array([0.0, 0.0, -1.0]),
        point.copy(),
        tuple(steps),
    )
    rank = chain_rank(chain, position_only=True)
    if rank < 3:
        raise ValueError(
            f"leg of {foot!r}: its {n} joints ({', '.join(names)}) move the foot in {rank} "
            "directions only; a standing foot must stay put while the trunk moves over it "
            "(forward, sideways and at a height), which takes joints that move it in 3 "
            "(for instance a yaw joint and two pitch joints)"
        )
    first = m.joints[path[1]]  # the first joint after the trunk
    if m.joints[first.parent].movable:
        raise ValueError(f"leg of {foot!r} is not mounted on the trunk")
    mount = np.array(first.origin[:3, 3], dtype=float)
    q0 = np.zeros(n)
    p0, _, _, origins = chain.frames(q0)
    d = p0 - mount
    last = origins[-1]
    return Leg(
        name=_leg_prefix(first.name, names),
        joints=tuple(names),
        mount=mount,
        yaw=math.atan2(d[1], d[0]),
        coxa=0.0,
        femur=float(np.hypot(*(last - mount)[:2]) + np.linalg.norm(p0 - last)),
        tibia=float(max(0.0, -d[2])),
        lower=np.array(lo),
        upper=np.array(hi),
        foot_body=foot,
        chain=chain,
    )


def _translation(point: np.ndarray) -> np.ndarray:
    """The (4, 4) transform that moves by ``point`` (3,)."""
    out = np.eye(4)
    out[:3, 3] = point
    return out


def _leg_prefix(first: str, names: Sequence[str]) -> str:
    """The leg's name: what its joints' names share before an underscore (``lf`` of
    ``lf_hip``, ``lf_knee``), else the first joint's name."""
    common = os.path.commonprefix(list(names))
    cut = common.rfind("_")
    return common[:cut] if cut > 0 else first


def _chain_ik(leg: Leg, p: np.ndarray, exact: bool = True) -> np.ndarray:
    """Joint angles (..., n) of a chain leg for foot points ``p`` (..., 3) (trunk frame):
    damped least squares on every point at once from the leg's pose as built
    (:func:`_chain_start`; the minimal steps of a redundant leg keep its posture near
    that one, and smooth along a path), inside the limits; a point it leaves short is
    solved by :func:`gaits.arm_ik.solve_ik` from there. ValueError when a point is out of
    reach. ``exact`` False: a point left short is out of reach (no second try: the
    stride search's probes, most of them out of reach)."""
    chain = leg.chain
    p = np.asarray(p, dtype=float)
    flat = p.reshape(-1, 3)
    q = np.tile(_chain_start(leg), (len(flat), 1))
    lo, hi = leg.lower, leg.upper
    eye = np.eye(3) * DAMPING**2
    for _ in range(CHAIN_IK_ITERATIONS):
        end, axes, origins = _chain_frames(chain, q)
        e = flat - end
        if not len(e) or float(np.max(np.abs(e))) < CHAIN_IK_TOL:
            break
        J = np.cross(axes, (end[:, None, :] - origins))  # (N, n, 3): J^T
        JJt = np.einsum("nki,nkj->nij", J, J) + eye
        dq = np.einsum("nki,ni->nk", J, np.linalg.solve(JJt, e[..., None])[..., 0])
        big = np.max(np.abs(dq), axis=1, keepdims=True)
        dq = dq * np.minimum(1.0, MAX_STEP / np.maximum(big, 1e-300))
        q = np.clip(q + dq, lo, hi)
    end, _, _ = _chain_frames(chain, q)
    short = np.flatnonzero(np.linalg.norm(flat - end, axis=1) > CHAIN_IK_ACCEPT)
    if len(short) and not exact:
        raise ValueError(f"leg {leg.name}: foot target out of reach")
    for i in short:
        try:
            q[i] = solve_ik(chain, flat[i], q0=q[i], tol=1e-9, refine=0, restarts=4)
        except ValueError as e:
            raise ValueError(f"leg {leg.name}: foot target out of reach ({e})") from None
    return q.reshape(*p.shape[:-1], chain.n)


#: The chain legs' batched IK: iterations, the error m at which all points stop, the
#: error m above which a point is solved again by ``solve_ik``.
CHAIN_IK_ITERATIONS = 60
CHAIN_IK_TOL = 1e-10
CHAIN_IK_ACCEPT = 1e-7


def _chain_frames(chain: SerialChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`SerialChain.frames` of many configurations ``q`` (N, n) at once: (end
    points (N, 3), joint axes (N, n, 3), joint origins (N, n, 3)), root frame."""
    N = len(q)
    R = np.tile(np.eye(3), (N, 1, 1))
    p = np.zeros((N, 3))
    axes = np.zeros((N, chain.n, 3))
    origins = np.zeros((N, chain.n, 3))
    for k, (origin, axis, i) in enumerate(chain.steps):
        p = p + R @ origin[:3, 3]
        R = R @ origin[:3, :3]
        if k == len(chain.steps) - 1:
            break
        if i >= 0:
            a = R @ axis
            axes[:, i] = a
            origins[:, i] = p
            R = R @ _rotations(axis, q[:, i])
    return p, axes, origins


def _rotations(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) by the angles (N,) rad about the unit ``axis`` (Rodrigues)."""
    x, y, z = (float(v) for v in axis)
    c, s = np.cos(angle), np.sin(angle)
    C = 1.0 - c
    return np.stack(
        [
            np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
            np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
            np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1),
        ],
        -2,
    )


def _chain_start(leg: Leg) -> np.ndarray:
    """The pose the IK of a chain leg starts from: its joints at 0 (the leg as built: the
    tubes reaching out and hanging down), inside the limits."""
    return np.clip(np.zeros(leg.chain.n), leg.lower, leg.upper)


def _chain_fk(leg: Leg, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    flat = q.reshape(-1, leg.chain.n)
    return _chain_frames(leg.chain, flat)[0].reshape(*q.shape[:-1], 3)


def leg_tilt(leg: Leg, q: np.ndarray) -> np.ndarray:
    """Tilt (...,) rad from vertical of the leg's last tube (the tibia of the closed form:
    :func:`tibia_tilt`) at the leg angles (..., n)."""
    if leg.chain is None:
        return tibia_tilt(q)
    q = np.asarray(q, dtype=float)
    flat = q.reshape(-1, leg.chain.n)
    end, _, origins = _chain_frames(leg.chain, flat)
    d = end - origins[:, -1]
    out = np.arctan2(np.hypot(d[:, 0], d[:, 1]), -d[:, 2])
    return out.reshape(q.shape[:-1])


def _yaw_first(leg: Leg) -> bool:
    """Whether the leg's first joint turns about the trunk's vertical (a coxa): the gait
    bounds its swing (``coxa_swing``)."""
    if leg.chain is None:
        return True
    R = np.eye(3)
    for origin, axis, i in leg.chain.steps:
        R = R @ origin[:3, :3]
        if i >= 0:
            return bool(abs(abs((R @ axis)[2]) - 1.0) < 1e-9)
    return False


def leg_fk(leg: Leg, q: np.ndarray) -> np.ndarray:
    """Foot positions (..., 3) m in the trunk frame of joint angles (..., 3) rad."""
    if leg.chain is not None:
        return _chain_fk(leg, q)
    q = np.asarray(q, dtype=float)
    psi = leg.yaw + q[..., 0]
    s = q[..., 1] + q[..., 2]
    r = leg.coxa + leg.femur * np.cos(q[..., 1]) - leg.tibia * np.sin(s)
    z = -leg.femur * np.sin(q[..., 1]) - leg.tibia * np.cos(s)
    return np.stack(
        [leg.mount[0] + r * np.cos(psi), leg.mount[1] + r * np.sin(psi), leg.mount[2] + z],
        axis=-1,
    )


def leg_ik(leg: Leg, p: np.ndarray) -> np.ndarray:
    """Joint angles (..., 3) rad (coxa, femur, tibia) that put the foot at ``p`` (..., 3) m
    (trunk frame), outward of the coxa axis, knee-up branch (|q_tibia| <= pi/2); ValueError
    when a point is out of the leg's reach.
    Joint limits are not checked (see :func:`limit_slack`). A chain leg
    (``leg.chain``): numerical IK inside the limits, point after point."""
    if leg.chain is not None:
        return _chain_ik(leg, p)
    q, k = _ik(leg.mount, leg.yaw, leg.coxa, leg.femur, leg.tibia, p)
    if np.any(np.abs(k) > 1 + 1e-12):
        worst = float(np.max(np.abs(k)))
        raise ValueError(f"leg {leg.name}: foot target out of reach (|sin q_tibia| = {worst:.3f})")
    return q


def _ik(
    mount: np.ndarray,
    yaw: float | np.ndarray,
    coxa: float | np.ndarray,
    femur: float | np.ndarray,
    tibia: float | np.ndarray,
    p: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`leg_ik`'s arithmetic without the reach check, for leg figures that are
    numbers or arrays broadcasting against ``p`` (..., 3) (``mount`` against ``p``, the
    others against ``p[..., 0]``; many legs at once): (joint angles (..., 3) rad,
    sin q_tibia (...,), out of reach where its magnitude exceeds 1)."""
    p = np.asarray(p, dtype=float)
    d = p - mount
    psi = np.arctan2(d[..., 1], d[..., 0])
    q_coxa = (psi - yaw + math.pi) % (2 * math.pi) - math.pi
    rho = np.hypot(d[..., 0], d[..., 1]) - coxa
    z = d[..., 2]
    f, t = femur, tibia
    k = (f * f + t * t - rho * rho - z * z) / (2 * f * t)
    q_tibia = np.arcsin(np.clip(k, -1.0, 1.0))
    q_femur = np.arctan2(-z, rho) - np.arctan2(t * np.cos(q_tibia), f - t * np.sin(q_tibia))
    q_femur = (q_femur + math.pi) % (2 * math.pi) - math.pi
    return np.stack([q_coxa, q_femur, q_tibia], axis=-1), k


def limit_slack(leg: Leg, q: np.ndarray) -> np.ndarray:
    """Smallest distance (...,) rad of the joint angles (..., 3) to the leg's limits
    (negative: outside)."""
    q = np.asarray(q, dtype=float)
    return np.minimum(q - leg.lower, leg.upper - q).min(axis=-1)


def tibia_tilt(q: np.ndarray) -> np.ndarray:
    """Tilt (...,) rad of the tibia from vertical for leg angles (..., 3)."""
    q = np.asarray(q, dtype=float)
    return np.abs(q[..., 1] + q[..., 2])


# --- support polygon -----------------------------------------------------------------------------


def _hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (k, 2) of points (n, 2) (monotone chain)."""
    pts = sorted(map(tuple, np.asarray(points, dtype=float)))
    if len(pts) <= 2:
        return np.array(pts)

    def half(seq: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 1e-15:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _edges(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inward unit normals (k, 2) and offsets (k,) of the hull of ``points``: a point x is
    inside when ``normals @ x - offsets >= 0`` for every edge."""
    h = _hull(points)
    if len(h) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    e = np.roll(h, -1, axis=0) - h
    n = np.stack([-e[:, 1], e[:, 0]], axis=1) / np.linalg.norm(e, axis=1)[:, None]
    return n, np.einsum("ij,ij->i", n, h)


def support_margin(feet: np.ndarray, com: np.ndarray) -> float:
    """Static stability margin m of a centre of mass ``com`` (2,) over stance feet (n, 2):
    inside their convex hull, the distance to its nearest edge; outside, negative (the
    signed distance to the line of the most violated edge); for fewer than three feet, or
    feet in a line, minus the distance to them."""
    feet = np.asarray(feet, dtype=float)[:, :2]
    c = np.asarray(com, dtype=float)[:2]
    n, b = _edges(feet)
    if len(b):
        return float(np.min(n @ c - b))
    if len(feet) == 0:
        return -math.inf
    h = _hull(feet)
    if len(h) == 1 or float(np.ptp(h, axis=0).max()) == 0.0:  # one point (maybe repeated)
        return -float(np.linalg.norm(c - h[0]))
    a, e = h[0], h[-1] - h[0]
    u = np.clip((c - a) @ e / (e @ e), 0.0, 1.0)
    return -float(np.linalg.norm(c - a - u * e))


def stability_margins(
    template: Template, legs: Sequence[Leg], q: np.ndarray, stance: np.ndarray
) -> np.ndarray:
    """Static stability margins (N,) m along joint trajectories ``q`` (N, nv) (template
    order) with the stance feet ``stance`` (N, legs) bool: centre of mass by
    ``center_of_mass`` and feet by ``forward_kinematics`` of the template, both in the
    trunk frame (the trunk stays level, so this is the ground projection)."""
    model = template.model
    q = np.atleast_2d(q)
    com = center_of_mass(model, q)
    T = forward_kinematics(model, q)
    feet = np.stack(
        [
            T[:, model.body(leg.foot_body), :3, :3] @ leg.foot_offset
            + T[:, model.body(leg.foot_body), :3, 3]
            for leg in legs
        ],
        axis=1,
    )
    out = np.empty(len(q))
    stance = np.asarray(stance, dtype=bool)
    masks, which = np.unique(stance, axis=0, return_inverse=True)
    for m, mask in enumerate(masks):  # the samples of one stance pattern at once
        rows = np.flatnonzero(which.reshape(-1) == m)
        out[rows] = support_margins(feet[rows][:, mask, :2], com[rows, :2])
    return out


def support_margins(feet: np.ndarray, com: np.ndarray) -> np.ndarray:
    """:func:`support_margin` of many samples at once: feet (N, k, 2), com (N, 2) -> (N,).

    An ordered pair of feet (i, j) is a counter-clockwise edge of the hull when no other
    foot lies to its right; the margin is the smallest signed distance of the centre of
    mass to those edges' lines. Samples whose feet give no such edge of positive length
    (fewer than three feet, or feet in a line) take :func:`support_margin` one by one."""
    feet = np.asarray(feet, dtype=float)
    com = np.asarray(com, dtype=float)
    n, k = feet.shape[:2]
    out = np.full(n, np.inf)
    if k >= 3:
        for i in range(k):
            for j in range(k):
                if i == j:
                    continue
                e = feet[:, j] - feet[:, i]  # (N, 2)
                length = np.hypot(e[:, 0], e[:, 1])
                rel = feet - feet[:, i : i + 1]  # (N, k, 2)
                cross = e[:, None, 0] * rel[:, :, 1] - e[:, None, 1] * rel[:, :, 0]
                tol = 1e-12 * np.maximum(length, 1e-300)[:, None]
                edge = (length > 1e-12) & np.all(cross >= -tol, axis=1)
                # inward normal of a counter-clockwise edge: e rotated by +90 degrees
                d = e[:, 0] * (com[:, 1] - feet[:, i, 1]) - e[:, 1] * (com[:, 0] - feet[:, i, 0])
                dist = d / np.where(length > 1e-12, length, 1.0)
                # every foot on the edge's line (collinear feet) is no polygon
                flat = np.all(np.abs(cross) <= tol, axis=1)
                use = edge & ~flat
                out[use] = np.minimum(out[use], dist[use])
    for r in np.flatnonzero(~np.isfinite(out)):
        out[r] = support_margin(feet[r], com[r])
    return out


# --- gaits ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GaitPattern:
    """A periodic gait: ``duty`` (stance share of a cycle) and each leg's lift-off phase
    in [0, 1) of the cycle (``phases``: leg name -> phase)."""

    name: str
    duty: float
    phases: Mapping[str, float]


class _GaitsByLegs(Mapping[int, tuple[str, ...]]):
    """Gaits by leg count, the first walking's: a hexapod's tripod, ripple and wave, a
    quadruped's crawl, and for any other count of at least five legs the gaits of
    :func:`_spread_gaits` (a pentapod's and a heptapod's tripod, an octopod's tetrapod
    first) and the wave (one leg at a time, statically stable for any count: ``1 - 1/n``
    of the legs stand)."""

    _KNOWN = {6: ("tripod", "ripple", "wave"), 4: ("crawl",)}

    def __getitem__(self, n: int) -> tuple[str, ...]:
        if n in self._KNOWN:
            return self._KNOWN[n]
        if isinstance(n, int) and n >= 5:
            return (*_spread_gaits(n), "wave")
        raise KeyError(n)

    def __iter__(self):
        return iter(self._KNOWN)

    def __len__(self) -> int:
        return len(self._KNOWN)


#: Gaits named by the feet they keep on the ground (:func:`_spread_gaits`).
STANCE_NAMES = {3: "tripod", 4: "tetrapod"}


def _spread_gaits(n: int) -> tuple[str, ...]:
    """The gaits of ``n`` (>= 5, not 6) legs besides the wave, by the feet that stand at
    a time (:func:`_spread_phases`): the tripod (3), the tetrapod (4, when that leaves at
    least two legs to swing) and the ripple (``n - 2``, two legs swing at once; for an
    even count each side's wave, see :func:`gait_pattern`) when it is neither; the fewest
    feet first, but for an even count the gait of two groups of alternate legs (half the
    feet standing, duty 1/2) when it is named. A pentapod has the tripod, a heptapod the
    tripod, tetrapod and ripple, an octopod the tetrapod, tripod and ripple."""
    out = [STANCE_NAMES[k] for k in sorted(STANCE_NAMES) if k <= n - 2]
    if n - 2 not in STANCE_NAMES:
        out.append("ripple")
    if n % 2 == 0 and n // 2 in STANCE_NAMES:  # two groups of alternate legs first
        out.insert(0, out.pop(out.index(STANCE_NAMES[n // 2])))
    return tuple(out)


def _stance_count(name: str, n: int) -> int:
    """Feet on the ground at a time in the gait ``name`` of ``n`` legs spread around the
    trunk (the ripple: all but two; the wave: all but one)."""
    for k, v in STANCE_NAMES.items():
        if v == name:
            return k
    return n - 2 if name == "ripple" else n - 1


def _ring(legs: Sequence[Leg]) -> list[Leg]:
    """The legs counter-clockwise around the centre of their mounts."""
    c = np.mean([leg.mount[:2] for leg in legs], axis=0)

    def angle(leg: Leg) -> float:
        d = leg.mount[:2] - c
        return round(math.atan2(float(d[1]), float(d[0])) % (2 * math.pi), 9)

    return sorted(legs, key=lambda g: (angle(g), g.name))


def _spread_phases(legs: Sequence[Leg], k: int, direction: float) -> tuple[float, dict[str, float]]:
    """(duty, lift-off phases) of a gait of ``legs`` that keeps ``k`` feet on the ground,
    spread around the trunk.

    Half the legs (``k = n/2``): two groups of alternate legs around the trunk, duty 1/2
    (the octopod's tetrapod). Otherwise one leg lifts every ``1/n`` of a cycle and swings
    for ``(n - k)/n`` of it (duty ``k/n``), each lift ``j`` legs around the trunk from the
    one before, ``j`` coprime with ``n`` and such that the ``k`` standing legs (``k``
    consecutive lifts apart) leave the smallest largest gap around the trunk (the
    pentapod's tripod: every other leg, a five-pointed star, three feet always standing
    on a triangle around the trunk's centre); the first lift is the trailing leg in the
    direction of travel, the sense the one whose next lift is further forward."""
    ring = _ring(legs)
    n = len(ring)
    if 2 * k == n:
        return 0.5, {leg.name: (i % 2) / 2 for i, leg in enumerate(ring)}

    def widest(j: int) -> int:  # the largest gap around the ring between standing legs
        at = sorted(p * j % n for p in range(k))
        return max(b - a for a, b in zip(at, [*at[1:], at[0] + n], strict=True))

    j = min((j for j in range(1, n // 2 + 1) if math.gcd(j, n) == 1), key=lambda j: (widest(j), j))
    u = np.array([math.cos(direction), math.sin(direction)])
    along = [float(leg.mount[:2] @ u) for leg in ring]
    start = min(range(n), key=lambda i: (round(along[i], 9), ring[i].name))
    if along[(start - j) % n] > along[(start + j) % n] + 1e-9:
        j = n - j
    return k / n, {ring[(start + p * j) % n].name: p / n for p in range(n)}


#: Gaits by leg count.
GAITS: Mapping[int, tuple[str, ...]] = _GaitsByLegs()


def _ranked(
    legs: Sequence[Leg], direction: float, turn: float = 0.0
) -> tuple[list[Leg], list[Leg]]:
    """Two groups of legs, each ordered from its trailing to its leading leg.

    Walking towards ``direction`` (rad): the legs left and right of the travel, rear to
    front. Turning (``turn`` > 0 counter-clockwise, < 0 clockwise): the rear and the front
    half of the legs (their feet travel sideways, in opposite directions), each ordered
    along its own travel.
    """
    if turn:
        order = sorted(legs, key=lambda g: (round(float(g.mount[0]), 9), float(g.mount[1]), g.name))
        half = len(order) // 2
        groups = (order[:half], order[half:])
        out = []
        for group in groups:
            n = np.array([g.neutral[:2] for g in group])
            travel = math.copysign(1.0, turn) * np.array([-n[:, 1].sum(), n[:, 0].sum()])
            out.append(sorted(group, key=lambda g, t=travel: (float(g.neutral[:2] @ t), g.name)))
        return out[0], out[1]
    u = np.array([math.cos(direction), math.sin(direction)])
    w = np.array([-u[1], u[0]])
    key = {leg.name: (float(leg.mount[:2] @ w), float(leg.mount[:2] @ u)) for leg in legs}
    order = sorted(legs, key=lambda g: (round(key[g.name][0], 9), key[g.name][1], g.name))
    half = len(order) // 2
    right, left = order[:half], order[half:]
    return (sorted(left, key=lambda g: key[g.name][1]), sorted(right, key=lambda g: key[g.name][1]))


def gait_pattern(
    name: str,
    legs: Sequence[Leg],
    direction: float = 0.0,
    turn: float = 0.0,
    duty: float | None = None,
) -> GaitPattern:
    """The named gait for these legs, travelling towards ``direction`` rad (trunk frame),
    or turning in place when ``turn`` is not 0 (its sign: counter-clockwise > 0).

    tripod: legs alternate around the trunk, duty 1/2; ripple: each group of legs (see
    :func:`_ranked`: the sides of the travel, or the rear and front halves in a turn) a
    trailing-to-leading wave, duty 1 - 1/rows, the second group half a cycle after the
    first; wave: one leg at a time, the first group then the second, duty 1 - 1/legs;
    crawl (quadruped): as ripple with duty ``CRAWL_DUTY``, so that the two swings of a
    group follow each other and four-foot phases separate the groups; ``duty`` (crawl
    only) a shorter one, at least ``MIN_CRAWL_DUTY``. For counts other than 4 and 6 the
    tripod, the tetrapod and an odd count's ripple keep 3, 4 and all but two feet standing,
    spread around the trunk (:func:`_spread_phases`). ValueError for a gait the legs cannot
    do.
    """
    n = len(legs)
    valid = GAITS.get(n, ())
    if name not in valid:
        raise ValueError(
            f"gait: a {n}-legged robot walks with {', '.join(valid) or 'no gait'}, not {name!r}"
        )
    if duty is not None and (name != "crawl" or not MIN_CRAWL_DUTY <= duty <= CRAWL_DUTY):
        raise ValueError(f"duty: only a crawl takes one, in [{MIN_CRAWL_DUTY:g}, {CRAWL_DUTY:.4g}]")
    spread = name in STANCE_NAMES.values() or (name == "ripple" and n % 2 == 1)
    if spread and n not in _GaitsByLegs._KNOWN:
        return GaitPattern(name, *_spread_phases(legs, _stance_count(name, n), direction))
    left, right = _ranked(
        legs, 0.0 if name == "tripod" else direction, 0.0 if name == "tripod" else turn
    )
    rows = len(left)
    phases: dict[str, float] = {}
    if name == "tripod":
        duty = 0.5
        for s, side in enumerate((left, right)):
            for r, leg in enumerate(side):
                phases[leg.name] = 0.5 * ((r + s) % 2)
    elif name == "wave":
        duty = 1 - 1 / n
        for k, leg in enumerate([*left, *right]):
            phases[leg.name] = k / n
    else:  # ripple, crawl
        own = CRAWL_DUTY if name == "crawl" else 1 - 1 / rows
        duty = own if duty is None else duty
        for s, side in enumerate((left, right)):
            for r, leg in enumerate(side):
                phases[leg.name] = (0.5 * s + r * (1 - duty)) % 1.0
    return GaitPattern(name, duty, phases)


# --- stride -----------------------------------------------------------------------------------


def _segment_ok(
    leg: Leg, points: np.ndarray, height: float, step: float, coxa_swing: float
) -> bool:
    """Whether the foot can stand on ``points`` (k, 2) (trunk frame, ``height`` m below the
    trunk) and lift ``step`` m there, within the gait's reach rules."""
    p = np.column_stack([points, np.full(len(points), -height)])
    lifted = p + (0.0, 0.0, step)
    try:
        if leg.chain is not None:
            q = _chain_ik(leg, p, exact=False)
            ql = _chain_ik(leg, lifted, exact=False)
        else:
            q = leg_ik(leg, p)
            ql = leg_ik(leg, lifted)
    except ValueError:
        return False
    return bool(
        (not _yaw_first(leg) or np.all(np.abs(q[:, 0]) <= coxa_swing))
        and np.all(limit_slack(leg, q) >= JOINT_MARGIN)
        and np.all(limit_slack(leg, ql) >= JOINT_MARGIN)
        and np.all(leg_tilt(leg, q) <= TIBIA_TILT)
    )


def _segment_distance(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> float:
    """Distance m between two 2-D segments (sampled finely; segments are short)."""
    s = np.linspace(0.0, 1.0, 41)[:, None]
    pa = a0 + s * (a1 - a0)
    pb = b0 + s * (b1 - b0)
    return float(np.min(np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=2)))


def _segment_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`_segment_distance` of many pairs at once, to the bit: segments ``a`` and
    ``b`` (P, 2 ends, 2) -> (P,) m."""
    s = np.linspace(0.0, 1.0, 41)[:, None]
    pa = a[:, :1] + s * (a[:, 1:] - a[:, :1])  # (P, 41, 2)
    pb = b[:, :1] + s * (b[:, 1:] - b[:, :1])
    d = np.linalg.norm(pa[:, :, None, :] - pb[:, None, :, :], axis=3)
    return d.min(axis=(1, 2))


def stance_inset(leg: Leg, sweep: np.ndarray) -> float:
    """How far m to pull a stance segment (the foot's sweep (2,) m relative to the trunk,
    centred on the leg's neutral point) towards the mount so that the foot's distance from
    the coxa axis, and so the tibia's tilt, varies as much outward as inward of the
    neutral one (a sweep across the leg bulges outward at its ends): ``TIBIA_CENTRING`` of
    half that bulge."""
    n = leg.neutral[:2] - leg.mount[:2]
    s = np.linspace(-0.5, 0.5, 21)[:, None] * np.asarray(sweep, dtype=float)
    r = np.linalg.norm(n + s, axis=1)
    return float(TIBIA_CENTRING * max(0.0, 0.5 * (r.max() + r.min()) - np.linalg.norm(n)))


def max_stride(
    legs: Sequence[Leg],
    travel: Mapping[str, np.ndarray],
    height: float,
    step: float,
    coxa_swing: float = COXA_SWING,
) -> float:
    """The longest stride s m such that every leg's stance segment, its neutral point
    +- s/2 x ``travel[leg]`` (a (2,) vector in the trunk frame, of length <= 1: the
    leg's share of the stride), is reachable (:func:`_segment_ok`) and neighbouring
    segments stay ``LEG_CLEARANCE`` apart. 0 when none is.

    Found by ``STRIDE_BISECTIONS`` halvings of [0, 4 x the longest leg]; each batch of
    ``STRIDE_BATCH_LEVELS`` of them is decided by one vectorised test of every midpoint
    they can reach (:func:`_stride_tests`), so the result is the one-by-one bisection's to
    the bit. Remembered per legs, travel, height and step (walking and running ask alike)."""
    key = (
        legs_key(legs),
        tuple(tuple(float(x) for x in np.asarray(travel[leg.name], dtype=float)) for leg in legs),
        float(height),
        float(step),
        float(coxa_swing),
    )
    hit = _STRIDES.get(key)
    if hit is not None:
        _STRIDES.move_to_end(key)
        return hit
    out = _bisect_stride(legs, travel, height, step, coxa_swing)
    _STRIDES[key] = out
    while len(_STRIDES) > _MEMO_SIZE:
        _STRIDES.popitem(last=False)
    return out


#: Halvings of the stride search (4 x leg length / 2^40: below a nanometre).
STRIDE_BISECTIONS = 40
#: Halvings decided by one batched test (its 2^k - 1 reachable midpoints).
STRIDE_BATCH_LEVELS = 4
#: Results kept by each memo of this module (strides, timings, plans).
_MEMO_SIZE = 64
_STRIDES: OrderedDict[tuple, float] = OrderedDict()


def legs_key(legs: Sequence[Leg]) -> tuple:
    """What identifies the legs' geometry (a memo key)."""
    return tuple(
        (
            leg.name,
            leg.joints,
            tuple(float(x) for x in leg.mount),
            leg.yaw,
            leg.coxa,
            leg.femur,
            leg.tibia,
            tuple(float(x) for x in leg.lower),
            tuple(float(x) for x in leg.upper),
            leg.foot_body,
        )
        + (() if leg.chain is None else (_chain_key(leg.chain),))
        for leg in legs
    )


def _chain_key(chain: SerialChain) -> bytes:
    """What identifies a chain leg's geometry: its joints' origins and axes, its foot."""
    h = hashlib.blake2b(digest_size=16)
    for origin, axis, i in chain.steps:
        h.update(np.ascontiguousarray(origin, dtype=float).tobytes())
        h.update(repr(i).encode())
        if axis is not None:
            h.update(np.ascontiguousarray(axis, dtype=float).tobytes())
    return h.digest()


def model_key(template: Template) -> bytes:
    """A digest of everything of ``template`` a gait plan reads: its model's bodies
    (masses, centres of mass, inertias), joints (frames, axes, limits) and gravity, and
    its feet (a memo key for plans of templates built alike)."""
    h = hashlib.blake2b(digest_size=20)
    m = template.model
    for b in m.bodies:
        h.update(repr((b.name, b.mass)).encode())
        h.update(np.ascontiguousarray(b.com, dtype=float).tobytes())
        h.update(np.ascontiguousarray(b.inertia, dtype=float).tobytes())
    for j in m.joints:
        h.update(repr((j.name, j.parent, j.child, j.kind, j.lower, j.upper)).encode())
        h.update(np.ascontiguousarray(j.origin, dtype=float).tobytes())
        h.update(np.ascontiguousarray(j.axis, dtype=float).tobytes())
    h.update(np.ascontiguousarray(m.gravity, dtype=float).tobytes())
    h.update(repr(tuple(template.feet)).encode())
    for p in template.foot_points:
        h.update(np.ascontiguousarray(p, dtype=float).tobytes())
    return h.digest()


def _bisect_stride(
    legs: Sequence[Leg],
    travel: Mapping[str, np.ndarray],
    height: float,
    step: float,
    coxa_swing: float,
) -> float:
    """:func:`max_stride` without its memo."""
    lo, hi = 0.0, 4 * max(leg.extent for leg in legs)
    if any(leg.chain is not None for leg in legs):
        return _bisect_stride_chain(legs, travel, height, step, coxa_swing, hi)
    left = STRIDE_BISECTIONS
    first = True
    while left > 0:
        k = min(STRIDE_BATCH_LEVELS, left)
        # every midpoint the next k halvings can reach, in heap order (node i's midpoint
        # failing leads to node 2i + 1, passing to 2i + 2)
        mids: list[float] = []
        spans = [(lo, hi)]
        for _ in range(k):
            nxt = []
            for a, b in spans:
                m = 0.5 * (a + b)
                mids.append(m)
                nxt += [(a, m), (m, b)]
            spans = nxt
        skip = int(first)  # the first batch also tests stride 0
        ok = _stride_tests(legs, travel, height, step, coxa_swing, [0.0] * skip + mids)
        if first and not ok(0):
            return 0.0
        first = False
        i = 0
        for _ in range(k):
            mid = 0.5 * (lo + hi)
            lo, hi, i = (mid, hi, 2 * i + 2) if ok(skip + i) else (lo, mid, 2 * i + 1)
        left -= k
    return lo


#: Chain legs (numerical IK): halvings of their stride search (4 x leg length / 2^14:
#: about 0.03 mm) and points tested along each stance segment.
CHAIN_STRIDE_BISECTIONS = 14
CHAIN_STRIDE_SAMPLES = 9


def _bisect_stride_chain(
    legs: Sequence[Leg],
    travel: Mapping[str, np.ndarray],
    height: float,
    step: float,
    coxa_swing: float,
    hi: float,
) -> float:
    """:func:`max_stride` for legs of which some are chain legs (numerical IK): the same
    rules (:func:`_segment_ok` on ``CHAIN_STRIDE_SAMPLES`` points of each stance segment,
    neighbouring segments ``LEG_CLEARANCE`` apart), one stride at a time."""
    n = {leg.name: leg.neutral[:2] for leg in legs}
    lin = np.linspace(-1.0, 1.0, CHAIN_STRIDE_SAMPLES)[:, None]

    def ok(s: float) -> bool:
        ends = {}
        for leg in legs:
            half = 0.5 * s * np.asarray(travel[leg.name], dtype=float)
            if not _segment_ok(leg, n[leg.name] + lin * half, height, step, coxa_swing):
                return False
            ends[leg.name] = (n[leg.name] - half, n[leg.name] + half)
        names = [leg.name for leg in legs]
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                if _segment_distance(*ends[a], *ends[b]) < LEG_CLEARANCE:
                    return False
        return True

    if not ok(0.0):
        return 0.0
    lo = 0.0
    for _ in range(CHAIN_STRIDE_BISECTIONS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def _stride_tests(
    legs: Sequence[Leg],
    travel: Mapping[str, np.ndarray],
    height: float,
    step: float,
    coxa_swing: float,
    strides: Sequence[float],
) -> Callable[[int], bool]:
    """``test(i)``: whether ``strides[i]`` m passes :func:`max_stride`'s test, with the
    arithmetic of :func:`_segment_ok` and :func:`_segment_distances` leg by leg. The legs'
    reach and the exact gaps between their segments are found for every stride at once;
    the sampled distances of the segments that come near, only for a stride tested."""
    s = np.asarray(strides, dtype=float)
    n = np.array([leg.neutral[:2] for leg in legs])  # (L, 2)
    tr = np.array([np.asarray(travel[leg.name], dtype=float) for leg in legs])
    half = (0.5 * s)[None, :, None] * tr[:, None, :]  # (L, S, 2)
    lin = np.linspace(-1.0, 1.0, 21)[:, None]
    pts = n[:, None, None, :] + lin[None, None] * half[:, :, None, :]  # (L, S, 21, 2)
    p = np.concatenate([pts, np.full((*pts.shape[:-1], 1), -height)], axis=-1)
    lifted = p + (0.0, 0.0, step)

    def fig(values: Sequence[float]) -> np.ndarray:  # (L, 1, 1): against (L, S, 21)
        return np.array(values, dtype=float)[:, None, None]

    mount = np.array([leg.mount for leg in legs], dtype=float)[:, None, None, :]
    shape = (
        fig([leg.yaw for leg in legs]),
        fig([leg.coxa for leg in legs]),
        fig([leg.femur for leg in legs]),
        fig([leg.tibia for leg in legs]),
    )
    lower = np.array([leg.lower for leg in legs], dtype=float)[:, None, None, :]
    upper = np.array([leg.upper for leg in legs], dtype=float)[:, None, None, :]
    q, k = _ik(mount, *shape, p)
    ql, kl = _ik(mount, *shape, lifted)
    reach = (
        ~np.any(np.abs(k) > 1 + 1e-12, axis=-1)
        & ~np.any(np.abs(kl) > 1 + 1e-12, axis=-1)
        & np.all(np.abs(q[..., 0]) <= coxa_swing, axis=-1)
        & np.all(np.minimum(q - lower, upper - q).min(axis=-1) >= JOINT_MARGIN, axis=-1)
        & np.all(np.minimum(ql - lower, upper - ql).min(axis=-1) >= JOINT_MARGIN, axis=-1)
        & np.all(np.abs(q[..., 1] + q[..., 2]) <= TIBIA_TILT, axis=-1)
    ).all(axis=0)  # (S,)
    first, second = np.triu_indices(len(legs), 1)
    ends = np.stack([n[:, None, :] - half, n[:, None, :] + half], axis=2)  # (L, S, 2, 2)
    a, b = ends[first], ends[second]  # (pairs, S, 2, 2)
    near = _segment_gaps(a.reshape(-1, 2, 2), b.reshape(-1, 2, 2)).reshape(len(first), len(s))
    near = near < LEG_CLEARANCE + GAP_SLACK

    def test(i: int) -> bool:
        if not reach[i]:
            return False
        pairs = np.flatnonzero(near[:, i])
        if not len(pairs):
            return True
        return bool(np.all(_segment_distances(a[pairs, i], b[pairs, i]) >= LEG_CLEARANCE))

    return test


#: The exact distance of two segments is at most their sampled distance
#: (:func:`_segment_distances`); pairs whose exact distance clears ``LEG_CLEARANCE`` by
#: this much (m, far above rounding) pass without sampling.
GAP_SLACK = 1e-9


def _segment_gaps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Exact distances (P,) m between 2-D segments ``a`` and ``b`` (P, 2 ends, 2)."""

    def to_segment(p: np.ndarray, s: np.ndarray) -> np.ndarray:
        e = s[:, 1] - s[:, 0]
        ee = np.einsum("ij,ij->i", e, e)
        t = np.einsum("ij,ij->i", p - s[:, 0], e) / np.where(ee > 0, ee, 1.0)
        t = np.clip(np.where(ee > 0, t, 0.0), 0.0, 1.0)
        return np.linalg.norm(p - s[:, 0] - t[:, None] * e, axis=1)

    def side(o: np.ndarray, e: np.ndarray, p: np.ndarray) -> np.ndarray:
        return e[:, 0] * (p[:, 1] - o[:, 1]) - e[:, 1] * (p[:, 0] - o[:, 0])

    ea, eb = a[:, 1] - a[:, 0], b[:, 1] - b[:, 0]
    crossing = (side(a[:, 0], ea, b[:, 0]) * side(a[:, 0], ea, b[:, 1]) < 0) & (
        side(b[:, 0], eb, a[:, 0]) * side(b[:, 0], eb, a[:, 1]) < 0
    )
    gap = np.minimum.reduce(
        [
            to_segment(a[:, 0], b),
            to_segment(a[:, 1], b),
            to_segment(b[:, 0], a),
            to_segment(b[:, 1], a),
        ]
    )
    return np.where(crossing, 0.0, gap)


# --- planning ---------------------------------------------------------------------------------


def _smooth(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk ramp 10u^3 - 15u^4 + 6u^5 of u clipped to [0, 1]."""
    x = np.clip(u, 0.0, 1.0)
    return x**3 * (10 - 15 * x + 6 * x * x)


def _lift(tau: np.ndarray) -> np.ndarray:
    """Height share (0..1) of a swing at its phase tau in [0, 1]."""
    return np.minimum(_smooth(tau / LIFT_FRACTION), _smooth((1 - tau) / LIFT_FRACTION))


def _advance(tau: np.ndarray, short: float = 0.0) -> np.ndarray:
    """Horizontal share (0..1) of a swing's way at its phase tau in [0, 1]; with ``short``
    > 0, the straight line stops that share of the way short of the foothold and a
    second move covers it over ``APPROACH_SHARE`` of the phase (module docstring)."""
    if short <= 0:
        return _smooth((tau - SWING_EDGE) / (1 - 2 * SWING_EDGE))
    end = 1 - SWING_EDGE - APPROACH_SHARE
    main = _smooth((tau - SWING_EDGE) / (end - SWING_EDGE))
    return (1 - short) * main + short * _smooth((tau - end) / APPROACH_SHARE)


@dataclass(frozen=True, eq=False)
class GaitPlan:
    """A planned legged motion, sampled at ``times`` (N,) s.

    ``q`` (N, nv) rad, template joint order; ``body`` (N, 3): the trunk's planned (x m,
    y m, yaw rad) in the world (sway included); ``stance`` (N, legs) bool; ``feet`` (N,
    legs, 3): feet in the trunk frame, m; ``margin`` (N,) m: static stability margin;
    ``sway`` (N, 2) m: the trunk's offset from its steady path, trunk axes; scalars:
    ``period`` s, ``stride`` m (the stance sweep of the farthest-travelling foot),
    ``speed`` (m/s, or rad/s for a turn), ``step_height`` and ``height`` m, ``duty``,
    ``cycles``, ``progress`` (s at full speed: distance / speed, or turn / yaw rate).
    """

    times: np.ndarray
    q: np.ndarray
    body: np.ndarray
    stance: np.ndarray
    feet: np.ndarray
    margin: np.ndarray
    sway: np.ndarray
    period: float
    stride: float
    speed: float
    step_height: float
    height: float
    duty: float
    cycles: int
    progress: float


def _envelope(t: np.ndarray, t0: float, t1: float, ramp: float) -> np.ndarray:
    """Speed share (0..1): minimum-jerk ramps of ``ramp`` s up from t0 and down to t1."""
    if ramp <= 0:
        return ((t >= t0) & (t <= t1)).astype(float)
    return _smooth((t - t0) / ramp) * _smooth((t1 - t) / ramp)


def _progress(t: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Cumulative trapezoidal integral of e over t (same shape)."""
    out = np.zeros_like(e)
    out[1:] = np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(t))
    return out


def _swings(
    pattern: GaitPattern, legs: Sequence[Leg], cycles: int, t_start: float, period: float
) -> dict[str, np.ndarray]:
    """Swing intervals (cycles, 2) s of each leg."""
    out = {}
    for leg in legs:
        a = t_start + (pattern.phases[leg.name] + np.arange(cycles)) * period
        out[leg.name] = np.stack([a, a + (1 - pattern.duty) * period], axis=1)
    return out


def _ramp_for(swings: Mapping[str, np.ndarray], t0: float, t1: float, budget: float) -> float:
    """The shortest ramp s whose envelope moves the body less than ``budget`` (s at full
    speed) during each leg's first and last stance (the same arithmetic as
    :func:`_envelope` and :func:`_progress` on a fine grid; the grid's steps and offsets
    computed once, every leg's first lift-off and last landing read at once)."""
    grid = np.linspace(t0, t1, 4001)
    dt, after, before = np.diff(grid), grid - t0, t1 - grid
    legs = len(swings)
    ends = np.array(
        [float(iv[0, 0]) for iv in swings.values()] + [float(iv[-1, 1]) for iv in swings.values()]
    )
    prog = np.zeros_like(grid)

    def worst(ramp: float) -> float:
        if ramp <= 0:
            e = ((grid >= t0) & (grid <= t1)).astype(float)
        else:
            e = _smooth(after / ramp) * _smooth(before / ramp)
        prog[1:] = np.cumsum(0.5 * (e[1:] + e[:-1]) * dt)
        at = np.interp(ends, grid, prog)
        return max(0.0, float(at[:legs].max()), float((prog[-1] - at[legs:]).max()))

    lo, hi = 0.0, 0.5 * (t1 - t0)
    if worst(lo) <= budget:
        return lo
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if worst(mid) <= budget else (mid, hi)
    return hi


def _rot(yaw: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 2, 2) of yaw angles."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


@dataclass(frozen=True, eq=False)
class GaitTiming:
    """When a gait's legs swing and how fast its trunk moves (share of full speed)."""

    times: np.ndarray  # (N,) s
    envelope: np.ndarray  # (N,) 0..1
    progress: np.ndarray  # (N,) s at full speed
    swings: Mapping[str, np.ndarray]  # leg -> (cycles, 2) s
    t_rise: float
    t_end: float


def gait_timing(
    pattern: GaitPattern,
    legs: Sequence[Leg],
    cycles: int,
    period: float,
    t_rise: float,
    lead: float,
) -> GaitTiming:
    """The schedule of ``cycles`` cycles of ``pattern`` after ``t_rise`` s of rising and
    ``lead`` s of standing (and ``lead`` s standing at the end). Remembered (read-only
    arrays): a planner asks for the same schedule again and again while it settles a
    gait's timing."""
    if cycles < 1 or not period > 0:
        raise ValueError("a gait needs at least one cycle of positive period")
    key = (
        pattern_key(pattern),
        tuple(leg.name for leg in legs),
        int(cycles),
        float(period),
        float(t_rise),
        float(lead),
    )
    hit = _TIMINGS.get(key)
    if hit is not None:
        _TIMINGS.move_to_end(key)
        return hit
    out = _timing(pattern, legs, cycles, period, t_rise, lead)
    for a in (out.times, out.envelope, out.progress, *out.swings.values()):
        a.setflags(write=False)
    _TIMINGS[key] = out
    while len(_TIMINGS) > _MEMO_SIZE:
        _TIMINGS.popitem(last=False)
    return out


_TIMINGS: OrderedDict[tuple, GaitTiming] = OrderedDict()


def pattern_key(pattern: GaitPattern) -> tuple:
    """What identifies a gait pattern (a memo key)."""
    return (pattern.name, float(pattern.duty), tuple(sorted(pattern.phases.items())))


def _timing(
    pattern: GaitPattern,
    legs: Sequence[Leg],
    cycles: int,
    period: float,
    t_rise: float,
    lead: float,
) -> GaitTiming:
    """:func:`gait_timing` without its memo."""
    t_start = t_rise + lead
    sw = _swings(pattern, legs, cycles, t_start, period)
    t_stop = max(float(iv[-1, 1]) for iv in sw.values())
    t_end = t_stop + lead
    n = int(math.ceil(t_end / SAMPLE_DT - 1e-9)) + 1
    times = np.linspace(0.0, (n - 1) * SAMPLE_DT, n)
    ramp = _ramp_for(sw, t_start, t_stop, 0.5 * pattern.duty * period)
    e = _envelope(times, t_start, t_stop, ramp)
    return GaitTiming(times, e, _progress(times, e), sw, t_rise, float(times[-1]))


def standing_height(legs: Sequence[Leg]) -> float:
    """Trunk height m above the ground at q = 0 (feet down)."""
    return max(float(-leg.neutral[2]) for leg in legs)


def plan_gait(
    template: Template,
    legs: Sequence[Leg],
    pattern: GaitPattern,
    cycles: int,
    period: float,
    twist: tuple[float, float, float],
    step_height: float,
    height: float,
    sway: bool | None = None,
    stand: bool = False,
    approach: float = 0.0,
    sway_limits: tuple[float, float] = (SWAY_MAX, SWAY_TARGET_MARGIN),
) -> GaitPlan:
    """Sample a gait: ``cycles`` cycles of ``period`` s of ``pattern`` while the trunk moves
    with ``twist`` = (v_x m/s, v_y m/s, yaw rate rad/s) in its own frame at full speed,
    feet lifting ``step_height`` m, trunk ``height`` m above the ground; each swing ends
    with a slow approach of ``approach`` rad about the coxa (module docstring; 0: none).

    The trunk sways (see the module docstring) when ``sway`` is True, or when it is None
    and the margin without sway would fall below ``MIN_MARGIN``, by at most
    ``sway_limits[0]`` m per axis for a margin of at most ``sway_limits[1]`` m (``SWAY_MAX``,
    ``SWAY_TARGET_MARGIN``); a swaying trunk (or
    ``stand``) stands ``SWAY_LEAD`` cycles before the first swing and after the last.
    Joint limits are not checked here (see ``LeggedController``); ValueError for
    unreachable feet or when no sway is possible.
    """
    h0 = standing_height(legs)
    t_rise = TRANSITION_S if abs(height - h0) > 1e-6 else 0.0
    sway_on = bool(sway)
    vx, vy, wz = twist
    # footholds pulled in on straight travel (a turn's sweeps cross the legs less)
    inset = {
        leg.name: 0.0
        if wz
        else stance_inset(
            leg,
            pattern.duty * period * np.array([vx - wz * leg.neutral[1], vy + wz * leg.neutral[0]]),
        )
        for leg in legs
    }
    while True:
        lead = SWAY_LEAD * period if (sway_on or stand) else 0.0
        tm = gait_timing(pattern, legs, cycles, period, t_rise, lead)
        times, e = tm.times, tm.envelope
        n = len(times)
        yaw = wz * tm.progress
        vel = np.einsum("nij,j->ni", _rot(yaw), np.array([vx, vy])) * e[:, None]
        pos = np.stack([_progress(times, vel[:, 0]), _progress(times, vel[:, 1])], axis=1)
        plan = _feet_plan(
            legs, tm.swings, times, pos, yaw, t_rise, h0, height, step_height, inset, approach
        )
        d = np.zeros((n, 2))
        q, feet_b = _joint_plan(template, legs, plan, pos, yaw, d)
        margin = stability_margins(template, legs, q, plan["stance"])
        if not sway_on and sway is None and margin.min() < MIN_MARGIN:
            sway_on = True
            continue
        break
    if sway_on:
        g = float(np.linalg.norm(template.model.gravity))
        # how much a sway along trunk x / y moves the stance feet radially (the tibia's
        # lever), averaged over the legs
        out = np.array([leg.neutral[:2] - leg.mount[:2] for leg in legs])
        out /= np.linalg.norm(out, axis=1)[:, None]
        radial = (float(np.mean(np.abs(out[:, 0]))), float(np.mean(np.abs(out[:, 1]))))
        for _ in range(2):  # the legs' share of the COM follows the sway: iterate
            com = center_of_mass(template.model, q)[:, :2]
            d = _sway(
                times,
                plan,
                pos,
                yaw,
                com,
                height / g,
                t_rise,
                tm.t_end,
                period,
                radial,
                sway_limits,
            )
            q, feet_b = _joint_plan(template, legs, plan, pos, yaw, d)
        margin = stability_margins(template, legs, q, plan["stance"])
    world = pos + np.einsum("nij,nj->ni", _rot(yaw), d)
    # the farthest-travelling foot's stance sweep at full speed
    stride = (
        pattern.duty
        * period
        * max(math.hypot(vx - wz * leg.neutral[1], vy + wz * leg.neutral[0]) for leg in legs)
    )
    return GaitPlan(
        times=times,
        q=q,
        body=np.column_stack([world, yaw]),
        stance=plan["stance"],
        feet=feet_b,
        margin=margin,
        sway=d,
        period=period,
        stride=stride,
        speed=math.hypot(vx, vy) if (vx or vy) else abs(wz),
        step_height=step_height,
        height=height,
        duty=pattern.duty,
        cycles=cycles,
        progress=float(tm.progress[-1]),
    )


def _feet_plan(
    legs: Sequence[Leg],
    swings: Mapping[str, np.ndarray],
    times: np.ndarray,
    pos: np.ndarray,
    yaw: np.ndarray,
    t_rise: float,
    h0: float,
    height: float,
    step: float,
    inset: Mapping[str, float] | None = None,
    approach: float = 0.0,
) -> dict[str, np.ndarray]:
    """World feet (N, legs, 2), lift above the ground (N, legs), stance (N, legs) and the
    trunk height (N,) of a gait; the footholds between the first and the last stance are
    ``inset[leg]`` m closer to the leg's mount than its neutral point; each swing's last
    ``approach`` rad x the foot's distance from its coxa axis is a slow second move (at
    most half the swing's way)."""
    n, nl = len(times), len(legs)
    feet = np.zeros((n, nl, 2))
    lift = np.zeros((n, nl))
    stance = np.ones((n, nl), dtype=bool)

    def neutral_world(leg: Leg, t: float) -> np.ndarray:
        p = np.array([np.interp(t, times, pos[:, 0]), np.interp(t, times, pos[:, 1])])
        return p + _rot(np.interp(t, times, yaw)) @ leg.neutral[:2]

    for k, leg in enumerate(legs):
        iv = swings[leg.name]
        lever = approach * float(np.linalg.norm(leg.neutral[:2] - leg.mount[:2]))
        holds = [neutral_world(leg, 0.0)]
        pull = (inset or {}).get(leg.name, 0.0)
        for c in range(1, len(iv)):
            a, b = iv[c - 1, 1], iv[c, 0]
            hold = 0.5 * (neutral_world(leg, a) + neutral_world(leg, b))
            mount = 0.5 * (
                _rot(np.interp(a, times, yaw)) @ leg.mount[:2]
                + _rot(np.interp(b, times, yaw)) @ leg.mount[:2]
            ) + np.array([np.interp(0.5 * (a + b), times, pos[:, k]) for k in range(2)])
            out = hold - mount
            holds.append(hold - pull * out / max(float(np.linalg.norm(out)), 1e-12))
        holds.append(neutral_world(leg, float(times[-1])))
        holds_a = np.array(holds)
        # index of the stance each sample is in or after: number of swings started
        started = np.searchsorted(iv[:, 0], times, side="left")
        feet[:, k] = holds_a[started]
        for c, (a, b) in enumerate(iv):
            inside = (times > a) & (times < b)
            tau = (times[inside] - a) / (b - a)
            way = holds_a[c + 1] - holds_a[c]
            short = min(0.5, lever / max(float(np.linalg.norm(way)), 1e-12))
            feet[inside, k] = holds_a[c] + _advance(tau, short)[:, None] * way
            lift[inside, k] = step * _lift(tau)
            stance[inside, k] = False
    z = np.full(n, height)
    if t_rise > 0:
        z = h0 + (height - h0) * _smooth(times / t_rise)
    return {"feet": feet, "lift": lift, "stance": stance, "height": z}


def _joint_plan(
    template: Template,
    legs: Sequence[Leg],
    plan: Mapping[str, np.ndarray],
    pos: np.ndarray,
    yaw: np.ndarray,
    sway: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles (N, nv) and trunk-frame feet (N, legs, 3) for the trunk at ``pos`` +
    ``sway`` (rotated by ``yaw``)."""
    m = template.model
    R = _rot(yaw)
    body = pos + np.einsum("nij,nj->ni", R, sway)
    rel = plan["feet"] - body[:, None, :]
    local = np.einsum("nji,nkj->nki", R, rel)  # R^T (feet - body)
    z = (plan["lift"] - plan["height"][:, None])[..., None]
    feet_b = np.concatenate([local, z], axis=2)
    q = np.zeros((len(pos), m.nv))
    for k, leg in enumerate(legs):
        qk = leg_ik(leg, feet_b[:, k])
        for j, name in enumerate(leg.joints):
            q[:, m.q_index[m.joint(name)]] = qk[:, j]
    return q, feet_b


#: Sway solutions kept on disk (``$PARMOR_CACHE/sway-KEY.npy``; the oldest beyond this
#: many are deleted when one is written).
SWAY_CACHE_FILES = 512


def _sway(
    times: np.ndarray,
    plan: Mapping[str, np.ndarray],
    pos: np.ndarray,
    yaw: np.ndarray,
    com: np.ndarray,
    kz: float,
    t0: float,
    t1: float,
    period: float,
    radial: tuple[float, float] = (0.0, 0.0),
    limits: tuple[float, float] = (SWAY_MAX, SWAY_TARGET_MARGIN),
) -> np.ndarray:
    """:func:`_sway_lp`, its solutions kept in parmor's cache folder
    (:func:`gaits.base.cache_folder`): the linear programmes (and scipy, whose import is
    most of a quadruped's start-up) are skipped for a plan solved before. KEY hashes every
    input the programmes read, this file (their code and constants) and scipy's and
    numpy's versions and builds, so an entry is never stale; an unreadable one is solved
    again."""

    folder = cache_folder()
    path = None
    if folder is not None:
        key = _sway_key(times, plan, pos, yaw, com, (kz, t0, t1, period, *radial, *limits))
        path = None if key is None else folder / f"sway-{key}.npy"
    if path is not None:
        try:
            got = np.load(path, allow_pickle=False)
            if got.shape == (len(times), 2) and got.dtype == np.float64:
                return got
        except (OSError, ValueError, EOFError):
            pass
    out = _sway_lp(times, plan, pos, yaw, com, kz, t0, t1, period, radial, limits)
    if path is not None:
        _write_cached(path, out, "sway-", SWAY_CACHE_FILES)
    return out


def _sway_key(times, plan, pos, yaw, com, scalars: tuple[float, ...]) -> str | None:
    """The cache key of a sway programme (see :func:`_sway`); None when scipy or the
    sources cannot be read."""
    if not _SWAY_CODE:
        _SWAY_CODE.append(_sway_code())
    code = _SWAY_CODE[0]
    if code is None:
        return None
    h = hashlib.blake2b(code, digest_size=20)
    for a in (times, plan["stance"], plan["feet"], pos, yaw, com):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    h.update(repr(tuple(float(x) for x in scalars)).encode())
    return h.hexdigest()


_SWAY_CODE: list[bytes | None] = []  # _sway_code(), once a process


def _sway_code() -> bytes | None:
    """What the sway programmes' solutions depend on besides their inputs: this file, and
    scipy's and numpy's versions and builds; None when they cannot be read."""
    import importlib.util

    spec = importlib.util.find_spec("scipy")
    if spec is None or spec.origin is None:
        return None
    try:
        h = hashlib.blake2b(Path(__file__).read_bytes(), digest_size=20)
        stat = os.stat(spec.origin)
        core = os.stat(np._core._multiarray_umath.__file__)
    except (OSError, AttributeError):
        return None
    h.update(f"{spec.origin}|{stat.st_size}|{stat.st_mtime_ns}".encode())
    h.update(f"{np.__version__}|{np.__file__}|{core.st_size}|{core.st_mtime_ns}".encode())
    return h.digest()


def _write_cached(path: Path, array: np.ndarray, prefix: str, keep: int) -> None:
    """``array`` saved as the cache entry ``path`` (``gaits.base.cache_write``), keeping
    the newest ``keep`` ``prefix*`` entries."""

    cache_write(path, lambda f: np.save(f, array, allow_pickle=False), prefix, keep)


def _sway_lp(
    times: np.ndarray,
    plan: Mapping[str, np.ndarray],
    pos: np.ndarray,
    yaw: np.ndarray,
    com: np.ndarray,
    kz: float,
    t0: float,
    t1: float,
    period: float,
    radial: tuple[float, float] = (0.0, 0.0),
    limits: tuple[float, float] = (SWAY_MAX, SWAY_TARGET_MARGIN),
) -> np.ndarray:
    """Trunk sway (N, 2) m (trunk axes) maximising the smallest stability margin of the
    centre of mass and of the cart-table ZMP (``COM - kz * acceleration``, kz = trunk
    height / g in s^2); ``com`` (N, 2): the centre of mass in the trunk frame with the legs
    where the last sway put them. See the module docstring.

    The sway is a clamped cubic B-spline on [t0, t1] with ``SWAY_KNOTS`` knot spans a
    cycle whose first and last three coefficients are 0 (no offset, velocity or
    acceleration at either end); its coefficients within +-``limits[0]`` bound the offset
    (a B-spline stays in the hull of its coefficients). Margins and accelerations are
    constrained at ``LP_SAMPLES`` samples a cycle.
    """
    from scipy import sparse
    from scipy.interpolate import BSpline
    from scipy.optimize import linprog

    pieces = max(8, int(math.ceil((t1 - t0) / period * SWAY_KNOTS)))
    knots = np.concatenate([[t0] * 3, np.linspace(t0, t1, pieces + 1), [t1] * 3])
    nb = len(knots) - 4
    free = np.arange(3, nb - 3)
    nf = len(free)
    every = max(1, int(period / LP_SAMPLES / SAMPLE_DT))
    sel = np.flatnonzero((times >= t0) & (times <= t1))[::every]
    ts = times[sel]
    B = BSpline.design_matrix(ts, knots, 3).tocsc()[:, free].tocsr()
    Bdd = sparse.csr_matrix(BSpline(knots, np.eye(nb)[:, free], 3).derivative(2)(ts))
    R = _rot(yaw)
    rows, normals, rhs = [], [], []
    for j, i in enumerate(sel):
        st = plan["stance"][i]
        if st.sum() < 3:
            continue
        feet = np.einsum("ji,kj->ki", R[i], plan["feet"][i, st] - pos[i])  # steady frame
        nrm, off = _edges(feet)
        rows.extend([j] * len(off))
        normals.append(nrm)
        rhs.append(nrm @ com[i] - off)
    rows_a = np.array(rows)
    nrm = np.concatenate(normals)
    rhs_a = np.concatenate(rhs)
    Bj, Bddj = B[rows_a], Bdd[rows_a]

    def margin_rows(k: float) -> sparse.csr_matrix:
        # n.(c + d - k d'') - b >= m  <=>  -n.d + k n.d'' + m <= n.c - b
        nx, ny = sparse.diags(nrm[:, 0]), sparse.diags(nrm[:, 1])
        return sparse.hstack([-nx @ Bj + k * nx @ Bddj, -ny @ Bj + k * ny @ Bddj])

    A_m = sparse.vstack([margin_rows(0.0), margin_rows(kz)]).tocsr()
    b_m = np.concatenate([rhs_a, rhs_a])
    Z = sparse.csr_matrix(Bdd.shape)
    A_acc = sparse.vstack(
        [
            sparse.hstack([Bdd, Z]),
            sparse.hstack([-Bdd, Z]),
            sparse.hstack([Z, Bdd]),
            sparse.hstack([Z, -Bdd]),
        ]
    ).tocsr()
    b_acc = np.full(A_acc.shape[0], SWAY_ACCEL)
    box = [(-limits[0], limits[0])] * (2 * nf)
    ones = sparse.csr_matrix(np.ones((A_m.shape[0], 1)))
    A1 = sparse.vstack(
        [sparse.hstack([A_m, ones]), sparse.hstack([A_acc, sparse.csr_matrix((A_acc.shape[0], 1))])]
    ).tocsr()
    cost = np.zeros(2 * nf + 1)
    cost[-1] = -1.0
    res = _linprog(linprog, cost, A1, np.concatenate([b_m, b_acc]), [*box, (None, None)])
    if res is None:
        raise ValueError("no trunk sway keeps the gait statically stable")
    best = float(res.x[-1])
    # the smoothest, least radial sway (sum of |second differences| of the coefficients
    # plus SWAY_RADIAL_WEIGHT x their radial share) keeping 95 % of the best margin, or
    # limits[1] (SWAY_TARGET_MARGIN) when that is less
    keep = min(best - 0.05 * abs(best), limits[1])
    nd = nf - 2
    D = sparse.diags([np.ones(nd), -2 * np.ones(nd), np.ones(nd)], [0, 1, 2], shape=(nd, nf))
    Zd, Id, Zdd = sparse.csr_matrix((nd, nf)), sparse.identity(nd), sparse.csr_matrix((nd, nd))
    Zf, If = sparse.csr_matrix((nf, nf)), sparse.identity(nf)
    Zdf = sparse.csr_matrix((nd, 2 * nf))
    A_s = sparse.vstack(
        [
            sparse.hstack([D, Zd, -Id, Zdd, Zdf]),
            sparse.hstack([-D, Zd, -Id, Zdd, Zdf]),
            sparse.hstack([Zd, D, Zdd, -Id, Zdf]),
            sparse.hstack([Zd, -D, Zdd, -Id, Zdf]),
        ]
    )
    Zfd = sparse.csr_matrix((nf, 2 * nd))
    A_a = sparse.vstack(  # |w| <= a
        [
            sparse.hstack([If, Zf, Zfd, -If, Zf]),
            sparse.hstack([-If, Zf, Zfd, -If, Zf]),
            sparse.hstack([Zf, If, Zfd, Zf, -If]),
            sparse.hstack([Zf, -If, Zfd, Zf, -If]),
        ]
    )
    pad = sparse.csr_matrix((A_m.shape[0] + A_acc.shape[0], 2 * nd + 2 * nf))
    A2 = sparse.vstack([sparse.hstack([sparse.vstack([A_m, A_acc]), pad]), A_s, A_a]).tocsr()
    b2 = np.concatenate([b_m - keep, b_acc, np.zeros(4 * nd + 4 * nf)])
    cost2 = np.concatenate(
        [
            np.zeros(2 * nf),
            np.ones(2 * nd),
            np.full(nf, SWAY_RADIAL_WEIGHT * radial[0]),
            np.full(nf, SWAY_RADIAL_WEIGHT * radial[1]),
        ]
    )
    res2 = _linprog(linprog, cost2, A2, b2, [*box, *[(0.0, None)] * (2 * nd + 2 * nf)])
    w = (res2 if res2 is not None else res).x[: 2 * nf]
    inside = (times >= t0) & (times <= t1)
    full = BSpline.design_matrix(times[inside], knots, 3).tocsc()[:, free]
    out = np.zeros((len(times), 2))
    out[inside, 0] = full @ w[:nf]
    out[inside, 1] = full @ w[nf:]
    return out


def _linprog(linprog, cost, A, b, bounds):
    """scipy's HiGHS on min cost.x, A x <= b; the dual simplex, then interior point if that
    fails numerically; None when neither solves it."""
    for method in ("highs-ds", "highs-ipm"):
        res = linprog(cost, A_ub=A, b_ub=b, bounds=bounds, method=method)
        if res.status == 0:
            return res
    return None
