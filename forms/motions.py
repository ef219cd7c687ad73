"""Rigid motions of bones: x = Q(t) X + c(t) (Q a rotation, c a translation), in numpy.

    HingeMotion(axis, point, angles)      rotation about a fixed axis through ``point`` by the angle
                                          theta(t), piecewise linear in t from a table (t_i, degrees_i):
                                          Q = exp(theta [a]x) (Rodrigues), c = p - Q p
    TransformTable(times, rotations, translations)
                                          keyframes (t_i, Q_i, c_i); between keys, with s = (t - t_i) /
                                          (t_(i+1) - t_i): Q = Q_i exp(s log(Q_i^T Q_(i+1))) (slerp: the
                                          geodesic at constant angular speed), c = (1 - s) c_i + s c_(i+1)
    Stationary()                          Q = I, c = 0

Both tables hold their end values beyond their first and last times. Time t is the load factor of
quasi-static runs and the physical time of dynamic ones. Constructors check their input (ValueError
naming the offending entry), so a configuration can build these objects before any mesh exists.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from forms.obstacles import Obstacle

Transform = tuple[np.ndarray, np.ndarray]

__all__ = ["Bone", "HingeMotion", "RigidMotion", "Stationary", "Transform", "TransformTable", "axis_angle",
           "rotation_log", "rotation_matrix"]


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
