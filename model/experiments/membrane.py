"""The inflation workflow of the thesis (ch. 3.3.3): a flat patch inflated into a muscle ready for simulation.

    result = inflate_patch(law, target_volume=0.4)

1. a disc patch (meshes.membrane.disc_surface, radius a) clamped on its rim (the thesis' fixed tendon vertices)
   is inflated under a pressure growing by ``dp`` until the enclosed volume (between the patch and its plane)
   reaches ``target_volume`` (the stop criterion; the last pressure is adjusted by the secant method,
   model.solvers.membrane.inflate_to_volume);
2. the inflated patch is closed with its flat rest shape as the base (meshes.membrane.close_with_base) and
   filled with tetrahedra by gmsh (meshes.membrane.tetrahedralise), boundaries ``patch``, ``base``, and the
   fibre ends ``origin`` / ``insertion``: the base triangles whose centroid has x < -end a / x > end a (on the
   plane base no tetrahedron has all four vertices on an end, so grad phi never vanishes in a cell);
3. the tetrahedral mesh gets the Laplace fibre field a0 = grad phi / |grad phi| (model.fields.fibres),
   phi = 0 on ``origin``, 1 on ``insertion``: ready for a muscle run.

The flat disc has no transverse stiffness at zero pressure, so Newton starts from a small paraboloid bump
(height ``bump`` a); the equilibria do not depend on it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from forms.membrane import MembraneLaw
from meshes.data import MeshData
from meshes.membrane import close_with_base, disc_surface, tetrahedralise
from model import compat
from model.domain.distribute import Domain, build_domain
from model.fields.fibres import FibreField
from model.problem.membrane import MembraneProblem, axis_orientation
from model.solvers.membrane import InflationStep, inflate_to_volume

log = logging.getLogger(__name__)

__all__ = ["InflatedPatch", "deformed_points", "inflate_patch"]


@dataclass
class InflatedPatch:
    """The workflow's products: the membrane problem at the target volume, its pressure steps, the
    tetrahedral domain of the closed patch and its fibre field (``mesh_data`` on rank 0 only, else None)."""

    problem: MembraneProblem
    steps: list[InflationStep]
    domain: Domain
    fibres: FibreField
    mesh_data: MeshData | None


def deformed_points(problem: MembraneProblem, num_points: int) -> np.ndarray | None:
    """X + u at every input point of the surface mesh (input order), on rank 0 (None elsewhere). Collective."""
    msh = problem.domain.mesh
    geometry = compat.geometry_dofs(msh)[:, :3]
    dofs = compat.cell_dofs(problem.V.dofmap)[: len(geometry), :3]
    ids = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[geometry].reshape(-1)
    u = problem.u.x.array.reshape(-1, 3)[dofs.reshape(-1)]
    x = msh.geometry.x[geometry.reshape(-1), :3] + u
    gathered = msh.comm.gather((ids, x), root=0)
    if msh.comm.rank != 0:
        return None
    points = np.full((num_points, 3), np.nan)
    for i, xi in gathered:
        points[i] = xi
    if np.isnan(points).any():
        raise RuntimeError("deformed_points: some input points were not found on any rank")
    return points


def inflate_patch(law: MembraneLaw, target_volume: float, radius: float = 1.0, size: float = 0.15,
                  dp: float | None = None, tet_size: float = 0.15, end: float = 0.6, bump: float = 0.05,
                  comm: MPI.Comm = MPI.COMM_WORLD) -> InflatedPatch:
    """Run the workflow (module docstring) on a disc of ``radius`` meshed at ``size``. ``dp``: the pressure
    increment (default 0.05 w'(1.1) / radius, w' the law's equibiaxial dw/dlambda). Collective."""
    data = disc_surface(radius, size) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    problem = MembraneProblem(domain, law, axis_orientation(), {"rim": (0, 1, 2)})
    problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0],
                                               bump * radius * (1 - (x[0]**2 + x[1]**2) / radius**2)]))
    if dp is None:
        dp = 0.05 * law.equibiaxial(1.1)[1] / radius
    steps = inflate_to_volume(problem, target_volume, dp)
    num_points = comm.bcast(len(data.points) if comm.rank == 0 else None)
    deformed = deformed_points(problem, num_points)
    mesh_data = None
    if comm.rank == 0:
        rim = np.unique(data.facets[data.facet_tags == data.boundary_names["rim"]])
        points, triangles, side = close_with_base(data, deformed, rim)
        centre_x = np.concatenate([np.full(len(data.cells), np.nan), data.points[data.cells].mean(axis=1)[:, 0]])
        groups = [(triangles, side)]
        for tag, mask in ((3, centre_x < -end * radius), (4, centre_x > end * radius)):  # base triangles only
            groups.append((triangles[mask], np.full(int(mask.sum()), tag, np.int32)))
        mesh_data = tetrahedralise(points, np.vstack([g[0] for g in groups]), np.concatenate([g[1] for g in groups]),
                                   {"patch": 1, "base": 2, "origin": 3, "insertion": 4}, tet_size)
    tet_domain = build_domain(comm, mesh_data)
    fibres = FibreField(tet_domain).laplace("origin", "insertion")
    log.info("inflate_patch: V = %.6g at p = %.6g after %d steps", steps[-1].volume, steps[-1].pressure, len(steps))
    return InflatedPatch(problem, steps, tet_domain, fibres, mesh_data)
