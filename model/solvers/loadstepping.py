"""Load stepping with automatic cut-back and re-growth.

The load factor goes from 0 to 1 in ``steps`` equal increments d = 1/steps. When
SNES fails, the solution is restored to the last converged state and the
increment is halved; after a converged step it grows by ``growth`` again, never beyond d.
The run gives up after ``max_cutbacks`` failures in a row, or when the increment falls below
d / 2^max_cutbacks (so that alternating failures and successes cannot crawl on forever).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from model.solvers.newton import NewtonSolver, SolveResult

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StepRecord:
    load_factor: float
    result: SolveResult
    seconds: float = 0.0  # wall time of the solve


def step_loads(solver: NewtonSolver, steps: int, max_cutbacks: int = 8, growth: float = 1.5,
               on_step: Callable[[StepRecord], None] | None = None) -> bool:
    """Drive the load factor of solver.problem from its current value to 1; True when it got there."""
    problem = solver.problem
    nominal = 1.0 / steps
    increment = nominal
    current = float(problem.time)
    cutbacks = 0
    while current < 1.0 - 1e-12:
        target = min(current + increment, 1.0)
        if 1.0 - target < 1e-9:
            target = 1.0
        saved = problem.solution.x.array.copy()
        problem.set_load_factor(target)
        start = time.perf_counter()
        result = solver.solve()
        record = StepRecord(target, result, time.perf_counter() - start)
        if on_step is not None:
            on_step(record)
        if result.converged:
            current = target
            cutbacks = 0
            increment = min(increment * growth, nominal)
            continue
        problem.solution.x.array[:] = saved
        problem.set_load_factor(current)
        cutbacks += 1
        increment *= 0.5
        if cutbacks > max_cutbacks or increment < nominal * 0.5**max_cutbacks * (1 - 1e-12):
            log.error("load step to %.6g failed (%d times in a row, increment %.3g; last SNES reason %s); "
                      "giving up at %.6g", target, cutbacks, 2 * increment, result.reason_name, current)
            return False
        log.warning("SNES failed at load factor %.6g (%s); cutting the increment back to %.4g",
                    target, result.reason_name, increment)
    return True
