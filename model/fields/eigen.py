"""Quadrature-point storage of an eigen state (Q0, D) of a symmetric X(F), refreshed before each assembly.

forms.spectral.spectral_energy(X, Q0, D, f) then gives UFL the exact value, first and second derivative
of the spectral function sum_i f(eig_i(X)) at the current state, repeated eigenvalues included (see that
module). ``EigenField.update`` evaluates X at the quadrature points of its cells (dolfinx Expression),
runs numpy's batched eigh and writes Q0 and the divided differences D of f'. It is updated wherever the
polar rotations are (ElasticityProblem.update_state, verify's ReferenceEvaluator.evaluate).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from forms.spectral import Derivatives, eigen_state
from model import compat


class EigenField:
    """(Q0, D) of X per quadrature point on the given cells (all local cells by default)."""

    def __init__(self, domain: dmesh.Mesh, X: ufl.core.expr.Expr, quadrature_degree: int, f: Derivatives,
                 cells: np.ndarray | None = None) -> None:
        self.mesh = domain
        self.f = f
        self.space = compat.quadrature_space(domain, quadrature_degree, (3, 3))
        self.Q0 = fem.Function(self.space, name="eigenbasis")
        self.D = fem.Function(self.space, name="eigen_divided_differences")
        points = compat.quadrature_points(domain, quadrature_degree)
        self.expression = fem.Expression(X, points)
        imap = domain.topology.index_map(domain.topology.dim)
        if cells is None:
            cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        self.cells = np.asarray(cells, dtype=np.int32)
        dofs = compat.cell_dofs(self.space.dofmap)[self.cells]
        self._index = (dofs[..., None] * 9 + np.arange(9)).reshape(-1)
        self.Q0.x.array[:] = np.tile(np.eye(3).reshape(-1), self.Q0.x.array.size // 9)
        D0 = eigen_state(np.eye(3)[None], f)[2]  # the state at F = I until the first update
        self.D.x.array[:] = np.tile(D0.reshape(-1), self.D.x.array.size // 9)

    def update(self) -> None:
        """(Q0, D) <- eigen state of X at every quadrature point of the cells, from the current coefficients."""
        if self.cells.size == 0:
            return
        values = compat.evaluate(self.expression, self.mesh, self.cells).reshape(-1, 3, 3)
        Q0, _, D = eigen_state(values, self.f)
        self.Q0.x.array[self._index] = Q0.reshape(-1)
        self.D.x.array[self._index] = D.reshape(-1)
