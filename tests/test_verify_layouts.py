"""Tangent and stress layouts (model/verify/layouts.py) against independent numpy implementations.

The reference here is not the UFL one: a compressible neo-Hookean law with a fibre term, whose P, A, S,
dS/dE and spatial tangent are written below in closed form, and the Abaqus-form neo-Hookean law of the
Abaqus UMAT example, whose A comes from a complex-step derivative of P. Every layout is rebuilt from its
definition with explicit index loops, never by calling the module under test.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from model.verify import layouts

I3 = np.eye(3)
MU, LMBDA, K_FIBRE = 1.3, 2.1, 0.7
ABAQUS_ORDER = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]  # 11, 22, 33, 12, 13, 23


def rotation(rng: np.random.Generator) -> np.ndarray:
    Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q * np.sign(np.linalg.det(Q))


def samples(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """F (identity, rotation, repeated singular values (a, b, b) and (a, a, a), distinct ones in [0.5, 2],
    random near I) and a unit fibre direction per sample."""
    rng = np.random.default_rng(seed)
    sigmas = [(1, 1, 1), None, (1.6, 0.8, 0.8), (0.7, 0.7, 0.7), (0.6, 1.4, 2.0), (2.0, 2.0, 0.5), (1.2, 0.9, 0.55)]
    F = []
    for s in sigmas:
        if s is None:
            F.append(rotation(rng))
        else:
            F.append(rotation(rng) @ np.diag(s) @ rotation(rng))
    for _ in range(5):
        G = I3 + 0.3 * rng.standard_normal((3, 3))
        F.append(G if np.linalg.det(G) > 0 else -G)
    F[0] = I3.copy()
    a0 = rng.standard_normal((len(F), 3))
    return np.array(F), a0 / np.linalg.norm(a0, axis=1)[:, None]


def neo_hookean_fibre(F: np.ndarray, a0: np.ndarray, k_fibre: float = K_FIBRE) -> dict[str, np.ndarray]:
    """psi = mu/2 (I1 - 3) - mu ln J + lambda/2 ln^2 J + k/2 (I4 - 1)^2, I4 = a0 . C a0, in closed form:

    P = mu (F - F^-T) + lambda ln J F^-T + 2 k (I4 - 1) (F a0) (x) a0
    A_ijkl = mu delta_ik delta_jl + (mu - lambda ln J) G_il G_kj + lambda G_ij G_kl
             + 2 k (I4 - 1) delta_ik a_j a_l + 4 k (F a0)_i a_j (F a0)_k a_l            (G = F^-T)
    S = mu (I - C^-1) + lambda ln J C^-1 + 2 k (I4 - 1) a0 (x) a0
    dS/dE_IJKL = lambda Ci_IJ Ci_KL + (mu - lambda ln J)(Ci_IK Ci_JL + Ci_IL Ci_JK) + 4 k a_I a_J a_K a_L
    (Bonet & Wood, Nonlinear continuum mechanics for FEA, 2nd ed., section 6.4.3 for the neo-Hookean part).
    """
    out = {"P": [], "A": [], "S": [], "CC": []}
    for Fn, a in zip(F, a0):
        G = np.linalg.inv(Fn).T
        J = np.linalg.det(Fn)
        Ci = np.linalg.inv(Fn.T @ Fn)
        I4 = a @ Fn.T @ Fn @ a
        Fa = Fn @ a
        P = MU * (Fn - G) + LMBDA * np.log(J) * G + 2 * k_fibre * (I4 - 1) * np.outer(Fa, a)
        A = np.zeros((3, 3, 3, 3))
        CC = np.zeros((3, 3, 3, 3))
        for i, j, k, m in itertools.product(range(3), repeat=4):
            A[i, j, k, m] = (MU * I3[i, k] * I3[j, m] + (MU - LMBDA * np.log(J)) * G[i, m] * G[k, j]
                             + LMBDA * G[i, j] * G[k, m] + 2 * k_fibre * (I4 - 1) * I3[i, k] * a[j] * a[m]
                             + 4 * k_fibre * Fa[i] * a[j] * Fa[k] * a[m])
            CC[i, j, k, m] = (LMBDA * Ci[i, j] * Ci[k, m] + (MU - LMBDA * np.log(J)) * (Ci[i, k] * Ci[j, m]
                              + Ci[i, m] * Ci[j, k]) + 4 * k_fibre * a[i] * a[j] * a[k] * a[m])
        S = MU * (I3 - Ci) + LMBDA * np.log(J) * Ci + 2 * k_fibre * (I4 - 1) * np.outer(a, a)
        for key, value in (("P", P), ("A", A), ("S", S), ("CC", CC)):
            out[key].append(value)
    return {k: np.array(v) for k, v in out.items()}


def push_forward(F: np.ndarray, CC: np.ndarray) -> np.ndarray:
    """c_ijkl = (1/J) F_iI F_jJ F_kK F_lL C_IJKL, with explicit sums."""
    c = np.zeros_like(CC)
    for n, Fn in enumerate(F):
        J = np.linalg.det(Fn)
        for i, j, k, m in itertools.product(range(3), repeat=4):
            total = 0.0
            for I, Jx, K, L in itertools.product(range(3), repeat=4):
                total += Fn[i, I] * Fn[j, Jx] * Fn[k, K] * Fn[m, L] * CC[n, I, Jx, K, L]
            c[n, i, j, k, m] = total / J
    return c


def jaumann(c: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """C^J_ijkl = c_ijkl + (delta_ik sigma_jl + sigma_ik delta_jl + delta_il sigma_jk + sigma_il delta_jk)/2."""
    out = c.copy()
    for n in range(len(c)):
        s = sigma[n]
        for i, j, k, m in itertools.product(range(3), repeat=4):
            out[n, i, j, k, m] += (I3[i, k] * s[j, m] + s[i, k] * I3[j, m]
                                   + I3[i, m] * s[j, k] + s[i, m] * I3[j, k]) / 2
    return out


def voigt66(T: np.ndarray) -> np.ndarray:
    """D[I, K] = T[i, j, k, l], I = (ij), K = (kl) in the order 11, 22, 33, 12, 13, 23 (engineering shear)."""
    return np.array([[[Tn[i, j, k, m] for (k, m) in ABAQUS_ORDER] for (i, j) in ABAQUS_ORDER] for Tn in T])


def voigt6(T: np.ndarray) -> np.ndarray:
    return np.array([[Tn[i, j] for (i, j) in ABAQUS_ORDER] for Tn in T])


def hessian(A: np.ndarray, column_major: bool) -> np.ndarray:
    H = np.zeros((len(A), 9, 9))
    for n, i, j, k, m in itertools.product(range(len(A)), *[range(3)] * 4):
        a, b = (i + 3 * j, k + 3 * m) if column_major else (3 * i + j, 3 * k + m)
        H[n, a, b] = A[n, i, j, k, m]
    return H


def independent(layout: str, F: np.ndarray, law: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(stress, tangent) of ``layout``, built from the definitions in the test."""
    J = np.linalg.det(F)
    sigma = np.array([Fn @ Sn @ Fn.T / Jn for Fn, Sn, Jn in zip(F, law["S"], J)])
    if layout == "ijkl":
        return law["P"], law["A"]
    if layout in ("hessian9-col", "hessian9-row"):
        return law["P"], hessian(law["A"], layout == "hessian9-col")
    if layout == "voigt-material":
        return voigt6(law["S"]), voigt66(law["CC"])
    c = push_forward(F, law["CC"])
    if layout == "voigt-spatial":
        return voigt6(sigma), voigt66(c)
    return voigt6(sigma), voigt66(jaumann(c, sigma))


def rel_errors(user: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-sample ||user - ref|| / max(||ref||, 1e-4 max ||ref||): P vanishes at the identity and at rotations,
    where both sides are rounding noise (1e-16) that only the scale of the set can judge."""
    u, r = user.reshape(len(user), -1), ref.reshape(len(ref), -1)
    norm = np.linalg.norm(r, axis=1)
    return np.linalg.norm(u - r, axis=1) / np.maximum(norm, 1e-4 * norm.max())


def max_rel(user: np.ndarray, ref: np.ndarray) -> float:
    return float(rel_errors(user, ref).max())


@pytest.fixture(scope="module")
def case() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    F, a0 = samples()
    return F, neo_hookean_fibre(F, a0)


def test_closed_form_is_consistent(case) -> None:
    """The test's own law: P = F S, and A against central differences of P (guards the closed forms)."""
    F, law = case
    assert max_rel(F @ law["S"], law["P"]) < 1e-12
    rng = np.random.default_rng(5)
    a0 = rng.standard_normal((len(F), 3))
    a0 /= np.linalg.norm(a0, axis=1)[:, None]
    base = neo_hookean_fibre(F, a0)
    h = 1e-6
    A_fd = np.zeros_like(base["A"])
    for k, m in itertools.product(range(3), repeat=2):
        E = np.zeros((3, 3))
        E[k, m] = h
        A_fd[:, :, :, k, m] = (neo_hookean_fibre(F + E, a0)["P"] - neo_hookean_fibre(F - E, a0)["P"]) / (2 * h)
    assert max_rel(A_fd, base["A"]) < 1e-7


@pytest.mark.parametrize("layout", layouts.TANGENT_LAYOUTS)
def test_layout_matches_independent_implementation(layout: str, case) -> None:
    F, law = case
    out = layouts.from_reference(layout, F, law["P"], law["A"])
    stress, tangent = independent(layout, F, law)
    assert out["tangent"].shape == (len(F), *layouts.TANGENT_SHAPES[layout])
    assert max_rel(out["stress"], stress) < 1e-12
    assert max_rel(out["tangent"], tangent) < 1e-12


@pytest.mark.parametrize("layout", layouts.TANGENT_LAYOUTS)
def test_round_trip(layout: str, case) -> None:
    F, law = case
    out = layouts.from_reference(layout, F, law["P"], law["A"])
    P, A = layouts.to_reference(layout, F, out["stress"], out["tangent"])
    assert max_rel(P, law["P"]) < 1e-12
    assert max_rel(A, law["A"]) < 1e-12
    # the user's arrays as the independent implementation builds them convert to the same P and A
    stress, tangent = independent(layout, F, law)
    P, A = layouts.to_reference(layout, F, stress, tangent)
    assert max_rel(A, law["A"]) < 1e-12


@pytest.mark.parametrize("layout", layouts.TANGENT_LAYOUTS)
def test_perturbed_entry_is_detected(layout: str, case) -> None:
    F, law = case
    out = layouts.from_reference(layout, F, law["P"], law["A"])
    tangent = out["tangent"].copy()
    index = (4, 0, 3) if tangent.ndim == 3 else (4, 0, 1, 2, 2)
    tangent[index] += 1e-6 * np.abs(tangent[4]).max()
    stress = out["stress"].copy()
    stress[6, 1] = stress[6, 1] + 1e-6 * np.abs(stress[6]).max()
    P, A = layouts.to_reference(layout, F, stress, tangent)
    rel_A, rel_P = rel_errors(A, law["A"]), rel_errors(P, law["P"])
    assert rel_A[4] > 1e-8 and np.delete(rel_A, [4, 6]).max() < 1e-12
    assert rel_P[6] > 1e-8 and np.delete(rel_P, 6).max() < 1e-12


@pytest.mark.parametrize("measure", layouts.STRESS_MEASURES)
def test_stress_measures(measure: str, case) -> None:
    F, law = case
    J = np.linalg.det(F)
    expected = {"P": law["P"], "S": law["S"],
                "sigma": np.array([Fn @ Sn @ Fn.T / Jn for Fn, Sn, Jn in zip(F, law["S"], J)])}[measure]
    stress = layouts.stress_from_P(measure, F, law["P"])
    assert max_rel(stress, expected) < 1e-12
    assert max_rel(layouts.P_from_stress(measure, F, expected), law["P"]) < 1e-12
    if measure != "P":
        assert max_rel(layouts.P_from_stress(measure, F, voigt6(expected)), law["P"]) < 1e-12
    else:
        with pytest.raises(ValueError, match="P is not symmetric"):
            layouts.P_from_stress("P", F, voigt6(expected))


# --- DDSDDE against the Abaqus neo-Hookean UMAT ----------------------------------------------------------

C10, D1 = 0.8, 0.05


def abaqus_P(F: np.ndarray) -> np.ndarray:
    """U = C10 (Ibar1 - 3) + (J - 1)^2 / D1 (Abaqus' compressible neo-Hookean): tau = 2 C10 dev(bbar)
    + (2/D1) J (J - 1) I, bbar = J^(-2/3) F F^T, P = tau F^-T. Complex-safe (complex step below)."""
    J = np.linalg.det(F)
    b = J[:, None, None] ** (-2 / 3) * F @ np.transpose(F, (0, 2, 1))
    tr = np.trace(b, axis1=1, axis2=2)[:, None, None]
    tau = 2 * C10 * (b - tr / 3 * I3) + (2 / D1 * J * (J - 1))[:, None, None] * I3
    return tau @ np.transpose(np.linalg.inv(F), (0, 2, 1))


def complex_step_A(F: np.ndarray) -> np.ndarray:
    h = 1e-30
    A = np.zeros((len(F), 3, 3, 3, 3))
    for k, m in itertools.product(range(3), repeat=2):
        E = np.zeros((3, 3), dtype=complex)
        E[k, m] = 1j * h
        A[:, :, :, k, m] = abaqus_P(F.astype(complex) + E).imag / h
    return A


def abaqus_ddsdde(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cauchy stress and the Jaumann-rate material Jacobian of the Abaqus neo-Hookean UMAT in closed form.

    From the Abaqus User Subroutines Reference Guide's UMAT example "compressible neo-Hookean
    hyperelasticity" (also in idaholab/moose modules/tensor_mechanics/test/plugins/neo_hooke.f), written as a
    tensor (Jaumann rate of bbar: d bbar + bbar d - 2/3 tr(d) bbar):
        sigma = EG dev(bbar) + PR I,                 EG = 2 C10 / J, PR = 2 (J - 1) / D1, EK = 2 (2 J - 1) / D1
        C^J_ijkl = EG [(d_ik b_jl + b_ik d_jl + d_il b_jk + b_il d_jk)/2 - 2/3 (b_ij d_kl + d_ij b_kl)
                   + 2/9 tr(b) d_ij d_kl] + EK d_ij d_kl                            (b = bbar, d = delta)
    """
    J = np.linalg.det(F)
    sig, CJ = [], []
    for Fn, Jn in zip(F, J):
        b = Jn ** (-2 / 3) * Fn @ Fn.T
        EG, PR, EK = 2 * C10 / Jn, 2 * (Jn - 1) / D1, 2 * (2 * Jn - 1) / D1
        sig.append(EG * (b - np.trace(b) / 3 * I3) + PR * I3)
        T = np.zeros((3, 3, 3, 3))
        for i, j, k, m in itertools.product(range(3), repeat=4):
            T[i, j, k, m] = EG * ((I3[i, k] * b[j, m] + b[i, k] * I3[j, m] + I3[i, m] * b[j, k]
                                   + b[i, m] * I3[j, k]) / 2
                                  - 2 / 3 * (b[i, j] * I3[k, m] + I3[i, j] * b[k, m])
                                  + 2 / 9 * np.trace(b) * I3[i, j] * I3[k, m]) + EK * I3[i, j] * I3[k, m]
        CJ.append(T)
        # entries as the UMAT example prints them (1-based Voigt 11, 22, 33, 12, 13, 23)
        tb = np.trace(b) / 3
        D = voigt66(T[None])[0]
        assert abs(D[0, 0] - (EG * 2 / 3 * (b[0, 0] + tb) + EK)) < 1e-12 * abs(EK)
        assert abs(D[0, 1] - (-EG * 2 / 3 * (b[0, 0] + b[1, 1] - tb) + EK)) < 1e-12 * abs(EK)
        assert abs(D[2, 3] - (-EG * 2 / 3 * b[0, 1])) < 1e-12 * abs(EK)
        assert abs(D[3, 4] - EG * b[1, 2] / 2) < 1e-12 * abs(EK)
        assert abs(D[3, 3] - EG * (b[0, 0] + b[1, 1]) / 2) < 1e-12 * abs(EK)
    return voigt6(np.array(sig)), voigt66(np.array(CJ))


def test_ddsdde_matches_abaqus_neo_hookean_umat() -> None:
    F, _ = samples(3)
    P = abaqus_P(F)
    A = complex_step_A(F)
    sigma, ddsdde = abaqus_ddsdde(F)
    out = layouts.from_reference("abaqus-ddsdde", F, P, A)
    assert max_rel(out["stress"], sigma) < 1e-12
    assert max_rel(out["tangent"], ddsdde) < 1e-10
    # and without the Jaumann correction it would not: the spatial tangent differs
    assert max_rel(layouts.from_reference("voigt-spatial", F, P, A)["tangent"], ddsdde) > 1e-3


def test_ddsdde_matches_bonet_wood_neo_hookean() -> None:
    """sigma = mu/J (b - I) + lambda ln J / J I; c = lambda/J I (x) I + (mu - lambda ln J)/J (d_ik d_jl + d_il d_jk)
    (Bonet & Wood 2008, section 6.4.3); C^J = c + the Jaumann correction with sigma."""
    F, _ = samples(4)
    a0 = np.tile([1.0, 0.0, 0.0], (len(F), 1))
    law = neo_hookean_fibre(F, a0, k_fibre=0.0)
    J = np.linalg.det(F)
    sigma = np.array([MU / Jn * (Fn @ Fn.T - I3) + LMBDA * np.log(Jn) / Jn * I3 for Fn, Jn in zip(F, J)])
    c = np.array([LMBDA / Jn * np.einsum("ij,kl->ijkl", I3, I3) + (MU - LMBDA * np.log(Jn)) / Jn
                  * (np.einsum("ik,jl->ijkl", I3, I3) + np.einsum("il,jk->ijkl", I3, I3)) for Jn in J])
    out = layouts.from_reference("abaqus-ddsdde", F, law["P"], law["A"])
    assert max_rel(out["stress"], voigt6(sigma)) < 1e-12
    assert max_rel(out["tangent"], voigt66(jaumann(c, sigma))) < 1e-10
    assert max_rel(layouts.from_reference("voigt-spatial", F, law["P"], law["A"])["tangent"], voigt66(c)) < 1e-10


# --- hints -----------------------------------------------------------------------------------------------

def test_hints(case) -> None:
    F, law = case
    P, A = law["P"], law["A"]
    col, row = hessian(A, True), hessian(A, False)
    assert layouts.hints("hessian9-col", F, P, A, user_stress=P, user_tangent=col) == []
    found = layouts.hints("hessian9-row", F, P, A, user_tangent=col)
    assert len(found) == 1 and "hessian9-col" in found[0] and "--layout hessian9-col" in found[0], found
    found = layouts.hints("hessian9-col", F, P, A, user_stress=np.transpose(P, (0, 2, 1)), user_tangent=row)
    assert len(found) == 2 and "transposed (P^T)" in found[0] and "--layout hessian9-row" in found[1], found
    found = layouts.hints("ijkl", F, P, A, user_stress=0.5 * P, user_tangent=0.5 * A)
    assert found[0].startswith("P is 0.5 times the reference") and "mu vs mu/2" in found[0], found
    assert "0.5 times the reference" in found[1], found
    perm = np.transpose(A, (0, 1, 3, 2, 4))  # T[i,j,k,l] = A[i,k,j,l]
    found = layouts.hints("ijkl", F, P, A, user_tangent=perm)
    assert len(found) == 1 and "A[i,k,j,l]" in found[0], found
    # Voigt layouts: the spatial tangent given as DDSDDE, sigma given where S was expected, the other order
    spatial = voigt66(push_forward(F, law["CC"]))
    sigma = np.array([Fn @ Sn @ Fn.T / np.linalg.det(Fn) for Fn, Sn in zip(F, law["S"])])
    found = layouts.hints("abaqus-ddsdde", F, P, A, user_tangent=spatial)
    assert len(found) == 1 and "--layout voigt-spatial" in found[0], found
    found = layouts.hints("voigt-material", F, P, A, user_stress=voigt6(sigma))
    assert len(found) == 1 and "--stress sigma" in found[0], found
    other = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    reordered = np.array([[[Tn[i, j, k, m] for (k, m) in other] for (i, j) in other] for Tn in law["CC"]])
    found = layouts.hints("voigt-material", F, P, A, user_tangent=reordered)
    assert len(found) == 1 and "11, 22, 33, 23, 13, 12" in found[0], found
    ddsdde = layouts.from_reference("abaqus-ddsdde", F, P, A)["tangent"]  # checked above against the closed form
    found = layouts.hints("abaqus-ddsdde", F, P, A, user_tangent=np.linalg.det(F)[:, None, None] * ddsdde)
    assert len(found) == 1 and "J times abaqus-ddsdde" in found[0] and "divide by J" in found[0], found
    tensor_shear = ddsdde.copy()
    tensor_shear[:, :, 3:] *= 2
    found = layouts.hints("abaqus-ddsdde", F, P, A, user_tangent=tensor_shear)
    assert len(found) == 1 and "engineering shear strains" in found[0], found
    # a sample where the reference is undefined (NaN, e.g. ln J at J <= 0) does not hide the explanation
    P_nan, col_nan = P.copy(), col.copy()
    P_nan[3] = np.nan
    found = layouts.hints("hessian9-row", F, P_nan, A, user_stress=np.transpose(P, (0, 2, 1)), user_tangent=col_nan)
    assert len(found) == 2 and "(P^T)" in found[0] and "--layout hessian9-col" in found[1], found
    # noise explains nothing
    rng = np.random.default_rng(2)
    assert layouts.hints("ijkl", F, P, A, user_stress=P + rng.standard_normal(P.shape),
                         user_tangent=A + rng.standard_normal(A.shape)) == []


def test_bad_input() -> None:
    F, a0 = samples()
    law = neo_hookean_fibre(F, a0)
    with pytest.raises(ValueError, match="layout 'voigt' is unknown"):
        layouts.from_reference("voigt", F, law["P"], law["A"])
    with pytest.raises(ValueError, match=r"tangent: shape \(12, 9, 8\), hessian9-col needs \(N, 9, 9\)"):
        layouts.to_reference("hessian9-col", F, law["P"], np.zeros((12, 9, 8)))
    with pytest.raises(ValueError, match="needs the stress"):
        layouts.to_reference("voigt-spatial", F, None, np.zeros((12, 6, 6)))
    with pytest.raises(ValueError, match="stress measure 'tau' is unknown"):
        layouts.stress_from_P("tau", F, law["P"])


def test_help_lists_every_layout_and_measure() -> None:
    text = layouts.layouts_help()
    lines = text.splitlines()
    for name in layouts.TANGENT_LAYOUTS:
        assert any(line.split()[0] == name for line in lines), name
    for name in layouts.STRESS_MEASURES:
        assert f"stress {name} " in text, name


@pytest.mark.parametrize("smallest", [1e-1, 1e-2, 1e-3, 1e-4])
def test_nearly_flat_accuracy(smallest: float) -> None:
    """StVK (C = lambda I (x) I + mu (d_ik d_jl + d_il d_jk), constant) at nearly flat F: the conversion of the
    exact A stays within conversion_accuracy; for dS/dE that bound is eps cond(F)^3, not rounding."""
    rng = np.random.default_rng(11)
    n = 12
    F = np.array([rotation(rng) @ np.diag([rng.uniform(0.8, 1.5), rng.uniform(0.8, 1.5), smallest]) @ rotation(rng)
                  for _ in range(n)])
    CC = np.zeros((3, 3, 3, 3))
    for i, j, k, m in itertools.product(range(3), repeat=4):
        CC[i, j, k, m] = LMBDA * I3[i, j] * I3[k, m] + MU * (I3[i, k] * I3[j, m] + I3[i, m] * I3[j, k])
    CC = np.broadcast_to(CC, (n, 3, 3, 3, 3))
    E = (np.transpose(F, (0, 2, 1)) @ F - I3) / 2
    S = LMBDA * np.trace(E, axis1=1, axis2=2)[:, None, None] * I3 + 2 * MU * E
    P = F @ S
    A = np.zeros((n, 3, 3, 3, 3))
    for i, j, k, m in itertools.product(range(3), repeat=4):  # A_ijkl = delta_ik S_jl + F_iI F_kK C_IjKl
        A[:, i, j, k, m] = I3[i, k] * S[:, j, m] + np.einsum("nI,nK,IK->n", F[:, i, :], F[:, k, :], CC[0][:, j, :, m])
    c = push_forward(F, np.array(CC))
    for layout, stress, tangent in (("voigt-material", voigt6(S), voigt66(CC)), ("voigt-spatial", None, voigt66(c))):
        out = layouts.from_reference(layout, F, P, A)
        bound = layouts.conversion_accuracy(layout, F)
        assert np.all(rel_errors(out["tangent"], tangent) <= np.maximum(bound["tangent"], 1e-15)), layout
        if stress is not None:
            assert np.all(rel_errors(out["stress"], stress) <= np.maximum(bound["stress"], 1e-15))
    material = layouts.conversion_accuracy("voigt-material", F)["tangent"]
    assert (material.max() > 1e-8) == (smallest <= 1e-3)  # where a check of dS/dE at rtol 1e-8 must be told
