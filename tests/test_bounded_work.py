"""Work that ends, tolerances with the body's scale, failures that say what helps:

- Newton's snes_atol and the line search's largest step follow the body's force scale and size
  (ScaleCheck.newton_options): a box 1e-12 m across and one 1e9 m across solve like the 1 m one, step for step
  (before: the small one "converged" at u = 0 after 0 iterations, the large one took 30 iterations, its steps cut to
  PETSc's fixed 1e8 m);
- loading.max_steps caps the solves of a load-stepping run (default 10 x steps + 100): it stops as failed,
  naming the key;
- MUMPS out of memory (here its own limit, mat_mumps_icntl_23 = 1 MB) is named, with what helps, and ends the run
  at once (no cut-back: the matrix is the same at any load).
Serially and under mpirun -n 2 (the same figures)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import run_raw

from model.errors import SolveFailed


def box(size: float, **loading: Any) -> dict[str, Any]:
    """The uniaxial example on a cube of side ``size``: u_x = 0, u_y = 0, u_z = 0 on three faces, a traction of
    2 kPa on x = size (the same strain at any size)."""
    def face(on: str, c: int) -> dict[str, Any]:
        return {"on": on, "type": "displacement", "components": [c], "value": [0.0]}

    return {"mesh": {"generator": "box", "size": [size] * 3, "cells": [2, 2, 2]},
            "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
            "boundary": [face("xmin", 0), face("ymin", 1), face("zmin", 2),
                         {"on": "xmax", "type": "traction", "value": [2.0e3, 0.0, 0.0]}],
            "loading": {"steps": 2, **loading},
            "probe": [{"name": "corner", "point": [size] * 3}],
            "output": {"xdmf": False, "vtu": False, "png": False}}


def test_a_tiny_and_a_huge_body_solve_like_a_unit_one(shared_tmp: Path) -> None:
    runs = {s: run_raw(box(s), shared_tmp / f"size_{s:g}") for s in (1.0, 1e-12, 1e9)}
    unit = runs[1.0]
    iterations = [s["newton_iterations"] for s in unit["steps"]]
    assert all(2 <= n <= 6 for n in iterations), iterations  # a few quadratic Newton steps on the unit cube
    for size, summary in runs.items():
        assert [s["newton_iterations"] for s in summary["steps"]] == iterations, size
        corner = np.array(summary["steps"][-1]["probes"]["corner"]) / size
        np.testing.assert_allclose(corner, unit["steps"][-1]["probes"]["corner"], rtol=1e-9)
        options = summary["solver"]["petsc_options"]
        assert options["snes_atol"] == pytest.approx(1e-16 * 1e4 * (3**0.5 * size) ** 2, rel=1e-12)
        assert options["snes_linesearch_maxstep"] == pytest.approx(1e8 * 3**0.5 * size, rel=1e-12)


def test_max_steps_caps_the_solves_and_names_the_key(shared_tmp: Path) -> None:
    with pytest.raises(SolveFailed) as caught:
        run_raw(box(1.0, steps=4, max_steps=3), shared_tmp)
    assert "load steps: 3 solves (loading.max_steps) without reaching 1; stopped at 0.75" in str(caught.value)
    from conftest import EXAMPLES

    from model.config import parse

    assert parse(box(1.0, steps=7), EXAMPLES).loading.step_cap == 170
    assert parse(box(1.0, control="arc_length"), EXAMPLES).loading.step_cap == 200


def test_mumps_out_of_memory_is_named_and_not_cut_back(shared_tmp: Path) -> None:
    raw = box(1.0)
    raw["mesh"]["cells"] = [10, 10, 10]
    raw["solver"] = {"petsc_options": {"mat_mumps_icntl_23": 1}}
    with pytest.raises(SolveFailed) as caught:
        run_raw(raw, shared_tmp)
    message = str(caught.value)
    assert "MUMPS ran out of memory in the factorisation (INFOG(1) = -19" in message, message
    assert "smaller load steps cannot help" in message
    import json

    steps = json.loads((shared_tmp / "summary.json").read_text())["steps"]
    assert len(steps) == 1 and steps[0]["snes_reason_name"] == "DIVERGED_LINEAR_SOLVE"
