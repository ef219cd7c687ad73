"""Why a load step failed: an instability of the structure, or a solver that could not follow.

When load stepping gives up, ``diagnose`` looks at the tangent K = dR/du of the last converged state u_c
(load factor lambda_c) and of the last failed iterate:

* its inertia: the number of negative eigenvalues of the symmetric part (K + K^T)/2 (a follower pressure's
  load stiffness is not symmetric), from the pivots of an LDL^T factorisation (MUMPS Cholesky, Sylvester's law
  of inertia; ICNTL(13) = 1 so that the count is exact on any number of ranks). In the displacement
  formulation a stable state has none; in the mixed one the saddle point [A B^T; B -C] has exactly as many
  as there are pressure dofs when A is positive definite on the constraint, so the count beyond that is what
  says the structure lost stability. Dirichlet rows are identity rows (+1).
* the current stiffness parameter (Bergan): S = (f . K_0^-1 f) / (f_c . K_c^-1 f_c), the stiffness along the
  load at lambda_c over that of the unloaded state; S -> 0 at a load maximum (a limit point, where
  dlambda/du = 0), S < 0 beyond it.

Either sign (negative eigenvalues beyond the constraint count, or S < LIMIT_STIFFNESS) names an instability
(a limit point or a bifurcation of the structure, physics, not the solver): no smaller load step can pass it, and
the advice is path following ([loading] control = "arc_length", or "volume" for a pressure load). Otherwise
the failure is the solver's and the load stepping's own advice stands.
"""

from __future__ import annotations

import itertools
import logging
import math
from typing import Any

import numpy as np
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

log = logging.getLogger(__name__)

#: S below this (the stiffness along the load, relative to the unloaded state's) names a limit point
LIMIT_STIFFNESS = 0.05
#: above this many unknowns the report is not made (four sparse direct factorisations: minutes and gigabytes)
MAX_DOFS = 300_000
_counter = itertools.count()


def _pressure_dofs(problem: Any) -> int:
    """The number of pressure dofs of the mixed formulation (global), 0 in the displacement formulation."""
    if problem.formulation != "mixed":
        return 0
    space, _ = problem.space.sub(1).collapse()
    imap = space.dofmap.index_map
    return int(imap.size_global * space.dofmap.index_map_bs)


def _jacobian(solver: Any) -> PETSc.Mat:
    """K at the problem's current solution and load factor, one assembled matrix (Dirichlet rows identity)."""
    problem = solver.problem
    problem.update_state()
    if solver.projected is not None:
        solver.projected.update()
    A = fem_petsc.assemble_matrix(solver.jacobian_form, bcs=problem.bcs)
    A.assemble()
    for coupling in problem.couplings:
        coupling.add_jacobian(A)
        A.assemble()
    return A


def inertia(solver: Any) -> tuple[int, int, int]:
    """(negative, zero, positive) eigenvalue counts of (K + K^T)/2 at the current state (collective)."""
    A = _jacobian(solver)
    At = A.transpose(PETSc.Mat())
    At.axpy(1.0, A)  # different patterns allowed: contact couplings need not be symmetric in pattern
    At.scale(0.5)
    A.destroy()
    prefix = f"stability{next(_counter)}_"
    options = PETSc.Options()
    values = {"ksp_type": "preonly", "pc_type": "cholesky", "pc_factor_mat_solver_type": "mumps",
              "mat_mumps_icntl_13": 1, "mat_mumps_icntl_24": 1}
    for key, value in values.items():
        options[f"{prefix}{key}"] = value
    ksp = PETSc.KSP().create(solver.problem.domain.mesh.comm)
    try:
        ksp.setOptionsPrefix(prefix)
        ksp.setOperators(At)
        ksp.setFromOptions()
        ksp.setUp()
        counts = ksp.getPC().getFactorMatrix().getInertia()
        return int(counts[0]), int(counts[1]), int(counts[2])
    finally:
        ksp.destroy()
        At.destroy()
        for key in values:
            options.delValue(f"{prefix}{key}")


def _load_vector(problem: Any) -> PETSc.Vec | None:
    """f = the loads at load factor 1 at the current state (Dirichlet rows 0), or None without loads."""
    form = problem.unit_load_form()
    if form is None:
        return None
    f = fem_petsc.assemble_vector(form)
    f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    problem.zero_dirichlet_rows(f)
    return f


def _stiffness_along_load(solver: Any) -> float | None:
    """f . K^-1 f at the current state (collective); None without loads or when the solve fails."""
    problem = solver.problem
    f = _load_vector(problem)
    if f is None or f.norm() == 0.0:
        return None
    A = _jacobian(solver)
    ksp = PETSc.KSP().create(problem.domain.mesh.comm)
    b = f.duplicate()
    try:
        ksp.setOperators(A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        ksp.solve(f, b)
        value = f.dot(b)
        return float(value) if math.isfinite(value) and value != 0.0 else None
    finally:
        ksp.destroy()
        A.destroy()
        b.destroy()
        f.destroy()


def diagnose(solver: Any, failed_state: np.ndarray | None = None) -> dict[str, Any] | None:
    """The stability report (module docstring; None above MAX_DOFS unknowns or when a factorisation fails) of the
    last converged state (the problem's current solution and load factor) and,
    when given, of the last failed iterate (its solution array): {"load_factor", "negative_eigenvalues",
    "constraint_eigenvalues", "stiffness_ratio", "unstable", "message"}; None for a solver without a tangent
    (collective)."""
    if solver is None or not hasattr(solver, "jacobian_form"):
        return None
    problem = solver.problem
    comm = problem.domain.mesh.comm
    dofs = problem.space.dofmap.index_map.size_global * problem.space.dofmap.index_map_bs
    if dofs > MAX_DOFS:
        log.info("stability report skipped: %d unknowns (more than %d)", dofs, MAX_DOFS)
        return None
    lam = float(problem.time)
    expected = _pressure_dofs(problem)
    report: dict[str, Any] = {"load_factor": lam, "constraint_eigenvalues": expected}
    try:
        negative, zero, _ = inertia(solver)
        report["negative_eigenvalues"] = negative - expected
        report["zero_eigenvalues"] = zero
        failed_negative = None
        saved = problem.solution.x.array.copy()
        if failed_state is not None and np.all(np.isfinite(failed_state)):
            problem.solution.x.array[:] = failed_state
            problem.invalidate_state()
            try:
                failed_negative = inertia(solver)[0] - expected
            finally:
                problem.solution.x.array[:] = saved
                problem.invalidate_state()
            report["negative_eigenvalues_failed_iterate"] = failed_negative
        current = _stiffness_along_load(solver)
        initial = None
        if current is not None:  # K_0: the unloaded state (u = 0, p = 0 at load factor 0)
            problem.solution.x.array[:] = 0.0
            problem.set_load_factor(0.0)
            problem.invalidate_state()
            try:
                initial = _stiffness_along_load(solver)
            finally:
                problem.solution.x.array[:] = saved
                problem.set_load_factor(lam)
                problem.invalidate_state()
                problem.update_state()
        ratio = initial / current if current and initial else None
        report["stiffness_ratio"] = ratio
    except Exception as err:  # noqa: BLE001 - a diagnosis only (e.g. MUMPS out of memory): the run's message stands
        log.warning("stability report not made (%s: %s)", type(err).__name__, err)
        return None
    unstable = report["negative_eigenvalues"] > 0 or (failed_negative is not None and failed_negative > 0) \
        or (ratio is not None and ratio < LIMIT_STIFFNESS)
    report["unstable"] = bool(comm.allreduce(unstable, op=MPI.LOR))
    if report["unstable"]:
        parts = []
        if report["negative_eigenvalues"] > 0:
            parts.append(f"{report['negative_eigenvalues']} negative eigenvalue(s) of the tangent at load {lam:.6g}")
        elif failed_negative:
            parts.append(f"{failed_negative} negative eigenvalue(s) of the tangent just beyond load {lam:.6g}")
        if ratio is not None:
            parts.append(f"the stiffness along the load fell to {ratio:.3g} of its initial value")
        negative = report["negative_eigenvalues"] > 0 or bool(failed_negative)
        lost = "lost positive definiteness" if negative else "became singular along the load"
        report["message"] = (f"the tangent {lost} at load factor {lam:.6g} ({'; '.join(parts)}): "
                             "a limit point or bifurcation (an instability of the structure), not a solver failure; "
                             "smaller load steps cannot pass it: follow the path with [loading] control = "
                             "\"arc_length\" (or control = \"volume\" for a pressure load)")
    return report
