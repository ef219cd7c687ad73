"""Shape targeting in the model: targets reached, per-cell order, procedural targets, SPD checks, exact tangent."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import example, run_raw
from mpi4py import MPI
from test_jacobian import residual

import forms
import meshes
from model import compat
from model.config import parse
from model.domain import build_domain
from model.errors import ConfigError
from model.fields.targets import TargetField
from model.pipeline import build
from model.problem import ElasticityProblem

TARGET = [[1.2, 0.0, 0.0], [0.0, 0.9, 0.0], [0.0, 0.0, 1.05]]


def free_cube(material: dict) -> dict:
    """The unit cube on three symmetry planes, no load: it takes the shape its targets ask for."""
    raw = example("uniaxial")
    raw["material"] = [{"region": "all", "law": "shape_target", "mu": 1.0e4, **material}]
    raw["boundary"] = raw["boundary"][:3]
    raw["loading"] = {"steps": 2}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    return raw


@pytest.mark.parametrize("kappa", [0.0, 1.0e5])
def test_compatible_target_is_reached_exactly(kappa: float, shared_tmp) -> None:
    summary = run_raw(free_cube({"kappa": kappa, "S": TARGET}), shared_tmp)
    for step in summary["steps"]:
        np.testing.assert_allclose(step["probes"]["corner"], np.diag(TARGET) - 1.0, atol=1e-12)
        assert abs(step["strain_energy"]) < 1e-16 * 1.0e4
        for force in step["reactions"].values():
            np.testing.assert_allclose(force, 0.0, atol=1e-8)


def target_function(x: np.ndarray, t: float) -> np.ndarray:
    """diag(1 + 0.25 t, 1 - 0.1 t, 1): homogeneous, changing with the load factor."""
    S = np.zeros((len(x), 3, 3))
    S[:, 0, 0], S[:, 1, 1], S[:, 2, 2] = 1 + 0.25 * t, 1 - 0.1 * t, 1.0
    return S


def test_procedural_target_follows_the_load_factor(shared_tmp) -> None:
    path = Path(__file__).resolve()
    raw = free_cube({"kappa": 1.0e5, "S_function": f"{path}:target_function"})
    raw["loading"] = {"steps": 4}
    summary = run_raw(raw, shared_tmp)
    for step in summary["steps"]:
        t = step["load_factor"]
        np.testing.assert_allclose(step["probes"]["corner"], [0.25 * t, -0.1 * t, 0.0], atol=1e-12)


def test_per_cell_targets_follow_mesh_cell_order(shared_tmp) -> None:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(1.0, 1.0, 1.0), cells=(3, 3, 3))
    centroids = data.points[data.cells].mean(axis=1)
    array = np.zeros((len(data.cells), 3, 3))
    array[:, 0, 0] = 1 + centroids[:, 0]
    array[:, 1, 1] = 2 + centroids[:, 1]
    array[:, 2, 2] = 3 + centroids[:, 2]
    path = shared_tmp / "targets.npy"
    if comm.rank == 0:
        np.save(path, array)
    comm.barrier()
    raw = free_cube({"S_file": str(path)})
    raw["mesh"]["cells"] = [3, 3, 3]
    setup = build(parse(raw))
    target = setup.targets[0]
    from dolfinx import mesh as dmesh

    mid = dmesh.compute_midpoints(setup.domain.mesh, 3, target.cells)
    dofs = compat.cell_dofs(target.function.function_space.dofmap).reshape(-1)
    values = target.function.x.array.reshape(-1, 9)[dofs[target.cells]]
    np.testing.assert_allclose(values[:, 0], 1 + mid[:, 0], atol=1e-12)
    np.testing.assert_allclose(values[:, 4], 2 + mid[:, 1], atol=1e-12)
    np.testing.assert_allclose(values[:, 8], 3 + mid[:, 2], atol=1e-12)


def not_spd(x: np.ndarray, t: float) -> np.ndarray:
    S = np.broadcast_to(np.eye(3), (len(x), 3, 3)).copy()
    S[:, 2, 2] = -0.5
    return S


@pytest.mark.parametrize("entry,key,message", [
    ({"S": [[1, 0, 0], [0, -1, 0], [0, 0, 1]]}, "material[0].S", "not positive definite"),
    ({"S": [[1, 0.3, 0], [0, 1, 0], [0, 0, 1]]}, "material[0].S", "not symmetric"),
    ({"S": [[1, 0, 0], [0, 1, 0]]}, "material[0].S", "3x3"),
    ({"S": TARGET, "S_file": "x.npy"}, "material[0].S_file", "only one"),
    ({"S_function": "nowhere.py:f"}, "material[0].S_function", "no such file"),
])
def test_bad_targets_are_rejected_at_parse(entry: dict, key: str, message: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse(free_cube(entry))
    assert str(err.value).startswith(f"{key}: ") and message in str(err.value), str(err.value)


def test_bad_targets_are_rejected_before_the_solve(shared_tmp) -> None:
    comm = MPI.COMM_WORLD
    path = shared_tmp / "bad.npy"
    if comm.rank == 0:
        bad = np.broadcast_to(np.eye(3), (384, 3, 3)).copy()
        bad[17, 1, 1] = 0.0
        np.save(path, bad)
    comm.barrier()
    with pytest.raises(ConfigError, match=r"^material\[0\]\.S_file: .*target 17 is not positive definite"):
        parse(free_cube({"S_file": str(path)}))
    comm.barrier()  # every rank has read the file before rank 0 rewrites it
    if comm.rank == 0:
        np.save(path, np.broadcast_to(np.eye(3), (10, 3, 3)))
    comm.barrier()
    with pytest.raises(ConfigError, match=r"^material\[0\]\.S_file: .*\(384, 3, 3\)"):
        build(parse(free_cube({"S_file": str(path)})))
    with pytest.raises(ConfigError, match=r"^material\[0\]\.S_function: .*not positive definite"):
        build(parse(free_cube({"S_function": f"{Path(__file__).resolve()}:not_spd"})))


@pytest.mark.parametrize("inverted", [False, True])
def test_incompatible_targets_jacobian_matches_finite_differences(inverted: bool) -> None:
    comm = MPI.COMM_WORLD
    data = meshes.box(size=(1.0, 1.0, 1.0), cells=(3, 3, 3)) if comm.rank == 0 else None
    domain = build_domain(comm, data)
    cells = domain.region_cells("all")

    def targets(x: np.ndarray, t: float) -> np.ndarray:
        a = 0.4 * np.sin(3 * x[:, 0]) + 1.0
        b = 0.3 * np.cos(2 * x[:, 2]) + 0.9
        S = np.zeros((len(x), 3, 3))
        S[:, 0, 0], S[:, 1, 1], S[:, 2, 2] = a, b, 1.0 / (a * b)
        S[:, 0, 1] = S[:, 1, 0] = 0.2 * x[:, 1]
        return S

    target = TargetField(domain.mesh, cells, targets)
    law = forms.make_law("shape_target", mu=3.0, kappa=20.0, S=target.function)
    problem = ElasticityProblem(domain, [("all", law)], 1, 2)
    problem.add_traction("xmax", [1.0, 0.5, -0.3])
    problem.set_load_factor(1.0)
    flip = -1.6 if inverted else 0.0  # u_z = flip * z inverts every cell (det F < 0) when flip < -1
    problem.solution.interpolate(lambda x: np.array([0.2 * x[1] * x[2] + 0.1 * x[0] ** 2,
                                                     -0.15 * x[0] * x[2] + 0.2 * np.sin(x[1]),
                                                     0.25 * x[0] * x[1] + flip * x[2]]))
    from dolfinx.fem import petsc as fem_petsc

    problem.update_state()
    A = fem_petsc.assemble_matrix(problem.forms[1])
    A.assemble()
    rng = np.random.default_rng(11 + comm.rank)
    direction = compat.petsc_vector(problem.solution).copy()
    owned = problem.space.dofmap.index_map.size_local * 3
    direction.array[:] = rng.uniform(-1, 1, owned)
    tangent = A.createVecLeft()
    A.mult(direction, tangent)
    from petsc4py import PETSc

    direction.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with direction.localForm() as d_local:
        d = d_local.array.copy()
    x0 = problem.solution.x.array.copy()
    h = 1e-6
    problem.solution.x.array[:] = x0 + h * d
    r_plus = residual(problem)
    problem.solution.x.array[:] = x0 - h * d
    r_minus = residual(problem)
    fd = (r_plus - r_minus) / (2 * h)
    error = comm.allreduce(np.abs(fd - tangent.array).max(), op=MPI.MAX)
    scale = comm.allreduce(np.abs(tangent.array).max(), op=MPI.MAX)
    assert error / scale < 1e-7, f"relative FD mismatch {error / scale:.2e}"
