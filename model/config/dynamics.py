"""[dynamics]: the time-integration scheme, its time step and damping (DynamicsSpec)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import model_validator

from model.config.base import MAX_STEPS, NonNegative, Number, Positive, Section, entries, fail, interval, key, validate

#: time-integration schemes of model.solvers.dynamics.Dynamics
SCHEMES = ("backward_euler", "newmark", "generalized_alpha")
#: values of [dynamics].scheme: "quasi_static" means the load stepping of model.solvers.loadstepping
CONFIG_SCHEMES = ("quasi_static", *SCHEMES)
_TIME_KEYS = ("dt", "end_time", "rayleigh", "rho_infinity", "load_ramp", "initial")


def _schema(schema: dict[str, Any]) -> None:
    """JSON schema: the time-integration keys need a time-integration scheme; rho_infinity generalized_alpha."""
    dynamic = {"required": ["scheme"], "properties": {"scheme": {"enum": list(SCHEMES)}}}
    schema["allOf"] = [
        {"if": dynamic, "then": {"required": ["dt"]}, "else": {"properties": {k: False for k in _TIME_KEYS}}},
        {"if": {"required": ["scheme"], "properties": {"scheme": {"const": "generalized_alpha"}}},
         "else": {"properties": {"rho_infinity": False}}},
    ]


class DynamicsSpec(Section):
    """[dynamics]: ``scheme`` "quasi_static" (the default: load stepping, [loading]; no other key) or a time
    integration of M a + C v + f_int(u) = f_ext(t) from t = 0 to ``end_time`` with step ``dt`` (each material
    needs a density). With the default load_ramp the loads reach their full value at end_time.

    In Python, ``dt`` is None for the quasi-static scheme.
    """

    model_config = {"json_schema_extra": _schema}

    scheme: Literal[CONFIG_SCHEMES] = key(
        "quasi_static (load stepping) or a time-integration scheme: backward_euler (first order, dissipative), "
        "newmark (average acceleration, energy conserving), generalized_alpha (second order, damping set by "
        "rho_infinity)", default="quasi_static")
    dt: Positive | None = key("the time step (required by a time-integration scheme)", "s (time)", default=None)
    end_time: Positive = key("the end of the time interval", "s (time)", default=1.0)
    rayleigh: Annotated[tuple[NonNegative, NonNegative], entries(2, " [a_M, b_K]")] = key(
        "Rayleigh damping C = a_M M + b_K K: [a_M (1/s), b_K (s)], each >= 0", "1/s, s (a_M, b_K)", default=(0.0, 0.0))
    #: generalized_alpha only: spectral radius at infinite frequency
    rho_infinity: Annotated[Number, *interval(0, 1)] = key(
        "generalized_alpha: spectral radius at infinite frequency (1: no numerical damping)", "dimensionless",
        default=0.8)
    #: constant loads and Dirichlet values grow linearly to their full value at this time (None: end_time);
    #: expressions, tables (activation, bones) and S_function see the time itself
    load_ramp: Positive | None = key(
        "constant loads and prescribed values grow linearly to their full value at this time (default: end_time); "
        "expressions and tables see the time itself", "s (time)", default=None)
    #: u_0: "rest" (u = 0) or "equilibrium" (the quasi-static solution at t = 0, e.g. an activated muscle)
    initial: Literal["rest", "equilibrium"] = key(
        "the initial state: rest (u = 0, v = 0) or equilibrium (the quasi-static solution at t = 0, v = 0)",
        default="rest")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        """Also positionally, in field order: DynamicsSpec("newmark", 0.01, 2.0, (0.5, 1e-3))."""
        super().__init__(**dict(zip(type(self).model_fields, args, strict=False)), **kwargs)

    @model_validator(mode="after")
    def _scheme_keys(self) -> DynamicsSpec:
        given = self.model_fields_set
        if self.scheme == "quasi_static":
            for k in _TIME_KEYS:
                if k in given:
                    fail(f"only applies to a time-integration scheme ({', '.join(SCHEMES)}), not \"quasi_static\"", k)
            return self
        if self.dt is None:
            fail(f"missing: scheme = \"{self.scheme}\" needs a time step", "dt")
        if self.end_time / self.dt > MAX_STEPS:
            fail(f"{self.dt!r} gives end_time / dt = {self.end_time / self.dt:.3g} time steps, at most {MAX_STEPS}",
                 "dt")
        if "rho_infinity" in given and self.scheme != "generalized_alpha":
            fail(f"only applies to scheme = \"generalized_alpha\", not \"{self.scheme}\"", "rho_infinity")
        return self

    def load_scale(self, t: float) -> float:
        """s(t) = min(t / load_ramp, 1): the factor of the scaled loads at time t."""
        ramp = self.load_ramp if self.load_ramp is not None else self.end_time
        return min(t / ramp, 1.0)

    @property
    def is_dynamic(self) -> bool:
        return self.scheme != "quasi_static"


def parse_dynamics(raw: Any) -> DynamicsSpec:
    """Check a [dynamics] table; errors are ConfigError("dynamics.KEY: message")."""
    return validate(DynamicsSpec, raw, "dynamics")


__all__ = ["CONFIG_SCHEMES", "SCHEMES", "DynamicsSpec", "parse_dynamics"]
