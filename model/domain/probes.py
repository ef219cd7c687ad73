"""Probes: point evaluation of a displacement at fixed reference points, the same on every rank."""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from model import compat


class Probes:
    """Point evaluation of a vector Function at fixed reference points, the same on every rank."""

    def __init__(self, domain_mesh, points: dict[str, tuple[float, float, float]]) -> None:
        self.mesh = domain_mesh
        self.names = list(points)
        self.points = np.array([points[n] for n in self.names], dtype=np.float64).reshape(-1, 3)
        comm = domain_mesh.comm
        tdim = domain_mesh.topology.dim
        colliding = compat.colliding_cells(domain_mesh, self.points)
        num_owned = domain_mesh.topology.index_map(tdim).size_local
        self.cells = np.full(len(self.names), -1, dtype=np.int32)
        for i in range(len(self.names)):
            links = colliding.links(i)
            owned = links[links < num_owned]
            if len(owned):
                self.cells[i] = owned[0]
        found = np.where(self.cells >= 0, comm.rank, comm.size)
        self.owner = np.empty_like(found)
        comm.Allreduce(found, self.owner, op=MPI.MIN)
        self.missing = [n for n, o in zip(self.names, self.owner) if o == comm.size]

    def evaluate(self, function: fem.Function) -> dict[str, list[float]]:
        """{name: value} of the function at each probe point (each point evaluated by one rank)."""
        comm = self.mesh.comm
        size = function.function_space.dofmap.index_map_bs
        values = np.zeros((len(self.names), size))
        mine = np.flatnonzero(self.owner == comm.rank)
        if len(mine):
            values[mine] = function.eval(self.points[mine], self.cells[mine]).reshape(len(mine), size)
        total = np.zeros_like(values)
        comm.Allreduce(values, total, op=MPI.SUM)
        return {n: total[i].tolist() for i, n in enumerate(self.names)}
