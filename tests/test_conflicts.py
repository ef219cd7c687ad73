"""Contradicting boundary conditions (model.problem.conflicts) are one-line ConfigErrors naming both keys, found
by build before any solve: two Dirichlet conditions with different values on shared dofs (compared at load
factors 1 and 0.5, expressions of t included), a traction or pressure whose direction a condition on the same
facets prescribes. Agreeing conditions on a shared edge, a traction across a constrained direction and a roller
under a pressure pass. Collective: the same messages serially and under mpirun -n 2."""

from __future__ import annotations

from typing import Any

import pytest
from conftest import EXAMPLES

from model.errors import ConfigError

CLAMP = {"on": "xmin", "type": "displacement", "value": [0.0, 0.0, 0.0]}


def build_with(*boundaries: dict[str, Any]) -> None:
    from model.config import parse
    from model.pipeline import build

    raw = {"mesh": {"generator": "box", "size": [1.0, 1.0, 1.0], "cells": [2, 2, 2]},
           "material": [{"region": "all", "law": "neo_hookean", "E": 1.0e4, "nu": 0.3}],
           "boundary": list(boundaries), "loading": {"steps": 1},
           "output": {"xdmf": False, "vtu": False, "png": False}}
    build(parse(raw, EXAMPLES))


def refused(*boundaries: dict[str, Any]) -> str:
    with pytest.raises(ConfigError) as caught:
        build_with(*boundaries)
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_two_values_for_one_dof_name_both_keys() -> None:
    message = refused({"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
                      {"on": "xmin", "type": "displacement", "components": [0], "value": [0.1]})
    assert message.startswith("boundary[0] and boundary[1]: both prescribe u_x at 9 shared dofs of 'xmin' and "
                              "'xmin', with different values"), message
    assert "0 and 0.1 at load factor 1" in message


def test_an_expression_of_t_that_differs_only_at_half_load_is_refused() -> None:
    # 0.1 (t - 1) agrees with 0 at t = 1, not at t = 0.5: the edge x = 0, y = 0 is shared
    message = refused(CLAMP, {"on": "ymin", "type": "displacement", "components": [1], "expression": ["0.1*(t-1)"]})
    assert message.startswith("boundary[0] and boundary[1]: both prescribe u_y at 3 shared dofs of 'xmin' and "
                              "'ymin'"), message
    assert "0 and -0.05 at load factor 0.5" in message


def test_agreeing_conditions_on_a_shared_edge_pass() -> None:
    build_with(CLAMP, {"on": "ymin", "type": "displacement", "components": [1], "value": [0.0]},
               {"on": "zmin", "type": "displacement", "components": [2], "expression": ["0.1*x[0]*t"]},
               {"on": "xmax", "type": "traction", "value": [10.0, 0.0, 0.0]})


def test_a_traction_along_a_prescribed_direction_is_refused() -> None:
    message = refused(CLAMP, {"on": "xmin", "type": "traction", "value": [0.0, 5.0, 0.0]})
    assert message.startswith("boundary[1] and boundary[0]: the load on 'xmin' and the condition on 'xmin' share 8 "
                              "facets, where u_x/y/z is prescribed, so its t_y would be silently dropped"), message
    # across the prescribed direction it acts: accepted
    build_with({"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
               {"on": "xmin", "type": "traction", "value": [0.0, 5.0, 0.0]}, {**CLAMP, "on": "ymin"})


def test_a_pressure_on_a_face_held_along_its_normal_is_refused_a_roller_is_not() -> None:
    message = refused({"on": "xmin", "type": "displacement", "components": [0], "value": [0.0]},
                      {"on": "xmin", "type": "pressure", "value": 1.0}, {**CLAMP, "on": "ymin"})
    assert message.startswith("boundary[1] and boundary[0]: the load on 'xmin' and the condition on 'xmin' share 8 "
                              "facets, where u_x is prescribed, so the part of the pressure along the prescribed x "
                              "would be silently dropped"), message
    build_with({"on": "xmin", "type": "displacement", "components": [1], "value": [0.0]},
               {"on": "xmin", "type": "pressure", "value": 1.0}, {**CLAMP, "on": "ymin"})


def test_a_prescribed_value_that_is_not_finite_is_refused() -> None:
    message = refused(CLAMP, {"on": "xmax", "type": "displacement", "components": [0], "expression": ["log(-t)"]})
    assert message.startswith("boundary[1]: u_x on 'xmax' is nan at [1, "), message
    assert message.endswith("at load factor 1: a prescribed value must be a finite number at every node")
