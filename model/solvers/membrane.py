"""Pressure stepping for model.problem.membrane.MembraneProblem (Newton: model.solvers.form_newton.FormNewton).

    steps = inflate(problem, pressures)                       # one equilibrium per pressure, in order
    steps = inflate_to_volume(problem, target, dp)            # grow p by dp until V >= target, then secant on p

Each step solves dPi/du = 0 (symmetric Jacobian, MUMPS LU) from the previous state and records the pressure,
the volume V(x), the elastic energy and Newton's iterations. A step whose Newton fails is retried with the
pressure increment halved (at most ``cutbacks`` times); then RuntimeError names the pressure.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from model.problem.membrane import MembraneProblem
from model.solvers.form_newton import FormNewton

log = logging.getLogger(__name__)

__all__ = ["InflationStep", "inflate", "inflate_to_volume", "membrane_newton"]


@dataclass(frozen=True)
class InflationStep:
    """One converged equilibrium: pressure, enclosed volume, elastic energy, Newton iterations."""

    pressure: float
    volume: float
    energy: float
    iterations: int


def membrane_newton(problem: MembraneProblem, options: dict | None = None) -> FormNewton:
    """A FormNewton on the problem's residual (Newton with a backtracking line search by default)."""
    opts = {"snes_linesearch_type": "bt", "snes_rtol": 1e-10, "snes_atol": 1e-11, "snes_max_it": 40}
    return FormNewton(problem.residual, problem.u, problem.bcs, options={**opts, **(options or {})})


def _solve_at(problem: MembraneProblem, newton: FormNewton, p_from: float, p_to: float, cutbacks: int) -> int:
    """Reach pressure p_to from the equilibrium at p_from, halving the increment on failure; Newton iterations."""
    saved = problem.u.x.array.copy()
    target, current, iterations, left = p_to, p_from, 0, cutbacks
    while True:
        problem.pressure.value = target
        result = newton.solve()
        if result.converged:
            iterations += result.iterations
            if target == p_to:
                return iterations
            current, saved = target, problem.u.x.array.copy()
            target = p_to
            continue
        if left == 0:
            raise RuntimeError(f"membrane: Newton failed at pressure {target:.6g} ({result.reason_name}) after "
                               f"{cutbacks} cut-backs")
        left -= 1
        problem.u.x.array[:] = saved
        target = 0.5 * (current + target)
        log.info("membrane: Newton failed, cutting the pressure step back to %.6g", target)


def inflate(problem: MembraneProblem, pressures: np.ndarray | list[float], cutbacks: int = 4,
            options: dict | None = None) -> list[InflationStep]:
    """Equilibria at the increasing ``pressures``, each from the previous one (collective)."""
    newton = membrane_newton(problem, options)
    steps, previous = [], float(problem.pressure.value)
    try:
        for p in pressures:
            its = _solve_at(problem, newton, previous, float(p), cutbacks)
            previous = float(p)
            steps.append(InflationStep(previous, problem.volume(), problem.elastic_energy(), its))
            log.info("membrane: p = %.6g, V = %.6g, %d Newton iterations", previous, steps[-1].volume, its)
    finally:
        newton.destroy()
    return steps


def inflate_to_volume(problem: MembraneProblem, target_volume: float, dp: float, max_steps: int = 200,
                      tolerance: float = 1e-6, cutbacks: int = 4, options: dict | None = None
                      ) -> list[InflationStep]:
    """Grow the pressure by ``dp`` until V(x) >= ``target_volume`` (the stop criterion), then adjust p by the
    secant method between the last two steps until |V - target| <= tolerance * target. Returns every step;
    the last is at the target volume. RuntimeError if ``max_steps`` increments do not reach it."""
    newton = membrane_newton(problem, options)
    steps: list[InflationStep] = []
    p = float(problem.pressure.value)
    start = InflationStep(p, problem.volume(), problem.elastic_energy(), 0)
    try:
        for _ in range(max_steps):
            its = _solve_at(problem, newton, p, p + dp, cutbacks)
            p += dp
            steps.append(InflationStep(p, problem.volume(), problem.elastic_energy(), its))
            if steps[-1].volume >= target_volume:
                break
        else:
            raise RuntimeError(f"membrane: volume {steps[-1].volume:.6g} < target {target_volume:.6g} after "
                               f"{max_steps} pressure steps (p = {p:.6g})")
        below = steps[-2] if len(steps) > 1 else start
        above = steps[-1]
        for _ in range(30):
            if abs(above.volume - target_volume) <= tolerance * target_volume:
                break
            slope = (above.volume - below.volume) / (above.pressure - below.pressure)
            p_new = above.pressure + (target_volume - above.volume) / slope
            its = _solve_at(problem, newton, above.pressure, p_new, cutbacks)
            below, above = above, InflationStep(p_new, problem.volume(), problem.elastic_energy(), its)
            steps.append(above)
    finally:
        newton.destroy()
    return steps
