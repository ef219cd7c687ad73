"""PETSc SNES for an ElasticityProblem: Newton with line search, every option overridable.

SNES owns its own vector x. Both callbacks copy x into the solution Function
(and refresh quadrature-point state such as polar rotations) before assembling,
so the Jacobian is always evaluated at the iterate SNES asks for.

``bounds(xl, xu)``, when given, fills the lower and upper bound vectors before every solve
(SNESVISetVariableBounds; for the VI solvers ``snes_type = "vinewtonrsls"``, e.g. contact).

``tangent = "projected"`` replaces the consistent tangent by its per-quadrature-point
positive semidefinite projection (model.solvers.tangent, the "modified Newton" of Klar et al. 2020):
the residual is unchanged, the Newton matrices are positive semidefinite, so CG with
algebraic multigrid (``ksp_type = "cg"``, ``pc_type = "gamg"``) can solve them. For the
displacement formulation the matrix carries the rigid-body modes as its near null space
(used by GAMG, ignored by LU).
"""

from __future__ import annotations

import ctypes
import itertools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.problem import ElasticityProblem
from model.solvers import linear

log = logging.getLogger(__name__)

#: Defaults: Newton with backtracking line search, MUMPS LU. Tolerances tight enough that
#: serial and parallel runs agree to ~1e-10 (quadratic convergence makes them cheap).
DEFAULT_OPTIONS: dict[str, str | int | float | bool] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-12,
    "snes_stol": 1e-12,
    "snes_max_it": 30,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

#: Jacobians NewtonSolver can use: the consistent one, or its PSD projection (model.solvers.tangent).
TANGENTS = ("exact", "projected")

_counter = itertools.count()

#: SNES converged-reason codes by value (PETSc 3.18), for messages.
REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}


def _petsc_library() -> ctypes.CDLL | None:
    """The PETSc shared library this process has loaded (for PetscOptionsUsed, which petsc4py lacks)."""
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "/libpetsc" in line and ".so" in line.split()[-1]}
    except OSError:
        return None
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
            lib.PetscOptionsUsed  # noqa: B018 - raises AttributeError if absent
            return lib
        except (OSError, AttributeError):
            continue
    return None


_PETSC = _petsc_library()
#: option families PETSc reads only during the first solve, or at its end (viewers, reasons)
_READ_LATER = ("mat_", "mg_", "fieldsplit_", "sub_", "pc_gamg_", "pc_mg_", "pc_factor_")
_READ_LATER_WORDS = ("view", "converged_reason", "monitor")


def read_later(key: str) -> bool:
    """True for options PETSc may legitimately read only in the first solve."""
    return key.startswith(_READ_LATER) or any(word in key for word in _READ_LATER_WORDS)


def unused_options(prefix: str, keys: list[str]) -> list[str]:
    """The keys (without prefix) PETSc has not read so far; empty when the query is unavailable."""
    if _PETSC is None:
        return []
    out = []
    for key in keys:
        used = ctypes.c_int(0)
        if _PETSC.PetscOptionsUsed(None, f"{prefix}{key}".encode(), ctypes.byref(used)) == 0 and not used.value:
            out.append(key)
    return out


@dataclass(frozen=True)
class SolveResult:
    converged: bool
    reason: int
    reason_name: str
    iterations: int
    linear_iterations: int
    residual_norm: float
    #: a failed solve: where its last residual is largest, in words ("largest residual 3.1e2 at (...), in region
    #: 'belly', on boundary 'cap'"), and as data (ResidualLocation.as_dict); empty / None otherwise
    where: str = ""
    largest_residual: dict[str, Any] | None = None


@dataclass(frozen=True)
class ResidualLocation:
    """The displacement dof with the largest |residual| (Dirichlet dofs excluded): its value, node, component and
    the named regions and boundaries the node lies in and on."""

    value: float
    point: tuple[float, float, float]
    component: int
    regions: tuple[str, ...]
    boundaries: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        value = self.value if math.isfinite(self.value) else str(self.value)  # JSON has no inf or nan
        return {"value": value, "point": list(self.point), "component": self.component,
                "region": ", ".join(self.regions) or None, "boundary": ", ".join(self.boundaries) or None}

    def __str__(self) -> str:
        text = (f"largest residual {self.value:.3g} ({'xyz'[self.component]} component) at "
                f"({', '.join(f'{c:.6g}' for c in self.point)})")
        if self.regions:
            text += f", in region {' and '.join(repr(r) for r in self.regions)}"
        if self.boundaries:
            text += f", on boundary {' and '.join(repr(b) for b in self.boundaries)}"
        return text


def _point_on_triangles(point: np.ndarray, triangles: np.ndarray, tol: float) -> np.ndarray:
    """For (n, 3, 3) triangle vertex coordinates: is ``point`` on each (within ``tol``)?"""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2, d = b - a, c - a, point - a
    normal = np.cross(e1, e2)
    area2 = np.linalg.norm(normal, axis=1)
    safe = np.where(area2 > 0, area2, 1.0)
    off_plane = np.abs(np.einsum("ij,ij->i", d, normal)) / safe
    # barycentric coordinates of the projection
    d11, d12, d22 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2), np.einsum("ij,ij->i", e2, e2))
    d1, d2 = np.einsum("ij,ij->i", d, e1), np.einsum("ij,ij->i", d, e2)
    det = np.where(d11 * d22 - d12**2 > 0, d11 * d22 - d12**2, 1.0)
    s, t = (d22 * d1 - d12 * d2) / det, (d11 * d2 - d12 * d1) / det
    slack = tol / np.sqrt(np.maximum(d11, d22))
    return (off_plane <= tol) & (s >= -slack) & (t >= -slack) & (s + t <= 1 + slack) & (area2 > 0)


def residual_location(problem: ElasticityProblem, residual: PETSc.Vec) -> ResidualLocation | None:
    """Where |residual| is largest among the displacement dofs that are not Dirichlet dofs (the pressure
    equations of the mixed formulation are volumes, not forces: left out), reduced over ranks.

    Values within 1e-3 relative of the largest count as ties and go to the smallest (x, y, z, component), so
    that the answer does not depend on the partition (a failed iterate's symmetric peaks differ in the last
    digits from one partition to another; the location is a hint, its value the largest).
    The node's regions are those of the cells that contain it, its boundaries those of the
    tagged facets it lies on (both gathered over ranks). None when there is no such dof.
    """
    msh = problem.domain.mesh
    comm = msh.comm
    space = problem.displacement_space
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    with residual.localForm() as local_form:
        values = np.abs(np.array(local_form.array[:owned]))
    constrained = np.zeros(owned, dtype=bool)
    for entry in problem.dirichlet:
        for dofs in entry.dofs:
            constrained[dofs[dofs < owned]] = True
    candidates = []  # (|R|, x, y, z, component) of each owned, free displacement dof
    for component in range(3):
        collapsed, parent = space.sub(component).collapse()
        parent = np.asarray(parent)
        mine = parent < owned
        dofs = parent[mine]
        x = collapsed.tabulate_dof_coordinates()[: len(parent)][mine]
        free = ~constrained[dofs]
        r = np.nan_to_num(values[dofs[free]], nan=np.inf)
        candidates.append(np.column_stack([r, x[free], np.full(free.sum(), component)]))
    table = np.vstack(candidates) if candidates else np.empty((0, 5))
    largest = comm.allreduce(float(np.max(table[:, 0])) if len(table) else -1.0, op=MPI.MAX)
    if largest < 0:
        return None
    near = table[table[:, 0] >= largest * (1 - 1e-3)] if math.isfinite(largest) else table[np.isinf(table[:, 0])]
    best = tuple(min(map(tuple, near[:, 1:]))) if len(near) else (math.inf,) * 4
    best = min(comm.allgather(best))
    point = np.array(best[:3])
    x = msh.geometry.x
    tol = 1e-8 * comm.allreduce(float(np.linalg.norm(np.ptp(x, axis=0))) if len(x) else 0.0, op=MPI.MAX)
    domain = problem.domain
    regions: set[str] = set()
    cells = compat.colliding_cells(msh, point).links(0)
    tags = domain.cell_tags
    values_of = dict(zip(tags.indices, tags.values))
    for cell in cells:
        code = values_of.get(int(cell))
        regions |= {name for name, codes in domain.regions.items() if code in codes}
    boundaries: set[str] = set()
    fdim = msh.topology.dim - 1
    facets = domain.facet_tags
    if len(facets.indices):
        nodes = compat.entity_geometry(msh, fdim, facets.indices)
        on = _point_on_triangles(point, msh.geometry.x[nodes[:, :3]], tol)
        for code in set(np.asarray(facets.values)[on].tolist()):
            boundaries |= {name for name, codes in domain.boundaries.items() if code in codes}
    regions = set().union(*comm.allgather(regions))
    boundaries = set().union(*comm.allgather(boundaries))
    return ResidualLocation(largest, (float(point[0]), float(point[1]), float(point[2])), int(best[3]),
                            tuple(sorted(regions)), tuple(sorted(boundaries)))


def rigid_body_modes(problem: ElasticityProblem) -> PETSc.NullSpace:
    """The six rigid-body modes of a displacement space, orthonormalised (a near null space for GAMG; the mixed
    formulation's u block gets them through model.solvers.linear.MixedFields)."""
    if problem.formulation != "displacement":
        raise ValueError("rigid-body modes: only for the displacement formulation")
    return PETSc.NullSpace().create(vectors=linear.vector_rigid_body_modes(problem.space), comm=problem.space.mesh.comm)


class NewtonSolver:
    """SNES on the residual and Jacobian forms of a problem, with a unique options prefix.

    ``tangent``: "exact" (the consistent Jacobian, ufl.derivative of the residual) or
    "projected" (model.solvers.tangent.ProjectedTangent; displacement formulation only).
    """

    def __init__(self, problem: ElasticityProblem, options: dict[str, str | int | float | bool] | None = None,
                 prefix: str | None = None, tangent: str = "exact",
                 bounds: Callable[[PETSc.Vec, PETSc.Vec], None] | None = None,
                 defaults: dict[str, str | int | float | bool] | None = None) -> None:
        if tangent not in TANGENTS:
            raise ValueError(f"solver.tangent: {tangent!r} is not one of {', '.join(TANGENTS)}")
        self.problem = problem
        comm = problem.domain.mesh.comm
        self.tangent = tangent
        self.projected = None
        if tangent == "projected":
            from model.solvers.tangent import ProjectedTangent

            self.projected = ProjectedTangent(problem)
            self.residual_form = fem.form(problem.residual_form)  # the exact Jacobian is never compiled
            self.jacobian_form = self.projected.form
        else:
            self.residual_form, self.jacobian_form = problem.forms
        self.b = fem_petsc.create_vector(self.residual_form)
        self.A = fem_petsc.create_matrix(self.jacobian_form)
        self.near_null_space = None
        if problem.formulation == "displacement":
            self.near_null_space = rigid_body_modes(problem)
            self.A.setNearNullSpace(self.near_null_space)
        self.x = compat.petsc_vector(problem.solution).copy()
        self.snes = PETSc.SNES().create(comm)
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        self.prefix = prefix or f"elasticity{next(_counter)}_"
        linear.check_options(problem, options or {})  # fieldsplit options this problem cannot take
        # DEFAULT_OPTIONS < the linear preset's ``defaults`` (model.solvers.linear) < the user's ``options``
        self.options = {**DEFAULT_OPTIONS, **(defaults or {}), **(options or {})}
        self.user_options = list(options or {})
        db = PETSc.Options()
        for key, value in self.options.items():
            db[f"{self.prefix}{key}"] = value
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
        # fieldsplit (mixed formulation): the u and p index sets, the u block's near null space, Schur's Sp
        self.fields = linear.configure_fields(self.snes, problem, self.options)
        #: linear iterations of each Newton iteration of the last solve
        self.linear_monitor = linear.LinearMonitor(self.snes)
        # the options stay in the database until destroy(): PETSc reads some of them only when the
        # preconditioner is set up in the first solve (MUMPS's mat_mumps_*, multigrid levels, ...)
        unknown = [k for k in unused_options(self.prefix, self.user_options) if not read_later(k)]
        if unknown:
            self._delete_options()
            from model.errors import ConfigError

            raise ConfigError(f"solver.petsc_options.{unknown[0]}: PETSc does not use this option with the "
                              f"solver it configures (misspelt, or for another solver type)")
        self.unused_options: list[str] = []
        self._checked = False
        # variable bounds (SNES VI solvers, e.g. contact): bounds(xl, xu) fills them before every solve
        self.bounds = bounds
        self.xl = self.x.duplicate() if bounds is not None else None
        self.xu = self.x.duplicate() if bounds is not None else None

    def _copy_in(self, x: PETSc.Vec) -> None:
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        solution = compat.petsc_vector(self.problem.solution)
        x.copy(solution)
        solution.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        self.problem.update_state()

    def _residual(self, snes: PETSc.SNES, x: PETSc.Vec, b: PETSc.Vec) -> None:
        # With the projected tangent, the lifting of Dirichlet increments uses the projected matrix
        # of the last Jacobian evaluation (of the initial state at the first residual of a solve):
        # the same linearisation as the Newton matrix. It vanishes once x satisfies the conditions.
        self._copy_in(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, self.residual_form)
        bcs = self.problem.bcs
        compat.apply_lifting(b, [self.jacobian_form], bcs=[bcs], x0=[x], alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        compat.set_bc(b, bcs, x, -1.0)

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        self._copy_in(x)
        if self.projected is not None:
            self.projected.update()
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.jacobian_form, bcs=self.problem.bcs)
        A.assemble()

    def solve(self) -> SolveResult:
        """Newton from the current solution; the solution holds the last iterate afterwards."""
        compat.petsc_vector(self.problem.solution).copy(self.x)
        if self.projected is not None:  # the tangent of the initial state (targets may have changed)
            self._copy_in(self.x)
            self.projected.invalidate()
            self.projected.update()
        if self.bounds is not None:
            self.bounds(self.xl, self.xu)
            self.snes.setVariableBounds(self.xl, self.xu)
        self.snes.solve(None, self.x)
        if not self._checked:
            self._checked = True
            self.unused_options = unused_options(self.prefix, self.user_options)
            for key in self.unused_options:
                log.warning("PETSc did not use the option %s (solver.petsc_options)", key)
        self._copy_in(self.x)
        reason = self.snes.getConvergedReason()
        where = self.residual_location() if reason <= 0 else None
        return SolveResult(
            converged=reason > 0,
            reason=int(reason),
            reason_name=REASONS.get(int(reason), str(reason)),
            iterations=self.snes.getIterationNumber(),
            linear_iterations=self.snes.getLinearSolveIterations(),
            residual_norm=float(self.snes.getFunctionNorm()),
            where=str(where) if where is not None else "",
            largest_residual=where.as_dict() if where is not None else None,
        )

    def residual_location(self) -> ResidualLocation | None:
        """Where the residual SNES sees at the current iterate (Dirichlet rows: the conditions' misfit) is largest
        among the free displacement dofs (residual_location)."""
        b = self.b.duplicate()
        try:
            self._residual(self.snes, self.x, b)
            return residual_location(self.problem, b)
        finally:
            b.destroy()

    def unconstrained_residual(self) -> PETSc.Vec:
        """R(u) = f_int - f_ext with no Dirichlet rows replaced.

        At a solution its entries at constrained dofs are the forces the supports exert.
        """
        self.problem.update_state()
        b = fem_petsc.assemble_vector(self.residual_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def _delete_options(self) -> None:
        db = PETSc.Options()
        for key in self.options:
            db.delValue(f"{self.prefix}{key}")

    def destroy(self) -> None:
        self._delete_options()
        self.snes.destroy()
        self.A.destroy()
        self.b.destroy()
        self.x.destroy()
        for bound in (self.xl, self.xu):
            if bound is not None:
                bound.destroy()
        if self.near_null_space is not None:
            self.near_null_space.destroy()
        if self.fields is not None:
            self.fields.destroy()
