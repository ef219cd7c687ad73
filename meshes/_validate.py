"""Parameter validation shared by the mesh generators.

Every check raises :class:`ParameterError` (a :class:`ValueError`) with a message of the form
``"<generator>: <parameter> must be ..., got <value>"`` so that callers of
:func:`meshes.generate` can tell which generator and which parameter were wrong.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Integral, Real

#: the largest count a generator takes (cells along an edge, divisions ...)
MAX_COUNT = 10_000
#: the most hexahedra (before the split into tetrahedra) a block generator makes: 5e7 x 6 tetrahedra, about 3e8
#: unknowns, more than the 24 GB of the machines this runs on hold (1e6 unknowns took 7.3 GB on 2 ranks)
MAX_CELLS = 50_000_000

__all__ = [
    "MAX_CELLS",
    "MAX_COUNT",
    "ParameterError",
    "positive_float",
    "positive_floats",
    "positive_int",
    "positive_ints",
]


class ParameterError(ValueError, TypeError):
    """A mesh generator parameter is unknown, of the wrong type or out of range.

    It is a :class:`ValueError` (the documented contract of :func:`meshes.generate`)
    and also a :class:`TypeError`, so either can be caught.
    """


def positive_float(generator: str, name: str, value: object) -> float:
    """Return ``value`` as a float after checking it is a finite real number > 0."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ParameterError(f"{generator}: {name} must be a real number > 0, got {value!r}")
    result = float(value)
    if not math.isfinite(result) or result <= 0.0:
        raise ParameterError(f"{generator}: {name} must be > 0, got {result!r}")
    return result


def positive_int(generator: str, name: str, value: object) -> int:
    """Return ``value`` as an int after checking it is an integer in [1, MAX_COUNT] (bools are rejected)."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise ParameterError(f"{generator}: {name} must be an integer >= 1, got {value!r}")
    result = int(value)
    if result < 1:
        raise ParameterError(f"{generator}: {name} must be >= 1, got {result!r}")
    if result > MAX_COUNT:
        raise ParameterError(f"{generator}: {name} must be <= {MAX_COUNT}, got {result!r}")
    return result


def _entries(generator: str, name: str, value: object, length: int) -> Sequence[object]:
    """Check that ``value`` is a non-string sequence with exactly ``length`` entries."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ParameterError(f"{generator}: {name} must be a sequence of {length} numbers, got {value!r}")
    if len(value) != length:
        raise ParameterError(f"{generator}: {name} must have {length} entries, got {len(value)}: {value!r}")
    return value


def positive_floats(generator: str, name: str, value: object, length: int) -> tuple[float, ...]:
    """Validate a sequence of ``length`` finite reals > 0 and return it as a tuple of floats."""
    entries = _entries(generator, name, value, length)
    return tuple(positive_float(generator, f"{name}[{i}]", v) for i, v in enumerate(entries))


def positive_ints(generator: str, name: str, value: object, length: int) -> tuple[int, ...]:
    """Validate a sequence of ``length`` integers >= 1 and return it as a tuple of ints."""
    entries = _entries(generator, name, value, length)
    counts = tuple(positive_int(generator, f"{name}[{i}]", v) for i, v in enumerate(entries))
    if name == "cells" and math.prod(counts) > MAX_CELLS:
        raise ParameterError(f"{generator}: {name} {list(counts)} make {math.prod(counts):.3g} cells, more than "
                             f"{MAX_CELLS:.0e}: far beyond the memory of a workstation")
    return counts
