"""Structured tetrahedral mesh of Cook's membrane, extruded along z."""

from __future__ import annotations

import numpy as np

from meshes._structured import grid_indices, structured_mesh
from meshes._validate import positive_float, positive_int
from meshes.data import MeshData

__all__ = ["COOK_AREA", "COOK_CORNERS", "COOK_FACES", "cook"]

#: In-plane corners (mm) of the Cook membrane, counter-clockwise from the origin.
COOK_CORNERS = ((0.0, 0.0), (48.0, 44.0), (48.0, 60.0), (0.0, 44.0))
#: Area of the trapezoid (mm^2): parallel sides 44 (x=0) and 16 (x=48), width 48.
COOK_AREA = 0.5 * (44.0 + 16.0) * 48.0
#: Boundary names (facet tags 1..6) of :func:`cook`.
COOK_FACES = ("left", "right", "bottom", "top", "front", "back")


def cook_map(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear map of the unit square onto the Cook trapezoid (straight grid lines)."""
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = COOK_CORNERS
    x = (1 - s) * (1 - t) * x0 + s * (1 - t) * x1 + s * t * x2 + (1 - s) * t * x3
    y = (1 - s) * (1 - t) * y0 + s * (1 - t) * y1 + s * t * y2 + (1 - s) * t * y3
    return x, y


def cook(cells: int = 8, layers: int = 1, thickness: float = 1.0) -> MeshData:
    """Mesh Cook's membrane (corners (0,0), (48,44), (48,60), (0,44) mm) extruded to ``z in [0, thickness]``.

    A ``cells x cells x layers`` hexahedral grid of the unit cube is mapped
    bilinearly onto the trapezoid and each hexahedron is split into 6 tetrahedra
    (Kuhn subdivision), so the mesh is structured, conforming and deterministic,
    and its volume is exactly ``1440 * thickness``.

    Parameters
    ----------
    cells:
        Subdivisions along each in-plane edge (the mesh size parameter), >= 1.
    layers:
        Subdivisions through the thickness, >= 1.
    thickness:
        Extrusion length along z, > 0.

    Returns
    -------
    MeshData
        Volume ``body`` (tag 1); faces ``left`` (x=0, clamped), ``right`` (x=48,
        loaded), ``bottom`` (edge (0,0)-(48,44)), ``top`` (edge (0,44)-(48,60)),
        ``front`` (z=0), ``back`` (z=thickness), tags 1..6 in that order.
    """
    n = positive_int("cook", "cells", cells)
    nz = positive_int("cook", "layers", layers)
    depth = positive_float("cook", "thickness", thickness)
    ijk = grid_indices((n, n, nz))
    unit = np.linspace(0.0, 1.0, n + 1)
    x, y = cook_map(unit[ijk[:, 0]], unit[ijk[:, 1]])
    z = np.linspace(0.0, depth, nz + 1)[ijk[:, 2]]
    return structured_mesh(np.stack([x, y, z], axis=1), (n, n, nz), COOK_FACES)
