"""Activation estimation: hidden activations recovered from the deformation they produce.

    .venv/bin/python examples/activation_estimation.py [--noise 0.01] [--case block|cells|arm]

A muscle block 1 x 1 x 4 cm in two regions ("lower", "upper"), fibres along z, held 10 % stretched between
clamped ends, is activated to the hidden (0.3, 0.8); its displacement (plus optional noise) is the target.
Starting from 0.5 in both regions, model.experiments.inverse.estimate_region_activations (L-BFGS-B on [0, 1]^2
with adjoint gradients, model.solvers.adjoint) recovers them (``--case block``, the default).

``--case cells``: the same block (finer, 2 x 2 x 6 hexahedra of 6 tetrahedra each) activated by a hidden field
varying per cell (``hidden_field``); estimate_cell_activations (TAO BLMVM over one activation per cell, J = misfit
+ beta R with R the DG0 jump penalty) recovers it from 0.5 everywhere; the per-cell errors and the per-region
means are printed.

``--case arm``: the two-muscle arm segment (examples/arm_segment.toml, built by model.pipeline.build, with the
coarser mesh ``mesh.size = 0.02`` m) activated to the hidden (0.7, 0.3) in belly_a and belly_b; the two are
recovered by estimate_region_activations.

Used by tests/test_inverse.py and notebooks/activation_estimation.py.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import forms  # noqa: E402
import meshes  # noqa: E402
from model import compat  # noqa: E402
from model.domain import build_domain  # noqa: E402
from model.experiments.inverse import estimate_cell_activations, estimate_region_activations  # noqa: E402
from model.fields.fibres import FibreField  # noqa: E402
from model.problem import ElasticityProblem  # noqa: E402
from model.solvers.loadstepping import step_loads  # noqa: E402
from model.solvers.newton import NewtonSolver  # noqa: E402

HIDDEN = (0.3, 0.8)
OPTIONS = {"snes_rtol": 1e-12, "snes_atol": 1e-11, "snes_stol": 0.0, "snes_max_it": 50}


HIDDEN_ARM = (0.7, 0.3)
#: every estimation here: full Newton steps (bt on the potential fails on a start already converged to round-off,
#: as TAO's evaluations near the optimum are); the estimate's own step halving globalises
OPTIONS_ESTIMATE = {**OPTIONS, "snes_linesearch_type": "basic"}
#: the smoothing weight without noise, and with 1 % noise (a scan at 1 %: the per-cell L2 error is 0.11, 0.062,
#: 0.029 at beta = 1e-4, 1e-3, 1e-2: a smaller beta fits the noise)
BETA, BETA_NOISE = 1e-4, 1e-2


def hidden_field(x: np.ndarray) -> np.ndarray:
    """The hidden per-cell activation (evaluated at the cell centres): 0.2 + 0.6 sin^2(pi z / 4 cm) (0.75 + 25 x),
    between 0.2 and 0.8 + 0.15 on the block [0, 1 cm]^2 x [0, 4 cm]."""
    return 0.2 + 0.6 * np.sin(np.pi * x[2] / 0.04) ** 2 * (0.75 + 25.0 * x[0])


def two_muscles(cells: tuple[int, int, int] = (2, 2, 6)):
    """A 1 x 1 x 4 cm block in two regions along z, "lower" and "upper", fibres along z, both ends clamped
    and held 10 % stretched; one activation field alpha (DG0) over both."""
    comm = MPI.COMM_WORLD
    data = None
    if comm.rank == 0:
        data = meshes.box(size=(0.01, 0.01, 0.04), cells=cells)
        upper = data.points[data.cells].mean(axis=1)[:, 2] > 0.02
        data = dataclasses.replace(data, cell_tags=np.where(upper, 2, 1).astype(np.int32),
                                   region_names={"lower": 1, "upper": 2})
    domain = build_domain(comm, data, facet_ghosts=True)  # the per-cell smoothing integrates over facets (dS)
    alpha = fem.Function(compat.function_space(domain.mesh, "DG", 0), name="activation")
    fibres = FibreField(domain).constant([0, 0, 0], [0, 0, 1]).function
    law = dataclasses.replace(forms.make_law("muscle", c1=5e4, K=1e6, sigma_max=3e5), a0=fibres, alpha=alpha)
    problem = ElasticityProblem(domain, [("lower", law), ("upper", law)], 1, 2)
    problem.add_dirichlet("zmin", (0, 1, 2), [0.0, 0.0, 0.0])
    problem.add_dirichlet("zmax", (0, 1, 2), [0.0, 0.0, 0.004])
    regions = {name: domain.region_cells(name) for name in ("lower", "upper")}
    return problem, alpha, regions


def set_regions(alpha, regions, values) -> None:
    cell_dofs = compat.cell_dofs(alpha.function_space.dofmap).reshape(-1)
    for cells, value in zip(regions.values(), values):
        alpha.x.array[cell_dofs[cells]] = value
    alpha.x.scatter_forward()


def noise_field(x: np.ndarray) -> np.ndarray:
    """A deterministic noise in [-1, 1] per point and component, a hash of the coordinates (the same on any
    number of ranks and partitions)."""
    phase = x @ np.array([[12.9898, 78.233, 37.719], [39.346, 11.135, 83.155], [73.156, 52.235, 9.151]]).T * 1e3
    return (np.modf(np.abs(np.sin(phase)) * 43758.5453)[0] * 2.0 - 1.0).T


def recover(noise: float, keep: dict | None = None):
    """The target: the forward solution at the hidden activations (plus ``noise`` times the largest displacement
    times noise_field); then estimation from 0.5 in both regions, on the same mesh."""
    problem, alpha, regions = two_muscles()
    set_regions(alpha, regions, HIDDEN)
    solver = NewtonSolver(problem, options=OPTIONS_ESTIMATE)
    assert step_loads(solver, 2)
    u = problem.displacement()
    target = fem.Function(u.function_space)
    target.x.array[:] = u.x.array
    if noise:
        scale = MPI.COMM_WORLD.allreduce(float(np.max(np.abs(u.x.array))), op=MPI.MAX)
        target.interpolate(lambda x: noise_field(x.T))
        target.x.array[:] = u.x.array + noise * scale * target.x.array
        target.x.scatter_forward()
    set_regions(alpha, regions, (0.5, 0.5))
    assert solver.solve().converged
    dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 2})
    objective = 0.5 * ufl.inner(problem.u - target, problem.u - target) * dx
    estimate = estimate_region_activations(problem, solver, alpha, regions, objective, initial=0.5)
    if keep is not None:  # the fields, for pictures
        keep.update(problem=problem, target=target, displacement=problem.displacement())
    solver.destroy()
    return estimate


def add_noise(u: fem.Function, noise: float) -> fem.Function:
    """u + noise * max|u| * noise_field: the target (a new Function)."""
    target = fem.Function(u.function_space)
    target.x.array[:] = u.x.array
    if noise:
        scale = MPI.COMM_WORLD.allreduce(float(np.max(np.abs(u.x.array))), op=MPI.MAX)
        target.interpolate(lambda x: noise_field(x.T))
        target.x.array[:] = u.x.array + noise * scale * target.x.array
        target.x.scatter_forward()
    return target


def normalised_misfit(problem, target: fem.Function) -> ufl.Form:
    """1/2 int |u - u*|^2 dx / (|Omega| max|u*|^2): dimensionless, about the mean squared relative error / 2."""
    comm = MPI.COMM_WORLD
    dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 2})
    volume = comm.allreduce(fem.assemble_scalar(fem.form(fem.Constant(problem.domain.mesh, 1.0) * dx)), op=MPI.SUM)
    scale = comm.allreduce(float(np.max(np.abs(target.x.array))), op=MPI.MAX)
    return 0.5 * ufl.inner(problem.u - target, problem.u - target) / (volume * scale**2) * dx


def recover_cells(noise: float = 0.0, beta: float | None = None, cells: tuple[int, int, int] = (2, 2, 6),
                  max_iterations: int = 100, keep: dict | None = None) -> dict:
    """Per-cell estimation on the block: the target is the forward solution at ``hidden_field`` (plus noise);
    TAO BLMVM from 0.5 everywhere, J = normalised_misfit + beta R. Returns the estimate, the L2 (volume-weighted
    RMS) and max errors per cell at the start and at the end, and the per-region means of the hidden and the
    recovered field. ``beta``: BETA without noise, BETA_NOISE with."""
    comm = MPI.COMM_WORLD
    beta = (BETA_NOISE if noise else BETA) if beta is None else beta
    problem, alpha, regions = two_muscles(cells)
    space = alpha.function_space
    hidden = fem.Function(space)
    hidden.interpolate(hidden_field)
    alpha.x.array[:] = hidden.x.array
    solver = NewtonSolver(problem, options=OPTIONS_ESTIMATE)
    assert step_loads(solver, 2)
    target = add_noise(problem.displacement(), noise)
    alpha.x.array[:] = 0.5
    assert solver.solve().converged
    owned = space.dofmap.index_map.size_local
    dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 0})
    volumes = fem.assemble_vector(fem.form(ufl.TestFunction(space) * dx)).array[:owned]
    total = comm.allreduce(float(np.sum(volumes)), op=MPI.SUM)

    def errors() -> tuple[float, float]:
        e = alpha.x.array[:owned] - hidden.x.array[:owned]
        return (float(np.sqrt(comm.allreduce(float(np.sum(volumes * e**2)), op=MPI.SUM) / total)),
                comm.allreduce(float(np.max(np.abs(e), initial=0.0)), op=MPI.MAX))

    start = errors()
    estimate = estimate_cell_activations(problem, solver, alpha, normalised_misfit(problem, target), beta,
                                         max_iterations=max_iterations)
    cell_dofs = compat.cell_dofs(space.dofmap).reshape(-1)
    means = {}
    for name, region in regions.items():
        dofs = np.unique(cell_dofs[region])
        dofs = dofs[dofs < owned]
        v = comm.allreduce(float(np.sum(volumes[dofs])), op=MPI.SUM)
        means[name] = tuple(comm.allreduce(float(np.sum(volumes[dofs] * f.x.array[dofs])), op=MPI.SUM) / v
                            for f in (hidden, alpha))
    if keep is not None:  # the fields, for pictures
        keep.update(problem=problem, alpha=alpha, hidden=hidden, volumes=volumes)
    solver.destroy()
    return {"estimate": estimate, "start": start, "errors": errors(), "means": means}


def arm_segment(size: float = 0.02):
    """The two-muscle arm segment of examples/arm_segment.toml (model.pipeline.build) with mesh size ``size``,
    loaded to its final load factor with the activations (0.5, 0.5); its activation field and the belly regions
    (the tendons have no activation). The activation's load hook is removed: the estimation sets alpha."""
    import tomllib

    from model.config import parse
    from model.pipeline import build

    raw = tomllib.loads((Path(__file__).with_name("arm_segment.toml")).read_text())
    raw["mesh"]["size"] = size
    for material in raw["material"]:
        if "activation" in material:
            material["activation"] = [[0.0, 0.0], [1.0, 0.5]]
    setup = build(parse(raw, Path(__file__).parent))
    problem = setup.problem
    regions = {name: setup.domain.region_cells(f"belly_{name}") for name in ("a", "b")}
    return problem, setup.activation, regions


def recover_arm(noises: Sequence[float] = (0.0,), size: float = 0.02) -> tuple[list, int]:
    """Region estimation on the arm segment, once per noise level in ``noises``: the target is the forward
    solution at HIDDEN_ARM plus that noise; L-BFGS-B from (0.5, 0.5), each from the state at (0.5, 0.5).
    Returns (the estimates, number of cells)."""
    problem, activation, regions = arm_segment(size)
    alpha = activation.function
    solver = NewtonSolver(problem, options=OPTIONS_ESTIMATE)
    assert step_loads(solver, 4)
    problem.load_hooks.remove(activation.update)
    start = problem.solution.x.array.copy()  # the state at (0.5, 0.5)
    set_regions(alpha, regions, HIDDEN_ARM)
    problem.invalidate_state()
    assert solver.solve().converged
    exact = add_noise(problem.displacement(), 0.0)  # a copy: displacement() may be the solution itself
    estimates = []
    for noise in noises:
        target = add_noise(exact, noise)
        problem.solution.x.array[:] = start
        set_regions(alpha, regions, (0.5, 0.5))
        problem.invalidate_state()
        estimates.append(estimate_region_activations(problem, solver, alpha, regions,
                                                     normalised_misfit(problem, target), initial=0.5))
    cells = MPI.COMM_WORLD.allreduce(problem.domain.mesh.topology.index_map(3).size_local, op=MPI.SUM)
    solver.destroy()
    return estimates, cells


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise", type=float, default=0.0, help="noise on the target, a fraction of the largest "
                        "displacement")
    parser.add_argument("--case", choices=("block", "cells", "arm"), default="block",
                        help="block: two regions; cells: per-cell activations; arm: the two-muscle arm segment")
    args = parser.parse_args(argv)
    root = MPI.COMM_WORLD.rank == 0
    if args.case == "cells":
        r = recover_cells(args.noise)
        e = r["estimate"]
        if root:
            print(f"per cell (beta {e.beta:g}): error L2 {r['start'][0]:.3e} -> {r['errors'][0]:.3e}, max "
                  f"{r['start'][1]:.3e} -> {r['errors'][1]:.3e}; misfit {e.misfit:.3e}, R {e.regularisation:.3e}; "
                  f"{e.iterations} TAO iterations, {e.evaluations} forward + adjoint solves (reason {e.reason})")
            for name, (h, f) in r["means"].items():
                print(f"  {name}: mean hidden {h:.5f}, recovered {f:.5f} (error {abs(f - h):.1e})")
        return 0
    if args.case == "arm":
        (estimate,), cells = recover_arm((args.noise,))
        found = np.array([estimate.activations["a"], estimate.activations["b"]])
        if root:
            print(f"arm segment ({cells} cells): hidden {HIDDEN_ARM}, recovered {np.round(found, 8).tolist()} "
                  f"(error {np.max(np.abs(found - HIDDEN_ARM)):.1e}) in {estimate.iterations} iterations, "
                  f"{estimate.evaluations} forward and adjoint solves; J = {estimate.objective:.3e}")
        return 0
    estimate = recover(args.noise)
    found = np.array([estimate.activations["lower"], estimate.activations["upper"]])
    if root:
        print(f"hidden {HIDDEN}, recovered {np.round(found, 8).tolist()} (error {np.max(np.abs(found - HIDDEN)):.1e}) "
              f"in {estimate.iterations} iterations, {estimate.evaluations} forward and adjoint solves; "
              f"J = {estimate.objective:.3e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
