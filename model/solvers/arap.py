"""Load stepping with Newton for model.problem.mixed_arap.ArapProblem (mixed and displacement-only ARAP).

    result = solve_arap(problem, steps=4, options={"snes_rtol": 1e-12})

Load factors t = 1/steps, ..., 1 from the problem's current state; each step is one SNES Newton solve of the
whole system (model.solvers.form_newton.FormNewton: the Jacobian is UFL's derivative of the residual); a step
whose solve fails is retried from the last converged state with half the increment (at most ``max_halvings``
times in the run). After each converged step of the mixed form the rotations are re-based
(ArapProblem.rebase_rotations: R_ref <- R_ref Q(phi), phi <- 0).
"""

from __future__ import annotations

import logging
import time

from model.problem.mixed_arap import ArapProblem, ArapResult
from model.solvers.form_newton import FormNewton

log = logging.getLogger(__name__)


def solve_arap(problem: ArapProblem, steps: int = 1, options: dict | None = None,
               max_halvings: int = 6) -> ArapResult:
    """Drive ``problem`` from its current state to load factor 1 (module docstring). Collective."""
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps: {steps!r} must be a whole number >= 1")
    solver = FormNewton(problem.residual, problem.w, problem.bcs, options=options)
    start = time.perf_counter()
    t, dt, iterations, cut_backs, reached = 0.0, 1.0 / steps, [], 0, []
    try:
        while t < 1.0 - 1e-14:
            t_next = min(1.0, t + dt)
            saved = problem.w.x.array.copy()
            problem.set_load(t_next)
            result = solver.solve()
            if not result.converged:
                problem.w.x.array[:] = saved
                problem.w.x.scatter_forward()
                cut_backs += 1
                if cut_backs > max_halvings:
                    raise RuntimeError(f"ARAP ({problem.formulation}): Newton failed at load {t_next:.4g} "
                                       f"({result.reason_name}) after {max_halvings} halvings")
                dt *= 0.5
                continue
            iterations.append(result.iterations)
            reached.append(t_next)
            problem.rebase_rotations()
            t = t_next
            log.info("ARAP %s: load %.4g in %d Newton iterations", problem.formulation, t, result.iterations)
    finally:
        solver.destroy()
    elapsed = time.perf_counter() - start
    W = problem.W
    dofs = W.dofmap.index_map.size_global * W.dofmap.index_map_bs
    return ArapResult(problem.displacement(), problem.formulation, iterations, elapsed, dofs, problem.energy_value(),
                      cut_backs, reached, problem.rotations() if problem.formulation == "mixed" else None)


__all__ = ["solve_arap"]
