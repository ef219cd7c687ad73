"""The :class:`MeshData` container and conversion from/to gmsh models and ``.msh`` files."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gmsh
import numpy as np

from meshes._gmsh import gmsh_session
from meshes.topology import signed_volumes

__all__ = ["MeshData", "from_gmsh_model", "read_msh", "write_msh"]

logger = logging.getLogger(__name__)


def _as_array(name: str, value: Any, dtype: type, ncols: int | None) -> np.ndarray:
    """Return ``value`` as a C-contiguous array of ``dtype`` with ``ncols`` columns (1-D if None)."""
    array = np.ascontiguousarray(value, dtype=dtype)
    if ncols is None:
        array = array.reshape(-1) if array.size == 0 else array
        if array.ndim != 1:
            raise ValueError(f"MeshData: {name} must be 1-D, got shape {array.shape}")
    else:
        array = array.reshape(-1, ncols) if array.size == 0 else array
        if array.ndim != 2 or array.shape[1] != ncols:
            raise ValueError(f"MeshData: {name} must have shape (n, {ncols}), got {array.shape}")
    return array


def _check_names(name: str, names: dict[str, int]) -> dict[str, int]:
    """Copy a name -> tag mapping with ``str`` keys and ``int`` tags (several names may share a tag)."""
    try:
        return {str(key): int(tag) for key, tag in names.items()}
    except (AttributeError, TypeError, ValueError) as err:
        raise ValueError(f"MeshData: {name} must map names to integer tags, got {names!r}") from err


@dataclass(frozen=True, eq=False)
class MeshData:
    """A tetrahedral mesh with named physical groups, held on one rank: linear, or quadratic (``nodes``).

    Attributes
    ----------
    points:
        ``(n, 3)`` float64 vertex coordinates.
    cells:
        ``(m, 4)`` int64 vertex indices into ``points`` (linear tetrahedra).
    cell_tags:
        ``(m,)`` int32 physical-volume tag of each cell (0 = untagged).
    facets:
        ``(k, 3)`` int64 triangles on named boundary surfaces.
    facet_tags:
        ``(k,)`` int32; a triangle in two named groups appears twice, once per tag.
    region_names:
        Physical volume name -> tag.
    boundary_names:
        Physical surface name -> tag.  A group without elements keeps its name (an empty group).
    nodes:
        None (linear cells), or ``(m, 10)`` int64 indices into ``points`` of quadratic tetrahedra in
        gmsh's node order: the 4 vertices (``cells``), then the nodes on the edges 01, 12, 20, 30,
        32, 31. Everything else (volumes, facets, ``cells``) is the straight-sided vertex mesh.
    """

    points: np.ndarray
    cells: np.ndarray
    cell_tags: np.ndarray
    facets: np.ndarray
    facet_tags: np.ndarray
    region_names: dict[str, int] = field(default_factory=dict)
    boundary_names: dict[str, int] = field(default_factory=dict)
    nodes: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Coerce arrays to their documented dtypes/shapes and check consistency."""
        coerced = {
            "points": _as_array("points", self.points, np.float64, 3),
            "cells": _as_array("cells", self.cells, np.int64, 4),
            "cell_tags": _as_array("cell_tags", self.cell_tags, np.int32, None),
            "facets": _as_array("facets", self.facets, np.int64, 3),
            "facet_tags": _as_array("facet_tags", self.facet_tags, np.int32, None),
            "region_names": _check_names("region_names", self.region_names),
            "boundary_names": _check_names("boundary_names", self.boundary_names),
        }
        if self.nodes is not None:
            coerced["nodes"] = _as_array("nodes", self.nodes, np.int64, 10)
            if len(coerced["nodes"]) != len(coerced["cells"]) or np.any(coerced["nodes"][:, :4] != coerced["cells"]):
                raise ValueError("MeshData: the first 4 nodes of each quadratic cell must be its cells' vertices")
        for key, value in coerced.items():
            object.__setattr__(self, key, value)
        npts = len(self.points)
        if len(self.cell_tags) != len(self.cells):
            raise ValueError(f"MeshData: {len(self.cells)} cells but {len(self.cell_tags)} cell tags")
        if len(self.facet_tags) != len(self.facets):
            raise ValueError(f"MeshData: {len(self.facets)} facets but {len(self.facet_tags)} facet tags")
        for name in ("cells", "facets", "nodes"):
            array = getattr(self, name)
            if array is None:
                continue
            if array.size and (array.min() < 0 or array.max() >= npts):
                raise ValueError(f"MeshData: {name} reference vertices outside [0, {npts})")
        if not np.all(np.isfinite(self.points)):
            raise ValueError("MeshData: points contain non-finite coordinates")

    @property
    def num_points(self) -> int:
        """Number of vertices."""
        return int(self.points.shape[0])

    @property
    def num_cells(self) -> int:
        """Number of tetrahedra."""
        return int(self.cells.shape[0])

    def region_cells(self, name: str) -> np.ndarray:
        """Tetrahedra of the physical volume ``name`` (``KeyError`` if unknown)."""
        return self.cells[self.cell_tags == self.region_names[name]]

    def boundary_facets(self, name: str) -> np.ndarray:
        """Triangles of the physical surface ``name`` (``KeyError`` if unknown)."""
        return self.facets[self.facet_tags == self.boundary_names[name]]

    def volume(self, region: str | None = None) -> float:
        """Total volume (sum of ``|det| / 6``) of all cells or of the physical volume ``region``."""
        cells = self.cells if region is None else self.region_cells(region)
        return float(np.abs(signed_volumes(self.points, cells)).sum())


def _primary_connectivity(model: Any, etype: int, node_tags: Any, nvertices: int, dim: int) -> np.ndarray:
    """Vertex node tags (first ``nvertices`` nodes) of elements of gmsh type ``etype``."""
    name, _, _, nnodes, _, nprimary = model.mesh.getElementProperties(int(etype))
    if nprimary != nvertices:
        kind = "tetrahedra" if dim == 3 else "triangles"
        raise ValueError(f"unsupported {dim}D gmsh element type {etype} ({name}): only {kind} are supported")
    return np.asarray(node_tags, dtype=np.int64).reshape(-1, nnodes)[:, :nvertices]


def _entity_connectivity(model: Any, dim: int, entity: int, nvertices: int, keep: int | None = None
                         ) -> np.ndarray:
    """Vertex node tags of all elements of one gmsh entity, shape ``(e, nvertices)``; with ``keep``, all
    ``keep`` nodes of each element, shape ``(e, keep)`` (ValueError if an element has another count)."""
    types, _, node_tags = model.mesh.getElements(dim, entity)
    blocks = []
    for t, n in zip(types, node_tags, strict=True):
        if keep is None:
            blocks.append(_primary_connectivity(model, t, n, nvertices, dim))
        else:
            nnodes = model.mesh.getElementProperties(int(t))[3]
            if nnodes != keep:
                raise ValueError(f"gmsh element type {t} has {nnodes} nodes, not {keep}")
            blocks.append(np.asarray(n, dtype=np.int64).reshape(-1, keep))
    if not blocks:
        return np.empty((0, keep or nvertices), dtype=np.int64)
    return np.concatenate(blocks)


def _tetrahedron_nodes(model: Any) -> set[int]:
    """The node counts of the tetrahedra in the model (4, 10, 20, ...)."""
    counts = set()
    for _, entity in model.getEntities(3):
        for t in model.mesh.getElements(3, entity)[0]:
            name, _, _, nnodes, _, nprimary = model.mesh.getElementProperties(int(t))
            if nprimary == 4:
                counts.add(int(nnodes))
    return counts


def _physical_names(model: Any, dim: int) -> dict[str, int]:
    """Physical group name -> tag for dimension ``dim``; unnamed groups are called ``str(tag)``."""
    names: dict[str, int] = {}
    for _, tag in model.getPhysicalGroups(dim):
        name = model.getPhysicalName(dim, tag) or str(tag)
        if name in names:
            raise ValueError(f"physical name {name!r} is used by {dim}D groups {names[name]} and {tag}")
        names[name] = int(tag)
    return names


def _volume_elements(model: Any, keep: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedra (gmsh node tags: the vertices, or all ``keep`` nodes) of every 3D entity and the
    physical tag of each."""
    blocks: list[np.ndarray] = []
    tags: list[np.ndarray] = []
    for _, entity in model.getEntities(3):
        conn = _entity_connectivity(model, 3, entity, 4, keep)
        groups = sorted(int(g) for g in model.getPhysicalGroupsForEntity(3, entity))
        if len(groups) > 1:
            logger.warning("volume %d is in physical groups %s; using tag %d", entity, groups, groups[0])
        blocks.append(conn)
        tags.append(np.full(len(conn), groups[0] if groups else 0, dtype=np.int32))
    if not blocks or sum(len(b) for b in blocks) == 0:
        raise ValueError("gmsh model contains no tetrahedra: generate a 3D mesh (or read a 3D .msh) first")
    return np.concatenate(blocks), np.concatenate(tags)


def _surface_elements(model: Any) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (gmsh node tags) of every 2D physical group, repeated once per group."""
    blocks: list[np.ndarray] = [np.empty((0, 3), dtype=np.int64)]
    tags: list[np.ndarray] = [np.empty(0, dtype=np.int32)]
    for _, group in model.getPhysicalGroups(2):
        for entity in model.getEntitiesForPhysicalGroup(2, group):
            conn = _entity_connectivity(model, 2, int(entity), 3)
            blocks.append(conn)
            tags.append(np.full(len(conn), group, dtype=np.int32))
    return np.concatenate(blocks), np.concatenate(tags)


def from_gmsh_model(model: Any = None) -> MeshData:
    """Extract the current mesh of a gmsh model as :class:`MeshData`.

    Parameters
    ----------
    model:
        The ``gmsh.model`` API object (default: ``gmsh.model``); the *current*
        model is read.

    All tetrahedra are kept, with the tag of their volume's physical group (0 if none).
    Second-order tetrahedra (10 nodes, every tetrahedron of the model) keep their edge nodes in
    ``MeshData.nodes`` (curved cells); other higher orders are reduced to their 4 vertices, with a
    warning.
    Triangles are taken from every 2D physical group.  Vertices are renumbered
    compactly, in increasing gmsh node tag order, to those used by tetrahedra.

    Raises
    ------
    ValueError
        If there are no tetrahedra, if other 3D/2D element types are present, if
        a named triangle uses a vertex of no tetrahedron, or if a physical name is
        used twice in one dimension.
    """
    model = gmsh.model if model is None else model
    node_tags, coords, _ = model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(node_tags, kind="stable")
    sorted_tags, sorted_coords = node_tags[order], coords[order]

    orders = _tetrahedron_nodes(model)
    quadratic = orders == {10}
    if orders - {4, 10} or orders == {4, 10}:
        logger.warning("tetrahedra with %s nodes: reduced to their 4 vertices (straight-sided); only meshes "
                       "made entirely of 10-node tetrahedra keep their curved geometry", sorted(orders))
    tets, cell_tags = _volume_elements(model, 10 if quadratic else None)
    tris, facet_tags = _surface_elements(model)

    used = np.unique(tets)
    position = np.searchsorted(sorted_tags, used)
    found = position < len(sorted_tags)
    if not found.all() or np.any(sorted_tags[position] != used):
        raise ValueError("gmsh model: some tetrahedra reference nodes that do not exist")
    if tris.size and not np.all(np.isin(tris, used)):
        raise ValueError("gmsh model: a triangle of a 2D physical group uses a node of no tetrahedron")

    return MeshData(
        points=sorted_coords[position],
        cells=np.searchsorted(used, tets[:, :4]),
        nodes=np.searchsorted(used, tets) if quadratic else None,
        cell_tags=cell_tags,
        facets=np.searchsorted(used, tris),
        facet_tags=facet_tags,
        region_names=_physical_names(model, 3),
        boundary_names=_physical_names(model, 2),
    )


def read_msh(path: str | Path) -> MeshData:
    """Read a gmsh ``.msh`` file into :class:`MeshData` (see :func:`from_gmsh_model`).

    gmsh is initialised (quietly) only if it is not already, and finalised only
    if it was initialised here.  The file is merged into a fresh temporary model
    so an existing gmsh session is left untouched.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"read_msh: no such file: {path}")
    with gmsh_session(name="read_msh"):
        gmsh.merge(str(path))
        mesh = from_gmsh_model(gmsh.model)
    logger.info("read %s: %d points, %d tetrahedra", path, mesh.num_points, mesh.num_cells)
    return mesh


def _add_elements(dim: int, entity: int, etype: int, conn: np.ndarray, first_tag: int) -> int:
    """Add elements (0-based vertex indices ``conn``) to a discrete entity; return the next free tag."""
    tags = np.arange(first_tag, first_tag + len(conn), dtype=np.int64)
    gmsh.model.mesh.addElementsByType(entity, etype, tags.tolist(), (conn + 1).ravel().tolist())
    return first_tag + len(conn)


def write_msh(mesh: MeshData, path: str | Path, binary: bool = True) -> None:
    """Write ``mesh`` to a gmsh ``.msh`` (format 4.1) file that :func:`read_msh` reads back.

    Each volume tag becomes one discrete 3D entity and each boundary tag one
    discrete 2D entity, carrying the physical groups and names of ``mesh``.
    Cells are written grouped by tag, so the cell order may change on reading.
    The default binary format keeps coordinates bit-exact; text files store 16
    significant digits.  Named groups without any element are not written; quadratic cells
    (``mesh.nodes``) are written as their 4 vertices.
    """
    path = Path(path)
    with gmsh_session(
        {"Mesh.MshFileVersion": 4.1, "Mesh.Binary": int(binary), "Mesh.SaveAll": 1}, name="write_msh"
    ):
        volume_names = {tag: name for name, tag in mesh.region_names.items()}
        surface_names = {tag: name for name, tag in mesh.boundary_names.items()}
        next_element = 1
        node_entity = 0
        for entity, tag in enumerate(np.unique(mesh.cell_tags).tolist(), start=1):
            gmsh.model.addDiscreteEntity(3, entity)
            if node_entity == 0:
                node_entity = entity
                gmsh.model.mesh.addNodes(
                    3, entity, list(range(1, mesh.num_points + 1)), mesh.points.ravel().tolist()
                )
            next_element = _add_elements(3, entity, 4, mesh.cells[mesh.cell_tags == tag], next_element)
            if tag != 0:
                gmsh.model.addPhysicalGroup(3, [entity], tag)
                gmsh.model.setPhysicalName(3, tag, volume_names.get(tag, str(tag)))
        for entity, tag in enumerate(np.unique(mesh.facet_tags).tolist(), start=1):
            gmsh.model.addDiscreteEntity(2, entity)
            next_element = _add_elements(2, entity, 2, mesh.facets[mesh.facet_tags == tag], next_element)
            gmsh.model.addPhysicalGroup(2, [entity], tag)
            gmsh.model.setPhysicalName(2, tag, surface_names.get(tag, str(tag)))
        gmsh.write(str(path))
    logger.info("wrote %s: %d points, %d tetrahedra", path, mesh.num_points, mesh.num_cells)
