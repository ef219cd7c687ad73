"""Load stepping with automatic cut-back and re-growth.

The load factor goes from 0 to 1 in ``steps`` equal increments d = 1/steps. When SNES fails,
the solution is restored to the last converged state and the step that failed is halved (so the
next attempt always aims lower, also when the end of the range had shortened that step); after a
converged step the increment grows by ``growth`` again, never beyond d.
The run gives up after ``max_cutbacks`` failures in a row, or when the increment falls below
d / 2^max_cutbacks (so that alternating failures and successes cannot crawl on forever), or after
``max_attempts`` solves in all (loading.max_steps: bounded work, whatever the two rules allow); the
returned Outcome is false then and says which of these happened and which keys change it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from model.solvers.newton import NewtonSolver, SolveResult

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Outcome:
    """The end of a load (or time) stepping: true when it reached its end; else ``reason`` says why it gave
    up, naming the configuration keys that change it."""

    completed: bool
    reason: str = ""
    #: the stability report of a failed run (model.solvers.stability.diagnose), when one was made
    stability: dict[str, Any] | None = None

    def __bool__(self) -> bool:
        return self.completed


def give_up_reason(what: str, target: float, current: float, reason_name: str, failures: int, increment: float,
                   nominal: float, max_cutbacks: int, step_key: str) -> str | None:
    """Why cut-back stops, or None while it may go on.

    Two rules: more than ``max_cutbacks`` failures in a row, or an increment below nominal / 2^max_cutbacks
    (failures and successes alternating would otherwise crawl on for ever). ``step_key`` names the key of
    the nominal increment (loading.steps or dynamics.dt).
    """
    smallest = nominal * 0.5**max_cutbacks
    if failures > max_cutbacks:
        return (f"{what} to {target:.6g} failed {failures} times in a row, more than loading.max_cutbacks = "
                f"{max_cutbacks} (last SNES reason {reason_name}); stopped at {current:.6g}: raise "
                f"loading.max_cutbacks, or {step_key} for smaller increments from the start")
    if increment < smallest * (1 - 1e-12):
        return (f"{what} to {target:.6g} failed (SNES reason {reason_name}) and the next increment {increment:.3g} "
                f"would fall below the smallest allowed, {nominal:.3g} / 2^{max_cutbacks} = {smallest:.3g} "
                f"({step_key}, loading.max_cutbacks); stopped at {current:.6g}: raise loading.max_cutbacks or "
                f"{step_key}")
    return None


#: what a failure of this kind says, and what can help, by SNES reason (the cut-back advice of give_up_reason
#: follows it where smaller increments can help; a linear solver failure replaces it)
LINEAR_ADVICE = ("the linear solver failed in every attempt, and smaller load steps rarely help: with [solver] "
                 "linear = \"iterative\" try \"direct\" (MUMPS); with MUMPS the Newton matrix is singular (a rigid "
                 "motion that nothing holds, a zero modulus) or the factorisation ran out of memory")


def cause_of(result: SolveResult) -> tuple[str, bool]:
    """(what the last failed solve says about the cause, whether more cut-backs can help) for the give-up message:
    a linear solver failure, folded cells (with min det F and where), a NaN residual (with where it is largest)."""
    name = result.reason_name
    failure = getattr(result, "linear_failure", None)
    if failure:  # what MUMPS says: out of memory, a singular matrix
        return failure["message"], False
    if name == "DIVERGED_LINEAR_SOLVE":
        return LINEAR_ADVICE, False
    fold = (result.admissibility or {}).get("folded_trial")
    if fold:  # DIVERGED_FUNCTION_DOMAIN (PETSc may also report the domain error's residual as DIVERGED_FNORM_NAN)
        point = fold.get("min_det_F_point")
        where = f" near ({', '.join(f'{c:.4g}' for c in point)})" if point else ""
        return (f"every attempt folded cells (det F = {fold.get('min_det_F')}{where} in its last trial state): "
                "a finer mesh there or smaller steps may help, a load past what the body can carry will not"), True
    if name == "DIVERGED_FNORM_NAN":
        return f"the residual became NaN ({result.where or 'a law evaluated outside its domain'})", True
    return "", True


def _rank0(problem: object) -> bool:
    """Whether this process logs for the problem (rank 0 of its mesh's communicator; a problem without a mesh:
    always)."""
    domain = getattr(problem, "domain", None)
    return domain is None or domain.mesh.comm.rank == 0


@dataclass(frozen=True)
class StepRecord:
    load_factor: float
    result: SolveResult
    seconds: float = 0.0  # wall time of the solve
    next_increment: float = 0.0  # the increment the next step takes when this one converged (checkpoints)


def continuation(solver: NewtonSolver, apply: Callable[[float], None], steps: int, max_cutbacks: int = 8,
                 growth: float = 1.5, on_step: Callable[[StepRecord], None] | None = None, start: float = 0.0,
                 what: str = "load step", step_key: str = "loading.steps", increment: float | None = None,
                 diagnose: Callable[[np.ndarray | None], dict[str, Any] | None] | None = None,
                 max_attempts: int | None = None) -> Outcome:
    """Drive a parameter s from ``start`` to 1 in increments of 1/steps, ``apply(s)`` setting it on the problem
    before each solve; a failed solve restores the last converged state and halves the increment that failed,
    a converged one grows the increment by ``growth`` (up to 1/steps). A true Outcome when s got to 1, else
    one whose ``reason`` says why it gave up (give_up_reason). ``increment``: the first step's (a restart
    continues with the cut-back state it saved; default 1/steps). ``diagnose(failed_state)``, called when it
    gives up (at the last converged state, with the last failed iterate's solution array when that step was at most
    a quarter of the nominal increment, else None): a stability report
    (model.solvers.stability.diagnose) whose "message", when the structure is unstable, replaces the cut-back
    advice, which cannot help there. ``max_attempts``: the most solves (converged and failed) before it gives up
    (loading.max_steps; None: no cap beyond the cut-back rules)."""
    problem = solver.problem
    nominal = 1.0 / steps
    attempts = 0
    increment = nominal if increment is None else float(increment)
    current = start
    cutbacks = 0
    while current < 1.0 - 1e-12:
        if max_attempts is not None and attempts >= max_attempts:
            reason = (f"{what}s: {attempts} solves (loading.max_steps) without reaching 1; stopped "
                      f"at {current:.6g} with an increment of {increment:.3g} ({step_key} gives {nominal:.3g}): "
                      "cut-backs and regrowth alternate here; raise loading.max_steps, or loading.steps for smaller "
                      "increments from the start")
            if _rank0(problem):
                log.error("giving up: %s", reason)
            return Outcome(False, reason)
        attempts += 1
        target = min(current + increment, 1.0)
        if 1.0 - target < 1e-9:
            target = 1.0
        saved = problem.solution.x.array.copy()
        apply(target)
        began = time.perf_counter()
        result = solver.solve()
        record = StepRecord(target, result, time.perf_counter() - began, min(increment * growth, nominal))
        if on_step is not None:
            on_step(record)
        if result.converged:
            current = target
            cutbacks = 0
            increment = min(increment * growth, nominal)
            continue
        # the failed iterate's tangent says something about the path only when its step was short (cut back
        # at least to a quarter of the nominal increment): a long step's iterate can be anywhere
        near = target - current <= 0.25 * nominal * (1 + 1e-12)
        failed_state = problem.solution.x.array.copy() if diagnose is not None and near else None
        problem.solution.x.array[:] = saved
        apply(current)
        cutbacks += 1
        increment = 0.5 * (target - current)  # half the step that failed (which the end may have shortened)
        reason = give_up_reason(what, target, current, f"{result.reason}, {result.reason_name}", cutbacks,
                                increment, nominal, max_cutbacks, step_key)
        if (getattr(result, "linear_failure", None) or {}).get("memory"):  # the same matrix at any load: no cut-back
            reason = (f"{what} to {target:.6g} failed (SNES reason {result.reason}, {result.reason_name}); stopped "
                      f"at {current:.6g}: {result.linear_failure['message']}")
            if _rank0(problem):
                log.error("giving up: %s", reason)
            return Outcome(False, reason)
        rank0 = _rank0(problem)
        if reason is not None:
            report = diagnose(failed_state) if diagnose is not None else None
            if report is not None and report.get("unstable"):
                reason = (f"{what} to {target:.6g} failed (last SNES reason {result.reason}, {result.reason_name}) "
                          f"after {cutbacks} cut-backs; stopped at {current:.6g}: {report['message']}")
            else:
                cause, cutting_helps = cause_of(result)
                if not cutting_helps:
                    reason = (f"{what} to {target:.6g} failed (last SNES reason {result.reason}, "
                              f"{result.reason_name}) after {cutbacks} cut-backs; stopped at {current:.6g}: {cause}")
                elif cause:
                    reason = f"{reason}; {cause}"
            if rank0:
                log.error("giving up: %s", reason)
            return Outcome(False, reason, report)
        if rank0:
            log.warning("SNES failed at %s %.6g (%s%s); cutting the increment back to %.4g",
                        what.removesuffix(" step"), target, result.reason_name,
                        f"; {result.where}" if result.where else "", increment)
    return Outcome(True)


def step_loads(solver: NewtonSolver, steps: int, max_cutbacks: int = 8, growth: float = 1.5,
               on_step: Callable[[StepRecord], None] | None = None, increment: float | None = None,
               diagnose: Callable[[np.ndarray | None], dict[str, Any] | None] | None = None,
               max_attempts: int | None = None) -> Outcome:
    """Drive the load factor of solver.problem from its current value to 1 (continuation with
    apply = problem.set_load_factor, first increment ``increment``); a true Outcome when it got there, else one
    whose ``reason`` says why it gave up."""
    problem = solver.problem
    return continuation(solver, problem.set_load_factor, steps, max_cutbacks, growth, on_step,
                        start=float(problem.time), increment=increment, diagnose=diagnose, max_attempts=max_attempts)
