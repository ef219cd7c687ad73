"""Run configuration: a TOML file parsed into typed dataclasses, every key checked.

The layout is shared/design/run-contract.md. Any error (unknown key, wrong
type, value out of range, unknown name) raises ConfigError with a one-line
message that starts with the offending key, e.g.
``material[0].nu: 0.5 is out of range, must be in (-1, 0.5)``.
Names of regions and boundaries are checked against the mesh later
(model.pipeline.build), still before any solve.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import forms
from model.errors import ConfigError

BOUNDARY_TYPES = ("displacement", "traction", "pressure", "attached", "sliding")
FORMULATIONS = ("displacement", "mixed")


@dataclass(frozen=True)
class MeshConfig:
    generator: str | None = None
    file: Path | None = None
    params: dict[str, Any] = field(default_factory=dict)
    regions: dict[str, int] = field(default_factory=dict)
    boundaries: dict[str, int] = field(default_factory=dict)
    cell_data: str | None = None
    facet_data: str | None = None


@dataclass(frozen=True)
class DiscretizationConfig:
    degree: int = 1
    quadrature_degree: int = 2
    formulation: str = "displacement"


@dataclass(frozen=True)
class FibreConfig:
    """[material].fibres: where a0 comes from (model.fields.fibres).

    type = "constant": the unit vector from point ``origin`` to point ``insertion``;
    type = "laplace": grad phi / |grad phi|, phi = 0 on surface ``origin``, 1 on surface ``insertion``,
    harmonic on ``regions`` (default: the material's region);
    type = "file": a .npy array (num_cells, 3) in mesh cell order.
    """

    type: str
    origin: tuple[float, ...] | str | None = None
    insertion: tuple[float, ...] | str | None = None
    regions: tuple[str, ...] = ()
    file: Path | None = None


@dataclass(frozen=True)
class MaterialConfig:
    region: str
    law: forms.Law
    #: field name -> source: a 3x3 array (constant), an (n, 3, 3) array (per cell) or f(x, t) (procedural)
    fields: dict[str, Any] = field(default_factory=dict)
    fibres: FibreConfig | None = None
    #: activation alpha against time (load factor): (t_i, alpha_i), piecewise linear, constant beyond the ends
    activation: tuple[tuple[float, float], ...] = ()
    #: mass density (kg/m^3), for [dynamics]
    density: float | None = None


@dataclass(frozen=True)
class BoundaryConfig:
    on: str
    type: str
    components: tuple[int, ...] = (0, 1, 2)
    value: tuple[float, ...] = ()
    expression: tuple[str, ...] = ()
    #: restrict a displacement condition to the boundary's nodes at these points (e.g. to stop rigid-body modes)
    points: tuple[tuple[float, ...], ...] = ()
    #: attached / sliding: the bone's name; sliding: its penalty stiffness and quadrature degree
    bone: str | None = None
    penalty: float | None = None
    quadrature_degree: int | str | None = None


@dataclass(frozen=True)
class BoneConfig:
    """[[bone]]: a rigid body with a prescribed motion and, optionally, a shape (an analytic obstacle)."""

    name: str
    motion: Any  # forms.motions.HingeMotion | TransformTable | Stationary
    obstacle: Any = None  # forms.obstacles.Plane | Sphere | Capsule
    shape: dict[str, Any] = field(default_factory=dict)  # the raw shape keys, for contacts on this bone


@dataclass(frozen=True)
class ContactConfig:
    spec: Any  # model.config.contact.ContactSpec
    bone: str | None = None


@dataclass(frozen=True)
class BodyForceConfig:
    region: str
    value: tuple[float, float, float]


@dataclass(frozen=True)
class LoadingConfig:
    steps: int = 1
    max_cutbacks: int = 8
    growth: float = 1.5


@dataclass(frozen=True)
class ProbeConfig:
    name: str
    point: tuple[float, float, float]


@dataclass(frozen=True)
class OutputConfig:
    dir: Path = Path("results")
    xdmf: bool = True
    vtu: bool = True
    png: bool = True


@dataclass(frozen=True)
class SolverConfig:
    """[solver]: the nonlinear method, Newton's tangent, PETSc options, Projective Dynamics' stopping rule."""

    method: str = "newton"
    tangent: str = "exact"
    petsc_options: dict[str, str | int | float | bool] = field(default_factory=dict)
    pd_max_iterations: int = 1000
    pd_rtol: float = 1e-8
    pd_atol: float = 1e-12


@dataclass(frozen=True)
class RunConfig:
    mesh: MeshConfig
    discretization: DiscretizationConfig
    materials: tuple[MaterialConfig, ...]
    boundaries: tuple[BoundaryConfig, ...]
    body_forces: tuple[BodyForceConfig, ...]
    loading: LoadingConfig
    petsc_options: dict[str, str | int | float | bool]
    probes: tuple[ProbeConfig, ...]
    output: OutputConfig
    solver: SolverConfig = field(default_factory=SolverConfig)
    bones: tuple[BoneConfig, ...] = ()
    contacts: tuple[ContactConfig, ...] = ()
    dynamics: Any = None  # model.config.dynamics.DynamicsSpec


# --- small checkers: each raises ConfigError naming the key ---------------------------------------

def _fail(key: str, message: str) -> None:
    raise ConfigError(f"{key}: {message}")


def _table(value: Any, key: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        _fail(key, f"must be a table, got {type(value).__name__}")
    return value


def _tables(value: Any, key: str) -> list[dict[str, Any]]:
    if isinstance(value, dict):
        _fail(key, f"must be an array of tables ([[{key}]]), got a single table ([{key}])")
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        _fail(key, "must be an array of tables")
    return value


def _known(table: dict[str, Any], allowed: set[str], key: str) -> None:
    for k in table:
        if k not in allowed:
            what = "unknown key" if key else "unknown section"
            _fail(f"{key}.{k}" if key else k, f"{what} (allowed: {', '.join(sorted(allowed))})")


def _number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(key, f"must be a number, got {value!r}")
    if not math.isfinite(value):
        _fail(key, f"must be finite, got {value!r}")
    return float(value)


def _integer(value: Any, key: str, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        _fail(key, f"must be an integer, got {value!r}")
    if minimum is not None and value < minimum:
        _fail(key, f"{value} is out of range, must be >= {minimum}")
    return value


def _string(value: Any, key: str, choices: tuple[str, ...] | None = None) -> str:
    if not isinstance(value, str):
        _fail(key, f"must be a string, got {value!r}")
    if choices is not None and value not in choices:
        _fail(key, f"{value!r} is not one of {', '.join(choices)}")
    return value


def _boolean(value: Any, key: str) -> bool:
    if not isinstance(value, bool):
        _fail(key, f"must be true or false, got {value!r}")
    return value


def _vector(value: Any, key: str, length: int | None = 3, why: str = "") -> tuple[float, ...]:
    if not isinstance(value, list):
        _fail(key, f"must be an array of numbers, got {value!r}")
    if length is not None and len(value) != length:
        _fail(key, f"must have {length} {'entry' if length == 1 else 'entries'}{why}, got {len(value)}: {value!r}")
    return tuple(_number(v, f"{key}[{i}]") for i, v in enumerate(value))


def _name_map(value: Any, key: str) -> dict[str, int]:
    table = _table(value, key)
    return {name: _integer(tag, f"{key}.{name}") for name, tag in table.items()}


# --- sections -------------------------------------------------------------------------------------

_MESH_KEYS = {"generator", "file", "regions", "boundaries", "cell_data", "facet_data"}


def _mesh(raw: dict[str, Any], base: Path) -> MeshConfig:
    from meshes import GENERATORS, generator_parameters

    has_gen, has_file = "generator" in raw, "file" in raw
    if has_gen == has_file:
        _fail("mesh", "give exactly one of mesh.generator or mesh.file")
    regions = _name_map(raw.get("regions", {}), "mesh.regions")
    boundaries = _name_map(raw.get("boundaries", {}), "mesh.boundaries")
    cell_data = _string(raw["cell_data"], "mesh.cell_data") if "cell_data" in raw else None
    facet_data = _string(raw["facet_data"], "mesh.facet_data") if "facet_data" in raw else None
    params = {k: v for k, v in raw.items() if k not in _MESH_KEYS}
    if has_gen:
        gen = _string(raw["generator"], "mesh.generator", tuple(sorted(GENERATORS)))
        for k in ("regions", "boundaries", "cell_data", "facet_data"):
            if k in raw:
                _fail(f"mesh.{k}", "only applies to mesh.file")
        accepted = generator_parameters(gen)
        for k in params:
            if k not in accepted:
                _fail(f"mesh.{k}", f"unknown parameter of generator {gen!r} (allowed: generator, "
                      f"{', '.join(accepted)})")
        return MeshConfig(generator=gen, params=params)
    if params:
        _fail(f"mesh.{sorted(params)[0]}", "unknown key for a mesh file (allowed: file, regions, boundaries, "
              "cell_data, facet_data)")
    path = Path(_string(raw["file"], "mesh.file"))
    if path.suffix == ".msh":
        for k in ("regions", "boundaries", "cell_data", "facet_data"):
            if k in raw:
                _fail(f"mesh.{k}", "a gmsh .msh file names its physical groups itself; remove this key")
    if not path.is_absolute():
        path = base / path
    if not path.is_file():
        _fail("mesh.file", f"no such file: {path}")
    return MeshConfig(file=path, regions=regions, boundaries=boundaries, cell_data=cell_data,
                      facet_data=facet_data)


def _discretization(raw: dict[str, Any]) -> DiscretizationConfig:
    _known(raw, {"degree", "quadrature_degree", "formulation"}, "discretization")
    degree = _integer(raw.get("degree", 1), "discretization.degree", 1)
    if degree > 3:
        _fail("discretization.degree", f"{degree} is out of range, must be 1, 2 or 3")
    quad = _integer(raw.get("quadrature_degree", 2 * degree), "discretization.quadrature_degree", 1)
    if quad > 12:
        _fail("discretization.quadrature_degree", f"{quad} is out of range, must be <= 12")
    formulation = _string(raw.get("formulation", "displacement"), "discretization.formulation", FORMULATIONS)
    if formulation == "mixed" and degree < 2:
        _fail("discretization.formulation", "mixed (Taylor-Hood) needs degree >= 2")
    return DiscretizationConfig(degree, quad, formulation)


def _target_source(raw: dict[str, Any], key: str, base: Path) -> Any:
    """The shape-target source of a material: S (3x3), S_file (.npy, per cell) or S_function (FILE.py:NAME)."""
    from model.config.userfiles import load_function

    given = [k for k in ("S", "S_file", "S_function") if k in raw]
    if len(given) > 1:
        _fail(f"{key}.{given[1]}", f"give only one of S, S_file, S_function (also got {given[0]})")
    if not given:
        return None
    name = given[0]
    value = raw[name]
    if name == "S":
        if not (isinstance(value, list) and len(value) == 3 and all(isinstance(r, list) for r in value)):
            _fail(f"{key}.S", "must be a 3x3 array of numbers, e.g. [[1, 0, 0], [0, 1, 0], [0, 0, 1]]")
        rows = [_vector(r, f"{key}.S[{i}]", 3) for i, r in enumerate(value)]
        try:
            return forms.check_shape_targets(np.array(rows), "S")
        except forms.ParameterError as err:
            _fail(f"{key}.S", str(err).removeprefix("S: "))
    path = Path(_string(value, f"{key}.{name}"))
    if name == "S_function":
        try:
            return load_function(str(value), base)
        except Exception as err:  # noqa: BLE001 - any import error is reported against the key
            _fail(f"{key}.S_function", str(err).splitlines()[0] if str(err) else type(err).__name__)
    if not path.is_absolute():
        path = base / path
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        _fail(f"{key}.S_file", f"cannot read {path}: {str(err).splitlines()[0]}")
    if array.ndim != 3 or array.shape[1:] != (3, 3):
        _fail(f"{key}.S_file", f"{path} must hold an array of shape (num_cells, 3, 3), got {array.shape}")
    try:
        return forms.check_shape_targets(array, "S")
    except forms.ParameterError as err:
        _fail(f"{key}.S_file", str(err).removeprefix("S: "))


def _material(raw: dict[str, Any], key: str, base: Path = Path(".")) -> MaterialConfig:
    region = _string(raw.get("region", "all"), f"{key}.region")
    if "law" not in raw:
        _fail(f"{key}.law", f"missing (choose from {', '.join(sorted(forms.LAWS))})")
    law_name = _string(raw["law"], f"{key}.law", tuple(sorted(forms.LAWS)))
    fibre_keys = ("fibres", "activation")
    fibres, activation = None, ()
    if "a0" in forms.FIELDS.get(law_name, ()):
        if "fibres" not in raw:
            _fail(f"{key}.fibres", f"missing: {law_name} needs fibre directions, e.g. fibres = {{ type = \"laplace\", "
                  "origin = \"SURFACE\", insertion = \"SURFACE\" }")
        fibres = _fibres(raw["fibres"], f"{key}.fibres", base)
    elif "fibres" in raw:
        _fail(f"{key}.fibres", f"only applies to laws with fibres (muscle, tendon), not {law_name}")
    if "alpha" in forms.FIELDS.get(law_name, ()):
        activation = _activation(raw.get("activation", 0.0), f"{key}.activation")
    elif "activation" in raw:
        _fail(f"{key}.activation", f"only applies to law = \"muscle\", not {law_name}")
    fields: dict[str, Any] = {}
    field_keys = ("S", "S_file", "S_function")
    if "S" in forms.FIELDS.get(law_name, ()):
        source = _target_source(raw, key, base)
        if source is not None:
            fields["S"] = source
    else:
        for k in field_keys:
            if k in raw:
                _fail(f"{key}.{k}", f"only applies to laws with a shape target (shape_target, volume), not {law_name}")
    density = None
    if "density" in raw:
        density = _number(raw["density"], f"{key}.density")
        if density <= 0:
            _fail(f"{key}.density", f"{density} is out of range, must be > 0")
    params = {k: v for k, v in raw.items() if k not in ("region", "law", "density", *field_keys, *fibre_keys)}
    if "isotropic" in params and law_name in ("muscle", "tendon"):
        from forms.muscle import ISOTROPIC

        _string(params["isotropic"], f"{key}.isotropic", ISOTROPIC)

    def check_numbers() -> None:
        for k, v in params.items():
            if k != "isotropic":
                _number(v, f"{key}.{k}")

    # errors in the order: unknown parameter (e.g. a misspelt "region"), wrong type, missing or out of range
    try:
        law = forms.make_law(law_name, **params)
    except forms.ParameterError as err:
        message = str(err).removeprefix(f"{law_name}: ")
        if not message.startswith("unknown parameter"):
            check_numbers()
        _fail(_parameter_key(key, message, params), f"{law_name}: {message}")
    except TypeError:
        check_numbers()
        raise
    check_numbers()
    return MaterialConfig(region, law, fields, fibres, activation, density)


FIBRE_TYPES = ("constant", "laplace", "file")


def _fibres(value: Any, key: str, base: Path) -> FibreConfig:
    """[material].fibres: an inline table with ``type`` and the keys of that type (FibreConfig)."""
    raw = _table(value, key)
    if "type" not in raw:
        _fail(f"{key}.type", f"missing (one of {', '.join(FIBRE_TYPES)})")
    kind = _string(raw["type"], f"{key}.type", FIBRE_TYPES)
    allowed = {"constant": {"type", "origin", "insertion"}, "laplace": {"type", "origin", "insertion", "regions"},
               "file": {"type", "file"}}[kind]
    _known(raw, allowed, key)
    for k in sorted(allowed - {"type", "regions"}):
        if k not in raw:
            what = {"constant": "a point [x, y, z]", "laplace": "the name of a boundary", "file": "a .npy file"}[kind]
            _fail(f"{key}.{k}", f"missing ({what})")
    if kind == "constant":
        origin = _vector(raw["origin"], f"{key}.origin", 3)
        insertion = _vector(raw["insertion"], f"{key}.insertion", 3)
        if np.linalg.norm(np.subtract(insertion, origin)) == 0.0:
            _fail(f"{key}.insertion", f"{list(insertion)} equals origin: the fibre direction is undefined")
        return FibreConfig(kind, origin, insertion)
    if kind == "laplace":
        origin = _string(raw["origin"], f"{key}.origin")
        insertion = _string(raw["insertion"], f"{key}.insertion")
        if origin == insertion:
            _fail(f"{key}.insertion", f"{insertion!r} is also the origin surface")
        regions = raw.get("regions", [])
        if not isinstance(regions, list) or not regions and "regions" in raw:
            _fail(f"{key}.regions", f"must be a non-empty array of region names, got {regions!r}")
        names = tuple(_string(r, f"{key}.regions[{i}]") for i, r in enumerate(regions))
        return FibreConfig(kind, origin, insertion, names)
    path = Path(_string(raw["file"], f"{key}.file"))
    if not path.is_absolute():
        path = base / path
    if not path.is_file():
        _fail(f"{key}.file", f"no such file: {path}")
    return FibreConfig(kind, file=path)


def _activation(value: Any, key: str) -> tuple[tuple[float, float], ...]:
    """A constant activation in [0, 1], or a table [[t0, alpha0], [t1, alpha1], ...] with t increasing."""
    if not isinstance(value, list):
        alpha = _number(value, key)
        if not 0.0 <= alpha <= 1.0:
            _fail(key, f"{alpha} is out of range, must be in [0, 1]")
        return ((0.0, alpha),)
    if not value:
        _fail(key, "must be a number in [0, 1] or a table [[t0, alpha0], [t1, alpha1], ...]")
    table = tuple(_vector(row, f"{key}[{i}]", 2, " (time, activation)") for i, row in enumerate(value))
    for i, (t, alpha) in enumerate(table):
        if not 0.0 <= alpha <= 1.0:
            _fail(f"{key}[{i}][1]", f"{alpha} is out of range, must be in [0, 1]")
        if i and t <= table[i - 1][0]:
            _fail(f"{key}[{i}][0]", f"times must increase, got {t} after {table[i - 1][0]}")
    return table  # type: ignore[return-value]


def _parameter_key(key: str, message: str, params: dict[str, Any]) -> str:
    """The key a law's ParameterError message is about: the parameter it starts with or names."""
    match = re.match(r"(?:unknown parameter '(\w+)'|(\w+) (?:=|is missing))", message)
    if match:
        return f"{key}.{match.group(1) or match.group(2)}"
    if "not both" in message:  # (E, nu) and (mu, lmbda) together: name the first of the second pair given
        second = [p for p in ("mu", "lmbda") if p in params]
        if second:
            return f"{key}.{second[0]}"
    return key


def _boundary(raw: dict[str, Any], key: str) -> BoundaryConfig:
    _known(raw, {"on", "type", "components", "value", "expression", "points", "bone", "penalty", "quadrature_degree"},
           key)
    if "on" not in raw:
        _fail(f"{key}.on", "missing (the name of a boundary)")
    on = _string(raw["on"], f"{key}.on")
    if "type" not in raw:
        _fail(f"{key}.type", f"missing (one of {', '.join(BOUNDARY_TYPES)})")
    kind = _string(raw["type"], f"{key}.type", BOUNDARY_TYPES)
    bone_keys = {"attached": ("bone",), "sliding": ("bone", "penalty", "quadrature_degree")}
    for k in ("bone", "penalty", "quadrature_degree"):
        if k in raw and k not in bone_keys.get(kind, ()):
            types = [t for t, keys in bone_keys.items() if k in keys]
            _fail(f"{key}.{k}", f"only applies to type = {' or '.join(repr(t) for t in types)}, not {kind!r}")
    if kind in bone_keys:
        for k in ("components", "value", "expression", "points"):
            if k in raw:
                _fail(f"{key}.{k}", f"does not apply to type = {kind!r} (the bone's motion gives the data)")
        if "bone" not in raw:
            _fail(f"{key}.bone", "missing (the name of a [[bone]])")
        bone = _string(raw["bone"], f"{key}.bone")
        if kind == "attached":
            return BoundaryConfig(on, kind, (), bone=bone)
        if "penalty" not in raw:
            _fail(f"{key}.penalty", "missing (the sliding stiffness k > 0, per unit reference area and unit gap)")
        penalty = _number(raw["penalty"], f"{key}.penalty")
        if penalty <= 0:
            _fail(f"{key}.penalty", f"{penalty} is out of range, must be > 0")
        quadrature = raw.get("quadrature_degree")
        if quadrature is not None and quadrature != "vertex":
            quadrature = _integer(quadrature, f"{key}.quadrature_degree", 1)
        return BoundaryConfig(on, kind, (), bone=bone, penalty=penalty, quadrature_degree=quadrature)
    if kind == "displacement":
        comps = raw.get("components", [0, 1, 2])
        if not isinstance(comps, list) or not comps:
            _fail(f"{key}.components", f"must be a non-empty array of 0, 1, 2, got {comps!r}")
        comps = tuple(_integer(c, f"{key}.components[{i}]") for i, c in enumerate(comps))
        if any(c not in (0, 1, 2) for c in comps) or len(set(comps)) != len(comps):
            _fail(f"{key}.components", f"{list(comps)} must be distinct entries of 0, 1, 2")
        if ("value" in raw) == ("expression" in raw):
            _fail(f"{key}.value", "give exactly one of value or expression")
        points: tuple[tuple[float, ...], ...] = ()
        if "points" in raw:
            if not isinstance(raw["points"], list) or not raw["points"]:
                _fail(f"{key}.points", f"must be a non-empty array of points [[x, y, z], ...], got {raw['points']!r}")
            points = tuple(_vector(p, f"{key}.points[{i}]", 3) for i, p in enumerate(raw["points"]))
        if "value" in raw:
            value = _vector(raw["value"], f"{key}.value", len(comps), f" (one per entry of components {list(comps)})")
            return BoundaryConfig(on, kind, comps, value=value, points=points)
        expr = raw["expression"]
        if not isinstance(expr, list) or len(expr) != len(comps):
            _fail(f"{key}.expression", f"must be an array of {len(comps)} strings (one per component)")
        exprs = tuple(_string(e, f"{key}.expression[{i}]") for i, e in enumerate(expr))
        from model.config.expressions import compile_expression

        for i, e in enumerate(exprs):
            try:
                compile_expression(e)
            except ValueError as err:
                _fail(f"{key}.expression[{i}]", str(err))
        return BoundaryConfig(on, kind, comps, expression=exprs, points=points)
    for k in ("components", "expression", "points"):
        if k in raw:
            _fail(f"{key}.{k}", f"only applies to type = \"displacement\", not {kind!r}")
    if "value" not in raw:
        _fail(f"{key}.value", "missing")
    if kind == "traction":
        return BoundaryConfig(on, kind, (), value=_vector(raw["value"], f"{key}.value", 3))
    value = raw["value"]
    if isinstance(value, list) and len(value) == 1:
        value = value[0]
    return BoundaryConfig(on, kind, (), value=(_number(value, f"{key}.value"),))


def _body_force(raw: dict[str, Any], key: str) -> BodyForceConfig:
    _known(raw, {"region", "value"}, key)
    if "value" not in raw:
        _fail(f"{key}.value", "missing (force per unit reference volume, 3 numbers)")
    value = _vector(raw["value"], f"{key}.value", 3)
    return BodyForceConfig(_string(raw.get("region", "all"), f"{key}.region"), value)  # type: ignore[arg-type]


def _loading(raw: dict[str, Any]) -> LoadingConfig:
    _known(raw, {"steps", "max_cutbacks", "growth"}, "loading")
    steps = _integer(raw.get("steps", 1), "loading.steps", 1)
    cut = _integer(raw.get("max_cutbacks", 8), "loading.max_cutbacks", 0)
    growth = _number(raw.get("growth", 1.5), "loading.growth")
    if growth < 1.0:
        _fail("loading.growth", f"{growth} is out of range, must be >= 1")
    return LoadingConfig(steps, cut, growth)


SOLVER_METHODS = ("newton", "projective_dynamics")
TANGENTS = ("exact", "projected")
_PD_KEYS = ("pd_max_iterations", "pd_rtol", "pd_atol")


def _solver(raw: dict[str, Any]) -> SolverConfig:
    _known(raw, {"petsc_options", "method", "tangent", *_PD_KEYS}, "solver")
    opts = _table(raw.get("petsc_options", {}), "solver.petsc_options")
    for k, v in opts.items():
        if not isinstance(v, (str, int, float, bool)):
            _fail(f"solver.petsc_options.{k}", f"must be a string, number or boolean, got {v!r}")
        if k.startswith("-"):
            _fail(f"solver.petsc_options.{k}", "write the option without its leading '-'")
    method = _string(raw.get("method", "newton"), "solver.method", SOLVER_METHODS)
    tangent = _string(raw.get("tangent", "exact"), "solver.tangent", TANGENTS)
    if method != "newton" and tangent != "exact":
        _fail("solver.tangent", f"{tangent!r} only applies to method = \"newton\", not {method!r}")
    if method != "projective_dynamics":
        for k in _PD_KEYS:
            if k in raw:
                _fail(f"solver.{k}", f"only applies to method = \"projective_dynamics\", not {method!r}")
    defaults = SolverConfig()
    max_iterations = _integer(raw.get("pd_max_iterations", defaults.pd_max_iterations), "solver.pd_max_iterations", 1)
    rtol = _number(raw.get("pd_rtol", defaults.pd_rtol), "solver.pd_rtol")
    if not 0.0 < rtol < 1.0:
        _fail("solver.pd_rtol", f"{rtol} is out of range, must be in (0, 1)")
    atol = _number(raw.get("pd_atol", defaults.pd_atol), "solver.pd_atol")
    if atol < 0.0:
        _fail("solver.pd_atol", f"{atol} is out of range, must be >= 0")
    return SolverConfig(method, tangent, dict(opts), max_iterations, rtol, atol)


def _check_solver(solver: SolverConfig, materials: tuple[MaterialConfig, ...],
                  disc: DiscretizationConfig) -> None:
    """What [solver] asks for must suit the formulation and the materials."""
    if solver.tangent == "projected" and disc.formulation != "displacement":
        _fail("solver.tangent", f"\"projected\" needs discretization.formulation = \"displacement\", "
              f"not {disc.formulation!r}")
    if solver.method == "projective_dynamics":
        if disc.formulation != "displacement":
            _fail("solver.method", f"\"projective_dynamics\" needs discretization.formulation = "
                  f"\"displacement\", not {disc.formulation!r}")
        for i, m in enumerate(materials):
            if m.law.name != "shape_target" or m.law.bulk_penalty != 0:
                what = m.law.name if m.law.name != "shape_target" else f"shape_target with kappa = {m.law.bulk_penalty}"
                _fail("solver.method", f"\"projective_dynamics\" needs every material to be shape_target with "
                      f"kappa = 0 (material[{i}] is {what})")


def _probe(raw: dict[str, Any], key: str) -> ProbeConfig:
    _known(raw, {"name", "point"}, key)
    if "name" not in raw or "point" not in raw:
        _fail(f"{key}.{'name' if 'name' not in raw else 'point'}", "missing")
    return ProbeConfig(_string(raw["name"], f"{key}.name"), _vector(raw["point"], f"{key}.point", 3))  # type: ignore[arg-type]


def _output(raw: dict[str, Any]) -> OutputConfig:
    _known(raw, {"dir", "xdmf", "vtu", "png"}, "output")
    return OutputConfig(
        dir=Path(_string(raw.get("dir", "results"), "output.dir")),
        xdmf=_boolean(raw.get("xdmf", True), "output.xdmf"),
        vtu=_boolean(raw.get("vtu", True), "output.vtu"),
        png=_boolean(raw.get("png", True), "output.png"),
    )


_SHAPE_KEYS = {"plane": ("point", "normal"), "sphere": ("centre", "radius"), "capsule": ("a", "b", "radius")}


def _obstacle(raw: dict[str, Any], key: str) -> Any:
    """An analytic obstacle from ``obstacle`` and its shape keys (plane: point, normal; sphere: centre,
    radius; capsule: a, b, radius)."""
    from forms.obstacles import Capsule, Plane, Sphere

    kind = _string(raw["obstacle"], f"{key}.obstacle", tuple(_SHAPE_KEYS))
    for k in _SHAPE_KEYS[kind]:
        if k not in raw:
            _fail(f"{key}.{k}", f"missing (obstacle = {kind!r} needs {', '.join(_SHAPE_KEYS[kind])})")
    if kind == "plane":
        normal = _vector(raw["normal"], f"{key}.normal")
        if not any(normal):
            _fail(f"{key}.normal", "must not be zero")
        return Plane(_vector(raw["point"], f"{key}.point"), normal)  # type: ignore[arg-type]
    radius = _number(raw["radius"], f"{key}.radius")
    if radius <= 0:
        _fail(f"{key}.radius", f"{radius} is out of range, must be > 0")
    if kind == "sphere":
        return Sphere(_vector(raw["centre"], f"{key}.centre"), radius)  # type: ignore[arg-type]
    a, b = _vector(raw["a"], f"{key}.a"), _vector(raw["b"], f"{key}.b")
    if a == b:
        _fail(f"{key}.b", "must differ from a")
    return Capsule(a, b, radius)  # type: ignore[arg-type]


def _bone(raw: dict[str, Any], key: str) -> BoneConfig:
    """[[bone]]: name; motion hinge = {axis, point, angles = [[t, degrees], ...]} or transform = {times,
    rotations (rotation vectors, radians, or 3x3 matrices), translations}; none: the bone stays put;
    optional shape: obstacle = plane | sphere | capsule with its keys (the shape at t = 0)."""
    from forms.motions import HingeMotion, Stationary, TransformTable

    shape_keys = {k for keys in _SHAPE_KEYS.values() for k in keys}
    _known(raw, {"name", "hinge", "transform", "obstacle", *shape_keys}, key)
    if "name" not in raw:
        _fail(f"{key}.name", "missing")
    name = _string(raw["name"], f"{key}.name")
    if "hinge" in raw and "transform" in raw:
        _fail(f"{key}.transform", "give one of hinge or transform, not both")
    motion: Any = Stationary()
    if "hinge" in raw:
        hinge = _table(raw["hinge"], f"{key}.hinge")
        _known(hinge, {"axis", "point", "angles"}, f"{key}.hinge")
        for k in ("axis", "point", "angles"):
            if k not in hinge:
                _fail(f"{key}.hinge.{k}", "missing")
        axis = _vector(hinge["axis"], f"{key}.hinge.axis")
        if not any(axis):
            _fail(f"{key}.hinge.axis", "must not be zero")
        point = _vector(hinge["point"], f"{key}.hinge.point")
        angles = hinge["angles"]
        if not isinstance(angles, list) or not angles:
            _fail(f"{key}.hinge.angles", "must be a table [[t0, degrees0], [t1, degrees1], ...]")
        table = [_vector(row, f"{key}.hinge.angles[{i}]", 2, " (time, degrees)") for i, row in enumerate(angles)]
        for i in range(1, len(table)):
            if table[i][0] <= table[i - 1][0]:
                _fail(f"{key}.hinge.angles[{i}][0]", f"times must increase, got {table[i][0]} after {table[i - 1][0]}")
        motion = HingeMotion(axis, point, table)  # type: ignore[arg-type]
    elif "transform" in raw:
        tr = _table(raw["transform"], f"{key}.transform")
        _known(tr, {"times", "rotations", "translations"}, f"{key}.transform")
        for k in ("times", "rotations", "translations"):
            if k not in tr or not isinstance(tr[k], list) or not tr[k]:
                _fail(f"{key}.transform.{k}", "missing or empty (one entry per time)")
        times = _vector(tr["times"], f"{key}.transform.times", None)
        for k in ("rotations", "translations"):
            if len(tr[k]) != len(times):
                _fail(f"{key}.transform.{k}", f"needs one entry per time ({len(times)}), got {len(tr[k])}")
        translations = [_vector(c, f"{key}.transform.translations[{i}]") for i, c in enumerate(tr["translations"])]
        rotations = []
        for i, r in enumerate(tr["rotations"]):
            if isinstance(r, list) and r and all(isinstance(row, list) for row in r):
                rotations.append([_vector(row, f"{key}.transform.rotations[{i}][{j}]") for j, row in enumerate(r)])
            else:
                rotations.append(_vector(r, f"{key}.transform.rotations[{i}]", 3, " (a rotation vector in radians)"))
        try:
            motion = TransformTable(times, rotations, translations)
        except ValueError as err:
            _fail(f"{key}.transform", str(err).removeprefix("transform table: "))
    obstacle, shape = None, {}
    if "obstacle" in raw:
        obstacle = _obstacle(raw, key)
        shape = {k: raw[k] for k in ("obstacle", *_SHAPE_KEYS[raw["obstacle"]])}
    else:
        for k in shape_keys:
            if k in raw:
                _fail(f"{key}.{k}", "only applies with obstacle = \"plane\" | \"sphere\" | \"capsule\"")
    return BoneConfig(name, motion, obstacle, shape)


def _contact(raw: dict[str, Any], key: str, bones: dict[str, BoneConfig]) -> ContactConfig:
    """[[contact]] (run-contract.md) plus ``bone``: the obstacle moves with that bone (and takes its shape
    when the table gives no ``obstacle``)."""
    from model.config.contact import parse_contact

    raw = dict(_table(raw, key))
    bone = raw.pop("bone", None)
    if bone is not None:
        bone = _string(bone, f"{key}.bone")
        if bone not in bones:
            _fail(f"{key}.bone", f"no [[bone]] named {bone!r} (bones: {', '.join(bones) or 'none'})")
        if "obstacle" not in raw:
            if not bones[bone].shape:
                _fail(f"{key}.obstacle", f"missing, and bone {bone!r} has no shape")
            raw.update(bones[bone].shape)
    return ContactConfig(parse_contact(raw, key), bone)


def _check_bones_and_dynamics(config: RunConfig) -> None:
    """Bone names used by boundaries exist (sliding needs a shape); a dynamic run has every density."""
    bones = {b.name: b for b in config.bones}
    for i, b in enumerate(config.boundaries):
        if b.bone is None:
            continue
        if b.bone not in bones:
            _fail(f"boundary[{i}].bone", f"no [[bone]] named {b.bone!r} (bones: {', '.join(bones) or 'none'})")
        if b.type == "sliding" and bones[b.bone].obstacle is None:
            _fail(f"boundary[{i}].bone", f"bone {b.bone!r} has no shape to slide on (give it obstacle = ...)")
    dynamics = config.dynamics
    if dynamics is not None and dynamics.is_dynamic:
        for i, m in enumerate(config.materials):
            if m.density is None:
                _fail(f"material[{i}].density", f"missing: scheme = \"{dynamics.scheme}\" needs a mass density")
        if config.solver.method != "newton" or config.solver.tangent != "exact":
            _fail("dynamics.scheme", "time integration needs solver.method = \"newton\" with tangent = \"exact\"")
    if config.contacts and config.solver.method != "newton":
        _fail("solver.method", "contact needs method = \"newton\"")


SECTIONS = {"mesh", "discretization", "material", "boundary", "body_force", "loading", "solver", "probe", "output",
            "bone", "contact", "dynamics"}


def parse(raw: dict[str, Any], base: Path = Path(".")) -> RunConfig:
    """Check a parsed TOML document and build the RunConfig (file paths relative to ``base``)."""
    _known(raw, SECTIONS, "")
    if "mesh" not in raw:
        _fail("mesh", "missing section [mesh]")
    if "material" not in raw:
        _fail("material", "missing: at least one [[material]]")
    mesh = _mesh(_table(raw["mesh"], "mesh"), base)
    disc = _discretization(_table(raw.get("discretization", {}), "discretization"))
    materials = tuple(_material(m, f"material[{i}]", base)
                      for i, m in enumerate(_tables(raw["material"], "material")))
    if not materials:
        _fail("material", "at least one [[material]] is needed")
    boundaries = tuple(_boundary(b, f"boundary[{i}]")
                       for i, b in enumerate(_tables(raw.get("boundary", []), "boundary")))
    body = tuple(_body_force(b, f"body_force[{i}]")
                 for i, b in enumerate(_tables(raw.get("body_force", []), "body_force")))
    probes = tuple(_probe(p, f"probe[{i}]") for i, p in enumerate(_tables(raw.get("probe", []), "probe")))
    names = [p.name for p in probes]
    for i, n in enumerate(names):
        if n in names[:i]:
            _fail(f"probe[{i}].name", f"{n!r} is used twice")
    loading = _loading(_table(raw.get("loading", {}), "loading"))
    solver = _solver(_table(raw.get("solver", {}), "solver"))
    _check_solver(solver, materials, disc)
    bones = tuple(_bone(b, f"bone[{i}]") for i, b in enumerate(_tables(raw.get("bone", []), "bone")))
    names = [b.name for b in bones]
    for i, n in enumerate(names):
        if n in names[:i]:
            _fail(f"bone[{i}].name", f"{n!r} is used twice")
    contacts = tuple(_contact(c, f"contact[{i}]", dict(zip(names, bones)))
                     for i, c in enumerate(_tables(raw.get("contact", []), "contact")))
    from model.config.dynamics import parse_dynamics

    dynamics = parse_dynamics(raw.get("dynamics", {}))
    config = RunConfig(
        mesh=mesh,
        discretization=disc,
        materials=materials,
        boundaries=boundaries,
        body_forces=body,
        loading=loading,
        petsc_options=solver.petsc_options,
        probes=probes,
        output=_output(_table(raw.get("output", {}), "output")),
        solver=solver,
        bones=bones,
        contacts=contacts,
        dynamics=dynamics,
    )
    _check_bones_and_dynamics(config)
    return config


def read(path: str | Path) -> dict[str, Any]:
    """The parsed TOML document of a configuration file (ConfigError naming the file when unreadable)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"config: no such file: {path}")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"config: {path}: invalid TOML: {err}") from None


def load(path: str | Path, overrides: dict[str, Any] | None = None) -> RunConfig:
    """Read and check a TOML configuration file, with optional overrides {dotted.key: value}
    (model.config.overrides); paths in it are relative to the file's folder."""
    from model.config.overrides import apply

    path = Path(path)
    raw = read(path)
    if overrides:
        raw = apply(raw, overrides)
    return parse(raw, path.parent)
