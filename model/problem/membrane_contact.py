"""Contact of a membrane (model.problem.membrane.MembraneProblem) with rigid bones: penalty, nodal rule, UFL.

    contact = ObstacleContact(problem, Sphere((0, 0, 0), 1.2), k=1e3, inside=True)   # adds its energy to Pi
    inflate(problem, pressures); contact.report()   # penetration, force, contact fraction

A rigid obstacle (forms.obstacles: Plane, Sphere, Capsule; signed distance d > 0 on its free side) gives the gap
of the current point x = X + u of the membrane,

    g(x) = s d(x),   s = +1 (the membrane stays outside the obstacle: a bone) or -1 (``inside``: the membrane
                     stays inside it, e.g. a balloon in a rigid spherical cavity),

and the penalty energy, integrated over the reference membrane with the nodal ("vertex") rule (A/3) sum over
each triangle's vertices (a node-by-node constraint, P1),

    Pi_c = int_S0 (k/2) min(g, 0)^2 dA          (forms.obstacles.penalty_energy),

k > 0 a stiffness per reference area per length. UFL derives the residual and Newton matrix of Pi + Pi_c. The
contact pressure per reference area is p_c = k max(-g, 0) (forms.obstacles.contact_pressure), the force on the
membrane F = -dPi_c/du summed over the nodes (= int p_c grad d dA), and the contact fraction the share of the
reference area, lumped to the nodes (m_i = int phi_i dA), whose nodes touch (g_i < 0):

    fraction = sum_{g_i < 0} m_i / sum_i m_i.

Closed form (tests/test_membrane_contact.py): a thin spherical balloon of radius R in a rigid concentric
cavity of radius R_c > R is free until p = p_m(R_c/R) (p_m(lambda) = w'(lambda)/(R lambda^2),
model.problem.membrane.balloon_pressure); beyond it d/dr [4 pi R^2 (w + (k/2) delta^2) - p (4/3) pi r^3] = 0
with r = R_c + delta gives the penetration delta = lambda^2 (p - p_m(lambda)) / k, lambda = (R_c + delta)/R,
and the contact fraction jumps from 0 to 1.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.obstacles import Obstacle, penalty_energy
from model.problem.membrane import MembraneProblem

log = logging.getLogger(__name__)

__all__ = ["ObstacleContact", "VERTEX_RULE", "contact_fraction", "nodal_measure"]

#: the nodal quadrature on a triangle: (A/3) at each vertex (reference triangle of area 1/2)
VERTEX_RULE = {"quadrature_rule": "custom", "quadrature_degree": 1,
               "quadrature_points": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
               "quadrature_weights": np.full(3, 1.0 / 6.0)}


def nodal_measure(problem: MembraneProblem, region: str | None = None) -> ufl.Measure:
    """dA over the membrane's cells (or its cell region ``region``) with the vertex rule.

    Always restricted to tagged cells: on dolfinx 0.5 FFCx merges two quadrature rules of the same (untagged)
    cell integral into one kernel that does not compile on a manifold (J declared twice)."""
    dx = ufl.Measure("dx", domain=problem.domain.mesh, subdomain_data=problem.domain.cell_tags,
                     metadata=dict(VERTEX_RULE))
    regions = problem.domain.regions
    if region is not None:
        error = problem.domain.region_error(region)
        if error is not None:
            raise ValueError(f"membrane contact: region: {error}")
    codes = regions[region] if region is not None else tuple(sorted({c for v in regions.values() for c in v}))
    return dx(tuple(int(c) for c in codes))


class _NodalContact:
    """What the membrane contacts share: owned nodes, their lumped areas, the force from a contact energy."""

    def _setup(self, problem: MembraneProblem, energy: ufl.Form, dA: ufl.Measure) -> None:
        self.problem, self.comm = problem, problem.domain.mesh.comm
        V = problem.V
        self.n_owned = V.dofmap.index_map.size_local
        self.reference = V.tabulate_dof_coordinates()[:, :3]
        v = ufl.TestFunction(V)
        lumped = fem_petsc.assemble_vector(fem.form(v[0] * dA))
        lumped.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.lumped_area = lumped.array_r.reshape(-1, 3)[: self.n_owned, 0].copy()
        lumped.destroy()
        self.energy = energy
        self._force = fem.form(ufl.derivative(energy, problem.u, v))
        problem.add_energy(energy)
        problem.contacts.append(self)

    def positions(self) -> np.ndarray:
        """x = X + u at the owned nodes (n, 3)."""
        u = self.problem.u.x.array.reshape(-1, 3)[: self.n_owned]
        return self.reference[: self.n_owned] + u

    def force(self) -> np.ndarray:
        """The contact force on the membrane, -dPi_c/du summed over all nodes (3,). Collective."""
        R = fem_petsc.assemble_vector(self._force)
        R.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        local = R.array_r.reshape(-1, 3).sum(axis=0)
        R.destroy()
        return -np.asarray(self.comm.allreduce(local, op=MPI.SUM))

    def touching(self) -> np.ndarray:
        """A bool per owned node of the membrane: True where it touches (g < 0)."""
        raise NotImplementedError

    def contact_fraction(self) -> float:
        """The share of the reference area (lumped to the nodes) whose nodes touch, g < 0. Collective."""
        return _area_fraction(self.comm, self.lumped_area, self.touching())


def _area_fraction(comm: MPI.Comm, lumped: np.ndarray, mask: np.ndarray) -> float:
    touching = comm.allreduce(float(lumped[mask].sum()), op=MPI.SUM)
    return touching / comm.allreduce(float(lumped.sum()), op=MPI.SUM)


def contact_fraction(problem: MembraneProblem) -> float:
    """The share of the membrane's reference area whose nodes touch any of its contacts (bones or other
    membranes; each node counted once), 0 without contacts. Collective."""
    if not problem.contacts:
        return 0.0
    mask = np.zeros(problem.contacts[0].n_owned, dtype=bool)
    for contact in problem.contacts:
        mask |= contact.touching()
    return _area_fraction(problem.domain.mesh.comm, problem.contacts[0].lumped_area, mask)


class ObstacleContact(_NodalContact):
    """Penalty contact of the whole membrane with a rigid ``obstacle`` (module docstring); ``inside``: the free
    side is the obstacle's interior (g = -d). Adds Pi_c to the problem's energy on construction."""

    def __init__(self, problem: MembraneProblem, obstacle: Obstacle, k: float, inside: bool = False,
                 name: str | None = None) -> None:
        if not (isinstance(k, (int, float)) and np.isfinite(k) and k > 0):
            raise ValueError(f"membrane contact: k must be a finite number > 0, got {k!r}")
        self.obstacle, self.sign = obstacle, -1.0 if inside else 1.0
        self.name = name or type(obstacle).__name__.lower()
        msh = problem.domain.mesh
        self.k = fem.Constant(msh, PETSc.ScalarType(k))
        x = ufl.SpatialCoordinate(msh) + problem.u
        self.gap = self.sign * obstacle.distance(x)
        self._setup(problem, penalty_energy(self.gap, self.k) * nodal_measure(problem), nodal_measure(problem))

    def nodal_gaps(self) -> np.ndarray:
        """g at the owned nodes."""
        return self.sign * np.asarray(self.obstacle.distance(self.positions()), dtype=np.float64)

    def touching(self) -> np.ndarray:
        return self.nodal_gaps() < 0.0

    def report(self) -> dict[str, Any]:
        """max_penetration = max(0, -min g), force (on the membrane), contact_fraction, active_points (g < 0);
        the same on every rank. Collective."""
        g = self.nodal_gaps()
        low = self.comm.allreduce(float(g.min(initial=np.inf)), op=MPI.MIN)
        return {"pair": self.name, "max_penetration": max(0.0, -low), "force": [float(f) for f in self.force()],
                "contact_fraction": self.contact_fraction(),
                "active_points": self.comm.allreduce(int(np.sum(g < 0.0)), op=MPI.SUM)}
