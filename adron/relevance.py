"""Relevance before grounding: the part of a translated ontology that can reach the robot
vocabulary, so that a large ontology (SUMO, ORA) loaded as it is grounds like a small one.

The *vocabulary* is every string the encodings name (``"Robot"``, ``"RobotAction"``,
``"StructuralRobotPart"``, the module classes, ``"part"``, ``"abilityName"`` ...: the
string literals of ``asp/*.lp``, passed in by the caller) plus a focused class. A relation
the encodings read with a variable first argument and no constant (``abilityName``,
``requiredPartCount``, ``extensiblePart`` ...) is read *wholesale*: all its facts are kept.
Any other relation is *keyed*: the encodings ask about it only for given classes (the
taxonomy relations, whose closure ``asp/taxonomy.lp`` computes, are read this way).

Graph reachability over the translated forms, in three steps:

1. *Relations*: those the encodings name, their subrelations, and the body relations of
   translated rules that derive one of them. A fact of any other relation (``domain``,
   ``disjoint``, ``documentation`` is metadata anyway) and a rule deriving one are
   filtered: no rule reads them.
2. *Reach* (downwards): a class reaches the vocabulary when it is in it, is the first
   argument of a wholesale fact, or is the first argument of a keyed fact whose other
   argument reaches it (``(subclass MyHexapod HexapodRobot)``, ``(instance X
   BaseConfiguration)``, ``(subrelation robotPart part)``): every robot type, action and
   part kind below the vocabulary.
3. *Needed* (upwards): what a reaching class depends on: the other arguments of keyed
   facts about it (its ancestors ...), the witness classes, relations and constants of
   existential axioms over it, transitively. A keyed fact is kept when its first argument
   is needed, an axiom when its class is; the rest is filtered.

Translated rules are kept when they derive a needed relation, and pass what is needed of
their head on to their body (sideways, through shared variables): a body relation is then
needed at the argument positions so bound (its facts are kept when that argument is a
needed name), for the constants the rule names there, or wholesale when nothing binds it.
A rule that could make a class reach the vocabulary where no fact says so (a head
``(subclass ?X Robot)`` fed by another relation) cannot be followed: then nothing is
filtered, and ``Relevance.off`` says which rule -- as when the user gives rule files,
which may read anything. SUMO's Merge.kif has such rules (``(=> (and (subclass ?X ?Y)
(instance ?Z ?X)) (instance ?Z ?Y))`` is followed; its web of temporal and graph rules
makes ``instance`` wholesale). The solver therefore filters ``KnowledgeBase.grounded``:
the translation with every rule that reads only the ontology replaced by the facts it
derives (adron/materialise.py). What remains are facts, axioms and the few rules that
read what the request sets, which this filter follows; Merge + Mid-level then keeps 967
of 18,500 forms.
"""

from __future__ import annotations

import gc
import re
from collections.abc import Iterable
from dataclasses import dataclass, field

from adron.translate import Translation, Unit

#: the reasons a form is filtered, as ``ontology check`` prints them
REASONS = {
    "relation": "a relation no rule reads",
    "class": "about a class that does not reach the robot vocabulary",
    "axiom": "an axiom over a class that does not reach the robot vocabulary",
    "rule": "a rule deriving a relation no rule reads",
}

_COMMENT = re.compile(r'%\*.*?\*%|%[^\n]*|("(?:[^"\\\n]|\\.)*")', re.S)
_LITERAL = re.compile(r'"((?:[^"\\\n]|\\.)*)"')
_WHOLESALE = re.compile(r'holds\(\s*"(\w+)"\s*,\s*([^()]*)\)')


def vocabulary(texts: Iterable[str]) -> set[str]:
    """The string literals of ASP ``texts``, comments left out."""
    out: set[str] = set()
    for text in texts:
        for m in _COMMENT.finditer(text):
            if m.group(1):
                out.add(m.group(1)[1:-1].replace('\\"', '"').replace("\\\\", "\\"))
    return out


def downward(texts: Iterable[str]) -> set[str]:
    """Relations ``texts`` read as ``holds("R", V, ..., "C" ...)``: a variable first argument
    and a constant after it (the subjects of given classes: ``instance`` of
    ``BaseConfiguration``). The taxonomy layer reads its relations so too (``isa(R,
    "Robot")`` asks for every class below Robot)."""
    out: set[str] = set()
    for text in texts:
        plain = _COMMENT.sub(lambda m: m.group(1) or "", text)
        for m in _WHOLESALE.finditer(plain):
            args = [a.strip() for a in m.group(2).split(",")]
            if (args[0][:1].isupper() or args[0] == "_") and any('"' in a for a in args[1:]):
                out.add(m.group(1))
    return out


def wholesale(texts: Iterable[str]) -> set[str]:
    """Relations ``texts`` read as ``holds("R", V, ...)`` with a variable first argument and
    no constant: every fact of them matters."""
    out: set[str] = set()
    for text in texts:
        plain = _COMMENT.sub(lambda m: m.group(1) or "", text)
        for m in _WHOLESALE.finditer(plain):
            args = [a.strip() for a in m.group(2).split(",")]
            if (args[0][:1].isupper() or args[0] == "_") and not any('"' in a for a in args):
                out.add(m.group(1))
    return out


@dataclass(frozen=True)
class Relevance:
    """Which translated forms go to the grounder. ``kept[i]`` is True for ``units[i]``;
    ``reasons[i]`` names why a filtered one is (a key of :data:`REASONS`)."""

    kept: tuple[bool, ...]
    reasons: tuple[str, ...]
    off: str | None = None  # why nothing is filtered, or None
    counts: dict[str, int] = field(default_factory=dict)
    needed: frozenset[str] = frozenset()  # the names the kept forms are about

    def program(self, tr: Translation) -> str:
        """The translated program with the filtered forms left out (order kept)."""
        if self.off is not None or all(self.kept):
            return tr.program
        lines = [ln for u, k in zip(tr.units, self.kept, strict=True) if k for ln in u.lines]
        return "\n".join(lines) + "\n"


def _vs(kind: str, name: str) -> list[str]:
    """The variables of a shape argument (a variable, or those inside a function term)."""
    if kind == "v":
        return [name]
    return name.split("|")[0].split() if kind == "f" else []


def _hit(kind: str, name: str, anchored: set[str]) -> bool:
    """True when a shape argument holds a variable of ``anchored``."""
    return kind in "vf" and bool(set(_vs(kind, name)) & anchored)


def _bindings(
    unit: Unit,
    need: dict[str, set[int]],
    keyc: dict[str, dict[int, set[str]]],
    whole: set[str],
    active: set[str],
    later: set[str],
) -> tuple[dict[str, set[int]], dict[str, dict[int, set[str]]], set[str]]:
    """What rule ``unit`` needs of its body relations when its head relations are needed at
    the positions ``need`` (or wholesale): (relation -> positions whose facts are needed
    when that argument is needed, relation -> position -> the constants it is needed for,
    relations needed wholesale). The binding is passed
    sideways: from a needed head argument through every body atom sharing a variable. A
    constant at a needed head position binds nothing: the rule counts only once the
    constant is needed (in ``active``); until then it is added to ``later``."""
    pos: dict[str, set[int]] = {}
    cons: dict[str, dict[int, set[str]]] = {}
    full: set[str] = set()
    for rel, hargs in unit.heads:
        starts: list[set[str]] = []
        if rel in whole:
            starts.append(set())
        for p, ks in keyc.get(rel, {}).items():
            if p < len(hargs):
                kind, name = hargs[p]
                if kind in "vf":
                    starts.append(set(_vs(kind, name)))
                elif name in ks:
                    starts.append(set())
        for p in sorted(need.get(rel, ())):
            if p < len(hargs):
                kind, name = hargs[p]
                keys = name.split("|")[1].split() if kind == "f" and not _vs(kind, name) else [name]
                constant = kind in "co" or (kind == "f" and not _vs(kind, name))
                if constant and not set(keys) & active:
                    later.update(keys)
                    continue
                starts.append(set(_vs(kind, name)))
        for anchored in starts:
            done: set[int] = set()
            changed = True
            while changed:
                changed = False
                for i, (positive, brel, bargs) in enumerate(unit.body):
                    if i in done or not positive:
                        continue
                    bound = [q for q, (k, n) in enumerate(bargs) if _hit(k, n, anchored)]
                    fixed = [q for q, (k, _n) in enumerate(bargs) if k in "co"]
                    if bound:
                        pos.setdefault(brel, set()).update(bound)
                    else:
                        for q in fixed:
                            cons.setdefault(brel, {}).setdefault(q, set()).add(bargs[q][1])
                    if bound or fixed:
                        done.add(i)
                        for k, n in bargs:
                            anchored.update(_vs(k, n) if k in "vf" else ())
                        changed = True
                if not changed:  # an atom bound by nothing: all its facts are needed
                    for i, (positive, brel, bargs) in enumerate(unit.body):
                        if i not in done and positive:
                            full.add(brel)
                            done.add(i)
                            for k, n in bargs:
                                anchored.update(_vs(k, n) if k in "vf" else ())
                            changed = True
                            break
            for positive, brel, bargs in unit.body:
                if positive:
                    continue
                bound = [q for q, (k, n) in enumerate(bargs) if _hit(k, n, anchored)]
                fixed = [q for q, (k, _n) in enumerate(bargs) if k in "co"]
                if bound:
                    pos.setdefault(brel, set()).update(bound)
                elif fixed:
                    for q in fixed:
                        cons.setdefault(brel, {}).setdefault(q, set()).add(bargs[q][1])
                else:
                    full.add(brel)
    return pos, cons, full


def _reach_unsafe(
    unit: Unit, reach: set[str], whole: set[str], down: set[str], added: list[str]
) -> str | None:
    """Why a rule could make its head's first argument reach the vocabulary where no fact
    says so, or None: every other head argument must be a constant outside the vocabulary
    or a variable bound from the first argument through the body's atoms. A wholesale
    head's first argument reaches it: it must be a constant (added to ``reach``, and to
    ``added`` when new)."""
    for rel, hargs in unit.heads:
        if not hargs or (rel not in whole and rel not in down):
            continue
        kind, name = hargs[0]
        if rel in whole:
            if kind != "c":
                return f"it derives ({rel} {name} ...) for any {name}"
            if name not in reach:
                reach.add(name)
                added.append(name)
            continue
        linked = set(_vs(kind, name)) if kind in "vf" else set()
        changed = True
        while changed:
            changed = False
            for positive, _brel, bargs in unit.body:
                first = bargs[0] if positive and bargs else ("c", "")
                if first[0] in "vf" and set(_vs(*first)) & linked:
                    new = {x for k, n in bargs if k in "vf" for x in _vs(k, n)} - linked
                    if new:
                        linked |= new
                        changed = True
        for k, n in hargs[1:]:
            if k == "c" and n in reach and kind != "c":
                return f"its head ({rel} ...) makes anything reach {n}"
            if k in "vf" and not set(_vs(k, n)) <= linked:
                return f"its head ({rel} ...) takes {n} from outside its first argument"
    return None


def relevance(
    tr: Translation, texts: Iterable[str], taxonomy: Iterable[str] = (), extra: Iterable[str] = ()
) -> Relevance:
    """The forms of ``tr`` that can reach the vocabulary of the ASP ``texts`` (the
    encodings), of ``taxonomy`` (the closure layer: its relations are keyed, not read
    wholesale) and the names in ``extra`` (a focused class)."""
    texts, taxonomy = list(texts), list(taxonomy)
    vocab = vocabulary(texts + taxonomy) | set(extra)
    active: set[str] = set()
    was = gc.isenabled()
    gc.disable()  # 100,000s of short-lived containers, none in a cycle: no collections
    try:
        ix = _Index(tr)  # what every pass reads of the forms, built once
        while True:
            later: set[str] = set()
            down = downward(texts) | {r for r in vocabulary(taxonomy) if r in tr.ground}
            out = _relevance(ix, vocab, wholesale(texts), down, active, later)
            if out.off is not None or not (later & out.needed) - active:
                return out
            active |= later & out.needed
    finally:
        if was:
            gc.enable()


class _Index:
    """A translation's units grouped for the passes of :func:`_relevance`: facts by
    relation, and (made when first asked) the facts of a relation by the name at one
    argument position, each relation's downward links and the names of its facts. A pass
    then visits the facts of the relations it needs, by name, not all the units."""

    def __init__(self, tr: Translation) -> None:
        self.units = tr.units
        self.facts: list[Unit] = []
        self.rules: list[Unit] = []
        self.axioms: dict[str, list[Unit]] = {}
        self.by_rel: dict[str, list[Unit]] = {}
        for u in self.units:
            if u.kind == "fact":
                self.facts.append(u)
                self.by_rel.setdefault(u.relation, []).append(u)
            elif u.kind == "rule":
                self.rules.append(u)
            elif u.kind == "axiom":
                self.axioms.setdefault(u.relation, []).append(u)
        self.subs: dict[str, list[str]] = {}
        for u in self.by_rel.get("subrelation", ()):
            if len(u.args) == 2:
                self.subs.setdefault(u.args[1], []).append(u.args[0])
        self.derived = {h[0] for u in self.rules for h in u.heads} | set(self.by_rel)
        self._at: dict[tuple[str, int], dict[str, list[Unit]]] = {}
        self._by_names: dict[tuple[str, int], dict[str, list[Unit]]] = {}
        self._below: dict[str, dict[str, list[str]]] = {}
        self._names: dict[str, set[str]] = {}
        self._merged: dict[tuple, dict[str, list]] = {}
        self.results: dict[tuple, Relevance] = {}  # by what steps 2 and 3 read

    def at(self, rel: str, p: int) -> dict[str, list[Unit]]:
        """The facts of ``rel`` by their argument ``p`` as written."""
        d = self._at.get((rel, p))
        if d is None:
            d = self._at[(rel, p)] = {}
            for u in self.by_rel.get(rel, ()):
                if p < len(u.args):
                    d.setdefault(u.args[p], []).append(u)
        return d

    def by_name(self, rel: str, p: int) -> dict[str, list[Unit]]:
        """The facts of ``rel`` by the name at argument ``p``, or by each name inside it
        when it is a function term."""
        d = self._by_names.get((rel, p))
        if d is None:
            d = self._by_names[(rel, p)] = {}
            for u in self.by_rel.get(rel, ()):
                if p < len(u.args):
                    if u.args[p].startswith("("):
                        for a in u.names:
                            d.setdefault(a, []).append(u)
                    else:
                        d.setdefault(u.args[p], []).append(u)
        return d

    def below(self, rel: str) -> dict[str, list[str]]:
        """For a downward relation: each name -> the first arguments of the facts that
        link down to it (``(subclass A B)``: B -> [A])."""
        d = self._below.get(rel)
        if d is None:
            d = self._below[rel] = {}
            for u in self.by_rel.get(rel, ()):
                if u.args:
                    for a in u.names[1:] if u.names[:1] == u.args[:1] else u.names:
                        d.setdefault(a, []).append(u.args[0])
        return d

    def merged(self, kinds: tuple[tuple[str, str, int], ...]) -> dict[str, list]:
        """One dict of the lookups ``kinds`` (("below", rel, 0), ("name", rel, p) or
        ("axiom", "", 0)): a pass asks it once per name instead of once per lookup (a
        100,000-class chain has 100,000 names to ask about); kept for the next pass."""
        d = self._merged.get(kinds)
        if d is None:
            get = {"below": lambda r, _p: self.below(r), "name": self.by_name}
            parts = [get[k](r, p) if k in get else self.axioms for k, r, p in kinds]
            if len(parts) == 1:
                d = parts[0]
            else:  # a key in one part shares its list (nothing changes these lists)
                d = {}
                for part in parts:
                    for key, vs in part.items():
                        old = d.get(key)
                        d[key] = vs if old is None else old + vs
            self._merged[kinds] = d
        return d

    def names(self, rel: str) -> set[str]:
        """Every name in the facts of ``rel``."""
        n = self._names.get(rel)
        if n is None:
            n = self._names[rel] = {a for u in self.by_rel.get(rel, ()) for a in u.names}
        return n


def _relevance(
    ix: _Index,
    vocab: set[str],
    whole: set[str],
    down: set[str],
    active: set[str],
    later: set[str],
) -> Relevance:
    rules, subs = ix.rules, ix.subs
    # 1. relations that something reads, and at which argument (binding patterns)
    need: dict[str, set[int]] = {v: {0} for v in vocab}
    derived = ix.derived
    keyc: dict[str, dict[int, set[str]]] = {}

    def size() -> tuple[int, ...]:
        n = sum(len(p) for p in need.values())
        k = sum(len(ks) for d in keyc.values() for ks in d.values())
        return n, k, len(need), len(keyc), len(whole)

    while True:
        before = size()
        for s in list(need) + list(keyc) + list(whole):  # holds(S, X, Y) :- holds(R, X, Y),
            for r in subs.get(s, ()):  # holds("subrelation", R, S)
                need.setdefault(r, set()).update(need.get(s, set()))
                for p, ks in keyc.get(s, {}).items():
                    keyc.setdefault(r, {}).setdefault(p, set()).update(ks)
                if s in whole:
                    whole.add(r)
        for u in rules:
            if any(h[0] in need or h[0] in keyc or h[0] in whole for h in u.heads):
                pos, cons, full = _bindings(u, need, keyc, whole, active, later)
                for r, ps in pos.items():
                    need.setdefault(r, set()).update(ps)
                for r, d in cons.items():
                    for p, ks in d.items():
                        keyc.setdefault(r, {}).setdefault(p, set()).update(ks)
                whole |= full
        if size() == before:
            break
    rels = set(need) | set(keyc) | whole
    whole |= {r for r in rels if r not in derived}  # the parameters: nothing to filter
    # 2. reach, downwards through the facts of downward relations and their subrelations
    todo = list(down)
    while todo:
        for r in subs.get(todo.pop(), ()):
            if r not in down:
                down.add(r)
                todo.append(r)
    # what the rest reads; a later pass that reads the same (its newly active relations
    # changed nothing here) has the same result, worked out once
    key = (
        frozenset((r, frozenset(ps)) for r, ps in need.items()),
        frozenset((r, p, frozenset(ks)) for r, d in keyc.items() for p, ks in d.items()),
        frozenset(whole),
        frozenset(down),
        frozenset(vocab),
    )
    if key in ix.results:
        return ix.results[key]
    out = _reached(ix, vocab, need, keyc, whole, down, rels)
    ix.results[key] = out
    return out


def _reached(
    ix: _Index,
    vocab: set[str],
    need: dict[str, set[int]],
    keyc: dict[str, dict[int, set[str]]],
    whole: set[str],
    down: set[str],
    rels: set[str],
) -> Relevance:
    """Steps 2 and 3 of :func:`_relevance`: what reaches the vocabulary, what it needs."""
    units, rules = ix.units, ix.rules
    reach = set(vocab)
    for r in rels & set(ix.by_rel):
        if r in whole:
            reach.update(u.args[0] for u in ix.by_rel[r] if u.args)
    below = ix.merged(
        tuple(("below", r, 0) for r in sorted(rels & down & set(ix.by_rel)) if r not in whole)
    )

    def spread(todo: list[str]) -> None:  # down the links from what reaches
        while todo:
            for s in below.get(todo.pop(), ()):
                if s not in reach:
                    reach.add(s)
                    todo.append(s)

    spread(list(reach))
    kept_rules = [u for u in rules if any(h[0] in rels for h in u.heads)]
    added: list[str] = []
    for u in kept_rules:
        why = _reach_unsafe(u, reach, whole, down, added)
        if why is not None:
            return Relevance((True,) * len(units), ("",) * len(units), f"{u.where}: {why}")
    spread(added)  # from the constants the wholesale heads added
    # 3. needed, upwards from what reaches
    needed = set(reach)
    for r in whole:
        if r in ix.by_rel:
            needed |= ix.names(r)
    index = ix.merged(
        (
            *(
                ("name", r, p)
                for r in sorted(need)
                if r in ix.by_rel and r not in whole
                for p in sorted(need[r])
            ),
            ("axiom", "", 0),
        )
    )
    for u in kept_rules:
        needed.update(a[1] for _r, args in u.heads for a in args if a[0] == "c")
        needed.update(a[1] for _p, _r, args in u.body for a in args if a[0] == "c")
    keep: set[int] = set()
    for r, d in keyc.items():
        if r in whole or r not in ix.by_rel:
            continue
        for p, ks in d.items():
            at = ix.at(r, p)
            for k in ks:
                for u in at.get(k, ()):
                    keep.add(id(u))
                    needed.update(u.names)
    todo = list(needed)
    while todo:
        for u in index.get(todo.pop(), ()):
            if id(u) in keep:
                continue
            keep.add(id(u))
            for a in u.names if u.kind == "fact" else u.args:
                if a not in needed:
                    needed.add(a)
                    todo.append(a)
    kept: list[bool] = []
    reasons: list[str] = []
    for u in units:
        if u.kind == "rule":
            ok, why = any(h[0] in rels for h in u.heads), "rule"
        elif u.kind == "axiom":
            ok, why = id(u) in keep, "axiom"
        elif u.relation not in rels:
            ok, why = False, "relation"
        else:
            ok, why = u.relation in whole or id(u) in keep, "class"
        kept.append(ok)
        reasons.append("" if ok else why)
    counts = {k: reasons.count(k) for k in REASONS if k in reasons}
    return Relevance(tuple(kept), tuple(reasons), None, counts, frozenset(needed))
