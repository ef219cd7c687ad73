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
# # A render mesh embedded in the simulation mesh
#
# The thesis (4.3.2) renders a fine surface that is not the simulation mesh: each vertex of the render mesh is
# embedded in a tetrahedron of the simulation mesh by its barycentric coordinates and follows it,
# $x = X + u(X)$. Here `[output] render_mesh` does that for any surface meshio reads (OBJ, STL, PLY, ...): the
# twisting bar (`examples/twisting_bar_render.toml`, a 20 x 4 x 4 box of 480 tetrahedra whose end is turned by
# 90 degrees) carries a smooth tube of rounded-square section, 1,984 triangles
# (`examples/twisting_bar_skin.obj`), written deformed at every step as `render/twisting_bar_skin_NNNN.obj`.

# %%
import sys
import tomllib
from pathlib import Path

import meshio
import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("render_mesh")

from meshes.topology import boundary_facets  # noqa: E402
from model.config import parse  # noqa: E402
from model.pipeline import run  # noqa: E402

raw = tomllib.loads((ROOT / "examples" / "twisting_bar_render.toml").read_text())
raw["output"].update(dir=str(OUT / "run"), png=False, xdmf=False)
if CI:
    raw["loading"]["steps"] = 3
summary = run(parse(raw, ROOT / "examples"), OUT / "run")
print(f"status {summary['status']}, {len(summary['steps'])} steps; render mesh: {summary['render_mesh']}")

# %%
frames = sorted((OUT / "run" / "render").glob("twisting_bar_skin_*.obj"))
rest = meshio.read(ROOT / "examples" / "twisting_bar_skin.obj")
last = meshio.read(frames[-1])
print([f.name for f in frames])
# the tube's end ring turns with the bar's end face: by 90 degrees about the axis (y, z) = (0.1, 0.1)
end = np.isclose(rest.points[:, 0], 1.0) & (np.linalg.norm(rest.points[:, 1:] - 0.1, axis=1) > 0.05)
before = rest.points[end, 1:] - 0.1
after = last.points[end, 1:] - 0.1
turn = np.degrees(np.arctan2(np.cross(before, after), np.einsum("ij,ij->i", before, after)))
print(f"end ring turned by {turn.mean():.4f} degrees (spread {np.ptp(turn):.2e})")
assert abs(turn.mean() - 90.0) < 1e-6 and np.ptp(turn) < 1e-6

# %%
vtu = sorted((OUT / "run").glob("step_*.vtu"))[-1]
body = meshio.read(vtu)
tets = body.cells_dict["tetra"]
boundary = boundary_facets(tets)
moved = body.points + body.point_data["u"]
if plt is not None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(12, 4.5))
    for k, (title, pts, tris, colour) in enumerate(
            [("simulation mesh (480 tetrahedra), deformed", moved, boundary, "0.75"),
             ("embedded render mesh (1,984 triangles), deformed", last.points, last.cells_dict["triangle"],
              "tab:orange")]):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        if k == 1:  # stripes along the tube's sides show the twist
            side = (np.arctan2(rest.points[tris, 2].mean(1) - 0.1, rest.points[tris, 1].mean(1) - 0.1) // (np.pi / 4))
            colour = np.where(side.astype(int) % 2 == 0, "tab:orange", "tab:blue")
        ax.add_collection3d(Poly3DCollection(pts[tris], facecolor=colour, edgecolor="k", linewidths=0.1,
                                             alpha=0.9))
        ax.set_xlim(0, 1)
        ax.set_ylim(-0.2, 0.4)
        ax.set_zlim(-0.2, 0.4)
        ax.set_box_aspect((1, 0.6, 0.6))
        ax.view_init(elev=20, azim=-60)
        ax.set_title(title, fontsize=10)
    fig.savefig(OUT / "render_mesh.png", dpi=120, bbox_inches="tight")
