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
# # Fibre-based muscles by shape targeting
#
# Klar et al. (2020, section 3) simulate a whole upper arm as one volume; the muscles are
# influence regions with fibre directions and activations, each element receives full or
# fractional contributions from one or several muscles, and its shape target is computed from
# their combined effect.
#
# Here (`examples/muscle_targets.toml`, `examples/muscle_targets.py`) the arm is a box,
# 8 x 8 x 30 cm, clamped at the shoulder end z = 0. Two spindle-shaped influence regions
# overlap inside it: a *biceps* on the front (+x) side along z, and a tilted *brachialis* behind
# it near the elbow end. A muscle with unit fibre direction $a$ and activation $\alpha$ wants to
# contract along $a$ and expand across, keeping its volume:
#
# $$S_m = l\, a\otimes a + l^{-1/2} (I - a\otimes a), \qquad l = 1 - 0.3\,\alpha, \qquad \det S_m = 1.$$
#
# Each cell has weights $w_m \in [0, 1]$ from its distance to muscle $m$'s axis (1 in the core,
# 0 outside the spindle), scaled down where they add up to more than one; the rest
# $w_0 = 1 - \sum_m w_m$ is passive tissue with target $I$. The targets are combined as a
# log-Euclidean mean,
#
# $$S = \exp\Big(\sum_m w_m \log S_m\Big),$$
#
# i.e. the cell's logarithmic (Hencky) target strain is the weighted sum of the muscles' ones.
# It is always symmetric positive definite, whatever the fibre directions; it keeps the volume
# exactly ($\operatorname{tr}\log S_m = 0$, so $\det S = 1$), where a linear mean
# $\sum_m w_m S_m$ of two different isochoric targets has $\det > 1$ and would make the overlap
# swell; and a cell half inside a muscle gets $S_m^{1/2}$, half its log strain.
#
# Run with plain Python (`python notebooks/muscle_targets.py`); `CI` set: coarse mesh, 10 frames.
# `WRITE_DOCS=1` also writes `docs/muscle_targets.png`.

# %%
import importlib.util
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "muscle_targets"
WRITE_DOCS = os.environ.get("WRITE_DOCS") == "1"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import meshio  # noqa: E402
from _pictures import deformation_gradients, render, small_png  # noqa: E402

import model  # noqa: E402

spec = importlib.util.spec_from_file_location("muscle_targets", ROOT / "examples" / "muscle_targets.py")
muscles = importlib.util.module_from_spec(spec)
spec.loader.exec_module(muscles)

# %% [markdown]
# ## Activation curves
#
# The biceps ramps up to full activation by t = 1/2 and holds; the brachialis rises and falls
# (sin(pi t)), so at t = 1/2 both contract and at t = 1 only the biceps does.

# %%
t_fine = np.linspace(0, 1, 101)
alpha = np.array([muscles.activation(t) for t in t_fine])
if plt is not None:
    fig, ax = plt.subplots(figsize=(5, 3))
    for m, muscle in enumerate(muscles.MUSCLES):
        ax.plot(t_fine, alpha[:, m], label=muscle.name)
    ax.set_xlabel("frame time t")
    ax.set_ylabel("activation alpha")
    ax.legend()
    fig.tight_layout()

# %% [markdown]
# ## The run

# %%
cells = (5, 5, 16) if CI else (8, 8, 24)
frames = 10 if CI else 20
config = model.load_config(ROOT / "examples" / "muscle_targets.toml",
                           overrides={"mesh.cells": list(cells), "loading.steps": frames, "output.png": False})
summary = model.run(config, out=OUT).summary
steps = [s for s in summary["steps"] if s["converged"]]
print(f"{summary['cells']} cells, {summary['dofs']} dofs, {len(steps)} frames, {summary['wall_time_s']:.1f} s, "
      f"Newton iterations per frame: {[s['newton_iterations'] for s in steps]}")

# %% [markdown]
# ## What the muscles did
#
# From the results of every frame (`step_NNNN.vtu`: reference points, cells, displacements):
# the deformation gradient of every tetrahedron, the fibre stretch $|F a|$ of the cells in
# each muscle's core (weight 1, away from the clamped shoulder), the mean stretch across the
# fibres $\sqrt{J / |F a|}$, and the volume of the whole arm.

# %%
rows = []
for n, step in enumerate(steps):
    data = meshio.read(OUT / f"step_{n + 1:04d}.vtu")
    tets = data.cells_dict["tetra"]
    F = deformation_gradients(data.points, tets, data.point_data["u"])
    X = data.points[tets]
    volume = np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / 6.0
    x = X.mean(axis=1)
    w = muscles.weights(x)
    J = np.linalg.det(F)
    row = {"t": step["load_factor"], "volume change": np.sum(J * volume) / np.sum(volume) - 1.0}
    for m, muscle in enumerate(muscles.MUSCLES):
        core = (w[:, m] > 0.99) & (x[:, 2] > 0.08)
        along = np.linalg.norm(np.einsum("nij,nj->ni", F[core], muscle.fibres(x[core])), axis=1)
        row[f"{muscle.name} along"] = along.mean()
        row[f"{muscle.name} across"] = np.sqrt(J[core] / along).mean()
    S = muscles.muscle_targets(x, step["load_factor"])
    row["min eig S"] = np.linalg.eigvalsh(S)[:, 0].min()
    rows.append(row)
keys = list(rows[0])
print(" ".join(f"{k:>18s}" for k in keys))
for row in rows:
    print(" ".join(f"{row[k]:18.4f}" for k in keys))
final = rows[-1]
assert final["biceps along"] < 1.0 < final["biceps across"]
assert max(abs(r["volume change"]) for r in rows) < 0.03

# %% [markdown]
# The active biceps shortens along its fibres (target 0.7 at full activation; the passive tissue
# around it and the clamp hold it to about 0.88) and bulges across them; the brachialis
# follows its rise and fall. The arm's volume changes by well under one percent: the targets
# are isochoric and $\kappa = 10\mu$ holds $J$ near $\det S = 1$. The smallest eigenvalue of
# $S$ stays positive (about $l = 0.7$ at full activation): the targets are SPD in every cell,
# every frame.

# %%
if plt is not None:
    t = [r["t"] for r in rows]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.5))
    for muscle in muscles.MUSCLES:
        ax1.plot(t, [r[f"{muscle.name} along"] for r in rows], "o-", label=f"{muscle.name}: along fibres")
        ax1.plot(t, [r[f"{muscle.name} across"] for r in rows], "s--", label=f"{muscle.name}: across")
    ax1.axhline(1.0, color="grey", lw=0.8)
    ax1.set_xlabel("frame time t")
    ax1.set_ylabel("mean stretch in the muscle's core")
    ax1.legend(fontsize=8)
    ax2.plot(t, [100 * r["volume change"] for r in rows], "o-")
    ax2.set_xlabel("frame time t")
    ax2.set_ylabel("volume change of the arm (%)")
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT / "muscle_stretches.png", dpi=90)

# %% [markdown]
# ## Picture
#
# The arm cut open through the muscles' axes (cells with y > 4 cm; the shoulder, clamped, at
# the bottom). Left: the influence regions at rest (red biceps, blue brachialis, white passive
# tissue, mixed colours where they overlap). Middle and right: t = 1/2 (both active) and t = 1
# (biceps only), coloured by the stretch along the fibres of the dominant muscle (1 in passive
# tissue).

# %%
n_half = int(np.argmin([abs(s["load_factor"] - 0.5) for s in steps]))
shown = [(0, False), (n_half, True), (len(steps) - 1, True)]
panels = []
for k, (n, deformed) in enumerate(shown):
    data = meshio.read(OUT / f"step_{n + 1:04d}.vtu")
    tets = data.cells_dict["tetra"]
    x = data.points[tets].mean(axis=1)
    w = muscles.weights(x)
    F = deformation_gradients(data.points, tets, data.point_data["u"])
    dominant = np.argmax(w, axis=1)
    a = np.where((dominant == 0)[:, None], muscles.MUSCLES[0].fibres(x), muscles.MUSCLES[1].fibres(x))
    stretch = np.where(w.sum(axis=1) > 0.05, np.linalg.norm(np.einsum("nij,nj->ni", F, a), axis=1), 1.0)
    path = OUT / f"picture_{k}.vtu"
    meshio.write(path, meshio.Mesh(data.points, [("tetra", tets)], point_data={"u": data.point_data["u"]},
                                   cell_data={"muscle": [w[:, 0] - w[:, 1]], "fibre_stretch": [stretch]}))
    panel = {"vtu": str(path), "offset": [0.13 * k, 0.0, 0.0], "deformed": deformed,
             "cells": np.flatnonzero(x[:, 1] > 0.04).tolist(), "reference": deformed,
             "label": "rest" if not deformed else f"t = {steps[n]['load_factor']:.2f}"}
    if deformed:
        panel.update(scalars="fibre_stretch", cmap="magma", clim=[0.8, 1.05], bar="stretch along the fibres",
                     bar_position=[0.45, 0.04, 0.45])
    else:
        panel.update(scalars="muscle", cmap="coolwarm", clim=[-1.0, 1.0], bar="weight: biceps (+), brachialis (-)",
                     bar_position=[0.03, 0.04, 0.33])
    panels.append(panel)
png = render({"png": str(OUT / "muscle_targets.png"), "window": [1400, 900], "view": "xz", "elevation": 15,
              "zoom": 1.2, "panels": panels, "label_size": 20})
print("wrote", png)

# %%
if WRITE_DOCS:
    small_png(png, ROOT / "docs" / "muscle_targets.png")
    print("wrote docs/muscle_targets.png", (ROOT / "docs" / "muscle_targets.png").stat().st_size // 1024, "kB")
