"""Several meshes as one mesh of separate bodies (for contact and sliding between bodies).

    data = combine({"lower": box(...), "upper": moved(box(...), (0, 0, 1))})

The bodies share no node (a body touching another does so through two surfaces, one of each). Each body's cells
form a region named after it (a body with several regions keeps them, as "<body>_<region>", instead); each boundary
becomes "<body>_<boundary>", and "<body>_surface" is the body's whole boundary (every boundary triangle).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from meshes.data import MeshData
from meshes.topology import boundary_facets


def moved(data: MeshData, offset: Sequence[float]) -> MeshData:
    """The mesh translated by ``offset``."""
    return MeshData(data.points + np.asarray(offset, dtype=float), data.cells, data.cell_tags, data.facets,
                    data.facet_tags, dict(data.region_names), dict(data.boundary_names), data.nodes)


def combine(bodies: Mapping[str, MeshData]) -> MeshData:
    """One MeshData of the bodies (module docstring); linear meshes only."""
    points, cells, cell_tags, facets, facet_tags = [], [], [], [], []
    regions: dict[str, int] = {}
    boundaries: dict[str, int] = {}
    offset, next_tag = 0, 1
    for name, data in bodies.items():
        if data.nodes is not None:
            raise ValueError(f"{name}: combine takes linear meshes only")
        points.append(data.points)
        cells.append(data.cells + offset)
        if len(data.region_names) > 1:  # the body's own regions as "<body>_<region>" (a cell carries one tag)
            mapping = {}
            for region, tag in data.region_names.items():
                regions[f"{name}_{region}"] = mapping[tag] = next_tag
                next_tag += 1
            tags = np.array([mapping.get(t, 0) for t in data.cell_tags], dtype=np.int32)
        else:
            regions[name] = next_tag
            tags = np.full(len(data.cells), next_tag, dtype=np.int32)
            next_tag += 1
        cell_tags.append(tags)
        for boundary, tag in data.boundary_names.items():
            new = len(boundaries) + 1
            boundaries[f"{name}_{boundary}"] = new
            chosen = data.facets[data.facet_tags == tag]
            facets.append(chosen + offset)
            facet_tags.append(np.full(len(chosen), new, dtype=np.int32))
        surface = boundary_facets(data.cells)
        if f"{name}_surface" in boundaries:
            raise ValueError(f"{name}: a boundary named 'surface' would clash with {name}_surface (the whole "
                             "boundary): rename it")
        new = len(boundaries) + 1
        boundaries[f"{name}_surface"] = new
        facets.append(surface + offset)
        facet_tags.append(np.full(len(surface), new, dtype=np.int32))
        offset += len(data.points)
    return MeshData(np.vstack(points), np.vstack(cells), np.concatenate(cell_tags), np.vstack(facets),
                    np.concatenate(facet_tags), regions, boundaries)


__all__ = ["combine", "moved"]
