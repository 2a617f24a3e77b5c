"""Materialising an ontology: its translated rules replaced by the facts they derive.

A large ontology (SUMO's Merge.kif has ~900 Horn rules) grounds slowly and defeats the
relevance filter (adron/relevance.py): a rule such as ``(=> (and (subclass ?X ?Y)
(instance ?Z ?X)) (instance ?Z ?Y))`` can derive taxonomy facts about anything, so the
filter cannot tell which facts matter and switches itself off. But most translated rules
read only what the ontology itself says, and the ontology alone (its facts, those rules
and the KIF meaning of ``subclass``/``instance``/``subrelation``, :data:`KIF_TAXONOMY`)
has one least model. Its consequences are computed once with clingo, and those rules are
replaced by the facts they derive; the filter then sees facts only and filters soundly.

Which rules stay rules (never materialised): a rule that reads an atom something outside
the ontology defines. The encodings define unary atoms from the request
(``asp/request.lp``: ``holds(Rel, T) :- param(Rel, T)`` for each relation with a
``parameterValue`` fact): those relations are *open*. A rule reading an open atom (or its
negation) stays, its heads become open, transitively; an open binary relation makes its
super-relations open and an open ``subclass``/``instance`` makes ``instance`` open (the
taxonomy rules pass them on). Nothing is materialised when a rule derives
``parameterValue`` atoms, or ``subrelation`` atoms from open ones, when the remaining program is
not stratified into one model, or when the caller has rule files (``--rules``: they may
define any ``holds`` atom; the solver then grounds the translation as it is).

By the splitting theorem the answer sets of (materialised facts + kept rules + encodings)
are those of (translation + encodings): the materialised part reads nothing the rest
defines. Output: the translation's facts and axioms unchanged, the kept rules, then the
atoms the materialised rules derive that are not facts already (sorted; those the taxonomy
rules alone derive are left out, the encodings' taxonomy layer derives them again).
"""

from __future__ import annotations

from dataclasses import replace

from adron.translate import Translation, Unit

#: the KIF meaning of the taxonomy relations, as the encodings give it (asp/taxonomy.lp and
#: asp/closure.lp: tests/adron/test_materialise.py checks that they agree)
KIF_TAXONOMY = """\
holds("instance", X, D) :- holds("instance", X, C), holds("subclass", C, D).
holds(S, X, Y) :- holds(R, X, Y), holds("subrelation", R, S).
holds("subclass", A, C) :- holds("subclass", A, B), holds("subclass", B, C).
holds("subrelation", A, C) :- holds("subrelation", A, B), holds("subrelation", B, C).
"""

#: the relation whose facts name the unary relations the request sets (asp/request.lp)
PARAMETER_VALUE = "parameterValue"
#: where a materialised fact comes from, as messages show it
DERIVED = "(derived by the ontology's rules)"


def _open_rules(tr: Translation, pairs: set[tuple[str, str]]) -> tuple[list[bool], str | None]:
    """For each rule unit of ``tr``, whether it must stay a rule, given the ``subrelation``
    ``pairs`` (facts and derived ones); or a reason why nothing can be materialised."""
    rules = [u for u in tr.units if u.kind == "rule"]
    for u in rules:  # the request's parameters would depend on what the rules derive
        if any(r == PARAMETER_VALUE for r, _a in u.heads):
            return [False] * len(rules), f"{u.where}: a rule derives {PARAMETER_VALUE} facts"
    opened: set[tuple[str, int]] = {(a[0], 1) for a in tr.relation(PARAMETER_VALUE) if a}
    supers: dict[str, set[str]] = {}
    for a, b in pairs:
        supers.setdefault(a, set()).add(b)
    keep = [False] * len(rules)
    changed = True
    while changed:
        changed = False
        for rel, n in list(opened):
            if n == 2:
                if rel == "subrelation":
                    return keep, "a rule reads request-set atoms and derives subrelation facts"
                new = {(s, 2) for s in supers.get(rel, ())}
                if rel in ("subclass", "instance"):
                    new.add(("instance", 2))
                if new - opened:
                    opened |= new
                    changed = True
        for i, u in enumerate(rules):
            if keep[i] or not any((r, len(a)) in opened for _p, r, a in u.body):
                continue
            keep[i] = True
            changed = True
            for r, a in u.heads:
                opened.add((r, len(a)))
    return keep, None


def _unit(sym: object) -> Unit:
    """A fact unit for a derived ``holds(...)`` symbol."""
    args = sym.arguments  # type: ignore[attr-defined]
    rel = args[0].string
    shown: list[str] = []
    names: list[str] = []

    def walk(s: object) -> None:
        if s.type.name == "String":  # type: ignore[attr-defined]
            names.append(s.string)  # type: ignore[attr-defined]
        elif s.type.name == "Function":  # type: ignore[attr-defined]
            for a in s.arguments:  # type: ignore[attr-defined]
                walk(a)

    for a in args[1:]:
        shown.append(a.string if a.type.name == "String" else str(a))
        walk(a)
    return Unit("fact", (f"{sym}.",), DERIVED, rel, tuple(shown), tuple(names))


#: What materialising a translation changes (:func:`derivation`): which rules stay (one
#: flag per rule, in order), the derived facts' units and, for each, its ground arguments
#: (None: not all strings or numbers). Small to send from a worker process, where the
#: translation itself (100,000 units for a large ontology) would take seconds to pickle.
Derivation = tuple[tuple[bool, ...], tuple[Unit, ...], tuple[tuple | None, ...]]


def materialise(tr: Translation) -> tuple[Translation, str | None]:
    """``tr`` with every rule that reads only the ontology replaced by what it derives
    (see the module doc), and None; or ``tr`` itself and why nothing was materialised."""
    d, why = derivation(tr)
    return (tr, why) if d is None else (applied(tr, d), None)


def derivation(tr: Translation) -> tuple[Derivation | None, str | None]:
    """What :func:`materialise` changes in ``tr`` (grounding with clingo), or None and why
    nothing is materialised; :func:`applied` makes the materialised translation of it."""
    rules = [u for u in tr.units if u.kind == "rule"]
    if not rules:
        return None, "no rules"
    facts = [u for u in tr.units if u.kind == "fact"]
    pairs = {(str(a[0]), str(a[1])) for a in tr.relation("subrelation") if len(a) == 2}
    while True:  # the derived subrelation pairs can open more relations: to a fixpoint
        keep, why = _open_rules(tr, pairs)
        if why is not None:
            return None, why
        gone = [u for u, k in zip(rules, keep, strict=True) if not k]
        if not gone:
            return None, "every rule reads what the request sets"
        model = _model(facts, gone)
        if model is None:
            return None, "the ontology's rules do not have exactly one model"
        more = {
            (s.arguments[1].string, s.arguments[2].string)
            for s in model
            if s.name == "holds"
            and len(s.arguments) == 3
            and s.arguments[0].type.name == "String"
            and s.arguments[0].string == "subrelation"
            and all(a.type.name == "String" for a in s.arguments[1:])
        }
        if more <= pairs:
            break
        pairs |= more
    return _derived(facts, keep, model), None


def _model(facts: list[Unit], gone: list[Unit]) -> list | None:
    """The holds atoms of the one model of ``facts``, the ``gone`` rules and the taxonomy
    rules (every atom: the subrelation pairs are read from it), or None."""
    import clingo

    arities = {len(a) + 1 for u in gone for _r, a in u.heads}
    text = [ln for u in facts for ln in u.lines]
    for u in gone:
        for ln in u.lines:
            head, body = ln.split(" :- ", 1)
            text.append(f"mat({head}) :- {body}")
    for n in sorted(arities):
        xs = ",".join(f"X{i}" for i in range(n))
        text.append(f"holds({xs}) :- mat(holds({xs})).")
    text.append(KIF_TAXONOMY)
    ctl = clingo.Control(["--models=2", "--warn=none"])
    ctl.add("base", [], "\n".join(text))
    ctl.ground([("base", [])])
    models: list[list] = []
    ctl.solve(on_model=lambda m: models.append(m.symbols(atoms=True)))
    return models[0] if len(models) == 1 else None


def _derived(facts: list[Unit], keep: list[bool], model: list) -> Derivation:
    """The rules kept and the facts ``model`` derives beyond ``facts``, with their ground
    arguments."""
    mats = [s.arguments[0] for s in model if s.name == "mat"]
    known = {ln for u in facts for ln in u.lines}
    by_text = {str(s): s for s in mats}
    derived = sorted(set(by_text) - {ln[:-1] for ln in known})
    new = tuple(_unit(by_text[t]) for t in derived)
    vals = []
    for t in derived:
        v = tuple(
            a.string if a.type.name == "String" else a.number if a.type.name == "Number" else None
            for a in by_text[t].arguments[1:]
        )
        vals.append(None if None in v else v)
    return tuple(keep), new, tuple(vals)


def applied(tr: Translation, d: Derivation) -> Translation:
    """``tr`` with the rules ``d`` does not keep replaced by the facts they derive."""
    keep, new, vals = d
    units: list[Unit] = []
    k = iter(keep)
    for u in tr.units:
        if u.kind != "rule" or next(k):
            units.append(u)
    units.extend(new)
    ground = {r: list(v) for r, v in tr.ground.items()}
    ground_at = {r: list(v) for r, v in tr.ground_at.items()}
    for u, v in zip(new, vals, strict=True):
        if v is not None:
            ground.setdefault(u.relation, []).append(v)
            ground_at.setdefault(u.relation, []).append(DERIVED)
    out = replace(
        tr,
        program="\n".join(ln for u in units for ln in u.lines) + "\n",
        ground={r: tuple(v) for r, v in ground.items()},
        ground_at={r: tuple(v) for r, v in ground_at.items()},
        units=tuple(units),
    )
    return out


__all__ = ["DERIVED", "KIF_TAXONOMY", "PARAMETER_VALUE", "applied", "derivation", "materialise"]
