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
# # Isometric contraction of a fusiform muscle
#
# A spindle-shaped muscle (`meshes.fusiform`: belly 10 cm long, radius 15 mm at its middle,
# between two cylindrical tendons 2 cm long and 4 mm in radius, 14 cm in all, axis along z) is
# held by both tendon ends (`origin` at z = 0 and `insertion` at z = 0.14 m fully clamped), and
# the belly's activation $\alpha$ ramps from 0 to 1 with the load factor
# (`examples/isometric.toml`). The muscle cannot shorten as a whole: *isometric*. What does it
# do inside, and how hard does it pull on its tendons?
#
# **The law** (`forms/muscle.py`, `energies.md`), after Teran et al. 2003 and Blemker et al. 2005
# with the thesis' choices: per unit reference volume
#
# $$\psi = F_1 + K (\ln J)^2 + F_2(\bar\lambda, \alpha), \qquad
#   \bar\lambda = \sqrt{a_0 \cdot \bar C a_0},\quad \bar C = J^{-2/3} F^T F,$$
#
# where $F_1 = \mu E{:}E + \tfrac{\lambda}{2} (\operatorname{tr} E)^2$ is the isotropic matrix
# (StVK, as the thesis; $E$ = 9 MPa, $\nu$ = 0.45 for muscle, $E$ = 15 MPa for tendon), $a_0$ the
# unit fibre direction in the reference configuration and $\bar\lambda$ the isochoric fibre
# stretch. The fibre term is defined by its derivative ($F_2(1) = 0$):
#
# $$\frac{\partial F_2}{\partial \bar\lambda} = \frac{\sigma_{max}}{l_{ofl}}
#   \big(f_{passive}(s) + \alpha\, f_{active}(s)\big),\qquad s = \bar\lambda / l_{ofl},$$
#
# $$f_{active}(s) = \begin{cases} 9 (s - 0.4)^2 & 0.4 < s \le 0.6\\ 1 - 4 (1 - s)^2 & 0.6 < s < 1.4\\
#   9 (s - 1.6)^2 & 1.4 \le s < 1.6\\ 0 & \text{otherwise}\end{cases}$$
#
# with $\sigma_{max}$ = 300 kPa, $l_{ofl}$ = 1 and the exponential-then-linear passive curve
# $f_{passive}$ (zero for $s \le 1$). The tendons have the same structure with their own stiff
# exponential curve $\sigma_{tendon}(\bar\lambda)$ and no active term. Fibres: a Laplace field from
# the origin disk to the insertion disk through belly and tendons, so they follow the spindle.
#
# **What we measure** (`model.experiments.muscle.isometric_curves`): per load step the
# activation, the *bulge* (the x displacement of a point on the belly's surface at mid-belly,
# (14.5 mm, 0, 70 mm)), the belly's volume change and the axial force the insertion reaction
# exerts (the tendon force). Then, from the last step's results, the fibre stretch along the
# muscle, which explains the numbers.
#
# Run with plain Python (`python notebooks/isometric.py`); with `CI` set it runs the example as
# written (5 load steps), otherwise 10 steps. `WRITE_DOCS=1` also writes `docs/isometric.png`.

# %%
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "isometric"
WRITE_DOCS = os.environ.get("WRITE_DOCS") == "1"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import meshio  # noqa: E402
from _pictures import cell_fibre_state, render, small_png, surface_cut  # noqa: E402

import model  # noqa: E402
from model.experiments.muscle import active_stress, isometric_curves  # noqa: E402

OUT.mkdir(parents=True, exist_ok=True)
MAGNIFY = 20.0  # displacements in the outline plot and the picture

# %% [markdown]
# ## The run
#
# `examples/isometric.toml` as written (P2/P1 Taylor-Hood, about 7000 tetrahedra), with more load
# steps in the full notebook; only the VTU results are written (they feed the analysis and the
# picture).

# %%
config = model.load_config(ROOT / "examples" / "isometric.toml",
                           overrides={"loading.steps": 5 if CI else 10, "output.png": False, "output.xdmf": False})
law = next(m.law for m in config.materials if m.region == "belly")
result = model.run(config, out=OUT)
summary, steps = result.summary, result.converged_steps
print(f"{summary['cells']} cells, {summary['dofs']} dofs, {len(steps)} steps, {summary['wall_time_s']:.1f} s, "
      f"Newton iterations per step: {[s['newton_iterations'] for s in steps]}")

# %% [markdown]
# ## Bulge, volume and tendon force against activation

# %%
curves = isometric_curves(summary)
belly_area = np.pi * 0.015**2  # the belly's largest cross-section (m^2)
print(f"{'activation':>10s} {'bulge (mm)':>11s} {'belly dV (%)':>13s} {'tendon force (N)':>17s} "
      f"{'force / (sigma_max A_belly)':>28s}")
for a, b, v, f in zip(curves["activation"], curves["bulge"], curves["volume_change"], curves["tendon_force"]):
    print(f"{a:10.2f} {1e3 * b:11.4f} {100 * v:13.4f} {f:17.3f} {f / (law.sigma_max * belly_area):28.4f}")
last = steps[-1]["reactions"]
print(f"origin + insertion reactions at full activation (N): {np.add(last['origin'], last['insertion'])}")
assert np.all(np.diff([0.0, *curves["bulge"]]) > 0) and np.all(np.diff([0.0, *curves["tendon_force"]]) > 0)
assert max(abs(v) for v in curves["volume_change"]) < 0.01

# %%
if plt is not None:
    act = [0.0, *curves["activation"]]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for ax, key, scale, label in zip(axes, ("bulge", "volume_change", "tendon_force"), (1e3, 100.0, 1.0),
                                     ("mid-belly bulge (mm)", "belly volume change (%)", "tendon force (N)")):
        ax.plot(act, [0.0, *(scale * np.asarray(curves[key]))], "o-")
        ax.set_xlabel("activation alpha")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "isometric_curves.png", dpi=90)

# %% [markdown]
# The bulge and the tendon force grow linearly with the activation. The belly thickens at its
# middle by a fraction of a millimetre; its volume grows by less than 0.04 % (nearly
# incompressible: $\nu$ = 0.45 in the StVK matrix plus $K (\ln J)^2$; the narrow, stretched ends of
# the belly, where the mean stress is tensile, gain a little volume, the middle loses a little).
# The tendons are pulled with some tens of newtons; the reactions at the two ends are equal and
# opposite (their sum, printed above, is at round-off level).
#
# The tendon force is far below $\sigma_{max}$ times the belly's largest cross-section
# (about 212 N): the last column shows the mean axial stress over the mid-belly cross-section as a
# fraction of $\sigma_{max}$. Where does the rest of the active stress go? Look inside.
#
# ## Inside the muscle: the fibre stretch along its length
#
# From the last step's `step_NNNN.vtu`: the deformation gradient of every tetrahedron (from the
# P1-interpolated displacement), the isochoric fibre stretch
# $\bar\lambda = J^{-1/3} |F a_0|$ and the Cauchy stress along the fibre
# $a \cdot \sigma a$ ($a = F a_0 / |F a_0|$), volume-averaged in 1 cm slices along the axis.

# %%
data = meshio.read(OUT / f"step_{len(steps):04d}.vtu")
tets = data.cells_dict["tetra"]
state = cell_fibre_state(data)
volume, centroid, Fa, fibre_stretch = (state[k] for k in ("volume", "centroid", "Fa", "fibre_stretch"))
a = Fa / np.linalg.norm(Fa, axis=1)[:, None]
sigma = data.cell_data["cauchy_stress"][0].reshape(-1, 3, 3)
fibre_stress = np.einsum("ni,nij,nj->n", a, sigma, a)
active = data.cell_data["activation"][0][:, 0] > 0

edges = np.linspace(0.0, 0.14, 15)
profile = []
print(f"{'z (cm)':>8s} {'part':>7s} {'fibre stretch':>14s} {'min..max':>14s} {'a.sigma.a (kPa)':>16s} "
      f"{'active stress (kPa)':>20s}")
for lo, hi in zip(edges[:-1], edges[1:]):
    m = (centroid[:, 2] >= lo) & (centroid[:, 2] < hi)
    lam = np.average(fibre_stretch[m], weights=volume[m])
    stress = np.average(fibre_stress[m], weights=volume[m])
    # what the fibres alone would carry at that stretch, fully active: (sigma_max / l_ofl) f_active
    act_stress = active_stress(lam, law) if active[m].any() else 0.0
    profile.append((0.5 * (lo + hi), lam, stress))
    print(f"{50 * (lo + hi):8.1f} {'belly' if active[m].any() else 'tendon':>7s} {lam:14.4f} "
          f"{fibre_stretch[m].min():6.3f}..{fibre_stretch[m].max():6.3f} {stress / 1e3:16.1f} {act_stress / 1e3:20.1f}")
profile = np.array(profile)
mid = profile[len(profile) // 2]
print(f"mid-belly: fibre stretch {mid[1]:.4f}, fibre stress {mid[2] / 1e3:.1f} kPa "
      f"against sigma_max f_active = {active_stress(mid[1], law) / 1e3:.1f} kPa")

# %%
if plt is not None:
    fig, ax1 = plt.subplots(figsize=(7, 3.4))
    ax1.plot(100 * profile[:, 0], profile[:, 1], "o-", color="C0")
    ax1.axhline(1.0, color="grey", lw=0.8)
    for z in (2.0, 12.0):
        ax1.axvline(z, color="grey", ls=":", lw=0.8)
    ax1.set_xlabel("z (cm)   (tendons: z < 2 and z > 12)")
    ax1.set_ylabel("fibre stretch (mean per slice)", color="C0")
    ax2 = ax1.twinx()
    ax2.plot(100 * profile[:, 0], profile[:, 2] / 1e3, "s--", color="C3")
    ax2.set_ylabel("fibre Cauchy stress (kPa)", color="C3")
    ax1.set_title("full activation, both ends clamped")
    fig.tight_layout()
    fig.savefig(OUT / "fibre_stretch_profile.png", dpi=90)

# %% [markdown]
# The muscle keeps its length, but not its fibres' lengths. The same axial force has to pass
# through every cross-section, and the cross-sections are small near the tendons: there the
# stress is high, the fibres in the narrow ends of the belly are *stretched* by about 4 % and the
# tendons by about half a percent, which lets the fibres in the thick middle of the belly
# *shorten* by about 2.4 %. Shortening at nearly constant volume is what makes the belly bulge.
#
# At that stretch the fibres' active stress is still almost $\sigma_{max}$
# ($f_{active}(0.976) \approx 0.998$), but the mid-belly's fibre stress is only a small fraction of
# it: the isotropic matrix is very stiff ($E$ = 9 MPa, thirty times $\sigma_{max}$), so a 2.4 %
# shortening compresses it by roughly $E \times 0.024 \approx$ 200 kPa along the fibres, which
# cancels most of the active stress. With the thesis' parameters most of the active fibre stress
# is spent deforming the muscle's own matrix instead of pulling on the tendons.

# %% [markdown]
# ## The belly's outline
#
# The plane y = 0 cuts the muscle's surface (its boundary triangles) along two curves; the
# reference curve and the deformed one, and the radial displacement of the surface along the axis.

# %%


Xs, us = surface_cut(data.points, data.point_data["u"], tets, 1, 0.0)
inside = (Xs[:, 2] > 1e-9) & (Xs[:, 2] < 0.14 - 1e-9)  # without the end disks
curves_xz = {}
for name, sign in (("x > 0", 1.0), ("x < 0", -1.0)):
    m = inside & (sign * Xs[:, 0] > 0)
    order = np.argsort(Xs[m, 2])
    curves_xz[name] = (Xs[m][order], us[m][order], sign)
Xp, up, _ = curves_xz["x > 0"]
k = np.argmax(up[:, 0])
print(f"surface radial displacement (x > 0 side) along the axis: max {1e3 * up[k, 0]:.4f} mm at z = "
      f"{100 * Xp[k, 2]:.1f} cm, min {1e3 * up[:, 0].min():.4f} mm at z = {100 * Xp[np.argmin(up[:, 0]), 2]:.1f} cm")

if plt is not None:
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for name, (Xc, uc, sign) in curves_xz.items():
        first = name == "x > 0"
        ax1.plot(100 * Xc[:, 2], 1e3 * Xc[:, 0], color="grey", lw=1.0, label="reference" if first else None)
        ax1.plot(100 * (Xc[:, 2] + MAGNIFY * uc[:, 2]), 1e3 * (Xc[:, 0] + MAGNIFY * uc[:, 0]), color="C0",
                 label=f"full activation, displacements x{MAGNIFY:.0f}" if first else None)
        ax2.plot(100 * Xc[:, 2], 1e3 * sign * uc[:, 0], ".-", label=f"side {name}")
    ax1.set_ylabel("x (mm), plane y = 0")
    ax1.legend(fontsize=8, loc="upper right")
    ax2.axhline(0.0, color="grey", lw=0.8)
    ax2.set_xlabel("z (cm)")
    ax2.set_ylabel("radial displacement (mm)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "outline.png", dpi=90)

# %% [markdown]
# The belly thickens in its middle (about 0.19 mm radially at z = 7 cm, the probe's bulge a little
# inside the surface is 0.18 mm) and becomes *thinner*, by up to 0.1 mm, just past the tendons
# (z = 2.3 and 11.7 cm), where its fibres are stretched; the tendons hardly change their radius.
# The two sides agree to a few micrometres (the unstructured mesh is not exactly symmetric).

# %% [markdown]
# ## Picture
#
# Top: the muscle at full activation, displacements magnified 20 times, coloured by the von Mises
# stress (the undeformed mesh's feature edges are drawn in grey, `reference`, but at this scale
# the deformed surface covers them: the outline plot above compares the shapes). Bottom: the same,
# cut open along its axis (the half y > 0), coloured by the fibre stretch $\bar\lambda$: blue where
# the fibres shorten, red where they are stretched. The muscle's axis is drawn horizontally (origin
# on the left).

# %%
ROTATE = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # muscle axis z -> horizontal x
picture_vtu = OUT / "picture.vtu"
meshio.write(picture_vtu, meshio.Mesh(
    data.points @ ROTATE.T, [("tetra", tets)], point_data={"u": MAGNIFY * data.point_data["u"] @ ROTATE.T},
    cell_data={"von_mises_kPa": [data.cell_data["von_mises"][0][:, 0] / 1e3], "fibre_stretch": [fibre_stretch]}))
half = np.flatnonzero(centroid[:, 1] > 0.0).tolist()
png = render({
    "png": str(OUT / "isometric.png"), "window": [1200, 600], "view": "xz", "zoom": 1.25, "label_size": 16,
    "panels": [
        {"vtu": str(picture_vtu), "offset": [0.0, 0.0, 0.0], "reference": True, "scalars": "von_mises_kPa",
         "cmap": "viridis", "clim": [0.0, 1000.0], "bar": "von Mises (kPa)", "bar_position": [0.05, 0.03, 0.4]},
        {"vtu": str(picture_vtu), "offset": [0.0, 0.0, -0.045], "cells": half, "scalars": "fibre_stretch",
         "cmap": "coolwarm", "clim": [0.96, 1.04], "bar": "fibre stretch (cut open)",
         "bar_position": [0.55, 0.03, 0.4]},
    ],
    "texts": [[f"full activation, displacements x{MAGNIFY:.0f}", 0.02, 0.93]],
})
print("wrote", png)

# %%
if WRITE_DOCS:
    small_png(png, ROOT / "docs" / "isometric.png")
    print("wrote docs/isometric.png", (ROOT / "docs" / "isometric.png").stat().st_size // 1024, "kB")
