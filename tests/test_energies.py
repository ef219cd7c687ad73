"""The energies of summary.json, each what its name says (ElasticityProblem.energies).

- Homogeneous uniaxial traction of a neo-Hookean unit cube: the stretches solve the 1D equilibrium
  P11(l1, l2) = t, P22(l1, l2) = 0 (numpy/scipy, independent of UFL); then strain_energy = W(F) V,
  load_potential = -t u_x A (u_x = l1 - 1 on the loaded face, A = 1), total_potential their sum.
- Isometric contraction (examples/isometric.toml, coarse): active_energy is the fibre activation's term
  int sigma_max alpha (Fa(lbar / l_ofl) - Fa(1 / l_ofl)) dx (assembled here from forms.muscle's
  antiderivative), negative because the activated belly shortens its fibres; strain_energy is the
  passive rest; total_potential is the sum (no loads: load_potential = 0).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import example, run_raw
from dolfinx import fem
from mpi4py import MPI
from scipy.optimize import fsolve

from forms.muscle import active_antiderivative, fibre_stretch
from model.config import parse
from model.pipeline import RunResult, build
from model.solvers.loadstepping import step_loads
from model.solvers.newton import NewtonSolver

comm = MPI.COMM_WORLD


def neo_hookean_uniaxial(E: float, nu: float, t: float) -> tuple[float, float, float]:
    """(l1, l2, W): psi = mu/2 (tr C - 3) - mu ln J + lmbda/2 (ln J)^2, P = mu (F - F^-T) + lmbda ln J F^-T,
    F = diag(l1, l2, l2) with P11 = t, P22 = 0."""
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))

    def balance(x: np.ndarray) -> np.ndarray:
        l1, l2 = x
        lnJ = np.log(l1 * l2 * l2)
        return np.array([mu * (l1 - 1 / l1) + lmbda * lnJ / l1 - t, mu * (l2 - 1 / l2) + lmbda * lnJ / l2])

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        l1, l2 = fsolve(balance, np.array([1.0, 1.0]), xtol=1e-14)
    assert np.abs(balance(np.array([l1, l2]))).max() < 1e-9 * max(abs(t), 1.0)
    lnJ = np.log(l1 * l2 * l2)
    W = mu / 2 * (l1**2 + 2 * l2**2 - 3) - mu * lnJ + lmbda / 2 * lnJ**2
    return float(l1), float(l2), float(W)


def test_uniaxial_neo_hookean_energies_in_closed_form(shared_tmp) -> None:
    raw = example("uniaxial")
    raw["mesh"]["cells"] = [2, 2, 2]
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    material = raw["material"][0]
    traction = raw["boundary"][3]["value"][0]
    assert summary["units"] == {"system": "SI", "length": "m", "force": "N", "stress": "Pa", "energy": "J",
                                "time": "s"}
    worst = 0.0
    for step in summary["steps"]:
        assert step["converged"] and "energy" not in step and "active_energy" not in step
        t = traction * step["load_factor"]
        l1, _, W = neo_hookean_uniaxial(material["E"], material["nu"], t)
        expected = {"strain_energy": W * 1.0, "load_potential": -t * (l1 - 1.0) * 1.0}
        expected["total_potential"] = expected["strain_energy"] + expected["load_potential"]
        for key, value in expected.items():
            error = abs(step[key] - value) / abs(value)
            worst = max(worst, error)
            assert error < 1e-8, f"{key} at load factor {step['load_factor']}: {step[key]} vs {value}"
        assert step["total_potential"] == pytest.approx(step["strain_energy"] + step["load_potential"], rel=1e-14)
        assert step["total_potential"] < 0  # a dead load: at equilibrium the potential is below 0 = Pi(u = 0)
    if comm.rank == 0:
        last = summary["steps"][-1]
        print(f"\nload factor 1: strain_energy {last['strain_energy']:.12g} J, load_potential "
              f"{last['load_potential']:.12g} J; worst relative error {worst:.2e}")
    result = RunResult(summary, shared_tmp)
    np.testing.assert_array_equal(result.energies["strain_energy"], [s["strain_energy"] for s in summary["steps"]])
    with pytest.warns(DeprecationWarning):
        old = result.energy  # the former "energy": the stored energy, no load potential
    np.testing.assert_array_equal(old, result.energies["strain_energy"])


def test_isometric_active_energy_and_total_potential() -> None:
    raw = example("isometric")
    raw["mesh"]["size"] = 0.01
    raw["discretization"] = {"degree": 1, "quadrature_degree": 2}  # coarse: P1, K finite
    raw["loading"] = {"steps": 2}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    config = parse(raw)
    setup = build(config, comm)
    problem = setup.problem
    solver = NewtonSolver(problem, config.petsc_options)
    energies = []
    def on_step(record) -> None:
        if record.result.converged:
            energies.append(problem.energies())

    assert step_loads(solver, 2, on_step=on_step)
    solver.destroy()
    assert len(energies) == 2
    muscle = config.materials[0].law
    s = fibre_stretch(problem.F, setup.fibres) / muscle.l_ofl
    density = muscle.sigma_max * setup.activation.function * (
        active_antiderivative(s) - active_antiderivative(1.0 / muscle.l_ofl, math))
    active = comm.allreduce(fem.assemble_scalar(fem.form(density * problem.region_measure("belly"))), op=MPI.SUM)
    last = energies[-1]
    assert set(last) == {"strain_energy", "active_energy", "load_potential", "total_potential"}
    assert last["active_energy"] == pytest.approx(active, rel=1e-10)
    assert last["active_energy"] < 0 < last["strain_energy"]
    assert last["load_potential"] == 0.0
    assert last["total_potential"] == pytest.approx(last["strain_energy"] + last["active_energy"], rel=1e-14)
    # the stored energy of the former summary key "energy" is the sum of the two
    assert problem.total_energy() == pytest.approx(last["strain_energy"] + last["active_energy"], rel=1e-10)
    # half the activation (first step): less active energy in magnitude
    assert abs(energies[0]["active_energy"]) < abs(last["active_energy"])
    if comm.rank == 0:
        print(f"\nisometric (coarse), alpha = 1: strain_energy {last['strain_energy']:.6g} J, active_energy "
              f"{last['active_energy']:.6g} J (by hand {active:.6g}), total_potential {last['total_potential']:.6g} J")


def test_mixed_strain_energy_is_the_mixed_functional_and_converges(shared_tmp: Path) -> None:
    """Cook's membrane, Taylor-Hood at nu = 0.4999: the strain energy is Pi(u, p) = W + p g - p^2/(2 kappa),
    close to half the external work (nearly linear response) and converging with the mesh. With
    W + (kappa/2) g(u)^2 of the discrete u it read 17583 and 4938 on 4 and 8 cells (332 converged)."""
    energies = []
    for cells in (4, 8):
        raw = example("cook")
        raw["mesh"]["cells"] = cells
        raw["output"] = {"xdmf": False, "vtu": False, "png": False}
        last = run_raw(raw, shared_tmp / f"cook{cells}")["steps"][-1]
        work = -last["load_potential"]
        assert 0.45 * work < last["strain_energy"] < 0.5 * work, (cells, last["strain_energy"], work)
        assert last["total_potential"] == pytest.approx(last["strain_energy"] + last["load_potential"], rel=1e-12)
        energies.append(last["strain_energy"])
    assert abs(energies[1] - energies[0]) < 0.05 * energies[1]
