"""A user's own mesh files and their mistakes, found when the mesh is read, before any solve.

- folded meshes (an interior node moved through its neighbours' faces) are refused with the count,
  the worst cells and how much the cell volumes exceed the volume the surface encloses;
- slivers are warned about; summary.json records the quality minimum;
- every shipped example's mesh passes;
- quadratic (10-node) tetrahedra keep their curved geometry;
- a physical group without elements is "empty", not "missing".

Every mesh file is written on rank 0 into a directory shared by all ranks; all ranks then build.
Messages are compared over ranks (the same on 1 and 2 ranks: computed from the same cells).
"""

from __future__ import annotations

import logging
import tomllib
from pathlib import Path
from typing import Any

import gmsh
import numpy as np
import pytest
import ufl
from conftest import EXAMPLES, RUN_EXAMPLES, example, run_raw
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from test_mesh_files import on_rank0

import meshes
from meshes.topology import signed_volumes
from model import compat
from model.config import parse
from model.domain import make_domain
from model.domain.checks import QUALITY_WARNING, radius_ratio
from model.errors import ConfigError
from model.pipeline import build

SIDE = 0.03  # a 30 mm cube in 8^3 x 6 tetrahedra (3.75 mm cells): the scale
MOVE = np.array([0.0011, -0.0012, 0.0058])  # 6 mm: the centre node goes through its neighbours' faces


def moved_box(move: np.ndarray) -> meshes.MeshData:
    """The cube with its centre node moved by ``move``."""
    box = meshes.box(size=(SIDE, SIDE, SIDE), cells=(8, 8, 8))
    points = box.points.copy()
    points[np.argmin(np.linalg.norm(points - SIDE / 2, axis=1))] += move
    return meshes.MeshData(points=points, cells=box.cells, cell_tags=box.cell_tags, facets=box.facets,
                           facet_tags=box.facet_tags, region_names=box.region_names,
                           boundary_names=box.boundary_names)


def file_config(path: Path, probe: list[float] | None = None) -> dict[str, Any]:
    """The uniaxial example (one step, no files) on the mesh file ``path``."""
    raw = example("uniaxial")
    raw["mesh"] = {"file": str(path)}
    raw["loading"] = {"steps": 1}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    raw["probe"] = [{"name": "corner", "point": probe or [SIDE, SIDE, SIDE]}]
    return raw


def build_error(raw: dict[str, Any]) -> str:
    with pytest.raises(ConfigError) as info:
        build(parse(raw, EXAMPLES))
    message = str(info.value)
    assert "\n" not in message
    assert MPI.COMM_WORLD.allgather(message) == [message] * MPI.COMM_WORLD.size
    return message


# --- folds -----------------------------------------------------------------------------------------------

def test_folded_mesh_is_refused(shared_tmp: Path) -> None:
    path = on_rank0(shared_tmp, "folded.msh", lambda p: meshes.write_msh(moved_box(MOVE), p))
    message = build_error(file_config(path))
    # what the file holds, counted independently on its cells in input order
    data = meshes.read_msh(path)
    volumes = signed_volumes(data.points, data.cells)
    inverted = np.flatnonzero(volumes < 0)
    ratio = np.abs(volumes).sum() / SIDE**3
    assert len(inverted) == 6 and ratio == pytest.approx(1.00217, abs=1e-5)
    assert message.startswith(f"mesh.file: {len(inverted)} cells are folded over their neighbours "
                              "(inverted or overlapping), worst: cell ")
    assert message.endswith(f"; the cell volumes add up to {ratio:.6g} times the volume the surface encloses")
    named = [int(part.split()[0]) for part in message.split("cell ")[1:4]]
    assert len(named) == 3 and set(named) <= set(inverted.tolist())
    worst = inverted[np.argmax(np.abs(volumes[inverted]))]
    centroid = data.points[data.cells[worst]].mean(axis=0)
    assert f"cell {worst} at ({', '.join(f'{c:.6g}' for c in centroid)})" in message


def test_a_moved_node_that_folds_nothing_passes(shared_tmp: Path) -> None:
    """Half the move keeps every cell the right way round: the mesh is read, its quality recorded."""
    path = on_rank0(shared_tmp, "moved.msh", lambda p: meshes.write_msh(moved_box(0.4 * MOVE), p))
    domain = make_domain(parse(file_config(path), EXAMPLES).mesh, MPI.COMM_WORLD)
    assert 0.1 < domain.quality["min_radius_ratio"] < 0.7


def test_radius_ratio() -> None:
    regular = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    right = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    q = radius_ratio(np.stack([regular, flat, right]))
    # right-angled corner: r_in = 1 / (3 + sqrt 3), r_circ = sqrt(3) / 2
    assert q == pytest.approx([1.0, 0.0, 3 * (1 / (3 + np.sqrt(3))) / (np.sqrt(3) / 2)], abs=1e-12)


def circumradius_ratio(x: np.ndarray) -> float:
    """3 r_in / r_circ of one tetrahedron by another route: the circumcentre from a linear system."""
    centre = np.linalg.solve(2 * (x[1:] - x[0]), (x[1:] ** 2).sum(axis=1) - (x[0] ** 2).sum())
    volume = abs(np.linalg.det(x[1:] - x[0])) / 6
    area = sum(np.linalg.norm(np.cross(x[b] - x[a], x[c] - x[a])) / 2
               for a, b, c in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)))
    return 3 * (3 * volume / area) / np.linalg.norm(centre - x[0])


def test_sliver_warns_and_is_recorded(shared_tmp: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The centre node moved to 2 % short of a face of its star: that cell is a sliver, not inverted."""
    box = moved_box(np.zeros(3))
    centre = np.argmin(np.linalg.norm(box.points - SIDE / 2, axis=1))
    direction = MOVE / np.linalg.norm(MOVE)
    moved = box.points.copy()
    moved[centre] += direction
    rate = signed_volumes(moved, box.cells) - signed_volumes(box.points, box.cells)  # V is linear in the node
    v0 = signed_volumes(box.points, box.cells)
    crossing = np.min(-v0[rate < 0] / rate[rate < 0])
    path = on_rank0(shared_tmp, "sliver.msh", lambda p: meshes.write_msh(moved_box(0.98 * crossing * direction), p))
    data = meshes.read_msh(path)
    ratios = np.array([circumradius_ratio(data.points[c]) for c in data.cells])
    expected = ratios.min()
    assert expected < QUALITY_WARNING
    raw = file_config(path)
    with caplog.at_level(logging.WARNING, logger="model.domain.checks"):
        summary = run_raw(raw, shared_tmp / "out")
    quality = summary["mesh_quality"]
    assert quality["min_radius_ratio"] == pytest.approx(expected, rel=1e-8)
    worst = int(np.argmin(ratios))
    np.testing.assert_allclose(quality["worst_cell_centroid"], data.points[data.cells[worst]].mean(axis=0),
                               rtol=1e-12)
    assert "radius ratio" in quality["measure"]
    warnings = [r.getMessage() for r in caplog.records if "sliver" in r.getMessage()]
    assert len(warnings) == (1 if MPI.COMM_WORLD.rank == 0 else 0)
    if warnings:
        count = int(np.sum(ratios < QUALITY_WARNING))
        assert warnings[0].startswith(f"mesh.file: {count} sliver or degenerate cells")
        assert f"cell {worst} at" in warnings[0]


def test_every_example_mesh_passes() -> None:
    """The shipped examples' meshes: no fold, no sliver (quality above the warning threshold)."""
    seen: dict[str, float] = {}
    for toml in RUN_EXAMPLES:
        mesh = tomllib.loads(toml.read_text())["mesh"]
        key = repr(sorted(mesh.items()))
        if key in seen:
            continue
        domain = make_domain(parse({**example(toml.stem), "mesh": mesh}, EXAMPLES).mesh, MPI.COMM_WORLD)
        seen[key] = domain.quality["min_radius_ratio"]
        assert seen[key] > QUALITY_WARNING, toml.name


# --- quadratic tetrahedra ----------------------------------------------------------------------------------

def write_sphere(path: Path, order: int) -> None:
    """The unit sphere (gmsh OCC, 0.5 cells) of ``order`` with physical groups body and surface."""
    with meshes._gmsh.gmsh_session({"Mesh.MeshSizeMax": 0.5, "Mesh.MshFileVersion": 4.1}):
        gmsh.model.occ.addSphere(0, 0, 0, 1.0)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], 1)
        gmsh.model.setPhysicalName(3, 1, "body")
        gmsh.model.addPhysicalGroup(2, [1], 1)
        gmsh.model.setPhysicalName(2, 1, "surface")
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(order)
        gmsh.write(str(path))


def sphere_config(path: Path) -> dict[str, Any]:
    """The unit sphere with a pressure on its surface (built only: nothing holds it) and a probe near the top."""
    raw = file_config(path, probe=[0.0, 0.0, 0.0])
    raw["boundary"] = [{"on": "surface", "type": "pressure", "value": [1.0e2]}]
    raw["probe"] = [{"name": "top", "point": [0.0, 0.0, 0.95]}]
    return raw


def volume_error(domain: Any) -> float:
    one = fem.Constant(domain.mesh, PETSc.ScalarType(1.0))
    dx = ufl.Measure("dx", domain=domain.mesh, metadata={"quadrature_degree": 6})
    volume = MPI.COMM_WORLD.allreduce(fem.assemble_scalar(fem.form(one * dx)), op=MPI.SUM)
    return abs(volume / (4 / 3 * np.pi) - 1)


def test_quadratic_tetrahedra_keep_their_curved_geometry(shared_tmp: Path, caplog: pytest.LogCaptureFixture) -> None:
    errors = {}
    for order in (1, 2):
        path = on_rank0(shared_tmp, f"sphere{order}.msh", lambda p, o=order: write_sphere(p, o))
        with caplog.at_level(logging.WARNING, logger="model.domain.readers"):
            setup = build(parse(sphere_config(path), EXAMPLES))
        assert compat.geometry_degree(setup.domain.mesh) == order
        errors[order] = volume_error(setup.domain)
        curved = [r.getMessage() for r in caplog.records if "10-node tetrahedra" in r.getMessage()]
        assert len(curved) == (1 if order == 2 and MPI.COMM_WORLD.rank == 0 else 0)
        caplog.clear()
    # the same 679 tetrahedra: straight-sided 3.5 % short of the sphere, curved 0.015 %
    assert errors[1] == pytest.approx(0.035, abs=0.002)
    assert errors[2] < 5e-4 < errors[1] / 50


def test_quadratic_sphere_runs_and_writes(shared_tmp: Path) -> None:
    """A solve on the curved mesh, with the XDMF (P2 displacement) and VTU (its vertices) written."""
    path = on_rank0(shared_tmp, "sphere2.msh", lambda p: write_sphere(p, 2))
    raw = sphere_config(path)
    raw["boundary"] = [{"on": "surface", "type": "displacement", "value": [0.0, 0.0, 0.0]}]
    raw["body_force"] = [{"region": "all", "value": [0.0, 0.0, -1.0e3]}]
    raw["output"] = {"xdmf": True, "vtu": True, "png": False}
    out = Path(MPI.COMM_WORLD.bcast(str(shared_tmp / "run"), root=0))
    summary = run_raw(raw, out)
    assert summary["status"] == "completed"
    assert summary["region_volumes"]["all"] == pytest.approx(4 / 3 * np.pi, rel=2e-3)
    assert summary["steps"][-1]["probes"]["top"][2] < 0  # sags under its weight
    assert (out / "results.xdmf").exists() and (out / "step_0001.vtu").exists()


# --- empty physical groups ---------------------------------------------------------------------------------

def write_with_empty_groups(path: Path) -> None:
    """The split box's geometry as a gmsh box with an empty physical volume 'tendon' and surface 'glued'."""
    with meshes._gmsh.gmsh_session({"Mesh.MeshSizeMax": 0.5, "Mesh.MshFileVersion": 4.1}):
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.mesh.generate(3)
        gmsh.model.addPhysicalGroup(3, [1], 1)
        gmsh.model.setPhysicalName(3, 1, "body")
        gmsh.model.addPhysicalGroup(3, [gmsh.model.addDiscreteEntity(3)], 2)
        gmsh.model.setPhysicalName(3, 2, "tendon")
        for tag, name in enumerate(("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"), start=1):
            gmsh.model.addPhysicalGroup(2, [tag], tag)  # OCC box faces 1..6 are x-, x+, y-, y+, z-, z+
            gmsh.model.setPhysicalName(2, tag, name)
        gmsh.model.addPhysicalGroup(2, [gmsh.model.addDiscreteEntity(2)], 7)
        gmsh.model.setPhysicalName(2, 7, "glued")
        gmsh.write(str(path))


def write_inp_with_empty_sets(path: Path) -> None:
    """The box as Abaqus .inp (meshio) with an empty ELSET 'tendon' and an empty NSET 'glued' added."""
    import meshio

    box = meshes.box(size=(1.0, 1.0, 1.0), cells=(2, 2, 2))
    meshio.Mesh(box.points, [("tetra", box.cells)],
                cell_sets={"body": [np.arange(box.num_cells)]},
                point_sets={n: np.unique(box.boundary_facets(n)) for n in box.boundary_names}).write(path)
    with open(path, "a") as file:
        file.write("*ELSET, ELSET=tendon\n*NSET, NSET=glued\n")


@pytest.mark.parametrize("name", ["empty.msh", "empty.inp"])
def test_empty_group_is_empty_not_missing(shared_tmp: Path, name: str) -> None:
    writer = write_with_empty_groups if name.endswith(".msh") else write_inp_with_empty_sets
    path = on_rank0(shared_tmp, name, writer)
    raw = file_config(path)
    law = {k: v for k, v in raw["material"][0].items() if k != "region"}
    raw["material"] = [{"region": "body", **law}, {"region": "tendon", **law}]
    assert build_error(raw) == ("material[1].region: region 'tendon' is empty (the physical group exists in "
                                "mesh.file but holds no cells)")
    raw["material"] = [{"region": "body", **law}]
    raw["boundary"].append({"on": "glued", "type": "traction", "value": [1.0, 0.0, 0.0]})
    k = len(raw["boundary"]) - 1
    assert build_error(raw) == (f"boundary[{k}].on: boundary 'glued' is empty (the physical group exists in "
                                "mesh.file but holds no facets)")
    raw["boundary"][-1]["on"] = "glue"
    assert build_error(raw).startswith(f"boundary[{k}].on: no boundary named 'glue' in the mesh")


def test_guided_simulation_refuses_curved_cells(shared_tmp: Path) -> None:
    """Guided simulation records vertex positions of 4-node cells: a 10-node mesh is refused before solving."""
    from model.experiments.guided import run_stage1

    path = on_rank0(shared_tmp, "sphere2_guided.msh", lambda p: write_sphere(p, 2))
    raw = sphere_config(path)
    raw["material"] = [{"region": "all", "law": "shape_target", "mu": 1.0e4, "kappa": 5.0e4, "S": np.eye(3).tolist()}]
    raw["boundary"] = [{"on": "surface", "type": "displacement", "value": [0.0, 0.0, 0.0]}]
    raw["discretization"] = {"degree": 1, "quadrature_degree": 1}
    with pytest.raises(ConfigError, match=r"^mesh\.file: guided simulation records the vertices of 4-node"):
        run_stage1(parse(raw, EXAMPLES))


# --- curved (10-node) cells --------------------------------------------------------------------------------

GMSH_TET10_EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))  # node 4 + k of a gmsh tet10 sits on edge k


def quadratic_box(jitter: float = 0.03) -> tuple[meshes.MeshData, np.ndarray]:
    """The cube (4^3 x 6 tetrahedra) with 10-node cells whose edge nodes are moved off the edges' midpoints by up
    to ``jitter`` times the cell size in each direction (seeded); also the (num_edges, 2) vertices of the edge
    node ``num_points + e`` (the vertices come first in ``points``)."""
    box = meshes.box(size=(SIDE, SIDE, SIDE), cells=(4, 4, 4))
    ends = np.sort(np.concatenate([box.cells[:, list(e)] for e in GMSH_TET10_EDGES]), axis=1)
    edges, inverse = np.unique(ends, axis=0, return_inverse=True)
    middles = box.points[edges].mean(axis=1)
    middles += np.random.default_rng(7).uniform(-jitter, jitter, middles.shape) * SIDE / 4
    nodes = np.column_stack([box.cells, box.num_points + inverse.reshape(6, -1).T])
    return meshes.MeshData(points=np.vstack([box.points, middles]), cells=box.cells, cell_tags=box.cell_tags,
                           facets=box.facets, facet_tags=box.facet_tags, region_names=box.region_names,
                           boundary_names=box.boundary_names, nodes=nodes), edges


def write_tet10(data: meshes.MeshData, path: Path) -> None:
    """A 10-node mesh as VTU (meshio's tetra10 is VTK's order: edges 01 12 20 03 13 23)."""
    import meshio

    meshio.Mesh(data.points, [("tetra10", data.nodes[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]])]).write(path)


def p2_map(x: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """X(xi) = sum_a N_a(xi) x_a of one gmsh-ordered tet10 (10, 3) at reference points (m, 3), from the shape
    functions' values (not their gradients, as the check has them)."""
    lam = np.column_stack([1 - xi.sum(axis=1), xi])
    values = np.column_stack([lam * (2 * lam - 1)] + [4 * lam[:, a] * lam[:, b] for a, b in GMSH_TET10_EDGES])
    return values @ x


def jacobian_by_differences(x: np.ndarray, xi: np.ndarray, step: float = 1e-6) -> float:
    """det dX/dxi at one reference point by central differences of p2_map."""
    columns = [(p2_map(x, xi[None] + step * e) - p2_map(x, xi[None] - step * e))[0] / (2 * step) for e in np.eye(3)]
    return float(np.linalg.det(np.column_stack(columns)))


def test_curved_cells_that_stay_valid_pass(shared_tmp: Path) -> None:
    """Edge nodes moved by up to 3 % of the cell size: every curved cell keeps det J > 0; the quality records
    min det J / max |det J| (1 on straight sides, read from the same cells without the move)."""
    ratios = {}
    for jitter in (0.0, 0.03):
        path = on_rank0(shared_tmp, f"curved{jitter}.vtu", lambda p, j=jitter: write_tet10(quadratic_box(j)[0], p))
        domain = make_domain(parse(file_config(path), EXAMPLES).mesh, MPI.COMM_WORLD)
        assert compat.geometry_degree(domain.mesh) == 2
        ratios[jitter] = domain.quality["min_jacobian_ratio"]
        assert MPI.COMM_WORLD.allgather(ratios[jitter]) == [ratios[jitter]] * MPI.COMM_WORLD.size
        alone = make_domain(parse(file_config(path), EXAMPLES).mesh, MPI.COMM_SELF)  # the one-rank value
        assert alone.quality["min_jacobian_ratio"] == pytest.approx(ratios[jitter], rel=1e-14)
    assert ratios[0.0] == pytest.approx(1.0, abs=1e-12)
    assert 0.3 < ratios[0.03] < 0.9


@pytest.mark.parametrize("move", ["along", "across"])
def test_inverted_curved_cell_is_refused(shared_tmp: Path, move: str) -> None:
    """One edge node of an edge that only one cell has, moved along the edge to a tenth of it (past the
    quarter point: det J < 0 at the near vertex) or pushed 80 % of the way across the cell to the opposite
    edge's midpoint: that cell's vertex tetrahedron is unchanged, its curved map folds. The one-line error
    names it (its index in the file and its vertices' centroid), the same on every rank."""
    data, edges = quadratic_box()
    owners = [np.flatnonzero(np.isin(data.cells, edge).sum(axis=1) == 2) for edge in edges]  # cells with the edge
    k = next(k for k, cells in enumerate(owners) if len(cells) == 1)
    a, b = edges[k]
    cell = int(owners[k][0])
    points = data.points.copy()
    if move == "along":
        points[data.num_points - len(edges) + k] = points[a] + 0.1 * (points[b] - points[a])
    else:
        middle = points[data.num_points - len(edges) + k]
        opposite = points[[v for v in data.cells[cell] if v not in (a, b)]].mean(axis=0)
        points[data.num_points - len(edges) + k] = middle + 0.8 * (opposite - middle)
    moved = meshes.MeshData(points=points, cells=data.cells, cell_tags=data.cell_tags, facets=data.facets,
                            facet_tags=data.facet_tags, region_names=data.region_names,
                            boundary_names=data.boundary_names, nodes=data.nodes)
    # independently: the vertex tetrahedron is the right way round, the curved map is not everywhere
    x = points[data.nodes[cell]]
    assert signed_volumes(points, data.cells[[cell]])[0] > 0
    inside = np.random.default_rng(1).dirichlet(np.ones(4), 50)[:, 1:]  # reference points from barycentrics
    samples = np.vstack([np.zeros(3), np.eye(3), np.full(3, 0.25), inside])
    assert min(jacobian_by_differences(x, xi) for xi in samples) < 0
    path = on_rank0(shared_tmp, f"inverted_{move}.vtu", lambda p: write_tet10(moved, p))
    with pytest.raises(ConfigError) as info:
        make_domain(parse(file_config(path), EXAMPLES).mesh, MPI.COMM_WORLD)
    message = str(info.value)
    assert "\n" not in message
    assert MPI.COMM_WORLD.allgather(message) == [message] * MPI.COMM_WORLD.size
    with pytest.raises(ConfigError) as alone:  # each rank on its own: the one-rank message
        make_domain(parse(file_config(path), EXAMPLES).mesh, MPI.COMM_SELF)
    assert str(alone.value) == message
    centroid = points[data.cells[cell]].mean(axis=0)
    assert message.startswith(f"mesh.file: 1 curved cell is inverted (the Jacobian determinant of the 10-node "
                              f"map is negative or zero inside the cell, its vertices' tetrahedron is not), worst: "
                              f"cell {cell} at ({', '.join(f'{c:.6g}' for c in centroid)}); "), message
    head, _, ratio = message.rpartition("; in the worst, min det J / max |det J| = ")
    assert head and -1 <= float(ratio) < 0, message
