# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Screened Poisson, standard and mixed: the skinning seed's first step
#
# The skinning blog post (Kassahun et al., "Automatic Skinning Transformations using Mixed Finite Elements")
# starts from the screened Poisson
# problem: minimise
#
# $$E(u) = \tfrac12 \int_\Omega |\nabla u|^2 + \tfrac12 \int_\Omega \alpha u^2 - \int_\Omega f u,$$
#
# whose minimiser solves $-\Delta u + \alpha u = f$ with zero flux on the boundary (the seed writes
# the equation as $\Delta u - \alpha u = f$: `verify seeds` row `sgi-poisson-equation` shows that as
# printed $f$ has the wrong sign). The *mixed* form makes the gradient an unknown $g$ of its own and
# ties it to $u$ by a multiplier $\lambda$:
#
# $$L(g, u, \lambda) = \tfrac12 \int |g|^2 + \tfrac12 \int \alpha u^2 - \int f u
#   + \int \lambda \cdot (\nabla u - g).$$
#
# `model.problem.screened_poisson` writes both energies in UFL (`forms/poisson.py`); UFL derives the
# linear systems (for the mixed form, the KKT matrix is the Hessian of $L$ in $(g, u, \lambda)$) and
# MUMPS solves them. With $u \in P_k$ and $g, \lambda \in DG_{k-1}^d$ (which holds $\nabla$ of every
# $P_k$ function) the constraint gives $g = \nabla u$ exactly, so both forms give the same $u$, at
# about eight times the unknowns for the mixed one in 3D.
#
# Run with plain Python; with `CI` set it uses fewer meshes.

# %%
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("screened_poisson")

import ufl  # noqa: E402
from dolfinx import fem  # noqa: E402
from dolfinx import mesh as dmesh  # noqa: E402
from mpi4py import MPI  # noqa: E402

from model import compat  # noqa: E402
from model.problem.screened_poisson import l2_h1_errors, solve_screened_poisson  # noqa: E402

ALPHA = 2.0


def exact(x, dim: int):
    u = ufl.cos(ufl.pi * x[0]) * ufl.cos(ufl.pi * x[1])
    return u * ufl.cos(ufl.pi * x[2]) if dim == 3 else u


def source(dim: int):
    return lambda x: (dim * ufl.pi**2 + ALPHA) * exact(x, dim)


def unit(dim: int, n: int):
    comm = MPI.COMM_WORLD
    return dmesh.create_unit_square(comm, n, n) if dim == 2 else dmesh.create_unit_cube(comm, n, n, n)


# %% [markdown]
# ## One 2D solve, both ways
#
# $u = \cos(\pi x)\cos(\pi y)$ has zero normal derivative on the unit square's boundary, so with
# $f = (2\pi^2 + \alpha) u$ it is the exact solution.

# %%
msh = unit(2, 24)
standard = solve_screened_poisson(msh, ALPHA, source(2), 1, "standard")
mixed = solve_screened_poisson(msh, ALPHA, source(2), 1, "mixed")
dx = ufl.dx(domain=msh, metadata={"quadrature_degree": 2})
difference = np.sqrt(fem.assemble_scalar(fem.form((standard.u - mixed.u) ** 2 * dx)))
gap = np.sqrt(fem.assemble_scalar(fem.form(ufl.inner(mixed.g - ufl.grad(mixed.u), mixed.g - ufl.grad(mixed.u)) * dx)))
print(f"standard: {standard.dofs} unknowns, {standard.time_s:.3f} s; mixed: {mixed.dofs} unknowns, "
      f"{mixed.time_s:.3f} s")
print(f"||u_standard - u_mixed||_L2 = {difference:.2e}, ||g - grad u||_L2 = {gap:.2e}")
assert difference < 1e-10 and gap < 1e-10

# %%
if plt is not None:
    import matplotlib.tri as mtri

    # the triangulation of the P1 dofs (their coordinates and each cell's three dofs), u at them
    points = standard.u.function_space.tabulate_dof_coordinates()
    triangles = compat.cell_dofs(standard.u.function_space.dofmap)
    triangulation = mtri.Triangulation(points[:, 0], points[:, 1], triangles)
    vertex_u = standard.u.x.array[: len(points)]
    # g: DG0, one gradient per cell (the dofmap's block of each cell)
    g = mixed.g.x.array.reshape(-1, 2)[compat.cell_dofs(mixed.g.function_space.dofmap)[:, 0]]
    centroids = points[triangles].mean(axis=1)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.3))
    shaded = ax1.tripcolor(triangulation, vertex_u, shading="gouraud", cmap="viridis")
    fig.colorbar(shaded, ax=ax1, label="u")
    ax1.set_title("u (standard P1)", fontsize=10)
    ax2.triplot(triangulation, color="0.8", lw=0.4)
    ax2.quiver(centroids[:, 0], centroids[:, 1], g[:, 0], g[:, 1], color="C3", scale=60)
    ax2.set_title("g = grad u, an unknown of the mixed form (DG0)", fontsize=10)
    for ax in (ax1, ax2):
        ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(OUT / "screened_poisson_2d.png", dpi=90)

# %% [markdown]
# ## Convergence to the manufactured solution
#
# $L^2$ and $H^1$ errors on refined meshes, P1 and P2, 2D and 3D, for the standard form (the mixed u is
# the same to 1e-10, checked on the coarsest mesh of each). Expected rates: $k + 1$ in $L^2$, $k$ in $H^1$,
# reached from the second-finest to the finest mesh (the coarsest 3D meshes are not yet asymptotic:
# 3D P1 from 4 to 8 cells per edge gives 1.74 and 0.88).

# %%
cases = {(2, 1): (8, 16, 32, 64), (2, 2): (4, 8, 16, 32), (3, 1): (4, 8, 16, 24), (3, 2): (3, 6, 12, 16)}
if CI:
    cases = {(2, 1): (16, 32), (2, 2): (8, 16), (3, 1): (8, 16), (3, 2): (6, 12)}
results = {}
for (dim, degree), sizes in cases.items():
    rows = []
    for n in sizes:
        mesh_n = unit(dim, n)
        s = solve_screened_poisson(mesh_n, ALPHA, source(dim), degree, "standard")
        if n == sizes[0]:
            m = solve_screened_poisson(mesh_n, ALPHA, source(dim), degree, "mixed")
            d = np.sqrt(fem.assemble_scalar(fem.form((s.u - m.u) ** 2 * ufl.dx(domain=mesh_n))))
            assert d < 1e-10, (dim, degree, d)
        rows.append((1.0 / n, *l2_h1_errors(s.u, lambda x, dim=dim: exact(x, dim)), s.dofs))
    results[dim, degree] = np.array(rows)
    h, l2, h1, dofs = results[dim, degree].T
    rate_l2, rate_h1 = np.log(l2[-2] / l2[-1]) / np.log(h[-2] / h[-1]), np.log(h1[-2] / h1[-1]) / np.log(h[-2] / h[-1])
    print(f"{dim}D P{degree}: L2 errors {', '.join(f'{e:.2e}' for e in l2)} (rate {rate_l2:.2f}); "
          f"H1 {', '.join(f'{e:.2e}' for e in h1)} (rate {rate_h1:.2f}); up to {int(dofs[-1])} unknowns")
    assert abs(rate_l2 - (degree + 1)) < 0.1 and abs(rate_h1 - degree) < 0.1

# %%
if plt is not None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for ax, (column, name) in zip(axes, ((1, "L2"), (2, "H1"))):
        for (dim, degree), data in results.items():
            ax.loglog(data[:, 0], data[:, column], "o-", label=f"{dim}D P{degree}")
        ax.set_xlabel("h = 1 / cells per edge")
        ax.set_ylabel(f"{name} error")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "screened_poisson_rates.png", dpi=90)
