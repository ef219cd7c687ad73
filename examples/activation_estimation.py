"""Activation estimation: hidden per-region activations recovered from the deformation they produce.

    .venv/bin/python examples/activation_estimation.py [--noise 0.01]

A muscle block 1 x 1 x 4 cm in two regions ("lower", "upper"), fibres along z, held 10 % stretched between
clamped ends, is activated to the hidden (0.3, 0.8); its displacement (plus optional noise) is the target.
Starting from 0.5 in both regions, model.experiments.inverse.estimate_region_activations (L-BFGS-B on [0, 1]^2
with adjoint gradients, model.solvers.adjoint) recovers them. Used by tests/test_inverse.py and
notebooks/activation_estimation.py.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
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
from model.experiments.inverse import estimate_region_activations  # noqa: E402
from model.fields.fibres import FibreField  # noqa: E402
from model.problem import ElasticityProblem  # noqa: E402
from model.solvers.loadstepping import step_loads  # noqa: E402
from model.solvers.newton import NewtonSolver  # noqa: E402

HIDDEN = (0.3, 0.8)
OPTIONS = {"snes_rtol": 1e-12, "snes_atol": 1e-11, "snes_stol": 0.0, "snes_max_it": 50}


def two_muscles():
    """A 1 x 1 x 4 cm block in two regions along z, "lower" and "upper", fibres along z, both ends clamped
    and held 10 % stretched; one activation field alpha (DG0) over both."""
    comm = MPI.COMM_WORLD
    data = None
    if comm.rank == 0:
        data = meshes.box(size=(0.01, 0.01, 0.04), cells=(2, 2, 6))
        upper = data.points[data.cells].mean(axis=1)[:, 2] > 0.02
        data = dataclasses.replace(data, cell_tags=np.where(upper, 2, 1).astype(np.int32),
                                   region_names={"lower": 1, "upper": 2})
    domain = build_domain(comm, data)
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
    solver = NewtonSolver(problem, options=OPTIONS)
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



def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise", type=float, default=0.0, help="noise on the target, a fraction of the largest "
                        "displacement")
    args = parser.parse_args(argv)
    estimate = recover(args.noise)
    found = np.array([estimate.activations["lower"], estimate.activations["upper"]])
    if MPI.COMM_WORLD.rank == 0:
        print(f"hidden {HIDDEN}, recovered {np.round(found, 8).tolist()} (error {np.max(np.abs(found - HIDDEN)):.1e}) "
              f"in {estimate.iterations} iterations, {estimate.evaluations} forward and adjoint solves; "
              f"J = {estimate.objective:.3e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
