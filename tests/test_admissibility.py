"""A folded state is never accepted: det F <= 0 at a material point is a domain error for SNES, Newton
directions are shortened to keep det F > 0, and every step records min det F (model.problem.admissibility)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES, example, run_raw
from petsc4py import PETSc

from model import compat
from model.config import parse
from model.pipeline import build, make_solver
from model.problem.admissibility import Admissibility


def uniaxial_solver(shared_tmp: Path):  # noqa: ANN201 - (setup, solver)
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]

    setup = build(parse(raw, EXAMPLES))
    return setup, make_solver(setup.problem, parse(raw, EXAMPLES))


def test_step_limit_is_the_largest_admissible_halving(shared_tmp: Path) -> None:
    """u = -s y with y = 3 X: F = (1 - 3 s) I, admissible for s < 1/3: the limit is 1/4 (exact halvings)."""
    setup, solver = uniaxial_solver(shared_tmp)
    problem = setup.problem
    check = Admissibility(problem)
    direction = problem.solution.copy()
    direction.interpolate(lambda x: 3.0 * x)
    assert check.step_limit(compat.petsc_vector(direction)) == 0.25
    direction.interpolate(lambda x: -0.5 * x)  # expansion: never folds
    assert check.step_limit(compat.petsc_vector(direction)) == 1.0
    solver.destroy()


def test_a_folded_state_is_refused_and_located(shared_tmp: Path) -> None:
    """A state with one node pushed through its neighbours: Newton from it ends with DIVERGED_FUNCTION_DOMAIN
    (not a NaN, not a converged state) and the report names min det F < 0 and where."""
    setup, solver = uniaxial_solver(shared_tmp)
    problem = setup.problem
    problem.set_load_factor(0.1)
    # the centre node (0.5, 0.5, 0.5) moved by 1.2 along x: through the cells on its +x side
    centre = np.all(np.isclose(problem.space.tabulate_dof_coordinates(), 0.5), axis=1)
    values = problem.solution.x.array.reshape(-1, 3)
    values[centre, 0] = 1.2
    problem.solution.x.scatter_forward()
    check = Admissibility(problem)
    assert check.minimum() < 0
    result = solver.solve()
    assert not result.converged
    assert result.reason == PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN
    assert result.admissibility["min_det_F"] < 0
    assert result.admissibility["min_det_F_point"] is not None
    solver.destroy()


def test_overloaded_mixed_step_is_shortened_not_folded(shared_tmp: Path) -> None:
    """Cook's membrane, Taylor-Hood, nu = 0.4999, 24x the benchmark's load in one step: full Newton steps fold
    cells (NaN residuals, four cut-backs before this change); shortened directions converge in the one step, with
    every material point's J > 0 and the count of shortened directions recorded."""
    raw = example("cook")
    raw["mesh"]["cells"] = 4
    raw["boundary"][3]["value"] = [0.0, 150.0, 0.0]
    raw["loading"] = {"steps": 1}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    run_raw(raw, shared_tmp)
    import json

    summary = json.loads((shared_tmp / "summary.json").read_text())
    steps = summary["steps"]
    assert summary["status"] == "completed"
    assert len(steps) == 1 and steps[0]["converged"]
    assert steps[0]["limited_steps"] >= 1
    assert 0 < steps[0]["min_det_F"] < 1
    assert steps[0]["min_det_F_regions"]["all"] == pytest.approx(steps[0]["min_det_F"])
