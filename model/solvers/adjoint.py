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

Material parameters (mu, lmbda, c1, K, sigma_max, ... of a region's law) are numbers in the residual, not
coefficients: material_gradient rebuilds the region's term with the parameter held by a DG0 Function c (the
law's validation done on its number) and takes dR/dc = ufl.derivative of that term, per cell or summed over
the region (the scalar parameter):

    dmu = material_gradient(problem, J, region="all", parameter="mu")                 # float, every rank
    dmu_K = material_gradient(problem, J, region="all", parameter="mu", per_cell=True)  # per owned cell

Taylor test (tests/test_adjoint.py): |J(p + h dp) - J(p) - h g . dp| shrinks as h^2.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.law import Law, with_parameter_values
from forms.polar import linearised_rotation
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


def _adjoint_solve(problem: ElasticityProblem, objective: ufl.Form) -> PETSc.Vec:
    """lambda: (dR/du)^T lambda = dJ/du, lambda = 0 on the Dirichlet dofs (MUMPS LU of the consistent Jacobian,
    assembled at the current state after update_state). The caller destroys the vector. Collective."""
    problem.update_state()  # quadrature-point states (polar, eigen) of the current solution
    V = problem.space
    A = fem_petsc.assemble_matrix(fem.form(ufl.derivative(problem.residual_form, problem.solution,
                                                          ufl.TrialFunction(V))), bcs=problem.bcs)
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
    for obj in (A, dJdu, ksp):
        obj.destroy()
    if reason < 0:
        lam.destroy()
        raise RuntimeError(f"adjoint: the transposed solve failed (KSP reason {reason})")
    return lam


def _gradient(problem: ElasticityProblem, lam: PETSc.Vec, dRdp_form: ufl.Form, dJdp_form: ufl.Form,
              space: fem.FunctionSpace) -> np.ndarray:
    """dJ/dp|_u - lambda^T dR/dp on the owned dofs of ``space`` (the Dirichlet rows of dR/dp zeroed)."""
    gradient = _vector(dJdp_form, space)
    if not _is_zero(dRdp_form):
        B = fem_petsc.assemble_matrix(fem.form(dRdp_form), bcs=problem.bcs)  # Dirichlet rows zeroed
        B.assemble()
        correction = gradient.duplicate()
        B.multTranspose(lam, correction)
        gradient.axpy(-1.0, correction)
        B.destroy()
        correction.destroy()
    owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
    out = gradient.array_r[:owned].copy()
    gradient.destroy()
    return out


def _store(lam: PETSc.Vec, adjoint: fem.Function | None) -> None:
    if adjoint is not None:
        with lam.localForm() as local:
            adjoint.x.array[:] = local.array_r[: len(adjoint.x.array)]
        adjoint.x.scatter_forward()


def adjoint_gradient(problem: ElasticityProblem, objective: ufl.Form, parameter: fem.Function,
                     adjoint: fem.Function | None = None) -> np.ndarray:
    """dJ/dp at the problem's current (converged) state: one value per owned dof of ``parameter``'s space
    (its vector's owned entries). ``adjoint``: a Function of the problem's space that receives lambda.
    Collective."""
    P = parameter.function_space
    lam = _adjoint_solve(problem, objective)
    out = _gradient(problem, lam, ufl.derivative(problem.residual_form, parameter, ufl.TrialFunction(P)),
                    ufl.derivative(objective, parameter, ufl.TestFunction(P)), P)
    _store(lam, adjoint)
    lam.destroy()
    return out


def owned_cell_values(field: fem.Function, per_dof: np.ndarray) -> np.ndarray:
    """A per-owned-dof array of a DG0 scalar ``field``'s space (adjoint_gradient's) as one value per owned cell
    (local cell index)."""
    space = field.function_space
    cells = space.mesh.topology.index_map(space.mesh.topology.dim).size_local
    dofs = compat.cell_dofs(space.dofmap)[:cells, 0]
    return np.asarray(per_dof)[dofs]


def region_gradient(problem: ElasticityProblem, per_cell: np.ndarray, region: str) -> float:
    """dJ/dp of one value p per region (the field equal to p on every cell of ``region``): by the chain rule
    the sum of the per-cell gradient (one value per owned cell, owned_cell_values) over the region's cells, over
    all ranks. Collective."""
    owned = len(per_cell)
    cells = problem.domain.region_cells(region)
    cells = cells[cells < owned]
    return float(problem.domain.mesh.comm.allreduce(float(np.sum(per_cell[cells])), op=MPI.SUM))


def material_term(problem: ElasticityProblem, index: int, law: Law) -> ufl.Form:
    """The residual term of ``problem.materials[index]``'s region built with ``law`` in place of the material's:
    int P(F; R) : grad v dx_r (+ int (g(F) - p / kappa) q dx_r in the mixed formulation), as
    ElasticityProblem._add_material builds it, R the linearised polar rotation of law.rotation_argument(F) about
    the problem's quadrature-point state R0 (the polar fields are one per law with a rotation, in material order)."""
    region, own = problem.materials[index]
    R = None
    if own.needs_rotation:
        rotating = [i for i, (_, m) in enumerate(problem.materials) if m.needs_rotation]
        if len(rotating) != len(problem.polar_fields):
            raise RuntimeError("material_term: the problem's polar fields do not match its materials")
        polar = problem.polar_fields[rotating.index(index)]
        R = linearised_rotation(law.rotation_argument(problem.F), polar.R0)
    dx = problem.energy_measure(region)
    term = ufl.inner(law.stress(problem.F, R, problem.p), ufl.grad(problem.v)) * dx
    if problem.p is not None:
        term += law.pressure_residual(problem.F, problem.p) * problem.q * dx
    return term


class _ParameterField(fem.Function):
    """A DG0 Function that is never a number: float() and complex() raise TypeError at once, so a law that
    computes with its parameter outside UFL (math.exp(P2 ...)) fails there instead of UFL trying to evaluate
    the Function (a recursion that takes minutes before it fails)."""

    def __float__(self) -> float:
        raise TypeError(f"{self.name} is a field, not a number")

    def __complex__(self) -> complex:
        raise TypeError(f"{self.name} is a field, not a number")


def _check_same_term(problem: ElasticityProblem, index: int, law: Law, term: ufl.Form, parameter: str) -> None:
    """ValueError unless the rebuilt term (the law holding its parameter as a field) assembles to the residual's
    term (the law with the number) at the current state, to 1e-10 relative: a law that branches on the
    parameter's value in Python (``if c3 != 0``) would take another branch with a UFL value."""
    V = problem.space
    vectors = [_vector(form, V) for form in (material_term(problem, index, law), term)]
    scale = vectors[0].norm()
    vectors[1].axpy(-1.0, vectors[0])
    difference = vectors[1].norm()
    for vec in vectors:
        vec.destroy()
    if difference > 1e-10 * max(scale, np.finfo(float).tiny):
        raise ValueError(f"material_gradient: {law.name} with {parameter} as a field gives another residual than "
                         f"with its number (|difference| = {difference:.3e} of {scale:.3e}): the law computes "
                         "with the parameter's value outside UFL")


def material_gradient(problem: ElasticityProblem, objective: ufl.Form, region: str = "all", parameter: str = "mu",
                      per_cell: bool = False, adjoint: fem.Function | None = None) -> float | np.ndarray:
    """dJ/dp for p = the scalar parameter ``parameter`` (a float field of the law: mu, lmbda, c1, K, sigma_max,
    ...) of the material on ``region``, at the problem's current (converged) state. Collective.

    The residual holds the parameter as a literal number, which ufl.derivative cannot see. The region's term is
    rebuilt (material_term) with the law holding a DG0 Function c in place of the number (forms.law
    .with_parameter_values: the law's validation runs on the number), c = p on every cell; the rest of the residual
    does not depend on p, so

        dR/dc = ufl.derivative(term(c), c),     dJ/dc_K = - lambda^T dR/dc_K     (per cell K)

    with lambda the adjoint of adjoint_gradient (J must not depend on p explicitly: the parameter is no
    coefficient of the objective). ``per_cell``: the gradient with respect to a parameter field per cell (one
    value per owned cell, local index; zero outside the region), else the region's scalar p:
    dJ/dp = sum_K dJ/dc_K (region_gradient), the same on every rank.

    ValueError: no or several materials on ``region``; not a float parameter of the law; inf (incompressible);
    a law whose parameters enter through numbers computed outside UFL (an eigen state, math of the parameters:
    e.g. muscle's P2 or l_ofl), which ufl.derivative cannot follow; a rebuilt term that does not assemble to the
    residual's own at the current state (1e-10 relative: a law branching on the parameter's value).
    """
    matches = [i for i, (r, _) in enumerate(problem.materials) if r == region]
    if len(matches) != 1:
        regions = ", ".join(repr(r) for r, _ in problem.materials)
        raise ValueError(f"material_gradient: {len(matches)} materials on region {region!r} (regions: {regions})")
    index = matches[0]
    law = problem.materials[index][1]
    if getattr(law, "needs_eigenbasis", False):
        raise ValueError(f"material_gradient: {law.name}'s eigen state is computed in numpy from its parameters "
                         "(ufl.derivative cannot follow it)")
    msh = problem.domain.mesh
    space = compat.function_space(msh, "DG", 0)
    c = _ParameterField(space, name=parameter)
    value = getattr(law, parameter, None)
    symbolic = with_parameter_values(law, {parameter: (c, [value] if value is not None else [])})
    c.x.array[:] = float(value)
    try:
        term = material_term(problem, index, symbolic)
        dRdc = ufl.algorithms.expand_derivatives(ufl.derivative(term, c, ufl.TrialFunction(space)))
    except (TypeError, ValueError, AttributeError) as err:
        raise ValueError(f"material_gradient: {law.name}'s {parameter} enters the law through numbers, not UFL "
                         f"({type(err).__name__}: {err})") from None
    if dRdc.empty():
        raise ValueError(f"material_gradient: the residual of {law.name} does not depend on {parameter}")
    _check_same_term(problem, index, law, term, parameter)
    lam = _adjoint_solve(problem, objective)
    per_dof = _gradient(problem, lam, dRdc, ufl.derivative(objective, c, ufl.TestFunction(space)), space)
    _store(lam, adjoint)
    lam.destroy()
    cells = owned_cell_values(c, per_dof)
    return cells if per_cell else region_gradient(problem, cells, region)


def objective_value(objective: ufl.Form, comm: MPI.Comm) -> float:
    """J assembled and summed over the ranks."""
    return float(comm.allreduce(fem.assemble_scalar(fem.form(objective)), op=MPI.SUM))


__all__ = ["adjoint_gradient", "dirichlet_dofs", "material_gradient", "material_term", "objective_value",
           "owned_cell_values", "region_gradient"]
