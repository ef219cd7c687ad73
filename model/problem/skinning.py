"""The mixed ARAP skinning problem in the plane for given rotations (forms.skinning): its KKT system and the
sensitivities of its solution to the angles.

    problem = SkinningProblem(msh, pinned_cells, k)      # y = (s, x, lambda) in [DG0^3, P1^2, DG0^(2x2)]
    problem.theta.x.array[:] = ...                       # R(theta) per triangle (DG0)
    problem.solve()                                      # A(theta) y = b by MUMPS

For given theta the Lagrangian is quadratic in y, so one step from any y solves it: y <- y - A^-1 r(y), with
r = dL/dy and A = d^2L/dy^2 derived by UFL (ufl.derivative twice, as model.problem.screened_poisson). The
solution's derivative in theta is dy/dtheta = -A^-1 dr/dtheta (the seed's -A^-1 (dA/dtheta) A^-1 b, since
dr/dtheta = (dA/dtheta) y and b does not depend on theta), dr/dtheta = ufl.derivative of r in theta (the matrix
C: rows y, columns theta). For an objective J(y, theta):

    dJ/dtheta = dJ/dtheta|_y - C^T mu,    A^T mu = dJ/dy         (one transposed solve, ``adjoint_gradient``).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.skinning import skinning_lagrangian
from model import compat

logger = logging.getLogger(__name__)

#: MUMPS ICNTL(14): the percentage by which the factorisation's workspace exceeds MUMPS's estimate (its default,
#: 20 or 35, fails with INFOG(1) = -9 on the gingerbread mesh: pivots delayed by the zero multiplier block)
MUMPS_WORKSPACE_PERCENT = 200


def _collapse(part) -> fem.Function:
    return part[0] if isinstance(part, tuple) else part


class SkinningProblem:
    """The KKT system of forms.skinning on a plane triangle mesh, for the angles ``theta`` (DG0).

    ``pinned_cells``: local cells (owned or ghost) of the pinned region (the seed's P); ``x_pinned``: their
    positions, a UFL expression in the spatial coordinate X (default: X, pinned at rest); ``k``: the penalty.
    Attributes: ``theta`` (DG0), ``y`` (the mixed unknown), ``pinned`` (DG0 indicator), ``lagrangian``,
    ``residual_form`` (dL/dy), ``jacobian_form`` (A), ``theta_form`` (C = dr/dtheta), ``dx``. Collective.
    """

    def __init__(self, msh, pinned_cells: np.ndarray, k: float, x_pinned=None, quadrature_degree: int = 2):
        self.msh = msh
        cell = msh.ufl_cell() if compat.LEGACY else compat.cell_name(msh)
        elements = [compat.element("DG", cell, 0, (3,)), compat.element("Lagrange", cell, 1, (2,)),
                    compat.element("DG", cell, 0, (2, 2))]
        self.space = compat.function_space(msh, compat.mixed_element(elements))
        self.angle_space = compat.function_space(msh, "DG", 0)
        self.theta = fem.Function(self.angle_space, name="theta")
        self.pinned = fem.Function(self.angle_space, name="pinned")
        self.pinned.x.array[np.asarray(pinned_cells, dtype=np.int32)] = 1.0
        self.pinned.x.scatter_forward()
        self.y = fem.Function(self.space)
        self.k = fem.Constant(msh, PETSc.ScalarType(k))
        X = ufl.SpatialCoordinate(msh)
        self.x_pinned = X if x_pinned is None else x_pinned
        self.dx = ufl.dx(domain=msh, metadata={"quadrature_degree": quadrature_degree})
        s, x, lam = ufl.split(self.y)
        self.lagrangian = skinning_lagrangian(s, x, lam, self.theta, self.k, self.pinned, self.x_pinned, self.dx)
        self.residual_form = ufl.derivative(self.lagrangian, self.y, ufl.TestFunction(self.space))
        self.jacobian_form = ufl.derivative(self.residual_form, self.y, ufl.TrialFunction(self.space))
        self.theta_form = ufl.derivative(self.residual_form, self.theta, ufl.TrialFunction(self.angle_space))
        self._residual = fem.form(self.residual_form)
        self._jacobian = fem.form(self.jacobian_form)
        self._theta = fem.form(self.theta_form)
        self.A = fem_petsc.create_matrix(self._jacobian)
        self.ksp = PETSc.KSP().create(msh.comm)
        self.ksp.setType("preonly")
        self.ksp.getPC().setType("lu")
        self.ksp.getPC().setFactorSolverType("mumps")
        self._first = True
        self.solves = 0

    # --- the state -------------------------------------------------------------------------------------
    def parts(self) -> tuple[fem.Function, fem.Function, fem.Function]:
        """Copies of (s, x, lambda) as Functions of their own spaces."""
        return tuple(_collapse(self.y.sub(i).collapse()) for i in range(3))  # type: ignore[return-value]

    def _vector(self, form) -> PETSc.Vec:
        b = fem_petsc.assemble_vector(form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def solve(self) -> float:
        """Solve A(theta) y = b at the current theta (one exact step); returns the relative residual
        ||A y - b|| / ||b|| of the linear solve."""
        start = time.perf_counter()
        self.A.zeroEntries()
        fem_petsc.assemble_matrix(self.A, self._jacobian)
        self.A.assemble()
        self.ksp.setOperators(self.A)
        if self._first:  # the zero multiplier block delays pivots: MUMPS needs more than its estimated workspace
            pc = self.ksp.getPC()
            pc.setFactorSetUpSolverType()
            pc.getFactorMatrix().setMumpsIcntl(14, MUMPS_WORKSPACE_PERCENT)
            self._first = False
        r = self._vector(self._residual)
        dy = r.duplicate()
        self.ksp.solve(r, dy)
        reason = self.ksp.getConvergedReason()
        check = r.duplicate()
        self.A.mult(dy, check)
        check.axpy(-1.0, r)
        rel = check.norm() / max(r.norm(), np.finfo(float).tiny)
        owned = self.space.dofmap.index_map.size_local * self.space.dofmap.index_map_bs
        with dy.localForm() as local:
            self.y.x.array[:owned] -= local.array_r[:owned]
        self.y.x.scatter_forward()
        for v in (r, dy, check):
            v.destroy()
        if reason < 0:
            info = self.ksp.getPC().getFactorMatrix().getMumpsInfog(1)
            raise RuntimeError(f"skinning KKT: the MUMPS solve failed (KSP reason {reason}, MUMPS INFOG(1) = {info})")
        self.solves += 1
        logger.debug("skinning KKT solve %d: rel residual %.2e in %.3f s", self.solves, rel,
                     time.perf_counter() - start)
        return float(rel)

    # --- sensitivities ----------------------------------------------------------------------------------
    def theta_matrix(self) -> PETSc.Mat:
        """C = d r / d theta at the current (y, theta) (rows: y's dofs, columns: theta's); the caller destroys it."""
        C = fem_petsc.assemble_matrix(self._theta)
        C.assemble()
        return C

    def adjoint_gradient(self, objective: ufl.Form) -> np.ndarray:
        """dJ/dtheta at the current solution (call ``solve`` first): one value per owned cell of theta's space.

        J(y, theta) a UFL form in ``self.y`` and ``self.theta``: A^T mu = dJ/dy (the factorisation of the
        last solve, transposed), dJ/dtheta = dJ/dtheta|_y - C^T mu. Collective."""
        dJdy = self._vector(fem.form(ufl.derivative(objective, self.y, ufl.TestFunction(self.space))))
        mu = dJdy.duplicate()
        self.ksp.solveTranspose(dJdy, mu)
        if self.ksp.getConvergedReason() < 0:
            raise RuntimeError(f"skinning adjoint: the MUMPS solve failed (KSP reason {self.ksp.getConvergedReason()})")
        partial = ufl.algorithms.expand_derivatives(ufl.derivative(objective, self.theta,
                                                                   ufl.TestFunction(self.angle_space)))
        if isinstance(partial, ufl.Form) and partial.empty():
            holder = fem.Function(self.angle_space)
            grad = compat.petsc_vector(holder).copy()
        else:
            grad = self._vector(fem.form(partial))
        C = self.theta_matrix()
        Ctmu = grad.duplicate()
        C.multTranspose(mu, Ctmu)
        grad.axpy(-1.0, Ctmu)
        owned = self.angle_space.dofmap.index_map.size_local
        out = grad.getArray(readonly=True)[:owned].copy()
        for obj in (dJdy, mu, grad, C, Ctmu):
            obj.destroy()
        return out

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self.ksp.destroy()
        self.A.destroy()


def objective_value(form: ufl.Form, comm: MPI.Comm) -> float:
    """The assembled scalar, summed over the ranks."""
    return float(comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM))


__all__ = ["SkinningProblem", "objective_value"]
