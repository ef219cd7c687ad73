"""Biharmonic weights of point handles on a 2D square, unbounded (mixed form) and bounded (TAO).

    .venv/bin/python examples/biharmonic_weights.py [--cells N] [--handles x0,y0 x1,y1 ...]

The weights the skinning seed uses to spread a few optimised rotation angles to every element
(Kassahun et al.'s skinning blog post, section 1.3: theta = sum_j W_ij theta_j); model.fields.biharmonic.
Prints, per variant, the range of the weights, the partition-of-unity error and the handle values.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from model.fields.biharmonic import (  # noqa: E402
    _locate,
    biharmonic_weights,
    bounded_biharmonic_weights,
    handle_at_point,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=24, help="cells per edge of the unit square")
    parser.add_argument("--handles", nargs="+", default=["0.1,0.1", "0.9,0.2", "0.5,0.9", "0.2,0.7"],
                        help="handle points x,y")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    msh = dmesh.create_unit_square(comm, args.cells, args.cells)
    points = [tuple(float(c) for c in text.split(",")) for text in args.handles]
    handles = [handle_at_point(msh, p) for p in points]
    unbounded = biharmonic_weights(msh, handles)
    bounded, reports = bounded_biharmonic_weights(msh, handles)
    for name, weights in (("unbounded (mixed form)", unbounded), ("bounded (TAO TRON)", bounded)):
        low = comm.allreduce(min(w.x.array.min() for w in weights), op=MPI.MIN)
        high = comm.allreduce(max(w.x.array.max() for w in weights), op=MPI.MAX)
        unity = comm.allreduce(float(np.max(np.abs(sum(w.x.array for w in weights) - 1.0))), op=MPI.MAX)
        at_handles = [[comm.allreduce(float(w.x.array[_locate(w.function_space, h)].max(initial=-np.inf)),
                                      op=MPI.MAX) for w in weights] for h in handles]
        if comm.rank == 0:
            print(f"{name}: weights in [{low:.4f}, {high:.4f}], |sum - 1| <= {unity:.1e}, "
                  f"w_j(handle k) = {np.round(at_handles, 12).tolist()}")
    if comm.rank == 0:
        print("TAO:", ", ".join(f"handle {r['handle']}: {r['iterations']} iterations (reason {r['reason']})"
                                for r in reports))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
