"""Adjoint gradients over converged quasi-static states (model.solvers.adjoint; issue 13 item 3): Taylor tests.

For a parameter field p (a Function in the residual) and a direction dp, the remainder
r(h) = |J(p + h dp) - J(p) - h g . dp| of the adjoint gradient g shrinks as h^2 (and without the gradient
term only as h): the observed order over halvings of h is checked to be 2 within 0.1. The forward problem
is re-solved at each p + h dp (Newton to a relative residual of 1e-12).
"""

from __future__ import annotations

import numpy as np
import ufl
from mpi4py import MPI

from model.config import parse
from model.pipeline import build
from model.solvers.adjoint import adjoint_gradient, objective_value
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-11, "snes_stol": 0.0, "snes_max_it": 50}


def muscle_block(formulation: str = "displacement") -> dict:
    """A muscle block 1 x 1 x 4 cm, fibres along z, held stretched by 10 % (the fibre stretch stays inside one
    smooth piece of the fibre curves, between their breakpoints at 1 and 1.4), activated to 1."""
    return {
        "mesh": {"generator": "box", "size": [0.01, 0.01, 0.04], "cells": [2, 2, 5]},
        "discretization": {"degree": 2 if formulation == "mixed" else 1, "formulation": formulation,
                           "quadrature_degree": 2},
        "material": [{"region": "all", "law": "muscle", "c1": 5e4, "K": 1e6, "sigma_max": 3e5,
                      "fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [0.0, 0.0, 1.0]},
                      "activation": [[0.0, 0.0], [1.0, 1.0]]}],
        "boundary": [{"on": "zmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                     {"on": "zmax", "type": "displacement", "value": [0.0, 0.0, 0.004]}],
    }


def check_taylor(problem, solver, parameter, objective, direction, h0: float) -> None:
    """The adjoint gradient g of ``objective`` in ``parameter`` at the current (converged) state; J(p + h dp)
    re-solved from that state for h = h0, h0/2, h0/4, h0/8 (dp = ``direction`` on the owned dofs); the
    remainders with the gradient term shrink at order 2 +- 0.1, without it at order < 1.2 (first order)."""
    g = adjoint_gradient(problem, objective, parameter)
    owned = len(g)
    gradient_dot = MPI.COMM_WORLD.allreduce(float(g @ direction[:owned]), op=MPI.SUM)
    base, state = parameter.x.array.copy(), problem.solution.x.array.copy()

    def J(h: float) -> float:
        parameter.x.array[:] = base
        parameter.x.array[:owned] += h * direction[:owned]
        parameter.x.scatter_forward()
        problem.solution.x.array[:] = state
        problem.invalidate_state()  # states at quadrature points (polar rotations) may depend on p
        assert solver.solve().converged
        return objective_value(objective, MPI.COMM_WORLD)

    J0 = J(0.0)
    with_g, without = [], []
    for k in range(4):
        h = h0 / 2**k
        Jh = J(h)
        with_g.append(abs(Jh - J0 - h * gradient_dot))
        without.append(abs(Jh - J0))
    order = [float(np.log2(a / b)) for a, b in zip(with_g, with_g[1:])]
    first = [float(np.log2(a / b)) for a, b in zip(without, without[1:])]
    report = (order, first, gradient_dot)
    assert all(abs(o - 2.0) < 0.1 for o in order), report
    assert all(o < 1.2 for o in first), report  # without the gradient term: first order


def test_activation_gradient_passes_the_taylor_test() -> None:
    setup = build(parse(muscle_block()))
    problem, alpha = setup.problem, setup.activation.function
    solver = NewtonSolver(problem, options=TIGHT)
    assert step_loads(solver, 2)
    rng = np.random.default_rng(1 + MPI.COMM_WORLD.rank)
    alpha.x.array[:] = rng.uniform(0.7, 1.0, alpha.x.array.shape)  # a generic per-cell activation
    alpha.x.scatter_forward()
    assert solver.solve().converged
    u = problem.u
    X = ufl.SpatialCoordinate(problem.domain.mesh)
    target = ufl.as_vector([0.02 * X[2] * (0.04 - X[2]), 0.0, 0.0])  # a sideways bulge to reach
    dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 4})
    objective = 0.5 * ufl.inner(u - target, u - target) * dx + 1e-9 * alpha**2 * dx
    check_taylor(problem, solver, alpha, objective, rng.uniform(-1.0, 1.0, alpha.x.array.size), h0=0.05)
    solver.destroy()


def test_shape_target_gradient_passes_the_taylor_test() -> None:
    """p = the per-cell target stretches S of shape_target (a DG0 tensor field), through the polar decomposition
    (R0 per quadrature point from the state, R = R0 (I + [w]x) linearised: forms/polar.py)."""
    raw = {"mesh": {"generator": "box", "size": [1.0, 1.0, 3.0], "cells": [2, 2, 4]},
           "discretization": {"degree": 1, "quadrature_degree": 1},
           "material": [{"region": "all", "law": "shape_target", "mu": 1e4, "kappa": 5e4}],
           "boundary": [{"on": "zmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                        {"on": "zmax", "type": "traction", "value": [2e3, 0.0, 0.0]}]}
    setup = build(parse(raw))
    problem, S = setup.problem, setup.targets[0].function
    # forces of order 1e3 N here: an absolute tolerance of 1e-9 is 1e-12 of them (bt stalls at that level)
    solver = NewtonSolver(problem, options={**TIGHT, "snes_atol": 1e-9, "snes_linesearch_type": "basic"})
    assert step_loads(solver, 2)
    rng = np.random.default_rng(3 + MPI.COMM_WORLD.rank)
    blocks = S.x.array.reshape(-1, 3, 3)
    noise = rng.uniform(-0.1, 0.1, blocks.shape)
    blocks += 0.5 * (noise + np.swapaxes(noise, 1, 2))  # a generic symmetric target per cell
    S.x.scatter_forward()
    problem.invalidate_state()
    assert solver.solve().converged
    dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 2})
    X = ufl.SpatialCoordinate(problem.domain.mesh)
    target = ufl.as_vector([0.1 * X[2] ** 2, 0.05 * X[2], 0.0])
    objective = 0.5 * ufl.inner(problem.u - target, problem.u - target) * dx
    direction = rng.uniform(-1.0, 1.0, S.x.array.size).reshape(-1, 3, 3)
    direction = (0.5 * (direction + np.swapaxes(direction, 1, 2))).reshape(-1)  # symmetric, as S
    check_taylor(problem, solver, S, objective, direction, h0=0.02)
    solver.destroy()
