"""Projective Dynamics (Bouaziz et al. 2014) for shape targeting: local/global iterations of one load step.

For shape targeting alone (Klar et al. 2020, eq. 1; law ``shape_target`` with kappa = 0) the
total potential is

    Pi(u, R) = sum_r int_r mu_r ||F - R S||^2 dx - lambda W_ext(u),   F = I + grad u,

and min over R in SO(3) per quadrature point gives back psi(F). Pi is quadratic in u for
fixed R, so block-coordinate descent alternates

- local step: R0 = polar(F S) at every quadrature point (model.fields.polar.PolarField.update,
  the machinery the Newton solver uses), which minimises Pi over R;
- global step: the minimiser over u with R fixed, the linear problem
  K u = int 2 mu (R0 S - I) : grad v dx + lambda f_ext,   K = sum_r int_r 2 mu_r grad du : grad v dx,
  with the Dirichlet conditions. K does not depend on R, u or lambda: it is assembled and
  factorised once (KSP preonly + MUMPS LU by default) for the whole run.

The global step is computed in increment form. The gradient of the quadratic in u at the
current iterate is the full nonlinear residual r(u) = int 2 mu (F - R0 S) : grad v dx - lambda f_ext
(by the envelope theorem, with R0 current), and K is its Hessian, so the minimiser is
u_new = u - K^-1 r(u) (exactly the linear problem above; at Dirichlet dofs the increment is
0, the iterate having been given the Dirichlet values first). Each iteration therefore
costs one polar update, one residual assembly and one pair of triangular solves, and the
residual it computes is the one the convergence test uses: the residual of the Newton
solver (model.solvers.newton), Dirichlet rows zeroed. Pi decreases monotonically (block-coordinate
descent) for dead loads; a follower pressure is lagged (evaluated at the current iterate),
which keeps the fixed point but not the monotonicity.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass

import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.shape_target import ShapeTarget
from model import compat
from model.problem import ElasticityProblem
from model.solvers.newton import REASONS, SolveResult

log = logging.getLogger(__name__)

#: Defaults of the local/global iteration and of its linear solver (any ``ksp_*``/``pc_*``
#: PETSc option may be given instead; K is symmetric positive definite, so CG + GAMG also works).
DEFAULT_OPTIONS: dict[str, str | int | float | bool] = {
    "pd_max_iterations": 1000,
    "pd_rtol": 1e-8,
    "pd_atol": 1e-12,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

_LINEAR_PREFIXES = ("ksp_", "pc_", "mat_")
_counter = itertools.count()
_Reason = PETSc.SNES.ConvergedReason


@dataclass(frozen=True)
class ProjectiveDynamicsResult(SolveResult):
    """A SolveResult (reason codes as SNES's) with the residual norm before each global step and at the end.

    ``energy_history`` (total potential Pi after each local step) is filled when the solver records it.
    """

    residual_history: tuple[float, ...] = ()
    energy_history: tuple[float, ...] = ()


def check_projective_dynamics(problem: ElasticityProblem) -> None:
    """Raise ValueError (naming solver.method) unless every material is shape_target with kappa = 0."""
    if problem.formulation != "displacement":
        raise ValueError("solver.method: projective_dynamics needs formulation = 'displacement'")
    for i, (_, law) in enumerate(problem.materials):
        if not isinstance(law, ShapeTarget) or law.kappa != 0:
            what = law.name if not isinstance(law, ShapeTarget) else f"shape_target with kappa = {law.kappa}"
            raise ValueError(f"solver.method: projective_dynamics needs every material to be shape_target with "
                             f"kappa = 0; material[{i}] is {what}")


class ProjectiveDynamicsSolver:
    """Local/global iterations for one load step (drop-in for model.solvers.newton.NewtonSolver in step_loads).

    ``options``: ``pd_max_iterations`` (global steps per load step), ``pd_rtol`` (stop when
    ||r|| <= pd_rtol ||r_0||, r_0 the residual at the start of the load step once the Dirichlet
    values are imposed), ``pd_atol`` (or ||r|| <= pd_atol), and PETSc options of the linear
    solver (``ksp_*``, ``pc_*``, ``mat_*``); any other key (e.g. ``snes_*``) is ignored.
    ``record_energy``: also evaluate Pi after every local step (dead loads only; for tests).
    """

    def __init__(self, problem: ElasticityProblem, options: dict[str, str | int | float | bool] | None = None,
                 prefix: str | None = None, record_energy: bool = False) -> None:
        check_projective_dynamics(problem)
        self.problem = problem
        self.options = {**DEFAULT_OPTIONS, **(options or {})}
        self.max_iterations = int(self.options["pd_max_iterations"])
        self.rtol = float(self.options["pd_rtol"])
        self.atol = float(self.options["pd_atol"])
        self.record_energy = record_energy
        comm = problem.domain.mesh.comm
        self.residual_form = fem.form(problem.residual_form)
        du = ufl.TrialFunction(problem.space)
        stiffness = sum(2.0 * law.mu * ufl.inner(ufl.grad(du), ufl.grad(problem.v)) * problem.region_measure(region)
                        for region, law in problem.materials)
        self.stiffness_form = fem.form(stiffness)
        self.K = fem_petsc.assemble_matrix(self.stiffness_form, bcs=problem.bcs)  # BC rows: identity
        self.K.assemble()
        self.b = fem_petsc.create_vector(self.residual_form)
        self.du = self.b.duplicate()
        self.ksp = PETSc.KSP().create(comm)
        self.ksp.setOperators(self.K)  # once: the factorisation is reused by every solve
        self.prefix = prefix or f"projective_dynamics{next(_counter)}_"
        db = PETSc.Options()
        linear = {k: v for k, v in self.options.items() if k.startswith(_LINEAR_PREFIXES)}
        for key, value in linear.items():
            db[f"{self.prefix}{key}"] = value
        self.ksp.setOptionsPrefix(self.prefix)
        self.ksp.setFromOptions()
        for key in linear:
            db.delValue(f"{self.prefix}{key}")
        self._work_form: compat.Form | None = None
        #: how often K was assembled (1: never re-assembled)
        self.stiffness_assemblies = 1

    # --- the pieces of one iteration ------------------------------------------------------------

    def _impose_dirichlet(self) -> None:
        x = compat.petsc_vector(self.problem.solution)
        compat.set_bc(x, self.problem.bcs)
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _residual(self) -> float:
        """Local step (polar update) and the residual with Dirichlet rows zeroed; returns its norm.

        The iterate satisfies the Dirichlet conditions, so this is the Newton solver's residual
        (whose lifting term vanishes there).
        """
        problem = self.problem
        problem.update_state()
        b = self.b
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, self.residual_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        x = compat.petsc_vector(problem.solution)
        compat.set_bc(b, problem.bcs, x, -1.0)
        return b.norm()

    def _global_step(self) -> int:
        """u <- u - K^-1 r: the minimiser of Pi over u with the rotations fixed. Returns KSP iterations."""
        self.ksp.solve(self.b, self.du)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            raise RuntimeError(f"projective dynamics: the global solve failed (KSP reason {reason})")
        x = compat.petsc_vector(self.problem.solution)
        x.axpy(-1.0, self.du)
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return max(self.ksp.getIterationNumber(), 1)

    def potential_energy(self) -> float:
        """Pi = int psi dx - lambda W_ext(u) at the current solution (dead loads only)."""
        problem = self.problem
        if self._work_form is None:
            work = 0
            if problem.external != 0:
                if problem.solution in problem.external.coefficients():
                    raise ValueError("projective dynamics: no potential energy with a follower pressure")
                work = ufl.replace(problem.external, {problem.v: problem.u})
            self._work_form = fem.form(work) if work != 0 else None
        energy = problem.total_energy()
        if self._work_form is not None:
            comm = problem.domain.mesh.comm
            energy -= comm.allreduce(fem.assemble_scalar(self._work_form), op=MPI.SUM)
        return energy

    # --- one load step --------------------------------------------------------------------------

    def solve(self) -> ProjectiveDynamicsResult:
        """Local/global iterations from the current solution (Dirichlet values imposed first)."""
        self._impose_dirichlet()
        history: list[float] = []
        energies: list[float] = []
        linear = 0
        reason = _Reason.DIVERGED_MAX_IT
        for iteration in range(self.max_iterations + 1):
            norm = self._residual()
            history.append(norm)
            if self.record_energy:
                energies.append(self.potential_energy())
            if not math.isfinite(norm):
                reason = _Reason.DIVERGED_FNORM_NAN
                break
            if norm <= self.atol:
                reason = _Reason.CONVERGED_FNORM_ABS
                break
            if norm <= self.rtol * history[0]:
                reason = _Reason.CONVERGED_FNORM_RELATIVE
                break
            if iteration == self.max_iterations:
                break
            linear += self._global_step()
        return ProjectiveDynamicsResult(
            converged=reason > 0,
            reason=int(reason),
            reason_name=REASONS.get(int(reason), str(reason)),
            iterations=len(history) - 1,
            linear_iterations=linear,
            residual_norm=history[-1],
            residual_history=tuple(history),
            energy_history=tuple(energies),
        )

    def unconstrained_residual(self) -> PETSc.Vec:
        """R(u) = f_int - f_ext with no Dirichlet rows replaced (the supports' forces at a solution)."""
        self.problem.update_state()
        b = fem_petsc.assemble_vector(self.residual_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def destroy(self) -> None:
        self.ksp.destroy()
        self.K.destroy()
        self.b.destroy()
        self.du.destroy()
