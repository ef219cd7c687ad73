"""PETSc SNES for an ElasticityProblem: Newton with line search, every option overridable.

SNES owns its own vector x. Both callbacks copy x into the solution Function
(and refresh quadrature-point state such as polar rotations) before assembling,
so the Jacobian is always evaluated at the iterate SNES asks for.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass

from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

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

_counter = itertools.count()

#: SNES converged-reason codes by value (PETSc 3.18), for messages.
REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}


@dataclass(frozen=True)
class SolveResult:
    converged: bool
    reason: int
    reason_name: str
    iterations: int
    linear_iterations: int
    residual_norm: float


class NewtonSolver:
    """SNES on the residual and Jacobian forms of a problem, with a unique options prefix."""

    def __init__(self, problem: ElasticityProblem, options: dict[str, str | int | float | bool] | None = None,
                 prefix: str | None = None) -> None:
        self.problem = problem
        comm = problem.domain.mesh.comm
        self.residual_form, self.jacobian_form = problem.forms
        self.b = fem_petsc.create_vector(self.residual_form)
        self.A = fem_petsc.create_matrix(self.jacobian_form)
        self.x = problem.solution.vector.copy()
        self.snes = PETSc.SNES().create(comm)
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        self.prefix = prefix or f"elasticity{next(_counter)}_"
        self.options = {**DEFAULT_OPTIONS, **(options or {})}
        db = PETSc.Options()
        for key, value in self.options.items():
            db[f"{self.prefix}{key}"] = value
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
        for key in self.options:
            db.delValue(f"{self.prefix}{key}")

    def _copy_in(self, x: PETSc.Vec) -> None:
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(self.problem.solution.vector)
        self.problem.solution.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        self.problem.update_state()

    def _residual(self, snes: PETSc.SNES, x: PETSc.Vec, b: PETSc.Vec) -> None:
        self._copy_in(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, self.residual_form)
        bcs = self.problem.bcs
        fem_petsc.apply_lifting(b, [self.jacobian_form], bcs=[bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(b, bcs, x, -1.0)

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        self._copy_in(x)
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.jacobian_form, bcs=self.problem.bcs)
        A.assemble()

    def solve(self) -> SolveResult:
        """Newton from the current solution; the solution holds the last iterate afterwards."""
        self.problem.solution.vector.copy(self.x)
        self.snes.solve(None, self.x)
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

    def destroy(self) -> None:
        self.snes.destroy()
        self.A.destroy()
        self.b.destroy()
        self.x.destroy()
