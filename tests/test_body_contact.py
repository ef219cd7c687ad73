"""Contact and sliding between deformable bodies (model.problem.body_contact; issue 14 items 1 and 2).

Two identical unit blocks stacked (separate meshes in one, meshes.combine), rollers on x = 0 and y = 0, the lower
block's bottom on rollers, a pressure p on the upper block's top: a homogeneous uniaxial state. The contact
force equals p times the area (closed form), every slave node penetrates by p/k (the nodal penalty), so the error
against the same problem as one body (a 1 x 1 x 2 block) is p/k: it shrinks as 1/k. Newton converges
quadratically (the pairing does not change). Sliding holds the upper block pulled away (g = +p/k, tension).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

import forms
import meshes
from meshes.combine import combine, moved
from model.domain import build_domain
from model.problem import ElasticityProblem
from model.problem.body_contact import BodyContact, closest_points_on_triangles
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

P = 200.0
LAW = forms.make_law("neo_hookean", E=1e4, nu=0.3)
OPTIONS = {"snes_rtol": 1e-11, "snes_atol": 1e-10}


def stacked(k: float, kind: str = "contact", pressure: float = P,
            augmented: bool = False) -> tuple[ElasticityProblem, BodyContact]:
    comm = MPI.COMM_WORLD
    data = None
    if comm.rank == 0:
        data = combine({"lower": meshes.box((1, 1, 1), (2, 2, 2)),
                        "upper": moved(meshes.box((1, 1, 1), (2, 2, 2)), (0.0, 0.0, 1.0))})
    problem = ElasticityProblem(build_domain(comm, data), [("lower", LAW), ("upper", LAW)], 1)
    problem.add_dirichlet("lower_zmin", (2,), [0.0])
    for body in ("lower", "upper"):
        problem.add_dirichlet(f"{body}_xmin", (0,), [0.0])
        problem.add_dirichlet(f"{body}_ymin", (1,), [0.0])
    problem.add_traction("upper_zmax", [0.0, 0.0, -pressure])
    return problem, BodyContact(problem, "upper_zmin", "lower_zmax", k, kind=kind, augmented=augmented,
                                tolerance=1e-10)


def one_body(pressure: float = P) -> ElasticityProblem:
    data = meshes.box((1, 1, 2), (2, 2, 4)) if MPI.COMM_WORLD.rank == 0 else None
    problem = ElasticityProblem(build_domain(MPI.COMM_WORLD, data), [("all", LAW)], 1)
    problem.add_dirichlet("zmin", (2,), [0.0])
    problem.add_dirichlet("xmin", (0,), [0.0])
    problem.add_dirichlet("ymin", (1,), [0.0])
    problem.add_traction("zmax", [0.0, 0.0, -pressure])
    return problem


def top_displacement(problem: ElasticityProblem) -> float:
    """The displacement of the top (the smallest u_z: the top face moves down uniformly)."""
    uz = problem.solution.x.array.reshape(-1, 3)[:, 2]
    return float(MPI.COMM_WORLD.allreduce(uz.min(initial=np.inf), op=MPI.MIN))


def solve(problem: ElasticityProblem, steps: int = 2) -> list[int]:
    solver = NewtonSolver(problem, options=OPTIONS)
    records: list = []
    assert step_loads(solver, steps, on_step=records.append).completed
    solver.destroy()
    return [r.result.iterations for r in records if r.result.converged]


def test_stacked_blocks_against_the_closed_form_and_one_body() -> None:
    reference = one_body()
    solve(reference)
    top = top_displacement(reference)
    errors = []
    for k in (1e6, 1e7, 1e8):
        problem, contact = stacked(k)
        iterations = solve(problem)
        report = contact.report()
        assert report["force"][2] == pytest.approx(P, rel=1e-10)  # the contact force is p A
        assert abs(report["force"][0]) + abs(report["force"][1]) < 1e-9 * P
        assert report["max_penetration"] == pytest.approx(P / k, rel=1e-9)  # nodal penalty: g = -p/k
        assert report["active_points"] == 9  # the 3 x 3 nodes of the upper block's bottom
        errors.append(abs(top_displacement(problem) - top))
        assert max(iterations) <= 4, iterations  # quadratic: the pairing does not change
    assert errors[0] == pytest.approx(P / 1e6, rel=1e-8)
    assert errors[0] / errors[1] == pytest.approx(10.0, rel=1e-6)
    assert errors[1] / errors[2] == pytest.approx(10.0, rel=1e-5)


def test_augmented_lagrangian_reaches_the_one_body_answer() -> None:
    """Uzawa updates of the nodal contact pressure (k = 1e6, where the penalty alone is 2e-4 off): the penetration
    falls below the tolerance (1e-10 x size) and the answer is the one-body one to that, in a few rounds."""
    from model.solvers.contact import UzawaSolver

    reference = one_body()
    solve(reference)
    problem, contact = stacked(1e6, augmented=True)
    solver = UzawaSolver(NewtonSolver(problem, options=OPTIONS), [contact])
    assert step_loads(solver, 2).completed
    report = contact.report()
    assert report["force"][2] == pytest.approx(P, rel=1e-9)
    assert report["max_penetration"] < 1e-10 * contact.size
    assert abs(top_displacement(problem) - top_displacement(reference)) < 1e-9
    assert 2 <= solver.uzawa_iterations <= 10, solver.history
    assert float(MPI.COMM_WORLD.allreduce(contact.multiplier.x.array.max(initial=0.0), op=MPI.MAX)) \
        == pytest.approx(P, rel=1e-6)  # the multiplier is the contact pressure


def test_sliding_holds_a_block_pulled_away() -> None:
    """Sliding (k/2) g^2: the upper block pulled up by p stays on the lower one, the gap opens by p/k."""
    problem, sliding = stacked(1e7, kind="sliding", pressure=-P)
    solve(problem)
    report = sliding.report()
    assert report["force"][2] == pytest.approx(-P, rel=1e-10)  # the lower block holds the upper one down
    assert report["max_penetration"] == 0.0 and report["max_gap"] == pytest.approx(P / 1e7, rel=1e-9)
    reference = one_body(pressure=-P)
    solve(reference)
    top = float(MPI.COMM_WORLD.allreduce(reference.solution.x.array.reshape(-1, 3)[:, 2].max(initial=-np.inf),
                                         op=MPI.MAX))
    mine = float(MPI.COMM_WORLD.allreduce(problem.solution.x.array.reshape(-1, 3)[:, 2].max(initial=-np.inf),
                                          op=MPI.MAX))
    assert mine - top == pytest.approx(P / 1e7, rel=1e-7)  # the one-body stretch plus the springs' opening


def test_closest_points_on_triangles() -> None:
    """Face, edge and vertex regions against a brute-force search over the triangle."""
    rng = np.random.default_rng(2)
    triangles = rng.normal(size=(200, 3, 3))
    points = rng.normal(size=(200, 3)) * 2.0
    closest, bary = closest_points_on_triangles(points, triangles)
    assert np.allclose(bary.sum(axis=1), 1.0) and np.all(bary >= -1e-12)
    s, t = np.meshgrid(np.linspace(0, 1, 301), np.linspace(0, 1, 301))
    inside = (s + t) <= 1.0
    weights = np.c_[1 - s[inside] - t[inside], s[inside], t[inside]]
    for i in range(0, 200, 20):
        samples = weights @ triangles[i]
        brute = np.linalg.norm(samples - points[i], axis=1).min()
        assert np.linalg.norm(closest[i] - points[i]) <= brute + 1e-12
        assert np.linalg.norm(closest[i] - points[i]) >= brute - 1e-2


def test_bad_input_is_refused() -> None:
    problem, _ = stacked(1e6)
    with pytest.raises(ValueError, match="kind"):
        BodyContact(problem, "upper_zmin", "lower_zmax", 1e6, kind="glue")
    with pytest.raises(ValueError, match="k:"):
        BodyContact(problem, "upper_zmin", "lower_zmax", -1.0)
    with pytest.raises(ValueError, match="surface"):
        BodyContact(problem, "upper_zmin", "nowhere", 1e6)
