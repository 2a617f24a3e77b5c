"""The variation a printed robot meets, drawn deterministically and applied to its MuJoCo
model: the perturbed runs of a robust verification (``parmor design --robustness K``) and
``parmor simulate DIR --perturb SEED``.

The ranges are data: ``synth/verification/perturb.toml`` (documented there), whose tables a
catalog's ``[perturbation]`` table may override key by key. For a design they are resolved once
into its **table** (:func:`design_table`: plain SI numbers, JSON), which names every body
and position servo the draws apply to, each servo's backlash range and dead band, each
printed link's bending stiffness and the battery's scale; the record keeps it
(``verified.robust.table``), so a run is replayed from the bundle alone.

Perturbation ``seed`` (:func:`draw`) is drawn from ``numpy.random.default_rng((stream,
seed))`` in a fixed order (friction, slope, slope direction, latency, then one mass factor
per body and one backlash per servo, in the table's order): the same table and seed give
the same perturbation, to the bit. Applied (:func:`perturbed_xml`, an edit of the MJCF
text, then compiled as any bundle model):

- **masses**: each body's mass and inertia x its factor (the payload's bodies excepted);
- **floor**: the robot's contact friction (which MuJoCo applies: its geoms have priority)
  x the friction factor; gravity turned by the slope angle towards its direction (the
  floor, the world's xy plane, is then a slope of that angle), and MuJoCo's no-slip
  solver on when it is tilted (``NOSLIP_ITERATIONS``: without it, soft contacts creep
  down the slope);
- **joint play** (backlash + dead band): a passive hinge in series with each position
  servo, in the same body, about the same axis, free within +-play/2 (a joint limit);
  its armature is 1 % of the servo's (the rotor's side of the gears is the servo's
  joint) and its damping 1 % of the servo's back-EMF damping (gear friction);
- **battery at its low cut-off**: each servo's stall torque (``forcerange``), position
  gains (``kp``, ``kv``) and a wheel's no-load speed (``ctrlrange``) x the battery
  scale (a DC motor's torque and speed go with its voltage);
- **link compliance**: the servo's position gain in series with the printed tube's
  bending stiffness k: ``kp k / (kp + k)``;
- **command latency and control rate**: not a model edit; the run's references are
  those of ``latency`` s earlier, held for each control period
  (:func:`synth.verification.simulate.simulate`'s ``latency_s``, ``command_period_s``);
- **sensors**: not a model edit; the IMU's noise and gyro bias (``imu``) reach the plans'
  feedback loops, the line sensors' edge offsets and jitter and the ranger's scale, noise
  and resolution (``sensing``, drawn after the IMU's) the sensing loops
  (:class:`program.sensing.SensorNoise`).
"""

from __future__ import annotations

import json
import math
import tomllib
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from importlib import resources
from typing import Any

from adron.errors import InputError
from adron.formats import PerturbationOverrides
from adron.schema import validate
from adron.units import quantity
from export.mjcf import load_mjcf

#: The shipped ranges (package data).
TABLE_FILE = "perturb.toml"
#: Suffix of the passive hinge that models a servo's play (``JOINT/play``).
PLAY_SUFFIX = "/play"
#: The play hinge's armature and damping as fractions of its servo's.
PLAY_ARMATURE = 0.01
PLAY_DAMPING = 0.01
#: The play hinge's end stops (gear teeth meeting): MuJoCo limits of time constant
#: ``PLAY_STOP_STEPS`` physics steps (``solreflimit``; 2, the stiffest MuJoCo integrates
#: stably) and impedance near 1 (``PLAY_SOLIMP``). MuJoCo's default (0.02 s, 0.9-0.95)
#: scales a stop's stiffness with the light body behind the hinge: a foot's stop gave
#: about 5 N m/rad, a seventh of its servo's kp, and bent 5-6 deg past a 1 deg play under
#: the robot's weight; a 3-joint arm's shoulder at its ready pose sat at 1.125 deg for a
#: half play of 0.548 deg. With these: 0.552 deg.
PLAY_STOP_STEPS = 2
PLAY_SOLIMP = "0.99 0.999 0.001"
#: Iterations of MuJoCo's no-slip solver in a perturbed model: its soft contacts let a
#: body creep down a tilted floor (the shipped quadruped standing still on a 3 deg slope
#: slid 45 mm in 30 s; with these 0.2 mm), which friction stops on a real floor. Set when
#: the floor is tilted; a level floor's model (the nominal one) is left as it is.
NOSLIP_ITERATIONS = 10
#: The sensor module classes whose readings a sensing loop (:mod:`program.sensing`) takes,
#: and the table's key of their noise (``perturb.toml``'s section of that name).
SENSING_MODULES = {"InfraredSensorModule": "infrared", "UltrasonicSensorModule": "ultrasonic"}
#: Prefix of the payload's bodies (:func:`.simulate.carrying_payload`): not scaled.
PAYLOAD_PREFIX = "payload_"


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


def ranges(overrides: Mapping[str, Any] | None = None, where: str = "catalog") -> dict[str, Any]:
    """The perturbation ranges in SI: the shipped table with ``overrides`` (a catalog's
    ``[perturbation]`` table, tables merged key by key) applied. InputError naming
    ``where`` and the key for an unknown key or a bad value."""
    text = (resources.files("synth.verification") / TABLE_FILE).read_text(encoding="utf-8")
    raw = tomllib.loads(text)
    source = TABLE_FILE
    if overrides:
        for key, value in overrides.items():
            if key not in raw:
                raise InputError(
                    f"{where}: [perturbation] unknown key {key!r} (one of {', '.join(sorted(raw))})"
                )
            if not isinstance(value, Mapping):
                raise InputError(f"{where}: [perturbation] {key}: expected a table")
            if key in ("servo", "gears"):
                continue  # actuator models and gear materials of the user's own
            for sub in value:
                if sub not in raw[key]:
                    raise InputError(
                        f"{where}: [perturbation] unknown key {key}.{sub} "
                        f"(one of {', '.join(sorted(raw[key]))})"
                    )

        validate(PerturbationOverrides, dict(overrides), f"{where}: [perturbation]")
        raw = _merge(raw, overrides)
        source = f"{where}: [perturbation]"
    return _resolve(raw, source)


def _resolve(raw: Mapping[str, Any], source: str) -> dict[str, Any]:
    def get(table: str, key: str) -> Any:
        try:
            return raw[table][key]
        except (KeyError, TypeError):
            raise InputError(f"{source}: missing key {table}.{key}") from None

    def q(table: str, key: str, dim: str, zero: bool = False) -> float:
        return quantity(get(table, key), dim, f"{source}: {table}.{key}", allow_zero=zero)

    def ratio(table: str, key: str, low: float = 0.0, high: float = math.inf) -> float:
        v = get(table, key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not low <= v <= high:
            raise InputError(
                f"{source}: {table}.{key} = {v!r}: expected a number in [{low:g}, {high:g}]"
            )
        return float(v)

    def span(table: str, key: str, lo: float, hi: float, what: str) -> list[float]:
        if lo > hi:
            raise InputError(f"{source}: {table}: {what}: the low end is above the high end")
        return [lo, hi]

    supply = get("battery", "supply")
    if supply not in ("regulated", "direct"):
        raise InputError(f"{source}: battery.supply = {supply!r}: expected 'regulated' or 'direct'")
    gears: dict[str, list[float]] = {}
    for name, pair in dict(raw.get("gears") or {}).items():
        where = f"{source}: gears.{name}"
        if not isinstance(pair, list) or len(pair) != 2:
            raise InputError(f"{where}: expected [low, high] angles such as ['1 deg', '2 deg']")
        lo, hi = (quantity(x, "angle", where, allow_zero=True) for x in pair)
        gears[name] = span("gears", name, lo, hi, "backlash")
    servo = dict(raw.get("servo") or {})
    span_s = quantity(servo.pop("pulse_span", None), "time", f"{source}: servo.pulse_span")
    servos: dict[str, dict[str, Any]] = {}
    for model, entry in sorted(servo.items()):
        where = f"{source}: servo.{model}"
        if not isinstance(entry, Mapping) or set(entry) != {"gears", "deadband"}:
            raise InputError(f"{where}: expected {{ gears = ..., deadband = ... }}")
        if entry["gears"] not in gears:
            raise InputError(
                f"{where}.gears = {entry['gears']!r}: one of {', '.join(sorted(gears))}"
            )
        dead = quantity(entry["deadband"], "time", f"{where}.deadband", allow_zero=True)
        servos[model] = {"gears": entry["gears"], "deadband_share": dead / span_s}
    if "default" not in servos:
        raise InputError(f"{source}: missing key servo.default")
    stream = get("draw", "stream")
    if isinstance(stream, bool) or not isinstance(stream, int) or stream < 0:
        raise InputError(f"{source}: draw.stream: expected a non-negative integer")
    return {
        "stream": stream,
        "mass_spread": ratio("mass", "spread", 0.0, 0.9),
        "friction": span(
            "floor",
            "friction",
            ratio("floor", "friction_low", 0.0, 10.0),
            ratio("floor", "friction_high", 0.0, 10.0),
            "friction_low, friction_high",
        ),
        "max_slope_rad": q("floor", "max_slope", "angle", zero=True),
        "latency_s": span(
            "bus",
            "latency",
            q("bus", "latency_low", "time", zero=True),
            q("bus", "latency_high", "time", zero=True),
            "latency_low, latency_high",
        ),
        "control_period_s": q("bus", "control_period", "time", zero=True),
        "battery": {
            "supply": supply,
            "nominal_per_cell_V": q("battery", "nominal_per_cell", "voltage"),
            "cutoff_per_cell_V": q("battery", "cutoff_per_cell", "voltage"),
            "rail_V": q("battery", "rail_voltage", "voltage"),
            "dropout_V": q("battery", "dropout", "voltage", zero=True),
            "rail_resistance_ohm": ratio("battery", "rail_resistance_ohm", 0.0, 10.0),
            "rated_V": q("battery", "rated_voltage", "voltage"),
        },
        "gears": gears,
        "servos": servos,
        "compliance_scale": ratio("compliance", "scale", 0.0, 1e6),
        "imu": {
            "gyro_std_rad_s": q("imu", "gyro_noise", "angular_speed", zero=True),
            "gyro_bias_rad_s": q("imu", "gyro_bias", "angular_speed", zero=True),
            "accel_std_m_s2": q("imu", "accel_noise", "acceleration", zero=True),
        },
        "infrared": {
            "edge_offset_m": q("infrared", "edge_offset", "length", zero=True),
            "edge_jitter_m": q("infrared", "edge_jitter", "length", zero=True),
        },
        "ultrasonic": {
            "noise_m": q("ultrasonic", "noise", "length", zero=True),
            "resolution_m": q("ultrasonic", "resolution", "length", zero=True),
            "scale": ratio("ultrasonic", "scale", 0.0, 0.5),
        },
        "share": ratio("acceptance", "share", 0.0, 1.0),
        "default_k": int(ratio("acceptance", "default_k", 0, 1000)),
    }


def battery_scale(r: Mapping[str, Any], pack_V: float, peak_A: float) -> float:
    """The servos' torque and speed at the battery's low cut-off over the catalog's (at the
    rated voltage): the supply voltage there (``ranges()["battery"]``, the pack's nominal
    ``pack_V`` and the design's peak current ``peak_A``) over the rated one, at most 1."""
    b = r["battery"]
    cells = max(1, round(pack_V / b["nominal_per_cell_V"]))
    cutoff = cells * b["cutoff_per_cell_V"]
    supply = min(b["rail_V"], cutoff - b["dropout_V"]) if b["supply"] == "regulated" else cutoff
    volts = supply - b["rail_resistance_ohm"] * peak_A
    return max(0.0, min(1.0, volts / b["rated_V"]))


def tube_stiffness(E: float, r_outer: float, r_inner: float, length: float) -> float:
    """N m/rad: a printed tube's bending stiffness seen from the joint at its base,
    3 E I / L with I = pi/4 (ro^4 - ri^4) (the tip's deflection under a tip load over L)."""
    second_moment = math.pi / 4 * (r_outer**4 - r_inner**4)
    return 3 * E * second_moment / max(length, 1e-9)


def servo_play(r: Mapping[str, Any], model: str | None, act=None) -> tuple[list[float], float]:
    """([low, high] backlash, dead band), rad, of a position servo ``model`` under the
    resolved ranges ``r`` (:func:`ranges`): its gear material's backlash and its pulse dead
    band over the catalog actuator ``act``'s travel (pi when unknown)."""
    spec = r["servos"].get(model) or r["servos"]["default"]
    travel = act.travel_rad if act is not None else math.pi
    return list(r["gears"][spec["gears"]]), spec["deadband_share"] * travel


def catalog_play(catalog, overrides: Mapping[str, Any] | None = None) -> dict[str, float]:
    """Model -> the largest play (backlash + dead band, rad) a perturbation gives each
    actuator of ``catalog`` (its ``[perturbation]`` table, then ``overrides``, over the
    shipped ranges): what the verification loop compares to choose a servo with less play."""
    own = json.loads(catalog.perturbation) if getattr(catalog, "perturbation", "") else {}
    r = ranges(_merge(own, overrides or {}), getattr(catalog, "source", "catalog"))
    out = {}
    for act in catalog.actuators:
        backlash, deadband = servo_play(r, act.model, act)
        out[act.model] = backlash[1] + deadband
    return out


def catalog_ranges(catalog, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """:func:`ranges` with ``catalog``'s ``[perturbation]`` table and then ``overrides``
    over the shipped one."""
    own = json.loads(catalog.perturbation) if getattr(catalog, "perturbation", "") else {}
    return ranges(_merge(own, overrides or {}), getattr(catalog, "source", "catalog"))


def default_k(catalog) -> int:
    """The default K of ``parmor design --robustness`` with ``catalog``'s ``[perturbation]``
    table over the shipped one (``[acceptance] default_k``)."""
    return int(catalog_ranges(catalog)["default_k"])


def design_table(
    record: Mapping[str, Any], xml: str, catalog, overrides: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The perturbation table of one design (module docstring): the ranges resolved for the
    bodies and servos of its MJCF text ``xml``, its record and its ``catalog`` (the
    material's modulus, the battery's voltage, each servo's travel), with the catalog's
    ``[perturbation]`` table and then ``overrides`` over the shipped ranges."""
    r = catalog_ranges(catalog, overrides)
    root = ET.fromstring(xml)
    acts = {a.model: a for a in catalog.actuators}
    joints = {j["name"]: j for j in record.get("joints", ())}
    links = {link["name"]: link for link in record.get("links", ())}
    position = {el.get("joint") for el in root.iter("position") if el.get("joint") is not None}
    E = catalog.material.youngs_modulus_Pa * r["compliance_scale"]
    bodies, servos = [], {}
    for body in root.iter("body"):
        name = body.get("name", "")
        if name.startswith(PAYLOAD_PREFIX):
            continue
        bodies.append(name)
        stiffness = None
        for geom in body.findall("geom"):
            mesh = geom.get("mesh") or ""
            link = links.get(mesh[len("link_") :]) if mesh.startswith("link_") else None
            if link is not None:
                k = tube_stiffness(E, link["r_outer_m"], link["r_inner_m"], link["length_m"])
                stiffness = k if stiffness is None else min(stiffness, k)
        for joint in body.findall("joint"):
            jname = joint.get("name")
            if jname not in position:
                continue
            model = (joints.get(jname) or {}).get("actuator")
            backlash, deadband = servo_play(r, model, acts.get(model))
            servos[jname] = {
                "model": model,
                "backlash_rad": backlash,
                "deadband_rad": deadband,
                "link_stiffness_Nm_rad": stiffness,
            }
    power = record.get("power") or {}
    kinds = {str(m.get("kind")) for m in record.get("modules") or () if isinstance(m, Mapping)}
    pack = catalog.battery.voltage_V
    return {
        "stream": r["stream"],
        "mass_spread": r["mass_spread"],
        "friction": r["friction"],
        "max_slope_rad": r["max_slope_rad"],
        "latency_s": r["latency_s"],
        "control_period_s": r["control_period_s"],
        "battery_scale": battery_scale(r, pack, float(power.get("peak_current_A") or 0.0)),
        "bodies": bodies,
        "servos": servos,
        "share": r["share"],
        # the IMU's noise where the design carries one (export.mjcf's gyro sensor)
        **({"imu": r["imu"]} if root.find(".//sensor/gyro") is not None else {}),
        # the sensing loops' sensors where the design carries them (program.sensing)
        **{key: r[key] for cls, key in SENSING_MODULES.items() if cls in kinds},
    }


def draw(table: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """Perturbation ``seed`` of a design's ``table`` (module docstring): plain numbers."""
    import numpy as np

    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"perturbation seed {seed!r}: expected a non-negative integer")
    rng = np.random.default_rng([int(table["stream"]), seed])
    lo, hi = table["friction"]
    friction = float(rng.uniform(lo, hi))
    slope = float(rng.uniform(0.0, table["max_slope_rad"]))
    direction = float(rng.uniform(0.0, 2 * math.pi))
    lo, hi = table["latency_s"]
    latency = float(rng.uniform(lo, hi))
    s = table["mass_spread"]
    masses = {b: 1.0 + float(rng.uniform(-s, s)) for b in table["bodies"]}
    play = {}
    for joint, servo in table["servos"].items():
        lo, hi = servo["backlash_rad"]
        play[joint] = float(rng.uniform(lo, hi)) + servo["deadband_rad"]
    imu = None
    if table.get("imu"):  # drawn last: the draws above are those of tables without an IMU
        i = table["imu"]
        b = float(i["gyro_bias_rad_s"])
        imu = {
            "stream": int(table["stream"]),
            "seed": seed,
            "gyro_bias_rad_s": [float(x) for x in rng.uniform(-b, b, 3)],
            "gyro_std_rad_s": float(i["gyro_std_rad_s"]),
            "accel_std_m_s2": float(i["accel_std_m_s2"]),
        }
    sensing = {}
    # drawn after the IMU's: the draws above are those of tables without these sensors
    if table.get("infrared"):  # one edge offset per sensor (left, right) and run
        i = table["infrared"]
        e = float(i["edge_offset_m"])
        sensing["infrared"] = {
            "edge_offset_m": [float(x) for x in rng.uniform(-e, e, 2)],
            "edge_jitter_m": float(i["edge_jitter_m"]),
        }
    if table.get("ultrasonic"):  # one speed-of-sound scale a run
        u = table["ultrasonic"]
        sensing["ultrasonic"] = {
            "scale": 1.0 + float(rng.uniform(-float(u["scale"]), float(u["scale"]))),
            "noise_m": float(u["noise_m"]),
            "resolution_m": float(u["resolution_m"]),
        }
    if sensing:  # the readings' noise: a stream of its own (program.sensing.SensorNoise)
        sensing |= {"stream": int(table["stream"]), "seed": seed}
    return {
        **({"imu": imu} if imu is not None else {}),
        **({"sensing": sensing} if sensing else {}),
        "seed": seed,
        "friction_scale": friction,
        "slope_rad": slope,
        "slope_direction_rad": direction,
        "latency_s": latency,
        "control_period_s": float(table["control_period_s"]),
        "battery_scale": float(table["battery_scale"]),
        "mass_scale": masses,
        "play_rad": play,
    }


def severity(table: Mapping[str, Any], p: Mapping[str, Any]) -> float:
    """How adverse perturbation ``p`` of ``table`` looks before it is run, in [0, 1]: the
    mean of where each of its draws lies in its range, 0 at the benign end and 1 at the
    adverse one: the floor's friction (low is adverse), its slope (steep), the bus latency
    (long), the heaviest body's mass factor (heavy) and the servos' play (each servo's
    backlash across its range, averaged; wide). The runs that can only refuse a design go
    in this order, the worst-looking first (:func:`worst_first`)."""

    def where(x: float, lo: float, hi: float) -> float:
        return min(1.0, max(0.0, (x - lo) / (hi - lo))) if hi > lo else 0.0

    lo, hi = table["friction"]
    parts = [1.0 - where(p["friction_scale"], lo, hi)]
    parts.append(where(p["slope_rad"], 0.0, float(table["max_slope_rad"])))
    lo, hi = table["latency_s"]
    parts.append(where(p["latency_s"], lo, hi))
    spread = float(table["mass_spread"])
    masses = list(p["mass_scale"].values())
    parts.append(where(max(masses), 1.0 - spread, 1.0 + spread) if masses else 0.0)
    plays = []
    for joint, servo in table["servos"].items():
        lo, hi = servo["backlash_rad"]
        plays.append(where(p["play_rad"][joint] - servo["deadband_rad"], lo, hi))
    parts.append(sum(plays) / len(plays) if plays else 0.0)
    return sum(parts) / len(parts)


def worst_first(table: Mapping[str, Any], seeds: list[int]) -> list[int]:
    """``seeds`` ordered by :func:`severity` of their perturbations, the worst-looking
    first (ties: the lower seed first)."""
    return sorted(seeds, key=lambda s: (-severity(table, draw(table, s)), s))


def summary(p: Mapping[str, Any]) -> dict[str, Any]:
    """A perturbation in a few figures (records, messages): its seed, the floor, the bus,
    the battery, the range of the mass factors and the largest play."""
    masses = list(p["mass_scale"].values()) or [1.0]
    plays = p["play_rad"]
    worst = max(plays, key=lambda j: (plays[j], j)) if plays else None

    def r(x: float) -> float:
        return float(f"{x:.4g}")

    return {
        "seed": p["seed"],
        "friction_scale": r(p["friction_scale"]),
        "slope_deg": r(math.degrees(p["slope_rad"])),
        "slope_direction_deg": r(math.degrees(p["slope_direction_rad"])),
        "latency_ms": r(p["latency_s"] * 1000),
        "battery_scale": r(p["battery_scale"]),
        "mass_scale": [r(min(masses)), r(max(masses))],
        "max_play_deg": r(math.degrees(plays[worst])) if worst else 0.0,
        "max_play_joint": worst,
        **({"sensors": sensor_text(p).lstrip(", ")} if p.get("sensing") else {}),
    }


def describe(p: Mapping[str, Any], sensors: bool = False) -> str:
    """One line: ``seed 3 (friction x0.71, slope 2.1 deg, latency 31 ms, ...)``; with
    ``sensors``, the sensing loops' sensors' draws too (:func:`sensor_text`)."""
    s = summary(p)
    extra = sensor_text(p) if sensors else ""
    play = (
        f", play up to {s['max_play_deg']:g} deg ({s['max_play_joint']})"
        if s["max_play_joint"]
        else ""
    )
    return (
        f"seed {s['seed']} (friction x{s['friction_scale']:g}, slope {s['slope_deg']:g} deg, "
        f"latency {s['latency_ms']:g} ms, battery x{s['battery_scale']:g}, masses "
        f"x{s['mass_scale'][0]:g}-{s['mass_scale'][1]:g}{play}{extra})"
    )


def sensor_text(p: Mapping[str, Any]) -> str:
    """The sensing loops' sensors of perturbation ``p``, e.g. ``, line edges +1.2/-0.4 mm
    +- 0.5 mm, ranger x1.008 +- 3 mm``; "" when it draws none."""
    sensing = p.get("sensing") or {}
    out = ""
    ir = sensing.get("infrared")
    if ir:
        edges = "/".join(f"{x * 1000:+.2g}" for x in ir["edge_offset_m"])
        out += f", line edges {edges} mm +- {ir['edge_jitter_m'] * 1000:.2g} mm"
    us = sensing.get("ultrasonic")
    if us:
        out += f", ranger x{us['scale']:.4g} +- {us['noise_m'] * 1000:.2g} mm"
    return out


def _num(x: float) -> str:
    return f"{x:.12g}"


def _scale_attr(el: ET.Element, key: str, factors: list[float] | float) -> None:
    text = el.get(key)
    if text is None:
        return
    values = [float(v) for v in text.split()]
    if not isinstance(factors, list):
        factors = [factors] * len(values)
    el.set(key, " ".join(_num(v * f) for v, f in zip(values, factors, strict=False)))


def perturbed_xml(
    xml: str, table: Mapping[str, Any], p: Mapping[str, Any], play: bool = True
) -> str:
    """The MJCF text ``xml`` with perturbation ``p`` of ``table`` applied (module docstring;
    ``play``: add the servos' play hinges)."""
    root = ET.fromstring(xml)
    option = root.find("option")
    if option is None:
        option = ET.SubElement(root, "option")
    g = [float(v) for v in (option.get("gravity") or "0 0 -9.81").split()]
    if table.get("timestep_s"):  # the perturbed runs' physics (runs.physics_check)
        option.set("timestep", _num(float(table["timestep_s"])))
    timestep = float(option.get("timestep") or 0.002)  # MuJoCo's default
    magnitude = math.sqrt(sum(v * v for v in g))
    a, d = p["slope_rad"], p["slope_direction_rad"]
    tilted = (
        magnitude * math.sin(a) * math.cos(d),
        magnitude * math.sin(a) * math.sin(d),
        -magnitude * math.cos(a),
    )
    option.set("gravity", " ".join(_num(v) for v in tilted))
    if a > 0:  # a tilted floor: friction holds the robot on it (NOSLIP_ITERATIONS)
        option.set("noslip_iterations", str(NOSLIP_ITERATIONS))
    f = p["friction_scale"]
    for geom in root.iter("geom"):
        if geom.get("name") == "floor":
            continue
        _scale_attr(geom, "friction", [f, 1.0, 1.0])
    masses = p["mass_scale"]
    servos = table["servos"]
    for body in root.iter("body"):
        factor = masses.get(body.get("name", ""))
        inertial = body.find("inertial")
        if factor is not None and inertial is not None:
            _scale_attr(inertial, "mass", factor)
            _scale_attr(inertial, "diaginertia", factor)
            _scale_attr(inertial, "fullinertia", factor)
        if not play:
            continue
        children = list(body)
        for joint in children:
            name = joint.get("name")
            if joint.tag != "joint" or not p["play_rad"].get(name):
                continue  # no play: no hinge
            half = p["play_rad"][name] / 2
            attrs = {
                "name": name + PLAY_SUFFIX,
                "type": "hinge",
                "axis": joint.get("axis", "0 0 1"),
                "range": f"{_num(-half)} {_num(half)}",
                "armature": _num(float(joint.get("armature") or 0.0) * PLAY_ARMATURE or 1e-7),
                "damping": _num(float(joint.get("damping") or 0.0) * PLAY_DAMPING),
                "limited": "true",
                # a hard stop: MuJoCo's default soft limit (0.02 s, 0.9-0.95) lets a
                # gravity-loaded joint sink past it by as much again as its play
                "solreflimit": f"{_num(PLAY_STOP_STEPS * timestep)} 1",
                "solimplimit": PLAY_SOLIMP,
            }
            if joint.get("pos") is not None:
                attrs["pos"] = joint.get("pos")
            body.insert(list(body).index(joint) + 1, ET.Element("joint", attrs))
    s = p["battery_scale"]
    for act in root.iter("position"):
        servo = servos.get(act.get("joint"), {})
        kp = float(act.get("kp") or 1.0) * s
        k = servo.get("link_stiffness_Nm_rad")
        series = kp * k / (kp + k) if k else kp
        act.set("kp", _num(series))
        _scale_attr(act, "kv", s)
        _scale_attr(act, "forcerange", s)
    for act in root.iter("velocity"):
        _scale_attr(act, "ctrlrange", s)
        _scale_attr(act, "forcerange", s)
    return ET.tostring(root, encoding="unicode")


def perturbed_model(xml: str, meshes: Mapping[str, bytes], table: Mapping[str, Any], p):
    """The compiled MuJoCo model of ``xml`` (a bundle's robot.xml carrying its payload)
    under perturbation ``p``."""

    return load_mjcf(perturbed_xml(xml, table, p), dict(meshes))


def table_digest(table: Mapping[str, Any]) -> str:
    """A short digest of a table (to tell two apart in messages and tests)."""
    import hashlib

    text = json.dumps(table, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:12]
