"""Solvers for shape targeting: exact Newton, projected ("modified") Newton, Projective Dynamics (figures only).

The problem: a 2 x 0.5 x 0.5 bar clamped at xmin, law shape_target alone (mu = 1 kPa, kappa = 0)
with the procedural, incompatible targets of tests/test_projected_tangent.py (bending_targets:
the top lengthens and the bottom shortens, so the bar bends; a width change and an in-plane
shear vary along it), P1, quadrature degree 2, loaded in --steps equal steps of the target
(S(t) = I + t (...)). Every method stops a load step at the same residual reduction
||r|| <= --rtol ||r_0|| (Newton: snes_rtol, snes_stol = 0; Projective Dynamics: pd_rtol), r the
residual with Dirichlet rows zeroed:

(a) Newton, exact tangent, MUMPS LU (the default solver);
(b) Newton, projected tangent (model.solvers.tangent: per-point PSD projection of dP/dF), MUMPS LU and
    CG + GAMG (rigid-body near null space); also the exact tangent with CG + GAMG, for contrast;
(c) Projective Dynamics (model.solvers.projective_dynamics): local polar step + global solve with the
    constant matrix, factorised once (MUMPS LU).

Times: wall time of the load stepping (forms compiled by an untimed warm-up, set-up excluded),
of the polar updates within it (PolarField.update: the dolfinx Expression of M = F S at the
quadrature points and the batched polar rotation of forms.polar), and of the projection
(ProjectedTangent.update: Expression of dP/dF and numpy eigen-decompositions). In parallel
each time is the slowest rank's. The last column compares the final probe displacements with (a).

    python benchmarks/shape_targeting.py [--cells 32 8 8] [--steps 2] [--rtol 1e-8] [--json out.json]
    python benchmarks/shape_targeting.py --quick
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
for path in (ROOT, ROOT / "tests"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from model import compat  # noqa: E402
from model.config import parse  # noqa: E402
from model.pipeline import build  # noqa: E402
from model.solvers.loadstepping import StepRecord, step_loads  # noqa: E402
from model.solvers.newton import NewtonSolver  # noqa: E402
from model.solvers.projective_dynamics import ProjectiveDynamicsSolver  # noqa: E402

TARGETS = ROOT / "tests" / "test_projected_tangent.py"
PROBES = {"end_centre": [2.0, 0.25, 0.25], "end_corner": [2.0, 0.5, 0.5], "middle_corner": [1.0, 0.0, 0.5]}
LU = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
CG_GAMG = {"ksp_type": "cg", "pc_type": "gamg", "ksp_rtol": 1e-8, "ksp_max_it": 2000}

#: (label, method, tangent, linear solver label, linear-solver options)
CASES = [
    ("(a) Newton, exact tangent", "newton", "exact", "MUMPS LU", LU),
    ("(b) Newton, projected tangent", "newton", "projected", "MUMPS LU", LU),
    ("(b) Newton, projected tangent", "newton", "projected", "CG + GAMG", CG_GAMG),
    ("Newton, exact tangent (contrast)", "newton", "exact", "CG + GAMG", CG_GAMG),
    ("(c) Projective Dynamics", "projective_dynamics", "exact", "MUMPS LU", LU),
    ("(a) Newton, exact tangent, full steps", "newton", "exact", "MUMPS LU", {**LU, "snes_linesearch_type": "basic"}),
    ("(b) Newton, projected tangent, full steps", "newton", "projected", "MUMPS LU",
     {**LU, "snes_linesearch_type": "basic"}),
]


def configuration(cells: tuple[int, int, int], steps: int) -> dict[str, Any]:
    return {
        "mesh": {"generator": "box", "size": [2.0, 0.5, 0.5], "cells": list(cells)},
        "discretization": {"degree": 1, "quadrature_degree": 2},
        "material": [{"region": "all", "law": "shape_target", "mu": 1.0e3, "kappa": 0.0,
                      "S_function": f"{TARGETS}:bending_targets"}],
        "boundary": [{"on": "xmin", "type": "displacement", "components": [0, 1, 2], "value": [0.0, 0.0, 0.0]}],
        "loading": {"steps": steps},
        "probe": [{"name": name, "point": point} for name, point in PROBES.items()],
        "output": {"xdmf": False, "vtu": False, "png": False},
    }


class Stopwatch:
    """Accumulated wall time and calls of a wrapped bound method."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.calls = 0

    def wrap(self, method: Callable[[], None]) -> Callable[[], None]:
        def timed() -> None:
            start = time.perf_counter()
            method()
            self.seconds += time.perf_counter() - start
            self.calls += 1

        return timed


def make_solver(problem, method: str, tangent: str, options: dict, rtol: float, max_iterations: int):
    if method == "projective_dynamics":
        return ProjectiveDynamicsSolver(problem, {**options, "pd_rtol": rtol, "pd_max_iterations": max_iterations,
                                                  "pd_atol": 0.0})
    newton = {**options, "snes_rtol": rtol, "snes_atol": 0.0, "snes_stol": 0.0, "snes_max_it": max_iterations}
    return NewtonSolver(problem, newton, tangent=tangent)


def projection_breakdown(comm: MPI.Comm, tangent) -> dict[str, float]:
    """Seconds of one projected-tangent update split into the Expression of dP/dF and the numpy projection."""
    from forms.projection import project_tangent

    evaluate = project = 0.0
    for expression, cells, _ in tangent.blocks:
        start = time.perf_counter()
        values = compat.evaluate(expression, tangent.problem.domain.mesh, cells).reshape(-1, 3, 3, 3, 3)
        evaluate += time.perf_counter() - start
        start = time.perf_counter()
        project_tangent(values)
        project += time.perf_counter() - start
    return {"expression_s": comm.allreduce(evaluate, op=MPI.MAX), "projection_s": comm.allreduce(project, op=MPI.MAX)}


def run_case(comm: MPI.Comm, raw: dict, case: tuple, rtol: float, newton_max: int, pd_max: int) -> dict[str, Any]:
    label, method, tangent, linear_label, options = case
    config = parse(raw, ROOT)
    max_iterations = pd_max if method == "projective_dynamics" else newton_max
    warm = build(config, comm)  # compiles every form into the JIT cache, untimed
    make_solver(warm.problem, method, tangent, options, rtol, max_iterations).destroy()
    setup = build(config, comm)
    problem = setup.problem
    solver = make_solver(problem, method, tangent, options, rtol, max_iterations)
    polar = Stopwatch()
    for field in problem.polar_fields:
        field.update = polar.wrap(field.update)
    projection = Stopwatch()
    if getattr(solver, "projected", None) is not None:
        solver.projected.update = projection.wrap(solver.projected.update)
    records: list[StepRecord] = []
    comm.Barrier()
    start = time.perf_counter()
    completed = step_loads(solver, raw["loading"]["steps"], max_cutbacks=3, on_step=records.append)
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    probes = setup.probes.evaluate(problem.displacement()) if completed else None
    points = comm.allreduce(sum(len(f.cells) for f in problem.polar_fields) * problem.polar_fields[0].num_points,
                            op=MPI.SUM)
    breakdown, indefinite = None, None
    if getattr(solver, "projected", None) is not None:
        breakdown = projection_breakdown(comm, solver.projected)
        solver.projected.count_negative = True  # at the final state
        solver.projected.invalidate()
        solver.projected.update()
        indefinite = comm.allreduce(solver.projected.negative_points, op=MPI.SUM)
    solver.destroy()
    msh = setup.domain.mesh
    return {
        "label": label, "method": method, "tangent": tangent, "linear_solver": linear_label,
        "cells": msh.topology.index_map(3).size_global,
        "dofs": problem.space.dofmap.index_map.size_global * problem.space.dofmap.index_map_bs,
        "quadrature_points": points, "ranks": comm.size,
        "iterations": [r.result.iterations for r in records],
        "converged": [r.result.converged for r in records],
        "failures": sorted({r.result.reason_name for r in records if not r.result.converged}),
        "projection_breakdown": breakdown, "indefinite_points_at_end": indefinite,
        "linear_iterations": sum(r.result.linear_iterations for r in records),
        "completed": completed, "wall_s": wall,
        "polar_s": comm.allreduce(polar.seconds, op=MPI.MAX), "polar_calls": polar.calls,
        "projection_s": comm.allreduce(projection.seconds, op=MPI.MAX), "projection_calls": projection.calls,
        "probes": probes,
    }


def table(results: list[dict[str, Any]]) -> str:
    reference = next((r["probes"] for r in results if r["probes"] is not None), None)
    lines = ["| solver | linear solver | iterations per load step (x = failed) | total | linear its "
             "| wall (s) | polar updates (s, calls) | projection (s, calls) | max probe diff vs (a) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        its = " ".join(f"{n}{'' if ok else 'x'}" for n, ok in zip(r["iterations"], r["converged"]))
        projection = f"{r['projection_s']:.1f} ({r['projection_calls']})" if r["projection_calls"] else "-"
        if r["probes"] is None or reference is None:
            diff = "not completed"
        else:
            a = np.array(list(reference.values()))
            b = np.array(list(r["probes"].values()))
            diff = f"{np.abs(a - b).max() / np.abs(a).max():.1e}"
        lines.append(f"| {r['label']} | {r['linear_solver']} | {its} | {sum(r['iterations'])} "
                     f"| {r['linear_iterations']} | {r['wall_s']:.1f} "
                     f"| {r['polar_s']:.1f} ({r['polar_calls']}) | {projection} | {diff} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, nargs=3, default=[32, 8, 8], help="hexahedra per axis (6 tets each)")
    parser.add_argument("--steps", type=int, default=2, help="load steps")
    parser.add_argument("--rtol", type=float, default=1e-8, help="residual reduction per load step")
    parser.add_argument("--newton-max", type=int, default=200, help="Newton iterations per load step at most")
    parser.add_argument("--pd-max", type=int, default=10000, help="PD iterations per load step at most")
    parser.add_argument("--quick", action="store_true", help="a small mesh (smoke test)")
    parser.add_argument("--skip", nargs="*", default=[], type=int, help="case numbers (0-4) to leave out")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    root = comm.rank == 0
    logging.getLogger("model").setLevel(logging.ERROR)
    cells = (8, 2, 2) if args.quick else tuple(args.cells)
    raw = configuration(cells, args.steps)
    results = []
    for i, case in enumerate(CASES):
        if i in args.skip:
            continue
        r = run_case(comm, raw, case, args.rtol, args.newton_max, args.pd_max)
        results.append(r)
        if root:
            print(f"{r['label']}, {r['linear_solver']}: iterations {r['iterations']} "
                  f"{'completed' if r['completed'] else 'FAILED'} in {r['wall_s']:.1f} s "
                  f"(polar {r['polar_s']:.1f} s / {r['polar_calls']} calls, projection {r['projection_s']:.1f} s "
                  f"/ {r['projection_calls']} calls); probes {r['probes']}", flush=True)
    first = results[0]
    if root:
        print(f"\n## Shape targeting: bending bar, {first['cells']} cells P1, {first['dofs']} dofs, "
              f"{first['quadrature_points']} quadrature points, {args.steps} load steps, "
              f"residual reduction {args.rtol:g} per step, {comm.size} rank{'s' if comm.size > 1 else ''}\n")
        print(table(results))
        polar = [(r["polar_s"], r["polar_calls"]) for r in results if r["polar_calls"]]
        seconds, calls = map(sum, zip(*polar))
        per_point = seconds / calls / first["quadrature_points"] * comm.size * 1e6
        print(f"\npolar update: {seconds / calls * 1e3:.1f} ms per call, {per_point:.2f} us per quadrature point "
              f"(per rank: Expression of F S + forms.polar.polar_rotation)")
        proj = [(r["projection_s"], r["projection_calls"]) for r in results if r["projection_calls"]]
        if proj:
            seconds, calls = map(sum, zip(*proj))
            per_point = seconds / calls / first["quadrature_points"] * comm.size * 1e6
            split = next(r["projection_breakdown"] for r in results if r["projection_breakdown"])
            print(f"projected tangent: {seconds / calls * 1e3:.1f} ms per update, {per_point:.2f} us per quadrature "
                  f"point; one update, in one go: Expression of dP/dF {split['expression_s']:.2f} s, "
                  f"forms.projection.project_tangent {split['projection_s']:.2f} s")
            indefinite = next(r["indefinite_points_at_end"] for r in results if r["projection_breakdown"])
            print(f"at the converged state dP/dF is indefinite at {indefinite} of {first['quadrature_points']} "
                  f"quadrature points ({100 * indefinite / first['quadrature_points']:.0f}%)")
        for r in results:
            if r["failures"]:
                print(f"failed attempts of {r['label']}, {r['linear_solver']} (cut back): {', '.join(r['failures'])}")
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps({"cells": cells, "steps": args.steps, "rtol": args.rtol,
                                             "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
