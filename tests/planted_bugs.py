"""Planted bugs for ``model.verify.check``: correct numpy formulas of five laws and a catalogue of the mistakes people
make deriving them by hand, each with the diagnosis the report should give (tests/test_verify_planted.py).

A module, not a test file. Laws (``LAWS``): vectorised numpy psi (N,), P (N,3,3) and A (N,3,3,3,3),
A[n,i,j,k,l] = dP_ij/dF_kl, written from the formulas (independent of the UFL reference):

    neo_hookean         (mu/2)(Ic - 3) - mu ln J + (lmbda/2)(ln J)^2                      forms/isotropic.py
    stvk                mu E:E + (lmbda/2)(tr E)^2, E = (F^T F - I)/2                      forms/isotropic.py
    stable_neo_hookean  rest_stable: (mu/2)(Ic - 3) - mu (J - 1) + (ls/2)(J - 1)^2, ls = lmbda + mu;
                        paper: (ms/2)(Ic - 3) + (ls/2)(J - alpha)^2 - (ms/2) ln(Ic + 1), ms = 4 mu / 3,
                        ls = lmbda + 5 mu / 6, alpha = 1 + 3 ms / (4 ls) (with its constant: no shift to
                        psi(I) = 0)                                                        forms/isotropic_more.py
    corotated           mu ||F - R||^2 + (lmbda/2)(J - 1)^2, R the polar rotation of the signed SVD (det F < 0:
                        U's last column and the last singular value negated); arap = corotated, lmbda = 0
    fibre               examples/fibre_neo_hookean_law.py: neo_hookean + k1/(2 k2)(exp(k2 (I4 - 1)^2) - 1),
                        I4 = a0 . C a0 (a law of the user's own, "FILE.py:psi", field a0)

Ic = ||F||^2, J = det F, cof F = J F^-T (computed from F's entries, no inverse), d(cof F)_ij/dF_kl =
e_ikm e_jln F_mn. The corotated tangent is closed form: dR = U [w]x V^T with (tr S I - S) w = 2 axial(skew(U^T dF V)),
S the signed singular values (tests/svd_reference.py, vectorised). Every tangent is exact (no finite differences):
the correct formulas pass at rtol 1e-8.

The catalogue (``BUGS``): each ``Planted`` has a name, the law, a function (F, fields) -> the user's arrays
({"psi", "P", "tangent"}: which quantities are given), the tangent's layout, the quantity the diagnosis is about,
the expected ``Diagnosis.kind`` (None: no specific hint expected) and a substring its text must contain, and
whether it goes through the command line (an .npz of ``verify emit``'s keys, ``python -m model verify check``).
``CORRECT``: the laws' right formulas (and stvk evaluated in float32, at rtol 1e-4 with an atol).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from model.verify.layouts import VOIGT_ORDER, VOIGT_ORDER_STANDARD, from_reference

Arrays = dict[str, np.ndarray]
FIBRE_LAW = Path(__file__).resolve().parents[1] / "examples" / "fibre_neo_hookean_law.py"
EYE = np.eye(3)
#: e_ijk
LEVI = np.zeros((3, 3, 3))
LEVI[0, 1, 2] = LEVI[1, 2, 0] = LEVI[2, 0, 1] = 1.0
LEVI[0, 2, 1] = LEVI[2, 1, 0] = LEVI[1, 0, 2] = -1.0
#: delta_ik delta_jl: dF_ij/dF_kl
IDENTITY4 = np.einsum("ik,jl->ijkl", EYE, EYE)

MU, LMBDA = 3.0, 7.0
#: stable_neo_hookean "paper": mu = 3, lmbda = 6.5 give ms = 4, ls = 9, the constant 9 ms^2 / (32 ls) = 0.5
PAPER_LMBDA = 6.5
K1, K2 = 2.0, 0.1


# --- kinematics ------------------------------------------------------------------------------------------------

def det(F: np.ndarray) -> np.ndarray:
    return np.linalg.det(F)


def cofactor(F: np.ndarray) -> np.ndarray:
    """cof F = J F^-T, from the entries of F (defined at every F)."""
    return 0.5 * np.einsum("imn,jpq,zmp,znq->zij", LEVI, LEVI, F, F, optimize=True)


def d_cofactor(F: np.ndarray) -> np.ndarray:
    """d(cof F)_ij / dF_kl = e_ikm e_jln F_mn."""
    return np.einsum("ikm,jln,zmn->zijkl", LEVI, LEVI, F, optimize=True)


def outer(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """(X x Y)_ijkl = X_ij Y_kl."""
    return np.einsum("nij,nkl->nijkl", X, Y)


def inverse_transpose(F: np.ndarray) -> np.ndarray:
    return np.transpose(np.linalg.inv(F), (0, 2, 1))


def col(x: np.ndarray) -> np.ndarray:
    """(N,) -> (N,1,1), for scaling matrices per sample."""
    return np.asarray(x)[:, None, None]


def col4(x: np.ndarray) -> np.ndarray:
    return np.asarray(x)[:, None, None, None, None]


def quantities(psi: np.ndarray, P: np.ndarray, A: np.ndarray) -> Arrays:
    return {"psi": psi, "P": P, "tangent": A}


# --- the laws ---------------------------------------------------------------------------------------------------

def neo_hookean(F: np.ndarray, mu: float = MU, lmbda: float = LMBDA, J: np.ndarray | None = None) -> Arrays:
    """psi = (mu/2)(Ic - 3) - mu ln J + (lmbda/2)(ln J)^2, P = mu (F - F^-T) + lmbda ln J F^-T,
    A_ijkl = mu d_ik d_jl + (mu - lmbda ln J) Finv_jk Finv_li + lmbda Finv_ji Finv_lk (NaN where det F <= 0).
    ``J``: the J the user computes (default det F)."""
    J = det(F) if J is None else J
    with np.errstate(invalid="ignore", divide="ignore"):
        lnJ = np.log(J)
    FinvT = inverse_transpose(F)
    Finv = np.transpose(FinvT, (0, 2, 1))
    psi = 0.5 * mu * (np.einsum("nij,nij->n", F, F) - 3.0) - mu * lnJ + 0.5 * lmbda * lnJ**2
    P = mu * (F - FinvT) + lmbda * col(lnJ) * FinvT
    A = (mu * IDENTITY4[None] + col4(mu - lmbda * lnJ) * np.einsum("njk,nli->nijkl", Finv, Finv)
         + lmbda * outer(FinvT, FinvT))
    return quantities(psi, P, A)


def stvk(F: np.ndarray, mu: float = MU, lmbda: float = LMBDA) -> Arrays:
    """psi = mu E:E + (lmbda/2)(tr E)^2, S = 2 mu E + lmbda tr E I, P = F S,
    A_ijkl = d_ik S_jl + lmbda F_ij F_kl + mu ((F F^T)_ik d_jl + F_il F_kj)."""
    E = 0.5 * (np.einsum("nki,nkj->nij", F, F) - EYE)
    trE = np.trace(E, axis1=1, axis2=2)
    psi = mu * np.einsum("nij,nij->n", E, E) + 0.5 * lmbda * trE**2
    S = 2.0 * mu * E + lmbda * col(trE) * EYE
    P = F @ S
    FFt = F @ np.transpose(F, (0, 2, 1))
    A = (np.einsum("ik,njl->nijkl", EYE, S) + lmbda * outer(F, F)
         + mu * (np.einsum("nik,jl->nijkl", FFt, EYE) + np.einsum("nil,nkj->nijkl", F, F)))
    return quantities(psi, P, A)


def stable_neo_hookean(F: np.ndarray, ms: float, ls: float, alpha: float = 1.0, log_term: bool = False,
                       constant: float = 0.0, J: np.ndarray | None = None) -> Arrays:
    """(ms/2)(Ic - 3) + (ls/2)(J - alpha)^2 - ms (J - 1) [rest_stable, log_term False] or
    - (ms/2) ln(Ic + 1) [paper, log_term True, alpha from the caller], + ``constant``.

    rest_stable: ms = mu, ls = lmbda + mu, alpha = 1; paper: ms = 4 mu / 3, ls = lmbda + 5 mu / 6, alpha =
    1 + 3 ms / (4 ls) and no -ms (J - 1) term. ``J``: the J the user computes (det F; the cofactor stays F's)."""
    J = det(F) if J is None else J
    cof, dcof = cofactor(F), d_cofactor(F)
    Ic = np.einsum("nij,nij->n", F, F)
    psi = 0.5 * ms * (Ic - 3.0) + 0.5 * ls * (J - alpha) ** 2 + constant
    P = ms * F + ls * col(J - alpha) * cof
    A = ms * IDENTITY4[None] + ls * outer(cof, cof) + ls * col4(J - alpha) * dcof
    if log_term:
        psi = psi - 0.5 * ms * np.log(Ic + 1.0)
        P = P - ms * F / col(Ic + 1.0)
        A = A - ms * IDENTITY4[None] / col4(Ic + 1.0) + 2.0 * ms * outer(F, F) / col4((Ic + 1.0) ** 2)
    else:
        psi = psi - ms * (J - 1.0)
        P = P - ms * cof
        A = A - ms * dcof
    return quantities(psi, P, A)


def snh_rest_stable(F: np.ndarray, mu: float = MU, lmbda: float = LMBDA, **kwargs) -> Arrays:
    return stable_neo_hookean(F, mu, lmbda + mu, **kwargs)


def snh_paper(F: np.ndarray, mu: float = MU, lmbda: float = PAPER_LMBDA, **kwargs) -> Arrays:
    ms, ls = 4.0 * mu / 3.0, lmbda + 5.0 * mu / 6.0
    return stable_neo_hookean(F, ms, ls, alpha=1.0 + 0.75 * ms / ls, log_term=True, **kwargs)


def _cross(w: np.ndarray) -> np.ndarray:
    """[w]x for w (..., 3)."""
    out = np.zeros((*w.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def signed_svd(F: np.ndarray, signed: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """U, s, Vt with U s Vt = F; ``signed``: U's last column and s's last entry negated where det(U Vt) < 0
    (the rotation variant: U Vt is then the polar rotation)."""
    U, s, Vt = np.linalg.svd(F)
    if signed:
        flip = np.linalg.det(U @ Vt) < 0
        U[flip, :, 2] *= -1.0
        s[flip, 2] *= -1.0
    return U, s, Vt


def rotation_derivative(U: np.ndarray, s: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    """dR_ij/dF_kl of R = U Vt: dR = U [w]x Vt, (tr S I - S) w = 2 axial(skew(U^T dF V)), dF = e_k e_l^T."""
    V = np.transpose(Vt, (0, 2, 1))
    X = np.einsum("nka,nlb->nklab", U, V)  # U^T e_k e_l^T V
    axial = 0.5 * np.stack([X[..., 2, 1] - X[..., 1, 2], X[..., 0, 2] - X[..., 2, 0], X[..., 1, 0] - X[..., 0, 1]],
                           axis=-1)
    K = np.sum(s, axis=1)[:, None] - s  # the diagonal of tr(S) I - S
    w = 2.0 * axial / K[:, None, None, :]
    return np.einsum("nia,nklab,nbj->nijkl", U, _cross(w), Vt, optimize=True)


def corotated(F: np.ndarray, mu: float = MU, lmbda: float = LMBDA, signed: bool = True, abs_K: bool = False,
              J: np.ndarray | None = None) -> Arrays:
    """psi = mu ||F - R||^2 + (lmbda/2)(J - 1)^2, P = 2 mu (F - R) + lmbda (J - 1) cof F,
    A = 2 mu (I - dR/dF) + lmbda (cof F x cof F + (J - 1) d cof F). ``signed``: the rotation variant of the SVD;
    ``abs_K``: dR/dF with |s| (the unsigned singular values); ``J``: the J the user computes."""
    U, s, Vt = signed_svd(F, signed)
    R = U @ Vt
    J = det(F) if J is None else J
    cof, dcof = cofactor(F), d_cofactor(F)
    psi = mu * np.sum((F - R) ** 2, axis=(1, 2)) + 0.5 * lmbda * (J - 1.0) ** 2
    P = 2.0 * mu * (F - R) + lmbda * col(J - 1.0) * cof
    dR = rotation_derivative(U, np.abs(s) if abs_K else s, Vt)
    A = 2.0 * mu * (IDENTITY4[None] - dR) + lmbda * (outer(cof, cof) + col4(J - 1.0) * dcof)
    return quantities(psi, P, A)


def fibre(F: np.ndarray, a0: np.ndarray, mu: float = MU, lmbda: float = LMBDA, k1: float = K1, k2: float = K2,
          tension_only: bool = False, exp_cap: float | None = None, fibre_factor: float = 1.0) -> Arrays:
    """neo_hookean + k1/(2 k2)(exp(k2 x^2) - 1), x = I4 - 1, I4 = |F a0|^2: P += 2 f' (F a0) x a0,
    A_ijkl += 4 f'' (F a0)_i a0_j (F a0)_k a0_l + 2 f' d_ik a0_j a0_l, f' = k1 x e, f'' = k1 e (1 + 2 k2 x^2),
    e = exp(k2 x^2). Bugs: ``tension_only`` (no fibre term where I4 < 1), ``exp_cap`` (the exponent capped, an
    overflow guard, its derivative kept), ``fibre_factor`` (times the fibre term)."""
    out = neo_hookean(F, mu, lmbda)
    Fa = np.einsum("nij,nj->ni", F, a0)
    x = np.sum(Fa * Fa, axis=1) - 1.0
    e = np.exp(k2 * x**2 if exp_cap is None else np.minimum(k2 * x**2, exp_cap))
    f0 = k1 / (2.0 * k2) * (e - 1.0)
    f1 = k1 * x * e
    f2 = k1 * e * (1.0 + 2.0 * k2 * x**2)
    on = fibre_factor * ((x > 0) if tension_only else np.ones_like(x))
    Faa = np.einsum("ni,nj->nij", Fa, a0)
    out["psi"] = out["psi"] + on * f0
    out["P"] = out["P"] + col(on * 2.0 * f1) * Faa
    out["tangent"] = out["tangent"] + col4(on) * (col4(4.0 * f2) * outer(Faa, Faa)
                                                  + col4(2.0 * f1) * np.einsum("ik,nj,nl->nijkl", EYE, a0, a0))
    return out


@dataclass(frozen=True)
class Law:
    """A law of the catalogue: its ``check`` name and parameters and the correct numpy formulas."""

    key: str
    spec: str
    params: dict
    formulas: Callable[..., Arrays]  # (F, fields) -> {"psi", "P", "tangent"}


LAWS = {law.key: law for law in (
    Law("neo_hookean", "neo_hookean", {"mu": MU, "lmbda": LMBDA}, lambda F, f: neo_hookean(F)),
    Law("stvk", "stvk", {"mu": MU, "lmbda": LMBDA}, lambda F, f: stvk(F)),
    Law("stable_neo_hookean", "stable_neo_hookean", {"mu": MU, "lmbda": LMBDA}, lambda F, f: snh_rest_stable(F)),
    Law("stable_neo_hookean_paper", "stable_neo_hookean", {"mu": MU, "lmbda": PAPER_LMBDA, "variant": "paper"},
        lambda F, f: snh_paper(F)),
    Law("corotated", "corotated", {"mu": MU, "lmbda": LMBDA}, lambda F, f: corotated(F)),
    Law("arap", "arap", {"mu": MU}, lambda F, f: corotated(F, lmbda=0.0)),
    Law("fibre", f"{FIBRE_LAW}:psi", {"mu": MU, "lmbda": LMBDA, "k1": K1, "k2": K2},
        lambda F, f: fibre(F, f["a0"])),
)}


# --- the catalogue ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Planted:
    """A planted bug (or, in CORRECT, a right formula): ``make(F, fields)`` gives the user's arrays."""

    name: str
    law: str  # a key of LAWS
    make: Callable[[np.ndarray, Arrays], Arrays]
    quantity: str = ""  # what the diagnosis is about: psi, P or A
    kind: str | None = None  # the expected Diagnosis.kind; None: no specific hint expected
    contains: str = ""  # a substring of the diagnosis text
    layout: str = "ijkl"
    cli: bool = False  # through the command line (an .npz and `python -m model verify check FILE`)
    rtol: float = 1e-8
    atol: float | None = None
    det_negative_only: bool = False  # wrong only where det F < 0 (seen once the samples include inverted F)

    @property
    def given(self) -> tuple[str, ...]:
        """The quantities the user gives (psi, P, tangent), computed at one F."""
        return tuple(self.make(np.eye(3)[None] * 1.1, {"a0": np.array([[1.0, 0.0, 0.0]])}))


def only(arrays: Arrays, *keys: str) -> Arrays:
    return {k: arrays[k] for k in keys}


def replace(arrays: Arrays, **changes: np.ndarray) -> Arrays:
    return {**arrays, **changes}


def in_layout(layout: str, F: np.ndarray, arrays: Arrays) -> np.ndarray:
    """The tangent of ``arrays`` written in ``layout`` (model.verify.layouts.from_reference)."""
    return from_reference(layout, F, arrays["P"], arrays["tangent"])["tangent"]


def voigt_reordered(D: np.ndarray) -> np.ndarray:
    """A 6x6 of VOIGT_ORDER (11, 22, 33, 12, 13, 23) rewritten in 11, 22, 33, 23, 13, 12."""
    perm = [VOIGT_ORDER.index(pair) for pair in VOIGT_ORDER_STANDARD]
    return D[:, perm][:, :, perm]


def float32(formulas: Callable[[np.ndarray], Arrays]) -> Callable[[np.ndarray, Arrays], Arrays]:
    """The formulas evaluated in float32 (F rounded to float32, every operation in float32), returned as float64."""
    def make(F: np.ndarray, fields: Arrays) -> Arrays:
        out = formulas(F.astype(np.float32))
        return {k: np.asarray(v, dtype=np.float32).astype(np.float64) for k, v in out.items()}
    return make


def _stvk32(F: np.ndarray) -> Arrays:
    """stvk with every intermediate in float32 (numpy keeps float32 when both operands are)."""
    one = np.float32
    eye = np.eye(3, dtype=np.float32)
    mu, lmbda = one(MU), one(LMBDA)
    E = one(0.5) * (np.einsum("nki,nkj->nij", F, F) - eye)
    trE = np.trace(E, axis1=1, axis2=2)
    psi = mu * np.einsum("nij,nij->n", E, E) + one(0.5) * lmbda * trE**2
    S = one(2.0) * mu * E + lmbda * trE[:, None, None] * eye
    FFt = F @ np.transpose(F, (0, 2, 1))
    A = (np.einsum("ik,njl->nijkl", eye, S) + lmbda * np.einsum("nij,nkl->nijkl", F, F)
         + mu * (np.einsum("nik,jl->nijkl", FFt, eye) + np.einsum("nil,nkj->nijkl", F, F)))
    return quantities(psi, F @ S, A)


def _nh_P_mu_sign(F: np.ndarray, f: Arrays) -> Arrays:
    """P = mu (F + F^-T) + lmbda ln J F^-T: yours - reference = 2 mu F^-T."""
    FinvT = inverse_transpose(F)
    return {"P": MU * (F + FinvT) + LMBDA * col(np.log(det(F))) * FinvT}


def _nh_A_mu_sign(F: np.ndarray, f: Arrays) -> Arrays:
    """(-mu - lmbda ln J) Finv_jk Finv_li: yours - reference = -2 mu Finv_jk Finv_li."""
    Finv = np.linalg.inv(F)
    return {"tangent": neo_hookean(F)["tangent"] - 2.0 * MU * np.einsum("njk,nli->nijkl", Finv, Finv)}


def _nh_ln_detC(F: np.ndarray, f: Arrays) -> Arrays:
    """-mu ln(det C) for -mu ln J (J = det C, not sqrt(det C), in the mu term): yours - reference = -mu ln J
    (psi), -mu F^-T (P)."""
    ref = neo_hookean(F)
    return {"psi": ref["psi"] - MU * np.log(det(F)), "P": ref["P"] - MU * inverse_transpose(F)}


def _nh_J_minus_1(F: np.ndarray, f: Arrays) -> Arrays:
    """ln J replaced by J - 1: (mu/2)(Ic - 3) - mu (J - 1) + (lmbda/2)(J - 1)^2 and its own P, A (right at J = 1,
    the difference grows under compression and large stretch)."""
    return stable_neo_hookean(F, MU, LMBDA)


def _stvk_A_missing_lmbda(F: np.ndarray, f: Arrays) -> Arrays:
    return {"tangent": stvk(F)["tangent"] - LMBDA * outer(F, F)}


def _stvk_P_is_S(F: np.ndarray, f: Arrays) -> Arrays:
    """The second Piola-Kirchhoff stress S = F^-1 P given as P."""
    return {"P": np.linalg.solve(F, stvk(F)["P"])}


def _cr_P_mu(F: np.ndarray, f: Arrays) -> Arrays:
    """mu (F - R) for 2 mu (F - R): yours - reference = -mu (F - R)."""
    U, _, Vt = signed_svd(F)
    return {"P": corotated(F)["P"] - MU * (F - U @ Vt)}


def _cr_A_rotation_shortcut(F: np.ndarray, f: Arrays) -> Arrays:
    """At a pure rotation (F^T F = I) the tangent of linear elasticity, mu (d_ik d_jl + d_il d_jk) + lmbda d_ij d_kl,
    unrotated: right at the identity, wrong at every other rotation."""
    A = corotated(F)["tangent"].copy()
    rest = np.all(np.abs(np.einsum("nki,nkj->nij", F, F) - EYE) < 1e-10, axis=(1, 2))
    linear = MU * (IDENTITY4 + np.einsum("il,jk->ijkl", EYE, EYE)) + LMBDA * np.einsum("ij,kl->ijkl", EYE, EYE)
    A[rest] = linear
    return {"tangent": A}


def _cli_nh_transposed(F: np.ndarray, f: Arrays) -> Arrays:
    ref = neo_hookean(F)
    return {"psi": ref["psi"], "P": np.transpose(ref["P"], (0, 2, 1))}


BUGS: list[Planted] = [
    # neo_hookean (mu = 3, lmbda = 7)
    Planted("nh_A_missing_lmbda_FinvT_x_FinvT", "neo_hookean",
            lambda F, f: {"tangent": neo_hookean(F)["tangent"]
                          - LMBDA * outer(inverse_transpose(F), inverse_transpose(F))}, "A", "term", "-lmbda"),
    Planted("nh_P_mu_FinvT_sign", "neo_hookean", _nh_P_mu_sign, "P", "term", "F^-T"),
    Planted("nh_A_mu_term_sign", "neo_hookean", _nh_A_mu_sign, "A", "term", "mu"),
    Planted("nh_A_missing_mu_identity", "neo_hookean",
            lambda F, f: {"tangent": neo_hookean(F)["tangent"] - MU * IDENTITY4}, "A", "term", "-mu"),
    Planted("nh_psi_offset", "neo_hookean",
            lambda F, f: replace(only(neo_hookean(F), "psi", "P"), psi=neo_hookean(F)["psi"] + 1.5),
            "psi", "offset", "1.5"),
    Planted("nh_all_times_2", "neo_hookean", lambda F, f: {k: 2.0 * v for k, v in neo_hookean(F).items()},
            "psi", "factor", "2"),
    Planted("nh_P_lmbda_times_1.1", "neo_hookean", lambda F, f: only(neo_hookean(F, lmbda=1.1 * LMBDA), "P"),
            "P", "term", "0.7"),
    Planted("nh_P_transposed", "neo_hookean",
            lambda F, f: {"P": np.transpose(neo_hookean(F)["P"], (0, 2, 1))}, "P", "transpose", "transpose"),
    Planted("nh_A_hessian9_row_as_col", "neo_hookean",
            lambda F, f: {"tangent": in_layout("hessian9-row", F, neo_hookean(F))}, "A", "layout", "hessian9-row",
            layout="hessian9-col"),
    Planted("nh_A_hessian9_col_as_row", "neo_hookean",
            lambda F, f: {"tangent": in_layout("hessian9-col", F, neo_hookean(F))}, "A", "layout", "hessian9-col",
            layout="hessian9-row"),
    Planted("nh_A_spatial_as_ddsdde", "neo_hookean",
            lambda F, f: {"tangent": in_layout("voigt-spatial", F, neo_hookean(F))}, "A", "layout", "voigt-spatial",
            layout="abaqus-ddsdde"),
    Planted("nh_A_indices_ikjl", "neo_hookean",
            lambda F, f: {"tangent": np.transpose(neo_hookean(F)["tangent"], (0, 1, 3, 2, 4))}, "A", "layout",
            "A[i,k,j,l]"),
    Planted("nh_psi_zero", "neo_hookean", lambda F, f: replace(only(neo_hookean(F), "psi", "P"),
                                                               psi=np.zeros(len(F))), "psi", "zero", "zero"),
    Planted("nh_ln_detC_in_mu_term", "neo_hookean", _nh_ln_detC, "P", "term", "-mu"),
    Planted("nh_lnJ_as_J_minus_1", "neo_hookean", _nh_J_minus_1, "psi"),
    Planted("nh_J_clamped_1e-2", "neo_hookean", lambda F, f: neo_hookean(F, J=np.maximum(det(F), 1e-2)), "A", "region",
            "nearly flat"),
    # stvk (mu = 3, lmbda = 7)
    Planted("stvk_E_without_half", "stvk", lambda F, f: {k: 4.0 * v for k, v in stvk(F).items()}, "psi", "factor",
            "4"),
    Planted("stvk_A_missing_lmbda_F_x_F", "stvk", _stvk_A_missing_lmbda, "A", "term", "-lmbda"),
    Planted("stvk_A_voigt_order_23_13_12", "stvk",
            lambda F, f: {"tangent": voigt_reordered(in_layout("voigt-spatial", F, stvk(F)))}, "A", "layout", "Voigt",
            layout="voigt-spatial"),
    Planted("stvk_P_is_S", "stvk", _stvk_P_is_S, "P"),
    Planted("stvk_float32_at_rtol_1e-8", "stvk", float32(_stvk32), "A"),
    # stable_neo_hookean rest_stable (mu = 3, lmbda = 7: ls = 10)
    Planted("snh_alpha_form_offset", "stable_neo_hookean",
            lambda F, f: snh_rest_stable(F, constant=0.5 * MU**2 / (LMBDA + MU)), "psi", "offset", "0.45"),
    Planted("snh_J_as_sqrt_det_C", "stable_neo_hookean",
            lambda F, f: snh_rest_stable(F, J=np.abs(det(F))), "P", "region", "det F < 0", det_negative_only=True),
    Planted("snh_ls_without_mu", "stable_neo_hookean",
            lambda F, f: stable_neo_hookean(F, MU, LMBDA), "psi"),
    # stable_neo_hookean paper (mu = 3, lmbda = 6.5: ms = 4, ls = 9, constant 0.5)
    Planted("snh_paper_without_constant", "stable_neo_hookean_paper",
            lambda F, f: only(snh_paper(F, constant=-0.5), "psi", "P"), "psi", "offset", "-0.5"),
    # corotated (mu = 3, lmbda = 7)
    Planted("cr_svd_unsigned", "corotated", lambda F, f: corotated(F, signed=False), "P", "region",
            "det F < 0", det_negative_only=True),
    Planted("cr_abs_det", "corotated", lambda F, f: only(corotated(F, J=np.abs(det(F))), "psi", "P"), "P", "region",
            "det F < 0", det_negative_only=True),
    Planted("cr_dR_with_abs_sigma", "corotated", lambda F, f: only(corotated(F, abs_K=True), "tangent"), "A",
            "region", "det F < 0", det_negative_only=True),
    Planted("cr_P_mu_for_2mu", "corotated", _cr_P_mu, "P", "term", "-mu"),
    Planted("cr_A_rotation_shortcut", "corotated", _cr_A_rotation_shortcut, "A", "region", "rest"),
    # arap (mu = 3): mu/2 ||F - R||^2, the other convention
    Planted("arap_mu_half", "arap", lambda F, f: {k: 0.5 * v for k, v in corotated(F, lmbda=0.0).items()}, "psi",
            "factor", "0.5"),
    # fibre law of the user's own (examples/fibre_neo_hookean_law.py)
    Planted("fibre_F_column_major", "fibre", lambda F, f: fibre(np.transpose(F, (0, 2, 1)), f["a0"]), "P",
            "column_major", "F^T"),
    Planted("fibre_term_missing", "fibre", lambda F, f: only(neo_hookean(F), "psi", "P"), "P", "term", "fibre"),
    Planted("fibre_k1_over_k2", "fibre", lambda F, f: only(fibre(F, f["a0"], fibre_factor=2.0), "P", "tangent"),
            "P", "term", "fibre"),
    # another sample's fibre direction: wrong wherever |F a0| differs between the two directions (no region, no
    # recognisable term: the report gives yours beside the reference and the worst samples, no hint)
    Planted("fibre_wrong_direction", "fibre", lambda F, f: fibre(F, np.roll(f["a0"], -1, axis=0)), "P"),
    Planted("fibre_tension_only", "fibre", lambda F, f: fibre(F, f["a0"], tension_only=True), "P", "region",
            "compress"),
    Planted("fibre_exp_capped", "fibre", lambda F, f: fibre(F, f["a0"], exp_cap=0.2), "P", "region",
            "large stretch"),
    # through the command line
    Planted("cli_nh_P_transposed", "neo_hookean", _cli_nh_transposed, "P", "transpose", "transpose", cli=True),
    Planted("cli_arap_mu_half", "arap", lambda F, f: {k: 0.5 * v for k, v in corotated(F, lmbda=0.0).items()},
            "psi", "factor", "0.5", cli=True),
    Planted("cli_cr_svd_unsigned", "corotated", lambda F, f: corotated(F, signed=False), "P", "region",
            "det F < 0", cli=True, det_negative_only=True),
    Planted("cli_nh_A_hessian9_row_as_col", "neo_hookean",
            lambda F, f: {"tangent": in_layout("hessian9-row", F, neo_hookean(F))}, "A", "layout", "hessian9-row",
            layout="hessian9-col", cli=True),
]

#: right formulas: each must pass with no diagnosis. stvk in float32: at rtol 1e-4 with atol 1e-4 (an absolute error
#: allowed per sample, |yours - ref| <= atol + rtol |ref| as numpy's allclose: at the rotations P_ref ~ 1e-15 while
#: float32's P is ~1e-6, the largest absolute errors are ~2e-5 in psi, P and A)
CORRECT: list[Planted] = [
    *[Planted(key, key, lambda F, f, law=law: law.formulas(F, f)) for key, law in LAWS.items()],
    Planted("stvk_float32", "stvk", float32(_stvk32), rtol=1e-4, atol=1e-4),
]
