"""Mesh checks at read time, before any solve: folded or inverted cells, and cell quality.

Computed on the distributed mesh (each rank its owned cells, from the geometry as dolfinx stores
it: the first four geometry nodes of a cell are its vertices, in the cell's vertex order), reduced
over the communicator, so one and two ranks give the same result and the same message.

Folds (an error, ConfigError starting with the mesh key):

(a) the signed volume V_c = det[x1 - x0, x2 - x0, x3 - x0] / 6 of each cell. The input's
    orientation is not prescribed (a file may hold either), so the sign alone is no error: a cell
    whose sign is against the mesh's majority is *inverted* when it also lies on a fold (b);
    a cell with |V_c| <= 1e-12 h^3 (h the mean edge length) is degenerate, an error by itself.
(b) for each interior facet with vertices a, b, c (ordered by global vertex number, so both sides
    use the same plane) and normal n = (b - a) x (c - a), the two cells' opposite vertices p, q
    must lie on opposite sides: sign(n.(p - a)) != sign(n.(q - a)). Same side: the cells overlap
    (a fold). Facets held by cells on two ranks are matched by their global index.
(c) the divergence theorem over the exterior facets (each oriented away from its cell's opposite
    vertex): V_surface = sum_f (x_f - x_o) . n_f A_f / 3 (x_f the facet's centroid, x_o the centre
    of the bounding box) is the volume the surface encloses. Without folds sum_c |V_c| = V_surface;
    a fold counts the overlap twice, sum_c |V_c| = V_surface + 2 sum_inverted |V_c|, so
    sum_c |V_c| / V_surface - 1 > 1e-9 is an error even when (b) finds no facet.

Quality (a warning, and ``Domain.quality`` for summary.json): the normalised radius ratio
q = 3 r_in / r_circ, with r_in = 3 |V| / (sum of the face areas) and r_circ the circumsphere's
radius; q = 1 for the regular tetrahedron, q -> 0 for slivers, needles and caps. Below
QUALITY_WARNING = 0.02 the gradients in that cell are poor (its condition number grows like 1/q)
and the stiffness matrix ill-conditioned: the run warns once with the worst value and where it is.
The threshold is below what gmsh's Delaunay meshes of the shipped examples reach (min q 0.18-0.72,
the fusiform muscles 0.050 and 0.062, which solve well), so it flags real slivers only; 0.1, the
usual "poor element" mark, would warn on the shipped muscles. A curved (degree-2) cell is measured
on its four vertices. The built-in generators mesh again with another seed when their first mesh has a
sliver (meshes._gmsh.generate_tetrahedra: gmsh 4.8 left a flat boundary tetrahedron, q = 0.0067, in
examples/arm_flexion.toml's muscle on one machine and not on another), so the warning is for files.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from mpi4py import MPI

from meshes.topology import SLIVER_RADIUS_RATIO, radius_ratio
from model import compat
from model.errors import ConfigError

log = logging.getLogger(__name__)

#: relative tolerance of sum |V_c| against the volume the boundary surface encloses
VOLUME_RTOL = 1e-9
#: q = 3 r_in / r_circ below which the run warns (see the module docstring); the generators regenerate below it
QUALITY_WARNING = SLIVER_RADIUS_RATIO
#: how many of the worst cells an error or warning names
WORST = 3
#: the measure named in summary.json
QUALITY_MEASURE = "normalised radius ratio 3 r_in / r_circ (1 regular tetrahedron, 0 degenerate)"


def signed_volumes(x: np.ndarray) -> np.ndarray:
    """V = det[x1 - x0, x2 - x0, x3 - x0] / 6 of tetrahedra given by vertex coordinates (n, 4, 3)."""
    e = x[:, 1:, :] - x[:, :1, :]
    return np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2])) / 6.0


def _point(x: np.ndarray) -> str:
    return "(" + ", ".join(f"{c:.6g}" for c in x) + ")"


def check_mesh(msh: Any, key: str) -> dict[str, Any]:
    """Check a distributed tetrahedral mesh for folds (ConfigError naming ``key``, on every rank) and
    measure its quality; returns {"min_radius_ratio", "worst_cell", "worst_cell_centroid", "measure"},
    the same on every rank. Warns (rank 0, once) when the minimum is below QUALITY_WARNING."""
    comm = msh.comm
    tdim = msh.topology.dim
    num_owned = msh.topology.index_map(tdim).size_local
    geo = compat.geometry_dofs(msh)[:num_owned, :4]
    xc = msh.geometry.x[geo][:, :, :3]  # (n, 4, 3) vertex coordinates in the stored vertex order
    original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)[:num_owned]
    centroids = xc.mean(axis=1)
    volumes = signed_volumes(xc)

    # global scales: mean edge length (degeneracy), bounding box centre (divergence theorem origin)
    edges = np.linalg.norm(xc[:, [1, 2, 3, 2, 3, 3]] - xc[:, [0, 0, 0, 1, 1, 2]], axis=2)
    n_cells = comm.allreduce(num_owned, op=MPI.SUM)
    h = comm.allreduce(float(edges.sum()), op=MPI.SUM) / max(6 * n_cells, 1)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    comm.Allreduce(xc.reshape(-1, 3).min(axis=0) if num_owned else lo.copy(), lo, op=MPI.MIN)
    comm.Allreduce(xc.reshape(-1, 3).max(axis=0) if num_owned else hi.copy(), hi, op=MPI.MAX)
    origin = 0.5 * (lo + hi)
    degenerate = np.abs(volumes) <= 1e-12 * h**3
    positive = comm.allreduce(int(np.sum(volumes > 0)), op=MPI.SUM)
    negative = comm.allreduce(int(np.sum(volumes < 0)), op=MPI.SUM)
    majority = 1.0 if positive >= negative else -1.0

    # (b): per (owned cell, facet) the side of the opposite vertex relative to the facet's canonical plane
    msh.topology.create_connectivity(tdim, tdim - 1)
    msh.topology.create_connectivity(tdim - 1, 0)
    msh.topology.create_connectivity(tdim, 0)
    c2f = compat.cell_dofs(msh.topology.connectivity(tdim, tdim - 1))[:num_owned]
    f2v = compat.cell_dofs(msh.topology.connectivity(tdim - 1, 0))
    c2v = compat.cell_dofs(msh.topology.connectivity(tdim, 0))[:num_owned]
    vertex_global = msh.topology.index_map(0).local_to_global(np.arange(
        msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts, dtype=np.int32))
    fv = f2v[c2f]  # (n, 4, 3) local vertices of each cell's facets
    in_facet = (c2v[:, None, :, None] == fv[:, :, None, :]).any(axis=3)  # (n, 4 facets, 4 cell vertices)
    opposite_pos = np.argmin(in_facet, axis=2)  # the cell vertex not on the facet
    order = np.argsort(vertex_global[fv], axis=2)
    fv_sorted = np.take_along_axis(fv, order, axis=2)
    # positions of the facet's vertices within the cell: coordinates come from the cell's geometry nodes
    pos = np.argmax(c2v[:, None, None, :] == fv_sorted[:, :, :, None], axis=3)  # (n, 4, 3)
    rows = np.arange(num_owned)[:, None, None]
    a, b, c = (xc[rows[:, :, 0], pos[:, :, i]] for i in range(3))
    p = xc[np.arange(num_owned)[:, None], opposite_pos]
    normal = np.cross(b - a, c - a)
    side = np.sign(np.einsum("ijk,ijk->ij", normal, p - a))  # (n, 4)

    facet_imap = msh.topology.index_map(tdim - 1)
    facets = c2f.reshape(-1)
    cells_of = np.repeat(np.arange(num_owned), 4)
    sides = side.reshape(-1)
    counts = np.bincount(facets, minlength=facet_imap.size_local + facet_imap.num_ghosts)
    from dolfinx import mesh as dmesh

    exterior = np.zeros(counts.size, dtype=bool)
    exterior[dmesh.exterior_facet_indices(msh.topology)] = True
    single = counts[facets] == 1
    is_ext = single & exterior[facets]
    shared = single & ~exterior[facets]
    pair = counts[facets] >= 2

    folded: set[int] = set()  # local owned cells on a fold facet
    # local interior facets: both cells owned here
    idx = np.flatnonzero(pair)
    by_facet = idx[np.argsort(facets[idx], kind="stable")]
    fs = facets[by_facet]
    starts = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
    ends = np.r_[starts[1:], len(fs)]
    for s, e in zip(starts, ends):
        sd = sides[by_facet[s:e]]
        if e - s != 2 or sd[0] == sd[1] or sd[0] == 0:
            folded.update(int(cells_of[k]) for k in by_facet[s:e])
    # facets between ranks: matched by global index over all ranks
    sidx = np.flatnonzero(shared)
    records = np.column_stack([
        facet_imap.local_to_global(facets[sidx].astype(np.int32)).astype(np.float64) if len(sidx) else
        np.empty(0), sides[sidx], original[cells_of[sidx]].astype(np.float64)])
    everything = np.concatenate([r.reshape(-1, 3) for r in comm.allgather(records)])
    bad_remote: set[int] = set()  # original indices of cells on folded inter-rank facets
    if len(everything):
        srt = everything[np.lexsort((everything[:, 2], everything[:, 0]))]
        starts = np.flatnonzero(np.r_[True, srt[1:, 0] != srt[:-1, 0]])
        ends = np.r_[starts[1:], len(srt)]
        for s, e in zip(starts, ends):
            if e - s != 2 or srt[s, 1] == srt[s + 1, 1] or srt[s, 1] == 0:
                bad_remote.update(int(v) for v in srt[s:e, 2])
    mine = np.isin(original, np.fromiter(bad_remote, dtype=np.int64, count=len(bad_remote)))
    on_fold = np.zeros(num_owned, dtype=bool)
    on_fold[list(folded)] = True
    on_fold |= mine

    # (c): the volume the exterior surface encloses
    eidx = np.flatnonzero(is_ext)
    k, j = cells_of[eidx], eidx % 4
    fa, fb, fc = a[k, j], b[k, j], c[k, j]
    area_vec = 0.5 * np.cross(fb - fa, fc - fa)
    outward = -side[k, j]  # the opposite vertex is inside: the outward normal points away from it
    enclosed_local = float(np.sum(outward * np.einsum("ij,ij->i", (fa + fb + fc) / 3.0 - origin, area_vec)) / 3.0)
    enclosed = comm.allreduce(enclosed_local, op=MPI.SUM)
    total = comm.allreduce(float(np.abs(volumes).sum()), op=MPI.SUM)
    ratio = total / enclosed if enclosed > 0 else np.inf

    # the cells to name: inverted cells on folds (against the majority), else every cell on a fold; degenerate
    inverted = on_fold & (np.sign(volumes) != majority)
    if comm.allreduce(int(inverted.sum()), op=MPI.SUM) == 0:
        inverted = on_fold
    bad = inverted | degenerate
    n_bad = comm.allreduce(int(bad.sum()), op=MPI.SUM)
    n_degenerate = comm.allreduce(int(degenerate.sum()), op=MPI.SUM)
    if n_bad or not abs(ratio - 1.0) <= VOLUME_RTOL:
        local = [(-abs(float(volumes[i])) if not degenerate[i] else 0.0, int(original[i]), centroids[i].tolist())
                 for i in np.flatnonzero(bad)]
        worst = sorted(sum(comm.allgather(local), []), key=lambda r: (r[0], r[1]))[:WORST]
        what = ", ".join(f"cell {i} at {_point(x)}" for _, i, x in worst)
        surface = f"the cell volumes add up to {ratio:.6g} times the volume the surface encloses"
        if n_degenerate and n_degenerate == n_bad:
            message = f"{n_bad} cells are degenerate (zero volume), worst: {what}; {surface}"
        elif n_bad:
            message = (f"{n_bad} cells are folded over their neighbours (inverted or overlapping), worst: {what}"
                       + (f" ({n_degenerate} of them degenerate)" if n_degenerate else "") + f"; {surface}")
        else:
            message = (f"{surface} (sum |V| = {total:.6g}, enclosed {enclosed:.6g}): cells overlap, or the "
                       "boundary surface is not closed")
        raise ConfigError(f"{key}: {message}")

    q = radius_ratio(xc)
    i = int(np.lexsort((original, q))[0]) if num_owned else -1  # ties: the lowest input index
    local_min = (float(q[i]), int(original[i]), centroids[i].tolist()) if num_owned else (np.inf, -1, [])
    q_min, worst_cell, where = min(comm.allgather(local_min), key=lambda r: (r[0], r[1]))
    quality = {"min_radius_ratio": q_min, "worst_cell": worst_cell, "worst_cell_centroid": where,
               "measure": QUALITY_MEASURE}
    n_low = comm.allreduce(int(np.sum(q < QUALITY_WARNING)), op=MPI.SUM)
    if q_min < QUALITY_WARNING and comm.rank == 0:
        log.warning("%s: %d sliver or degenerate cells (radius ratio 3 r_in / r_circ < %g), worst %.3g: cell %d at %s;"
                    " expect poor stresses there and an ill-conditioned stiffness", key, n_low, QUALITY_WARNING,
                    q_min, worst_cell, _point(np.asarray(where)))
    return quality
