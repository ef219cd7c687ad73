"""Rigid obstacles as signed distances, and the energies that keep a surface off (or on) them.

An obstacle is described in its own frame by a signed distance d(y): d > 0 outside (the free
side), d < 0 inside, |grad d| = 1 away from the medial set:

    Plane(p, n)         d(y) = (y - p) . n                      n normalised; the side n points to is free
    Sphere(c, r)        d(y) = |y - c| - r
    Capsule(a, b, r)    d(y) = |y - a - s (b - a)| - r,         s = clamp((y - a).(b - a) / |b - a|^2, 0, 1)
                        (the points within r of the segment a-b: a bone)

A rigid motion x -> Q(t) x + c(t) moves the obstacle (Q a rotation, c a translation, both
fem.Constants owned by the caller, so moving never recompiles). A current point x is then
mapped back into the obstacle's frame, and the gap is

    g(x) = d(Q^T (x - c)),        x = X + u  (current position of the reference point X).

Energies per unit reference area of a surface, k > 0 the penalty stiffness (energies.md):

    penalty_energy:               psi = (k/2) min(g, 0)^2                  (one-sided contact)
    augmented_lagrangian_energy:  psi = (k/2) min(g - lambda/k, 0)^2 - lambda^2/(2k)
                                      = (1/(2k)) (max(lambda - k g, 0)^2 - lambda^2)
                                  lambda >= 0 the contact pressure (Uzawa multiplier); lambda = 0
                                  gives the penalty energy
    sliding_energy:               psi = (k/2) g^2                          (both sides: stay on the surface)
    triangle_squared_distance:    d^2 of a point to a triangle in its closest point's Voronoi region (face,
                                  edge, vertex): the sliding between deformable bodies, psi = (k/2) d^2

Contact pressure (force per reference area along grad g): p = -dpsi/dg = max(lambda - k g, 0).

Every function takes UFL expressions and, where useful, numpy arrays of points with shape
(..., 3) (the same formula serves both; used to evaluate gaps at nodes and in tests).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import ufl

Expr = ufl.core.expr.Expr
#: a point or points: a UFL vector expression, or a numpy array of shape (..., 3)
Points = Expr | np.ndarray
Scalar = Expr | np.ndarray | float

__all__ = ["REGION_EDGE", "REGION_FACE", "REGION_NONE", "REGION_VERTEX", "Capsule", "Obstacle", "Plane", "Sphere",
           "augmented_lagrangian_energy", "contact_pressure", "gap", "in_frame", "penalty_energy", "sliding_energy",
           "triangle_squared_distance"]


# --- arithmetic shared by UFL and numpy -----------------------------------------------------------

def _is_numpy(y: Points) -> bool:
    return isinstance(y, np.ndarray)


def _vector(values: tuple[float, ...], like: Points) -> Points:
    return np.asarray(values, dtype=np.float64) if _is_numpy(like) else ufl.as_vector(values)


def _dot(a: Points, b: Points) -> Scalar:
    return np.sum(a * b, axis=-1) if _is_numpy(a) else ufl.dot(a, b)


def _norm(a: Points) -> Scalar:
    return np.sqrt(_dot(a, a)) if _is_numpy(a) else ufl.sqrt(ufl.dot(a, a))


def _clamp01(s: Scalar) -> Scalar:
    return np.clip(s, 0.0, 1.0) if _is_numpy(s) else ufl.max_value(ufl.min_value(s, 1.0), 0.0)


def _point(value: Sequence[float], name: str, owner: str) -> tuple[float, float, float]:
    array = np.asarray(value, dtype=np.float64).reshape(-1)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{owner}: {name} must be 3 finite numbers, got {value!r}")
    return (float(array[0]), float(array[1]), float(array[2]))


def _positive(value: float, name: str, owner: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{owner}: {name} must be a finite number > 0, got {value!r}")
    return float(value)


# --- obstacles ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Plane:
    """Half-space behind a plane: d(y) = (y - point) . normal; the side ``normal`` points to is free."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]

    def __post_init__(self) -> None:
        point = _point(self.point, "point", "plane")
        normal = np.asarray(_point(self.normal, "normal", "plane"))
        length = float(np.linalg.norm(normal))
        if length == 0.0:
            raise ValueError("plane: normal must not be zero")
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "normal", tuple(float(v) for v in normal / length))

    def distance(self, y: Points) -> Scalar:
        """d(y) = (y - p) . n."""
        return _dot(y - _vector(self.point, y), _vector(self.normal, y))


@dataclass(frozen=True)
class Sphere:
    """Ball of radius r about c: d(y) = |y - c| - r."""

    centre: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _point(self.centre, "centre", "sphere"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius", "sphere"))

    def distance(self, y: Points) -> Scalar:
        """d(y) = |y - c| - r (not differentiable at y = c)."""
        return _norm(y - _vector(self.centre, y)) - self.radius


@dataclass(frozen=True)
class Capsule:
    """Points within r of the segment a-b (a bone): d(y) = |y - a - s (b - a)| - r, s = clamp(...)."""

    a: tuple[float, float, float]
    b: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        a, b = _point(self.a, "a", "capsule"), _point(self.b, "b", "capsule")
        if a == b:
            raise ValueError("capsule: b must differ from a (use a sphere for a single point)")
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "radius", _positive(self.radius, "radius", "capsule"))

    def distance(self, y: Points) -> Scalar:
        """d(y) = |y - a - s (b - a)| - r with s = clamp((y - a).(b - a) / |b - a|^2, 0, 1)."""
        a = _vector(self.a, y)
        ab = _vector(tuple(bi - ai for ai, bi in zip(self.a, self.b)), y)
        length2 = sum((bi - ai) ** 2 for ai, bi in zip(self.a, self.b))
        ya = y - a
        s = _dot(ya, ab) / length2
        s = _clamp01(s)
        if _is_numpy(y):
            return _norm(ya - s[..., None] * ab) - self.radius
        return _norm(ya - s * ab) - self.radius


Obstacle = Plane | Sphere | Capsule


# --- rigid motion and gap -------------------------------------------------------------------------

def in_frame(x: Points, rotation: Expr | np.ndarray | None = None,
             translation: Expr | np.ndarray | None = None) -> Points:
    """y = Q^T (x - c): a current point in the frame of an obstacle moved by x -> Q x + c.

    Q (3x3) and c (3) are UFL expressions (fem.Constants) for UFL x, numpy arrays for numpy x
    (points as rows: y = (x - c) Q). None means the identity / no translation.
    """
    y = x
    if translation is not None:
        y = y - translation
    if rotation is not None:
        y = y @ np.asarray(rotation) if _is_numpy(x) else ufl.dot(ufl.transpose(rotation), y)
    return y


def gap(obstacle: Obstacle, x: Points, rotation: Expr | np.ndarray | None = None,
        translation: Expr | np.ndarray | None = None) -> Scalar:
    """g(x) = d(Q^T (x - c)): signed distance of the current point x to the moved obstacle (> 0 free)."""
    return obstacle.distance(in_frame(x, rotation, translation))


# --- surface energies -----------------------------------------------------------------------------

def penalty_energy(g: Expr, k: float | Expr, touching: float = 0.0) -> Expr:
    """psi = (k/2) min(g, 0)^2, written as (k/2) [g if g <= touching else 0]^2.

    Its derivative dpsi/dg = k min(g, 0) is continuous; the second derivative jumps from 0 to k at
    g = 0 and UFL differentiates the conditional branch-wise, so the tangent at g = 0 exactly is
    taken from the contact side (k): a body resting exactly on the obstacle (g = 0, e.g. at the
    start of a load step) keeps a nonsingular tangent. (ufl.min_value(g, 0) would give 0 there.)
    ``touching`` >= 0 widens "exactly": a gap computed as a difference of equal coordinates is 0 only
    to round-off (+2e-16 on some machines, 0 or -2e-16 on others), and 0 < g <= touching counts as
    touching too (tangent k, energy (k/2) g^2 <= (k/2) touching^2, a force k g <= k touching); with
    touching = 1e-12 x the body's size that is below the arithmetic's resolution of the total energy.
    """
    return 0.5 * k * ufl.conditional(ufl.le(g, touching), g, 0.0) ** 2


def augmented_lagrangian_energy(g: Expr, pressure: Expr, k: float | Expr, touching: float = 0.0) -> Expr:
    """psi = (k/2) min(g - lambda/k, 0)^2 - lambda^2/(2k), lambda >= 0 the multiplier (a pressure).

    Stationary in lambda for fixed g exactly where lambda = max(lambda - k g, 0), i.e. the
    complementarity conditions g >= 0, lambda >= 0, lambda g = 0 (Rockafellar's augmented
    Lagrangian of the inequality g >= 0; Uzawa iterates lambda <- max(lambda - k g, 0)).
    The tangent at the kink (g = lambda/k) is taken from the contact side, as in penalty_energy
    (``touching`` as there).
    """
    m = g - pressure / k
    return 0.5 * k * ufl.conditional(ufl.le(m, touching), m, 0.0) ** 2 - pressure**2 / (2.0 * k)


def contact_pressure(g: Scalar, k: float | Expr, pressure: Scalar = 0.0) -> Scalar:
    """p = max(lambda - k g, 0) = -dpsi/dg: the contact pressure of the (augmented) penalty energy."""
    if _is_numpy(g):
        return np.maximum(pressure - k * g, 0.0)
    return ufl.max_value(pressure - k * g, 0.0)


def sliding_energy(g: Expr, k: float | Expr) -> Expr:
    """psi = (k/2) g^2: holds a surface on the obstacle's surface from both sides, free to slide along it."""
    return 0.5 * k * g**2


#: region codes of triangle_squared_distance: no pairing (energy 0), vertex, edge, face
REGION_NONE, REGION_VERTEX, REGION_EDGE, REGION_FACE = 0.0, 1.0, 2.0, 3.0


def triangle_squared_distance(x: Expr, x1: Expr, x2: Expr, x3: Expr, region: Expr) -> Expr:
    """The squared distance d^2 of the point x to the triangle (x1, x2, x3) in the Voronoi region ``region`` of its
    closest point (Ericson's classification; the vertices ordered so that the region's vertex, or edge, comes
    first):

        face   (region 3):  d^2 = (n . (x - x1))^2 / (n . n),   n = (x2 - x1) x (x3 - x1)
        edge   (region 2):  d^2 = |r|^2 - (r . e)^2 / (e . e),  r = x - x1, e = x2 - x1
        vertex (region 1):  d^2 = |r|^2
        none   (region 0):  0

    In its region each is the exact squared distance, a smooth function of x and the three vertices; across the
    regions' boundaries on the convex side of a surface of triangles the pieces meet with their gradients
    (2 (x - x*), x* the closest point: the envelope theorem), so (k/2) d^2 summed over a surface's closest triangles
    is a C1 potential there whose exact derivatives UFL takes (the normal's rotation and the slip of x* included).
    The region is piecewise constant data (a P1 function read at the nodes by the vertex rule)."""
    r = x - x1
    e = x2 - x1
    n = ufl.cross(e, x3 - x1)
    face = ufl.dot(n, r) ** 2 / ufl.dot(n, n)
    edge = ufl.dot(r, r) - ufl.dot(r, e) ** 2 / ufl.dot(e, e)
    vertex = ufl.dot(r, r)
    return ufl.conditional(ufl.lt(region, 0.5), 0.0,
                           ufl.conditional(ufl.lt(region, 1.5), vertex,
                                           ufl.conditional(ufl.lt(region, 2.5), edge, face)))


def axis_of(normal: np.ndarray, key: str) -> tuple[int, float]:
    """(j, s) with normal = s e_j (to 1e-12), else ValueError naming ``key``."""
    j = int(np.argmax(np.abs(normal)))
    off = np.delete(np.abs(normal), j)
    if np.any(off > 1e-12):
        raise ValueError(f"{key}: method vi needs a plane normal along a coordinate axis (+-x, +-y, +-z), "
                         f"got {[float(v) for v in normal]}")
    return j, float(np.sign(normal[j]))
