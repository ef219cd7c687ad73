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
# # A muscle on a rotating bone: passive jiggles, active jiggles less (thesis figures 4.9-4.10)
#
# The thesis (chapter 4) shows the same animation of a biceps riding on a rotating humerus twice:
# with its fibres at rest, the muscle lags behind the bone and jiggles; with its fibres activated
# it "becomes stiffer and so is less governed by inertial motion".
#
# Here (`examples/rotating_muscle.toml`) the fusiform muscle's two tendon end disks are `attached`
# to a bone that turns by 20 degrees about an axis parallel to x, 3 cm beside the muscle's middle,
# in 0.05 s and then stops. The equations of motion
#
# $$M a + D v + f_{int}(u) = 0, \qquad D = a_M M \ (a_M = 2\,\mathrm{s}^{-1}),$$
#
# with the consistent mass matrix (density 1000 kg/m^3) are integrated by Newmark's average
# acceleration rule (dt = 5 ms). The belly's matrix is Mooney-Rivlin with $c_1$ = 10 kPa (shear
# modulus 20 kPa), the active fibre stress is up to $\sigma_{max}$ = 300 kPa. The active run starts
# from the contracted equilibrium (`dynamics.initial = "equilibrium"`): its fibres are under
# tension, which stiffens the belly across its fibres like a string, so the inertial lag and the
# oscillation after the stop are smaller.
#
# Run with plain Python; `CI` set: the same runs (each ~30-60 s).

# %%
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "rotating_muscle"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import model.config  # noqa: E402
from forms.motions import HingeMotion  # noqa: E402

OUT.mkdir(parents=True, exist_ok=True)
EXAMPLE = ROOT / "examples" / "rotating_muscle.toml"
raw = model.config.read(EXAMPLE)  # the document as written, for the bone's hinge

# %% [markdown]
# ## Passive and activated runs

# %%
summaries = {}
for name, alpha in (("passive", 0.0), ("active", 1.0)):
    overrides = {"output.xdmf": False, "output.vtu": False, "output.png": False, "material.0.activation": alpha}
    if alpha > 0:
        overrides["dynamics.initial"] = "equilibrium"
    summaries[name] = model.run(EXAMPLE, out=OUT / name, overrides=overrides).summary

# %% [markdown]
# ## The belly centre relative to the bone
#
# The bone carries the point X = (0, 0, 0.07) (the belly centre) rigidly to Q(t) X + c(t); the
# difference between the belly centre's displacement and that rigid displacement is the lag
# (during the turn) and the jiggle (after it).

# %%
hinge = raw["bone"][0]["hinge"]
motion = HingeMotion(hinge["axis"], hinge["point"], [tuple(a) for a in hinge["angles"]])
X = np.array([0.0, 0.0, 0.07])
stop = hinge["angles"][-1][0]
curves = {}
for name, summary in summaries.items():
    steps = [s for s in summary["steps"] if s["converged"]]
    t = np.array([s["time"] for s in steps])
    u = np.array([s["probes"]["belly_centre"] for s in steps])
    rigid = np.array([motion(ti)[0] @ X + motion(ti)[1] - X for ti in t])
    curves[name] = (t, 1e3 * (u - rigid), np.array([s["kinetic_energy"] for s in steps]))
    after = t > stop + 1e-12
    lag = curves[name][1][after]
    print(f"{name:8s}: after the stop, peak-to-peak lag y {np.ptp(lag[:, 1]):.3f} mm, z {np.ptp(lag[:, 2]):.3f} mm; "
          f"Newton iterations per step {np.mean([s['newton_iterations'] for s in steps]):.1f}")
jiggle = {name: np.ptp(lag[t > stop, 1]) for name, (t, lag, _) in curves.items()}
ratio = jiggle["active"] / jiggle["passive"]
print(f"active / passive jiggle (y, peak to peak): {ratio:.2f}")

# %%
if plt is not None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for name, (t, lag, ke) in curves.items():
        axes[0].plot(1e3 * t, lag[:, 1], label=f"{name}: y")
        axes[0].plot(1e3 * t, lag[:, 2], "--", label=f"{name}: z")
        axes[1].semilogy(1e3 * t, ke, label=name)
    for ax in axes:
        ax.axvline(1e3 * stop, color="grey", lw=0.8)
        ax.set_xlabel("t (ms)")
        ax.legend()
    axes[0].set_ylabel("belly centre minus rigid motion (mm)")
    axes[1].set_ylabel("kinetic energy (J)")
    fig.suptitle("muscle on a bone turning 20 degrees in 50 ms, then stopping (grey line)")
    fig.tight_layout()
    fig.savefig(OUT / "rotating_muscle.png", dpi=100)
    print("wrote", OUT / "rotating_muscle.png")
