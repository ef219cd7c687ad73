"""Load stepping: a step SNES cannot take is cut back, the increment grows again afterwards,
and the run still reaches load factor 1 with the same answer as a run in many small steps."""

from __future__ import annotations

import numpy as np
from conftest import example, run_raw


def test_cut_back_and_regrow(shared_tmp) -> None:
    raw = example("uniaxial")
    raw["boundary"][3]["value"] = [3.0e4, 0.0, 0.0]  # a large stretch: not reachable in 4 Newton iterations
    raw["loading"] = {"steps": 1, "growth": 2.0}
    raw["solver"] = {"petsc_options": {"snes_max_it": 4, "snes_linesearch_type": "basic"}}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp / "one_step")
    steps = summary["steps"]
    assert summary["status"] == "completed"
    assert not steps[0]["converged"] and steps[0]["load_factor"] == 1.0 and steps[0]["snes_reason"] < 0
    converged = [s["load_factor"] for s in steps if s["converged"]]
    assert converged[-1] == 1.0
    increments = np.diff([0.0, *converged])
    assert increments.min() < 0.5 and np.any(np.diff(increments) > 0), increments  # cut back, then regrown
    raw["loading"] = {"steps": 20}
    reference = run_raw(raw, shared_tmp / "small_steps")
    np.testing.assert_allclose(steps[-1]["probes"]["corner"], reference["steps"][-1]["probes"]["corner"],
                               rtol=1e-9)


def test_gives_up_instead_of_crawling(shared_tmp) -> None:
    """A solver that only manages tiny increments must stop once the increment falls below
    nominal / 2^max_cutbacks, even when failures alternate with successes."""
    from model.config import parse
    from model.pipeline import build
    from model.solvers.loadstepping import step_loads
    from model.solvers.newton import NewtonSolver

    raw = example("uniaxial")
    raw["boundary"][3]["value"] = [3.0e4, 0.0, 0.0]
    setup = build(parse(raw))
    solver = NewtonSolver(setup.problem, {"snes_max_it": 4, "snes_linesearch_type": "basic"})
    attempts = []
    ok = step_loads(solver, steps=1, max_cutbacks=2, growth=2.0, on_step=attempts.append)
    assert not ok
    increments = [a.load_factor for a in attempts]
    assert len(increments) < 40, increments
    solver.destroy()
