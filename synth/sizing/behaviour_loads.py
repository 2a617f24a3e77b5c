"""Joint loads from the behaviours a design will run: inverse dynamics along every
trajectory, with the ground's support and contact forces (issue 8, item 2).

The structure generator (``synth.sizing.structure``) sizes a design for its family's hand-made load
cases (``synth.sizing.families``) *and* for the behaviours the design lists: every behaviour of the
design's controller whose ability is among the design's abilities (``BehaviorSpec.ability``,
its own name when None; aliases are skipped), run with its default parameters on a
``gaits.DesignGeometry`` built from the sizing at hand exactly as ``design.json`` will give
it (lengths, modules, wheel radius, parameters and abilities rounded as the record rounds
them; the chosen actuators' no-load speeds). ``synth`` imports ``gaits`` for this, lazily
(only when a structure is sized), as docs/architecture.md's layers allow.

**Motion.** Each trajectory gives q and v per sample (the planned positions when the
controller compensates servo droop); accelerations are ``info["accelerations"]`` or the
time derivative of v (central differences). The joint speeds a behaviour needs are the
peaks of |v| over the full trajectory. The inverse dynamics runs on samples
``SAMPLE_DT`` apart at most (a coarser trajectory is used as it is).

**Support and contact forces (a contact solve, static in form).** The templates weld the
root body (trunk, chassis, base) to the world; a behaviour is analysed in the root's frame,
the root held level and not rotating, translating with the trunk's acceleration:

1. *Contacts* are generic over part kinds: every foot body's ``foot`` part (the four
   corners of a sole plate, or the template's foot point for a point foot), every wheel's
   lowest rim point (``wheel_radius`` below its centre) and every caster's origin. At each
   sample the contacts in *stance* are those within ``STANCE_TOLERANCE`` of the lowest
   one (the ground is the level plane through it).
2. *Trunk acceleration*: a stance contact does not slip, so the trunk moves opposite to
   the velocity of the stance contacts' material points (feet and wheels; casters roll
   freely): ``u = -mean J_c v``, smoothed over ``SMOOTH_S`` and differentiated. Its
   d'Alembert force ``-m_b a`` acts on every body at its centre of mass.
3. *Required wrench*: with gravity, the joints' motion and the trunk's acceleration, the
   inverse dynamics gives the wrench the world must apply to the root (its weld). The
   ground supplies it instead: its vertical part through the centre of pressure
   ``p = ((z0 F_x - M_y) / F_z, (M_x + z0 F_y) / F_z)`` on the ground plane z0, shared
   among the stance contacts for static equilibrium about p (``support_shares``: least
   norm, contacts that would have to pull dropped; batched here); its horizontal part
   shared among the stance feet and wheels (not casters) in proportion to their vertical
   shares. What the contacts cannot give (a centre of pressure outside the support
   polygon, the free moment about the vertical) stays on the weld: it would tip or twist
   the robot, not load its joints.
4. The contact forces join the d'Alembert forces as external wrenches; the joints'
   torques and the wrenches every link carries follow from the same recursion.

A robot welded to the world (a manipulator: end effectors, no feet, wheels or casters, as
``export.assembly`` welds it) has no contacts and no trunk motion. A floating robot without
declared contact points (the snake, whose whole body lies on the ground) is left to its
family's load cases.

Load case names are ``"<behaviour>@<t>s"``, the time of the governing sample.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gaits import controller_for
from gaits.base import DesignGeometry
from kinematics.dynamics import forward_kinematics, joint_wrenches
from kinematics.templates import Template

#: Contacts within this height of the lowest one are in stance, m.
STANCE_TOLERANCE = 0.003
#: Window of the moving average of the trunk's velocity before differentiating it, s.
SMOOTH_S = 0.05
#: Largest time step between the samples analysed, s (finer trajectories are thinned).
SAMPLE_DT = 0.02
#: Trajectory sets kept in memory (per design geometry and actuator speeds).
CACHE_SIZE = 8
#: The wheel radius, m, that ``DesignGeometry.from_record`` reads for a design without
#: wheels (the record's ``wheel_radius_m`` is null).
NO_WHEEL_RADIUS = 0.03


@dataclass(frozen=True)
class Contact:
    """One ground contact: the body it belongs to, its kind ("foot", "wheel", "caster"),
    the point (body frame, m; wheels: the centre, the contact is ``radius`` below it)."""

    body: int
    kind: str
    point: tuple[float, float, float]
    radius: float = 0.0

    @property
    def traction(self) -> bool:
        """Whether it can push horizontally (a foot or a driven wheel; not a caster)."""
        return self.kind != "caster"


@dataclass(frozen=True)
class Motion:
    """One behaviour's kinematics on the design's template (masses play no part).

    ``times`` (B,) s, ``q``/``v``/``a`` (B, nv) in the template's joint order (joints the
    trajectory does not move stay at 0), ``peak_speed`` (nv,) rad/s over the full
    trajectory, ``trunk_acc`` (B, 3) m/s^2, ``points`` (B, nc, 3) m and ``stance`` (B, nc)
    of the template's contacts, ``R`` (B, nbodies, 3, 3) and ``o`` (B, nbodies, 3) the
    bodies' frames.
    """

    behaviour: str
    times: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    peak_speed: np.ndarray
    trunk_acc: np.ndarray
    points: np.ndarray
    stance: np.ndarray
    R: np.ndarray
    o: np.ndarray


@dataclass(frozen=True)
class BehaviourCase:
    """Samples of one behaviour ready for inverse dynamics: ``q``, ``v``, ``a`` (B, nv)
    and external wrenches ``fext`` (B, nbodies, 6) (contacts and d'Alembert forces)."""

    behaviour: str
    times: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    fext: np.ndarray
    peak_speed: np.ndarray

    def label(self, k: int) -> str:
        """The load case name of sample ``k``: ``"<behaviour>@<t>s"``."""
        return f"{self.behaviour}@{self.times[k]:.2f}s"


# --- the design geometry and its behaviours -------------------------------------------------


def _rounded(x: float) -> float:
    """As the design record rounds (``export.record._r``): 9 significant digits."""
    return float(f"{x:.9g}")


def design_geometry(
    robot_type: str,
    template: str,
    lengths: Mapping[str, float],
    modules: int,
    wheel_radius: float | None,
    params: Mapping[str, float],
    abilities: Sequence[str],
    joint_speed: Mapping[str, float],
    ancestors: Mapping[str, tuple[str, ...]] | None = None,
):
    """The ``gaits.base.DesignGeometry`` that ``DesignGeometry.from_record`` will read from
    this design's record (SI units; values rounded as the record rounds them;
    ``wheel_radius`` None for a design without wheels; ``ancestors`` its abilities'
    ancestor abilities, the record's ``ability_ancestors``)."""

    return DesignGeometry(
        robot_type=robot_type,
        template=template,
        lengths={k: _rounded(v) for k, v in sorted(lengths.items())},
        modules=int(modules or 1),
        wheel_radius=_rounded(NO_WHEEL_RADIUS if wheel_radius is None else wheel_radius),
        params={k: _rounded(v) for k, v in sorted(params.items())},
        abilities=tuple(sorted(abilities)),
        joint_speed={k: _rounded(v) for k, v in sorted(joint_speed.items())},
        ancestors=dict(sorted((ancestors or {}).items())),
    )


def _key(geometry) -> tuple:
    return (
        geometry.robot_type,
        geometry.template,
        tuple(sorted(geometry.lengths.items())),
        geometry.modules,
        geometry.wheel_radius,
        tuple(sorted(geometry.params.items())),
        tuple(geometry.abilities),
        tuple(sorted(geometry.joint_speed.items())),
        tuple(sorted(geometry.ancestors.items())),
    )


_TRAJECTORIES: OrderedDict[tuple, tuple[dict, tuple[str, ...]]] = OrderedDict()


def behaviour_trajectories(geometry) -> tuple[dict, tuple[str, ...]]:
    """The default trajectory of every behaviour whose ability the design has (name ->
    ``gaits.base.Trajectory``), and notes on behaviours that could not be planned. Cached
    per geometry (``CACHE_SIZE`` geometries): a simulation of the same design reuses them."""
    key = _key(geometry)
    hit = _TRAJECTORIES.get(key)
    if hit is not None:
        _TRAJECTORIES.move_to_end(key)
        return hit

    try:
        controller = controller_for(geometry)
    except ValueError as e:
        out: tuple[dict, tuple[str, ...]] = ({}, (f"no behaviours analysed: {e}",))
    else:
        trajs, notes = {}, []
        for name in controller.listed(geometry.abilities):
            try:
                trajs[name] = controller.run(name)
            except ValueError as e:
                notes.append(f"behaviour {name} not analysed: {e}")
        out = (trajs, tuple(notes))
    _TRAJECTORIES[key] = out
    while len(_TRAJECTORIES) > CACHE_SIZE:
        _TRAJECTORIES.popitem(last=False)
    return out


# --- contacts and motions -------------------------------------------------------------------


def fixed_base(tmpl: Template) -> bool:
    """Whether the template's root is bolted down (end effectors and no ground contacts:
    a manipulator), as ``export.assembly`` welds it in the MJCF."""
    return bool(tmpl.end_effectors) and not (tmpl.feet or tmpl.wheels or tmpl.casters)


def contacts(tmpl: Template) -> tuple[Contact, ...]:
    """The template's ground contacts (see the module docstring), feet, wheels, casters."""
    m = tmpl.model
    out: list[Contact] = []
    for k, foot in enumerate(tmpl.feet):
        b = m.body(foot)
        sole = [p for p in tmpl.parts.get(foot, ()) if p.kind == "foot" and len(p.dims) == 3]
        if sole:
            dx, dy = sole[0].dims[0] / 2, sole[0].dims[1] / 2
            place = sole[0].placement
            for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
                pt = (place @ np.array([sx * dx, sy * dy, 0.0, 1.0]))[:3]
                out.append(Contact(b, "foot", tuple(float(x) for x in pt)))
        else:
            out.append(Contact(b, "foot", tuple(float(x) for x in tmpl.foot_points[k])))
    for wheel in tmpl.wheels:
        disc = [p for p in tmpl.parts.get(wheel, ()) if p.kind == "wheel"]
        r = disc[0].dims[0] if disc else tmpl.params.wheel_radius
        out.append(Contact(m.body(wheel), "wheel", (0.0, 0.0, 0.0), float(r)))
    for caster in tmpl.casters:
        out.append(Contact(m.body(caster), "caster", (0.0, 0.0, 0.0)))
    return tuple(out)


def _contact_kinematics(
    tmpl: Template, cs: Sequence[Contact], T: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World points (B, nc, 3) of the contacts and the velocities (B, nc, 3) of the
    material points there, from the frames ``T`` (B, nbodies, 4, 4) and joint speeds."""
    m = tmpl.model
    B = T.shape[0]
    P = np.zeros((B, len(cs), 3))
    V = np.zeros((B, len(cs), 3))
    down = np.array([0.0, 0.0, -1.0])
    for c, ct in enumerate(cs):
        R, o = T[:, ct.body, :3, :3], T[:, ct.body, :3, 3]
        p = o + R @ np.array(ct.point) + ct.radius * down
        P[:, c] = p
        for j in m.ancestors(ct.body):
            k = m.q_index[j]
            if k < 0:
                continue
            axis = T[:, j, :3, :3] @ m.joints[j].axis
            V[:, c] += np.cross(axis, p - T[:, j, :3, 3]) * v[:, k : k + 1]
    return P, V


def _smooth(x: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Centred moving average over ``SMOOTH_S`` along axis 0 (ends: shorter windows)."""
    if len(times) < 3:
        return x
    dt = float(np.median(np.diff(times)))
    half = int(round(SMOOTH_S / dt / 2))
    if half < 1:
        return x
    c = np.cumsum(np.concatenate([np.zeros((1, *x.shape[1:])), x]), axis=0)
    n = len(x)
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def motion(tmpl: Template, traj) -> Motion:
    """The kinematics of trajectory ``traj`` (a ``gaits.base.Trajectory``) on ``tmpl``."""
    m = tmpl.model
    n = len(traj.times)
    times = np.asarray(traj.times, dtype=float)
    q = np.zeros((n, m.nv))
    v = np.zeros((n, m.nv))
    a = np.zeros((n, m.nv))
    cols = [m.q_names.index(j) for j in traj.joints]
    planned = traj.info.get("planned_positions")
    qt = np.asarray(planned if planned is not None else traj.positions, dtype=float)
    acc = traj.info.get("accelerations")
    vt = np.asarray(traj.velocities, dtype=float)
    at = np.gradient(vt, times, axis=0) if acc is None else np.asarray(acc, dtype=float)
    q[:, cols], v[:, cols], a[:, cols] = qt, vt, at
    peak = np.abs(v).max(axis=0)
    cs = contacts(tmpl)
    T = forward_kinematics(m, q)
    if cs and not fixed_base(tmpl):
        P, V = _contact_kinematics(tmpl, cs, T, v)
        z = P[..., 2]
        stance = z <= z.min(axis=1, keepdims=True) + STANCE_TOLERANCE
        traction = np.array([c.traction for c in cs])
        grip = stance & traction
        count = grip.sum(axis=1)
        u = -np.where(grip[..., None], V, 0.0).sum(axis=1) / np.maximum(count, 1)[:, None]
        u[count == 0] = 0.0
        trunk_acc = np.gradient(_smooth(u, times), times, axis=0) if n > 1 else np.zeros((n, 3))
    else:
        P = np.zeros((n, 0, 3))
        stance = np.zeros((n, 0), dtype=bool)
        trunk_acc = np.zeros((n, 3))
    keep = np.union1d(_thin(times), np.abs(v).argmax(axis=0))  # and each joint's fastest
    return Motion(
        traj.behavior,
        times[keep],
        q[keep],
        v[keep],
        a[keep],
        peak,
        trunk_acc[keep],
        P[keep],
        stance[keep],
        T[keep, :, :3, :3],
        T[keep, :, :3, 3],
    )


def _thin(times: np.ndarray) -> np.ndarray:
    """Indices of samples at least ``SAMPLE_DT`` apart (the first and last kept)."""
    if len(times) < 3:
        return np.arange(len(times))
    dt = float(np.median(np.diff(times)))
    step = max(1, int(math.floor(SAMPLE_DT / dt + 1e-9)))
    idx = np.arange(0, len(times), step)
    if idx[-1] != len(times) - 1:
        idx = np.append(idx, len(times) - 1)
    return idx


# --- the contact solve ----------------------------------------------------------------------


def support_shares_batch(points: np.ndarray, mask: np.ndarray, cop: np.ndarray) -> np.ndarray:
    """``synth.sizing.families.support_shares`` over a batch: vertical shares (B, n) of the contacts
    at ``points`` (B, n, 2) in use where ``mask`` (B, n), holding a load whose centre of
    pressure is ``cop`` (B, 2): total 1 and no moment about ``cop`` (least norm; contacts
    that would have to pull dropped, the most negative first). When ``cop`` is outside
    the contacts the remaining ones share what least squares gives them (the rest would
    tip the robot). Rows without a contact are 0."""
    B, n = mask.shape
    active = mask.copy()
    f = np.zeros((B, n))
    rows = np.flatnonzero(active.any(axis=1))
    for _ in range(n):
        if len(rows) == 0:
            break
        act = active[rows].astype(float)
        d = points[rows] - cop[rows, None, :]
        A = np.stack([act, act * d[..., 0], act * d[..., 1]], axis=1)  # (b, 3, n)
        sol = np.linalg.pinv(A)[:, :, 0]  # least-norm solution of A f = (1, 0, 0)
        f[rows] = np.where(active[rows], sol, 0.0)
        neg = active[rows] & (sol < -1e-12)
        bad = neg.any(axis=1)
        if not bad.any():
            break
        worst = np.argmin(np.where(neg, sol, np.inf), axis=1)
        r = rows[bad]
        active[r, worst[bad]] = False
        rows = r[active[r].sum(axis=1) > 0]
    f = np.where(active, np.clip(f, 0.0, None), 0.0)
    total = f.sum(axis=1, keepdims=True)
    return np.divide(f, total, out=np.zeros_like(f), where=total > 0)


def _wrench_on(R: np.ndarray, o: np.ndarray, point: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Body-frame wrenches (..., 6) of world forces (..., 3) at world points (..., 3) on
    bodies with rotations ``R`` (..., 3, 3) and origins ``o`` (..., 3)."""
    Rt = np.swapaxes(R, -1, -2)
    f = (Rt @ force[..., None])[..., 0]
    mo = (Rt @ np.cross(point - o, force)[..., None])[..., 0]
    return np.concatenate([f, mo], axis=-1)


def behaviour_case(tmpl: Template, mo: Motion) -> BehaviourCase:
    """The external wrenches of motion ``mo`` on ``tmpl`` (its masses): d'Alembert forces
    of the trunk's acceleration and the ground's contact forces (module docstring)."""
    m = tmpl.model
    B, nb = len(mo.times), m.nbodies
    fext = np.zeros((B, nb, 6))
    if mo.points.shape[1] == 0:
        return BehaviourCase(mo.behaviour, mo.times, mo.q, mo.v, mo.a, fext, mo.peak_speed)
    cs = contacts(tmpl)
    masses = np.array([b.mass for b in m.bodies])
    coms = np.array([b.com for b in m.bodies])
    heavy = np.flatnonzero(masses > 0)  # every body with mass at once
    R, o = mo.R[:, heavy], mo.o[:, heavy]
    com_w = o + (R @ coms[heavy][..., None])[..., 0]
    inertial = -masses[heavy][None, :, None] * mo.trunk_acc[:, None, :]
    fext[:, heavy] += _wrench_on(R, o, com_w, inertial)
    W0 = joint_wrenches(m, mo.q, mo.v, mo.a, fext)[:, 0]  # onto the root, root frame
    R0, o0 = mo.R[:, 0], mo.o[:, 0]
    F = (R0 @ W0[:, :3, None])[..., 0]
    M = (R0 @ W0[:, 3:, None])[..., 0] + np.cross(o0, F)
    z0 = np.where(mo.stance, mo.points[..., 2], np.inf).min(axis=1)
    up = (F[:, 2] > 0) & mo.stance.any(axis=1)
    Fz = np.where(up, F[:, 2], 1.0)
    z0 = np.where(up, z0, 0.0)
    cop = np.stack([(z0 * F[:, 0] - M[:, 1]) / Fz, (M[:, 0] + z0 * F[:, 1]) / Fz], axis=1)
    mask = mo.stance & up[:, None]
    shares = support_shares_batch(mo.points[..., :2], mask, cop)
    traction = np.array([c.traction for c in cs])
    grip = shares * traction
    gsum = grip.sum(axis=1, keepdims=True)
    count = (mask & traction).sum(axis=1, keepdims=True)
    hshare = np.where(
        gsum > 1e-12,
        np.divide(grip, gsum, out=np.zeros_like(grip), where=gsum > 1e-12),
        (mask & traction) / np.maximum(count, 1),
    )
    for c, ct in enumerate(cs):
        force = np.zeros((B, 3))
        force[:, 2] = shares[:, c] * np.where(up, F[:, 2], 0.0)
        force[:, :2] = hshare[:, c, None] * np.where(up[:, None], F[:, :2], 0.0)
        fext[:, ct.body] += _wrench_on(mo.R[:, ct.body], mo.o[:, ct.body], mo.points[:, c], force)
    return BehaviourCase(mo.behaviour, mo.times, mo.q, mo.v, mo.a, fext, mo.peak_speed)


def joint_torques(tmpl: Template, wrenches: np.ndarray) -> np.ndarray:
    """Joint torques (B, nv) N m from the joint wrenches (B, nbodies, 6) of
    ``kinematics.dynamics.joint_wrenches``: each moment about its joint's axis."""
    m = tmpl.model
    tau = np.zeros((wrenches.shape[0], m.nv))
    for k, j in enumerate(m.q_joints):
        tau[:, k] = wrenches[:, j, 3:] @ m.joints[j].axis
    return tau


def analyse(tmpl: Template, case: BehaviourCase) -> tuple[np.ndarray, np.ndarray]:
    """Joint torques (B, nv) N m and joint wrenches (B, nbodies, 6) along ``case``."""
    W = joint_wrenches(tmpl.model, case.q, case.v, case.a, case.fext)
    return joint_torques(tmpl, W), W


def motions_for(geometry, tmpl: Template) -> tuple[tuple[Motion, ...], tuple[str, ...]]:
    """The motions of the behaviours of ``geometry`` on ``tmpl`` (the design's template,
    same kinematics), and notes on behaviours left out; cached with the trajectories."""
    key = ("motions", *_key(geometry))
    hit = _TRAJECTORIES.get(key)
    if hit is not None:
        _TRAJECTORIES.move_to_end(key)
        return hit  # type: ignore[return-value]
    if not (contacts(tmpl) or fixed_base(tmpl)):
        out: tuple = ((), ())
    else:
        trajs, notes = behaviour_trajectories(geometry)
        out = (tuple(motion(tmpl, t) for _, t in sorted(trajs.items())), notes)
    _TRAJECTORIES[key] = out  # type: ignore[assignment]
    while len(_TRAJECTORIES) > 2 * CACHE_SIZE:
        _TRAJECTORIES.popitem(last=False)
    return out
