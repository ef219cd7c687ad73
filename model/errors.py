"""The project's exceptions (a leaf module: it imports nothing of ours).

ConfigError: bad input, found before any solve; the message is one line that starts with the
dotted key it is about, e.g. ``material[0].nu: 0.5 is out of range, must be in (-1, 0.5)``.
SolveFailed: the solver gave up (after the allowed cut-backs); the message holds the last SNES
reason, and everything written before stays readable. ``did_you_mean`` words the closest valid name to a
misspelt one, for the messages that refuse it.
OutputFailed (a SolveFailed: exit 1): the operating system refused a write (a full disk, a folder that is not
writable or turned read-only); the message is one line naming the path, and the steps written before stay readable.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


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



def closest(word: str, choices: Iterable[str]) -> str | None:
    """The valid name ``word`` most likely misspells (case ignored), or None when none is close."""
    choices = [c for c in choices if isinstance(c, str)]
    folded = {c.lower(): c for c in choices}
    match = difflib.get_close_matches(word.lower(), list(folded), n=1, cutoff=0.6)
    return folded[match[0]] if match and folded[match[0]] != word else None


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """" (did you mean 'neo_hookean'?)" for the closest of ``choices`` to ``word``, or "" when none is close."""
    match = closest(word, choices) if isinstance(word, str) else None
    return f" (did you mean {match!r}?)" if match else ""


__all__ = ["ConfigError", "OutputFailed", "SolveFailed", "closest", "did_you_mean", "os_error_message"]
