"""PETSc options in [solver] petsc_options: a misspelt one stops the run before any solve; one PETSc
reads only in the first solve is applied (it stays in the options database), and reported when unused.
Bad values (an unknown type, a tolerance out of range, text for a number) stop the run right after the
build, before the earlier run's files are removed and before the scale check or any solve: one line
naming the key, through model.run and the command line, without PETSc's error dump."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import EXAMPLES, ROOT, environment, example, run_raw, serial_only
from mpi4py import MPI

from model.errors import ConfigError
from model.solvers.options import check_option_values, component


def uniaxial(options: dict) -> dict:
    raw = example("uniaxial")
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    raw["loading"] = {"steps": 1}
    raw["solver"] = {"petsc_options": options}
    return raw


def test_misspelt_option_is_a_config_error_before_the_solve(shared_tmp) -> None:
    with pytest.raises(ConfigError, match=r"^solver\.petsc_options\.snes_rtoll: PETSc does not use"):
        run_raw(uniaxial({"snes_rtoll": 1e-9}), shared_tmp / "a")
    assert not (shared_tmp / "a").exists()


def test_options_read_in_the_first_solve_are_applied(shared_tmp) -> None:
    # MUMPS reads its ICNTL options only when it factorises, inside the first solve: the option must
    # still be in the database then (PETSc reports it as used)
    summary = run_raw(uniaxial({"mat_mumps_icntl_14": 40}), shared_tmp / "b")
    assert summary["status"] == "completed"
    assert "unused_petsc_options" not in summary


def test_unused_late_option_is_reported(shared_tmp) -> None:
    summary = run_raw(uniaxial({"mat_mumps_icntl_999": 1}), shared_tmp / "c")
    assert summary["status"] == "completed"
    assert summary["unused_petsc_options"] == ["mat_mumps_icntl_999"]


# --- values --------------------------------------------------------------------------------------------------

#: (key, value, the message after "solver.petsc_options.KEY: ", or its start)
BAD_VALUES = [
    ("ksp_type", "preonly_nope", "'preonly_nope' is not a KSP type PETSc knows (did you mean 'preonly'?)"),
    ("pc_type", "", "'' is not a PC type PETSc knows (e.g. lu, cholesky, gamg, hypre, fieldsplit, jacobi, sor, none)"),
    ("snes_linesearch_type", 42, "42 is not a line search PETSc knows (one of: basic, bt, "),
    ("pc_factor_mat_solver_type", "mumps_nope", "'mumps_nope' is not a factorisation package this PETSc has for lu "
                                                "(it has: mumps, "),
    ("snes_rtol", -1, "-1 is out of range, must be in [0, 1) (a relative tolerance)"),
    ("ksp_rtol", "tight", "'tight' is not a number (a relative tolerance, in [0, 1))"),
    ("fieldsplit_u_ksp_type", "cgg", "'cgg' is not a KSP type PETSc knows (did you mean 'cg'?)"),
    ("mg_levels_ksp_max_it", 2.5, "2.5 is not an integer (an iteration count, an integer >= 0)"),
]
#: an earlier run's folder: its summary.json accounts for step_0001.vtu; mine.txt is the user's
EARLIER = {"status": "completed", "steps": [{"converged": True}], "files": ["step_0001.vtu", "summary.json"]}


def earlier_run(out: Path) -> None:
    """An earlier run's files and a file of the user's in ``out`` (rank 0 writes, every rank waits)."""
    if MPI.COMM_WORLD.rank == 0:
        out.mkdir(parents=True)
        (out / "summary.json").write_text(json.dumps(EARLIER))
        (out / "step_0001.vtu").write_text("earlier")
        (out / "mine.txt").write_text("mine")
    MPI.COMM_WORLD.barrier()


def untouched(out: Path) -> bool:
    return (sorted(p.name for p in out.iterdir()) == ["mine.txt", "step_0001.vtu", "summary.json"]
            and json.loads((out / "summary.json").read_text()) == EARLIER)


@pytest.mark.parametrize(("key", "value", "expected"), BAD_VALUES, ids=[k for k, *_ in BAD_VALUES])
def test_bad_value_is_refused_before_anything_is_deleted(shared_tmp: Path, capfd: pytest.CaptureFixture,
                                                         key: str, value: Any, expected: str) -> None:
    out = shared_tmp / "out"
    earlier_run(out)
    with pytest.raises(ConfigError) as info:
        run_raw(uniaxial({key: value}), out)
    message = str(info.value)
    assert message.startswith(f"solver.petsc_options.{key}: {expected}"), message
    assert "\n" not in message
    assert MPI.COMM_WORLD.allgather(message) == [message] * MPI.COMM_WORLD.size
    assert untouched(out)
    assert "PETSC ERROR" not in capfd.readouterr().err


def test_bad_value_is_refused_without_a_solve() -> None:
    """The check alone: the first bad value in the order given; the same prefixed options pass with good values."""
    with pytest.raises(ConfigError, match=r"^solver\.petsc_options\.fieldsplit_p_pc_type: 'jacoby' is not a PC "
                                          r"type PETSc knows \(did you mean 'jacobi'\?\)$"):
        check_option_values({"fieldsplit_u_pc_type": "gamg", "fieldsplit_p_pc_type": "jacoby", "snes_rtol": -1})
    for key, value, message in [
        ("snes_max_it", True, "True is not an integer (an iteration count, an integer >= 0)"),
        ("snes_atol", "1e-3x", "'1e-3x' is not a number (an absolute tolerance, >= 0)"),
        ("snes_stol", -1e-12, "-1e-12 is out of range, must be >= 0 (a step tolerance)"),
        ("ksp_divtol", 0.5, "0.5 is out of range, must be >= 1 (a divergence tolerance)"),
        ("ksp_initial_guess_nonzero", "maybe", "'maybe' is not a boolean (true or false)"),
        ("snes_type", 1, "1 is not a SNES type PETSc knows (e.g. newtonls, newtontr, vinewtonrsls, ksponly)"),
    ]:
        with pytest.raises(ConfigError) as info:
            check_option_values({key: value})
        assert str(info.value) == f"solver.petsc_options.{key}: {message}"
    # a Cholesky package is checked as Cholesky when the same prefix asks for it (UMFPACK is LU only)
    with pytest.raises(ConfigError, match=r"^solver\.petsc_options\.pc_factor_mat_solver_type: 'umfpack' is not a "
                                          r"factorisation package this PETSc has for cholesky \(it has: mumps"):
        check_option_values({"pc_type": "cholesky", "pc_factor_mat_solver_type": "umfpack"})
    check_option_values({"pc_type": "lu", "pc_factor_mat_solver_type": "umfpack"})
    check_option_values({
        "snes_type": "newtonls", "snes_linesearch_type": "basic", "ksp_type": "fgmres", "pc_type": "fieldsplit",
        "fieldsplit_u_ksp_type": "preonly", "fieldsplit_u_pc_type": "hypre", "fieldsplit_p_pc_type": "jacobi",
        "mg_levels_ksp_type": "chebyshev", "mg_levels_ksp_max_it": "2", "snes_rtol": "1e-8", "ksp_atol": 0,
        "snes_max_it": 50, "ksp_divtol": 1e4, "pc_gamg_reuse_interpolation": True, "ksp_initial_guess_nonzero": "yes",
        "pc_factor_mat_solver_type": "mumps", "mat_mumps_icntl_14": 40, "snes_monitor": "",
    })


def test_options_are_checked_by_their_last_component() -> None:
    assert component("fieldsplit_u_ksp_type") == "ksp_type"
    assert component("fieldsplit_p_upper_pc_type") == "pc_type"
    assert component("snes_linesearch_type") == "snes_linesearch_type"
    assert component("fieldsplit_u_pc_factor_mat_solver_type") == "pc_factor_mat_solver_type"
    assert component("mg_levels_ksp_max_it") == "max_it"
    assert component("snes_rtol") == "rtol"
    for other in ("pc_fieldsplit_type", "pc_mg_type", "pc_hypre_type", "ksp_norm_type", "mat_mumps_icntl_14",
                  "pc_fieldsplit_schur_fact_type", "snes_rtoll"):
        assert component(other) is None, other


@pytest.mark.parametrize("options", [
    {"ksp_type": "gmres", "pc_type": "hypre", "snes_linesearch_type": "bt"},
    {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps", "snes_linesearch_type": "bt"},
], ids=["gmres-hypre-bt", "lu-mumps-bt"])
def test_valid_values_still_run(shared_tmp: Path, options: dict[str, Any]) -> None:
    summary = run_raw(uniaxial(options), shared_tmp / "ok")
    assert summary["status"] == "completed"
    assert "unused_petsc_options" not in summary
    assert {k: summary["solver"]["petsc_options"][k] for k in options} == options


#: the bad values above, as --set writes them (TOML; a bare word is a string)
CLI_VALUES = [("ksp_type", "preonly_nope"), ("pc_type", '""'), ("snes_linesearch_type", "42"),
              ("pc_factor_mat_solver_type", "mumps_nope"), ("snes_rtol", "-1"), ("ksp_rtol", "tight")]


@serial_only
@pytest.mark.parametrize(("key", "text"), CLI_VALUES, ids=[k for k, _ in CLI_VALUES])
def test_command_line_bad_value(tmp_path: Path, key: str, text: str) -> None:
    """Exit code 2, one line on stderr naming the key, the earlier run's files kept (nothing removed)."""
    out = tmp_path / "out"
    earlier_run(out)
    expected = next(e for k, _, e in BAD_VALUES if k == key)
    command = [sys.executable, "-m", "model", "run", str(EXAMPLES / "uniaxial.toml"), "--out", str(out),
               "--set", "loading.steps=1", "--set", f"solver.petsc_options.{key}={text}"]
    start = time.perf_counter()
    result = subprocess.run(command, cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.splitlines() == [result.stderr.strip()], result.stderr
    assert result.stderr.startswith(f"error: solver.petsc_options.{key}: {expected}"), result.stderr
    assert "Traceback" not in result.stderr and "PETSC ERROR" not in result.stderr
    assert "removed" not in result.stdout and "PETSC ERROR" not in result.stdout  # only the build's log lines
    assert untouched(out)
    assert time.perf_counter() - start < 60


def test_viewer_options_take_true_or_a_viewer() -> None:
    """``snes_monitor = true`` (TOML's natural spelling) switches the monitor on (PETSc itself would stop with
    "Unsupported viewer true"); false leaves it out; a value that is no viewer is one line naming the key."""
    from model.errors import ConfigError
    from model.solvers.options import check_option_values, is_viewer, petsc_value

    assert is_viewer("snes_monitor") and is_viewer("ksp_monitor_true_residual") and is_viewer("fieldsplit_u_ksp_view")
    assert not is_viewer("snes_monitor_cancel") and not is_viewer("ksp_type")
    assert petsc_value("snes_monitor", True) == "" and petsc_value("ksp_view", False) is None
    assert petsc_value("snes_rtol", 1e-8) == 1e-8
    check_option_values({"snes_monitor": True, "ksp_view": "ascii:ksp.txt", "snes_converged_reason": ""})
    with pytest.raises(ConfigError, match=r"^solver.petsc_options.snes_monitor: 'yes please' is not a PETSc viewer"):
        check_option_values({"snes_monitor": "yes please"})
