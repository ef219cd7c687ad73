"""Unstructured tetrahedral mesh of a fusiform (spindle-shaped) muscle with two tendons (gmsh OCC).

Geometry (SI units, axis along z)::

    z = 0 .. Lt              tendon_origin     cylinder of radius rt
    z = Lt .. Lt + L         belly             r(z) = rt + (rb - rt) sin(pi s)^2,  s = (z - Lt) / L
    z = Lt + L .. L + 2 Lt   tendon_insertion  cylinder of radius rt

with ``L = length``, ``Lt = tendon_length``, ``rb = belly_radius`` and
``rt = tendon_radius``.  The belly is a smooth B-spline loft through
:data:`SECTIONS` circular sections of the profile, so it joins the tendons
almost tangentially (``r'(0) = r'(L) = 0``).  The three solids are fragmented
together so that the interface disks are shared and the mesh is conforming
across them.
"""

from __future__ import annotations

import logging
import math
import time

import gmsh
import numpy as np

from meshes._gmsh import CURVATURE_ELEMENTS, curved_size_options, generate_tetrahedra, gmsh_session
from meshes._validate import ParameterError, positive_float
from meshes.data import MeshData, from_gmsh_model

__all__ = [
    "CURVATURE_ELEMENTS",
    "FUSIFORM_FACES",
    "FUSIFORM_REGIONS",
    "SECTIONS",
    "add_muscle",
    "belly_radius_at",
    "build_fusiform_model",
    "fusiform",
    "fusiform_options",
    "tendon_volume",
]

logger = logging.getLogger(__name__)

#: Physical volume names (tags 1..3) of :func:`fusiform`.
FUSIFORM_REGIONS = ("belly", "tendon_origin", "tendon_insertion")
#: Physical surface names (tags 1..3) of :func:`fusiform`.
FUSIFORM_FACES = ("origin", "insertion", "surface")
#: Number of circular sections the belly is lofted through.
SECTIONS = 13
#: Curved surfaces get at least this many elements per 2*pi radians of curvature
#: (gmsh ``Mesh.MeshSizeFromCurvature``), whatever ``size`` is: without it the
#: thin tendons would be faceted with ~7 segments and lose ~8 % of their volume.


def belly_radius_at(s: np.ndarray | float, belly_radius: float, tendon_radius: float) -> np.ndarray:
    """Belly radius at normalised position ``s`` in [0, 1]: ``rt + (rb - rt) sin(pi s)^2``."""
    return tendon_radius + (belly_radius - tendon_radius) * np.sin(np.pi * np.asarray(s, dtype=float)) ** 2


def _add_belly(z0: float, length: float, belly_radius: float, tendon_radius: float, x0: float = 0.0) -> int:
    """Loft the belly (axis ``x = x0, y = 0``) through :data:`SECTIONS` circles; return the OCC volume tag."""
    occ = gmsh.model.occ
    s = np.linspace(0.0, 1.0, SECTIONS)
    radii = belly_radius_at(s, belly_radius, tendon_radius)
    wires = []
    for si, ri in zip(s.tolist(), radii.tolist(), strict=True):
        circle = occ.addCircle(x0, 0.0, z0 + si * length, ri)
        wires.append(occ.addCurveLoop([circle]))
    out = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    volumes = [tag for dim, tag in out if dim == 3]
    if len(volumes) != 1:
        raise RuntimeError(f"fusiform: belly loft produced {len(volumes)} volumes instead of 1")
    return volumes[0]


def _face_name(z_center: float, total: float) -> str:
    """Name of an exterior face from the z coordinate of its centre of mass."""
    tol = 1e-6 * total
    if abs(z_center) < tol:
        return "origin"
    if abs(z_center - total) < tol:
        return "insertion"
    return "surface"


def add_muscle(
    length: float, belly_radius: float, tendon_radius: float, tendon_length: float, x0: float = 0.0
) -> tuple[int, int, int]:
    """Add the (unfragmented) belly, origin and insertion tendon solids on the axis ``x = x0, y = 0``.

    The muscle spans ``z in [0, length + 2 tendon_length]``; returns the OCC volume tags
    ``(belly, tendon_origin, tendon_insertion)``.
    """
    occ = gmsh.model.occ
    belly = _add_belly(tendon_length, length, belly_radius, tendon_radius, x0)
    origin = occ.addCylinder(x0, 0.0, 0.0, 0.0, 0.0, tendon_length, tendon_radius)
    insertion = occ.addCylinder(x0, 0.0, tendon_length + length, 0.0, 0.0, tendon_length, tendon_radius)
    return belly, origin, insertion


def build_fusiform_model(
    length: float, belly_radius: float, tendon_radius: float, tendon_length: float
) -> None:
    """Create the fragmented muscle geometry and its physical groups in the current gmsh model."""
    occ = gmsh.model.occ
    belly, origin, insertion = add_muscle(length, belly_radius, tendon_radius, tendon_length)
    _, mapping = occ.fragment([(3, belly)], [(3, origin), (3, insertion)])
    occ.synchronize()
    volumes: dict[str, list[int]] = {}
    for name, pieces in zip(FUSIFORM_REGIONS, mapping, strict=True):
        volumes[name] = [tag for dim, tag in pieces if dim == 3]
        if len(volumes[name]) != 1:
            raise RuntimeError(f"fusiform: fragment split {name} into {len(volumes[name])} volumes")

    owners: dict[int, int] = {}
    for tags in volumes.values():
        for _, surface in gmsh.model.getBoundary([(3, t) for t in tags], combined=False, oriented=False):
            owners[surface] = owners.get(surface, 0) + 1
    total = length + 2.0 * tendon_length
    faces: dict[str, list[int]] = {name: [] for name in FUSIFORM_FACES}
    for surface in sorted(s for s, count in owners.items() if count == 1):
        faces[_face_name(occ.getCenterOfMass(2, surface)[2], total)].append(surface)

    for tag, name in enumerate(FUSIFORM_REGIONS, start=1):
        gmsh.model.addPhysicalGroup(3, volumes[name], tag)
        gmsh.model.setPhysicalName(3, tag, name)
    for tag, name in enumerate(FUSIFORM_FACES, start=1):
        if not faces[name]:
            raise RuntimeError(f"fusiform: no exterior surface classified as {name!r}")
        gmsh.model.addPhysicalGroup(2, faces[name], tag)
        gmsh.model.setPhysicalName(2, tag, name)


def fusiform_options(size: float, tendon_radius: float | None = None) -> dict[str, float]:
    """gmsh options used for maximum element size ``size`` (refined on curved surfaces; below
    ``size = tendon_radius`` the tendons' elements shrink with ``size``: meshes._gmsh.curvature_elements)."""
    return curved_size_options(size, tendon_radius)


def fusiform(
    length: float = 0.1,
    belly_radius: float = 0.015,
    tendon_radius: float = 0.004,
    tendon_length: float = 0.02,
    size: float = 0.004,
) -> MeshData:
    """Mesh a spindle-shaped muscle belly with a cylindrical tendon at each end (SI metres).

    Parameters
    ----------
    length:
        Belly length ``L`` (the whole muscle spans ``z in [0, L + 2 tendon_length]``), > 0.
    belly_radius:
        Radius at the middle of the belly, > 0 and > ``tendon_radius``.
    tendon_radius:
        Radius of the tendons and of the belly's ends, > 0.
    tendon_length:
        Length of each tendon, > 0.
    size:
        Maximum element size, > 0; curved surfaces are refined to
        max(:data:`CURVATURE_ELEMENTS`, 16 tendon_radius / size) elements per 2 pi
        radians, so below ``size = tendon_radius`` every element shrinks with ``size``.

    Returns
    -------
    MeshData
        Volumes ``belly`` (1), ``tendon_origin`` (2, z in [0, Lt]) and
        ``tendon_insertion`` (3, z in [Lt + L, L + 2 Lt]); faces ``origin`` (1, the
        disk z=0), ``insertion`` (2, the disk z=L+2Lt) and ``surface`` (3, the
        lateral skin).  The interfaces between volumes are shared but not named.
    """
    belly_length = positive_float("fusiform", "length", length)
    rb = positive_float("fusiform", "belly_radius", belly_radius)
    rt = positive_float("fusiform", "tendon_radius", tendon_radius)
    tendon = positive_float("fusiform", "tendon_length", tendon_length)
    lc = positive_float("fusiform", "size", size)
    if rt >= rb:
        raise ParameterError(f"fusiform: tendon_radius must be < belly_radius ({rb!r}), got {rt!r}")
    start = time.perf_counter()
    with gmsh_session(fusiform_options(lc, rt), name="fusiform"):
        build_fusiform_model(belly_length, rb, rt, tendon)
        generate_tetrahedra("fusiform")
        mesh = from_gmsh_model(gmsh.model)
    logger.info(
        "fusiform(length=%g, belly_radius=%g, tendon_radius=%g, tendon_length=%g, size=%g): "
        "%d tets, %d points in %.2f s",
        belly_length,
        rb,
        rt,
        tendon,
        lc,
        mesh.num_cells,
        mesh.num_points,
        time.perf_counter() - start,
    )
    return mesh


def tendon_volume(tendon_radius: float, tendon_length: float) -> float:
    """Exact volume of one tendon cylinder."""
    return math.pi * tendon_radius**2 * tendon_length
