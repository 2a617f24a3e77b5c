"""The one owner of ``clingo.Control``: grounds the knowledge base once, then answers
queries by assigning externals (multi-shot), returning frozen dataclasses.

The program is the KIF translation, the encodings of ``asp/conceptual.lp`` and any user
rule files. A query sets the externals ``request/1``, ``answer/2`` and ``param/2``
and enumerates all answer sets: one per candidate robot type.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import hashlib
import itertools
import os
import re
import resource
import signal
import sys
import tempfile
import threading
import weakref
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from importlib import resources
from multiprocessing.connection import Connection, Pipe
from pathlib import Path

import clingo

from adron import relevance as relevance_module
from adron.errors import InputError, OntologyError, ParmorError
from adron.kb import KnowledgeBase, materialised, prune, read_user_file
from adron.materialise import Derivation, applied, derivation
from adron.relevance import Relevance, relevance
from adron.translate import asp_string, closed_taxonomy
from adron.units import cache_folder, read_cache_bytes, write_cache_file
from synth import limits
from synth.reasoning import ground_probe

_SCRIPT = re.compile(r"#\s*script", re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class Query:
    """A request in KIF terms. ``answers`` maps action class to True (yes) / False (no);
    ``params`` holds (relation, term) pairs."""

    requests: tuple[str, ...] = ()
    answers: tuple[tuple[str, bool], ...] = ()
    params: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True, slots=True, order=True)
class Reason:
    """Why a robot can do an action: it has ``have`` parts of ``kind``, it needs ``need``."""

    action: str
    kind: str
    need: int
    have: int


@dataclass(frozen=True, slots=True)
class PartSource:
    """A part count and the axioms (by id) that declare it."""

    kind: str
    count: int
    axioms: tuple[int, ...]


@dataclass(frozen=True)
class Candidate:
    """One answer set: a robot type and its conceptual design under the query."""

    robot_type: str
    active_total: int
    dof: int
    parts: tuple[tuple[str, int], ...]
    modules: tuple[tuple[str, int], ...]
    passive: tuple[tuple[str, int], ...]
    abilities: tuple[str, ...]
    potential: tuple[str, ...]
    reasons: tuple[Reason, ...] = ()
    sources: tuple[PartSource, ...] = ()
    module_limit: int | None = None
    hierarchy: int = 1  # depth of the part tree (robot -> parts -> modules: 2)
    declared: tuple[str, ...] = ()  # abilities its declared parts give (no growth, add-ons)
    ancestors: tuple[str, ...] = ()  # robot classes it is (itself included)
    preference: tuple[int, ...] = ()  # asp/preference.lp's cost of choosing it
    needed: tuple[str, ...] = ()  # the abilities the query demands of it (KIF classes)


@dataclass(frozen=True)
class Solution:
    """All candidates of a query (preference order) and the demands as the solver saw them."""

    candidates: tuple[Candidate, ...]
    needed: tuple[str, ...] = ()
    excluded: tuple[str, ...] = ()
    satisfiable: bool = True


def encoding_dir() -> Path:
    """The folder of the shipped encodings (package data of ``asp``)."""
    return Path(str(resources.files("asp")))


# -- user rule files: includes resolved by parmor, scripts and protected predicates -------

#: a comment, an #include directive (group 2: quoted target, 3: <target>) or a string:
#: scanning left to right skips directives inside comments and strings, as clingo does
_LEXICAL = re.compile(
    r'%\*.*?\*%|%[^\n]*|(#include\s*(?:"((?:[^"\\]|\\.)*)"|<([^>]*)>)\s*\.)'
    r'|"(?:[^"\\\n]|\\.)*"',
    re.DOTALL,
)
#: atoms counted per predicate when a size limit is reached (then 100 times this)
_SAMPLE = 1000
#: predicates of the KB vocabulary a rule file may define (knowledge, not answers)
OPEN_PREDICATES = frozenset({"holds"})


@dataclass(frozen=True, slots=True)
class RuleFile:
    """A user's rule file as clingo gets it: ``text`` with its ``#include`` directives
    blanked (positions kept), ``name`` as the user gave it."""

    name: str
    path: Path
    text: str


def _position(text: str, offset: int) -> tuple[int, int]:
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def _directives(text: str) -> list[tuple[int, int, str]]:
    """(start, end, target) of every ``#include`` outside comments and strings."""
    out = []
    for m in _LEXICAL.finditer(text):
        if m.group(1):
            target = m.group(2) if m.group(2) is not None else m.group(3)
            out.append((m.start(), m.end(), target.replace('\\"', '"').replace("\\\\", "\\")))
    return out


def _blank_includes(text: str) -> str:
    """``text`` with its ``#include`` directives replaced by spaces (positions kept)."""
    chars = list(text)
    for start, end, _ in _directives(text):
        chars[start:end] = [c if c == "\n" else " " for c in chars[start:end]]
    return "".join(chars)


def _refuse_scripts(name: str, text: str) -> None:
    # anywhere in the text, comments and strings included: refusing too much is safe,
    # guessing where clingo's lexer sees a comment is not
    for lineno, line in enumerate(text.splitlines(), 1):
        m = _SCRIPT.search(line)
        if m:
            raise InputError(
                f"{name}:{lineno}:{m.start() + 1}: refusing a rule file that contains "
                "#script (clingo would run its code); pass --allow-scripts to trust it"
            )


#: Outside strings and comments clingo's lexer reads ASCII only, and its message about any
#: other byte is cut mid-character, which aborts the process inside clingo's Python logger.
# Only closed strings and comments are skipped: clingo echoes an unclosed one's text.
_ASP_TOKEN = re.compile(r'"(?:[^"\\\n]|\\.)*"|%\*.*?\*%|%[^\n]*|[^"%]+|.', re.S)
_UNLEXABLE = re.compile(r"[^\t\n\r\x20-\x7e]")


def check_lexable(name: str, text: str) -> None:
    """InputError (file:line:col) for a character clingo cannot read outside strings and
    comments: non-ASCII (a byte order mark too) or a control character."""
    for m in _ASP_TOKEN.finditer(text):
        if m.group()[0] in '"%':
            continue
        bad = _UNLEXABLE.search(m.group())
        if bad:
            at = m.start() + bad.start()
            line = text.count("\n", 0, at) + 1
            col = at - (text.rfind("\n", 0, at) + 1) + 1
            raise InputError(
                f"{name}:{line}:{col}: character U+{ord(bad.group()):04X} outside a string or "
                "comment (ASP reads ASCII there)"
            )


def read_rule_files(paths: Sequence[str | Path], allow_scripts: bool) -> tuple[RuleFile, ...]:
    """The user's rule files and every file they ``#include`` (each once, in load order).

    parmor resolves ``#include`` itself: an included path is relative to the including
    file's folder and, unless ``allow_scripts``, must stay inside it; every file is
    refused when it contains ``#script`` (unless ``allow_scripts``) or defines a predicate
    the encodings derive (:func:`protected_predicates`)."""
    out: list[RuleFile] = []
    seen: set[Path] = set()
    todo: list[tuple[str | Path, str | None]] = [(p, None) for p in reversed(paths)]
    while todo:
        path, _ = todo.pop()
        name, text = read_user_file(path)
        real = Path(path).resolve()
        if real in seen:
            continue
        seen.add(real)
        check_lexable(name, text)
        if not allow_scripts:
            _refuse_scripts(name, text)
        includes = []
        for start, _end, target in _directives(text):
            line, col = _position(text, start)
            where = f"{name}:{line}:{col}"
            inc = Path(target)
            inc = inc if inc.is_absolute() else real.parent / inc
            folder = real.parent
            if not allow_scripts and not inc.resolve().is_relative_to(folder):
                raise InputError(
                    f"{where}: #include {target!r} leaves the folder of {name}; "
                    "pass --allow-scripts to trust it"
                )
            if not inc.is_file():
                raise InputError(f"{where}: #include {target!r}: no such file")
            includes.append(str(inc))
        body = _blank_includes(text)
        _refuse_protected(name, body)
        out.append(RuleFile(name, real, body))
        todo.extend((p, name) for p in reversed(includes))
    return tuple(out)


def check_rules_file(path: str | Path, allow_scripts: bool) -> str:
    """Read a user's .lp file (and what it includes), refusing ``#script`` unless scripts
    are allowed, includes outside its folder and protected predicates; its text."""
    return read_rule_files([path], allow_scripts)[0].text


_PROTECTED: frozenset[tuple[str, int]] | None = None


def _atom_names(term: object) -> Iterator[tuple[str, int, object]]:
    """(name, arity, location) of every atom an atom's term can stand for: a pool
    (``chosen("A";"B")``) any of its elements, ``-p(..)`` p's (classical negation)."""
    from clingo import ast

    t = term.ast_type
    if t == ast.ASTType.Pool:
        for e in term.arguments:
            yield from _atom_names(e)
    elif t == ast.ASTType.Function:
        if not term.external:
            yield term.name, len(term.arguments), term.location
    elif t == ast.ASTType.UnaryOperation:
        yield from _atom_names(term.argument)
    elif t == ast.ASTType.SymbolicTerm and term.symbol.type == clingo.SymbolType.Function:
        yield term.symbol.name, len(term.symbol.arguments), term.location


def _literal_names(lit: object) -> Iterator[tuple[str, int, object]]:
    """What a head literal defines: its atom unless it is ``not a`` (a constraint);
    ``not not a`` is a choice of ``a``."""
    from clingo import ast

    if lit.ast_type != ast.ASTType.Literal or lit.sign == ast.Sign.Negation:
        return
    if lit.atom.ast_type == ast.ASTType.SymbolicAtom:
        yield from _atom_names(lit.atom.symbol)


def _heads(stmt: object) -> list[tuple[str, int, object]]:
    """(name, arity, location) of the atoms a parsed statement defines, declares external,
    shows, projects or steers (``#heuristic``), in every form clingo accepts: pools in
    heads and arguments, disjunctions, conditional heads, choices and head aggregates."""
    from clingo import ast

    T = ast.ASTType
    t = stmt.ast_type
    out: list[tuple[str, int, object]] = []
    if t == T.Rule:
        h = stmt.head
        if h.ast_type == T.Literal:
            out += _literal_names(h)
        elif h.ast_type in (T.Disjunction, T.Aggregate):
            for e in h.elements:
                out += _literal_names(e.literal)
        elif h.ast_type == T.HeadAggregate:
            for e in h.elements:
                out += _literal_names(e.condition.literal)
        # a theory atom (&p {...}) defines no ordinary atom
    elif t in (T.External, T.Heuristic, T.ProjectAtom):
        if stmt.atom.ast_type == T.SymbolicAtom:
            out += _atom_names(stmt.atom.symbol)
    elif t == T.ShowTerm:
        out += _atom_names(stmt.term)
    elif t in (T.ShowSignature, T.ProjectSignature):
        out.append((stmt.name, stmt.arity, stmt.location))
    return out


def _open_show(term: object) -> object | None:
    """The location of a ``#show`` term that a variable or a script call gives (``#show X
    : p(X).`` shows whatever ``X`` is bound to, ``chosen("A")`` included), else None."""
    from clingo import ast

    t = term.ast_type
    if t == ast.ASTType.Variable or (t == ast.ASTType.Function and term.external):
        return term.location
    if t == ast.ASTType.UnaryOperation:
        return _open_show(term.argument)
    if t == ast.ASTType.Pool:
        for e in term.arguments:
            loc = _open_show(e)
            if loc is not None:
                return loc
    return None


def _parse(text: str) -> list[object]:
    from clingo import ast

    stmts: list[object] = []
    ast.parse_string(text, stmts.append, logger=lambda c, m: None)
    return stmts


def protected_predicates() -> frozenset[tuple[str, int]]:
    """(name, arity) of every predicate a shipped encoding derives, declares external or
    shows (``chosen/1``, ``isa/2``, ``need/1`` ...), except the KB vocabulary ``holds``.
    A user's rule file may constrain them (``:- chosen("X").``) but not define them."""
    global _PROTECTED
    if _PROTECTED is None:
        # explain's mode switch, the catalog bus's limit and the fast path's externals:
        # facts and rules the solver adds
        found = {("focus", 1), ("bus_limit", 1), (_EXTERNAL, 1)}
        for lp in sorted(encoding_dir().glob("*.lp")):
            for stmt in _parse(_blank_includes(lp.read_text(encoding="utf-8"))):
                found.update((n, a) for n, a, _ in _heads(stmt) if n and n not in OPEN_PREDICATES)
        _PROTECTED = frozenset(found)
    return _PROTECTED


def _refuse_protected(name: str, text: str) -> None:
    """InputError (file:line:col) for the first statement of ``text`` that defines,
    declares external, projects or steers a protected predicate, or shows one (by name, at
    any arity: the solver reads shown atoms by name) or a term a variable gives."""
    from clingo import ast

    try:
        stmts = _parse(text)
    except RuntimeError:
        return  # a syntax error: clingo reports it with its location when grounding
    protected = protected_predicates()
    names = {n for n, _ in protected}
    for stmt in stmts:
        show = stmt.ast_type in (ast.ASTType.ShowTerm, ast.ASTType.ShowSignature)
        if stmt.ast_type == ast.ASTType.ShowTerm:
            loc = _open_show(stmt.term)
            if loc is not None:
                raise InputError(
                    f"{name}:{loc.begin.line}:{loc.begin.column}: a rule file may not show "
                    f"the term {stmt.term} (a variable or script could give chosen/1 or "
                    "another atom parmor derives); show name(...) with a name of its own"
                )
        for pred, arity, loc in _heads(stmt):
            line, col = loc.begin.line, loc.begin.column
            if show and pred in names and (pred, arity) not in protected:
                raise InputError(
                    f"{name}:{line}:{col}: a rule file may not show {pred}/{arity}: parmor "
                    f"reads every shown atom named {pred} as its own (asp/doc.lp)"
                )
            if (pred, arity) in protected:
                raise InputError(
                    f"{name}:{line}:{col}: a rule file may not define {pred}/{arity}: parmor "
                    "derives it (asp/doc.lp); constrain it instead, e.g. ':- "
                    f"{pred}(...).'"
                )


# -- the clingo worker ---------------------------------------------------------------------


def _str(sym: clingo.Symbol) -> str:
    return sym.string if sym.type == clingo.SymbolType.String else str(sym)


def _models(ctl: clingo.Control, where: str = "solve") -> Iterator[clingo.Model]:
    """The models of a solve in this process, waiting in slices so that signals and the
    time limit get in (a plain solve does not return to Python until the next model)."""
    with ctl.solve(yield_=True, async_=True) as handle:
        while True:
            handle.resume()
            while not handle.wait(0.05):
                limits.check(where)
            model = handle.model()
            if model is None:
                return
            yield model


def _worker_models(ctl: clingo.Control) -> Iterator[clingo.Model]:
    """The models of a solve in a worker: synchronous (its parent kills it to stop it)."""
    with ctl.solve(yield_=True) as handle:
        yield from handle


@functools.cache
def _encoding_texts() -> tuple[str, ...]:
    return tuple(
        p.read_text(encoding="utf-8")
        for p in sorted(encoding_dir().glob("*.lp"))
        if p.name != "closure.lp"
    )


#: Without rule files and focus, ground every candidate into one answer set (asp/every.lp:
#: the same candidates, solved and read ~2x faster with 1000 of them); False: always the
#: choice of one per answer set (tests compare the two).
EVERY_IN_ONE = True
#: The fast path's replacements of conceptual.lp's includes (asp/every.lp says why).
_EVERY = {"choice.lp": "every.lp", "preference.lp": None}


#: With a query's externals as facts, what ``#external X : C.`` becomes: ``_EXTERNAL(X) :-
#: C.``, so that the externals a query may set are still known (``_Core.externals``).
_EXTERNAL = "parmor_external"
_EXTERNAL_LINE = re.compile(r"^#external\s+(.*?)\s*(?::\s*(.*?))?\s*\.[ \t]*$", re.MULTILINE)


@functools.cache
def conceptual_text(every: bool = False, fixed: bool = False) -> str:
    """asp/conceptual.lp with its ``#include`` lines replaced by the files they name. Not
    ``Control.load``: clingo looks for an included file in the working folder first, so a
    ``choice.lp`` of the user's there would replace parmor's. With ``every``, every
    candidate in one answer set (asp/every.lp in place of choice.lp and preference.lp);
    with ``fixed``, no externals: each ``#external`` statement a rule of _EXTERNAL."""
    if fixed:
        return _EXTERNAL_LINE.sub(
            lambda m: f"{_EXTERNAL}({m.group(1)})" + (f" :- {m.group(2)}." if m.group(2) else "."),
            conceptual_text(every),
        )

    def include(name: str) -> str:
        if every and name in _EVERY:
            name = _EVERY[name]
            if name is None:
                return ""
        return inline((encoding_dir() / name).read_text(encoding="utf-8"))

    def inline(text: str) -> str:
        return re.sub(
            r'^#include\s+"([^"]+)"\s*\.[ \t]*$', lambda m: include(m.group(1)), text, flags=re.M
        )

    return inline((encoding_dir() / "conceptual.lp").read_text(encoding="utf-8"))


#: the encodings of the taxonomy layer: they read subclass/subrelation/instance for any
#: pair to build the closure, which the other encodings then ask about given classes only
_TAXONOMY_LAYER = ("taxonomy.lp", "closure.lp")


@functools.cache
def _relevance_texts() -> tuple[tuple[str, ...], tuple[str, ...]]:
    files = sorted(encoding_dir().glob("*.lp"))
    return (
        tuple(p.read_text(encoding="utf-8") for p in files if p.name not in _TAXONOMY_LAYER),
        tuple(p.read_text(encoding="utf-8") for p in files if p.name in _TAXONOMY_LAYER),
    )


def relevant(
    kb: KnowledgeBase,
    focus: str | None = None,
    rules: Sequence[str] = (),
    grounded: bool = False,
) -> Relevance:
    """Which translated forms of ``kb`` can reach the encodings' vocabulary (adron/relevance.py);
    nothing is filtered when user ``rules`` are given (a rule file may read anything).
    ``grounded``: of ``kb.grounded`` (its rules materialised, adron/materialise.py), not of
    ``kb.translation``."""
    tr = kb.translation if not grounded or kb.grounded is None else kb.grounded
    if rules:
        n = len(tr.units)
        return Relevance((True,) * n, ("",) * n, "rule files are given (they may read anything)")
    body, taxo = _relevance_texts()
    return relevance(tr, body, taxo, [focus] if focus is not None else [])


def _relevant_program(
    kb: KnowledgeBase, focus: str | None, rules: Sequence[str], grounded: bool
) -> str:
    """The relevant part of ``kb.translation``, or with ``grounded`` of ``kb.grounded``
    (its ontology-only rules materialised here when the cache misses), as ASP text.

    Kept on disk beside the cached knowledge base (``$PARMOR_CACHE/relevant-KEY.lp``, KEY
    a hash of the knowledge base's key, ``focus``, the encodings, and the code of this
    module and adron/relevance.py): computing it costs ~0.3 s for SUMO. Written whole
    (temporary file + rename); an unreadable or unwritable one only costs time."""
    path = None
    if kb.key is not None and not rules:
        folder = cache_folder()
        if folder is not None:
            h = hashlib.sha256(f"{kb.key}|{grounded}|{focus!r}".encode())
            for text in (*_relevance_texts()[0], *_relevance_texts()[1]):
                h.update(hashlib.sha256(text.encode()).digest())
            for mod in (relevance_module.__file__, __file__):
                h.update(hashlib.sha256(Path(str(mod)).read_bytes()).digest())
            path = folder / f"relevant-{h.hexdigest()[:32]}.lp"
            with contextlib.suppress(OSError, UnicodeDecodeError):
                text = (read_cache_bytes(path) or b"").decode("utf-8")  # the user's own only
                if text.startswith(_RELEVANT_TAG) and text.endswith(_RELEVANT_END):
                    os.utime(path)  # recently used (adron/kb.py: prune)
                    return text[len(_RELEVANT_TAG) : -len(_RELEVANT_END)]
    if grounded:
        kb = materialised(kb)
    tr = kb.grounded if grounded and kb.grounded is not None else kb.translation
    program = relevant(kb, focus, rules, grounded).program(tr)
    text = _RELEVANT_TAG + program + _RELEVANT_END
    if path is not None and write_cache_file(path, text.encode("utf-8")):
        prune(path.parent)
    return program


#: the first and last line of a cached relevant program (a file cut short lacks the last)
_RELEVANT_TAG = "% parmor relevant program 1\n"
_RELEVANT_END = "% end\n"


def taxonomy_program(
    kb: KnowledgeBase, others: Sequence[str], rules: Sequence[str], program: str | None = None
) -> tuple[str, str]:
    """``program`` (the translation as it goes to the grounder; by default all of it) as it
    is grounded, and the taxonomy closure it needs: facts, with the program's direct edges
    between classes that nothing asks about left out, or the recursive rules, with the
    program whole, when only they are exact (adron/translate.py: closed_taxonomy)."""
    program = kb.translation.program if program is None else program
    found = closed_taxonomy(program, [*_encoding_texts(), *others], rules)
    if found is None:
        return program, (encoding_dir() / "closure.lp").read_text(encoding="utf-8")
    return found


_STRING = clingo.SymbolType.String
#: from this many possible candidates on, a solve looks up each model's atoms for its
#: chosen robot instead of reading all shown atoms (building that index costs ~20 ms)
_INDEXED = 64


_SHOW_SIGNATURE = re.compile(r"^[ \t]*#show[ \t]+(\w+)/(\d+)[ \t]*\.", re.MULTILINE)


@functools.cache
def _shown_signatures() -> tuple[tuple[str, int], ...]:
    """(name, arity) of every ``#show name/arity`` line of the shipped encodings."""
    out = {
        (m.group(1), int(m.group(2)))
        for lp in sorted(encoding_dir().glob("*.lp"))
        for m in _SHOW_SIGNATURE.finditer(lp.read_text(encoding="utf-8"))
    }
    return tuple(sorted(out))


class _Core:
    """The Control of a :class:`Reasoner`, in its worker process."""

    def __init__(
        self,
        kb: KnowledgeBase,
        rules: Sequence[RuleFile],
        focus: str | None,
        size: int | None,
        bus_limit: int | None | Callable[[], int | None] = None,
        first: frozenset[str] | None | Callable[[], frozenset[str]] = None,
    ) -> None:
        """``bus_limit`` may be a function that gives it: called once the program is
        filtered and its taxonomy closed, just before grounding (the parent sends it
        then, having parsed the catalog meanwhile). ``first``: the externals (as text) of
        the query expected first; on the fast path they are grounded as facts (a program
        the grounder evaluates whole: ~2x quicker to ground and solve with 1000
        candidates), and a program with externals is grounded when another query comes."""
        self._messages: list[str] = []
        self._rules, self._size = rules, size
        # the fast path: every candidate in one answer set (asp/every.lp)
        self.every = EVERY_IN_ONE and not rules and focus is None
        extra = [f"focus({asp_string(focus)})."] if focus is not None else []
        texts = [r.text for r in rules]
        # with rule files the translation as it is (they may define any holds atom the
        # ontology's rules read); without, its rules materialised (adron/materialise.py)
        program = _relevant_program(kb, focus, texts, grounded=not texts)
        program, taxonomy = taxonomy_program(kb, extra, texts, program)
        if callable(bus_limit):
            bus_limit = bus_limit()
        if bus_limit is not None:  # no string in it: the closure's anchors are the same
            extra.append(f"bus_limit({int(bus_limit)}).")
        self._program = (program, taxonomy, *extra)
        if callable(first):  # sent as bus_limit is, after it
            first = first()
        self._fixed = frozenset(first) if self.every and first is not None else None
        self._ctl = self._ground(self._fixed)
        self._general = None if self._fixed is not None else self._ctl
        atoms = self._ctl.symbolic_atoms
        self._index: tuple[list, dict[str, list], list] | None = None
        if self._fixed is not None:
            self.externals = {a.symbol.arguments[0] for a in atoms.by_signature(_EXTERNAL, 1)}
        else:
            self.externals = self._externals(self._ctl)

    @staticmethod
    def _externals(ctl: clingo.Control) -> set[clingo.Symbol]:
        """The externals a query may set in ``ctl`` (asp/request.lp)."""
        atoms = ctl.symbolic_atoms
        return {
            a.symbol
            for sig in (("request", 1), ("answer", 2), ("param", 2))
            for a in atoms.by_signature(*sig)
            if a.is_external
        }

    def _ground(self, fixed: frozenset[str] | None) -> clingo.Control:
        """The program grounded: with ``fixed``, those externals as facts and the others
        absent (asp/request.lp's ``#external`` statements become rules of _EXTERNAL)."""
        rules = self._rules
        ctl = clingo.Control(["--models=0", "--opt-mode=enum"], logger=self._log, message_limit=20)
        try:
            for text in self._program:
                ctl.add("base", [], text)
            ctl.add("base", [], conceptual_text(self.every, fixed is not None))
            if fixed is not None:
                ctl.add("base", [], "".join(f"{x}.\n" for x in sorted(fixed)))
            self._tmp: dict[str, str] = {}
            with (
                tempfile.TemporaryDirectory(prefix="parmor-rules-")
                if rules
                else (contextlib.nullcontext("")) as tmp
            ):
                for i, r in enumerate(rules):
                    copy = Path(tmp) / f"{i}.lp"
                    copy.write_text(r.text, encoding="utf-8")
                    self._tmp[str(copy)] = r.name
                    ctl.load(str(copy))
            ctl.ground([("base", [])])
        except RuntimeError as e:
            if "bad_alloc" in str(e):
                raise MemoryError from None
            detail = "; ".join(self._messages) or str(e)
            for copy, name in self._tmp.items():
                detail = detail.replace(copy, name)
            raise OntologyError(f"the rules do not ground: {detail}") from None
        if self._size is not None and len(ctl.symbolic_atoms) > self._size:
            raise limits.LimitExceeded(
                limits.Limits(size_atoms=self._size).describe("size"),
                "size",
                self._largest(ctl, rules),
            )
        return ctl

    def _control(self, on: set[str]) -> clingo.Control:
        """The control that answers the query ``on``: the first query's own, or the one
        with externals (grounded when first needed), with ``on`` assigned."""
        if self._fixed is not None and on == self._fixed:
            return self._ctl
        if self._general is None:
            # from now on every query here: the first query's control is let go (memory)
            self._ctl = self._general = self._ground(None)
            self._fixed = None
            self.externals = self._externals(self._ctl)
        for sym in self.externals:
            self._general.assign_external(sym, str(sym) in on)
        return self._general

    def robot_types(self) -> tuple[str, ...]:
        """Every subclass of Robot (asked for by name checks only: can be 100,000)."""
        atoms = self._ctl.symbolic_atoms
        return tuple(
            sorted(a.symbol.arguments[0].string for a in atoms.by_signature("robot_class", 1))
        )

    def _largest(self, ctl: clingo.Control, rules: Sequence[RuleFile]) -> str:
        """What grew: the predicate with the most ground atoms (counted up to a cap, in
        two rounds, to stay quick) and where a rule file defines it."""
        atoms = ctl.symbolic_atoms

        def count(sig: tuple[str, int, bool], cap: int) -> int:
            return sum(1 for _ in itertools.islice(atoms.by_signature(*sig), cap))

        sigs = list(atoms.signatures)
        first = {sig: count(sig, _SAMPLE) for sig in sigs}
        big = [sig for sig, n in first.items() if n >= _SAMPLE] or sigs
        n, (name, arity, _) = max((count(sig, 100 * _SAMPLE), sig) for sig in big)
        amount = f"over {n}" if n >= 100 * _SAMPLE else str(n)
        where = ""
        for r in rules:
            with contextlib.suppress(RuntimeError):
                for stmt in _parse(r.text):
                    for pred, ar, loc in _heads(stmt):
                        if (pred, ar) == (name, arity) and not where:
                            where = f" (defined at {r.name}:{loc.begin.line}:{loc.begin.column})"
        return f"{amount} ground atoms of {name}/{arity}{where}"

    def _log(self, code: clingo.MessageCode, message: str) -> None:
        self._messages.append(message.strip().replace("\n", " "))

    def satisfiable(self, on: set[str]) -> bool:
        ctl = self._control(on)
        for m in _worker_models(ctl):
            if not self.every:
                return True
            return any(m.is_true(a.literal) for a in ctl.symbolic_atoms.by_signature("chosen", 1))
        return False

    def _each(self, on: set[str]) -> list[tuple[list[tuple[str, tuple]], tuple[int, ...]]]:
        """The fast path's answer sets, as the choice's would be: per chosen robot, the
        shown atoms about no robot and those about it (its name their first argument), as
        (text, (name, args)), and its cost (asp/preference.lp: the sum of its active
        module counts)."""
        ctl = self._control(on)
        atoms = ctl.symbolic_atoms
        # every robot with atoms: candidates over the bus limit are not chosen/1 here
        robots = {a.symbol.arguments[0].string for a in atoms.by_signature("sel", 1)}
        for m in _worker_models(ctl):
            common: list[tuple[str, tuple]] = []
            by: dict[str, list[tuple[str, tuple]]] = {}
            for sym in m.symbols(shown=True):
                text = str(sym)
                atom = _read_symbol(text, sym)
                args = atom[1]
                key = args[0] if args and isinstance(args[0], str) else None
                (by.setdefault(key, []) if key in robots else common).append((text, atom))
            out = []
            for r in sorted(by):
                if any(atom[0] == "chosen" for _, atom in by[r]):
                    cost = sum(atom[1][2] for _, atom in by[r] if atom[0] == "active")
                    out.append((common + by[r], (cost,)))
            return out
        return []

    def answer_sets(self, on: set[str], keep: set[str] | None) -> frozenset:
        if self.every:
            return frozenset(
                frozenset(text for text, (name, _) in atoms if keep is None or name in keep)
                for atoms, _ in self._each(on)
            )
        return frozenset(
            frozenset(str(s) for s in m.symbols(shown=True) if keep is None or s.name in keep)
            for m in _worker_models(self._control(on))
        )

    def _shown_index(self) -> tuple[list, dict[str, list], list]:
        """(chosen/1 literals and robot names, shown atoms by robot, the other shown atoms),
        over the signatures ``asp/show.lp`` shows, built once."""
        if self._index is None:
            atoms = self._ctl.symbolic_atoms
            chosen = [
                (a.literal, a.symbol.arguments[0].string) for a in atoms.by_signature("chosen", 1)
            ]
            robots = {r for _, r in chosen}
            by: dict[str, list] = {}
            common: list = []
            for name, arity in _shown_signatures():
                for a in atoms.by_signature(name, arity):
                    sym = a.symbol
                    key = _first_string(sym) if arity else None
                    (by.setdefault(key, []) if key in robots else common).append((a.literal, sym))
            self._index = (chosen, by, common)
        return self._index

    def solve(self, on: set[str]) -> list[tuple[tuple, tuple[int, ...]]]:
        """Each answer set's shown atoms that concern its chosen robot (and the request's),
        and its cost. Reading a model's shown atoms costs the size of the output table, all
        candidates' designs: per model, only the chosen robot's atoms are looked up, or a
        request with 1000 candidates would take time quadratic in them."""
        if self.every:
            return [(tuple(atom for _, atom in atoms), cost) for atoms, cost in self._each(on)]
        ctl = self._control(on)
        if (
            sum(1 for _ in itertools.islice(ctl.symbolic_atoms.by_signature("chosen", 1), _INDEXED))
            < _INDEXED
        ):
            models = _worker_models(ctl)
            return [(_symbols(m.symbols(shown=True)), tuple(m.cost)) for m in models]
        chosen, by, common = self._shown_index()
        pending = list(chosen)
        out = []
        last = 0  # clingo tends to enumerate the candidates in runs: look near the last one
        for m in _worker_models(ctl):
            robot = None
            n = len(pending)
            for k in range(n):
                i = (last - 1 - k) % n
                if m.is_true(pending[i][0]):
                    robot = pending.pop(i)[1]
                    last = i
                    break
            if robot is None:  # explain's focus mode: one model, nothing chosen
                out.append((_symbols(m.symbols(shown=True)), tuple(m.cost)))
                continue
            syms = [s for lit, s in (*common, *by.get(robot, ())) if m.is_true(lit)]
            out.append((_symbols(syms), tuple(m.cost)))
        return out


_FIRST_STRING = re.compile(r'[^(]*\("([^"\\]*)"[,)]')


def _first_string(sym: clingo.Symbol) -> str | None:
    """The first argument of ``sym`` when it is a string, else None: read from its text
    (one call into clingo) where the string has no escapes, as most names have none."""
    m = _FIRST_STRING.match(str(sym))
    if m is not None:
        return m.group(1)
    first = sym.arguments[0] if sym.arguments else None
    return first.string if first is not None and first.type == _STRING else None


def _symbols(symbols: Iterable[clingo.Symbol]) -> tuple:
    """Shown atoms as plain (name, args) tuples (picklable)."""
    return tuple(_read_symbol(str(s), s) for s in symbols)


#: An atom with arguments, as text: its name and the text between its parentheses.
_ATOM_TEXT = re.compile(r"(\w+)\((.*)\)\Z")


def _read_symbol(text: str, sym: clingo.Symbol) -> tuple[str, tuple]:
    """``sym`` (whose text is ``text``) as (name, args): strings as their contents, numbers
    as ints, other terms as their text. Read from the text (one call into clingo instead
    of one per argument and property) where every argument is a string without quotes,
    commas or escapes in it, or an integer; else from the symbol."""
    m = _ATOM_TEXT.match(text)
    if m is None:
        if text.isidentifier():
            return text, ()
    elif "\\" not in text:
        args: list[str | int] = []
        quoted = 0
        try:
            for part in m.group(2).split(","):
                if part[0] == '"':
                    if part[-1] != '"' or len(part) < 2:
                        raise ValueError(part)
                    args.append(part[1:-1])
                    quoted += 1
                else:
                    args.append(int(part))
        except (ValueError, IndexError):
            pass
        else:
            if text.count('"') == 2 * quoted:
                return m.group(1), tuple(args)
    return (
        sym.name,
        tuple(_str(a) if a.type != clingo.SymbolType.Number else a.number for a in sym.arguments),
    )


def _serve(
    conn: Connection,
    make: Callable[[Connection], _Core],
    memory_mb: int | None,
    orphan_dies: bool,
) -> None:
    """The worker's loop: build the core (``make`` may read what the parent sends first
    from ``conn``), then answer calls until the pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides, and kills us
    signal.setitimer(signal.ITIMER_REAL, 0)
    signal.signal(signal.SIGALRM, signal.SIG_IGN)
    # the kernel's "parent" is the forking thread: only the main thread lives as long as us
    if orphan_dies and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if memory_mb is not None:
        cap = (limits.address_space_kb() + memory_mb * 1024) * 1024
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_AS, (cap, resource.getrlimit(resource.RLIMIT_AS)[1]))
    core = None
    where = "ground"
    while True:
        try:
            if core is None:
                core = make(conn)
                reply: tuple = ("ok", {str(x) for x in core.externals})
            else:
                try:
                    method, args = conn.recv()
                except EOFError:
                    return
                where = "solve"
                reply = ("ok", getattr(core, method)(*args))
        except MemoryError:
            core = None
            reply = ("limit", "memory", where, "")
        except limits.LimitExceeded as e:
            reply = ("limit", "size", e.stage, str(e).split(": ", 1)[-1])
        except ParmorError as e:
            reply = ("error", type(e).__name__, str(e))
        except Exception as e:  # noqa: BLE001 - reported to the parent, which raises
            if "bad_alloc" in str(e):
                reply = ("limit", "memory", where, "")
            else:
                reply = ("error", "RuntimeError", f"{type(e).__name__}: {e}")
        try:
            conn.send(reply)
        except (OSError, MemoryError):
            return
        if reply[0] != "ok" and where == "ground":
            return


_ERRORS = {"InputError": InputError, "OntologyError": OntologyError}


class _Materialiser:
    """A worker's core that materialises a knowledge base's ontology-only rules."""

    def __init__(self, kb: KnowledgeBase) -> None:
        self.found = derivation(kb.translation)
        self.externals: set = set()

    def result(self) -> tuple[Derivation | None, str | None]:
        """What materialising changes, not the materialised translation: the parent has
        the translation already, and pickling it back costs seconds for a large one."""
        return self.found


def materialised_in_worker(kb: KnowledgeBase) -> KnowledgeBase:
    """:func:`adron.kb.materialised` in a worker process, so that a limit or Ctrl-C stops
    it while clingo grounds (``ontology check``)."""
    if kb.grounded is not None or kb.why_not is not None:
        return kb
    worker = _Worker(lambda _conn: _Materialiser(kb), "the knowledge base's rules")  # type: ignore[arg-type, return-value]
    try:
        with limits.stage("ground"):
            worker.result("ground")
        found, why_not = worker.call("result")
    finally:
        worker.close()

    grounded = kb.translation if found is None else applied(kb.translation, found)
    return replace(kb, grounded=grounded, why_not=why_not)


class _Worker:
    """A forked process that owns one :class:`_Core`; killed on SIGINT or a limit."""

    def __init__(self, make: Callable[[Connection], _Core], what: str) -> None:
        lim = limits.current()
        self.what = what
        parent, child = Pipe()
        from_main = threading.current_thread() is threading.main_thread()
        pid = os.fork()
        if pid == 0:  # the worker
            code = 0
            try:
                parent.close()
                _serve(child, make, lim.memory_mb, from_main)
            except BaseException:  # noqa: BLE001 - a worker never returns into the caller
                code = 1
            finally:
                os._exit(code)
        child.close()
        self.pid, self.conn = pid, parent
        self._finalizer = weakref.finalize(self, _kill, pid, parent, os.getpid())

    def close(self) -> None:
        self._finalizer()

    def result(self, where: str) -> object:
        """The worker's next reply; raises what it reports, LimitExceeded, or
        KeyboardInterrupt (the worker is killed at once)."""
        try:
            while not self.conn.poll(0.05):
                limits.check(where)
            try:
                reply = self.conn.recv()
            except EOFError:
                # killed from outside (the kernel's OOM killer, kill -9)
                raise limits.LimitExceeded(
                    limits.current().describe("memory"),
                    where,
                    f"the clingo worker of {self.what} died",
                ) from None
        except BaseException:
            self.close()
            raise
        if reply[0] == "ok":
            return reply[1]
        self.close()
        if reply[0] == "limit":
            _, limit, stage, detail = reply
            detail = "; ".join(x for x in (detail, f"grounding {self.what}") if x)
            raise limits.LimitExceeded(limits.current().describe(limit), stage, detail)
        _, kind, message = reply
        raise _ERRORS.get(kind, OntologyError)(message)

    def call(self, method: str, *args: object) -> object:
        if not self._finalizer.alive:
            raise OntologyError(f"the reasoner of {self.what} was stopped")
        with limits.stage("solve"):
            self.conn.send((method, args))
            return self.result("solve")


#: killed workers not reaped yet (reaped without waiting at the next kill)
_UNREAPED: list[int] = []


def _kill(pid: int, conn: Connection, owner: int) -> None:
    with contextlib.suppress(OSError):
        conn.close()
    if os.getpid() != owner:  # a forked copy of the owner (a pool worker): not ours to kill
        return
    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGKILL)
    _UNREAPED.append(pid)
    for p in list(_UNREAPED):  # a killed process takes a few ms to go: do not wait for it
        with contextlib.suppress(ChildProcessError):
            if os.waitpid(p, os.WNOHANG)[0] == 0:
                continue
        _UNREAPED.remove(p)


class Reasoner:
    """Grounds once; :meth:`solve` and :meth:`satisfiable` re-solve under new externals.

    The clingo Control lives in a forked worker process, so that Ctrl-C and the limits of
    :mod:`synth.limits` stop grounding too (clingo's grounder does not return to Python
    until it is done): the worker is killed, this raises KeyboardInterrupt or
    LimitExceeded. The worker's memory is capped (``RLIMIT_AS``) by the memory limit."""

    def __init__(
        self,
        kb: KnowledgeBase,
        rules: Sequence[str | Path] = (),
        allow_scripts: bool = False,
        focus: str | None = None,
        bus_limit: int | None | Callable[[], int | None] = None,
        while_grounding: Callable[[Callable[[], bool]], object] | None = None,
        first: Query | None | Callable[[], Query] = None,
    ) -> None:
        """Ground ``kb`` with the encodings and ``rules``. With ``focus`` (a robot class),
        the program describes that class instead of choosing among candidates. With
        ``bus_limit`` (the catalog bus's module limit, ``Bus.module_limit``), that is a
        robot's active module limit instead of the ontology's ``activeModuleLimit``; given
        as a function (parsing a catalog), it is called here while the worker filters the
        ontology, and sent to it before it grounds. ``while_grounding`` is called on this
        thread once the worker has what it needs, before this process waits for it (to do
        work of its own meanwhile), with a function that tells whether the worker has
        replied; Ctrl-C or the time limit inside it stops the worker as a wait would.
        ``first``: the query expected first (a command's request), grounded with its
        externals as facts where that is quicker (``_Core``); any query may come. Given as
        a function, it is called and sent as ``bus_limit`` is (after it)."""
        self.kb = kb
        self._rules, self._allow_scripts = tuple(rules), allow_scripts
        files = read_rule_files(self._rules, allow_scripts)
        size = limits.current().size_atoms
        what = " + ".join(["the knowledge base", *(f.name for f in files)])
        deferred = callable(bus_limit)
        later = callable(first)
        expected = None if first is None or later else frozenset(self._texts(first))  # type: ignore[arg-type]
        self._worker = _Worker(
            lambda conn: _Core(
                kb,
                files,
                focus,
                size,
                conn.recv if deferred else bus_limit,
                conn.recv if later else expected,
            ),
            what,
        )
        try:
            sends = []
            if deferred:
                bus_limit = bus_limit()  # type: ignore[operator]
                sends.append(bus_limit)
            if later:
                sends.append(frozenset(self._texts(first())))  # type: ignore[operator]
        except BaseException:
            self._worker.close()
            raise
        for value in sends:
            with contextlib.suppress(OSError):  # a worker that died says why below
                self._worker.conn.send(value)
        self._bus_limit = bus_limit
        with limits.stage("ground"):
            try:
                if while_grounding is not None:
                    try:
                        while_grounding(self._worker.conn.poll)
                    except BaseException:
                        self._worker.close()
                        raise
                externals = self._worker.result("ground")
            except limits.LimitExceeded as e:  # name the files and the rule that grew
                raise _explained(e, kb, files, what, focus) from None
        self._externals: set[str] = externals  # as text: symbols do not cross processes
        self._robot_types: tuple[str, ...] | None = None

    @property
    def robot_types(self) -> tuple[str, ...]:
        """Every subclass of Robot, as the taxonomy closure found them (asked once)."""
        if self._robot_types is None:
            self._robot_types = self._worker.call("robot_types")
        return self._robot_types

    def close(self) -> None:
        """Stop the worker (also done when the Reasoner is collected)."""
        self._worker.close()

    def focused(self, robot_type: str) -> Reasoner:
        """A reasoner over the same program that describes ``robot_type`` (explain)."""
        return Reasoner(
            self.kb, self._rules, self._allow_scripts, focus=robot_type, bus_limit=self._bus_limit
        )

    def unlimited(self) -> Reasoner:
        """A reasoner over the same program with no active module limit (a bus of 2^30):
        which robots a request's refusal owes to the limit alone."""
        return Reasoner(self.kb, self._rules, self._allow_scripts, bus_limit=2**30)

    def _on(self, query: Query) -> set[str]:
        text = self._texts(query)
        missing = text - self._externals
        if missing:
            raise InputError("not known to the knowledge base: " + ", ".join(sorted(missing)))
        return text

    @staticmethod
    def _texts(query: Query) -> set[str]:
        """The externals ``query`` sets, as text."""
        on: set[clingo.Symbol] = set()
        S, F = clingo.String, clingo.Function
        for a in query.requests:
            on.add(F("request", [S(a)]))
        for a, yes in query.answers:
            on.add(F("answer", [S(a), F("yes" if yes else "no")]))
        for rel, term in query.params:
            on.add(F("param", [S(rel), S(term)]))
        return {str(x) for x in on}

    def satisfiable(self, query: Query) -> bool:
        """True when at least one candidate meets ``query`` (stops at the first model)."""
        return self._worker.call("satisfiable", self._on(query))

    def answer_sets(
        self, query: Query, predicates: Iterable[str] | None = None
    ) -> frozenset[frozenset[str]]:
        """The shown atoms of every answer set (as text), optionally only ``predicates``."""
        keep = set(predicates) if predicates is not None else None
        return self._worker.call("answer_sets", self._on(query), keep)

    def solve(self, query: Query) -> Solution:
        """Every candidate of ``query``, in preference order: the cost asp/preference.lp
        gives each answer set (fewest active modules), then the type name."""
        read: dict[str, tuple[Candidate, tuple[int, ...]]] = {}
        needed: set[str] = set()
        excluded: set[str] = set()
        for symbols, cost in self._worker.call("solve", self._on(query)):
            cand, need, excl = self._read(symbols)
            needed |= need
            excluded |= excl
            if cand is not None:
                read[cand.robot_type] = (cand, cost)
        demanded = tuple(sorted(needed))
        found = {t: replace(c, preference=cost, needed=demanded) for t, (c, cost) in read.items()}
        order = sorted(found.values(), key=lambda c: (c.preference, c.robot_type))
        return Solution(
            tuple(order), tuple(sorted(needed)), tuple(sorted(excluded)), satisfiable=bool(order)
        )

    @staticmethod
    def _read(symbols: Iterable[tuple[str, tuple]]) -> tuple[Candidate | None, set, set]:
        by: dict[str, list[list]] = {}
        for name, args in symbols:
            by.setdefault(name, []).append(list(args))
        need = {a[0] for a in by.get("need", [])}
        excl = {a[0] for a in by.get("excluded", [])}
        robots = [a[0] for a in by.get("chosen", [])]
        if not robots:
            # focus mode: the described robot is the one with parts
            robots = sorted({a[0] for a in by.get("structural", []) + by.get("active", [])})
        if not robots:
            return None, need, excl
        r = robots[0]

        def triples(name: str) -> tuple[tuple[str, int], ...]:
            return tuple(sorted((k, n) for rr, k, n in by.get(name, []) if rr == r and n > 0))

        def single(name: str) -> int | None:
            vals = [a[1] for a in by.get(name, []) if a[0] == r]
            return vals[0] if vals else None

        sources: dict[tuple[str, int], list[int]] = {}
        for rr, k, n, i in by.get("source", []):
            if rr == r:
                sources.setdefault((k, n), []).append(i)
        cand = Candidate(
            robot_type=r,
            active_total=sum(n for rr, _, n in by.get("active", []) if rr == r),
            dof=sum(n for rr, _, n in by.get("actuator", []) if rr == r),
            parts=triples("structural"),
            modules=triples("active"),
            passive=triples("passive"),
            abilities=tuple(sorted(a for rr, a in by.get("has_ability", []) if rr == r)),
            potential=tuple(sorted(a for rr, a in by.get("potential", []) if rr == r)),
            reasons=tuple(
                sorted(Reason(a, k, n, s) for rr, a, k, n, s in by.get("reason", []) if rr == r)
            ),
            sources=tuple(
                PartSource(k, n, tuple(sorted(ids))) for (k, n), ids in sorted(sources.items())
            ),
            module_limit=single("limit"),
            hierarchy=max((d for rr, d in by.get("level", []) if rr == r), default=1),
            declared=tuple(sorted(a for rr, a in by.get("declared", []) if rr == r)),
            ancestors=tuple(sorted(c for rr, c in by.get("ancestor", []) if rr == r)),
        )
        return cand, need, excl


def _explained(e: limits.LimitExceeded, kb, rules: Sequence, what: str, focus: str | None):
    """``e`` (a LimitExceeded of the grounding) with the files grounded and, for a time or
    memory limit, the rule that grew (``synth.reasoning.ground_probe.culprit``, given the program as
    ``_Core`` grounds it, the encodings and the parser; the size limit names its own)."""
    if e.stage != "ground" or not e.limit.startswith(("time", "memory")):
        return e
    limits.disarm()  # the time limit's alarm rings again until the run ends: not here
    detail = [x for x in (e.detail,) if x]
    if what not in e.detail:
        detail.append(f"grounding {what}")
    extra = [f"focus({asp_string(focus)})."] if focus is not None else []
    try:
        texts = [r.text for r in rules]
        program = relevant(kb, focus, texts).program(kb.translation)  # as _Core grounds it
        program, taxonomy = taxonomy_program(kb, extra, texts, program)
        found = ground_probe.culprit(
            kb,
            taxonomy,
            rules,
            limits.current().memory_mb,
            conceptual_text(),
            _parse,
            program=program,
        )
    except (OSError, RuntimeError, MemoryError):
        found = ""
    if found:
        detail.append(f"{found} grew (the grounding probed one statement at a time)")
    return limits.LimitExceeded(e.limit, e.stage, "; ".join(detail))
