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
(d) curved (10-node, degree-2 geometry) cells, after (a)-(c) pass: the isoparametric map
    X(xi) = sum_a N_a(xi) x_a has J = dX/dxi = sum_a x_a (grad_xi N_a)^T, and det J, a cubic in xi, is
    6 V_c everywhere for straight sides. An edge node moved far enough (along its edge past the quarter
    point, or across the cell) makes det J change sign inside the cell although the vertex tetrahedron
    is fine: the map folds (a run then can die in its first residual, NaN, or solve for a body that
    overlaps itself). det J is evaluated at the points of the degree-4 rule (CURVED_RULE_DEGREE, 14
    points) and at the 10 nodes; a cell with sign(V_c) det J <= 6e-12 h^3 at any of them (against its own
    vertex tetrahedron's orientation, which (a) and (b) have accepted, or zero at the scale of (a)) is an
    error naming the worst cells, ordered by r_c = min det J / max |det J| over the cell's points (with
    det J taken in the vertex tetrahedron's sense). Sampled: a fold small enough to lie between the points
    is not seen; an edge node moved along its edge past the quarter point makes det J < 0 at the near
    vertex, one of the nodes. min_c r_c (1 for straight sides) is ``quality["min_jacobian_ratio"]``.
    Vectorised: one matrix product per block of cells; 0.016 s for 11 019 cells, 3.5 % of reading that
    mesh (benchmarks/curved_check.py; docs/configuration.md, "Mesh checks").

Quality (a warning, and ``Domain.quality`` for summary.json): the normalised radius ratio
q = 3 r_in / r_circ, with r_in = 3 |V| / (sum of the face areas) and r_circ the circumsphere's
radius; q = 1 for the regular tetrahedron, q -> 0 for slivers, needles and caps. Below
QUALITY_WARNING = 0.02 the gradients in that cell are poor (its condition number grows like 1/q)
and the stiffness matrix ill-conditioned: the run warns once with the worst value and where it is.
The threshold is below what gmsh's Delaunay meshes of the shipped examples reach (min q 0.18-0.72,
the fusiform muscles 0.050 and 0.062, which solve well), so it flags real slivers only; 0.1, the
usual "poor element" mark, would warn on the shipped muscles. A curved (degree-2) cell's radius ratio
is measured on its four vertices (its curvature is checked by (d)). The built-in generators mesh again
with another seed when their first mesh has a sliver (meshes._gmsh.generate_tetrahedra: gmsh 4.8 left a
flat boundary tetrahedron, q = 0.0067, in examples/arm_flexion.toml's muscle on one machine and not on
another), so the warning is for files.
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


# --- curved (10-node) cells --------------------------------------------------------------------------------

#: the edges of dolfinx's (basix's) 10-node tetrahedron: geometry node 4 + k sits on edge k
P2_EDGES = ((2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1))
#: the degree of the quadrature rule whose points, with the 10 nodes, sample det J of a curved cell
CURVED_RULE_DEGREE = 4
#: cells per block of the vectorised evaluation: its temporaries (~ 2 kB a cell) stay in the cache (256 to 1024
#: cells: 4 times faster than 16384 at 11k cells)
_BLOCK = 512


def p2_reference_nodes() -> np.ndarray:
    """The 10 nodes of the reference tetrahedron in dolfinx's order: the vertices (0,0,0), (1,0,0), (0,1,0),
    (0,0,1), then the midpoints of the edges P2_EDGES."""
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return np.vstack([vertices, [(vertices[a] + vertices[b]) / 2 for a, b in P2_EDGES]])


def p2_gradients(points: np.ndarray) -> np.ndarray:
    """dN_a/dxi_k of the 10 quadratic Lagrange functions at reference points (m, 3): (m, 10, 3).

    With the barycentric coordinates L_0 = 1 - xi_1 - xi_2 - xi_3, L_i = xi_i: the vertex functions
    N_i = L_i (2 L_i - 1), grad N_i = (4 L_i - 1) grad L_i; the edge functions N_{4+k} = 4 L_a L_b on edge
    k = (a, b), grad N_{4+k} = 4 (L_b grad L_a + L_a grad L_b).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    lam = np.column_stack([1.0 - points.sum(axis=1), points])  # (m, 4)
    grad_lam = np.vstack([-np.ones(3), np.eye(3)])  # (4, 3)
    out = np.empty((len(points), 10, 3))
    out[:, :4] = (4.0 * lam - 1.0)[:, :, None] * grad_lam[None]
    for k, (a, b) in enumerate(P2_EDGES):
        out[:, 4 + k] = 4.0 * (lam[:, b, None] * grad_lam[a] + lam[:, a, None] * grad_lam[b])
    return out


def p2_jacobian_determinants(x: np.ndarray, points: np.ndarray) -> np.ndarray:
    """det J = det(dX/dxi) of the isoparametric map X(xi) = sum_a N_a(xi) x_a of 10-node tetrahedra with
    node coordinates ``x`` (n, 10, 3), dolfinx's order, at reference points (m, 3): (n, m).

    J_ik = sum_a x_ai dN_a/dxi_k (p2_gradients); det J = J_:1 . (J_:2 x J_:3) (columns dX/dxi_k). For straight
    sides (edge nodes at the midpoints) det J = 6 V, the signed volume of the vertex tetrahedron, at every point.
    """
    gradients = p2_gradients(points)
    m = len(gradients)
    table = gradients.transpose(1, 2, 0).reshape(10, 3 * m)  # (a, (k, q))
    out = np.empty((len(x), m))
    for start in range(0, len(x), _BLOCK):
        block = x[start:start + _BLOCK]
        # one matrix product: (n i, a) @ (a, k q) -> J[n, i, k, q]
        jac = (block.transpose(0, 2, 1).reshape(-1, 10) @ table).reshape(len(block), 3, 3, m)
        c1, c2, c3 = jac[:, :, 0], jac[:, :, 1], jac[:, :, 2]  # the columns dX/dxi_k: (n, i, q)
        out[start:start + _BLOCK] = (c1[:, 0] * (c2[:, 1] * c3[:, 2] - c2[:, 2] * c3[:, 1])
                                     + c1[:, 1] * (c2[:, 2] * c3[:, 0] - c2[:, 0] * c3[:, 2])
                                     + c1[:, 2] * (c2[:, 0] * c3[:, 1] - c2[:, 1] * c3[:, 0]))
    return out


def _point(x: np.ndarray) -> str:
    return "(" + ", ".join(f"{c:.6g}" for c in x) + ")"


def _check_curved(msh: Any, key: str, original: np.ndarray, centroids: np.ndarray, volumes: np.ndarray,
                  h: float) -> float:
    """The curved-cell check of check_mesh (module docstring, (d)) on the owned cells; returns the minimum over
    the mesh of min det J / max |det J| per cell, the same on every rank, or raises ConfigError."""
    comm = msh.comm
    num_owned = len(volumes)
    x = msh.geometry.x[compat.geometry_dofs(msh)[:num_owned]][:, :, :3]  # (n, 10, 3)
    points = np.vstack([compat.quadrature_points(msh, CURVED_RULE_DEGREE), p2_reference_nodes()])
    det = np.sign(volumes)[:, None] * p2_jacobian_determinants(x, points)  # > 0: the vertex tetrahedron's sense
    lowest = det.min(axis=1) if num_owned else np.empty(0)
    ratio = lowest / np.maximum(np.abs(det).max(axis=1), np.finfo(float).tiny) if num_owned else np.empty(0)
    bad = lowest <= 6 * 1e-12 * h**3
    n_bad = comm.allreduce(int(bad.sum()), op=MPI.SUM)
    if n_bad:
        local = [(float(ratio[i]), int(original[i]), centroids[i].tolist()) for i in np.flatnonzero(bad)]
        worst = sorted(sum(comm.allgather(local), []), key=lambda r: (r[0], r[1]))[:WORST]
        what = ", ".join(f"cell {i} at {_point(np.asarray(c))}" for _, i, c in worst)
        cells = "1 curved cell is" if n_bad == 1 else f"{n_bad} curved cells are"
        raise ConfigError(f"{key}: {cells} inverted (the Jacobian determinant of the 10-node map is negative or "
                          f"zero inside the cell, its vertices' tetrahedron is not), worst: {what}; "
                          f"in the worst, min det J / max |det J| = {worst[0][0]:.3g}")
    return comm.allreduce(float(ratio.min()) if num_owned else np.inf, op=MPI.MIN)


def check_mesh(msh: Any, key: str) -> dict[str, Any]:
    """Check a distributed tetrahedral mesh for folds, and a curved (10-node) one for inverted curved cells
    (ConfigError naming ``key``, on every rank), and measure its quality; returns {"min_radius_ratio",
    "worst_cell", "worst_cell_centroid", "measure"} and, for a curved mesh, "min_jacobian_ratio" (module
    docstring, (d)), the same on every rank. Warns (rank 0, once) when the minimum radius ratio is below
    QUALITY_WARNING."""
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

    curved = compat.geometry_degree(msh) > 1
    jacobian_ratio = _check_curved(msh, key, original, centroids, volumes, h) if curved else None

    q = radius_ratio(xc)
    i = int(np.lexsort((original, q))[0]) if num_owned else -1  # ties: the lowest input index
    local_min = (float(q[i]), int(original[i]), centroids[i].tolist()) if num_owned else (np.inf, -1, [])
    q_min, worst_cell, where = min(comm.allgather(local_min), key=lambda r: (r[0], r[1]))
    quality = {"min_radius_ratio": q_min, "worst_cell": worst_cell, "worst_cell_centroid": where,
               "measure": QUALITY_MEASURE}
    if jacobian_ratio is not None:
        quality["min_jacobian_ratio"] = jacobian_ratio
    n_low = comm.allreduce(int(np.sum(q < QUALITY_WARNING)), op=MPI.SUM)
    if q_min < QUALITY_WARNING and comm.rank == 0:
        log.warning("%s: %d sliver or degenerate cells (radius ratio 3 r_in / r_circ < %g), worst %.3g: cell %d at %s;"
                    " expect poor stresses there and an ill-conditioned stiffness", key, n_low, QUALITY_WARNING,
                    q_min, worst_cell, _point(np.asarray(where)))
    return quality
