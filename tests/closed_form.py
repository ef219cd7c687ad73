"""Closed-form homogeneous states, independent of UFL: energies in principal stretches.

For a diagonal F = diag(l1, l2, l3) the first Piola-Kirchhoff stress is diagonal with
P_ii = d psi / d l_i; the derivatives are taken by complex-step differentiation,
exact to rounding: d psi/d l_i = Im psi(l + i h e_i) / h with h = 1e-30.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
from scipy.optimize import fsolve

Energy = Callable[[np.ndarray, dict[str, float]], complex]


def _lame(p: dict[str, float]) -> tuple[float, float]:
    if "mu" in p:
        return p["mu"], p["lmbda"]
    E, nu = p["E"], p["nu"]
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def stvk(l: np.ndarray, p: dict[str, float]) -> complex:
    mu, lmbda = _lame(p)
    E = (l**2 - 1) / 2
    return mu * np.sum(E**2) + lmbda / 2 * np.sum(E) ** 2


def neo_hookean(l: np.ndarray, p: dict[str, float]) -> complex:
    mu, lmbda = _lame(p)
    lnJ = np.log(np.prod(l))
    return mu / 2 * (np.sum(l**2) - 3) - mu * lnJ + lmbda / 2 * lnJ**2


def mooney_rivlin(l: np.ndarray, p: dict[str, float]) -> complex:
    J = np.prod(l)
    I1 = J ** (-2 / 3) * np.sum(l**2)
    I2 = J ** (-4 / 3) * (l[0] ** 2 * l[1] ** 2 + l[1] ** 2 * l[2] ** 2 + l[0] ** 2 * l[2] ** 2)
    return p["c1"] * (I1 - 3) + p["c2"] * (I2 - 3) + p["K"] * np.log(J) ** 2


def corotated(l: np.ndarray, p: dict[str, float]) -> complex:
    mu, lmbda = _lame(p)  # R = I for diagonal F with positive stretches
    return mu * np.sum((l - 1) ** 2) + lmbda / 2 * (np.prod(l) - 1) ** 2


ENERGIES: dict[str, Energy] = {"stvk": stvk, "neo_hookean": neo_hookean, "mooney_rivlin": mooney_rivlin,
                               "corotated": corotated}


def principal_stress(law: str, stretches: np.ndarray, params: dict[str, float]) -> np.ndarray:
    """(P11, P22, P33) = d psi / d l_i by complex step."""
    h = 1e-30
    out = np.empty(3)
    for i in range(3):
        l = stretches.astype(complex)
        l[i] += 1j * h
        out[i] = np.imag(ENERGIES[law](l, params)) / h
    return out


def uniaxial_stretches(law: str, params: dict[str, float], traction: float) -> tuple[float, float]:
    """(l_axial, l_lateral) with P11 = traction (nominal) and P22 = P33 = 0."""

    def balance(x: np.ndarray) -> np.ndarray:
        P = principal_stress(law, np.array([x[0], x[1], x[1]]), params)
        return np.array([P[0] - traction, P[1]])

    with warnings.catch_warnings():  # "xtol too small": the residual check below is what counts
        warnings.simplefilter("ignore", RuntimeWarning)
        sol = fsolve(balance, np.array([1.0, 1.0]), xtol=1e-14)
    residual = np.max(np.abs(balance(sol)))
    assert residual < 1e-11 * max(abs(traction), 1.0), f"closed form not solved: residual {residual}"
    return float(sol[0]), float(sol[1])
