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
# # Which activations made this shape? An inverse problem with adjoint gradients
#
# A muscle block (1 x 1 x 4 cm, fibres along z, held 10 % stretched between clamped ends) has two regions,
# "lower" and "upper", activated to hidden values $a = (0.3, 0.8)$. Its displacement $u^*$ is the target.
# Starting from $a = (0.5, 0.5)$ we minimise
#
# $$J(a) = \tfrac12 \int_\Omega |u(a) - u^*|^2\,dx, \qquad 0 \le a_r \le 1,$$
#
# by L-BFGS-B (`model.experiments.inverse`). Each evaluation solves the forward problem (Newton, warm
# started) and one adjoint problem $(\partial R/\partial u)^T \lambda = \partial J/\partial u$ with the
# consistent Jacobian UFL derives; $dJ/d\alpha$ per cell is $-\lambda^T \partial R/\partial\alpha$
# (`model.solvers.adjoint`, Taylor-tested in `tests/test_adjoint.py`), summed over each region's cells.
# The set-up is `examples/activation_estimation.py`.
#
# Run with plain Python; with `CI` set it tries fewer noise levels.

# %%
import sys
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("activation_estimation")

import importlib.util  # noqa: E402

_spec = importlib.util.spec_from_file_location("example_activation_estimation",
                                               ROOT / "examples" / "activation_estimation.py")
example = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = example
_spec.loader.exec_module(example)


# %%
estimate = example.recover(0.0)
found = np.array([estimate.activations["lower"], estimate.activations["upper"]])
error = np.max(np.abs(found - example.HIDDEN))
print(f"hidden {example.HIDDEN}, recovered {found.round(10).tolist()}, error {error:.1e}; "
      f"{estimate.iterations} iterations, {estimate.evaluations} forward + adjoint solves")
assert np.max(np.abs(found - example.HIDDEN)) < 1e-4

# %% [markdown]
# ## With noise on the target
#
# A deterministic noise of a given fraction of the largest displacement, per node and component
# (`example.noise_field`), is added to $u^*$. The recovered activations move by about the noise
# level: the problem is well posed with two unknowns and hundreds of data.

# %%
levels = [0.0, 0.01] if CI else [0.0, 0.0025, 0.005, 0.01, 0.02, 0.05]
errors = []
for level in levels:
    e = example.recover(level) if level else estimate
    a = np.array([e.activations["lower"], e.activations["upper"]])
    errors.append(np.abs(a - example.HIDDEN))
    print(f"noise {100 * level:5.2f} %: recovered {a.round(5).tolist()}, error {errors[-1].max():.2e}")

# %%
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    path = np.array([h[0] for h in estimate.history])
    values = np.array([h[1] for h in estimate.history])
    ax1.plot(path[:, 0], path[:, 1], "o-", ms=3, label="L-BFGS-B evaluations")
    ax1.plot(*example.HIDDEN, "r*", ms=12, label="hidden")
    ax1.set_xlabel("a_lower")
    ax1.set_ylabel("a_upper")
    ax1.set_xlim(0, 1)
    ax1.set_ylim(0, 1)
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    inset = ax1.inset_axes([0.55, 0.12, 0.4, 0.35])
    inset.semilogy(values / values[0], ".-")
    inset.set_title("J / J(start)", fontsize=7)
    inset.tick_params(labelsize=6)
    noisy = [(lv, err) for lv, err in zip(levels, errors) if lv > 0]
    if noisy:
        ax2.loglog([100 * lv for lv, _ in noisy], [err.max() for _, err in noisy], "o-")
    ax2.set_xlabel("noise (% of the largest displacement)")
    ax2.set_ylabel("max |a - a_hidden|")
    ax2.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(OUT / "activation_estimation.png", dpi=90)

# %% [markdown]
# ## One activation per cell, with smoothing
#
# Now the block (2 x 2 x 6 hexahedra of six tetrahedra: 144 cells) is activated by a hidden field that varies
# from cell to cell, $\alpha^*(x) = 0.2 + 0.6 \sin^2(\pi z / L)(0.75 + 25 x)$ at the cell centres, and every
# cell's activation is an unknown in $[0, 1]$. The deformation alone does not determine them (more unknowns
# than the displacement separates), so the objective gains a smoothing term for piecewise constant fields,
#
# $$J(\alpha) = \frac{1}{2|\Omega|\,\max|u^*|^2} \int_\Omega |u(\alpha) - u^*|^2\,dx
#   + \beta\, \frac12 \sum_{F\ \mathrm{interior}} \int_F \frac{[\alpha]^2}{h_F}\,ds,
#   \qquad h_F = \tfrac12 (h_+ + h_-),$$
#
# the jump of $\alpha$ across each interior facet, weighted by the facet's area over the mean diameter of its two
# cells: the DG0 counterpart of $\frac12\int |\nabla \alpha|^2$ (`smoothing_regulariser`, UFL with `dS`).
# PETSc TAO BLMVM (bound-constrained limited-memory quasi-Newton) minimises it over a distributed PETSc vector of
# the cells' activations (`estimate_cell_activations`), from 0.5 everywhere, with $\beta = 10^{-4}$.

# %%
keep = {}
cells = example.recover_cells(0.0, keep=keep)
e = cells["estimate"]
print(f"per cell: error L2 {cells['start'][0]:.3e} -> {cells['errors'][0]:.3e}, max {cells['start'][1]:.3e} -> "
      f"{cells['errors'][1]:.3e}; misfit {e.misfit:.2e}, R {e.regularisation:.2e}; {e.iterations} BLMVM iterations, "
      f"{e.evaluations} forward + adjoint solves")
for name, (h, f) in cells["means"].items():
    print(f"  {name}: mean hidden {h:.4f}, recovered {f:.4f}")
assert cells["errors"][0] < 0.2 * cells["start"][0]

# %%
if plt is not None:
    alpha, hidden = keep["alpha"], keep["hidden"]
    msh = alpha.function_space.mesh
    n = alpha.function_space.dofmap.index_map.size_local
    centre = fem.Function(example.compat.function_space(msh, "DG", 0, (3,)))
    centre.interpolate(fem.Expression(ufl.SpatialCoordinate(msh), np.zeros((1, 3)) + 0.25))
    xc = centre.x.array.reshape(-1, 3)[:n]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    for side, marker in ((xc[:, 0] < 0.005, "o"), (xc[:, 0] >= 0.005, "^")):
        label = "x < 5 mm" if marker == "o" else "x > 5 mm"
        ax1.plot(100 * xc[side, 2], hidden.x.array[:n][side], marker, ms=4, mfc="none", color="0.5",
                 label=f"hidden, {label}")
        ax1.plot(100 * xc[side, 2], alpha.x.array[:n][side], marker, ms=3, label=f"recovered, {label}")
    ax1.set_xlabel("z of the cell centre (cm)")
    ax1.set_ylabel("activation")
    ax1.legend(fontsize=7)
    ax1.grid(alpha=0.3)
    ax2.plot(hidden.x.array[:n], alpha.x.array[:n], ".", ms=4)
    ax2.plot([0, 1], [0, 1], "k--", lw=0.8)
    ax2.set_xlabel("hidden activation per cell")
    ax2.set_ylabel("recovered")
    ax2.set_title(f"L2 error {cells['errors'][0]:.3f} (start {cells['start'][0]:.3f})", fontsize=9)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "activation_per_cell.png", dpi=90)
