"""The muscle experiments of examples/ (isometric contraction, force-length, two-muscle arm segment).

Each runs its example configuration as written (the force-length ones at several stretches) and
checks the physics: near-incompressibility, monotone bulge and tendon force, equal and opposite
tendon forces, the tissue force-length curve against energies.md within 2%, the asymmetric bulge.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import example, run_raw
from mpi4py import MPI

from model.config import parse
from model.experiments.muscle import active_stress, forces, isometric_curves, with_stretch


def shared_dir(factory: pytest.TempPathFactory, name: str) -> Path:
    return Path(MPI.COMM_WORLD.bcast(str(factory.mktemp(name)) if MPI.COMM_WORLD.rank == 0 else None, root=0))


@pytest.fixture(scope="module")
def isometric(tmp_path_factory: pytest.TempPathFactory) -> dict:
    raw = example("isometric")
    raw["output"]["vtu"] = False
    return run_raw(raw, shared_dir(tmp_path_factory, "isometric"))


def test_isometric_contraction_is_nearly_incompressible(isometric: dict) -> None:
    curves = isometric_curves(isometric)
    assert curves["activation"] == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])
    assert max(abs(v) for v in curves["volume_change"]) < 0.01  # default K: below 1 %


def test_isometric_contraction_bulges_and_pulls_on_the_tendons(isometric: dict) -> None:
    curves = isometric_curves(isometric)
    assert np.all(np.diff([0.0, *curves["bulge"]]) > 0)  # the belly grows thicker as activation rises
    assert np.all(np.diff([0.0, *curves["tendon_force"]]) > 0)  # and pulls harder on its tendons
    last = isometric["steps"][-1]["reactions"]
    np.testing.assert_allclose(last["origin"], -np.asarray(last["insertion"]), rtol=1e-8, atol=1e-8)
    assert 0.0 < curves["tendon_force"][-1] < 3e5 * np.pi * 0.015**2  # below sigma_max times the belly's area


@pytest.fixture(scope="module")
def cylinder_sweep(tmp_path_factory: pytest.TempPathFactory) -> dict[float, dict]:
    raw = example("force_length_cylinder")
    out = shared_dir(tmp_path_factory, "force_length")
    return {stretch: run_raw(with_stretch(raw, stretch), out / f"l{stretch}")
            for stretch in (0.5, 0.7, 1.0, 1.2, 1.4, 1.5)}


def test_force_length_of_the_cylinder_recovers_f_active(cylinder_sweep: dict[float, dict]) -> None:
    law = parse(example("force_length_cylinder")).materials[0].law
    for stretch, summary in cylinder_sweep.items():
        _, _, active = forces(summary, "top")
        nominal = active / summary["boundary_areas"]["top"]  # per reference cross-section
        assert nominal == pytest.approx(active_stress(stretch, law), rel=0.02), stretch


def test_force_length_passive_force_only_beyond_the_optimal_length(cylinder_sweep: dict[float, dict]) -> None:
    passive = {s: forces(summary, "top")[0] / summary["boundary_areas"]["top"] for s, summary in cylinder_sweep.items()}
    assert abs(passive[1.0]) < 1.0  # rest length: no force (Pa)
    assert passive[1.2] > 0 and passive[1.5] > passive[1.4] > passive[1.2]  # exponential passive curve
    assert passive[0.5] < 0  # compressed: the isotropic matrix pushes back


def test_force_length_of_the_fusiform_muscle(shared_tmp: Path) -> None:
    summary = run_raw(example("force_length_fusiform"), shared_tmp)
    passive, total, active = forces(summary, "insertion")
    assert passive > 0 and active > 0
    # the whole muscle delivers less than sigma_max times its largest cross-section
    assert active < 3e5 * np.pi * 0.015**2


def test_two_muscle_arm_segment_bulges_asymmetrically(shared_tmp: Path) -> None:
    raw = example("arm_segment")
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    u = {name: np.asarray(value) for name, value in summary["steps"][-1]["probes"].items()}
    # thickening of each belly at mid-length: its top surface moves away from its own axis
    thickening = {m: u[f"belly_{m}_top"][1] - u[f"belly_{m}_centre"][1] for m in ("a", "b")}
    # the run's own record, should the physics checks fail: load factor, activation, Newton iterations
    record = {"cells": summary["cells"], "dofs": summary["dofs"], "region_volumes": summary["region_volumes"],
              "steps": [{k: s.get(k) for k in ("load_factor", "activation", "newton_iterations", "residual_norm",
                                                "strain_energy", "active_energy", "volumes")}
                        for s in summary["steps"]]}
    assert summary["status"] == "completed", (summary["status"], record)
    assert thickening["b"] > 0, (thickening, record)
    # muscle a (alpha = 1) thickens more than b (alpha = 0.3)
    assert thickening["a"] > 1.5 * thickening["b"], (thickening, record)
    assert u["belly_b_centre"][0] > 0  # and pushes muscle b away (+x)
    for name in ("skin_over_a", "skin_over_b"):  # the skin bulges outwards over both
        point = np.array(next(p["point"] for p in raw["probe"] if p["name"] == name))
        assert np.dot(u[name][:2], point[:2]) > 0
