"""Every output works for every way the API adds an energy: laws, ElasticityProblem.add_energy, or both.

A problem whose energy is given by hand (add_energy(psi dx), no material) must report what the same
problem built from the law reports: solution, total_energy(), region volumes, reactions, and the
written fields (J, Cauchy and von Mises stress from P = dpsi/dF of the added cell integral). Before
the fix, total_energy() failed in pack_constants() (the energy form was the integer 0) and
ResultWriter.write_step with "'int' object has no attribute 'function_spaces'".
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import ufl
from conftest import EXAMPLES, example, run_raw
from mpi4py import MPI

import forms
import meshes
from model.config import parse
from model.domain import Probes, build_domain
from model.errors import ConfigError
from model.output.writer import CellAverages, ResultWriter
from model.problem import ElasticityProblem
from model.problem.measurements import Volumes, reactions
from model.solvers import NewtonSolver, step_loads

comm = MPI.COMM_WORLD
NEO_HOOKEAN = {"mu": 1.0e3, "lmbda": 2.0e3}
FIBRE = (1.0, 0.0, 0.0)


def box_domain(size: tuple[float, float, float] = (1.0, 1.0, 1.0), cells: tuple[int, int, int] = (2, 2, 2)):
    data = meshes.box(size=size, cells=cells) if comm.rank == 0 else None
    return build_domain(comm, data)


def load_cube(problem: ElasticityProblem) -> None:
    problem.add_dirichlet("xmin", [0, 1, 2], [0.0, 0.0, 0.0])
    problem.add_traction("xmax", [300.0, 80.0, -120.0])


def outputs(problem: ElasticityProblem, directory: Path, steps: int = 2) -> dict:
    """Solve, then every output: energy, volumes, reactions, cell averages, and the files of ResultWriter."""
    solver = NewtonSolver(problem)
    assert step_loads(solver, steps)
    residual = solver.unconstrained_residual()
    out = {"solution": problem.solution.x.array.copy(), "energy": problem.total_energy(),
           "volumes": Volumes(problem).current(), "reactions": reactions(problem, residual)}
    residual.destroy()
    out.update({name: f.x.array.copy() for name, f in CellAverages(problem).update().items()})
    writer = ResultWriter(problem, directory, xdmf=True, vtu=True, png=True)
    writer.write_step(1.0)
    png = writer.write_png("by hand")
    writer.close()
    if comm.rank == 0:
        assert (directory / "results.xdmf").is_file() and (directory / "step_0001.vtu").is_file()
        assert png is None or png.is_file()
    solver.destroy()
    return out


def assert_same(a: dict, b: dict, rtol: float = 1e-9) -> None:
    for key in ("solution", "J", "cauchy_stress", "von_mises"):
        scale = max(float(np.abs(a[key]).max(initial=0.0)), 1e-300)
        error = float(np.abs(a[key] - b[key]).max(initial=0.0)) / scale
        assert comm.allreduce(error, op=MPI.MAX) < rtol, f"{key}: relative difference {error:.2e}"
    assert b["energy"] == pytest.approx(a["energy"], rel=rtol)
    assert b["volumes"] == pytest.approx(a["volumes"], rel=rtol)
    for name in a["reactions"]:
        np.testing.assert_allclose(b["reactions"][name], a["reactions"][name], rtol=rtol,
                                   atol=rtol * np.abs(a["reactions"][name]).max())


def test_no_energy_at_all_reports_zero(shared_tmp: Path) -> None:
    """No material and nothing added: energy 0, J = 1 and zero stress written (the forms were the integer 0)."""
    problem = ElasticityProblem(box_domain(cells=(1, 1, 1)), [], 1, 2)
    assert problem.total_energy() == 0.0
    fields = CellAverages(problem).update()
    np.testing.assert_allclose(fields["J"].x.array, 1.0, rtol=1e-12)
    assert not np.any(fields["cauchy_stress"].x.array) and not np.any(fields["von_mises"].x.array)
    writer = ResultWriter(problem, shared_tmp, xdmf=True, vtu=True, png=False)
    writer.write_step(0.0)
    writer.close()
    assert Volumes(problem).current()["all"] == pytest.approx(1.0, rel=1e-12)


def test_add_energy_alone_reports_what_the_law_reports(shared_tmp: Path) -> None:
    """neo-Hookean as a law, and as add_energy(psi dx) on a problem with no material: identical outputs."""
    law = forms.make_law("neo_hookean", **NEO_HOOKEAN)
    reference = ElasticityProblem(box_domain(), [("all", law)], 1, 2)
    load_cube(reference)
    expected = outputs(reference, shared_tmp / "law")
    by_hand = ElasticityProblem(box_domain(), [], 1, 2)
    by_hand.add_energy(law.energy(by_hand.F) * by_hand.dx)
    load_cube(by_hand)
    assert len(by_hand.stress_terms) == 1  # P = dpsi/dF of the added cell integral
    got = outputs(by_hand, shared_tmp / "by_hand")
    assert expected["energy"] > 0
    assert_same(expected, got)


def test_law_plus_added_energy_is_one_stress(shared_tmp: Path) -> None:
    """neo-Hookean is linear in (mu, lmbda): a law (mu1, l1) plus add_energy of (mu2, l2) on the same cells is
    the law (mu1 + mu2, l1 + l2): same solution and energy, and one stress (von Mises of the sum)."""
    first, second = {"mu": 600.0, "lmbda": 500.0}, {"mu": 400.0, "lmbda": 1500.0}
    summed = {k: first[k] + second[k] for k in first}
    reference = ElasticityProblem(box_domain(), [("all", forms.make_law("neo_hookean", **summed))], 1, 2)
    load_cube(reference)
    expected = outputs(reference, shared_tmp / "law")
    mixed = ElasticityProblem(box_domain(), [("all", forms.make_law("neo_hookean", **first))], 1, 2)
    mixed.add_energy(forms.make_law("neo_hookean", **second).energy(mixed.F) * mixed.dx)
    load_cube(mixed)
    assert len(mixed.stress_terms) == 2 and len(mixed.von_mises_terms()) == 1
    assert_same(expected, outputs(mixed, shared_tmp / "law_plus_energy"))


def test_surface_energy_counts_in_the_energy_but_not_in_the_stress() -> None:
    """An added energy on a boundary (a spring holding xmax, like a contact penalty) adds no stress term; it
    counts in total_energy()."""
    k = 5.0e2
    problem = ElasticityProblem(box_domain(), [("all", forms.make_law("neo_hookean", **NEO_HOOKEAN))], 1, 2)
    u = problem.u
    spring = 0.5 * k * ufl.inner(u, u) * problem.boundary_measure("xmax")
    problem.add_energy(spring)
    load_cube(problem)
    assert len(problem.stress_terms) == 1
    solver = NewtonSolver(problem)
    assert step_loads(solver, 2)
    from dolfinx import fem

    def integral(form: ufl.Form) -> float:
        return comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)

    material = integral(forms.make_law("neo_hookean", **NEO_HOOKEAN).energy(problem.F) * problem.dx)
    assert integral(spring) > 0.01 * material
    assert problem.total_energy() == pytest.approx(material + integral(spring), rel=1e-12)
    solver.destroy()


def guccione_beam(by_hand: bool, cells: tuple[int, int, int] = (5, 1, 1)) -> ElasticityProblem:
    """The beam of Land et al. 2015 problem 1 (coarse), incompressible Guccione, mixed P2/P1: from the user
    law, or by hand as an expert user writes it: add_energy((W + p (J - 1)) dx) on a problem with no material."""
    domain = box_domain((10.0, 1.0, 1.0), cells)
    entry = forms.resolve_law("guccione_law.py:psi", base=EXAMPLES)
    a0 = ufl.as_vector(FIBRE)
    if by_hand:
        problem = ElasticityProblem(domain, [], 2, 4, "mixed")
        W = entry.law.function(problem.F, C=2.0, bf=8.0, bt=2.0, bfs=4.0, a0=a0)
        problem.add_energy((W + problem.p * (ufl.det(problem.F) - 1.0)) * problem.dx)
    else:
        law = entry.make(C=2.0, bf=8.0, bt=2.0, bfs=4.0, kappa=math.inf, a0=a0)
        problem = ElasticityProblem(domain, [("all", law)], 2, 4, "mixed")
    problem.add_dirichlet("xmin", [0, 1, 2], [0.0, 0.0, 0.0])
    problem.add_pressure("zmin", 0.004)
    return problem


def test_guccione_beam_by_hand_matches_the_user_law(shared_tmp: Path) -> None:
    """The expert user's Guccione beam built with add_energy: total_energy(), Volumes, reactions and ResultWriter
    work, and every output equals the user law's (kappa = inf) on the same mesh."""
    law = guccione_beam(by_hand=False)
    expected = outputs(law, shared_tmp / "law", steps=2)
    hand = guccione_beam(by_hand=True)
    got = outputs(hand, shared_tmp / "by_hand", steps=2)
    assert_same(expected, got, rtol=1e-8)
    tip = Probes(hand.domain.mesh, {"tip": [10.0, 0.5, 1.0]}).evaluate(hand.displacement())["tip"]
    assert tip[2] > 2.0  # the beam bends upwards (coarse mesh: about 3 mm)
    volume = Volumes(hand)
    assert volume.current()["all"] == pytest.approx(volume.reference["all"], rel=1e-9)  # int (J - 1) q dx = 0, q = 1


# --- a law of the user's own from the configuration file: law = "FILE.py:FUNCTION" -------------------------------

def test_guccione_beam_example_runs_the_user_law(shared_tmp: Path) -> None:
    """examples/guccione_beam.toml (law = "guccione_law.py:psi", kappa = inf, mixed) on a coarse mesh: the tip
    rises as in Land et al. 2015 problem 1 (z = 4.17 mm converged; 3.1 mm of displacement on this mesh) and the
    volume is kept exactly."""
    raw = example("guccione_beam")
    raw["mesh"]["cells"] = [10, 1, 1]
    raw["loading"]["steps"] = 2
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp / "guccione")
    assert summary["status"] == "completed"
    tip = summary["steps"][-1]["probes"]["tip"]
    assert 2.5e-3 < tip[2] < 3.3e-3, tip
    volume = summary["steps"][-1]["volumes"]["all"]
    assert volume == pytest.approx(1.0e-8, rel=1e-8)


@pytest.mark.parametrize(("change", "key", "fragment"), [
    ({"law": "nowhere.py:psi"}, "material[0].law", "no such file"),
    ({"law": "guccione_law.py:phi"}, "material[0].law", "no function 'phi'"),
    ({"law": "guccione"}, "material[0].law", "FILE.py:FUNCTION"),
    ({"C": -1.0}, "material[0].C", "C"),
    ({"stiffness": 1.0}, "material[0].stiffness", "unknown parameter"),
])
def test_user_law_errors_name_the_key(change: dict, key: str, fragment: str) -> None:
    raw = example("guccione_beam")
    raw["material"][0].update(change)
    with pytest.raises(ConfigError) as err:
        parse(raw, EXAMPLES)
    message = str(err.value)
    assert message.startswith(f"{key}: ") and fragment in message and "\n" not in message, message


@pytest.mark.parametrize(("formulation", "kappa", "fragment"), [
    ("displacement", math.inf, "needs discretization.formulation = \"mixed\""),
    ("mixed", 0.0, "needs a volumetric term"),
])
def test_bulk_parameter_must_suit_the_formulation(formulation: str, kappa: float, fragment: str) -> None:
    """kappa = inf without a pressure, or kappa = 0 with one, is refused before any mesh is built."""
    raw = example("guccione_beam")
    raw["discretization"].update(formulation=formulation, degree=2)
    raw["material"][0]["kappa"] = kappa
    with pytest.raises(ConfigError) as err:
        parse(raw, EXAMPLES)
    assert str(err.value).startswith("material[0].kappa: ") and fragment in str(err.value), str(err.value)
