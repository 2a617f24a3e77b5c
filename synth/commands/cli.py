"""The ``parmor`` command line: a thin shell over the Python API.

Exit codes: 0 done; 1 the request cannot be met (unsatisfiable, infeasible, regression
changed); 2 bad input; 3 an answer is needed and input is off. Heavy modules (clingo and
everything after it) are imported inside the commands, so ``parmor --help`` stays fast.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import io
import math
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import TextIO

from adron.errors import AnswerNeeded, ExportError, InfeasibleError, InputError, ParmorError
from synth import limits
from synth.limits import (
    DEFAULT_MEMORY_MB,
    DEFAULT_SIZE_ATOMS,
    DEFAULT_TIME_S,
    MAX_ROBUSTNESS,
    MIN_PROCESS_MB,
    LimitExceeded,
    paused,
    stage,
)

EPILOG = """\
examples:
  parmor abilities
  parmor design walking                       asks "Does the robot need to grasp?"
  parmor design walking --answer grasping=yes --json
  parmor design pick-and-place --param object_shape=oval
  parmor enumerate walking
  parmor explain HexapodRobot
  parmor ontology check mine.kif
  parmor regress suite.toml --update
  parmor simulate out/hexapod --behavior walking
  parmor run walk.py out/hexapod

exit codes: 0 done, 1 cannot be met, 2 bad input, 3 an answer is needed and input is off
"""


def _json_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print JSON on stdout")


def _structure_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("structure (sizing links and choosing actuators)")
    g.add_argument(
        "--catalog",
        metavar="NAME|FILE.toml",
        help="module catalog: a shipped one by name (default: the ParMoR modules; "
        "dynamixel: ROBOTIS DYNAMIXEL X servos) or your own file",
    )
    g.add_argument(
        "--parts",
        action="append",
        default=[],
        metavar="FILE.toml",
        help="part kinds of your own (bodies, joints, mounts of a part class; README: Part "
        "kinds), added to or replacing the shipped ones (repeatable)",
    )
    g.add_argument(
        "--conceptual", action="store_true", help="stop after the conceptual design (no sizing)"
    )
    g.add_argument(
        "--no-symmetry",
        action="store_true",
        help="let alike joints (the same joint of alike legs) get different actuators",
    )
    g.add_argument(
        "--objective",
        default="mass,cost",
        metavar="ORDER",
        help="what the actuator choice minimises first: mass,cost (default) or cost,mass",
    )


def _backend_options(p: argparse.ArgumentParser, what: str, jobs_default: str) -> None:
    g = p.add_argument_group(f"where the {what} run")
    g.add_argument(
        "--jobs",
        type=int,
        metavar="N",
        help=f"worker processes, or Ray tasks at once (default: {jobs_default})",
    )
    g.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help=f"local: the {what} run on local processes (default); ray: on a Ray cluster "
        "(pip install 'parmor[ray]'), with the same results",
    )
    g.add_argument(
        "--address",
        metavar="HOST:PORT",
        help="the Ray cluster's head to join (default: RAY_ADDRESS, else a new local Ray instance)",
    )


def _kb_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("knowledge base")
    g.add_argument(
        "--ontology",
        action="append",
        default=[],
        metavar="FILE.kif",
        help="extra SUO-KIF file loaded after ADROn (repeatable)",
    )
    g.add_argument(
        "--rules",
        action="append",
        default=[],
        metavar="FILE.lp",
        help="extra ASP rule file joined to the encodings (repeatable)",
    )
    g.add_argument(
        "--allow-scripts",
        action="store_true",
        help="accept rule files that contain #script or #include files outside their folder",
    )
    _limit_options(p)


def _limit_options(
    p: argparse.ArgumentParser, size: bool = True, each: str = "", memory: str = ""
) -> None:
    """--time-limit, --memory-limit and (where clingo grounds) --size-limit. ``each``: the
    time limit is per item of the command (a sweep's request, a suite's query), not for
    the whole of it."""

    g = p.add_argument_group("limits (0 turns one off; reaching one: exit 1)")
    what = f"wall time of {each}" if each else "wall time of the command, questions excepted"
    g.add_argument(
        "--time-limit",
        type=_limit_value(float),
        default=DEFAULT_TIME_S,
        metavar="SECONDS",
        help=f"{what} (default {DEFAULT_TIME_S:g})",
    )
    g.add_argument(
        "--memory-limit",
        type=_limit_value(int),
        default=DEFAULT_MEMORY_MB,
        metavar="MB",
        help=f"memory {memory or 'of the clingo worker and of this process'} beyond what it "
        f"holds at the start (this process: at least {MIN_PROCESS_MB}; default "
        f"{DEFAULT_MEMORY_MB})",
    )
    if size:
        g.add_argument(
            "--size-limit",
            type=_limit_value(int),
            default=DEFAULT_SIZE_ATOMS,
            metavar="ATOMS",
            help=f"ground program size (default {DEFAULT_SIZE_ATOMS})",
        )


def _limit_value(kind: type):
    def parse(text: str) -> float | int:
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: expected a number >= 0") from None
        if not math.isfinite(v) or v < 0 or v > 1e12:
            raise argparse.ArgumentTypeError(f"{text!r}: expected a number from 0 to 1e12")
        return v

    return parse


#: A seed's largest value (the most perturbed runs, ``MAX_ROBUSTNESS``, is in synth.limits,
#: where a study's reader finds it too).
MAX_SEED = 2**31 - 1


def _whole(name: str, high: int):
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number") from None
        if not 0 <= v <= high:
            raise argparse.ArgumentTypeError(f"{text!r}: expected {name} from 0 to {high}")
        return v

    return parse


def _request_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "abilities",
        nargs="+",
        metavar="ABILITY",
        help="abilities the robot must have (see 'parmor abilities')",
    )
    p.add_argument(
        "--answer",
        action="append",
        default=[],
        metavar="ABILITY=yes|no",
        help="answer a disambiguating question in advance (repeatable)",
    )
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a design parameter, e.g. object_shape=oval (repeatable)",
    )
    _kb_options(p)
    _json_option(p)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="parmor",
        description="Design modular robots from the abilities they must have: the ADROn "
        "ontology (SUO-KIF) is translated to Answer Set Programming and clingo finds the "
        "robot types that can do it, asks what tells them apart, and gives the parts and "
        "modules of the design.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "abilities",
        help="list the abilities a robot can be asked for",
        description="List every ability with its KIF class, the question "
        "that asks for it and the robot types that can have it.",
    )
    _kb_options(p)
    _json_option(p)

    p = sub.add_parser(
        "design",
        help="design a robot for a set of abilities",
        description="Find the robot types that can do every ABILITY, ask "
        "yes/no questions until one remains (on a terminal), and print its "
        "conceptual design: parts, modules, degrees of freedom, abilities.",
        epilog="example: parmor design walking --answer grasping=yes --json",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _request_options(p)
    p.add_argument(
        "--no-input", action="store_true", help="never ask; exit 3 when an answer is still needed"
    )
    _structure_options(p)
    p.add_argument(
        "--no-verify",
        action="store_true",
        help="do not simulate the sized design's behaviours in MuJoCo (faster; the record "
        "says it was not simulated)",
    )
    p.add_argument(
        "--allow-unverified",
        action="store_true",
        help="accept a demanded ability that no behaviour serves, so none can be simulated "
        "(refused otherwise, exit 1); the record and the bundle's README say so",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write the bundle into the folder DIR: "
        "design.json, robot.urdf, robot.xml, meshes/*.stl, bom.csv, README.md "
        "(design.json alone with --conceptual)",
    )
    p.add_argument("--force", action="store_true", help="replace DIR if it is not empty")
    p.add_argument(
        "--bed",
        metavar="WxDxH|PRINTER",
        help="your printer: its build volume (e.g. 180x180x180mm) or a printer of the "
        "catalog by name; a printed part too big for it is turned or split into pieces "
        "joined by dovetails (print/<piece>.stl and .3mf)",
    )
    p.add_argument(
        "--robustness",
        type=_whole("a number of runs", MAX_ROBUSTNESS),
        nargs="?",
        const=-1,
        default=None,
        metavar="K",
        help="run every behaviour that passed under K seeded perturbations too (masses, "
        "floor friction and slope, servo play, bus latency, battery at cut-off, link "
        "compliance; synth/verification/perturb.toml) and accept the design only when each "
        "passes in all of them (the share in that file). Default: K = 8 (that file's default_k; "
        "the environment variable PARMOR_ROBUSTNESS=K sets another); 0 turns it off "
        "(nominal model only, about 8-15 x faster)",
    )
    p.add_argument(
        "--certify",
        type=_whole("a number of runs", MAX_ROBUSTNESS),
        metavar="N",
        help="run N perturbations per behaviour instead of K and print what they show: the "
        "lower bound of each behaviour's success probability at 90 %% confidence "
        "(Clopper-Pearson; 8 of 8 shows > 74 %%, 30 of 30 > 92 %%); a behaviour passes when "
        "its runs show at least what K of K shows (26 of 30, 81 of 100; every run for N <= K)",
    )
    p.add_argument(
        "--with-payload",
        action="store_true",
        help="robot.urdf and robot.xml carry the payload (by default they are the robot "
        "alone; design.json says where the payload is held)",
    )

    p = sub.add_parser(
        "enumerate",
        help="list every candidate robot for a set of abilities",
        description="List every robot type that meets the request, in "
        "preference order (fewest active modules first), with its parts, "
        "modules and abilities, sized for the --param values, with the exact count of its "
        "feasible actuator assignments and the best of them. Asks nothing. With --json, "
        "one JSON object per line as each candidate is done, then a summary line.",
    )
    _request_options(p)
    _structure_options(p)
    p.add_argument("--limit", type=int, metavar="N", help="list at most N candidates")
    p.add_argument(
        "--assignments",
        type=int,
        default=3,
        metavar="K",
        help="list the K best actuator assignments of each candidate (default 3)",
    )
    p.add_argument(
        "--pareto",
        action="store_true",
        help="also print each candidate's mass/cost Pareto front of assignments",
    )
    _backend_options(
        p,
        "candidates' sizings",
        "one per core up to the candidates to size, in this process for one; "
        "on Ray the cluster's CPUs",
    )

    p = sub.add_parser(
        "explain",
        help="show a robot type's parts and abilities, with reasons",
        description="Show the parts of ROBOT_TYPE (own and inherited, with "
        "the axiom that declares each) and each ability with its reason.",
    )
    p.add_argument("robot_type", metavar="ROBOT_TYPE", help="a KIF class, e.g. HexapodRobot")
    _kb_options(p)
    _json_option(p)

    p = sub.add_parser(
        "ontology", help="check SUO-KIF files", description="Work with SUO-KIF files."
    )
    osub = p.add_subparsers(dest="ontology_command", metavar="ACTION", required=True)
    c = osub.add_parser(
        "check",
        help="parse and translate KIF files, report what is not translated",
        description="Parse and translate FILE.kif... on their "
        "own and print the counts of forms, translated forms and untranslated "
        "ones with their locations. Exit 0 when they parse, 2 on a syntax "
        "error.",
    )
    c.add_argument("files", nargs="+", metavar="FILE.kif")
    _json_option(c)
    c.add_argument("--all", action="store_true", help="list every untranslated form")
    _limit_options(c, size=False, memory="of this process")

    p = sub.add_parser(
        "simulate",
        help="run a behaviour of an exported design in MuJoCo and measure it",
        description="Generate the joint trajectory of a behaviour (an ability's short name: "
        "walking, rolling, driving, pick-and-place...) for the design in DIR (written by "
        "'parmor design --out DIR') and run it on DIR/robot.xml in MuJoCo, with the "
        "actuators limited to their stall torques. Reports distance, heading change, "
        "whether it fell, the largest torque over stall, tracking or placing errors. Exit 1 "
        "when the robot fell.",
        epilog="examples:\n  parmor simulate hexapod --behavior walking --gait tripod "
        "--seconds 10\n  parmor simulate cart --behavior driving --set v=0.2 --set w=0.5 "
        "--json\n  parmor simulate arm --behavior pick-and-place --plot",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dir", metavar="DIR", help="a bundle folder written by 'parmor design --out'")
    p.add_argument(
        "--behavior",
        required=True,
        metavar="NAME",
        help="the behaviour to run ('--behavior help' lists them)",
    )
    p.add_argument(
        "--seconds",
        type=float,
        metavar="S",
        help="simulated time (default: the behaviour's duration)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a behaviour parameter, e.g. --set v=0.2 (repeatable)",
    )
    p.add_argument("--gait", metavar="NAME", help="shortcut for --set gait=NAME")
    p.add_argument(
        "--perturb",
        type=_whole("a seed", MAX_SEED),
        metavar="SEED",
        help="run the robot under perturbation SEED of the table it was verified with "
        "(design.json verified.robust; seeds 1..K are the verification's runs)",
    )
    p.add_argument(
        "--fine",
        action="store_true",
        help="with --perturb: run at the model's own time step, where the verification ran "
        "its perturbed runs at the coarse one (design.json verified.robust.physics says which)",
    )
    p.add_argument("--plot", action="store_true", help="write PNG plots of the run into DIR/plots/")
    _json_option(p)
    _limit_options(p, size=False, memory="of this process")

    p = sub.add_parser(
        "blocks",
        help="write a drag-and-drop block page for a design bundle (and serve it)",
        description="Write DIR/blocks/index.html for the design in DIR (written by 'parmor "
        "design --out DIR'): a Blockly page whose blocks are the design's behaviours with "
        "their parameters (units and limits shown), repeat, wait and if/else on what the robot "
        "reports, and the Python program the blocks stand for (run it with 'parmor run "
        "PROGRAM.py DIR'). The page works offline from the bundle. With --serve, a local server "
        "on 127.0.0.1 serves it and runs the programs its Run button sends (as JSON, never "
        "code): validated against the design's behaviours and limits, simulated in MuJoCo, "
        "answered with the path, the verdict figures and the robot moving. Needs the npm "
        "packages ('make web').",
        epilog="examples:\n  parmor blocks hexapod            then open hexapod/blocks/index.html"
        "\n  parmor blocks hexapod --serve    then open http://127.0.0.1:8765/",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dir", metavar="DIR", help="a bundle folder written by 'parmor design --out'")
    p.add_argument("--serve", action="store_true", help="serve the page and run its programs")
    p.add_argument(
        "--port", type=int, default=None, metavar="P", help="port of --serve (default 8765)"
    )
    p.add_argument(
        "--time-limit",
        type=float,
        default=None,
        metavar="S",
        help="wall-clock seconds a run may take before it is stopped (default 120)",
    )

    p = sub.add_parser(
        "run",
        help="run a program of behaviours on a design in simulation",
        description="Run PROGRAM on the design in DIR (a folder written by 'parmor design "
        "--out DIR') in MuJoCo: its behaviours one after another, each starting where the "
        "last ended. PROGRAM is a Python file defining main(robot), calling "
        "robot.do(BEHAVIOUR, PARAM=VALUE, ...), robot.wait(SECONDS) and "
        "robot.report(NAME) (the text a block page shows), or a JSON program as a block "
        'page sends it ({"program": [...]}, see the README). Prints each behaviour\'s '
        "verdict and where the robot ended against where the program says it should. Exit "
        "0 when every behaviour kept its promise and the robot ended where commanded, 1 "
        "when not, 2 on bad input.",
        epilog=RUN_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("program", metavar="PROGRAM.py|PROGRAM.json")
    p.add_argument("dir", metavar="DIR")
    p.add_argument(
        "--animation",
        action="store_true",
        help="with --json: include the animation frames (every drawn part's pose, 20 per s)",
    )
    p.add_argument(
        "--perturb",
        type=_whole("a seed", MAX_SEED),
        metavar="SEED",
        help="run the program on the robot of perturbation SEED of the table it was verified "
        "with (design.json verified.robust; seeds 1..K are the verification's runs): its "
        "masses, floor, battery, play, bus latency and sensor noise",
    )
    _json_option(p)
    _limit_options(p, size=False, memory="of this process")

    p = sub.add_parser(
        "regress",
        help="run a regression suite of design queries",
        description="Run the named queries of SUITE.toml and compare their "
        "results with the snapshot beside it (SUITE.snapshot.json). Exit 0 "
        "when all match, 1 with a diff when one changed.",
        epilog=REGRESS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("suite", metavar="SUITE.toml")
    p.add_argument("--update", action="store_true", help="store the results as the snapshot")
    p.add_argument(
        "--allow-scripts",
        action="store_true",
        help="accept the suite's rule files that contain #script",
    )
    _limit_options(p, each="the grounding and of each query")

    p = sub.add_parser(
        "sweep",
        help="design (and simulate) every request of a parameter study",
        description="Design every request of STUDY.toml (a [[request]] table whose params "
        "hold lists expands into their product) as 'parmor design --no-input' would: sized, "
        "and every behaviour the design lists simulated with its default parameters, "
        "failures fed back (--no-simulate designs as --no-verify does). Requests run in "
        "parallel on local processes, or on a Ray cluster (--backend ray). Writes "
        "DIR/results.csv (one row per request and behaviour: parameters, accepted or the "
        "reason, every verdict figure), DIR/summary.md (pass rates per robot type, failures "
        "by criterion, the refused requests and why) and DIR/plots/*.png (outcome over each "
        "pair of swept parameters per robot type). Each finished request is stored in "
        "DIR/requests/, so an interrupted sweep (Ctrl-C) continues where it stopped when "
        "run again, and gives the same files as an uninterrupted run. Exit 0 when the "
        "sweep ran, whatever its pass rates; 2 on bad input (nothing is written then).",
        epilog=SWEEP_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("study", metavar="STUDY.toml")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="folder of the results (default: the study's name with .sweep, beside it)",
    )
    _backend_options(p, "requests", "the machine's cores; on Ray the cluster's CPUs")
    p.add_argument(
        "--no-simulate",
        action="store_true",
        help="design as 'design --no-verify' does: no simulation (much faster)",
    )
    p.add_argument(
        "--certify",
        type=_whole("a number of runs", MAX_ROBUSTNESS),
        metavar="N",
        help="then design the study's finalists (its accepted requests) again with N "
        "perturbed runs per behaviour, as 'design --certify N', and print what they show: "
        "the lower bound of each behaviour's success probability at 90 %% confidence "
        "(stored, so a certification resumes too)",
    )
    p.add_argument(
        "--allow-scripts",
        action="store_true",
        help="accept the study's rule files that contain #script",
    )
    _json_option(p)
    _limit_options(p, each="the grounding and of each request (in its worker)")

    p = sub.add_parser(
        "ros",
        help="write a ROS 1 package that serves the design's behaviours",
        description="Write DIR/ros/parmor_<robot>/ for the design in DIR (written by 'parmor "
        "design --out DIR'): package.xml, CMakeLists.txt, one service per behaviour "
        "(/<robot>/<behaviour>, its parameters as request fields), a rospy node that plans "
        "them with a parmor worker and publishes the joint trajectory and joint states, a "
        "launch file and the URDF. Exit 2 when DIR has no design with a structure.",
        epilog="example:\n  parmor ros hexapod && source hexapod/ros/parmor_hexapod_robot/"
        "setup.bash && roslaunch parmor_hexapod_robot parmor.launch",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dir", metavar="DIR", help="a bundle folder written by 'parmor design --out'")
    p.add_argument("--name", metavar="NAME", help="the robot's ROS name (default: from its type)")
    p.add_argument("--force", action="store_true", help="replace the package if it exists")
    _json_option(p)
    _limit_options(p, size=False, memory="of this process")
    return parser


SWEEP_HELP = """\
study format (TOML; paths are relative to the study file):
  ontology = ["mine.kif"]          # optional, like --ontology
  rules = ["extra.lp"]             # optional, like --rules
  catalog = "my-catalog.toml"      # optional, like --catalog
  [[request]]
  name = "hexapod"                 # optional (default: the abilities joined by +)
  abilities = ["rough-terrain-walking"]
  answers = { grasping = "no" }    # optional
  params = { payload = ["0.1kg", "0.3kg"], speed = ["0.03m/s", "0.05m/s"], obstacle_height = "4cm" }
  # a list expands into the product with the other lists: 4 requests here

examples:
  parmor sweep studies/parameter-range.toml --no-simulate   designs only (fast)
  parmor sweep studies/parameter-range.toml --jobs 4        into studies/parameter-range.sweep/
  parmor sweep mine.toml --out runs/mine --json             the summary as JSON on stdout
  parmor sweep mine.toml --out runs/mine                    again: only what is not stored yet
  parmor sweep mine.toml --backend ray --address head:6379  on a Ray cluster (README)
"""


RUN_HELP = """\
a program (PROGRAM.py; 'parmor blocks DIR' writes the same text from blocks):
  def main(robot):
      for _ in range(3):
          robot.do("walking", steps=2)
      robot.do("turning", angle=1.5708)
      if robot.report("heading_deg") > 45:
          robot.wait(1)

reports: x_m, y_m, heading_deg (since the start), distance_m (last behaviour), ok and
fell (1 or 0), time_s. Behaviours and their parameters: parmor simulate DIR --behavior help

examples:
  parmor run walk.py out/hexapod
  parmor run walk.json out/hexapod --json
"""


REGRESS_HELP = """\
suite format (TOML; paths are relative to the suite file):
  ontology = ["mine.kif"]          # optional, like --ontology
  rules = ["extra.lp"]             # optional, like --rules
  catalog = "my-catalog.toml"      # optional, like --catalog
  conceptual = true                # optional, like --conceptual
  [[query]]
  name = "walking-grasp"
  abilities = ["walking"]
  answers = { grasping = "yes" }   # optional
  params = { object_shape = "oval" }  # optional
"""


def use_parts(files, kb=None) -> None:
    """Assemble with the shipped part kinds and ``files`` (``--parts``); InputError (exit
    2) naming the file and the key of a part kind that cannot be used, or (given the
    knowledge base ``kb``) of a user's kind for a class no ontology has."""
    from kinematics.partkinds import PartKindError, shipped_text, use
    from kinematics.partkinds import load as load_kinds

    try:
        kinds = load_kinds(files) if files else None
    except PartKindError as e:
        raise InputError(str(e)) from None
    if kinds is not None and kb is not None:
        known = {a for args in kb.translation.relation("subclass") for a in args[:2]}
        shipped = shipped_text()[0] + ":"
        for kind in kinds.kinds.values():
            if kind.cls not in known and not kind.where.startswith(shipped):
                raise InputError(
                    f"{kind.where.rsplit(' (', 1)[0]}.class: {kind.cls!r} is no class of the "
                    "ontology (a kind for it would never be used; give the file that defines "
                    "it with --ontology)"
                )
    use(kinds)


def _with_composed_arm(kb, args: argparse.Namespace):
    """``kb``, or ``kb`` with a serial arm of ``--param dof=N`` joints composed from the
    part kinds (``synth.reasoning.composition``) when none of its base configurations is one."""
    from synth.reasoning.conceptual import parse_param

    given = [v for n, v in (parse_param(p) for p in getattr(args, "param", ())) if n == "dof"]
    if not given:
        return kb
    from adron.kb import load
    from kinematics.partkinds import in_use
    from synth.params import parse_dof
    from synth.reasoning.composition import serial_arm_kif
    from synth.reasoning.plans import arm_joints

    n = parse_dof(given[-1])
    bases = [a[0] for a in kb.translation.relation("instance") if a[1:] == ("BaseConfiguration",)]
    if any(arm_joints(kb, t) == n for t in bases):
        return kb
    text = serial_arm_kif(n, in_use())
    return load(args.ontology, texts=[(f"<parmor: arm composed for --param dof={n}>", text)])


def _designer(args: argparse.Namespace, err: TextIO, req=None):
    """Load the knowledge base and ground it; returns a Designer. ``req``: the command's
    request, whose query the reasoner then grounds for first (``Reasoner``'s ``first``)."""
    from adron.kb import load
    from synth.reasoning.conceptual import Designer, query_for
    from synth.reasoning.solver import Reasoner

    with stage("parse"):
        kb = load(args.ontology)
        use_parts(getattr(args, "parts", ()), kb)
        kb = _with_composed_arm(kb, args)
    _warn_untranslated(kb, err)
    # checked while the worker filters the ontology (a large one's abilities take a while)
    first = (lambda: query_for(kb, req)) if req is not None else None
    limit = None  # the catalog bus's module limit governs the conceptual step too
    if hasattr(args, "catalog"):
        from synth.pipeline import bus_limit

        def limit() -> int | None:  # parsed while the worker filters the ontology
            return bus_limit(args.catalog, getattr(args, "conceptual", False))

    modules: tuple[str, ...] = ()
    if hasattr(args, "conceptual") and not args.conceptual:  # sizing follows
        modules = SIZING_MODULES
        if args.command == "design" and (not args.no_verify or args.out):
            modules += MODEL_MODULES
    reasoner = Reasoner(
        kb,
        args.rules,
        args.allow_scripts,
        bus_limit=limit,
        while_grounding=(lambda ready: _prefetch(modules, kb, ready)) if modules else None,
        first=first,
    )
    return Designer(kb, reasoner)


#: What sizing imports, and what the models of a verification or a bundle import (trimesh
#: and MuJoCo: 1-2 s on a loaded machine), imported while the reasoner's worker grounds:
#: this process only waits on a pipe then, and a large ontology grounds for seconds.
SIZING_MODULES = (
    "synth.sizing.structure",
    "synth.sizing.families",
    "synth.sizing.behaviour_loads",
    "gaits.legged",
    "gaits.hexapod",
    "gaits.humanoid",
    "gaits.snake",
    "gaits.wheeled",
    "gaits.manipulator",
)
MODEL_MODULES = (
    "export.bundle",
    "export.assembly",
    "export.meshes",
    "export.mjcf",
    "synth.verification.simulate",
    "synth.verification.loop",
    "export.polymesh",
    "mujoco",
)
#: What only a first design needs (the quadruped's sway programmes, cached on disk after:
#: gaits/hexapod.py: _sway): imported only while the worker still grounds, so that a
#: design that does not need it does not wait for its import.
IDLE_MODULES = ("scipy.sparse", "scipy.optimize", "scipy.interpolate")


def _prefetch(names: Sequence[str], kb=None, ready: Callable[[], bool] | None = None) -> None:
    """Import ``names``, then index ``kb``'s taxonomy for the actuator assignment
    (``synth.sizing.assign.prepare_knowledge``), then import IDLE_MODULES until ``ready()`` (the
    worker has replied). Run by the reasoner on this (the main) thread while its worker
    grounds, not on a thread of its own: a thread still importing when the process forks
    (the ground probe after a time limit) or exits (Ctrl-C, an early refusal) deadlocked
    the fork or crashed the interpreter's shutdown (issue 23). Ctrl-C and the time limit
    stop these imports as any other (see ``_SignalsWait``). An import or an index that
    fails is left to where it is used, which reports it."""

    def load(name: str) -> None:
        # a failed import is tried again, and reported, where the module is used
        with contextlib.suppress(Exception):
            __import__(name)  # through the import statement's hook (``_SignalsWait``)

    for name in names:
        load(name)
    if kb is not None:
        try:
            from synth.sizing.assign import prepare_knowledge

            prepare_knowledge(kb)
        except LimitExceeded:
            raise
        except Exception:  # noqa: BLE001 - done again, and reported, where used
            pass
    for name in IDLE_MODULES if ready is not None else ():
        if ready():
            break
        load(name)


def _warn_untranslated(kb, err: TextIO) -> None:
    # The shipped ontology translates completely (a test holds it to that), so every
    # untranslated form comes from the user's --ontology files.
    user = kb.translation.untranslated
    if user:
        first = user[0]
        err.write(
            f"parmor: note: {len(user)} form(s) of your ontology were not translated "
            f"(first at {first.location}: {first.reason}); see 'parmor ontology "
            "check'\n"
        )


def _request(args: argparse.Namespace):
    from synth.reasoning.conceptual import Request, parse_answer, parse_param

    return Request(
        abilities=tuple(args.abilities),
        answers=tuple(parse_answer(a) for a in args.answer),
        params=tuple(parse_param(p) for p in args.param),
    )


def _ask(question, err: TextIO) -> bool:
    with paused():  # a person thinking is not the command hanging
        return _ask_now(question, err)


def _ask_now(question, err: TextIO) -> bool:
    while True:
        err.write(f"{question.text} [y/n] ")
        err.flush()
        line = sys.stdin.readline()
        if not line:
            raise AnswerNeeded(f"an answer is needed: {question.text}")
        v = line.strip().lower()
        if v in ("y", "yes"):
            return True
        if v in ("n", "no"):
            return False
        err.write("please answer y or n\n")


def _options(args: argparse.Namespace):
    from synth.pipeline import StructureOptions, parse_objective

    return StructureOptions(
        args.catalog,
        args.conceptual,
        not args.no_symmetry,
        parse_objective(args.objective),
        verify=not getattr(args, "no_verify", False),
        with_payload=getattr(args, "with_payload", False),
        allow_unverified=getattr(args, "allow_unverified", False),
        robustness=_robustness(getattr(args, "robustness", 0), getattr(args, "no_verify", False)),
        certify=getattr(args, "certify", None) is not None,
    )


#: The environment variable that sets ``parmor design``'s K when ``--robustness`` is not
#: given (a whole number; 0: nominal verification only).
ROBUSTNESS_ENV = "PARMOR_ROBUSTNESS"


def _robustness(k: int | None, no_verify: bool = False) -> int:
    """``--robustness``'s K: -1 (the option alone) is the table's default
    (``synth/verification/perturb.toml``, ``[acceptance] default_k``); without the option (None) the
    design is robustly verified too, with ``PARMOR_ROBUSTNESS`` when it is set, else that
    default (0 under ``--no-verify``: nothing is simulated)."""
    if k is not None and k >= 0:
        return k
    if k is None:
        if no_verify:
            return 0
        env = os.environ.get(ROBUSTNESS_ENV)
        if env is not None and env.strip() != "":
            try:
                return _whole("a number of runs", MAX_ROBUSTNESS)(env.strip())
            except argparse.ArgumentTypeError as e:
                raise InputError(f"environment variable {ROBUSTNESS_ENV}: {e}") from None
    from synth.verification.perturb import ranges

    return int(ranges()["default_k"])


def cmd_design(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from export.record import design_text, to_json, verification_text
    from synth.pipeline import run

    if args.certify is not None:
        conflict = args.robustness is not None or args.no_verify
        args.robustness = limits.certify_runs(args.certify, conflict, "--robustness/--no-verify")
    if args.no_verify and args.robustness is not None and args.robustness != 0:
        raise InputError("--robustness runs the verification under perturbations: drop --no-verify")
    if args.out is not None:
        from export.bundle import check_out

        check_out(args.out, args.force)  # before any work (written after it)
    req = _request(args)
    designer = _designer(args, err, req)
    opts = _options(args)
    bed = _bed(args.bed, args.catalog, designer) if args.bed is not None else None
    interactive = not args.no_input and sys.stdin.isatty()
    while interactive:
        d = designer.step(req)
        if d.status != "ambiguous":
            break
        err.write("Candidates: " + ", ".join(c.robot_type for c in d.candidates) + "\n")
        q = d.questions[-1]
        req = req.answer(q.ability, _ask(q, err))
    with stage("structure/simulate"):
        result = run(designer, req, opts)
    if bed is not None:
        from dataclasses import replace

        result = replace(result, bed=bed)
    d = result.design
    if result.note and not opts.conceptual:
        err.write(f"parmor: note: {result.note}\n")
    rec = result.record(designer)
    if result.infeasible:
        if args.json:
            out.write(to_json(rec))
        err.write(f"parmor: cannot build it: {result.infeasible}\n")
        return 1
    if args.out and d.status == "designed":
        from export.bundle import write_bundle

        files = result.files(designer)
        write_bundle(args.out, files, force=args.force)
    if args.json:
        out.write(to_json(rec))
    else:
        out.write(design_text(d, designer.short, result.structure))
        out.write(verification_text(rec.get("verified")))
    if d.status == "ambiguous":
        q = d.questions[-1]
        err.write(
            f"parmor: an answer is needed: {q.text} "
            f"(pass --answer {q.ability}=yes or --answer {q.ability}=no)\n"
        )
        return AnswerNeeded.exit_code
    if d.status == "unsatisfiable":
        why = f" ({d.note})" if d.note else ""
        err.write(f"parmor: no robot can meet the request: {' + '.join(d.conflict)}{why}\n")
        return 1
    if args.out:
        err.write(f"parmor: wrote {args.out}: {', '.join(sorted(files))}\n")
    return 0


def _bed(text: str, catalog: str | None, designer):
    """The user's printer of ``--bed``: a size ``WxDxH`` or a catalog printer's model
    (``export.split.Bed``); InputError naming the value otherwise."""
    from export.split import Bed, bed_label, parse_bed

    try:
        size = parse_bed(text)
    except ValueError as e:
        raise InputError(f"--bed {e}") from None
    if size is not None:
        return Bed(bed_label(size), size)
    from synth.pipeline import load_checked_catalog

    cat = load_checked_catalog(catalog, designer)
    for p in cat.printers:
        if p.model.casefold() == text.strip().casefold():
            return Bed(p.model, p.bed_m)
    names = ", ".join(repr(p.model) for p in cat.printers) or "none"
    raise InputError(
        f"--bed {text!r}: neither a build volume WxDxH (e.g. 180x180x180mm) nor a printer "
        f"of the catalog ({names})"
    )


def cmd_enumerate(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    import json

    from export.record import candidate_record, candidate_text
    from synth.commands.backend import Backend, tasks

    engine = Backend(args.backend, args.jobs, args.address)  # bad values told before any work
    req = _request(args)
    designer = _designer(args, err, req)
    opts = _options(args)
    if args.limit is not None and args.limit < 0:
        raise InputError("--limit must be 0 or more")
    if args.assignments < 1:
        raise InputError("--assignments must be 1 or more")
    sol = designer.reasoner.solve(designer.query(req))
    physical = designer.structural(req)
    cands, over = designer.within_limits(sol.candidates, physical)
    shown = cands[: args.limit] if args.limit is not None else cands
    sizing = not opts.conceptual
    if args.backend == "local" and args.jobs is None:
        # one process per core while there is more than one candidate to size (the sizings
        # are independent; the output is the same), else in this process
        from dataclasses import replace

        engine = replace(engine, jobs=max(1, min(os.cpu_count() or 1, len(shown))) if sizing else 1)
    progress = _progress(err, len(shown)) if sizing and shown and err.isatty() else None

    def emit(i: int, rec: dict) -> None:
        c = shown[i - 1]
        if args.json:
            out.write(
                json.dumps({"type": "candidate", "rank": i, **rec}, ensure_ascii=False) + "\n"
            )
            out.flush()
        else:
            out.write(f"{i}. {c.robot_type}\n{candidate_text(c, designer.short, '   ')}\n")
            if sizing:
                out.write(_Sizer.text(rec, "   "))
        if progress and i < len(shown):
            progress(i + 1, shown[i].robot_type)

    records = [candidate_record(c, designer.short) for c in shown]
    if not sizing:
        for i, rec in enumerate(records, 1):
            emit(i, rec)
    else:  # sized on the engine; printed in rank order as soon as each is done
        if progress:
            progress(1, shown[0].robot_type)
        arg = (args.ontology, args.rules, args.allow_scripts, opts, physical)
        arg += (args.assignments, args.pareto)
        here = _Sizer(designer, opts, physical, args.assignments, args.pareto)
        files = (args.catalog, args.ontology, args.rules)
        items = list(enumerate(shown, 1))
        sized: dict[int, dict] = {}
        nxt = 1
        with (
            stage("structure"),
            tasks(engine, _sizer_init, arg, _sizer_work, items, files, here=here) as done,
        ):
            for i, result in done:
                sized[i] = result
                while nxt in sized:
                    emit(nxt, {**records[nxt - 1], **sized.pop(nxt)})
                    nxt += 1
    if progress:
        progress(None, "")
    conflict = list(designer.conflict(req)) if not sol.candidates else []
    if sol.candidates and not cands:
        conflict = list(designer.limit_conflict(req, over))
    status = "enumerated" if cands else "unsatisfiable"
    if args.json:
        summary = {
            "type": "summary",
            "status": status,
            "count": len(cands),
            "shown": len(shown),
            "conflict": conflict,
            "excluded": over,
        }
        out.write(json.dumps(summary, ensure_ascii=False) + "\n")
    else:
        for t, ws in over.items():
            out.write(f"not built for this request: {t} ({', '.join(ws)})\n")
        listed = f"{len(shown)} of {len(cands)}" if len(shown) < len(cands) else f"{len(cands)}"
        out.write(f"{listed} candidate(s)\n")
    if not cands:
        why = ""
        limited = designer.over_limit(req) if not sol.candidates else ()
        if limited:  # robots the module limit alone excludes: name them and the bus
            from synth.pipeline import limit_source
            from synth.reasoning.conceptual import limit_note

            why = f" ({limit_note(limited, limit_source(opts))})"
        err.write(f"parmor: no robot can meet the request: {' + '.join(conflict)}{why}\n")
        return 1
    return 0


class _Sizer:
    """Sizes each enumerated candidate and lists its feasible actuator assignments."""

    def __init__(self, designer, opts, physical, k: int, pareto: bool) -> None:
        from synth.pipeline import load_checked_catalog

        self.designer, self.opts, self.physical = designer, opts, physical
        self.k, self.pareto = k, pareto
        self.catalog = load_checked_catalog(opts.catalog, designer)

    def size(self, c) -> dict:
        from export.record import alternatives_record, structure_record
        from synth.sizing.structure import StructureDesigner, alternatives

        try:
            sd = StructureDesigner(
                self.designer.kb,
                c,
                self.catalog,
                self.physical,
                self.opts.symmetric,
                self.opts.objective,
            )
            s = sd.run()
            alts = alternatives(sd, self.k, self.pareto)
        except InfeasibleError as e:
            return {"structure": None, "infeasible": str(e)}
        except InputError as e:  # a candidate whose body plan cannot be sized: said, not sized
            return {"structure": None, "note": str(e)}
        srec = structure_record(s)
        keep = ("mass_kg", "cost", "iterations", "params", "lengths_m", "wheel_radius_m")
        return {"structure": {k: srec[k] for k in keep}, "assignments": alternatives_record(alts)}

    @staticmethod
    def text(rec: dict, indent: str) -> str:
        if rec.get("infeasible"):
            return f"{indent}infeasible: {rec['infeasible']}\n"
        if rec.get("structure") is None:
            return f"{indent}{rec.get('note', '')}\n"
        s, a = rec["structure"], rec["assignments"]
        alike = "alike joints alike" if a["symmetric"] else "joints independent"
        of = a["count_capable"]
        lines = [
            f"{indent}sized:      {s['mass_kg']:.3f} kg, cost {s['cost']:.2f}",
            f"{indent}assignments: {_count(a['count'])} feasible of {_count(of)} capable "
            f"({alike}), best first:"
            if a.get("count_exact", True)
            else f"{indent}assignments: between {_count(a.get('count_lower', 0), -1)} and "
            f"{_count(a['count'], 1)} feasible of {_count(of)} capable ({alike}; too many "
            "to count exactly), best first:",
        ]
        for n, x in enumerate(a["ranked"], 1):
            lines.append(
                f"{indent}  {n}. modules {x['modules_mass_kg']:.3f} kg, "
                f"cost {x['modules_cost']:.2f}: {x['summary']}"
            )
        if a.get("pareto") is not None:
            lines.append(f"{indent}mass/cost Pareto front:")
            lines += [
                f"{indent}  modules {x['modules_mass_kg']:.3f} kg, cost "
                f"{x['modules_cost']:.2f}: {x['summary']}"
                for x in a["pareto"]
            ]
        return "\n".join(lines) + "\n"


def _count(n: int, way: int = 0) -> str:
    """A count for people: exact up to 10^9, else three significant digits (``1.25e+20``),
    rounded down (``way`` -1: a lower bound), up (1: an upper bound) or to the nearest
    (0: an exact count, said to be approximate). ``--json`` keeps every digit."""
    if n < 10**9:
        return str(n)
    exp = len(str(n)) - 3
    head, rest = divmod(n, 10**exp)
    half = 5 * 10 ** (exp - 1)
    head += (way > 0 and rest > 0) or (way == 0 and rest >= half)
    if head >= 1000:
        head, exp = head // 10, exp + 1
    text = f"{head / 100:.2f}e+{exp + 2:02d}"
    return text if way else f"about {text}"


def _sizer_init(arg: tuple) -> _Sizer:
    """A worker's sizer (``synth.commands.backend``): the knowledge base grounded again there."""
    from synth.commands.regress import designer_for

    ontology, rules, allow_scripts, opts, physical, k, pareto = arg
    kb = {
        "ontology": ontology,
        "rules": rules,
        "allow_scripts": allow_scripts,
        "catalog": opts.catalog,
    }
    return _Sizer(designer_for(kb), opts, physical, k, pareto)


def _sizer_work(sizer: _Sizer, c) -> dict:
    return sizer.size(c)


def _progress(err: TextIO, total: int):
    """A progress line on a terminal (rich): call with (i, name), then (None, "")."""
    from rich.console import Console
    from rich.progress import Progress

    bar = Progress(transient=True, console=Console(file=err))
    task = bar.add_task("sizing", total=total)
    bar.start()

    def step(i: int | None, name: str) -> None:
        if i is None:
            bar.stop()
        else:
            bar.update(task, completed=i - 1, description=f"sizing {name}")

    return step


def cmd_explain(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from export.record import to_json
    from synth.reasoning.explain import explain_record, explain_text

    designer = _designer(args, err)
    rec = explain_record(designer, args.robot_type)
    out.write(to_json(rec) if args.json else explain_text(rec))
    return 0


def cmd_abilities(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from export.record import to_json
    from synth.reasoning.solver import Query

    designer = _designer(args, err)
    sol = designer.reasoner.solve(Query())
    kb = designer.kb
    rows = []
    for a in kb.abilities:
        rows.append(
            {
                "ability": a.name,
                "kif": a.kif,
                "question": a.question,
                "robot_types": sorted(c.robot_type for c in sol.candidates if a.kif in c.potential),
                "documentation": kb.translation.documentation.get(a.kif, ""),
            }
        )
    if args.json:
        out.write(to_json(rows))
    else:
        width = max((len(r["ability"]) for r in rows), default=0)
        for r in rows:
            who = ", ".join(r["robot_types"]) or "(no robot type)"
            out.write(f"{r['ability']:<{width}}  {r['kif']}: {who}\n")
    return 0


def cmd_ontology_check(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from adron.kb import load
    from adron.relevance import REASONS
    from export.record import to_json
    from synth.reasoning.solver import materialised_in_worker, relevant

    # one load, the shipped ontology with the user's files (it holds the vocabulary that
    # relevance is judged by); the user's files' own counts are read from it by file
    full = load(args.files)
    files = list(full.files[len(full.files) - len(args.files) :])
    mine = set(files)
    tr = full.translation
    counts = [tr.by_file.get(f, (0, 0, 0, 0, 0)) for f in mine]
    forms, facts, rules, axioms, metadata = (sum(c[i] for c in counts) for i in range(5))
    un = [u for u in tr.untranslated if u.file in mine]
    full = materialised_in_worker(full)
    # as the solver sees it: the ontology-only rules materialised (adron/materialise.py)
    rel = relevant(full, grounded=True)
    grounded = full.grounded if full.grounded is not None else full.translation
    own = [
        (k, why)
        for u, k, why in zip(grounded.units, rel.kept, rel.reasons, strict=True)
        if u.where.rsplit(":", 2)[0] in mine
    ]
    filtered = {r: sum(1 for _, w in own if w == r) for r in REASONS}
    n_rules = sum(1 for u in full.translation.units if u.kind == "rule")
    materialised = n_rules - sum(1 for u in grounded.units if u.kind == "rule")
    relevance_rec = {
        "forms": len(own),
        "relevant": sum(1 for k, _ in own if k),
        "filtered": {r: n for r, n in filtered.items() if n},
        "unfiltered_because": rel.off,
        "materialised_rules": materialised,
        "derived_facts": len(grounded.units) - len(full.translation.units) + materialised,
    }
    rec = {
        "files": files,
        "forms": forms,
        "translated": facts + rules + axioms + metadata,
        "facts": facts,
        "rules": rules,
        "existential_axioms": axioms,
        "metadata": metadata,
        "untranslated": len(un),
        "relevance": relevance_rec,
        "untranslated_forms": [
            {"file": u.file, "line": u.line, "col": u.col, "reason": u.reason, "text": u.text}
            for u in (un if args.all or args.json else un[:10])
        ],
    }
    if args.json:
        out.write(to_json(rec))
        return 0
    out.write(
        f"{forms} forms in {len(files)} file(s): {rec['translated']} translated "
        f"({facts} facts, {rules} rules, {axioms} existential axioms, "
        f"{metadata} metadata), {len(un)} untranslated\n"
    )
    r = relevance_rec
    shown = ", ".join(f"{n} {REASONS[k]}" for k, n in r["filtered"].items()) or "nothing"
    out.write(
        f"{r['relevant']} of {r['forms']} translated forms (metadata aside) reach the robot "
        f"vocabulary and go to the grounder; filtered: {shown}\n"
    )
    if r["materialised_rules"]:
        out.write(
            f"  {r['materialised_rules']} rule(s) read only the ontology: replaced by the "
            f"{r['derived_facts']} fact(s) they derive, filtered as facts\n"
        )
    if r["unfiltered_because"]:
        out.write(f"  nothing is filtered: {r['unfiltered_because']}\n")
    for u in rec["untranslated_forms"]:
        out.write(f"  {u['file']}:{u['line']}:{u['col']}: {u['reason']}: {u['text']}\n")
    if len(un) > len(rec["untranslated_forms"]):
        out.write(f"  ... and {len(un) - len(rec['untranslated_forms'])} more (--all lists them)\n")
    return 0


def cmd_regress(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from synth.commands.regress import run_suite

    return run_suite(
        args.suite,
        update=args.update,
        out=out,
        err=err,
        allow_scripts=args.allow_scripts,
        lim=getattr(args, "limits", None),
    )


def cmd_sweep(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from synth.commands.sweep import cmd_sweep as sweep

    return sweep(args, out, err)


#: Longest simulated time of one ``simulate`` run, s (the samples are held in memory).
MAX_SIM_SECONDS = 600.0
#: Shortest one, s: a behaviour's verdict needs some motion to judge (50 MuJoCo steps).
MIN_SIM_SECONDS = 0.1


def cmd_simulate(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from pathlib import Path

    from export.record import to_json

    folder = Path(args.dir)
    if args.fine and args.perturb is None:
        raise InputError("--fine sets the step of a perturbed run: add --perturb SEED")
    from synth.verification.runs import figures, run_behavior
    from synth.verification.source import Bundle

    params: dict[str, str] = {}
    for item in args.set:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise InputError(f"--set {item!r}: expected NAME=VALUE")
        params[name.strip()] = value.strip()
    if args.gait:
        params["gait"] = args.gait
    if args.seconds is not None and not (
        math.isfinite(args.seconds) and MIN_SIM_SECONDS <= args.seconds <= MAX_SIM_SECONDS
    ):
        raise InputError(
            f"--seconds {args.seconds:g}: expected a number of seconds in "
            f"[{MIN_SIM_SECONDS:g}, {MAX_SIM_SECONDS:g}]"
        )

    if args.plot:
        _check_writable(folder / "plots", "--plot")
    bundle = Bundle.read(folder)
    record, model = bundle.record, bundle.model()
    try:
        controller = bundle.controller()
        if args.behavior == "help":
            listed = set(controller.listed(record.get("abilities", ())))
            for name, spec in sorted(controller.behaviors.items()):
                ps = ", ".join(
                    f"{p.name}={p.default}{' ' + p.unit if p.unit else ''}" for p in spec.params
                )
                tag = "" if name in listed else f"  (not verified: {spec.realises} is not listed)"
                if spec.alias_of:
                    tag = f"  (alias of {spec.alias_of})"
                out.write(f"{name}: {spec.doc}{tag}\n  parameters: {ps or 'none'}\n")
            return 0
        if args.behavior not in controller.behaviors:
            sensed = _simulate_sensing(folder, args, params)
            if sensed is not None:
                return _report_sensing(sensed, args, out, err)
        progress = None
        if err.isatty():
            step = _progress(err, 100)

            def progress(fraction: float) -> None:
                step(int(fraction * 100) + 1, f"simulating {args.behavior}")

        with stage("simulate"):
            if args.perturb is None:
                traj, result = run_behavior(
                    model, controller, args.behavior, params, args.seconds, progress
                )
            else:
                from synth.verification.perturb import summary
                from synth.verification.runs import recorded_table, run_perturbed

                table = None
                if args.fine:  # the recorded table at the model's own step
                    table = recorded_table(record)
                    table.pop("timestep_s", None)
                traj, result, drawn = run_perturbed(
                    bundle,
                    args.behavior,
                    args.perturb,
                    params,
                    args.seconds,
                    table=table,
                    progress=progress,
                )
    except (ValueError, KeyError) as e:
        raise InputError(e.args[0] if isinstance(e, KeyError) and e.args else str(e)) from None
    if progress is not None:
        step(None, "")
    rec = figures(traj, result)
    if args.perturb is not None:
        rec["perturbation"] = summary(drawn)
    if args.plot:
        from export.plots import write_plots

        try:
            rec["plots"] = write_plots(folder / "plots", traj, result)
        except OSError as e:
            raise InputError(f"{folder / 'plots'}: cannot write the plots: {e}") from None
    if args.json:
        out.write(to_json(rec))
    else:
        for key, value in rec.items():
            if value is not None:
                if isinstance(value, list):
                    value = ", ".join(str(v) for v in value)
                out.write(f"{key:>22}: {value}\n")
    if not result.ok:
        why = ", ".join(result.verdict)
        when = f" (fell at {result.fell_at_s:.2f} s)" if result.fell_at_s is not None else ""
        err.write(f"parmor: {args.behavior} failed its verdict: {why}{when}\n")
        return 1
    return 0


def _simulate_sensing(folder, args: argparse.Namespace, params: dict) -> dict | None:
    """A sensing behaviour of the bundle (line-tracking, obstacle-avoidance:
    :mod:`program.sensing`) run as the design's verification runs it, on a fresh robot with
    ``params``; its judged figures, or None when ``args.behavior`` is not one of them. Its
    course sets its time, so ``--seconds`` and ``--plot`` do not apply. ``--perturb SEED``
    runs it on that perturbation of the table the design was verified with, as the robust
    verification ran it (the figures of its ``verified.robust`` entry, to the bit)."""
    from program.session import Session

    session = Session(folder)
    if args.behavior not in session.sensing:
        return None
    if args.seconds is not None:
        raise InputError(
            f"--seconds does not apply to {args.behavior}, a sensing loop (its course "
            "sets its time): drop it"
        )
    if args.plot:
        raise InputError(f"--plot does not apply to {args.behavior}, a sensing loop: drop it")

    if args.perturb is not None:
        from synth.verification.perturb import summary
        from synth.verification.runs import recorded_table

        session = Session(folder, perturb=(recorded_table(session.record), args.perturb))
    with stage("simulate"):
        fig = session.do(args.behavior, **params)["figures"]
    if session.perturbation is not None:
        fig["perturbation"] = summary(session.perturbation)
    return fig


def _report_sensing(fig: dict, args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Print a sensing run's figures (JSON or a table); exit 1 when its verdict failed."""
    from export.record import to_json

    if args.json:
        out.write(to_json(fig))
    else:
        for key, value in fig.items():
            if value is not None:
                out.write(f"{key:>22}: {value}\n")
    if fig["verdict"] != "ok":
        why = ", ".join(fig["verdict"]) if isinstance(fig["verdict"], list) else fig["verdict"]
        err.write(f"parmor: {args.behavior} failed its verdict: {why}\n")
        return 1
    return 0


def _check_writable(target, option: str) -> None:
    """Refuse, before any work, a ``target`` folder that cannot be written: a file in its
    place, or a parent folder without write permission."""
    if target.exists() and not target.is_dir():
        raise InputError(f"{option}: {target} exists and is not a folder")
    where = target if target.is_dir() else target.parent
    if not os.access(where, os.W_OK | os.X_OK):
        raise InputError(f"{option}: {where} is not writable")


def cmd_ros(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from export.record import to_json
    from program.ros import ros_package

    path, iface = ros_package(args.dir, args.name, args.force)
    services = [f"/{iface['robot']}/{s['service']}" for s in iface["services"]]
    if args.json:
        out.write(to_json({"package": str(path), "services": services}))
    else:
        out.write(f"{path}\n" + "".join(f"  {s}\n" for s in services))
    return 0


def cmd_blocks(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from pathlib import Path

    from program.blocks import write_page
    from program.server import DEFAULT_PORT, DEFAULT_TIME_LIMIT, check_time_limit, serve

    if not args.serve and (args.port is not None or args.time_limit is not None):
        raise InputError("--port and --time-limit need --serve")
    port = DEFAULT_PORT if args.port is None else args.port
    if not 0 <= port <= 65535:
        raise InputError(f"--port {port}: expected a port number in [0, 65535] (0: any free)")
    limit = check_time_limit(DEFAULT_TIME_LIMIT if args.time_limit is None else args.time_limit)
    page = write_page(Path(args.dir))
    err.write(f"parmor: wrote {page}\n")
    if args.serve:
        serve(args.dir, port, limit, out=out, log=err)
        err.write("parmor: stopped serving\n")
    return 0


def cmd_run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from pathlib import Path

    from export.record import to_json
    from program.script import read_file
    from program.session import run_program, run_python

    path = Path(args.program)
    progress = None
    if err.isatty():

        def progress(text: str) -> None:
            err.write(f"running {text}\n")

    form, program = read_file(path)  # JSON or Python, by content and suffix

    with stage("run"):  # the program and its behaviours: a limit here is not in 'parse'
        if form == "json":
            result = run_program(args.dir, program, progress, args.perturb, str(path))
        else:
            result = run_python(args.dir, path, progress, args.perturb)
    if not args.animation:
        result.pop("animation")
    if args.json:
        out.write(to_json(result))
    else:
        out.write(run_text(result))
    if result["verdict"] != "ok":
        err.write(f"parmor: the program failed its verdict: {'; '.join(result['verdict'])}\n")
        return 1
    return 0


def run_text(result: dict) -> str:
    """A program run for people: one line per behaviour, then where the robot ended."""
    lines = []
    for i, st in enumerate(result["steps"], 1):
        f = st["figures"]
        what = "ok" if st["verdict"] == "ok" else "FAILED " + ", ".join(st["verdict"])
        moved = ""
        if f.get("distance_m") is not None and result["final_pose"] is not None:
            moved = (
                f", moved {f['distance_m']:.3f} m, turned {math.degrees(f['heading_rad']):.1f} deg"
            )
        if f.get("placing_error_m") is not None:
            moved += f", placed within {1000 * f['placing_error_m']:.1f} mm"
        lines.append(f"{i:3d}. {st['behavior']:<24} at {st['start_s']:7.2f} s: {what}{moved}")
    if result["final_pose"] is not None:
        x, y, yaw = result["final_pose"]
        lines.append(f"ended at   x {x:.3f} m, y {y:.3f} m, heading {math.degrees(yaw):.1f} deg")
        if result["expected_pose"] is not None:
            x, y, yaw = result["expected_pose"]
            lines.append(
                f"commanded  x {x:.3f} m, y {y:.3f} m, heading {math.degrees(yaw):.1f} deg "
                f"(off by {result['end_pose_error_m']:.3f} m)"
            )
    verdict = result["verdict"]
    lines.append(
        f"simulated {result['seconds']:.2f} s; verdict: "
        + ("ok" if verdict == "ok" else "; ".join(verdict))
    )
    return "\n".join(lines) + "\n"


#: Commands whose --time-limit is for each item (a suite's query, a sweep's request).
PER_ITEM = ("regress", "sweep")

COMMANDS = {
    "abilities": cmd_abilities,
    "blocks": cmd_blocks,
    "design": cmd_design,
    "enumerate": cmd_enumerate,
    "explain": cmd_explain,
    "regress": cmd_regress,
    "ros": cmd_ros,
    "run": cmd_run,
    "simulate": cmd_simulate,
    "sweep": cmd_sweep,
}


def main(
    argv: Sequence[str] | None = None, out: TextIO | None = None, err: TextIO | None = None
) -> int:
    """Run the command line; returns the exit code (never raises for user errors). Run as
    the program (``argv`` None), it also stands in for standard streams the shell closed
    (``>&-``), lets Ctrl-C and the time limit wait while a module is imported
    (``_SignalsWait``), ignores Ctrl-C once the exit code is decided (a Ctrl-C while the
    interpreter shuts down would end it with a traceback and signal 2), and ends the
    process without the interpreter's shutdown when that is not safe (``_end``)."""
    global _WAIT
    program = argv is None
    if program:
        _fill_closed_fds()
        _WAIT = _SignalsWait()
    out = out or sys.stdout or _ClosedOutput()
    err = err or sys.stderr or open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115
    try:
        code = _main(sys.argv[1:] if argv is None else list(argv), out, err)
    except KeyboardInterrupt:  # before the command ran, or again while an exit was told
        _tell(err, "parmor: interrupted\n")
        code = 130
    except ParmorError as e:  # the time limit's alarm again while an exit was told
        _tell(err, f"parmor: error: {_one_line(str(e))}\n")
        code = e.exit_code
    finally:
        if program:
            with contextlib.suppress(ValueError, OSError):
                signal.signal(signal.SIGINT, signal.SIG_IGN)
            _WAIT.remove()
            _WAIT = None
    if program:
        _end(code)
    return code


def _end(code: int) -> None:
    """End the program at once, without the interpreter's shutdown, unless it ended well
    with no other thread running: a run stopped by a limit, Ctrl-C or an error may leave
    threads simulating (the time limit's alarm interrupts the wait for them) or a
    library's C state half done, and the shutdown then died of SIGSEGV after the message
    (issue 23). The standard streams are flushed and the atexit functions run first (they
    stop the reasoner's workers and process pools)."""
    import threading

    if code == 0 and threading.active_count() == 1:
        return
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            if stream is not None:
                stream.flush()
    import atexit

    with contextlib.suppress(BaseException):
        atexit._run_exitfuncs()
    os._exit(code)


def _main(argv: list[str], out: TextIO, err: TextIO) -> int:
    # Nothing parmor does renders through MuJoCo's OpenGL back-end. Without this, `import
    # mujoco` on Linux first runs a Python child to probe glfw's version (50-150 ms), and a
    # process killed meanwhile (a block-page run at its time limit) leaves that child to
    # print a BrokenPipeError traceback. Processes started from here inherit it.
    os.environ.setdefault("MUJOCO_GL", "disable")
    for arg in argv:  # a shell cannot pass one; a caller in Python can (open() would raise)
        if "\x00" in arg:
            err.write(f"parmor: error: argument {arg!r} contains a NUL character\n")
            return InputError.exit_code
    parser = build_parser()
    limited = False
    uncap = None
    try:
        shown = io.StringIO()  # argparse ignores a write that fails: written below
        try:
            with contextlib.redirect_stdout(shown), contextlib.redirect_stderr(err):
                args = parser.parse_args(argv)
        except SystemExit as e:  # argparse: --help (0) or a usage error (2)
            out.write(shown.getvalue())
            out.flush()
            return int(e.code or 0)
        handler = cmd_ontology_check if args.command == "ontology" else COMMANDS[args.command]
        # the shipped ontology's body plans, for a bundle whose record predates body plans
        # (explicit here: importing export or program installs nothing)
        from synth.reasoning.plans import install

        install()
        limited = hasattr(args, "memory_limit")  # every command but blocks (its own limit)
        if limited:
            lim = limits.Limits(
                args.time_limit or None,
                args.memory_limit or None,
                getattr(args, "size_limit", 0) or None,
            )
            if args.command in PER_ITEM:  # their time limit is per item (limits.bounded)
                args.limits = lim
                lim = limits.Limits(None, lim.memory_mb, lim.size_atoms)
            limits.configure(lim)
            if _WAIT is not None:
                _WAIT.hold_alarm(limits.remaining)
            if getattr(args, "backend", "local") != "ray":  # Ray's own processes inherit it
                uncap = limits.cap_memory(lim.memory_mb)
        with contextlib.ExitStack() as stack:
            if limited:  # reading the input (and the imports) until a stage says otherwise
                stack.enter_context(limits.stage("parse"))
            code = handler(args, out, err)
        out.flush()
        return code
    except ParmorError as e:
        _tell(err, f"parmor: error: {_one_line(str(e))}\n")
        return e.exit_code
    except MemoryError:
        if uncap is None:
            raise
        uncap()
        _tell(err, f"parmor: error: {_one_line(str(limits.memory_exceeded()))}\n")
        return 1
    except KeyboardInterrupt:
        _tell(err, "parmor: interrupted\n")
        return 130
    except OSError as e:
        # the output went away (``| head -1``: a broken pipe), is full (``> /dev/full``) or
        # was closed (``>&-``)
        if not isinstance(e, _OutputClosed) and e.errno not in (
            errno.EPIPE,
            errno.ENOSPC,
            errno.EDQUOT,
            errno.EIO,
        ):
            return _unexpected(e, err, limited)
        _discard_output(out)
        why = "closed early (broken pipe)" if e.errno == errno.EPIPE else e.strerror
        _tell(err, f"parmor: error: cannot write the output: {why}\n")
        return ExportError.exit_code
    except Exception as e:  # noqa: BLE001 - told when a stop caused it, else raised
        return _unexpected(e, err, limited)
    finally:
        if uncap is not None:
            uncap()
        if limited:
            limits.configure(limits.Limits())


class _SignalsWait:
    """Run as the program, Ctrl-C and the time limit's alarm wait while the main thread
    imports a module, and act as soon as the outermost import is done (a module takes
    0.2 s at most, more on a loaded machine). Raised inside an extension module's
    initialisation, the exception was lost to an ImportError (the command went on: a
    hang while the worker grounded), turned into an ImportError's traceback (numpy), or
    left the interpreter to end by signal 2 after the message (MuJoCo runs Python code
    through ``PyRun_String``, which records a KeyboardInterrupt as never caught).

    Imports are counted by a hook on ``builtins.__import__`` (every import statement, and
    C code's ``PyImport_Import``); signals wait in their Python handlers, not in the
    signal mask (the libraries' threads, OpenBLAS's, would take a masked signal, and
    Python runs every handler on the main thread). The alarm waits only under the handler
    in force when ``hold_alarm`` is called (``limits.bounded`` sets its own).

    A Ctrl-C that Python reports as unraisable (its handler ran inside a ``__del__`` or a
    weakref callback, which cannot raise: clingo's AST objects are collected at any
    moment) is raised again 20 ms later by the alarm, instead of being printed and lost
    (the command then waited for its worker: a hang). Nothing can raise it sooner: each
    way of sending a signal from Python runs the handler at once, still inside the hook.
    A time limit lost so is not printed either: its alarm rings again until the run ends."""

    def __init__(self) -> None:
        import _thread
        import builtins

        self.depth = 0
        self.came: list[tuple[int, Callable | None]] = []
        self.lost = False  # a Ctrl-C lost in a finalizer, for the alarm to raise again
        self.interrupted = False  # Ctrl-C came
        self._remaining: Callable[[], float | None] | None = None
        self.main = _thread.get_ident()
        self._ident = _thread.get_ident
        self._builtins = builtins
        self._import = builtins.__import__
        builtins.__import__ = self.importing
        self._unraisable = sys.unraisablehook
        sys.unraisablehook = self.unraisable
        signal.signal(signal.SIGINT, self.signalled)

    def hold_alarm(self, remaining: Callable[[], float | None]) -> None:
        """Let the time limit's alarm (its handler now in force) wait too; ``remaining``:
        the seconds left before the limit (``limits.remaining``)."""
        handler = signal.getsignal(signal.SIGALRM)
        if callable(handler):
            self._remaining = remaining
            signal.signal(signal.SIGALRM, lambda n, f: self.rang(n, f, handler))

    def rang(self, signum: int, frame: object, handler: Callable) -> None:
        if not self.lost:
            self.signalled(signum, frame, handler)
            return
        self.lost = False  # the alarm was set to raise a lost Ctrl-C again
        left = self._remaining() if self._remaining is not None else None
        if left is not None and left > 0:  # the time limit's own ring, back in place
            signal.setitimer(signal.ITIMER_REAL, left)
        self.signalled(signal.SIGINT, frame)

    def remove(self) -> None:
        if self._builtins.__import__ == self.importing:
            self._builtins.__import__ = self._import
        if sys.unraisablehook == self.unraisable:
            sys.unraisablehook = self._unraisable

    def unraisable(self, info) -> None:  # noqa: ANN001 - sys.UnraisableHookArgs

        kind = info.exc_type if isinstance(info.exc_type, type) else type(None)
        if issubclass(kind, KeyboardInterrupt) and self._remaining is not None:
            self.lost = True
            signal.setitimer(signal.ITIMER_REAL, 0.02)
        elif not issubclass(kind, LimitExceeded):  # the alarm rings again (REPEAT_S)
            self._unraisable(info)

    def signalled(self, signum: int, frame: object, handler: Callable | None = None) -> None:
        self.interrupted |= handler is None
        if self.depth:
            self.came.append((signum, handler))
        elif handler is None:
            raise KeyboardInterrupt
        else:
            handler(signum, frame)

    def importing(self, *args, **kwargs):  # noqa: ANN002, ANN003, ANN204 - __import__'s
        if self._ident() != self.main:
            return self._import(*args, **kwargs)
        self.depth += 1
        try:
            return self._import(*args, **kwargs)
        finally:
            self.depth -= 1
            if not self.depth and self.came:
                came, self.came = self.came, []
                for signum, handler in came:  # the first that raises ends the import
                    self.signalled(signum, None, handler)


#: The program's _SignalsWait (None when ``main`` is called from Python)
_WAIT: _SignalsWait | None = None


def _unexpected(e: Exception, err: TextIO, limited: bool) -> int:
    """Tell ``e``, an error parmor does not expect, as what stopped the run when a stop
    caused it (Ctrl-C or the time limit's alarm raised inside a library that turned it
    into another error: numpy's TypeError, an ImportError), and return the exit code;
    otherwise raise it (a bug: its traceback is the report)."""

    x: BaseException | None = e
    while x is not None and not isinstance(x, (KeyboardInterrupt, limits.LimitExceeded)):
        x = x.__cause__ or x.__context__
    left = limits.remaining() if limited else None
    if x is None and _WAIT is not None and _WAIT.interrupted:
        x = KeyboardInterrupt()
    elif x is None and left is not None and left <= 0:
        x = limits.LimitExceeded(limits.current().describe("time"), limits.stage_name())
    if isinstance(x, KeyboardInterrupt):
        err.write("parmor: interrupted\n")
        return 130
    if isinstance(x, limits.LimitExceeded):
        err.write(f"parmor: error: {_one_line(str(x))}\n")
        return x.exit_code
    raise e


def _tell(err: TextIO, text: str) -> None:
    """Write ``text`` to ``err`` if it can be written."""
    with contextlib.suppress(OSError, ValueError):
        err.write(text)
        err.flush()


class _OutputClosed(OSError):
    """A write to a standard output the shell closed (``>&-``)."""


class _ClosedOutput(io.TextIOBase):
    """Standard output when the process started without one: each write fails, as a
    write to a closed pipe would, so the command ends with exit 2 and says why."""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        if not text:
            return 0
        raise _OutputClosed(errno.EBADF, "standard output is closed")


def _fill_closed_fds() -> None:
    """Put /dev/null on each of the descriptors 0, 1 and 2 that the shell closed: else the
    next file or pipe opened takes the number, and a child writes its output into it.
    (Python leaves ``sys.stdout`` None then; ``main`` writes to a ``_ClosedOutput``.)"""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            with contextlib.suppress(OSError):
                null = os.open(os.devnull, os.O_RDWR)
                if null != fd:
                    os.dup2(null, fd)
                    os.close(null)
    if sys.stdin is None:  # read as "no answer" (exit 3), as an empty input is
        sys.stdin = open(os.devnull, encoding="utf-8")  # noqa: SIM115


#: Longest error message printed, characters (a message quoting a huge input is cut).
MAX_MESSAGE = 2000


def _one_line(message: str) -> str:
    """``message`` on one line (line breaks shown as ' | '), its middle cut past MAX_MESSAGE."""
    message = " | ".join(part.strip() for part in message.strip().splitlines() if part.strip())
    if len(message) > MAX_MESSAGE:
        cut = len(message) - MAX_MESSAGE
        message = (
            f"{message[: MAX_MESSAGE // 2]} [... {cut} characters ...] "
            + message[-MAX_MESSAGE // 2 :]
        )
    return message


def _discard_output(out: TextIO) -> None:
    """Point the standard output that failed at /dev/null, so that the interpreter's last
    flush of what is still buffered does not fail again with a traceback."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        if out is sys.stdout or out is sys.__stdout__:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, out.fileno())
            os.close(null)


if __name__ == "__main__":
    sys.exit(main())
