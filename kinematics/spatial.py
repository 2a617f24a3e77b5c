"""Frames and rigid-body inertia helpers (pytransform3d naming; SI units, numpy only).

Frames are 4x4 homogeneous transforms ``A2B`` that map points in frame A to frame B
(``p_B = A2B @ [p_A, 1]``). Rotations are active 3x3 matrices. Inertia tensors are 3x3,
kg m^2, about the centre of mass unless a function says otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from math import comb, gamma, pi

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


#: Angles (rad) below this are float noise: :func:`rpy_from_matrix` gives them as 0.
RPY_SNAP = 1e-12


def rpy_from_matrix(R: ArrayLike) -> np.ndarray:
    """URDF roll, pitch, yaw (rad) of a rotation (3,3), the inverse of
    :func:`matrix_from_rpy`: ``R = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)``, pitch in
    [-pi/2, pi/2], roll and yaw in (-pi, pi].

    Robust at gimbal lock (pitch = +-pi/2, where only roll - yaw or roll + yaw is defined):
    yaw is set to 0 and the whole rotation about z goes into roll. Angles below
    :data:`RPY_SNAP` are snapped to 0, and -pi is given as pi (one angle). ValueError for a
    matrix that is not a finite rotation (orthonormal with determinant +1, to 1e-6)."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ValueError("a rotation must be a finite (3, 3) matrix")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or abs(np.linalg.det(R) - 1.0) > 1e-6:
        raise ValueError("transform rotation is not orthonormal with determinant +1")
    cp = math.hypot(R[0, 0], R[1, 0])
    pitch = math.atan2(-R[2, 0], cp)
    if cp > 1e-9:
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
    else:  # gimbal lock: only roll - yaw (pitch = pi/2) or roll + yaw (-pi/2) is defined
        roll = math.atan2(-R[1, 2], R[1, 1])
        yaw = 0.0
    out = []
    for a in (roll, pitch, yaw):
        if abs(a) < RPY_SNAP:
            a = 0.0
        elif a <= -pi + RPY_SNAP:  # -pi and pi are one angle: give pi
            a = pi
        out.append(a)
    return np.array(out)


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


# --- the printed link module (paper Fig. 10) ---------------------------------------------
#
# Geometry, in the part frame (the tube axis is the part's axis, x below; all lengths m):
#
# - tube: a hollow cylinder r_inner <= r <= r_outer over 0 <= x <= length;
# - two face plates: squares of side ``face_side`` perpendicular to the axis over
#   0 <= x <= t and length - t <= x <= length (t = ``face_thickness``), centred on the axis,
#   with a central bore of radius r_inner (the tube stays open end to end); the plates lie
#   inside the tube's length, so the overall length stays ``length``;
# - two concave fillet rings of radius f (= ``fillet``) between each plate's inner face and
#   the tube's outside: the rings of revolution whose half-section is the square
#   r_outer <= r <= r_outer + f, t <= x <= t + f (mirrored at the far end) less the disc of
#   radius f centred at (x, r) = (t + f, r_outer + f).
#
# The plates need face_side / 2 > r_outer + f (the fillet stands on the plate) and
# length >= 2 (t + f) (the fillets do not meet). face_side = face_thickness = fillet = 0 is
# the bare tube. The part is symmetric about its mid-length and about the axis (the square
# plates have equal second moments about every in-plane axis), so its inertia about the
# centre of mass is diag(axial, transverse, transverse) in axis-aligned coordinates.

#: Centroid of the fillet's half-section from its corner (r_outer, t), along x and along r,
#: as a fraction of the fillet radius: (10 - 3 pi) / (12 - 3 pi).
FILLET_CENTROID = (10.0 - 3.0 * pi) / (12.0 - 3.0 * pi)


def _cos_sin_integral(i: int, j: int) -> float:
    """Integral of cos^i(t) sin^j(t) over 0 <= t <= pi/2 (a Beta function)."""
    return gamma((i + 1) / 2) * gamma((j + 1) / 2) / (2.0 * gamma((i + j) / 2 + 1))


def _fillet_moment(f: float, a: int, b: int) -> float:
    """Integral of u^a w^b over a fillet's half-section, m^(a+b+2).

    The section is 0 <= u, w <= f outside the disc of radius f centred at (f, f): the
    square's moment less the quarter disc's (polar coordinates about (f, f), exact).
    """
    quarter = sum(
        comb(a, i) * comb(b, j) * (-1) ** (i + j) * _cos_sin_integral(i, j) / (i + j + 2)
        for i in range(a + 1)
        for j in range(b + 1)
    )
    return f ** (a + b + 2) * (1.0 / ((a + 1) * (b + 1)) - quarter)


def check_link_part(
    length: float,
    r_outer: float,
    r_inner: float,
    face_side: float,
    face_thickness: float,
    fillet: float,
) -> bool:
    """ValueError unless these are a valid printed link (m); True if it has face plates."""
    _check_positive(length, "length")
    _check_positive(r_outer, "r_outer")
    _check_positive(r_inner, "r_inner", allow_zero=True)
    if r_inner >= r_outer:
        raise ValueError(f"r_inner ({r_inner}) must be less than r_outer ({r_outer})")
    for x, name in ((face_side, "face_side"), (face_thickness, "face_thickness")):
        _check_positive(x, name, allow_zero=True)
    _check_positive(fillet, "fillet", allow_zero=True)
    plates = face_side > 0 and face_thickness > 0
    if not plates:
        if face_side > 0 or face_thickness > 0 or fillet > 0:
            raise ValueError(
                "a link's face plates need both face_side and face_thickness (and a fillet "
                f"needs plates), got face_side={face_side}, face_thickness={face_thickness}, "
                f"fillet={fillet}"
            )
        return False
    if face_side / 2 <= r_outer + fillet:
        raise ValueError(
            f"face_side/2 ({face_side / 2}) must exceed r_outer + fillet "
            f"({r_outer + fillet}): the tube and its fillet must stand on the face plate"
        )
    if length < 2 * (face_thickness + fillet):
        raise ValueError(
            f"length ({length}) must be at least 2 (face_thickness + fillet) "
            f"({2 * (face_thickness + fillet)}): the plates and fillets must not overlap"
        )
    return True


def link_part_volume(
    length: float,
    r_outer: float,
    r_inner: float,
    face_side: float = 0.0,
    face_thickness: float = 0.0,
    fillet: float = 0.0,
) -> float:
    """Solid volume m^3 of a printed link: tube + two bored face plates + two fillet rings.

    Geometry as described above this function (m). The plates add their square less the
    tube's disc, t (a^2 - pi r_outer^2) each; a fillet ring adds (Pappus) 2 pi R A with
    A = f^2 (1 - pi/4) and R = r_outer + f (10 - 3 pi) / (12 - 3 pi).
    """
    plates = check_link_part(length, r_outer, r_inner, face_side, face_thickness, fillet)
    v = pi * (r_outer**2 - r_inner**2) * length
    if plates:
        v += 2.0 * face_thickness * (face_side**2 - pi * r_outer**2)
        area = fillet**2 * (1.0 - pi / 4.0)
        v += 2.0 * 2.0 * pi * (r_outer + FILLET_CENTROID * fillet) * area
    return float(v)


def link_part_mass_properties(
    density: float,
    length: float,
    r_outer: float,
    r_inner: float,
    face_side: float = 0.0,
    face_thickness: float = 0.0,
    fillet: float = 0.0,
    axis: ArrayLike = (1.0, 0.0, 0.0),
) -> Part:
    """Mass kg, COM (3,) m and inertia (3,3) kg m^2 about the COM of a printed link.

    The part starts at the origin and runs ``length`` m along the unit ``axis``; geometry as
    described above :func:`link_part_volume`; ``density`` kg/m^3. The COM is at mid-length.
    With no plates (all face dimensions 0) it is exactly ``tube_mass`` / ``tube_inertia``.
    """
    plates = check_link_part(length, r_outer, r_inner, face_side, face_thickness, fillet)
    _check_positive(density, "density")
    a = _vec3(axis, "axis")
    a = a / np.linalg.norm(a)
    if not plates:
        m = tube_mass(density, length, r_outer, r_inner)
        return m, 0.5 * length * a, tube_inertia(m, length, r_outer, r_inner, a)
    L, ro, ri, side, t, f = length, r_outer, r_inner, face_side, face_thickness, fillet
    # Each piece: mass, R2 = integral of r^2 dm (r: distance from the axis), X2 = integral
    # of (x - L/2)^2 dm. Axial inertia = sum R2; transverse = sum X2 + sum R2 / 2 (exact for
    # solids of revolution and for the square plates, by their symmetry).
    m_tube = density * pi * (ro**2 - ri**2) * L
    pieces = [(m_tube, m_tube * (ro**2 + ri**2) / 2.0, m_tube * L**2 / 12.0)]
    h = L / 2.0 - t / 2.0  # plate centre from mid-length
    m_box = density * side**2 * t
    m_disc = density * pi * ro**2 * t
    plate = (
        m_box - m_disc,
        m_box * side**2 / 6.0 - m_disc * ro**2 / 2.0,
        (m_box - m_disc) * (t**2 / 12.0 + h**2),
    )
    S = lambda i, j: _fillet_moment(f, i, j)  # noqa: E731  (u along x, w along r)
    g = t - L / 2.0  # the fillet section's corner from mid-length, along x
    two_pi_rho = 2.0 * pi * density
    ring = (
        two_pi_rho * (ro * S(0, 0) + S(0, 1)),
        two_pi_rho * (ro**3 * S(0, 0) + 3 * ro**2 * S(0, 1) + 3 * ro * S(0, 2) + S(0, 3)),
        two_pi_rho
        * (
            g**2 * (ro * S(0, 0) + S(0, 1))
            + 2 * g * (ro * S(1, 0) + S(1, 1))
            + (ro * S(2, 0) + S(2, 1))
        ),
    )
    pieces += [plate, plate, ring, ring]
    m = float(sum(p[0] for p in pieces))
    r2 = sum(p[1] for p in pieces)
    x2 = sum(p[2] for p in pieces)
    aa = np.outer(a, a)
    inertia = (x2 + r2 / 2.0) * (np.eye(3) - aa) + r2 * aa
    return m, 0.5 * L * a, inertia


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
