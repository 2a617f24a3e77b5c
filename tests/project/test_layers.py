"""The layering of docs/architecture.md, checked: import contracts and no import-time work.

The contracts are ``[tool.importlinter]`` in pyproject.toml (a layers contract over the
pipeline's layers, an acyclic-siblings contract over each package), run here with
``lint-imports`` as a user runs it; their exceptions are listed there with their reasons.
Importing ``export`` or ``program`` installs nothing: the entry points install the shipped
ontology's body plans (``synth.reasoning.plans.install``), which a bundle whose record predates
recorded body plans needs.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from tests.conftest import need

ROOT = Path(__file__).resolve().parents[2]
CONFIG = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
LINT = Path(sys.executable).parent / "lint-imports"


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(ROOT)
    return env


def lint(folder: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` on the packages in ``folder`` with its pyproject.toml's contracts."""
    need(LINT.is_file(), "import-linter is not installed (pip install -e '.[test]')")
    env = _env()
    env["PYTHONPATH"] = str(folder)  # the packages of this folder, not the installed ones
    return subprocess.run(
        [str(LINT), "--no-cache", "--no-logo"],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


# --------------------------------------------------------------------------- contracts


def test_the_import_contracts_hold() -> None:
    proc = lint(ROOT)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "0 broken" in proc.stdout


def _copy(tmp_path: Path) -> Path:
    for pkg in CONFIG["root_packages"]:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    return tmp_path


def _append(path: Path, text: str) -> None:
    path.write_text(path.read_text() + text)


def test_an_upward_import_or_a_new_circle_breaks_the_contracts(tmp_path: Path) -> None:
    """A copy of the packages with one upward import (kinematics -> export, function-local,
    as the circles of old were closed), one new circle (the ground probe importing the
    solver back) and a controller reading the ontology: each contract fails, naming them."""
    root = _copy(tmp_path)
    _append(root / "kinematics" / "spatial.py", "\n\ndef _up():\n    from export import urdf\n")
    probe = root / "synth" / "reasoning" / "ground_probe.py"
    _append(probe, "\n\ndef _back():\n    from synth.reasoning import solver\n")
    _append(root / "gaits" / "feedback.py", "\n\ndef _onto():\n    from adron import units\n")
    proc = lint(root)
    assert proc.returncode == 1, proc.stdout[-4000:]
    assert "Contracts: 0 kept, 3 broken." in proc.stdout
    assert "gaits is not allowed to import adron" in proc.stdout
    assert "kinematics.spatial -> export.urdf" in proc.stdout
    assert "No cycles are allowed in synth.reasoning." in proc.stdout
    assert ".solver -> .ground_probe" in proc.stdout


def test_an_exception_no_import_needs_fails(tmp_path: Path) -> None:
    """The exception list stays what the code is: an ignored import that no longer exists
    is an error (import-linter's default), so a circle broken later leaves the list."""
    root = _copy(tmp_path)
    text = (root / "pyproject.toml").read_text()
    stale = '    "kinematics.templates -> kinematics.assemble",\n'
    assert stale in text
    (root / "pyproject.toml").write_text(
        text.replace(stale, stale + '    "gaits.base -> gaits.legged",\n', 1)
    )
    proc = lint(root)
    assert proc.returncode != 0
    assert "No matches for ignored import gaits.base -> gaits.legged" in proc.stdout + proc.stderr


def _modules(root: Path = ROOT) -> list[str]:
    out = []
    for pkg in CONFIG["root_packages"]:
        for f in sorted((root / pkg).rglob("*.py")):
            rel = f.relative_to(root).with_suffix("")
            if "ros_templates" in rel.parts:  # files written into a ROS package, not imported
                continue
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            out.append(".".join(parts))
    return out


def unplaced(modules: list[str], layers: list[str]) -> list[str]:
    """The modules no layer holds (a layer names modules or packages, ``a : b``), other
    than the root packages' own ``__init__`` (they import nothing of parmor)."""
    named = [m.strip() for layer in layers for m in layer.replace("|", ":").split(":")]
    roots = set(CONFIG["root_packages"])
    return [
        m
        for m in modules
        if m not in roots and not any(m == n or m.startswith(n + ".") for n in named)
    ]


def test_every_module_is_in_a_layer() -> None:
    """A new module is placed on purpose: one line in the layers contract."""
    layers = next(c for c in CONFIG["contracts"] if c["type"] == "layers")["layers"]
    assert unplaced(_modules(), layers) == []
    # the check itself: a module of a new job in synth/ is caught
    assert unplaced(["synth.studies.grid", "export.urdf"], layers) == ["synth.studies.grid"]


#: The tests' folder for what is not one package: the documentation and the layers.
PROJECT_TESTS = "project"


def misplaced_tests(tests: Path, root: Path) -> list[str]:
    """Test files not in a folder that mirrors a package of ``root`` (``tests/gaits/`` for
    ``gaits/``, ``tests/synth/sizing/`` for ``synth/sizing/``) or in ``tests/project/``."""
    out = []
    for path in sorted(tests.rglob("test_*.py")):
        folder = path.parent.relative_to(tests)
        package = root.joinpath(*folder.parts)
        mirrored = bool(folder.parts) and (package / "__init__.py").is_file()
        if not (mirrored or folder.parts == (PROJECT_TESTS,)):
            out.append(path.relative_to(tests).as_posix())
    return out


def test_the_tests_mirror_the_packages(tmp_path: Path) -> None:
    assert misplaced_tests(ROOT / "tests", ROOT) == []
    # the check itself: a test at the top, or in a folder no package has, is caught
    (tmp_path / "tests" / "gaits").mkdir(parents=True)
    (tmp_path / "gaits").mkdir()
    (tmp_path / "gaits" / "__init__.py").write_text("")
    for name in ("test_top.py", "gaits/test_ok.py", "gates/test_typo.py"):
        (tmp_path / "tests" / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "tests" / name).write_text("")
    assert misplaced_tests(tmp_path / "tests", tmp_path) == ["gates/test_typo.py", "test_top.py"]


# ------------------------------------------------------------- no import-time side effects


def _python(code: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, env=_env(), capture_output=True, text=True
    )


def test_importing_a_package_installs_nothing() -> None:
    proc = _python(
        "import sys\n"
        "import adron, export, gaits, kinematics, program, synth\n"
        "import export.record, program.script\n"
        "from kinematics.bodyplan import PLAN_SOURCE\n"
        "print(len(PLAN_SOURCE), 'synth.reasoning.plans' in sys.modules)\n"
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["0", "False"]


@pytest.fixture(scope="module")
def old_bundle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A cart's bundle whose record has no body plan, as records before body plans were."""
    folder = tmp_path_factory.mktemp("old") / "cart"
    proc = subprocess.run(
        [sys.executable, "-m", "synth.commands.cli", "design", "driving", "--no-verify", "--out"]
        + [str(folder)],
        cwd=ROOT,
        env=_env(),
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    record = json.loads((folder / "design.json").read_text())
    del record["body_plan"]
    (folder / "design.json").write_text(json.dumps(record, indent=1))
    return folder


def test_an_old_bundle_needs_the_installed_body_plans(old_bundle: Path) -> None:
    """Without ``install()`` the record's type has no body plan (the error says what to
    call); with it, the shipped ontology's is found."""
    record = str(old_bundle / "design.json")
    proc = _python(
        "import json, sys\n"
        "from gaits import controller_for\n"
        "from gaits.base import DesignGeometry\n"
        f"g = DesignGeometry.from_record(json.loads(open({record!r}).read()))\n"
        "try:\n"
        "    controller_for(g)\n"
        "except ValueError as e:\n"
        "    print('refused:', e)\n"
        "from synth.reasoning.plans import install\n"
        "install()\n"
        "print('then:', type(controller_for(g)).__name__)\n"
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("refused: unknown robot type 'DifferentialDriveRobot'")
    assert "synth.reasoning.plans.install()" in lines[0]
    assert lines[1] == "then: WheeledController"


def test_parmor_installs_them_itself(old_bundle: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "synth.commands.cli", "simulate", str(old_bundle)]
        + ["--behavior", "driving", "--seconds", "0.2"],
        cwd=ROOT,
        env=_env(),
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "behavior: driving" in proc.stdout


# --------------------------------------------------------------- function-local imports

#: Commands whose start-up a function-local import may keep light (the project's modules
#: each imports are measured in a fresh process): every command's help, the dialogue's
#: listing, a design without verification, and the same written out.
STARTUP_COMMANDS = (
    ["--help"],
    ["abilities"],
    [
        "design",
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=no",
        "--no-verify",
        "--no-input",
    ],
    [
        "design",
        "walking",
        "--answer",
        "grasping=no",
        "--answer",
        "rough-terrain-walking=no",
        "--no-verify",
        "--no-input",
        "--out",
        "{tmp}/bundle",
    ],
)

#: Function-local imports kept for a start-up no command above shows, with the reason.
DEFERRED = {
    ("program.server", "program.session"): "the block server answers pages without MuJoCo; "
    "only the child process that runs a program imports the session",
    ("program.server", "synth.reasoning.plans"): "the same child installs the body plans",
}

_LOADED = (
    "import json, sys\n"
    "from synth.commands.cli import main\n"
    "try:\n    main(json.loads(sys.argv[1]))\nexcept SystemExit:\n    pass\n"
    "roots = {roots!r}\n"
    "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in roots)))\n"
)


def function_local_imports(root: Path, graph) -> list[tuple[str, int, str]]:
    """(module, line, imported module) of every import of a parmor module inside a
    function of the packages in ``root`` (a name imported from a package resolves to the
    package unless it is a module of ``graph``)."""
    import ast

    roots = set(CONFIG["root_packages"])
    out = []
    for module in _modules(root):
        path = root.joinpath(*module.split("."))
        path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for fn in ast.walk(tree):
            if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                    names = [
                        f"{node.module}.{a.name}"
                        if f"{node.module}.{a.name}" in graph.modules
                        else node.module
                        for a in node.names
                    ]
                else:
                    continue
                for name in names:
                    if name.split(".")[0] in roots:
                        out.append((module, node.lineno, name))
    return sorted(set(out))


def circles(graph) -> dict[str, int]:
    """Module -> the number of its import circle (strongly connected component of more than
    one module, function-local imports included)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: dict[str, int] = {}
    counter = [0]

    def visit(v: str) -> None:  # Tarjan's algorithm, iterative over the edges
        work = [(v, iter(sorted(graph.find_modules_directly_imported_by(v))))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        while work:
            node, edges = work[-1]
            for w in edges:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.find_modules_directly_imported_by(w)))))
                    break
                if w in on:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    if len(comp) > 1:
                        number = len(set(out.values()))
                        for w in comp:
                            out[w] = number

    for m in sorted(graph.modules):
        if m not in index:
            visit(m)
    return out


def unexplained(
    imports: list[tuple[str, int, str]],
    circle_of: dict[str, int],
    loaded: list[set[str]],
    deferred: dict[tuple[str, str], str],
) -> list[str]:
    """The function-local imports that neither close an import circle (both modules in
    one), nor keep a measured start-up light (a command in ``loaded`` imports the module
    but not what it imports), nor are listed in ``deferred``: "module:line -> target"."""
    out = []
    for module, line, target in imports:
        if module in circle_of and circle_of.get(target) == circle_of[module]:
            continue
        if any(module in s and target not in s for s in loaded):
            continue
        if (module, target) in deferred:
            continue
        out.append(f"{module}:{line} -> {target}")
    return out


def _loaded(argv: list[str], tmp: Path) -> set[str]:
    argv = [a.replace("{tmp}", str(tmp)) for a in argv]
    code = _LOADED.format(roots=sorted(CONFIG["root_packages"]))
    proc = subprocess.run(
        [sys.executable, "-c", code, json.dumps(argv)],
        cwd=tmp,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    return set(json.loads(proc.stdout.strip().splitlines()[-1]))


def test_function_local_imports_keep_start_up_light_or_close_a_circle(tmp_path: Path) -> None:
    """A function-local import of a parmor module is there for a reason a machine can check:
    a command's start-up it keeps light (measured: the command imports the module, not what
    it imports), or an import circle it closes (listed in pyproject.toml's contracts), or
    one of ``DEFERRED``; anything else belongs at the top of its module."""
    grimp = pytest.importorskip("grimp")
    graph = grimp.build_graph(
        *CONFIG["root_packages"], include_external_packages=False, cache_dir=None
    )
    imports = function_local_imports(ROOT, graph)
    loaded = [_loaded(argv, tmp_path) for argv in STARTUP_COMMANDS]
    assert all(len(s) > 3 for s in loaded), loaded  # the commands ran
    assert unexplained(imports, circles(graph), loaded, DEFERRED) == []
    # the check itself: one import no start-up and no circle needs is named
    # (the command line importing what every command loads anyway)
    local = ("synth.commands.cli", 1, "synth.limits")
    assert unexplained([local], circles(graph), loaded, {}) == [
        "synth.commands.cli:1 -> synth.limits"
    ]
    # ... while one that closes a circle is not
    kept = ("adron.catalog", 1, "adron.catalog_schema")
    assert unexplained([kept], circles(graph), loaded, {}) == []
    # ... as is one that only a listed reason kept
    server = [i for i in imports if i[0] == "program.server"]
    assert server and unexplained(server, circles(graph), loaded, {})
