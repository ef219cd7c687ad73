"""What a membrane run writes (model.experiments.membrane_run): summary.json's per-step records (pressure, volume,
energy, Newton iterations, contact fraction, deflections, the balloon's and Hencky's closed forms, each pair's
forces and penetration) and the deformed surface per step (XDMF time series and VTU files)."""

from __future__ import annotations

import logging
from dataclasses import asdict
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from forms.membrane import MembraneLaw
from meshes.membrane import (
    SurfaceMeshData,
)
from model.config.membrane import MembraneRunConfig
from model.experiments.membrane import deformed_points
from model.output.writer import XdmfSeries
from model.problem.membrane import (
    MembraneProblem,
    balloon_pressure,
    hencky,
)
from model.problem.membrane_contact import MembranePairContact
from model.solvers.membrane import InflationStep

log = logging.getLogger(__name__)

__all__ = []


def _largest_displacement(problem: MembraneProblem) -> float:
    """max over the nodes of |u| (collective)."""
    bs = problem.V.dofmap.index_map_bs
    n = problem.V.dofmap.index_map.size_local
    local = np.linalg.norm(problem.u.x.array[: n * bs].reshape(-1, bs), axis=1)
    return float(problem.domain.mesh.comm.allreduce(local.max() if len(local) else 0.0, op=MPI.MAX))


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
        if pairs:
            record["pairs"] = [_pair_record(pair) for pair in pairs]
        if m.law == "stvk":
            record["hencky_deflection"] = _hencky(m.nu).centre_deflection(m.radius, step.pressure, m.young,
                                                                           m.thickness)
    return record


@cache
def _hencky(nu: float) -> Any:
    return hencky(nu)
