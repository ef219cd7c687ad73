"""Triangle surface meshes in 3D for membranes (gmsh OCC), and the tetrahedral mesh of an inflated closed patch.

* ``sphere_octant(radius, size)``: the part x, y, z >= 0 of the sphere |x| = radius (a balloon with its three
  symmetry planes), boundaries ``x0``, ``y0``, ``z0`` (the quarter circles on the planes x = 0, y = 0, z = 0).
* ``sphere_surface(radius, size)``: the whole sphere, no boundary.
* ``disc_surface(radius, size)``: the disc x^2 + y^2 <= radius^2 in the plane z = 0, boundary ``rim``.

Each is a :class:`SurfaceMeshData` (the attributes of :class:`meshes.gingerbread.PlanarMeshData`, with 3D points),
region ``membrane`` (tag 1), triangles oriented (right-handed vertex order) outward (spheres) or along +z (disc),
held on one rank; ``model.domain.distribute.build_domain`` distributes it as a surface mesh (tdim 2, gdim 3).

The inflation workflow of the thesis (ch. 3.3.3): ``close_with_base(data, deformed, fixed)`` closes an inflated
patch with its flat rest shape (the base: the rest triangles reversed, its free nodes duplicated, the fixed
nodes shared), and ``tetrahedralise(points, triangles, tags, names, size)`` fills a closed triangulated surface
with tetrahedra (gmsh, the surface mesh kept as given): a :class:`meshes.data.MeshData` with region ``muscle``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import ClassVar

import gmsh
import numpy as np

from meshes._gmsh import gmsh_session
from meshes._validate import positive_float
from meshes.data import MeshData
from meshes.gingerbread import PlanarMeshData

__all__ = ["SurfaceMeshData", "close_with_base", "disc_surface", "orient_triangles", "sphere_octant", "sphere_surface",
           "surface_areas", "tetrahedralise"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class SurfaceMeshData(PlanarMeshData):
    """A triangle surface in 3D (``points`` (n, 3) with any z), the attributes of PlanarMeshData; build_domain
    makes it a manifold mesh (gdim 3, tdim 2)."""

    gdim: ClassVar[int] = 3

    def area(self, region: str = "membrane") -> float:
        """Total area of a region's triangles."""
        return float(surface_areas(self.points, self.region_cells(region)).sum())


def surface_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Area of each triangle, |(p1 - p0) x (p2 - p0)| / 2."""
    p = np.asarray(points, dtype=np.float64)[np.asarray(cells, dtype=np.int64)]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def orient_triangles(points: np.ndarray, cells: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """``cells`` with the vertex order of each triangle swapped where (p1 - p0) x (p2 - p0) . direction < 0;
    ``direction`` one vector per triangle (n, 3) or one for all (3,)."""
    cells = np.array(cells, dtype=np.int64)
    p = np.asarray(points, dtype=np.float64)[cells]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = np.einsum("ij,ij->i", normal, np.broadcast_to(direction, normal.shape)) < 0.0
    cells[flip] = cells[flip][:, [0, 2, 1]]
    return cells


def _elements(dim: int, entity: int, nvertices: int) -> np.ndarray:
    types, _, node_tags = gmsh.model.mesh.getElements(dim, entity)
    blocks = [np.asarray(n, dtype=np.int64).reshape(-1, nvertices) for t, n in zip(types, node_tags, strict=True)
              if gmsh.model.mesh.getElementProperties(int(t))[3] == nvertices]
    return np.concatenate(blocks) if blocks else np.empty((0, nvertices), dtype=np.int64)


def _extract(surfaces: list[int], boundaries: dict[str, list[int]]) -> tuple[np.ndarray, np.ndarray, dict]:
    """Points, triangles of ``surfaces`` and the edges of each named boundary (curves), in local numbering."""
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    tris = np.concatenate([_elements(2, s, 3) for s in surfaces])
    edges = {name: np.concatenate([_elements(1, c, 2) for c in curves]) if curves else np.empty((0, 2), np.int64)
             for name, curves in boundaries.items()}
    used = np.unique(tris)
    order = np.argsort(node_tags)
    points = coords[order[np.searchsorted(node_tags[order], used)]]
    return points, np.searchsorted(used, tris), {n: np.searchsorted(used, e) for n, e in edges.items()}


def _data(points: np.ndarray, cells: np.ndarray, edges: dict[str, np.ndarray]) -> SurfaceMeshData:
    names = {name: k for k, name in enumerate(edges, start=1)}
    facets = np.concatenate([edges[n] for n in names]) if names else np.empty((0, 2), dtype=np.int64)
    facet_tags = (np.concatenate([np.full(len(edges[n]), names[n], dtype=np.int32) for n in names]) if names
                  else np.empty(0, dtype=np.int32))
    return SurfaceMeshData(points, cells, np.ones(len(cells), dtype=np.int32), facets, facet_tags,
                           {"membrane": 1}, names)


def _on_sphere(points: np.ndarray, radius: float) -> np.ndarray:
    """Nodes projected radially onto the exact sphere (gmsh's are on it to round-off)."""
    return points * (radius / np.linalg.norm(points, axis=1))[:, None]


def sphere_octant(radius: float = 1.0, size: float = 0.2) -> SurfaceMeshData:
    """The octant x, y, z >= 0 of the sphere of ``radius`` (triangles of size <= ``size``), oriented outward;
    boundaries ``x0``, ``y0``, ``z0``: the edges on the planes x = 0, y = 0, z = 0."""
    R = positive_float("sphere_octant", "radius", radius)
    lc = positive_float("sphere_octant", "size", size)
    with gmsh_session({"Mesh.MeshSizeMax": lc, "Mesh.MeshSizeMin": 0.0}, name="sphere_octant"):
        gmsh.model.occ.addSphere(0.0, 0.0, 0.0, R, -1, 0.0, math.pi / 2, math.pi / 2)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(2)
        curved = []
        for _, s in gmsh.model.getEntities(2):
            c = np.array(gmsh.model.occ.getCenterOfMass(2, s))
            if np.all(np.abs(c) > 1e-6 * R):
                curved.append(s)
        plane_curves: dict[str, list[int]] = {"x0": [], "y0": [], "z0": []}
        for _, c in gmsh.model.getBoundary([(2, s) for s in curved], combined=False, oriented=False):
            xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(1, abs(c))
            for name, lo, hi in (("x0", xmin, xmax), ("y0", ymin, ymax), ("z0", zmin, zmax)):
                if max(abs(lo), abs(hi)) < 1e-6 * R:
                    plane_curves[name].append(abs(c))
        points, cells, edges = _extract(curved, plane_curves)
    points = _on_sphere(points, R)
    for k, name in enumerate(("x0", "y0", "z0")):
        points[np.unique(edges[name]), k] = 0.0
    cells = orient_triangles(points, cells, points[cells].mean(axis=1))
    data = _data(points, cells, edges)
    logger.info("sphere_octant(R=%g, size=%g): %d triangles, area %.6f (exact %.6f)", R, lc, len(cells),
                data.area(), math.pi * R**2 / 2)
    return data


def sphere_surface(radius: float = 1.0, size: float = 0.3) -> SurfaceMeshData:
    """The whole sphere of ``radius``, triangles of size <= ``size`` oriented outward; no boundary."""
    R = positive_float("sphere_surface", "radius", radius)
    lc = positive_float("sphere_surface", "size", size)
    with gmsh_session({"Mesh.MeshSizeMax": lc, "Mesh.MeshSizeMin": 0.0}, name="sphere_surface"):
        gmsh.model.occ.addSphere(0.0, 0.0, 0.0, R)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(2)
        points, cells, _ = _extract([s for _, s in gmsh.model.getEntities(2)], {})
    points = _on_sphere(points, R)
    cells = orient_triangles(points, cells, points[cells].mean(axis=1))
    return _data(points, cells, {})


def disc_surface(radius: float = 1.0, size: float = 0.1) -> SurfaceMeshData:
    """The disc of ``radius`` about the origin in the plane z = 0, triangles of size <= ``size`` oriented along
    +z, a node at the centre; boundary ``rim``."""
    a = positive_float("disc_surface", "radius", radius)
    lc = positive_float("disc_surface", "size", size)
    with gmsh_session({"Mesh.MeshSizeMax": lc, "Mesh.MeshSizeMin": 0.0}, name="disc_surface"):
        disc = gmsh.model.occ.addDisk(0.0, 0.0, 0.0, a, a)
        centre = gmsh.model.occ.addPoint(0.0, 0.0, 0.0)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.embed(0, [centre], 2, disc)
        gmsh.model.mesh.generate(2)
        surfaces = [s for _, s in gmsh.model.getEntities(2)]
        rim = [abs(c) for _, c in gmsh.model.getBoundary([(2, s) for s in surfaces], combined=True, oriented=False)]
        points, cells, edges = _extract(surfaces, {"rim": rim})
    points[:, 2] = 0.0
    cells = orient_triangles(points, cells, np.array([0.0, 0.0, 1.0]))
    return _data(points, cells, edges)


def close_with_base(data: SurfaceMeshData, deformed: np.ndarray, fixed: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed surface of an inflated patch: (points, triangles, side) with side 1 for the patch (the
    deformed positions ``deformed``, data's triangles) and 2 for the base (the rest triangles, reversed, on
    copies of the free nodes at their rest positions; the ``fixed`` nodes, e.g. the clamped rim, are shared).
    A patch oriented along its outward normal gives a closed surface oriented outward."""
    deformed = np.asarray(deformed, dtype=np.float64)
    if deformed.shape != data.points.shape:
        raise ValueError(f"close_with_base: deformed has shape {deformed.shape}, expected {data.points.shape}")
    n = len(data.points)
    free = np.setdiff1d(np.arange(n), np.asarray(fixed, dtype=np.int64))
    index = np.arange(n)
    index[free] = n + np.arange(len(free))
    points = np.vstack([deformed, data.points[free]])
    base = index[data.cells][:, [0, 2, 1]]
    triangles = np.vstack([data.cells, base])
    side = np.concatenate([np.ones(len(data.cells), np.int32), np.full(len(base), 2, np.int32)])
    return points, triangles, side


def tetrahedralise(points: np.ndarray, triangles: np.ndarray, tags: np.ndarray, names: dict[str, int],
                   size: float) -> MeshData:
    """Tetrahedra (size <= ``size`` inside) filling the closed surface ``triangles``; the surface mesh is kept
    (a gmsh discrete surface bounding a geo volume). Region ``muscle`` (1); every boundary triangle keeps its
    tag (``names``: boundary name -> tag; a triangle may be repeated with another tag to be in two groups)."""
    lc = positive_float("tetrahedralise", "size", size)
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    tags = np.asarray(tags, dtype=np.int32)
    unique = np.unique(np.sort(triangles, axis=1), axis=0, return_index=True)[1]
    surface = triangles[np.sort(unique)]
    with gmsh_session({"Mesh.MeshSizeMax": lc, "Mesh.MeshSizeMin": 0.0}, name="tetrahedralise"):
        gmsh.model.addDiscreteEntity(2, 1)
        gmsh.model.mesh.addNodes(2, 1, np.arange(1, len(points) + 1), points.reshape(-1))
        gmsh.model.mesh.addElementsByType(1, 2, [], (surface + 1).reshape(-1))
        loop = gmsh.model.geo.addSurfaceLoop([1])
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(3)
        node_tags, coords, _ = gmsh.model.mesh.getNodes()
        _, tet_nodes = gmsh.model.mesh.getElementsByType(4)
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(node_tags)
    all_points = coords[order]  # node tag k + 1 at row k: the surface nodes keep their indices
    if not np.array_equal(node_tags[order][: len(points)], np.arange(1, len(points) + 1)):
        raise RuntimeError("tetrahedralise: gmsh renumbered the surface nodes")
    tets = np.searchsorted(node_tags[order], np.asarray(tet_nodes, dtype=np.int64).reshape(-1, 4))
    p = all_points[tets]
    negative = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) < 0
    tets[negative] = tets[negative][:, [0, 2, 1, 3]]
    used = np.unique(np.concatenate([tets.reshape(-1), triangles.reshape(-1)]))
    renumber = np.full(len(all_points), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    mesh = MeshData(all_points[used], renumber[tets], np.ones(len(tets), np.int32), renumber[triangles], tags,
                    {"muscle": 1}, dict(names))
    logger.info("tetrahedralise: %d tetrahedra, %d points from %d surface triangles", len(tets), len(used),
                len(surface))
    return mesh
