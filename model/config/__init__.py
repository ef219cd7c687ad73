"""The configuration schema: a TOML file checked into typed, frozen pydantic models, without dolfinx.

One module per section (mesh, discretization, material, boundary, body_force, loading, solver, probe,
output, bone, contact, dynamics), shared types and error wording in ``base``, the whole file in
``document``; ``reference`` renders the JSON schema and docs/config.md from the models.
``load(path, overrides)`` reads a file, ``parse(raw, base)`` checks a parsed document (paths relative
to ``base``). Every error is a ConfigError whose one-line message starts with the dotted key.
A file with a top-level [membrane] table is a membrane run instead: ``membrane`` (MembraneRunConfig,
``load_membrane``).
"""

from model.config.body_force import BodyForceConfig
from model.config.bone import BoneConfig
from model.config.boundary import BoundaryConfig
from model.config.contact import ContactConfig
from model.config.discretization import DiscretizationConfig
from model.config.document import RunConfig, load, parse, read
from model.config.loading import LoadingConfig
from model.config.material import FibreConfig, MaterialConfig
from model.config.mesh import MeshConfig
from model.config.output import OutputConfig
from model.config.probe import ProbeConfig
from model.config.solver import SolverConfig
from model.errors import ConfigError

__all__ = ["BodyForceConfig", "BoneConfig", "BoundaryConfig", "ConfigError", "ContactConfig",
           "DiscretizationConfig", "FibreConfig", "LoadingConfig", "MaterialConfig", "MeshConfig", "OutputConfig",
           "ProbeConfig", "RunConfig", "SolverConfig", "load", "parse", "read"]
