"""Tier 1: homogeneous uniaxial tension (the run-contract example) against the closed form, every law."""

from __future__ import annotations

import numpy as np
import pytest
from closed_form import principal_stress, uniaxial_stretches
from conftest import example, run_raw
from scipy.optimize import brentq

LAWS = {
    "stvk": {"E": 1.0e4, "nu": 0.3},
    "neo_hookean": {"E": 1.0e4, "nu": 0.3},
    "mooney_rivlin": {"c1": 1500.0, "c2": 400.0, "K": 8000.0},
    "corotated": {"mu": 3846.0, "lmbda": 5769.0},
}


@pytest.mark.parametrize("law", sorted(LAWS))
def test_uniaxial_tension_matches_closed_form(law: str, shared_tmp) -> None:
    raw = example("uniaxial")
    raw["material"] = [{"region": "all", "law": law, **LAWS[law]}]
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    traction = raw["boundary"][3]["value"][0]
    assert summary["status"] == "completed"
    steps = [s for s in summary["steps"] if s["converged"]]
    assert [round(s["load_factor"], 12) for s in steps] == [0.2, 0.4, 0.6, 0.8, 1.0]
    for step in steps:
        la, lt = uniaxial_stretches(law, LAWS[law], step["load_factor"] * traction)
        expected = np.array([la - 1.0, lt - 1.0, lt - 1.0])  # corner (1, 1, 1) of the unit cube
        got = np.array(step["probes"]["corner"])
        np.testing.assert_allclose(got, expected, rtol=1e-8, atol=0)
        # equilibrium: the xmin support balances the applied traction (area 1)
        np.testing.assert_allclose(step["reactions"]["xmin"][0], -step["load_factor"] * traction, rtol=1e-9)


@pytest.mark.parametrize("law", sorted(LAWS))
def test_follower_pressure_gives_hydrostatic_cauchy_stress(law: str, shared_tmp) -> None:
    """Pressure p on xmax, ymax, zmax (symmetry on the other faces): uniform stretch l with
    Cauchy stress sigma = P l / J = -p, because a follower pressure acts on the deformed faces."""
    pressure = 1000.0
    raw = example("uniaxial")
    raw["material"] = [{"region": "all", "law": law, **LAWS[law]}]
    raw["boundary"] = raw["boundary"][:3] + [{"on": face, "type": "pressure", "value": pressure}
                                              for face in ("xmax", "ymax", "zmax")]
    raw["loading"] = {"steps": 2}
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    summary = run_raw(raw, shared_tmp)
    assert summary["status"] == "completed"
    for step in summary["steps"]:
        p = step["load_factor"] * pressure
        stretch = brentq(lambda l, p=p: principal_stress(law, np.full(3, l), LAWS[law])[0] / l**2 + p, 0.5, 1.0)
        np.testing.assert_allclose(step["probes"]["corner"], np.full(3, stretch - 1.0), rtol=1e-8)
        # the supports balance the pressure on the deformed face of area l^2
        np.testing.assert_allclose(step["reactions"]["xmin"][0], p * stretch**2, rtol=1e-8)
