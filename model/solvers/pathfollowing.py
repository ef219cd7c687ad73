"""Path following past load maxima: arc length (Crisfield) and cavity-volume control.

Under load control the load factor lambda is prescribed and Newton solves R(u, lambda) = 0 for u. At a load
maximum (a limit point) dlambda/du = 0: beyond it there is no equilibrium at a larger load, and no load step,
however small, passes it. Path following makes lambda an unknown and adds one scalar equation g(u, lambda) = 0
that the path crosses transversally:

    R(u, lambda) = f_int(u) - lambda f(u) = 0         (f: the loads at lambda = 1: tractions, body forces and the
                                                       follower pressure p J F^-T N, which depends on u)
    g(u, lambda) = 0

    arc length (Crisfield's cylindrical form):  g = |u - u_n|^2 - ds^2   (displacement dofs only: the pressure of
                                                                           the mixed formulation has other units)
    cavity-volume control:                      g = V(u) - V_target,
                                                V(u) = -(1/3) int_Gamma (x - x_0) . n da
                                                     = -(1/3) int_Gamma0 (X + u - x_0) . J F^-T N dA

(V: the volume of the cavity that the loaded boundary Gamma encloses together with planes through x_0, e.g.
the symmetry planes of an octant or the base plane of a truncated ventricle, where (x - x_0) . n = 0; N is the
body's outward normal, which points into the cavity.) Newton on the pair, with K = dR/du (UFL's Jacobian at
the current lambda, load stiffness included) and c = dg/du (UFL's derivative of V, or 2 (u - u_n)):

    K du - f dlambda = -R,   c . du = -g
    K a = R,  K b = f  (one factorisation, two solves)
    dlambda = (c . a - g) / (c . b),   du = -a + dlambda b

(the bordering algorithm). Each update is shortened to keep det F > 0 at every material point
(model.problem.admissibility), and a step whose Newton iterations fail is halved and regrown as in load
stepping. The predictor: arc length along the tangent b / |b| (its sign continuing the previous step's
direction: the path turns back in lambda at a maximum and the step follows it); volume control the
linearised volume, dlambda = (V_target - V) / (c . b). The first arc length is that of the first load step
under load control (|b| / steps). Dirichlet values must not move with lambda (they are not part of f).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.solvers.loadstepping import Outcome, StepRecord
from model.solvers.newton import NewtonSolver, SolveResult

log = logging.getLogger(__name__)

CONTROLS = ("load", "arc_length", "volume")
#: Newton tolerance of a path step: |R| <= RTOL max(|lambda f|, |R| of the predictor), |g| <= RTOL scale of g
RTOL = 1e-9


def cavity_volume_form(problem: Any, boundary: str, origin: np.ndarray | list[float]) -> ufl.Form:
    """V(u) = -(1/3) int_Gamma0 (X + u - x_0) . J F^-T N dA over the named boundary (module docstring)."""
    msh = problem.domain.mesh
    X = ufl.SpatialCoordinate(msh)
    N = ufl.FacetNormal(msh)
    F = problem.F
    x0 = ufl.as_vector([float(c) for c in origin])
    return -(1.0 / 3.0) * ufl.inner(X + problem.u - x0, ufl.det(F) * ufl.inv(F).T * N) * problem.boundary_measure(
        boundary)


class PathFollower:
    """Arc length or volume control on a NewtonSolver's problem (module docstring).

    ``control``: "arc_length" or "volume"; volume control needs ``boundary`` (the pressure boundary whose
    cavity is controlled), ``origin`` (x_0) and the final volume ``target`` (or ``ratio`` = target / V_0).
    """

    def __init__(self, solver: NewtonSolver, control: str, *, boundary: str | None = None,
                 origin: list[float] | None = None, ratio: float | None = None) -> None:
        if control not in ("arc_length", "volume"):
            raise ValueError(f"control must be 'arc_length' or 'volume', got {control!r}")
        if solver.nested is not None:
            raise ValueError("path following solves with one assembled matrix: [solver] matrix = \"aij\"")
        problem = solver.problem
        self.solver = solver
        self.problem = problem
        self.control = control
        self.comm = problem.domain.mesh.comm
        self._load_form = problem.unit_load_form()
        if self._load_form is None:
            raise ValueError("path following needs a load (a traction, pressure or body force): there is none")
        self.x = compat.petsc_vector(problem.solution).copy()
        self.R, self.f, self.a, self.b, self.c = (self.x.duplicate() for _ in range(5))
        owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
        #: 1 on the free displacement dofs, 0 on the pressure and the constrained dofs (the arc length's norm)
        self.mask = self.x.duplicate()
        mask = np.zeros(owned)
        if problem.formulation == "mixed":
            _, parent = problem.space.sub(0).collapse()
            parent = np.asarray(parent)
            mask[parent[parent < owned]] = 1.0
        else:
            mask[:] = 1.0
        self.mask.array[:] = mask
        problem.zero_dirichlet_rows(self.mask)
        self.boundary = boundary
        self.ratio = ratio
        if control == "volume":
            volume = cavity_volume_form(problem, boundary, origin or [0.0, 0.0, 0.0])
            self._volume = fem.form(volume)
            self._volume_derivative = fem.form(ufl.derivative(volume, problem.solution,
                                                              ufl.TestFunction(problem.space)))
            self.initial_volume = self.volume()
            if not self.initial_volume > 0:
                raise ValueError(f"the cavity of boundary {boundary!r} has volume {self.initial_volume:.6g} <= 0 at "
                                 "rest: its normal points out of the cavity, or origin is not on its open side")
        self.ksp = solver.snes.getKSP()
        max_it = solver.snes.getTolerances()[3]
        self.max_it = int(max_it)
        self.lam = float(problem.time)
        self.linear_iterations = 0

    # --- pieces ------------------------------------------------------------------------------

    def volume(self) -> float:
        """The cavity volume V(u) at the current solution (collective)."""
        self.problem.update_state()
        return float(self.comm.allreduce(fem.assemble_scalar(self._volume), op=MPI.SUM))

    def _assemble_vector(self, form: Any, out: PETSc.Vec) -> None:
        with out.localForm() as local:
            local.set(0.0)
        fem_petsc.assemble_vector(out, form)
        out.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.problem.zero_dirichlet_rows(out)

    def _linearise(self, lam: float) -> None:
        """At (self.x, lam): R, K (in the solver's matrix), f; then a = K^-1 R and b = K^-1 f."""
        solver = self.solver
        self.problem.set_load_factor(lam)
        solver._residual(solver.snes, self.x, self.R)
        solver._jacobian(solver.snes, self.x, solver.A, solver.A)
        self._assemble_vector(self._load_form, self.f)
        self.ksp.setOperators(solver.A, solver.A)
        self.ksp.solve(self.R, self.a)
        self.ksp.solve(self.f, self.b)
        self.linear_iterations += self.ksp.getIterationNumber()

    def _constraint(self, x_n: PETSc.Vec, target: float) -> tuple[float, PETSc.Vec]:
        """g and c = dg/du at self.x (the current solution)."""
        if self.control == "volume":
            self._assemble_vector(self._volume_derivative, self.c)
            return self.volume() - target, self.c
        self.c.waxpy(-1.0, x_n, self.x)
        self.c.pointwiseMult(self.c, self.mask)
        g = self.c.dot(self.c) - target**2
        self.c.scale(2.0)
        return g, self.c

    def tangent(self) -> tuple[PETSc.Vec, float]:
        """b = K^-1 f at the current state and its masked norm (the arc length of a unit load increment)."""
        self.x.array[:] = compat.petsc_vector(self.problem.solution).array
        self._linearise(self.lam)
        tb = self.b.duplicate()
        tb.pointwiseMult(self.b, self.mask)
        norm = tb.norm()
        tb.destroy()
        return self.b, float(norm)

    # --- one step ----------------------------------------------------------------------------

    def step(self, increment: float, previous: PETSc.Vec | None) -> tuple[SolveResult, dict[str, Any]]:
        """One step of arc length ``increment`` (ds) or volume increment (dV) from the current converged state;
        ``previous`` is the last step's displacement increment (the arc length's direction) or None. On
        failure the state is restored. Returns the solve's result and the step's control record."""
        problem = self.problem
        solver = self.solver
        self.linear_iterations = 0
        x_n = compat.petsc_vector(problem.solution).copy()
        lam_n = self.lam
        self.x.array[:] = x_n.array
        self._linearise(lam_n)
        if self.control == "volume":
            V_n = self.volume()
            target = V_n + increment
            self._assemble_vector(self._volume_derivative, self.c)
            dlam = (target - V_n) / self.c.dot(self.b)
            constraint_target = target
        else:
            tb = self.b.duplicate()
            tb.pointwiseMult(self.b, self.mask)
            norm = tb.norm()
            sign = 1.0
            if previous is not None and previous.dot(tb) < 0:
                sign = -1.0
            tb.destroy()
            dlam = sign * increment / norm
            constraint_target = increment
        lam = lam_n + dlam
        self.x.axpy(dlam, self.b)  # the predictor: u_n + dlambda K^-1 f
        predictor = self._scaled(self.b, -dlam)
        s = solver.admissibility.step_limit(predictor)
        predictor.destroy()
        if s < 1.0:  # the predictor folds a cell: shorten it (the corrector restores the constraint)
            self.x.axpy(-(1.0 - s) * dlam, self.b)
            lam = lam_n + s * dlam
        iterations, converged, norm, reference = 0, False, math.inf, None
        reason_name = "DIVERGED_MAX_IT"
        limited = 0
        while iterations <= self.max_it:
            self._linearise(lam)
            norm = self.R.norm()
            g, c = self._constraint(x_n, constraint_target)
            if not math.isfinite(norm) or not solver.last_min_det_F > 0:
                reason_name = "DIVERGED_FUNCTION_DOMAIN" if math.isfinite(norm) else "DIVERGED_FNORM_NAN"
                break
            load = abs(lam) * self.f.norm()
            if reference is None:
                reference = max(load, norm)
            g_scale = self.initial_volume if self.control == "volume" else constraint_target**2
            if norm <= RTOL * max(load, reference) and abs(g) <= RTOL * g_scale:
                converged = True
                reason_name = "CONVERGED_FNORM_RELATIVE"
                break
            if iterations == self.max_it:
                break
            cb = c.dot(self.b)
            if cb == 0.0 or not math.isfinite(cb):
                reason_name = "DIVERGED_CONSTRAINT_SINGULAR"
                break
            dlam = (c.dot(self.a) - g) / cb
            direction = self.a.copy()
            direction.axpy(-dlam, self.b)  # -du = a - dlambda b
            s = solver.admissibility.step_limit(direction)
            if s == 0.0:
                direction.destroy()
                reason_name = "DIVERGED_FUNCTION_DOMAIN"
                break
            limited += s < 1.0
            self.x.axpy(-s, direction)
            lam += s * dlam
            direction.destroy()
            iterations += 1
        if converged:
            self.x.copy(compat.petsc_vector(problem.solution))
            compat.petsc_vector(problem.solution).ghostUpdate(addv=PETSc.InsertMode.INSERT,
                                                              mode=PETSc.ScatterMode.FORWARD)
            problem.set_load_factor(lam)
            problem.update_state()
            self.lam = lam
        else:
            x_n.copy(compat.petsc_vector(problem.solution))
            compat.petsc_vector(problem.solution).ghostUpdate(addv=PETSc.InsertMode.INSERT,
                                                              mode=PETSc.ScatterMode.FORWARD)
            problem.set_load_factor(lam_n)
            problem.invalidate_state()
            problem.update_state()
        x_n.destroy()
        admissibility = {**solver.admissibility.report(), "limited_steps": limited}
        reason = 2 if converged else -5
        result = SolveResult(converged, reason, reason_name, iterations, self.linear_iterations, float(norm),
                             admissibility=admissibility)
        record: dict[str, Any] = {"control": self.control, "load_factor_carried": lam}
        if self.control == "volume":
            record["cavity_volume"] = self.volume()
            record["target_volume"] = constraint_target
        else:
            record["arc_length"] = increment
        return result, record

    def _scaled(self, vec: PETSc.Vec, factor: float) -> PETSc.Vec:
        out = self.a.duplicate()
        vec.copy(out)
        out.scale(factor)
        return out

    def destroy(self) -> None:
        for v in (self.x, self.R, self.f, self.a, self.b, self.c, self.mask):
            v.destroy()


@dataclass(frozen=True)
class PathRecord(StepRecord):
    """A path step's record: StepRecord with the control's own figures (cavity volume, arc length)."""

    control: dict[str, Any] | None = None


def follow_path(follower: PathFollower, steps: int, max_steps: int, max_cutbacks: int = 8, growth: float = 1.5,
                on_step: Callable[[PathRecord], None] | None = None) -> Outcome:
    """Arc length: from the current state along the path until the load factor reaches 1 (the last step is then
    solved under load control at exactly 1) or ``max_steps`` steps were taken. Volume control: V from V_0 to
    ratio V_0 in ``steps`` equal increments. A failed step is halved (at most ``max_cutbacks`` times in a row)
    and the increment grows by ``growth`` after a success, never beyond the nominal one."""
    problem = follower.problem
    if follower.control == "volume":
        total = (follower.ratio - 1.0) * follower.initial_volume
        nominal = total / steps
        remaining = total
    else:
        _, norm = follower.tangent()
        if not norm > 0:
            return Outcome(False, "arc length: the load does not move the body (K^-1 f = 0)")
        nominal = norm / steps
        remaining = math.inf
    increment = nominal
    cutbacks = taken = 0
    previous: PETSc.Vec | None = None
    rank0 = follower.comm.rank == 0
    while taken < max_steps:
        if follower.control == "volume":
            if abs(remaining) <= 1e-12 * abs(total):
                return Outcome(True)
            increment = min(increment, remaining) if total > 0 else max(increment, remaining)
        x_before = compat.petsc_vector(problem.solution).copy()
        lam_before = follower.lam
        began = time.perf_counter()
        result, record = follower.step(increment, previous)
        seconds = time.perf_counter() - began
        if not result.converged:
            x_before.destroy()
            cutbacks += 1
            if on_step is not None:
                on_step(PathRecord(record["load_factor_carried"], result, seconds, increment, record))
            if cutbacks > max_cutbacks:
                what = "volume" if follower.control == "volume" else "arc-length"
                return Outcome(False, f"{what} step failed {cutbacks} times in a row ({result.reason_name}), more "
                                      f"than loading.max_cutbacks = {max_cutbacks}; stopped at load factor "
                                      f"{lam_before:.6g}: raise loading.max_cutbacks or loading.steps")
            increment *= 0.5
            if rank0:
                log.warning("%s step failed (%s); halving the increment to %.4g", follower.control,
                            result.reason_name, increment)
            continue
        cutbacks = 0
        taken += 1
        if previous is not None:
            previous.destroy()
        previous = compat.petsc_vector(problem.solution).copy()
        previous.axpy(-1.0, x_before)
        previous.pointwiseMult(previous, follower.mask)
        x_before.destroy()
        if follower.control == "volume":
            remaining -= increment
        elif follower.lam >= 1.0 > lam_before:  # the path crossed the full load: solve it there exactly
            x_after = compat.petsc_vector(problem.solution).copy()
            problem.set_load_factor(1.0)
            exact = follower.solver.solve()
            if exact.converged:
                x_after.destroy()
                follower.lam = 1.0
                record = {**record, "load_factor_carried": 1.0}
                if on_step is not None:
                    on_step(PathRecord(1.0, exact, seconds, increment, record))
                return Outcome(True)
            x_after.copy(compat.petsc_vector(problem.solution))  # keep the path's state beyond the full load
            x_after.destroy()
            problem.set_load_factor(follower.lam)
            problem.invalidate_state()
        if on_step is not None:
            on_step(PathRecord(follower.lam, result, seconds, min(increment * growth, nominal), record))
        increment = min(increment * growth, nominal) if follower.control == "arc_length" else \
            (min(increment * growth, nominal) if total > 0 else max(increment * growth, nominal))
    if follower.control == "volume":
        return Outcome(True)
    return Outcome(False, f"arc length: the path did not reach load factor 1 within loading.max_steps = {max_steps} "
                          f"steps (load factor {follower.lam:.6g} at the end): past a limit point the load may "
                          "never reach it; raise loading.max_steps to follow the path further")
