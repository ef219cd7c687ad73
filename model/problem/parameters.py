"""A law's parameters as runtime values: compile once, run with any numbers.

A parameter held as a Python float is a literal of the generated C kernel: every new value is a new form
signature and a new compile (6-35 s on these machines). ``hold_parameters`` replaces each scalar parameter
of a law by a ``HeldParameter`` (a fem.Constant holding the same number), so that the forms of the same law
with other numbers have the same signature and reuse the compiled kernels (the JIT cache is keyed by it).

Which parameters can be held is found, not declared: a law may use a parameter outside UFL (math.exp(P2),
``if c3 != 0``, ``math.isinf(kappa)``), where a UFL value would either fail or silently take another
branch. A HeldParameter refuses every such use at once: float(), int(), bool() and == / != with a Python
number raise TypeError (UFL's own structural comparisons are between UFL expressions and are kept). Each
parameter is tried alone: the law's expressions are built with it held (``build``, the same calls the
problem makes); any exception keeps that parameter a number. The parameters that pass are then held
together, and the expressions built once more (all of them numbers again if that fails).

``SOFTTISSUE_NUMBER_PARAMETERS=1`` in the environment holds nothing (every parameter a literal of the kernels, as
before): for benchmarks/compile_once.py and for telling a suspected difference apart.

The law keeps its validation: the numbers are checked by the frozen dataclass when the law is made
(forms.law.with_parameter_values checks them again), and the copy holding UFL values is not validated.
A law of the user's own (forms.user_law.UserLaw) holds its parameters as ``values`` pairs; they are held
the same way. Laws with an eigen state computed in numpy from their parameters (ogden) are left as they are.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import warnings
from collections.abc import Callable, Iterator
from typing import Any

from dolfinx import fem

from forms.law import Law, replace_fields, with_parameter_values

log = logging.getLogger(__name__)


class HeldParameter(fem.Constant):
    """A fem.Constant that is never a Python number (module docstring)."""

    def __float__(self) -> float:
        raise TypeError("a held parameter is a UFL value, not a number")

    def __int__(self) -> int:
        raise TypeError("a held parameter is a UFL value, not a number")

    def __complex__(self) -> complex:
        raise TypeError("a held parameter is a UFL value, not a number")

    def __bool__(self) -> bool:
        raise TypeError("a held parameter is a UFL value, not a truth value")

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (int, float, complex)) and not isinstance(other, bool):
            raise TypeError("a held parameter is not compared with numbers")
        return super().__eq__(other)

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)

    __hash__ = fem.Constant.__hash__


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def candidates(law: Law) -> dict[str, float]:
    """The law's finite scalar parameters by name: its float dataclass fields, or a user law's ``values``."""
    if getattr(law, "needs_eigenbasis", False) or not dataclasses.is_dataclass(law):
        return {}
    values = getattr(law, "values", None)
    if isinstance(values, tuple) and all(isinstance(v, tuple) and len(v) == 2 for v in values):  # a user law
        return {name: float(value) for name, value in values if _is_number(value)}
    return {f.name: float(getattr(law, f.name)) for f in dataclasses.fields(law) if _is_number(getattr(law, f.name))}


def curve_constants(material: Any) -> set[str]:
    """The law constants a material's load curves change (model.config.MaterialConfig: ``parameter_curves``,
    ``law_at``): those whose value at t = 1 or at a point of a curve's table differs from t = 0 (E(t) changes
    mu and lmbda). What a curve's load hook sets at every step, and what nothing else may set."""
    curves = material.parameter_curves
    if not curves:
        return set()
    base = candidates(material.law_at(0.0))
    times = sorted({0.0, 1.0, *(t for c in curves.values() for t in c.checked_at)})
    return {name for t in times for name, value in candidates(material.law_at(t)).items() if value != base.get(name)}


def _with(law: Law, held: dict[str, HeldParameter]) -> Law:
    """The law with the parameters ``held`` in place of its numbers."""
    values = getattr(law, "values", None)
    if isinstance(values, tuple) and "values" in {f.name for f in dataclasses.fields(law)}:
        return replace_fields(law, values=tuple((name, held.get(name, value)) for name, value in values))
    return with_parameter_values(law, {name: (c, [float(c.value)]) for name, c in held.items()})


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """UFL's "Couldn't map 'c_0' to a float" (a warning of its logger in UFL 2022, warnings.warn in 2024), said
    when a law's float() of an expression meets a held parameter: expected while probing, not for the user."""
    ufl_log = logging.getLogger("UFL")
    level = ufl_log.level
    ufl_log.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        ufl_log.setLevel(level)


def hold_parameters(law: Law, mesh: Any, build: Callable[[Law], object]) -> tuple[Law, dict[str, HeldParameter]]:
    """(the law holding every parameter it can as a HeldParameter, {name: constant}) (module docstring).

    ``build(law)`` builds every UFL expression the caller needs from a law and raises what the law raises."""
    if os.environ.get("SOFTTISSUE_NUMBER_PARAMETERS") == "1":
        return law, {}
    with _quiet():
        return _hold(law, mesh, build)


def _hold(law: Law, mesh: Any, build: Callable[[Law], object]) -> tuple[Law, dict[str, HeldParameter]]:
    numbers = candidates(law)
    held: dict[str, HeldParameter] = {}
    for name, value in numbers.items():
        constant = HeldParameter(mesh, value)
        try:
            build(_with(law, {name: constant}))
        except Exception as err:  # noqa: BLE001 -- any use outside UFL keeps the number
            log.debug("%s: %s stays a number (%s: %s)", getattr(law, "name", law), name, type(err).__name__, err)
            continue
        held[name] = constant
    if not held:
        return law, {}
    try:
        runtime = _with(law, held)
        build(runtime)
    except Exception as err:  # noqa: BLE001 -- together they fail: every parameter stays a number
        log.debug("%s: the parameters stay numbers (%s: %s)", getattr(law, "name", law), type(err).__name__, err)
        return law, {}
    return runtime, held
