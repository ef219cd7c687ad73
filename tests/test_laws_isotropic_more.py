"""The isotropic laws of issue 11 (forms/isotropic_more.py): stable_neo_hookean (both variants), yeoh, and the
aliases fixed_corotated and arap.

- psi, P and A from the UFL path (model.verify) against independent numpy implementations written
  here from the papers' formulas: psi directly (numpy operations that accept a complex F), P by complex step
  of psi (h = 1e-30: exact to rounding), A by fourth-order central differences of the complex-step P (step
  1e-3 times the smallest singular value). Tolerances: psi 1e-12 relative (to the sum of the magnitudes of
  its terms plus mu tr C, the scale of its rounding: at rest Ic - 3 vanishes), P 1e-9, A 1e-6 (finite
  differences), relative to the shear modulus where the quantity vanishes (P at rest). Samples: identity,
  rotations, repeated singular values, large stretches in [0.3, 3], nearly flat (J ~ 1e-3) and, for
  stable_neo_hookean only (defined there), inverted F (including -I and singular values (1.5, 0.8, -0.8)).
- stable_neo_hookean: P(I) = 0 for both variants, psi(I) = 0 (rest_stable) and 9 ms^2/(32 ls) - ms ln 2
  (paper); the tangent at I is linear elasticity's with the Lame constants given (yeoh: 2 c1, kappa).
- The mixed energy W + p g - p^2/(2 kappa) at p = kappa g equals psi; kappa = inf (lmbda = inf) works
  and gives psi's limit at J = 1.
- Aliases: exactly corotated's values (1e-14), under their own names in errors; arap equals HOBAK's
  mu ||F - U V^T||^2 (SVD of F).
- A uniaxial run (tests/conftest.py example("uniaxial")) with the law swapped converges to the homogeneous
  closed form (principal stretches solved with the numpy energies here), the aliases under their own names in
  the configuration too.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import ufl
from conftest import EXAMPLES, example, run_raw
from dolfinx import fem
from mpi4py import MPI
from scipy.optimize import fsolve
from scipy.spatial.transform import Rotation

import forms
from model import compat
from model.verify import reference

inf = math.inf


# --- independent numpy energies (complex F allowed) ---------------------------------------------------------

def det3(F: np.ndarray) -> np.ndarray:
    """det F of (N,3,3) by the rule of Sarrus (complex-safe)."""
    return (F[:, 0, 0] * (F[:, 1, 1] * F[:, 2, 2] - F[:, 1, 2] * F[:, 2, 1])
            - F[:, 0, 1] * (F[:, 1, 0] * F[:, 2, 2] - F[:, 1, 2] * F[:, 2, 0])
            + F[:, 0, 2] * (F[:, 1, 0] * F[:, 2, 1] - F[:, 1, 1] * F[:, 2, 0]))


def lame(params: dict[str, Any]) -> tuple[float, float]:
    if "E" in params:
        E, nu = params["E"], params["nu"]
        return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    return params["mu"], params["lmbda"]


def snh_terms(F: np.ndarray, params: dict[str, Any]) -> list[np.ndarray]:
    """Smith et al. 2018 eq. 14 (paper) or Kim & Eberle 2022's rest-stable form, term by term."""
    mu, lmbda = lame(params)
    Ic = np.einsum("nij,nij->n", F, F)  # no conjugate: complex step
    J = det3(F)
    if params.get("variant", "rest_stable") == "rest_stable":
        ms, ls = mu, lmbda + mu
        return [0.5 * ms * (Ic - 3.0), -ms * (J - 1.0), 0.5 * ls * (J - 1.0) ** 2]
    ms, ls = 4.0 * mu / 3.0, lmbda + 5.0 * mu / 6.0
    alpha = 1.0 + 3.0 * ms / (4.0 * ls)
    return [0.5 * ms * (Ic - 3.0), 0.5 * ls * (J - alpha) ** 2, -0.5 * ms * np.log(Ic + 1.0)]


def yeoh_terms(F: np.ndarray, params: dict[str, Any]) -> list[np.ndarray]:
    """sum_i c_i (Ibar1 - 3)^i + (kappa/2)(ln J)^2, Ibar1 = J^(-2/3) tr C (FEBio's Yeoh with U = (k/2) ln^2 J)."""
    J = det3(F)
    x = J ** (-2.0 / 3.0) * np.einsum("nij,nij->n", F, F) - 3.0
    c = [params["c1"], params.get("c2", 0.0), params.get("c3", 0.0)]
    return [c[0] * x, c[1] * x**2, c[2] * x**3, 0.5 * params["kappa"] * np.log(J) ** 2]


def corotated_diagonal_terms(F: np.ndarray, params: dict[str, Any]) -> list[np.ndarray]:
    """mu sum_i (F_ii - 1)^2 + (lmbda/2)(J - 1)^2: corotated's psi = mu ||F - R||^2 + (lmbda/2)(J - 1)^2 at a
    diagonal F with positive entries (R = I; a complex step off the diagonal leaves R = I to first order, so
    the P of these terms is exact there). arap: lmbda = 0."""
    mu, lmbda = lame(params) if "E" in params or "lmbda" in params else (params["mu"], 0.0)
    return [mu * sum((F[:, i, i] - 1.0) ** 2 for i in range(3)), 0.5 * lmbda * (det3(F) - 1.0) ** 2]


TERMS: dict[str, Callable[[np.ndarray, dict[str, Any]], list[np.ndarray]]] = {
    "stable_neo_hookean": snh_terms, "yeoh": yeoh_terms, "fixed_corotated": corotated_diagonal_terms,
    "arap": corotated_diagonal_terms}


def numpy_psi(law: str, F: np.ndarray, params: dict[str, Any]) -> np.ndarray:
    return sum(TERMS[law](F, params))


def numpy_P(law: str, F: np.ndarray, params: dict[str, Any], h: float = 1e-30) -> np.ndarray:
    """P[n,i,j] = Im psi(F + i h e_ij) / h."""
    P = np.empty(F.shape)
    for i in range(3):
        for j in range(3):
            Fc = F.astype(complex)
            Fc[:, i, j] += 1j * h
            P[:, i, j] = np.imag(numpy_psi(law, Fc, params)) / h
    return P


def numpy_A(law: str, F: np.ndarray, params: dict[str, Any]) -> np.ndarray:
    """A[n,i,j,k,l] by fourth-order central differences of the complex-step P, step 1e-3 sigma_min(F)."""
    d = 1e-3 * np.linalg.svd(F, compute_uv=False)[:, -1]
    A = np.empty((len(F), 3, 3, 3, 3))
    for k in range(3):
        for l in range(3):
            def P_at(s: float, k: int = k, l: int = l) -> np.ndarray:
                G = F.copy()
                G[:, k, l] += s * d
                return numpy_P(law, G, params)
            A[:, :, :, k, l] = (-P_at(2) + 8 * P_at(1) - 8 * P_at(-1) + P_at(-2)) / (12 * d[:, None, None])
    return A


# --- samples --------------------------------------------------------------------------------------------------

def rotations(n: int, seed: int) -> np.ndarray:
    return Rotation.random(n, random_state=seed).as_matrix()


def from_singular_values(sigma: list[list[float]], seed: int) -> np.ndarray:
    s = np.asarray(sigma, dtype=float)
    return rotations(len(s), seed) @ (s[:, :, None] * np.eye(3)) @ rotations(len(s), seed + 1)


def hard_samples(inverted: bool) -> tuple[np.ndarray, list[str]]:
    """identity, rotations, repeated singular values, large stretches, nearly flat (J ~ 1e-3) [, inverted]."""
    rng = np.random.default_rng(11)
    groups = [("identity", np.eye(3)[None]),
              ("rotation", rotations(2, 1)),
              ("uniaxial", from_singular_values([[1.7, 0.8, 0.8], [0.6, 1.3, 1.3]], 3)),
              ("isotropic", 1.4 * rotations(1, 5)),
              ("large_stretch", from_singular_values([[3.0, 0.3, 1.0], [0.3, 0.35, 2.9],
                                                      *rng.uniform(0.3, 3.0, (2, 3))], 7)),
              ("nearly_flat", from_singular_values([[1.2, 0.9, 1e-3], [1.0, 1.0, 1.5e-3]], 9)),
              ("random", np.eye(3) + 0.3 * rng.standard_normal((2, 3, 3)))]
    F = np.concatenate([g for _, g in groups])
    labels = [name for name, g in groups for _ in g]
    F[np.linalg.det(F) < 0] *= -1.0  # the random ones: det > 0
    if inverted:
        flip = np.diag([1.0, 1.0, -1.0])
        extra = np.concatenate([F[[1, 3, 5, 7, 10]] @ flip, -np.eye(3)[None],
                                from_singular_values([[1.5, 0.8, -0.8]], 13)])
        F = np.concatenate([F, extra])
        labels += ["inverted"] * len(extra)
    return F, labels


CASES = [
    ("stable_neo_hookean", {"mu": 3.0, "lmbda": 7.0}),
    ("stable_neo_hookean", {"mu": 3.0, "lmbda": 7.0, "variant": "paper"}),
    ("stable_neo_hookean", {"E": 1.0e4, "nu": 0.45, "variant": "paper"}),
    ("stable_neo_hookean", {"mu": 2.0, "lmbda": -1.0}),  # lmbda > -2 mu / 3: ls = 1 > 0
    ("yeoh", {"c1": 2.0, "c2": -0.1, "c3": 0.02, "kappa": 50.0}),
    ("yeoh", {"c1": 500.0, "kappa": 1.0e4}),
]


def shear_modulus(law: str, params: dict[str, Any]) -> float:
    return 2.0 * params["c1"] if law == "yeoh" else lame(params)[0]


@pytest.mark.parametrize("law,params", CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_psi_P_A_against_complex_step(law: str, params: dict[str, Any]) -> None:
    F, labels = hard_samples(inverted=law == "stable_neo_hookean")
    ref = reference(law, params, F)
    terms = TERMS[law](F, params)
    mu = shear_modulus(law, params)
    # the scale of psi's rounding: its terms' magnitudes, and mu tr C (whose difference Ic - 3 vanishes at rest)
    psi, scale = sum(terms), sum(np.abs(t) for t in terms) + mu * np.einsum("nij,nij->n", F, F)
    psi_err = np.abs(ref["psi"] - psi) / np.maximum(np.abs(psi), scale)
    P = numpy_P(law, F, params)
    P_err = np.linalg.norm(ref["P"] - P, axis=(1, 2)) / np.maximum(np.linalg.norm(P, axis=(1, 2)), mu)
    A = numpy_A(law, F, params)
    A_norm = np.linalg.norm(A.reshape(len(F), -1), axis=1)
    A_err = np.linalg.norm((ref["A"] - A).reshape(len(F), -1), axis=1) / np.maximum(A_norm, mu)
    worst = {q: (f"{e.max():.1e}", labels[int(np.argmax(e))]) for q, e in (("psi", psi_err), ("P", P_err),
                                                                           ("A", A_err))}
    print(f"{law} {params}: max relative error (worst sample) {worst}")
    assert psi_err.max() < 1e-12 and P_err.max() < 1e-9 and A_err.max() < 1e-6, worst


@pytest.mark.parametrize("variant", ["rest_stable", "paper"])
def test_snh_rest_state_and_linearisation(variant: str) -> None:
    """P(I) = 0 for both variants; psi(I) = 0 (rest_stable) or 9 ms^2/(32 ls) - ms ln 2 (paper, where
    (ls/2)(1 - alpha)^2 = 9 ms^2/(32 ls)); A(I) = lmbda I x I + mu (I (x) I + I (x)- I) of linear elasticity
    with the (mu, lmbda) given, here as (E, nu) too."""
    I3 = np.eye(3)
    elastic = {}
    for params in ({"mu": 3.0, "lmbda": 11.0}, {"E": 1.0e4, "nu": 0.3}):
        mu, lmbda = lame(params)
        ref = reference("stable_neo_hookean", {**params, "variant": variant}, I3[None])
        ms, ls = (mu, lmbda + mu) if variant == "rest_stable" else (4 * mu / 3, lmbda + 5 * mu / 6)
        psi_rest = 0.0 if variant == "rest_stable" else 9 * ms**2 / (32 * ls) - ms * math.log(2.0)
        assert abs(ref["psi"][0] - psi_rest) <= 1e-14 * mu
        assert np.abs(ref["P"][0]).max() <= 1e-14 * mu
        C = (lmbda * np.einsum("ij,kl->ijkl", I3, I3)
             + mu * (np.einsum("ik,jl->ijkl", I3, I3) + np.einsum("il,jk->ijkl", I3, I3)))
        np.testing.assert_allclose(ref["A"][0], C, rtol=0, atol=1e-12 * np.abs(C).max())
        elastic[tuple(params)] = ref["A"][0]


def test_yeoh_linearisation() -> None:
    """A(I) is linear elasticity's with mu = 2 c1 and the bulk modulus kappa (lmbda = kappa - 2 mu / 3)."""
    c1, kappa = 7.0, 90.0
    ref = reference("yeoh", {"c1": c1, "c2": -3.0, "c3": 1.0, "kappa": kappa}, np.eye(3)[None])
    mu, lmbda, I3 = 2 * c1, kappa - 4 * c1 / 3, np.eye(3)
    C = (lmbda * np.einsum("ij,kl->ijkl", I3, I3)
         + mu * (np.einsum("ik,jl->ijkl", I3, I3) + np.einsum("il,jk->ijkl", I3, I3)))
    assert abs(ref["psi"][0]) <= 1e-14 * c1 and np.abs(ref["P"][0]).max() <= 1e-14 * c1
    np.testing.assert_allclose(ref["A"][0], C, rtol=0, atol=1e-12 * np.abs(C).max())


# --- the mixed formulation --------------------------------------------------------------------------------------

class Expressions:
    """UFL expressions of F (and nothing else) at N deformation gradients: one disjoint tetrahedron each, DG0 F."""

    def __init__(self, n: int) -> None:
        tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        self.mesh = compat.create_mesh(MPI.COMM_SELF, np.arange(4 * n, dtype=np.int64).reshape(n, 4),
                                       np.tile(tet, (n, 1)))
        self.order = np.asarray(self.mesh.topology.original_cell_index, dtype=np.int64)
        self.n = n
        self.F = fem.Function(compat.function_space(self.mesh, "DG", 0, (3, 3)))

    def __call__(self, expression: ufl.core.expr.Expr, F: np.ndarray) -> np.ndarray:
        self.F.x.array[:] = np.asarray(F).reshape(self.n, 9)[self.order].reshape(-1)
        inverse = np.empty_like(self.order)
        inverse[self.order] = np.arange(self.n)
        compiled = fem.Expression(expression, compat.quadrature_points(self.mesh, 1))
        return compat.evaluate(compiled, self.mesh, np.arange(self.n, dtype=np.int32)).reshape(self.n)[inverse]


@pytest.mark.parametrize("law,params", CASES[:2] + CASES[4:5], ids=["snh-rest_stable", "snh-paper", "yeoh"])
def test_mixed_energy_at_p_equal_kappa_g_is_psi(law: str, params: dict[str, Any]) -> None:
    F, _ = hard_samples(inverted=law == "stable_neo_hookean")
    material = forms.make_law(law, **params)
    evaluate = Expressions(len(F))
    p = material.bulk_penalty * material.volume_constraint(evaluate.F)
    mixed = evaluate(material.mixed_energy(evaluate.F, p), F)
    terms = TERMS[law](F, params)
    scale = sum(np.abs(t) for t in terms) + shear_modulus(law, params) * np.einsum("nij,nij->n", F, F)
    assert np.all(np.abs(mixed - sum(terms)) <= 1e-12 * scale), np.abs(mixed - sum(terms)).max()


@pytest.mark.parametrize("law,params,limit", [
    ("stable_neo_hookean", {"mu": 3.0, "lmbda": inf}, lambda Ic: 1.5 * (Ic - 3)),
    ("stable_neo_hookean", {"mu": 3.0, "lmbda": inf, "variant": "paper"},
     lambda Ic: 2.0 * (Ic - 3) - 2.0 * np.log(Ic + 1)),
    ("yeoh", {"c1": 2.0, "c2": -0.1, "c3": 0.02, "kappa": inf},
     lambda Ic: 2.0 * (Ic - 3) - 0.1 * (Ic - 3) ** 2 + 0.02 * (Ic - 3) ** 3),
], ids=["snh-rest_stable", "snh-paper", "yeoh"])
def test_incompressible_limit(law: str, params: dict[str, Any], limit: Callable[[np.ndarray], np.ndarray]) -> None:
    """Bulk parameter = inf: psi is refused, the mixed energy is W + p g, and at J = 1 (g = 0) it is psi's
    limit: (ms/2)(Ic - 3) [- (ms/2) ln(Ic + 1)] (ms = mu or 4 mu / 3), sum_i c_i (I1 - 3)^i for yeoh."""
    material = forms.make_law(law, **params)
    assert material.incompressible and math.isinf(material.bulk_penalty)
    with pytest.raises(ValueError, match=f"^{law}: .* = inf \\(incompressible\\)"):
        material.energy(ufl.Identity(3))
    F = from_singular_values([[1.0, 1.0, 1.0], [2.0, 0.5, 1.0], [1.3, 1.3, 1 / 1.69], [0.4, 0.5, 5.0]], 21)
    evaluate = Expressions(len(F))
    mixed = evaluate(material.mixed_energy(evaluate.F, ufl.as_ufl(123.0)), F)
    np.testing.assert_allclose(mixed, limit(np.einsum("nij,nij->n", F, F)), rtol=1e-12, atol=1e-13)


# --- the aliases ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("alias,params,corotated", [
    ("fixed_corotated", {"mu": 3.0, "lmbda": 7.0}, {"mu": 3.0, "lmbda": 7.0}),
    ("fixed_corotated", {"E": 1.0e4, "nu": 0.3}, {"E": 1.0e4, "nu": 0.3}),
    ("arap", {"mu": 2.5}, {"mu": 2.5, "lmbda": 0.0}),
])
def test_aliases_are_corotated(alias: str, params: dict[str, Any], corotated: dict[str, Any]) -> None:
    """Exactly corotated's values (1e-14), det F > 0 (inverted F: corotated's own business, issue 11's polar part);
    arap also equals HOBAK's ARAP.cpp psi = mu ||F - U V^T||^2 written with numpy's SVD."""
    F, labels = hard_samples(inverted=False)
    got, want = reference(alias, params, F), reference("corotated", corotated, F)
    for q in ("psi", "P", "A"):
        scale = max(np.abs(want[q]).max(), 1.0)
        assert np.abs(got[q] - want[q]).max() <= 1e-14 * scale, q
    if alias == "arap":
        U, _, Vt = np.linalg.svd(F)
        hobak = params["mu"] * np.sum((F - U @ Vt) ** 2, axis=(1, 2))
        np.testing.assert_allclose(got["psi"], hobak, rtol=1e-12, atol=1e-13)


def test_aliases_under_their_own_names() -> None:
    with pytest.raises(forms.ParameterError, match="^fixed_corotated: mu = -1.0, must be > 0$"):
        forms.make_law("fixed_corotated", mu=-1.0, lmbda=1.0)
    with pytest.raises(forms.ParameterError, match=r"^arap: unknown parameter 'lmbda' \(allowed: mu\)$"):
        forms.make_law("arap", mu=1.0, lmbda=1.0)
    with pytest.raises(forms.ParameterError, match="^arap: mu is missing$"):
        forms.make_law("arap")
    with pytest.raises(ValueError, match="^arap: has no volumetric term"):
        forms.make_law("arap", mu=1.0).mixed_energy(ufl.Identity(3), ufl.as_ufl(0.0))
    with pytest.raises(forms.ParameterError, match="^stable_neo_hookean: variant = 'pixar', must be one of "
                                                   "rest_stable, paper$"):
        forms.make_law("stable_neo_hookean", mu=1.0, lmbda=1.0, variant="pixar")
    assert forms.make_law("arap", mu=2.0).parameters() == {"mu": 2.0}
    snh = forms.make_law("stable_neo_hookean", E=1.0, nu=0.25, variant="paper")
    assert snh.parameters() == {"mu": 0.4, "lmbda": 0.4, "variant": "paper"}
    assert forms.make_law("stable_neo_hookean", **snh.parameters()) == snh
    text = forms.laws_markdown()
    for name in ("fixed_corotated", "arap", "stable_neo_hookean", "yeoh"):
        assert f"### `{name}`" in text


# --- a simulation through the configuration path -----------------------------------------------------------------

def principal_stress(law: str, stretches: np.ndarray, params: dict[str, Any]) -> np.ndarray:
    """P_ii at F = diag(stretches), by complex step of the numpy energies."""
    F = np.diag(stretches)[None]
    return np.diag(numpy_P(law, F, params)[0])


def uniaxial(law: str, params: dict[str, Any], traction: float) -> tuple[float, float]:
    def balance(x: np.ndarray) -> np.ndarray:
        P = principal_stress(law, np.array([x[0], x[1], x[1]]), params)
        return np.array([P[0] - traction, P[1]])

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sol = fsolve(balance, np.array([1.0, 1.0]), xtol=1e-14)
    assert np.abs(balance(sol)).max() < 1e-10 * traction
    return float(sol[0]), float(sol[1])


@pytest.mark.parametrize("law,params,formulation", [
    ("stable_neo_hookean", {"E": 1.0e4, "nu": 0.3, "variant": "paper"}, "displacement"),
    ("yeoh", {"c1": 1500.0, "c2": -50.0, "c3": 20.0, "kappa": 2.0e4}, "mixed"),
    ("fixed_corotated", {"E": 1.0e4, "nu": 0.3}, "displacement"),
    ("arap", {"mu": 3.0e3}, "displacement"),
], ids=["snh-paper-displacement", "yeoh-mixed", "fixed_corotated", "arap"])
def test_uniaxial_run(law: str, params: dict[str, Any], formulation: str, shared_tmp) -> None:
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["material"] = [{"region": "all", "law": law, **params}]
    if formulation == "mixed":
        raw["discretization"] = {"degree": 2, "formulation": "mixed"}
    raw["loading"] = {"steps": 2}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    assert summary["status"] == "completed"
    traction = raw["boundary"][3]["value"][0]
    steps = [s for s in summary["steps"] if s["converged"]]
    assert [round(s["load_factor"], 12) for s in steps] == [0.5, 1.0]
    for step in steps:
        la, lt = uniaxial(law, params, step["load_factor"] * traction)
        np.testing.assert_allclose(step["probes"]["corner"], [la - 1.0, lt - 1.0, lt - 1.0], rtol=1e-8, atol=1e-14)


@pytest.mark.parametrize("change,key,fragment", [
    ({"law": "stable_neo_hookean", "E": 1.0e4, "nu": 0.3, "variant": "pixar"}, "material[0].variant",
     "stable_neo_hookean: variant = 'pixar', must be one of rest_stable, paper"),
    ({"law": "stable_neo_hookean", "E": 1.0e4, "nu": 0.3, "variant": 2}, "material[0].variant",
     "variant = 2, must be one of rest_stable, paper"),
    ({"law": "yeoh", "c1": 1.0e3, "kappa": "big"}, "material[0].kappa", "must be a number, got 'big'"),
    ({"law": "yeoh", "c1": 1.0e3}, "material[0].kappa", "yeoh: kappa is missing"),
    ({"law": "arap", "mu": 1.0e3, "mixed": True}, "material[0].law", "'arap' has no volumetric term"),
])
def test_configuration_words_and_errors(change: dict[str, Any], key: str, fragment: str) -> None:
    """A choice is a word in a configuration file (variant = "paper" builds), anything else is named by its key."""
    from model.config import ConfigError, parse

    raw = example("uniaxial")
    mixed = change.pop("mixed", False)
    if mixed:
        raw["discretization"] = {"degree": 2, "formulation": "mixed"}
    raw["material"] = [{"region": "all", **change}]
    with pytest.raises(ConfigError) as info:
        parse(raw, EXAMPLES)
    assert str(info.value).startswith(key) and fragment in str(info.value), str(info.value)
    raw["material"][0] = {"region": "all", "law": "stable_neo_hookean", "E": 1.0e4, "nu": 0.3, "variant": "paper"}
    assert parse(raw, EXAMPLES).materials[0].law.variant == "paper"


@pytest.mark.parametrize("variant", ["rest_stable", "paper"])
def test_snh_equals_hobak(variant: str) -> None:
    """HOBAK's own forms (SNH.cpp, SNH_WITH_BARRIER.cpp) written in numpy with its reparametrisations:
    psi_H = (ms/2)(Ic - 3) + (ls/2)(J - a)^2 [- (ms/2) ln(Ic + 1)], P_H = ms F + ls (J - a) cof F
    [- ms F / (Ic + 1)], a = 1 + ms / ls (rest_stable) or 1 + 3 ms / (4 ls) (paper). P equals ours; psi too
    for paper, and for rest_stable up to HOBAK's constant ms^2 / (2 ls) (its (J - a)^2 expanded about 1)."""
    mu, lmbda = 3.0, 7.0
    F, _ = hard_samples(inverted=True)
    ref = reference("stable_neo_hookean", {"mu": mu, "lmbda": lmbda, "variant": variant}, F)
    if variant == "rest_stable":
        ms, ls = mu, lmbda + mu
        a = 1.0 + ms / ls
    else:
        ms, ls = 4.0 * mu / 3.0, lmbda + 5.0 * mu / 6.0
        a = 1.0 + ms / ls - ms / (4.0 * ls)
    Ic, J = np.einsum("nij,nij->n", F, F), np.linalg.det(F)
    cof = np.stack([np.cross(F[:, :, 1], F[:, :, 2]), np.cross(F[:, :, 2], F[:, :, 0]),
                    np.cross(F[:, :, 0], F[:, :, 1])], axis=2)  # dJ/dF, column by column
    psi = 0.5 * ms * (Ic - 3.0) + 0.5 * ls * (J - a) ** 2
    P = ms * F + (ls * (J - a))[:, None, None] * cof
    if variant == "paper":
        psi = psi - 0.5 * ms * np.log(Ic + 1.0)
        P = P - (ms / (Ic + 1.0))[:, None, None] * F
    shift = ms**2 / (2.0 * ls) if variant == "rest_stable" else 0.0
    np.testing.assert_allclose(ref["psi"] + shift, psi, rtol=1e-12, atol=1e-12 * mu)
    np.testing.assert_allclose(ref["P"], P, rtol=1e-12, atol=1e-12 * mu)
