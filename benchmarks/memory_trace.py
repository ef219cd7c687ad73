"""Per-rank resident memory at each stage of one Taylor-Hood bar run (issue 10: where 2 ranks' memory goes).

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 [mpirun -n 2] .venv/bin/python benchmarks/memory_trace.py [--n 13] \
        [--case th_0.4999] [--linear iterative] [--out results/memory_trace]

Runs benchmarks/scaling.py's bar config (2n x n x n boxes; n = 13 is 1.2e5 Taylor-Hood dofs) through
model.pipeline.run after an untimed warm-up (forms compiled), and records on every rank VmRSS and VmHWM
(/proc/self/status, MB) at the stage marks: after the warm-up, around ``build`` (mesh, spaces, forms), around
the scale check (below 5e4 dofs a factorisation, above it an iterative solve: the first GAMG hierarchy), around
``make_solver`` and around each load step's solve; a 0.1 s sampler thread records the largest VmRSS between
marks (a transient peak shows as sampled peak > the marks' values). Rank 0 prints one JSON line ``TRACE``
{"dofs", "wall", "ranks": [{"marks": [[t, stage, rss, hwm], ...], "sampled_peak": MB}, ...], "sum_hwm": MB}.
PETSc's own breakdown by event: PETSC_OPTIONS="-log_view :FILE -log_view_memory". Asserts nothing; the
measured trace is in docs/solvers.md ("Where the 2-rank memory goes").
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def status() -> tuple[int, int]:
    """(VmRSS, VmHWM) of this process in MB."""
    values = {}
    with open("/proc/self/status") as lines:
        for line in lines:
            if line.startswith(("VmRSS:", "VmHWM:")):
                values[line.split(":")[0]] = int(line.split()[1]) // 1024
    return values["VmRSS"], values["VmHWM"]


class Trace:
    """Stage marks and a background sampler of VmRSS (one per process)."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.marks: list[tuple[float, str, int, int]] = []
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        while not self._stop.is_set():
            self.peak = max(self.peak, status()[0])
            self._stop.wait(0.1)

    def mark(self, stage: str) -> None:
        rss, hwm = status()
        self.peak = max(self.peak, rss)
        self.marks.append((round(time.perf_counter() - self.start, 2), stage, rss, hwm))

    def wrap(self, function: Callable[..., Any], stage: str) -> Callable[..., Any]:
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            self.mark(f"{stage} start")
            result = function(*args, **kwargs)
            self.mark(f"{stage} end")
            return result
        return wrapped

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=13, help="bar of 2n x n x n boxes")
    parser.add_argument("--case", default="th_0.4999", help="a bar case of benchmarks/scaling.py")
    parser.add_argument("--linear", default="iterative")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "memory_trace")
    args = parser.parse_args()

    from mpi4py import MPI

    import model.pipeline as pipeline
    import model.solvers.scale as scale
    from benchmarks.scaling import config
    from model.config import parse

    comm = MPI.COMM_WORLD
    trace = Trace()
    raw = config(args.case, args.n, args.linear)
    warm = {**raw, "loading": {"steps": 1}, "mesh": {**raw["mesh"], "cells": [2, 1, 1]}}
    pipeline.run(parse(warm, ROOT / "examples"), args.out / "warm-up", comm)

    pipeline.build = trace.wrap(pipeline.build, "build")
    scale.scale_check = trace.wrap(scale.scale_check, "scale_check")
    make_solver = trace.wrap(pipeline.make_solver, "make_solver")

    def traced_solver(*a: Any, **k: Any) -> Any:
        solver = make_solver(*a, **k)
        solver.solve = trace.wrap(solver.solve, "solve")  # one call per load step
        return solver

    pipeline.make_solver = traced_solver
    comm.Barrier()
    trace.marks.clear()
    trace.mark("after warm-up")
    start = time.perf_counter()
    summary = pipeline.run(parse(raw, ROOT / "examples"), args.out / "run", comm)
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    trace.mark("end")
    trace.stop()
    ranks = comm.gather({"marks": trace.marks, "sampled_peak": trace.peak}, root=0)
    if comm.rank == 0:
        print("TRACE " + json.dumps({"dofs": summary["dofs"], "wall": wall, "ranks": ranks,
                                     "sum_hwm": sum(r["marks"][-1][3] for r in ranks)}), flush=True)


if __name__ == "__main__":
    main()
