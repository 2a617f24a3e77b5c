"""Issue 34: a seeded fuzzing of every user file format (bench/fuzz_formats.py, which
runs 2,400 cases) in a few hundred cases: no traceback, no hang, every refusal names the
file and a key, nothing written by a refused run (an ``--out`` folder, a bundle whose
``.parmor`` was refused)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path


def _bench():
    path = Path(__file__).resolve().parents[2] / "bench" / "fuzz_formats.py"
    spec = importlib.util.spec_from_file_location("fuzz_formats", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["fuzz_formats"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_every_format_fuzzed(monkeypatch) -> None:
    monkeypatch.setenv("PARMOR_ROBUSTNESS", "0")
    outcome = _bench().run(300, seed=3400, cli_share=0.03, record_share=0.08)
    figures = outcome.figures()
    assert figures["cases"] == 300
    assert not outcome.tracebacks, outcome.tracebacks[:3]
    assert not outcome.hangs, outcome.hangs[:3]
    assert not outcome.unnamed, outcome.unnamed[:3]
    assert not outcome.written, outcome.written[:3]
    assert figures["refused (exit 2)"] > 50  # the mutations do reach the checks
    every = {"partkinds", "catalog", "perturbation", "study", "suite", "design record"}
    every |= {"program", ".parmor", "kif facts"}
    assert every <= set(figures["by format (cases, refused)"]), figures
