"""A write the system refuses ends a run with one line naming the path (OutputFailed, a SolveFailed: exit 1), on
every rank at once (most writes are rank 0's: the others must not wait in the next solve), keeping what was
written: summary.json "failed" with the reason, the XDMF series readable up to the last complete step. An output
path that is a file is bad input (ConfigError) before anything is deleted or solved. Serially and under
mpirun -n 2."""

from __future__ import annotations

import errno
import json
from pathlib import Path
from typing import Any

import pytest
from conftest import run_raw
from mpi4py import MPI

from model.errors import ConfigError, OutputFailed


def bar(**output: Any) -> dict[str, Any]:
    return {"mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [2, 2, 2]},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
            "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                         {"on": "xmax", "type": "traction", "value": [500.0, 0.0, 0.0]}],
            "loading": {"steps": 3},
            "output": {"xdmf": True, "vtu": True, "png": False, **output}}


def test_an_output_path_that_is_a_file_is_bad_input(shared_tmp: Path) -> None:
    taken = shared_tmp / "taken"
    if MPI.COMM_WORLD.rank == 0:
        taken.write_text("mine")
    MPI.COMM_WORLD.barrier()
    with pytest.raises(ConfigError, match=r"^output.dir \(--out\): .*taken is a file, not a folder"):
        run_raw(bar(), taken)
    with pytest.raises(ConfigError, match=r"^output.dir \(--out\): .*taken is a file, not a folder"):
        run_raw(bar(), taken / "out" / "deeper")
    assert taken.read_text() == "mine"
    # a folder the system will not make (even for root: /proc takes no new entries): one line naming it, exit 1
    with pytest.raises(OutputFailed, match=r"^/proc/softtissue: cannot write the results there \(No such file"):
        run_raw(bar(), Path("/proc/softtissue/out"))


def test_a_full_disk_mid_run_fails_on_every_rank_and_keeps_the_steps(shared_tmp: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    written = []
    import meshio

    original = meshio.Mesh.write

    def filling(mesh: Any, path: Path, *args: Any, **kwargs: Any) -> None:  # rank 0 writes VTU: step 2 finds no space
        if written:
            Path(path).write_bytes(b"half")
            raise OSError(errno.ENOSPC, "No space left on device")
        written.append(path)
        original(mesh, path, *args, **kwargs)

    monkeypatch.setattr(meshio.Mesh, "write", filling)
    with pytest.raises(OutputFailed) as caught:
        run_raw(bar(), shared_tmp)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"{shared_tmp / 'step_0002.vtu'}: cannot write (No space left on device)"), message
    summary = json.loads((shared_tmp / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["failure"] == message
    assert [s["converged"] for s in summary["steps"]] == [True]
    assert not (shared_tmp / ".space_reserve").exists() and not (shared_tmp / "step_0002.vtu").exists()

    series = meshio.xdmf.TimeSeriesReader(str(shared_tmp / "results.xdmf"))
    series.read_points_cells()
    assert series.num_steps == 2  # the second step's XDMF part was complete before its VTU failed
    for k in range(series.num_steps):
        series.read_data(k)
