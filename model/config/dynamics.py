"""[dynamics]: the time-integration scheme, its time step and damping (DynamicsSpec)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from model.errors import ConfigError

#: time-integration schemes of model.solvers.dynamics.Dynamics
SCHEMES = ("backward_euler", "newmark", "generalized_alpha")
#: values of [dynamics].scheme: "quasi_static" means the load stepping of model.solvers.loadstepping
CONFIG_SCHEMES = ("quasi_static", *SCHEMES)


@dataclass(frozen=True)
class DynamicsSpec:
    """The [dynamics] section: scheme, time step, end time, Rayleigh coefficients (a_M, b_K).

    ``dt`` is None for the quasi-static scheme; ``end_time`` defaults to 1 (with the default
    time_to_load(t) = t, the loads reach their full value at the end).
    """

    scheme: str = "quasi_static"
    dt: float | None = None
    end_time: float = 1.0
    rayleigh: tuple[float, float] = (0.0, 0.0)
    #: generalized_alpha only: spectral radius at infinite frequency
    rho_infinity: float = 0.8
    #: constant loads and Dirichlet values grow linearly to their full value at this time (None: end_time);
    #: expressions, tables (activation, bones) and S_function see the time itself
    load_ramp: float | None = None
    #: u_0: "rest" (u = 0) or "equilibrium" (the quasi-static solution at t = 0, e.g. an activated muscle)
    initial: str = "rest"

    def load_scale(self, t: float) -> float:
        """s(t) = min(t / load_ramp, 1): the factor of the scaled loads at time t."""
        ramp = self.load_ramp if self.load_ramp is not None else self.end_time
        return min(t / ramp, 1.0)

    @property
    def is_dynamic(self) -> bool:
        return self.scheme != "quasi_static"


_DYNAMICS_KEYS = ("scheme", "dt", "end_time", "rayleigh", "rho_infinity", "load_ramp", "initial")


def _config_error(key: str, message: str) -> None:
    raise ConfigError(f"dynamics.{key}: {message}")


def _config_number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _config_error(key, f"must be a number, got {value!r}")
    if not math.isfinite(value):
        _config_error(key, f"must be finite, got {value!r}")
    return float(value)


def parse_dynamics(raw: Any) -> DynamicsSpec:
    """Check a [dynamics] table; errors are ConfigError("dynamics.KEY: message").

    Keys: ``scheme`` ("quasi_static" (default), "backward_euler", "newmark", "generalized_alpha"),
    ``dt`` (> 0, required by a time-integration scheme), ``end_time`` (> 0, default 1),
    ``rayleigh = [a_M, b_K]`` (each >= 0, default [0, 0]), ``rho_infinity`` (generalized_alpha only,
    in [0, 1], default 0.8), ``load_ramp`` (> 0, default end_time: constant loads reach their full
    value then), ``initial`` ("rest" (default): u_0 = 0; "equilibrium": u_0 is the quasi-static
    solution at t = 0). These are refused with "quasi_static".
    Densities are per material (``density`` in [[material]]), not here.
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"dynamics: must be a table, got {type(raw).__name__}")
    for key in raw:
        if key not in _DYNAMICS_KEYS:
            _config_error(key, f"unknown key (allowed: {', '.join(sorted(_DYNAMICS_KEYS))})")
    scheme = raw.get("scheme", "quasi_static")
    if not isinstance(scheme, str):
        _config_error("scheme", f"must be a string, got {scheme!r}")
    if scheme not in CONFIG_SCHEMES:
        _config_error("scheme", f"{scheme!r} is not one of {', '.join(CONFIG_SCHEMES)}")
    if scheme == "quasi_static":
        for key in ("dt", "end_time", "rayleigh", "rho_infinity", "load_ramp", "initial"):
            if key in raw:
                _config_error(key, f"only applies to a time-integration scheme ({', '.join(SCHEMES)}), "
                              "not \"quasi_static\"")
        return DynamicsSpec()
    if "dt" not in raw:
        _config_error("dt", f"missing: scheme = \"{scheme}\" needs a time step")
    dt = _config_number(raw["dt"], "dt")
    if dt <= 0.0:
        _config_error("dt", f"{dt} is out of range, must be > 0")
    end_time = _config_number(raw.get("end_time", 1.0), "end_time")
    if end_time <= 0.0:
        _config_error("end_time", f"{end_time} is out of range, must be > 0")
    rayleigh = raw.get("rayleigh", [0.0, 0.0])
    if not isinstance(rayleigh, list) or len(rayleigh) != 2:
        _config_error("rayleigh", f"must be an array of 2 numbers [a_M, b_K], got {rayleigh!r}")
    coefficients = tuple(_config_number(c, f"rayleigh[{i}]") for i, c in enumerate(rayleigh))
    for i, c in enumerate(coefficients):
        if c < 0.0:
            _config_error(f"rayleigh[{i}]", f"{c} is out of range, damping coefficients must be >= 0")
    rho_infinity = DynamicsSpec.rho_infinity
    if "rho_infinity" in raw:
        if scheme != "generalized_alpha":
            _config_error("rho_infinity", f"only applies to scheme = \"generalized_alpha\", not \"{scheme}\"")
        rho_infinity = _config_number(raw["rho_infinity"], "rho_infinity")
        if not 0.0 <= rho_infinity <= 1.0:
            _config_error("rho_infinity", f"{rho_infinity} is out of range, must be in [0, 1]")
    load_ramp = None
    if "load_ramp" in raw:
        load_ramp = _config_number(raw["load_ramp"], "load_ramp")
        if load_ramp <= 0.0:
            _config_error("load_ramp", f"{load_ramp} is out of range, must be > 0")
    initial = raw.get("initial", "rest")
    if initial not in ("rest", "equilibrium"):
        _config_error("initial", f"{initial!r} is not one of rest, equilibrium")
    return DynamicsSpec(scheme, dt, end_time, (coefficients[0], coefficients[1]), rho_infinity, load_ramp,
                        initial)

