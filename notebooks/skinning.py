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
# # Skinning with the adjoint method: which angles make this pose?
#
# The gingerbread man (`meshes.gingerbread`) is a mixed ARAP body: per triangle a symmetric stretch $S$, P1
# positions $x$ and a multiplier $\lambda$ of the constraint $\nabla x = R(\theta) S$, feet pinned at rest by
# $\tfrac{k}{2}\int_{feet} |x - X|^2$. For given angles the KKT system $A(\theta)\,y = b$ is linear (UFL derives
# it from the Lagrangian; MUMPS solves it). Angles $\theta_j$ at six sample points (head, chest, hands, legs)
# reach every triangle through biharmonic weights, $\theta_c = \sum_j W_{cj}\theta_j$ (the seed's section 1.3).
# A target pose is made by known angles; L-BFGS-B recovers them from zero by minimising
#
# $$J(\theta) = \tfrac12 \int_{tracked} |x(\theta) - x_{target}|^2\,dx$$
#
# with $dJ/d\theta_j$ from one adjoint solve $A^T\mu = \partial J/\partial y$, $dJ/d\theta_c = -\mu^T
# (\partial A/\partial\theta_c)\, y$ (`model.experiments.skinning`, Taylor-tested in `tests/test_skinning.py`).
# The set-up is `examples/skinning.py`. With `CI` set it uses a coarser mesh.

# %%
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("skinning")

import importlib.util  # noqa: E402

_spec = importlib.util.spec_from_file_location("example_skinning", ROOT / "examples" / "skinning.py")
example = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = example
_spec.loader.exec_module(example)

# %% [markdown]
# ## Fit: tracking the whole body, then only the hands and the head

# %%
out = example.run(size=0.14 if CI else 0.08)
print(f"{out['dofs']} unknowns (S, x, lambda)")
print(example.table(out))

# %% [markdown]
# Tracking the whole body recovers the six angles (to about 1e-8). Tracking only the hands and the head
# leaves the leg angles nearly free: L-BFGS-B stops at another pose of the hands and head, with the legs bent
# differently (J small but not zero).

# %%
body = out["fits"]["body"]
found = np.array([body.angles[n] for n in example.SAMPLE_POINTS])
assert np.max(np.abs(found - example.TRUTH)) < 1e-6, found

# %% [markdown]
# ## Rest, target and found poses

# %%
if plt is not None:
    example.picture(out, OUT / "poses.png")
    print("wrote", OUT / "poses.png")

# %% [markdown]
# ## Convergence of the objective

# %%
if plt is not None:
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for case, fit in out["fits"].items():
        ax.semilogy([max(v, 1e-30) for _, v in fit.history], label=case)
    ax.set_xlabel("evaluation (KKT + adjoint solve)")
    ax.set_ylabel("J")
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "convergence.png", dpi=110)
    plt.close(fig)
