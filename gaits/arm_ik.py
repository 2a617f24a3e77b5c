"""Numerical inverse kinematics of any serial chain (issue 21): the path of joints from a
kinematic model's root to an end body (a gripper), whatever its joints' count and axes.

:func:`serial_chain` reads the chain off a :class:`kinematics.model.Model`; its forward
kinematics and Jacobian are computed here on the chain alone (a product of the joints'
fixed origins and rotations), so that an IK iteration costs one walk along the chain.

:func:`solve_ik` is a task-priority damped least squares with joint limits:

1. the *primary* task: the end point at a position (3 rows) and, when asked, the tool
   frame at a rotation (3 more rows); it decides convergence;
2. an optional *secondary* task in the primary's null space: the tool axis pointing
   along a direction (e.g. down for grasping from above), as far as the chain allows it
   (a chain of 4 pitch-and-yaw joints points down at most targets, one of 3 joints not);
3. a *tertiary* gradient in what null space is left (a redundant chain): down the
   limit-distance cost (:func:`limit_cost`: a joint past ``LIMIT_BAND`` of its half range
   is pushed back towards the middle), so a redundant arm stays away from its limits.

Each step is the damped pseudo-inverse of the free joints' Jacobian (SVD, damping
``DAMPING``), at most ``MAX_STEP`` rad per joint, clipped to the limits; a joint on a limit
that the step pushes further out is locked there and the step recomputed without it (an
active set), so no iterate leaves the limits. Several starts are tried in a fixed order (the given
configuration, then configurations drawn inside the limits by a generator seeded with a
constant): the answer depends on nothing but the arguments (same input, same bytes).

What a chain can do is read from it, never from its joint count: :func:`chain_rank` is the
rank of its Jacobian at generic configurations (3: it places a point; 6: it also orients
the tool in every way; 4 or 5: some orientation freedom).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from kinematics.model import Model

__all__ = [
    "SerialChain",
    "chain_rank",
    "limit_cost",
    "rotation_error",
    "serial_chain",
    "solve_ik",
]

#: Damping of the least-squares steps (singular values below it are attenuated).
DAMPING = 1e-3
#: Largest change rad of one joint in one iteration.
MAX_STEP = 0.2
#: Gain of the tertiary step towards the middle of the joints' ranges, per iteration.
LIMIT_GAIN = 0.2
#: The tertiary task acts on a joint past this fraction of its half range from the middle:
#: nearer the middle a redundant arm keeps the posture it started from (pulling every
#: joint to the middle would turn a 7-joint arm's elbow aside for nothing).
LIMIT_BAND = 0.85
#: Configurations drawn inside the limits after the given start, in this order.
RESTARTS = 16
#: Seed of the generator that draws the restarts (a constant: the answer is reproducible).
SEED = 20240521
#: Singular values below this fraction of the largest count as zero (rank, null spaces).
RANK_TOL = 1e-6


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation (3, 3) by ``angle`` rad about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array(
        [
            [c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C],
        ]
    )


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of (..., 3) arrays (numpy's cross is slow on small arrays)."""
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(a.shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def rotation_error(R: np.ndarray, Rd: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) rad, world axes, that turns ``R`` into ``Rd``."""
    E = Rd @ R.T
    angle = math.acos(min(1.0, max(-1.0, (np.trace(E) - 1) / 2)))
    v = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    if angle < 1e-9:
        return v / 2
    if math.pi - angle < 1e-6:  # half turn: the axis from the symmetric part
        k = int(np.argmax(np.diag(E)))
        axis = (E[:, k] + np.eye(3)[:, k]) / math.sqrt(2 * (1 + E[k, k]))
        return angle * axis
    return angle * v / (2 * math.sin(angle))


@dataclass(frozen=True, eq=False)
class SerialChain:
    """The joints from a model's root to its end body.

    ``joints``: the movable joints' names, root first (the end body's own joint excluded:
    it turns about the end point, e.g. a gripper's fingers); ``q_index``: their places in
    the model's q; ``lower``, ``upper`` (n,) rad; ``end_body``: the body whose origin is
    the end point; ``tool_body``: the body it hangs on (its frame is the tool frame);
    ``tool_axis`` (3,): the chain's last link's direction in the tool frame (the direction
    from the last joint off the end point to it, at q = 0), the axis a tool points along;
    ``tool_offset`` (3,) m: the end point in the tool frame.
    """

    joints: tuple[str, ...]
    q_index: tuple[int, ...]
    lower: np.ndarray
    upper: np.ndarray
    end_body: str
    tool_body: str
    tool_axis: np.ndarray
    tool_offset: np.ndarray
    #: per body on the path, root first: (origin (4, 4), axis (3,) or None, arm index or -1)
    steps: tuple[tuple[np.ndarray, np.ndarray | None, int], ...]
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return len(self.joints)

    def frames(self, q: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At the arm configuration ``q`` (n,): end point (3,), tool rotation (3, 3), each
        joint's world axis (n, 3) and origin (n, 3), in the root frame."""
        q = np.asarray(q, dtype=float)
        R, p = np.eye(3), np.zeros(3)
        axes, origins = np.zeros((self.n, 3)), np.zeros((self.n, 3))
        R_tool = R
        for k, (origin, axis, i) in enumerate(self.steps):
            p = p + R @ origin[:3, 3]
            R = R @ origin[:3, :3]
            if k == len(self.steps) - 1:
                break  # the end body: its own joint turns about the end point
            if i >= 0:
                axes[i] = R @ axis
                origins[i] = p
                R = R @ _rot(axis, float(q[i]))
            R_tool = R
        return p, R_tool, axes, origins

    def forward(self, q: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """(end point (3,), tool rotation (3, 3)) at ``q`` (n,)."""
        p, R, _, _ = self.frames(q)
        return p, R

    def jacobian(self, q: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(J (6, n): linear velocity of the end point and angular velocity of the tool,
        world axes; end point; tool rotation) at ``q``."""
        p, R, axes, origins = self.frames(q)
        J = np.zeros((6, self.n))
        J[:3] = _cross(axes, p - origins).T
        J[3:] = axes.T
        return J, p, R

    def shoulder(self) -> tuple[np.ndarray, float]:
        """Cached :meth:`_shoulder`."""
        got = self._cache.get("shoulder")
        if got is None:
            got = self._cache["shoulder"] = self._shoulder()
        return got[0].copy(), got[1]

    def _shoulder(self) -> tuple[np.ndarray, float]:
        """(a point fixed in the root frame whatever q, the farthest the end point can be
        from it m): the deepest joint origin that lies on the axes of all the joints
        before it (a serial arm's shoulder, on its base's vertical axis), and the sum of
        the lengths between the joint origins after it and the end point."""
        q0 = np.clip(np.zeros(self.n), self.lower, self.upper)
        p, _, axes, origins = self.frames(q0)
        points = [*origins, p]
        anchor = 0
        for s in range(1, self.n):
            on_axes = all(
                np.linalg.norm(np.cross(axes[j], points[s] - origins[j])) < 1e-9 for j in range(s)
            )
            if not on_axes:
                break
            anchor = s
        reach = sum(
            float(np.linalg.norm(b - a))
            for a, b in zip(points[anchor:], points[anchor + 1 :], strict=False)
        )
        return points[anchor].copy(), reach

    def tool_length(self) -> float:
        """The distance m from the end point to the last joint that moves the tool axis
        (at q = 0; joints turning about the tool axis itself, a tool roll, are passed
        over): how far above a target a tool pointing down at it holds its wrist."""
        q0 = np.clip(np.zeros(self.n), self.lower, self.upper)
        p, R, axes, origins = self.frames(q0)
        t = R @ self.tool_axis
        for a, o in zip(axes[::-1], origins[::-1], strict=True):
            on_line = (
                np.linalg.norm(_cross(a, t)) < 1e-9 and np.linalg.norm(_cross(o - p, t)) < 1e-9
            )
            if not on_line:
                return float(np.linalg.norm(p - o))
        return 0.0


def serial_chain(model: Model, end_body: str) -> SerialChain:
    """The serial chain of ``model`` from its root to ``end_body`` (ValueError when the
    path has no movable joint, or a joint other than a revolute or continuous one)."""
    e = model.body(end_body)
    path = []
    b = e
    while b >= 0:
        path.append(b)
        b = model.joints[b].parent
    path.reverse()
    names, qidx, lo, hi, steps = [], [], [], [], []
    qn = model.q_names
    for b in path:
        j = model.joints[b]
        i = -1
        if j.movable and b != e:
            if j.kind not in ("revolute", "continuous"):
                raise ValueError(f"joint {j.name!r} of the chain to {end_body} is {j.kind}")
            i = len(names)
            names.append(j.name)
            qidx.append(qn.index(j.name))
            lo.append(j.lower if j.kind == "revolute" else -math.inf)
            hi.append(j.upper if j.kind == "revolute" else math.inf)
        steps.append((np.array(j.origin), np.array(j.axis) if i >= 0 else None, i))
    if not names:
        raise ValueError(f"no movable joint between {model.bodies[0].name} and {end_body}")
    tool = model.bodies[model.joints[e].parent].name
    chain = SerialChain(
        tuple(names),
        tuple(qidx),
        np.array(lo),
        np.array(hi),
        end_body,
        tool,
        np.array([1.0, 0.0, 0.0]),
        np.zeros(3),
        tuple(steps),
    )
    q0 = np.clip(np.zeros(chain.n), chain.lower, chain.upper)
    p, R, _, origins = chain.frames(q0)
    last = next((o for o in origins[::-1] if np.linalg.norm(p - o) > 1e-9), None)
    if last is not None:
        object.__setattr__(chain, "tool_axis", R.T @ ((p - last) / np.linalg.norm(p - last)))
    object.__setattr__(chain, "tool_offset", np.array(steps[-1][0][:3, 3]))
    return chain


def chain_rank(chain: SerialChain, position_only: bool = False) -> int:
    """The rank of the chain's Jacobian (6 rows, or its 3 position rows) at generic
    configurations (the largest over three drawn inside the limits)."""
    rng = np.random.default_rng(SEED)
    lo, hi = _finite_limits(chain)
    best = 0
    for _ in range(3):
        q = lo + rng.random(chain.n) * (hi - lo)
        J, _, _ = chain.jacobian(q)
        s = np.linalg.svd(J[:3] if position_only else J, compute_uv=False)
        best = max(best, int(np.sum(s > RANK_TOL * max(1.0, float(s[0])))))
    return best


def _finite_limits(chain: SerialChain) -> tuple[np.ndarray, np.ndarray]:
    lo = np.where(np.isfinite(chain.lower), chain.lower, -math.pi)
    hi = np.where(np.isfinite(chain.upper), chain.upper, math.pi)
    return lo, hi


def _excess(q: np.ndarray, mid: np.ndarray, span: np.ndarray) -> np.ndarray:
    """How far each joint is past ``LIMIT_BAND`` of its half range from the middle (signed,
    0 inside the band): the gradient of the limit-distance cost ``limit_cost``/2."""
    d = q - mid
    edge = LIMIT_BAND * span / 2
    out = np.zeros_like(d)
    m = np.isfinite(edge) & (np.abs(d) > edge)
    out[m] = d[m] - np.sign(d[m]) * edge[m]
    return out


def limit_cost(chain: SerialChain, q: Sequence[float]) -> float:
    """The limit-distance cost the tertiary task lowers: the sum over joints of
    ``(pi / range)^2 * excess^2``, the excess being how far a joint is past
    ``LIMIT_BAND`` of its half range from the middle (0 for continuous joints)."""
    lo, hi = chain.lower, chain.upper
    finite = np.isfinite(lo) & np.isfinite(hi)
    mid = np.where(finite, (lo + hi) / 2, 0.0)
    span = np.where(finite, hi - lo, math.inf)
    x = _excess(np.asarray(q, dtype=float), mid, span)
    return float(np.sum((math.pi / span) ** 2 * x * x))


def _pinv_step(J: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(damped least-squares step J# e, the projector onto J's null space)."""
    n = J.shape[1]
    if J.size == 0 or not np.any(J):
        return np.zeros(n), np.eye(n)
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    step = Vt.T @ ((s / (s * s + DAMPING**2)) * (U.T @ e))
    r = int(np.sum(s > RANK_TOL * max(1.0, float(s[0]))))
    N = np.eye(n) - Vt[:r].T @ Vt[:r]
    return step, N


@dataclass
class _Result:
    q: np.ndarray
    error: float  # primary position error m
    angle: float  # primary orientation error rad (0 without rotation)
    converged: bool


def _descend(
    chain: SerialChain,
    target: np.ndarray,
    rotation: np.ndarray | None,
    pointing: np.ndarray | None,
    q: np.ndarray,
    tol: float,
    max_iter: int,
    refine: int,
    gain: float,
) -> _Result:
    """Task-priority damped least squares from ``q`` (see the module docstring)."""
    lo, hi = chain.lower, chain.upper
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), (lo + hi) / 2, 0.0)
    span = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo, math.inf)
    weight = (math.pi / span) ** 2  # 1 for a joint of +-pi/2, 0 for a continuous one
    q = np.clip(q.astype(float), lo, hi)
    after = 0
    err = ang = math.inf
    for _ in range(max_iter):
        J, p, R = chain.jacobian(q)
        e = target - p
        rows = [J[:3]]
        errs = [e]
        err = float(np.linalg.norm(e))
        ang = 0.0
        if rotation is not None:
            w = rotation_error(R, rotation)
            ang = float(np.linalg.norm(w))
            rows.append(J[3:])
            errs.append(w)
        done = err < tol and ang < tol
        if done:
            after += 1
            if after > refine:
                break
        J1, e1 = np.vstack(rows), np.concatenate(errs)
        if pointing is not None:
            a = R @ chain.tool_axis
            c = _cross(a, pointing)
            s, cos = float(np.linalg.norm(c)), float(a @ pointing)
            th = math.atan2(s, cos)
            if s > 1e-12:
                e2 = th * c / s
            elif cos < 0:  # opposite: turn about any axis across the tool's
                ref = np.eye(3)[int(np.argmin(np.abs(a)))]
                perp = _cross(a, ref)
                e2 = math.pi * perp / np.linalg.norm(perp)
            else:
                e2 = np.zeros(3)
            P = np.eye(3) - np.outer(a, a)
            J2 = P @ J[3:]
        free = np.ones(chain.n, dtype=bool)
        step = np.zeros(chain.n)
        for _ in range(chain.n + 1):
            mask = free.astype(float)
            A1 = J1 * mask
            dq, N = _pinv_step(A1, e1)
            N = N * mask[:, None] * mask[None, :]
            if pointing is not None:
                B = (J2 * mask) @ N
                d2, N2 = _pinv_step(B, e2 - (J2 * mask) @ dq)
                dq = dq + N @ d2
                N = N @ N2
            dq = dq + N @ (-gain * weight * _excess(q, mid, span))
            dq = dq * mask
            big = float(np.max(np.abs(dq)))
            if big > MAX_STEP:
                dq = dq * (MAX_STEP / big)
            # a joint on a limit that the step pushes further out is locked there and
            # the step recomputed without it; one short of it stops on it (the clip)
            out = free & (((q <= lo + 1e-12) & (dq < 0)) | ((q >= hi - 1e-12) & (dq > 0)))
            step = dq
            if not np.any(out):
                break
            free &= ~out
        q = np.clip(q + step, lo, hi)
        if done and float(np.max(np.abs(step))) < 1e-10:
            break
    p, R = chain.forward(q)
    err = float(np.linalg.norm(target - p))
    ang = 0.0 if rotation is None else float(np.linalg.norm(rotation_error(R, rotation)))
    return _Result(q, err, ang, err < tol and ang < tol)


def solve_ik(
    chain: SerialChain,
    position: Sequence[float],
    rotation: np.ndarray | None = None,
    pointing: Sequence[float] | None = None,
    q0: Sequence[float] | None = None,
    *,
    tol: float = 1e-7,
    max_iter: int = 200,
    refine: int = 50,
    restarts: int = RESTARTS,
    score: Callable[[np.ndarray], float] | None = None,
    avoid_limits: bool = True,
) -> np.ndarray:
    """Arm configuration (n,) rad, inside the joint limits, that puts the chain's end point
    at ``position`` (3,) m (root frame) and, if given, the tool frame at ``rotation``
    (3, 3); the tool axis as near ``pointing`` (3,) as the chain allows (secondary); the
    joints as far from their limits as what is left free allows (tertiary,
    :func:`limit_cost`).

    Starts from ``q0`` (default: the middle of the ranges; its solution is returned when
    it converges and ``score`` is None), then from ``restarts`` configurations drawn
    inside the limits by a generator of constant seed; of the converged solutions the one
    of least ``score`` (default: the distance from ``q0``) is returned, the first one on a
    tie. ``refine``: iterations spent on the secondary and tertiary tasks once the primary
    one is met. ``avoid_limits``: False drops the tertiary task (for comparison). ValueError,
    naming the target and why, when no start converges.
    """
    target = np.asarray(position, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise ValueError(f"target must be 3 finite numbers, got {position!r}")
    Rd = None
    if rotation is not None:
        Rd = np.asarray(rotation, dtype=float)
        if Rd.shape != (3, 3) or not np.allclose(Rd.T @ Rd, np.eye(3), atol=1e-6):
            raise ValueError("rotation must be a (3, 3) rotation matrix")
    d = None
    if pointing is not None:
        d = np.asarray(pointing, dtype=float)
        d = d / np.linalg.norm(d)
    where = f"({', '.join(f'{c:.4f}' for c in target)}) m"
    anchor, reach = chain.shoulder()
    dist = float(np.linalg.norm(target - anchor))
    if dist > reach * (1 + 1e-9) + 1e-12:
        raise ValueError(
            f"cannot reach {where}: it is {dist:.4f} m from the shoulder at "
            f"({', '.join(f'{c:.4f}' for c in anchor)}); the arm reaches {reach:.4f} m from it"
        )
    lo, hi = _finite_limits(chain)
    start = (lo + hi) / 2 if q0 is None else np.asarray(q0, dtype=float)

    def seeds():
        yield start
        rng = np.random.default_rng(SEED)
        for _ in range(restarts):
            yield lo + (0.05 + 0.9 * rng.random(chain.n)) * (hi - lo)

    def dist_from_start(q: np.ndarray) -> float:
        return float(np.sum((q - start) ** 2))

    key = score or dist_from_start
    best, best_key, nearest = None, math.inf, math.inf
    gain = LIMIT_GAIN if avoid_limits else 0.0
    # the pointing is a wish: where it drives the joints into limits that keep the
    # gripper off its target, the starts are tried again without it
    for wish in (d, None) if d is not None else (None,):
        for k, s in enumerate(seeds()):
            r = _descend(chain, target, Rd, wish, s, tol, max_iter, refine, gain)
            nearest = min(nearest, r.error)
            if not r.converged:
                continue
            if k == 0 and score is None:
                return r.q
            v = key(r.q)
            if v < best_key - 1e-12:
                best, best_key = r.q, v
        if best is not None:
            break
    if best is None:
        what = " with the tool at the rotation asked" if Rd is not None else ""
        raise ValueError(
            f"cannot reach {where}{what}: no configuration inside the joint limits of "
            f"{', '.join(chain.joints)} does (the nearest came {nearest * 1000:.1f} mm from it)"
        )
    return best
