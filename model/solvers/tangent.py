"""Projected tangent for the "modified Newton" of Klar et al. 2020: dP/dF made positive semidefinite per point.

At every quadrature point the material tangent A = dP/dF, seen as the 9x9 matrix
A[(i,j),(k,l)] = dP_ij/dF_kl (symmetric: the Hessian of psi), is replaced by its nearest
positive semidefinite matrix (forms.projection.project_tangent: negative eigenvalues
clamped at 0). The element stiffness

    K_e = int_e grad(v) : A_proj : grad(du) dx

is then positive semidefinite, so CG with algebraic multigrid can solve the Newton
systems. Only the Jacobian changes; the residual stays exact, so a converged solution is
the same as with the exact tangent (the iteration is a modified Newton, linearly
convergent where A is indefinite at the solution).

A = ufl.diff(P, F) of each material is evaluated at the quadrature points by a dolfinx
Expression (laws with a polar rotation use the problem's own quadrature-point R0, so the
problem's state must be current: call problem.update_state() first), projected with numpy
and stored in a Quadrature-element Function of value shape (9, 9). External terms that
depend on u (follower pressure) keep their exact derivative.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem

from forms.polar import linearised_rotation
from forms.projection import project_tangent
from model import compat
from model.problem import ElasticityProblem

#: Expression evaluation and projection go by blocks of this many cells (bounds the memory of
#: 81 values per point and the eigen-decomposition's work arrays).
CHUNK_CELLS = 4096


def _as_9x9(A: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """A[i,j,k,l] as the 9x9 matrix [(3i+j), (3k+l)]."""
    return ufl.as_matrix([[A[a // 3, a % 3, b // 3, b % 3] for b in range(9)] for a in range(9)])


def _flat(G: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """A 3x3 matrix as the vector of its 9 entries, row by row."""
    return ufl.as_vector([G[a // 3, a % 3] for a in range(9)])


class ProjectedTangent:
    """A_proj = PSD projection of dP/dF at the quadrature points, and the Jacobian form that uses it."""

    def __init__(self, problem: ElasticityProblem) -> None:
        if problem.formulation != "displacement":
            raise ValueError(f"solver.tangent = 'projected' needs formulation = 'displacement', "
                             f"not {problem.formulation!r}")
        self.problem = problem
        msh = problem.domain.mesh
        q = problem.energy_quadrature_degree  # the materials' quadrature (and the polar fields')
        self.space = compat.quadrature_space(msh, q, (9, 9))
        self.A = fem.Function(self.space, name="projected_tangent")
        points = compat.quadrature_points(msh, q)
        self.num_points = points.shape[0]
        rotating = [law for _, law in problem.materials if law.needs_rotation]
        if len(rotating) != len(problem.polar_fields):
            raise RuntimeError("projected tangent: the problem's polar fields do not match its materials")
        polar_fields = iter(problem.polar_fields)  # one per law with a rotation, in material order
        num_owned = msh.topology.index_map(msh.topology.dim).size_local
        owner = np.full(num_owned, -1)
        dofmap = compat.cell_dofs(self.space.dofmap)
        Fv = ufl.variable(problem.F)
        du = ufl.TrialFunction(problem.space)
        flat_grad_du = _flat(ufl.grad(du))
        flat_grad_v = _flat(ufl.grad(problem.v))
        jacobian = 0
        #: per material: (Expression of the 9x9 tangent, owned cells, indices into A.x.array)
        self.blocks: list[tuple[fem.Expression, np.ndarray, np.ndarray]] = []
        for m, (region, law) in enumerate(problem.materials):
            R = None
            if law.needs_rotation:
                R = linearised_rotation(law.rotation_argument(Fv), next(polar_fields).R0)
            tangent = ufl.diff(law.stress(Fv, R), Fv)
            cells = problem.domain.region_cells(region)
            cells = np.asarray(cells[cells < num_owned], dtype=np.int32)  # ghosts: no cell integrals there
            if np.any(owner[cells] >= 0):
                raise ValueError(f"projected tangent: material {m} overlaps material {int(owner[cells].max())}")
            owner[cells] = m
            index = (dofmap[cells][..., None] * 81 + np.arange(81)).reshape(len(cells), -1)
            self.blocks.append((fem.Expression(_as_9x9(tangent), points), cells, index))
            jacobian += ufl.inner(self.A * flat_grad_du, flat_grad_v) * problem.energy_measure(region)
        if problem.external != 0:
            jacobian -= ufl.derivative(problem.external, problem.solution, du)
        self.jacobian_ufl = jacobian
        self.form = fem.form(jacobian)
        self._stamp: np.ndarray | None = None
        #: after each update: number of local quadrature points whose tangent had a negative eigenvalue
        #: (counted only when ``count_negative`` is set: it costs an extra eigenvalue computation)
        self.count_negative = False
        self.negative_points = 0

    def update(self) -> None:
        """A_proj <- project(dP/dF) at the current solution (whose state must be up to date).

        Skipped when the solution is unchanged since the last update.
        """
        current = self.problem.solution.x.array
        if self._stamp is not None and np.array_equal(self._stamp, current):
            return
        values = self.A.x.array
        negative = 0
        for expression, cells, index in self.blocks:
            for start in range(0, len(cells), CHUNK_CELLS):
                chunk = slice(start, start + CHUNK_CELLS)
                A = compat.evaluate(expression, self.problem.domain.mesh, cells[chunk]).reshape(-1, 3, 3, 3, 3)
                if self.count_negative:
                    smallest = np.linalg.eigvalsh(0.5 * (A.reshape(-1, 9, 9) + A.reshape(-1, 9, 9).transpose(0, 2, 1)))
                    scale = np.abs(A).reshape(len(A), -1).max(axis=1)
                    negative += int(np.sum(smallest[:, 0] < -1e-12 * scale))
                values[index[chunk].reshape(-1)] = project_tangent(A).reshape(-1)
        self.negative_points = negative
        self._stamp = current.copy()

    def invalidate(self) -> None:
        """Force the next update to recompute (e.g. after a coefficient such as S changed)."""
        self._stamp = None
