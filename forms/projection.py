"""Positive-semidefinite projection of tangents (Klar et al. 2020, "modified Newton").

For a symmetric matrix A = Q diag(l) Q^T the nearest positive semidefinite matrix in
the Frobenius norm is Q diag(max(l, 0)) Q^T (Higham 1988). Applied per quadrature
point to the 9x9 matrix A[(i,j),(k,l)] = dP_ij/dF_kl of a hyperelastic law (symmetric,
being a Hessian of psi), it leaves the element stiffness positive semidefinite, so
CG with algebraic multigrid can solve the Newton systems.
"""

from __future__ import annotations

import numpy as np


def project_psd(A: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """Nearest symmetric positive semidefinite matrix of each (..., n, n) matrix (eigenvalues clamped at floor).

    The symmetric part is projected; a PSD input is returned unchanged up to rounding.
    """
    A = np.asarray(A, dtype=np.float64)
    sym = 0.5 * (A + np.swapaxes(A, -1, -2))
    values, vectors = np.linalg.eigh(sym)
    clamped = np.maximum(values, floor)
    return (vectors * clamped[..., None, :]) @ np.swapaxes(vectors, -1, -2)


def project_tangent(A: np.ndarray) -> np.ndarray:
    """project_psd of tangents A (..., 3, 3, 3, 3) seen as 9x9 matrices [(i,j),(k,l)]."""
    shape = np.shape(A)
    return project_psd(np.reshape(A, (*shape[:-4], 9, 9))).reshape(shape)
