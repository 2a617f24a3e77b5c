"""The design record: a conceptual design as plain JSON-ready data, and as text.

``design_record`` is what ``parmor design --json`` prints and ``design.json`` holds. Type
and part names are KIF class names; abilities are short command-line names.
"""

from __future__ import annotations

import json
from collections.abc import Callable

from synth.conceptual import Design
from synth.solver import Candidate

Short = Callable[[str], str]


def _counts(pairs: tuple[tuple[str, int], ...]) -> list[dict]:
    return [{"kind": k, "count": n} for k, n in pairs]


def candidate_record(c: Candidate, short: Short) -> dict:
    """Parts, modules and abilities of one candidate."""
    return {
        "robot_type": c.robot_type,
        "parts": _counts(c.parts),
        "modules": _counts(c.modules),
        "passive_modules": _counts(c.passive),
        "active_modules": c.active_total,
        "module_limit": c.module_limit,
        "dof": c.dof,
        "abilities": sorted(short(a) for a in c.abilities),
        "potential_abilities": sorted(short(a) for a in c.potential),
    }


def design_record(d: Design, short: Short) -> dict:
    """The whole outcome of ``parmor design`` as a dict (stable key order)."""
    c = d.chosen
    rec: dict = {
        "status": d.status,
        "request": {
            "abilities": list(d.request.abilities),
            "answers": {a: "yes" if y else "no" for a, y in d.request.answers},
            "params": dict(d.request.params),
        },
        "robot_type": c.robot_type if c else None,
        "chosen_by": d.chosen_by,
        "note": d.note,
        "candidates": [x.robot_type for x in d.candidates],
        "questions": [
            {
                "ability": q.ability,
                "text": q.text,
                "answer": None if q.answer is None else ("yes" if q.answer else "no"),
            }
            for q in d.questions
        ],
        "conflict": list(d.conflict),
        "needed": list(d.needed),
        "parts": _counts(c.parts) if c else [],
        "modules": _counts(c.modules) if c else [],
        "passive_modules": _counts(c.passive) if c else [],
        "active_modules": c.active_total if c else None,
        "module_limit": c.module_limit if c else None,
        "dof": c.dof if c else None,
        "abilities": sorted(short(a) for a in c.abilities) if c else [],
    }
    return rec


def to_json(data: object) -> str:
    """Canonical JSON text: two-space indent, key order as built, trailing newline."""
    return json.dumps(data, indent=2, ensure_ascii=False) + "\n"


def _list(pairs: tuple[tuple[str, int], ...]) -> str:
    return ", ".join(f"{k} x{n}" for k, n in pairs) or "-"


def candidate_text(c: Candidate, short: Short, indent: str = "  ") -> str:
    limit = f" of {c.module_limit}" if c.module_limit is not None else ""
    lines = [
        f"{indent}parts:      {_list(c.parts)}",
        f"{indent}modules:    {_list(c.modules)}  ({c.active_total}{limit} active)",
        f"{indent}passive:    {_list(c.passive)}",
        f"{indent}dof:        {c.dof}",
        f"{indent}abilities:  {', '.join(sorted(short(a) for a in c.abilities)) or '-'}",
    ]
    return "\n".join(lines)


def design_text(d: Design, short: Short) -> str:
    """A human-readable account of a design outcome."""
    out: list[str] = []
    for q in d.questions:
        if q.answer is not None:
            out.append(f"{q.text} {'yes' if q.answer else 'no'}")
    if d.status == "unsatisfiable":
        what = " and ".join(d.conflict)
        out.append(
            f"No robot can meet the request: {what} conflict."
            if len(d.conflict) > 1
            else f"No robot can meet the request: {what}."
        )
        return "\n".join(out) + "\n"
    if d.status == "ambiguous":
        out.append("Candidates: " + ", ".join(c.robot_type for c in d.candidates))
        pending = d.questions[-1]
        out.append(f"{pending.text} (answer with --answer {pending.ability}=yes|no)")
        return "\n".join(out) + "\n"
    c = d.chosen
    assert c is not None
    how = {"only candidate": "the only candidate", "preference": "chosen by preference"}
    out.append(f"{c.robot_type} ({how.get(d.chosen_by or '', d.chosen_by)})")
    if d.note:
        out.append(f"  note:       {d.note}")
    out.append(candidate_text(c, short))
    return "\n".join(out) + "\n"
