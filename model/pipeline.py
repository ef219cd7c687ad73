"""The pipeline of one run: config -> domain -> fields -> problem -> solver -> steps -> output.

    build(config)   the Domain (model.domain), the fields on it (fibres, activation, shape targets:
                    model.fields), the ElasticityProblem with every load, boundary condition, bone tie
                    and contact term (model.problem), and the probes. Every name the configuration
                    uses (regions, boundaries, probes inside the body or snapped onto it, full and
                    non-overlapping material coverage) is checked here and raises ConfigError naming
                    the key, before any solve.
    run(config)     the solver [solver] asks for (model.solvers), load steps 0 -> 1 with cut-back, or
                    time steps of a [dynamics] scheme, and after every attempted step summary.json,
                    the XDMF/VTU time series and finally the PNG (model.output).

summary.json is rewritten after every attempted step, so a failed run keeps what it did. Each
converged step records probes, reactions and the energies (strain_energy, active_energy,
contact/sliding penalty energies, load_potential, total_potential: ElasticityProblem.energies; plus
contact, sliding and, in a dynamic run, time and kinetic energy); a failed attempt records its SNES
reason and is followed by a cut-back.

One run per output folder: before anything is solved or written, the files an earlier run's
summary.json accounts for are removed (model.output.writer.remove_earlier_run; a user's other files
stay), and the new summary.json lists in "files" every file this run wrote there, kept current.

Interruption and restart: SIGINT and SIGTERM (on any rank; mpirun forwards them) set a flag that every
rank checks collectively (an allreduce) after each attempted step, so all ranks stop at the same step:
the step being solved when the signal came is finished and recorded, the outputs are complete (each
step's XDMF part is closed when written), summary.json says status "interrupted" with "signal" and
"last_completed_step", and run() raises Interrupted (the CLI exits 128 + the signal number: 130, 143).
A signal before the first step is checked after build (the output folder is left as it was) and before the
first step (summary.json "interrupted"); gmsh's hold on SIGINT and the command line's start-up: model.signals.
After every converged step a checkpoint is written (model.output.checkpoint) and summary.json's
"checkpoint" names it. ``run(config, DIR, restart=True)`` (``--restart DIR``) keeps the earlier run's
files and summary steps up to that checkpoint, restores the state (solution, dynamics' u_n, v_n, a_n,
time, contact multipliers, load factor and the cut-back increment) and goes on, appending to the same
XDMF series and VTU numbering; summary.json then covers every step and lists the restarts in "restarts".
The restart needs the same problem (only output.*, solver.*, loading.max_cutbacks and loading.max_steps may
change: a restart of another configuration is refused naming the first key that differs, model.config.restart),
not the same number of ranks (model.output.checkpoint).

In a dynamic run the "load factor" passed to expressions, activation curves and bone motions is the
time t, and constant loads are scaled by min(t / load_ramp, 1).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

import forms
from model import compat
from model.config import RunConfig
from model.config.expressions import compile_expression, uses_load_factor
from model.domain import Domain, Probes, make_domain, place_probes
from model.errors import ConfigError, OutputFailed, SolveFailed, os_error_message
from model.fields.activation import ActivationField
from model.fields.fibres import FibreField, solve_laplace
from model.fields.targets import TargetField
from model.output.checkpoint import read_checkpoint, remove_checkpoint, write_checkpoint
from model.output.writer import SUMMARY, ResultWriter, discard, named, on_rank0, remove_earlier_run, write_json_atomic
from model.problem import ElasticityProblem
from model.problem.conflicts import Condition, Load, check_conditions
from model.problem.measurements import Volumes, reactions, shared_reactions
from model.problem.parameters import candidates, curve_constants
from model.signals import Interrupted, StopFlag
from model.solvers import linear, stability
from model.solvers.loadstepping import continuation, step_loads
from model.solvers.newton import NewtonSolver, free_garbage
from model.solvers.options import check_option_values

log = logging.getLogger(__name__)


@dataclass
class Setup:
    domain: Domain
    problem: ElasticityProblem
    probes: Probes
    targets: list[TargetField]
    fibres: fem.Function | None = None
    activation: ActivationField | None = None
    contacts: list[Any] = field(default_factory=list)  # model.problem.contact objects
    sliding: list[Any] = field(default_factory=list)  # model.problem.bones.SlidingConstraint
    render: Any = None  # model.fields.embedding.Embedding of output.render_mesh


def _parameter_curves(index: int, material: Any, problem: ElasticityProblem) -> Callable[[float], None]:
    """The load hook that sets material ``index``'s held parameters (model.problem.parameters) to its law at the
    load factor t, the law made again from the curves' values (E(t), nu(t) -> mu(t), lmbda(t)). ConfigError
    naming the keys when a curve changes a number the law uses outside UFL (it cannot be held, so it cannot
    follow a curve)."""
    curves = material.parameter_curves
    held = problem.held_parameters[index]
    changing = curve_constants(material)
    fixed = sorted(changing - set(held))
    if fixed:
        law = problem.materials[index][1].name
        raise ConfigError(f"material[{index}].{', '.join(curves)}: the curve changes {', '.join(fixed)}, which {law} "
                          "uses outside UFL (a number in its formulas: it cannot be a runtime value), so it cannot "
                          "follow a curve; give it a number")
    log.info("material[%d]: %s follow load curves (held: %s)", index, ", ".join(curves), ", ".join(sorted(changing)))

    def update(t: float) -> None:
        values = candidates(material.law_at(t))
        for name in changing:
            held[name].value = values[name]

    update(0.0)
    return update


def _check_fibre_names(config: RunConfig, domain: Domain) -> None:
    for i, m in enumerate(config.materials):
        for which in ("fibres", "sheets"):
            spec = getattr(m, which)
            if spec is None or spec.type != "laplace":
                continue
            for k in ("origin", "insertion"):
                error = domain.boundary_error(getattr(spec, k))
                if error:
                    raise ConfigError(f"material[{i}].{which}.{k}: {error}")
            for j, r in enumerate(spec.regions):
                error = domain.region_error(r)
                if error:
                    raise ConfigError(f"material[{i}].{which}.regions[{j}]: {error}")


def _fibre_fields(config: RunConfig, domain: Domain, attribute: str = "fibres",
                  name: str = "fibre_direction") -> fem.Function | None:
    """One DG0 vector Function for all materials with ``attribute`` (fibres: a0; sheets: s0), each setting its
    region's cells."""
    if not any(getattr(m, attribute) is not None for m in config.materials):
        return None
    function = fem.Function(compat.function_space(domain.mesh, "DG", 0, (3,)), name=name)
    potentials: dict[tuple[str, str, tuple[str, ...]], fem.Function] = {}
    for i, m in enumerate(config.materials):
        spec = getattr(m, attribute)
        if spec is None:
            continue
        field = FibreField(domain, m.region, function=function)
        key = f"material[{i}].{attribute}"
        try:
            if spec.type == "constant":
                field.constant(spec.origin, spec.insertion)  # type: ignore[arg-type]
            elif spec.type == "laplace":
                regions = spec.regions or (m.region,)
                which = (str(spec.origin), str(spec.insertion), tuple(regions))
                if which not in potentials:
                    try:
                        potentials[which] = solve_laplace(domain, *which)
                    except ValueError as err:
                        raise ConfigError(f"{key}.regions: {err}; name the regions the fibres run through "
                                          "(fibres.regions)") from None
                field.laplace(which[0], which[1], potential=potentials[which])
            else:
                try:
                    array = np.load(spec.file, allow_pickle=False)  # type: ignore[arg-type]
                except (OSError, ValueError) as err:
                    raise ConfigError(f"{key}.file: cannot read {spec.file}: {str(err).splitlines()[0]}") from None
                field.from_cell_array(array)
        except ValueError as err:
            if isinstance(err, ConfigError):
                raise
            where = {"constant": "insertion", "laplace": "regions", "file": "file"}[spec.type]
            raise ConfigError(f"{key}.{where}: {err}") from None
    return function


def _check_names(config: RunConfig, domain: Domain) -> None:
    regions = sorted(domain.regions)
    for key, error in [*((f"material[{i}].region", domain.region_error(m.region))
                         for i, m in enumerate(config.materials)),
                       *((f"boundary[{i}].on", domain.boundary_error(b.on)) for i, b in enumerate(config.boundaries)),
                       *((f"body_force[{i}].region", domain.region_error(f.region))
                         for i, f in enumerate(config.body_forces))]:
        if error:
            raise ConfigError(f"{key}: {error}")
    comm = domain.mesh.comm
    tdim = domain.mesh.topology.dim
    num_owned = domain.mesh.topology.index_map(tdim).size_local
    count = np.zeros(num_owned, dtype=np.int32)
    owner = np.full(num_owned, -1)
    for i, m in enumerate(config.materials):
        cells = domain.region_cells(m.region)
        cells = cells[cells < num_owned]
        clash = comm.allreduce(int(np.max(owner[cells], initial=-1)), op=MPI.MAX)
        if clash >= 0:
            raise ConfigError(f"material[{i}].region: {m.region!r} overlaps the region of material[{clash}]")
        owner[cells] = i
        count[cells] += 1
    uncovered = comm.allreduce(int(np.sum(count == 0)), op=MPI.SUM)
    if uncovered:
        raise ConfigError(f"material: {uncovered} cells are in no material's region (use region = \"all\" "
                          f"or cover regions {', '.join(regions)})")


def build(config: RunConfig, comm: MPI.Comm = MPI.COMM_WORLD) -> Setup:
    """Domain, problem with all loads and boundary conditions, and probes of a configuration."""
    domain = make_domain(config.mesh, comm)
    _check_names(config, domain)
    probes = place_probes(domain.mesh, config.probes, config.units.unit("length"))
    _check_fibre_names(config, domain)
    disc = config.discretization
    fibres = _fibre_fields(config, domain)
    sheets = _fibre_fields(config, domain, "sheets", "sheet_direction")
    activation = None
    if any("alpha" in forms.law_fields(m.law) for m in config.materials):
        activation = ActivationField(domain)
    materials, targets = [], []
    for i, m in enumerate(config.materials):
        law = m.law
        if fibres is not None and "a0" in forms.law_fields(law):
            law = dataclasses.replace(law, a0=fibres)
        if sheets is not None and "s0" in forms.law_fields(law):
            law = dataclasses.replace(law, s0=sheets)
        if activation is not None and "alpha" in forms.law_fields(law):
            activation.add(m.region, m.activation)
            law = dataclasses.replace(law, alpha=activation.function)
        if "S" in forms.law_fields(law):
            source = m.fields.get("S")
            key = "S_function" if callable(source) else "S_file" if np.ndim(source) == 3 else "S"
            try:
                target = TargetField(domain.mesh, domain.region_cells(m.region), source)
            except (ValueError, forms.ParameterError) as err:
                raise ConfigError(f"material[{i}].{key}: {err}") from None
            law = dataclasses.replace(law, S=target.function)
            targets.append(target)
        materials.append((m.region, law))
    problem = ElasticityProblem(domain, materials, disc.degree, disc.quadrature_degree, disc.formulation)
    for i, m in enumerate(config.materials):
        if m.parameter_curves:
            problem.add_load_hook(_parameter_curves(i, m, problem))
    for target in targets:
        if target.procedural:
            problem.add_load_hook(target.update)
    if fibres is not None:
        problem.cell_fields["fibre_direction"] = fibres
    if sheets is not None:
        problem.cell_fields["sheet_direction"] = sheets
    if activation is not None:
        problem.add_load_hook(activation.update)
        problem.cell_fields["activation"] = activation.function
    bones = {b.name: b for b in config.bones}
    sliding = []
    conditions: list[Condition] = []  # the Dirichlet conditions and loads by key: check_conditions
    loads: list[Load] = []
    for i, b in enumerate(config.boundaries):
        before = len(problem.dirichlet)
        if b.type == "attached":
            from model.problem.bones import attach

            attach(problem, b.on, bones[b.bone].motion)  # type: ignore[index]
        elif b.type == "sliding":
            from model.problem.bones import add_sliding

            bone = bones[b.bone]  # type: ignore[index]
            sliding.append(add_sliding(problem, b.on, bone.obstacle, b.penalty, bone.motion,  # type: ignore[arg-type]
                                       b.quadrature_degree))
        elif b.type == "displacement":
            try:
                if b.value:
                    problem.add_dirichlet(b.on, b.components, b.value, points=b.points)
                else:
                    values = [compile_expression(e, config.parameters) for e in b.expression]
                    problem.add_dirichlet(b.on, b.components, values, [uses_load_factor(e) for e in b.expression],
                                          points=b.points)
            except ValueError as err:  # a point that is not a node of the boundary
                j = int(str(err).split()[1]) if str(err).startswith("point ") else 0
                raise ConfigError(f"boundary[{i}].points[{j}]: {err}") from None
        elif b.type == "traction":
            problem.add_traction(b.on, b.value)
            loads.append(Load(f"boundary[{i}]", b.on, tuple(b.value)))
        else:
            problem.add_pressure(b.on, b.value[0])
            loads.append(Load(f"boundary[{i}]", b.on, None))
        conditions += [Condition(f"boundary[{i}]", entry, not getattr(b, "points", ()))
                       for entry in problem.dirichlet[before:]]
    check_conditions(problem, conditions, loads)  # two values for one dof, a load a condition drops: one line
    for f in config.body_forces:
        problem.add_body_force(f.region, f.value)
    contacts = []
    if config.contacts:
        from model.problem.contact import build_contact

        for i, c in enumerate(config.contacts):
            motion = bones[c.bone].motion if c.bone is not None else None
            contacts.append(build_contact(problem, c.spec, motion, key=f"contact[{i}]"))
    render = None
    if config.output.render_mesh is not None:
        from model.fields.embedding import Embedding

        try:
            render = Embedding.from_file(domain.mesh, config.output.render_mesh)
        except ValueError as err:
            raise ConfigError(f"output.render_mesh: {err}") from None
    return Setup(domain, problem, probes, targets, fibres, activation, contacts, sliding, render)


#: the energy keys of a converged step besides "<name>_energy" (ElasticityProblem.energies)
ENERGY_KEYS = ("strain_energy", "active_energy", "load_potential", "total_potential")


def units_summary(config: RunConfig) -> dict[str, str]:
    """summary.json's "units": the [units] system and the units of the reported quantities."""
    units = config.units
    return {"system": units.system, **{d: units.unit(d) for d in ("length", "force", "stress", "energy", "time")}}


@dataclass(frozen=True)
class RunResult:
    """What a run produced: its summary (as in summary.json), where its files are, and per-step series.

    ``probes[name]`` and ``reactions[boundary]`` are arrays (converged steps, 3), ``load_factors`` and
    ``energies[key]`` (strain_energy, active_energy, load_potential, total_potential, ...: every energy key
    of the steps) arrays over the converged steps; ``files`` maps "summary", "xdmf", "png", "vtu" and "render"
    (lists: the frames of output.render_mesh) to the paths that exist. ``energy`` is the former summary key
    "energy" (deprecated).
    """

    summary: dict[str, Any]
    directory: Path

    @property
    def status(self) -> str:
        return str(self.summary["status"])

    @property
    def converged_steps(self) -> list[dict[str, Any]]:
        return [s for s in self.summary["steps"] if s["converged"]]

    @property
    def load_factors(self) -> np.ndarray:
        return np.array([s["load_factor"] for s in self.converged_steps])

    @property
    def energies(self) -> dict[str, np.ndarray]:
        """Per energy key of the converged steps (ENERGY_KEYS and "<name>_energy"), its values (NaN where a
        step has none, e.g. load_potential with a follower pressure)."""
        steps = self.converged_steps
        keys = dict.fromkeys(k for s in steps for k in s if k.endswith("_energy") or k in ENERGY_KEYS)
        keys.pop("kinetic_energy", None)
        return {k: np.array([np.nan if s.get(k) is None else s[k] for s in steps]) for k in keys}

    @property
    def energy(self) -> np.ndarray:
        """Deprecated: the stored energy the summary used to call "energy", int psi(F; alpha) dx plus the
        added (contact, sliding) energies = total_potential - load_potential. Use ``energies``."""
        import warnings

        warnings.warn("RunResult.energy is deprecated: use RunResult.energies['strain_energy'] (passive), "
                      "['active_energy'] or ['total_potential']", DeprecationWarning, stacklevel=2)
        return np.array([sum(v for k, v in s.items() if k.endswith("_energy") and k != "kinetic_energy")
                         for s in self.converged_steps])

    @property
    def probes(self) -> dict[str, np.ndarray]:
        return self._series("probes")

    @property
    def reactions(self) -> dict[str, np.ndarray]:
        return self._series("reactions")

    def _series(self, key: str) -> dict[str, np.ndarray]:
        steps = self.converged_steps
        names = steps[0][key] if steps else {}
        return {n: np.array([s[key][n] for s in steps]).reshape(len(steps), -1) for n in names}

    @property
    def files(self) -> dict[str, Any]:
        d = self.directory
        out: dict[str, Any] = {"summary": d / "summary.json", "vtu": sorted(d.glob("step_*.vtu")),
                               "render": sorted(p for p in (d / "render").glob("*_[0-9][0-9][0-9][0-9].*"))}
        for name, file in (("xdmf", d / "results.xdmf"), ("png", d / "deformed.png")):
            if file.exists():
                out[name] = file
        return out


def make_solver(problem: ElasticityProblem, config: RunConfig, contacts: list[Any] | None = None,
                objective: bool | None = None, scaled: dict[str, float] | None = None) -> Any:
    """The solver [solver] asks for: NewtonSolver (exact or projected tangent), ProjectiveDynamicsSolver,
    or, with contacts, model.solvers.contact's VI / Uzawa solvers (same interface). The line search is
    NewtonSolver's default (bt on the total potential where the problem has one, else basic:
    model.solvers.newton.default_line_search) unless solver.petsc_options sets snes_linesearch_type;
    ``objective`` (None: where there is a potential) is NewtonSolver's.

    Newton's linear solver is the preset ``solver.linear`` resolves to for this problem's size and formulation
    (model.solvers.linear.resolve; ConfigError before any solve for a preset or fieldsplit options the problem
    cannot take), its options under ``petsc_options`` (the user's win). The choice is the solver's
    ``linear_choice``. ``scaled``: the options with a unit set for this body (the run's
    ScaleCheck.newton_options: snes_atol relative to its force scale, the line search's largest step relative to
    its size), below the user's.
    """
    solver = config.solver
    if solver.method == "projective_dynamics":
        from model.solvers.projective_dynamics import ProjectiveDynamicsSolver

        options = {**config.petsc_options, "pd_max_iterations": solver.pd_max_iterations,
                   "pd_rtol": solver.pd_rtol, "pd_atol": solver.pd_atol}
        return ProjectiveDynamicsSolver(problem, options)
    vi = _vi(config)
    choice = linear.resolve(problem, solver.linear, config.petsc_options, vi=vi)
    defaults = {**choice.options, **(scaled or {})}
    if contacts:
        from model.solvers.contact import make_contact_solver

        made = make_contact_solver(problem, contacts, config.petsc_options, tangent=solver.tangent,
                                   defaults=defaults, objective=objective, matrix=solver.matrix)
    else:
        made = NewtonSolver(problem, config.petsc_options, tangent=solver.tangent, defaults=defaults,
                            objective=objective, matrix=solver.matrix)
    made.linear_choice = choice
    log.info("linear solver: %s (%s asked, %d dofs)", choice.preset, choice.requested, choice.dofs)
    return made


def _vi(config: RunConfig) -> bool:
    """Whether a [[contact]] uses method "vi" (SNES VI: the direct preset, no nested Jacobian)."""
    return any(getattr(c, "method", None) == "vi" for c in config.contacts)


def _check_matrix(problem: ElasticityProblem, config: RunConfig, contacts: list[Any] | None) -> None:
    """ConfigError for [solver] matrix = "nest" where the nested Jacobian cannot serve (linear.matrix_kind with the
    preset and options the solver will have), before the scale check's solve."""
    solver = config.solver
    if solver.method != "newton" or solver.matrix != "nest":
        return
    vi = _vi(config)
    choice = linear.resolve(problem, solver.linear, config.petsc_options, vi=vi)
    linear.matrix_kind(problem, "nest", {**choice.options, **config.petsc_options}, tangent=solver.tangent,
                       bounds=vi and bool(contacts))


def newton_of(solver: Any) -> NewtonSolver | None:
    """The NewtonSolver inside a solver (itself, or the one a contact solver wraps), or None (Projective Dynamics)."""
    while solver is not None and not isinstance(solver, NewtonSolver):
        solver = getattr(solver, "newton", getattr(solver, "inner", None))
    return solver


def _solver_summary(config: RunConfig, solver: Any) -> dict[str, Any]:
    """summary.json's "solver": method, tangent and, for Newton, the linear preset used (``linear``), the one
    asked for, the dof count it was chosen by and every PETSc option in effect (defaults, preset, user's)."""
    out: dict[str, Any] = {"method": config.solver.method, "tangent": config.solver.tangent}
    newton = newton_of(solver)
    choice = getattr(solver, "linear_choice", None)
    if newton is not None and choice is not None:
        out.update(choice.as_dict(newton.options))
        out["matrix"] = newton.matrix
    return out


def _linear_per_newton(solver: Any) -> dict[str, list[int]]:
    """{"linear_iterations_per_newton": [...]} of the last solve (a SNES monitor's counts), or {}."""
    newton = newton_of(solver)
    monitor = getattr(newton, "linear_monitor", None)
    return {"linear_iterations_per_newton": list(monitor.per_newton)} if monitor is not None else {}


def _dynamics(setup: Setup, config: RunConfig) -> Any:
    """The time integrator of a dynamic run (before the solver: it adds inertia and damping terms)."""
    from model.solvers.dynamics import Dynamics

    spec = config.dynamics
    problem = setup.problem
    density = {m.region: m.density for m in config.materials}
    problem.load_scale = spec.load_scale
    dynamics = Dynamics(problem, density if "all" not in density else density["all"], spec.scheme,
                        spec.rayleigh, spec.dt, rho_infinity=spec.rho_infinity)
    return dynamics


def _initial_equilibrium(setup: Setup, config: RunConfig) -> None:
    """u_0 of a dynamic run = the quasi-static solution at t = 0 (before inertia is added to the forms).

    Reached by continuation: the activation goes from 0 to its t = 0 values in loading.steps steps,
    cut back on failure (a muscle activated at once from rest would invert elements in Newton's
    first iterate).
    """
    problem = setup.problem
    problem.load_scale = config.dynamics.load_scale
    problem.set_load_factor(0.0)
    activation = setup.activation
    full = activation.function.x.array.copy() if activation is not None else None
    solver = make_solver(problem, config, setup.contacts)

    def activate(fraction: float) -> None:
        if activation is not None:
            activation.function.x.array[:] = fraction * full
        problem.invalidate_state()

    outcome = continuation(solver, activate, config.loading.steps, config.loading.max_cutbacks,
                           config.loading.growth, what="activation step")
    solver.destroy()
    problem._forms = None  # the dynamic run compiles its own forms (inertia and damping added)
    if not outcome:
        raise SolveFailed(f"the initial equilibrium (dynamics.initial = \"equilibrium\") failed: {outcome.reason}")
    log.info("initial equilibrium reached (activation continuation)")


def _earlier_summary(directory: Path, comm: MPI.Comm) -> dict[str, Any]:
    """The summary.json of the run a restart continues (rank 0 reads, every rank gets it); ConfigError when it
    is missing or has no checkpoint."""
    path = Path(directory) / SUMMARY
    summary, error = None, None
    if comm.rank == 0:
        try:
            summary = json.loads(path.read_text())
        except (OSError, ValueError) as err:
            error = f"--restart {directory}: cannot read {path}: {str(err).splitlines()[0]}"
        else:
            if not isinstance(summary, dict) or not isinstance(summary.get("checkpoint"), dict):
                error = (f"--restart {directory}: {path} has no checkpoint (the run stopped before its first "
                         "converged step, or was written by a version without checkpoints)")
    summary, error = comm.bcast((summary, error), root=0)
    if error:
        raise ConfigError(error)
    return summary  # type: ignore[return-value]


def _problem_record(config: RunConfig, directory: Path, comm: MPI.Comm,
                    restart: bool) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The record every checkpoint keeps of the problem (the SHA-256 of each file a key that defines the problem
    names: model.config.restart) and, for a restart, the earlier run's summary once the configuration is found to
    continue its problem: a ConfigError naming the first key that differs otherwise (before the mesh is built and
    before anything in DIR is touched)."""
    from model.config.restart import file_digests, same_problem

    earlier = _earlier_summary(directory, comm) if restart else None
    found: Any = None
    if comm.rank == 0:
        record = {"files": file_digests(config.document)}
        found = (record, *(same_problem(config.document, record["files"], earlier) if earlier else (None, None)))
    record, error, warning = comm.bcast(found, root=0)
    if error:
        raise ConfigError(f"--restart {directory}: {error}")
    if warning and comm.rank == 0:
        log.warning("--restart %s: %s", directory, warning)
    return record, earlier


def _check_control(config: RunConfig, setup: Setup, restart: bool) -> None:
    """ConfigError (before any solve) for [loading] control = "arc_length" / "volume" where it cannot drive the run:
    it needs Newton on a quasi-static run without contact, load hooks (activation, bones) or Dirichlet values that
    move with the load, a restart-free run, and for "volume" a pressure boundary and a volume_ratio."""
    loading = config.loading
    if loading.control == "load":
        return
    key = "loading.control"
    why = None
    if config.dynamics is not None and config.dynamics.is_dynamic:
        why = "a dynamic run is driven by time"
    elif config.solver.method != "newton":
        why = f"it needs solver.method = \"newton\", not {config.solver.method!r}"
    elif setup.contacts or config.contacts:
        why = "contact is not supported with path following"
    elif restart:
        why = "--restart continues load-controlled runs only"
    elif setup.problem.load_hooks:
        why = "the load factor also drives an activation, bone motion or targets (not a load vector)"
    else:
        comm = setup.domain.mesh.comm
        moving = any(f is not None or np.any(ref != 0.0) for entry in setup.problem.dirichlet
                     for ref, f in zip(entry.reference, entry.of_load_factor))
        if comm.allreduce(moving, op=MPI.LOR):
            why = "a displacement condition moves with the load factor (path following drives forces only)"
    if why is not None:
        raise ConfigError(f"{key}: {loading.control!r}: {why}")
    if loading.control == "volume":
        pressures = [b.on for b in config.boundaries if b.type == "pressure"]
        if loading.volume_boundary is None:
            raise ConfigError(f"loading.volume_boundary: control = \"volume\" needs the pressure boundary whose cavity "
                              f"volume is prescribed (one of {pressures or 'none: there is no pressure boundary'})")
        if loading.volume_boundary not in pressures:
            raise ConfigError(f"loading.volume_boundary: {loading.volume_boundary!r} carries no pressure (pressure "
                              f"boundaries: {', '.join(map(repr, pressures)) or 'none'})")
        if loading.volume_ratio is None:
            raise ConfigError("loading.volume_ratio: control = \"volume\" needs the final volume over the rest volume")


#: a file of RESERVE_BYTES kept in the output folder during a run and removed when summary.json must be written on a
#: full disk (its status "failed" with the reason) or at the end
RESERVE = ".space_reserve"
RESERVE_BYTES = 4 << 20


def _guarded(comm: MPI.Comm, where: Path, action: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """``action(*args, **kwargs)``, with an OSError (named by its file, else by ``where``) on any rank (a full disk,
    a folder turned read-only: most writes are rank 0's) raised on every rank as one OutputFailed naming the path
    (collective: the other ranks would otherwise wait in the next solve for ever)."""
    failure = None
    result = None
    try:
        result = action(*args, **kwargs)
    except OSError as err:
        failure = os_error_message(named(err, where))
    failures = [f for f in comm.allgather(failure) if f]
    if failures:
        raise OutputFailed(f"{failures[0]}: free space or pick a writable --out; the steps written before are "
                           "kept (continue with --restart where a checkpoint was written)")
    return result


def _check_output_folder(directory: Path, comm: MPI.Comm) -> None:
    """Before anything is deleted or solved: ConfigError when the output path (or a folder above it) is an existing
    file, OutputFailed when the folder cannot be made or written (a probe file is written and removed, and the
    folders made for it). Collective."""
    failure: tuple[str, str] | None = None
    if comm.rank == 0:
        taken = next((p for p in (directory, *directory.parents) if p.exists() and not p.is_dir()), None)
        if taken is not None:  # the folder, or a folder above it, is a file
            failure = ("config", f"output.dir (--out): {taken} is a file, not a folder: give a folder's path")
        else:
            probe = directory / f".write_check_{os.getpid()}"
            made = [p for p in (directory, *directory.parents) if not p.exists()]  # what the probe creates
            try:
                directory.mkdir(parents=True, exist_ok=True)
                probe.write_bytes(b"")
                probe.unlink()
                for folder in made:  # left as found: the run makes its folder when it writes (a later error: none)
                    folder.rmdir()
            except OSError as err:
                failure = ("os", os_error_message(err, "cannot write the results there"))
    failure = comm.bcast(failure, root=0)
    if failure is not None:
        kind, message = failure
        raise ConfigError(message) if kind == "config" else OutputFailed(message)


def run(config: RunConfig, out: Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD, *,
        objective: bool | None = None, restart: bool = False) -> dict[str, Any]:
    """Run a configuration; returns the summary (also written to OUT/summary.json).

    ``objective``: whether SNES gets the total potential as its objective (make_solver; None, the default:
    where the problem has one). False gives the residual-norm line searches (benchmarks/line_search.py).
    ``restart``: continue the earlier run in OUT from its last checkpoint (module docstring).

    Raises ConfigError before any solve on bad input, SolveFailed (after writing
    the summary) when SNES fails beyond the allowed cut-backs, Interrupted after SIGINT or SIGTERM.
    """
    with StopFlag() as stop:
        return _run(config, out, comm, objective, restart, stop)


def _stop_before_solve(stop: StopFlag, comm: MPI.Comm, when: str) -> None:
    """Interrupted when a rank got SIGINT or SIGTERM so far (collective; model.signals)."""
    signum = stop.check(comm)
    if signum:
        raise Interrupted(signum, f"interrupted by {signal.Signals(signum).name} {when}")


def _run(config: RunConfig, out: Path | None, comm: MPI.Comm, objective: bool | None, restart: bool,
         stop: StopFlag) -> dict[str, Any]:
    start = time.perf_counter()
    directory = Path(out) if out is not None else config.output.dir
    # a restart of another problem is refused before the mesh is built and before anything in DIR is touched
    problem_record, earlier = _problem_record(config, directory, comm, restart)
    setup = build(config, comm)
    _stop_before_solve(stop, comm, "before the solve started; the output folder is as it was")  # model.signals
    check_option_values(config.petsc_options)  # values PETSc would refuse: before anything is deleted or solved
    versions, host = comm.bcast((compat.versions(), compat.host()) if comm.rank == 0 else None, root=0)
    if comm.rank == 0:
        log.info("dolfinx %s, PETSc %s, %s", versions["dolfinx"], versions["petsc"], versions["os"])
    problem = setup.problem
    _check_control(config, setup, restart)  # arc length / volume control: what they cannot drive, before any solve
    _check_output_folder(directory, comm)  # a file, or a folder the system will not let us write: one line
    if earlier is None:
        _guarded(comm, directory, remove_earlier_run, directory, comm)  # before any solve, before anything is written
    from model.solvers.scale import scale_check

    _check_matrix(problem, config, setup.contacts)  # [solver] matrix = "nest" where it cannot serve: before any solve
    support_warnings: list[str] = []
    if config.solver.allow_rigid_modes:
        support_warnings.append("the support check was skipped (solver.allow_rigid_modes = true): a rigid-body mode "
                                "nothing holds is not removed, and makes the Newton matrix singular")
    elif not (config.dynamics is not None and config.dynamics.is_dynamic):
        from model.problem.supports import check_supports  # every mesh piece held (a dynamic run needs no supports)

        support_warnings = check_supports(problem, setup.contacts, setup.sliding)
    scale = scale_check(problem, config)  # before any solve: loads, moduli and size against the units
    dynamic = config.dynamics is not None and config.dynamics.is_dynamic
    if dynamic and config.dynamics.initial == "equilibrium" and earlier is None:
        _initial_equilibrium(setup, config)
    dynamics = _dynamics(setup, config) if dynamic else None
    solver = make_solver(problem, config, setup.contacts, objective=objective,
                         scaled=scale.newton_options(setup.domain.mesh.geometry.dim))
    checkpoint = earlier["checkpoint"] if earlier is not None else None
    writer = _guarded(comm, directory, ResultWriter, problem, directory, config.output.xdmf, config.output.vtu,
                      config.output.png, stress_unit=config.units.unit("stress"),
                      length_unit=config.units.unit("length"), resume=checkpoint["step"] if checkpoint else 0,
                      files=[f for f in earlier.get("files", []) if not f.startswith("checkpoint_")]
                      if earlier else None, render=setup.render)
    reserve = directory / RESERVE  # space kept for summary.json's last word should the disk fill up
    _guarded(comm, directory, on_rank0, comm, reserve.write_bytes, bytes(RESERVE_BYTES))
    msh = setup.domain.mesh
    imap = problem.space.dofmap.index_map
    volumes = Volumes(problem)
    summary: dict[str, Any] = {
        "dofs": imap.size_global * problem.space.dofmap.index_map_bs,
        "cells": msh.topology.index_map(msh.topology.dim).size_global,
        "ranks": comm.size,
        # the degrees used: the materials' energy, and the loads / surfaces / inertia (quadrature_degrees)
        "quadrature_degree": {"energy": problem.energy_quadrature_degree, "loads": problem.quadrature_degree},
        "region_volumes": volumes.reference,
        "mesh_quality": {k: setup.domain.quality[k] for k in ("min_radius_ratio", "worst_cell_centroid", "measure",
                                                              "min_jacobian_ratio")
                         if k in setup.domain.quality},
        "boundary_areas": volumes.areas,
        **({"render_mesh": setup.render.summary()} if setup.render is not None else {}),
        "probe_points": setup.probes.points_by_name(),
        "solver": _solver_summary(config, solver),
        "versions": versions,
        "host": host,  # rank 0's cores: cpu_count, cpu_affinity (None where the OS does not say)
        "config": config.document,  # the document after overrides, files made absolute (None: not from parse)
        "units": units_summary(config),
        "wall_time_s": 0.0,
        "status": "running",
        "steps": [],
    }
    line_search = getattr(solver, "line_search", None)
    if line_search is not None:  # the one SNES uses: {"type": "bt", "merit": "total_potential"}, ...
        summary["solver"]["line_search"] = line_search
    if setup.probes.snapped:
        summary["snapped_probes"] = setup.probes.snapped
    previous_time = 0.0
    if earlier is not None:
        summary["steps"] = earlier["steps"][: checkpoint["summary_steps"]]
        where = {"time": checkpoint["time"]} if dynamic else {"load_factor": checkpoint["load_factor"]}
        summary["restarts"] = [*earlier.get("restarts", []), {"from_step": checkpoint["step"], **where}]
        previous_time = float(earlier.get("wall_time_s", 0.0))
    summary["scale_check"] = scale.figures
    summary.setdefault("warnings", []).extend([*support_warnings, *scale.warnings])
    if dynamic:
        spec = config.dynamics
        summary["dynamics"] = {"scheme": spec.scheme, "dt": spec.dt, "end_time": spec.end_time,
                               "rayleigh": list(spec.rayleigh)}

    saved_checkpoint: dict[str, Any] = dict(checkpoint) if checkpoint else {}

    def save() -> None:
        _guarded(comm, directory, _save)

    def _save() -> None:
        summary["wall_time_s"] = previous_time + time.perf_counter() - start
        if saved_checkpoint:
            summary["checkpoint"] = dict(saved_checkpoint)
        summary["files"] = sorted({*writer.files, *saved_checkpoint.get("files", []), SUMMARY})
        if comm.rank == 0:
            write_json_atomic(directory / "summary.json", summary)

    def state() -> dict[str, fem.Function]:
        functions = {"solution": problem.solution}
        if dynamics is not None:
            functions.update(u_n=dynamics.u_n, v_n=dynamics.v_n, a_n=dynamics.a_n)
        for i, c in enumerate(setup.contacts):
            if isinstance(getattr(c, "multiplier", None), fem.Function):
                functions[f"multiplier_{i}"] = c.multiplier
        return functions

    def write_state(next_increment: float) -> int | None:
        """Checkpoint the converged state; returns the step of the checkpoint it replaces (remove it once
        summary.json names the new one)."""
        step = writer.count
        meta = {"step": step, "summary_steps": len(summary["steps"]), "load_factor": float(problem.time),
                "increment": next_increment, "problem": problem_record}
        if dynamics is not None:
            meta.update(time=dynamics.time, dissipated_energy=dynamics.dissipated_energy)
        files = write_checkpoint(directory, step, state(), meta)
        previous = saved_checkpoint.get("step")
        saved_checkpoint.clear()
        saved_checkpoint.update(meta, files=files)
        return previous if previous != step else None

    def record_step(t: float, r: Any, extra: dict[str, Any], next_increment: float) -> None:
        step: dict[str, Any] = {
            "load_factor": float(problem.load_factor.value) if dynamic else t,
            **extra,
            "newton_iterations": r.iterations,
            "linear_iterations": r.linear_iterations,
            **_linear_per_newton(solver),
            "converged": r.converged,
            "snes_reason": r.reason,
            "snes_reason_name": r.reason_name,
            "residual_norm": r.residual_norm,
        }
        if setup.activation is not None:
            step["activation"] = setup.activation.values(t)
        if not r.converged and getattr(r, "largest_residual", None):
            step["largest_residual"] = r.largest_residual
        if getattr(r, "admissibility", None):  # min det F over the material points, per region, and where
            step.update(r.admissibility)
        if r.converged:
            step.update(problem.energies())
            if dynamics is not None:
                step["kinetic_energy"] = dynamics.kinetic_energy()
            step["volumes"] = volumes.current()
            step["probes"] = setup.probes.evaluate(problem.displacement())
            residual = solver.unconstrained_residual()
            step["reactions"] = reactions(problem, residual)
            exclusive, shared = shared_reactions(problem, residual)
            if shared:  # dofs two boundaries constrain count in both reactions: what each has alone, what they share
                step["reactions_exclusive"] = exclusive
                step["reactions_shared"] = shared
            residual.destroy()
            if setup.contacts:
                from model.problem.contact import contact_report, pair_reports

                step["contact"] = contact_report(setup.contacts)
                pairs = pair_reports(setup.contacts)
                if pairs:
                    step["contact_pairs"] = pairs
            if setup.sliding:
                step["sliding"] = {c.surface: {"max_gap": c.max_gap(), "force": c.force()} for c in setup.sliding}
            _guarded(comm, directory, writer.write_step, t)
        summary["steps"].append(step)
        replaced = _guarded(comm, directory, write_state, next_increment) if r.converged else None
        save()
        if replaced is not None:
            _guarded(comm, directory, remove_checkpoint, directory, replaced, comm)
        if comm.rank == 0:
            n = len(summary["steps"])
            status = "converged" if r.converged else f"FAILED ({r.reason_name})"  # what follows: loadstepping
            what = "t" if dynamic else "load"
            log.info("step %3d  %s %.4f  newton %2d  |R| %.3e  %s", n, what, t, r.iterations, r.residual_norm,
                     status)
        signum = stop.check(comm)
        if signum:
            raise Interrupted(signum, f"interrupted by {signal.Signals(signum).name}")

    increment = None
    if checkpoint is not None:
        restored = {k: fem.Function(f.function_space) for k, f in state().items()}
        try:
            meta = read_checkpoint(directory, checkpoint["step"], restored)
        except ValueError as err:
            raise ConfigError(f"--restart {directory}: {err}") from None
        increment = meta["increment"]

    if dynamic:
        from model.solvers.dynamics import step_time

        problem.set_load_factor(0.0)
        dynamics.initialize(time=0.0, load_factor=0.0)
        if checkpoint is not None:
            problem.set_load_factor(meta["load_factor"])
            for name in ("u_n", "v_n", "a_n"):
                getattr(dynamics, name).x.array[:] = restored[name].x.array
            dynamics.time = float(meta["time"])
            dynamics.dissipated_energy = float(meta["dissipated_energy"])
        save()
        spec = config.dynamics
        stepping = lambda: step_time(  # noqa: E731
            solver, dynamics, spec.end_time, spec.dt,
            lambda rec: record_step(rec.time, rec.result, {"time": rec.time, "dt": rec.dt}, rec.next_increment),
            max_cutbacks=config.loading.max_cutbacks, growth=config.loading.growth, increment=increment)
    elif config.loading.control != "load":
        from model.solvers.pathfollowing import PathFollower, follow_path

        loading = config.loading
        problem.set_load_factor(0.0)
        try:
            follower = PathFollower(solver, loading.control, boundary=loading.volume_boundary,
                                    origin=list(loading.volume_origin), ratio=loading.volume_ratio)
        except ValueError as err:  # a nested matrix, no load, a cavity of no volume: one line naming the key
            solver.destroy()
            raise ConfigError(f"loading.control: {loading.control!r}: {err}") from None
        summary["control"] = {"type": loading.control, **({"boundary": loading.volume_boundary,
                                                             "rest_volume": follower.initial_volume,
                                                             "volume_ratio": loading.volume_ratio}
                                                            if loading.control == "volume" else {})}
        save()
        stepping = lambda: follow_path(  # noqa: E731
            follower, loading.steps, loading.step_cap, loading.max_cutbacks, loading.growth,
            lambda rec: record_step(rec.load_factor, rec.result, {"solve_time_s": rec.seconds, **rec.control},
                                    rec.next_increment))
    else:
        problem.set_load_factor(0.0 if checkpoint is None else meta["load_factor"])
        save()
        stepping = lambda: step_loads(  # noqa: E731
            solver, config.loading.steps, config.loading.max_cutbacks, config.loading.growth,
            lambda rec: record_step(rec.load_factor, rec.result, {"solve_time_s": rec.seconds}, rec.next_increment),
            increment=increment, diagnose=lambda state: stability.diagnose(newton_of(solver), state),
            max_attempts=max(1, config.loading.step_cap - len(summary["steps"])))  # a restart's earlier steps count
    if checkpoint is not None:
        problem.solution.x.array[:] = restored["solution"].x.array
        for i, c in enumerate(setup.contacts):
            if f"multiplier_{i}" in restored:
                c.multiplier.x.array[:] = restored[f"multiplier_{i}"].x.array
        problem.invalidate_state()
        if comm.rank == 0:
            log.info("restarted from step %d (load factor %.6g) of %s", checkpoint["step"], meta["load_factor"],
                     directory)
    try:
        _stop_before_solve(stop, comm, "before the first step")  # summary.json "interrupted" (model.signals)
        ok = stepping()
    except Interrupted as err:
        if comm.rank == 0:
            discard(reserve)
        summary["status"] = "interrupted"
        summary["signal"] = signal.Signals(err.signum).name
        summary["last_completed_step"] = writer.count
        writer.close()
        save()
        solver.destroy()
        if dynamics is not None:
            dynamics.destroy()
        free_garbage(msh.comm)
        if comm.rank == 0:
            then = f"continue with --restart {directory}" if saved_checkpoint else "no checkpoint: run it again"
            log.warning("%s: stopped after %d completed steps; summary.json says \"interrupted\"; %s", err,
                        writer.count, then)
        raise
    except OutputFailed as err:  # the disk: the steps written before are kept; summary.json "failed" if it can be
        summary["status"] = "failed"
        summary["failure"] = str(err)
        if comm.rank == 0:
            discard(reserve)  # the space summary.json needs on a full disk
        try:
            save()
        except OutputFailed:
            if comm.rank == 0:
                log.warning("summary.json could not be updated (it says \"running\" with the steps before)")
        solver.destroy()
        if dynamics is not None:
            dynamics.destroy()
        free_garbage(msh.comm)
        raise
    summary["status"] = "completed" if ok else "failed"
    if not ok:
        summary["failure"] = ok.reason
    if ok.stability is not None:  # the tangent's inertia and stiffness along the load where the stepping gave up
        summary["stability"] = ok.stability
    unused = getattr(solver, "unused_options", [])
    if unused:
        summary["unused_petsc_options"] = unused
    what = "t" if dynamic else "load factor"
    png = _guarded(comm, directory, writer.write_png, f"{what} {problem.time:.3g}")
    if png is not None:
        summary["png"] = png.name
    _guarded(comm, directory, writer.close)
    if comm.rank == 0:
        discard(reserve)
    save()
    solver.destroy()
    if dynamics is not None:
        dynamics.destroy()
    free_garbage(msh.comm)  # with the mesh alive: the parallel PETSc objects the collector freed (newton.free_garbage)
    if not ok:
        raise SolveFailed(f"{ok.reason}; results up to {what} {problem.time:.6g} are in {directory}")
    return summary
