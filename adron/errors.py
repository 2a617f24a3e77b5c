"""The one exception hierarchy of parmor.

Every error a user can cause derives from :class:`ParmorError`; the CLI maps each
subclass to an exit code and prints its message without a traceback.
"""

from __future__ import annotations


class ParmorError(Exception):
    """Base of all parmor errors. ``exit_code`` is what the CLI returns."""

    exit_code = 2


class InputError(ParmorError):
    """Bad input: unknown ability or parameter, malformed value or file, refused file."""

    exit_code = 2


class KifSyntaxError(InputError):
    """A SUO-KIF text that cannot be read; carries file, line and column (1-based)."""

    def __init__(self, message: str, file: str, line: int, col: int) -> None:
        self.file, self.line, self.col, self.reason = file, line, col, message
        super().__init__(f"{file}:{line}:{col}: {message}")


class OntologyError(InputError):
    """An ontology that parses but is inconsistent with what parmor needs."""


class UnsatisfiableError(ParmorError):
    """The request cannot be met by any robot the knowledge base defines."""

    exit_code = 1


class InfeasibleError(ParmorError):
    """A structure cannot be sized to meet a requirement."""

    exit_code = 1


class AnswerNeeded(ParmorError):
    """A question must be answered but input is off (``--no-input`` or no terminal)."""

    exit_code = 3


class ExportError(ParmorError):
    """Writing the output bundle failed."""

    exit_code = 2
