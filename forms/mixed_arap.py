"""As-rigid-as-possible (ARAP) and shape targeting in mixed form (the skinning seed's "Mixed FEM"; issue 13 item 2).

The displacement-only laws minimise over rotations inside the energy density,

    psi(F) = mu min_{R in SO(d)} ||F - R S_t||^2  (+ (kappa/2)(det F - det S_t)^2),

(forms.shape_target; S_t = I is ARAP). The mixed form makes the stretch S and the rotation R unknowns of their
own, per cell, tied to the deformation gradient by the constraint F = R S with a multiplier Lambda (a d x d
matrix per cell):

    L(u, S, R, Lambda) = int mu ||S - S_t||^2 + (kappa/2)(det F - det S_t)^2 + Lambda : (F - R S) dx
                         + sum_h (k_h / 2) int_{Omega_h} |u - u_h|^2 dx,

and Newton solves its stationarity conditions in (u, S, R, Lambda) at once. Two choices of S:

* ``symmetric`` (the seed's ARAP): S = S^T, d(d+1)/2 unknowns per cell. F = R S with S symmetric positive
  definite is the polar decomposition, so the energy is mu ||U - S_t||^2 with U = (F^T F)^(1/2): for S_t = I
  this is min_R ||F - R||^2 exactly, the displacement-only ARAP; for S_t != I it is a different law
  (min_R ||F - R S_t||^2 <= ||U - S_t||^2, equal when U S_t is symmetric);
* ``general``: S any d x d matrix (d^2 unknowns). Then F = R S for every R (S = R^T F) and
  min_{R, S: RS = F} ||S - S_t||^2 = min_R ||F - R S_t||^2: the shape-targeting law of Klar et al. 2020 for
  any S_t (forms.shape_target), the extra rotation freedom fixed by the energy.

Rotations: R = R_ref Q(phi) with R_ref a per-cell rotation held fixed during a solve (the "reference", moved to
R after each converged load step) and the unknown phi: in 2D an angle, Q = [[cos, -sin], [sin, cos]]; in 3D a
vector, Q = cay(phi) = I + 2/(1 + |phi|^2) ([phi]x + [phi]x^2) (the Cayley map: a rotation for every phi, smooth,
Q(0) = I, dQ/dphi(0) = [.]x), so no derivative is singular at the rest state (the eigenvalue closed forms of
the polar decomposition are; forms.polar).

In 2D the displacement-only law has a closed-form rotation: the R in SO(2) nearest to M = F S_t is
R = [[a, -b], [b, a]] / sqrt(a^2 + b^2), a = M_11 + M_22, b = M_21 - M_12 (it maximises tr(R^T M) =
a cos t + b sin t), smooth wherever (a, b) != 0: ``arap_energy_2d`` lets UFL differentiate it twice.
"""

from __future__ import annotations

import ufl

Expr = ufl.core.expr.Expr

STRETCHES = ("symmetric", "general")


def stretch_components(dim: int, stretch: str) -> int:
    """Unknowns of S per cell: d(d+1)/2 for ``symmetric``, d^2 for ``general``."""
    if stretch not in STRETCHES:
        raise ValueError(f"stretch: {stretch!r} is not one of {', '.join(STRETCHES)}")
    return dim * (dim + 1) // 2 if stretch == "symmetric" else dim * dim


def rotation_components(dim: int) -> int:
    """Unknowns phi of the rotation per cell: 1 in 2D (an angle), 3 in 3D (a Cayley vector)."""
    return 1 if dim == 2 else 3


#: positions (row, column) of the symmetric components: Voigt order xx, yy, (zz, yz, xz,) xy
SYMMETRIC_ORDER = {2: [(0, 0), (1, 1), (0, 1)], 3: [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]}


def stretch_matrix(s: Expr, dim: int, stretch: str) -> Expr:
    """S as a d x d UFL matrix from its components s: symmetric (Voigt order ``SYMMETRIC_ORDER``) or row-major."""
    if stretch == "general":
        return ufl.as_matrix([[s[dim * i + j] for j in range(dim)] for i in range(dim)])
    index = {}
    for k, (i, j) in enumerate(SYMMETRIC_ORDER[dim]):
        index[(i, j)] = index[(j, i)] = k
    return ufl.as_matrix([[s[index[(i, j)]] for j in range(dim)] for i in range(dim)])


def identity_components(dim: int, stretch: str) -> list[float]:
    """The components of S = I."""
    if stretch == "general":
        return [1.0 if i == j else 0.0 for i in range(dim) for j in range(dim)]
    return [1.0 if i == j else 0.0 for i, j in SYMMETRIC_ORDER[dim]]


def cross_matrix(w: Expr) -> Expr:
    """[w]x, the matrix of v -> w x v."""
    return ufl.as_matrix([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def cayley(w: Expr) -> Expr:
    """cay(w) = (I - [w]x)^-1 (I + [w]x) = I + 2/(1 + w.w) ([w]x + [w]x^2): a rotation for every w."""
    W = cross_matrix(w)
    return ufl.Identity(3) + 2.0 / (1.0 + ufl.dot(w, w)) * (W + W * W)


def rotation_2d(theta: Expr) -> Expr:
    """[[cos t, -sin t], [sin t, cos t]]."""
    return ufl.as_matrix([[ufl.cos(theta), -ufl.sin(theta)], [ufl.sin(theta), ufl.cos(theta)]])


def incremental_rotation(phi: Expr, dim: int) -> Expr:
    """Q(phi): rotation_2d(phi[0]) in 2D, cayley(phi) in 3D."""
    return rotation_2d(phi[0]) if dim == 2 else cayley(phi)


def mixed_arap_density(F: Expr, S: Expr, R: Expr, Lam: Expr, mu: Expr | float, target: Expr,
                       kappa: Expr | float = 0.0) -> Expr:
    """mu ||S - S_t||^2 + (kappa/2)(det F - det S_t)^2 + Lambda : (F - R S), the mixed Lagrangian's density."""
    D = S - target
    density = mu * ufl.inner(D, D) + ufl.inner(Lam, F - R * S)
    if not (isinstance(kappa, (int, float)) and kappa == 0.0):
        density += 0.5 * kappa * (ufl.det(F) - ufl.det(target)) ** 2
    return density


def nearest_rotation_2d(M: Expr) -> Expr:
    """The R in SO(2) nearest to the 2 x 2 matrix M: [[a, -b], [b, a]] / sqrt(a^2 + b^2), a = tr M,
    b = M_21 - M_12 (closed form, smooth where (a, b) != 0)."""
    a = M[0, 0] + M[1, 1]
    b = M[1, 0] - M[0, 1]
    n = ufl.sqrt(a * a + b * b)
    return ufl.as_matrix([[a / n, -b / n], [b / n, a / n]])


def arap_energy_2d(F: Expr, mu: Expr | float, target: Expr, kappa: Expr | float = 0.0) -> Expr:
    """mu ||F - R* S_t||^2 + (kappa/2)(det F - det S_t)^2, R* = nearest_rotation_2d(F S_t) (2D shape targeting;
    ARAP for S_t = I): the displacement-only law the mixed form must reproduce."""
    D = F - nearest_rotation_2d(F * target) * target
    density = mu * ufl.inner(D, D)
    if not (isinstance(kappa, (int, float)) and kappa == 0.0):
        density += 0.5 * kappa * (ufl.det(F) - ufl.det(target)) ** 2
    return density


def handle_penalty(u: Expr, target: Expr, k: Expr | float) -> Expr:
    """(k/2)|u - u_h|^2: a handle region pinned to its target displacement by a penalty."""
    d = u - target
    return 0.5 * k * ufl.dot(d, d)


__all__ = ["STRETCHES", "SYMMETRIC_ORDER", "arap_energy_2d", "cayley", "cross_matrix", "handle_penalty",
           "identity_components", "incremental_rotation", "mixed_arap_density", "nearest_rotation_2d",
           "rotation_2d", "rotation_components", "stretch_components", "stretch_matrix"]
