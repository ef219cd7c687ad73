"""[loading]: quasi-static load stepping of the load factor t from 0 to 1, with cut-backs."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from model.config.base import MAX_STEPS, Number, Point, Section, Text, count, key

#: the most halvings of a load step in a row
MAX_CUTBACKS = 50
Steps = count(1)
Cutbacks = count(0, MAX_CUTBACKS)


class LoadingConfig(Section):
    """[loading]: the load factor t goes from 0 to 1 in ``steps`` equal steps; a step that fails is halved (at
    most ``max_cutbacks`` times in a row) and the step grows again by ``growth`` after each success.

    ``control`` "arc_length" or "volume" makes the load factor an unknown (model.solvers.pathfollowing): arc
    length follows the equilibrium path through load maxima until the load factor reaches 1 (or ``max_steps``);
    volume control prescribes the volume of the cavity of the pressure boundary ``volume_boundary``, from its
    rest volume to ``volume_ratio`` times it in ``steps`` steps, and the pressure is the unknown."""

    steps: Steps = key(f"number of equal load steps from t = 0 to t = 1 (at most {MAX_STEPS})", default=1)
    max_cutbacks: Cutbacks = key(
        f"how many times in a row a failed step may be halved before the run gives up (at most {MAX_CUTBACKS}: "
        "2^-50 of a step is below the load factor's rounding)", default=8)
    growth: Annotated[Number, Field(ge=1)] = key(
        "factor by which the step grows after a converged cut-back step (up to the nominal step)", "dimensionless",
        default=1.5)
    control: Literal["load", "arc_length", "volume"] = key(
        "what drives the run: \"load\" (the load factor is prescribed: 0 to 1 in steps), \"arc_length\" (the load "
        "factor is an unknown, the path is followed past load maxima with Crisfield's arc length until it reaches "
        "1), \"volume\" (the cavity volume of volume_boundary is prescribed, its pressure is the unknown)",
        default="load")
    max_steps: Steps | None = key(
        "the most steps (converged and failed) the run may take before it stops as failed (bounded work: "
        "cut-backs and regrowth cannot go on for ever); default: 200 with control = \"arc_length\", "
        f"10 x steps + 100 otherwise (at most {MAX_STEPS})", default=None)
    volume_boundary: Text | None = key(
        "control = \"volume\": the boundary with the pressure whose cavity volume is prescribed", default=None)
    volume_ratio: Annotated[Number, Field(gt=0)] | None = key(
        "control = \"volume\": the final cavity volume over the rest volume", "dimensionless", default=None)
    volume_origin: Point = key(
        "control = \"volume\": a point on the planes that close the cavity (symmetry planes, a base plane): "
        "V = -(1/3) int (x - origin) . n da over volume_boundary", "length", default=(0.0, 0.0, 0.0))

    @property
    def step_cap(self) -> int:
        """max_steps, or its default: 200 steps of arc length, 10 x steps + 100 otherwise."""
        if self.max_steps is not None:
            return self.max_steps
        return 200 if self.control == "arc_length" else 10 * self.steps + 100
