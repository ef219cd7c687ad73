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
# # Calibration: E and nu of a stretched block, from a force and a thinning with noise
#
# A material test measures what a simulation computes: the force a grip pulls with, the displacement
# of a marker, a volume. Fitting the law's parameters to such curves is the inverse problem: find p
# minimising $\Phi(p) = \frac12 \sum_i w_i (q_i(p) - m_i)^2$ over the measured quantities $q_i$ at their
# load factors (docs/calibration.md). Here the "measurements" are synthetic, so the answer is known:
# `examples/calibration/make_data.py` runs the block of `examples/calibration/specimen.toml` (2 x 1 x 1,
# clamped at x = 0, pulled to a stretch of 1.4) with E = 1e4 Pa, nu = 0.3 and adds Gaussian noise of 1 % of
# each quantity's largest value. The fit starts from the file's E = 5e3, nu = 0.2.

# %%
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks"), str(ROOT / "examples" / "calibration")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("calibration")

from make_data import TRUE, measurements  # noqa: E402

from model.studies.calibration import calibrate  # noqa: E402

data = measurements()  # the forward run with the true values, plus noise (seed 1): measured.csv
print(data.to_string(index=False, float_format="%.5g"))

# %% [markdown]
# ## The fit
#
# `calibrate` holds every law parameter as a runtime constant (one compile for the whole fit), derives the
# Jacobian of each quantity with respect to E and nu exactly (one factorisation of the tangent per measured
# load factor) and runs a bounded Gauss-Newton (scipy's trust-region reflective least squares). The standard
# errors come from the Gauss-Newton Hessian with the given sigmas.

# %%
result = calibrate(ROOT / "examples" / "calibration" / "specimen.toml", data[["load_factor", "quantity", "value",
                                                                          "sigma"]],
                   list(TRUE), out=OUT)
print(result.text())
for key, true in TRUE.items():
    off = (result.parameters[key] - true) / result.std[key]
    print(f"{key}: true {true:g}, fitted {result.parameters[key]:.6g} +- {result.std[key]:.3g} "
          f"({off:+.2f} standard errors from the truth)")
    assert abs(off) < 2.0
print("correlation of E and nu:", f"{result.correlation[0, 1]:+.3f}")

# %% [markdown]
# Both values land within their standard errors of the truth, and E and nu are nearly uncorrelated here: the
# force sets E (at a given nu the force is proportional to E), the thinning sets nu. The table of the fit
# shows it in the relative sensitivities $p_k\, \partial q_i / \partial p_k$:

# %%
columns = ["load_factor", "quantity", "measured", "fitted", "sensitivity.material.0.E", "sensitivity.material.0.nu"]
print(result.table[columns].to_string(index=False, float_format="%.4g"))

# %% [markdown]
# ## Measured against fitted
#
# `fit.png` in the output folder is the same plot; here with the residuals in units of sigma.

# %%
if plt is not None:
    names = list(dict.fromkeys(result.table["quantity"]))
    fig, axes = plt.subplots(1, len(names) + 1, figsize=(13, 3.6))
    for ax, name in zip(axes, names):
        rows = result.table[result.table["quantity"] == name]
        ax.plot(rows["load_factor"], rows["start"], "--", color="0.6", label="start")
        ax.plot(rows["load_factor"], rows["fitted"], "-", label="fitted")
        ax.errorbar(rows["load_factor"], rows["measured"], yerr=rows["sigma"], fmt="o", ms=4, capsize=2,
                    label="measured")
        ax.set_xlabel("load factor")
        ax.set_title(name)
    axes[0].legend()
    ax = axes[-1]
    ax.axhline(0.0, color="0.5", lw=0.8)
    for name in names:
        rows = result.table[result.table["quantity"] == name]
        ax.plot(rows["load_factor"], rows["weighted_residual"], "o-", label=name)
    ax.set_title("residual / sigma")
    ax.set_xlabel("load factor")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "calibration.png", dpi=110)
assert np.all(np.abs(result.table["weighted_residual"]) < 4.0)
