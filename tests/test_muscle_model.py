"""Muscle and tendon at the model level: configuration files, fibre fields, activation curves.

Tier 1 (closed form): a block under the homogeneous isochoric fibre stretch F = diag(l, l^-1/2, l^-1/2)
(every boundary node prescribed) has reactions R_xmax = P11 A, R_ymax = P22 A, so
sigma_11 - sigma_22 = l P11 - l^-1/2 P22 must equal the energies.md curves (1e-8).
Tier 3 (physical invariants): equal and opposite tendon forces, volume change, no recompilation.
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from conftest import example, run_raw
from test_muscle_law import MUSCLE, TENDON, muscle_dF2, tendon_dF2

from model.config import parse
from model.errors import ConfigError
from model.pipeline import build


def stretched_block(law: str, params: dict, stretch: float, alpha: float | None) -> dict:
    lateral = stretch**-0.5 - 1.0
    exprs = [f"({stretch} - 1)*x[0]", f"{lateral}*x[1]", f"{lateral}*x[2]"]
    material = {"region": "all", "law": law, **params,
                "fibres": {"type": "constant", "origin": [0.0, 0.0, 0.0], "insertion": [2.0, 0.0, 0.0]}}
    if alpha is not None:
        material["activation"] = alpha
    return {
        "mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [2, 2, 2]},
        "discretization": {"degree": 1, "quadrature_degree": 2},
        "material": [material],
        "boundary": [{"on": face, "type": "displacement", "expression": exprs}
                     for face in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")],
        "loading": {"steps": 1},
        "solver": {"petsc_options": {"snes_linesearch_type": "basic"}},
        "output": {"xdmf": False, "vtu": False, "png": False},
    }


def fibre_stress_difference(summary: dict, stretch: float) -> float:
    last = summary["steps"][-1]
    P11 = last["reactions"]["xmax"][0] / summary["boundary_areas"]["xmax"]
    P22 = last["reactions"]["ymax"][1] / summary["boundary_areas"]["ymax"]
    return stretch * P11 - stretch**-0.5 * P22


@pytest.mark.parametrize("alpha", [0.0, 1.0])
@pytest.mark.parametrize("stretch", [0.75, 1.25, 1.45])
def test_block_fibre_stretch_muscle(shared_tmp, stretch: float, alpha: float) -> None:
    params = {k: MUSCLE[k] for k in ("c1", "c2", "K", "sigma_max", "P1", "P2", "l_ofl", "l_star")}
    summary = run_raw(stretched_block("muscle", params, stretch, alpha), shared_tmp)
    c1, c2 = MUSCLE["c1"], MUSCLE["c2"]
    expected = 2 * (c1 + c2 / stretch) * (stretch**2 - 1 / stretch) + stretch * muscle_dF2(stretch, alpha, MUSCLE)
    assert fibre_stress_difference(summary, stretch) == pytest.approx(expected, rel=1e-8)


@pytest.mark.parametrize("stretch", [1.02, 1.06])
def test_block_fibre_stretch_tendon(shared_tmp, stretch: float) -> None:
    params = {k: TENDON[k] for k in ("c1", "K", "L1", "L2", "l_star_t")}
    summary = run_raw(stretched_block("tendon", params, stretch, None), shared_tmp)
    expected = 2 * TENDON["c1"] * (stretch**2 - 1 / stretch) + stretch * tendon_dF2(stretch, TENDON)
    assert fibre_stress_difference(summary, stretch) == pytest.approx(expected, rel=1e-8)


def test_activation_follows_its_curve_without_recompiling(shared_tmp) -> None:
    raw = stretched_block("muscle", {}, 1.2, None)
    raw["material"][0]["activation"] = [[0.0, 0.0], [0.5, 0.8], [1.0, 0.2]]
    setup = build(parse(raw))
    problem = setup.problem
    forms_before = problem.forms
    values = []
    for t in (0.25, 0.5, 0.75, 2.0):
        problem.set_load_factor(t)
        assert problem.forms is forms_before  # same compiled forms
        values.append(setup.activation.function.x.array.max())
    np.testing.assert_allclose(values, [0.4, 0.8, 0.5, 0.2], rtol=1e-14)


def test_fibres_and_activation_are_written(shared_tmp) -> None:
    raw = stretched_block("muscle", {}, 1.1, 0.5)
    raw["output"] = {"xdmf": True, "vtu": False, "png": False}
    run_raw(raw, shared_tmp)
    last_step = sorted(shared_tmp.glob("results_*.h5"))[-1]  # a file per step (model.output.writer.XdmfSeries)
    with h5py.File(last_step, "r") as f:
        a0 = f["Function/fibre_direction"]
        last = a0[sorted(a0)[-1]][:]
        np.testing.assert_allclose(last[:, :3], np.tile([1.0, 0.0, 0.0], (len(last), 1)), atol=1e-15)
        alpha = f["Function/activation"]
        assert np.allclose(alpha[sorted(alpha)[-1]][:], 0.5)


# --- configuration errors: each names its key, before any solve -----------------------------------

def muscle_config(**material: object) -> dict:
    raw = example("isometric")
    raw["material"][0].update(material)
    return raw


@pytest.mark.parametrize(("change", "key", "fragment"), [
    ({"fibres": None}, r"material\[0\]\.fibres", "missing"),
    ({"fibres": {"type": "spline"}}, r"material\[0\]\.fibres\.type", "not one of"),
    ({"fibres": {"type": "constant", "origin": [0, 0, 0]}}, r"material\[0\]\.fibres\.insertion", "missing"),
    ({"fibres": {"type": "constant", "origin": [0, 0, 0], "insertion": [0, 0, 0]}},
     r"material\[0\]\.fibres\.insertion", "equals origin"),
    ({"fibres": {"type": "laplace", "origin": "origin", "insertion": "insertion", "region": ["belly"]}},
     r"material\[0\]\.fibres\.region", "unknown key"),
    ({"fibres": {"type": "file", "file": "nowhere.npy"}}, r"material\[0\]\.fibres\.file", "no such file"),
    ({"activation": 1.5}, r"material\[0\]\.activation", "out of range"),
    ({"activation": [[0.0, 0.0], [0.0, 1.0]]}, r"material\[0\]\.activation\[1\]\[0\]", "must increase"),
    ({"activation": [[0.0, 0.0], [1.0, -0.1]]}, r"material\[0\]\.activation\[1\]\[1\]", "out of range"),
    ({"activation": [[0.0, 0.0, 1.0]]}, r"material\[0\]\.activation\[0\]", "must have 2 entries"),
    ({"isotropic": "ogden"}, r"material\[0\]\.isotropic", "not one of"),
    ({"sigma_max": "big"}, r"material\[0\]\.sigma_max", "must be a number"),
])
def test_muscle_config_errors(change: dict, key: str, fragment: str) -> None:
    raw = muscle_config()
    for k, v in change.items():
        if v is None:
            raw["material"][0].pop(k)
        else:
            raw["material"][0][k] = v
    with pytest.raises(ConfigError, match=rf"^{key}: .*{fragment}"):
        parse(raw)


def test_fibre_keys_only_where_they_apply() -> None:
    raw = example("isometric")
    raw["material"][1]["activation"] = 0.5  # a tendon
    with pytest.raises(ConfigError, match=r"^material\[1\]\.activation: only applies to law = \"muscle\""):
        parse(raw)
    raw = example("uniaxial")
    raw["material"][0]["fibres"] = {"type": "constant", "origin": [0, 0, 0], "insertion": [1, 0, 0]}
    with pytest.raises(ConfigError, match=r"^material\[0\]\.fibres: only applies to laws with fibres"):
        parse(raw)


@pytest.mark.parametrize(("fibres", "key", "fragment"), [
    ({"type": "laplace", "origin": "start", "insertion": "insertion"}, r"fibres\.origin", "no boundary named 'start'"),
    ({"type": "laplace", "origin": "origin", "insertion": "insertion", "regions": ["bone"]},
     r"fibres\.regions\[0\]", "no region named 'bone'"),
    ({"type": "laplace", "origin": "origin", "insertion": "insertion"}, r"fibres\.regions",
     "the surface 'origin' has no node in region belly"),
])
def test_fibre_names_are_checked_against_the_mesh(fibres: dict, key: str, fragment: str) -> None:
    raw = example("isometric")
    raw["mesh"]["size"] = 0.02
    raw["material"][0]["fibres"] = fibres
    with pytest.raises(ConfigError, match=rf"^material\[0\]\.{key}: .*{fragment}"):
        build(parse(raw))


def test_point_constraints_must_be_nodes() -> None:
    raw = example("force_length_cylinder")
    raw["boundary"][3]["points"] = [[0.001, 0.0, 0.0]]
    with pytest.raises(ConfigError, match=r"^boundary\[3\]\.points\[0\]: .*not a node of boundary 'bottom'"):
        build(parse(raw))
