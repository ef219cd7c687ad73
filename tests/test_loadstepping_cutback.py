"""Cut-back halves the step that failed, also when the end of the load range had shortened it, and the
give-up message says why and which keys change it (a solver stand-in: no mesh, no PETSc)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from model.solvers.loadstepping import step_loads
from model.solvers.newton import SolveResult


@dataclass
class FakeProblem:
    time: float = 0.0
    solution: object = field(default_factory=lambda: type("S", (), {"x": type("X", (), {"array": np.zeros(3)})()})())

    def set_load_factor(self, value: float) -> None:
        self.time = value


@dataclass
class FakeSolver:
    """Fails on the first attempt at each load factor in ``fail_once``, at every one above ``limit``."""

    problem: FakeProblem
    fail_once: set[float] = field(default_factory=set)
    limit: float = 2.0

    def solve(self) -> SolveResult:
        t = round(self.problem.time, 12)
        failed = t in self.fail_once or t > self.limit
        self.fail_once.discard(t)
        reason = -6 if failed else 2
        return SolveResult(not failed, reason, "DIVERGED_LINE_SEARCH" if failed else "CONVERGED_FNORM_RELATIVE", 3,
                           3, 1.0)


def test_a_failed_final_step_is_retried_lower() -> None:
    problem = FakeProblem(time=0.96)
    attempts = []
    ok = step_loads(FakeSolver(problem, fail_once={1.0}), steps=10, on_step=attempts.append)
    assert ok
    targets = [a.load_factor for a in attempts]
    assert targets[0] == 1.0 and not attempts[0].result.converged
    assert targets[1] < 1.0  # not the same failed target again
    assert targets[1] == 0.98  # half of the step 0.96 -> 1.0 that failed
    assert targets[-1] == 1.0


def test_give_up_reasons_name_the_keys() -> None:
    outcome = step_loads(FakeSolver(FakeProblem(), limit=0.0), steps=5, max_cutbacks=3)
    assert not outcome
    assert outcome.reason.startswith("load step to 0.025 failed 4 times in a row, more than loading.max_cutbacks = 3 "
                                     "(last SNES reason -6, DIVERGED_LINE_SEARCH); stopped at 0: raise "
                                     "loading.max_cutbacks, or loading.steps"), outcome.reason
    outcome = step_loads(FakeSolver(FakeProblem(), limit=0.3), steps=5, max_cutbacks=3)
    assert not outcome
    assert "the next increment 0.0187 would fall below the smallest allowed, 0.2 / 2^3 = 0.025 (loading.steps, " \
           "loading.max_cutbacks); stopped at 0.3" in outcome.reason, outcome.reason


@dataclass
class FailingSolver(FakeSolver):
    """Fails above ``limit`` with a given SNES reason and det F report."""

    reason_name: str = "DIVERGED_LINEAR_SOLVE"
    admissibility: dict | None = None

    def solve(self) -> SolveResult:
        result = super().solve()
        if result.converged:
            return result
        return SolveResult(False, -3, self.reason_name, 3, 3, 1.0, admissibility=self.admissibility)


def test_give_up_messages_match_the_cause() -> None:
    """A linear solver failure is not answered with more cut-backs; folded trial states are located."""
    outcome = step_loads(FailingSolver(FakeProblem(), limit=0.3), steps=5, max_cutbacks=3)
    assert "the linear solver failed in every attempt" in outcome.reason
    assert "raise loading.max_cutbacks" not in outcome.reason
    fold = {"min_det_F": -0.25, "min_det_F_point": [0.5, 0.25, 1.0]}
    outcome = step_loads(FailingSolver(FakeProblem(), limit=0.3, reason_name="DIVERGED_FUNCTION_DOMAIN",
                                       admissibility={"min_det_F": 0.4, "folded_trial": fold}), steps=5, max_cutbacks=3)
    assert "raise loading.max_cutbacks" in outcome.reason  # smaller steps may help here
    assert "every attempt folded cells (det F = -0.25 near (0.5, 0.25, 1) in its last trial state)" in outcome.reason
