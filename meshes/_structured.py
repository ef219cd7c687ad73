"""Structured hexahedral grids split conformingly into tetrahedra (numpy only).

Every hexahedron of an ``nx x ny x nz`` grid is cut into the 6 tetrahedra of the
Kuhn (Freudenthal) subdivision along its ``(0,0,0) -> (1,1,1)`` diagonal.  Since
all hexahedra use the same diagonal direction, neighbouring hexahedra cut their
shared face along the same diagonal, so the tetrahedral mesh is conforming.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import permutations

import numpy as np

from meshes.data import MeshData
from meshes.topology import boundary_facets, orient_positive

__all__ = ["grid_indices", "kuhn_cells", "structured_mesh"]

Cells3 = tuple[int, int, int]


def grid_indices(cells: Cells3) -> np.ndarray:
    """Integer grid coordinates ``(i, j, k)`` of all vertices, shape ``(n, 3)``, ``i`` varying fastest."""
    nx, ny, nz = cells
    k, j, i = np.meshgrid(np.arange(nz + 1), np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
    return np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1).astype(np.int64)


def _kuhn_local(cells: Cells3) -> np.ndarray:
    """Vertex-index offsets of the 6 Kuhn tetrahedra relative to a hexahedron's ``(0,0,0)`` corner."""
    nx, ny, _ = cells
    stride = np.array([1, nx + 1, (nx + 1) * (ny + 1)], dtype=np.int64)
    local = []
    for perm in permutations(range(3)):
        corner = np.zeros(3, dtype=np.int64)
        path = [corner.copy()]
        for axis in perm:
            corner[axis] = 1
            path.append(corner.copy())
        local.append([int(p @ stride) for p in path])
    return np.array(local, dtype=np.int64)


def kuhn_cells(cells: Cells3) -> np.ndarray:
    """Tetrahedra (``(6 nx ny nz, 4)`` int64) of the Kuhn subdivision of the structured grid."""
    nx, ny, nz = cells
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    base = (i + (nx + 1) * (j + (ny + 1) * k)).ravel().astype(np.int64)
    return (base[:, None, None] + _kuhn_local(cells)[None, :, :]).reshape(-1, 4)


def structured_mesh(
    points: np.ndarray, cells: Cells3, face_names: Sequence[str], region: str = "body"
) -> MeshData:
    """Build :class:`MeshData` from the mapped vertices of a structured grid.

    Parameters
    ----------
    points:
        ``(n, 3)`` coordinates of the grid vertices in :func:`grid_indices` order.
    cells:
        Number of hexahedra ``(nx, ny, nz)`` along the three grid directions.
    face_names:
        Six boundary names for the grid faces ``i=0, i=nx, j=0, j=ny, k=0, k=nz``;
        they get facet tags 1..6.
    region:
        Name of the single physical volume (tag 1).
    """
    if len(face_names) != 6:
        raise ValueError(f"structured_mesh: need 6 face names, got {len(face_names)}")
    ijk = grid_indices(cells)
    tets = orient_positive(points, kuhn_cells(cells))
    boundary = boundary_facets(tets)
    corners = ijk[boundary]  # (k, 3 vertices, 3 grid coordinates)
    facets, tags = [], []
    for tag in range(1, 7):
        axis, side = divmod(tag - 1, 2)
        value = cells[axis] if side else 0
        on_face = np.all(corners[:, :, axis] == value, axis=1)
        facets.append(boundary[on_face])
        tags.append(np.full(int(on_face.sum()), tag, dtype=np.int32))
    return MeshData(
        points=points,
        cells=tets,
        cell_tags=np.ones(len(tets), dtype=np.int32),
        facets=np.concatenate(facets),
        facet_tags=np.concatenate(tags),
        region_names={region: 1},
        boundary_names={name: tag for tag, name in enumerate(face_names, start=1)},
    )
