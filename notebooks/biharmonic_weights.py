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
# # Biharmonic weights: spreading a few handles' values to every element
#
# The skinning blog post (Kassahun et al., "Automatic Skinning Transformations using Mixed Finite Elements",
# section 1.3) optimises rotation
# angles at a few sample points only and spreads them to every triangle with biharmonic weights,
# $\theta_i = \sum_j W_{ij} \theta_j$. Weight $w_j$ minimises $\tfrac12\int (\Delta w)^2$ with
# $w_j = 1$ at handle $j$ and 0 at the others (`model.fields.biharmonic`):
#
# - **unbounded**, by the mixed two-field form of the bilaplacian: $v = -\Delta w$ is an unknown of its
#   own, the stationary point of $L(w, v) = \int \nabla w\cdot\nabla v - \tfrac12\int v^2$; the weights
#   sum to 1 everywhere (the constant is biharmonic) but overshoot: negative weights far from a handle
#   make a rotation there turn the wrong way;
# - **bounded** (Jacobson et al. 2011): the same energy with $0 \le w_j \le 1$, a bound-constrained
#   quadratic program solved by PETSc TAO (TRON), then normalised to sum to 1.
#
# Run with plain Python; with `CI` set it uses a coarser mesh.

# %%
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("biharmonic_weights")
if plt is not None:
    import matplotlib.tri as mtri

from dolfinx import mesh as dmesh  # noqa: E402
from mpi4py import MPI  # noqa: E402

from model import compat  # noqa: E402
from model.fields.biharmonic import biharmonic_weights, bounded_biharmonic_weights, handle_at_point  # noqa: E402

n = 24 if CI else 48
msh = dmesh.create_unit_square(MPI.COMM_WORLD, n, n)
POINTS = [(0.1, 0.1), (0.9, 0.2), (0.5, 0.9), (0.2, 0.7), (0.6, 0.45)]
handles = [handle_at_point(msh, p) for p in POINTS]
unbounded = biharmonic_weights(msh, handles)
bounded, reports = bounded_biharmonic_weights(msh, handles)
for name, weights in (("unbounded", unbounded), ("bounded", bounded)):
    values = np.array([w.x.array for w in weights])
    print(f"{name:9s}: min {values.min():+.4f}, max {values.max():.4f}, |sum - 1| <= "
          f"{np.abs(values.sum(axis=0) - 1).max():.1e}")
print("TAO TRON iterations per handle:", [r["iterations"] for r in reports])
assert np.abs(sum(w.x.array for w in bounded) - 1).max() < 1e-12
assert min(w.x.array.min() for w in bounded) >= 0.0 and max(w.x.array.max() for w in bounded) <= 1.0

# %% [markdown]
# ## The weights of one handle
#
# Handle 0 (bottom left): the unbounded weight dips below zero across the square (blue); the bounded
# one stays in [0, 1] and has a smaller support.

# %%
V = unbounded[0].function_space
points = V.tabulate_dof_coordinates()
triangulation = mtri.Triangulation(points[:, 0], points[:, 1], compat.cell_dofs(V.dofmap)) if plt else None
if plt is not None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.3))
    for ax, (name, weights) in zip(axes, (("unbounded", unbounded), ("bounded (TAO)", bounded))):
        shaded = ax.tripcolor(triangulation, weights[0].x.array[: len(points)], shading="gouraud", cmap="RdBu_r",
                              vmin=-0.6, vmax=1.0)
        ax.plot(*np.array(POINTS).T, "k^", ms=6)
        ax.set_title(f"w_0, {name}", fontsize=10)
        ax.set_aspect("equal")
        fig.colorbar(shaded, ax=ax)
    fig.tight_layout()
    fig.savefig(OUT / "weights.png", dpi=90)

# %% [markdown]
# ## Skinning: angles at the handles, a rotation field everywhere
#
# Angles $\theta_j$ at the five handles (as the seed's optimiser would return them), spread by each set
# of weights: $\theta(x) = \sum_j w_j(x)\,\theta_j$. Each point of the square is then rotated about the
# square's centre by $\theta(x)$. With the unbounded weights some regions turn beyond the largest
# handle angle or against it; the bounded weights keep every angle between the handles' angles.

# %%
theta = np.radians([0.0, 0.0, 40.0, 25.0, 10.0])
for name, weights in (("unbounded", unbounded), ("bounded", bounded)):
    field = sum(t * w.x.array for t, w in zip(theta, weights))
    print(f"{name:9s}: theta from {np.degrees(field.min()):+.1f} to {np.degrees(field.max()):.1f} degrees "
          f"(handles: {np.degrees(theta.min()):.0f} to {np.degrees(theta.max()):.0f})")
bounded_field = sum(t * w.x.array for t, w in zip(theta, bounded))
assert theta.min() - 1e-12 <= bounded_field.min() and bounded_field.max() <= theta.max() + 1e-12

# %%
if plt is not None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6))
    centre = np.array([0.5, 0.5])
    for ax, (name, weights) in zip(axes, (("unbounded", unbounded), ("bounded (TAO)", bounded))):
        angle = sum(t * w.x.array for t, w in zip(theta, weights))[: len(points)]
        c, s = np.cos(angle), np.sin(angle)
        r = points[:, :2] - centre
        moved = centre + np.column_stack([c * r[:, 0] - s * r[:, 1], s * r[:, 0] + c * r[:, 1]])
        deformed = mtri.Triangulation(moved[:, 0], moved[:, 1], triangulation.triangles)
        shaded = ax.tripcolor(deformed, np.degrees(angle), shading="gouraud", cmap="viridis")
        ax.triplot(deformed, color="k", lw=0.2, alpha=0.4)
        ax.set_title(f"each point rotated by theta(x), {name}", fontsize=10)
        ax.set_aspect("equal")
        fig.colorbar(shaded, ax=ax, label="theta (degrees)")
    fig.tight_layout()
    fig.savefig(OUT / "skinning_angles.png", dpi=90)
