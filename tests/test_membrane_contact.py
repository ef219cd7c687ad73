"""Membrane contact (issue 14 item 4, thesis ch. 3.3.3): bones, the contact-fraction stop of the inflation."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from forms.membrane import MembraneNeoHookean, MembraneStVK
from forms.obstacles import Capsule, Plane, Sphere
from meshes.membrane import (
    SurfaceMeshData,
    disc_surface,
    enclosed_volume,
    extrude,
    facing_discs,
    smooth_rest_shape,
    sphere_octant,
    vertex_normals,
)
from model.domain.distribute import build_domain
from model.problem.membrane import MembraneProblem, axis_orientation, balloon_pressure, radial_orientation
from model.problem.membrane_contact import MembranePairContact, ObstacleContact, contact_fraction, pair_contacts
from model.solvers.membrane import inflate, inflate_to_volume

COMM = MPI.COMM_WORLD
STVK = MembraneStVK(young=1.0, nu=0.3, thickness=0.01)
NEO = MembraneNeoHookean(mu=1.0, thickness=0.01)
OCTANT_FIXED = {"x0": (0,), "y0": (1,), "z0": (2,)}
R_CAVITY = 1.1
#: Newton for the pressed discs: the l2 line search (the default with membrane-membrane contact, 12 to 19
#: iterations a step; backtracking on |R| took 50 to 110 at the first contact step)
PAIR_OPTIONS = {"snes_linesearch_type": "l2"}


def _domain(generator, *args):
    return build_domain(COMM, generator(*args) if COMM.rank == 0 else None)


def _balloon_in_cavity(k: float = 1.0, augmented: bool = False):
    problem = MembraneProblem(_domain(sphere_octant, 1.0, 0.2), STVK, radial_orientation(), OCTANT_FIXED)
    contact = ObstacleContact(problem, Sphere((0.0, 0.0, 0.0), R_CAVITY), k, inside=True, augmented=augmented)
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


@pytest.mark.parametrize("augmented", [False, True], ids=["penalty", "augmented"])
def test_inflation_stops_at_the_contact_fraction_of_the_cavity(augmented):
    """The balloon touches the cavity everywhere at once, at p_m(R_c/R): the contact-fraction stop (0.5)
    finds that pressure (to 1.5 %: the faceted balloon, size 0.2) long before the target volume; with the
    augmented Lagrangian too (Uzawa rounds after every equilibrium: no penetration at the stop)."""
    problem, contact = _balloon_in_cavity(1.0, augmented)
    p_touch = float(balloon_pressure(STVK, 1.0, R_CAVITY))
    steps = inflate_to_volume(problem, target_volume=10.0, dp=0.3 * p_touch, contact_fraction=0.5)
    assert steps[-1].contact_fraction >= 0.5
    assert steps[-1].pressure == pytest.approx(p_touch, rel=0.015)  # measured +0.84 %
    assert all(s.contact_fraction < 0.5 for s in steps if s.pressure < steps[-1].pressure)
    if augmented:
        assert contact.report()["max_penetration"] < 1e-9


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


def _facing_discs(H: float, lower_size: float = 0.2, upper_size: float | None = None) -> SurfaceMeshData:
    """Two clamped unit discs (meshes.membrane.facing_discs): ``lower`` on z = 0 (normal +z) and ``upper`` on
    z = H (normal -z, the triangles reversed; the mirror image of ``lower`` unless it has a size of its own)."""
    return facing_discs(1.0, H, lower_size, upper_size)


def _pressed_discs(H: float, bump: float, lower_size: float = 0.2, upper_size: float | None = None
                   ) -> MembraneProblem:
    """The two facing discs (``_facing_discs``), clamped, both starting from a paraboloid of height ``bump``."""
    data = _facing_discs(H, lower_size, upper_size) if COMM.rank == 0 else None
    problem = MembraneProblem(build_domain(COMM, data), STVK,
                              lambda c: np.where(c[:, 2:3] < H / 2, 1.0, -1.0) * np.array([0.0, 0.0, 1.0]),
                              {"lower_rim": (0, 1, 2), "upper_rim": (0, 1, 2)})
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0],
                                               np.where(x[2] < H / 2, 1, -1) * bump * (1 - x[0] ** 2 - x[1] ** 2)]))
    return problem


def _against_plane(size: float, H: float, bump: float, k: float, pressures: list[float], augmented: bool = False
                   ) -> ObstacleContact:
    """One clamped disc of mesh ``size`` inflated against the rigid plane z = H/2 (penalty k): the symmetric
    equivalent of two identical discs pressed together."""
    rigid = MembraneProblem(_domain(disc_surface, 1.0, size), STVK, axis_orientation(), {"rim": (0, 1, 2)})
    rigid.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], bump * (1 - x[0] ** 2 - x[1] ** 2)]))
    plane = ObstacleContact(rigid, Plane((0.0, 0.0, H / 2), (0.0, 0.0, -1.0)), k, augmented=augmented)
    inflate(rigid, pressures, options=PAIR_OPTIONS)
    return plane


def test_two_membranes_pressed_together():
    """Two mirror-image clamped discs (H = 0.8 apart) inflated towards each other under the same pressure: by
    symmetry each is the disc against a rigid plane at z = H/2 whose penalty is 2k (the gap g = n . (x_s - x*)
    counts both penetrations); the slave's and master's contact forces balance, the penetration (sum of both)
    is twice the rigid one and stays below 2 p / k (the contact pressure k g balances p lambda^2 < 2 p).
    Newton (l2 line search, the default with membrane-membrane contact) within its default 40 iterations."""
    H, k, bump = 0.8, 10.0, 0.3
    pressures = [2e-3, 4e-3, 6e-3]
    problem = _pressed_discs(H, bump)
    pair = MembranePairContact(problem, "lower", "upper", k)
    steps = inflate(problem, pressures)
    assert max(s.iterations for s in steps) <= 25  # measured 15 to 19 (bt on |R|: 50 to 110)
    both = pair.report()
    one = _against_plane(0.2, H, bump, 2 * k, pressures).report()
    assert both["force"][2] == pytest.approx(one["force"][2], rel=2e-3) and one["force"][2] < 0
    assert np.allclose(both["master_force"], -np.asarray(both["force"]), atol=1e-12)
    assert both["contact_fraction"] == pytest.approx(one["contact_fraction"], rel=1e-12)
    assert one["contact_fraction"] > 0.1
    assert both["max_penetration"] == pytest.approx(2 * one["max_penetration"], rel=5e-3)
    assert both["max_penetration"] < 2 * pressures[-1] / k
    assert steps[-1].contact_fraction == pytest.approx(0.5 * both["contact_fraction"])  # of both discs' area


def test_two_membranes_on_non_matching_meshes():
    """Two discs of different meshes (slave 0.2, master 0.15; refined: 0.1, 0.075) pressed together: the contact
    force lies between the rigid-plane forces (2k) of the two meshes, its distance to the slave mesh's (and the
    contact fraction's) shrinks with the mesh, action = reaction; Newton's default 40 iterations suffice.
    Measured: force 3.8679e-3 against 3.8534e-3 (0.2) and 3.8992e-3 (0.15): +0.38 %; refined 3.9360e-3 against
    3.9332e-3 (0.1) and 3.9375e-3 (0.075): +0.07 %; fraction 0.1873 against 0.2094 (-10.6 %), refined 0.1767
    against 0.1850 (-4.5 %)."""
    H, k, bump = 0.8, 10.0, 0.3
    pressures = [2e-3, 4e-3, 6e-3]
    errors = []
    for slave, master in ((0.2, 0.15), (0.1, 0.075)):
        problem = _pressed_discs(H, bump, slave, master)
        pair = MembranePairContact(problem, "lower", "upper", k)
        steps = inflate(problem, pressures)
        assert max(s.iterations for s in steps) <= 25  # measured 12 to 19
        both = pair.report()
        fine, coarse = (_against_plane(size, H, bump, 2 * k, pressures).report() for size in (master, slave))
        assert np.allclose(both["master_force"], -np.asarray(both["force"]), atol=1e-12)
        assert coarse["force"][2] > both["force"][2] > fine["force"][2]  # all negative: between the two
        errors.append((both["force"][2] / coarse["force"][2] - 1.0,
                       both["contact_fraction"] / coarse["contact_fraction"] - 1.0))
    (force, fraction), (force_fine, fraction_fine) = errors
    assert abs(force) < 5e-3 and abs(force_fine) < 0.3 * abs(force)
    assert abs(fraction) < 0.12 and abs(fraction_fine) < 0.6 * abs(fraction)


def test_two_pass_on_non_matching_meshes():
    """Two passes (pair_contacts(two_pass=True), FEBio's two_pass): the discs of the non-matching meshes (lower
    0.2, upper 0.15, H = 0.8, k = 10 a pass) pressed together. One pass (lower the slave) keeps the lower's nodes
    out of the upper's triangles but not the upper's nodes out of the lower's (measured after the solve by the
    reverse pairing: 1.55e-2 against the slave's 9.1e-4); with two passes neither penetrates by more than
    2 p / k (measured 6.1e-4 and 8.3e-4). Each membrane's force (its pass as slave plus the other pass's reaction)
    balances the other's, and lies between the rigid-plane forces of the two meshes with penalty 4k (each pass
    pushes with k g, g counting both penetrations: measured -3.8875e-3 between -3.8558e-3 (0.2) and -3.9020e-3
    (0.15)). Newton within its default 40 iterations (measured 7, 13, 17)."""
    H, k, bump = 0.8, 10.0, 0.3
    pressures = [2e-3, 4e-3, 6e-3]
    problem = _pressed_discs(H, bump, 0.2, 0.15)
    (one,) = pair_contacts(problem, "lower", "upper", k)
    inflate(problem, pressures)
    slave_only = one.report()["max_penetration"]
    master_nodes = MembranePairContact(problem, "upper", "lower", k).report()["max_penetration"]  # a probe
    assert master_nodes > 10 * slave_only > 0  # measured 1.55e-2 against 9.1e-4

    problem = _pressed_discs(H, bump, 0.2, 0.15)
    passes = pair_contacts(problem, "lower", "upper", k, two_pass=True)
    assert [p.name for p in passes] == ["lower-upper", "upper-lower"]
    steps = inflate(problem, pressures)
    assert max(s.iterations for s in steps) <= 25
    first, second = (p.report() for p in passes)
    for report in (first, second):
        assert 0.0 < report["max_penetration"] < 2 * pressures[-1] / k and report["contact_fraction"] > 0.1
        assert np.allclose(report["master_force"], -np.asarray(report["force"]), atol=1e-12)
    lower = np.asarray(first["force"]) + np.asarray(second["master_force"])
    upper = np.asarray(second["force"]) + np.asarray(first["master_force"])
    assert np.allclose(lower, -upper, atol=1e-12)
    coarse, fine = (_against_plane(size, H, bump, 4 * k, pressures).report()["force"][2] for size in (0.2, 0.15))
    assert coarse > lower[2] > fine  # all negative
    with pytest.raises(ValueError, match="two_pass is penalty only"):
        pair_contacts(problem, "lower", "upper", k, augmented=True, two_pass=True)


def test_pair_contact_jacobian_with_the_pairing_held():
    """The coupled Newton matrix (K + K_uz Pi + Pi^T K_zu + Pi^T K_zz Pi) is the derivative of the coupled
    residual when the pairing (triangle, barycentric coordinates, normal) is held: finite differences O(eps)."""
    from model.solvers.membrane import membrane_newton

    H = 0.4
    problem = MembraneProblem(build_domain(COMM, _facing_discs(H) if COMM.rank == 0 else None), STVK,
                              lambda c: np.where(c[:, 2:3] < H / 2, 1.0, -1.0) * np.array([0.0, 0.0, 1.0]),
                              {"lower_rim": (0, 1, 2), "upper_rim": (0, 1, 2)})
    problem.u.interpolate(lambda x: np.vstack([0.02 * x[1] * (1 - x[0] ** 2 - x[1] ** 2), 0 * x[0],
                                               np.where(x[2] < H / 2, 1, -1) * 0.25 * (1 - x[0] ** 2 - x[1] ** 2)]))
    pair = MembranePairContact(problem, "lower", "upper", 10.0)
    problem.pressure.value = 1e-3
    newton = membrane_newton(problem)
    x = newton.x
    x.array[:] = problem.u.x.array[: len(x.array)]
    b0 = newton.b.duplicate()
    newton._residual(None, x, b0)
    assert pair.report()["active_points"] > 10  # interpenetrating: the contact terms are on
    newton._jacobian(None, x, newton.A, newton.A)
    pair.frozen = pair.pairing
    du = x.duplicate()
    du.array[:] = np.random.default_rng(COMM.rank).standard_normal(len(du.array))
    for bc in problem.bcs:
        du.array[bc.dof_indices()[0][bc.dof_indices()[0] < len(du.array)]] = 0.0
    Jdu = x.duplicate()
    newton.A.mult(du, Jdu)
    errors = []
    for eps in (1e-4, 1e-5):
        x1 = x.copy()
        x1.axpy(eps, du)
        b1 = newton.b.duplicate()
        newton._residual(None, x1, b1)
        b1.axpy(-1.0, b0)
        b1.scale(1.0 / eps)
        b1.axpy(-1.0, Jdu)
        errors.append(b1.norm() / Jdu.norm())
    newton.destroy()
    assert errors[1] < 1e-3 and errors[1] < 0.2 * errors[0]


def test_augmented_lagrangian_balloon_in_the_cavity():
    """Augmented Lagrangian (Uzawa): the penetration vanishes and the multiplier (contact pressure per reference
    area) is lambda_c = (R_c/R)^2 (p - p_m(R_c/R)), from the balance of the penalty case with k delta -> lambda_c."""
    problem = MembraneProblem(_domain(sphere_octant, 1.0, 0.2), STVK, radial_orientation(), OCTANT_FIXED)
    contact = ObstacleContact(problem, Sphere((0.0, 0.0, 0.0), R_CAVITY), 1.0, inside=True, augmented=True)
    p_touch = float(balloon_pressure(STVK, 1.0, R_CAVITY))
    p = 2.0 * p_touch
    step = inflate(problem, [0.5 * p_touch, p], uzawa_tolerance=1e-10)[-1]
    report = contact.report()
    assert report["max_penetration"] < 1e-10 and contact.uzawa_residual() <= 1e-10
    assert report["contact_fraction"] == step.contact_fraction == 1.0
    lam = contact.nodal_pressures()
    area = contact.lumped_area
    mean = COMM.allreduce(float(lam @ area), op=MPI.SUM) / COMM.allreduce(float(area.sum()), op=MPI.SUM)
    assert mean == pytest.approx(R_CAVITY**2 * (p - p_touch), rel=0.02)
    # the force is the multiplier's resultant: -lambda_c pi R^2 / 4 per axis
    assert np.allclose(report["force"], -R_CAVITY**2 * (p - p_touch) * np.pi / 4, rtol=0.03)


def test_augmented_lagrangian_two_membranes():
    """Augmented Lagrangian between two membranes (Uzawa on the slave nodes' multipliers): the two mirror-image
    discs pressed together have no penetration left (max |min(g, lambda/k)| <= 1e-9) and the multiplier is the
    contact pressure of each disc against the rigid plane z = H/2 with the augmented Lagrangian (by symmetry the
    same problem, for any k): the resultant of the multipliers, the forces, the contact fraction; the master's
    force is minus the slave's."""
    H, k, bump = 0.8, 10.0, 0.3
    pressures = [2e-3, 4e-3, 6e-3]
    problem = _pressed_discs(H, bump)
    pair = MembranePairContact(problem, "lower", "upper", k, augmented=True)
    inflate(problem, pressures)
    both = pair.report()
    plane = _against_plane(0.2, H, bump, k, pressures, augmented=True)
    one = plane.report()
    assert both["max_penetration"] < 1e-9 and pair.uzawa_residual() <= 1e-9
    assert one["max_penetration"] < 1e-9
    assert both["contact_fraction"] == pytest.approx(one["contact_fraction"], rel=1e-12)
    assert one["contact_fraction"] > 0.1
    # the same equilibrium; the pair's force along the master's vertex normals, tilted at the contact's edge
    assert both["force"][2] == pytest.approx(one["force"][2], rel=2e-3) and one["force"][2] < 0
    assert np.allclose(both["master_force"], -np.asarray(both["force"]), atol=1e-12)
    # the multiplier is the contact pressure (per reference area): its resultant is the contact force
    lam, area = pair.nodal_pressures(), pair.lumped_area[pair.slave_blocks]
    resultant = COMM.allreduce(float(lam @ area), op=MPI.SUM)
    assert resultant == pytest.approx(-both["force"][2], rel=2e-3)  # measured 3.8612e-3 against 3.8561e-3
    reference = COMM.allreduce(float(plane.nodal_pressures() @ plane.lumped_area), op=MPI.SUM)
    assert resultant == pytest.approx(reference, rel=2e-3)  # measured 3.8612e-3 against 3.8581e-3 (+8e-4)
