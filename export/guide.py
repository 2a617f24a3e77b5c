"""The bundle's ``README.md``: what the robot is, how to print and assemble it (module
order and bus addresses) and which file to open with what. Pure: returns the text."""

from __future__ import annotations

from export.model3d import Assembly
from export.record import robust_markdown

FILES = (
    (
        "design.json",
        "the full design record: conceptual design, links, joints, modules",
        "any JSON viewer; `parmor` reads it",
    ),
    (
        "robot.urdf",
        "the robot description for ROS: links, inertias, joints, limits",
        "`check_urdf robot.urdf`, MuJoCo, yourdfpy, pinocchio and RViz with no extra argument "
        "(meshes named by absolute `file://` path of this folder; if the folder is moved, MuJoCo "
        "and yourdfpy still find them in `meshes/`, pinocchio and RViz need the bundle "
        "written again; `parmor ros` makes a ROS package with `package://` URIs)",
    ),
    (
        "robot.xml",
        "the MuJoCo model: the same bodies on a floor, position actuators",
        "`python -m mujoco.viewer --mjcf robot.xml`, `parmor simulate`",
    ),
    ("meshes/*.stl", "every printed part, in millimetres, lying as it prints", "a slicer"),
    (
        "print/*.3mf",
        "each printed part as a print project: its copies on its printer's bed, its settings",
        "PrusaSlicer",
    ),
    ("bom.csv", "bill of materials with totals", "a spreadsheet"),
)


#: The bus of a record written before records named theirs: the paper's I2C bus.
_OLD_BUS = {"name": "I2C", "address_word": "address"}


def _bus(record: dict) -> dict:
    """The record's ``bus`` (name, address word, module limit)."""
    return record.get("bus") or _OLD_BUS


def _plural(word: str) -> str:
    """'address' -> 'addresses', 'ID' -> 'IDs'."""
    return word + ("es" if word.endswith(("s", "x", "sh", "ch")) else "s")


def _md(text: str) -> str:
    """Text from user input, safe inside Markdown table cells and lines."""
    return text.replace("|", "\\|").replace("\n", " ")


def assembly_steps(record: dict, asm: Assembly) -> list[str]:
    """The numbered assembly sequence (Markdown lines): the root body's printed plate and
    its modules, then every joint from the root outwards (the assembly's tree order): its
    servo module (with its bus address) onto the part before it, then the printed and
    bought parts of the body it turns; a passive joint's body goes onto the bearing hub of
    the part before it."""
    bus = _bus(record)
    addresses = {j["name"]: j.get("bus_address", "") for j in record.get("joints", ())}
    word = bus["address_word"]
    # "I2C 0x09", "DYNAMIXEL TTL ID 3": the plain word "address" goes without saying
    label = bus["name"] if word == "address" else f"{bus['name']} {word}"
    by_body = {b.name: b for b in asm.bodies}

    def parts_of(body: str, skip: str = "") -> str:
        names: dict[str, int] = {}
        for u in by_body[body].parts:
            if u.source in ("printed", "bought") or (u.source == "module" and u.name != skip):
                label = f"`meshes/{u.name}.stl`" if u.source == "printed" else _md(u.name)
                names[label] = names.get(label, 0) + 1
        return ", ".join(f"{n} x{k}" if k > 1 else n for n, k in names.items())

    out = [
        f"Set each active module's {_md(bus['name'])} {_md(word)} before "
        f"mounting it (the {_md(_plural(word))} below). "
        "Then, from the root outwards, slide each module onto the dovetail face of the part "
        "before it:",
        "",
        f"1. The root body `{_md(asm.root)}`: {parts_of(asm.root)}.",
    ]
    step = 2
    for j in asm.joints:
        parts = parts_of(j.child, j.actuator)
        if j.kind == "fixed":
            if parts:
                out.append(f"{step}. On `{_md(j.parent)}`, fixed: {parts}.")
                step += 1
            continue
        if j.passive:  # no servo: the body turns on the bearing hub of the part before it
            out.append(
                f"{step}. Joint `{_md(j.name)}` turns freely (no servo): onto the bearing hub "
                f"on `{_md(j.parent)}`: {parts or 'the next joint'}."
            )
            step += 1
            continue
        addr = addresses.get(j.name, "")
        out.append(
            f"{step}. Joint `{_md(j.name)}`: the {_md(j.actuator)} servo module"
            + (f" ({_md(label)} {_md(addr)})" if addr else "")
            + f" onto `{_md(j.parent)}`; on its output: {parts or 'the next joint'}."
        )
        step += 1
    return out


def _unsimulated(record: dict) -> list[str]:
    """The README's warning for demanded abilities accepted unsimulated (--allow-unverified;
    the record's ``verified.accepted_unsimulated``), or nothing."""
    names = (record.get("verified") or {}).get("accepted_unsimulated") or []
    if not names:
        return []
    return [
        f"**Not simulated: {_md(', '.join(names))}.** No behaviour serves "
        f"{'it' if len(names) == 1 else 'them'}, so nothing checked that the robot can do "
        f"{'it' if len(names) == 1 else 'them'}; the design was accepted with "
        "`--allow-unverified`."
    ]


def guide_markdown(
    record: dict, asm: Assembly, documentation: str = "", pictures: bool = False
) -> str:
    """The bundle's README for the design ``record`` (as in design.json) built as ``asm``;
    ``pictures``: the bundle has ``pictures/robot.png`` and ``pictures/<part>.png``."""
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
    bus = _bus(r)
    limits = [x for x in (r.get("module_limit"), bus.get("module_limit")) if x is not None]
    limit = min(limits) if limits else "none"
    lines = [f"# {_md(r['robot_type'])}: a parmor design", ""]
    if documentation:
        lines += [_md(documentation), ""]
    req = r["request"]
    asked = ", ".join(req["abilities"])
    lines += [
        f"Requested abilities: {_md(asked)}.",
        f"It can: {_md(', '.join(r['abilities']))}.",
        *_unsimulated(r),
        f"The robot weighs {asm.total_mass - (load if payload.get('in_models') else 0.0):.3f} kg "
        f"(every part in bom.csv), modules cost {r['cost']:.2f}, {r['dof']} degrees of "
        f"freedom, {r['active_modules']} active modules on the {_md(bus['name'])} bus "
        f"(limit {limit}).{carried}",
        "",
        "## Files",
        "",
        "| file | what | open with |",
        "|---|---|---|",
    ]
    lines += [f"| `{f}` | {what} | {how} |" for f, what, how in FILES]
    lines += ["", "## Print", ""]
    if pictures:
        lines += ["![the assembled robot](pictures/robot.png)", ""]
    lines += [
        "Open `print/<part>.3mf` in PrusaSlicer: the part's copies on the bed of its "
        "printer, with its settings (solid, 0.2 mm layers, supports only where it "
        "overhangs); a project named `x1 of 2` is printed twice. Or slice the STL files as "
        "they are (millimetres, each already lying in its printing orientation; "
        "`print/prusaslicer.ini` holds the settings the figures are for, on the bed of the "
        "largest printer a part needs; `print/<part>.3mf` is each part on its own printer's "
        "bed).",
    ]
    yours = next((p.printer for p in printed if p.fits_bed and p.printer), None)
    if yours is not None:  # --bed: every part on the user's printer
        lines[-1] = (
            f"Everything prints on your printer ({_md(yours)}): `print/prusaslicer.ini` and "
            "every `print/*.3mf` have its bed. Open `print/<part>.3mf` (a split part: "
            "`print/<piece>.3mf`) in PrusaSlicer: its copies with its settings (solid, "
            "0.2 mm layers, supports only where it overhangs); a project named `x1 of 2` "
            "is printed twice. Or slice the STL files as they are "
            "(millimetres, each lying in its printing orientation: `meshes/<part>.stl` where "
            "it fits as it lies, else `print/<part>.stl` or `print/<piece>.stl`)."
        )
    lines += [
        "",
        "| part | count | mass (g) | print time (min) | printer | picture |",
        "|---|---|---|---|---|---|",
    ]
    for p in sorted(printed, key=lambda p: p.name):
        if p.joints:
            printer = f"{_md(p.printer)}: in {len(p.pieces)} pieces (below)"
        elif p.pieces:
            printer = f"{_md(p.printer)}: turned, `print/{p.pieces[0].name}.stl`"
        elif p.fits_bed and p.printer:  # the user's printer (--bed): it fits as it lies
            printer = _md(p.printer)
        elif p.fits_bed:
            printer = "the catalog's"
        elif p.printer in ("", "split"):
            printer = "**none of the catalog's: split it**"
        else:
            printer = f"**{_md(p.printer)}** (too big for the catalog's bed)"
        pic = f"![{p.name}](pictures/{p.name}.png)" if pictures else ""
        lines.append(
            f"| `meshes/{p.name}.stl` | {p.count} | {p.mass_kg * 1000:.1f} | "
            f"{p.print_time_s / 60:.0f} | {printer} | {pic} |"
        )
    lines += _piece_lines(printed, pictures)
    lines += ["", "## Assemble", ""]
    lines += assembly_steps(r, asm)
    robust = robust_markdown(r.get("verified"))
    if robust:
        lines += ["", *robust]
    lines += [
        "",
        "Made by parmor from the ADROn ontology. Parameters: "
        + ", ".join(f"{k} = {v:g}" for k, v in r["params"].items())
        + " (SI units).",
        "",
    ]
    return "\n".join(lines)


def _piece_lines(printed, pictures: bool = True) -> list[str]:
    """The pieces of the parts split for the user's bed (``--bed``, ``export.split``) and
    where they join; none without split parts."""
    split = [p for p in sorted(printed, key=lambda p: p.name) if p.joints]
    if not split:
        return []
    c = split[0].joints[0].clearance_m * 1000
    lines = [
        "",
        "### Pieces",
        "",
        f"A part too big for the bed ({_md(split[0].printer)}) is printed in pieces "
        "(`print/<piece>.stl` and `.3mf`, each lying as it prints). Two pieces join by a "
        "dovetail: the tongue of the first slides into the slot of the second along the "
        f"axis named, with {c:g} mm clearance on every side (glue it if it is loose). "
        "Positions are in the part's STL (`meshes/<part>.stl`, mm).",
        "",
        "| part | piece | joins | where | slides along |",
        "|---|---|---|---|---|",
    ]
    for p in split:
        for j in p.joints:
            lines.append(
                f"| `{p.name}` | `{j.low}` | `{j.high}` | {j.axis} = {j.at_m * 1000:.1f} mm | "
                f"{j.slide} |"
            )
    if pictures:
        lines.append("")
        lines += [f"![{p.name}: its pieces](pictures/{p.name}_pieces.png)" for p in split]
    return lines
