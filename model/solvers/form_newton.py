"""PETSc SNES on any residual form R(w; v) = 0 with its UFL Jacobian (mixed problems outside ElasticityProblem).

    solver = FormNewton(residual, w, bcs, options={"snes_rtol": 1e-12})
    result = solver.solve()          # w holds the solution; result.converged, .iterations, .reason_name

The Jacobian is ufl.derivative(residual, w) (never hand-coded). SNES owns its own vector x: both callbacks copy
x into w (and call ``before_assembly``, e.g. to refresh quadrature-point states) before assembling, so the
forms are always evaluated at the iterate SNES asks for. Dirichlet conditions enter as in dolfinx's
NonlinearProblem: rows of the Jacobian are identity rows, the residual there is x - g. Defaults: Newton with
full steps (``basic`` line search) and MUMPS LU, every option overridable, under a unique options prefix.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

from model import compat

log = logging.getLogger(__name__)

DEFAULT_OPTIONS: dict[str, Any] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-12,
    "snes_stol": 0.0,
    "snes_max_it": 30,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
_counter = itertools.count()


@dataclass
class FormSolveResult:
    """A solve's outcome: converged, Newton iterations, linear iterations, SNES reason, final |R|."""

    converged: bool
    iterations: int
    linear_iterations: int
    reason: int
    reason_name: str
    residual_norm: float


class FormNewton:
    """Newton (SNES) for ``residual`` = 0 in the Function ``w`` with Dirichlet conditions ``bcs`` (module doc)."""

    def __init__(self, residual: ufl.Form, w: fem.Function, bcs: list[Any] | None = None,
                 options: dict[str, Any] | None = None, prefix: str | None = None,
                 before_assembly: Callable[[], None] | None = None) -> None:
        self.w, self.bcs = w, list(bcs or [])
        self.before_assembly = before_assembly
        self.residual = fem.form(residual)
        self.jacobian = fem.form(ufl.derivative(residual, w, ufl.TrialFunction(w.function_space)))
        self.A = fem_petsc.create_matrix(self.jacobian)
        self.b = fem_petsc.create_vector(self.residual)
        self.x = self.b.duplicate()
        comm = w.function_space.mesh.comm
        self.snes = PETSc.SNES().create(comm)
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        self.prefix = prefix or f"form_newton{next(_counter)}_"
        self.options = {**DEFAULT_OPTIONS, **(options or {})}
        db = PETSc.Options()
        for key, value in self.options.items():
            db[f"{self.prefix}{key}"] = value
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
        self.snes.getKSP().setFromOptions()
        for key in self.options:
            db.delValue(f"{self.prefix}{key}")

    def _copy_in(self, x: PETSc.Vec) -> None:
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with x.localForm() as local:
            self.w.x.array[:] = local.array_r[: len(self.w.x.array)]
        if self.before_assembly is not None:
            self.before_assembly()

    def _residual(self, snes: PETSc.SNES, x: PETSc.Vec, b: PETSc.Vec) -> None:
        self._copy_in(x)
        with b.localForm() as local:
            local.set(0.0)
        fem_petsc.assemble_vector(b, self.residual)
        compat.apply_lifting(b, [self.jacobian], bcs=[self.bcs], x0=[x], alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        compat.set_bc(b, self.bcs, x, -1.0)

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        self._copy_in(x)
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.jacobian, bcs=self.bcs)
        A.assemble()

    def solve(self) -> FormSolveResult:
        """Newton from the current w; w holds the last iterate (the solution when converged). Collective."""
        with self.x.localForm() as local:
            local.array[:] = self.w.x.array
        self.snes.solve(None, self.x)
        reason = int(self.snes.getConvergedReason())
        self._copy_in(self.x)
        self.w.x.scatter_forward()
        result = FormSolveResult(reason > 0, int(self.snes.getIterationNumber()),
                                 int(self.snes.getLinearSolveIterations()), reason,
                                 REASONS.get(reason, str(reason)), float(self.snes.getFunctionNorm()))
        log.debug("%s: %s after %d Newton iterations, |R| = %.3e", self.prefix, result.reason_name,
                  result.iterations, result.residual_norm)
        return result

    def destroy(self) -> None:
        for obj in (self.snes, self.A, self.b, self.x):
            obj.destroy()


__all__ = ["DEFAULT_OPTIONS", "FormNewton", "FormSolveResult"]
