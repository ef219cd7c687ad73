"""Unstructured triangle mesh of a gingerbread-man outline in the plane z = 0 (gmsh OCC), the 2D body of the
skinning problem (issue 13, seed mixed-fem-skinning-sgi).

Geometry (units of length; the figure stands on y = 0, symmetric about x = 0, about 2 tall)::

    head        disc, centre (0, 1.68), radius 0.32                      (top at y = 2)
    body        rectangle x in [-0.36, 0.36], y in [0.62, 1.42], rounded by a disc of radius 0.36 at its top
    arms        rectangle x in [-0.92, 0.92], y in [1.08, 1.30], hands discs radius 0.15 at (+-0.92, 1.19)
    legs        rectangles x in +-[0.06, 0.32], y in [0.14, 0.72], feet discs radius 0.15 at (+-0.19, 0.15)

fused into one outline. The handle regions are the parts of the figure inside five boxes at its extremities:

    left_foot   y < 0.16, x < 0          right_foot  y < 0.16, x > 0
    left_hand   x < -0.86                right_hand  x > 0.86
    head        y > 1.82

(left = negative x). The figure is fragmented by these boxes so each region is meshed conformingly.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import gmsh
import numpy as np

from meshes._gmsh import gmsh_session
from meshes._validate import positive_float

__all__ = ["GINGERBREAD_BOUNDARIES", "GINGERBREAD_HANDLES", "GINGERBREAD_REGIONS", "PlanarMeshData",
           "gingerbread", "triangle_areas"]

logger = logging.getLogger(__name__)

#: Handle regions (cell tags 2..6) of :func:`gingerbread`, each with its box (xmin, ymin, xmax, ymax).
GINGERBREAD_HANDLES: dict[str, tuple[float, float, float, float]] = {
    "left_foot": (-1.0, -0.5, 0.0, 0.16),
    "right_foot": (0.0, -0.5, 1.0, 0.16),
    "left_hand": (-1.5, 0.5, -0.86, 1.8),
    "right_hand": (0.86, 0.5, 1.5, 1.8),
    "head": (-1.0, 1.82, 1.0, 2.5),
}
#: Cell region names in tag order: ``body`` (tag 1, every triangle) and the handles (tags 2..6).
GINGERBREAD_REGIONS = ("body", *GINGERBREAD_HANDLES)
#: Boundary names (edge tag 1): the whole outline.
GINGERBREAD_BOUNDARIES = ("outline",)


@dataclass(frozen=True, eq=False)
class PlanarMeshData:
    """A triangle mesh in the plane with named (possibly overlapping) physical groups, held on one rank.

    The attribute names are those of :class:`meshes.data.MeshData`, so ``model.domain.distribute.build_domain``
    distributes either. A triangle in several named regions appears once per region in ``cells`` (with that
    region's tag), as an edge in several boundaries does in ``facets``.

    Attributes
    ----------
    points:
        ``(n, 3)`` float64 vertex coordinates, z = 0.
    cells:
        ``(m, 3)`` int64 vertex indices, counter-clockwise (positive signed area).
    cell_tags:
        ``(m,)`` int32 region tag of each row of ``cells``.
    facets:
        ``(k, 2)`` int64 boundary edges.
    facet_tags:
        ``(k,)`` int32 boundary tag of each edge.
    region_names, boundary_names:
        Name -> tag.
    nodes:
        Always None (straight-sided triangles).
    """

    points: np.ndarray
    cells: np.ndarray
    cell_tags: np.ndarray
    facets: np.ndarray
    facet_tags: np.ndarray
    region_names: dict[str, int] = field(default_factory=dict)
    boundary_names: dict[str, int] = field(default_factory=dict)
    nodes: None = None

    def region_cells(self, name: str) -> np.ndarray:
        """Triangles of the region ``name`` (``KeyError`` if unknown)."""
        return self.cells[self.cell_tags == self.region_names[name]]

    def area(self, region: str = "body") -> float:
        """Area (sum of the triangles' signed areas) of a region."""
        return float(triangle_areas(self.points, self.region_cells(region)).sum())


def triangle_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed area of each triangle, ``((p1 - p0) x (p2 - p0))_z / 2``."""
    p = np.asarray(points, dtype=np.float64)[np.asarray(cells, dtype=np.int64)]
    a, b = p[:, 1, :2] - p[:, 0, :2], p[:, 2, :2] - p[:, 0, :2]
    return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def _outline() -> list[tuple[int, int]]:
    """The fused gingerbread outline (OCC surfaces) in the current model."""
    occ = gmsh.model.occ
    parts = [
        occ.addDisk(0.0, 1.68, 0.0, 0.32, 0.32),                 # head
        occ.addRectangle(-0.36, 0.62, 0.0, 0.72, 0.80),          # body
        occ.addDisk(0.0, 1.42, 0.0, 0.36, 0.36),                 # shoulders
        occ.addRectangle(-0.92, 1.08, 0.0, 1.84, 0.22),          # arms
        occ.addDisk(-0.92, 1.19, 0.0, 0.15, 0.15),               # hands
        occ.addDisk(0.92, 1.19, 0.0, 0.15, 0.15),
        occ.addRectangle(-0.32, 0.14, 0.0, 0.26, 0.58),          # legs
        occ.addRectangle(0.06, 0.14, 0.0, 0.26, 0.58),
        occ.addDisk(-0.19, 0.15, 0.0, 0.15, 0.15),               # feet
        occ.addDisk(0.19, 0.15, 0.0, 0.15, 0.15),
    ]
    fused, _ = occ.fuse([(2, parts[0])], [(2, p) for p in parts[1:]])
    return fused


def build_gingerbread_model() -> dict[str, list[int]]:
    """Create the fragmented outline and its physical groups in the current gmsh model; return the
    surfaces of each region."""
    occ = gmsh.model.occ
    figure = _outline()
    boxes = [(2, occ.addRectangle(x0, y0, 0.0, x1 - x0, y1 - y0)) for x0, y0, x1, y1 in GINGERBREAD_HANDLES.values()]
    _, mapping = occ.fragment(figure, boxes)
    occ.synchronize()
    inside = {tag for pieces in mapping[: len(figure)] for _, tag in pieces}
    regions: dict[str, list[int]] = {"body": sorted(inside)}
    for name, pieces in zip(GINGERBREAD_HANDLES, mapping[len(figure):], strict=True):
        regions[name] = sorted(tag for _, tag in pieces if tag in inside)
        if not regions[name]:
            raise RuntimeError(f"gingerbread: the handle box of {name!r} misses the figure")
    outside = sorted({tag for pieces in mapping[len(figure):] for _, tag in pieces} - inside)
    if outside:
        occ.remove([(2, t) for t in outside], recursive=True)
        occ.synchronize()
    owners: dict[int, int] = {}
    for _, curve in gmsh.model.getBoundary([(2, t) for t in regions["body"]], combined=False, oriented=False):
        owners[abs(curve)] = owners.get(abs(curve), 0) + 1
    for tag, name in enumerate(GINGERBREAD_REGIONS, start=1):
        gmsh.model.addPhysicalGroup(2, regions[name], tag)
        gmsh.model.setPhysicalName(2, tag, name)
    gmsh.model.addPhysicalGroup(1, sorted(c for c, n in owners.items() if n == 1), 1)
    gmsh.model.setPhysicalName(1, 1, GINGERBREAD_BOUNDARIES[0])
    return regions


def _elements(dim: int, entity: int, nvertices: int) -> np.ndarray:
    """Vertex node tags of the linear elements of one entity."""
    types, _, node_tags = gmsh.model.mesh.getElements(dim, entity)
    blocks = [np.asarray(n, dtype=np.int64).reshape(-1, nvertices) for t, n in zip(types, node_tags, strict=True)
              if gmsh.model.mesh.getElementProperties(int(t))[3] == nvertices]
    return np.concatenate(blocks) if blocks else np.empty((0, nvertices), dtype=np.int64)


def _groups(dim: int, nvertices: int) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """Elements of every physical group of dimension ``dim`` (repeated per group), their tags, the names."""
    blocks, tags, names = [np.empty((0, nvertices), dtype=np.int64)], [np.empty(0, dtype=np.int32)], {}
    for _, group in gmsh.model.getPhysicalGroups(dim):
        names[gmsh.model.getPhysicalName(dim, group)] = int(group)
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, group):
            conn = _elements(dim, int(entity), nvertices)
            blocks.append(conn)
            tags.append(np.full(len(conn), group, dtype=np.int32))
    return np.concatenate(blocks), np.concatenate(tags), names


def gingerbread(size: float = 0.08) -> PlanarMeshData:
    """Mesh the gingerbread-man outline (module docstring) with linear triangles of maximum size ``size``.

    Call it on one rank (it runs gmsh) and distribute the result with
    ``model.domain.distribute.build_domain(comm, data_or_None)``, which returns the dolfinx mesh (gdim 2), the
    cell and facet tags and the name -> codes of every region and boundary.

    Parameters
    ----------
    size:
        Maximum element size, > 0 (0.08 gives about 820 triangles, 0.1 about 600).

    Returns
    -------
    PlanarMeshData
        Regions ``body`` (1: every triangle), ``left_foot`` (2), ``right_foot`` (3), ``left_hand`` (4),
        ``right_hand`` (5), ``head`` (6); boundary ``outline`` (1). Triangles counter-clockwise.
    """
    lc = positive_float("gingerbread", "size", size)
    start = time.perf_counter()
    with gmsh_session({"Mesh.MeshSizeMax": lc, "Mesh.MeshSizeMin": 0.0}, name="gingerbread"):
        build_gingerbread_model()
        gmsh.model.mesh.generate(2)
        node_tags, coords, _ = gmsh.model.mesh.getNodes()
        tris, cell_tags, region_names = _groups(2, 3)
        edges, facet_tags, boundary_names = _groups(1, 2)
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    used = np.unique(tris)
    order = np.argsort(node_tags)
    position = order[np.searchsorted(node_tags[order], used)]
    points = coords[position]
    points[:, 2] = 0.0
    cells = np.searchsorted(used, tris)
    negative = triangle_areas(points, cells) < 0.0
    cells[negative] = cells[negative][:, [0, 2, 1]]
    mesh = PlanarMeshData(points, cells, cell_tags, np.searchsorted(used, edges), facet_tags,
                          region_names, boundary_names)
    logger.info("gingerbread(size=%g): %d triangles, %d points, area %.6f in %.2f s", lc,
                int(np.sum(cell_tags == 1)), len(points), mesh.area(), time.perf_counter() - start)
    return mesh
