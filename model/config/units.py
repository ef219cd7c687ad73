"""[units]: the consistent system of units the numbers of a run are in; it names units, it converts nothing.

Any consistent system works (the equations have no built-in constants); ``system`` says which one the
configuration uses, so that results are labelled with their units (summary.json, the PNG's colour bar)
and the scale check can tell a mesh in mm from one in m. The two systems in use:

    SI:      m, Pa, N, s, kg/m^3, J            (the examples but two)
    mm-MPa:  mm, MPa = N/mm^2, N, s, tonne/mm^3, mJ = N mm   (examples/isometric_mm.toml, examples/cook.toml)
"""

from __future__ import annotations

from typing import Literal

from model.config.base import Section, key

#: dimension -> unit name, per system (the dimensions of the configuration reference's unit column)
SYSTEMS: dict[str, dict[str, str]] = {
    "SI": {"length": "m", "stress": "Pa", "force": "N", "time": "s", "mass density": "kg/m^3", "energy": "J",
           "stress per length": "Pa/m", "force per volume": "N/m^3", "volume": "m^3", "area": "m^2",
           "angle": "rad", "dimensionless": "1"},
    "mm-MPa": {"length": "mm", "stress": "MPa", "force": "N", "time": "s", "mass density": "tonne/mm^3",
               "energy": "mJ", "stress per length": "MPa/mm", "force per volume": "N/mm^3", "volume": "mm^3",
               "area": "mm^2", "angle": "rad", "dimensionless": "1"},
}


class UnitsConfig(Section):
    """[units]: the system of units of every number in the file (labels only: nothing is converted)."""

    system: Literal["SI", "mm-MPa"] = key(
        "\"SI\" (m, Pa, N, s, kg/m^3) or \"mm-MPa\" (mm, MPa, N, s, tonne/mm^3); used to label results and by "
        "the scale check, nothing is converted", default="SI")

    def unit(self, dimension: str) -> str:
        """The unit of ``dimension`` ("length", "stress", "force", "energy", ...) in this system."""
        return SYSTEMS[self.system][dimension]


__all__ = ["SYSTEMS", "UnitsConfig"]
