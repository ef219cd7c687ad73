"""Spectral energies Phi(X) = sum_i f(x_i) of a symmetric 3x3 X (x_i its eigenvalues) with an exact tangent.

UFL's closed-form eigenvalues have NaN derivatives at repeated eigenvalues (X = I, uniaxial stretch:
the common cases). As for the polar rotation (forms.polar), the eigen decomposition is computed
numerically per quadrature point before each assembly: X0 = Q0 diag(x) Q0^T (``eigen_state``), stored
with the weights

    D_ij = (f'(x_i) - f'(x_j)) / (x_i - x_j)   (i != j),   D_ij -> f''(x_i) when x_i = x_j,

and the energy is written in UFL as the surrogate (``spectral_energy``)

    Psi(X) = sum_i f(X'_ii) + sum_{i<j} D_ij X'_ij^2,     X' = Q0^T X Q0.

Claim: Psi and Phi have the same value, gradient and Hessian at X0. Proof: with X' = diag(x) + E, E
symmetric, second-order perturbation theory gives for distinct x the eigenvalues
x_i + E_ii + sum_{j != i} E_ij^2 / (x_i - x_j) + O(|E|^3), so

    Phi = sum_i [f(x_i) + f'(x_i) (E_ii + sum_{j != i} E_ij^2 / (x_i - x_j)) + f''(x_i) E_ii^2 / 2] + O(|E|^3)
        = sum_i [f(x_i) + f'(x_i) E_ii + f''(x_i) E_ii^2 / 2] + sum_{i<j} D_ij E_ij^2 + O(|E|^3),

pairing the (i, j) and (j, i) terms: f'(x_i)/(x_i - x_j) + f'(x_j)/(x_j - x_i) = D_ij. Psi expands to the
same second-order polynomial (f(x_i + E_ii) to second order, and the D_ij E_ij^2 terms exactly). For
repeated eigenvalues the same second-order expansion holds with D_ij = f''(x_i) (a spectral function
of a C^2 f is C^2, its Hessian being the divided differences with f'' on coincidences: Lewis and
Sendov 2001), which is the limit of the quotient. Q0 and D are constants of the forms, so UFL
differentiates Psi twice exactly; with a current state (Q0, x from X at this iterate) the residual and the
Jacobian are those of Phi. Between updates (Q0 stale) Psi is only a second-order model of Phi: every
consumer updates the state before evaluating (model.fields.eigen.EigenField).

The quotient is computed as written when |x_i - x_j| > 1e-3 max|x| (cancellation ~1e-13 relative),
otherwise as the Taylor series f''(m) + f''''(m) d^2 / 24 about the midpoint m, d = x_i - x_j (error
O(d^4 f^(6)), ~1e-14 relative).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import ufl

Expr = ufl.core.expr.Expr
#: f^(k)(x) for k = 0..4, element-wise on numpy arrays
Derivatives = Callable[[np.ndarray, int], np.ndarray]

NEAR = 1e-3


def eigen_state(X: np.ndarray, f: Derivatives) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Q0 (N,3,3), x (N,3), D (N,3,3)) of symmetric X (N,3,3): X = Q0 diag(x) Q0^T and the weights D."""
    X = np.asarray(X, dtype=np.float64).reshape(-1, 3, 3)
    x, Q = np.linalg.eigh(0.5 * (X + np.transpose(X, (0, 2, 1))))
    return Q, x, divided_differences(x, f)


def divided_differences(x: np.ndarray, f: Derivatives) -> np.ndarray:
    """D_ij = (f'(x_i) - f'(x_j)) / (x_i - x_j), f''(x_i) on the diagonal and at near coincidence (module doc)."""
    xi, xj = x[:, :, None], x[:, None, :]
    d = xi - xj
    scale = np.maximum(np.abs(x).max(axis=1), 1e-300)[:, None, None]
    near = np.abs(d) <= NEAR * scale
    m = 0.5 * (xi + xj)
    taylor = f(m, 2) + f(m, 4) * d**2 / 24.0
    with np.errstate(divide="ignore", invalid="ignore"):
        quotient = (f(xi, 1) - f(xj, 1)) / d
    return np.where(near, taylor, quotient)


def spectral_energy(X: Expr, Q0: Expr, D: Expr, f: Callable[[Expr], Expr]) -> Expr:
    """Psi(X) = sum_i f(X'_ii) + sum_{i<j} D_ij X'_ij^2, X' = Q0^T X Q0 (module docstring)."""
    Xp = Q0.T * X * Q0
    energy = f(Xp[0, 0]) + f(Xp[1, 1]) + f(Xp[2, 2])
    for i, j in ((0, 1), (0, 2), (1, 2)):
        energy += D[i, j] * Xp[i, j] ** 2
    return energy
