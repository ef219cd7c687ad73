"""The Ogden law (Ogden 1972), in FEBio's uncoupled form, with an exact tangent at repeated stretches.

    psi = sum_{p=1..N} c_p / m_p^2 (lbar_1^m_p + lbar_2^m_p + lbar_3^m_p - 3) + (kappa/2)(ln J)^2,  N <= 6,

lbar_i = J^(-1/3) lambda_i the isochoric principal stretches (lambda_i the singular values of F). This is
FEBio's "Ogden" (FEBioMech/FEOgdenMaterial.cpp: up to six terms c_i, m_i; its uncoupled volumetric term
U(J) = (k/2)(ln J)^2, k = kappa). Ogden's original form sum_p mu_p / alpha_p (lambda_1^alpha_p + ... - 3) maps to
it by c_p = mu_p alpha_p, m_p = alpha_p; the small-strain shear modulus is mu = sum_p c_p / 2 = sum_p mu_p alpha_p / 2.
A term with c_p = 0 is absent (m_p then unused); m_p != 0, c_p >= 0 with c_1 > 0 (so c_p / m_p^2 > 0 and the
law is stable: Ogden's mu_p alpha_p > 0).

The isochoric part is the spectral function Phi(Cbar) = sum_i f(x_i) of Cbar = J^(-2/3) F^T F (x_i = lbar_i^2),
f(x) = sum_p c_p / m_p^2 (x^(m_p/2) - 1), written with forms.spectral's per-point eigenbasis (exact value,
stress and tangent at repeated stretches, where UFL's closed-form eigenvalues give NaN). The law therefore
needs quadrature-point state: ``needs_eigenbasis``; the machinery (model.fields.eigen.EigenField) computes
(Q0, D) from ``spectral_argument(F)`` with ``spectral_derivatives`` before each assembly and hands them over
with ``with_eigenbasis``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import ufl

from forms.law import Expr, Law, ParameterError, check_keys, require, require_bulk, require_finite
from forms.spectral import spectral_energy

#: the most terms (FEBio's Ogden: c1..c6, m1..m6); the parameter names are c_p, m_p for p = 1..TERMS
TERMS = 6
KEYS = tuple(f"{x}{p}" for p in range(1, TERMS + 1) for x in ("c", "m")) + ("kappa",)


@dataclass(frozen=True)
class Ogden(Law):
    """psi = sum_p c_p / m_p^2 (sum_i lbar_i^m_p - 3) + (kappa/2)(ln J)^2 (module docstring)."""

    name: ClassVar[str] = "ogden"
    bulk_parameter: ClassVar[str] = "kappa"
    #: the energy needs (Q0, D) of spectral_argument(F) per quadrature point (forms.spectral)
    needs_eigenbasis: ClassVar[bool] = True
    c1: float
    m1: float
    kappa: float
    c2: float = 0.0
    m2: float = 1.0
    c3: float = 0.0
    m3: float = 1.0
    c4: float = 0.0
    m4: float = 1.0
    c5: float = 0.0
    m5: float = 1.0
    c6: float = 0.0
    m6: float = 1.0
    #: (Q0, D) UFL coefficients of the current eigen state, set by the machinery (with_eigenbasis)
    eigenbasis: Any = None

    def __post_init__(self) -> None:
        require_finite(self.name, **{k: getattr(self, k) for k in KEYS if k != "kappa"})
        require_bulk(self.name, kappa=self.kappa)
        require(self.c1 > 0, self.name, "c1", self.c1, "> 0")
        for p in range(2, TERMS + 1):
            require(getattr(self, f"c{p}") >= 0, self.name, f"c{p}", getattr(self, f"c{p}"), ">= 0")
        for p in range(1, TERMS + 1):
            require(getattr(self, f"m{p}") != 0, self.name, f"m{p}", getattr(self, f"m{p}"), "!= 0")
        require(self.kappa >= 0, self.name, "kappa", self.kappa, ">= 0")

    @classmethod
    def from_parameters(cls, **params: Any) -> Ogden:
        check_keys(cls.name, params, KEYS, required=("c1", "m1", "kappa"))
        return cls(**params)

    @property
    def bulk_penalty(self) -> float:
        return self.kappa

    @property
    def terms(self) -> tuple[tuple[float, float], ...]:
        """(c_p / m_p^2, m_p / 2) of the terms with c_p != 0: f(x) = sum a (x^e - 1)."""
        out = []
        for p in range(1, TERMS + 1):
            c, m = getattr(self, f"c{p}"), getattr(self, f"m{p}")
            if c != 0:
                out.append((c / m**2, m / 2.0))
        return tuple(out)

    def spectral_argument(self, F: Expr) -> Expr:
        """Cbar = J^(-2/3) F^T F, whose eigenvalues are lbar_i^2."""
        return ufl.det(F) ** (-2.0 / 3.0) * F.T * F

    def spectral_derivatives(self, x: np.ndarray, k: int) -> np.ndarray:
        """f^(k)(x), f(x) = sum_p c_p / m_p^2 (x^(m_p/2) - 1), for k = 0..4 (numpy)."""
        out = np.zeros_like(np.asarray(x, dtype=np.float64))
        for a, e in self.terms:
            factor = a
            for n in range(k):
                factor *= e - n
            out = out + factor * (x ** (e - k) - (1.0 if k == 0 else 0.0))
        return out

    def with_eigenbasis(self, Q0: Expr, D: Expr) -> Ogden:
        """This law reading the eigen state (Q0, D) of spectral_argument(F) (model.fields.eigen)."""
        return dataclasses.replace(self, eigenbasis=(Q0, D))

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        if self.eigenbasis is None:
            raise ValueError("ogden: the per-point eigenbasis is required (with_eigenbasis; "
                             "model.fields.eigen.EigenField computes it)")
        Q0, D = self.eigenbasis

        def f(x: Expr) -> Expr:
            return sum(a * (x**e - 1.0) for a, e in self.terms)

        return spectral_energy(self.spectral_argument(F), Q0, D, f)

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.ln(ufl.det(F))

    def parameters(self) -> dict[str, float]:
        return {k: float(getattr(self, k)) for k in KEYS}


__all__ = ["Ogden", "ParameterError"]
