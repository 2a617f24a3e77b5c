"""Frames and rigid-body inertia helpers (pytransform3d naming; SI units, numpy only).

Frames are 4x4 homogeneous transforms ``A2B`` that map points in frame A to frame B
(``p_B = A2B @ [p_A, 1]``). Rotations are active 3x3 matrices. Inertia tensors are 3x3,
kg m^2, about the centre of mass unless a function says otherwise.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

ArrayLike = Sequence[float] | np.ndarray

#: One rigid part of a body: (mass kg, centre of mass (3,) m, inertia (3,3) kg m^2 about it).
Part = tuple[float, np.ndarray, np.ndarray]


def _vec3(x: ArrayLike, name: str) -> np.ndarray:
    v = np.asarray(x, dtype=float)
    if v.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def rot_x(angle: float) -> np.ndarray:
    """Rotation (3,3) by ``angle`` rad about x."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Rotation (3,3) by ``angle`` rad about y."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """Rotation (3,3) by ``angle`` rad about z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def matrix_from_rpy(rpy: ArrayLike) -> np.ndarray:
    """Rotation (3,3) from URDF roll-pitch-yaw (rad): ``rot_z(y) @ rot_y(p) @ rot_x(r)``."""
    r, p, y = _vec3(rpy, "rpy")
    return rot_z(y) @ rot_y(p) @ rot_x(r)


def matrix_from_axis_angle(axis: ArrayLike, angle: float) -> np.ndarray:
    """Rotation (3,3) by ``angle`` rad about the unit vector ``axis`` (Rodrigues)."""
    a = _vec3(axis, "axis")
    n = np.linalg.norm(a)
    if n == 0.0:
        raise ValueError("axis must be non-zero")
    a = a / n
    k = cross_matrix(a)
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def cross_matrix(v: ArrayLike) -> np.ndarray:
    """Skew matrix (3,3) with ``cross_matrix(v) @ w == np.cross(v, w)``."""
    x, y, z = _vec3(v, "v")
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def transform_from(R: np.ndarray, p: ArrayLike) -> np.ndarray:
    """Transform (4,4) from a rotation (3,3) and a translation (3,) m."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"R must have shape (3, 3), got {R.shape}")
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = _vec3(p, "p")
    return T


def transform(xyz: ArrayLike = (0.0, 0.0, 0.0), rpy: ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Transform (4,4) from a URDF-style origin: translation ``xyz`` m, rotation ``rpy`` rad."""
    return transform_from(matrix_from_rpy(rpy), xyz)


def transform_from_pq(pq: ArrayLike) -> np.ndarray:
    """Transform (4,4) from position and unit quaternion ``(x, y, z, qw, qx, qy, qz)``."""
    v = np.asarray(pq, dtype=float)
    if v.shape != (7,):
        raise ValueError(f"pq must have shape (7,), got {v.shape}")
    w, x, y, z = v[3:] / np.linalg.norm(v[3:])
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    return transform_from(R, v[:3])


def invert_transform(A2B: np.ndarray) -> np.ndarray:
    """The inverse (4,4) ``B2A`` of a rigid transform."""
    T = np.asarray(A2B, dtype=float)
    R, p = T[:3, :3], T[:3, 3]
    return transform_from(R.T, -R.T @ p)


def is_rotation(R: np.ndarray, tol: float = 1e-9) -> bool:
    """True if ``R`` (3,3) is orthonormal with determinant +1 (to ``tol``)."""
    R = np.asarray(R, dtype=float)
    return (
        R.shape == (3, 3)
        and bool(np.all(np.isfinite(R)))
        and np.allclose(R.T @ R, np.eye(3), atol=tol)
        and abs(np.linalg.det(R) - 1.0) < tol
    )


# --- inertia ------------------------------------------------------------------------------


def point_inertia(mass: float) -> np.ndarray:
    """Inertia (3,3) of a point mass about itself: zero."""
    _check_mass(mass)
    return np.zeros((3, 3))


def sphere_inertia(mass: float, radius: float) -> np.ndarray:
    """Inertia (3,3) kg m^2 of a solid sphere of ``radius`` m about its centre."""
    _check_mass(mass)
    _check_positive(radius, "radius", allow_zero=True)
    return 0.4 * mass * radius**2 * np.eye(3)


def box_inertia(mass: float, size: ArrayLike) -> np.ndarray:
    """Inertia (3,3) kg m^2 of a solid box of edge lengths ``size`` (x, y, z) m about its centre."""
    _check_mass(mass)
    x, y, z = _vec3(size, "size")
    if min(x, y, z) < 0:
        raise ValueError(f"box size must be non-negative, got {(x, y, z)}")
    return mass / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])


def tube_inertia(
    mass: float, length: float, r_outer: float, r_inner: float, axis: ArrayLike = (0, 0, 1)
) -> np.ndarray:
    """Inertia (3,3) kg m^2 of a hollow cylinder about its centre; its axis along ``axis``.

    ``length``, ``r_outer`` and ``r_inner`` in m with ``0 <= r_inner <= r_outer``
    (``r_inner = 0``: a solid cylinder).
    """
    _check_mass(mass)
    _check_positive(length, "length", allow_zero=True)
    _check_positive(r_outer, "r_outer", allow_zero=True)
    _check_positive(r_inner, "r_inner", allow_zero=True)
    if r_inner > r_outer:
        raise ValueError(f"r_inner ({r_inner}) must not exceed r_outer ({r_outer})")
    a = _vec3(axis, "axis")
    a = a / np.linalg.norm(a)
    r2 = r_outer**2 + r_inner**2
    i_axial = 0.5 * mass * r2
    i_trans = mass * (3.0 * r2 + length**2) / 12.0
    aa = np.outer(a, a)
    return i_trans * (np.eye(3) - aa) + i_axial * aa


def tube_mass(density: float, length: float, r_outer: float, r_inner: float) -> float:
    """Mass kg of a hollow cylinder: ``density`` kg/m^3 x pi (r_outer^2 - r_inner^2) x length."""
    return float(density * np.pi * (r_outer**2 - r_inner**2) * length)


def rotate_inertia(R: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """Inertia (3,3) expressed in a frame rotated by ``R``: ``R @ I @ R.T``."""
    return R @ np.asarray(inertia, dtype=float) @ R.T


def translate_inertia(inertia: np.ndarray, mass: float, offset: ArrayLike) -> np.ndarray:
    """Parallel axis theorem: inertia (3,3) about a point ``offset`` m away from the COM."""
    d = _vec3(offset, "offset")
    return np.asarray(inertia, dtype=float) + mass * (d @ d * np.eye(3) - np.outer(d, d))


def combine_parts(parts: Iterable[Part]) -> Part:
    """One rigid part from several: total mass kg, its COM (3,) m, inertia (3,3) about it.

    Each part is (mass, com, inertia about its own com), all in the same frame. An empty or
    massless set gives (0, origin, zero).
    """
    items = [(float(m), _vec3(c, "com"), np.asarray(i, dtype=float)) for m, c, i in parts]
    for m, _, i in items:
        _check_mass(m)
        if i.shape != (3, 3):
            raise ValueError(f"inertia must have shape (3, 3), got {i.shape}")
    total = sum(m for m, _, _ in items)
    if total <= 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = sum(m * c for m, c, _ in items) / total
    inertia = sum(translate_inertia(i, m, c - com) for m, c, i in items)
    inertia = 0.5 * (inertia + inertia.T)
    return total, com, inertia


def _check_mass(mass: float) -> None:
    if not np.isfinite(mass) or mass < 0:
        raise ValueError(f"mass must be finite and non-negative, got {mass}")


def _check_positive(x: float, name: str, allow_zero: bool = False) -> None:
    ok = np.isfinite(x) and (x >= 0 if allow_zero else x > 0)
    if not ok:
        raise ValueError(f"{name} must be {'non-negative' if allow_zero else 'positive'}, got {x}")
