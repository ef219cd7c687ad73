"""UFL energies and kinematics: pure functions of UFL expressions, no meshes, no solvers.

The laws are listed once, in forms.registry (REGISTRY: name -> LawEntry with parameter metadata);
LAWS, FIELDS and make_law below are views of it. A user's law from a file: resolve_law("FILE.py:psi")
(forms.user_law).
"""

from __future__ import annotations

from typing import Any

from forms.fibre_laws import Blemker, HolzapfelOgden, TransIsoMooneyRivlin
from forms.isotropic import Corotated, MooneyRivlin, NeoHookean, StVenantKirchhoff
from forms.law import Law, ParameterError
from forms.metadata import FIELD_MEANINGS, LawEntry, Parameter
from forms.muscle import Muscle, Tendon
from forms.registry import REGISTRY, laws_markdown, resolve_law
from forms.shape_target import ShapeTarget, Volume, check_shape_targets
from forms.user_law import UserLaw

#: Law classes by their name in energies.md.
LAWS: dict[str, type[Law]] = {name: entry.law for name, entry in REGISTRY.items()}


def make_law(name: str, **params: Any) -> Law:
    """The law called ``name`` built from its parameters (raises ParameterError naming the key)."""
    if name not in LAWS:
        raise ParameterError(f"unknown law {name!r} (choose from {', '.join(sorted(LAWS))})")
    return LAWS[name].from_parameters(**params)  # type: ignore[attr-defined]


#: Fields a law takes besides its scalar parameters (energies.md): S, the shape target; a0, the fibre
#: direction; alpha, the activation (FIELD_MEANINGS).
FIELDS: dict[str, tuple[str, ...]] = {name: entry.fields for name, entry in REGISTRY.items() if entry.fields}


def law_fields(law: Law) -> tuple[str, ...]:
    """The fields (S, a0, alpha) the law ``law`` takes: a built-in's from REGISTRY, a user law's from its file."""
    entry = getattr(type(law), "entry", None)
    return entry.fields if entry is not None else FIELDS.get(law.name, ())

__all__ = ["FIELDS", "FIELD_MEANINGS", "LAWS", "Law", "LawEntry", "Parameter", "ParameterError", "REGISTRY",
           "UserLaw", "law_fields", "make_law", "check_shape_targets", "laws_markdown", "resolve_law", "Corotated",
           "Blemker", "HolzapfelOgden", "TransIsoMooneyRivlin",
           "MooneyRivlin", "Muscle", "NeoHookean", "ShapeTarget", "StVenantKirchhoff", "Tendon", "Volume"]
