"""Newton's globalisation: the total potential as SNES's objective, and the default line search.

* the objective NewtonSolver hands SNES is the total potential summary.json reports, and its derivative along a
  direction is the residual's action on it (central differences, 1e-6);
* the soft L-bracket cantilever of benchmarks/l_bracket.toml (the user's own gmsh script, P1 Mooney-Rivlin,
  tip traction; coarse here) reaches the full load in one step with the default (bt on the potential), where
  bt on the residual norm stalls and gives up after its cut-backs;
* a run records the line search it used in summary.json; prescribed displacements (the Dirichlet step before
  an objective line search), a follower pressure (no potential: full steps), VI and penalty contact converge
  with the defaults.

Collective: every test runs on all ranks (serially and under mpirun -n 2).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import EXAMPLES, ROOT, example, run_raw
from dolfinx import fem

from model import compat
from model.config import parse
from model.pipeline import build, make_solver
from model.solvers.loadstepping import StepRecord, step_loads
from model.solvers.newton import NewtonSolver, default_line_search

BENCHMARKS = ROOT / "benchmarks"


def l_bracket(size: float = 0.02, **solver: Any) -> dict[str, Any]:
    """benchmarks/l_bracket.toml with the largest element edge ``size`` (0.02: 390 dofs) and [solver] keys."""
    raw = tomllib.loads((BENCHMARKS / "l_bracket.toml").read_text())
    raw["mesh"].update(file=str(BENCHMARKS / "l_bracket.geo"), parameters={"size": size})
    if solver:
        raw["solver"] = solver
    return raw


def quiet(raw: dict[str, Any]) -> dict[str, Any]:
    """``raw`` without output files (summary.json only)."""
    return {**raw, "output": {**raw.get("output", {}), "xdmf": False, "vtu": False, "png": False}}


def smooth(scale: float, shift: float):  # noqa: ANN201 - a vector field x -> (3, n)
    return lambda x: scale * np.vstack([np.sin(3 * x[1] + shift) * x[0], np.cos(2 * x[2] - shift) * x[0] ** 2,
                                        np.sin(x[0] + x[1] + shift) * x[2]])


def test_objective_is_the_total_potential_and_its_derivative_the_residual() -> None:
    raw = example("uniaxial")
    raw["body_force"] = [{"region": "all", "value": [0.0, 300.0, -500.0]}]
    setup = build(parse(raw, EXAMPLES))
    problem = setup.problem
    assert problem.potential_reason() is None
    solver = NewtonSolver(problem)
    assert solver.objective and solver.line_search == {"type": "bt", "merit": "total_potential"}
    problem.set_load_factor(0.7)
    problem.solution.interpolate(smooth(0.05, 0.3))  # a state off equilibrium (Dirichlet values not held)
    x = compat.petsc_vector(problem.solution).copy()
    pi = solver._objective(solver.snes, x)
    energies = problem.energies()
    assert math.isclose(pi, energies["total_potential"], rel_tol=1e-13)
    assert energies["load_potential"] != 0.0 and energies["strain_energy"] > 0.0
    # dPi/du [d] = R(u) . d, R unconstrained (f_int - f_ext, constrained rows included)
    residual = solver.unconstrained_residual()
    direction = fem.Function(problem.space)
    direction.interpolate(smooth(1.0, 1.1))
    d = compat.petsc_vector(direction)
    slope = residual.dot(d)
    h = 1e-5
    trial = x.copy()
    values = []
    for sign in (1.0, -1.0):
        x.copy(trial)
        trial.axpy(sign * h, d)
        values.append(solver._objective(solver.snes, trial))
    difference = (values[0] - values[1]) / (2 * h)
    assert abs(slope) > 1.0
    assert abs(difference - slope) <= 1e-6 * abs(slope), (difference, slope)
    # the callback copied SNES's vector into the solution, and SNES's vector is not the function's own
    assert np.allclose(compat.petsc_vector(problem.solution).array_r, trial.array_r)
    for vec in (x, trial, residual):
        vec.destroy()
    solver.destroy()


def bracket_stepping(objective: bool | None, line_search: str | None, max_cutbacks: int = 4
                     ) -> tuple[bool, list[StepRecord], dict[str, str]]:
    raw = l_bracket(**({"petsc_options": {"snes_linesearch_type": line_search}} if line_search else {}))
    config = parse(raw, BENCHMARKS)
    setup = build(config)
    solver = make_solver(setup.problem, config, objective=objective)
    records: list[StepRecord] = []
    outcome = step_loads(solver, config.loading.steps, max_cutbacks, config.loading.growth, records.append)
    used = solver.line_search
    solver.destroy()
    return bool(outcome), records, used


def test_l_bracket_default_reaches_full_load_where_bt_on_the_residual_stalls() -> None:
    done, records, used = bracket_stepping(None, None)
    assert used == {"type": "bt", "merit": "total_potential"}
    assert done and len(records) == 1 and records[0].result.converged  # no cut-back
    assert records[0].result.iterations <= 25
    done, records, used = bracket_stepping(False, "bt")
    assert used == {"type": "bt", "merit": "residual_norm"}
    failed = [r for r in records if not r.result.converged]
    assert not done and len(failed) == len(records) == 5  # cut back 4 times, then gave up: no step converged
    assert min(r.load_factor for r in records) == 0.0625


def test_summary_records_the_line_search(shared_tmp: Path) -> None:
    summary = run_raw(quiet(l_bracket()), shared_tmp / "bracket")
    assert summary["status"] == "completed"
    assert summary["solver"]["line_search"] == {"type": "bt", "merit": "total_potential"}
    assert [s["converged"] for s in summary["steps"]] == [True]
    tip = summary["steps"][-1]["probes"]["tip"]
    assert tip[1] < -0.05  # bent substantially (0.07 m down at the tip of the 0.1 m arm)
    raw = l_bracket(petsc_options={"snes_linesearch_type": "cp"})
    summary = run_raw(quiet(raw), shared_tmp / "cp")
    assert summary["solver"]["line_search"] == {"type": "cp", "merit": "none"}
    assert np.allclose(summary["steps"][-1]["probes"]["tip"], tip, rtol=1e-7, atol=1e-10)


def test_round_off_near_the_solution_is_finished_with_full_steps(shared_tmp: Path) -> None:
    """Shape targets (polar rotations at the quadrature points, refreshed by the objective callback): near the
    solution Pi changes below its round-off, bt on Pi gave up there (DIVERGED_LINE_SEARCH at |R| ~ 1e-7 |R_0|,
    two cut-backs) before the solve finished with full steps."""
    raw = example("muscle_targets")
    raw["mesh"]["cells"] = [3, 3, 8]
    raw.pop("solver", None)
    summary = run_raw(quiet(raw), shared_tmp / "targets")
    assert summary["solver"]["line_search"] == {"type": "bt", "merit": "total_potential"}
    assert summary["status"] == "completed"
    assert all(s["converged"] for s in summary["steps"]) and len(summary["steps"]) == 10
    assert max(s["newton_iterations"] for s in summary["steps"]) <= 8


def test_prescribed_displacements_take_the_dirichlet_step_first(shared_tmp: Path) -> None:
    raw = example("twisting_bar")
    raw["mesh"]["cells"] = [8, 2, 2]
    raw["loading"]["steps"] = 4
    raw["solver"].pop("petsc_options", None)
    summary = run_raw(quiet(raw), shared_tmp / "twist")
    assert summary["solver"]["line_search"] == {"type": "bt", "merit": "total_potential"}
    assert summary["status"] == "completed"
    assert all(s["converged"] for s in summary["steps"])  # no cut-back
    assert len(summary["steps"]) == 4


def test_follower_pressure_has_no_objective_and_converges(shared_tmp: Path) -> None:
    raw = example("uniaxial")
    raw["solver"].pop("petsc_options", None)
    traction = next(b for b in raw["boundary"] if b["type"] == "traction")
    traction.update(type="pressure", value=[-2.0e3])  # pulls outwards, along the deformed normal
    config = parse(raw, EXAMPLES)
    setup = build(config)
    assert "follower pressure" in setup.problem.potential_reason()
    assert default_line_search(setup.problem) == "basic"
    with pytest.raises(ValueError, match="follower pressure"):
        NewtonSolver(setup.problem, objective=True)
    summary = run_raw(quiet(raw), shared_tmp / "pressure")
    assert summary["solver"]["line_search"] == {"type": "basic", "merit": "none"}
    assert summary["status"] == "completed" and all(s["converged"] for s in summary["steps"])
    assert "total_potential" not in summary["steps"][-1]


@pytest.mark.parametrize("method", ["vi", "penalty"])
def test_contact_converges_with_the_default(shared_tmp: Path, method: str) -> None:
    raw = example("contact_block")
    raw["solver"] = {}
    raw["contact"][0]["method"] = method
    if method == "penalty":
        raw["contact"][0]["penalty"] = 1.0e6
    summary = run_raw(quiet(raw), shared_tmp / method)
    expected = {"type": "basic", "merit": "none"} if method == "vi" else {"type": "bt", "merit": "total_potential"}
    assert summary["solver"]["line_search"] == expected
    assert summary["status"] == "completed"
    assert all(s["converged"] for s in summary["steps"])
    last = summary["steps"][-1]
    assert last["contact"]["force"][2] > 0.0  # the plane pushes the block up
    if method == "penalty":
        assert last["contact_energy"] > 0.0


def test_dynamics_and_mixed_have_no_objective() -> None:
    raw = example("cook")
    raw["mesh"]["cells"] = 2
    setup = build(parse(raw, EXAMPLES))
    assert "saddle" in setup.problem.potential_reason()
    solver = NewtonSolver(setup.problem)
    assert not solver.objective and solver.line_search == {"type": "basic", "merit": "none"}
    solver.destroy()
    raw = example("uniaxial")
    setup = build(parse(raw, EXAMPLES))
    from model.solvers.dynamics import Dynamics

    Dynamics(setup.problem, 1000.0, "newmark", dt=0.01)
    assert "inertia" in setup.problem.potential_reason()
    solver = NewtonSolver(setup.problem)
    assert not solver.objective and solver.line_search["type"] == "basic"
    solver.destroy()
