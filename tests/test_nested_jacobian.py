"""[solver] matrix = "nest": the mixed (Taylor-Hood) Jacobian as one PETSc matrix per block (model.solvers.nested).

The blocks are the assembled Jacobian's, Dirichlet rows included; PCFieldSplit takes them as they are (no copies);
runs give the assembled matrix's answers; "nest" where it cannot serve is a ConfigError naming the key. Collective:
runs serially and under mpirun -n 2."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import example, run_raw
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from test_linear_presets import TIGHT, bar, quiet, relative_difference

from model.config import parse
from model.errors import ConfigError
from model.pipeline import build
from model.solvers import linear
from model.solvers.nested import NestedJacobian, block_forms
from model.solvers.newton import NewtonSolver

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _problem(raw: dict[str, Any]) -> Any:
    setup = build(parse(raw, EXAMPLES))
    return setup.problem


def _random_state(problem: Any, seed: int = 3) -> None:
    """A state off the rest (random u and p, the same on any partition: by dof coordinates), load factor 0.7."""
    problem.set_load_factor(0.7)

    def wave(x: np.ndarray, k: int) -> np.ndarray:
        return 1e-2 * np.sin(7.0 * x[0] + 3.0 * x[1] - 5.0 * x[2] + seed + k)

    problem.solution.sub(0).interpolate(lambda x: np.stack([wave(x, k) for k in range(3)]))
    problem.solution.sub(1).interpolate(lambda x: 1e2 * wave(x, 3))
    problem.solution.x.scatter_forward()
    problem.update_state()


NEO_HOOKEAN = {"law": "neo_hookean", "E": 1.0e4, "nu": 0.4999}
#: obstacles pressing on the bar's lower face z = 0 at rest (their penalties' conditionals in every block)
PLANE = {"surface": "zmin", "obstacle": "plane", "point": [0.0, 0.0, 0.004], "normal": [0.0, 0.0, 1.0],
         "method": "penalty", "penalty": 1.0e6}
CAPSULE = {"surface": "zmin", "obstacle": "capsule", "a": [0.0, 0.5, -0.2], "b": [2.0, 0.5, -0.2], "radius": 0.205,
           "method": "penalty", "penalty": 1.0e6}


@pytest.mark.parametrize(("law", "contact"), [
    (NEO_HOOKEAN, None),
    ({"law": "mooney_rivlin", "c1": 1.0e3, "c2": 5.0e2, "K": float("inf")}, None),
    (NEO_HOOKEAN, PLANE),
    (NEO_HOOKEAN, {**PLANE, "augmented": True}),
    (NEO_HOOKEAN, CAPSULE),
], ids=["nearly_incompressible", "incompressible", "penalty_plane", "augmented_plane", "penalty_capsule"])
def test_blocks_are_the_assembled_jacobian(law: dict[str, Any], contact: dict[str, Any] | None) -> None:
    """J_nest x = J x for random x (both in the mixed space's layout, through the block layout's permutation),
    at a state off the rest, with the clamped face's Dirichlet rows (identity rows and columns): to round-off.
    The incompressible law has no p-p term (J_pp = 0: a zero block with the cells' pattern); the obstacles'
    penalties put conditional(c, 0, 0) into the blocks without displacement, which must vanish there."""
    raw = bar(3, 0.4999)
    raw["material"] = [{"region": "all", **law}]
    if contact is not None:
        raw["contact"] = [contact]
    _assert_blocks_are_the_assembled_jacobian(_problem(raw))


def _assert_blocks_are_the_assembled_jacobian(problem: Any) -> None:
    """J_nest x = J x to 1e-13 relative at the state of _random_state, and the Dirichlet rows the identity."""
    _random_state(problem)
    _, jacobian = problem.forms
    assembled = fem_petsc.assemble_matrix(jacobian, bcs=problem.bcs)
    assembled.assemble()
    fields = linear.MixedFields(problem, nested=True)
    nested = NestedJacobian(problem, fields)
    nested.assemble()
    x = assembled.createVecRight()
    start = x.getOwnershipRange()[0]
    x.array[:] = np.cos(0.37 * np.arange(start, start + x.getLocalSize()))
    expected = assembled.createVecLeft()
    assembled.mult(x, expected)
    x_block, y_block = nested.block_vector(), nested.block_vector()
    nested.to_block(x, x_block)
    nested.matrix.mult(x_block, y_block)
    got = expected.duplicate()
    got.set(0.0)
    nested.to_mixed(y_block, got)
    got.axpy(-1.0, expected)
    assert got.norm() <= 1e-13 * expected.norm(), (got.norm(), expected.norm())
    # the Dirichlet rows: identity in the nest as in the assembled matrix
    constrained = np.concatenate([bc.dof_indices()[0] for bc in problem.bcs])
    owned = problem.space.dofmap.index_map.size_local * problem.space.dofmap.index_map_bs
    constrained = constrained[constrained < owned]
    assert MPI.COMM_WORLD.allreduce(len(constrained), op=MPI.SUM) > 0
    x.set(0.0)
    x.array[constrained] = 1.0
    nested.to_block(x, x_block)
    nested.matrix.mult(x_block, y_block)
    nested.to_mixed(y_block, got)
    assert np.all(got.array[constrained] == 1.0)
    for obj in (nested, fields, assembled, x, expected, got, x_block, y_block):
        obj.destroy()


#: fibres oblique to the bar's axes, so that F a0 mixes all of grad u's components
OBLIQUE = {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [2.0, 1.0, 0.5]}


@pytest.mark.parametrize("law", [
    {"law": "muscle", "isotropic": "stvk", "E": 9.0e6, "nu": 0.45, "sigma_max": 3.0e5, "fibres": OBLIQUE,
     "activation": [[0.0, 0.0], [1.0, 1.0]]},
    {"law": "tendon", "isotropic": "stvk", "E": 15.0e6, "nu": 0.45, "fibres": OBLIQUE},
    {"law": "muscle", "c1": 1.0e4, "c2": 2.0e3, "K": 1.0e6, "sigma_max": 3.0e5, "fibres": OBLIQUE},
    {"law": "stvk", "E": 1.0e4, "nu": 0.45},
    {"law": "stable_neo_hookean", "E": 1.0e4, "nu": 0.45},
], ids=["muscle_stvk_active", "tendon_stvk", "muscle_mooney_rivlin", "stvk", "stable_neo_hookean"])
def test_laws_with_inner_blocks_are_the_assembled_jacobian(law: dict[str, Any]) -> None:
    """Laws written with ufl.inner of F-dependent tensors: the fibre laws (forms.muscle: psi of the invariants
    I1 = F : F, I4 = |F a0|^2, C : C and of their piecewise fibre curves; activation 0.7, fibre stretches 0.94 to
    1.06, on both sides of the curves' break at 1), stvk (E : E), stable_neo_hookean, on a 4 x 2 x 2 bar:
    J_nest x = J x to 1e-13. UFL differentiates inner(a, a) = a : conj(a) into da : conj(a) + a : conj(da), which
    the arity check reads as not linear in the trial function unless the Conj nodes (the identity in real
    arithmetic) are removed first: before that, these laws' (u, u) blocks raised BlockError (UFL 2022.2 and
    2024.2)."""
    raw = bar(2, 0.45)
    raw["material"] = [{"region": "all", **law}]
    _assert_blocks_are_the_assembled_jacobian(_problem(raw))


def test_isometric_muscle_blocks_separate() -> None:
    """examples/isometric.toml (muscle belly and two tendons, Laplace fibres), meshed coarsely: each of the four
    blocks' forms is bilinear in its own test and trial functions (block_forms raises no BlockError), so
    matrix = "auto" with the iterative preset takes the nest (nested_jacobian is not None)."""
    raw = example("isometric")
    raw["mesh"]["size"] = 0.01
    problem = _problem(raw)
    fields = linear.MixedFields(problem, nested=True)
    try:
        forms = block_forms(problem, [fields.spaces[name] for name in linear.FIELDS])
    finally:
        fields.destroy()
    assert [[len(form.arguments()) for form in row] for row in forms] == [[2, 2], [2, 2]]
    assert all(not form.empty() for row in forms for form in row)


def test_fieldsplit_takes_the_blocks_as_they_are() -> None:
    """After a Newton solve with the iterative preset the fieldsplit's u and p solvers work on the nest's own
    diagonal blocks (the same PETSc objects: no copies), and the u block carries the near null space."""
    raw = quiet(bar(3, 0.3), "iterative", steps=1)
    problem = _problem(raw)
    choice = linear.resolve(problem, "iterative")
    solver = NewtonSolver(problem, {}, defaults=choice.options)
    try:
        assert solver.matrix == "nest"
        problem.set_load_factor(1.0)
        result = solver.solve()
        assert result.converged
        sub = solver.snes.getKSP().getPC().getFieldSplitSubKSP()
        blocks = solver.nested.blocks
        assert sub[0].getOperators()[0].handle == blocks[0][0].handle
        assert blocks[0][0].getNearNullSpace().handle != 0
    finally:
        solver.destroy()


def test_runs_agree_with_the_assembled_matrix(shared_tmp: Path) -> None:
    """The bar at nu = 0.4999 with the iterative preset, pressed on a plane (penalty): "auto" uses the nest, "aij"
    the assembled matrix; the reactions and the strain energy agree to 1e-8 (ksp_rtol 1e-12), and summary.json
    says which was used."""
    runs = {}
    for matrix in ("auto", "aij"):
        raw = quiet(bar(3, 0.4999), "iterative", TIGHT, steps=2)
        raw["contact"] = [PLANE]
        raw["solver"]["matrix"] = matrix
        runs[matrix] = run_raw(copy.deepcopy(raw), shared_tmp / matrix)
    nest, aij = runs["auto"], runs["aij"]
    assert nest["status"] == aij["status"] == "completed"
    assert nest["solver"]["matrix"] == "nest" and aij["solver"]["matrix"] == "aij"
    last_n, last_a = nest["steps"][-1], aij["steps"][-1]
    assert relative_difference(last_n["reactions"], last_a["reactions"]) < 1e-8
    assert abs(last_n["strain_energy"] - last_a["strain_energy"]) <= 1e-8 * abs(last_a["strain_energy"])
    direct = run_raw(quiet(bar(3, 0.4999), "direct", steps=1), shared_tmp / "direct")
    assert direct["solver"]["matrix"] == "aij"  # LU needs the assembled matrix


@pytest.mark.parametrize(("change", "message"), [
    ({"discretization": {"degree": 2, "quadrature_degree": 2, "formulation": "displacement"}},
     r'^solver\.matrix: "nest" needs the mixed formulation'),
    ({"solver": {"linear": "direct", "matrix": "nest"}},
     r"^solver\.matrix: \"nest\" needs a fieldsplit preconditioner \(the iterative preset\), not pc_type = 'lu'"),
])
def test_nest_where_it_cannot_serve_is_a_config_error(shared_tmp: Path, change: dict[str, Any], message: str,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Refused before any solve: the scale check's linear solve (the first solve of a run) never starts."""
    import model.solvers.scale as scale

    def no_solve(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the scale check's solve started")

    monkeypatch.setattr(scale, "linear_first_increment", no_solve)
    raw = quiet(bar(2, 0.3), "iterative", steps=1)
    raw["solver"]["matrix"] = "nest"
    raw.update(change)
    with pytest.raises(ConfigError, match=message):
        run_raw(raw, shared_tmp / "refused")
