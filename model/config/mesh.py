"""[mesh]: the body's tetrahedral mesh, from a generator of the ``meshes`` package or from a file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import ValidationInfo, field_validator, model_validator

from model.config.base import ByPresence, ExistingFile, Integer, Name, Number, Text, Variant, fail, key, kinds
from model.errors import closest, did_you_mean

_FILE_KEYS = ("regions", "boundaries", "cell_data", "facet_data", "parameters")
#: files that name their regions and boundaries by their physical groups
_GMSH = (".msh", ".geo")


#: the unit of each generator parameter that has one (lengths; the others are counts, flags or, for cook, the
#: benchmark's fixed 48 x 60 outline, whose thickness is in the same unit); a box's size: its three edge lengths
GENERATOR_UNITS = {name: "m (length)" for name in (
    "length", "radius", "muscle_radius", "tendon_radius", "tendon_length", "spacing", "size", "thickness",
    "belly_radius", "height", "base_radius", "top_radius", "bend", "pole_size", "pole_radius", "gap", "lower_radius",
    "lower_pole_size")}


def _generator_schema(schema: dict[str, Any]) -> None:
    """The generator names, and per generator its parameters with their defaults (meshes' signatures) and units."""
    from meshes import GENERATORS, generator_parameters

    schema["properties"]["generator"]["enum"] = sorted(GENERATORS)
    variants = []
    for name in sorted(GENERATORS):
        properties: dict[str, Any] = {"generator": {"const": name}}
        for parameter, default in generator_parameters(name).items():
            properties[parameter] = {"description": f"parameter of the {name!r} generator (meshes.{name})"}
            if parameter in GENERATOR_UNITS:
                unit = GENERATOR_UNITS[parameter]
                properties[parameter]["description"] += f" [{unit}]"
                properties[parameter]["x-unit"] = unit
            if default is not None:
                properties[parameter]["default"] = json.loads(json.dumps(default))
        variants.append({"properties": properties, "additionalProperties": False})
    schema["oneOf"] = variants
    del schema["additionalProperties"]
    del schema["properties"]["params"]


_FILE_MEANING = ("mesh file, relative to the configuration file's folder: a gmsh mesh (.msh) or geometry script "
                 "(.geo, meshed when read), or any tetrahedral mesh meshio reads (.vtu, .xdmf, .inp, .mesh, ...)")


class MeshConfig(Variant):
    """[mesh]: exactly one of ``generator`` (a generator of meshes.GENERATORS, its parameters as the other
    keys of the table) or ``file`` (a mesh file read with meshio or gmsh)."""

    kind_key = "mesh"

    generator: Text | None = key("name of the mesh generator (meshes.GENERATORS); its parameters are the table's "
                                "other keys", default=None)
    file: ExistingFile | None = key(_FILE_MEANING, default=None)
    params: dict[str, Any] = key("the generator's parameters (the table's other keys)", default_factory=dict)
    regions: dict[str, Integer] = key(
        "region name -> cell tag of the file (not for .msh or .geo: their physical groups name themselves)",
        default_factory=dict)
    boundaries: dict[str, Integer] = key(
        "boundary name -> facet tag of the file (not for .msh or .geo)", default_factory=dict)
    cell_data: Name | None = key("name of the file's cell data holding the region tags (default: the file's only "
                                 "integer cell data)", default=None)
    facet_data: Name | None = key("name of the file's facet data holding the boundary tags", default=None)
    parameters: dict[str, Number] = key(
        "only for a .geo file: values of the script's DefineConstant parameters by name, e.g. { size = 0.004 }",
        default_factory=dict)

    @classmethod
    def kind(cls) -> str:
        return cls.keys[0]

    @classmethod
    def not_applicable(cls, key: str) -> str:
        return "only applies to mesh.file"


class GeneratedMesh(MeshConfig):
    """[mesh] with ``generator``: the generator's parameters are the table's other keys (their defaults
    otherwise); their values are checked by the generator when the mesh is made."""

    model_config = {"json_schema_extra": _generator_schema}
    keys = ("generator", "params")
    generator: Text = key("name of the mesh generator (meshes.GENERATORS); its parameters are the table's other keys")

    @classmethod
    def gather(cls, data: dict[str, Any]) -> dict[str, Any]:
        params = {k: v for k, v in data.items() if k != "generator" and k not in _FILE_KEYS}
        return {**{k: v for k, v in data.items() if k == "generator" or k in _FILE_KEYS}, "params": params}

    @field_validator("generator")
    @classmethod
    def _known_generator(cls, name: str) -> str:
        from meshes import GENERATORS

        if name not in GENERATORS:
            fail(f"{name!r} is not one of {', '.join(sorted(GENERATORS))}{did_you_mean(name, GENERATORS)}")
        return name

    @field_validator("params")
    @classmethod
    def _known_parameters(cls, params: dict[str, Any], info: ValidationInfo) -> dict[str, Any]:
        from meshes import generator_parameters

        name = info.data.get("generator")
        if name is not None:
            accepted = generator_parameters(name)
            for parameter in params:
                if parameter not in accepted:
                    guess = closest(parameter, accepted)
                    hint = f", did you mean {guess!r}?" if guess else ""
                    fail(f"unknown parameter of generator {name!r}{hint} (allowed: generator, {', '.join(accepted)})",
                         parameter, up=1)
        return params


class MeshFile(MeshConfig):
    """[mesh] with ``file``: regions and boundaries are the file's tags, named by ``regions`` and
    ``boundaries`` (a gmsh .msh file or .geo script names them by its physical groups; a .geo script is
    meshed when read, its DefineConstant parameters set by ``parameters``)."""

    keys = ("file", *_FILE_KEYS)
    file: ExistingFile = key(_FILE_MEANING)

    @model_validator(mode="before")
    @classmethod
    def _gmsh_names_itself(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("file"), str):
            suffix = Path(data["file"]).suffix
            for k in _FILE_KEYS:
                if k in data and suffix in _GMSH and k != "parameters":
                    fail(f"a gmsh {suffix} file names its physical groups itself; remove this key", k)
                if k == "parameters" and k in data and suffix != ".geo":
                    fail("only applies to a gmsh .geo script", k)
        return data

    @field_validator("parameters")
    @classmethod
    def _declared_parameters(cls, parameters: dict[str, float], info: ValidationInfo) -> dict[str, float]:
        from meshes import geo_parameters

        path = info.data.get("file")
        if parameters and path is not None:
            declared = geo_parameters(path)
            for name in parameters:
                if name not in declared:
                    fail(f"{path.name} declares no parameter {name!r} (its DefineConstant parameters: "
                         f"{', '.join(declared) or 'none'})", name)
        return parameters


Mesh = kinds(GeneratedMesh, MeshFile, by=ByPresence(("generator", "file"),
                                                   "give exactly one of mesh.generator or mesh.file"))

__all__ = ["GENERATOR_UNITS", "GeneratedMesh", "Mesh", "MeshConfig", "MeshFile"]
