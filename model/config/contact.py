"""[[contact]]: frictionless contact of a boundary of the body with a rigid obstacle, or of two bodies (ContactSpec).

With ``self_contact`` = true the surface is its own master (model.problem.self_contact.SelfContact: penalty,
optionally augmented; ``rings`` and ``reach`` set which of its triangles a node may pair with).
With ``master`` (a boundary of another body of the same mesh) the contact is between deformable bodies
(model.problem.body_contact.BodyContact: penalty, optionally augmented Lagrangian, or ``sliding`` = true, the
thesis' zero-length normal springs); ``master`` excludes ``obstacle``, ``bone`` and the shape keys.

The surface (and master) names are checked against the mesh later (model.problem.contact.build_contact), still
before any solve; ``bone`` against the [[bone]] tables and P1 (contact between bodies) by model.config.document.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import model_validator

from forms.obstacles import Plane, axis_of
from model.config.base import By, Flag, Name, Point, Positive, Variant, count, fail, key, kinds, validate
from model.config.bone import ALL_SHAPE_KEYS, ObstacleField, shape_keys_schema
from model.config.boundary import QuadratureDegree

METHODS = ("vi", "penalty")
OBSTACLES = ("plane", "sphere", "capsule")


def _contact_schema(schema: dict[str, Any]) -> None:
    """The obstacle's keys by kind; a contact on a bone may leave them out (it takes the bone's shape)."""
    shape_keys_schema(schema)
    schema["required"] = [k for k in schema.get("required", []) if k != "obstacle"]
    schema["anyOf"] = [{"required": ["obstacle"]}, {"required": ["bone"]}, {"required": ["master"]},
                       {"required": ["self_contact"]}]
    schema.setdefault("allOf", []).append(
        {"if": {"required": ["master"]},
         "then": {"properties": {k: False for k in ("obstacle", "bone", *ALL_SHAPE_KEYS)}},
         "else": {"properties": {"sliding": False, "smooth_normals": False}}})
    schema["allOf"].append({"if": {"not": {"anyOf": [{"required": ["master"]}, {"required": ["self_contact"]}]}},
                            "then": {"properties": {"exact": False}}})


class ContactSpec(Variant):
    """[[contact]]: the boundary ``surface`` of the body stays on the free side of a rigid obstacle: exactly
    (method = "vi", a plane along a coordinate axis) or by a penalty (method = "penalty", optionally
    augmented Lagrangian). The obstacle is given by its keys, or is the shape of ``bone`` (and moves with it).
    With ``master`` instead: contact (or, ``sliding`` = true, sliding) of the surface on the boundary ``master``
    of another body of the same mesh (method = "penalty", P1)."""

    model_config = {"json_schema_extra": _contact_schema}
    kind_key = "method"

    surface: Name = key("name of the boundary of the body that touches the obstacle (with master: the slave "
                        "boundary, whose nodes are checked against master)")
    method: str = key("how non-penetration is enforced")
    master: Name | None = key("name of a boundary of another body of the same mesh: contact between deformable "
                              "bodies (surface's nodes against master's deformed triangles; no obstacle or bone)",
                              default=None)
    sliding: Flag = key("master only: the surface stays on master and slides along it (zero-length normal "
                        "springs, (k/2) g^2; false: contact, (k/2) min(g, 0)^2)", default=False)
    exact: Flag = key("master or self_contact only: every derivative of the energy taken by UFL, the paired "
                      "triangle's rotation included (a consistent potential: backtracking on it; docs/layers.md): "
                      "sliding (k/2) d^2, d the distance to master's deformed triangles; contact (k/2) min(g, 0)^2, "
                      "g the signed distance to the paired triangle's plane (not with augmented)", default=False)
    smooth_normals: Flag | None = key(
        "master only: the gap along master's interpolated nodal normals (area-weighted, continuous across its "
        "edges) instead of the paired triangle's own; default: on for sliding, off for contact; no consistent "
        "potential, so Newton takes full steps unless snes_linesearch_type is set (\"l2\" for the twin muscles; "
        "docs/layers.md); not with exact", default=None)
    self_contact: Flag = key("the surface against itself (self-contact of one body: its nodes against its own deformed "
                             "triangles outside their neighbourhood, facing them; no master, obstacle or bone; "
                             "docs/layers.md)", default=False)
    rings: count(1, 1000) | None = key(
        "self_contact only: a node never pairs with a triangle that has a vertex within rings - 1 edges of it "
        "(default 2)", default=None)
    reach: Positive | None = key("self_contact only: the farthest master point a node pairs with (default: the "
                                 "surface's mean edge length at rest)", "m (length)", default=None)
    bone: Name | None = key("name of a [[bone]]: the obstacle moves with it (and is its shape when obstacle is not "
                            "given)", default=None)
    penalty: Positive | None = key("penalty stiffness k per unit reference area and unit penetration",
                                   "Pa/m (stress per length)", default=None)
    augmented: Flag = key("augmented Lagrangian: Uzawa updates of the contact pressure until the penetration is "
                          "below tolerance", default=False)
    tolerance: Positive = key("augmented only: largest penetration, relative to the body's size",
                              "dimensionless", default=1e-8)
    max_uzawa: count(1) = key("augmented only: most Uzawa updates per load step", default=25)
    quadrature_degree: QuadratureDegree | None = key(
        "quadrature degree of the contact energy (default: discretization.quadrature_degree), or \"vertex\": the "
        "nodal rule, where the gaps are measured (P1 only)", default=None)
    point: Point | None = key("obstacle = \"plane\": a point of the plane", "m (length)", default=None)
    normal: Point | None = key("obstacle = \"plane\": the plane's normal, pointing to the free side",
                               "dimensionless", default=None)
    centre: Point | None = key("obstacle = \"sphere\": the centre", "m (length)", default=None)
    radius: Positive | None = key("obstacle = \"sphere\" or \"capsule\": the radius", "m (length)", default=None)
    a: Point | None = key("obstacle = \"capsule\": one end of the capsule's segment", "m (length)", default=None)
    b: Point | None = key("obstacle = \"capsule\": the other end", "m (length)", default=None)
    obstacle: ObstacleField = key("the obstacle's shape (with its keys above); after validation the obstacle itself",
                                  default=None)

    @model_validator(mode="before")
    @classmethod
    def _master_or_obstacle(cls, data: Any) -> Any:
        """master excludes the obstacle, its bone and its shape keys; without master an obstacle (or bone)."""
        if isinstance(data, dict):
            if data.get("self_contact") is True:
                if data.get("method", "penalty") != "penalty":
                    fail(f"self-contact needs method = \"penalty\", not {data['method']!r}", "method")
                for k in ("master", "sliding", "smooth_normals", "bone", "obstacle", *ALL_SHAPE_KEYS):
                    if k in data:
                        fail("not with self_contact = true (the surface is its own master)", k)
                if data.get("exact") is True and data.get("augmented") is True:
                    fail("not with exact = true (exact contact is the penalty only)", "augmented")
                if data.get("quadrature_degree", "vertex") != "vertex":
                    fail("self-contact always uses the nodal rule (\"vertex\"): leave it out", "quadrature_degree")
                return data
            for k in ("rings", "reach"):
                if k in data:
                    fail("only with self_contact = true", k)
            if "master" in data:
                if data.get("method", "penalty") != "penalty":
                    fail(f"contact between bodies (master) needs method = \"penalty\", not {data['method']!r}",
                         "method")
                for k in ("bone", "obstacle", *ALL_SHAPE_KEYS):
                    if k in data:
                        fail("not with master (contact between two bodies has no rigid obstacle)", k)
            else:
                for k in ("sliding", "exact"):
                    if k in data:
                        fail("only with master = \"<boundary of another body>\" or self_contact = true (between "
                             "deformable surfaces)", k)
                if "smooth_normals" in data:
                    fail("only with master = \"<boundary of another body>\" (the master's nodal normals)",
                         "smooth_normals")
                if "obstacle" not in data and "bone" not in data:
                    fail("missing (give obstacle = \"plane\" | \"sphere\" | \"capsule\", a bone, or master = a "
                         "boundary of another body)", "obstacle")
        return data

    @model_validator(mode="after")
    def _between_bodies(self) -> ContactSpec:
        if self.master is None:
            return self
        if self.exact and self.augmented:
            fail("not with exact = true (exact contact is the penalty only)", "augmented")
        if self.exact and self.smooth_normals:
            fail("not with exact = true (the exact energies use the paired triangle itself: no normal to smooth)",
                 "smooth_normals")
        if self.master == self.surface:
            fail(f"must differ from surface ({self.surface!r}): contact between two bodies' boundaries", "master")
        if self.sliding and self.augmented:
            fail("not with sliding = true (the sliding springs hold both ways; Uzawa updates are for contact)",
                 "augmented")
        if self.quadrature_degree not in (None, "vertex"):
            fail("contact between bodies always uses the nodal rule (\"vertex\"): leave it out", "quadrature_degree")
        return self

    @property
    def spec(self) -> ContactSpec:
        """The contact's specification (the table itself; ContactConfig.spec of the pipeline)."""
        return self


_SHAPE_AND_COMMON = ("surface", "method", "bone", *ALL_SHAPE_KEYS, "obstacle")


class VIContact(ContactSpec):
    """method = "vi": exact non-penetration of the surface nodes (SNES vinewtonrsls), against a plane whose normal
    is along a coordinate axis."""

    keys = _SHAPE_AND_COMMON
    method: Literal["vi"] = key("bounds on the normal displacement of the surface nodes (variational inequality)")

    @model_validator(mode="after")
    def _axis_plane(self) -> VIContact:
        if self.obstacle is None:
            return self
        if not isinstance(self.obstacle, Plane):
            kind = type(self.obstacle).__name__.lower()
            fail(f"vi needs obstacle = \"plane\" (got {kind!r}); use method = \"penalty\"", "method")
        try:
            axis_of(np.asarray(self.obstacle.normal), "normal")
        except ValueError:
            fail("method = \"vi\" needs a normal along a coordinate axis (+-x, +-y, +-z), "
                 f"got {list(self.normal or ())}", "normal")
        return self


class PenaltyContact(ContactSpec):
    """method = "penalty": the energy (k/2) min(g, 0)^2 per unit reference area (g the gap), or with
    augmented = true its augmented Lagrangian with Uzawa updates."""

    keys = (*_SHAPE_AND_COMMON, "master", "sliding", "exact", "smooth_normals", "self_contact", "rings", "reach",
            "penalty", "augmented", "tolerance", "max_uzawa",
            "quadrature_degree")
    method: Literal["penalty"] = key("a penalty energy on the penetration")
    penalty: Positive = key("the penalty stiffness k > 0, per unit reference area and unit penetration",
                            "Pa/m (stress per length)")

    @model_validator(mode="after")
    def _augmented_keys(self) -> PenaltyContact:
        if not self.augmented:
            for k in ("tolerance", "max_uzawa"):
                if k in self.model_fields_set:
                    fail("only used with augmented = true", k)
        return self


Contact = kinds(VIContact, PenaltyContact, by=By("method"))
#: a [[contact]] table: its ContactSpec is itself (``.spec``), ``.bone`` the bone its obstacle moves with
ContactConfig = ContactSpec


def parse_contact(raw: Any, key: str) -> ContactSpec:
    """Check one [[contact]] table; ConfigError("KEY.NAME: message") for the first problem."""
    return validate(Contact, raw, key)


__all__ = ["METHODS", "OBSTACLES", "Contact", "ContactConfig", "ContactSpec", "PenaltyContact", "VIContact",
           "parse_contact"]
