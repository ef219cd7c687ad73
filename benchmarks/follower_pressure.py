"""Newton's iterative linear solver on a nonsymmetric tangent: CG against GMRES (and BiCGStab), GAMG on both.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/follower_pressure.py [--n 6] [--steps 2]
    mpirun -n 2 .venv/bin/python benchmarks/follower_pressure.py

The problem: a 10 x 1 x 1 cantilever (10n x n x n boxes of 6 tetrahedra, P2: 61 347 dofs at n = 6), clamped at
x = 0, a follower pressure p = 1 on its bottom face z = 0 that bends it upwards (tip deflection 1.49, 15 % of the
length, at the end), neo-Hookean E = 1e4, nu = 0.3, the displacement formulation, [solver] linear = "iterative"
(the preset, which picks GMRES here because the pressure's load stiffness makes the tangent nonsymmetric) with
``ksp_type`` replaced: cg (the preset before it followed the symmetry), gmres (the preset), bcgs. Output files off;
the forms are compiled by an untimed warm-up on a coarse mesh.

Printed per variant: the run's status, Newton iterations per load step, linear iterations per Newton iteration
(mean, min-max), the failed attempts (cut-backs) and the time to solution (wall, the slowest rank). Asserts nothing.
"""

from __future__ import annotations

import argparse
import logging
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
from model.errors import SolveFailed  # noqa: E402
from model.pipeline import run  # noqa: E402

log = logging.getLogger("benchmarks.follower_pressure")

VARIANTS: list[tuple[str, dict[str, Any]]] = [
    ("CG + GAMG (the preset before)", {"ksp_type": "cg"}),
    ("GMRES + GAMG (the preset)", {}),
    ("BiCGStab + GAMG", {"ksp_type": "bcgs"}),
]


def beam(n: int, steps: int, options: dict[str, Any], pressure: float = 1.0) -> dict[str, Any]:
    return {"mesh": {"generator": "box", "size": [10.0, 1.0, 1.0], "cells": [10 * n, n, n]},
            "discretization": {"degree": 2},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
            "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                         {"on": "zmin", "type": "pressure", "value": [pressure]}],
            "loading": {"steps": steps},
            "probe": [{"name": "tip", "point": [10.0, 0.5, 1.0]}],
            "solver": {"linear": "iterative", "petsc_options": dict(options)},
            "output": {"xdmf": False, "vtu": False, "png": False}}


def solve(raw: dict[str, Any], out: Path) -> tuple[dict[str, Any], float, str]:
    start = time.perf_counter()
    status = "completed"
    try:
        summary = run(parse(raw, ROOT), out)
    except SolveFailed as err:
        status = f"failed: {str(err)[:60]}"
        import json

        summary = MPI.COMM_WORLD.bcast(json.loads((out / "summary.json").read_text())
                                       if MPI.COMM_WORLD.rank == 0 else None, root=0)
    return summary, MPI.COMM_WORLD.allreduce(time.perf_counter() - start, op=MPI.MAX), status


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=6, help="n of the 10n x n x n boxes")
    parser.add_argument("--steps", type=int, default=2, help="load steps")
    parser.add_argument("--variants", type=int, nargs="+", default=list(range(len(VARIANTS))),
                        help="which rows to run (0: CG, 1: GMRES, 2: BiCGStab)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    comm = MPI.COMM_WORLD
    out = Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0))
    solve(beam(1, 1, {}), out / "warm-up")
    rows = []
    for name, options in (VARIANTS[i] for i in args.variants):
        summary, seconds, status = solve(beam(args.n, args.steps, options), out / name.split()[0])
        counts = [c for s in summary["steps"] for c in s.get("linear_iterations_per_newton", [])]
        converged = [s for s in summary["steps"] if s["converged"]]
        failed = len(summary["steps"]) - len(converged)
        newton = " + ".join(str(s["newton_iterations"]) for s in converged) or "-"
        its = f"{np.mean(counts):.1f} ({min(counts)}-{max(counts)})" if counts else "-"
        reasons = sorted({s["snes_reason_name"] for s in summary["steps"] if not s["converged"]})
        rows.append(f"| {name} | {summary['dofs']} | {status}{' ' + ', '.join(reasons) if reasons else ''} | "
                    f"{newton} | {its} | {failed} | {seconds:.1f} |")
        if comm.rank == 0:
            print(rows[-1], flush=True)
    if comm.rank == 0:
        print(f"\n{comm.size} rank(s)\n| variant | dofs | status | Newton its per step | linear its per Newton it "
              "(mean, min-max) | failed attempts | time (s) |\n|---|---|---|---|---|---|---|")
        print("\n".join(rows))


if __name__ == "__main__":
    main()
