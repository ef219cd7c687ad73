"""From a mesh section to a distributed Domain: a built-in generator, a gmsh .msh, or any mesh meshio reads.

The mesh is built on rank 0 (meshes.MeshData) and distributed (model.domain.distribute); every
reader failure becomes a ConfigError naming the key (mesh.file, mesh.PARAMETER), raised on every rank.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
from mpi4py import MPI

import meshes
from meshes import MeshData
from model import compat
from model.config import MeshConfig
from model.domain.checks import check_mesh
from model.domain.distribute import Domain, build_domain
from model.errors import ConfigError

log = logging.getLogger(__name__)


def load_mesh_data(cfg: MeshConfig) -> meshes.MeshData:
    """The MeshData of a mesh section (call on one rank); errors become ConfigError naming the key."""
    if cfg.generator is not None:
        try:
            return meshes.generate(cfg.generator, **cfg.params)
        except (TypeError, ValueError) as err:
            # generator messages read "<generator>: <parameter>[i] must be ...": name mesh.<parameter>
            message = " ".join(str(err).split())
            param = message.removeprefix(f"{cfg.generator}: ").split(" ")[0].split("[")[0]
            key = f"mesh.{param}" if param in cfg.params else "mesh"
            raise ConfigError(f"{key}: {message}") from None
    assert cfg.file is not None
    if cfg.file.suffix == ".geo":  # a gmsh script, meshed here; its physical groups name regions and boundaries
        try:
            return meshes.read_geo(cfg.file, cfg.parameters)
        except ValueError as err:
            raise ConfigError(f"mesh.file: cannot mesh {cfg.file}: {' '.join(str(err).split())}") from None
    try:
        if cfg.file.suffix == ".msh":
            data = meshes.read_msh(cfg.file)
            for key, mapping in (("regions", cfg.regions), ("boundaries", cfg.boundaries)):
                if mapping:
                    raise ConfigError(f"mesh.{key}: a .msh file names its physical groups itself; remove this table")
            return data
        return read_meshio(cfg.file, cfg.regions, cfg.boundaries, cfg.cell_data, cfg.facet_data)
    except ConfigError:
        raise
    except Exception as err:  # noqa: BLE001 - any reader failure is reported against mesh.file
        message = " ".join(str(err).split())  # one line
        if message.startswith("mesh."):
            raise ConfigError(message) from None
        raise ConfigError(f"mesh.file: cannot read {cfg.file}: {message}") from None


def make_domain(cfg: MeshConfig, comm: MPI.Comm) -> Domain:
    """Build the mesh on rank 0 and distribute it; a failure on rank 0 is raised on every rank."""
    data, error, failure = None, None, None
    if comm.rank == 0:
        try:
            data = load_mesh_data(cfg)
        except ConfigError as err:
            error = str(err)
        except Exception as err:  # noqa: BLE001 - re-raised below, after telling the other ranks
            failure = err
    error, other = comm.bcast((error, None if failure is None else f"{type(failure).__name__}: {failure}"), root=0)
    if error is not None:
        raise ConfigError(error)
    if other is not None:
        if failure is not None:
            raise failure
        raise RuntimeError(f"building the mesh failed on rank 0: {other}")
    domain = build_domain(comm, data)
    key = "mesh.file" if cfg.file is not None else "mesh.generator"
    domain.quality = check_mesh(domain.mesh, key)
    if compat.geometry_degree(domain.mesh) > 1 and comm.rank == 0:
        log.warning("%s: 10-node tetrahedra: the geometry is curved (degree 2); approximated by the straight-"
                    "sided vertex tetrahedra: the fold and quality checks (the curved map is checked for inverted "
                    "cells on its own), the VTU files and the PNG; integrals use discretization.quadrature_degree "
                    "(3 or more integrates a curved cell's volume exactly)", key)
    return domain


def read_meshio(path: Path, regions: dict[str, int], boundaries: dict[str, int],
                cell_data: str | None = None, facet_data: str | None = None) -> MeshData:
    """A MeshData from any tetrahedral mesh meshio reads (VTU, Abaqus .inp, Medit .mesh, ...).

    Cell tags come from the integer cell-data array ``cell_data`` of the tetrahedra
    (default: the first integer array, e.g. gmsh:physical or medit:ref) mapped to
    names by ``regions``; facet tags likewise from the triangles with ``facet_data``
    and ``boundaries``. Named cell sets (Abaqus ELSET) become regions, named point
    sets (NSET) become boundaries made of the boundary triangles whose vertices are
    all in the set. Untagged tetrahedra form the region "all" only.
    """
    path = Path(path)
    m = _meshio_read(path)
    if path.suffix.lower() == ".inp":
        _fix_abaqus_element_sets(path, m)
    tet_blocks = [i for i, c in enumerate(m.cells) if c.type in ("tetra", "tetra10")]
    if not tet_blocks:
        raise ValueError(f"{path}: no tetrahedra in the mesh (found {', '.join(c.type for c in m.cells)})")
    tri_blocks = [i for i, c in enumerate(m.cells) if c.type in ("triangle", "triangle6")]

    def block_data(blocks: list[int], name: str | None, key: str) -> np.ndarray | None:
        candidates = [name] if name else [k for k, v in m.cell_data.items()
                                          if all(np.issubdtype(np.asarray(v[b]).dtype, np.integer) for b in blocks)]
        if name and name not in m.cell_data:
            raise ValueError(f"mesh.{key}: {path.name} has no cell data named {name!r} "
                             f"(found: {', '.join(m.cell_data) or 'none'})")
        if name and not all(np.issubdtype(np.asarray(m.cell_data[name][b]).dtype, np.integer) for b in blocks):
            raise ValueError(f"mesh.{key}: the cell data {name!r} of {path.name} is not integer")
        if not candidates or not blocks:
            return None
        return np.concatenate([np.asarray(m.cell_data[candidates[0]][b]).reshape(-1) for b in blocks])

    cells = np.concatenate([m.cells[b].data[:, :4] for b in tet_blocks]).astype(np.int64)
    nodes = None
    if all(m.cells[b].type == "tetra10" for b in tet_blocks):
        # meshio's tetra10 is VTK's order (edges 01 12 20 03 13 23); MeshData.nodes is gmsh's (... 30 32 31)
        nodes = np.concatenate([m.cells[b].data for b in tet_blocks]).astype(np.int64)
        nodes = nodes[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]]
    elif any(m.cells[b].type == "tetra10" for b in tet_blocks):
        log.warning("mesh.file: %s mixes 4- and 10-node tetrahedra: all are reduced to their vertices "
                    "(straight-sided)", path.name)
    ctags = block_data(tet_blocks, cell_data, "cell_data")
    cell_tags = np.zeros(len(cells), dtype=np.int32) if ctags is None else ctags.astype(np.int32)
    region_names = dict(regions)
    cell_sets = getattr(m, "cell_sets", None) or {}

    def set_members(per_block: list, blocks: list[int]) -> np.ndarray:
        """Indices (into the concatenation of ``blocks``) of a named cell set's members in those blocks."""
        offset = np.cumsum([0, *(len(m.cells[b].data) for b in blocks)])
        parts = [np.asarray(per_block[b], dtype=np.int64).reshape(-1) + offset[i] for i, b in enumerate(blocks)
                 if b < len(per_block) and per_block[b] is not None]
        return np.concatenate(parts) if parts else np.empty(0, dtype=np.int64)

    all_blocks = list(range(len(m.cells)))
    # a named set without any member is kept as an empty region and an empty boundary (its dimension
    # is unknown), so that a lookup reports "empty", not "missing"
    empty_sets = [name for name, per_block in cell_sets.items() if set_members(per_block, all_blocks).size == 0]
    next_tag = int(max([0, *np.unique(cell_tags).tolist(), *region_names.values()])) + 1
    extra_cells, extra_tags, extra_nodes = [], [], []
    for set_name, per_block in cell_sets.items():
        members = set_members(per_block, tet_blocks)
        if set_name in empty_sets and set_name not in region_names:
            region_names[set_name] = next_tag
            next_tag += 1
        if members.size == 0 or set_name in region_names:
            continue
        extra_cells.append(cells[members])
        extra_nodes.append(nodes[members] if nodes is not None else None)
        extra_tags.append(np.full(len(members), next_tag, dtype=np.int32))
        region_names[set_name] = next_tag
        next_tag += 1
    for tag_name, tag in regions.items():
        if not np.any(cell_tags == tag):
            raise ValueError(f"mesh.regions.{tag_name}: no tetrahedron has tag {tag}")
    if tri_blocks:
        facets = np.concatenate([m.cells[b].data[:, :3] for b in tri_blocks]).astype(np.int64)
        ftags = block_data(tri_blocks, facet_data, "facet_data")
        facet_tags = np.zeros(len(facets), dtype=np.int32) if ftags is None else ftags.astype(np.int32)
    else:
        facets, facet_tags = np.empty((0, 3), dtype=np.int64), np.empty(0, dtype=np.int32)
    for tag_name, tag in boundaries.items():
        if not np.any(facet_tags == tag):
            raise ValueError(f"mesh.boundaries.{tag_name}: no triangle has tag {tag}")
    boundary_names = dict(boundaries)
    point_sets = getattr(m, "point_sets", None) or {}
    next_tag = int(max([0, *np.unique(facet_tags).tolist(), *boundary_names.values()])) + 1
    nf, nt = [facets], [facet_tags]
    if tri_blocks:
        # named sets of triangles (Abaqus ELSET of S3 elements) are boundaries
        tri_all = np.concatenate([m.cells[b].data[:, :3] for b in tri_blocks]).astype(np.int64)
        for set_name, per_block in cell_sets.items():
            members = set_members(per_block, tri_blocks)
            if members.size == 0 or set_name in boundary_names:
                continue
            boundary_names[set_name] = next_tag
            nf.append(tri_all[members])
            nt.append(np.full(len(members), next_tag, dtype=np.int32))
            next_tag += 1
    for set_name in empty_sets:
        if set_name not in boundary_names:
            boundary_names[set_name] = next_tag
            next_tag += 1
    if point_sets:
        exterior = exterior_triangles(cells)
        for set_name, ids in point_sets.items():
            if set_name in boundary_names:
                continue
            inside = np.zeros(len(m.points), dtype=bool)
            inside[np.asarray(ids, dtype=np.int64)] = True
            tris = exterior[inside[exterior].all(axis=1)]
            boundary_names[set_name] = next_tag  # no boundary triangle: an empty boundary
            nf.append(tris)
            nt.append(np.full(len(tris), next_tag, dtype=np.int32))
            next_tag += 1
    facets, facet_tags = np.concatenate(nf), np.concatenate(nt)
    if extra_cells:
        # cells in named sets are duplicated with the set's tag; _combine merges them into codes
        cells = np.concatenate([cells, *extra_cells])
        cell_tags = np.concatenate([cell_tags, *extra_tags])
        nodes = None if nodes is None else np.concatenate([nodes, *extra_nodes])
    return MeshData(points=np.asarray(m.points, dtype=np.float64)[:, :3] if m.points.shape[1] >= 3 else
                    np.pad(m.points, ((0, 0), (0, 3 - m.points.shape[1]))),
                    cells=cells, cell_tags=cell_tags, facets=facets, facet_tags=facet_tags,
                    region_names=region_names, boundary_names=boundary_names, nodes=nodes)


def _fix_abaqus_element_sets(path: Path, m) -> None:  # noqa: ANN001 - a meshio.Mesh
    """Put the ELSET=name of each ``*ELEMENT`` line on its own block.

    meshio 5 gives the i-th ``*ELEMENT, ..., ELSET=`` it meets to block i, which is
    wrong when an earlier ``*ELEMENT`` block has no ELSET (e.g. tetrahedra without a
    set followed by ``*ELEMENT, TYPE=S3, ELSET=load``). Only done when each block
    is one ``*ELEMENT`` line (no ``*INCLUDE``) and the set has no ``*ELSET`` of its own.
    """
    headers, explicit = [], set()
    for line in path.read_text(errors="replace").splitlines():
        keyword, _, params = line.partition(",")
        keyword = keyword.strip().replace("*", "").upper()
        if line.startswith("**") or not line.startswith("*"):
            continue
        if keyword == "INCLUDE":
            return
        found = re.search(r"\bELSET\s*=\s*([^,\s]+)", params, flags=re.IGNORECASE)
        if keyword == "ELEMENT":
            headers.append(found.group(1) if found else None)
        elif keyword == "ELSET" and found:
            explicit.add(found.group(1))
    if len(headers) != len(m.cells):
        return
    for block, name in enumerate(headers):
        if name is None or name in explicit:
            continue
        m.cell_sets[name] = [np.arange(len(c.data), dtype=np.int32) if i == block else np.empty(0, dtype=np.int32)
                             for i, c in enumerate(m.cells)]


def _meshio_read(path: Path):  # noqa: ANN202 - a meshio.Mesh
    """meshio.read, but a file it cannot parse raises ValueError (meshio prints and calls sys.exit)."""
    import contextlib
    import io

    import meshio

    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
            return meshio.read(path)
    except SystemExit:
        raise ValueError(" ".join(printed.getvalue().split()) or f"meshio cannot read {path}") from None


def exterior_triangles(cells: np.ndarray) -> np.ndarray:
    """The triangles of a tetrahedral mesh that belong to exactly one tetrahedron."""
    faces = np.concatenate([cells[:, [1, 2, 3]], cells[:, [0, 2, 3]], cells[:, [0, 1, 3]], cells[:, [0, 1, 2]]])
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.reshape(-1)] == 1]
