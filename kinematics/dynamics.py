"""Batched rigid-body kinematics and dynamics of a :class:`~kinematics.model.Model`.

Names follow pinocchio. Every function takes configurations ``q`` (and velocities ``v``,
accelerations ``a``) of shape ``(nv,)`` or ``(B, nv)``; results have a leading batch
dimension ``B`` when any input had one and none for 1-D inputs. A batch of one broadcasts
against the others. Units: rad, rad/s, rad/s^2, m, N, N m.

Spatial vectors are ``[linear; angular]`` (pinocchio's order). A wrench on a body is
``[force; moment about the body-frame origin]`` expressed in the body frame.

Implementation: Featherstone's recursive algorithms in body coordinates, vectorised over
the batch (loops run over bodies or tree levels, never over configurations). Each body is
handled in an internal frame, its body frame turned so that the joint axis is +z: the
joint rotation then only mixes x and y components, and the per-body constants (6x6
transforms, spatial inertias) are precomputed once per model and cached on it. The RNEA
processes all bodies at one depth of the tree together (the legs of a hexapod in one
go), on chunks of ``CHUNK`` configurations with preallocated scratch arrays; arrays are
component-first, ``(..., 6, n)``, so every numpy call runs over long contiguous rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.model import Model
from kinematics.spatial import cross_matrix

__all__ = [
    "center_of_mass",
    "external_force_at",
    "forward_kinematics",
    "gravity_torques",
    "jacobian",
    "joint_wrenches",
    "mass_matrix",
    "nonlinear_effects",
    "rnea",
]

#: Configurations per chunk: big enough to amortise numpy call overhead, small enough that a
#: chunk's arrays stay in cache.
CHUNK = 2048


# --- per-model constants ---------------------------------------------------------------------


@dataclass(frozen=True)
class _Plan:
    """Constants of a model in internal frames (joint axis = +z)."""

    n: int
    parent: tuple[int, ...]
    qi: tuple[int, ...]  # index in q, -1 for fixed joints
    C: tuple[np.ndarray, ...]  # (3,3) internal frame -> body frame rotation
    KR: tuple[np.ndarray, ...]  # (3,3) rotation parent' -> child' before the joint rotation
    Kp: tuple[np.ndarray, ...]  # (3,) child' origin in parent' coordinates
    XK: tuple[np.ndarray, ...]  # (6,6) motion transform parent' -> child' (before joint)
    XKT: tuple[np.ndarray, ...]  # (6,6) force transform child' -> parent' (after joint)
    I6: tuple[np.ndarray, ...]  # (6,6) spatial inertia about the origin, internal frame
    C6: tuple[np.ndarray, ...]  # (6,6) internal -> body frame for spatial vectors
    C6T: tuple[np.ndarray, ...]  # (6,6) body -> internal frame
    mass: np.ndarray  # (n,)
    com: tuple[np.ndarray, ...]  # (3,) COM in internal frames
    moving: tuple[int, ...]  # movable bodies in order


def _axis_to_z(axis: np.ndarray) -> np.ndarray:
    """A rotation C (3,3) with ``C @ e_z == axis``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(axis @ z)
    if c > 1.0 - 1e-15:
        return np.eye(3)
    if c < -1.0 + 1e-15:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(z, axis)
    s = np.linalg.norm(k)
    k = k / s
    K = cross_matrix(k)
    C = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    return C


def _motion_transform(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(6,6) motion transform into a frame at ``p`` rotated by ``R`` (both in the old frame)."""
    X = np.zeros((6, 6))
    X[:3, :3] = R.T
    X[:3, 3:] = -R.T @ cross_matrix(p)
    X[3:, 3:] = R.T
    return X


def _plan(model: Model) -> _Plan:
    plan = model._cache.get("plan")
    if plan is not None:
        return plan
    n = model.nbodies
    C, KR, Kp, XK, XKT, I6, C6, C6T, com = [], [], [], [], [], [], [], [], []
    for i, (b, j) in enumerate(zip(model.bodies, model.joints, strict=True)):
        Ci = _axis_to_z(j.axis) if j.movable else np.eye(3)
        Cp = C[j.parent] if j.parent >= 0 else np.eye(3)
        R = Cp.T @ j.origin[:3, :3] @ Ci
        p = Cp.T @ j.origin[:3, 3]
        C.append(Ci)
        KR.append(R)
        Kp.append(p)
        X = _motion_transform(R, p)
        XK.append(np.ascontiguousarray(X))
        XKT.append(np.ascontiguousarray(X.T))
        c = Ci.T @ b.com
        com.append(c)
        S = cross_matrix(c)
        inertia = np.zeros((6, 6))
        inertia[:3, :3] = b.mass * np.eye(3)
        inertia[:3, 3:] = -b.mass * S
        inertia[3:, :3] = b.mass * S
        inertia[3:, 3:] = Ci.T @ b.inertia @ Ci - b.mass * S @ S
        I6.append(inertia)
        c6 = np.zeros((6, 6))
        c6[:3, :3] = Ci
        c6[3:, 3:] = Ci
        C6.append(c6)
        C6T.append(np.ascontiguousarray(c6.T))
        assert i == j.child
    plan = _Plan(
        n=n,
        parent=model.parents,
        qi=model.q_index,
        C=tuple(C),
        KR=tuple(KR),
        Kp=tuple(Kp),
        XK=tuple(XK),
        XKT=tuple(XKT),
        I6=tuple(I6),
        C6=tuple(C6),
        C6T=tuple(C6T),
        mass=np.array([b.mass for b in model.bodies]),
        com=tuple(com),
        moving=tuple(model.q_joints),
    )
    model._cache["plan"] = plan
    return plan


# --- input checking ------------------------------------------------------------------------


def _batch(model: Model, x: object, name: str) -> tuple[np.ndarray, bool]:
    """``x`` as a finite (B, nv) float array, and whether it came batched (2-D)."""
    a = np.asarray(x, dtype=float)
    nv = model.nv
    if not (a.ndim in (1, 2) and a.shape[-1] == nv):
        raise ValueError(f"{name} must have shape (nv,) or (B, nv) with nv = {nv}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    return (a if a.ndim == 2 else a[None, :]), a.ndim == 2


def _fext(model: Model, fext: object) -> tuple[np.ndarray, bool]:
    """External wrenches as (B, nbodies, 6), and whether they came batched."""
    f = np.asarray(fext, dtype=float)
    nb = model.nbodies
    if not (f.ndim in (2, 3) and f.shape[-2:] == (nb, 6)):
        raise ValueError(
            f"fext must have shape (nbodies, 6) or (B, nbodies, 6) with nbodies = {nb}, "
            f"got {f.shape}"
        )
    if not np.all(np.isfinite(f)):
        raise ValueError("fext must be finite")
    return (f if f.ndim == 3 else f[None]), f.ndim == 3


def _common_batch(named: dict[str, np.ndarray]) -> int:
    """The batch size shared by arrays of leading size B or 1; ValueError if they differ."""
    sizes = {a.shape[0] for a in named.values()} - {1}
    if len(sizes) > 1:
        shapes = ", ".join(f"{k} {a.shape}" for k, a in named.items())
        raise ValueError(f"batch sizes differ: {shapes}")
    return sizes.pop() if sizes else 1


def _batches(model: Model, **arrays: object) -> tuple[list[np.ndarray], int, bool]:
    """Check several (B?, nv) inputs and broadcast them to one batch size B."""
    got = {k: _batch(model, x, k) for k, x in arrays.items()}
    named = {k: a for k, (a, _) in got.items()}
    B = _common_batch(named)
    out = [np.broadcast_to(a, (B, model.nv)) for a in named.values()]
    return out, B, any(b for _, b in got.values())


def _body_index(model: Model, body: int | str) -> int:
    if isinstance(body, str):
        return model.body(body)
    i = int(body)
    if not 0 <= i < model.nbodies:
        raise ValueError(f"body index {body} out of range 0..{model.nbodies - 1}")
    return i


def _sincos(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos q and sin q from one tan(q/2) (half the cost of np.cos plus np.sin)."""
    t = np.tan(0.5 * q)
    t2 = t * t
    d = 1.0 / (1.0 + t2)
    c = (1.0 - t2) * d
    t *= 2.0 * d
    return c, t


def _chunks(B: int, chunk: int):
    for s in range(0, B, chunk):
        yield slice(s, min(B, s + chunk))


# --- the recursive Newton-Euler algorithm ------------------------------------------------------


def _rotate_xy(M: np.ndarray, c: np.ndarray, s: np.ndarray, inverse: bool, axis: int = 0) -> None:
    """In place: turn the x, y components of the 6-vectors along ``axis`` of ``M`` by Rz(q).

    ``inverse`` applies Rz(q)^T (parent -> child coordinates), else Rz(q) (child -> parent).
    ``c``, ``s`` broadcast against ``M``'s slices without that axis kept.
    """
    lead = (slice(None),) * axis
    X, Y = M[(*lead, slice(0, None, 3))], M[(*lead, slice(1, None, 3))]
    if inverse:
        tx = c * X + s * Y
        Y *= c
        Y -= s * X
    else:
        tx = c * X - s * Y
        Y *= c
        Y += s * X
    X[...] = tx


#: Row order of spatial vectors inside the RNEA kernel: x, y and z pairs of [linear,
#: angular] (``_P[r]`` is the standard [lin; ang] row held in kernel row r), so that the
#: joint rotation (which mixes x and y only) works on contiguous blocks.
_P = np.array([0, 3, 1, 4, 2, 5])


@dataclass(frozen=True)
class _Level:
    """Bodies at one depth of the tree, contiguous in level order (children of one parent
    adjacent), processed together. ``parents``: None (the world), or a slice / index
    array into level order; ``up``: how child wrenches reach the parents. Matrices are in
    kernel row order (see ``_P``)."""

    start: int
    stop: int
    moving: bool
    parents: slice | np.ndarray | None
    up: tuple
    up_needed: bool  # a movable joint at or above some parent: torques need the parents' F
    XK: np.ndarray  # (L, 1, 6, 6) motion transform parent' -> child' before the joint
    XKT: np.ndarray  # (L, 6, 6) force transform child' -> parent' after the joint
    I6: np.ndarray  # (L, 6, 6) spatial inertia about the origin
    K: np.ndarray  # (L, 6, 6) velocity -> [linear momentum; angular momentum about the COM]
    IG: np.ndarray  # (L, 6, 12) [acceleration; w x [p; L]] -> wrench: [I6 | G]


@dataclass(frozen=True)
class _Levels:
    order: np.ndarray  # level position -> body index
    pos: np.ndarray  # body index -> level position
    q_rows: np.ndarray  # level position of each coordinate of q
    fixed_rows: np.ndarray  # level positions of fixed joints
    levels: tuple[_Level, ...]
    width: int  # largest level
    C6out: np.ndarray  # (nbodies, 6, 6) kernel rows -> body-frame [lin; ang], level order
    C6in: np.ndarray  # (nbodies, 6, 6) body-frame [lin; ang] -> kernel rows, level order


def _levels(model: Model) -> _Levels:
    got = model._cache.get("levels")
    if got is not None:
        return got
    plan = _plan(model)
    P = _P
    depth: list[int] = []
    for p in plan.parent:
        depth.append(0 if p < 0 else depth[p] + 1)
    order: list[int] = []
    pos = np.zeros(plan.n, dtype=int)
    levels = []
    for d in range(max(depth) + 1):
        members = [i for i in range(plan.n) if depth[i] == d]
        members.sort(key=lambda i: (-1 if plan.parent[i] < 0 else pos[plan.parent[i]], i))
        start = len(order)
        for i in members:
            pos[i] = len(order)
            order.append(i)
        up: tuple = ()
        parents: slice | np.ndarray | None = None
        up_needed = d > 0 and any(
            plan.qi[k] >= 0 for i in members for k in model.ancestors(plan.parent[i])
        )
        if d > 0:
            pp = np.array([pos[plan.parent[i]] for i in members])
            if np.all(pp == pp[0]):
                parents, up = slice(int(pp[0]), int(pp[0]) + 1), ("one", int(pp[0]))
            elif np.all(np.diff(pp) == 1):
                parents = slice(int(pp[0]), int(pp[-1]) + 1)
                up = ("slice", parents)
            else:
                uniq, first = np.unique(pp, return_index=True)
                parents, up = pp, ("reduce", uniq, first)
        levels.append(
            _Level(
                start=start,
                stop=len(order),
                moving=any(plan.qi[i] >= 0 for i in members),
                parents=parents,
                up=up,
                up_needed=up_needed,
                XK=np.stack([plan.XK[i][P][:, P] for i in members])[:, None],
                XKT=np.stack([plan.XKT[i][P][:, P] for i in members]),
                I6=np.stack([plan.I6[i][P][:, P] for i in members]),
                K=np.stack([_momentum_map(plan, i)[P][:, P] for i in members]),
                IG=np.stack(
                    [np.hstack([plan.I6[i][P][:, P], _bias_map(plan, i)[P][:, P]]) for i in members]
                ),
            )
        )
    got = _Levels(
        order=np.array(order),
        pos=pos,
        q_rows=pos[list(plan.moving)],
        fixed_rows=np.array([pos[i] for i in range(plan.n) if plan.qi[i] < 0], dtype=int),
        levels=tuple(levels),
        width=max(L.stop - L.start for L in levels),
        C6out=np.stack([plan.C6[i][:, P] for i in order]),
        C6in=np.stack([plan.C6T[i][P] for i in order]),
    )
    model._cache["levels"] = got
    return got


def _momentum_map(plan: _Plan, i: int) -> np.ndarray:
    """(6,6): body velocity [v; w] -> [p; L], p = m (v + w x c), L = Ic w (about the COM)."""
    m, c = plan.mass[i], plan.com[i]
    K = np.zeros((6, 6))
    K[:3, :3] = m * np.eye(3)
    K[:3, 3:] = -m * cross_matrix(c)
    Ic = plan.I6[i][3:, 3:] + m * cross_matrix(c) @ cross_matrix(c)
    K[3:, 3:] = Ic
    return K


def _bias_map(plan: _Plan, i: int) -> np.ndarray:
    """(6,6): [w x p; w x L] -> the velocity-product wrench v x* (I v) about the origin.

    With p = m v_com and L = Ic w: f_lin = w x p and f_ang = w x L + c x (w x p).
    """
    G = np.eye(6)
    G[3:, :3] = cross_matrix(plan.com[i])
    return G


class _Work:
    """Scratch arrays for one chunk size ``n``, reused across chunks and levels."""

    def __init__(self, nb: int, width: int, n: int) -> None:
        self.M = np.empty((nb, 3, 6, n))  # [velocity, acceleration, w x [p; L]] per body
        self.F = np.empty((nb, 6, n))  # wrench per body, kernel rows
        self.H = np.empty((width, 6, n))  # momentum
        self.T1 = np.empty((width, 2, 2, n))
        self.T2 = np.empty((width, 2, 2, n))
        self.U = np.empty((width, 6, n))
        self.C4 = np.empty((nb, 2, 2, n))
        self.S4 = np.empty((nb, 2, 2, n))
        self.V2 = np.empty((nb, 2, n))


def _prod_diff(out, a1, b1, a2, b2, t) -> None:
    """``out = a1 * b1 - a2 * b2`` without temporaries (``t``: scratch)."""
    np.multiply(a1, b1, out=out)
    np.multiply(a2, b2, out=t)
    np.subtract(out, t, out=out)


def _rnea_chunk(
    lv: _Levels,
    w: _Work,
    c: np.ndarray,
    s: np.ndarray,
    v: np.ndarray | None,
    a: np.ndarray | None,
    fext: np.ndarray | None,
    gravity: np.ndarray,
    all_wrenches: bool = True,
) -> np.ndarray:
    """Subtree wrenches (nbodies, 6, n) in internal frames, level order and kernel rows.

    Without ``all_wrenches`` the wrenches of bodies with no movable joint at or above them
    are left incomplete (the torques do not need them).

    ``c``, ``s``: (nbodies, n) cos and sin of each joint angle (1 and 0 for fixed joints);
    ``v``, ``a``: (nbodies, n) joint rates (0 for fixed joints) or None for zero; ``fext``:
    (nbodies, 6, n) in kernel rows or None. Internal frames have the joint axis along z, so
    S = e_z (angular): kernel row 5.
    """
    M, F = w.M, w.F
    nb, n = c.shape
    # cos, sin and joint rates repeated to the shapes they multiply: same-shape ufunc loops
    # are several times faster than broadcasting ones
    C4, S4 = w.C4, w.S4
    for i in range(2):
        for j in range(2):
            C4[:, i, j] = c
            S4[:, i, j] = s
    if v is not None:
        V2 = w.V2
        V2[:, 0] = v
        V2[:, 1] = v
    base = np.zeros((6, 2))
    base[:3, 1] = -gravity  # the world's "acceleration" that produces gravity
    base = base[_P]
    for L in lv.levels:
        k = L.stop - L.start
        lvl = slice(L.start, L.stop)
        Ml = M[lvl, 0:2]
        if L.parents is None:
            Ml[...] = np.swapaxes(L.XK[:, 0] @ base, 1, 2)[..., None]
        else:
            np.matmul(L.XK, M[L.parents, 0:2], out=Ml)
        T1, T2 = w.T1[:k], w.T2[:k]
        if L.moving:
            # parent -> child coordinates: x' = c x + s y, y' = c y - s x
            cl, sl = C4[lvl], S4[lvl]
            X, Y = Ml[:, :, 0:2], Ml[:, :, 2:4]
            np.multiply(X, cl, out=T1)
            np.multiply(Y, sl, out=T2)
            np.add(T1, T2, out=T1)
            np.multiply(X, sl, out=T2)
            np.multiply(Y, cl, out=Y)
            np.subtract(Y, T2, out=Y)
            X[...] = T1
            if v is not None:
                Ml[:, 0, 5] += v[lvl]
                # a += v x (S qd): x += qd * y, y -= qd * x (linear and angular rows)
                qd2, t = V2[lvl], T1[:, 0]
                np.multiply(Ml[:, 0, 2:4], qd2, out=t)
                Ml[:, 1, 0:2] += t
                np.multiply(Ml[:, 0, 0:2], qd2, out=t)
                Ml[:, 1, 2:4] -= t
            if a is not None:
                Ml[:, 1, 5] += a[lvl]
        Fl = F[lvl]
        if v is None:
            np.matmul(L.I6, Ml[:, 1], out=Fl)
        else:
            # f = I a + v x* (I v) = I a + G [w x p; w x L]
            h = w.H[:k]
            np.matmul(L.K, Ml[:, 0], out=h)  # rows p_x, L_x, p_y, L_y, p_z, L_z
            y = M[lvl, 2]
            vel = Ml[:, 0]
            wx, wy, wz = vel[:, 1], vel[:, 3], vel[:, 5]
            t = T1[:, 0, 0]
            for r in (0, 1):  # p, then L
                _prod_diff(y[:, r], wy, h[:, 4 + r], wz, h[:, 2 + r], t)
                _prod_diff(y[:, 2 + r], wz, h[:, r], wx, h[:, 4 + r], t)
                _prod_diff(y[:, 4 + r], wx, h[:, 2 + r], wy, h[:, r], t)
            blk = M[lvl, 1:3].reshape(k, 12, n)
            np.matmul(L.IG, blk, out=Fl)
        if fext is not None:
            Fl -= fext[lvl]
    for L in reversed(lv.levels):
        if L.parents is None or not (all_wrenches or L.up_needed):
            continue
        k = L.stop - L.start
        lvl = slice(L.start, L.stop)
        f = F[lvl]
        if L.moving:
            # child -> parent coordinates: x' = c x - s y, y' = s x + c y
            cl, sl = C4[lvl, 0], S4[lvl, 0]
            g, t = w.H[:k], w.T1[:k, 0]
            X, Y = f[:, 0:2], f[:, 2:4]
            np.multiply(X, cl, out=g[:, 0:2])
            np.multiply(Y, sl, out=t)
            np.subtract(g[:, 0:2], t, out=g[:, 0:2])
            np.multiply(Y, cl, out=g[:, 2:4])
            np.multiply(X, sl, out=t)
            np.add(g[:, 2:4], t, out=g[:, 2:4])
            g[:, 4:6] = f[:, 4:6]
            f = g
        up = np.matmul(L.XKT, f, out=w.U[:k])
        if L.up[0] == "one":
            F[L.up[1]] += up.sum(axis=0)
        elif L.up[0] == "slice":
            F[L.up[1]] += up
        else:
            F[L.up[1]] += np.add.reduceat(up, L.up[2], axis=0)
    return F


def _rnea_all(
    model: Model,
    q: object,
    v: object | None,
    a: object | None,
    fext: object | None,
    gravity: np.ndarray,
    want: str,
    chunk: int | None = None,
) -> np.ndarray:
    """Shared driver: ``want`` "tau" -> (B?, nv); "wrench" -> (B?, nbodies, 6)."""
    lv = _levels(model)
    named = {"q": _batch(model, q, "q")}
    if v is not None:
        named["v"] = _batch(model, v, "v")
    if a is not None:
        named["a"] = _batch(model, a, "a")
    if fext is not None:
        named["fext"] = _fext(model, fext)
    B = _common_batch({k: x for k, (x, _) in named.items()})
    batched = any(b for _, b in named.values())
    nb = model.nbodies
    step = min(B, chunk or CHUNK)
    Bp = -(-B // step) * step  # padded to whole chunks

    def rows(x: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """(nv, B) -> (nbodies, Bp) in level order, ``fill`` in rows of fixed joints."""
        out = np.full((nb, Bp), fill) if lv.fixed_rows.size else np.empty((nb, Bp))
        out[lv.q_rows, :B] = x
        if Bp > B:
            out[:, B:] = fill
        return out

    cq, sq = _sincos(np.ascontiguousarray(named["q"][0].T))
    c, s = rows(cq, 1.0), rows(sq)
    vf = rows(named["v"][0].T) if v is not None else None
    af = rows(named["a"][0].T) if a is not None else None
    ff = None
    if fext is not None:
        # to internal frames, level order, kernel rows, component-first: (nbodies, 6, Bp)
        f = named["fext"][0][:, lv.order]
        ff = np.zeros((nb, 6, Bp))
        ff[:, :, :B] = np.einsum("bij,zbj->biz", lv.C6in, f)
    out = np.empty((model.nv, Bp)) if want == "tau" else np.empty((nb, 6, Bp))
    work = _Work(nb, lv.width, step)
    for start in range(0, Bp, step):
        sl = slice(start, start + step)
        F = _rnea_chunk(
            lv,
            work,
            c[:, sl],
            s[:, sl],
            None if vf is None else vf[:, sl],
            None if af is None else af[:, sl],
            None if ff is None else ff[:, :, sl],
            gravity,
            all_wrenches=want != "tau",
        )
        if want == "tau":
            out[:, sl] = F[lv.q_rows, 5]
        else:
            out[:, :, sl] = np.matmul(lv.C6out, F)[lv.pos]
    res = out[:, :B].T if want == "tau" else out[:, :, :B].transpose(2, 0, 1)
    res = np.ascontiguousarray(res)
    return res if batched else res[0]


def rnea(model: Model, q: object, v: object, a: object, fext: object | None = None) -> np.ndarray:
    """Joint torques (B?, nv) N m that produce accelerations ``a`` at (q, v) under gravity.

    ``fext`` (B?, nbodies, 6): external wrench acting on each body, [force N; moment N m
    about the body origin] in the body frame (pinocchio's ``fext`` in local frames).
    """
    return _rnea_all(model, q, v, a, fext, model.gravity, "tau")


def joint_wrenches(
    model: Model, q: object, v: object, a: object, fext: object | None = None
) -> np.ndarray:
    """Wrench (B?, nbodies, 6) each joint transmits from its parent onto its child's subtree.

    [force N; moment N m about the child body origin] in the child body frame; fixed joints
    included (pinocchio's ``data.f`` after rnea).
    """
    return _rnea_all(model, q, v, a, fext, model.gravity, "wrench")


def gravity_torques(model: Model, q: object) -> np.ndarray:
    """Torques (B?, nv) N m that hold configuration q against gravity."""
    return _rnea_all(model, q, None, None, None, model.gravity, "tau")


def nonlinear_effects(model: Model, q: object, v: object) -> np.ndarray:
    """Coriolis, centrifugal and gravity torques (B?, nv) N m: ``rnea(q, v, 0)``."""
    return _rnea_all(model, q, v, None, None, model.gravity, "tau")


# --- kinematics ---------------------------------------------------------------------------------


def _world_frames(
    plan: _Plan, cq: np.ndarray, sq: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """World rotations (3,3,n) and origins (3,n) of the internal frames."""
    n = cq.shape[1]
    Rw: list[np.ndarray] = [None] * plan.n  # type: ignore[list-item]
    pw: list[np.ndarray] = [None] * plan.n  # type: ignore[list-item]
    for i in range(plan.n):
        p = plan.parent[i]
        k = plan.qi[i]
        if p < 0:
            R = np.empty((3, 3, n))
            R[...] = plan.KR[i][:, :, None]
            o = np.empty((3, n))
            o[...] = plan.Kp[i][:, None]
        else:
            Rp = Rw[p]
            # R[a, b] = sum_c Rp[a, c] KR[c, b]
            R = np.einsum("acn,cb->abn", Rp, plan.KR[i], optimize=False)
            o = pw[p] + np.einsum("acn,c->an", Rp, plan.Kp[i])
        if k >= 0:
            c, s = cq[k], sq[k]
            x = R[:, 0].copy()
            R[:, 0] = c * x + s * R[:, 1]
            R[:, 1] = c * R[:, 1] - s * x
        Rw[i] = R
        pw[i] = o
    return Rw, pw


def _frames_batch(model: Model, q: object) -> tuple[_Plan, list, list, int, bool]:
    plan = _plan(model)
    (qb,), B, batched = _batches(model, q=q)
    Rw, pw = _world_frames(plan, *_sincos(np.ascontiguousarray(qb.T)))
    return plan, Rw, pw, B, batched


def forward_kinematics(model: Model, q: object) -> np.ndarray:
    """World transform (B?, nbodies, 4, 4) of each body frame."""
    plan, Rw, pw, B, batched = _frames_batch(model, q)
    T = np.zeros((B, plan.n, 4, 4))
    for i in range(plan.n):
        # body frame = internal frame rotated back: oR_i = oR_i' C^T
        R = np.einsum("abn,cb->nac", Rw[i], plan.C[i])
        T[:, i, :3, :3] = R
        T[:, i, :3, 3] = pw[i].T
    T[:, :, 3, 3] = 1.0
    return T if batched else T[0]


def jacobian(model: Model, q: object, body: int | str, point: object | None = None) -> np.ndarray:
    """World-aligned Jacobian (B?, 6, nv) of a point fixed in ``body``.

    Rows: [linear velocity m/s of the point; angular velocity rad/s of the body], both in
    world axes (pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian). ``point`` (3,) m in the
    body frame, default the body origin.
    """
    bi = _body_index(model, body)
    plan, Rw, pw, B, batched = _frames_batch(model, q)
    if point is None:
        pt = pw[bi]
    else:
        pl = np.asarray(point, dtype=float)
        if pl.shape != (3,) or not np.all(np.isfinite(pl)):
            raise ValueError(f"point must be a finite (3,) vector, got shape {pl.shape}")
        pt = pw[bi] + np.einsum("abn,b->an", Rw[bi], plan.C[bi].T @ pl)
    J = np.zeros((B, 6, model.nv))
    for j in model.ancestors(bi):
        k = plan.qi[j]
        if k < 0:
            continue
        z = Rw[j][:, 2]  # (3, n) joint axis in world
        r = pt - pw[j]
        J[:, :3, k] = np.cross(z.T, r.T)
        J[:, 3:, k] = z.T
    return J if batched else J[0]


def center_of_mass(model: Model, q: object) -> np.ndarray:
    """Centre of mass (B?, 3) m of the whole model in the world frame."""
    plan, Rw, pw, B, batched = _frames_batch(model, q)
    total = float(plan.mass.sum())
    acc = np.zeros((3, B))
    for i in range(plan.n):
        m = plan.mass[i]
        if m == 0.0:
            continue
        acc += m * (pw[i] + np.einsum("abn,b->an", Rw[i], plan.com[i]))
    com = (acc / total).T if total > 0 else acc.T
    return com if batched else com[0]


def external_force_at(
    model: Model, q: object, body: int | str, point_world: object, force_world: object
) -> np.ndarray:
    """Body-frame wrench (B?, 6) of a world force (3,)/(B,3) N applied at a world point m.

    The result is what ``rnea``'s ``fext[..., body, :]`` expects: [force; moment about the
    body origin], both in the body frame.
    """
    bi = _body_index(model, body)
    T = forward_kinematics(model, q)
    batched = T.ndim == 4
    Tb = T[:, bi] if batched else T[None, bi]
    P = np.asarray(point_world, dtype=float)
    Fw = np.asarray(force_world, dtype=float)
    for name, x in (("point_world", P), ("force_world", Fw)):
        if x.ndim not in (1, 2) or x.shape[-1] != 3:
            raise ValueError(f"{name} must have shape (3,) or (B, 3), got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"{name} must be finite")
        batched |= x.ndim == 2
    P, Fw = np.atleast_2d(P), np.atleast_2d(Fw)
    _common_batch({"q": Tb, "point_world": P, "force_world": Fw})
    Rt = Tb[:, :3, :3].transpose(0, 2, 1)
    moment = np.cross(P - Tb[:, :3, 3], Fw)
    out = np.concatenate([(Rt @ Fw[..., None])[..., 0], (Rt @ moment[..., None])[..., 0]], -1)
    return out if batched else out[0]


# --- mass matrix -----------------------------------------------------------------------------


def _sandwich(XK: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``XK^T @ A @ XK`` for a stack A (6, 6, n) and a constant XK (6, 6)."""
    n = A.shape[2]
    L = (XK.T @ A.reshape(6, 6 * n)).reshape(6, 6, n)  # XK^T A
    Lt = np.ascontiguousarray(L.transpose(1, 0, 2))
    R = (XK.T @ Lt.reshape(6, 6 * n)).reshape(6, 6, n)  # XK^T (XK^T A)^T = (XK^T A XK)^T
    return np.ascontiguousarray(R.transpose(1, 0, 2))


def mass_matrix(model: Model, q: object) -> np.ndarray:
    """Joint-space inertia matrix (B?, nv, nv) kg m^2 (composite rigid body algorithm)."""
    plan = _plan(model)
    (qb,), B, batched = _batches(model, q=q)
    nv = model.nv
    H = np.zeros((nv, nv, B))
    qT = np.ascontiguousarray(qb.T)
    for sl in _chunks(B, CHUNK):
        cq, sq = _sincos(qT[:, sl])
        n = cq.shape[1]
        IC = [np.repeat(plan.I6[i][:, :, None], n, axis=2) for i in range(plan.n)]
        for i in range(plan.n - 1, -1, -1):
            p = plan.parent[i]
            k = plan.qi[i]
            if k >= 0:
                # column S = e5: F = IC S, then walk to the root
                f = IC[i][:, 5].copy()
                H[k, k, sl] = f[5]
                j = i
                while plan.parent[j] >= 0:
                    kj = plan.qi[j]
                    if kj >= 0:
                        _rotate_xy(f, cq[kj], sq[kj], inverse=False)
                    f = plan.XKT[j] @ f
                    j = plan.parent[j]
                    kk = plan.qi[j]
                    if kk >= 0:
                        H[k, kk, sl] = f[5]
                        H[kk, k, sl] = f[5]
            if p >= 0:
                A = IC[i]
                if k >= 0:
                    # X^T A X with X = Rz6(q)^T XK: first Rz6 A Rz6^T, rows then columns
                    A = A.copy()
                    _rotate_xy(A, cq[k], sq[k], inverse=False)
                    At = np.ascontiguousarray(A.transpose(1, 0, 2))
                    _rotate_xy(At, cq[k], sq[k], inverse=False)
                    A = At.transpose(1, 0, 2)
                IC[p] += _sandwich(plan.XK[i], np.ascontiguousarray(A))
    H = np.ascontiguousarray(H.transpose(2, 0, 1))
    H = 0.5 * (H + H.transpose(0, 2, 1))
    return H if batched else H[0]
