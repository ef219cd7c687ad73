"""Newton's linear solver presets on a Taylor-Hood problem: MUMPS against the Schur-complement fieldsplit.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/linear_presets.py [--sizes 4 6 8] [--variants]
    mpirun -n 2 .venv/bin/python benchmarks/linear_presets.py

The problem: a 2 x 1 x 1 bar (2n x n x n boxes of 6 tetrahedra), clamped at x = 0, a traction (0, 100, 30) on
x = 2 in 2 load steps; neo-Hookean, E = 1e4, nu = 0.49 and 0.4999; Taylor-Hood P2/P1 (quadrature degree 2).
Output files off; the forms are compiled by an untimed warm-up on the smallest mesh.

Table 1 (always): for each size and nu, [solver] linear = "direct" and "iterative" (the presets, nothing
overridden): dofs, Newton iterations, linear iterations per Newton iteration (the mean, and min-max), time
to solution (model.pipeline.run, wall) and the largest probe difference between the two presets (relative).

Table 2 (--variants; on the middle size, nu = 0.4999): the iterative preset with the displacement block's AMG
(GAMG with the rigid-body near null space, or hypre BoomerAMG) and the Schur factorisation (lower, upper,
full; MINRES with the block-diagonal one) swapped, and the time to assemble the weighted pressure mass matrix
Sp (what assembling it per Newton step instead of once per run would add per step: it depends on the
materials only, so it would be the same matrix). Asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from model.config import parse  # noqa: E402
from model.pipeline import build, run  # noqa: E402

VARIANTS: list[tuple[str, dict[str, Any]]] = [
    ("GAMG, lower (the preset)", {}),
    ("GAMG, upper", {"pc_fieldsplit_schur_fact_type": "upper"}),
    ("GAMG, full", {"pc_fieldsplit_schur_fact_type": "full"}),
    ("GAMG, diag + MINRES", {"pc_fieldsplit_schur_fact_type": "diag", "ksp_type": "minres"}),
    ("hypre, lower", {"fieldsplit_u_pc_type": "hypre"}),
    ("hypre, full", {"fieldsplit_u_pc_type": "hypre", "pc_fieldsplit_schur_fact_type": "full"}),
    ("GAMG, lower, Jacobi on Sp", {"fieldsplit_p_pc_type": "jacobi"}),
]


def bar(n: int, nu: float, linear: str, options: dict[str, Any] | None = None) -> dict[str, Any]:
    return {"mesh": {"generator": "box", "size": [2.0, 1.0, 1.0], "cells": [2 * n, n, n]},
            "discretization": {"degree": 2, "quadrature_degree": 2, "formulation": "mixed"},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": nu}],
            "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                         {"on": "xmax", "type": "traction", "value": [0.0, 100.0, 30.0]}],
            "loading": {"steps": 2},
            "probe": [{"name": "tip", "point": [2.0, 0.5, 0.5]}],
            "solver": {"linear": linear, "petsc_options": dict(options or {})},
            "output": {"xdmf": False, "vtu": False, "png": False}}


def solve(raw: dict[str, Any], out: Path) -> tuple[dict[str, Any], float]:
    start = time.perf_counter()
    summary = run(parse(raw, ROOT), out)
    return summary, MPI.COMM_WORLD.allreduce(time.perf_counter() - start, op=MPI.MAX)


def per_newton(summary: dict[str, Any]) -> str:
    counts = [c for s in summary["steps"] for c in s.get("linear_iterations_per_newton", [])]
    return f"{np.mean(counts):.1f} ({min(counts)}-{max(counts)})" if counts else "-"


def newton(summary: dict[str, Any]) -> str:
    return " + ".join(str(s["newton_iterations"]) for s in summary["steps"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 6, 8], help="n of the 2n x n x n boxes")
    parser.add_argument("--nus", type=float, nargs="+", default=[0.49, 0.4999])
    parser.add_argument("--variants", action="store_true", help="also table 2 (on the middle size)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    out = Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None))
    for nu in args.nus:  # warm-up: compile the forms
        run(parse({**bar(2, nu, "direct"), "loading": {"steps": 1}}, ROOT), out / "warm-up")
    rows = []
    for n in args.sizes:
        for nu in args.nus:
            direct, t_direct = solve(bar(n, nu, "direct"), out / f"d{n}_{nu}")
            iterative, t_iterative = solve(bar(n, nu, "iterative"), out / f"i{n}_{nu}")
            a, b = np.array(iterative["steps"][-1]["probes"]["tip"]), np.array(direct["steps"][-1]["probes"]["tip"])
            diff = float(np.linalg.norm(a - b) / np.linalg.norm(b))
            for name, summary, wall in (("direct", direct, t_direct), ("iterative", iterative, t_iterative)):
                rows.append(f"| {summary['dofs']} | {nu} | {name} | {newton(summary)} | {per_newton(summary)} "
                            f"| {wall:.1f} | {diff:.1e} |")
            if comm.rank == 0:
                print(rows[-2], rows[-1], sep="\n", flush=True)
    if comm.rank == 0:
        print(f"\nTaylor-Hood P2/P1 neo-Hookean bar, 2 load steps, {comm.size} rank(s)\n")
        print("| dofs | nu | linear | Newton its | linear its per Newton it: mean (min-max) | time to solution (s) "
              "| tip probe, iterative vs direct |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(rows))
    if not args.variants:
        return
    n = args.sizes[len(args.sizes) // 2]
    rows = []
    for label, options in VARIANTS:
        summary, wall = solve(bar(n, 0.4999, "iterative", options), out / f"v{len(rows)}")
        status = "" if summary["status"] == "completed" else " (failed)"
        rows.append(f"| {label}{status} | {newton(summary)} | {per_newton(summary)} | {wall:.1f} |")
        if comm.rank == 0:
            print(rows[-1], flush=True)
    from model.solvers.linear import MixedFields

    setup = build(parse(bar(n, 0.4999, "iterative"), ROOT))
    start = time.perf_counter()
    fields = MixedFields(setup.problem)
    seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    fields.destroy()
    if comm.rank == 0:
        print(f"\nVariants of the iterative preset, {summary['dofs']} dofs, nu = 0.4999, {comm.size} rank(s)\n")
        print("| variant | Newton its | linear its per Newton it: mean (min-max) | time to solution (s) |")
        print("|---|---|---|---|")
        print("\n".join(rows))
        print(f"\nindex sets, near null space and Sp (MixedFields, once per run): {seconds:.2f} s")


if __name__ == "__main__":
    main()
