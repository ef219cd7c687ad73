"""Quadrature-point storage of the polar rotation R0 = polar(M), refreshed before each assembly.

forms.polar.linearised_rotation(M, R0) then gives UFL the exact value and first
derivative of R*(M) (see that module). ``PolarField.update`` evaluates M at the
quadrature points of its cells (dolfinx Expression), runs the batched SVD with
the rotation variant, and writes R0.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from forms.polar import linearised_rotation, polar_rotation
from model import compat


class PolarField:
    """R0 = polar(M) per quadrature point on the given cells (all local cells by default)."""

    def __init__(self, domain: dmesh.Mesh, M: ufl.core.expr.Expr, quadrature_degree: int,
                 cells: np.ndarray | None = None) -> None:
        self.mesh = domain
        self.space = compat.quadrature_space(domain, quadrature_degree, (3, 3))
        self.R0 = fem.Function(self.space, name="polar_rotation")
        points = compat.quadrature_points(domain, quadrature_degree)
        self.num_points = points.shape[0]
        self.expression = fem.Expression(M, points)
        tdim = domain.topology.dim
        imap = domain.topology.index_map(tdim)
        if cells is None:
            cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        self.cells = np.asarray(cells, dtype=np.int32)
        dofs = compat.cell_dofs(self.space.dofmap)[self.cells]
        self._index = (dofs[..., None] * 9 + np.arange(9)).reshape(-1)
        identity = np.tile(np.eye(3).reshape(-1), self.R0.x.array.size // 9)
        self.R0.x.array[:] = identity
        self.rotation = linearised_rotation(M, self.R0)

    def update(self) -> None:
        """R0 <- polar(M) at every quadrature point of the cells, from the current coefficients."""
        if self.cells.size == 0:
            return
        values = compat.evaluate(self.expression, self.mesh, self.cells)
        M = values.reshape(-1, 3, 3)
        self.R0.x.array[self._index] = polar_rotation(M).reshape(-1)
