"""References for the thesis' spring, membrane and time-step formulas, through UFL and dolfinx (the project's path).

Nothing here is differentiated by hand: every gradient and Hessian is ``ufl.diff`` or ``ufl.derivative`` of an
energy (or residual) written in UFL, evaluated by a dolfinx Expression or assembled by dolfinx. Every mesh lives on
MPI.COMM_SELF (each rank computes the same values).

- ``SpringReference``: W(x_a, x_b) = k_s (|x_b - x_a| - r)^2 (thesis eq. 4.13) on per-sample end points held in a
  variable X = (x_a, x_b); dW/dX, d2W/dX2 by ``ufl.diff``.
- ``MembraneTriangle``: one triangle in 3D (gdim 3, tdim 2); plane-stress St. Venant-Kirchhoff membrane energy
  h int mu E:E + (lambda'/2) (tr E)^2 dA, F = grad(phi) T (3x2, T an orthonormal tangent frame of the rest
  triangle), E = (F^T F - I2)/2, lambda' = 2 mu lambda / (lambda + 2 mu) (the in-plane Lame constant); residual and
  Jacobian by ``ufl.derivative`` (thesis section 3.3.3.1).
- ``PressureSurface``: the closed surface of a tetrahedron (4 triangles); enclosed volume V(x) = (1/3) int
  phi . (F t1 x F t2) dA (the divergence theorem on the deformed surface); the pressure forces p dV/dx.
- ``BackwardEulerCell``: one tetrahedron, ``stvk`` from forms/; the backward Euler residual (thesis eq. 4.4, before
  its linearisation) R(v) = M (v - v_n) - h (f_ext - f_int(q_n + h v) - D v), D = alpha M + beta K(q_n), its
  Jacobian by ``ufl.derivative``, and the matrices M, K(q_n) and vectors f_int(q_n), f_ext the printed step uses.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from model import compat


def _disjoint_tets(n: int) -> Any:
    """n disjoint reference tetrahedra (one per sample) and the sample of each local cell."""
    reference_tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    cells = np.arange(4 * n, dtype=np.int64).reshape(n, 4)
    mesh = compat.create_mesh(MPI.COMM_SELF, cells, np.tile(reference_tet, (n, 1)))
    return mesh, np.asarray(mesh.topology.original_cell_index, dtype=np.int64)


def _node_order(space: fem.FunctionSpace, X: np.ndarray) -> np.ndarray:
    """vertex[d] = the row of X at dof node d (nodes matched by position)."""
    nodes = space.tabulate_dof_coordinates()
    vertex = np.argmin(np.linalg.norm(nodes[:, None, :] - X[None, :, :], axis=2), axis=1)
    if sorted(vertex) != list(range(len(X))):
        raise RuntimeError("one-cell mesh: could not match the dof nodes to the vertices")
    return vertex


def _dense(form: Any) -> np.ndarray:
    A = fem_petsc.assemble_matrix(form)
    A.assemble()
    dense = A.convert("dense").getDenseArray().copy()
    A.destroy()
    return dense


def _vector(form: Any) -> np.ndarray:
    b = fem_petsc.assemble_vector(form)
    values = b.array.copy()
    b.destroy()
    return values


class _Nodal:
    """A P1 vector space on a small mesh, with dof (node, component) <-> (vertex, component) permutations."""

    def __init__(self, mesh: Any, X: np.ndarray) -> None:
        self.space = compat.function_space(mesh, "Lagrange", 1, (3,))
        vertex = _node_order(self.space, X)
        self.vertex = vertex
        self.perm = (3 * vertex[:, None] + np.arange(3)).reshape(-1)  # dof d is (vertex, component) index perm[d]

    def set(self, function: fem.Function, values: np.ndarray) -> None:
        """Nodal values (vertices, 3) into a P1 vector function."""
        function.x.array[:] = np.asarray(values, dtype=np.float64).reshape(-1)[self.perm]

    def vector(self, values: np.ndarray) -> np.ndarray:
        out = np.empty_like(values)
        out[self.perm] = values
        return out

    def matrix(self, values: np.ndarray) -> np.ndarray:
        out = np.empty_like(values)
        out[np.ix_(self.perm, self.perm)] = values
        return out


class SpringReference:
    """W = k_s (|q| - r)^2, q = x_b - x_a (eq. 4.13), with dW/dX and d2W/dX2, X = (x_a, x_b), by ``ufl.diff``.

    One sample per cell of a mesh of disjoint tetrahedra: X a DG0 vector of size 6, r a DG0 scalar.
    """

    def __init__(self, num_samples: int, ks: float) -> None:
        self.n = num_samples
        self.mesh, self.order = _disjoint_tets(num_samples)
        self.X = fem.Function(compat.function_space(self.mesh, "DG", 0, (6,)), name="ends")
        self.r = fem.Function(compat.function_space(self.mesh, "DG", 0), name="rest_length")
        Xv = ufl.variable(self.X)
        q = ufl.as_vector([Xv[3 + i] - Xv[i] for i in range(3)])
        W = ks * (ufl.sqrt(ufl.dot(q, q)) - self.r) ** 2
        gradient = ufl.diff(W, Xv)
        hessian = ufl.diff(gradient, Xv)
        points = compat.quadrature_points(self.mesh, 1)
        self.expressions = {"psi": fem.Expression(W, points), "P": fem.Expression(gradient, points),
                            "A": fem.Expression(hessian, points)}

    def evaluate(self, ends: np.ndarray, rest_length: np.ndarray) -> dict[str, np.ndarray]:
        """{'psi': W (n,), 'P': dW/dX (n, 6), 'A': d2W/dX2 (n, 6, 6)} at end points (n, 2, 3), rest lengths (n,)."""
        self.X.x.array[:] = np.asarray(ends, dtype=np.float64).reshape(self.n, 6)[self.order].reshape(-1)
        self.r.x.array[:] = np.asarray(rest_length, dtype=np.float64)[self.order]
        inverse = np.empty_like(self.order)
        inverse[self.order] = np.arange(self.n)
        cells = np.arange(self.n, dtype=np.int32)
        return {name: compat.evaluate(self.expressions[name], self.mesh, cells).reshape(self.n, *shape)[inverse]
                for name, shape in (("psi", ()), ("P", (6,)), ("A", (6, 6)))}


def _tangent_frame(mesh: Any, normal: Any = None) -> tuple[Any, Any]:
    """An orthonormal tangent frame (t1, t2) of each rest triangle from the UFL Jacobian: t1 along the first
    reference edge, t2 = n x t1 with n the unit cell normal (``normal``: a given unit normal, e.g. outward)."""
    J = ufl.Jacobian(mesh)
    j0 = ufl.as_vector([J[i, 0] for i in range(3)])
    j1 = ufl.as_vector([J[i, 1] for i in range(3)])
    if normal is None:
        c = ufl.cross(j0, j1)
        normal = c / ufl.sqrt(ufl.dot(c, c))
    t1 = j0 / ufl.sqrt(ufl.dot(j0, j0))
    return t1, ufl.cross(normal, t1)


class MembraneTriangle:
    """Plane-stress StVK membrane on one triangle in 3D: energy, residual dE/dx, Jacobian d2E/dx2 and F F^T.

    phi (P1 vector) holds the deformed positions; F = grad(phi) [t1 t2] is the 3x2 deformation gradient in the
    rest triangle's orthonormal frame; E = (F^T F - I2)/2; psi = mu E:E + (lambda'/2)(tr E)^2 with
    mu = Y / (2 (1 + nu)), lambda' = Y nu / (1 - nu^2) (= 2 mu lambda / (lambda + 2 mu)); energy h int psi dA.
    """

    def __init__(self, X: np.ndarray, young: float, nu: float, thickness: float) -> None:
        self.X = np.asarray(X, dtype=np.float64)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, np.array([[0, 1, 2]], dtype=np.int64), self.X, cell="triangle")
        self.nodal = _Nodal(self.mesh, self.X)
        self.phi = fem.Function(self.nodal.space)
        t1, t2 = _tangent_frame(self.mesh)
        G3 = ufl.grad(self.phi)
        F = ufl.as_matrix([[ufl.dot(ufl.as_vector([G3[i, k] for k in range(3)]), t)
                            for t in (t1, t2)] for i in range(3)])
        E = 0.5 * (F.T * F - ufl.Identity(2))
        mu = young / (2.0 * (1.0 + nu))
        lam_plane = young * nu / (1.0 - nu**2)
        psi = mu * ufl.inner(E, E) + 0.5 * lam_plane * ufl.tr(E) ** 2
        dx = ufl.dx(domain=self.mesh, metadata={"quadrature_degree": 1})
        energy = thickness * psi * dx
        residual = ufl.derivative(energy, self.phi, ufl.TestFunction(self.nodal.space))
        self.forms = (fem.form(energy), fem.form(residual),
                      fem.form(ufl.derivative(residual, self.phi, ufl.TrialFunction(self.nodal.space))))
        self.b = fem.Expression(F * F.T, compat.quadrature_points(self.mesh, 1))

    def evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """(energy, residual (9,), Jacobian (9, 9), F F^T (3, 3)) at deformed positions x (3, 3), in
        (vertex, component) order."""
        self.nodal.set(self.phi, x)
        energy = fem.assemble_scalar(self.forms[0])
        b = compat.evaluate(self.b, self.mesh, np.array([0], dtype=np.int32)).reshape(3, 3)
        return (energy, self.nodal.vector(_vector(self.forms[1])), self.nodal.matrix(_dense(self.forms[2])), b)


class PressureSurface:
    """The closed surface of a tetrahedron: enclosed volume V(x) and dV/dx (the pressure forces are p dV/dx).

    V = (1/3) int phi . (F t1 x F t2) dA over the rest surface, F = grad(phi), (t1, t2, n) a right-handed frame
    with n the outward rest normal (a DG0 field): F t1 x F t2 dA = n_def dA_def, the divergence theorem.
    """

    def __init__(self, X: np.ndarray, faces: np.ndarray) -> None:
        self.X = np.asarray(X, dtype=np.float64)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, np.asarray(faces, dtype=np.int64), self.X, cell="triangle")
        self.nodal = _Nodal(self.mesh, self.X)
        order = np.asarray(self.mesh.topology.original_cell_index, dtype=np.int64)
        outward = np.array([_outward_normal(self.X, f) for f in np.asarray(faces)])
        self.normal = fem.Function(compat.function_space(self.mesh, "DG", 0, (3,)), name="outward_normal")
        self.normal.x.array[:] = outward[order].reshape(-1)
        self.phi = fem.Function(self.nodal.space)
        t1, t2 = _tangent_frame(self.mesh, self.normal)
        F = ufl.grad(self.phi)
        dx = ufl.dx(domain=self.mesh, metadata={"quadrature_degree": 2})
        volume = ufl.dot(self.phi, ufl.cross(F * t1, F * t2)) / 3.0 * dx
        self.forms = (fem.form(volume),
                      fem.form(ufl.derivative(volume, self.phi, ufl.TestFunction(self.nodal.space))))

    def evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """(V, dV/dx (12,)) at deformed positions x (4, 3), (vertex, component) order."""
        self.nodal.set(self.phi, x)
        return fem.assemble_scalar(self.forms[0]), self.nodal.vector(_vector(self.forms[1]))


def _outward_normal(X: np.ndarray, face: np.ndarray) -> np.ndarray:
    """Unit normal of a face of a tetrahedron pointing away from the fourth vertex's side (centroid)."""
    a, b, c = X[face]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    return n if n @ (a - X.mean(axis=0)) > 0 else -n


class BackwardEulerCell:
    """One tetrahedron of ``stvk``: the backward Euler residual in v_{n+1} and what the printed step uses.

    R(v; w) = int rho (v - v_n).w - h (b.w - P(I + grad(q_n + h v)) : grad w) dx + h D[v](w),
    D[v](w) = alpha int rho v.w dx + beta K(q_n)[v](w), K(q_n)[v] = ufl.derivative of f_int at q_n in direction v
    (Rayleigh damping frozen at q_n); Jacobian dR/dv by ``ufl.derivative``. f_int(q)(w) = int P(F(q)) : grad w dx is
    the gradient of the elastic energy, K its derivative.
    """

    def __init__(self, X: np.ndarray, mu: float, lmbda: float, rho: float, alpha: float, beta: float, h: float,
                 body_force: np.ndarray) -> None:
        import forms

        self.X = np.asarray(X, dtype=np.float64)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, np.array([[0, 1, 2, 3]], dtype=np.int64), self.X)
        self.nodal = _Nodal(self.mesh, self.X)
        V = self.nodal.space
        self.qn, self.vn, self.v = fem.Function(V), fem.Function(V), fem.Function(V)
        w, du = ufl.TestFunction(V), ufl.TrialFunction(V)
        law = forms.make_law("stvk", mu=mu, lmbda=lmbda)
        dx = ufl.dx(domain=self.mesh, metadata={"quadrature_degree": 2})
        b = ufl.as_vector([float(c) for c in body_force])

        def f_int(q: Any) -> Any:
            return ufl.inner(law.stress(ufl.Identity(3) + ufl.grad(q)), ufl.grad(w)) * dx

        damping = alpha * rho * ufl.inner(self.v, w) * dx + beta * ufl.derivative(f_int(self.qn), self.qn, self.v)
        residual = (rho * ufl.inner(self.v - self.vn, w) * dx
                    - h * (ufl.inner(b, w) * dx - f_int(self.qn + h * self.v)) + h * damping)
        self.residual = fem.form(residual)
        self.jacobian = fem.form(ufl.derivative(residual, self.v, du))
        self.mass = fem.form(rho * ufl.inner(du, w) * dx)
        self.stiffness = fem.form(ufl.derivative(f_int(self.qn), self.qn, du))
        self.internal = fem.form(f_int(self.qn))
        self.external = fem.form(ufl.inner(b, w) * dx)

    def state(self, qn: np.ndarray, vn: np.ndarray) -> None:
        """Set q_n, v_n (nodal (4, 3) or (12,), (vertex, component) order)."""
        self.nodal.set(self.qn, qn)
        self.nodal.set(self.vn, vn)

    def newton_step(self, v0: np.ndarray) -> np.ndarray:
        """v1 = v0 - (dR/dv(v0))^-1 R(v0): one Newton step of the backward Euler system from v0 (12,)."""
        self.nodal.set(self.v, v0)
        R = self.nodal.vector(_vector(self.residual))
        J = self.nodal.matrix(_dense(self.jacobian))
        return np.asarray(v0, dtype=np.float64).reshape(-1) - np.linalg.solve(J, R)

    def residual_norm(self, v: np.ndarray) -> float:
        self.nodal.set(self.v, v)
        return float(np.linalg.norm(_vector(self.residual)))

    def ingredients(self) -> dict[str, np.ndarray]:
        """M, K(q_n) (12x12) and f_int(q_n), f_ext (12,) at the current state, (vertex, component) order."""
        return {"M": self.nodal.matrix(_dense(self.mass)), "K": self.nodal.matrix(_dense(self.stiffness)),
                "f_int": self.nodal.vector(_vector(self.internal)), "f_ext": self.nodal.vector(_vector(self.external))}
