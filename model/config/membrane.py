"""A membrane run's configuration: a TOML file with a [membrane] table (docs/membranes.md, "Running from a config").

    python -m model run examples/membrane_balloon.toml --out results/balloon

A document with a top-level [membrane] table is a membrane run (a triangle surface in 3D under a follower
pressure, model.experiments.membrane.run_membrane), not a solid run (RunConfig): its sections are

    [membrane]     the surface (a generator of meshes.membrane with radius and size, or a user's triangle
                   surface file read by meshes.surface_file: surface = "file", file, orientation), the law and its
                   parameters (plane-stress StVK: young, nu; incompressible neo-Hookean: mu; both: thickness),
                   the Dirichlet border (``fixed``: boundary name -> displacement components held at 0)
    [inflation]    the pressure: a ramp (``pressure`` in ``steps`` equal increments), a list (``pressures``),
                   or growth by ``dp`` until ``target_volume`` or until ``contact_fraction`` of the area
                   touches the obstacles (model.solvers.membrane.inflate / inflate_to_volume)
    [[obstacle]]   rigid obstacles (plane, sphere, capsule: the keys of [[bone]] shapes) with a penalty
                   (model.problem.membrane_contact.ObstacleContact)
    [[contact]]    membrane-membrane contact between two regions of the surface (facing_discs: lower, upper; a
                   .msh file: its named physical surfaces),
                   penalty or augmented Lagrangian (model.problem.membrane_contact.MembranePairContact), or
                   ``self_contact = true``: one region (default the whole membrane) against itself
                   (model.problem.membrane_contact.MembraneSelfContact, penalty)
    [extrusion]    before [inflation] (surface = "disc" or a "file" patch, rim clamped): the patch extruded,
                   inflated without contact to a first volume and smoothed into a new rest shape (the thesis' two
                   phases)
    [muscle]       after the inflation (surface = "disc" or a "file" patch, rim clamped): the patch closed with
                   its rest shape as the base, filled with tetrahedra, given Laplace fibres and written as
                   muscle.msh, fibres.npy, muscle.vtu and a solid run's configuration muscle.toml (the thesis' ch.
                   3.3.3; model.experiments.membrane)
    [output]       folder, XDMF and VTU of the deformed surface
    [units]        labels only

Every error is a ConfigError whose one-line message starts with the dotted key, before any mesh is made.
No dolfinx here.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from model.config.base import (
    ExistingFile,
    Flag,
    Integer,
    Name,
    NonNegative,
    Number,
    Point,
    Positive,
    Section,
    count,
    fail,
    interval,
    key,
    validate,
)
from model.config.bone import ObstacleField, shape_keys_schema
from model.config.expressions import compile_expression, uses_load_factor
from model.config.units import UnitsConfig
from model.errors import ConfigError

#: the surface generators (meshes.membrane), their boundaries and the default Dirichlet border
SURFACES: dict[str, dict[str, Any]] = {
    "sphere_octant": {"boundaries": ("x0", "y0", "z0"), "fixed": {"x0": [0], "y0": [1], "z0": [2]}},
    "disc": {"boundaries": ("rim",), "fixed": {"rim": [0, 1, 2]}},
    "facing_discs": {"boundaries": ("lower_rim", "upper_rim"), "regions": ("lower", "upper"),
                     "fixed": {"lower_rim": [0, 1, 2], "upper_rim": [0, 1, 2]}},
    "closed_can": {"boundaries": ("lower_rim", "upper_rim", "wall"), "regions": ("lower", "upper", "wall"),
                   "fixed": {"wall": [0, 1, 2]}},
    # a user's file (meshes.surface_file): "boundary" the open edges, plus a .msh file's named physical lines; its
    # regions (a .msh file's named physical surfaces, "<region>_boundary" their open edges) checked when read
    "file": {"boundaries": None, "regions": None, "fixed": {"boundary": [0, 1, 2]}},
}
#: the surfaces' own keys (others refuse them)
SURFACE_KEYS = {"bump": ("disc", "facing_discs", "closed_can", "file"), "gap": ("facing_discs", "closed_can"),
                "upper_size": ("facing_discs",), "size": ("sphere_octant", "disc", "facing_discs", "closed_can"),
                "file": ("file",), "orientation": ("file",),
                "centre": ("file",)}
#: each law's parameters besides thickness
LAW_PARAMETERS = {"stvk": ("young", "nu"), "neo_hookean": ("mu",)}

Component = Annotated[Integer, Field(ge=0, le=2)]


class MembraneSection(Section):
    """[membrane]: the surface, its law and its Dirichlet border."""

    surface: Literal["sphere_octant", "disc", "facing_discs", "closed_can", "file"] = key(
        "the surface generator (meshes.membrane): \"sphere_octant\" (x, y, z >= 0 of the sphere |x| = radius, "
        "boundaries x0, y0, z0 on the symmetry planes: the closed balloon by symmetry), \"disc\" (x^2 + y^2 <= "
        "radius^2 in z = 0, boundary rim) or \"facing_discs\" (two membranes of one mesh, meshes.membrane."
        "facing_discs: region lower, the disc in z = 0 with normal +z, and region upper, the disc in z = gap with "
        "normal -z; boundaries lower_rim, upper_rim; inflated towards each other, for [[contact]]), \"closed_can\" "
        "(one closed membrane, meshes.membrane.closed_can: facing_discs' mirror-image discs, regions lower and "
        "upper, joined by the cylinder wall of height gap, region wall, normals inward; boundaries lower_rim, "
        "upper_rim, wall (every wall edge, held by default); for [[contact]] self_contact) or \"file\" (the "
        "user's triangle surface of ``file``, meshes.surface_file: boundary \"boundary\" its open edges, and a gmsh "
        ".msh file's named physical lines)")
    file: ExistingFile | None = key(
        "surface = \"file\": the triangle surface, any format meshio reads (.obj, .stl, .ply, .vtu, gmsh .msh ...), "
        "relative to the configuration file's folder; its coordinates in the length unit; triangles only, every "
        "edge in at most two of them, one fan of triangles around each point (no bow-tie), none degenerate",
        default=None)
    orientation: Literal["file", "outward"] | Point | None = key(
        "surface = \"file\": the side the pressure pushes to (the rest normals N): \"file\" the triangles' "
        "right-handed vertex order (default; must be consistent), \"outward\" away from the middle of the "
        "points' bounding box, or a direction [x, y, z] (N . direction > 0); the result must be consistent",
        "dimensionless", default=None)
    centre: Point | None = key(
        "surface = \"file\": the centre c of the starting bump u = bump R max(0, 1 - |X - c|^2 / R^2) N_vertex "
        "(default: the middle of the bounding box of the fixed nodes, or of all nodes without any)", "m (length)",
        default=None)
    radius: Positive = key("radius of the sphere or the disc(s); surface = \"file\": the starting bump's R and "
                           "the length of the default [inflation] dp (default: the largest distance of a fixed node, "
                           "or of any node without any, from centre)", "m (length)", default=1.0)
    size: Positive = key("largest triangle edge of the surface mesh (facing_discs: of the lower disc)",
                         "m (length)", default=0.2)
    gap: Positive | None = key("surface = \"facing_discs\", \"closed_can\": the distance H between the two "
                               "discs' planes",
                               "m (length)", default=None)
    upper_size: Positive | None = key("surface = \"facing_discs\": largest triangle edge of the upper disc "
                                      "(default: size; another size gives non-matching meshes)", "m (length)",
                                      default=None)
    law: Literal["stvk", "neo_hookean"] = key(
        "\"stvk\" (plane-stress St Venant-Kirchhoff: young, nu, thickness) or \"neo_hookean\" (incompressible "
        "neo-Hookean membrane: mu, thickness)")
    young: Positive | None = key("law = \"stvk\": Young's modulus", "Pa (stress)", default=None)
    nu: Annotated[Number, *interval(-1.0, 0.5, "()")] | None = key("law = \"stvk\": Poisson's ratio",
                                                                   "dimensionless", default=None)
    mu: Positive | None = key("law = \"neo_hookean\": shear modulus", "Pa (stress)", default=None)
    thickness: Positive = key("the membrane's thickness h (the energy per area is h w)", "m (length)")
    fixed: dict[Name, Annotated[tuple[Component, ...], Field(min_length=1)]] | None = key(
        "the Dirichlet border: boundary name -> displacement components held at 0 (default: sphere_octant "
        "{x0 = [0], y0 = [1], z0 = [2]} (symmetry), disc {rim = [0, 1, 2]} (clamped), file {boundary = [0, 1, 2]} "
        "(the open edges clamped); a file's names are checked when it is read, before any solve)", default=None)
    bump: NonNegative = key("disc, facing_discs, closed_can: Newton starts from the paraboloid u_z = bump radius "
                            "(1 - r^2/radius^2) (facing_discs, closed_can: each disc towards the other; a flat "
                            "membrane has no transverse stiffness); file: from u = bump R max(0, 1 - |X - c|^2/R^2) "
                            "N_vertex (see centre, radius; N_vertex the nodes' oriented normals); the equilibria do "
                            "not depend on it",
                            "dimensionless", default=0.05)
    quadrature_degree: Annotated[Integer, Field(ge=1, le=12)] = key("quadrature degree of the membrane energy",
                                                              default=2)

    @model_validator(mode="after")
    def _law_and_border(self) -> MembraneSection:
        for name, keys in LAW_PARAMETERS.items():
            for k in keys:
                if name != self.law and getattr(self, k) is not None:
                    fail(f"only applies to law = {name!r}, not {self.law!r}", k)
        for k in LAW_PARAMETERS[self.law]:
            if getattr(self, k) is None:
                fail(f"missing (law = {self.law!r} needs {', '.join(LAW_PARAMETERS[self.law])}, thickness)", k)
        if self.surface == "file" and self.file is None:
            fail("missing (surface = 'file' needs the surface's file)", "file")
        known = SURFACES[self.surface]["boundaries"]
        for name in (self.fixed or {}) if known is not None else ():  # a file's: checked when it is read
            if name not in known:
                fail(f"{self.surface} has no boundary {name!r} (boundaries: {', '.join(known)})", "fixed", name)
        for k, surfaces in SURFACE_KEYS.items():
            if k in self.model_fields_set and self.surface not in surfaces:
                fail(f"only applies to surface = {' or '.join(map(repr, surfaces))}, not {self.surface!r}", k)
        if self.surface in ("facing_discs", "closed_can") and self.gap is None:
            fail(f"missing (surface = {self.surface!r} needs the distance between the discs)", "gap")
        return self

    @property
    def regions(self) -> tuple[str, ...] | None:
        """The surface's named membranes (cell regions), for [[contact]]; None for a file (known when read)."""
        regions = SURFACES[self.surface].get("regions", ())
        return None if regions is None else tuple(regions)

    @property
    def border(self) -> dict[str, tuple[int, ...]]:
        """The Dirichlet border: ``fixed`` or the surface's default."""
        fixed = self.fixed if self.fixed is not None else SURFACES[self.surface]["fixed"]
        return {name: tuple(int(c) for c in components) for name, components in fixed.items()}

    @property
    def law_parameters(self) -> dict[str, float]:
        """The keyword arguments of forms.membrane.membrane_law."""
        return {**{k: float(getattr(self, k)) for k in LAW_PARAMETERS[self.law]}, "thickness": self.thickness}


class InflationSection(Section):
    """[inflation]: the pressure path. Exactly one of ``pressure`` (a ramp in ``steps`` increments),
    ``pressures`` (a list) or ``target_volume`` / ``contact_fraction`` (growth by ``dp`` to a stop)."""

    pressure: Positive | None = key("the last pressure of the ramp p_k = pressure k / steps", "Pa (stress)",
                                    default=None)
    steps: count(1) | None = key("pressure only: the ramp's equal increments (default 5)",
                                                        default=None)
    pressures: Annotated[tuple[Positive, ...], Field(min_length=1)] | None = key(
        "the pressures, increasing, one equilibrium each", "Pa (stress)", default=None)
    target_volume: Positive | None = key(
        "grow the pressure by dp until the enclosed volume reaches it (the last pressure by the secant method, to "
        "1e-6 of it)", "m^3 (volume)", default=None)
    contact_fraction: Annotated[Number, *interval(0.0, 1.0, "(]")] | None = key(
        "stop when this fraction of the membrane's area touches the obstacles (bisection on p to 1e-3 p); needs an "
        "[[obstacle]]", "dimensionless", default=None)
    dp: Positive | None = key("target_volume / contact_fraction: the pressure increment (default 0.05 w'(1.1) / "
                              "radius, w' the law's equibiaxial dw/dlambda)", "Pa (stress)", default=None)
    max_steps: count(1) = key("target_volume / contact_fraction: most increments of dp",
                                                     default=200)
    cutbacks: count(0, 50) = key("halvings of a pressure increment whose Newton fails",
                                                    default=4)
    freeze_on_contact: Flag = key(
        "the thesis' per-node pressure: a node that touches an [[obstacle]] or a [[contact]] keeps the pressure of "
        "the step it first touched at, the others follow the pressure (with target_volume / contact_fraction the "
        "secant and the bisection reach each trial pressure from the last equilibrium below it)", default=False)
    pressure_weight: str | None = key(
        "the thesis' painted pressure weight map: an expression of the rest position x[0], x[1], x[2] (m), e.g. "
        "\"1 + 2 * x[0]\"; every node's pressure is w(X) p (>= 0 at every node, checked on the mesh)",
        default=None)
    unit_area: Flag = key(
        "the thesis' unit-area nodal pressure force f_i = (p_i / 3) sum_j n_j over the node's triangles (A_j = 1): "
        "the pressure is then a force per triangle, and the load grows with the number of triangles (not "
        "consistent: no mesh convergence)", default=False)

    @model_validator(mode="after")
    def _weight_expression(self) -> InflationSection:
        if self.pressure_weight is not None:
            try:
                compile_expression(self.pressure_weight)
            except ValueError as err:
                fail(str(err), "pressure_weight")
            if uses_load_factor(self.pressure_weight):
                fail(f"must not mention t (a map of the rest position; the pressure path scales it), got "
                     f"{self.pressure_weight!r}", "pressure_weight")
        return self

    @model_validator(mode="after")
    def _one_path(self) -> InflationSection:
        given = [k for k in ("pressure", "pressures", "target_volume") if getattr(self, k) is not None]
        if self.contact_fraction is not None and "target_volume" not in given:
            given.append("contact_fraction")
        if not given:
            fail("missing (give pressure, pressures, target_volume or contact_fraction)", "pressure")
        if len(given) > 1:
            fail(f"not with {given[0]} (give one of pressure, pressures, target_volume / contact_fraction)",
                 given[1])
        if self.steps is not None and self.pressure is None:
            fail("only applies with pressure (a ramp)", "steps")
        if self.pressures is not None and any(b <= a for a, b in zip(self.pressures, self.pressures[1:])):
            fail("must increase", "pressures")
        if given[0] in ("pressure", "pressures"):
            for k in ("dp", "max_steps"):
                if k in self.model_fields_set:
                    fail("only applies with target_volume or contact_fraction", k)
        return self

    @property
    def ramp(self) -> list[float] | None:
        """The pressures of a ramp or list; None for a stop (target_volume / contact_fraction)."""
        if self.pressures is not None:
            return [float(p) for p in self.pressures]
        if self.pressure is not None:
            n = self.steps or 5
            return [self.pressure * (k + 1) / n for k in range(n)]
        return None

    @property
    def volume(self) -> float:
        """The target volume of a stop (inf when only the contact fraction stops it)."""
        return float(self.target_volume) if self.target_volume is not None else math.inf


def _obstacle_schema(schema: dict[str, Any]) -> None:
    shape_keys_schema(schema)


class ObstacleSection(Section):
    """[[obstacle]]: a rigid obstacle the whole membrane stays clear of (penalty on the nodes' gaps,
    model.problem.membrane_contact.ObstacleContact)."""

    model_config = {"json_schema_extra": _obstacle_schema}

    name: Name | None = key("a name for the summary (default: the shape's)", default=None)
    penalty: Positive = key("the penalty stiffness k, per unit reference area and unit penetration",
                            "Pa/m (stress per length)")
    inside: Flag = key("the membrane stays inside the obstacle (a cavity) instead of outside (a bone)",
                       default=False)
    augmented: Flag = key("augmented Lagrangian: Uzawa updates of the nodal contact pressure after each "
                          "equilibrium until max |min(g, lambda/k)| <= 1e-9", default=False)
    point: Point | None = key("obstacle = \"plane\": a point of the plane", "m (length)", default=None)
    normal: Point | None = key("obstacle = \"plane\": the plane's normal, pointing to the free side",
                               "dimensionless", default=None)
    centre: Point | None = key("obstacle = \"sphere\": the centre", "m (length)", default=None)
    radius: Positive | None = key("obstacle = \"sphere\" or \"capsule\": the radius", "m (length)", default=None)
    a: Point | None = key("obstacle = \"capsule\": one end of the segment", "m (length)", default=None)
    b: Point | None = key("obstacle = \"capsule\": the other end", "m (length)", default=None)
    obstacle: ObstacleField = key("the shape: \"plane\", \"sphere\" or \"capsule\" (with its keys above); after "
                                  "validation the obstacle itself")


class ContactSection(Section):
    """[[contact]]: penalty contact between two membranes of the surface (two regions, e.g. facing_discs' lower
    and upper, or two named physical surfaces of a .msh file, sharing no node): the ``surface`` region's nodes
    stay on the side of the ``master`` region its normal points to (model.problem.membrane_contact
    .MembranePairContact; one pass: pick the finer mesh as ``surface``; ``two_pass``: also the master's nodes
    against the surface's triangles, model.problem.membrane_contact.pair_contacts). ``self_contact``: the
    ``surface`` region (default: the whole membrane) against itself, no master (model.problem.membrane_contact
    .MembraneSelfContact; penalty only; ``rings`` and ``reach`` set which triangles a node may pair with)."""

    name: Name | None = key("a name for the summary (default: \"<surface>-<master>\", self-contact "
                            "\"<surface>-self\")", default=None)
    surface: Name | None = key("the slave region: its nodes are checked against the master's triangles "
                               "(facing_discs: lower or upper; surface = \"file\": a named physical surface of the "
                               ".msh file, checked when it is read); required unless self_contact (then default: "
                               "the whole membrane, \"all\")", default=None)
    master: Name | None = key("the master region: its deformed triangles are the contact surface; required unless "
                              "self_contact", default=None)
    self_contact: Flag = key("the surface region against itself (self-contact of one membrane: its nodes against its "
                             "own deformed triangles outside their neighbourhood, on the side each node lay at rest; "
                             "no master; penalty only; docs/membranes.md)", default=False)
    rings: count(1, 1000) | None = key(
        "self_contact only: a node never pairs with a triangle that has a vertex within rings - 1 edges of it "
        "(default 2)", default=None)
    reach: Positive | None = key("self_contact only: the farthest master point a node pairs with (default: the "
                                 "region's mean edge length at rest)", "m (length)", default=None)
    penalty: Positive = key("the penalty stiffness k, per unit reference area and unit penetration (g counts both "
                            "membranes' penetrations)", "Pa/m (stress per length)")
    augmented: Flag = key("augmented Lagrangian: Uzawa updates of the slave nodes' contact pressure after each "
                          "equilibrium until max |min(g, lambda/k)| <= tolerance", default=False)
    tolerance: Positive | None = key("augmented only: the Uzawa tolerance on max |min(g, lambda/k)| (default "
                                     "1e-9; with several contacts the smallest)", "m (length)", default=None)
    two_pass: Flag = key("two passes (FEBio's two_pass): each membrane slave and master in turn, the two "
                         "penalty energies (each with this penalty) summed, so that neither membrane's nodes enter "
                         "the other's triangles on non-matching meshes; penalty only", default=False)

    @model_validator(mode="after")
    def _pair(self) -> ContactSection:
        if self.self_contact:
            for k in ("master", "two_pass", "augmented", "tolerance"):
                if k in self.model_fields_set and getattr(self, k):
                    why = "the surface is its own master" if k == "master" else \
                        "self-contact already checks every node against the other side" if k == "two_pass" else \
                        "penalty only: both sides' nodes held exactly over-constrain, as with two_pass" \
                        if k == "augmented" else "penalty only: there is no Uzawa tolerance"
                    fail(f"not with self_contact = true ({why})", k)
            return self
        for k in ("rings", "reach"):
            if getattr(self, k) is not None:
                fail("only with self_contact = true", k)
        for k in ("surface", "master"):
            if getattr(self, k) is None:
                fail("missing (a contact pairs two regions; or self_contact = true)", k)
        if self.master == self.surface:
            fail(f"the same region as surface ({self.surface!r}): a contact pairs two membranes", "master")
        if self.tolerance is not None and not self.augmented:
            fail("only applies with augmented = true", "tolerance")
        if self.two_pass and self.augmented:
            fail("not with augmented = true (both membranes' nodes held exactly on the other's triangles "
                 "over-constrain non-matching meshes: Uzawa stalls)", "two_pass")
        return self

    @property
    def label(self) -> str:
        """The name in summary.json."""
        if self.self_contact:
            return self.name or f"{self.region}-self"
        return self.name or f"{self.surface}-{self.master}"

    @property
    def region(self) -> str:
        """The slave region (self-contact: default "all", the whole membrane)."""
        return self.surface if self.surface is not None else "all"


class ExtrusionSection(Section):
    """[extrusion]: the thesis' first inflation phase and new rest shape (ch. 3.3.3; model.experiments.membrane
    .inflate_extruded_patch) before [inflation]: the patch is extruded by ``offset`` along its oriented vertex
    normals (the clamped rim stays), inflated without contact until ``first_volume``, and its free nodes smoothed
    and relaxed until the enclosed volume falls to ``rest_volume`` (meshes.membrane.smooth_rest_shape);
    [inflation] (with the [[obstacle]]s) then inflates the membrane on that rest shape from u = 0. The volumes
    are those between the surface and the patch at rest (the muscle's base). Needs surface = "disc", or "file"
    with one patch of one rim (disc topology), the rim clamped."""

    offset: Positive = key("the extrusion of the free nodes along the patch's oriented vertex normals",
                           "m (length)")
    first_volume: Positive = key("the first phase's stop: the enclosed volume of the inflated extrusion (no "
                                 "contact)", "m^3 (volume)")
    rest_volume: Positive = key("the new rest shape's enclosed volume: the smoothing stops when the volume falls "
                                "to it", "m^3 (volume)")

    @model_validator(mode="after")
    def _volumes(self) -> ExtrusionSection:
        if self.rest_volume >= self.first_volume:
            fail(f"{self.rest_volume!r} must be below first_volume ({self.first_volume!r}): the smoothing shrinks "
                 "the inflated shape", "rest_volume")
        return self


#: the boundaries of the closed patch's tetrahedral mesh (model.experiments.membrane): the inflated patch, the flat
#: base, and the base's two ends where the fibres start and end
MUSCLE_BOUNDARIES = ("patch", "base", "origin", "insertion")
#: the surfaces [extrusion] and [muscle] take: the built-in disc, or a user's patch (one rim, disc topology)
PATCH_SURFACES = ("disc", "file")
#: the files the [muscle] phase writes into the output folder
MUSCLE_FILES = {"mesh": "muscle.msh", "fibres": "fibres.npy", "config": "muscle.toml", "vtu": "muscle.vtu"}


class MuscleSection(Section):
    """[muscle]: after the inflation, the thesis' closing (ch. 3.3.3): the patch closed with its rest shape (the
    disc's flat one, a file's patch as read) as the base and filled with tetrahedra (gmsh), the Laplace fibre
    field a0 = grad phi / |grad phi| (phi = 0 on the base's end s < -end a, ``origin``, and 1 on s > end a,
    ``insertion``; s the position along ``axis`` about the patch's middle, a its half-length), written as
    muscle.msh (physical groups: volume muscle; surfaces patch, base, origin, insertion), fibres.npy (a0 per
    tetrahedron in the mesh file's cell order), muscle.vtu (both, to look at) and muscle.toml: a solid run of
    the muscle (law muscle, isotropic StVK, the fibres from fibres.npy, the activation ramped from 0, the
    ``fixed`` boundaries clamped) that ``python -m model run`` takes as it is. Needs surface = "disc", or "file"
    with one patch of one rim (disc topology), the rim clamped."""

    tet_size: Positive | None = key("largest tetrahedron edge inside the muscle (default: membrane.size; the "
                                    "surface mesh is kept)", "m (length)", default=None)
    end: Annotated[Number, *interval(0.0, 1.0, "()")] = key(
        "the fibre ends: the base triangles whose centroid has s < -end a (origin) and s > end a (insertion), "
        "s = X . e - c along the unit axis e (``axis``), c and a the middle and the half-length of the patch "
        "along it (disc: c = 0, a = radius, so with the default axis x < -end radius and x > end radius; file: "
        "the middle and half of the nodes' extent min..max of X . e)", "dimensionless", default=0.6)
    axis: Point | None = key(
        "the direction e the fibres run along, from origin to insertion (normalised; default: disc [1, 0, 0]; "
        "file: the patch's principal axis, the direction of the largest area-weighted second moment of its "
        "triangles' centroids about their mean, its largest component positive; a patch whose two largest "
        "moments are within 5 % of each other (round) has none: give axis)", "dimensionless", default=None)
    young: Positive = key("the muscle's Young's modulus E (its isotropic StVK part)", "Pa (stress)")
    nu: Annotated[Number, *interval(-1.0, 0.5, "()")] = key("the muscle's Poisson's ratio", "dimensionless",
                                                            default=0.45)
    sigma_max: Positive = key("the muscle's maximum active fibre stress", "Pa (stress)")
    activation: Annotated[Number, *interval(0.0, 1.0, "(]")] = key(
        "the activation reached at the end of the muscle run (ramped linearly from 0)", "dimensionless",
        default=1.0)
    steps: count(1) = key("load steps of the muscle run", default=4)
    degree: Annotated[Integer, Field(ge=1, le=2)] = key("the muscle run's displacement degree (1 or 2)", default=1)
    fixed: Annotated[tuple[Literal[MUSCLE_BOUNDARIES], ...], Field(min_length=1)] = key(
        "the boundaries of the muscle run held in place: [\"origin\", \"insertion\"] an isometric contraction, "
        "[\"origin\"] a free one (boundaries: patch, base, origin, insertion)", default=("origin", "insertion"))


class MembraneOutput(Section):
    """[output]: the results folder (summary.json is always written) and the deformed surface's files."""

    dir: Path = key("folder of the results, relative to the working directory (the command line's --out wins)",
                    default=Path("results"))
    xdmf: Flag = key("write the displacement per pressure step as an XDMF time series (surface.xdmf)",
                     default=True)
    vtu: Flag = key("write the deformed surface per pressure step as VTU (surface_NNNN.vtu: reference points, "
                    "point data u)", default=True)


class MembraneRunConfig(Section):
    """A membrane run: a TOML file with [membrane] and [inflation] (docs/membranes.md)."""

    membrane: MembraneSection = key("the surface, its law and its Dirichlet border")
    inflation: InflationSection = key("the pressure path: a ramp, a list, or growth to a volume or contact "
                                      "fraction")
    obstacles: tuple[ObstacleSection, ...] = key("rigid obstacles with a penalty", default=(), alias="obstacle")
    contacts: tuple[ContactSection, ...] = key("membrane-membrane contacts (two regions of the surface)",
                                               default=(), alias="contact")
    extrusion: ExtrusionSection | None = key("before [inflation]: the patch (disc or file) extruded, inflated to a "
                                             "first volume and smoothed into a new rest shape", default=None)
    muscle: MuscleSection | None = key("after the inflation: the patch closed, tetrahedralised, given Laplace "
                                       "fibres and written with a muscle run's configuration", default=None)
    output: MembraneOutput = key("results folder and files", default_factory=MembraneOutput)
    units: UnitsConfig = key("the system of units the numbers are in (labels only)", default_factory=UnitsConfig)

    @model_validator(mode="after")
    def _across(self) -> MembraneRunConfig:
        if self.inflation.contact_fraction is not None and not (self.obstacles or self.contacts):
            fail("needs an [[obstacle]] or a [[contact]] to touch", "inflation", "contact_fraction")
        if self.inflation.freeze_on_contact and not (self.obstacles or self.contacts):
            fail("needs an [[obstacle]] or a [[contact]] to touch", "inflation", "freeze_on_contact")
        labels = [contact.label for contact in self.contacts]
        for i, label in enumerate(labels):
            if label in labels[:i]:
                fail(f"{label!r} names two contacts (summary.json reports each by its name): give each its own "
                     "name", "contact", i, "name")
        if self.membrane.surface == "disc" and any(contact.self_contact for contact in self.contacts):
            i = next(i for i, contact in enumerate(self.contacts) if contact.self_contact)
            fail("the disc is flat at rest, so no node lies on either side of another triangle and none could pair "
                 "(docs/membranes.md, self-contact of one membrane)", "contact", i, "self_contact")
        regions = self.membrane.regions
        for i, contact in enumerate(self.contacts if regions is not None else ()):  # a file's: when read
            for k in ("surface", "master"):
                name = getattr(contact, k)
                if contact.self_contact and k == "surface" and name == "all":
                    continue  # the whole membrane, spelled out
                if name is not None and name not in regions:
                    known = f"regions: {', '.join(regions)}" if regions else \
                        "no regions: membrane-membrane contact needs surface = 'facing_discs' or a .msh file's " \
                        "named physical surfaces"
                    fail(f"{self.membrane.surface} has no region {name!r} ({known})", "contact", i, k)
        if self.extrusion is not None:
            if self.membrane.surface not in PATCH_SURFACES:
                fail(f"needs surface = 'disc' or 'file' (the extruded patch), not {self.membrane.surface!r}",
                     "extrusion")
            if not self._rim_clamped():
                fail(f"needs the rim clamped ({self._clamped_hint()}): the extrusion keeps it", "extrusion")
            if "bump" in self.membrane.model_fields_set:
                fail("not with [extrusion] (the first phase starts from the extruded disc, the second from its rest "
                     "shape)", "membrane", "bump")
        if self.muscle is not None:
            if self.membrane.surface not in PATCH_SURFACES:
                fail(f"needs surface = 'disc' or 'file' (a patch closed with its rest shape as the base), not "
                     f"{self.membrane.surface!r}", "muscle")
            if not self._rim_clamped():
                fail(f"needs the rim clamped ({self._clamped_hint()}): the base is closed on it", "muscle")
            if self.muscle.axis is not None and not any(float(c) != 0.0 for c in self.muscle.axis):
                fail("must not be zero (the direction the fibres run along)", "muscle", "axis")
        return self

    def _rim_clamped(self) -> bool:
        """[extrusion], [muscle]: the disc's rim held in x, y, z; a file's every border held in x, y, z (that the
        borders are the patch's whole open boundary and nothing else is checked when the file is read)."""
        border = self.membrane.border
        if self.membrane.surface == "disc":
            return border.get("rim") == (0, 1, 2)
        return bool(border) and all(tuple(sorted(set(c))) == (0, 1, 2) for c in border.values())

    def _clamped_hint(self) -> str:
        return "membrane.fixed = { rim = [0, 1, 2] }" if self.membrane.surface == "disc" else \
            "membrane.fixed = { boundary = [0, 1, 2] }, the patch's open boundary held in x, y, z"

    @property
    def uzawa_tolerance(self) -> float:
        """The Uzawa tolerance of the augmented contacts: the smallest given, default 1e-9."""
        given = [c.tolerance for c in self.contacts if c.tolerance is not None]
        return float(min(given)) if given else 1e-9

    @property
    def document(self) -> dict[str, Any] | None:
        """The TOML document this configuration was checked from (after overrides): summary.json's "config"."""
        return self.__dict__.get("_document")


def is_membrane(raw: Any) -> bool:
    """Whether a parsed document is a membrane run (it has a top-level [membrane] table)."""
    return isinstance(raw, dict) and "membrane" in raw


def parse_membrane(raw: dict[str, Any], base: Path = Path(".")) -> MembraneRunConfig:
    """Check a parsed membrane document (ConfigError naming the key)."""
    from model.config.overrides import resolved

    config = validate(MembraneRunConfig, raw, context={"base": Path(base)})
    config.__dict__["_document"] = resolved(raw, Path(base))
    return config


def load_membrane(path: str | Path, overrides: dict[str, Any] | None = None) -> MembraneRunConfig:
    """Read and check a membrane TOML file, with optional overrides {dotted.key: value}."""
    from model.config.document import read
    from model.config.overrides import apply

    path = Path(path)
    raw = read(path)
    if not is_membrane(raw):
        raise ConfigError("membrane: missing section [membrane] (a membrane run's file)")
    if overrides:
        raw = apply(raw, overrides, MembraneRunConfig)
    return parse_membrane(raw, path.parent)


__all__ = ["ContactSection", "ExtrusionSection", "InflationSection", "LAW_PARAMETERS", "MUSCLE_BOUNDARIES",
           "MUSCLE_FILES", "PATCH_SURFACES", "SURFACES", "SURFACE_KEYS", "MembraneOutput", "MembraneRunConfig",
           "MembraneSection", "MuscleSection", "ObstacleSection", "is_membrane", "load_membrane", "parse_membrane"]
