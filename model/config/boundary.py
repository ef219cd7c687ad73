"""[[boundary]]: a condition on a named boundary (facet group), by ``type``."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Discriminator, Field, Tag, ValidationInfo, field_validator, model_validator

from model.config.base import (
    By,
    Integer,
    Name,
    Number,
    Point,
    Positive,
    Text,
    Variant,
    Wording,
    entries,
    fail,
    key,
    kinds,
)

BOUNDARY_TYPES = ("displacement", "traction", "pressure", "attached", "sliding")
_BONE_TYPES = ("attached", "sliding")


def _components(value: tuple[int, ...]) -> tuple[int, ...]:
    if any(c not in (0, 1, 2) for c in value) or len(set(value)) != len(value):
        fail(f"{list(value)} must be distinct entries of 0, 1, 2")
    return value


_COMPONENTS_SCHEMA = {"items": {"enum": [0, 1, 2]}, "uniqueItems": True, "maxItems": 3}
Components = Annotated[
    tuple[Integer, ...], Field(min_length=1),
    Wording(too_short="must be a non-empty array of 0, 1, 2, got {input!r}",
            tuple_type="must be a non-empty array of 0, 1, 2, got {input!r}"),
]


def _compiled(expressions: tuple[str, ...], parameters: dict[str, float]) -> tuple[str, ...]:
    from model.config.expressions import compile_expression

    for i, text in enumerate(expressions):
        try:
            compile_expression(text, parameters)
        except ValueError as err:
            fail(str(err), i)
    return expressions


QuadratureDegree = Annotated[
    Annotated[Annotated[Integer, Field(ge=1, le=12)], Tag("degree")] | Annotated[Literal["vertex"], Tag("vertex")],
    Discriminator(lambda v: "vertex" if isinstance(v, str) else "degree"),
]


class BoundaryConfig(Variant):
    """[[boundary]]: a condition on the boundary ``on`` (a facet group of the mesh), by ``type``; loads and
    prescribed values are scaled by the load factor (or ramped in time: [dynamics] load_ramp)."""

    on: Name = key("name of the boundary (facet group) the condition acts on")
    type: str = key("the kind of condition")
    components: tuple[int, ...] = key("displacement components it prescribes (0: x, 1: y, 2: z)", default=())
    value: tuple[float, ...] = key("prescribed values; their unit depends on type",
                                   "by type: m (displacement), Pa (traction, pressure)", default=())
    expression: tuple[str, ...] = key("prescribed values as expressions of x and t", "m (length)", default=())
    points: tuple[tuple[float, ...], ...] = key("restrict to the boundary's nodes at these points", "m (length)",
                                                default=())
    bone: Name | None = key("name of the [[bone]] the boundary moves with", default=None)
    penalty: Positive | None = key("sliding stiffness k per unit reference area and unit gap",
                                   "Pa/m (stress per length)", default=None)
    quadrature_degree: QuadratureDegree | None = key("quadrature of the sliding energy", default=None)

    @classmethod
    def not_applicable(cls, key: str) -> str:
        if cls.kind() in _BONE_TYPES and key in ("components", "value", "expression", "points"):
            return f"does not apply to type = {cls.kind()!r} (the bone's motion gives the data)"
        return super().not_applicable(key)


class DisplacementBoundary(BoundaryConfig):
    """type = "displacement": u_i = value_i (or expression_i(x, t)) on the boundary for i in ``components``."""

    model_config = {"json_schema_extra": {"oneOf": [{"required": ["value"]}, {"required": ["expression"]}]}}
    keys = ("on", "type", "components", "value", "expression", "points")
    type: Literal["displacement"] = key("prescribed displacement components (Dirichlet)")
    components: Components = key("the displacement components prescribed (0: x, 1: y, 2: z), distinct",
                                 default=(0, 1, 2), json_schema_extra=_COMPONENTS_SCHEMA)
    value: Annotated[tuple[Number, ...], Field(min_length=1)] = key(
        "the prescribed displacements, one per entry of components (scaled by the load factor); or give "
        "expression (value's unit depends on type: a length here)", "m (length)", default=(), silent=True)
    expression: Annotated[tuple[Text, ...], Field(min_length=1)] = key(
        "the prescribed displacements as expressions of x[0], x[1], x[2] and t (model.config.expressions), one "
        "per entry of components; without t they are scaled by the load factor", "m (length)", default=(),
        silent=True)
    points: Annotated[tuple[Point, ...], Field(min_length=1),
                      Wording(too_short="must be a non-empty array of points [[x, y, z], ...], got {input!r}")] = key(
        "prescribe only at the boundary's nodes at these points (default: at all its nodes; e.g. to stop "
        "rigid-body modes)", "m (length)", default=(), silent=True)

    @field_validator("components", mode="after")
    @classmethod
    def _check_components(cls, value: tuple[int, ...]) -> tuple[int, ...]:
        return _components(value)

    @field_validator("expression", mode="after")
    @classmethod
    def _check_expressions(cls, value: tuple[str, ...], info: ValidationInfo) -> tuple[str, ...]:
        return _compiled(value, (info.context or {}).get("parameters", {}))

    @model_validator(mode="after")
    def _one_per_component(self) -> DisplacementBoundary:
        given = self.model_fields_set
        if ("value" in given) == ("expression" in given):
            fail("give exactly one of value or expression", "value")
        n = len(self.components)
        if "value" in given and len(self.value) != n:
            fail(f"must have {n} {'entry' if n == 1 else 'entries'} (one per entry of components "
                 f"{list(self.components)}), got {len(self.value)}: {list(self.value)!r}", "value")
        if "expression" in given and len(self.expression) != n:
            fail(f"must be an array of {n} strings (one per component)", "expression")
        return self


class TractionBoundary(BoundaryConfig):
    """type = "traction": a dead load per unit reference area, scaled by the load factor."""

    keys = ("on", "type", "value")
    type: Literal["traction"] = key("a traction (Neumann)")
    value: Point = key("traction per unit reference area [tx, ty, tz] (value's unit depends on type: a stress here)",
                       "Pa (stress)")


def _pressure(value: Any) -> tuple[float]:
    return value if isinstance(value, tuple) else (value,)


class PressureBoundary(BoundaryConfig):
    """type = "pressure": a follower pressure p on the deformed surface (p > 0 pushes inwards), scaled by the
    load factor."""

    keys = ("on", "type", "value")
    type: Literal["pressure"] = key("a pressure (follower load)")
    value: Annotated[
        Annotated[Number, Tag("number")] | Annotated[tuple[Number], entries(1), Tag("array")],
        Discriminator(lambda v: "array" if isinstance(v, (list, tuple)) else "number"),
    ] = key("the pressure p (a number, or an array of one number; value's unit depends on type: a stress "
              "here)", "Pa (stress)")

    @field_validator("value", mode="after")
    @classmethod
    def _one_value(cls, value: Any) -> tuple[float]:
        return _pressure(value)


class AttachedBoundary(BoundaryConfig):
    """type = "attached": the boundary moves rigidly with a bone (u = Q(t) X + c(t) - X)."""

    keys = ("on", "type", "bone")
    type: Literal["attached"] = key("glued to a bone")
    bone: Name = key("name of the [[bone]] the boundary is attached to")


class SlidingBoundary(BoundaryConfig):
    """type = "sliding": the boundary stays on a bone's surface (penalty (k/2) g^2), free to slide along it."""

    keys = ("on", "type", "bone", "penalty", "quadrature_degree")
    type: Literal["sliding"] = key("kept on a bone's surface, frictionless")
    bone: Name = key("name of the [[bone]] (with a shape) the boundary slides on")
    penalty: Positive = key("the sliding stiffness k > 0, per unit reference area and unit gap",
                            "Pa/m (stress per length)")
    quadrature_degree: QuadratureDegree | None = key(
        "quadrature degree of the sliding energy (default: discretization.quadrature_degree), or \"vertex\": "
        "the nodal rule (P1 only)", default=None)


Boundary = kinds(DisplacementBoundary, TractionBoundary, PressureBoundary, AttachedBoundary, SlidingBoundary,
                 by=By("type"))

__all__ = ["BOUNDARY_TYPES", "AttachedBoundary", "Boundary", "BoundaryConfig", "DisplacementBoundary",
           "PressureBoundary", "SlidingBoundary", "TractionBoundary"]
