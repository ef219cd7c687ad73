"""A pressurised membrane on a triangle surface mesh in 3D (tdim 2, gdim 3), and its closed-form references.

    problem = MembraneProblem(domain, law, orientation=radial_orientation(), fixed={"rim": (0, 1, 2)})
    problem.set_pressure(0.01)         # then model.solvers.membrane.inflate / solve_membrane

Unknown: the displacement u (P1, 3 components) of the surface; deformed position x = X + u. Energy

    Pi(u) = int_S0 w(F) dA - p V(x),   V(x) = (1/3) int_S0 x . (F t1 x F t2) dA,

w a forms.membrane law, F the 3x2 surface gradient in the rest frame (t1, t2, N) with N the unit normal oriented
by ``orientation`` (a function of the cell centroids giving a direction per cell; N . direction > 0). V is the
enclosed volume when the surface is closed, or closed by fixed plane pieces through the origin (on which
x . n = 0): a sphere octant with its symmetry planes, a disc clamped on the plane z = 0. The residual
dPi/du [v] contains the follower pressure work p int n . v da, and the Jacobian (ufl.derivative twice) is
symmetric. Dirichlet data: ``fixed`` maps a boundary name to the displacement components held at zero.

References (``balloon_pressure``, ``hencky``):

* thin spherical balloon of radius R, equibiaxial stretch lambda = r/R: the energy balance
  p 4 pi r^2 dr = d(4 pi R^2 w(lambda)) gives p = w'(lambda) / (R lambda^2);
* Hencky's clamped circular membrane (radius a, plane-stress E, nu, thickness h, small rotations, Foppl's
  membrane equations): centre deflection w0 = c(nu) a (p a / (E h))^(1/3). ``hencky`` integrates the
  axisymmetric equations N'' + 3 N'/r + E h p^2 / (8 N^2) = 0 (N the radial force per length, N'(0) = 0,
  (1 - nu) N(a) + a N'(a) = 0: no hoop strain at the clamped rim) by shooting on N(0), and
  w0 = int_0^a p r / (2 N) dr. Hencky (1915, Z. Math. Phys. 63, 311) gives the series solution with b0 = 1.724
  for nu = 0.3; its sum is w0 = 0.6534 a (p a / E h)^(1/3), what the shooting gives. The often quoted
  0.662 (Timoshenko & Woinowsky-Krieger, Theory of Plates and Shells, 1959) carries Hencky's original higher
  coefficients, corrected later (see Fichter 1997, NASA TP-3658).

Per-node pressure frozen on contact (``freeze_on_contact=True``; the thesis, ch. 3.3.3: "Pressure per-vertex is
increased linearly over time. When a node collides, its pressure value is frozen to its last value, in order
to improve the solver's stability"): the pressure is a P1 Function p_h (``nodal_pressure``) and the load is
written as a follower-pressure residual, not as -p V(x):

    R(u; v) = d/du [int w(F) dA + Pi_contacts] [v] - int_S0 p_h (F t1 x F t2) . v dA,

(F t1 x F t2) dA = n da the deformed area vector; UFL derives the Jacobian of R (not symmetric once p_h varies).
With p_h = p uniform it is the residual of Pi above: on a surface closed by clamped rims the two agree to
round-off (the P1 volume gradient of a closed ring of triangles is the nodal sum of p A n / 3). ``set_pressure``
sets p on the free nodes, ``freeze`` fixes the given nodes at their current value (model.solvers.membrane
.inflate freezes the nodes that touch after each step's equilibrium).

The thesis' unit-area pressure force (``unit_area=True``; Skouras et al. 2012's nodal force
f_i = sum_{j in N_i} (1/3) p_i A_j n_j, "a unit area A_j for all triangles is used" so that the small tendon
triangles inflate too): A_j = 1 for every triangle, n_j its current unit normal,

    R(u; v) = d/du [int w(F) dA + Pi_contacts] [v] - sum_T (1/|T_0|) int_T p_h n . v dA   (vertex rule),

i.e. f_i = (p_i / 3) sum_{j in N_i} n_j: p is then a force per triangle, not a pressure. The load is not
consistent: its total is p sum_T n_T, the number of triangles times p instead of p times the area, so it grows
like 1/h^2 under refinement (no mesh convergence) and on a graded mesh loads each region by its number of
triangles, not by its area. Implies the per-node pressure (set_pressure, freeze work the same).

A painted pressure weight map (``pressure_weight``, a function of the rest position; the thesis, ch. 3.3.3:
artists paint "a spatial weight map to create variations in the inflating behaviour"): p_i = w(X_i) p at every
node not frozen, w >= 0, through the same per-node residual (w = 1 is the uniform pressure).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.membrane import MembraneLaw, enclosed_volume, membrane_deformation_gradient, tangent_frame
from forms.quadrature import vertex_rule
from model import compat
from model.domain.distribute import Domain

log = logging.getLogger(__name__)

__all__ = ["Hencky", "MembraneProblem", "axis_orientation", "balloon_pressure", "hencky", "radial_orientation",
           "triangle_orientation"]

Orientation = Callable[[np.ndarray], np.ndarray]


def radial_orientation(centre: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Orientation:
    """Normals pointing away from ``centre`` (a closed convex surface about it, outward)."""
    c = np.asarray(centre, dtype=np.float64)
    return lambda centroids: centroids - c


def axis_orientation(axis: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> Orientation:
    """Normals along ``axis`` (a surface that is a graph over the plane normal to it, e.g. a disc: +z)."""
    a = np.asarray(axis, dtype=np.float64)
    return lambda centroids: np.broadcast_to(a, centroids.shape)


def triangle_orientation(points: np.ndarray, cells: np.ndarray) -> Orientation:
    """Normals of the given triangles' right-handed vertex order ((x1 - x0) x (x2 - x0)), looked up by centroid:
    for a surface mesh whose input triangles are oriented (e.g. an inflated patch, whatever its shape)."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=np.float64)[np.asarray(cells, dtype=np.int64)]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    tree = cKDTree(p.mean(axis=1))
    return lambda centroids: normals[tree.query(centroids)[1]]


def _normal_field(domain: Domain, orientation: Orientation) -> fem.Function:
    """The unit normal of each local cell (DG0, 3 components), oriented so that N . orientation(centroid) > 0."""
    msh = domain.mesh
    W = compat.function_space(msh, "DG", 0, (3,))
    normal = fem.Function(W, name="reference_normal")
    x = msh.geometry.x[compat.geometry_dofs(msh)][:, :3, :3]
    n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    direction = np.asarray(orientation(x.mean(axis=1)), dtype=np.float64)
    n[np.einsum("ij,ij->i", n, direction) < 0.0] *= -1.0
    dofs = compat.cell_dofs(W.dofmap)[:, 0]
    bs = W.dofmap.index_map_bs
    for k in range(3):
        normal.x.array[bs * dofs + k] = n[: len(dofs), k]
    normal.x.scatter_forward()
    return normal


def _area_field(domain: Domain) -> fem.Function:
    """The rest area |T_0| of each local cell (DG0)."""
    msh = domain.mesh
    W = compat.function_space(msh, "DG", 0)
    area = fem.Function(W, name="reference_area")
    x = msh.geometry.x[compat.geometry_dofs(msh)][:, :3, :3]
    a = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    dofs = compat.cell_dofs(W.dofmap)[:, 0]
    area.x.array[dofs] = a[: len(dofs)]
    area.x.scatter_forward()
    return area


class MembraneProblem:
    """The membrane energy Pi(u) = int w(F) dA - p V(x) on ``domain`` (module docstring).

    Attributes: ``u`` (displacement), ``pressure`` (fem.Constant), ``energy`` (the UFL form Pi), ``residual``
    (dPi/du), ``bcs``, ``V`` (the space), ``normal`` (the oriented rest normal, DG0), ``contacts`` (the contact
    terms added to Pi, model.problem.membrane_contact). ``freeze_on_contact``: the pressure per node
    (``nodal_pressure``, a scalar P1 Function; ``frozen``, a bool per owned node; module docstring), ``energy``
    then without the pressure term; ``unit_area``: the thesis' unit-area nodal force (module docstring).
    ``base_volume``: a constant V_b that ``volume`` reports V(x) from, V(x) - V_b (the energy's derivatives do not
    change): for a patch clamped on a rim that is not in a plane through the origin, V_b = V(X_b) of the patch at
    rest (the same cone formula) makes V(x) - V_b the volume between x and the rest patch (the two close on the
    clamped rim: the divergence theorem; model.experiments.membrane's muscle), independent of the origin.
    ``pressure_weight``: w(X) for the rest positions X (3, n) -> (n,), the painted weight map (module docstring;
    ``weight``, a float per owned node); ValueError unless finite and >= 0 at every node.
    """

    def __init__(self, domain: Domain, law: MembraneLaw, orientation: Orientation,
                 fixed: dict[str, tuple[int, ...]] | None = None, quadrature_degree: int = 2,
                 freeze_on_contact: bool = False, unit_area: bool = False, base_volume: float = 0.0,
                 pressure_weight: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        msh = domain.mesh
        if msh.topology.dim != 2 or msh.geometry.dim != 3:
            raise ValueError(f"membrane: needs a surface mesh (tdim 2, gdim 3), got tdim {msh.topology.dim}, "
                             f"gdim {msh.geometry.dim}")
        self.domain, self.law = domain, law
        self.base_volume = float(base_volume)
        self.V = compat.function_space(msh, "Lagrange", 1, (3,))
        self.u = fem.Function(self.V, name="displacement")
        self.pressure = fem.Constant(msh, PETSc.ScalarType(0.0))
        self.normal = _normal_field(domain, orientation)
        self.frame = tangent_frame(msh, self.normal)
        # the cell tags as subdomain data: dolfinx 0.9 needs the same for every cell integral of a form, and the
        # contact terms (model.problem.membrane_contact) integrate over tagged cells
        self.dA = ufl.Measure("dx", domain=msh, subdomain_data=domain.cell_tags,
                              metadata={"quadrature_degree": quadrature_degree})
        X = ufl.SpatialCoordinate(msh)
        self.F = membrane_deformation_gradient(self.u, self.frame)
        self.stretch_energy = law.energy(self.F) * self.dA
        self.volume_form = enclosed_volume(self.u, self.frame, X) * self.dA
        self.nodal_pressure: fem.Function | None = None
        self._load: ufl.Form | None = None
        self.freeze_on_contact, self.unit_area = bool(freeze_on_contact), bool(unit_area)
        if freeze_on_contact or unit_area or pressure_weight is not None:
            # the pressure per node: a scalar P1 Function, the dof of each displacement block from the collapsed
            # first component (as the contact multipliers, model.problem.membrane_contact)
            Q, to_v = self.V.sub(0).collapse()
            self.nodal_pressure = fem.Function(Q, name="nodal_pressure")
            q_of_block = np.full(len(self.u.x.array) // 3, -1, dtype=np.int64)
            q_of_block[np.asarray(to_v, dtype=np.int64) // 3] = np.arange(len(to_v))
            self._q = q_of_block[: self.V.dofmap.index_map.size_local]
            self.frozen = np.zeros(len(self._q), dtype=bool)
            self.weight = np.ones(len(self._q))
            if pressure_weight is not None:
                X = Q.tabulate_dof_coordinates()[self._q].T
                self.weight = np.asarray(pressure_weight(X), dtype=np.float64).reshape(-1)
                _check_weight(msh.comm, X, self.weight)
            area_vector = ufl.cross(self.F[:, 0], self.F[:, 1])  # n da / dA
            v = ufl.TestFunction(self.V)
            if unit_area:  # (p_i / 3) sum_j n_j: the vertex rule over each triangle divided by its rest area
                dA_vertex = ufl.Measure("dx", domain=msh, subdomain_data=domain.cell_tags,
                                        metadata=vertex_rule("triangle"))
                codes = tuple(sorted({int(c) for v_ in domain.regions.values() for c in v_}))
                unit = area_vector / ufl.sqrt(ufl.dot(area_vector, area_vector))
                self._load = self.nodal_pressure * ufl.dot(unit, v) / _area_field(domain) * dA_vertex(codes)
            else:
                self._load = self.nodal_pressure * ufl.dot(area_vector, v) * self.dA
            self.energy = self.stretch_energy
        else:
            self.energy = self.stretch_energy - self.pressure * self.volume_form
        self.residual = self._residual()
        self.bcs = []
        for name, components in (fixed or {}).items():
            error = domain.boundary_error(name)
            if error is not None:
                raise ValueError(f"membrane: fixed: {error}")
            facets = domain.boundary_facets(name)
            for k in components:
                sub = self.V.sub(int(k))
                dofs = fem.locate_dofs_topological(sub, 1, facets)
                self.bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0), dofs, sub))
        self._volume = fem.form(self.volume_form)
        self._area = fem.form(fem.Constant(msh, PETSc.ScalarType(1.0)) * self.dA)
        self._stretch = fem.form(self.stretch_energy)
        self.contacts: list = []  # model.problem.membrane_contact objects (add_energy registers their energies)

    def add_energy(self, energy: ufl.Form) -> None:
        """Pi <- Pi + energy (e.g. a contact penalty), and the residual again; before a solver is made."""
        self.energy = self.energy + energy
        self.residual = self._residual()

    def _residual(self) -> ufl.Form:
        """dPi/du, minus the per-node follower load with ``freeze_on_contact``."""
        residual = ufl.derivative(self.energy, self.u, ufl.TestFunction(self.V))
        return residual if self._load is None else residual - self._load

    def set_pressure(self, value: float) -> None:
        """p = ``value``: the constant, and with a per-node pressure (``freeze_on_contact``, ``unit_area``,
        ``pressure_weight``) w_i p at every node not frozen (w_i = 1 without a weight map; ghosts updated)."""
        self.pressure.value = value
        if self.nodal_pressure is not None:
            self.nodal_pressure.x.array[self._q[~self.frozen]] = value * self.weight[~self.frozen]
            self.nodal_pressure.x.scatter_forward()

    def freeze(self, nodes: np.ndarray) -> int:
        """Freeze the owned ``nodes`` (a bool per owned node) at their current pressure (frozen ones stay);
        the number of frozen nodes over all ranks. Collective."""
        if not self.freeze_on_contact:
            raise ValueError("membrane: freeze needs a problem made with freeze_on_contact=True")
        self.frozen |= np.asarray(nodes, dtype=bool)
        return self.frozen_count()

    def state(self) -> tuple[np.ndarray, ...]:
        """A copy of what an equilibrium leaves behind: u's values and, with a per-node pressure, the frozen nodes
        and p_h's values (:meth:`restore` puts it back; an inflation that goes back to an earlier state)."""
        if self.nodal_pressure is None:
            return (self.u.x.array.copy(),)
        return self.u.x.array.copy(), self.frozen.copy(), self.nodal_pressure.x.array.copy()

    def restore(self, state: tuple[np.ndarray, ...]) -> None:
        """Put back a :meth:`state` of this problem (u, and the frozen nodes with their pressures)."""
        self.u.x.array[:] = state[0]
        if self.nodal_pressure is not None:
            self.frozen[:] = state[1]
            self.nodal_pressure.x.array[:] = state[2]

    def frozen_count(self) -> int:
        """The number of frozen nodes over all ranks (0 without ``freeze_on_contact``). Collective."""
        if not self.freeze_on_contact:
            return 0
        return int(self.domain.mesh.comm.allreduce(int(self.frozen.sum()), op=MPI.SUM))

    def pressure_force(self) -> np.ndarray:
        """The pressure's total nodal force sum_i f_i at the current u (3,), every node's (Dirichlet ones too):
        p int n da, or with ``unit_area`` sum_T p_T n_T. Collective."""
        v = ufl.TestFunction(self.V)
        load = self._load if self._load is not None else \
            self.pressure * ufl.dot(ufl.cross(self.F[:, 0], self.F[:, 1]), v) * self.dA
        vector = fem_petsc.assemble_vector(fem.form(load))
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        local = vector.array_r.reshape(-1, 3).sum(axis=0)
        vector.destroy()
        return np.asarray(self.domain.mesh.comm.allreduce(local, op=MPI.SUM))

    def nodal_pressures(self) -> np.ndarray:
        """The pressure at the owned nodes (n_owned,): p_h's values, or the constant p everywhere."""
        if self.nodal_pressure is None:
            return np.full(self.V.dofmap.index_map.size_local, float(self.pressure.value))
        return self.nodal_pressure.x.array[self._q].copy()

    def _sum(self, form: fem.Form) -> float:
        return float(self.domain.mesh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))

    def volume(self) -> float:
        """V(x) - base_volume at the current u (collective)."""
        return self._sum(self._volume) - self.base_volume

    def reference_area(self) -> float:
        """The rest surface's area (collective)."""
        return self._sum(self._area)

    def elastic_energy(self) -> float:
        """int w(F) dA at the current u (collective)."""
        return self._sum(self._stretch)

    def max_component(self, k: int) -> float:
        """max over the nodes of u_k (collective)."""
        bs = self.V.dofmap.index_map_bs
        n = self.V.dofmap.index_map.size_local
        local = self.u.x.array[: n * bs].reshape(-1, bs)[:, k]
        return float(self.domain.mesh.comm.allreduce(local.max() if len(local) else -np.inf, op=MPI.MAX))


def _check_weight(comm: MPI.Comm, X: np.ndarray, weight: np.ndarray) -> None:
    """ValueError (the same on every rank) unless the weight is finite and >= 0 at every node: the first bad
    node's rest position and value."""
    bad = ~np.isfinite(weight) | (weight < 0.0)
    local = (float(weight[bad][0]), *map(float, X[:, bad][:, 0])) if bad.any() else None
    found = [b for b in comm.allgather(local) if b is not None]
    if found:
        w, *x = found[0]
        raise ValueError(f"must be finite and >= 0 at every node, got {w:.6g} at ({x[0]:.6g}, {x[1]:.6g}, "
                         f"{x[2]:.6g})")


def balloon_pressure(law: MembraneLaw, radius: float, stretch: float | np.ndarray) -> np.ndarray:
    """p(lambda) = w'(lambda) / (R lambda^2) of a thin spherical balloon of ``radius`` (module docstring)."""
    lam = np.asarray(stretch, dtype=np.float64)
    dw = np.vectorize(lambda s: law.equibiaxial(float(s))[1])(lam)
    return dw / (radius * lam**2)


@dataclass(frozen=True)
class Hencky:
    """Hencky's clamped membrane in dimensionless form: N(r) = s(r/a) (E h p^2 a^2)^(1/3),
    w(r) = a (p a / (E h))^(1/3) omega(r/a); ``coefficient`` = omega(0) (0.662 for nu = 0.3), ``b0`` = 4 s(0)
    (Hencky's 1.724 for nu = 0.3); ``rho``, ``omega``: the profile on [0, 1]."""

    nu: float
    b0: float
    coefficient: float
    rho: np.ndarray
    omega: np.ndarray

    def centre_deflection(self, radius: float, pressure: float, young: float, thickness: float) -> float:
        return self.coefficient * radius * (pressure * radius / (young * thickness)) ** (1.0 / 3.0)


def hencky(nu: float) -> Hencky:
    """Solve the dimensionless Foppl-Hencky equations s'' + 3 s'/rho + 1/(8 s^2) = 0, s'(0) = 0,
    (1 - nu) s(1) + s'(1) = 0 by shooting on s(0), then omega(rho) = int_rho^1 t / (2 s(t)) dt."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    rho0 = 1e-6

    def shoot(s0: float, dense: bool = False):
        s2 = -1.0 / (64.0 * s0**2)  # s = s0 + s2 rho^2 near the centre (regular solution)

        def rhs(r, y):  # y = (s, s', w-integral)
            return [y[1], -3.0 * y[1] / r - 1.0 / (8.0 * y[0] ** 2), -r / (2.0 * y[0])]

        return solve_ivp(rhs, (rho0, 1.0), [s0 + s2 * rho0**2, 2.0 * s2 * rho0, 0.0], rtol=1e-12, atol=1e-14,
                         dense_output=dense, method="DOP853")

    def mismatch(s0: float) -> float:
        sol = shoot(s0)
        s, ds = sol.y[0, -1], sol.y[1, -1]
        return (1.0 - nu) * s + ds

    s0 = brentq(mismatch, 0.2, 2.0, xtol=1e-14)
    sol = shoot(s0, dense=True)
    rho = np.linspace(rho0, 1.0, 201)
    integral = sol.sol(rho)[2]  # -int_0^rho t/(2 s) dt
    omega = integral - integral[-1]
    return Hencky(nu, 4.0 * s0, float(omega[0]), rho, omega)
