"""The ogden law (issue 11, item 2) against an independent numpy implementation through the SVD.

numpy: lambda_i the singular values of F, lbar_i = J^(-1/3) lambda_i,
    psi = sum_p c_p / m_p^2 (sum_i lbar_i^m_p - 3) + (kappa/2)(ln J)^2,
    P   = U diag(dpsi/dlambda_k) V^T,  dpsi/dlambda_k = [sum_p c_p / m_p (lbar_k^m_p - sum_i lbar_i^m_p / 3)
                                                         + kappa ln J] / lambda_k,
and A by central differences of that P (smooth at repeated stretches: an isotropic function of F).
At F = I, A is the linear elastic tensor with mu = sum_p c_p / 2 and bulk modulus kappa.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import example, run_raw
from scipy.optimize import fsolve
from scipy.spatial.transform import Rotation

from forms.law import ParameterError
from forms.registry import resolve_law
from model.verify import ReferenceEvaluator, deformation_samples

PARAMS = {"c1": 2.0e3, "m1": 3.5, "c2": 400.0, "m2": -2.0, "c3": 50.0, "m3": 7.0, "kappa": 1.0e4}
#: terms 4 and 6 of the six FEBio's Ogden takes (c2 = c3 = c5 = 0: absent); three active terms keep the form's
#: compilation as cheap as PARAMS' (all six active: 35 s), and the terms go through one loop (Ogden.terms)
PARAMS6 = {"c1": 2.0e3, "m1": 3.5, "c4": 300.0, "m4": -1.5, "c6": 50.0, "m6": 5.0, "kappa": 1.0e4}


def _terms(params: dict) -> list[tuple[float, float]]:
    return [(params.get(f"c{p}", 0.0), params.get(f"m{p}", 1.0)) for p in range(1, 7) if params.get(f"c{p}", 0.0)]


def principal(params: dict, lam: np.ndarray) -> tuple[float, np.ndarray]:
    """(psi, dpsi/dlambda_k) of the principal stretches lam (3,)."""
    J = np.prod(lam)
    lbar = J ** (-1.0 / 3.0) * lam
    psi = 0.5 * params["kappa"] * np.log(J) ** 2
    dpsi = np.full(3, params["kappa"] * np.log(J))
    for c, m in _terms(params):
        powers = lbar**m
        psi += c / m**2 * (powers.sum() - 3.0)
        dpsi += c / m * (powers - powers.sum() / 3.0)
    return psi, dpsi / lam


def numpy_psi_P(params: dict, F: np.ndarray) -> tuple[float, np.ndarray]:
    U, s, Vt = np.linalg.svd(F)
    psi, dpsi = principal(params, s)
    return psi, U @ np.diag(dpsi) @ Vt


def numpy_A(params: dict, F: np.ndarray) -> np.ndarray:
    """Richardson-extrapolated central differences of numpy_psi_P's P, steps scaled by the smallest stretch."""
    h = 1e-3 * np.linalg.svd(F, compute_uv=False).min()

    def central(step: float) -> np.ndarray:
        A = np.zeros((3, 3, 3, 3))
        for k in range(3):
            for l in range(3):
                E = np.zeros((3, 3))
                E[k, l] = step
                A[:, :, k, l] = (numpy_psi_P(params, F + E)[1] - numpy_psi_P(params, F - E)[1]) / (2 * step)
        return A

    return (4.0 * central(0.5 * h) - central(h)) / 3.0


def _samples() -> tuple[np.ndarray, list[str]]:
    Q1, Q2 = Rotation.random(2, random_state=21).as_matrix()
    F = [np.eye(3), Q1 @ np.diag([1.4, 0.8, 0.8]) @ Q2, Q1 @ np.diag([0.7, 1.2, 1.2]) @ Q1.T,
         1.3 * Q2, 0.8 * np.eye(3), Q1 @ np.diag([1.5, 0.9, 0.6]) @ Q2, np.diag([1.2, 1.0, 1.0]),
         Q1, Q1 @ np.diag([1.0, 1.0, 1.0 + 1e-9]) @ Q2]
    labels = ["identity", "uniaxial", "uniaxial_symmetric", "isotropic", "isotropic_compression", "distinct",
              "axis_aligned_uniaxial", "rotation", "nearly_identity"]
    G, glabels = deformation_samples(7, seed=3, inverted=False)
    return np.concatenate([np.array(F), G]), labels + glabels


@pytest.mark.parametrize("params", [PARAMS, PARAMS6], ids=["terms-1-3", "terms-1-4-6"])
def test_against_numpy_at_repeated_and_distinct_stretches(params: dict) -> None:
    F, labels = _samples()
    out = ReferenceEvaluator("ogden", params, len(F)).evaluate(F)
    for n, label in enumerate(labels):
        psi, P = numpy_psi_P(params, F[n])
        assert np.all(np.isfinite(out["A"][n])), label
        assert abs(out["psi"][n] - psi) <= 1e-11 * max(abs(psi), params["c1"] * 1e-3), label
        np.testing.assert_allclose(out["P"][n], P, rtol=0, atol=1e-11 * max(np.abs(P).max(), params["c1"]),
                                   err_msg=label)
        A = numpy_A(params, F[n])
        np.testing.assert_allclose(out["A"][n], A, rtol=0, atol=1e-7 * np.abs(A).max(), err_msg=label)


@pytest.mark.parametrize("params", [PARAMS, PARAMS6], ids=["terms-1-3", "terms-1-4-6"])
def test_tangent_at_identity_is_linear_elasticity(params: dict) -> None:
    out = ReferenceEvaluator("ogden", params, 1).evaluate(np.eye(3)[None])
    mu = 0.5 * sum(c for c, _ in _terms(params))
    lam = params["kappa"] - 2.0 * mu / 3.0
    d = np.eye(3)
    C = (mu * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d))
         + lam * np.einsum("ij,kl->ijkl", d, d))
    np.testing.assert_allclose(out["A"][0], C, rtol=0, atol=1e-12 * np.abs(C).max())
    np.testing.assert_allclose(out["P"][0], 0.0, atol=1e-12 * mu)


def test_single_term_m2_is_neo_hookean_like_isochoric() -> None:
    """c/4 (Ibar1 - 3) for m = 2 (a closed form in invariants, no eigenvalues)."""
    F, _ = _samples()
    params = {"c1": 3.0, "m1": 2.0, "kappa": 2.0}
    out = ReferenceEvaluator("ogden", params, len(F)).evaluate(F)
    J = np.linalg.det(F)
    Ibar1 = J ** (-2.0 / 3.0) * np.sum(F**2, axis=(1, 2))
    np.testing.assert_allclose(out["psi"], 0.75 * (Ibar1 - 3.0) + np.log(J) ** 2, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("change, fragment", [
    ({"m1": 0.0}, "ogden: m1 = 0.0, must be != 0"),
    ({"c1": -1.0}, "ogden: c1 = -1.0, must be > 0"),
    ({"c2": -1.0}, "ogden: c2 = -1.0, must be >= 0"),
    ({"kappa": -1.0}, "ogden: kappa = -1.0, must be >= 0"),
    ({"c6": -1.0}, "ogden: c6 = -1.0, must be >= 0"),
    ({"m5": 0.0}, "ogden: m5 = 0.0, must be != 0"),
    ({"m7": 1.0}, "ogden: unknown parameter 'm7'"),
])
def test_parameter_errors(change: dict, fragment: str) -> None:
    with pytest.raises(ParameterError, match=fragment.replace("(", r"\(")):
        resolve_law("ogden").make(**{**PARAMS, **change})


def test_uniaxial_config_run_matches_closed_form(shared_tmp: Path) -> None:
    params = {"c1": 2000.0, "m1": 4.0, "c2": 300.0, "m2": -2.0, "kappa": 1.0e4}
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["material"] = [{"region": "all", "law": "ogden", **params}]
    raw["loading"] = {"steps": 3}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    assert summary["status"] == "completed"
    traction = raw["boundary"][3]["value"][0]
    steps = [s for s in summary["steps"] if s["converged"]]
    assert len(steps) == 3
    for step in steps:
        t = step["load_factor"] * traction

        def equations(x: np.ndarray, t: float = t) -> np.ndarray:
            _, dpsi = principal(params, np.array([x[0], x[1], x[1]]))
            return np.array([dpsi[0] - t, dpsi[1]]) / params["c1"]

        la, lt = fsolve(equations, [1.0, 1.0], xtol=1e-12)
        np.testing.assert_allclose(equations(np.array([la, lt])), 0.0, atol=1e-12)
        np.testing.assert_allclose(step["probes"]["corner"], [la - 1.0, lt - 1.0, lt - 1.0], rtol=1e-8)
        np.testing.assert_allclose(step["reactions"]["xmin"][0], -t, rtol=1e-9)


def test_verify_element_tet4_at_rest_and_in_uniaxial_stretch() -> None:
    """verify element: K = dP/dF contracted with the P1 gradients, finite at rest (no NaN from eigenvalues);
    W = volume psi and f from numpy's P (F is constant in a tet4)."""
    from model.verify.element import assemble_element

    X = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    grads = np.array([[-1.0, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]])  # shape-function gradients
    for F in (np.eye(3), np.diag([1.3, 0.9, 0.9])):
        u = X @ (F - np.eye(3)).T
        ref = assemble_element("ogden", PARAMS, X, u)
        psi, P = numpy_psi_P(PARAMS, F)
        A = numpy_A(PARAMS, F)
        assert abs(ref.W - psi / 6.0) <= 1e-12 * max(abs(psi), PARAMS["c1"])
        np.testing.assert_allclose(ref.f, (P @ grads.T).T.reshape(-1) / 6.0, atol=1e-11 * PARAMS["c1"])
        K = np.einsum("iakb,ma,nb->mink", A, grads, grads).reshape(12, 12) / 6.0
        np.testing.assert_allclose(ref.K, K, atol=1e-7 * np.abs(K).max())
