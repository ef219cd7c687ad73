"""Projective Dynamics ([solver] method = "projective_dynamics", model.projective_dynamics).

- On the bending bar of test_projected_tangent (incompatible, per-cell shape targets, kappa = 0) PD run
  to a 1e-10 residual reduction reaches the configuration Newton finds.
- It is a block-coordinate descent: the total potential (with a dead load) never increases; the constant
  matrix is factorised once for all iterations and load steps.
- [solver] keys are checked, and PD refuses anything but shape_target with kappa = 0.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import run_raw
from mpi4py import MPI
from petsc4py import PETSc
from test_projected_tangent import bar_config, bending_targets, box_problem, final_probes

import forms
import meshes
from model.config import parse
from model.domain import build_domain
from model.errors import ConfigError
from model.fields.targets import TargetField
from model.problem import ElasticityProblem
from model.solvers.loadstepping import step_loads
from model.solvers.projective_dynamics import ProjectiveDynamicsSolver


def test_projective_dynamics_reaches_the_newton_solution(shared_tmp: Path) -> None:
    newton = final_probes(run_raw(bar_config({}), shared_tmp / "newton"))
    summary = run_raw(bar_config({"method": "projective_dynamics", "pd_rtol": 1e-10, "pd_max_iterations": 20000},
                                 steps=1), shared_tmp / "pd")
    assert summary["solver"]["method"] == "projective_dynamics"
    step = summary["steps"][-1]
    assert step["newton_iterations"] > 10  # local/global iterations: linear convergence
    pd = final_probes(summary)
    np.testing.assert_allclose(pd, newton, rtol=0, atol=1e-6 * np.abs(newton).max())


def bar_problem() -> tuple[ElasticityProblem, TargetField]:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(2.0, 0.5, 0.5), cells=(8, 2, 2)) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    target = TargetField(domain.mesh, domain.region_cells("all"), bending_targets)
    problem = ElasticityProblem(domain, [("all", forms.make_law("shape_target", mu=1.0e3, S=target.function))], 1, 2)
    problem.add_load_hook(target.update)
    problem.add_dirichlet("xmin", [0, 1, 2], [0.0, 0.0, 0.0])
    problem.add_traction("xmax", [0.0, 30.0, -20.0])  # a dead load: its work is in the potential
    problem.add_body_force("all", [0.0, 0.0, -40.0])
    return problem, target


def test_energy_decreases_monotonically_and_the_matrix_is_factorised_once() -> None:
    problem, _ = bar_problem()
    PETSc.Log.begin()
    factorisations = PETSc.Log.Event("MatLUFactorNum")
    before = factorisations.getPerfInfo()["count"]
    solver = ProjectiveDynamicsSolver(problem, {"pd_rtol": 1e-6, "pd_max_iterations": 5000}, record_energy=True)
    records = []
    assert step_loads(solver, 2, on_step=records.append)
    assert [r.load_factor for r in records] == [0.5, 1.0]
    for record in records:
        result = record.result
        assert result.converged and result.reason_name == "CONVERGED_FNORM_RELATIVE"
        history = np.array(result.residual_history)
        assert len(history) == result.iterations + 1 and history[-1] <= 1e-6 * history[0]
        energy = np.array(result.energy_history)
        increase = np.diff(energy)
        assert np.all(increase <= 1e-12 * np.abs(energy).max()), f"energy went up by {increase.max():.3e}"
        assert energy[-1] < energy[0]
    assert factorisations.getPerfInfo()["count"] - before == 1
    assert solver.stiffness_assemblies == 1
    solver.destroy()


def test_projective_dynamics_reports_failure_after_max_iterations() -> None:
    problem, _ = bar_problem()
    problem.set_load_factor(1.0)
    solver = ProjectiveDynamicsSolver(problem, {"pd_rtol": 1e-10, "pd_max_iterations": 3})
    result = solver.solve()
    assert not result.converged and result.reason_name == "DIVERGED_MAX_IT"
    assert result.iterations == 3 and len(result.residual_history) == 4
    solver.destroy()


@pytest.mark.parametrize("law,params", [("neo_hookean", {"E": 1.0e4, "nu": 0.3}),
                                        ("shape_target", {"mu": 1.0e3, "kappa": 1.0e3})])
def test_projective_dynamics_needs_shape_targets_without_volume_term(law: str, params: dict) -> None:
    problem = box_problem(law, params)
    with pytest.raises(ValueError, match=r"^solver\.method: projective_dynamics needs every material"):
        ProjectiveDynamicsSolver(problem)


@pytest.mark.parametrize("change,key,fragment", [
    (lambda r: r["solver"].update(method="pd"), "solver.method", "'pd' is not one of newton, projective_dynamics"),
    (lambda r: r["material"][0].update(kappa=10.0), "solver.method", "kappa = 0 (material[0] is shape_target"),
    (lambda r: r["material"].__setitem__(0, {"region": "all", "law": "neo_hookean", "E": 1e4, "nu": 0.3}),
     "solver.method", "(material[0] is neo_hookean)"),
    (lambda r: r["solver"].update(pd_rtol=0.0), "solver.pd_rtol", "out of range"),
    (lambda r: r["solver"].update(pd_rtol="small"), "solver.pd_rtol", "must be a number"),
    (lambda r: r["solver"].update(pd_max_iterations=0), "solver.pd_max_iterations", "must be >= 1"),
    (lambda r: r["solver"].update(pd_max_iterations=2.5), "solver.pd_max_iterations", "must be an integer"),
    (lambda r: r["solver"].update(pd_atol=-1.0), "solver.pd_atol", "out of range"),
    (lambda r: r["solver"].update(method="newton"), "solver.pd_max_iterations", "only applies to method"),
])
def test_bad_projective_dynamics_keys_are_named(change, key: str, fragment: str) -> None:
    raw = bar_config({"method": "projective_dynamics", "pd_max_iterations": 100})
    change(raw)
    with pytest.raises(ConfigError) as err:
        parse(raw)
    message = str(err.value)
    assert message.startswith(f"{key}: ") and fragment in message and "\n" not in message, message
