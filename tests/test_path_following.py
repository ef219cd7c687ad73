"""Folded states refused, limit points named and passed (arc length, cavity-volume control).

The check is the thick-walled incompressible neo-Hookean sphere (examples/thick_sphere.toml: inner radius
A = 1, outer B = 1.5, mu = 1000 Pa, an octant of curved P2 cells, Taylor-Hood with K = inf) under an inner
follower pressure. Its pressure against the inner stretch lambda_a = a / A is known in closed form,

    p(lambda_a) = mu (2/lambda_b + 1/(2 lambda_b^4) - 2/lambda_a - 1/(2 lambda_a^4)),
    lambda_b^3 = 1 + (lambda_a^3 - 1) (A/B)^3,

with a maximum p_max = 0.49352 mu at lambda_a = 1.603. lambda_a is read at the inner pole (0, 0, 1).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import example, run_raw

from model.errors import ConfigError, SolveFailed

MU = 1000.0
A, B = 1.0, 1.5
P_MAX = 0.49351893  # / mu, at lambda_a = 1.6035 (closed form, maximised on a fine grid)


def closed_form(stretch: np.ndarray) -> np.ndarray:
    """p(lambda_a) / mu of the thick-walled incompressible neo-Hookean sphere (module docstring)."""
    outer = (1.0 + (stretch**3 - 1.0) * (A / B) ** 3) ** (1.0 / 3.0)
    return 2.0 / outer + 1.0 / (2.0 * outer**4) - 2.0 / stretch - 1.0 / (2.0 * stretch**4)


def sphere(**loading: Any) -> dict[str, Any]:
    raw = example("thick_sphere")
    raw["output"] = {"xdmf": False, "vtu": False, "png": False}
    raw["loading"] = loading
    return raw


def path(summary: dict[str, Any], pressure: float) -> tuple[np.ndarray, np.ndarray]:
    """(lambda_a, p / mu) of the converged steps."""
    steps = [s for s in summary["steps"] if s["converged"]]
    stretch = np.array([1.0 + s["probes"]["inner_pole"][2] for s in steps])
    return stretch, np.array([s["load_factor"] for s in steps]) * pressure / MU


def test_closed_form_has_its_maximum() -> None:
    stretch = np.linspace(1.0001, 3.0, 200_001)
    p = closed_form(stretch)
    assert p.max() == pytest.approx(P_MAX, rel=1e-7)
    assert stretch[p.argmax()] == pytest.approx(1.6035, abs=1e-3)


@pytest.fixture(scope="module")
def volume_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    from mpi4py import MPI

    out = Path(MPI.COMM_WORLD.bcast(str(tmp_path_factory.mktemp("volume")), root=0))
    return run_raw(sphere(control="volume", volume_boundary="inner", volume_ratio=8.0, steps=6), out)


def test_volume_control_passes_the_maximum_on_the_closed_form(volume_run: dict[str, Any]) -> None:
    """V from V_0 to 8 V_0 (lambda_a = 2): through p_max and down its far side, every step within 0.1 %."""
    stretch, p = path(volume_run, MU)
    assert volume_run["status"] == "completed"
    assert len(stretch) == 6 and stretch[-1] == pytest.approx(2.0, abs=2e-3)
    np.testing.assert_allclose(p, closed_form(stretch), rtol=1e-3)
    peak = int(np.argmax(p))
    assert 0 < peak < len(p) - 1  # the pressure rises, then falls: the maximum was passed
    assert p.max() == pytest.approx(P_MAX, rel=5e-3)
    steps = volume_run["steps"]
    rest = volume_run["control"]["rest_volume"]
    assert rest == pytest.approx(np.pi / 6, rel=1e-4)  # an octant of the unit ball: curved cells, exact
    for i, s in enumerate(steps, start=1):
        assert s["cavity_volume"] == pytest.approx(rest * (1 + 7 * i / 6), rel=1e-8)
        assert s["min_det_F"] > 0.5
        assert set(s["min_det_F_regions"]) == {"all"}


def test_arc_length_passes_the_maximum_on_the_closed_form(shared_tmp: Path) -> None:
    """A reference pressure above p_max: arc length climbs to the maximum and follows the path down beyond it
    (the load factor falls), on the closed form; it never reaches load 1 and says so."""
    pressure = 1.2 * P_MAX * MU
    raw = sphere(control="arc_length", steps=2, max_steps=9)
    raw["boundary"][3]["value"] = pressure
    with pytest.raises(SolveFailed, match="did not reach load factor 1 within loading.max_steps = 9"):
        run_raw(raw, shared_tmp)
    import json

    summary = json.loads((shared_tmp / "summary.json").read_text())
    stretch, p = path(summary, pressure)
    np.testing.assert_allclose(p, closed_form(stretch), rtol=1e-3)
    assert stretch[-1] > 1.7 and p[-1] < p.max()  # past the maximum, on the falling branch
    assert p.max() == pytest.approx(P_MAX, rel=5e-3)
    assert all(s["control"] == "arc_length" for s in summary["steps"])


def test_load_control_names_the_limit_point(shared_tmp: Path) -> None:
    """Pressure control towards 1.2 p_max: the steps converge up to the maximum, then the run stops with a
    message naming the instability and the load, and advice that can help (not more cut-backs)."""
    pressure = 1.2 * P_MAX * MU
    raw = sphere(steps=4, max_cutbacks=5)
    raw["solver"] = {"petsc_options": {"snes_max_it": 12}}  # failures beyond the maximum end sooner
    raw["boundary"][3]["value"] = pressure
    with pytest.raises(SolveFailed) as failed:
        run_raw(raw, shared_tmp)
    message = str(failed.value)
    assert "a limit point or bifurcation (an instability of the structure), not a solver failure" in message
    assert 'control = "arc_length"' in message and "raise loading.max_cutbacks" not in message
    import json

    summary = json.loads((shared_tmp / "summary.json").read_text())
    stability = summary["stability"]
    assert stability["unstable"] and stability["stiffness_ratio"] < 0.05
    last = stability["load_factor"] * pressure / MU
    assert last == pytest.approx(P_MAX, rel=2e-2) and last < P_MAX * 1.001  # stopped at the maximum
    assert f"{stability['load_factor']:.6g}" in message


@pytest.mark.parametrize(("loading", "key"), [
    ({"control": "volume", "steps": 2}, "loading.volume_boundary"),
    ({"control": "volume", "volume_boundary": "outer", "volume_ratio": 2.0}, "loading.volume_boundary"),
    ({"control": "volume", "volume_boundary": "inner"}, "loading.volume_ratio"),
])
def test_volume_control_refuses_what_it_cannot_drive(shared_tmp: Path, loading: dict[str, Any], key: str) -> None:
    with pytest.raises(ConfigError, match=f"^{key}: "):
        run_raw(sphere(**loading), shared_tmp)


def test_path_following_refuses_moving_displacements(shared_tmp: Path) -> None:
    raw = example("uniaxial")
    raw["loading"] = {"control": "arc_length"}
    raw["boundary"] = [b for b in raw["boundary"] if b["on"] != "xmax"]
    raw["boundary"].append({"on": "xmax", "type": "displacement", "components": [0], "value": [0.1]})
    with pytest.raises(ConfigError, match="^loading.control: 'arc_length': a displacement condition moves"):
        run_raw(raw, shared_tmp)


def test_path_following_needs_a_load(shared_tmp: Path) -> None:
    """A run whose only load is gone (the pressure removed): one line naming the key, no traceback."""
    raw = sphere(control="arc_length")
    raw["boundary"] = raw["boundary"][:3]
    with pytest.raises(ConfigError, match="^loading.control: 'arc_length': path following needs a load"):
        run_raw(raw, shared_tmp)
