"""Adjoint gradients of an objective J(u(p), p) over a converged quasi-static state.

With R(u, p) = 0 the problem's residual (problem.residual_form: every material, load, penalty contact and
sliding term) and p a coefficient of it (a Function: activation per cell, shape targets S, a field of
parameters), the total derivative is

    dJ/dp = dJ/dp|_u - lambda^T dR/dp,    (dR/du)^T lambda = dJ/du,   lambda = 0 on the Dirichlet dofs,

one transposed solve with the consistent Jacobian (UFL: ufl.derivative of the residual), whatever the number
of parameters. dJ/du, dJ/dp and dR/dp are ufl.derivative of the objective and of the residual too. The
Dirichlet data must not depend on p (the Dirichlet rows of dR/dp are zero). The state must be converged:
the gradient is that of the discrete solution map only where R(u, p) = 0.

    g = adjoint_gradient(problem, J, p)    # J a UFL form in problem.u (and p); g: one value per local dof of p

Taylor test (tests/test_adjoint.py): |J(p + h dp) - J(p) - h g . dp| shrinks as h^2.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.problem import ElasticityProblem


def _is_zero(form: ufl.Form) -> bool:
    """True when the form is empty once its derivatives are expanded (J does not depend on p, ...)."""
    expanded = ufl.algorithms.expand_derivatives(form)
    return isinstance(expanded, ufl.Form) and expanded.empty()


def _vector(form: ufl.Form, space: fem.FunctionSpace) -> PETSc.Vec:
    """The assembled vector of ``form`` (owned + ghost layout of ``space``), zero when the form is empty."""
    if _is_zero(form):
        zero = fem.Function(space)  # held: its vector wraps the Function's memory until copied
        return compat.petsc_vector(zero).copy()
    b = fem_petsc.assemble_vector(fem.form(form))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


def dirichlet_dofs(problem: ElasticityProblem) -> np.ndarray:
    """The owned Dirichlet dofs of the problem's space (unrolled indices of its vectors)."""
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    dofs = [np.asarray(bc.dof_indices()[0], dtype=np.int64) for bc in problem.bcs]
    all_dofs = np.unique(np.concatenate(dofs)) if dofs else np.empty(0, dtype=np.int64)
    return all_dofs[all_dofs < owned]


def adjoint_gradient(problem: ElasticityProblem, objective: ufl.Form, parameter: fem.Function,
                     adjoint: fem.Function | None = None) -> np.ndarray:
    """dJ/dp at the problem's current (converged) state: one value per owned dof of ``parameter``'s space
    (its vector's owned entries). ``adjoint``: a Function of the problem's space that receives lambda.
    Collective."""
    problem.update_state()  # quadrature-point states (polar, eigen) of the current solution
    V, P = problem.space, parameter.function_space
    residual = problem.residual_form
    A = fem_petsc.assemble_matrix(fem.form(ufl.derivative(residual, problem.solution, ufl.TrialFunction(V))),
                                  bcs=problem.bcs)
    A.assemble()
    dJdu = _vector(ufl.derivative(objective, problem.solution, ufl.TestFunction(V)), V)
    fixed = dirichlet_dofs(problem)
    with dJdu.localForm() as local:
        local.array[fixed] = 0.0  # lambda = 0 on the Dirichlet dofs (the rows of A there are the identity)
    lam = dJdu.duplicate()
    ksp = PETSc.KSP().create(problem.domain.mesh.comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.solveTranspose(dJdu, lam)
    reason = ksp.getConvergedReason()
    dRdp_form = ufl.derivative(residual, parameter, ufl.TrialFunction(P))
    gradient = _vector(ufl.derivative(objective, parameter, ufl.TestFunction(P)), P)
    if not _is_zero(dRdp_form):
        B = fem_petsc.assemble_matrix(fem.form(dRdp_form), bcs=problem.bcs)  # Dirichlet rows zeroed
        B.assemble()
        correction = gradient.duplicate()
        B.multTranspose(lam, correction)
        gradient.axpy(-1.0, correction)
        B.destroy()
        correction.destroy()
    if adjoint is not None:
        with lam.localForm() as local:
            adjoint.x.array[:] = local.array_r[: len(adjoint.x.array)]
        adjoint.x.scatter_forward()
    owned = P.dofmap.index_map.size_local * P.dofmap.index_map_bs
    out = gradient.array_r[:owned].copy()
    for obj in (A, dJdu, lam, ksp, gradient):
        obj.destroy()
    if reason < 0:
        raise RuntimeError(f"adjoint: the transposed solve failed (KSP reason {reason})")
    return out


def objective_value(objective: ufl.Form, comm: MPI.Comm) -> float:
    """J assembled and summed over the ranks."""
    return float(comm.allreduce(fem.assemble_scalar(fem.form(objective)), op=MPI.SUM))


__all__ = ["adjoint_gradient", "dirichlet_dofs", "objective_value"]
