"""Admissibility of a displacement: det F > 0 at every checked point of every material cell.

A state in which some material point has J = det F <= 0 (or a NaN) is folded: the map x = X + u(X)
turns a piece of the body inside out. Its residual may still be small (the mixed formulation enforces
J = 1 only weakly, so Newton can converge to such a state), but it is no solution of the continuum
problem and is never accepted. The check evaluates

    J(X_q) = det(I + grad u(X_q))

at the points of the materials' quadrature rule (those at which the energy is integrated) and, for
displacement degree >= 2, also at the four vertices of each cell (J of a P2 field is a cubic in the
cell: it can dip below zero at a vertex while every quadrature point is positive), on every owned cell
of every material region. The minimum over the points of a cell is that cell's J_min; a NaN counts as
-inf.

``step_limit(direction)``: for a Newton update x - s y, J is evaluated as det(F - s G) with
G = grad y_u at the same points, from one evaluation of F and one of G (no re-assembly): the largest
s in {1, 1/2, 1/4, ...} (at most ``MAX_HALVINGS`` halvings) at which every point stays admissible.
All reductions are over the mesh's communicator: every rank gets the same answer.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from model import compat

#: a Newton direction is halved at most this many times to keep det F > 0 (then it is left to the residual's
#: domain error: the solve fails and the load step is cut back)
MAX_HALVINGS = 12
def _det(F: np.ndarray) -> np.ndarray:
    """det of a stack (..., d, d) (closed form for d = 3)."""
    if F.shape[-1] != 3:
        return np.linalg.det(F) if F.size else np.empty(F.shape[:-2])
    return (F[..., 0, 0] * (F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1])
            - F[..., 0, 1] * (F[..., 1, 0] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 0])
            + F[..., 0, 2] * (F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0]))


class Admissibility:
    """J = det F at the checked points of the material cells of an ElasticityProblem (module docstring)."""

    def __init__(self, problem: Any) -> None:
        self.problem = problem
        domain = problem.domain
        msh = domain.mesh
        self.mesh = msh
        self.comm = msh.comm
        points = compat.quadrature_points(msh, problem.energy_quadrature_degree)
        tdim = msh.topology.dim
        self.dim = tdim
        if problem.degree >= 2:  # the reference simplex's vertices
            points = np.vstack([points, np.vstack([np.zeros(tdim), np.eye(tdim)])])
        self.num_points = len(points)
        self._F = fem.Expression(problem.F, points)
        #: a work function in the solution's space: the Newton direction for step_limit
        self.direction = fem.Function(problem.space)
        y = ufl.split(self.direction)[0] if problem.formulation == "mixed" else self.direction
        self._G = fem.Expression(ufl.grad(y), points)
        owned = msh.topology.index_map(msh.topology.dim).size_local
        regions = [region for region, _ in problem.materials] or ["all"]
        per_region = {}
        for region in regions:
            cells = np.asarray(domain.region_cells(region), dtype=np.int32)
            per_region[region] = np.unique(cells[cells < owned])
        self.cells = np.unique(np.concatenate(list(per_region.values()))) if per_region else np.empty(0, np.int32)
        self.cells = self.cells.astype(np.int32)
        #: per region: the positions of its cells in self.cells
        self.region_index = {r: np.searchsorted(self.cells, c) for r, c in per_region.items()}
        geo = compat.geometry_dofs(msh)[self.cells, : tdim + 1]
        self.centroids = msh.geometry.x[geo].mean(axis=1) if len(self.cells) else np.empty((0, 3))
        #: the solution F was last evaluated at, and that F (_gradients)
        self._stamp: np.ndarray | None = None
        self._last = np.empty(0)

    def _gradients(self) -> np.ndarray:
        """F at the checked points of the local cells: (cells, points, d, d), from the current solution (kept for the
        same solution: the residual's check and the line-search pre-check evaluate it at the same iterate)."""
        d = self.dim
        if not len(self.cells):
            return np.empty((0, self.num_points, d, d))
        current = self.problem.solution.x.array
        if self._stamp is not None and np.array_equal(self._stamp, current):
            return self._last
        self._last = compat.evaluate(self._F, self.mesh, self.cells).reshape(len(self.cells), self.num_points, d, d)
        self._stamp = current.copy()
        return self._last

    def cell_minima(self) -> np.ndarray:
        """J_min of each local material cell (NaN -> -inf), from the current solution."""
        J = _det(self._gradients())
        J = np.where(np.isnan(J), -np.inf, J)
        return J.min(axis=1) if J.size else np.empty(0)

    def minimum(self) -> float:
        """min J over every checked point of the mesh (collective)."""
        local = self.cell_minima()
        return float(self.comm.allreduce(float(local.min()) if local.size else math.inf, op=MPI.MIN))

    def admissible(self) -> bool:
        """Whether J > 0 at every checked point (collective; the same answer on every rank)."""
        return self.minimum() > 0.0

    def report(self) -> dict[str, Any]:
        """{"min_det_F": global minimum, "min_det_F_regions": {region: minimum}, "min_det_F_point": the
        reference centroid of the cell where it is reached}, the same on every rank (collective)."""
        minima = self.cell_minima()
        regions = {}
        for region, index in self.region_index.items():
            local = float(minima[index].min()) if len(index) else math.inf
            regions[region] = _finite(self.comm.allreduce(local, op=MPI.MIN))
        local = (float(minima.min()), *self.centroids[int(np.argmin(minima))]) if minima.size else (math.inf,) * 4
        worst = min(self.comm.allgather(local))
        return {"min_det_F": _finite(worst[0]), "min_det_F_regions": regions,
                "min_det_F_point": [float(c) for c in worst[1:]] if worst[0] != math.inf else None}

    def step_limit(self, direction: Any) -> float:
        """The largest s = 2^-k (k <= MAX_HALVINGS) with det(F - s grad y) > 0 at every checked point, where y
        is the displacement part of ``direction`` (a PETSc vector in the solution's layout); 0.0 when none
        is (collective)."""
        target = compat.petsc_vector(self.direction)
        direction.copy(target)
        target.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        F = self._gradients()
        G = (compat.evaluate(self._G, self.mesh, self.cells).reshape(F.shape) if len(self.cells)
             else np.empty_like(F))
        s = 1.0
        for _ in range(MAX_HALVINGS + 1):
            J = _det(F - s * G)
            ok = bool(np.all(J > 0.0)) if J.size else True
            if self.comm.allreduce(ok, op=MPI.LAND):
                return s
            s *= 0.5
        return 0.0


def _finite(value: float) -> float | str:
    """A float for JSON: -inf (a NaN somewhere) as the string "-inf"."""
    return value if math.isfinite(value) else str(value)
