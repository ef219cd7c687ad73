"""Turchet's thesis (Bournemouth University, 2018): the formulas as printed.

- eqs. 4.3, 4.11, 4.12 (section 4.3.3), appendix C.15, C.16, C.22 -> law ``stvk``; the thesis' Lame
  constants mu, lambda (defined from Y, nu right after eq. 4.3, the same formulas as energies.md) are the
  law's ``mu``, ``lmbda``;
- eq. 4.5 (G = P B_m) and the stiffness printed below it, against the element vector and matrix dolfinx
  assembles on a one-cell mesh, for stvk, neo_hookean, corotated and shape_target;
- eqs. 4.8 (= B.19), 4.9, 4.10 and dU/dF = 2 K ln(J) F^-T -> law ``muscle`` with its fibre term isolated
  (c1 = c2 = 0, P1 = 0, alpha = 1, a0 from ``field_samples``): P_fibre = P(muscle) - P(muscle with
  sigma_max = 0) = dF2/dlbar d lbar/dF, at the samples whose fibre stretch lies in the middle piece of
  f_active; the muscle with sigma_max = 0 is psi = K (ln J)^2 exactly, whose P is dU/dF.

- eqs. 4.13-4.15 (sec. 4.3.4.1): the spring potential W = k_s (|q| - r)^2, its force and Hessian, on the end
  points, against ufl.diff of W (``thesis_reference.SpringReference``);
- sec. 3.3.3.1: the membrane's 3x2 F, the plane-stress energy with the printed Voigt B, -grad and -Hessian on one
  triangle in 3D (``MembraneTriangle``), the nodal pressure force with unit areas on the closed surface of a
  tetrahedron (``PressureSurface``: p dV/dx);
- eq. 4.4 (sec. 4.3.2): the semi-implicit backward Euler step against one Newton step of the implicit system on
  one stvk tetrahedron (``BackwardEulerCell``).

Rows: thesis-eq4.3, -eq4.11, -eq4.12, -eqC.15, -eqC.16 (each with C.22), thesis-eq4.5-<law>, thesis-eq4.8,
-eqB.19, -eq4.9, -eq4.10, -dUdF, thesis-eq4.13, -eq4.14, -eq4.15, thesis-sec3.3.3.1-F, -energy, -forces, -hessian,
-pressure, thesis-eq4.4; ``-corrected`` variants for every disagreement.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

import forms
from model.verify import ReferenceEvaluator, deformation_samples, field_samples
from model.verify.element import ElementAssembler
from model.verify.seeds.common import (
    _T,
    ELEMENT_SAMPLES,
    I3,
    SAMPLES,
    SEED,
    THESIS,
    Quantities,
    SeedRow,
    _check,
    _row,
)
from model.verify.seeds.klar import MU_KLAR, klar_eq3_stress, klar_eq4_tangent, klar_rotation

#: thesis: Young's modulus Y and Poisson ratio nu; Lame constants as printed after eq. 4.3
THESIS_Y, THESIS_NU = 3.0, 0.3
MU_THESIS = THESIS_Y / (2.0 * (1.0 + THESIS_NU))
LAMBDA_THESIS = THESIS_Y * THESIS_NU / ((1.0 + THESIS_NU) * (1.0 - 2.0 * THESIS_NU))


# --- Turchet thesis: St. Venant-Kirchhoff ---------------------------------------------------------------------

def _green(F: np.ndarray) -> np.ndarray:
    """E = (F^T F - I)/2 (thesis eq. 4.2)."""
    return 0.5 * (_T(F) @ F - I3)


def thesis_eq4_3_energy(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Thesis eq. 4.3, as printed: Psi(F) = mu E:E + lambda tr^2(E), tr^2(E) read as (tr E)^2."""
    E = _green(F)
    return mu * np.einsum("nij,nij->n", E, E) + lam * np.trace(E, axis1=1, axis2=2) ** 2


def thesis_eq4_3_corrected(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Eq. 4.3 corrected: Psi(F) = mu E:E + (lambda/2) (tr E)^2 (the energy whose derivative is eq. 4.11)."""
    E = _green(F)
    return mu * np.einsum("nij,nij->n", E, E) + 0.5 * lam * np.trace(E, axis1=1, axis2=2) ** 2


def thesis_eq4_11_stress(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Thesis eq. 4.11 (= C.1), as printed: P(F) = F [2 mu E + lambda tr(E) I]."""
    E = _green(F)
    return F @ (2.0 * mu * E + lam * np.trace(E, axis1=1, axis2=2)[:, None, None] * I3)


def _lambda_part_c22(F: np.ndarray, lam: float) -> np.ndarray:
    """Thesis eq. C.22 (the lambda part of eq. 4.12), as printed, indices (i, j, p, q) = dP_ij/dF_pq:
    (1/2) lambda (2 F_pq F_ij + delta_ip delta_jq tr(F^T F) - 3 delta_ip delta_jq)."""
    trC = np.einsum("nkl,nkl->n", F, F)
    dd = np.einsum("ip,jq->ijpq", I3, I3)
    return 0.5 * lam * (2.0 * np.einsum("npq,nij->nijpq", F, F) + (trC - 3.0)[:, None, None, None, None] * dd)


def thesis_eq4_12_tangent(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Thesis eq. 4.12, as printed, a 4th-order tensor with indices (i, j, p, q) = dP_ij/dF_pq:

        mu (delta_ip (F^T F)_qj + (F^T F)_pi delta_jq + F^T_qi F_pj - delta_ip delta_jq)
        + (1/2) lambda (2 F_pq F_ij + delta_ip delta_jq tr(F^T F) - 3 delta_ip delta_jq)

    Notation: the printed parentheses of the mu part are unbalanced ("mu (delta_ip F^T F)_qj + ...
    - delta_ip delta_jq)"); they are read as mu multiplying all four terms (as in C.13), with
    (delta_ip F^T F)_qj = delta_ip (F^T F)_qj. F^T_qi = F_iq. A[n, i, j, p, q].
    """
    C = _T(F) @ F
    mu_part = (np.einsum("ip,nqj->nijpq", I3, C) + np.einsum("npi,jq->nijpq", C, I3)
               + np.einsum("niq,npj->nijpq", F, F) - np.einsum("ip,jq->ijpq", I3, I3))
    trC = np.einsum("nkl,nkl->n", F, F)
    dd = np.einsum("ip,jq->ijpq", I3, I3)
    lam_part = 0.5 * lam * (2.0 * np.einsum("npq,nij->nijpq", F, F) + trC[:, None, None, None, None] * dd - 3.0 * dd)
    return mu * mu_part + lam_part


def thesis_eqC16_tangent(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Appendix C: term A (eq. C.16) + term B (eq. C.22), as printed, indices (i, j, p, q):

        C.16: mu (delta_ip (F^T F)_qj + (F^T F)_pi delta_jq + F^T_qi F_pj - delta_ip delta_jq)
        C.22: (1/2) lambda (2 F_pq F_ij + delta_ip delta_jq tr(F^T F) - 3 delta_ip delta_jq)

    (C.6 splits dP/dF into A + B; the same parenthesis reading as eq. 4.12.)
    """
    C = _T(F) @ F
    term_a = mu * (np.einsum("ip,nqj->nijpq", I3, C) + np.einsum("npi,jq->nijpq", C, I3)
                   + np.einsum("niq,npj->nijpq", F, F) - np.einsum("ip,jq->ijpq", I3, I3))
    return term_a + _lambda_part_c22(F, lam)


def thesis_eqC15_tangent(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Appendix C.15 (the step before C.16) + C.22, as printed, indices (i, j, p, q):

        C.15: mu (delta_ip (F^T F)_qj + (F_pl F^T_li delta_jq + F^T_li F_pj delta_lq) - delta_ip delta_jq)

    F_pl F^T_li = (F F^T)_pi, F^T_li F_pj delta_lq = F_iq F_pj.
    """
    C = _T(F) @ F
    term_a = mu * (np.einsum("ip,nqj->nijpq", I3, C) + np.einsum("npl,nil,jq->nijpq", F, F, I3)
                   + np.einsum("nil,npj,lq->nijpq", F, F, I3) - np.einsum("ip,jq->ijpq", I3, I3))
    return term_a + _lambda_part_c22(F, lam)


def thesis_eq4_12_corrected(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """Eq. 4.12 (and C.16 + C.22) corrected, indices (i, j, p, q):

        mu (delta_ip (F^T F)_qj + (F F^T)_ip delta_jq + F_iq F_pj - delta_ip delta_jq)
        + (1/2) lambda (2 F_pq F_ij + delta_ip delta_jq (tr(F^T F) - 3))
    """
    C = _T(F) @ F
    B = F @ _T(F)
    term_a = mu * (np.einsum("ip,nqj->nijpq", I3, C) + np.einsum("nip,jq->nijpq", B, I3)
                   + np.einsum("niq,npj->nijpq", F, F) - np.einsum("ip,jq->ijpq", I3, I3))
    return term_a + _lambda_part_c22(F, lam)


# --- thesis: the muscle law (eqs. 4.6-4.10, appendix B) --------------------------------------------------------

#: the fibre term isolated: c1 = c2 = 0 (isotropic = mooney_rivlin), P1 = 0 (no passive curve), alpha = 1, and a
#: small K so that P(muscle) - P(muscle with sigma_max = 0) loses nothing to cancellation
MUSCLE_K, MUSCLE_SIGMA_MAX, MUSCLE_L_OFL = 1.5, 3.0, 1.0
MUSCLE_FIBRE = {"c1": 0.0, "c2": 0.0, "K": MUSCLE_K, "sigma_max": MUSCLE_SIGMA_MAX, "P1": 0.0, "l_ofl": MUSCLE_L_OFL}
#: the same law with no fibre term: psi = U(J) = K (ln J)^2 exactly
MUSCLE_VOLUME = {**MUSCLE_FIBRE, "sigma_max": 0.0}
#: fibre stretches kept: inside the middle piece of f_active (0.6, 1.4), away from its kinks
MUSCLE_STRETCH_RANGE = (0.62, 1.38)


def fibre_stretch_np(F: np.ndarray, a0: np.ndarray) -> np.ndarray:
    """lbar = sqrt(a0 . J^(-2/3) F^T F a0) (thesis, after eq. 4.6)."""
    Fa = np.einsum("nij,nj->ni", F, a0)
    return np.sqrt(np.linalg.det(F) ** (-2.0 / 3.0) * np.einsum("ni,ni->n", Fa, Fa))


def muscle_fibre_derivatives(lbar: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dF2/dlbar and d2F2/dlbar2 of the isolated fibre term (alpha = 1, P1 = 0): sigma_max / l_ofl f_active(s),
    in the middle piece 0.6 < s < 1.4 of f_active (Blemker table, thesis fig. B.1): f = 1 - 4 (1 - s)^2."""
    s = lbar / MUSCLE_L_OFL
    if np.any((s <= 0.6) | (s >= 1.4)):
        raise ValueError("fibre stretch outside the middle piece of f_active")
    scale = MUSCLE_SIGMA_MAX / MUSCLE_L_OFL
    return scale * (1.0 - 4.0 * (1.0 - s) ** 2), scale * 8.0 * (1.0 - s) / MUSCLE_L_OFL


def thesis_eq4_8_dlbar(F: np.ndarray, a0: np.ndarray) -> np.ndarray:
    """Thesis eq. 4.8 (= B.19), as printed: d lbar/dF = J^(-2/3)/lbar [-1/3 F^-T tr((Fa)(Fa)^T) + F (a a^T)]."""
    J = np.linalg.det(F)
    lbar = fibre_stretch_np(F, a0)
    Fa = np.einsum("nij,nj->ni", F, a0)
    FinvT = _T(np.linalg.inv(F))
    tr = np.einsum("ni,ni->n", Fa, Fa)  # tr((Fa)(Fa)^T)
    bracket = -tr[:, None, None] * FinvT / 3.0 + F @ np.einsum("ni,nj->nij", a0, a0)
    return (J ** (-2.0 / 3.0) / lbar)[:, None, None] * bracket


def thesis_diagonalise(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """F = U Fhat V^T (numpy SVD; det F > 0 so Fhat = diag(sigma) needs no sign flip): U, sigma, V."""
    U, sigma, Vt = np.linalg.svd(F)
    return U, sigma, _T(Vt)


def thesis_eq4_9_stress(F: np.ndarray, a0: np.ndarray, dF2: np.ndarray) -> np.ndarray:
    """Thesis eq. 4.9 (= the unnumbered formula after fig. B.1), as printed, in the diagonalised frame:

    Phat = dF2/dlbar (1/(2 lbar) V^T a0 . 2(-1/3 J^2 Fhat + J^(-2/3) Fhat Ones) V^T a0),
    lbar = sqrt(V^T a0 . J^(-2/3) Fhat^2 V^T a0), J = det Fhat, Ones the all-ones matrix.
    Read with "b . M b" (b = V^T a0) taken componentwise, M_ij b_i b_j with no sum, as B.8 writes
    "(...)_lm a_l a_m": summed, the expression is a scalar and cannot be a stress. Returns Phat (n, 3, 3),
    to compare with U^T P V.
    """
    _, sigma, V = thesis_diagonalise(F)
    Fhat = sigma[:, :, None] * I3
    b = np.einsum("nji,nj->ni", V, a0)
    J = np.prod(sigma, axis=1)
    lbar = np.sqrt(np.einsum("ni,nij,nj->n", b, J[:, None, None] ** (-2.0 / 3.0) * Fhat @ Fhat, b))
    M = 2.0 * (-J[:, None, None] ** 2 * Fhat / 3.0 + J[:, None, None] ** (-2.0 / 3.0) * Fhat @ np.ones((3, 3)))
    return (dF2 / (2.0 * lbar))[:, None, None] * M * np.einsum("ni,nj->nij", b, b)


def thesis_eq4_9_corrected(F: np.ndarray, a0: np.ndarray, dF2: np.ndarray) -> np.ndarray:
    """Eq. 4.8 in the diagonalised frame (Fhat^-T = Fhat^-1, b = V^T a0): Phat = U^T P V =
    dF2/dlbar J^(-2/3)/lbar [-1/3 (b . Fhat^2 b) Fhat^-1 + Fhat b b^T]."""
    _, sigma, V = thesis_diagonalise(F)
    b = np.einsum("nji,nj->ni", V, a0)
    J = np.prod(sigma, axis=1)
    tr = np.einsum("ni,ni->n", sigma * b, sigma * b)  # b . Fhat^2 b
    lbar = np.sqrt(J ** (-2.0 / 3.0) * tr)
    bracket = -tr[:, None, None] * (1.0 / sigma)[:, :, None] * I3 / 3.0 + np.einsum("ni,nj->nij", sigma * b, b)
    return (dF2 * J ** (-2.0 / 3.0) / lbar)[:, None, None] * bracket


def thesis_eq4_10_tangent(F: np.ndarray, a0: np.ndarray) -> np.ndarray:
    """Thesis eq. 4.10 (= the second derivative at the end of appendix B), as printed:

    dP_aniso/dF = -2/9 J^(-2/3) (F^-T)_ij (a0 . J^(-2/3) F^T F a0)^(-1/2) (F^-T)_ij (Fa)_k (Fa)_k
                  - 2/3 J^(-2/3) (F^-T)_ij (a0 . J^(-2/3) F^T F a0)^(-1/2) (Fa)_i a_j.
    Only i, j are free as printed; read as A[p, q, k, l] = dP_pq/dF_kl with the leading (F^-T)_ij (the
    derivative of J^(-2/3)) the differentiation pair (k, l) and the rest the stress pair (p, q):
    A = -2/9 J^(-2/3)/lbar |Fa|^2 (F^-T)_pq (F^-T)_kl - 2/3 J^(-2/3)/lbar (Fa)_p a_q (F^-T)_kl.
    """
    J = np.linalg.det(F)
    lbar = fibre_stretch_np(F, a0)
    Fa = np.einsum("nij,nj->ni", F, a0)
    FinvT = _T(np.linalg.inv(F))
    c = J ** (-2.0 / 3.0) / lbar
    first = (-2.0 / 9.0) * (c * np.einsum("ni,ni->n", Fa, Fa))[:, None, None, None, None] * \
        np.einsum("npq,nkl->npqkl", FinvT, FinvT)
    second = (-2.0 / 3.0) * c[:, None, None, None, None] * np.einsum("np,nq,nkl->npqkl", Fa, a0, FinvT)
    return first + second


def thesis_eq4_10_corrected(F: np.ndarray, a0: np.ndarray, dF2: np.ndarray, d2F2: np.ndarray) -> np.ndarray:
    """dP_aniso/dF = d2F2/dlbar2 g (x) g + dF2/dlbar H, g = d lbar/dF (eq. 4.8) = -lbar/3 F^-T + c (Fa) a^T,
    c = J^(-2/3)/lbar, and H = d g/dF:
    H_pqkl = -1/3 (F^-T)_pq g_kl + lbar/3 (F^-1)_lp (F^-1)_qk + c (-2/3 (F^-T)_kl - g_kl/lbar) (Fa)_p a_q
             + c delta_pk a_q a_l."""
    J = np.linalg.det(F)
    lbar = fibre_stretch_np(F, a0)
    Fa = np.einsum("nij,nj->ni", F, a0)
    Finv = np.linalg.inv(F)
    FinvT = _T(Finv)
    c = J ** (-2.0 / 3.0) / lbar
    g = thesis_eq4_8_dlbar(F, a0)
    x = (slice(None), None, None, None, None)
    H = (-np.einsum("npq,nkl->npqkl", FinvT, g) / 3.0
         + (lbar / 3.0)[x] * np.einsum("nlp,nqk->npqkl", Finv, Finv)
         + c[x] * np.einsum("np,nq,nkl->npqkl", Fa, a0, -2.0 / 3.0 * FinvT - g / lbar[:, None, None])
         + c[x] * np.einsum("pk,nq,nl->npqkl", I3, a0, a0))
    return d2F2[x] * np.einsum("npq,nkl->npqkl", g, g) + dF2[x] * H


def thesis_dUdF(F: np.ndarray, K: float) -> np.ndarray:
    """Thesis (after eq. 4.10 and in appendix B), as printed: dU/dF = 2 K ln(J) F^-T for U = K (ln J)^2."""
    J = np.linalg.det(F)
    return (2.0 * K * np.log(J))[:, None, None] * _T(np.linalg.inv(F))


def thesis_dUdFhat(F: np.ndarray, K: float) -> np.ndarray:
    """The diagonalised form printed next to it: dU/dFhat = 2 K ln(det Fhat) Fhat^-1 (compare with U^T P V)."""
    _, sigma, _ = thesis_diagonalise(F)
    return (2.0 * K * np.log(np.prod(sigma, axis=1)))[:, None, None] * (1.0 / sigma)[:, :, None] * I3


# --- hand-derived P and dP/dF of the other laws (for the element check of eq. 4.5) ------------------------------

def neo_hookean_stress(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """P = mu (F - F^-T) + lambda ln J F^-T, of psi = (mu/2)(tr C - 3) - mu ln J + (lambda/2)(ln J)^2."""
    Finv_T = _T(np.linalg.inv(F))
    lnJ = np.log(np.linalg.det(F))
    return mu * (F - Finv_T) + lam * lnJ[:, None, None] * Finv_T


def neo_hookean_tangent(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """A_ijkl = mu d_ik d_jl + (mu - lambda ln J) F^-T_il F^-T_kj + lambda F^-T_ij F^-T_kl
    (d(F^-T)_ij/dF_kl = -F^-T_il F^-T_kj, d(ln J)/dF = F^-T)."""
    G = _T(np.linalg.inv(F))
    lnJ = np.log(np.linalg.det(F))
    return (mu * np.einsum("ik,jl->ijkl", I3, I3) + (mu - lam * lnJ)[:, None, None, None, None]
            * np.einsum("nil,nkj->nijkl", G, G) + lam * np.einsum("nij,nkl->nijkl", G, G))


def corotated_stress(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """P = 2 mu (F - R) + lambda (J - 1) J F^-T, R = polar rotation of F (Klar's R* with S = I)."""
    J = np.linalg.det(F)
    R = klar_rotation(F, np.broadcast_to(I3, F.shape), rotation_variant=True)
    return 2.0 * mu * (F - R) + (lam * (J - 1.0) * J)[:, None, None] * _T(np.linalg.inv(F))


def corotated_tangent(F: np.ndarray, mu: float, lam: float) -> np.ndarray:
    """A = 2 mu (d_ik d_jl - dR_ij/dF_kl)
         + lambda (J^2 F^-T_ij F^-T_kl + (J - 1) J (F^-T_ij F^-T_kl - F^-T_il F^-T_kj)),
    dR from Klar eqs. 5-6 with S = I (McAdams et al. 2011)."""
    S = np.broadcast_to(I3, F.shape)
    J = np.linalg.det(F)
    G = _T(np.linalg.inv(F))
    shear = klar_eq4_tangent(F, S, mu, rotation_variant=True)  # 2 mu (dF - dR) with S = I
    GG = np.einsum("nij,nkl->nijkl", G, G)
    Gx = np.einsum("nil,nkj->nijkl", G, G)
    c = lambda a: a[:, None, None, None, None]  # noqa: E731
    return shear + lam * (c(J * J) * GG + c((J - 1.0) * J) * (GG - Gx))


# --- thesis eq. 4.5 on one tetrahedron --------------------------------------------------------------------------

#: the one tetrahedron (reference positions), not the unit one, positively oriented
TET = np.array([[0.05, -0.02, 0.01], [1.2, 0.1, 0.0], [0.2, 0.9, 0.1], [0.1, 0.3, 1.1]])


def irving_Bm(X: np.ndarray) -> np.ndarray:
    """B_m of eq. 4.5: "the matrix having as vectors the area-weighted normals (Irving et al. 2004)".

    Notation decision: Irving et al.'s definition, columns b_i = -(1/3)(A_1 N_1 + A_2 N_2 + A_3 N_3)
    for the vertices i = 1, 2, 3, the sum over the three faces incident to vertex i, A N the
    outward area-weighted normals in the reference configuration (computed here from cross
    products of the face edges). G = P B_m holds the forces g_1, g_2, g_3, and g_0 = -(g_1 + g_2 + g_3).
    """
    normals = []
    for opposite in range(4):
        a, b, c = (v for v in range(4) if v != opposite)
        n = 0.5 * np.cross(X[b] - X[a], X[c] - X[a])
        normals.append(n if n @ (X[a] - X[opposite]) > 0 else -n)
    return np.stack([-sum(normals[f] for f in range(4) if f != i) / 3.0 for i in (1, 2, 3)], axis=1)


def thesis_eq4_5_forces(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Eq. 4.5, as printed: G = P B_m, the forces on vertices 1..3 (columns), g_0 = -(g_1 + g_2 + g_3).

    Returns (n, 4, 3): force on vertex a, component i.
    """
    G = P @ irving_Bm(X)  # (n, 3, 3): [component, vertex 1..3]
    g = np.concatenate([-G.sum(axis=2, keepdims=True), G], axis=2)
    return _T(g)


def thesis_eq4_5_stiffness(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The stiffness printed below eq. 4.5: K = dG/dq = (dP/dF B_m) dF/dq.

    K[(a, i), (b, k)] = sum_jl dP_ij/dF_kl (B_m)_ja dF_kl/dx_bk with F = D_s D_m^-1,
    D_m = [X_1 - X_0, X_2 - X_0, X_3 - X_0]: dF_kl/dx_bk = (D_m^-1)_bl for b = 1..3 and
    -sum_b (D_m^-1)_bl for b = 0; the row of vertex 0 is minus the sum of the others (g_0).
    Returns (n, 12, 12) in (vertex, component) order.
    """
    Bm = irving_Bm(X)
    Dinv = np.linalg.inv((X[1:] - X[0]).T)  # rows b = 1..3 of dF/dx_b
    dFdx = np.concatenate([-Dinv.sum(axis=0, keepdims=True), Dinv], axis=0)  # (4, 3): [b, l]
    K = np.einsum("nijkl,ja,bl->naibk", A, Bm, dFdx)  # a = 1..3
    K = np.concatenate([-K.sum(axis=1, keepdims=True), K], axis=1)
    return K.reshape(len(A), 12, 12)


def _thesis_rows(F: np.ndarray, ref: Quantities) -> list[SeedRow]:
    mu, lam = MU_THESIS, LAMBDA_THESIS
    E = _green(F)
    trE2 = np.trace(E, axis1=1, axis2=2) ** 2
    src = f"{THESIS} "
    rows = []
    eq43 = thesis_eq4_3_energy(F, mu, lam)
    excess = _check({"psi": eq43 - ref["psi"]}, {"psi": 0.5 * lam * trE2})[0]
    rows.append(_row("thesis-eq4.3", src + "eq. 4.3", _check({"psi": eq43}, ref),
                     "lambda tr^2(E) must be (lambda/2) tr^2(E): eq. 4.3 exceeds the StVK energy by exactly "
                     f"(lambda/2)(tr E)^2 (rel {excess.max_rel_error:.1e}); its own stress eq. 4.11 is the "
                     "derivative of the lambda/2 form"))
    rows.append(_row("thesis-eq4.3-corrected", src + "eq. 4.3",
                     _check({"psi": thesis_eq4_3_corrected(F, mu, lam)}, ref),
                     "Psi = mu E:E + (lambda/2)(tr E)^2"))
    rows.append(_row("thesis-eq4.11", src + "eq. 4.11 (= C.1)", _check({"P": thesis_eq4_11_stress(F, mu, lam)}, ref),
                     "agrees: P = F [2 mu E + lambda tr(E) I]"))
    diagnosis = ("the second mu term (F^T F)_pi delta_jq must be (F F^T)_ip delta_jq (C.15 has "
                 "F_pl F^T_li = (F F^T)_pi; C.16 mis-simplifies it); equal only where F^T F = F F^T "
                 "(identity, rotations, isotropic stretch); the lambda part C.22 is right")
    rows.append(_row("thesis-eq4.12", src + "eq. 4.12", _check({"A": thesis_eq4_12_tangent(F, mu, lam)}, ref),
                     diagnosis))
    rows.append(_row("thesis-eq4.12-corrected", src + "eq. 4.12",
                     _check({"A": thesis_eq4_12_corrected(F, mu, lam)}, ref),
                     "mu (d_ip (F^T F)_qj + (F F^T)_ip d_jq + F_iq F_pj - d_ip d_jq) + C.22"))
    rows.append(_row("thesis-eqC.15", src + "eqs. C.15 + C.22", _check({"A": thesis_eqC15_tangent(F, mu, lam)}, ref),
                     "agrees: the step before C.16 is still right (F_pl F^T_li = (F F^T)_pi); C.22 agrees"))
    rows.append(_row("thesis-eqC.16", src + "eqs. C.16 + C.22", _check({"A": thesis_eqC16_tangent(F, mu, lam)}, ref),
                     "C.16: " + diagnosis))
    rows.append(_row("thesis-eqC.16-corrected", src + "eqs. C.16 + C.22",
                     _check({"A": thesis_eq4_12_corrected(F, mu, lam)}, ref),
                     "C.16 with (F F^T)_ip d_jq, plus C.22 as printed"))
    return rows


def _thesis_muscle_rows() -> list[SeedRow]:
    """Eqs. 4.8 (B.19), 4.9, 4.10 and dU/dF against the ``muscle`` law with its fibre term isolated."""
    F, _ = deformation_samples(SAMPLES, SEED, inverted=False)
    a0 = field_samples("muscle", SAMPLES, SEED)["a0"]
    alpha = np.ones(SAMPLES)
    full = ReferenceEvaluator("muscle", MUSCLE_FIBRE, SAMPLES).evaluate(F, a0=a0, alpha=alpha)
    volume = ReferenceEvaluator("muscle", MUSCLE_VOLUME, SAMPLES).evaluate(F, a0=a0, alpha=alpha)
    lbar = fibre_stretch_np(F, a0)
    lo, hi = MUSCLE_STRETCH_RANGE
    keep = (lbar > lo * MUSCLE_L_OFL) & (lbar < hi * MUSCLE_L_OFL)
    Fk, ak = F[keep], a0[keep]
    dF2, d2F2 = muscle_fibre_derivatives(lbar[keep])
    # P_fibre = P(muscle) - P(U) = dF2/dlbar d lbar/dF, A_fibre likewise
    fibre = {"P": (full["P"] - volume["P"])[keep], "A": (full["A"] - volume["A"])[keep]}
    where = (f"{int(keep.sum())} of {SAMPLES} samples with {lo} < lbar < {hi} (alpha = 1, P1 = 0, c1 = c2 = 0: "
             "P_fibre = P(muscle) - P(muscle, sigma_max = 0))")
    U, _, V = thesis_diagonalise(Fk)
    fibre_hat = {"P": _T(U) @ fibre["P"] @ V}
    src = f"{THESIS} "
    rows = [_row("thesis-eq4.8", src + "eq. 4.8 (= B.19)",
                 _check({"P": dF2[:, None, None] * thesis_eq4_8_dlbar(Fk, ak)}, fibre),
                 f"agrees: dF2/dlbar times eq. 4.8 is the UFL fibre stress; {where}"),
            _row("thesis-eqB.19", src + "eq. B.19",
                 _check({"P": dF2[:, None, None] * thesis_eq4_8_dlbar(Fk, ak)}, fibre),
                 "agrees: B.19 is eq. 4.8 (the same formula, derived step by step in B.2-B.18)")]
    rows.append(_row("thesis-eq4.9", src + "eq. 4.9 (and after fig. B.1)",
                     _check({"P": thesis_eq4_9_stress(Fk, ak, dF2)}, fibre_hat),
                     "the F^-T term is wrong in the diagonal frame: -1/3 J^2 Fhat must be -1/3 (b . Fhat^2 b) Fhat^-1 "
                     "(F^-T tr((Fa)(Fa)^T) with Fhat^-T = Fhat^-1, b = V^T a0); Fhat Ones (x) b b^T is the right "
                     "Fhat b b^T; compared in the frame U^T P V"))
    rows.append(_row("thesis-eq4.9-corrected", src + "eq. 4.9",
                     _check({"P": thesis_eq4_9_corrected(Fk, ak, dF2)}, fibre_hat),
                     "Phat = dF2/dlbar J^(-2/3)/lbar [-1/3 (b . Fhat^2 b) Fhat^-1 + Fhat b b^T], b = V^T a0 "
                     "(eq. 4.8 with F = Fhat)"))
    as_lambda_hessian = _check({"A": d2F2[:, None, None, None, None] * np.einsum(
        "npq,nkl->npqkl", thesis_eq4_8_dlbar(Fk, ak), thesis_eq4_8_dlbar(Fk, ak))
        + dF2[:, None, None, None, None] * thesis_eq4_10_tangent(Fk, ak)}, fibre)[0]
    rows.append(_row("thesis-eq4.10", src + "eq. 4.10 (and end of appendix B)",
                     _check({"A": thesis_eq4_10_tangent(Fk, ak)}, fibre),
                     "incomplete: it only differentiates the J^(-2/3) factor of eq. 4.8 (with -2/9 where that gives "
                     "+2/9), drops d(F^-T)/dF, d|Fa|^2/dF, d(1/lbar)/dF and d(F a a^T)/dF, and the chain rule "
                     "factors dF2/dlbar and d2F2/dlbar2 (dlbar/dF (x) dlbar/dF); even read as d2lbar/dF2 inside "
                     f"the chain rule it disagrees (rel {as_lambda_hessian.max_rel_error:.1e})"))
    rows.append(_row("thesis-eq4.10-corrected", src + "eq. 4.10",
                     _check({"A": thesis_eq4_10_corrected(Fk, ak, dF2, d2F2)}, fibre),
                     "d2F2/dlbar2 g (x) g + dF2/dlbar dg/dF, g = eq. 4.8 = -lbar/3 F^-T + J^(-2/3)/lbar (Fa) a^T, "
                     "dg/dF written out in thesis_eq4_10_corrected"))
    U_all, _, V_all = thesis_diagonalise(F)
    checks = _check({"P": thesis_dUdF(F, MUSCLE_K)}, volume)
    checks += _check({"P": thesis_dUdFhat(F, MUSCLE_K)}, {"P": _T(U_all) @ volume["P"] @ V_all})
    rows.append(_row("thesis-dUdF", src + "dU/dF after eq. 4.10 (and appendix B)", checks,
                     f"agrees at all {SAMPLES} samples: 2 K ln(J) F^-T is P of the muscle law with c1 = c2 = 0, "
                     "sigma_max = 0 (psi = K (ln J)^2); the diagonalised 2 K ln(det Fhat) Fhat^-1 equals U^T P V "
                     f"(rel {checks[1].max_rel_error:.1e})"))
    return rows


HandLaw = tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]


def _element_rows() -> list[SeedRow]:
    """Thesis eq. 4.5 and its stiffness, with hand-derived P and dP/dF, against a one-cell dolfinx assembly."""
    mu, lam = MU_THESIS, LAMBDA_THESIS
    F, _ = deformation_samples(ELEMENT_SAMPLES, SEED + 1, inverted=False)
    S = field_samples("shape_target", ELEMENT_SAMPLES, SEED + 1)["S"]
    lame = {"mu": mu, "lmbda": lam}
    cases: list[tuple[str, dict[str, float], str, HandLaw]] = [
        ("stvk", lame, "P eq. 4.11, dP/dF eq. 4.12-corrected",
         (lambda F_: thesis_eq4_11_stress(F_, mu, lam), lambda F_: thesis_eq4_12_corrected(F_, mu, lam))),
        ("neo_hookean", lame, "P = mu (F - F^-T) + lambda ln J F^-T and its derivative",
         (lambda F_: neo_hookean_stress(F_, mu, lam), lambda F_: neo_hookean_tangent(F_, mu, lam))),
        ("corotated", lame, "P = 2 mu (F - R) + lambda (J - 1) J F^-T, dR from Klar eq. 5 with S = I",
         (lambda F_: corotated_stress(F_, mu, lam), lambda F_: corotated_tangent(F_, mu, lam))),
        ("shape_target", {"mu": MU_KLAR}, "P Klar eq. 3, dP/dF Klar eqs. 4-6",
         (lambda F_: klar_eq3_stress(F_, S, MU_KLAR), lambda F_: klar_eq4_tangent(F_, S, MU_KLAR))),
    ]
    rows = []
    for material, params, hand, (stress, tangent) in cases:
        # the one-tetrahedron element of verify element; u = (F - I) X at the nodes, f = dW/du (the residual)
        cell = ElementAssembler(material, params, TET, "tet4",
                                fields={"S": np.eye(3)} if "S" in forms.FIELDS.get(material, ()) else None)
        assembled = [cell.assemble(TET @ (F[n] - I3).T, {"S": S[n]} if cell.constants else None)
                     for n in range(ELEMENT_SAMPLES)]
        ref = {"P": np.array([a.f for a in assembled]), "A": np.array([a.K for a in assembled])}
        forces = thesis_eq4_5_forces(stress(F), TET).reshape(-1, 12)
        stiffness = thesis_eq4_5_stiffness(tangent(F), TET)
        # the residual is dW/du = -G, its Jacobian -dG/dq (G are forces; the element vector in the "P" slot
        # of compare, the matrix in the "A" slot)
        checks = _check({"P": -forces, "A": -stiffness}, ref)
        rows.append(_row(f"thesis-eq4.5-{material}", f"{THESIS} eq. 4.5 and K below it", checks,
                         f"element vector (rel {checks[0].max_rel_error:.1e}) and 12x12 matrix (rel "
                         f"{checks[1].max_rel_error:.1e}) agree with dolfinx on one tet: G = P B_m (B_m from Irving's "
                         f"area-weighted normals) = -residual, (dP/dF B_m) dF/dq = -Jacobian; {hand}"))
    return rows


# --- thesis eqs. 4.13-4.15: spring constraints (section 4.3.4.1) -------------------------------------------------

#: spring stiffness k_s (eq. 4.13)
SPRING_KS = 2.5
SPRING_SOURCE = "eq. {} (sec. 4.3.4.1 Springs view, p. 76)"


def thesis_eq4_13_energy(q: np.ndarray, r: np.ndarray, ks: float) -> np.ndarray:
    """Thesis eq. 4.13, as printed: W(q) = k_s ||q| - r|^2, q = x_b - x_a the spring vector, r its rest length
    (r = 0: the zero-length springs of the penalty collisions)."""
    return ks * np.abs(np.linalg.norm(q, axis=-1) - r) ** 2


def thesis_eq4_14_force(q: np.ndarray, r: np.ndarray, ks: float) -> np.ndarray:
    """Thesis eq. 4.14, as printed: f(q) = k_s (|q| - r) q/|q|, "the Jacobian of the energy" (dW/dq: no minus sign;
    the force on the end x_b is -f, on x_a +f)."""
    L = np.linalg.norm(q, axis=-1)
    return (ks * (L - r) / L)[:, None] * q


def thesis_eq4_14_corrected(q: np.ndarray, r: np.ndarray, ks: float) -> np.ndarray:
    """dW/dq of eq. 4.13: 2 k_s (|q| - r) q/|q| (or eq. 4.14 as printed with W = (k_s/2)(|q| - r)^2)."""
    return 2.0 * thesis_eq4_14_force(q, r, ks)


def thesis_eq4_15_hessian(q: np.ndarray, r: np.ndarray, ks: float) -> np.ndarray:
    """Thesis eq. 4.15, as printed: df/dq = k_s [(1 - r/|q|) I + r/|q| q q^T] (the parenthesis "(|q|)" read as |q|)."""
    L = np.linalg.norm(q, axis=-1)
    return ks * ((1.0 - r / L)[:, None, None] * I3 + (r / L)[:, None, None] * np.einsum("ni,nj->nij", q, q))


def thesis_eq4_15_corrected(q: np.ndarray, r: np.ndarray, ks: float) -> np.ndarray:
    """d2W/dq2 of eq. 4.13: 2 k_s [(1 - r/|q|) I + r/|q|^3 q q^T]."""
    L = np.linalg.norm(q, axis=-1)
    return 2.0 * ks * ((1.0 - r / L)[:, None, None] * I3
                       + (r / L**3)[:, None, None] * np.einsum("ni,nj->nij", q, q))


def spring_on_ends(gradient: np.ndarray, hessian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dW/dq and d2W/dq2 carried to the end points X = (x_a, x_b), q = x_b - x_a: (-g, g) and [[H, -H], [-H, H]]."""
    return (np.concatenate([-gradient, gradient], axis=1),
            np.block([[hessian, -hessian], [-hessian, hessian]]))


def spring_samples(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n springs: end points (n, 2, 3) and rest lengths (n,): the first third zero-length, then springs stretched
    and compressed (|q|/r from 0.2 to 3), a few at |q| = r."""
    rng = np.random.default_rng(seed)
    ends = rng.standard_normal((n, 2, 3))
    L = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    ratio = np.exp(rng.uniform(np.log(0.2), np.log(3.0), n))
    ratio[-3:] = 1.0
    r = L / ratio
    r[: n // 3] = 0.0
    return ends, r


def _spring_rows() -> list[SeedRow]:
    from model.verify.seeds.thesis_reference import SpringReference

    ks = SPRING_KS
    ends, r = spring_samples(SAMPLES, SEED + 4)
    ref = SpringReference(SAMPLES, ks).evaluate(ends, r)
    q = ends[:, 1] - ends[:, 0]
    n_zero = int(np.sum(r == 0.0))
    src = f"{THESIS} " + SPRING_SOURCE
    where = (f"{SAMPLES} springs ({n_zero} zero-length), |q|/r in 0.2-3, reference dW/dX, d2W/dX2 by ufl.diff of "
             "eq. 4.13 with respect to the end points X = (x_a, x_b)")
    rows = [_row("thesis-eq4.13", src.format("4.13"), _check({"psi": thesis_eq4_13_energy(q, r, ks)}, ref),
                 f"agrees: W = k_s (|q| - r)^2 is the potential the reference differentiates; {where}")]
    g_printed, _ = spring_on_ends(thesis_eq4_14_force(q, r, ks), np.zeros((SAMPLES, 3, 3)))
    half = _check({"P": 2.0 * g_printed}, ref)[0]
    rows.append(_row("thesis-eq4.14", src.format("4.14"), _check({"P": g_printed}, ref),
                     "f = k_s (|q| - r) q/|q| is half of dW/dq of eq. 4.13 (twice it agrees, rel "
                     f"{half.max_rel_error:.1e}): the factor 2 is missing, or eq. 4.13 needs k_s/2"))
    rows.append(_row("thesis-eq4.14-corrected", src.format("4.14"),
                     _check({"P": spring_on_ends(thesis_eq4_14_corrected(q, r, ks), np.zeros((SAMPLES, 3, 3)))[0]},
                            ref), "f = dW/dq = 2 k_s (|q| - r) q/|q| (-f on x_a, +f on x_b)"))
    _, H_printed = spring_on_ends(q, thesis_eq4_15_hessian(q, r, ks))
    _, H_of_eq4_14 = spring_on_ends(q, 0.5 * thesis_eq4_15_corrected(q, r, ks))
    vs_eq4_14 = _check({"A": H_printed}, {"A": H_of_eq4_14})[0]
    zero = r == 0.0
    at_zero = _check({"A": 2.0 * H_printed[zero]}, {"A": ref["A"][zero]})[0]
    rows.append(_row("thesis-eq4.15", src.format("4.15"), _check({"A": H_printed}, ref),
                     "r/|q| q q^T must be r/|q|^3 q q^T (= r/|q| qhat qhat^T, qhat = q/|q|), and the factor 2 "
                     "of eq. 4.14 is missing: eq. 4.15 is not even the derivative of eq. 4.14 (rel "
                     f"{vs_eq4_14.max_rel_error:.1e}); right up to the factor 2 only for zero-length springs "
                     f"(2x eq. 4.15 at r = 0: rel {at_zero.max_rel_error:.1e})"))
    rows.append(_row("thesis-eq4.15-corrected", src.format("4.15"),
                     _check({"A": spring_on_ends(q, thesis_eq4_15_corrected(q, r, ks))[1]}, ref),
                     "d2W/dq2 = 2 k_s [(1 - r/|q|) I + r/|q|^3 q q^T] ([[H, -H], [-H, H]] on the end points)"))
    return rows


# --- thesis section 3.3.3.1: the inflating membrane (elastic model and forces) ----------------------------------

MEMBRANE_SOURCE = "sec. 3.3.3.1 Elastic Model and Forces, p. 49"
#: the membrane's Young's modulus E, Poisson ratio nu, thickness h, and the base pressure p
MEMBRANE_Y, MEMBRANE_NU, MEMBRANE_THICKNESS, MEMBRANE_PRESSURE = 3.0, 0.3, 0.02, 0.7
#: the one rest triangle (in 3D, not in a coordinate plane)
TRIANGLE = np.array([[0.1, -0.05, 0.2], [1.1, 0.2, 0.1], [0.3, 0.9, 0.5]])
#: the closed surface of the tetrahedron TET: its faces, each oriented outward (x_b - x_a) x (x_c - x_a)
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def membrane_material_coords(X: np.ndarray) -> np.ndarray:
    """"At the initialization stage, 2D material space coordinates are calculated for each element": the rest
    triangle X (3, 3) laid flat isometrically, (u, v) of its nodes (3, 2), u along X_2 - X_1, v in its plane."""
    e1 = (X[1] - X[0]) / np.linalg.norm(X[1] - X[0])
    n = np.cross(X[1] - X[0], X[2] - X[0])
    e2 = np.cross(n / np.linalg.norm(n), e1)
    return np.stack([(X - X[0]) @ e1, (X - X[0]) @ e2], axis=1)


def _membrane_Dm(Xbar: np.ndarray) -> np.ndarray:
    """[[xb2 - xb1, xb3 - xb1], [yb2 - yb1, yb3 - yb1]] of the printed F."""
    return (Xbar[1:] - Xbar[0]).T


def thesis_membrane_F(x: np.ndarray, Xbar: np.ndarray) -> np.ndarray:
    """Sec. 3.3.3.1, as printed: F (3x2) = [x2 - x1, x3 - x1] [[xb2 - xb1, xb3 - xb1], [yb2 - yb1, yb3 - yb1]]^-1,
    x (n, 3 nodes, 3) the deformed nodes, Xbar (3, 2) the material coordinates."""
    Ds = np.swapaxes(x[:, 1:] - x[:, :1], 1, 2)  # (n, 3, 2)
    return Ds @ np.linalg.inv(_membrane_Dm(Xbar))


def thesis_membrane_B(young: float, nu: float) -> np.ndarray:
    """The printed 3x3 B: E/(1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu)/2]]."""
    c = young / (1.0 - nu**2)
    return c * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]])


#: Voigt vector (11, 22, 12) <-> symmetric 2x2 tensor: VOIGT[a, i, j] = 1 where (i, j) is the a-th component
VOIGT = np.zeros((3, 2, 2))
VOIGT[0, 0, 0] = VOIGT[1, 1, 1] = VOIGT[2, 0, 1] = VOIGT[2, 1, 0] = 1.0
#: engineering shear: the strain in Voigt form is (G11, G22, 2 G12)
STRAIN_SCALE = np.array([1.0, 1.0, 2.0])


def thesis_membrane_stress(F: np.ndarray, young: float, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """(G (n, 2, 2), sigma (n, 3)): G = (C - I)/2, C = F^T F; sigma = B eps with eps = (G11, G22, 2 G12), the usual
    Voigt strain (engineering shear; the reading that makes b33 = E/(1 - nu^2)(1 - nu)/2 the shear modulus)."""
    G = 0.5 * (_T(F) @ F - np.eye(2))
    eps = STRAIN_SCALE * np.stack([G[:, 0, 0], G[:, 1, 1], G[:, 0, 1]], axis=1)
    return G, eps @ thesis_membrane_B(young, nu).T


def thesis_membrane_energy(x: np.ndarray, Xbar: np.ndarray, young: float, nu: float, thickness: float) -> np.ndarray:
    """Sec. 3.3.3.1, as printed: E_e = int_Ve 1/2 (G:B:G) dv = 1/2 (G:sigma) A_e h, G:sigma the tensor contraction
    (G11 s11 + G22 s22 + 2 G12 s12 = eps . sigma), A_e = |det Dm|/2 the undeformed area."""
    G, sigma = thesis_membrane_stress(thesis_membrane_F(x, Xbar), young, nu)
    area = 0.5 * abs(np.linalg.det(_membrane_Dm(Xbar)))
    return 0.5 * np.einsum("nij,aij,na->n", G, VOIGT, sigma) * area * thickness


def _membrane_dFdx(Xbar: np.ndarray) -> np.ndarray:
    """dF_ij/dx_(a, k) = delta_ik D[a, j]: D (3 nodes, 2), rows 2, 3 = Dm^-1 rows, row 1 minus their sum."""
    Dinv = np.linalg.inv(_membrane_Dm(Xbar))
    return np.concatenate([-Dinv.sum(axis=0, keepdims=True), Dinv], axis=0)


def thesis_membrane_forces(x: np.ndarray, Xbar: np.ndarray, young: float, nu: float,
                           thickness: float) -> np.ndarray:
    """-grad_x E_e ("obtained by analytical derivation", not printed): with psi = 1/2 G:sigma, dpsi/dF = F S,
    S the 2x2 tensor of sigma (s12 off the diagonal): f_a = -A_e h (F S) D[a] (n, 3 nodes, 3)."""
    F = thesis_membrane_F(x, Xbar)
    _, sigma = thesis_membrane_stress(F, young, nu)
    S = np.einsum("na,aij->nij", sigma, VOIGT)
    area = 0.5 * abs(np.linalg.det(_membrane_Dm(Xbar)))
    return -area * thickness * np.einsum("nij,aj->nai", F @ S, _membrane_dFdx(Xbar))


def thesis_membrane_hessian(x: np.ndarray, Xbar: np.ndarray, young: float, nu: float,
                            thickness: float) -> np.ndarray:
    """-grad_x grad_x E_e (n, 9, 9), (node, component) order: dP_ij/dF_kl = delta_ik S_jl + F_im dS_mj/dF_kl,
    dS = VOIGT^T B (STRAIN_SCALE deps), dG_mj/dF_kl = (delta_jl F_km + delta_ml F_kj)/2."""
    F = thesis_membrane_F(x, Xbar)
    _, sigma = thesis_membrane_stress(F, young, nu)
    S = np.einsum("na,aij->nij", sigma, VOIGT)
    I2 = np.eye(2)
    dG = 0.5 * (np.einsum("jl,nkm->nmjkl", I2, F) + np.einsum("ml,nkj->nmjkl", I2, F))  # dG_mj/dF_kl
    deps = STRAIN_SCALE[None, :, None, None] * dG[:, [0, 1, 0], [0, 1, 1]]  # d(G11, G22, 2 G12)/dF_kl
    dsigma = np.einsum("ab,nbkl->nakl", thesis_membrane_B(young, nu), deps)
    dS = np.einsum("nakl,amj->nmjkl", dsigma, VOIGT)
    dP = np.einsum("ik,njl->nijkl", I3, S) + np.einsum("nim,nmjkl->nijkl", F, dS)
    D = _membrane_dFdx(Xbar)
    area = 0.5 * abs(np.linalg.det(_membrane_Dm(Xbar)))
    return -area * thickness * np.einsum("nijkl,aj,bl->naibk", dP, D, D).reshape(len(x), 9, 9)


def thesis_membrane_pressure(x: np.ndarray, faces: np.ndarray, p: float, unit_area: bool = True) -> np.ndarray:
    """Sec. 3.3.3.1, as printed: f_i = sum over the triangles j around vertex i of 1/3 p_i A_j n_j, "a unit area
    A_j for all triangles is used" (``unit_area``; False: A_j the deformed area), n_j the unit normal of the
    deformed triangle (outward: faces ordered so), p_i = p at every vertex. x (n, vertices, 3) -> (n, vertices, 3)."""
    f = np.zeros_like(x)
    for face in faces:
        c = np.cross(x[:, face[1]] - x[:, face[0]], x[:, face[2]] - x[:, face[0]])
        area = 0.5 * np.linalg.norm(c, axis=1)
        normal = 0.5 * c / area[:, None]
        A = np.ones_like(area) if unit_area else area
        for i in face:
            f[:, i] += (p * A / 3.0)[:, None] * normal
    return f


def _membrane_rows() -> list[SeedRow]:
    from model.verify.seeds.thesis_reference import MembraneTriangle, PressureSurface

    Y, nu, h, p = MEMBRANE_Y, MEMBRANE_NU, MEMBRANE_THICKNESS, MEMBRANE_PRESSURE
    F3, _ = deformation_samples(ELEMENT_SAMPLES, SEED + 2, inverted=False)
    rng = np.random.default_rng(SEED + 2)
    x = np.einsum("nij,aj->nai", F3, TRIANGLE) + 0.05 * rng.standard_normal((ELEMENT_SAMPLES, 3, 3))
    Xbar = membrane_material_coords(TRIANGLE)
    cell = MembraneTriangle(TRIANGLE, Y, nu, h)
    values = [cell.evaluate(xn) for xn in x]
    ref = {"psi": np.array([v[0] for v in values]), "P": np.array([v[1] for v in values]),
           "A": np.array([v[2] for v in values])}
    F = thesis_membrane_F(x, Xbar)
    src = f"{THESIS} " + MEMBRANE_SOURCE
    how = (f"one triangle in 3D, {ELEMENT_SAMPLES} deformations; dolfinx manifold mesh (gdim 3, tdim 2), F = grad(phi) "
           "[t1 t2], E = (F^T F - I2)/2, psi = mu E:E + (lambda'/2)(tr E)^2, lambda' = E nu/(1 - nu^2)")
    b_check = _check({"P": F @ _T(F)}, {"P": np.array([v[3] for v in values])})
    rows = [_row("thesis-sec3.3.3.1-F", src + ", F", b_check,
                 "agrees: F = [x2 - x1, x3 - x1] Dm^-1 (3x2) in the flattened material coordinates; compared as F F^T "
                 "(independent of the in-plane material frame) with dolfinx's grad(phi) [t1 t2]")]
    energy = _check({"psi": thesis_membrane_energy(x, Xbar, Y, nu, h)}, ref)
    rows.append(_row("thesis-sec3.3.3.1-energy", src + ", B and E_e", energy,
                     "agrees: 1/2 (G:sigma) A_e h with sigma = B eps, eps = (G11, G22, 2 G12) (Voigt, engineering "
                     f"shear) is the plane-stress StVK membrane energy; {how}"))
    forces = _check({"P": -thesis_membrane_forces(x, Xbar, Y, nu, h).reshape(-1, 9)}, ref)
    rows.append(_row("thesis-sec3.3.3.1-forces", src + ", -grad_x E_stretch", forces,
                     "agrees: -grad_x E_e = -A_e h (F S) Dm^-T (node 1: minus the sum) = -residual, ufl.derivative of "
                     "the UFL energy"))
    hessian = _check({"A": -thesis_membrane_hessian(x, Xbar, Y, nu, h)}, ref)
    rows.append(_row("thesis-sec3.3.3.1-hessian", src + ", -grad_x grad_x E_stretch", hessian,
                     "agrees: -A_e h (d(F S)/dF : D (x) D) = -Jacobian, the second ufl.derivative of the energy"))
    # pressure: the closed surface of TET, the reference the derivative of the pressure work p V(x)
    xs = np.einsum("nij,aj->nai", F3, TET) + 0.05 * rng.standard_normal((ELEMENT_SAMPLES, 4, 3))
    surface = PressureSurface(TET, TET_FACES)
    ref_p = {"P": p * np.array([surface.evaluate(xn)[1] for xn in xs])}
    areas = np.array([0.5 * np.linalg.norm(np.cross(xs[:, f[1]] - xs[:, f[0]], xs[:, f[2]] - xs[:, f[0]]), axis=1)
                      for f in TET_FACES])
    printed = _check({"P": thesis_membrane_pressure(xs, TET_FACES, p).reshape(-1, 12)}, ref_p)
    rows.append(_row("thesis-sec3.3.3.1-pressure", src + ", f_i with unit A_j", printed,
                     "with A_j = 1 (the thesis' deliberate choice, so that small tendon triangles inflate) f_i is not "
                     "the pressure force p dV/dx_i = sum_j p A_j n_j / 3 (V the enclosed volume, UFL on the closed "
                     f"surface of a tetrahedron); off by the factor 1/A_j per triangle (deformed areas "
                     f"{areas.min():.2f}-"
                     f"{areas.max():.2f})"))
    rows.append(_row("thesis-sec3.3.3.1-pressure-corrected", src + ", f_i",
                     _check({"P": thesis_membrane_pressure(xs, TET_FACES, p, unit_area=False).reshape(-1, 12)}, ref_p),
                     "f_i = sum_j 1/3 p A_j n_j with A_j the deformed area (uniform p): p dV/dx_i, dV/dx by "
                     "ufl.derivative of V = (1/3) int phi . n da"))
    return rows


# --- thesis eq. 4.4: the semi-implicit backward Euler step (section 4.3.2) ---------------------------------------

EULER_SOURCE = "eq. 4.4 and the linear system below it (sec. 4.3.2 Solver, from p. 64)"
#: density rho, Rayleigh damping D = alpha M + beta K, time step h, body force
EULER_RHO, EULER_ALPHA, EULER_BETA, EULER_H = 1.1, 0.2, 0.01, 0.1
EULER_BODY_FORCE = np.array([0.0, -0.3, -1.0])
EULER_SAMPLES = 7


def thesis_eq4_4_step(M: np.ndarray, K: np.ndarray, f_int: np.ndarray, f_ext: np.ndarray, qn: np.ndarray,
                      vn: np.ndarray, h: float, alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Thesis eq. 4.4 linearised, as printed: (M + h D = h^2 K)(v_{n+1} - v_n) = h (f_ext - f_int(q_n) - D v_n
    - h K v_n), q_{n+1} = q_n + h v_{n+1}, D = alpha M + beta K(q_n). The "=" inside the matrix is read as "+"
    (M + h D + h^2 K, what f_int(q_{n+1}) = f_int(q_n) + K (q_{n+1} - q_n) put into eq. 4.4 gives)."""
    D = alpha * M + beta * K
    dv = np.linalg.solve(M + h * D + h * h * K, h * (f_ext - f_int - D @ vn - h * K @ vn))
    v1 = vn + dv
    return qn + h * v1, v1


def _euler_rows() -> list[SeedRow]:
    from model.verify.seeds.thesis_reference import BackwardEulerCell

    mu, lam, h = MU_THESIS, LAMBDA_THESIS, EULER_H
    cell = BackwardEulerCell(TET, mu, lam, EULER_RHO, EULER_ALPHA, EULER_BETA, h, EULER_BODY_FORCE)
    rng = np.random.default_rng(SEED + 3)
    printed, newton, from_vn, converged = [], [], [], []
    for _ in range(EULER_SAMPLES):
        F = I3 + 0.25 * rng.standard_normal((3, 3))
        while np.linalg.det(F) < 0.3:
            F = I3 + 0.25 * rng.standard_normal((3, 3))
        qn = ((F - I3) @ TET.T).T.reshape(-1)
        vn = 0.5 * rng.standard_normal(12)
        cell.state(qn, vn)
        parts = cell.ingredients()
        q1, v1 = thesis_eq4_4_step(parts["M"], parts["K"], parts["f_int"], parts["f_ext"], qn, vn, h,
                                   EULER_ALPHA, EULER_BETA)
        printed.append(np.concatenate([q1, v1]))
        v_newton = cell.newton_step(np.zeros(12))
        newton.append(np.concatenate([qn + h * v_newton, v_newton]))
        v_alt = cell.newton_step(vn)
        from_vn.append(np.concatenate([qn + h * v_alt, v_alt]))
        v = v_newton
        for _ in range(30):
            v = cell.newton_step(v)
            if cell.residual_norm(v) < 1e-13:
                break
        converged.append(np.concatenate([qn + h * v, v]))
    ref = {"P": np.array(newton)}
    checks = _check({"P": np.array(printed)}, ref)
    other = _check({"P": np.array(from_vn)}, ref)[0]
    exact = _check({"P": np.array(printed)}, {"P": np.array(converged)})[0]
    return [_row("thesis-eq4.4", f"{THESIS} {EULER_SOURCE}", checks,
                 "agrees, reading the printed (M + hD = h^2 K) as M + hD + h^2 K: (q_{n+1}, v_{n+1}) is exactly one "
                 "Newton step of the backward Euler system R(v) = M (v - v_n) - h (f_ext - f_int(q_n + h v) - D v) "
                 "from v = 0 (q = q_n, the current positions), Jacobian by ufl.derivative, D = alpha M + beta K(q_n) "
                 f"frozen; not the step from v = v_n (rel {other.max_rel_error:.1e}); one step is "
                 f"{exact.max_rel_error:.1e} (rel) from the converged implicit solution; {EULER_SAMPLES} states of "
                 "one stvk tet, h = 0.1")]
