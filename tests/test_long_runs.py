"""Long runs (issue 12, item 4): SIGTERM / SIGINT end a run cleanly (exit 143 / 130, summary.json
"interrupted"), the XDMF time series opens with meshio and pyvista after SIGKILL with every completed step,
and ``--restart DIR`` reaches the final probes of an uninterrupted run to 1e-10 (quasi-static and dynamic,
and from a run on 2 ranks restarted on 1). A restart of another problem (material.0.E, mesh.cells changed) is
refused naming the key before anything in the folder is touched; output.*, solver.* and loading.max_cutbacks may
change (model.config.restart). A checkpoint written on 1 rank reads on 2 and one written on 2 on 1, on a bar whose
partitions are shorter than it.

The runs are subprocesses (serial_only); each is stopped once summary.json shows two converged steps. The
checkpoint and XDMF writers are also tested in-process (collective, on 1 and 2 ranks) against functions
interpolated from formulas evaluated here with numpy.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import meshio
import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI

import model
from model import compat, pipeline
from model.config.restart import RULE, file_digests, same_problem
from model.errors import ConfigError
from model.output.checkpoint import read_checkpoint, remove_checkpoint, write_checkpoint
from model.output.writer import XdmfSeries
from tests.conftest import EXAMPLES, ROOT, environment, serial_only, write_toml

ENV = {**environment(), "PYTHONPATH": str(ROOT), "OMPI_MCA_rmaps_base_oversubscribe": "1"}


def _uniaxial(steps: int) -> dict[str, Any]:
    raw = tomllib.loads((EXAMPLES / "uniaxial.toml").read_text())
    raw["loading"]["steps"] = steps
    return raw


def _dynamic() -> dict[str, Any]:
    """The uniaxial cube (3^3 cells), loaded over 40 generalized-alpha time steps."""
    raw = _uniaxial(5)
    raw["mesh"]["cells"] = [3, 3, 3]
    raw["material"][0]["density"] = 1.0
    raw["dynamics"] = {"scheme": "generalized_alpha", "dt": 0.002, "end_time": 0.08, "rayleigh": [1.0, 0.0]}
    return raw


def _write_config(raw: dict[str, Any], folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    raw = {**raw, "output": {"dir": str(folder / "out"), "png": False}}
    return write_toml(raw, folder / "run.toml")


def _command(config: Path, *args: str, ranks: int = 1) -> list[str]:
    command = [sys.executable, "-m", "model", "run", str(config), *args]
    return ["mpirun", "-n", str(ranks), *command] if ranks > 1 else command


def _converged(out: Path) -> int:
    try:
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return 0
    return sum(1 for s in summary.get("steps", []) if s.get("converged"))


def _descendants(pid: int) -> list[int]:
    """The processes below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def _interrupt(config: Path, out: Path, signum: int, ranks: int = 1,
               to_ranks: bool = False) -> subprocess.CompletedProcess:
    """Start the run, send ``signum`` once summary.json shows 2 converged steps, wait for the end.
    ``to_ranks``: signal the ranks (the python processes below mpirun, as a batch system's scancel does)
    instead of mpirun."""
    process = subprocess.Popen(_command(config, "--out", str(out), ranks=ranks), env=ENV, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 300
    while _converged(out) < 2:
        assert process.poll() is None, f"the run ended before the signal: {process.communicate()}"
        assert time.monotonic() < deadline
        time.sleep(0.02)
    if to_ranks:
        for pid in _descendants(process.pid):
            if "model" in Path(f"/proc/{pid}/cmdline").read_text(errors="replace"):
                os.kill(pid, signum)
    else:
        process.send_signal(signum)
    stdout, stderr = process.communicate(timeout=300)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


def _run(config: Path, *args: str) -> dict[str, Any]:
    result = subprocess.run(_command(config, *args), env=ENV, text=True, capture_output=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    out = Path(args[-1])
    return json.loads((out / "summary.json").read_text())


def _summary(out: Path) -> dict[str, Any]:
    return json.loads((out / "summary.json").read_text())


def _xdmf_meshio(path: Path) -> tuple[np.ndarray, list[float], list[np.ndarray]]:
    """Points, times and u per step of an XDMF time series, read by meshio's TimeSeriesReader from the "u"
    collection (meshio reads the last collection: it is checked to have the same times)."""
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, _ = reader.read_points_cells()
        times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
    # meshio reads only the domain's last collection; read "u" by keeping only that one
    import xml.etree.ElementTree as ET

    tree = ET.parse(path)
    domain = tree.getroot().find("Domain")
    for grid in list(domain):
        if grid.get("GridType") == "Collection" and grid.get("Name") != "u":
            domain.remove(grid)
    only_u = path.with_name("only_u.xdmf")
    tree.write(only_u)
    with meshio.xdmf.TimeSeriesReader(only_u) as reader:
        reader.read_points_cells()
        steps = [reader.read_data(k) for k in range(reader.num_steps)]
    only_u.unlink()
    assert [t for t, _, _ in steps] == times
    return points, times, [p["u"] for _, p, _ in steps]


def _xdmf_pyvista(path: Path) -> tuple[list[float], np.ndarray, np.ndarray]:
    """Times, and the points and u (float32) of the last step, read by VTK's XDMF reader through pyvista."""
    import pyvista

    reader = pyvista.get_reader(str(path))
    times = list(reader.time_values)
    reader.set_active_time_value(times[-1])
    block = reader.read()["u"]
    return times, np.asarray(block.points), np.asarray(block.point_data["u"])


def _corner(points: np.ndarray) -> int:
    return int(np.flatnonzero(np.all(np.isclose(points, 1.0), axis=1))[0])


def _check_series(out: Path, converged: list[dict[str, Any]], at_least: bool = False) -> None:
    """The XDMF holds every converged step of the summary (its load factor or time as time, u at the corner = the
    corner probe), read with meshio and with pyvista. ``at_least``: it may hold one more (SIGKILL between
    the step's XDMF and the summary)."""
    points, times, u = _xdmf_meshio(out / "results.xdmf")
    factors = [s.get("time", s["load_factor"]) for s in converged]  # the XDMF time: t in a dynamic run
    assert len(times) == len(factors) or (at_least and len(times) == len(factors) + 1)
    np.testing.assert_allclose(times[: len(factors)], factors, rtol=1e-12)
    corner = _corner(points)
    for step, values in zip(converged, u):
        np.testing.assert_allclose(values[corner], step["probes"]["corner"], rtol=1e-10, atol=1e-14)
    pv_times, pv_points, pv_u = _xdmf_pyvista(out / "results.xdmf")
    np.testing.assert_allclose(pv_times, times, rtol=1e-12)
    if len(times) == len(factors):
        # VTK's reader gives float32 (the DataItems have no Precision)
        np.testing.assert_allclose(pv_u[_corner(pv_points)], converged[-1]["probes"]["corner"], rtol=1e-6,
                                   atol=1e-9)


@serial_only
@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signal_ends_the_run_cleanly(tmp_path: Path, signum: int, code: int) -> None:
    config = _write_config(_uniaxial(60), tmp_path)
    out = tmp_path / "out"
    result = _interrupt(config, out, signum)
    assert result.returncode == code, result.stderr[-3000:]
    summary = _summary(out)
    converged = [s for s in summary["steps"] if s["converged"]]
    assert summary["status"] == "interrupted" and summary["signal"] == signal.Signals(signum).name
    assert 2 <= len(converged) < 60 and summary["last_completed_step"] == len(converged)
    assert summary["checkpoint"]["step"] == len(converged)
    assert f"interrupted by {signal.Signals(signum).name}" in result.stderr
    _check_series(out, converged)
    listed = set(summary["files"])
    assert {p.name for p in out.iterdir()} == listed  # no stray temporary files, every file accounted for


@serial_only
def test_sigkill_keeps_every_completed_step_and_restarts(tmp_path: Path) -> None:
    config = _write_config(_uniaxial(60), tmp_path)
    out = tmp_path / "out"
    result = _interrupt(config, out, signal.SIGKILL)
    assert result.returncode == -signal.SIGKILL
    summary = _summary(out)
    assert summary["status"] == "running"
    converged = [s for s in summary["steps"] if s["converged"]]
    assert len(converged) >= 2
    _check_series(out, converged, at_least=True)
    # the checkpoint summary.json names exists, and the restart from it reaches the uninterrupted answer
    restarted = _run(config, "--restart", str(out))
    reference = _run(config, "--out", str(tmp_path / "reference"))
    np.testing.assert_allclose(_final_probes(restarted), _final_probes(reference), rtol=0, atol=1e-10)
    _check_series(out, [s for s in restarted["steps"] if s["converged"]])


def _final_probes(summary: dict[str, Any]) -> np.ndarray:
    return np.array(summary["steps"][-1]["probes"]["corner"])


@serial_only
@pytest.mark.parametrize("kind", ["quasi_static", "dynamic"])
def test_restart_reaches_the_uninterrupted_answer(tmp_path: Path, kind: str) -> None:
    raw = _uniaxial(40) if kind == "quasi_static" else _dynamic()
    config = _write_config(raw, tmp_path)
    reference = _run(config, "--out", str(tmp_path / "reference"))
    out = tmp_path / "out"
    result = _interrupt(config, out, signal.SIGTERM)
    assert result.returncode == 143, result.stderr[-3000:]
    stopped = _summary(out)["last_completed_step"]
    summary = _run(config, "--restart", str(out))
    assert summary["status"] == "completed"
    key = "time" if kind == "dynamic" else "load_factor"
    assert summary["restarts"] == [{"from_step": stopped, key: pytest.approx(reference["steps"][stopped - 1][key],
                                                                             rel=1e-14)}]
    assert len(summary["steps"]) == len(reference["steps"])
    np.testing.assert_allclose(_final_probes(summary), _final_probes(reference), rtol=0, atol=1e-10)
    for mine, theirs in zip(summary["steps"], reference["steps"]):
        assert mine["load_factor"] == pytest.approx(theirs["load_factor"], rel=1e-14)
        np.testing.assert_allclose(mine["probes"]["corner"], theirs["probes"]["corner"], atol=1e-10)
        if kind == "dynamic":
            assert mine["kinetic_energy"] == pytest.approx(theirs["kinetic_energy"], rel=1e-8, abs=1e-14)
    _check_series(out, [s for s in summary["steps"] if s["converged"]])


@serial_only
def test_restart_of_an_unstarted_folder_is_a_one_line_error(tmp_path: Path) -> None:
    config = _write_config(_uniaxial(3), tmp_path)
    result = subprocess.run(_command(config, "--restart", str(tmp_path / "nothing")), env=ENV, text=True,
                            capture_output=True, timeout=300)
    assert result.returncode == 2
    assert result.stderr.startswith("error: --restart ") and result.stderr.count("\n") == 1


@serial_only
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="no mpirun")
def test_sigterm_under_mpirun_then_restart_on_one_rank(tmp_path: Path) -> None:
    """SIGTERM to both ranks, as a batch system's scancel sends it (mpirun's own forwarding differs: Open MPI
    4.1 forwards it but SIGKILLs the ranks 1 s later, and once in this suite the run went on to completion;
    Open MPI 5 kills the ranks at once): they stop after the same step; the restart on 1 rank (another
    partition) reaches the serial answer."""
    config = _write_config(_uniaxial(40), tmp_path)
    out = tmp_path / "out"
    result = _interrupt(config, out, signal.SIGTERM, ranks=2, to_ranks=True)
    assert result.returncode != 0
    summary = _summary(out)
    assert summary["status"] == "interrupted" and summary["ranks"] == 2
    converged = [s for s in summary["steps"] if s["converged"]]
    _check_series(out, converged)
    reference = _run(config, "--out", str(tmp_path / "reference"))
    restarted = _run(config, "--restart", str(out))
    np.testing.assert_allclose(_final_probes(restarted), _final_probes(reference), rtol=0, atol=1e-10)


@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The uniaxial cube (3^3 cells, 20 steps) stopped by SIGTERM after 2 or more converged steps: (its config,
    its folder). Shared by the restart-check tests below, which must leave the folder as it is."""
    folder = tmp_path_factory.mktemp("stopped")
    raw = _uniaxial(20)
    raw["mesh"]["cells"] = [3, 3, 3]
    config = _write_config(raw, folder)
    result = _interrupt(config, folder / "out", signal.SIGTERM)
    assert result.returncode == 143, result.stderr[-3000:]
    return config, folder / "out"


def _snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    return {str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns) for p in folder.rglob("*")
            if p.is_file()}


@serial_only
def test_restart_of_another_problem_is_refused_and_touches_nothing(stopped_run: tuple[Path, Path]) -> None:
    """A restart whose configuration changes a key that defines the problem: exit 2 with one line naming the key
    (also when an allowed key changes too), and the folder is as it was (every file's bytes and time). A changed
    mesh likewise (model.pipeline.run, in-process: the check comes before the mesh is built)."""
    config, out = stopped_run
    before = _snapshot(out)
    result = subprocess.run(_command(config, "--restart", str(out), "--set", "output.vtu=false", "--set",
                                     "material.0.E=2e6"), env=ENV, text=True, capture_output=True, timeout=300)
    assert result.returncode == 2, result.stderr[-3000:]
    assert result.stderr == (f"error: --restart {out}: material.0.E is 2000000.0 here, 10000.0 in the run being "
                             f"continued; {RULE}\n")
    assert _snapshot(out) == before
    changed = model.load_config(config, overrides={"mesh.cells": [4, 3, 3]})
    with pytest.raises(ConfigError, match=r"^--restart .*: mesh\.cells is \[4, 3, 3\] here, \[3, 3, 3\] in the run "
                                          r"being continued; a restart continues the same problem \(only output"):
        pipeline.run(changed, out, restart=True)
    assert _snapshot(out) == before


@serial_only
def test_restart_may_change_output_solver_and_max_cutbacks(stopped_run: tuple[Path, Path], tmp_path: Path) -> None:
    """Output, solver options and loading.max_cutbacks may change: the restart goes on to load factor 1."""
    config, stopped = stopped_run
    out = tmp_path / "out"
    shutil.copytree(stopped, out)
    summary = _run(config, "--set", "output.vtu=false", "--set", "solver.petsc_options.snes_rtol=1e-10",
                   "--set", "loading.max_cutbacks=3", "--restart", str(out))
    assert summary["status"] == "completed" and summary["steps"][-1]["load_factor"] == 1.0
    assert summary["restarts"][0]["from_step"] == _summary(stopped)["last_completed_step"]
    assert summary["config"]["solver"]["petsc_options"]["snes_rtol"] == 1e-10
    assert summary["checkpoint"]["problem"] == {"files": {}}  # the box mesh names no file


def test_restart_check_compares_files_by_contents_and_keys_as_written(tmp_path: Path) -> None:
    """model.config.restart without a run: files by the digest of their contents (moved: the same; changed on disk:
    refused naming the key), a key given in one document only differs, output.* and loading.max_cutbacks may
    change, and a checkpoint without the record of the files is accepted with a warning (files by name)."""
    law, msh = tmp_path / "law.py", tmp_path / "body.msh"
    law.write_text("def psi(F):\n    return 0\n")
    msh.write_bytes(b"mesh 1")
    document = {"mesh": {"file": str(msh)}, "material": [{"region": "all", "law": f"{law}:psi", "E": 1.0}],
                "loading": {"steps": 4}, "probe": [{"name": "tip", "point": [1.0, 1.0, 1.0]}],
                "output": {"render_mesh": str(msh)}}
    digests = file_digests(document)
    assert sorted(digests) == ["material.0.law", "mesh.file"]  # output.* is not recorded
    earlier = {"config": document, "checkpoint": {"step": 2, "problem": {"files": digests}}}
    assert same_problem(document, digests, earlier) == (None, None)
    allowed = {**document, "loading": {"steps": 4, "max_cutbacks": 2}, "output": {"png": False}, "solver": {}}
    assert same_problem(allowed, digests, earlier) == (None, None)
    moved = tmp_path / "moved.msh"
    shutil.copy(msh, moved)
    elsewhere = {**document, "mesh": {"file": str(moved)}}
    assert same_problem(elsewhere, file_digests(elsewhere), earlier) == (None, None)
    error, _ = same_problem({**document, "probe": [{"name": "tip", "point": [1.0, 0.5, 0.5]}]}, digests, earlier)
    assert error == f"probe.0.point is [1.0, 0.5, 0.5] here, [1.0, 1.0, 1.0] in the run being continued; {RULE}"
    error, _ = same_problem({**document, "loading": {}}, digests, earlier)
    assert error == f"loading.steps is not given here, 4 in the run being continued; {RULE}"
    msh.write_bytes(b"mesh 2")
    error, _ = same_problem(document, file_digests(document), earlier)
    assert error == f"mesh.file: the contents of {msh} differ from the run being continued's (SHA-256); {RULE}"
    old = {"config": document, "checkpoint": {"step": 2}}  # written before the record: files by name
    error, warning = same_problem(document, file_digests(document), old)
    assert error is None and "files compared by name only" in warning
    error, _ = same_problem(elsewhere, file_digests(elsewhere), old)
    assert error.startswith(f"mesh.file is \"{moved}\" here, \"{msh}\" in the run being continued")


# --- in-process, collective -----------------------------------------------------------------------------


def _field(x: np.ndarray) -> np.ndarray:
    return np.vstack([np.sin(3 * x[0]) + x[1], x[0] * x[2] ** 2, np.cos(x[1] + 2 * x[2])])


def test_checkpoint_round_trip_mixed_space(shared_tmp: Path) -> None:
    """A Taylor-Hood (P2 u, P1 p) Function and a P1 vector Function, written and read back onto fresh Functions:
    equal to the interpolants of the formulas (on 1 and on 2 ranks)."""
    msh = mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    cell = compat.cell_name(msh)
    mixed = compat.function_space(msh, compat.mixed_element([compat.element("Lagrange", cell, 2, (3,)),
                                                              compat.element("Lagrange", cell, 1)]))
    vector = compat.function_space(msh, "Lagrange", 1, (3,))
    w, v = fem.Function(mixed), fem.Function(vector)
    w.sub(0).interpolate(_field)
    w.sub(1).interpolate(lambda x: x[0] - 2 * x[1] + x[2] ** 3)
    w.x.scatter_forward()
    v.interpolate(lambda x: 2 * _field(x))
    names = write_checkpoint(shared_tmp, 3, {"solution": w, "u_n": v}, {"load_factor": 0.25, "increment": 0.1})
    assert names == ["checkpoint_0003.npz"]
    back = {"solution": fem.Function(mixed), "u_n": fem.Function(vector)}
    meta = read_checkpoint(shared_tmp, 3, back)
    assert meta == {"load_factor": 0.25, "increment": 0.1}
    u_back = back["solution"].sub(0).collapse()  # Lagrange interpolants: the formula at the nodes
    nodes = u_back.function_space.tabulate_dof_coordinates()
    np.testing.assert_allclose(u_back.x.array.reshape(-1, 3), _field(nodes.T).T, atol=1e-14)
    p_back = back["solution"].sub(1).collapse()
    dofs = p_back.function_space.tabulate_dof_coordinates()
    np.testing.assert_allclose(p_back.x.array, dofs[:, 0] - 2 * dofs[:, 1] + dofs[:, 2] ** 3, atol=1e-14)
    nodes = vector.tabulate_dof_coordinates()
    np.testing.assert_allclose(back["u_n"].x.array.reshape(-1, 3), 2 * _field(nodes.T).T, atol=1e-14)
    write_checkpoint(shared_tmp, 4, {"solution": w}, {})
    assert sorted(p.name for p in shared_tmp.glob("checkpoint_*")) == ["checkpoint_0003.npz", "checkpoint_0004.npz"]
    MPI.COMM_WORLD.barrier()
    remove_checkpoint(shared_tmp, 3, MPI.COMM_WORLD)
    assert sorted(p.name for p in shared_tmp.glob("checkpoint_*")) == ["checkpoint_0004.npz"]
    other = fem.Function(compat.function_space(mesh.create_unit_cube(MPI.COMM_WORLD, 3, 2, 2), "Lagrange", 1, (3,)))
    with pytest.raises(ValueError, match="dofs of 'solution' are not in the checkpoint"):
        read_checkpoint(shared_tmp, 4, {"solution": other})


def test_checkpoint_keys_off_by_one_quantum_are_found(shared_tmp: Path) -> None:
    """A dof whose coordinates come out one quantization step (1e-9 of the size) away from the saved key, as the
    last bit of a coordinate computed from another cell can, is still found; two steps away it is not."""
    v = fem.Function(compat.function_space(mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2), "Lagrange", 1, (3,)))
    v.interpolate(_field)
    v.x.scatter_forward()  # the ghosts' values as their owners' (interpolated on another cell, they may differ)
    write_checkpoint(shared_tmp, 1, {"u_n": v}, {})
    path = shared_tmp / "checkpoint_0001.npz"

    def shift(by: list[int]) -> None:
        if MPI.COMM_WORLD.rank == 0:
            with np.load(path) as f:
                data = {k: f[k] for k in f.files}
            data["u_n.keys"][:, 2:] += np.array(by)
            np.savez(path, **data)
        MPI.COMM_WORLD.barrier()

    shift([1, -1, 1])
    back = fem.Function(v.function_space)
    read_checkpoint(shared_tmp, 1, {"u_n": back})
    np.testing.assert_array_equal(back.x.array, v.x.array)
    shift([1, 0, 0])
    with pytest.raises(ValueError, match="dofs of 'u_n' are not in the checkpoint"):
        read_checkpoint(shared_tmp, 1, {"u_n": back})


def test_xdmf_series_each_step_readable(shared_tmp: Path) -> None:
    """Steps written by XdmfSeries read back with meshio (rank 0) as the formula at the mesh points, also
    before the series is finished; a resumed series keeps the first steps and goes on."""
    msh = mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    u = fem.Function(compat.function_space(msh, "Lagrange", 1, (3,)), name="u")
    series = XdmfSeries(msh, shared_tmp)
    for k in (1, 2, 3):
        u.interpolate(lambda x, k=k: k * _field(x))
        assert series.write([u], 0.5 * k) == f"results_{k:04d}.h5"
        if MPI.COMM_WORLD.rank == 0:
            with meshio.xdmf.TimeSeriesReader(shared_tmp / "results.xdmf") as reader:
                points, _ = reader.read_points_cells()
                assert reader.num_steps == k
                t, point_data, _ = reader.read_data(k - 1)
            assert t == 0.5 * k
            np.testing.assert_allclose(point_data["u"], k * _field(points.T).T, atol=1e-13)
    resumed = XdmfSeries(msh, shared_tmp, resume=2)
    u.interpolate(lambda x: 7 * _field(x))
    resumed.write([u], 3.5)
    if MPI.COMM_WORLD.rank == 0:
        with meshio.xdmf.TimeSeriesReader(shared_tmp / "results.xdmf") as reader:
            points, _ = reader.read_points_cells()
            times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
            last = reader.read_data(2)[1]["u"]
        assert times == [0.5, 1.0, 3.5]
        np.testing.assert_allclose(last, 7 * _field(points.T).T, atol=1e-13)
    MPI.COMM_WORLD.barrier()


def _bar_functions(comm: MPI.Comm) -> dict[str, fem.Function]:
    """On a 4 x 1 x 1 bar (8 x 2 x 2 cells, so that 2 ranks get partitions shorter than the bar): a Taylor-Hood
    (P2 u, P1 p), a P1 vector and a scalar P1 Function collapsed from the vector space (as a contact multiplier
    is), all zero."""
    msh = mesh.create_box(comm, [np.zeros(3), np.array([4.0, 1.0, 1.0])], [8, 2, 2])
    cell = compat.cell_name(msh)
    mixed = compat.function_space(msh, compat.mixed_element([compat.element("Lagrange", cell, 2, (3,)),
                                                              compat.element("Lagrange", cell, 1)]))
    vector = compat.function_space(msh, "Lagrange", 1, (3,))
    scalar, _ = vector.sub(0).collapse()
    return {"solution": fem.Function(mixed), "u_n": fem.Function(vector), "multiplier_0": fem.Function(scalar)}


def _scalar_field(x: np.ndarray) -> np.ndarray:
    return x[0] - 2 * x[1] + x[2] ** 3


def bar_checkpoint(folder: str, read: int, write: int) -> None:
    """Read checkpoint ``read`` of ``folder`` (0: none) into the bar's functions and assert they equal _field /
    _scalar_field at the dofs, then write the functions interpolated from those formulas to checkpoint ``write``
    (0: none): collective, run by test_checkpoint_on_another_number_of_ranks on 1 rank and under mpirun on 2."""
    functions = _bar_functions(MPI.COMM_WORLD)
    if read:
        assert read_checkpoint(Path(folder), read, functions) == {"load_factor": 0.5}
        u = functions["solution"].sub(0).collapse()
        nodes = u.function_space.tabulate_dof_coordinates().T
        np.testing.assert_allclose(u.x.array.reshape(-1, 3), _field(nodes).T, atol=1e-13)
        p = functions["solution"].sub(1).collapse()
        np.testing.assert_allclose(p.x.array, _scalar_field(p.function_space.tabulate_dof_coordinates().T),
                                   atol=1e-13)
        nodes = functions["u_n"].function_space.tabulate_dof_coordinates().T
        np.testing.assert_allclose(functions["u_n"].x.array.reshape(-1, 3), 2 * _field(nodes).T, atol=1e-13)
        nodes = functions["multiplier_0"].function_space.tabulate_dof_coordinates().T
        np.testing.assert_allclose(functions["multiplier_0"].x.array, _scalar_field(nodes), atol=1e-13)
    if write:
        functions["solution"].sub(0).interpolate(_field)
        functions["solution"].sub(1).interpolate(_scalar_field)
        functions["u_n"].interpolate(lambda x: 2 * _field(x))
        functions["multiplier_0"].interpolate(_scalar_field)
        for f in functions.values():
            f.x.scatter_forward()
        write_checkpoint(Path(folder), write, functions, {"load_factor": 0.5})


@serial_only
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="no mpirun")
def test_checkpoint_on_another_number_of_ranks(tmp_path: Path) -> None:
    """A checkpoint written on 1 rank is read on 2 (mpirun -n 2 started here), which write one read back on 1, on a
    bar whose 2 partitions are shorter than the bar: every value back at its dof (Taylor-Hood, vector, and a
    collapsed scalar space)."""
    bar_checkpoint(str(tmp_path), read=0, write=1)
    code = f"from tests.test_long_runs import bar_checkpoint; bar_checkpoint({str(tmp_path)!r}, read=1, write=2)"
    result = subprocess.run(["mpirun", "-n", "2", sys.executable, "-c", code], env=ENV, text=True,
                            capture_output=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    bar_checkpoint(str(tmp_path), read=2, write=0)
