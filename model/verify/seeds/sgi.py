"""The skinning seed (shared/seeds/mixed-fem-skinning-sgi.txt), "Screened Poisson Equation" and "Mixed FEM":
the screened Poisson energy, its discrete standard and KKT systems and the stationarity conditions as printed.

The discrete operators are assembled by dolfinx on a small triangle mesh (COMM_SELF): the gradient matrix G
(P1 -> per-triangle gradients, G = W^-1 B with B[c, :] u = int_c grad u), the weight matrix W (triangle
areas, one per gradient component), the P1 mass matrix M and stiffness K (= G^T W G). The seed sets W = M = I
("by assuming a uniform mesh of equal triangles"); the rows check the printed algebra with W = M = I, and the
FE meaning of the same system with W and M written out, on a perturbed (non-uniform) mesh.

Rows:
- sgi-kkt: the printed KKT system [[I, 0, -I], [0, alpha I, G^T], [-I, G, 0]] [g; u; lambda] = [0; f; 0]
  gives the u of the printed standard system (G^T G + alpha I) u = f;
- sgi-kkt-stationarity: the printed gradients of L = 1/2 g^T g + 1/2 alpha u^T u - u^T f + lambda^T (G u - g),
  g - lambda, alpha u - f + G^T lambda, G u - g, against central differences of L;
- sgi-poisson-equation: the PDE as printed, "lap u - alpha u = f", against the minimiser of the printed energy
  E(u) (its Euler-Lagrange equation is -lap u + alpha u = f); -corrected: -lap u + alpha u = f;
- sgi-kkt-fem: the KKT system with the weights written out, [[W, 0, -W], [0, alpha M, B^T], [-W, B, 0]]
  [g; u; lambda] = [0; M f; 0] (what I stands for), against the standard finite elements (K + alpha M) u = M f
  on the non-uniform mesh; the diagnosis gives how far the identity weights are from it there.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from forms.poisson import screened_poisson_energy
from model import compat
from model.verify.seeds.common import RTOL, SeedRow

SGI = "mixed-fem-skinning-sgi.txt"
ALPHA = 2.0
CELLS = 6  # per edge of the unit square: 72 triangles, 49 vertices
PERTURB = 0.3  # interior vertices moved by up to this fraction of the cell size (non-uniform mesh)


def _dense(form) -> np.ndarray:
    A = fem_petsc.assemble_matrix(fem.form(form))
    A.assemble()
    dense = A.convert("dense").getDenseArray().copy()
    A.destroy()
    return dense


def sgi_operators(seed: int = 2020) -> dict[str, np.ndarray]:
    """G, B, W, K, M of a perturbed CELLS x CELLS triangle mesh of the unit square, and the nodal values f of
    f(x, y) = cos(pi x) cos(pi y) + x, and the minimiser of E(u) in P1 derived by UFL (COMM_SELF; module docstring)."""
    msh = dmesh.create_unit_square(MPI.COMM_SELF, CELLS, CELLS)
    x = msh.geometry.x
    interior = (x[:, 0] > 1e-12) & (x[:, 0] < 1 - 1e-12) & (x[:, 1] > 1e-12) & (x[:, 1] < 1 - 1e-12)
    rng = np.random.default_rng(seed)
    x[interior, :2] += PERTURB / CELLS * rng.uniform(-1.0, 1.0, (int(interior.sum()), 2))
    V = compat.function_space(msh, "Lagrange", 1)
    D = compat.function_space(msh, "DG", 0, (2,))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    g, mu = ufl.TrialFunction(D), ufl.TestFunction(D)
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": 2})
    B = _dense(ufl.inner(mu, ufl.grad(u)) * dx)
    W = _dense(ufl.inner(mu, g) * dx)
    K = _dense(ufl.inner(ufl.grad(v), ufl.grad(u)) * dx)
    M = _dense(v * u * dx)
    G = np.linalg.solve(W, B)
    points = V.tabulate_dof_coordinates()
    f = np.cos(np.pi * points[:, 0]) * np.cos(np.pi * points[:, 1]) + points[:, 0]
    # the reference: the minimiser of E(u) (forms.poisson, f its P1 interpolant), with the linear system
    # UFL derives from the energy (independent of the hand-assembled K and M above)
    f_h, w = fem.Function(V), fem.Function(V)
    f_h.x.array[:] = f
    energy = screened_poisson_energy(w, ALPHA, f_h, dx)
    residual = ufl.derivative(energy, w, v)
    hessian = _dense(ufl.derivative(residual, w, u))
    b = fem_petsc.assemble_vector(fem.form(residual))  # at w = 0: -(the right-hand side)
    minimiser = np.linalg.solve(hessian, -b.array.copy())
    b.destroy()
    return {"G": G, "B": B, "W": W, "K": K, "M": M, "f": f, "minimiser": minimiser}


def printed_kkt(G: np.ndarray, alpha: float, f: np.ndarray) -> np.ndarray:
    """The seed's KKT matrix solved as printed: [[I, 0, -I], [0, alpha I, G^T], [-I, G, 0]] [g; x; lambda] =
    [0; f; 0]; returns x."""
    m, n = G.shape
    Im = np.eye(m)
    A = np.block([[Im, np.zeros((m, n)), -Im], [np.zeros((n, m)), alpha * np.eye(n), G.T], [-Im, G, np.zeros((m, m))]])
    y = np.linalg.solve(A, np.concatenate([np.zeros(m), f, np.zeros(m)]))
    return y[m:m + n]


def printed_lagrangian(g: np.ndarray, u: np.ndarray, lam: np.ndarray, G: np.ndarray, alpha: float,
                       f: np.ndarray) -> float:
    """L = 1/2 g^T g + 1/2 alpha u^T u - u^T f + lambda^T (G u - g), as printed."""
    return float(0.5 * g @ g + 0.5 * alpha * u @ u - u @ f + lam @ (G @ u - g))


def printed_gradients(g: np.ndarray, u: np.ndarray, lam: np.ndarray, G: np.ndarray, alpha: float,
                      f: np.ndarray) -> np.ndarray:
    """The printed KKT conditions' left-hand sides: (g - lambda, alpha u - f + G^T lambda, G u - g)."""
    return np.concatenate([g - lam, alpha * u - f + G.T @ lam, G @ u - g])


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), np.finfo(float).tiny))


def _row(id_: str, where: str, error: float, diagnosis: str) -> SeedRow:
    return SeedRow(id_, f"{SGI} {where}", bool(error <= RTOL), error, diagnosis)


def _sgi_rows() -> list[SeedRow]:
    ops = sgi_operators()
    G, B, W, K, M, f = (ops[k] for k in ("G", "B", "W", "K", "M", "f"))
    m, n = G.shape
    rows = []
    standard = np.linalg.solve(G.T @ G + ALPHA * np.eye(n), f)
    rows.append(_row("sgi-kkt", "Mixed FEM, the KKT system", _rel(printed_kkt(G, ALPHA, f), standard),
                     "the printed KKT system (W = M = I) gives the u of the printed (G^T G + alpha I) u = f"))
    rng = np.random.default_rng(7)
    g, u, lam = rng.standard_normal(m), rng.standard_normal(n), rng.standard_normal(m)
    point = np.concatenate([g, u, lam])
    h = 1e-3  # L is quadratic: central differences are exact up to rounding

    def L(y: np.ndarray) -> float:
        return printed_lagrangian(y[:m], y[m:m + n], y[m + n:], G, ALPHA, f)

    fd = np.array([(L(point + h * e) - L(point - h * e)) / (2 * h) for e in np.eye(len(point))])
    rows.append(_row("sgi-kkt-stationarity", "Mixed FEM, the KKT conditions",
                     _rel(printed_gradients(g, u, lam, G, ALPHA, f), fd),
                     "the printed gradients of L in g, u and lambda are its derivatives (central differences)"))
    energy_minimiser = ops["minimiser"]  # dE/du = 0 for E(u) as printed, in P1 (derived by UFL)
    as_printed = np.linalg.solve(K + ALPHA * M, -M @ f)  # lap u - alpha u = f, weakly: -(K + alpha M) u = M f
    rows.append(_row("sgi-poisson-equation", "Screened Poisson Equation, the PDE",
                     _rel(as_printed, energy_minimiser),
                     "the printed energy E(u) is minimised by the solution of -lap u + alpha u = f (its Euler-Lagrange "
                     "equation), but the text writes lap u - alpha u = f: f has the wrong sign (u changes sign)"))
    corrected = np.linalg.solve(K + ALPHA * M, M @ f)  # -lap u + alpha u = f, weakly: (K + alpha M) u = M f
    rows.append(_row("sgi-poisson-equation-corrected", "Screened Poisson Equation, the PDE",
                     _rel(corrected, energy_minimiser), "-lap u + alpha u = f is the minimiser of E(u)"))
    A = np.block([[W, np.zeros((m, n)), -W], [np.zeros((n, m)), ALPHA * M, B.T], [-W, B, np.zeros((m, m))]])
    y = np.linalg.solve(A, np.concatenate([np.zeros(m), M @ f, np.zeros(m)]))
    identity = _rel(printed_kkt(G, ALPHA, f), energy_minimiser)
    rows.append(_row("sgi-kkt-fem", "Mixed FEM, the KKT system with the weights",
                     _rel(y[m:m + n], energy_minimiser),
                     "with W (areas) and M (mass) for the identities the KKT system gives the FE minimiser of E(u) "
                     f"(K + alpha M) u = M f on a non-uniform mesh; the identity weights are {identity:.2g} from it "
                     "there (the text assumes equal triangles)"))
    return rows


__all__ = ["ALPHA", "SGI", "printed_gradients", "printed_kkt", "printed_lagrangian", "sgi_operators"]
