"""Robust verification in the design loop: a sized design's behaviours run under K seeded
perturbations (:mod:`export.perturb`, :func:`export.verify.verify_robust`) once they pass
on the nominal model, and judged by the acceptance rule: every behaviour passes in at
least ``share`` x K of its runs (``export/perturb.toml``, ``[acceptance]``).

:mod:`synth.verify` calls :func:`robust_check` where it judges the nominal results: a
perturbed run that failed with an actuator at its limit feeds the same loop as a nominal
one (:func:`failing_runs`: each saturated joint gets a stronger actuator, the design is
sized again); a behaviour still not robust then fails a demanded ability (the request is
refused naming the behaviour, the perturbation that broke it and its figures against the
thresholds) or drops a bonus one (:func:`not_robust`).

The runs use the bundle as the user gets it (robot.xml without the payload, which
design.json places as ``parmor simulate`` does), so that ``parmor simulate DIR --perturb
SEED`` replays each recorded run to the bit.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from synth.conceptual import Designer
    from synth.pipeline import Outcome


def robust_check(designer: Designer, outcome: Outcome, k: int) -> dict | None:
    """``verified.robust`` of ``outcome`` (a sized design) under perturbations 1..``k`` of
    its table; None when ``k`` is 0."""
    if k <= 0 or outcome.structure is None or outcome.catalog is None:
        return None
    from export.bundle import bundle_files
    from export.perturb import design_table
    from export.verify import bundle_parts, verify_robust

    rec = outcome.record(designer)
    files = bundle_files(
        rec,
        outcome.structure,
        outcome.catalog,
        with_payload=outcome.with_payload,
        pictures=False,
        simulated_only=True,
    )
    record, xml, _ = bundle_parts(files)
    # through JSON as design.json keeps it: the replay draws from the very same numbers
    table = json.loads(json.dumps(design_table(record, xml, outcome.catalog)))
    return verify_robust(files, k, table)


def failing_runs(robust: Mapping | None) -> list[dict]:
    """The failed perturbed runs of the behaviours that are not robust (figures with
    ``verdict`` and ``saturated_joints``, as the nominal results)."""
    if not robust:
        return []
    return [
        f
        for b in robust["behaviors"]
        if not b["robust"]
        for f in b["figures"]
        if f["verdict"] != "ok"
    ]


def not_robust(robust: Mapping | None) -> list[tuple[str, str]]:
    """(ability, why) of each behaviour that is not robust (:func:`export.verify.
    robust_failure`), in name order."""
    if not robust:
        return []
    from export.verify import robust_failure

    why = robust_failure(robust)
    return [(b["ability"], why[b["behavior"]]) for b in robust["behaviors"] if not b["robust"]]
