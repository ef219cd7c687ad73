"""The skinning seed's inverse problem (mixed-fem-skinning-sgi.txt, sections 1.2 and 1.3; issue 13 item 4):
rotation angles at a few sample points, spread to every triangle by biharmonic weights, optimised so the pinned
mixed-ARAP body reaches a pose.

    model = SkinningModel(domain)                     # the gingerbread mesh (meshes.gingerbread), feet pinned
    target = model.pose(known_angles)                 # positions x produced by known angles
    fit = model.fit(target, initial=np.zeros(h))      # scipy L-BFGS-B on the h angles; exact adjoint gradients

The body (forms.skinning, model.problem.skinning): per triangle a symmetric stretch S (DG0, 3 values), the P1
positions x, the multiplier lambda (DG0 2 x 2) of F = grad x = R(theta) S, and the feet pinned at rest by the
penalty k/2 int_feet |x - X|^2. For given angles the KKT system A(theta) y = b is linear; MUMPS solves it.

Angles (section 1.3): h sample points p_j with handles at the mesh vertices nearest to them; unbounded biharmonic
weights w_j (model.fields.biharmonic, a partition of unity) give each triangle c the angle

    theta_c = sum_j W_cj theta_j,    W_cj = w_j at the centroid of c (the mean of its vertex values).

Objective (a pose objective; the seed's terms weighted by ``gamma``):

    J(theta) = 1/2 int chi_track |x*(theta) - x_target|^2 dx
               + gamma (E_ARAP(S*) + k/2 int_feet |x* - X|^2 dx + int ||R(theta) - I||_F^2 dx),

chi_track the indicator of the tracked regions (default: hands and head), (S*, x*) the KKT solution; gamma = 0
is pure pose tracking (a target made by known angles is then recovered exactly), gamma = 1 with no tracked
region is the seed's E(R) with R_pinned = I. Gradient: dJ/dtheta_c by one adjoint solve with the transposed KKT
matrix (``SkinningProblem.adjoint_gradient``: UFL derives dA/dtheta), then dJ/dtheta_j = sum_c W_cj dJ/dtheta_c
(summed over owned cells and the ranks).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from forms.skinning import arap_energy, pinning_penalty, rotation_regularisation
from model.domain.distribute import Domain
from model.fields.biharmonic import biharmonic_weights, handle_at_point
from model.problem.skinning import SkinningProblem, objective_value

log = logging.getLogger(__name__)

#: Sample points of the angles on the gingerbread figure (meshes.gingerbread): name -> (x, y).
SAMPLE_POINTS: dict[str, tuple[float, float]] = {
    "head": (0.0, 1.72),
    "chest": (0.0, 1.15),
    "left_hand": (-0.92, 1.19),
    "right_hand": (0.92, 1.19),
    "left_leg": (-0.19, 0.40),
    "right_leg": (0.19, 0.40),
}
#: Pinned regions (the seed's P) and tracked regions of the pose objective.
PINNED = ("left_foot", "right_foot")
TRACKED = ("left_hand", "right_hand", "head")


@dataclass
class SkinningFit:
    """The angles found (per sample point), the objective there, L-BFGS-B's iterations, evaluations (one KKT
    solve and one adjoint solve each), success and message, the wall time and the history of (angles, J)."""

    angles: dict[str, float]
    objective: float
    iterations: int
    evaluations: int
    converged: bool
    message: str
    time_s: float
    history: list[tuple[list[float], float]] = field(default_factory=list)


def _cells(domain: Domain, names: Sequence[str]) -> np.ndarray:
    return np.unique(np.concatenate([domain.region_cells(n) for n in names])) if names else np.empty(0, np.int32)


class SkinningModel:
    """The gingerbread body with angles at sample points (module docstring). Collective.

    ``domain``: a plane triangle Domain with the regions named in ``pinned`` and ``tracked``; ``k``: the
    pinning penalty; ``sample_points``: name -> point; ``gamma``: the weight of the seed's terms in J."""

    def __init__(self, domain: Domain, k: float = 100.0, sample_points: Mapping[str, Sequence[float]] | None = None,
                 pinned: Sequence[str] = PINNED, tracked: Sequence[str] = TRACKED, gamma: float = 0.0,
                 quadrature_degree: int = 2) -> None:
        self.domain = domain
        msh = domain.mesh
        self.comm = msh.comm
        self.names = list((sample_points or SAMPLE_POINTS).keys())
        points = list((sample_points or SAMPLE_POINTS).values())
        self.problem = p = SkinningProblem(msh, _cells(domain, pinned), k, quadrature_degree=quadrature_degree)
        weights = biharmonic_weights(msh, [handle_at_point(msh, point) for point in points])
        cellwise = fem.Function(p.angle_space)
        columns = []
        for w in weights:
            cellwise.interpolate(w)  # P1 -> DG0: the value at the centroid
            columns.append(cellwise.x.array.copy())
        #: W_cj for the local cells (owned and ghost), one column per sample point
        self.W = np.stack(columns, axis=1)
        self.owned = p.angle_space.dofmap.index_map.size_local
        self.tracked = fem.Function(p.angle_space, name="tracked")
        self.tracked.x.array[_cells(domain, tracked)] = 1.0
        self.target = fem.Function(p.parts()[1].function_space, name="x_target")
        self.target.interpolate(lambda X: X[:2])
        s, x, _ = ufl.split(p.y)
        self.gamma = fem.Constant(msh, PETSc.ScalarType(gamma))
        zero = fem.Constant(msh, PETSc.ScalarType(0.0))
        self.seed_terms = (arap_energy(s, p.dx) + pinning_penalty(x, p.x_pinned, p.pinned, p.k, p.dx)
                           + rotation_regularisation(p.theta, zero, p.dx))
        d = x - self.target
        self.tracking = 0.5 * self.tracked * ufl.inner(d, d) * p.dx
        self.objective = self.tracking + self.gamma * self.seed_terms

    # --- forward ----------------------------------------------------------------------------------------
    def set_angles(self, angles: Sequence[float]) -> None:
        """theta_c = sum_j W_cj theta_j on every local cell."""
        self.problem.theta.x.array[:] = self.W @ np.asarray(angles, dtype=float)
        self.problem.theta.x.scatter_forward()

    def solve(self, angles: Sequence[float]) -> float:
        """The KKT solution for the sample angles (relative residual of the linear solve)."""
        self.set_angles(angles)
        return self.problem.solve()

    def positions(self) -> fem.Function:
        """The current positions x (a copy)."""
        return self.problem.parts()[1]

    def pose(self, angles: Sequence[float]) -> fem.Function:
        """The positions x reached with the sample angles ``angles`` (e.g. a target pose)."""
        self.solve(angles)
        return self.positions()

    def set_target(self, target: fem.Function) -> None:
        """x_target of the pose objective (a P1 vector Function of the positions' space)."""
        self.target.x.array[:] = target.x.array
        self.target.x.scatter_forward()

    # --- objective and gradient -------------------------------------------------------------------------
    def value(self) -> float:
        """J at the current solution."""
        return objective_value(self.objective, self.comm)

    def gradient(self) -> np.ndarray:
        """dJ/dtheta_j at the current solution: one adjoint solve, then sum_c W_cj dJ/dtheta_c."""
        per_cell = self.problem.adjoint_gradient(self.objective)
        return self.comm.allreduce(self.W[: self.owned].T @ per_cell, op=MPI.SUM)

    def evaluate(self, angles: Sequence[float]) -> tuple[float, np.ndarray]:
        """(J, dJ/dtheta_j) at the sample angles ``angles`` (one KKT and one adjoint solve)."""
        self.solve(angles)
        return self.value(), self.gradient()

    def fit(self, target: fem.Function, initial: Sequence[float] | None = None, gtol: float = 1e-10,
            max_iterations: int = 200) -> SkinningFit:
        """Minimise J over the sample angles from ``initial`` (default 0) with scipy's L-BFGS-B (unbounded);
        the iterates are the same on every rank (J and its gradient are reduced). The problem's state is the
        solution at the angles returned."""
        from scipy.optimize import minimize

        self.set_target(target)
        start_time = time.perf_counter()
        start = np.zeros(len(self.names)) if initial is None else np.asarray(initial, dtype=float)
        history: list[tuple[list[float], float]] = []
        scale: dict[str, float] = {}

        def evaluate(angles: np.ndarray) -> tuple[float, np.ndarray]:
            value, grad = self.evaluate(angles)
            scale.setdefault("J", max(abs(value), np.finfo(float).tiny))
            history.append((angles.tolist(), value))
            log.debug("angles %s: J = %.6e, |dJ/dtheta| = %.3e", angles, value, np.linalg.norm(grad))
            return value / scale["J"], grad / scale["J"]

        result = minimize(evaluate, start, jac=True, method="L-BFGS-B",
                          options={"gtol": gtol, "ftol": 1e-15, "maxiter": max_iterations})
        self.solve(result.x)
        value = self.value()
        elapsed = time.perf_counter() - start_time
        log.info("skinning fit: J = %.3e after %d iterations, %d evaluations, %.2f s", value, result.nit,
                 result.nfev, elapsed)
        return SkinningFit(dict(zip(self.names, map(float, result.x))), value, int(result.nit), int(result.nfev),
                           bool(result.success), str(result.message), elapsed, history)


__all__ = ["PINNED", "SAMPLE_POINTS", "TRACKED", "SkinningFit", "SkinningModel"]
