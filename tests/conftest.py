"""Shared fixtures: the shipped knowledge base grounded once per session, and a runner
for the command line through ``main(argv)``."""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path

import pytest

import synth.bodyplan  # noqa: F401  (the shipped ontology's body plans, by type name)
from adron.kb import KnowledgeBase, load
from synth.cli import main
from synth.conceptual import Designer
from synth.solver import Reasoner

REPO = Path(__file__).resolve().parents[1]

#: ``parmor design`` verifies under 8 perturbations by default; the suite's many designs
#: stay on the nominal model (set here, before any test, for in-process runs and the
#: subprocesses alike). Tests of the robust verification pass ``--robustness K`` or
#: ``StructureOptions(robustness=K)``; tests/test_robust_default.py checks the default.
os.environ["PARMOR_ROBUSTNESS"] = "0"


def _shipped_types() -> tuple[str, ...]:
    """The shipped ontology's base configurations, in the order the paper presents them."""
    kb = load()
    bases = {a[0] for a in kb.translation.relation("instance") if a[1:] == ("BaseConfiguration",)}
    order = ("Manipulator3DOF", "Manipulator6DOF", "HexapodRobot", "QuadrupedRobot")
    return tuple(t for t in order if t in bases) + tuple(sorted(bases - set(order)))


#: The shipped robot types (what the old per-type templates were): the tests' table.
TEMPLATES = _shipped_types()
SHARED = REPO.parent / "shared"
CI = os.environ.get("CI") == "true"


def need(ok: bool, why: str) -> None:
    """Skip with ``why`` unless ``ok``: a tool or folder the test needs is absent here. Under
    CI=true fail instead: CI installs every tool and has ../shared (.ci/run)."""
    if not ok:
        if os.environ.get("CI") == "true":  # read now: a test may set it
            pytest.fail(f"{why}, and CI=true forbids skipping")
        pytest.skip(why)


def require_dir(path: Path) -> Path:
    """``path`` if it is a folder; otherwise skip, or fail when CI=true (CI has ../shared)."""
    need(path.is_dir(), f"{path} is absent (tests that need ../shared skip)")
    return path


def require_shared(sub: str) -> Path:
    """``../shared/<sub>``; skips where it is absent, fails under CI=true."""
    return require_dir(SHARED / sub)


@pytest.fixture(scope="session")
def kb() -> KnowledgeBase:
    return load()


@pytest.fixture(scope="session")
def designer(kb: KnowledgeBase) -> Designer:
    return Designer(kb, Reasoner(kb))


@pytest.fixture(scope="session")
def catalog():
    """The shipped module catalog."""
    from adron.catalog import load_catalog

    return load_catalog()


@pytest.fixture(scope="session")
def bases(designer: Designer) -> dict:
    """Robot type -> conceptual design of every base configuration of the ontology."""
    from synth.solver import Query

    return {c.robot_type: c for c in designer.reasoner.solve(Query()).candidates}


@dataclass
class Run:
    code: int
    out: str
    err: str


@pytest.fixture
def cli(monkeypatch: pytest.MonkeyPatch):
    """Run ``parmor ARGS`` in-process; stdin is a non-terminal unless ``stdin`` is given."""

    def run(*argv: str, stdin: str | None = None, tty: bool = False) -> Run:
        class In(io.StringIO):
            def isatty(self) -> bool:
                return tty

        monkeypatch.setattr("sys.stdin", In(stdin or ""))
        out, err = io.StringIO(), io.StringIO()
        code = main(list(argv), out=out, err=err)
        return Run(code, out.getvalue(), err.getvalue())

    return run
