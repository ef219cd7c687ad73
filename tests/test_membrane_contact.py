"""Membrane contact (issue 14 item 4, thesis ch. 3.3.3): bones, the contact-fraction stop of the inflation."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from forms.membrane import MembraneNeoHookean, MembraneStVK
from forms.obstacles import Capsule, Sphere
from meshes.membrane import disc_surface, enclosed_volume, extrude, smooth_rest_shape, sphere_octant, vertex_normals
from model.domain.distribute import build_domain
from model.problem.membrane import MembraneProblem, axis_orientation, balloon_pressure, radial_orientation
from model.problem.membrane_contact import ObstacleContact, contact_fraction
from model.solvers.membrane import inflate, inflate_to_volume

COMM = MPI.COMM_WORLD
STVK = MembraneStVK(young=1.0, nu=0.3, thickness=0.01)
NEO = MembraneNeoHookean(mu=1.0, thickness=0.01)
OCTANT_FIXED = {"x0": (0,), "y0": (1,), "z0": (2,)}
R_CAVITY = 1.1


def _domain(generator, *args):
    return build_domain(COMM, generator(*args) if COMM.rank == 0 else None)


def _balloon_in_cavity(k: float = 1.0):
    problem = MembraneProblem(_domain(sphere_octant, 1.0, 0.2), STVK, radial_orientation(), OCTANT_FIXED)
    contact = ObstacleContact(problem, Sphere((0.0, 0.0, 0.0), R_CAVITY), k, inside=True)
    return problem, contact


def penetration(p: float, k: float) -> float:
    """delta = lambda^2 (p - p_m(lambda)) / k, lambda = (R_c + delta) / R (R = 1), by fixed-point iteration."""
    delta = 0.0
    for _ in range(60):
        lam = R_CAVITY + delta
        delta = lam**2 * (p - float(balloon_pressure(STVK, 1.0, lam))) / k
    return max(delta, 0.0)


def test_balloon_in_a_rigid_cavity():
    """Unit balloon (StVK octant) in a concentric rigid sphere R_c = 1.1: free and on p(lambda) before contact;
    after it the radius stays at R_c + delta with delta = lambda^2 (p - p_m(lambda))/k, the contact fraction is
    1 and the contact force on the octant is -k delta (pi R^2/4) per axis."""
    k = 1.0
    problem, contact = _balloon_in_cavity(k)
    V0 = problem.volume()
    p_touch = float(balloon_pressure(STVK, 1.0, R_CAVITY))
    for lam in (1.04, 1.08):
        step = inflate(problem, [float(balloon_pressure(STVK, 1.0, lam))])[0]
        stretch = (step.volume / V0) ** (1.0 / 3.0)
        assert abs(stretch / lam - 1.0) < 2e-3  # the free balloon's closed form (pressure error 0.4 %)
        report = contact.report()
        assert report["contact_fraction"] == 0.0 and report["max_penetration"] == 0.0 and step.contact_fraction == 0
        assert np.allclose(report["force"], 0.0)
    for factor in (1.5, 3.0):
        p = factor * p_touch
        step = inflate(problem, [p])[0]
        report = contact.report()
        delta = penetration(p, k)
        assert report["contact_fraction"] == 1.0 and step.contact_fraction == 1.0
        # the area-weighted mean penetration of the nodes, against the closed form
        x = contact.positions()
        pen = np.linalg.norm(x, axis=1) - R_CAVITY
        mean = COMM.allreduce(float(pen @ contact.lumped_area), op=MPI.SUM) / \
            COMM.allreduce(float(contact.lumped_area.sum()), op=MPI.SUM)
        assert mean == pytest.approx(delta, rel=0.02)
        assert delta <= report["max_penetration"] < 1.4 * delta
        assert np.allclose(report["force"], -k * delta * np.pi / 4, rtol=0.03)
    # penetration ~ 1/k: ten times stiffer, a tenth of the penetration
    problem, contact = _balloon_in_cavity(10.0)
    inflate(problem, [1.5 * p_touch])
    x = contact.positions()
    pen = COMM.allreduce(float((np.linalg.norm(x, axis=1) - R_CAVITY) @ contact.lumped_area), op=MPI.SUM) / \
        COMM.allreduce(float(contact.lumped_area.sum()), op=MPI.SUM)
    assert pen == pytest.approx(penetration(1.5 * p_touch, 10.0), rel=0.02)


def test_inflation_stops_at_the_contact_fraction_of_the_cavity():
    """The balloon touches the cavity everywhere at once, at p_m(R_c/R): the contact-fraction stop (0.5)
    finds that pressure (to the balloon's 0.4 % discretisation error) long before the target volume."""
    problem, _ = _balloon_in_cavity(1.0)
    p_touch = float(balloon_pressure(STVK, 1.0, R_CAVITY))
    steps = inflate_to_volume(problem, target_volume=10.0, dp=0.3 * p_touch, contact_fraction=0.5)
    assert steps[-1].contact_fraction >= 0.5
    assert steps[-1].pressure == pytest.approx(p_touch, rel=0.01)
    assert all(s.contact_fraction < 0.5 for s in steps if s.pressure < steps[-1].pressure)


def test_inflation_stops_at_the_contact_fraction_of_a_bone():
    """A clamped disc inflated towards a capsule bone along x above it: the fraction grows with p; the stop is
    the smallest pressure (to 1e-3 p) at which 12 % of the area touches, and the volume target is not reached."""
    problem = MembraneProblem(_domain(disc_surface, 1.0, 0.15), STVK, axis_orientation(), {"rim": (0, 1, 2)})
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], 0.3 * (1 - x[0] ** 2 - x[1] ** 2)]))
    contact = ObstacleContact(problem, Capsule((-2.0, 0.0, 0.7), (2.0, 0.0, 0.7), 0.4), k=10.0)
    with pytest.raises(ValueError, match="contact_fraction"):
        inflate_to_volume(problem, 1.0, 1e-3, contact_fraction=1.5)
    steps = inflate_to_volume(problem, target_volume=5.0, dp=1e-3, contact_fraction=0.12)
    last = steps[-1]
    assert last.contact_fraction >= 0.12 and last.volume < 5.0
    assert contact.report()["contact_fraction"] == last.contact_fraction == contact_fraction(problem)
    assert contact.report()["force"][2] < 0.0  # the bone above pushes the membrane down
    below = [s for s in steps if s.pressure < last.pressure]
    assert max(s.contact_fraction for s in below) < 0.12
    assert max(s.pressure for s in below) > last.pressure * (1 - 2e-3)


def test_contact_input_errors():
    problem = MembraneProblem(_domain(disc_surface, 1.0, 0.3), NEO, axis_orientation(), {"rim": (0, 1, 2)})
    with pytest.raises(ValueError, match="contact_fraction needs a contact"):
        inflate_to_volume(problem, 1.0, 1e-3, contact_fraction=0.5)
    with pytest.raises(ValueError, match="k must be"):
        ObstacleContact(problem, Sphere((0.0, 0.0, 1.0), 0.2), k=-1.0)


def test_extrusion_moves_the_free_vertices_by_the_offset_along_their_normals():
    """Thesis ch. 3.3.3: every vertex but the attachment moved by the offset along its vertex normal."""
    disc = disc_surface(1.0, 0.2)
    rim = np.unique(disc.facets)
    out = extrude(disc, 0.03, rim)
    free = np.setdiff1d(np.arange(len(disc.points)), rim)
    assert np.array_equal(out.points[rim], disc.points[rim])
    assert np.allclose(out.points[free, 2], 0.03, atol=1e-15)  # the flat patch: straight up
    assert np.array_equal(out.points[:, :2], disc.points[:, :2])
    octant = sphere_octant(1.0, 0.2)
    edge = np.unique(octant.facets)
    out = extrude(octant, 0.05, edge)
    free = np.setdiff1d(np.arange(len(octant.points)), edge)
    step = out.points[free] - octant.points[free]
    assert np.allclose(np.linalg.norm(step, axis=1), 0.05, rtol=1e-12)
    assert np.allclose(np.cross(step, vertex_normals(octant.points, octant.cells)[free]), 0.0, atol=1e-15)
    assert np.allclose(np.linalg.norm(out.points[free], axis=1), 1.05, atol=2e-3)  # ~radial on the sphere
    with pytest.raises(ValueError, match="offset"):
        extrude(disc, -0.1, rim)


def test_smoothing_keeps_the_border_and_stops_at_the_volume():
    """Alternated Laplacian smoothing and tangential relaxation of a rough dome: the rim does not move, the
    volume decreases at every iteration and stops at the first one <= the estimate, the roughness drops."""
    disc = disc_surface(1.0, 0.1)
    rim = np.unique(disc.facets)
    x = disc.points.copy()
    r2 = x[:, 0] ** 2 + x[:, 1] ** 2
    x[:, 2] = (1 - r2) * (0.5 + 0.05 * np.sin(9 * x[:, 0]) * np.cos(7 * x[:, 1]))
    V0 = enclosed_volume(x, disc.cells)
    shape = smooth_rest_shape(x, disc.cells, rim, 0.7 * V0)
    assert np.array_equal(shape.points[rim], x[rim])
    assert np.all(np.diff(shape.volumes) < 0) and shape.volumes[0] == pytest.approx(V0)
    assert shape.volumes[-1] <= 0.7 * V0 < shape.volumes[-2]
    assert shape.volumes[-1] == pytest.approx(enclosed_volume(shape.points, disc.cells), rel=1e-14)
    free = np.setdiff1d(np.arange(len(x)), rim)

    def roughness(p):
        return np.linalg.norm((smoothing_laplacian(p, disc.cells) - p)[free][:, 2])

    assert roughness(shape.points) < 0.5 * roughness(x)
    with pytest.raises(ValueError, match="volume"):
        smooth_rest_shape(x, disc.cells, rim, 2 * V0)


def smoothing_laplacian(points, cells):
    """The mean of each node's edge neighbours (the umbrella operator's c_i)."""
    from meshes.membrane import _neighbour_means

    return _neighbour_means(points, cells)


def test_two_phase_inflation_against_a_bone():
    """The thesis' workflow: extrusion inflated to the first volume, rest shape smoothed to the estimate, then
    inflated against a capsule bone until 5 % of the area touches (before the target volume); closed and
    tetrahedralised (volume = the membrane's), fibres."""
    import ufl
    from dolfinx import fem

    from model.experiments.membrane import inflate_extruded_patch

    bone = Capsule((-2.0, 0.0, 0.75), (2.0, 0.0, 0.75), 0.3)
    result = inflate_extruded_patch(NEO, offset=0.03, first_volume=0.8, rest_volume=0.4, target_volume=2.0,
                                    obstacles=[(bone, 10.0, False)], contact_fraction=0.05)
    assert result.first_steps[-1].volume == pytest.approx(0.8, rel=1e-6)
    assert all(s.contact_fraction == 0.0 for s in result.first_steps)
    if COMM.rank == 0:
        assert result.smoothing.volumes[-1] <= 0.4 < result.smoothing.volumes[-2]
        assert np.allclose(result.extruded[:, 2][np.abs(result.extruded[:, 2]) > 0], 0.03)
    assert result.initial_energy > 0.0  # the extruded positions on the smoothed rest shape: compressed
    last = result.steps[-1]
    assert last.contact_fraction >= 0.05 and last.volume < 2.0
    report = result.contacts[0].report()
    assert report["contact_fraction"] == last.contact_fraction and report["force"][2] < 0.0
    assert 0.0 < report["max_penetration"] < 0.02
    msh = result.domain.mesh
    volume = COMM.allreduce(fem.assemble_scalar(fem.form(1.0 * ufl.dx(domain=msh))), op=MPI.SUM)
    assert volume == pytest.approx(result.problem.volume(), rel=1e-10)
