"""Malformed KIF never ends in a traceback (issue 23, item 6): a fact parmor reads by
position with another number of arguments (``(subclass Foo)``: an IndexError in
check_taxonomy; ``(liftedModuleShare G 1)``: a ValueError when sizing) is an error naming
its file:line:col, and a seeded fuzz of the shipped ontology (tokens truncated, duplicated,
dropped, replaced, swapped) through ``parmor ontology check`` only exits 0 or 2."""

from __future__ import annotations

import random
import re
from importlib.resources import files
from pathlib import Path

import pytest

from adron.kb import SHAPES

TOKEN = re.compile(r'\(|\)|"(?:[^"\\]|\\.)*"|[^\s()"]+')


@pytest.fixture(autouse=True)
def no_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each mutated ontology would be a new cache entry: the cache is off here."""
    monkeypatch.setenv("PARMOR_CACHE", "")


@pytest.mark.parametrize(
    ("text", "where", "shape"),
    [
        ("(subclass Foo)\n", "1:1", "(subclass CLASS PARENT), 2 arguments, not 1"),
        ("; mine\n  (subclass Foo Bar Baz)\n", "2:3", "(subclass CLASS PARENT), 2 arguments"),
        ("(subrelation myPart)\n", "1:1", "(subrelation RELATION PARENT), 2 arguments"),
        ("(extensiblePart SnakeRobot)\n", "1:1", "(extensiblePart ROBOT PART)"),
        ('(defaultLength HexapodRobot "12 cm")\n', "1:1", "(defaultLength CLASS NAME LENGTH)"),
        ("(liftedModuleShare RobotRotating 1)\n", "1:1", "(liftedModuleShare GAIT N D)"),
    ],
)
def test_a_fact_of_another_arity_is_located(
    cli, tmp_path: Path, text: str, where: str, shape: str
) -> None:
    path = tmp_path / "m.kif"
    path.write_text(text, encoding="utf-8")
    r = cli("ontology", "check", str(path))
    assert r.code == 2, (r.out, r.err)
    assert f"{path}:{where}: (" in r.err and f"expected {shape}" in r.err
    assert "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1


def test_sizing_is_not_reached_with_a_malformed_share(cli, tmp_path: Path) -> None:
    """Before the check, this design sized the snake and failed unpacking the share."""
    path = tmp_path / "m.kif"
    path.write_text("(liftedModuleShare RobotLateralRolling 1)\n", encoding="utf-8")
    r = cli("design", "rolling", "--ontology", str(path), "--no-input", "--no-verify")
    assert r.code == 2 and f"{path}:1:1: (liftedModuleShare" in r.err, r.err


def test_the_shipped_ontology_fits_the_shapes(kb) -> None:
    for relation, shape in SHAPES.items():
        assert all(len(a) == len(shape) for a in kb.translation.relation(relation)), relation


def _shipped() -> dict[str, str]:
    root = files("adron.ontology")
    return {
        p.name: p.read_text(encoding="utf-8")
        for p in sorted(root.iterdir(), key=lambda p: p.name)
        if p.name.endswith(".kif")
    }


def _mutate(rng: random.Random, text: str) -> str:
    spans = [m.span() for m in TOKEN.finditer(text)]
    i = rng.randrange(len(spans))
    a, b = spans[i]
    op = rng.choice(["truncate", "duplicate", "drop", "replace", "swap"])
    if op == "truncate":
        return text[:a]
    if op == "duplicate":
        return text[:b] + " " + text[a:b] + text[b:]
    if op == "replace":
        c, d = spans[rng.randrange(len(spans))]
        return text[:a] + text[c:d] + text[b:]
    if op == "swap" and i + 1 < len(spans):
        c, d = spans[i + 1]
        return text[:a] + text[c:d] + text[b:c] + text[a:b] + text[d:]
    return text[:a] + text[b:]


def _cases(n: int, seed: int) -> list[tuple[str, str]]:
    """(name, text): each shipped file with its first subclass fact cut to one argument
    (the IndexError of issue 23), then ``n`` seeded mutations of 1-3 tokens each."""
    shipped = _shipped()
    out = []
    for name, text in shipped.items():
        m = re.search(r"\(subclass (\S+) [^\s()]+\)", text)
        if m:
            out.append((f"{name}: cut", text[: m.start()] + f"(subclass {m[1]})" + text[m.end() :]))
    rng = random.Random(seed)
    names = sorted(shipped)
    for k in range(n):
        name = rng.choice(names)
        text = shipped[name]
        for _ in range(rng.choice([1, 1, 2, 3])):
            text = _mutate(rng, text)
        out.append((f"{name}: mutation {k}", text))
    return out


def test_a_seeded_fuzz_of_the_shipped_ontology(cli, tmp_path: Path) -> None:
    """~2 s; a larger run (5,000 cases, seeds 2 and 3) found only the arity errors."""
    codes: dict[int, int] = {}
    for name, text in _cases(80, seed=23):
        path = tmp_path / "m.kif"
        path.write_text(text, encoding="utf-8")
        r = cli("ontology", "check", str(path))
        assert r.code in (0, 2) and "Traceback" not in r.err, (name, r.err)
        if r.code:
            said = r.err.strip().splitlines()
            assert len(said) == 1 and said[0].startswith("parmor: error: "), (name, r.err)
        codes[r.code] = codes.get(r.code, 0) + 1
    assert codes.get(2, 0) >= 5 and codes.get(0, 0) >= 5, codes  # both kinds are met
