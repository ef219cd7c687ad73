"""A render mesh embedded in the simulation mesh (thesis 4.3.2): each vertex moves with the body around it.

    embedding = Embedding.from_file(msh, "skin.obj")         # any surface meshio reads: OBJ, STL, PLY, ...
    x = embedding.positions(u)                               # (N, 3) deformed vertices on rank 0, None elsewhere
    embedding.write(path, u)                                 # the deformed surface, in the format of path's suffix

Every vertex X of the render mesh is given one cell of the simulation mesh and its reference coordinates there;
its deformed position is x = X + u(X), u evaluated with the cell's own basis (for P1 displacements the
barycentric combination x = sum_i lambda_i(X) x_i of the cell's deformed vertices; for P2 the quadratic
interpolant), so an affine motion of the body moves the render mesh exactly. A vertex inside the body takes a
cell that contains it; a vertex outside (a skin a little outside the simulation mesh) takes the cell nearest to
it, measured by the barycentric coordinates of the cell's vertices (the cell whose smallest lambda_i is largest,
among the 8 cells with the nearest midpoints on each rank), and moves with that cell's interpolant extended
beyond it. ``outside`` and ``max_outside_distance`` say how many vertices are outside and how far (to the
nearest vertex of their cell's hull, an upper bound).

MPI: the points are broadcast from rank 0; each is assigned to the lowest rank that owns a containing (or the
best nearest) cell; positions are gathered to rank 0. Collective.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from model import compat

log = logging.getLogger(__name__)


@dataclass
class SurfaceMesh:
    """A render mesh: points (N, 3) and its cell blocks (meshio's (type, connectivity) pairs)."""

    points: np.ndarray
    cells: list[tuple[str, np.ndarray]]


def read_surface(path: Path) -> SurfaceMesh:
    """The points and cells of a mesh file meshio reads (2D points get z = 0). ValueError naming the file."""
    import meshio

    try:
        mesh = meshio.read(path)
    except Exception as error:  # meshio raises many kinds (ReadError, KeyError, ValueError) for a bad file
        raise ValueError(f"{path}: not a mesh meshio can read ({type(error).__name__}: {error})") from None
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or len(points) == 0:
        raise ValueError(f"{path}: the file has no points")
    if points.shape[1] == 2:
        points = np.c_[points, np.zeros(len(points))]
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{path}: a point has a non-finite coordinate")
    cells = [(block.type, np.asarray(block.data)) for block in mesh.cells]
    return SurfaceMesh(points[:, :3].copy(), cells)


def _barycentric(vertices: np.ndarray, points: np.ndarray) -> np.ndarray:
    """lambda (n, 4) of points (n, 3) in tetrahedra (n, 4, 3) (affine: the first four nodes)."""
    T = np.transpose(vertices[:, 1:4] - vertices[:, :1], (0, 2, 1))
    rest = np.linalg.solve(T, (points - vertices[:, 0])[:, :, None])[:, :, 0]
    return np.c_[1.0 - rest.sum(axis=1), rest]


class Embedding:
    """Render-mesh vertices located in the simulation mesh ``msh`` (module docstring)."""

    def __init__(self, msh, points: np.ndarray | None, cells: list[tuple[str, np.ndarray]] | None = None,
                 neighbours: int = 8) -> None:
        comm = msh.comm
        self.msh, self.comm = msh, comm
        self.path: Path | None = None
        self.surface_cells = comm.bcast(cells if comm.rank == 0 else None, root=0) or []
        points = comm.bcast(np.asarray(points, dtype=np.float64) if comm.rank == 0 else None, root=0)
        self.points = points
        n = len(points)
        tdim = msh.topology.dim
        owned_cells = msh.topology.index_map(tdim).size_local
        # containing cells: the first owned one per point on this rank
        colliding = compat.colliding_cells(msh, points)
        cell = np.full(n, -1, dtype=np.int32)
        for i in range(n):
            links = colliding.links(i)
            links = links[links < owned_cells]
            if len(links):
                cell[i] = links[0]
        rank = np.where(cell >= 0, comm.rank, comm.size).astype(np.int32)
        owner = np.empty_like(rank)
        comm.Allreduce(rank, owner, op=MPI.MIN)
        outside = np.flatnonzero(owner == comm.size)
        distance = np.zeros(n)
        if len(outside):
            best_cell, score, dist = self._nearest_cells(points[outside], owned_cells, neighbours)
            best = np.empty_like(score)
            comm.Allreduce(score, best, op=MPI.MAX)
            mine = (score == best) & (best_cell >= 0)
            candidate = np.where(mine, comm.rank, comm.size).astype(np.int32)
            chosen = np.empty_like(candidate)
            comm.Allreduce(candidate, chosen, op=MPI.MIN)
            owner[outside] = chosen
            cell[outside] = np.where(chosen == comm.rank, best_cell, -1)
            summed = np.zeros(len(outside))
            comm.Allreduce(np.where(chosen == comm.rank, dist, 0.0), summed, op=MPI.SUM)
            distance[outside] = summed
            if np.any(chosen == comm.size):
                raise ValueError("render mesh: a vertex found no cell (is the simulation mesh empty?)")
        self.mine = np.flatnonzero(owner == comm.rank)
        self.cells = cell[self.mine]
        self.outside = int(len(outside))
        self.max_outside_distance = float(distance.max(initial=0.0))
        if self.outside:
            log.info("render mesh: %d of %d vertices outside the simulation mesh (up to %.3g away)", self.outside,
                     n, self.max_outside_distance)

    def _nearest_cells(self, points: np.ndarray, owned_cells: int, neighbours: int):
        """Per point: the owned local cell whose smallest barycentric coordinate is largest among the cells with
        the ``neighbours`` nearest midpoints, that score, and the distance to the nearest vertex of that cell."""
        if owned_cells == 0:
            return (np.full(len(points), -1, dtype=np.int32), np.full(len(points), -np.inf), np.zeros(len(points)))
        from scipy.spatial import cKDTree

        nodes = compat.geometry_dofs(self.msh)[:owned_cells, :4]
        vertices = self.msh.geometry.x[nodes]  # (cells, 4, 3)
        tree = cKDTree(vertices.mean(axis=1))
        k = min(neighbours, owned_cells)
        _, near = tree.query(points, k=k)
        near = np.asarray(near).reshape(len(points), k)
        scores = np.empty((len(points), k))
        for j in range(k):
            lam = _barycentric(vertices[near[:, j]], points)
            scores[:, j] = lam.min(axis=1)
        pick = np.argmax(scores, axis=1)
        chosen = near[np.arange(len(points)), pick].astype(np.int32)
        hull = vertices[chosen]
        dist = np.linalg.norm(hull - points[:, None, :], axis=2).min(axis=1)
        return chosen, scores[np.arange(len(points)), pick], dist

    @classmethod
    def from_file(cls, msh, path: Path | str) -> Embedding:
        """Read ``path`` on rank 0 (read_surface) and embed it. ValueError (on every rank) for a bad file."""
        comm = msh.comm
        surface, error = None, None
        if comm.rank == 0:
            try:
                surface = read_surface(Path(path))
            except ValueError as exc:
                error = str(exc)
        error = comm.bcast(error, root=0)
        if error:
            raise ValueError(error)
        embedding = cls(msh, surface.points if surface else None, surface.cells if surface else None)
        embedding.path = Path(path)
        return embedding

    def positions(self, u: fem.Function) -> np.ndarray | None:
        """x = X + u(X) of every render vertex, (N, 3) on rank 0 (None on the other ranks). Collective."""
        values = np.zeros((len(self.mine), 3))
        if len(self.mine):
            ux = np.asarray(u.eval(self.points[self.mine], self.cells)).reshape(len(self.mine), -1)
            values[:, : ux.shape[1]] = ux
        gathered = self.comm.gather((self.mine, values), root=0)
        if self.comm.rank != 0:
            return None
        out = self.points.copy()
        for index, value in gathered:
            out[index] += value
        return out

    def write(self, path: Path, u: fem.Function) -> None:
        """The deformed render mesh into ``path`` (format from its suffix, written to a temporary file and
        renamed, so an interrupted run never leaves a half-written frame). Collective; rank 0 writes."""
        x = self.positions(u)
        if self.comm.rank == 0:
            import meshio

            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            partial = path.with_name(f".{path.name}.partial{path.suffix}")
            meshio.write(partial, meshio.Mesh(x, self.surface_cells))
            os.replace(partial, path)
        self.comm.barrier()

    def summary(self) -> dict:
        """Vertices, vertices outside the body and their largest distance from it (for summary.json)."""
        return {"vertices": int(len(self.points)), "outside": self.outside,
                "max_outside_distance": self.max_outside_distance}


__all__ = ["Embedding", "SurfaceMesh", "read_surface"]
