"""Writing an output folder atomically: all files appear together or none do."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

from adron.errors import ExportError


def write_bundle(out: str | Path, files: Mapping[str, str | bytes], force: bool = False) -> Path:
    """Write ``files`` (relative name -> content) into the folder ``out``.

    The files are written to a temporary sibling folder that is then renamed into place,
    so an error leaves nothing half-written. An existing ``out`` is an error unless
    ``force``, in which case it is replaced whole.
    """
    out = Path(out)
    if out.exists() and not force:
        raise ExportError(f"{out}: already exists; pass --force to replace it")
    if out.exists() and not out.is_dir():
        raise ExportError(f"{out}: exists and is not a folder")
    parent = out.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    except OSError as e:
        raise ExportError(f"{out}: cannot create: {e.strerror}") from None
    try:
        for name, content in sorted(files.items()):
            target = tmp / name
            target.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, str):
                target.write_text(content, encoding="utf-8", newline="\n")
            else:
                target.write_bytes(content)
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=parent))
            out.rename(old / "x")
            tmp.rename(out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(out)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        raise ExportError(f"{out}: cannot write: {e.strerror}") from None
    return out
