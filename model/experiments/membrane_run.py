"""A membrane run from its configuration (model.config.membrane): ``python -m model run FILE`` with [membrane].

    summary = run_membrane(load_membrane("examples/membrane_balloon.toml"), Path("results/balloon"))

1. the surface from its generator (meshes.membrane.sphere_octant / disc_surface), distributed
   (model.domain.distribute.build_domain); normals outward (octant) or +z (disc); or (surface = "file") the user's
   triangle surface read and checked on rank 0 before the output folder is made (meshes.surface_file: borders
   "boundary" and a .msh file's named lines, the triangles turned by ``orientation`` and checked consistent; a
   .msh file's named physical surfaces are regions, each with the border "<region>_boundary", for [[contact]],
   whose region names and disjointness are checked there; a bad file, border or region name is a ConfigError
   naming the key and the file), its normals the turned triangles';
2. model.problem.membrane.MembraneProblem with the law (forms.membrane.membrane_law) and the Dirichlet border,
   one model.problem.membrane_contact.ObstacleContact per [[obstacle]];
3. the pressure path: model.solvers.membrane.inflate (a ramp or a list) or inflate_to_volume (growth by dp to a
   target volume or contact fraction); the disc starts from a small paraboloid (``bump``);
4. summary.json: per step the pressure, the enclosed volume V, the elastic energy, Newton's iterations, the
   contact fraction, the largest displacement along the normal axis (disc: the centre deflection) and, for the
   sphere octant, the stretch lambda = (V/V0)^(1/3) with the balloon's closed-form pressure
   p(lambda) = w'(lambda) / (R lambda^2) (model.problem.membrane.balloon_pressure); for an StVK disc Hencky's
   centre deflection w0 = c(nu) a (p a / (E h))^(1/3) (model.problem.membrane.hencky; small rotations); at the
   end each obstacle's report (penetration, force, contact fraction, active nodes);
5. the deformed surface per step of a ramp or list (the final state of a volume or fraction stop): an XDMF time
   series of u (surface.xdmf) and VTU files (surface_NNNN.vtu);
6. [muscle] (a clamped disc): the final surface closed with its flat rest shape as the base, filled with
   tetrahedra and given the Laplace fibre field (model.experiments.membrane.close_and_mesh, the thesis' ch.
   3.3.3), written as muscle.msh (gmsh, physical groups muscle; patch, base, origin, insertion), fibres.npy (a0
   per tetrahedron in the file's cell order), muscle.vtu (the tetrahedra with the cell data fibre_direction) and
   muscle.toml, a solid run of that muscle (``python -m model run OUT/muscle.toml``: law muscle with an StVK
   isotropic part, fibres = { type = "file" }, the activation ramped from 0, the ``fixed`` boundaries clamped),
   checked by the solid run's configuration reader before it is written; summary.json's "muscle" records the
   tetrahedra's volume next to the membrane's enclosed volume (the surface mesh is kept: equal to round-off).
"""

from __future__ import annotations

import gc
import json
import logging
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from forms.membrane import MembraneLaw, membrane_law
from meshes.data import MeshData, read_msh, write_msh
from meshes.membrane import (
    SurfaceMeshData,
    closed_can,
    disc_surface,
    extrude,
    facing_discs,
    smooth_rest_shape,
    sphere_octant,
    vertex_normals,
)
from meshes.surface_file import oriented_cells, read_surface
from model.config.membrane import MUSCLE_FILES, MembraneRunConfig
from model.domain.distribute import build_domain
from model.errors import ConfigError, SolveFailed
from model.experiments.membrane import cell_values, close_and_mesh, deformed_points, set_nodal_displacement
from model.output.writer import SUMMARY, XdmfSeries, remove_earlier_run, write_json_atomic
from model.pipeline import Interrupted, StopFlag
from model.problem.membrane import (
    MembraneProblem,
    axis_orientation,
    balloon_pressure,
    hencky,
    radial_orientation,
    triangle_orientation,
)
from model.problem.membrane_contact import MembranePairContact, MembraneSelfContact, ObstacleContact, pair_contacts
from model.solvers.membrane import InflationStep, InflationStopped, inflate, inflate_to_volume

log = logging.getLogger(__name__)

__all__ = ["run_membrane"]


def _extrusion(config: MembraneRunConfig, law: MembraneLaw, flat: SurfaceMeshData | None, num_points: int,
               comm: MPI.Comm) -> tuple[SurfaceMeshData | None, dict[str, Any]]:
    """[extrusion]: the disc ``flat`` extruded by ``offset`` (the clamped rim stays), inflated without contact to
    ``first_volume`` (inflate_to_volume, [inflation]'s dp and cutbacks), its free nodes smoothed and relaxed down to
    ``rest_volume`` (meshes.membrane.smooth_rest_shape): the new rest shape (rank 0, else None) and summary.json's
    "extrusion". SolveFailed when the first phase's Newton fails. Collective."""
    e, m, inflation = config.extrusion, config.membrane, config.inflation
    rim = np.unique(flat.facets[flat.facet_tags == flat.boundary_names["rim"]]) if comm.rank == 0 else None
    extruded = extrude(flat, e.offset, rim) if comm.rank == 0 else None
    first = MembraneProblem(build_domain(comm, extruded), law, axis_orientation(), m.border,
                            quadrature_degree=m.quadrature_degree)
    dp = inflation.dp if inflation.dp is not None else 0.05 * law.equibiaxial(1.1)[1] / m.radius
    try:
        steps = inflate_to_volume(first, e.first_volume, dp, max_steps=inflation.max_steps,
                                  cutbacks=inflation.cutbacks)
    except RuntimeError as err:
        raise SolveFailed(f"extrusion: the first inflation failed: {err}") from None
    inflated = deformed_points(first, num_points)
    rest, record = None, None
    if comm.rank == 0:
        smoothing = smooth_rest_shape(inflated, flat.cells, rim, e.rest_volume)
        rest = SurfaceMeshData(smoothing.points, flat.cells, flat.cell_tags, flat.facets, flat.facet_tags,
                               flat.region_names, flat.boundary_names)
        record = {"offset": e.offset, "first_volume": e.first_volume, "rest_volume": e.rest_volume,
                  "first_steps": [{"pressure": s.pressure, "volume": s.volume, "energy": s.energy,
                                   "iterations": s.iterations} for s in steps],
                  "smoothing_iterations": smoothing.iterations, "smoothed_volume": float(smoothing.volumes[-1])}
    record = comm.bcast(record)
    log.info("extrusion: V = %.6g at p = %.6g after %d steps; smoothed to V = %.6g in %d iterations",
             steps[-1].volume, steps[-1].pressure, len(steps), record["smoothed_volume"],
             record["smoothing_iterations"])
    return rest, record


def _ends(config: MembraneRunConfig, data: SurfaceMeshData) -> tuple[int, int]:
    """[muscle]: how many base (rest) triangles have their centroid at x < -end radius and at x > end radius."""
    x = data.points[data.cells].mean(axis=1)[:, 0]
    limit = config.muscle.end * config.membrane.radius
    return int(np.count_nonzero(x < -limit)), int(np.count_nonzero(x > limit))


def _check_ends(config: MembraneRunConfig, data: SurfaceMeshData | None, comm: MPI.Comm) -> None:
    """ConfigError before any solve when an end of the muscle has no base triangle (no fibre origin or insertion)."""
    counts = comm.bcast(_ends(config, data) if comm.rank == 0 else None)
    if min(counts) == 0:
        m = config.membrane
        raise ConfigError(f"muscle.end: no base triangle has its centroid beyond x = +-{config.muscle.end:g} radius "
                          f"(membrane.size {m.size:g}, radius {m.radius:g}): lower end or size")


def muscle_document(config: MembraneRunConfig, out: Path) -> str:
    """muscle.toml's text: a solid run (model.config.RunConfig) of the closed patch's tetrahedra (muscle.msh)
    with the Laplace fibres of fibres.npy, the activation ramped from 0 to ``activation`` in ``steps`` load steps
    and the ``fixed`` boundaries clamped; its results go to OUT/contraction, an absolute path, so that the file
    runs from any working directory (the command line's --out wins)."""
    m = config.muscle
    lines = [
        "# The muscle of a membrane run ([muscle], model.experiments.membrane_run; docs/membranes.md): the inflated",
        "# disc patch closed with its flat base, filled with tetrahedra (muscle.msh: volume muscle; surfaces patch,",
        "# base, origin, insertion) and given the Laplace fibre field from origin to insertion (fibres.npy).",
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


def _muscle(config: MembraneRunConfig, problem: MembraneProblem, data: SurfaceMeshData | None, num_points: int,
            out: Path, comm: MPI.Comm) -> dict[str, Any]:
    """[muscle]: close the final surface, tetrahedralise, Laplace fibres, write the files (module docstring).
    Collective; returns summary.json's "muscle"."""
    with _collected():
        return _close_and_write(config, problem, data, num_points, out, comm)


def _close_and_write(config: MembraneRunConfig, problem: MembraneProblem, data: SurfaceMeshData | None,
                     num_points: int, out: Path, comm: MPI.Comm) -> dict[str, Any]:
    m, muscle = config.membrane, config.muscle
    tet_size = muscle.tet_size if muscle.tet_size is not None else m.size
    deformed = deformed_points(problem, num_points)
    _, fibres, mesh_data = close_and_mesh(data, deformed, m.radius, muscle.end, tet_size, comm)
    a0 = cell_values(fibres)
    enclosed = problem.volume()
    record, error = None, None
    if comm.rank == 0:
        try:
            record = _write_muscle(config, data, mesh_data, a0, enclosed, tet_size, out)
        except (OSError, RuntimeError, ValueError) as err:  # ConfigError is a ValueError: muscle.toml refused
            error = f"muscle: {err}"
    record, error = comm.bcast((record, error))
    if error:
        raise RuntimeError(error)
    return record


def _write_muscle(config: MembraneRunConfig, data: SurfaceMeshData, mesh_data: MeshData, a0: np.ndarray,
                  enclosed: float, tet_size: float, out: Path) -> dict[str, Any]:
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
    origin, insertion = _ends(config, data)
    record = {**MUSCLE_FILES, "tetrahedra": mesh_data.num_cells, "points": mesh_data.num_points,
              "tet_size": tet_size, "end": muscle.end, "volume": mesh_data.volume(), "enclosed_volume": enclosed,
              "origin_triangles": origin, "insertion_triangles": insertion,
              "boundaries": sorted(mesh_data.boundary_names), "fixed": list(muscle.fixed)}
    log.info("muscle: %d tetrahedra, volume %.9g (membrane %.9g); %s", mesh_data.num_cells, record["volume"],
             enclosed, out / MUSCLE_FILES["config"])
    return record


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


def _largest_displacement(problem: MembraneProblem) -> float:
    """max over the nodes of |u| (collective)."""
    bs = problem.V.dofmap.index_map_bs
    n = problem.V.dofmap.index_map.size_local
    local = np.linalg.norm(problem.u.x.array[: n * bs].reshape(-1, bs), axis=1)
    return float(problem.domain.mesh.comm.allreduce(local.max() if len(local) else 0.0, op=MPI.MAX))


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


def _pair_record(pair: MembranePairContact) -> dict[str, Any]:
    """A membrane-membrane contact's state for a step: force on the slave and on the master, penetration,
    contact fraction (of the slave's area), active nodes. Collective."""
    report = pair.report()
    return {k: report[k] for k in ("pair", "force", "master_force", "max_penetration", "contact_fraction",
                                   "active_points")}


def _obstacle_name(spec: Any, index: int) -> str:
    return spec.name or f"{type(spec.obstacle).__name__.lower()}_{index}"


def _obstacle_summary(spec: Any) -> dict[str, Any]:
    """The obstacle's shape (forms.obstacles dataclass fields) and contact settings, for summary.json."""
    o = spec.obstacle
    return {"obstacle": type(o).__name__.lower(), **asdict(o), "penalty": spec.penalty, "inside": spec.inside,
            "augmented": spec.augmented}


class _Writer:
    """The deformed surface per step: XDMF of u (collective) and VTU (rank 0, meshio)."""

    def __init__(self, problem: MembraneProblem, data: SurfaceMeshData | None, num_points: int, out: Path,
                 xdmf: bool, vtu: bool) -> None:
        self.problem, self.data, self.num_points, self.out = problem, data, num_points, out
        self.series = XdmfSeries(problem.domain.mesh, out, "surface") if xdmf else None
        self.vtu = vtu
        self.files: list[str] = ["surface.xdmf", "surface.h5"] if xdmf else []
        self.count = 0

    def write(self, pressure: float) -> None:
        self.count += 1
        if self.series is not None:
            self.files.append(self.series.write([self.problem.u], pressure))
        if self.vtu:
            points = deformed_points(self.problem, self.num_points)
            name = f"surface_{self.count:04d}.vtu"
            if points is not None:
                import meshio

                u = points - self.data.points
                meshio.Mesh(self.data.points, [("triangle", self.data.cells)], point_data={"u": u}).write(
                    self.out / name)
            self.files.append(name)


def _step_record(step: InflationStep, problem: MembraneProblem, config: MembraneRunConfig, law: MembraneLaw,
                 rest_volume: float, pairs: list[MembranePairContact]) -> dict[str, Any]:
    m = config.membrane
    record: dict[str, Any] = {"pressure": step.pressure, "volume": step.volume, "energy": step.energy,
                              "iterations": step.iterations, "contact_fraction": step.contact_fraction}
    if config.inflation.freeze_on_contact:
        record["frozen_nodes"] = step.frozen_nodes
    if m.surface == "sphere_octant":
        stretch = (step.volume / rest_volume) ** (1.0 / 3.0)
        record["stretch"] = stretch
        record["balloon_pressure"] = float(balloon_pressure(law, m.radius, stretch))
    elif m.surface == "file":
        record["max_displacement"] = _largest_displacement(problem)
        if pairs:
            record["pairs"] = [_pair_record(pair) for pair in pairs]
    elif m.surface in ("facing_discs", "closed_can"):
        record["centre_deflection"] = problem.max_component(2)  # the lower disc's (towards +z)
        record["pairs"] = [_pair_record(pair) for pair in pairs]
    else:
        record["centre_deflection"] = problem.max_component(2)
        if m.law == "stvk":
            record["hencky_deflection"] = _hencky(m.nu).centre_deflection(m.radius, step.pressure, m.young,
                                                                           m.thickness)
    return record


@cache
def _hencky(nu: float) -> Any:
    return hencky(nu)


def run_membrane(config: MembraneRunConfig, out: Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
                 stop: Any = None) -> dict[str, Any]:
    """Run a membrane configuration into ``out`` (default output.dir) and return summary.json's content.
    SolveFailed (after writing the summary, status "failed") when Newton gives up. Collective.

    summary.json is rewritten after every pressure step of a ramp or list (status "running"), so a run that dies
    keeps the steps it finished, next to their surfaces (each XDMF step is closed when written); a volume or
    contact-fraction growth rewrites it after every equilibrium it finds (growth, secant or bisection). SIGINT or
    SIGTERM stop the run after the step it is solving (model.pipeline.StopFlag; ``stop``: any object whose
    ``check(comm)`` returns the signal number, 0 for none): status "interrupted" (a growth's surface written at
    its last equilibrium), then model.pipeline.Interrupted.
    """
    if stop is None:
        with StopFlag() as flag:
            return _run_membrane(config, out, comm, flag)
    return _run_membrane(config, out, comm, stop)


def _run_membrane(config: MembraneRunConfig, out: Path | None, comm: MPI.Comm, stop: Any) -> dict[str, Any]:
    start = time.perf_counter()
    out = Path(out) if out is not None else config.output.dir
    m = config.membrane
    # a surface file is read and checked first: a bad one leaves the output folder as it was
    surface_file = _file_surface(config, comm) if m.surface == "file" else None
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    comm.barrier()
    remove_earlier_run(out, comm)
    m, inflation = config.membrane, config.inflation
    law = membrane_law(m.law, **m.law_parameters)
    if surface_file is not None:
        flat = data = surface_file.data
        orientation = triangle_orientation(*comm.bcast((data.points, data.cells) if comm.rank == 0 else None))
    else:
        flat = data = _surface(config) if comm.rank == 0 else None
        orientation = _orientation(config) if m.surface != "closed_can" else \
            triangle_orientation(*comm.bcast((data.points, data.cells) if comm.rank == 0 else None))
    num_points = comm.bcast(len(data.points) if comm.rank == 0 else None)
    if config.muscle is not None:
        _check_ends(config, data, comm)
    extrusion = None
    if config.extrusion is not None:  # the first phase: data becomes the smoothed rest shape (rank 0)
        data, extrusion = _extrusion(config, law, flat, num_points, comm)
        orientation = triangle_orientation(*comm.bcast((data.points, data.cells) if comm.rank == 0 else None))
    domain = build_domain(comm, data)
    problem = MembraneProblem(domain, law, orientation, m.border, quadrature_degree=m.quadrature_degree,
                              freeze_on_contact=inflation.freeze_on_contact, unit_area=inflation.unit_area)
    rest_volume = problem.volume()
    contacts = [ObstacleContact(problem, spec.obstacle, spec.penalty, spec.inside, _obstacle_name(spec, i),
                                spec.augmented) for i, spec in enumerate(config.obstacles)]
    pairs = [pair for spec in config.contacts
             for pair in ([MembraneSelfContact(problem, spec.penalty, spec.region, rings=spec.rings or 2,
                                               reach=spec.reach, name=spec.label)] if spec.self_contact else
                          pair_contacts(problem, spec.surface, spec.master, spec.penalty, name=spec.name,
                                        augmented=spec.augmented, two_pass=spec.two_pass))]
    contacts = [*contacts, *pairs]
    if m.surface in ("disc", "facing_discs", "closed_can") and extrusion is None:
        bump = m.bump * m.radius
        side = (lambda x: _facing_side(x[2], m.gap)) if m.surface in ("facing_discs", "closed_can") else \
            (lambda x: 1.0)
        problem.u.interpolate(lambda x: np.vstack([0 * x[0], 0 * x[0],
                                                   side(x) * bump * (1 - (x[0]**2 + x[1]**2) / m.radius**2)]))
    if surface_file is not None:
        _file_bump(config, surface_file, problem, comm)
    scale = surface_file.radius if surface_file is not None else m.radius
    units = config.units
    summary: dict[str, Any] = {
        "kind": "membrane", "config": config.document, "status": "running",
        "surface": {"generator": m.surface, "radius": scale, "size": None if surface_file else m.size,
                    "triangles": domain.mesh.topology.index_map(2).size_global, "nodes": num_points,
                    "reference_area": problem.reference_area(), "rest_volume": rest_volume,
                    "fixed": {k: list(v) for k, v in m.border.items()}},
        "law": {"name": law.name, **m.law_parameters},
        "obstacles": [_obstacle_summary(spec) for spec in config.obstacles],
        "pairs": [{"name": spec.label, "surface": spec.surface, "master": spec.master, "penalty": spec.penalty,
                   "augmented": spec.augmented, "two_pass": spec.two_pass,
                   **({"self_contact": True, "region": spec.region, "rings": spec.rings or 2,
                       "reach": next(p.reach for p in pairs if p.name == spec.label)}
                      if spec.self_contact else {})} for spec in config.contacts],
        "units": {"system": units.system, **{d: units.unit(d) for d in ("length", "stress", "energy", "volume")}},
        "steps": [], "contacts": [], "wall_time_s": 0.0,
    }
    if extrusion is not None:
        summary["extrusion"] = extrusion
    if surface_file is not None:
        summary["surface"].update({"file": str(config.membrane.file), "centre": list(surface_file.centre),
                                   "orientation": m.orientation if m.orientation is not None else "file"})
    writer = _Writer(problem, data, num_points, out, config.output.xdmf, config.output.vtu)

    def save() -> None:
        summary["files"] = [*writer.files, SUMMARY]
        summary["wall_time_s"] = time.perf_counter() - start
        if comm.rank == 0:
            write_json_atomic(out / SUMMARY, summary)

    def interrupted(signum: int, count: int, pressure: float) -> Interrupted:
        summary["contacts"] = [c.report() for c in contacts]
        summary["status"] = "interrupted"
        save()
        comm.barrier()
        return Interrupted(signum, f"interrupted by {signal.Signals(signum).name} after pressure step {count} "
                                   f"(p = {pressure:.6g}); results in {out}")

    error = None
    try:
        pressures = inflation.ramp
        if pressures is not None:
            steps = []
            for p in pressures:  # one at a time: the surface is written after each equilibrium
                steps += inflate(problem, [p], cutbacks=inflation.cutbacks, uzawa_tolerance=config.uzawa_tolerance)
                summary["steps"].append(_step_record(steps[-1], problem, config, law, rest_volume, pairs))
                writer.write(p)
                signum = stop.check(comm)
                if signum:
                    raise interrupted(signum, len(steps), p)
                save()
        else:
            dp = inflation.dp if inflation.dp is not None else 0.05 * law.equibiaxial(1.1)[1] / scale
            signals = [0]
            found: list[InflationStep] = []  # the equilibria recorded, in summary["steps"]'s order

            def on_step(step: InflationStep) -> bool:
                # every equilibrium of the growth (its state is problem.u now): recorded once and saved, and the
                # signals checked between the steps
                found.append(step)
                summary["steps"].append(_step_record(step, problem, config, law, rest_volume, pairs))
                signals[0] = stop.check(comm)
                if not signals[0]:
                    save()
                return bool(signals[0])

            try:
                steps = inflate_to_volume(problem, inflation.volume, dp, max_steps=inflation.max_steps,
                                          cutbacks=inflation.cutbacks, contact_fraction=inflation.contact_fraction,
                                          on_step=on_step, uzawa_tolerance=config.uzawa_tolerance)
            except InflationStopped as stopped:
                writer.write(stopped.steps[-1].pressure)
                raise interrupted(signals[0], len(stopped.steps), stopped.steps[-1].pressure) from None
            # each equilibrium was recorded once, as it was found; the accepted one (the state left in the
            # problem: a contact-fraction stop's bisection may have tried a lower pressure after it) goes last
            accepted = next(i for i in range(len(found) - 1, -1, -1) if found[i] is steps[-1])
            summary["steps"].append(summary["steps"].pop(accepted))
            writer.write(steps[-1].pressure)
        if config.muscle is not None:
            summary["muscle"] = _muscle(config, problem, flat, num_points, out, comm)
            writer.files += list(MUSCLE_FILES.values())
    except RuntimeError as err:
        error = str(err)
    summary["contacts"] = [c.report() for c in contacts]
    summary["status"] = "failed" if error else "completed"
    if error:
        summary["error"] = error
    save()
    comm.barrier()
    if error:
        raise SolveFailed(error)
    last = summary["steps"][-1]
    log.info("membrane: %d pressure steps, last p = %.6g, V = %.6g, contact fraction %.4g, %.1f s",
             len(summary["steps"]), last["pressure"], last["volume"], last["contact_fraction"],
             summary["wall_time_s"])
    return summary

