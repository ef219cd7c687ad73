"""Cook's membrane, nearly incompressible neo-Hookean (E = 240.565, nu = 0.4999), plane strain by u_z = 0.

Reference: top-right corner vertical displacement 6.9083 mm (Elguedj et al. 2008).
P1 tetrahedra lock (the corner moves about a third of the reference); the Taylor-Hood
mixed formulation converges to the reference and is within 1% on the finest test mesh.
"""

from __future__ import annotations

import pytest
from conftest import example, run_raw

REFERENCE = 6.9083


def corner_uy(shared_tmp, cells: int, degree: int, formulation: str, linesearch: str = "bt") -> float:
    raw = example("cook")
    raw["mesh"]["cells"] = cells
    raw["discretization"] = {"degree": degree, "quadrature_degree": 2 * degree, "formulation": formulation}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    raw["solver"] = {"petsc_options": {"snes_linesearch_type": linesearch}}
    summary = run_raw(raw, shared_tmp)
    assert summary["status"] == "completed"
    return summary["steps"][-1]["probes"]["top_right"][1]


def test_p1_tetrahedra_lock(shared_tmp) -> None:
    # full Newton steps: a residual-norm line search stalls on the locked, stiff P1 system
    coarse, fine = (corner_uy(shared_tmp, n, 1, "displacement", "basic") for n in (8, 16))
    assert fine < 0.4 * REFERENCE and coarse < 0.4 * REFERENCE, (coarse, fine)


def test_taylor_hood_converges_to_reference(shared_tmp) -> None:
    values = [corner_uy(shared_tmp, n, 2, "mixed") for n in (4, 8, 16)]
    errors = [abs(v - REFERENCE) / REFERENCE for v in values]
    assert errors[0] > errors[1] > errors[2], values
    assert errors[-1] < 0.01, f"finest Taylor-Hood mesh: {values[-1]} vs {REFERENCE} ({100 * errors[-1]:.2f}%)"


@pytest.mark.slow
def test_taylor_hood_fine_mesh(shared_tmp) -> None:
    value = corner_uy(shared_tmp, 24, 2, "mixed")
    assert abs(value - REFERENCE) / REFERENCE < 0.005, value
