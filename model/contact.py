"""Frictionless contact of a body's surface with a rigid (moving) obstacle: penalty, augmented Lagrangian, VI.

g(x) is the obstacle's signed distance at the current position x = X + u of a surface point,
measured in the obstacle's moving frame (forms.obstacles; Q, c fem.Constants set from the load
factor). Non-penetration asks g >= 0 on the surface ``surface``.

Methods (one class each):

    PenaltyContact                 Pi_c = int (k/2) min(g, 0)^2 dA (reference area; energies.md). The
                                   penetration is O(p/k): the error in the solution falls like 1/k.
    AugmentedLagrangianContact     Pi_c = int (k/2) min(g - lambda/k, 0)^2 - lambda^2/(2k) dA with a
                                   multiplier lambda >= 0 (the contact pressure), P_m Lagrange like the
                                   displacement, nodal values ("lumped"). UzawaSolver alternates a Newton
                                   solve at fixed lambda with the nodal update
                                       lambda_i <- max(lambda_i - k g_i, 0)
                                   until max_i |min(g_i, lambda_i / k)| <= tol (no node penetrates or is
                                   held off by a positive pressure by more than tol), i.e. the
                                   complementarity g >= 0, lambda >= 0, lambda g = 0 at the nodes.
                                   The penetration falls by a factor of about K_body / (K_body + k) per
                                   update.
    VIContact                      (a plane whose moving normal stays along a coordinate axis) the
                                   bounds X_j + u_j >= p_j (normal +e_j) or <= p_j (normal -e_j) on the
                                   normal displacement component of every surface node, solved exactly
                                   by SNES vinewtonrsls (a semismooth active-set Newton method), after a
                                   linearised predictor step that imposes the violated bounds as
                                   Dirichlet increments (VISolver; SNES alone would only project the
                                   surface nodes, which can invert the elements under them).

Report (``contact_report()``, the same on every rank): ``max_penetration`` = max(0, -min_i g_i) over
the surface nodes; ``force`` = the total force the obstacle exerts on the body: penalty and
augmented Lagrangian int p grad g dA with p = max(lambda - k g, 0) (= -dPi_c/du summed per component);
VI: the residual R = f_int - f_ext at the bounded dofs (their reaction); ``active_points`` = nodes with
g <= 0 (penalty), pressure max(lambda_i - k g_i, 0) > 0 (augmented Lagrangian), at their bound (VI).
Nodes are those of the displacement's Lagrange degree (P2: vertices and edge midpoints).

Wiring a run (before the solver is created):

    contacts = [build_contact(problem, parse_contact(raw, f"contact[{i}]")) for i, raw in ...]
    solver = make_contact_solver(problem, contacts, petsc_options, tangent=...)
    ... after each converged step: step["contact"] = contact_report(contacts)
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from forms.obstacles import (
    Capsule,
    Obstacle,
    Plane,
    Sphere,
    augmented_lagrangian_energy,
    contact_pressure,
    penalty_energy,
)
from model import compat
from model.bones import MovingFrame, RigidMotion, SurfaceNodes, body_size, current_position, surface_measure
from model.problem import ElasticityProblem
from model.solver import NewtonSolver, SolveResult

log = logging.getLogger(__name__)

METHODS = ("vi", "penalty")
OBSTACLES = ("plane", "sphere", "capsule")
#: PETSc options a VI contact needs (the VI Newton of PETSc with a full-step, projected line search)
VI_OPTIONS: dict[str, str | int | float | bool] = {"snes_type": "vinewtonrsls", "snes_linesearch_type": "basic"}
VI_TYPES = ("vinewtonrsls", "vinewtonssls")
#: SolveResult.reason of an augmented Lagrangian run that hit max_uzawa (outside PETSc's range)
DIVERGED_UZAWA_MAX_IT = -100

__all__ = ["AugmentedLagrangianContact", "Contact", "ContactSpec", "PenaltyContact", "UzawaSolver", "VIContact",
           "VISolver", "build_contact", "contact_report", "make_contact_solver", "parse_contact"]


# --- the methods ----------------------------------------------------------------------------------

class _SurfaceContact:
    """What every method shares: the surface, the moving obstacle, the UFL gap and nodal evaluations."""

    def __init__(self, problem: ElasticityProblem, surface: str, obstacle: Obstacle,
                 motion: RigidMotion | None = None, quadrature_degree: int | str | None = None) -> None:
        self.problem = problem
        self.surface = surface
        self.obstacle = obstacle
        self.ds = surface_measure(problem, surface, quadrature_degree)
        self.frame = MovingFrame(problem.domain.mesh, motion)
        self.frame.follow(problem)
        self.gap = self.frame.gap(obstacle, current_position(problem))
        self.nodes = SurfaceNodes(problem, surface)
        self.size = body_size(problem)

    def nodal_gaps(self) -> np.ndarray:
        """g at the surface nodes this rank owns."""
        return self.nodes.evaluate(self.gap)

    def max_penetration(self) -> float:
        """max(0, -min_i g_i) over the surface nodes (all ranks)."""
        worst = self.nodes.max(-self.nodal_gaps(), initial=0.0)
        return worst if worst > 0.0 else 0.0  # never -0.0

    def _normal(self) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
        """(g, grad_x g) with x = X + u a UFL variable: the obstacle's gap and unit normal at x."""
        xv = ufl.variable(current_position(self.problem))
        gv = self.frame.gap(self.obstacle, xv)
        return gv, ufl.diff(gv, xv)

    def _force(self, forms: list[compat.Form]) -> list[float]:
        comm = self.nodes.comm
        return [float(comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM)) for f in forms]


class PenaltyContact(_SurfaceContact):
    """Pi_c = int (k/2) min(g, 0)^2 dA over ``surface`` (forms.obstacles.penalty_energy), added to the problem."""

    def __init__(self, problem: ElasticityProblem, surface: str, obstacle: Obstacle, k: float,
                 motion: RigidMotion | None = None, quadrature_degree: int | str | None = None) -> None:
        _positive(k, "penalty")
        super().__init__(problem, surface, obstacle, motion, quadrature_degree)
        self.k = float(k)
        # k enters the forms as a constant: contacts differing only in k share compiled code
        self.k_constant = fem.Constant(problem.domain.mesh, PETSc.ScalarType(self.k))
        self._add_fields()
        self.energy = self._energy(self.gap)
        problem.add_energy(self.energy * self.ds)
        gv, n = self._normal()
        traction = self._pressure(gv) * n
        self.force_forms = [fem.form(traction[i] * self.ds) for i in range(3)]

    def _add_fields(self) -> None:
        """Fields the energy needs besides u (none for the plain penalty)."""

    def _energy(self, g: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return penalty_energy(g, self.k_constant)

    def _pressure(self, g: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return contact_pressure(g, self.k_constant)

    def force(self) -> list[float]:
        """Total force the obstacle exerts on the body: int p grad g dA, p = max(lambda - k g, 0)."""
        return self._force(self.force_forms)

    def active_points(self) -> int:
        return int(self.nodes.sum(self.nodal_gaps() <= 0.0))

    def contact_report(self) -> dict[str, Any]:
        """{"max_penetration", "force", "active_points"} (the same on every rank)."""
        return {"max_penetration": self.max_penetration(), "force": self.force(),
                "active_points": self.active_points()}


class AugmentedLagrangianContact(PenaltyContact):
    """Pi_c = int (k/2) min(g - lambda/k, 0)^2 - lambda^2/(2k) dA; lambda updated by UzawaSolver.

    ``tolerance`` (relative to the body's bounding-box diagonal) and ``max_uzawa`` bound the
    iteration: converged when max_i |min(g_i, lambda_i / k)| <= tolerance * size.
    """

    def __init__(self, problem: ElasticityProblem, surface: str, obstacle: Obstacle, k: float,
                 motion: RigidMotion | None = None, quadrature_degree: int | str | None = None,
                 tolerance: float = 1e-8, max_uzawa: int = 25) -> None:
        _positive(tolerance, "tolerance")
        if isinstance(max_uzawa, bool) or not isinstance(max_uzawa, int) or max_uzawa < 1:
            raise ValueError(f"max_uzawa must be an integer >= 1, got {max_uzawa!r}")
        self.tolerance = float(tolerance)
        self.max_uzawa = max_uzawa
        super().__init__(problem, surface, obstacle, k, motion, quadrature_degree)

    def _add_fields(self) -> None:
        self.multiplier = fem.Function(self.nodes.space, name="contact_pressure")

    def _energy(self, g: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return augmented_lagrangian_energy(g, self.multiplier, self.k_constant)

    def _pressure(self, g: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return contact_pressure(g, self.k_constant, self.multiplier)

    @property
    def absolute_tolerance(self) -> float:
        return self.tolerance * self.size

    def uzawa_residual(self) -> float:
        """max_i |min(g_i, lambda_i / k)| over the surface nodes (all ranks): 0 at the exact solution."""
        g = self.nodal_gaps()
        lam = self.multiplier.x.array[self.nodes.dofs]
        return self.nodes.max(np.abs(np.minimum(g, lam / self.k)), initial=0.0)

    def update_multiplier(self) -> None:
        """lambda_i <- max(lambda_i - k g_i, 0) at the surface nodes."""
        g = self.nodal_gaps()
        lam = self.multiplier.x.array
        lam[self.nodes.dofs] = np.maximum(lam[self.nodes.dofs] - self.k * g, 0.0)
        self.multiplier.x.scatter_forward()

    def active_points(self) -> int:
        p = contact_pressure(self.nodal_gaps(), self.k, self.multiplier.x.array[self.nodes.dofs])
        return int(self.nodes.sum(p > 0.0))


class VIContact(_SurfaceContact):
    """Exact non-penetration of a plane with a coordinate-axis normal: SNES variable bounds.

    For the world normal n_w = Q n = s e_j (s = +-1) and world point p_w = Q p + c, every surface
    node X gets the bound u_j >= p_w,j - X_j (s = +1) or u_j <= p_w,j - X_j (s = -1); all other
    dofs are unbounded (PETSc.INFINITY). Dofs with Dirichlet data keep them (no bound).
    A normal off the axes raises ValueError naming "normal" (at construction, and at a solve if
    the motion turns it away).
    """

    def __init__(self, problem: ElasticityProblem, surface: str, obstacle: Plane,
                 motion: RigidMotion | None = None) -> None:
        if not isinstance(obstacle, Plane):
            raise ValueError(f"obstacle: method vi needs a plane, got a {type(obstacle).__name__.lower()}")
        _axis_of(np.asarray(obstacle.normal), "normal")
        super().__init__(problem, surface, obstacle, motion)
        self._world_plane()  # the moved normal too
        msh = problem.domain.mesh
        fdim = msh.topology.dim - 1
        facets = problem.domain.boundary_facets(surface)
        bs = problem.space.dofmap.index_map_bs
        owned = problem.space.dofmap.index_map.size_local * bs
        self._dofs: list[np.ndarray] = []  # per component: solution-vector indices (owned)
        self._coords: list[np.ndarray] = []  # their reference coordinates
        for comp in range(3):
            sub = problem.displacement_space.sub(comp)
            collapsed, _ = sub.collapse()
            dofs = fem.locate_dofs_topological((sub, collapsed), fdim, facets)
            keep = dofs[0] < owned
            self._dofs.append(np.asarray(dofs[0][keep], dtype=np.int32))
            self._coords.append(collapsed.tabulate_dof_coordinates()[dofs[1][keep]])
        self.solver: Any = None
        self._active_tol = 1e-10 * self.size

    def _world_plane(self) -> tuple[int, float, float]:
        """(j, s, p_w,j) of the moved plane: n_w = Q n = s e_j, p_w = Q p + c."""
        Q = np.asarray(self.frame.rotation.value)
        c = np.asarray(self.frame.translation.value)
        j, s = _axis_of(Q @ np.asarray(self.obstacle.normal), "normal")
        p = Q @ np.asarray(self.obstacle.point) + c
        return j, s, float(p[j])

    def _bounded(self) -> tuple[np.ndarray, np.ndarray, int, float]:
        """(dofs, bound values, s, j) for the current plane, Dirichlet dofs excluded."""
        j, s, pj = self._world_plane()
        dofs, coords = self._dofs[j], self._coords[j]
        fixed = [d for entry in self.problem.dirichlet for d in entry.dofs]
        keep = ~np.isin(dofs, np.concatenate(fixed)) if fixed else np.ones(len(dofs), dtype=bool)
        return dofs[keep], pj - coords[keep, j], s, j

    def apply_bounds(self, lower: np.ndarray, upper: np.ndarray) -> None:
        """Tighten the owned arrays of the bound vectors by this contact's bounds."""
        dofs, values, s, _ = self._bounded()
        if s > 0:
            lower[dofs] = np.maximum(lower[dofs], values)
        else:
            upper[dofs] = np.minimum(upper[dofs], values)

    def force(self) -> list[float]:
        """The residual R = f_int - f_ext summed over the bounded dofs: the force of the plane on the body."""
        if self.solver is None:
            raise RuntimeError("VIContact.force: no solver (use make_contact_solver)")
        dofs, _, _, j = self._bounded()
        residual = self.solver.unconstrained_residual()
        force = [0.0, 0.0, 0.0]
        force[j] = float(residual.array_r[dofs].sum())
        residual.destroy()
        comm = self.nodes.comm
        return [float(comm.allreduce(f, op=MPI.SUM)) for f in force]

    def active_points(self) -> int:
        dofs, values, _, _ = self._bounded()
        u = self.problem.solution.x.array[dofs]
        return int(self.nodes.sum(np.abs(u - values) <= self._active_tol))

    def contact_report(self) -> dict[str, Any]:
        """{"max_penetration", "force", "active_points"} (the same on every rank)."""
        return {"max_penetration": self.max_penetration(), "force": self.force(),
                "active_points": self.active_points()}


Contact = PenaltyContact | AugmentedLagrangianContact | VIContact


def _axis_of(normal: np.ndarray, key: str) -> tuple[int, float]:
    """(j, s) with normal = s e_j (to 1e-12), else ValueError naming ``key``."""
    j = int(np.argmax(np.abs(normal)))
    off = np.delete(np.abs(normal), j)
    if np.any(off > 1e-12):
        raise ValueError(f"{key}: method vi needs a plane normal along a coordinate axis (+-x, +-y, +-z), "
                         f"got {[float(v) for v in normal]}")
    return j, float(np.sign(normal[j]))


def _positive(value: Any, key: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{key} must be a finite number > 0, got {value!r}")


# --- solvers --------------------------------------------------------------------------------------

class VISolver:
    """NewtonSolver with the bounds of VI contacts (snes_type vinewtonrsls), and a predictor.

    SNES VI projects its initial guess onto the bounds: when the obstacle has moved by a load
    step, that pushes the surface nodes alone and can invert the elements under them. The
    predictor first takes one linearised step with the violated bounds imposed as Dirichlet
    increments (rows of the tangent replaced by identity, du_i = bound_i - x_i; Dirichlet data as in
    every Newton step), so the interior follows the surface; SNES VI then solves from there.
    The predictor's linear solve is MUMPS LU.
    """

    def __init__(self, newton: NewtonSolver, contacts: Sequence[VIContact], predictor: bool = True) -> None:
        self.newton = newton
        self.problem = newton.problem
        self.contacts = list(contacts)
        self.predictor = predictor
        self._ksp: PETSc.KSP | None = None

    @property
    def unused_options(self) -> list[str]:
        return self.newton.unused_options

    def _predict(self) -> None:
        newton, problem = self.newton, self.problem
        x = newton.x
        compat.petsc_vector(problem.solution).copy(x)
        lower = np.full(x.getLocalSize(), PETSc.NINFINITY)
        upper = np.full(x.getLocalSize(), PETSc.INFINITY)
        _fill_bounds(self.contacts, lower, upper)
        values = x.array_r
        low, high = values < lower, values > upper
        rows = np.flatnonzero(low | high).astype(np.int32)
        comm = problem.domain.mesh.comm
        if comm.allreduce(len(rows), op=MPI.SUM) == 0:
            return
        newton._residual(newton.snes, x, newton.b)  # at x, Dirichlet rows x - g
        newton._jacobian(newton.snes, x, newton.A, newton.A)
        target = np.where(low, lower, upper)[rows]
        b = newton.b
        b.array[rows] = values[rows] - target  # du_i = target_i - x_i
        start = x.getOwnershipRange()[0]
        newton.A.zeroRows(rows + start, diag=1.0)
        if self._ksp is None:
            self._ksp = PETSc.KSP().create(comm)
            self._ksp.setType("preonly")
            self._ksp.getPC().setType("lu")
            self._ksp.getPC().setFactorSolverType("mumps")
        self._ksp.setOperators(newton.A)
        du = x.duplicate()
        self._ksp.solve(b, du)
        x.axpy(-1.0, du)  # Newton: A du = b, x <- x - du
        du.destroy()
        x.copy(compat.petsc_vector(problem.solution))
        compat.petsc_vector(problem.solution).ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        log.debug("VI predictor: %d bounds violated before the solve", comm.allreduce(len(rows), op=MPI.SUM))

    def solve(self) -> SolveResult:
        if self.predictor:
            self._predict()
        return self.newton.solve()

    def unconstrained_residual(self) -> PETSc.Vec:
        return self.newton.unconstrained_residual()

    def destroy(self) -> None:
        if self._ksp is not None:
            self._ksp.destroy()
        self.newton.destroy()


def _fill_bounds(contacts: Sequence[VIContact], lower: np.ndarray, upper: np.ndarray) -> None:
    for c in contacts:
        c.apply_bounds(lower, upper)


class UzawaSolver:
    """Augmented Lagrangian contact: Newton solves at fixed multipliers, then Uzawa updates, until converged.

    Same interface as NewtonSolver (``problem``, ``solve()``, ``unconstrained_residual()``,
    ``destroy()``). A solve converges when every contact's Uzawa residual is below its tolerance;
    a failed Newton solve, or ``max_uzawa`` updates without convergence, fails (reason
    DIVERGED_UZAWA_MAX_IT = -100 for the latter) and restores the multipliers of the start of the
    solve (load stepping restores the solution and cuts the step back).
    ``iterations`` of the result counts Newton iterations over all Uzawa rounds; ``uzawa_iterations``
    holds the rounds of the last solve.
    """

    def __init__(self, newton: NewtonSolver | VISolver, contacts: Sequence[AugmentedLagrangianContact]) -> None:
        self.newton = newton
        self.problem = newton.problem
        self.contacts = list(contacts)
        self.max_uzawa = max(c.max_uzawa for c in self.contacts)
        self.uzawa_iterations = 0
        self.history: list[float] = []

    @property
    def unused_options(self) -> list[str]:
        return self.newton.unused_options

    def _residual(self) -> float:
        return max(c.uzawa_residual() / c.absolute_tolerance for c in self.contacts)

    def solve(self) -> SolveResult:
        saved = [c.multiplier.x.array.copy() for c in self.contacts]
        newton_its = linear_its = 0
        self.history = []
        result: SolveResult | None = None
        for round_ in range(1, self.max_uzawa + 1):
            result = self.newton.solve()
            newton_its += result.iterations
            linear_its += result.linear_iterations
            self.uzawa_iterations = round_
            if not result.converged:
                self._restore(saved)
                return SolveResult(False, result.reason, result.reason_name, newton_its, linear_its,
                                   result.residual_norm)
            ratio = self._residual()
            self.history.append(ratio)
            log.debug("uzawa round %d: residual / tolerance = %.3e", round_, ratio)
            if ratio <= 1.0:
                return SolveResult(True, result.reason, result.reason_name, newton_its, linear_its,
                                   result.residual_norm)
            if round_ < self.max_uzawa:
                for c in self.contacts:
                    c.update_multiplier()
        self._restore(saved)
        log.error("augmented Lagrangian contact: after %d Uzawa rounds max |min(g, lambda/k)| is still %.3g times "
                  "the tolerance (raise max_uzawa or the penalty)", self.max_uzawa, self.history[-1])
        assert result is not None
        return SolveResult(False, DIVERGED_UZAWA_MAX_IT, "DIVERGED_UZAWA_MAX_IT", newton_its, linear_its,
                           result.residual_norm)

    def _restore(self, saved: list[np.ndarray]) -> None:
        for c, lam in zip(self.contacts, saved):
            c.multiplier.x.array[:] = lam

    def unconstrained_residual(self) -> PETSc.Vec:
        """R(u) = f_int - f_ext (contact terms included) with no Dirichlet rows replaced."""
        return self.newton.unconstrained_residual()

    def destroy(self) -> None:
        self.newton.destroy()


def make_contact_solver(problem: ElasticityProblem, contacts: Sequence[Contact],
                        options: dict[str, str | int | float | bool] | None = None, prefix: str | None = None,
                        tangent: str = "exact", predictor: bool = True) -> NewtonSolver | VISolver | UzawaSolver:
    """The solver for a problem with contacts (build them first); all have NewtonSolver's interface.

    VI contacts: VISolver, a NewtonSolver with snes_type vinewtonrsls (VI_OPTIONS; a user snes_type
    must be a VI type) and the bounds of every VI contact (the tightest wins), with the predictor
    unless ``predictor`` is False. Augmented Lagrangian contacts: wrapped in UzawaSolver. Penalty
    contacts need nothing (their energy is in the residual): a plain NewtonSolver.
    """
    options = dict(options or {})
    vi = [c for c in contacts if isinstance(c, VIContact)]
    augmented = [c for c in contacts if isinstance(c, AugmentedLagrangianContact)]
    bounds = None
    if vi:
        given = options.get("snes_type")
        if given is not None and given not in VI_TYPES:
            from model.config import ConfigError

            raise ConfigError(f"solver.petsc_options.snes_type: contact method vi needs one of {', '.join(VI_TYPES)}, "
                              f"got {given!r}")
        options = {**VI_OPTIONS, **options}

        def bounds(xl: PETSc.Vec, xu: PETSc.Vec) -> None:
            lower = np.full(xl.getLocalSize(), PETSc.NINFINITY)
            upper = np.full(xu.getLocalSize(), PETSc.INFINITY)
            _fill_bounds(vi, lower, upper)
            xl.array[:] = lower
            xu.array[:] = upper

    newton = NewtonSolver(problem, options, prefix=prefix, tangent=tangent, bounds=bounds)
    for c in vi:
        c.solver = newton
    inner: Any = VISolver(newton, vi, predictor) if vi else newton
    return UzawaSolver(inner, augmented) if augmented else inner


def contact_report(contacts: Sequence[Contact]) -> dict[str, Any]:
    """One report for all contacts: the largest penetration, the summed force and active points."""
    reports = [c.contact_report() for c in contacts]
    return {"max_penetration": max((r["max_penetration"] for r in reports), default=0.0),
            "force": [float(sum(r["force"][i] for r in reports)) for i in range(3)],
            "active_points": int(sum(r["active_points"] for r in reports))}


# --- configuration --------------------------------------------------------------------------------

@dataclass(frozen=True)
class ContactSpec:
    """A checked [[contact]] table (run-contract.md, "Contact")."""

    surface: str
    obstacle: Obstacle
    method: str
    penalty: float | None = None
    augmented: bool = False
    tolerance: float = 1e-8
    max_uzawa: int = 25
    quadrature_degree: int | str | None = None  # or "vertex": nodal quadrature, where the gaps are measured


_KEYS = {"plane": ("point", "normal"), "sphere": ("centre", "radius"), "capsule": ("a", "b", "radius")}
_COMMON = ("surface", "obstacle", "method", "penalty", "augmented", "tolerance", "max_uzawa", "quadrature_degree")


def parse_contact(raw: dict[str, Any], key: str) -> ContactSpec:
    """Check one [[contact]] table; ConfigError("KEY.NAME: message") for the first problem.

    Keys: surface (a boundary name; checked against the mesh by build_contact), obstacle
    (plane: point, normal; sphere: centre, radius; capsule: a, b, radius), method (vi | penalty),
    penalty (k > 0; penalty only), augmented (true: augmented Lagrangian with Uzawa updates;
    penalty only), tolerance (> 0, relative to the body size, default 1e-8) and max_uzawa
    (>= 1, default 25) (augmented only), quadrature_degree (>= 1; penalty only).
    """
    from model.config import ConfigError

    def fail(name: str, message: str) -> None:
        raise ConfigError(f"{key}.{name}: {message}")

    if not isinstance(raw, dict):
        raise ConfigError(f"{key}: must be a table, got {type(raw).__name__}")

    def number(name: str) -> float:
        value = raw[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            fail(name, f"must be a finite number, got {value!r}")
        return float(value)

    def vector(name: str) -> tuple[float, float, float]:
        value = raw[name]
        if not isinstance(value, list) or len(value) != 3:
            fail(name, f"must be an array of 3 numbers, got {value!r}")
        out = []
        for i, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                fail(f"{name}[{i}]", f"must be a finite number, got {v!r}")
            out.append(float(v))
        return (out[0], out[1], out[2])

    def required(name: str, what: str) -> None:
        if name not in raw:
            fail(name, f"missing ({what})")

    required("obstacle", f"one of {', '.join(OBSTACLES)}")
    kind = raw["obstacle"]
    if not isinstance(kind, str) or kind not in OBSTACLES:
        fail("obstacle", f"{kind!r} is not one of {', '.join(OBSTACLES)}")
    allowed = (*_COMMON, *_KEYS[kind])
    for name in raw:
        if name not in allowed:
            other = [o for o, keys in _KEYS.items() if name in keys]
            hint = f" for obstacle = {kind!r}" if other else ""
            fail(name, f"unknown key{hint} (allowed: {', '.join(sorted(allowed))})")
    required("surface", "the name of a boundary of the body")
    if not isinstance(raw["surface"], str) or not raw["surface"]:
        fail("surface", f"must be a boundary name, got {raw['surface']!r}")
    required("method", f"one of {', '.join(METHODS)}")
    method = raw["method"]
    if not isinstance(method, str) or method not in METHODS:
        fail("method", f"{method!r} is not one of {', '.join(METHODS)}")

    obstacle: Obstacle
    if kind == "plane":
        required("point", "a point of the plane")
        required("normal", "the plane's normal, pointing to the free side")
        point, normal = vector("point"), vector("normal")
        if not any(normal):
            fail("normal", "must not be zero")
        obstacle = Plane(point, normal)
    elif kind == "sphere":
        required("centre", "the sphere's centre")
        required("radius", "the sphere's radius")
        centre, radius = vector("centre"), number("radius")
        if radius <= 0:
            fail("radius", f"{radius} is out of range, must be > 0")
        obstacle = Sphere(centre, radius)
    else:
        for name, what in (("a", "one end of the capsule's segment"), ("b", "the other end"),
                           ("radius", "the capsule's radius")):
            required(name, what)
        a, b, radius = vector("a"), vector("b"), number("radius")
        if a == b:
            fail("b", "must differ from a")
        if radius <= 0:
            fail("radius", f"{radius} is out of range, must be > 0")
        obstacle = Capsule(a, b, radius)

    penalty_only = [n for n in ("penalty", "augmented", "tolerance", "max_uzawa", "quadrature_degree") if n in raw]
    if method == "vi":
        if penalty_only:
            fail(penalty_only[0], 'only used with method = "penalty"')
        if kind != "plane":
            fail("method", f'vi needs obstacle = "plane" (got {kind!r}); use method = "penalty"')
        try:
            _axis_of(np.asarray(obstacle.normal), "normal")
        except ValueError:
            fail("normal", f"method = \"vi\" needs a normal along a coordinate axis (+-x, +-y, +-z), "
                           f"got {list(raw['normal'])}")
        return ContactSpec(raw["surface"], obstacle, method)

    required("penalty", "the penalty stiffness k (> 0), per unit reference area and unit penetration")
    k = number("penalty")
    if k <= 0:
        fail("penalty", f"{k} is out of range, must be > 0")
    augmented = raw.get("augmented", False)
    if not isinstance(augmented, bool):
        fail("augmented", f"must be true or false, got {augmented!r}")
    if not augmented:
        extra = [n for n in ("tolerance", "max_uzawa") if n in raw]
        if extra:
            fail(extra[0], "only used with augmented = true")
    tolerance = number("tolerance") if "tolerance" in raw else 1e-8
    if tolerance <= 0:
        fail("tolerance", f"{tolerance} is out of range, must be > 0")
    max_uzawa = raw.get("max_uzawa", 25)
    if isinstance(max_uzawa, bool) or not isinstance(max_uzawa, int):
        fail("max_uzawa", f"must be an integer, got {max_uzawa!r}")
    if max_uzawa < 1:
        fail("max_uzawa", f"{max_uzawa} is out of range, must be >= 1")
    quadrature = raw.get("quadrature_degree")
    if quadrature is not None and quadrature != "vertex" and (
            isinstance(quadrature, bool) or not isinstance(quadrature, int) or quadrature < 1):
        fail("quadrature_degree", f"must be an integer >= 1 or \"vertex\", got {quadrature!r}")
    return ContactSpec(raw["surface"], obstacle, method, k, augmented, tolerance, max_uzawa, quadrature)


def build_contact(problem: ElasticityProblem, spec: ContactSpec, motion: RigidMotion | None = None,
                  key: str = "contact") -> Contact:
    """The contact object of a checked spec, its energy added to the problem (call before the solver).

    ``motion`` moves the obstacle (model.bones; default: stationary). An unknown surface raises
    ConfigError naming ``key``.surface.
    """
    from model.config import ConfigError

    if spec.surface not in problem.domain.boundaries:
        raise ConfigError(f"{key}.surface: no boundary named {spec.surface!r} in the mesh "
                          f"(boundaries: {', '.join(sorted(problem.domain.boundaries)) or 'none'})")
    if spec.method == "vi":
        return VIContact(problem, spec.surface, spec.obstacle, motion)  # type: ignore[arg-type]
    assert spec.penalty is not None
    if spec.augmented:
        return AugmentedLagrangianContact(problem, spec.surface, spec.obstacle, spec.penalty, motion,
                                          spec.quadrature_degree, spec.tolerance, spec.max_uzawa)
    return PenaltyContact(problem, spec.surface, spec.obstacle, spec.penalty, motion, spec.quadrature_degree)
