"""The thesis' per-node pressure frozen on contact (model.problem.membrane, ``freeze_on_contact``).

A clamped StVK disc (a = 1, E = 1, nu = 0.3, h = 0.01, mesh size 0.15, from a paraboloid bump of 0.3) inflated in
six steps to p = 0.012 against the rigid plane z = 0.45 (penalty k = 10), one pressure at a time:

- without contact the per-node follower residual (p_h uniform) gives the energy's equilibria to round-off;
- with freezing every node that touched carries exactly the pressure of the step it first touched at, every
  other node the last pressure, and the steps count the frozen nodes;
- on a flat frictionless obstacle the pressure of the flat contact patch goes straight into the obstacle, so
  the contact force drops by the pressure deficit of the frozen nodes, sum_frozen (p - p_i) a_i (a_i the
  deformed area lumped to the node, projected on the plane's normal), and the free membrane near the rim
  hardly moves.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.membrane import MembraneStVK
from forms.obstacles import Plane
from meshes.membrane import disc_surface
from model import compat
from model.config.membrane import load_membrane
from model.domain.distribute import build_domain
from model.errors import ConfigError
from model.problem.membrane import MembraneProblem, axis_orientation
from model.problem.membrane_contact import ObstacleContact, nodal_measure, touching_nodes
from model.solvers.membrane import inflate, inflate_to_volume

COMM = MPI.COMM_WORLD
STVK = MembraneStVK(young=1.0, nu=0.3, thickness=0.01)
PRESSURES = [float(p) for p in np.linspace(2e-3, 1.2e-2, 6)]
PLANE_HEIGHT = 0.45


def _disc(freeze: bool, plane: bool = True) -> tuple[MembraneProblem, ObstacleContact | None]:
    problem = MembraneProblem(build_domain(COMM, disc_surface(1.0, 0.15) if COMM.rank == 0 else None), STVK,
                              axis_orientation(), {"rim": (0, 1, 2)}, freeze_on_contact=freeze)
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], 0.3 * (1 - x[0] ** 2 - x[1] ** 2)]))
    contact = ObstacleContact(problem, Plane((0.0, 0.0, PLANE_HEIGHT), (0.0, 0.0, -1.0)), 10.0) if plane else None
    return problem, contact


@cache
def _against_plane(freeze: bool):
    """The disc inflated against the plane, one pressure at a time: problem, contact, steps, and the touching
    nodes (owned) after each step."""
    problem, contact = _disc(freeze)
    steps, touching = [], []
    for p in PRESSURES:
        steps += inflate(problem, [p])
        touching.append(touching_nodes(problem))
    return problem, contact, steps, touching


def _lumped_normal_area(problem: MembraneProblem) -> np.ndarray:
    """a_i = int phi_i (F t1 x F t2) . e_z dA (vertex rule): the deformed area at the owned nodes, projected on z."""
    v = ufl.TestFunction(problem.V)
    area = ufl.dot(ufl.cross(problem.F[:, 0], problem.F[:, 1]), ufl.as_vector((0.0, 0.0, 1.0)))
    vector = fem_petsc.assemble_vector(fem.form(area * v[2] * nodal_measure(problem)))
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    values = vector.array_r.reshape(-1, 3)[: problem.V.dofmap.index_map.size_local, 2].copy()
    vector.destroy()
    return values


def test_uniform_nodal_pressure_is_the_energy_residual():
    """No contact: the per-node residual dW - int p_h n . v da with p_h = p gives the equilibria of
    Pi = W - p V (the clamped disc) to round-off, in as many Newton iterations."""
    free, _ = _disc(False, plane=False)
    nodal, _ = _disc(True, plane=False)
    a, b = inflate(free, PRESSURES[:3]), inflate(nodal, PRESSURES[:3])
    assert [s.iterations for s in a] == [s.iterations for s in b]
    assert [s.frozen_nodes for s in b] == [0, 0, 0]
    difference = COMM.allreduce(float(np.abs(free.u.x.array - nodal.u.x.array).max()), op=MPI.MAX)
    assert difference < 1e-12 and free.max_component(2) > 0.4  # measured 1.1e-16 (u_z max 0.59)
    assert np.all(nodal.nodal_pressures() == PRESSURES[2])


def test_frozen_nodes_keep_the_pressure_of_their_first_contact_step():
    problem, _, steps, touching = _against_plane(True)
    first = np.full(len(touching[0]), -1)
    for k, mask in enumerate(touching):
        first[(first < 0) & mask] = k
        # the nodes that touched so far, over all ranks, are the step's frozen nodes
        assert steps[k].frozen_nodes == COMM.allreduce(int(np.sum(first >= 0)), op=MPI.SUM)
    assert np.array_equal(problem.frozen, first >= 0)
    p = problem.nodal_pressures()
    touched = first >= 0
    assert np.all(p[touched] == np.asarray(PRESSURES)[first[touched]])
    assert np.all(p[~touched] == PRESSURES[-1])
    # the contact grew over the last five steps: five frozen pressures, 42 nodes in the end (measured)
    frozen_levels = set(COMM.allreduce(sorted(set(p[touched].tolist())), op=MPI.SUM))
    assert len(frozen_levels) == 5 and steps[-1].frozen_nodes == 42
    assert [s.frozen_nodes for s in steps] == [0, 10, 23, 29, 37, 42]


def test_freezing_lowers_the_contact_force_by_the_pressure_deficit():
    """The contact force with freezing (-0.00647, measured) against without (-0.01226) at the same p = 0.012:
    their difference within 3 % of sum_frozen (p - p_i) a_i (measured 1.4 % apart: the patch's edge nodes also
    carry the membrane's tension); the free membrane (r > 0.7) the same to 0.3 % of its largest displacement
    (measured 0.2 %), the contact fraction the same to 5 % (0.254 against 0.260)."""
    frozen, contact_frozen, steps_frozen, _ = _against_plane(True)
    free, contact_free, steps_free, _ = _against_plane(False)
    f_frozen, f_free = contact_frozen.report()["force"][2], contact_free.report()["force"][2]
    assert f_free < f_frozen < 0.0
    deficit = COMM.allreduce(float(((PRESSURES[-1] - frozen.nodal_pressures()) * _lumped_normal_area(frozen))
                                   [frozen.frozen].sum()), op=MPI.SUM)
    assert f_frozen - f_free == pytest.approx(deficit, rel=3e-2)
    assert deficit > 0.4 * abs(f_free)  # the effect is not small
    n = free.V.dofmap.index_map.size_local
    X = free.V.tabulate_dof_coordinates()[:n]
    outer = np.hypot(X[:, 0], X[:, 1]) > 0.7
    u_free, u_frozen = (p.u.x.array.reshape(-1, 3)[:n][outer] for p in (free, frozen))
    difference = COMM.allreduce(float(np.abs(u_free - u_frozen).max(initial=0.0)), op=MPI.MAX)
    largest = COMM.allreduce(float(np.abs(u_free).max(initial=0.0)), op=MPI.MAX)
    assert difference < 3e-3 * largest
    assert difference > 1e-6  # the contact does reach the free part
    assert steps_frozen[-1].contact_fraction == pytest.approx(steps_free[-1].contact_fraction, rel=5e-2)


def _increasing_path(steps: list, below) -> list[float]:
    """The pressures of an increasing path to the last step: the steps that stayed below the target (``below``)
    in order of pressure, each above the last one kept, then the last step's."""
    path: list[float] = []
    for s in steps[:-1]:
        if below(s) and (not path or s.pressure > path[-1]):
            path.append(s.pressure)
    return [*path, steps[-1].pressure]


@pytest.mark.parametrize("stop", ["volume", "fraction"])
def test_frozen_inflation_to_a_target_is_an_increasing_path(stop: str) -> None:
    """inflate_to_volume with freeze_on_contact: the target volume (between the ramp's 4th and 5th steps, the
    secant) or contact fraction (0.15, the bisection) is reached, nodes are frozen on the way, and the final state
    (u, the frozen nodes and their pressures) is that of ``inflate`` along the increasing path of the steps that
    stayed below the target and the final pressure, to round-off: the trials above the target are let go."""
    _, _, ramp, _ = _against_plane(True)
    problem, _ = _disc(True)
    if stop == "volume":
        target = 0.5 * (ramp[3].volume + ramp[4].volume)
        steps = inflate_to_volume(problem, target, 2e-3)
        assert steps[-1].volume == pytest.approx(target, rel=1e-6)
        path = _increasing_path(steps, lambda s: s.volume < target)
        assert any(s.pressure > steps[-1].pressure for s in steps)  # a trial above the target was let go
    else:
        steps = inflate_to_volume(problem, 10.0, 2e-3, contact_fraction=0.15)
        assert steps[-1].contact_fraction >= 0.15
        assert all(s.contact_fraction < 0.15 for s in steps if s.pressure < steps[-1].pressure)
        path = _increasing_path(steps, lambda s: s.contact_fraction < 0.15)
    assert ramp[2].pressure < steps[-1].pressure < ramp[4].pressure
    assert steps[-1].frozen_nodes == problem.frozen_count() > 0
    replay, _ = _disc(True)
    again = inflate(replay, path)
    assert again[-1].frozen_nodes == steps[-1].frozen_nodes
    assert np.abs(replay.u.x.array - problem.u.x.array).max() <= 1e-10
    assert np.abs(replay.nodal_pressure.x.array - problem.nodal_pressure.x.array).max() <= 1e-14
    frozen = np.concatenate(COMM.allgather(problem.nodal_pressures()[problem.frozen]))
    assert np.all(np.isin(frozen, path))  # each at a pressure of the path
    assert len(set(frozen)) >= 3  # frozen at the steps of their first touch


def test_freezing_refuses_what_it_cannot_do():
    plain, _ = _disc(False, plane=False)
    with pytest.raises(ValueError, match="freeze needs a problem made with freeze_on_contact=True"):
        plain.freeze(np.zeros(plain.V.dofmap.index_map.size_local, dtype=bool))


BALLOON = Path(__file__).resolve().parent.parent / "examples" / "membrane_balloon.toml"
#: the disc against the plane of the tests above, from the balloon example's file
DISC = {"membrane.surface": "disc", "membrane.size": 0.15, "membrane.fixed": {"rim": [0, 1, 2]},
        "membrane.bump": 0.3, "output.xdmf": False, "output.vtu": False,
        "obstacle": [{"obstacle": "plane", "point": [0.0, 0.0, PLANE_HEIGHT], "normal": [0.0, 0.0, -1.0],
                      "penalty": 10.0}],
        "inflation": {"pressures": PRESSURES, "freeze_on_contact": True}}


def test_freeze_on_contact_from_the_config(shared_tmp: Path) -> None:
    """[inflation] freeze_on_contact = true: summary.json's steps count the frozen nodes as the solver does, and
    the contact force is the one of the problem solved directly."""
    from model.experiments.membrane_run import run_membrane

    summary = run_membrane(load_membrane(BALLOON, DISC), shared_tmp / "freeze", COMM)
    _, contact, steps, _ = _against_plane(True)
    assert [s["frozen_nodes"] for s in summary["steps"]] == [s.frozen_nodes for s in steps]
    assert summary["contacts"][0]["force"][2] == pytest.approx(contact.report()["force"][2], rel=1e-9)
    assert summary["config"]["inflation"]["freeze_on_contact"] is True
    plain = run_membrane(load_membrane(BALLOON, {**DISC, "inflation": {"pressures": PRESSURES[:1]}}),
                         shared_tmp / "plain", COMM)
    assert "frozen_nodes" not in plain["steps"][0]


def test_frozen_target_volume_from_the_config(shared_tmp: Path) -> None:
    """[inflation] target_volume with freeze_on_contact = true: the run reaches the volume of the solver's run
    and summary.json's steps count the frozen nodes as the solver does."""
    from model.experiments.membrane_run import run_membrane

    _, _, ramp, _ = _against_plane(True)
    target = 0.5 * (ramp[3].volume + ramp[4].volume)
    summary = run_membrane(load_membrane(BALLOON, {**DISC, "inflation": {
        "target_volume": target, "dp": 2e-3, "freeze_on_contact": True}}), shared_tmp / "freeze_volume", COMM)
    problem, _ = _disc(True)
    steps = inflate_to_volume(problem, target, 2e-3)
    assert [s["frozen_nodes"] for s in summary["steps"]] == [s.frozen_nodes for s in steps]
    assert summary["steps"][-1]["volume"] == pytest.approx(target, rel=1e-6)


@pytest.mark.parametrize(("overrides", "message"), [
    ({"inflation.freeze_on_contact": "yes"}, r"^inflation\.freeze_on_contact: "),
    ({"inflation.unit_area": 1}, r"^inflation\.unit_area: "),
    ({"obstacle": []}, r"^inflation\.freeze_on_contact: needs an \[\[obstacle\]\] or a \[\[contact\]\] to touch$"),
])
def test_freeze_on_contact_bad_input_names_the_key(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        load_membrane(BALLOON, {**DISC, **overrides})
    assert "\n" not in str(err.value)


def test_unit_area_force_counts_triangles_not_area() -> None:
    """The thesis' unit-area nodal force f_i = (p_i / 3) sum_j n_j on the flat disc at p = 1: its total is the
    number of triangles e_z (99 at size 0.3 and 346 at 0.15 on Debian 12's gmsh), where the consistent
    p int n da is the area (3.10, 3.13): the unit-area load grows like 1/h^2 under refinement."""
    totals = []
    for size in (0.3, 0.15):
        domain = build_domain(COMM, disc_surface(1.0, size) if COMM.rank == 0 else None)
        consistent = MembraneProblem(domain, STVK, axis_orientation(), {"rim": (0, 1, 2)}, freeze_on_contact=True)
        unit = MembraneProblem(domain, STVK, axis_orientation(), {"rim": (0, 1, 2)}, unit_area=True)
        for problem in (consistent, unit):
            problem.set_pressure(1.0)
        triangles = domain.mesh.topology.index_map(2).size_global
        assert np.allclose(unit.pressure_force(), [0.0, 0.0, triangles], rtol=1e-12, atol=1e-10)
        assert np.allclose(consistent.pressure_force(), [0.0, 0.0, consistent.reference_area()], rtol=1e-12,
                           atol=1e-12)
        totals.append((unit.pressure_force()[2], consistent.pressure_force()[2]))
    assert totals[1][0] > 3.0 * totals[0][0]  # halving h: about 4 times the triangles
    assert totals[1][1] == pytest.approx(totals[0][1], rel=2e-2)  # the polygon's area


@pytest.mark.parametrize("unit_area", [False, True])
def test_nodal_pressure_jacobian_is_the_residual_derivative(unit_area: bool) -> None:
    """Taylor test of UFL's Jacobian of the per-node residual at an inflated state with a non-uniform p_h
    (p_i = 1e-3 (1 + x_i^2)): |R(u + e d) - R(u) - e J d| falls as e^2 (ratio 4 per halving, to 10 %)."""
    problem, _ = _disc(True, plane=False)
    if unit_area:
        problem = MembraneProblem(problem.domain, STVK, axis_orientation(), {"rim": (0, 1, 2)}, unit_area=True)
    problem.u.interpolate(lambda x: np.vstack([0.05 * x[1], -0.03 * x[0], 0.3 * (1 - x[0] ** 2 - x[1] ** 2)]))
    problem.nodal_pressure.interpolate(lambda x: 1e-3 * (1.0 + x[0] ** 2))
    residual = fem.form(problem.residual)
    jacobian = fem.form(ufl.derivative(problem.residual, problem.u, ufl.TrialFunction(problem.V)))

    def assemble_r() -> np.ndarray:
        vector = fem_petsc.assemble_vector(residual)
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out = vector.array_r.copy()
        vector.destroy()
        return out

    rng = np.random.default_rng(3)
    direction = fem.Function(problem.V)
    direction.x.array[:] = rng.standard_normal(len(direction.x.array))
    direction.x.scatter_forward()
    A = fem_petsc.assemble_matrix(jacobian)
    A.assemble()
    Jd = A.createVecLeft()
    A.mult(compat.petsc_vector(direction), Jd)
    u0, r0, jd = problem.u.x.array.copy(), assemble_r(), Jd.array_r.copy()
    errors = []
    for eps in (1e-3, 5e-4, 2.5e-4):
        problem.u.x.array[:] = u0 + eps * direction.x.array
        errors.append(COMM.allreduce(float(np.abs(assemble_r() - r0 - eps * jd).max(initial=0.0)), op=MPI.MAX))
    problem.u.x.array[:] = u0
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.1)
