"""UFL energies and kinematics: pure functions of UFL expressions, no meshes, no solvers."""

from __future__ import annotations

from typing import Any

from forms.isotropic import Corotated, MooneyRivlin, NeoHookean, StVenantKirchhoff
from forms.law import Law, ParameterError

#: Law classes by their name in energies.md.
LAWS: dict[str, type[Law]] = {
    cls.name: cls for cls in (StVenantKirchhoff, NeoHookean, MooneyRivlin, Corotated)
}


def make_law(name: str, **params: Any) -> Law:
    """The law called ``name`` built from its parameters (raises ParameterError naming the key)."""
    if name not in LAWS:
        raise ParameterError(f"unknown law {name!r} (choose from {', '.join(sorted(LAWS))})")
    return LAWS[name].from_parameters(**params)  # type: ignore[attr-defined]


__all__ = ["LAWS", "Law", "ParameterError", "make_law", "Corotated", "MooneyRivlin", "NeoHookean",
           "StVenantKirchhoff"]
