"""Membranes (issue 14 item 4, thesis sec. 3.3.3.1): laws, pressure potential, balloon and Hencky verification."""

from __future__ import annotations

import math

import numpy as np
import pytest
import ufl
from conftest import ROOT, environment, serial_only
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from forms.law import ParameterError
from forms.membrane import MembraneNeoHookean, MembraneStVK, membrane_law, pressure_virtual_work
from meshes.membrane import disc_surface, sphere_octant, sphere_surface
from model.domain.distribute import build_domain
from model.problem.membrane import MembraneProblem, axis_orientation, balloon_pressure, hencky, radial_orientation
from model.solvers.membrane import inflate

COMM = MPI.COMM_WORLD
STVK = MembraneStVK(young=1.0, nu=0.3, thickness=0.01)
NEO = MembraneNeoHookean(mu=1.0, thickness=0.01)
OCTANT_FIXED = {"x0": (0,), "y0": (1,), "z0": (2,)}


def _domain(generator, *args):
    return build_domain(COMM, generator(*args) if COMM.rank == 0 else None)


def test_laws_are_validated():
    with pytest.raises(ParameterError, match="nu"):
        MembraneStVK(young=1.0, nu=0.5, thickness=0.01)
    with pytest.raises(ParameterError, match="thickness"):
        MembraneNeoHookean(mu=1.0, thickness=0.0)
    with pytest.raises(ParameterError, match="young"):
        MembraneStVK(young=float("nan"), nu=0.3, thickness=0.01)
    with pytest.raises(ParameterError, match="unknown parameter 'E'"):
        membrane_law("stvk", E=1.0, nu=0.3, thickness=0.01)
    with pytest.raises(ParameterError, match="unknown"):
        membrane_law("ogden", mu=1.0)
    assert membrane_law("neo_hookean", mu=2.0, thickness=0.1) == MembraneNeoHookean(2.0, 0.1)
    # the plane-stress Lame constant of the thesis' B matrix
    assert STVK.lmbda_plane == pytest.approx(0.3 / (1 - 0.09))


def test_surface_domain_is_a_manifold_mesh():
    data = sphere_octant(1.0, 0.2) if COMM.rank == 0 else None
    domain = build_domain(COMM, data)
    msh = domain.mesh
    assert (msh.topology.dim, msh.geometry.dim) == (2, 3)
    area = COMM.allreduce(fem.assemble_scalar(fem.form(1.0 * ufl.dx(domain=msh))), op=MPI.SUM)
    reference = COMM.bcast(data.area() if COMM.rank == 0 else None)
    assert area == pytest.approx(reference, rel=1e-12)
    assert abs(area - math.pi / 2) / (math.pi / 2) < 0.01  # faceted octant of the unit sphere
    owned = msh.topology.index_map(1).size_local
    counts = COMM.bcast({n: int(np.sum(data.facet_tags == t)) for n, t in data.boundary_names.items()}
                        if COMM.rank == 0 else None)
    for name in ("x0", "y0", "z0"):
        facets = domain.boundary_facets(name)
        assert COMM.allreduce(int(np.sum(facets < owned)), op=MPI.SUM) == counts[name] > 0


@pytest.mark.parametrize("law", [STVK, NEO], ids=["stvk", "neo_hookean"])
def test_energy_of_an_affine_map_matches_the_closed_form(law):
    """x = A X on the flat disc: C = T^T A^T A T (T = [e1 e2]) in every triangle; int w dA = area w(C)."""
    domain = _domain(disc_surface, 1.0, 0.25)
    problem = MembraneProblem(domain, law, axis_orientation())
    A = np.array([[1.2, 0.3, 0.0], [-0.1, 0.9, 0.0], [0.2, 0.25, 1.0]])
    problem.u.interpolate(lambda x: (A - np.eye(3)) @ x)
    T = np.eye(3)[:, :2]
    C = T.T @ A.T @ A @ T
    if isinstance(law, MembraneStVK):
        E = 0.5 * (C - np.eye(2))
        w = law.thickness * (law.mu * np.sum(E * E) + 0.5 * law.lmbda_plane * np.trace(E) ** 2)
    else:
        w = 0.5 * law.mu * law.thickness * (np.trace(C) + 1.0 / np.linalg.det(C) - 3.0)
    assert problem.elastic_energy() == pytest.approx(w * problem.reference_area(), rel=1e-12)
    # equibiaxial closed form (w, w') against the UFL energy of x = lambda X
    lam = 1.17
    problem.u.interpolate(lambda x: (lam - 1.0) * x)
    w_lam, dw_lam = law.equibiaxial(lam)
    assert problem.elastic_energy() == pytest.approx(w_lam * problem.reference_area(), rel=1e-12)
    eps = 1e-6
    assert dw_lam == pytest.approx((law.equibiaxial(lam + eps)[0] - law.equibiaxial(lam - eps)[0]) / (2 * eps),
                                   rel=1e-7)


def test_volume_potential_gives_the_follower_pressure():
    """On a closed surface d/du [p V(x)] = int p n . v da (the follower load), and V is the polyhedron's volume."""
    data = sphere_surface(1.0, 0.4) if COMM.rank == 0 else None
    domain = build_domain(COMM, data)
    problem = MembraneProblem(domain, STVK, radial_orientation())
    problem.u.interpolate(lambda x: np.vstack([0.1 * x[1] ** 2, 0.05 * x[0] * x[2], 0.2 * x[2] + 0.1 * x[0] ** 2]))
    v = ufl.TestFunction(problem.V)
    from_volume = fem_petsc.assemble_vector(fem.form(ufl.derivative(problem.volume_form, problem.u, v)))
    follower = fem_petsc.assemble_vector(fem.form(pressure_virtual_work(problem.u, v, problem.frame, 1.0)
                                                  * problem.dA))
    for b in (from_volume, follower):
        b.ghostUpdate(addv=2, mode=1)  # ADD, REVERSE
    from_volume.axpy(-1.0, follower)
    assert from_volume.norm() < 1e-12 * follower.norm()
    # V(x): (1/6) sum x0 . (x1 x x2) over the deformed triangles (data on rank 0)
    if COMM.rank == 0:
        X = data.points
        x = X + np.column_stack([0.1 * X[:, 1] ** 2, 0.05 * X[:, 0] * X[:, 2], 0.2 * X[:, 2] + 0.1 * X[:, 0] ** 2])
        t = x[data.cells]
        exact = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0
    else:
        exact = None
    assert problem.volume() == pytest.approx(COMM.bcast(exact), rel=1e-12)
    # the Newton matrix of Pi = int w dA - p V is symmetric
    problem.pressure.value = 0.3
    J = fem_petsc.assemble_matrix(fem.form(ufl.derivative(problem.residual, problem.u, ufl.TrialFunction(problem.V))))
    J.assemble()
    assert J.isSymmetric(1e-10 * J.norm())
    follower = ufl.derivative(pressure_virtual_work(problem.u, v, problem.frame, 1.0) * problem.dA, problem.u,
                              ufl.TrialFunction(problem.V))
    K = fem_petsc.assemble_matrix(fem.form(follower))
    K.assemble()
    assert K.isSymmetric(1e-10 * K.norm())  # on a closed surface the follower tangent is V's Hessian


def _balloon_errors(law, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Inflate the symmetric octant of a unit sphere; stretch lambda = (V/V0)^(1/3) and the relative error of
    the pressure against p(lambda) = w'(lambda) / (R lambda^2)."""
    domain = _domain(sphere_octant, 1.0, size)
    problem = MembraneProblem(domain, law, radial_orientation(), OCTANT_FIXED)
    V0 = problem.volume()
    pressures = balloon_pressure(law, 1.0, np.linspace(1.02, 1.25, 5))
    steps = inflate(problem, pressures)
    lam = np.array([(s.volume / V0) ** (1.0 / 3.0) for s in steps])
    return lam, np.array([s.pressure for s in steps]) / balloon_pressure(law, 1.0, lam) - 1.0


@pytest.mark.parametrize("law", [STVK, NEO], ids=["stvk", "neo_hookean"])
def test_balloon_pressure_stretch_curve(law):
    """Thin sphere: p = w'(lambda)/(R lambda^2) within 1% on the fine octant, the error shrinking with h.

    Neo-Hookean: p = (2 mu h / R)(1/lambda - 1/lambda^7) has its maximum at lambda = 7^(1/6) = 1.383; pressure
    control stops at lambda = 1.25, before the limit point."""
    lam_c, err_c = _balloon_errors(law, 0.2)
    lam_f, err_f = _balloon_errors(law, 0.1)
    assert lam_f[-1] > 1.24 and lam_f[0] < 1.03
    assert np.max(np.abs(err_f)) < 0.01
    assert np.max(np.abs(err_f)) < 0.6 * np.max(np.abs(err_c))


def test_hencky_reference():
    """The shooting solution reproduces Hencky's b0 = 1.724 for nu = 0.3 (his series' leading coefficient) and
    the corrected centre coefficient 0.6535 (series a0 + a2 + ... with b0: 1/b0 + 1/(2 b0^4) + 5/(9 b0^7) + ...)."""
    ref = hencky(0.3)
    assert ref.b0 == pytest.approx(1.724, abs=5e-4)
    b0 = ref.b0
    series = 1 / b0 + 1 / (2 * b0**4) + 5 / (9 * b0**7) + 55 / (72 * b0**10) + 7 / (6 * b0**13) \
        + 205 / (108 * b0**16)
    assert ref.coefficient == pytest.approx(series, rel=5e-4)


def test_hencky_clamped_disc():
    """Clamped disc under p a / (E h) = 1e-4: centre deflection and profile within 2% of Hencky."""
    ref = hencky(0.3)
    domain = _domain(disc_surface, 1.0, 0.1)
    problem = MembraneProblem(domain, STVK, axis_orientation(), {"rim": (0, 1, 2)})
    p = 1e-6
    w0 = ref.centre_deflection(1.0, p, STVK.young, STVK.thickness)
    # a flat membrane has no transverse stiffness: start Newton from a paraboloid of about the right height
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0], w0 * (1 - x[0] ** 2 - x[1] ** 2)]))
    inflate(problem, [p])
    assert abs(problem.max_component(2) / w0 - 1.0) < 0.02
    n = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:n]
    w = problem.u.x.array[: 3 * n].reshape(-1, 3)[:, 2]
    expected = w0 / ref.coefficient * np.interp(np.hypot(X[:, 0], X[:, 1]), ref.rho, ref.omega)
    local = np.max(np.abs(w - expected)) if n else 0.0
    assert COMM.allreduce(local, op=MPI.MAX) < 0.02 * w0


def test_inflation_workflow_patch_to_muscle():
    """Thesis ch. 3.3.3: clamped disc inflated until V = target (stop criterion), closed with its base, filled
    with tetrahedra whose volume equals the membrane's enclosed volume, and given a Laplace fibre field."""
    from model.experiments.membrane import inflate_patch

    target = 0.5
    result = inflate_patch(NEO, target_volume=target, size=0.15, tet_size=0.15)
    steps = result.steps
    assert abs(steps[-1].volume - target) <= 1e-6 * target
    growth = [s.volume for s in steps if s.volume < target]
    assert len(growth) >= 3 and np.all(np.diff(growth) > 0)  # the volume grows with the pressure
    msh = result.domain.mesh
    assert (msh.topology.dim, msh.geometry.dim) == (3, 3)
    volume = COMM.allreduce(fem.assemble_scalar(fem.form(1.0 * ufl.dx(domain=msh))), op=MPI.SUM)
    assert volume == pytest.approx(result.problem.volume(), rel=1e-10)
    cells = result.fibres.cells
    a0 = result.fibres.function.x.array.reshape(-1, 3)[cells]
    assert np.allclose(np.linalg.norm(a0, axis=1), 1.0)
    mean_x = COMM.allreduce(a0[:, 0].sum(), op=MPI.SUM) / COMM.allreduce(len(a0), op=MPI.SUM)
    assert mean_x > 0.7  # from the origin end (x < 0) to the insertion end (x > 0)


@serial_only
def test_example_script() -> None:
    """examples/membrane_balloon.py: the printed balloon errors < 1%, Hencky's error < 2%, the target volume, the
    balloon in the rigid cavity on its closed form (1e-3) and the contact-fraction stop at p_m(R_c) (1.5 %)."""
    import re
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "examples/membrane_balloon.py", "--size", "0.2", "--stretch", "1.2",
                           "--law", "stvk"], cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    errors = [float(line.split()[-1]) for line in proc.stdout.splitlines() if re.match(r"\s+1\.\d+\s", line)]
    assert len(errors) == 8 and max(abs(e) for e in errors) < 0.01
    assert abs(float(re.search(r"error (\S+)$", proc.stdout, re.M).group(1))) < 0.02
    assert "inflation: V = 0.500000" in proc.stdout
    cavity = [[float(v) for v in line.split()[1:]] for line in proc.stdout.splitlines() if line.startswith("cavity: ")]
    assert len(cavity) == 4 and all(abs(mean / closed - 1) < 1e-3 for _, mean, closed, _ in cavity)
    assert [fraction for *_, fraction in cavity] == [0.0, 0.0, 1.0, 1.0]
    assert abs(float(re.search(r"p / p_m\(R_c\) - 1 = (\S+)$", proc.stdout, re.M).group(1))) < 0.015
