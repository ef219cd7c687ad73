"""An independent numpy computation of shape targeting and corotated psi, P and A, through the SVD.

M = F S = U Sigma V^T (rotation variant: U's last column and Sigma's last entry negated when
det(U V^T) < 0), R = U V^T. With X = U^T dM V, the rotation differential is dR = U [w]x V^T
where (tr(Sigma) I - Sigma) w = 2 axial(skew X) (from X - X^T = W Sigma + Sigma W, W = U^T dR V).

    psi = mu ||F - R S||^2 + (kappa/2)(J - det S)^2
    P   = 2 mu (F - R S) + kappa (J - det S) J F^-T
    dP  = 2 mu (dF - dR S) + kappa [ J^2 (F^-T : dF) F^-T + (J - det S)(J (F^-T : dF) F^-T - J F^-T dF^T F^-T) ]
"""

from __future__ import annotations

import numpy as np


def _cross_matrix(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def shape_target(F: np.ndarray, S: np.ndarray, mu: float, kappa: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(psi, P (3,3), A (3,3,3,3)) at one F with target S."""
    U, sigma, Vt = np.linalg.svd(F @ S)
    if np.linalg.det(U @ Vt) < 0:
        U[:, 2] *= -1.0
        sigma[2] *= -1.0
    V = Vt.T
    R = U @ Vt
    J, JS = np.linalg.det(F), np.linalg.det(S)
    Finv_T = np.linalg.inv(F).T
    psi = mu * np.sum((F - R @ S) ** 2) + 0.5 * kappa * (J - JS) ** 2
    P = 2 * mu * (F - R @ S) + kappa * (J - JS) * J * Finv_T
    K = np.sum(sigma) * np.eye(3) - np.diag(sigma)
    A = np.zeros((3, 3, 3, 3))
    for k in range(3):
        for l in range(3):
            dF = np.zeros((3, 3))
            dF[k, l] = 1.0
            X = U.T @ dF @ S @ V
            skew = 0.5 * (X - X.T)
            w = np.linalg.solve(K, 2.0 * np.array([skew[2, 1], skew[0, 2], skew[1, 0]]))
            dR = U @ _cross_matrix(w) @ Vt
            trace = np.sum(Finv_T * dF)
            dvol = J**2 * trace * Finv_T + (J - JS) * (J * trace * Finv_T - J * Finv_T @ dF.T @ Finv_T)
            A[:, :, k, l] = 2 * mu * (dF - dR @ S) + kappa * dvol
    return psi, P, A
