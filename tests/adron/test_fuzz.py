"""Property-based fuzzing (hypothesis) of the input readers: the KIF reader with the
translator, the catalog loader, the rule-file loader (through clingo) and the parameter
parser. Each may only succeed or raise a ParmorError; never anything else."""

from __future__ import annotations

import contextlib
from importlib.resources import files
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adron.errors import ParmorError


def cases(n: int) -> settings:
    """``n`` examples, no deadline (the machine is shared)."""
    return settings(
        max_examples=n, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
    )


KIF_ALPHABET = list('()?@";\n -.0123456789abcXYZ=>\t\x00\ufeffÖ') + ["(=> ", "(and ", "(exists "]
KIFISH = st.lists(st.sampled_from(KIF_ALPHABET), max_size=120).map("".join)
DEEP = st.tuples(st.integers(1, 600), st.sampled_from(["(p ", "(and ", "(=> (a ?X) "])).map(
    lambda t: t[1] * t[0] + "x" + ")" * t[0]
)


@cases(2000)
@given(st.one_of(KIFISH, DEEP, st.text(max_size=80)))
def test_kif_reader_and_translator(text: str) -> None:
    from adron.kif import MAX_DEPTH, parse
    from adron.translate import translate

    with contextlib.suppress(ParmorError):
        translate(parse(text, "f.kif", MAX_DEPTH))


def _catalog_lines() -> list[str]:
    return (files("adron") / "catalog.toml").read_text(encoding="utf-8").split("\n")


@cases(1000)
@given(
    st.integers(0, 400),
    st.one_of(
        st.text(max_size=30),
        st.sampled_from(['"1e308 kg"', '"nan"', "-1", '"\\u0000"', "[", '""', "1e400"]),
    ),
)
def test_catalog_loader(line: int, value: str) -> None:
    from adron.catalog import parse_catalog

    lines = _catalog_lines()
    k = line % len(lines)
    key, sep, _ = lines[k].partition("=")
    lines[k] = f"{key}= {value}" if sep else value + lines[k]
    try:
        parse_catalog("\n".join(lines), "c.toml")
    except ParmorError as e:
        assert "\n" not in str(e)


RULE_ALPHABET = list('pq(),.:-X_"%*\n 01é\ufeff\x01#') + ["not ", ":- ", "#const ", "{", "}"]


@pytest.fixture(scope="module")
def empty_kb():
    from adron.kb import load

    return load([], builtin=False)


@cases(250)  # each example grounds a Reasoner (~0.05 s): 600 took 26 s of the suite
@given(st.lists(st.sampled_from(RULE_ALPHABET), max_size=60).map("".join))
def test_rule_loader(empty_kb, tmp_path_factory, text: str) -> None:
    from synth.reasoning.solver import Reasoner

    path = Path(tmp_path_factory.mktemp("rules")) / "r.lp"
    path.write_text(text, encoding="utf-8")
    with contextlib.suppress(ParmorError):
        Reasoner(empty_kb, [path])


@cases(2000)
@given(
    st.sampled_from(
        [
            "payload",
            "reach",
            "speed",
            "obstacle_height",
            "load_area",
            "height",
            "deflection",
            "slope",
        ]
    ),  # fmt: skip
    st.one_of(
        st.text(max_size=20),
        st.tuples(
            st.floats(allow_nan=True, allow_infinity=True),
            st.sampled_from(["kg", "m", "cm", "m/s", "cm2", "deg", "mm", "", " g"]),
        ).map(lambda t: f"{t[0]}{t[1]}"),
    ),
)
def test_parameter_parser(name: str, value: str) -> None:
    from synth.params import BY_NAME, bounds, parse_structural

    try:
        got = parse_structural({name: value})[name]
    except ParmorError:
        return
    low, high = bounds(BY_NAME[name])
    assert low <= got <= high
