"""Mesh input from files: gmsh .msh, VTU, Abaqus .inp and Medit .mesh give the same solve as the generator.

The mesh is the uniaxial example's 4x4x4 box, split into two named volumes
(left: x < 1/2, right: x > 1/2) so that the region names of each format are used
by two [[material]] entries (same law), and its six faces. Every file is written
on rank 0 into a directory shared by all ranks; all ranks then build (collective).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import meshio
import numpy as np
import pytest
from conftest import EXAMPLES, example, run_raw
from mpi4py import MPI

import meshes
from meshes.box import BOX_FACES
from model.config import parse
from model.errors import ConfigError
from model.pipeline import build

LEFT, RIGHT = 1, 2  # region tags of the split box


def split_box() -> meshes.MeshData:
    """The example's box with volumes left (tag 1) and right (tag 2) and faces xmin..zmax (tags 1..6)."""
    box = meshes.box(size=(1.0, 1.0, 1.0), cells=(4, 4, 4))
    centroids = box.points[box.cells].mean(axis=1)
    tags = np.where(centroids[:, 0] < 0.5, LEFT, RIGHT).astype(np.int32)
    return meshes.MeshData(points=box.points, cells=box.cells, cell_tags=tags, facets=box.facets,
                           facet_tags=box.facet_tags, region_names={"left": LEFT, "right": RIGHT},
                           boundary_names=box.boundary_names)


def on_rank0(directory: Path, name: str, write) -> Path:
    """``write(path)`` on rank 0 only, then a barrier: the file exists for every rank afterwards."""
    path = directory / name
    comm = MPI.COMM_WORLD
    error = None
    if comm.rank == 0:
        try:
            write(path)
        except Exception as err:  # noqa: BLE001 - reported on every rank below
            error = repr(err)
    error = comm.bcast(error, root=0)
    assert error is None, error
    return path


def file_config(path: Path, **mesh: Any) -> dict[str, Any]:
    """The uniaxial example in one load step on the mesh file ``path``, one material per half."""
    raw = example("uniaxial")
    raw["mesh"] = {"file": str(path), **mesh}
    law = {k: v for k, v in raw["material"][0].items() if k != "region"}
    raw["material"] = [{"region": "left", **law}, {"region": "right", **law}]
    raw["loading"] = {"steps": 1}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return raw


def last_step(raw: dict[str, Any], out: Path) -> dict[str, Any]:
    summary = run_raw(raw, out)
    assert summary["status"] == "completed"
    assert summary["cells"] == 384
    return summary["steps"][-1]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The last step of the same one-step solve on the box generator (region "all")."""
    out = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("generator")), root=0))
    raw = example("uniaxial")
    raw["loading"] = {"steps": 1}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return last_step(raw, out)


def assert_same(step: dict[str, Any], reference: dict[str, Any]) -> None:
    """Probes and reactions equal to the generator run to 1e-10 relative."""
    np.testing.assert_allclose(step["probes"]["corner"], reference["probes"]["corner"], rtol=1e-10, atol=1e-14)
    assert set(step["reactions"]) == set(reference["reactions"])
    scale = max(np.abs(v).max() for v in reference["reactions"].values())
    for name, force in reference["reactions"].items():
        np.testing.assert_allclose(step["reactions"][name], force, rtol=1e-10, atol=1e-10 * scale)
    assert reference["reactions"]["xmin"][0] == pytest.approx(-2.0e3, rel=1e-8)  # equilibrium with the traction


def test_gmsh_msh_with_physical_groups(shared_tmp: Path, reference: dict[str, Any]) -> None:
    path = on_rank0(shared_tmp, "box.msh", lambda p: meshes.write_msh(split_box(), p))
    assert_same(last_step(file_config(path), shared_tmp / "out"), reference)


def test_vtu_with_integer_cell_data(shared_tmp: Path, reference: dict[str, Any]) -> None:
    """Tags 100/200 (tetrahedra) and 11..16 (triangles) mapped to names by mesh.regions / mesh.boundaries;
    a decoy integer array shows that mesh.cell_data / mesh.facet_data pick the array."""
    data = split_box()

    def write(path: Path) -> None:
        tags = [100 * data.cell_tags, 10 + data.facet_tags]
        decoy = [np.zeros(len(data.cells), dtype=np.int32), np.zeros(len(data.facets), dtype=np.int32)]
        meshio.Mesh(data.points, [("tetra", data.cells), ("triangle", data.facets)],
                    cell_data={"aaa_decoy": decoy, "tags": tags}).write(path)

    path = on_rank0(shared_tmp, "box.vtu", write)
    raw = file_config(path, regions={"left": 100, "right": 200},
                      boundaries={name: 10 + tag for name, tag in data.boundary_names.items()},
                      cell_data="tags", facet_data="tags")
    assert_same(last_step(raw, shared_tmp / "out"), reference)


def test_abaqus_inp_written_by_meshio(shared_tmp: Path, reference: dict[str, Any]) -> None:
    """ELSETs left/right become regions, NSETs of the face vertices become boundaries."""
    data = split_box()

    def write(path: Path) -> None:
        cell_sets = {name: [np.flatnonzero(data.cell_tags == tag)] for name, tag in data.region_names.items()}
        point_sets = {name: np.unique(data.boundary_facets(name)) for name in BOX_FACES}
        meshio.Mesh(data.points, [("tetra", data.cells)], cell_sets=cell_sets, point_sets=point_sets).write(path)

    path = on_rank0(shared_tmp, "box.inp", write)
    assert_same(last_step(file_config(path), shared_tmp / "out"), reference)


def write_inp_by_hand(data: meshes.MeshData, path: Path, element_sets: bool) -> None:
    """An Abaqus deck as other tools write it: 1-based node ids with gaps, S3 triangles in an ELSET (xmax,
    the loaded face), NSETs for the three supported faces, 8 ids per line, comments and lower case.

    element_sets: one ``*ELEMENT, TYPE=C3D4, ELSET=name`` block per region; else a single C3D4 block
    without a set and the regions as ``*ELSET`` lists of element ids (written after the S3 block).
    """
    node_id = 1000 + 3 * np.arange(len(data.points))  # non-consecutive node numbers

    def id_lines(ids: np.ndarray) -> list[str]:
        return [", ".join(str(i) for i in ids[k:k + 8]) for k in range(0, len(ids), 8)]

    def element_lines(first: int, conn: np.ndarray) -> list[str]:
        return [f"{first + k}, " + ", ".join(str(n) for n in node_id[c]) for k, c in enumerate(conn)]

    lines = ["*Heading", "split box written by hand", "** a comment", "*Node"]
    lines += [f"{node_id[i]}, {x!r}, {y!r}, {z!r}" for i, (x, y, z) in enumerate(data.points.tolist())]
    order = np.argsort(data.cell_tags, kind="stable")
    if element_sets:
        first = 1
        for name, tag in data.region_names.items():
            conn = data.cells[data.cell_tags == tag]
            lines += [f"*Element, type=C3D4, elset={name}", *element_lines(first, conn)]
            first += len(conn)
    else:
        lines += ["*ELEMENT, TYPE=C3D4", *element_lines(1, data.cells[order])]
    xmax = data.boundary_facets("xmax")
    lines += ["*ELEMENT, TYPE=S3, ELSET=xmax", *element_lines(len(data.cells) + 1, xmax)]
    if not element_sets:
        for name, tag in data.region_names.items():
            lines += [f"*ELSET, ELSET={name}", *id_lines(1 + np.flatnonzero(data.cell_tags[order] == tag))]
    for name in ("xmin", "ymin", "zmin"):
        lines += [f"*Nset, nset={name}", *id_lines(node_id[np.unique(data.boundary_facets(name))])]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("element_sets", [True, False], ids=["element-sets", "elset-lists"])
def test_abaqus_inp_written_by_hand(shared_tmp: Path, reference: dict[str, Any], element_sets: bool) -> None:
    path = on_rank0(shared_tmp, "hand.inp", lambda p: write_inp_by_hand(split_box(), p, element_sets))
    assert_same(last_step(file_config(path), shared_tmp / "out"), reference)


def test_medit_mesh_with_refs(shared_tmp: Path, reference: dict[str, Any]) -> None:
    """medit:ref of tetrahedra and triangles (the default: first integer cell data) mapped by name."""
    data = split_box()

    def write(path: Path) -> None:
        meshio.Mesh(data.points, [("tetra", data.cells), ("triangle", data.facets)],
                    cell_data={"medit:ref": [data.cell_tags, data.facet_tags]}).write(path)

    path = on_rank0(shared_tmp, "box.mesh", write)
    raw = file_config(path, regions=dict(data.region_names), boundaries=dict(data.boundary_names))
    assert_same(last_step(raw, shared_tmp / "out"), reference)


# --- errors of mesh files: ConfigError naming the key, on every rank, before any solve ---------------------------

def build_error(raw: dict[str, Any]) -> str:
    with pytest.raises(ConfigError) as info:
        build(parse(raw, EXAMPLES))
    message = str(info.value)
    assert "\n" not in message
    assert MPI.COMM_WORLD.allgather(message) == [message] * MPI.COMM_WORLD.size
    return message


def write_medit(path: Path) -> None:
    data = split_box()
    meshio.Mesh(data.points, [("tetra", data.cells), ("triangle", data.facets)],
                cell_data={"medit:ref": [data.cell_tags, data.facet_tags]}).write(path)


def test_region_tag_not_in_file(shared_tmp: Path) -> None:
    path = on_rank0(shared_tmp, "box.mesh", write_medit)
    message = build_error(file_config(path, regions={"left": 1, "right": 7}, boundaries={"xmin": 1}))
    assert message.startswith("mesh.regions.right: ") and "7" in message


def test_boundary_tag_not_in_file(shared_tmp: Path) -> None:
    path = on_rank0(shared_tmp, "box.mesh", write_medit)
    message = build_error(file_config(path, regions={"left": 1, "right": 2}, boundaries={"xmin": 9}))
    assert message.startswith("mesh.boundaries.xmin: ")


def test_cell_data_name_not_in_file(shared_tmp: Path) -> None:
    path = on_rank0(shared_tmp, "box.mesh", write_medit)
    message = build_error(file_config(path, regions={"left": 1}, cell_data="gmsh:physical"))
    assert message.startswith("mesh.cell_data: ") and "medit:ref" in message


def test_mapped_names_missing_from_config_names(shared_tmp: Path) -> None:
    """A boundary the file does not name is reported against the [[boundary]] that uses it."""
    path = on_rank0(shared_tmp, "box.mesh", write_medit)
    message = build_error(file_config(path, regions={"left": 1, "right": 2}, boundaries={"xmin": 1}))
    assert message.startswith("boundary[1].on: ") and "'ymin'" in message


def test_file_without_tetrahedra(shared_tmp: Path) -> None:
    data = split_box()
    path = on_rank0(shared_tmp, "surface.vtu",
                    lambda p: meshio.Mesh(data.points, [("triangle", data.facets)]).write(p))
    message = build_error(file_config(path))
    assert message.startswith("mesh.file: ") and "no tetrahedra" in message


def test_unreadable_file(shared_tmp: Path) -> None:
    path = on_rank0(shared_tmp, "garbage.vtu", lambda p: p.write_text("this is\nnot a mesh\n"))
    assert build_error(file_config(path)).startswith("mesh.file: ")


def test_msh_with_a_name_map_is_refused(shared_tmp: Path) -> None:
    path = on_rank0(shared_tmp, "box.msh", lambda p: meshes.write_msh(split_box(), p))
    with pytest.raises(ConfigError, match=r"^mesh\.regions: "):
        parse(file_config(path, regions={"left": 1}), EXAMPLES)
