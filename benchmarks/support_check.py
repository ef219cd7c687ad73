"""The support check's cost (model.problem.supports.check_supports) on every shipped example, against its build.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/support_check.py [NAME ...]
    mpirun -n 2 .venv/bin/python benchmarks/support_check.py arm_segment

For each examples/NAME.toml with a solid run (not a [membrane] file; all of them by default): cells, the time of
model.pipeline.build (mesh, fields, problem) and of check_supports alone (wall, the slowest rank), and its verdict
(ok, the warnings, or the ConfigError). Asserts nothing.
"""

from __future__ import annotations

import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpi4py import MPI  # noqa: E402

from model import load_config  # noqa: E402
from model.errors import ConfigError  # noqa: E402
from model.pipeline import build  # noqa: E402
from model.problem.supports import check_supports  # noqa: E402


def main() -> None:
    comm = MPI.COMM_WORLD
    names = sys.argv[1:] or [p.stem for p in sorted((ROOT / "examples").glob("*.toml"))
                             if "membrane" not in tomllib.loads(p.read_text())]
    if comm.rank == 0:
        print(f"{comm.size} rank(s)\n| example | cells | build (s) | check (s) | verdict |\n|---|---|---|---|---|")
    for name in names:
        start = time.perf_counter()
        setup = build(load_config(ROOT / "examples" / f"{name}.toml"))
        built = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        start = time.perf_counter()
        try:
            warnings = check_supports(setup.problem, setup.contacts, setup.sliding)
            verdict = "ok" + (f", {len(warnings)} warning(s)" if warnings else "")
        except ConfigError as err:
            verdict = f"refused: {err}"
        checked = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        cells = setup.domain.mesh.topology.index_map(setup.domain.mesh.topology.dim).size_global
        if comm.rank == 0:
            print(f"| {name} | {cells} | {built:.1f} | {checked:.2f} | {verdict} |", flush=True)


if __name__ == "__main__":
    main()
