"""Shape targets of fibre-based muscles inside one volume (Klar et al. 2020, section 3), for muscle_targets.toml.

The "upper arm" is one box-shaped volume, 8 x 8 x 30 cm, the shoulder end z = 0 clamped. Two
muscles act inside it, each given by an influence region (a fusiform spindle around an axis
segment, like a muscle's surface geometry), a fibre direction field and an activation curve of
time (the load factor t is the frame time):

- ``biceps``: along z on the +x side; activation ramps up to 1 by t = 1/2 and holds;
- ``brachialis``: tilted, behind it, overlapping it near the elbow end; activation sin(pi t)
  (up and down again, 0 at t = 1).

Target of one muscle m with unit fibre direction a and activation alpha in [0, 1]:
contraction along a, volume-preserving expansion across,

    S_m = l a(x)a + l^(-1/2) (I - a(x)a),    l = 1 - C alpha,     det S_m = 1.

Each cell has a weight w_m in [0, 1] per muscle, from its distance to the muscle's axis
relative to the spindle's radius there (1 in the core, 0 outside, smooth in between); where
the weights add up to more than 1 they are scaled down, and the rest, w_0 = 1 - sum w_m, stays
passive (target I). The cell's target is the log-Euclidean weighted mean

    S = exp( sum_m w_m log S_m )       (+ w_0 log I = 0)

Why this mean: log S_m is the muscle's target logarithmic (Hencky) strain,
log l (3/2 a(x)a - 1/2 I); averaging strains, not stretch matrices, (1) is always symmetric
positive definite (the exponential of a symmetric matrix), whatever the fibre directions;
(2) keeps volume exactly: tr log S_m = log det S_m = 0, so det S = prod det(S_m)^w_m = 1, where a
linear mean sum w_m S_m of two different isochoric targets has det > 1 (det^(1/3) is concave)
and would make overlaps swell; (3) gives a fractional contribution the natural meaning: a cell
half inside one muscle gets S_m^(1/2), half of its log strain, and two coinciding muscles with
the same fibres simply add their log strains.
"""

from __future__ import annotations

import numpy as np

#: maximum contraction: l = 1 - C alpha along the fibres
C = 0.3
#: the box of examples/muscle_targets.toml
SIZE = (0.08, 0.08, 0.30)


class Muscle:
    """An influence region: a spindle around the axis origin -> insertion, radius end -> belly -> end."""

    # (a plain class: model.config.userfiles loads this file without registering it in sys.modules, which
    # dataclasses need)
    def __init__(self, name: str, origin: tuple[float, float, float], insertion: tuple[float, float, float],
                 belly_radius: float, end_radius: float) -> None:
        self.name, self.origin, self.insertion = name, origin, insertion
        self.belly_radius, self.end_radius = belly_radius, end_radius

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.subtract(self.insertion, self.origin)))

    def local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(s in [0, 1] along the axis (unclipped), distance d to the axis, radial unit vector n, axis e)."""
        p0 = np.asarray(self.origin)
        e = (np.asarray(self.insertion) - p0) / self.length
        rel = x - p0
        s = rel @ e / self.length
        radial = rel - np.outer(rel @ e, e)
        d = np.linalg.norm(radial, axis=1)
        n = radial / np.maximum(d, 1e-300)[:, None]
        return s, d, n, e

    def radius(self, s: np.ndarray) -> np.ndarray:
        """Spindle radius r(s) = r_end + (r_belly - r_end) sin(pi s)^2."""
        return self.end_radius + (self.belly_radius - self.end_radius) * np.sin(np.pi * np.clip(s, 0, 1)) ** 2

    def weight(self, x: np.ndarray) -> np.ndarray:
        """1 where d < 0.6 r(s), 0 where d > r(s) or outside the axis segment, smoothstep in between."""
        s, d, _, _ = self.local(x)
        q = np.clip((1.0 - d / self.radius(s)) / 0.4, 0.0, 1.0)
        w = q * q * (3.0 - 2.0 * q)
        return np.where((s >= 0.0) & (s <= 1.0), w, 0.0)

    def fibres(self, x: np.ndarray) -> np.ndarray:
        """Unit fibre direction (n, 3): along the spindle's profile curves, L e + (d / r) r'(s) n."""
        s, d, n, e = self.local(x)
        r = self.radius(s)
        slope = (self.belly_radius - self.end_radius) * np.pi * np.sin(2.0 * np.pi * np.clip(s, 0, 1))
        a = self.length * e[None, :] + (np.minimum(d / r, 1.0) * slope)[:, None] * n
        return a / np.linalg.norm(a, axis=1, keepdims=True)


MUSCLES = (
    Muscle("biceps", origin=(0.050, 0.040, 0.02), insertion=(0.050, 0.040, 0.29), belly_radius=0.032,
           end_radius=0.008),
    Muscle("brachialis", origin=(0.026, 0.036, 0.10), insertion=(0.038, 0.044, 0.29), belly_radius=0.026,
           end_radius=0.008),
)


def activation(t: float) -> np.ndarray:
    """alpha_m(t) of every muscle: biceps smooth ramp to 1 by t = 1/2, brachialis sin(pi t)."""
    r = min(max(2.0 * t, 0.0), 1.0)
    return np.array([r * r * (3.0 - 2.0 * r), max(np.sin(np.pi * t), 0.0)])


def weights(x: np.ndarray) -> np.ndarray:
    """(n, M) weights w_m, scaled down where their sum exceeds 1 (the remainder 1 - sum is passive)."""
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    w = np.stack([m.weight(x) for m in MUSCLES], axis=1)
    total = w.sum(axis=1, keepdims=True)
    return np.where(total > 1.0, w / np.maximum(total, 1e-300), w)


def log_target(a: np.ndarray, alpha: float) -> np.ndarray:
    """log S_m = log(l) (3/2 a a - 1/2 I) for fibre directions a (n, 3) and activation alpha."""
    aa = a[:, :, None] * a[:, None, :]
    return np.log(1.0 - C * alpha) * (1.5 * aa - 0.5 * np.eye(3))


def spd_exp(L: np.ndarray) -> np.ndarray:
    """exp of a batch of symmetric matrices (n, 3, 3), by eigen-decomposition."""
    w, V = np.linalg.eigh(0.5 * (L + np.swapaxes(L, 1, 2)))
    S = (V * np.exp(w)[:, None, :]) @ np.swapaxes(V, 1, 2)
    return 0.5 * (S + np.swapaxes(S, 1, 2))


def muscle_targets(x: np.ndarray, t: float) -> np.ndarray:
    """S (n, 3, 3) = exp(sum_m w_m log S_m) at reference centroids x (n, 3) and frame time t."""
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    w = weights(x)
    alpha = activation(t)
    L = np.zeros((len(x), 3, 3))
    for m, muscle in enumerate(MUSCLES):
        L += w[:, m, None, None] * log_target(muscle.fibres(x), float(alpha[m]))
    return spd_exp(L)
