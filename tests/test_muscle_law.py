"""The muscle and tendon laws at the constitutive level, against closed forms from energies.md.

Isochoric fibre stretch F = diag(l, l^-1/2, l^-1/2), a0 = e1 (J = 1, lbar = l): the Cauchy stress
difference is sigma_11 - sigma_22 = 2 (c1 + c2 / l)(l^2 - 1/l) + l dF2/dlbar, with dF2/dlbar written
here directly from the piecewise curves of energies.md (the law integrates them in closed form).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import forms
from model.verify import reference


def f_active(s: float) -> float:
    if 0.4 < s <= 0.6:
        return 9 * (s - 0.4) ** 2
    if 0.6 < s < 1.4:
        return 1 - 4 * (1 - s) ** 2
    if 1.4 <= s < 1.6:
        return 9 * (s - 1.6) ** 2
    return 0.0


def exponential_linear(x: float, star: float, A: float, B: float) -> float:
    """0 (x <= 1); A (exp(B (x - 1)) - 1) (1 < x < star); the C1 line A B e^(B(star-1)) x + ... beyond."""
    if x <= 1:
        return 0.0
    if x < star:
        return A * (math.exp(B * (x - 1)) - 1)
    slope = A * B * math.exp(B * (star - 1))
    return A * (math.exp(B * (star - 1)) - 1) + slope * (x - star)


def muscle_dF2(l: float, alpha: float, p: dict) -> float:
    s = l / p["l_ofl"]
    return p["sigma_max"] / p["l_ofl"] * (exponential_linear(s, p["l_star"] / p["l_ofl"], p["P1"], p["P2"])
                                          + alpha * f_active(s))


def tendon_dF2(l: float, p: dict) -> float:
    return exponential_linear(l, p["l_star_t"], p["L1"], p["L2"])


STRETCHES = [0.45, 0.55, 0.75, 0.98, 1.02, 1.25, 1.45, 1.55, 1.7]
MUSCLE = {"sigma_max": 3e5, "P1": 0.05, "P2": 6.6, "l_ofl": 1.0, "l_star": 1.4, "c1": 500.0, "c2": 120.0, "K": 1e7}
TENDON = {"L1": 2.7e6, "L2": 46.4, "l_star_t": 1.03, "c1": 500.0, "c2": 0.0, "K": 1e7}


def stress_difference(material: str, params: dict, stretches: list[float], alpha: float | None) -> np.ndarray:
    l = np.array(stretches)
    F = np.zeros((len(l), 3, 3))
    F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = l, l**-0.5, l**-0.5
    fields = {"a0": np.tile([1.0, 0.0, 0.0], (len(l), 1))}
    if alpha is not None:
        fields["alpha"] = np.full(len(l), alpha)
    P = reference(material, params, F, **fields)["P"]
    sigma = P @ np.transpose(F, (0, 2, 1))  # J = 1
    return sigma[:, 0, 0] - sigma[:, 1, 1]


@pytest.mark.parametrize("alpha", [0.0, 1.0, 0.4])
def test_muscle_fibre_stress_closed_form(alpha: float) -> None:
    got = stress_difference("muscle", MUSCLE, STRETCHES, alpha)
    c1, c2 = MUSCLE["c1"], MUSCLE["c2"]
    expected = [2 * (c1 + c2 / l) * (l**2 - 1 / l) + l * muscle_dF2(l, alpha, MUSCLE) for l in STRETCHES]
    np.testing.assert_allclose(got, expected, rtol=1e-8)


def test_tendon_fibre_stress_closed_form() -> None:
    stretches = [0.9, 0.99, 1.005, 1.02, 1.029, 1.031, 1.06, 1.2]
    got = stress_difference("tendon", TENDON, stretches, None)
    expected = [2 * TENDON["c1"] * (l**2 - 1 / l) + l * tendon_dF2(l, TENDON) for l in stretches]
    np.testing.assert_allclose(got, expected, rtol=1e-8)


def test_stvk_isotropic_part_and_defaults() -> None:
    law = forms.make_law("muscle", isotropic="stvk", E=9e6, nu=0.45, K=1e7)
    assert law.isotropic == "stvk" and law.mu == pytest.approx(9e6 / 2.9) and law.sigma_max == 3e5
    assert forms.make_law("tendon").parameters()["L2"] == 46.4


@pytest.mark.parametrize("params,key", [({"sigma_max": -1.0}, "sigma_max"), ({"l_star": 0.9}, "l_star"),
                                        ({"isotropic": "ogden"}, "isotropic"), ({"sigmamax": 1.0}, "sigmamax"),
                                        ({"K": 0.0}, "K")])
def test_bad_muscle_parameters(params: dict, key: str) -> None:
    with pytest.raises(forms.ParameterError, match=key):
        forms.make_law("muscle", **params)
