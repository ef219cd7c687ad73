"""Tetrahedral mesh of a circular cylinder (gmsh OpenCASCADE): a disk mesh extruded along z in layers.

The extrusion (without recombination, so each prism is split into tetrahedra) makes every lateral
facet a vertical plane: a function linear in z then solves zero-flux problems on the discrete
domain exactly (a Laplace fibre field is the axis to rounding, not to the faceting error).

The disk's centre is a geometric vertex of the disk (fragmented into it before extrusion), so the axis
``x = y = 0`` is an edge of the mesh with a vertex on every layer, and the circle starts (and is
split) at ``(radius, 0)``: the nodes ``(0, 0, z)`` and ``(radius, 0, z)`` exist (to rounding) on the bottom
(``z = 0``) and top (``z = length``) faces, for point constraints that remove rigid-body modes.
"""

from __future__ import annotations

import logging
import time

import gmsh

from meshes._gmsh import CURVATURE_ELEMENTS, curved_size_options, generate_tetrahedra, gmsh_session
from meshes._validate import positive_float
from meshes.data import MeshData, from_gmsh_model

__all__ = ["CURVATURE_ELEMENTS", "CYLINDER_FACES", "build_cylinder_model", "cylinder", "cylinder_options"]

logger = logging.getLogger(__name__)

#: Boundary names (facet tags 1..3) of :func:`cylinder`.
CYLINDER_FACES = ("bottom", "top", "lateral")
#: Curved surfaces get at least this many elements per 2*pi radians of curvature
#: (gmsh ``Mesh.MeshSizeFromCurvature``), whatever ``size`` is: keeps the
#: faceting volume error at about 2 % on coarse meshes.


def _classify_face(z_center: float, length: float) -> str:
    """Name of a cylinder face from the z coordinate of its centre of mass."""
    tol = 1e-6 * length
    if abs(z_center) < tol:
        return "bottom"
    if abs(z_center - length) < tol:
        return "top"
    return "lateral"


def build_cylinder_model(radius: float, length: float, layers: int = 1) -> None:
    """Create the cylinder (a disk extruded in ``layers`` layers) and its physical groups (no meshing)."""
    occ = gmsh.model.occ
    disk = occ.addDisk(0.0, 0.0, 0.0, radius, radius)  # its circle starts at (radius, 0, 0)
    # the centre becomes a vertex inside the disk, extruded into an edge on the axis
    pieces, _ = occ.fragment([(2, disk)], [(0, occ.addPoint(0.0, 0.0, 0.0))])
    surfaces = [(dim, tag) for dim, tag in pieces if dim == 2]
    extruded = occ.extrude(surfaces, 0.0, 0.0, length, numElements=[layers], recombine=False)
    volume = next(tag for dim, tag in extruded if dim == 3)
    occ.synchronize()
    faces: dict[str, list[int]] = {name: [] for name in CYLINDER_FACES}
    for _, surface in gmsh.model.getBoundary([(3, volume)], combined=False, oriented=False):
        z_center = occ.getCenterOfMass(2, surface)[2]
        faces[_classify_face(z_center, length)].append(surface)
    gmsh.model.addPhysicalGroup(3, [volume], 1)
    gmsh.model.setPhysicalName(3, 1, "body")
    for tag, name in enumerate(CYLINDER_FACES, start=1):
        gmsh.model.addPhysicalGroup(2, faces[name], tag)
        gmsh.model.setPhysicalName(2, tag, name)


def cylinder_options(size: float) -> dict[str, float]:
    """gmsh options used for maximum element size ``size`` (refined on curved surfaces)."""
    return curved_size_options(size)


def cylinder(radius: float = 0.5, length: float = 2.0, size: float = 0.25) -> MeshData:
    """Mesh the cylinder ``x^2 + y^2 <= radius^2, 0 <= z <= length`` with linear tetrahedra.

    Parameters
    ----------
    radius:
        Cylinder radius, > 0.
    length:
        Cylinder length along z, > 0.
    size:
        Maximum element size, > 0; curved surfaces are refined to
        :data:`CURVATURE_ELEMENTS` elements per 2 pi radians.

    Returns
    -------
    MeshData
        Volume ``body`` (tag 1); faces ``bottom`` (z=0), ``top`` (z=length) and
        ``lateral`` (tags 1..3).  The vertices ``(0, 0, z)`` and ``(radius, 0, z)`` exist
        (to rounding) for ``z = 0`` and ``z = length`` and on every extrusion layer between:
        point constraints there remove the rigid-body modes (e.g. a slider end: fix the
        axis point and the y component at ``(radius, 0, z)``).
    """
    r = positive_float("cylinder", "radius", radius)
    h = positive_float("cylinder", "length", length)
    lc = positive_float("cylinder", "size", size)
    start = time.perf_counter()
    with gmsh_session(cylinder_options(lc), name="cylinder"):
        build_cylinder_model(r, h, layers=max(1, round(h / lc)))
        generate_tetrahedra("cylinder")
        mesh = from_gmsh_model(gmsh.model)
    logger.info(
        "cylinder(radius=%g, length=%g, size=%g): %d tets, %d points in %.2f s",
        r,
        h,
        lc,
        mesh.num_cells,
        mesh.num_points,
        time.perf_counter() - start,
    )
    return mesh
