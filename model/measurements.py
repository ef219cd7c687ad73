"""Quantities reported after each step: probe displacements and reactions.

Reaction of a Dirichlet boundary: at a converged state the residual
R = f_int - f_ext vanishes at free dofs, and at the dofs a boundary constrains it
is the force the support exerts on the body; summed per component over the
boundary's dofs (owned dofs only, then reduced over ranks) it is the total force
the boundary exerts on the body. A dof constrained by two boundaries counts in both.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.problem import ElasticityProblem


class Probes:
    """Point evaluation of a vector Function at fixed reference points, the same on every rank."""

    def __init__(self, domain_mesh, points: dict[str, tuple[float, float, float]]) -> None:
        self.mesh = domain_mesh
        self.names = list(points)
        self.points = np.array([points[n] for n in self.names], dtype=np.float64).reshape(-1, 3)
        comm = domain_mesh.comm
        tdim = domain_mesh.topology.dim
        colliding = compat.colliding_cells(domain_mesh, self.points)
        num_owned = domain_mesh.topology.index_map(tdim).size_local
        self.cells = np.full(len(self.names), -1, dtype=np.int32)
        for i in range(len(self.names)):
            links = colliding.links(i)
            owned = links[links < num_owned]
            if len(owned):
                self.cells[i] = owned[0]
        found = np.where(self.cells >= 0, comm.rank, comm.size)
        self.owner = np.empty_like(found)
        comm.Allreduce(found, self.owner, op=MPI.MIN)
        self.missing = [n for n, o in zip(self.names, self.owner) if o == comm.size]

    def evaluate(self, function: fem.Function) -> dict[str, list[float]]:
        """{name: value} of the function at each probe point (each point evaluated by one rank)."""
        comm = self.mesh.comm
        size = function.function_space.dofmap.index_map_bs
        values = np.zeros((len(self.names), size))
        mine = np.flatnonzero(self.owner == comm.rank)
        if len(mine):
            values[mine] = function.eval(self.points[mine], self.cells[mine]).reshape(len(mine), size)
        total = np.zeros_like(values)
        comm.Allreduce(values, total, op=MPI.SUM)
        return {n: total[i].tolist() for i, n in enumerate(self.names)}


def reactions(problem: ElasticityProblem, residual: PETSc.Vec) -> dict[str, list[float]]:
    """{boundary: [Fx, Fy, Fz]}: total force each Dirichlet boundary exerts on the body."""
    comm = problem.domain.mesh.comm
    imap = problem.space.dofmap.index_map
    owned = imap.size_local * problem.space.dofmap.index_map_bs
    array = residual.array_r
    out: dict[str, list[float]] = {}
    for entry in problem.dirichlet:
        force = np.zeros(3)
        for comp, dofs in zip(entry.components, entry.dofs):
            force[comp] = array[dofs[dofs < owned]].sum()
        total = comm.allreduce(force, op=MPI.SUM)
        out[entry.name] = (np.asarray(out.get(entry.name, np.zeros(3))) + total).tolist()
    return out


class Volumes:
    """Current volumes v_r = int_r J dX of every named region and of the whole body ("all").

    ``reference`` holds the volumes at u = 0 (int_r 1 dX) and ``areas`` the reference area of every
    named boundary (int_b 1 dA): the denominators of nominal stresses and volume changes.
    """

    def __init__(self, problem: ElasticityProblem) -> None:
        import ufl

        domain = problem.domain
        self.comm = domain.mesh.comm
        J = ufl.det(problem.F)
        one = fem.Constant(domain.mesh, PETSc.ScalarType(1.0))
        names = ["all", *sorted(domain.regions)]
        self._forms = {n: fem.form(J * problem.region_measure(n)) for n in names}
        self.reference = {n: self._sum(fem.form(one * problem.region_measure(n))) for n in names}
        self.areas = {n: self._sum(fem.form(one * problem.boundary_measure(n))) for n in sorted(domain.boundaries)}

    def _sum(self, form: compat.Form) -> float:
        return float(self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))

    def current(self) -> dict[str, float]:
        """{region: int_r J dX} at the current solution (all ranks)."""
        return {n: self._sum(f) for n, f in self._forms.items()}
