"""[discretization]: the finite element space of the displacement (and pressure) and the quadrature."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Discriminator, Field, Tag, model_validator

from model.config.base import Integer, Section, Wording, fail, key

FORMULATIONS = ("displacement", "mixed")
#: an integer degree 1..12, or "auto" (model.problem.elasticity.quadrature_degrees)
EnergyQuadrature = Annotated[
    Annotated[Annotated[Integer, Field(ge=1, le=12)], Tag("degree")] | Annotated[Literal["auto"], Tag("auto")],
    Discriminator(lambda v: "auto" if isinstance(v, str) else "degree"),
]
_ONE_TWO_THREE = Wording(less_than_equal="{input} is out of range, must be 1, 2 or 3")


class DiscretizationConfig(Section):
    """[discretization]: Lagrange elements of ``degree`` on tetrahedra; "mixed" adds a pressure one degree
    lower (Taylor-Hood P2/P1, for nearly incompressible laws)."""

    degree: Annotated[Integer, Field(ge=1, le=3), _ONE_TWO_THREE] = key(
        "polynomial degree of the displacement's Lagrange elements", default=1)
    quadrature_degree: EnergyQuadrature = key(
        "degree of the quadrature rule of every integral, or \"auto\": the materials' energy with degree 1 (one "
        "point, exact) for degree = 1 and 2 x degree otherwise, loads and inertia with 2 x degree",
        default="auto")
    formulation: Literal[FORMULATIONS] = key(
        "displacement only, or mixed displacement-pressure (Taylor-Hood; needs degree >= 2)", default="displacement")

    @model_validator(mode="after")
    def _taylor_hood(self) -> DiscretizationConfig:
        if self.formulation == "mixed" and self.degree < 2:
            fail("mixed (Taylor-Hood) needs degree >= 2", "formulation")
        return self
