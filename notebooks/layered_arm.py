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
# # The layered arm: muscles that slide under the fat
#
# `notebooks/arm_segment.py` activates two fusiform muscles (a to 1, b to 0.3) in a fat cylinder meshed as one
# conforming body: the muscles are glued to the fat. Here the same mesh is cut open along the muscle-fat
# interfaces (`meshes.layered_arm`: three bodies, no shared node, every interface node twice at the same place)
# and `examples/layered_arm.toml` couples the bodies by `[[contact]]` pairs between bodies
# (`model.problem.body_contact`):
#
# - the fat's cavity **slides** on each muscle: zero-length normal springs, energy
#   $\int (k/2)\, g^2\, dA$ with the gap $g = n \cdot (x_s - x^*)$ to the closest point $x^*$ of the muscle's
#   surface: the fat stays on the muscle, free to slide along it;
# - muscle a **cannot enter** muscle b: frictionless contact, $\int (k/2) \min(g, 0)^2\, dA$, augmented
#   Lagrangian.
#
# Both runs use the same coarse mesh (12 mm, 8 elements per turn on the curved surfaces, about 8 000
# tetrahedra), the same materials and activations, two load steps. What changes when the muscles may slide:
# the bulge of the skin, the skin's displacement, the forces between the layers, the slip.
#
# Run with plain Python (`python notebooks/layered_arm.py`); about three minutes.

# %%
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "layered_arm"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import meshio  # noqa: E402

import model  # noqa: E402

OUT.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## The two runs

# %%
OVERRIDES = {"output.png": False, "output.xdmf": False, "output.vtu": True}
layered_run = model.run(ROOT / "examples" / "layered_arm.toml", out=OUT / "layered", overrides=OVERRIDES)
conforming_run = model.run(ROOT / "examples" / "arm_segment.toml", out=OUT / "conforming",
                           overrides={**OVERRIDES, "mesh.size": 0.012, "mesh.turn_elements": 8, "loading.steps": 2})
runs = {"conforming": conforming_run, "layered": layered_run}
for name, result in runs.items():
    s = result.summary
    steps = [step for step in s["steps"] if step["converged"]]
    newton = [st["newton_iterations"] for st in steps]
    print(f"{name}: {s['cells']} cells, {s['dofs']} dofs, Newton iterations {newton}, {s['wall_time_s']:.1f} s")
last = [step for step in layered_run.summary["steps"] if step["converged"]][-1]
for pair, report in last["contact_pairs"].items():
    print(f"{pair:24s} {report['kind']:8s} penetration {1e6 * report['max_penetration']:6.2f} um, gap "
          f"{1e6 * report['max_gap']:8.2f} um, normal force {report['normal_force']:7.2f} N, "
          f"active points {report['active_points']}")

# %% [markdown]
# The sliding pairs' normal forces are negative: the springs pull the fat onto the muscles (the contracting
# muscles would leave the fat behind if it were only pressed against them); their gaps, a few micrometres,
# are the penalty's p/k. The muscles stay apart: the 2 mm of fat between them at mid-length is squeezed,
# not pierced, so the contact between a and b has no active point at these activations.
#
# ## The mid-length section and the slip

# %%
def last_vtu(result):
    steps = [step for step in result.summary["steps"] if step["converged"]]
    return meshio.read(Path(result.directory) / f"step_{len(steps):04d}.vtu")


def surface_cut(points, u, tets, value, axis=2):
    """Where the plane x[axis] = value cuts the boundary triangles of the tetrahedra: reference points and u."""
    faces = np.sort(tets[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    unique, count = np.unique(faces, axis=0, return_counts=True)
    triangles = unique[count == 1]
    d = points[triangles, axis] - value
    crossing = triangles[(d.min(axis=1) < 0) & (d.max(axis=1) > 0)]
    cut_points, cut_u = [], []
    for tri in crossing:
        for i, j in ((0, 1), (1, 2), (2, 0)):
            di, dj = points[tri[i], axis] - value, points[tri[j], axis] - value
            if di * dj < 0:
                s = di / (di - dj)
                cut_points.append(points[tri[i]] + s * (points[tri[j]] - points[tri[i]]))
                cut_u.append(u[tri[i]] + s * (u[tri[j]] - u[tri[i]]))
    X, index = np.unique(np.round(np.array(cut_points), 12), axis=0, return_index=True)
    return X, np.array(cut_u)[index]


def ring(X, u, centre):
    theta = np.arctan2(X[:, 1] - centre[1], X[:, 0] - centre[0])
    order = np.argsort(theta)
    return X[order], u[order], theta[order]


Z_MID, MAGNIFY = 0.06, 50.0
CENTRES = {"a": (-0.012, 0.0), "b": (0.012, 0.0)}
sections = {}
for name, result in runs.items():
    data = last_vtu(result)
    tets, U = data.cells_dict["tetra"], data.point_data["u"]
    activation = data.cell_data["activation"][0][:, 0]
    X, us = surface_cut(data.points, U, tets, Z_MID)
    skin = np.hypot(X[:, 0], X[:, 1]) > 0.025
    curves = {"skin": ring(X[skin], us[skin], (0.0, 0.0))}
    for m, cells in (("a", activation > 0.99), ("b", np.abs(activation - 0.3) < 0.05)):
        curves[m] = ring(*surface_cut(data.points, U, tets[cells], Z_MID), CENTRES[m])
    sections[name] = curves
    Xs, usk, _ = curves["skin"]
    ur = np.einsum("ij,ij->i", usk[:, :2], Xs[:, :2]) / np.hypot(Xs[:, 0], Xs[:, 1])
    print(f"{name}: skin at z = 6 cm, {len(Xs)} points: radial displacement max {1e6 * ur.max():.1f} um, "
          f"mean {1e6 * ur.mean():.1f} um")

# the slip: the layered mesh has every interface node twice (a fat node and a muscle node at the same place)
data = last_vtu(layered_run)
tets, U = data.cells_dict["tetra"], data.point_data["u"]
key = np.round(data.points, 10)
_, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
inverse = np.asarray(inverse).reshape(-1)
twins = np.flatnonzero(counts[inverse] == 2)
order = twins[np.argsort(inverse[twins], kind="stable")].reshape(-1, 2)  # pairs of the same place
slip = U[order[:, 0]] - U[order[:, 1]]
z_slip = data.points[order[:, 0], 2]
print(f"{len(order)} interface node pairs: |u_fat - u_muscle| max {1e6 * np.abs(slip).max():.1f} um; "
      f"axial part max {1e6 * np.abs(slip[:, 2]).max():.1f} um, in-plane max "
      f"{1e6 * np.linalg.norm(slip[:, :2], axis=1).max():.1f} um")

# %%
if plt is not None:
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(16, 5), gridspec_kw={"width_ratios": [1, 1.2, 1.2]})
    styles = {"conforming": ("--", 0.9), "layered": ("-", 1.4)}
    colours = {"skin": "black", "a": "C3", "b": "C0"}
    for name, curves in sections.items():
        ls, lw = styles[name]
        for part, (Xc, uc, _) in curves.items():
            closed = np.r_[np.arange(len(Xc)), 0]
            ax1.plot(1e3 * (Xc[closed, 0] + MAGNIFY * uc[closed, 0]), 1e3 * (Xc[closed, 1] + MAGNIFY * uc[closed, 1]),
                     ls=ls, lw=lw, color=colours[part], label=f"{name}: {part}" if part == "skin" else None)
    ax1.set_aspect("equal")
    ax1.set_title(f"z = 6 cm, displacements x{MAGNIFY:.0f} (muscle a red, b blue)")
    ax1.set_xlabel("x (mm)")
    ax1.set_ylabel("y (mm)")
    ax1.legend(fontsize=8, loc="upper right")
    for name, curves in sections.items():
        Xs, usk, theta = curves["skin"]
        ur = np.einsum("ij,ij->i", usk[:, :2], Xs[:, :2]) / np.hypot(Xs[:, 0], Xs[:, 1])
        ax2.plot(np.degrees(theta), 1e6 * ur, styles[name][0], marker="o", ms=3, color="black" if name == "layered"
                 else "grey", label=name)
    ax2.set_xlabel("angle about the axis (deg): 0 = +x (muscle b's side)")
    ax2.set_ylabel("skin radial displacement (um)")
    ax2.set_title("the skin at z = 6 cm")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    side = np.where(data.points[order[:, 0], 0] < 0.0, "a", "b")
    for m in ("a", "b"):
        mask = side == m
        ax3.plot(1e3 * z_slip[mask], 1e6 * np.abs(slip[mask, 2]), ".", ms=3, color=colours[m],
                 label=f"muscle {m}: axial |u_fat - u_muscle|")
        ax3.plot(1e3 * z_slip[mask], 1e6 * np.linalg.norm(slip[mask, :2], axis=1), "x", ms=3, color=colours[m],
                 alpha=0.5, label=f"muscle {m}: in-plane")
    ax3.set_xlabel("z (mm)")
    ax3.set_ylabel("slip (um)")
    ax3.set_title("the fat's slip on the muscles (layered)")
    ax3.legend(fontsize=8)
    ax3.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "layered_vs_conforming.png", dpi=90)
    print("wrote", OUT / "layered_vs_conforming.png")

# %% [markdown]
# Left: the mid-length section, the conforming run dashed, the layered one solid; right: the skin's radial
# displacement against the angle; the slip along the muscles. Glued, the contracting muscles drag the fat with
# them (their fibres shorten towards the middle of the belly) and the skin bulges more; free to slide, the
# muscles shorten under the fat (the slip is mostly axial, largest on the fully active muscle a, on either side
# of its middle), and the skin's bulge is about 60 % of the glued one (docs/layers.md has the table).

# %% [markdown]
# ## Elbow flexion on capsule bones
#
# `examples/layered_arm_flexion.toml` puts the same arms on two capsule bones, as `examples/arm_flexion.toml`
# does for one muscle: a stationary humerus behind the segment (1 mm behind the skin), to which the proximal face
# is attached, and a forearm turning forward about the elbow axis (the humerus' distal end), to which the distal
# face is attached; the activations rise with the angle and the skin is in frictionless contact with the humerus.
# The segment bends back onto the humerus and the muscles, in front of the elbow axis, shorten.
# `model.experiments.layered_arm.flexion_raw` writes both configurations (layered: the example; conforming: the
# same bones and loading on the glued mesh): the example's 10 degrees in 4 steps on the coarse mesh (15 mm), about
# 30 s for both (beyond 15 degrees the layered run's Newton stalls: docs/layers.md).

# %%
from model.config import parse  # noqa: E402
from model.experiments.layered_arm import flexion_bones, flexion_raw  # noqa: E402

ANGLE = 10.0
flexion = {}
for name, layered in (("conforming", False), ("layered", True)):
    raw = flexion_raw(layered, ANGLE, steps=4, size=0.015, turn_elements=8)
    raw["output"] = {"png": False, "xdmf": False, "vtu": True}
    flexion[name] = model.run(parse(raw), out=OUT / f"flexion_{name}")
    s = flexion[name].summary
    steps = [step for step in s["steps"] if step["converged"]]
    pairs = steps[-1].get("contact_pairs", {})  # the humerus' push: the summed contact force minus the pairs'
    bone = np.asarray(steps[-1]["contact"]["force"]) - sum((np.asarray(r["force"]) for r in pairs.values()), 0.0)
    print(f"{name}: {s['cells']} cells, Newton iterations {[st['newton_iterations'] for st in steps]}, "
          f"{s['wall_time_s']:.1f} s; the humerus' push on the skin {np.round(bone, 2)} N")
    for pair, report in steps[-1].get("contact_pairs", {}).items():
        print(f"  {pair:24s} {report['kind']:8s} normal force {report['normal_force']:8.2f} N, gap "
              f"{1e6 * report['max_gap']:6.2f} um, penetration {1e6 * report['max_penetration']:6.2f} um")


# %%
def plane_segments(points, u, tets, value, axis=0):
    """The segments where the plane x[axis] = value cuts the boundary triangles of ``tets``: (n, 2, 3) reference
    points and displacements."""
    faces = np.sort(tets[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    unique, count = np.unique(faces, axis=0, return_counts=True)
    X_out, u_out = [], []
    for tri in unique[count == 1]:
        d = points[tri, axis] - value
        if d.min() >= 0 or d.max() <= 0:
            continue
        ends_X, ends_u = [], []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            if d[i] * d[j] < 0:
                s = d[i] / (d[i] - d[j])
                ends_X.append(points[tri[i]] + s * (points[tri[j]] - points[tri[i]]))
                ends_u.append(u[tri[i]] + s * (u[tri[j]] - u[tri[i]]))
        if len(ends_X) == 2:
            X_out.append(ends_X)
            u_out.append(ends_u)
    return np.array(X_out), np.array(u_out)


def capsule_outline(a, b, r, n=40):
    """The outline of a capsule's projection on the (z, y) plane (a and b in the plane x = 0)."""
    a, b = np.asarray(a)[[2, 1]], np.asarray(b)[[2, 1]]
    d = (b - a) / np.linalg.norm(b - a)
    normal = np.array([-d[1], d[0]])
    phi = np.linspace(-np.pi / 2, np.pi / 2, n)
    cap_b = b + r * (np.outer(np.cos(phi), d) + np.outer(np.sin(phi), normal))
    cap_a = a + r * (np.outer(np.cos(phi), -d) + np.outer(np.sin(phi), -normal))
    return np.vstack([cap_b, cap_a, cap_b[:1]])


X_PLANE = -0.012  # muscle a's axis
if plt is not None:
    from matplotlib.collections import LineCollection

    fig, ax = plt.subplots(figsize=(11, 6))
    bones = flexion_bones(ANGLE)
    hinge = bones[1]["hinge"]
    from forms.motions import HingeMotion

    Q, c = HingeMotion(hinge["axis"], hinge["point"], hinge["angles"])(1.0)
    for bone, (a, b) in zip(bones, ((bones[0]["a"], bones[0]["b"]),
                                    (bones[1]["a"], Q @ np.array([0.0, bones[1]["a"][1], 0.22]) + c))):
        outline = capsule_outline(a, b, bone["radius"])
        ax.fill(1e3 * outline[:, 0], 1e3 * outline[:, 1], color="0.85", zorder=0)
        ax.text(1e3 * 0.5 * (a[2] + b[2]), 1e3 * 0.5 * (a[1] + b[1]), bone["name"], ha="center", va="center",
                fontsize=8)
    for name, ls in (("conforming", "--"), ("layered", "-")):
        data = last_vtu(flexion[name])
        tets, U = data.cells_dict["tetra"], data.point_data["u"]
        activation = data.cell_data["activation"][0][:, 0]
        for part, cells, colour in (("outline", tets, "black"), ("a", tets[activation > 0.99], "C3")):
            X, uu = plane_segments(data.points, U, cells, X_PLANE)
            if part == "outline":  # the skin and the end faces, not the interfaces of the layered mesh
                mid = X.mean(axis=1)
                keep = (np.hypot(mid[:, 0], mid[:, 1]) > 0.026) | (mid[:, 2] < 1e-9) | (mid[:, 2] > 0.12 - 1e-9)
                X, uu = X[keep], uu[keep]
            x = X + uu
            lines = LineCollection(1e3 * x[:, :, [2, 1]], colors=colour, linestyles=ls, linewidths=1.2,
                                   label=f"{name}: {'skin' if part == 'outline' else 'muscle a'}")
            ax.add_collection(lines)
    ax.set_aspect("equal")
    ax.autoscale()
    ax.set_xlabel("z (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"flexion {ANGLE:.0f} degrees, the plane x = {1e3 * X_PLANE:.0f} mm (muscle a's axis), true "
                 "displacements")
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(OUT / "layered_arm_flexion.png", dpi=90)
    print("wrote", OUT / "layered_arm_flexion.png")

# %% [markdown]
# The plane through muscle a's axis: the humerus behind (below; its projection: the skin touches it on the line
# x = 0, 2.5 mm further back than this plane's skin), the forearm turned by 10 degrees about the elbow axis (the
# humerus' distal end); the layered arm solid, the conforming one dashed. The numbers of both runs (bulge,
# skin displacement, slip, the pairs' and the humerus' forces) are in docs/layers.md.

# %% [markdown]
# ## Muscles that close a gap
#
# `examples/layered_arm_gap.toml`: no fat between the muscles, whose bellies are cut flat 0.15 mm apart (the
# slab between them is a void: `layered_arm`'s `gap`); both muscles are activated to 1 in two steps and their
# flat faces are in frictionless penalty contact. At half the activation the faces have approached but are still
# apart (no contact force); at full activation they touch and press on each other. About 40 s.

# %%
gap_run = model.run(ROOT / "examples" / "layered_arm_gap.toml", out=OUT / "gap", overrides=OVERRIDES)
gap_steps = [step for step in gap_run.summary["steps"] if step["converged"]]
for step in gap_steps:
    report = step["contact_pairs"]["a_flat-b_flat"]
    print(f"load {step['load_factor']:.2f}: a_flat-b_flat normal force {report['normal_force']:.3f} N, "
          f"active points {report['active_points']}, penetration {1e6 * report['max_penetration']:.3f} um, "
          f"largest gap {1e6 * report['max_gap']:.1f} um")

# %%
if plt is not None:
    from matplotlib.collections import LineCollection

    fig, ax = plt.subplots(figsize=(9, 4.5))
    final = last_vtu(gap_run)
    tets = final.cells_dict["tetra"]
    belly = final.cell_data["activation"][0][:, 0] > 0.99  # both bellies are active (the tendons and the fat not)
    centre_x = final.points[tets, 0].mean(axis=1)
    for index, (ls, label) in enumerate((("--", "rest"), (":", "half the activation"), ("-", "full activation"))):
        data = meshio.read(Path(gap_run.directory) / f"step_{max(index, 1):04d}.vtu")
        U = data.point_data["u"] * (index > 0)
        for muscle, colour in (("a", "C3"), ("b", "C0")):
            cells = tets[belly & ((centre_x < 0) if muscle == "a" else (centre_x > 0))]
            X, uu = plane_segments(data.points, U, cells, 0.06, axis=2)  # the mid-length section
            near = np.abs(X[:, :, 0]).max(axis=1) < 0.002  # the flat faces (x within 2 mm)
            x = X[near] + uu[near]
            ax.add_collection(LineCollection(np.stack([1e3 * x[:, :, 1], 1e6 * x[:, :, 0]], axis=2), colors=colour,
                                             linestyles=ls, linewidths=1.2,
                                             label=f"muscle {muscle}, {label}"))
    ax.autoscale()
    ax.set_ylim(-150, 150)
    ax.set_xlabel("y (mm)")
    ax.set_ylabel("x (um)")
    ax.set_title("the flat faces at mid-length (z = 60 mm): 150 um apart at rest, pressed together at full "
                 "activation", fontsize=9)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    fig.tight_layout()
    fig.savefig(OUT / "layered_arm_gap.png", dpi=90)
    print("wrote", OUT / "layered_arm_gap.png")

# %% [markdown]
# The section of the two bellies at mid-length near the plane x = 0 (x magnified: micrometres against
# millimetres): the flat faces start 150 um apart (dashed), approach by about 100 um at half the activation
# (dotted: still apart, no contact force) and meet at full activation (solid: on top of each other at
# mid-length, the contact holding them within the penalty's p/k, 0.5 um); towards the lens' ends (z) they stay
# apart (the largest gap, 47 um).
# docs/layers.md ("Muscles that close a gap") has the numbers.

# %% [markdown]
# ## The touching muscles flexed
#
# `examples/layered_arm_touching_flexion.toml`: the touching muscles (their bellies share a flat face, no fat
# between them) on the flexion's bones. Over the first half of the load both muscles are activated to 1: the
# bellies thicken and press the shared face together. Over the second half the forearm turns forward by 5
# degrees, the activations held: the bones shorten the segment and the face is unloaded. About 30 s.

# %%
flexed = model.run(ROOT / "examples" / "layered_arm_touching_flexion.toml", out=OUT / "touching_flexion",
                   overrides={**OVERRIDES, "output.vtu": False})
flexed_steps = [step for step in flexed.summary["steps"] if step["converged"]]
loads, forces, actives = [0.0], [0.0], [0]
for step in flexed_steps:
    report = step["contact_pairs"]["a_flat-b_flat"]
    loads.append(step["load_factor"])
    forces.append(report["normal_force"])
    actives.append(report["active_points"])
    print(f"load {step['load_factor']:.2f}: a_flat-b_flat normal force {report['normal_force']:.4f} N on "
          f"{report['active_points']} nodes, penetration {1e6 * report['max_penetration']:.2f} um")

# %%
if plt is not None:
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(loads, forces, "o-", color="C3", label="normal force on the shared face")
    ax.axvspan(0.0, 0.5, color="C1", alpha=0.1, label="activation 0 to 1")
    ax.axvspan(0.5, 1.0, color="C0", alpha=0.1, label="flexion 0 to 5 degrees")
    for load, force, active in zip(loads, forces, actives):
        ax.annotate(f"{active} nodes", (load, force), textcoords="offset points", xytext=(4, 6), fontsize=8)
    ax.set_xlabel("load factor")
    ax.set_ylabel("N")
    ax.set_title("the muscles' contact: pressed by the activation, unloaded by the flexion", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(OUT / "layered_arm_touching_flexion.png", dpi=90)
    print("wrote", OUT / "layered_arm_touching_flexion.png")

# %% [markdown]
# The force rises about linearly with the activation (10.3 N at full activation, the touching run's with its end
# faces clamped: the bones have not moved yet) and falls with the flexion: 4.3 N at 2.5 degrees, 0.02 N on one
# node at 5; beyond, the face opens. docs/layers.md ("Flexion of the touching muscles") has the numbers.
