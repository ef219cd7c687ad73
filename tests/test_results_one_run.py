"""One run per output folder: summary.json's "files" lists exactly the files of the run in its folder.

A finished run, then a failing run into the same folder: nothing of the first run is left, the new
summary lists every file in the folder (a user's own files aside, which are never touched), and the
PNG is the failing run's. Summaries written before "files" existed are recognised by their steps and
png keys, conservatively.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import pytest
from conftest import example, run_raw
from mpi4py import MPI

from model.errors import SolveFailed
from model.output.writer import earlier_run_files, remove_earlier_run

comm = MPI.COMM_WORLD
#: a user's own files in the output folder: not written by any run, so never removed
USER_FILES = {"notes.txt": "my notes\n", "step_0042.vtu": "not a run's\n"}


def small_uniaxial() -> dict:
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["output"] = {"png": True}
    return raw


def limit_load() -> dict:
    """tests/test_cli.py failing_config: St Venant-Kirchhoff in compression beyond its limit load."""
    raw = small_uniaxial()
    raw["material"][0]["law"] = "stvk"
    raw["boundary"][3]["value"] = [-1.0e4, 0.0, 0.0]
    raw["loading"] = {"steps": 4, "max_cutbacks": 1}
    return raw


def listing(directory: Path) -> set[str]:
    return {p.name for p in directory.iterdir()}


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_a_failing_run_replaces_the_files_of_an_earlier_run(shared_tmp: Path) -> None:
    out = shared_tmp / "out"
    if comm.rank == 0:
        out.mkdir()
        for name, text in USER_FILES.items():
            (out / name).write_text(text)
    comm.barrier()
    first = run_raw(small_uniaxial(), out)
    assert first["status"] == "completed" and len(first["steps"]) == 5
    assert set(first["files"]) == listing(out) - set(USER_FILES)
    assert {f"step_{i:04d}.vtu" for i in range(1, 6)} | {f"results_{i:04d}.h5" for i in range(1, 6)} | {
        "results.xdmf", "results.h5", "summary.json", "deformed.png", "checkpoint_0005.npz"} == set(first["files"])
    first_png = digest(out / "deformed.png")
    comm.barrier()
    started = comm.bcast(time.time(), root=0)
    time.sleep(0.05)
    with pytest.raises(SolveFailed):
        run_raw(limit_load(), out)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    converged = sum(s["converged"] for s in summary["steps"])
    assert 0 < converged < 5
    # exactly the failing run's files, and the user's, which survive unchanged
    assert set(summary["files"]) == listing(out) - set(USER_FILES)
    for name, text in USER_FILES.items():
        assert (out / name).read_text() == text
    steps = {p.name for p in out.glob("step_*.vtu")} - set(USER_FILES)
    assert steps == {f"step_{i:04d}.vtu" for i in range(1, converged + 1)}
    # nothing of the first run is left: every file the summary lists was written by the failing run
    for name in summary["files"]:
        assert (out / name).stat().st_mtime >= started, f"{name} is the first run's"
    if (out / "deformed.png").exists():
        assert "deformed.png" in summary["files"] and digest(out / "deformed.png") != first_png
    comm.barrier()


def _legacy_folder(out: Path, summary: dict, files: list[str]) -> None:
    if comm.rank == 0:
        out.mkdir()
        for name in files:
            (out / name).write_text("x")
        for name, text in USER_FILES.items():
            (out / name).write_text(text)
        (out / "summary.json").write_text(json.dumps(summary))
    comm.barrier()


def test_a_summary_without_files_is_read_conservatively(shared_tmp: Path) -> None:
    """Before "files": step_0001 ... step_NNNN.vtu (N converged steps), results.xdmf/.h5 and deformed.png
    (its "png" key) are the run's; a step file beyond N and anything else stay."""
    out = shared_tmp / "legacy"
    steps = [{"converged": True}, {"converged": False}, {"converged": True}, {"converged": True}]
    run_files = ["step_0001.vtu", "step_0002.vtu", "step_0003.vtu", "results.xdmf", "results.h5", "deformed.png"]
    _legacy_folder(out, {"status": "failed", "steps": steps, "png": "deformed.png"}, run_files)
    found = earlier_run_files(out) if comm.rank == 0 else None
    removed = remove_earlier_run(out, comm)
    assert removed == len(run_files) + 1  # and summary.json
    if comm.rank == 0:
        assert found == ([*run_files, "summary.json"], "failed")
        assert listing(out) == set(USER_FILES)
    comm.barrier()


@pytest.mark.parametrize("summary", [{"something": "else"}, ["steps"], {"steps": [{"converged": True}]}])
def test_a_summary_of_something_else_is_left_alone(shared_tmp: Path, summary: object) -> None:
    out = shared_tmp / "other"
    _legacy_folder(out, summary, ["step_0001.vtu", "results.xdmf"])  # type: ignore[arg-type]
    assert remove_earlier_run(out, comm) == 0
    if comm.rank == 0:
        assert listing(out) == {"step_0001.vtu", "results.xdmf", "summary.json", *USER_FILES}
    comm.barrier()


def test_files_outside_the_folder_are_never_removed(shared_tmp: Path) -> None:
    out = shared_tmp / "escape"
    outside = shared_tmp / "outside.txt"
    if comm.rank == 0:
        outside.write_text("keep")
    _legacy_folder(out, {"status": "completed", "steps": [],
                         "files": ["../outside.txt", str(outside), "sub", "notes.txt.missing", "summary.json"]}, [])
    if comm.rank == 0:
        (out / "sub").mkdir()
    comm.barrier()
    assert remove_earlier_run(out, comm) == 1  # summary.json alone
    if comm.rank == 0:
        assert outside.read_text() == "keep" and listing(out) == {"sub", *USER_FILES}
    comm.barrier()
