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
# # Elbow flexion: a muscle shortens, bulges and is pressed onto the humerus
#
# An arm in its simplest form (`examples/arm_flexion.toml`): two bones as capsules (rigid bodies
# with an analytic shape, `[[bone]]`) and one fusiform, biceps-like muscle between them.
#
# * **Humerus**: a stationary capsule of radius 11 mm parallel to the muscle, 1 mm behind its belly,
#   from the shoulder to the elbow.
# * **Forearm** (the radius): a capsule that turns about the elbow axis (the x axis through the
#   distal end of the humerus) from 0 to 90 degrees: a `hinge` whose angle is a table of the
#   load factor t. Flexion brings it forward, to the muscle's side.
# * **Muscle** (`meshes.fusiform`: belly 12 cm long and 16 mm in radius between two tendons
#   2 cm long, 5 mm in radius): its origin disk is `attached` to the humerus, its insertion disk to
#   the forearm, 2.8 cm in front of the forearm's axis and 2.3 cm beyond the elbow, so flexion
#   pulls the insertion back towards the shoulder: the muscle shortens from 16 to 10.9 cm and its
#   insertion tendon is bent through 90 degrees.
# * **Laws**: the Teran/Blemker fibre law (`forms/muscle.py`) with a soft Mooney-Rivlin matrix
#   ($c_1$ = 10 kPa, $K$ = 1 MPa) in the belly and the tendon law (stiffer matrix,
#   $c_1$ = 100 kPa, $K$ = 10 MPa) in the tendons; fibres along a Laplace field from origin to
#   insertion. The belly's activation rises with the angle: $\alpha = t$ (0 at rest, 1 at 90 degrees).
# * **Contact**: the muscle's whole skin against the humerus' capsule, frictionless, with the energy
#   $\int \tfrac{k}{2}\min(g - \lambda/k, 0)^2 - \lambda^2/(2k)\,dA$ ($k$ = 1e9 Pa/m) and Uzawa updates
#   of the nodal pressures $\lambda$ until no skin node penetrates (or is held off) by more than
#   2e-4 of the body size (33 um, 0.3 % of the bone's radius): `model/contact.py`.
#
# Everything is quasi-static: t is a pseudo-time that moves the forearm and raises the activation
# together; each load step is a Newton solve (cut back when it fails). We follow the elbow angle,
# the contact force, the penetration, the number of skin nodes in contact and the belly's bulge,
# and draw frames of the motion.
#
# Run with plain Python (`python notebooks/arm_flexion.py`); with `CI` set it runs the example as
# written (12 load steps, about 20 s), otherwise 24 steps. `WRITE_DOCS=1` also writes
# `docs/arm_flexion.png`.

# %%
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "arm_flexion"
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

import model.config  # noqa: E402
from forms.motions import HingeMotion  # noqa: E402

OUT.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## The run
#
# P1 displacements (about 6300 tetrahedra, 5200 dofs); only the VTU results are written (they
# feed the pictures).

# %%
EXAMPLE = ROOT / "examples" / "arm_flexion.toml"
raw = model.config.read(EXAMPLE)  # the document as written, for its bones, probes and contact settings
config = model.load_config(EXAMPLE, overrides={"loading.steps": 12 if CI else 24, "output.png": False,
                                               "output.xdmf": False, "output.vtu": True})
summary = model.run(config, out=OUT).summary
attempts = summary["steps"]
steps = [s for s in attempts if s["converged"]]
print(f"{summary['cells']} cells, {summary['dofs']} dofs, {len(steps)} steps ({len(attempts) - len(steps)} cut "
      f"back), {summary['wall_time_s']:.1f} s")
print("Newton iterations per attempt (x: failed, cut back):",
      " ".join(f"{s['newton_iterations']}{'' if s['converged'] else 'x'}" for s in attempts))

# %% [markdown]
# ## Angle, contact, bulge
#
# Per converged step: the elbow angle $\theta(t)$ (the forearm's hinge), the activation, the
# muscle's length (origin disk centre to insertion disk centre), the total force the humerus exerts
# on the muscle, the largest penetration of a skin node into the bone, the skin nodes in contact
# (positive contact pressure), the bulge (half the change of the belly's width across the plane of
# motion, between two probes at mid-belly, 15.5 mm either side of the axis) and the muscle's volume
# change.

# %%
bones = {b["name"]: b for b in raw["bone"]}
humerus, forearm = bones["humerus"], bones["radius"]
hinge = forearm["hinge"]
motion = HingeMotion(hinge["axis"], hinge["point"], [tuple(row) for row in hinge["angles"]])
probes = {p["name"]: np.array(p["point"]) for p in raw["probe"]}
mesh = raw["mesh"]
length0 = mesh["length"] + 2 * mesh["tendon_length"]


def curve(key):
    return np.array([key(s) for s in steps])


t = curve(lambda s: s["load_factor"])
angle = np.degrees([motion.angle(ti) for ti in t])
activation = curve(lambda s: s["activation"]["belly"])
force = curve(lambda s: s["contact"]["force"])
penetration = curve(lambda s: s["contact"]["max_penetration"])
active = curve(lambda s: s["contact"]["active_points"])
bulge = curve(lambda s: 0.5 * (s["probes"]["belly_side_plus"][0] - s["probes"]["belly_side_minus"][0]))
length = curve(lambda s: np.linalg.norm(probes["insertion_centre"] + s["probes"]["insertion_centre"]))
volume = curve(lambda s: s["volumes"]["all"] / summary["region_volumes"]["all"] - 1.0)
print(f"{'angle':>6s} {'alpha':>6s} {'length (cm)':>11s} {'contact force (N)':>24s} {'|F| (N)':>8s} "
      f"{'penetration (um)':>16s} {'nodes':>5s} {'bulge (mm)':>10s} {'dV (%)':>7s}")
for i in range(len(t)):
    f = force[i]
    print(f"{angle[i]:6.1f} {activation[i]:6.3f} {100 * length[i]:11.2f} [{f[0]:6.2f} {f[1]:7.2f} {f[2]:6.2f}] "
          f"{np.linalg.norm(f):8.2f} {1e6 * penetration[i]:16.1f} {active[i]:5d} {1e3 * bulge[i]:10.3f} "
          f"{100 * volume[i]:7.3f}")
size = np.sqrt(2 * (2 * mesh["belly_radius"]) ** 2 + length0**2)  # bounding-box diagonal of the muscle
uzawa = raw["contact"][0]["tolerance"] * size
print(f"Uzawa tolerance {1e6 * uzawa:.1f} um = {100 * uzawa / humerus['radius']:.2f} % of the humerus radius; "
      f"largest penetration {1e6 * penetration.max():.1f} um")
assert summary["status"] == "completed" and np.all(np.diff(length) < 0) and penetration.max() <= 1.01 * uzawa

# %%
if plt is not None:
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    ax = axes[0, 0]
    ax.plot(angle, np.linalg.norm(force, axis=1), "o-", label="|F|")
    ax.plot(angle, force[:, 1], ".--", label="F_y (away from the bone)")
    ax.set_ylabel("contact force on the muscle (N)")
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    ax.plot(angle, 1e6 * penetration, "o-", color="C3")
    ax.axhline(1e6 * uzawa, color="grey", ls="--", lw=0.8, label="Uzawa tolerance")
    ax.set_ylabel("max penetration of a skin node (um)")
    ax.legend(fontsize=8)
    ax = axes[1, 0]
    ax.step(angle, active, where="mid", color="C2")
    ax.set_ylabel("skin nodes in contact")
    ax = axes[1, 1]
    ax.plot(angle, 1e3 * bulge, "o-", color="C4", label="mid-belly bulge")
    ax.set_ylabel("bulge (mm)", color="C4")
    twin = ax.twinx()
    twin.plot(angle, 100 * length, "s--", color="C5", ms=3)
    twin.set_ylabel("muscle length (cm)", color="C5")
    for ax in axes[1]:
        ax.set_xlabel("elbow angle (degrees)   (activation = angle / 90)")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "arm_flexion_curves.png", dpi=90)

# %% [markdown]
# The belly bulges from the first step on: the activation makes its fibres contract, at nearly
# constant volume, and the forearm lets the muscle shorten. Within the first 10 degrees (activation
# 0.1) the bulge closes the 1 mm gap and the back of the belly touches the humerus; from then on the
# bone pushes it forward (+y, away from the bone's axis; no component along the bone: the contact
# is frictionless and on the capsule's shaft). The force grows with the angle: the muscle, ever
# more active and shorter, is pulled straight between its origin and its insertion, which flexion
# has brought to 5 mm behind the muscle's original axis, and its back slides along the bone (the
# contact moves from z = 7 cm to z = 5 cm); near 90 degrees the end of the belly, where the bent
# insertion tendon starts, also comes down onto the bone. The contact patches are narrow (a spindle
# on a cylinder: two convex bodies), so only a few skin nodes carry the force. The penetration stays
# below the Uzawa tolerance at every step, and the volume changes by less than 1 %.
#
# ## Inside the belly at 90 degrees
#
# From the last step's VTU: the isochoric fibre stretch $\bar\lambda = J^{-1/3}|F a_0|$ of every
# tetrahedron, volume-averaged in 1 cm slices of the reference axis.

# %%
last = meshio.read(OUT / f"step_{len(steps):04d}.vtu")
tets = last.cells_dict["tetra"]
state = cell_fibre_state(last)
cell_volume, centroid, J, fibre_stretch = (state[k] for k in ("volume", "centroid", "J", "fibre_stretch"))
belly = last.cell_data["activation"][0][:, 0] > 0
print(f"{'z (cm)':>7s} {'part':>7s} {'fibre stretch':>14s}")
for lo in np.arange(0.0, length0 - 1e-9, 0.01):
    m = (centroid[:, 2] >= lo) & (centroid[:, 2] < lo + 0.01)
    print(f"{100 * lo + 0.5:7.1f} {'belly' if belly[m].mean() > 0.5 else 'tendon':>7s} "
          f"{np.average(fibre_stretch[m], weights=cell_volume[m]):14.3f}")
middle = belly & (np.abs(centroid[:, 2] - 0.08) < 0.04)
print(f"middle of the belly: fibre stretch {np.average(fibre_stretch[middle], weights=cell_volume[middle]):.3f}; "
      f"J of all cells {J.min():.3f} .. {J.max():.3f}")

# %% [markdown]
# The belly's fibres have shortened much more than the muscle as a whole (10.9 / 16 = 0.68): with a
# soft matrix the active stress (up to 300 kPa) contracts them to about 0.6 of their rest length in
# the middle of the belly, less at its ends (0.8 next to the origin tendon, about 1 where the
# insertion tendon bends), while the tendons keep their length (their fibres are stiff in tension;
# the bent insertion tendon is shortened on average). The contracting middle of the belly is what
# bulges.
#
# ## Side view of the motion
#
# The muscle's outline in its plane of motion (where the plane x = 0 cuts its skin), at four
# angles, with the two bones (the forearm is drawn 10 cm long, with a thin bar from its axis to the
# insertion disk: the tuberosity the muscle is attached to). Arm hanging down: shoulder at the top,
# front to the right; crosses: the centres of the origin and insertion disks.

# %%


def forearm_point(X):
    """The point of the forearm's axis nearest to the reference point X."""
    a, b = np.asarray(forearm["a"], dtype=float), np.asarray(forearm["b"], dtype=float)
    e = (b - a) / np.linalg.norm(b - a)
    return a + ((X - a) @ e) * e


# what the pictures draw, as capsules (a, b, radius, carried by the forearm?): the humerus, the forearm
# shortened to 10 cm, and a thin bar from the forearm's axis to the insertion disk (the tuberosity the
# muscle is attached to, 2.8 cm in front of the axis)
SHAPES = [
    (humerus["a"], humerus["b"], humerus["radius"], False),
    (forearm["a"], forearm_point(np.asarray(forearm["a"]) + [0.0, 0.0, 0.1]), forearm["radius"], True),
    (forearm_point(probes["insertion_centre"]), probes["insertion_centre"], 0.003, True),
]


def shapes_at(ti):
    """[(a, b, radius)] of the drawn capsules at time ti."""
    Q, c = motion(ti)
    out = []
    for a, b, r, moving in SHAPES:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        out.append((Q @ a + c, Q @ b + c, r) if moving else (a, b, r))
    return out


def stadium(a, b, r, n=24):
    """The outline of a capsule's projection on the plane (y, z): points (y, z)."""
    a2, b2 = np.asarray(a)[1:], np.asarray(b)[1:]
    d = (b2 - a2) / np.linalg.norm(b2 - a2)
    phi0 = np.arctan2(d[1], d[0])
    arc = np.linspace(-np.pi / 2, np.pi / 2, n)
    return np.vstack([b2 + r * np.c_[np.cos(phi0 + arc), np.sin(phi0 + arc)],
                      a2 + r * np.c_[np.cos(phi0 + np.pi + arc), np.sin(phi0 + np.pi + arc)]])


targets = [0.0, 30.0, 60.0, 90.0]
frames = [None] + [int(np.argmin(np.abs(angle - target))) for target in targets[1:]]  # None: the rest state
if plt is not None:
    fig, axes = plt.subplots(1, 4, figsize=(13, 4.8), sharey=True)
    for ax, k in zip(axes, frames):
        ti = 0.0 if k is None else t[k]
        data = last if k is None else meshio.read(OUT / f"step_{k + 1:04d}.vtu")
        u = np.zeros_like(data.points) if k is None else data.point_data["u"]
        Xs, us = surface_cut(data.points, u, tets, 0, 0.0)
        xs = Xs + us
        for shape in shapes_at(ti):
            outline = stadium(*shape)
            ax.fill(outline[:, 0], -outline[:, 1], color="0.75", ec="0.4", lw=0.8)
        ax.plot(xs[:, 1], -xs[:, 2], ".", ms=2.5, color="C0")
        insertion = probes["insertion_centre"] + (0.0 if k is None else np.asarray(
            steps[k]["probes"]["insertion_centre"]))
        ax.plot([0.0, insertion[1]], [0.0, -insertion[2]], "x", color="C3")  # origin and insertion disk centres
        ax.set_title(f"{np.degrees(motion.angle(ti)):.0f} degrees, alpha = {ti:.2f}", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlim(-0.045, 0.11)
        ax.set_xlabel("y (m): front ->")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("-z (m): shoulder at the top")
    fig.tight_layout()
    fig.savefig(OUT / "side_view.png", dpi=90)
    print("wrote", OUT / "side_view.png")

# %% [markdown]
# ## Picture: four frames of the motion
#
# The deformed muscle coloured by the von Mises stress (kPa; the bent insertion tendon is far above
# the colour range), the bones in grey, in the same view as above (arm hanging down, front to the
# right). Rendering runs in a separate process (pyvista must not share a process with dolfinx).


# %%
def capsule_tets(a, b, r, n_theta=24, n_cap=6):
    """A tetrahedral capsule (points, tets) for the picture: rings along the axis, each wedge between two rings
    and the axis split into three tetrahedra (degenerate at the poles, harmless for drawing)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    e = (b - a) / np.linalg.norm(b - a)
    p = np.cross(e, [1.0, 0.0, 0.0] if abs(e[0]) < 0.9 else [0.0, 1.0, 0.0])
    p /= np.linalg.norm(p)
    q = np.cross(e, p)
    phi = np.linspace(-np.pi / 2, 0.0, n_cap + 1)
    rings = [(a, r * np.sin(f), r * np.cos(f)) for f in phi] + [(b, r * np.sin(f), r * np.cos(f)) for f in -phi[::-1]]
    theta = np.linspace(0.0, 2 * np.pi, n_theta, endpoint=False)
    points, tets = [], []
    for i, (centre, s, rho) in enumerate(rings):
        axis_point = centre + s * e
        points.append(axis_point)
        points.extend(axis_point + rho * (np.cos(th) * p + np.sin(th) * q) for th in theta)
        if i:
            A0, A1 = (i - 1) * (n_theta + 1), i * (n_theta + 1)
            for j in range(n_theta):
                v = [A0, A0 + 1 + j, A0 + 1 + (j + 1) % n_theta, A1, A1 + 1 + j, A1 + 1 + (j + 1) % n_theta]
                tets += [[v[0], v[1], v[2], v[5]], [v[0], v[1], v[5], v[4]], [v[0], v[4], v[5], v[3]]]
    return np.array(points), np.array(tets)


ROTATE = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # (x, y, z) -> (y, x, -z): front right, z down
SPACING = 0.17
panels = []
for n, k in enumerate(frames):
    ti = 0.0 if k is None else t[k]
    data = last if k is None else meshio.read(OUT / f"step_{k + 1:04d}.vtu")
    u = np.zeros_like(data.points) if k is None else data.point_data["u"]
    von_mises = np.zeros(len(tets)) if k is None else data.cell_data["von_mises"][0][:, 0] / 1e3
    points, cells, values, shift = [data.points], [tets], [von_mises], len(data.points)
    for shape in shapes_at(ti):
        bp, bt = capsule_tets(*shape)
        points.append(bp)
        cells.append(bt + shift)
        values.append(np.full(len(bt), np.nan))  # no value: drawn in the NaN colour (grey)
        shift += len(bp)
    displacement = np.vstack([u, np.zeros((shift - len(data.points), 3))])
    path = OUT / f"frame_{n}.vtu"
    meshio.write(path, meshio.Mesh(np.vstack(points) @ ROTATE.T, [("tetra", np.vstack(cells))],
                                   point_data={"u": displacement @ ROTATE.T},
                                   cell_data={"von_mises_kPa": [np.concatenate(values)]}))
    panels.append({"vtu": str(path), "offset": [SPACING * n, 0.0, 0.0],
                   "label": f"{np.degrees(motion.angle(ti)):.0f} deg"})
png = render({"png": str(OUT / "arm_flexion.png"), "window": [1600, 640], "view": "xz", "zoom": 1.9,
              "scalars": "von_mises_kPa", "clim": [0.0, 150.0], "cmap": "viridis", "edges": False,
              "bar": "von Mises stress (kPa)", "bar_position": [0.3, 0.04, 0.4], "panels": panels, "label_size": 18,
              "texts": [["elbow flexion, activation = angle / 90 deg", 0.02, 0.93]]})
print("wrote", png)

# %%
if WRITE_DOCS:
    small_png(png, ROOT / "docs" / "arm_flexion.png")
    print("wrote docs/arm_flexion.png", (ROOT / "docs" / "arm_flexion.png").stat().st_size // 1024, "kB")
