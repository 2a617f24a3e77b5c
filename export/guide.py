"""The bundle's ``README.md``: what the robot is, how to print and assemble it (module
order and I2C addresses) and which file to open with what. Pure: returns the text."""

from __future__ import annotations

from export.model3d import Assembly

FILES = (
    (
        "design.json",
        "the full design record: conceptual design, links, joints, modules",
        "any JSON viewer; `parmor` reads it",
    ),
    (
        "robot.urdf",
        "the robot description for ROS: links, inertias, joints, limits",
        "RViz, `check_urdf robot.urdf`, yourdfpy",
    ),
    (
        "robot.xml",
        "the MuJoCo model: the same bodies on a floor, position actuators",
        "`python -m mujoco.viewer --mjcf robot.xml`, `parmor simulate`",
    ),
    ("meshes/*.stl", "every printed part, in metres", "a slicer (scale mm: x1000)"),
    ("bom.csv", "bill of materials with totals", "a spreadsheet"),
)


def _md(text: str) -> str:
    """Text from user input, safe inside Markdown table cells and lines."""
    return text.replace("|", "\\|").replace("\n", " ")


def guide_markdown(record: dict, asm: Assembly, documentation: str = "") -> str:
    """The bundle's README for the design ``record`` (as in design.json) built as ``asm``."""
    r = record
    printed = asm.printed
    payload = r.get("payload") or {}
    load = float(payload.get("mass_kg", 0.0))
    carried = (
        f" It is sized and simulated for a payload of {load:.3f} kg, which is not part of "
        "it (not in bom.csv; "
        + (
            "robot.urdf and robot.xml carry it"
            if payload.get("in_models")
            else "not in robot.urdf and robot.xml"
        )
        + "; design.json's `payload` says where it is held)."
        if load > 0
        else ""
    )
    lines = [f"# {_md(r['robot_type'])}: a parmor design", ""]
    if documentation:
        lines += [_md(documentation), ""]
    req = r["request"]
    asked = ", ".join(req["abilities"])
    lines += [
        f"Requested abilities: {_md(asked)}.",
        f"It can: {_md(', '.join(r['abilities']))}.",
        f"The robot weighs {asm.total_mass - (load if payload.get('in_models') else 0.0):.3f} kg "
        f"(every part in bom.csv), modules cost {r['cost']:.2f}, {r['dof']} degrees of "
        f"freedom, {r['active_modules']} active modules on the I2C bus "
        f"(limit {r['module_limit']}).{carried}",
        "",
        "## Files",
        "",
        "| file | what | open with |",
        "|---|---|---|",
    ]
    lines += [f"| `{f}` | {what} | {how} |" for f, what, how in FILES]
    lines += [
        "",
        "## Print",
        "",
        "| part | count | mass (g) | print time (min) | fits the bed |",
        "|---|---|---|---|---|",
    ]
    for p in sorted(printed, key=lambda p: p.name):
        lines.append(
            f"| `meshes/{p.name}.stl` | {p.count} | {p.mass_kg * 1000:.1f} | "
            f"{p.print_time_s / 60:.0f} | {'yes' if p.fits_bed else '**no: split it**'} |"
        )
    lines += [
        "",
        "## Assemble",
        "",
        "Set each active module's I2C address before mounting it. Then, from the root "
        "outwards, slide each module onto the dovetail face of the part before it:",
        "",
    ]
    step = 1
    joint_kinds = {j["module_class"] for j in r["joints"]}
    for m in r["modules"]:
        if m["kind"] not in joint_kinds:
            where = "bus master" if not m["i2c_addresses"] else ", ".join(m["i2c_addresses"])
            lines.append(
                f"{step}. {m['kind']} {_md(m['model'])} x{m['count']} on the root body ({where})."
            )
            step += 1
    for j in r["joints"]:
        lines.append(
            f"{step}. Joint `{_md(j['name'])}`: {_md(j['actuator'])} at "
            f"{j['i2c_address']}, holding {j['required_torque_Nm']:.3f} N m of its "
            f"{j['usable_torque_Nm']:.3f} usable."
        )
        step += 1
    lines += [
        "",
        "Made by parmor from the ADROn ontology. Parameters: "
        + ", ".join(f"{k} = {v:g}" for k, v in r["params"].items())
        + " (SI units).",
        "",
    ]
    return "\n".join(lines)
