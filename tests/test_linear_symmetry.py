"""[solver] linear follows the symmetry of Newton's matrix: ElasticityProblem.symmetry_reason against the assembled
Jacobian (|J - J^T| / |J|), "auto" above AUTO_DOFS picks GMRES + GAMG for a nonsymmetric tangent (a follower pressure)
and CG + GAMG without one, the mixed formulation keeps its GMRES fieldsplit, summary.json records the reason, and an
explicit CG on a nonsymmetric tangent is a logged warning. Collective: runs serially and under mpirun -n 2."""

from __future__ import annotations

import copy
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import EXAMPLES, example, run_raw
from mpi4py import MPI
from petsc4py import PETSc

from model.solvers import linear

QUIET = {"xdmf": False, "vtu": False, "png": False}


def box(pressure: bool = False, mixed: bool = False, cells: int = 2) -> dict[str, Any]:
    """A unit cube clamped at x = 0, a traction or (``pressure``) a follower pressure on x = 1; P1, or Taylor-Hood."""
    raw: dict[str, Any] = {
        "mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [cells, cells, cells]},
        "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3, "density": 1000.0}],
        "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                     {"on": "xmax", "type": "pressure", "value": [500.0]} if pressure else
                     {"on": "xmax", "type": "traction", "value": [0.0, 0.0, 500.0]}],
        "loading": {"steps": 1},
        "output": dict(QUIET)}
    if mixed:
        raw["discretization"] = {"degree": 2, "quadrature_degree": 2, "formulation": "mixed"}
    return raw


def setup_of(raw: dict[str, Any]) -> Any:
    from model.config import parse
    from model.pipeline import _dynamics, build

    config = parse(raw, EXAMPLES)
    setup = build(config)
    if config.dynamics is not None and config.dynamics.is_dynamic:
        _dynamics(setup, config)
    return setup, config


def asymmetry(raw: dict[str, Any]) -> tuple[float, str | None]:
    """|J - J^T|_F / |J|_F of Newton's matrix at a random state (1e-2) and load factor 0.5, and symmetry_reason."""
    from model import compat
    from model.pipeline import make_solver, newton_of

    setup, config = setup_of(raw)
    problem = setup.problem
    problem.set_load_factor(0.5)
    values = np.random.default_rng(MPI.COMM_WORLD.rank).standard_normal(len(problem.solution.x.array))
    problem.solution.x.array[:] = 1e-2 * values
    problem.solution.x.scatter_forward()
    solver = make_solver(problem, config, setup.contacts)
    newton = newton_of(solver)
    x = compat.petsc_vector(problem.solution)
    newton._jacobian(newton.snes, x, newton.A, newton.A)
    difference = newton.A.transpose(PETSc.Mat())
    difference.axpy(-1.0, newton.A, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    ratio = difference.norm() / newton.A.norm()
    difference.destroy()
    reason = problem.symmetry_reason(config.solver.tangent)
    solver.destroy()
    return ratio, reason


def _dynamic(raw: dict[str, Any], scheme: str) -> dict[str, Any]:
    raw["dynamics"] = {"scheme": scheme, "dt": 0.01, "end_time": 0.1, "rayleigh": [2.0, 0.01]}
    return raw


def _sliding_smoothed() -> dict[str, Any]:
    raw = example("contact_bodies")
    raw["output"] = dict(QUIET)
    contact = raw["contact"][0]
    for k in ("augmented", "tolerance", "max_uzawa"):
        contact.pop(k, None)
    contact.update(sliding=True, smooth_normals=True)
    return raw


def _projected(raw: dict[str, Any]) -> dict[str, Any]:
    raw["solver"] = {"tangent": "projected"}
    return raw


def _law(law: dict[str, Any]) -> dict[str, Any]:
    raw = box()
    raw["material"] = [{"region": "all", **law}]
    return raw


CASES = {
    "traction": (lambda: box(), True),
    "corotated (the polar rotation at the points)": (lambda: _law({"law": "corotated", "E": 1e4, "nu": 0.3}), True),
    "ogden (the eigen state at the points)": (lambda: _law({"law": "ogden", "c1": 1e3, "m1": 3.0, "kappa": 1e4}), True),
    "follower pressure": (lambda: box(pressure=True), False),
    "follower pressure, projected tangent": (lambda: _projected(box(pressure=True)), False),
    "mixed": (lambda: box(mixed=True, cells=1), True),
    "mixed, follower pressure": (lambda: box(pressure=True, mixed=True, cells=1), False),
    "newmark, Rayleigh mass and stiffness damping": (lambda: _dynamic(box(), "newmark"), True),
    "generalized alpha, Rayleigh damping": (lambda: _dynamic(box(), "generalized_alpha"), True),
    "contact between bodies (augmented)": (lambda: {**example("contact_bodies"), "output": dict(QUIET)}, True),
    "sliding between bodies, smoothed normals": (_sliding_smoothed, True),
}


@pytest.mark.parametrize("case", list(CASES))
def test_symmetry_reason_matches_the_assembled_jacobian(case: str) -> None:
    """symmetry_reason is None exactly where Newton's assembled matrix is symmetric to round-off (1e-12), and a
    reason where it is not by far (measured 1.6e-3 to 2.5e-3 with the follower pressure; the symmetric ones ~1e-16,
    also sliding with smoothed normals, which has no potential but a symmetric matrix)."""
    make, symmetric = CASES[case]
    ratio, reason = asymmetry(make())
    assert (reason is None) == symmetric, (case, reason)
    if symmetric:
        assert ratio < 1e-12, (case, ratio)
    else:
        assert ratio > 1e-5, (case, ratio)
        assert "follower pressure on 'xmax'" in reason


def test_unknown_residual_term_is_nonsymmetric() -> None:
    """A residual added without saying it is symmetric counts as nonsymmetric (the exact tangent); the projected
    tangent leaves such terms out of its matrix."""
    setup, _ = setup_of(box())
    problem = setup.problem
    assert problem.symmetry_reason() is None
    problem.add_residual(0.0 * problem.u[0] * problem.v[0] * problem.dx)
    assert "unknown symmetry" in problem.symmetry_reason()
    assert problem.symmetry_reason("projected") is None
    problem.residual_symmetry[-1] = "a stated reason"
    assert problem.symmetry_reason() is None


@pytest.mark.parametrize(("pressure", "ksp"), [(True, "gmres"), (False, "cg")])
def test_auto_above_the_threshold_follows_the_symmetry(monkeypatch: pytest.MonkeyPatch, pressure: bool,
                                                       ksp: str) -> None:
    """"auto" from AUTO_DOFS (patched to 0: the iterative preset on a small mesh) picks GMRES + GAMG with a follower
    pressure, CG + GAMG without; below the threshold MUMPS either way, the reason recorded."""
    setup, _ = setup_of(box(pressure=pressure))
    monkeypatch.setattr(linear, "AUTO_DOFS", 0)
    choice = linear.resolve(setup.problem, "auto")
    assert choice.preset == "iterative" and choice.options["ksp_type"] == ksp
    assert choice.options["pc_type"] == "gamg" and choice.options["ksp_rtol"] == 1e-8
    assert choice.symmetric is not pressure
    if pressure:
        assert choice.options["ksp_gmres_restart"] >= 100 and choice.options["ksp_pc_side"] == "right"
        assert "follower pressure" in choice.nonsymmetric_because
    else:
        assert "ksp_gmres_restart" not in choice.options and choice.nonsymmetric_because is None
    monkeypatch.setattr(linear, "AUTO_DOFS", 10**9)
    below = linear.resolve(setup.problem, "auto")
    assert below.preset == "direct" and below.symmetric is not pressure


def test_mixed_formulation_keeps_its_fieldsplit(monkeypatch: pytest.MonkeyPatch) -> None:
    """The mixed formulation's iterative preset is GMRES with the Schur fieldsplit with or without a follower
    pressure (the factorisation needs no symmetry); only the recorded reason differs."""
    monkeypatch.setattr(linear, "AUTO_DOFS", 0)
    for pressure in (False, True):
        setup, _ = setup_of(box(pressure=pressure, mixed=True, cells=1))
        choice = linear.resolve(setup.problem, "auto")
        assert choice.options["ksp_type"] == "gmres" and choice.options["pc_type"] == "fieldsplit"
        assert choice.symmetric is not pressure


def test_summary_records_why_and_the_run_converges(shared_tmp: Path) -> None:
    """A follower-pressure run with the iterative preset: GMRES, summary.json's solver says symmetric false and
    why; the mixed formulation's fieldsplit converges with the follower pressure too."""
    for mixed in (False, True):
        raw = box(pressure=True, mixed=mixed, cells=2)
        raw["solver"] = {"linear": "iterative"}
        summary = run_raw(copy.deepcopy(raw), shared_tmp / f"mixed_{mixed}")
        solver = summary["solver"]
        assert summary["status"] == "completed"
        assert solver["symmetric"] is False
        assert solver["nonsymmetric_because"] == "the follower pressure on 'xmax' has a nonsymmetric load stiffness"
        assert solver["petsc_options"]["ksp_type"] == "gmres"
        assert solver["petsc_options"]["pc_type"] == ("fieldsplit" if mixed else "gamg")
        assert max(c for s in summary["steps"] for c in s["linear_iterations_per_newton"]) > 1
    plain = run_raw(box(), shared_tmp / "traction")
    assert plain["solver"]["symmetric"] is True and "nonsymmetric_because" not in plain["solver"]


def test_explicit_cg_on_a_nonsymmetric_tangent_warns(caplog: pytest.LogCaptureFixture) -> None:
    """ksp_type = "cg" given by the user with a follower pressure: a warning naming why (rank 0), not an error; the
    user's choice stands."""
    setup, _ = setup_of(box(pressure=True))
    with caplog.at_level(logging.WARNING, logger="model.solvers.linear"):
        choice = linear.resolve(setup.problem, "iterative", {"ksp_type": "cg"})
    messages = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    if MPI.COMM_WORLD.rank == 0:
        assert any("'cg' needs a symmetric matrix" in m and "follower pressure" in m for m in messages), messages
    assert "ksp_gmres_restart" not in choice.options  # the user's cg: GMRES's options left out
    caplog.clear()
    setup, _ = setup_of(box())
    with caplog.at_level(logging.WARNING, logger="model.solvers.linear"):
        linear.resolve(setup.problem, "iterative", {"ksp_type": "cg"})
    assert not [r for r in caplog.records if r.levelno == logging.WARNING]
