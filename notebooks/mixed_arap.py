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
# # ARAP in mixed form: the gingerbread man, and shape targeting in 3D
#
# The skinning blog post (Kassahun et al., "Automatic Skinning Transformations using Mixed Finite Elements",
# "Mixed FEM" and "ARAP") makes the stretch
# $S$ of every triangle an unknown of its own, tied to the deformation gradient by $F = R S$:
#
# $$L(u, S, R, \Lambda) = \int \mu \|S - S_t\|^2 + \Lambda : (F - R S)\,dx
#   + \sum_h \tfrac{k_h}{2} \int_{\Omega_h} |u - u_h|^2 dx .$$
#
# With $S = S^T$ and $S_t = I$ this is ARAP: $F = RS$ is the polar decomposition, so the energy is
# $\min_R \|F - R\|^2$, the displacement-only law. With a general $S$ it is shape targeting
# $\min_R \|F - R S_t\|^2$ (Klar et al. 2020) for any target $S_t$. Newton solves the whole saddle-point
# system in $(u, S, \varphi, \Lambda)$, the rotation written $R = R_{ref}\,Q(\varphi)$ (an angle in 2D, the
# Cayley map in 3D; `forms/mixed_arap.py`). UFL derives every block.

# %%
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("mixed_arap")

import importlib.util  # noqa: E402

_spec = importlib.util.spec_from_file_location("example_mixed_arap", ROOT / "examples" / "mixed_arap.py")
example = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = example
_spec.loader.exec_module(example)

from model import compat  # noqa: E402

SIZE, STEPS = (0.08, 2) if CI else (0.04, 4)

# %% [markdown]
# ## The gingerbread man
# Both feet are pinned by penalty handles ($k = 10^3 \mu$), the right hand is swung up by 60 degrees about the
# right shoulder and the head is pushed sideways by 0.15. The two formulations must reach the same pose.

# %%
domain, results = example.pose_gingerbread(size=SIZE, steps=STEPS)
disp, mixed = results["displacement"], results["mixed"]
gap = example.max_difference(mixed.u, disp.u)
for name, r in results.items():
    print(f"{name:>12}: {r.dofs:6d} unknowns, Newton iterations per step {r.iterations}, "
          f"{r.time_s:.2f} s, energy {r.energy:.10f}")
print(f"largest difference of the displacements: {gap:.2e}")
assert gap < 1e-8

# %%
V = disp.u.function_space
points = V.tabulate_dof_coordinates()[:, :2]
triangles = compat.cell_dofs(V.dofmap)
owned_cells = domain.mesh.topology.index_map(2).size_local
triangles = triangles[:owned_cells]
moved = points + disp.u.x.array.reshape(-1, 2)
R = mixed.rotations[:owned_cells]
angles = np.degrees(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
print(f"rotation per triangle: {angles.min():.1f} to {angles.max():.1f} degrees")
if plt is not None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
    axes[0].triplot(points[:, 0], points[:, 1], triangles, lw=0.3, color="0.6")
    axes[0].set_title("rest shape")
    shade = axes[1].tripcolor(moved[:, 0], moved[:, 1], triangles, facecolors=angles, cmap="coolwarm")
    axes[1].triplot(moved[:, 0], moved[:, 1], triangles, lw=0.2, color="k")
    axes[1].set_title("posed (mixed ARAP)")
    fig.colorbar(shade, ax=axes[1], label="rotation angle of R (degrees)")
    for ax in axes:
        ax.set_aspect("equal")
    fig.savefig(OUT / "gingerbread_pose.png", dpi=120, bbox_inches="tight")

# %% [markdown]
# ## 3D: shape targeting with per-cell targets
# A 1 x 1 x 3 bar with a target stretch $S_t(x)$ per cell, clamped at the bottom and its top moved by
# (0.8, 0.3, -0.4): the pipeline's displacement-only `shape_target` law (polar rotation per quadrature
# point, `forms/polar.py`) against the mixed form with a general $S$.

# %%
u_disp, info, mixed3 = example.bend_bar(steps=2)
gap3 = example.max_difference(mixed3.u, u_disp)
print(f"displacement-only: {info['dofs']} unknowns, Newton {info['iterations']}, {info['time_s']:.2f} s")
print(f"mixed (general S): {mixed3.dofs} unknowns, Newton {mixed3.iterations}, {mixed3.time_s:.2f} s")
print(f"largest difference: {gap3:.2e}")
assert gap3 < 1e-8

# %% [markdown]
# The mixed system has 8-17 times the unknowns (per cell: the stretch, the rotation and the $d^2$ multipliers)
# and costs correspondingly more per Newton step here; its value is elsewhere: the rotations are unknowns
# (so an objective can ask for them, as the adjoint skinning problem does) and no SVD enters the Jacobian.
