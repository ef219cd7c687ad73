"""[[contact]]: a checked contact table (run-contract.md, "Contact"), ContactSpec.

The surface name is checked against the mesh later (model.problem.contact.build_contact), still before
any solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from forms.obstacles import Capsule, Obstacle, Plane, Sphere, axis_of
from model.errors import ConfigError

METHODS = ("vi", "penalty")
OBSTACLES = ("plane", "sphere", "capsule")


@dataclass(frozen=True)
class ContactSpec:
    """A checked [[contact]] table (run-contract.md, "Contact")."""

    surface: str
    obstacle: Obstacle
    method: str
    penalty: float | None = None
    augmented: bool = False
    tolerance: float = 1e-8
    max_uzawa: int = 25
    quadrature_degree: int | str | None = None  # or "vertex": nodal quadrature, where the gaps are measured


_KEYS = {"plane": ("point", "normal"), "sphere": ("centre", "radius"), "capsule": ("a", "b", "radius")}
_COMMON = ("surface", "obstacle", "method", "penalty", "augmented", "tolerance", "max_uzawa", "quadrature_degree")


def parse_contact(raw: dict[str, Any], key: str) -> ContactSpec:
    """Check one [[contact]] table; ConfigError("KEY.NAME: message") for the first problem.

    Keys: surface (a boundary name; checked against the mesh by build_contact), obstacle
    (plane: point, normal; sphere: centre, radius; capsule: a, b, radius), method (vi | penalty),
    penalty (k > 0; penalty only), augmented (true: augmented Lagrangian with Uzawa updates;
    penalty only), tolerance (> 0, relative to the body size, default 1e-8) and max_uzawa
    (>= 1, default 25) (augmented only), quadrature_degree (>= 1; penalty only).
    """
    def fail(name: str, message: str) -> None:
        raise ConfigError(f"{key}.{name}: {message}")

    if not isinstance(raw, dict):
        raise ConfigError(f"{key}: must be a table, got {type(raw).__name__}")

    def number(name: str) -> float:
        value = raw[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            fail(name, f"must be a finite number, got {value!r}")
        return float(value)

    def vector(name: str) -> tuple[float, float, float]:
        value = raw[name]
        if not isinstance(value, list) or len(value) != 3:
            fail(name, f"must be an array of 3 numbers, got {value!r}")
        out = []
        for i, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                fail(f"{name}[{i}]", f"must be a finite number, got {v!r}")
            out.append(float(v))
        return (out[0], out[1], out[2])

    def required(name: str, what: str) -> None:
        if name not in raw:
            fail(name, f"missing ({what})")

    required("obstacle", f"one of {', '.join(OBSTACLES)}")
    kind = raw["obstacle"]
    if not isinstance(kind, str) or kind not in OBSTACLES:
        fail("obstacle", f"{kind!r} is not one of {', '.join(OBSTACLES)}")
    allowed = (*_COMMON, *_KEYS[kind])
    for name in raw:
        if name not in allowed:
            other = [o for o, keys in _KEYS.items() if name in keys]
            hint = f" for obstacle = {kind!r}" if other else ""
            fail(name, f"unknown key{hint} (allowed: {', '.join(sorted(allowed))})")
    required("surface", "the name of a boundary of the body")
    if not isinstance(raw["surface"], str) or not raw["surface"]:
        fail("surface", f"must be a boundary name, got {raw['surface']!r}")
    required("method", f"one of {', '.join(METHODS)}")
    method = raw["method"]
    if not isinstance(method, str) or method not in METHODS:
        fail("method", f"{method!r} is not one of {', '.join(METHODS)}")

    obstacle: Obstacle
    if kind == "plane":
        required("point", "a point of the plane")
        required("normal", "the plane's normal, pointing to the free side")
        point, normal = vector("point"), vector("normal")
        if not any(normal):
            fail("normal", "must not be zero")
        obstacle = Plane(point, normal)
    elif kind == "sphere":
        required("centre", "the sphere's centre")
        required("radius", "the sphere's radius")
        centre, radius = vector("centre"), number("radius")
        if radius <= 0:
            fail("radius", f"{radius} is out of range, must be > 0")
        obstacle = Sphere(centre, radius)
    else:
        for name, what in (("a", "one end of the capsule's segment"), ("b", "the other end"),
                           ("radius", "the capsule's radius")):
            required(name, what)
        a, b, radius = vector("a"), vector("b"), number("radius")
        if a == b:
            fail("b", "must differ from a")
        if radius <= 0:
            fail("radius", f"{radius} is out of range, must be > 0")
        obstacle = Capsule(a, b, radius)

    penalty_only = [n for n in ("penalty", "augmented", "tolerance", "max_uzawa", "quadrature_degree") if n in raw]
    if method == "vi":
        if penalty_only:
            fail(penalty_only[0], 'only used with method = "penalty"')
        if kind != "plane":
            fail("method", f'vi needs obstacle = "plane" (got {kind!r}); use method = "penalty"')
        try:
            axis_of(np.asarray(obstacle.normal), "normal")
        except ValueError:
            fail("normal", f"method = \"vi\" needs a normal along a coordinate axis (+-x, +-y, +-z), "
                           f"got {list(raw['normal'])}")
        return ContactSpec(raw["surface"], obstacle, method)

    required("penalty", "the penalty stiffness k (> 0), per unit reference area and unit penetration")
    k = number("penalty")
    if k <= 0:
        fail("penalty", f"{k} is out of range, must be > 0")
    augmented = raw.get("augmented", False)
    if not isinstance(augmented, bool):
        fail("augmented", f"must be true or false, got {augmented!r}")
    if not augmented:
        extra = [n for n in ("tolerance", "max_uzawa") if n in raw]
        if extra:
            fail(extra[0], "only used with augmented = true")
    tolerance = number("tolerance") if "tolerance" in raw else 1e-8
    if tolerance <= 0:
        fail("tolerance", f"{tolerance} is out of range, must be > 0")
    max_uzawa = raw.get("max_uzawa", 25)
    if isinstance(max_uzawa, bool) or not isinstance(max_uzawa, int):
        fail("max_uzawa", f"must be an integer, got {max_uzawa!r}")
    if max_uzawa < 1:
        fail("max_uzawa", f"{max_uzawa} is out of range, must be >= 1")
    quadrature = raw.get("quadrature_degree")
    if quadrature is not None and quadrature != "vertex" and (
            isinstance(quadrature, bool) or not isinstance(quadrature, int) or quadrature < 1):
        fail("quadrature_degree", f"must be an integer >= 1 or \"vertex\", got {quadrature!r}")
    return ContactSpec(raw["surface"], obstacle, method, k, augmented, tolerance, max_uzawa, quadrature)

