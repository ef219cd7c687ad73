"""A membrane run on the user's own triangle surface (surface = "file": meshes.surface_file, docs/membranes.md).

- the built-in disc (meshes.membrane.disc_surface) written to OBJ, STL (a triangle soup: its points merged) and
  gmsh .msh (its rim a named physical line) and inflated from the file: the same displacement node by node
  (matched by coordinates) as the built-in disc to 1e-12, and the same pressure-volume records; the .msh's named
  line is a border;
- the same file with half its triangles turned: refused with orientation = "file" (the file named), and
  inflated to the same displacements with orientation = [0, 0, 1];
- bad files: a one-line ConfigError naming the key and the file before the output folder is made (missing,
  unreadable, no triangles, quads besides triangles, a non-manifold edge, a bow-tie vertex (two fans meeting at
  one point; ``vertex_fans`` counts one fan at every vertex of a disc, a sphere and a disc with half its triangles
  turned), a degenerate triangle, an unknown border name, a closed surface with the default border);
- examples/membrane_file.toml (examples/data/dome_patch.obj) runs.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI

from meshes.membrane import disc_surface, sphere_surface
from model.config.membrane import load_membrane, parse_membrane
from model.errors import ConfigError

RADIUS, SIZE = 1.0, 0.3
BASE = {"law": "stvk", "young": 1.0, "nu": 0.3, "thickness": 0.01, "bump": 0.03}
INFLATION = {"pressures": [2e-7, 1e-6]}
OUTPUT = {"xdmf": False, "vtu": True}


def _write(data, path: Path, cells: np.ndarray | None = None, msh: bool = False) -> Path:  # noqa: ANN001
    """The surface written with meshio on rank 0 (.msh: triangles and the rim as physical groups)."""
    if MPI.COMM_WORLD.rank == 0:
        cells = data.cells if cells is None else cells
        if msh:
            rim = data.facets[data.facet_tags == data.boundary_names["rim"]]
            mesh = meshio.Mesh(data.points, [("line", rim), ("triangle", cells)],
                               cell_data={"gmsh:physical": [np.full(len(rim), 2), np.full(len(cells), 1)],
                                          "gmsh:geometrical": [np.full(len(rim), 2), np.full(len(cells), 1)]},
                               field_data={"membrane": np.array([1, 2]), "edge": np.array([2, 1])})
            mesh.write(path, file_format="gmsh22", binary=False)
        else:
            meshio.Mesh(data.points, [("triangle", cells)]).write(path)
    MPI.COMM_WORLD.barrier()
    return path


def _run(membrane: dict, out: Path, inflation: dict | None = None) -> tuple[dict, np.ndarray, np.ndarray]:
    """Run; the summary, the rest points and the last step's displacement at them (its VTU file)."""
    from model.experiments.membrane_run import run_membrane

    config = parse_membrane({"membrane": {**BASE, **membrane}, "inflation": inflation or INFLATION,
                             "output": OUTPUT})
    summary = run_membrane(config, out, MPI.COMM_WORLD)
    last = meshio.read(out / sorted(f for f in summary["files"] if f.endswith(".vtu"))[-1])
    return summary, last.points, last.point_data["u"]


def _by_coordinates(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The index into ``points`` of each reference point (exact coordinates)."""
    from scipy.spatial import cKDTree

    distance, index = cKDTree(points).query(reference)
    assert distance.max() == 0.0
    return index


@pytest.fixture(scope="module")
def disc():  # noqa: ANN201
    return disc_surface(RADIUS, SIZE)


@pytest.fixture(scope="module")
def builtin(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, np.ndarray, np.ndarray]:
    out = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("builtin")), root=0))
    return _run({"surface": "disc", "radius": RADIUS, "size": SIZE}, out)


def _same_as_builtin(result: tuple[dict, np.ndarray, np.ndarray], builtin: tuple) -> None:
    summary, rest, u = result
    ref_summary, ref_rest, ref_u = builtin
    index = _by_coordinates(rest, ref_rest)
    assert len(rest) == len(ref_rest)
    assert np.max(np.abs(u[index] - ref_u)) <= 1e-12 * np.max(np.abs(ref_u))
    assert np.max(np.abs(ref_u[:, 2])) > 0.01  # inflated: u_z ~ 0.03 at the centre
    for step, ref in zip(summary["steps"], ref_summary["steps"], strict=True):
        assert step["pressure"] == ref["pressure"]
        assert step["volume"] == pytest.approx(ref["volume"], rel=1e-12)
        assert step["energy"] == pytest.approx(ref["energy"], rel=1e-10)
    assert summary["surface"]["rest_volume"] == pytest.approx(0.0, abs=1e-14)
    assert summary["surface"]["reference_area"] == pytest.approx(ref_summary["surface"]["reference_area"], rel=1e-14)


@pytest.mark.parametrize("suffix", [".obj", ".stl", ".msh"])
def test_a_file_inflates_as_the_builtin_disc(disc, builtin, shared_tmp: Path, suffix: str) -> None:  # noqa: ANN001
    path = _write(disc, shared_tmp / f"disc{suffix}", msh=suffix == ".msh")
    border = {"fixed": {"edge": [0, 1, 2]}} if suffix == ".msh" else {}
    result = _run({"surface": "file", "file": str(path), "centre": [0.0, 0.0, 0.0], "radius": RADIUS, **border},
                  shared_tmp / "out")
    _same_as_builtin(result, builtin)
    assert result[0]["surface"]["file"] == str(path)
    assert result[0]["surface"]["triangles"] == len(disc.cells)


def test_inconsistent_triangles_refused_or_oriented(disc, builtin, shared_tmp: Path) -> None:  # noqa: ANN001
    cells = disc.cells.copy()
    cells[::2] = cells[::2][:, [0, 2, 1]]
    path = _write(disc, shared_tmp / "mixed.ply", cells)
    with pytest.raises(ConfigError, match=r"^membrane\.file: .*mixed\.ply: triangles inconsistently oriented by the "
                                          r"file's vertex order: \d+ edges .*give membrane\.orientation\)$"):
        _run({"surface": "file", "file": str(path)}, shared_tmp / "refused")
    result = _run({"surface": "file", "file": str(path), "orientation": [0.0, 0.0, 1.0], "centre": [0.0, 0.0, 0.0],
                   "radius": RADIUS}, shared_tmp / "oriented")
    _same_as_builtin(result, builtin)


def _bad_files(folder: Path) -> dict[str, Path]:
    """Bad surfaces written on rank 0."""
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 1.0], [2, 0, 0]], dtype=float)
    files = {"missing": folder / "none.obj", "unreadable": folder / "garbage.stl",
             "no_triangles": folder / "lines.vtu", "quads": folder / "quads.vtu", "non_manifold": folder / "fin.obj",
             "degenerate": folder / "flat.obj", "closed": folder / "sphere.obj", "bow_tie": folder / "bowtie.obj"}
    if MPI.COMM_WORLD.rank == 0:
        files["unreadable"].write_text("solid nothing\n facet normal garbage\n")
        meshio.Mesh(p, [("line", np.array([[0, 1], [1, 2]]))]).write(files["no_triangles"])
        meshio.Mesh(p, [("triangle", np.array([[0, 1, 2]])), ("quad", np.array([[0, 1, 3, 2]]))]).write(
            files["quads"])
        meshio.Mesh(p, [("triangle", np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))]).write(files["non_manifold"])
        meshio.Mesh(p, [("triangle", np.array([[0, 1, 2], [0, 1, 5]]))]).write(files["degenerate"])
        sphere = sphere_surface(1.0, 0.8)
        meshio.Mesh(sphere.points, [("triangle", sphere.cells)]).write(files["closed"])
        # two fans, one triangle each at the point (0.5, 0.5, 0) (triangles 0 and 2; 1 and 3 hang on their far edges),
        # meeting only there
        q = np.array([[0.5, 0.5, 0], [0, 0, 0], [1, 0, 0], [0.5, -0.5, 0.2], [0, 1, 0], [1, 1, 0], [0.5, 1.5, 0.2]])
        meshio.Mesh(q, [("triangle", np.array([[0, 1, 2], [1, 3, 2], [0, 5, 4], [4, 5, 6]]))]).write(
            files["bow_tie"])
    MPI.COMM_WORLD.barrier()
    return files


@pytest.mark.parametrize(("name", "extra", "message"), [
    ("missing", {}, r"^membrane\.file: no such file: .*none\.obj$"),
    ("unreadable", {}, r"^membrane\.file: .*garbage\.stl: cannot read it: "),
    ("no_triangles", {}, r"^membrane\.file: .*lines\.vtu: has no triangles$"),
    ("quads", {}, r"^membrane\.file: .*quads\.vtu: has quad cells besides triangles"),
    ("non_manifold", {}, r"^membrane\.file: .*fin\.obj: has 1 non-manifold edges \(shared by more than two"),
    ("degenerate", {}, r"^membrane\.file: .*flat\.obj: has 1 degenerate triangles"),
    ("bow_tie", {}, r"^membrane\.file: .*bowtie\.obj: has 1 non-manifold \(bow-tie\) vertices \(two or more fans "
                    r"of triangles meeting only at the vertex\), e\.g\. point 0 at \[0\.5, 0\.5, 0\.0\] with 2 fans$"),
    ("closed", {}, r"^membrane\.fixed: .*sphere\.obj has no edges on 'boundary' \(a closed surface"),
    ("closed", {"fixed": {"rim": [2]}}, r"^membrane\.fixed\.rim: .*sphere\.obj has no boundary 'rim' "
                                        r"\(boundaries: boundary\)$"),
])
def test_bad_files_name_the_key_and_file(shared_tmp: Path, name: str, extra: dict, message: str) -> None:
    path = _bad_files(shared_tmp)[name]
    with pytest.raises(ConfigError, match=message) as err:
        _run({"surface": "file", "file": str(path), **extra}, shared_tmp / "out")
    assert "\n" not in str(err.value)
    assert not (shared_tmp / "out").exists()  # checked before the output folder is made


@pytest.mark.parametrize(("membrane", "message"), [
    ({"surface": "file"}, r"^membrane\.file: missing \(surface = 'file' needs"),
    ({"surface": "disc", "orientation": "outward"}, r"^membrane\.orientation: only applies to surface = 'file'"),
    ({"surface": "file", "file": __file__, "size": 0.1}, r"^membrane\.size: only applies to surface = "),
    ({"surface": "file", "file": __file__, "orientation": "inward"}, r"^membrane\.orientation: "),
])
def test_file_keys(membrane: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_membrane({"membrane": {**BASE, **membrane}, "inflation": INFLATION})


def test_the_example(shared_tmp: Path) -> None:
    from model.experiments.membrane_run import run_membrane

    config = load_membrane(EXAMPLES / "membrane_file.toml", {"output.xdmf": False, "output.vtu": False})
    summary = run_membrane(config, shared_tmp / "example", MPI.COMM_WORLD)
    assert summary["status"] == "completed"
    volumes = [s["volume"] for s in summary["steps"]]
    assert all(b > a for a, b in zip(volumes, volumes[1:]))
    assert volumes[0] > summary["surface"]["rest_volume"]


def test_outward_and_a_direction_on_a_closed_surface() -> None:
    """The whole sphere with its triangles turned at random: "outward" orients all of them away from the centre
    (consistent), one direction cannot orient a closed surface consistently (refused, naming it)."""
    from meshes.surface_file import check_orientation, oriented_cells

    sphere = sphere_surface(1.0, 0.8)
    cells = sphere.cells.copy()
    turn = np.random.default_rng(1).random(len(cells)) < 0.5
    cells[turn] = cells[turn][:, [0, 2, 1]]
    assert check_orientation(cells)[0] > 0
    outward = oriented_cells(sphere.points, cells, "outward")
    assert check_orientation(outward) == (0, None)
    p = sphere.points[outward]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert np.all(np.einsum("ij,ij->i", normals, p.mean(axis=1)) > 0)
    with pytest.raises(ValueError, match=r"^triangles inconsistently oriented by orientation \[0\.0, 0\.0, 1\.0\]: "):
        oriented_cells(sphere.points, cells, np.array([0.0, 0.0, 1.0]))


def test_a_flat_file_cannot_be_oriented_outward(disc, shared_tmp: Path) -> None:  # noqa: ANN001
    """A flat disc's triangles are all perpendicular to "outward" (in-plane): the file's inconsistent order stays
    and the run is refused naming membrane.orientation."""
    cells = disc.cells.copy()
    cells[::2] = cells[::2][:, [0, 2, 1]]
    path = _write(disc, shared_tmp / "mixed.obj", cells)
    with pytest.raises(ConfigError, match=r"^membrane\.orientation: .*mixed\.obj: triangles inconsistently oriented "
                                          r"by orientation outward: "):
        _run({"surface": "file", "file": str(path), "orientation": "outward"}, shared_tmp / "out")


def test_vertex_fans_one_fan_on_manifold_surfaces(disc) -> None:  # noqa: ANN001
    """One fan at every vertex of the disc (open fans on the rim), the sphere (closed fans) and the disc with every
    other triangle turned (the fans do not depend on the orientation); two at the tip of two fans meeting at a point,
    and three at three fans."""
    from meshes.surface_file import vertex_fans

    turned = disc.cells.copy()
    turned[::2] = turned[::2][:, [0, 2, 1]]
    for cells in (disc.cells, sphere_surface(1.0, 0.8).cells, turned):
        assert np.all(vertex_fans(cells) == 1)
    fans = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 6]])
    assert vertex_fans(fans).tolist() == [2, 1, 1, 1, 1, 1, 1]
    assert vertex_fans(np.vstack([fans, [[0, 7, 8]]])).tolist() == [3] + [1] * 8
