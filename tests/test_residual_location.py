"""A failed Newton step reports where its residual is largest (model.solvers.newton.residual_location).

St Venant-Kirchhoff in compression beyond its limit load (tests/test_cli.py failing_config): the unit cube
is pushed on its face xmax, held by symmetry conditions on xmin, ymin, zmin. The failed steps report the
largest residual, a free displacement dof of the loaded face, in the body; serially and on 2 ranks alike.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import ROOT, environment, example, run_raw, serial_only, write_toml

from model.errors import SolveFailed


def limit_load() -> dict[str, Any]:
    raw = example("uniaxial")
    raw["material"][0]["law"] = "stvk"
    raw["boundary"][3]["value"] = [-1.0e4, 0.0, 0.0]
    raw["loading"] = {"steps": 4, "max_cutbacks": 1}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return raw


def failed_steps(summary: dict[str, Any]) -> list[dict[str, Any]]:
    return [s for s in summary["steps"] if not s["converged"]]


def test_failed_steps_report_the_largest_residual(shared_tmp: Path, caplog: pytest.LogCaptureFixture) -> None:
    with pytest.raises(SolveFailed):
        run_raw(limit_load(), shared_tmp / "out")
    summary = json.loads((shared_tmp / "out" / "summary.json").read_text())
    failed = failed_steps(summary)
    assert failed
    for step in failed:
        where = step["largest_residual"]
        assert where["value"] > 0
        assert where["region"] == "body"
        assert "xmax" in where["boundary"].split(", ")
        assert where["point"][0] == pytest.approx(1.0)  # on the loaded face
        assert where["component"] in (0, 1, 2)
    for step in summary["steps"]:
        assert ("largest_residual" in step) == (not step["converged"])
    # the cut-back's warning says it too (rank 0 logs)
    from mpi4py import MPI

    if MPI.COMM_WORLD.rank == 0:
        warnings = [r.getMessage() for r in caplog.records if "cutting the increment back" in r.getMessage()]
        assert warnings and "largest residual" in warnings[0] and "on boundary 'xmax'" in warnings[0]


@serial_only
def test_two_ranks_report_the_same_location(tmp_path: Path) -> None:
    """Beyond the limit load the symmetric cube buckles one way or its mirror image, by round-off: a small
    transverse traction picks the way, so that the failed iterates (and their largest residuals) are the
    same problem's on 1 and 2 ranks."""
    raw = limit_load()
    raw["boundary"][3]["value"] = [-1.0e4, 200.0, 100.0]
    with pytest.raises(SolveFailed):
        run_raw(raw, tmp_path / "serial")
    config = write_toml(raw, tmp_path / "limit_load.toml")
    cmd = ["mpirun", "-n", "2", "--oversubscribe", sys.executable, "-m", "model", "run", str(config),
           "--out", str(tmp_path / "parallel")]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=environment(), cwd=ROOT, timeout=600)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    serial = failed_steps(json.loads((tmp_path / "serial" / "summary.json").read_text()))
    parallel = failed_steps(json.loads((tmp_path / "parallel" / "summary.json").read_text()))
    assert len(serial) == len(parallel)
    for s, p in zip(serial, parallel):
        a, b = s["largest_residual"], p["largest_residual"]
        assert a["value"] == pytest.approx(b["value"], rel=1e-8)
        assert a["point"] == pytest.approx(b["point"], abs=1e-12)  # dof coordinates: round-off per partition
        assert (a["component"], a["region"], a["boundary"]) == (b["component"], b["region"], b["boundary"])
