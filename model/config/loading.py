"""[loading]: quasi-static load stepping of the load factor t from 0 to 1, with cut-backs."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from model.config.base import Integer, Number, Section, key


class LoadingConfig(Section):
    """[loading]: the load factor t goes from 0 to 1 in ``steps`` equal steps; a step that fails is halved (at
    most ``max_cutbacks`` times in a row) and the step grows again by ``growth`` after each success."""

    steps: Annotated[Integer, Field(ge=1)] = key("number of equal load steps from t = 0 to t = 1", default=1)
    max_cutbacks: Annotated[Integer, Field(ge=0)] = key(
        "how many times in a row a failed step may be halved before the run gives up", default=8)
    growth: Annotated[Number, Field(ge=1)] = key(
        "factor by which the step grows after a converged cut-back step (up to the nominal step)", "dimensionless",
        default=1.5)
