"""The mixed (Taylor-Hood) Jacobian as a nested matrix: one PETSc matrix per block of the fields u and p.

    J = [[J_uu, J_up],      (PETSc MATNEST in the block layout: on each rank its owned u dofs, then its owned
         [J_pu, J_pp]]       p dofs; SNES works in it, the callbacks permute to and from the mixed space's layout)

PCFieldSplit extracts the blocks of an assembled (AIJ) Jacobian by copying them (MatCreateSubMatrix: J_uu, J_pp,
B = J_up and C = J_pu, together as large as J), at every Newton iteration, into matrices it keeps; from a MATNEST
it takes them as they are. The nest holds the Jacobian once instead of twice (docs/solvers.md, "Where the 2-rank
memory goes").

The blocks' forms come from the mixed Jacobian form itself (UFL differentiates the residual once, as for the
assembled matrix): with W = V x Q the mixed space and E_u(v) = (v, 0), E_p(q) = (0, q) its embeddings,

    J_ij(du_j; v_i) = J(E_j(du_j); E_i(v_i)),   i, j in {u, p},

the mixed test and trial functions replaced by the embedded ones of the collapsed spaces V and Q, and the
components that vanish removed before compilation (a component of a ListTensor taken by a fixed index is that
component, and a conditional whose two values are zero is zero: the terms multiplied by a zero component drop
out, so each kernel computes its own block only; in real arithmetic conj(x) = real(x) = x, so the Conj and Real
nodes go too, as FFCx removes them from a real form; a block whose arguments are still not its own is an error). The
coefficients (the state, fibres, loads) stay functions of W. Dirichlet conditions (on sub-spaces of W) act on the
blocks as on the assembled matrix: the constrained rows and columns zeroed, 1 on the diagonal of the diagonal
blocks (J_ij <- D_i J_ij D_j + (I - D_i) delta_ij, D the diagonal of the free dofs).
"""

from __future__ import annotations

import logging

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms import expand_derivatives
from ufl.algorithms.check_arities import ArityMismatch, check_form_arity
from ufl.algorithms.map_integrands import map_integrand_dags
from ufl.algorithms.remove_complex_nodes import remove_complex_nodes
from ufl.classes import FixedIndex, ListTensor, MultiIndex, Zero
from ufl.corealg.multifunction import MultiFunction

from model.problem.elasticity import ElasticityProblem
from model.solvers.linear import FIELDS, MixedFields

log = logging.getLogger(__name__)

__all__ = ["BlockError", "NestedJacobian", "block_forms", "nested_jacobian"]


class _FixedComponents(MultiFunction):
    """A ListTensor's component taken by fixed indices is that component (UFL's constructors then drop the terms a
    zero component multiplies)."""

    expr = MultiFunction.reuse_if_untouched

    def indexed(self, o: ufl.core.expr.Expr, operand: ufl.core.expr.Expr, indices: MultiIndex) -> ufl.core.expr.Expr:
        if isinstance(operand, ListTensor) and isinstance(indices.indices()[0], FixedIndex):
            return operand[indices]
        return self.reuse_if_untouched(o, operand, indices)

    def conditional(self, o: ufl.core.expr.Expr, condition: ufl.core.expr.Expr, true: ufl.core.expr.Expr,
                    false: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """conditional(c, 0, 0) = 0 (e.g. a contact penalty's derivative in a block without displacement)."""
        if isinstance(true, Zero) and isinstance(false, Zero):
            return true
        return self.reuse_if_untouched(o, condition, true, false)


class BlockError(ValueError):
    """A block of the mixed Jacobian whose form is not bilinear in its own test and trial functions after the
    simplification (a construct _FixedComponents does not reduce): the assembled matrix serves instead."""


def _embedding(argument: ufl.Argument, offset: int, size: int, total: int) -> ufl.core.expr.Expr:
    """The vector of ``total`` components holding ``argument``'s ``size`` components from ``offset``, zero elsewhere."""
    zero = Zero()
    if size == 1 and argument.ufl_shape == ():
        components = [argument]
    else:
        components = [argument[k] for k in range(size)]
    return ufl.as_vector([zero] * offset + components + [zero] * (total - offset - size))


def block_forms(problem: ElasticityProblem, spaces: list[fem.FunctionSpace]) -> list[list[ufl.Form]]:
    """The UFL forms J_ij of the mixed Jacobian's blocks on the collapsed spaces (module docstring); a block with no
    term (J_pp of a law without a bulk penalty) is the zero form 0 du_0 v_0 dx, which gives it the pattern of the
    cells' couplings (PCFieldSplit's Schur complement reads J_pp).

    In real arithmetic the Conj and Real nodes are removed before the arity check (conj(x) = real(x) = x: UFL's
    remove_complex_nodes, which FFCx applies to a real form before its own check). UFL differentiates
    inner(a, b) = a : conj(b) into da : conj(b) + a : conj(db), so a law written with inner(F, F) (the fibre laws'
    I1, I4 = |F a0|^2, C : C; stvk's E : E) leaves grad(du) : conj(F) + F : conj(grad(du)) in the Jacobian, which
    the check reads as the sum of a du and a conj(du) term, not linear in du, where it is 2 F : grad(du)."""
    jacobian = expand_derivatives(ufl.derivative(problem.residual_form, problem.solution,
                                                 ufl.TrialFunction(problem.space)))
    test, trial = sorted(jacobian.arguments(), key=lambda a: a.number())
    sizes = [_value_size(s) for s in spaces]
    offsets = [sum(sizes[:i]) for i in range(len(sizes))]
    total = sum(sizes)
    complex_mode = bool(np.iscomplexobj(PETSc.ScalarType(0)))
    out: list[list[ufl.Form]] = []
    for i, row_space in enumerate(spaces):
        row = []
        for j, column_space in enumerate(spaces):
            v = ufl.TestFunction(row_space)
            du = ufl.TrialFunction(column_space)
            mapping = {test: _embedding(v, offsets[i], sizes[i], total),
                       trial: _embedding(du, offsets[j], sizes[j], total)}
            form = expand_derivatives(ufl.replace(jacobian, mapping))
            form = map_integrand_dags(_FixedComponents(), form)
            if not complex_mode:
                form = remove_complex_nodes(form)
            try:
                check_form_arity(form, (v, du), complex_mode)
            except (ArityMismatch, ValueError) as err:  # UFL 2024.2 raises ValueError formatting its ArityMismatch
                raise BlockError(f"the Jacobian's block ({FIELDS[i]}, {FIELDS[j]}) is not bilinear in its own "
                                 f"arguments after simplification: {err}") from None
            if form.empty():  # e.g. J_pp of incompressible laws: a zero form, so that the block has a pattern
                zero = fem.Constant(problem.domain.mesh, PETSc.ScalarType(0.0))
                form = zero * _first(du) * _first(v) * problem.dx
            row.append(form)
        out.append(row)
    return out


def _first(argument: ufl.Argument) -> ufl.core.expr.Expr:
    """The first component of an argument (itself if scalar)."""
    return argument if argument.ufl_shape == () else argument[(0,) * len(argument.ufl_shape)]


def _value_size(space: fem.FunctionSpace) -> int:
    shape = ufl.TestFunction(space).ufl_shape
    return int(np.prod(shape)) if shape else 1


class NestedJacobian:
    """The blocks' compiled forms and matrices and the nest over them (``matrix``), in the block layout of a
    ``MixedFields(problem, nested=True)``: on each rank its owned u dofs (the collapsed space's order), then its
    owned p dofs. PCFieldSplit needs each field's rows sorted, which the mixed space's numbering does not give
    the u dofs (the collapsed space numbers them node by node, in another node order), so SNES works in the block
    layout: ``to_block`` / ``to_mixed`` permute a vector between it and the mixed space's (a permutation of each
    rank's owned entries, no communication)."""

    def __init__(self, problem: ElasticityProblem, fields: MixedFields) -> None:
        if not fields.nested:
            raise ValueError("NestedJacobian: the fields' index sets must be in the collapsed spaces' order "
                             "(MixedFields(problem, nested=True))")
        self.problem = problem
        spaces = [fields.spaces[name] for name in FIELDS]
        index_sets = [fields.index_sets[name] for name in FIELDS]
        self.forms = [[fem.form(f) for f in row] for row in block_forms(problem, spaces)]
        self.blocks = [[fem_petsc.create_matrix(f) for f in row] for row in self.forms]
        # no MatAssembly of the nest before the blocks hold values: it would squeeze their empty preallocation
        self.matrix = PETSc.Mat().createNest(self.blocks, isrows=index_sets, iscols=index_sets,
                                             comm=problem.domain.mesh.comm)
        # the Dirichlet conditions' dofs, once: no solver adds conditions to a problem after it is made
        self.free = [self._free(fields.spaces[name], fields.parents[name]) for name in FIELDS]
        #: the mixed space's local dof of each owned row of the block layout
        self.permutation = np.concatenate([
            fields.parents[name][:fields.spaces[name].dofmap.index_map.size_local
                                 * fields.spaces[name].dofmap.index_map_bs] for name in FIELDS])
        self.comm = problem.domain.mesh.comm

    def block_vector(self) -> PETSc.Vec:
        """A vector of the block layout (no ghosts)."""
        return PETSc.Vec().createMPI((len(self.permutation), PETSc.DECIDE), comm=self.comm)

    def to_block(self, mixed: PETSc.Vec, block: PETSc.Vec) -> None:
        """block <- the owned entries of ``mixed`` (the mixed space's layout) in the block layout."""
        block.array[:] = mixed.array_r[self.permutation]

    def to_mixed(self, block: PETSc.Vec, mixed: PETSc.Vec) -> None:
        """The owned entries of ``mixed`` <- ``block`` (ghosts not updated)."""
        mixed.array[self.permutation] = block.array_r

    def _free(self, space: fem.FunctionSpace, parent: np.ndarray) -> tuple[PETSc.Vec, PETSc.Vec] | None:
        """(D, I - D) of a field (1 / 0 on its free / constrained owned dofs), None when it has no constrained dof.
        The conditions are the problem's Dirichlet conditions on sub-spaces of the mixed space."""
        constrained = np.zeros(len(self.problem.solution.x.array), dtype=bool)
        for bc in self.problem.bcs:
            constrained[np.asarray(bc.dof_indices()[0], dtype=np.int64)] = True
        owned = space.dofmap.index_map.size_local * space.dofmap.index_map_bs
        mine = constrained[parent[:owned]]
        comm = space.mesh.comm
        if not comm.allreduce(bool(mine.any()), op=MPI.LOR):
            return None
        free = PETSc.Vec().createMPI((owned, PETSc.DECIDE), comm=comm)
        free.array[:] = np.where(mine, 0.0, 1.0)
        fixed = free.duplicate()
        fixed.array[:] = np.where(mine, 1.0, 0.0)
        return free, fixed

    def assemble(self) -> None:
        """Assemble every block at the current state, then the Dirichlet conditions: J_ij <- D_i J_ij D_j, and
        + (I - D_i) on the diagonal blocks (what the assembled matrix gets: rows and columns zeroed, 1 on the
        diagonal)."""
        for i, row in enumerate(self.blocks):
            for j, block in enumerate(row):
                block.zeroEntries()
                fem_petsc.assemble_matrix(block, self.forms[i][j])
                block.assemble()
                left = self.free[i][0] if self.free[i] is not None else None
                right = self.free[j][0] if self.free[j] is not None else None
                if left is not None or right is not None:
                    block.diagonalScale(left, right)
                if i == j and self.free[i] is not None:
                    block.setDiagonal(self.free[i][1], addv=PETSc.InsertMode.ADD_VALUES)
        self.matrix.assemble()

    def destroy(self) -> None:
        self.matrix.destroy()
        for row in self.blocks:
            for block in row:
                block.destroy()
        for pair in self.free:
            if pair is not None:
                for vector in pair:
                    vector.destroy()


def nested_jacobian(problem: ElasticityProblem) -> tuple[MixedFields, NestedJacobian] | None:
    """The fields (block layout) and the nested Jacobian of a mixed problem; None, with nothing left allocated,
    where a block's form cannot be separated (BlockError: the caller uses the assembled matrix)."""
    fields = MixedFields(problem, nested=True)
    try:
        return fields, NestedJacobian(problem, fields)
    except BlockError as err:
        fields.destroy()
        log.info("%s: the assembled matrix instead", err)
        return None
