"""Contact with rigid obstacles (model.problem.contact, model.solvers.contact, forms.obstacles): penalty,
augmented Lagrangian (Uzawa), VI.

Closed form (homogeneous block): a unit cube, neo-Hookean, xmin/ymin on sliders, zmin resting on a
rigid plane z = 0 that moves up by delta (a transform table) against zmax held at u_z = 0: uniaxial
compression with free lateral faces, axial stretch l3, lateral stretch lt from P11(lt, lt, l3) = 0.
Exact contact (VI, Uzawa): l3 = 1 - delta, force -P33 (reference area 1). Penalty k: the plane
pushes with p = k (delta - (1 - l3)) = -P33(l3) (solved with scipy). Stresses come from
tests/closed_form.py (complex-step derivatives of psi in principal stretches), not from UFL.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import ufl
from closed_form import principal_stress
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from scipy.optimize import brentq

import forms
import meshes
from forms.motions import TransformTable, axis_angle
from forms.obstacles import Capsule, Plane, Sphere, gap, penalty_energy
from model import compat
from model.config.contact import parse_contact
from model.domain import build_domain
from model.errors import ConfigError
from model.problem import ElasticityProblem
from model.problem.contact import AugmentedLagrangianContact, PenaltyContact, VIContact, build_contact, contact_report
from model.solvers.contact import DIVERGED_UZAWA_MAX_IT, make_contact_solver
from model.solvers.loadstepping import step_loads

log = logging.getLogger(__name__)

LAW = {"E": 1.0e4, "nu": 0.3}
DELTA = 0.1


# --- closed forms -----------------------------------------------------------------------------------

def lateral_stretch(l3: float) -> float:
    """lt with P11(lt, lt, l3) = 0 (free lateral faces)."""
    return brentq(lambda lt: principal_stress("neo_hookean", np.array([lt, lt, l3]), LAW)[0], 0.5, 2.0, xtol=1e-15)


def axial_stress(l3: float) -> float:
    """P33 of uniaxial stress at axial stretch l3 (nominal, per reference area)."""
    lt = lateral_stretch(l3)
    return float(principal_stress("neo_hookean", np.array([lt, lt, l3]), LAW)[2])


def exact_force() -> float:
    """Force of a rigid plane that pushes the block's face up by DELTA exactly."""
    return -axial_stress(1.0 - DELTA)


def penalty_force(k: float) -> float:
    """Force of the penalty plane: -P33(l3) = k (DELTA - (1 - l3)), solved for l3 in [1 - DELTA, 1]."""
    l3 = brentq(lambda l3: -axial_stress(l3) - k * (DELTA - 1.0 + l3), 1.0 - DELTA, 1.0, xtol=1e-15)
    return k * (DELTA - 1.0 + l3)


# --- set-up -----------------------------------------------------------------------------------------

def block(cells: int = 2, down: bool = False) -> tuple[ElasticityProblem, TransformTable, Plane]:
    """The unit cube on sliders; the plane under zmin moving up by DELTA (or, ``down``, over zmax moving down)."""
    comm = MPI.COMM_WORLD
    data = meshes.box((1.0, 1.0, 1.0), (cells, cells, cells)) if comm.rank == 0 else None
    problem = ElasticityProblem(build_domain(comm, data), [("all", forms.make_law("neo_hookean", **LAW))], 1, 2)
    problem.add_dirichlet("xmin", [0], [0.0])
    problem.add_dirichlet("ymin", [1], [0.0])
    problem.add_dirichlet("zmin" if down else "zmax", [2], [0.0])
    sign = -1.0 if down else 1.0
    motion = TransformTable([0.0, 1.0], [[0.0, 0.0, 0.0]] * 2, [[0.0, 0.0, 0.0], [0.0, 0.0, sign * DELTA]])
    plane = Plane((0.0, 0.0, 1.0 if down else 0.0), (0.0, 0.0, sign))
    return problem, motion, plane


def solve(problem: ElasticityProblem, contact, steps: int = 2) -> object:
    solver = make_contact_solver(problem, [contact])
    assert step_loads(solver, steps)
    return solver


def lateral_from_solution(problem: ElasticityProblem) -> float:
    """1 + u_x at the nodes of x = 1 (all equal in the homogeneous state), from the solution vector."""
    x = problem.space.tabulate_dof_coordinates()
    u = problem.solution.x.array.reshape(-1, 3)
    owned = problem.space.dofmap.index_map.size_local
    at = np.isclose(x[:owned, 0], 1.0)
    return 1.0 + MPI.COMM_WORLD.allreduce(float(u[:owned][at, 0].max(initial=-np.inf)), op=MPI.MAX)


# --- obstacles ----------------------------------------------------------------------------------------

def test_signed_distances_numpy_and_ufl_agree() -> None:
    """d(y) at known points (numpy), and the UFL gap with a rigid motion equals numpy's at the mesh nodes."""
    plane, ball = Plane((0, 0, 1), (0, 0, 2)), Sphere((1, 0, 0), 0.5)
    capsule = Capsule((0, 0, 0), (0, 0, 2), 0.25)
    y = np.array([[0.0, 0.0, 3.0], [1.0, 0.0, 0.2], [0.0, 0.5, 1.0], [0.0, 0.0, -1.0]])
    np.testing.assert_allclose(plane.distance(y), [2.0, -0.8, 0.0, -2.0])
    np.testing.assert_allclose(ball.distance(y), np.linalg.norm(y - [1, 0, 0], axis=1) - 0.5)
    np.testing.assert_allclose(capsule.distance(y), [1.0 - 0.25, 1.0 - 0.25, 0.25, 0.75])
    with pytest.raises(ValueError, match="normal"):
        Plane((0, 0, 0), (0, 0, 0))

    comm = MPI.COMM_WORLD
    data = meshes.box((1.0, 1.0, 1.0), (2, 2, 2)) if comm.rank == 0 else None
    msh = build_domain(comm, data).mesh
    V = compat.function_space(msh, "Lagrange", 1)
    Q, c = axis_angle((1, 1, 0), 30.0), np.array([0.1, -0.2, 0.3])
    Qc = fem.Constant(msh, PETSc.ScalarType(Q))
    cc = fem.Constant(msh, PETSc.ScalarType(c))
    x = ufl.SpatialCoordinate(msh)
    f = fem.Function(V)
    points = V.tabulate_dof_coordinates()
    for obstacle in (plane, ball, capsule):
        f.interpolate(fem.Expression(gap(obstacle, x, Qc, cc), V.element.interpolation_points()))
        expected = obstacle.distance((points - c) @ Q)  # y = Q^T (x - c) as rows
        np.testing.assert_allclose(f.x.array, expected, atol=1e-13)
        np.testing.assert_allclose(gap(obstacle, points, Q, c), expected, atol=1e-14)


def test_penalty_energy_tangent_at_zero_gap() -> None:
    """(k/2) min(g, 0)^2: dpsi/dg = k min(g, 0); d2psi/dg2 = k for g <= 0 (including g = 0), 0 for g > 0."""
    comm = MPI.COMM_WORLD
    data = meshes.box((1.0, 1.0, 1.0), (1, 1, 1)) if comm.rank == 0 else None
    msh = build_domain(comm, data).mesh
    g0 = fem.Constant(msh, PETSc.ScalarType(0.0))
    g = ufl.variable(g0)
    k = 7.0
    psi = penalty_energy(g, k)
    dpsi = ufl.diff(psi, g)
    d2psi = ufl.diff(dpsi, g)
    forms_ = [fem.form(e * ufl.dx(domain=msh, metadata={"quadrature_degree": 1})) for e in (psi, dpsi, d2psi)]
    for value, expected in ((-0.5, (0.875, -3.5, 7.0)), (0.0, (0.0, 0.0, 7.0)), (0.5, (0.0, 0.0, 0.0))):
        g0.value = value
        got = [comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM) for f in forms_]  # unit volume
        np.testing.assert_allclose(got, expected, atol=1e-14)


# --- homogeneous block ---------------------------------------------------------------------------------

@pytest.mark.parametrize("down", [False, True], ids=["plane_below", "plane_above"])
def test_vi_block_matches_closed_form(down: bool) -> None:
    """VI (lower bounds with the plane below, upper bounds above): force -P33(1 - delta), exact stretches."""
    problem, motion, plane = block(down=down)
    contact = VIContact(problem, "zmax" if down else "zmin", plane, motion)
    solver = solve(problem, contact)
    report = contact.contact_report()
    sign = -1.0 if down else 1.0
    expected = exact_force()
    np.testing.assert_allclose(report["force"][2], sign * expected, rtol=1e-8)
    assert report["force"][:2] == [0.0, 0.0]
    assert report["max_penetration"] <= 1e-12
    assert report["active_points"] == 9  # the 3 x 3 nodes of the face
    lt = lateral_from_solution(problem)
    np.testing.assert_allclose(lt, lateral_stretch(1.0 - DELTA), rtol=1e-8)
    # the pressure: nominal -P33, Cauchy -sigma33 = F / (deformed area lt^2)
    lt_exact = lateral_stretch(1.0 - DELTA)
    np.testing.assert_allclose(abs(report["force"][2]) / lt**2, expected / lt_exact**2, rtol=1e-8)
    assert report == contact_report([contact])
    solver.destroy()


def test_vi_block_with_taylor_hood() -> None:
    """The mixed formulation (P2/P1): the bounds act on the displacement block only; same closed form."""
    comm = MPI.COMM_WORLD
    data = meshes.box((1.0, 1.0, 1.0), (1, 1, 1)) if comm.rank == 0 else None
    law = forms.make_law("neo_hookean", **LAW)
    problem = ElasticityProblem(build_domain(comm, data), [("all", law)], 2, 4, "mixed")
    for face, comp in (("xmin", 0), ("ymin", 1), ("zmax", 2)):
        problem.add_dirichlet(face, [comp], [0.0])
    _, motion, plane = block(1)
    contact = VIContact(problem, "zmin", plane, motion)
    solver = solve(problem, contact)
    report = contact.contact_report()
    np.testing.assert_allclose(report["force"][2], exact_force(), rtol=1e-8)
    assert report["active_points"] == 9 and report["max_penetration"] <= 1e-12  # P2: 3 x 3 nodes
    solver.destroy()


def test_penalty_block_matches_closed_form_and_converges_like_one_over_k() -> None:
    """Penalty force = the closed form for each k; its error against exact contact falls like 1/k (order ~1)."""
    exact = exact_force()
    errors = []
    ks = (1.0e6, 1.0e7, 1.0e8)
    for k in ks:
        problem, motion, plane = block()
        contact = PenaltyContact(problem, "zmin", plane, k, motion)
        solver = solve(problem, contact)
        report = contact.contact_report()
        expected = penalty_force(k)
        np.testing.assert_allclose(report["force"][2], expected, rtol=1e-8)
        np.testing.assert_allclose(report["force"][:2], [0.0, 0.0], atol=1e-8 * expected)
        np.testing.assert_allclose(report["max_penetration"], expected / k, rtol=1e-7)  # p = k |g|
        assert report["active_points"] == 9
        errors.append(abs(report["force"][2] - exact) / exact)
        solver.destroy()
    orders = np.log(np.array(errors[:-1]) / np.array(errors[1:])) / np.log(np.array(ks[1:]) / np.array(ks[:-1]))
    log.info("penalty: relative force errors %s, observed orders %s", errors, orders)
    assert np.all(np.abs(orders - 1.0) < 0.05), orders
    assert errors[-1] < 1e-3  # VI and penalty agree as k grows


def test_uzawa_reaches_the_tolerance_and_the_exact_pressure() -> None:
    """Augmented Lagrangian (k = 1e5, 10 times E): penetration <= 1e-8 of the body size; multipliers = -P33."""
    problem, motion, plane = block()
    contact = AugmentedLagrangianContact(problem, "zmin", plane, 1.0e5, motion, tolerance=1e-8)
    solver = make_contact_solver(problem, [contact])
    rounds = []
    assert step_loads(solver, 2, on_step=lambda r: rounds.append(solver.uzawa_iterations))
    report = contact.contact_report()
    size = math.sqrt(3.0)
    assert report["max_penetration"] <= 1e-8 * size
    expected = exact_force()
    np.testing.assert_allclose(report["force"][2], expected, rtol=1e-6)
    pressures = contact.multiplier.x.array[contact.nodes.dofs]
    np.testing.assert_allclose(pressures, expected, rtol=1e-6)  # nominal pressure at every node
    assert report["active_points"] == 9
    log.info("Uzawa rounds per load step: %s; residual history of the last: %s", rounds, solver.history)
    assert all(2 <= r <= 15 for r in rounds), rounds
    solver.destroy()


def test_uzawa_gives_up_after_max_uzawa() -> None:
    problem, motion, plane = block()
    contact = AugmentedLagrangianContact(problem, "zmin", plane, 1.0e4, motion, tolerance=1e-12, max_uzawa=2)
    solver = make_contact_solver(problem, [contact])
    problem.set_load_factor(1.0)
    result = solver.solve()
    assert not result.converged and result.reason == DIVERGED_UZAWA_MAX_IT
    assert result.reason_name == "DIVERGED_UZAWA_MAX_IT"
    assert np.all(contact.multiplier.x.array == 0.0)  # restored to the start of the solve
    solver.destroy()


# --- VI on a curved body -----------------------------------------------------------------------------

def octant(size: float, pole_size: float, pole_radius: float, degree: int) -> ElasticityProblem:
    """An octant of the unit sphere (symmetry faces on sliders, the equator held at u_z = 0)."""
    from meshes.sphere import sphere

    comm = MPI.COMM_WORLD
    data = sphere(1.0, size, True, pole_size, pole_radius) if comm.rank == 0 else None
    law = forms.make_law("neo_hookean", **LAW)
    problem = ElasticityProblem(build_domain(comm, data), [("all", law)], degree, 2 * degree)
    problem.add_dirichlet("xmin", [0], [0.0])
    problem.add_dirichlet("ymin", [1], [0.0])
    problem.add_dirichlet("zmax", [2], [0.0])
    return problem


def lowest_point_above(problem: ElasticityProblem, height: float) -> float:
    """min over all nodes of z + u_z - height (all ranks), straight from the solution vector."""
    x = problem.space.tabulate_dof_coordinates()
    u = problem.solution.x.array.reshape(-1, 3)
    return MPI.COMM_WORLD.allreduce(float(np.min(x[:, 2] + u[:, 2] - height)), op=MPI.MIN)


def test_vi_sphere_never_penetrates_the_plane() -> None:
    """A sphere pushed by a rising plane (VI): no node below the plane by more than 1e-10; a contact patch forms."""
    problem = octant(0.3, 0.02, 0.1, 1)
    d = 0.01
    motion = TransformTable([0.0, 1.0], [[0.0, 0.0, 0.0]] * 2, [[0.0, 0.0, 0.0], [0.0, 0.0, d]])
    contact = VIContact(problem, "surface", Plane((0.0, 0.0, -1.0), (0.0, 0.0, 1.0)), motion)
    solver = solve(problem, contact, steps=2)
    assert lowest_point_above(problem, -1.0 + d) >= -1e-10
    report = contact.contact_report()
    assert report["max_penetration"] <= 1e-10
    assert report["active_points"] > 3 and report["force"][2] > 0.0
    solver.destroy()


HERTZ_D = 1.0e-3


def hertz_error(pole_size: float) -> float:
    """(F - F_Hertz) / F_Hertz for the unit sphere squeezed between plates by HERTZ_D each (VI, P2).

    An octant with symmetry conditions (the equator plane of a sphere between two plates stays
    plane, u_z = 0 there); F = 4 times the octant's force; F_Hertz = (4/3) E* R^(1/2) d^(3/2),
    E* = E / (1 - nu^2) for a rigid plane. The mesh is refined to ``pole_size`` within 0.03 of the
    pole (the contact radius is a = (R d)^(1/2) = 0.032).
    """
    d, R = HERTZ_D, 1.0
    e_star = LAW["E"] / (1.0 - LAW["nu"] ** 2)
    hertz = 4.0 / 3.0 * e_star * math.sqrt(R) * d**1.5
    problem = octant(0.25, pole_size, 0.03, 2)
    motion = TransformTable([0.0, 1.0], [[0.0, 0.0, 0.0]] * 2, [[0.0, 0.0, 0.0], [0.0, 0.0, d]])
    contact = VIContact(problem, "surface", Plane((0.0, 0.0, -R), (0.0, 0.0, 1.0)), motion)
    solver = make_contact_solver(problem, [contact])
    attempts = []
    assert step_loads(solver, 1, on_step=attempts.append)
    assert [a.result.converged for a in attempts] == [True]  # one step: the VI predictor carries the interior
    report = contact.contact_report()
    force = 4.0 * report["force"][2]
    assert lowest_point_above(problem, -R + d) >= -1e-10
    log.info("Hertz: pole size %g, %d dofs, %d nodes in contact: F = %.6g, Hertz %.6g, error %+.3f %%", pole_size,
             problem.space.dofmap.index_map.size_global * 3, report["active_points"], force, hertz,
             100 * (force - hertz) / hertz)
    solver.destroy()
    return (force - hertz) / hertz


def test_hertz_sphere_on_rigid_plane() -> None:
    """Force against indentation d = 1e-3 R within 5 % of Hertz on the finest test mesh (8 P2 elements across a)."""
    error = hertz_error(0.004)
    assert abs(error) < 0.05, error


@pytest.mark.slow
def test_hertz_mesh_refinement() -> None:
    """Pole sizes 0.008, 0.004, 0.002: within 5 % of Hertz, and the two finest within 0.5 % of each other
    (what remains is the model error: a finite sphere is stiffer than Hertz's half-spaces, by ~ (d/R)^(1/2))."""
    errors = [hertz_error(h) for h in (0.008, 0.004, 0.002)]
    assert all(abs(e) < 0.05 for e in errors), errors
    assert abs(errors[2] - errors[1]) < 0.005, errors


# --- errors -----------------------------------------------------------------------------------------------

def test_vi_needs_an_axis_normal() -> None:
    problem, motion, _ = block()
    with pytest.raises(ValueError, match="normal"):
        VIContact(problem, "zmin", Plane((0.0, 0.0, 0.0), (0.0, 0.1, 1.0)), motion)
    with pytest.raises(ValueError, match="plane"):
        VIContact(problem, "zmin", Sphere((0.0, 0.0, -1.0), 1.0), motion)  # type: ignore[arg-type]
    # a motion that tilts the plane: refused when the bounds are set
    tilt = TransformTable([0.0, 1.0], [[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]], [[0.0, 0.0, 0.0]] * 2)
    contact = VIContact(problem, "zmin", Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), tilt)
    solver = make_contact_solver(problem, [contact])
    problem.set_load_factor(0.5)
    with pytest.raises(ValueError, match="normal"):
        solver.solve()
    solver.destroy()
    with pytest.raises(ConfigError, match=r"^solver\.petsc_options\.snes_type: "):
        make_contact_solver(problem, [contact], {"snes_type": "newtonls"})


BASE = {"surface": "zmin", "obstacle": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0],
        "method": "vi"}
PENALTY = {**BASE, "method": "penalty", "penalty": 1.0e6}


@pytest.mark.parametrize("raw, key", [
    ({**BASE, "colour": "red"}, "contact[0].colour"),
    ({k: v for k, v in BASE.items() if k != "surface"}, "contact[0].surface"),
    ({**BASE, "surface": 3}, "contact[0].surface"),
    ({**BASE, "obstacle": "cube"}, "contact[0].obstacle"),
    ({k: v for k, v in BASE.items() if k != "obstacle"}, "contact[0].obstacle"),
    ({k: v for k, v in BASE.items() if k != "normal"}, "contact[0].normal"),
    ({**BASE, "normal": [0.0, 0.0, 0.0]}, "contact[0].normal"),
    ({**BASE, "normal": [0.0, 1.0, 1.0]}, "contact[0].normal"),
    ({**BASE, "normal": [0.0, 1.0]}, "contact[0].normal"),
    ({**BASE, "point": [0.0, "a", 0.0]}, "contact[0].point[1]"),
    ({**BASE, "method": "lagrange"}, "contact[0].method"),
    ({k: v for k, v in BASE.items() if k != "method"}, "contact[0].method"),
    ({**BASE, "penalty": 1.0e6}, "contact[0].penalty"),
    ({**PENALTY, "penalty": 0.0}, "contact[0].penalty"),
    ({**PENALTY, "penalty": -1.0}, "contact[0].penalty"),
    ({**PENALTY, "penalty": "big"}, "contact[0].penalty"),
    ({k: v for k, v in PENALTY.items() if k != "penalty"}, "contact[0].penalty"),
    ({**PENALTY, "augmented": "yes"}, "contact[0].augmented"),
    ({**PENALTY, "tolerance": 1e-6}, "contact[0].tolerance"),
    ({**PENALTY, "augmented": True, "tolerance": 0.0}, "contact[0].tolerance"),
    ({**PENALTY, "augmented": True, "max_uzawa": 0}, "contact[0].max_uzawa"),
    ({**PENALTY, "augmented": True, "max_uzawa": 2.5}, "contact[0].max_uzawa"),
    ({**PENALTY, "quadrature_degree": 0}, "contact[0].quadrature_degree"),
    ({**PENALTY, "obstacle": "sphere", "radius": 1.0}, "contact[0].point"),
    ({"surface": "zmin", "obstacle": "sphere", "centre": [0, 0, 0], "method": "penalty", "penalty": 1.0},
     "contact[0].radius"),
    ({"surface": "zmin", "obstacle": "sphere", "centre": [0, 0, 0], "radius": -1.0, "method": "penalty",
      "penalty": 1.0}, "contact[0].radius"),
    ({"surface": "zmin", "obstacle": "sphere", "centre": [0, 0, 0], "radius": 1.0, "method": "vi"},
     "contact[0].method"),
    ({"surface": "zmin", "obstacle": "capsule", "a": [0, 0, 0], "b": [0, 0, 0], "radius": 1.0, "method": "penalty",
      "penalty": 1.0}, "contact[0].b"),
    ({"surface": "zmin", "obstacle": "capsule", "a": [0, 0, 0], "radius": 1.0, "method": "penalty",
      "penalty": 1.0}, "contact[0].b"),
])
def test_parse_contact_errors_name_the_key(raw: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_contact(raw, "contact[0]")
    assert str(err.value).startswith(f"{key}: "), str(err.value)
    assert "\n" not in str(err.value)


def test_parse_and_build_contact() -> None:
    spec = parse_contact(BASE, "contact[0]")
    assert spec.method == "vi" and spec.obstacle == Plane((0, 0, 0), (0, 0, 1))
    spec = parse_contact({**PENALTY, "augmented": True, "tolerance": 1e-6, "max_uzawa": 7}, "contact[1]")
    assert (spec.penalty, spec.augmented, spec.tolerance, spec.max_uzawa) == (1.0e6, True, 1e-6, 7)
    capsule = parse_contact({"surface": "s", "obstacle": "capsule", "a": [0, 0, 0], "b": [0, 0, 1], "radius": 0.5,
                             "method": "penalty", "penalty": 10}, "c")
    assert capsule.obstacle == Capsule((0, 0, 0), (0, 0, 1), 0.5)
    problem, _, _ = block()
    assert isinstance(build_contact(problem, parse_contact(BASE, "contact[0]")), VIContact)
    assert isinstance(build_contact(problem, spec), AugmentedLagrangianContact)
    assert type(build_contact(problem, parse_contact(PENALTY, "contact[0]"))) is PenaltyContact
    with pytest.raises(ConfigError, match=r"^contact\[2\]\.surface: no boundary named 'floor'"):
        build_contact(problem, parse_contact({**BASE, "surface": "floor"}, "contact[2]"), key="contact[2]")
