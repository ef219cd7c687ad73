"""The layered arm segment: two fusiform muscles and a fat layer as three separate bodies (no shared node).

The geometry is :func:`meshes.arm_segment.arm_segment`'s (same parameters, same defaults): a cylinder of fat
``x^2 + y^2 <= R^2, z in [0, L]`` with the muscles' volumes taken out (the OCC boolean of the cylinder with the
muscles: the fat's pieces that belong to no muscle), muscle a on the axis ``x = -spacing / 2``, muscle b on
``x = +spacing / 2``. It is meshed once, conforming, and then cut open along the muscle-fat interfaces: every
body gets its own copy of the interface nodes (:func:`split_bodies`), and :func:`meshes.combine.combine` puts the
three bodies into one mesh of separate bodies, so that contact and sliding (model.problem.body_contact) couple
them instead of shared nodes.

Why not three independent gmsh meshes: their interface triangulations would not match, and a node of the fat's
cavity (on the exact curved surface) would start a chordal sag h^2 / (8 r) away from the muscle's faceted
surface, about 0.2 mm at the default size (16 elements per turn on r = 11 mm), which zero-length sliding springs
would pull shut: a spurious pre-stress as large as the activation's bulge. Cut open, every cavity node starts on a
vertex of the muscle's surface (gap 0 exactly), and the layered and conforming meshes have the same nodes, so
their displacements compare node by node.

Regions (volumes): ``a_belly``, ``a_tendon``, ``b_belly``, ``b_tendon``, ``fat``. Boundaries: ``a_origin``,
``a_insertion`` (muscle a's tendon disks at z = 0 and z = L), ``a_lateral`` (the rest of muscle a's surface:
belly and tendons, the fat's cavity), the same for b, ``fat_proximal``, ``fat_distal`` (the fat's end faces),
``fat_skin``, ``fat_cavity_a`` and ``fat_cavity_b`` (the fat's side of the interface with muscle a / b), and
``a_surface``, ``b_surface``, ``fat_surface`` (each body's whole boundary, from combine). Touching muscles
(``touching``) add ``a_flat``, ``a_round``, ``b_flat``, ``b_round``; muscles apart across a void (``gap`` > 0)
also ``fat_void`` (:func:`layered_arm`).
"""

from __future__ import annotations

import logging
import time

import gmsh
import numpy as np

from meshes._gmsh import CURVATURE_ELEMENTS, generate_tetrahedra, gmsh_session
from meshes._validate import ParameterError, positive_float
from meshes.arm_segment import GAP_FACES, _check, arm_segment_options, build_arm_segment_model, check_turn_elements
from meshes.combine import combine
from meshes.data import MeshData, from_gmsh_model
from meshes.topology import boundary_facets

__all__ = ["GAP_BOUNDARY", "GAP_FACES", "LAYERED_ARM_BODIES", "LAYERED_ARM_FACES", "LAYERED_ARM_REGIONS", "layered_arm",
           "layered_arm_meshes", "TOUCHING_FACES", "split_bodies"]

logger = logging.getLogger(__name__)

_GENERATOR = "layered_arm"
#: The bodies and the conforming mesh's regions each one takes.
LAYERED_ARM_BODIES = {"a": ("belly_a", "tendon_a"), "b": ("belly_b", "tendon_b"), "fat": ("fat",)}
#: Region names of :func:`layered_arm`.
LAYERED_ARM_REGIONS = ("a_belly", "a_tendon", "b_belly", "b_tendon", "fat")
#: The extra boundary names of ``layered_arm(touching=True)``: each muscle's copy of the flat face the two share,
#: and the rest of its lateral surface (the fat's cavity).
TOUCHING_FACES = ("a_flat", "a_round", "b_flat", "b_round")
#: The extra boundary of ``layered_arm(touching=True, gap=g > 0)`` (besides :data:`TOUCHING_FACES`): the fat's
#: surface facing the void between the flat faces (a free surface).
GAP_BOUNDARY = "fat_void"
#: Boundary names of :func:`layered_arm`.
LAYERED_ARM_FACES = ("a_origin", "a_insertion", "a_lateral", "a_surface", "b_origin", "b_insertion", "b_lateral",
                     "b_surface", "fat_proximal", "fat_distal", "fat_skin", "fat_cavity_a", "fat_cavity_b",
                     "fat_surface")


def _triangle_keys(triangles: np.ndarray) -> np.ndarray:
    """Sorted vertex triples, one row per triangle (to compare triangles regardless of orientation)."""
    return np.sort(np.asarray(triangles, dtype=np.int64), axis=1)


def _member(triangles: np.ndarray, of: np.ndarray) -> np.ndarray:
    """Mask of the rows of ``triangles`` that are (as vertex sets) rows of ``of``."""
    if len(triangles) == 0 or len(of) == 0:
        return np.zeros(len(triangles), dtype=bool)
    both = np.vstack([_triangle_keys(of), _triangle_keys(triangles)])
    _, inverse = np.unique(both, axis=0, return_inverse=True)
    inverse = np.asarray(inverse).reshape(-1)
    return np.isin(inverse[len(of):], inverse[: len(of)])


def split_bodies(data: MeshData) -> dict[str, MeshData]:
    """Cut the conforming arm-segment mesh (:func:`meshes.arm_segment.arm_segment`) into its three bodies.

    Each body keeps its cells and a copy of their nodes (renumbered); muscle ``m`` gets the regions ``belly`` and
    ``tendon`` and the boundaries ``origin``, ``insertion`` and ``lateral`` (its other boundary triangles); the fat
    gets ``proximal``, ``distal``, ``skin`` and ``cavity_a`` / ``cavity_b`` (its boundary triangles that are also
    muscle a's / b's). Muscles that share a face (touching) also get ``flat`` (that face) and ``round`` (the rest of
    ``lateral``: the fat's cavity); muscles apart across a void (the physical surfaces ``a_flat``, ``b_flat`` and
    ``void`` of build_arm_segment_model's ``gap``) get ``flat`` (their named face) and ``round``, the fat ``void``.
    """
    tags = {name: data.region_names[name] for names in LAYERED_ARM_BODIES.values() for name in names}
    body_cells = {body: np.isin(data.cell_tags, [tags[r] for r in regions])
                  for body, regions in LAYERED_ARM_BODIES.items()}
    boundary = {body: boundary_facets(data.cells[mask]) for body, mask in body_cells.items()}

    def named(name: str) -> np.ndarray:
        return data.facets[data.facet_tags == data.boundary_names[name]]

    out: dict[str, MeshData] = {}
    for body, regions in LAYERED_ARM_BODIES.items():
        cells = data.cells[body_cells[body]]
        used, local = np.unique(cells, return_inverse=True)
        renumber = np.full(len(data.points), -1, dtype=np.int64)
        renumber[used] = np.arange(len(used))
        faces: dict[str, np.ndarray] = {}
        if body == "fat":
            faces = {"proximal": named("proximal"), "distal": named("distal"), "skin": named("skin"),
                     "cavity_a": boundary["fat"][_member(boundary["fat"], boundary["a"])],
                     "cavity_b": boundary["fat"][_member(boundary["fat"], boundary["b"])]}
            if "void" in data.boundary_names:  # muscles apart with a void between them (gap > 0)
                faces["void"] = named("void")
            region_names = {"fat": 1}
            cell_tags = np.ones(len(cells), dtype=np.int32)
        else:
            ends = np.vstack([named(f"{body}_origin"), named(f"{body}_insertion")])
            faces = {"origin": named(f"{body}_origin"), "insertion": named(f"{body}_insertion"),
                     "lateral": boundary[body][~_member(boundary[body], ends)]}
            if f"{body}_flat" in data.boundary_names:  # muscles apart across a void (gap > 0): the named face
                flat = _member(faces["lateral"], named(f"{body}_flat"))
            else:  # touching muscles (gap 0): the face they share, if any
                flat = _member(faces["lateral"], boundary["b" if body == "a" else "a"])
            if flat.any():  # touching muscles (layered_arm's touching = true): their flat face, and the rest
                faces["flat"] = faces["lateral"][flat]
                faces["round"] = faces["lateral"][~flat]
            region_names = {"belly": 1, "tendon": 2}
            source = data.cell_tags[body_cells[body]]
            cell_tags = np.where(source == tags[regions[0]], 1, 2).astype(np.int32)
        for name, triangles in faces.items():
            if len(triangles) == 0:
                raise RuntimeError(f"{_GENERATOR}: body {body} has no {name} triangle")
        facets = np.vstack([renumber[t] for t in faces.values()])
        facet_tags = np.concatenate([np.full(len(t), i, dtype=np.int32) for i, t in enumerate(faces.values(), 1)])
        out[body] = MeshData(data.points[used], np.asarray(local).reshape(cells.shape), cell_tags, facets,
                             facet_tags, region_names, {name: i for i, name in enumerate(faces, 1)})
    return out


def _check_gap(gap: object, touching: bool, spacing: float, tendon_radius: float) -> float:
    """``gap`` as a float, else :class:`ParameterError`: a finite number >= 0, > 0 only with ``touching`` and below
    ``spacing - 2 tendon_radius`` (the planes x = -+gap / 2 cut the bellies, not the tendons)."""
    if isinstance(gap, bool) or not isinstance(gap, (int, float)) or not 0.0 <= gap < float("inf"):
        raise ParameterError(f"{_GENERATOR}: gap must be a finite number >= 0, got {gap!r}")
    if gap > 0.0 and not touching:
        raise ParameterError(f"{_GENERATOR}: gap (the void between the flat faces) needs touching = true, got {gap!r}")
    if gap >= spacing - 2.0 * tendon_radius:
        raise ParameterError(f"{_GENERATOR}: gap must be < spacing - 2 * tendon_radius "
                             f"({spacing - 2.0 * tendon_radius!r}) so that the tendons are not cut, got {gap!r}")
    return float(gap)


def layered_arm(
    length: float = 0.12,
    radius: float = 0.03,
    muscle_radius: float = 0.011,
    tendon_radius: float = 0.004,
    tendon_length: float = 0.02,
    spacing: float = 0.024,
    size: float = 0.005,
    turn_elements: int = CURVATURE_ELEMENTS,
    touching: bool = False,
    gap: float = 0.0,
) -> MeshData:
    """The arm segment's geometry as three separate bodies, muscle a, muscle b and the fat (module docstring).

    Parameters are :func:`meshes.arm_segment.arm_segment`'s, with the same defaults and checks (``turn_elements``:
    elements per 2 pi radians on curved surfaces; fewer than the default for a coarse, fast mesh).
    ``touching`` (default False): no fat between the muscles; the bellies overlap (``2 tendon_radius < spacing <
    2 muscle_radius``) and are cut at the plane x = 0 into two bellies that share a flat, lens-shaped face there,
    cut open like the muscle-fat interfaces (every node of it has a twin in the other muscle: gap 0 at rest); it is
    part of ``a_lateral`` and ``b_lateral``, and named ``a_flat`` and ``b_flat``; ``a_round`` and ``b_round`` are
    the rest of ``a_lateral`` and ``b_lateral`` (the fat's cavity: :data:`TOUCHING_FACES`).
    ``gap`` (m, default 0; only with ``touching``, ``0 <= gap < spacing - 2 tendon_radius`` so that the tendons
    are not cut): the bellies are cut at x = -gap / 2 (a) and x = +gap / 2 (b) instead, and the slab between them
    (the part of the two bellies with |x| < gap / 2) is empty: ``a_flat`` and ``b_flat`` face each other ``gap``
    apart across a void (no fat there), and the fat's surface facing the void is ``fat_void`` (a free surface:
    :data:`GAP_BOUNDARY`). The fat's band on the void's rim is ``gap / 2`` wide: the mesh is refined to 10 gaps
    there (meshes.arm_segment.VOID_SIZE), else its tetrahedra would be slivers.

    Returns
    -------
    MeshData
        Regions ``a_belly``, ``a_tendon``, ``b_belly``, ``b_tendon``, ``fat``; boundaries
        :data:`LAYERED_ARM_FACES`. The bodies share no node; a node of a muscle-fat interface appears once in
        each of the two bodies, at the same coordinates.

    Raises
    ------
    ParameterError
        As :func:`meshes.arm_segment.arm_segment`.
    """
    return layered_arm_meshes(length, radius, muscle_radius, tendon_radius, tendon_length, spacing, size,
                              turn_elements, touching, gap)[1]


def layered_arm_meshes(
    length: float = 0.12,
    radius: float = 0.03,
    muscle_radius: float = 0.011,
    tendon_radius: float = 0.004,
    tendon_length: float = 0.02,
    spacing: float = 0.024,
    size: float = 0.005,
    turn_elements: int = CURVATURE_ELEMENTS,
    touching: bool = False,
    gap: float = 0.0,
) -> tuple[MeshData, MeshData]:
    """The conforming arm segment (:func:`meshes.arm_segment.arm_segment` with the same parameters: its very mesh)
    and the layered arm cut open from it (:func:`layered_arm`): the same nodes."""
    total = positive_float(_GENERATOR, "length", length)
    r = positive_float(_GENERATOR, "radius", radius)
    rm = positive_float(_GENERATOR, "muscle_radius", muscle_radius)
    rt = positive_float(_GENERATOR, "tendon_radius", tendon_radius)
    lt = positive_float(_GENERATOR, "tendon_length", tendon_length)
    spacing_ = positive_float(_GENERATOR, "spacing", spacing)
    lc = positive_float(_GENERATOR, "size", size)
    turns = check_turn_elements(_GENERATOR, turn_elements)
    if not isinstance(touching, bool):
        raise ParameterError(f"{_GENERATOR}: touching must be true or false, got {touching!r}")
    if touching:
        _check(total, r, rm, rt, lt, spacing_, touching=True, generator=_GENERATOR)
    else:
        _check(total, r, rm, rt, lt, spacing_)
    void = _check_gap(gap, touching, spacing_, rt)
    start = time.perf_counter()
    with gmsh_session(arm_segment_options(lc, rt, turns), name=_GENERATOR):
        build_arm_segment_model(total, r, rm, rt, lt, spacing_, touching, void)
        generate_tetrahedra("layered_arm")
        conforming = from_gmsh_model(gmsh.model)
    mesh = combine(split_bodies(conforming))
    logger.info("layered_arm(length=%g, radius=%g, muscle_radius=%g, tendon_radius=%g, tendon_length=%g, "
                "spacing=%g, size=%g, turn_elements=%d, touching=%s, gap=%g): %d tets, %d points (%d conforming) in "
                "%.2f s", total, r, rm, rt, lt, spacing_, lc, turn_elements, touching, void, mesh.num_cells,
                mesh.num_points,
                conforming.num_points, time.perf_counter() - start)
    return conforming, mesh
