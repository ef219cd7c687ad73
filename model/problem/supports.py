"""Unsupported bodies, found before any solve: the rigid-body modes of each mesh piece that nothing holds.

A quasi-static problem whose body (or one of the separate pieces of its mesh) can move rigidly without changing
its energy has a singular tangent: Newton fails step after step (or "converges" to a floating motion). The check:

1. The pieces (``mesh_pieces``): cells connected through shared vertices. Each rank's owned cells give the
   edges (first vertex, other vertex) of a graph on the global vertex numbers, gathered on rank 0, whose
   connected components (scipy.sparse.csgraph) label the vertices; every rank takes its cells' labels from the
   broadcast labels. The pieces are numbered 1, 2, ... in the order of their centroids (x, then y, then z: the
   same on any number of ranks).

2. What holds a piece: rows a = [d, (x - x_0) x d / L] of the six rigid-body modes of the piece (translations e_i,
   rotations e_i x (x - x_0) about its centroid x_0, scaled by the piece's size L), one per constraint acting at a
   node x in direction d: a Dirichlet condition (a bone's attachment is one) on component c at a node, d = e_c
   (a rigid mode m moves that dof by a . m, so the condition holds the modes with a . m != 0); a rigid obstacle
   (penalty, augmented Lagrangian or VI contact with a plane, sphere, capsule or a bone's shape; sliding on a
   bone, the zero-length normal springs) at each node of its surface, d = grad g(X) the obstacle's normal at the
   node's rest position (counted as if every node touched: a contact holds at most that much). The modes nothing
   holds are the null space of

       G = sum_rows a a^T   (6 x 6, summed over the ranks' owned nodes),

   its eigenvectors with eigenvalue <= RANK_TOLERANCE x max(1, largest eigenvalue): its rank is the rank of the
   constraint rows applied to the six modes restricted to the constrained dofs. A single component on a plane
   face (u_x = 0 on x = 0) holds the translation along x and the rotations about y and z; a clamped face all six.

3. Pieces coupled by contact or sliding between deformable bodies ([[contact]] with master, or a self-contact
   surface that spans several pieces) hold one another in ways the check cannot tell (contact holds only once it
   touches): a piece free on its own but coupled is a logged warning, not an error; the coupled group as a whole
   (its pieces' rows, the modes about the group's centroid: a contact between them never resists a rigid motion
   of the whole group) with a free mode is an error.

A free mode is a ConfigError (one line) naming the piece by its regions, cell count and centroid and the modes
(translation along x, rotation about y, ... or a direction where the free space is not along the axes). A
dynamic run (inertia) needs no supports: the caller leaves the check out there.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from model import compat
from model.errors import ConfigError
from model.problem.elasticity import ElasticityProblem

log = logging.getLogger(__name__)

#: eigenvalues of G at most this x max(1, the largest) are free modes
RANK_TOLERANCE = 1e-9
#: the names of the six rigid-body modes (translations, then rotations about the axes through the centroid)
AXES = ("x", "y", "z")
REMEDY = ("add a displacement boundary condition, a bone (type = \"attached\" or \"sliding\"), contact with an "
          "obstacle, or [solver] allow_rigid_modes = true")


@dataclass
class Piece:
    """One connected piece of the mesh (the same numbers on every rank)."""

    number: int
    cells: int
    centroid: np.ndarray
    low: np.ndarray
    high: np.ndarray
    regions: list[str] = field(default_factory=list)

    @property
    def size(self) -> float:
        return float(np.linalg.norm(self.high - self.low)) or 1.0

    def describe(self, count: int) -> str:
        where = f"{self.cells:,} cells, centroid {_point(self.centroid)}"
        if self.regions:
            where = f"region{'s' if len(self.regions) > 1 else ''} {', '.join(repr(r) for r in self.regions)}, {where}"
        return f"the body ({where})" if count == 1 else f"mesh piece {self.number} of {count} ({where})"


def _point(x: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in np.asarray(x, dtype=float)) + ")"


def mesh_pieces(domain: Any) -> tuple[np.ndarray, list[Piece]]:
    """(piece index of every local cell, owned and ghost; the pieces in their order) of a distributed mesh: cells
    connected through shared vertices (module docstring, 1.). Collective."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    msh = domain.mesh
    comm = msh.comm
    tdim = msh.topology.dim
    cell_map = msh.topology.index_map(tdim)
    num_cells = cell_map.size_local + cell_map.num_ghosts
    owned = cell_map.size_local
    c2v = msh.topology.connectivity(tdim, 0)
    vertices = np.asarray(c2v.array, dtype=np.int32).reshape(num_cells, -1)
    vertex_map = msh.topology.index_map(0)
    glob = np.asarray(vertex_map.local_to_global(vertices.ravel()), dtype=np.int64).reshape(vertices.shape)
    first = np.repeat(glob[:owned, :1], glob.shape[1] - 1, axis=1).ravel()
    edges = np.stack([first, glob[:owned, 1:].ravel()])
    gathered = comm.gather(edges, root=0)
    n = int(vertex_map.size_global)
    labels = None
    if comm.rank == 0:
        both = np.concatenate(gathered, axis=1)
        graph = coo_matrix((np.ones(both.shape[1], dtype=np.int8), (both[0], both[1])), shape=(n, n))
        _, labels = connected_components(graph, directed=False)
        labels = labels.astype(np.int32)
    labels = comm.bcast(labels, root=0)
    cell_label = labels[glob[:, 0]]
    count = int(labels.max()) + 1 if n else 0
    # per label: owned cells, sum of cell centroids, bounding box
    x = msh.geometry.x[:, :3]
    nodes = compat.geometry_dofs(msh)[:num_cells]
    centres = x[nodes].mean(axis=1)
    cells = np.bincount(cell_label[:owned], minlength=count).astype(np.int64)
    sums = np.stack([np.bincount(cell_label[:owned], weights=centres[:owned, i], minlength=count)
                     for i in range(3)], axis=1)
    low = np.full((count, 3), np.inf)
    high = np.full((count, 3), -np.inf)
    corners_low, corners_high = x[nodes].min(axis=1), x[nodes].max(axis=1)
    np.minimum.at(low, cell_label, corners_low)
    np.maximum.at(high, cell_label, corners_high)
    comm.Allreduce(MPI.IN_PLACE, cells, op=MPI.SUM)
    comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
    comm.Allreduce(MPI.IN_PLACE, low, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, high, op=MPI.MAX)
    centroids = sums / np.maximum(cells, 1)[:, None]
    # order: by centroid, rounded to 1e-6 of the mesh's size (partition-independent), then by cell count
    scale = float(np.linalg.norm(high.max(axis=0) - low.min(axis=0))) if count else 1.0
    rounded = np.round(centroids / (1e-6 * scale)) if scale > 0 else centroids
    order = np.lexsort((cells, rounded[:, 2], rounded[:, 1], rounded[:, 0]))
    rank_of = np.empty(count, dtype=np.int32)
    rank_of[order] = np.arange(count, dtype=np.int32)
    pieces = [Piece(i + 1, int(cells[k]), centroids[k], low[k], high[k]) for i, k in enumerate(order)]
    # region names per piece (the mesh's named regions)
    names = sorted(domain.regions)
    if names:
        counts = np.zeros((len(names), count), dtype=np.int64)
        for j, name in enumerate(names):
            region = domain.region_cells(name)
            region = region[region < owned]
            counts[j] = np.bincount(cell_label[region], minlength=count)
        comm.Allreduce(MPI.IN_PLACE, counts, op=MPI.SUM)
        for k in range(count):
            pieces[rank_of[k]].regions = [names[j] for j in range(len(names)) if counts[j, k] > 0]
    return rank_of[cell_label], pieces


class _Nodes:
    """The displacement's nodes: coordinates, the piece of each, and the map from the solution's local dofs."""

    def __init__(self, problem: ElasticityProblem, cell_piece: np.ndarray) -> None:
        if problem.formulation == "mixed":
            space, parent = problem.space.sub(0).collapse()
            parent = np.asarray(parent, dtype=np.int64)
        else:
            space = problem.space
            parent = np.arange(len(problem.solution.x.array), dtype=np.int64)
        self.space = space
        self.bs = space.dofmap.index_map_bs
        #: solution dof -> the displacement space's unrolled dof (-1: a pressure dof)
        self.unrolled = np.full(len(problem.solution.x.array), -1, dtype=np.int64)
        self.unrolled[parent] = np.arange(len(parent))
        self.x = space.tabulate_dof_coordinates()[:, :3]
        self.owned = space.dofmap.index_map.size_local
        self.piece = np.full(len(self.x), -1, dtype=np.int32)
        dofs = compat.cell_dofs(space.dofmap)
        self.piece[dofs] = cell_piece[: len(dofs), None]

    def surface(self, problem: ElasticityProblem, name: str) -> np.ndarray:
        """The owned nodes (blocks) of a named boundary."""
        fdim = problem.domain.mesh.topology.dim - 1
        blocks = np.asarray(fem.locate_dofs_topological(self.space, fdim, problem.domain.boundary_facets(name)))
        return blocks[blocks < self.owned]


def _rows(problem: ElasticityProblem, nodes: _Nodes, contacts: Sequence[Any], sliding: Sequence[Any]
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, d, piece) of every constraint row on this rank's owned nodes (module docstring, 2.)."""
    xs, ds, ps = [], [], []
    for entry in problem.dirichlet:
        for component, dofs in zip(entry.components, entry.dofs):
            unrolled = nodes.unrolled[np.asarray(dofs, dtype=np.int64)]
            blocks = unrolled[unrolled >= 0] // nodes.bs
            blocks = np.unique(blocks[blocks < nodes.owned])
            d = np.zeros((len(blocks), 3))
            d[:, component] = 1.0
            xs.append(nodes.x[blocks]), ds.append(d), ps.append(nodes.piece[blocks])
    obstacles = [c for c in [*contacts, *sliding] if hasattr(c, "frame") and hasattr(c, "obstacle")]
    for c in obstacles:
        blocks = nodes.surface(problem, c.surface)
        x = nodes.x[blocks]
        h = 1e-7 * max(float(np.max(np.abs(nodes.x), initial=1.0)), 1e-300)
        d = np.stack([(c.frame.gap_at(c.obstacle, x + h * e) - c.frame.gap_at(c.obstacle, x - h * e)) / (2 * h)
                      for e in np.eye(3)], axis=1) if len(x) else np.zeros((0, 3))
        norm = np.linalg.norm(d, axis=1)
        keep = norm > 0
        xs.append(x[keep]), ds.append(d[keep] / norm[keep, None]), ps.append(nodes.piece[blocks][keep])
    if not xs:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, dtype=np.int32)
    return np.concatenate(xs), np.concatenate(ds), np.concatenate(ps)


def _gram(x: np.ndarray, d: np.ndarray, centre: np.ndarray, size: float) -> np.ndarray:
    """G = sum a a^T, a = [d, (x - centre) x d / size] (this rank's rows)."""
    a = np.concatenate([d, np.cross(x - centre, d) / size], axis=1)
    return a.T @ a


def free_modes(G: np.ndarray) -> np.ndarray:
    """The null space of G (6 x k, orthonormal columns): eigenvalues <= RANK_TOLERANCE x max(1, the largest)."""
    values, vectors = np.linalg.eigh(G)
    return vectors[:, values <= RANK_TOLERANCE * max(1.0, float(values.max(initial=0.0)))]


def _orthonormal(M: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """An orthonormal basis (columns) of M's column space."""
    if M.size == 0:
        return np.zeros((M.shape[0], 0))
    u, s, _ = np.linalg.svd(M, full_matrices=False)
    return u[:, s > tol * max(1.0, float(s.max(initial=0.0)))]


def _null(M: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """An orthonormal basis (columns) of M's null space."""
    if M.shape[1] == 0:
        return np.zeros((0, 0))
    _, s, vt = np.linalg.svd(M)
    rank = int(np.sum(s > tol * max(1.0, float(s.max(initial=0.0)))))
    return vt[rank:].T


def _directions(basis: np.ndarray) -> list[str]:
    """A subspace of R^3 (orthonormal columns) in words: its coordinate axes ("x", ...) when it is spanned by
    axes, else its basis vectors."""
    if basis.shape[1] == 0:
        return []
    inside = [i for i in range(3) if np.linalg.norm(basis[i]) > 1 - 1e-6]
    if len(inside) == basis.shape[1]:
        return [AXES[i] for i in inside]
    return [_point(v) for v in basis.T]


def _and(words: list[str]) -> str:
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def describe_modes(N: np.ndarray) -> str:
    """The free modes (the null space N of G, 6 x k) in words: the free translations, the directions d with
    [d, 0] in span N (N_t c for c in null(N_r)), and the free rotations, the axes spanned by N's rotation parts N_r
    (each about some axis of that direction), e.g. "translation along y and z and rotation about x"."""
    translations = _orthonormal(N[:3] @ _null(N[3:])) if N.shape[1] else np.zeros((3, 0))
    rotations = _orthonormal(N[3:])
    parts = []
    if translations.shape[1]:
        parts.append(f"translation along {_and(_directions(translations))}")
    if rotations.shape[1]:
        parts.append(f"rotation about {_and(_directions(rotations))}")
    return " and ".join(parts)


def _couplings(problem: ElasticityProblem, nodes: _Nodes, contacts: Sequence[Any], count: int) -> list[set[int]]:
    """Groups of pieces coupled by contact or sliding between deformable bodies (union over the ranks)."""
    parent = list(range(count))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    comm = problem.domain.mesh.comm
    for c in contacts:
        slave, master = getattr(c, "slave", None), getattr(c, "master", None)
        if slave is None or master is None:
            continue
        touched = np.zeros(count, dtype=np.int32)  # the pieces the pair's surfaces touch, on any rank
        for surface in (slave, master):
            touched[nodes.piece[nodes.surface(problem, surface)]] = 1
        comm.Allreduce(MPI.IN_PLACE, touched, op=MPI.MAX)
        group = np.flatnonzero(touched)
        for other in group[1:]:
            parent[find(int(other))] = find(int(group[0]))
    groups: dict[int, set[int]] = {}
    for i in range(count):
        groups.setdefault(find(i), set()).add(i)
    return list(groups.values())


def check_supports(problem: ElasticityProblem, contacts: Sequence[Any] = (), sliding: Sequence[Any] = (),
                   key: str = "boundary") -> list[str]:
    """ConfigError (one line, starting with ``key``) when a rigid-body mode of a mesh piece is held by nothing
    (module docstring); returns the warnings (pieces free on their own but coupled to others by contact between
    bodies), also logged. Collective: the same answer on any number of ranks."""
    comm = problem.domain.mesh.comm
    cell_piece, pieces = mesh_pieces(problem.domain)
    count = len(pieces)
    nodes = _Nodes(problem, cell_piece)
    x, d, piece = _rows(problem, nodes, contacts, sliding)
    local = np.zeros((count, 6, 6))
    for p in range(count):
        mine = piece == p
        local[p] = _gram(x[mine], d[mine], pieces[p].centroid, pieces[p].size)
    G = np.empty_like(local)
    comm.Allreduce(local, G, op=MPI.SUM)
    free = [free_modes(G[p]) for p in range(count)]
    warnings = []
    for group in _couplings(problem, nodes, contacts, count):
        unheld = [p for p in sorted(group) if free[p].shape[1]]
        if not unheld:
            continue
        if len(group) == 1:
            p = unheld[0]
            raise ConfigError(f"{key}: {pieces[p].describe(count)}: nothing holds its {describe_modes(free[p])}: "
                              f"{REMEDY}")
        members = sorted(group)
        cells = np.array([pieces[p].cells for p in members], dtype=float)
        centre = (cells[:, None] * np.array([pieces[p].centroid for p in members])).sum(axis=0) / cells.sum()
        size = float(np.linalg.norm(np.max([pieces[p].high for p in members], axis=0)
                                    - np.min([pieces[p].low for p in members], axis=0))) or 1.0
        mine = np.isin(piece, members)
        joint = np.empty((6, 6))
        comm.Allreduce(_gram(x[mine], d[mine], centre, size), joint, op=MPI.SUM)
        together = free_modes(joint)
        names = _and([str(pieces[p].number) for p in members])
        if together.shape[1]:
            raise ConfigError(f"{key}: mesh pieces {names} of {count} (in contact with one another): nothing holds "
                              f"their {describe_modes(together)} as a whole: {REMEDY}")
        for p in unheld:
            others = _and([str(pieces[q].number) for q in members if q != p])
            plural = "s" if len(members) > 2 else ""
            warnings.append(f"{pieces[p].describe(count)}: only contact with mesh piece{plural} {others} can hold its "
                            f"{describe_modes(free[p])}; a solve fails while that contact is open")
    if comm.rank == 0:
        for message in warnings:
            log.warning("support check: %s", message)
        log.info("support check: %d mesh piece(s), each held", count)
    return warnings
