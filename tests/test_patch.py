"""Tier 1: patch test. Affine Dirichlet data u = G x + c on all six faces reproduces the affine field exactly."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import example
from mpi4py import MPI

from model.config import parse
from model.pipeline import build
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

G = np.array([[0.10, 0.05, -0.02], [0.03, -0.08, 0.04], [-0.05, 0.02, 0.12]])
c = np.array([0.01, -0.02, 0.03])
PARAMS = {"stvk": {"E": 1e4, "nu": 0.3}, "neo_hookean": {"E": 1e4, "nu": 0.3},
          "mooney_rivlin": {"c1": 1500.0, "c2": 400.0, "K": 8000.0}, "corotated": {"E": 1e4, "nu": 0.3}}


def affine_config(law: str, degree: int) -> dict:
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [3, 3, 3]
    raw["discretization"] = {"degree": degree, "quadrature_degree": 2 * degree}
    raw["material"] = [{"region": "all", "law": law, **PARAMS[law]}]
    expr = [" + ".join([f"({float(G[i, j])!r})*x[{j}]" for j in range(3)] + [repr(float(c[i]))]) for i in range(3)]
    raw["boundary"] = [{"on": face, "type": "displacement", "components": [0, 1, 2], "expression": expr}
                       for face in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")]
    raw["loading"] = {"steps": 2}
    raw["probe"] = []
    return raw


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("law", sorted(PARAMS))
def test_affine_patch(law: str, degree: int) -> None:
    setup = build(parse(affine_config(law, degree)))
    solver = NewtonSolver(setup.problem)
    assert step_loads(solver, 2)
    u = setup.problem.solution
    x = u.function_space.tabulate_dof_coordinates()
    exact = x @ G.T + c
    error = np.abs(u.x.array.reshape(-1, 3) - exact).max()
    error = MPI.COMM_WORLD.allreduce(error, op=MPI.MAX)
    assert error < 1e-12, f"{law} P{degree}: max nodal error {error:.3e}"
    solver.destroy()
