"""MJCF (MuJoCo) model of an :class:`~export.model3d.Assembly` (pure: returns the text).

Choices, all in one place:

- **Simulation**: ``timestep = 0.002`` s with the ``implicitfast`` integrator. Joint
  damping and the servos' velocity gains (``kv``) are then integrated implicitly, which
  keeps the light printed links (a few grams at centimetres) stable with stiff servo gains;
  2 ms is MuJoCo's default step and resolves the fastest servo loop (see armature below).
- **Frames**: the root body sits at ``(0, 0, spawn_height)`` with a ``<freejoint/>``
  (unnamed, so it cannot clash with a design's joint names) unless ``fixed_base``; every
  other body is nested in its parent with ``pos``/``quat`` of its joint origin and a hinge
  about the joint axis (body frame = joint frame, as in URDF). Fixed joints nest the body
  without a joint.
- **Inertia**: ``inertiafromgeom="false"``: each body's ``<inertial>`` is the assembly's
  (mass, COM) and its inertia tensor diagonalised with ``numpy.linalg.eigh``: ``quat`` is
  the principal frame, its axes ordered and signed to be closest to the body axes
  (deterministic), right-handed. Principal moments are floored at
  ``max(1e-12 kg m^2, 1e-9 x the largest)`` so point masses and ideal thin rods compile
  (MuJoCo needs ``A + B >= C`` and positive moments); masses are exact. A body of zero mass
  has no ``<inertial>`` (legal for welded bodies). The model's total mass is the assembly's.
- **Contacts**: robot geoms ``contype=2 conaffinity=1``, the floor ``contype=1
  conaffinity=1``. MuJoCo collides two geoms when ``contype_a & conaffinity_b`` or
  ``contype_b & conaffinity_a`` is non-zero, so robot-floor (2&1 or 1&1) collides, robot-
  robot (2&1) never does (the printed parts interpenetrate at the joints by design), and
  any object added later with MuJoCo's defaults (1, 1) collides with the robot and the
  floor. Robot geoms have ``priority="1"``, so their friction, not the floor's, applies.
  A fixed base is welded to the world, so MuJoCo never collides it with the floor.
- **Friction** (sliding, torsional, rolling; MuJoCo's ``condim=3`` unless said): printed
  PLA on a floor ``0.5``; geoms of foot bodies ``1.0`` with ``condim=4`` (rubber-like pads
  that also resist spinning on the ground); geoms of wheel bodies ``1.0`` (tyres roll
  without slipping); geoms of caster bodies ``0.05`` (a ball caster turns freely, modelled
  as a low-friction slider). Snake modules (no feet or wheels) keep the isotropic PLA
  value: the snake's gaits (rolling, sidewinding, rectilinear) need no anisotropy.
  Solver softness (``solref``/``solimp``) stays MuJoCo's default.
- **Actuators**: a ``<position>`` servo per revolute joint with ``kp = effort / 0.05 rad``
  (the stall torque is reached at a 3 degree error, a hobby servo's proportional band; at
  0.1 rad the designed humanoid's SG90 ankles are softer than its inverted pendulum and it
  sinks over), ``forcerange = +-effort`` (stall torque), ``ctrlrange`` = the joint range. A
  ``<velocity>`` servo per continuous joint (wheels) with ``kv = effort / velocity``, which
  with ``ctrlrange = +-velocity`` is exactly the DC motor line (stall torque at rest, zero
  torque at the no-load speed; ``kv = effort / 1 rad/s`` when no speed is given), and
  ``forcerange = +-effort``. Every revolute and continuous joint must have ``effort > 0``
  but a passive one (a free wheel's, ``JointSpec.passive``): a hinge with no actuator and
  its bearing's small damping (``export.urdf.PASSIVE_DAMPING``).
- **Joint dynamics**: ``armature = (effort / 0.05 rad) * (4 dt)^2``, the gear-reflected
  rotor inertia the catalog does not give, of the order of a hobby servo's (1e-4..1e-3 kg
  m^2); it keeps each position loop's natural frequency at most ``1 / (4 dt)`` = 125 rad/s,
  well inside the step's stability limit even for an unloaded joint. A wheel's armature is
  at least ``kv * WHEEL_MOTOR_TIME_CONSTANT`` (its geared motor's reflected inertia), and a
  model with wheels uses MuJoCo's elliptic friction cone (``WHEELED_CONE``). A revolute
  joint's passive ``damping = effort / velocity`` is the motor's back-EMF: with the servo
  saturated at its stall torque the joint tends to the no-load speed, as on the motor line.
  The position servo's derivative gain ``kv`` (inside ``forcerange``, as in a real servo's
  controller) tops the damping up to critical, ``2 sqrt(kp (I + armature))``, with ``I`` the
  inertia of the joint's subtree about its axis at ``q = 0``.
"""

from __future__ import annotations

import itertools
import math
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING

import numpy as np

from export.assembly import with_payload as loaded
from export.model3d import Assembly, BodySpec, Geometry, JointSpec
from export.urdf import (
    MESH_SCALE,
    SNAP,
    check_assembly,
    joint_damping,
    mesh_file,
    number,
    numbers,
    symmetric_inertia,
    unit_axis,
)

if TYPE_CHECKING:  # mujoco is imported only by load_mjcf
    import mujoco

TIMESTEP = 0.002  # s
INTEGRATOR = "implicitfast"
#: Position error (rad) at which a servo gives its stall torque: kp = effort / SERVO_BAND.
SERVO_BAND = 0.05
#: Robot geoms: contype, conaffinity; the floor's are (1, 1). See the module docstring.
ROBOT_CONTACT = (2, 1)
FLOOR_CONTACT = (1, 1)
#: Mechanical time constant (s) of a wheel servo's geared motor: the gear-reflected rotor
#: inertia is ``kv * WHEEL_MOTOR_TIME_CONSTANT`` (kv = stall torque / no-load speed, the
#: motor line's slope), a small geared DC motor's 20-50 ms. Controllers that feed forward a
#: wheel's acceleration use the same value (``gaits.wheeled``).
WHEEL_MOTOR_TIME_CONSTANT = 0.05
#: Friction cone of models with wheels: elliptic (MuJoCo's pyramid lets a sliding tyre
#: push sideways harder than along its rolling direction, so a skid-steer robot turning
#: in place scrubs as if its wheel base were about twice as long; measured). The pyramid is
#: also anisotropic in the world's x/y: a differential robot's sliding caster drags with a
#: moment that changes with its heading, and on an arc its yaw rate swings with it (measured:
#: 0.08-0.5 rad/s for a commanded 0.46), so every model with wheels gets the elliptic cone.
WHEELED_CONE = "elliptic"
#: Geom default classes: (class, condim, friction sliding/torsional/rolling).
CONTACT_CLASSES = (
    ("robot", 3, (0.5, 0.005, 0.0001)),
    ("foot", 4, (1.0, 0.005, 0.0001)),
    ("wheel", 3, (1.0, 0.005, 0.0001)),
    ("caster", 3, (0.05, 0.005, 0.0001)),
)


# --- numbers --------------------------------------------------------------------------------


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation (3,3); ``w >= 0`` (first non-zero > 0)."""
    R = np.asarray(R, dtype=float)
    t = np.trace(R)
    if t > 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] >= R[1, 1] and R[0, 0] >= R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] >= R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.array(q) / np.linalg.norm(q)
    q[np.abs(q) < SNAP] = 0.0
    first = q[np.flatnonzero(q)[0]]
    return -q if first < 0 else q


def principal_inertia(inertia: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (3,) kg m^2 and axes (3,3, columns; a rotation) of a tensor.

    Axes are permuted and signed to be closest to the body axes, then made right-handed;
    a tensor that is already diagonal keeps the body axes exactly. Moments are floored at
    ``max(1e-12, 1e-9 * largest)`` (see the module docstring).
    """
    inertia = symmetric_inertia(inertia, what)
    if not np.any(inertia - np.diag(np.diag(inertia))):
        moments, axes = np.diag(inertia).copy(), np.eye(3)
    else:
        w, V = np.linalg.eigh(inertia)
        perm = max(
            itertools.permutations(range(3)),
            key=lambda p: sum(abs(V[i, p[i]]) for i in range(3)),
        )
        axes, moments = V[:, perm].copy(), w[list(perm)].copy()
        for i in range(3):
            if axes[i, i] < 0:
                axes[:, i] = -axes[:, i]
        if np.linalg.det(axes) < 0:
            k = int(np.argmin(np.abs(np.diag(axes))))
            axes[:, k] = -axes[:, k]
    if np.min(moments) < -1e-9 * max(np.max(moments), 0.0) - 1e-15:
        raise ValueError(f"{what}: inertia is not positive semi-definite")
    return np.maximum(moments, max(1e-12, 1e-9 * float(np.max(moments)))), axes


# --- model quantities ----------------------------------------------------------------------


def _world_frames(assembly: Assembly) -> dict[str, np.ndarray]:
    """Frame (4,4) of every body in the root frame at q = 0."""
    frames = {assembly.root: np.eye(4)}
    for j in assembly.joints:
        frames[j.child] = frames[j.parent] @ np.asarray(j.origin, dtype=float)
    return frames


def _subtree_inertia(
    assembly: Assembly, bodies: dict[str, BodySpec], frames: dict[str, np.ndarray], j: JointSpec
) -> float:
    """Inertia (kg m^2) of everything moved by joint ``j`` about its axis at q = 0."""
    children: dict[str, list[str]] = {}
    for k in assembly.joints:
        children.setdefault(k.parent, []).append(k.child)
    T = frames[j.child]
    a, p = T[:3, :3] @ unit_axis(j.axis, j.name), T[:3, 3]
    total, stack = 0.0, [j.child]
    while stack:
        name = stack.pop()
        stack.extend(children.get(name, ()))
        b, Tb = bodies[name], frames[name]
        R = Tb[:3, :3]
        r = Tb[:3, :3] @ np.asarray(b.com, dtype=float) + Tb[:3, 3] - p
        r_perp = r - (r @ a) * a
        total += float(a @ R @ np.asarray(b.inertia, dtype=float) @ R.T @ a)
        total += b.mass * float(r_perp @ r_perp)
    return total


def _gains(j: JointSpec) -> tuple[float, float]:
    """(kp or kv, armature) of the servo of a movable joint."""
    if not (math.isfinite(j.effort) and j.effort > 0):
        raise ValueError(f"joint {j.name!r} moves but has no actuator effort ({j.effort})")
    return servo_gains(j.effort, j.velocity, j.kind == "continuous")


def servo_gains(effort: float, velocity: float, continuous: bool) -> tuple[float, float]:
    """(kp or kv, armature) of a servo of stall torque ``effort`` N m and no-load speed
    ``velocity`` rad/s: a position servo's ``kp = effort / SERVO_BAND``, or, turning without
    an end stop (``continuous``), a velocity servo's ``kv = effort / velocity``; the armature
    of the module docstring."""
    kp = effort / SERVO_BAND
    armature = kp * (4.0 * TIMESTEP) ** 2
    if continuous:
        speed = velocity if math.isfinite(velocity) and velocity > 0 else 1.0
        kv = effort / speed
        return kv, max(armature, kv * WHEEL_MOTOR_TIME_CONSTANT)
    return kp, armature


# --- XML -------------------------------------------------------------------------------------


def _pose(el: ET.Element, T: np.ndarray) -> None:
    T = np.asarray(T, dtype=float)
    el.set("pos", numbers(T[:3, 3], SNAP))
    q = quat_from_matrix(T[:3, :3])
    if not np.array_equal(q, [1.0, 0.0, 0.0, 0.0]):
        el.set("quat", numbers(q))


def _geom_class(assembly: Assembly, body: str) -> str | None:
    if body in assembly.feet:
        return "foot"
    if body in assembly.wheels:
        return "wheel"
    if body in assembly.casters:
        return "caster"
    return None


def _geom(parent: ET.Element, g: Geometry, name: str, cls: str | None) -> None:
    el = ET.SubElement(parent, "geom", name=name)
    if cls is not None:
        el.set("class", cls)
    size = [float(s) for s in g.size]
    if g.kind == "mesh":
        el.set("type", "mesh")
        el.set("mesh", mesh_file(g.mesh)[:-4])
    elif g.kind == "box" and len(size) == 3:
        el.set("type", "box")
        el.set("size", numbers([0.5 * s for s in size]))
    elif g.kind == "cylinder" and len(size) == 2:
        el.set("type", "cylinder")
        el.set("size", numbers([size[0], 0.5 * size[1]]))
    elif g.kind == "sphere" and len(size) == 1:
        el.set("type", "sphere")
        el.set("size", number(size[0]))
    else:
        raise ValueError(f"geometry {name!r}: kind {g.kind!r} with size {size} is not supported")
    _pose(el, g.origin)
    el.set("rgba", numbers(g.rgba))
    if not g.contact:
        el.set("contype", "0")
        el.set("conaffinity", "0")


def _body_content(el: ET.Element, body: BodySpec, cls: str | None, meshes: dict[str, str]) -> None:
    if body.mass > 0:
        moments, axes = principal_inertia(body.inertia, f"body {body.name!r}")
        inertial = ET.SubElement(el, "inertial", pos=numbers(body.com, SNAP))
        q = quat_from_matrix(axes)
        if not np.array_equal(q, [1.0, 0.0, 0.0, 0.0]):
            inertial.set("quat", numbers(q))
        inertial.set("mass", number(body.mass))
        inertial.set("diaginertia", numbers(moments))
    i = 0
    for part in body.parts:
        g = part.geometry
        if g is None:
            continue
        if g.kind == "mesh":
            file = mesh_file(g.mesh)
            if meshes.setdefault(file[:-4], file) != file:
                raise ValueError(f"mesh files {meshes[file[:-4]]!r} and {file!r} share a name")
        _geom(el, g, f"{body.name}/{i}", cls)
        i += 1


def _preamble(root: ET.Element, mesh_dir: str) -> tuple[ET.Element, ET.Element]:
    """Compiler, options, contact classes, the floor and a light; (asset, worldbody)."""
    compiler = {"angle": "radian", "meshdir": mesh_dir, "autolimits": "true"}
    ET.SubElement(root, "compiler", compiler, inertiafromgeom="false")
    ET.SubElement(root, "option", timestep=number(TIMESTEP), integrator=INTEGRATOR)
    default = ET.SubElement(root, "default")
    (robot, condim, friction), *kinds = CONTACT_CLASSES
    robot_cls = ET.SubElement(default, "default", {"class": robot})
    contact = {"contype": str(ROBOT_CONTACT[0]), "conaffinity": str(ROBOT_CONTACT[1])}
    ET.SubElement(
        robot_cls, "geom", contact, priority="1", condim=str(condim), friction=numbers(friction)
    )
    for name, condim, friction in kinds:
        cls = ET.SubElement(robot_cls, "default", {"class": name})
        ET.SubElement(cls, "geom", condim=str(condim), friction=numbers(friction))

    asset = ET.SubElement(root, "asset")
    checker = {"name": "grid", "type": "2d", "builtin": "checker", "rgb1": "0.2 0.3 0.4"}
    ET.SubElement(asset, "texture", checker, rgb2="0.1 0.2 0.3", width="512", height="512")
    ET.SubElement(asset, "material", name="grid", texture="grid", texrepeat="8 8")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", name="sun", pos="0 0 3", dir="0 0 -1", directional="true")
    floor = {"name": "floor", "type": "plane", "size": "0 0 0.05", "material": "grid"}
    contact = {"contype": str(FLOOR_CONTACT[0]), "conaffinity": str(FLOOR_CONTACT[1])}
    ET.SubElement(world, "geom", {**floor, **contact})
    return asset, world


def _servo(el: ET.Element, j: JointSpec, inertia: float) -> tuple[str, dict[str, str]]:
    """Add the hinge of movable joint ``j`` to body ``el``; its actuator (tag, attributes).

    ``inertia``: the joint's subtree inertia about its axis at q = 0, kg m^2.
    """
    gain, armature = _gains(j)
    axis = numbers(unit_axis(j.axis, j.name), SNAP)
    joint = ET.SubElement(el, "joint", name=j.name, type="hinge", axis=axis)
    attrs = {"name": j.name, "joint": j.name}
    has_speed = math.isfinite(j.velocity) and j.velocity > 0
    if j.kind == "revolute":
        joint.set("range", numbers((j.lower, j.upper)))
        emf = joint_damping(j)
        if emf > 0:
            joint.set("damping", number(emf))
        kv = max(0.0, 2.0 * math.sqrt(gain * (inertia + armature)) - emf)
        attrs.update(kp=number(gain), kv=number(kv), ctrlrange=numbers((j.lower, j.upper)))
        tag = "position"
    else:
        attrs["kv"] = number(gain)
        if has_speed:
            attrs["ctrlrange"] = numbers((-j.velocity, j.velocity))
        tag = "velocity"
    joint.set("armature", number(armature))
    attrs["forcerange"] = numbers((-j.effort, j.effort))
    return tag, attrs


def mjcf_string(assembly: Assembly, mesh_dir: str = "meshes", with_payload: bool = False) -> str:
    """MJCF text of ``assembly`` for MuJoCo (choices in the module docstring).

    Mesh geoms name their files relative to ``mesh_dir`` (the compiler's ``meshdir``);
    load the text with :func:`load_mjcf` or with the files beside it. Identical input gives
    identical text. Raises ``ValueError`` on an invalid tree, name or mesh file name, or a
    movable joint without effort. ``with_payload``: the payload (``Assembly.payload``) is
    added to the body that holds it (the verification simulates the loaded robot).
    """
    if with_payload:
        assembly = loaded(assembly)
    bodies = check_assembly(assembly)
    if "world" in bodies:
        raise ValueError("a body cannot be named 'world' in MJCF (MuJoCo's world body)")
    frames = _world_frames(assembly)

    root = ET.Element("mujoco", model=assembly.robot_type)
    asset, world = _preamble(root, mesh_dir)
    if assembly.wheels:
        root.find("option").set("cone", WHEELED_CONE)  # type: ignore[union-attr]

    meshes: dict[str, str] = {}  # mesh asset name -> file
    spawn = numbers((0.0, 0.0, assembly.spawn_height), SNAP)
    base = ET.SubElement(world, "body", name=assembly.root, pos=spawn, childclass="robot")
    if not assembly.fixed_base:
        ET.SubElement(base, "freejoint")
    _body_content(base, bodies[assembly.root], _geom_class(assembly, assembly.root), meshes)
    elements = {assembly.root: base}
    actuators: list[tuple[str, dict[str, str]]] = []
    for j in assembly.joints:
        el = ET.SubElement(elements[j.parent], "body", name=j.child)
        _pose(el, j.origin)
        if j.passive:
            axis = numbers(unit_axis(j.axis, j.name), SNAP)
            ET.SubElement(el, "joint", name=j.name, type="hinge", axis=axis).set(
                "damping", number(joint_damping(j))
            )
        elif j.kind != "fixed":
            actuators.append(_servo(el, j, _subtree_inertia(assembly, bodies, frames, j)))
        _body_content(el, bodies[j.child], _geom_class(assembly, j.child), meshes)
        elements[j.child] = el

    for name, file in sorted(meshes.items()):
        ET.SubElement(asset, "mesh", name=name, file=file, scale=numbers([MESH_SCALE] * 3))
    act = ET.SubElement(root, "actuator")
    for tag, attrs in actuators:
        ET.SubElement(act, tag, attrs)
    _imu_sensors(root, assembly, elements)
    ET.indent(root, space="  ")
    return ET.tostring(root, "unicode") + "\n"


#: the catalog class of an inertial measurement unit (as :data:`gaits.feedback.IMU_CLASS`)
IMU_CLASS = "IMUSensorModule"


def _imu_sensors(root: ET.Element, assembly: Assembly, elements: dict[str, ET.Element]) -> None:
    """A site at each IMU module's centre (the first is ``imu``; others ``imu_1``...) and its
    MuJoCo sensors: ``imu_gyro`` (rad/s) and ``imu_accel`` (m/s^2, specific force) in the
    module's frame (the body's axes). What the feedback loops read (:mod:`gaits.feedback`);
    the noise is added by the runner from the perturbation table (MuJoCo adds none)."""
    found = [
        (body.name, part)
        for body in assembly.bodies
        for part in body.parts
        if part.kind == IMU_CLASS
    ]
    if not found:
        return
    sensor = ET.SubElement(root, "sensor")
    for k, (body, part) in enumerate(found):
        site = "imu" if k == 0 else f"imu_{k}"
        ET.SubElement(elements[body], "site", name=site, pos=numbers(part.com, SNAP), size="0.005")
        ET.SubElement(sensor, "gyro", name=f"{site}_gyro", site=site)
        ET.SubElement(sensor, "accelerometer", name=f"{site}_accel", site=site)


def load_mjcf(xml: str, meshes: dict[str, bytes]) -> mujoco.MjModel:
    """Compile MJCF text with its mesh files given in memory (file name -> bytes).

    Keys are the files' names (``NAME.stl``; a bare ``NAME`` is given ``.stl``). MuJoCo
    matches in-memory assets by file name; should a version want the ``meshdir`` prefix
    instead, the load is retried with ``MESHDIR/NAME.stl`` keys.
    """
    import mujoco

    assets = {mesh_file(name): data for name, data in sorted(meshes.items())}
    try:
        return mujoco.MjModel.from_xml_string(xml, assets=assets)
    except ValueError as first:
        compiler = ET.fromstring(xml).find("compiler")
        d = (compiler.get("meshdir", "") if compiler is not None else "").rstrip("/")
        if not d or not assets:
            raise
        prefixed = {f"{d}/{file}": data for file, data in assets.items()}
        try:
            return mujoco.MjModel.from_xml_string(xml, assets=prefixed)
        except ValueError:
            raise first from None
