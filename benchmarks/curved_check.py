"""The cost of the curved-cell check (model.domain.checks, (d)) against reading the mesh (figures only).

A unit ball meshed by gmsh with 10-node tetrahedra (setOrder(2): edge nodes on the sphere) is written to a
.msh file, then read as a run reads it (model.domain.make_domain: gmsh's reader, distribution, all mesh
checks). Timed, best of --repeats: the whole read; check_mesh alone (folds, quality and the curved check);
the curved check alone (det J at the degree-4 rule's 14 points and the 10 nodes of every owned cell, the
reductions). In parallel each figure is the slowest rank's.

    python benchmarks/curved_check.py [--size 0.125] [--repeats 5]
    mpirun -n 2 python benchmarks/curved_check.py
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import gmsh
import numpy as np
from mpi4py import MPI

import meshes
from model.config import parse
from model.domain import checks, make_domain


def write_ball(path: Path, size: float) -> None:
    with meshes._gmsh.gmsh_session({"Mesh.MeshSizeMax": size, "Mesh.MshFileVersion": 4.1}):
        gmsh.model.occ.addSphere(0, 0, 0, 1.0)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], 1)
        gmsh.model.setPhysicalName(3, 1, "body")
        gmsh.model.addPhysicalGroup(2, [1], 1)
        gmsh.model.setPhysicalName(2, 1, "surface")
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        gmsh.write(str(path))


def best(comm: MPI.Comm, repeats: int, work: Callable[[], object]) -> float:
    times = []
    for _ in range(repeats):
        comm.barrier()
        start = time.perf_counter()
        work()
        times.append(comm.allreduce(time.perf_counter() - start, op=MPI.MAX))
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=0.125, help="gmsh's largest cell size (0.125: ~10k cells)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    logging.getLogger("model").setLevel(logging.ERROR)  # the reader's note on curved cells, once per read
    comm = MPI.COMM_WORLD
    folder = comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0)
    path = Path(folder) / "ball2.msh"
    if comm.rank == 0:
        write_ball(path, args.size)
    comm.barrier()
    raw = {"mesh": {"file": str(path)}, "material": [{"region": "all", "law": "neo_hookean", "E": 1.0, "nu": 0.3}]}
    cfg = parse(raw, Path(folder)).mesh
    domain = make_domain(cfg, comm)
    msh = domain.mesh
    cells = msh.topology.index_map(3).size_global
    read = best(comm, args.repeats, lambda: make_domain(cfg, comm))
    whole = best(comm, args.repeats, lambda: checks.check_mesh(msh, "mesh.file"))
    owned = msh.topology.index_map(3).size_local
    x = msh.geometry.x[checks.compat.geometry_dofs(msh)[:owned, :4]][:, :, :3]
    volumes, centroids = checks.signed_volumes(x), x.mean(axis=1)
    original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)[:owned]
    curved = best(comm, args.repeats, lambda: checks._check_curved(msh, "mesh.file", original, centroids, volumes,
                                                                     args.size))
    if comm.rank == 0:
        print("| 10-node cells | ranks | read the mesh (make_domain) | check_mesh | curved check | min det J ratio |")
        print("|---|---|---|---|---|---|")
        print(f"| {cells} | {comm.size} | {read:.3f} s | {whole:.3f} s | {curved:.4f} s "
              f"({100 * curved / read:.1f} % of the read) | {domain.quality['min_jacobian_ratio']:.3f} |")


if __name__ == "__main__":
    main()
