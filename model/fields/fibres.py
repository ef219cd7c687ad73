"""Fibre directions a0 per cell (DG0 vector Functions), three ways (thesis 4.4.2 and the works it cites):

- constant: the unit vector from an origin point to an insertion point;
- computed: solve  -div grad phi = 0  on the region, phi = 0 on the origin surface, phi = 1 on the
  insertion surface, zero flux elsewhere (Choi & Blemker; Saito et al.); a0 = grad phi / |grad phi|,
  evaluated at the cell midpoints;
- from an array or .npy file of shape (num_cells, 3) in the mesh's cell order.
Every direction is normalised and checked (finite, non-zero).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.domain import Domain


def unit_vectors(values: np.ndarray, where: str = "a0") -> np.ndarray:
    """values (n, 3) normalised; ValueError naming ``where`` for non-finite or (near) zero rows."""
    values = np.asarray(values, dtype=np.float64).reshape(-1, 3)
    norm = np.linalg.norm(values, axis=1)
    bad = ~np.isfinite(norm) | (norm < 1e-12)
    if np.any(bad):
        raise ValueError(f"{where}: fibre direction {int(np.flatnonzero(bad)[0])} is zero or not finite")
    return values / norm[:, None]


class FibreField:
    """a0 on the cells of a region as a DG0 vector Function (zero elsewhere).

    Several regions may share one Function (pass ``function``): each sets its own cells.
    """

    def __init__(self, domain: Domain, region: str = "all", name: str = "fibre_direction",
                 function: fem.Function | None = None) -> None:
        self.domain = domain
        self.cells = domain.region_cells(region)
        if function is None:
            function = fem.Function(compat.function_space(domain.mesh, "DG", 0, (3,)), name=name)
        space = function.function_space
        self.function = function
        dofs = compat.cell_dofs(space.dofmap).reshape(-1)[self.cells]
        self._index = (dofs[:, None] * 3 + np.arange(3)).reshape(-1)

    def set_values(self, values: np.ndarray) -> FibreField:
        """a0 of each of the region's cells (len(cells), 3), normalised."""
        self.function.x.array[self._index] = unit_vectors(values).reshape(-1)
        self.function.x.scatter_forward()
        return self

    def constant(self, origin: Sequence[float], insertion: Sequence[float]) -> FibreField:
        """a0 = (insertion - origin) / |insertion - origin| in every cell."""
        direction = unit_vectors(np.subtract(insertion, origin), "insertion - origin")[0]
        return self.set_values(np.tile(direction, (len(self.cells), 1)))

    def from_cell_array(self, array: np.ndarray) -> FibreField:
        """a0 from an array over all cells of the mesh (num_cells_global, 3) in mesh cell order."""
        msh = self.domain.mesh
        array = np.asarray(array, dtype=np.float64)
        num_global = msh.topology.index_map(msh.topology.dim).size_global
        if array.shape != (num_global, 3):
            raise ValueError(f"a0: per-cell fibre directions must have shape ({num_global}, 3), got {array.shape}")
        original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)
        return self.set_values(array[original[self.cells]])

    def laplace(self, origin: str, insertion: str, region: str | Sequence[str] = "all",
                potential: fem.Function | None = None) -> FibreField:
        """a0 = grad phi / |grad phi|, phi harmonic on the region(s), 0 on ``origin``, 1 on ``insertion``.

        ``potential``: a phi already solved (solve_laplace), e.g. shared by several regions.
        """
        phi = potential if potential is not None else solve_laplace(self.domain, origin, insertion, region)
        grad = fem.Expression(ufl.grad(phi), np.zeros((1, 3)) + 0.25)  # P1: grad is constant per cell
        values = compat.evaluate(grad, self.domain.mesh, self.cells).reshape(-1, 3)
        return self.set_values(values)


def region_dofs(V: fem.FunctionSpace, domain: Domain, names: Sequence[str]) -> np.ndarray:
    """The local dofs (owned and ghost) of the scalar space V that a cell of the regions ``names`` touches on
    any rank. Collective.

    A rank sees only its own cells: a node on the border between ranks may touch region cells of the other
    rank only, so the local test is completed by a sum over the ranks (reverse scatter, then forward).
    """
    cells = np.concatenate([domain.region_cells(n) for n in names])
    marker = fem.Function(V)
    marker.x.array[np.unique(compat.cell_dofs(V.dofmap)[cells])] = 1.0
    vector = compat.petsc_vector(marker)
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return np.flatnonzero(marker.x.array > 0.0).astype(np.int32)


def solve_laplace(domain: Domain, origin: str, insertion: str, region: str | Sequence[str] = "all") -> fem.Function:
    """phi in P1: -div grad phi = 0 on the region's cells, phi = 0 / 1 on the named surfaces, zero flux
    elsewhere; dofs outside the region(s) are held at 0 (they are not coupled to it).

    ``region``: "all", one region name or several. ValueError if a surface has no node in the region(s).
    """
    msh = domain.mesh
    V = compat.function_space(msh, "Lagrange", 1)
    phi, q = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=msh, subdomain_data=domain.cell_tags, metadata={"quadrature_degree": 1})
    names = [region] if isinstance(region, str) else list(region)
    if "all" in names:
        names = ["all"]
    dx_region = dx if names == ["all"] else dx(tuple(c for n in names for c in domain.regions[n]))
    # the zero term over every cell puts the dofs outside the region into the sparsity pattern, so that
    # their Dirichlet rows (phi = 0) get a diagonal entry
    zero_outside = fem.Constant(msh, PETSc.ScalarType(0.0)) * phi * q * dx
    a = fem.form(ufl.inner(ufl.grad(phi), ufl.grad(q)) * dx_region + zero_outside)
    L = fem.form(fem.Constant(msh, PETSc.ScalarType(0.0)) * q * dx_region)
    fdim = msh.topology.dim - 1
    zero, one = fem.Function(V), fem.Function(V)
    one.x.array[:] = 1.0
    bcs = [fem.dirichletbc(zero, fem.locate_dofs_topological(V, fdim, domain.boundary_facets(origin))),
           fem.dirichletbc(one, fem.locate_dofs_topological(V, fdim, domain.boundary_facets(insertion)))]
    num_local = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    inside = np.arange(num_local, dtype=np.int32)
    if names != ["all"]:
        inside = region_dofs(V, domain, names)
        outside = np.setdiff1d(np.arange(num_local, dtype=np.int32), inside)
        bcs.append(fem.dirichletbc(zero, outside))
    owned = V.dofmap.index_map.size_local
    for name, bc in ((origin, bcs[0]), (insertion, bcs[1])):
        dofs = bc.dof_indices()[0]
        touching = np.intersect1d(dofs[dofs < owned], inside)
        if msh.comm.allreduce(len(touching), op=MPI.SUM) == 0:
            raise ValueError(f"the surface {name!r} has no node in region {' + '.join(names)}")
    A = fem_petsc.assemble_matrix(a, bcs=bcs)
    A.assemble()
    b = fem_petsc.assemble_vector(L)
    compat.apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    compat.set_bc(b, bcs)
    ksp = PETSc.KSP().create(msh.comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    solution = fem.Function(V, name="fibre_potential")
    ksp.solve(b, compat.petsc_vector(solution))
    solution.x.scatter_forward()
    ksp.destroy()
    A.destroy()
    b.destroy()
    return solution


__all__ = ["FibreField", "region_dofs", "solve_laplace", "unit_vectors"]
