"""A user's own law: a Python file whose function returns W(F) as a UFL expression.

    forms.resolve_law("my_law.py:psi", base=folder)        -> LawEntry (like a built-in law's)
    forms.resolve_law("my_law.py:psi", base=folder).make(C=2e3, kappa=inf, a0=fibres) -> Law

The file contract (examples/guccione_law.py is one)::

    import ufl

    PARAMETERS = {                          # optional: metadata per parameter
        "C": {"meaning": "stiffness", "unit": "Pa (stress)", "bounds": (0, None), "exclusive": True},
        "b": {"meaning": "exponent", "unit": "dimensionless", "bounds": (0, None)},
    }
    FIELDS = ("a0",)                        # optional: fields the law needs, among S, a0, s0, alpha
    VOLUMETRIC = "J - 1"                    # optional: g(F) of the volumetric term, "J - 1" or "ln J"
    FORMULA = "(C/2)(exp(b (I1 - 3)) - 1)"  # optional: one line for the documentation

    def psi(F, *, C=2000.0, b=8.0, a0=None):
        '''W(F): the energy density per unit reference volume, without a volumetric penalty.'''
        I1 = ufl.tr(F.T * F)
        return 0.5 * C * (ufl.exp(b * (I1 - 3)) - 1)

- ``F`` (the first argument) is the 3x3 deformation gradient as a UFL expression; the function returns
  W(F), a scalar UFL expression of F and the fields. UFL derives the stress dW/dF and the tangent.
- The law's parameters are the function's keyword-only arguments (after ``*``) that are not fields:
  a keyword's default is the parameter's default (a number); one without a default is required.
  Values are real finite numbers.
- ``FIELDS`` names the fields the law needs: ``S`` (3x3 shape target), ``a0`` (unit fibre direction,
  a 3-vector), ``s0`` (unit sheet direction, orthogonal to a0) and ``alpha`` (activation, a scalar). Each is
  also a keyword argument of the function and receives a UFL expression (a per-cell Function, a Constant, ...).
- ``PARAMETERS`` (optional, every key a parameter of the function) gives per parameter ``meaning``
  (one line), ``unit`` (e.g. "Pa (stress)", "dimensionless"), and ``bounds = (low, high)`` (None: no
  bound), inclusive unless ``exclusive`` is True (both ends) or a pair of booleans (low, high).
  Values outside the bounds raise the built-in laws' ParameterError ("law: C = -1.0, must be > 0").

The mixed formulation. The function's W is the part without a volumetric penalty; the law adds

    psi(F) = W(F) + (kappa/2) g(F)^2,   g = J - 1 (default) or ln J (VOLUMETRIC = "ln J"),

with the standard parameter ``kappa`` (Pa, default 0, >= 0, or inf), so that the same law serves
both formulations as the built-in ones do (forms.law): the displacement formulation uses psi
(kappa = 0: W alone); the mixed one uses W + p g - p^2 / (2 kappa), and kappa = inf is exact
incompressibility (g(F) = 0 enforced by the pressure p; mixed formulation only). ``kappa`` is
therefore a reserved name.

A rotation-based energy. A function with a keyword-only argument ``R`` receives the polar rotation
R = polar(M) (as ``corotated`` does): M = F by default, or M = F S with ``ROTATION = "F S"`` (S in
FIELDS); ``ROTATION = "F"`` may be written too, and ROTATION without an ``R`` argument is an error::

    ROTATION = "F"
    def psi(F, *, R, mu=1.0):
        return mu * ufl.inner(F - R, F - R)

R is the rotation of forms.polar (R0 per quadrature point from a batched SVD before each assembly,
R0 (I + [w]x) with the exact first derivative of R*(M); det M < 0 gives a rotation, never a reflection).
The rule for the stress: P is exactly the derivative of the user's W(F, R(F)) with R = polar(M),

    P = dW/dF|_R + (dM/dF)^T [ R [K^-1 g]x ],   g = 2 axial(skew(R^T dW/dR)),
    K = tr(H) I - H, H = sym(R^T M)            (forms.polar.rotation_stress)

and the tangent is UFL's derivative of that P (an explicit function of F and R, R with its exact first
derivative, so A is exact too). No envelope theorem is assumed: for W = mu ||F - R||^2 (R minimises it)
g = 0 and P = 2 mu (F - R), corotated's stress; for any other W the rotation term is kept. Where the
rotation is not unique (det M < 0 with the two smallest singular values of M equal) the term is
dropped: W's value is right there, P and A do not exist.

The law's name is the spec as written ("my_law.py:psi"); error messages start with it.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, ClassVar

import numpy as np
import ufl
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering
from ufl.algorithms.apply_derivatives import apply_derivatives

from forms.law import Expr, Law, ParameterError, check_keys
from forms.metadata import FIELD_MEANINGS, LawEntry, Parameter
from forms.polar import linearised_rotation, polar_rotation_svd, rotation_not_unique, rotation_stress

VOLUMETRIC = {"J - 1": "J - 1", "ln J": "ln J"}
#: the matrices M whose polar rotation a user law may ask for (module-level ROTATION)
ROTATIONS = ("F", "F S")
#: the standard bulk parameter every user law has
KAPPA = Parameter("kappa", "bulk penalty of the volumetric term (kappa/2) g(F)^2", "Pa (stress)", default=0.0,
                  lower=0.0, lower_open=False, infinite=True)


@dataclass(frozen=True)
class UserLaw(Law):
    """psi = W(F; params, fields) + (kappa/2) g(F)^2 with W from a user's file (module docstring).

    Each loaded file gets a subclass holding the function and its LawEntry (``load_user_law``);
    ``values`` are the user's parameters as (name, value) pairs.
    """

    values: tuple[tuple[str, Any], ...] = ()
    kappa: float = 0.0
    S: Any = None
    a0: Any = None
    s0: Any = None
    alpha: Any = None

    name: ClassVar[str] = "user law"
    bulk_parameter: ClassVar[str] = "kappa"
    entry: ClassVar[LawEntry]
    function: ClassVar[Callable[..., Any]]
    logarithmic: ClassVar[bool] = False
    #: "F" or "F S" when the function takes the polar rotation R of that matrix, else None
    rotation: ClassVar[str | None] = None

    def __post_init__(self) -> None:
        given = dict(self.values)
        for p in self.entry.parameters:
            p.check(self.name, self.kappa if p.name == "kappa" else given[p.name])

    @classmethod
    def from_parameters(cls, **params: Any) -> UserLaw:
        """Build from the parameters (defaults filled in) and fields by keyword; ParameterError naming the key."""
        entry = cls.entry
        required = tuple(p.name for p in entry.parameters if p.required)
        check_keys(cls.name, params, (*entry.names, *entry.fields), required=required)
        fields = {k: params.pop(k) for k in entry.fields if k in params}
        values = {**entry.defaults, **params}
        kappa = values.pop("kappa")
        return cls(values=tuple((p.name, values[p.name]) for p in entry.parameters if p.name != "kappa"),
                   kappa=kappa, **fields)

    @property
    def bulk_penalty(self) -> float:
        return self.kappa

    def field_values(self) -> dict[str, Expr]:
        """The fields the law needs, by name (ValueError naming a missing one)."""
        out = {}
        for name in self.entry.fields:
            value = getattr(self, name)
            if value is None:
                raise ValueError(f"{self.name}: the field {name} ({FIELD_MEANINGS[name]}) is required")
            out[name] = value
        return out

    def reduced_energy(self, F: Expr, R: Expr | None = None) -> Expr:
        """W(F) (or W(F, R)) of the user's function."""
        extra: dict[str, Expr] = {}
        if self.rotation is not None:
            if R is None:
                raise ValueError(f"{self.name}: the polar rotation R is required")
            extra["R"] = R
        return _as_scalar(self.name, self.function(F, **dict(self.values), **self.field_values(), **extra))

    def rotation_argument(self, F: Expr) -> Expr:
        """M = F, or F S with ROTATION = "F S"."""
        return F * self.field_values()["S"] if self.rotation == "F S" else F

    def reduced_stress(self, F: Expr, R: Expr | None = None) -> Expr:
        """dW/dF of W(F, R(F)) with R = polar(M): dW/dF|_R + (dM/dF)^T rotation_stress(M, R, dW/dR).

        Without a rotation, UFL's dW/dF (forms.law).
        """
        if self.rotation is None:
            return super().reduced_stress(F, R)
        if R is None:
            raise ValueError(f"{self.name}: the polar rotation R is required")
        Fv, Rv = ufl.variable(F), ufl.variable(R)
        W = self.reduced_energy(Fv, Rv)
        through_rotation = rotation_stress(self.rotation_argument(F), R, ufl.diff(W, Rv))
        if self.rotation == "F S":
            through_rotation = through_rotation * self.field_values()["S"].T
        return ufl.diff(W, Fv) + through_rotation

    def tangent_undefined(self, F: np.ndarray, **fields: np.ndarray) -> np.ndarray:
        """With a rotation: where it is not unique (forms.polar.rotation_not_unique of M = F, or F S with the
        field ``S`` (N,3,3))."""
        F = np.asarray(F, dtype=np.float64).reshape(-1, 3, 3)
        if self.rotation is None:
            return super().tangent_undefined(F, **fields)
        S = fields.get("S") if self.rotation == "F S" else None
        M = F if S is None else F @ np.asarray(S, dtype=np.float64).reshape(-1, 3, 3)
        return rotation_not_unique(M)

    def volume_constraint(self, F: Expr) -> Expr:
        """g(F) = J - 1, or ln J when the file says VOLUMETRIC = "ln J"."""
        J = ufl.det(F)
        return ufl.ln(J) if self.logarithmic else J - 1.0

    def parameters(self) -> dict[str, float]:
        return {**{k: float(v) for k, v in self.values}, "kappa": float(self.kappa)}


def _fail(spec: str, message: str) -> None:
    raise ParameterError(f"{spec}: {message}")


def _as_scalar(spec: str, value: Any) -> Expr:
    """The function's return value as a scalar UFL expression, or ValueError naming what it was."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return ufl.as_ufl(float(value))
    if not isinstance(value, ufl.core.expr.Expr):
        raise ValueError(f"{spec}: the function must return a scalar UFL expression of F, got "
                         f"{type(value).__module__}.{type(value).__qualname__}")
    if value.ufl_shape != ():
        raise ValueError(f"{spec}: the function must return a scalar UFL expression of F, got shape "
                         f"{value.ufl_shape}")
    return value


def _where(err: BaseException, path: Path | None) -> str:
    """" (FILE line N)" of the innermost traceback frame in the user's file, or ""."""
    if path is None:
        return ""
    tb, line = err.__traceback__, None
    while tb is not None:
        if Path(tb.tb_frame.f_code.co_filename).resolve() == path.resolve():
            line = tb.tb_lineno
        tb = tb.tb_next
    return "" if line is None else f" ({path.name} line {line})"


def _bounds(spec: str, name: str, meta: dict[str, Any]) -> dict[str, Any]:
    """Parameter keywords (lower, upper, lower_open, upper_open) from PARAMETERS[name]."""
    bounds = meta.get("bounds", (None, None))
    if not (isinstance(bounds, (tuple, list)) and len(bounds) == 2):
        _fail(spec, f"PARAMETERS[{name!r}]['bounds'] must be (low, high) with None for no bound, got {bounds!r}")
    for b in bounds:
        if b is not None and not (isinstance(b, (int, float)) and not isinstance(b, bool) and not math.isnan(b)):
            _fail(spec, f"PARAMETERS[{name!r}]['bounds'] must hold numbers or None, got {bounds!r}")
    exclusive = meta.get("exclusive", False)
    if isinstance(exclusive, bool):
        exclusive = (exclusive, exclusive)
    if not (isinstance(exclusive, (tuple, list)) and len(exclusive) == 2 and all(isinstance(e, bool)
                                                                                  for e in exclusive)):
        _fail(spec, f"PARAMETERS[{name!r}]['exclusive'] must be true, false or a pair of them, got {exclusive!r}")
    low, high = bounds
    return {"lower": None if low is None else float(low), "upper": None if high is None else float(high),
            "lower_open": exclusive[0], "upper_open": exclusive[1]}


def _import(spec: str, path: Path) -> ModuleType:
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:10]
    module_spec = importlib.util.spec_from_file_location(f"_user_law_{path.stem}_{digest}", path)
    if module_spec is None or module_spec.loader is None:
        _fail(spec, f"cannot import {path}")
    module = importlib.util.module_from_spec(module_spec)  # type: ignore[arg-type]
    sys.modules[module_spec.name] = module  # type: ignore[union-attr]
    try:
        module_spec.loader.exec_module(module)  # type: ignore[union-attr]
    except Exception as err:  # noqa: BLE001 - any error in the user's file is reported against the spec
        del sys.modules[module_spec.name]  # type: ignore[union-attr]
        first = str(err).splitlines()[0] if str(err) else ""
        _fail(spec, f"importing {path} failed: {type(err).__name__}: {first}")
    return module


def _rotation(spec: str, module: ModuleType, function: Callable[..., Any], fields: tuple[str, ...]) -> str | None:
    """"F" or "F S" when the function takes the polar rotation R (keyword ``R``), else None."""
    takes_R = "R" in inspect.signature(function).parameters
    rotation = getattr(module, "ROTATION", None)
    if rotation is None:
        return "F" if takes_R else None
    if rotation not in ROTATIONS:
        _fail(spec, f"ROTATION = {rotation!r}, must be one of {', '.join(repr(r) for r in ROTATIONS)}")
    if not takes_R:
        _fail(spec, f"ROTATION = {rotation!r}: the function must take the rotation, def psi(F, *, R, ...)")
    if rotation == "F S" and "S" not in fields:
        _fail(spec, "ROTATION = 'F S' needs the shape target: FIELDS = ('S',)")
    return rotation


def _parameters(spec: str, function: Callable[..., Any], fields: tuple[str, ...],
                metadata: dict[str, Any], rotation: bool = False) -> tuple[Parameter, ...]:
    """The parameters of the function's signature, with PARAMETERS' metadata, then kappa."""
    signature = inspect.signature(function)
    arguments = list(signature.parameters.values())
    if not arguments or arguments[0].kind not in (inspect.Parameter.POSITIONAL_ONLY,
                                                  inspect.Parameter.POSITIONAL_OR_KEYWORD):
        _fail(spec, "the function must take F first: def psi(F, *, param=default, ...)")
    out = []
    for arg in arguments[1:]:
        if arg.kind != inspect.Parameter.KEYWORD_ONLY:
            _fail(spec, f"argument {arg.name!r} must be keyword-only: def psi(F, *, {arg.name}=...) "
                        "(parameters and fields follow the *)")
        if arg.name in fields:
            continue
        if arg.name == "R" and rotation:
            if arg.default is not inspect.Parameter.empty and arg.default is not None:
                _fail(spec, "the rotation R takes no default: def psi(F, *, R, ...)")
            continue
        if arg.name == "kappa":
            _fail(spec, "'kappa' is reserved: the law adds the volumetric term (kappa/2) g(F)^2 itself")
        if arg.name in FIELD_MEANINGS:
            _fail(spec, f"argument {arg.name!r} is a field: list it in FIELDS = ({arg.name!r},)")
        default = None if arg.default is inspect.Parameter.empty else arg.default
        if default is not None and not (isinstance(default, (int, float)) and not isinstance(default, bool)
                                        and math.isfinite(default)):
            _fail(spec, f"the default of {arg.name!r} must be a finite number, got {default!r}")
        meta = metadata.get(arg.name, {})
        if not isinstance(meta, dict):
            _fail(spec, f"PARAMETERS[{arg.name!r}] must be a dict (meaning, unit, bounds, exclusive)")
        unknown = set(meta) - {"meaning", "unit", "bounds", "exclusive"}
        if unknown:
            _fail(spec, f"PARAMETERS[{arg.name!r}] has unknown key {sorted(unknown)[0]!r} "
                        "(allowed: meaning, unit, bounds, exclusive)")
        p = Parameter(arg.name, str(meta.get("meaning", "")), str(meta.get("unit", "")), default,
                      **_bounds(spec, arg.name, meta))
        if default is not None:
            p.check(spec, default)
        out.append(p)
    names = {p.name for p in out}
    for key in metadata:
        if key not in names:
            _fail(spec, f"PARAMETERS names {key!r}, which is not a keyword argument of the function")
    for field in fields:
        if field not in signature.parameters:
            _fail(spec, f"FIELDS lists {field!r}: the function must take it, def psi(F, *, ..., {field}=None)")
    return (*out, KAPPA)


def _probe(spec: str, law: UserLaw, path: Path | None = None) -> None:
    """Call the function once with a symbolic F (and R), and derive its stress and tangent, to report a
    broken law at load time: an exception inside the function (named with its line in the file), a
    value that is not a scalar UFL expression, or an expression UFL cannot differentiate."""
    values = np.array([[1.1, 0.1, 0.0], [0.0, 0.9, 0.05], [0.02, 0.0, 1.0]])
    F = ufl.variable(ufl.as_matrix(values.tolist()))
    R = None
    if law.rotation is not None:
        M = values @ np.diag([1.2, 1.0, 0.9]) if law.rotation == "F S" else values
        R = linearised_rotation(law.rotation_argument(F), ufl.as_matrix(polar_rotation_svd(M[None])[0].tolist()))
    function = getattr(law.function, "__name__", "psi")
    try:
        law.reduced_energy(F, R)
    except ValueError as err:
        if str(err).startswith(f"{law.name}: the function must return"):
            raise ParameterError(str(err)) from None
        raise _failure(spec, function, "calling", err, path) from None
    except Exception as err:  # noqa: BLE001 - reported against the spec
        raise _failure(spec, function, "calling", err, path) from None
    try:
        apply_derivatives(apply_algebra_lowering(ufl.diff(law.reduced_stress(F, R), F)))
    except Exception as err:  # noqa: BLE001 - reported against the spec
        raise _failure(spec, function, "differentiating", err, path) from None


def _failure(spec: str, function: str, doing: str, err: BaseException, path: Path | None) -> ParameterError:
    first = str(err).splitlines()[0] if str(err) else ""
    what = "calling the function with a UFL F" if doing == "calling" else "deriving its stress and tangent"
    return ParameterError(f"{spec}: {what} failed in {function}(){_where(err, path)}: {type(err).__name__}: {first}")


_CACHE: dict[tuple[str, str, int], LawEntry] = {}


def load_user_law(spec: str, path: Path, function_name: str, base: Path) -> LawEntry:
    """The LawEntry of the function ``function_name`` of the file ``path`` (relative to ``base``).

    ParameterError naming ``spec`` when the file is missing or breaks the contract (module docstring).
    A file is imported once per modification time.
    """
    full = path if path.is_absolute() else base / path
    if not full.is_file():
        _fail(spec, f"no such file: {full}")
    key = (spec, str(full.resolve()), full.stat().st_mtime_ns)
    if key in _CACHE:
        return _CACHE[key]
    module = _import(spec, full)
    function = getattr(module, function_name, None)
    if not callable(function):
        _fail(spec, f"{full} has no function {function_name!r}")
    fields = tuple(getattr(module, "FIELDS", ()))
    for field in fields:
        if field not in FIELD_MEANINGS:
            _fail(spec, f"FIELDS lists {field!r}; the fields are {', '.join(FIELD_MEANINGS)}")
    volumetric = getattr(module, "VOLUMETRIC", "J - 1")
    if volumetric not in VOLUMETRIC:
        _fail(spec, f"VOLUMETRIC = {volumetric!r}, must be one of {', '.join(repr(v) for v in VOLUMETRIC)}")
    metadata = getattr(module, "PARAMETERS", {})
    if not isinstance(metadata, dict):
        _fail(spec, "PARAMETERS must be a dict {name: {meaning, unit, bounds, exclusive}}")
    rotation = _rotation(spec, module, function, fields)
    parameters = _parameters(spec, function, fields, metadata, rotation is not None)
    doc = inspect.getdoc(function) or ""
    formula = str(getattr(module, "FORMULA", "")) or (doc.splitlines()[0] if doc else function_name)
    summary = (inspect.getdoc(module) or "").split("\n\n")[0].replace("\n", " ")
    cls = type(f"UserLaw_{full.stem}_{function_name}", (UserLaw,),
               {"name": spec, "function": staticmethod(function), "logarithmic": volumetric == "ln J",
                "rotation": rotation, "needs_rotation": rotation is not None,
                "__module__": __name__, "__doc__": doc or UserLaw.__doc__})
    entry = LawEntry(spec, summary, f"W + (kappa/2) g^2, W = {formula}", parameters, cls, fields=fields,
                     bulk_parameter="kappa", volume_constraint=volumetric, source=str(path))
    cls.entry = entry  # type: ignore[attr-defined]
    try:
        probe = cls.from_parameters(**{p.name: _sample_value(p) for p in parameters if p.required},
                                    **{f: _SAMPLE_FIELDS[f]() for f in fields})
    except ParameterError as err:
        _fail(spec, f"the default parameters are not valid: {err}")
    _probe(spec, probe, full)
    _CACHE[key] = entry
    return entry


def _sample_value(p: Parameter) -> float:
    """A value inside the parameter's bounds (for the load-time probe of a required parameter)."""
    if p.lower is not None and p.upper is not None:
        return 0.5 * (p.lower + p.upper)
    if p.lower is not None:
        return p.lower + 1.0
    return 1.0 if p.upper is None else p.upper - 1.0


_SAMPLE_FIELDS: dict[str, Callable[[], Expr]] = {
    "S": lambda: ufl.Identity(3),
    "a0": lambda: ufl.as_vector([1.0, 0.0, 0.0]),
    "s0": lambda: ufl.as_vector([0.0, 1.0, 0.0]),
    "alpha": lambda: ufl.as_ufl(0.5),
}

__all__ = ["KAPPA", "UserLaw", "load_user_law"]
