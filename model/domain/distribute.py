"""The computational domain: a distributed dolfinx mesh with named regions and boundaries.

Every mesh source (built-in generator, gmsh .msh, any tetrahedral mesh meshio
reads) is first turned into a meshes.MeshData on rank 0, then distributed here.
Named groups may overlap (a facet in two physical surfaces): each distinct set
of names an entity belongs to gets its own integer code, and a name maps to the
tuple of codes that contain it, which is what ufl.Measure accepts as subdomain id.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from meshes import MeshData
from model import compat


@dataclass
class Domain:
    """A mesh with cell and facet tags and the codes of each named region and boundary."""

    mesh: dmesh.Mesh
    cell_tags: compat.MeshTags
    facet_tags: compat.MeshTags
    regions: dict[str, tuple[int, ...]]
    boundaries: dict[str, tuple[int, ...]]

    def region_cells(self, name: str) -> np.ndarray:
        """Local cells (owned and ghost) of a region; "all" is every cell."""
        if name == "all":
            imap = self.mesh.topology.index_map(self.mesh.topology.dim)
            return np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        return self.cell_tags.indices[np.isin(self.cell_tags.values, self.regions[name])]

    def boundary_facets(self, name: str) -> np.ndarray:
        """Local facets of a named boundary."""
        return self.facet_tags.indices[np.isin(self.facet_tags.values, self.boundaries[name])]


def _combine(entities: np.ndarray, tags: np.ndarray, names: dict[str, int]
             ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[int, ...]]]:
    """Unique entities, a code per entity for its set of tags, and name -> codes containing its tag."""
    if entities.shape[0] == 0:
        return entities, tags.astype(np.int32), {n: () for n in names}
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
    return entities[first[order]], codes[order], by_name


def build_domain(comm: MPI.Comm, data: MeshData | None, root: int = 0) -> Domain:
    """Distribute a MeshData held on rank ``root`` (None elsewhere) into a Domain."""
    if comm.rank == root:
        assert data is not None
        cells, cell_codes, regions = _combine(data.cells, data.cell_tags, data.region_names)
        facets, facet_codes, boundaries = _combine(data.facets, data.facet_tags, data.boundary_names)
        points = np.ascontiguousarray(data.points[:, :3], dtype=np.float64)
        comm.bcast((regions, boundaries), root=root)
    else:
        regions, boundaries = comm.bcast(None, root=root)
        cells = np.empty((0, 4), dtype=np.int64)
        facets = np.empty((0, 3), dtype=np.int64)
        cell_codes = np.empty(0, dtype=np.int32)
        facet_codes = np.empty(0, dtype=np.int32)
        points = np.empty((0, 3), dtype=np.float64)
    msh = compat.create_mesh(comm, cells, points)
    tdim = msh.topology.dim
    ct = compat.meshtags_from_input(msh, tdim, cells, cell_codes)
    ct.name = "regions"
    msh.topology.create_connectivity(tdim - 1, tdim)
    ft = compat.meshtags_from_input(msh, tdim - 1, facets, facet_codes)
    ft.name = "boundaries"
    return Domain(msh, ct, ft, regions, boundaries)
