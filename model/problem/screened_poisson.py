"""The screened Poisson problem -lap u + alpha u = f (zero flux on the boundary), standard or mixed (KKT).

    solve_screened_poisson(msh, alpha, f, degree=1, formulation="standard" | "mixed") -> PoissonSolution

Both minimise the energy of forms.poisson; UFL derives every block of the linear system from it
(ufl.derivative twice: the KKT matrix of the mixed form is the Hessian of its Lagrangian), and MUMPS
solves it. The mixed form has the unknowns (u in P_k, g and lambda in DG_(k-1)^d): its u equals the
standard u to solver precision (forms.poisson). 2D (triangles) and 3D (tetrahedra) alike.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.poisson import screened_poisson_energy, screened_poisson_lagrangian
from model import compat

FORMULATIONS = ("standard", "mixed")

Source = Callable[[ufl.SpatialCoordinate], ufl.core.expr.Expr] | float


@dataclass
class PoissonSolution:
    """u (P_k); for the mixed form also g = grad u and the multiplier lambda (DG_(k-1)^d); the global number
    of unknowns, the wall time of assembly and solve, and the relative residual of the linear system."""

    u: fem.Function
    formulation: str
    dofs: int
    time_s: float
    residual: float
    g: fem.Function | None = None
    multiplier: fem.Function | None = None


def _source(msh, f: Source) -> ufl.core.expr.Expr:
    return f(ufl.SpatialCoordinate(msh)) if callable(f) else fem.Constant(msh, PETSc.ScalarType(f))


def solve_screened_poisson(msh, alpha: float, f: Source, degree: int = 1, formulation: str = "standard",
                           quadrature_degree: int | None = None) -> PoissonSolution:
    """Minimise E(u) = 1/2 int |grad u|^2 + alpha u^2 - int f u over P_``degree`` (forms.poisson), directly
    (``formulation="standard"``) or as the saddle point of the mixed Lagrangian (``"mixed"``).

    ``f``: a number, or a function of the spatial coordinate returning a UFL expression. ``alpha`` > 0 makes
    the problem well posed without Dirichlet data. ``quadrature_degree``: default 2 degree + 2 (f is often
    not a polynomial). Collective over the mesh's communicator.
    """
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation: {formulation!r} is not one of {', '.join(FORMULATIONS)}")
    if not alpha > 0:
        raise ValueError(f"alpha: {alpha!r} must be > 0 (without Dirichlet data alpha = 0 leaves u + c free)")
    if not (isinstance(degree, int) and degree >= 1):
        raise ValueError(f"degree: {degree!r} must be a whole number >= 1")
    start = time.perf_counter()
    cell = compat.cell_name(msh)
    dim = msh.geometry.dim if compat.LEGACY else msh.topology.dim
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": quadrature_degree or 2 * degree + 2})
    a_const = fem.Constant(msh, PETSc.ScalarType(alpha))
    source = _source(msh, f)
    if formulation == "standard":
        V = compat.function_space(msh, "Lagrange", degree)
        w = fem.Function(V, name="u")
        energy = screened_poisson_energy(w, a_const, source, dx)
    else:
        P = compat.element("Lagrange", cell if not compat.LEGACY else msh.ufl_cell(), degree)
        D = compat.element("DG", cell if not compat.LEGACY else msh.ufl_cell(), degree - 1, (dim,))
        V = compat.function_space(msh, compat.mixed_element([D, P, D]))
        w = fem.Function(V)
        g, u, lam = ufl.split(w)
        energy = screened_poisson_lagrangian(g, u, lam, a_const, source, dx)
    residual_form = ufl.derivative(energy, w, ufl.TestFunction(V))
    matrix_form = ufl.derivative(residual_form, w, ufl.TrialFunction(V))
    # the energy is quadratic: one Newton step from w = 0 solves J dw = -R(0) exactly
    A = fem_petsc.assemble_matrix(fem.form(matrix_form))
    A.assemble()
    b = fem_petsc.assemble_vector(fem.form(residual_form))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    b.scale(-1.0)
    ksp = PETSc.KSP().create(msh.comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    x = b.duplicate()
    ksp.solve(b, x)
    reason = ksp.getConvergedReason()
    r = b.duplicate()
    A.mult(x, r)
    r.axpy(-1.0, b)
    residual = r.norm() / max(b.norm(), np.finfo(float).tiny)
    with x.localForm() as local:
        w.x.array[:] = local.array_r[: len(w.x.array)]
    w.x.scatter_forward()
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    for obj in (ksp, A, b, x, r):
        obj.destroy()
    if reason < 0:
        raise RuntimeError(f"screened Poisson: the LU solve failed (KSP reason {reason})")
    elapsed = time.perf_counter() - start
    if formulation == "standard":
        return PoissonSolution(w, formulation, dofs, elapsed, residual)
    parts = [w.sub(i).collapse() for i in range(3)]
    parts = [p[0] if isinstance(p, tuple) else p for p in parts]
    parts[1].name, parts[0].name, parts[2].name = "u", "g", "lambda"
    return PoissonSolution(parts[1], formulation, dofs, elapsed, residual, g=parts[0], multiplier=parts[2])


def l2_h1_errors(u: fem.Function, exact: Callable[[ufl.SpatialCoordinate], ufl.core.expr.Expr],
                 quadrature_degree: int = 8) -> tuple[float, float]:
    """(||u - u_ex||_L2, |u - u_ex|_H1) on u's mesh, reduced over its communicator."""
    msh = u.function_space.mesh
    e = u - exact(ufl.SpatialCoordinate(msh))
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": quadrature_degree})
    values = [fem.assemble_scalar(fem.form(form * dx)) for form in (e * e, ufl.inner(ufl.grad(e), ufl.grad(e)))]
    return tuple(float(np.sqrt(msh.comm.allreduce(v, op=MPI.SUM))) for v in values)  # type: ignore[return-value]


__all__ = ["FORMULATIONS", "PoissonSolution", "l2_h1_errors", "solve_screened_poisson"]
