"""A user's triangle surface from a file (any format meshio reads: OBJ, STL, PLY, VTU, gmsh .msh ...), checked.

    data = read_surface("patch.obj")              # a meshes.membrane.SurfaceMeshData, region "membrane"
    data = read_surface("sheets.msh")             # regions: the .msh file's named physical surfaces
    cells = oriented_cells(data.points, data.cells, "file")   # or "outward", or a direction

``read_surface`` keeps the file's triangles (every triangle block), drops the points no triangle uses and merges
points with identical coordinates (an STL repeats them per facet); the coordinates are taken as they are (in the
configuration's length unit). Regions (cell tags 1, 2, ... in the order of the groups' physical tags): one,
``membrane``, or the named gmsh physical surface groups of a .msh file (e.g. two sheets for membrane-membrane
contact), which must then hold every triangle. Boundaries (edges, for Dirichlet conditions):

* ``boundary``: the open boundary, every edge of exactly one triangle (found here; none on a closed surface);
* ``<region>_boundary`` for each named physical surface: the open boundary of that region's triangles alone
  (every edge of exactly one of them);
* each named gmsh physical line group of a .msh file (its line elements, which must be edges of the triangles);
  a group named "boundary" (or "<region>_boundary") replaces the automatic one.

Refused with a one-line ValueError (the caller names the key and the file): a file meshio cannot read, no
triangles, other 2D or 3D cells (quads, polygons, tetrahedra: a mixed mesh), a triangle with a repeated vertex
or a zero area (|(x1 - x0) x (x2 - x0)| <= 1e-10 l^2, l its longest edge), a non-manifold edge (shared by more
than two triangles), a non-manifold (bow-tie) vertex (its triangles form two or more fans that meet only at it:
two triangles around it are in one fan when a chain of them joins them, each sharing an edge through the vertex
with the next), a named line that is not an edge of the surface, triangles in no named physical surface of a
file that names some, a triangle in two of them.

Orientation (``oriented_cells``): two triangles sharing an edge are consistently oriented when they run through it
in opposite directions (their right-handed normals on the same side). ``"file"`` keeps the file's vertex order
and refuses an inconsistent one; a direction ``(3,)`` or ``"outward"`` (away from the middle of the points'
bounding box) turns each triangle so that its normal has a positive component along it, and refuses a result
that is inconsistent (e.g. a closed surface given one direction).

Topology (``patch_topology``, for a patch that is closed into a muscle): the number of pieces (connected
components of the triangles), of boundary loops (connected components of the open edges; each boundary vertex
of a manifold surface without bow-ties has two of them) and the Euler characteristic V - E + F; a disc (one
patch with one rim) has 1, 1, 1.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from meshes.membrane import SurfaceMeshData, orient_triangles

__all__ = ["AUTO_BOUNDARY", "PatchTopology", "check_orientation", "oriented_cells", "patch_topology", "read_surface",
           "vertex_fans"]

#: the name of the open boundary found from the triangles
AUTO_BOUNDARY = "boundary"
_SURFACE_CELLS = ("quad", "polygon", "triangle6", "quad8", "quad9", "triangle7")
_VOLUME_CELLS = ("tetra", "hexahedron", "wedge", "pyramid", "tetra10", "hexahedron20", "hexahedron27")


def _edges(cells: np.ndarray) -> np.ndarray:
    """The three directed edges of each triangle, (3 m, 2): (v0, v1), (v1, v2), (v2, v0)."""
    return np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])


def _undirected(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct undirected edges (sorted pairs), the edge of each directed edge, and each edge's count."""
    directed = _edges(cells)
    edges, index, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    return edges, np.asarray(index).reshape(-1), counts


def _read(path: Path):  # noqa: ANN202 - a meshio.Mesh
    import meshio

    with warnings.catch_warnings():  # meshio's STL size test overflows numpy 2's uint32 (harmless)
        warnings.simplefilter("ignore", RuntimeWarning)
        return meshio.read(path)


def read_surface(path: str | Path) -> SurfaceMeshData:
    """The checked triangle surface of ``path`` (module docstring); ValueError with a one-line reason."""
    path = Path(path)
    try:
        mesh = _read(path)
    except Exception as err:  # noqa: BLE001 - any reader failure is one reason
        raise ValueError(f"cannot read it: {' '.join(str(err).split()) or type(err).__name__}") from None
    kinds = [block.type for block in mesh.cells]
    other = sorted({k for k in kinds if k in _SURFACE_CELLS or k in _VOLUME_CELLS})
    if other:
        raise ValueError(f"has {', '.join(other)} cells besides triangles (a membrane takes a triangle surface only)")
    blocks = [i for i, k in enumerate(kinds) if k == "triangle"]
    if not blocks:
        raise ValueError("has no triangles")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"points of shape {points.shape}: need x, y(, z)")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    cells = np.concatenate([np.asarray(mesh.cells[i].data, dtype=np.int64) for i in blocks])
    sheets, cell_tags = _named_surfaces(mesh, blocks)  # the file's named regions (none: one, "membrane")
    regions = sheets or {"membrane": 1}
    lines = _named_lines(mesh)
    # the points the triangles use, identical coordinates merged, in the file's order
    used = np.unique(cells)
    unique, first, inverse = np.unique(points[used], axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    new = np.full(len(points), -1, dtype=np.int64)
    new[used] = rank[np.asarray(inverse).reshape(-1)]
    points, cells = unique[order], new[cells]
    _check_triangles(points, cells)
    _, first_of, repeats = np.unique(np.sort(cells, axis=1), axis=0, return_index=True, return_counts=True)
    if np.any(repeats > 1):
        i = int(first_of[np.flatnonzero(repeats > 1)[0]])
        raise ValueError(f"has {int(np.sum(repeats[repeats > 1] - 1))} repeated triangles (the same three points, "
                         f"e.g. triangle {i}; a triangle in two physical surfaces?)")
    edges, _, counts = _undirected(cells)
    if np.any(counts > 2):
        bad = edges[counts > 2][0]
        raise ValueError(f"has {int(np.count_nonzero(counts > 2))} non-manifold edges (shared by more than two "
                         f"triangles), e.g. the edge of points {points[bad[0]].tolist()} and {points[bad[1]].tolist()}")
    _check_vertex_fans(points, cells)
    named: dict[str, np.ndarray] = {}
    if AUTO_BOUNDARY not in lines:
        named[AUTO_BOUNDARY] = edges[counts == 1]
    for region, tag in sheets.items():
        own, _, own_counts = _undirected(cells[cell_tags == tag])
        if f"{region}_boundary" not in lines:
            named[f"{region}_boundary"] = own[own_counts == 1]
    for name, line in lines.items():
        if np.any(new[line] < 0):
            raise ValueError(f"physical line {name!r} has points that are on no triangle")
        pairs = np.sort(new[line], axis=1)
        found = _rows_in(pairs, edges)
        if not np.all(found):
            raise ValueError(f"physical line {name!r} has {int(np.count_nonzero(~found))} elements that are not "
                             "edges of the triangles")
        named[name] = pairs
    names = {name: k for k, name in enumerate(named, start=1)}
    facets = np.concatenate([named[n] for n in names]).astype(np.int64).reshape(-1, 2)
    facet_tags = np.concatenate([np.full(len(named[n]), names[n], dtype=np.int32) for n in names])
    return SurfaceMeshData(points, cells, cell_tags, facets, facet_tags, regions, names)


def _named_surfaces(mesh, blocks: list[int]) -> tuple[dict[str, int], np.ndarray]:  # noqa: ANN001 - meshio.Mesh
    """The regions and a tag per triangle (in the order of the triangle ``blocks``): a .msh file's named physical
    surface groups, tagged 1, 2, ... in the order of their physical tags, or ({}, ones) without any."""
    count = sum(len(mesh.cells[i].data) for i in blocks)
    tags = mesh.cell_data.get("gmsh:physical")
    names = {int(v[0]): name for name, v in (mesh.field_data or {}).items() if len(v) > 1 and int(v[1]) == 2} \
        if tags is not None else {}
    if not names:
        return {}, np.ones(count, dtype=np.int32)
    physical = np.concatenate([np.asarray(tags[i]).reshape(-1) for i in blocks]).astype(np.int64)
    order = sorted(names)
    regions = {names[t]: k for k, t in enumerate(order, start=1)}
    cell_tags = np.zeros(count, dtype=np.int32)
    for t in order:
        cell_tags[physical == t] = regions[names[t]]
    if np.any(cell_tags == 0):
        raise ValueError(f"has {int(np.count_nonzero(cell_tags == 0))} triangles in no named physical surface "
                         f"(named: {', '.join(regions)}; name every physical surface of the file or none)")
    return regions, cell_tags


def _rows_in(rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Whether each row of ``rows`` (k, 2) is a row of ``table`` (n, 2), both of non-negative integers."""
    scale = int(max(rows.max(initial=0), table.max(initial=0))) + 1
    return np.isin(rows[:, 0] * scale + rows[:, 1], table[:, 0] * scale + table[:, 1])


def _named_lines(mesh) -> dict[str, np.ndarray]:  # noqa: ANN001 - a meshio.Mesh
    """A gmsh file's named physical line groups: name -> (k, 2) point indices (the file's numbering)."""
    tags = mesh.cell_data.get("gmsh:physical")
    if tags is None:
        return {}
    names = {int(v[0]): name for name, v in (mesh.field_data or {}).items() if len(v) > 1 and int(v[1]) == 1}
    lines: dict[str, list[np.ndarray]] = {}
    for block, block_tags in zip(mesh.cells, tags, strict=True):
        if block.type != "line":
            continue
        block_tags = np.asarray(block_tags).reshape(-1)
        for tag, name in names.items():
            selected = np.asarray(block.data, dtype=np.int64)[block_tags == tag]
            if len(selected):
                lines.setdefault(name, []).append(selected)
    return {name: np.concatenate(parts) for name, parts in lines.items()}


def _check_triangles(points: np.ndarray, cells: np.ndarray) -> None:
    """ValueError for a triangle with a repeated vertex or a zero area (relative to its longest edge)."""
    repeated = (cells[:, 0] == cells[:, 1]) | (cells[:, 1] == cells[:, 2]) | (cells[:, 2] == cells[:, 0])
    p = points[cells]
    area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    longest = np.max(np.linalg.norm(p - p[:, [1, 2, 0]], axis=2), axis=1)
    degenerate = repeated | (area2 <= 1e-10 * longest**2)
    if np.any(degenerate):
        i = int(np.flatnonzero(degenerate)[0])
        raise ValueError(f"has {int(np.count_nonzero(degenerate))} degenerate triangles (a repeated vertex or zero "
                         f"area), e.g. triangle {i} with points {p[i].tolist()}")


def vertex_fans(cells: np.ndarray) -> np.ndarray:
    """The number of fans of triangles around each vertex (0 for a vertex on no triangle): the connected components
    of the graph whose nodes are the triangle corners at the vertex, two corners joined when their triangles share
    an edge through the vertex. One on a manifold surface (an interior vertex's closed fan or a boundary vertex's
    open one); two or more at a bow-tie vertex. Needs every edge in at most two triangles."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    cells = np.asarray(cells, dtype=np.int64)
    m = len(cells)
    corner = np.arange(3 * m).reshape(m, 3)  # corner (t, i): triangle t at its local vertex i
    local = np.array([[0, 1], [1, 2], [2, 0]])
    # each directed edge's two corners, in the order of _edges
    ends = np.concatenate([corner[:, local[k]] for k in range(3)])
    _, index, counts = _undirected(cells)
    rows = np.flatnonzero(counts[index] == 2)
    order = rows[np.argsort(index[rows], kind="stable")]
    a, b = order[0::2], order[1::2]  # the two directed copies of each interior edge
    directed = _edges(cells)
    same = np.all(directed[a] == directed[b], axis=1)
    # join the corners at the same vertex: (a0 with b0, a1 with b1) if both run the same way, else crossed
    b_ends = np.where(same[:, None], ends[b], ends[b][:, ::-1])
    i = np.concatenate([ends[a][:, 0], ends[a][:, 1]])
    j = np.concatenate([b_ends[:, 0], b_ends[:, 1]])
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(3 * m, 3 * m))
    _, label = connected_components(graph, directed=False)
    vertex = cells.reshape(-1)
    pairs = np.unique(np.column_stack([vertex, label]), axis=0)
    return np.bincount(pairs[:, 0], minlength=int(vertex.max(initial=-1)) + 1)


def _check_vertex_fans(points: np.ndarray, cells: np.ndarray) -> None:
    """ValueError for a bow-tie vertex (two or more fans of triangles meeting only at it; ``vertex_fans``)."""
    fans = vertex_fans(cells)
    bad = np.flatnonzero(fans > 1)
    if len(bad):
        v = int(bad[0])
        raise ValueError(f"has {len(bad)} non-manifold (bow-tie) vertices (two or more fans of triangles meeting "
                         f"only at the vertex), e.g. point {v} at {points[v].tolist()} with {int(fans[v])} fans")


def check_orientation(cells: np.ndarray) -> tuple[int, tuple[int, int] | None]:
    """How many interior edges two triangles run through in the same direction (inconsistent orientation), and
    one such pair of triangles (None when consistent)."""
    cells = np.asarray(cells, dtype=np.int64)
    directed = _edges(cells)
    _, index, counts = _undirected(cells)
    interior = counts[index] == 2
    rows = np.flatnonzero(interior)
    # each interior edge twice; consistent when one copy is (a, b) and the other (b, a)
    order = rows[np.argsort(index[rows], kind="stable")]
    a, b = order[0::2], order[1::2]
    same = np.all(directed[a] == directed[b], axis=1)
    if not np.any(same):
        return 0, None
    m = len(cells)
    k = int(np.flatnonzero(same)[0])
    return int(np.count_nonzero(same)), (int(a[k] % m), int(b[k] % m))


def oriented_cells(points: np.ndarray, cells: np.ndarray, orientation: str | np.ndarray) -> np.ndarray:
    """The triangles turned by ``orientation`` ("file", "outward" or a direction; module docstring), checked
    consistent; ValueError naming two inconsistent neighbours otherwise."""
    points = np.asarray(points, dtype=np.float64)
    if isinstance(orientation, str) and orientation == "file":
        result = np.asarray(cells, dtype=np.int64)
    elif isinstance(orientation, str) and orientation == "outward":
        middle = 0.5 * (points.min(axis=0) + points.max(axis=0))
        result = orient_triangles(points, cells, points[cells].mean(axis=1) - middle)
    elif isinstance(orientation, str):
        raise ValueError(f"unknown orientation {orientation!r}")
    else:
        result = orient_triangles(points, cells, np.asarray(orientation, dtype=np.float64))
    count, pair = check_orientation(result)
    if count:
        how = "the file's vertex order" if isinstance(orientation, str) and orientation == "file" else \
            f"orientation {orientation if isinstance(orientation, str) else list(map(float, orientation))}"
        raise ValueError(f"triangles inconsistently oriented by {how}: {count} edges run the same way in both "
                         f"their triangles, e.g. triangles {pair[0]} and {pair[1]}")
    return result


@dataclass(frozen=True)
class PatchTopology:
    """A triangle surface's pieces, boundary loops and Euler characteristic V - E + F (module docstring)."""

    pieces: int
    loops: int
    euler: int

    @property
    def is_disc(self) -> bool:
        """One piece with one boundary loop and chi = 1: a disc (no handles)."""
        return (self.pieces, self.loops, self.euler) == (1, 1, 1)


def patch_topology(cells: np.ndarray) -> PatchTopology:
    """The topology of the surface ``cells`` (every edge in at most two triangles, no bow-tie vertex, every point
    0 .. max used): pieces and boundary loops as connected components (scipy.sparse.csgraph), V - E + F."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    cells = np.asarray(cells, dtype=np.int64)
    edges, _, counts = _undirected(cells)
    n = int(cells.max(initial=-1)) + 1

    def components(pairs: np.ndarray, nodes: np.ndarray) -> int:
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        label = connected_components(graph, directed=False)[1]
        return len(np.unique(label[nodes]))

    open_edges = edges[counts == 1]
    pieces = components(edges, np.unique(cells))
    loops = components(open_edges, np.unique(open_edges)) if len(open_edges) else 0
    return PatchTopology(pieces, loops, len(np.unique(cells)) - len(edges) + len(cells))
