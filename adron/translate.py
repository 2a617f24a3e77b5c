"""SUO-KIF -> ASP translation, generic over axiom patterns (never per robot type).

Every atomic formula ``(R t1 ... tn)`` becomes the ASP atom ``holds("R", T1, ..., Tn)``:
relation and constant names are ASP strings, KIF variables ``?X`` become ASP variables
``V_X``, numbers stay numbers (decimals become strings), and nested function terms
``(F a b)`` become ``fn("F", A, B)``. The patterns translated:

* ground atoms -> facts (``subclass``, ``instance``, ``subrelation``, ``domain`` ...);
* ``(=> (instance ?X C) (exists (?v ...) (and L ...)))`` -> an *existential axiom*:
  ``exists_axiom(I, "C")``, one ``witness(I, "?v", "K")`` per ``(instance ?v K)`` and one
  ``link(I, "R", A, B)`` per binary literal, where A and B are ``self`` (for ?X), the
  witness name, or ``c("Const")``. Each existential variable is a distinct individual
  (the unique-witness reading the paper's axioms rely on); ``(not (equal ?a ?b))``
  between witnesses agrees with that and is accepted. The ASP encodings turn these into
  part counts and structural requirements (``asp/parts.lp``, ``asp/capability.lp``);
* Horn-like ``(=> body head)`` and ``(<=> a b)`` without quantifiers -> ASP rules. A
  ``(not A)`` in a body is read as default negation (closed world); ``(equal a b)`` in a
  body is ASP equality. Head variables must occur in a positive body atom.
* ``documentation``, ``comment``, ``termFormat``, ``format`` -> metadata kept for ``explain``,
  not sent to the solver.

Anything else is reported as :class:`Untranslated` with its location, never dropped
silently. The output depends only on the forms and their order.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field

from adron.kif import Form, RowVar, String, Symbol, Var

LOGICAL = frozenset({"and", "or", "not", "=>", "<=>", "exists", "forall"})
METADATA = frozenset({"documentation", "comment", "termFormat", "format"})
_IDENT = re.compile(r"[^A-Za-z0-9_]")


class _Skip(Exception):
    """Raised inside the translator when a form has no ASP reading; carries the reason."""


@dataclass(frozen=True, slots=True)
class Untranslated:
    """A form the translator could not express in ASP."""

    file: str
    line: int
    col: int
    reason: str
    text: str

    @property
    def location(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


@dataclass(frozen=True, slots=True)
class AxiomSource:
    """Where existential axiom ``id`` came from, and the class it quantifies over."""

    id: int
    cls: str
    file: str
    line: int
    col: int

    @property
    def location(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


#: an argument of an atom as relevance sees it: ("v", name) a variable, ("c", name) a
#: constant (relation or class name, string), ("f", "?A ?B") a function term and the
#: variables inside it, ("o", text) a number
Arg = tuple[str, str]


@dataclass(frozen=True, slots=True)
class Unit:
    """One translated form as the relevance filter (adron/relevance.py) sees it: its ASP
    ``lines``, its kind ("fact", "rule", "axiom"), where it is, and its shape.

    A fact: ``relation`` and ``args`` (constants, numbers as text). An axiom: ``relation``
    is the class it quantifies over, ``args`` its witness classes, link relations and
    constants. A rule: ``heads`` and ``body`` atoms as (relation, args); body atoms carry
    a leading "+" or "-" (default negation) in their relation slot's ``polarity``."""

    kind: str
    lines: tuple[str, ...]
    where: str
    relation: str = ""
    args: tuple[str, ...] = ()
    names: tuple[str, ...] = ()  # a fact's constants, inside function terms too
    heads: tuple[tuple[str, tuple[Arg, ...]], ...] = ()
    body: tuple[tuple[bool, str, tuple[Arg, ...]], ...] = ()


_UNIT_FIELDS = ("kind", "lines", "where", "relation", "args", "names", "heads", "body")
_UNIT_SETTERS = tuple(Unit.__dict__[name].__set__ for name in _UNIT_FIELDS)


def fact_unit(lines: tuple[str, ...], where: str, relation: str, args: tuple[str, ...]) -> Unit:
    """``Unit("fact", lines, where, relation, args, args)``, built through the slots'
    descriptors (about half the cost of the frozen dataclass's ``__init__``, which goes
    through ``object.__setattr__`` per field: 100,000 facts are built per large ontology)."""
    unit = object.__new__(Unit)
    values = ("fact", lines, where, relation, args, args, (), ())
    for setter, value in zip(_UNIT_SETTERS, values, strict=True):
        setter(unit, value)
    return unit


class _Quoted(dict):
    """Name -> :func:`asp_string` of it, worked out once per name."""

    def __missing__(self, name: str) -> str:
        text = self[name] = asp_string(name)
        return text


class LazyUnits(Sequence[Unit]):
    """A translation's units as plain tuples, turned into :class:`Unit` objects on first
    use: what a cached knowledge base (adron/kb.py) holds, since unpickling 20,000 frozen
    dataclasses costs ~0.5 s and a cached relevance result (synth/reasoning/solver.py) needs
    none."""

    def __init__(self, rows: tuple[tuple, ...]) -> None:
        self._rows = rows
        self._units: tuple[Unit, ...] | None = None

    def _all(self) -> tuple[Unit, ...]:
        if self._units is None:
            self._units = tuple(Unit(*r) for r in self._rows)
        return self._units

    def __len__(self) -> int:
        return len(self._rows)

    def __getitem__(self, i):  # type: ignore[override]
        return self._all()[i]

    def __iter__(self) -> Iterator[Unit]:
        return iter(self._all())

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (tuple, LazyUnits)):
            return tuple(self) == tuple(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __reduce__(self) -> tuple:
        return (LazyUnits, (self._rows,))


def unit_rows(units: Iterable[Unit], memo: dict[int, tuple]) -> LazyUnits:
    """``units`` as :class:`LazyUnits` for pickling; ``memo`` shares the rows of units two
    translations share (a materialised one keeps the facts of its source)."""
    if isinstance(units, LazyUnits) and units._units is None:
        return units
    rows = []
    for u in units:
        r = memo.get(id(u))
        if r is None:
            r = memo[id(u)] = tuple(getattr(u, f) for f in _UNIT_FIELDS)
        rows.append(r)
    return LazyUnits(tuple(rows))


@dataclass(frozen=True)
class Translation:
    """The ASP program of a set of KIF forms and an account of what was translated.

    ``facts``, ``rules``, ``axioms`` and ``metadata`` count *forms* (a ``<=>`` form is one
    rule form that yields two ASP rules), so ``translated + len(untranslated) == forms``.
    """

    program: str
    forms: int
    facts: int
    rules: int
    axioms: int
    metadata: int
    untranslated: tuple[Untranslated, ...]
    sources: tuple[AxiomSource, ...]
    documentation: dict[str, str] = field(default_factory=dict)
    ground: dict[str, tuple[tuple, ...]] = field(default_factory=dict)
    ground_at: dict[str, tuple[str, ...]] = field(default_factory=dict)  # file:line:col
    #: every translated form but metadata, in program order (a tuple, or LazyUnits when read
    #: from the cache)
    units: Sequence[Unit] = ()
    #: file -> (forms, facts, rules, axioms, metadata) of its forms (the counts above, by file)
    by_file: dict[str, tuple[int, int, int, int, int]] = field(default_factory=dict)

    @property
    def translated(self) -> int:
        return self.facts + self.rules + self.axioms + self.metadata

    def relation(self, name: str) -> tuple[tuple, ...]:
        """The argument tuples of every ground fact of relation ``name``, in file order."""
        return self.ground.get(name, ())

    def located(self, name: str) -> tuple[tuple[tuple, str], ...]:
        """(arguments, "file:line:col") of every ground fact of relation ``name``."""
        return tuple(zip(self.ground.get(name, ()), self.ground_at.get(name, ()), strict=True))


def asp_string(text: str) -> str:
    """Quote ``text`` as an ASP string constant."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{escaped}"'


def _asp_var(v: str) -> str:
    """An injective ASP variable name for a KIF variable: ``?X-1`` -> ``V_X_2d_1``,
    ``?X_1`` -> ``V_X__1`` (``_`` doubles; any other character ASP does not allow becomes
    its code point in hex between two ``_``)."""
    body = v[1:].replace("_", "__")
    return "V_" + _IDENT.sub(lambda m: f"_{ord(m.group()):x}_", body)


def _comment(text: str) -> str:
    """Text safe inside an ASP line comment (no line breaks)."""
    return "".join(c if c.isprintable() else "?" for c in text)


def _term(t: object) -> str:
    """An argument position: constant, variable, number or function term."""
    if isinstance(t, Var):
        return _asp_var(t)
    if isinstance(t, RowVar):
        raise _Skip(f"row variable {t}")
    if isinstance(t, (Symbol, String)):
        return asp_string(str(t))
    if isinstance(t, bool):
        raise _Skip("boolean")
    if isinstance(t, int):
        return str(t)
    if isinstance(t, float):
        return asp_string(repr(t))
    if isinstance(t, Form):
        head = t.items[0] if t.items else None
        if not isinstance(head, Symbol) or head in LOGICAL:
            raise _Skip("formula in argument position")
        return "fn(" + ",".join([asp_string(head), *(_term(a) for a in t.items[1:])]) + ")"
    raise _Skip(f"unsupported term {t!r}")


def _atom(f: object) -> str:
    """A relational atom ``(R args...)`` as ``holds("R", ...)``."""
    if not isinstance(f, Form) or not f.items:
        raise _Skip("expected an atomic formula")
    head = f.items[0]
    if isinstance(head, Var):
        raise _Skip("variable in predicate position")
    if not isinstance(head, Symbol) or head in LOGICAL:
        raise _Skip(f"{head} is not a relation")
    if head == "equal":
        raise _Skip("equality as a conclusion")
    if len(f.items) < 2:
        raise _Skip("relation without arguments")
    return "holds(" + ",".join([asp_string(head), *(_term(a) for a in f.items[1:])]) + ")"


def _vars(f: object) -> set[str]:
    if isinstance(f, Var):
        return {str(f)}
    if isinstance(f, Form):
        out: set[str] = set()
        for item in f.items:
            out |= _vars(item)
        return out
    return set()


def _has_vars(f: object) -> bool:
    if isinstance(f, (Var, RowVar)):
        return True
    return isinstance(f, Form) and any(_has_vars(i) for i in f.items)


def _op(f: object) -> str | None:
    if isinstance(f, Form) and f.items and isinstance(f.items[0], Symbol):
        return str(f.items[0])
    return None


def _conjuncts(f: object) -> list[object]:
    return list(f.items[1:]) if _op(f) == "and" else [f]


def _body(f: object) -> tuple[list[str], set[str], set[str]]:
    """Body literals, variables bound by positive atoms, variables needing binding."""
    lits: list[str] = []
    bound: set[str] = set()
    needs: set[str] = set()
    for c in _conjuncts(f):
        op = _op(c)
        if op == "not":
            if len(c.items) != 2:
                raise _Skip("malformed not")
            inner = c.items[1]
            if _op(inner) == "equal" and len(inner.items) == 3:
                lits.append(f"{_term(inner.items[1])} != {_term(inner.items[2])}")
            else:
                lits.append("not " + _atom(inner))
            needs |= _vars(inner)
        elif op == "equal":
            if len(c.items) != 3:
                raise _Skip("malformed equal")
            lits.append(f"{_term(c.items[1])} = {_term(c.items[2])}")
            needs |= _vars(c)
        elif op in LOGICAL:
            raise _Skip(f"'{op}' in a rule body")
        else:
            lits.append(_atom(c))
            bound |= _vars(c)
    return lits, bound, needs


def _shape_arg(t: object) -> Arg:
    if isinstance(t, Var):
        return ("v", str(t))
    if isinstance(t, (Symbol, String)):
        return ("c", str(t))
    if isinstance(t, Form):  # a function term: the variables inside it | its constants
        return ("f", " ".join(sorted(_vars(t))) + "|" + " ".join(_constants(t)))
    return ("o", str(t))


def _shape(f: object) -> tuple[str, tuple[Arg, ...]]:
    return str(f.items[0]), tuple(_shape_arg(a) for a in f.items[1:])


def _rule_shape(body: object, head: object) -> tuple[tuple, tuple]:
    """(heads, body) of a Horn-like ``(=> body head)`` for the relevance filter; equality
    literals are left out (they bind nothing the filter follows)."""
    heads = tuple(_shape(h) for h in _conjuncts(head))
    lits = []
    for c in _conjuncts(body):
        op = _op(c)
        if op == "not":
            inner = c.items[1]
            if _op(inner) != "equal":
                lits.append((False, *_shape(inner)))
        elif op != "equal":
            lits.append((True, *_shape(c)))
    return heads, tuple(lits)


def _constants(f: object) -> tuple[str, ...]:
    """Every constant (Symbol or String) inside ``f``, in order."""
    if isinstance(f, (Symbol, String)):
        return (str(f),)
    if isinstance(f, Form):
        return tuple(c for i in f.items for c in _constants(i))
    return ()


def _horn(body: object, head: object) -> list[str]:
    """ASP rules for ``(=> body head)``; raises _Skip when it is not Horn-like."""
    lits, bound, needs = _body(body)
    rules = []
    for h in _conjuncts(head):
        op = _op(h)
        if op in LOGICAL:
            raise _Skip(f"'{op}' in a rule head")
        atom = _atom(h)
        unsafe = sorted((_vars(h) | needs) - bound)
        if unsafe:
            raise _Skip(f"unsafe variable {unsafe[0]} (not bound by a positive body atom)")
        rules.append(f"{atom} :- {', '.join(lits)}.")
    return rules


def _witness_pair(lit: object) -> bool:
    """True for ``(not (equal ?a ?b))``, also in the paper's ``(not (equal (?a ?b)))`` form."""
    if _op(lit) != "not" or len(lit.items) != 2 or _op(lit.items[1]) != "equal":
        return False
    args = lit.items[1].items[1:]
    if len(args) == 1 and isinstance(args[0], Form):
        args = args[0].items
    return len(args) == 2 and all(isinstance(a, Var) for a in args)


def _existential(axiom_id: int, f: Form) -> list[str] | None:
    """Facts for ``(=> (instance ?X C) (exists (...) ...))``; None if not that pattern."""
    if len(f.items) != 3 or _op(f) != "=>":
        return None
    ante, cons = f.items[1], f.items[2]
    if not (
        _op(ante) == "instance"
        and len(ante.items) == 3
        and isinstance(ante.items[1], Var)
        and isinstance(ante.items[2], Symbol)
        and _op(cons) == "exists"
        and len(cons.items) == 3
        and isinstance(cons.items[1], Form)
    ):
        return None
    this, cls = str(ante.items[1]), str(ante.items[2])
    names = cons.items[1].items
    if not all(isinstance(v, Var) for v in names):
        raise _Skip("exists over something other than variables")
    witnesses = [str(v) for v in names]
    if this in witnesses:
        raise _Skip(f"{this} is both universal and existential")

    def ref(t: object) -> str:
        if isinstance(t, Var):
            if str(t) == this:
                return "self"
            if str(t) in witnesses:
                return asp_string(str(t))
            raise _Skip(f"free variable {t}")
        if isinstance(t, Symbol):
            return f"c({asp_string(str(t))})"
        raise _Skip(f"unsupported argument {t!r} in an existential axiom")

    out = [f"exists_axiom({axiom_id},{asp_string(cls)})."]
    typed: set[str] = set()
    links: list[str] = []
    for lit in _conjuncts(cons.items[2]):
        if _witness_pair(lit):
            continue
        op = _op(lit)
        if op is None or op in LOGICAL or op == "equal" or len(lit.items) != 3:
            raise _Skip(f"literal {_short(lit)} in an existential axiom")
        a, b = lit.items[1], lit.items[2]
        if op == "instance" and isinstance(a, Var) and str(a) in witnesses:
            if not isinstance(b, Symbol):
                raise _Skip("instance of a non-constant class")
            out.append(f"witness({axiom_id},{asp_string(str(a))},{asp_string(str(b))}).")
            typed.add(str(a))
        else:
            links.append(f"link({axiom_id},{asp_string(op)},{ref(a)},{ref(b)}).")
    for w in witnesses:
        if w not in typed:
            out.append(f'witness({axiom_id},{asp_string(w)},"Entity").')
    return out + links


def _short(f: object, width: int = 72) -> str:
    text = f.to_text() if isinstance(f, Form) else str(f)
    return text if len(text) <= width else text[: width - 3] + "..."


def translate(forms: Iterable[Form]) -> Translation:
    """Translate KIF forms (in order) into one ASP program and an account of it."""
    lines: list[str] = []
    untranslated: list[Untranslated] = []
    sources: list[AxiomSource] = []
    docs: dict[str, str] = {}
    ground: dict[str, list[tuple]] = {}
    ground_at: dict[str, list[str]] = {}
    units: list[Unit] = []
    n_forms = n_facts = n_rules = n_axioms = n_meta = 0
    by_file: dict[str, tuple[int, ...]] = {}
    current, opened = None, (0, 0, 0, 0, 0)
    quoted = _Quoted().__getitem__  # each name quoted once (a relation's name 100,000 times)

    def close() -> None:  # the counts since ``opened`` go to ``current``'s file
        now = (n_forms, n_facts, n_rules, n_axioms, n_meta)
        had = by_file.get(current, (0, 0, 0, 0, 0))
        by_file[current] = tuple(h + n - o for h, n, o in zip(had, now, opened, strict=True))

    for f in forms:
        if f.file != current:
            if current is not None:
                close()
            current, opened = f.file, (n_forms, n_facts, n_rules, n_axioms, n_meta)
        n_forms += 1
        op = _op(f)
        where = f"{f.file}:{f.line}:{f.col}"
        try:
            if op in METADATA:
                n_meta += 1
                if op == "documentation" and len(f.items) >= 4:
                    docs.setdefault(str(f.items[1]), str(f.items[3]))
                continue
            if op in ("=>", "<=>"):
                if len(f.items) != 3:
                    raise _Skip(f"'{op}' needs two arguments")
                if op == "=>":
                    facts = _existential(n_axioms + 1, f)
                    if facts is not None:
                        n_axioms += 1
                        cls = str(f.items[1].items[2])
                        sources.append(AxiomSource(n_axioms, cls, f.file, f.line, f.col))
                        chunk = [f"% {_comment(f.file)}:{f.line}", *facts]
                        lines.extend(chunk)
                        names = _constants(f.items[2].items[2])
                        units.append(Unit("axiom", tuple(chunk), where, cls, names))
                        continue
                    rules = _horn(f.items[1], f.items[2])
                    shapes = [_rule_shape(f.items[1], f.items[2])]
                else:
                    rules = _horn(f.items[1], f.items[2]) + _horn(f.items[2], f.items[1])
                    shapes = [
                        _rule_shape(f.items[1], f.items[2]),
                        _rule_shape(f.items[2], f.items[1]),
                    ]
                lines.extend(rules)
                n_rules += 1
                start = 0
                for heads, body in shapes:
                    units.append(
                        Unit(
                            "rule",
                            tuple(rules[start : start + len(heads)]),
                            where,
                            heads=heads,
                            body=body,
                        )
                    )
                    start += len(heads)
                continue
            if op in LOGICAL:
                raise _Skip(f"top-level '{op}'")
            items = f.items
            if len(items) >= 2 and items[0] != "equal" and all(type(a) is Symbol for a in items):
                # the common case (subclass, instance ...): names only, quoted directly
                args = tuple(map(str, items[1:]))
                rel = str(items[0])
                line = "holds(" + ",".join(map(quoted, items)) + ")."
                lines.append(line)
                units.append(fact_unit((line,), where, rel, args))
                ground.setdefault(rel, []).append(args)
                ground_at.setdefault(rel, []).append(where)
                n_facts += 1
                continue
            if _has_vars(f):
                raise _Skip("free variables in a top-level fact")
            line = _atom(f) + "."
            lines.append(line)
            shown = tuple(a.to_text() if isinstance(a, Form) else str(a) for a in f.items[1:])
            names = _constants(Form(tuple(f.items[1:]), f.file, f.line, f.col))
            units.append(Unit("fact", (line,), where, str(f.items[0]), shown, names))
            ground.setdefault(str(f.items[0]), []).append(
                tuple(a if isinstance(a, (int, float)) else str(a) for a in f.items[1:])
            )
            ground_at.setdefault(str(f.items[0]), []).append(where)
            n_facts += 1
        except _Skip as why:
            untranslated.append(Untranslated(f.file, f.line, f.col, str(why), _short(f)))
    if current is not None:
        close()

    return Translation(
        program="\n".join(lines) + "\n",
        forms=n_forms,
        facts=n_facts,
        rules=n_rules,
        axioms=n_axioms,
        metadata=n_meta,
        untranslated=tuple(untranslated),
        sources=tuple(sources),
        documentation=docs,
        ground={k: tuple(v) for k, v in ground.items()},
        ground_at={k: tuple(v) for k, v in ground_at.items()},
        units=tuple(units),
        by_file=by_file,
    )


# -- the taxonomy closure, computed once in Python ----------------------------------------

_STR = r'"(?:[^"\\]|\\.)*"'
_TERM = rf"(?:{_STR}|-?\d+)"
_EDGE = re.compile(rf'^holds\("(subclass|subrelation)",({_TERM}),({_TERM})\)\.$')
_EDGE_LINE = re.compile(rf'^holds\("(subclass|subrelation)",({_TERM}),({_TERM})\)\.$\n?', re.M)
_TAXO_PREFIXES = ('holds("subclass",', 'holds("subrelation",')
_TAXO_WHOLE_LINE = re.compile(r'^holds\("sub(?:class|relation)",.*(?:\n|$)', re.M)
_LITERAL = re.compile(_STR)
_TAXO_HEAD = re.compile(r'holds\("sub(?:class|relation)"')
_READS_UP = re.compile(rf'holds\("(?:subclass|instance)",(?:{_STR}|[A-Z_]\w*|-?\d+),[A-Z_]\w*\)')
_ENUMERATED = re.compile(
    rf'(?:\bisa\(\s*[A-Z_]\w*\s*,\s*|holds\(\s*"subclass"\s*,\s*[A-Z_]\w*\s*,\s*)({_STR})\s*\)'
)
_TAXO_FREE = re.compile(r'holds\("sub(?:class|relation)",V_\w+,V_\w+\)')
#: what a user's rule file may not mention for the Python closure to be exact: it could
#: derive new taxonomy facts or read pairs between classes that nothing else names
_TAXO_USER = re.compile(r'"sub(?:class|relation)"|\b(?:isa|rel_isa|class|relation)\s*\(')


def taxonomy_closure(
    program: str, others: Iterable[str] = (), user: Iterable[str] = ()
) -> str | None:
    """The transitive ``subclass`` and ``subrelation`` pairs ``program`` needs, as ASP
    facts, or None (:func:`closed_taxonomy`'s facts)."""
    found = closed_taxonomy(program, others, user)
    return None if found is None else found[1]


def closed_taxonomy(
    program: str, others: Iterable[str] = (), user: Iterable[str] = ()
) -> tuple[str, str] | None:
    """``program`` without the direct taxonomy edges nothing can ask for, and the
    transitive ``subclass`` and ``subrelation`` pairs a program needs, as ASP facts,
    or None when only the recursive rules of ``asp/closure.lp`` give exact answers.

    Recursive ASP over every pair explodes on deep taxonomies (a chain of n classes has
    n^2/2 pairs: 5e9 for n = 100,000). The encodings only ever ask ``isa(C, D)`` with C or
    D a class that the program names outside the subclass facts (an *anchor*: a robot
    type, a part kind, "Robot", a catalog class...), so this gives, for each anchor, the
    pairs to its ancestors and from its descendants (the direct edges are in ``program``):
    linear in the hierarchy's size for a fixed set of anchors. ``program`` is
    the KIF translation; ``others`` the rest of the program's text (encodings, facts);
    ``user`` the user's rule files. None (exact fallback) when a translated rule derives
    taxonomy facts or reads them with both arguments free, or a user rule file mentions
    the taxonomy at all, or an edge is not between plain names.

    Every pair with an anchor at either end is among the facts, so a direct edge between
    two classes that are not anchors is one nothing can ask for (the same argument as
    above): the returned program leaves those out, and the facts name as ``class/1`` only
    the anchors among the classes of the subclass facts (asp/taxonomy.lp: ``isa(C, C)``;
    asp/closure.lp derives it for every class). On a 100,000-class chain under ``Robot``
    that is 300,000 atoms less to parse and ground (about 0.8 s).

    A non-anchor descendant of an anchor D can only be asked about through a rule that
    reads D's descendants by a variable: ``isa(X, "D")`` (the encodings: ``Robot``,
    ``RobotAction``, the module kinds...) or ``holds("subclass", V_X, "D")`` (a translated
    rule; one with both arguments free means the fallback). Every other rule that asks
    ``isa`` binds its first argument from a class something names (the encodings were
    checked for this; tests/adron/test_limits.py compares every design with the recursive
    closure over hierarchies hung below every class). So D's pairs from non-anchor
    descendants are given only for such D: a 100,000-class chain of leg kinds gives
    100,000 pairs instead of one per ancestor of ``RobotLeg``. Likewise upwards: unless a
    translated rule reads a class's ancestors or an instance's classes by a variable
    (``holds("subclass", _, V_Y)``, ``holds("instance", _, V_C)``), an anchor's pairs go
    only to anchors and to the classes such a D's descendants can bind (the encodings'
    ``isa(R, C)`` with C free asks for robot classes, below the enumerated ``Robot``): a
    100,000-class chain above ``Robot`` is not paired with every robot class.
    """
    edges = _EDGE_LINE.findall(program)
    starts = sum(program.startswith(p) + program.count("\n" + p) for p in _TAXO_PREFIXES)
    if len(edges) != starts:
        return None  # a taxonomy fact between other than plain names
    rule_lines = list(_rule_lines(program))
    for line in rule_lines:
        if _EDGE.match(line) is None:
            head = line.split(":-", 1)[0]
            if _TAXO_HEAD.search(head) or _TAXO_FREE.search(line):
                return None
    user = list(user)
    if any(_TAXO_USER.search(text) for text in user):
        return None
    up: dict[str, dict[str, list[str]]] = {"subclass": {}, "subrelation": {}}
    down: dict[str, dict[str, list[str]]] = {"subclass": {}, "subrelation": {}}
    for rel, a, b in edges:
        up[rel].setdefault(a, []).append(b)
        down[rel].setdefault(b, []).append(a)
    anchors: set[str] = set()
    for text in [_TAXO_WHOLE_LINE.sub("", program), *others, *user]:  # all are edges
        anchors.update(_LITERAL.findall(text))
    # the classes whose descendants a rule reads through a variable: isa(X, "D") in the
    # encodings, holds("subclass", V_X, "D") in a translated rule
    enumerated: set[str] = set()
    for text in [*rule_lines, *others, *user]:
        enumerated.update(_ENUMERATED.findall(text))
    # unless a translated rule reads a class's ancestors (or an instance's classes) by a
    # variable, an anchor's pairs to ancestors are needed only to anchors and to classes
    # a rule can bind by a variable (the non-anchor descendants of the enumerated ones)
    reads_up = any(_READS_UP.search(line) for line in rule_lines)
    below = {d: _reach(down["subclass"], d) for d in sorted(enumerated & down["subclass"].keys())}
    readable: set[str] = set().union(*below.values()) if not reads_up else set()
    out: list[str] = []
    for rel in ("subclass", "subrelation"):
        for start in sorted(anchors & (up[rel].keys() | down[rel].keys())):
            for forward in (True, False):
                if forward:
                    seen = _reach(up[rel], start)
                    if rel == "subclass" and not reads_up:
                        seen = {x for x in seen if x in anchors or x in readable}
                elif rel == "subclass":  # nothing names the others or reads them freely
                    seen = below[start] - anchors if start in below else set()
                else:  # pairs between anchors came with the lower one's ancestors
                    seen = _reach(down[rel], start) - anchors
                if seen:  # one fact with a pool: clingo parses it 3x faster than many
                    pool = "(" + ";".join(sorted(seen)) + ")"
                    pair = f"{start},{pool}" if forward else f"{pool},{start}"
                    out.append(f'holds("{rel}",{pair}).')
    out.extend(
        f"class({a})." for a in sorted(anchors & (up["subclass"].keys() | down["subclass"].keys()))
    )
    # in the program's order: the edge lines are the lines that start as one (checked above)
    lines = program.split("\n")
    drop = iter([not (a in anchors or b in anchors) for _rel, a, b in edges])
    kept = "\n".join(ln for ln in lines if not (ln.startswith(_TAXO_PREFIXES) and next(drop)))
    return kept if kept.endswith("\n") or not kept else kept + "\n", "\n".join(out) + "\n"


def _reach(graph: dict[str, list[str]], start: str) -> set[str]:
    """Every name reached from ``start`` along ``graph`` (not ``start`` itself, unless on
    a cycle)."""
    seen: set[str] = set()
    stack = list(graph.get(start, ()))
    while stack:
        x = stack.pop()
        if x not in seen:
            seen.add(x)
            stack.extend(graph.get(x, ()))
    return seen


def _rule_lines(program: str) -> Iterator[str]:
    """The lines of ``program`` with ``:-`` in them (few: found by ``str.find``)."""
    at = program.find(":-")
    while at >= 0:
        start = program.rfind("\n", 0, at) + 1
        end = program.find("\n", at)
        end = len(program) if end < 0 else end
        yield program[start:end]
        at = program.find(":-", end)


_CLASS_DECL = re.compile(rf"^(?:exists_axiom\(\d+,({_STR})\)|witness\(\d+,{_STR},({_STR})\))\.$")


def isa_facts(program: str, classes: Iterable[str], relations: Iterable[str]) -> str | None:
    """``isa(C, D)`` facts for the given ``classes`` (ASP strings: themselves, if they are
    classes, and every ancestor) and the program's ground facts of ``relations``, or None
    when only grounding the whole program with ``asp/taxonomy.lp`` is exact: a translated
    rule derives taxonomy facts or one of ``relations``, or a subrelation of one exists.

    For a program part that asks only these (the actuator assignment), so that a 100,000
    class taxonomy is not grounded again for it."""
    index = IsaIndex.of(program, relations)
    return None if index is None else index.facts(classes)


@dataclass(frozen=True)
class IsaIndex:
    """What :func:`isa_facts` reads of a program, read once (one pass over a 100,000-line
    translation costs ~0.3 s): each class's direct superclasses, the names known to be
    classes, and the facts of the relations asked for."""

    up: dict[str, list[str]]
    known: frozenset[str]
    keep: tuple[str, ...]

    @classmethod
    def of(cls, program: str, relations: Iterable[str]) -> IsaIndex | None:
        """The index of ``program``, or None where :func:`isa_facts` gives None."""
        wanted = {asp_string(r) for r in relations}
        up: dict[str, list[str]] = {}
        known: set[str] = set()
        keep: list[str] = []
        for line in program.splitlines():
            m = _EDGE.match(line)
            if m is not None:
                rel, a, b = m.groups()
                if rel == "subclass":
                    up.setdefault(a, []).append(b)
                    known.update((a, b))
                elif b in wanted:
                    return None
                continue
            if line.startswith(_TAXO_PREFIXES):
                return None
            if ":-" in line:
                head = line.split(":-", 1)[0]
                if _TAXO_HEAD.search(head) or any(f"holds({r}" in head for r in wanted):
                    return None
                continue
            d = _CLASS_DECL.match(line)
            if d is not None:
                known.add(d.group(1) or d.group(2))
            elif any(line.startswith(f"holds({r},") for r in wanted):
                keep.append(line)
        return cls(up, frozenset(known), tuple(keep))

    def facts(self, classes: Iterable[str]) -> str:
        """:func:`isa_facts` of these ``classes``."""
        out = []
        for c in sorted(set(classes)):
            seen = _reach(self.up, c)
            if c in self.known:
                seen.add(c)
            out.extend(f"isa({c},{d})." for d in sorted(seen))
        return "\n".join([*out, *self.keep]) + "\n"
