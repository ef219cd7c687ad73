"""How it is solved: our SNES driver (newton), load stepping, the projected tangent, Projective
Dynamics, the contact loops (VI bounds, Uzawa), the time integrators (dynamics) and the check of the
PETSc option values before a run (options)."""

from model.solvers.loadstepping import Outcome, StepRecord, step_loads
from model.solvers.newton import DEFAULT_OPTIONS, NewtonSolver, SolveResult

__all__ = ["DEFAULT_OPTIONS", "NewtonSolver", "Outcome", "SolveResult", "StepRecord", "step_loads"]
