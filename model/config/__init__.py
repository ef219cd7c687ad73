"""The configuration schema: a TOML file checked into typed, frozen objects, without dolfinx.

``load(path, overrides)`` reads a file, ``parse(raw, base)`` checks a parsed document (paths relative
to ``base``). Every error is a ConfigError whose one-line message starts with the dotted key.
"""

from model.config.schema import (
    BodyForceConfig,
    BoneConfig,
    BoundaryConfig,
    ContactConfig,
    DiscretizationConfig,
    FibreConfig,
    LoadingConfig,
    MaterialConfig,
    MeshConfig,
    OutputConfig,
    ProbeConfig,
    RunConfig,
    SolverConfig,
    load,
    parse,
    read,
)
from model.errors import ConfigError

__all__ = ["BodyForceConfig", "BoneConfig", "BoundaryConfig", "ConfigError", "ContactConfig",
           "DiscretizationConfig", "FibreConfig", "LoadingConfig", "MaterialConfig", "MeshConfig", "OutputConfig",
           "ProbeConfig", "RunConfig", "SolverConfig", "load", "parse", "read"]
