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
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from forms.motions import RigidMotion
from forms.obstacles import (
    Obstacle,
    Plane,
    augmented_lagrangian_energy,
    axis_of,
    contact_pressure,
    penalty_energy,
)
from model import compat
from model.config.contact import ContactSpec
from model.errors import ConfigError
from model.problem import ElasticityProblem
from model.problem.body_contact import BodyContact
from model.problem.bones import MovingFrame, SurfaceNodes, body_size, current_position, surface_measure

log = logging.getLogger(__name__)


__all__ = ["AugmentedLagrangianContact", "Contact", "PenaltyContact", "VIContact", "build_contact",
           "contact_report", "pair_reports"]


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
        problem.add_energy(self.energy * self.ds, "contact")
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
        axis_of(np.asarray(obstacle.normal), "normal")
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
        j, s = axis_of(Q @ np.asarray(self.obstacle.normal), "normal")
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


def _positive(value: Any, key: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{key} must be a finite number > 0, got {value!r}")


Contact = PenaltyContact | AugmentedLagrangianContact | VIContact | BodyContact


def contact_report(contacts: Sequence[Contact]) -> dict[str, Any]:
    """One report for all contacts: the largest penetration, the summed force and active points (a contact
    between bodies counts with the force on its surface's body; pair_reports has each pair)."""
    reports = [c.contact_report() for c in contacts]
    return {"max_penetration": max((r["max_penetration"] for r in reports), default=0.0),
            "force": [float(sum(r["force"][i] for r in reports)) for i in range(3)],
            "active_points": int(sum(r["active_points"] for r in reports))}


def pair_reports(contacts: Sequence[Contact]) -> dict[str, dict[str, Any]]:
    """Per contact between bodies, by its pair name "<surface>-<master>": surface, master, kind (contact or
    sliding), max_penetration, max_gap, force (on the surface's body), normal_force (int p dA), active_points
    (model.problem.body_contact.BodyContact.report; the same on every rank)."""
    out = {}
    for c in contacts:
        if isinstance(c, BodyContact):
            report = c.report()
            out[report.pop("pair")] = report
    return out


def _body_contact(problem: ElasticityProblem, spec: ContactSpec, key: str) -> BodyContact:
    """A [[contact]] with master: model.problem.body_contact.BodyContact (contact, or sliding = true)."""
    assert spec.master is not None and spec.penalty is not None
    error = problem.domain.boundary_error(spec.master)
    if error:
        raise ConfigError(f"{key}.master: {error}")
    if problem.formulation != "displacement" or problem.degree != 1:
        raise ConfigError(f"{key}.master: contact between bodies needs P1 displacements (discretization.degree = 1, "
                          f"formulation = \"displacement\")")
    try:
        return BodyContact(problem, spec.surface, spec.master, spec.penalty,
                           kind="sliding" if spec.sliding else "contact", name=f"{spec.surface}-{spec.master}",
                           augmented=spec.augmented, tolerance=spec.tolerance, max_uzawa=spec.max_uzawa,
                           exact=spec.exact, smooth_normals=spec.smooth_normals)
    except ValueError as err:
        raise ConfigError(f"{key}.{err}") from None


def _self_contact(problem: ElasticityProblem, spec: ContactSpec, key: str) -> BodyContact:
    """A [[contact]] with self_contact = true: model.problem.self_contact.SelfContact of the surface."""
    from model.problem.self_contact import SelfContact

    assert spec.penalty is not None
    if problem.formulation != "displacement" or problem.degree != 1:
        raise ConfigError(f"{key}.self_contact: self-contact needs P1 displacements (discretization.degree = 1, "
                          f"formulation = \"displacement\")")
    try:
        return SelfContact(problem, spec.surface, spec.penalty, rings=spec.rings or 2, reach=spec.reach,
                           augmented=spec.augmented, tolerance=spec.tolerance, max_uzawa=spec.max_uzawa,
                           exact=spec.exact)
    except ValueError as err:
        raise ConfigError(f"{key}.{err}") from None


def build_contact(problem: ElasticityProblem, spec: ContactSpec, motion: RigidMotion | None = None,
                  key: str = "contact") -> Contact:
    """The contact object of a checked spec, its energy added to the problem (call before the solver).

    ``motion`` moves the obstacle (forms.motions; default: stationary). An unknown surface raises
    ConfigError naming ``key``.surface (``key``.master for a master boundary). With ``master``: a
    model.problem.body_contact.BodyContact between the two bodies.
    """
    error = problem.domain.boundary_error(spec.surface)
    if error:
        raise ConfigError(f"{key}.surface: {error}")
    if spec.self_contact:
        return _self_contact(problem, spec, key)
    if spec.master is not None:
        return _body_contact(problem, spec, key)
    if spec.method == "vi":
        return VIContact(problem, spec.surface, spec.obstacle, motion)  # type: ignore[arg-type]
    assert spec.penalty is not None
    if spec.augmented:
        return AugmentedLagrangianContact(problem, spec.surface, spec.obstacle, spec.penalty, motion,
                                          spec.quadrature_degree, spec.tolerance, spec.max_uzawa)
    return PenaltyContact(problem, spec.surface, spec.obstacle, spec.penalty, motion, spec.quadrature_degree)
