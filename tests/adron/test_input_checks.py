"""The input checks of issue 11, each with a case built to fail it: parameter ranges, KIF
nesting and control characters, subclass cycles, catalog text and magnitudes, rule-file
characters, simulate options, and the CLI's one-line messages."""

from __future__ import annotations

import io
import re
from importlib.resources import files

import pytest

from adron.errors import InfeasibleError, InputError, KifSyntaxError, OntologyError


def _catalog_text() -> str:
    return (files("adron") / "catalog.toml").read_text(encoding="utf-8")


# ---- parameter ranges ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["payload", "reach", "speed", "obstacle_height", "load_area",
                                  "height", "deflection", "slope"])  # fmt: skip
def test_each_parameter_range_accepts_its_bounds_and_refuses_beyond(name) -> None:
    from synth.params import BY_NAME, parse_structural

    spec = BY_NAME[name]
    low, high = spec.range
    assert parse_structural({name: high})[name] > 0
    parse_structural({name: low})
    number, unit = high.split(" ", 1)
    with pytest.raises(
        InputError, match=rf"--param {name}=.*outside {re.escape(f'{low} to {high}')}"
    ):
        parse_structural({name: f"{float(number) * 1.01:g} {unit}"})
    number, unit = low.split(" ", 1)
    beyond = f"{float(number) * 0.99:g} {unit}" if float(number) > 0 else f"-1 {unit}"
    with pytest.raises(InputError, match=f"--param {name}"):
        parse_structural({name: beyond})


@pytest.mark.parametrize(
    "value", ["payload=1e308kg", "reach=1e-300m", "load_area=1e-9cm2", "height=1mm"]
)
def test_absurd_requests_are_refused_before_any_work(value) -> None:
    from synth.commands.cli import main

    err = io.StringIO()
    code = main(["design", "walking", "--param", value, "--no-input"], io.StringIO(), err)
    assert code == 2 and "range where designs make sense" in err.getvalue()
    assert err.getvalue().count("\n") == 1


def test_a_humanoid_below_its_gait_maps_is_refused_not_clamped() -> None:
    from adron.catalog import load_catalog
    from synth.sizing.families import Humanoid

    catalog = load_catalog()
    with pytest.raises(InfeasibleError, match="smallest height that works"):
        Humanoid().size("HumanoidRobot", {"height": 0.05, "payload": 0.0}, catalog)
    Humanoid().size("HumanoidRobot", {"height": 0.4, "payload": 0.0}, catalog)


# ---- KIF -------------------------------------------------------------------------------------


def test_kif_nesting_is_bounded_where_translated() -> None:
    from adron.kif import MAX_DEPTH, parse

    ok = "(a " * (MAX_DEPTH - 1) + "(b)" + ")" * (MAX_DEPTH - 1)
    parse(ok, "f.kif", MAX_DEPTH)
    deep = "(a " * MAX_DEPTH + "(b)" + ")" * MAX_DEPTH
    with pytest.raises(KifSyntaxError, match="nest more than") as e:
        parse(deep, "f.kif", MAX_DEPTH)
    assert (e.value.line, e.value.col) == (1, 3 * MAX_DEPTH + 1)
    parse("(a " * 5000 + ")" * 5000, "f.kif")  # the reader alone needs no bound


def test_the_translator_takes_the_deepest_forms_the_reader_passes() -> None:
    from adron.kif import MAX_DEPTH, parse
    from adron.translate import translate

    n = MAX_DEPTH - 3
    text = "\n".join(
        [
            "(=> (instance ?X Robot) " + "(and (p ?X) " * n + "(q ?X)" + ")" * n + ")",
            "(=> " + "(and " * n + "(instance ?X Robot)" + ")" * n + " (q ?X))",
            "(p " * (MAX_DEPTH - 1) + "a" + ")" * (MAX_DEPTH - 1),
        ]
    )
    assert translate(parse(text, "deep.kif", MAX_DEPTH)).forms == 3


def test_kif_control_characters_are_refused_and_a_bom_ignored() -> None:
    from adron.kif import parse

    with pytest.raises(KifSyntaxError, match="U\\+0000") as e:
        parse("(subclass A Robot)\n(subclass B\x00 Robot)\n", "f.kif")
    assert (e.value.line, e.value.col) == (2, 12)
    assert len(parse("\ufeff(subclass A Robot)\t\r\n", "f.kif")) == 1


def test_a_subclass_cycle_names_the_fact_that_closes_it(tmp_path) -> None:
    from adron.kb import load

    mine = tmp_path / "mine.kif"
    mine.write_text("(subclass MyRobot Robot)\n(subclass Robot HexapodRobot)\n", encoding="utf-8")
    with pytest.raises(OntologyError, match=rf"{mine}:2:1: .*cycle.*Robot < HexapodRobot"):
        load([mine])
    mine.write_text("(subclass MyRobot Robot)\n", encoding="utf-8")
    load([mine])


def test_a_long_subclass_chain_is_no_cycle() -> None:
    from adron.kb import check_taxonomy
    from adron.kif import parse
    from adron.translate import translate

    n = 20_000
    text = "".join(f"(subclass C{i} C{i + 1})\n" for i in range(n))
    check_taxonomy(translate(parse(text, "chain.kif")))
    with pytest.raises(OntologyError, match=f"chain.kif:{n + 1}:1"):
        check_taxonomy(translate(parse(text + f"(subclass C{n} C0)\n", "chain.kif")))


# ---- catalogs --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('model = "SG90"', 'model = "SG\\n90"', "control character U\\+000A"),
        ('model = "SG90"', 'model = "SG\\u000090"', "control character U\\+0000"),
        ('mass = "34 g"', 'mass = "1e300 kg"', "above 50 kg"),
        ('mass = "34 g"', 'mass = "51 kg"', "above 50 kg"),
    ],
)
def test_catalog_text_and_magnitudes_are_bounded(old, new, message) -> None:
    from adron.catalog import parse_catalog

    text = _catalog_text()
    assert old in text
    with pytest.raises(InputError, match=message) as e:
        parse_catalog(text.replace(old, new, 1), "c.toml")
    assert "\n" not in str(e.value)


def test_catalog_cost_is_bounded_and_a_bom_ignored(tmp_path) -> None:
    from adron.catalog import load_catalog

    text = _catalog_text()
    path = tmp_path / "c.toml"
    path.write_text("\ufeff" + text, encoding="utf-8")
    assert load_catalog(path).actuators
    path.write_text(re.sub(r"cost = [0-9.]+", "cost = 1e9", text, count=1), encoding="utf-8")
    with pytest.raises(
        InputError, match=r"\.cost = 1000000000\.0: out of range: .* at most 100000"
    ):
        load_catalog(path)


# ---- rule files ------------------------------------------------------------------------------


def test_rule_files_refuse_what_clingo_cannot_lex() -> None:
    from synth.reasoning.solver import check_lexable

    check_lexable("r.lp", 'p("é ☃"). % é\n%* é *% q.\n')
    for text, col in (("p :- é.\n", 6), ("\ufeffp.\n", 1), ("p(\x01).\n", 3)):
        with pytest.raises(InputError, match=f"r.lp:1:{col}: character U\\+"):
            check_lexable("r.lp", text)


# ---- command line ----------------------------------------------------------------------------


def run(*argv: str) -> tuple[int, str]:
    from synth.commands.cli import main

    err = io.StringIO()
    return main(list(argv), io.StringIO(), err), err.getvalue()


@pytest.mark.parametrize("seconds", ["0.05", "nan", "inf", "1e9"])
def test_simulate_checks_seconds_before_the_bundle(seconds, tmp_path) -> None:
    code, err = run("simulate", str(tmp_path / "none"), "--behavior", "x", "--seconds", seconds)
    assert code == 2 and "--seconds" in err and "design.json" not in err


def test_behaviour_parameters_refuse_nan() -> None:
    from gaits.base import Parameter

    p = Parameter("v", "float", 0.1, "speed", "m/s", low=-1.0, high=1.0)
    assert p.check("0.5") == 0.5
    with pytest.raises(ValueError, match="expected a number"):
        p.check("nan")


def test_empty_out_nul_arguments_and_answers_with_equals() -> None:
    from synth.reasoning.conceptual import parse_answer

    code, err = run("design", "walking", "--out", "", "--no-input")
    assert code == 2 and "--out ''" in err
    code, err = run("ontology", "check", "a\x00b.kif")
    assert code == 2 and "NUL" in err and err.count("\n") == 1
    assert parse_answer("odd=name=yes") == ("odd=name", True)


def test_messages_are_one_line_and_bounded() -> None:
    from synth.commands.cli import MAX_MESSAGE, _one_line

    assert _one_line("a\n  b\n\nc") == "a | b | c"
    long = _one_line("x" * 10 * MAX_MESSAGE)
    assert len(long) < MAX_MESSAGE + 100 and "characters ..." in long
