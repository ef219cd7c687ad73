"""Probes: point evaluation of a displacement at fixed reference points, the same on every rank.

A probe point must lie in the body. One that does not (typically a point on the true, curved surface
of an organ while the mesh is a faceted approximation of it) is refused with its distance to the body
and the body's nearest point, or, with ``snap = true``, moved to that nearest point:

    q(p) = argmin_{x in dB} |p - x|,   dB = union of the exterior triangles T of the mesh,

computed exactly: for every exterior triangle the closest point of T to p (the Voronoi regions of its
vertices, edges and face; Ericson, Real-Time Collision Detection, 5.1.5), the minimum over the
triangles, and the minimum over the ranks (the lowest rank wins a tie, so every rank gets the same q).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from model import compat
from model.config import ProbeConfig
from model.errors import ConfigError

log = logging.getLogger(__name__)

#: a probe snapped farther than this fraction of the body's size (bounding-box diagonal) is logged as a warning
FAR = 0.05


class Probes:
    """Point evaluation of a vector Function at fixed reference points, the same on every rank."""

    def __init__(self, domain_mesh, points: dict[str, tuple[float, float, float]]) -> None:
        self.mesh = domain_mesh
        self.names = list(points)
        self.points = np.array([points[n] for n in self.names], dtype=np.float64).reshape(-1, 3)
        #: name -> distance each snapped probe was moved by (see place_probes)
        self.snapped: dict[str, float] = {}
        comm = domain_mesh.comm
        tdim = domain_mesh.topology.dim
        colliding = compat.colliding_cells(domain_mesh, self.points)
        num_owned = domain_mesh.topology.index_map(tdim).size_local
        self.cells = np.full(len(self.names), -1, dtype=np.int32)
        for i in range(len(self.names)):
            links = colliding.links(i)
            owned = links[links < num_owned]
            if len(owned):
                self.cells[i] = owned[0]
        found = np.where(self.cells >= 0, comm.rank, comm.size)
        self.owner = np.empty_like(found)
        comm.Allreduce(found, self.owner, op=MPI.MIN)
        self.missing = [n for n, o in zip(self.names, self.owner) if o == comm.size]

    def evaluate(self, function: fem.Function) -> dict[str, list[float]]:
        """{name: value} of the function at each probe point (each point evaluated by one rank)."""
        comm = self.mesh.comm
        size = function.function_space.dofmap.index_map_bs
        values = np.zeros((len(self.names), size))
        mine = np.flatnonzero(self.owner == comm.rank)
        if len(mine):
            values[mine] = function.eval(self.points[mine], self.cells[mine]).reshape(len(mine), size)
        total = np.zeros_like(values)
        comm.Allreduce(values, total, op=MPI.SUM)
        return {n: total[i].tolist() for i, n in enumerate(self.names)}

    def points_by_name(self) -> dict[str, list[float]]:
        """{name: [x, y, z]} the point each probe is evaluated at (after any snap)."""
        return {n: self.points[i].tolist() for i, n in enumerate(self.names)}


def closest_points_on_triangles(p: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The closest point of each triangle to the point ``p``: (n, 3) for triangles (n, 3, 3).

    With ab = b - a, ac = c - a and d1..d6 the dot products of ab, ac with p - a, p - b, p - c, the
    closest point is a vertex, a point of an edge or of the face, by the region p projects into:
    a (d1, d2 <= 0), b (d3 >= 0, d4 <= d3), ab (vc <= 0, d1 >= 0, d3 <= 0: a + d1/(d1 - d3) ab),
    c (d6 >= 0, d5 <= d6), ac (vb <= 0, d2 >= 0, d6 <= 0: a + d2/(d2 - d6) ac), bc (va <= 0, d4 >= d3,
    d5 >= d6: b + (d4 - d3)/((d4 - d3) + (d5 - d6)) (c - b)), else the face a + (vb ab + vc ac)/(va + vb + vc),
    where va = d3 d6 - d5 d4, vb = d5 d2 - d1 d6, vc = d1 d4 - d3 d2 (the first region that applies wins).
    """
    p = np.asarray(p, dtype=np.float64).reshape(1, 3)
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c

    def dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", u, v)

    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    def ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
        safe = np.where(den != 0.0, den, 1.0)
        return (num / safe)[:, None]

    candidates = [
        (a, (d1 <= 0) & (d2 <= 0)),
        (b, (d3 >= 0) & (d4 <= d3)),
        (a + ratio(d1, d1 - d3) * ab, (vc <= 0) & (d1 >= 0) & (d3 <= 0)),
        (c, (d6 >= 0) & (d5 <= d6)),
        (a + ratio(d2, d2 - d6) * ac, (vb <= 0) & (d2 >= 0) & (d6 <= 0)),
        (b + ratio(d4 - d3, (d4 - d3) + (d5 - d6)) * (c - b), (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)),
    ]
    total = va + vb + vc
    result = a + ratio(vb, total) * ab + ratio(vc, total) * ac
    for point, where in reversed(candidates):
        result = np.where(where[:, None], point, result)
    return result


def nearest_surface_points(msh: dmesh.Mesh, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distance of each point to the body's surface and the nearest point of the surface, the
    same on every rank: min over the exterior triangles of each rank, then over the ranks (lowest rank on
    a tie). Collective. Returns (distances (n,), nearest (n, 3))."""
    comm = msh.comm
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    triangles = compat.exterior_facet_vertices(msh)
    distances = np.full(len(points), np.inf)
    nearest = np.zeros((len(points), 3))
    for i, p in enumerate(points):
        if len(triangles):
            q = closest_points_on_triangles(p, triangles)
            d = np.linalg.norm(q - p, axis=1)
            j = int(np.argmin(d))
            distances[i], nearest[i] = d[j], q[j]
    best = np.empty_like(distances)
    comm.Allreduce(distances, best, op=MPI.MIN)
    mine = np.where(distances == best, comm.rank, comm.size)
    winner = np.empty_like(mine)
    comm.Allreduce(mine, winner, op=MPI.MIN)
    chosen = np.where((winner == comm.rank)[:, None], nearest, 0.0)
    out = np.zeros_like(chosen)
    comm.Allreduce(chosen, out, op=MPI.SUM)
    return best, out


def format_length(value: float) -> str:
    """A length in two significant digits, e.g. 1.2e-4 (no padded exponent); inf or nan as such."""
    if not math.isfinite(value):
        return str(value)
    mantissa, exponent = f"{value:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def format_point(point: Sequence[float]) -> str:
    """[x, y, z] in 6 significant digits; coordinates below 1e-12 of the largest one print as 0.0."""
    scale = max(abs(float(x)) for x in point)
    values = [0.0 if abs(x) <= 1e-12 * scale else float(f"{x:.6g}") + 0.0 for x in point]
    return "[" + ", ".join(repr(v) for v in values) + "]"


def _body_size(msh: dmesh.Mesh) -> float:
    """The diagonal of the body's bounding box (reduced over the ranks)."""
    x = msh.geometry.x[:, :3]
    low = x.min(axis=0) if len(x) else np.full(3, np.inf)
    high = x.max(axis=0) if len(x) else np.full(3, -np.inf)
    lows, highs = np.empty(3), np.empty(3)
    msh.comm.Allreduce(np.ascontiguousarray(low), lows, op=MPI.MIN)
    msh.comm.Allreduce(np.ascontiguousarray(high), highs, op=MPI.MAX)
    return float(np.linalg.norm(highs - lows))


def place_probes(msh: dmesh.Mesh, specs: Sequence[ProbeConfig], length_unit: str = "m") -> Probes:
    """Probes at the configured points. A point outside the body raises ConfigError (``probe[i].point``)
    with its distance to the body and the body's nearest point, unless the probe has ``snap = true``:
    then it is moved to that nearest point (logged; recorded in ``Probes.snapped``). Collective; the
    same message and points on every rank and for any number of ranks."""
    probes = Probes(msh, {p.name: p.point for p in specs})
    if not probes.missing:
        return probes
    index = {p.name: i for i, p in enumerate(specs)}
    missing = [index[n] for n in probes.missing]
    distances, nearest = nearest_surface_points(msh, np.array([specs[i].point for i in missing]))
    for k, i in enumerate(missing):
        if not specs[i].snap:
            raise ConfigError(
                f"probe[{i}].point: {list(specs[i].point)} is outside the mesh, {format_length(distances[k])} "
                f"{length_unit} from its surface (nearest point of the body: {format_point(nearest[k])}); "
                "set snap = true on the probe to move it there")
    size = _body_size(msh)
    points = {p.name: p.point for p in specs}
    for k, i in enumerate(missing):
        name = specs[i].name
        points[name] = tuple(nearest[k].tolist())
        if msh.comm.rank == 0:
            level = logging.WARNING if distances[k] > FAR * size else logging.INFO
            far = f", more than {FAR:g} of the body's size: check the point" if level == logging.WARNING else ""
            log.log(level, "probe %r snapped by %s %s to %s%s", name, format_length(distances[k]), length_unit,
                    format_point(nearest[k]), far)
    snapped = Probes(msh, points)
    if snapped.missing:  # the nearest point of a triangle is in its cell to rounding; not expected
        raise RuntimeError(f"probes {', '.join(snapped.missing)}: snapped points are not found in the mesh")
    snapped.snapped = {specs[i].name: float(distances[k]) for k, i in enumerate(missing)}
    return snapped


__all__ = ["Probes", "closest_points_on_triangles", "format_length", "format_point", "nearest_surface_points",
           "place_probes"]
