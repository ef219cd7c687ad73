"""[[probe]]: points whose displacement is recorded at every step."""

from __future__ import annotations

from model.config.base import Flag, Name, Position, Section, key


class ProbeConfig(Section):
    """[[probe]]: a named point of the reference configuration; its displacement is written per step
    (summary.json). The point must lie in the mesh (checked when the mesh is read): one outside is refused
    with its distance to the body and the body's nearest point, or moved there with ``snap = true``."""

    name: Name = key("name of the probe in the results (unique)")
    point: Position = key("position [x, y, z] in the reference configuration (each coordinate within +-1e9)",
                          "m (length)")
    snap: Flag = key("a point outside the body is moved to the nearest point of the body's surface (logged, "
                     "and recorded in summary.json's probe_points) instead of being refused", default=False)
