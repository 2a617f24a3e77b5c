"""Shared fixtures: the shipped knowledge base grounded once per session, and a runner
for the command line through ``main(argv)``."""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path

import pytest

import synth.reasoning.plans
from adron.kb import KnowledgeBase, load
from synth.commands.cli import main
from synth.reasoning.conceptual import Designer
from synth.reasoning.solver import Reasoner

REPO = Path(__file__).resolve().parents[1]

# the shipped ontology's body plans, by type name (the tests build templates of the
# shipped types by name, as parmor's entry points let a bundle older than recorded plans)
synth.reasoning.plans.install()

#: ``parmor design`` verifies under 8 perturbations by default; the suite's many designs
#: stay on the nominal model (set here, before any test, for in-process runs and the
#: subprocesses alike). Tests of the robust verification pass ``--robustness K`` or
#: ``StructureOptions(robustness=K)``; tests/synth/verification/test_robust_default.py
#: checks the default.
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
    from synth.reasoning.solver import Query

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


# --- designs several test files ask for: one per request per session ----------------------


@dataclass(frozen=True)
class Designed:
    """What ``parmor design ARGV --no-input --out FOLDER`` printed and wrote."""

    folder: Path
    code: int
    out: str
    err: str


class SharedDesigns:
    """``parmor design`` run once per session for each request (its arguments and the
    text of its KIF files): several files design the same request, and a verified design
    takes seconds. The bundle is read-only for the tests: one that writes into it copies it
    first (:meth:`copy`). An argument ``KIF:<name>`` is the path of a file ``<name>.kif``
    holding ``kif[name]``."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self._made: dict[tuple, Designed] = {}

    def __call__(self, *argv: str, kif: dict[str, str] | None = None) -> Designed:
        texts = kif or {}
        key = (argv, tuple(sorted(texts.items())))
        if key not in self._made:
            here = self.root / f"design{len(self._made)}"
            here.mkdir(parents=True)
            args = []
            for a in argv:
                if a.startswith("KIF:"):
                    path = here / f"{a[4:]}.kif"
                    path.write_text(texts[a[4:]], encoding="utf-8")
                    a = str(path)
                args.append(a)
            out, err = io.StringIO(), io.StringIO()
            folder = here / "bundle"
            code = main(["design", *args, "--no-input", "--out", str(folder)], out, err)
            self._made[key] = Designed(folder, code, out.getvalue(), err.getvalue())
        done = self._made[key]
        assert done.code == 0, done.err
        return done

    @staticmethod
    def copy(done: Designed, to: Path) -> Path:
        """A copy of the bundle of ``done`` at ``to``, for a test that writes into it."""
        import shutil

        shutil.copytree(done.folder, to)
        return to


@pytest.fixture(scope="session")
def designs(tmp_path_factory: pytest.TempPathFactory) -> SharedDesigns:
    """The session's :class:`SharedDesigns`."""
    return SharedDesigns(tmp_path_factory.mktemp("shared-designs"))


@pytest.fixture(scope="session")
def humanoid(designs: SharedDesigns) -> Path:
    """The humanoid's bundle (walking with grasping, not verified), designed once for the
    files that perturb it (read-only)."""
    return designs("walking", "--answer", "grasping=yes", "--no-verify").folder


@pytest.fixture
def robust_walk(monkeypatch):
    """``gaits.humanoid.ROBUST_WALK`` as the humanoid's walk for one test (the plan memos
    cleared before and after)."""
    from gaits import base, humanoid

    monkeypatch.setattr(humanoid, "WALK", humanoid.ROBUST_WALK)
    humanoid.conversion_maps.cache_clear()
    base._PLANNED.clear()
    yield
    humanoid.conversion_maps.cache_clear()
    base._PLANNED.clear()


def _without_imu(record: dict) -> dict:
    """The record with its IMU module dropped: a biped whose design carries none (it walks
    ``gaits.humanoid.WALK`` open loop, as every biped did before it had an IMU)."""
    import copy

    from gaits.feedback import IMU_CLASS

    out = copy.deepcopy(record)
    out["modules"] = [m for m in out.get("modules", ()) if m.get("kind") != IMU_CLASS]
    return out


def _open_loop(traj):
    """The same plan without its feedback loop (what ``simulate(..., feedback=False)``
    runs), for the runners that take no ``feedback`` argument."""
    import dataclasses

    return dataclasses.replace(traj, info={k: v for k, v in traj.info.items() if k != "feedback"})


@pytest.fixture(scope="session")
def without_imu():
    """``without_imu(record)``: the record with its IMU dropped (tests/gaits/test_balance.py)."""
    return _without_imu


@pytest.fixture(scope="session")
def open_loop():
    """``open_loop(traj)``: the plan without its feedback loop (tests/gaits/test_balance.py)."""
    return _open_loop
