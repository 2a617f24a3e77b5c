"""The structure vocabulary and the tables keyed by it, held together (issue 33).

A body plan's structure (``kinematics.assemble.STRUCTURES``: what the assembler can tell a
plan is) names how it is sized (``synth.sizing.families.FAMILIES``), which controller
drives it (``gaits.CONTROLLERS``) and which structural parameters it takes
(``synth.params.PARAMS``' per-structure defaults). A structure added to one table and not
to the others fails here, naming the table, before a user meets it as "no sizing rules"
or "no controller"; a table keyed by a structure the assembler never gives fails too.
"""

from __future__ import annotations

import importlib

import pytest

from gaits import CONTROLLERS
from kinematics.assemble import STRUCTURES
from synth.params import PARAMS, structure_defaults
from synth.sizing.families import FAMILIES


def tables() -> dict[str, set[str]]:
    """Each table keyed by a structure -> the structures it has."""
    params: set[str] = set()
    for spec in PARAMS:
        params |= set(spec.defaults)
    return {"FAMILIES": set(FAMILIES), "CONTROLLERS": set(CONTROLLERS), "PARAMS": params}


def missing(vocabulary: tuple[str, ...], have: dict[str, set[str]]) -> list[str]:
    """``table: structure`` for each structure a table lacks or has beyond the vocabulary."""
    out = []
    for name, keys in sorted(have.items()):
        out += [f"{name} lacks {s}" for s in vocabulary if s not in keys]
        out += [f"{name} has unknown {s}" for s in sorted(keys - set(vocabulary))]
    return out


def test_every_structure_is_in_every_table() -> None:
    assert missing(STRUCTURES, tables()) == []


def test_the_check_names_a_structure_a_table_lacks() -> None:
    """Built to fail: a new structure the assembler gives and no table knows, and a table
    keyed by a name that is no structure."""
    have = tables()
    assert missing((*STRUCTURES, "hopper"), have) == [
        "CONTROLLERS lacks hopper",
        "FAMILIES lacks hopper",
        "PARAMS lacks hopper",
    ]
    have["FAMILIES"] = have["FAMILIES"] | {"wheeld"}
    assert "FAMILIES has unknown wheeld" in missing(STRUCTURES, have)


@pytest.mark.parametrize("structure", STRUCTURES)
def test_each_structure_has_a_controller_class_and_parameters(structure: str) -> None:
    module, name = CONTROLLERS[structure]
    assert isinstance(getattr(importlib.import_module(module), name), type)
    assert structure_defaults(structure), f"{structure} takes no structural parameter"
