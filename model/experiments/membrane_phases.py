"""The phases of a membrane run around its inflation (model.experiments.membrane_run): [extrusion] before it (the
patch extruded, inflated without contact to a first volume and smoothed into a new rest shape) and [muscle] after
it (the final surface closed with the patch at rest as its base, tetrahedralised, given Laplace fibres and written
with a solid run's configuration, muscle.toml).

The patch is the built-in disc or a user's file (surface = "file", generally not planar: one piece with one rim,
disc topology, its whole open boundary clamped; checked when the file is read, model.experiments.membrane_surface).
``_patch`` finds, before any solve, what both phases need: the clamped rim's nodes, the base volume V_b (the cone
volume of the patch at rest about the origin, model.problem.membrane.MembraneProblem's base_volume: every volume of
the run is then the volume between the surface and the rest patch; 0 for the disc in z = 0) and the fibre axis
(model.experiments.membrane.PatchAxis: the disc's x axis, or muscle.axis, or the file's principal axis)."""

from __future__ import annotations

import gc
import json
import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from forms.membrane import MembraneLaw
from meshes.data import MeshData, read_msh, write_msh
from meshes.membrane import (
    SurfaceMeshData,
    enclosed_volume,
    extrude,
    smooth_rest_shape,
)
from model.config.membrane import MUSCLE_FILES, MembraneRunConfig
from model.domain.distribute import build_domain
from model.errors import ConfigError, SolveFailed
from model.experiments.membrane import PatchAxis, cell_values, close_and_mesh, deformed_points, patch_axis
from model.problem.membrane import (
    MembraneProblem,
    triangle_orientation,
)
from model.solvers.membrane import inflate_to_volume

log = logging.getLogger(__name__)

__all__ = ['muscle_document']


@dataclass(frozen=True)
class _Patch:
    """What [extrusion] and [muscle] need of the patch (module docstring): the clamped rim's nodes (rank 0, else
    None), the base volume V_b and, with [muscle], the fibre axis (every rank)."""

    rim: np.ndarray | None
    base_volume: float
    axis: PatchAxis | None


def _patch(config: MembraneRunConfig, flat: SurfaceMeshData | None, comm: MPI.Comm) -> _Patch:
    """The patch's rim, V_b and axis (rank 0's, broadcast); ConfigError before any solve when the axis is not
    defined (a round file patch without muscle.axis) or an end of the muscle has no base triangle. Collective."""
    rim, found, error = None, None, None
    if comm.rank == 0:
        edges = [flat.facets[flat.facet_tags == flat.boundary_names[name]] for name in config.membrane.border]
        rim = np.unique(np.concatenate(edges))
        base = enclosed_volume(flat.points, flat.cells) + 0.0  # the disc in z = 0: 0 (+ 0.0: not -0.0)
        try:
            found = (base, _axis(config, flat) if config.muscle is not None else None)
        except ConfigError as err:
            error = str(err)
    found, error = comm.bcast((found, error))
    if error is not None:
        raise ConfigError(error)
    return _Patch(rim, *found)


def _axis(config: MembraneRunConfig, flat: SurfaceMeshData) -> PatchAxis:
    """Rank 0: the fibre axis (disc: e = muscle.axis or x, c = 0, a = radius; file: patch_axis), checked: each end
    has a base triangle."""
    m, muscle = config.membrane, config.muscle
    if m.surface == "disc":
        e = np.asarray(muscle.axis if muscle.axis is not None else (1.0, 0.0, 0.0), dtype=np.float64)
        axis = PatchAxis(tuple(float(c) for c in e / np.linalg.norm(e)), 0.0, float(m.radius))
    else:
        try:
            axis = patch_axis(flat.points, flat.cells, muscle.axis)
        except ValueError as err:
            raise ConfigError(f"muscle.axis: {m.file}: {err}: give axis") from None
    counts = [int(np.count_nonzero(mask)) for mask in axis.ends(flat.points, flat.cells, muscle.end)]
    if min(counts) == 0:
        if m.surface == "disc":
            along = "x" if muscle.axis is None else "s"
            raise ConfigError(f"muscle.end: no base triangle has its centroid beyond {along} = +-{muscle.end:g} "
                              f"radius (membrane.size {m.size:g}, radius {m.radius:g}): lower end or size")
        raise ConfigError(f"muscle.end: {m.file}: no base triangle has its centroid beyond s = +-{muscle.end:g} a "
                          f"along the axis {list(axis.direction)} (a = {axis.half_length:.6g}): lower end or "
                          "refine the patch")
    return axis


def _extrusion(config: MembraneRunConfig, law: MembraneLaw, flat: SurfaceMeshData | None, patch: _Patch,
               scale: float, num_points: int, comm: MPI.Comm) -> tuple[SurfaceMeshData | None, dict[str, Any]]:
    """[extrusion]: the patch ``flat`` extruded by ``offset`` along its oriented vertex normals (the clamped rim
    stays), inflated without contact to ``first_volume`` (inflate_to_volume, [inflation]'s dp, default with the
    length ``scale``, and cutbacks), its free nodes smoothed and relaxed down to ``rest_volume``
    (meshes.membrane.smooth_rest_shape), the volumes measured from the rest patch (V - V_b): the new rest shape
    (rank 0, else None) and summary.json's "extrusion". SolveFailed when the first phase's Newton fails.
    Collective."""
    e, m, inflation = config.extrusion, config.membrane, config.inflation
    rim, base = patch.rim, patch.base_volume
    extruded = extrude(flat, e.offset, rim) if comm.rank == 0 else None
    # the rest normals: the extruded triangles' own (oriented as the patch's: the disc's +z, the same field)
    orientation = triangle_orientation(*comm.bcast((extruded.points, extruded.cells) if comm.rank == 0 else None))
    first = MembraneProblem(build_domain(comm, extruded), law, orientation, m.border,
                            quadrature_degree=m.quadrature_degree, base_volume=base)
    dp = inflation.dp if inflation.dp is not None else 0.05 * law.equibiaxial(1.1)[1] / scale
    try:
        steps = inflate_to_volume(first, e.first_volume, dp, max_steps=inflation.max_steps,
                                  cutbacks=inflation.cutbacks)
    except RuntimeError as err:
        raise SolveFailed(f"extrusion: the first inflation failed: {err}") from None
    inflated = deformed_points(first, num_points)
    rest, record, error = None, None, None
    if comm.rank == 0:  # a failure here is every rank's (broadcast): no rank waits for the others forever
        try:
            smoothing = smooth_rest_shape(inflated, flat.cells, rim, e.rest_volume + base)  # volumes V, not V - V_b
        except ValueError as err:
            error = f"extrusion.rest_volume: {e.rest_volume!r}: the smoothing cannot reach it ({err}; volumes there " \
                    f"measured from the origin; V_b = {base:.6g})"
        else:
            rest = SurfaceMeshData(smoothing.points, flat.cells, flat.cell_tags, flat.facets, flat.facet_tags,
                                   flat.region_names, flat.boundary_names)
            record = {"offset": e.offset, "first_volume": e.first_volume, "rest_volume": e.rest_volume,
                      "first_steps": [{"pressure": s.pressure, "volume": s.volume, "energy": s.energy,
                                       "iterations": s.iterations} for s in steps],
                      "smoothing_iterations": smoothing.iterations,
                      "smoothed_volume": float(smoothing.volumes[-1]) - base}
    record, error = comm.bcast((record, error))
    if error is not None:
        raise SolveFailed(error)
    log.info("extrusion: V = %.6g at p = %.6g after %d steps; smoothed to V = %.6g in %d iterations",
             steps[-1].volume, steps[-1].pressure, len(steps), record["smoothed_volume"],
             record["smoothing_iterations"])
    return rest, record


def muscle_document(config: MembraneRunConfig, out: Path) -> str:
    """muscle.toml's text: a solid run (model.config.RunConfig) of the closed patch's tetrahedra (muscle.msh)
    with the Laplace fibres of fibres.npy, the activation ramped from 0 to ``activation`` in ``steps`` load steps
    and the ``fixed`` boundaries clamped; its results go to OUT/contraction, an absolute path, so that the file
    runs from any working directory (the command line's --out wins)."""
    m = config.muscle
    lines = [
        "# The muscle of a membrane run ([muscle], model.experiments.membrane_run; docs/membranes.md): the inflated",
        "# patch closed with the patch at rest as its base, filled with tetrahedra (muscle.msh: volume muscle;",
        "# surfaces patch, base, origin, insertion) and given the Laplace fibre field from origin to insertion",
        "# (fibres.npy).",
        f"#   python -m model run {(out / MUSCLE_FILES['config']).as_posix()}",
        "",
        "[units]",
        f"system = {json.dumps(config.units.system)}",
        "",
        "[mesh]",
        f"file = {json.dumps(MUSCLE_FILES['mesh'])}",
        "",
        "[discretization]",
        f"degree = {m.degree}",
        "",
        "[[material]]",
        'region = "muscle"',
        'law = "muscle"',
        'isotropic = "stvk"',
        f"E = {float(m.young)!r}",
        f"nu = {float(m.nu)!r}",
        f"sigma_max = {float(m.sigma_max)!r}",
        f'fibres = {{ type = "file", file = {json.dumps(MUSCLE_FILES["fibres"])} }}',
        f"activation = [[0.0, 0.0], [1.0, {float(m.activation)!r}]]",
    ]
    for name in m.fixed:
        lines += ["", "[[boundary]]", f"on = {json.dumps(name)}", 'type = "displacement"', "value = [0.0, 0.0, 0.0]"]
    lines += ["", "[loading]", f"steps = {m.steps}", "", "[output]",
              f"dir = {json.dumps((out / 'contraction').resolve().as_posix())}", ""]
    return "\n".join(lines)


@contextmanager
def _collected() -> Iterator[None]:
    """Collect the garbage on every rank now and not inside: the block has rank-0-only work (gmsh, meshio, the
    configuration reader) while the other ranks wait in a collective, and a PETSc object left to the garbage
    collector (a Newton with MUMPS: its destroy is collective) destroyed there on rank 0 alone would hang."""
    gc.collect()
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _muscle(config: MembraneRunConfig, problem: MembraneProblem, data: SurfaceMeshData | None, patch: _Patch,
            num_points: int, out: Path, comm: MPI.Comm) -> dict[str, Any]:
    """[muscle]: close the final surface with the rest patch ``data``, tetrahedralise, Laplace fibres, write the
    files (module docstring). Collective; returns summary.json's "muscle"."""
    with _collected():
        return _close_and_write(config, problem, data, patch, num_points, out, comm)


def _close_and_write(config: MembraneRunConfig, problem: MembraneProblem, data: SurfaceMeshData | None,
                     patch: _Patch, num_points: int, out: Path, comm: MPI.Comm) -> dict[str, Any]:
    m, muscle = config.membrane, config.muscle
    tet_size = muscle.tet_size if muscle.tet_size is not None else m.size
    deformed = deformed_points(problem, num_points)
    _, fibres, mesh_data = close_and_mesh(data, deformed, patch.axis, muscle.end, tet_size, comm, rim=patch.rim)
    a0 = cell_values(fibres)
    enclosed = problem.volume()
    record, error = None, None
    if comm.rank == 0:
        try:
            record = _write_muscle(config, data, patch, mesh_data, a0, enclosed, tet_size, out)
        except (OSError, RuntimeError, ValueError) as err:  # ConfigError is a ValueError: muscle.toml refused
            error = f"muscle: {err}"
    record, error = comm.bcast((record, error))
    if error:
        raise RuntimeError(error)
    return record


def _flat_end_tetrahedra(mesh: MeshData) -> int:
    """The tetrahedra with all four vertices on one end (phi constant: model.experiments.membrane.laplace_fibres)."""
    count = 0
    for name in ("origin", "insertion"):
        on_end = np.zeros(mesh.num_points, dtype=bool)
        on_end[np.unique(mesh.boundary_facets(name))] = True
        count += int(np.count_nonzero(on_end[mesh.cells].all(axis=1)))
    return count


def _write_muscle(config: MembraneRunConfig, data: SurfaceMeshData, patch: _Patch, mesh_data: MeshData,
                  a0: np.ndarray, enclosed: float, tet_size: float, out: Path) -> dict[str, Any]:
    """Rank 0: muscle.msh, fibres.npy, muscle.vtu, muscle.toml (read back by the solid run's reader)."""
    import meshio

    from model.config.document import load

    muscle = config.muscle
    write_msh(mesh_data, out / MUSCLE_FILES["mesh"])
    if not np.array_equal(read_msh(out / MUSCLE_FILES["mesh"]).cells, mesh_data.cells):
        raise RuntimeError("muscle.msh: the cells read back in another order than fibres.npy's")
    np.save(out / MUSCLE_FILES["fibres"], a0)
    meshio.Mesh(mesh_data.points, [("tetra", mesh_data.cells)],
                cell_data={"fibre_direction": [a0]}).write(out / MUSCLE_FILES["vtu"])
    (out / MUSCLE_FILES["config"]).write_text(muscle_document(config, out))
    load(out / MUSCLE_FILES["config"])  # the solid run's reader takes it (a ConfigError would be a bug here)
    origin, insertion = (int(np.count_nonzero(mask)) for mask in patch.axis.ends(data.points, data.cells, muscle.end))
    record = {**MUSCLE_FILES, "tetrahedra": mesh_data.num_cells, "points": mesh_data.num_points,
              "tet_size": tet_size, "end": muscle.end, "volume": mesh_data.volume(), "enclosed_volume": enclosed,
              "base_volume": patch.base_volume, "axis": list(patch.axis.direction), "axis_centre": patch.axis.centre,
              "half_length": patch.axis.half_length, "origin_triangles": origin, "insertion_triangles": insertion,
              "flat_end_tetrahedra": _flat_end_tetrahedra(mesh_data),
              "boundaries": sorted(mesh_data.boundary_names), "fixed": list(muscle.fixed)}
    log.info("muscle: %d tetrahedra, volume %.9g (membrane %.9g); %s", mesh_data.num_cells, record["volume"],
             enclosed, out / MUSCLE_FILES["config"])
    return record
