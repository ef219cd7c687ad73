"""A probe a hair outside the faceted surface: refused with its distance and the body's nearest point, or
snapped there with ``snap = true``.

The body is an ellipsoid octant with semi-axes (A, B, C): the sphere generator's octant scaled per axis.
The scaled faceted surface is inscribed in the true ellipsoid (its vertices are on it, its triangles
inside), so a point of the true ellipsoid that is not a vertex lies just outside the mesh. The distance
and the nearest point are checked against a brute force of the test's own (every exterior triangle of
the mesh file, the plane projection when it falls inside the triangle, else the nearest of the three
edges). Loaded by a uniform pressure with symmetry conditions on the flat faces, the exact solution is a
homogeneous compression u = c X, which P1 reproduces: the snapped probe must read c times the snapped
point.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI

import meshes
from model.config import parse
from model.domain import exterior_triangles, make_domain, nearest_surface_points
from model.domain.probes import closest_points_on_triangles
from model.errors import ConfigError
from model.pipeline import run

AXES = np.array([0.015, 0.02, 0.03])  # semi-axes A, B, C of the ellipsoid [m]
THETA, PHI = 0.9, 0.7  # the probe's polar and azimuthal angles on the ellipsoid (octant z <= 0)
TRUE_POINT = AXES * np.array([np.sin(THETA) * np.cos(PHI), np.sin(THETA) * np.sin(PHI), -np.cos(THETA)])
INSIDE = [0.004, 0.005, -0.008]  # a point well inside, to measure c of u = c X


def ellipsoid() -> meshes.MeshData:
    """The unit sphere's octant (x, y >= 0, z <= 0) scaled to the semi-axes AXES."""
    ball = meshes.sphere(radius=1.0, size=0.3, octant=True)
    return meshes.MeshData(points=ball.points * AXES, cells=ball.cells, cell_tags=ball.cell_tags,
                           facets=ball.facets, facet_tags=ball.facet_tags, region_names=ball.region_names,
                           boundary_names=ball.boundary_names)


@pytest.fixture(scope="module")
def mesh_file(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    """The ellipsoid written on rank 0 into a folder every rank sees, and its exterior triangles (n, 3, 3)."""
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path_factory.mktemp("ellipsoid")) if comm.rank == 0 else None, root=0))
    path = folder / "ellipsoid.msh"
    data = ellipsoid() if comm.rank == 0 else None
    if comm.rank == 0:
        meshes.write_msh(data, path)
    data = comm.bcast(data, root=0)
    return path, data.points[exterior_triangles(data.cells)]


def brute_force(p: np.ndarray, triangles: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance and nearest point of the triangles to p: per triangle the projection onto its plane if
    its barycentric coordinates are all >= 0, else the nearest point of its three edges (each the clamped
    projection onto the segment); the minimum over all."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    q = p - np.einsum("ij,ij->i", p - a, n)[:, None] * n
    area = lambda u, v, w: np.einsum("ij,ij->i", np.cross(v - u, w - u), n)  # noqa: E731
    total = area(a, b, c)
    bary = np.stack([area(q, b, c), area(a, q, c), area(a, b, q)], axis=1) / total[:, None]
    best, point = np.inf, None
    for i in range(len(triangles)):
        if np.all(bary[i] >= 0):
            candidates = [q[i]]
        else:
            candidates = []
            for u, v in ((a[i], b[i]), (b[i], c[i]), (c[i], a[i])):
                t = np.clip(np.dot(p - u, v - u) / np.dot(v - u, v - u), 0.0, 1.0)
                candidates.append(u + t * (v - u))
        for x in candidates:
            d = float(np.linalg.norm(p - x))
            if d < best:
                best, point = d, x
    return best, point


def config(path: Path, snap: bool, out: Path | None = None) -> dict[str, Any]:
    """Uniform pressure on the curved surface of the ellipsoid octant, symmetry on its flat faces."""
    raw: dict[str, Any] = {
        "mesh": {"file": str(path)},
        "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
        "boundary": [
            {"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
            {"on": "ymin", "type": "displacement", "components": [1], "value": [0.0]},
            {"on": "zmax", "type": "displacement", "components": [2], "value": [0.0]},
            {"on": "surface", "type": "pressure", "value": [300.0]},
        ],
        "loading": {"steps": 1},
        "probe": [{"name": "inside", "point": INSIDE},
                  {"name": "tip", "point": TRUE_POINT.tolist(), "snap": snap}],
        "output": {"xdmf": False, "vtu": False, "png": False},
    }
    return raw


def test_closest_point_matches_brute_force(mesh_file: tuple[Path, np.ndarray]) -> None:
    """The Voronoi-region closest point equals the projection/edges brute force, for points around the body."""
    _, triangles = mesh_file
    rng = np.random.default_rng(3)
    for p in [TRUE_POINT, *rng.uniform(-0.04, 0.04, size=(20, 3))]:
        q = closest_points_on_triangles(p, triangles)
        d = np.linalg.norm(q - p, axis=1)
        distance, point = brute_force(p, triangles)
        assert abs(d.min() - distance) < 1e-15
        assert np.linalg.norm(q[np.argmin(d)] - point) < 1e-14


def test_outside_probe_names_distance_and_nearest_point(mesh_file: tuple[Path, np.ndarray]) -> None:
    path, triangles = mesh_file
    comm = MPI.COMM_WORLD
    distance, point = brute_force(TRUE_POINT, triangles)
    assert 1e-7 < distance < 1e-3  # a hair outside: the premise of the test
    raw = config(path, snap=False)
    with pytest.raises(ConfigError) as caught:
        run(parse(raw, EXAMPLES), out=None)
    message = str(caught.value)
    assert comm.allgather(message) == [message] * comm.size
    pattern = (r"probe\[1\]\.point: \[(.*)\] is outside the mesh, (\S+) m from its surface "
               r"\(nearest point of the body: \[(.*)\]\); set snap = true on the probe to move it there$")
    found = re.match(pattern, message)
    assert found, message
    assert np.allclose([float(x) for x in found.group(1).split(",")], TRUE_POINT, rtol=1e-15, atol=0)
    assert float(found.group(2)) == pytest.approx(distance, rel=0.05)  # two significant digits
    assert np.allclose([float(x) for x in found.group(3).split(",")], point, rtol=1e-5, atol=0)  # six digits

    domain = make_domain(parse(raw, EXAMPLES).mesh, comm)  # the exact values, reduced over the ranks
    d, q = nearest_surface_points(domain.mesh, TRUE_POINT[None, :])
    assert abs(d[0] - distance) < 1e-15
    assert np.linalg.norm(q[0] - point) < 1e-15


def test_snapped_probe_evaluates_at_the_nearest_point(mesh_file: tuple[Path, np.ndarray],
                                                      tmp_path: Path) -> None:
    path, triangles = mesh_file
    comm = MPI.COMM_WORLD
    out = Path(comm.bcast(str(tmp_path), root=0))
    distance, point = brute_force(TRUE_POINT, triangles)
    summary = run(parse(config(path, snap=True), EXAMPLES), out)
    assert summary["status"] == "completed"
    assert np.linalg.norm(np.array(summary["probe_points"]["tip"]) - point) < 1e-15
    assert summary["probe_points"]["inside"] == INSIDE
    assert summary["snapped_probes"] == {"tip": pytest.approx(distance, rel=1e-12)}
    step = summary["steps"][-1]
    c = np.array(step["probes"]["inside"]) / np.array(INSIDE)  # u = c X, the same c for every component
    assert np.ptp(c) < 1e-8 * abs(c.mean()) and c.mean() < -1e-3
    tip = np.array(step["probes"]["tip"])
    assert np.allclose(tip, c.mean() * point, rtol=1e-8, atol=0)
    # the probe was moved: reading it at the original point would differ by |c| times the distance
    assert np.linalg.norm(c.mean() * (TRUE_POINT - point)) > 1e3 * np.linalg.norm(tip - c.mean() * point)
