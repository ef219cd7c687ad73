"""The nonlinear elasticity problem: function spaces, UFL forms, boundary data, load factor.

Residual (pure displacement), with lambda the load factor:

    R(u; v) = sum_r  P_r(F) : grad v  dx_r                 internal forces, P_r = dpsi_r/dF
            - lambda sum_b  t_b . v  ds_b                  dead traction (per reference area)
            + lambda sum_b  p_b J F^-T N . v  ds_b         follower pressure (acts along -n)
            - lambda sum_r  b_r . v  dx_r                  body force (per reference volume)

Mixed displacement-pressure (Taylor-Hood, P_k / P_(k-1)): with psi = W + (kappa/2) g^2
(forms.law), the internal term uses P = dW/dF + p dg/dF and the pressure equation
(g(F) - p / kappa) q dx is added. An incompressible law (its bulk parameter lmbda, K or kappa = inf)
gets the pressure equation g(F) q dx instead: p is the Lagrange multiplier of g(F) = 0, there is no
-p^2 / (2 kappa) term, and inf never enters a form. The displacement formulation refuses such a law
(ValueError naming the parameter), and the mixed one a law with kappa = 0 (no pressure to solve for).
The Jacobian is always ufl.derivative of the residual. Dirichlet values are lambda times their
reference value.

Quadrature (quadrature_degrees): quadrature_degree = "auto" (the default) integrates the materials'
terms (energy, stress, tangent, and the polar rotations' quadrature points) with degree 1 (one point)
for P1 displacements, where F and the per-cell fields are constant in each cell so one point is exact,
and with 2 degree otherwise; loads, surfaces and inertia use 2 degree (dx, ds; the materials use
dx_energy). An integer quadrature_degree is used for every term.

Energies added with add_energy (contact and sliding penalties, a user's own terms) enter the residual
as dPi/du [v], the stored energy (total_energy, energies) and, for their cell integrals psi dx, the
stress outputs as P = dpsi/dF (stress_terms), so that a problem built from add_energy alone reports the
same quantities as one built from laws.

The energies reported per step (``energies()``), at the current solution and load factor:

    strain_energy    = sum_r int psi_r(F; alpha = 0) dx_r       passive elastic energy of the materials
    active_energy    = sum_r int psi_r(F; alpha) - psi_r(F; 0) dx_r
                                                               the fibre activation's term (activated laws only)
    <name>_energy    = Pi_name                                  each energy added with add_energy, by its name
                                                               (contact, sliding, added)
    load_potential   = - lambda sum_b int t_b . u ds_b - lambda sum_r int b_r . u dx_r
                                                               minus the work of the dead loads
    total_potential  = the sum of all of the above              (stationary at equilibrium)

psi_r(F; 0) is the law with its activation field replaced by zero (a separate form, compiled once).
For the muscle law the active term is sigma_max alpha (Fa(s) - Fa(1/l_ofl)): negative where the fibres
are shorter than at rest (isometric contraction), positive where longer. In the mixed formulation psi
is the mixed density W + p g - p^2/(2 kappa) (W + p g when kappa = inf; p g vanishes at convergence), not
W + (kappa/2) g(u)^2, which a Taylor-Hood solution satisfies only weakly (Cook's membrane at nu = 0.4999:
2039 instead of 332 N mm on 16 cells). A follower pressure has
no potential: with one, load_potential and total_potential are not reported (and the work of the
pressure, path dependent, is not either).

The potential as a function of the unknowns (``potential_reason()``, ``total_potential()``): the residual is
its Gateaux derivative, R(u; v) = dPi/du [v] with Pi = total_potential, exactly when every term of the residual
comes from an energy: the materials, dead tractions and body forces, and add_energy (contact and sliding
penalties, augmented Lagrangian contact at fixed multipliers). Then Newton's problem is the minimisation of Pi
over the displacements that satisfy the Dirichlet conditions, and Pi is the merit function of a line search
(model.solvers.newton). There is none with a follower pressure (no potential), with residual terms added with
add_residual (inertia and damping of a time integrator, added as residuals; docs/solvers.md), in the mixed
formulation, whose Pi(u, p) is a saddle (W + p g - p^2 / (2 kappa) is maximised in p), not a minimum, or with a
coupling whose residual is not the derivative of its energy (its ``potential_reason()``: sliding between bodies
with smoothed normals, model.problem.body_contact).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from forms import Law, law_fields
from forms.kinematics import cauchy_stress, deformation_gradient, von_mises
from forms.law import replace_fields
from model import compat
from model.domain import Domain
from model.fields.eigen import EigenField
from model.fields.polar import PolarField
from model.problem.parameters import hold_parameters

log = logging.getLogger(__name__)

ValueSource = float | Callable[[np.ndarray], np.ndarray]


#: the default quadrature_degree: chosen from the displacement degree (quadrature_degrees)
AUTO = "auto"


def quadrature_degrees(degree: int, quadrature_degree: int | str = AUTO) -> tuple[int, int]:
    """(q, q_energy): the quadrature degree of the loads, surface terms and inertia, and of the materials.

    "auto": q = 2 degree, q_energy = 1 for degree 1 and 2 degree otherwise. For degree 1, F = I + grad u
    is constant per cell and the laws' fields (a0, alpha, S) are per cell (DG0), so every material's
    integrands psi(F), P(F) : grad v and A(F) grad du : grad v are constant per cell: one point
    (degree 1) integrates them exactly, where degree 2 (four points) evaluates the same value four
    times. The loads keep 2 degree (a traction or body force given by an expression of x varies in the
    cell), and so does the inertia rho u . v (quadratic). An integer is used for both, as given.
    """
    if quadrature_degree == AUTO:
        return 2 * degree, (1 if degree == 1 else 2 * degree)
    if isinstance(quadrature_degree, bool) or not isinstance(quadrature_degree, int) or quadrature_degree < 1:
        raise ValueError(f"quadrature_degree must be an integer >= 1 or 'auto', got {quadrature_degree!r}")
    return quadrature_degree, quadrature_degree


@dataclass
class DirichletBoundary:
    """Dirichlet data on one named boundary: per constrained component its dofs and values at lambda = 1."""

    name: str
    components: tuple[int, ...]
    bcs: list[compat.DirichletBC] = field(default_factory=list)
    dofs: list[np.ndarray] = field(default_factory=list)  # local indices in the solution vector
    collapsed: list[np.ndarray] = field(default_factory=list)  # the same dofs in the component's collapsed space
    values: list[fem.Function] = field(default_factory=list)
    reference: list[np.ndarray] = field(default_factory=list)
    #: per component: f(x, t) evaluated at t = load factor (not scaled), or None (value scaled by t)
    of_load_factor: list[Callable[..., np.ndarray] | None] = field(default_factory=list)


class ElasticityProblem:
    """Forms and boundary data of one run; quantities that change (load factor, Dirichlet values) never recompile."""

    def __init__(self, domain: Domain, materials: Sequence[tuple[str, Law]], degree: int = 1,
                 quadrature_degree: int | str = AUTO, formulation: str = "displacement") -> None:
        if formulation not in ("displacement", "mixed"):
            raise ValueError(f"formulation must be 'displacement' or 'mixed', got {formulation!r}")
        if formulation == "mixed" and degree < 2:
            raise ValueError("the mixed (Taylor-Hood) formulation needs degree >= 2")
        self.domain = domain
        self.degree = degree
        #: quadrature degree of the loads, surface terms, inertia and added energies; the materials'
        #: energy uses energy_quadrature_degree (quadrature_degrees)
        self.quadrature_degree, self.energy_quadrature_degree = quadrature_degrees(degree, quadrature_degree)
        self.formulation = formulation
        self.materials = list(materials)
        msh = domain.mesh
        cell = compat.cell_name(msh)
        displacement_element = compat.element("Lagrange", cell, degree, (3,))
        if formulation == "mixed":
            element = compat.mixed_element([displacement_element, compat.element("Lagrange", cell, degree - 1)])
            self.space = compat.function_space(msh, element)
            self.displacement_space = self.space.sub(0)
        else:
            self.space = compat.function_space(msh, displacement_element)
            self.displacement_space = self.space
        self.solution = fem.Function(self.space, name="solution")
        if formulation == "mixed":
            self.u, self.p = ufl.split(self.solution)
            self.v, self.q = ufl.TestFunctions(self.space)
        else:
            self.u, self.p = self.solution, None
            self.v, self.q = ufl.TestFunction(self.space), None
        self.load_factor = fem.Constant(msh, PETSc.ScalarType(0.0))
        #: the time t of the last set_load_factor (quasi-static: the load factor itself)
        self.time = 0.0
        #: s(t), the factor of scaled loads and Dirichlet values at time t (quasi-static: s = t; a dynamic
        #: run ramps them over its ramp time)
        self.load_scale: Callable[[float], float] = lambda t: t
        metadata = {"quadrature_degree": self.quadrature_degree}
        self.dx = ufl.Measure("dx", domain=msh, subdomain_data=domain.cell_tags, metadata=metadata)
        self.ds = ufl.Measure("ds", domain=msh, subdomain_data=domain.facet_tags, metadata=metadata)
        #: dx of the materials' energy, stress and tangent (and of their quadrature-point state)
        self.dx_energy = ufl.Measure("dx", domain=msh, subdomain_data=domain.cell_tags,
                                     metadata={"quadrature_degree": self.energy_quadrature_degree})
        log.info("quadrature degree %d (materials' energy %d), displacement degree %d", self.quadrature_degree,
                 self.energy_quadrature_degree, degree)
        self.F = deformation_gradient(self.u)
        self.polar_fields: list[PolarField] = []
        #: per-point eigen states of the laws that need one (forms.ogden), updated with the polar fields
        self.eigen_fields: list[EigenField] = []
        self._state_stamp: np.ndarray | None = None
        self.internal = 0
        self.external = 0
        zero = fem.Constant(msh, PETSc.ScalarType(0.0))
        #: the materials' energy int psi(F; alpha) dx, active term included (a zero form when there is no
        #: material: always a ufl.Form)
        self.material_energy: ufl.Form = zero * self.dx_energy
        #: the materials' passive energy int psi(F; alpha = 0) dx
        self.passive_energy: ufl.Form = zero * self.dx_energy
        #: sum_r int psi_r(F; alpha) - psi_r(F; 0) dx_r over the activated materials, or None (none is)
        self.active_energy: ufl.Form | None = None
        #: the zero activation the passive energy is built with
        self._no_activation = fem.Constant(msh, PETSc.ScalarType(0.0))
        #: (P, dx): first Piola-Kirchhoff stress of each material and of each cell integral of an added energy
        self.stress_terms: list[tuple[ufl.core.expr.Expr, ufl.Measure]] = []
        #: terms coupling distant dofs (model.problem.body_contact.BodyContact): refreshed in update_state, their
        #: residual and matrix added by the Newton solver (add_residual(b), add_jacobian(A))
        self.couplings: list[Any] = []
        self.extra_energies: list[ufl.Form] = []
        #: the name of each added energy (parallel to extra_energies): "contact", "sliding", "added", ...
        self.extra_energy_names: list[str] = []
        #: - lambda (int t . u ds + int b . u dx) of the dead loads (a zero form when there is none)
        self.load_potential: ufl.Form = zero * self.dx
        #: the boundaries carrying a follower pressure (no potential)
        self.follower_pressures: list[str] = []
        #: how many residual terms add_residual added (inertia, damping: no potential)
        self.residual_terms = 0
        #: per term add_residual added: why its derivative (its part of the Jacobian) is symmetric, or None (not
        #: known to be: symmetry_reason then takes the Jacobian as nonsymmetric)
        self.residual_symmetry: list[str | None] = []
        self._potential_form: compat.Form | None = None
        self._energy_form: compat.Form | None = None
        self._energy_forms: dict[str, compat.Form] | None = None
        #: per-cell input fields written with the results (fibre directions, activation), by name
        self.cell_fields: dict[str, fem.Function] = {}
        #: per material (in order): the law parameters held as runtime values, {name: fem.Constant}
        self.held_parameters: list[dict[str, fem.Constant]] = []
        for i, (region, law) in enumerate(self.materials):
            if formulation == "displacement" and law.incompressible:
                value = getattr(law, law.bulk_parameter, law.bulk_penalty)
                raise ValueError(f"{law.name}: {law.bulk_parameter} = {value!r} (incompressible, materials[{i}] on "
                                 f"region {region!r}) needs formulation = 'mixed' (Taylor-Hood): the displacement "
                                 "formulation has no pressure to enforce the constraint")
            self.materials[i] = (region, self._add_material(region, law))
        self.dirichlet: list[DirichletBoundary] = []
        self.load_hooks: list[Callable[[float], None]] = []
        self._forms: tuple[compat.Form, compat.Form] | None = None
        self._unit_load: tuple[Any, compat.Form] | None = None

    # --- set-up ---------------------------------------------------------------------------------

    def region_measure(self, region: str) -> ufl.Measure:
        """dx restricted to a named region ("all" is the whole mesh)."""
        return self.dx if region == "all" else self.dx(self.domain.regions[region])

    def energy_measure(self, region: str) -> ufl.Measure:
        """dx_energy (the materials' quadrature, energy_quadrature_degree) restricted to a named region."""
        return self.dx_energy if region == "all" else self.dx_energy(self.domain.regions[region])

    def boundary_measure(self, name: str) -> ufl.Measure:
        """ds restricted to a named boundary."""
        return self.ds(self.domain.boundaries[name])

    def _add_material(self, region: str, law: Law) -> Law:
        """Add the law's terms; returns the law as used (with its eigen state when it needs one), with its numbers.

        The terms are built from the law holding its parameters as runtime values (model.problem.parameters:
        fem.Constants, so that the same law with other numbers reuses the compiled kernels); the constants are
        ``held_parameters[material index]``, {name: constant}."""
        dx = self.energy_measure(region)
        R = None
        if getattr(law, "needs_eigenbasis", False):
            eigen = EigenField(self.domain.mesh, law.spectral_argument(self.F),  # type: ignore[attr-defined]
                               self.energy_quadrature_degree, law.spectral_derivatives,  # type: ignore[attr-defined]
                               self.domain.region_cells(region))
            self.eigen_fields.append(eigen)
            law = law.with_eigenbasis(eigen.Q0, eigen.D)  # type: ignore[attr-defined]
        if law.needs_rotation:
            polar = PolarField(self.domain.mesh, law.rotation_argument(self.F), self.energy_quadrature_degree,
                               self.domain.region_cells(region))
            self.polar_fields.append(polar)
            R = polar.rotation
        runtime, held = hold_parameters(law, self.domain.mesh, lambda candidate: self._law_terms(candidate, R))
        self.held_parameters.append(held)
        P, energy, pressure, passive = self._law_terms(runtime, R)
        self.internal += ufl.inner(P, ufl.grad(self.v)) * dx
        if pressure is not None:
            self.internal += pressure * self.q * dx
        self.material_energy += energy * dx
        if passive is None:
            self.passive_energy += energy * dx
        else:
            self.passive_energy += passive * dx
            active = (energy - passive) * dx
            self.active_energy = active if self.active_energy is None else self.active_energy + active
        self.stress_terms.append((P, dx))
        self._energy_form = None
        self._energy_forms = None
        self._potential_form = None
        return law

    def _law_terms(self, law: Law, R: ufl.core.expr.Expr | None) -> tuple[Any, Any, Any, Any]:
        """(P, energy, pressure residual or None, passive energy or None) of a law: the stress P(F; R, p), the
        energy (the mixed formulation's Pi(u, p) = W + p g - p^2/(2 kappa): (kappa/2) g(u)^2 of the discrete u
        is not the volumetric energy of a Taylor-Hood solution, whose p is kappa g only in the weak sense), the
        pressure equation g(F) - p/kappa, and the energy without activation."""
        P = law.stress(self.F, R, self.p)
        energy = law.energy(self.F, R) if self.p is None else law.mixed_energy(self.F, self.p, R)
        pressure = law.pressure_residual(self.F, self.p) if self.p is not None else None
        return P, energy, pressure, self._without_activation(law, R)

    def _without_activation(self, law: Law, R: ufl.core.expr.Expr | None) -> ufl.core.expr.Expr | None:
        """psi(F; alpha = 0) of a law whose activation field alpha is set, else None (nothing to remove)."""
        if "alpha" not in law_fields(law) or getattr(law, "alpha", None) is None or not dataclasses.is_dataclass(law):
            return None
        passive = replace_fields(law, alpha=self._no_activation)  # parameters may be UFL values (adjoint)
        return passive.energy(self.F, R) if self.p is None else passive.mixed_energy(self.F, self.p, R)

    def add_dirichlet(self, name: str, components: Sequence[int], values: Sequence[ValueSource],
                      load_dependent: Sequence[bool] | None = None,
                      points: Sequence[Sequence[float]] = ()) -> None:
        """u_i = lambda * value_i on boundary ``name`` for each listed component (constant or f(x)).

        A component marked load-dependent has u_i = f(x, lambda) instead (not scaled).
        With ``points``, only the boundary's nodes at those points are constrained (a ValueError
        names the first point that is not a node of the boundary).
        """
        load_dependent = load_dependent or [False] * len(components)
        facets = self.domain.boundary_facets(name)
        fdim = self.domain.mesh.topology.dim - 1
        entry = DirichletBoundary(name, tuple(components))
        for comp, value, dependent in zip(components, values, load_dependent):
            sub = self.displacement_space.sub(comp)
            collapsed, _ = sub.collapse()
            dofs = fem.locate_dofs_topological((sub, collapsed), fdim, facets)
            if len(points):
                dofs = self._dofs_at_points(collapsed, dofs, points, name)
            g = fem.Function(collapsed)
            entry.of_load_factor.append(value if dependent else None)
            if dependent:
                g.interpolate(lambda x, f=value: f(x, self.time))
            elif callable(value):
                g.interpolate(lambda x, f=value: f(x))
            else:
                g.x.array[:] = float(value)
            entry.reference.append(g.x.array.copy())
            entry.values.append(g)
            entry.dofs.append(dofs[0])
            entry.collapsed.append(dofs[1])
            entry.bcs.append(fem.dirichletbc(g, dofs, sub))
        self.dirichlet.append(entry)
        self._forms = None

    def _dofs_at_points(self, collapsed: fem.FunctionSpace, dofs: list[np.ndarray],
                        points: Sequence[Sequence[float]], name: str) -> list[np.ndarray]:
        """The entries of (dofs in V, dofs in the collapsed space) located at the given points."""
        msh = self.domain.mesh
        comm = msh.comm
        x = collapsed.tabulate_dof_coordinates()[dofs[1]]
        low, high = np.empty(3), np.empty(3)
        comm.Allreduce(msh.geometry.x.min(axis=0), low, op=MPI.MIN)
        comm.Allreduce(msh.geometry.x.max(axis=0), high, op=MPI.MAX)
        tol = 1e-8 * float(np.linalg.norm(high - low))
        keep = np.zeros(len(x), dtype=bool)
        for i, point in enumerate(points):
            near = np.linalg.norm(x - np.asarray(point, dtype=np.float64), axis=1) <= tol
            if comm.allreduce(int(near.sum()), op=MPI.SUM) == 0:
                raise ValueError(f"point {i} {list(point)} is not a node of boundary {name!r}")
            keep |= near
        return [dofs[0][keep], dofs[1][keep]]

    def add_traction(self, name: str, traction: Sequence[float] | ufl.core.expr.Expr) -> None:
        """Dead traction t (per unit reference area) on boundary ``name``, scaled by lambda."""
        t = ufl.as_vector(traction) if not isinstance(traction, ufl.core.expr.Expr) else traction
        self.external += self.load_factor * ufl.inner(t, self.v) * self.boundary_measure(name)
        self.load_potential += -self.load_factor * ufl.inner(t, self.u) * self.boundary_measure(name)
        self._forms = None
        self._energy_forms = None
        self._potential_form = None

    def add_pressure(self, name: str, pressure: float) -> None:
        """Follower pressure p on boundary ``name`` (positive pushes inwards), scaled by lambda.

        Reference-configuration traction t0 = -p J F^-T N (Nanson's formula).
        """
        N = ufl.FacetNormal(self.domain.mesh)
        J = ufl.det(self.F)
        t0 = -pressure * J * ufl.inv(self.F).T * N
        self.external += self.load_factor * ufl.inner(t0, self.v) * self.boundary_measure(name)
        self.follower_pressures.append(name)
        self._forms = None
        self._energy_forms = None
        self._potential_form = None

    def add_energy(self, energy: ufl.Form, name: str = "added") -> None:
        """Add a potential Pi (a UFL form in the solution, e.g. a contact penalty): R += dPi/du [v].

        Pi counts in total_energy() and in energies() as "<name>_energy" (energies of the same name are
        summed: "contact", "sliding", "added" for a user's terms); each of its cell integrals psi dx whose
        psi depends on grad u adds P = dpsi/dF to the stress outputs (stress_terms). Call before a solver
        is created (the forms are compiled then).
        """
        self.internal += ufl.derivative(energy, self.solution, ufl.TestFunction(self.space))
        self.extra_energies.append(energy)
        self.extra_energy_names.append(name)
        self.stress_terms += self._stress_terms_of(energy)
        self._energy_form = None
        self._energy_forms = None
        self._potential_form = None
        self._forms = None

    def _stress_terms_of(self, energy: ufl.Form) -> list[tuple[ufl.core.expr.Expr, ufl.Measure]]:
        """(P = dpsi/dF, dx) of each cell integral psi dx of ``energy`` that depends on F = I + grad u.

        grad u is replaced by a variable F - I, so P holds u and p fixed: the first Piola-Kirchhoff
        stress of psi (its dependence on u itself, e.g. a body-force potential, is no stress).
        """
        from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering
        from ufl.algorithms.apply_derivatives import apply_derivatives

        Fv = ufl.variable(self.F)
        grad_u = ufl.grad(self.u)
        out = []
        for integral in energy.integrals():
            if integral.integral_type() != "cell":
                continue
            density = ufl.replace(integral.integrand(), {grad_u: Fv - ufl.Identity(3)})
            P = apply_derivatives(ufl.diff(apply_algebra_lowering(density), Fv))
            if isinstance(P, ufl.constantvalue.Zero):
                continue
            dx = ufl.Measure("dx", domain=integral.ufl_domain(), subdomain_id=integral.subdomain_id(),
                             metadata=integral.metadata(), subdomain_data=integral.subdomain_data())
            out.append((P, dx))
        return out

    def add_residual(self, form: ufl.Form, symmetric: str | None = None) -> None:
        """Add a residual term linear in the test functions (self.v, self.q), e.g. inertia or damping.

        ``symmetric``: why the term's derivative d(form)/du [du] is symmetric in (v, du), when it is (the time
        integrator's inertia and Rayleigh damping: model.solvers.dynamics); None (the default): not known, and
        the Jacobian is taken as nonsymmetric (symmetry_reason). Call before a solver is created (the forms are
        compiled then).
        """
        self.internal += form
        self.residual_terms += 1
        self.residual_symmetry.append(symmetric)
        self._forms = None

    def add_load_hook(self, hook: Callable[[float], None]) -> None:
        """Call hook(lambda) whenever the load factor is set (e.g. to re-evaluate procedural targets)."""
        self.load_hooks.append(hook)

    def add_body_force(self, region: str, force: Sequence[float] | ufl.core.expr.Expr) -> None:
        """Body force b (per unit reference volume) on ``region``, scaled by lambda."""
        b = ufl.as_vector(force) if not isinstance(force, ufl.core.expr.Expr) else force
        self.external += self.load_factor * ufl.inner(b, self.v) * self.region_measure(region)
        self.load_potential += -self.load_factor * ufl.inner(b, self.u) * self.region_measure(region)
        self._forms = None
        self._energy_forms = None
        self._potential_form = None

    # --- forms ----------------------------------------------------------------------------------

    @property
    def residual_form(self) -> ufl.Form:
        return self.internal - self.external if self.external != 0 else self.internal

    @property
    def forms(self) -> tuple[compat.Form, compat.Form]:
        """(residual, Jacobian) compiled; the Jacobian is the Gateaux derivative of the residual."""
        if self._forms is None:
            residual = self.residual_form
            jacobian = ufl.derivative(residual, self.solution, ufl.TrialFunction(self.space))
            self._forms = (fem.form(residual), fem.form(jacobian))
        return self._forms

    def unit_load_form(self) -> compat.Form | None:
        """f(u; v), the loads at load factor 1 (dead tractions, follower pressures, body forces) compiled: the
        residual is R(u, lambda) = internal(u; v) - lambda f(u; v). None without loads. Compiled once per set of
        loads (kept with the external form it came from)."""
        if isinstance(self.external, int):
            return None
        if self._unit_load is None or self._unit_load[0] is not self.external:
            one = fem.Constant(self.domain.mesh, PETSc.ScalarType(1.0))
            self._unit_load = (self.external, fem.form(ufl.replace(self.external, {self.load_factor: one})))
        return self._unit_load[1]

    def zero_dirichlet_rows(self, vec: PETSc.Vec) -> None:
        """Set the entries of the owned Dirichlet dofs of a vector in the solution's layout to 0."""
        owned = vec.getLocalSize()
        array = vec.array
        for entry in self.dirichlet:
            for dofs in entry.dofs:
                array[dofs[dofs < owned]] = 0.0

    @property
    def bcs(self) -> list[compat.DirichletBC]:
        return [bc for entry in self.dirichlet for bc in entry.bcs]

    def set_load_factor(self, value: float) -> None:
        """t <- value: scaled loads and Dirichlet values get s(t) (load_scale; s = t unless a dynamic run
        ramps them), expressions f(x, t) and the load hooks (activation, bones, targets) get t.
        Nothing recompiles."""
        self.time = float(value)
        scale = float(self.load_scale(self.time))
        self.load_factor.value = scale
        for hook in self.load_hooks:
            hook(value)
        if self.load_hooks:
            self.invalidate_state()
        for entry in self.dirichlet:
            for g, ref, f in zip(entry.values, entry.reference, entry.of_load_factor):
                if f is None:
                    g.x.array[:] = scale * ref
                else:
                    g.interpolate(lambda x, f=f: f(x, value))

    def update_state(self) -> None:
        """Refresh state stored at quadrature points (polar rotations, eigen states) from the current solution.

        Skipped when the solution is unchanged since the last refresh (SNES evaluates the
        residual and the Jacobian at the same iterate; outputs evaluate it once more).
        """
        for coupling in self.couplings:  # each keeps its own stamp of the solution it was paired at
            coupling.update()
        if not self.polar_fields and not self.eigen_fields:
            return
        current = self.solution.x.array
        if self._state_stamp is not None and np.array_equal(self._state_stamp, current):
            return
        for polar in self.polar_fields:
            polar.update()
        for eigen in self.eigen_fields:
            eigen.update()
        self._state_stamp = current.copy()

    def invalidate_state(self) -> None:
        """Force the next update_state to recompute (after changing a coefficient the state depends on)."""
        self._state_stamp = None

    # --- derived quantities ---------------------------------------------------------------------

    def total_energy(self) -> float:
        """The stored energy at the current solution (all ranks): the materials' int psi(F; alpha) dx
        (strain_energy + active_energy of energies()) plus every energy added with add_energy (contact,
        sliding, a user's terms); the loads' potential is not included (see energies()).

        For an incompressible law (kappa = inf, mixed formulation) the material's term is the Lagrangian
        int (W + p g(F)) dx, whose p g part vanishes at convergence (the pressure equation makes
        int g q dx = 0 for every q of the pressure space, p among them): it is int W dx to solver
        tolerance. A law with finite kappa contributes int psi dx = int W + (kappa/2) g^2 dx in both
        formulations.
        """
        if self._energy_form is None:
            energy = self.material_energy
            for extra in self.extra_energies:
                energy = energy + extra
            self._energy_form = fem.form(energy)
        self.update_state()
        comm = self.domain.mesh.comm
        return comm.allreduce(fem.assemble_scalar(self._energy_form), op=MPI.SUM)

    def energies(self) -> dict[str, float]:
        """The energies of the module docstring at the current solution and load factor (all ranks):
        strain_energy; active_energy (only with an activated material); <name>_energy per name of the
        added energies; load_potential and total_potential (left out with a follower pressure, which has
        no potential). The forms are compiled on the first call (and again only after a term is added).
        """
        if self._energy_forms is None:
            forms = {"strain_energy": self.passive_energy}
            if self.active_energy is not None:
                forms["active_energy"] = self.active_energy
            for name, extra in zip(self.extra_energy_names, self.extra_energies):
                key = f"{name}_energy"
                forms[key] = forms[key] + extra if key in forms else extra
            if not self.follower_pressures:
                forms["load_potential"] = self.load_potential
            self._energy_forms = {k: fem.form(f) for k, f in forms.items()}
        self.update_state()
        comm = self.domain.mesh.comm
        out = {k: float(comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM)) for k, f in self._energy_forms.items()}
        if not self.follower_pressures:
            out["total_potential"] = sum(out.values())
        return out

    def potential_reason(self) -> str | None:
        """None when the residual is the derivative of total_potential (module docstring), else why it is not."""
        if self.formulation != "displacement":
            return "the mixed formulation's potential is a saddle in (u, p), not a minimum"
        if self.follower_pressures:
            return f"the follower pressure on {', '.join(repr(b) for b in self.follower_pressures)} has no potential"
        if self.residual_terms:
            return "residual terms without a potential (inertia, damping) were added"
        for coupling in self.couplings:  # contact between bodies whose residual is not its energy's derivative
            reason = getattr(coupling, "potential_reason", lambda: None)()
            if reason is not None:
                return reason
        return None

    def symmetry_reason(self, tangent: str = "exact") -> str | None:
        """None when Newton's matrix J is symmetric, else why it is not (the linear presets pick the Krylov method
        by it: model.solvers.linear.resolve; docs/solvers.md, "Which tangents are symmetric").

        Symmetric terms (J_ij = J_ji): the materials' d2psi/du2 (the Hessian of a strain-energy density; with the
        projected tangent its per-point PSD projection A_proj = A_proj^T), every energy added with add_energy (its
        Hessian d2Pi/du2: obstacle contact, sliding on bones, augmented Lagrangian at fixed multipliers), the mixed
        formulation's [A B^T; B C] (symmetric indefinite: C = -int p q / kappa dx), the Dirichlet rows and columns
        (zeroed, 1 on the diagonal) and the couplings' C = K_uz Pi + Pi^T K_zu + Pi^T K_zz Pi (their
        ``symmetry_reason``). Not symmetric:

            follower pressure   d/du [p J F^-T N . v] = p J ((F^-T : grad du) F^-T - F^-T grad du^T F^-T) N . v,
                                not symmetric in (v, du) on a surface with a free rim (on a closed surface, or one
                                whose rim is held, its assembled matrix is the Hessian of p V and symmetric; that is
                                not looked for: treated as nonsymmetric). Kept by the projected tangent.
            add_residual        a term whose symmetry was not stated (``symmetric`` None); the projected tangent
                                leaves such terms out of J (only the materials and the external loads).
            couplings           one whose ``symmetry_reason`` says so, or that has none (unknown).
        """
        if self.follower_pressures:
            return (f"the follower pressure on {', '.join(repr(b) for b in self.follower_pressures)} has a "
                    "nonsymmetric load stiffness")
        unknown = sum(reason is None for reason in self.residual_symmetry)
        if unknown and tangent == "exact":
            return f"{unknown} residual term(s) of unknown symmetry were added (add_residual)"
        for coupling in self.couplings:
            method = getattr(coupling, "symmetry_reason", None)
            name = getattr(coupling, "name", type(coupling).__name__)
            reason = method() if method is not None else f"the coupling {name} does not say whether its matrix is " \
                                                           "symmetric"
            if reason is not None:
                return reason
        return None

    def total_potential(self) -> float:
        """Pi(u) = int psi(F) dx + the added energies + load_potential at the current solution and load factor
        (all ranks): the sum energies() reports as total_potential, from one compiled form. ValueError when the
        residual is not its derivative (potential_reason)."""
        reason = self.potential_reason()
        if reason is not None:
            raise ValueError(f"no total potential: {reason}")
        if self._potential_form is None:
            energy = self.material_energy + self.load_potential
            for extra in self.extra_energies:
                energy = energy + extra
            self._potential_form = fem.form(energy)
        self.update_state()
        comm = self.domain.mesh.comm
        return float(comm.allreduce(fem.assemble_scalar(self._potential_form), op=MPI.SUM))

    def stress_groups(self) -> list[tuple[ufl.core.expr.Expr, ufl.Measure]]:
        """(P, dx): the stress terms summed per measure (a material and an added energy on the same cells
        make one stress), in the order of their first term."""
        groups: dict[ufl.Measure, ufl.core.expr.Expr] = {}
        for P, dx in self.stress_terms:
            groups[dx] = groups[dx] + P if dx in groups else P
        return list((P, dx) for dx, P in groups.items())

    def cauchy_stress_terms(self) -> list[tuple[ufl.core.expr.Expr, ufl.Measure]]:
        """(sigma = J^-1 P F^T, dx) per material region and added energy (stress_groups)."""
        return [(cauchy_stress(P, self.F), dx) for P, dx in self.stress_groups()]

    def von_mises_terms(self) -> list[tuple[ufl.core.expr.Expr, ufl.Measure]]:
        """(von Mises stress of sigma, dx) per stress group: the stresses of one measure summed first."""
        return [(von_mises(sigma), dx) for sigma, dx in self.cauchy_stress_terms()]

    def displacement(self) -> fem.Function:
        """The displacement as a Function of its own (collapsed) space."""
        if self.formulation == "mixed":
            return self.solution.sub(0).collapse()
        return self.solution
