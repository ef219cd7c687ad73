"""The scale check: before the first solve, do the loads, the moduli and the body's size fit together?

Units are any consistent system ([units] system names it: "SI" or "mm-MPa"); nothing converts them, so a
mesh in mm with moduli in Pa, or E in MPa with sigma_max in Pa, runs, and fails (or succeeds) far from
the intended problem. Two checks, run by model.pipeline.run after build and before any solve:

(a) The first load increment, linearised at the reference state. With t1 = 1 / loading.steps (the
    activation, prescribed motions and expressions at t1, constant loads scaled by t1) the increment du
    of Newton's first iterate from u = 0 solves

        J(0) du = -R(0; t1),   du = g(t1) on the Dirichlet dofs

    (J the problem's Jacobian form at u = 0, R its residual form; the mixed formulation solves for
    (du, dp) together), by one LU factorisation (MUMPS) below linear.AUTO_DOFS unknowns and from there by the
    `iterative` preset of model.solvers.linear (CG + GAMG with the rigid-body modes; GMRES + the Schur
    fieldsplit for the mixed formulation) with ksp_rtol ITERATIVE_RTOL = 1e-4, so that the check costs less
    than one Newton step of the run at any size (LU would take longer than the whole iterative run on large
    meshes). The solution must satisfy the system to DIRECT_MISFIT = 1e-6 (LU) or 10 ITERATIVE_RTOL relative,
    else the check falls back to the estimate below. Its strain

        strain = max over cells, and points of each cell, of max |eig(sym grad du)|

    (the small strain: du is a first-order quantity, whose Green-Lagrange strain would only add a
    second-order term the linearisation does not get right; rigid motions have none, so a body held by
    too few conditions still gives a meaningful figure) is reduced over ranks. Above STRAIN_LIMIT = 0.5 a
    warning names the largest load and the smallest modulus with their ratio, and loading.steps.
    Contact terms enter as far as they are in the residual (penalties); the bounds of VI contact do not.
    The fibre laws' curves have a kink at the fibre stretch lbar = 1 (the passive and tendon curves start
    there), which u = 0 sits on: which side's tangent Newton gets depends on the last bit of |a0| (the
    partition, the unit system). The check takes the side of stretch on every rank and in every system:
    it scales the fibre directions by 1 + FIBRE_STRETCH (1e-9) for the solve, and restores them.

    Fallback, an estimate instead of the solve, where the solve is not possible or not the first step:
    no Dirichlet dof (the tangent is singular: a body held by contact alone, or floating) and dynamic
    runs (inertia, loads ramped in time; the first increment is dt). Then

        strain ~ max( s1 |t| / G, s1 |p| / G, s1 |b| L / G, alpha(t1) sigma_max / G, s1 |u_D| / L )

    over tractions t, pressures p, body forces b, muscle fibre stresses and constant prescribed
    displacements u_D; G the smallest modulus (below), L the body's size, s1 the scale of constant loads
    in the first increment (t1, or load_scale(dt) in a dynamic run with t1 = dt). Shape targets,
    expressions and bone motions do not enter the estimate.

(b) The body's size and the moduli against the unit system: L, the diagonal of the mesh's bounding box
    (reduced over ranks), and per material its modulus (the first of E, mu, c1, C the table gives, else
    the law's value of one of them, else another stress parameter of the law, else its bulk parameter).
    Expected for soft tissue, with margin (the upper length bound admits the 10 m trunk example):

        SI:      1e-4 m <= L <= 20 m,     1 Pa <= modulus <= 1e10 Pa
        mm-MPa:  0.1 mm <= L <= 2e4 mm,   1e-6 MPa <= modulus <= 1e4 MPa     (the same bounds)

    Outside them a warning says which system the numbers look like (a mesh in mm with moduli in Pa:
    L in "m" beyond 20 with moduli in Pa).

The warnings are logged once (rank 0) and returned (the pipeline puts them in summary.json "warnings",
the figures in "scale_check"); the figures are reduced over ranks, so 1 and 2 ranks report the same.

This module lives in model.solvers: it needs the assembled problem (model.problem's forms and
Dirichlet data) and a linear solve with PETSc (the solvers' business), and names the configuration's keys
(model.config); model.pipeline, above both, runs it.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

import forms
from model import compat
from model.config import RunConfig
from model.errors import ConfigError
from model.fields.activation import activation_at
from model.problem import ElasticityProblem
from model.solvers import linear

log = logging.getLogger(__name__)

#: Newton's absolute tolerance per unit force scale (ScaleCheck.absolute_tolerance)
ATOL_PER_FORCE = 1e-16
#: the line search's largest step per unit body size (PETSc's default 1e8, absolute, at L = 1)
MAXSTEP_PER_LENGTH = 1e8
#: the first increment's strain above which the loads and moduli look inconsistent
STRAIN_LIMIT = 0.5
#: the fibre stretch the tangent is taken at (fibre directions scaled by 1 + FIBRE_STRETCH; module docstring)
FIBRE_STRETCH = 1e-9
_prefixes = itertools.count()
#: the relative residual the check's LU solution must reach, and the iterative preset's ksp_rtol (module docstring)
DIRECT_MISFIT = 1e-6
ITERATIVE_RTOL = 1e-4
#: (lowest, highest) body size and modulus expected per unit system (module docstring)
SIZE_BOUNDS = {"SI": (1e-4, 20.0), "mm-MPa": (0.1, 2e4)}
MODULUS_BOUNDS = {"SI": (1.0, 1e10), "mm-MPa": (1e-6, 1e4)}
_UNITS = {"SI": ("m", "Pa"), "mm-MPa": ("mm", "MPa")}
#: the parameters taken as a material's modulus, in order of preference
_MODULI = ("E", "mu", "c1", "C")


def number(value: float) -> str:
    """A figure for a message: 3 significant digits, exponent without padding (3.33e4, 9, 0.14)."""
    text = f"{value:.3g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


@dataclass(frozen=True)
class ScaleCheck:
    """What the check found: the figures (summary.json "scale_check") and the warnings (already logged)."""

    first_increment_strain: float
    method: str  # "linear solve" or "estimate"
    body_size: float
    moduli: list[float]
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def figures(self) -> dict[str, Any]:
        return {"first_increment_strain": self.first_increment_strain, "method": self.method,
                "body_size": self.body_size, "moduli": list(self.moduli), "time_s": self.seconds}

    def newton_options(self, dimension: int) -> dict[str, float]:
        """The PETSc options of Newton that carry a unit, set for this body: ``snes_atol`` (absolute_tolerance) and
        ``snes_linesearch_maxstep`` = MAXSTEP_PER_LENGTH x L (PETSc's fixed 1e8 cut every Newton step of a body
        1e12 m across to 1e8 m, so that 30 iterations did not converge at any load). Empty where no modulus or
        size is known: PETSc's fixed values stay."""
        options: dict[str, float] = {}
        atol = self.absolute_tolerance(dimension)
        if atol is not None:
            options["snes_atol"] = atol
            options["snes_linesearch_maxstep"] = MAXSTEP_PER_LENGTH * self.body_size
        return options

    def absolute_tolerance(self, dimension: int) -> float | None:
        """Newton's absolute tolerance on |R| for this body: ATOL_PER_FORCE x the force scale

            F_ref = max modulus x L^(d - 1)        (a force in 3D; per unit thickness in 2D)

        so that a body 1e-12 m across solves like one 1 m across (a fixed snes_atol = 1e-12 exceeds the whole
        residual of the small one, which then "converges" at u = 0 after 0 iterations, and is never reached by the
        large one). ATOL_PER_FORCE = 1e-16 is the round-off of |R| at unit strain and gives the former fixed 1e-12
        at F_ref = 1e4 (E = 1e4 Pa on a 1 m body). None (keep the fixed default) where no modulus is known."""
        moduli = [m for m in self.moduli if math.isfinite(m) and m > 0]
        if not moduli or not math.isfinite(self.body_size) or self.body_size <= 0:
            return None
        force = max(moduli) * self.body_size ** (dimension - 1)
        return ATOL_PER_FORCE * force if math.isfinite(force) and force > 0 else None


# --- what the configuration says ------------------------------------------------------------------------------------

def _law_value(law: forms.Law, name: str) -> float | None:
    """The law's value of parameter ``name`` (a user law keeps its values as pairs), None when it has none."""
    value = getattr(law, name, None)
    if value is None:
        value = dict(getattr(law, "values", ())).get(name)
    try:
        return float(value) if value is not None else None
    except (TypeError, ValueError):
        return None


def material_modulus(index: int, material: Any) -> tuple[str, float] | None:
    """(key, value) of a material's modulus: the first of E, mu, c1, C its table gives; else the law's value of
    one of them (a default); else another stress parameter of the law; else its bulk parameter (finite)."""
    law = material.law
    given = material.given_parameters
    stvk = getattr(law, "isotropic", None) == "stvk"
    names = [n for n in _MODULI if not (stvk and n == "c1")]
    for name in names:
        value = given.get(name)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and 0 < value < math.inf:
            return f"material[{index}].{name}", float(value)
    for name in names:
        value = _law_value(law, name)
        if value is not None and 0 < value < math.inf:
            return f"material[{index}].{name}", value
    entry = getattr(type(law), "entry", None) or forms.REGISTRY.get(law.name)
    fibre = getattr(law, "fibre_parameters", ())
    for p in entry.parameters if entry is not None else ():
        if p.unit.startswith("Pa") and p.name != law.bulk_parameter and p.name not in fibre:
            value = _law_value(law, p.name)
            if value is not None and 0 < value < math.inf:
                return f"material[{index}].{p.name}", value
    value = _law_value(law, law.bulk_parameter)
    if value is not None and 0 < value < math.inf:
        return f"material[{index}].{law.bulk_parameter}", value
    return None


@dataclass(frozen=True)
class _Load:
    key: str
    value: float  # the magnitude as the key gives it
    stress: float  # its stress (|t|, |p|, |b| L, sigma_max alpha), or 0 for a displacement
    strain: float = 0.0  # a prescribed displacement's strain |u| / L
    first: float = 0.0  # its share in the first increment (s1, or alpha(t1) for a fibre stress)


def _loads(config: RunConfig, size: float, scale: float, t1: float) -> list[_Load]:
    """The configuration's loads with a magnitude: tractions, pressures, body forces, constant prescribed
    displacements and the active fibre stress of activated materials."""
    loads = []
    for i, b in enumerate(config.boundaries):
        if b.type in ("traction", "pressure"):
            value = float(np.max(np.abs(b.value)))
            loads.append(_Load(f"boundary[{i}].value", value, value, first=scale))
        elif b.type == "displacement" and b.value:
            value = float(np.max(np.abs(b.value)))
            loads.append(_Load(f"boundary[{i}].value", value, 0.0, strain=value / size, first=scale))
    for i, f in enumerate(config.body_forces):
        value = float(np.linalg.norm(f.value))
        loads.append(_Load(f"body_force[{i}].value", value, value * size, first=scale))
    for i, m in enumerate(config.materials):
        # the active fibre stress at alpha = 1: muscle's sigma_max, blemker's smax, trans_iso_mooney_rivlin's Tmax
        name = next((k for k in ("sigma_max", "smax", "Tmax") if _law_value(m.law, k)), "sigma_max")
        sigma_max = _law_value(m.law, name)
        if sigma_max and "alpha" in forms.law_fields(m.law) and m.activation:
            peak = max(a for _, a in m.activation)
            loads.append(_Load(f"material[{i}].{name}", sigma_max, sigma_max * peak,
                               first=activation_at(m.activation, t1) / peak if peak else 0.0))
    return loads


# --- the first increment --------------------------------------------------------------------------------------------

def _reference_points(degree: int) -> np.ndarray:
    """Points of the reference tetrahedron where sym grad du is sampled: vertices, edge midpoints and centroid
    (exact maxima for P1 and P2, whose gradients are linear in a cell)."""
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    edges = [(vertices[a] + vertices[b]) / 2 for a in range(4) for b in range(a + 1, 4)]
    return np.vstack([vertices, edges, vertices.mean(axis=0)])


def _largest_strain(problem: ElasticityProblem, increment: fem.Function) -> float:
    """max over owned cells and sample points of max |eig(sym grad u)| of the increment's displacement,
    reduced over ranks."""
    msh = problem.domain.mesh
    u = ufl.split(increment)[0] if problem.formulation == "mixed" else increment
    expression = fem.Expression(ufl.sym(ufl.grad(u)), _reference_points(problem.degree))
    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
    local = 0.0
    if len(cells):
        values = compat.evaluate(expression, msh, cells).reshape(-1, 3, 3)
        eigenvalues = np.linalg.eigvalsh(0.5 * (values + values.transpose(0, 2, 1)))
        local = float(np.max(np.abs(eigenvalues))) if np.all(np.isfinite(eigenvalues)) else math.inf
    return msh.comm.allreduce(local, op=MPI.MAX)


def _iterative(problem: ElasticityProblem) -> bool:
    """Whether the check solves with the iterative preset: from linear.AUTO_DOFS unknowns."""
    return problem.space.dofmap.index_map.size_global * problem.space.dofmap.index_map_bs >= linear.AUTO_DOFS


def _linear_solver(problem: ElasticityProblem, A: PETSc.Mat,
                   fields: linear.MixedFields | None = None) -> tuple[PETSc.KSP, Any, float]:
    """A KSP for the check's solve with A (module docstring, (a)): MUMPS LU below linear.AUTO_DOFS unknowns,
    else the iterative preset (ksp_rtol ITERATIVE_RTOL) on its own options prefix; with the function that frees
    what it made and the relative residual the solution must reach. ``fields``: the mixed formulation's, when
    A is a nested Jacobian (their block layout; else the check makes its own)."""
    comm = problem.domain.mesh.comm
    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    imap = problem.space.dofmap.index_map
    dofs = imap.size_global * problem.space.dofmap.index_map_bs
    iterative = dofs >= linear.AUTO_DOFS
    if comm.rank == 0:
        log.debug("scale check: the %s preset's linear solve (%d dofs)", "iterative" if iterative else "direct", dofs)
    if not iterative:
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        return ksp, lambda: None, DIRECT_MISFIT
    choice = linear.resolve(problem, "iterative")
    choice.options["ksp_rtol"] = ITERATIVE_RTOL  # a warning's figure: 3 digits suffice, at half the iterations
    prefix = f"scale_check{next(_prefixes)}_"
    database = PETSc.Options()
    for key, value in choice.options.items():
        database[prefix + key] = value
    made: list[Any] = []
    if problem.formulation == "displacement":
        null_space = linear.rigid_body_modes(problem)
        A.setNearNullSpace(null_space)
        made.append(null_space)
    ksp.setOptionsPrefix(prefix)
    ksp.setFromOptions()
    if problem.formulation == "mixed":
        if fields is None:
            fields = linear.MixedFields(problem)
            made.append(fields)
        fields.configure(ksp.getPC(), choice.options)

    def release() -> None:
        for key in choice.options:
            database.delValue(prefix + key)
        for obj in made:
            obj.destroy()

    return ksp, release, 10.0 * ITERATIVE_RTOL


def _nested(problem: ElasticityProblem, matrix: str) -> tuple[Any, Any]:
    """(fields, NestedJacobian) for the check's iterative solve of a mixed problem, as the run's Newton solver makes
    them under [solver] matrix = ``matrix`` (linear.matrix_kind with the iterative preset); (None, None) for the
    assembled matrix (also where a block cannot be separated: nested.nested_jacobian)."""
    from model.solvers.nested import nested_jacobian

    if problem.formulation != "mixed" or not _iterative(problem) or matrix == "aij":
        return None, None
    if linear.matrix_kind(problem, "auto", linear.ITERATIVE_MIXED) != "nest":
        return None, None
    return nested_jacobian(problem) or (None, None)


def linear_first_increment(problem: ElasticityProblem, t1: float, matrix: str = "auto") -> float | None:
    """The strain of du solving J(0) du = -R(0; t1) with du = g(t1) on the Dirichlet dofs (module docstring);
    None when the solve fails (a singular tangent, or a solution that does not satisfy the system).
    The problem is left as it was (solution, load factor). ``matrix``: [solver] matrix (the mixed formulation's
    iterative solve with the nested Jacobian or the assembled one, as the run's)."""
    saved_solution = problem.solution.x.array.copy()
    saved_time = problem.time
    residual, jacobian = problem.forms
    fibres = problem.cell_fields.get("fibre_direction")
    saved_fibres = fibres.x.array.copy() if fibres is not None else None
    A = b = dx = ksp = rhs = None
    nested: Any = None
    fields = None
    release: Any = None
    try:
        if fibres is not None:  # every fibre stretch 1 + 1e-9: the fibre curves' tangent from the side of stretch
            fibres.x.array[:] *= 1.0 + FIBRE_STRETCH
        problem.solution.x.array[:] = 0.0
        problem.set_load_factor(t1)
        problem.invalidate_state()
        problem.update_state()
        bcs = problem.bcs
        fields, nested = _nested(problem, matrix)  # the run's nested Jacobian: no copies of its blocks
        if nested is not None:
            nested.assemble()
            A = nested.matrix
        else:
            A = fem_petsc.assemble_matrix(jacobian, bcs=bcs)
            A.assemble()
        b = fem_petsc.assemble_vector(residual)
        x0 = compat.petsc_vector(problem.solution)
        compat.apply_lifting(b, [jacobian], bcs=[bcs], x0=[x0], alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        compat.set_bc(b, bcs, x0, -1.0)
        ksp, release, tolerance = _linear_solver(problem, A, fields)
        rhs = b
        if nested is not None:  # the block layout
            rhs = nested.block_vector()
            nested.to_block(b, rhs)
        dx = rhs.duplicate()
        ksp.solve(rhs, dx)
        if ksp.getConvergedReason() < 0:
            return None
        check = rhs.duplicate()
        A.mult(dx, check)
        check.axpy(-1.0, rhs)
        misfit, norm = check.norm(), rhs.norm()
        check.destroy()
        if not (math.isfinite(misfit) and misfit <= tolerance * max(norm, 1e-300)):
            return None
        increment = fem.Function(problem.space)
        step = compat.petsc_vector(increment)
        if nested is not None:
            nested.to_mixed(dx, step)
            step.scale(-1.0)
        else:
            step.axpy(-1.0, dx)  # du = -dx (Newton's update x - dx from x = 0)
        increment.x.scatter_forward()
        return _largest_strain(problem, increment)
    except (PETSc.Error, ConfigError):  # ConfigError: the mixed iterative preset needs every shear modulus
        return None
    finally:
        if ksp is not None:
            release()
        for obj in (ksp, nested if nested is not None else A, b, dx, rhs if rhs is not b else None, fields):
            if obj is not None:
                obj.destroy()
        if fibres is not None:
            fibres.x.array[:] = saved_fibres
        problem.solution.x.array[:] = saved_solution
        problem.set_load_factor(saved_time)
        problem.invalidate_state()


def _dirichlet_dofs(problem: ElasticityProblem) -> int:
    comm = problem.domain.mesh.comm
    local = sum(len(d) for entry in problem.dirichlet for d in entry.dofs)
    return comm.allreduce(local, op=MPI.SUM)


def body_size(problem: ElasticityProblem) -> float:
    """The diagonal of the mesh's bounding box, reduced over ranks."""
    msh = problem.domain.mesh
    x = msh.geometry.x
    low, high = np.empty(3), np.empty(3)
    msh.comm.Allreduce(np.min(x, axis=0) if len(x) else np.full(3, np.inf), low, op=MPI.MIN)
    msh.comm.Allreduce(np.max(x, axis=0) if len(x) else np.full(3, -np.inf), high, op=MPI.MAX)
    return float(np.linalg.norm(high - low))


# --- the check ------------------------------------------------------------------------------------------------------

def _size_warning(system: str, size: float, moduli: list[tuple[str, float]]) -> str | None:
    """(b): the body's size and the moduli against the expected ranges of the unit system."""
    length, stress = _UNITS[system]
    (lo_size, hi_size), (lo_mod, hi_mod) = SIZE_BOUNDS[system], MODULUS_BOUNDS[system]
    values = [v for _, v in moduli]
    lo, hi = (min(values), max(values)) if values else (None, None)
    big, small = size > hi_size, size < lo_size
    stiff, soft = hi is not None and hi > hi_mod, lo is not None and lo < lo_mod
    if not (big or small or stiff or soft):
        return None
    span = "" if lo is None else f" with moduli {number(lo)}" + ("" if hi == lo else f"-{number(hi)}") + f" {stress}"
    text = f"scale check: the body is {number(size)} {length} across{span}"
    if system == "SI":
        if big and not soft:
            hint = "if the mesh is in mm, give moduli in MPa (and [units] system = \"mm-MPa\"), or the mesh in m"
        elif soft and not big:
            hint = "if the moduli are in MPa, give them in Pa, or the mesh in mm (and [units] system = \"mm-MPa\")"
        else:
            hint = "check their units"
    else:
        if small and not stiff:
            hint = "if the mesh is in m, give it in mm, or everything in SI ([units] system = \"SI\")"
        elif stiff and not small:
            hint = "if the moduli are in Pa, give them in MPa (x 1e-6), or everything in SI ([units] system = \"SI\")"
        else:
            hint = "check their units"
    expected = (f"expected for soft tissue in {system}: {number(lo_size)}-{number(hi_size)} {length} and "
                f"{number(lo_mod)}-{number(hi_mod)} {stress}")
    return f"{text}: {hint} ({expected})"


def _strain_warning(strain: float, loads: list[_Load], moduli: list[tuple[str, float]], size: float,
                    length: str) -> str:
    """(a): the first increment's strain, with the load and modulus that make it."""
    text = f"scale check: the first load increment strains the body by {number(strain)} (> {STRAIN_LIMIT})"
    stiffness = min(moduli, key=lambda km: km[1]) if moduli else None
    ratios = []
    for load in loads:
        if load.stress > 0 and stiffness is not None:
            ratios.append((load.stress / stiffness[1], f"{load.key} = {number(load.value)} vs {stiffness[0]} = "
                           f"{number(stiffness[1])}: ratio {number(load.stress / stiffness[1])}"))
        elif load.strain > 0:
            ratios.append((load.strain, f"{load.key} = {number(load.value)} on a body {number(size)} {length} "
                           f"across: ratio {number(load.strain)}"))
    if ratios:
        text += f": loads and moduli look inconsistent ({max(ratios)[1]})"
    return text + "; check their units, or raise loading.steps"


def scale_check(problem: ElasticityProblem, config: RunConfig) -> ScaleCheck:
    """Checks (a) and (b) of the module docstring on a built problem, before any solve; logs the warnings
    once (rank 0) and returns them with the figures. The problem is left as it was."""
    start = time.perf_counter()
    comm = problem.domain.mesh.comm
    system = config.units.system
    length = _UNITS[system][0]
    size = body_size(problem)
    moduli = [km for i, m in enumerate(config.materials) if (km := material_modulus(i, m)) is not None]
    dynamics = config.dynamics
    if dynamics.is_dynamic:
        t1, scale = float(dynamics.dt), float(dynamics.load_scale(dynamics.dt))
    else:
        t1 = scale = 1.0 / config.loading.steps
    loads = _loads(config, size, scale, t1)
    strain = None
    if not dynamics.is_dynamic and _dirichlet_dofs(problem) > 0:
        strain = linear_first_increment(problem, t1, getattr(config.solver, "matrix", "auto"))
    method = "linear solve"
    if strain is None:
        method = "estimate"
        stiffness = min((v for _, v in moduli), default=math.inf)
        strain = max([ld.first * (ld.stress / stiffness if ld.stress > 0 else ld.strain) for ld in loads],
                     default=0.0)
        if comm.rank == 0:
            log.debug("scale check: no linear solve (%s); estimated from the loads and moduli",
                      "dynamics" if dynamics.is_dynamic else "no Dirichlet condition, or a singular tangent")
    warnings = []
    if strain > STRAIN_LIMIT:
        warnings.append(_strain_warning(strain, loads, moduli, size, length))
    size_warning = _size_warning(system, size, moduli)
    if size_warning is not None:
        warnings.append(size_warning)
    seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    if comm.rank == 0:
        for warning in warnings:
            log.warning("%s", warning)
        log.info("scale check (%s, %.2f s): first increment strain %s, body %s %s across, moduli %s", method,
                 seconds, number(strain), number(size), length, ", ".join(f"{k} = {number(v)}" for k, v in moduli))
    return ScaleCheck(strain, method, size, [v for _, v in moduli], warnings, seconds)


__all__ = ["MODULUS_BOUNDS", "SIZE_BOUNDS", "STRAIN_LIMIT", "ScaleCheck", "body_size", "linear_first_increment",
           "material_modulus", "number", "scale_check"]
