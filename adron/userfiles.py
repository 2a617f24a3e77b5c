"""A user's input file must be a regular file: checked before it is opened.

Opening a named pipe (FIFO) for reading waits until something writes to it, and a device
(``/dev/zero``, ``/dev/urandom``) never ends: given as ``--catalog``, ``--ontology``,
``--rules`` or in a suite or study, either would hold the command until its time limit.
Such a path is refused at once (InputError, exit 2) naming it and what it is.
Import-light: nothing but the standard library.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from adron.errors import InputError

__all__ = ["check_regular"]

_KINDS = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def check_regular(path: str | Path, source: str | None = None) -> None:
    """InputError naming ``source`` (default: the path) when ``path`` (its symbolic links
    followed) is a named pipe, a device or a socket: reading it would wait for a writer or
    never end. A missing file, a folder or one that cannot be examined is left to the
    reader, whose message says so."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    raise InputError(
        f"{path if source is None else source}: is {kind}, not a file; parmor reads input "
        "files whole, so give the path of a regular file"
    )
