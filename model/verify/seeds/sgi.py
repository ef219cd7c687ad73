"""The skinning blog post (Kassahun et al., "Automatic Skinning Transformations using Mixed Finite Elements"),
"Screened Poisson Equation" and "Mixed FEM":
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

Section "1.2 Apply Adjoint Method" (``_adjoint_rows``), on a 3 x 3 unit square of 18 equal triangles
(``adjoint_setup``): L(S, x, lambda) = E_ARAP(S) + k/2 ||P x - x_pinned||^2 + lambda (B x - R S) with R = R(theta)
per triangle as printed, [[cos, sin], [-sin, cos]]. What E_ARAP(S) = ||S - I||^2 means here (forms.skinning):
S is symmetric per triangle with 3 unknowns (s11, s12, s22), and ||S - I||_F^2 is the Frobenius norm of the full
2 x 2 matrix, (s11 - 1)^2 + 2 s12^2 + (s22 - 1)^2 (the off-diagonal counts twice), summed over the triangles
weighted by their areas (the integral; on this mesh of equal triangles a constant factor, the seed's plain sum).
B x - R S is the 2 x 2 constraint per triangle (grad x of the P1 positions x; lambda 4 values per triangle);
the pinning penalty k/2 int_pin |x - x_pin|^2 over the bottom row of triangles (x_pin a stretch of the rest
positions), so P^T P is its mass matrix (the FE meaning of the selection, as W and M for I above). The KKT matrix
A(theta) (the Hessian of L in y = (S, x, lambda)) and b = -dL/dy(0) are assembled by dolfinx from the UFL
Lagrangian (model.problem.skinning), dA/dtheta_c by ufl.derivative in theta; theta random in [-0.6, 0.6].

- sgi-adjoint: the printed dy/dR = -A^-1 (dA/dR) A^-1 b, per triangle angle, against central differences of
  y(theta) = A(theta)^-1 b (h = 1e-5);
- sgi-adjoint-dlambda: the printed dy/dR = (dS*/dR, dx*/dR, 0): the multiplier's block is not 0;
  -corrected: the lambda block of -A^-1 (dA/dR) A^-1 b;
- sgi-adjoint-stationarity: the printed gradients of L, grad_S L = H S + g - R^T lambda, grad_x L = k/2 P^T P
  (read as k/2 P^T P x, the only vector it makes) + B^T lambda, grad_lambda L = B x - R S, against central
  differences of L (assembled from UFL) at a random point; H, g the Hessian and gradient at 0 of E_ARAP in
  (s11, s12, s22), R^T lambda the adjoint of S -> R S in those coordinates (the - d/dS of lambda : R S);
  -corrected: grad_x L = k P^T (P x - x_pinned) + B^T lambda;
- sgi-adjoint-gradient: the printed chain rule dE/dtheta = dx/dtheta dE/dx + dS/dtheta dE/dS + dE/dtheta of
  E(R) = E_ARAP(S*) + k/2 ||P x* - x_pinned||^2 + ||R - R_pinned||^2 (R_pinned = I, int ||R - I||_F^2), with
  the derivatives of the printed dy/dR, against central differences of E(theta).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from forms.poisson import screened_poisson_energy
from forms.skinning import arap_energy, pinning_penalty, rotation_regularisation
from model import compat
from model.problem.skinning import SkinningProblem
from model.verify.seeds.common import RTOL, SeedRow

SGI = "mixed-fem-skinning-sgi.txt"
ALPHA = 2.0
CELLS = 6  # per edge of the unit square: 72 triangles, 49 vertices
PERTURB = 0.3  # interior vertices moved by up to this fraction of the cell size (non-uniform mesh)


def _dense(form) -> np.ndarray:
    A = fem_petsc.assemble_matrix(fem.form(form) if isinstance(form, ufl.Form) else form)
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
    rows += _adjoint_rows()
    return rows


ADJOINT_CELLS = 3  # per edge of the unit square: 18 triangles, 16 vertices, 158 unknowns y
ADJOINT_K = 10.0
ADJOINT_H = 1e-5


def _dense_vector(form) -> np.ndarray:
    b = fem_petsc.assemble_vector(fem.form(form))
    out = b.array.copy()
    b.destroy()
    return out


class AdjointSetup:
    """The section-1.2 system on a small mesh, dense (module docstring): ``A(theta)``, ``b``, ``dA(theta, c)``,
    the index sets ``blocks`` of S, x and lambda in y, the Lagrangian and the seed's E(R) assembled at any y."""

    def __init__(self, seed: int = 12):
        msh = dmesh.create_unit_square(MPI.COMM_SELF, ADJOINT_CELLS, ADJOINT_CELLS)
        cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
        bottom = cells[dmesh.compute_midpoints(msh, 2, cells)[:, 1] < 1.0 / ADJOINT_CELLS]
        X = ufl.SpatialCoordinate(msh)
        self.problem = p = SkinningProblem(msh, bottom, ADJOINT_K, x_pinned=ufl.as_vector([1.1 * X[0], 0.9 * X[1]]))
        self.blocks = [np.asarray(p.space.sub(i).collapse()[1], dtype=np.int64) for i in range(3)]
        self.theta0 = np.random.default_rng(seed).uniform(-0.6, 0.6, len(cells))
        self.direction = fem.Function(p.angle_space)
        self._A = fem.form(p.jacobian_form)
        self._dA = fem.form(ufl.derivative(p.jacobian_form, p.theta, self.direction))
        self._L = fem.form(p.lagrangian)
        s, x, _ = ufl.split(p.y)
        self.E_form = arap_energy(s, p.dx) + pinning_penalty(x, p.x_pinned, p.pinned, p.k, p.dx) \
            + rotation_regularisation(p.theta, fem.Constant(msh, 0.0), p.dx)
        self._E = fem.form(self.E_form)
        p.y.x.array[:] = 0.0
        self.b = -_dense_vector(p.residual_form)  # -dL/dy at y = 0

    def set(self, theta: np.ndarray, y: np.ndarray | None = None) -> None:
        self.problem.theta.x.array[:] = theta
        if y is not None:
            self.problem.y.x.array[:] = y

    def A(self, theta: np.ndarray) -> np.ndarray:
        self.set(theta)
        return _dense(self._A)

    def dA(self, theta: np.ndarray, c: int) -> np.ndarray:
        """dA/dtheta_c (UFL's derivative of the KKT matrix in the direction of cell c's angle)."""
        self.set(theta)
        self.direction.x.array[:] = 0.0
        self.direction.x.array[c] = 1.0
        return _dense(self._dA)

    def solve(self, theta: np.ndarray) -> np.ndarray:
        return np.linalg.solve(self.A(theta), self.b)

    def lagrangian(self, y: np.ndarray) -> float:
        self.set(self.theta0, y)
        return float(fem.assemble_scalar(self._L))

    def objective(self, theta: np.ndarray) -> float:
        """The seed's E(R) at y*(theta)."""
        self.set(theta, self.solve(theta))
        return float(fem.assemble_scalar(self._E))


def printed_dy(A: np.ndarray, dA: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The seed's dy/dR = -A^-1 (dA/dR) A^-1 b (one angle)."""
    return -np.linalg.solve(A, dA @ np.linalg.solve(A, b))


def printed_stationarity(y: np.ndarray, ops: dict[str, np.ndarray], blocks: list[np.ndarray], k: float,
                         corrected: bool = False) -> np.ndarray:
    """The printed grad_S L = H S + g - R^T lambda, grad_x L = k/2 P^T P x + B^T lambda (``corrected``:
    k P^T (P x - x_pinned) + B^T lambda), grad_lambda L = B x - R S, in y's ordering."""
    s, x, lam = (y[i] for i in blocks)
    out = np.empty_like(y)
    out[blocks[0]] = ops["H"] @ s + ops["g"] - ops["R"].T @ lam
    if corrected:
        out[blocks[1]] = k * (ops["PtP"] @ x - ops["Ptx_pinned"]) + ops["B"].T @ lam
    else:
        out[blocks[1]] = 0.5 * k * ops["PtP"] @ x + ops["B"].T @ lam
    out[blocks[2]] = ops["B"] @ x - ops["R"] @ s
    return out


def _adjoint_rows() -> list[SeedRow]:
    setup = AdjointSetup()
    theta, b = setup.theta0, setup.b
    S_, X_, L_ = setup.blocks
    A = setup.A(theta)
    n = len(theta)
    dA = [setup.dA(theta, c) for c in range(n)]
    printed = np.stack([printed_dy(A, dA[c], b) for c in range(n)], axis=1)
    fd = np.stack([(setup.solve(theta + ADJOINT_H * e) - setup.solve(theta - ADJOINT_H * e)) / (2 * ADJOINT_H)
                   for e in np.eye(n)], axis=1)
    rows = [_row("sgi-adjoint", "1.2 Apply Adjoint Method, dy/dR", _rel(printed, fd),
                 "the printed dy/dR = -A^-1 (dA/dR) A^-1 b is the derivative of y = A^-1 b (b does not depend on R) "
                 "against central differences, per triangle angle theta")]
    lam_max, rest_max = float(np.max(np.abs(fd[L_]))), float(np.max(np.abs(fd[np.concatenate([S_, X_])])))
    rows.append(_row("sgi-adjoint-dlambda", "1.2 Apply Adjoint Method, dy/dR = (dS/dR, dx/dR, 0)",
                     _rel(np.zeros_like(fd[L_]), fd[L_]),
                     "the text writes dy/dR = (dS*/dR, dx*/dR, 0), but the multiplier moves with R: "
                     f"max |dlambda/dtheta| = {lam_max:.2g} (max |d(S, x)/dtheta| = {rest_max:.2g}); harmless for "
                     "dE/dR, which does not depend on lambda"))
    rows.append(_row("sgi-adjoint-dlambda-corrected", "1.2 Apply Adjoint Method, dy/dR = (dS/dR, dx/dR, 0)",
                     _rel(printed[L_], fd[L_]), "the lambda block of -A^-1 (dA/dR) A^-1 b is dlambda*/dR"))
    # the printed stationarity conditions, with the blocks of the discrete system (module docstring)
    k = ADJOINT_K
    ops = {"H": A[np.ix_(S_, S_)], "g": -b[S_], "B": A[np.ix_(L_, X_)], "R": -A[np.ix_(L_, S_)],
           "PtP": A[np.ix_(X_, X_)] / k, "Ptx_pinned": b[X_] / k}
    rng = np.random.default_rng(3)
    point = rng.standard_normal(len(b))
    h = 1e-3  # L is quadratic in y: central differences are exact up to rounding
    grad = np.array([(setup.lagrangian(point + h * e) - setup.lagrangian(point - h * e)) / (2 * h)
                     for e in np.eye(len(b))])
    as_printed = printed_stationarity(point, ops, setup.blocks, k)
    corrected = printed_stationarity(point, ops, setup.blocks, k, corrected=True)
    rows.append(_row("sgi-adjoint-stationarity", "1.2 Apply Adjoint Method, the gradients of L",
                     _rel(as_printed, grad),
                     "grad_S L and grad_lambda L as printed are the derivatives of L "
                     f"({_rel(as_printed[S_], grad[S_]):.1g}, {_rel(as_printed[L_], grad[L_]):.1g}), but "
                     "grad_x L = k/2 P^T P + B^T lambda is not: the derivative of k/2 ||P x - x_pinned||^2 is "
                     "k P^T (P x - x_pinned) (factor 2 and x_pinned "
                     f"missing; x block {_rel(as_printed[X_], grad[X_]):.2g} off)"))
    rows.append(_row("sgi-adjoint-stationarity-corrected", "1.2 Apply Adjoint Method, the gradients of L",
                     _rel(corrected, grad), "grad_x L = k P^T (P x - x_pinned) + B^T lambda"))
    # the printed chain rule for dE/dR with the printed dy/dR
    y = np.linalg.solve(A, b)
    setup.set(theta, y)
    p = setup.problem
    dEdy = _dense_vector(ufl.derivative(setup.E_form, p.y, ufl.TestFunction(p.space)))
    dEdtheta = _dense_vector(ufl.derivative(setup.E_form, p.theta, ufl.TestFunction(p.angle_space)))
    chain = printed[X_].T @ dEdy[X_] + printed[S_].T @ dEdy[S_] + dEdtheta
    fd_E = np.array([(setup.objective(theta + ADJOINT_H * e) - setup.objective(theta - ADJOINT_H * e))
                     / (2 * ADJOINT_H) for e in np.eye(n)])
    rows.append(_row("sgi-adjoint-gradient", "1.2 Apply Adjoint Method, dE/dR", _rel(chain, fd_E),
                     "the printed chain rule dE/dtheta = dx/dtheta dE/dx + dS/dtheta dE/dS + dE/dtheta of E(R) = "
                     "E_ARAP(S*) + k/2 ||P x* - x_pinned||^2 + ||R - I||^2, with the printed dy/dR, against central "
                     "differences of E(theta)"))
    return rows


__all__ = ["ADJOINT_CELLS", "ALPHA", "SGI", "AdjointSetup", "printed_dy", "printed_gradients", "printed_kkt",
           "printed_lagrangian", "printed_stationarity", "sgi_operators"]
