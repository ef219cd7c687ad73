"""The interface every material law implements, and the project's parameter error.

Each law splits its energy density into a part W and a volumetric penalty,

    psi(F) = W(F; R) + (kappa / 2) g(F)^2,

so that the same law serves the pure-displacement formulation (psi as written)
and the mixed displacement-pressure formulation (Taylor-Hood), whose energy is

    Pi(u, p) = W(F; R) + p g(F) - p^2 / (2 kappa),

stationary in p at p = kappa g(F), which gives back psi exactly.
R is the polar rotation (forms.polar) for laws that need it, else unused.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar

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


class Law(ABC):
    """A hyperelastic law psi(F) = W(F; R) + (kappa/2) g(F)^2 (see module docstring)."""

    name: ClassVar[str]
    #: True when W needs the polar rotation R of ``rotation_argument(F)``.
    needs_rotation: ClassVar[bool] = False

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

    def rotation_argument(self, F: Expr) -> Expr:
        """M whose polar rotation R* the law uses (F unless a law says otherwise)."""
        return F

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        """dW/dF, derived by UFL. Laws with a polar rotation override it (envelope theorem)."""
        Fv = ufl.variable(F)
        return ufl.diff(self.reduced_energy(Fv, R), Fv)

    def energy(self, F: Expr, R: Expr | None = None) -> Expr:
        """psi(F) = W(F; R) + (kappa/2) g(F)^2."""
        g = self.volume_constraint(F)
        return self.reduced_energy(F, R) + 0.5 * self.bulk_penalty * g**2

    def stress(self, F: Expr, R: Expr | None = None, p: Expr | None = None) -> Expr:
        """First Piola-Kirchhoff stress P = dW/dF + p dg/dF, with p = kappa g(F) unless given.

        With p = None this is dpsi/dF; with p the mixed field it is the stress of Pi(u, p).
        """
        Fv = ufl.variable(F)
        g = self.volume_constraint(Fv)
        if p is None:
            p = self.bulk_penalty * g
        return self.reduced_stress(F, R) + p * ufl.diff(g, Fv)

    def parameters(self) -> dict[str, float]:
        """Every parameter of the law, by name."""
        return {k: float(v) for k, v in vars(self).items()}
