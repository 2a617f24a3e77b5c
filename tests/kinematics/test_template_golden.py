"""The eight shipped robot types assemble, from their ontology body plans and the part
kinds' data, to the templates the per-type builders made before them (issue 20).

``tests/golden/templates.json`` was written by those builders (the last release that had
them) at two parameter sets: the defaults, and printed link modules with face plates,
fillets and dovetails, three fingers, a 5-module snake and other masses. Joints (name,
parent, child, kind, origin, axis, limits, group), bodies (mass, centre of mass,
inertia), printed segments, feet, wheels and lengths must agree to 1e-9.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from kinematics.templates import TemplateParams, build

GOLDEN = json.loads((Path(__file__).resolve().parents[1] / "golden" / "templates.json").read_text())

VARIANTS = (
    TemplateParams(),
    TemplateParams(
        payload=0.3,
        trunk_mass=0.4,
        modules=5,
        wheel_radius=0.045,
        fingers=3,
        face_side=0.05,
        face_thickness=0.004,
        fillet=0.003,
        dovetail_clearance=0.0002,
        actuator_size=(0.041, 0.021, 0.038),
    ),
)


def _snapshot(t) -> dict:
    m = t.model
    return {
        "joints": [
            [j.name, j.parent, j.child, j.kind, np.asarray(j.origin).tolist(),
             np.asarray(j.axis).tolist(), j.lower, j.upper, j.group]
            for j in m.joints
        ],
        "bodies": [
            [b.name, b.mass, np.asarray(b.com).tolist(), np.asarray(b.inertia).tolist()]
            for b in m.bodies
        ],
        "segments": [
            [s.name, s.body, s.start.tolist(), s.direction.tolist(), s.length, s.r_outer,
             s.r_inner, s.distal_joint, s.length_name]
            for s in t.segments
        ],
        "extra": [
            list(t.end_effectors), list(t.feet), [p.tolist() for p in t.foot_points],
            list(t.wheels), t.legs, t.arms, list(t.length_names), list(t.casters),
            dict(t.lengths),
        ],
    }  # fmt: skip


def _same(a, b, path: str) -> list[str]:
    if isinstance(a, dict):
        if sorted(a) != sorted(b):
            return [f"{path}: keys {sorted(a)} != {sorted(b)}"]
        return [d for k in a for d in _same(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items != {len(b)}"]
        return [
            d
            for i, (x, y) in enumerate(zip(a, b, strict=True))
            for d in _same(x, y, f"{path}[{i}]")
        ]
    if isinstance(a, float) or isinstance(b, float):
        ok = a is not None and b is not None and abs(a - b) <= 1e-9 * max(1.0, abs(a))
        return [] if ok else [f"{path}: {a} != {b}"]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


@pytest.mark.parametrize("key", sorted(GOLDEN))
def test_a_shipped_type_assembles_to_its_former_template(key) -> None:
    robot_type, variant = key.split("/")
    mine = json.loads(json.dumps(_snapshot(build(robot_type, VARIANTS[int(variant)]))))
    diffs = _same(GOLDEN[key], mine, key)
    assert not diffs, "\n".join(diffs[:20])


def test_the_golden_check_can_fail() -> None:
    """A template one joint limit away from the golden one is told apart."""
    t = _snapshot(build("HexapodRobot", VARIANTS[0]))
    t["joints"][1][7] += 1e-6
    assert _same(GOLDEN["HexapodRobot/0"], json.loads(json.dumps(t)), "x")
