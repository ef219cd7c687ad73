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
from collections.abc import Callable
from dataclasses import dataclass

from dolfinx import fem, la
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

from model import compat
from model.problem import ElasticityProblem

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


def rigid_body_modes(problem: ElasticityProblem) -> PETSc.NullSpace:
    """The six rigid-body modes of a displacement space, orthonormalised (a near null space for GAMG)."""
    if problem.formulation != "displacement":
        raise ValueError("rigid-body modes: only for the displacement formulation")
    space = problem.space
    imap = space.dofmap.index_map
    bs = space.dofmap.index_map_bs
    owned = imap.size_local
    x = space.tabulate_dof_coordinates()[:owned]
    vectors = [la.create_petsc_vector(imap, bs) for _ in range(6)]
    for i in range(3):  # translations
        with vectors[i].localForm() as local:
            local.array[i:owned * bs:bs] = 1.0
    for k, (a, b) in enumerate(((0, 1), (1, 2), (2, 0))):  # rotations about the axes: u_a = -x_b, u_b = x_a
        with vectors[3 + k].localForm() as local:
            local.array[a:owned * bs:bs] = -x[:, b]
            local.array[b:owned * bs:bs] = x[:, a]
    for i, v in enumerate(vectors):  # modified Gram-Schmidt
        for w in vectors[:i]:
            v.axpy(-w.dot(v), w)
        v.normalize()
    return PETSc.NullSpace().create(vectors=vectors, comm=space.mesh.comm)


class NewtonSolver:
    """SNES on the residual and Jacobian forms of a problem, with a unique options prefix.

    ``tangent``: "exact" (the consistent Jacobian, ufl.derivative of the residual) or
    "projected" (model.solvers.tangent.ProjectedTangent; displacement formulation only).
    """

    def __init__(self, problem: ElasticityProblem, options: dict[str, str | int | float | bool] | None = None,
                 prefix: str | None = None, tangent: str = "exact",
                 bounds: Callable[[PETSc.Vec, PETSc.Vec], None] | None = None) -> None:
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
        self.options = {**DEFAULT_OPTIONS, **(options or {})}
        self.user_options = list(options or {})
        db = PETSc.Options()
        for key, value in self.options.items():
            db[f"{self.prefix}{key}"] = value
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
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
        return SolveResult(
            converged=reason > 0,
            reason=int(reason),
            reason_name=REASONS.get(int(reason), str(reason)),
            iterations=self.snes.getIterationNumber(),
            linear_iterations=self.snes.getLinearSolveIterations(),
            residual_norm=float(self.snes.getFunctionNorm()),
        )

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
