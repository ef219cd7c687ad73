"""Shape targeting (Klar et al. 2020, after Phace) and its volume term.

    psi(F; S) = mu ||F - R* S||_F^2 + (kappa/2)(J - det S)^2,
    R* = argmin_{R in SO(3)} ||F - R S||_F = U V^T from F S = U Sigma V^T (rotation variant:
         the last column of U negated when det(U V^T) < 0, so R* is never a reflection).

S is the symmetric positive definite "shape target" of the element. By the envelope
theorem dW/dF = 2 mu (F - R* S) (R* minimises the first term); the residual is built
from that stress, and UFL differentiates it with R* = R0 (I + [w]x) of forms.polar,
whose first derivative is the exact dR*/dF: dP[dF] = 2 mu (dF - dR*[dF] S) + ...
With kappa = 0 the law is `shape_target` alone; `volume` is the second term alone.
kappa = inf is the incompressible limit J = det S (mixed formulation only, forms.law).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import ufl

from forms.law import Expr, Law, ParameterError, check_keys, require, require_bulk, require_finite
from forms.polar import rotation_not_unique


def check_shape_targets(S: np.ndarray, where: str = "S", tol: float = 1e-10) -> np.ndarray:
    """S of shape (..., 3, 3) as float64 after checking each is symmetric positive definite.

    Raises ParameterError naming ``where`` and the first offending index otherwise.
    """
    S = np.asarray(S, dtype=np.float64)
    if S.shape[-2:] != (3, 3):
        raise ParameterError(f"{where}: shape targets must be 3x3 matrices, got shape {S.shape}")
    flat = S.reshape(-1, 3, 3)
    if not np.all(np.isfinite(flat)):
        bad = int(np.flatnonzero(~np.isfinite(flat).all(axis=(1, 2)))[0])
        raise ParameterError(f"{where}: shape target {bad} has a non-finite entry")
    scale = np.maximum(np.abs(flat).max(axis=(1, 2)), 1e-300)
    asym = np.abs(flat - np.transpose(flat, (0, 2, 1))).max(axis=(1, 2)) / scale
    if np.any(asym > tol):
        bad = int(np.flatnonzero(asym > tol)[0])
        raise ParameterError(f"{where}: shape target {bad} is not symmetric (|S - S^T| / |S| = {asym[bad]:.2e})")
    smallest = np.linalg.eigvalsh(0.5 * (flat + np.transpose(flat, (0, 2, 1))))[:, 0]
    if np.any(smallest <= 0):
        bad = int(np.flatnonzero(smallest <= 0)[0])
        raise ParameterError(f"{where}: shape target {bad} is not positive definite "
                             f"(smallest eigenvalue {smallest[bad]:.3g})")
    return S


@dataclass(frozen=True)
class ShapeTarget(Law):
    """psi = mu ||F - R* S||^2 + (kappa/2)(J - det S)^2, R* = polar rotation of F S.

    ``S`` is a UFL expression (a Constant, a per-cell Function, ...) of symmetric
    positive definite 3x3 targets; the model checks its values.
    """

    name: ClassVar[str] = "shape_target"
    needs_rotation: ClassVar[bool] = True
    mu: float
    kappa: float = 0.0
    S: Any = None  # UFL expression; identity when None

    def __post_init__(self) -> None:
        require_finite(self.name, mu=self.mu)
        require_bulk(self.name, kappa=self.kappa)
        require(self.mu > 0, self.name, "mu", self.mu, "> 0")
        require(self.kappa >= 0, self.name, "kappa", self.kappa, ">= 0")

    @classmethod
    def from_parameters(cls, S: Any = None, **params: Any) -> ShapeTarget:
        check_keys(cls.name, params, ("mu", "kappa", "S"), required=("mu",))
        return cls(S=S, **params)

    @property
    def target(self) -> Expr:
        return ufl.Identity(3) if self.S is None else self.S

    @property
    def bulk_penalty(self) -> float:
        return self.kappa

    def rotation_argument(self, F: Expr) -> Expr:
        """M = F S, whose polar rotation is R*."""
        return F * self.target

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        if R is None:
            raise ValueError("shape_target: the polar rotation R is required")
        D = F - R * self.target
        return self.mu * ufl.inner(D, D)

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        if R is None:
            raise ValueError("shape_target: the polar rotation R is required")
        return 2.0 * self.mu * (F - R * self.target)

    def volume_constraint(self, F: Expr) -> Expr:
        return ufl.det(F) - ufl.det(self.target)

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """Where the polar rotation of M = F S is not unique (forms.polar.rotation_not_unique): det M < 0
        with the two smallest singular values of M equal (relative 1e-8), or rank M <= 1. S is the
        field ``S`` (N,3,3), or the identity when not given."""
        F = np.asarray(F, dtype=np.float64).reshape(-1, 3, 3)
        S = fields.get("S")
        M = F if S is None else F @ np.asarray(S, dtype=np.float64).reshape(-1, 3, 3)
        return rotation_not_unique(M)

    def parameters(self) -> dict[str, float]:
        return {"mu": float(self.mu), "kappa": float(self.kappa)}


@dataclass(frozen=True)
class Volume(Law):
    """psi = (kappa/2)(J - det S)^2, the volume term of shape targeting (no shear stiffness alone)."""

    name: ClassVar[str] = "volume"
    kappa: float
    S: Any = None

    def __post_init__(self) -> None:
        require_bulk(self.name, kappa=self.kappa)
        require(self.kappa > 0, self.name, "kappa", self.kappa, "> 0")

    @classmethod
    def from_parameters(cls, S: Any = None, **params: Any) -> Volume:
        check_keys(cls.name, params, ("kappa", "S"), required=("kappa",))
        return cls(S=S, **params)

    @property
    def bulk_penalty(self) -> float:
        return self.kappa

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        return 0.0 * ufl.det(F)

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        return ufl.zero(3, 3)

    def volume_constraint(self, F: Expr) -> Expr:
        target = ufl.Identity(3) if self.S is None else self.S
        return ufl.det(F) - ufl.det(target)

    def parameters(self) -> dict[str, float]:
        return {"kappa": float(self.kappa)}
