"""Biharmonic weights (the skinning seed, section 1.3; Jacobson et al. 2011, "Bounded biharmonic weights").

For handles H_1..H_m (mesh entities: vertices (points), facets (named boundaries) or cells (regions), given as
(dimension, local entity indices)), weight w_j in P1 minimises the discrete Laplacian energy

    E(w) = 1/2 int (lap w)^2 ~ 1/2 w^T K M^-1 K w        (K stiffness, M lumped mass of P1)

with w_j = 1 on H_j and 0 on the other handles, natural conditions elsewhere.

- Unbounded (``biharmonic_weights``): the mixed two-field form of the bilaplacian, v = -lap w an unknown of
  its own, the stationary point of L(w, v) = int grad w . grad v - 1/2 int v^2 (dL/dv: v = -lap w weakly;
  dL/dw: lap v = 0), with v^2 integrated by the vertex rule (the lumped mass); eliminating v gives E(w). UFL
  derives the system, MUMPS factors it once, one solve per handle. Partition of unity holds exactly (to
  solver precision): the constant 1 is in the kernel of K and the handle data sum to 1.
- Bounded (``bounded_biharmonic_weights``): the same energy with 0 <= w_j <= 1, a bound-constrained QP
  solved by PETSc TAO (TRON: Newton trust region with the exact Hessian Q = K M^-1 K, its subproblem factored by
  MUMPS Cholesky (without it the unpreconditioned subproblem stalls: Q has the condition of h^-4); bounds lb = ub on
  the handles); then w_j / sum_k w_k restores the partition of unity (Jacobson et al.'s normalisation),
  which keeps 0 <= w <= 1 and w_j = delta_jk on the handles.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from forms.quadrature import vertex_rule
from model import compat

Handle = tuple[int, np.ndarray]


def _locate(space: fem.FunctionSpace | tuple, handle: Handle) -> np.ndarray:
    dim, entities = handle
    msh = (space[0] if isinstance(space, tuple) else space).mesh
    msh.topology.create_connectivity(dim, 0)
    msh.topology.create_connectivity(dim, msh.topology.dim)
    return fem.locate_dofs_topological(space, dim, np.asarray(entities, dtype=np.int32))


def _check_handles(msh, handles: Sequence[Handle]) -> list[Handle]:
    comm = msh.comm
    if len(handles) < 2:
        raise ValueError(f"handles: at least two are needed, got {len(handles)}")
    V = compat.function_space(msh, "Lagrange", 1)
    located = [np.unique(_locate(V, h)) for h in handles]
    for j, dofs in enumerate(located):
        if comm.allreduce(len(dofs), op=MPI.SUM) == 0:
            raise ValueError(f"handles[{j}]: no node")
        for k in range(j):
            if comm.allreduce(len(np.intersect1d(dofs, located[k])), op=MPI.SUM):
                raise ValueError(f"handles[{j}] and handles[{k}] share nodes")
    return [(int(d), np.asarray(e, dtype=np.int32)) for d, e in handles]


def handle_at_point(msh, point: Sequence[float]) -> Handle:
    """The handle of the mesh vertex nearest to ``point`` (the same vertex on every rank; local index, or none
    on a rank that does not hold it)."""
    num_vertices = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    msh.topology.create_connectivity(0, msh.topology.dim)
    vertices = np.arange(num_vertices, dtype=np.int32)
    nodes = compat.entity_geometry(msh, 0, vertices).reshape(num_vertices, -1)[:, 0]
    coords = msh.geometry.x[nodes, : len(point)]
    distance = np.linalg.norm(coords - np.asarray(point, dtype=float), axis=1)
    best = msh.comm.allreduce(float(distance.min()) if len(distance) else np.inf, op=MPI.MIN)
    return 0, vertices[np.isclose(distance, best, rtol=0.0, atol=1e-12 * max(best, 1e-300) + 1e-14)][:1]


def biharmonic_weights(msh, handles: Sequence[Handle]) -> list[fem.Function]:
    """The unbounded biharmonic weights w_1..w_m in P1, one per handle (module docstring). Collective."""
    handles = _check_handles(msh, handles)
    cell = compat.cell_name(msh)
    P = compat.element("Lagrange", cell if not compat.LEGACY else msh.ufl_cell(), 1)
    W = compat.function_space(msh, compat.mixed_element([P, P]))
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": 1})
    dx_vertex = ufl.dx(domain=msh, metadata=vertex_rule(cell))
    # the Hessian of L(w, v) = int grad w . grad v - 1/2 int v^2 (L is quadratic: its second derivative)
    state, test = fem.Function(W), ufl.TestFunction(W)
    w_s, v_s = ufl.split(state)
    lagrangian = ufl.inner(ufl.grad(w_s), ufl.grad(v_s)) * dx - 0.5 * v_s * v_s * dx_vertex
    a = fem.form(ufl.derivative(ufl.derivative(lagrangian, state, test), state, ufl.TrialFunction(W)))
    zero = fem.form(fem.Constant(msh, PETSc.ScalarType(0.0)) * ufl.split(test)[0] * dx)
    W0 = W.sub(0)
    V0, _ = W0.collapse()
    located = [_locate((W0, V0), h) for h in handles]
    # DirichletBC takes its dofs sorted (it finds the owned ones by bisection, owned indices coming first):
    # the handles' sorted lists concatenated are not, and on 2 ranks an owned dof after a ghost one was
    # counted as a ghost, its row left without the diagonal 1 (a zero row: MUMPS INFOG(1) = -10)
    order = np.argsort(np.concatenate([d[0] for d in located]), kind="stable")
    dofs = [np.concatenate([d[0] for d in located])[order], np.concatenate([d[1] for d in located])[order]]
    value = fem.Function(V0)
    bc = fem.dirichletbc(value, dofs, W0)
    A = fem_petsc.assemble_matrix(a, bcs=[bc])
    A.assemble()
    ksp = PETSc.KSP().create(msh.comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    pc.setFactorSolverType("mumps")
    weights = []
    solution = fem.Function(W)
    for j in range(len(handles)):
        value.x.array[:] = 0.0
        value.x.array[located[j][1]] = 1.0
        b = fem_petsc.assemble_vector(zero)
        compat.apply_lifting(b, [a], bcs=[[bc]])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        compat.set_bc(b, [bc])
        x = b.duplicate()
        ksp.solve(b, x)
        if ksp.getConvergedReason() < 0:
            info = pc.getFactorMatrix().getMumpsInfog(1)
            raise RuntimeError(f"biharmonic weights: the LU solve failed for handle {j} (KSP reason "
                               f"{ksp.getConvergedReason()}, MUMPS INFOG(1) = {info})")
        with x.localForm() as local:
            solution.x.array[:] = local.array_r[: len(solution.x.array)]
        solution.x.scatter_forward()
        w_j = solution.sub(0).collapse()
        w_j = w_j[0] if isinstance(w_j, tuple) else w_j
        w_j.name = f"w{j}"
        weights.append(w_j)
        b.destroy()
        x.destroy()
    ksp.destroy()
    A.destroy()
    return weights


def bilaplacian(V: fem.FunctionSpace) -> PETSc.Mat:
    """Q = K M^-1 K on P1 (K stiffness, M lumped mass by the vertex rule): the Hessian of 1/2 int (lap w)^2."""
    msh = V.mesh
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    K = fem_petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx(
        domain=msh, metadata={"quadrature_degree": 1})))
    K.assemble()
    lumped = fem_petsc.assemble_vector(fem.form(v * ufl.dx(domain=msh, metadata=vertex_rule(compat.cell_name(msh)))))
    lumped.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    lumped.reciprocal()
    scaled = K.copy()
    scaled.diagonalScale(L=lumped)  # M^-1 K
    Q = K.matMult(scaled)
    for obj in (K, scaled, lumped):
        obj.destroy()
    return Q


def bounded_biharmonic_weights(msh, handles: Sequence[Handle], tao_type: str = "tron", gatol: float = 1e-10,
                               grtol: float = 1e-10, max_iterations: int = 500
                               ) -> tuple[list[fem.Function], list[dict]]:
    """Weights with 0 <= w_j <= 1 (module docstring): per handle the QP min 1/2 w^T Q w over the box, w = delta
    on the handles, by TAO TRON; then normalised to sum to 1. Returns (weights, per-handle TAO reports:
    iterations, TAO's converged reason, final objective). ``tao_type``, ``gatol``, ``grtol``: TAO's solver and
    gradient tolerances (absolute, relative to the objective; either ends it). Collective."""
    handles = _check_handles(msh, handles)
    V = compat.function_space(msh, "Lagrange", 1)
    Q = bilaplacian(V)
    located = [_locate(V, h) for h in handles]
    start = biharmonic_weights(msh, handles)  # the unbounded weights: a good first point once clipped
    raw, reports = [], []
    for j in range(len(handles)):
        w = fem.Function(V, name=f"w{j}")
        w.x.array[:] = np.clip(start[j].x.array, 0.0, 1.0)
        lower, upper = fem.Function(V), fem.Function(V)
        lower.x.array[:], upper.x.array[:] = 0.0, 1.0
        for k, dofs in enumerate(located):
            value = 1.0 if k == j else 0.0
            lower.x.array[dofs] = upper.x.array[dofs] = w.x.array[dofs] = value
        x = compat.petsc_vector(w).copy()
        tao = PETSc.TAO().create(msh.comm)
        tao.setType(tao_type)
        if tao_type == "tron":  # the trust-region subproblem on the free variables: a direct factorisation of Q
            pc = tao.getKSP().getPC()
            pc.setType("cholesky")
            pc.setFactorSolverType("mumps")

        def objective_gradient(tao, x, g):  # noqa: ANN001, ANN202 - TAO's callback signature
            Q.mult(x, g)
            return 0.5 * x.dot(g)

        def hessian(tao, x, H, P):  # noqa: ANN001, ANN202 - constant Hessian
            pass

        gradient = x.duplicate()
        tao.setObjectiveGradient(objective_gradient, gradient)
        tao.setHessian(hessian, Q)
        tao.setVariableBounds(compat.petsc_vector(lower), compat.petsc_vector(upper))
        tao.setTolerances(gatol=gatol, grtol=grtol, gttol=0.0)
        tao.setMaximumIterations(max_iterations)
        tao.setSolution(x)
        tao.solve()
        reason = tao.getConvergedReason()
        reports.append({"handle": j, "iterations": tao.getIterationNumber(), "reason": int(reason),
                        "objective": float(tao.getObjectiveValue())})
        if reason < 0:
            raise RuntimeError(f"bounded biharmonic weights: TAO did not converge for handle {j} (reason {reason})")
        with x.localForm() as local:
            w.x.array[:] = local.array_r[: len(w.x.array)]
        w.x.scatter_forward()
        raw.append(w)
        for obj in (tao, x, gradient):
            obj.destroy()
    Q.destroy()
    total = sum(w.x.array for w in raw)
    for w in raw:
        w.x.array[:] = w.x.array / total
    return raw, reports


__all__ = ["Handle", "biharmonic_weights", "bilaplacian", "bounded_biharmonic_weights", "handle_at_point"]
