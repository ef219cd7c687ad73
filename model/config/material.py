"""[[material]]: a hyperelastic law on a region, with its parameters, fibres, activation and shape targets.

The table's common keys are declared here; every other key is a parameter of the law (E, nu, mu,
...), checked by the law itself (forms.make_law) after the type check here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    Discriminator,
    Field,
    PlainValidator,
    PrivateAttr,
    Tag,
    ValidationInfo,
    field_validator,
    model_validator,
)

import forms
from model.config.base import (
    By,
    ExistingFile,
    Name,
    Number,
    Point,
    Positive,
    Section,
    Text,
    Variant,
    Wording,
    adapter,
    base_folder,
    entries,
    fail,
    interval,
    key,
    kinds,
)
from model.errors import closest, did_you_mean

LAW_NAMES = tuple(sorted(forms.LAWS))
#: law = "FILE.py:FUNCTION" (or "FILE.py", FUNCTION = psi): a law of the user's own
UserLawSpec = Annotated[str, Field(pattern=r"\.py(:[A-Za-z_]\w*)?$")]
FIBRE_TYPES = ("constant", "laplace", "file")
TARGET_KEYS = ("S", "S_file", "S_function")


def _laws_with(field: str) -> list[str]:
    """The laws that take ``field`` (S, a0 or alpha; forms.FIELDS)."""
    return [name for name, fields in forms.FIELDS.items() if field in fields]


def _takes(law: Any, field: str) -> bool:
    return isinstance(law, forms.Law) and field in forms.law_fields(law)


# --- the law and its parameters --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LawInput:
    """The ``law`` key with the table's other keys, its parameters (what MaterialConfig hands to forms)."""

    name: Any
    parameters: dict[str, Any]


def _parameter_key(message: str, params: dict[str, Any]) -> tuple[str, ...]:
    """The key a law's ParameterError message is about: the parameter it starts with or names."""
    match = re.match(r"(?:unknown parameter '(\w+)'|(\w+) (?:=|is missing))", message)
    if match:
        return (match.group(1) or match.group(2),)
    if "not both" in message:  # (E, nu) and (mu, lmbda) together: name the first of the second pair given
        second = [p for p in ("mu", "lmbda") if p in params]
        if second:
            return (second[0],)
    return ()


def _misspelt_parameter(message: str, params: dict[str, Any], entry: forms.LawEntry) -> str:
    """A law's "unknown parameter 'E' (allowed: ...)" about the key most likely misspelt instead, with the name it
    misspells: a misspelt ``isotropic`` leaves the muscle its default isotropic part, which then refuses the E and
    nu meant for the other; the user wrote 'isotropc', not 'E'."""
    match = re.match(r"unknown parameter '(\w+)' \(allowed: (.*)\)$", message)
    if not match:
        return message
    allowed = [a.strip() for a in match.group(2).split(",")]
    names = list(dict.fromkeys([*allowed, *(p.name for p in entry.parameters), *MaterialConfig.toml_keys()]))
    unknown = [k for k in params if k not in allowed]
    for k in unknown:
        guess = closest(k, [n for n in names if n not in params])
        if guess is not None:
            return f"unknown parameter {k!r}, did you mean {guess!r}? (allowed: {match.group(2)})"
    return message


def _user_law(name: str, info: ValidationInfo) -> forms.LawEntry | None:
    """The entry of a law of the user's own, ``law = "FILE.py:FUNCTION"`` (FILE relative to the config file)."""
    path = name.rpartition(":")[0] if ":" in name else name
    if not path.endswith(".py"):
        return None
    try:
        return forms.resolve_law(name, base_folder(info))
    except forms.ParameterError as err:
        fail(str(err).removeprefix(f"{name}: "))
    except Exception as err:  # noqa: BLE001 - an error in the user's file is reported against the key
        fail(f"{name}: {type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}")


def _make_law(value: Any, info: ValidationInfo) -> forms.Law:
    """forms.make_law(name, **parameters); errors name the parameter (keys beside ``law`` in the table)."""
    if isinstance(value, forms.Law):
        return value
    name, params = (value.name, value.parameters) if isinstance(value, LawInput) else (value, {})
    if name is None:
        for k in params:  # a misspelt "law" key
            if closest(k, ["law"]):
                fail(f"unknown key, did you mean 'law'? (a material needs law = one of {', '.join(LAW_NAMES)})", k,
                     up=1)
        fail(f"missing (one of {', '.join(LAW_NAMES)}, or \"FILE.py:FUNCTION\" for a law of your own)")
    if not isinstance(name, str):
        fail(f"must be a string, got {name!r}")
    entry = forms.REGISTRY.get(name) or _user_law(name, info)
    if entry is None:
        fail(f"{name!r} is not one of {', '.join(LAW_NAMES)} (or \"FILE.py:FUNCTION\" for a law of your own)"
             f"{did_you_mean(name, LAW_NAMES)}")
    if "isotropic" in params and name in ("muscle", "tendon"):
        from forms.muscle import ISOTROPIC

        if not isinstance(params["isotropic"], str):
            fail(f"must be a string, got {params['isotropic']!r}", "isotropic", up=1)
        if params["isotropic"] not in ISOTROPIC:
            fail(f"{params['isotropic']!r} is not one of {', '.join(ISOTROPIC)}"
                 f"{did_you_mean(params['isotropic'], ISOTROPIC)}", "isotropic", up=1)

    words = {p.name for p in entry.parameters if p.choices}  # a choice: isotropic, variant

    def check_numbers() -> None:
        """Parameters are numbers (finite or not: the law says which values it accepts), choices words."""
        for k, v in params.items():
            if k not in words and (isinstance(v, bool) or not isinstance(v, (int, float))):
                fail(f"must be a number, got {v!r}", k, up=1)

    numeric = {p.name for p in entry.parameters if not p.choices}  # unknown keys: the law names them below
    curves = {k: parameter_curve(k, v) for k, v in params.items() if k in numeric and is_curve(v)}
    if curves:  # the law as it is at t = 1, checked at every point of each curve below
        params = {**params, **{k: curve(1.0) for k, curve in curves.items()}}
    # errors in the order: unknown parameter (e.g. a misspelt "region"), wrong type, missing or out of range
    try:
        law = entry.make(**params)
    except forms.ParameterError as err:
        message = _misspelt_parameter(str(err).removeprefix(f"{name}: "), params, entry)
        if not message.startswith("unknown parameter"):
            check_numbers()
        fail(f"{name}: {message}", *_parameter_key(message, params), up=1)
    except TypeError:
        check_numbers()
        raise
    check_numbers()
    for k, curve in curves.items():
        for t in curve.checked_at:
            try:
                entry.make(**{**params, k: curve(t)})
            except forms.ParameterError as err:
                fail(f"at t = {t:g}: {str(err).removeprefix(f'{name}: ')}", k, up=1)
    return law


# --- parameter curves ------------------------------------------------------------------------------------------------

def is_curve(value: Any) -> bool:
    """A law parameter written as a load curve: a table [[t0, v0], [t1, v1], ...] or an expression of t (a string)."""
    return isinstance(value, (list, tuple)) or isinstance(value, str)


@dataclass(frozen=True)
class ParameterCurve:
    """p(t) of a law parameter: a table, piecewise linear in t and constant beyond its ends, or an expression of
    the load factor t (model.config.expressions; not of the position x). ``checked_at``: the times the law's
    validation runs at (the table's times, or 0, 0.1, ..., 1 for an expression)."""

    table: tuple[tuple[float, float], ...] = ()
    expression: str = ""
    checked_at: tuple[float, ...] = ()

    def __call__(self, t: float) -> float:
        if self.table:
            times, values = zip(*self.table)
            return float(np.interp(t, times, values))
        from model.config.expressions import compile_expression

        return float(compile_expression(self.expression)(np.zeros((3, 1)), t)[0])


def parameter_curve(key_name: str, value: Any) -> ParameterCurve:
    """The curve of parameter ``key_name`` (a table or an expression of t), or fail naming the key."""
    if isinstance(value, str):
        from model.config.expressions import compile_expression, names_used

        try:
            names = names_used(value)
            compile_expression(value)
        except ValueError as err:
            fail(f"must be a number, got {value!r} (or a load curve: a table [[t0, p0], [t1, p1], ...] or an "
                 f"expression of t; as an expression: {err})", key_name, up=1)
        if "x" in names:
            fail(f"{value!r}: a law parameter may follow the load factor t, not the position x (a parameter field "
                 "per cell is not supported: give each region its own material)", key_name, up=1)
        if "t" not in names:
            fail(f"must be a number, got {value!r} (a string is a load curve, an expression of the load factor t, "
                 "and this one does not mention t: write the number)", key_name, up=1)
        curve = ParameterCurve(expression=value, checked_at=tuple(np.linspace(0.0, 1.0, 11)))
        for t in curve.checked_at:
            if not np.isfinite(curve(t)):
                fail(f"{value!r} is not finite at t = {t:g}", key_name, up=1)
        return curve
    rows = list(value)
    if not rows:
        fail("must be a number, a table [[t0, p0], [t1, p1], ...] or an expression of t, got []", key_name, up=1)
    table = []
    for i, row in enumerate(rows):
        if (not isinstance(row, (list, tuple)) or len(row) != 2
                or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) for v in row)):
            fail(f"must be a number, got {value!r} (or a load curve: a table [[t0, p0], [t1, p1], ...] whose rows are "
                 f"two finite numbers [t, value], or an expression of t; row {i} is {row!r})", key_name, up=1)
        if table and row[0] <= table[-1][0]:
            fail(f"row {i}: times must increase, got {row[0]} after {table[-1][0]}", key_name, up=1)
        table.append((float(row[0]), float(row[1])))
    return ParameterCurve(table=tuple(table), checked_at=tuple(t for t, _ in table))


def _entry_of(law: forms.Law) -> Any:
    """The LawEntry a law was made from: a law of the user's own carries it, a built-in one is in the registry."""
    return getattr(type(law), "entry", None) or forms.REGISTRY[law.name]


# --- fibres ----------------------------------------------------------------------------------------------------------

class FibreConfig(Variant):
    """material.fibres: where the fibre direction a0 comes from (model.fields.fibres), by ``type``."""

    type: str = key("where the fibre direction comes from")
    origin: tuple[float, ...] | str | None = key("where the fibres start", default=None)
    insertion: tuple[float, ...] | str | None = key("where the fibres end", default=None)
    regions: tuple[str, ...] = key("regions the fibres run through", default=())
    file: Path | None = key("file of fibre directions", default=None)


class ConstantFibres(FibreConfig):
    """fibres with type = "constant": the unit vector from point ``origin`` to point ``insertion``."""

    keys = ("type", "origin", "insertion")
    type: Literal["constant"] = key("one direction everywhere")
    origin: Point = key("a point [x, y, z] the fibres start from", "m (length)")
    insertion: Point = key("a point [x, y, z] the fibres run to", "m (length)")

    @model_validator(mode="after")
    def _direction(self) -> ConstantFibres:
        if np.linalg.norm(np.subtract(self.insertion, self.origin)) == 0.0:
            fail(f"{list(self.insertion)} equals origin: the fibre direction is undefined", "insertion")
        return self


class LaplaceFibres(FibreConfig):
    """fibres with type = "laplace": a0 = grad phi / |grad phi|, phi harmonic with phi = 0 on the surface
    ``origin`` and 1 on the surface ``insertion``."""

    keys = ("type", "origin", "insertion", "regions")
    type: Literal["laplace"] = key("along the gradient of a harmonic potential")
    origin: Name = key("the boundary (surface) where phi = 0: the fibres' origin")
    insertion: Name = key("the boundary (surface) where phi = 1: the fibres' insertion")
    regions: Annotated[tuple[Name, ...], Field(min_length=1),
                       Wording(too_short="must be a non-empty array of region names, got {input!r}")] = key(
        "the regions phi is solved on (default: the material's region)", default=(), silent=True)

    @model_validator(mode="after")
    def _two_surfaces(self) -> LaplaceFibres:
        if self.origin == self.insertion:
            fail(f"{self.insertion!r} is also the origin surface", "insertion")
        return self


class FileFibres(FibreConfig):
    """fibres with type = "file": a .npy array (num_cells, 3) of directions, in the mesh's cell order."""

    keys = ("type", "file")
    type: Literal["file"] = key("read from a file")
    file: ExistingFile = key("a .npy file of shape (num_cells, 3), relative to the configuration file")


Fibres = kinds(ConstantFibres, LaplaceFibres, FileFibres, by=By("type"))


# --- activation ------------------------------------------------------------------------------------------------------

#: an activation level
Fraction = Annotated[Number, *interval(0, 1)]
ActivationRow = Annotated[tuple[Number, Fraction], entries(2, " (time, activation)")]


def _activation_kind(value: Any) -> str:
    return "table" if isinstance(value, (list, tuple)) else "constant"


def _activation_table(value: float | tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
    if not isinstance(value, tuple):
        return ((0.0, value),)
    for i in range(1, len(value)):
        if value[i][0] <= value[i - 1][0]:
            fail(f"times must increase, got {value[i][0]} after {value[i - 1][0]}", i, 0)
    return value


#: alpha(t): a constant in [0, 1], or a table [[t0, alpha0], [t1, alpha1], ...], piecewise linear
Activation = Annotated[
    Annotated[Fraction, Tag("constant")]
    | Annotated[tuple[ActivationRow, ...], Field(min_length=1),
                Wording(too_short="must be a number in [0, 1] or a table [[t0, alpha0], [t1, alpha1], ...]"),
                Tag("table")],
    Discriminator(_activation_kind),
    AfterValidator(_activation_table),
]


# --- shape targets ---------------------------------------------------------------------------------------------------

_MATRIX = "must be a 3x3 array of numbers, e.g. [[1, 0, 0], [0, 1, 0], [0, 0, 1]]"
Matrix3 = Annotated[tuple[Point, Point, Point], Wording(too_short=_MATRIX, too_long=_MATRIX, tuple_type=_MATRIX)]


def _spd(array: np.ndarray) -> np.ndarray:
    try:
        return forms.check_shape_targets(array, "S")
    except forms.ParameterError as err:
        fail(str(err).removeprefix("S: "))


def _target_matrix(value: Any) -> np.ndarray:
    if isinstance(value, np.ndarray):
        return value
    return _spd(np.array(adapter(Matrix3).validate_python(value)))


def _target_file(value: Any, info: ValidationInfo) -> np.ndarray:
    if isinstance(value, np.ndarray):
        return value
    if not isinstance(value, str):
        fail(f"must be a string, got {value!r}")
    path = Path(value)
    if not path.is_absolute():
        path = base_folder(info) / path
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        fail(f"cannot read {path}: {str(err).splitlines()[0]}")
    if array.ndim != 3 or array.shape[1:] != (3, 3):
        fail(f"{path} must hold an array of shape (num_cells, 3, 3), got {array.shape}")
    return _spd(array)


def _target_function(value: Any, info: ValidationInfo) -> Any:
    from model.config.userfiles import load_function

    if callable(value):
        return value
    if not isinstance(value, str):
        fail(f"must be a string, got {value!r}")
    try:
        return load_function(value, base_folder(info))
    except Exception as err:  # noqa: BLE001 - any import error is reported against the key
        fail(str(err).splitlines()[0] if str(err) else type(err).__name__)


# --- the table -------------------------------------------------------------------------------------------------------

def _parameters_schema(schema: dict[str, Any]) -> None:
    schema["additionalProperties"] = {
        "description": "a parameter of the law (E, nu, mu, ...: see the laws' parameters): a number, a word "
                       "(isotropic = \"stvk\"), or a load curve: a table [[t0, p0], [t1, p1], ...] piecewise linear "
                       "in t, or an expression of t such as \"3e5 * minimum(2 * t, 1)\" (t: the load factor, or the "
                       "time of a dynamic run)",
        "type": ["number", "string", "array"]}


class MaterialConfig(Section):
    """[[material]]: the hyperelastic law of a region (the whole body: region = "all"), its parameters (the
    table's other keys) and the fields some laws take: fibres and activation (muscle, tendon), shape targets
    S (shape_target, volume), a mass density for dynamics."""

    model_config = {"json_schema_extra": _parameters_schema}

    region: Name = key("the region the law applies to (\"all\": the whole body)", default="all")
    law: Annotated[forms.Law, PlainValidator(_make_law, json_schema_input_type=Literal[LAW_NAMES] | UserLawSpec)] = key(
        "name of the hyperelastic law, or \"FILE.py:FUNCTION\" for a law of your own (forms/user_law.py; FILE "
        "relative to the configuration file); its parameters are the table's other keys")
    fibres: Fibres | None = key("the fibre directions a0 (laws with fibres: muscle, tendon, holzapfel_ogden, "
                                "trans_iso_mooney_rivlin, blemker)", default=None)
    sheets: Fibres | None = key("the sheet directions s0, orthogonal to the fibres (holzapfel_ogden), given as "
                                "fibres are", default=None)
    activation: Activation = key(
        "the activation alpha in [0, 1] (law = \"muscle\", \"trans_iso_mooney_rivlin\" or \"blemker\"): a constant, "
        "or a table [[t, alpha], ...] piecewise "
        "linear in t, constant beyond its ends (t: the load factor, or the time of a dynamic run in s)",
        "dimensionless", default_factory=lambda data: ((0.0, 0.0),) if _takes(data.get("law"), "alpha") else ())
    density: Positive | None = key("mass density, for [dynamics]", "kg/m^3 (mass density)", default=None)
    S: Annotated[np.ndarray | None, PlainValidator(_target_matrix, json_schema_input_type=Matrix3)] = key(
        "shape target S: a symmetric positive definite 3x3 matrix, the same in every cell", "dimensionless",
        default=None)
    S_file: Annotated[np.ndarray | None, PlainValidator(_target_file, json_schema_input_type=Text)] = key(
        "shape targets per cell: a .npy file of shape (num_cells, 3, 3), relative to the configuration file",
        default=None)
    S_function: Annotated[Any, PlainValidator(_target_function, json_schema_input_type=Text)] = key(
        "shape targets S(x, t): \"FILE.py:FUNCTION\", relative to the configuration file, evaluated per cell at "
        "every step", default=None)
    _given: dict[str, Any] = PrivateAttr(default_factory=dict)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_given_parameters(cls, data: Any, handler: Any) -> MaterialConfig:
        """Keep the law's parameters as written (E and nu, or mu and lmbda ...), for messages that name them."""
        material = handler(data)
        if isinstance(data, dict):
            declared = cls.toml_keys()
            material._given = {k: v for k, v in data.items() if k not in declared}
        return material

    @model_validator(mode="before")
    @classmethod
    def _law_with_its_parameters(cls, data: Any) -> Any:
        """The table's keys that are not declared here are the law's parameters: hand them to the law."""
        if isinstance(data, dict):
            declared = cls.toml_keys()
            params = {k: v for k, v in data.items() if k not in declared}
            data = {k: v for k, v in data.items() if k in declared}
            data["law"] = LawInput(data.get("law"), params)
        return data

    @field_validator("fibres", mode="before")
    @classmethod
    def _fibre_law(cls, value: Any, info: ValidationInfo) -> Any:
        law = info.data.get("law")
        if law is not None and not _takes(law, "a0"):
            fail(f"only applies to laws with fibres ({', '.join(_laws_with('a0'))}), not {law.name}")
        return value

    @field_validator("sheets", mode="before")
    @classmethod
    def _sheet_law(cls, value: Any, info: ValidationInfo) -> Any:
        law = info.data.get("law")
        if law is not None and not _takes(law, "s0"):
            fail(f"only applies to laws with a sheet direction ({', '.join(_laws_with('s0'))}), not {law.name}")
        return value

    @field_validator("activation", mode="before")
    @classmethod
    def _activated_law(cls, value: Any, info: ValidationInfo) -> Any:
        law = info.data.get("law")
        if law is not None and not _takes(law, "alpha"):
            laws = " or ".join(f'"{name}"' for name in _laws_with("alpha"))
            fail(f"only applies to law = {laws}, not {law.name}")
        return value

    @field_validator(*TARGET_KEYS, mode="before")
    @classmethod
    def _one_target(cls, value: Any, info: ValidationInfo) -> Any:
        law = info.data.get("law")
        if law is not None and not _takes(law, "S"):
            fail(f"only applies to laws with a shape target ({', '.join(_laws_with('S'))}), not {law.name}")
        given = [k for k in TARGET_KEYS[: TARGET_KEYS.index(info.field_name)] if info.data.get(k) is not None]
        if given:
            fail(f"give only one of {', '.join(TARGET_KEYS)} (also got {given[0]})")
        return value

    @model_validator(mode="after")
    def _fibres_given(self) -> MaterialConfig:
        if _takes(self.law, "a0") and self.fibres is None:
            fail(f"missing: {self.law.name} needs fibre directions, e.g. fibres = {{ type = \"laplace\", "
                 "origin = \"SURFACE\", insertion = \"SURFACE\" }", "fibres")
        if _takes(self.law, "s0") and self.sheets is None:
            fail(f"missing: {self.law.name} needs the sheet directions s0, e.g. sheets = {{ type = \"constant\", "
                 "origin = [0, 0, 0], insertion = [0, 1, 0] }", "sheets")
        return self

    @property
    def parameter_curves(self) -> dict[str, ParameterCurve]:
        """The law's parameters written as load curves, by name."""
        words = {p.name for p in _entry_of(self.law).parameters if p.choices}
        return {k: parameter_curve(k, v) for k, v in self._given.items() if k not in words and is_curve(v)
                and not isinstance(v, bool)}

    def law_at(self, t: float) -> forms.Law:
        """The law (without its fields) with every curve at load factor ``t``; the others as written."""
        curves = self.parameter_curves
        return _entry_of(self.law).make(**{**self._given, **{k: c(t) for k, c in curves.items()}})

    def law_with(self, values: dict[str, float], t: float = 0.0) -> forms.Law:
        """The law (without its fields) with ``values`` in place of the table's parameters of those names, the
        curves of the others at load factor ``t``; validated as the table is (ParameterError naming the value)."""
        curves = self.parameter_curves
        return _entry_of(self.law).make(**{**self._given, **{k: c(t) for k, c in curves.items()}, **values})

    @property
    def given_parameters(self) -> dict[str, Any]:
        """The law's parameters as the table writes them (name -> value; defaults the table leaves out are not
        here: the law has them)."""
        return dict(self._given)

    @property
    def fields(self) -> dict[str, Any]:
        """Field name -> source: S as a 3x3 array (constant), an (n, 3, 3) array (per cell) or f(x, t)."""
        source = next((s for s in (self.S, self.S_file, self.S_function) if s is not None), None)
        return {} if source is None else {"S": source}


__all__ = ["Activation", "ConstantFibres", "FibreConfig", "FileFibres", "Fibres", "LaplaceFibres", "LawInput",
           "MaterialConfig"]
