"""Pressure stepping for model.problem.membrane.MembraneProblem (Newton: model.solvers.form_newton.FormNewton).

    steps = inflate(problem, pressures)                       # one equilibrium per pressure, in order
    steps = inflate_to_volume(problem, target, dp)            # grow p by dp until V >= target, then secant on p
    steps = inflate_to_volume(problem, target, dp, contact_fraction=0.3)   # ... or until 30 % of it touches

The contact-fraction stop (thesis ch. 3.3.3: "until a desired volume amount is achieved or until a specified
percentage of the total area is in contact"): the fraction of the membrane's reference area whose nodes touch
a bone or another membrane (model.problem.membrane_contact.contact_fraction) is piecewise constant in p, so the
pressure where it first reaches the target is found by bisection between the last two pressure steps, to
``pressure_tolerance`` times p; the last step is the smallest pressure found with fraction >= target.

Each step solves dPi/du = 0 (symmetric Jacobian, MUMPS LU) from the previous state and records the pressure,
the volume V(x), the elastic energy and Newton's iterations. A step whose Newton fails is retried with the
pressure increment halved (at most ``cutbacks`` times); then RuntimeError names the pressure.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

from model import compat
from model.problem.membrane import MembraneProblem
from model.problem.membrane_contact import contact_fraction as fraction_in_contact
from model.problem.membrane_contact import touching_nodes
from model.solvers.form_newton import FormNewton

log = logging.getLogger(__name__)

__all__ = ["CoupledNewton", "InflationStep", "InflationStopped", "inflate", "inflate_to_volume", "membrane_newton"]


class InflationStopped(Exception):
    """An inflation stopped between its steps because ``on_step`` asked so (e.g. SIGINT / SIGTERM): ``steps``
    the equilibria found so far, the last one the state left in problem.u."""

    def __init__(self, steps: list[InflationStep]) -> None:
        super().__init__(f"membrane: inflation stopped after {len(steps)} steps")
        self.steps = steps


@dataclass(frozen=True)
class InflationStep:
    """One converged equilibrium: pressure, enclosed volume, elastic energy, Newton iterations, and the fraction
    of the membrane's area in contact (0 without contacts)."""

    pressure: float
    volume: float
    energy: float
    iterations: int
    contact_fraction: float = 0.0
    #: freeze_on_contact: the nodes frozen after this step (model.problem.membrane), 0 otherwise
    frozen_nodes: int = 0


def _step(problem: MembraneProblem, pressure: float, iterations: int) -> InflationStep:
    frozen = problem.freeze(touching_nodes(problem)) if problem.freeze_on_contact else 0
    return InflationStep(pressure, problem.volume(), problem.elastic_energy(), iterations,
                         fraction_in_contact(problem), frozen)


class CoupledNewton(FormNewton):
    """FormNewton plus the membrane-membrane contacts' couplings (model.problem.membrane_contact
    .MembranePairContact): their pairing is updated before every assembly, the residual gets Pi^T dPi_c/dz and
    the Jacobian the coupling matrices (Dirichlet rows and columns left to the identity rows)."""

    def __init__(self, problem: MembraneProblem, couplings: list, options: dict) -> None:
        self.couplings = couplings

        def refresh() -> None:
            for c in couplings:
                c.update()

        super().__init__(problem.residual, problem.u, problem.bcs, options=options, before_assembly=refresh)

    def _residual(self, snes: PETSc.SNES, x: PETSc.Vec, b: PETSc.Vec) -> None:
        self._copy_in(x)
        with b.localForm() as local:
            local.set(0.0)
        fem_petsc.assemble_vector(b, self.residual)
        compat.apply_lifting(b, [self.jacobian], bcs=[self.bcs], x0=[x], alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        for c in self.couplings:
            c.add_residual(b)
        compat.set_bc(b, self.bcs, x, -1.0)

    def _jacobian(self, snes: PETSc.SNES, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        super()._jacobian(snes, x, A, P)
        for c in self.couplings:
            c.add_jacobian(A, self.bcs)
        A.assemble()

    def destroy(self) -> None:
        super().destroy()
        for c in self.couplings:  # their matrices and vector (MembranePairContact.destroy: made again when needed)
            c.destroy()


def membrane_newton(problem: MembraneProblem, options: dict | None = None) -> FormNewton:
    """A FormNewton on the problem's residual (Newton with a backtracking line search by default); a
    CoupledNewton when the membrane has membrane-membrane contacts, with the l2 line search (a secant on
    |R(x + s dx)|^2 in s): backtracking on |R| cut the step to 0.1 for 50 to 110 iterations at the first contact
    of two discs (the free step overshoots through the other membrane and the penalty's |R| jumps), which the
    default 40 iterations did not survive on non-matching meshes; with l2 (or full steps) 12 to 19 iterations,
    the last ones linear (the lagged pairing). tests/test_membrane_contact.py."""
    couplings = [c for c in problem.contacts if hasattr(c, "add_jacobian")]
    opts = {"snes_linesearch_type": "l2" if couplings else "bt", "snes_rtol": 1e-10, "snes_atol": 1e-11,
            "snes_max_it": 40, **(options or {})}
    if couplings:
        return CoupledNewton(problem, couplings, opts)
    return FormNewton(problem.residual, problem.u, problem.bcs, options=opts)


def _solve_at(problem: MembraneProblem, newton: FormNewton, p_from: float, p_to: float, cutbacks: int) -> int:
    """Reach pressure p_to from the equilibrium at p_from, halving the increment on failure; Newton iterations."""
    saved = problem.u.x.array.copy()
    target, current, iterations, left = p_to, p_from, 0, cutbacks
    while True:
        problem.set_pressure(target)
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


def _uzawa(problem: MembraneProblem, newton: FormNewton, pressure: float, tolerance: float, max_rounds: int,
           cutbacks: int) -> int:
    """Uzawa rounds at a fixed pressure for the augmented contacts (model.problem.membrane_contact): update the
    multipliers and solve again until max |min(g, lambda/k)| <= ``tolerance``; Newton iterations."""
    augmented = [c for c in problem.contacts if getattr(c, "augmented", False)]
    iterations = 0
    for _ in range(max_rounds):
        residual = max((c.uzawa_residual() for c in augmented), default=0.0)
        if residual <= tolerance:
            return iterations
        for c in augmented:
            c.update_multiplier()
        iterations += _solve_at(problem, newton, pressure, pressure, cutbacks)
    raise RuntimeError(f"membrane: Uzawa did not reach |min(g, lambda/k)| <= {tolerance:g} in {max_rounds} rounds "
                       f"at pressure {pressure:.6g} (residual {residual:.3g})")


def inflate(problem: MembraneProblem, pressures: np.ndarray | list[float], cutbacks: int = 4,
            options: dict | None = None, uzawa_tolerance: float = 1e-9, max_uzawa: int = 30
            ) -> list[InflationStep]:
    """Equilibria at the increasing ``pressures``, each from the previous one (collective). With augmented
    contacts each equilibrium is followed by Uzawa rounds until max |min(g, lambda/k)| <= ``uzawa_tolerance``.
    A problem with ``freeze_on_contact``: after each equilibrium the nodes that touch a contact are frozen at
    that step's pressure; the next steps raise only the others' (model.problem.membrane)."""
    newton = membrane_newton(problem, options)
    steps, previous = [], float(problem.pressure.value)
    try:
        for p in pressures:
            its = _solve_at(problem, newton, previous, float(p), cutbacks)
            its += _uzawa(problem, newton, float(p), uzawa_tolerance, max_uzawa, cutbacks)
            previous = float(p)
            steps.append(_step(problem, previous, its))
            log.info("membrane: p = %.6g, V = %.6g, %d Newton iterations", previous, steps[-1].volume, its)
    finally:
        newton.destroy()
    return steps


def inflate_to_volume(problem: MembraneProblem, target_volume: float, dp: float, max_steps: int = 200,
                      tolerance: float = 1e-6, cutbacks: int = 4, options: dict | None = None,
                      contact_fraction: float | None = None, pressure_tolerance: float = 1e-3,
                      uzawa_tolerance: float = 1e-9, max_uzawa: int = 30,
                      on_step: Callable[[InflationStep], bool] | None = None) -> list[InflationStep]:
    """Grow the pressure by ``dp`` until V(x) >= ``target_volume`` or, if ``contact_fraction`` is given, until
    that fraction of the membrane's area touches its contacts (the stop criteria, module docstring). Volume:
    p is adjusted by the secant method between the last two steps until |V - target| <= tolerance * target.
    Contact fraction: bisection on p to ``pressure_tolerance`` * p. Returns every step; the last is at the
    target. Augmented contacts: Uzawa rounds after every equilibrium (as in ``inflate``). RuntimeError if
    ``max_steps`` increments reach neither. ``on_step(step)`` is called after every equilibrium (growth, secant
    and bisection; collective: its answer must be the same on every rank); True stops the inflation there:
    InflationStopped carries the steps so far (the last one's state in problem.u). With ``freeze_on_contact`` each
    equilibrium freezes the nodes that touch at its pressure (as ``inflate``), and the secant and the bisection
    reach every trial pressure in one increment from the last equilibrium below the target (its u, frozen nodes
    and their pressures: problem.state), so the final state is that of an increasing path of pressures, the
    pressures of the steps that stayed below the target and the final one (``_secant_from_below``; augmented
    contacts' multipliers are not restored: the Uzawa rounds at each trial bring them to its pressure)."""
    uzawa = (uzawa_tolerance, max_uzawa)
    if contact_fraction is not None and not 0.0 < contact_fraction <= 1.0:
        raise ValueError(f"inflate_to_volume: contact_fraction must be in (0, 1], got {contact_fraction!r}")
    if contact_fraction is not None and not problem.contacts:
        raise ValueError("inflate_to_volume: contact_fraction needs a contact on the membrane (none added)")
    newton = membrane_newton(problem, options)
    steps: list[InflationStep] = []
    p = float(problem.pressure.value)
    start = _step(problem, p, 0)
    touched = False

    def record(step: InflationStep, tried: tuple | list = ()) -> InflationStep:
        if on_step is not None and on_step(step):
            raise InflationStopped([*steps, *tried, step])
        return step

    try:
        for _ in range(max_steps):
            saved = problem.state()
            its = _solve_at(problem, newton, p, p + dp, cutbacks) + _uzawa(problem, newton, p + dp, *uzawa, cutbacks)
            p += dp
            steps.append(record(_step(problem, p, its)))
            if contact_fraction is not None and steps[-1].contact_fraction >= contact_fraction:
                touched = True
                break
            if steps[-1].volume >= target_volume:
                break
        else:
            raise RuntimeError(f"membrane: volume {steps[-1].volume:.6g} < target {target_volume:.6g} after "
                               f"{max_steps} pressure steps (p = {p:.6g})")
        below = steps[-2] if len(steps) > 1 else start
        above = steps[-1]
        if touched:
            steps += _bisect_fraction(problem, newton, below.pressure, saved, above, contact_fraction,
                                      pressure_tolerance, cutbacks, uzawa, record)
            return steps
        if problem.freeze_on_contact:
            steps += _secant_from_below(problem, newton, below, saved, above, target_volume, tolerance, cutbacks,
                                        uzawa, record)
            return steps
        for _ in range(30):
            if abs(above.volume - target_volume) <= tolerance * target_volume:
                break
            slope = (above.volume - below.volume) / (above.pressure - below.pressure)
            p_new = above.pressure + (target_volume - above.volume) / slope
            its = _solve_at(problem, newton, above.pressure, p_new, cutbacks) + _uzawa(problem, newton, p_new, *uzawa,
                                                                                     cutbacks)
            below, above = above, record(_step(problem, p_new, its))
            steps.append(above)
    finally:
        newton.destroy()
    return steps


def _secant_from_below(problem: MembraneProblem, newton: FormNewton, low: InflationStep,
                       low_state: tuple[np.ndarray, ...], high: InflationStep, target: float, rtol: float,
                       cutbacks: int, uzawa: tuple[float, int],
                       record: Callable[..., InflationStep]) -> list[InflationStep]:
    """The target volume with frozen pressures (``freeze_on_contact``): V(low) < target <= V(high), the state at
    ``high`` in problem.u. Each trial pressure p (the secant through the last two equilibria, bisection of the
    bracket where the secant leaves it) is reached in one increment from the bracket's lower equilibrium
    (``low_state``: u, the frozen nodes and their pressures), and freezes the nodes it touches at p, so the
    accepted state is that of an increasing path of pressures, as a ramp would reach it (the nodes frozen by a
    trial above the target are let go with its state). Stops at |V - target| <= ``rtol`` target; the equilibria
    tried, the last the accepted one (the state left in problem.u)."""
    high_state, tried = problem.state(), []
    previous, last = low, high
    for _ in range(60):
        if abs(high.volume - target) <= rtol * target or high.pressure - low.pressure <= 1e-12 * high.pressure:
            break
        p_new = last.pressure + (target - last.volume) * (last.pressure - previous.pressure) / \
            (last.volume - previous.volume) if last.volume != previous.volume else -1.0
        if not low.pressure < p_new < high.pressure:
            p_new = 0.5 * (low.pressure + high.pressure)
        problem.restore(low_state)
        its = _solve_at(problem, newton, low.pressure, p_new, cutbacks) + _uzawa(problem, newton, p_new, *uzawa,
                                                                                cutbacks)
        step = record(_step(problem, p_new, its), tried)
        tried.append(step)
        previous, last = last, step
        if step.volume < target:
            low, low_state = step, problem.state()
            if abs(step.volume - target) <= rtol * target:
                return tried
        else:
            high, high_state = step, problem.state()
    problem.restore(high_state)
    problem.set_pressure(high.pressure)
    if abs(high.volume - target) > rtol * target:
        log.warning("membrane: volume %.8g at p = %.8g, target %.8g not reached to %.1g (a jump of V in p)",
                    high.volume, high.pressure, target, rtol)
    if not tried:  # the growth step was within the tolerance: already the last step
        return []
    return tried if tried[-1] is high else [*tried, high]


def _bisect_fraction(problem: MembraneProblem, newton: FormNewton, p_low: float, low: tuple[np.ndarray, ...],
                     high: InflationStep, target: float, rtol: float, cutbacks: int,
                     uzawa: tuple[float, int],
                     record: Callable[..., InflationStep]) -> list[InflationStep]:
    """Bisection on p in [p_low, high.pressure] for the smallest pressure with contact fraction >= target; the
    equilibria tried, the last the accepted one (the state left in problem.u). ``low``: the state at p_low
    (problem.state(): u, and the frozen nodes with their pressures), from which every trial is reached in one
    increment, so with ``freeze_on_contact`` the accepted state is that of an increasing path of pressures.
    ``record(step, tried)`` sees every equilibrium tried (the stop hook of inflate_to_volume)."""
    high_state, tried = problem.state(), []
    p_high = high.pressure
    while p_high - p_low > rtol * p_high:
        mid = 0.5 * (p_low + p_high)
        problem.restore(low)
        its = _solve_at(problem, newton, p_low, mid, cutbacks) + _uzawa(problem, newton, mid, *uzawa, cutbacks)
        step = record(_step(problem, mid, its), tried)
        tried.append(step)
        if step.contact_fraction >= target:
            p_high, high_state, high = mid, problem.state(), step
        else:
            p_low, low = mid, problem.state()
    problem.restore(high_state)
    problem.set_pressure(p_high)
    log.info("membrane: contact fraction %.4g >= %.4g at p = %.6g", high.contact_fraction, target, p_high)
    return [*tried, high]
