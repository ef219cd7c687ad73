"""Hertz contact of two deformable spheres (issue 14): two ball octants pressed together, against Hertz's formula.

    result = hertz_spheres(pole_size=0.004, growth=0.15, size=0.125)

The mesh is meshes.sphere.sphere_pair: the octants x, y >= 0 of an ``upper`` ball (radius R1, centre (0, 0, R1))
and a ``lower`` one (R2, centre (0, 0, -R2)) touching at the origin, refined there (``pole_size`` within
``pole_radius``, growing by ``growth`` per unit distance to ``size``; the lower mesh 1.25 times coarser, so
the two surfaces meet at non-matching nodes). Symmetry: u_x = 0 on x = 0, u_y = 0 on y = 0 of both bodies; the
lower equator (z = -R2) held at u_z = 0, the upper one (z = R1) moved down by the approach d (load factor x d).
Contact between the bodies: model.problem.body_contact.BodyContact, slave = the upper sphere's curved surface,
master = the lower one's, penalty k with Uzawa updates (augmented Lagrangian) until the penetration is below
``tolerance`` x the bounding-box diagonal. Hertz (frictionless, small strain, half-spaces):

    F = (4/3) E* R^(1/2) d^(3/2),   a = (R d)^(1/2),   1/R = 1/R1 + 1/R2,   1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2

The total force is 4 times the octant's (the contact force on the upper body, z component). The equators are
Hertz's "distant points": the finite spheres are stiffer than half-spaces by O(a/R) (measured in docs/layers.md).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

import forms
from meshes.sphere import sphere_pair
from model.domain import build_domain
from model.problem import ElasticityProblem
from model.problem.body_contact import BodyContact
from model.solvers.contact import make_contact_solver
from model.solvers.loadstepping import step_loads

log = logging.getLogger(__name__)

__all__ = ["HertzPoint", "HertzResult", "face_triangles", "hertz_force", "hertz_pressure", "hertz_spheres",
           "pressure_profile"]


def hertz_force(d: float, R1: float, R2: float, E1: float, E2: float, nu1: float, nu2: float) -> float:
    """F = (4/3) E* R^(1/2) d^(3/2) with 1/R = 1/R1 + 1/R2 and 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2."""
    radius = 1.0 / (1.0 / R1 + 1.0 / R2)
    modulus = 1.0 / ((1.0 - nu1**2) / E1 + (1.0 - nu2**2) / E2)
    return 4.0 / 3.0 * modulus * math.sqrt(radius) * d**1.5


def hertz_pressure(r: np.ndarray, force: float, a: float) -> np.ndarray:
    """Hertz's contact pressure p(r) = p0 (1 - r^2/a^2)^(1/2), p0 = 3 F / (2 pi a^2) (0 outside the contact)."""
    p0 = 3.0 * force / (2.0 * math.pi * a**2)
    return p0 * np.sqrt(np.clip(1.0 - (np.asarray(r) / a) ** 2, 0.0, None))


@dataclass
class HertzPoint:
    """One converged load step: approach d, total force (4 x the octant's z force), Hertz's force, the contact
    radius (the largest distance from the axis of an active slave node, reference coordinates), active slave
    nodes, the largest penetration, Newton iterations and Uzawa rounds."""

    approach: float
    force: float
    hertz: float
    contact_radius: float
    active_points: int
    max_penetration: float
    newton_iterations: int
    uzawa_rounds: int

    @property
    def error(self) -> float:
        """(F - F_Hertz) / F_Hertz (nan while the spheres are apart: F_Hertz = 0)."""
        return (self.force - self.hertz) / self.hertz if self.hertz > 0.0 else float("nan")


@dataclass
class HertzResult:
    """The steps of a run, the problem (its solution: the last step) and the contact."""

    points: list[HertzPoint]
    problem: ElasticityProblem
    contact: BodyContact
    dofs: int
    completed: bool
    radii: tuple[float, float] = (1.0, 1.0)
    extra: dict = field(default_factory=dict)


def hertz_spheres(pole_size: float = 0.004, growth: float = 0.15, size: float = 0.125, approach: float = 2e-3,
                  steps: int = 1, radius: float = 1.0, lower_radius: float | None = None, pole_radius: float = 0.05,
                  E: tuple[float, float] = (1.0e4, 2.0e4), nu: tuple[float, float] = (0.3, 0.3), k: float = 1.0e7,
                  tolerance: float = 1e-6, comm: MPI.Comm = MPI.COMM_WORLD, gap: float = 0.0) -> HertzResult:
    """Press the two octants together by ``approach`` in ``steps`` equal load steps (module docstring); neo-Hookean
    upper (E[0], nu[0]) and lower (E[1], nu[1]) spheres. ``gap``: the spheres start that far apart
    (meshes.sphere_pair's gap) and the upper equator moves down by gap + approach, so that at load factor t the
    approach is d = t (gap + approach) - gap (negative: still apart, Hertz's force 0)."""
    R2 = radius if lower_radius is None else lower_radius
    data = sphere_pair(radius, R2, size, pole_size, pole_radius, 1.25 * pole_size, growth, gap) \
        if comm.rank == 0 else None
    laws = [(body, forms.make_law("neo_hookean", E=e, nu=n)) for body, e, n in zip(("upper", "lower"), E, nu)]
    problem = ElasticityProblem(build_domain(comm, data), laws, 1)
    for body in ("upper", "lower"):
        problem.add_dirichlet(f"{body}_xmin", (0,), [0.0])
        problem.add_dirichlet(f"{body}_ymin", (1,), [0.0])
    problem.add_dirichlet("lower_zmin", (2,), [0.0])
    problem.add_dirichlet("upper_zmax", (2,), [-(approach + gap)])
    contact = BodyContact(problem, "upper_sphere", "lower_sphere", k, augmented=True, tolerance=tolerance,
                          max_uzawa=30)
    solver = make_contact_solver(problem, [contact], {"snes_rtol": 1e-10, "snes_atol": 1e-9})
    points: list[HertzPoint] = []
    slave_xy = contact.reference[contact.slave_blocks][:, :2]

    def record(rec) -> None:  # noqa: ANN001 - loadstepping's StepRecord
        if not rec.result.converged:
            return
        report = contact.report()
        gaps = contact.nodal_gaps()
        lam = contact.multiplier.x.array[contact.slave_q]
        pressed = np.maximum(lam - float(contact.k.value) * gaps, 0.0) > 0.0
        local = float(np.linalg.norm(slave_xy[pressed], axis=1).max(initial=0.0))
        d = rec.load_factor * (approach + gap) - gap
        points.append(HertzPoint(d, 4.0 * report["force"][2], hertz_force(max(d, 0.0), radius, R2, *E, *nu),
                                 comm.allreduce(local, op=MPI.MAX), report["active_points"],
                                 report["max_penetration"], rec.result.iterations, solver.uzawa_iterations))
        log.info("Hertz spheres: d = %.3e, F = %.6g, Hertz %.6g (%+.2f %%), a = %.4f, %d active, %d Newton, %d Uzawa",
                 d, points[-1].force, points[-1].hertz, 100 * points[-1].error, points[-1].contact_radius,
                 points[-1].active_points, points[-1].newton_iterations, points[-1].uzawa_rounds)

    completed = step_loads(solver, steps, on_step=record).completed
    solver.destroy()
    dofs = problem.space.dofmap.index_map.size_global * problem.space.dofmap.index_map_bs
    return HertzResult(points, problem, contact, dofs, completed, (radius, R2))


def pressure_profile(contact: BodyContact) -> tuple[np.ndarray, np.ndarray]:
    """(r, p) at every slave node, all ranks: the reference distance from the axis and the contact pressure
    p = max(lambda - k g, 0) (per reference area)."""
    r = np.linalg.norm(contact.reference[contact.slave_blocks][:, :2], axis=1)
    lam = contact.multiplier.x.array[contact.slave_q]
    p = np.maximum(lam - float(contact.k.value) * contact.nodal_gaps(), 0.0)
    parts = contact.comm.allgather((r, p))
    return np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts])


def face_triangles(problem: ElasticityProblem, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The triangles of boundary ``name``: reference vertices (n, 3, 3) and their displacements (n, 3, 3), every
    rank's (for pictures; P1)."""
    from model import compat

    msh, V = problem.domain.mesh, problem.space
    geometry_to_dof = np.empty(len(msh.geometry.x), dtype=np.int64)
    geometry_to_dof[compat.geometry_dofs(msh)[:, :4].ravel()] = compat.cell_dofs(V.dofmap)[:, :4].ravel()
    fdim = msh.topology.dim - 1
    facets = np.asarray(problem.domain.boundary_facets(name), dtype=np.int32)
    facets = facets[facets < msh.topology.index_map(fdim).size_local]
    nodes = np.asarray(compat.entity_geometry(msh, fdim, facets), dtype=np.int64).reshape(len(facets), -1)[:, :3] \
        if len(facets) else np.empty((0, 3), dtype=np.int64)
    u = problem.solution.x.array.reshape(-1, 3)[geometry_to_dof[nodes]]
    parts = msh.comm.allgather((msh.geometry.x[nodes], u))
    return np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts])
