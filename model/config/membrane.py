"""A membrane run's configuration: a TOML file with a [membrane] table (docs/membranes.md, "Running from a config").

    python -m model run examples/membrane_balloon.toml --out results/balloon

A document with a top-level [membrane] table is a membrane run (a triangle surface in 3D under a follower
pressure, model.experiments.membrane.run_membrane), not a solid run (RunConfig): its sections are

    [membrane]     the surface (a generator of meshes.membrane with radius and size), the law and its
                   parameters (plane-stress StVK: young, nu; incompressible neo-Hookean: mu; both: thickness),
                   the Dirichlet border (``fixed``: boundary name -> displacement components held at 0)
    [inflation]    the pressure: a ramp (``pressure`` in ``steps`` equal increments), a list (``pressures``),
                   or growth by ``dp`` until ``target_volume`` or until ``contact_fraction`` of the area
                   touches the obstacles (model.solvers.membrane.inflate / inflate_to_volume)
    [[obstacle]]   rigid obstacles (plane, sphere, capsule: the keys of [[bone]] shapes) with a penalty
                   (model.problem.membrane_contact.ObstacleContact)
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
    Flag,
    Integer,
    Name,
    NonNegative,
    Number,
    Point,
    Positive,
    Section,
    fail,
    interval,
    key,
    validate,
)
from model.config.bone import ObstacleField, shape_keys_schema
from model.config.units import UnitsConfig
from model.errors import ConfigError

#: the surface generators (meshes.membrane), their boundaries and the default Dirichlet border
SURFACES: dict[str, dict[str, Any]] = {
    "sphere_octant": {"boundaries": ("x0", "y0", "z0"), "fixed": {"x0": [0], "y0": [1], "z0": [2]}},
    "disc": {"boundaries": ("rim",), "fixed": {"rim": [0, 1, 2]}},
}
#: each law's parameters besides thickness
LAW_PARAMETERS = {"stvk": ("young", "nu"), "neo_hookean": ("mu",)}

Component = Annotated[Integer, Field(ge=0, le=2)]


class MembraneSection(Section):
    """[membrane]: the surface, its law and its Dirichlet border."""

    surface: Literal["sphere_octant", "disc"] = key(
        "the surface generator (meshes.membrane): \"sphere_octant\" (x, y, z >= 0 of the sphere |x| = radius, "
        "boundaries x0, y0, z0 on the symmetry planes: the closed balloon by symmetry) or \"disc\" (x^2 + y^2 <= "
        "radius^2 in z = 0, boundary rim)")
    radius: Positive = key("radius of the sphere or the disc", "m (length)", default=1.0)
    size: Positive = key("largest triangle edge of the surface mesh", "m (length)", default=0.2)
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
        "{x0 = [0], y0 = [1], z0 = [2]} (symmetry), disc {rim = [0, 1, 2]} (clamped))", default=None)
    bump: NonNegative = key("disc only: Newton starts from the paraboloid u_z = bump radius (1 - r^2/radius^2) "
                            "(a flat membrane has no transverse stiffness); the equilibria do not depend on it",
                            "dimensionless", default=0.05)
    quadrature_degree: Annotated[Integer, Field(ge=1)] = key("quadrature degree of the membrane energy",
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
        known = SURFACES[self.surface]["boundaries"]
        for name in self.fixed or {}:
            if name not in known:
                fail(f"{self.surface} has no boundary {name!r} (boundaries: {', '.join(known)})", "fixed", name)
        if "bump" in self.model_fields_set and self.surface != "disc":
            fail(f"only applies to surface = 'disc', not {self.surface!r}", "bump")
        return self

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
    steps: Annotated[Integer, Field(ge=1)] | None = key("pressure only: the ramp's equal increments (default 5)",
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
    max_steps: Annotated[Integer, Field(ge=1)] = key("target_volume / contact_fraction: most increments of dp",
                                                     default=200)
    cutbacks: Annotated[Integer, Field(ge=0)] = key("halvings of a pressure increment whose Newton fails",
                                                    default=4)

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
    output: MembraneOutput = key("results folder and files", default_factory=MembraneOutput)
    units: UnitsConfig = key("the system of units the numbers are in (labels only)", default_factory=UnitsConfig)

    @model_validator(mode="after")
    def _across(self) -> MembraneRunConfig:
        if self.inflation.contact_fraction is not None and not self.obstacles:
            fail("needs an [[obstacle]] to touch", "inflation", "contact_fraction")
        return self

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


__all__ = ["LAW_PARAMETERS", "SURFACES", "InflationSection", "MembraneOutput", "MembraneRunConfig", "MembraneSection",
           "ObstacleSection", "is_membrane", "load_membrane", "parse_membrane"]
