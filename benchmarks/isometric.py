"""Isometric contraction of the fusiform muscle (examples/isometric.toml) at three mesh sizes.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/isometric.py [--quick]

Prints a Markdown table: gmsh size, cells, dofs, Newton iterations per load step, time to
solution (model.pipeline.run, forms compiled by an untimed warm-up on the coarsest mesh, so the JIT
cache is warm), time in set-up (mesh, fibre Laplace solve, forms), mid-belly bulge, belly volume
change and tendon force at full activation. The Newton iteration counts must not grow with the
refinement (the consistent tangent converges quadratically at every size). Asserts nothing.
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
from model.experiments.muscle import isometric_curves  # noqa: E402
from model.pipeline import run  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the two coarser meshes only")
    args = parser.parse_args()
    sizes = [0.006, 0.003, 0.002][: 2 if args.quick else 3]
    base = tomllib.loads((ROOT / "examples" / "isometric.toml").read_text())
    base["output"] = {"xdmf": False, "vtu": False, "png": False}
    out = Path(MPI.COMM_WORLD.bcast(tempfile.mkdtemp() if MPI.COMM_WORLD.rank == 0 else None))
    warm = {**base, "mesh": {**base["mesh"], "size": sizes[0]}, "loading": {"steps": 1}}
    run(parse(warm, ROOT / "examples"), out / "warm-up")
    rows = []
    for size in sizes:
        raw = {**base, "mesh": {**base["mesh"], "size": size}}
        start = time.perf_counter()
        summary = run(parse(raw, ROOT / "examples"), out / f"h{size}")
        wall = time.perf_counter() - start
        solve = sum(s.get("solve_time_s", 0.0) for s in summary["steps"])
        its = " ".join(str(s["newton_iterations"]) for s in summary["steps"])
        curves = isometric_curves(summary)
        rows.append(f"| {size} | {summary['cells']} | {summary['dofs']} | {its} | {wall:.1f} | {wall - solve:.1f} "
                    f"| {1e3 * curves['bulge'][-1]:.4f} | {100 * curves['volume_change'][-1]:.4f} "
                    f"| {curves['tendon_force'][-1]:.3f} |")
    if MPI.COMM_WORLD.rank == 0:
        print(f"Isometric contraction (examples/isometric.toml: Taylor-Hood P2/P1, 5 activation steps), "
              f"{MPI.COMM_WORLD.size} rank(s)\n")
        print("| gmsh size (m) | cells | dofs | Newton its per step | time to solution (s) | of which outside "
              "SNES (s) | bulge (mm) | belly dV/V (%) | tendon force (N) |")
        print("|---|---|---|---|---|---|---|---|---|")
        print("\n".join(rows))


if __name__ == "__main__":
    main()
