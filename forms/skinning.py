"""Mixed ARAP skinning in the plane (the skinning seed, mixed-fem-skinning-sgi.txt, sections 1.2 and 1.3).

Unknowns: the stretch s = (s11, s12, s22) per triangle (DG0; the symmetric S = [[s11, s12], [s12, s22]]), the
deformed positions x (P1 vectors; the deformation gradient F = grad x, constant per triangle) and the multiplier
lambda (DG0 2 x 2) of the constraint F = R S; the rotation R = R(theta) per triangle is a given parameter,
written as the seed prints it (a clockwise rotation by theta):

    R(theta) = [[cos theta, sin theta], [-sin theta, cos theta]].

Lagrangian (the seed's L(S, x, lambda) with the sums over triangles as integrals):

    L(s, x, lambda; theta) = E_ARAP(S) + k/2 int chi_pin |x - x_pin|^2 dx + int lambda : (grad x - R(theta) S) dx,
    E_ARAP(S) = int ||S - I||_F^2 dx = sum_c |c| ((s11 - 1)^2 + 2 s12^2 + (s22 - 1)^2),

with chi_pin the indicator of the pinned cells (the seed's P: the feet) and x_pin their positions. ||S - I||_F^2
is the Frobenius norm of the full symmetric 2 x 2 matrix (the off-diagonal entry counts twice); |c| weighs each
triangle by its area (the FE integral), where the seed's discrete sum weighs every triangle by 1 (the same on a
mesh of equal triangles). For fixed theta, L is quadratic in y = (s, x, lambda): its stationary point solves the
KKT system A(theta) y = b, A the Hessian of L in y (symmetric, indefinite), b = -dL/dy at y = 0 (independent of
theta).

Pure UFL: measures, spaces and coefficients are the caller's.
"""

from __future__ import annotations

import ufl


def rotation(theta: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """R(theta) = [[cos theta, sin theta], [-sin theta, cos theta]] (as printed in the seed)."""
    c, s = ufl.cos(theta), ufl.sin(theta)
    return ufl.as_matrix([[c, s], [-s, c]])


def symmetric(s: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """S = [[s0, s1], [s1, s2]] from its three coordinates."""
    return ufl.as_matrix([[s[0], s[1]], [s[1], s[2]]])


def arap_energy(s: ufl.core.expr.Expr, dx: ufl.Measure) -> ufl.Form:
    """E_ARAP(S) = int ||S - I||_F^2 dx."""
    D = symmetric(s) - ufl.Identity(2)
    return ufl.inner(D, D) * dx


def pinning_penalty(x: ufl.core.expr.Expr, x_pinned: ufl.core.expr.Expr, pinned: ufl.core.expr.Expr,
                    k: ufl.core.expr.Expr, dx: ufl.Measure) -> ufl.Form:
    """k/2 int chi_pin |x - x_pin|^2 dx."""
    d = x - x_pinned
    return 0.5 * k * pinned * ufl.inner(d, d) * dx


def constraint(s: ufl.core.expr.Expr, x: ufl.core.expr.Expr, lam: ufl.core.expr.Expr, theta: ufl.core.expr.Expr,
               dx: ufl.Measure) -> ufl.Form:
    """int lambda : (grad x - R(theta) S) dx."""
    return ufl.inner(lam, ufl.grad(x) - ufl.dot(rotation(theta), symmetric(s))) * dx


def skinning_lagrangian(s: ufl.core.expr.Expr, x: ufl.core.expr.Expr, lam: ufl.core.expr.Expr,
                        theta: ufl.core.expr.Expr, k: ufl.core.expr.Expr, pinned: ufl.core.expr.Expr,
                        x_pinned: ufl.core.expr.Expr, dx: ufl.Measure) -> ufl.Form:
    """L = E_ARAP(S) + k/2 int chi_pin |x - x_pin|^2 + int lambda : (grad x - R(theta) S) (module docstring)."""
    return arap_energy(s, dx) + pinning_penalty(x, x_pinned, pinned, k, dx) + constraint(s, x, lam, theta, dx)


def rotation_regularisation(theta: ufl.core.expr.Expr, theta_pinned: ufl.core.expr.Expr,
                            dx: ufl.Measure) -> ufl.Form:
    """The seed's ||R - R_pinned||^2 as int ||R(theta) - R(theta_pinned)||_F^2 dx (= int 4 (1 - cos(theta -
    theta_pinned)) dx)."""
    D = rotation(theta) - rotation(theta_pinned)
    return ufl.inner(D, D) * dx


__all__ = ["arap_energy", "constraint", "pinning_penalty", "rotation", "rotation_regularisation",
           "skinning_lagrangian", "symmetric"]
