"""SUO-KIF reader: text -> located, immutable forms.

One compiled regular expression tokenises the whole text; an explicit stack builds the
nested lists, so nesting depth is not limited by Python's recursion limit. Line and column
(1-based, counted in characters) are computed only for opening parentheses and errors.
"""

from __future__ import annotations

import math
import re
from bisect import bisect_right
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from adron.errors import KifSyntaxError

__all__ = [
    "MAX_DEPTH",
    "Atom",
    "Form",
    "RowVar",
    "String",
    "Symbol",
    "Var",
    "parse",
    "parse_file",
]


class Symbol(str):
    """A constant, function or relation name: ``part``, ``=>``, ``ListFn``."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"Symbol({str.__repr__(self)})"


class Var(str):
    """A variable; the text includes the leading ``?``."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"Var({str.__repr__(self)})"


class RowVar(str):
    """A row variable; the text includes the leading ``@``."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"RowVar({str.__repr__(self)})"


class String(str):
    """A string literal's contents, quotes removed, text kept as is."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"String({str.__repr__(self)})"


Atom = Symbol | Var | RowVar | String | int | float


@dataclass(frozen=True, slots=True)
class Form:
    """A parenthesised list with the location of its opening ``(``."""

    items: tuple
    file: str
    line: int
    col: int

    @property
    def head(self) -> Symbol | None:
        """The first item if it is a :class:`Symbol`, else ``None``."""
        if self.items:
            first = self.items[0]
            if type(first) is Symbol:
                return first
        return None

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, index: int | slice) -> Any:
        return self.items[index]

    def __iter__(self) -> Iterator[Atom | Form]:
        return iter(self.items)

    @property
    def location(self) -> str:
        """``file:line:col`` of the opening parenthesis."""
        return f"{self.file}:{self.line}:{self.col}"

    def to_text(self) -> str:
        """Compact KIF text of this form (strings re-quoted); parses back to the same items."""
        out: list[str] = []
        # Iterative walk: (items, next index) frames, so deep nesting is safe.
        stack: list[tuple[tuple, int]] = [(self.items, 0)]
        out.append("(")
        while stack:
            items, i = stack.pop()
            if i == len(items):
                out.append(")")
                continue
            if i:
                out.append(" ")
            stack.append((items, i + 1))
            item = items[i]
            if isinstance(item, Form):
                out.append("(")
                stack.append((item.items, 0))
            else:
                out.append(_atom_text(item))
        return "".join(out)

    def __str__(self) -> str:
        return self.to_text()


_FORM_SETTERS = tuple(Form.__dict__[name].__set__ for name in ("items", "file", "line", "col"))


def _atom_text(atom: object) -> str:
    """KIF text of one atom."""
    if type(atom) is String:
        return f'"{atom}"'
    if isinstance(atom, str):
        return str.__str__(atom)
    if isinstance(atom, float) and not math.isfinite(atom):
        return "1e999" if atom > 0 else "-1e999"  # NaN cannot come from parsing
    return repr(atom)


# Every non-whitespace character starts exactly one alternative, so finditer never skips
# anything but whitespace. To keep the Python loop short, bare atoms travel in runs:
#   "(" plus the atoms that follow it, with the ")" too when the list holds only atoms;
#   ")" alone; a run of atoms (and the whitespace between them) up to the next special char;
#   a string up to the next '"' (SUO-KIF has no escapes; an unterminated one runs to the end
#   of the text and is recognised by its missing closing quote); a comment to end of line.
_TOKEN = re.compile(r'\([^()";]*\)?|\)|[^\s()";][^()";]*|"[^"]*"?|;[^\n]*')
_NEWLINE = re.compile("\n")
_INT = re.compile(r"[-+]?[0-9]+")
_FLOAT = re.compile(r"[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+|[0-9]+(?=[eE]))(?:[eE][-+]?[0-9]+)?")
_ATOM_AT = r'(?<![^\s()";]){}(?![^\s()";])'
# Control characters other than whitespace (tab, newlines, vertical tab, form feed): a NUL
# or an escape in a name would reach clingo and fail there, far from the user's file.
_CONTROL = re.compile(r"[\x00-\x08\x0e-\x1f\x7f]")
_BOM = "\ufeff"

#: Deepest nesting of lists that parmor translates (the translator walks forms recursively,
#: and Python's stack ends near 500 levels); SUMO's deepest axioms nest about 15 levels.
MAX_DEPTH = 100


class _BadNumber(Exception):
    """An integer literal Python refuses to convert (beyond its digit limit)."""


def _atom(tok: str) -> Atom:
    """Classify one bare token (not a string, not a parenthesis)."""
    c = tok[0]
    if c == "?":
        return Var(tok)
    if c == "@":
        return RowVar(tok)
    if c in "0123456789-+.":
        if _INT.fullmatch(tok):
            try:
                return int(tok)
            except ValueError:  # more digits than sys.get_int_max_str_digits()
                raise _BadNumber(tok) from None
        if _FLOAT.fullmatch(tok):
            return float(tok)
    return Symbol(tok)


class _Locator:
    """Maps character offsets to 1-based (line, col) via a table of newline offsets."""

    __slots__ = ("newlines",)

    def __init__(self, text: str) -> None:
        self.newlines = [m.start() for m in _NEWLINE.finditer(text)]

    def __call__(self, offset: int) -> tuple[int, int]:
        n = bisect_right(self.newlines, offset - 1)  # newlines strictly before offset
        start = self.newlines[n - 1] + 1 if n else 0
        return n + 1, offset - start + 1


def _short(tok: str) -> str:
    """A token shortened for an error message."""
    tok = tok.split("\n", 1)[0]
    return tok if len(tok) <= 30 else tok[:27] + "..."


class _AtomCache(dict):
    """Token text -> atom; converts (and interns) each distinct token once."""

    def __missing__(self, tok: str) -> Atom:
        atom = self[tok] = _atom(tok)
        return atom


def parse(text: str, file: str = "<string>", max_depth: int | None = None) -> list[Form]:
    """Parse SUO-KIF text into its top-level forms, in order.

    A leading UTF-8 byte order mark is ignored. Raises :class:`KifSyntaxError` (with file,
    1-based line and column) for an unclosed ``(`` (located where it opened), an unexpected
    ``)``, an unterminated string (located where it started), anything other than a list at
    top level, a control character (NUL, ESC...), or a list nested more than ``max_depth``
    levels deep (None: no limit; the reader itself needs none, but consumers that walk
    forms recursively do).
    """
    if text.startswith(_BOM):
        text = " " + text[1:]  # whitespace of the same length: locations stay as they were
    bad = _CONTROL.search(text)
    if bad:
        line, col = _Locator(text)(bad.start())
        what = f"control character U+{ord(bad.group()):04X} is not allowed in KIF text"
        raise KifSyntaxError(what, file, line, col)
    try:
        return _parse(text, file, max_depth)
    except _BadNumber as exc:
        tok = exc.args[0]
        line, col = _Locator(text)(_atom_offset(text, tok))
        raise KifSyntaxError(f"integer too long: {_short(tok)}", file, line, col) from None


def _parse(text: str, file: str, max_depth: int | None = None) -> list[Form]:
    """The tokeniser loop of :func:`parse`."""
    locate = _Locator(text)
    newlines = locate.newlines
    top: list[Form] = []
    # Open lists: a stack of (items of the enclosing list, its start offset).
    stack: list[tuple[list, int]] = []
    push = stack.append
    pop = stack.pop
    cur: list | None = None  # items of the innermost open list
    start = 0  # offset of its "("
    atom = _AtomCache().__getitem__
    # Build Forms through their slot descriptors: same frozen object, about half the cost
    # of the dataclass __init__ (which goes through object.__setattr__ per field).
    new = object.__new__
    set_items, set_file, set_line, set_col = _FORM_SETTERS

    for m in _TOKEN.finditer(text):
        tok = m.group()
        c = tok[0]
        if c == "(":
            # Depth of this list: the open lists around it (stack + cur), plus one.
            if max_depth is not None and cur is not None and len(stack) + 2 > max_depth:
                line, col = locate(m.start())
                raise KifSyntaxError(
                    f"lists nest more than {max_depth} levels deep (the limit of the "
                    "translation to ASP)",
                    file,
                    line,
                    col,
                )
            if tok[-1] == ")":  # a list of atoms only, complete in one token
                p = m.start()
                n = bisect_right(newlines, p - 1)  # inline _Locator.__call__ (hot path)
                form = new(Form)
                set_items(form, tuple(map(atom, tok[1:-1].split())))
                set_file(form, file)
                set_line(form, n + 1)
                set_col(form, p - (newlines[n - 1] + 1 if n else 0) + 1)
                if cur is None:
                    top.append(form)
                else:
                    cur.append(form)
            else:
                if cur is not None:
                    push((cur, start))
                cur = list(map(atom, tok[1:].split()))
                start = m.start()
        elif c == ")":
            if cur is None:
                line, col = locate(m.start())
                raise KifSyntaxError("unexpected ')'", file, line, col)
            n = bisect_right(newlines, start - 1)
            form = new(Form)
            set_items(form, tuple(cur))
            set_file(form, file)
            set_line(form, n + 1)
            set_col(form, start - (newlines[n - 1] + 1 if n else 0) + 1)
            if stack:
                cur, start = pop()
                cur.append(form)
            else:
                top.append(form)
                cur = None
        elif c == '"':
            if len(tok) < 2 or tok[-1] != '"':
                line, col = locate(m.start())
                raise KifSyntaxError("unterminated string", file, line, col)
            if cur is None:
                line, col = locate(m.start())
                raise KifSyntaxError(
                    f"expected '(' at top level, found string {_short(tok)}", file, line, col
                )
            cur.append(String(tok[1:-1]))
        elif c == ";":
            continue
        else:  # a run of bare atoms
            if cur is None:
                line, col = locate(m.start())
                first = tok.split(None, 1)[0]
                raise KifSyntaxError(
                    f"expected '(' at top level, found {_short(first)!r}", file, line, col
                )
            cur.extend(map(atom, tok.split()))

    if cur is not None:
        line, col = locate(start)
        raise KifSyntaxError("unclosed '(': no matching ')' before end of text", file, line, col)
    return top


def _atom_offset(text: str, tok: str) -> int:
    """Offset of the first occurrence of bare atom ``tok`` outside strings and comments."""
    pattern = re.compile(_ATOM_AT.format(re.escape(tok)))
    for m in _TOKEN.finditer(text):
        if m.group()[0] not in '";)':
            found = pattern.search(text, m.start(), m.end())
            if found:
                return found.start()
    return 0  # not reached: the token came from this text


def parse_file(path: str | Path) -> list[Form]:
    """Parse a UTF-8 SUO-KIF file (a leading BOM is ignored); locations name ``str(path)``."""
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        text = fh.read()
    return parse(text, str(path))
