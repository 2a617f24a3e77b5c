"""Tests of the SUO-KIF reader (adron.kif)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adron.errors import InputError, KifSyntaxError
from adron.kif import Form, RowVar, String, Symbol, Var, parse, parse_file
from tests.conftest import require_dir, require_shared

SUMO_COUNTS = {"Merge.kif": 5504, "Mid-level-ontology.kif": 10046, "tinySUMO.kif": 347}


@pytest.fixture
def sumo_dir() -> Path:
    """The shared SUMO sample folder; skip without it, but fail under CI=true."""
    return require_shared("kif/sumo")


def shape(x: object) -> object:
    """Structure of a parsed item with atom types made explicit and locations dropped."""
    if isinstance(x, Form):
        return tuple(shape(i) for i in x.items)
    return (type(x).__name__, x)


def S(*names: str) -> tuple:
    """Shape of a list of symbols."""
    return tuple(("Symbol", n) for n in names)


def all_forms(forms: list[Form]) -> list[Form]:
    """Every form, nested ones included (iteratively)."""
    out, todo = [], list(forms)
    while todo:
        f = todo.pop()
        out.append(f)
        todo.extend(i for i in f.items if isinstance(i, Form))
    return out


def assert_locations_point_at_parens(text: str, forms: list[Form]) -> None:
    """Each form's (line, col) is the position of a '(' in the text."""
    lines = text.split("\n")
    for f in all_forms(forms):
        assert lines[f.line - 1][f.col - 1] == "(", (f.line, f.col)


# --- parsing -------------------------------------------------------------------------------

CASES = [
    ("empty", "", []),
    ("only comments", "; a comment (\n;; another )\n", []),
    ("empty list", "()", [()]),
    ("symbols", "(instance Foo Bar)", [S("instance", "Foo", "Bar")]),
    (
        "comments between and inside",
        "; header (\n(a b) ; trailing ) (\n(c ; inner (\n d)",
        [S("a", "b"), S("c", "d")],
    ),
    ("comment at end without newline", "(a) ; bye", [S("a")]),
    ("comment glued to symbol", "(a;b\nc)", [S("a", "c")]),
    (
        "multi-line string with ; ?X and unbalanced parens",
        '(documentation X EnglishLanguage "A ; not a comment\n?X (( ) and )) ;\n end.")',
        [
            S("documentation", "X", "EnglishLanguage")
            + (("String", "A ; not a comment\n?X (( ) and )) ;\n end."),)
        ],
    ),
    ("empty string", '(a "")', [S("a") + (("String", ""),)]),
    ("string glued to atoms", '(a"b"c)', [(("Symbol", "a"), ("String", "b"), ("Symbol", "c"))]),
    (
        "variables",
        "(=> (p ?X ?y-1) (q ?X))",
        [
            (
                ("Symbol", "=>"),
                (("Symbol", "p"), ("Var", "?X"), ("Var", "?y-1")),
                (("Symbol", "q"), ("Var", "?X")),
            )
        ],
    ),
    (
        "row variables",
        "(<=> (p @ROW) (ListFn @ROW ?X))",
        [
            (
                ("Symbol", "<=>"),
                (("Symbol", "p"), ("RowVar", "@ROW")),
                (("Symbol", "ListFn"), ("RowVar", "@ROW"), ("Var", "?X")),
            )
        ],
    ),
    (
        "numbers",
        "(n 42 -3 +7 0 0.5 -2.75 .5 -.5 3. 1e3 -2.5E-2)",
        [
            (("Symbol", "n"), ("int", 42), ("int", -3), ("int", 7), ("int", 0))
            + (("float", 0.5), ("float", -2.75), ("float", 0.5), ("float", -0.5))
            + (("float", 3.0), ("float", 1000.0), ("float", -0.025))
        ],
    ),
    (
        "number-like symbols",
        "(- -x 1-2 3a 1e . -. 1.2.3)",
        [S("-", "-x", "1-2", "3a", "1e", ".", "-.", "1.2.3")],
    ),
    (
        "symbols with - _ and others",
        "(part-of a_b => <=> ListFn Ö x.y ab'c #t Foo-Bar_9)",
        [S("part-of", "a_b", "=>", "<=>", "ListFn", "Ö", "x.y", "ab'c", "#t", "Foo-Bar_9")],
    ),
    (
        "nesting",
        "(a (b (c (d)) e) ((f)) g)",
        [
            (
                ("Symbol", "a"),
                (("Symbol", "b"), (("Symbol", "c"), (("Symbol", "d"),)), ("Symbol", "e")),
                ((("Symbol", "f"),),),
                ("Symbol", "g"),
            )
        ],
    ),
    ("whitespace kinds", "\t(a\r\n\tb\x0cc)\r\n( d )", [S("a", "b", "c"), S("d")]),
    ("several top-level forms", "(a)(b) (c)\n(d)", [S("a"), S("b"), S("c"), S("d")]),
]


@pytest.mark.parametrize(("text", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_parse_cases(text: str, expected: list) -> None:
    forms = parse(text)
    assert [shape(f) for f in forms] == expected
    assert_locations_point_at_parens(text, forms)


LOCATION_CASES = [
    # text, [(line, col) of every form in depth-first, left-to-right order]
    ("(a)", [(1, 1)]),
    ("  (a)", [(1, 3)]),
    ("(a\n  (b (c))\n (d))", [(1, 1), (2, 3), (2, 6), (3, 2)]),
    ("; c (\n\n\t(x)", [(3, 2)]),
    ('(a "x\n(y\n" (b))', [(1, 1), (3, 3)]),
    ("(Ö (ü (x)))", [(1, 1), (1, 4), (1, 7)]),
    ("(a)\n(b)\n\n(c (d))", [(1, 1), (2, 1), (4, 1), (4, 4)]),
]


def preorder(forms: list[Form]) -> list[tuple[int, int]]:
    """(line, col) of every form, depth first."""
    out: list[tuple[int, int]] = []
    todo = list(reversed(forms))
    while todo:
        f = todo.pop()
        out.append((f.line, f.col))
        todo.extend(reversed([i for i in f.items if isinstance(i, Form)]))
    return out


@pytest.mark.parametrize(("text", "expected"), LOCATION_CASES)
def test_locations(text: str, expected: list[tuple[int, int]]) -> None:
    forms = parse(text, "loc.kif")
    assert preorder(forms) == expected
    assert all(f.file == "loc.kif" for f in all_forms(forms))


def test_atom_types_and_form_api() -> None:
    (form,) = parse('(=> (p ?X @R "s" 1 2.5) q)', "api.kif")
    assert form.head == "=>" and type(form.head) is Symbol
    assert len(form) == 3 and form[2] == "q" and list(form) == list(form.items)
    inner = form[1]
    assert isinstance(inner, Form)
    assert [type(i) for i in inner] == [Symbol, Var, RowVar, String, int, float]
    assert inner.items[1:4] == ("?X", "@R", "s")
    assert (inner.file, inner.line, inner.col) == ("api.kif", 1, 5)
    assert form.to_text() == '(=> (p ?X @R "s" 1 2.5) q)'
    with pytest.raises(AttributeError):
        form.line = 3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("text", "head"), [("(a b)", "a"), ("((a) b)", None), ("(?X)", None), ("()", None)]
)
def test_head(text: str, head: str | None) -> None:
    assert parse(text)[0].head == head


def test_deep_nesting_needs_no_recursion() -> None:
    depth = 20_000
    text = "(" * depth + "x" + ")" * depth
    (form,) = parse(text)
    d, f = 1, form
    while f.items and isinstance(f.items[0], Form):
        f, d = f.items[0], d + 1
    assert d == depth and f.items == ("x",) and f.col == depth
    assert form.to_text() == text
    with pytest.raises(KifSyntaxError) as err:
        parse("(" * depth)
    assert (err.value.line, err.value.col) == (1, depth)


def test_to_text_requotes_and_round_trips() -> None:
    text = '(doc "a ; (b\n?X" (f -1 0.25 @R) ())'
    (form,) = parse(text)
    assert form.to_text() == text
    assert [shape(f) for f in parse(form.to_text())] == [shape(form)]


def test_parse_file(tmp_path: Path) -> None:
    path = tmp_path / "x.kif"
    path.write_bytes('\ufeff; bom\n(a \xd6 "caf\xe9")\n'.encode() + b"(b \xff)\n")
    forms = parse_file(path)
    assert [f.file for f in forms] == [str(path), str(path)]
    assert [(f.line, f.col) for f in forms] == [(2, 1), (3, 1)]
    assert forms[0].items == ("a", "Ö", "café") and forms[1].items == ("b", "\ufffd")


# --- errors --------------------------------------------------------------------------------

ERROR_CASES = [
    ("unclosed paren", "(a (b c)\n(d)", 1, 1, "unclosed"),
    ("innermost unclosed paren", "(a\n  (b", 2, 3, "unclosed"),
    ("unclosed after string", '(a "x)"', 1, 1, "unclosed"),
    ("stray close paren", "(a)\n  )", 2, 3, "unexpected ')'"),
    ("stray close paren first", ")", 1, 1, "unexpected ')'"),
    ("unterminated string", '(a "abc\n\ndef (x)', 1, 4, "unterminated string"),
    ("unterminated string at end", '(a)\n\t"', 2, 2, "unterminated string"),
    ("bare atom at top level", "(a)\n  foo (b)", 2, 3, "expected '(' at top level"),
    ("number at top level", "(a) ; c\n 42", 2, 2, "expected '(' at top level"),
    ("string at top level", '"s" (a)', 1, 1, "expected '(' at top level"),
    ("variable at top level", "?X", 1, 1, "expected '(' at top level"),
    ("unicode columns count characters", "(ÖÖ)\n(ÖÖ))", 2, 5, "unexpected ')'"),
]


@pytest.mark.parametrize(
    ("text", "line", "col", "reason"), [c[1:] for c in ERROR_CASES], ids=[c[0] for c in ERROR_CASES]
)
def test_errors(text: str, line: int, col: int, reason: str) -> None:
    with pytest.raises(KifSyntaxError) as err:
        parse(text, "bad.kif")
    e = err.value
    assert (e.file, e.line, e.col) == ("bad.kif", line, col)
    assert reason in e.reason
    assert str(e).startswith(f"bad.kif:{line}:{col}: ")
    assert isinstance(e, InputError)


def test_integer_beyond_digit_limit_is_a_syntax_error() -> None:
    big = "9" * 5000
    with pytest.raises(KifSyntaxError) as err:
        parse(f'; {big}\n(a "{big}"\n  b {big})')
    assert (err.value.line, err.value.col) == (3, 5)


# --- property test -------------------------------------------------------------------------

KIFISH = st.text(alphabet=st.sampled_from(list('()?@";\n -.0123456789abcXYZ\tÖ')), max_size=200)


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.text(), KIFISH))
def test_any_text_parses_or_raises_located_error(text: str) -> None:
    try:
        forms = parse(text)
    except KifSyntaxError as e:
        lines = text.split("\n")
        assert 1 <= e.line <= len(lines)
        assert 1 <= e.col <= len(lines[e.line - 1]) + 1
        return
    assert_locations_point_at_parens(text, forms)
    again = parse("\n".join(f.to_text() for f in forms))
    assert [shape(f) for f in again] == [shape(f) for f in forms]


# --- SUMO files ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("ci", "outcome"), [("true", pytest.fail.Exception), ("", pytest.skip.Exception)]
)
def test_missing_sumo_dir_skips_or_fails_under_ci(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ci: str, outcome: type
) -> None:
    monkeypatch.setenv("CI", ci)
    with pytest.raises(outcome):
        require_dir(tmp_path / "absent")
    assert require_dir(tmp_path) == tmp_path


def test_sumo_checksums(sumo_dir: Path) -> None:
    lines = (sumo_dir / "SHA256SUMS").read_text().split("\n")
    sums = dict(reversed(line.split(None, 1)) for line in lines if line.strip())
    assert set(SUMO_COUNTS) <= set(sums)
    for name, digest in sums.items():
        name = name.lstrip("*")
        assert hashlib.sha256((sumo_dir / name).read_bytes()).hexdigest() == digest, name


def test_every_sumo_file_parses(sumo_dir: Path) -> None:
    files = sorted(sumo_dir.glob("*.kif"))
    assert {p.name for p in files} >= set(SUMO_COUNTS)
    for path in files:
        forms = parse_file(path)
        assert forms, path
        assert_locations_point_at_parens(path.read_text(encoding="utf-8"), forms)


@pytest.mark.parametrize(("name", "count"), sorted(SUMO_COUNTS.items()))
def test_sumo_form_counts(sumo_dir: Path, name: str, count: int) -> None:
    assert len(parse_file(sumo_dir / name)) == count


def strings_of(forms: list[Form]) -> list[String]:
    """Every string literal in the forms."""
    return [i for f in all_forms(forms) for i in f.items if type(i) is String]


def test_sumo_structure(sumo_dir: Path) -> None:
    forms = parse_file(sumo_dir / "Merge.kif")
    assert [f.head for f in forms].count("=>") == 989
    assert any(type(i) is RowVar for f in all_forms(forms) for i in f.items)
    assert any(";" in s and "\n" in s for s in strings_of(forms))
    mid = strings_of(parse_file(sumo_dir / "Mid-level-ontology.kif"))
    assert sum(s.count("(") != s.count(")") for s in mid) == 6


def test_sumo_round_trip(sumo_dir: Path) -> None:
    forms = parse_file(sumo_dir / "tinySUMO.kif")
    for form in forms:
        (again,) = parse(form.to_text())
        assert shape(again) == shape(form), form.location
