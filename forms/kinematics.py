"""Kinematics of finite deformation, as pure functions of UFL expressions.

    F = I + grad(u)                      deformation gradient
    J = det F
    C = F^T F                            right Cauchy-Green tensor
    E = (C - I) / 2                      Green-Lagrange strain
    Cbar = J^(-2/3) C                    isochoric right Cauchy-Green tensor
    Ibar1 = tr Cbar,  Ibar2 = ((tr Cbar)^2 - tr(Cbar^2)) / 2
    sigma = J^-1 P F^T                   Cauchy stress from the first Piola-Kirchhoff stress P
"""

from __future__ import annotations

import ufl


def deformation_gradient(u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """F = I + grad(u)."""
    d = len(u)
    return ufl.Identity(d) + ufl.grad(u)


def right_cauchy_green(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """C = F^T F."""
    return F.T * F


def green_lagrange(F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """E = (F^T F - I) / 2."""
    return 0.5 * (right_cauchy_green(F) - ufl.Identity(F.ufl_shape[0]))


def isochoric_invariants(F: ufl.core.expr.Expr) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """(Ibar1, Ibar2) of Cbar = J^(-2/3) C: Ibar1 = tr Cbar, Ibar2 = ((tr Cbar)^2 - tr(Cbar^2)) / 2."""
    J = ufl.det(F)
    Cbar = J ** (-2.0 / 3.0) * right_cauchy_green(F)
    Ibar1 = ufl.tr(Cbar)
    Ibar2 = 0.5 * (Ibar1**2 - ufl.tr(Cbar * Cbar))
    return Ibar1, Ibar2


def cauchy_stress(P: ufl.core.expr.Expr, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """sigma = J^-1 P F^T."""
    return P * F.T / ufl.det(F)


def von_mises(sigma: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """sigma_vm = sqrt(3/2 s:s), s = sigma - tr(sigma)/3 I."""
    s = ufl.dev(sigma)
    return ufl.sqrt(1.5 * ufl.inner(s, s))


def lame_parameters(E: float, nu: float) -> tuple[float, float]:
    """mu = E / (2(1+nu)), lmbda = E nu / ((1+nu)(1-2nu))."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
