"""Calibration: law parameters fitted to measurements, with exact gradients and their uncertainty.

    result = calibrate(config, data, ["material.0.E", "material.0.nu"], out=DIR)

**The problem.** The data are measured quantities q_i at given load factors t_i, each with a weight w_i
(or a standard deviation sigma_i, w_i = 1 / sigma_i^2). The fitted parameters p (keys of the
configuration, ``material.I.NAME``) minimise

    Phi(p) = 1/2 sum_i w_i (q_i(u(t_i; p), p) - m_i)^2,

u(t; p) the converged state at load factor t: R(u, p; t) = 0. The quantities are those of a run's
summary (and of a sweep's table): ``probe.NAME.x|y|z`` (a probe's displacement), ``reaction.BOUNDARY.x|y|z``
(the force a Dirichlet boundary exerts on the body, as summary.json reports it) and ``volume.REGION``
(int_r J dX; ``volume.all`` the whole body).

**Exact gradients.** Each law parameter is held by a fem.Constant c (model.problem.parameters), so the
forms compile once for the whole fit and UFL derives dR/dc: the integrand of R is differentiated with
respect to c (ufl.diff of the integrand with c made a ufl.variable). A configuration key k (E, nu, ...)
may set several held constants (E, nu -> mu, lmbda); D_ck = dc/dk is the derivative of that algebraic
map (central differences of the law's own conversion, relative step 1e-6: error ~1e-12 relative). At each
converged measured step, with K = dR/du the consistent tangent (Dirichlet rows the identity),

    K s_k = - sum_c D_ck dR/dc          (s_k = du/dk, zero on the Dirichlet dofs: their data do not depend on p)
    dq/dk = q'(u) s_k + dq/dk|_u:
        probe:    the probe evaluated on s_k (a point value is linear in u)
        reaction: sum over the boundary's dofs of K_full s_k + sum_c D_ck dR/dc   (K_full without Dirichlet rows)
        volume:   int_r dJ/dF : grad s_k dX

one factorisation of K (MUMPS) per measured step and one back-substitution per fitted parameter: the
Jacobian G_ik = dq_i/dk that Gauss-Newton and the covariance need. The gradient of the misfit is
G^T W r, r = q - m; ``adjoint_gradient`` computes it the adjoint way instead, one transposed solve per
measured step, K^T lambda = sum_i w_i r_i q_i'(u), dPhi/dk = sum_i w_i r_i dq_i/dk|_u - lambda^T dR/dk
(the tests check that both agree and pass a Taylor test of order 2).

**The fit.** scipy.optimize.least_squares (trust-region reflective: a bounded Levenberg-Marquardt) on
r_i sqrt(w_i) with the Jacobian above, in the variables p_k / |p_k^0| (p^0 the configuration's values, the
start). Bounds: the law registry's allowed range of each parameter (an open end moved inside by 1e-9
relative), narrowed by ``bounds``. Each evaluation solves the forward problem from the rest state through the
measured load factors (the configuration's loading.steps per unit of load factor, with its cut-back
rules), starting each measured step from the previous evaluation's state there when Newton converges from it.

**Uncertainty.** At the optimum, with G_w = W^(1/2) G, the Gauss-Newton approximation of the covariance is

    Cov = s^2 (G_w^T G_w)^-1,    s^2 = 1 with sigma given (absolute),  s^2 = 2 Phi / (m - n) else

(m measurements, n parameters), the standard errors sqrt(diag Cov), the correlations Cov_kl / (se_k se_l).
A correlation above 0.99 in magnitude, or a singular G_w^T G_w, is a warning: the data cannot tell those
parameters apart. The relative sensitivities p_k dq_i/dk say which measurement informs which parameter.

``write(out)``: calibration.json (everything above, the history of evaluations), fit.csv (a row per
measurement: measured, start, fitted, weighted residual, the sensitivities), fit.png (measured and fitted
against the load factor, one panel per quantity) and fitted.toml (the configuration with the fitted values).

Not supported (ConfigError before any solve): contacts, dynamics, arc-length or volume control, projective
dynamics, a parameter a law uses outside UFL (a number of its formulas: it cannot be held), a parameter that
follows a load curve.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from model import compat
from model.config import RunConfig, parse
from model.config.overrides import apply, split_path
from model.errors import ConfigError, SolveFailed
from model.pipeline import build, make_solver
from model.problem.measurements import Volumes, reactions
from model.problem.parameters import candidates, curve_constants
from model.solvers.loadstepping import continuation

log = logging.getLogger(__name__)

COMPONENTS = {"x": 0, "y": 1, "z": 2}
#: relative step of the central differences of a key's map to the held constants (E, nu -> mu, lmbda)
MAP_STEP = 1e-6
#: an open end of a registry range is moved inside by this fraction (|end| or 1)
OPEN_END = 1e-9
#: correlations beyond this (in magnitude) are reported as parameters the data cannot tell apart
CORRELATED = 0.99


# --- data ---------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Quantity:
    """A measured quantity by its name: kind (probe, reaction, volume), what (the probe, boundary or region) and
    component (0-2; None for a volume)."""

    name: str
    kind: str
    what: str
    component: int | None


def parse_quantity(name: str) -> Quantity:
    """``probe.NAME.x``, ``reaction.BOUNDARY.y``, ``volume.REGION`` (ValueError saying what is expected)."""
    parts = str(name).strip().split(".")
    expected = "probe.NAME.x|y|z, reaction.BOUNDARY.x|y|z or volume.REGION"
    if parts[0] in ("probe", "reaction"):
        if len(parts) != 3 or not parts[1] or parts[2] not in COMPONENTS:
            raise ValueError(f"{name!r} is not {parts[0]}.NAME.x|y|z (expected {expected})")
        return Quantity(str(name).strip(), parts[0], parts[1], COMPONENTS[parts[2]])
    if parts[0] == "volume":
        if len(parts) != 2 or not parts[1]:
            raise ValueError(f"{name!r} is not volume.REGION (expected {expected})")
        return Quantity(str(name).strip(), "volume", parts[1], None)
    raise ValueError(f"{name!r}: unknown quantity (expected {expected})")


def read_data(source: str | Path | pd.DataFrame) -> pd.DataFrame:
    """The measurements of a CSV file (or a DataFrame) with columns ``load_factor``, ``quantity``, ``value`` and
    at most one of ``sigma`` (standard deviation, > 0) and ``weight`` (> 0; default 1): a DataFrame with columns
    load_factor, quantity, value, weight, sigma (NaN when not given), row (the file's line, or the frame's index),
    at ("data FILE, line N": for messages). ConfigError naming
    the file, the line and the column otherwise."""
    where = "data" if isinstance(source, pd.DataFrame) else f"data {source}"
    if isinstance(source, pd.DataFrame):
        frame = source.copy()
    else:
        path = Path(source)
        if not path.is_file():
            raise ConfigError(f"{where}: no such file")
        try:
            frame = pd.read_csv(path, comment="#", skipinitialspace=True)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
            raise ConfigError(f"{where}: not a CSV table ({str(err).splitlines()[0]})") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    missing = [c for c in ("load_factor", "quantity", "value") if c not in frame.columns]
    if missing:
        raise ConfigError(f"{where}: no column {missing[0]!r} (columns: {', '.join(frame.columns) or 'none'}; "
                          "needed: load_factor, quantity, value, and optionally sigma or weight)")
    unknown = [c for c in frame.columns if c not in ("load_factor", "quantity", "value", "sigma", "weight")]
    if unknown:
        raise ConfigError(f"{where}: unknown column {unknown[0]!r} (allowed: load_factor, quantity, value, sigma, "
                          "weight)")
    if "sigma" in frame.columns and "weight" in frame.columns:
        raise ConfigError(f"{where}: give sigma or weight, not both (weight = 1 / sigma^2)")
    if frame.empty:
        raise ConfigError(f"{where}: no measurements")
    rows = []
    for index, row in frame.iterrows():
        line = int(index) + 2 if not isinstance(source, pd.DataFrame) else int(index)  # header is line 1
        at = f"{where}, line {line}" if not isinstance(source, pd.DataFrame) else f"{where}, row {line}"
        try:
            quantity = parse_quantity(row["quantity"])
        except ValueError as err:
            raise ConfigError(f"{at}: quantity {err}") from None
        numbers = {}
        for column in ("load_factor", "value", "sigma", "weight"):
            if column not in frame.columns:
                continue
            try:
                numbers[column] = float(row[column])
            except (TypeError, ValueError):
                raise ConfigError(f"{at}: {column} must be a number, got {row[column]!r}") from None
            if not math.isfinite(numbers[column]):
                raise ConfigError(f"{at}: {column} must be a finite number, got {row[column]!r}")
        t = numbers["load_factor"]
        if not 0.0 < t <= 1.0:
            raise ConfigError(f"{at}: load_factor must be in (0, 1] (the load factor of a quasi-static run), got {t}")
        for column in ("sigma", "weight"):
            if column in numbers and numbers[column] <= 0:
                raise ConfigError(f"{at}: {column} must be > 0, got {numbers[column]}")
        sigma = numbers.get("sigma", float("nan"))
        weight = 1.0 / sigma**2 if "sigma" in numbers else numbers.get("weight", 1.0)
        rows.append({"load_factor": t, "quantity": quantity.name, "value": numbers["value"], "weight": weight,
                     "sigma": sigma, "row": line, "at": at})
    out = pd.DataFrame(rows)
    twice = out.duplicated(["load_factor", "quantity"], keep=False)
    if twice.any():
        first = out[twice].iloc[0]
        raise ConfigError(f"{first['at']}: {first['quantity']} at load_factor {first['load_factor']} "
                          "is given twice (average the repeats, or give each its weight)")
    return out


# --- the parameters ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FitParameter:
    """A fitted key ``material.I.NAME``: the material's index, the parameter's name, its start value and bounds."""

    key: str
    material: int
    name: str
    start: float
    lower: float
    upper: float


def _registry_bounds(entry: Any, name: str) -> tuple[float, float]:
    """The law registry's numeric range of parameter ``name`` (-inf, inf where it has none), open ends moved
    inside."""
    try:
        p = entry.parameter(name)
    except KeyError:
        return -math.inf, math.inf
    lower = -math.inf if p.lower is None else p.lower + (OPEN_END * max(abs(p.lower), 1.0) if p.lower_open else 0.0)
    upper = math.inf if p.upper is None else p.upper - (OPEN_END * max(abs(p.upper), 1.0) if p.upper_open else 0.0)
    return lower, upper


def fit_parameters(config: RunConfig, keys: Sequence[str],
                   bounds: Mapping[str, tuple[float | None, float | None]] | None = None) -> list[FitParameter]:
    """The fitted keys checked against the configuration (ConfigError naming the key): ``material.I.NAME`` with
    NAME a numeric parameter of material I's law (written in its table or a default), not a load curve."""
    from model.config.material import _entry_of

    bounds = dict(bounds or {})
    if not keys:
        raise ConfigError("fit: name at least one parameter, e.g. material.0.E")
    out = []
    for key in keys:
        parts = split_path(key)
        if len(parts) != 3 or parts[0] != "material" or not isinstance(parts[1], int):
            raise ConfigError(f"fit: {key!r} is not material.I.NAME (a parameter of material I's law, e.g. "
                              "material.0.E)")
        index, name = parts[1], str(parts[2])
        if not 0 <= index < len(config.materials):
            raise ConfigError(f"fit: {key}: there are {len(config.materials)} materials (indices 0 to "
                              f"{len(config.materials) - 1})")
        material = config.materials[index]
        entry = _entry_of(material.law)
        given = material.given_parameters
        if name not in entry.names:
            raise ConfigError(f"fit: {key}: {entry.name} has no parameter {name!r} (its parameters: "
                              f"{', '.join(entry.names)})")
        if name in material.parameter_curves:
            raise ConfigError(f"fit: {key} follows a load curve in the configuration; give it a number to fit it")
        value = given.get(name, entry.parameter(name).default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"fit: {key}: needs a finite number to start from, got {value!r} (give it in "
                              f"material[{index}]'s table)")
        lower, upper = _registry_bounds(entry, name)
        if key in bounds:
            lo, hi = bounds.pop(key)
            lower = max(lower, -math.inf if lo is None else float(lo))
            upper = min(upper, math.inf if hi is None else float(hi))
        if not lower < upper:
            raise ConfigError(f"fit: {key}: empty range [{lower}, {upper}]")
        if not lower <= value <= upper:
            raise ConfigError(f"fit: {key} = {value} is outside its range [{lower:g}, {upper:g}]: start inside it")
        out.append(FitParameter(key, index, name, float(value), lower, upper))
    if bounds:
        raise ConfigError(f"bounds: {next(iter(bounds))} is not a fitted key (fitted: {', '.join(keys)})")
    if len({p.key for p in out}) != len(out):
        raise ConfigError(f"fit: a key is named twice ({', '.join(keys)})")
    return out


def _held_names(config: RunConfig, parameter: FitParameter, values: Mapping[str, float],
                fitted: Sequence[FitParameter]) -> dict[str, float]:
    """{held constant name: d constant / d parameter} of one fitted key at ``values`` (the ``fitted`` parameters'
    values; central differences of the law's own conversion)."""
    material = config.materials[parameter.material]
    value = values[parameter.key]
    h = MAP_STEP * max(abs(value), 1e-300)
    own = {p.name: values[p.key] for p in fitted if p.material == parameter.material}
    plus = candidates(material.law_with({**own, parameter.name: value + h}))
    minus = candidates(material.law_with({**own, parameter.name: value - h}))
    return {n: (plus[n] - minus.get(n, plus[n])) / (2 * h) for n in plus if plus[n] != minus.get(n)}


# --- forward model with sensitivities ------------------------------------------------------------------------------

def constant_derivative(form: ufl.Form, constant: fem.Constant) -> ufl.Form:
    """d form / d constant: each integrand differentiated with respect to the constant (made a ufl.variable; UFL's
    derivative takes Coefficients, not Constants). Empty when the form does not depend on it."""
    var = ufl.variable(constant)
    integrals = [itg.reconstruct(integrand=ufl.diff(ufl.replace(itg.integrand(), {constant: var}), var))
                 for itg in form.integrals()]
    return ufl.algorithms.expand_derivatives(ufl.Form(integrals))


@dataclass
class Evaluation:
    """One forward evaluation: the parameters, the quantities (one per measurement, the data's order), their
    derivatives (measurements x parameters) and the forward work."""

    values: dict[str, float]
    quantities: np.ndarray
    jacobian: np.ndarray | None
    newton_iterations: int
    seconds: float


class Calibration:
    """The forward model of a calibration: the configuration built once (forms compiled once), evaluated at any
    parameter values with the quantities' derivatives (module docstring). Collective over ``comm``."""

    def __init__(self, config: RunConfig, data: pd.DataFrame | str | Path, fit: Sequence[str],
                 bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
                 comm: MPI.Comm = MPI.COMM_WORLD) -> None:
        self.config = config
        self.comm = comm
        self.data = read_data(data)
        self.parameters = fit_parameters(config, list(fit), bounds)
        self._check_config()
        self.setup = build(config, comm)
        self.problem = self.setup.problem
        self._check_quantities()
        self._check_held()
        from model.solvers.scale import scale_check

        scale = scale_check(self.problem, config)
        self.solver = make_solver(self.problem, config,
                                  scaled=scale.newton_options(self.setup.domain.mesh.geometry.dim))
        self.volumes = Volumes(self.problem)
        self.times = np.array(sorted(set(self.data["load_factor"].tolist())))
        self._warm: dict[int, np.ndarray] = {}
        self._cache: dict[bytes, Evaluation] = {}
        self.evaluations: list[Evaluation] = []
        self._compile()

    # -- checks before any solve --

    def _check_config(self) -> None:
        c = self.config
        what = None
        if c.contacts:
            what = "contacts ([[contact]])"
        elif c.dynamics is not None and c.dynamics.is_dynamic:
            what = "a dynamic run ([dynamics])"
        elif c.loading.control != "load":
            what = f"loading.control = {c.loading.control!r} (load control only)"
        elif c.solver.method != "newton":
            what = f"solver.method = {c.solver.method!r} (Newton only)"
        elif any(b.type == "sliding" for b in c.boundaries):
            what = "sliding boundaries"
        if what is not None:
            raise ConfigError(f"calibrate: {what} is not supported by calibration (its gradients)")

    def _check_quantities(self) -> None:
        probes = set(self.setup.probes.names)
        boundaries = {e.name for e in self.problem.dirichlet}
        regions = {"all", *self.setup.domain.regions}
        for _, row in self.data.iterrows():
            q = parse_quantity(row["quantity"])
            known = {"probe": probes, "reaction": boundaries, "volume": regions}[q.kind]
            if q.what not in known:
                names = ", ".join(sorted(known)) or "none"
                kind = {"probe": "probe", "reaction": "Dirichlet boundary", "volume": "region"}[q.kind]
                raise ConfigError(f"{row['at']}: {q.name}: no {kind} named {q.what!r} (the configuration "
                                  f"has: {names})")

    def _check_held(self) -> None:
        """Every constant a fitted key sets is held (a runtime value of the forms) and follows no curve."""
        start = self.start
        self._maps: list[dict[str, float]] = []
        for p in self.parameters:
            held = self.problem.held_parameters[p.material]
            try:
                names = _held_names(self.config, p, start, self.parameters)
            except Exception as err:  # noqa: BLE001 -- the law's validation at the start +- h: say which
                raise ConfigError(f"fit: {p.key}: {err}") from None
            outside = sorted(set(names) - set(held))
            if outside:
                law = self.problem.materials[p.material][1].name
                raise ConfigError(f"fit: {p.key}: {law} uses {', '.join(outside)} outside UFL (a number of its "
                                  "formulas, not a runtime value), so its gradient cannot be derived; fit another "
                                  "parameter")
            if not names:
                raise ConfigError(f"fit: {p.key}: the law does not depend on it")
            curved = curve_constants(self.config.materials[p.material])
            if set(names) & curved:
                raise ConfigError(f"fit: {p.key} sets {', '.join(sorted(set(names) & curved))}, which a load curve "
                                  "of the same material sets too")
            self._maps.append(names)

    # -- compiled forms --

    def _compile(self) -> None:
        problem = self.problem
        V = problem.space
        residual = problem.residual_form
        self.s = fem.Function(V, name="sensitivity")
        # the displacement space (collapsed from the mixed one: its entries' indices in V) and a Function on it, for
        # the probes' interpolation weights (_probe_weights); made here, on every rank (collective)
        if problem.formulation == "mixed":
            displacement_space, parent = V.sub(0).collapse()
            self._parent = np.asarray(parent, dtype=np.int64)
        else:
            displacement_space = V
            self._parent = np.arange(len(self.s.x.array), dtype=np.int64)
        self._trial = fem.Function(displacement_space)
        names = sorted({(p.material, n) for p, m in zip(self.parameters, self._maps) for n in m})
        self._dR_forms = {}
        for index, name in names:
            constant = problem.held_parameters[index][name]
            self._dR_forms[(index, name)] = fem.form(constant_derivative(residual, constant))
        self._volume_tests: dict[str, Any] = {}  # int dJ/dF : grad v dX per region (the adjoint's right-hand sides)
        self._action = fem.form(ufl.derivative(residual, problem.solution, self.s))
        self._jacobian = problem.forms[1]
        self._volume_forms = {}
        for region in sorted({parse_quantity(q).what for q in self.data["quantity"] if q.startswith("volume.")}):
            J = ufl.det(problem.F)
            self._volume_forms[region] = fem.form(ufl.derivative(J * problem.region_measure(region),
                                                                 problem.solution, self.s))

    # -- parameters --

    @property
    def start(self) -> dict[str, float]:
        return {p.key: p.start for p in self.parameters}

    def set_values(self, values: Mapping[str, float]) -> None:
        """Hold the laws' constants at the parameters ``values`` (ConfigError naming the key and value when the law
        refuses them)."""
        by_material: dict[int, dict[str, float]] = {}
        for p in self.parameters:
            by_material.setdefault(p.material, {})[p.name] = float(values[p.key])
        for index, own in by_material.items():
            material = self.config.materials[index]
            try:
                law = material.law_with(own)
            except Exception as err:  # noqa: BLE001 -- ParameterError and the like, with the values tried
                raise ConfigError(f"calibrate: material[{index}] with {own}: {err}") from None
            held = self.problem.held_parameters[index]
            for name, value in candidates(law).items():
                if name in held:
                    held[name].value = value
        self.problem.invalidate_state()

    # -- the forward problem --

    def _steps_to(self, t0: float, t1: float) -> int:
        return max(1, math.ceil(self.config.loading.steps * (t1 - t0) - 1e-9))

    def _reach(self, k: int, t0: float, t1: float) -> int:
        """The converged state at load factor t1 from the converged one at t0 (the previous evaluation's state at
        t1 first, when Newton converges from it); Newton iterations spent. SolveFailed when it cannot."""
        problem, solver = self.problem, self.solver
        iterations = 0
        warm = self._warm.get(k)
        if warm is not None:
            saved = problem.solution.x.array.copy()
            problem.solution.x.array[:] = warm
            problem.set_load_factor(t1)
            problem.invalidate_state()
            result = solver.solve()
            iterations += result.iterations
            if result.converged:
                return iterations
            problem.solution.x.array[:] = saved
            problem.set_load_factor(t0)
            problem.invalidate_state()
        counted = []
        outcome = continuation(solver, lambda s: problem.set_load_factor(t0 + s * (t1 - t0)), self._steps_to(t0, t1),
                               self.config.loading.max_cutbacks, self.config.loading.growth,
                               lambda record: counted.append(record.result.iterations))
        iterations += sum(counted)
        if not outcome:
            raise SolveFailed(f"calibrate: the forward solve failed between load factors {t0:.6g} and {t1:.6g}: "
                              f"{outcome.reason}")
        return iterations

    def evaluate(self, values: Mapping[str, float], derivatives: bool = True) -> Evaluation:
        """The quantities (and their derivatives) at the parameters ``values`` ({key: value}). Collective."""
        values = {p.key: float(values[p.key]) for p in self.parameters}
        key = np.array([values[p.key] for p in self.parameters]).tobytes()
        cached = self._cache.get(key)
        if cached is not None and (cached.jacobian is not None or not derivatives):
            return cached
        began = time.perf_counter()
        self.set_values(values)
        problem = self.problem
        problem.solution.x.array[:] = 0.0
        problem.set_load_factor(0.0)
        problem.invalidate_state()
        n, m = len(self.parameters), len(self.data)
        q = np.full(m, np.nan)
        G = np.full((m, n), np.nan) if derivatives else None
        iterations = 0
        previous = 0.0
        for k, t in enumerate(self.times):
            iterations += self._reach(k, previous, float(t))
            self._warm[k] = problem.solution.x.array.copy()
            previous = float(t)
            rows = np.flatnonzero(self.data["load_factor"].to_numpy() == t)
            self._measure(values, rows, q, G)
        evaluation = Evaluation(values, q, G, iterations, time.perf_counter() - began)
        self._cache[key] = evaluation
        self.evaluations.append(evaluation)
        return evaluation

    def _quantities(self, rows: np.ndarray, probes: dict, reacts: dict, volumes: dict) -> np.ndarray:
        out = np.empty(len(rows))
        for j, i in enumerate(rows):
            q = parse_quantity(self.data["quantity"].iloc[i])
            if q.kind == "probe":
                out[j] = probes[q.what][q.component]
            elif q.kind == "reaction":
                out[j] = reacts[q.what][q.component]
            else:
                out[j] = volumes[q.what]
        return out

    def _measure(self, values: Mapping[str, float], rows: np.ndarray, q: np.ndarray, G: np.ndarray | None) -> None:
        problem = self.problem
        kinds = {parse_quantity(self.data["quantity"].iloc[i]).kind for i in rows}
        probes = self.setup.probes.evaluate(problem.displacement()) if "probe" in kinds else {}
        reacts = {}
        if "reaction" in kinds:
            residual = self.solver.unconstrained_residual()
            reacts = reactions(problem, residual)
            residual.destroy()
        volumes = self.volumes.current() if "volume" in kinds else {}
        q[rows] = self._quantities(rows, probes, reacts, volumes)
        if G is None:
            return
        for j, column in enumerate(self._sensitivities(values)):
            s_probes, s_reacts, s_volumes = column
            G[rows, j] = self._quantities(rows, s_probes, s_reacts, s_volumes)

    def _dR(self, values: Mapping[str, float]) -> list[PETSc.Vec]:
        """sum_c D_ck dR/dc per fitted key k (assembled, ghosts summed, no Dirichlet rows replaced)."""
        vectors = {}
        for name, form in self._dR_forms.items():
            b = fem_petsc.assemble_vector(form)
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            vectors[name] = b
        out = []
        for p in self.parameters:
            total = vectors[next(iter(vectors))].duplicate()
            total.set(0.0)
            for name, d in _held_names(self.config, p, values, self.parameters).items():
                total.axpy(d, vectors[(p.material, name)])
            out.append(total)
        for b in vectors.values():
            b.destroy()
        return out

    def _factor(self) -> PETSc.KSP:
        """The MUMPS LU of the consistent tangent at the current state (Dirichlet rows the identity)."""
        problem = self.problem
        problem.update_state()
        A = fem_petsc.assemble_matrix(self._jacobian, bcs=problem.bcs)
        A.assemble()
        ksp = PETSc.KSP().create(problem.domain.mesh.comm)
        ksp.setOptionsPrefix("calibrate_")
        ksp.setOperators(A)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType("mumps")
        ksp.setUp()
        A.destroy()
        return ksp

    def _sensitivities(self, values: Mapping[str, float]) -> list[tuple[dict, dict, dict]]:
        """Per fitted key: (probes, reactions, volumes) of s_k = du/dk (their derivatives, module docstring)."""
        problem = self.problem
        ksp = self._factor()
        out = []
        for b in self._dR(values):
            rhs = b.copy()
            rhs.scale(-1.0)
            problem.zero_dirichlet_rows(rhs)
            x = compat.petsc_vector(self.s)
            ksp.solve(rhs, x)
            reason = ksp.getConvergedReason()
            rhs.destroy()
            if reason < 0:
                b.destroy()
                ksp.destroy()
                raise SolveFailed(f"calibrate: the sensitivity solve failed (KSP reason {reason})")
            self.s.x.scatter_forward()
            probes = self.setup.probes.evaluate(_displacement(problem, self.s))
            action = fem_petsc.assemble_vector(self._action)
            action.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            action.axpy(1.0, b)
            reacts = reactions(problem, action)
            action.destroy()
            b.destroy()
            volumes = {r: float(self.comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM))
                       for r, f in self._volume_forms.items()}
            out.append((probes, reacts, volumes))
        ksp.destroy()
        return out

    # -- objective --

    def residuals(self, evaluation: Evaluation) -> np.ndarray:
        """sqrt(w_i) (q_i - m_i)."""
        return np.sqrt(self.data["weight"].to_numpy()) * (evaluation.quantities - self.data["value"].to_numpy())

    def misfit(self, values: Mapping[str, float]) -> float:
        """Phi = 1/2 sum_i w_i (q_i - m_i)^2."""
        r = self.residuals(self.evaluate(values, derivatives=False))
        return 0.5 * float(r @ r)

    def gradient(self, values: Mapping[str, float]) -> np.ndarray:
        """dPhi/dp = G^T W (q - m) from the sensitivities."""
        e = self.evaluate(values)
        w = self.data["weight"].to_numpy()
        return e.jacobian.T @ (w * (e.quantities - self.data["value"].to_numpy()))

    def adjoint_gradient(self, values: Mapping[str, float]) -> np.ndarray:
        """dPhi/dp the adjoint way: per measured step one transposed solve K^T lambda = dPhi_t/du (module
        docstring); the same as ``gradient`` to round-off."""
        values = {p.key: float(values[p.key]) for p in self.parameters}
        self.set_values(values)
        w = self.data["weight"].to_numpy()
        measured = self.data["value"].to_numpy()
        problem = self.problem
        total = np.zeros(len(self.parameters))
        problem.solution.x.array[:] = 0.0
        problem.set_load_factor(0.0)
        problem.invalidate_state()
        previous = 0.0
        q = np.full(len(self.data), np.nan)
        for k, t in enumerate(self.times):
            self._reach(k, previous, float(t))
            self._warm[k] = problem.solution.x.array.copy()
            previous = float(t)
            rows = np.flatnonzero(self.data["load_factor"].to_numpy() == t)
            self._measure(values, rows, q, None)
            total += self._adjoint_step(values, rows, w[rows] * (q[rows] - measured[rows]))
        return total

    def _adjoint_step(self, values: Mapping[str, float], rows: np.ndarray, weighted: np.ndarray) -> np.ndarray:
        """sum_i c_i dq_i/dk at this step by one transposed solve: g = sum_i c_i q_i'(u) assembled as a vector
        (probes by their interpolation weights, reactions as row sums of K_full, volumes as int dJ/dF : grad v),
        K^T lambda = g (lambda = 0 on the Dirichlet dofs), then sum_i c_i dq_i/dk|_u - lambda^T dR/dk."""
        problem = self.problem
        V = problem.space
        g = fem.Function(V)  # owned entries: contributions summed over the ranks already
        local = fem.Function(V)  # contributions of this rank's cells, ghosts included: summed onto the owners below
        explicit = np.zeros(len(self.parameters))
        dR = self._dR(values)
        v = ufl.TestFunction(V)
        full = None
        for c, i in zip(weighted, rows):
            q = parse_quantity(self.data["quantity"].iloc[i])
            if q.kind == "probe":
                local.x.array[:] += c * self._probe_weights(q)
            elif q.kind == "volume":
                if q.what not in self._volume_tests:
                    self._volume_tests[q.what] = fem.form(ufl.derivative(
                        ufl.det(problem.F) * problem.region_measure(q.what), problem.solution, v))
                vec = fem_petsc.assemble_vector(self._volume_tests[q.what])
                vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
                owned = vec.getLocalSize()
                g.x.array[:owned] += c * vec.array_r[:owned]
                vec.destroy()
            else:
                indicator = self._boundary_indicator(q)
                for j, b in enumerate(dR):  # the explicit part: sum over the boundary's dofs of dR/dk
                    explicit[j] += c * self._sum_owned(b, indicator)
                # q'(u) = K_full^T e_b: the Jacobian's action transposed on the indicator
                e = fem.Function(V)
                e.x.array[:] = indicator
                if full is None:  # K_full (no Dirichlet rows replaced), once per step
                    problem.update_state()
                    full = fem_petsc.assemble_matrix(self._jacobian)
                    full.assemble()
                y = full.createVecLeft()
                full.multTranspose(compat.petsc_vector(e), y)
                owned = y.getLocalSize()
                g.x.array[:owned] += c * y.array_r[:owned]
                y.destroy()
        if full is not None:
            full.destroy()
        summed = compat.petsc_vector(local)
        summed.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        owned = summed.getLocalSize()
        g.x.array[:owned] += local.x.array[:owned]
        rhs = compat.petsc_vector(g).copy()
        problem.zero_dirichlet_rows(rhs)
        ksp = self._factor()
        lam = rhs.duplicate()
        ksp.solveTranspose(rhs, lam)
        reason = ksp.getConvergedReason()
        ksp.destroy()
        rhs.destroy()
        if reason < 0:
            raise SolveFailed(f"calibrate: the adjoint solve failed (KSP reason {reason})")
        out = explicit.copy()
        for j, b in enumerate(dR):
            problem.zero_dirichlet_rows(b)  # dR/dk's Dirichlet rows are those of the identity: no p there
            out[j] -= lam.dot(b)
            b.destroy()
        lam.destroy()
        return out

    def _sum_owned(self, vec: PETSc.Vec, indicator: np.ndarray) -> float:
        owned = vec.getLocalSize()
        return float(self.comm.allreduce(float(vec.array_r[:owned] @ indicator[:owned]), op=MPI.SUM))

    def _boundary_indicator(self, q: Quantity) -> np.ndarray:
        """1 at the dofs of component q.component that boundary q.what constrains (local layout with ghosts)."""
        V = self.problem.space
        out = np.zeros(len(fem.Function(V).x.array))
        for entry in self.problem.dirichlet:
            if entry.name != q.what:
                continue
            for comp, dofs in zip(entry.components, entry.dofs):
                if comp == q.component:
                    out[dofs] = 1.0
        return out

    def _probe_weights(self, q: Quantity) -> np.ndarray:
        """The vector w with probe value = w . u (local layout of the problem's space): the basis functions of the
        probe's cell evaluated at its point (on the rank that evaluates the probe; zero elsewhere). Local: the
        displacement space, its map into the mixed space and the trial Function are made collectively in
        _compile."""
        probes = self.setup.probes
        i = probes.names.index(q.what)
        out = np.zeros(len(self.s.x.array))
        if probes.owner[i] != self.comm.rank:
            return out
        cell = int(probes.cells[i])
        trial, parent = self._trial, self._parent
        bs = trial.function_space.dofmap.index_map_bs
        for dof in compat.cell_dofs(trial.function_space.dofmap)[cell]:
            for comp in range(bs):
                index = int(dof) * bs + comp
                trial.x.array[:] = 0.0
                trial.x.array[index] = 1.0
                value = trial.eval(probes.points[i:i + 1], np.array([cell], dtype=np.int32))
                out[parent[index]] = np.ravel(value)[q.component]
        trial.x.array[:] = 0.0
        return out

    # -- the fit --

    def fit(self, max_evaluations: int = 50, xtol: float = 1e-8, ftol: float = 1e-10,
            gtol: float = 1e-10) -> CalibrationResult:
        """Minimise Phi over the fitted parameters within their bounds (module docstring). Collective."""
        from scipy.optimize import least_squares

        scale = np.array([abs(p.start) if p.start != 0 else 1.0 for p in self.parameters])
        lower = np.array([p.lower for p in self.parameters]) / scale
        upper = np.array([p.upper for p in self.parameters]) / scale
        x0 = np.array([p.start for p in self.parameters]) / scale
        began = time.perf_counter()
        start_eval = self.evaluate(self.start)
        start_misfit = 0.5 * float(self.residuals(start_eval) @ self.residuals(start_eval))
        sqrt_w = np.sqrt(self.data["weight"].to_numpy())
        count = [0]

        def values_of(x: np.ndarray) -> dict[str, float]:
            x = self.comm.bcast(np.asarray(x, dtype=float) if self.comm.rank == 0 else None, root=0)
            return {p.key: float(v) for p, v in zip(self.parameters, x * scale)}

        def residuals(x: np.ndarray) -> np.ndarray:
            values = values_of(x)
            e = self.evaluate(values)
            r = self.residuals(e)
            count[0] += 1
            if self.comm.rank == 0:
                shown = ", ".join(f"{k} = {v:.6g}" for k, v in values.items())
                log.info("calibrate: evaluation %d: %s: misfit %.6e (%d Newton iterations, %.1f s)", count[0], shown,
                         0.5 * float(r @ r), e.newton_iterations, e.seconds)
            return r

        def jacobian(x: np.ndarray) -> np.ndarray:
            return sqrt_w[:, None] * self.evaluate(values_of(x)).jacobian * scale[None, :]

        solution = least_squares(residuals, x0, jac=jacobian, bounds=(lower, upper), method="trf", x_scale=1.0,
                                 max_nfev=max_evaluations, xtol=xtol, ftol=ftol, gtol=gtol)
        best = values_of(solution.x)
        final = self.evaluate(best)
        return CalibrationResult.of(self, best, start_eval, final, start_misfit, solution,
                                    time.perf_counter() - began)


@dataclass
class CalibrationResult:
    """The fitted values and what goes with them (module docstring); ``write(out)`` the files."""

    parameters: dict[str, float]
    start: dict[str, float]
    std: dict[str, float]
    covariance: np.ndarray
    correlation: np.ndarray
    misfit_start: float
    misfit: float
    absolute_sigma: bool
    table: pd.DataFrame
    message: str
    success: bool
    evaluations: int
    newton_iterations: int
    wall_time_s: float
    warnings: list[str] = field(default_factory=list)
    history: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def of(cls, cal: Calibration, best: dict[str, float], start_eval: Evaluation, final: Evaluation,
           start_misfit: float, solution: Any, seconds: float) -> CalibrationResult:
        data = cal.data
        w = data["weight"].to_numpy()
        r = cal.residuals(final)
        misfit = 0.5 * float(r @ r)
        Gw = np.sqrt(w)[:, None] * final.jacobian
        m, n = Gw.shape
        absolute = bool(np.all(np.isfinite(data["sigma"].to_numpy())))
        s2 = 1.0 if absolute else (2 * misfit / (m - n) if m > n else float("nan"))
        keys = list(best)
        warnings = []
        H = Gw.T @ Gw
        try:
            rank = np.linalg.matrix_rank(H, tol=1e-12 * max(np.abs(H).max(), 1e-300))
            covariance = s2 * np.linalg.inv(H) if rank == n else np.full((n, n), np.nan)
        except np.linalg.LinAlgError:
            rank, covariance = 0, np.full((n, n), np.nan)
        if rank < n:
            warnings.append(f"the data do not determine every parameter (Gauss-Newton Hessian of rank {rank} for "
                            f"{n} parameters): measure other quantities, or fit fewer parameters")
        std = np.sqrt(np.abs(np.diag(covariance)))
        with np.errstate(invalid="ignore", divide="ignore"):
            correlation = covariance / np.outer(std, std)
        for a in range(n):
            for b in range(a + 1, n):
                if abs(correlation[a, b]) > CORRELATED:
                    warnings.append(f"{keys[a]} and {keys[b]} are correlated {correlation[a, b]:+.4f}: the data "
                                    "hardly tell them apart")
        if not absolute and m <= n:
            warnings.append(f"{m} measurements for {n} parameters: no residual variance, no uncertainty")
        table = pd.DataFrame({
            "load_factor": data["load_factor"], "quantity": data["quantity"], "measured": data["value"],
            "sigma": data["sigma"], "weight": data["weight"], "start": start_eval.quantities,
            "fitted": final.quantities, "weighted_residual": r})
        for j, k in enumerate(keys):
            table[f"sensitivity.{k}"] = final.jacobian[:, j] * best[k]  # p_k dq/dp_k
        history = [{"values": e.values, "misfit": 0.5 * float(cal.residuals(e) @ cal.residuals(e)),
                    "newton_iterations": e.newton_iterations, "seconds": e.seconds} for e in cal.evaluations]
        return cls(best, cal.start, dict(zip(keys, std.tolist())), covariance, correlation, start_misfit, misfit,
                   absolute, table, str(solution.message), bool(solution.success), len(cal.evaluations),
                   sum(e.newton_iterations for e in cal.evaluations), seconds, warnings, history)

    def summary(self) -> dict[str, Any]:
        """calibration.json's content."""
        keys = list(self.parameters)
        return {
            "parameters": self.parameters, "start": self.start, "standard_error": self.std,
            "uncertainty": "absolute (sigma given)" if self.absolute_sigma else
            "relative: scaled by the residual variance 2 Phi / (m - n)",
            "covariance": _listed(self.covariance), "correlation": _listed(self.correlation), "keys": keys,
            "misfit_start": self.misfit_start, "misfit": self.misfit, "success": self.success,
            "message": self.message, "evaluations": self.evaluations, "newton_iterations": self.newton_iterations,
            "wall_time_s": self.wall_time_s, "warnings": self.warnings, "history": self.history}

    def text(self) -> str:
        """A few lines for the terminal: fitted values with their standard errors, misfit, warnings."""
        lines = [f"calibration: {'converged' if self.success else 'stopped'} after {self.evaluations} evaluations "
                 f"({self.message}); misfit {self.misfit_start:.4g} -> {self.misfit:.4g}"]
        for k, v in self.parameters.items():
            lines.append(f"  {k} = {v:.6g} +- {self.std[k]:.3g} (start {self.start[k]:.6g})")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def write(self, out: str | Path, config: RunConfig, comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, Path]:
        """calibration.json, fit.csv, fit.png and fitted.toml in ``out`` (rank 0 writes); their paths."""
        out = Path(out)
        files = {"summary": out / "calibration.json", "table": out / "fit.csv", "png": out / "fit.png",
                 "config": out / "fitted.toml"}
        if comm.rank == 0:
            from model.studies.runs import toml_text

            out.mkdir(parents=True, exist_ok=True)
            files["summary"].write_text(json.dumps(self.summary(), indent=2, default=float) + "\n")
            self.table.to_csv(files["table"], index=False)
            document = apply(config.document, self.parameters)
            files["config"].write_text(toml_text(document))
            self.plot(files["png"])
        comm.barrier()
        return files

    def plot(self, path: Path) -> None:
        """Measured (points) against start (dashed) and fitted (line) over the load factor, a panel per quantity."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        names = list(dict.fromkeys(self.table["quantity"]))
        fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.6), squeeze=False)
        for ax, name in zip(axes[0], names):
            rows = self.table[self.table["quantity"] == name].sort_values("load_factor")
            t = rows["load_factor"].to_numpy()
            ax.plot(t, rows["start"], "--", color="0.6", label="start")
            ax.plot(t, rows["fitted"], "-", color="C0", label="fitted")
            sigma = rows["sigma"].to_numpy()
            ax.errorbar(t, rows["measured"], yerr=sigma if np.all(np.isfinite(sigma)) else None, fmt="o", color="C3",
                        ms=4, capsize=2, label="measured")
            ax.set_xlabel("load factor")
            ax.set_title(name, fontsize=10)
            ax.grid(alpha=0.3)
        axes[0][0].legend(fontsize=8)
        shown = ", ".join(f"{k.split('.')[-1]} = {v:.4g} ± {self.std[k]:.2g}" for k, v in self.parameters.items())
        fig.suptitle(f"calibration: {shown}", fontsize=10)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)


def _listed(matrix: np.ndarray) -> list[list[float | None]]:
    return [[None if not np.isfinite(v) else float(v) for v in row] for row in np.asarray(matrix)]


def _displacement(problem: Any, function: fem.Function) -> fem.Function:
    """The displacement part of a Function of the problem's space (collapsed in the mixed formulation)."""
    return function.sub(0).collapse() if problem.formulation == "mixed" else function


def calibrate(config: RunConfig | str | Path, data: pd.DataFrame | str | Path, fit: Sequence[str],
              bounds: Mapping[str, tuple[float | None, float | None]] | None = None, out: str | Path | None = None,
              max_evaluations: int = 50, comm: MPI.Comm = MPI.COMM_WORLD) -> CalibrationResult:
    """Fit the keys ``fit`` of ``config`` (a RunConfig or a file) to ``data`` (module docstring); with ``out`` the
    files are written there. Collective over ``comm``."""
    if not isinstance(config, RunConfig):
        from model.config import read

        path = Path(config)
        config = parse(read(path), path.parent)
    calibration = Calibration(config, data, fit, bounds, comm)
    result = calibration.fit(max_evaluations=max_evaluations)
    calibration.solver.destroy()
    if out is not None:
        result.write(out, config, comm)
    return result


__all__ = ["Calibration", "CalibrationResult", "Evaluation", "FitParameter", "Quantity", "calibrate",
           "constant_derivative", "fit_parameters", "parse_quantity", "read_data"]
