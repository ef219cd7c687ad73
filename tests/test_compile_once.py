"""Law parameters are runtime values (model/problem/parameters.py): the same law with other numbers reuses the
compiled kernels. Counted: FFCx's compiles (cache misses: ffcx.codegeneration.jit._compile_objects) over a sweep."""

from __future__ import annotations

from pathlib import Path

from conftest import ROOT, serial_only

from model import pipeline
from model.config import load

#: runs in-process several times; the held parameters on 2 ranks are every MPI test's
pytestmark = serial_only


def _run(path: Path, overrides: dict, out: Path) -> dict:
    return pipeline.run(load(path, overrides), out)


#: the uniaxial bar as an activated muscle (P1, 4 x 4 x 4 cells): fibres along x, activation ramped to 1
MUSCLE = {"material.0.law": "muscle", "material.0.isotropic": "stvk", "loading.steps": 1,
          "material.0.fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [1.0, 0.0, 0.0]},
          "material.0.activation": [[0.0, 0.0], [1.0, 1.0]]}


def test_a_muscle_sweep_compiles_one_set_of_kernels(tmp_path: Path, compiles: list[str]) -> None:
    """Five values of the muscle's sigma_max (with E and the passive fibre's P1 changed too): after the first
    run nothing is compiled (before: every value compiled the forms again, 30-35 s for this law); the
    contraction grows with sigma_max."""
    uniaxial = ROOT / "examples" / "uniaxial.toml"
    points = [(1.0e3, 1.0e4, 0.05), (2.0e3, 1.1e4, 0.06), (3.0e3, 1.2e4, 0.07), (4.0e3, 1.3e4, 0.08),
              (5.0e3, 1.4e4, 0.09)]
    shortening = []
    for i, (sigma_max, E, P1) in enumerate(points):
        if i == 1:
            compiles.clear()
        summary = _run(uniaxial, {**MUSCLE, "material.0.sigma_max": sigma_max, "material.0.E": E,
                                  "material.0.P1": P1}, tmp_path / str(i))
        assert summary["status"] == "completed"
        shortening.append(summary["steps"][-1]["probes"]["corner"][0])
    assert compiles == [], compiles
    assert len(set(shortening)) == len(points), shortening


def test_each_run_uses_its_own_numbers(tmp_path: Path, compiles: list[str]) -> None:
    """The numbers reach the kernels: a stiffer neo-Hookean bar (E doubled) stretches less under the same traction,
    and the first value run again gives the first answer to the last bit; no compile after the first run."""
    base = {"loading.steps": 1}

    def corner(E: float, name: str) -> list[float]:
        summary = _run(ROOT / "examples" / "uniaxial.toml", {**base, "material.0.E": E}, tmp_path / name)
        return summary["steps"][-1]["probes"]["corner"]

    soft = corner(1.0e4, "soft")
    compiles.clear()
    stiff = corner(2.0e4, "stiff")
    again = corner(1.0e4, "again")
    assert compiles == []
    assert 0 < stiff[0] < 0.75 * soft[0] and again == soft
