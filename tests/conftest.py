"""Shared fixtures. Tests run serially and under ``mpirun -n 2 python -m pytest``: every test is
collective (all ranks run it), output directories are rank 0's, broadcast."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path
from typing import Any

import pytest
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

#: for tests that start processes of their own (CLI, mpirun): only in the serial run
serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="starts its own processes; serial run only")


@pytest.fixture
def comm() -> MPI.Comm:
    return MPI.COMM_WORLD


@pytest.fixture
def shared_tmp(tmp_path: Path) -> Path:
    """A temporary directory that is the same on every rank (rank 0's)."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


def example(name: str) -> dict[str, Any]:
    """A parsed example configuration (a fresh copy) from examples/NAME.toml."""
    return copy.deepcopy(tomllib.loads((EXAMPLES / f"{name}.toml").read_text()))


def run_raw(raw: dict[str, Any], out: Path) -> dict[str, Any]:
    """Check and run a configuration given as a dict; returns the summary."""
    from model.config import parse
    from model.run import run

    return run(parse(raw, EXAMPLES), out)
