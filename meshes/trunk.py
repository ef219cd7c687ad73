"""Unstructured tetrahedral mesh of a tall, tapered, slightly curved tree trunk (gmsh OpenCASCADE).

Geometry (axis along z, horizontal circular sections)::

    s = z / H                                   H = height, 0 <= s <= 1
    radius(s)     = rb + (rt - rb) s            rb = base_radius, rt = top_radius (linear taper)
    centre(s)     = (bend s^2, 0, z)            the trunk leans towards +x, more and more with height

The lateral surface is a smooth B-spline loft through :data:`SECTIONS` circles.
Physical groups: volume ``trunk``; faces ``base`` (the disk z = 0), ``top`` (the
disk z = H) and ``bark`` (the lateral surface).
"""

from __future__ import annotations

import logging
import math
import time

import gmsh
import numpy as np

from meshes._gmsh import generate_tetrahedra, gmsh_session
from meshes._validate import ParameterError, positive_float
from meshes.data import MeshData, from_gmsh_model

__all__ = [
    "SECTIONS",
    "TRUNK_CURVATURE_ELEMENTS",
    "TRUNK_FACES",
    "build_trunk_model",
    "trunk",
    "trunk_centre",
    "trunk_options",
    "trunk_radius",
    "trunk_volume",
]

logger = logging.getLogger(__name__)

#: Boundary names (facet tags 1..3) of :func:`trunk`.
TRUNK_FACES = ("base", "top", "bark")
#: Number of circular sections the trunk is lofted through.
SECTIONS = 11
#: Elements per 2 pi radians of curvature on the bark (gmsh Mesh.MeshSizeFromCurvature). Lower than
#: meshes._gmsh.CURVATURE_ELEMENTS: the thin top (radius 0.15 of a 10 m trunk) would otherwise
#: dominate the element count; 10 keeps the faceting volume error near 6 % at the coarsest sizes.
TRUNK_CURVATURE_ELEMENTS = 10


def trunk_radius(z: np.ndarray | float, height: float = 10.0, base_radius: float = 0.5,
                 top_radius: float = 0.15) -> np.ndarray:
    """Radius of the section at height ``z`` (linear taper from ``base_radius`` to ``top_radius``)."""
    s = np.clip(np.asarray(z, dtype=float) / height, 0.0, 1.0)
    return base_radius + (top_radius - base_radius) * s


def trunk_centre(z: np.ndarray | float, height: float = 10.0, bend: float = 0.6) -> np.ndarray:
    """Centre (x, y) of the section at height ``z``, shape (..., 2): ``(bend (z/H)^2, 0)``."""
    s = np.clip(np.asarray(z, dtype=float) / height, 0.0, 1.0)
    return np.stack([bend * s**2, np.zeros_like(s)], axis=-1)


def trunk_volume(height: float = 10.0, base_radius: float = 0.5, top_radius: float = 0.15) -> float:
    """Exact volume of the trunk (a frustum; horizontal shearing by the bend does not change it)."""
    return math.pi * height * (base_radius**2 + base_radius * top_radius + top_radius**2) / 3.0


def _face_name(z_center: float, height: float) -> str:
    tol = 1e-6 * height
    if abs(z_center) < tol:
        return "base"
    if abs(z_center - height) < tol:
        return "top"
    return "bark"


def build_trunk_model(height: float, base_radius: float, top_radius: float, bend: float) -> None:
    """Create the lofted trunk and its physical groups in the current gmsh model (no meshing)."""
    occ = gmsh.model.occ
    z = np.linspace(0.0, height, SECTIONS)
    radii = trunk_radius(z, height, base_radius, top_radius)
    centres = trunk_centre(z, height, bend)
    wires = []
    for zi, ri, (xi, yi) in zip(z.tolist(), radii.tolist(), centres.tolist(), strict=True):
        wires.append(occ.addCurveLoop([occ.addCircle(xi, yi, zi, ri)]))
    out = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    volumes = [tag for dim, tag in out if dim == 3]
    if len(volumes) != 1:
        raise RuntimeError(f"trunk: the loft produced {len(volumes)} volumes instead of 1")
    occ.synchronize()
    faces: dict[str, list[int]] = {name: [] for name in TRUNK_FACES}
    for _, surface in gmsh.model.getBoundary([(3, volumes[0])], combined=False, oriented=False):
        faces[_face_name(occ.getCenterOfMass(2, surface)[2], height)].append(surface)
    gmsh.model.addPhysicalGroup(3, volumes, 1)
    gmsh.model.setPhysicalName(3, 1, "trunk")
    for tag, name in enumerate(TRUNK_FACES, start=1):
        if not faces[name]:
            raise RuntimeError(f"trunk: no surface classified as {name!r}")
        gmsh.model.addPhysicalGroup(2, faces[name], tag)
        gmsh.model.setPhysicalName(2, tag, name)


def trunk_options(size: float) -> dict[str, float]:
    """gmsh options used for maximum element size ``size`` (refined on the curved bark)."""
    return {"Mesh.MeshSizeMax": size, "Mesh.MeshSizeMin": 0.0, "Mesh.MeshSizeFromCurvature": TRUNK_CURVATURE_ELEMENTS}


def trunk(height: float = 10.0, base_radius: float = 0.5, top_radius: float = 0.15, bend: float = 0.6,
          size: float = 0.3) -> MeshData:
    """Mesh a tapered, slightly curved trunk standing on the plane z = 0 with linear tetrahedra.

    Parameters
    ----------
    height:
        Height ``H`` of the trunk (z in [0, H]), > 0.
    base_radius, top_radius:
        Radii of the base and top sections, > 0 (linear taper in between).
    bend:
        Horizontal offset (towards +x) of the top centre; the centreline is ``x = bend (z/H)^2``.
        Finite, ``|bend| < height``; 0 gives a straight, conical trunk.
    size:
        Maximum element size, > 0; the bark is refined to :data:`TRUNK_CURVATURE_ELEMENTS`
        elements per 2 pi radians, so the thin top gets smaller elements.

    Returns
    -------
    MeshData
        Volume ``trunk`` (tag 1); faces ``base`` (1, z = 0), ``top`` (2, z = H), ``bark`` (3).
    """
    h = positive_float("trunk", "height", height)
    rb = positive_float("trunk", "base_radius", base_radius)
    rt = positive_float("trunk", "top_radius", top_radius)
    lc = positive_float("trunk", "size", size)
    if isinstance(bend, bool) or not isinstance(bend, (int, float)) or not math.isfinite(bend) or abs(bend) >= h:
        raise ParameterError(f"trunk: bend must be a finite number with |bend| < height ({h!r}), got {bend!r}")
    if max(rb, rt) >= 0.5 * h:
        raise ParameterError(f"trunk: base_radius and top_radius must be < height / 2, got {rb!r}, {rt!r}")
    start = time.perf_counter()
    with gmsh_session(trunk_options(lc), name="trunk"):
        build_trunk_model(h, rb, rt, float(bend))
        generate_tetrahedra("trunk")
        mesh = from_gmsh_model(gmsh.model)
    logger.info("trunk(height=%g, base_radius=%g, top_radius=%g, bend=%g, size=%g): %d tets, %d points in %.2f s",
                h, rb, rt, bend, lc, mesh.num_cells, mesh.num_points, time.perf_counter() - start)
    return mesh
