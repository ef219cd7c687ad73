"""Self-contact of one deformable body (model.problem.self_contact.SelfContact; issue 14).

A slotted (C-shaped) block (meshes.slotted_block: arms 0.4 thick, a slot 0.05 wide from x = 0.5 to 2, cells of
0.25), bottom clamped, top clamped and moved down by d. With d = 0.1 > 0.05 the slot closes (from the open end:
the spine holds it open near x = 0.5): the self-contact of the surface ``slot`` (both faces) is the two-surface
contact slot_lower on slot_upper plus slot_upper on slot_lower (the same penalty), node for node; its forces are
internal (their sum is zero, the two reactions balance) and the penetration shrinks as 1/k. With d = 0.02 the slot
stays open: no pressed node, the answer is the run without contact; a ball's surface has no pair at all.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

import forms
import meshes
from meshes.slotted import slotted_block
from model.domain import build_domain
from model.problem import ElasticityProblem
from model.problem.body_contact import BodyContact
from model.problem.measurements import reactions
from model.problem.self_contact import SelfContact
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

LAW = forms.make_law("neo_hookean", E=1e4, nu=0.3)
#: full Newton steps for both (SelfContact.potential_reason; the two-surface pairs would backtrack and stall)
OPTIONS = {"snes_rtol": 1e-11, "snes_atol": 1e-10, "snes_linesearch_type": "basic"}
ARM, SLOT = 0.4, 0.05


def slotted(closure: float) -> ElasticityProblem:
    comm = MPI.COMM_WORLD
    data = slotted_block(arm=ARM, slot=SLOT) if comm.rank == 0 else None
    problem = ElasticityProblem(build_domain(comm, data), [("body", LAW)], 1)
    problem.add_dirichlet("zmin", (0, 1, 2), [0.0, 0.0, 0.0])
    problem.add_dirichlet("zmax", (0, 1, 2), [0.0, 0.0, -closure])
    return problem


def solve(problem: ElasticityProblem, steps: int = 4) -> dict:
    solver = NewtonSolver(problem, options=OPTIONS, objective=False)
    records: list = []
    assert step_loads(solver, steps, on_step=records.append).completed
    residual = solver.unconstrained_residual()  # the couplings' master terms are not at the supports
    out = reactions(problem, residual)
    residual.destroy()
    solver.destroy()
    assert max(r.result.iterations for r in records) <= 25, [r.result.iterations for r in records]
    return out


def gathered(problem: ElasticityProblem) -> np.ndarray:
    """The solution by dof coordinates (rounded), the same order on any partition."""
    V = problem.space
    owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:owned, :3]
    u = problem.solution.x.array.reshape(-1, 3)[:owned]
    parts = MPI.COMM_WORLD.allgather(np.c_[np.round(X, 12), u])
    rows = np.concatenate(parts)
    return rows[np.lexsort(rows[:, :3].T[::-1])][:, 3:]


def side_forces(problem: ElasticityProblem, pairs: list[BodyContact]) -> tuple[np.ndarray, np.ndarray, float]:
    """The contact force on the upper arm's nodes (z > arm + slot / 2), on the whole body, and sum |r|."""
    V = problem.space
    owned = V.dofmap.index_map.size_local
    upper = V.tabulate_dof_coordinates()[:owned, 2] > ARM + 0.5 * SLOT
    r = np.zeros((owned, 3))
    for pair in pairs:
        vec = pair.contact_residual()
        r += vec.array_r.reshape(-1, 3)[:owned]
        vec.destroy()
    comm = MPI.COMM_WORLD
    return (-comm.allreduce(r[upper].sum(axis=0), op=MPI.SUM), -comm.allreduce(r.sum(axis=0), op=MPI.SUM),
            comm.allreduce(float(np.abs(r).sum()), op=MPI.SUM))


def test_self_contact_is_the_two_surface_contact_of_the_slot_faces() -> None:
    """k = 1e6: the self-contact of ``slot`` and the two pairs slot_lower-slot_upper, slot_upper-slot_lower give the
    same displacements (measured difference 0), pressed nodes, penetration and forces; the contact forces sum to
    zero (internal), the upper arm is pushed up, the reactions of top and bottom balance."""
    k = 1e6
    problem = slotted(0.1)
    pair = SelfContact(problem, "slot", k)
    react = solve(problem)
    mine = pair.report()
    reference = slotted(0.1)
    two = [BodyContact(reference, a, b, k, smallest_ties=True) for a, b in (("slot_lower", "slot_upper"),
                                                                          ("slot_upper", "slot_lower"))]
    solve(reference)
    theirs = [p.report() for p in two]
    assert np.abs(gathered(problem) - gathered(reference)).max() < 1e-10
    assert mine["active_points"] == sum(r["active_points"] for r in theirs) > 20
    assert mine["paired_points"] == 42  # every node of both faces (2 x 7 x 3) sees the other face
    assert mine["max_penetration"] == pytest.approx(max(r["max_penetration"] for r in theirs), rel=1e-9)
    assert mine["normal_force"] == pytest.approx(sum(r["normal_force"] for r in theirs), rel=1e-9)
    upper, net, total = side_forces(problem, [pair])
    upper_two, _, _ = side_forces(reference, two)
    assert np.abs(upper - upper_two).max() < 1e-8 * abs(upper[2])
    assert upper[2] > 100.0  # the lower arm pushes the upper one up
    assert np.abs(net).max() < 1e-12 * total  # internal: action = reaction
    top, bottom = react["zmax"], react["zmin"]
    assert top[2] < -100.0 and abs(top[2] + bottom[2]) < 1e-8 * abs(top[2])


def test_penetration_shrinks_as_one_over_k() -> None:
    """k = 1e5, 1e6, 1e7 (each k from the last one's answer at full load: the same answers as from rest, 1e-14, in
    a third of the Newton iterations): the largest penetration falls by nearly 10 per decade of k (by more as the
    pressure converges), and so does the change of the displacements."""
    problem = slotted(0.1)
    pair = SelfContact(problem, "slot", 1e5)
    solve(problem, steps=8)
    penetrations, solutions = [pair.report()["max_penetration"]], [gathered(problem)]
    solver = NewtonSolver(problem, options=OPTIONS, objective=False)
    for k in (1e6, 1e7):
        pair.k.value = k
        result = solver.solve()
        assert result.converged and result.iterations <= 25, result
        penetrations.append(pair.report()["max_penetration"])
        solutions.append(gathered(problem))
    solver.destroy()
    # measured 3.70e-3, 5.75e-4, 6.61e-5 (ratios 6.4, 8.7: k g = the largest nodal pressure 370, 575, 661 still
    # grows as the contact stiffens and concentrates), total normal force 464, 498, 502
    assert 5.0 < penetrations[0] / penetrations[1] < penetrations[1] / penetrations[2] < 10.5
    assert penetrations[1] / penetrations[2] > 8.0
    changes = [np.abs(solutions[i + 1] - solutions[i]).max() for i in range(2)]
    assert 5.0 < changes[0] / changes[1] < 12.0, changes


def test_an_open_slot_and_a_ball_have_no_pressed_pair() -> None:
    """The whole boundary as the self-contact surface: at rest and with d = 0.02 < 0.05 (the slot stays open) no node
    is pressed and the answer is the run without contact (the slot's faces are paired, across the open slot); a
    ball's surface (convex, 8 facets per quarter turn) pairs no node, at rest and squashed by 20 %."""
    problem = slotted(0.02)
    pair = SelfContact(problem, "surface", 1e6)
    problem.update_state()
    assert pair.report()["active_points"] == 0
    solve(problem, steps=1)
    report = pair.report()
    assert report["active_points"] == 0 and report["normal_force"] == 0.0 and report["max_penetration"] == 0.0
    assert report["paired_points"] > 0  # the slot's faces see each other (measured 24 of 42 nodes: those at the
    # block's edges have normals tilted by more than 60 degrees, those by the slot's end are within 2 rings)
    reference = slotted(0.02)
    solve(reference, steps=1)
    assert np.abs(gathered(problem) - gathered(reference)).max() < 1e-12
    comm = MPI.COMM_WORLD
    data = meshes.sphere(radius=1.0, size=0.3) if comm.rank == 0 else None
    ball = ElasticityProblem(build_domain(comm, data), [("body", LAW)], 1)
    surface = SelfContact(ball, "surface", 1e6)
    ball.update_state()
    assert surface.report()["paired_points"] == 0
    X = ball.space.tabulate_dof_coordinates()[:, :3]
    ball.solution.x.array[:] = (X * [0.1, 0.1, -0.2]).ravel()
    ball.update_state()
    report = surface.report()
    assert report["paired_points"] == 0 and report["active_points"] == 0


def test_bad_input_is_refused() -> None:
    problem = slotted(0.1)
    with pytest.raises(ValueError, match="rings"):
        SelfContact(problem, "slot", 1e6, rings=0)
    with pytest.raises(ValueError, match="reach"):
        SelfContact(problem, "slot", 1e6, reach=-1.0)
    with pytest.raises(ValueError, match="SelfContact"):
        BodyContact(problem, "slot", "slot", 1e6)
    with pytest.raises(ValueError, match="surface"):
        SelfContact(problem, "nowhere", 1e6)


def test_config_self_contact_keys() -> None:
    """[[contact]] self_contact = true: a one-line ConfigError naming the key for what does not go with it."""
    from model.config.base import ConfigError
    from model.config.contact import parse_contact

    good = parse_contact({"surface": "slot", "self_contact": True, "method": "penalty", "penalty": 1e6, "rings": 3,
                          "reach": 0.1}, "contact")
    assert good.self_contact and good.rings == 3 and good.reach == 0.1
    for extra, key in (({"master": "slot_upper"}, "master"), ({"rings": 0}, "rings"), ({"reach": -1.0}, "reach"),
                       ({"sliding": True}, "sliding"), ({"obstacle": "plane"}, "obstacle")):
        raw = {"surface": "slot", "self_contact": True, "method": "penalty", "penalty": 1e6, **extra}
        with pytest.raises(ConfigError, match=f"contact.{key}"):
            parse_contact(raw, "contact")
    with pytest.raises(ConfigError, match="contact.rings"):
        parse_contact({"surface": "slot", "master": "x", "method": "penalty", "penalty": 1e6, "rings": 2}, "contact")
    exact = {"surface": "slot", "self_contact": True, "method": "penalty", "penalty": 1e6, "exact": True}
    assert parse_contact(exact, "contact").exact
    with pytest.raises(ConfigError, match="contact.augmented: not with exact"):
        parse_contact({**exact, "augmented": True}, "contact")


def test_config_self_contact_needs_p1_and_a_known_surface() -> None:
    """The example's document: degree 2 is refused at parse time (contact[0].self_contact), an unknown surface when
    the contact is built (contact.surface), both before any solve."""
    import tomllib
    from pathlib import Path

    from model.config import parse
    from model.config.base import ConfigError
    from model.problem.contact import build_contact

    examples = Path(__file__).resolve().parents[1] / "examples"
    raw = tomllib.loads((examples / "self_contact_slot.toml").read_text())
    spec = parse(raw, examples).contacts[0]
    assert spec.self_contact and spec.surface == "slot"
    with pytest.raises(ConfigError, match=r"contact\[0\]\.self_contact: self-contact needs P1"):
        parse({**raw, "discretization": {"degree": 2}}, examples)
    problem = slotted(0.1)
    with pytest.raises(ConfigError, match="contact.surface"):
        build_contact(problem, spec.model_copy(update={"surface": "nowhere"}))
    assert isinstance(build_contact(problem, spec), SelfContact)


def test_exact_self_contact_converges_quadratically() -> None:
    """exact = True (BodyContact's exact contact: the signed distance to the paired triangle's plane, every derivative
    by UFL): a consistent potential, so backtracking on it; the closed slot's last load step converges quadratically
    (measured residuals 19, 2.9e-2, 1.4e-6, 9.8e-12: 4 iterations; the default's lagged pairing: 21, a rate of 0.36)
    to the default's answer within the penalty's scale (measured 8.2e-5 against a penetration of 5.7e-4: the default's
    R differs where the closest point is on an edge or vertex), 42 Newton iterations in all against 28."""
    answers, reports = [], []
    for exact in (False, True):
        problem = slotted(0.1)
        pair = SelfContact(problem, "slot", 1e6, exact=exact)
        assert (problem.potential_reason() is None) == exact
        solver = NewtonSolver(problem, options=OPTIONS if not exact else {"snes_rtol": 1e-11, "snes_atol": 1e-10})
        assert solver.line_search["type"] == ("bt" if exact else "basic")
        records: list = []
        assert step_loads(solver, 4, on_step=records.append).completed
        solver.destroy()
        answers.append(gathered(problem))
        reports.append(pair.report())
    assert records[-1].result.iterations <= 5, [r.result.iterations for r in records]
    default, exact = reports
    assert exact["active_points"] == default["active_points"] > 20
    assert exact["max_penetration"] == pytest.approx(default["max_penetration"], rel=1e-2)
    assert exact["normal_force"] == pytest.approx(default["normal_force"], rel=1e-3)
    assert np.abs(answers[1] - answers[0]).max() < 0.2 * default["max_penetration"]


def test_ties_go_to_the_smallest_triangle_for_any_numbering() -> None:
    """closest_candidates: the closest candidate of each point, ties (equal distances) to the triangle with the
    smallest sorted global vertex triple; global numbers beyond 2^21 (where the arithmetic key would overflow int64)
    give the same choice through the triples' rank."""
    from model.problem.self_contact import closest_candidates

    rng = np.random.default_rng(3)
    g_tri = np.array([rng.choice(50, 3, replace=False) for _ in range(40)], dtype=np.int64)
    rows = rng.integers(0, 6, 200)
    cols = rng.integers(0, 40, 200)
    d = rng.choice([0.5, 1.0, 2.0], 200)  # many exact ties
    chosen = closest_candidates(6, rows, cols, d, g_tri)
    for i in range(6):
        mine = rows == i
        if mine.any():
            best = d[mine].min()
            tied = cols[mine & (d == best)]
            smallest = min(tied, key=lambda c: tuple(np.sort(g_tri[c])))
            assert set(cols[chosen & mine]) == {smallest}
    large = g_tri * 1_000_003 + 7  # the same order of the sorted triples, numbers up to 5e7 > 2^21
    assert np.array_equal(closest_candidates(6, rows, cols, d, large), chosen)
