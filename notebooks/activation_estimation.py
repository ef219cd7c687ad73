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
