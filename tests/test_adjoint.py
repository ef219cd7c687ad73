"""Adjoint gradients over converged quasi-static states (model.solvers.adjoint; issue 13 item 3): Taylor tests.

For a parameter field p (a Function in the residual) and a direction dp, the remainder
r(h) = |J(p + h dp) - J(p) - h g . dp| of the adjoint gradient g shrinks as h^2 (and without the gradient
term only as h): the observed order over halvings of h is checked to be 2 within 0.1. The forward problem
is re-solved at each p + h dp (Newton to a relative residual of 1e-12).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from forms.law import with_parameter_values
from model import compat
from model.config import parse
from model.pipeline import build
from model.problem import ElasticityProblem
from model.solvers.adjoint import (
    adjoint_gradient,
    material_gradient,
    objective_value,
    owned_cell_values,
    region_gradient,
)
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


def check_taylor(problem, solver, parameter, objective, direction, h0: float, gradient_dot: float | None = None,
                 after_solve: Callable[[], None] | None = None) -> None:
    """The adjoint gradient g of ``objective`` in ``parameter`` at the current (converged) state; J(p + h dp)
    re-solved from that state for h = h0, h0/2, h0/4, h0/8 (dp = ``direction`` on the owned dofs); the
    remainders with the gradient term shrink at order 2 +- 0.1, without it at order < 1.2 (first order).
    ``gradient_dot``: g . dp computed elsewhere (material_gradient), else from adjoint_gradient here;
    ``after_solve``: called after each forward solve (e.g. to check a contact's active set)."""
    owned = parameter.function_space.dofmap.index_map.size_local * parameter.function_space.dofmap.index_map_bs
    if gradient_dot is None:
        g = adjoint_gradient(problem, objective, parameter)
        gradient_dot = MPI.COMM_WORLD.allreduce(float(g @ direction[:owned]), op=MPI.SUM)
    base, state = parameter.x.array.copy(), problem.solution.x.array.copy()

    def J(h: float) -> float:
        parameter.x.array[:] = base
        parameter.x.array[:owned] += h * direction[:owned]
        parameter.x.scatter_forward()
        problem.solution.x.array[:] = state
        problem.invalidate_state()  # states at quadrature points (polar rotations) may depend on p
        assert solver.solve().converged
        if after_solve is not None:
            after_solve()
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
    parameter.x.array[:] = base
    problem.solution.x.array[:] = state
    problem.invalidate_state()


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


# --- material parameters (material_gradient) ------------------------------------------------------------

def twin(setup, raw: dict, parameters: tuple[str, ...]) -> tuple[ElasticityProblem, dict[str, fem.Function]]:
    """The pipeline's one-material problem of ``raw`` rebuilt on the same domain with the law's ``parameters``
    held by DG0 Functions (forms.law.with_parameter_values), equal to the law's numbers: the forward map
    p -> u(p) per cell, to perturb in a Taylor test of material_gradient (which sees only the numbers)."""
    (region, law), = setup.problem.materials
    msh = setup.domain.mesh
    fields = {}
    for name in parameters:
        fields[name] = fem.Function(compat.function_space(msh, "DG", 0), name=name)
        fields[name].x.array[:] = getattr(law, name)
    law = with_parameter_values(law, {name: (f, [getattr(law, name)]) for name, f in fields.items()})
    disc = raw["discretization"]
    problem = ElasticityProblem(setup.domain, [(region, law)], disc.get("degree", 1),
                                disc.get("quadrature_degree", "auto"), disc.get("formulation", "displacement"))
    for b in raw["boundary"]:
        if b["type"] == "displacement":
            problem.add_dirichlet(b["on"], [0, 1, 2], b["value"])
        else:
            assert b["type"] == "traction"
            problem.add_traction(b["on"], b["value"])
    return problem, fields


def per_dof(field: fem.Function, cells: np.ndarray) -> np.ndarray:
    """A per-owned-cell array as a (owned + ghost) dof array of the DG0 ``field``'s space (ghosts 0)."""
    out = np.zeros(field.x.array.size)
    dofs = compat.cell_dofs(field.function_space.dofmap)[: len(cells), 0]
    out[dofs] = cells
    return out


def check_material_taylor(setup, raw: dict, solver_options: dict, parameters: dict[str, str], objective_of,
                          h0: float, seed: int) -> None:
    """For each parameter (name -> "cell" or "region"): material_gradient on the pipeline's problem (numbers in
    its residual), Taylor-tested on the twin whose parameter fields are perturbed (per cell: a random direction
    of +-1 times the parameter (cell_noise); region: the parameter times 1 on every cell, gradient the scalar
    dJ/dp)."""
    problem = setup.problem
    solver = NewtonSolver(problem, options=solver_options)
    assert step_loads(solver, 2)
    if setup.activation is not None:  # a generic activation per cell (shared by the twin's law)
        alpha = setup.activation.function
        alpha.x.array[:] = 0.85 + 0.15 * cell_noise(alpha, seed + 1)
        assert solver.solve().converged
    twin_problem, fields = twin(setup, raw, tuple(parameters))
    twin_solver = NewtonSolver(twin_problem, options=solver_options)
    assert step_loads(twin_solver, 2)
    difference = np.abs(twin_problem.solution.x.array - problem.solution.x.array).max(initial=0.0)
    scale = np.abs(problem.solution.x.array).max(initial=0.0)
    assert MPI.COMM_WORLD.allreduce(difference, op=MPI.MAX) <= 1e-9 * MPI.COMM_WORLD.allreduce(scale, op=MPI.MAX)
    objective = objective_of(problem)
    for name, kind in parameters.items():
        c = fields[name]
        value = float(getattr(problem.materials[0][1], name))
        if kind == "cell":
            g = material_gradient(problem, objective, "all", name, per_cell=True)
            cells = value * owned_cell_values(c, cell_noise(c, seed))
            gradient_dot = MPI.COMM_WORLD.allreduce(float(g @ cells), op=MPI.SUM)
            # the scalar gradient is the sum of the per-cell one
            total = material_gradient(problem, objective, "all", name)
            assert np.isclose(total, MPI.COMM_WORLD.allreduce(float(g.sum()), op=MPI.SUM), rtol=1e-12)
        else:
            gradient_dot = value * material_gradient(problem, objective, "all", name)
            cells = np.full(len(owned_cell_values(c, c.x.array)), value)
        check_taylor(twin_problem, twin_solver, c, objective_of(twin_problem), per_dof(c, cells), h0,
                     gradient_dot=gradient_dot)
    solver.destroy()
    twin_solver.destroy()


@pytest.mark.parametrize("law, formulation", [("neo_hookean", "displacement"), ("neo_hookean", "mixed"),
                                             ("corotated", "displacement")])
def test_isotropic_mu_and_lmbda_gradients_pass_the_taylor_test(law: str, formulation: str) -> None:
    """dJ/dmu per cell and dJ/dlmbda of the region (the bulk parameter) of a block bent by a traction,
    J = 1/2 int |u - u_target|^2: neo-Hookean in both formulations (mixed: lmbda enters only the pressure
    equation g(F) - p / lmbda), corotated through its polar rotation."""
    start = time.perf_counter()
    mixed = formulation == "mixed"
    raw = {"mesh": {"generator": "box", "size": [1.0, 1.0, 3.0], "cells": [1, 1, 3] if mixed else [2, 2, 4]},
           "discretization": {"degree": 2 if mixed else 1, "quadrature_degree": 2 if mixed else 1,
                              "formulation": formulation},
           "material": [{"region": "all", "law": law, "mu": 1e4, "lmbda": 5e4}],
           "boundary": [{"on": "zmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                        {"on": "zmax", "type": "traction", "value": [2e3, 0.0, 0.0]}]}
    setup = build(parse(raw))

    def objective_of(problem: ElasticityProblem) -> ufl.Form:
        dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 2})
        X = ufl.SpatialCoordinate(problem.domain.mesh)
        target = ufl.as_vector([0.1 * X[2] ** 2, 0.05 * X[2], 0.0])
        return 0.5 * ufl.inner(problem.u - target, problem.u - target) * dx

    options = {**TIGHT, "snes_atol": 1e-9, "snes_linesearch_type": "basic"}
    check_material_taylor(setup, raw, options, {"mu": "cell", "lmbda": "region"}, objective_of, h0=0.1, seed=5)
    assert time.perf_counter() - start < 60.0


def test_muscle_sigma_max_and_c1_gradients_pass_the_taylor_test() -> None:
    """dJ/dsigma_max per cell and dJ/dc1 of the region of the stretched muscle block (fibre law), activated per
    cell between 0.7 and 1 (a uniform block is symmetric, and these gradients of the sideways target vanish)."""
    raw = muscle_block()
    setup = build(parse(raw))

    def objective_of(problem: ElasticityProblem) -> ufl.Form:
        X = ufl.SpatialCoordinate(problem.domain.mesh)
        target = ufl.as_vector([0.02 * X[2] * (0.04 - X[2]), 0.0, 0.0])
        dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 4})
        return 0.5 * ufl.inner(problem.u - target, problem.u - target) * dx

    options = {**TIGHT, "snes_linesearch_type": "basic"}  # bt stalls at the residual's rounding level here
    check_material_taylor(setup, raw, options, {"sigma_max": "cell", "c1": "region"}, objective_of, h0=0.02, seed=7)


def test_material_gradient_refuses_what_it_cannot_differentiate() -> None:
    setup = build(parse(muscle_block()))
    problem = setup.problem
    J = ufl.inner(problem.u, problem.u) * ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 2})
    with pytest.raises(ValueError, match="no parameter 'E'"):
        material_gradient(problem, J, "all", "E")
    with pytest.raises(ValueError, match="0 materials on region 'belly'"):
        material_gradient(problem, J, "belly", "c1")
    with pytest.raises(ValueError, match="P2 enters the law through numbers"):
        material_gradient(problem, J, "all", "P2")
    with pytest.raises(ValueError, match="not a number"):
        material_gradient(problem, J, "all", "isotropic")


def cell_noise(field: fem.Function, seed: int) -> np.ndarray:
    """Values in [-1, 1] per dof of a DG0 field, a hash of the cell's midpoint: the same field on any number of
    ranks (a generic per-cell field, unlike a random generator seeded per rank)."""
    msh = field.function_space.mesh
    size = msh.comm.allreduce(float(np.abs(msh.geometry.x).max()), op=MPI.MAX)
    x = field.function_space.tabulate_dof_coordinates() * 1e3 / size
    phase = x @ np.array([12.9898, 78.233, 37.719]) + 1.618 * seed
    return 2.0 * np.modf(np.abs(np.sin(phase)) * 43758.5453)[0] - 1.0


def test_activation_gradient_with_penalty_contact_passes_the_taylor_test() -> None:
    """The muscle block (fibre law, activated) pressed against a rigid plane by penalty contact (x <= 9.6 mm:
    its face xmax at 10 mm starts 0.4 mm inside; nodal quadrature, so the active set is that of the nodes):
    dJ/dalpha per cell, and per region (alpha = a on every cell: dJ/da = sum over the cells, region_gradient).
    The contact is active at the state and its active set (the sign of every nodal gap, with a margin) is the
    same at every perturbed state of the Taylor steps (the penalty's min(g, 0)^2 is smooth there)."""
    raw = muscle_block()
    raw["contact"] = [{"surface": "xmax", "obstacle": "plane", "point": [0.0096, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0],
                       "method": "penalty", "penalty": 1e8, "quadrature_degree": "vertex"}]
    setup = build(parse(raw))
    problem, alpha = setup.problem, setup.activation.function
    contact, = setup.contacts
    assert any(name == "contact" for name in problem.extra_energy_names)  # the penalty is in the residual
    solver = NewtonSolver(problem, options=TIGHT)
    assert step_loads(solver, 2)
    alpha.x.array[:] = 0.85 + 0.15 * cell_noise(alpha, 1)  # the same field on any number of ranks
    assert solver.solve().converged
    active = contact.active_points()
    gaps = contact.nodal_gaps()
    total = MPI.COMM_WORLD.allreduce(len(gaps), op=MPI.SUM)
    assert 0 < active < total, (active, total)
    margin = MPI.COMM_WORLD.allreduce(float(np.abs(gaps).min(initial=np.inf)), op=MPI.MIN)
    assert margin > 1e-5, margin  # every node clearly in or out of contact (2 % of the initial overlap)
    signs = gaps <= 0.0

    def same_active_set() -> None:
        changed = MPI.COMM_WORLD.allreduce(int(np.sum((contact.nodal_gaps() <= 0.0) != signs)), op=MPI.SUM)
        assert changed == 0 and contact.active_points() == active, (changed, active)

    u = problem.u
    X = ufl.SpatialCoordinate(problem.domain.mesh)
    target = ufl.as_vector([0.02 * X[2] * (0.04 - X[2]), 0.0, 0.0])
    dx = ufl.dx(domain=problem.domain.mesh, metadata={"quadrature_degree": 4})
    objective = 0.5 * ufl.inner(u - target, u - target) * dx
    check_taylor(problem, solver, alpha, objective, cell_noise(alpha, 2), h0=0.02, after_solve=same_active_set)
    per_cell = owned_cell_values(alpha, adjoint_gradient(problem, objective, alpha))
    region = region_gradient(problem, per_cell, "all")
    check_taylor(problem, solver, alpha, objective, np.ones(alpha.x.array.size), h0=0.02, gradient_dot=region,
                 after_solve=same_active_set)
    solver.destroy()
