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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from forms.obstacles import Obstacle, gap, sliding_energy
from model import compat
from model.problem import ElasticityProblem

log = logging.getLogger(__name__)

Transform = tuple[np.ndarray, np.ndarray]

__all__ = ["Bone", "HingeMotion", "MovingFrame", "RigidMotion", "SlidingConstraint", "Stationary", "SurfaceNodes",
           "TransformTable", "add_sliding", "attach", "axis_angle", "current_position", "rotation_log",
           "rotation_matrix", "surface_measure"]


class RigidMotion(Protocol):
    """t -> (Q, c): the rigid motion x = Q X + c at time t (Q 3x3 rotation, c 3-vector)."""

    def __call__(self, t: float) -> Transform: ...


# --- rotations ------------------------------------------------------------------------------------

def _unit(axis: Sequence[float], name: str) -> np.ndarray:
    a = np.asarray(axis, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers, got {axis!r}")
    length = float(np.linalg.norm(a))
    if length == 0.0:
        raise ValueError(f"{name} must not be zero")
    return a / length


def _hat(w: np.ndarray) -> np.ndarray:
    """[w]x, the cross-product matrix: [w]x v = w x v."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rotation_matrix(rotation_vector: Sequence[float]) -> np.ndarray:
    """exp([w]x) for the rotation vector w = theta a (radians): Rodrigues,
    Q = I + sin(theta) [a]x + (1 - cos(theta)) [a]x^2."""
    w = np.asarray(rotation_vector, dtype=np.float64).reshape(3)
    theta = float(np.linalg.norm(w))
    if theta == 0.0:
        return np.eye(3)
    K = _hat(w / theta)
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def axis_angle(axis: Sequence[float], degrees: float) -> np.ndarray:
    """The rotation by ``degrees`` about ``axis`` (right-handed), as a 3x3 matrix."""
    return rotation_matrix(_unit(axis, "axis") * math.radians(degrees))


def rotation_log(Q: np.ndarray) -> np.ndarray:
    """The rotation vector w (|w| = theta in [0, pi]) with exp([w]x) = Q.

    theta = atan2(|v|, (tr Q - 1)/2), v = axial(Q - Q^T)/2 = sin(theta) a. For theta > pi/2 the axis
    comes from a a^T = (sym Q - cos(theta) I) / (1 - cos(theta)) (accurate up to theta = pi), its
    sign from v.
    """
    Q = np.asarray(Q, dtype=np.float64)
    v = 0.5 * np.array([Q[2, 1] - Q[1, 2], Q[0, 2] - Q[2, 0], Q[1, 0] - Q[0, 1]])
    s = float(np.linalg.norm(v))
    c = float(np.clip((np.trace(Q) - 1.0) / 2.0, -1.0, 1.0))
    theta = math.atan2(s, c)
    if theta < 1e-12:
        return v.copy()
    if c >= 0.0:
        return theta * v / s
    B = (0.5 * (Q + Q.T) - c * np.eye(3)) / (1.0 - c)
    i = int(np.argmax(np.diag(B)))
    a = B[:, i] / math.sqrt(B[i, i])
    if float(a @ v) < 0.0:
        a = -a
    return theta * a


def _check_rotation(Q: np.ndarray, name: str) -> np.ndarray:
    Q = np.asarray(Q, dtype=np.float64)
    if Q.shape != (3, 3) or not np.all(np.isfinite(Q)):
        raise ValueError(f"{name} must be a 3x3 matrix or a rotation vector (3 numbers)")
    if np.abs(Q.T @ Q - np.eye(3)).max() > 1e-9 or np.linalg.det(Q) <= 0:
        raise ValueError(f"{name} is not a rotation (Q^T Q = I, det Q = 1 to 1e-9)")
    return Q


def _increasing(times: Sequence[float], name: str) -> np.ndarray:
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    if t.size == 0 or not np.all(np.isfinite(t)):
        raise ValueError(f"{name} must be a non-empty list of finite times")
    if np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise ValueError(f"{name}[{i}]: times must increase, got {t[i]} after {t[i - 1]}")
    return t


def _bracket(times: np.ndarray, t: float) -> tuple[int, float]:
    """(i, s): t lies between times[i] and times[i+1] at fraction s in [0, 1] (clamped beyond the ends)."""
    if len(times) == 1 or t <= times[0]:
        return 0, 0.0
    if t >= times[-1]:
        return len(times) - 2, 1.0
    i = int(np.searchsorted(times, t, side="right")) - 1
    return i, float((t - times[i]) / (times[i + 1] - times[i]))


# --- motions --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Stationary:
    """No motion: Q = I, c = 0."""

    def __call__(self, t: float) -> Transform:
        return np.eye(3), np.zeros(3)


@dataclass(frozen=True)
class HingeMotion:
    """Rotation about the axis through ``point`` by theta(t), piecewise linear in a table (t_i, degrees_i).

    Q(t) = exp(theta(t) [a]x), c(t) = p - Q(t) p (so the axis points stay put).
    """

    axis: Sequence[float]
    point: Sequence[float]
    angles: Sequence[tuple[float, float]]

    def __post_init__(self) -> None:
        object.__setattr__(self, "axis", tuple(_unit(self.axis, "hinge: axis")))
        point = np.asarray(self.point, dtype=np.float64).reshape(-1)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise ValueError(f"hinge: point must be 3 finite numbers, got {self.point!r}")
        object.__setattr__(self, "point", tuple(point))
        table = np.asarray(self.angles, dtype=np.float64)
        if table.ndim != 2 or table.shape[1] != 2 or not np.all(np.isfinite(table)):
            raise ValueError(f"hinge: angles must be a table of (time, degrees) pairs, got {self.angles!r}")
        _increasing(table[:, 0], "hinge: angles")
        object.__setattr__(self, "angles", tuple(map(tuple, table)))

    def angle(self, t: float) -> float:
        """theta(t) in radians."""
        table = np.asarray(self.angles)
        return math.radians(float(np.interp(t, table[:, 0], table[:, 1])))

    def __call__(self, t: float) -> Transform:
        Q = rotation_matrix(np.asarray(self.axis) * self.angle(t))
        p = np.asarray(self.point)
        return Q, p - Q @ p


@dataclass(frozen=True)
class TransformTable:
    """Keyframed rigid motion: rotations slerped, translations interpolated linearly (see module docstring).

    ``rotations[i]``: a 3x3 rotation matrix or a rotation vector (axis times angle in radians);
    ``translations[i]``: c_i. Between keys the rotation turns about the fixed axis of
    Q_i^T Q_(i+1) at constant speed, by less than 180 degrees (the shorter way).
    """

    times: Sequence[float]
    rotations: Sequence[Sequence[float] | Sequence[Sequence[float]]]
    translations: Sequence[Sequence[float]]

    def __post_init__(self) -> None:
        times = _increasing(self.times, "transform table: times")
        if len(self.rotations) != len(times) or len(self.translations) != len(times):
            raise ValueError(f"transform table: {len(times)} times need as many rotations and translations, "
                             f"got {len(self.rotations)} and {len(self.translations)}")
        rotations = []
        for i, r in enumerate(self.rotations):
            r = np.asarray(r, dtype=np.float64)
            Q = rotation_matrix(r) if r.shape == (3,) else r
            rotations.append(_check_rotation(Q, f"transform table: rotations[{i}]"))
        translations = np.asarray(self.translations, dtype=np.float64)
        if translations.shape != (len(times), 3) or not np.all(np.isfinite(translations)):
            raise ValueError("transform table: translations must be one 3-vector per time")
        object.__setattr__(self, "times", tuple(times))
        object.__setattr__(self, "rotations", tuple(rotations))
        object.__setattr__(self, "translations", tuple(map(tuple, translations)))
        # relative rotation vectors between keys, once
        object.__setattr__(self, "_steps", tuple(rotation_log(rotations[i].T @ rotations[i + 1])
                                                  for i in range(len(times) - 1)))

    def __call__(self, t: float) -> Transform:
        i, s = _bracket(np.asarray(self.times), t)
        Q = self.rotations[i]
        c = np.asarray(self.translations[i])
        if len(self.times) == 1:
            return Q.copy(), c.copy()
        Q = Q @ rotation_matrix(s * self._steps[i])  # type: ignore[attr-defined]
        c = (1.0 - s) * c + s * np.asarray(self.translations[i + 1])
        return Q, c


@dataclass(frozen=True)
class Bone:
    """A rigid bone: a name, its motion and, optionally, its shape as an analytic obstacle."""

    name: str
    motion: RigidMotion = field(default_factory=Stationary)
    obstacle: Obstacle | None = None

    def transform(self, t: float) -> Transform:
        return self.motion(t)


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

#: the vertex rule on the reference triangle: int f dA ~ (A/3) sum of f at the vertices
_VERTEX_RULE = {"quadrature_rule": "custom", "quadrature_degree": 1,
                "quadrature_points": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
                "quadrature_weights": np.full(3, 1.0 / 6.0)}


def surface_measure(problem: ElasticityProblem, surface: str, quadrature_degree: int | str | None = None
                    ) -> ufl.Measure:
    """ds restricted to a named boundary, with an explicit quadrature.

    ``quadrature_degree``: None (the problem's), an integer (Gauss), or "vertex" (the nodal rule
    (A/3) sum over the triangle's vertices: a lumped, node-by-node constraint; P1 only).
    """
    domain = problem.domain
    if surface not in domain.boundaries:
        raise ValueError(f"surface: no boundary named {surface!r} in the mesh "
                         f"(boundaries: {', '.join(sorted(domain.boundaries)) or 'none'})")
    if quadrature_degree == "vertex":
        if problem.degree != 1:
            raise ValueError("quadrature_degree: the vertex rule is for P1 displacements only")
        metadata = dict(_VERTEX_RULE)
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
    if surface not in problem.domain.boundaries:
        raise ValueError(f"surface: no boundary named {surface!r} in the mesh")
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
    problem.add_energy(sliding_energy(g, stiffness) * ds)
    xv = ufl.variable(current_position(problem))
    gv = frame.gap(obstacle, xv)
    traction = -stiffness * gv * ufl.diff(gv, xv)
    force_forms = [fem.form(traction[i] * ds) for i in range(3)]
    log.info("sliding: surface %r on %s, k = %g", surface, type(obstacle).__name__.lower(), k)
    return SlidingConstraint(problem, surface, obstacle, float(k), frame, g, SurfaceNodes(problem, surface),
                             force_forms)

