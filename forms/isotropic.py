"""The four isotropic hyperelastic laws of docs/laws.md.

| name            | psi(F)                                                         |
|-----------------|----------------------------------------------------------------|
| `stvk`          | mu E:E + (lmbda/2) (tr E)^2                                    |
| `neo_hookean`   | (mu/2)(tr C - 3) - mu ln J + (lmbda/2)(ln J)^2                 |
| `mooney_rivlin` | c1 (Ibar1 - 3) + c2 (Ibar2 - 3) + K (ln J)^2                   |
| `corotated`     | mu ||F - R(F)||^2 + (lmbda/2)(J - 1)^2, R(F) = polar rotation  |

Each is W + (kappa/2) g^2 (forms.law): stvk g = tr E, kappa = lmbda;
neo_hookean g = ln J, kappa = lmbda; mooney_rivlin g = ln J, kappa = 2K;
corotated g = J - 1, kappa = lmbda. The bulk parameter (lmbda, K) may be inf: the
incompressible limit, g(F) = 0 exactly in the mixed formulation (incompressible
neo-Hookean is mu with lmbda = inf; nu = 0.5 stays refused, (E, nu) give finite lmbda).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import ufl

from forms.kinematics import green_lagrange, isochoric_invariants, lame_parameters, right_cauchy_green
from forms.law import Expr, Law, ParameterError, check_keys, require, require_bulk, require_finite
from forms.polar import rotation_not_unique


def _lame_from(law: str, params: dict[str, Any]) -> dict[str, float]:
    """(mu, lmbda) from exactly one of the pairs (E, nu) or (mu, lmbda)."""
    has_E = "E" in params or "nu" in params
    has_mu = "mu" in params or "lmbda" in params
    if has_E and has_mu:
        raise ParameterError(f"{law}: give either (E, nu) or (mu, lmbda), not both")
    if has_E:
        for key in ("E", "nu"):
            if key not in params:
                raise ParameterError(f"{law}: {key} is missing (E and nu go together)")
        E, nu = params["E"], params["nu"]
        require_finite(law, E=E, nu=nu)
        require(E > 0, law, "E", E, "> 0")
        require(-1.0 < nu < 0.5, law, "nu", nu, "in (-1, 0.5)")
        mu, lmbda = lame_parameters(E, nu)
        return {"mu": mu, "lmbda": lmbda}
    if has_mu:
        for key in ("mu", "lmbda"):
            if key not in params:
                raise ParameterError(f"{law}: {key} is missing (mu and lmbda go together)")
        return {"mu": params["mu"], "lmbda": params["lmbda"]}
    raise ParameterError(f"{law}: give either (E, nu) or (mu, lmbda)")


@dataclass(frozen=True)
class _LameLaw(Law):
    """A law parametrised by the Lame constants mu > 0, lmbda > -2 mu / 3 (or inf: incompressible)."""

    mu: float
    lmbda: float
    bulk_parameter: ClassVar[str] = "lmbda"

    def __post_init__(self) -> None:
        require_finite(self.name, mu=self.mu)
        require_bulk(self.name, lmbda=self.lmbda)
        require(self.mu > 0, self.name, "mu", self.mu, "> 0")
        require(self.lmbda + 2.0 * self.mu / 3.0 > 0, self.name, "lmbda", self.lmbda, "> -2 mu / 3")

    @classmethod
    def from_parameters(cls, **params: Any) -> _LameLaw:
        """Build from (E, nu) or (mu, lmbda); any other key is an error naming it."""
        check_keys(cls.name, params, ("E", "nu", "mu", "lmbda"))
        return cls(**_lame_from(cls.name, params))

    @property
    def bulk_penalty(self) -> float:
        return self.lmbda


@dataclass(frozen=True)
class StVenantKirchhoff(_LameLaw):
    """psi = mu E:E + (lmbda/2)(tr E)^2, E = (F^T F - I)/2."""

    name: ClassVar[str] = "stvk"

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        E = green_lagrange(F)
        return self.mu * ufl.inner(E, E)

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.tr(green_lagrange(F))


@dataclass(frozen=True)
class NeoHookean(_LameLaw):
    """psi = (mu/2)(tr C - 3) - mu ln J + (lmbda/2)(ln J)^2."""

    name: ClassVar[str] = "neo_hookean"

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        return 0.5 * self.mu * (ufl.tr(right_cauchy_green(F)) - 3.0) - self.mu * ufl.ln(ufl.det(F))

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.ln(ufl.det(F))


@dataclass(frozen=True)
class Corotated(_LameLaw):
    """psi = mu ||F - R||^2 + (lmbda/2)(J - 1)^2, R = polar rotation of F.

    By the envelope theorem (R minimises ||F - R|| over SO(3)) dW/dF = 2 mu (F - R);
    the residual is built from that stress and UFL differentiates it, with R the
    linearised rotation of forms.polar (exact value and first derivative).
    """

    name: ClassVar[str] = "corotated"
    needs_rotation: ClassVar[bool] = True

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        if R is None:
            raise ValueError("corotated: the polar rotation R is required")
        return self.mu * ufl.inner(F - R, F - R)

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        if R is None:
            raise ValueError("corotated: the polar rotation R is required")
        return 2.0 * self.mu * (F - R)

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.det(F) - 1.0

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where the polar rotation of F is not unique (forms.polar.rotation_not_unique): det F < 0 with
        the two smallest singular values equal (relative 1e-8), or rank F <= 1."""
        return rotation_not_unique(F)


@dataclass(frozen=True)
class MooneyRivlin(Law):
    """psi = c1 (Ibar1 - 3) + c2 (Ibar2 - 3) + K (ln J)^2 (Teran et al. 2003, no factor 1/2 on K)."""

    name: ClassVar[str] = "mooney_rivlin"
    bulk_parameter: ClassVar[str] = "K"
    c1: float
    c2: float
    K: float

    def __post_init__(self) -> None:
        require_finite(self.name, c1=self.c1, c2=self.c2)
        require_bulk(self.name, K=self.K)
        require(self.c1 >= 0, self.name, "c1", self.c1, ">= 0")
        require(self.c2 >= 0, self.name, "c2", self.c2, ">= 0")
        require(self.c1 + self.c2 > 0, self.name, "c1", self.c1, "> 0 when c2 = 0")
        require(self.K > 0, self.name, "K", self.K, "> 0")

    @classmethod
    def from_parameters(cls, **params: Any) -> MooneyRivlin:
        check_keys(cls.name, params, ("c1", "c2", "K"), required=("c1", "c2", "K"))
        return cls(**params)

    @property
    def bulk_penalty(self) -> float:
        return 2.0 * self.K

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        Ibar1, Ibar2 = isochoric_invariants(F)
        return self.c1 * (Ibar1 - 3.0) + self.c2 * (Ibar2 - 3.0)

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.ln(ufl.det(F))
