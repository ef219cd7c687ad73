"""[parameters]: named numbers the expressions use, so that a sweep or an override varies one number.

examples/force_length_cylinder.toml moves its top by "(stretch - 1)*0.04*minimum(2*t, 1)" with
stretch = 1.2 in [parameters]; test_muscle_experiments runs it at six stretches (model.experiments.muscle.
with_stretch sets parameters.stretch) against the closed-form force-length curve.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT, example

from model.config import load, parse
from model.config.expressions import compile_expression
from model.errors import ConfigError

EXAMPLE = ROOT / "examples" / "force_length_cylinder.toml"


def _top_expression(config) -> str:
    return next(b for b in config.boundaries if b.on == "top" and b.type == "displacement").expression[0]


def test_an_expression_sees_the_parameters() -> None:
    config = load(EXAMPLE)
    assert config.parameters == {"stretch": 1.2}
    f = compile_expression(_top_expression(config), config.parameters)
    assert f(np.zeros((3, 2)), t=0.25)[0] == pytest.approx(0.2 * 0.04 * 0.5)
    assert f(np.zeros((3, 2)), t=1.0)[0] == pytest.approx(0.2 * 0.04)


def test_an_override_of_a_parameter_changes_the_expression() -> None:
    config = load(EXAMPLE, {"parameters.stretch": 0.7})
    f = compile_expression(_top_expression(config), config.parameters)
    assert f(np.zeros((3, 1)), t=1.0)[0] == pytest.approx(-0.3 * 0.04)
    assert config.document["parameters"] == {"stretch": 0.7}  # summary.json's config records it


@pytest.mark.parametrize(("table", "message"), [
    ({"stretch": "long"}, "parameters.stretch: must be a number, got 'long'"),
    ({"stretch": True}, "parameters.stretch: must be a number, got True"),
    ({"stretch": float("inf")}, "parameters.stretch: must be finite"),
    ({"t": 1.0, "stretch": 1.0}, "parameters.t: 't' is taken: expressions already use"),
    ({"sin": 1.0, "stretch": 1.0}, "parameters.sin: 'sin' is taken"),
    ({"2l": 1.0, "stretch": 1.0}, "parameters.2l: '2l' is not a name an expression can use"),
    ({"stretch": 1.0, "strech": 1.1}, "parameters.strech: no expression uses it (they use: stretch)"),
    ({"lenght": 1.1}, "boundary[1].expression[0]: invalid expression '(stretch - 1)*0.04*minimum(2*t, 1)': "
                      "unknown name 'stretch' (use x[0], x[1], x[2], t, or a [parameters] name: lenght)"),
    ([1.2], "parameters: must be a table"),
])
def test_parameter_errors_name_the_key(table: object, message: str) -> None:
    raw = example("force_length_cylinder")
    raw["parameters"] = table
    with pytest.raises(ConfigError) as err:
        parse(raw, EXAMPLE.parent)
    assert str(err.value).startswith(message), str(err.value)
    assert "\n" not in str(err.value)


def test_without_parameters_an_unknown_name_says_what_expressions_use() -> None:
    raw = example("force_length_cylinder")
    del raw["parameters"]
    with pytest.raises(ConfigError, match=r"unknown name 'stretch' \(use x\[0\], x\[1\], x\[2\], t\)$"):
        parse(raw, EXAMPLE.parent)


def test_a_misspelt_override_is_refused_before_any_run() -> None:
    with pytest.raises(ConfigError, match="^parameters.strech: no expression uses it"):
        load(EXAMPLE, {"parameters.strech": 1.1})
