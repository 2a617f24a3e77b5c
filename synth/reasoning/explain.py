"""``parmor explain``: a robot type's parts (own and inherited, with the declaring axiom's
location) and its abilities, each with the reason the reasoner gave."""

from __future__ import annotations

from synth.reasoning.conceptual import Designer


def explain_record(designer: Designer, robot_type: str) -> dict:
    """Parts with their axioms, abilities with reasons, for the KIF class ``robot_type``."""
    c = designer.describe(robot_type)
    sources = {s.id: s for s in designer.kb.translation.sources}
    parts = []
    for ps in c.sources:
        axioms = [sources[i] for i in ps.axioms if i in sources]
        parts.append(
            {
                "kind": ps.kind,
                "count": ps.count,
                "declared_by": [
                    {"class": a.cls, "location": a.location, "inherited": a.cls != c.robot_type}
                    for a in axioms
                ],
            }
        )
    reasons: dict[str, list[dict]] = {}
    for r in c.reasons:
        reasons.setdefault(r.action, []).append({"part": r.kind, "needs": r.need, "has": r.have})
    abilities = [
        {"ability": designer.short(a), "kif": a, "requires": reasons.get(a, [])}
        for a in sorted(c.abilities, key=designer.short)
    ]
    gainable = sorted(designer.short(a) for a in set(c.potential) - set(c.abilities))
    return {
        "robot_type": c.robot_type,
        "documentation": designer.kb.translation.documentation.get(c.robot_type, ""),
        "parts": parts,
        "modules": [{"kind": k, "count": n} for k, n in c.modules],
        "passive_modules": [{"kind": k, "count": n} for k, n in c.passive],
        "active_modules": c.active_total,
        "module_limit": c.module_limit,
        "dof": c.dof,
        "abilities": abilities,
        "gainable_abilities": gainable,
    }


def explain_text(rec: dict) -> str:
    out = [rec["robot_type"]]
    if rec["documentation"]:
        out.append(f"  {rec['documentation']}")
    out.append("parts:")
    for p in rec["parts"]:
        where = "; ".join(
            f"{'inherited from ' if d['inherited'] else ''}{d['class']} at {d['location']}"
            for d in p["declared_by"]
        )
        out.append(f"  {p['kind']} x{p['count']}  ({where})")
    mods = ", ".join(f"{m['kind']} x{m['count']}" for m in rec["modules"])
    limit = rec["module_limit"]
    over = ""
    if limit is not None and rec["active_modules"] > limit:
        over = f"; over the limit of {limit}, so never a candidate"
    out.append(f"modules: {mods}  ({rec['active_modules']} active, dof {rec['dof']}{over})")
    out.append("abilities:")
    for a in rec["abilities"]:
        why = "; ".join(f"has {r['has']} {r['part']}, needs {r['needs']}" for r in a["requires"])
        out.append(f"  {a['ability']}: {why or 'no structural requirement'}")
    if rec["gainable_abilities"]:
        out.append("can gain by adding modules: " + ", ".join(rec["gainable_abilities"]))
    return "\n".join(out) + "\n"
