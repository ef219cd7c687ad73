"""The computational domain: a distributed dolfinx mesh with named regions and boundaries.

Every mesh source (built-in generator, gmsh .msh, any tetrahedral mesh meshio
reads) is first turned into a meshes.MeshData on rank 0, then distributed here.
Named groups may overlap (a facet in two physical surfaces): each distinct set
of names an entity belongs to gets its own integer code, and a name maps to the
tuple of codes that contain it, which is what ufl.Measure accepts as subdomain id.
A named group that holds no entity (a physical group of the file without elements)
is kept by name in ``empty_regions`` / ``empty_boundaries``, so a lookup can say
"empty" rather than "missing" (region_error, boundary_error).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from meshes import MeshData
from meshes.gingerbread import PlanarMeshData
from model import compat
from model.errors import did_you_mean


@dataclass
class Domain:
    """A mesh with cell and facet tags and the codes of each named region and boundary."""

    mesh: dmesh.Mesh
    cell_tags: compat.MeshTags
    facet_tags: compat.MeshTags
    regions: dict[str, tuple[int, ...]]
    boundaries: dict[str, tuple[int, ...]]
    #: names of the file's groups that hold no cell / no facet (not in regions / boundaries)
    empty_regions: tuple[str, ...] = ()
    empty_boundaries: tuple[str, ...] = ()
    #: mesh quality from model.domain.checks (min radius ratio, where, measure), set when read for a run
    quality: dict[str, Any] = field(default_factory=dict)

    def region_cells(self, name: str) -> np.ndarray:
        """Local cells (owned and ghost) of a region; "all" is every cell."""
        if name == "all":
            imap = self.mesh.topology.index_map(self.mesh.topology.dim)
            return np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        return self.cell_tags.indices[np.isin(self.cell_tags.values, self.regions[name])]

    def boundary_facets(self, name: str) -> np.ndarray:
        """Local facets of a named boundary."""
        return self.facet_tags.indices[np.isin(self.facet_tags.values, self.boundaries[name])]

    def region_error(self, name: str) -> str | None:
        """Why ``name`` cannot be used as a region (the message after the key), or None if it can."""
        if name == "all" or name in self.regions:
            return None
        if name in self.empty_regions:
            return f"region {name!r} is empty (the physical group exists in mesh.file but holds no cells)"
        hint = did_you_mean(name, ["all", *self.regions, *self.empty_regions])
        return f"no region named {name!r} in the mesh{hint} (regions: {', '.join(['all', *sorted(self.regions)])})"

    def boundary_error(self, name: str) -> str | None:
        """Why ``name`` cannot be used as a boundary (the message after the key), or None if it can."""
        if name in self.boundaries:
            return None
        if name in self.empty_boundaries:
            return f"boundary {name!r} is empty (the physical group exists in mesh.file but holds no facets)"
        hint = did_you_mean(name, [*self.boundaries, *self.empty_boundaries])
        return (f"no boundary named {name!r} in the mesh{hint} (boundaries: "
                f"{', '.join(sorted(self.boundaries)) or 'none'})")


def _combine(entities: np.ndarray, tags: np.ndarray, names: dict[str, int]
             ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[int, ...]], np.ndarray]:
    """Unique entities, a code per entity for its set of tags, name -> codes containing its tag, and the
    rows of ``entities`` kept."""
    if entities.shape[0] == 0:
        return entities, tags.astype(np.int32), {n: () for n in names}, np.arange(0)
    key = np.sort(entities, axis=1)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    sets: list[set[int]] = [set() for _ in range(unique.shape[0])]
    for i, t in zip(inverse, tags):
        sets[i].add(int(t))
    combos: dict[frozenset[int], int] = {}
    codes = np.empty(unique.shape[0], dtype=np.int32)
    for i, s in enumerate(sets):
        codes[i] = combos.setdefault(frozenset(s), len(combos) + 1)
    by_name = {n: tuple(sorted(c for s, c in combos.items() if t in s)) for n, t in names.items()}
    # entities in the order of their first occurrence, with its vertex order: without duplicates
    # the output order is the input order (dolfinx's original_cell_index then indexes MeshData.cells)
    first = np.zeros(unique.shape[0], dtype=np.int64)
    first[inverse[::-1]] = np.arange(len(inverse))[::-1]
    order = np.argsort(first, kind="stable")
    return entities[first[order]], codes[order], by_name, first[order]


#: gmsh's tet10 edge nodes: node 4 + k sits on the edge _TET10_EDGES[k]
_TET10_EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))


def _quadratic_triangles(facets: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The 6-node triangles (dolfinx's order) of the vertex triangles ``facets`` of a tet10 mesh
    (``nodes`` in gmsh's order): each edge's middle node looked up from the cells."""
    if facets.shape[0] == 0:
        return np.empty((0, 6), dtype=np.int64)
    ends = np.concatenate([nodes[:, list(e)] for e in _TET10_EDGES])
    middle = np.concatenate([nodes[:, 4 + k] for k in range(6)])
    keys = np.sort(ends, axis=1)
    unique, first = np.unique(keys, axis=0, return_index=True)
    wanted = np.sort(np.concatenate([facets[:, [0, 1]], facets[:, [1, 2]], facets[:, [2, 0]]]), axis=1)
    position = np.searchsorted(unique[:, 0] * (nodes.max() + 1) + unique[:, 1],
                               wanted[:, 0] * (nodes.max() + 1) + wanted[:, 1])
    mid = middle[first[position]].reshape(3, -1).T  # gmsh's triangle6: vertices, then edges 01 12 20
    return np.column_stack([facets, mid])[:, compat.gmsh_node_order("triangle", 6)]


def build_domain(comm: MPI.Comm, data: MeshData | PlanarMeshData | None, root: int = 0,
                 facet_ghosts: bool = False) -> Domain:
    """Distribute a MeshData held on rank ``root`` (None elsewhere) into a Domain; quadratic cells
    (``data.nodes``) give a mesh with degree-2 (curved) geometry. A PlanarMeshData (triangles, edges as
    facets) gives a plane mesh (gdim 2, tdim 2); a meshes.membrane.SurfaceMeshData (class attribute gdim = 3)
    a surface mesh of triangles in 3D (gdim 3, tdim 2). ``facet_ghosts``: the cells across the rank border
    are ghosts on both dolfinx releases (compat.create_mesh), for interior-facet integrals."""
    if comm.rank == root:
        assert data is not None
        cells, cell_codes, regions, rows = _combine(data.cells, data.cell_tags, data.region_names)
        facets, facet_codes, boundaries, _ = _combine(data.facets, data.facet_tags, data.boundary_names)
        points = np.ascontiguousarray(data.points[:, :3], dtype=np.float64)
        degree = 1 if data.nodes is None else 2
        nvertices = data.cells.shape[1]
        gdim = int(getattr(data, "gdim", 2 if nvertices == 3 else 3))
        comm.bcast((regions, boundaries, degree, nvertices, gdim), root=root)
        # dolfinx's node order (the vertices stay first: tags and checks use cells' vertices)
        nodes = cells if degree == 1 else data.nodes[rows][:, compat.gmsh_node_order("tetrahedron", 10)]
        if degree == 2:
            facets = _quadratic_triangles(facets, data.nodes)
    else:
        regions, boundaries, degree, nvertices, gdim = comm.bcast(None, root=root)
        cells = np.empty((0, nvertices), dtype=np.int64)
        nodes = np.empty((0, nvertices if degree == 1 else 10), dtype=np.int64)
        facets = np.empty((0, nvertices - 1 if degree == 1 else 6), dtype=np.int64)
        cell_codes = np.empty(0, dtype=np.int32)
        facet_codes = np.empty(0, dtype=np.int32)
        points = np.empty((0, 3), dtype=np.float64)
    if nvertices == 3:  # triangles: plane (PlanarMeshData) or a surface in 3D (SurfaceMeshData)
        msh = compat.create_mesh(comm, nodes, points, degree, cell="triangle", gdim=gdim, facet_ghosts=facet_ghosts)
    else:
        msh = compat.create_mesh(comm, nodes, points, degree, facet_ghosts=facet_ghosts)
    tdim = msh.topology.dim
    ct = compat.meshtags_from_input(msh, tdim, nodes, cell_codes)
    ct.name = "regions"
    msh.topology.create_connectivity(tdim - 1, tdim)
    ft = compat.meshtags_from_input(msh, tdim - 1, facets, facet_codes)
    ft.name = "boundaries"
    empty_regions = tuple(sorted(n for n, codes in regions.items() if not codes))
    empty_boundaries = tuple(sorted(n for n, codes in boundaries.items() if not codes))
    return Domain(msh, ct, ft, {n: c for n, c in regions.items() if c}, {n: c for n, c in boundaries.items() if c},
                  empty_regions, empty_boundaries)
