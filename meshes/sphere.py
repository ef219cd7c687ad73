"""Tetrahedral meshes of a ball (gmsh OpenCASCADE), optionally one octant, refined near the south pole.

The octant is the part x >= 0, y >= 0, z <= 0 of the ball of radius R about the origin: with
symmetry conditions on its three flat faces it models a whole sphere squeezed between two plates
(Hertz contact at the south pole (0, 0, -R), a mesh vertex).

``sphere_pair``: two such octants, one on the other, touching at the origin (Hertz contact of two deformable
spheres; separate bodies of one mesh, meshes.combine).
"""

from __future__ import annotations

import logging
import time

import gmsh
import numpy as np

from meshes._gmsh import generate_tetrahedra, gmsh_session
from meshes._validate import ParameterError, positive_float
from meshes.data import MeshData, from_gmsh_model

__all__ = ["OCTANT_FACES", "PAIR_BODIES", "SPHERE_FACES", "sphere", "sphere_pair"]

logger = logging.getLogger(__name__)

#: Boundary names of :func:`sphere` (``octant=False``).
SPHERE_FACES = ("surface",)
#: Boundary names of :func:`sphere` (``octant=True``): the flat faces x = 0, y = 0, z = 0 and the curved one.
OCTANT_FACES = ("xmin", "ymin", "zmax", "surface")


def _classify(centre: tuple[float, float, float], radius: float) -> str:
    tol = 1e-6 * radius
    x, y, z = centre
    if abs(x) < tol:
        return "xmin"
    if abs(y) < tol:
        return "ymin"
    if abs(z) < tol:
        return "zmax"
    return "surface"


def sphere(radius: float = 1.0, size: float = 0.25, octant: bool = False, pole_size: float | None = None,
           pole_radius: float | None = None, growth: float = 0.3) -> MeshData:
    """Mesh the ball |x| <= radius (or its octant x, y >= 0, z <= 0) with linear tetrahedra.

    Parameters
    ----------
    radius:
        Ball radius R, > 0.
    size:
        Maximum element size, > 0.
    octant:
        Mesh only the octant x >= 0, y >= 0, z <= 0 (faces ``xmin``, ``ymin``, ``zmax``, ``surface``).
    pole_size, pole_radius:
        Element size within ``pole_radius`` of the south pole (0, 0, -R), growing linearly (by
        ``growth`` per unit distance) to ``size`` beyond; both or neither.
    growth:
        How fast the element size grows beyond ``pole_radius`` (size per distance), > 0.

    Returns
    -------
    MeshData
        Volume ``body`` (tag 1); boundary ``surface`` (the sphere) and, for the octant, its flat
        faces ``xmin`` (x = 0), ``ymin`` (y = 0), ``zmax`` (z = 0, the equator).
    """
    R = positive_float("sphere", "radius", radius)
    h = positive_float("sphere", "size", size)
    if (pole_size is None) != (pole_radius is None):
        raise ParameterError("sphere: pole_size and pole_radius go together, got one of them")
    refine = pole_size is not None
    rate = positive_float("sphere", "growth", growth)
    if refine:
        hp = positive_float("sphere", "pole_size", pole_size)
        rp = positive_float("sphere", "pole_radius", pole_radius)
    start = time.perf_counter()
    options = {"Mesh.MeshSizeMax": h, "Mesh.MeshSizeMin": 0.0, "Mesh.MeshSizeFromCurvature": 0,
               "Mesh.MeshSizeExtendFromBoundary": 0 if refine else 1, "Mesh.MeshSizeFromPoints": 0}
    with gmsh_session(options, name="sphere"):
        occ = gmsh.model.occ
        ball = occ.addSphere(0.0, 0.0, 0.0, R)
        if octant:
            box = occ.addBox(0.0, 0.0, -R, R, R, R)
            result, _ = occ.intersect([(3, ball)], [(3, box)])
            volume = result[0][1]
        else:
            volume = ball
        occ.synchronize()
        faces: dict[str, list[int]] = {}
        for _, surface in gmsh.model.getBoundary([(3, volume)], combined=False, oriented=False):
            name = _classify(occ.getCenterOfMass(2, surface), R) if octant else "surface"
            faces.setdefault(name, []).append(surface)
        gmsh.model.addPhysicalGroup(3, [volume], 1)
        gmsh.model.setPhysicalName(3, 1, "body")
        for tag, name in enumerate(OCTANT_FACES if octant else SPHERE_FACES, start=1):
            gmsh.model.addPhysicalGroup(2, faces.get(name, []), tag)
            gmsh.model.setPhysicalName(2, tag, name)
        if refine:
            field = gmsh.model.mesh.field
            f = field.add("MathEval")
            distance = f"Sqrt(x*x + y*y + (z + {R!r})*(z + {R!r}))"
            field.setString(f, "F", f"Min({h!r}, {hp!r} + {rate!r} * Max({distance} - {rp!r}, 0))")
            field.setAsBackgroundMesh(f)
        generate_tetrahedra("sphere")
        mesh = from_gmsh_model(gmsh.model)
    logger.info("sphere(radius=%g, size=%g, octant=%s, pole_size=%s): %d tets, %d points in %.2f s", R, h, octant,
                pole_size, mesh.num_cells, mesh.num_points, time.perf_counter() - start)
    return mesh


#: the bodies of :func:`sphere_pair`
PAIR_BODIES = ("upper", "lower")


def sphere_pair(radius: float = 1.0, lower_radius: float | None = None, size: float = 0.25,
                pole_size: float | None = None, pole_radius: float | None = None,
                lower_pole_size: float | None = None, growth: float = 0.3, gap: float = 0.0) -> MeshData:
    """Two ball octants (x, y >= 0) touching at the origin: ``upper``, the part z <= R1 of the ball of radius
    R1 = ``radius`` about (0, 0, R1), and ``lower``, the part z >= -R2 of the ball of radius R2 = ``lower_radius``
    (default R1) about (0, 0, -R2); each refined near the origin as :func:`sphere` near its pole (``pole_size``;
    ``lower_pole_size``, default ``pole_size``, for the lower one: different sizes make the two meshes meet
    at non-matching nodes; ``growth`` as :func:`sphere`'s). ``gap`` >= 0 (default 0): the upper octant moved up by
    it, so that the two start that far apart (the upper ball about (0, 0, R1 + gap)).

    The lower octant is :func:`sphere`'s turned by 180 degrees about the line x = y, z = 0 ((x, y, z) ->
    (y, x, -z), which keeps the cells' orientation) and moved down by R2.

    Returns
    -------
    MeshData
        Volumes ``upper``, ``lower``; boundaries ``<body>_xmin``, ``<body>_ymin`` (the symmetry planes x = 0,
        y = 0), ``upper_zmax`` (z = R1) and ``lower_zmin`` (z = -R2) (the equators), ``<body>_sphere`` (the
        curved surface) and ``<body>_surface`` (the whole boundary).
    """
    from meshes.combine import combine

    R1 = positive_float("sphere_pair", "radius", radius)
    R2 = R1 if lower_radius is None else positive_float("sphere_pair", "lower_radius", lower_radius)
    if isinstance(gap, bool) or not isinstance(gap, (int, float)) or not 0.0 <= gap < float("inf"):
        raise ParameterError(f"sphere_pair: gap must be a finite number >= 0, got {gap!r}")
    upper = sphere(R1, size, True, pole_size, pole_radius, growth)
    lower = sphere(R2, size, True, pole_size if lower_pole_size is None else lower_pole_size,
                   pole_radius, growth)
    upper = MeshData(upper.points + np.array([0.0, 0.0, R1 + float(gap)]), upper.cells, upper.cell_tags, upper.facets,
                     upper.facet_tags, dict(upper.region_names),
                     {("sphere" if k == "surface" else k): v for k, v in upper.boundary_names.items()})
    renamed = {"xmin": "ymin", "ymin": "xmin", "zmax": "zmin", "surface": "sphere"}
    points = lower.points[:, [1, 0, 2]] * np.array([1.0, 1.0, -1.0]) - np.array([0.0, 0.0, R2])
    lower = MeshData(points, lower.cells, lower.cell_tags, lower.facets, lower.facet_tags,
                     dict(lower.region_names), {renamed[k]: v for k, v in lower.boundary_names.items()})
    return combine({"upper": upper, "lower": lower})
