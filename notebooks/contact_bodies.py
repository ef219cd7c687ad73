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
# # Contact between deformable bodies: stacked blocks and Hertz's two spheres
#
# `[[contact]]` with `master` (docs/layers.md): the nodes of the `surface` (slave) of one body are paired, at
# every Newton iteration, with the closest points of the deformed `master` triangles of another body of the
# same mesh, gap $g = n \cdot (x_s - x^*)$, penalty $(k/2)\min(g, 0)^2$ per reference area, here with Uzawa
# updates of the nodal contact pressure (augmented Lagrangian) until the penetration is below the tolerance.
#
# 1. Two unit blocks one on the other (`examples/contact_bodies.toml`), a pressure $p = 200$ on top: the contact
#    force is $p A$ and the top moves as one $1 \times 1 \times 2$ block.
# 3. Self-contact of one body (below, `examples/self_contact_slot.toml`): a slotted block whose slot closes.
# 2. Two elastic spheres ($R = 1$, $E_2 = 2 E_1$, $\nu = 0.3$; octants with symmetry planes, non-matching meshes)
#    pressed together: force against approach and the pressure against Hertz,
#    $F = \frac43 E^* \sqrt{R_{eff}}\, d^{3/2}$, $a = \sqrt{R_{eff} d}$, $p = p_0 \sqrt{1 - r^2/a^2}$,
#    $1/R_{eff} = 1/R_1 + 1/R_2$, $1/E^* = (1-\nu_1^2)/E_1 + (1-\nu_2^2)/E_2$.

# %%
import sys
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("contact_bodies")

import meshio  # noqa: E402

from meshes.topology import boundary_facets  # noqa: E402
from model.config import parse  # noqa: E402
from model.pipeline import run  # noqa: E402

raw = tomllib.loads((ROOT / "examples" / "contact_bodies.toml").read_text())
raw["output"] = {"dir": str(OUT / "blocks"), "png": False, "xdmf": False, "vtu": True}
summary = run(parse(raw, ROOT / "examples"), OUT / "blocks")
last = summary["steps"][-1]
pair = last["contact_pairs"]["upper_zmin-lower_zmax"]
print(f"status {summary['status']}; last step: {pair}")
assert abs(pair["normal_force"] - 200.0) < 1e-6  # p A

# the same problem as one 1 x 1 x 2 block
one = {**raw, "mesh": {"generator": "box", "size": [1.0, 1.0, 2.0], "cells": [2, 2, 4]},
       "material": [{**raw["material"][0], "region": "all"}],
       "boundary": [{"on": "zmin", "type": "displacement", "components": [2], "value": [0.0]},
                    {"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
                    {"on": "ymin", "type": "displacement", "components": [1], "value": [0.0]},
                    {"on": "zmax", "type": "traction", "value": [0.0, 0.0, -200.0]}],
       "output": {"dir": str(OUT / "one"), "png": False, "xdmf": False, "vtu": False}}
del one["contact"]
top_one = run(parse(one, ROOT / "examples"), OUT / "one")["steps"][-1]["probes"]["top"][2]
print(f"top u_z: two bodies {last['probes']['top'][2]:.12f}, one body {top_one:.12f}")

# %%
vtu = meshio.read(sorted((OUT / "blocks").glob("step_*.vtu"))[-1])
if plt is not None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    tets = vtu.cells_dict["tetra"]
    boundary = boundary_facets(tets)
    scale = 5.0  # displacements magnified
    moved = vtu.points + scale * vtu.point_data["u"]
    upper_nodes = np.zeros(len(vtu.points), dtype=bool)  # the bodies share no node: the upper one's cells' nodes
    upper_nodes[tets[vtu.points[tets, 2].mean(axis=1) > 1.0].ravel()] = True
    upper = upper_nodes[boundary].all(axis=1)
    fig = plt.figure(figsize=(5, 6))
    ax = fig.add_subplot(projection="3d")
    ax.add_collection3d(Poly3DCollection(moved[boundary], facecolor=np.where(upper, "tab:orange", "tab:blue"),
                                         edgecolor="k", linewidths=0.3, alpha=0.8))
    ax.set_xlim(0, 1.1)
    ax.set_ylim(0, 1.1)
    ax.set_zlim(0, 2)
    ax.set_box_aspect((1, 1, 1.8))
    ax.view_init(elev=15, azim=-55)
    ax.set_title(f"stacked blocks under p = 200 (u x {scale:g}):\ncontact force {pair['normal_force']:.6f} = p A",
                 fontsize=10)
    fig.savefig(OUT / "stacked_blocks.png", dpi=110, bbox_inches="tight")

# %% [markdown]
# ## Hertz: two deformable spheres
#
# `model.experiments.hertz.hertz_spheres`: the octants $x, y \ge 0$ of two balls touching at the origin
# (`meshes.sphere_pair`), refined there; the lower equator held, the upper one moved down by $d$ in load steps.
# The total force is four times the octant's. (In CI mode the coarse mesh and two steps.)

# %%
from model.experiments.hertz import face_triangles, hertz_force, hertz_pressure, hertz_spheres, pressure_profile  # noqa: E402

D = 2.0e-3
mesh = (0.008, 0.3, 0.25) if CI else (0.004, 0.15, 0.125)
result = hertz_spheres(*mesh, approach=D, steps=2 if CI else 5)
E1, E2, NU = 1.0e4, 2.0e4, 0.3
for p in result.points:
    print(f"d = {p.approach:.2e}: F = {p.force:.5f}, Hertz {p.hertz:.5f} ({100 * p.error:+.2f} %), "
          f"a = {p.contact_radius:.4f} (Hertz {np.sqrt(0.5 * p.approach):.4f}), {p.active_points} nodes, "
          f"{p.newton_iterations} Newton, {p.uzawa_rounds} Uzawa")
assert result.completed and abs(result.points[-1].error) < (0.08 if CI else 0.05)

# %%
if plt is not None:
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    ax = axes[0]  # the symmetry plane y = 0 near the contact, deformed (true scale; the z axis stretched)
    for body, colour in (("upper", "tab:orange"), ("lower", "tab:blue")):
        X, u = face_triangles(result.problem, f"{body}_ymin")
        x = X + u
        near = (np.abs(X[:, :, 2]).min(axis=1) < 0.01) & (X[:, :, 0].min(axis=1) < 0.07)
        for tri in x[near]:
            ax.fill(tri[:, 0], tri[:, 2], facecolor=colour, edgecolor="k", linewidth=0.2, alpha=0.6)
    a = np.sqrt(0.5 * D)
    xs = np.linspace(0.0, 0.06, 100)
    rest = 1.0 - np.sqrt(1.0 - xs**2)
    ax.plot(xs, rest, "--", color="tab:red", linewidth=1, label="spheres at rest")
    ax.plot(xs, -rest, "--", color="tab:red", linewidth=1)
    ax.axvline(a, color="k", linestyle=":", linewidth=1, label="Hertz a")
    ax.set_xlim(0, 0.06)
    ax.set_ylim(-0.004, 0.004)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_title("plane y = 0 at d = 2e-3, true displacements", fontsize=10)

    ax = axes[1]
    d = np.linspace(0.0, D, 100)
    ax.plot(1e3 * d, [hertz_force(v, 1.0, 1.0, E1, E2, NU, NU) for v in d], "k-", label="Hertz")
    ax.plot([1e3 * p.approach for p in result.points], [p.force for p in result.points], "o", color="tab:red",
            label=f"two deformable spheres ({result.dofs} dofs)")
    ax.set_xlabel("approach d / R (x 1e-3)")
    ax.set_ylabel("force F")
    ax.legend()
    ax.set_title("force against approach", fontsize=10)

    ax = axes[2]
    r, pressure = pressure_profile(result.contact)
    last = result.points[-1]
    rr = np.linspace(0.0, 1.3 * a, 200)
    ax.plot(rr, hertz_pressure(rr, last.force, a), "k-", label="Hertz p0 (1 - r^2/a^2)^1/2")
    near = r < 1.3 * a
    ax.plot(r[near], pressure[near], ".", color="tab:red", label="nodal contact pressure")
    ax.set_xlabel("r")
    ax.set_ylabel("p")
    ax.legend()
    ax.set_title(f"pressure at d = {last.approach:g}", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / "hertz_spheres.png", dpi=110)


# %% [markdown]
# ## Self-contact: a slotted block closes its slot
#
# `[[contact]] self_contact = true` (docs/layers.md, "Self-contact of one body"): the surface `slot` (both faces of
# the slot of `meshes.slotted_block`) is its own slave and master; a node pairs only with triangles outside its
# 2-ring that face it (normals more than 120 degrees apart) within reach. Bottom clamped, top clamped and moved
# down by 0.1 (the slot is 0.05 wide): the slot closes from its open end, the spine holds it open near x = 0.5.

# %%
raw = tomllib.loads((ROOT / "examples" / "self_contact_slot.toml").read_text())
raw["output"] = {"dir": str(OUT / "slot"), "png": False, "xdmf": False, "vtu": True}
if CI:
    raw["loading"] = {"steps": 4}
summary = run(parse(raw, ROOT / "examples"), OUT / "slot")
slot = summary["steps"][-1]["contact_pairs"]["slot-self"]
reactions = summary["steps"][-1]["reactions"]
print(f"status {summary['status']}; self-contact: {slot['active_points']} pressed of {slot['paired_points']} paired "
      f"nodes, normal force {slot['normal_force']:.2f}, max penetration {slot['max_penetration']:.2e}; "
      f"reactions z: top {reactions['zmax'][2]:.3f}, bottom {reactions['zmin'][2]:.3f}")
assert summary["status"] == "completed" and slot["active_points"] > 20
assert abs(reactions["zmax"][2] + reactions["zmin"][2]) < 1e-6 * abs(reactions["zmax"][2])  # internal forces

# %%
vtu = meshio.read(sorted((OUT / "slot").glob("step_*.vtu"))[-1])
if plt is not None:
    tets = vtu.cells_dict["tetra"]
    boundary = boundary_facets(tets)
    front = boundary[np.all(np.abs(vtu.points[boundary, 1]) < 1e-12, axis=1)]  # the face y = 0
    fig, axes = plt.subplots(1, 2, figsize=(13, 4))
    for ax, (points, title) in zip(axes, ((vtu.points, "at rest"),
                                          (vtu.points + vtu.point_data["u"], "top moved down 0.1 (true scale)"))):
        for tri in points[front]:
            ax.fill(tri[:, 0], tri[:, 2], facecolor="tab:orange", edgecolor="k", linewidth=0.3, alpha=0.7)
        ax.set_aspect("equal")
        ax.set_xlabel("x")
        ax.set_ylabel("z")
        ax.set_title(f"slotted block, face y = 0, {title}", fontsize=10)
    axes[1].set_title(f"slot closed by self-contact: {slot['active_points']} nodes pressed, "
                      f"normal force {slot['normal_force']:.0f}", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / "self_contact_slot.png", dpi=110)

# %% [markdown]
# ## Curved bellies in contact: two activated muscles press on each other
#
# `examples/twin_muscles.toml` (docs/layers.md, "Curved bellies in contact"): two fusiform muscles, mirror images
# about x = 0, bellies 0.05 mm apart, activated to 1 with the ends clamped; a_lateral and b_lateral in penalty
# contact both ways. By the mirror symmetry the answer is each muscle against a rigid wall x = 0 with the penalty
# 4 k (`model.experiments.twin_muscles`). Below: the nodes near the plane y = 0 around the bellies' mid-length,
# x against z, at rest and activated (the contact is one node pair on this coarse mesh).

# %%
from model.experiments.twin_muscles import WALL_FACTOR, mirror_pairs, plane_raw, run_twin, twin_raw  # noqa: E402

wall = run_twin(plane_raw(WALL_FACTOR * 1e10))
twin = run_twin(twin_raw(1e10))
ia, ib = mirror_pairs(twin.X)
scale = np.abs(wall.u).max()
mirror = np.abs(twin.u[ia] - twin.u[ib] * np.array([-1.0, 1.0, 1.0])).max() / scale
against_wall = np.abs(twin.u[ib] - wall.u[ib]).max() / scale
print(f"force on b {twin.body_force['b'][0]:.5f} N (wall {wall.reports[1]['force'][0]:.5f} N); max |u| "
      f"{scale * 1e3:.3f} mm; off the mirror image {mirror:.1e}, off the wall run {against_wall:.1e} of max |u|; "
      f"penetration {twin.reports[0]['max_penetration'] * 1e6:.2f} um")
assert mirror < 1e-10 and against_wall < 1e-3

# %%
if plt is not None:
    near = (np.abs(twin.X[:, 1]) < 1.5e-3) & (np.abs(twin.X[:, 0]) < 1.5e-3)
    fig, ax = plt.subplots(figsize=(7, 4))
    for points, style, label in ((twin.X, "o", "at rest"), (twin.X + twin.u, ".", "activated")):
        for side, colour in ((twin.X[:, 0] < 0, "tab:blue"), (twin.X[:, 0] > 0, "tab:orange")):
            pick = near & side
            ax.plot(points[pick, 2] * 1e3, points[pick, 0] * 1e3, style, color=colour, alpha=0.8,
                    label=f"{'a' if colour == 'tab:blue' else 'b'} {label}")
    ax.axhline(0.0, color="k", linewidth=0.5)
    ax.set_xlabel("z (mm)")
    ax.set_ylabel("x (mm)")
    ax.set_title("twin muscles: nodes near y = 0 facing each other", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "twin_muscles.png", dpi=110)
