"""ARAP and shape targeting in mixed form, Newton on the whole system (issue 13 item 2; forms.mixed_arap).

    problem = ArapProblem(msh, formulation="mixed", stretch="symmetric", mu=1.0, handles=[...], dirichlet=[...])
    result = model.solvers.arap.solve_arap(problem, steps=4)   # result.u; Newton iterations per step, time_s

Unknowns of the ``mixed`` formulation: u (P1, d components), and per cell (DG0) the stretch S (d(d+1)/2 or d^2
components), the rotation increment phi (1 in 2D, 3 in 3D; R = R_ref Q(phi)) and the multiplier Lambda (d^2) of
F = R S. The ``displacement`` formulation (2D only here; in 3D the pipeline's ``shape_target`` law is the
displacement-only solve) has u alone, with the closed-form 2D rotation. Both minimise over the same admissible
displacements: handles (regions pinned by penalties (k/2)|u - u_h|^2 to a target affine motion
u_h = (Q(t a) - I)(X - c) + t d, a rotation a about the centre c and a translation d, t the load factor) and
Dirichlet values t g on boundary facets.

Load stepping: t = 1/n, 2/n, ..., 1; a step whose Newton solve fails is halved (up to ``max_halvings``). After
each converged step of the mixed form the rotations are re-based, R_ref <- R_ref Q(phi), phi <- 0 (R is
unchanged; the Cayley map stays far from its singularity at a half turn). The initial state is the rest state:
u = 0, S = I, R = I, Lambda = 0.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from forms.mixed_arap import (
    arap_energy_2d,
    handle_penalty,
    identity_components,
    incremental_rotation,
    mixed_arap_density,
    rotation_components,
    stretch_components,
    stretch_matrix,
)
from model import compat

log = logging.getLogger(__name__)

FORMULATIONS = ("mixed", "displacement")


def rotation_matrix(angle: float | Sequence[float], dim: int) -> np.ndarray:
    """The rotation by ``angle`` (2D: radians) or by the rotation vector ``angle`` (3D: axis times radians)."""
    if dim == 2:
        a = float(np.asarray(angle).reshape(-1)[0])
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    w = np.asarray(angle, dtype=float).reshape(3)
    theta = float(np.linalg.norm(w))
    if theta == 0.0:
        return np.eye(3)
    k = w / theta
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


@dataclass
class Handle:
    """Cells (local indices) pinned by a penalty of stiffness ``stiffness`` to the motion u_h =
    (Q(t angle) - I)(X - center) + t translation (``angle``: radians in 2D, a rotation vector in 3D)."""

    cells: np.ndarray
    stiffness: float
    angle: float | Sequence[float] = 0.0
    center: Sequence[float] = (0.0, 0.0, 0.0)
    translation: Sequence[float] = (0.0, 0.0, 0.0)


@dataclass
class Dirichlet:
    """Boundary facets (local indices) whose displacement is t ``value``."""

    facets: np.ndarray
    value: Sequence[float]


@dataclass
class ArapResult:
    """The displacement (P1), the per-step Newton iterations and linear iterations, the wall time of the solves,
    the global number of unknowns, the final energy (without multiplier terms, which vanish), the halvings of the
    load step, the load factors reached and (mixed form) the rotations."""

    u: fem.Function
    formulation: str
    iterations: list[int]
    time_s: float
    dofs: int
    energy: float
    cut_backs: int = 0
    steps: list[float] = field(default_factory=list)
    #: the mixed form's R per local cell (num_cells, d, d); None for the displacement formulation
    rotations: np.ndarray | None = None


class ArapProblem:
    """ARAP / shape targeting on ``msh`` (module docstring). ``target``: S_t, a UFL d x d expression (a
    Function of a DG0 tensor space, a Constant) or None for I. ``mu`` > 0, ``kappa`` >= 0."""

    def __init__(self, msh: dmesh.Mesh, *, formulation: str = "mixed", stretch: str = "symmetric",
                 mu: float = 1.0, kappa: float = 0.0, target: ufl.core.expr.Expr | None = None,
                 handles: Sequence[Handle] = (), dirichlet: Sequence[Dirichlet] = ()) -> None:
        if formulation not in FORMULATIONS:
            raise ValueError(f"formulation: {formulation!r} is not one of {', '.join(FORMULATIONS)}")
        dim = msh.topology.dim
        if formulation == "displacement" and dim != 2:
            raise ValueError("formulation: 'displacement' is built here for 2D meshes only; in 3D use the "
                             "pipeline's shape_target law (the displacement-only solve)")
        if not mu > 0:
            raise ValueError(f"mu: {mu!r} must be > 0")
        if not kappa >= 0:
            raise ValueError(f"kappa: {kappa!r} must be >= 0")
        if not handles and not dirichlet:
            raise ValueError("handles/dirichlet: none given, the rigid motions are free")
        self.msh, self.dim, self.formulation, self.stretch = msh, dim, formulation, stretch
        self.ns = stretch_components(dim, stretch)
        self.nr = rotation_components(dim)
        cell = msh.ufl_cell() if compat.LEGACY else compat.cell_name(msh)
        P1 = compat.element("Lagrange", cell, 1, (dim,))
        if formulation == "mixed":
            elements = [P1, compat.element("DG", cell, 0, (self.ns,)), compat.element("DG", cell, 0, (self.nr,)),
                        compat.element("DG", cell, 0, (dim * dim,))]
            self.W = compat.function_space(msh, compat.mixed_element(elements))
        else:
            self.W = compat.function_space(msh, P1)
        self.w = fem.Function(self.W)
        self.load = fem.Constant(msh, PETSc.ScalarType(0.0))
        I = ufl.Identity(dim)
        S_t = I if target is None else target
        dx0 = ufl.dx(domain=msh, metadata={"quadrature_degree": 0 if formulation == "mixed" else 1})
        dx2 = ufl.dx(domain=msh, metadata={"quadrature_degree": 2})
        X = ufl.SpatialCoordinate(msh)
        if formulation == "mixed":
            u, s, phi, lam = ufl.split(self.w)
            F = I + ufl.grad(u)
            S = stretch_matrix(s, dim, stretch)
            self.R_ref = fem.Function(compat.function_space(msh, "DG", 0, (dim, dim)), name="R_ref")
            R = self.R_ref * incremental_rotation(phi, dim)
            Lam = ufl.as_matrix([[lam[dim * i + j] for j in range(dim)] for i in range(dim)])
            energy = mixed_arap_density(F, S, R, Lam, mu, S_t, kappa) * dx0
            self.rotation_expr = R
        else:
            u = self.w
            F = I + ufl.grad(u)
            energy = arap_energy_2d(F, mu, S_t, kappa) * dx0
        self.u_expr = u
        self.handles = []
        DG0 = compat.function_space(msh, "DG", 0)
        owned_cells = msh.topology.index_map(dim).size_local
        for h in handles:
            indicator = fem.Function(DG0)
            cells = np.asarray(h.cells, dtype=np.int32)
            indicator.x.array[compat.cell_dofs(DG0.dofmap)[cells, 0]] = 1.0
            indicator.x.scatter_forward()
            Q = fem.Constant(msh, PETSc.ScalarType(np.eye(dim)))
            c = fem.Constant(msh, PETSc.ScalarType(np.asarray(h.center, dtype=float)[:dim]))
            d = fem.Constant(msh, PETSc.ScalarType(np.zeros(dim)))
            Xd = ufl.as_vector([X[i] for i in range(dim)])
            target_u = (Q - I) * (Xd - c) + d
            energy += indicator * handle_penalty(u, target_u, h.stiffness) * dx2
            self.handles.append((h, Q, d))
            h_cells = int(msh.comm.allreduce(int(np.sum(cells < owned_cells)), op=MPI.SUM))
            if h_cells == 0:
                raise ValueError("handles: a handle has no cells")
        self.energy = energy
        self.bcs, self._bc_values = [], []
        if dirichlet:
            if formulation == "mixed":
                V0, _ = self.W.sub(0).collapse()
                sub = self.W.sub(0)
            else:
                V0, sub = self.W, None
            for bc in dirichlet:
                g = fem.Function(V0)
                facets = np.asarray(bc.facets, dtype=np.int32)
                if sub is not None:
                    dofs = fem.locate_dofs_topological((sub, V0), dim - 1, facets)
                    self.bcs.append(fem.dirichletbc(g, dofs, sub))
                else:
                    dofs = fem.locate_dofs_topological(V0, dim - 1, facets)
                    self.bcs.append(fem.dirichletbc(g, dofs))
                self._bc_values.append((g, np.asarray(bc.value, dtype=float)[:dim]))
        #: the residual: the Lagrangian's derivative in every unknown (UFL; its Jacobian is derived again)
        self.residual = ufl.derivative(energy, self.w, ufl.TestFunction(self.W))
        self._rest_state()

    # --- state ----------------------------------------------------------------------------------------------
    def _cell_dofs(self, sub: int, component: int) -> np.ndarray:
        """W-dof of the DG0 component ``component`` of sub-space ``sub`` on every local cell."""
        space = self.W.sub(sub)
        if space.num_sub_spaces > 0:  # dolfinx 0.9 makes a one-component blocked element a scalar one
            space = space.sub(component)
        return compat.cell_dofs(space.dofmap)[:, 0]

    def _rest_state(self) -> None:
        self.w.x.array[:] = 0.0
        if self.formulation == "mixed":
            for k, value in enumerate(identity_components(self.dim, self.stretch)):
                self.w.x.array[self._cell_dofs(1, k)] = value
            blocks = self.R_ref.x.array.reshape(-1, self.dim, self.dim)
            blocks[:] = np.eye(self.dim)
            self.R_ref.x.scatter_forward()
        self.w.x.scatter_forward()

    def set_load(self, t: float) -> None:
        """Handle targets and Dirichlet values at load factor t."""
        self.load.value = t
        for h, Q, d in self.handles:
            Q.value[:] = rotation_matrix(np.asarray(h.angle, dtype=float) * t, self.dim)
            d.value[:] = t * np.asarray(h.translation, dtype=float)[: self.dim]
        for g, value in self._bc_values:
            g.interpolate(lambda x, v=value: np.outer(t * v, np.ones(x.shape[1])))
            g.x.scatter_forward()

    def rebase_rotations(self) -> None:
        """R_ref <- R_ref Q(phi), phi <- 0 on every local cell (R unchanged)."""
        if self.formulation != "mixed":
            return
        phi = np.stack([self.w.x.array[self._cell_dofs(2, k)] for k in range(self.nr)], axis=1)
        if self.dim == 2:
            Q = np.array([rotation_matrix(p[0], 2) for p in phi])
        else:
            W = np.zeros((len(phi), 3, 3))
            W[:, 0, 1], W[:, 0, 2], W[:, 1, 2] = -phi[:, 2], phi[:, 1], -phi[:, 0]
            W[:, 1, 0], W[:, 2, 0], W[:, 2, 1] = phi[:, 2], -phi[:, 1], phi[:, 0]
            scale = 2.0 / (1.0 + np.einsum("ij,ij->i", phi, phi))
            Q = np.eye(3) + scale[:, None, None] * (W + W @ W)
        space = self.R_ref.function_space
        rdofs = compat.cell_dofs(space.dofmap)[:, 0]
        blocks = self.R_ref.x.array.reshape(-1, self.dim, self.dim)
        blocks[rdofs] = blocks[rdofs] @ Q
        self.R_ref.x.scatter_forward()
        for k in range(self.nr):
            self.w.x.array[self._cell_dofs(2, k)] = 0.0
        self.w.x.scatter_forward()

    # --- solve ----------------------------------------------------------------------------------------------
    def displacement(self) -> fem.Function:
        """u as a Function of the P1 vector space (a copy)."""
        if self.formulation == "mixed":
            u = self.w.sub(0).collapse()
            u = u[0] if isinstance(u, tuple) else u
        else:
            u = self.w.copy()
        u.name = "u"
        return u

    def energy_value(self) -> float:
        """The Lagrangian at the current state, summed over the ranks (the energy at a solution: F = R S)."""
        return float(self.msh.comm.allreduce(fem.assemble_scalar(fem.form(self.energy)), op=MPI.SUM))

    def rotations(self) -> np.ndarray:
        """R per local cell, (num_cells, d, d) (mixed form; after a converged step R = R_ref: re-based)."""
        blocks = self.R_ref.x.array.reshape(-1, self.dim, self.dim)
        return blocks[compat.cell_dofs(self.R_ref.function_space.dofmap)[:, 0]].copy()


__all__ = ["ArapProblem", "ArapResult", "Dirichlet", "FORMULATIONS", "Handle", "rotation_matrix"]
