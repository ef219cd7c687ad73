"""Cook's membrane convergence study: P1 and P2 displacement vs Taylor-Hood, against 6.9083 mm.

    python benchmarks/cook_convergence.py [--quick]

Prints a Markdown table: formulation, mesh (cells per edge), dofs, corner u_y, error, Newton
iterations per step, wall time. P1/P2 displacement runs use full Newton steps
(snes_linesearch_type = basic): a residual-norm line search stalls on the stiff locked system.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpi4py import MPI  # noqa: E402

from model.config import parse  # noqa: E402
from model.pipeline import run  # noqa: E402

REFERENCE = 6.9083


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="coarse meshes only")
    args = parser.parse_args()
    cases = [(1, "displacement", n) for n in (4, 8, 16, 32)] + [(2, "displacement", n) for n in (4, 8, 16)]
    cases += [(2, "mixed", n) for n in (4, 8, 16, 24)]
    if args.quick:
        cases = [c for c in cases if c[2] <= 8]
    base = tomllib.loads((ROOT / "examples" / "cook.toml").read_text())
    rows = []
    out = Path(MPI.COMM_WORLD.bcast(tempfile.mkdtemp() if MPI.COMM_WORLD.rank == 0 else None))
    for degree, formulation, n in cases:
        raw = {**base, "mesh": {**base["mesh"], "cells": n},
               "discretization": {"degree": degree, "quadrature_degree": 2 * degree, "formulation": formulation},
               "output": {"xdmf": False, "vtu": False, "png": False},
               "solver": {"petsc_options": {"snes_linesearch_type": "bt" if formulation == "mixed" else "basic"}}}
        start = time.perf_counter()
        summary = run(parse(raw, ROOT / "examples"), out)
        uy = summary["steps"][-1]["probes"]["top_right"][1]
        its = " ".join(str(s["newton_iterations"]) for s in summary["steps"])
        name = f"P{degree}" + ("/P1 Taylor-Hood" if formulation == "mixed" else " displacement")
        rows.append(f"| {name} | {n} | {summary['dofs']} | {uy:.4f} | {100 * (uy - REFERENCE) / REFERENCE:+.2f}% "
                    f"| {its} | {time.perf_counter() - start:.1f} |")
    if MPI.COMM_WORLD.rank == 0:
        print(f"Cook's membrane, top-right u_y (reference {REFERENCE} mm), {MPI.COMM_WORLD.size} rank(s)\n")
        print("| formulation | cells per edge | dofs | u_y (mm) | error | Newton its per step | wall (s) |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(rows))


if __name__ == "__main__":
    main()
