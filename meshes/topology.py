"""Small pure helpers on linear tetrahedral meshes (numpy only)."""

from __future__ import annotations

import numpy as np

__all__ = [
    "SLIVER_RADIUS_RATIO",
    "boundary_facets",
    "facet_keys",
    "orient_positive",
    "radius_ratio",
    "signed_volumes",
    "tet_faces",
]

#: q = 3 r_in / r_circ below which a tetrahedron is a sliver (its gradients are poor, its condition number
#: grows like 1/q): the gmsh generators mesh again with another seed, and a run warns.
SLIVER_RADIUS_RATIO = 0.02

# Local vertex triples of the four faces of a tetrahedron (face i is opposite vertex i).
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)


def signed_volumes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed volume of each tetrahedron, ``det([p1-p0, p2-p0, p3-p0]) / 6``."""
    p = np.asarray(points, dtype=np.float64)[np.asarray(cells, dtype=np.int64)]
    edges = p[:, 1:, :] - p[:, :1, :]
    return np.linalg.det(edges) / 6.0


def radius_ratio(x: np.ndarray) -> np.ndarray:
    """q = 3 r_in / r_circ of tetrahedra given by vertex coordinates (n, 4, 3); 0 for a degenerate cell.

    r_in = 3 |V| / (A_0 + A_1 + A_2 + A_3);  with u, v, w the edges from x0,
    r_circ = | |u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v) | / (12 |V|).
    """
    u, v, w = (x[:, i, :] - x[:, 0, :] for i in (1, 2, 3))
    volume = np.abs(np.einsum("ij,ij->i", u, np.cross(v, w))) / 6.0
    faces = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
    area = sum(0.5 * np.linalg.norm(np.cross(x[:, b] - x[:, a], x[:, c] - x[:, a]), axis=1) for a, b, c in faces)
    circ = (np.einsum("i,ij->ij", np.einsum("ij,ij->i", u, u), np.cross(v, w))
            + np.einsum("i,ij->ij", np.einsum("ij,ij->i", v, v), np.cross(w, u))
            + np.einsum("i,ij->ij", np.einsum("ij,ij->i", w, w), np.cross(u, v)))
    with np.errstate(divide="ignore", invalid="ignore"):
        r_in = 3.0 * volume / area
        r_circ = np.linalg.norm(circ, axis=1) / (12.0 * volume)
        q = np.where(volume > 0, 3.0 * r_in / r_circ, 0.0)
    return np.nan_to_num(q, nan=0.0)


def orient_positive(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Copy of ``cells`` with the last two vertices swapped where the volume is negative (outward faces)."""
    out = np.array(cells, dtype=np.int64, copy=True)
    negative = signed_volumes(points, out) < 0.0
    out[negative] = out[negative][:, [0, 1, 3, 2]]
    return out


def tet_faces(cells: np.ndarray) -> np.ndarray:
    """All faces of all tetrahedra, shape ``(4 m, 3)``; faces of cell ``c`` are rows ``4c .. 4c+3``."""
    return np.asarray(cells, dtype=np.int64)[:, _TET_FACES].reshape(-1, 3)


def facet_keys(facets: np.ndarray) -> np.ndarray:
    """Orientation-independent representation of triangles: each row sorted ascending."""
    return np.sort(np.asarray(facets, dtype=np.int64).reshape(-1, 3), axis=1)


def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """Triangles that belong to exactly one tetrahedron, oriented as in that tetrahedron.

    The returned triangles are ordered by their sorted vertex triple, which makes the
    result deterministic.
    """
    faces = tet_faces(cells)
    if faces.size == 0:
        return np.empty((0, 3), dtype=np.int64)
    _, first, counts = np.unique(facet_keys(faces), axis=0, return_index=True, return_counts=True)
    return faces[first[counts == 1]]
