"""Tetrahedral meshes with named regions and boundaries, built on one rank.

Every mesh source produces a :class:`MeshData` (plain numpy arrays plus
name -> tag maps); distributing it over MPI ranks is left to the caller.

Generators (all return :class:`MeshData`; see each function for its parameters
and physical group names):

=========== ================================================ =======================
name        physical volumes                                  physical surfaces
=========== ================================================ =======================
box         body                                              xmin xmax ymin ymax zmin zmax
cylinder    body                                              bottom top lateral
cook        body                                              left right bottom top front back
fusiform    belly tendon_origin tendon_insertion              origin insertion surface
trunk       trunk                                             base top bark
arm_segment fat belly_a tendon_a belly_b tendon_b             a_origin a_insertion b_origin b_insertion
                                                              proximal distal skin
layered_arm a_belly a_tendon b_belly b_tendon fat               a_origin a_insertion a_lateral a_surface (same for b)
            (separate bodies, no shared node)                fat_proximal fat_distal fat_skin fat_cavity_a
                                                              fat_cavity_b fat_surface; touching: a_flat a_round
                                                              b_flat b_round; gap > 0: fat_void (a void between
                                                              the flat faces)
sphere      body                                              surface (octant: xmin ymin zmax surface)
stacked_    lower upper (two separate bodies, one on the      <body>_xmin ... <body>_zmax, <body>_surface
blocks      other: contact between bodies)
sphere_pair upper lower (two ball octants touching at the     <body>_xmin <body>_ymin upper_zmax lower_zmin
            origin: Hertz contact of deformable spheres)      <body>_sphere <body>_surface
slotted_    body (a C: two arms across a thin slot; self-     xmin xmax ymin ymax zmin zmax slot_lower slot_upper
block       contact)                                          slot_end slot surface
twin_       a_belly a_tendon b_belly b_tendon (two separate   a_origin a_insertion a_lateral a_surface (same for b)
muscles     fusiform muscles, mirror images about x = 0,
            their bellies gap apart: curved bellies' contact)
=========== ================================================ =======================

A plane triangle mesh (not a [mesh] generator: the elasticity pipeline is 3D): ``meshes.gingerbread.gingerbread``
(a gingerbread-man outline, regions body, left_foot, right_foot, left_hand, right_hand, head; boundary outline),
a :class:`meshes.gingerbread.PlanarMeshData` that ``model.domain.distribute.build_domain`` distributes.

Render surfaces (output.render_mesh): ``meshes.surfaces.tube`` (a closed tube, round or rounded-square) and
``write_surface`` (any format meshio writes).

Files: :func:`read_msh` (a gmsh mesh) and :func:`read_geo` (a gmsh geometry script, meshed here); both
name regions and boundaries by the file's physical groups.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from meshes import _gmsh  # noqa: F401 - first: gmsh imported keeping Python's signal handlers (meshes._gmsh)
from meshes._validate import ParameterError
from meshes.arm_segment import arm_segment
from meshes.blocks import stacked_blocks
from meshes.box import box
from meshes.cook import cook
from meshes.cylinder import cylinder
from meshes.data import MeshData, from_gmsh_model, read_msh, write_msh
from meshes.fusiform import fusiform
from meshes.geo import geo_parameters, read_geo
from meshes.layered_arm import layered_arm
from meshes.slotted import slotted_block
from meshes.sphere import sphere, sphere_pair
from meshes.trunk import trunk
from meshes.twin_muscles import twin_muscles

__all__ = [
    "GENERATORS",
    "MeshData",
    "ParameterError",
    "arm_segment",
    "box",
    "cook",
    "cylinder",
    "from_gmsh_model",
    "fusiform",
    "generate",
    "generator_parameters",
    "geo_parameters",
    "layered_arm",
    "read_geo",
    "read_msh",
    "sphere",
    "slotted_block",
    "sphere_pair",
    "stacked_blocks",
    "trunk",
    "twin_muscles",
    "write_msh",
]

#: Mesh generators by name; each returns a :class:`MeshData`.
GENERATORS: dict[str, Callable[..., MeshData]] = {
    "box": box,
    "cylinder": cylinder,
    "cook": cook,
    "fusiform": fusiform,
    "sphere": sphere,
    "trunk": trunk,
    "arm_segment": arm_segment,
    "layered_arm": layered_arm,
    "stacked_blocks": stacked_blocks,
    "sphere_pair": sphere_pair,
    "slotted_block": slotted_block,
    "twin_muscles": twin_muscles,
}


def generator_parameters(name: str) -> dict[str, Any]:
    """Parameter names of generator ``name`` with their default values."""
    if name not in GENERATORS:
        raise ParameterError(f"unknown mesh generator {name!r}; available: {', '.join(sorted(GENERATORS))}")
    signature = inspect.signature(GENERATORS[name])
    return {key: p.default for key, p in signature.parameters.items()}


def generate(name: str, **params: Any) -> MeshData:
    """Run the generator ``name`` with keyword parameters ``params``.

    Raises
    ------
    ParameterError
        (a :class:`ValueError`) for an unknown generator, an unknown parameter, or
        a parameter of the wrong type or out of range; the message names the
        generator and the parameter.
    """
    accepted = generator_parameters(name)
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ParameterError(f"{name}: unknown parameter {unknown[0]!r}; accepted: {', '.join(accepted)}")
    return GENERATORS[name](**params)
