"""Any law parameter may follow a load curve (model/config/material.py ParameterCurve, model/pipeline.py): the
held parameter (model/problem/parameters.py) is set to the law made again at each load factor, with no compile.

Hyperelastic equilibrium does not depend on the path: at load factor t the state of a run whose E follows a
curve is the state of a run with E fixed at E(t), at the same load factor."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import ROOT, serial_only

from model import pipeline
from model.config import load
from model.errors import ConfigError

UNIAXIAL = ROOT / "examples" / "uniaxial.toml"

#: runs in-process several times; the held parameters on 2 ranks are every MPI test's
pytestmark = serial_only


def _corners(overrides: dict, out: Path) -> list[list[float]]:
    summary = pipeline.run(load(UNIAXIAL, {"loading.steps": 2, **overrides}), out)
    return [step["probes"]["corner"] for step in summary["steps"]]


def test_a_modulus_curve_is_the_fixed_modulus_at_each_load_factor(tmp_path: Path, compiles: list[str]) -> None:
    ramp = _corners({"material.0.E": [[0.0, 1.0e4], [1.0, 2.0e4]]}, tmp_path / "ramp")
    compiles.clear()
    expression = _corners({"material.0.E": "1e4 * (1 + t)"}, tmp_path / "expression")
    half = _corners({"material.0.E": 1.5e4}, tmp_path / "half")
    full = _corners({"material.0.E": 2.0e4}, tmp_path / "full")
    assert compiles == []  # the curves and the fixed values share the kernels
    assert ramp[0] == pytest.approx(half[0], rel=1e-9) and ramp[1] == pytest.approx(full[1], rel=1e-9)
    assert expression[0] == pytest.approx(ramp[0], rel=1e-12) and expression[1] == pytest.approx(ramp[1], rel=1e-12)
    assert ramp[0] != pytest.approx(full[0], rel=1e-3)  # the curve did move E


def test_a_user_law_parameter_follows_a_curve(tmp_path: Path) -> None:
    """Land et al.'s active tension as a user law's parameter Ta = [[0, 0], [1, 1000]] Pa (examples/
    guccione_active.toml, coarser): at t = 1/2 the beam is where Ta = 500 Pa fixed puts it."""
    coarse = {"mesh.cells": [6, 1, 1], "loading.steps": 2, "probe": [{"name": "tip", "point": [0.01, 0.0005, 0.001]}]}
    path = ROOT / "examples" / "guccione_active.toml"
    ramp = pipeline.run(load(path, coarse), tmp_path / "ramp")["steps"]
    fixed = pipeline.run(load(path, {**coarse, "material.0.Ta": 500.0}), tmp_path / "fixed")["steps"]
    assert ramp[0]["probes"]["tip"] == pytest.approx(fixed[0]["probes"]["tip"], rel=1e-8)
    assert ramp[1]["probes"]["tip"][0] < 1.5 * ramp[0]["probes"]["tip"][0] < 0  # shorter still at Ta = 1000 Pa


@pytest.mark.parametrize(("value", "message"), [
    ([[0.0, 1.0e4], [0.0, 2.0e4]], "material[0].E: row 1: times must increase, got 0.0 after 0.0"),
    ([[0.0, -1.0], [1.0, 1.0e4]], "material[0].E: at t = 0: "),
    ("1e4 * (1 + x[0])", "material[0].E: '1e4 * (1 + x[0])': a law parameter may follow the load factor t, not"),
    ("1e4 * nope", "material[0].E: must be a number, got '1e4 * nope' (or a load curve: a table"),
    ([[0.0, "a"]], "material[0].E: must be a number, got [[0.0, 'a']] (or a load curve: a table"),
])
def test_bad_curves_are_one_line_errors(value: object, message: str) -> None:
    with pytest.raises(ConfigError) as err:
        load(UNIAXIAL, {"material.0.E": value})
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_a_parameter_used_outside_ufl_cannot_follow_a_curve(tmp_path: Path) -> None:
    """The muscle's passive curve uses P2 in math.exp: it stays a number, and a curve on it is refused before
    any solve, naming the key."""
    muscle = {"material.0.law": "muscle", "material.0.isotropic": "stvk", "loading.steps": 1,
              "material.0.fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [1.0, 0.0, 0.0]},
              "material.0.P2": [[0.0, 6.0], [1.0, 7.0]]}
    with pytest.raises(ConfigError, match=r"^material\[0\]\.P2: the curve changes P2, which muscle uses outside UFL"):
        pipeline.run(load(UNIAXIAL, muscle), tmp_path / "run")
    assert not (tmp_path / "run" / "steps").exists()
