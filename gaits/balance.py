"""Balance from the trunk's IMU: the loop a biped's firmware closes on its tilt.

A biped walks on a narrow support (two feet, one of them lifted half of the time); its
plan keeps the trunk upright over the feet, and whatever tilts it (a sloped floor, the
servos' play, a late command) goes uncorrected in an open-loop replay until the robot
falls. The loop (:class:`Balance`, kind ``"balance"``) reads the firmware's attitude
estimate (roll, pitch: the complementary filter of :mod:`gaits.feedback`, never the
simulator's pose) and the gyro's rates, and turns the trunk back upright through the legs'
joints:

- **ankle strategy** on the stance feet (each foot's share of the support is the plan's:
  ``support``, from its feet's heights): every joint of a leg's ankle (the joints nearest
  its foot whose axes are the trunk's roll and pitch axes) is offset by
  ``kp_ankle * tilt + kd_ankle * rate + k_level * floor`` along its axis (``tilt`` beyond
  a ``deadband_rad``; ``floor`` the floor's slope). With the foot flat on the floor,
  turning a joint of the leg by ``d`` about its axis turns everything above it by ``-d``:
  the offset turns the trunk back by ``kp`` of its tilt, and the ankle's torque moves the
  centre of pressure under the foot the way that stops the fall (the inverted pendulum's
  only lever without stepping); ``k_level`` leans the legs off the slope.
- **swing foot**: a lifted foot's ankle turns by minus the trunk's tilt relative to the
  floor (``kp_swing``), so it lands flat. The floor's slope is the trunk's tilt at
  switch-on: the robot stands on it with q = 0 (the firmware's levelling).
- **stride** (gaits): the plan carries its leg angles' derivative per relative change of
  the step length (``stride``) and its travel direction (``travel``); the steps are
  shortened by ``k_slope`` x the slope along the walk downhill and lengthened uphill
  (within ``stride_limit``): the pendulum goes farther per step downhill.
- **hip strategy** (off by default): the hips' roll and pitch joints (the joints nearest
  the trunk with those axes) of the stance legs get ``kp_hip`` and ``kd_hip`` on the part
  of the tilt beyond ``hip_from_rad``.
- **heading** (off by default, ``kp_yaw``): the hips' yaw joints turn the trunk back to the
  plan's heading from the attitude's yaw (the gyro's, drifting with its bias): a stance
  leg alone on the floor turns the trunk, a swing leg aims its foot the other way.

Each joint's offset is bounded by ``limit_rad`` (and each strategy's by its own
``*_limit_rad``), so the loop never asks a servo for more than a few degrees beyond its
plan; the rates are low-pass filtered (``rate_filter_s``) so the gyro's noise does not
reach the servos. The joints, their axes and their roles come from the design's template
(:func:`balance_joints`: the chain from each foot up to the trunk, the joints classified by
their axis in the trunk's frame and their position in the chain), never from a type's name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from gaits.feedback import Loop, Reading, register, roll_pitch_yaw
from kinematics.dynamics import forward_kinematics

#: the loop's kind (``Trajectory.info["feedback"]["loop"]``)
KIND = "balance"

#: The gains of the biped's balance (the module docstring; measured in MuJoCo on the
#: default humanoid under the perturbation table: ``docs/feedback-balance.md``). Angles rad,
#: rates rad/s: ``kp`` rad of offset per rad of tilt, ``kd`` per rad/s (s).
GAINS: dict[str, float] = {
    "kp_ankle": 0.3,
    "kd_ankle": 0.05,
    "kp_hip": 0.0,
    "kd_hip": 0.0,
    "hip_from_rad": 0.05,
    "kp_yaw": 0.0,
    "ankle_limit_rad": 0.15,
    "hip_limit_rad": 0.15,
    "yaw_limit_rad": 0.1,
    "limit_rad": 0.2,
    "rate_filter_s": 0.02,
    "kp_swing": 1.0,
    "lead_s": 0.03,
    "k_slope": 0.0,
    "k_level": 0.0,
    "deadband_rad": 0.0,
    "stride_limit": 0.3,
}


def balance_joints(model, feet: tuple[str, ...], joint_names: tuple[str, ...]) -> dict:
    """The joints a balance loop drives, by structure: for each foot body of ``model``
    (a :class:`kinematics.model.Model`; leg ``k`` is ``feet[k]``), the revolute joints from
    the foot up to the root, each with its axis in the root's frame at q = 0. ``ankle``:
    the first joint from the foot about the trunk's roll axis (x) and the first about its
    pitch axis (y); ``hip``: the first of each from the trunk; ``yaw``: the first from the
    trunk about z. Joints not in ``joint_names`` (the plan's) are left out. Each entry
    ``[joint, leg, ax, ay, az]``."""

    fk = forward_kinematics(model, np.zeros((1, model.nq)))[0]  # (nb, 4, 4) at q = 0
    root = fk[0, :3, :3]
    out: dict[str, list[list[object]]] = {"ankle": [], "hip": [], "yaw": []}
    plan = set(joint_names)

    def first(seq, k: int):
        for name, axis in seq:
            if int(np.argmax(np.abs(axis))) == k and abs(axis[k]) > 0.9:
                return name, axis
        return None

    for leg, foot in enumerate(feet):
        chain = []  # foot first
        body = model.body(foot)
        while body > 0:
            j = model.joints[body]
            if j.kind == "revolute":
                axis = root.T @ fk[body, :3, :3] @ np.asarray(j.axis, dtype=float)
                chain.append((j.name, axis))
            body = j.parent
        picks = {
            "ankle": [first(chain, 0), first(chain, 1)],
            "hip": [first(chain[::-1], 0), first(chain[::-1], 1)],
            "yaw": [first(chain[::-1], 2)],
        }
        taken: set[str] = set()
        for role, found in picks.items():
            for f in found:
                if f is None or f[0] not in plan or f[0] in taken:
                    continue  # a short leg: its one roll joint is the ankle's
                taken.add(f[0])
                out[role].append([f[0], leg, *(round(float(c), 6) for c in f[1])])
    return out


def support_weights(model, feet: tuple[str, ...], names: tuple[str, ...], q) -> np.ndarray:
    """(n, len(feet)) in [0, 1]: each foot's share of the support along the planned angles
    ``q`` (n, len(names)): 1 while its sole is the lowest (within ``CONTACT_M``), fading to
    0 as it rises ``2 CONTACT_M`` above it (the plan's stance and swing phases)."""

    index = {n: k for k, n in enumerate(model.q_names)}
    full = np.zeros((len(q), model.nq))
    for k, n in enumerate(names):
        full[:, index[n]] = q[:, k]
    frames = forward_kinematics(model, full)
    z = np.stack([frames[:, model.body(f), 2, 3] for f in feet], axis=1)  # (n, legs)
    up = z - z.min(axis=1, keepdims=True)
    return np.clip(2.0 - up / CONTACT_M, 0.0, 1.0)


#: m: a sole this close to the lowest one is on the floor (:func:`support_weights`)
CONTACT_M = 0.002


def balance_spec(model, feet: tuple[str, ...], names: tuple[str, ...], q, **gains) -> dict:
    """The plan's ``info["feedback"]`` for a balance loop along the planned angles ``q``
    (n, len(names)): the joints of :func:`balance_joints`, the feet's support
    (:func:`support_weights`, ``support``: (n, legs) at the plan's samples) and
    :data:`GAINS` (overridden by ``gains``)."""
    spec: dict[str, object] = {"loop": KIND, **GAINS, **gains}
    spec.update(balance_joints(model, feet, names))
    spec["support"] = support_weights(model, feet, names, np.asarray(q, dtype=float))
    return spec


@register(KIND)
class Balance(Loop):
    """The trunk kept upright from the IMU (module docstring)."""

    needs_imu = True
    #: the feedback gains of :data:`GAINS` (its limits, filters and timing are not)
    GAINS = ("kp_ankle", "kd_ankle", "kp_hip", "kd_hip", "kp_yaw", "k_slope", "k_level")

    def __init__(self, traj, spec: Mapping[str, object]) -> None:
        super().__init__(traj, spec)
        self.g = {k: self.gain(k, GAINS[k]) for k in GAINS}
        index = {j: k for k, j in enumerate(self.joints)}

        def rows(role: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            entries = [e for e in spec.get(role, ()) if e[0] in index]  # type: ignore[union-attr]
            idx = np.array([index[e[0]] for e in entries], dtype=int)
            legs = np.array([int(e[1]) for e in entries], dtype=int)
            axes = np.array([[float(c) for c in e[2:5]] for e in entries]).reshape(-1, 3)
            return idx, legs, axes

        self.ankle, self.hip, self.yaw = rows("ankle"), rows("hip"), rows("yaw")
        support = spec.get("support")
        self.support = None if support is None else np.asarray(support, dtype=float)
        stride = spec.get("stride")
        self.stride = None if stride is None else np.asarray(stride, dtype=float)
        self.travel = float(spec.get("travel", 0.0))  # type: ignore[arg-type]
        self.step_change = 0.0  # the stride correction: relative change of the step length
        self.rate = np.zeros(3)
        self.floor = np.zeros(3)  # the floor's tilt (roll, pitch, 0) against gravity
        self.yaw0: float | None = None
        self.last_t: float | None = None

    def reset(self, first: Reading) -> None:
        self.rate = np.zeros(3)
        self.last_t = first.t
        if first.attitude is not None:
            roll0, pitch0, self.yaw0 = roll_pitch_yaw(first.attitude)
            # standing on the floor at switch-on (q = 0, both soles flat), the trunk's
            # tilt is the floor's: what a swing foot is kept parallel to
            self.floor = np.array([roll0, pitch0, 0.0])
            if self.stride is not None:
                # standing on the floor at switch-on, the trunk's pitch is the floor's slope
                # along the walk (positive: downhill ahead); the pendulum goes farther per
                # step downhill: shorter steps there, longer uphill
                g = self.g
                self.step_change = float(
                    np.clip(
                        -g["k_slope"] * self.travel * pitch0, -g["stride_limit"], g["stride_limit"]
                    )
                )

    def stance(self, t: float) -> np.ndarray:
        """(legs,) each foot's planned share of the support at ``t`` (1 without a plan)."""
        if self.support is None:
            return np.ones(1)
        tt = self.traj.times
        return np.array(
            [np.interp(t, tt, self.support[:, k]) for k in range(self.support.shape[1])]
        )

    def correct(self, r: Reading) -> np.ndarray:
        out = np.zeros(len(self.joints))
        if r.attitude is None or r.gyro is None:
            return out
        g = self.g
        dt = 0.0 if self.last_t is None else max(0.0, r.t - self.last_t)
        self.last_t = r.t
        a = dt / (dt + g["rate_filter_s"]) if dt > 0 else 1.0
        self.rate = self.rate + a * (np.asarray(r.gyro, dtype=float) - self.rate)
        roll, pitch, yaw = roll_pitch_yaw(r.attitude)
        tilt = np.array([roll, pitch, 0.0])
        rate = np.array([self.rate[0], self.rate[1], 0.0])
        s = self.stance(r.t + g["lead_s"])
        if self.support is None:
            s = np.ones(max(1 + max(self.ankle[1], default=0), 1))

        # tilts within the dead band are the plan's own sway: left to it
        band = np.sign(tilt) * np.maximum(np.abs(tilt) - g["deadband_rad"], 0.0)
        # ankle: the stance feet turn the trunk back; a swing foot is kept level
        idx, legs, axes = self.ankle
        if len(idx):
            w = s[legs]
            push = np.clip(
                axes @ (g["kp_ankle"] * band + g["kd_ankle"] * rate + g["k_level"] * self.floor),
                -g["ankle_limit_rad"],
                g["ankle_limit_rad"],
            )
            level = np.clip(
                -g["kp_swing"] * (axes @ (tilt - self.floor)),
                -g["ankle_limit_rad"],
                g["ankle_limit_rad"],
            )
            out[idx] += w * push + (1 - w) * level
        idx, legs, axes = self.hip
        if len(idx) and (g["kp_hip"] or g["kd_hip"]):
            over = np.sign(tilt) * np.maximum(np.abs(tilt) - g["hip_from_rad"], 0.0)
            u = np.clip(
                axes @ (g["kp_hip"] * over + g["kd_hip"] * rate),
                -g["hip_limit_rad"],
                g["hip_limit_rad"],
            )
            out[idx] += s[legs] * u
        idx, legs, axes = self.yaw
        if len(idx) and g["kp_yaw"] and self.yaw0 is not None:
            err = math.remainder(yaw - self.yaw0 - self.heading(r.t), 2 * math.pi)
            u = np.clip(g["kp_yaw"] * axes[:, 2] * err, -g["yaw_limit_rad"], g["yaw_limit_rad"])
            w = s[legs]
            alone = w * (1 - s[1 - legs]) if len(s) == 2 else w  # one foot down: it turns
            out[idx] += alone * u - (1 - w) * u
        if self.stride is not None and self.step_change:
            tt = self.traj.times
            t = r.t + g["lead_s"]
            out += self.step_change * np.array(
                [np.interp(t, tt, self.stride[:, k]) for k in range(len(self.joints))]
            )
        return np.clip(out, -g["limit_rad"], g["limit_rad"])

    def heading(self, t: float) -> float:
        """rad: the plan's change of heading at ``t`` (0 for a straight or standing plan;
        an arc's planned turn in proportion to the time walked)."""
        turn = self.traj.info.get("planned_pose")
        if not turn or self.traj.info.get("motion") != "arc":
            return 0.0
        return float(turn[2]) * min(max(t / float(self.traj.times[-1]), 0.0), 1.0)
