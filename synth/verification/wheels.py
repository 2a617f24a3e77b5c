"""The wheels' answer to a perturbed run they break: a stiffer wheel servo, measured.

A wheel servo is a DC motor line (``export.mjcf``: a velocity servo of gain ``kv =
stall torque / no-load speed``): under a load torque tau it turns ``tau / kv`` slower
than commanded. An open-loop plan commands each wheel its speed plus the droop of the
load it predicts on flat ground of the catalog's friction; whatever load it cannot know
(a floor's slope across the robot's path pulling its centre of mass sideways, a floor of
other friction, a heavier robot) turns the wheels by another ``delta tau / kv``, and the
robot veers or turns by another angle. Measured on the designed differential drive with
1 kg (FS90R wheels): 1.9-2.9 deg of cross slope veered its 5 s drive by 23-37 deg; the
same runs with the wheels' ``kv`` x 2, 4, 8, 32: 16-25, 8-15, 9, 2 deg. A stiffer servo
(more torque for its speed) is the answer no plan can give.

:func:`wheel_blame` measures it as :func:`synth.verification.robust.play_blame` measures the play:
the failed perturbed runs of each behaviour that is not robust (up to
:data:`synth.verification.robust.BLAMED_RUNS`, the worst first) are replayed under the very same
perturbation with the wheel servos swapped for each stiffer servo of the catalog that
serves them (same class, continuous rotation, holding the joint's required torque at its
required speed; the least stiff first): the first with which every replayed run passes is
the answer: the next sizing may give the wheels no servo less stiff than it
(:func:`wheel_exclusions`, as :func:`synth.verification.robust.less_play` excludes servos of too
much play). The replay is the bundle with the swapped servo in both files:
``design.json``'s joint (stall torque, no-load speed: what the controller plans with) and
``robot.xml``'s velocity servo (``kv``, ``ctrlrange``, ``forcerange``, the rotor's
armature), so its plans and its model are those the next sizing gives (less the modules'
own mass, which that sizing's verification then includes). None answers it when the
stiffest does not make every run pass: the failure stands, and :func:`wheel_note` says so.

Wheels are read off the structure (a joint whose actuator turns without an end stop);
no robot type is named.

How the loop (:mod:`synth.verification.loop`) asks it: :class:`Wheels`, a cause
(:mod:`synth.verification.causes`): where a round's perturbed runs failed and no actuator
saturated, :func:`wheel_exclusions` on the round's bundle gives joint -> the models
excluded (empty: no wheel, or no stiffer wheel servo makes them pass), merged into the
round's exclusions before it sizes again. The replays stop at a failure: whether they pass
is all that is asked.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import TYPE_CHECKING

from export.mjcf import servo_gains
from export.urdf import number, numbers
from gaits import controller_for
from gaits.base import DesignGeometry
from synth.sizing.structure import meets
from synth.verification.causes import Remedy, Round
from synth.verification.robust import BLAMED_RUNS, worst_failures
from synth.verification.runs import Perturbed

if TYPE_CHECKING:
    from adron.catalog import Actuator, Catalog
    from synth.verification.results import RobustRuns, Run
    from synth.verification.source import Bundle

#: A stiffer servo's kv must exceed the wheel's by this factor (else it is the same motor line).
STIFFER = 1.0001


def wheel_joints(record: Mapping, catalog: Catalog) -> dict[str, Actuator]:
    """The design's wheel joints -> their actuator: the joints of its template's wheels
    whose catalog actuator turns without an end stop (continuous rotation: a velocity servo
    in the MJCF). A leg's joint on a servo that can also turn continuously (a DYNAMIXEL) is
    not a wheel."""
    by_model = {a.model: a for a in catalog.actuators}
    turning = [
        j
        for j in record.get("joints", ())
        if getattr(by_model.get(j.get("actuator")), "continuous", False)
    ]
    if not turning:
        return {}
    wheels = set(controller_for(DesignGeometry.from_record(record)).template.wheel_joints)
    return {j["name"]: by_model[j["actuator"]] for j in turning if j["name"] in wheels}


def kv(a: Actuator) -> float:
    """The motor line's gain N m s/rad of actuator ``a`` (stall torque / no-load speed)."""
    return a.stall_torque_Nm / a.no_load_speed_rad_s


def stiffer_servos(record: Mapping, catalog: Catalog) -> list[Actuator]:
    """The catalog's servos that may replace every wheel servo of the design, the least
    stiff first: of the wheels' class (the record's ``module_class``), continuous,
    stiffer than each wheel's (``kv`` x :data:`STIFFER`), holding each wheel's required
    torque at its required speed (``synth.sizing.structure.meets``)."""

    wheels = wheel_joints(record, catalog)
    joints = [j for j in record.get("joints", ()) if j["name"] in wheels]
    if not joints:
        return []
    out = []
    for a in catalog.actuators:
        if not a.continuous or a.no_load_speed_rad_s <= 0:
            continue
        if any(
            a.ontology_class != j.get("module_class")
            or kv(a) <= kv(wheels[j["name"]]) * STIFFER
            or not meets(
                a,
                float(j.get("required_torque_Nm") or 0.0),
                float(j.get("required_speed_rad_s") or 0.0),
                catalog,
            )
            for j in joints
        ):
            continue
        out.append(a)
    return sorted(out, key=lambda a: (kv(a), a.cost, a.model))


def swapped(bundle: Bundle, joints: list[str], actuator: Actuator) -> Bundle:
    """``bundle`` with ``actuator`` driving ``joints`` (wheels): the record's stall torque
    and no-load speed, the MJCF's velocity servo (``kv``, ``ctrlrange``, ``forcerange``)
    and the joint's armature, as ``export.mjcf`` writes them."""
    import xml.etree.ElementTree as ET

    def text(v: str | bytes) -> str:
        return v.decode("utf-8") if isinstance(v, bytes) else v

    names = set(joints)
    files = bundle.files
    record = json.loads(text(files["design.json"]))
    for j in record.get("joints", ()):
        if j["name"] in names:
            j["actuator"] = actuator.model
            j["actuator_torque_Nm"] = actuator.stall_torque_Nm
            j["no_load_speed_rad_s"] = actuator.no_load_speed_rad_s
    effort, speed = actuator.stall_torque_Nm, actuator.no_load_speed_rad_s
    gain, armature = servo_gains(effort, speed, continuous=True)
    root = ET.fromstring(text(files["robot.xml"]))
    for act in root.iter("velocity"):
        if act.get("joint") in names:
            act.set("kv", number(gain))
            act.set("ctrlrange", numbers((-speed, speed)))
            act.set("forcerange", numbers((-effort, effort)))
    for joint in root.iter("joint"):
        if joint.get("name") in names:
            joint.set("armature", number(armature))
    return bundle.with_files(
        {"design.json": json.dumps(record), "robot.xml": ET.tostring(root, encoding="unicode")}
    )


def _failed_runs(robust: RobustRuns) -> list[tuple[str, int, Run | None]]:
    """(behaviour, seed, the run) of the failed perturbed runs replayed: those
    ``play_blame`` replays (``synth.verification.robust.worst_failures``)."""

    return worst_failures(robust, BLAMED_RUNS)


def wheel_blame(bundle: Bundle, robust: RobustRuns | None, catalog: Catalog) -> dict | None:
    """Does a stiffer wheel servo make the failed perturbed runs pass? Measured (module
    docstring): ``{"model": the first servo of :func:`stiffer_servos` with which every
    replayed run passes, "from": the wheels' servo, "joints": the wheels, "runs": [{behavior,
    seed, verdict (as failed), "figures": {"with": the failed run's criteria figures,
    "stiffer": the replay's}}]}``; None without wheels, without a failed run, or when
    none of them makes every run pass (``{"model": None, "tried": [...]}`` then, so that a
    refusal can say so)."""
    if not robust or not robust.table:
        return None

    runs = _failed_runs(robust)
    if not runs:
        return None
    record = bundle.record
    wheels = wheel_joints(record, catalog)
    if not wheels:
        return None
    candidates = stiffer_servos(record, catalog)
    joints = sorted(wheels)
    table = robust.table
    for a in candidates:
        trial = swapped(bundle, joints, a)
        replays = []
        for behavior, seed, failed in runs:
            plan = trial.controller().run(behavior)
            run = Perturbed(trial, table, seed).run(plan, stop_on_failure=True)
            if not run.ok:
                break
            replays.append(
                {
                    "behavior": behavior,
                    "seed": seed,
                    "verdict": failed.verdict if failed else [],
                    "figures": {
                        "with": failed.criteria() if failed else {},
                        "stiffer": run.criteria(),
                    },
                }
            )
        else:
            return {
                "model": a.model,
                "from": sorted({w.model for w in wheels.values()}),
                "joints": joints,
                "runs": replays,
            }
    return {
        "model": None,
        "from": sorted({w.model for w in wheels.values()}),
        "joints": joints,
        "tried": [a.model for a in candidates],
    }


def wheel_exclusions(
    bundle: Bundle,
    robust: RobustRuns | None,
    catalog: Catalog,
    excluded: Mapping[str, frozenset[str]] | None = None,
) -> tuple[dict[str, frozenset[str]], dict | None]:
    """The wheels' answer for the next sizing: each wheel joint -> the models it may no
    longer have (``excluded``'s and every continuous servo less stiff than the one
    :func:`wheel_blame` measured as the answer: the sizing then picks that one or a stiffer
    one that meets the joint's operating points), new entries only; and what
    :func:`wheel_blame` found (None: no wheel or no failed run). Empty when no stiffer
    wheel servo makes the failed runs pass."""
    excluded = excluded or {}
    found = wheel_blame(bundle, robust, catalog)
    if not found or found["model"] is None:
        return {}, found
    answer = next(x for x in catalog.actuators if x.model == found["model"])
    looser = frozenset(
        a.model for a in catalog.actuators if a.continuous and kv(a) * STIFFER < kv(answer)
    )
    out = {}
    for j in found["joints"]:
        ex = excluded.get(j, frozenset()) | looser
        if ex != excluded.get(j):
            out[j] = ex
    return out, found


def wheel_note(found: Mapping | None, behavior: str) -> str:
    """What a refusal adds when the wheels' servos were tried stiffer for ``behavior``
    and none made it pass; "" otherwise."""
    if not found or found.get("model") is not None:
        return ""
    wheels = f"{', '.join(found['joints'])} ({', '.join(found['from'])})"
    tried = found.get("tried")
    if not tried:
        return f"; the catalog has no stiffer servo that drives the wheels {wheels} as fast"
    return f"; stiffer servos for the wheels {wheels}, {', '.join(tried)}, do not make it pass"


class Wheels:
    """The wheels' servos as a cause of the loop (:class:`synth.verification.causes.
    Cause`): on a robot with wheels, the failed runs replayed with each stiffer wheel servo
    (:func:`wheel_exclusions`); the answer is a sizing without the servos less stiff."""

    name = "wheels"

    def __init__(self) -> None:
        self.at = 0  # the round it was last measured on, and what it found there
        self.found: dict | None = None
        self.first: dict[str, str] = {}  # wheel joint -> its servo before a stiffer one
        self.runs: list[dict] = []  # the perturbed runs that called for the stiffer wheels

    def applies(self, now: Round) -> bool:
        """The design has wheels (:func:`wheel_joints`)."""
        return bool(wheel_joints(now.record, now.catalog))

    def explains(self, now: Round) -> Remedy | None:
        stiffer, self.found = wheel_exclusions(now.bundle(), now.robust, now.catalog, now.excluded)
        self.at = now.number
        return Remedy((stiffer,)) if stiffer else None

    def taken(self, now: Round, sizing: Mapping[str, frozenset[str]]) -> None:
        self.runs += (self.found or {}).get("runs", [])
        for j in sizing:
            self.first.setdefault(j, now.models[j])

    def note(self, behavior: str, final: int) -> str:
        return wheel_note(self.found, behavior) if self.at == final else ""

    def record(self, models: Mapping[str, str]) -> dict | None:
        """``verified.wheels``: each wheel's servo swapped (from, to) and the runs that
        called for it; None when none was."""
        if not self.first:
            return None
        return {
            "swapped": {j: {"from": m, "to": models.get(j)} for j, m in sorted(self.first.items())},
            "runs": self.runs,
        }
