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
# # Force-length: muscle tissue and a whole muscle
#
# The force a fully activated muscle fibre can deliver depends on its length. The muscle law of
# this project (`forms/muscle.py`, `energies.md`; Teran et al. 2003, Blemker et al. 2005) writes
# the strain-energy density per unit reference volume as
#
# $$\psi = F_1 + K (\ln J)^2 + F_2(\bar\lambda, \alpha),\qquad
#   \bar\lambda = \sqrt{a_0 \cdot \bar C a_0},\quad \bar C = J^{-2/3} F^T F,$$
#
# $F_1$ the isotropic matrix, $a_0$ the fibre direction, $\bar\lambda$ the *isochoric* fibre
# stretch and $\alpha \in [0, 1]$ the activation, with the fibre term given by its derivative
#
# $$\frac{\partial F_2}{\partial \bar\lambda} = \frac{\sigma_{max}}{l_{ofl}}
#   \big(f_{passive}(s) + \alpha\, f_{active}(s)\big),\qquad s = \bar\lambda / l_{ofl},$$
#
# $f_{active}(s) = 9 (s - 0.4)^2$ on (0.4, 0.6], $1 - 4 (1 - s)^2$ on (0.6, 1.4),
# $9 (s - 1.6)^2$ on [1.4, 1.6), 0 elsewhere; $f_{passive}(s) = 0$ for $s \le 1$,
# $P_1 (e^{P_2 (s - 1)} - 1)$ up to $s^* = l^*/l_{ofl}$, then the $C^1$ straight line
# ($\sigma_{max}$ = 300 kPa, $P_1$ = 0.05, $P_2$ = 6.6, $l_{ofl}$ = 1, $l^*$ = 1.4).
#
# Both experiments hold the body at a length, then activate it at that length
# (`model.experiments.muscle`): the load factor $t$ goes 0 → 0.5 stretching the body passively
# to $l$ times its length, 0.5 → 1 ramping $\alpha$ from 0 to 1. The stretch $l$ is the
# configuration's `parameters.stretch` (the end displacement is the expression
# `(stretch - 1)*length*minimum(2*t, 1)`), so each curve is one parameter sweep
# (`model.studies.sweep`, the same as `python -m model sweep CONFIG --set parameters.stretch=...`):
# one run per stretch in its own folder, and one table with a row per run and converged step. The
# *active force* is the end reaction at $t = 1$ minus the one at $t = 0.5$, the *passive force* the
# reaction at $t = 0.5$.
#
# **(a) Tissue:** a uniform cylinder of muscle (`examples/force_length_cylinder.toml`, radius
# 5 mm, length 4 cm, fibres along the axis, Mooney-Rivlin matrix $c_1$ = 500 Pa, $K$ = 1e8 Pa,
# ends on sliders). Its deformation is homogeneous, so the active force divided by the reference
# cross-section should be $(\sigma_{max}/l_{ofl}) f_{active}(l)$.
#
# **(b) Whole muscle:** the fusiform muscle of `notebooks/isometric.py` (belly plus tendons, the
# thesis' StVK matrix $E$ = 9 MPa, $\nu$ = 0.45, `examples/force_length_fusiform.toml`) held by its
# tendon ends at $l$ times its rest length of 14 cm.
#
# Run with plain Python (`python notebooks/force_length.py`); with `CI` set it sweeps fewer
# stretches (5 for the cylinder, 2 for the fusiform muscle).

# %%
import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd().resolve().parent
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks")]
CI = bool(os.environ.get("CI"))
OUT = Path(os.environ.get("NOTEBOOK_OUT", ROOT / "results" / "notebooks")) / "force_length"
WRITE_DOCS = os.environ.get("WRITE_DOCS") == "1"
try:
    import matplotlib

    if "ipykernel" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # plots are optional
    plt = None

import json  # noqa: E402

import meshio  # noqa: E402
import pandas as pd  # noqa: E402
from _pictures import deformation_gradients, render  # noqa: E402

import model.config  # noqa: E402
from model.experiments.muscle import active_stress, f_active  # noqa: E402
from model.studies import sweep  # noqa: E402

OUT.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## (a) The tissue curve: a uniform cylinder
#
# One run per stretch, two at a time (`jobs=2`); each takes about a second plus the start of its
# process. Sweeping again into the same folder skips the runs already completed. From the table:
# the passive force is the top reaction at $t$ = 0.5, the active force the one at $t$ = 1 minus it.

# %%
EXAMPLES = ROOT / "examples"
cylinder_file = EXAMPLES / "force_length_cylinder.toml"
law = model.load_config(cylinder_file).materials[0].law
FULL_SWEEP = [0.45, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.45, 1.5, 1.55]
stretches = [0.5, 0.8, 1.0, 1.2, 1.55] if CI else FULL_SWEEP
cylinder_table = sweep(cylinder_file, {"parameters.stretch": stretches, "output.vtu": [True]}, jobs=2,
                       out=OUT / "cylinder")


def force_length_table(table: pd.DataFrame, boundary: str, folder: Path) -> pd.DataFrame:
    """Per stretch: passive (t = 0.5) and active (t = 1 minus t = 0.5) reaction z on ``boundary``, the run's
    folder, its last step's number and its wall time, from a sweep's table."""
    done = table[table["status"] == "completed"]
    failed = sorted(set(table["parameters.stretch"]) - set(done["parameters.stretch"]))
    assert not failed, f"runs failed at stretches {failed}"
    column = f"reaction.{boundary}.z"
    held = done[np.isclose(done["load_factor"], 0.5)].set_index("parameters.stretch")
    full = done[np.isclose(done["load_factor"], 1.0)].set_index("parameters.stretch")
    return pd.DataFrame({"passive": held[column], "active": full[column] - held[column],
                         "folder": [folder / "runs" / r for r in full["run"]], "last_step": full["step"],
                         "wall": full["wall_time_s"]})


cylinder_forces = force_length_table(cylinder_table, "top", OUT / "cylinder")
cylinder = {}
for stretch, row in cylinder_forces.iterrows():
    summary = json.loads((row["folder"] / "summary.json").read_text())
    area = summary["boundary_areas"]["top"]  # reference cross-section
    J_fe = meshio.read(row["folder"] / f"step_{row['last_step']:04d}.vtu").cell_data["J"][0].mean()
    cylinder[stretch] = {"passive": row["passive"] / area, "active": row["active"] / area, "J": J_fe,
                         "wall": row["wall"]}
print(f"{len(stretches)} cylinder runs ({cylinder_table.attrs['ran']} run now, {cylinder_table.attrs['skipped']} "
      f"from an earlier sweep), {summary['cells']} cells each, {sum(c['wall'] for c in cylinder.values()):.1f} s "
      "of solving in all")
print(cylinder_table[["parameters.stretch", "step", "load_factor", "reaction.top.z", "newton_iterations"]]
      .head(6).to_string(index=False))

# %% [markdown]
# The printed comparison: the active force per reference cross-section against
# $(\sigma_{max}/l_{ofl}) f_{active}(l)$, and its relative error.

# %%
print(f"{'l':>5s} {'passive (kPa)':>14s} {'active (kPa)':>13s} {'sigma_max f_active(l) (kPa)':>28s} "
      f"{'rel. error':>11s} {'J at t = 1':>11s}")
for stretch, c in cylinder.items():
    expected = active_stress(stretch, law)
    c["error"] = (c["active"] - expected) / expected
    print(f"{stretch:5.2f} {c['passive'] / 1e3:14.3f} {c['active'] / 1e3:13.3f} {expected / 1e3:28.3f} "
          f"{100 * c['error']:10.3f}% {c['J']:11.6f}")
    assert abs(c["error"]) < 0.02, stretch

# %% [markdown]
# The cylinder recovers the tissue curve within 2 %. The error is a few 1e-4 over most of the
# range and grows towards $l$ = 1.55. The reason is the finite bulk modulus: the law sees the
# *isochoric* stretch $\bar\lambda = J^{-1/3} l$, not $l$, and $J$ is not exactly 1. The fibre
# stress (active, and passive beyond $l$ = 1) pulls on the material, which expands a little
# ($J - 1$ = 5e-4 at $l$ = 1, 1.06e-3 at $l$ = 1.55, printed above), so $\bar\lambda$ is slightly
# shorter than $l$. The relative force error is about $(f'_{active}/f_{active})(\bar\lambda - l)$:
# negligible where $f_{active}$ is flat or large, but near $l$ = 1.55, where $f_{active}$ is small
# (0.0225) and steep ($f'_{active} = -0.9$), a shift of $\bar\lambda$ by $-5\cdot 10^{-4}$ changes
# the force by 2 %.
#
# **Check: the homogeneous state in closed form.** For $F = \mathrm{diag}(r, r, l)$ every term of
# $\psi$ depends only on $J = r^2 l$ and $\bar\lambda$ ($\bar I_1 = \bar\lambda^2 + 2/\bar\lambda$):
# $\psi = W(\bar\lambda) + K (\ln J)^2$, $W = c_1 (\bar\lambda^2 + 2/\bar\lambda - 3) + F_2$.
# Free lateral faces ($\partial\psi/\partial r = 0$) give $\ln J = W'(\bar\lambda)\,\bar\lambda / (6K)$,
# and the axial nominal stress is $P = \partial\psi/\partial l = W'(\bar\lambda)\, \bar\lambda / l$.
# Solving $\bar\lambda = l\, e^{-W'(\bar\lambda) \bar\lambda / (18 K)}$ by fixed-point iteration
# gives the exact force of the law, bulk modulus included; the finite elements reproduce it.

# %%
def f_passive(s: float) -> float:
    """The passive fibre curve of energies.md (s = lbar / l_ofl)."""
    star = law.l_star / law.l_ofl
    if s <= 1.0:
        return 0.0
    if s < star:
        return law.P1 * (math.exp(law.P2 * (s - 1.0)) - 1.0)
    P3 = law.P1 * law.P2 * math.exp(law.P2 * (star - 1.0))
    P4 = law.P1 * (math.exp(law.P2 * (star - 1.0)) - 1.0) - P3 * star
    return P3 * s + P4


def homogeneous(stretch: float, alpha: float) -> tuple[float, float, float]:
    """(nominal axial stress P, lbar, J) of the cylinder held at ``stretch`` with free lateral faces."""
    def dW(lbar: float) -> float:
        s = lbar / law.l_ofl
        fibres = law.sigma_max / law.l_ofl * (f_passive(s) + alpha * f_active(s))
        return 2.0 * law.c1 * (lbar - lbar**-2) + fibres

    lbar = stretch
    for _ in range(100):
        lbar = stretch * math.exp(-dW(lbar) * lbar / (18.0 * law.K))
    return dW(lbar) * lbar / stretch, lbar, math.exp(dW(lbar) * lbar / (6.0 * law.K))


print(f"{'l':>5s} {'lbar at t = 1':>14s} {'J closed form':>14s} {'J FE':>11s} {'active closed form (kPa)':>25s} "
      f"{'FE / closed form - 1':>21s} {'passive: FE / closed form - 1':>30s}")
for stretch, c in cylinder.items():
    P1, lbar1, J1 = homogeneous(stretch, 1.0)
    P0, _, _ = homogeneous(stretch, 0.0)
    c["closed_form"] = P1 - P0
    c["passive_closed_form"] = P0
    passive_error = c["passive"] / P0 - 1.0 if abs(P0) > 1.0 else c["passive"] - P0
    print(f"{stretch:5.2f} {lbar1:14.6f} {J1:14.6f} {c['J']:11.6f} {(P1 - P0) / 1e3:25.3f} "
          f"{c['active'] / (P1 - P0) - 1.0:21.2e} {passive_error:30.2e}")
    assert abs(c["active"] / (P1 - P0) - 1.0) < 1e-3, stretch

# %% [markdown]
# The finite-element forces agree with the closed form to about 1e-6 or better (the homogeneous
# state is exactly representable by linear elements, the remainder is the solver tolerance; at
# $l$ = 1, where the passive force is 0, the passive column gives the absolute difference in Pa). So the
# whole 2 % near $l$ = 1.55 is the law itself, $\bar\lambda = J^{-1/3} l$ with a finite $K$:
# a stiffer $K$ would bring the cylinder closer to $f_{active}(l)$.

# %%
l_fine = np.linspace(0.35, 1.65, 261)
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    ax1.plot(l_fine, [active_stress(s, law) / 1e3 for s in l_fine], color="C0",
             label="(sigma_max / l_ofl) f_active(l)")
    ax1.plot(stretches, [cylinder[s]["active"] / 1e3 for s in stretches], "o", color="C0", label="active, FE")
    ax1.plot(l_fine, [homogeneous(s, 0.0)[0] / 1e3 for s in l_fine], color="C1", label="passive, closed form")
    ax1.plot(stretches, [cylinder[s]["passive"] / 1e3 for s in stretches], "s", color="C1", label="passive, FE")
    ax1.set_xlabel("stretch l")
    ax1.set_ylabel("force / reference cross-section (kPa)")
    ax1.set_ylim(-20, 520)
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.plot(stretches, [100 * cylinder[s]["error"] for s in stretches], "o-")
    ax2.axhline(0.0, color="grey", lw=0.8)
    ax2.set_xlabel("stretch l")
    ax2.set_ylabel("active: FE / (sigma_max f_active(l)) - 1 (%)")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "tissue_force_length.png", dpi=90)

# %% [markdown]
# ## (b) A whole fusiform muscle
#
# The insertion disk moves by $(l - 1) \times 0.14$ m, the origin disk is clamped. Two probes of
# the example on the axis, at the two tendon-belly junctions, tell how the stretch is shared between
# the tendons and the belly (their columns of the sweep's table). The whole-muscle active force is normalised by
# $\sigma_{max}$ times the belly's largest cross-section $\pi\, (15\,\mathrm{mm})^2$, the force the
# muscle would deliver if every fibre of its thickest section pulled with $\sigma_{max}$.
# Each run takes about half a minute.

# %%
fusiform_file = EXAMPLES / "force_length_fusiform.toml"
sigma_max = model.load_config(fusiform_file).materials[0].law.sigma_max
LENGTH, TENDON, BELLY = 0.14, 0.02, 0.10
belly_area = math.pi * 0.015**2
muscle_stretches = [1.0, 1.1] if CI else [0.9, 0.95, 1.0, 1.05, 1.1, 1.15]


def fibre_stretches(data: meshio.Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cell: the isochoric fibre stretch J^(-1/3) |F a0|, the reference volume and the centroid's z."""
    tets = data.cells_dict["tetra"]
    X = data.points[tets]
    F = deformation_gradients(data.points, tets, data.point_data["u"])
    Fa = np.einsum("nij,nj->ni", F, data.cell_data["fibre_direction"][0])
    lam = np.linalg.det(F) ** (-1.0 / 3.0) * np.linalg.norm(Fa, axis=1)
    return lam, np.abs(np.linalg.det(X[:, 1:] - X[:, :1])) / 6.0, X.mean(axis=1)[:, 2]


def fibre_stretch_profile(vtu: Path, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slice centres, per-slice volume-averaged fibre stretch, and the belly's (min, max) fibre stretch."""
    lam, volume, z = fibre_stretches(meshio.read(vtu))
    inside = [(z >= lo) & (z < hi) for lo, hi in zip(edges[:-1], edges[1:])]
    mean = np.array([np.average(lam[m], weights=volume[m]) for m in inside])
    belly = (z > TENDON) & (z < LENGTH - TENDON)
    return 0.5 * (edges[:-1] + edges[1:]), mean, np.array([lam[belly].min(), lam[belly].max()])


edges = np.linspace(0.0, LENGTH, 15)
fusiform_table = sweep(fusiform_file, {"parameters.stretch": muscle_stretches, "output.vtu": [True]}, jobs=2,
                       out=OUT / "fusiform")
fusiform_forces = force_length_table(fusiform_table, "insertion", OUT / "fusiform")
whole = {}
for stretch, forces_row in fusiform_forces.iterrows():
    steps = fusiform_table[(fusiform_table["parameters.stretch"] == stretch)
                           & (fusiform_table["status"] == "completed")]
    row = {"passive": forces_row["passive"], "active": forces_row["active"],
           "normalised": forces_row["active"] / (sigma_max * belly_area), "wall": forces_row["wall"]}
    for label, t in (("held", 0.5), ("active", 1.0)):
        step = steps[np.isclose(steps["load_factor"], t)].iloc[0]
        origin_j, insertion_j = step["probe.origin_junction.z"], step["probe.insertion_junction.z"]
        row[f"belly_{label}"] = 1.0 + (insertion_j - origin_j) / BELLY
        row[f"tendons_{label}"] = 1.0 + (origin_j + (stretch - 1.0) * LENGTH - insertion_j) / (2 * TENDON)
        row[f"vtu_{label}"] = forces_row["folder"] / f"step_{int(step['step']):04d}.vtu"
        row[f"z_{label}"], row[f"profile_{label}"], row[f"range_{label}"] = fibre_stretch_profile(
            row[f"vtu_{label}"], edges)
    whole[stretch] = row
summary = json.loads((fusiform_forces["folder"].iloc[0] / "summary.json").read_text())
print(f"{len(muscle_stretches)} fusiform runs, {summary['cells']} cells, {summary['dofs']} dofs each, "
      f"{sum(r['wall'] for r in whole.values()):.1f} s in all")

# %%
print(f"{'l':>5s} {'passive (N)':>12s} {'active (N)':>11s} {'active / (sigma_max A)':>23s} {'f_active(l)':>12s} "
      f"{'belly stretch':>14s} {'tendon stretch':>15s} {'mid-belly fibres: held -> active':>33s} "
      f"{'belly fibres min..max (held)':>29s}")
for stretch, r in whole.items():
    mid = len(r["profile_held"]) // 2
    print(f"{stretch:5.2f} {r['passive']:12.2f} {r['active']:11.3f} {r['normalised']:23.4f} {f_active(stretch):12.4f} "
          f"{r['belly_held']:14.4f} {r['tendons_held']:15.4f} "
          f"{r['profile_held'][mid]:22.4f} -> {r['profile_active'][mid]:.4f} "
          f"{r['range_held'][0]:21.3f}..{r['range_held'][1]:.3f}")
    assert r["active"] > 0 and r["active"] < 3e5 * belly_area

# %%
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    ax1.plot(l_fine, [f_active(s) for s in l_fine], color="C0", label="tissue: f_active(l)")
    ax1.plot(stretches, [cylinder[s]["active"] / law.sigma_max for s in stretches], "o", color="C0",
             label="tissue: cylinder FE / sigma_max")
    ax1.plot(muscle_stretches, [whole[s]["normalised"] for s in muscle_stretches], "s-", color="C3",
             label="whole muscle: active force / (sigma_max pi 15 mm^2)")
    ax1.set_xlabel("stretch l (tissue) / muscle stretch (insertion displacement / 0.14 m + 1)")
    ax1.set_ylabel("normalised active force")
    ax1.set_xlim(0.35, 1.65)
    ax1.set_ylim(-0.03, 1.35)
    ax1.legend(fontsize=8, loc="upper left")
    ax1.grid(alpha=0.3)
    for k, stretch in enumerate(muscle_stretches):
        r = whole[stretch]
        ax2.plot(100 * r["z_held"], r["profile_held"], "o-", color=f"C{k}", label=f"l = {stretch}")
        ax2.plot(100 * r["z_active"], r["profile_active"], "x--", color=f"C{k}")
    for z in (2.0, 12.0):
        ax2.axvline(z, color="grey", ls=":", lw=0.8)
    ax2.set_xlabel("z (cm)   (tendons: z < 2 and z > 12)")
    ax2.set_ylabel("fibre stretch (mean per 1 cm slice)")
    ax2.set_title("o-: held passively (t = 0.5), x--: fully active (t = 1)", fontsize=9)
    ax2.legend(fontsize=7, ncol=3, loc="upper center")
    ax2.set_ylim(top=ax2.get_ylim()[1] + 0.12 * (ax2.get_ylim()[1] - ax2.get_ylim()[0]))
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "whole_muscle_force_length.png", dpi=90)

# %% [markdown]
# The whole muscle is not a big piece of tissue. At its rest length it delivers only about 20 % of
# $\sigma_{max}$ times its largest cross-section (42.8 N, the tendon force of
# `notebooks/isometric.py`), and between $l$ = 1 and 1.1 its normalised force *rises*
# (0.20 → 0.27) where the tissue's $f_{active}$ falls (1 → 0.96). The table and the right-hand
# plot show why:
#
# - **The tendons take part of the stretch**, and the belly the rest: at $l$ = 1.1 the tendons
#   (stiff: $E$ = 15 MPa and an exponential fibre curve) are stretched by about 3 %, so the belly
#   between the two junctions is stretched by about 13 %, more than the muscle's 10 %. In the
#   full sweep, shortening is different: the tendons have no fibre stiffness in compression and
#   take most of it (at $l$ = 0.9 they are at 0.85, the belly at 0.92), and the active force drops
#   to about 0.12. The muscle's stretch is not its fibres' stretch.
# - **The fibre stretch is far from uniform along the varying cross-section.** The same axial
#   force passes through the narrow ends of the belly (radius 4 mm at the junctions) and its
#   thick middle (15 mm): held at $l$ = 1.1, the fibres near the junctions are stretched by up
#   to 33 %, those at mid-belly by only 4 %. Different fibres sit at different points of
#   $f_{active}$, so the whole-muscle curve is no rescaled copy of the tissue's.
# - **The isotropic matrix is stiff.** With the thesis' parameters ($E$ = 9 MPa, thirty times
#   $\sigma_{max}$), activation at fixed length lets the mid-belly fibres shorten (by 2.4 % at
#   $l$ = 1, by 2.0 % at $l$ = 1.1: the held → active column) while the narrow ends stretch
#   further, and the compressed matrix cancels most of the active fibre stress, as in
#   `notebooks/isometric.py`: hence the small fraction of $\sigma_{max}$. The stretched muscle is
#   stiffer (exponential passive fibre and tendon curves), its mid-belly fibres shorten less on
#   activation and more of the active stress reaches the tendons, which is consistent with the
#   rising whole-muscle force over this range.
#
# So a whole-muscle force-length curve measured on this model says as much about the geometry,
# the tendons and the matrix stiffness as about $f_{active}$; the tissue curve is recovered only
# in the homogeneous cylinder of part (a).
#
# ## Picture
#
# The fusiform muscle held at the longest stretch of the sweep, cut open along its axis (the half
# y > 0), at true scale. Top: held passively (t = 0.5); bottom: fully activated at the same length
# (t = 1); both coloured by the isochoric fibre stretch. The muscle's axis is drawn horizontally.

# %%
ROTATE = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # muscle axis z -> horizontal x
longest = muscle_stretches[-1]
panels, texts = [], []
for k, label in enumerate(("held", "active")):
    data = meshio.read(whole[longest][f"vtu_{label}"])
    lam, _, _ = fibre_stretches(data)
    path = OUT / f"picture_{label}.vtu"
    meshio.write(path, meshio.Mesh(data.points @ ROTATE.T, [("tetra", data.cells_dict["tetra"])],
                                   point_data={"u": data.point_data["u"] @ ROTATE.T},
                                   cell_data={"fibre_stretch": [lam]}))
    half = np.flatnonzero(data.points[data.cells_dict["tetra"]].mean(axis=1)[:, 1] > 0.0).tolist()
    panels.append({"vtu": str(path), "offset": [0.0, 0.0, -0.045 * k], "cells": half})
    texts.append([f"l = {longest}, {'held passively (t = 0.5)' if k == 0 else 'fully active (t = 1)'}",
                  0.02, 0.9 - 0.42 * k])
png = render({"png": str(OUT / "fusiform_fibre_stretch.png"), "window": [1200, 600], "view": "xz", "zoom": 1.2,
              "scalars": "fibre_stretch", "cmap": "coolwarm", "clim": [0.7, 1.3], "bar": "fibre stretch",
              "bar_position": [0.3, 0.03, 0.4], "panels": panels, "texts": texts})
print("wrote", png)
