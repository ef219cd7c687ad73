"""The screened Poisson energy and its mixed (KKT) Lagrangian (the skinning seed, mixed-fem-skinning-sgi.txt).

Standard form, u in a Lagrange space:

    E(u) = 1/2 int |grad u|^2 dx + 1/2 int alpha u^2 dx - int f u dx,

whose minimiser solves -lap u + alpha u = f with zero flux on the boundary (the natural condition).

Mixed form: g = grad u becomes an unknown of its own, tied to u by a multiplier lambda:

    L(g, u, lambda) = 1/2 int |g|^2 dx + 1/2 int alpha u^2 dx - int f u dx + int lambda . (grad u - g) dx.

Its stationarity conditions (the seed's KKT conditions, with the mass and weight matrices written out):
dL/dg = g - lambda = 0, dL/du = alpha u - f + div-adjoint(lambda) = 0, dL/dlambda = grad u - g = 0. With g and
lambda in the discontinuous space DG_(k-1)^d, which holds grad of every P_k function, the constraint gives
g = grad u exactly, so the mixed and the standard discrete u are the same.

Pure UFL: the measure (with its quadrature degree) is the caller's.
"""

from __future__ import annotations

import ufl


def screened_poisson_energy(u: ufl.core.expr.Expr, alpha: ufl.core.expr.Expr, f: ufl.core.expr.Expr,
                            dx: ufl.Measure) -> ufl.Form:
    """E(u) = 1/2 int |grad u|^2 + 1/2 int alpha u^2 - int f u."""
    return (0.5 * ufl.inner(ufl.grad(u), ufl.grad(u)) + 0.5 * alpha * u * u - f * u) * dx


def screened_poisson_lagrangian(g: ufl.core.expr.Expr, u: ufl.core.expr.Expr, lam: ufl.core.expr.Expr,
                                alpha: ufl.core.expr.Expr, f: ufl.core.expr.Expr, dx: ufl.Measure) -> ufl.Form:
    """L(g, u, lambda) = 1/2 int |g|^2 + 1/2 int alpha u^2 - int f u + int lambda . (grad u - g)."""
    return (0.5 * ufl.inner(g, g) + 0.5 * alpha * u * u - f * u + ufl.inner(lam, ufl.grad(u) - g)) * dx


__all__ = ["screened_poisson_energy", "screened_poisson_lagrangian"]
