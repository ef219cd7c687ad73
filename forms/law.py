"""The interface every material law implements, and the project's parameter error.

Each law splits its energy density into a part W and a volumetric penalty,

    psi(F) = W(F; R) + (kappa / 2) g(F)^2,

so that the same law serves the pure-displacement formulation (psi as written)
and the mixed displacement-pressure formulation (Taylor-Hood), whose energy is

    Pi(u, p) = W(F; R) + p g(F) - p^2 / (2 kappa),

stationary in p at p = kappa g(F), which gives back psi exactly.
R is the polar rotation (forms.polar) for laws that need it, else unused.

Exact incompressibility is the limit kappa = inf, given as the law's bulk parameter
(``bulk_parameter``: lmbda, K or kappa) = inf. Then psi is undefined (only the constraint g(F) = 0
remains) and the mixed energy loses its last term,

    Pi(u, p) = W(F; R) + p g(F),        p the Lagrange multiplier of g(F) = 0,

whose pressure equation is g(F) q dx = 0 (``pressure_residual``). ``energy`` and a stress without
p refuse such a law (ValueError naming the parameter), so inf never reaches a form: only the mixed
formulation can use it.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from typing import Any, ClassVar

import numpy as np
import ufl

Expr = ufl.core.expr.Expr


class ParameterError(ValueError):
    """A material parameter is missing, unknown or out of range; the message names it."""


def require(condition: bool, law: str, key: str, value: Any, allowed: str) -> None:
    """Raise ParameterError("law: key = value, must be allowed") unless condition holds."""
    if not condition:
        raise ParameterError(f"{law}: {key} = {value!r}, must be {allowed}")


def check_keys(law: str, params: dict[str, Any], allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> None:
    """ParameterError for the first unknown key ("unknown parameter 'x' (allowed: ...)") or missing one."""
    unknown = set(params) - set(allowed)
    if unknown:
        raise ParameterError(f"{law}: unknown parameter {sorted(unknown)[0]!r} (allowed: {', '.join(allowed)})")
    for key in required:
        if key not in params:
            raise ParameterError(f"{law}: {key} is missing")


def require_finite(law: str, **values: float) -> None:
    """Every value is a real finite number."""
    for key, value in values.items():
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        require(ok, law, key, value, "a finite number")


def require_bulk(law: str, **values: float) -> None:
    """Every value is a real number, finite or +inf (a bulk parameter: inf is the incompressible limit)."""
    for key, value in values.items():
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and (math.isfinite(value)
                                                                                  or value == math.inf)
        require(ok, law, key, value, "a finite number or inf (incompressible)")


class Law(ABC):
    """A hyperelastic law psi(F) = W(F; R) + (kappa/2) g(F)^2 (see module docstring)."""

    name: ClassVar[str]
    #: True when W needs the polar rotation R of ``rotation_argument(F)``.
    needs_rotation: ClassVar[bool] = False
    #: the parameter that sets kappa (lmbda, K or kappa); inf there is the incompressible limit
    bulk_parameter: ClassVar[str] = "kappa"

    @abstractmethod
    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        """W(F; R): the energy density without the volumetric penalty."""

    @abstractmethod
    def volume_constraint(self, F: Expr) -> Expr:
        """g(F), the measure of volume change penalised by kappa."""

    @property
    @abstractmethod
    def bulk_penalty(self) -> float:
        """kappa, the penalty factor of (kappa/2) g(F)^2."""

    @property
    def incompressible(self) -> bool:
        """True when kappa = inf: g(F) = 0 exactly, enforced by the mixed formulation's pressure. A bulk
        parameter held as a UFL value (with_parameter_values) is finite: its numbers were checked."""
        kappa = self.bulk_penalty
        return not isinstance(kappa, Expr) and math.isinf(kappa)

    def require_compressible(self, what: str) -> None:
        """ValueError naming the bulk parameter when kappa = inf (``what`` needs a finite kappa)."""
        if self.incompressible:
            value = getattr(self, self.bulk_parameter, self.bulk_penalty)
            raise ValueError(f"{self.name}: {self.bulk_parameter} = {value!r} (incompressible) has no {what}: "
                             "use the mixed formulation (formulation = 'mixed', Taylor-Hood), whose pressure "
                             "enforces g(F) = 0 exactly")

    def rotation_argument(self, F: Expr) -> Expr:
        """M whose polar rotation R* the law uses (F unless a law says otherwise)."""
        return F

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        """dW/dF, derived by UFL. Laws with a polar rotation override it (envelope theorem), and the fibre
        laws (chain rule through scalar invariants, each factor derived by UFL: forms.muscle)."""
        Fv = ufl.variable(F)
        return ufl.diff(self.reduced_energy(Fv, R), Fv)

    def energy(self, F: Expr, R: Expr | None = None) -> Expr:
        """psi(F) = W(F; R) + (kappa/2) g(F)^2 (ValueError when kappa = inf: see mixed_energy)."""
        self.require_compressible("energy psi(F) (the penalty (kappa/2) g^2 is infinite)")
        g = self.volume_constraint(F)
        return self.reduced_energy(F, R) + 0.5 * self.bulk_penalty * g**2

    def mixed_energy(self, F: Expr, p: Expr, R: Expr | None = None) -> Expr:
        """Pi(u, p) density W(F; R) + p g(F) - p^2 / (2 kappa); the last term is absent when kappa = inf."""
        self.require_mixed()
        energy = self.reduced_energy(F, R) + p * self.volume_constraint(F)
        return energy if self.incompressible else energy - p**2 / (2.0 * self.bulk_penalty)

    def require_mixed(self) -> None:
        """ValueError naming the bulk parameter when kappa = 0: the mixed formulation needs kappa > 0 (or inf)."""
        if self.bulk_penalty == 0:
            value = getattr(self, self.bulk_parameter, self.bulk_penalty)
            raise ValueError(f"{self.name}: {self.bulk_parameter} = {value!r}: the mixed formulation needs "
                             f"{self.bulk_parameter} > 0 (or inf for incompressible); with no volumetric term "
                             "use the displacement formulation")

    def pressure_residual(self, F: Expr, p: Expr) -> Expr:
        """The mixed formulation's pressure equation dPi/dp: g(F) - p / kappa, or g(F) when kappa = inf."""
        self.require_mixed()
        g = self.volume_constraint(F)
        return g if self.incompressible else g - p / self.bulk_penalty

    def stress(self, F: Expr, R: Expr | None = None, p: Expr | None = None) -> Expr:
        """First Piola-Kirchhoff stress P = dW/dF + p dg/dF, with p = kappa g(F) unless given.

        With p = None this is dpsi/dF (ValueError when kappa = inf); with p the mixed field it is
        the stress of Pi(u, p).
        """
        Fv = ufl.variable(F)
        g = self.volume_constraint(Fv)
        if p is None:
            self.require_compressible("stress dpsi/dF without a pressure field")
            p = self.bulk_penalty * g
        return self.reduced_stress(F, R) + p * ufl.diff(g, Fv)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """(N,) bool: True where A = dP/dF does not exist at the numpy F (N,3,3): a breakpoint of a
        piecewise curve of the law, or a rotation that is not unique; within a relative 1e-8.

        ``fields`` are numpy arrays per sample (S (N,3,3), a0 (N,3), s0 (N,3), alpha (N,)). Laws with
        such points override this; psi is still defined there, and so is P except where ``stress_undefined``
        says otherwise (verify avoids these samples when it emits them, and leaves A out of a check there,
        with a count).
        """
        return np.zeros(len(np.reshape(F, (-1, 3, 3))), dtype=bool)

    def stress_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """(N,) bool: True where P = dpsi/dF itself does not exist at the numpy F (N,3,3).

        For a law with the polar rotation (``needs_rotation``) these are the points where the rotation is not
        unique (its ``tangent_undefined``): there psi = mu min_{R in SO(3)} ||M - R||^2 + ... has a kink
        (with det M < 0, max_R tr(M^T R) = s1 + s2 - s3 and s2 - s3 is |x|-like at s2 = s3), so P is only
        one of its one-sided derivatives. Nowhere for every other law: a fibre curve's breakpoints are C1
        points of psi (P is continuous, only A jumps).
        """
        if self.needs_rotation:
            return np.asarray(self.tangent_undefined(F, **fields), dtype=bool)
        return np.zeros(len(np.reshape(F, (-1, 3, 3))), dtype=bool)

    def parameters(self) -> dict[str, float]:
        """Every parameter of the law, by name."""
        return {k: float(v) for k, v in vars(self).items()}


def with_parameter_values(law: Law, values: Mapping[str, tuple[Expr, Iterable[float]]]) -> Law:
    """The law with each scalar parameter ``name`` of ``values`` replaced by its UFL scalar (a fem.Constant, or a
    DG0 Function for a parameter per cell) that holds the given numbers, so that ufl.derivative differentiates
    the law's energy, stress and pressure equation with respect to it (e.g. dR/dmu of the residual,
    model.solvers.adjoint.material_gradient).

    The law's own validation (__post_init__) runs on the numbers: for each parameter and each of its distinct
    numbers, the law rebuilt with that float (dataclasses.replace; the other replaced parameters at their first
    number) must be valid, else its ParameterError. The copy returned holds the UFL values in place of the
    floats (replace_fields: the fields are set on a shallow copy, which is not validated again). Every other
    field (fibres a0, activation alpha, targets S, an eigen state) is the law's own. ValueError when a name is not
    a float field of the law, or is its bulk parameter at inf (the incompressible limit has no derivative).
    """
    names = {f.name for f in dataclasses.fields(law)} if dataclasses.is_dataclass(law) else set()
    numbers: dict[str, list[float]] = {}
    for name, (_, given) in values.items():
        if name not in names:
            raise ValueError(f"{law.name}: no parameter {name!r} (parameters: {', '.join(sorted(law.parameters()))})")
        current = getattr(law, name)
        if isinstance(current, bool) or not isinstance(current, (int, float)):
            raise ValueError(f"{law.name}: {name} = {current!r} is not a number")
        if math.isinf(current):
            raise ValueError(f"{law.name}: {name} = inf (incompressible) has no derivative")
        numbers[name] = sorted(set(float(x) for x in given)) or [float(current)]
    first = {name: given[0] for name, given in numbers.items()}
    for name, given in numbers.items():
        for number in given:
            dataclasses.replace(law, **{**first, name: number})  # the law's validation on the numbers
    return replace_fields(law, **{name: value for name, (value, _) in values.items()})


def replace_fields(law: Law, **changes: Any) -> Law:
    """A copy of the (valid) frozen dataclass law with ``changes`` set and not validated again: fields (alpha, a0,
    S) and parameters held as UFL values (with_parameter_values), whose numbers the caller has checked."""
    out = copy.copy(law)
    for name, value in changes.items():
        object.__setattr__(out, name, value)
    return out
