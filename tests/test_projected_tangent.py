"""Projected tangent ([solver] tangent = "projected", model.tangent): the modified Newton of Klar et al. 2020.

- Where dP/dF is positive semidefinite at every quadrature point, the projected Jacobian is the exact one.
- For shape targeting at a compressed state, where dP/dF has negative eigenvalues, the exact stiffness
  matrix (Dirichlet rows removed) is indefinite and the projected one positive semidefinite.
- A bending bar driven by incompatible, per-cell shape targets: Newton with the projected tangent converges
  to the configuration the exact tangent finds, with MUMPS LU and with CG + GAMG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import run_raw
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

import forms
import meshes
from model.config import parse
from model.domain import build_domain
from model.errors import ConfigError
from model.fields.targets import TargetField
from model.problem import ElasticityProblem
from model.solvers.newton import NewtonSolver
from model.solvers.tangent import ProjectedTangent

HERE = Path(__file__).resolve()


def bending_targets(x: np.ndarray, t: float) -> np.ndarray:
    """Incompatible targets of a 2 x 0.5 x 0.5 bar: lengthen the top, shorten the bottom (it bends),
    widen with z, vary along x; an in-plane shear that changes sign along the bar. Identity at t = 0."""
    z = (x[:, 2] - 0.25) / 0.25
    S = np.zeros((len(x), 3, 3))
    S[:, 0, 0] = 1.0 + 0.4 * t * z
    S[:, 1, 1] = 1.0 - 0.1 * t * z
    S[:, 2, 2] = 1.0 + 0.1 * t * np.sin(3.0 * x[:, 0])
    S[:, 0, 1] = S[:, 1, 0] = 0.1 * t * np.cos(2.0 * x[:, 0])
    return S


def bar_config(solver: dict, steps: int = 2) -> dict:
    """A bar clamped at xmin, shape targets only (kappa = 0), its shape driven by bending_targets."""
    return {
        "mesh": {"generator": "box", "size": [2.0, 0.5, 0.5], "cells": [8, 2, 2]},
        "discretization": {"degree": 1, "quadrature_degree": 2},
        "material": [{"region": "all", "law": "shape_target", "mu": 1.0e3, "kappa": 0.0,
                      "S_function": f"{HERE}:bending_targets"}],
        "boundary": [{"on": "xmin", "type": "displacement", "components": [0, 1, 2], "value": [0.0, 0.0, 0.0]}],
        "loading": {"steps": steps},
        "solver": solver,
        "probe": [{"name": "end_centre", "point": [2.0, 0.25, 0.25]},
                  {"name": "end_corner", "point": [2.0, 0.5, 0.5]},
                  {"name": "middle_corner", "point": [1.0, 0.0, 0.5]}],
        "output": {"xdmf": False, "vtu": False, "png": False},
    }


def final_probes(summary: dict) -> np.ndarray:
    last = summary["steps"][-1]
    assert summary["status"] == "completed" and last["converged"] and last["load_factor"] == 1.0
    return np.array([last["probes"][name] for name in sorted(last["probes"])])


def box_problem(law: str, params: dict, cells=(2, 2, 2), degree: int = 1, targets=None) -> ElasticityProblem:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(1.0, 1.0, 1.0), cells=cells) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    extra = {}
    if targets is not None:
        field = TargetField(domain.mesh, domain.region_cells("all"), targets)
        extra["S"] = field.function
    problem = ElasticityProblem(domain, [("all", forms.make_law(law, **params, **extra))], degree, 2 * degree)
    problem.add_dirichlet("xmin", [0, 1, 2], [0.0, 0.0, 0.0])
    problem._keep = extra  # the target Function lives as long as the problem
    return problem


def negative_points(tangent: ProjectedTangent) -> int:
    tangent.count_negative = True
    tangent.invalidate()
    tangent.update()
    return MPI.COMM_WORLD.allreduce(tangent.negative_points, op=MPI.SUM)


def assembled(problem: ElasticityProblem, form) -> PETSc.Mat:
    A = fem_petsc.assemble_matrix(form, bcs=problem.bcs)
    A.assemble()
    return A


PSD_CASES = [
    ("neo_hookean", {"E": 1.0e4, "nu": 0.3}, 1),
    ("neo_hookean", {"E": 1.0e4, "nu": 0.3}, 2),
    ("shape_target", {"mu": 1.0e3, "kappa": 5.0e3}, 1),
]


@pytest.mark.parametrize("law,params,degree", PSD_CASES)
def test_projected_jacobian_is_exact_where_the_tangent_is_psd(law: str, params: dict, degree: int) -> None:
    """Small tension (every singular value of F, and of F S, above 1): dP/dF is PSD at every point."""
    problem = box_problem(law, params, degree=degree)
    problem.add_pressure("ymax", 20.0)  # follower pressure: its exact derivative is in both Jacobians
    problem.set_load_factor(1.0)
    problem.solution.interpolate(lambda x: np.array([0.04 * x[0] + 0.01 * x[1] * x[2],
                                                     0.03 * x[1] + 0.01 * x[0] ** 2,
                                                     0.02 * x[2] + 0.005 * x[0] * x[1]]))
    problem.update_state()
    tangent = ProjectedTangent(problem)
    assert negative_points(tangent) == 0
    exact = assembled(problem, problem.forms[1])
    projected = assembled(problem, tangent.form)
    difference = exact.copy()
    difference.axpy(-1.0, projected)
    relative = difference.norm(PETSc.NormType.FROBENIUS) / exact.norm(PETSc.NormType.FROBENIUS)
    assert relative < 1e-10, f"{law} P{degree}: projected differs from exact by {relative:.2e}"
    for matrix in (exact, projected, difference):
        matrix.destroy()


def dense_without_dirichlet_rows(problem: ElasticityProblem, A: PETSc.Mat) -> np.ndarray | None:
    """The global matrix as a dense array on rank 0, rows and columns of Dirichlet dofs removed (None elsewhere)."""
    comm = MPI.COMM_WORLD
    start, _ = A.getOwnershipRange()
    indptr, indices, data = A.getValuesCSR()
    imap = problem.space.dofmap.index_map
    bs = problem.space.dofmap.index_map_bs
    owned = imap.size_local * bs
    local = np.unique(np.concatenate([d for entry in problem.dirichlet for d in entry.dofs]))
    local = local[local < owned]
    constrained = imap.local_to_global(local // bs) * bs + local % bs
    pieces = comm.gather((start, indptr, indices, data, constrained), root=0)
    if comm.rank != 0:
        return None
    n = A.getSize()[0]
    dense = np.zeros((n, n))
    for first, ptr, cols, values, _ in pieces:
        for row in range(len(ptr) - 1):
            dense[first + row, cols[ptr[row]:ptr[row + 1]]] = values[ptr[row]:ptr[row + 1]]
    free = np.setdiff1d(np.arange(n), np.concatenate([p[4] for p in pieces]))
    return dense[np.ix_(free, free)]


def compressive_targets(x: np.ndarray, t: float) -> np.ndarray:
    S = np.zeros((len(x), 3, 3))
    S[:, 0, 0] = 1.0 + 0.3 * x[:, 1]
    S[:, 1, 1] = 0.9 + 0.2 * np.sin(3.0 * x[:, 2])
    S[:, 2, 2] = 1.1
    S[:, 0, 2] = S[:, 2, 0] = 0.15 * x[:, 0]
    return S


def test_projected_stiffness_is_psd_where_the_exact_one_is_indefinite() -> None:
    problem = box_problem("shape_target", {"mu": 1.0e3}, cells=(3, 2, 2), targets=compressive_targets)
    problem.set_load_factor(1.0)
    # compressed to about half its size with a twist and a shear: F S has singular values well below 1
    problem.solution.interpolate(lambda x: np.array([-0.5 * x[0] + 0.1 * x[1] * x[2],
                                                     -0.45 * x[1] + 0.2 * x[0] * x[2],
                                                     -0.55 * x[2] - 0.15 * x[0] * x[1]]))
    problem.update_state()
    tangent = ProjectedTangent(problem)
    assert negative_points(tangent) > 0
    exact = assembled(problem, problem.forms[1])
    projected = assembled(problem, tangent.form)
    K_exact = dense_without_dirichlet_rows(problem, exact)
    K_projected = dense_without_dirichlet_rows(problem, projected)
    if MPI.COMM_WORLD.rank == 0:
        for K in (K_exact, K_projected):
            assert np.abs(K - K.T).max() < 1e-12 * np.abs(K).max()
        smallest_exact = np.linalg.eigvalsh(K_exact)[0] / np.linalg.norm(K_exact)
        smallest_projected = np.linalg.eigvalsh(K_projected)[0] / np.linalg.norm(K_projected)
        assert smallest_exact < -1e-3, f"the exact stiffness should be indefinite here: {smallest_exact:.2e}"
        assert smallest_projected >= -1e-10, f"projected stiffness not PSD: {smallest_projected:.2e}"
    exact.destroy()
    projected.destroy()


def test_projected_newton_converges_to_the_exact_newton_solution(shared_tmp: Path) -> None:
    exact = final_probes(run_raw(bar_config({"tangent": "exact"}), shared_tmp / "exact"))
    summary = run_raw(bar_config({"tangent": "projected", "petsc_options": {"snes_max_it": 200}}),
                      shared_tmp / "projected")
    assert {k: summary["solver"][k] for k in ("method", "tangent", "linear", "line_search")} == {
        "method": "newton", "tangent": "projected", "linear": "direct",
        "line_search": {"type": "bt", "merit": "total_potential"}}
    projected = final_probes(summary)
    assert np.abs(exact).max() > 0.3  # a real deformation
    np.testing.assert_allclose(projected, exact, rtol=0, atol=1e-8 * np.abs(exact).max())


@pytest.mark.parametrize("pc", ["gamg", "hypre"])
def test_projected_newton_with_cg_and_algebraic_multigrid(pc: str, shared_tmp: Path) -> None:
    if pc == "hypre" and not PETSc.Sys.hasExternalPackage("hypre"):
        pytest.skip("PETSc without hypre")
    options = {"snes_max_it": 200, "ksp_type": "cg", "pc_type": pc, "ksp_rtol": 1e-10,
               "ksp_max_it": 1000, "snes_linesearch_type": "bt"}
    if pc == "hypre":
        options["pc_hypre_type"] = "boomeramg"
    reference = final_probes(run_raw(bar_config({"tangent": "exact"}), shared_tmp / "exact"))
    summary = run_raw(bar_config({"tangent": "projected", "petsc_options": options}), shared_tmp / pc)
    assert all(step["converged"] for step in summary["steps"])
    assert all(step["linear_iterations"] > step["newton_iterations"] for step in summary["steps"])  # CG ran
    np.testing.assert_allclose(final_probes(summary), reference, rtol=0, atol=1e-8 * np.abs(reference).max())


def test_projected_tangent_needs_the_displacement_formulation() -> None:
    raw = bar_config({"tangent": "projected"})
    raw["discretization"] = {"degree": 2, "formulation": "mixed"}
    raw["material"][0]["kappa"] = 1.0e4
    with pytest.raises(ConfigError, match=r'^solver\.tangent: "projected" needs discretization\.formulation'):
        parse(raw)
    problem = box_problem("neo_hookean", {"E": 1.0e4, "nu": 0.3}, degree=1)
    with pytest.raises(ValueError, match="^solver.tangent: 'fancy' is not one of exact, projected"):
        NewtonSolver(problem, tangent="fancy")


@pytest.mark.parametrize("solver,key,fragment", [
    ({"tangent": "psd"}, "solver.tangent", "'psd' is not one of exact, projected"),
    ({"tangent": 1}, "solver.tangent", "must be a string"),
    ({"tangent": "projected", "method": "projective_dynamics"}, "solver.tangent", "only applies to method"),
    ({"tangents": "projected"}, "solver.tangents", "unknown key"),
])
def test_bad_tangent_keys_are_named(solver: dict, key: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse(bar_config(solver))
    message = str(err.value)
    assert message.startswith(f"{key}: ") and fragment in message and "\n" not in message, message
