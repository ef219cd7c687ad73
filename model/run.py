"""One run: configuration -> set-up -> load steps (SNES) -> summary.json, XDMF, VTU, PNG.

summary.json is rewritten after every attempted step, so a failed run keeps
what it did. Each converged step records probes, reactions and the strain energy;
a failed attempt records its SNES reason and is followed by a cut-back.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

from mpi4py import MPI

from model.config import RunConfig
from model.loadstepping import StepRecord, step_loads
from model.measurements import Volumes, reactions
from model.output import ResultWriter, write_json_atomic
from model.problem import ElasticityProblem
from model.setup import build
from model.solver import NewtonSolver

log = logging.getLogger(__name__)


class SolveFailed(RuntimeError):
    """The load stepping gave up; the message holds the last SNES reason."""


def make_solver(problem: ElasticityProblem, config: RunConfig) -> Any:
    """The solver [solver] asks for: NewtonSolver (exact or projected tangent) or ProjectiveDynamicsSolver."""
    solver = config.solver
    if solver.method == "projective_dynamics":
        from model.projective_dynamics import ProjectiveDynamicsSolver

        options = {**config.petsc_options, "pd_max_iterations": solver.pd_max_iterations,
                   "pd_rtol": solver.pd_rtol, "pd_atol": solver.pd_atol}
        return ProjectiveDynamicsSolver(problem, options)
    return NewtonSolver(problem, config.petsc_options, tangent=solver.tangent)


def run(config: RunConfig, out: Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, Any]:
    """Run a configuration; returns the summary (also written to OUT/summary.json).

    Raises ConfigError before any solve on bad input, SolveFailed (after writing
    the summary) when SNES fails beyond the allowed cut-backs.
    """
    start = time.perf_counter()
    directory = Path(out) if out is not None else config.output.dir
    setup = build(config, comm)
    problem = setup.problem
    solver = make_solver(problem, config)
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
        "wall_time_s": 0.0,
        "status": "running",
        "steps": [],
    }

    def save() -> None:
        summary["wall_time_s"] = time.perf_counter() - start
        if comm.rank == 0:
            write_json_atomic(directory / "summary.json", summary)

    def on_step(record: StepRecord) -> None:
        r = record.result
        step: dict[str, Any] = {
            "load_factor": record.load_factor,
            "newton_iterations": r.iterations,
            "linear_iterations": r.linear_iterations,
            "converged": r.converged,
            "snes_reason": r.reason,
            "snes_reason_name": r.reason_name,
            "residual_norm": r.residual_norm,
            "solve_time_s": record.seconds,
        }
        if setup.activation is not None:
            step["activation"] = setup.activation.values(record.load_factor)
        if r.converged:
            step["energy"] = problem.total_energy()
            step["volumes"] = volumes.current()
            step["probes"] = setup.probes.evaluate(problem.displacement())
            residual = solver.unconstrained_residual()
            step["reactions"] = reactions(problem, residual)
            residual.destroy()
            writer.write_step(record.load_factor)
        summary["steps"].append(step)
        save()
        if comm.rank == 0:
            n = len(summary["steps"])
            status = "converged" if r.converged else f"FAILED ({r.reason_name}), cutting back"
            log.info("step %3d  load %.4f  newton %2d  |R| %.3e  %s", n, record.load_factor, r.iterations,
                     r.residual_norm, status)

    problem.set_load_factor(0.0)
    save()
    ok = step_loads(solver, config.loading.steps, config.loading.max_cutbacks, config.loading.growth, on_step)
    summary["status"] = "completed" if ok else "failed"
    unused = getattr(solver, "unused_options", [])
    if unused:
        summary["unused_petsc_options"] = unused
    png = writer.write_png(f"load factor {problem.load_factor.value:.3g}")
    if png is not None:
        summary["png"] = png.name
    writer.close()
    save()
    solver.destroy()
    if not ok:
        last = summary["steps"][-1]
        raise SolveFailed(f"SNES failed at load factor {last['load_factor']:.6g}: reason {last['snes_reason']} "
                          f"({last['snes_reason_name']}); results up to load factor "
                          f"{problem.load_factor.value:.6g} are in {directory}")
    return summary
