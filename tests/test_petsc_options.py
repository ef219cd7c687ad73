"""PETSc options in [solver] petsc_options: a misspelt one stops the run before any solve; one PETSc
reads only in the first solve is applied (it stays in the options database), and reported when unused."""

from __future__ import annotations

import pytest
from conftest import example, run_raw

from model.errors import ConfigError


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
