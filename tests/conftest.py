"""Shared fixtures. Tests run serially and under ``mpirun -n 2 python -m pytest``: every test is
collective (all ranks run it), output directories are rank 0's, broadcast."""

from __future__ import annotations

import copy
import json
import os
import tomllib
from pathlib import Path
from typing import Any

import pytest
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def _is_membrane_run(path: Path) -> bool:
    return "membrane" in tomllib.loads(path.read_text())


#: examples/*.toml that are solid runs (model.config.RunConfig); MEMBRANE_EXAMPLES: those with a [membrane]
#: table, membrane runs (model.config.membrane.MembraneRunConfig, docs/membrane.schema.json)
RUN_EXAMPLES = [p for p in sorted(EXAMPLES.glob("*.toml")) if not _is_membrane_run(p)]
MEMBRANE_EXAMPLES = [p for p in sorted(EXAMPLES.glob("*.toml")) if _is_membrane_run(p)]

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
    from model.pipeline import run

    return run(parse(raw, EXAMPLES), out)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {value!r} as TOML")


def write_toml(raw: dict[str, Any], path: Path) -> Path:
    """A configuration dict (tables of scalars, arrays and inline tables; arrays of tables) as a TOML file."""
    lines: list[str] = []
    for section, body in raw.items():
        for table in body if isinstance(body, list) else [body]:
            lines.append(f"[[{section}]]" if isinstance(body, list) else f"[{section}]")
            lines += [f"{key} = {_toml_value(value)}" for key, value in table.items()]
    path.write_text("\n".join(lines) + "\n")
    assert tomllib.loads(path.read_text()) == raw
    return path


def environment() -> dict[str, str]:
    """This environment for a child run: the project on PYTHONPATH, one thread, mpirun allowed as root.

    Without the variables an MPI initialisation leaves in the environment (OMPI_*, PMIX_*, OPAL_*, PRTE_*):
    a pytest-xdist worker inherits them from the controller, whose conftest initialised MPI, and an mpirun
    started with them fails at once, silently."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_", "OPAL_", "PRTE_"))}
    env.update(PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
               OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1")
    return env


@pytest.fixture
def compiles(monkeypatch) -> list[str]:  # noqa: ANN001
    """The module names FFCx compiled (cache misses: ffcx.codegeneration.jit._compile_objects) while the test
    runs (tests/test_compile_once.py, tests/test_parameter_curves.py)."""
    import ffcx.codegeneration.jit as ffcx_jit

    names: list[str] = []
    original = ffcx_jit._compile_objects

    def counting(decl, ufl_objects, object_names, module_name, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        names.append(module_name)
        return original(decl, ufl_objects, object_names, module_name, *args, **kwargs)

    monkeypatch.setattr(ffcx_jit, "_compile_objects", counting)
    return names
