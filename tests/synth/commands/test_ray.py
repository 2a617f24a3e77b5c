"""The Ray backend (synth.commands.backend): a sweep and an enumeration on a local Ray
cluster of two workers give the same files and lines as on local processes.

The cluster is started once for the module in this process (``ray.init``: two CPUs, no
dashboard, a small object store, its files under the test's temporary folder) and shut down
at the end, which ends every process it started. The command runs in this process with
``--backend ray`` (it uses the open Ray session) and once as a separate process that joins
the cluster by ``--address``, as on a cluster of many machines. Skips when Ray is absent;
fails under CI=true, where ``.[test]`` installs it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import synth.commands.sweep
from tests.conftest import need
from tests.synth.commands.test_sweep import TINY, outputs, write

REPO = Path(__file__).resolve().parents[3]
WORKERS = 2  # CPUs of the test cluster: two tasks at once
OBJECT_STORE = 100 * 1024**2  # bytes; the results are small dicts

# the sweep tests' cheap study: two snakes, two carts, one too fast to size, one no robot
# can meet, one that needs an answer
STUDY = TINY
N_STUDY = 7


def need_ray():
    """The ray module; skips when it is absent, fails under CI=true."""
    try:
        import ray
    except ImportError:
        need(False, "ray is not installed (pip install 'parmor[ray]')")
    return ray


def test_an_address_where_no_cluster_answers_is_refused_at_once(cli, tmp_path: Path) -> None:
    """Before the module's cluster starts (an open Ray session would be used instead)."""
    need_ray()
    import socket

    with socket.socket() as s:  # a port nothing listens on once closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    study = write(tmp_path / "s.toml", STUDY)
    r = cli(
        "sweep", str(study), "--no-simulate", "--backend", "ray", "--address", f"127.0.0.1:{port}"
    )
    assert r.code == 2 and "no Ray cluster answers there" in r.err, r.err
    assert not list((tmp_path / "s.sweep" / "requests").glob("*.json"))


@pytest.fixture(scope="module")
def ray_cluster(tmp_path_factory: pytest.TempPathFactory):
    """A local Ray cluster of two workers; yields the address of its head."""
    ray = need_ray()
    with pytest.MonkeyPatch.context() as mp:
        # a throwaway cluster on this machine: no token written to the home folder, no
        # usage report
        mp.setenv("RAY_AUTH_MODE", "disabled")
        mp.setenv("RAY_USAGE_STATS_ENABLED", "0")
        ctx = ray.init(
            num_cpus=WORKERS,
            include_dashboard=False,
            object_store_memory=OBJECT_STORE,
            _temp_dir=str(tmp_path_factory.mktemp("ray")),
            log_to_driver=False,
            configure_logging=False,
        )
        try:
            yield ctx.address_info["gcs_address"]
        finally:
            ray.shutdown()


def test_sweep_gives_the_same_files_on_ray(cli, ray_cluster: str, tmp_path: Path) -> None:
    study = write(tmp_path / "s.toml", STUDY)
    here, there = tmp_path / "here", tmp_path / "there"
    r = cli("sweep", str(study), "--no-simulate", "--jobs", "1", "--out", str(here))
    assert r.code == 0, r.err
    r = cli("sweep", str(study), "--no-simulate", "--backend", "ray", "--out", str(there))
    assert r.code == 0, r.err
    assert f"{N_STUDY} requests ({N_STUDY} designed now" in r.out
    assert outputs(here) == outputs(there)
    stored = {p.name: p.read_bytes() for p in (here / "requests").iterdir()}
    assert stored == {p.name: p.read_bytes() for p in (there / "requests").iterdir()}
    assert len(stored) == N_STUDY


def test_a_simulated_sweep_gives_the_same_files_on_ray(
    cli, ray_cluster: str, tmp_path: Path
) -> None:
    study = write(tmp_path / "s.toml", '[[request]]\nabilities = ["driving"]\n')
    here, there = tmp_path / "here", tmp_path / "there"
    assert cli("sweep", str(study), "--jobs", "1", "--out", str(here)).code == 0
    r = cli("sweep", str(study), "--backend", "ray", "--out", str(there), "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["simulated"] is True
    assert b"driving" in (there / "results.csv").read_bytes()
    assert outputs(here) == outputs(there)


def test_ctrl_c_cancels_the_ray_tasks_and_keeps_what_is_stored(
    cli, ray_cluster: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import ray

    study = write(tmp_path / "s.toml", STUDY)
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert cli("sweep", str(study), "--no-simulate", "--jobs", "1", "--out", str(whole)).code == 0
    real_store, real_cancel = synth.commands.sweep._store, ray.cancel
    stored, cancelled = [], []

    def store(*args) -> None:
        if len(stored) == 2:
            raise KeyboardInterrupt  # Ctrl-C as the third result comes in
        stored.append(1)
        real_store(*args)

    def cancel(ref, **kw) -> None:
        cancelled.append(kw)
        real_cancel(ref, **kw)

    monkeypatch.setattr(synth.commands.sweep, "_store", store)
    monkeypatch.setattr(ray, "cancel", cancel)
    r = cli("sweep", str(study), "--no-simulate", "--backend", "ray", "--out", str(cut))
    assert r.code == 130 and f"2 of {N_STUDY} requests stored" in r.err
    assert cancelled and all(kw == {"force": True} for kw in cancelled)
    assert len(list((cut / "requests").glob("*.json"))) == 2
    assert not (cut / "results.csv").exists()
    monkeypatch.undo()
    r = cli("sweep", str(study), "--no-simulate", "--backend", "ray", "--out", str(cut), "--json")
    assert r.code == 0, r.err
    assert (json.loads(r.out)["computed"], json.loads(r.out)["reused"]) == (N_STUDY - 2, 2)
    assert outputs(cut) == outputs(whole)


def test_enumerate_prints_the_same_lines_on_ray(cli, ray_cluster: str) -> None:
    argv = ("enumerate", "driving", "--assignments", "2")
    here = cli(*argv)
    there = cli(*argv, "--backend", "ray")
    assert here.code == there.code == 0, there.err
    assert here.out == there.out and "2 candidate(s)" in here.out


def test_enumerate_json_on_ray_from_another_process_by_address(cli, ray_cluster: str) -> None:
    """As on a cluster of many machines: a separate driver joins the cluster by its
    address; the JSON lines are those of the local run, in the same order."""
    argv = ["enumerate", "driving", "--assignments", "1", "--json"]
    here = cli(*argv)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    there = subprocess.run(
        [
            sys.executable,
            "-m",
            "synth.commands.cli",
            *argv,
            "--backend",
            "ray",
            "--address",
            ray_cluster,
        ],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
        timeout=300,
    )
    assert there.returncode == here.code, there.stderr
    assert there.stdout == here.out
    lines = [json.loads(x) for x in here.out.splitlines()]
    assert [x["type"] for x in lines] == ["candidate", "candidate", "summary"]
    assert all(x["assignments"]["count"] >= 1 for x in lines[:2])
