"""A study's size is bounded before it is expanded, and the same request in other units
is the same request (issue 23, item 8)."""

from __future__ import annotations

from pathlib import Path

import pytest

from adron.errors import InputError
from synth.commands.sweep import MAX_STUDY_REQUESTS, load_study, validate


def values(n: int, unit: str = "cm") -> str:
    return "[" + ", ".join(f'"{i + 1}{unit}"' for i in range(n)) + "]"


def study(tmp_path: Path, *tables: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text("\n".join(tables), encoding="utf-8")
    return path


def table(params: str, abilities: str = '["rolling"]', extra: str = "") -> str:
    return f"[[request]]\nabilities = {abilities}\n{extra}params = {{ {params} }}\n"


def test_a_study_of_10_to_the_12_requests_is_refused_before_it_is_expanded(
    cli, tmp_path: Path
) -> None:
    # 12 lists of 10 values: a file of about 1 KB
    params = ", ".join(f"p{i} = {values(10)}" for i in range(12))
    path = study(tmp_path, table(params))
    assert path.stat().st_size < 2000
    r = cli("sweep", str(path), "--no-simulate")
    assert r.code == 2, r.err
    assert "expands to 1,000,000,000,000 requests" in r.err
    assert f"{MAX_STUDY_REQUESTS:,} a study may have" in r.err
    assert str(path) in r.err and "request[0]" in r.err and "Traceback" not in r.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_a_size_past_any_integer_text_is_written_as_a_power_of_ten(tmp_path: Path) -> None:
    # 1000 lists of 2 values: 2^1000 requests (302 digits; Python refuses to print ints
    # past 4300 digits, so the count is never made into text)
    params = ", ".join(f'p{i} = ["1cm", "2cm"]' for i in range(1000))
    path = study(tmp_path, table(params))
    with pytest.raises(InputError, match=r"expands to about 10\^301 requests"):
        load_study(path)
    params = ", ".join(f'p{i} = ["1cm", "2cm"]' for i in range(20000))
    path = study(tmp_path, table(params))
    with pytest.raises(InputError, match=r"expands to about 10\^6020 requests"):
        load_study(path)


def test_the_limit_counts_every_table_and_is_inclusive(tmp_path: Path) -> None:
    # at the limit: read (expanded, not designed)
    half = MAX_STUDY_REQUESTS // 2
    a = table(f"x = {values(half // 10)}, y = {values(10)}")
    path = study(tmp_path, a, a)
    _, reqs = load_study(path)
    assert len(reqs) == MAX_STUDY_REQUESTS
    # one more request, in a third table of none of lists: refused, naming the total
    path = study(tmp_path, a, a, "[[request]]\nabilities = ['driving']\n")
    with pytest.raises(InputError) as e:
        load_study(path)
    assert f"expands to {MAX_STUDY_REQUESTS + 1:,} requests" in str(e.value)
    assert f"request[0]: params x {half // 10} x y 10 = {half:,}" in str(e.value)


@pytest.fixture(scope="module")
def opts() -> dict:
    return {"suite": "s.toml", "ontology": [], "rules": [], "catalog": None, "allow_scripts": False}


def requests_of(tmp_path: Path, *tables: str) -> list[dict]:
    return load_study(study(tmp_path, *tables))[1]


SAME = {
    "grams and kilograms in one list": [table('payload = ["1kg", "1000g"]')],
    "two tables, other units": [
        table('payload = ["0.5kg", "1kg"]'),
        table('payload = ["100g", "500g"]'),
    ],
    # 35 cm is 0.35000000000000003 m, 0.35 m is 0.35 m: the same value to 12 digits
    "centimetres and metres, floats differing in the last bit": [
        table('deflection = "3.5mm", speed = "35cm/s"', '["driving"]'),
        table('deflection = "0.35cm", speed = "0.35m/s"', '["driving"]'),
    ],
    "an answer written y and yes": [
        table('payload = "1kg"', '["walking"]', 'answers = { grasping = "y" }\n'),
        table('payload = "1kg"', '["walking"]', 'answers = { grasping = "yes" }\n'),
    ],
}


@pytest.mark.parametrize("case", sorted(SAME))
def test_the_same_request_in_other_units_is_refused(tmp_path: Path, opts, case: str) -> None:
    reqs = requests_of(tmp_path, *SAME[case])
    with pytest.raises(InputError, match="the same request as"):
        validate(opts, reqs)


DIFFERENT = {
    "a gram apart": [table('payload = ["1kg", "1001g"]')],
    "other abilities": [table('payload = "1kg"'), table('payload = "1kg"', '["driving"]')],
    "another answer": [
        table('payload = "1kg"', '["walking"]', 'answers = { grasping = "no" }\n'),
        table('payload = "1kg"', '["walking"]', 'answers = { grasping = "yes" }\n'),
    ],
    "a parameter given and left to its default": [table('payload = "1kg"'), table("")],
}


@pytest.mark.parametrize("case", sorted(DIFFERENT))
def test_different_requests_pass(tmp_path: Path, opts, case: str) -> None:
    validate(opts, requests_of(tmp_path, *DIFFERENT[case]))


def test_the_message_names_both_requests_and_their_values(cli, tmp_path: Path) -> None:
    path = study(tmp_path, table('payload = ["0.5kg", "1kg"]'), table('payload = "1000g"'))
    r = cli("sweep", str(path), "--no-simulate")
    assert r.code == 2, r.err
    assert f"{path}: request[1] (rolling): the same request as {path}: request[0]" in r.err
    assert '{"payload": "1000g"} and {"payload": "1kg"}, the same in SI units' in r.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
