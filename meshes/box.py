"""Structured tetrahedral mesh of an axis-aligned box."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from meshes._structured import grid_indices, structured_mesh
from meshes._validate import positive_floats, positive_ints
from meshes.data import MeshData

__all__ = ["BOX_FACES", "box"]

#: Boundary names (facet tags 1..6) of :func:`box`.
BOX_FACES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")


def box(size: Sequence[float] = (1.0, 1.0, 1.0), cells: Sequence[int] = (4, 4, 4)) -> MeshData:
    """Mesh the box ``[0, Lx] x [0, Ly] x [0, Lz]`` with exactly 6 tetrahedra per hexahedron.

    Parameters
    ----------
    size:
        Edge lengths ``(Lx, Ly, Lz)``, all > 0.
    cells:
        Number of hexahedra ``(nx, ny, nz)`` along each axis, all >= 1.

    Returns
    -------
    MeshData
        ``6 nx ny nz`` positively oriented tetrahedra on ``(nx+1)(ny+1)(nz+1)``
        vertices; volume ``body`` (tag 1); faces ``xmin, xmax, ymin, ymax, zmin,
        zmax`` (tags 1..6).
    """
    lengths = positive_floats("box", "size", size, 3)
    counts = positive_ints("box", "cells", cells, 3)
    nx, ny, nz = counts
    axes = [np.linspace(0.0, length, n + 1) for length, n in zip(lengths, counts, strict=True)]
    ijk = grid_indices((nx, ny, nz))
    points = np.stack([axes[d][ijk[:, d]] for d in range(3)], axis=1)
    return structured_mesh(points, (nx, ny, nz), BOX_FACES)
