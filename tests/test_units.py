"""examples/isometric_mm.toml is examples/isometric.toml in mm, MPa, N, s, tonne/mm^3 ([units] system = "mm-MPa").

Every number of the SI example converted (lengths x 1e3, stresses x 1e-6, forces unchanged), and the two
runs agree: probes x 1e3, reactions equal (N), energies x 1e3 (mJ against J), to 1e-8 relative. gmsh does
not mesh a body 1e3 times larger into a similar mesh, so the runs share one coarse mesh (written as .msh,
its points scaled by 1e3 for the mm run).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from conftest import example, run_raw
from mpi4py import MPI

import forms
import meshes

LENGTH, STRESS = 1e3, 1e-6
#: how each number of the example converts, by key (anything else is dimensionless and unchanged)
LENGTH_KEYS = {"length", "belly_radius", "tendon_radius", "tendon_length", "size", "point"}
STRESS_KEYS = {"E", "sigma_max", "K", "L1", "mu", "lmbda", "c1", "c2"}


def _converted(si: Any, mm: Any, key: str, where: str) -> None:
    if isinstance(si, dict):
        assert set(si) <= set(mm), f"{where}: keys {set(si) - set(mm)} missing"
        for k in si:
            _converted(si[k], mm[k], k, f"{where}.{k}")
    elif isinstance(si, list):
        assert len(si) == len(mm), where
        for i, (a, b) in enumerate(zip(si, mm)):
            _converted(a, b, key, f"{where}[{i}]")
    elif isinstance(si, float) and not isinstance(si, bool):
        factor = LENGTH if key in LENGTH_KEYS else STRESS if key in STRESS_KEYS else 1.0
        assert np.isclose(mm, si * factor, rtol=1e-12, atol=0.0), (where, si, mm)
    elif key != "dir":
        assert si == mm, where


def test_every_number_is_converted() -> None:
    si, mm = example("isometric"), example("isometric_mm")
    assert mm.pop("units") == {"system": "mm-MPa"}
    _converted(si, mm, "", "config")
    # what the SI example leaves to the laws' defaults (SI values) the mm example gives, converted
    for s, m in zip(si["material"], mm["material"], strict=True):
        entry = forms.REGISTRY[s["law"]]
        for p in entry.parameters:
            if p.unit.startswith("Pa") and p.name not in s and p.name in m:
                assert np.isclose(m[p.name], p.default * STRESS, rtol=1e-12), (s["region"], p.name)
        defaulted = [p.name for p in entry.parameters if p.unit.startswith("Pa") and p.name not in m
                     and isinstance(p.default, float) and p.default > 0 and p.applies != "isotropic = mooney_rivlin"]
        assert defaulted == [], (m["region"], defaulted)


def _with_mesh(raw: dict[str, Any], path: Path) -> dict[str, Any]:
    return {**raw, "mesh": {"file": str(path)}, "loading": {"steps": 2},
            "output": {"xdmf": False, "vtu": False, "png": False}}


def test_mm_run_matches_si_run(shared_tmp: Path) -> None:
    si_mesh, mm_mesh = shared_tmp / "si.msh", shared_tmp / "mm.msh"
    if MPI.COMM_WORLD.rank == 0:
        params = {k: v for k, v in example("isometric")["mesh"].items() if k != "generator"}
        mesh = meshes.generate("fusiform", **{**params, "size": 0.012})
        meshes.write_msh(mesh, si_mesh)
        meshes.write_msh(dataclasses.replace(mesh, points=mesh.points * LENGTH), mm_mesh)
    MPI.COMM_WORLD.barrier()
    si = run_raw(_with_mesh(example("isometric"), si_mesh), shared_tmp / "si")
    mm = run_raw(_with_mesh(example("isometric_mm"), mm_mesh), shared_tmp / "mm")
    assert si["status"] == mm["status"] == "completed"
    assert si["warnings"] == mm["warnings"] == []
    assert np.isclose(mm["scale_check"]["body_size"], si["scale_check"]["body_size"] * LENGTH, rtol=1e-12)
    assert np.isclose(mm["scale_check"]["first_increment_strain"], si["scale_check"]["first_increment_strain"],
                      rtol=1e-8)
    a, b = [s for s in si["steps"] if s["converged"]], [s for s in mm["steps"] if s["converged"]]
    assert [s["load_factor"] for s in a] == [s["load_factor"] for s in b] == [0.5, 1.0]

    def close(x: Any, y: Any, factor: float, what: str) -> None:
        x, y = np.asarray(x, dtype=float) * factor, np.asarray(y, dtype=float)
        assert np.max(np.abs(x - y)) <= 1e-8 * np.max(np.abs(x)), (what, x, y)

    for s, m in zip(a, b):
        energies = ("strain_energy", "active_energy", "load_potential", "total_potential")
        assert [k for k in energies if k in s] == [k for k in energies if k in m] != []
        for key in (k for k in energies if k in s):
            close(s[key], m[key], LENGTH, f"{key} (J -> mJ)")
        for name in s["probes"]:
            close(s["probes"][name], m["probes"][name], LENGTH, f"probe {name} (m -> mm)")
        for name in s["reactions"]:
            close(s["reactions"][name], m["reactions"][name], 1.0, f"reaction {name} (N)")
