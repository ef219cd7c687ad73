"""Reference model for active soft-tissue elasticity on FEniCSx.

The Python API (the same pipeline as ``python -m model run``):

    import model
    config = model.load_config("examples/isometric.toml", overrides={"loading.steps": 3})
    result = model.run(config, out="results/isometric")
    result.summary, result.probes["belly_surface"], result.files["png"]

``load_config`` checks everything a configuration says before any mesh is read (ConfigError naming
the key); ``run`` builds the domain, fields, problem and solver, steps the load (or time) and writes
the results, returning a RunResult. Importing ``model`` or ``model.config`` does not load dolfinx.

One BLAS thread per MPI rank (set before numpy or PETSc load BLAS), and one SCOTCH thread per rank: PT-SCOTCH's
threads made the partition of a mesh random (dolfinx 0.5's create_box of one box in three 2-rank runs of the same
script: three different partitions, and a different one for each later mesh of a process, even with
partitioner_scotch(seed=0)), so a 2-rank run's iteration counts and last digits changed from run to run; with
SCOTCH_PTHREAD_NUMBER = 1 every run and every mesh of a process gets the same partition (Debian 12 and 13).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("SCOTCH_PTHREAD_NUMBER", "1")  # a deterministic mesh partition (module docstring)

if TYPE_CHECKING:
    from model.config import RunConfig
    from model.pipeline import RunResult


def load_config(source: str | Path | dict[str, Any], overrides: dict[str, Any] | None = None,
                base: str | Path | None = None) -> RunConfig:
    """A checked configuration from a TOML file (or an already parsed document, with paths relative to
    ``base``), with optional overrides {"material.0.E": 2e5, ...}."""
    from model import config

    if isinstance(source, dict):
        from model.config.overrides import apply

        raw = apply(source, overrides or {})
        return config.parse(raw, Path(base) if base is not None else Path("."))
    return config.load(source, overrides)


def run(configuration: RunConfig | str | Path, out: str | Path | None = None, comm: Any = None,
        overrides: dict[str, Any] | None = None) -> RunResult:
    """Run a configuration (a RunConfig, or a TOML file's path) into ``out`` (default: output.dir).

    Raises ConfigError before any solve on bad input, SolveFailed after writing the summary when the
    solver gives up (the results so far stay on disk).
    """
    from mpi4py import MPI

    from model import pipeline

    config = configuration if not isinstance(configuration, (str, Path)) else load_config(configuration, overrides)
    directory = Path(out) if out is not None else config.output.dir
    summary = pipeline.run(config, directory, comm if comm is not None else MPI.COMM_WORLD)
    return pipeline.RunResult(summary, directory)


__all__ = ["load_config", "run"]
