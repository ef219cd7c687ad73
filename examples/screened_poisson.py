"""Screened Poisson, -lap u + alpha u = f with zero flux, standard and mixed (KKT) in 2D and 3D.

    .venv/bin/python examples/screened_poisson.py [--cells N] [--degree K] [--alpha A]

The skinning seed's first problem (Kassahun et al.'s skinning blog post): the energy
E(u) = 1/2 int |grad u|^2 + 1/2 int alpha u^2 - int f u minimised directly, and as the saddle point of
L(g, u, lambda) = 1/2 int |g|^2 + 1/2 int alpha u^2 - int f u + int lambda . (grad u - g) (forms.poisson).
With f = (d pi^2 + alpha) cos(pi x) cos(pi y) [cos(pi z)] the exact solution is the cosine product; the
script prints, for each dimension, the unknowns and time of both solves, their difference and the error.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from model.problem.screened_poisson import l2_h1_errors, solve_screened_poisson  # noqa: E402


def exact(x, dim: int):
    u = ufl.cos(ufl.pi * x[0]) * ufl.cos(ufl.pi * x[1])
    return u * ufl.cos(ufl.pi * x[2]) if dim == 3 else u


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=16, help="cells per edge in 2D (half of it in 3D)")
    parser.add_argument("--degree", type=int, default=1)
    parser.add_argument("--alpha", type=float, default=2.0)
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    for dim in (2, 3):
        n = args.cells if dim == 2 else max(args.cells // 2, 1)
        msh = dmesh.create_unit_square(comm, n, n) if dim == 2 else dmesh.create_unit_cube(comm, n, n, n)
        f = (lambda d: lambda x: (d * ufl.pi**2 + args.alpha) * exact(x, d))(dim)
        standard = solve_screened_poisson(msh, args.alpha, f, args.degree, "standard")
        mixed = solve_screened_poisson(msh, args.alpha, f, args.degree, "mixed")
        diff = standard.u - mixed.u
        dx = ufl.dx(domain=msh, metadata={"quadrature_degree": 2 * args.degree})
        difference = np.sqrt(comm.allreduce(fem.assemble_scalar(fem.form(diff * diff * dx)), op=MPI.SUM))
        l2, h1 = l2_h1_errors(standard.u, lambda x, d=dim: exact(x, d))
        if comm.rank == 0:
            print(f"{dim}D, P{args.degree}, {n} cells per edge: standard {standard.dofs} unknowns "
                  f"{standard.time_s:.2f} s, mixed {mixed.dofs} unknowns {mixed.time_s:.2f} s; "
                  f"||u_standard - u_mixed||_L2 = {difference:.1e}; error L2 {l2:.3e}, H1 {h1:.3e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
