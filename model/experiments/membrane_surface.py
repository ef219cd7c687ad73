"""The surface of a membrane run (model.experiments.membrane_run): a built-in generator's (meshes.membrane) or the
user's file (meshes.surface_file) read and checked on rank 0 (borders, regions, contacts' names; with [extrusion]
or [muscle] one patch with one rim, disc topology, whose whole open boundary, and nothing else, is clamped: a
ConfigError naming the key and the file before the output folder is made), the rest normals and the starting
bump."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np
from mpi4py import MPI

from meshes.membrane import (
    SurfaceMeshData,
    closed_can,
    disc_surface,
    facing_discs,
    sphere_octant,
    vertex_normals,
)
from meshes.surface_file import oriented_cells, patch_topology, read_surface
from model.config.membrane import MembraneRunConfig
from model.errors import ConfigError
from model.experiments.membrane import set_nodal_displacement
from model.problem.membrane import (
    MembraneProblem,
    axis_orientation,
    radial_orientation,
)

log = logging.getLogger(__name__)

__all__ = []


def _surface(config: MembraneRunConfig) -> SurfaceMeshData:
    m = config.membrane
    if m.surface == "facing_discs":
        return facing_discs(m.radius, m.gap, m.size, m.upper_size)
    if m.surface == "closed_can":
        return closed_can(m.radius, m.gap, m.size)
    return sphere_octant(m.radius, m.size) if m.surface == "sphere_octant" else disc_surface(m.radius, m.size)


@dataclass(frozen=True)
class _FileSurface:
    """surface = "file": the checked surface with its oriented triangles (rank 0, else None), the starting bump's
    centre c and radius R (every rank; of the whole surface) and, for a file of several named regions, each
    region's (rank 0, else None): (region, c, R)."""

    data: SurfaceMeshData | None
    centre: tuple[float, float, float]
    radius: float
    bumps: tuple[tuple[str, np.ndarray, float], ...] | None = None


def _bump_centre(config: MembraneRunConfig, nodes: np.ndarray, where: str) -> tuple[np.ndarray, float]:
    """The bump's c (``centre`` or the middle of ``nodes``' bounding box) and R (``radius`` or the largest distance
    of a node from c); ConfigError when R = 0."""
    m = config.membrane
    centre = (np.asarray(m.centre, dtype=np.float64) if m.centre is not None
              else 0.5 * (nodes.min(axis=0) + nodes.max(axis=0)))
    radius = float(m.radius) if "radius" in m.model_fields_set else \
        float(np.sqrt(np.max(np.sum((nodes - centre) ** 2, axis=1))))
    if not radius > 0.0:
        raise ConfigError(f"membrane.radius: the fixed nodes of {where} are all at the centre: give radius")
    return centre, radius


def _check_contacts(config: MembraneRunConfig, data: SurfaceMeshData) -> None:
    """[[contact]] on a file: both regions named in it (a .msh file's physical surfaces), sharing no node (a node of
    both would be its own contact partner); ConfigError naming the key and the file."""
    m = config.membrane
    for i, contact in enumerate(config.contacts):
        for k in ("surface", "master"):
            name = getattr(contact, k)
            if contact.self_contact and k == "surface" and name == "all":
                continue  # the whole membrane, spelled out
            if name is not None and name not in data.region_names:
                hint = "" if len(data.region_names) > 1 else \
                    "; name the sheets as physical surfaces of a .msh file"
                raise ConfigError(f"contact[{i}].{k}: {m.file} has no region {name!r} (regions: "
                                  f"{', '.join(data.region_names)}{hint})")
        if contact.self_contact:
            continue
        slave, master = (np.unique(data.region_cells(getattr(contact, k))) for k in ("surface", "master"))
        shared = np.intersect1d(slave, master)
        if len(shared):
            raise ConfigError(f"contact[{i}]: {m.file}: regions {contact.surface!r} and {contact.master!r} share "
                              f"{len(shared)} nodes, e.g. the point {data.points[shared[0]].tolist()} (membrane-"
                              "membrane contact needs two separate sheets: a shared node would be its own partner)")


def _needs(config: MembraneRunConfig) -> str:
    """The phases that close the patch into a muscle and their verb, for the messages: "[muscle] needs",
    "[extrusion] and [muscle] need"."""
    names = [name for name, section in (("[extrusion]", config.extrusion), ("[muscle]", config.muscle))
             if section is not None]
    return f"{' and '.join(names)} {'needs' if len(names) == 1 else 'need'}"


def _check_patch(config: MembraneRunConfig, data: SurfaceMeshData) -> None:
    """[extrusion], [muscle]: one piece with one boundary loop, a disc (meshes.surface_file.patch_topology; the
    orientation is already consistent); ConfigError naming membrane.file."""
    m = config.membrane
    need = f"{_needs(config)} one patch with one rim"
    topology = patch_topology(data.cells)
    if topology.pieces > 1:
        raise ConfigError(f"membrane.file: {m.file} has {topology.pieces} separate pieces; {need}")
    if topology.loops == 0:
        raise ConfigError(f"membrane.file: {m.file} is a closed surface (no boundary loop); {need}")
    if topology.loops > 1:
        raise ConfigError(f"membrane.file: {m.file} has {topology.loops} boundary loops; {need}")
    if not topology.is_disc:
        raise ConfigError(f"membrane.file: {m.file} has one boundary loop but Euler characteristic V - E + F = "
                          f"{topology.euler} (a disc's is 1: the patch has handles); {need}")


def _check_rim(config: MembraneRunConfig, data: SurfaceMeshData) -> None:
    """[extrusion], [muscle]: the Dirichlet border is the patch's whole open boundary (the rim the base is closed
    on) and nothing inside it (a clamped node inside would be shared by the patch and the base: the closed surface
    pinched); ConfigError naming membrane.fixed."""
    m = config.membrane
    held = np.sort(np.concatenate([data.facets[data.facet_tags == data.boundary_names[name]] for name in m.border]),
                   axis=1)
    directed = np.concatenate([data.cells[:, [0, 1]], data.cells[:, [1, 2]], data.cells[:, [2, 0]]])
    edges, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    rim = edges[counts == 1]
    n = len(data.points)
    free = ~np.isin(rim[:, 0] * n + rim[:, 1], held[:, 0] * n + held[:, 1])
    inside = ~np.isin(held[:, 0] * n + held[:, 1], rim[:, 0] * n + rim[:, 1])
    for mask, edge, what in ((free, rim, f"of the rim's {len(rim)} edges are not held"),
                             (inside, held, "held edges are inside the patch, not on its rim")):
        if np.any(mask):
            a, b = edge[np.flatnonzero(mask)[0]]
            raise ConfigError(f"membrane.fixed: {m.file}: {int(np.count_nonzero(mask))} {what}, e.g. the edge of "
                              f"points {data.points[a].tolist()} and {data.points[b].tolist()}; {_needs(config)} "
                              "the whole rim clamped and nothing else (the base is closed on it)")


def _read_file_surface(config: MembraneRunConfig) -> tuple[SurfaceMeshData, tuple[float, float, float], float,
                                                            tuple[tuple[str, np.ndarray, float], ...] | None]:
    """Rank 0: read and check the file (meshes.surface_file), orient its triangles, check the Dirichlet border's
    and the contacts' names, and find the bump's c and R (of the whole surface and, for several regions, of each);
    ConfigError naming the key and the file."""
    m = config.membrane
    try:
        data = read_surface(m.file)
    except ValueError as err:
        raise ConfigError(f"membrane.file: {m.file}: {err}") from None
    orientation = m.orientation if m.orientation is not None else "file"
    try:
        cells = oriented_cells(data.points, data.cells, orientation if isinstance(orientation, str)
                               else np.asarray(orientation, dtype=np.float64))
    except ValueError as err:
        key = "membrane.file" if orientation == "file" else "membrane.orientation"
        hint = " (turn them in the file or give membrane.orientation)" if orientation == "file" else ""
        raise ConfigError(f"{key}: {m.file}: {err}{hint}") from None
    data = SurfaceMeshData(data.points, cells, data.cell_tags, data.facets, data.facet_tags, data.region_names,
                           data.boundary_names)
    patch = config.muscle is not None or config.extrusion is not None
    if patch:
        _check_patch(config, data)
    fixed = []
    for name in m.border:
        key = f"membrane.fixed.{name}" if m.fixed is not None else "membrane.fixed"
        if name not in data.boundary_names:
            raise ConfigError(f"{key}: {m.file} has no boundary {name!r} (boundaries: "
                              f"{', '.join(data.boundary_names)})")
        edges = data.facets[data.facet_tags == data.boundary_names[name]]
        if not len(edges):
            raise ConfigError(f"{key}: {m.file} has no edges on {name!r} (a closed surface has no open boundary: "
                              "give the Dirichlet border)")
        fixed.append(edges.reshape(-1))
    if patch:
        _check_rim(config, data)
    _check_contacts(config, data)
    fixed_nodes = np.unique(np.concatenate(fixed)) if fixed else np.arange(len(data.points))
    centre, radius = _bump_centre(config, data.points[fixed_nodes], str(m.file))
    bumps = None
    if len(data.region_names) > 1:  # each sheet its own paraboloid (c, R from its fixed nodes, or all its nodes)
        bumps = []
        for region in data.region_names:
            nodes = np.unique(data.region_cells(region))
            held = np.intersect1d(nodes, fixed_nodes)
            c, r = _bump_centre(config, data.points[held if len(held) else nodes], f"region {region!r} of {m.file}")
            bumps.append((region, c, r))
        bumps = tuple(bumps)
    return data, tuple(float(c) for c in centre), radius, bumps


def _file_surface(config: MembraneRunConfig, comm: MPI.Comm) -> _FileSurface:
    """surface = "file" (_read_file_surface on rank 0); a ConfigError there is raised on every rank. Collective."""
    data, found, bumps, error = None, None, None, None
    if comm.rank == 0:
        try:
            data, *rest, bumps = _read_file_surface(config)
            found = tuple(rest)
        except ConfigError as err:
            error = str(err)
    found, error = comm.bcast((found, error))
    if error is not None:
        raise ConfigError(error)
    return _FileSurface(data, *found, bumps)


def _file_bump(config: MembraneRunConfig, surface: _FileSurface, problem: MembraneProblem, comm: MPI.Comm) -> None:
    """surface = "file": u = bump R max(0, 1 - |X - c|^2 / R^2) N_vertex, N_vertex the oriented vertex normals
    (meshes.membrane.vertex_normals); a file of several regions: on each region's nodes with its c and R.
    Collective."""
    values = None
    if comm.rank == 0:
        data = surface.data
        normals = vertex_normals(data.points, data.cells)
        bumps = surface.bumps or (("", np.asarray(surface.centre), surface.radius),)
        values = np.zeros_like(data.points)
        for region, c, r in bumps:
            nodes = np.unique(data.region_cells(region)) if region else np.arange(len(data.points))
            phi = np.maximum(1 - np.sum((data.points[nodes] - c) ** 2, axis=1) / r**2, 0.0)
            values[nodes] = config.membrane.bump * r * phi[:, None] * normals[nodes]
    set_nodal_displacement(problem, comm.bcast(values))


def _orientation(config: MembraneRunConfig) -> Any:
    """The rest normals: outward (octant), +z (disc), towards the other disc (facing_discs)."""
    m = config.membrane
    if m.surface == "sphere_octant":
        return radial_orientation()
    if m.surface == "disc":
        return axis_orientation()
    return lambda c: _facing_side(c[:, 2:3], m.gap) * np.array([0.0, 0.0, 1.0])


def _facing_side(z: np.ndarray, gap: float) -> np.ndarray:
    """facing_discs: +1 on the lower disc (z < gap/2), -1 on the upper: the direction towards the other one."""
    return np.where(z < gap / 2, 1.0, -1.0)
