"""The knowledge base: ADROn's shipped .kif files plus a user's own, parsed and translated.

Ability names, parameters and their values are read from the ontology's ground facts
(``abilityName``, ``abilityVerb``, ``parameterName``, ``parameterValue``), so a user's
.kif file that declares a new ability or parameter value makes it usable on the command
line with no Python change.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import NoReturn

from adron.errors import InputError, OntologyError
from adron.kif import MAX_DEPTH, Form, parse
from adron.materialise import materialise
from adron.translate import Translation, translate, unit_rows
from adron.units import cache_folder, prune_cache, read_cache_pickle, write_cache_file


@dataclass(frozen=True, slots=True)
class Ability:
    """A user-facing ability: its short name, KIF class and question verb."""

    name: str
    kif: str
    verb: str

    @property
    def question(self) -> str:
        return f"Does the robot need to {self.verb}?"


@dataclass(frozen=True, slots=True)
class ConceptualParameter:
    """A conceptual parameter: command-line name, KIF relation, value name -> KIF term."""

    name: str
    relation: str
    values: tuple[tuple[str, str], ...]

    def term(self, value: str) -> str | None:
        return dict(self.values).get(value)


@dataclass(frozen=True)
class KnowledgeBase:
    """The parsed and translated ontology, with the tables the command line needs."""

    files: tuple[str, ...]
    translation: Translation
    abilities: tuple[Ability, ...]
    parameters: tuple[ConceptualParameter, ...]
    #: the translation with its ontology-only rules materialised (adron/materialise.py),
    #: what the solver grounds when no rule files are given; ``translation`` itself when
    #: nothing was materialised, and then ``why_not`` says why
    grounded: Translation | None = None
    why_not: str | None = None
    #: the cache key of this knowledge base (a hash of its sources and of the code that
    #: loads them), None when the cache is off: other caches of results derived from it
    #: (synth/reasoning/solver.py: the relevant program) key on it
    key: str | None = field(default=None, compare=False)

    def ability(self, name: str) -> Ability | None:
        return next((a for a in self.abilities if a.name == name), None)

    def ability_of_kif(self, kif: str) -> Ability | None:
        return next((a for a in self.abilities if a.kif == kif), None)

    def parameter(self, name: str) -> ConceptualParameter | None:
        return next((p for p in self.parameters if p.name == name), None)


def builtin_files() -> list[tuple[str, str]]:
    """(display name, text) of every shipped ontology file, in name order."""
    root = resources.files("adron.ontology")
    entries = sorted((p for p in root.iterdir() if p.name.endswith(".kif")), key=lambda p: p.name)
    return [(p.name, p.read_text(encoding="utf-8")) for p in entries]


def read_user_file(path: str | Path) -> tuple[str, str]:
    """(display name, text) of a user's file; a missing or unreadable file is an InputError,
    and so is a named pipe or a device (adron/userfiles.py: reading it would not end)."""
    from adron.userfiles import check_regular

    p = Path(path)
    check_regular(p, str(path))
    try:
        return str(path), p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot read: {e}") from None


def facts(tr: Translation, relation: str, arity: int) -> list[tuple[str, ...]]:
    """The ground facts of ``relation``, each checked to have ``arity`` name or string
    arguments; an OntologyError names the file:line:col of a malformed one."""
    out = []
    for args, where in tr.located(relation):
        if len(args) != arity or not all(isinstance(a, str) for a in args):
            shape = " ".join(["X"] * arity)
            raise OntologyError(
                f"{where}: ({relation} {' '.join(map(str, args))}): expected "
                f"({relation} {shape}) with {arity} names or strings"
            )
        out.append(args)
    return out


#: The relations whose ground facts parmor reads by position, with the shape of a fact:
#: one of another arity (``(subclass Foo)``) is an OntologyError naming it.
SHAPES: dict[str, tuple[str, ...]] = {
    "subclass": ("CLASS", "PARENT"),
    "subrelation": ("RELATION", "PARENT"),
    "extensiblePart": ("ROBOT", "PART"),
    "defaultLength": ("CLASS", "NAME", "LENGTH"),
    "liftedModuleShare": ("GAIT", "N", "D"),
    "requiredPartCount": ("ABILITY", "PART", "N"),
    "connectedTo": ("PART", "PART"),
    "instance": ("THING", "CLASS"),
    "defaultParameter": ("CLASS", "NAME", "QUANTITY"),
}


#: the arguments of :data:`SHAPES` that are counts (whole numbers), and their bound
_COUNTS = ("N", "D")
MAX_COUNT = 10_000


def check_arities(tr: Translation) -> None:
    """OntologyError (file:line:col) for the first ground fact of a relation of
    :data:`SHAPES` with another number of arguments; where it is is looked up only then."""
    for relation, shape in SHAPES.items():
        for i, args in enumerate(tr.relation(relation)):
            why = ""
            if len(args) != len(shape):
                why = f"{len(shape)} arguments, not {len(args)}"
            else:
                for k, (a, kind) in enumerate(zip(args, shape, strict=True), 1):
                    if kind in _COUNTS:
                        if isinstance(a, bool) or not isinstance(a, int) or not 0 <= a <= MAX_COUNT:
                            why = f"argument {k} ({kind}) is a whole number from 0 to {MAX_COUNT}"
                            break
                    elif not isinstance(a, str):
                        why = f"argument {k} ({kind}) is a name or a string"
                        break
            if why:
                where = tr.located(relation)[i][1]
                shown = " ".join([relation, *map(str, args)])
                raise OntologyError(
                    f"{where}: ({shown}): expected ({' '.join([relation, *shape])}), {why}"
                )


def check_taxonomy(tr: Translation) -> None:
    """OntologyError when a fact parmor reads by position has another arity
    (:func:`check_arities`), or when the ground ``subclass`` facts form a cycle, such as
    ``(subclass Robot HexapodRobot)`` beside the shipped ``HexapodRobot`` under ``Robot``:
    the message names the cycle's last-loaded fact (a user's file comes after the shipped
    ones). Iterative depth-first search over the names only, linear in the facts; where
    the facts are is looked up only for a cycle found."""
    check_arities(tr)
    graph: dict[str, list[str]] = {}
    for args in tr.relation("subclass"):
        a, b = args[0], args[1]
        if isinstance(a, str) and isinstance(b, str):
            graph.setdefault(a, []).append(b)
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    for root in graph:
        if root in state:
            continue
        state[root] = 1
        path = [root]
        stack = [iter(graph[root])]
        while stack:
            b = next(stack[-1], None)
            if b is None:
                state[path.pop()] = 2
                stack.pop()
                continue
            seen = state.get(b)
            if seen == 1:  # back to a class on the path: a cycle
                _cycle_error(tr, [*path[path.index(b) :], b])
            if seen is None:
                state[b] = 1
                path.append(b)
                stack.append(iter(graph.get(b, ())))


def _cycle_error(tr: Translation, names: list[str]) -> NoReturn:
    """The OntologyError of the cycle through ``names`` (its first name again at the end):
    blamed on its last-loaded fact (each step the first fact of that pair, the one the
    search followed)."""
    first: dict[tuple[str, str], tuple[int, str]] = {}
    for i, (args, where) in enumerate(tr.located("subclass")):
        first.setdefault((args[0], args[1]), (i, where))
    _, blame = max(first[(a, b)] for a, b in zip(names, names[1:], strict=False))
    shown = " < ".join(names if len(names) <= 8 else [*names[:4], "...", *names[-3:]])
    raise OntologyError(
        f"{blame}: this subclass fact closes a cycle in the class hierarchy "
        f"({shown}); a class cannot be its own subclass"
    )


#: the modules whose code makes a KnowledgeBase: part of the cache key
_CODE = ("kb.py", "kif.py", "translate.py", "materialise.py", "errors.py")
_CACHE_FORMAT = b"parmor-kb-1"


def _cache_file(sources: Sequence[tuple[str, str]]) -> Path | None:
    """``$PARMOR_CACHE/kb-KEY.pickle`` (adron/units.py: cache_folder), KEY a hash of the
    sources' names and texts, of this package's code that turns them into a knowledge base
    and of the Python and clingo versions; None when the cache is off."""
    import hashlib
    import sys

    import clingo

    folder = cache_folder()
    if folder is None:
        return None
    h = hashlib.sha256(_CACHE_FORMAT)
    here = Path(__file__).parent
    for name in _CODE:
        h.update((here / name).read_bytes())
    h.update(f"{sys.version}|{clingo.__version__}|{len(sources)}".encode())
    for name, text in sources:
        for part in (name, text):
            b = part.encode("utf-8", "surrogatepass")
            h.update(len(b).to_bytes(8, "little") + b)
    return folder / f"kb-{h.hexdigest()[:32]}.pickle"


def _cached(path: Path | None, files: tuple[str, ...]) -> KnowledgeBase | None:
    """The knowledge base stored at ``path``, or None when it is absent or not valid."""

    kb = read_cache_pickle(path, _CACHE_FORMAT, KnowledgeBase)
    return kb if isinstance(kb, KnowledgeBase) and kb.files == files else None


def _store(path: Path | None, kb: KnowledgeBase) -> None:
    """Write ``kb`` to ``path`` whole (temporary file + rename); an unwritable folder
    only costs time."""
    import pickle

    if path is None:
        return
    memo: dict[int, tuple] = {}
    light = dataclasses.replace(
        kb,
        translation=dataclasses.replace(
            kb.translation, units=unit_rows(kb.translation.units, memo)
        ),
    )
    if kb.grounded is not None:
        lazy = dataclasses.replace(kb.grounded, units=unit_rows(kb.grounded.units, memo))
        light = dataclasses.replace(
            light, grounded=lazy if kb.grounded is not kb.translation else light.translation
        )
    data = _CACHE_FORMAT + pickle.dumps(light, protocol=pickle.HIGHEST_PROTOCOL)
    if write_cache_file(path, data):
        prune(path.parent)


#: how many knowledge bases (and relevant programs) the cache keeps: the least recently
#: used beyond this are removed when a new one is written (SUMO's is ~6 MB)
CACHE_ENTRIES = 16


def prune(folder: Path, keep: int = CACHE_ENTRIES) -> None:
    """Remove all but the ``keep`` most recently used ``kb-*`` and ``relevant-*`` files of
    ``folder`` (a hit touches its file; ``adron.units.prune_cache``)."""

    prune_cache(folder, ("kb-*.pickle", "relevant-*.lp"), keep)


def load(
    extra: Sequence[str | Path] = (),
    builtin: bool = True,
    texts: Sequence[tuple[str, str]] = (),
) -> KnowledgeBase:
    """Parse and translate the shipped ontology (unless ``builtin`` is False) and ``extra``,
    and materialise its ontology-only rules (adron/materialise.py). ``texts``: generated
    sources (display name, KIF text) read after the files (a composed robot type).

    Cache: a successful load is kept on disk (``$PARMOR_CACHE/kb-KEY.pickle``, see
    :func:`_cache_file`); the files are read each time, and a change to any of them, to
    their names or to the code that loads them makes a new key, so a cached knowledge base
    is never stale. A failing load is not cached: its error is raised again, as it is."""
    sources = (
        (builtin_files() if builtin else []) + [read_user_file(p) for p in extra] + list(texts)
    )
    files = tuple(n for n, _ in sources)
    path = _cache_file(sources)
    with _no_gc():
        kb = _cached(path, files)
        if kb is None:
            kb = _load(sources)
            if path is not None:
                kb = dataclasses.replace(kb, key=path.stem)
            if len(kb.translation.units) >= BACKGROUND_STORE_UNITS:
                _store_in_background(path, kb)
            else:
                _store(path, kb)
    return kb


#: A knowledge base of at least this many translated forms is written to the cache by a
#: detached process while this one goes on (grounding, on the other core): pickling a
#: 100,000-form ontology takes ~0.7 s. Smaller ones are written before ``load`` returns.
BACKGROUND_STORE_UNITS = 50_000


def _store_in_background(path: Path | None, kb: KnowledgeBase) -> None:
    """:func:`_store` in a grandchild process (double fork: nothing to reap, no zombie);
    where ``fork`` is missing or fails, here and now. The file appears whole (rename) or
    not at all, so a reader never sees it half-written."""
    import os

    if path is None:
        return
    try:
        pid = os.fork()
    except (AttributeError, OSError):
        _store(path, kb)
        return
    if pid:
        os.waitpid(pid, 0)  # the child exits at once, leaving the grandchild to write
        return
    code = 0
    try:
        if os.fork() == 0:
            os.setsid()  # Ctrl-C at the terminal is for the command, not for this write
            with contextlib.suppress(OSError):
                os.nice(19)  # the command's worker and threads come first on the cores
            null = os.open(os.devnull, os.O_RDWR)  # nor are its pipes held open by it
            for fd in (0, 1, 2):
                os.dup2(null, fd)
            _store(path, kb)
    except BaseException:  # noqa: BLE001 - never back into the caller's code
        code = 1
    finally:
        os._exit(code)


@contextlib.contextmanager
def _no_gc():
    """The cyclic garbage collector off while a knowledge base is built, and what exists
    then frozen (``gc.freeze``): a large ontology's 100,000s of small objects are made
    once and live as long as the process, and each collection would walk them all
    (about a fifth of a 100,000-class ontology's load and relevance filter)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if was:
            gc.enable()


def materialised(kb: KnowledgeBase) -> KnowledgeBase:
    """``kb`` with its ontology-only rules materialised (``grounded``, ``why_not``: see
    adron/materialise.py); this grounds them with clingo, so callers run it where a limit
    or Ctrl-C can stop it (synth/reasoning/solver.py does, in its worker process)."""
    if kb.grounded is not None or kb.why_not is not None:
        return kb
    grounded, why_not = materialise(kb.translation)
    return dataclasses.replace(kb, grounded=grounded, why_not=why_not)


def _load(sources: Sequence[tuple[str, str]]) -> KnowledgeBase:
    """The knowledge base of (name, text) ``sources``, uncached."""
    forms: list[Form] = []
    for name, text in sources:
        forms.extend(parse(text, name, MAX_DEPTH))
    tr = translate(forms)
    check_taxonomy(tr)
    verbs = {kif: verb for kif, verb in facts(tr, "abilityVerb", 2)}
    abilities, seen = [], {}
    for kif, name in facts(tr, "abilityName", 2):
        if name in seen and seen[name] != kif:
            raise OntologyError(f"ability name {name!r} is given to both {seen[name]} and {kif}")
        if name not in seen:
            seen[name] = kif
            abilities.append(Ability(name, kif, verbs.get(kif, name)))
    params = []
    values = facts(tr, "parameterValue", 3)
    for rel, name in facts(tr, "parameterName", 2):
        vals = tuple((v, t) for r, v, t in values if r == rel)
        params.append(ConceptualParameter(name, rel, vals))
    facts(tr, "structuralLimit", 3)  # checked here, used by the structure stage
    # materialised later, where grounding can be interrupted and limited (the reasoner's
    # worker process: synth/reasoning/solver.py), not here in the parse stage
    grounded, why_not = None, None
    return KnowledgeBase(
        files=tuple(n for n, _ in sources),
        translation=tr,
        abilities=tuple(sorted(abilities, key=lambda a: a.name)),
        parameters=tuple(sorted(params, key=lambda p: p.name)),
        grounded=grounded,
        why_not=why_not,
    )
