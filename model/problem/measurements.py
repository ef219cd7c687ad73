"""Quantities reported after each step: probe displacements and reactions.

Reaction of a Dirichlet boundary: at a converged state the residual
R = f_int - f_ext vanishes at free dofs, and at the dofs a boundary constrains it
is the force the support exerts on the body; summed per component over the
boundary's dofs (owned dofs only, then reduced over ranks) it is the total force
the boundary exerts on the body. A dof constrained by two boundaries (a node on the edge where a clamped face
meets a symmetry plane, in the component both fix) counts in both: the sum of the boundaries' reactions then
counts its force twice. ``shared_reactions`` splits it: each boundary's force at the dofs only it constrains
(``exclusive``), and the force at the dofs each set of boundaries shares (``shared``, by "A & B"), so that
reactions[A] = exclusive[A] + the shared forces of the sets with A, and exclusive + shared sum to the total
support force once.
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


def _owned_dofs_by_boundary(problem: ElasticityProblem, owned: int) -> dict[str, dict[int, np.ndarray]]:
    """{boundary: {component: owned dofs it constrains}} (entries of one name merged)."""
    out: dict[str, dict[int, np.ndarray]] = {}
    for entry in problem.dirichlet:
        mine = out.setdefault(entry.name, {})
        for comp, dofs in zip(entry.components, entry.dofs):
            dofs = np.asarray(dofs)
            mine[comp] = np.union1d(mine.get(comp, np.empty(0, dtype=dofs.dtype)), dofs[dofs < owned])
    return out


def shared_reactions(problem: ElasticityProblem, residual: PETSc.Vec) -> tuple[dict[str, list[float]],
                                                                                dict[str, list[float]]]:
    """(exclusive, shared): each boundary's force at the dofs only it constrains, and the force at the dofs a set
    of boundaries shares, by "A & B" (names sorted; empty when no dof is shared). Module docstring. Collective."""
    comm = problem.domain.mesh.comm
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    array = residual.array_r
    by_boundary = _owned_dofs_by_boundary(problem, owned)
    names = sorted(by_boundary)
    owners: dict[tuple[int, int], list[str]] = {}  # (component, dof) -> boundaries
    for name in names:
        for comp, dofs in by_boundary[name].items():
            for dof in dofs.tolist():
                owners.setdefault((comp, dof), []).append(name)
    exclusive = {name: np.zeros(3) for name in names}
    shared: dict[str, np.ndarray] = {}
    for (comp, dof), who in owners.items():
        if len(who) == 1:
            exclusive[who[0]][comp] += array[dof]
        else:
            shared.setdefault(" & ".join(who), np.zeros(3))[comp] += array[dof]
    keys = sorted(set().union(*comm.allgather(sorted(shared))))
    totals = comm.allreduce(np.array([exclusive[n] for n in names] + [shared.get(k, np.zeros(3)) for k in keys]),
                            op=MPI.SUM) if names else np.zeros((0, 3))
    return ({n: totals[i].tolist() for i, n in enumerate(names)},
            {k: totals[len(names) + j].tolist() for j, k in enumerate(keys)})


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
