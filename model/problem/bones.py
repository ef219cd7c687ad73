"""Bones: rigid bodies moving against time, and how soft tissue is tied to them.

Time t is the load factor of quasi-static runs (0..1; later the physical time of dynamics).
A rigid motion maps a reference point to x = Q(t) X + c(t) (Q a rotation, c a translation):

    HingeMotion(axis, point, angles)      rotation about a fixed axis through ``point`` by the angle
                                          theta(t), piecewise linear in t from a table (t_i, degrees_i):
                                          Q = exp(theta [a]x) (Rodrigues), c = p - Q p
    TransformTable(times, rotations, translations)
                                          keyframes (t_i, Q_i, c_i); between keys, with s = (t - t_i) /
                                          (t_(i+1) - t_i): Q = Q_i exp(s log(Q_i^T Q_(i+1))) (slerp: the
                                          geodesic at constant angular speed), c = (1 - s) c_i + s c_(i+1)
    Stationary()                          Q = I, c = 0

Both tables hold their end values beyond their first and last times.

Ties between tissue and bone:

    attach(problem, surface, motion)      the surface's nodes follow the bone rigidly: Dirichlet data
                                          u(X, t) = Q(t) X + c(t) - X (load-dependent, re-evaluated
                                          whenever the load factor is set; no recompilation)
    add_sliding(problem, surface, obstacle, k)
                                          the surface stays on the (moving) obstacle's surface and slides
                                          freely along it: energy int (k/2) g(X + u)^2 dA over the
                                          surface (forms.obstacles.sliding_energy), g the signed distance
                                          in the obstacle's frame, g(x) = d(Q^T (x - c)); its force is
                                          normal to the obstacle (frictionless), on both sides

The obstacle's rotation Q and translation c enter the forms as fem.Constants (MovingFrame), updated
by a load hook: moving a bone never recompiles.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from forms.motions import Bone, RigidMotion, Stationary, Transform
from forms.obstacles import Obstacle, gap, sliding_energy
from forms.quadrature import vertex_rule
from model import compat
from model.problem import ElasticityProblem

log = logging.getLogger(__name__)

__all__ = ["MovingFrame", "SlidingConstraint", "SurfaceNodes", "add_sliding", "attach", "body_size",
           "current_position", "surface_measure"]


# --- the moving frame of an obstacle --------------------------------------------------------------

class MovingFrame:
    """Q(t), c(t) of a rigid motion as fem.Constants (3x3 and 3), set by ``update(t)`` without recompiling."""

    def __init__(self, msh: dmesh.Mesh, motion: RigidMotion | None = None) -> None:
        self.motion: RigidMotion = motion if motion is not None else Stationary()
        self.rotation = fem.Constant(msh, PETSc.ScalarType(np.eye(3)))
        self.translation = fem.Constant(msh, PETSc.ScalarType(np.zeros(3)))
        self.time = 0.0
        self.update(0.0)

    def update(self, t: float) -> None:
        """Q <- Q(t), c <- c(t)."""
        Q, c = self.motion(float(t))
        self.rotation.value = np.asarray(Q, dtype=np.float64)
        self.translation.value = np.asarray(c, dtype=np.float64)
        self.time = float(t)

    def follow(self, problem: ElasticityProblem) -> None:
        """Set from the problem's load factor now and whenever it is set (a load hook)."""
        problem.add_load_hook(self.update)
        self.update(problem.time)

    def gap(self, obstacle: Obstacle, x: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """g(x) = d(Q^T (x - c)) in UFL, with the current Q, c as constants."""
        return gap(obstacle, x, self.rotation, self.translation)

    def gap_at(self, obstacle: Obstacle, x: np.ndarray) -> np.ndarray:
        """g at points x (rows) with the current values of Q and c (numpy)."""
        return gap(obstacle, x, np.asarray(self.rotation.value), np.asarray(self.translation.value))


# --- surfaces -------------------------------------------------------------------------------------

def surface_measure(problem: ElasticityProblem, surface: str, quadrature_degree: int | str | None = None
                    ) -> ufl.Measure:
    """ds restricted to a named boundary, with an explicit quadrature.

    ``quadrature_degree``: None (the problem's), an integer (Gauss), or "vertex" (the nodal rule
    (A/3) sum over the triangle's vertices: a lumped, node-by-node constraint; P1 only).
    """
    domain = problem.domain
    error = domain.boundary_error(surface)
    if error:
        raise ValueError(f"surface: {error}")
    if quadrature_degree == "vertex":
        if problem.degree != 1:
            raise ValueError("quadrature_degree: the vertex rule is for P1 displacements only")
        metadata = vertex_rule("triangle")  # on the tetrahedra's facets
    elif quadrature_degree is None:
        metadata = {"quadrature_degree": problem.quadrature_degree}
    elif isinstance(quadrature_degree, int) and not isinstance(quadrature_degree, bool) and quadrature_degree >= 1:
        metadata = {"quadrature_degree": quadrature_degree}
    else:
        raise ValueError(f"quadrature_degree must be None, an integer >= 1 or 'vertex', got {quadrature_degree!r}")
    ds = ufl.Measure("ds", domain=domain.mesh, subdomain_data=domain.facet_tags, metadata=metadata)
    return ds(domain.boundaries[surface])


def current_position(problem: ElasticityProblem) -> ufl.core.expr.Expr:
    """x = X + u."""
    return ufl.SpatialCoordinate(problem.domain.mesh) + problem.u


class SurfaceNodes:
    """The nodes of a named surface (those of the displacement's Lagrange degree), for nodal evaluations.

    ``evaluate(expr)`` interpolates a scalar UFL expression into the scalar Lagrange space of the
    displacement's degree (Lagrange interpolation: point values at the nodes) and returns its values
    at the surface nodes this rank owns; ``reduce`` combines over ranks.
    """

    def __init__(self, problem: ElasticityProblem, surface: str) -> None:
        msh = problem.domain.mesh
        self.comm: MPI.Comm = msh.comm
        self.space = compat.function_space(msh, "Lagrange", problem.degree)
        fdim = msh.topology.dim - 1
        dofs = fem.locate_dofs_topological(self.space, fdim, problem.domain.boundary_facets(surface))
        owned = self.space.dofmap.index_map.size_local
        self.all_dofs = np.asarray(dofs, dtype=np.int32)  # owned and ghost
        self.dofs = self.all_dofs[self.all_dofs < owned]
        self.count = self.comm.allreduce(len(self.dofs), op=MPI.SUM)
        self._work = fem.Function(self.space)
        self._expressions: dict[int, tuple[fem.Expression, ufl.core.expr.Expr]] = {}

    def evaluate(self, expr: ufl.core.expr.Expr) -> np.ndarray:
        """Nodal values of expr at the owned surface nodes."""
        key = id(expr)
        if key not in self._expressions:
            self._expressions[key] = (fem.Expression(expr, self.space.element.interpolation_points()), expr)
        compiled = self._expressions[key][0]
        self._work.interpolate(compiled)
        return self._work.x.array[self.dofs].copy()

    def max(self, values: np.ndarray, initial: float = -np.inf) -> float:
        return float(self.comm.allreduce(float(np.max(values, initial=initial)), op=MPI.MAX))

    def sum(self, values: np.ndarray | float) -> float:
        return float(self.comm.allreduce(float(np.sum(values)), op=MPI.SUM))


def body_size(problem: ElasticityProblem) -> float:
    """The diagonal of the reference mesh's bounding box (all ranks)."""
    msh = problem.domain.mesh
    comm = msh.comm
    x = msh.geometry.x
    low = np.array([comm.allreduce(float(v), op=MPI.MIN) for v in np.min(x, axis=0, initial=np.inf)])
    high = np.array([comm.allreduce(float(v), op=MPI.MAX) for v in np.max(x, axis=0, initial=-np.inf)])
    return float(np.linalg.norm(high - low))


# --- attachments and sliding ----------------------------------------------------------------------

def _motion_of(motion: RigidMotion | Bone) -> RigidMotion:
    return motion.motion if isinstance(motion, Bone) else motion


def attach(problem: ElasticityProblem, surface: str, motion: RigidMotion | Bone) -> None:
    """The nodes of ``surface`` follow the bone: u(X, t) = Q(t) X + c(t) - X (Dirichlet, all components).

    t is the load factor; the data are re-evaluated whenever it is set (problem.add_dirichlet with
    load-dependent callables).
    """
    rigid = _motion_of(motion)
    error = problem.domain.boundary_error(surface)
    if error:
        raise ValueError(f"surface: {error}")
    cache: dict[float, Transform] = {}

    def transform(t: float) -> Transform:
        if t not in cache:
            cache.clear()
            cache[t] = rigid(t)
        return cache[t]

    def component(i: int) -> Callable[[np.ndarray, float], np.ndarray]:
        def value(x: np.ndarray, t: float) -> np.ndarray:
            Q, c = transform(float(t))
            return Q[i] @ x + c[i] - x[i]
        return value

    problem.add_dirichlet(surface, (0, 1, 2), [component(i) for i in range(3)], [True, True, True])


@dataclass
class SlidingConstraint:
    """A surface held on a moving obstacle by the energy int (k/2) g^2 dA (see add_sliding)."""

    problem: ElasticityProblem
    surface: str
    obstacle: Obstacle
    k: float
    frame: MovingFrame
    gap: ufl.core.expr.Expr
    nodes: SurfaceNodes
    force_forms: list[compat.Form]

    def max_gap(self) -> float:
        """max |g| over the surface nodes (all ranks)."""
        return self.nodes.max(np.abs(self.nodes.evaluate(self.gap)), initial=0.0)

    def force(self) -> list[float]:
        """Total force the obstacle exerts on the body: -int k g grad g dA (all ranks)."""
        comm = self.nodes.comm
        return [comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM) for f in self.force_forms]


def add_sliding(problem: ElasticityProblem, surface: str, obstacle: Obstacle | Bone, k: float,
                motion: RigidMotion | None = None, quadrature_degree: int | str | None = None) -> SlidingConstraint:
    """Hold ``surface`` on the obstacle's surface, free to slide along it: Pi = int (k/2) g(X + u)^2 dA.

    ``obstacle`` may be a Bone (its shape and motion are used). The gap is measured in the
    obstacle's moving frame (fem.Constants set from the load factor by a load hook). Call before
    the solver is created.
    """
    if isinstance(obstacle, Bone):
        if obstacle.obstacle is None:
            raise ValueError(f"bone {obstacle.name!r} has no obstacle shape to slide on")
        motion = motion or obstacle.motion
        obstacle = obstacle.obstacle
    if isinstance(k, bool) or not isinstance(k, (int, float)) or not math.isfinite(k) or k <= 0:
        raise ValueError(f"k: the sliding stiffness must be a finite number > 0, got {k!r}")
    ds = surface_measure(problem, surface, quadrature_degree)
    frame = MovingFrame(problem.domain.mesh, motion)
    frame.follow(problem)
    g = frame.gap(obstacle, current_position(problem))
    stiffness = fem.Constant(problem.domain.mesh, PETSc.ScalarType(k))  # shared compiled code for any k
    problem.add_energy(sliding_energy(g, stiffness) * ds, "sliding")
    xv = ufl.variable(current_position(problem))
    gv = frame.gap(obstacle, xv)
    traction = -stiffness * gv * ufl.diff(gv, xv)
    force_forms = [fem.form(traction[i] * ds) for i in range(3)]
    log.info("sliding: surface %r on %s, k = %g", surface, type(obstacle).__name__.lower(), k)
    return SlidingConstraint(problem, surface, obstacle, float(k), frame, g, SurfaceNodes(problem, surface),
                             force_forms)

