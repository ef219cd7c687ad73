"""A render mesh embedded in the simulation mesh (model.fields.embedding, output.render_mesh; issue 14 item 5).

An affine motion of the tetrahedral mesh moves the embedded mesh exactly (1e-12), P1 and P2, vertices inside the
body and outside it (they move with the nearest cell's interpolant), on 1 and 2 ranks; a run writes one frame
per step in the file's own format, listed in summary.json; bad files are one-line errors before any solve.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import example, run_raw
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from model import compat
from model.errors import ConfigError
from model.fields.embedding import Embedding

A = np.array([[1.1, 0.2, -0.1], [0.05, 0.9, 0.3], [-0.2, 0.1, 1.3]])
B = np.array([0.1, -0.2, 0.3])


def sphere(centre, radius: float, refine: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """An icosphere: points (N, 3) and triangles."""
    t = (1 + 5**0.5) / 2
    p = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]
    points = [np.array(q, dtype=float) / np.linalg.norm(q) for q in p]
    faces = f
    for _ in range(refine):
        cache: dict[tuple[int, int], int] = {}

        def middle(i: int, j: int, cache: dict[tuple[int, int], int] = cache) -> int:
            key = (min(i, j), max(i, j))
            if key not in cache:
                m = points[i] + points[j]
                points.append(m / np.linalg.norm(m))
                cache[key] = len(points) - 1
            return cache[key]

        faces = [g for a, b, c in faces for g in ((a, middle(a, b), middle(c, a)), (b, middle(b, c), middle(a, b)),
                                                 (c, middle(c, a), middle(b, c)), (middle(a, b), middle(b, c),
                                                                                   middle(c, a)))]
    return np.asarray(centre) + radius * np.array(points), np.array(faces, dtype=np.int64)


@pytest.mark.parametrize("degree", [1, 2])
def test_an_affine_motion_moves_the_embedded_mesh_exactly(degree: int) -> None:
    msh = dmesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [1, 1, 2]], [3, 3, 5], dmesh.CellType.tetrahedron)
    points, faces = sphere((0.5, 0.5, 1.0), 0.62)  # pokes out of the 1 x 1 sides
    V = compat.function_space(msh, "Lagrange", degree, (3,))
    u = fem.Function(V)
    u.interpolate(lambda x: (A - np.eye(3)) @ x + B[:, None])
    embedding = Embedding(msh, points, [("triangle", faces)])
    x = embedding.positions(u)
    assert embedding.outside > 0 and embedding.summary()["vertices"] == len(points)
    if MPI.COMM_WORLD.rank == 0:
        assert np.abs(x - (points @ A.T + B)).max() < 1e-12
    else:
        assert x is None


def render_config(tmp: Path, render: Path) -> dict:
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["loading"] = {"steps": 3}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False, "render_mesh": str(render)}
    return raw


def test_a_run_writes_a_frame_per_step(shared_tmp: Path) -> None:
    """The uniaxial example (a homogeneous stretch: u affine) with a sphere OBJ poking out of the cube: one OBJ per
    step with the file's faces, its vertices the affine image of the rest vertices (fitted, residual 1e-10),
    stretched along x; the frames listed in summary.json."""
    render = shared_tmp / "skin.obj"
    points, faces = sphere((0.5, 0.5, 0.5), 0.55)
    if MPI.COMM_WORLD.rank == 0:
        meshio.write(render, meshio.Mesh(points, [("triangle", faces)]))
    MPI.COMM_WORLD.barrier()
    summary = run_raw(render_config(shared_tmp, render), shared_tmp / "out")
    frames = sorted((shared_tmp / "out" / "render").glob("skin_*.obj"))
    assert [f.name for f in frames] == ["skin_0001.obj", "skin_0002.obj", "skin_0003.obj"]
    assert {f"render/{f.name}" for f in frames} <= set(summary["files"])
    assert summary["render_mesh"]["vertices"] == len(points) and summary["render_mesh"]["outside"] > 0
    last = meshio.read(frames[-1])
    assert np.array_equal(last.cells[0].data, faces)
    X = np.c_[points, np.ones(len(points))]
    fit, *_ = np.linalg.lstsq(X, last.points, rcond=None)
    assert np.abs(X @ fit - last.points).max() < 1e-10  # an affine image (homogeneous state)
    stretch = fit[0, 0]
    assert stretch > 1.05 and abs(fit[1, 1] - 1.0) < 0.1  # pulled along x, contracting a little sideways


def test_bad_render_meshes_are_refused_before_any_solve(shared_tmp: Path) -> None:
    with pytest.raises(ConfigError, match=r"output\.render_mesh: .*no such file"):
        run_raw(render_config(shared_tmp, shared_tmp / "missing.obj"), shared_tmp / "out")
    bad = shared_tmp / "bad.stl"
    if MPI.COMM_WORLD.rank == 0:
        bad.write_text("this is not an STL file\n")
    MPI.COMM_WORLD.barrier()
    with pytest.raises(ConfigError, match=r"output\.render_mesh: .*bad\.stl: not a mesh meshio can read"):
        run_raw(render_config(shared_tmp, bad), shared_tmp / "out2")
    assert not (shared_tmp / "out2" / "summary.json").exists()
