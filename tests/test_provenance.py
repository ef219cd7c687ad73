"""Provenance in summary.json: the resolved configuration (after overrides), the project's revision, the versions
of dolfinx, PETSc, UFL, basix, numpy and Python, the number of MPI ranks and the host's cores.

Each value is compared with what the test finds out on its own (git on the command line, the packages'
version attributes, /proc/self/status for the cores a process may use); collective on 1 or 2 ranks.
"""

from __future__ import annotations

import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import basix
import dolfinx
import numpy as np
import pytest
import ufl
from conftest import EXAMPLES, ROOT, environment, serial_only
from mpi4py import MPI
from petsc4py import PETSc

import model

UNIAXIAL = EXAMPLES / "uniaxial.toml"
SMALL = {"mesh.cells": [2, 2, 2], "loading.steps": 1, "material.0.E": 2.0e4, "output.png": False,
         "output.vtu": False, "solver.linear": "direct"}


def by_hand(raw: dict[str, Any]) -> dict[str, Any]:
    """The uniaxial example with SMALL applied by item assignment."""
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["loading"]["steps"] = 1
    raw["material"][0]["E"] = 2.0e4
    raw["output"].update(png=False, vtu=False)
    raw["solver"]["linear"] = "direct"
    return raw


def git_facts() -> tuple[str, bool] | None:
    """(commit, dirty) of the checkout by git's own commands, None without git or a checkout."""
    git = shutil.which("git")
    if git is None or not (ROOT / ".git").exists():
        return None
    head = subprocess.run([git, "-C", str(ROOT), "rev-parse", "--verify", "HEAD"], capture_output=True, text=True)
    if head.returncode != 0:
        return None
    clean = subprocess.run([git, "-C", str(ROOT), "diff", "--quiet", "HEAD", "--"], capture_output=True)
    return head.stdout.strip(), clean.returncode != 0


def allowed_cores() -> int | None:
    """The number of cores this process may run on, from /proc/self/status (Linux), e.g. "0-3,8" -> 5."""
    try:
        text = Path("/proc/self/status").read_text()
    except OSError:
        return None
    match = re.search(r"^Cpus_allowed_list:\s*(\S+)", text, re.M)
    if match is None:
        return None
    count = 0
    for item in match.group(1).split(","):
        low, _, high = item.partition("-")
        count += int(high or low) - int(low) + 1
    return count


def check_provenance(summary: dict[str, Any], ranks: int) -> None:
    versions = summary["versions"]
    assert versions["dolfinx"] == dolfinx.__version__
    assert versions["petsc"] == "{}.{}.{}".format(*PETSc.Sys.getVersion())
    assert versions["ufl"] == ufl.__version__ and versions["basix"] == basix.__version__
    assert versions["numpy"] == np.__version__
    assert versions["python"] == "{}.{}.{}".format(*sys.version_info[:3]) == platform.python_version()
    assert summary["ranks"] == ranks
    host = summary["host"]
    assert host["cpu_count"] == MPI.COMM_WORLD.bcast(os.cpu_count(), root=0) >= 1
    cores = MPI.COMM_WORLD.bcast(allowed_cores(), root=0)  # rank 0's, as recorded
    if cores is not None:
        assert host["cpu_affinity"] == cores
    assert 1 <= (host["cpu_affinity"] or 1) <= host["cpu_count"]
    facts = MPI.COMM_WORLD.bcast(git_facts() if MPI.COMM_WORLD.rank == 0 else None, root=0)
    if facts is None:
        assert "git_commit" not in versions
    else:
        commit, dirty = facts
        assert re.fullmatch(r"[0-9a-f]{40}", versions["git_commit"])
        assert (versions["git_commit"], versions["git_dirty"]) == (commit, dirty)
        assert versions["git_revision"] == commit + ("-dirty" if dirty else "")


def test_summary_records_provenance_and_the_resolved_config(shared_tmp: Path) -> None:
    comm = MPI.COMM_WORLD
    result = model.run(UNIAXIAL, out=shared_tmp / "run", overrides=SMALL)
    assert result.status == "completed" and len(result.summary["steps"]) == 1
    summary = json.loads((shared_tmp / "run" / "summary.json").read_text())  # what is on disk
    check_provenance(summary, comm.size)
    assert summary["config"] == by_hand(tomllib.loads(UNIAXIAL.read_text()))
    assert summary["cells"] == 6 * 2**3  # the overridden mesh was run


def test_a_config_naming_a_file_records_its_absolute_path() -> None:
    """examples/guccione_beam.toml's law "guccione_law.py:psi", relative to the file's folder, is recorded
    absolute; everything else as written."""
    path = EXAMPLES / "guccione_beam.toml"
    raw = tomllib.loads(path.read_text())
    law = raw["material"][0]["law"]
    assert law == "guccione_law.py:psi"
    config = model.load_config(path, {"loading.steps": 7})
    raw["material"][0]["law"] = f"{(EXAMPLES / 'guccione_law.py').resolve()}:psi"
    raw["loading"]["steps"] = 7
    assert config.document == raw


@serial_only
def test_command_line_sets_are_recorded(tmp_path: Path) -> None:
    out = tmp_path / "out"
    command = [sys.executable, "-m", "model", "run", str(UNIAXIAL), "--out", str(out)]
    for key, value in SMALL.items():
        text = json.dumps(value) if not isinstance(value, bool) else str(value).lower()
        command += ["--set", f"{key}={text}"]
    result = subprocess.run(command, cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"] == by_hand(tomllib.loads(UNIAXIAL.read_text()))
    check_provenance(summary, 1)


@serial_only
def test_two_ranks_from_the_command_line(tmp_path: Path) -> None:
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    out = tmp_path / "out"
    command = [mpirun, "-n", "2", "--oversubscribe", sys.executable, "-m", "model", "run", str(UNIAXIAL),
               "--out", str(out), "--set", "mesh.cells=[2, 2, 2]", "--set", "loading.steps=1",
               "--set", "output.png=false"]
    result = subprocess.run(command, cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ranks"] == 2
    assert summary["config"]["mesh"]["cells"] == [2, 2, 2] and summary["config"]["loading"]["steps"] == 1
