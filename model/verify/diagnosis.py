"""What is wrong, not only that something is: the diagnosis of a failing quantity, and the coverage
of the samples a check compared.

Tolerance (model.verify.checker): sample n of a quantity agrees when

    |yours_n - ref_n| <= tol_n = rtol max(|ref_n|, M) + atol,

|.| the Frobenius norm, M the law's modulus (``modulus``: the largest |A_ijkl| at F = I, lambda + 2 mu
for an isotropic law), so that every sample is measured against its own reference and a nearly flat
sample (|A| ~ 1e9 M) cannot hide the others; score_n = |yours_n - ref_n| / tol_n (> 1: out of tolerance).

For a failing quantity (``diagnose``):

- details: yours beside the reference at the identity and at the worst sample, at the component of
  the largest difference ((i, j) of a stress, (i, j, k, l) of an ijkl tangent, the matrix entry of the
  other layouts), with that sample's J, principal stretches and fibre stretch |F a0|;
- hints, each printed only when it explains the difference to the tolerance at every compared sample
  (the corrected values agree, score <= 1):
  ``zero`` (yours is 0), ``offset`` (psi: yours = ref + c), ``factor`` (yours = c ref),
  ``transpose`` (P: yours_n = ref_n^T), ``layout`` (another tangent layout, measure, Voigt order or index
  permutation matches: model.verify.layouts.hints), ``column_major`` (yours are the reference at F^T: F
  read column-major), ``term`` (yours - ref = c T for one recognisable term T of the
  hyperelastic laws' formulas (``terms``), c named as a multiple of a law parameter when it is one,
  or for one addend psi_k of the law's own energy in UFL, with its P_k and A_k), ``parameter`` (yours
  match the law with one parameter p changed to s p: ``parameter_hint``, over every failing quantity
  without a cause), and, when none of those explains it, ``region`` (every failing sample lies in one region, the
  narrowest of: det F < 0, a nearly flat element, the rest state (identity, rotations), compression
  J < 1, extension J > 1, a large stretch, a compressed or stretched fibre, holding at most 60 % of the
  compared samples; every sample outside it agrees, and at least 3 in it fail).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from forms.polar import polar_rotation_svd

#: principal stretches outside [1/LARGE, LARGE] count as a large stretch
LARGE = 1.5
#: a smallest principal stretch below this is a nearly flat element
FLAT = 0.05
#: a region hint only when the region holds at most this fraction of the compared samples, and at least
#: REGION_FAILING_MIN of its samples fail (one or two bad samples are no region)
REGION_SHARE = 0.6
REGION_FAILING_MIN = 3


@dataclass(frozen=True)
class Diagnosis:
    """One hint: the quantity (psi, P, PK2, sigma, A), its kind (module docstring) and the text printed."""

    quantity: str
    kind: str
    text: str


# --- kinematics per sample ---------------------------------------------------------------------------

def sample_features(F: np.ndarray, a0: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per sample: J = det F, the principal stretches (singular values, ascending), the fibre stretch
    |F a0| (NaN without a fibre field)."""
    F = np.asarray(F, dtype=np.float64).reshape(-1, 3, 3)
    J = np.linalg.det(F)
    stretches = np.sort(np.linalg.svd(F, compute_uv=False), axis=1)
    if a0 is None:
        fibre = np.full(len(F), np.nan)
    else:
        d = np.broadcast_to(np.asarray(a0, dtype=np.float64), (len(F), 3))
        fibre = np.linalg.norm(np.einsum("nij,nj->ni", F, d), axis=1)
    rest = np.linalg.norm(np.transpose(F, (0, 2, 1)) @ F - np.eye(3), axis=(1, 2)) < 1e-10
    identity = np.linalg.norm(F - np.eye(3), axis=(1, 2)) < 1e-12
    return {"J": J, "stretches": stretches, "fibre": fibre, "rest": rest, "identity": identity}


def _regions(features: dict[str, np.ndarray]) -> list[tuple[str, np.ndarray, str]]:
    """(name, (N,) bool, what it suggests), narrowest meaning first in ties."""
    J, s, fibre = features["J"], features["stretches"], features["fibre"]
    large = ((s[:, 2] > LARGE) | (s[:, 0] < 1 / LARGE)) & (s[:, 0] >= FLAT)
    out = [
        ("det F < 0", J < 0, "an SVD not sign-corrected, abs(det F), ln|J|, or |sigma| where the signed "
                             "singular value belongs"),
        ("a nearly flat element (smallest stretch < 0.05)", s[:, 0] < FLAT,
         "round-off in F^-1 or 1/J, or a clamp or regularisation of small J"),
        ("the rest state (identity and rotations)", features["rest"],
         "a term that should vanish at rest, or a rotation handled apart (R != I)"),
        ("compression (J < 1)", J < 1, "a volumetric term (ln J vs J - 1, J^-2/3) that differs away from J = 1"),
        ("extension (J > 1)", J > 1, "a volumetric term that differs away from J = 1"),
        (f"a large stretch (a principal stretch outside [{1 / LARGE:.2g}, {LARGE:g}])", large,
         "a higher-order term (e.g. a small-strain formula) that only shows at large strain"),
    ]
    if np.any(np.isfinite(fibre)):
        out += [("a compressed fibre (|F a0| < 1)", fibre < 1, "the fibre law's branch for lambda < 1"),
                ("a stretched fibre (|F a0| > 1)", fibre > 1, "the fibre law's branch for lambda > 1")]
    return out


# --- recognisable terms --------------------------------------------------------------------------------

def _kinematic_arrays(F: np.ndarray) -> dict[str, np.ndarray]:
    with np.errstate(all="ignore"):
        J = np.linalg.det(F)
        Finv = np.linalg.inv(F)
        FinvT = np.transpose(Finv, (0, 2, 1))
        C = np.transpose(F, (0, 2, 1)) @ F
        B = F @ np.transpose(F, (0, 2, 1))
        lnJ = np.where(J > 0, np.log(np.abs(J)), np.nan)
        I1 = np.trace(C, axis1=1, axis2=2)
        E = 0.5 * (C - np.eye(3))
        trE = np.trace(E, axis1=1, axis2=2)
        R = polar_rotation_svd(F)
        Jm23 = np.where(J > 0, np.abs(J) ** (-2.0 / 3.0), np.nan)
    return {"J": J, "Finv": Finv, "FinvT": FinvT, "C": C, "B": B, "lnJ": lnJ, "I1": I1, "E": E, "trE": trE,
            "R": R, "Jm23": Jm23}


def _s(x: np.ndarray) -> np.ndarray:
    return x[:, None, None]


def _t(x: np.ndarray) -> np.ndarray:
    return x[:, None, None, None, None]


def terms(quantity: str, F: np.ndarray) -> list[tuple[str, Callable[[], np.ndarray]]]:
    """The recognisable terms of ``quantity`` ("psi", "P" or "A", ijkl) at F (N,3,3): (name, values on
    call), the pieces the hyperelastic laws' formulas are made of (neo-Hookean, St Venant-Kirchhoff,
    corotated, Mooney-Rivlin, the volumetric penalties). Computed one at a time: an ijkl term of 1e5
    samples is 65 MB."""
    k = _kinematic_arrays(F)
    J, lnJ, I1, trE = k["J"], k["lnJ"], k["I1"], k["trE"]
    eye = np.eye(3)
    if quantity == "psi":
        FR = F - k["R"]
        return [("ln J", lambda: lnJ), ("(ln J)^2", lambda: lnJ**2), ("J - 1", lambda: J - 1),
                ("(J - 1)^2", lambda: (J - 1) ** 2), ("I1 - 3 = tr C - 3", lambda: I1 - 3),
                ("(tr E)^2", lambda: trE**2), ("tr(E^2)", lambda: np.einsum("nij,nij->n", k["E"], k["E"])),
                ("|F - R|^2", lambda: np.einsum("nij,nij->n", FR, FR)), ("J^-2/3 I1 - 3", lambda: k["Jm23"] * I1 - 3)]
    if quantity == "P":
        FinvT = k["FinvT"]
        return [("F", lambda: F), ("F^-T", lambda: FinvT), ("ln J F^-T", lambda: _s(lnJ) * FinvT),
                ("J F^-T", lambda: _s(J) * FinvT), ("(J - 1) J F^-T", lambda: _s((J - 1) * J) * FinvT),
                ("J^2 F^-T", lambda: _s(J**2) * FinvT), ("F C", lambda: F @ k["C"]), ("I1 F", lambda: _s(I1) * F),
                ("tr(E) F", lambda: _s(trE) * F), ("F E", lambda: F @ k["E"]), ("R", lambda: k["R"]),
                ("F - R", lambda: F - k["R"]), ("J^-2/3 F", lambda: _s(k["Jm23"]) * F),
                ("J^-2/3 I1 F^-T", lambda: _s(k["Jm23"] * I1) * FinvT)]
    if quantity != "A":
        raise ValueError(f"terms: {quantity!r} is not psi, P or A")
    Finv, FinvT, C, B = k["Finv"], k["FinvT"], k["C"], k["B"]

    def II() -> np.ndarray:
        return np.broadcast_to(np.einsum("ik,jl->ijkl", eye, eye), (len(F), 3, 3, 3, 3))

    def TT() -> np.ndarray:
        return np.einsum("nij,nkl->nijkl", FinvT, FinvT)

    def dT() -> np.ndarray:  # d(F^-T)_ij / dF_kl
        return -np.einsum("nli,njk->nijkl", Finv, Finv)

    return [("delta_ik delta_jl (dF/dF)", II), ("F^-T x F^-T", TT), ("d(F^-T)/dF = -F^-1_li F^-1_jk", dT),
            ("ln J d(F^-T)/dF", lambda: _t(lnJ) * dT()), ("J F^-T x F^-T", lambda: _t(J) * TT()),
            ("J^2 F^-T x F^-T", lambda: _t(J**2) * TT()), ("(J - 1) J d(F^-T)/dF", lambda: _t((J - 1) * J) * dT()),
            ("F x F", lambda: np.einsum("nij,nkl->nijkl", F, F)),
            ("F_il F_kj", lambda: np.einsum("nil,nkj->nijkl", F, F)),
            ("delta_ik C_jl", lambda: np.einsum("ik,njl->nijkl", eye, C)),
            ("B_ik delta_jl", lambda: np.einsum("nik,jl->nijkl", B, eye)),
            ("tr(E) delta_ik delta_jl", lambda: _t(trE) * II()),
            ("delta_ik E_jl", lambda: np.einsum("ik,njl->nijkl", eye, k["E"]))]


# --- naming numbers ------------------------------------------------------------------------------------

def _simple_ratio(x: float) -> bool:
    """x is a short decimal (at most two significant digits) within 1e-6 relative, between 0.01 and 100."""
    if not (0.01 <= abs(x) <= 100):
        return False
    digits = -int(np.floor(np.log10(abs(x)))) + 1
    return abs(round(x, digits) - x) <= 1e-6 * abs(x)


def name_coefficient(c: float, params: dict[str, float]) -> str | None:
    """"-lmbda", "0.1 lmbda", "2 mu" when c is a simple multiple of a law parameter (the simplest ratio first),
    else None."""
    best: tuple[int, str] | None = None
    for name, value in params.items():
        if not value or not np.isfinite(value):
            continue
        ratio = c / value
        if not _simple_ratio(ratio):
            continue
        text = {1.0: name, -1.0: f"-{name}"}.get(round(ratio, 12), f"{ratio:.2g} {name}")
        rank = len(f"{abs(ratio):.2g}")
        if best is None or rank < best[0]:
            best = (rank, text)
    return best[1] if best else None


def _number(x: float) -> str:
    return f"{x:.6g}"


# --- the diagnosis -----------------------------------------------------------------------------------------

@dataclass
class Quantity:
    """One quantity as compared: yours and the reference (N, ...) in your layout, the samples compared,
    the tolerance per sample, and how to bring a term in P / A form into your layout."""

    name: str
    user: np.ndarray
    ref: np.ndarray
    keep: np.ndarray
    tol: np.ndarray
    #: (term values in P (n,3,3) or ijkl A form, the samples' indices or None for all) -> the same in the user's
    #: layout / measure; None: psi
    convert: Callable[[np.ndarray, np.ndarray | None], np.ndarray] | None = None
    #: the samples these arrays are of (None: all, else indices into the check's samples)
    index: np.ndarray | None = None

    def subset(self, index: np.ndarray) -> Quantity:
        """The same quantity at the samples ``index`` (of all of the check's samples)."""
        return Quantity(self.name, self.user[index], self.ref[index], self.keep[index], self.tol[index],
                        convert=self.convert, index=index, family=self.family)

    def to_layout(self, T: np.ndarray) -> np.ndarray:
        return self.convert(T, self.index) if self.convert is not None else T
    #: ("P" | "A" | "psi"): which TERMS a difference is regressed on
    family: str = "psi"


def scores(user: np.ndarray, ref: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """|yours_n - ref_n| / tol_n per sample (Frobenius norm over the sample's entries)."""
    n = len(ref)
    diff = np.asarray(user, dtype=np.float64).reshape(n, -1) - np.asarray(ref, dtype=np.float64).reshape(n, -1)
    with np.errstate(all="ignore"):
        out = np.linalg.norm(diff, axis=1) / tol
    return np.where(np.isfinite(out), out, np.inf)


def _explains(q: Quantity, candidate: np.ndarray, slack: float = 1.0) -> bool:
    """The candidate (N, ...) agrees with yours at every compared sample within slack x the tolerance."""
    k = q.keep
    if not k.any() or not np.all(np.isfinite(np.reshape(candidate[k], (int(k.sum()), -1)))):
        return False
    return bool(np.all(scores(q.user[k], candidate[k], q.tol[k]) <= slack))


def _fit(q: Quantity, T: np.ndarray) -> float | None:
    """The c minimising sum_n |d_n - c T_n|^2 / tol_n^2 over the compared samples (d = yours - ref)."""
    k = q.keep
    n = int(k.sum())
    d = (q.user[k] - q.ref[k]).reshape(n, -1)
    t = np.asarray(T[k], dtype=np.float64).reshape(n, -1)
    if not np.all(np.isfinite(t)):
        return None
    w = 1.0 / q.tol[k] ** 2
    tt = float(np.sum(w * np.einsum("ni,ni->n", t, t)))
    if tt == 0 or not np.isfinite(tt):
        return None
    return float(np.sum(w * np.einsum("ni,ni->n", d, t))) / tt


def zero_hint(q: Quantity) -> Diagnosis | None:
    k = q.keep
    if k.any() and np.all(scores(q.user[k], np.zeros_like(q.user[k]), q.tol[k]) <= 1.0):
        return Diagnosis(q.name, "zero", f"{q.name}: yours is zero at every compared sample (the reference is not): "
                                         "not written, or not read")
    return None


def factor_hint(q: Quantity) -> Diagnosis | None:
    """yours = c ref, c fitted."""
    c = _fit(Quantity(q.name, q.user, np.zeros_like(q.ref), q.keep, q.tol), q.ref)
    if c is None or abs(c - 1) < 1e-12 or abs(c) < 1e-6 or not _explains(q, c * q.ref):
        return None
    return Diagnosis(q.name, "factor", f"{q.name}: yours = c x reference with c = {_number(c)} at every sample: a "
                                       "constant factor (a modulus off by a factor, e.g. mu vs mu/2, or a missing "
                                       "1/2 or 2)")


def offset_hint(q: Quantity) -> Diagnosis | None:
    """psi: yours = ref + c (c the tolerance-weighted mean difference)."""
    if q.name != "psi":
        return None
    c = _fit(q, np.ones_like(q.ref))
    if c is None or not _explains(q, q.ref + c):
        return None
    return Diagnosis("psi", "offset", f"psi: yours = reference + c with c = {_number(c)} at every sample: a constant "
                                      "offset (P and A do not see it; the reference has psi = 0 at the identity)")


def transpose_hint(q: Quantity) -> Diagnosis | None:
    if q.name != "P" or not _explains(q, np.transpose(q.ref, (0, 2, 1))):
        return None
    return Diagnosis("P", "transpose", "P: yours is the transpose of the reference (yours[i,j] = P[j,i]); "
                                       "P_ij = dpsi/dF_ij with F_ij = dx_i/dX_j")


def column_major_hint(q: Quantity, at_transpose: np.ndarray | None) -> Diagnosis | None:
    """Yours are the reference computed at F^T (written as it is, or transposed back)."""
    if at_transpose is None:
        return None
    variants = [at_transpose]
    if q.name == "P":
        variants.append(np.transpose(at_transpose, (0, 2, 1)))
    if q.family == "A" and at_transpose.ndim == 5:
        variants.append(np.transpose(at_transpose, (0, 2, 1, 4, 3)))
    if any(_explains(q, v) for v in variants):
        return Diagnosis(q.name, "column_major", f"{q.name}: yours equal the reference at F^T: your code reads F "
                                                 "column-major (F[i, j] must be dx_i/dX_j, row i, column j)")
    return None


def term_hint(q: Quantity, F: np.ndarray, params: dict[str, float],
              only: str | None = None) -> tuple[str, Diagnosis] | None:
    """yours - ref = c T for one of ``terms(q.family, F)`` (converted into the user's layout): (T's name, the
    hint); F are the quantity's samples; ``only``: that term alone."""
    for term, values in terms(q.family, F):
        if only is not None and term != only:
            continue
        T = q.to_layout(values())
        c = _fit(q, T)
        if c is None or abs(c) == 0 or not _explains(q, q.ref + c * T):
            continue
        named = name_coefficient(c, params)
        coefficient = f" (c = {named})" if named else ""
        name = f"({term})" if " - " in term or " + " in term else term
        if c < 0:
            meaning = (f"a term {_number(-c)} {name} of the reference is missing from yours (or yours has it with "
                       "a smaller coefficient)")
        else:
            meaning = f"yours has an extra {_number(c)} {name} (or the reference's term has a larger coefficient)"
        return term, Diagnosis(q.name, "term", f"{q.name}: yours - reference = {_number(c)} {name} at every "
                                               f"compared sample{coefficient}: {meaning}")
    return None


def region_hint(q: Quantity, features: dict[str, np.ndarray]) -> Diagnosis | None:
    """Every failing sample in one region (the narrowest that holds them), every other sample agrees."""
    k = q.keep
    s = scores(q.user, q.ref, q.tol)
    failing = k & (s > 1)
    compared = int(k.sum())
    if not failing.any():
        return None
    found: tuple[int, str, str, int] | None = None
    for name, region, suggestion in _regions(features):
        region = region & k
        size = int(region.sum())
        bad = int(np.sum(failing & region))
        if np.any(failing & ~region) or size > REGION_SHARE * compared or size == compared or bad < REGION_FAILING_MIN:
            continue
        if found is None or size < found[0]:
            found = (size, name, suggestion, int(np.sum(failing & region)))
    if found is None:
        return None
    size, name, suggestion, bad = found
    return Diagnosis(q.name, "region", f"{q.name}: wrong only at {name}: {bad} of the {size} compared samples there "
                                       f"fail, all {compared - size} others agree; look for {suggestion}")


def law_term_hint(q: Quantity, law_terms: list[tuple[str, np.ndarray]],
                  only: str | None = None) -> tuple[str, Diagnosis] | None:
    """yours - ref = c psi_k (or its P, A) for one addend psi_k of the law's own energy (UFL), in your layout:
    (its description, the hint); ``only``: that term alone."""
    for description, T in law_terms:
        if only is not None and description != only:
            continue
        c = _fit(q, T)
        if c is None or abs(c) < 1e-9 or not _explains(q, q.ref + c * T):
            continue
        if abs(c + 1) <= 1e-6:
            meaning = f"the reference's {description} is missing from yours"
        elif abs(c - 1) <= 1e-6:
            meaning = f"yours has the {description} twice"
        else:
            meaning = f"yours has the {description} times {_number(1 + c)}"
        return description, Diagnosis(q.name, "term", f"{q.name}: yours - reference = {_number(c)} x ({description}) "
                                                      f"at every compared sample: {meaning}")
    return None


#: at most this many samples (evenly spaced) are searched for a cause; the cause found is then confirmed on
#: every sample (the layout search excepted: model.verify.layouts.hints runs on these samples only)
SCREEN = 1024


def diagnose(q: Quantity, F: np.ndarray, params: dict[str, float], features: dict[str, np.ndarray],
             at_transpose: np.ndarray | None = None,
             layout_hints: Callable[[np.ndarray | None], list[str]] | None = None,
             law_terms: Callable[[np.ndarray | None], list[tuple[str, np.ndarray]]] | None = None
             ) -> list[Diagnosis]:
    """The hints for a failing quantity (module docstring): the first cause that explains the difference;
    else the region it is confined to; else nothing. Causes are searched on at most SCREEN samples and
    confirmed on all."""
    n = len(q.ref)
    index = None if n <= SCREEN else np.unique(np.linspace(0, n - 1, SCREEN).astype(int))
    sub = q if index is None else q.subset(index)
    F_sub = F if index is None else F[index]
    T_sub = None if at_transpose is None else (at_transpose if index is None else at_transpose[index])

    def confirmed(found: Diagnosis | None, again: Callable[[], Diagnosis | None]) -> Diagnosis | None:
        return found if found is None or index is None else again()

    checks: list[tuple[Callable[[Quantity], Diagnosis | None], Callable[[], Diagnosis | None]]] = [
        (zero_hint, lambda: zero_hint(q)), (offset_hint, lambda: offset_hint(q)),
        (factor_hint, lambda: factor_hint(q)), (transpose_hint, lambda: transpose_hint(q))]
    for screen, again in checks:
        hint = confirmed(screen(sub), again)
        if hint is not None:
            return [hint]
    if layout_hints is not None:  # before F^T: for an isotropic law a tangent at F^T is a permuted layout
        found = layout_hints(index)
        if found:
            return [Diagnosis(q.name, "layout", text) for text in found]
    hint = confirmed(column_major_hint(sub, T_sub), lambda: column_major_hint(q, at_transpose))
    if hint is not None:
        return [hint]
    with np.errstate(all="ignore"):
        found_term = term_hint(sub, F_sub, params)
        if found_term is not None and index is not None:
            found_term = term_hint(q, F, params, only=found_term[0])
        if found_term is None and law_terms is not None:
            found_term = law_term_hint(sub, law_terms(index))
            if found_term is not None and index is not None:
                found_term = law_term_hint(q, law_terms(None), only=found_term[0])
    if found_term is not None:
        return [found_term[1]]
    hint = region_hint(q, features)
    return [hint] if hint is not None else []


def parameter_hint(quantities: list[Quantity], params: dict[str, float],
                   reference_at: Callable[[dict[str, float], np.ndarray], dict[str, np.ndarray]], law: str,
                   iterations: int = 12, fit_samples: int = 256) -> Diagnosis | None:
    """Yours match the law with one parameter p changed to p s: for each parameter, s from Gauss-Newton on
    sum over the quantities and samples of |yours_n - ref_n(p s)|^2 / tol_n^2 (derivative by a difference in
    s, the reference recomputed with p as a runtime value: no compile per value), fitted on at most
    ``fit_samples`` of the compared samples (evenly spaced); the hint when the fitted reference agrees with
    every given quantity at every compared sample. ``reference_at(values, index)``: the reference in the
    user's layout at the samples ``index``."""
    if not quantities:
        return None
    compared = np.flatnonzero(np.logical_or.reduce([q.keep for q in quantities]))
    subset = compared[np.unique(np.linspace(0, len(compared) - 1, min(fit_samples, len(compared))).astype(int))]

    def residual(values: dict[str, float], index: np.ndarray) -> np.ndarray | None:
        with np.errstate(all="ignore"):
            ref = reference_at(values, index)
        parts = []
        for q in quantities:
            k = q.keep[index]
            u, t = q.user[index][k], q.tol[index][k]
            d = (u - ref[q.name][k]).reshape(int(k.sum()), -1) / t[:, None]
            parts.append(d.reshape(-1))
        out = np.concatenate(parts)
        return out if np.all(np.isfinite(out)) else None

    for name, p in params.items():
        if not p or not np.isfinite(p):
            continue
        s = 1.0
        r = residual({name: p}, subset)
        if r is None:
            continue
        for _ in range(iterations):
            h = 1e-6 * max(abs(s), 1e-3)
            r_h = residual({name: p * (s + h)}, subset)
            if r_h is None:
                break
            g = (r_h - r) / h
            gg = float(g @ g)
            if gg == 0:
                break
            step = -float(g @ r) / gg
            r_new = residual({name: p * (s + step)}, subset)
            if r_new is None:
                break
            s, r = s + step, r_new
            if abs(step) <= 1e-12 * max(abs(s), 1.0):
                break
        if abs(s - 1) < 1e-9 or not np.all(np.abs(r) <= 1.0):
            continue
        with np.errstate(all="ignore"):  # the fit confirmed on every compared sample
            fitted = reference_at({name: p * s}, compared)
        if not all(np.all(scores(q.user[compared][q.keep[compared]], ref_q, q.tol[compared][q.keep[compared]]) <= 1.0)
                   for q, ref_q in _at(quantities, fitted, compared)):
            continue
        names = ", ".join(q.name for q in quantities)
        return Diagnosis(quantities[0].name, "parameter",
                         f"{names}: yours match {law} with {name} x {s:.6g} ({name} = {_number(p * s)} instead of "
                         f"{_number(p)}) at every compared sample: a parameter off by a factor, or another "
                         "convention for it (lmbda of plane stress, K for lmbda, E and nu converted otherwise)")
    return None


def _at(quantities: list[Quantity], ref: dict[str, np.ndarray], index: np.ndarray) -> list[tuple[Quantity, np.ndarray]]:
    return [(q, ref[q.name][q.keep[index]]) for q in quantities]


# --- what the report shows of a failing quantity --------------------------------------------------------

def _index(flat: int, shape: tuple[int, ...]) -> str:
    return "[" + ", ".join(str(int(i)) for i in np.unravel_index(flat, shape)) + "]" if shape else ""


def describe_sample(n: int, label: str, features: dict[str, np.ndarray]) -> str:
    """"#12 large_stretch (J 2.31, stretches 0.42, 1.3, 3.1, fibre stretch 1.21)"."""
    s = features["stretches"][n]
    text = f"#{n}{' ' + label if label else ''} (J {features['J'][n]:.4g}, stretches {s[0]:.3g}, {s[1]:.3g}, {s[2]:.3g}"
    if np.isfinite(features["fibre"][n]):
        text += f", fibre stretch {features['fibre'][n]:.4g}"
    return text + ")"


def detail(q: Quantity, n: int, label: str, features: dict[str, np.ndarray], where: str) -> str:
    """Yours beside the reference at sample n, at the entry of the largest difference."""
    u = np.asarray(q.user[n], dtype=np.float64)
    r = np.asarray(q.ref[n], dtype=np.float64)
    diff = np.abs(u - r).reshape(-1)
    diff[~np.isfinite(diff)] = np.inf
    flat = int(np.argmax(diff)) if diff.size else 0
    entry = _index(flat, u.shape)
    yours, reference = u.reshape(-1)[flat], r.reshape(-1)[flat]
    head = f"{q.name}{entry} at {where} {describe_sample(n, '' if where == 'the identity' else label, features)}"
    if np.linalg.norm(u - r) <= q.tol[n]:
        return f"{q.name} at {where} {describe_sample(n, '' if where == 'the identity' else label, features)}: agrees"
    if u.shape:
        return (f"{head}: yours {yours:.8g}, reference {reference:.8g} (the largest difference; "
                f"|yours - reference| {np.linalg.norm(u - r):.4g}, |reference| {np.linalg.norm(r):.4g})")
    return f"{head}: yours {yours:.8g}, reference {reference:.8g}"


# --- coverage -------------------------------------------------------------------------------------------------

def coverage(F: np.ndarray, labels: list[str] | None, features: dict[str, np.ndarray], compared: np.ndarray,
             fibre_law: bool) -> list[str]:
    """Two lines: what was compared (kinds, J range, stretches, fibre stretches) and what was never compared."""
    k = np.asarray(compared, dtype=bool)
    n = len(F)
    J, s, fibre = features["J"][k], features["stretches"][k], features["fibre"][k]
    if labels is not None:
        counts: dict[str, int] = {}
        for label, used in zip(labels, k):
            if used:
                counts[label] = counts.get(label, 0) + 1
        kinds = ", ".join(f"{name} {count}" for name, count in counts.items())
    else:
        kinds = f"{int(np.sum(features['rest'][k]))} at rest (identity, rotations)"
    line = f"coverage: {int(k.sum())} of {n} samples compared ({kinds})"
    if k.any():
        line += (f"; J from {J.min():.3g} to {J.max():.3g}; principal stretches from {s[:, 0].min():.3g} to "
                 f"{s[:, 2].max():.3g}")
        if np.any(np.isfinite(fibre)):
            line += f"; fibre stretch from {np.nanmin(fibre):.3g} to {np.nanmax(fibre):.3g}"
    rotation = features["rest"][k] & ~features["identity"][k]
    checks = [("the identity", features["identity"][k]), ("a rotation", rotation),
              ("det F < 0", J < 0), ("compression (J < 1)", (J > 0) & (J < 1)), ("extension (J > 1)", J > 1),
              (f"a stretch > {LARGE:g}", s[:, 2] > LARGE) if len(s) else ("", np.zeros(0, bool)),
              ("a nearly flat element (stretch < 0.05)", s[:, 0] < FLAT) if len(s) else ("", np.zeros(0, bool))]
    if fibre_law:
        checks += [("a compressed fibre", fibre < 1), ("a stretched fibre", fibre > 1)]
    never = [name for name, mask in checks if name and not np.any(mask)]
    return [line, "never compared: " + (", ".join(never) if never else "nothing of the list (identity, rotation, "
                                        "det F < 0, compression, extension, large stretch, nearly flat"
                                        + (", fibre compression and extension" if fibre_law else "") + ")")]
