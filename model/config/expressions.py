"""Scalar expressions of position x = (x[0], x[1], x[2]) and load factor t written in config files.

Example: "0.1*x[0] + 0.05*x[1]", a twist "x[1]*cos(t*pi/2) - x[2]*sin(t*pi/2) - x[1]", or a ramp
that stops half-way "0.01*minimum(2*t, 1)".
An expression that does not mention t is scaled by the load factor like a constant
value; one that mentions t is evaluated at t = load factor and not scaled.

Only arithmetic, numbers, x[i], the names of the configuration's [parameters] table
(e.g. ``stretch = 1.2`` there and "(stretch - 1)*0.04*t" here: a sweep varies the parameter)
and the numpy functions in ALLOWED are accepted; anything else (attribute access, other
names, calls of other functions) is rejected when the configuration is checked, before any solve.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Mapping

import numpy as np

ALLOWED: dict[str, object] = {
    name: getattr(np, name)
    for name in ("sin", "cos", "tan", "exp", "log", "sqrt", "abs", "arctan2", "sinh", "cosh", "tanh", "pi",
                 "minimum", "maximum")
}
#: names an expression always has: a [parameters] name may not be one of them
RESERVED = frozenset({"x", "t", *ALLOWED})
_NODES = (ast.Expression, ast.BinOp, ast.UnaryOp, ast.Constant, ast.Name, ast.Load, ast.Subscript, ast.Call,
          ast.operator, ast.unaryop)


class _FloatLiterals(ast.NodeTransformer):
    """Integer constants -> floats, except the indices of x[i]."""

    def visit_Subscript(self, node: ast.Subscript) -> ast.Subscript:
        return node

    def visit_Constant(self, node: ast.Constant) -> ast.Constant:
        if type(node.value) is int:
            return ast.copy_location(ast.Constant(float(node.value)), node)
        return node


def uses_load_factor(text: str) -> bool:
    """True when the expression mentions the load factor t."""
    return "t" in names_used(text)


def names_used(text: str) -> set[str]:
    """The names an expression mentions (x, t, functions and parameters alike)."""
    return {n.id for n in ast.walk(ast.parse(text, mode="eval")) if isinstance(n, ast.Name)}


def compile_expression(text: str, parameters: Mapping[str, float] | None = None) -> Callable[..., np.ndarray]:
    """A function f(x, t=1.0) -> values for x of shape (3, n), from the text; ValueError if not allowed.

    ``parameters``: the named numbers the text may use besides x and t (the [parameters] table).
    """
    parameters = dict(parameters or {})
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as err:
        raise ValueError(f"invalid expression {text!r}: {err.msg}") from None
    for node in ast.walk(tree):
        if not isinstance(node, _NODES):
            raise ValueError(f"invalid expression {text!r}: {type(node).__name__} is not allowed")
        if isinstance(node, ast.Name) and node.id not in RESERVED and node.id not in parameters:
            known = f", or a [parameters] name: {', '.join(sorted(parameters))}" if parameters else ""
            raise ValueError(f"invalid expression {text!r}: unknown name {node.id!r} (use x[0], x[1], x[2], t{known})")
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in ALLOWED):
            raise ValueError(f"invalid expression {text!r}: only {', '.join(sorted(ALLOWED))} may be called")
        if isinstance(node, ast.Subscript) and not (
                isinstance(node.value, ast.Name) and node.value.id == "x" and isinstance(node.slice, ast.Constant)
                and type(node.slice.value) is int and node.slice.value in (0, 1, 2)):
            raise ValueError(f"invalid expression {text!r}: only x[0], x[1] and x[2] may be indexed")
    # integer literals become floats, so "9**9**9**9" overflows at once instead of computing a huge integer
    code = compile(ast.fix_missing_locations(_FloatLiterals().visit(tree)), "<expression>", "eval")

    def evaluate(x: np.ndarray, t: float = 1.0) -> np.ndarray:
        value = eval(code, {"__builtins__": {}}, {**parameters, "x": x, "t": t, **ALLOWED})  # noqa: S307 - checked AST above
        return np.broadcast_to(np.asarray(value, dtype=np.float64), x.shape[1:]).copy()

    try:
        evaluate(np.zeros((3, 1)))
    except Exception as err:  # noqa: BLE001 - any evaluation error is a config error
        raise ValueError(f"invalid expression {text!r}: {err}") from None
    return evaluate
