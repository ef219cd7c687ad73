"""Klar et al. 2020, shape targeting (SIGGRAPH Talks 2020): eqs. 1-6 as printed.

Law ``shape_target`` (mu, field S = S_t). Rows: klar-eq1, klar-eq2, klar-eq3, klar-eq4-6 (positive-det F),
klar-psd (the PSD projection the paper describes, checked independently: optimality certificate and random
competitors), and the klar-eq1/eq3/eq4-6 ``-inverted`` rows (``--inverted`` samples: R* = U* V*^T as the text
defines it is a reflection when det F < 0); ``-corrected`` variants for every disagreement.
"""

from __future__ import annotations

import numpy as np

from model.verify import ReferenceEvaluator, compare, deformation_samples, field_samples
from model.verify.seeds.common import (
    _T,
    I3,
    KLAR,
    RTOL,
    SAMPLES,
    SEED,
    Quantities,
    SeedRow,
    _central_differences,
    _check,
    _fro,
    _row,
)

#: shape targeting: mu (Klar eq. 1)
MU_KLAR = 1.3
#: Levi-Civita symbol eps[i, j, k], eps[0, 1, 2] = +1
LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    LEVI_CIVITA[_i, _j, _k], LEVI_CIVITA[_i, _k, _j] = 1.0, -1.0



# --- Klar et al. 2020: shape targeting ---------------------------------------------------------------------

def _quaternion_rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of (unnormalised) quaternions q = (w, x, y, z), shape (..., 4) -> (..., 3, 3)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1)], -2)


# R_ij(q) = q^T Q[i, j] q: the quadratic forms of the quaternion-to-rotation map, by polarisation.
_E4 = np.eye(4)
_QUAD = np.empty((3, 3, 4, 4))
for _a in range(4):
    for _b in range(4):
        _QUAD[:, :, _a, _b] = 0.25 * (_quaternion_rotation(_E4[_a] + _E4[_b]) - _quaternion_rotation(_E4[_a] - _E4[_b]))


def klar_eq1_energy(F: np.ndarray, S: np.ndarray, mu: float) -> np.ndarray:
    """Klar eq. 1, as printed: Psi(F) = min over R in SO(3) of mu ||F - R S_t||_F^2.

    The minimum over SO(3) is found without an SVD (independently of eq. 2's R* = U V^T):
    ||F - R S||^2 = ||F||^2 + ||S||^2 - 2 tr(R^T F S), and max over unit quaternions q of
    tr(R(q)^T M) = q^T N(M) q (Davenport's q-method) is the largest eigenvalue of the symmetric
    4x4 matrix N(M) = sum_ij M_ij Q_ij, with R_ij(q) = q^T Q_ij q. The maximiser R(q) is put back
    into mu ||F - R S||^2 (the error in R enters only at second order at the minimum).
    """
    M = F @ S
    N = np.einsum("nij,ijab->nab", M, _QUAD)
    _, vectors = np.linalg.eigh(N)
    R = _quaternion_rotation(vectors[..., -1])
    D = F - R @ S
    return mu * np.einsum("nij,nij->n", D, D)


def klar_svd(F: np.ndarray, S: np.ndarray, rotation_variant: bool = False):
    """(U*, Sigma* (as a vector), V*) of F S_t = U* Sigma* V*^T.

    As printed (the text after eq. 2): the SVD, R* = U* V*^T. With ``rotation_variant`` the last
    (smallest) singular value and the last column of U* are negated when det(U* V*^T) < 0, so that
    R* = U* V*^T is a rotation (the correction needed for det F < 0).
    """
    U, sigma, Vt = np.linalg.svd(F @ S)
    if rotation_variant:
        sign = np.where(np.linalg.det(U @ Vt) < 0, -1.0, 1.0)
        U[..., :, 2] *= sign[:, None]
        sigma[..., 2] *= sign
    return U, sigma, _T(Vt)


def klar_rotation(F: np.ndarray, S: np.ndarray, rotation_variant: bool = False) -> np.ndarray:
    """R*(F; S_t) = U* V*^T (text after eq. 2), from ``klar_svd``."""
    U, _, V = klar_svd(F, S, rotation_variant)
    return U @ _T(V)


def klar_eq2_energy(F: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Klar eq. 2, as printed: Psi(F) = ||F - R* S_t||_F (no square, no mu), R* = U* V*^T."""
    return _fro(F - klar_rotation(F, S) @ S)


def klar_eq2_corrected(F: np.ndarray, S: np.ndarray, mu: float) -> np.ndarray:
    """Eq. 2 corrected to equal eq. 1: Psi(F) = mu ||F - R* S_t||_F^2."""
    return mu * _fro(F - klar_rotation(F, S) @ S) ** 2


def klar_eq3_stress(F: np.ndarray, S: np.ndarray, mu: float, rotation_variant: bool = False) -> np.ndarray:
    """Klar eq. 3, as printed: P(F) = 2 mu (F - R* S_t), R* = U* V*^T."""
    return 2.0 * mu * (F - klar_rotation(F, S, rotation_variant) @ S)


def klar_eq5_rotation_differential(F: np.ndarray, S: np.ndarray, dF: np.ndarray,
                                   rotation_variant: bool = False) -> np.ndarray:
    """Klar eqs. 5-6, as printed: dR*[F; dF] = U* {E : [K^-1 E^T : (U*^T dF S_t V*)]} V*^T, K = tr(Sigma*) I - Sigma*.

    Notation decisions. E is the alternating (Levi-Civita) tensor eps_ijk, eps_012 = +1, read as
    the 9x3 matrix E[(ij), k]; E^T is its 3x9 transpose, and ":" contracts the shared index pair:
    (E^T : X)_k = eps_ijk X_ij, a vector (minus twice the axial vector of skew X), and
    (E : w)_ij = eps_ijk w_k, a skew matrix. K^-1 acts on the vector. So, with X = U*^T dF S_t V*,
    the bracket is the skew matrix Omega = E : [K^-1 (E^T : X)] and dR* = U* Omega V*^T. This is
    the reading under which the derivation goes through (skew(X) = (Omega Sigma + Sigma Omega)/2
    = [K w / 2]x with Omega = [w]x); the two contractions with E must be over the same index
    positions (contracting the middle index of eps in one of them flips the sign of dR*).
    """
    U, sigma, V = klar_svd(F, S, rotation_variant)
    X = _T(U) @ dF @ S @ V
    v = np.einsum("ijk,nij->nk", LEVI_CIVITA, X)  # E^T : X
    K = sigma.sum(axis=1)[:, None, None] * I3 - sigma[:, :, None] * I3  # tr(Sigma) I - Sigma
    w = np.linalg.solve(K, v[..., None])[..., 0]  # K^-1 (.)
    Omega = np.einsum("ijk,nk->nij", LEVI_CIVITA, w)  # E : (.)
    return U @ Omega @ _T(V)


def klar_eq4_tangent(F: np.ndarray, S: np.ndarray, mu: float, rotation_variant: bool = False) -> np.ndarray:
    """Klar eq. 4, as printed: dP[F; dF] = 2 mu (dF - dR*[F; dF] S_t), dR* from eq. 5.

    A[n, i, j, k, l] = dP_ij/dF_kl is dP for dF = e_k e_l^T.
    """
    n = len(F)
    A = np.empty((n, 3, 3, 3, 3))
    for k in range(3):
        for l in range(3):
            dF = np.zeros((n, 3, 3))
            dF[:, k, l] = 1.0
            A[:, :, :, k, l] = 2.0 * mu * (dF - klar_eq5_rotation_differential(F, S, dF, rotation_variant) @ S)
    return A


# --- PSD projection (Klar, "modified Newton", described in the text, formula in the supplement) --------------

def check_psd_projection(A_tangent: np.ndarray, seed: int) -> tuple[float, str]:
    """Independent checks of forms.projection.project_psd / project_tangent; (worst normalised violation, summary).

    1. PSD inputs (random Z Z^T of full and deficient rank, 9x9 and 12x12) come back unchanged.
    2. Symmetric indefinite inputs A: X = project_psd(A) is symmetric PSD and satisfies the optimality
       certificate of the projection onto the (self-dual) PSD cone, X >= 0, X - A >= 0, <X, X - A> = 0
       (Moreau), and no random PSD competitor Y = (X^1/2 + e G)(X^1/2 + e G)^T or Y = Z Z^T is closer to
       A in the Frobenius norm.
    3. project_tangent of the reference shape_target tangents (9x9 [(i,j),(k,l)]) is PSD, and leaves the
       already PSD ones unchanged.
    """
    from forms.projection import project_psd, project_tangent

    rng = np.random.default_rng(seed)
    worst = 0.0
    # 1
    unchanged = 0.0
    for n in (9, 12):
        for rank in (n, n - 3, 1):
            Z = rng.standard_normal((40, n, rank))
            P = Z @ _T(Z)
            unchanged = max(unchanged, float(np.max(_fro(project_psd(P) - P) / _fro(P))))
    worst = max(worst, unchanged)
    # 2
    certificate = 0.0
    closer = 0
    competitors = 0
    for n in (9, 12):
        B = rng.standard_normal((40, n, n))
        A = 0.5 * (B + _T(B))
        X = project_psd(A)
        scale = _fro(A)
        certificate = max(certificate,
                          float(np.max(_fro(X - _T(X)) / scale)),
                          float(np.max(-np.linalg.eigvalsh(X)[:, 0] / scale)),
                          float(np.max(-np.linalg.eigvalsh(X - A)[:, 0] / scale)),
                          float(np.max(np.abs(np.einsum("nij,nij->n", X, X - A)) / scale**2)))
        best = _fro(X - A)
        values, vectors = np.linalg.eigh(X)
        root = (vectors * np.sqrt(np.maximum(values, 0.0))[:, None, :]) @ _T(vectors)
        for eps in (1e-6, 1e-3, 1e-1, 1.0):
            for _ in range(25):
                Zc = root + eps * rng.standard_normal(root.shape)
                Y = Zc @ _T(Zc)
                closer += int(np.sum(_fro(Y - A) < best * (1.0 - 1e-12)))
                competitors += len(A)
        for _ in range(25):
            Zc = rng.standard_normal((len(A), n, n)) / np.sqrt(n)
            Y = Zc @ _T(Zc)
            closer += int(np.sum(_fro(Y - A) < best * (1.0 - 1e-12)))
            competitors += len(A)
    worst = max(worst, certificate, float(closer))
    # 3
    A9 = A_tangent.reshape(-1, 9, 9)
    scale = _fro(A9)
    projected = project_tangent(A_tangent).reshape(-1, 9, 9)
    min_eig = np.linalg.eigvalsh(projected)[:, 0]
    negativity = float(np.max(np.maximum(-min_eig, 0.0) / scale))
    was_psd = np.linalg.eigvalsh(0.5 * (A9 + _T(A9)))[:, 0] >= -1e-12 * scale
    kept = float(np.max(_fro(projected - A9)[was_psd] / scale[was_psd], initial=0.0))
    asymmetry = float(np.max(_fro(A9 - _T(A9)) / scale))
    worst = max(worst, negativity, kept)
    summary = (f"PSD inputs unchanged (rel {unchanged:.1e}); indefinite inputs -> PSD with the optimality "
               f"certificate X>=0, X-A>=0, <X,X-A>=0 (rel {certificate:.1e}), {closer} of {competitors} random PSD "
               f"matrices closer; project_tangent(shape_target A) PSD at all {len(A9)} samples "
               f"({int(np.sum(~was_psd))} indefinite before, PSD ones kept to {kept:.1e}; "
               f"A major-symmetric to {asymmetry:.1e})")
    return worst, summary



def _klar_rows(F: np.ndarray, S: np.ndarray, ref: Quantities) -> list[SeedRow]:
    mu = MU_KLAR
    rows = []
    src = f"{KLAR} eq. "
    rows.append(_row("klar-eq1", src + "1", _check({"psi": klar_eq1_energy(F, S, mu)}, ref),
                     "agrees: min over SO(3) (Davenport q-method, no SVD) of mu ||F - R S_t||^2"))
    eq2 = klar_eq2_energy(F, S)
    root = {"psi": np.sqrt(np.maximum(ref["psi"], 0.0) / mu)}
    is_root = _check({"psi": eq2}, root)[0]
    rows.append(_row("klar-eq2", src + "2", _check({"psi": eq2}, ref),
                     f"eq. 2 drops the square and mu: it is sqrt(psi/mu) (to rel {is_root.max_rel_error:.1e})"))
    rows.append(_row("klar-eq2-corrected", src + "2", _check({"psi": klar_eq2_corrected(F, S, mu)}, ref),
                     "Psi = mu ||F - R* S_t||_F^2, R* = U* V*^T from the SVD of F S_t"))
    # the reference P of shape_target is this same envelope-theorem formula (forms/shape_target.py), so also
    # check it independently against central differences of eq. 1, and eqs. 4-6 against differences of eq. 3
    eq3 = klar_eq3_stress(F, S, mu)
    fd_p = compare({"P": eq3}, {"P": _central_differences(lambda G: klar_eq1_energy(G, S, mu), F)}, 1e-5)[0]
    rows.append(_row("klar-eq3", src + "3", _check({"P": eq3}, ref),
                     "agrees: P = 2 mu (F - R* S_t), R* = U* V*^T (a rotation, det F S_t > 0); also equals central "
                     f"differences of eq. 1 (rel {fd_p.max_rel_error:.0e}; the reference P is this same "
                     "envelope-theorem formula, not a UFL derivative)"))
    eq46 = klar_eq4_tangent(F, S, mu)
    fd_a = compare({"A": eq46}, {"A": _central_differences(lambda G: klar_eq3_stress(G, S, mu), F)}, 1e-5)[0]
    rows.append(_row("klar-eq4-6", src + "4-6", _check({"A": eq46}, ref),
                     "agrees, reading E as eps_ijk seen as a 9x3 matrix [(ij),k], E^T its 3x9 transpose, ':' the "
                     "contraction of the shared indices: (E^T:X)_k = eps_ijk X_ij, (E:w)_ij = eps_ijk w_k; also "
                     f"equals central differences of eq. 3 (rel {fd_a.max_rel_error:.0e})"))
    worst, summary = check_psd_projection(ref["A"], SEED)
    rows.append(SeedRow("klar-psd", f"{KLAR} sec. 2 (described; formula in the supplement)", worst <= RTOL, worst,
                        summary))
    return rows


def _klar_inverted_rows(evaluator: ReferenceEvaluator) -> list[SeedRow]:
    """Klar's formulas at the --inverted samples (a quarter of them with det F < 0)."""
    mu = MU_KLAR
    F, labels = deformation_samples(SAMPLES, SEED, inverted=True)
    S = field_samples("shape_target", SAMPLES, SEED)["S"]
    ref = evaluator.evaluate(F, S=S)
    inverted = np.array([label.startswith("inverted") for label in labels])
    # R* (rotation variant) is unique and differentiable only where no two signed singular values of F S_t sum
    # to 0, i.e. sigma_2 + sigma_3 > 0 after the sign flip; samples on that set (psi has a kink) are left out
    _, sigma, _ = klar_svd(F, S, rotation_variant=True)
    gap = (sigma[:, 1] + sigma[:, 2]) / sigma[:, 0]
    smooth = gap > 1e-6
    excluded = int((~smooth).sum())
    where = (f"{excluded} samples on the kink set sigma_2 + sigma_3 = 0 left out" if excluded else
             f"smallest (sigma_2 + sigma_3)/sigma_1 of F S_t {gap[inverted].min():.2g}")

    def sub(q: Quantities) -> Quantities:
        return {k: v[smooth] for k, v in q.items()}

    src = f"{KLAR} eq. "
    n_inv = int(inverted.sum())
    rows = [_row("klar-eq1-inverted", src + "1", _check({"psi": klar_eq1_energy(F, S, mu)}, ref),
                 f"agrees at all {SAMPLES} samples, {n_inv} of them with det F < 0")]
    rows.append(_row("klar-eq3-inverted", src + "3", _check({"P": klar_eq3_stress(F, S, mu)[smooth]}, sub(ref)),
                     "for det F < 0, R* = U* V*^T from the SVD of F S_t (as the text defines it) is a reflection, "
                     "not eq. 1's minimiser over SO(3): P is wrong at every inverted sample"))
    rows.append(_row("klar-eq3-inverted-corrected", src + "3",
                     _check({"P": klar_eq3_stress(F, S, mu, True)[smooth]}, sub(ref)),
                     f"R* = U* diag(1, 1, det(U* V*^T)) V*^T (last column of U* negated) ({n_inv} inverted samples, "
                     f"{where})"))
    rows.append(_row("klar-eq4-6-inverted", src + "4-6",
                     _check({"A": klar_eq4_tangent(F, S, mu)[smooth]}, sub(ref)),
                     "with the plain SVD, eq. 5 differentiates the reflection U* V*^T, not R*, when det F < 0"))
    rows.append(_row("klar-eq4-6-inverted-corrected", src + "4-6",
                     _check({"A": klar_eq4_tangent(F, S, mu, True)[smooth]}, sub(ref)),
                     "eqs. 5-6 with the signed SVD: the last column of U* and sigma_3 negated when det F S_t < 0, "
                     f"K = tr(Sigma*) I - Sigma* with the signed Sigma* ({where})"))
    return rows
