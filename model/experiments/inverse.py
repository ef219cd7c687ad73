"""Inverse problems over quasi-static states: activations from a target deformation (issue 13 item 4).

    estimate = estimate_region_activations(problem, solver, alpha, regions, objective, initial=0.5)

``alpha`` is the activation field (DG0) in the problem's muscle laws; ``regions`` maps a name to its cells;
the unknowns are one activation a_r in [0, 1] per region (alpha = a_r on the cells of region r). The
objective J(u, alpha) is a UFL form, e.g. 1/2 int |u - u_target|^2 (+ regularisation). Each evaluation
re-solves the forward problem from the last converged state (Newton; the step from the last converged
activations is halved while Newton fails) and takes dJ/dalpha per cell from one adjoint solve
(model.solvers.adjoint), summed over each region's cells: dJ/da_r. scipy's L-BFGS-B minimises J over the
box [0, 1]^m; its iterates are the same on every rank (values and gradients are reduced over the ranks).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from model import compat
from model.solvers.adjoint import adjoint_gradient, objective_value

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
    last = {"a": None, "state": problem.solution.x.array.copy()}
    history: list[tuple[list[float], float]] = []
    scale = {"J": None}

    def forward(a: np.ndarray) -> None:
        base = last["a"] if last["a"] is not None else a
        step, halvings = 1.0, 0
        while True:
            trial = base + step * (a - base)
            mapping.set(trial)
            problem.invalidate_state()
            result = solver.solve()
            if result.converged:
                last["state"] = problem.solution.x.array.copy()
                if step == 1.0:
                    last["a"] = a.copy()
                    return
                base, step = trial, 1.0  # a converged intermediate point: go on from it to a
                continue
            problem.solution.x.array[:] = last["state"]
            halvings += 1
            if halvings > max_halvings:
                raise RuntimeError(f"activation estimation: the forward problem failed at {trial.tolist()} "
                                   f"({result.reason_name}), {max_halvings} halvings of the step from "
                                   f"{base.tolist()}")
            step *= 0.5

    def evaluate(a: np.ndarray) -> tuple[float, np.ndarray]:
        forward(a)
        value = objective_value(objective, comm)
        gradient = mapping.reduce(adjoint_gradient(problem, objective, alpha))
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


__all__ = ["ActivationEstimate", "estimate_region_activations"]
