"""[[bone]]: a rigid body with a prescribed motion and, optionally, a shape (an analytic obstacle).

The shape keys (``obstacle`` with point, normal / centre, radius / a, b, radius) are shared with
[[contact]] (model.config.contact).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Discriminator, Field, PlainValidator, PrivateAttr, Tag, ValidationInfo, model_validator

from forms.motions import HingeMotion, Stationary, TransformTable
from forms.obstacles import Capsule, Obstacle, Plane, Sphere
from model.config.base import Name, Number, Point, Positive, Section, Wording, entries, fail, key
from model.errors import did_you_mean

# --- shapes ----------------------------------------------------------------------------------------------------------

#: the keys of each obstacle shape
SHAPE_KEYS = {"plane": ("point", "normal"), "sphere": ("centre", "radius"), "capsule": ("a", "b", "radius")}
ALL_SHAPE_KEYS = ("point", "normal", "centre", "radius", "a", "b")


def _obstacle(kind: Any, info: ValidationInfo) -> Obstacle | None:
    """The obstacle ``kind`` built from the shape keys (validated before it, in info.data)."""
    if isinstance(kind, (Plane, Sphere, Capsule)):
        return kind
    if not isinstance(kind, str):
        fail(f"must be a string, got {kind!r}")
    if kind not in SHAPE_KEYS:
        fail(f"{kind!r} is not one of {', '.join(SHAPE_KEYS)}{did_you_mean(kind, SHAPE_KEYS)}")
    data = info.data
    if any(k not in data for k in ALL_SHAPE_KEYS):
        return None  # a shape key is wrong: its own error is reported
    needed = SHAPE_KEYS[kind]
    for k in ALL_SHAPE_KEYS:
        if data[k] is not None and k not in needed:
            fail(f"unknown key for obstacle = {kind!r} (allowed: {', '.join(needed)})", k, up=1)
    for k in needed:
        if data[k] is None:
            fail(f"missing (obstacle = {kind!r} needs {', '.join(needed)})", k, up=1)
    if kind == "plane":
        if not any(data["normal"]):
            fail("must not be zero", "normal", up=1)
        return Plane(data["point"], data["normal"])
    if kind == "sphere":
        return Sphere(data["centre"], data["radius"])
    if data["a"] == data["b"]:
        fail("must differ from a", "b", up=1)
    return Capsule(data["a"], data["b"], data["radius"])


#: ``obstacle``: after validation, the forms.obstacles object built from the shape keys
ObstacleField = Annotated[Obstacle | None, PlainValidator(_obstacle, json_schema_input_type=Literal[
    "plane", "sphere", "capsule"])]


def shape_keys_schema(schema: dict[str, Any]) -> None:
    """JSON schema: each obstacle kind needs its shape keys and refuses the others."""
    schema.setdefault("allOf", []).extend(
        {"if": {"properties": {"obstacle": {"const": kind}}, "required": ["obstacle"]},
         "then": {"required": list(keys),
                  "properties": {k: False for k in ALL_SHAPE_KEYS if k not in keys}}}
        for kind, keys in SHAPE_KEYS.items())


# --- motions ---------------------------------------------------------------------------------------------------------

AngleRow = Annotated[tuple[Number, Number], entries(2, " (time, degrees)")]
_ANGLES = "must be a table [[t0, degrees0], [t1, degrees1], ...]"


class Hinge(Section):
    """bone.hinge: a rotation about the fixed axis through ``point`` by the angle theta(t), piecewise linear in a
    table of (t, degrees); the axis' points stay put."""

    axis: Point = key("direction of the rotation axis (right-handed), not zero", "dimensionless")
    point: Point = key("a point of the axis", "m (length)")
    angles: Annotated[tuple[AngleRow, ...], Field(min_length=1), Wording(too_short=_ANGLES, tuple_type=_ANGLES)] = \
        key("[[t, degrees], ...]: the angle against t (the load factor, or time in s), times increasing; "
            "constant beyond the ends", "degrees (angle)")
    _motion: Any = PrivateAttr(None)

    @model_validator(mode="after")
    def _build(self) -> Hinge:
        if not any(self.axis):
            fail("must not be zero", "axis")
        for i in range(1, len(self.angles)):
            if self.angles[i][0] <= self.angles[i - 1][0]:
                fail(f"times must increase, got {self.angles[i][0]} after {self.angles[i - 1][0]}", "angles", i, 0)
        self._motion = HingeMotion(self.axis, self.point, self.angles)
        return self

    @property
    def motion(self) -> HingeMotion:
        return self._motion


def _rotation_kind(value: Any) -> str:
    matrix = isinstance(value, (list, tuple)) and value and all(isinstance(r, (list, tuple)) for r in value)
    return "matrix" if matrix else "vector"


Rotation = Annotated[
    Annotated[Annotated[tuple[Number, Number, Number], entries(3, " (a rotation vector in radians)")], Tag("vector")]
    | Annotated[tuple[Point, Point, Point], entries(3, " (the rows of a rotation matrix)"), Tag("matrix")],
    Discriminator(_rotation_kind),
]
_PER_TIME = "missing or empty (one entry per time)"


class Transform(Section):
    """bone.transform: keyframes (t_i, Q_i, c_i) of x = Q X + c; between them the rotation turns at constant speed
    about a fixed axis (slerp) and the translation is linear; constant beyond the ends."""

    times: Annotated[tuple[Number, ...], Field(min_length=1), Wording(too_short=_PER_TIME)] = key(
        "the key times (load factor, or time in s), increasing", "s (time) in a dynamic run, else dimensionless "
        "(the load factor)")
    rotations: Annotated[tuple[Rotation, ...], Field(min_length=1), Wording(too_short=_PER_TIME)] = key(
        "per time: a rotation vector (axis times angle, in radians) or a 3x3 rotation matrix", "rad (angle)")
    translations: Annotated[tuple[Point, ...], Field(min_length=1), Wording(too_short=_PER_TIME)] = key(
        "per time: the translation c", "m (length)")
    _motion: Any = PrivateAttr(None)

    @model_validator(mode="after")
    def _build(self) -> Transform:
        for k in ("rotations", "translations"):
            if len(getattr(self, k)) != len(self.times):
                fail(f"needs one entry per time ({len(self.times)}), got {len(getattr(self, k))}", k)
        try:
            self._motion = TransformTable(self.times, self.rotations, self.translations)
        except ValueError as err:
            fail(str(err).removeprefix("transform table: "))
        return self

    @property
    def motion(self) -> TransformTable:
        return self._motion


# --- the table -------------------------------------------------------------------------------------------------------

class BoneConfig(Section):
    """[[bone]]: a rigid body with a name, a prescribed motion (``hinge`` or ``transform``; none: it stays put) and
    optionally a shape (``obstacle`` with its keys, the shape at t = 0) that boundaries slide on and contacts
    press against."""

    model_config = {"json_schema_extra": shape_keys_schema}

    name: Name = key("name of the bone, used by [[boundary]] bone = ... and [[contact]] bone = ... (unique)")
    hinge: Hinge | None = key("motion: rotation about a fixed axis", default=None)
    transform: Transform | None = key("motion: keyframed rotations and translations", default=None)
    point: Point | None = key("obstacle = \"plane\": a point of the plane", "m (length)", default=None)
    normal: Point | None = key("obstacle = \"plane\": the plane's normal, pointing to the free side",
                               "dimensionless", default=None)
    centre: Point | None = key("obstacle = \"sphere\": the centre", "m (length)", default=None)
    radius: Positive | None = key("obstacle = \"sphere\" or \"capsule\": the radius", "m (length)", default=None)
    a: Point | None = key("obstacle = \"capsule\": one end of the capsule's segment", "m (length)", default=None)
    b: Point | None = key("obstacle = \"capsule\": the other end", "m (length)", default=None)
    obstacle: ObstacleField = key("the bone's shape (with its keys above); after validation the obstacle itself",
                                  default=None)
    _shape: dict[str, Any] = PrivateAttr(default_factory=dict)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_shape_keys(cls, data: Any, handler: Any) -> BoneConfig:
        """Keep the shape's keys as written, for the contacts on this bone (which check them again)."""
        bone = handler(data)
        if isinstance(data, dict) and bone.obstacle is not None:
            bone._shape = {k: data[k] for k in ("obstacle", *SHAPE_KEYS[data["obstacle"]])}
        return bone

    @model_validator(mode="after")
    def _one_motion_and_a_shape(self) -> BoneConfig:
        if self.hinge is not None and self.transform is not None:
            fail("give one of hinge or transform, not both", "transform")
        if self.obstacle is None:
            for k in ALL_SHAPE_KEYS:
                if getattr(self, k) is not None:
                    fail("only applies with obstacle = \"plane\" | \"sphere\" | \"capsule\"", k)
        return self

    @property
    def motion(self) -> Any:
        """The rigid motion t -> (Q, c): forms.motions HingeMotion, TransformTable or Stationary."""
        if self.hinge is not None:
            return self.hinge.motion
        if self.transform is not None:
            return self.transform.motion
        return Stationary()

    @property
    def shape(self) -> dict[str, Any]:
        """The shape's keys as written (obstacle and its keys; {} without a shape), for contacts on this bone."""
        return dict(self._shape)


__all__ = ["ALL_SHAPE_KEYS", "SHAPE_KEYS", "BoneConfig", "Hinge", "ObstacleField", "Transform", "shape_keys_schema"]
