"""The project's exceptions (a leaf module: it imports nothing of ours).

ConfigError: bad input, found before any solve; the message is one line that starts with the
dotted key it is about, e.g. ``material[0].nu: 0.5 is out of range, must be in (-1, 0.5)``.
SolveFailed: the solver gave up (after the allowed cut-backs); the message holds the last SNES
reason, and everything written before stays readable.
OutputFailed (a SolveFailed: exit 1): the operating system refused a write (a full disk, a folder that is not
writable or turned read-only); the message is one line naming the path, and the steps written before stay readable.
"""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration error; the message names the offending key."""


class SolveFailed(RuntimeError):
    """The load or time stepping gave up; the message holds the last SNES reason."""


class OutputFailed(SolveFailed):
    """A write of the results failed (OSError); the message names the path and what the system said."""


def os_error_message(err: OSError, what: str = "cannot write") -> str:
    """One line for an OSError: ``PATH: what (strerror)``; the path is the error's file name where it has one."""
    path = err.filename if err.filename is not None else "?"
    reason = err.strerror or str(err) or type(err).__name__
    return f"{path}: {what} ({reason})"


__all__ = ["ConfigError", "OutputFailed", "SolveFailed", "os_error_message"]
