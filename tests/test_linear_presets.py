"""[solver] linear: the direct (MUMPS) and iterative presets give the same answers; the Taylor-Hood block
preconditioner's iteration counts do not grow with the mesh or as nu -> 1/2; settings that cannot work are
ConfigErrors naming the key, before any solve. Collective: runs serially and under mpirun -n 2."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import example, run_raw
from mpi4py import MPI

from model.errors import ConfigError

#: tight linear tolerance, so that the two presets' Newton solutions agree far below 1e-8
TIGHT = {"ksp_rtol": 1e-12, "ksp_atol": 1e-50}


def quiet(raw: dict[str, Any], linear: str, options: dict[str, Any] | None = None, steps: int = 2) -> dict[str, Any]:
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    raw["loading"] = {"steps": steps}
    raw["solver"] = {"linear": linear, "petsc_options": dict(options or {})}
    return raw


def relative_difference(a: dict[str, list[float]], b: dict[str, list[float]]) -> float:
    """max over names of |a - b| (vectors) / the largest |b| (the scale: a support that carries no load in some
    direction has a reaction of rounding size there)."""
    assert a.keys() == b.keys()
    scale = max(float(np.linalg.norm(b[k])) for k in b)
    assert scale > 0
    return max(float(np.linalg.norm(np.subtract(a[k], b[k]))) for k in a) / scale


def both_presets(raw: dict[str, Any], out: Path, steps: int = 2) -> tuple[dict[str, Any], dict[str, Any]]:
    direct = run_raw(quiet(copy.deepcopy(raw), "direct", steps=steps), out / "direct")
    iterative = run_raw(quiet(copy.deepcopy(raw), "iterative", TIGHT, steps=steps), out / "iterative")
    return direct, iterative


def assert_same_answers(direct: dict[str, Any], iterative: dict[str, Any]) -> None:
    assert direct["status"] == iterative["status"] == "completed"
    last_d, last_i = direct["steps"][-1], iterative["steps"][-1]
    assert last_d["load_factor"] == last_i["load_factor"] == 1.0
    assert relative_difference(last_i["probes"], last_d["probes"]) < 1e-8
    assert relative_difference(last_i["reactions"], last_d["reactions"]) < 1e-8
    assert direct["solver"]["linear"] == "direct" and iterative["solver"]["linear"] == "iterative"
    assert direct["solver"]["petsc_options"]["pc_type"] == "lu"
    # the iterative preset did iterate, and every Newton iteration's count is recorded
    for step in iterative["steps"]:
        counts = step["linear_iterations_per_newton"]
        assert len(counts) == step["newton_iterations"]
        assert sum(counts) == step["linear_iterations"]
    assert max(max(s["linear_iterations_per_newton"]) for s in iterative["steps"]) > 1


def test_cook_taylor_hood(shared_tmp: Path) -> None:
    raw = example("cook")
    raw["mesh"]["cells"] = 4
    direct, iterative = both_presets(raw, shared_tmp)
    assert_same_answers(direct, iterative)
    options = iterative["solver"]["petsc_options"]
    assert options["pc_type"] == "fieldsplit" and options["pc_fieldsplit_type"] == "schur"
    assert options["ksp_rtol"] == 1e-12  # the user's option won over the preset's


def test_isometric_contraction(shared_tmp: Path) -> None:
    raw = example("isometric")
    raw["mesh"]["size"] = 0.03  # the coarsest the curvature sizing allows: 37621 dofs
    direct, iterative = both_presets(raw, shared_tmp, steps=1)
    assert_same_answers(direct, iterative)


def test_uniaxial_displacement_formulation(shared_tmp: Path) -> None:
    raw = example("uniaxial")
    raw["boundary"][-1]["value"] = [2.0e3, 5.0e2, 0.0]  # with a shear part: not a homogeneous deformation
    direct, iterative = both_presets(raw, shared_tmp)
    assert_same_answers(direct, iterative)
    assert iterative["solver"]["petsc_options"]["pc_type"] == "gamg"


def test_auto_is_direct_on_small_problems(shared_tmp: Path) -> None:
    summary = run_raw(quiet(example("uniaxial"), "auto", steps=1), shared_tmp)
    solver = summary["solver"]
    assert solver["linear_requested"] == "auto" and solver["linear"] == "direct"
    assert solver["dofs"] == summary["dofs"] < solver["auto_dofs"]
    # the threshold the key's documentation states is the one the solver uses
    from model.config.solver import NewtonSettings
    from model.solvers.linear import AUTO_DOFS

    assert solver["auto_dofs"] == AUTO_DOFS
    assert f"below {AUTO_DOFS} unknowns" in NewtonSettings.model_fields["linear"].description


def bar(n: int, nu: float) -> dict[str, Any]:
    """A 2 x 1 x 1 bar, clamped at x = 0, sheared at x = 2; Taylor-Hood P2/P1 neo-Hookean, 2n x n x n cells."""
    return {"mesh": {"generator": "box", "size": [2.0, 1.0, 1.0], "cells": [2 * n, n, n]},
            "discretization": {"degree": 2, "quadrature_degree": 2, "formulation": "mixed"},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": nu}],
            "boundary": [{"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]},
                         {"on": "xmax", "type": "traction", "value": [0.0, 100.0, 30.0]}]}


def mean_iterations(summary: dict[str, Any]) -> float:
    counts = [c for step in summary["steps"] for c in step["linear_iterations_per_newton"]]
    return float(np.mean(counts))


def test_taylor_hood_iterations_do_not_grow(shared_tmp: Path) -> None:
    """Linear iterations per Newton iteration (ksp_rtol 1e-8, the preset's) on bars of 6 x 3 x 3 and 12 x 6 x 6
    boxes (2 200 and 13 300 dofs): refining the mesh once (at nu 0.3 and at 0.4999) changes them by less than
    issue 10's 30 % serially and 45 % on 2 ranks (below); measured 1.15-1.26 in the file alone, up to 1.36 with
    the six rigid-body modes alone as the u block's near null space (docs/solvers.md, "The displacement block's
    near null space"). Going from nu 0.3 to 0.4999 on either mesh: less than issue 10's 30 % (the full Schur
    factorisation; the lower one grew by 18-30 % here and 33 % at 4.3e5 dofs, docs/solvers.md, "Scaling"). A
    preconditioner that lost its near null space or its Schur approximation would grow by far more."""
    counts = {}
    for n, nu in ((3, 0.3), (6, 0.3), (3, 0.4999), (6, 0.4999)):
        summary = run_raw(quiet(bar(n, nu), "iterative", steps=1), shared_tmp / f"{n}_{nu}")
        assert summary["status"] == "completed"
        counts[n, nu] = mean_iterations(summary)
    assert min(counts.values()) > 3, counts  # a real iteration, not a direct solve in disguise
    # On 2 ranks inside the whole suite the counts depend on what ran before in the process (CI, Debian 12:
    # 41.25 at (6, 0.3) where the file alone gives 32.5; not understood): there the bound is 45 %
    refinement = 1.30 if MPI.COMM_WORLD.size == 1 else 1.45
    for nu in (0.3, 0.4999):  # refinement
        a, b = (3, nu), (6, nu)
        assert max(counts[a], counts[b]) / min(counts[a], counts[b]) < refinement, (a, b, counts)
    for n in (3, 6):  # nu -> 1/2
        a, b = (n, 0.3), (n, 0.4999)
        assert max(counts[a], counts[b]) / min(counts[a], counts[b]) < 1.30, (a, b, counts)


@pytest.mark.parametrize(("options", "key"), [
    ({"fieldsplit_0_pc_type": "gamg"}, "solver.petsc_options.fieldsplit_0_pc_type"),
    ({"fieldsplit_displacement_ksp_type": "cg"}, "solver.petsc_options.fieldsplit_displacement_ksp_type"),
])
def test_fieldsplit_options_must_name_u_or_p(shared_tmp: Path, options: dict[str, Any], key: str) -> None:
    raw = quiet(example("cook"), "iterative", options)
    raw["mesh"]["cells"] = 2
    with pytest.raises(ConfigError, match=rf"^{key}: the fields of the mixed formulation are named u and p"):
        run_raw(raw, shared_tmp)
    assert not (shared_tmp / "summary.json").exists()


def test_schur_upper_solve_is_accepted_and_used(shared_tmp: Path) -> None:
    """PCFieldSplit's own prefix for the second u solve of the full factorisation, fieldsplit_p_upper_ (named after
    the Schur complement's split, p): the option check accepts it, PETSc creates the separate solver and reads its
    options (none left unused), and the run takes more iterations with Jacobi there than with the V-cycle the
    full factorisation otherwise applies twice (a weaker upper solve in effect)."""
    full = {"pc_fieldsplit_schur_fact_type": "full"}
    upper = {**full, "fieldsplit_p_upper_ksp_type": "preonly", "fieldsplit_p_upper_pc_type": "jacobi"}
    summaries = {}
    for name, options in (("full", full), ("upper", upper)):
        summary = run_raw(quiet(bar(2, 0.4999), "iterative", options, steps=1), shared_tmp / name)
        assert summary["status"] == "completed"
        assert "unused_petsc_options" not in summary, summary["unused_petsc_options"]
        assert {k: summary["solver"]["petsc_options"][k] for k in options} == options
        summaries[name] = summary
    assert sum(s["linear_iterations"] for s in summaries["upper"]["steps"]) > \
        sum(s["linear_iterations"] for s in summaries["full"]["steps"]), summaries


@pytest.mark.parametrize(("options", "message"), [
    ({"fieldsplit_u_upper_ksp_type": "preonly"}, r"PETSc names the Schur.*'s upper solve.*fieldsplit_p_upper_"),
    ({"fieldsplit_u_inner_pc_type": "jacobi"}, r"PETSc names the Schur.*'s inner solve.*fieldsplit_p_inner_"),
    ({"fieldsplit_x_upper_ksp_type": "preonly"}, r"the fields of the mixed formulation are named u and p.*not 'x'"),
])
def test_schur_sub_solvers_need_the_schur_split(shared_tmp: Path, options: dict[str, Any], message: str) -> None:
    """fieldsplit_u_upper_... PETSc never reads (it names the upper and inner solvers after the second split);
    a field that does not exist stays a ConfigError with the sub-solver prefixes too. Before any solve."""
    raw = quiet(bar(1, 0.3), "iterative", options, steps=1)
    key = next(iter(options))
    with pytest.raises(ConfigError, match=rf"^solver\.petsc_options\.{key}: {message}"):
        run_raw(raw, shared_tmp)
    assert not (shared_tmp / "summary.json").exists()


def test_fields_are_not_redefined(shared_tmp: Path) -> None:
    raw = quiet(example("cook"), "iterative", {"pc_fieldsplit_0_fields": "0,1,2"})
    raw["mesh"]["cells"] = 2
    with pytest.raises(ConfigError, match=r"^solver\.petsc_options\.pc_fieldsplit_0_fields: the solver defines"):
        run_raw(raw, shared_tmp)


def test_fieldsplit_needs_the_mixed_formulation(shared_tmp: Path) -> None:
    raw = quiet(example("uniaxial"), "iterative", {"pc_type": "fieldsplit"})
    with pytest.raises(ConfigError, match=r"^solver\.petsc_options\.pc_type: fieldsplit needs the mixed formulation"):
        run_raw(raw, shared_tmp)
    assert not (shared_tmp / "summary.json").exists()


def test_iterative_mixed_needs_a_shear_modulus(shared_tmp: Path) -> None:
    raw = quiet(bar(1, 0.3), "iterative")
    raw["material"] = [{"region": "all", "law": "volume", "kappa": 1.0e4}]
    with pytest.raises(ConfigError, match=r"^solver\.linear: \"iterative\" with the mixed formulation needs the "
                                          r"shear modulus.*material\[0\]"):
        run_raw(raw, shared_tmp)


def test_unknown_preset_is_a_config_error(shared_tmp: Path) -> None:
    with pytest.raises(ConfigError, match=r"^solver\.linear"):
        run_raw(quiet(example("uniaxial"), "fast"), shared_tmp)


def test_iterative_mixed_refuses_vi_contact() -> None:
    from model.config import parse
    from model.pipeline import build
    from model.solvers.linear import resolve

    raw = quiet(example("cook"), "iterative")
    raw["mesh"]["cells"] = 2
    problem = build(parse(raw, Path("examples"))).problem
    with pytest.raises(ConfigError, match=r"^solver\.linear: \"iterative\" with the mixed formulation cannot be used "
                                          r"with contact method \"vi\""):
        resolve(problem, "iterative", vi=True)
    assert resolve(problem, "auto", vi=True).preset == "direct"
    assert resolve(problem, "iterative").options["pc_type"] == "fieldsplit"


def _stiffness(space: Any, deviatoric: bool) -> Any:
    """int 2 dev(eps(u)) : dev(eps(v)) dx (or the same with + tr(eps(u)) tr(eps(v)): lambda = 1, compressible), no
    boundary conditions."""
    import ufl
    from dolfinx import fem
    from dolfinx.fem import petsc as fem_petsc

    u, v = ufl.TrialFunction(space), ufl.TestFunction(space)
    eps_u, eps_v = ufl.sym(ufl.grad(u)), ufl.sym(ufl.grad(v))
    form = 2.0 * ufl.inner(ufl.dev(eps_u), ufl.dev(eps_v))
    if not deviatoric:
        form = form + ufl.tr(eps_u) * ufl.tr(eps_v)
    matrix = fem_petsc.assemble_matrix(fem.form(form * ufl.dx(metadata={"quadrature_degree": 2})))
    matrix.assemble()
    return matrix


@pytest.mark.parametrize("degree", [1, 2])
def test_dilation_is_a_zero_energy_mode_of_the_deviatoric_stiffness(degree: int) -> None:
    """The u block's near null space (vector_rigid_body_modes(dilation=True)): seven orthonormal vectors, and each
    one, the dilation x - x_c included, has zero deviatoric energy: |K_dev m| <= 1e-12 |K_dev| (dev(eps(x)) = 0).
    With a bulk term (lambda = 1) the dilation is not a zero-energy mode, the rigid-body modes still are."""
    from dolfinx import mesh
    from mpi4py import MPI

    from model import compat
    from model.solvers.linear import vector_rigid_body_modes

    msh = mesh.create_box(MPI.COMM_WORLD, [[0.0, 0.0, 0.0], [2.0, 1.0, 1.0]], [4, 2, 3])
    space = compat.function_space(msh, "Lagrange", degree, shape=(3,))
    modes = vector_rigid_body_modes(space, dilation=True)
    assert len(modes) == 7
    gram = np.array([[a.dot(b) for b in modes] for a in modes])
    assert np.allclose(gram, np.eye(7), atol=1e-12)
    for deviatoric in (True, False):
        matrix = _stiffness(space, deviatoric)
        scale = matrix.norm()
        residuals = []
        for mode in modes:
            product = mode.duplicate()
            matrix.mult(mode, product)
            residuals.append(product.norm() / scale)
            product.destroy()
        matrix.destroy()
        assert max(residuals[:6]) < 1e-12, residuals
        if deviatoric:
            assert residuals[6] < 1e-12, residuals
        else:
            assert residuals[6] > 1e-4, residuals  # 2.8e-3 (P2), not rounding
    for mode in modes:
        mode.destroy()


def test_gmres_unless_an_inner_krylov_solve(shared_tmp: Path) -> None:
    """The mixed preset's outer method is GMRES, right preconditioned (the preconditioner is a fixed linear
    operator); an inner Krylov solve in the user's options (fieldsplit_u_ksp_type cg) makes it FGMRES, and a
    Krylov method of the user's own keeps no GMRES-only option."""
    from model.config import parse
    from model.pipeline import build
    from model.solvers.linear import resolve

    problem = build(parse(quiet(bar(2, 0.4999), "iterative"), Path("."))).problem
    plain = resolve(problem, "iterative").options
    assert plain["ksp_type"] == "gmres" and plain["ksp_pc_side"] == "right"
    inner = resolve(problem, "iterative", {"fieldsplit_u_ksp_type": "cg"}).options
    assert inner["ksp_type"] == "fgmres" and "ksp_pc_side" not in inner and inner["ksp_gmres_restart"] == 200
    assert resolve(problem, "iterative", {"fieldsplit_u_ksp_type": "preonly"}).options["ksp_type"] == "gmres"
    minres = resolve(problem, "iterative", {"ksp_type": "minres"}).options
    assert "ksp_pc_side" not in minres and "ksp_gmres_restart" not in minres
    chosen = resolve(problem, "iterative", {"ksp_type": "gmres", "fieldsplit_u_ksp_type": "cg"}).options
    assert chosen["ksp_type"] == "gmres"  # the user's own choice stands
