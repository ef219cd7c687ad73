"""Membrane-membrane contact on a surface from a file (surface = "file", [[contact]]; docs/membranes.md).

- the built-in facing discs of examples/membrane_discs.toml (meshes.membrane.facing_discs: lower 0.2, upper 0.15,
  H = 0.8) written with meshio to a gmsh .msh (the sheets `lower`, `upper` as named physical surfaces, their rims
  as named physical lines) and run with the example's [[contact]] from the file: the same displacement node by
  node (matched by coordinates) as the built-in run to 1e-12 of max |u|, the same contact force (to 1e-12) and
  penetration per step; the file's sheets get their open boundaries as borders (`lower_boundary`,
  `upper_boundary`, the same edges as the rims);
- a contact naming a region the file does not have, sheets sharing nodes (along a seam; two sheets touching at a
  point are a bow-tie vertex, refused by meshes.surface_file), triangles in no named surface, a
  triangle in two, a file without named surfaces: a one-line ConfigError naming the key and the file, before any solve.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import EXAMPLES
from mpi4py import MPI

from meshes.membrane import facing_discs
from meshes.surface_file import read_surface
from model.config.membrane import parse_membrane
from model.errors import ConfigError

DISCS = tomllib.loads((EXAMPLES / "membrane_discs.toml").read_text())
PRESSURES = [4.0e-3, 6.0e-3]  # the contact starts between 2e-3 and 4e-3


def _write(data, path: Path, names: dict[str, str] | None = None) -> Path:  # noqa: ANN001
    """The surface written with meshio on rank 0 as gmsh 2.2: its regions as physical surfaces and its boundaries
    as physical lines (tags 1, 2, ... for the regions, then the boundaries), renamed by ``names``."""
    if MPI.COMM_WORLD.rank == 0:
        names = names or {}
        regions, boundaries = data.region_names, data.boundary_names
        lines = np.concatenate([data.facets[data.facet_tags == t] for t in boundaries.values()])
        line_tags = np.concatenate([np.full(int(np.sum(data.facet_tags == t)), len(regions) + k)
                                    for k, t in enumerate(boundaries.values(), start=1)])
        cell_tags = np.asarray(data.cell_tags, dtype=np.int64)
        field = {names.get(n, n): np.array([t, 2]) for n, t in regions.items()}
        field.update({names.get(n, n): np.array([len(regions) + k, 1]) for k, n in enumerate(boundaries, start=1)})
        mesh = meshio.Mesh(data.points, [("line", lines), ("triangle", data.cells)],
                           cell_data={"gmsh:physical": [line_tags, cell_tags],
                                      "gmsh:geometrical": [line_tags, cell_tags]}, field_data=field)
        mesh.write(path, file_format="gmsh22", binary=False)
    MPI.COMM_WORLD.barrier()
    return path


def _document(membrane: dict | None = None, contact: dict | None = None) -> dict:
    document = copy.deepcopy(DISCS)
    document["inflation"] = {"pressures": PRESSURES}
    document["output"] = {"xdmf": False, "vtu": True}
    if membrane is not None:
        keep = {k: v for k, v in document["membrane"].items() if k not in ("surface", "radius", "gap", "size",
                                                                            "upper_size")}
        document["membrane"] = {**keep, **membrane}
    document["contact"][0].update(contact or {})
    return document


def _run(document: dict, out: Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """Run; the summary, the rest points and the last step's displacement at them (its VTU file)."""
    from model.experiments.membrane_run import run_membrane

    summary = run_membrane(parse_membrane(document), out, MPI.COMM_WORLD)
    last = meshio.read(out / sorted(f for f in summary["files"] if f.endswith(".vtu"))[-1])
    return summary, last.points, last.point_data["u"]


@pytest.fixture(scope="module")
def discs():  # noqa: ANN201
    """The built-in facing discs, meshed on rank 0 only (the files are written there)."""
    m = DISCS["membrane"]
    return facing_discs(m["radius"], m["gap"], m["size"], m["upper_size"]) if MPI.COMM_WORLD.rank == 0 else None


def test_sheets_of_a_file_in_contact_as_the_builtin_discs(discs, shared_tmp: Path) -> None:  # noqa: ANN001
    path = _write(discs, shared_tmp / "sheets.msh")
    data = read_surface(path)
    assert data.region_names == {"lower": 1, "upper": 2}
    assert set(data.boundary_names) == {"boundary", "lower_boundary", "upper_boundary", "lower_rim", "upper_rim"}
    for region in ("lower", "upper"):
        own = np.sort(data.facets[data.facet_tags == data.boundary_names[f"{region}_boundary"]], axis=1)
        rim = np.sort(data.facets[data.facet_tags == data.boundary_names[f"{region}_rim"]], axis=1)
        assert len(own) > 20 and np.array_equal(np.unique(own, axis=0), np.unique(rim, axis=0))
    builtin = _run(_document(), shared_tmp / "builtin")
    result = _run(_document({"surface": "file", "file": str(path)}), shared_tmp / "file")
    (summary, rest, u), (ref_summary, ref_rest, ref_u) = result, builtin
    from scipy.spatial import cKDTree

    distance, index = cKDTree(rest).query(ref_rest)
    assert distance.max() == 0.0 and len(rest) == len(ref_rest)
    scale = np.max(np.abs(ref_u))
    assert scale > 0.1
    assert np.max(np.abs(u[index] - ref_u)) <= 1e-12 * scale
    assert summary["surface"]["nodes"] == ref_summary["surface"]["nodes"]
    for step, ref in zip(summary["steps"], ref_summary["steps"], strict=True):
        (pair,), (ref_pair,) = step["pairs"], ref["pairs"]
        assert pair["pair"] == ref_pair["pair"] == "lower-upper"
        assert ref_pair["max_penetration"] > 1e-4 and ref_pair["force"][2] < -1e-4
        assert np.allclose(pair["force"], ref_pair["force"], rtol=0, atol=1e-12 * abs(ref_pair["force"][2]))
        assert np.allclose(pair["master_force"], ref_pair["master_force"], rtol=0,
                           atol=1e-12 * abs(ref_pair["force"][2]))
        assert pair["max_penetration"] == pytest.approx(ref_pair["max_penetration"], rel=1e-9)
        assert pair["active_points"] == ref_pair["active_points"]
        assert step["volume"] == pytest.approx(ref["volume"], rel=1e-12)


def test_bad_contacts_on_a_file(discs, shared_tmp: Path) -> None:  # noqa: ANN001
    path = _write(discs, shared_tmp / "sheets.msh")
    file = {"surface": "file", "file": str(path)}
    with pytest.raises(ConfigError, match=r"^contact\[0\]\.master: .*sheets\.msh has no region 'top' \(regions: "
                                          r"lower, upper\)$"):
        _run(_document(file, {"master": "top"}), shared_tmp / "refused")
    assert not (shared_tmp / "refused").exists()
    # two sheets touching at one point: the upper disc moved beside the lower one in z = 0, its point of smallest
    # x onto the lower's point of largest x (read_surface merges identical coordinates: one shared node)
    if MPI.COMM_WORLD.rank == 0:
        mesh = meshio.read(path)
        points = mesh.points.copy()
        upper = np.unique(mesh.cells_dict["triangle"][mesh.cell_data_dict["gmsh:physical"]["triangle"] == 2])
        lower = np.unique(mesh.cells_dict["triangle"][mesh.cell_data_dict["gmsh:physical"]["triangle"] == 1])
        right = lower[np.argmax(points[lower, 0])]
        left = upper[np.argmin(points[upper, 0])]
        points[upper] += points[right] - points[left]
        points[left] = points[right]
        meshio.Mesh(points, mesh.cells, cell_data=mesh.cell_data, field_data=mesh.field_data).write(
            shared_tmp / "touching.msh", file_format="gmsh22", binary=False)
    MPI.COMM_WORLD.barrier()
    # (a bow-tie point: refused by meshes.surface_file before the contact's check)
    with pytest.raises(ConfigError, match=r"^membrane\.file: .*touching\.msh: has 1 non-manifold \(bow-tie\) "
                                          r"vertices .* with 2 fans$"):
        _run(_document({"surface": "file", "file": str(shared_tmp / "touching.msh")}), shared_tmp / "refused")
    # two sheets along a seam: the lower disc alone, its triangles of x < 0 named lower, the others upper
    if MPI.COMM_WORLD.rank == 0:
        mesh = meshio.read(path)
        triangles = mesh.cells_dict["triangle"][mesh.cell_data_dict["gmsh:physical"]["triangle"] == 1]
        tags = np.where(mesh.points[triangles].mean(axis=1)[:, 0] < 0, 1, 2)
        meshio.Mesh(mesh.points, [("triangle", triangles)], cell_data={"gmsh:physical": [tags],
                                                                       "gmsh:geometrical": [tags]},
                    field_data={"lower": np.array([1, 2]), "upper": np.array([2, 2])}).write(
            shared_tmp / "seam.msh", file_format="gmsh22", binary=False)
    MPI.COMM_WORLD.barrier()
    with pytest.raises(ConfigError, match=r"^contact\[0\]: .*seam\.msh: regions 'lower' and 'upper' share \d+ "
                                          r"nodes, e\.g\. the point \[.*\] \(membrane-membrane contact needs two "
                                          r"separate sheets.*\)$"):
        _run(_document({"surface": "file", "file": str(shared_tmp / "seam.msh"), "fixed": {"boundary": [0, 1, 2]}}),
             shared_tmp / "refused")
    # a triangle in no named physical surface
    if MPI.COMM_WORLD.rank == 0:
        mesh = meshio.read(path)
        tags = [np.array(t) for t in mesh.cell_data["gmsh:physical"]]
        tags[1][0] = 99
        meshio.Mesh(mesh.points, mesh.cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                    field_data=mesh.field_data).write(shared_tmp / "stray.msh", file_format="gmsh22", binary=False)
    MPI.COMM_WORLD.barrier()
    with pytest.raises(ConfigError, match=r"^membrane\.file: .*stray\.msh: has 1 triangles in no named physical "
                                          r"surface \(named: lower, upper; name every physical surface"):
        _run(_document({"surface": "file", "file": str(shared_tmp / "stray.msh")}), shared_tmp / "refused")
    # a triangle in both named surfaces (gmsh writes it twice): a repeated triangle
    if MPI.COMM_WORLD.rank == 0:
        mesh = meshio.read(path)
        tags = [*mesh.cell_data["gmsh:physical"], np.array([2])]
        meshio.Mesh(mesh.points, [*mesh.cells, ("triangle", mesh.cells[1].data[:1])],
                    cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                    field_data=mesh.field_data).write(shared_tmp / "twice.msh", file_format="gmsh22", binary=False)
    MPI.COMM_WORLD.barrier()
    with pytest.raises(ConfigError, match=r"^membrane\.file: .*twice\.msh: has 1 repeated triangles \(the same three "
                                          r"points, e\.g\. triangle 0; a triangle in two physical surfaces\?\)$"):
        _run(_document({"surface": "file", "file": str(shared_tmp / "twice.msh")}), shared_tmp / "refused")
    # a file of one (unnamed) sheet: no regions for a contact
    if MPI.COMM_WORLD.rank == 0:
        meshio.Mesh(discs.points, [("triangle", discs.cells)]).write(shared_tmp / "soup.obj")
    MPI.COMM_WORLD.barrier()
    with pytest.raises(ConfigError, match=r"^contact\[0\]\.surface: .*soup\.obj has no region 'lower' \(regions: "
                                          r"membrane; name the sheets as physical surfaces of a \.msh file\)$"):
        _run(_document({"surface": "file", "file": str(shared_tmp / "soup.obj")}), shared_tmp / "refused")
