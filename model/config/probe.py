"""[[probe]]: points whose displacement is recorded at every step."""

from __future__ import annotations

from model.config.base import Name, Point, Section, key


class ProbeConfig(Section):
    """[[probe]]: a named point of the reference configuration; its displacement is written per step
    (summary.json). The point must lie in the mesh (checked when the mesh is read)."""

    name: Name = key("name of the probe in the results (unique)")
    point: Point = key("position [x, y, z] in the reference configuration", "m (length)")
