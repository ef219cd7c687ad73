"""A slotted (C-shaped) block: one body whose two arms face each other across a thin slot (self-contact).

The block [0, L] x [0, W] x [0, 2a + s] with the slot (spine, L] x [0, W] x (a, a + s) cut out: a spine
[0, spine] joins the lower arm z in [0, a] and the upper arm z in [a + s, 2a + s], whose faces z = a
(``slot_lower``, outward normal +z) and z = a + s (``slot_upper``, -z) face each other at distance s. A structured
grid (cells of about ``h``, one cell across the slot) with the slot's hexahedra removed, 6 tetrahedra each
(meshes._structured), so the arms stay one conforming body with the spine.
"""

from __future__ import annotations

import numpy as np

from meshes._structured import grid_indices, kuhn_cells
from meshes._validate import ParameterError, positive_float
from meshes.data import MeshData
from meshes.topology import boundary_facets, orient_positive

__all__ = ["SLOTTED_FACES", "slotted_block"]

#: the boundaries of :func:`slotted_block` (tags 1..), then ``slot`` (slot_lower and slot_upper) and ``surface``
SLOTTED_FACES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax", "slot_lower", "slot_upper", "slot_end")


def _axis(pieces: list[tuple[float, float]], h: float) -> tuple[np.ndarray, list[int]]:
    """Nodes along an axis from consecutive pieces (start, end), each cut into round(length / h) >= 1 cells; the
    node index where each piece starts."""
    nodes, starts = [pieces[0][0]], []
    for a, b in pieces:
        starts.append(len(nodes) - 1)
        n = max(1, int(round((b - a) / h)))
        nodes.extend(np.linspace(a, b, n + 1)[1:])
    return np.asarray(nodes), starts


def slotted_block(length: float = 2.0, width: float = 0.5, arm: float = 0.4, slot: float = 0.05,
                  spine: float = 0.5, h: float = 0.25) -> MeshData:
    """The slotted block (module docstring).

    Returns
    -------
    MeshData
        Volume ``body``; boundaries ``xmin xmax ymin ymax zmin zmax`` (the outer faces; xmax is both arms'
        ends), ``slot_lower`` ``slot_upper`` (the slot's faces), ``slot_end`` (x = spine, the slot's bottom),
        ``slot`` (slot_lower and slot_upper) and ``surface`` (the whole boundary).
    """
    for name, value in (("length", length), ("width", width), ("arm", arm), ("slot", slot), ("spine", spine),
                        ("h", h)):
        positive_float("slotted_block", name, value)
    if spine >= length:
        raise ParameterError(f"slotted_block: spine must be < length, got {spine!r} >= {length!r}")
    x, (_, i_slot) = _axis([(0.0, spine), (spine, length)], h)
    y, _ = _axis([(0.0, width)], h)
    arm_nodes, _ = _axis([(0.0, arm)], h)  # one cell across the slot
    z = np.r_[arm_nodes, arm + slot + arm_nodes]
    k_slot = len(arm_nodes) - 1
    cells = (len(x) - 1, len(y) - 1, len(z) - 1)
    ijk = grid_indices(cells)
    points = np.stack([x[ijk[:, 0]], y[ijk[:, 1]], z[ijk[:, 2]]], axis=1)
    nx, ny, nz = cells
    k, _, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    solid = ~((i.ravel() >= i_slot) & (k.ravel() == k_slot))
    tets = kuhn_cells(cells).reshape(-1, 6, 4)[solid].reshape(-1, 4)
    used = np.unique(tets)
    renumber = np.full(len(points), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    points, ijk, tets = points[used], ijk[used], renumber[tets]
    tets = orient_positive(points, tets)
    boundary = boundary_facets(tets)
    g = ijk[boundary]  # (facets, 3 vertices, 3 grid coordinates)

    def on(axis: int, value: int) -> np.ndarray:
        return np.all(g[:, :, axis] == value, axis=1)

    in_slot = np.all(g[:, :, 0] >= i_slot, axis=1)
    groups = {"xmin": on(0, 0), "xmax": on(0, nx), "ymin": on(1, 0), "ymax": on(1, ny), "zmin": on(2, 0),
              "zmax": on(2, nz), "slot_lower": on(2, k_slot) & in_slot, "slot_upper": on(2, k_slot + 1) & in_slot,
              "slot_end": on(0, i_slot) & np.all((g[:, :, 2] >= k_slot) & (g[:, :, 2] <= k_slot + 1), axis=1)}
    groups["slot"] = groups["slot_lower"] | groups["slot_upper"]
    groups["surface"] = np.ones(len(boundary), dtype=bool)
    facets, tags = [], []
    for tag, mask in enumerate(groups.values(), start=1):
        facets.append(boundary[mask])
        tags.append(np.full(int(mask.sum()), tag, dtype=np.int32))
    return MeshData(points=points, cells=tets, cell_tags=np.ones(len(tets), dtype=np.int32),
                    facets=np.concatenate(facets), facet_tags=np.concatenate(tags), region_names={"body": 1},
                    boundary_names={name: tag for tag, name in enumerate(groups, start=1)})
