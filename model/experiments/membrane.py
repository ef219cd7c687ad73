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

    result = inflate_extruded_patch(law, offset=0.02, first_volume=0.8, rest_volume=0.4, target_volume=0.8,
                                    obstacles=[(Capsule(...), k, False)], contact_fraction=0.2)

The thesis' two phases (ch. 3.3.3), on the same disc patch:

1. the patch is extruded by ``offset`` along its normal (meshes.membrane.extrude; the clamped rim stays) and the
   extrusion is inflated without contact until ``first_volume`` ("full inflation");
2. a new rest shape: alternated Laplacian smoothing and tangential relaxation of the inflated (free) vertices
   until the enclosed volume falls to ``rest_volume`` (meshes.membrane.smooth_rest_shape);
3. the membrane on that rest shape, with penalty contact against the ``obstacles``
   (model.problem.membrane_contact.ObstacleContact), is inflated until ``target_volume`` or
   ``contact_fraction`` of its area touches them. The thesis starts its (implicit Euler) dynamics at the
   extruded positions, u0 = extruded - rest ("the vertex positions of the initial extruded vertices
   constitute the initial conditions applied to the rest shape, so there is a non-negative elastic
   potential"); ``initial_energy`` records that potential. A quasi-static pressure stepping cannot start
   there: the compressed, nearly flat state snaps through to the rest dome, where Newton fails (measured:
   DIVERGED_MAX_IT at the first pressure step). Each pressure's equilibrium is on the branch that starts at
   the rest shape (u = 0, the equilibrium at p = 0), so the stepping starts from u = 0;
4. closed with the flat patch as base, tetrahedralised, Laplace fibres, as above.

A user's patch (model.experiments.membrane_run, surface = "file" with [extrusion] / [muscle]) is generally not
planar: the same steps with

* the extrusion along the patch's oriented vertex normals (meshes.membrane.extrude, as for the disc);
* the volume measured from the patch at rest: V(x) - V_b, V_b = enclosed_volume(rest patch) (the cone formula
  (1/6) sum x0 . (x1 x x2) about the origin): the closed surface "x, then the rest patch reversed" shares the
  clamped rim, so by the divergence theorem V(x) - V_b is the volume it encloses, whatever the origin (the
  disc in z = 0 has V_b = 0 exactly: the same numbers as before);
* the rest patch as the base (close_with_base), tetrahedralised;
* the fibre ends along an axis (``PatchAxis``): s = X . e - c for the base triangles' centroids, origin
  s < -end a, insertion s > end a; the disc: e = (1, 0, 0) (or a given axis), c = 0, a = radius (x < -end a
  as before); a file: e given or the patch's principal axis (``patch_axis``), c and a the middle and half of the
  nodes' extent along e;
* a tetrahedron whose four vertices all lie on one end has phi constant, grad phi = 0 (none on the plane base;
  on a curved base one may fill a valley between two base triangles): it takes the mean over its vertices of the
  nodal averages of grad phi (``laplace_fibres``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.membrane import MembraneLaw
from forms.obstacles import Obstacle
from meshes.data import MeshData
from meshes.membrane import (
    SmoothedShape,
    SurfaceMeshData,
    close_with_base,
    disc_surface,
    extrude,
    smooth_rest_shape,
    tetrahedralise,
)
from model import compat
from model.domain.distribute import Domain, build_domain
from model.fields.fibres import FibreField, solve_laplace
from model.problem.membrane import MembraneProblem, axis_orientation, triangle_orientation
from model.problem.membrane_contact import ObstacleContact
from model.solvers.membrane import InflationStep, inflate_to_volume

log = logging.getLogger(__name__)

__all__ = ["InflatedPatch", "PatchAxis", "cell_values", "close_and_mesh", "deformed_points", "inflate_extruded_patch",
           "inflate_patch", "laplace_fibres", "patch_axis", "set_nodal_displacement"]

#: patch_axis refuses a principal axis whose second moment exceeds the next one's by less than this fraction
ROUND_PATCH = 0.05


@dataclass(frozen=True)
class PatchAxis:
    """The line the fibres run along: s(X) = X . e - c, e = ``direction`` (unit), c = ``centre``; the patch
    spans about s in [-a, a], a = ``half_length``."""

    direction: tuple[float, float, float]
    centre: float
    half_length: float

    def position(self, points: np.ndarray) -> np.ndarray:
        """s = X . e - c at each point (n, 3)."""
        return np.asarray(points, dtype=np.float64) @ np.asarray(self.direction, dtype=np.float64) - self.centre

    def ends(self, points: np.ndarray, cells: np.ndarray, end: float) -> tuple[np.ndarray, np.ndarray]:
        """The triangles whose centroid has s < -end a (origin) and s > end a (insertion): two bool masks."""
        s = self.position(np.asarray(points, dtype=np.float64)[np.asarray(cells, dtype=np.int64)].mean(axis=1))
        limit = end * self.half_length
        return s < -limit, s > limit


def patch_axis(points: np.ndarray, cells: np.ndarray, axis: tuple[float, float, float] | None = None) -> PatchAxis:
    """The axis of a patch: e = ``axis`` normalised, or the principal axis, the eigenvector of the largest
    eigenvalue of the area-weighted second moment sum_T A_T (x_T - m)(x_T - m)^T of the triangles' centroids x_T
    about their mean m, its largest component made positive; c and a the middle and half of min..max of X . e
    over the nodes. ValueError when the two largest moments are within ROUND_PATCH of the largest (a round patch
    has no principal axis)."""
    points = np.asarray(points, dtype=np.float64)
    cells = np.asarray(cells, dtype=np.int64)
    if axis is not None:
        e = np.asarray(axis, dtype=np.float64)
        e = e / np.linalg.norm(e)
    else:
        p = points[cells]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        x = p.mean(axis=1)
        d = x - (area @ x) / area.sum()
        moments, vectors = np.linalg.eigh((d * area[:, None]).T @ d)
        if moments[1] > (1.0 - ROUND_PATCH) * moments[2]:
            raise ValueError(f"the patch has no principal axis: its two largest second moments {moments[2]:.6g} "
                             f"and {moments[1]:.6g} are within {ROUND_PATCH:.0%} (a round patch)")
        e = vectors[:, 2]
        e = e if e[np.argmax(np.abs(e))] > 0 else -e
    s = points[np.unique(cells)] @ e
    return PatchAxis(tuple(float(c) for c in e), float(0.5 * (s.max() + s.min())), float(0.5 * (s.max() - s.min())))


@dataclass
class InflatedPatch:
    """The workflow's products: the membrane problem at the target volume, its pressure steps, the
    tetrahedral domain of the closed patch and its fibre field (``mesh_data`` on rank 0 only, else None)."""

    problem: MembraneProblem
    steps: list[InflationStep]
    domain: Domain
    fibres: FibreField
    mesh_data: MeshData | None
    #: inflate_extruded_patch only: the first phase's steps, the extruded and the smoothed rest points (rank 0)
    first_steps: list[InflationStep] | None = None
    extruded: np.ndarray | None = None
    smoothing: SmoothedShape | None = None
    contacts: list[ObstacleContact] | None = None
    #: the second phase's elastic energy at the extruded positions (>= 0, the thesis' initial condition)
    initial_energy: float | None = None


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


def cell_values(fibres: FibreField) -> np.ndarray | None:
    """The fibre directions of every cell of the mesh (num_cells_global, 3) in the input cell order (the order
    of the MeshData the domain was built from: FibreField.from_cell_array's and a .npy fibre file's), on rank 0
    (None elsewhere). Collective."""
    msh = fibres.domain.mesh
    owned = msh.topology.index_map(msh.topology.dim).size_local
    original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)[:owned]
    dofs = compat.cell_dofs(fibres.function.function_space.dofmap).reshape(-1)[:owned]
    values = fibres.function.x.array.reshape(-1, 3)[dofs]
    gathered = msh.comm.gather((original, values), root=0)
    if msh.comm.rank != 0:
        return None
    array = np.full((msh.topology.index_map(msh.topology.dim).size_global, 3), np.nan)
    for index, value in gathered:
        array[index] = value
    if np.isnan(array).any():
        raise RuntimeError("cell_values: some cells were not found on any rank")
    return array


def set_nodal_displacement(problem: MembraneProblem, values: np.ndarray) -> None:
    """u = values[input index] at every node (``values`` (num_points, 3), the same on every rank)."""
    msh = problem.domain.mesh
    geometry = compat.geometry_dofs(msh)[:, :3]
    dofs = compat.cell_dofs(problem.V.dofmap)[: len(geometry), :3]
    ids = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)[geometry].reshape(-1)
    array = problem.u.x.array.reshape(-1, 3)
    array[dofs.reshape(-1)] = np.asarray(values, dtype=np.float64)[ids]
    problem.u.x.scatter_forward()


def close_and_mesh(data: SurfaceMeshData | None, deformed: np.ndarray | None, axis: PatchAxis | float, end: float,
                   tet_size: float, comm: MPI.Comm, rim: np.ndarray | None = None
                   ) -> tuple[Domain, FibreField, MeshData | None]:
    """Close the inflated patch (``deformed``: X + u at the input points of the patch ``data``, rank 0) with the
    rest ``data`` as base, tetrahedralise, Laplace fibres (steps 2-3 of the module docstring; the ends along
    ``axis``, a float: the disc's radius a, e = (1, 0, 0), c = 0). ``rim``: the clamped nodes the patch and the
    base share (default: data's boundary "rim"). Returns the distributed tetrahedral domain, its fibre field and
    the MeshData (rank 0, else None). Collective."""
    if not isinstance(axis, PatchAxis):
        axis = PatchAxis((1.0, 0.0, 0.0), 0.0, float(axis))
    mesh_data = None
    if comm.rank == 0:
        if rim is None:
            rim = np.unique(data.facets[data.facet_tags == data.boundary_names["rim"]])
        points, triangles, side = close_with_base(data, deformed, rim)
        origin, insertion = axis.ends(data.points, data.cells, end)
        none = np.zeros(len(data.cells), dtype=bool)
        groups = [(triangles, side)]
        for tag, mask in ((3, np.concatenate([none, origin])), (4, np.concatenate([none, insertion]))):  # base
            groups.append((triangles[mask], np.full(int(mask.sum()), tag, np.int32)))
        mesh_data = tetrahedralise(points, np.vstack([g[0] for g in groups]), np.concatenate([g[1] for g in groups]),
                                   {"patch": 1, "base": 2, "origin": 3, "insertion": 4}, tet_size)
    tet_domain = build_domain(comm, mesh_data)
    return tet_domain, laplace_fibres(tet_domain), mesh_data


def laplace_fibres(domain: Domain, origin: str = "origin", insertion: str = "insertion") -> FibreField:
    """FibreField(domain).laplace(origin, insertion), a0 = grad phi / |grad phi|, except in the cells where grad phi
    vanishes (|grad phi| <= 1e-8 of its largest: phi constant, every vertex on one end): there a0 is the mean over
    the cell's vertices of the nodal averages g_i = int grad phi psi_i dx / int psi_i dx (psi_i the P1 hat
    functions: the area-weighted mean of the gradients of the cells around node i, nonzero next to the cells where
    phi varies). Collective."""
    msh = domain.mesh
    fibres = FibreField(domain)
    phi = solve_laplace(domain, origin, insertion)
    grad = compat.evaluate(fem.Expression(ufl.grad(phi), np.zeros((1, 3)) + 0.25), msh, fibres.cells).reshape(-1, 3)
    norm = np.linalg.norm(grad, axis=1)
    flat = norm <= 1e-8 * msh.comm.allreduce(float(norm.max(initial=0.0)), op=MPI.MAX)
    count = msh.comm.allreduce(int(np.count_nonzero(flat)), op=MPI.SUM)
    if count:  # on every rank: the assembly is collective
        Q = compat.function_space(msh, "Lagrange", 1)
        q = ufl.TestFunction(Q)
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 1})
        sums = []
        for integrand in (q, *(phi.dx(k) * q for k in range(3))):
            total = fem.Function(Q)
            vector = compat.petsc_vector(total)
            fem_petsc.assemble_vector(vector, fem.form(integrand * dx))
            vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
            sums.append(total.x.array.copy())
        nodal = np.column_stack(sums[1:]) / sums[0][:, None]
        grad[flat] = nodal[compat.cell_dofs(Q.dofmap)[fibres.cells[flat]]].mean(axis=1)
        log.info("laplace_fibres: %d cells with grad phi = 0 (every vertex on one end) take their vertices' mean",
                 count)
    return fibres.set_values(grad)


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
    tet_domain, fibres, mesh_data = close_and_mesh(data, deformed, radius, end, tet_size, comm)
    log.info("inflate_patch: V = %.6g at p = %.6g after %d steps", steps[-1].volume, steps[-1].pressure, len(steps))
    return InflatedPatch(problem, steps, tet_domain, fibres, mesh_data)


def inflate_extruded_patch(law: MembraneLaw, offset: float, first_volume: float, rest_volume: float,
                           target_volume: float, obstacles: list[tuple[Obstacle, float, bool]] | None = None,
                           contact_fraction: float | None = None, radius: float = 1.0, size: float = 0.15,
                           dp: float | None = None, tet_size: float = 0.15, end: float = 0.6,
                           comm: MPI.Comm = MPI.COMM_WORLD) -> InflatedPatch:
    """The thesis' two inflation phases (module docstring) on a disc of ``radius`` meshed at ``size``;
    ``obstacles``: (obstacle, penalty k, inside) for the second phase. Collective."""
    data = disc_surface(radius, size) if comm.rank == 0 else None
    rim = np.unique(data.facets[data.facet_tags == data.boundary_names["rim"]]) if comm.rank == 0 else None
    extruded = extrude(data, offset, rim) if comm.rank == 0 else None
    if dp is None:
        dp = 0.05 * law.equibiaxial(1.1)[1] / radius
    # phase 1: the extrusion inflated without contact
    first = MembraneProblem(build_domain(comm, extruded), law, axis_orientation(), {"rim": (0, 1, 2)})
    first_steps = inflate_to_volume(first, first_volume, dp)
    num_points = comm.bcast(len(data.points) if comm.rank == 0 else None)
    inflated = deformed_points(first, num_points)
    # the new rest shape: smoothing and relaxation of the free nodes down to rest_volume
    smoothing = smooth_rest_shape(inflated, data.cells, rim, rest_volume) if comm.rank == 0 else None
    rest = None
    if comm.rank == 0:
        rest = SurfaceMeshData(smoothing.points, data.cells, data.cell_tags, data.facets, data.facet_tags,
                               data.region_names, data.boundary_names)
    orientation = comm.bcast((rest.points, rest.cells) if comm.rank == 0 else None)
    problem = MembraneProblem(build_domain(comm, rest), law, triangle_orientation(*orientation), {"rim": (0, 1, 2)})
    u0 = comm.bcast(extruded.points - rest.points if comm.rank == 0 else None)
    set_nodal_displacement(problem, u0)
    initial_energy = problem.elastic_energy()
    problem.u.x.array[:] = 0.0
    contacts = [ObstacleContact(problem, obstacle, k, inside) for obstacle, k, inside in (obstacles or [])]
    # phase 2: from the extruded positions, with contact, to the target volume or contact fraction
    steps = inflate_to_volume(problem, target_volume, dp, contact_fraction=contact_fraction)
    deformed = deformed_points(problem, num_points)
    tet_domain, fibres, mesh_data = close_and_mesh(data, deformed, radius, end, tet_size, comm)
    log.info("inflate_extruded_patch: V = %.6g, contact fraction %.4g at p = %.6g after %d + %d steps",
             steps[-1].volume, steps[-1].contact_fraction, steps[-1].pressure, len(first_steps), len(steps))
    return InflatedPatch(problem, steps, tet_domain, fibres, mesh_data, first_steps,
                         extruded.points if comm.rank == 0 else None, smoothing, contacts, initial_energy)
