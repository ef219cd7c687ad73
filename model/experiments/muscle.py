"""The standard muscle experiments as functions of run configurations and summaries.

Used by the tests, the notebooks and the benchmarks, so that all three read the same numbers:

- force-length (examples/force_length_*.toml): the load factor 0 -> 0.5 stretches the body to
  l = parameters.stretch times its length passively, 0.5 -> 1 activates it at that length; the active force is the
  reaction at t = 1 minus the reaction at t = 0.5 (same stretch);
- isometric contraction (examples/isometric.toml): activation, mid-belly bulge, volume change of
  the belly and tendon force per step.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from forms.muscle import Muscle


def f_active(s: float) -> float:
    """The active force-length curve of energies.md (s = lbar / l_ofl)."""
    if 0.4 < s <= 0.6:
        return 9.0 * (s - 0.4) ** 2
    if 0.6 < s < 1.4:
        return 1.0 - 4.0 * (1.0 - s) ** 2
    if 1.4 <= s < 1.6:
        return 9.0 * (s - 1.6) ** 2
    return 0.0


def active_stress(stretch: float, law: Muscle) -> float:
    """(sigma_max / l_ofl) f_active(stretch / l_ofl): the active fibre stress at full activation."""
    return law.sigma_max / law.l_ofl * f_active(stretch / law.l_ofl)


def with_stretch(raw: dict[str, Any], stretch: float) -> dict[str, Any]:
    """A copy of a force-length configuration held at ``stretch``: its parameters.stretch set (the prescribed
    end displacement of examples/force_length_*.toml is an expression of it)."""
    if not isinstance(raw.get("parameters"), dict) or "stretch" not in raw["parameters"]:
        raise ValueError("with_stretch: the configuration has no parameters.stretch")
    out = copy.deepcopy(raw)
    out["parameters"]["stretch"] = float(stretch)
    return out


def _step_at(summary: dict[str, Any], load_factor: float) -> dict[str, Any]:
    for step in summary["steps"]:
        if step["converged"] and math.isclose(step["load_factor"], load_factor, abs_tol=1e-9):
            return step
    raise ValueError(f"no converged step at load factor {load_factor} in the summary")


def forces(summary: dict[str, Any], boundary: str, component: int = 2) -> tuple[float, float, float]:
    """(passive, total, active) reaction force on ``boundary`` of a force-length run."""
    passive = _step_at(summary, 0.5)["reactions"][boundary][component]
    total = _step_at(summary, 1.0)["reactions"][boundary][component]
    return passive, total, total - passive


def isometric_curves(summary: dict[str, Any], region: str = "belly", probe: str = "belly_surface",
                     boundary: str = "insertion") -> dict[str, list[float]]:
    """Per converged step: activation, radial bulge (x displacement of the probe on the x axis),
    relative volume change of ``region`` and the axial force the tendon end transmits."""
    steps = [s for s in summary["steps"] if s["converged"]]
    reference = summary["region_volumes"][region]
    return {
        "activation": [s["activation"][region] for s in steps],
        "bulge": [s["probes"][probe][0] for s in steps],
        "volume_change": [s["volumes"][region] / reference - 1.0 for s in steps],
        "tendon_force": [s["reactions"][boundary][2] for s in steps],
    }


__all__ = ["active_stress", "f_active", "forces", "isometric_curves", "with_stretch"]
