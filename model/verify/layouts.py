"""Tangent and stress layouts: the reference (P, A = dP/dF) as other codes store it, and back.

Pure numpy (no dolfinx). Notation: F (N,3,3) deformation gradients, J = det F, P (N,3,3) the first
Piola-Kirchhoff stress, A (N,3,3,3,3) with A[n,i,j,k,l] = dP_ij/dF_kl (the reference's layout), and

    S     = F^-1 P                 second Piola-Kirchhoff stress (symmetric)
    sigma = (1/J) P F^T            Cauchy stress (symmetric); tau = J sigma = P F^T the Kirchhoff stress
    E     = (F^T F - I)/2          Green-Lagrange strain
    C_IJKL = dS_IJ/dE_KL           material tangent, from P = F S:  A_ijkl = delta_ik S_jl + F_iI F_kK C_IjKl
    c_ijkl = (1/J) F_iI F_jJ F_kK F_lL C_IJKL
           = (1/J) F_jJ F_lL A_iJkL - delta_ik sigma_jl
                                   spatial tangent: the Truesdell rate of the Kirchhoff stress over J,
                                   (1/J) L_v tau = c : d, d the rate of deformation
    C^J_ijkl = c_ijkl + (delta_ik sigma_jl + sigma_ik delta_jl + delta_il sigma_jk + sigma_il delta_jk)/2
                                   the Jaumann-rate tangent of an Abaqus UMAT (the material Jacobian
                                   C^MJ): (1/J) (Jaumann rate of tau) = C^J : d, since
                                   tau^J = tau^T + d tau + tau d (tau^T the Truesdell rate)

Layouts of the tangent (``TANGENT_LAYOUTS``) and the stress each carries by default (``NATURAL_STRESS``):

    ijkl            T[n,i,j,k,l] = A[n,i,j,k,l]                          with P (3x3)
    hessian9-col    H[n, i + 3j, k + 3l] = A[n,i,j,k,l]: vec(F) stacks the columns of F (HOBAK, the
                    book "Dynamic Deformables"); the 9x9 Hessian of psi over vec(F)   with P (3x3)
    hessian9-row    H[n, 3i + j, 3k + l] = A[n,i,j,k,l]: vec(F) stacks the rows     with P (3x3)
    voigt-spatial   D[n,I,K] = c[n,i,j,k,l]                               with sigma (Voigt 6)
    abaqus-ddsdde   D[n,I,K] = C^J[n,i,j,k,l] (DDSDDE of a UMAT)          with sigma (Voigt 6)
    voigt-material  D[n,I,K] = C[n,i,j,k,l] = dS_ij/dE_kl                 with S (Voigt 6)

Voigt convention (all three Voigt layouts): the order is Abaqus' 11, 22, 33, 12, 13, 23 (``VOIGT_ORDER``,
0-based pairs (0,0), (1,1), (2,2), (0,1), (0,2), (1,2)) for rows, columns and the stress; strains
are engineering strains (shear entry gamma_12 = 2 d_12, resp. 2 E_12), so the matrix entries are the
tensor components with no factor: D[I,K] = C[i,j,k,l] for I = (ij), K = (kl); the stress entries are
the tensor components (sigma_11, sigma_22, sigma_33, sigma_12, sigma_13, sigma_23). A 3x3x3x3 array is
brought to Voigt form by averaging its minor-symmetric positions ((ij) and (ji), (kl) and (lk)); no
major symmetrisation: the 6x6 of a hyperelastic law is symmetric by itself (C^J too: its correction
term is symmetric under (ij) <-> (kl)), that of another law is kept as it is (Abaqus' UNSYMM).

Round trips: ijkl and hessian9-* are permutations, exact for any array. The Voigt layouts carry the
minor-symmetric part only: ``to_reference(from_reference(A))`` gives A back (to rounding, amplified by
the condition of F) exactly when A = dP/dF of a law P = F S(E) with S symmetric, which every hyperelastic
law is (its A moreover has the major symmetry A_ijkl = A_klij, i.e. a symmetric 6x6); for an
arbitrary 81-entry array it returns the A of its minor-symmetric projection.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

TANGENT_LAYOUTS = ("ijkl", "hessian9-col", "hessian9-row", "voigt-spatial", "abaqus-ddsdde", "voigt-material")
STRESS_MEASURES = ("P", "S", "sigma")

#: the stress a layout carries unless another measure is asked for
NATURAL_STRESS: dict[str, str] = {"ijkl": "P", "hessian9-col": "P", "hessian9-row": "P",
                                  "voigt-spatial": "sigma", "abaqus-ddsdde": "sigma", "voigt-material": "S"}

#: the shape of one sample's tangent in each layout
TANGENT_SHAPES: dict[str, tuple[int, ...]] = {"ijkl": (3, 3, 3, 3), "hessian9-col": (9, 9), "hessian9-row": (9, 9),
                                              "voigt-spatial": (6, 6), "abaqus-ddsdde": (6, 6),
                                              "voigt-material": (6, 6)}

#: one line per layout, for --help and messages
LAYOUT_DESCRIPTIONS: dict[str, str] = {
    "ijkl": "A[n,i,j,k,l] = dP_ij/dF_kl, with P",
    "hessian9-col": "9x9 H[i+3j, k+3l] = A[i,j,k,l], vec(F) column-major (HOBAK, Dynamic Deformables), with P",
    "hessian9-row": "9x9 H[3i+j, 3k+l] = A[i,j,k,l], vec(F) row-major, with P",
    "voigt-spatial": "6x6 spatial tangent c (Truesdell rate of Kirchhoff stress / J), with Cauchy sigma",
    "abaqus-ddsdde": "6x6 UMAT DDSDDE C^J (Jaumann rate of Kirchhoff stress / J), with Cauchy sigma",
    "voigt-material": "6x6 material tangent dS/dE, with S",
}

#: a few words per layout, for hints
LAYOUT_SHORT: dict[str, str] = {
    "ijkl": "A[i,j,k,l]", "hessian9-col": "vec(F) column-major", "hessian9-row": "vec(F) row-major",
    "voigt-spatial": "c, Truesdell rate, no Jaumann term", "abaqus-ddsdde": "C^J = c + the Jaumann term",
    "voigt-material": "dS/dE",
}

STRESS_DESCRIPTIONS: dict[str, str] = {
    "P": "first Piola-Kirchhoff stress P = dpsi/dF",
    "S": "second Piola-Kirchhoff stress S = F^-1 P",
    "sigma": "Cauchy stress sigma = P F^T / J",
}

#: Abaqus' Voigt order 11, 22, 33, 12, 13, 23 as 0-based index pairs
VOIGT_ORDER: tuple[tuple[int, int], ...] = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
#: the other common order 11, 22, 33, 23, 13, 12 (used only to recognise it in ``hints``)
VOIGT_ORDER_STANDARD: tuple[tuple[int, int], ...] = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))

VOIGT_LAYOUTS = ("voigt-spatial", "abaqus-ddsdde", "voigt-material")

_I3 = np.eye(3)


def _check_layout(layout: str) -> None:
    if layout not in TANGENT_LAYOUTS:
        raise ValueError(f"layout {layout!r} is unknown; known: {', '.join(TANGENT_LAYOUTS)}")


def _check_measure(measure: str) -> None:
    if measure not in STRESS_MEASURES:
        raise ValueError(f"stress measure {measure!r} is unknown; known: {', '.join(STRESS_MEASURES)}")


def _as_F(F: np.ndarray) -> np.ndarray:
    F = np.asarray(F, dtype=np.float64)
    if F.ndim < 2 or F.shape[-2:] != (3, 3):
        raise ValueError(f"F: shape {F.shape}, needs (N, 3, 3)")
    return F.reshape(-1, 3, 3)


# --- Voigt -----------------------------------------------------------------------------------------

def to_voigt(T: np.ndarray, order: tuple[tuple[int, int], ...] = VOIGT_ORDER) -> np.ndarray:
    """(N,3,3) -> (N,6): v[I] = (T_ij + T_ji)/2 for I = (ij) in ``order`` (tensor components)."""
    T = np.asarray(T, dtype=np.float64)
    return np.stack([(T[:, i, j] + T[:, j, i]) / 2 for i, j in order], axis=1)


def from_voigt(v: np.ndarray, order: tuple[tuple[int, int], ...] = VOIGT_ORDER) -> np.ndarray:
    """(N,6) -> (N,3,3) symmetric: T_ij = T_ji = v[I] for I = (ij) in ``order``."""
    v = np.asarray(v, dtype=np.float64)
    T = np.empty((len(v), 3, 3))
    for index, (i, j) in enumerate(order):
        T[:, i, j] = T[:, j, i] = v[:, index]
    return T


def tangent_to_voigt(C: np.ndarray, order: tuple[tuple[int, int], ...] = VOIGT_ORDER) -> np.ndarray:
    """(N,3,3,3,3) -> (N,6,6): D[I,K] = (C_ijkl + C_jikl + C_ijlk + C_jilk)/4, I = (ij), K = (kl) in ``order``
    (engineering shear strains: no factor 2)."""
    C = np.asarray(C, dtype=np.float64)
    Cs = (C + C.transpose(0, 2, 1, 3, 4) + C.transpose(0, 1, 2, 4, 3) + C.transpose(0, 2, 1, 4, 3)) / 4
    D = np.empty((len(C), 6, 6))
    for a, (i, j) in enumerate(order):
        for b, (k, m) in enumerate(order):
            D[:, a, b] = Cs[:, i, j, k, m]
    return D


def tangent_from_voigt(D: np.ndarray, order: tuple[tuple[int, int], ...] = VOIGT_ORDER) -> np.ndarray:
    """(N,6,6) -> (N,3,3,3,3) with the minor symmetries: C_ijkl = C_jikl = C_ijlk = C_jilk = D[I,K]."""
    D = np.asarray(D, dtype=np.float64)
    C = np.empty((len(D), 3, 3, 3, 3))
    for a, (i, j) in enumerate(order):
        for b, (k, m) in enumerate(order):
            for p, q in {(i, j), (j, i)}:
                for r, s in {(k, m), (m, k)}:
                    C[:, p, q, r, s] = D[:, a, b]
    return C


# --- stress measures -------------------------------------------------------------------------------

def _stress_3x3(measure: str, stress: np.ndarray) -> np.ndarray:
    stress = np.asarray(stress, dtype=np.float64)
    if stress.ndim == 2 and stress.shape[1] == 6:
        if measure == "P":
            raise ValueError("stress: P is not symmetric and has no Voigt form; give (N, 3, 3)")
        return from_voigt(stress)
    if stress.ndim == 3 and stress.shape[1:] == (3, 3):
        return stress
    raise ValueError(f"stress: shape {stress.shape}, {measure} needs (N, 3, 3) or Voigt (N, 6)")


def stress_from_P(measure: str, F: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The stress ``measure`` from P (N,3,3): P; S = F^-1 P; sigma = P F^T / J. Returns (N,3,3)."""
    _check_measure(measure)
    F = _as_F(F)
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3, 3)
    if measure == "P":
        return P.copy()
    if measure == "S":
        return np.linalg.solve(F, P)
    return P @ np.transpose(F, (0, 2, 1)) / np.linalg.det(F)[:, None, None]


def P_from_stress(measure: str, F: np.ndarray, stress: np.ndarray) -> np.ndarray:
    """P from the stress ``measure`` given as (N,3,3) or Voigt (N,6): P; P = F S; P = J sigma F^-T."""
    _check_measure(measure)
    F = _as_F(F)
    T = _stress_3x3(measure, stress)
    if measure == "P":
        return T.copy()
    if measure == "S":
        return F @ T
    J = np.linalg.det(F)
    return J[:, None, None] * np.transpose(np.linalg.solve(F, np.transpose(T, (0, 2, 1))), (0, 2, 1))


# --- tangents ---------------------------------------------------------------------------------------

def material_tangent(F: np.ndarray, P: np.ndarray, A: np.ndarray) -> np.ndarray:
    """C_IJKL = dS_IJ/dE_KL = F^-1_Ii F^-1_Kk (A_iJkL - delta_ik S_JL), S = F^-1 P (no symmetrisation)."""
    F = _as_F(F)
    Finv = np.linalg.inv(F)
    S = np.linalg.solve(F, P)
    G = A - np.einsum("ik,njl->nijkl", _I3, S)
    return np.einsum("nIi,nKk,niJkL->nIJKL", Finv, Finv, G)


def spatial_tangent(F: np.ndarray, P: np.ndarray, A: np.ndarray) -> np.ndarray:
    """c_ijkl = (1/J) F_jJ F_lL A_iJkL - delta_ik sigma_jl, sigma = P F^T / J."""
    F = _as_F(F)
    J = np.linalg.det(F)
    sigma = stress_from_P("sigma", F, P)
    a = np.einsum("njJ,nlL,niJkL->nijkl", F, F, A) / J[:, None, None, None, None]
    return a - np.einsum("ik,njl->nijkl", _I3, sigma)


def jaumann_correction(sigma: np.ndarray) -> np.ndarray:
    """(delta_ik sigma_jl + sigma_ik delta_jl + delta_il sigma_jk + sigma_il delta_jk)/2, so that C^J = c + this."""
    return (np.einsum("ik,njl->nijkl", _I3, sigma) + np.einsum("nik,jl->nijkl", sigma, _I3)
            + np.einsum("il,njk->nijkl", _I3, sigma) + np.einsum("nil,jk->nijkl", sigma, _I3)) / 2


def _A_from_material(F: np.ndarray, S: np.ndarray, C: np.ndarray) -> np.ndarray:
    """A_ijkl = delta_ik S_jl + F_iI F_kK C_IjKl."""
    return np.einsum("ik,njl->nijkl", _I3, S) + np.einsum("niI,nkK,nIjKl->nijkl", F, F, C)


def _A_from_spatial(F: np.ndarray, sigma: np.ndarray, c: np.ndarray) -> np.ndarray:
    """A_iJkL = F^-1_Jj F^-1_Ll (J c_ijkl + delta_ik tau_jl), tau = J sigma."""
    J = np.linalg.det(F)
    Finv = np.linalg.inv(F)
    a = J[:, None, None, None, None] * (c + np.einsum("ik,njl->nijkl", _I3, sigma))
    return np.einsum("nJj,nLl,nijkl->niJkL", Finv, Finv, a)


def _check_arrays(F: np.ndarray, P: np.ndarray | None, A: np.ndarray | None) -> None:
    n = len(F)
    if P is not None and np.shape(P) != (n, 3, 3):
        raise ValueError(f"P: shape {np.shape(P)}, needs ({n}, 3, 3)")
    if A is not None and np.shape(A) != (n, 3, 3, 3, 3):
        raise ValueError(f"A: shape {np.shape(A)}, needs ({n}, 3, 3, 3, 3)")


def _reference_inputs(layout: str, measure: str | None, F: np.ndarray, P: np.ndarray,
                      A: np.ndarray) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """(measure, F, P, A) checked and as float64: the layout and measure known (measure defaults to the
    layout's), F (N,3,3), P (N,3,3), A (N,3,3,3,3)."""
    _check_layout(layout)
    measure = measure or NATURAL_STRESS[layout]
    _check_measure(measure)
    F = _as_F(F)
    P = np.asarray(P, dtype=np.float64)
    A = np.asarray(A, dtype=np.float64)
    _check_arrays(F, P, A)
    return measure, F, P, A


def from_reference(layout: str, F: np.ndarray, P: np.ndarray, A: np.ndarray,
                   measure: str | None = None) -> dict[str, np.ndarray]:
    """The reference (P (N,3,3), A (N,3,3,3,3)) in ``layout``: {"stress": ..., "tangent": ...}.

    The stress is ``measure`` (default: the layout's, ``NATURAL_STRESS``): (N,3,3), or Voigt (N,6) for a
    symmetric measure (S, sigma) with a Voigt layout. The tangent has the shape ``(N, *TANGENT_SHAPES[layout])``;
    formulas in the module docstring.
    """
    measure, F, P, A = _reference_inputs(layout, measure, F, P, A)
    stress = stress_from_P(measure, F, P)
    if layout in VOIGT_LAYOUTS and measure != "P":
        stress = to_voigt(stress)
    if layout == "ijkl":
        tangent = A.copy()
    elif layout == "hessian9-col":
        tangent = A.transpose(0, 2, 1, 4, 3).reshape(-1, 9, 9)
    elif layout == "hessian9-row":
        tangent = A.reshape(-1, 9, 9).copy()
    elif layout == "voigt-material":
        tangent = tangent_to_voigt(material_tangent(F, P, A))
    else:
        c = spatial_tangent(F, P, A)
        if layout == "abaqus-ddsdde":
            c = c + jaumann_correction(stress_from_P("sigma", F, P))
        tangent = tangent_to_voigt(c)
    return {"stress": stress, "tangent": tangent}


def conversion_accuracy(layout: str, F: np.ndarray, measure: str | None = None) -> dict[str, np.ndarray]:
    """Per sample, the relative error ``from_reference`` may add to exact (rounded) P and A: {"stress": (N,),
    "tangent": (N,)}, in the per-sample Frobenius norm. A check in ``layout`` should not ask for less.

    ijkl, hessian9-*: 0 (a permutation). voigt-spatial, abaqus-ddsdde: 16 eps (products with F only).
    voigt-material: eps cond(F)^3, from F^-1 (A - delta S) F^-T with S = F^-1 P: the flat directions of a
    nearly flat F hold C scaled by the smallest singular value squared, so their digits are lost in A
    itself (measured: at most 0.05 eps cond(F)^3 for StVK and neo-Hookean with a fibre; 1e-5 at
    cond(F) = 1.2e4). Stress: P, sigma 4 eps; S = F^-1 P: 4 eps cond(F). eps = 2.2e-16.
    """
    _check_layout(layout)
    measure = measure or NATURAL_STRESS[layout]
    _check_measure(measure)
    F = _as_F(F)
    eps = np.finfo(np.float64).eps
    cond = np.linalg.cond(F)
    tangent = {"ijkl": 0.0 * cond, "hessian9-col": 0.0 * cond, "hessian9-row": 0.0 * cond,
               "voigt-spatial": 16 * eps + 0.0 * cond, "abaqus-ddsdde": 16 * eps + 0.0 * cond,
               "voigt-material": eps * cond**3}[layout]
    stress = 4 * eps * cond if measure == "S" else 4 * eps + 0.0 * cond
    return {"stress": stress, "tangent": tangent}


def to_reference(layout: str, F: np.ndarray, stress: np.ndarray | None, tangent: np.ndarray | None,
                 measure: str | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(P, A) from a stress and tangent in ``layout``: the inverse of ``from_reference``.

    ``stress`` is ``measure`` (default: the layout's), (N,3,3) or Voigt (N,6); either argument may be
    None (then so is its result), but the Voigt tangents need the stress to be converted:
    A = delta S + F F C (voigt-material), A_iJkL = F^-1_Jj F^-1_Ll (J c_ijkl + delta_ik tau_jl)
    (voigt-spatial; abaqus-ddsdde after c = C^J - the Jaumann correction). Exact for ijkl and hessian9-*;
    for the Voigt layouts see the module docstring (exact for any law P = F S(E), S symmetric).
    """
    _check_layout(layout)
    measure = measure or NATURAL_STRESS[layout]
    _check_measure(measure)
    F = _as_F(F)
    n = len(F)
    P = None
    if stress is not None:
        stress = np.asarray(stress, dtype=np.float64)
        if len(stress) != n:
            raise ValueError(f"stress: {len(stress)} samples, F has {n}")
        P = P_from_stress(measure, F, stress)
    if tangent is None:
        return P, None
    tangent = np.asarray(tangent, dtype=np.float64)
    shape = TANGENT_SHAPES[layout]
    if tangent.shape != (n, *shape):
        raise ValueError(f"tangent: shape {tangent.shape}, {layout} needs (N, {', '.join(map(str, shape))}) "
                         f"with N = {n}")
    if layout == "ijkl":
        return P, tangent.copy()
    if layout == "hessian9-col":
        return P, tangent.reshape(n, 3, 3, 3, 3).transpose(0, 2, 1, 4, 3).copy()
    if layout == "hessian9-row":
        return P, tangent.reshape(n, 3, 3, 3, 3).copy()
    if P is None:
        raise ValueError(f"tangent: converting a {layout} tangent to A needs the stress too")
    C = tangent_from_voigt(tangent)
    if layout == "voigt-material":
        return P, _A_from_material(F, stress_from_P("S", F, P), C)
    sigma = stress_from_P("sigma", F, P)
    if layout == "abaqus-ddsdde":
        C = C - jaumann_correction(sigma)
    return P, _A_from_spatial(F, sigma, C)


def layouts_help() -> str:
    """The layouts and stress measures, one per line, for ``--help``."""
    lines = [f"  {name:15} {LAYOUT_DESCRIPTIONS[name]}" for name in TANGENT_LAYOUTS]
    lines.append("  Voigt order 11, 22, 33, 12, 13, 23; engineering shear strains (no factor 2 in the tangent)")
    lines += [f"  stress {name:8} {STRESS_DESCRIPTIONS[name]}" for name in STRESS_MEASURES]
    return "\n".join(lines)


# --- hints ------------------------------------------------------------------------------------------

def relative_errors(user: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-sample ||user_n - ref_n|| / max(||ref_n||, 1e-6 max_m ||ref_m||) (Frobenius norms, as ``check``);
    samples where either array is not finite are left out (NaN)."""
    u = np.asarray(user, dtype=np.float64).reshape(len(user), -1)
    r = np.asarray(ref, dtype=np.float64).reshape(len(ref), -1)
    finite = np.all(np.isfinite(u), axis=1) & np.all(np.isfinite(r), axis=1)
    norm = np.linalg.norm(np.where(finite[:, None], r, 0.0), axis=1)
    floor = 1e-6 * max(float(norm.max(initial=0.0)), 1e-300)
    err = np.linalg.norm(np.where(finite[:, None], u - r, 0.0), axis=1) / np.maximum(norm, floor)
    return np.where(finite, err, np.nan)


def _max_error(user: np.ndarray, ref: np.ndarray) -> float:
    rel = relative_errors(user, ref)
    rel = rel[np.isfinite(rel)]
    return float(rel.max()) if len(rel) else np.inf


def _factor(user: np.ndarray, ref: np.ndarray) -> float:
    """The least-squares constant alpha in user ~ alpha ref (finite samples only)."""
    u = np.asarray(user, dtype=np.float64).reshape(len(user), -1)
    r = np.asarray(ref, dtype=np.float64).reshape(len(ref), -1)
    finite = np.all(np.isfinite(u), axis=1) & np.all(np.isfinite(r), axis=1)
    rr = float(np.sum(r[finite] ** 2))
    return float(np.sum(u[finite] * r[finite]) / rr) if rr > 0 else np.nan


def _factor_note(alpha: float) -> str:
    notes = {0.5: " (mu vs mu/2, or a missing factor 2?)", 2.0: " (mu vs mu/2, or a factor 2 too many?)",
             -1.0: " (the opposite sign)", 0.25: " (two factors 1/2?)", 4.0: " (two factors 2?)"}
    for value, note in notes.items():
        if abs(alpha - value) <= 1e-6 * abs(value):
            return note
    return ""


@dataclass(frozen=True)
class _Candidate:
    what: str  # what the user's array would then be: "the reference transposed (P^T)", "hessian9-col (...)"
    advice: str  # what to do about it ("" for none)
    array: np.ndarray


def _first_match(name: str, user: np.ndarray, candidates: list[_Candidate], tol: float) -> list[str]:
    """The first candidate the user's array matches (to tol), else the first it matches up to a constant factor."""
    for c in candidates:
        err = _max_error(user, c.array)
        if err <= tol:
            return [f"{name} matches {c.what} to {err:.1e}" + (f": {c.advice}" if c.advice else "")]
    for c in candidates:
        alpha = _factor(user, c.array)
        if not np.isfinite(alpha) or alpha == 0.0:
            continue
        err = _max_error(user, alpha * c.array)
        if err <= tol:
            return [f"{name} is {alpha:.6g} times {c.what} (to {err:.1e}){_factor_note(alpha)}"
                    + (f"; {c.advice}" if c.advice else "")]
    return []


_STRESS_NAMES = {"P": "P", "S": "S (second Piola-Kirchhoff)", "sigma": "sigma (Cauchy)",
                 "tau": "the Kirchhoff stress tau = J sigma = P F^T"}
_STANDARD_ORDER = "the Voigt order 11, 22, 33, 23, 13, 12"
_REORDER = "reorder to 11, 22, 33, 12, 13, 23"


def _stress_candidates(measure: str, F: np.ndarray, P_ref: np.ndarray, voigt: bool) -> list[_Candidate]:
    J = np.linalg.det(F)
    values = {m: stress_from_P(m, F, P_ref) for m in STRESS_MEASURES}
    values["tau"] = J[:, None, None] * values["sigma"]
    advice = {m: f"pass --stress {m}" for m in STRESS_MEASURES}
    advice["tau"] = "divide by J for sigma"
    if voigt:
        out = [_Candidate("the reference", "", to_voigt(values[measure])),
               _Candidate(f"the reference in {_STANDARD_ORDER}", _REORDER,
                          to_voigt(values[measure], VOIGT_ORDER_STANDARD))]
        out += [_Candidate(_STRESS_NAMES[m], advice[m], to_voigt(values[m]))
                for m in ("S", "sigma", "tau") if m != measure]
        return out
    out = [_Candidate("the reference", "", values[measure])]
    out += [_Candidate(_STRESS_NAMES[m], advice[m], values[m]) for m in ("P", "S", "sigma", "tau") if m != measure]
    out.append(_Candidate(f"the reference transposed ({measure}^T)", "", np.transpose(values[measure], (0, 2, 1))))
    if measure != "P":
        out.append(_Candidate("P transposed (P^T)", "pass --stress P and transpose",
                              np.transpose(values["P"], (0, 2, 1))))
    return out


_PERMUTATIONS = [p for p in itertools.permutations(range(4)) if p != (0, 1, 2, 3)]


def _permuted_A(p: tuple[int, ...]) -> str:
    """How T = A.transpose(0, *p+1) reads: T[i,j,k,l] = A[<this>]."""
    return "A[" + ",".join("ijkl"[p.index(m)] for m in range(4)) + "]"


def _tangent_candidates(layout: str, F: np.ndarray, P_ref: np.ndarray, A_ref: np.ndarray) -> list[_Candidate]:
    shape = TANGENT_SHAPES[layout]
    ref = from_reference(layout, F, P_ref, A_ref)["tangent"]
    out = [_Candidate("the reference", "", ref)]
    out += [_Candidate(f"{other} ({LAYOUT_SHORT[other]})", f"pass --layout {other}",
                       from_reference(other, F, P_ref, A_ref)["tangent"])
            for other in TANGENT_LAYOUTS if other != layout and TANGENT_SHAPES[other] == shape]
    if len(shape) == 2:
        out.append(_Candidate("the reference transposed", "transpose each matrix", np.transpose(ref, (0, 2, 1))))
    if layout not in VOIGT_LAYOUTS:
        return out
    J = np.linalg.det(F)[:, None, None]
    c = spatial_tangent(F, P_ref, A_ref)
    fourth = {"voigt-spatial": c, "abaqus-ddsdde": c + jaumann_correction(stress_from_P("sigma", F, P_ref)),
              "voigt-material": material_tangent(F, P_ref, A_ref)}
    for name in (layout, *[o for o in VOIGT_LAYOUTS if o != layout]):
        advice = "" if name == layout else f"pass --layout {name}, "
        D = tangent_to_voigt(fourth[name])
        out.append(_Candidate(f"{name} in {_STANDARD_ORDER}", advice + _REORDER,
                              tangent_to_voigt(fourth[name], VOIGT_ORDER_STANDARD)))
        tensorial = D.copy()
        tensorial[:, :, 3:] *= 2
        out.append(_Candidate(f"{name} for tensor shear strains (shear columns times 2)",
                              advice + "use engineering shear strains (no factor 2)", tensorial))
        mandel = D.copy()
        mandel[:, :, 3:] *= np.sqrt(2)
        mandel[:, 3:, :] *= np.sqrt(2)
        out.append(_Candidate(f"{name} in Mandel notation (shear rows and columns times sqrt 2)",
                              advice + "divide the shear rows and columns by sqrt 2", mandel))
    for name in ("voigt-spatial", "abaqus-ddsdde"):
        out.append(_Candidate(f"J times {name} (a Kirchhoff-stress tangent, no 1/J)",
                              ("" if name == layout else f"pass --layout {name}, ") + "divide by J",
                              J * tangent_to_voigt(fourth[name])))
    return out


def hints(layout: str, F: np.ndarray, P_ref: np.ndarray, A_ref: np.ndarray, user_stress: np.ndarray | None = None,
          user_tangent: np.ndarray | None = None, measure: str | None = None, tol: float = 1e-6) -> list[str]:
    """One-line hints when a user's stress or tangent (given in ``layout``, the stress in ``measure``, default the
    layout's) differs from the reference P_ref (N,3,3), A_ref (N,3,3,3,3).

    Tried in this order; the first that matches to ``tol`` (max per-sample relative error, ``relative_errors``)
    is reported, else the first that matches up to a constant factor alpha (least squares over the samples):
    stress: another measure (P, S, sigma, the Kirchhoff stress tau = J sigma), the transpose, for a Voigt
    stress the order 11, 22, 33, 23, 13, 12; tangent: the other layouts of the same shape (hessian9-col vs
    -row; the three Voigt layouts), the transposed matrix, for Voigt layouts the order 11, 22, 33, 23, 13, 12,
    tensor shear strains (factor 2), Mandel notation and J times c; for ijkl/hessian9 at last the 23 index
    permutations of A (e.g. "read as T[i,j,k,l] it matches A[i,k,j,l]").
    Returns [] when the arrays match the reference as given, or when none of these explains the difference.
    Samples where the reference or the user's array is not finite are left out.
    """
    measure, F, P_ref, A_ref = _reference_inputs(layout, measure, F, P_ref, A_ref)
    out: list[str] = []
    if user_stress is not None:
        user = np.asarray(user_stress, dtype=np.float64)
        voigt = user.shape[1:] == (6,)
        if user.shape != (len(F), 3, 3) and not (voigt and user.shape[0] == len(F)):
            raise ValueError(f"stress: shape {user.shape}, needs ({len(F)}, 3, 3) or Voigt ({len(F)}, 6)")
        candidates = _stress_candidates(measure, F, P_ref, voigt)
        if _max_error(user, candidates[0].array) > tol:
            out += _first_match("P" if measure == "P" else f"the stress ({measure})", user, candidates, tol)
    if user_tangent is not None:
        user = np.asarray(user_tangent, dtype=np.float64)
        shape = TANGENT_SHAPES[layout]
        if user.shape != (len(F), *shape):
            raise ValueError(f"tangent: shape {user.shape}, {layout} needs (N, {', '.join(map(str, shape))}) "
                             f"with N = {len(F)}")
        candidates = _tangent_candidates(layout, F, P_ref, A_ref)
        if _max_error(user, candidates[0].array) > tol:
            name = f"the tangent ({layout})"
            found = _first_match(name, user, candidates, tol)
            if not found and layout not in VOIGT_LAYOUTS:
                as_ijkl = to_reference(layout, F, None, user)[1]
                found = _first_match(f"{name}, read as T[i,j,k,l],", as_ijkl,
                                     [_Candidate(_permuted_A(p), "", A_ref.transpose(0, *[m + 1 for m in p]))
                                      for p in _PERMUTATIONS], tol)
            out += found
    return out


__all__ = ["LAYOUT_DESCRIPTIONS", "LAYOUT_SHORT", "NATURAL_STRESS", "STRESS_DESCRIPTIONS", "STRESS_MEASURES",
           "TANGENT_LAYOUTS", "TANGENT_SHAPES", "VOIGT_LAYOUTS", "VOIGT_ORDER", "P_from_stress", "conversion_accuracy",
           "from_reference", "from_voigt", "hints", "jaumann_correction", "layouts_help", "material_tangent",
           "relative_errors", "spatial_tangent", "stress_from_P", "tangent_from_voigt", "tangent_to_voigt",
           "to_reference", "to_voigt"]
