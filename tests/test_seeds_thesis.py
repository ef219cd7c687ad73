"""The thesis' spring, membrane and time-step transcriptions (model/verify/seeds/thesis.py), checked independently.

tests/test_seeds.py pins which rows of ``verify seeds`` agree; here each transcription (and each corrected
variant) is checked against numpy written in this file: central differences of energies written here, the
signed volume of a tetrahedron, and backward Euler for a linear system (where one linearised step is exact).
The manifold (gdim 3, tdim 2) mesh of model/compat.py is checked by its area.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from model import compat
from model.verify.seeds import thesis


def central(f, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """d f/d x (f: (n, m) -> (n, ...)) by central differences, -> (n, ..., m)."""
    out = []
    for k in range(x.shape[1]):
        dx = np.zeros_like(x)
        dx[:, k] = h
        out.append((f(x + dx) - f(x - dx)) / (2 * h))
    return np.stack(out, axis=-1)


# --- springs -----------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def springs() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    q = rng.standard_normal((12, 3))
    r = np.abs(rng.standard_normal(12))
    r[:4] = 0.0
    return q, r


def energy(q: np.ndarray, r: np.ndarray, ks: float) -> np.ndarray:
    return ks * (np.sqrt(np.sum(q * q, axis=1)) - r) ** 2


def test_spring_energy_force_hessian(springs) -> None:
    q, r = springs
    ks = 1.7
    np.testing.assert_allclose(thesis.thesis_eq4_13_energy(q, r, ks), energy(q, r, ks), rtol=1e-14)
    grad = central(lambda x: energy(x, r, ks), q)
    np.testing.assert_allclose(thesis.thesis_eq4_14_corrected(q, r, ks), grad, atol=1e-7)
    np.testing.assert_allclose(2.0 * thesis.thesis_eq4_14_force(q, r, ks), grad, atol=1e-7)  # the factor 2
    hess = central(lambda x: thesis.thesis_eq4_14_corrected(x, r, ks), q)
    np.testing.assert_allclose(thesis.thesis_eq4_15_corrected(q, r, ks), hess, atol=1e-6)
    printed = thesis.thesis_eq4_15_hessian(q, r, ks)
    zero = r == 0.0
    np.testing.assert_allclose(2.0 * printed[zero], hess[zero], atol=1e-6)  # zero-length: only the factor 2
    assert np.max(np.abs(2.0 * printed[~zero] - hess[~zero])) > 1e-2  # r > 0: r/|q| q q^T is wrong


def test_spring_on_ends_is_the_chain_rule(springs) -> None:
    q, r = springs
    ks = 0.9
    X = np.concatenate([np.zeros_like(q), q], axis=1) + 0.3  # x_a = 0.3, x_b = q + 0.3

    def on_ends(Y: np.ndarray) -> np.ndarray:
        return energy(Y[:, 3:] - Y[:, :3], r, ks)

    g, H = thesis.spring_on_ends(thesis.thesis_eq4_14_corrected(q, r, ks), thesis.thesis_eq4_15_corrected(q, r, ks))
    np.testing.assert_allclose(g, central(on_ends, X), atol=1e-7)
    np.testing.assert_allclose(H, central(lambda Y: thesis.spring_on_ends(
        thesis.thesis_eq4_14_corrected(Y[:, 3:] - Y[:, :3], r, ks), np.zeros((len(Y), 3, 3)))[0], X), atol=1e-6)


# --- membrane ----------------------------------------------------------------------------------------------------

YOUNG, NU, THICK = 2.0, 0.35, 0.1


def membrane_energy(x: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Plane-stress StVK, frame-free: E_e = h A (mu |E|^2 + lambda'/2 (tr E)^2), E on the triangle's plane from the
    edge metric: with edges e1 = X2 - X1, e2 = X3 - X1, Gram matrices g (rest), c (deformed), tr E = tr(g^-1 (c - g))/2,
    |E|^2 = tr((g^-1 (c - g))^2)/4."""
    mu = YOUNG / (2 * (1 + NU))
    lam = YOUNG * NU / (1 - NU**2)
    E0 = np.stack([X[1] - X[0], X[2] - X[0]])
    g = E0 @ E0.T
    e = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)
    c = e @ np.swapaxes(e, 1, 2)
    M = np.linalg.solve(g, c - g) / 2.0
    area = 0.5 * np.linalg.norm(np.cross(E0[0], E0[1]))
    tr = np.trace(M, axis1=1, axis2=2)
    return THICK * area * (mu * np.trace(M @ M, axis1=1, axis2=2) + 0.5 * lam * tr**2)


@pytest.fixture(scope="module")
def membrane() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    X = np.array([[0.2, 0.1, -0.3], [1.3, 0.0, 0.2], [0.1, 1.1, 0.4]])
    x = X[None] + 0.3 * rng.standard_normal((8, 3, 3))
    return X, x


def test_membrane_material_coords_are_isometric(membrane) -> None:
    X, _ = membrane
    Xbar = thesis.membrane_material_coords(X)
    for a in range(3):
        for b in range(3):
            assert np.isclose(np.linalg.norm(Xbar[a] - Xbar[b]), np.linalg.norm(X[a] - X[b]), rtol=1e-14, atol=1e-15)


def test_membrane_energy_forces_hessian(membrane) -> None:
    X, x = membrane
    Xbar = thesis.membrane_material_coords(X)
    np.testing.assert_allclose(thesis.thesis_membrane_energy(x, Xbar, YOUNG, NU, THICK), membrane_energy(x, X),
                               rtol=1e-12)
    flat = x.reshape(len(x), 9)
    grad = central(lambda y: membrane_energy(y.reshape(-1, 3, 3), X), flat)
    forces = thesis.thesis_membrane_forces(x, Xbar, YOUNG, NU, THICK).reshape(len(x), 9)
    np.testing.assert_allclose(forces, -grad, atol=1e-8 * np.abs(grad).max())
    hess = central(lambda y: thesis.thesis_membrane_forces(y.reshape(-1, 3, 3), Xbar, YOUNG, NU, THICK)
                   .reshape(-1, 9), flat)
    np.testing.assert_allclose(thesis.thesis_membrane_hessian(x, Xbar, YOUNG, NU, THICK), hess,
                               atol=1e-7 * np.abs(hess).max())


def test_membrane_B_is_plane_stress() -> None:
    """B = the plane-stress stiffness: sigma_11 = E/(1 - nu^2)(eps_11 + nu eps_22), sigma_12 = G gamma_12."""
    B = thesis.thesis_membrane_B(YOUNG, NU)
    shear = YOUNG / (2 * (1 + NU))
    np.testing.assert_allclose(B @ [1.0, 0.0, 0.0], [YOUNG / (1 - NU**2), NU * YOUNG / (1 - NU**2), 0.0])
    np.testing.assert_allclose(B @ [0.0, 0.0, 1.0], [0.0, 0.0, shear])


def test_pressure_force_is_p_times_the_volume_gradient() -> None:
    """On a closed tetrahedron surface the corrected nodal force is p dV/dx, V = det[x1-x0, x2-x0, x3-x0]/6;
    with unit areas it is not (unless every deformed area is 1)."""
    rng = np.random.default_rng(5)
    X = thesis.TET
    x = X[None] + 0.1 * rng.standard_normal((6, 4, 3))
    p = 1.3

    def volume(y: np.ndarray) -> np.ndarray:
        y = y.reshape(-1, 4, 3)
        return np.linalg.det(np.swapaxes(y[:, 1:] - y[:, :1], 1, 2)) / 6.0

    assert np.all(volume(x) > 0)  # TET_FACES outward for these
    grad = p * central(volume, x.reshape(6, 12))
    corrected = thesis.thesis_membrane_pressure(x, thesis.TET_FACES, p, unit_area=False).reshape(6, 12)
    np.testing.assert_allclose(corrected, grad, atol=1e-8)
    printed = thesis.thesis_membrane_pressure(x, thesis.TET_FACES, p).reshape(6, 12)
    assert np.max(np.abs(printed - grad)) > 1e-2


# --- eq. 4.4 -----------------------------------------------------------------------------------------------------

def test_semi_implicit_step_is_exact_backward_euler_for_linear_forces() -> None:
    """f_int(q) = K q (linear): the linearised step of eq. 4.4 solves backward Euler exactly, written here as
    M (v1 - vn) = h (f_ext - K q1 - D v1), q1 = qn + h v1 (one linear system in (q1, v1))."""
    rng = np.random.default_rng(9)
    n = 6
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    B = rng.standard_normal((n, n))
    K = B @ B.T
    qn, vn, f_ext = rng.standard_normal((3, n))
    h, alpha, beta = 0.07, 0.3, 0.02
    D = alpha * M + beta * K
    # unknowns (q1, v1): q1 - h v1 = qn; h K q1 + (M + h D) v1 = M vn + h f_ext
    system = np.block([[np.eye(n), -h * np.eye(n)], [h * K, M + h * D]])
    exact = np.linalg.solve(system, np.concatenate([qn, M @ vn + h * f_ext]))
    q1, v1 = thesis.thesis_eq4_4_step(M, K, K @ qn, f_ext, qn, vn, h, alpha, beta)
    np.testing.assert_allclose(np.concatenate([q1, v1]), exact, rtol=1e-12, atol=1e-12)


# --- model/compat: manifold meshes -------------------------------------------------------------------------------

def test_compat_triangle_mesh_in_3d_has_the_right_area() -> None:
    X = np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.3], [0.1, 0.8, 0.9], [1.0, 1.0, 1.5]])
    cells = np.array([[0, 1, 2], [1, 3, 2]], dtype=np.int64)
    mesh = compat.create_mesh(MPI.COMM_SELF, cells, X, cell="triangle")
    assert mesh.topology.dim == 2 and mesh.geometry.x.shape[1] == 3
    area = fem.assemble_scalar(fem.form(fem.Constant(mesh, 1.0) * ufl.dx(domain=mesh)))
    expected = sum(0.5 * np.linalg.norm(np.cross(X[b] - X[a], X[c] - X[a])) for a, b, c in cells)
    assert np.isclose(area, expected, rtol=1e-13)
    V = compat.function_space(mesh, "Lagrange", 1, (3,))
    assert V.dofmap.index_map_bs == 3
