"""Procedural shape targets for examples/trunk.toml: a trunk that sways round and curls (artistic control).

``sway(x, t)`` returns one target S per cell from the reference centroids x (n, 3) and the
load factor t, which examples/trunk.toml uses as the frame time (one load step per frame).
It is called again before every frame; nothing is recompiled.

Each cell gets a volume-preserving stretch along the trunk's local axis e (the tangent of the
centreline of meshes.trunk):

    S = (1 + eps) e(x)e + (1 + eps)^(-1/2) (I - e(x)e),      det S = 1
    eps = a(t) k(s) g(xi),   g(xi) = tanh(2 xi) / tanh(2)

with s = z / H the relative height, xi in [-1, 1] the position across the section along the
horizontal direction d = (cos theta, sin theta, 0): the side facing d is told to lengthen, the
opposite side to shorten, which bends the trunk away from d. The direction turns with time and
lags with height, theta = 2 pi t - LAG s, so the trunk sways round once per animation and its top
curls after the base; k(s) grows towards the thin top. a(t) ramps the amplitude in over the
first quarter.

The targets are mutually incompatible on purpose: g is not linear across the section and the
cross-section is told to change shape differently from fibre to fibre, so no displacement puts
every cell into its target shape. The solve finds the closest compatible shape (the minimum of
the total shape-targeting energy), as in the palm tree of Klar et al. (2020).
"""

from __future__ import annotations

import numpy as np

from meshes.trunk import trunk_centre, trunk_radius

#: geometry of examples/trunk.toml (meshes.trunk defaults)
HEIGHT, BASE_RADIUS, TOP_RADIUS, BEND = 10.0, 0.5, 0.15, 0.6
#: target axial strain at the edge of the top section, before the ramp
AMPLITUDE = 0.06
#: phase lag (radians) of the bending direction between the base and the top
LAG = 0.5 * np.pi


def amplitude(t: float) -> float:
    """a(t): a smooth ramp from 0 to AMPLITUDE over t in [0, 1/4], then constant."""
    r = min(max(4.0 * t, 0.0), 1.0)
    return AMPLITUDE * r * r * (3.0 - 2.0 * r)


def direction(s: np.ndarray, t: float) -> np.ndarray:
    """Horizontal bending direction d(s, t), shape (n, 2)."""
    theta = 2.0 * np.pi * t - LAG * s
    return np.stack([np.cos(theta), np.sin(theta)], axis=-1)


def axis(s: np.ndarray) -> np.ndarray:
    """Unit tangent of the centreline x = BEND s^2 at relative height s, shape (n, 3)."""
    e = np.stack([2.0 * BEND * s / HEIGHT, np.zeros_like(s), np.ones_like(s)], axis=-1)
    return e / np.linalg.norm(e, axis=-1, keepdims=True)


def sway(x: np.ndarray, t: float) -> np.ndarray:
    """S (n, 3, 3) for reference centroids x (n, 3) at frame time t."""
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    s = np.clip(x[:, 2] / HEIGHT, 0.0, 1.0)
    offset = x[:, :2] - trunk_centre(x[:, 2], HEIGHT, BEND)
    xi = np.sum(offset * direction(s, t), axis=1) / trunk_radius(x[:, 2], HEIGHT, BASE_RADIUS, TOP_RADIUS)
    k = 0.3 + 0.7 * s**2
    eps = amplitude(t) * k * np.tanh(2.0 * xi) / np.tanh(2.0)
    e = axis(s)
    ee = e[:, :, None] * e[:, None, :]
    along = (1.0 + eps)[:, None, None]
    return along * ee + along ** -0.5 * (np.eye(3) - ee)
