"""[[body_force]]: a dead load per unit reference volume."""

from __future__ import annotations

from model.config.base import Name, Point, Section, key


class BodyForceConfig(Section):
    """[[body_force]]: a force per unit reference volume on a region, scaled by the load factor (e.g. gravity
    rho g)."""

    region: Name = key("the region it acts on (\"all\": the whole body)", default="all")
    value: Point = key("force per unit reference volume [fx, fy, fz], 3 numbers", "N/m^3 (force per volume)")
