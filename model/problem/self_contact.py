"""Self-contact of one deformable body: a surface's deformed boundary as both slave and master (issue 14).

The thesis computes the fat layer's self-collisions in the elbow's folding region explicitly (they make its lateral
bulge). Here a named surface S of the mesh (a body's whole boundary, or a part of it) is both the slave and the
master of a model.problem.body_contact.BodyContact of kind "contact": frictionless penalty (optionally the
augmented Lagrangian, Uzawa updates of the nodal pressure), energy, gap, chain rule R = dPi_c/du + Pi^T dPi_c/dz and
UFL-derived tangent exactly as there (only the closest-point search differs; ``exact=True``: BodyContact's exact
contact, every derivative by UFL, a consistent potential and backtracking on it). Every node s of S is a slave; its
master is the closest point x* of the deformed S among the triangles T that pass the exclusion rule:

    (1) neighbourhood: T has no vertex within ``rings`` - 1 edges of s along S's edges (rings = 1: T does not
        contain s; the default 2: T touches neither s nor any node joined to s by an edge of S);
    (2) facing: N_s . n_T < -1/2 (FACING), N_s the area-weighted unit normal of s on S (the normalised sum of the
        outward normals of S's triangles at s), n_T T's outward unit normal, both in the current configuration:
        the two sides face each other (their normals more than 120 degrees apart);
    (3) reach: |x_s - x*| <= ``reach`` (default: the mean edge length of S's triangles at rest).

A node with no such triangle is not paired: n = 0 at it, so g = 0 and it carries no energy, force or tangent
(its augmented multiplier is reset to 0). (1) leaves out the trivial pairs (a node and its own triangles, at
distance 0); (2) the triangles beside it on a curved or folded surface (their normals nearly parallel to N_s);
(3) the far side of a closed convex surface (a ball's antipodes face each other, at the diameter's distance, and
would read as a penetration of -2R). The candidates are the triangles whose centroid lies within reach plus the
largest centroid-to-vertex distance of S's triangles (a k-d tree ball query); among them the closest, ties (equal
distances up to 1e-14 relative) to the smallest global triangle, so the pairing is the same on any partition.

What the rule cannot see: a fold sharper than rings - 1 edges (two triangles of one node's neighbourhood pressed
into each other: refine the mesh) and a penetration deeper than ``reach`` (the node is not paired and passes
through: choose k so that the penetration p/k stays well below it). P1 displacement formulation only.

Measured on the slotted block (tests/test_self_contact.py, docs/layers.md): the same answer as the two-surface
contact of the slot's faces both ways (difference 0), Newton with full steps converging linearly (rate ~0.36: the
BodyContact tangent lags the pairing, T, b_j and n_T; J d is 0.3 % off central differences of R there); with
``exact=True`` quadratic (the last step 19, 2.9e-2, 1.4e-6, 9.8e-12: 4 iterations against 21; 28 in all against 42).
The augmented Lagrangian gives the pairs' answer too but its Uzawa updates stall near 1e-7 x size (two passes: both
sides' multipliers share the load in no unique way).
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from model.problem.body_contact import BodyContact, closest_points_on_triangles
from model.problem.elasticity import ElasticityProblem

log = logging.getLogger(__name__)

#: a slave node and a master triangle face each other when N_s . n_T < -FACING (normals > 120 degrees apart)
FACING = 0.5


def neighbourhood_keys(tri: np.ndarray, count: int, rings: int) -> np.ndarray:
    """The pairs of the ``count`` nodes of the triangles ``tri`` (local node numbers) within rings - 1 edges of each
    other: the nonzeros of (I + A)^(rings - 1), A the edge adjacency, as sorted keys row * count + column."""
    rows = np.concatenate([tri[:, i] for i in (0, 1, 2, 1, 2, 0)])
    cols = np.concatenate([tri[:, i] for i in (1, 2, 0, 0, 1, 2)])
    step = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(count, count)) + sp.identity(count, format="csr")
    near = sp.identity(count, format="csr")
    for _ in range(rings - 1):
        near = (near @ step).tocsr()
    near = near.tocoo()
    return np.sort(near.row.astype(np.int64) * count + near.col.astype(np.int64))


def candidate_pairs(xs: np.ndarray, x_tri: np.ndarray, reach: float, node_rows: np.ndarray, tri: np.ndarray,
                    neighbourhood: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(slave row, triangle) candidates: the triangles whose centroid lies within ``reach`` plus the largest
    centroid-to-vertex distance of the triangles of each point ``xs`` (a k-d tree ball query), less those with a
    vertex in the point's neighbourhood (``neighbourhood_keys``; ``node_rows``: each point's node number there)."""
    from scipy.spatial import cKDTree

    centroids = x_tri.mean(axis=1)
    radius = reach + float(np.linalg.norm(x_tri - centroids[:, None], axis=2).max())
    lists = cKDTree(centroids).query_ball_point(xs, radius)
    lengths = np.array([len(c) for c in lists], dtype=np.int64)
    rows = np.repeat(np.arange(len(xs)), lengths)
    cols = np.concatenate([np.asarray(c, dtype=np.int64) for c in lists]) if lengths.sum() else \
        np.zeros(0, dtype=np.int64)
    keys = node_rows[rows][:, None] * count + tri[cols]
    position = np.minimum(np.searchsorted(neighbourhood, keys), len(neighbourhood) - 1)
    keep = ~np.any(neighbourhood[position] == keys, axis=1)
    return rows[keep], cols[keep]


def closest_candidates(n: int, rows: np.ndarray, cols: np.ndarray, d: np.ndarray, g_tri: np.ndarray) -> np.ndarray:
    """Mask of the candidates (slave row, triangle, distance d) that are each of the ``n`` slave points' closest;
    ties (equal distances within 1e-14 relative) go to the smallest global triangle (``g_tri``: its global vertex
    numbers), so the choice is the same on any partition."""
    shortest = np.full(n, np.inf)
    np.minimum.at(shortest, rows, d)
    tie = d <= shortest[rows] + 1e-14 * np.maximum(shortest[rows], 1.0)
    ordered = np.sort(g_tri, axis=1)
    size = int(g_tri.max(initial=0)) + 1
    if size <= 2**21:  # (o0 size + o1) size + o2 < 2^63
        triangle_key = (ordered[:, 0] * size + ordered[:, 1]) * size + ordered[:, 2]
    else:  # the rank of the sorted vertex triple (the same order, no overflow)
        triangle_key = np.unique(ordered, axis=0, return_inverse=True)[1].reshape(-1).astype(np.int64)
    key = np.where(tie, triangle_key[cols], np.iinfo(np.int64).max)
    smallest = np.full(n, np.iinfo(np.int64).max)
    np.minimum.at(smallest, rows, key)
    return tie & (key == smallest[rows])


class SelfContact(BodyContact):
    """Penalty self-contact of the surface ``surface`` (slave = master; module docstring for the exclusion rule).
    ``rings`` >= 1 (integer) and ``reach`` > 0 (a length; None: the mean rest edge length of the surface) set the
    rule; ``augmented``, ``tolerance``, ``max_uzawa`` as for BodyContact."""

    self_contact = True

    def __init__(self, problem: ElasticityProblem, surface: str, k: float, rings: int = 2,
                 reach: float | None = None, name: str | None = None, augmented: bool = False,
                 tolerance: float = 1e-8, max_uzawa: int = 25, exact: bool = False) -> None:
        if isinstance(rings, bool) or not isinstance(rings, int) or rings < 1:
            raise ValueError(f"rings: {rings!r} must be an integer >= 1")
        if reach is not None and not (np.isfinite(reach) and reach > 0):
            raise ValueError(f"reach: {reach!r} must be a finite number > 0")
        self.rings = rings
        self._reach = reach
        self.paired = np.zeros(0, dtype=bool)
        super().__init__(problem, surface, surface, k, kind="contact", name=name or f"{surface}-self",
                         augmented=augmented, tolerance=tolerance, max_uzawa=max_uzawa, smooth_normals=False,
                         leave_shared=False, exact=exact)
        self._topology()

    def _topology(self) -> None:
        """S's nodes (sorted global block dofs), the neighbourhood relation (nodes within rings - 1 edges: the
        nonzeros of (I + A)^(rings - 1), A S's edge adjacency) as sorted keys row * n + column, the slave nodes'
        rows in it and the default reach (the mean rest edge length). Collective."""
        X_tri, _, g_tri = self._gather_master()
        self.nodes = np.unique(g_tri)
        count = len(self.nodes)
        tri = np.searchsorted(self.nodes, g_tri)
        self.neighbourhood = neighbourhood_keys(tri, count, self.rings)
        imap = self.V.dofmap.index_map
        global_slave = np.asarray(imap.local_to_global(self.slave_blocks.astype(np.int32)), dtype=np.int64)
        self.slave_rows = np.searchsorted(self.nodes, global_slave)
        if len(global_slave) and not np.array_equal(self.nodes[np.minimum(self.slave_rows, count - 1)], global_slave):
            raise RuntimeError("self-contact: a slave node is on no triangle of the surface")
        edges = np.linalg.norm(X_tri - np.roll(X_tri, 1, axis=1), axis=2)
        self.reach = float(edges.mean()) if self._reach is None else float(self._reach)
        log.info("self-contact %s: %d triangles, %d nodes, rings %d, reach %.3g", self.name, len(g_tri), count,
                 self.rings, self.reach)

    def _search(self, xs: np.ndarray, x_tri: np.ndarray, g_tri: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The closest triangle of the surface to each slave node that passes the exclusion rule (module
        docstring), its barycentric coordinates, and whether there is one."""
        n = len(xs)
        best_t, best_b, paired = np.zeros(n, dtype=np.int64), np.zeros((n, 3)), np.zeros(n, dtype=bool)
        if n == 0 or len(x_tri) == 0:
            return best_t, best_b, paired
        count = len(self.nodes)
        tri = np.searchsorted(self.nodes, g_tri)
        faces = np.cross(x_tri[:, 1] - x_tri[:, 0], x_tri[:, 2] - x_tri[:, 0])
        nodal = np.zeros((count, 3))
        np.add.at(nodal, tri.ravel(), np.repeat(faces, 3, axis=0))
        nodal /= np.maximum(np.linalg.norm(nodal, axis=1, keepdims=True), 1e-300)
        n_tri = faces / np.maximum(np.linalg.norm(faces, axis=1, keepdims=True), 1e-300)
        # (1) neighbourhood: no vertex of T within rings - 1 edges of the node
        rows, cols = candidate_pairs(xs, x_tri, self.reach, self.slave_rows, tri, self.neighbourhood, count)
        # (2) facing
        facing = np.einsum("ij,ij->i", nodal[self.slave_rows[rows]], n_tri[cols]) < -FACING
        rows, cols = rows[facing], cols[facing]
        closest, bary = closest_points_on_triangles(xs[rows], x_tri[cols])
        d = np.linalg.norm(xs[rows] - closest, axis=1)
        keep = d <= self.reach  # (3) reach
        rows, cols, bary, d = rows[keep], cols[keep], bary[keep], d[keep]
        if len(rows) == 0:
            return best_t, best_b, paired
        chosen = closest_candidates(n, rows, cols, d, g_tri)  # ties to the smallest global triangle
        best_t[rows[chosen]] = cols[chosen]
        best_b[rows[chosen]] = bary[chosen]
        paired[rows[chosen]] = True
        return best_t, best_b, paired

    def potential_reason(self) -> str | None:
        """Full Newton steps for a self-contact pair: backtracking on the total potential stalled on the slotted block
        (|R| stuck at 1e-5 |R_0|, SNES stopped by snes_stol) with the tangent's lagged pairing (module docstring);
        full steps converge (tests/test_self_contact.py). With ``exact`` the residual is the derivative of the energy
        (BodyContact, "Exact contact"): None, backtracking on the total potential."""
        if self.exact:
            return None
        return (f"the self-contact {self.name}: backtracking on the total potential stalls with the lagged "
                "pairing in the tangent (full Newton steps)")

    def update(self, matrices: bool = False) -> None:
        """BodyContact.update; the augmented multiplier of a node not paired is reset to 0. Collective."""
        super().update(matrices)
        if self.augmented:
            lam = self.multiplier.x.array
            lam[self.slave_q[~self.paired]] = 0.0
            self.multiplier.x.scatter_forward()

    def report(self) -> dict[str, Any]:
        """BodyContact.report (force: int p n_T dA over the slave nodes of both sides, not the net contact force on
        the body, which is 0 (contact_residual: the master terms Pi^T cancel it); normal_force: int p dA over every
        pressed node of both sides) and paired_points (nodes with a master point, pressed or not), the same on
        every rank."""
        self.update()
        report = super().report()
        report["paired_points"] = int(self.comm.allreduce(int(np.sum(self.paired)), op=MPI.SUM))
        return report


__all__ = ["FACING", "SelfContact"]
