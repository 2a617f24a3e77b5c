"""The structure generator sizes a serial chain's links together (issue 20, item 5):
``synth.sizing.chain_links.chain_tubes`` wired into ``StructureDesigner.run``.

A chain of N links (root to a foot or an end effector) may deflect N times the
``deflection`` parameter, shared among its links. Checked here with the beam formulas of
``synth.sizing.links`` (``beam_check``) and against the per-link closed form (every link within
``deflection`` on its own, ``StructureDesigner._size_link``), not with the program's own
numbers.
"""

from __future__ import annotations

import numpy as np
import pytest

from adron.errors import InfeasibleError
from synth.sizing.chain_links import Chain, ChainLink, chain_tubes, per_link_tubes
from synth.sizing.links import Tube, TubeLimits, beam_check, max_allowed_stress
from synth.sizing.structure import StructureDesigner

#: Shipped types with a serial chain of several links, and their chains (length names
#: from the root to the tip: the arm's gripper, a leg's foot).
CHAINS = {
    "Manipulator3DOF": [("L1", "L2", "L3")],
    "HexapodRobot": [("coxa", "femur", "tibia")],
}


def per_link(self, lengths, loads, counts, analysis):
    """The sizing before the chains: every link on its own within ``deflection``."""
    return {n: self._size_link(n, lengths[n], loads[n]) for n in lengths}


def printed_mass(structure) -> float:
    """kg of all the printed links (every copy)."""
    return sum(link.count * link.mass_kg for link in structure.links)


def designer(kb, bases, catalog, robot_type: str, params=None) -> StructureDesigner:
    return StructureDesigner(kb, bases[robot_type], catalog, params or {})


@pytest.fixture(scope="module")
def wired(kb, bases, catalog):
    """Robot type -> (its designer after ``run``, the structure)."""
    out = {}
    for t in (*CHAINS, "SnakeRobot"):
        d = designer(kb, bases, catalog, t)
        out[t] = (d, d.run())
    return out


@pytest.fixture(scope="module")
def closed_form(kb, bases, catalog):
    """Robot type -> the structure sized link by link (the sizing the chains replace)."""
    mp = pytest.MonkeyPatch()
    mp.setattr(StructureDesigner, "_size_links", per_link)
    try:
        return {t: designer(kb, bases, catalog, t).run() for t in (*CHAINS, "SnakeRobot")}
    finally:
        mp.undo()


@pytest.mark.parametrize("robot_type", list(CHAINS))
def test_chains_are_lighter_than_the_closed_form(robot_type, wired, closed_form) -> None:
    """The designed robot's printed links weigh no more than when each link is sized on
    its own; the arm's (every link deflection-governed) strictly less."""
    _, s = wired[robot_type]
    before = printed_mass(closed_form[robot_type])
    assert printed_mass(s) <= before
    if robot_type == "Manipulator3DOF":
        assert printed_mass(s) < before * (1.0 - 1e-5)
    assert {link.name for link in s.links} == {link.name for link in closed_form[robot_type].links}


@pytest.mark.parametrize("robot_type", list(CHAINS))
def test_same_loads_lighter_and_within_the_chain_allowance(robot_type, wired, catalog) -> None:
    """At the converged loads the chain sizing's printed mass is at most the per-link
    one's; every chain's tip deflection (the sum of its links' own tip deflections,
    beam_check under each link's worst load) is within N x deflection, every stress
    within the allowed (beam_check with Kt), and the record says so."""
    d, s = wired[robot_type]
    loads = d.requirements.loads
    lengths = {link.name: link.length_m for link in s.links}
    counts = {link.name: link.count for link in s.links}
    joint = d._size_links(lengths, loads, counts, d.analysis)
    alone = per_link(d, lengths, loads, counts, d.analysis)

    def mass(sized) -> float:
        return sum(counts[n] * d._part_volume(t) for n, (t, _) in sized.items())

    assert mass(joint) <= mass(alone) * (1.0 + 1e-12)
    dmax = d.values["deflection"]
    E = catalog.material.youngs_modulus_Pa
    kt = catalog.passive.stress_concentration
    allowed = max_allowed_stress(
        catalog.material.yield_strength_Pa, catalog.design.stress_safety_factor
    )
    by_name = {link.name: link for link in s.links}
    for chain in CHAINS[robot_type]:
        total = 0.0
        for n in chain:
            link = by_name[n]
            tube = Tube(link.length_m, link.r_outer_m, link.r_inner_m, link.volume_m3, link.branch)
            checks = [beam_check(tube, ld, E, kt) for ld in loads[n]]
            total += max(c.tip_deflection_m for c in checks)
            assert max(c.max_stress_Pa for c in checks) <= allowed * (1.0 + 1e-9), n
            assert link.max_deflection_m == pytest.approx(len(chain) * dmax, rel=1e-12)
            assert link.tip_deflection_m <= link.max_deflection_m
        assert total <= len(chain) * dmax * (1.0 + 1e-9), (chain, total / dmax)
        assert sum(by_name[n].tip_deflection_m for n in chain) <= len(chain) * dmax * (1 + 1e-9)


def test_a_link_in_no_chain_of_two_keeps_the_closed_form(wired, closed_form) -> None:
    """The snake's modules share one length name (a chain of one link): sized as before,
    to the last bit, within ``deflection`` on its own."""
    _, s = wired["SnakeRobot"]
    assert s.links == closed_form["SnakeRobot"].links
    assert all(link.max_deflection_m == s.params["deflection"] for link in s.links)


def test_identical_inputs_give_identical_links(kb, bases, catalog, wired) -> None:
    _, s = wired["Manipulator3DOF"]
    again = designer(kb, bases, catalog, "Manipulator3DOF").run()
    assert again.links == s.links


def test_a_budget_too_tight_names_the_chain_and_the_link(kb, bases, catalog) -> None:
    """0.01 mm a link: the chain's 0.03 mm is beyond the stiffest printable tubes."""
    d = designer(kb, bases, catalog, "Manipulator3DOF", {"deflection": 1e-5})
    with pytest.raises(InfeasibleError) as e:
        d.run()
    text = str(e.value)
    assert "chain 'L1 -> L2 -> L3'" in text and "within 0.03 mm (3 links x 0.01 mm)" in text
    assert any(f"link '{n}'" in text for n in ("L1", "L2", "L3")), text
    assert "--param deflection=" in text, text


def test_the_command_line_refuses_a_budget_too_tight(cli) -> None:
    r = cli(
        "design",
        "pick-and-place",
        "--param",
        "object_shape=cylinder",
        "--param",
        "deflection=0.01mm",
        "--no-verify",
        "--no-input",
    )
    assert r.code == 1, r.err
    assert "Traceback" not in r.err
    assert "chain 'L1 -> L2 -> L3'" in r.err and "link 'L" in r.err, r.err


# --------------------------------------------------------------------------- no solve


def _two_links(force: float) -> list[ChainLink]:
    lim = TubeLimits(0.02, 0.0012, 0.1, 0.1)
    load = np.array([0.0, force, 0.0, 0.0, 0.0, 0.0])
    return [ChainLink("A", lim, (load,)), ChainLink("B", lim, (load * 0.5,))]


def test_nothing_deflection_governed_is_not_solved(monkeypatch) -> None:
    """Every link at its stress floor (a generous budget): the per-link sizing is the
    optimum, returned without the convex program; a budget that makes a link
    deflection-governed does call it (the case built to fail the shortcut)."""
    import synth.sizing.chain_links as chain_links

    def no_solver(n: int, m: int):
        raise AssertionError("the convex program was built")

    E, allowed = 2.3e9, 20e6
    links = _two_links(20.0)
    chains = [Chain(("A", "B"), 1.0, (0.0, 0.0))]
    monkeypatch.setattr(chain_links, "_program", no_solver)
    sized = chain_tubes(links, chains, E, allowed, 1.8)
    assert sized.iterations == 0
    assert set(sized.governed.values()) == {"stress"}
    same = per_link_tubes(links, chains, E, allowed, 1.8)
    assert sized.tubes == same.tubes
    tight = [Chain(("A", "B"), 2e-4, (0.0, 0.0))]
    assert "deflection" in per_link_tubes(links, tight, E, allowed, 1.8).governed.values()
    with pytest.raises(AssertionError, match="convex program was built"):
        chain_tubes(links, tight, E, allowed, 1.8, method="program")  # one chain: asked


def test_a_solve_does_not_depend_on_the_solves_before() -> None:
    """The same chain sized before and after another one gives the same tubes to the last
    bit (a warm-started solver differed at ~1e-10)."""
    E, allowed = 2.3e9, 20e6
    lim = [TubeLimits(0.02, 0.0012, L, L) for L in (0.1, 0.15, 0.15)]

    def links(scale: float) -> list[ChainLink]:
        load = np.array([0.1, 2.0, 0.5, 0.01, 0.05, 0.1]) * scale
        return [ChainLink(f"L{i}", lim[i], (load * (i + 1),)) for i in range(3)]

    chains = [Chain(("L0", "L1", "L2"), 3e-3, (0.0, 0.0, 0.0))]
    first = chain_tubes(links(1.0), chains, E, allowed, 1.8)
    assert first.iterations >= 1 and "deflection" in first.governed.values()
    chain_tubes(links(1.3), chains, E, allowed, 1.8)
    assert chain_tubes(links(1.0), chains, E, allowed, 1.8) == first
