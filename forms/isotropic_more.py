"""More isotropic laws beside forms/isotropic.py's four: the graphics laws and Yeoh (issue 11).

The module's name says what it holds: isotropic laws added after the first four, kept apart so that
forms/isotropic.py (whose classes other code subclasses and imports) stays as it was.

| name                 | psi(F)                                                                     |
|----------------------|----------------------------------------------------------------------------|
| `stable_neo_hookean` | variant = "rest_stable" (Kim & Eberle 2022, HOBAK's SNH):                  |
|                      |   (ms/2)(Ic - 3) - ms (J - 1) + (ls/2)(J - 1)^2, ms = mu, ls = lmbda + mu  |
|                      | variant = "paper" (Smith, de Goes & Kim 2018, eq. 14):                     |
|                      |   (ms/2)(Ic - 3) + (ls/2)(J - alpha)^2 - (ms/2) ln(Ic + 1),                |
|                      |   ms = 4 mu / 3, ls = lmbda + 5 mu / 6, alpha = 1 + 3 ms / (4 ls)          |
| `yeoh`               | c1 (Ibar1 - 3) + c2 (Ibar1 - 3)^2 + c3 (Ibar1 - 3)^3 + (kappa/2)(ln J)^2   |
| `fixed_corotated`    | mu ||F - R||^2 + (lmbda/2)(J - 1)^2  (Stomakhin et al. 2012; = corotated)  |
| `arap`               | mu ||F - R||^2  (HOBAK's ARAP; = corotated with lmbda = 0)                 |

Ic = tr(F^T F) = ||F||^2, J = det F, Ibar1 = J^(-2/3) Ic, R the polar rotation of F (forms.polar).
(mu, lmbda) are the Lame constants of linear elasticity, given as (mu, lmbda) or (E, nu); the
stable Neo-Hookean laws reparametrise them (ms, ls) so that their small-strain tangent is linear
elasticity's with (mu, lmbda) (Smith et al. 2018, section 3.4). Both variants have P(I) = 0.

Mixed split psi = W + (kappa/2) g(F)^2 (forms.law):
- stable_neo_hookean: g = J - 1, kappa = ls; W = (ms/2)(Ic - 3) - ms (J - 1) (rest_stable) or
  (ms/2)(Ic - 3) - (ms/2) ln(Ic + 1) - (3 ms / 4)(J - 1) + 9 ms^2 / (32 ls) (paper: (ls/2)(J - alpha)^2
  expanded about J = 1, alpha - 1 = 3 ms / (4 ls)); lmbda = inf is incompressible (ls = inf);
- yeoh: g = ln J, kappa = kappa (FEBio's default uncoupled U(J) = (k/2)(ln J)^2);
- fixed_corotated: as corotated (g = J - 1, kappa = lmbda); arap: no volumetric term (kappa = 0).
The aliases are subclasses of forms.isotropic.Corotated that only rename it (and, for arap, fix
lmbda = 0): their values are corotated's, computed by the same code.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import ufl

from forms.isotropic import Corotated, _lame_from, _LameLaw
from forms.kinematics import isochoric_invariants
from forms.law import Expr, Law, check_keys, require, require_bulk, require_finite

#: the two forms of the stable Neo-Hookean energy (``variant``)
SNH_VARIANTS = ("rest_stable", "paper")


@dataclass(frozen=True)
class StableNeoHookean(_LameLaw):
    """Stable Neo-Hookean (Smith, de Goes & Kim 2018), mu, lmbda the Lame constants of linear elasticity.

    variant = "rest_stable" (Kim & Eberle 2022, Dynamic Deformables; HOBAK's SNH.cpp):
        psi = (ms/2)(Ic - 3) - ms (J - 1) + (ls/2)(J - 1)^2,             ms = mu, ls = lmbda + mu
    variant = "paper" (Smith et al. 2018, eq. 14, with the Lame reparametrisation of its section 3.4):
        psi = (ms/2)(Ic - 3) + (ls/2)(J - alpha)^2 - (ms/2) ln(Ic + 1),   ms = 4 mu / 3,
        ls = lmbda + 5 mu / 6, alpha = 1 + 3 ms / (4 ls)
    Ic = ||F||^2. Defined for every F (inverted too); P(I) = 0 for both; the small-strain tangent is
    that of linear elasticity with (mu, lmbda). Mixed split: g = J - 1, kappa = ls (module docstring).
    """

    variant: str = "rest_stable"
    name: ClassVar[str] = "stable_neo_hookean"

    def __post_init__(self) -> None:
        require(self.variant in SNH_VARIANTS, self.name, "variant", self.variant, f"one of {', '.join(SNH_VARIANTS)}")
        super().__post_init__()

    @classmethod
    def from_parameters(cls, **params: Any) -> StableNeoHookean:
        """Build from (E, nu) or (mu, lmbda) and ``variant``; any other key is an error naming it."""
        check_keys(cls.name, params, ("E", "nu", "mu", "lmbda", "variant"))
        variant = params.pop("variant", "rest_stable")
        require(variant in SNH_VARIANTS, cls.name, "variant", variant, f"one of {', '.join(SNH_VARIANTS)}")
        return cls(**_lame_from(cls.name, params), variant=variant)

    @property
    def snh_mu(self) -> float:
        """ms: mu (rest_stable) or 4 mu / 3 (paper)."""
        return self.mu if self.variant == "rest_stable" else 4.0 * self.mu / 3.0

    @property
    def snh_lambda(self) -> float:
        """ls: lmbda + mu (rest_stable) or lmbda + 5 mu / 6 (paper); inf when lmbda = inf."""
        return self.lmbda + (self.mu if self.variant == "rest_stable" else 5.0 * self.mu / 6.0)

    @property
    def alpha(self) -> float:
        """The rest volume of the paper's (J - alpha)^2: 1 + 3 ms / (4 ls) (1 when ls = inf)."""
        return 1.0 + 0.75 * self.snh_mu / self.snh_lambda

    @property
    def bulk_penalty(self) -> float:
        return self.snh_lambda

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        ms, J = self.snh_mu, ufl.det(F)
        Ic = ufl.inner(F, F)
        if self.variant == "rest_stable":
            return 0.5 * ms * (Ic - 3.0) - ms * (J - 1.0)
        constant = 9.0 * ms**2 / (32.0 * self.snh_lambda)  # (ls/2)(alpha - 1)^2; 0 when ls = inf
        return 0.5 * ms * (Ic - 3.0) - 0.5 * ms * ufl.ln(Ic + 1.0) - 0.75 * ms * (J - 1.0) + constant

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.det(F) - 1.0

    def parameters(self) -> dict[str, Any]:
        """mu, lmbda (the Lame constants given) and variant."""
        return {"mu": float(self.mu), "lmbda": float(self.lmbda), "variant": self.variant}


@dataclass(frozen=True)
class Yeoh(Law):
    """psi = c1 (Ibar1 - 3) + c2 (Ibar1 - 3)^2 + c3 (Ibar1 - 3)^3 + (kappa/2)(ln J)^2 (Yeoh 1993).

    The isochoric part is FEBio's "Yeoh" (FEBioMech/FEYeoh.cpp, three of its six terms), the volumetric
    part FEBio's default uncoupled U(J) = (k/2)(ln J)^2 (FEUncoupledMaterial), kappa = k. Small strain:
    shear modulus 2 c1, bulk modulus kappa. Mixed split: g = ln J, kappa.
    """

    c1: float
    kappa: float
    c2: float = 0.0
    c3: float = 0.0
    name: ClassVar[str] = "yeoh"
    bulk_parameter: ClassVar[str] = "kappa"

    def __post_init__(self) -> None:
        require_finite(self.name, c1=self.c1, c2=self.c2, c3=self.c3)
        require_bulk(self.name, kappa=self.kappa)
        require(self.c1 > 0, self.name, "c1", self.c1, "> 0")
        require(self.kappa > 0, self.name, "kappa", self.kappa, "> 0")

    @classmethod
    def from_parameters(cls, **params: Any) -> Yeoh:
        check_keys(cls.name, params, ("c1", "c2", "c3", "kappa"), required=("c1", "kappa"))
        return cls(**params)

    @property
    def bulk_penalty(self) -> float:
        return self.kappa

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        x = isochoric_invariants(F)[0] - 3.0
        W = self.c1 * x
        if self.c2 != 0.0:
            W = W + self.c2 * x * x
        if self.c3 != 0.0:
            W = W + self.c3 * x * x * x
        return W

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.ln(ufl.det(F))


@dataclass(frozen=True)
class FixedCorotated(Corotated):
    """fixed_corotated, Stomakhin et al. 2012: psi = mu sum_i (sigma_i - 1)^2 + (lmbda/2)(J - 1)^2.

    sum_i (sigma_i - 1)^2 = ||F - R||^2 with R the polar rotation (sigma_i the signed singular values
    of the rotation variant of the SVD), so this is corotated under its graphics name, the same code.
    """

    name: ClassVar[str] = "fixed_corotated"


@dataclass(frozen=True)
class Arap(Corotated):
    """arap, HOBAK's ARAP (ARAP.cpp: psi = _mu ||F - U V^T||^2): psi = mu ||F - R||^2.

    HOBAK's factor is mu (not mu/2), so arap(mu) is corotated with the same mu and lmbda = 0, the same
    code; there is no volumetric term (kappa = 0: displacement formulation only).
    """

    lmbda: float = 0.0
    name: ClassVar[str] = "arap"

    def __post_init__(self) -> None:
        require(self.lmbda == 0.0, self.name, "lmbda", self.lmbda, "0 (arap has no volumetric term: use corotated)")
        super().__post_init__()

    @classmethod
    def from_parameters(cls, **params: Any) -> Arap:
        check_keys(cls.name, params, ("mu",), required=("mu",))
        return cls(mu=params["mu"])

    def require_mixed(self) -> None:
        raise ValueError(f"{self.name}: has no volumetric term (it is corotated with lmbda = 0): the mixed "
                         "formulation needs one; use the displacement formulation, or corotated with lmbda > 0")

    def parameters(self) -> dict[str, float]:
        """mu only (lmbda = 0 is not a parameter of arap)."""
        return {"mu": float(self.mu)}


__all__ = ["SNH_VARIANTS", "Arap", "FixedCorotated", "StableNeoHookean", "Yeoh"]
