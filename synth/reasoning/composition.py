"""Robot types composed from the part kinds for a request: a serial arm of ``--param dof=N``
joints (the paper's manipulator has four user parameters: object shape, payload, workspace
radius and degrees of freedom).

The arm is written as KIF exactly as the shipped arms are (an ``ArmBase``, N
``PositionServomotor`` and printed ``LinkModule`` parts in one ``connectedTo`` chain,
ending in a ``RoboticGripper``) and joins the knowledge base as a generated source, so
that the reasoner works out its abilities like any other type's: with N >= 3 joints it
positions what it holds, with N >= 6 it also orients it (the ontology's
``requiredPartCount`` of positioning and orienting), and a gripper grasps. Its joints are
the part kinds' ``[serial]`` row for N (names, axes, limits), with a printed link after
each joint the row marks "link" (the shipped rows: after the column's joint and every
pitch joint, as in the paper's 3- and 6-joint arms; a roll joint sits at the end of the
link before it). When the ontology already has a base
configuration that is a serial arm of N joints (the shipped 3- and 6-joint arms), nothing
is composed: ``dof`` then picks that arm.
"""

from __future__ import annotations

from adron.errors import InputError
from kinematics.partkinds import PartKinds

__all__ = ["arm_type_name", "serial_arm_kif"]


def arm_type_name(n: int) -> str:
    """The composed arm's class name."""
    return f"SerialArm{n}DOF"


def serial_arm_kif(n: int, kinds: PartKinds) -> str:
    """The KIF of a serial arm of ``n`` joints (see the module's docstring)."""
    rows = kinds.serial.get(n)
    if rows is None:
        have = ", ".join(str(k) for k in sorted(kinds.serial))
        raise InputError(
            f"--param dof={n}: the part kinds' [serial] table has arms of {have} joints"
        )
    name = arm_type_name(n)
    servos = [f"?S{i}" for i in range(1, n + 1)]
    links = [f"?K{i}" for i, row in enumerate(rows, 1) if row[4]]
    chain = ["?BASE"]
    for i, row in enumerate(rows, 1):
        chain.append(f"?S{i}")
        if row[4]:
            chain.append(f"?K{i}")
    chain.append("?GRIP")
    joints = ", ".join(r[0] for r in rows)
    lits = ["(instance ?BASE ArmBase)", "(instance ?GRIP RoboticGripper)"]
    lits += [f"(instance {s} PositionServomotor)" for s in servos]
    lits += [f"(instance {k} LinkModule)" for k in links]
    lits += [f"(robotPart {v} ?ROB)" for v in ["?BASE", *servos, *links, "?GRIP"]]
    lits += [f"(connectedTo {a} {b})" for a, b in zip(chain, chain[1:], strict=False)]
    body = "\n      ".join(lits)
    return f"""\
;; Composed by parmor for --param dof={n}: a serial arm of {n} joints ({joints}).
(subclass {name} IndustrialRobot)
(instance {name} BaseConfiguration)
(documentation {name} EnglishLanguage "A stationary arm of {n} joints ({joints}) ending \
in a gripper, composed from the part kinds for --param dof={n}.")
(=>
  (instance ?ROB {name})
  (exists (?BASE ?GRIP {" ".join(servos)} {" ".join(links)})
    (and
      {body})))
"""
