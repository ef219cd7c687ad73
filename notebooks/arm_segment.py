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
# # Two muscles in an arm segment
#
# A 12 cm long cylinder of fat, radius 3 cm, holds two fusiform muscles side by side
# (`meshes.arm_segment`, `examples/arm_segment.toml`): muscle **a** on the axis x = -12 mm,
# muscle **b** on x = +12 mm, both along z, each a belly of radius 11 mm at mid-length between
# tendons of radius 4 mm and 2 cm length. At mid-length the two bellies are only 2 mm apart.
# Every end face is clamped (the fat's two end faces and the four tendon disks); the lateral
# surface, the *skin*, is free. With the load factor, muscle a is activated to $\alpha$ = 1 and
# muscle b to $\alpha$ = 0.3. Both contract isometrically and bulge, and the question is what the
# surrounding fat and the skin make of it.
#
# **Laws** (thesis parameters, chapter 4). Muscle (`forms/muscle.py`, `energies.md`):
#
# $$\psi = F_1 + K (\ln J)^2 + F_2(\bar\lambda, \alpha),\qquad
#   \frac{\partial F_2}{\partial \bar\lambda} = \frac{\sigma_{max}}{l_{ofl}}
#   \big(f_{passive}(\bar\lambda / l_{ofl}) + \alpha\, f_{active}(\bar\lambda / l_{ofl})\big),$$
#
# with $\bar\lambda = \sqrt{a_0 \cdot J^{-2/3} C a_0}$ the isochoric fibre stretch, $F_1$ the StVK
# matrix $\mu E{:}E + \frac{\lambda}{2} (\operatorname{tr} E)^2$ ($E$ = 9 MPa, $\nu$ = 0.45),
# $\sigma_{max}$ = 300 kPa, $f_{active}(s) = 1 - 4 (1 - s)^2$ near $s = 1$. Tendon: the same
# structure with a stiff exponential fibre curve and no activation ($E$ = 15 MPa). Fat: StVK,
# $E$ = 1 MPa, $\nu$ = 0.45. Fibres: per muscle a Laplace field from its origin disk to its
# insertion disk through belly and tendons. P1 displacement (about 42 000 tetrahedra; $\nu$ = 0.45
# does not lock).
#
# Probes at mid-length (z = 6 cm) give each belly's centre and top point (10.5 mm above its axis)
# and two skin points above the muscles. The VTU results give the rest: the mid-length
# cross-section of the skin and of both bellies.
#
# Run with plain Python (`python notebooks/arm_segment.py`); the run is the same with and
# without `CI` (about half a minute).

# %%
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "arm_segment"
WRITE_DOCS = os.environ.get("WRITE_DOCS") == "1"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import meshio  # noqa: E402
from _pictures import render  # noqa: E402

import model.config  # noqa: E402

OUT.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## The run

# %%
EXAMPLE = ROOT / "examples" / "arm_segment.toml"
raw = model.config.read(EXAMPLE)  # the document as written, for its probes
result = model.run(EXAMPLE, out=OUT, overrides={"output.png": False, "output.xdmf": False, "output.vtu": True})
summary = result.summary
steps = [s for s in summary["steps"] if s["converged"]]
print(f"{summary['cells']} cells, {summary['dofs']} dofs, {len(steps)} steps, {summary['wall_time_s']:.1f} s, "
      f"Newton iterations per step: {[s['newton_iterations'] for s in steps]}")
print("activation at the last step:", steps[-1]["activation"])

# %% [markdown]
# ## The probes: how much each muscle thickens, and where it goes
#
# A belly's *thickening* at mid-length is how far its top point moves away from its own axis:
# $u_y$(top) $-\ u_y$(centre). The centre's $u_x$ says whether the muscle as a whole is pushed
# sideways.

# %%
u = {name: np.asarray(value) for name, value in steps[-1]["probes"].items()}
thickening = {m: u[f"belly_{m}_top"][1] - u[f"belly_{m}_centre"][1] for m in ("a", "b")}
for m, alpha in (("a", 1.0), ("b", 0.3)):
    print(f"muscle {m} (alpha = {alpha}): thickening {1e6 * thickening[m]:6.1f} um, "
          f"centre displacement (x, y, z) = {np.array2string(1e6 * u[f'belly_{m}_centre'], precision=1)} um")
print(f"thickening a / b = {thickening['a'] / thickening['b']:.2f}")
probe_points = {p["name"]: np.asarray(p["point"]) for p in raw["probe"]}
for name in ("skin_over_a", "skin_over_b"):
    point = probe_points[name]
    radial = np.dot(u[name][:2], point[:2]) / np.linalg.norm(point[:2])
    theta = np.degrees(np.arctan2(point[1], point[0]))
    print(f"{name} (theta = {theta:5.1f} deg): radial displacement {1e6 * radial:6.1f} um, "
          f"u_x = {1e6 * u[name][0]:6.1f} um")
print("tendon forces (N, z component): " + ", ".join(
    f"{b} {steps[-1]['reactions'][b][2]:.2f}" for b in ("a_insertion", "b_insertion", "distal")))
assert thickening["a"] > 1.5 * thickening["b"] > 0 and u["belly_b_centre"][0] > 0

# %% [markdown]
# Muscle a, fully active, thickens more than twice as much as muscle b at 30 % activation, and
# pulls about three times harder on its tendons. Its centre stays where it was, while muscle b
# as a whole is pushed towards +x by about a tenth of a millimetre, more than its own thickening:
# muscle a's bulge pushes its weaker neighbour away through the 2 mm gap between them.
#
# ## The mid-length cross-section
#
# The plane z = 6 cm cuts the boundary triangles of the whole body (the skin) and of each belly
# (its interface with the fat) along closed curves; along them the P1 displacement is exact
# (linear interpolation on the triangle edges). Cells are told apart by their activation at the
# last step (1: belly a, 0.3: belly b, 0: fat; the tendons do not reach mid-length).

# %%
def surface_cut(points, u, tets, axis, value):
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


def closed_curve(X, u, centre):
    """The cut points ordered by their angle about ``centre`` (reference), the first repeated at the end."""
    theta = np.arctan2(X[:, 1] - centre[1], X[:, 0] - centre[0])
    order = np.argsort(theta)
    order = np.append(order, order[0])
    return X[order], u[order], theta[order]


Z_MID, MAGNIFY = 0.06, 50.0
data = meshio.read(OUT / f"step_{len(steps):04d}.vtu")
tets, U = data.cells_dict["tetra"], data.point_data["u"]
activation = data.cell_data["activation"][0][:, 0]
outlines = {}
X, us = surface_cut(data.points, U, tets, 2, Z_MID)
skin = np.hypot(X[:, 0], X[:, 1]) > 0.025
outlines["skin"] = closed_curve(X[skin], us[skin], (0.0, 0.0))
for m, cells, centre in (("a", activation > 0.99, (-0.012, 0.0)), ("b", np.abs(activation - 0.3) < 0.05, (0.012, 0.0))):
    X, us = surface_cut(data.points, U, tets[cells], 2, Z_MID)
    outlines[f"muscle {m}"] = closed_curve(X, us, centre)
    print(f"muscle {m}: {len(X)} outline points, reference radius "
          f"{1e3 * np.hypot(X[:, 0] - centre[0], X[:, 1] - centre[1]).mean():.2f} mm")

# radial displacement of the skin against the angle theta about the segment's axis (the ring without its repeat)
Xs, usk, theta = (v[:-1] for v in outlines["skin"])
radius = np.hypot(Xs[:, 0], Xs[:, 1])
ur = (usk[:, 0] * Xs[:, 0] + usk[:, 1] * Xs[:, 1]) / radius
deg = np.degrees(theta)
print(f"skin: {len(Xs)} points on the ring, reference radius {1e3 * radius.min():.2f}..{1e3 * radius.max():.2f} mm")
k_max, k_min = np.argmax(ur), np.argmin(ur)
print(f"skin radial displacement: max {1e6 * ur[k_max]:.1f} um at theta = {deg[k_max]:.1f} deg, "
      f"min {1e6 * ur[k_min]:.1f} um at theta = {deg[k_min]:.1f} deg")
for target in (0.0, 90.0, 180.0, -90.0):
    k = np.argmin(np.abs((deg - target + 180.0) % 360.0 - 180.0))
    print(f"  theta = {deg[k]:7.1f} deg: u_r = {1e6 * ur[k]:6.1f} um")

# Fourier modes of u_r(theta) (trapezoidal rule on the periodic, unevenly spaced ring):
# c0 = mean swelling, c1 cos(theta) = shift towards +x, c2 cos(2 theta) = ovalisation along x
t_per = np.append(theta, theta[0] + 2.0 * np.pi)
ur_per = np.append(ur, ur[0])


def mode(weight):
    return np.trapz(ur_per * weight(t_per), t_per) / np.pi


fourier = {"c0 (mean)": 0.5 * mode(np.ones_like), "c1 cos": mode(np.cos), "s1 sin": mode(np.sin),
           "c2 cos 2": mode(lambda t: np.cos(2 * t)), "c3 cos 3": mode(lambda t: np.cos(3 * t))}
print("skin u_r Fourier modes (um): " + ", ".join(f"{k} {1e6 * v:.1f}" for k, v in fourier.items()))

# the muscles' outer edges along x: muscle b's at theta = 0, muscle a's at theta = 180 deg (about their own axes)
for m, side in (("a", 180.0), ("b", 0.0)):
    Xc, uc, th = outlines[f"muscle {m}"]
    k = np.argmin(np.abs((np.degrees(th) - side + 180.0) % 360.0 - 180.0))
    print(f"muscle {m}: outer edge (local angle {np.degrees(th[k]):6.1f} deg) moves u_x = {1e6 * uc[k, 0]:6.1f} um")

# %%
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1, 1.3]})
    colours = {"skin": "black", "muscle a": "C3", "muscle b": "C0"}
    for name, (Xc, uc, _) in outlines.items():
        ax1.plot(1e3 * Xc[:, 0], 1e3 * Xc[:, 1], color="grey", lw=0.8, ls="--")
        ax1.plot(1e3 * (Xc[:, 0] + MAGNIFY * uc[:, 0]), 1e3 * (Xc[:, 1] + MAGNIFY * uc[:, 1]), color=colours[name],
                 label=name)
    ax1.plot([], [], color="grey", lw=0.8, ls="--", label="reference")
    ax1.set_aspect("equal")
    ax1.set_xlabel("x (mm)")
    ax1.set_ylabel("y (mm)")
    ax1.set_title(f"z = {100 * Z_MID:.0f} cm, displacements x{MAGNIFY:.0f}")
    ax1.legend(fontsize=8, loc="upper right")
    ax2.plot(deg, 1e6 * ur, "o-", ms=3, color="black", label="skin (about the segment's axis)")
    ax2.plot(np.linspace(-180, 180, 181), 1e6 * (fourier["c0 (mean)"] + fourier["c1 cos"] * np.cos(np.radians(
        np.linspace(-180, 180, 181))) + fourier["c2 cos 2"] * np.cos(2 * np.radians(np.linspace(-180, 180, 181)))),
        color="grey", lw=0.8, ls=":", label="skin: c0 + c1 cos(theta) + c2 cos(2 theta)")
    for m, centre in (("a", (-0.012, 0.0)), ("b", (0.012, 0.0))):
        Xc, uc, th = (v[:-1] for v in outlines[f"muscle {m}"])
        rel = uc[:, :2] - u[f"belly_{m}_centre"][:2]  # relative to the motion of the muscle's axis
        radial = (rel[:, 0] * (Xc[:, 0] - centre[0]) + rel[:, 1] * (Xc[:, 1] - centre[1])) / np.hypot(
            Xc[:, 0] - centre[0], Xc[:, 1] - centre[1])
        ax2.plot(np.degrees(th), 1e6 * radial, ".-", color=colours[f"muscle {m}"],
                 label=f"muscle {m} outline (about its own axis, minus the axis' motion)")
    ax2.axhline(0.0, color="grey", lw=0.8)
    ax2.set_xticks(np.arange(-180, 181, 45))
    ax2.set_xlabel("angle theta (deg): 0 = +x (towards b), 180 = -x (beyond a), 90 = +y")
    ax2.set_ylabel("radial displacement (um)")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "cross_section.png", dpi=90)

# %% [markdown]
# What the cross-section shows (left: outlines with displacements magnified 50 times; right:
# radial displacements against the angle):
#
# - **Muscle a** (fully active) swells almost uniformly about its axis, by 92 to 101 um all
#   round, and stays in place.
# - **Muscle b** (30 %) swells much less and not uniformly: 20 to 27 um along x (towards the skin
#   at 0 deg and towards muscle a at 180 deg), about 40 um at +-120 deg. As a whole it moves
#   +x by 115 um, its outer edge by about 136 um: muscle a pushes it sideways.
# - **The skin** moves outwards all round (mean 93 um: both muscles thicken and the nearly
#   incompressible fat has to go somewhere), but not uniformly. Its radial displacement is
#   ovalised along the line of the muscles (the cos 2 theta mode, about 22 um: 100 to 130 um at
#   0 and 180 deg, 68 to 79 um near +-90 deg) and shifted towards +x (the cos theta mode, about
#   13 um). It peaks near theta = 0 (130 to 132 um between -13 and +13 deg), on muscle b's side,
#   where the fat between muscle and skin is thinnest (7 mm) and muscle b's outer edge has moved
#   136 um; beyond muscle a (theta = 180 deg) it moves about 100 um, close to a's outer edge
#   (93 um).
#
# So the skin deforms asymmetrically, but not by bulging most over the most active muscle: the
# skin probes above the muscles (theta = 66 and 114 deg) move out by 84 um over b and 77 um over
# a. The asymmetry comes from muscle a pushing muscle b towards +x, and it is modest next to the
# overall swelling (cos theta mode 13 um, mean 93 um). The ring has only about 50 points (the
# mesh's resolution on the skin), so the angles of the extremes are known to about +-10 deg.
#
# ## Picture
#
# The segment cut open along the plane of the two muscles' axes (the half y > 0, seen from -y;
# proximal end at the bottom). Left: the rest shape coloured by the activation (a: 1 on the left,
# b: 0.3 on the right, fat and tendons 0). Right: the last step with displacements magnified
# 50 times, coloured by the displacement magnitude. The largest displacements (about 0.3 mm) are
# axial, inside muscle a, halfway between its middle and its tendons: its fibres shorten towards
# the middle of the belly while the stretched narrow ends and the tendons let them; the sideways
# bulge of both muscles and of the skin is a third of that.

# %%
PICTURE_MAGNIFY = 50.0
X = data.points[tets]
half = np.flatnonzero(X.mean(axis=1)[:, 1] > 0.0).tolist()
magnitude = 1e6 * np.linalg.norm(U, axis=1)[tets].mean(axis=1)  # um, cell average
path = OUT / "picture.vtu"
meshio.write(path, meshio.Mesh(data.points, [("tetra", tets)], point_data={"u": PICTURE_MAGNIFY * U},
                               cell_data={"activation": [activation], "displacement_um": [magnitude]}))
png = render({
    "png": str(OUT / "arm_segment.png"), "window": [1200, 700], "view": "xz", "zoom": 1.15, "label_size": 16,
    "panels": [
        {"vtu": str(path), "offset": [0.0, 0.0, 0.0], "deformed": False, "cells": half, "scalars": "activation",
         "cmap": "Reds", "clim": [0.0, 1.0], "bar": "activation", "bar_position": [0.08, 0.03, 0.35]},
        {"vtu": str(path), "offset": [0.075, 0.0, 0.0], "cells": half, "scalars": "displacement_um",
         "cmap": "viridis", "clim": [0.0, float(np.percentile(magnitude, 99.5))],
         "bar": f"displacement (um), shown x{PICTURE_MAGNIFY:.0f}", "bar_position": [0.57, 0.03, 0.35]},
    ],
})
print("wrote", png)
