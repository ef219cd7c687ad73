"""Every law's consistent tangent against central finite differences of its residual, at a non-trivial state.

The residual includes dead traction, follower pressure and body force; for corotated the
polar rotations are recomputed at each perturbed state, so the check covers the exact
derivative of the quadrature-point polar machinery. The mixed (Taylor-Hood) residual is
checked in u and p together.
"""

from __future__ import annotations

import numpy as np
import pytest
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc
from test_patch import PARAMS

import forms
import meshes
from model import compat
from model.domain import build_domain
from model.problem import ElasticityProblem


def deformed_problem(law: str, degree: int, formulation: str) -> ElasticityProblem:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(1.0, 1.0, 1.0), cells=(3, 3, 3)) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    problem = ElasticityProblem(domain, [("all", forms.make_law(law, **PARAMS[law]))], degree, 2 * degree,
                                formulation)
    problem.add_traction("xmax", [100.0, 50.0, -30.0])
    problem.add_pressure("ymax", 300.0)
    problem.add_body_force("all", [10.0, -20.0, 5.0])
    problem.set_load_factor(1.0)
    sub = problem.solution.sub(0) if formulation == "mixed" else problem.solution
    sub.interpolate(lambda x: np.array([0.2 * x[1] * x[2] + 0.1 * x[0] ** 2,
                                        -0.15 * x[0] * x[2] + 0.2 * np.sin(x[1]),
                                        0.25 * x[0] * x[1] - 0.1 * x[2] ** 2]))
    if formulation == "mixed":
        problem.solution.sub(1).interpolate(lambda x: 100.0 * (x[0] - 0.3 * x[1] + 0.2))
    return problem


def residual(problem: ElasticityProblem) -> np.ndarray:
    problem.update_state()
    b = fem_petsc.assemble_vector(problem.forms[0])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = b.array.copy()
    b.destroy()
    return out


CASES = [(law, 1, "displacement") for law in sorted(PARAMS)] + [(law, 2, "displacement") for law in sorted(PARAMS)]
CASES += [("neo_hookean", 2, "mixed"), ("corotated", 2, "mixed")]


@pytest.mark.parametrize("law,degree,formulation", CASES)
def test_jacobian_matches_finite_differences(law: str, degree: int, formulation: str) -> None:
    problem = deformed_problem(law, degree, formulation)
    problem.update_state()
    A = fem_petsc.assemble_matrix(problem.forms[1])
    A.assemble()
    rng = np.random.default_rng(7 + MPI.COMM_WORLD.rank)
    x = problem.solution.x
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    direction = compat.petsc_vector(problem.solution).copy()  # ghosted, like the solution
    direction.array[:] = rng.uniform(-1.0, 1.0, owned)
    if formulation == "mixed":  # scale the pressure part like the pressure itself
        _, pdofs = problem.space.sub(1).collapse()
        pdofs = np.asarray(pdofs)
        direction.array[pdofs[pdofs < owned]] *= 100.0
    tangent = A.createVecLeft()
    A.mult(direction, tangent)
    direction.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with direction.localForm() as d_local:
        d = d_local.array.copy()
    x0 = x.array.copy()
    h = 1e-6
    x.array[:] = x0 + h * d
    r_plus = residual(problem)
    x.array[:] = x0 - h * d
    r_minus = residual(problem)
    x.array[:] = x0
    fd = (r_plus - r_minus) / (2 * h)
    comm = MPI.COMM_WORLD
    error = comm.allreduce(np.abs(fd - tangent.array).max(), op=MPI.MAX)
    scale = comm.allreduce(np.abs(tangent.array).max(), op=MPI.MAX)
    assert error / scale < 1e-7, f"{law} P{degree} {formulation}: relative FD mismatch {error / scale:.2e}"
    A.destroy()
