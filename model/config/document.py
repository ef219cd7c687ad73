"""The whole configuration file: RunConfig (its sections and the checks across them), parse, load, read.

The layout is the project's run contract (docs/configuration.md). Any error (unknown key, wrong type, value out of
range, unknown name) raises ConfigError with a one-line message that starts with the offending key, e.g.
``material[0].nu: 0.5 is out of range, must be in (-1, 0.5)``. Names of regions and boundaries are
checked against the mesh later (model.pipeline.build), still before any solve.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, Field, ValidationInfo, field_validator, model_validator

from model.config.base import Name, Number, Section, fail, key, validate
from model.config.body_force import BodyForceConfig
from model.config.bone import BoneConfig
from model.config.boundary import Boundary
from model.config.contact import Contact
from model.config.discretization import DiscretizationConfig
from model.config.dynamics import DynamicsSpec
from model.config.loading import LoadingConfig
from model.config.material import MaterialConfig
from model.config.mesh import Mesh
from model.config.output import OutputConfig
from model.config.probe import ProbeConfig
from model.config.solver import NewtonSettings, Solver
from model.config.units import UnitsConfig
from model.errors import ConfigError


def _unique_names(tables: tuple[Any, ...]) -> tuple[Any, ...]:
    names = [t.name for t in tables]
    for i, name in enumerate(names):
        if name in names[:i]:
            fail(f"{name!r} is used twice", i, "name")
    return tables


def _parameter_names(table: dict[str, float]) -> dict[str, float]:
    from model.config.expressions import RESERVED

    for name in table:
        if not name.isidentifier():
            fail(f"{name!r} is not a name an expression can use (letters, digits and _, not starting with a digit)",
                 name)
        if name in RESERVED:
            fail(f"{name!r} is taken: expressions already use {', '.join(sorted(RESERVED))}", name)
    return table


#: the [parameters] table: names an expression can use, and their numbers
Parameters = Annotated[dict[Name, Number], AfterValidator(_parameter_names)]


def _bones_named(bones: dict[str, BoneConfig]) -> str:
    return ", ".join(bones) or "none"


class RunConfig(Section):
    """A run configuration: one TOML file with the sections below (run-contract.md). Only [mesh] and at least
    one [[material]] are required."""

    mesh: Mesh = key("the body's mesh: a generator with its parameters, or a file")
    discretization: DiscretizationConfig = key("finite element spaces and quadrature",
                                               default_factory=DiscretizationConfig)
    materials: Annotated[tuple[MaterialConfig, ...], Field(min_length=1)] = key(
        "the materials, one per region (together covering the mesh)", alias="material")
    boundaries: tuple[Boundary, ...] = key("boundary conditions", default=(), alias="boundary")
    body_forces: tuple[BodyForceConfig, ...] = key("body forces", default=(), alias="body_force")
    loading: LoadingConfig = key("quasi-static load stepping", default_factory=LoadingConfig)
    solver: Solver = key("the nonlinear solver and its options", default_factory=NewtonSettings)
    probes: Annotated[tuple[ProbeConfig, ...], AfterValidator(_unique_names)] = key(
        "points whose displacement is recorded", default=(), alias="probe")
    output: OutputConfig = key("results folder and formats", default_factory=OutputConfig)
    bones: Annotated[tuple[BoneConfig, ...], AfterValidator(_unique_names)] = key(
        "rigid bones: motions and shapes", default=(), alias="bone")
    contacts: tuple[Contact, ...] = key("contacts with rigid obstacles, and between bodies (master)", default=(),
                                        alias="contact")
    dynamics: DynamicsSpec = key("time integration (default: quasi-static)", default_factory=DynamicsSpec)
    units: UnitsConfig = key("the system of units the numbers are in (labels only)", default_factory=UnitsConfig)
    parameters: Parameters = key(
        "named numbers the expressions may use, e.g. { stretch = 1.2 } and expression = [\"(stretch - 1)*0.04*t\"]: "
        "a sweep or an override varies them (--set parameters.stretch=1.1)", default_factory=dict)

    @property
    def document(self) -> dict[str, Any] | None:
        """The TOML document this configuration was checked from, after overrides, with the files it names made
        absolute (model.config.overrides.resolved; set by ``parse``): summary.json's "config"."""
        return self.__dict__.get("_document")

    @property
    def petsc_options(self) -> dict[str, str | int | float | bool]:
        """solver.petsc_options."""
        return self.solver.petsc_options

    @field_validator("contacts", mode="before")
    @classmethod
    def _bone_shapes(cls, value: Any, info: ValidationInfo) -> Any:
        """A contact on a bone takes the bone's shape when it gives no obstacle of its own."""
        if not isinstance(value, list) or "bones" not in info.data:
            return value
        bones = {b.name: b for b in info.data["bones"]}
        tables = []
        for i, table in enumerate(value):
            if isinstance(table, dict) and isinstance(table.get("bone"), str):
                name = table["bone"]
                if name not in bones:
                    fail(f"no [[bone]] named {name!r} (bones: {_bones_named(bones)})", i, "bone")
                if "obstacle" not in table:
                    if not bones[name].shape:
                        fail(f"missing, and bone {name!r} has no shape", i, "obstacle")
                    table = {**table, **bones[name].shape}
            tables.append(table)
        return tables

    @model_validator(mode="after")
    def _across_sections(self) -> RunConfig:
        self._check_solver()
        self._check_parameters_used()
        bones = {b.name: b for b in self.bones}
        for i, b in enumerate(self.boundaries):
            if b.bone is None:
                continue
            if b.bone not in bones:
                fail(f"no [[bone]] named {b.bone!r} (bones: {_bones_named(bones)})", "boundary", i, "bone")
            if b.type == "sliding" and bones[b.bone].obstacle is None:
                fail(f"bone {b.bone!r} has no shape to slide on (give it obstacle = ...)", "boundary", i, "bone")
        if self.dynamics.is_dynamic:
            for i, m in enumerate(self.materials):
                if m.density is None:
                    fail(f"missing: scheme = \"{self.dynamics.scheme}\" needs a mass density", "material", i,
                         "density")
            if self.solver.method != "newton" or self.solver.tangent != "exact":
                fail("time integration needs solver.method = \"newton\" with tangent = \"exact\"", "dynamics",
                     "scheme")
        if self.contacts and self.solver.method != "newton":
            fail("contact needs method = \"newton\"", "solver", "method")
        self._check_body_contacts()
        return self

    def _check_body_contacts(self) -> None:
        """Contact between bodies pairs nodes with triangles: P1 displacements only; each pair once."""
        pairs: dict[tuple[str, str], int] = {}
        degree, formulation = self.discretization.degree, self.discretization.formulation
        for i, c in enumerate(self.contacts):
            if c.self_contact and (degree != 1 or formulation != "displacement"):
                fail(f"self-contact needs P1 displacements (discretization.degree = 1, formulation = "
                     f"\"displacement\"), got degree {degree}, {formulation!r}", "contact", i, "self_contact")
            if c.master is None:
                continue
            if degree != 1 or formulation != "displacement":
                fail(f"contact between bodies needs P1 displacements (discretization.degree = 1, formulation = "
                     f"\"displacement\"), got degree {degree}, {formulation!r}", "contact", i, "master")
            pair = (c.surface, c.master)
            if pair in pairs:
                fail(f"the pair {c.surface!r} on {c.master!r} is already contact[{pairs[pair]}]", "contact", i,
                     "master")
            pairs[pair] = i

    def _check_parameters_used(self) -> None:
        """A parameter no expression uses is most likely misspelt (a sweep over it would repeat one run)."""
        from model.config.expressions import names_used

        used = {n for b in self.boundaries for e in getattr(b, "expression", ()) for n in names_used(e)}
        for name in self.parameters:
            if name not in used:
                fail(f"no expression uses it (they use: {', '.join(sorted(used & set(self.parameters))) or 'none'})",
                     "parameters", name)

    def _check_solver(self) -> None:
        """What [solver] asks for must suit the formulation and the materials."""
        solver, formulation = self.solver, self.discretization.formulation
        for i, m in enumerate(self.materials):
            bulk = m.law.bulk_parameter
            if formulation == "displacement" and m.law.incompressible:
                fail(f"{bulk} = inf (incompressible) needs discretization.formulation = \"mixed\" (Taylor-Hood): "
                     "the displacement formulation has no pressure to enforce the constraint", "material", i, bulk)
            if formulation == "mixed" and m.law.bulk_penalty == 0 and bulk not in m.law.parameters():  # arap
                fail(f"{m.law.name!r} has no volumetric term: the mixed formulation needs one (use formulation = "
                     "\"displacement\")", "material", i, "law")
            if formulation == "mixed" and m.law.bulk_penalty == 0:
                given = m.given_parameters
                if bulk not in given and "nu" in given:  # lmbda from E and nu: name the key the user wrote
                    fail(f"nu = {given['nu']!r} gives {bulk} = 0: the mixed formulation (Taylor-Hood) needs a "
                         f"volumetric term, nu > 0 (or give {bulk} > 0, inf for incompressible)", "material", i, "nu")
                fail(f"{bulk} = 0: the mixed formulation needs a volumetric term, {bulk} > 0 (or inf for "
                     "incompressible)", "material", i, bulk)
        if solver.tangent == "projected" and formulation != "displacement":
            fail(f"\"projected\" needs discretization.formulation = \"displacement\", not {formulation!r}",
                 "solver", "tangent")
        if solver.method == "projective_dynamics":
            if formulation != "displacement":
                fail(f"\"projective_dynamics\" needs discretization.formulation = \"displacement\", "
                     f"not {formulation!r}", "solver", "method")
            for i, m in enumerate(self.materials):
                if m.law.name != "shape_target" or m.law.bulk_penalty != 0:
                    what = m.law.name if m.law.name != "shape_target" else \
                        f"shape_target with kappa = {m.law.bulk_penalty}"
                    fail(f"\"projective_dynamics\" needs every material to be shape_target with kappa = 0 "
                         f"(material[{i}] is {what})", "solver", "method")


#: the sections of a configuration file, in their order
SECTIONS = tuple(f.alias or name for name, f in RunConfig.model_fields.items())


def parse(raw: dict[str, Any], base: Path = Path(".")) -> RunConfig:
    """Check a parsed TOML document and build the RunConfig (file paths relative to ``base``)."""
    from model.config.overrides import resolved

    if isinstance(raw, dict) and "membrane" in raw:
        raise ConfigError("membrane: this file is a membrane run (model.config.membrane), not a solid run: start it "
                          "with python -m model run FILE (sweeps and convergence studies take solid runs only)")
    # the parameters first: the expressions of every section are checked with their names
    parameters = validate(Parameters, raw["parameters"], "parameters") if isinstance(raw, dict) and \
        "parameters" in raw else {}
    config = validate(RunConfig, raw, context={"base": Path(base), "parameters": parameters})
    config.__dict__["_document"] = resolved(raw, Path(base))  # not a field: equality and dumps ignore it
    return config


def read(path: str | Path) -> dict[str, Any]:
    """The parsed TOML document of a configuration file (ConfigError naming the file when unreadable)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"config: {path} is a folder, not a configuration file")
    if not path.is_file():
        raise ConfigError(f"config: no such file: {path}")
    try:
        data = path.read_bytes()
    except OSError as err:
        raise ConfigError(f"config: cannot read {path}: {err.strerror or err}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        what = "a binary file" if b"\0" in data[:4096] else "not UTF-8 text"
        raise ConfigError(f"config: {path} is {what} (byte 0x{data[err.start]:02x} at offset {err.start}): a "
                          "configuration is a TOML file in UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"config: {path}: invalid TOML: {' '.join(str(err).split())}") from None
    except RecursionError:
        raise ConfigError(f"config: {path}: invalid TOML: arrays or tables nested too deeply") from None


def load(path: str | Path, overrides: dict[str, Any] | None = None) -> RunConfig:
    """Read and check a TOML configuration file, with optional overrides {dotted.key: value}
    (model.config.overrides); paths in it are relative to the file's folder."""
    from model.config.overrides import apply

    path = Path(path)
    raw = read(path)
    if overrides:
        raw = apply(raw, overrides)
    return parse(raw, path.parent)


__all__ = ["SECTIONS", "RunConfig", "load", "parse", "read"]
