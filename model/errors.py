"""The project's exceptions (a leaf module: it imports nothing of ours).

ConfigError: bad input, found before any solve; the message is one line that starts with the
dotted key it is about, e.g. ``material[0].nu: 0.5 is out of range, must be in (-1, 0.5)``.
SolveFailed: the solver gave up (after the allowed cut-backs); the message holds the last SNES
reason, and everything written before stays readable.
"""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration error; the message names the offending key."""


class SolveFailed(RuntimeError):
    """The load or time stepping gave up; the message holds the last SNES reason."""


__all__ = ["ConfigError", "SolveFailed"]
