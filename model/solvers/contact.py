"""Solvers for contact (model.problem.contact): the VI Newton of SNES and Uzawa's augmented Lagrangian loop.

    VISolver        bounds on the normal displacement of the surface nodes (SNES vinewtonrsls) after a
                    linearised predictor that imposes the violated bounds as Dirichlet increments
    UzawaSolver     Newton at fixed multipliers, then lambda_i <- max(lambda_i - k g_i, 0), until the
                    complementarity holds to the contact's tolerance (or max_uzawa updates)
    make_contact_solver   the solver a list of contacts needs (penalty alone: a plain NewtonSolver)
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.problem import ElasticityProblem
from model.problem.body_contact import BodyContact
from model.problem.contact import AugmentedLagrangianContact, Contact, VIContact
from model.solvers.newton import NewtonSolver, SolveResult

log = logging.getLogger(__name__)

#: PETSc options a VI contact needs (the VI Newton of PETSc with a full-step, projected line search)
VI_OPTIONS: dict[str, str | int | float | bool] = {"snes_type": "vinewtonrsls", "snes_linesearch_type": "basic"}
VI_TYPES = ("vinewtonrsls", "vinewtonssls")
#: SolveResult.reason of an augmented Lagrangian run that hit max_uzawa (outside PETSc's range)
DIVERGED_UZAWA_MAX_IT = -100


class VISolver:
    """NewtonSolver with the bounds of VI contacts (snes_type vinewtonrsls), and a predictor.

    SNES VI projects its initial guess onto the bounds: when the obstacle has moved by a load
    step, that pushes the surface nodes alone and can invert the elements under them. The
    predictor first takes one linearised step with the violated bounds imposed as Dirichlet
    increments (rows of the tangent replaced by identity, du_i = bound_i - x_i; Dirichlet data as in
    every Newton step), so the interior follows the surface; SNES VI then solves from there.
    The predictor's linear solve is MUMPS LU.
    """

    def __init__(self, newton: NewtonSolver, contacts: Sequence[VIContact], predictor: bool = True) -> None:
        self.newton = newton
        self.problem = newton.problem
        self.contacts = list(contacts)
        self.predictor = predictor
        self._ksp: PETSc.KSP | None = None

    @property
    def unused_options(self) -> list[str]:
        return self.newton.unused_options

    @property
    def line_search(self) -> dict[str, str]:
        return self.newton.line_search

    def _predict(self) -> None:
        newton, problem = self.newton, self.problem
        x = newton.x
        compat.petsc_vector(problem.solution).copy(x)
        lower = np.full(x.getLocalSize(), PETSc.NINFINITY)
        upper = np.full(x.getLocalSize(), PETSc.INFINITY)
        _fill_bounds(self.contacts, lower, upper)
        values = x.array_r
        low, high = values < lower, values > upper
        rows = np.flatnonzero(low | high).astype(np.int32)
        comm = problem.domain.mesh.comm
        if comm.allreduce(len(rows), op=MPI.SUM) == 0:
            return
        newton._residual(newton.snes, x, newton.b)  # at x, Dirichlet rows x - g
        newton._jacobian(newton.snes, x, newton.A, newton.A)
        target = np.where(low, lower, upper)[rows]
        b = newton.b
        b.array[rows] = values[rows] - target  # du_i = target_i - x_i
        start = x.getOwnershipRange()[0]
        newton.A.zeroRows(rows + start, diag=1.0)
        if self._ksp is None:
            self._ksp = PETSc.KSP().create(comm)
            self._ksp.setType("preonly")
            self._ksp.getPC().setType("lu")
            self._ksp.getPC().setFactorSolverType("mumps")
        self._ksp.setOperators(newton.A)
        du = x.duplicate()
        self._ksp.solve(b, du)
        x.axpy(-1.0, du)  # Newton: A du = b, x <- x - du
        du.destroy()
        x.copy(compat.petsc_vector(problem.solution))
        compat.petsc_vector(problem.solution).ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        log.debug("VI predictor: %d bounds violated before the solve", comm.allreduce(len(rows), op=MPI.SUM))

    def solve(self) -> SolveResult:
        if self.predictor:
            self._predict()
        return self.newton.solve()

    def unconstrained_residual(self) -> PETSc.Vec:
        return self.newton.unconstrained_residual()

    def destroy(self) -> None:
        if self._ksp is not None:
            self._ksp.destroy()
        self.newton.destroy()


def _fill_bounds(contacts: Sequence[VIContact], lower: np.ndarray, upper: np.ndarray) -> None:
    for c in contacts:
        c.apply_bounds(lower, upper)


class UzawaSolver:
    """Augmented Lagrangian contact: Newton solves at fixed multipliers, then Uzawa updates, until converged.

    Same interface as NewtonSolver (``problem``, ``solve()``, ``unconstrained_residual()``,
    ``destroy()``). A solve converges when every contact's Uzawa residual is below its tolerance;
    a failed Newton solve, or ``max_uzawa`` updates without convergence, fails (reason
    DIVERGED_UZAWA_MAX_IT = -100 for the latter) and restores the multipliers of the start of the
    solve (load stepping restores the solution and cuts the step back).
    ``iterations`` of the result counts Newton iterations over all Uzawa rounds; ``uzawa_iterations``
    holds the rounds of the last solve.
    """

    def __init__(self, newton: NewtonSolver | VISolver,
                 contacts: Sequence[AugmentedLagrangianContact | BodyContact]) -> None:
        self.newton = newton
        self.problem = newton.problem
        self.contacts = list(contacts)
        self.max_uzawa = max(c.max_uzawa for c in self.contacts)
        self.uzawa_iterations = 0
        self.history: list[float] = []

    @property
    def unused_options(self) -> list[str]:
        return self.newton.unused_options

    @property
    def line_search(self) -> dict[str, str]:
        return self.newton.line_search

    def _residual(self) -> float:
        return max(c.uzawa_residual() / c.absolute_tolerance for c in self.contacts)

    def solve(self) -> SolveResult:
        saved = [c.multiplier.x.array.copy() for c in self.contacts]
        newton_its = linear_its = 0
        self.history = []
        result: SolveResult | None = None
        for round_ in range(1, self.max_uzawa + 1):
            result = self.newton.solve()
            newton_its += result.iterations
            linear_its += result.linear_iterations
            self.uzawa_iterations = round_
            if not result.converged:
                self._restore(saved)
                return SolveResult(False, result.reason, result.reason_name, newton_its, linear_its,
                                   result.residual_norm)
            ratio = self._residual()
            self.history.append(ratio)
            log.debug("uzawa round %d: residual / tolerance = %.3e", round_, ratio)
            if ratio <= 1.0:
                return SolveResult(True, result.reason, result.reason_name, newton_its, linear_its,
                                   result.residual_norm)
            if round_ < self.max_uzawa:
                for c in self.contacts:
                    c.update_multiplier()
        self._restore(saved)
        log.error("augmented Lagrangian contact: after %d Uzawa rounds max |min(g, lambda/k)| is still %.3g times "
                  "the tolerance (raise max_uzawa or the penalty)", self.max_uzawa, self.history[-1])
        assert result is not None
        return SolveResult(False, DIVERGED_UZAWA_MAX_IT, "DIVERGED_UZAWA_MAX_IT", newton_its, linear_its,
                           result.residual_norm)

    def _restore(self, saved: list[np.ndarray]) -> None:
        for c, lam in zip(self.contacts, saved):
            c.multiplier.x.array[:] = lam

    def unconstrained_residual(self) -> PETSc.Vec:
        """R(u) = f_int - f_ext (contact terms included) with no Dirichlet rows replaced."""
        return self.newton.unconstrained_residual()

    def destroy(self) -> None:
        self.newton.destroy()


def make_contact_solver(problem: ElasticityProblem, contacts: Sequence[Contact],
                        options: dict[str, str | int | float | bool] | None = None, prefix: str | None = None,
                        tangent: str = "exact", predictor: bool = True,
                        defaults: dict[str, str | int | float | bool] | None = None,
                        objective: bool | None = None, matrix: str = "auto") -> NewtonSolver | VISolver | UzawaSolver:
    """The solver for a problem with contacts (build them first); all have NewtonSolver's interface.
    ``defaults``: the linear preset's options (model.solvers.linear), below ``options``; ``matrix``:
    NewtonSolver's ([solver] matrix).

    VI contacts: VISolver, a NewtonSolver with snes_type vinewtonrsls (VI_OPTIONS; a user snes_type
    must be a VI type) and the bounds of every VI contact (the tightest wins), with the predictor
    unless ``predictor`` is False. Augmented Lagrangian contacts (with rigid obstacles, or between bodies:
    BodyContact with augmented = True): wrapped in UzawaSolver. Penalty contacts (and sliding) need
    nothing (their energy is in the residual): a plain NewtonSolver. ``objective``: NewtonSolver's.
    """
    options = dict(options or {})
    vi = [c for c in contacts if isinstance(c, VIContact)]
    augmented = [c for c in contacts if isinstance(c, AugmentedLagrangianContact)
                 or (isinstance(c, BodyContact) and c.augmented)]
    bounds = None
    if vi:
        given = options.get("snes_type")
        if given is not None and given not in VI_TYPES:
            from model.errors import ConfigError

            raise ConfigError(f"solver.petsc_options.snes_type: contact method vi needs one of {', '.join(VI_TYPES)}, "
                              f"got {given!r}")
        options = {**VI_OPTIONS, **options}

        def bounds(xl: PETSc.Vec, xu: PETSc.Vec) -> None:
            lower = np.full(xl.getLocalSize(), PETSc.NINFINITY)
            upper = np.full(xu.getLocalSize(), PETSc.INFINITY)
            _fill_bounds(vi, lower, upper)
            xl.array[:] = lower
            xu.array[:] = upper

    newton = NewtonSolver(problem, options, prefix=prefix, tangent=tangent, bounds=bounds, defaults=defaults,
                          objective=objective, matrix=matrix)
    for c in vi:
        c.solver = newton
    inner: Any = VISolver(newton, vi, predictor) if vi else newton
    return UzawaSolver(inner, augmented) if augmented else inner

