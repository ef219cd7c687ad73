"""Unstructured tetrahedral mesh of an arm segment: two fusiform muscles side by side in a cylinder of fat (gmsh OCC).

Geometry (SI units, axis along z, ``L = length``, ``Lt = tendon_length``)::

    fat        x^2 + y^2 <= R^2, z in [0, L], minus the two muscles
    muscle a   on the axis x = -spacing / 2, y = 0
    muscle b   on the axis x = +spacing / 2, y = 0

Each muscle is built by :func:`meshes.fusiform.add_muscle`, exactly like :func:`meshes.fusiform.fusiform`
with a belly of length ``L - 2 Lt``: cylindrical tendons of radius ``rt`` over ``z in [0, Lt]`` and
``[L - Lt, L]``, and a lofted belly ``r(z) = rt + (rm - rt) sin(pi s)^2``, ``s = (z - Lt) / (L - 2 Lt)``
in between (:func:`meshes.fusiform.belly_radius_at`).  The tendons' end disks lie on the fat's end
faces.  All solids are fragmented together, so the interfaces are shared and the mesh is conforming.
"""

from __future__ import annotations

import logging
import math
import time

import gmsh

from meshes._gmsh import CURVATURE_ELEMENTS, curved_size_options, generate_tetrahedra, gmsh_session
from meshes._validate import MAX_COUNT, ParameterError, positive_float
from meshes.data import MeshData, from_gmsh_model
from meshes.fusiform import add_muscle

__all__ = [
    "ARM_SEGMENT_FACES",
    "ARM_SEGMENT_REGIONS",
    "GAP_FACES",
    "CURVATURE_ELEMENTS",
    "arm_segment",
    "arm_segment_options",
    "belly_volume",
    "build_arm_segment_model",
    "check_turn_elements",
]

logger = logging.getLogger(__name__)

#: Physical volume names (tags 1..5) of :func:`arm_segment`.
ARM_SEGMENT_REGIONS = ("fat", "belly_a", "tendon_a", "belly_b", "tendon_b")
#: Physical surface names (tags 1..7) of :func:`arm_segment`.
ARM_SEGMENT_FACES = ("a_origin", "a_insertion", "b_origin", "b_insertion", "proximal", "distal", "skin")
#: The extra physical surfaces (tags 8..10) of a touching arm with a gap (build_arm_segment_model's ``gap`` > 0):
#: the muscles' flat faces and the fat's surface facing the void between them.
GAP_FACES = ("a_flat", "b_flat", "void")

_GENERATOR = "arm_segment"


def _end(z_center: float, length: float) -> str | None:
    """``"origin"`` (z = 0), ``"insertion"`` (z = length) or None (lateral) from a face's centre of mass."""
    tol = 1e-6 * length
    if abs(z_center) < tol:
        return "origin"
    if abs(z_center - length) < tol:
        return "insertion"
    return None


def _face_name(region: str, end: str | None) -> str:
    """Name of an exterior face from the region that owns it and the end it lies on."""
    if region == "fat":
        return {"origin": "proximal", "insertion": "distal", None: "skin"}[end]
    if region.startswith("tendon_") and end is not None:
        return f"{region[-1]}_{end}"
    raise RuntimeError(f"{_GENERATOR}: unexpected exterior face of {region} (end {end}): a muscle reaches the skin")


def build_arm_segment_model(
    length: float,
    radius: float,
    muscle_radius: float,
    tendon_radius: float,
    tendon_length: float,
    spacing: float,
    touching: bool = False,
    gap: float = 0.0,
) -> None:
    """Create the fragmented arm-segment geometry and its physical groups in the current gmsh model.

    ``touching``: the bellies overlap (``spacing < 2 muscle_radius``) and each is cut by the plane x = 0, so that
    they share a flat face there (muscle a keeps x <= 0, muscle b x >= 0) and no fat lies between them.
    ``gap`` > 0 (with ``touching``): muscle a keeps x <= -gap / 2 and b x >= gap / 2, and the slab of the two
    bellies between those planes, (belly a | belly b) & |x| < gap / 2, is left empty (a void, taken out of the fat
    too): the flat faces are then single-sided, named ``a_flat`` and ``b_flat`` (tags 8, 9), and the fat's
    surface facing the void ``void`` (tag 10); the mesh is refined near the void (:data:`VOID_SIZE`)."""
    occ = gmsh.model.occ
    fat = occ.addCylinder(0.0, 0.0, 0.0, 0.0, 0.0, length, radius)
    solids: dict[str, list[int]] = {}
    half_gap = 0.5 * gap if touching else 0.0
    copies: list[tuple[int, int]] = []  # the whole bellies (gap > 0), for the void
    for label, x0 in (("a", -0.5 * spacing), ("b", 0.5 * spacing)):
        belly, origin, insertion = add_muscle(length - 2.0 * tendon_length, muscle_radius, tendon_radius,
                                              tendon_length, x0)
        if touching and gap > 0.0:
            copies += occ.copy([(3, belly)])
        if touching:  # keep the belly's half space x <= -gap / 2 (a) or x >= gap / 2 (b)
            x_min = -radius if label == "a" else half_gap
            half = occ.addBox(x_min, -radius, 0.0, radius - half_gap, 2.0 * radius, length)
            cut, _ = occ.intersect([(3, belly)], [(3, half)])
            if len(cut) != 1:
                plane = -half_gap if label == "a" else half_gap
                raise RuntimeError(f"{_GENERATOR}: cutting belly {label} at x = {plane:g} gave {len(cut)} volumes, "
                                   "not 1")
            belly = cut[0][1]
        solids[f"belly_{label}"] = [belly]
        solids[f"tendon_{label}"] = [origin, insertion]
    if copies:  # the void: the bellies' slab |x| < gap / 2, taken out of the fat
        slab = occ.addBox(-half_gap, -radius, 0.0, gap, 2.0 * radius, length)
        void, _ = occ.intersect(copies, [(3, slab)])
        if len(void) > 1:  # the two bellies' parts of the slab overlap: one solid
            void, _ = occ.fuse(void[:1], void[1:])
        cut, _ = occ.cut([(3, fat)], void)
        if len(cut) != 1:
            raise RuntimeError(f"{_GENERATOR}: taking the void out of the fat gave {len(cut)} volumes, not 1")
        fat = cut[0][1]
    tools = [(3, tag) for name in ARM_SEGMENT_REGIONS[1:] for tag in solids[name]]
    _, mapping = occ.fragment([(3, fat)], tools)
    occ.synchronize()

    # the fat's pieces include the muscles it overlaps: keep those that belong to no muscle solid
    pieces = iter(mapping[1:])
    volumes: dict[str, list[int]] = {}
    for name in ARM_SEGMENT_REGIONS[1:]:
        volumes[name] = sorted(tag for _ in solids[name] for dim, tag in next(pieces) if dim == 3)
    in_muscles = {tag for name in ARM_SEGMENT_REGIONS[1:] for tag in volumes[name]}
    volumes["fat"] = sorted(tag for dim, tag in mapping[0] if dim == 3 and tag not in in_muscles)
    expected = {"fat": 1, "belly_a": 1, "tendon_a": 2, "belly_b": 1, "tendon_b": 2}
    for name, count in expected.items():
        if len(volumes[name]) != count:
            raise RuntimeError(f"{_GENERATOR}: fragment gave {len(volumes[name])} volumes for {name}, not {count}")

    owners: dict[int, list[str]] = {}
    for name, tags in volumes.items():
        for _, surface in gmsh.model.getBoundary([(3, t) for t in tags], combined=False, oriented=False):
            owners.setdefault(surface, []).append(name)
    names = ARM_SEGMENT_FACES + (GAP_FACES if touching and gap > 0.0 else ())
    faces: dict[str, list[int]] = {name: [] for name in names}
    for surface in sorted(s for s, names in owners.items() if len(names) == 1):
        owner = owners[surface][0]
        if touching and gap > 0.0 and owner.startswith("belly_"):  # its flat face, on the void
            faces[f"{owner[-1]}_flat"].append(surface)
            continue
        end = _end(occ.getCenterOfMass(2, surface)[2], length)
        if touching and gap > 0.0 and owner == "fat" and end is None:
            # the skin's points lie on r = radius, the void's on a belly's surface (r <= spacing / 2 + muscle_radius
            # < radius): a point of the surface at its parameters' mid-range tells them apart
            bounds = gmsh.model.getParametrizationBounds(2, surface)
            x, y, _ = gmsh.model.getValue(2, surface, [0.5 * (lo + hi) for lo, hi in zip(*bounds, strict=True)])
            if math.hypot(x, y) < (1.0 - 1e-6) * radius:
                faces["void"].append(surface)
                continue
        faces[_face_name(owner, end)].append(surface)

    for tag, name in enumerate(ARM_SEGMENT_REGIONS, start=1):
        gmsh.model.addPhysicalGroup(3, volumes[name], tag)
        gmsh.model.setPhysicalName(3, tag, name)
    for tag, name in enumerate(names, start=1):
        if not faces[name]:
            raise RuntimeError(f"{_GENERATOR}: no exterior surface classified as {name!r}")
        gmsh.model.addPhysicalGroup(2, faces[name], tag)
        gmsh.model.setPhysicalName(2, tag, name)
    if touching and gap > 0.0:
        _refine_near(faces["void"], VOID_SIZE * gap, VOID_REACH * gap)


#: Element size on the void's surfaces (layered_arm's ``gap``), in gaps: the fat's band there is gap / 2 wide, and
#: the tetrahedra on it are slivers unless their edges along it are short: 10 gaps keep the radius ratio above
#: 0.03 (0.0017 with the coarse mesh's 8 mm edges there); the size grows back to the mesh's within VOID_REACH gaps.
VOID_SIZE = 10.0
VOID_REACH = 30.0


def _refine_near(surfaces: list[int], size: float, reach: float) -> None:
    """Element size ``size`` on ``surfaces``, growing linearly to the mesh's maximum at distance ``reach``
    (gmsh Distance and Threshold fields, the background mesh; the curvature rule still applies elsewhere)."""
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "SurfacesList", surfaces)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", min(size, gmsh.option.getNumber("Mesh.MeshSizeMax")))
    field.setNumber(threshold, "SizeMax", gmsh.option.getNumber("Mesh.MeshSizeMax"))
    field.setNumber(threshold, "DistMin", 0.0)
    field.setNumber(threshold, "DistMax", reach)
    field.setAsBackgroundMesh(threshold)


def arm_segment_options(size: float, tendon_radius: float | None = None,
                        turn_elements: int = CURVATURE_ELEMENTS) -> dict[str, float]:
    """gmsh options used for maximum element size ``size`` (refined on curved surfaces; below
    ``size = tendon_radius`` the tendons' elements shrink with ``size``: meshes._gmsh.curvature_elements);
    ``turn_elements`` other than :data:`CURVATURE_ELEMENTS` sets the elements per 2 pi radians itself."""
    options = curved_size_options(size, tendon_radius)
    if turn_elements != CURVATURE_ELEMENTS:
        options["Mesh.MeshSizeFromCurvature"] = turn_elements
    return options


def check_turn_elements(generator: str, turn_elements: object) -> int:
    """``turn_elements`` as an int in [6, MAX_COUNT], else :class:`ParameterError` naming the generator."""
    if isinstance(turn_elements, bool) or not isinstance(turn_elements, int) or not 6 <= turn_elements <= MAX_COUNT:
        raise ParameterError(f"{generator}: turn_elements must be an integer in [6, {MAX_COUNT}], "
                             f"got {turn_elements!r}")
    return turn_elements


def _check(length: float, radius: float, rm: float, rt: float, lt: float, spacing: float,
           touching: bool = False, generator: str = _GENERATOR) -> None:
    """Raise :class:`ParameterError` unless the muscles fit, apart (``touching``: overlapping bellies, tendons
    apart), inside the fat and the tendons are shorter."""
    if rt >= rm:
        raise ParameterError(f"{generator}: tendon_radius must be < muscle_radius ({rm!r}), got {rt!r}")
    if 2.0 * lt >= length:
        raise ParameterError(f"{generator}: tendon_length must be < length / 2 ({0.5 * length!r}), got {lt!r}")
    if touching:
        if not 2.0 * rt < spacing < 2.0 * rm:
            raise ParameterError(
                f"{generator}: with touching = true spacing must be between 2 * tendon_radius ({2.0 * rt!r}) and "
                f"2 * muscle_radius ({2.0 * rm!r}) so that the bellies overlap and the tendons do not, got {spacing!r}"
            )
    elif spacing <= 2.0 * rm:
        raise ParameterError(
            f"{generator}: spacing must be > 2 * muscle_radius ({2.0 * rm!r}) so that the muscles do not "
            f"overlap, got {spacing!r}"
        )
    if 0.5 * spacing + rm >= radius:
        raise ParameterError(
            f"{generator}: radius must be > spacing / 2 + muscle_radius ({0.5 * spacing + rm!r}) so that the "
            f"muscles lie inside the fat, got {radius!r}"
        )


def arm_segment(
    length: float = 0.12,
    radius: float = 0.03,
    muscle_radius: float = 0.011,
    tendon_radius: float = 0.004,
    tendon_length: float = 0.02,
    spacing: float = 0.024,
    size: float = 0.005,
    turn_elements: int = CURVATURE_ELEMENTS,
) -> MeshData:
    """Mesh two fusiform muscles side by side inside a cylinder of fat (SI metres).

    Parameters
    ----------
    length:
        Length of the segment along z (the fat and each muscle span ``z in [0, length]``), > 0.
    radius:
        Radius of the fat cylinder, > 0 and > ``spacing / 2 + muscle_radius``.
    muscle_radius:
        Radius of each belly at its middle, > 0 and > ``tendon_radius``.
    tendon_radius:
        Radius of the tendons and of the bellies' ends, > 0.
    tendon_length:
        Length of each tendon, > 0 and < ``length / 2``.
    spacing:
        Distance between the muscles' axes ``x = -spacing / 2`` (muscle a) and
        ``x = +spacing / 2`` (muscle b), > ``2 * muscle_radius``.
    size:
        Maximum element size, > 0; curved surfaces are refined to
        :data:`CURVATURE_ELEMENTS` elements per 2 pi radians (more below ``size = tendon_radius``).
    turn_elements:
        Elements per 2 pi radians on curved surfaces, an integer >= 6: the default keeps the rule above, fewer
        give a coarse, fast mesh (the tendons' 1.6 mm elements dominate the default mesh).

    Returns
    -------
    MeshData
        Volumes ``fat`` (1), ``belly_a`` (2), ``tendon_a`` (3, both tendons of muscle a),
        ``belly_b`` (4) and ``tendon_b`` (5); faces ``a_origin`` (1, muscle a's tendon
        disk at z=0), ``a_insertion`` (2, its disk at z=length), ``b_origin`` (3),
        ``b_insertion`` (4), ``proximal`` (5, the rest of the face z=0: fat only),
        ``distal`` (6, the rest of the face z=length) and ``skin`` (7, the lateral
        surface of the fat).  The interfaces between volumes are shared but not named.

    Raises
    ------
    ParameterError
        If a parameter is not a positive number, or the muscles overlap, leave the
        fat, or their tendons are not shorter than half the segment.
    """
    total = positive_float(_GENERATOR, "length", length)
    r = positive_float(_GENERATOR, "radius", radius)
    rm = positive_float(_GENERATOR, "muscle_radius", muscle_radius)
    rt = positive_float(_GENERATOR, "tendon_radius", tendon_radius)
    lt = positive_float(_GENERATOR, "tendon_length", tendon_length)
    gap = positive_float(_GENERATOR, "spacing", spacing)
    lc = positive_float(_GENERATOR, "size", size)
    turns = check_turn_elements(_GENERATOR, turn_elements)
    _check(total, r, rm, rt, lt, gap)
    start = time.perf_counter()
    with gmsh_session(arm_segment_options(lc, rt, turns), name=_GENERATOR):
        build_arm_segment_model(total, r, rm, rt, lt, gap)
        generate_tetrahedra("arm_segment")
        mesh = from_gmsh_model(gmsh.model)
    logger.info(
        "arm_segment(length=%g, radius=%g, muscle_radius=%g, tendon_radius=%g, tendon_length=%g, spacing=%g, "
        "size=%g): %d tets, %d points in %.2f s",
        total,
        r,
        rm,
        rt,
        lt,
        gap,
        lc,
        mesh.num_cells,
        mesh.num_points,
        time.perf_counter() - start,
    )
    return mesh


def belly_volume(length: float, muscle_radius: float, tendon_radius: float, tendon_length: float) -> float:
    """Exact volume of one belly: ``pi int r(z)^2 dz = pi Lb (rt^2 + rt d + 3 d^2 / 8)``, ``d = rm - rt``."""
    d = muscle_radius - tendon_radius
    return math.pi * (length - 2.0 * tendon_length) * (tendon_radius**2 + tendon_radius * d + 0.375 * d**2)
