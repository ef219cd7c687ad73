"""Reactions at dofs two boundaries share (model/problem/measurements.py shared_reactions): a quarter block on a
clamped base with two symmetry planes, pressed on its top. The base's edges lie in the symmetry planes, so their
x (or y) dofs are fixed twice; each boundary's reaction counts them, and the reactions' sum counts their force
twice. The exclusive and shared forces count it once: with no load along x and y they balance to zero, and they
add up to each boundary's reaction. Serially and on 2 ranks (the same numbers)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import run_raw


def quarter_block() -> dict:
    fixed = {"type": "displacement"}
    return {
        "mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [2, 2, 2]},
        "material": [{"law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
        "boundary": [{**fixed, "on": "zmin", "value": [0.0, 0.0, 0.0]},
                     {**fixed, "on": "xmin", "components": [0], "value": [0.0]},
                     {**fixed, "on": "ymin", "components": [1], "value": [0.0]},
                     {"on": "zmax", "type": "traction", "value": [0.0, 0.0, -500.0]}],
        "loading": {"steps": 1},
        "output": {"xdmf": False, "vtu": False, "png": False},
    }


def test_shared_dofs_are_counted_once(shared_tmp: Path) -> None:
    summary = run_raw(quarter_block(), shared_tmp / "block")
    step = summary["steps"][-1]
    reactions, exclusive, shared = step["reactions"], step["reactions_exclusive"], step["reactions_shared"]
    assert set(shared) == {"xmin & zmin", "ymin & zmin"}
    scale = abs(reactions["zmin"][2])
    assert scale == pytest.approx(500.0, rel=1e-8)  # the base carries the load
    for name in reactions:  # each boundary's reaction: its own dofs and its share of the shared ones
        with_it = sum(np.array(f) for key, f in shared.items() if name in key.split(" & "))
        assert np.allclose(reactions[name], np.array(exclusive[name]) + with_it, atol=1e-10 * scale)
    once = sum(np.array(f) for f in exclusive.values()) + sum(np.array(f) for f in shared.values())
    assert np.allclose(once, [0.0, 0.0, 500.0], atol=1e-8 * scale)  # the support force balances the load, once
    twice = sum(np.array(f) for f in reactions.values())
    assert abs(twice[0]) > 1e-3 * scale  # the edge's lateral force counted twice: no balance
    assert twice[0] == pytest.approx(shared["xmin & zmin"][0], rel=1e-6)


def test_no_shared_dofs_no_breakdown(shared_tmp: Path) -> None:
    raw = quarter_block()
    raw["boundary"][0] = {"type": "displacement", "on": "zmin", "components": [2], "value": [0.0]}
    step = run_raw(raw, shared_tmp / "rollers")["steps"][-1]
    assert "reactions_shared" not in step and "reactions_exclusive" not in step
