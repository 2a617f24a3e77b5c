"""The knowledge base: ADROn's shipped .kif files plus a user's own, parsed and translated.

Ability names, parameters and their values are read from the ontology's ground facts
(``abilityName``, ``abilityVerb``, ``parameterName``, ``parameterValue``), so a user's
.kif file that declares a new ability or parameter value makes it usable on the command
line with no Python change.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from adron.errors import InputError, OntologyError
from adron.kif import MAX_DEPTH, Form, parse
from adron.translate import Translation, translate


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
class Parameter:
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
    parameters: tuple[Parameter, ...]

    def ability(self, name: str) -> Ability | None:
        return next((a for a in self.abilities if a.name == name), None)

    def ability_of_kif(self, kif: str) -> Ability | None:
        return next((a for a in self.abilities if a.kif == kif), None)

    def parameter(self, name: str) -> Parameter | None:
        return next((p for p in self.parameters if p.name == name), None)


def builtin_files() -> list[tuple[str, str]]:
    """(display name, text) of every shipped ontology file, in name order."""
    root = resources.files("adron.ontology")
    entries = sorted((p for p in root.iterdir() if p.name.endswith(".kif")), key=lambda p: p.name)
    return [(p.name, p.read_text(encoding="utf-8")) for p in entries]


def read_user_file(path: str | Path) -> tuple[str, str]:
    """(display name, text) of a user's file; a missing or unreadable file is an InputError."""
    p = Path(path)
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


def load(extra: Sequence[str | Path] = (), builtin: bool = True) -> KnowledgeBase:
    """Parse and translate the shipped ontology (unless ``builtin`` is False) and ``extra``."""
    sources = (builtin_files() if builtin else []) + [read_user_file(p) for p in extra]
    forms: list[Form] = []
    for name, text in sources:
        forms.extend(parse(text, name, MAX_DEPTH))
    tr = translate(forms)
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
        params.append(Parameter(name, rel, vals))
    facts(tr, "structuralLimit", 3)  # checked here, used by the structure stage
    return KnowledgeBase(
        files=tuple(n for n, _ in sources),
        translation=tr,
        abilities=tuple(sorted(abilities, key=lambda a: a.name)),
        parameters=tuple(sorted(params, key=lambda p: p.name)),
    )
