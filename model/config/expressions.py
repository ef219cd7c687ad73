"""Scalar expressions of position x = (x[0], x[1], x[2]) and load factor t written in config files.

Example: "0.1*x[0] + 0.05*x[1]", a twist "x[1]*cos(t*pi/2) - x[2]*sin(t*pi/2) - x[1]", or a ramp
that stops half-way "0.01*minimum(2*t, 1)".
An expression that does not mention t is scaled by the load factor like a constant
value; one that mentions t is evaluated at t = load factor and not scaled.

Only arithmetic, numbers, x[i], the names of the configuration's [parameters] table
(e.g. ``stretch = 1.2`` there and "(stretch - 1)*0.04*t" here: a sweep varies the parameter)
and the numpy functions in ALLOWED are accepted; anything else (attribute access, other
names, calls of other functions) is rejected when the configuration is checked, before any solve, and
so is an expression too deep or too long to be a formula: more than MAX_LENGTH characters or nested more
than MAX_DEPTH levels (a sum of n terms is n levels deep), "expression too deep/long".
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
#: the longest expression accepted, in characters
MAX_LENGTH = 10_000
#: the deepest nesting of its syntax tree accepted (a sum of n terms, n nested calls or parentheses: n levels)
MAX_DEPTH = 200
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


def _shown(text: str) -> str:
    """The expression as a message quotes it: a long one shortened."""
    return repr(text) if len(text) <= 80 else f"{text[:60]!r}... ({len(text)} characters)"


def _depth(tree: ast.AST) -> int:
    """How deep the syntax tree nests (iteratively: a deep tree must not exhaust the stack here)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return deepest


def parse(text: str) -> ast.Expression:
    """The syntax tree of an expression; ValueError for one that is not an expression or too deep/long."""
    if len(text) > MAX_LENGTH:
        raise ValueError(f"expression too deep/long: {len(text)} characters, at most {MAX_LENGTH}: {_shown(text)}")
    try:
        tree = ast.parse(text, mode="eval")
    except (RecursionError, MemoryError):
        raise ValueError(f"expression too deep/long: nested too deeply to read: {_shown(text)}") from None
    except SyntaxError as err:
        if "too many nested" in str(err.msg) or "too complex" in str(err.msg):
            raise ValueError(f"expression too deep/long: {err.msg}: {_shown(text)}") from None
        raise ValueError(f"invalid expression {_shown(text)}: {err.msg}") from None
    depth = _depth(tree)
    if depth > MAX_DEPTH:
        raise ValueError(f"expression too deep/long: nested {depth} levels deep, at most {MAX_DEPTH} (a sum of n "
                         f"terms is n levels): {_shown(text)}")
    return tree


def uses_load_factor(text: str) -> bool:
    """True when the expression mentions the load factor t."""
    return "t" in names_used(text)


def names_used(text: str) -> set[str]:
    """The names an expression mentions (x, t, functions and parameters alike)."""
    return {n.id for n in ast.walk(parse(text)) if isinstance(n, ast.Name)}


def compile_expression(text: str, parameters: Mapping[str, float] | None = None) -> Callable[..., np.ndarray]:
    """A function f(x, t=1.0) -> values for x of shape (3, n), from the text; ValueError if not allowed.

    ``parameters``: the named numbers the text may use besides x and t (the [parameters] table).
    """
    parameters = dict(parameters or {})
    tree = parse(text)
    shown = _shown(text)
    for node in ast.walk(tree):
        if not isinstance(node, _NODES):
            raise ValueError(f"invalid expression {shown}: {type(node).__name__} is not allowed")
        if isinstance(node, ast.Name) and node.id not in RESERVED and node.id not in parameters:
            known = f", or a [parameters] name: {', '.join(sorted(parameters))}" if parameters else ""
            raise ValueError(f"invalid expression {shown}: unknown name {node.id!r} (use x[0], x[1], x[2], t{known})")
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in ALLOWED):
            raise ValueError(f"invalid expression {shown}: only {', '.join(sorted(ALLOWED))} may be called")
        if isinstance(node, ast.Subscript) and not (
                isinstance(node.value, ast.Name) and node.value.id == "x" and isinstance(node.slice, ast.Constant)
                and type(node.slice.value) is int and node.slice.value in (0, 1, 2)):
            raise ValueError(f"invalid expression {shown}: only x[0], x[1] and x[2] may be indexed")
    # integer literals become floats, so "9**9**9**9" overflows at once instead of computing a huge integer
    try:
        code = compile(ast.fix_missing_locations(_FloatLiterals().visit(tree)), "<expression>", "eval")
    except (RecursionError, MemoryError):
        raise ValueError(f"expression too deep/long: nested too deeply to compile: {shown}") from None

    def evaluate(x: np.ndarray, t: float = 1.0) -> np.ndarray:
        with np.errstate(all="ignore"):  # NaN / inf are values for the caller to check (Python 3.13's warning
            # machinery needs __import__, which the evaluation's empty builtins do not have: a warning would fail it)
            value = eval(code, {"__builtins__": {}}, {**parameters, "x": x, "t": t, **ALLOWED})  # noqa: S307
        return np.broadcast_to(np.asarray(value, dtype=np.float64), x.shape[1:]).copy()

    try:
        evaluate(np.zeros((3, 1)))
    except RecursionError:
        raise ValueError(f"expression too deep/long: nested too deeply to evaluate: {shown}") from None
    except Exception as err:  # noqa: BLE001 - any evaluation error is a config error
        raise ValueError(f"invalid expression {shown}: {' '.join(str(err).split())}") from None
    return evaluate
