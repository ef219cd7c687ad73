"""Implicit time integration of elastodynamics: M a + D v + f_int(u) = f_ext(t).

Semi-discrete equation of motion (Turchet, thesis chapter 4, eq. 4.3), with the consistent mass
matrix and Rayleigh damping D = a_M M + b_K K(u) (K the tangent stiffness at the current state):

    M a_{n+1} + D(u_{n+1}) v_{n+1} + f_int(u_{n+1}) = f_ext(t_{n+1})

As a residual in the test functions w (added to ElasticityProblem with ``add_residual``):

    R(u; w) = sum_r rho_r a . w dx_r                                      inertia (consistent mass)
            + a_M sum_r rho_r v . w dx_r                                  mass-proportional damping
            + b_K d/ds [f_int(u + s v; w)]_{s=0}                          stiffness-proportional damping
            + f_int(u; w) - f_ext(t; w)                                   the quasi-static residual

where v = v_{n+1}(u) and a = a_{n+1}(u) are the scheme's expressions of the unknown u = u_{n+1}
and of the previous state (u_n, v_n, a_n), held in Functions; the time step dt is a fem.Constant,
so changing it (cut-back) never recompiles. The stiffness-damping term is the directional
derivative of the internal-force form in the direction of the velocity,
ufl.derivative(f_int, u, v) (expanded with a placeholder direction, then v substituted), so it is
K(u_{n+1}) v_{n+1} exactly. The Newton Jacobian stays ufl.derivative of the whole residual:
M / (beta dt^2) + (a_M M + b_K K) gamma / (beta dt) + K + b_K (dK/du) v (Newmark).

Schemes (``scheme=``):

* ``"backward_euler"`` (first order, dissipative; the thesis' implicit Euler without its
  linearisation, solved to convergence)::

      v_{n+1} = (u_{n+1} - u_n) / dt
      a_{n+1} = (v_{n+1} - v_n) / dt

* ``"newmark"`` (beta = 1/4, gamma = 1/2 by default: the average-acceleration / trapezoidal rule,
  second order, unconditionally stable, conserves the energy of linear undamped systems)::

      a_{n+1} = (u_{n+1} - u_n - dt v_n) / (beta dt^2) - (1 / (2 beta) - 1) a_n
      v_{n+1} = v_n + dt ((1 - gamma) a_n + gamma a_{n+1})

  It needs a_0, from the equation of motion at t_0:
  M a_0 = f_ext(t_0) - f_int(u_0) - D(u_0) v_0 (mass matrix, MUMPS LU; a_0 = 0 at Dirichlet dofs,
  i.e. the prescribed motion is assumed unaccelerated at t_0).

* ``"generalized_alpha"`` (Chung & Hulbert 1993; second order, unconditionally stable, numerical
  dissipation of the high frequencies set by the spectral radius at infinity rho_inf in [0, 1])::

      alpha_m = (2 rho_inf - 1) / (rho_inf + 1),  alpha_f = rho_inf / (rho_inf + 1)
      gamma = 1/2 - alpha_m + alpha_f,            beta = (1 - alpha_m + alpha_f)^2 / 4
      M a_{n+1-alpha_m} + D v_{n+1-alpha_f} + f_int(u_{n+1-alpha_f}) = f_ext(t_{n+1-alpha_f})
      x_{n+1-alpha} = (1 - alpha) x_{n+1} + alpha x_n,  Newmark relations between u, v, a at n+1

  The unknown Newton solves for is y = u_{n+1-alpha_f} (so f_int, the polar rotations, follower
  loads and K in the damping are all evaluated at the solution, as the residual forms expect), with
  u_{n+1} = (y - alpha_f u_n) / (1 - alpha_f); loads and Dirichlet data are those of t_{n+1-alpha_f}
  (exact for Dirichlet data linear in time over a step, O(dt^2) otherwise). After a converged step the
  solution is overwritten with u_{n+1} and the load factor set back to that of t_{n+1}, so outputs see
  the end of the step (the residual is zero at the alpha-level state, not there: reactions taken from
  the residual after advance() are approximate). rho_inf = 1 (alpha_m = alpha_f = 1/2) conserves the
  energy of linear systems; rho_inf = 0 annihilates the highest frequencies in one step.

Mixed (Taylor-Hood) formulation: u_n, v_n, a_n are Functions of the mixed space; only their
displacement components enter the forms (the pressure component of u_n is p_n, used to restart a
failed step; those of v_n and a_n are meaningless). The pressure equation stays algebraic (no
inertia, no damping). Rayleigh stiffness damping is refused there (ValueError): K of the mixed
problem couples u and p, and a consistent K v would need a pressure rate; mass damping is allowed.
For a_0 the mass matrix is completed by the pressure mass int a_p q dx (a_p is discarded).

Time-dependent loads and Dirichlet data go through the load factor: ``step_time`` sets
problem.set_load_factor(time_to_load(t_{n+1})) before every step.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms import expand_derivatives

from model import compat
from model.config.dynamics import SCHEMES
from model.problem import ElasticityProblem
from model.solvers.loadstepping import Outcome, give_up_reason
from model.solvers.newton import SolveResult

log = logging.getLogger(__name__)


InitialValue = fem.Function | Callable[[np.ndarray], np.ndarray] | None


# --- the time-discrete problem ----------------------------------------------------------------------

class Dynamics:
    """Inertia and Rayleigh damping added to an ElasticityProblem, and the state (u_n, v_n, a_n).

    Create it after all loads and Dirichlet conditions and before the solver (its residual terms
    are added with problem.add_residual, and the solver compiles the forms). ``density`` is a
    number (the whole body) or {region: rho} ("all" or region names of the mesh; regions missing
    from the map are massless). ``rayleigh = (a_M, b_K)``: D = a_M M + b_K K(u). ``beta``, ``gamma``:
    Newmark's parameters (scheme "newmark"); ``rho_infinity``: scheme "generalized_alpha" (which derives
    its beta and gamma from it).

    The internal-force form used for the stiffness damping is problem.internal at construction
    (material terms and energies added with add_energy, not later residual terms).
    """

    def __init__(self, problem: ElasticityProblem, density: float | Mapping[str, float],
                 scheme: str = "newmark", rayleigh: tuple[float, float] = (0.0, 0.0), dt: float = 1.0,
                 beta: float = 0.25, gamma: float = 0.5, rho_infinity: float = 0.8) -> None:
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {', '.join(SCHEMES)}, got {scheme!r}")
        a_M, b_K = (float(c) for c in rayleigh)
        if not (math.isfinite(a_M) and math.isfinite(b_K)) or a_M < 0.0 or b_K < 0.0:
            raise ValueError(f"Rayleigh coefficients must be finite and >= 0, got {tuple(rayleigh)}")
        if b_K > 0.0 and problem.formulation != "displacement":
            raise ValueError("Rayleigh stiffness damping (b_K > 0) needs the displacement formulation: in the "
                             "mixed formulation K couples u and p and K v would need a pressure rate; use mass "
                             "damping (a_M) only")
        if not (beta > 0.0 and gamma >= 0.0):
            raise ValueError(f"Newmark parameters must have beta > 0 and gamma >= 0, got {beta}, {gamma}")
        if not 0.0 <= rho_infinity <= 1.0:
            raise ValueError(f"rho_infinity must be in [0, 1], got {rho_infinity}")
        #: generalized-alpha weights of the old state (0 for the other schemes)
        self.alpha_m = self.alpha_f = 0.0
        if scheme == "generalized_alpha":
            self.alpha_m = (2.0 * rho_infinity - 1.0) / (rho_infinity + 1.0)
            self.alpha_f = rho_infinity / (rho_infinity + 1.0)
            gamma = 0.5 - self.alpha_m + self.alpha_f
            beta = 0.25 * (1.0 - self.alpha_m + self.alpha_f) ** 2
        self.rho_infinity = float(rho_infinity)
        if not dt > 0.0:
            raise ValueError(f"dt must be > 0, got {dt}")
        densities = {"all": float(density)} if isinstance(density, (int, float)) else dict(density)
        if not densities:
            raise ValueError("density: give a density for the body or for at least one region")
        for region, rho in densities.items():
            error = problem.domain.region_error(region)
            if error:
                raise ValueError(f"density: {error}")
            if not (math.isfinite(rho) and rho >= 0.0):
                raise ValueError(f"density of region {region!r} must be finite and >= 0, got {rho}")
        self.problem = problem
        self.scheme = scheme
        self.beta, self.gamma = float(beta), float(gamma)
        self.rayleigh = (a_M, b_K)
        self.densities = densities
        msh = problem.domain.mesh
        self.comm = msh.comm
        self.mixed = problem.formulation == "mixed"
        space = problem.space
        self.u_n = fem.Function(space, name="u_n")
        self.v_n = fem.Function(space, name="v_n")
        self.a_n = fem.Function(space, name="a_n")
        self.dt = fem.Constant(msh, PETSc.ScalarType(dt))
        self.time = 0.0
        #: energy dissipated by the Rayleigh damping since initialize: sum over steps of dt vbar^T D(u_{n+1}) vbar,
        #: vbar = (v_n + v_{n+1}) / 2 (the exact discrete dissipation of the average-acceleration rule for a
        #: linear system, so kinetic + strain + dissipated is conserved; an estimate for the other schemes)
        self.dissipated_energy = 0.0
        self.initialized = False
        self._rho = {region: fem.Constant(msh, PETSc.ScalarType(rho)) for region, rho in densities.items()}
        self._a_M = fem.Constant(msh, PETSc.ScalarType(a_M))
        self._b_K = fem.Constant(msh, PETSc.ScalarType(b_K))
        self._elastic = problem.internal  # f_int(u; w) before inertia and damping are added
        self._direction = fem.Function(space)  # placeholder direction of the stiffness-damping derivative
        self._work = fem.Function(space)  # velocity slot of the dissipated-power form

        un, vn, an = (self._displacement(f) for f in (self.u_n, self.v_n, self.a_n))
        k = self.dt
        am, af = self.alpha_m, self.alpha_f
        u = problem.u if af == 0.0 else (problem.u - af * un) / (1.0 - af)  # u_{n+1}
        if scheme == "backward_euler":
            velocity = (u - un) / k
            acceleration = (velocity - vn) / k
        else:
            b, g = self.beta, self.gamma
            acceleration = (u - un - k * vn) / (b * k**2) - (1.0 / (2.0 * b) - 1.0) * an
            velocity = vn + k * ((1.0 - g) * an + g * acceleration)
        if scheme == "generalized_alpha":
            acceleration = (1.0 - am) * acceleration + am * an
            velocity = (1.0 - af) * velocity + af * vn
        #: the velocity and acceleration in the residual as UFL expressions of the unknown (v_{n+1}, a_{n+1};
        #: generalized alpha: v_{n+1-alpha_f}, a_{n+1-alpha_m})
        self.velocity = velocity
        self.acceleration = acceleration
        self.inertia_form = self._mass(acceleration, problem.v)
        self.damping_form = self._damping(velocity)
        residual = self.inertia_form if self.damping_form is None else self.inertia_form + self.damping_form
        problem.add_residual(residual, symmetric=self._symmetry(problem))

        kinetic = 0.5 * self._mass(vn, vn)
        self._kinetic_form = fem.form(kinetic)
        self._power_form = None
        damping_work = self._damping(self._displacement(self._work))
        if damping_work is not None:  # w -> work: v^T D v
            test = damping_work.arguments()[0]
            self._power_form = fem.form(ufl.replace(damping_work, {test: self._work}))
        self._potential_form: compat.Form | None = None
        self._mass_solver: tuple[Any, ...] | None = None

    # --- forms ---------------------------------------------------------------------------------------

    def _symmetry(self, problem: ElasticityProblem) -> str | None:
        """Why the derivative of the inertia and damping terms is symmetric (ElasticityProblem.add_residual), or
        None when it may not be.

        With a = c_a u + (old state), v = c_v u + (old state) (c_a, c_v > 0 scalars of the scheme and dt):
        d/du [rho a . w] = c_a M, d/du [a_M rho v . w] = a_M c_v M, and
        d/du [b_K K(u) v . w] = b_K (c_v K(u) + D3f[v](du, w)), where K = df_int/du and D3f[v](du, w) =
        d/du (K(u)[v, w]) [du]. When f_int = dPi/du (every term of problem.internal from an energy: the materials
        and add_energy), K is Pi's Hessian and D3f is Pi's third derivative, symmetric in all three arguments.
        A residual term of unknown symmetry added to the problem before (its internal form, the stiffness damping's
        f_int) makes the damping's derivative unknown: None (with b_K > 0)."""
        if self.rayleigh[1] > 0.0 and any(reason is None for reason in problem.residual_symmetry):
            return None
        return ("inertia and Rayleigh damping: c_a M + a_M c_v M + b_K (c_v K + D3Pi[v]), the mass matrix and "
                "the derivatives of a potential")

    def _displacement(self, f: fem.Function) -> ufl.core.expr.Expr:
        return ufl.split(f)[0] if self.mixed else f

    def _mass(self, a: ufl.core.expr.Expr, w: ufl.core.expr.Expr) -> ufl.Form:
        """sum_r rho_r a . w dx_r"""
        form = 0
        for region, rho in self._rho.items():
            form += rho * ufl.inner(a, w) * self.problem.region_measure(region)
        return form

    def _damping(self, velocity: ufl.core.expr.Expr) -> ufl.Form | None:
        """a_M M v + b_K K(u) v as a form linear in the test functions (None without damping).

        K(u) v = ufl.derivative(f_int, u, v): derived with a placeholder Function direction, derivatives
        expanded, then the placeholder replaced by the velocity expression (UFL cannot differentiate
        in the direction of an expression of the unknown directly).
        """
        a_M, b_K = self.rayleigh
        form = None
        if a_M > 0.0:
            form = self._a_M * self._mass(velocity, self.problem.v)
        if b_K > 0.0:
            directional = expand_derivatives(ufl.derivative(self._elastic, self.problem.solution, self._direction))
            stiffness = self._b_K * ufl.replace(directional, {self._direction: velocity})
            form = stiffness if form is None else form + stiffness
        return form

    # --- state ---------------------------------------------------------------------------------------

    def initialize(self, u0: InitialValue = None, v0: InitialValue = None, time: float = 0.0,
                   load_factor: float | None = None) -> None:
        """Set the initial state at ``time``: u_0 (default: the current solution), v_0 (default 0), a_0.

        u0 and v0: Functions (of the problem's space or of a displacement space) or callables f(x)
        returning the (3, n) values. ``load_factor`` (if given) is set first: f_ext(t_0) and the
        Dirichlet values at t_0, which u_0 takes at the constrained dofs. Newmark: a_0 solves
        M a_0 = f_ext(t_0) - f_int(u_0) - D(u_0) v_0 (a_0 = 0 at Dirichlet dofs); backward Euler
        does not use a_0 (set to 0); generalized alpha as Newmark.
        """
        problem = self.problem
        if load_factor is not None:
            problem.set_load_factor(load_factor)
        if u0 is not None:
            self._assign(problem.solution, u0)
        x = compat.petsc_vector(problem.solution)
        compat.set_bc(x, problem.bcs)
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        self.u_n.x.array[:] = problem.solution.x.array
        self.v_n.x.array[:] = 0.0
        if v0 is not None:
            self._assign(self.v_n, v0)
        self.a_n.x.array[:] = 0.0
        if self.scheme != "backward_euler":
            self._initial_acceleration()
        problem.invalidate_state()
        self.time = float(time)
        self.dissipated_energy = 0.0
        self.initialized = True

    def _assign(self, target: fem.Function, value: fem.Function | Callable[[np.ndarray], np.ndarray]) -> None:
        """target's displacement part <- value (a Function or f(x))."""
        if isinstance(value, fem.Function) and value.function_space == target.function_space:
            target.x.array[:] = value.x.array
            return
        sub = target.sub(0) if self.mixed else target
        sub.interpolate(value)
        target.x.scatter_forward()

    def _initial_acceleration(self) -> None:
        """a_n <- M^-1 (f_ext - f_int(u_n) - D v_n), zero at the Dirichlet dofs (MUMPS LU)."""
        problem = self.problem
        if self._mass_solver is None:
            trial = ufl.TrialFunction(problem.space)
            if self.mixed:
                a_u, a_p = ufl.split(trial)
                bilinear = self._mass(a_u, problem.v) + a_p * problem.q * problem.dx
            else:
                bilinear = self._mass(trial, problem.v)
            mass_form = fem.form(bilinear)
            static = self._elastic
            damping = self._damping(self._displacement(self.v_n))
            if damping is not None:
                static = static + damping
            if problem.external != 0:
                static = static - problem.external
            rhs_form = fem.form(-static)
            M = fem_petsc.create_matrix(mass_form)
            b = fem_petsc.create_vector(rhs_form)
            ksp = PETSc.KSP().create(self.comm)
            ksp.setOperators(M)
            ksp.setType("preonly")
            pc = ksp.getPC()
            pc.setType("lu")
            pc.setFactorSolverType("mumps")
            self._mass_solver = (mass_form, rhs_form, M, b, ksp)
        mass_form, rhs_form, M, b, ksp = self._mass_solver
        problem.update_state()
        M.zeroEntries()
        fem_petsc.assemble_matrix(M, mass_form, bcs=problem.bcs)
        M.assemble()
        with b.localForm() as local:
            local.set(0.0)
        fem_petsc.assemble_vector(b, rhs_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        with b.localForm() as local:
            for entry in problem.dirichlet:
                for dofs in entry.dofs:
                    local.array[dofs] = 0.0
        ksp.setOperators(M)
        ksp.solve(b, compat.petsc_vector(self.a_n))
        if ksp.getConvergedReason() < 0:
            raise RuntimeError(f"initial acceleration: the mass-matrix solve failed (KSP reason "
                               f"{ksp.getConvergedReason()}); is some region massless?")
        self.a_n.x.scatter_forward()

    def load_time(self, t_next: float) -> float:
        """The time whose loads and Dirichlet data the step to t_next uses: t_next, or for generalized
        alpha t_{n+1-alpha_f} = t_n + (1 - alpha_f) dt."""
        return t_next - self.alpha_f * (t_next - self.time)

    def advance(self) -> None:
        """Accept the converged solution as step n+1: update (u_n, v_n, a_n) and the time by dt.

        Generalized alpha: the solution (u_{n+1-alpha_f}) is replaced by u_{n+1}.
        """
        dt = float(self.dt.value)
        problem = self.problem
        un, vn, an = self.u_n.x.array, self.v_n.x.array, self.a_n.x.array
        u = problem.solution.x.array
        if self.alpha_f != 0.0:
            u = (u - self.alpha_f * un) / (1.0 - self.alpha_f)
            problem.solution.x.array[:] = u
            problem.invalidate_state()
        if self.scheme == "backward_euler":
            v = (u - un) / dt
            a = (v - vn) / dt
        else:
            b, g = self.beta, self.gamma
            a = (u - un - dt * vn) / (b * dt**2) - (1.0 / (2.0 * b) - 1.0) * an
            v = vn + dt * ((1.0 - g) * an + g * a)
        if self._power_form is not None:
            self._work.x.array[:] = 0.5 * (v + vn)
            self.dissipated_energy += dt * self._assemble(self._power_form)
        self.u_n.x.array[:] = u
        self.v_n.x.array[:] = v
        self.a_n.x.array[:] = a
        self.time += dt

    def restore(self) -> None:
        """solution <- u_n (after a failed step; in the mixed formulation also p_n)."""
        self.problem.solution.x.array[:] = self.u_n.x.array
        self.problem.invalidate_state()

    def set_dt(self, dt: float) -> None:
        """The next step's dt (a Constant: nothing recompiles)."""
        if not dt > 0.0:
            raise ValueError(f"dt must be > 0, got {dt}")
        self.dt.value = dt

    # --- energies ------------------------------------------------------------------------------------

    def _assemble(self, form: compat.Form) -> float:
        self.problem.update_state()
        return float(self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))

    def kinetic_energy(self) -> float:
        """1/2 int rho v_n . v_n dx over the body (all ranks)."""
        return self._assemble(self._kinetic_form)

    def dissipated_power(self) -> float:
        """v_n^T D(u) v_n = int a_M rho v.v dx + b_K K(u)[v, v] at the current solution (all ranks)."""
        if self._power_form is None:
            return 0.0
        self._work.x.array[:] = self.v_n.x.array
        return self._assemble(self._power_form)

    def potential_energy(self) -> float:
        """Stored internal energy at the current solution (all ranks).

        Displacement formulation: problem.total_energy() (int psi dx, the materials' material_energy) plus
        energies added with add_energy. Mixed: the potential whose stationarity the mixed equations express,
        int W(F) + p g(F) - p^2 / (2 kappa) dx (forms.Law.mixed_energy; equal to int psi dx when p = kappa g;
        no p^2 term when kappa = inf), plus the added
        energies. External loads are not included (follower pressure has no potential).
        """
        problem = self.problem
        if self._potential_form is None:
            energy = 0
            if self.mixed:
                polar = iter(problem.polar_fields)
                for region, law in problem.materials:
                    R = next(polar).rotation if law.needs_rotation else None
                    energy += law.mixed_energy(problem.F, problem.p, R) * problem.energy_measure(region)
            else:
                energy = problem.material_energy
            for extra in problem.extra_energies:
                energy += extra
            self._potential_form = fem.form(energy)
        return self._assemble(self._potential_form)

    def total_energy(self) -> float:
        """kinetic_energy() + potential_energy()."""
        return self.kinetic_energy() + self.potential_energy()

    def destroy(self) -> None:
        if self._mass_solver is not None:
            _, _, M, b, ksp = self._mass_solver
            ksp.destroy()
            M.destroy()
            b.destroy()
            self._mass_solver = None


# --- the time loop -------------------------------------------------------------------------------------

class _Solver(Protocol):
    def solve(self) -> SolveResult: ...


@dataclass(frozen=True)
class TimeStepRecord:
    """One attempted time step: the time it aimed at, its dt, the load factor and the SNES result."""

    time: float
    dt: float
    load_factor: float
    result: SolveResult
    next_increment: float = 0.0  # the step size after this one when it converged (checkpoints)


def step_time(solver: _Solver, dynamics: Dynamics, end_time: float, dt: float,
              on_step: Callable[[TimeStepRecord], None] | None = None,
              time_to_load: Callable[[float], float] = lambda t: t,
              max_cutbacks: int = 8, growth: float = 1.5, increment: float | None = None) -> Outcome:
    """Integrate from dynamics.time to ``end_time`` in steps of ``dt``; True when it got there.

    Each step: dt_k = min(h, end_time - t), problem.set_load_factor(time_to_load(t + dt_k))
    (generalized alpha: of dynamics.load_time(t + dt_k) during the solve, of t + dt_k after it),
    solve from u_n. Converged: dynamics.advance(), then on_step(record) (so the record's state is
    the new one), and h grows by ``growth`` again, never beyond ``dt``. Failed: on_step(record),
    the state and the load factor are restored and h is halved; the run gives up after
    ``max_cutbacks`` failures in a row or when h falls below dt / 2^max_cutbacks (as
    model.solvers.loadstepping). ``solver`` is a NewtonSolver of dynamics.problem (created after dynamics).
    ``increment``: the first step size (a restart's saved cut-back state; default ``dt``).
    """
    if not (end_time > 0.0 and dt > 0.0):
        raise ValueError(f"end_time and dt must be > 0, got {end_time}, {dt}")
    if not dynamics.initialized:
        raise RuntimeError("call dynamics.initialize(...) before step_time (it sets u_0, v_0 and a_0)")
    problem = dynamics.problem
    rank0 = dynamics.comm.rank == 0
    nominal = dt
    increment = nominal if increment is None else float(increment)
    cutbacks = 0
    while dynamics.time < end_time - 1e-12 * max(end_time, 1.0):
        current = dynamics.time
        target = min(current + increment, end_time)
        if end_time - target < 1e-9 * nominal:
            target = end_time
        step = target - current
        dynamics.set_dt(step)
        load = float(time_to_load(target))
        problem.set_load_factor(load if dynamics.alpha_f == 0.0 else float(time_to_load(dynamics.load_time(target))))
        dynamics.restore()  # Newton starts from u_n
        result = solver.solve()
        record = TimeStepRecord(target, step, load, result, min(increment * growth, nominal))
        if result.converged:
            dynamics.advance()
            dynamics.time = target  # no round-off drift
            if dynamics.alpha_f != 0.0:
                problem.set_load_factor(load)
            if rank0:
                log.info("t %.6g  dt %.4g  newton %2d  |R| %.3e", target, step, result.iterations,
                         result.residual_norm)
            if on_step is not None:
                on_step(record)
            cutbacks = 0
            increment = min(increment * growth, nominal)
            continue
        if on_step is not None:
            on_step(record)
        dynamics.restore()
        problem.set_load_factor(float(time_to_load(current)))
        cutbacks += 1
        increment = 0.5 * step  # half the step that failed (which end_time may have shortened)
        reason = give_up_reason("time step", target, current, f"{result.reason}, {result.reason_name}", cutbacks,
                                increment, nominal,                                 max_cutbacks, "dynamics.dt")
        if reason is not None:
            if rank0:
                log.error("giving up: %s", reason)
            return Outcome(False, reason)
        if rank0:
            log.warning("SNES failed at t = %.6g (%s%s); cutting the time step back to %.4g", target,
                        result.reason_name, f"; {result.where}" if getattr(result, "where", "") else "", increment)
    return Outcome(True)
