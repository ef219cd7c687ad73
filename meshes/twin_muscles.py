"""Two separate fusiform muscles side by side, mirror images of each other about the plane x = 0 (no fat).

Muscle b is :func:`meshes.fusiform.fusiform`'s muscle (same parameters, and ``turn_elements``) moved to the
axis ``x = c, y = 0`` with ``c = belly_radius + gap / 2``; muscle a is its mirror image
``(x, y, z) -> (-x, y, z)`` (the same mesh reflected: every node of a is the exact mirror image of the node of b
with the same local number, and a's cells and triangles are b's with two vertices swapped, so that they keep
their orientation). The bellies' exact surfaces come closest at mid-length on the plane y = 0, ``gap`` apart (the
meshed, faceted surfaces a chordal sag more when no node lies on y = 0 there: :func:`mesh_gap` measures it).
:func:`meshes.combine.combine` puts the two bodies in one mesh of separate bodies (no shared node), so that
contact (model.problem.body_contact) couples them.

Regions (volumes): ``a_belly``, ``a_tendon`` (both of a's tendons), ``b_belly``, ``b_tendon``. Boundaries:
``a_origin`` (the tendon disk at z = 0), ``a_insertion`` (z = length + 2 tendon_length), ``a_lateral`` (the rest
of a's surface: belly and tendons), ``a_surface`` (a's whole boundary, from combine), the same for b.
"""

from __future__ import annotations

import logging
import time

import gmsh
import numpy as np

from meshes._gmsh import CURVATURE_ELEMENTS, generate_tetrahedra, gmsh_session
from meshes._validate import ParameterError, positive_float
from meshes.arm_segment import arm_segment_options, check_turn_elements
from meshes.combine import combine
from meshes.data import MeshData, from_gmsh_model
from meshes.fusiform import build_fusiform_model

__all__ = ["TWIN_MUSCLES_FACES", "TWIN_MUSCLES_REGIONS", "mesh_gap", "mirrored", "twin_muscles"]

logger = logging.getLogger(__name__)

_GENERATOR = "twin_muscles"
#: Region names of :func:`twin_muscles`.
TWIN_MUSCLES_REGIONS = ("a_belly", "a_tendon", "b_belly", "b_tendon")
#: Boundary names of :func:`twin_muscles`.
TWIN_MUSCLES_FACES = ("a_origin", "a_insertion", "a_lateral", "a_surface", "b_origin", "b_insertion", "b_lateral",
                      "b_surface")


def mirrored(data: MeshData) -> MeshData:
    """The mirror image of ``data`` about the plane x = 0: points (x, y, z) -> (-x, y, z), the same node numbers,
    every cell and triangle with its last two vertices swapped (a reflection turns the orientation over)."""
    points = data.points * np.array([-1.0, 1.0, 1.0])
    return MeshData(points, data.cells[:, [0, 1, 3, 2]], data.cell_tags, data.facets[:, [0, 2, 1]], data.facet_tags,
                    dict(data.region_names), dict(data.boundary_names))


def _muscle(data: MeshData, offset: float) -> MeshData:
    """The fusiform mesh with regions belly (1) and tendon (2: both tendons), boundaries origin, insertion and
    lateral (fusiform's surface), moved by ``offset`` along x."""
    tags = data.region_names
    cell_tags = np.where(data.cell_tags == tags["belly"], 1, 2).astype(np.int32)
    faces = {"origin": "origin", "insertion": "insertion", "lateral": "surface"}
    facets = [data.facets[data.facet_tags == data.boundary_names[old]] for old in faces.values()]
    facet_tags = np.concatenate([np.full(len(f), i, dtype=np.int32) for i, f in enumerate(facets, 1)])
    points = data.points + np.array([offset, 0.0, 0.0])
    return MeshData(points, data.cells, cell_tags, np.vstack(facets), facet_tags, {"belly": 1, "tendon": 2},
                    {name: i for i, name in enumerate(faces, 1)})


def mesh_gap(data: MeshData) -> float:
    """The meshed gap (m): the distance between the two muscles' faceted surfaces along x, ``2 min x`` over muscle
    b's lateral nodes (a linear function's minimum over b's faceted surface is at a node; a is b's mirror image).
    At least ``gap``: the nodes lie on the exact surfaces, the facets inside them."""
    nodes = np.unique(data.facets[data.facet_tags == data.boundary_names["b_lateral"]])
    return float(2.0 * data.points[nodes, 0].min())


def twin_muscles(
    length: float = 0.04,
    belly_radius: float = 0.006,
    tendon_radius: float = 0.002,
    tendon_length: float = 0.01,
    gap: float = 0.0005,
    size: float = 0.003,
    turn_elements: int = CURVATURE_ELEMENTS,
) -> MeshData:
    """Two fusiform muscles a (x < 0) and b (x > 0), mirror images about x = 0, their bellies ``gap`` apart
    (module docstring).

    Parameters
    ----------
    length, belly_radius, tendon_radius, tendon_length, size:
        Each muscle's :func:`meshes.fusiform.fusiform` parameters (m; ``tendon_radius < belly_radius``).
    turn_elements:
        Elements per 2 pi radians on the curved surfaces (an integer >= 6; fewer than the default for a coarse,
        fast mesh), as :func:`meshes.layered_arm.layered_arm`'s.
    gap:
        The closest distance between the bellies' exact surfaces at rest (m), at mid-length: > 0 (two separate
        bodies) and < ``belly_radius`` (muscles side by side, not a pair far apart).

    Returns
    -------
    MeshData
        Regions :data:`TWIN_MUSCLES_REGIONS`, boundaries :data:`TWIN_MUSCLES_FACES`; muscle a's nodes are the
        mirror images of muscle b's (the first half of the points is a's, the second b's, in the same order).

    Raises
    ------
    ParameterError
        A parameter that is not a finite number > 0, ``tendon_radius >= belly_radius`` or
        ``gap >= belly_radius``.
    """
    rb = positive_float(_GENERATOR, "belly_radius", belly_radius)
    rt = positive_float(_GENERATOR, "tendon_radius", tendon_radius)
    g = positive_float(_GENERATOR, "gap", gap)
    lengths = {name: positive_float(_GENERATOR, name, value)
               for name, value in (("length", length), ("tendon_length", tendon_length), ("size", size))}
    if rt >= rb:
        raise ParameterError(f"{_GENERATOR}: tendon_radius must be < belly_radius ({rb!r}), got {rt!r}")
    if g >= rb:
        raise ParameterError(f"{_GENERATOR}: gap must be < belly_radius ({rb!r}), got {g!r}")
    turns = check_turn_elements(_GENERATOR, turn_elements)
    start = time.perf_counter()
    with gmsh_session(arm_segment_options(lengths["size"], rt, turns), name=_GENERATOR):
        build_fusiform_model(lengths["length"], rb, rt, lengths["tendon_length"])
        generate_tetrahedra(_GENERATOR)
        one = from_gmsh_model(gmsh.model)
    b = _muscle(one, rb + 0.5 * g)
    mesh = combine({"a": mirrored(b), "b": b})
    logger.info("twin_muscles(length=%g, belly_radius=%g, tendon_radius=%g, tendon_length=%g, gap=%g, size=%g, "
                "turn_elements=%d): %d tets, %d points, meshed gap %.4g in %.2f s", lengths["length"], rb, rt,
                lengths["tendon_length"], g, lengths["size"], turns, mesh.num_cells, mesh.num_points, mesh_gap(mesh),
                time.perf_counter() - start)
    return mesh
