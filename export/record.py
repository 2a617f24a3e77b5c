"""The design record: a conceptual design as plain JSON-ready data, and as text.

``design_record`` is what ``parmor design --json`` prints and ``design.json`` holds. Type
and part names are KIF class names; abilities are short command-line names.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from kinematics.partkinds import in_use

if TYPE_CHECKING:  # the structure stage pulls numpy in: keep it off the conceptual path;
    # the solver pulls clingo in: keep it off the path of a command that only prints JSON
    from adron.catalog import Bus, Catalog
    from synth.reasoning.conceptual import Design
    from synth.reasoning.solver import Candidate
    from synth.sizing.structure import Alternatives, Structure

Short = Callable[[str], str]


#: The format of the records this parmor writes (``design.json``'s ``format``); a reader
#: refuses another (export/record_schema.py). Raised when a field's meaning changes.
RECORD_FORMAT = 1


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


def _r(x: float) -> float:
    """Round for the record: 9 significant digits keep outputs stable across platforms."""
    return float(f"{x:.9g}")


def bus_record(bus: Bus) -> dict:
    """The bus the active modules are on, as the catalog names it."""
    return {
        "name": bus.name,
        "protocol": bus.protocol,
        "address_word": bus.address_word,
        "first_address": bus.address_text(bus.first_address),
        "last_address": bus.address_text(bus.last_address),
        "module_limit": bus.module_limit,
    }


def catalog_record(cat: Catalog) -> dict:
    """Which catalog a design used: its name, the shipped catalog's name ("" for a user's
    file) and the sha256 of its text (and of the texts it extends)."""
    return {"name": cat.name, "version": cat.version, "shipped": cat.shipped, "sha256": cat.sha256}


def _part_kinds_record() -> dict:
    """``part_kinds``: the user's part kinds files (``--parts``) the design was assembled
    with, each ``{"file": name, "toml": text}``, so that its bundle is rebuilt, simulated
    and programmed without them (``gaits.base.DesignGeometry.from_record``); nothing for
    the shipped part kinds alone (the record stays as it was)."""

    texts = in_use().texts
    if not texts:
        return {}
    return {"part_kinds": [{"file": name, "toml": text} for name, text in texts]}


def structure_record(s: Structure) -> dict:
    """The sized structure: links, joints, modules with models and bus addresses, totals."""
    at = s.bus.address_text
    return {
        "template": s.template.robot_type,
        "body_plan": s.template.plan.to_dict() if s.template.plan is not None else None,
        **_part_kinds_record(),
        "params": {k: _r(v) for k, v in s.params.items()},
        "ignored_params": list(s.ignored_params),
        "lengths_m": {k: _r(v) for k, v in s.lengths.items()},
        "wheel_radius_m": None if s.wheel_radius_m is None else _r(s.wheel_radius_m),
        "links": [
            {
                "name": link.name,
                "count": link.count,
                "length_m": _r(link.length_m),
                "r_outer_m": _r(link.r_outer_m),
                "r_inner_m": _r(link.r_inner_m),
                "volume_m3": _r(link.volume_m3),
                "part_volume_m3": _r(link.part_volume_m3),
                "mass_kg": _r(link.mass_kg),
                "tip_deflection_m": _r(link.tip_deflection_m),
                "max_deflection_m": _r(link.max_deflection_m),
                "max_stress_Pa": _r(link.max_stress_Pa),
                "allowed_stress_Pa": _r(link.allowed_stress_Pa),
                "branch": link.branch,
                "governed_by": link.governed_by,
            }
            for link in s.links
        ],
        "joints": [
            {
                "name": j.name,
                "group": j.group,
                "module_class": j.module_class,
                "actuator": j.actuator,
                "required_torque_Nm": _r(j.required_torque_Nm),
                "actuator_torque_Nm": _r(j.actuator_torque_Nm),
                "usable_torque_Nm": _r(j.usable_torque_Nm),
                "no_load_speed_rad_s": _r(j.no_load_speed_rad_s),
                "hold": {
                    "torque_Nm": _r(j.hold_torque_Nm),
                    "speed_rad_s": _r(j.hold_speed_rad_s),
                    "while": j.hold,
                }
                if j.hold
                else None,
                "required_speed_rad_s": _r(j.required_speed_rad_s),
                "operating_points": [[_r(t), _r(w)] for t, w in j.operating_points],
                "load_case": j.load_case,
                "bus_address": at(j.i2c_address),
            }
            for j in s.joints
        ],
        # the joints no actuator drives (a free wheel's): only where the design has some
        **({"passive_joints": list(s.template.passive)} if s.template.passive else {}),
        "modules": [
            {
                "kind": m.kind,
                "model": m.model,
                "count": m.count,
                "bus_addresses": [at(a) for a in m.i2c_addresses],
            }
            for m in s.modules
        ],
        "bus": bus_record(s.bus),
        "mass_kg": _r(s.robot_mass_kg),
        "loaded_mass_kg": _r(s.mass_kg),
        "cost": _r(s.cost),
        "power": {
            "peak_current_A": _r(s.power.peak_current_A),
            "stall_current_A": _r(s.power.stall_current_A),
            "battery_max_current_A": _r(s.power.battery_max_current_A),
            "ok": s.power.ok,
        },
        "metrics": {
            "modularity": s.metrics.modularity,
            "regularity": _r(s.metrics.regularity),
            "hierarchy": s.metrics.hierarchy,
        },
        "iterations": s.iterations,
        "notes": list(s.notes),
    }


def alternatives_record(a: Alternatives) -> dict:
    """Feasible actuator assignments: exact count, the best ones, the Pareto front."""

    def one(x) -> dict:
        per: dict[str, int] = {}
        for _, m in x.models:
            per[m] = per.get(m, 0) + 1
        return {
            "modules_mass_kg": _r(x.mass_kg),
            "modules_cost": _r(x.cost),
            "summary": ", ".join(f"{m} x{n}" for m, n in sorted(per.items())),
            "joints": dict(x.models),
        }

    return {
        "count": a.count,
        "count_exact": a.exact,
        "count_lower": a.count if a.exact or a.lower is None else a.lower,
        "count_capable": a.count if a.capable is None else a.capable,
        "symmetric": a.symmetric,
        "ranked": [one(x) for x in a.ranked],
        "pareto": None if a.pareto is None else [one(x) for x in a.pareto],
    }


def design_record(d: Design, short: Short, structure: Structure | None = None) -> dict:
    """The whole outcome of ``parmor design`` as a dict (stable key order). With a sized
    ``structure``, ``modules`` names catalog models and bus addresses and the structural
    fields follow (``links``, ``joints``, ``mass_kg``, ``cost``, ``power``, ``metrics``...)."""
    c = d.chosen
    rec: dict = {
        "format": RECORD_FORMAT,
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
        # which behaviours serve an ability with none of its own: its nearest ancestor's
        # (gaits.base.serving), so that a bundle needs no ontology
        "ability_ancestors": {a: list(up) for a, up in d.ancestors},
    }
    if d.over_limit:
        rec["over_limit"] = [
            {"robot_type": t, "active_modules": n, "module_limit": limit}
            for t, n, limit in d.over_limit
        ]
    if structure is not None:
        srec = structure_record(structure)
        rec["modules"] = srec.pop("modules")
        rec.update(srec)
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


def structure_text(s: Structure, indent: str = "  ") -> str:
    """The sized structure as text: links, joints, modules, totals."""
    load = f" (+ {s.payload_kg:.3f} kg payload)" if s.payload_kg > 0 else ""
    out = [
        f"{indent}structure:  {s.robot_mass_kg:.3f} kg{load}, cost {s.cost:.2f}, "
        f"{s.iterations} iterations"
    ]
    for link in s.links:
        out.append(
            f"{indent}  link {link.name:<10} x{link.count}  L {link.length_m * 1000:6.1f} mm  "
            f"r {link.r_outer_m * 1000:5.2f}/{link.r_inner_m * 1000:5.2f} mm  "
            f"deflection {link.tip_deflection_m * 1000:.2f}/{link.max_deflection_m * 1000:.2f} mm  "
            f"stress {link.max_stress_Pa / 1e6:.1f}/{link.allowed_stress_Pa / 1e6:.1f} MPa"
        )
    for j in s.joints:
        out.append(
            f"{indent}  joint {j.name:<18} {j.actuator:<8} needs {j.required_torque_Nm:6.3f} N m "
            f"(has {j.usable_torque_Nm:.3f}), {j.required_speed_rad_s:5.2f} rad/s"
            + (f"; {j.hold_torque_Nm:.3f} N m {j.hold}" if j.hold else "")
        )
    for m in s.modules:
        addrs = ", ".join(s.bus.address_text(a) for a in m.i2c_addresses) or "bus master"
        out.append(f"{indent}  module {m.kind} {m.model} x{m.count}  [{addrs}]")
    p = s.power
    out.append(
        f"{indent}  power: peak {p.peak_current_A:.2f} A (stall {p.stall_current_A:.2f} A) "
        f"of {p.battery_max_current_A:.1f} A{'' if p.ok else '  OVER THE BATTERY RATING'}"
    )
    m = s.metrics
    out.append(
        f"{indent}  MR&H: modularity {m.modularity}, regularity {m.regularity:.2f}, "
        f"hierarchy {m.hierarchy}"
    )
    if s.ignored_params:
        out.append(f"{indent}  not used by {s.robot_type}: {', '.join(s.ignored_params)}")
    return "\n".join(out)


def verification_text(verified: dict | None, indent: str = "  ") -> str:
    """The ``verified`` part of a record as lines: each behaviour's verdict and figures."""
    if not verified:
        return ""
    if not verified.get("simulated"):
        return f"{indent}verified:   {verified.get('note', 'no')}\n"
    out = [f"{indent}verified:   in MuJoCo, {verified['rounds']} sizing(s)"]
    for b in verified["behaviors"]:
        verdict = b["verdict"] if b["verdict"] == "ok" else "FAILED " + ", ".join(b["verdict"])
        figs = [f"saturated {b['saturated_fraction']:.0%}"]
        if b.get("line_progress_m") is not None:
            figs.append(
                f"followed {b['line_progress_m']:.2f} of {b['planned_distance_m']:.2f} m of "
                f"line, off it for {b['line_lost_s']:.2f} s at most"
            )
        elif b.get("obstacle_contact_s") is not None:
            figs.append(
                f"{b['distance_m']:.2f} of {b['planned_distance_m']:.2f} m past an obstacle, "
                f"touched it {b['obstacle_contact_s']:.2f} s"
            )
        elif b.get("planned_distance_m"):
            figs.append(f"{b['distance_m']:.3f} of {b['planned_distance_m']:.3f} m")
        elif b.get("distance_m") and b.get("planned_heading_rad") is None:
            figs.append(f"{b['distance_m']:.3f} m")
        if b.get("planned_heading_rad"):
            figs.append(f"turned {b['heading_rad']:.2f} of {b['planned_heading_rad']:.2f} rad")
        if b.get("placing_error_m") is not None:
            figs.append(f"placed within {b['placing_error_m'] * 1000:.3f} mm")
        if b.get("orientation_error_rad") is not None:
            figs.append(f"tool within {math.degrees(b['orientation_error_rad']):.2f} deg")
        out.append(f"{indent}  {b['behavior']:<22} {verdict:<8} {', '.join(figs)}")
    for j, t in verified.get("strengthened", {}).items():
        out.append(f"{indent}  strengthened {j}: saturated in simulation, sized for >= {t:.3f} N m")
    play = verified.get("play") or {}
    for j, sw in play.get("swapped", {}).items():
        broke = sorted({r["behavior"] for r in play.get("blamed", ()) if j in r["joints"]})
        out.append(
            f"{indent}  less play {j}: {sw['from']} -> {sw['to']} (play up to "
            f"{sw['play_deg'][0]:.2f} -> {sw['play_deg'][1]:.2f} deg): its play broke "
            f"{', '.join(broke) or 'a behaviour'} under perturbation"
        )
    wheels = verified.get("wheels") or {}
    for j, sw in wheels.get("swapped", {}).items():
        broke = sorted({r["behavior"] for r in wheels.get("runs", ())})
        out.append(
            f"{indent}  stiffer wheel {j}: {sw['from']} -> {sw['to']}: its motor line's droop "
            f"broke {', '.join(broke) or 'a behaviour'} under perturbation"
        )
    gains = (verified.get("robust") or {}).get("gains") or {}
    for name, scale in gains.get("chosen", {}).items():
        loop = next((t["loop"] for t in gains.get("tried", ()) if t["behavior"] == name), "")
        out.append(
            f"{indent}  gains {name}: its {loop} loop's gains x{scale:g}: with its own, "
            "perturbed runs failed; with these every one passes"
        )
    paces = (verified.get("robust") or {}).get("paces") or {}
    for name, pace in paces.get("chosen", {}).items():
        t = next((t for t in paces.get("tried", ()) if t["behavior"] == name), {})
        out.append(
            f"{indent}  pace {name}: {t.get('parameter', 'pace')} {pace:g} {t.get('unit', '')} "
            f"(the design's {t.get('from', 0):.3g}): the servos' command hold saturated it "
            "under perturbation; at this pace every perturbed run passes"
        )
    for a, why in verified.get("dropped", {}).items():
        out.append(f"{indent}  dropped {a}: {why}")
    if verified.get("not_simulated"):
        out.append(
            f"{indent}  not simulated (no behaviour): {', '.join(verified['not_simulated'])}"
        )
    if verified.get("accepted_unsimulated"):
        out.append(
            f"{indent}  accepted unsimulated (--allow-unverified): "
            f"{', '.join(verified['accepted_unsimulated'])}"
        )
    robust = verified.get("robust")
    if robust:
        out.append(
            f"{indent}robust:     {robust['k']} perturbed runs per behaviour, each must pass "
            f"{robust['required']} (parmor simulate DIR --behavior NAME --perturb SEED)"
        )
        physics = robust.get("physics") or {}
        if physics:
            step = physics.get("timestep_s")
            out.append(
                f"{indent}  physics: "
                + (
                    f"perturbed runs at a {step * 1000:g} ms step ({physics.get('why')}; "
                    "--fine replays at the model's own)"
                    if step
                    else f"perturbed runs at the model's own step ({physics.get('why')})"
                )
            )
        shown = robust.get("shows") or {}
        if shown:
            out.append(
                f"{indent}  shows: each behaviour succeeds with probability above "
                f"{math.floor(shown['success_lower_bound'] * 100)} % at "
                f"{shown['confidence'] * 100:.0f} % confidence ({shown['passed']} of "
                f"{shown['runs']}, Clopper-Pearson; --certify N runs N)"
            )
        for b in robust["behaviors"]:
            verdict = "ok" if b["robust"] else "FAILED"
            line = f"{indent}  {b['behavior']:<22} {verdict:<8} passed {b['passed']} of {b['runs']}"
            seeds = ", ".join(str(f["seed"]) for f in b["failures"])
            if seeds:
                line += f"; failed at seed {seeds}"
            out.append(line)
    return "\n".join(out) + "\n"


#: The worst figures of a robust verification the bundle's README shows (key -> label,
#: scale, unit), where a behaviour has them.
ROBUST_SHOWN = (
    ("saturated_fraction", "saturated", 100, "%"),
    ("max_torque_ratio", "torque / stall", 1, ""),
    ("min_height_ratio", "lowest height", 1, "x standing"),
    ("max_tilt_rad", "tilt", 180 / math.pi, "deg"),
    ("distance_ratio", "distance", 1, "x planned"),
    ("heading_error_rad", "heading error", 180 / math.pi, "deg"),
    ("final_pose_error_m", "pose error", 1000, "mm"),
    ("drift_m", "drift", 1000, "mm"),
    ("placing_error_m", "placing error", 1000, "mm"),
    ("orientation_error_rad", "orientation error", 180 / math.pi, "deg"),
)


def robust_markdown(verified: dict | None) -> list[str]:
    """The bundle README's section on a robust verification (``parmor design --robustness
    K``): per behaviour the nominal verdict, passed k of K, each worst figure with the seed
    that gave it, and the perturbations drawn. Empty without robust runs."""
    robust = verified.get("robust") if verified else None
    if not robust:
        return []
    nominal = {b["behavior"]: b["verdict"] for b in verified.get("behaviors", ())}
    lines = ["## Verified in simulation", ""]
    lines += [
        f"Every behaviour ran in MuJoCo on `robot.xml` (default parameters) on the nominal "
        f"model and under {robust['k']} seeded perturbations (masses, floor friction and "
        f"slope, servo backlash and dead band, bus latency, battery at its low cut-off, "
        f"link compliance: `design.json` `verified.robust.table`); a behaviour must pass "
        f"{robust['required']} of them. Replay one: `parmor simulate . --behavior NAME "
        f"--perturb SEED`.",
        "",
        "| behaviour | nominal | perturbed: passed | worst figures (seed) |",
        "|---|---|---|---|",
    ]
    for b in robust["behaviors"]:
        worst = []
        for key, label, scale, unit in ROBUST_SHOWN:
            w = b["worst"].get(key)
            if w is not None:
                unit_text = f" {unit}" if unit else ""
                worst.append(f"{label} {w['value'] * scale:.3g}{unit_text} ({w['seed']})")
        v = nominal.get(b["behavior"], "ok")
        lines.append(
            f"| {b['behavior']} | {'ok' if v == 'ok' else 'failed'} | {b['passed']} of "
            f"{b['runs']}{'' if b['robust'] else ' (not robust)'} | {'; '.join(worst)} |"
        )
    lines += [
        "",
        "| seed | friction | slope (deg) | latency (ms) | battery | masses | play (deg) |",
    ]
    lines.append("|---|---|---|---|---|---|---|")
    for p in robust["perturbations"]:
        lines.append(
            f"| {p['seed']} | x{p['friction_scale']:g} | {p['slope_deg']:g} | "
            f"{p['latency_ms']:g} | x{p['battery_scale']:g} | x{p['mass_scale'][0]:g}-"
            f"{p['mass_scale'][1]:g} | {p['max_play_deg']:g} |"
        )
    return [*lines, ""]


def design_text(d: Design, short: Short, structure: Structure | None = None) -> str:
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
        if d.note:
            out.append(f"  note:       {d.note}")
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
    if structure is not None:
        out.append(structure_text(structure))
    return "\n".join(out) + "\n"
