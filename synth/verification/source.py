"""The one bundle reader: a design's bundle, on disk or in memory, read once.

A bundle (``parmor design --out DIR``, or :meth:`synth.pipeline.Outcome.files` in memory)
gives the record (``design.json``) and the MuJoCo model (``robot.xml`` with its meshes).
:class:`Bundle` is what every runner reads it through (``parmor simulate``, ``run``,
``blocks``, the ROS node, the design loop, the studies): the record parsed and checked
(:mod:`export.record_schema`), the model's text carrying the design's payload
(:func:`synth.verification.simulate.carrying_payload`), its meshes, the nominal model
compiled once and the controller set up for it (:func:`synth.verification.runs.
controller_for_model`), each on first use. A bad bundle is an :class:`InputError` naming
the file and what is wrong with it (exit 2).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from adron import readers
from adron.errors import InputError
from export.mjcf import load_mjcf
from export.record_schema import check_record as check
from gaits import CONTROLLERS, structure
from gaits.base import DesignGeometry
from synth.verification.simulate import carrying_payload, check_agrees


def _text(v: str | bytes) -> str:
    return v.decode("utf-8") if isinstance(v, bytes) else v


class Bundle:
    """A design's bundle: ``files`` (design.json, robot.xml and meshes/*.stl, keys relative
    to the bundle folder) held in memory, or a ``folder`` read on demand (:meth:`read`)."""

    def __init__(
        self,
        files: Mapping[str, str | bytes] | None = None,
        *,
        folder: str | Path | None = None,
        record: dict | None = None,
    ) -> None:
        if files is None and folder is None:
            raise ValueError("a Bundle needs its files or its folder")
        self.folder = None if folder is None else Path(folder)
        self._files = None if files is None else dict(files)
        if record is None:
            record = readers.parse_json(_text(self.files["design.json"]), "design.json")
            check_record(record, "design.json")
        self.record: dict = record
        self._xml: str | None = None
        self._meshes: dict[str, bytes] | None = None
        self._model: Any = None
        self._controller: Any = None

    @classmethod
    def read(cls, folder: str | Path, structure: bool = True) -> Bundle:
        """The bundle in ``folder``: its design.json read and checked now (InputError naming
        the file when it is missing, unreadable or not a record, or, with ``structure``, a
        conceptual design with no structure to run), its model when first used."""
        return cls(folder=folder, record=folder_record(folder, structure))

    @property
    def source(self) -> str:
        """How messages name the bundle: its folder, or ``bundle`` for one in memory."""
        return str(self.folder) if self.folder is not None else "bundle"

    @property
    def files(self) -> dict[str, str | bytes]:
        """design.json, robot.xml and meshes/*.stl (what a run reads)."""
        if self._files is None:
            folder = self.folder
            assert folder is not None
            try:
                files: dict[str, str | bytes] = {
                    f"meshes/{p.name}": p.read_bytes()
                    for p in sorted((folder / "meshes").glob("*.stl"))
                }
                for name in ("design.json", "robot.xml"):
                    files[name] = (folder / name).read_bytes()
            except OSError as e:
                raise self._unloadable(e) from None
            self._files = files
        return self._files

    @property
    def xml(self) -> str:
        """robot.xml's text carrying the design's payload, checked to be the record's robot
        (:func:`synth.verification.simulate.check_agrees`)."""
        if self._xml is None:
            text = _text(self.files["robot.xml"])
            try:
                check_agrees(text, self.record)
            except InputError as e:  # "design.json: ...": in its folder
                if self.folder is None:
                    raise
                raise InputError(f"{self.folder / str(e)}") from None
            try:
                self._xml = carrying_payload(text, self.record)
            except (ValueError, SyntaxError) as e:  # xml.etree's ParseError too
                raise self._unloadable(e) from None
        return self._xml

    @property
    def meshes(self) -> dict[str, bytes]:
        """Mesh file name -> bytes."""
        if self._meshes is None:
            self._meshes = {
                Path(k).name: (v.encode() if isinstance(v, str) else v)
                for k, v in sorted(self.files.items())
                if k.endswith(".stl")
            }
        return self._meshes

    def compile(self, xml: str | None = None):
        """The MuJoCo model of ``xml`` (default: :attr:`xml`, the nominal robot) with the
        bundle's meshes; InputError naming the bundle when it does not compile."""

        try:
            return load_mjcf(self.xml if xml is None else xml, dict(self.meshes))
        except (OSError, ValueError, KeyError, SyntaxError) as e:
            raise self._unloadable(e) from None

    def model(self):
        """The nominal MuJoCo model, compiled once; InputError when it holds no robot."""
        if self._model is None:
            model = self.compile()
            if model.nbody < 2:
                raise InputError(
                    f"{self.source}/robot.xml: no robot body (not a model parmor wrote)"
                )
            self._model = model
        return self._model

    def controller(self):
        """The design's controller set up for the nominal model
        (:func:`synth.verification.runs.controller_for_model`), built once."""
        if self._controller is None:
            from synth.verification.runs import controller_for_model

            self._controller = controller_for_model(self.record, self.model())
        return self._controller

    def with_files(self, changed: Mapping[str, str | bytes]) -> Bundle:
        """This bundle with some files replaced (a replay's variant: another servo, other
        gains), read again from them."""
        return Bundle({**self.files, **changed})

    def _unloadable(self, e: Exception) -> InputError:
        why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        return InputError(f"{self.source}: cannot load the MuJoCo model robot.xml: {why}")


def check_record(record: object, source: str) -> None:
    """InputError naming ``source``, the key and the value when ``record`` is not a design
    record of this parmor's format (:mod:`export.record_schema`)."""

    check(record, source)


def folder_record(folder: str | Path, structure: bool = True) -> dict:
    """The design record (``design.json``) of a bundle folder, checked (:meth:`Bundle.read`)."""
    folder = Path(folder)
    path = folder / "design.json"
    if not path.exists():
        raise InputError(f"{folder}: no design.json (write one with 'parmor design ... --out DIR')")
    record = readers.read_json(path, what="design record")  # nesting and numbers bounded
    check_record(record, str(path))  # the fields readers use, typed (export/record_schema)
    if structure and record.get("template") is None:
        raise InputError(f"{path}: the design has no structure (designed with --conceptual?)")
    if structure:
        check_geometry(record, str(path))
    return record


def check_geometry(record: Mapping, source: str) -> None:
    """InputError naming ``source`` when the record's ``template``, ``body_plan`` and
    ``lengths_m`` do not make a robot (the one its controller is built for): each field is
    typed on its own (:func:`check_record`), this is how they fit together."""

    try:
        geometry = DesignGeometry.from_record(record)
        template = geometry.build()
        kind = structure(geometry)
        if kind not in CONTROLLERS:  # (a record whose parts no controller drives)
            raise ValueError(f"its structure is {kind or 'none known'}: no controller drives it")
    except (ValueError, KeyError, TypeError) as e:
        why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise InputError(
            f"{source}: template, body_plan, lengths_m: they do not make the design's robot: {why}"
        ) from None
    listed = {j["name"] for j in record.get("joints") or ()}
    listed |= set(record.get("passive_joints") or ())
    passive = set(getattr(template, "passive", ()) or ())
    moving = [j.name for j in template.model.joints if j.kind != "fixed" and j.name not in passive]
    missing = [n for n in moving if n not in listed]
    if missing:
        raise InputError(
            f"{source}: joints: the robot's joint(s) {', '.join(missing[:6])} are not listed "
            "(a joint's actuator and speed come from its entry)"
        )
