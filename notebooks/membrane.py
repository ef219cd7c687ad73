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
# # Membranes: a balloon, Hencky's disc, the inflation of a patch, contact with bones
#
# Turchet's thesis (Bournemouth University, 2018, sec. 3.3.3.1) builds muscles by inflating
# triangle patches: a 3x2 surface deformation gradient $F$ per triangle, the plane-stress St Venant-Kirchhoff
# membrane $w = h(\mu\, E{:}E + \tfrac{\lambda'}{2}(\operatorname{tr}E)^2)$ with $E = (F^TF - I)/2$ and
# $\lambda' = E\nu/(1-\nu^2)$, and a pressure on the deformed surface. `forms/membrane.py` writes it in UFL
# (with the incompressible neo-Hookean membrane $w = \tfrac{\mu h}{2}(\operatorname{tr}C + 1/\det C - 3)$
# next to it) and the pressure through the enclosed-volume potential $-pV(x)$, $V = \tfrac13\int x\cdot n\,da$,
# so the Newton matrix is symmetric. This notebook checks the membrane against two closed forms:
#
# * a thin spherical balloon: $p(\lambda) = w'(\lambda) / (R\lambda^2)$ for the equibiaxial stretch
#   $\lambda = r/R$ (from $p\,4\pi r^2 dr = d(4\pi R^2 w)$);
# * Hencky's clamped circular membrane: $w_0 = c(\nu)\, a\,(pa/Eh)^{1/3}$ with $c(0.3) = 0.6534$,
#
# then runs the thesis' inflation workflow, a balloon against a rigid cavity (closed form with the penalty) and
# the thesis' two inflation phases against a bone. Run with plain Python; with `CI` set it uses fewer meshes.

# %%
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
from _setup import start  # noqa: E402

CI, OUT, plt = start("membrane")

from mpi4py import MPI  # noqa: E402

from forms.membrane import MembraneNeoHookean, MembraneStVK  # noqa: E402
from meshes.membrane import disc_surface, sphere_octant  # noqa: E402
from model.domain.distribute import build_domain  # noqa: E402
from model.experiments.membrane import inflate_patch  # noqa: E402
from model.problem import membrane as pm  # noqa: E402
from model.solvers.membrane import inflate  # noqa: E402

COMM = MPI.COMM_WORLD
LAWS = {"StVK (E = 1, nu = 0.3)": MembraneStVK(1.0, 0.3, 0.01), "neo-Hookean (mu = 1)": MembraneNeoHookean(1.0, 0.01)}

# %% [markdown]
# ## The balloon
#
# The octant $x, y, z \ge 0$ of the unit sphere with symmetry conditions on its three edges (the volume
# potential stays exact: $x \cdot n = 0$ on the symmetry planes). The pressure is raised step by step and the
# stretch is read from the volume, $\lambda = (V/V_0)^{1/3}$. The neo-Hookean balloon has a pressure maximum
# at $\lambda = 7^{1/6} = 1.383$: under pressure control the run stops before it (StVK has none).

# %%
sizes = (0.2, 0.1) if CI else (0.2, 0.1, 0.05)
curves = {}
for name, law in LAWS.items():
    top = 1.35 if isinstance(law, MembraneNeoHookean) else 1.6
    for size in sizes:
        domain = build_domain(COMM, sphere_octant(1.0, size) if COMM.rank == 0 else None)
        problem = pm.MembraneProblem(domain, law, pm.radial_orientation(), {"x0": (0,), "y0": (1,), "z0": (2,)})
        V0 = problem.volume()
        steps = inflate(problem, pm.balloon_pressure(law, 1.0, np.linspace(1.02, top, 12)))
        lam = np.array([(s.volume / V0) ** (1 / 3) for s in steps])
        p = np.array([s.pressure for s in steps])
        error = p / pm.balloon_pressure(law, 1.0, lam) - 1
        curves[name, size] = (lam, p, error)
        print(f"{name}, size {size}: lambda up to {lam[-1]:.3f}, max |p / p(lambda) - 1| = {np.abs(error).max():.2e}")
    assert np.abs(curves[name, sizes[-1]][2]).max() < 0.01
    assert np.abs(curves[name, sizes[-1]][2]).max() < np.abs(curves[name, sizes[0]][2]).max()

# %%
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for k, (name, law) in enumerate(LAWS.items()):
        grid = np.linspace(1.0, 1.6 if k == 0 else 1.8, 200)
        ax1.plot(grid, pm.balloon_pressure(law, 1.0, grid) * 1e3, color=f"C{k}", label=f"{name}: closed form")
        lam, p, _ = curves[name, sizes[-1]]
        ax1.plot(lam, p * 1e3, "o", color=f"C{k}", ms=4, label=f"FE, size {sizes[-1]}")
        for size in sizes:
            lam, _, error = curves[name, size]
            ax2.plot(lam, np.abs(error) * 100, "o-", ms=3, color=f"C{k}", alpha=0.4 + 0.6 * size / max(sizes),
                     label=f"{name}, size {size}")
    ax1.axvline(7 ** (1 / 6), color="0.6", ls=":", lw=1)
    ax1.set_xlabel("stretch lambda = r / R")
    ax1.set_ylabel("pressure p  (x 1e3; R = 1, h = 0.01)")
    ax1.legend(fontsize=7)
    ax2.set_xlabel("stretch lambda")
    ax2.set_ylabel("|p / p_closed_form - 1|  (%)")
    ax2.set_yscale("log")
    ax2.legend(fontsize=7)
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "membrane_balloon.png", dpi=90)

# %% [markdown]
# ## Hencky's clamped disc
#
# A unit disc clamped on its rim, StVK with $E = 1$, $\nu = 0.3$, $h = 0.01$, under $pa/Eh = 10^{-4}$
# (small rotations: Hencky's membrane theory applies). `model.problem.membrane.hencky` integrates the
# axisymmetric Föppl-Hencky equations by shooting; it reproduces Hencky's $b_0 = 1.724$ and gives the centre
# coefficient $0.6534$ (the value $0.662$ often quoted comes from Hencky's original higher coefficients,
# corrected later). A flat membrane has no transverse stiffness, so Newton starts from a paraboloid.

# %%
ref = pm.hencky(0.3)
stvk = LAWS["StVK (E = 1, nu = 0.3)"]
domain = build_domain(COMM, disc_surface(1.0, 0.1 if CI else 0.05) if COMM.rank == 0 else None)
problem = pm.MembraneProblem(domain, stvk, pm.axis_orientation(), {"rim": (0, 1, 2)})
pressure = 1e-6
w0 = ref.centre_deflection(1.0, pressure, stvk.young, stvk.thickness)
problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], w0 * (1 - x[0] ** 2 - x[1] ** 2)]))
inflate(problem, [pressure])
w_fe = problem.max_component(2)
print(f"b0 = {ref.b0:.4f}, c(0.3) = {ref.coefficient:.4f}; centre deflection {w_fe:.5e} vs Hencky {w0:.5e} "
      f"({w_fe / w0 - 1:+.2e})")
assert abs(w_fe / w0 - 1) < 0.02

# %%
if plt is not None:
    n = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:n]
    w = problem.u.x.array[: 3 * n].reshape(-1, 3)[:, 2]
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(np.hypot(X[:, 0], X[:, 1]), w / w0 * ref.coefficient, ".", ms=3, color="C0", label="FE nodes")
    ax.plot(ref.rho, ref.omega, "-", color="C3", label="Hencky (shooting)")
    ax.set_xlabel("r / a")
    ax.set_ylabel("w / (a (p a / E h)^(1/3))")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "membrane_hencky.png", dpi=90)

# %% [markdown]
# ## The inflation workflow
#
# The thesis inflates an extruded patch with its tendon vertices fixed until a target volume. Here a clamped
# disc (neo-Hookean) is inflated until the volume between it and its plane is 0.5 (the last pressure found by
# the secant method), closed with its flat rest shape, filled with tetrahedra by gmsh (the surface mesh kept)
# and given a Laplace fibre field from one end of the base to the other: a muscle mesh ready for a run.

# %%
result = inflate_patch(MembraneNeoHookean(1.0, 0.01), target_volume=0.5, size=0.15 if CI else 0.1)
last = result.steps[-1]
cells = COMM.allreduce(result.domain.mesh.topology.index_map(3).size_local, op=MPI.SUM)
print(f"V = {last.volume:.6f} at p = {last.pressure:.4e} after {len(result.steps)} steps; {cells} tetrahedra")
assert abs(last.volume - 0.5) < 1e-6

# %%
if plt is not None and COMM.size == 1:
    msh = result.domain.mesh
    x = msh.geometry.x
    tets = result.mesh_data.cells
    centroids = result.mesh_data.points[tets].mean(axis=1)
    a0 = result.fibres.function.x.array.reshape(-1, 3)
    original = np.asarray(msh.topology.original_cell_index)
    a0_input = np.empty_like(a0)
    a0_input[original] = a0
    near = np.abs(centroids[:, 1]) < 0.08
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.quiver(centroids[near, 0], centroids[near, 2], a0_input[near, 0], a0_input[near, 2], color="C2",
              scale=30, width=0.003)
    ax.set_title("inflated patch, section y ~ 0: Laplace fibre directions", fontsize=10)
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(OUT / "membrane_inflation.png", dpi=90)

# %% [markdown]
# ### From a config: the patch, the muscle and its contraction
#
# The same workflow from a TOML file (`examples/membrane_muscle.toml`, `[muscle]`;
# `python -m model run examples/membrane_muscle.toml --out DIR`): after the inflation the output folder holds
# `muscle.msh` (physical groups `muscle`; `patch`, `base`, `origin`, `insertion`), `fibres.npy` (a0 per
# tetrahedron), `muscle.vtu` and `muscle.toml`, an isometric contraction of that muscle which the solid model
# runs as it is. Left: the inflated patch; right: the tetrahedral muscle cut at y = 0, coloured by the fibres'
# x-component, with the fibres as arrows (they leave the origin end of the base along +z, run along x through
# the belly and enter the insertion end along -z).

# %%
from model import pipeline  # noqa: E402
from model.config.document import load  # noqa: E402
from model.config.membrane import load_membrane  # noqa: E402
from model.experiments.membrane_run import run_membrane  # noqa: E402

patch = OUT / "patch"
run = run_membrane(load_membrane(ROOT / "examples" / "membrane_muscle.toml"), patch, COMM)
made = run["muscle"]
print(f"inflated to V = {run['steps'][-1]['volume']:.9f} at p = {run['steps'][-1]['pressure']:.4e}; "
      f"{made['tetrahedra']} tetrahedra of volume {made['volume']:.9f} (membrane {made['enclosed_volume']:.9f})")
assert abs(made["volume"] / made["enclosed_volume"] - 1) < 1e-12
contraction = pipeline.run(load(patch / "muscle.toml"), patch / "contraction", COMM)
reactions = contraction["steps"][-1]["reactions"]
print(f"isometric contraction: {contraction['status']}, {len(contraction['steps'])} steps; reactions origin "
      f"{np.round(reactions['origin'], 1)}, insertion {np.round(reactions['insertion'], 1)}")
assert contraction["status"] == "completed" and reactions["origin"][0] < 0 < reactions["insertion"][0]

# %%
if COMM.rank == 0:
    import meshio
    from _pictures import render

    muscle = meshio.read(patch / "muscle.vtu")
    centres = muscle.points[muscle.cells_dict["tetra"]].mean(axis=1)
    back = np.flatnonzero(centres[:, 1] > 0.0)  # the half y > 0: the section y = 0 shows the inside
    near = np.flatnonzero((centres[:, 1] > 0.0) & (centres[:, 1] < 0.35))  # arrows of the cells near the cut
    png = render({"png": str(OUT / "membrane_muscle.png"), "window": [1400, 560], "view": "xz", "elevation": 25,
                  "zoom": 1.8, "scalars": "fibre_direction", "clim": [-1.0, 1.0], "cmap": "coolwarm",
                  "bar": "fibre direction a0 . e_x", "bar_position": [0.55, 0.05, 0.35],
                  "texts": [["inflated patch (surface_0001.vtu)", 0.15, 0.82],
                            ["muscle.vtu: tetrahedra (y > 0), Laplace fibres", 0.55, 0.82]],
                  "panels": [{"vtu": str(patch / "surface_0001.vtu"), "color": "#d8b365"},
                             {"vtu": str(patch / "muscle.vtu"), "deformed": False, "offset": [2.3, 0.0, 0.0],
                              "cells": back.tolist(), "opacity": 0.35, "arrows": "fibre_direction",
                              "arrow_cells": near.tolist(), "arrow_scale": 0.18}]})
    print("wrote", png)

# %% [markdown]
# ## Contact: the balloon in a rigid cavity
#
# The unit balloon (StVK octant) inside a rigid concentric sphere of radius $R_c = 1.1$
# (`model.problem.membrane_contact.ObstacleContact`, penalty $\Pi_c = \int \tfrac{k}{2}\min(g, 0)^2\,dA$ with
# the nodal rule, $g = R_c - |x|$). Before contact it follows $p(\lambda)$; it touches everywhere at
# $p_m(R_c/R)$, where the contact fraction jumps from 0 to 1; beyond, the radius stays at $R_c + \delta$ with
# $\delta = \lambda^2 (p - p_m(\lambda))/k$ (the energy balance with the penalty term).

# %%
from forms.obstacles import Capsule, Sphere  # noqa: E402
from model.experiments.membrane import inflate_extruded_patch  # noqa: E402
from model.problem.membrane_contact import ObstacleContact  # noqa: E402

stvk, R_c, k = LAWS["StVK (E = 1, nu = 0.3)"], 1.1, 1.0
domain = build_domain(COMM, sphere_octant(1.0, 0.2 if CI else 0.1) if COMM.rank == 0 else None)
problem = pm.MembraneProblem(domain, stvk, pm.radial_orientation(), {"x0": (0,), "y0": (1,), "z0": (2,)})
cavity = ObstacleContact(problem, Sphere((0.0, 0.0, 0.0), R_c), k, inside=True)
p_touch = float(pm.balloon_pressure(stvk, 1.0, R_c))
pressures = p_touch * np.sort(np.r_[np.linspace(0.3, 3.0, 10 if CI else 19), 0.98, 1.01, 1.04])


def closed_radius(p: float) -> float:
    """The free balloon's r(p) (StVK: p(lambda) increases), or R_c + delta with delta = lambda^2 (p - p_m) / k."""
    grid = np.linspace(1.0, 1.6, 4001)
    lam = float(np.interp(p, pm.balloon_pressure(stvk, 1.0, grid), grid))
    if lam > R_c:
        lam = R_c
        for _ in range(60):
            lam = R_c + lam**2 * (p - float(pm.balloon_pressure(stvk, 1.0, lam))) / k
    return lam


radius, fraction, closed = [], [], []
for p in pressures:
    inflate(problem, [p])
    x = cavity.positions()
    area = cavity.lumped_area
    radius.append(COMM.allreduce(float(np.linalg.norm(x, axis=1) @ area), op=MPI.SUM)
                  / COMM.allreduce(float(area.sum()), op=MPI.SUM))
    fraction.append(cavity.contact_fraction())
    lam = closed_radius(p)
    closed.append(lam)
    print(f"p / p_touch = {p / p_touch:.2f}: mean radius {radius[-1]:.5f} (closed form {lam:.5f}), "
          f"contact fraction {fraction[-1]:.2f}")
assert max(abs(r / c - 1) for r, c in zip(radius, closed)) < 0.01

# %%
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    dense = np.linspace(pressures[0], pressures[-1], 300)
    ax1.plot(dense / p_touch, [closed_radius(p) for p in dense], "-", color="C3", label="closed form")
    ax1.plot(pressures / p_touch, radius, "o", ms=4, color="C0", label="FE (area-weighted node radius)")
    ax1.axhline(R_c, color="0.6", ls=":", lw=1)
    ax1.set_xlabel("p / p_m(R_c / R)")
    ax1.set_ylabel("radius r")
    ax1.legend(fontsize=8)
    ax2.step(pressures / p_touch, fraction, where="post", color="C2")
    ax2.set_xlabel("p / p_m(R_c / R)")
    ax2.set_ylabel("contact fraction")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "membrane_cavity.png", dpi=90)

# %% [markdown]
# ## The thesis' two phases against a bone
#
# The patch is extruded by a small offset (every free vertex moved along its normal), inflated without contact
# to a first volume, a new rest shape is made by alternated Laplacian smoothing and tangential relaxation of
# the inflated vertices down to a volume estimate, and that rest shape is inflated against a capsule bone
# until 5 % of its area touches it (the contact-fraction stop), then closed and tetrahedralised.

# %%
bone = Capsule((-2.0, 0.0, 0.75), (2.0, 0.0, 0.75), 0.3)
two = inflate_extruded_patch(MembraneNeoHookean(1.0, 0.01), offset=0.03, first_volume=0.8, rest_volume=0.4,
                             target_volume=2.0, obstacles=[(bone, 10.0, False)], contact_fraction=0.05)
report = two.contacts[0].report()
print(f"phase 1: V = {two.first_steps[-1].volume:.4f} at p = {two.first_steps[-1].pressure:.4e}; "
      f"phase 2: V = {two.steps[-1].volume:.4f}, contact fraction {report['contact_fraction']:.3f} at "
      f"p = {two.steps[-1].pressure:.4e}, max penetration {report['max_penetration']:.2e}, "
      f"force {np.round(report['force'], 5)}")
assert report["contact_fraction"] >= 0.05, report

# %%
if plt is not None and COMM.size == 1:
    from model.experiments.membrane import deformed_points

    final = deformed_points(two.problem, len(two.extruded))
    fig, ax = plt.subplots(figsize=(7, 3.4))
    for points, label, style in ((two.extruded, "extruded patch", "C7."),
                                 (two.smoothing.points, "smoothed rest shape", "C1."),
                                 (final, "inflated against the bone", "C0.")):
        near = np.abs(points[:, 1]) < 0.1
        order = np.argsort(points[near, 0])
        ax.plot(points[near, 0][order], points[near, 2][order], style + "-", ms=3, lw=0.8, label=label)
    t = np.linspace(0, 2 * np.pi, 200)
    ax.plot(0.3 * np.cos(t), 0.75 + 0.3 * np.sin(t), "k-", lw=1, label="capsule bone (section)")
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.legend(fontsize=7, loc="lower center")
    ax.set_title("nodes with |y| < 0.1, joined by x", fontsize=10)
    fig.tight_layout()
    fig.savefig(OUT / "membrane_bone.png", dpi=90)
