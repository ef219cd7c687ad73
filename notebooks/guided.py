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
# # Guided simulation: record shape targets from a driven run, replay them
#
# Klar et al. (2020, section 3) drive a face simulation by the vertices of a scanned performance
# (attachments) with all shape targets set to identity, store "the symmetric part of each
# element's deformation gradient" after every frame, and then recreate the performance from
# those stored targets alone.
#
# Here the body is a bar (`examples/guided_stage1.toml`, 1 x 0.2 x 0.2, 240 P1 tetrahedra), the
# "performance" a bend that rises and falls and a twist, imposed on its end faces as functions of
# the frame time t. `model/guided.py` does the rest:
#
# - **stage 1** solves every frame with $S = I$ and stores, per cell, the stretch $U$ of the
#   polar decomposition $F = RU$ (the rotation-free, symmetric part) in mesh cell order;
# - **stage 2** drops every attachment, pins the bar with 3-2-1 point pins (they remove the six
#   rigid-body modes and nothing else), and solves each frame with $S = U$ of that frame.
#
# Stage 1's shape has zero energy under its own $U$ ($F - R^*U = RU - RU = 0$, $J = \det U$), so
# stage 2 must land on it, up to a rigid motion. The notebook checks that to solver precision.
#
# Run it with plain Python (`python notebooks/guided.py`); `CI` set: fewer frames.
# `WRITE_DOCS=1` also writes `docs/guided.png`.

# %%
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "guided"
WRITE_DOCS = os.environ.get("WRITE_DOCS") == "1"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import model  # noqa: E402
from model.experiments.guided import bounding_box_pins, error_table, run_stage1, run_stage2  # noqa: E402

# %% [markdown]
# ## Stage 1: attachments drive the bar, targets are recorded

# %%
frames = 6 if CI else 10
config = model.load_config(ROOT / "examples" / "guided_stage1.toml",
                           overrides={"loading.steps": frames, "output.png": False})
stage1 = run_stage1(config, OUT / "stage1")
stage1.save(OUT / "stage1" / "targets.npz")
U = stage1.targets
print(f"stage 1: {len(stage1.frames)} frames in {stage1.wall_time_s:.1f} s; stored targets {U.shape}")
print(" frame     t  Newton  max |U - I|  energy (J)")
for n, f in enumerate(stage1.frames, start=1):
    strain = np.max(np.linalg.norm(f.targets - np.eye(3), axis=(1, 2)))
    print(f"{n:6d} {f.load_factor:5.2f} {f.newton_iterations:7d} {strain:12.4f} {f.energy:11.4g}")

# %% [markdown]
# `targets.npz` holds everything stage 2 needs (`load_factors`, `targets` of shape
# (frames, cells, 3, 3)); one frame can also be used from a configuration as
# `S_file` after `numpy.save`.
#
# ## Stage 2: targets alone, 3-2-1 pins
#
# The pins sit at three corners of the bounding box: A = (0, 0, 0) is held in all three
# directions, B = (1, 0, 0), on the x axis through A, across that axis (y and z), and
# C = (0, 0.2, 0), in the plane z = 0 through A and B, normal to it (z). Any shape can be moved
# rigidly so that it satisfies them (put A back, turn AB onto the x axis, turn about it until C
# is back in the plane), so the pins fix the rigid motion without straining anything. Clamping a
# face instead would strain it unless stage 1 held that face rigid too.

# %%
pins = bounding_box_pins(stage1.domain)
for point, components in pins:
    print("pin at", point, "components", components)
results = run_stage2(stage1, pins, OUT / "stage2")
print(error_table(results))
assert all(r.relative_error < 1e-6 for r in results)

# %% [markdown]
# The error is the largest distance between a vertex of stage 2, moved by the best rigid motion
# (Kabsch), and the same vertex in stage 1, relative to the largest stage-1 displacement. It is
# at round-off level in every frame, while the rigid motion between the two (last column) is
# tens of degrees: stage 2 reproduces the shapes, not the placement, which the pins choose.
# Stage 2 could now add what stage 1 did not have (collisions, gravity, other bodies) and the
# targets would keep the performance.

# %%
if plt is not None:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    t = [r.load_factor for r in results]
    ax.semilogy(t, [max(r.relative_error, 1e-17) for r in results], "o-")
    ax.axhline(1e-6, color="grey", ls="--", label="test tolerance")
    ax.set_xlabel("frame time t")
    ax.set_ylabel("max vertex error / max |u|")
    ax.set_title("stage 2 vs stage 1 after rigid alignment")
    ax.legend()
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT / "guided_errors.png", dpi=90)

# %% [markdown]
# ## Picture
#
# Top row: stage 1, driven by its attachments (the held xmin face and the moving xmax face).
# Bottom row: stage 2, the same frames from the stored targets and three pins only. Both are
# coloured by $\|U - I\|$ computed from their own deformation: the shapes agree cell by cell;
# only the rigid placement differs.

# %%
import meshio  # noqa: E402
from _pictures import deformation_gradients, render, small_png  # noqa: E402

from model.experiments.guided import polar_stretch  # noqa: E402

shown = [n for n in np.unique(np.round(np.linspace(0, len(results) - 1, 5)[1:]).astype(int))]
panels = []
for row, stage in enumerate(("stage1", "stage2")):
    for k, n in enumerate(shown):
        data = meshio.read(OUT / stage / f"step_{n + 1:04d}.vtu")
        cells = data.cells_dict["tetra"]
        F = deformation_gradients(data.points, cells, data.point_data["u"])
        strain = np.linalg.norm(polar_stretch(F) - np.eye(3), axis=(1, 2))
        path = OUT / stage / f"picture_{n + 1:04d}.vtu"
        meshio.write(path, meshio.Mesh(data.points, [("tetra", cells)], point_data={"u": data.point_data["u"]},
                                       cell_data={"stretch": [strain]}))
        label = f"t = {results[n].load_factor:.2f}" if row == 0 else None
        panels.append({"vtu": str(path), "offset": [1.6 * k, 0.0, -1.0 * row], "label": label,
                       "reference": row == 0})
limit = float(np.max(np.linalg.norm(U - np.eye(3), axis=(2, 3))))
png = render({"png": str(OUT / "guided.png"), "window": [1600, 720], "view": "xz", "elevation": 18, "azimuth": -20,
              "zoom": 1.9, "scalars": "stretch", "clim": [0.0, limit], "cmap": "viridis",
              "bar": "norm(U - I), the stored shape target", "panels": panels, "label_size": 20,
              "texts": [["stage 1:\nattachments,\nS = I", 0.01, 0.62], ["stage 2:\nstored U,\n3 pins", 0.01, 0.3]]})
print("wrote", png)

# %%
if WRITE_DOCS:
    small_png(png, ROOT / "docs" / "guided.png")
    print("wrote docs/guided.png", (ROOT / "docs" / "guided.png").stat().st_size // 1024, "kB")
