"""What the section models share: strict TOML types, tables whose keys depend on a kind, one-line errors.

Each section of a run configuration is a frozen pydantic model (one module per section); its fields
are the section's TOML keys, declared with their types, constraints, defaults, meaning and unit.
Pydantic validates; ``validate`` turns the first of its errors, in document order, into a
ConfigError whose one-line message starts with the dotted key, in the project's wording:

    material[0].nu: 0.5 is out of range, must be in (-1, 0.5)
    boundary[3].value[1]: must be a number, got '0'
    loading.stpes: unknown key (allowed: growth, max_cutbacks, steps)

Units: any consistent system, named by [units] system: "SI" (m, Pa, N, s, kg/m^3; most examples) or
"mm-MPa" (mm, MPa, N, s, tonne/mm^3). A field's unit is given as its dimension's SI unit, e.g.
"Pa (stress)"; a key whose unit depends on another key says so (boundary value: by type).

Validators raise ``fail(message, *key)`` for what a type cannot say (files that must exist, SPD
shape targets, expressions, keys that depend on one another).
"""

from __future__ import annotations

import functools
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, NoReturn, Union, get_args, get_origin

import annotated_types
from pydantic import (
    AfterValidator,
    AllowInfNan,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Strict,
    Tag,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import PydanticCustomError, PydanticUndefined

from model.errors import ConfigError, closest, did_you_mean

UNITS = ("Any consistent system of units, named by [units] system (nothing is converted): \"SI\", m (length), "
         "Pa (stress), N (force), s (time), kg/m^3 (mass density), J (energy), as in the examples; or \"mm-MPa\", "
         "mm, MPa = N/mm^2, N, s, tonne/mm^3, mJ (examples/isometric_mm.toml, examples/cook.toml).")


# --- how errors are worded -------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Wording:
    """Messages for errors of some pydantic types at this place, instead of the defaults (pydantic ignores this
    annotation; the translator reads it). Templates see ``input``, ``length`` and the error's context."""

    items: tuple[tuple[str, str], ...] = ()

    def __init__(self, **messages: str) -> None:
        object.__setattr__(self, "items", tuple(messages.items()))

    @property
    def messages(self) -> Mapping[str, str]:
        return dict(self.items)


def interval(low: float, high: float, closed: str = "[]") -> tuple[Any, ...]:
    """The constraints low <= x <= high (``closed`` "[]", "()", "[)" or "(]"), worded "must be in [low, high]"."""
    lower = {"ge": low} if closed[0] == "[" else {"gt": low}
    upper = {"le": high} if closed[1] == "]" else {"lt": high}
    text = "{input} is out of range, must be in " + f"{closed[0]}{low}, {high}{closed[1]}"
    return (Field(**lower, **upper), Wording(**{kind: text for kind in _BOUNDS}))


def entries(n: int, why: str = "") -> Wording:
    """Wording of an array that must have ``n`` entries (``why``: what they are, e.g. " (time, degrees)")."""
    text = f"must have {n} {'entry' if n == 1 else 'entries'}{why}, got {{length}}: {{input!r}}"
    return Wording(too_short=text, too_long=text)


def fail(message: str, *key: str | int, up: int = 0) -> NoReturn:
    """Stop validation: ``message`` is about ``key`` below the place being validated (``up`` levels above it
    first: ``up=1`` in a field's validator names a sibling key of the same table)."""
    raise PydanticCustomError("config", "{message}", {"message": message, "key": key, "up": up})


def meaning(info: FieldInfo | None) -> str:
    """A field's description without its unit."""
    if info is None or not info.description:
        return ""
    extra = info.json_schema_extra
    unit = dict(extra.values).get("x-unit") if isinstance(extra, KeyExtra) else None
    return info.description.removesuffix(f" [{unit}]") if unit else info.description


@dataclass(frozen=True)
class KeyExtra:
    """What a key adds to its JSON schema (``x-unit`` ...); ``silent``: leave its default out (it is what Python
    reads when the key is absent, not a value to write)."""

    values: tuple[tuple[str, Any], ...]
    silent: bool = False

    def __call__(self, json_schema: dict[str, Any]) -> None:
        if self.silent:
            json_schema.pop("default", None)
        json_schema.update(self.values)


def key(description: str, unit: str | None = None, default: Any = PydanticUndefined, *, silent: bool = False,
        **kwargs: Any) -> Any:
    """A TOML key: a pydantic Field with its one-line meaning and, where physical, its unit ("Pa (stress)";
    shown in the JSON schema as ``x-unit`` and at the end of the description, and in docs/config.md)."""
    extra = dict(kwargs.pop("json_schema_extra", None) or {})
    if unit is not None:
        extra["x-unit"] = unit
        description = f"{description} [{unit}]"
    return Field(default, description=description, json_schema_extra=KeyExtra(tuple(extra.items()), silent),
                 **kwargs)


# --- TOML types ------------------------------------------------------------------------------------------------------

#: an integer (not a float or boolean)
Integer = Annotated[int, Strict()]
#: a finite number (integer or float, not a boolean)
Number = Annotated[float, Strict(), AllowInfNan(False)]
Flag = Annotated[bool, Strict()]
Text = Annotated[str, Strict()]
#: a non-empty name (of a region, a boundary, a bone ...)
Name = Annotated[str, Strict(), Field(min_length=1)]
Positive = Annotated[float, Strict(), AllowInfNan(False), Field(gt=0)]
NonNegative = Annotated[float, Strict(), AllowInfNan(False), Field(ge=0)]
#: a point or vector [x, y, z]
Point = Annotated[tuple[Number, Number, Number], entries(3)]
#: the largest coordinate of a position (1e9 m or mm: far beyond any body, well inside what a distance can square)
MAX_COORDINATE = 1e9
_COORDINATE = (f"{{input}} is out of range: a coordinate must be within +-{MAX_COORDINATE:.0e} (no body is that "
               "large in any system of units)")
#: a coordinate of a position in the body's space: finite and within +-MAX_COORDINATE
Coordinate = Annotated[float, Strict(), AllowInfNan(False), Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE),
                       Wording(greater_than_equal=_COORDINATE, less_than_equal=_COORDINATE)]
#: a position [x, y, z] in the body's space (a probe point ...)
Position = Annotated[tuple[Coordinate, Coordinate, Coordinate], entries(3)]

#: the largest load step count, and the like: more would take longer than any run is meant to
MAX_STEPS = 100_000
_COUNT = "{input} is out of range, must be <= {le} (a larger count is a typo: no run takes that many)"


def count(low: int, high: int = MAX_STEPS) -> Any:
    """An integer count in [low, high]: steps, iterations, cut-backs (a huge one is refused, naming the key)."""
    return Annotated[int, Strict(), Field(ge=low, le=high), Wording(less_than_equal=_COUNT)]


def base_folder(info: ValidationInfo) -> Path:
    """The folder relative paths of the document are resolved against (the configuration file's)."""
    return Path((info.context or {}).get("base", Path(".")))


def _existing_file(path: Path, info: ValidationInfo) -> Path:
    if not path.is_absolute():
        path = base_folder(info) / path
    if not path.is_file():
        fail(f"no such file: {path}")
    return path


#: a file that must exist, relative to the configuration file's folder
ExistingFile = Annotated[Path, AfterValidator(_existing_file)]


# --- tables ----------------------------------------------------------------------------------------------------------

class Section(BaseModel):
    """A TOML table: frozen, every key declared (unknown keys are errors)."""

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)

    @classmethod
    def toml_keys(cls) -> tuple[str, ...]:
        """The keys this table accepts."""
        return tuple(f.alias or name for name, f in cls.model_fields.items())


class Variant(Section):
    """One kind of a table whose keys depend on the value of one of them (``kind_key``: type, method ...).

    The section's base class declares every attribute, so all kinds read alike downstream; a kind (a
    subclass) narrows the fields it uses and accepts only its ``keys``: the others keep their defaults
    and are refused when given ("only applies to type = ..."). In the JSON schema a kind shows its keys only.
    """

    kind_key: ClassVar[str] = "type"
    keys: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def kind(cls) -> str:
        """The value of ``kind_key`` that selects this kind."""
        return get_args(cls.model_fields[cls.kind_key].annotation)[0]

    @classmethod
    def toml_keys(cls) -> tuple[str, ...]:
        return cls.keys

    @classmethod
    def kinds(cls) -> list[type[Variant]]:
        """The kinds of this kind's section (the subclasses of its base class)."""
        return [k for k in cls.__mro__[1].__subclasses__() if k.keys]

    @classmethod
    def not_applicable(cls, key: str) -> str:
        """The message for a key of another kind."""
        values = " or ".join(repr(k.kind()) for k in cls.kinds() if key in k.keys)
        return f"only applies to {cls.kind_key} = {values}, not {cls.kind()!r}"

    @classmethod
    def gather(cls, data: dict[str, Any]) -> dict[str, Any]:
        """The table as the fields expect it (a kind may collect free keys into one field)."""
        return data

    @model_validator(mode="before")
    @classmethod
    def _own_keys_only(cls, data: Any) -> Any:
        if isinstance(data, dict):
            data = cls.gather(data)
            for k in data:
                if k in cls.model_fields and k not in cls.keys:
                    fail(cls.not_applicable(k), k)
        return data

    @classmethod
    def __get_pydantic_json_schema__(cls, core_schema: Any, handler: Any) -> Any:
        schema = handler(core_schema)
        target = handler.resolve_ref_schema(schema)
        if cls.keys:
            properties = target.get("properties", {})
            for k in [k for k in properties if k not in cls.keys]:
                del properties[k]
            if "required" in target:
                target["required"] = [k for k in target["required"] if k in cls.keys]
        return schema


@dataclass(frozen=True)
class By:
    """Which kind a table is: the value of its key ``key`` (``default`` when the key is absent).

    Use as ``Discriminator(By("type"))`` over ``Annotated[Kind, Tag(Kind.kind())]`` members.
    """

    key: str
    default: str | None = None

    @property
    def __name__(self) -> str:  # pydantic names the discriminator by it
        return f"the value of {self.key!r}"

    def __call__(self, data: Any) -> str | None:
        if isinstance(data, BaseModel):
            return getattr(data, self.key, None)
        if not isinstance(data, dict):
            return None
        value = data.get(self.key, self.default)
        return value if isinstance(value, str) or value is None else repr(value)


@dataclass(frozen=True)
class ByPresence:
    """Which kind a table is: the one of ``keys`` it has (``neither``: the message when it has none or several)."""

    keys: tuple[str, ...]
    neither: str

    @property
    def __name__(self) -> str:
        return f"which of {', '.join(self.keys)} is given"

    def __call__(self, data: Any) -> str | None:
        if isinstance(data, BaseModel):
            return next((k for k in self.keys if getattr(data, k, None) is not None), None)
        if not isinstance(data, dict):
            return None
        present = [k for k in self.keys if k in data]
        return present[0] if len(present) == 1 else None


def kinds(*members: type[Variant], by: By | ByPresence) -> Any:
    """The discriminated union of the kinds ``members`` of a table."""
    tagged = tuple(Annotated[m, Tag(m.kind())] for m in members)
    return Annotated[Union[tagged], Discriminator(by)]  # noqa: UP007 - a union built at run time


# --- from pydantic's errors to one line -----------------------------------------------------------------------------

_BOUNDS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")
_DEFAULTS = {
    "int_type": "must be an integer, got {input!r}",
    "int_parsing": "must be an integer, got {input!r}",
    "int_from_float": "must be an integer, got {input!r}",
    "float_type": "must be a number, got {input!r}",
    "float_parsing": "must be a number, got {input!r}",
    "finite_number": "must be finite, got {input!r}",
    "bool_type": "must be true or false, got {input!r}",
    "bool_parsing": "must be true or false, got {input!r}",
    "string_type": "must be a string, got {input!r}",
    "string_too_short": "must not be empty",
    "path_type": "must be a string (a file path), got {input!r}",
    "greater_than": "{input} is out of range, must be > {gt}",
    "greater_than_equal": "{input} is out of range, must be >= {ge}",
    "less_than": "{input} is out of range, must be < {lt}",
    "less_than_equal": "{input} is out of range, must be <= {le}",
    "model_type": "must be a table, got {typename}",
    "model_attributes_type": "must be a table, got {typename}",
    "dict_type": "must be a table, got {typename}",
}


@dataclass
class Spot:
    """Where an error is: the key's parts, its place in the document, and what the models say about it."""

    parts: list[str | int] = field(default_factory=list)
    position: list[int] = field(default_factory=list)
    table: Any = None  # the model whose key the last part is
    declared: FieldInfo | None = None  # the field the last part names
    annotation: Any = Any
    metadata: list[Any] = field(default_factory=list)
    node: Any = None  # the document's value there (None when absent)


def _unwrap(tp: Any, metadata: list[Any]) -> tuple[Any, list[Any]]:
    """Strip Annotated (keeping its metadata), Optional, and validators' input types."""
    while True:
        if get_origin(tp) is Annotated:
            tp, *extra = get_args(tp)
            metadata = [*metadata, *extra]
            continue
        if _is_union(tp) and not _discriminator(metadata):
            members = [m for m in get_args(tp) if m is not type(None)]
            if len(members) == 1:
                tp = members[0]
                continue
        given = [m.json_schema_input_type for m in metadata
                 if getattr(m, "json_schema_input_type", PydanticUndefined) not in (PydanticUndefined, Any)]
        if given:
            tp, metadata = given[-1], [m for m in metadata if not hasattr(m, "json_schema_input_type")]
            continue
        return tp, metadata


def _is_union(tp: Any) -> bool:
    return get_origin(tp) in (Union, types.UnionType)


def _discriminator(metadata: list[Any]) -> Any:
    for m in metadata:
        if isinstance(m, Discriminator):
            return m.discriminator
        if isinstance(m, FieldInfo) and m.discriminator is not None:
            return m.discriminator
    return None


def _members(tp: Any) -> list[tuple[str, Any]]:
    """(tag, member with its annotations) of a discriminated union."""
    out = []
    for member in get_args(tp):
        tag = next((m.tag for m in get_args(member)[1:] if isinstance(m, Tag)), None) \
            if get_origin(member) is Annotated else None
        inner = get_args(member)[0] if get_origin(member) is Annotated else member
        if tag is None and isinstance(inner, type) and issubclass(inner, Variant):
            tag = inner.kind()
        out.append((tag, member))
    return out


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def locate(root: Any, raw: Any, loc: tuple[str | int, ...], keys: tuple[str | int, ...] = ()) -> Spot:
    """Follow an error's ``loc`` and then the document ``keys`` below it through the models (from ``root``)
    and the document ``raw`` together (pydantic's loc names the kind of a discriminated union by its tag)."""
    spot = Spot(annotation=root, node=raw)
    tp, metadata = root, []
    present = True
    steps = [(part, True) for part in loc] + [(part, False) for part in keys]
    index = 0
    while index < len(steps):
        part, tagged = steps[index]
        tp, metadata = _unwrap(tp, metadata)
        if _is_union(tp):  # a discriminated union: which kind is named by the tag, or by the document
            if tagged:
                index += 1
            else:
                by = _discriminator(metadata)
                node = spot.node if present else None
                part = by(node) if callable(by) else node.get(by) if isinstance(node, dict) else None
            tp = dict(_members(tp)).get(part, Any)
            metadata = []
            continue
        index += 1
        spot.parts.append(part)
        node = spot.node if present else None
        if _is_model(tp):
            name = next((n for n, f in tp.model_fields.items() if (f.alias or n) == part), None)
            spot.table, spot.declared = tp, tp.model_fields.get(name) if name else None
            order = list(tp.model_fields).index(name) if name else 0
            tp = spot.declared.annotation if spot.declared else Any
            metadata = list(spot.declared.metadata) if spot.declared else []
        else:
            spot.table, spot.declared, order = None, None, 0
            origin, args = get_origin(tp), get_args(tp)
            if origin is tuple and args and args[-1] is not Ellipsis:
                tp = args[part] if isinstance(part, int) and part < len(args) else Any
            elif origin in (tuple, list) and args:
                tp = args[0]
            elif origin is dict and args:
                tp = args[1]
            else:
                tp = Any
            metadata = []
        if isinstance(node, dict) and part in node:
            spot.position.append(list(node).index(part))
            spot.node = node[part]
        elif isinstance(node, (list, tuple)) and isinstance(part, int) and part < len(node):
            spot.position.append(part)
            spot.node = node[part]
        else:  # absent: after what is there, in the order of the fields
            spot.position.append((len(node) if isinstance(node, (dict, list)) else 0) + order)
            spot.node, present = None, False
    spot.annotation, spot.metadata = _unwrap(tp, metadata)
    return spot


def format_key(parts: list[str | int], prefix: str = "") -> str:
    """["boundary", 3, "value", 1] -> "boundary[3].value[1]"."""
    text = prefix
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _choices(tp: Any) -> list[Any] | None:
    if get_origin(tp) is Literal:
        return list(get_args(tp))
    if _is_union(tp):
        return [tag for tag, _ in _members(tp)]
    return None


def _plural(tp: Any) -> str:
    """What an array of ``tp`` holds, in words."""
    tp, _ = _unwrap(tp, [])
    if tp is float:
        return "numbers"
    if tp is int:
        return "integers"
    if tp is str:
        return "strings"
    if _is_model(tp) or _is_union(tp):
        return "tables"
    if get_origin(tp) in (tuple, list):
        return "arrays"
    return "values"


def _length(tp: Any, metadata: list[Any]) -> tuple[int | None, int | None]:
    """(fewest, most) entries an array may have."""
    args = get_args(tp)
    if get_origin(tp) is tuple and args and args[-1] is not Ellipsis:
        return len(args), len(args)
    low = next((m.min_length for m in metadata if isinstance(m, annotated_types.MinLen)), None)
    high = next((m.max_length for m in metadata if isinstance(m, annotated_types.MaxLen)), None)
    return low, high


def _explain(error: dict[str, Any], spot: Spot, root: Any) -> tuple[list[str | int], str]:
    """(key parts, message) of one pydantic error."""
    kind, value, ctx = error["type"], error.get("input"), error.get("ctx") or {}
    parts = list(spot.parts)
    wording: dict[str, str] = {}
    for m in spot.metadata:
        if isinstance(m, Wording):
            wording.update(m.messages)
    values = {"input": value, "typename": type(value).__name__,
              "length": len(value) if hasattr(value, "__len__") else 0,
              **{k: int(v) if isinstance(v, float) and v.is_integer() else v for k, v in ctx.items()}}
    if kind in wording:
        return parts, wording[kind].format(**values)
    tp = spot.annotation
    if kind == "config":
        return parts, ctx["message"]
    if kind == "missing":
        if len(parts) == 1 and spot.table is root:
            many = get_origin(_unwrap(spot.declared.annotation, [])[0]) is tuple if spot.declared else False
            return parts, f"missing: at least one [[{parts[0]}]]" if many else f"missing section [{parts[0]}]"
        choices = _choices(tp)
        hint = f"one of {', '.join(map(str, choices))}" if choices else meaning(spot.declared)
        return parts, f"missing ({hint})" if hint else "missing"
    if kind == "extra_forbidden":
        table = spot.table
        allowed = ", ".join(sorted(table.toml_keys())) if table is not None else ""
        what = "unknown section" if len(parts) == 1 and table is root else "unknown key"
        guess = closest(str(parts[-1]), table.toml_keys()) if table is not None and parts else None
        hint = f", did you mean {guess!r}?" if guess else ""
        return parts, f"{what}{hint} (allowed: {allowed})"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        by = _discriminator(spot.metadata)
        if not isinstance(value, dict):
            return parts, f"must be a table, got {type(value).__name__}"
        if isinstance(by, ByPresence):
            return parts, by.neither
        name = by.key if isinstance(by, By) else str(by)
        tags = ", ".join(str(t) for t, _ in _members(tp))
        if name not in value:
            return [*parts, name], f"missing (one of {tags})"
        given = value[name]
        if not isinstance(given, str):
            return [*parts, name], f"must be a string, got {given!r}"
        return [*parts, name], f"{given!r} is not one of {tags}{did_you_mean(given, [t for t, _ in _members(tp)])}"
    if kind == "literal_error":
        choices = _choices(tp) or []
        if choices and all(isinstance(c, str) for c in choices) and not isinstance(value, str):
            return parts, f"must be a string, got {value!r}"
        hint = did_you_mean(value, choices) if isinstance(value, str) else ""
        return parts, f"{value!r} is not one of {', '.join(map(str, choices))}{hint}"
    if kind in ("tuple_type", "list_type"):
        if isinstance(value, dict) and len(parts) == 1 and spot.table is root:
            return parts, f"must be an array of tables ([[{parts[0]}]]), got a single table ([{parts[0]}])"
        args = get_args(tp)
        return parts, f"must be an array of {_plural(args[0] if args else Any)}, got {value!r}"
    if kind in ("too_short", "too_long"):
        low, high = _length(tp, spot.metadata)
        count = values["length"]
        if low is not None and low == high:
            return parts, f"must have {low} {'entry' if low == 1 else 'entries'}, got {count}: {value!r}"
        if kind == "too_short":
            return parts, "must not be empty" if (low or 1) == 1 else f"must have at least {low} entries, got {count}"
        return parts, f"must have at most {high} entries, got {count}"
    if kind == "value_error":
        return parts, str(ctx.get("error", error["msg"])).splitlines()[0]
    if kind in _DEFAULTS:
        return parts, _DEFAULTS[kind].format(**values)
    return parts, error["msg"]


def _consequence(error: dict[str, Any]) -> bool:
    """An error that only follows from another one: a default computed from a field that failed, an array
    too short because some of its entries failed."""
    if error["type"] == "default_factory_not_called":
        return True
    value = error.get("input")
    return error["type"] == "too_short" and hasattr(value, "__len__") and \
        len(value) != (error.get("ctx") or {}).get("actual_length", len(value))


def translate(err: ValidationError, root: Any, raw: Any, prefix: str = "") -> ConfigError:
    """The ConfigError for the first of pydantic's errors in document order: "KEY: message" on one line."""
    best: tuple[list[int], str] | None = None
    errors = [e for e in err.errors(include_url=False) if not _consequence(e)] or err.errors(include_url=False)
    for error in errors:
        loc, ctx, keys = tuple(error["loc"]), error.get("ctx") or {}, ()
        if error["type"] == "config":
            loc, keys = loc[: len(loc) - ctx.get("up", 0)], tuple(ctx.get("key", ()))
        if error["type"] == "missing" and loc and isinstance(loc[-1], int):  # a fixed-length array too short
            loc, error = loc[:-1], {**error, "type": "too_short"}
        spot = locate(root, raw, loc, keys)
        parts, message = _explain(error, spot, root)
        line = f"{format_key(parts, prefix) or prefix or 'config'}: {message}".replace("\n", " ")
        if best is None or spot.position < best[0]:
            best = (spot.position, line)
    assert best is not None
    return ConfigError(best[1])


@functools.cache
def adapter(tp: Any) -> TypeAdapter:
    """The TypeAdapter of a type (built once)."""
    return TypeAdapter(tp)


def validate(tp: Any, raw: Any, prefix: str = "", context: dict[str, Any] | None = None) -> Any:
    """``raw`` validated as ``tp``; ConfigError naming the key (under ``prefix``) otherwise."""
    try:
        return adapter(tp).validate_python(raw, context=context)
    except ValidationError as err:
        raise translate(err, tp, raw, prefix) from None


__all__ = ["MAX_COORDINATE", "MAX_STEPS", "UNITS", "By", "ByPresence", "Coordinate", "ExistingFile", "Flag",
           "Integer", "Name", "NonNegative", "Number", "Point", "Position", "Positive", "Section", "Spot", "Text",
           "Variant", "Wording", "adapter", "base_folder", "count", "entries", "fail", "format_key", "interval", "key",
           "kinds", "locate", "meaning", "translate", "validate"]
