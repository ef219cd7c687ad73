"""Inverse problems over quasi-static states: activations from a target deformation (issue 13 item 4).

    estimate = estimate_region_activations(problem, solver, alpha, regions, objective, initial=0.5)
    estimate = estimate_cell_activations(problem, solver, alpha, misfit, beta=1e-6, initial=0.5)

``alpha`` is the activation field (DG0) in the problem's muscle laws. The objective is a UFL form in the
problem's state (and alpha), e.g. the misfit 1/2 int |u - u_target|^2 dx. Each evaluation re-solves the
forward problem from the last converged state (Newton; the step from the last converged activations is
halved while Newton fails) and takes dJ/dalpha per cell from one adjoint solve (model.solvers.adjoint).

Per region (``estimate_region_activations``): ``regions`` maps a name to its cells; the unknowns are one
activation a_r in [0, 1] per region (alpha = a_r on the cells of region r); dJ/da_r is the sum of dJ/dalpha
over the region's cells. scipy's L-BFGS-B minimises J over the box [0, 1]^m; its iterates are the same on
every rank (values and gradients are reduced over the ranks).

Per cell (``estimate_cell_activations``): the unknowns are alpha's owned dofs themselves, one per cell, in
[0, 1], and the objective is

    J(alpha) = M(u(alpha), alpha) + beta R(alpha),
    R(alpha) = 1/2 sum_{F interior} int_F [alpha]^2 / h_F ds,   h_F = (h_+ + h_-) / 2,

with [alpha] = alpha_+ - alpha_- the jump of the piecewise constant alpha across the facet F and h_+-, the
diameters of its two cells (``smoothing_regulariser``: UFL with dS, an explicit quadrature degree). For DG0 it
is the facet sum sum_F |F| [alpha]_F^2 / (2 h_F), a graph Laplacian over the cells' neighbours weighted by
|F| / h_F: the discrete counterpart (the interior-penalty term of DG methods) of 1/2 int |grad alpha|^2 dx,
which a piecewise constant field does not have. Without it the per-cell problem is ill posed: many more
unknowns than the deformation determines. The optimiser is PETSc TAO BLMVM (bound-constrained limited-memory
quasi-Newton) on a distributed PETSc Vec of the owned dofs: on several ranks each rank owns its cells'
unknowns, TAO's vector operations (dot products, norms, the projection onto the bounds) reduce over the
communicator, so no rank gathers the whole vector (scipy would need every rank to hold all unknowns, and the
gradient gathered and its iterates broadcast by hand). The interior-facet integral needs the cells across
the rank border as ghosts (GhostMode.shared_facet: dolfinx 0.5's default; on 0.9
``build_domain(..., facet_ghosts=True)``); a mesh without ghost cells on several ranks is refused.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.solvers.adjoint import dirichlet_dofs, objective_value

log = logging.getLogger(__name__)


@dataclass
class ActivationEstimate:
    """The activations found (by region name), the objective there, the optimiser's iterations, forward
    solves and message, and the history of (activations, objective) per evaluation."""

    activations: dict[str, float]
    objective: float
    iterations: int
    evaluations: int
    converged: bool
    message: str
    history: list[tuple[list[float], float]] = field(default_factory=list)


@dataclass
class CellActivationEstimate:
    """Per-cell estimation: the activation field is left in ``alpha`` (and the forward solution at it in the
    problem); J = misfit + beta R there, its two parts, TAO's iterations, forward solves, converged reason
    (a TAO ConvergedReason: > 0 converged) and the history of (J, misfit, R) per evaluation."""

    objective: float
    misfit: float
    regularisation: float
    beta: float
    iterations: int
    evaluations: int
    converged: bool
    reason: int
    history: list[tuple[float, float, float]] = field(default_factory=list)


class _RegionMap:
    """alpha <-> per-region values: the owned DG0 dofs of each region's cells."""

    def __init__(self, alpha: fem.Function, regions: Mapping[str, np.ndarray]) -> None:
        space = alpha.function_space
        owned = space.dofmap.index_map.size_local
        cell_dofs = compat.cell_dofs(space.dofmap).reshape(-1)
        self.alpha = alpha
        self.names = list(regions)
        self.dofs = []
        for name in self.names:
            dofs = np.unique(cell_dofs[np.asarray(regions[name], dtype=np.int64)])
            self.dofs.append(dofs[dofs < owned])
        self.comm = space.mesh.comm

    def set(self, values: Sequence[float]) -> None:
        for dofs, value in zip(self.dofs, values):
            self.alpha.x.array[dofs] = value
        self.alpha.x.scatter_forward()

    def reduce(self, per_dof: np.ndarray) -> np.ndarray:
        """sum over each region's owned dofs of a per-owned-dof array, over all ranks."""
        local = np.array([float(np.sum(per_dof[dofs])) for dofs in self.dofs])
        return np.array(self.comm.allreduce(local, op=MPI.SUM))


def _empty(form: ufl.Form) -> bool:
    """True when the form is empty once its derivatives are expanded."""
    expanded = ufl.algorithms.expand_derivatives(form)
    return isinstance(expanded, ufl.Form) and expanded.empty()


def _assembled(form: compat.Form) -> PETSc.Vec:
    b = fem_petsc.assemble_vector(form)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return b


class CompiledGradient:
    """J and model.solvers.adjoint.adjoint_gradient's dJ/dp = dJ/dp|_u - lambda^T dR/dp, (dR/du)^T lambda = dJ/du
    (lambda = 0 on the Dirichlet dofs), with every form compiled once: an optimisation evaluates them hundreds of
    times, and building the forms (UFL's derivative expansion, the JIT cache lookup) took about 80 % of an
    evaluation on the 144-cell block. The Jacobian is the problem's own compiled one (problem.forms).
    tests/test_inverse.py checks it against adjoint_gradient."""

    def __init__(self, problem, objective: ufl.Form, parameter: fem.Function) -> None:
        V, P = problem.space, parameter.function_space
        self.problem, self.comm = problem, P.mesh.comm
        self.owned = P.dofmap.index_map.size_local * P.dofmap.index_map_bs
        self.value = fem.form(objective)
        self.dJdu = fem.form(ufl.derivative(objective, problem.solution, ufl.TestFunction(V)))
        dJdp = ufl.derivative(objective, parameter, ufl.TestFunction(P))
        dRdp = ufl.derivative(problem.residual_form, parameter, ufl.TrialFunction(P))
        self.dJdp = None if _empty(dJdp) else fem.form(dJdp)
        self.dRdp = None if _empty(dRdp) else fem.form(dRdp)
        if self.dJdp is None and self.dRdp is None:
            raise ValueError("activation estimation: the objective depends on the parameter neither directly nor "
                             "through the residual")

    def objective(self) -> float:
        return float(self.comm.allreduce(fem.assemble_scalar(self.value), op=MPI.SUM))

    def __call__(self) -> np.ndarray:
        """dJ/dp at the problem's current (converged) state, one value per owned dof of p. Collective."""
        problem = self.problem
        problem.update_state()
        A = fem_petsc.assemble_matrix(problem.forms[1], bcs=problem.bcs)
        A.assemble()
        rhs = _assembled(self.dJdu)
        with rhs.localForm() as local:
            local.array[dirichlet_dofs(problem)] = 0.0
        lam = rhs.duplicate()
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOperators(A)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType("mumps")
        ksp.solveTranspose(rhs, lam)
        reason = ksp.getConvergedReason()
        out = np.zeros(self.owned)
        if self.dJdp is not None:
            direct = _assembled(self.dJdp)
            out += direct.array_r[: self.owned]
            direct.destroy()
        if self.dRdp is not None:
            B = fem_petsc.assemble_matrix(self.dRdp, bcs=problem.bcs)  # Dirichlet rows zeroed
            B.assemble()
            correction = B.createVecRight()
            B.multTranspose(lam, correction)
            out -= correction.array_r[: self.owned]
            B.destroy()
            correction.destroy()
        for obj in (A, rhs, lam, ksp):
            obj.destroy()
        if reason < 0:
            raise RuntimeError(f"activation estimation: the transposed solve failed (KSP reason {reason})")
        return out


class _Forward:
    """The forward solve at parameters a (a numpy array: per region, or alpha's owned dofs), warm started from
    the last converged state; while Newton fails the step from the last converged parameters is halved (at
    most ``max_halvings`` times in a row). Collective: Newton's verdict is the same on every rank."""

    def __init__(self, problem, solver, apply: Callable[[np.ndarray], None], max_halvings: int) -> None:
        self.problem, self.solver, self.apply, self.max_halvings = problem, solver, apply, max_halvings
        self.last: np.ndarray | None = None
        self.state = problem.solution.x.array.copy()

    def __call__(self, a: np.ndarray) -> None:
        base = self.last if self.last is not None else a
        step, halvings = 1.0, 0
        while True:
            trial = base + step * (a - base)
            self.apply(trial)
            self.problem.invalidate_state()
            result = self.solver.solve()
            if result.converged:
                self.state = self.problem.solution.x.array.copy()
                if step == 1.0:
                    self.last = a.copy()
                    return
                base, step = trial, 1.0  # a converged intermediate point: go on from it to a
                continue
            self.problem.solution.x.array[:] = self.state
            halvings += 1
            if halvings > self.max_halvings:
                raise RuntimeError(f"activation estimation: the forward problem failed ({result.reason_name}) "
                                   f"after {self.max_halvings} halvings of the step towards the parameters")
            step *= 0.5


def estimate_region_activations(problem, solver, alpha: fem.Function, regions: Mapping[str, np.ndarray],
                                objective: ufl.Form, initial: float | Sequence[float] = 0.5,
                                gtol: float = 1e-12, max_iterations: int = 100,
                                max_halvings: int = 8) -> ActivationEstimate:
    """Minimise ``objective`` over one activation per region in [0, 1] (module docstring). ``solver`` is a
    NewtonSolver of ``problem`` at its final load factor; the problem's state is the forward solution at the
    activations returned. ``gtol``: L-BFGS-B's projected-gradient tolerance, relative to the gradient at the
    start. Collective."""
    from scipy.optimize import minimize

    mapping = _RegionMap(alpha, regions)
    comm = mapping.comm
    start = np.broadcast_to(np.asarray(initial, dtype=float), (len(mapping.names),)).copy()
    forward = _Forward(problem, solver, mapping.set, max_halvings)
    compiled = CompiledGradient(problem, objective, alpha)
    history: list[tuple[list[float], float]] = []
    scale = {"J": None}

    def evaluate(a: np.ndarray) -> tuple[float, np.ndarray]:
        forward(a)
        value = compiled.objective()
        gradient = mapping.reduce(compiled())
        if scale["J"] is None:
            scale["J"] = max(abs(value), np.finfo(float).tiny)
        history.append((a.tolist(), value))
        log.debug("activations %s: J = %.6e, |dJ/da| = %.3e", a, value, np.linalg.norm(gradient))
        return value / scale["J"], gradient / scale["J"]

    result = minimize(evaluate, start, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * len(start),
                      options={"gtol": gtol, "ftol": 1e-15, "maxiter": max_iterations})
    forward(np.asarray(result.x))
    value = objective_value(objective, comm)
    return ActivationEstimate(dict(zip(mapping.names, map(float, result.x))), value, int(result.nit),
                              int(result.nfev), bool(result.success), str(result.message), history)


def smoothing_regulariser(alpha: fem.Function, quadrature_degree: int = 0) -> ufl.Form:
    """R(alpha) = 1/2 sum_{F interior} int_F [alpha]^2 / h_F ds with h_F = avg(h), h the cell diameter (module
    docstring): for DG0 alpha, sum_F |F| (alpha_+ - alpha_-)^2 / (2 h_F). The integrand is constant on each
    facet of an affine mesh: degree 0 integrates it exactly."""
    msh = alpha.function_space.mesh
    h = ufl.avg(ufl.CellDiameter(msh))
    dS = ufl.dS(domain=msh, metadata={"quadrature_degree": quadrature_degree})
    return 0.5 * ufl.jump(alpha) ** 2 / h * dS


def _has_facet_ghosts(msh) -> bool:
    """On one rank True; on several, whether the mesh has ghost cells (the cells across the rank border that
    interior-facet integrals on it need), on any rank."""
    if msh.comm.size == 1:
        return True
    ghosts = msh.topology.index_map(msh.topology.dim).num_ghosts
    return bool(msh.comm.allreduce(int(ghosts), op=MPI.SUM) > 0)


def estimate_cell_activations(problem, solver, alpha: fem.Function, misfit: ufl.Form, beta: float,
                              initial: float | np.ndarray = 0.5, fixed: np.ndarray | None = None,
                              regulariser: ufl.Form | None = None, gatol: float = 1e-9, grtol: float = 0.0,
                              gttol: float = 1e-7, max_iterations: int = 500,
                              max_halvings: int = 8) -> CellActivationEstimate:
    """Minimise J(alpha) = misfit + beta R(alpha) over one activation per cell in [0, 1] by TAO BLMVM (module
    docstring); R is ``smoothing_regulariser(alpha)`` unless ``regulariser`` is given. ``initial``: a value, or
    one per owned dof of alpha. ``fixed``: cells whose activation stays at ``initial`` (their bounds are equal),
    e.g. cells of passive tissue. ``solver`` is a NewtonSolver of ``problem`` at its final load factor.

    TAO sees J / J(initial) (its gradient likewise): ``gatol`` bounds |grad| of that scaled J, ``gttol`` the
    ratio |grad| / |grad at the start|, ``grtol`` |grad| / |J|. On return alpha holds the activations found and
    the problem the forward solution there. Collective."""
    space = alpha.function_space
    msh = space.mesh
    comm = msh.comm
    if not _has_facet_ghosts(msh):
        raise ValueError("estimate_cell_activations: the smoothing term integrates over interior facets, which "
                         "on several ranks needs a mesh with ghost cells (ghost_mode shared_facet)")
    owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
    regulariser = smoothing_regulariser(alpha) if regulariser is None else regulariser
    objective = misfit + beta * regulariser

    def apply(values: np.ndarray) -> None:
        alpha.x.array[:owned] = values
        alpha.x.scatter_forward()

    forward = _Forward(problem, solver, apply, max_halvings)
    compiled = CompiledGradient(problem, objective, alpha)
    parts_forms = (fem.form(misfit), fem.form(regulariser))

    def parts() -> tuple[float, float]:
        return tuple(float(comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM)) for f in parts_forms)

    x = PETSc.Vec().createMPI((owned, PETSc.DECIDE), comm=comm)
    x.array[:] = np.broadcast_to(np.asarray(initial, dtype=float), (owned,))
    lower, upper = x.duplicate(), x.duplicate()
    lower.set(0.0)
    upper.set(1.0)
    if fixed is not None:
        dofs = np.unique(compat.cell_dofs(space.dofmap)[np.asarray(fixed, dtype=np.int64)].reshape(-1))
        dofs = dofs[dofs < owned]
        lower.array[dofs] = x.array[dofs]
        upper.array[dofs] = x.array[dofs]
    history: list[tuple[float, float, float]] = []
    scale = {"J": None}

    def objective_gradient(tao, v, g):  # noqa: ANN001, ANN202 - TAO's callback signature
        forward(v.array_r.copy())
        value, split = compiled.objective(), parts()
        gradient = compiled()
        if scale["J"] is None:
            scale["J"] = max(abs(value), np.finfo(float).tiny)
        g.array[:] = gradient / scale["J"]
        history.append((value, *split))
        log.debug("per-cell activations: J = %.6e (misfit %.6e, R %.6e)", value, *split)
        return value / scale["J"]

    tao = PETSc.TAO().create(comm)
    tao.setType("blmvm")
    gradient = x.duplicate()
    tao.setObjectiveGradient(objective_gradient, gradient)
    tao.setVariableBounds(lower, upper)
    tao.setTolerances(gatol=gatol, grtol=grtol, gttol=gttol)
    tao.setMaximumIterations(max_iterations)
    tao.setSolution(x)
    tao.solve()
    reason, iterations = int(tao.getConvergedReason()), int(tao.getIterationNumber())
    forward(x.array_r.copy())
    value, split = compiled.objective(), parts()
    evaluations = len(history)
    for obj in (tao, x, lower, upper, gradient):
        obj.destroy()
    log.info("per-cell activations: TAO BLMVM reason %d after %d iterations, %d evaluations; J = %.6e",
             reason, iterations, evaluations, value)
    return CellActivationEstimate(value, *split, float(beta), iterations, evaluations, reason > 0, reason, history)


__all__ = ["ActivationEstimate", "CellActivationEstimate", "CompiledGradient", "estimate_cell_activations",
           "estimate_region_activations", "smoothing_regulariser"]
