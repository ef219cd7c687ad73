"""Tier 2: manufactured solution for neo_hookean with body force, observed convergence rates.

u_ex is smooth and non-trivial; b = -div P(I + grad u_ex) is derived by UFL from the
same law; u = u_ex on the whole boundary. Errors are integrated against the exact
UFL expression with a high-degree rule; rates from the two finest meshes must lie
within 0.1 of (degree + 1) in L2 and degree in H1.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

import forms
import meshes
from forms.kinematics import deformation_gradient
from model.domain import build_domain
from model.problem import ElasticityProblem
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

LAW = forms.make_law("neo_hookean", E=1.0e3, nu=0.3)


def exact(x, mod):
    """u_ex with mod = np (interpolation) or ufl (error forms)."""
    return [0.1 * mod.sin(np.pi * x[0]) * mod.sin(np.pi * x[1]) + 0.05 * x[2] ** 2,
            0.08 * mod.cos(np.pi * x[2]) * x[0] - 0.04 * x[1] ** 2,
            0.06 * mod.sin(np.pi * x[1] * x[0]) + 0.05 * x[2] * x[0]]


def solve(n: int, degree: int) -> tuple[float, float, float]:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(1.0, 1.0, 1.0), cells=(n, n, n)) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    problem = ElasticityProblem(domain, [("all", LAW)], degree, 2 * degree + 2)
    X = ufl.SpatialCoordinate(domain.mesh)
    u_ex = ufl.as_vector(exact(X, ufl))
    body = -ufl.div(LAW.stress(deformation_gradient(u_ex)))
    problem.add_body_force("all", body)
    for face in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        problem.add_dirichlet(face, (0, 1, 2), [lambda x, i=i: np.asarray(exact(x, np), dtype=float)[i]
                                                for i in range(3)])
    solver = NewtonSolver(problem)
    assert step_loads(solver, 2)
    solver.destroy()
    dx = ufl.dx(metadata={"quadrature_degree": 2 * degree + 6})
    e = problem.solution - u_ex
    l2 = comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(e, e) * dx)), op=MPI.SUM)
    h1 = comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(ufl.grad(e), ufl.grad(e)) * dx)), op=MPI.SUM)
    return 1.0 / n, float(np.sqrt(l2)), float(np.sqrt(h1))


@pytest.mark.parametrize("degree,sizes", [(1, (4, 8, 16)), (2, (2, 4, 8))])
def test_neo_hookean_convergence_rates(degree: int, sizes: tuple[int, ...]) -> None:
    results = np.array([solve(n, degree) for n in sizes])
    h, l2, h1 = results.T
    rate_l2 = np.log(l2[1:] / l2[:-1]) / np.log(h[1:] / h[:-1])
    rate_h1 = np.log(h1[1:] / h1[:-1]) / np.log(h[1:] / h[:-1])
    report = f"P{degree}: h {h}, L2 {l2} rates {rate_l2}, H1 {h1} rates {rate_h1}"
    assert abs(rate_l2[-1] - (degree + 1)) < 0.1, report
    assert abs(rate_h1[-1] - degree) < 0.1, report
