"""UFL energies and kinematics: pure functions of UFL expressions, no meshes, no solvers."""

from __future__ import annotations

from typing import Any

from forms.isotropic import Corotated, MooneyRivlin, NeoHookean, StVenantKirchhoff
from forms.law import Law, ParameterError
from forms.muscle import Muscle, Tendon
from forms.shape_target import ShapeTarget, Volume, check_shape_targets

#: Law classes by their name in energies.md.
LAWS: dict[str, type[Law]] = {
    cls.name: cls
    for cls in (StVenantKirchhoff, NeoHookean, MooneyRivlin, Corotated, ShapeTarget, Volume, Muscle, Tendon)
}


def make_law(name: str, **params: Any) -> Law:
    """The law called ``name`` built from its parameters (raises ParameterError naming the key)."""
    if name not in LAWS:
        raise ParameterError(f"unknown law {name!r} (choose from {', '.join(sorted(LAWS))})")
    return LAWS[name].from_parameters(**params)  # type: ignore[attr-defined]


#: Fields a law takes besides its scalar parameters (energies.md): S, the shape target.
FIELDS: dict[str, tuple[str, ...]] = {"shape_target": ("S",), "volume": ("S",), "muscle": ("a0", "alpha"),
                                      "tendon": ("a0",)}

__all__ = ["FIELDS", "LAWS", "Law", "ParameterError", "make_law", "check_shape_targets", "Corotated", "MooneyRivlin",
           "Muscle", "NeoHookean", "ShapeTarget", "StVenantKirchhoff", "Tendon", "Volume"]
