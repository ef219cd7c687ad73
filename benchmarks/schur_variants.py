"""One variant of the iterative Taylor-Hood preset on the bar of benchmarks/scaling.py, at nu = 0.3 and 0.4999.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/schur_variants.py N [--nu 0.3 0.4999] \
        [--options '{"pc_fieldsplit_schur_fact_type": "full"}'] [--shear 1.0] [--bulk 1.0] [--matrix aij]
    mpirun -n 2 .venv/bin/python benchmarks/schur_variants.py ...

The bar: ``scaling.bar(N, "mixed", nu, "iterative")`` (2N x N x N boxes of six tetrahedra, neo-Hookean E = 1e4,
clamped, sheared by a dead traction, 2 load steps; 13 312 dofs at N = 6, 121 203 at N = 13). ``--options`` are
added to ``solver.petsc_options``; ``--shear a --bulk b`` replace the Schur preconditioner's weight 1/mu + 1/kappa
by a/mu + b/kappa (Sp's compliances are patched in model.solvers.linear.MixedFields for this process only).
Printed per nu (rank 0): dofs, the linear iterations of every Newton iteration and their mean, wall and CPU time
(the largest over the ranks), the PETSc flops of the run (summed over the ranks: the linear algebra's work,
machine-independent, unlike times on a shared machine) and the peak resident memory so far (VmHWM summed over the
ranks, warm-up and earlier nu included: run one nu for one run's peak). ``--conformal`` adds the three special
conformal fields to the u block's near null space (ten modes). Asserts nothing (docs/solvers.md, "Against the
targets").
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
for entry in (ROOT, ROOT / "benchmarks"):
    if str(entry) not in sys.path:
        sys.path.insert(0, str(entry))


def _hwm_mb() -> int:
    """This process's peak resident memory so far (VmHWM, MB; 0 where /proc is missing)."""
    try:
        with open("/proc/self/status") as lines:
            return next((int(line.split()[1]) // 1024 for line in lines if line.startswith("VmHWM:")), 0)
    except OSError:
        return 0


def _conformal_modes(space: Any, vectors: list[Any]) -> list[Any]:
    """``vectors`` (orthonormal, owned entries of a blocked vector space) and the three special conformal fields
    v_b(x) = 2 (b . x) x - |x|^2 b (b = e_1, e_2, e_3; x centred on the dofs' bounding box: sym grad v_b =
    2 (b . x) I, no deviatoric strain), orthonormalised against them and each other (modified Gram-Schmidt)."""
    import numpy as np
    from mpi4py import MPI

    imap, bs = space.dofmap.index_map, space.dofmap.index_map_bs
    owned = imap.size_local
    x = space.tabulate_dof_coordinates()[:owned, :3]
    low = x.min(axis=0) if owned else np.full(3, np.inf)
    high = x.max(axis=0) if owned else np.full(3, -np.inf)
    comm = space.mesh.comm
    comm.Allreduce(MPI.IN_PLACE, low, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, high, op=MPI.MAX)
    x = x - 0.5 * (low + high)
    square = np.sum(x * x, axis=1)
    out = list(vectors)
    for b in range(3):
        v = vectors[0].duplicate()
        with v.localForm() as local:
            for i in range(3):
                local.array[i:owned * bs:bs] = 2.0 * x[:, b] * x[:, i] - (square if i == b else 0.0)
        for w in out:
            v.axpy(-w.dot(v), w)
        v.normalize()
        out.append(v)
    return out


def main() -> None:
    from mpi4py import MPI
    from petsc4py import PETSc
    from scaling import bar

    import model.solvers.linear as linear
    from model.config import parse
    from model.pipeline import run

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", type=int, help="n of the 2n x n x n bar")
    parser.add_argument("--nu", type=float, nargs="+", default=[0.3, 0.4999])
    parser.add_argument("--options", default="{}", help="PETSc options (JSON) added to the preset's")
    parser.add_argument("--shear", type=float, default=1.0, help="a of the Schur weight a/mu + b/kappa")
    parser.add_argument("--bulk", type=float, default=1.0, help="b of the Schur weight a/mu + b/kappa")
    parser.add_argument("--conformal", action="store_true",
                        help="add the three special conformal fields to the u block's near null space (10 modes)")
    parser.add_argument("--matrix", choices=("auto", "aij", "nest"), default="auto",
                        help="[solver] matrix: the nested Jacobian (auto, nest) or one assembled matrix (aij)")
    args = parser.parse_args()
    options: dict[str, Any] = json.loads(args.options)

    assemble = linear.MixedFields._weighted_mass

    def weighted_mass(self: linear.MixedFields, problem: Any) -> PETSc.Mat:
        self.compliance = [(region, args.shear / linear.shear_modulus(law)
                            + (0.0 if math.isinf(law.bulk_penalty) else args.bulk / law.bulk_penalty))
                           for region, law in problem.materials]
        return assemble(self, problem)

    linear.MixedFields._weighted_mass = weighted_mass  # type: ignore[method-assign]
    if args.conformal:
        modes = linear.vector_rigid_body_modes

        def with_conformal(space: Any, dilation: bool = False) -> list[PETSc.Vec]:
            return _conformal_modes(space, modes(space, dilation=dilation))

        linear.vector_rigid_body_modes = with_conformal  # type: ignore[assignment]
    comm = MPI.COMM_WORLD
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(comm.bcast(scratch if comm.rank == 0 else None))
        warm = bar(1, "mixed", 0.3, "iterative")
        warm["loading"] = {"steps": 1}
        warm["solver"]["petsc_options"] = dict(options)
        warm["solver"]["matrix"] = args.matrix
        run(parse(warm, ROOT / "examples"), out / "warm-up", comm)  # compile the forms, untimed
        PETSc.Log.begin()
        for nu in args.nu:
            raw = bar(args.n, "mixed", nu, "iterative")
            raw["solver"]["petsc_options"] = dict(options)
            raw["solver"]["matrix"] = args.matrix
            comm.Barrier()
            flops, wall, cpu = PETSc.Log.getFlops(), time.perf_counter(), time.process_time()
            summary = run(parse(raw, ROOT / "examples"), out / f"nu{nu}", comm)
            wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)
            cpu = comm.allreduce(time.process_time() - cpu, op=MPI.MAX)
            flops = comm.allreduce(PETSc.Log.getFlops() - flops, op=MPI.SUM)
            peak = comm.allreduce(_hwm_mb(), op=MPI.SUM)
            counts = [c for step in summary["steps"] for c in step.get("linear_iterations_per_newton", [])]
            if comm.rank == 0:
                print(f"n = {args.n}, {summary['dofs']} dofs, {comm.size} rank(s), matrix "
                      f"{summary['solver'].get('matrix')}, nu = {nu}, weight "
                      f"{args.shear}/mu + {args.bulk}/kappa, {json.dumps(options)}: {summary['status']}; linear its "
                      f"{counts}, mean {sum(counts) / max(len(counts), 1):.2f}; wall {wall:.1f} s, CPU {cpu:.1f} s, "
                      f"{flops / 1e9:.1f} GFlop, peak {peak} MB (VmHWM summed over ranks)", flush=True)
        comm.Barrier()


if __name__ == "__main__":
    main()
