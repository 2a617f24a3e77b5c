"""One design request end to end, as both ``parmor design`` and ``parmor regress`` run it:
the conceptual procedure, then (unless asked not to) the structure generator, giving the
design record."""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from adron.catalog import load_catalog
from adron.errors import InfeasibleError, InputError
from export.bundle import bundle_files, payload_record
from export.record import catalog_record, design_record, to_json
from gaits import controller_for
from gaits.base import DesignGeometry
from synth.reasoning.conceptual import Design, Designer, Request, limit_note
from synth.sizing.structure import design_structure
from synth.verification.loop import demanded, served_abilities, verify

if TYPE_CHECKING:  # numpy-heavy: imported only when a structure is sized
    from adron.catalog import Catalog
    from synth.sizing.structure import Structure
    from synth.verification.loop import Verification


@dataclass(frozen=True, slots=True)
class StructureOptions:
    """How to size the structure: catalog file (None: the shipped one), whether to stop at
    the conceptual design, symmetry of alike joints, the actuator objective order, and
    whether to simulate every behaviour of the sized design (``synth.verification.loop``)."""

    catalog: str | None = None
    conceptual: bool = False
    symmetric: bool = True
    objective: tuple[str, ...] = ("mass", "cost")
    verify: bool = True
    with_payload: bool = False  # robot.urdf / robot.xml carry the payload (--with-payload)
    #: accept a demanded ability that no behaviour serves, unsimulated (--allow-unverified;
    #: otherwise the verification refuses it: ``synth.verification.loop``)
    allow_unverified: bool = False
    robustness: int = 0  # perturbed runs per behaviour (--robustness K; synth.verification.robust)
    #: the runs are a certification (--certify N): a behaviour passes when its runs show at
    #: least what the default K runs show (synth.verification.robust.certified_share)
    certify: bool = False


def parse_objective(text: str) -> tuple[str, ...]:
    order = tuple(x.strip() for x in text.split(",") if x.strip())
    if sorted(order) != ["cost", "mass"]:
        raise InputError(f"objective {text!r}: expected mass,cost or cost,mass")
    return order


def bus_limit(path: str | None, conceptual: bool = False) -> int | None:
    """The active module limit of the catalog's bus (``Bus.module_limit``), for the
    conceptual step (InputError for a catalog that cannot be loaded). None for a conceptual
    design without a catalog named: the ontology's ``activeModuleLimit`` then applies (the
    shipped catalog's bus has the same 24), and no catalog is loaded."""
    if conceptual and not path:
        return None
    return _catalog(path, _stamp(path)).bus.module_limit


def limit_source(opts: StructureOptions) -> str:
    """Where the active module limit of a request with ``opts`` comes from, as a refusal
    names it: the catalog's bus (``on the I2C bus (catalog 'ParMoR reference modules')``),
    or the ontology's ``activeModuleLimit`` for a conceptual design without a catalog
    (``bus_limit``)."""
    if bus_limit(opts.catalog, opts.conceptual) is None:
        return "set by the ontology (activeModuleLimit)"
    cat = _catalog(opts.catalog, _stamp(opts.catalog))
    return f"on the {cat.bus.name} bus (catalog {cat.name!r})"


def _stamp(path: str | None) -> tuple[int, int] | None:
    """(mtime ns, size) of a catalog file, None for a shipped name or a missing file."""
    try:
        st = os.stat(path) if path else None
    except OSError:
        return None
    return None if st is None else (st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=4)
def _catalog(path: str | None, stamp: tuple[int, int] | None) -> Catalog:
    """``load_catalog(path)`` parsed once per process for the bus limit and the sizing of
    one request (a 1000-actuator catalog takes 0.15 s); a changed file (``stamp``) is
    parsed again. Catalogs are immutable."""

    return load_catalog(path)


def load_checked_catalog(path: str | None, designer: Designer) -> Catalog:
    """The catalog, with every ontology class it names checked against the ontology."""
    cat = _catalog(path, _stamp(path))
    known = {n for pair in designer.kb.translation.relation("subclass") for n in pair[:2]}
    cat.check_classes(known)
    return cat


@dataclass(frozen=True)
class Outcome:
    """A design, its sized structure (or None) and why there is none."""

    design: Design
    structure: Structure | None = None
    infeasible: str | None = None  # the infeasibility message
    note: str | None = None  # why the design stayed conceptual
    catalog: Catalog | None = None  # the catalog the structure was sized with
    verification: Verification | None = None  # what the simulation found (None: not run)
    verify_skipped: bool = False  # sized but not simulated (--no-verify)
    bundle: dict[str, str | bytes] | None = None  # the files the verification simulated
    with_payload: bool = False  # the bundle's models carry the payload (--with-payload)
    calibration: dict[str, float] | None = None  # measured on a run (synth.verification.loop)
    #: behaviour -> the scale of its feedback loop's gains the robust verification chose
    #: (synth.verification.gains); the record's ``feedback_gains``, which its controller reads
    feedback_gains: dict[str, float] | None = None
    #: behaviour -> its pace the robust verification chose (synth.verification.hold); the
    #: record's ``paces``, which its controller reads
    paces: dict[str, float] | None = None
    bed: object = None  # the user's printer (export.split.Bed, --bed): parts made to fit it
    #: bonus abilities dropped before verifying: a behaviour serving them cannot be
    #: planned with its default parameters (ability -> why; :func:`drop_unplannable`)
    unplanned: tuple[tuple[str, str], ...] = ()

    @property
    def status(self) -> str:
        return "infeasible" if self.infeasible else self.design.status

    def files(self, designer: Designer) -> dict[str, str | bytes]:
        """The output bundle: everything for a sized design, design.json alone otherwise.

        The robot is sized for its payload and simulated with it: robot.urdf and robot.xml
        carry it only ``with_payload`` (the user's choice), else design.json places it and
        the simulation adds it there (the verification's files and the user's alike)."""

        rec = self.record(designer)
        if self.structure is None or self.catalog is None:
            return {"design.json": to_json(rec)}

        doc = designer.kb.translation.documentation.get(self.structure.robot_type, "")
        # the verification's own call: no pictures; afterwards the same design (its meshes
        # and trajectories reused) with them. Both carry the payload as the user's bundle
        # does (in the models only ``with_payload``, else placed from design.json by
        # ``synth.verification.simulate.carrying_payload``), so that ``parmor simulate`` on the
        # bundle reproduces the verification's figures exactly
        simulating = self.verification is None and not self.verify_skipped
        return bundle_files(
            rec,
            self.structure,
            self.catalog,
            doc,
            with_payload=self.with_payload,
            pictures=not simulating,
            simulated_only=simulating,
            bed=None if simulating else self.bed,
        )

    def record(self, designer: Designer) -> dict:
        rec = design_record(self.design, designer.short, self.structure)
        if self.catalog is not None:  # which catalog: to reload it, or to tell it changed
            rec["catalog"] = catalog_record(self.catalog)
        if self.structure is not None:
            rec["payload"] = payload_record(self.structure, self.with_payload)
        if self.calibration:
            rec["calibration"] = dict(sorted(self.calibration.items()))
        if self.feedback_gains:
            rec["feedback_gains"] = dict(sorted(self.feedback_gains.items()))
        if self.paces:
            rec["paces"] = dict(sorted(self.paces.items()))
        if self.note is not None and self.structure is None:
            rec["no_structure"] = self.note  # why there is none (the request keeps its params)
        if self.unplanned:
            rec["notes"] = [
                *rec.get("notes", []),
                *(f"dropped {a}: {why}" for a, why in self.unplanned),
            ]
        v = self.verification
        if v is not None:
            rec["verified"] = v.record()
            if v.dropped:
                rec["abilities"] = [a for a in rec["abilities"] if a not in v.dropped]
                rec["notes"] = [
                    *rec.get("notes", []),
                    *(f"dropped {a}: {why}" for a, why in sorted(v.dropped.items())),
                ]
            if v.accepted_unsimulated:
                rec["notes"] = [
                    *rec.get("notes", []),
                    *(
                        f"{a} is not simulated: no behaviour serves it (accepted with "
                        "--allow-unverified)"
                        for a in v.accepted_unsimulated
                    ),
                ]
        elif self.verify_skipped:
            rec["verified"] = {"simulated": False, "note": "not simulated (--no-verify)"}
        if self.infeasible:
            rec["status"] = "infeasible"
            rec["infeasible"] = self.infeasible
        return rec


def run(designer: Designer, req: Request, opts: StructureOptions) -> Outcome:
    """The conceptual step of ``req`` and, for a designed robot, its structure."""
    d = designer.step(req)
    if d.over_limit:  # name the bus whose limit it is
        d = replace(d, note=limit_note(d.over_limit, limit_source(opts)))
    if d.status != "designed":
        return Outcome(d)
    if opts.conceptual:
        return Outcome(d, note="designed with --conceptual: stopped after the conceptual design")

    catalog = load_checked_catalog(opts.catalog, designer)
    loaded = opts.with_payload
    try:
        s = design_structure(
            designer.kb, d.chosen, catalog, designer.structural(req), opts.symmetric, opts.objective
        )
    except InfeasibleError as e:
        return Outcome(d, infeasible=str(e), catalog=catalog, with_payload=loaded)
    d, unplanned = drop_unplannable(designer, d, s)
    if not opts.verify:
        return Outcome(
            d, s, catalog=catalog, verify_skipped=True, with_payload=loaded, unplanned=unplanned
        )

    return verify(
        designer,
        req,
        opts,
        Outcome(d, s, catalog=catalog, with_payload=loaded, unplanned=unplanned),
    )


def drop_unplannable(
    designer: Designer, d: Design, s: Structure
) -> tuple[Design, tuple[tuple[str, str], ...]]:
    """``d`` without the bonus abilities (abilities the chosen robot has but the request
    does not demand) whose behaviours cannot be planned with their default parameters, and
    (ability, why) for each dropped one; the design's note says so. A bonus ability never
    sinks a design: its failed plan drops it, as its failed simulation does
    (:mod:`synth.verification.loop`). A demanded ability's failed plan is left to refuse the request
    where the bundle is written."""

    c = d.chosen
    if c is None:
        return d, ()
    record = design_record(d, designer.short, s)
    try:
        controller = controller_for(DesignGeometry.from_record(record))
    except ValueError:  # no controller serves it: nothing is planned (verify refuses it)
        return d, ()
    served = served_abilities(record, controller)
    need = set(demanded(record))
    need_served = {served.get(a) for a in need} - {None}
    bonus = [a for a in record["abilities"] if a not in need]
    dropped: dict[str, str] = {}
    for name in controller.listed(bonus):
        realises = controller.behaviors[name].realises
        if realises in need_served:
            continue
        try:
            controller.run(name)
        except ValueError as e:
            why = _without_advice(str(e))
            for a in bonus:
                if served.get(a) == realises:
                    dropped.setdefault(
                        a,
                        f"its behaviour {name} cannot be planned with its "
                        f"default parameters ({why})",
                    )
    if not dropped:
        return d, ()
    keep = tuple(a for a in c.abilities if designer.short(a) not in dropped)
    notes = "; ".join(f"dropped the bonus ability {a}: {w}" for a, w in sorted(dropped.items()))
    note = f"{d.note}; {notes}" if d.note else notes
    return replace(d, chosen=replace(c, abilities=keep), note=note), tuple(sorted(dropped.items()))


def _without_advice(why: str) -> str:
    """A planner's error without its advice to the caller of a behaviour (``choose other
    targets``): in a design, no option sets a behaviour's default targets."""
    return re.sub(r";\s*choose other targets\b", "", why).strip()
