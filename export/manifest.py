"""The schema of ``.parmor``, the list of the files parmor wrote into a folder
(``export.bundle.MARKER``, written by :func:`export.bundle.manifest_text`).

``--force`` (and ``parmor blocks``, ``parmor ros``) replaces only the files this list
names, and only as parmor wrote them; the list is read from a folder that anyone may have
changed, so it is checked like any file a user gives (:func:`check_manifest`): its
``format``, and every name a relative path inside the folder (no ``..``, not absolute, no
empty or ``.`` part) with the SHA-256 of its bytes. What the schema cannot say (whether a
listed file is still as parmor wrote it) is checked against the folder by the writer.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, PlainValidator, WithJsonSchema

from adron.schema import Closed, described, json_schema, validate

#: the format of the list a bundle folder holds (``export.bundle.MARKER``)
MANIFEST_FORMAT = "parmor-files-1"
#: longest name of a listed file (bytes of a path on Linux)
MAX_PATH = 4096


def _relative(v: Any) -> str:
    if not isinstance(v, str) or not v:
        raise ValueError("not a file name")
    if len(v) > MAX_PATH or any(c in v for c in "\x00\n\r\\"):
        raise ValueError(f"not a file name (one line of at most {MAX_PATH} characters, no '\\')")
    parts = v.split("/")
    if v.startswith("/") or any(p in ("", ".", "..") for p in parts):
        raise ValueError(
            "not a name inside the folder (a relative path without '..', '.' or empty parts)"
        )
    if parts == [".parmor"]:
        raise ValueError("the list does not list itself")
    return v


#: a file's name inside the folder, with '/' between its parts
RelativeName = Annotated[
    str,
    PlainValidator(_relative),
    WithJsonSchema(
        {
            "type": "string",
            "minLength": 1,
            "maxLength": MAX_PATH,
            "pattern": "^(?!/)(?!(.*/)?\\.\\.?(/|$))(?!.*//)(?!\\.parmor$)[^\\\\\\x00\\n\\r]+$",
            "description": "a relative path inside the folder, '/' between its parts",
        }
    ),
]
Digest = Annotated[
    str,
    Field(pattern="^sha256:[0-9a-f]{64}$", description="sha256: and the hex digest of its bytes"),
]


class Manifest(Closed):
    """``.parmor``: the files parmor wrote into this folder, with their SHA-256."""

    format: Literal[MANIFEST_FORMAT] = described(doc="the list's format")
    note: Annotated[str, Field(max_length=1000)] = described("", "what the list is for")
    files: dict[RelativeName, Digest] = described(doc="file name -> 'sha256:<hex>'")


def check_manifest(body: Any, where: str, error: type[Exception]) -> Manifest:
    """``body`` (the parsed ``.parmor`` at ``where``) checked against :class:`Manifest`;
    ``error`` naming ``where``, the key path and the value otherwise."""

    def refused(message: str) -> Exception:
        return error(f"{message} (not parmor's list of its files)")

    return validate(Manifest, body, where, refused)


def schema() -> dict:
    return json_schema(Manifest, "manifest", Manifest.__doc__ or "")
