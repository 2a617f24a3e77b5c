"""Kinematic tree of rigid bodies joined by revolute, continuous or fixed joints.

Every body has exactly one joint, its inbound joint, with ``joints[i].child == i``; joint
``i`` connects body ``joints[i].parent`` (``-1``: the world, a fixed base) to body ``i``.
Bodies are topologically ordered (a parent comes before its children). At ``q = 0`` the
frame of body ``i`` is the joint frame ``parent_frame @ joints[i].origin``; at ``q`` it is
that frame rotated by ``q`` about ``joints[i].axis`` (given in the joint frame).

Units: m, kg, kg m^2, rad, N m. Objects are immutable (read-only arrays); build a new model
with ``dataclasses.replace`` (e.g. new joint limits) and it is validated again.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import pi

import numpy as np

from kinematics.spatial import (
    Part,
    box_inertia,
    combine_parts,
    cross_matrix,
    invert_transform,
    is_rotation,
    matrix_from_axis_angle,
    matrix_from_rpy,
    point_inertia,
    rot_x,
    rot_y,
    rot_z,
    rotate_inertia,
    sphere_inertia,
    transform,
    transform_from,
    transform_from_pq,
    translate_inertia,
    tube_inertia,
    tube_mass,
)

__all__ = [
    "JOINT_KINDS",
    "Body",
    "Joint",
    "Model",
    "Part",
    "box_inertia",
    "combine_parts",
    "cross_matrix",
    "invert_transform",
    "matrix_from_axis_angle",
    "matrix_from_rpy",
    "point_inertia",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotate_inertia",
    "sphere_inertia",
    "transform",
    "transform_from",
    "transform_from_pq",
    "translate_inertia",
    "tube_inertia",
    "tube_mass",
]

#: Joint kinds; "continuous" is a revolute joint without position limits.
JOINT_KINDS = ("revolute", "continuous", "fixed")
#: m/s^2, downwards: the gravity of every model, and MuJoCo's default (the MJCF sets none)
GRAVITY = 9.81
_TOL = 1e-9


def _frozen(x: object, shape: tuple[int, ...], what: str) -> np.ndarray:
    a = np.array(x, dtype=float)
    if a.shape != shape:
        raise ValueError(f"{what} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body: mass kg, COM (3,) m in the body frame, inertia (3,3) kg m^2 about the COM.

    The inertia must be symmetric, positive semi-definite and physically consistent (each
    principal moment at most the sum of the other two); a point mass has zero inertia.
    """

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"body name must be a non-empty string, got {self.name!r}")
        m = float(self.mass)
        if not np.isfinite(m) or m < 0:
            raise ValueError(f"body {self.name!r}: mass must be finite and >= 0, got {self.mass}")
        object.__setattr__(self, "mass", m)
        object.__setattr__(self, "com", _frozen(self.com, (3,), f"body {self.name!r} com"))
        inertia = _frozen(self.inertia, (3, 3), f"body {self.name!r} inertia")
        object.__setattr__(self, "inertia", inertia)
        scale = max(1.0, float(np.abs(inertia).max()))
        if not np.allclose(inertia, inertia.T, atol=_TOL * scale, rtol=0):
            raise ValueError(f"body {self.name!r}: inertia is not symmetric:\n{inertia}")
        eig = np.linalg.eigvalsh(inertia)
        if eig[0] < -_TOL * scale:
            raise ValueError(
                f"body {self.name!r}: inertia is not positive semi-definite "
                f"(principal moments {eig})"
            )
        if eig[2] > eig[0] + eig[1] + 1e-9 * scale:
            raise ValueError(
                f"body {self.name!r}: inertia violates the triangle inequality "
                f"(principal moments {eig}): no rigid body has it"
            )

    @classmethod
    def from_parts(cls, name: str, parts: list[Part] | tuple[Part, ...]) -> Body:
        """A body made of rigid parts ``(mass, com, inertia about com)`` in its frame."""
        mass, com, inertia = combine_parts(parts)
        return cls(name, mass, com, inertia)

    @property
    def spatial_inertia(self) -> np.ndarray:
        """Spatial inertia (6,6) about the body origin, [linear; angular] ordering."""
        c = cross_matrix(self.com)
        m = self.mass
        out = np.zeros((6, 6))
        out[:3, :3] = m * np.eye(3)
        out[:3, 3:] = -m * c
        out[3:, :3] = m * c
        out[3:, 3:] = self.inertia - m * c @ c
        return out

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Body):
            return NotImplemented
        return (
            self.name == other.name
            and self.mass == other.mass
            and np.array_equal(self.com, other.com)
            and np.array_equal(self.inertia, other.inertia)
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class Joint:
    """A joint from body ``parent`` (-1: the world) to body ``child``.

    ``origin`` (4,4): parent body frame -> joint frame at q = 0. ``axis`` (3,): unit vector
    in the joint frame; the child frame is the joint frame rotated by q about it. ``lower``,
    ``upper`` rad (ignored for "continuous"); ``effort`` N m and ``velocity`` rad/s limits
    (0: unknown). ``group``: symmetry class shared by the joints of alike limbs.
    """

    name: str
    parent: int
    child: int
    kind: str
    origin: np.ndarray
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    lower: float = -pi
    upper: float = pi
    effort: float = 0.0
    velocity: float = 0.0
    group: str = ""

    def __post_init__(self) -> None:
        n = self.name
        if not isinstance(n, str) or not n:
            raise ValueError(f"joint name must be a non-empty string, got {n!r}")
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"joint {n!r}: kind {self.kind!r} is not one of {JOINT_KINDS}")
        origin = _frozen(self.origin, (4, 4), f"joint {n!r} origin")
        if not is_rotation(origin[:3, :3], 1e-8) or not np.allclose(origin[3], [0, 0, 0, 1]):
            raise ValueError(f"joint {n!r}: origin is not a rigid transform:\n{origin}")
        object.__setattr__(self, "origin", origin)
        axis = _frozen(self.axis, (3,), f"joint {n!r} axis")
        if abs(np.linalg.norm(axis) - 1.0) > 1e-9:
            raise ValueError(f"joint {n!r}: axis {axis} is not a unit vector")
        object.__setattr__(self, "axis", axis)
        for attr in ("lower", "upper", "effort", "velocity"):
            x = float(getattr(self, attr))
            if np.isnan(x):
                raise ValueError(f"joint {n!r}: {attr} is NaN")
            object.__setattr__(self, attr, x)
        if self.lower > self.upper:
            raise ValueError(f"joint {n!r}: lower ({self.lower}) > upper ({self.upper})")
        if self.effort < 0 or self.velocity < 0:
            raise ValueError(f"joint {n!r}: effort and velocity limits must be >= 0")

    @property
    def movable(self) -> bool:
        """True for revolute and continuous joints (they have a coordinate in q)."""
        return self.kind != "fixed"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Joint):
            return NotImplemented
        return (
            (self.name, self.parent, self.child, self.kind, self.group)
            == (other.name, other.parent, other.child, other.kind, other.group)
            and (self.lower, self.upper, self.effort, self.velocity)
            == (other.lower, other.upper, other.effort, other.velocity)
            and np.array_equal(self.origin, other.origin)
            and np.array_equal(self.axis, other.axis)
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class Model:
    """A kinematic tree: ``bodies[i]`` hangs on ``joints[i]``; gravity (3,) m/s^2 in the world.

    ``nq == nv`` is the number of movable (revolute/continuous) joints; ``q_index[i]`` is
    joint i's index in q (-1 for fixed joints) and ``q_joints[k]`` the joint of q[k], in
    joint order.
    """

    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -GRAVITY]))
    nq: int = field(init=False)
    nv: int = field(init=False)
    q_index: tuple[int, ...] = field(init=False)
    q_joints: tuple[int, ...] = field(init=False)
    _cache: dict = field(init=False, repr=False, compare=False, default_factory=dict)

    def __post_init__(self) -> None:
        bodies, joints = tuple(self.bodies), tuple(self.joints)
        object.__setattr__(self, "bodies", bodies)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "gravity", _frozen(self.gravity, (3,), "gravity"))
        if not bodies:
            raise ValueError("a model needs at least one body")
        if len(bodies) != len(joints):
            raise ValueError(f"one joint per body: {len(bodies)} bodies but {len(joints)} joints")
        for b in bodies:
            if not isinstance(b, Body):
                raise ValueError(f"bodies must be Body objects, got {type(b).__name__}")
        for j in joints:
            if not isinstance(j, Joint):
                raise ValueError(f"joints must be Joint objects, got {type(j).__name__}")
        for names, what in ((bodies, "body"), (joints, "joint")):
            seen: set[str] = set()
            for x in names:
                if x.name in seen:
                    raise ValueError(f"duplicate {what} name {x.name!r}")
                seen.add(x.name)
        q_index, q_joints = [], []
        for i, j in enumerate(joints):
            if j.child != i:
                raise ValueError(
                    f"joint {j.name!r} is joint {i} so its child must be body {i}, got {j.child}"
                )
            if not -1 <= j.parent < i:
                raise ValueError(
                    f"joint {j.name!r}: parent {j.parent} must be -1 (world) or a body before "
                    f"{i} (bodies are topologically ordered)"
                )
            if j.movable:
                q_index.append(len(q_joints))
                q_joints.append(i)
            else:
                q_index.append(-1)
        object.__setattr__(self, "q_index", tuple(q_index))
        object.__setattr__(self, "q_joints", tuple(q_joints))
        object.__setattr__(self, "nq", len(q_joints))
        object.__setattr__(self, "nv", len(q_joints))
        object.__setattr__(self, "_cache", {})

    @property
    def nbodies(self) -> int:
        """Number of bodies (== number of joints)."""
        return len(self.bodies)

    @property
    def total_mass(self) -> float:
        """Sum of the body masses, kg."""
        return float(sum(b.mass for b in self.bodies))

    @property
    def parents(self) -> tuple[int, ...]:
        """Parent body index of each body (-1: the world)."""
        return tuple(j.parent for j in self.joints)

    @property
    def q_names(self) -> tuple[str, ...]:
        """Joint name of each coordinate of q."""
        return tuple(self.joints[i].name for i in self.q_joints)

    @property
    def lower(self) -> np.ndarray:
        """Lower position limits (nv,) rad; -inf for continuous joints."""
        return np.array([self._limit(i, True) for i in self.q_joints])

    @property
    def upper(self) -> np.ndarray:
        """Upper position limits (nv,) rad; +inf for continuous joints."""
        return np.array([self._limit(i, False) for i in self.q_joints])

    def _limit(self, i: int, low: bool) -> float:
        j = self.joints[i]
        if j.kind == "continuous":
            return -np.inf if low else np.inf
        return j.lower if low else j.upper

    def body(self, name: str) -> int:
        """Index of the body called ``name``; ValueError listing the names if there is none."""
        for i, b in enumerate(self.bodies):
            if b.name == name:
                return i
        raise ValueError(f"no body {name!r}; bodies: {', '.join(b.name for b in self.bodies)}")

    def joint(self, name: str) -> int:
        """Index of the joint called ``name``; ValueError listing the names if there is none."""
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise ValueError(f"no joint {name!r}; joints: {', '.join(j.name for j in self.joints)}")

    def ancestors(self, body: int) -> tuple[int, ...]:
        """Bodies from the root down to ``body`` (inclusive)."""
        chain = []
        while body >= 0:
            chain.append(body)
            body = self.joints[body].parent
        return tuple(reversed(chain))

    def subtree(self, body: int) -> tuple[int, ...]:
        """``body`` and every body below it, in index order."""
        inside = {body}
        for i in range(body + 1, self.nbodies):
            if self.joints[i].parent in inside:
                inside.add(i)
        return tuple(sorted(inside))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Model):
            return NotImplemented
        return (
            self.bodies == other.bodies
            and self.joints == other.joints
            and np.array_equal(self.gravity, other.gravity)
        )

    __hash__ = None  # type: ignore[assignment]
