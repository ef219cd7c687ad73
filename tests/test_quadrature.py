"""quadrature_degree = "auto": at P1 the materials' terms with one point, equal to four points to round-off.

For degree-1 displacements F = I + grad u is constant per cell and the fields (a0, alpha, S) are per
cell, so every material integrand is constant per cell: the one-point rule of "auto" and the earlier
default (degree 2, four points) integrate it exactly. Every law on a small deformed box, with a
traction and a body force given by an expression of x (both kept at degree 2 by "auto"): the stored
energy, the residual vector and the Jacobian matrix of the two rules agree to 1e-12 relative.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

import forms
import meshes
from model import compat
from model.domain import build_domain
from model.problem import ElasticityProblem
from model.problem.elasticity import quadrature_degrees

E, NU = 1.0e4, 0.3
MU, BULK = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
PARAMETERS: dict[str, dict[str, Any]] = {
    "stvk": {"E": E, "nu": NU}, "neo_hookean": {"E": E, "nu": NU}, "corotated": {"E": E, "nu": NU},
    "mooney_rivlin": {"c1": MU / 4, "c2": MU / 4, "K": BULK / 2},
    "shape_target": {"mu": MU, "kappa": BULK}, "volume": {"kappa": BULK},
    "muscle": {"c1": MU / 4, "c2": MU / 8, "K": BULK / 2, "sigma_max": 2e3},
    "tendon": {"c1": MU / 4, "K": BULK / 2, "L1": 1e3, "L2": 20.0},
    "fixed_corotated": {"E": E, "nu": NU}, "arap": {"mu": MU},
    "stable_neo_hookean": {"E": E, "nu": NU, "variant": "paper"},
    "yeoh": {"c1": MU / 2, "c2": -MU / 20, "c3": MU / 50, "kappa": BULK},
    "ogden": {"c1": MU, "m1": 4.0, "c2": MU / 5, "m2": -2.0, "kappa": BULK},
    "holzapfel_ogden": {}, "trans_iso_mooney_rivlin": {}, "blemker": {},  # their defaults
}


def deformed(x: np.ndarray) -> np.ndarray:
    """A twist, stretch and bend of the unit cube (lbar spans several pieces of the fibre curves)."""
    angle = 0.5 * x[0]
    y, z = x[1] - 0.5, x[2] - 0.5
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([0.15 * x[0] + 0.05 * np.sin(np.pi * x[1]) * x[2], c * y - s * z - y + 0.05 * x[0] ** 2,
                     s * y + c * z - z])


def fields(domain: Any, name: str) -> dict[str, fem.Function]:
    """Per-cell a0 (tilted differently in each cell), s0, alpha and S, as the pipeline's DG0 fields."""
    msh = domain.mesh
    n = msh.topology.index_map(3).size_local + msh.topology.index_map(3).num_ghosts
    mid = msh.geometry.x[compat.geometry_dofs(msh)[:n]].mean(axis=1)
    out = {}
    if "a0" in forms.REGISTRY[name].fields:
        a0 = np.stack([np.ones(n), 0.4 * np.sin(3 * mid[:, 1]), 0.3 * np.cos(2 * mid[:, 2])], axis=1)
        out["a0"] = fem.Function(compat.function_space(msh, "DG", 0, (3,)))
        out["a0"].x.array[: 3 * n] = (a0 / np.linalg.norm(a0, axis=1)[:, None]).reshape(-1)
        if "s0" in forms.REGISTRY[name].fields:  # a sheet direction orthogonal to a0
            s0 = np.cross(a0, [0.0, 0.0, 1.0])
            out["s0"] = fem.Function(compat.function_space(msh, "DG", 0, (3,)))
            out["s0"].x.array[: 3 * n] = (s0 / np.linalg.norm(s0, axis=1)[:, None]).reshape(-1)
    if "alpha" in forms.REGISTRY[name].fields:
        out["alpha"] = fem.Function(compat.function_space(msh, "DG", 0))
        out["alpha"].x.array[:n] = 0.5 + 0.5 * np.sin(5 * mid[:, 0])
    if "S" in forms.REGISTRY[name].fields:
        eig = 1.0 + 0.2 * np.sin(4 * mid)
        out["S"] = fem.Function(compat.function_space(msh, "DG", 0, (3, 3)))
        out["S"].x.array[: 9 * n] = (eig[:, :, None] * np.eye(3)).reshape(-1)
    return out


def assembled(domain: Any, name: str, quadrature_degree: int | str) -> tuple[ElasticityProblem, float, np.ndarray,
                                                                               PETSc.Mat]:
    law = forms.make_law(name, **PARAMETERS[name], **fields(domain, name))
    problem = ElasticityProblem(domain, [("all", law)], 1, quadrature_degree)
    x = ufl.SpatialCoordinate(domain.mesh)
    problem.add_traction("xmax", [100.0, 20.0, 0.0])
    problem.add_body_force("all", ufl.as_vector([0.0, 50.0 * x[0] ** 2, 30.0 * x[1] * x[2]]))
    problem.set_load_factor(1.0)
    problem.solution.interpolate(deformed)
    problem.solution.x.scatter_forward()
    problem.update_state()
    residual, jacobian = problem.forms
    b = fem_petsc.assemble_vector(residual)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    A = fem_petsc.assemble_matrix(jacobian)
    A.assemble()
    energy = domain.mesh.comm.allreduce(fem.assemble_scalar(fem.form(problem.material_energy)), op=MPI.SUM)
    values = b.array.copy()
    b.destroy()
    return problem, energy, values, A


@pytest.fixture(scope="module")
def domain() -> Any:
    comm = MPI.COMM_WORLD
    return build_domain(comm, meshes.box((1.0, 1.0, 1.0), (3, 3, 3)) if comm.rank == 0 else None)


def test_auto_degrees() -> None:
    assert quadrature_degrees(1) == (2, 1)
    assert quadrature_degrees(2) == (4, 4)
    assert quadrature_degrees(1, 3) == (3, 3)
    with pytest.raises(ValueError, match="quadrature_degree"):
        quadrature_degrees(1, 0)


@pytest.mark.parametrize("name", list(forms.REGISTRY))
def test_one_point_equals_four_points_at_p1(domain: Any, name: str) -> None:
    one, energy1, b1, A1 = assembled(domain, name, "auto")
    four, energy4, b4, A4 = assembled(domain, name, 2)
    assert (one.energy_quadrature_degree, one.quadrature_degree) == (1, 2)
    assert four.energy_quadrature_degree == 2
    comm = domain.mesh.comm
    assert abs(energy1 - energy4) <= 1e-12 * abs(energy4) and abs(energy4) > 0
    norm = np.sqrt(comm.allreduce(float(b4 @ b4), op=MPI.SUM))
    difference = np.sqrt(comm.allreduce(float((b1 - b4) @ (b1 - b4)), op=MPI.SUM))
    assert difference <= 1e-12 * norm and norm > 0
    A1.axpy(-1.0, A4)
    assert A1.norm(PETSc.NormType.FROBENIUS) <= 1e-12 * A4.norm(PETSc.NormType.FROBENIUS)
    A1.destroy()
    A4.destroy()


@pytest.mark.parametrize("cell", ["triangle", "tetrahedron"])
def test_vertex_rule_is_exact_for_p1_and_quiet(cell: str, caplog: pytest.LogCaptureFixture) -> None:
    """forms.quadrature.vertex_rule: int (1 + 2x - 3y (+ z)) over the unit square / cube is its P1 interpolant's
    integral, the closed form 1 - 1/2 (+ 1/2) to 1e-14, on the cells (dx) and on the cube's facets (ds, the
    triangle rule: int over the boundary of 1 + x = 6 + 3 = 9); and UFL logs no warning for the rule's metadata
    (numpy arrays made it warn "Applying str() to a metadata value of type ndarray" for every form)."""
    from forms.quadrature import vertex_rule

    comm = MPI.COMM_WORLD
    if cell == "triangle":
        msh = dmesh.create_unit_square(comm, 3, 4)
        x = ufl.SpatialCoordinate(msh)
        integrand, exact = 1 + 2 * x[0] - 3 * x[1], 1.0 + 1.0 - 1.5
    else:
        msh = dmesh.create_unit_cube(comm, 2, 3, 2)
        x = ufl.SpatialCoordinate(msh)
        integrand, exact = 1 + 2 * x[0] - 3 * x[1] + x[2], 1.0 + 1.0 - 1.5 + 0.5
    with caplog.at_level(logging.WARNING, logger="UFL"):
        value = fem.assemble_scalar(fem.form(integrand * ufl.dx(domain=msh, metadata=vertex_rule(cell))))
        assert abs(comm.allreduce(value, op=MPI.SUM) - exact) < 1e-14
        if cell == "tetrahedron":
            boundary = fem.assemble_scalar(fem.form((1 + x[0]) * ufl.ds(domain=msh,
                                                                       metadata=vertex_rule("triangle"))))
            assert abs(comm.allreduce(boundary, op=MPI.SUM) - 9.0) < 1e-13
    assert not [r for r in caplog.records if "metadata" in r.getMessage()], caplog.records
    with pytest.raises(ValueError, match="vertex_rule: cell must be one of"):
        vertex_rule("hexahedron")
