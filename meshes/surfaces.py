"""Closed triangle surfaces for render meshes (output.render_mesh): smooth skins to embed in coarse bodies.

    points, triangles = tube(centre=(0.1, 0.1), radius=0.095, length=1.0, around=32, along=30, exponent=4)
    write_surface("skin.obj", points, triangles)

``tube``: a closed tube along x from 0 to ``length`` around the axis (y, z) = ``centre``, ``around`` points
per ring and ``along`` rings, with flat end caps (a fan about each end's centre), outward-facing triangles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from meshes._validate import positive_float


def tube(centre: tuple[float, float] = (0.0, 0.0), radius: float = 1.0, length: float = 1.0, around: int = 32,
         along: int = 30, exponent: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(points (N, 3), triangles (M, 3)) of a closed tube (module docstring) whose cross-section is the
    superellipse |y'|^n + |z'|^n = radius^n, n = ``exponent`` (2: a circle; 4: a rounded square)."""
    radius, length = positive_float("tube", "radius", radius), positive_float("tube", "length", length)
    if around < 3 or along < 1:
        raise ValueError(f"around = {around} must be >= 3 and along = {along} >= 1")
    exponent = positive_float("tube", "exponent", exponent)
    angle = 2 * np.pi * np.arange(around) / around
    x = np.linspace(0.0, length, along + 1)
    c, s = np.cos(angle), np.sin(angle)
    power = 2.0 / exponent
    ring = np.c_[centre[0] + radius * np.sign(c) * np.abs(c) ** power,
                 centre[1] + radius * np.sign(s) * np.abs(s) ** power]
    points = np.array([[xi, y, z] for xi in x for y, z in ring])
    triangles = []
    for i in range(along):
        for j in range(around):
            a, b = i * around + j, i * around + (j + 1) % around
            c, d = a + around, b + around
            triangles += [(a, b, d), (a, d, c)]
    first, last = len(points), len(points) + 1
    points = np.vstack([points, [0.0, *centre], [length, *centre]])
    for j in range(around):
        triangles.append((first, (j + 1) % around, j))
        triangles.append((last, along * around + j, along * around + (j + 1) % around))
    return points, np.array(triangles, dtype=np.int64)


def write_surface(path: Path | str, points: np.ndarray, triangles: np.ndarray) -> Path:
    """Write a triangle surface with meshio (format from the suffix: .obj, .stl, .ply, ...)."""
    import meshio

    path = Path(path)
    meshio.write(path, meshio.Mesh(np.asarray(points, dtype=float), [("triangle", np.asarray(triangles))]))
    return path


__all__ = ["tube", "write_surface"]
