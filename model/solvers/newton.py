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

Line search (``default_line_search``, the one place the default is set; ``snes_linesearch_type`` in the
options overrides it). When the problem has a potential (ElasticityProblem.potential_reason is None: no
follower pressure, no inertia or damping terms, displacement formulation), Newton minimises

    Pi(u) = sum_r int psi_r(F) dx_r + sum of the added energies - lambda (int t . u ds + int b . u dx)

over the displacements that satisfy the Dirichlet conditions, and SNES gets Pi as its objective
(SNESSetObjective, ``objective``): ``bt`` then backtracks on Pi (Armijo: Pi(x - s dx) <= Pi(x) - 1e-4 s R . dx)
instead of on |R|^2: the Newton step descends |R|^2 too, but only over a short distance far from the solution
on bending and nearly incompressible problems, so that bt on |R|^2 cuts every step short and stalls.
The default there is ``bt`` on Pi; without a potential it is ``basic`` (full Newton steps, the load
stepping's cut-back as the globalisation):
measured over every example and an L-bracket cantilever by benchmarks/line_search.py (docs/solvers.md).
With an objective, a solve that starts off its Dirichlet values (the load factor moved them) first takes one
full Newton step, which puts the constrained dofs onto their values (the Newton matrix has identity rows there):
the minimisation, and the Armijo test, hold on that affine space only. That step counts as one Newton iteration.
Near the solution Pi changes by about |R|^2 / k, down at its round-off, and the Armijo test passes or fails on
noise (DIVERGED_LINE_SEARCH at |R| ~ 1e-7 |R_0|, steps cut for nothing, or cut so short that snes_stol stops SNES
above the tolerance): bt on Pi runs until |R| <= FULL_STEPS_BELOW |R_0| (1e-5), where Newton converges
quadratically, and the solve finishes with full steps from there, within the iterations left, to the original
tolerance (failing as a solve with ``basic`` would when they do not converge). Farther out a failed line search
fails the solve (the load stepping cuts back).
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
from model.problem.admissibility import Admissibility
from model.solvers import linear
from model.solvers.options import petsc_value

log = logging.getLogger(__name__)

#: Defaults: Newton, MUMPS LU. Tolerances tight enough that
#: serial and parallel runs agree to ~1e-10 (quadratic convergence makes them cheap).
#: The line search is not among them: default_line_search picks it per problem.
DEFAULT_OPTIONS: dict[str, str | int | float | bool] = {
    "snes_type": "newtonls",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-12,
    "snes_stol": 1e-12,
    "snes_max_it": 30,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

#: bt on the total potential hands over to full Newton steps once |R| <= FULL_STEPS_BELOW |R_0|
FULL_STEPS_BELOW = 1e-5
#: SNES types with a line search
LINE_SEARCH_SNES = ("newtonls", "vinewtonrsls", "vinewtonssls")
#: line searches that use an objective when SNES has one (the others ignore it)
OBJECTIVE_LINE_SEARCHES = ("bt", "l2")


def default_line_search(problem: ElasticityProblem) -> str:
    """``bt`` (on the total potential) when the problem has one, else ``basic`` (module docstring)."""
    return "bt" if problem.potential_reason() is None else "basic"


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
def set_domain_error(snes: PETSc.SNES) -> bool:
    """SNESSetFunctionDomainError: the state of the residual being evaluated is outside the problem's domain (a
    folded cell); the line search backs off or the solve ends with DIVERGED_FUNCTION_DOMAIN. Called on every rank
    (the caller's test is collective). petsc4py 3.18 lacks it: through the loaded library. False where neither
    is there (the caller then fills the residual with NaN, which fails the line search as well)."""
    method = getattr(snes, "setFunctionDomainError", None)
    if method is not None:
        method()
    elif _PETSC is not None:
        _PETSC.SNESSetFunctionDomainError(ctypes.c_void_p(snes.handle))
    else:
        return False
    return True


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
    #: the state's det F report (Admissibility.report: min_det_F, per region, where) and how many Newton directions
    #: the admissibility limit shortened ("limited_steps")
    admissibility: dict[str, Any] | None = None
    #: a DIVERGED_LINEAR_SOLVE that MUMPS explains (mumps_failure): {"solver", "infog", "memory", "message"}
    linear_failure: dict[str, Any] | None = None


#: MUMPS's INFOG(1) codes of a factorisation that ran out of memory (MUMPS 5 users' guide, section "Error
#: diagnostics"), and what helps
MUMPS_MEMORY = {
    -8: "its integer workspace was too small: raise mat_mumps_icntl_14 (extra workspace, percent)",
    -9: "its real workspace was too small: raise mat_mumps_icntl_14 (extra workspace, percent)",
    -11: "its real workspace for the solve was too small: raise mat_mumps_icntl_14 (extra workspace, percent)",
    -13: "an allocation failed: the machine is out of memory",
    -14: "its integer workspace for the solve was too small: raise mat_mumps_icntl_14",
    -15: "an integer overflow in its workspace: use more ranks",
    -17: "an internal send buffer was too small: raise mat_mumps_icntl_14",
    -19: "the memory limit mat_mumps_icntl_23 (MB per rank) is too small",
    -20: "an internal receive buffer was too small: raise mat_mumps_icntl_14",
}
MEMORY_ADVICE = ("smaller load steps cannot help: [solver] linear = \"iterative\" (far less memory), more memory "
                 "or ranks, or a coarser mesh")


def mumps_failure(ksp: PETSc.KSP) -> dict[str, Any] | None:
    """What MUMPS says of a failed linear solve (its INFOG(1), INFOG(2)): {"solver": "MUMPS", "infog": [i1, i2],
    "memory": whether it ran out of memory (MUMPS_MEMORY), "message"}; None where the preconditioner is not a
    MUMPS factorisation or MUMPS reports no error. Collective (INFOG is global)."""
    try:
        pc = ksp.getPC()
        if pc.getType() not in ("lu", "cholesky") or pc.getFactorSolverType() != "mumps":
            return None
        factor = pc.getFactorMatrix()
        info = [int(factor.getMumpsInfog(1)), int(factor.getMumpsInfog(2))]
    except PETSc.Error:
        return None
    if info[0] >= 0:
        return None
    memory = info[0] in MUMPS_MEMORY
    if memory:
        message = (f"MUMPS ran out of memory in the factorisation (INFOG(1) = {info[0]}, INFOG(2) = {info[1]}: "
                   f"{MUMPS_MEMORY[info[0]]}); {MEMORY_ADVICE}")
    elif info[0] == -10:
        message = ("MUMPS found the Newton matrix numerically singular (INFOG(1) = -10): a rigid motion that nothing "
                   "holds, a zero modulus, or a limit point of the load")
    else:
        message = f"MUMPS failed (INFOG(1) = {info[0]}, INFOG(2) = {info[1]})"
    return {"solver": "MUMPS", "infog": info, "memory": memory, "message": message}


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


class NewtonSolver:
    """SNES on the residual and Jacobian forms of a problem, with a unique options prefix.

    ``tangent``: "exact" (the consistent Jacobian, ufl.derivative of the residual) or
    "projected" (model.solvers.tangent.ProjectedTangent; displacement formulation only).
    ``objective``: give SNES the total potential as its objective (module docstring); None (the default):
    when the problem has one and there are no ``bounds`` (SNES VI with an objective line search fails in PETSc
    with "Cannot change local size of Amat"). True on a problem without one, or with bounds, is a ValueError.
    """

    def __init__(self, problem: ElasticityProblem, options: dict[str, str | int | float | bool] | None = None,
                 prefix: str | None = None, tangent: str = "exact",
                 bounds: Callable[[PETSc.Vec, PETSc.Vec], None] | None = None,
                 defaults: dict[str, str | int | float | bool] | None = None,
                 objective: bool | None = None, matrix: str = "auto") -> None:
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
        linear.check_options(problem, options or {})  # fieldsplit options this problem cannot take
        # DEFAULT_OPTIONS < the linear preset's ``defaults`` (model.solvers.linear) < the user's ``options``
        self.options = {**DEFAULT_OPTIONS, **(defaults or {}), **(options or {})}
        self.options.setdefault("snes_linesearch_type", default_line_search(problem))
        #: "nest" (the mixed Jacobian's blocks, model.solvers.nested) or "aij" (one assembled matrix)
        self.matrix = linear.matrix_kind(problem, matrix, self.options, tangent=tangent,
                                         bounds=bounds is not None)
        self.fields: linear.MixedFields | None = None
        self.nested = None
        self.x = compat.petsc_vector(problem.solution).copy()
        if self.matrix == "nest":
            self._make_nest(matrix)
        if self.matrix == "nest":  # SNES works in the nest's block layout (model.solvers.nested), x and b here
            self.A = self.nested.matrix  # in the mixed space's are the callbacks' own
            self._mixed_x, self._mixed_b = self.x, self.b
            self.x, self.b = self.nested.block_vector(), self.nested.block_vector()
        else:
            self.A = fem_petsc.create_matrix(self.jacobian_form)
        self.near_null_space = None
        if problem.formulation == "displacement":
            self.near_null_space = linear.rigid_body_modes(problem)
            self.A.setNearNullSpace(self.near_null_space)
        self.snes = PETSc.SNES().create(comm)
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        reason = problem.potential_reason()
        if bounds is not None:  # PETSc's VI solvers reject a line search on an objective (the reduced system
            reason = "the VI solvers' line search takes no objective"  # changes size: "Cannot change local size")
        if objective and reason is not None:
            raise ValueError(f"objective: {reason}")
        self.objective = reason is None if objective is None else bool(objective)
        if self.objective:
            self.snes.setObjective(self._objective)
        self.prefix = prefix or f"elasticity{next(_counter)}_"
        self.user_options = list(options or {})
        db = PETSc.Options()
        for key, value in self.options.items():
            value = petsc_value(key, value)  # a viewer switched on by true (options.petsc_value)
            if value is not None:
                db[f"{self.prefix}{key}"] = value
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
        # fieldsplit (mixed formulation): the u and p index sets, the u block's near null space, Schur's Sp
        if self.fields is not None:
            self.fields.configure(self.snes.getKSP().getPC(), self.options)
        else:
            self.fields = linear.configure_fields(self.snes, problem, self.options)
        #: linear iterations of each Newton iteration of the last solve
        self.linear_monitor = linear.LinearMonitor(self.snes)
        # the options stay in the database until destroy(): PETSc reads some of them only when the
        # preconditioner is set up in the first solve (MUMPS's mat_mumps_*, multigrid levels, ...)
        unknown = [k for k in unused_options(self.prefix, self.user_options) if not read_later(k)]
        if unknown:
            self._delete_options()
            self.destroy_petsc()
            from model.errors import ConfigError

            raise ConfigError(f"solver.petsc_options.{unknown[0]}: PETSc does not use this option with the "
                              f"solver it configures (misspelt, or for another solver type)")
        self.unused_options: list[str] = []
        self._checked = False
        #: det F > 0 at every material point (model.problem.admissibility): a trial state that folds a cell is a
        #: domain error for SNES, and every Newton direction is shortened (halved) until it keeps det F > 0
        self.admissibility = Admissibility(problem)
        #: how often the admissibility limit shortened a Newton direction in the last solve
        self.limited_steps = 0
        #: min det F at the last residual evaluation (collective)
        self.last_min_det_F = math.inf
        #: the det F report of the last trial state that folded a cell in this solve (None: none did)
        self.folded_trial: dict[str, Any] | None = None
        if self.snes.getType() in LINE_SEARCH_SNES:
            self.snes.setLineSearchPreCheck(self._precheck)
        # variable bounds (SNES VI solvers, e.g. contact): bounds(xl, xu) fills them before every solve
        self.bounds = bounds
        self.xl = self.x.duplicate() if bounds is not None else None
        self.xu = self.x.duplicate() if bounds is not None else None

    def _make_nest(self, requested: str) -> None:
        """The nested Jacobian and its fields; where a block's form cannot be separated (nested.nested_jacobian
        gives None): the assembled matrix under "auto", a ConfigError under "nest"."""
        from model.solvers.nested import nested_jacobian

        made = nested_jacobian(self.problem)
        if made is not None:
            self.fields, self.nested = made
            return
        if requested == "nest":
            from model.errors import ConfigError

            raise ConfigError("solver.matrix: \"nest\": a block of the Jacobian cannot be separated (its form "
                              "keeps terms without its own arguments); use \"auto\" or \"aij\"")
        self.matrix = "aij"

    def _mixed(self, x: PETSc.Vec) -> PETSc.Vec:
        """x in the mixed space's layout: x itself, or (nest) its permutation, in a work vector of the solver."""
        if self.nested is None:
            return x
        self.nested.to_mixed(x, self._mixed_x)
        return self._mixed_x

    def _copy_in(self, x: PETSc.Vec) -> None:
        x = self._mixed(x)
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
        self.last_min_det_F = self.admissibility.minimum()
        folded = not self.last_min_det_F > 0.0  # folded (or NaN): the line search backs off, or the solve fails
        if folded:  # where (for the failure message; SNES keeps the last admissible iterate, not this one)
            self.folded_trial = self.admissibility.report()
        out = b
        if self.nested is not None:  # the mixed space's layout here, the block layout for SNES at the end
            x, b = self._mixed_x, self._mixed_b
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, self.residual_form)
        bcs = self.problem.bcs
        compat.apply_lifting(b, [self.jacobian_form], bcs=[bcs], x0=[x], alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        for coupling in self.problem.couplings:  # contact between bodies: Pi^T dPi_c/dz (body_contact)
            coupling.add_residual(b)
        compat.set_bc(b, bcs, x, -1.0)
        if self.nested is not None:
            self.nested.to_block(b, out)
        if folded and not set_domain_error(snes):
            out.set(math.nan)

    def _objective(self, snes: PETSc.SNES, x: PETSc.Vec) -> float:
        """Pi(x), the total potential (ElasticityProblem.total_potential), the same on every rank."""
        self._copy_in(x)
        return self.problem.total_potential()

    def _precheck(self, x: PETSc.Vec, y: PETSc.Vec, *args: Any) -> bool:
        """SNES line-search pre-check: shorten the Newton direction y (the update is x - y) to y 2^-k, the longest
        that keeps det F > 0 at every material point (Admissibility.step_limit). Returns whether y changed."""
        self._copy_in(x)
        s = self.admissibility.step_limit(self._mixed(y))
        if s >= 1.0 or s == 0.0:  # s == 0: no halving helps; the residual's domain error fails the solve
            return False
        y.scale(s)
        self.limited_steps += 1
        log.debug("Newton direction shortened to %.3g of its length to keep det F > 0", s)
        return True

    @property
    def line_search(self) -> dict[str, str]:
        """The line search SNES uses and its merit function, for summary.json: {"type": ..., "merit": ...} with
        merit "total_potential" (bt or l2 with the objective), "residual_norm" (bt or l2 without) or "none"."""
        # from the options SNES was configured with (petsc4py 3.18 has no SNES.getLineSearch)
        kind = str(self.options["snes_linesearch_type"]) if self.snes.getType() in LINE_SEARCH_SNES else "none"
        if kind in OBJECTIVE_LINE_SEARCHES:
            merit = "total_potential" if self.objective else "residual_norm"
        else:
            merit = "none"
        return {"type": kind, "merit": merit}

    def _off_dirichlet(self) -> bool:
        """Whether self.x differs from the Dirichlet values (the load factor has moved them), on any rank."""
        x = self._mixed(self.x)
        gap = x.duplicate()
        gap.set(0.0)
        compat.set_bc(gap, self.problem.bcs, x, -1.0)  # x - g on the constrained dofs
        largest = gap.norm(PETSc.NormType.NORM_INFINITY)
        scale = max(x.norm(PETSc.NormType.NORM_INFINITY), largest)
        gap.destroy()
        return largest > 1e-14 * scale

    def _dirichlet_step(self) -> tuple[float, int]:
        """One full Newton step from self.x (the first iteration SNES would take with ``basic``): afterwards
        the constrained dofs hold their values, and the minimisation of Pi is on the affine space. Returns |R|
        at self.x before the step (Dirichlet rows: x - g), the |R_0| of the solve, and the step's linear iterations."""
        self._residual(self.snes, self.x, self.b)
        initial_norm = self.b.norm()
        self._jacobian(self.snes, self.x, self.A, self.A)
        ksp = self.snes.getKSP()
        ksp.setOperators(self.A, self.A)
        dx = self.x.duplicate()
        ksp.solve(self.b, dx)
        self.x.axpy(-1.0, dx)
        dx.destroy()
        return float(initial_norm), int(ksp.getIterationNumber())

    def _finish_with_full_steps(self, used: int, target: float, switch: float) -> tuple[int, int]:
        """Full Newton steps from the last iterate of bt on Pi, at most the iterations left, to the tolerance of the
        solve, ``target`` = max(atol, rtol |R_0|), when bt on Pi stopped at |R| <= ``switch`` = FULL_STEPS_BELOW |R_0|
        (by that tolerance, or by a failed line search or a step cut to nothing, snes_stol): near the solution Pi
        changes by ~|R|^2 / k, down at its round-off, the Armijo test passes or fails on noise and cuts good steps.
        Returns the Newton and linear iterations it took ((0, 0) when it did not run)."""
        norm = self.snes.getFunctionNorm()
        reason = self.snes.getConvergedReason()
        stopped = (PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS, PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE,
                   PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH, PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE)
        if reason not in stopped or norm <= target or norm > switch:
            return 0, 0
        max_it = self.snes.getTolerances()[3]
        log.debug("bt on Pi stopped at |R| = %.3e after %d iterations (%s): full steps to %.3e", norm, used,
                  REASONS.get(int(reason), reason), target)
        key = f"{self.prefix}snes_linesearch_type"
        db = PETSc.Options()
        db[key] = "basic"
        try:
            self.snes.setFromOptions()
            self.snes.setTolerances(atol=target, max_it=max(max_it - used, 1))
            self.snes.solve(None, self.x)
            return self.snes.getIterationNumber(), self.snes.getLinearSolveIterations()
        finally:
            db[key] = self.options["snes_linesearch_type"]
            self.snes.setFromOptions()  # the configured line search and tolerances again

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        self._copy_in(x)
        if self.projected is not None:
            self.projected.update()
        if self.nested is not None:  # A is the nest over the blocks
            self.nested.assemble()
            return
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.jacobian_form, bcs=self.problem.bcs)
        A.assemble()
        if self.problem.couplings:  # contact between bodies: the couplings through the closest points
            nonzeros = A.getInfo()["nz_allocated"]
            for coupling in self.problem.couplings:
                coupling.add_jacobian(A)
            A.assemble()
            if A.getInfo()["nz_allocated"] != nonzeros:  # the pattern grew (MatAXPY replaced A's storage): factor
                snes.getKSP().getPC().reset()  # anew (PETSc 3.22 reused the old symbolic factorisation: MUMPS error)

    def solve(self) -> SolveResult:
        """Newton from the current solution; the solution holds the last iterate afterwards."""
        if self.nested is not None:
            self.nested.to_block(compat.petsc_vector(self.problem.solution), self.x)
        else:
            compat.petsc_vector(self.problem.solution).copy(self.x)
        if self.projected is not None:  # the tangent of the initial state (targets may have changed)
            self._copy_in(self.x)
            self.projected.invalidate()
            self.projected.update()
        if self.bounds is not None:
            self.bounds(self.xl, self.xu)
            self.snes.setVariableBounds(self.xl, self.xu)
        extra = dirichlet_linear = 0
        self.linear_monitor.reset()
        self.limited_steps = 0
        self.folded_trial: dict[str, Any] | None = None
        tolerances = self.snes.getTolerances()
        rtol, atol, _, max_it = tolerances
        on_pi = self.objective and self.line_search["merit"] == "total_potential"
        if on_pi:  # bt on Pi down to FULL_STEPS_BELOW |R_0|, then full steps (_finish_with_full_steps)
            if self._off_dirichlet():
                initial_norm, dirichlet_linear = self._dirichlet_step()
                self.linear_monitor.add(dirichlet_linear)
                extra = 1
            else:
                self._residual(self.snes, self.x, self.b)
                initial_norm = float(self.b.norm())
            target = max(atol, rtol * initial_norm)
            self.snes.setTolerances(atol=max(target, FULL_STEPS_BELOW * initial_norm), max_it=max(max_it - extra, 1))
        try:
            self.snes.solve(None, self.x)
        finally:
            self.snes.setTolerances(*tolerances)
        iterations = self.snes.getIterationNumber() + extra
        linear_iterations = self.snes.getLinearSolveIterations() + dirichlet_linear
        if on_pi:
            more, linear = self._finish_with_full_steps(iterations, target, FULL_STEPS_BELOW * initial_norm)
            iterations += more
            linear_iterations += linear
        if not self._checked:
            self._checked = True
            self.unused_options = unused_options(self.prefix, self.user_options)
            for key in self.unused_options:
                log.warning("PETSc did not use the option %s (solver.petsc_options)", key)
        self._copy_in(self.x)
        reason = self.snes.getConvergedReason()
        admissibility = {**self.admissibility.report(), "limited_steps": self.limited_steps}
        if reason <= 0 and self.folded_trial is not None:
            admissibility["folded_trial"] = self.folded_trial
        if reason > 0 and not (isinstance(admissibility["min_det_F"], float) and admissibility["min_det_F"] > 0):
            # never accepted, whatever the residual says (a state SNES took without evaluating its residual)
            log.warning("a converged state has det F = %s at %s: refused", admissibility["min_det_F"],
                        admissibility["min_det_F_point"])
            reason = PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN
        where = self.residual_location() if reason <= 0 else None
        linear_failure = None
        if reason == PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE:
            linear_failure = mumps_failure(self.snes.getKSP())
            if linear_failure is not None and self.problem.domain.mesh.comm.rank == 0:
                log.warning("%s", linear_failure["message"])
        return SolveResult(
            converged=reason > 0,
            reason=int(reason),
            reason_name=REASONS.get(int(reason), str(reason)),
            iterations=iterations,
            linear_iterations=linear_iterations,
            residual_norm=float(self.snes.getFunctionNorm()),
            where=str(where) if where is not None else "",
            largest_residual=where.as_dict() if where is not None else None,
            admissibility=admissibility,
            linear_failure=linear_failure,
        )

    def residual_location(self) -> ResidualLocation | None:
        """Where the residual SNES sees at the current iterate (Dirichlet rows: the conditions' misfit) is largest
        among the free displacement dofs (residual_location)."""
        b = self.b.duplicate()
        try:
            self._residual(self.snes, self.x, b)
            return residual_location(self.problem, self._mixed_b if self.nested is not None else b)
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
        self.destroy_petsc()
        for coupling in self.problem.couplings:  # their matrices (BodyContact.destroy: made again when needed)
            coupling.destroy()

    def destroy_petsc(self) -> None:
        """Destroy the solver's own PETSc objects (SNES, matrices, vectors, near null space, fields)."""
        self.snes.destroy()
        if self.nested is not None:
            self.nested.destroy()  # the nest (self.A) and its blocks
            self._mixed_b.destroy()
            self._mixed_x.destroy()
        else:
            self.A.destroy()
        self.b.destroy()
        self.x.destroy()
        for bound in (getattr(self, "xl", None), getattr(self, "xu", None)):  # none yet in __init__'s refusal
            if bound is not None:
                bound.destroy()
        if self.near_null_space is not None:
            self.near_null_space.destroy()
        if self.fields is not None:
            self.fields.destroy()


def free_garbage(comm: MPI.Comm) -> None:
    """Collect Python's garbage, then destroy the parallel PETSc objects waiting on comm's garbage list.

    petsc4py (3.18 on) does not destroy an object of a communicator of more than one rank when the collector
    frees it (the ranks may free it at different times): it goes onto the communicator's list and is destroyed by
    the collective PETSc.garbage_cleanup. Give the mesh's communicator (dolfinx duplicates the one it was given)
    while the mesh lives: a list whose communicator is freed stays allocated. Collective."""
    import gc

    gc.collect()
    PETSc.garbage_cleanup(comm)

