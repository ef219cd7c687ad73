"""Mixed-form ARAP (the skinning seed's "Mixed FEM") against displacement-only ARAP / shape targeting.

    .venv/bin/python examples/mixed_arap.py [--size 0.06] [--steps 4] [--out results/mixed_arap]

2D: the gingerbread man (meshes.gingerbread), both feet pinned by penalty handles, the right hand swung up by 60
degrees about the right shoulder and the head pushed sideways by 0.15: solved by displacement-only ARAP
(closed-form SO(2) rotation) and by the mixed form (S = S^T, R and the multiplier of F = R S per triangle),
Newton on the whole system. 3D: a 1 x 1 x 3 bar with per-cell shape targets S_t, clamped at z = 0 and its top
moved by (0.8, 0.3, -0.4): the pipeline's shape_target law (displacement only, polar rotation per quadrature
point) against the mixed form with a general S. Prints dofs, Newton iterations, time and the largest
difference of the displacements; with --out writes the table (CSV) and a picture. Used by tests/test_mixed_arap.py
and notebooks/mixed_arap.py.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from dolfinx import fem
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from meshes.gingerbread import gingerbread  # noqa: E402
from model import compat  # noqa: E402
from model.config import parse  # noqa: E402
from model.domain.distribute import build_domain  # noqa: E402
from model.pipeline import build  # noqa: E402
from model.problem.mixed_arap import ArapProblem, ArapResult, Dirichlet, Handle  # noqa: E402
from model.solvers.arap import solve_arap  # noqa: E402
from model.solvers.loadstepping import step_loads  # noqa: E402
from model.solvers.newton import NewtonSolver  # noqa: E402

OPTIONS = {"snes_rtol": 1e-12, "snes_atol": 1e-13}
SHOULDER = (0.36, 1.19)


def max_difference(a: fem.Function, b: fem.Function) -> float:
    """max |a - b| over the nodes, a interpolated into b's space (the same P1 element: exact)."""
    v = fem.Function(b.function_space)
    v.interpolate(a)
    return float(b.function_space.mesh.comm.allreduce(np.abs(v.x.array - b.x.array).max(initial=0.0), op=MPI.MAX))


def gingerbread_domain(size: float):
    comm = MPI.COMM_WORLD
    return build_domain(comm, gingerbread(size=size) if comm.rank == 0 else None)


def gingerbread_handles(domain, stiffness: float = 1e3, swing: float = np.pi / 3, lean: float = 0.15) -> list[Handle]:
    """Feet pinned, right hand swung up by ``swing`` about the right shoulder, head pushed by ``lean`` along x."""
    return [Handle(domain.region_cells("left_foot"), stiffness), Handle(domain.region_cells("right_foot"), stiffness),
            Handle(domain.region_cells("right_hand"), stiffness, angle=swing, center=SHOULDER),
            Handle(domain.region_cells("head"), stiffness, translation=(lean, 0.0))]


def pose_gingerbread(size: float = 0.06, steps: int = 4, stretch: str = "symmetric"):
    """(domain, {formulation: ArapResult}) of the gingerbread pose, displacement-only and mixed."""
    domain = gingerbread_domain(size)
    results: dict[str, ArapResult] = {}
    for formulation in ("displacement", "mixed"):
        problem = ArapProblem(domain.mesh, formulation=formulation, stretch=stretch, mu=1.0,
                              handles=gingerbread_handles(domain))
        results[formulation] = solve_arap(problem, steps, OPTIONS)
    return domain, results


def bar_targets(msh) -> fem.Function:
    """Per-cell symmetric positive definite targets S_t(x) varying along the bar (DG0)."""
    S = fem.Function(compat.function_space(msh, "DG", 0, (3, 3)))

    def values(x: np.ndarray) -> np.ndarray:
        out = np.zeros((9, x.shape[1]))
        for i in range(3):
            out[4 * i] = 1.0 + 0.15 * np.sin(2.0 * x[2] + i)
        out[1] = out[3] = 0.1 * np.cos(3.0 * x[1] + x[2])
        return out

    S.interpolate(values)
    return S


def bend_bar(cells: tuple[int, int, int] = (2, 2, 6), steps: int = 2, value=(0.8, 0.3, -0.4)):
    """(pipeline displacement Function, its time and iterations, mixed ArapResult) for the 3D bar."""
    import time

    raw = {"mesh": {"generator": "box", "size": [1.0, 1.0, 3.0], "cells": list(cells)},
           "discretization": {"degree": 1, "quadrature_degree": 1},
           "material": [{"region": "all", "law": "shape_target", "mu": 1.0}],
           "boundary": [{"on": "zmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                        {"on": "zmax", "type": "displacement", "value": list(value)}]}
    setup = build(parse(raw))
    S_t = setup.targets[0].function
    S_t.interpolate(bar_targets(setup.domain.mesh))
    solver = NewtonSolver(setup.problem, options={**OPTIONS, "snes_linesearch_type": "basic"})
    records = []
    start = time.perf_counter()
    outcome = step_loads(solver, steps, on_step=records.append)
    elapsed = time.perf_counter() - start
    if not outcome.completed:
        raise RuntimeError(f"bar: the displacement-only solve failed ({outcome.reason})")
    iterations = [r.result.iterations for r in records if r.result.converged]
    solver.destroy()
    domain = setup.domain
    bcs = [Dirichlet(domain.boundary_facets("zmin"), [0.0, 0.0, 0.0]),
           Dirichlet(domain.boundary_facets("zmax"), list(value))]
    problem = ArapProblem(domain.mesh, formulation="mixed", stretch="general", target=S_t, dirichlet=bcs)
    mixed = solve_arap(problem, steps, OPTIONS)
    dofs = setup.problem.space.dofmap.index_map.size_global * setup.problem.space.dofmap.index_map_bs
    return setup.problem.solution, {"time_s": elapsed, "dofs": dofs, "iterations": iterations}, mixed


def table(size: float, steps: int) -> list[dict]:
    """One row per case and formulation: dofs, Newton iterations, time, energy, difference to displacement-only."""
    rows = []
    _, results = pose_gingerbread(size, steps)
    disp, mixed = results["displacement"], results["mixed"]
    gap = max_difference(mixed.u, disp.u)
    for name, r in results.items():
        rows.append({"case": "gingerbread 2D", "formulation": name, "dofs": r.dofs, "newton": sum(r.iterations),
                     "time_s": r.time_s, "energy": r.energy, "max |u - u_disp|": 0.0 if r is disp else gap})
    u_disp, info, mixed3 = bend_bar(steps=max(2, steps // 2))
    rows.append({"case": "bar 3D, S_t != I", "formulation": "displacement (pipeline shape_target)",
                 "dofs": info["dofs"], "newton": sum(info["iterations"]), "time_s": info["time_s"],
                 "energy": None, "max |u - u_disp|": 0.0})
    rows.append({"case": "bar 3D, S_t != I", "formulation": "mixed (general S)", "dofs": mixed3.dofs,
                 "newton": sum(mixed3.iterations), "time_s": mixed3.time_s, "energy": mixed3.energy,
                 "max |u - u_disp|": max_difference(mixed3.u, u_disp)})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=0.06, help="gingerbread element size (default 0.06)")
    parser.add_argument("--steps", type=int, default=4, help="load steps (default 4)")
    parser.add_argument("--out", type=Path, default=None, help="folder for table.csv and pose.png")
    args = parser.parse_args()
    rows = table(args.size, args.steps)
    if MPI.COMM_WORLD.rank == 0:
        import pandas as pd

        frame = pd.DataFrame(rows)
        print(frame.to_string(index=False))
        if args.out is not None:
            args.out.mkdir(parents=True, exist_ok=True)
            frame.to_csv(args.out / "table.csv", index=False)
            print(f"wrote {args.out / 'table.csv'}")


if __name__ == "__main__":
    main()
