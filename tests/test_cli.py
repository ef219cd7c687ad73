"""The command line ``python -m model run CONFIG [--out DIR]`` in subprocesses (serial run of the suite only).

- the contract example runs: progress lines, summary.json with the contract's keys,
  XDMF + HDF5, VTU files with u / J / cauchy_stress / von_mises, a PNG;
- a solve that cannot succeed exits 1 with a one-line SNES error and keeps summary.json;
- the same run under ``mpirun -n 2`` gives the serial probes and reactions to 1e-10.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import EXAMPLES, ROOT, environment, example, serial_only, write_toml

pytestmark = serial_only

PROGRESS = re.compile(r"^step\s+(\d+)\s+load\s+([0-9.]+)\s+newton\s+(\d+)\s+\|R\|\s+(\S+)\s+(.*)$")
STEP_KEYS = {"load_factor", "newton_iterations", "converged", "snes_reason", "residual_norm", "strain_energy",
             "load_potential", "total_potential", "probes", "reactions"}


def run_cli(config: Path, out: Path, ranks: int = 1) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "model", "run", str(config), "--out", str(out)]
    if ranks > 1:
        mpirun = shutil.which("mpirun")
        if mpirun is None:
            pytest.skip("mpirun not found")
        command = [mpirun, "-n", str(ranks), "--oversubscribe", *command]
    return subprocess.run(command, cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess, Path]:
    """The contract example run once, serially, for the tests below."""
    out = tmp_path_factory.mktemp("cli") / "uniaxial"
    return run_cli(EXAMPLES / "uniaxial.toml", out), out


def test_run_prints_progress(serial_run: tuple[subprocess.CompletedProcess, Path]) -> None:
    result, out = serial_run
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((out / "summary.json").read_text())
    progress = [PROGRESS.match(line) for line in result.stdout.splitlines() if line.startswith("step")]
    assert all(progress) and len(progress) == len(summary["steps"]) == 5, result.stdout
    for match, step in zip(progress, summary["steps"], strict=True):
        _, load, newton, residual, status = match.groups()
        assert float(load) == pytest.approx(step["load_factor"], abs=1e-4)
        assert int(newton) == step["newton_iterations"]
        assert float(residual) == pytest.approx(step["residual_norm"], rel=1e-3)
        assert status == "converged"
    assert [float(m.group(2)) for m in progress] == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])
    tail = result.stdout.splitlines()[-8:]  # the human summary: status, probes and reactions with units, the folder
    assert any(line.startswith("done: 5 steps (completed), 375 dofs") for line in tail), tail
    assert any(line.startswith("  probe corner: u = (") and line.endswith(") m") for line in tail), tail
    assert any(line.startswith("  reaction of xmin: F = (-2000,") and line.endswith(") N") for line in tail), tail
    assert tail[-1].startswith(f"results in {out}: summary.json"), tail


def test_run_writes_the_contract_summary(serial_run: tuple[subprocess.CompletedProcess, Path]) -> None:
    result, out = serial_run
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert {"dofs", "cells", "ranks", "wall_time_s", "steps"} <= set(summary)
    assert (summary["dofs"], summary["cells"], summary["ranks"]) == (375, 384, 1)
    assert summary["status"] == "completed" and summary["wall_time_s"] > 0
    for step in summary["steps"]:
        assert STEP_KEYS <= set(step)
        assert step["converged"] is True and step["snes_reason"] > 0 and step["newton_iterations"] >= 1
        assert set(step["probes"]) == {"corner"} and len(step["probes"]["corner"]) == 3
        assert set(step["reactions"]) == {"xmin", "ymin", "zmin"}
        assert step["strain_energy"] > 0 > step["total_potential"]
        # equilibrium: xmin carries the whole traction 2e3 * load factor on a unit face
        assert step["reactions"]["xmin"][0] == pytest.approx(-2.0e3 * step["load_factor"], rel=1e-8)
    assert summary["units"]["stress"] == "Pa" and summary["units"]["length"] == "m"
    energies = [step["strain_energy"] for step in summary["steps"]]
    assert energies == sorted(energies)


def test_run_writes_xdmf_vtu_png(serial_run: tuple[subprocess.CompletedProcess, Path]) -> None:
    result, out = serial_run
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    # XDMF time series of u, J, cauchy_stress, von_mises at the five load factors, data in results.h5
    root = ET.parse(out / "results.xdmf").getroot()
    series = {grid.get("Name"): [float(t.get("Value")) for t in grid.iter("Time")]
              for grid in root.iter("Grid") if grid.get("CollectionType") == "Temporal"}
    assert set(series) == {"u", "J", "cauchy_stress", "von_mises"}
    for times in series.values():
        assert times == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])
    assert (out / "results.h5").read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"
    # the last VTU: u at the corner is the probe; the homogeneous state gives J and the Cauchy stress
    mesh = meshio.read(out / "step_0005.vtu")
    assert {"u"} <= set(mesh.point_data) and {"J", "cauchy_stress", "von_mises"} <= set(mesh.cell_data)
    u = mesh.point_data["u"]
    assert u.shape == (125, 3)
    corner = np.flatnonzero(np.all(np.isclose(mesh.points, 1.0), axis=1))
    probe = np.array(summary["steps"][-1]["probes"]["corner"])
    np.testing.assert_allclose(u[corner[0]], probe, rtol=1e-12, atol=1e-14)
    stretch = 1.0 + probe  # (l1, l2, l2)
    J = np.asarray(mesh.cell_data["J"][0]).reshape(-1)
    sigma = np.asarray(mesh.cell_data["cauchy_stress"][0]).reshape(-1, 3, 3)
    von_mises = np.asarray(mesh.cell_data["von_mises"][0]).reshape(-1)
    assert J.shape == von_mises.shape == (384,)
    np.testing.assert_allclose(J, np.prod(stretch), rtol=1e-8)
    sigma_xx = 2.0e3 / stretch[1] ** 2  # P_xx l1 / J: the traction over the deformed area
    expected = np.zeros((3, 3))
    expected[0, 0] = sigma_xx
    np.testing.assert_allclose(sigma, np.broadcast_to(expected, sigma.shape), atol=1e-6 * sigma_xx)
    np.testing.assert_allclose(von_mises, sigma_xx, rtol=1e-8)
    for k in range(1, 5):
        assert (out / f"step_{k:04d}.vtu").is_file()
    png = (out / "deformed.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def failing_config(tmp_path: Path) -> Path:
    """St Venant-Kirchhoff in compression has a limit load (at about E/5): beyond it there is no solution.
    Loading to 1e4 (E = 1e4) in four steps converges at first, then SNES fails for every cut-back."""
    raw = example("uniaxial")
    raw["material"][0]["law"] = "stvk"
    raw["boundary"][3]["value"] = [-1.0e4, 0.0, 0.0]
    raw["loading"] = {"steps": 4, "max_cutbacks": 1}
    raw["output"] = {"dir": str(tmp_path / "unused"), "png": False}  # --out wins
    return write_toml(raw, tmp_path / "limit_load.toml")


def test_failing_solve_exits_1_and_keeps_the_summary(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = run_cli(failing_config(tmp_path), out)
    assert result.returncode == 1, result.stdout + result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, result.stderr
    assert "Traceback" not in result.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    steps = summary["steps"]
    failed = [s for s in steps if not s["converged"]]
    done = [s for s in steps if s["converged"]]
    assert done and failed and not steps[-1]["converged"]
    for step in failed:
        assert step["snes_reason"] < 0
        assert "probes" not in step
    for step in done:
        assert step["snes_reason"] > 0 and STEP_KEYS <= set(step)
    # the error line names SNES and its converged reason (number and name) of the last attempt
    last = steps[-1]
    error = errors[0]
    assert "SNES" in error and "reason" in error
    assert f"reason {last['snes_reason']}" in error and last["snes_reason_name"] in error
    assert f"{last['load_factor']:.6g}" in error
    # the real reason and the keys that change it: one cut-back allowed stops it at 0.125, short of the limit load
    # (near 0.2), where the tangent is still stable along the load (the stability report says so)
    assert "loading.max_cutbacks" in error and "loading.steps" in error and "stopped at 0.125" in error
    assert not summary["stability"]["unstable"] and summary["stability"]["load_factor"] == 0.125
    assert summary["failure"] in error
    # progress lines report the failed attempts too; the converged states were written
    assert sum("FAILED" in line for line in result.stdout.splitlines()) == len(failed)
    assert (out / f"step_{len(done):04d}.vtu").is_file()
    assert not (tmp_path / "unused").exists()


def test_mpi_run_matches_serial(serial_run: tuple[subprocess.CompletedProcess, Path], tmp_path: Path) -> None:
    serial, serial_out = serial_run
    assert serial.returncode == 0, serial.stderr
    out = tmp_path / "mpi"
    result = run_cli(EXAMPLES / "uniaxial.toml", out, ranks=2)
    assert result.returncode == 0, result.stdout + result.stderr
    # rank 0 alone prints: one progress line per step
    assert sum(1 for line in result.stdout.splitlines() if PROGRESS.match(line)) == 5, result.stdout
    one = json.loads((serial_out / "summary.json").read_text())
    two = json.loads((out / "summary.json").read_text())
    assert two["ranks"] == 2 and (two["dofs"], two["cells"]) == (one["dofs"], one["cells"])
    assert len(two["steps"]) == len(one["steps"])
    for a, b in zip(one["steps"], two["steps"], strict=True):
        assert b["load_factor"] == a["load_factor"] and b["converged"]
        for kind in ("probes", "reactions"):
            assert set(b[kind]) == set(a[kind])
            scale = max(np.abs(v).max() for v in a[kind].values())
            for name in a[kind]:
                np.testing.assert_allclose(b[kind][name], a[kind][name], rtol=1e-10, atol=1e-10 * scale,
                                           err_msg=f"{kind} {name} at load factor {a['load_factor']}")
        for key in ("strain_energy", "load_potential", "total_potential"):
            assert b[key] == pytest.approx(a[key], rel=1e-10), key
    mesh = meshio.read(out / "step_0005.vtu")  # gathered on rank 0: the whole mesh
    assert mesh.points.shape == (125, 3) and len(mesh.cells[0].data) == 384


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(actions[0].choices) if actions else {}


def test_every_command_explains_itself() -> None:
    """Every command's help renders with a description, examples and (where a command has them) exit codes; the
    defaults are shown; verify emit needs neither --samples nor --seed."""
    from model.cli import _parser

    top = _parser("softtissue", None)
    commands = {"": top}
    for name, sub in _subparsers(top).items():
        commands[name] = sub
        commands.update({f"{name} {n}": s for n, s in _subparsers(sub).items()})
    assert set(commands) >= {"", "run", "verify", "verify emit", "verify check", "verify seeds", "verify element",
                             "sweep", "converge", "calibrate", "schema"}
    for name, parser in commands.items():
        text = parser.format_help()
        assert "examples:" in text and len(parser.description or "") > 40, name
    for name in ("", "run"):  # whole sentences (the top-level description was its docstring's first line, cut)
        assert commands[name].description.rstrip().endswith("."), commands[name].description
    assert "exit codes:" in commands["run"].format_help() and "mpirun -n 2" in commands["run"].format_help()
    emit = commands["verify emit"]
    assert "(default: 1000)" in emit.format_help() and "(default: 0)" in emit.format_help()
    args = emit.parse_args(["--material", "neo_hookean", "--out", "ref.npz"])
    assert (args.samples, args.seed) == (1000, 0)
    assert "(default: 50)" in commands["calibrate"].format_help()
