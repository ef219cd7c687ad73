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
