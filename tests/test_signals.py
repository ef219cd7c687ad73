"""SIGINT and SIGTERM survive gmsh and start-up (model.signals): a background run on a gmsh mesh (SIGINT ignored at
its start, as a shell starts a background job) stops on ``kill -INT`` after the step it is solving; SIGTERM during
start-up ends the command line with 143 and one line; a signal before the first step stops the pipeline at its
checks (after build: the output folder as it was; before the first step: summary.json "interrupted").

The command-line runs are subprocesses (serial run of the suite only); the pipeline checks run in this process.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from mpi4py import MPI

from model import pipeline
from model.config import parse
from model.signals import Interrupted
from tests.conftest import EXAMPLES, environment, serial_only, write_toml

#: SIGTERM's bit in /proc/PID/status SigCgt: set once the process has a handler of its own for it
_SIGTERM_CAUGHT = 1 << (signal.SIGTERM - 1)


def _cylinder(out: Path, steps: int) -> dict[str, Any]:
    """A gmsh-meshed run (the cylinder generator, 0.5 x 1, ~200 cells, P1 neo-Hookean), pulled at its top."""
    return {
        "mesh": {"generator": "cylinder", "radius": 0.5, "length": 1.0, "size": 0.35},
        "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
        "boundary": [{"on": "bottom", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                     {"on": "top", "type": "traction", "value": [0.0, 0.0, 2.0e3]}],
        "loading": {"steps": steps},
        "output": {"dir": str(out), "png": False, "vtu": False},
    }


def _converged(out: Path) -> int:
    try:
        steps = json.loads((out / "summary.json").read_text()).get("steps", [])
    except (OSError, ValueError):
        return 0
    return sum(1 for s in steps if s.get("converged"))


def _caught(pid: int) -> int:
    """The signal mask of the handlers process ``pid`` installed (SigCgt), 0 once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0
    return int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)


@serial_only
def test_sigint_stops_a_background_gmsh_run(tmp_path: Path) -> None:
    """SIGINT ignored at start (a background job), gmsh imported, initialised and finalised: ``kill -INT`` after
    the first step gives exit 130, one line on stderr and summary.json "interrupted" (before: the run ignored the
    signal and completed)."""
    out = tmp_path / "out"
    config = write_toml(_cylinder(out, 40), tmp_path / "run.toml")
    process = subprocess.Popen([sys.executable, "-m", "model", "run", str(config)], env=environment(), text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    deadline = time.monotonic() + 120
    while _converged(out) < 1:
        assert process.poll() is None, f"the run ended before the signal: {process.communicate()}"
        assert time.monotonic() < deadline
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr[-3000:]
    assert stderr.splitlines() == [stderr.strip()] and "interrupted by SIGINT" in stderr, stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["signal"] == "SIGINT"
    assert 1 <= summary["last_completed_step"] < 40


@serial_only
def test_sigterm_during_startup_is_exit_143_and_one_line(tmp_path: Path) -> None:
    """SIGTERM as soon as the command line has its handlers (before numpy, mpi4py, dolfinx and gmsh load): exit 143,
    one line, no traceback, nothing written."""
    out = tmp_path / "out"
    config = write_toml(_cylinder(out, 2), tmp_path / "run.toml")
    process = subprocess.Popen([sys.executable, "-m", "model", "run", str(config)], env=environment(), text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while not _caught(process.pid) & _SIGTERM_CAUGHT:
        assert process.poll() is None, f"the run ended before the signal: {process.communicate()}"
        assert time.monotonic() < deadline
        time.sleep(0.001)
    loaded = Path(f"/proc/{process.pid}/maps").read_text()
    process.send_signal(signal.SIGTERM)
    stdout, stderr = process.communicate(timeout=60)
    assert "dolfinx" not in loaded, "the command line had no SIGTERM handler before dolfinx loaded"
    assert process.returncode == 143, stderr[-3000:]
    assert stderr == "error: interrupted by SIGTERM\n", stderr
    assert not out.exists()


def _signalled(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    """Every rank sends itself SIGTERM when ``pipeline.<name>`` returns (the run's flag notes it)."""
    original = getattr(pipeline, name)

    def wrapped(*args: Any, **kwargs: Any) -> Any:
        result = original(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGTERM)
        return result

    monkeypatch.setattr(pipeline, name, wrapped)


def _box(out: Path) -> Any:
    raw = {
        "mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [1, 1, 1]},
        "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
        "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                     {"on": "xmax", "type": "traction", "value": [1.0e3, 0.0, 0.0]}],
        "loading": {"steps": 2},
        "output": {"dir": str(out), "png": False, "vtu": False},
    }
    return parse(raw, EXAMPLES)


def test_signal_during_build_leaves_the_folder_as_it_was(shared_tmp: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM while the mesh, fields and forms are made: Interrupted at the check after build, the output folder
    (an earlier run's summary.json) untouched, the caller's handler back."""
    comm = MPI.COMM_WORLD
    out = shared_tmp / "out"
    if comm.rank == 0:
        out.mkdir()
        (out / "summary.json").write_text('{"status": "completed", "steps": []}')
    comm.barrier()
    _signalled(monkeypatch, "build")
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Interrupted, match="^interrupted by SIGTERM before the solve started") as caught:
        pipeline.run(_box(out), out, comm)
    assert caught.value.signum == signal.SIGTERM
    assert signal.getsignal(signal.SIGTERM) == before
    assert json.loads((out / "summary.json").read_text())["status"] == "completed"


def test_signal_before_the_first_step_says_interrupted(shared_tmp: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM while the solver is set up (the folder is the run's by then): Interrupted before the first step,
    summary.json "interrupted" with no step."""
    out = shared_tmp / "out"
    _signalled(monkeypatch, "make_solver")
    with pytest.raises(Interrupted, match="^interrupted by SIGTERM before the first step"):
        pipeline.run(_box(out), out, MPI.COMM_WORLD)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["signal"] == "SIGTERM"
    assert summary["last_completed_step"] == 0 and summary["steps"] == []
