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
6. [muscle] (a clamped disc, or a file's patch of one clamped rim; [extrusion] before the inflation likewise;
   every volume then measured from the patch at rest, model.experiments.membrane_phases): the final surface
   closed with the patch at rest (the disc's flat one) as the base, filled with
   tetrahedra and given the Laplace fibre field (model.experiments.membrane.close_and_mesh, the thesis' ch.
   3.3.3), written as muscle.msh (gmsh, physical groups muscle; patch, base, origin, insertion), fibres.npy (a0
   per tetrahedron in the file's cell order), muscle.vtu (the tetrahedra with the cell data fibre_direction) and
   muscle.toml, a solid run of that muscle (``python -m model run OUT/muscle.toml``: law muscle with an StVK
   isotropic part, fibres = { type = "file" }, the activation ramped from 0, the ``fixed`` boundaries clamped),
   checked by the solid run's configuration reader before it is written; summary.json's "muscle" records the
   tetrahedra's volume next to the membrane's enclosed volume (the surface mesh is kept: equal to round-off).

The parts: model.experiments.membrane_surface (1: the surface, its checks, normals and bump),
model.experiments.membrane_phases ([extrusion] and [muscle]), model.experiments.membrane_records (4, 5: the
records and the writers); this module runs them.
"""

from __future__ import annotations

import logging
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from forms.membrane import membrane_law
from model.config.expressions import compile_expression
from model.config.membrane import MUSCLE_FILES, MembraneRunConfig
from model.domain.distribute import build_domain
from model.errors import ConfigError, SolveFailed
from model.experiments.membrane_phases import _extrusion, _muscle, _patch
from model.experiments.membrane_records import _obstacle_name, _obstacle_summary, _step_record, _Writer
from model.experiments.membrane_surface import _facing_side, _file_bump, _file_surface, _orientation, _surface
from model.output.writer import SUMMARY, remove_earlier_run, write_json_atomic
from model.pipeline import Interrupted, StopFlag
from model.problem.membrane import (
    MembraneProblem,
    triangle_orientation,
)
from model.problem.membrane_contact import MembraneSelfContact, ObstacleContact, pair_contacts
from model.solvers.membrane import InflationStep, InflationStopped, inflate, inflate_to_volume

log = logging.getLogger(__name__)

__all__ = ["run_membrane"]


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
    scale = surface_file.radius if surface_file is not None else m.radius
    # [extrusion], [muscle]: the rim, the base volume (volumes from the rest patch) and the fibre axis, checked
    patch = _patch(config, flat, comm) if config.muscle is not None or config.extrusion is not None else None
    extrusion = None
    if config.extrusion is not None:  # the first phase: data becomes the smoothed rest shape (rank 0)
        data, extrusion = _extrusion(config, law, flat, patch, scale, num_points, comm)
        orientation = triangle_orientation(*comm.bcast((data.points, data.cells) if comm.rank == 0 else None))
    domain = build_domain(comm, data)
    weight = compile_expression(inflation.pressure_weight) if inflation.pressure_weight is not None else None
    try:
        problem = MembraneProblem(domain, law, orientation, m.border, quadrature_degree=m.quadrature_degree,
                                  freeze_on_contact=inflation.freeze_on_contact, unit_area=inflation.unit_area,
                                  base_volume=patch.base_volume if patch is not None else 0.0,
                                  pressure_weight=weight)
    except ValueError as err:
        if weight is None:
            raise
        raise ConfigError(f"inflation.pressure_weight: {err}") from None
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
    if surface_file is not None and extrusion is None:
        _file_bump(config, surface_file, problem, comm)
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
                       "reach": next(p.reach for p in pairs
                                     if isinstance(p, MembraneSelfContact) and p.name == spec.label)}
                      if spec.self_contact else {})} for spec in config.contacts],
        "units": {"system": units.system, **{d: units.unit(d) for d in ("length", "stress", "energy", "volume")}},
        "steps": [], "contacts": [], "wall_time_s": 0.0,
    }
    if patch is not None:
        summary["surface"]["base_volume"] = patch.base_volume
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
            summary["muscle"] = _muscle(config, problem, flat, patch, num_points, out, comm)
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
