"""One run: configuration -> set-up -> load steps or time steps (SNES) -> summary.json, XDMF, VTU, PNG.

summary.json is rewritten after every attempted step, so a failed run keeps
what it did. Each converged step records probes, reactions and the strain energy
(plus contact, sliding and, in a dynamic run, time and kinetic energy); a failed
attempt records its SNES reason and is followed by a cut-back.

Quasi-static runs step the load factor 0 -> 1 (model.loadstepping). A [dynamics] scheme
integrates in time instead (model.dynamics): the "load factor" passed to expressions, activation
curves and bone motions is the time t, and constant loads are scaled by min(t / load_ramp, 1).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

from mpi4py import MPI

from model import compat
from model.config import RunConfig
from model.loadstepping import step_loads
from model.measurements import Volumes, reactions
from model.output import ResultWriter, write_json_atomic
from model.problem import ElasticityProblem
from model.setup import Setup, build
from model.solver import NewtonSolver

log = logging.getLogger(__name__)


class SolveFailed(RuntimeError):
    """The load stepping gave up; the message holds the last SNES reason."""


def make_solver(problem: ElasticityProblem, config: RunConfig, contacts: list[Any] | None = None) -> Any:
    """The solver [solver] asks for: NewtonSolver (exact or projected tangent), ProjectiveDynamicsSolver,
    or, with contacts, model.contact's VI / Uzawa solvers (same interface)."""
    solver = config.solver
    if solver.method == "projective_dynamics":
        from model.projective_dynamics import ProjectiveDynamicsSolver

        options = {**config.petsc_options, "pd_max_iterations": solver.pd_max_iterations,
                   "pd_rtol": solver.pd_rtol, "pd_atol": solver.pd_atol}
        return ProjectiveDynamicsSolver(problem, options)
    if contacts:
        from model.contact import make_contact_solver

        return make_contact_solver(problem, contacts, config.petsc_options, tangent=solver.tangent)
    return NewtonSolver(problem, config.petsc_options, tangent=solver.tangent)


def _dynamics(setup: Setup, config: RunConfig) -> Any:
    """The time integrator of a dynamic run (before the solver: it adds inertia and damping terms)."""
    from model.dynamics import Dynamics

    spec = config.dynamics
    problem = setup.problem
    density = {m.region: m.density for m in config.materials}
    problem.load_scale = spec.load_scale
    dynamics = Dynamics(problem, density if "all" not in density else density["all"], spec.scheme,
                        spec.rayleigh, spec.dt, rho_infinity=spec.rho_infinity)
    return dynamics


def _initial_equilibrium(setup: Setup, config: RunConfig) -> None:
    """u_0 of a dynamic run = the quasi-static solution at t = 0 (before inertia is added to the forms).

    Reached by continuation: the activation goes from 0 to its t = 0 values in loading.steps steps,
    cut back on failure (a muscle activated at once from rest would invert elements in Newton's
    first iterate).
    """
    problem = setup.problem
    problem.load_scale = config.dynamics.load_scale
    problem.set_load_factor(0.0)
    activation = setup.activation
    full = activation.function.x.array.copy() if activation is not None else None
    solver = make_solver(problem, config, setup.contacts)
    nominal = 1.0 / config.loading.steps
    increment, current, cutbacks, result = nominal, 0.0, 0, None
    while current < 1.0 - 1e-12:
        target = min(current + increment, 1.0)
        saved = problem.solution.x.array.copy()
        if activation is not None:
            activation.function.x.array[:] = target * full
        problem.invalidate_state()
        result = solver.solve()
        if result.converged:
            current, cutbacks = target, 0
            increment = min(increment * config.loading.growth, nominal)
            continue
        problem.solution.x.array[:] = saved
        cutbacks += 1
        increment *= 0.5
        if cutbacks > config.loading.max_cutbacks:
            break
    solver.destroy()
    problem._forms = None  # the dynamic run compiles its own forms (inertia and damping added)
    if result is None or current < 1.0 - 1e-12:
        raise SolveFailed(f"the initial equilibrium (dynamics.initial = \"equilibrium\") failed at activation "
                          f"fraction {target:.4g}: SNES reason {result.reason} ({result.reason_name})")
    log.info("initial equilibrium reached (activation continuation)")


def run(config: RunConfig, out: Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, Any]:
    """Run a configuration; returns the summary (also written to OUT/summary.json).

    Raises ConfigError before any solve on bad input, SolveFailed (after writing
    the summary) when SNES fails beyond the allowed cut-backs.
    """
    start = time.perf_counter()
    directory = Path(out) if out is not None else config.output.dir
    setup = build(config, comm)
    versions = comm.bcast(compat.versions() if comm.rank == 0 else None, root=0)
    if comm.rank == 0:
        log.info("dolfinx %s, PETSc %s, %s", versions["dolfinx"], versions["petsc"], versions["os"])
    problem = setup.problem
    dynamic = config.dynamics is not None and config.dynamics.is_dynamic
    if dynamic and config.dynamics.initial == "equilibrium":
        _initial_equilibrium(setup, config)
    dynamics = _dynamics(setup, config) if dynamic else None
    solver = make_solver(problem, config, setup.contacts)
    writer = ResultWriter(problem, directory, config.output.xdmf, config.output.vtu, config.output.png)
    msh = setup.domain.mesh
    imap = problem.space.dofmap.index_map
    volumes = Volumes(problem)
    summary: dict[str, Any] = {
        "dofs": imap.size_global * problem.space.dofmap.index_map_bs,
        "cells": msh.topology.index_map(msh.topology.dim).size_global,
        "ranks": comm.size,
        "region_volumes": volumes.reference,
        "boundary_areas": volumes.areas,
        "solver": {"method": config.solver.method, "tangent": config.solver.tangent},
        "versions": versions,
        "wall_time_s": 0.0,
        "status": "running",
        "steps": [],
    }
    if dynamic:
        spec = config.dynamics
        summary["dynamics"] = {"scheme": spec.scheme, "dt": spec.dt, "end_time": spec.end_time,
                               "rayleigh": list(spec.rayleigh)}

    def save() -> None:
        summary["wall_time_s"] = time.perf_counter() - start
        if comm.rank == 0:
            write_json_atomic(directory / "summary.json", summary)

    def record_step(t: float, r: Any, extra: dict[str, Any]) -> None:
        step: dict[str, Any] = {
            "load_factor": float(problem.load_factor.value) if dynamic else t,
            **extra,
            "newton_iterations": r.iterations,
            "linear_iterations": r.linear_iterations,
            "converged": r.converged,
            "snes_reason": r.reason,
            "snes_reason_name": r.reason_name,
            "residual_norm": r.residual_norm,
        }
        if setup.activation is not None:
            step["activation"] = setup.activation.values(t)
        if r.converged:
            step["energy"] = problem.total_energy()
            if dynamics is not None:
                step["kinetic_energy"] = dynamics.kinetic_energy()
            step["volumes"] = volumes.current()
            step["probes"] = setup.probes.evaluate(problem.displacement())
            residual = solver.unconstrained_residual()
            step["reactions"] = reactions(problem, residual)
            residual.destroy()
            if setup.contacts:
                from model.contact import contact_report

                step["contact"] = contact_report(setup.contacts)
            if setup.sliding:
                step["sliding"] = {c.surface: {"max_gap": c.max_gap(), "force": c.force()} for c in setup.sliding}
            writer.write_step(t)
        summary["steps"].append(step)
        save()
        if comm.rank == 0:
            n = len(summary["steps"])
            status = "converged" if r.converged else f"FAILED ({r.reason_name}), cutting back"
            what = "t" if dynamic else "load"
            log.info("step %3d  %s %.4f  newton %2d  |R| %.3e  %s", n, what, t, r.iterations, r.residual_norm,
                     status)

    if dynamic:
        from model.dynamics import step_time

        problem.set_load_factor(0.0)
        dynamics.initialize(time=0.0, load_factor=0.0)
        save()
        spec = config.dynamics
        ok = step_time(solver, dynamics, spec.end_time, spec.dt,
                       lambda rec: record_step(rec.time, rec.result, {"time": rec.time, "dt": rec.dt}),
                       max_cutbacks=config.loading.max_cutbacks, growth=config.loading.growth)
    else:
        problem.set_load_factor(0.0)
        save()
        ok = step_loads(solver, config.loading.steps, config.loading.max_cutbacks, config.loading.growth,
                        lambda rec: record_step(rec.load_factor, rec.result, {"solve_time_s": rec.seconds}))
    summary["status"] = "completed" if ok else "failed"
    unused = getattr(solver, "unused_options", [])
    if unused:
        summary["unused_petsc_options"] = unused
    what = "t" if dynamic else "load factor"
    png = writer.write_png(f"{what} {problem.time:.3g}")
    if png is not None:
        summary["png"] = png.name
    writer.close()
    save()
    solver.destroy()
    if dynamics is not None:
        dynamics.destroy()
    if not ok:
        last = summary["steps"][-1]
        raise SolveFailed(f"SNES failed at {what} {last.get('time', last['load_factor']):.6g}: reason "
                          f"{last['snes_reason']} ({last['snes_reason_name']}); results up to {what} "
                          f"{problem.time:.6g} are in {directory}")
    return summary
