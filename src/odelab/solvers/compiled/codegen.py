"""Numba source for a right-hand side, generated from checked expressions or a matrix.

The generated text is built only from what the expression language has already validated:
ASTs that passed :func:`odelab.expressions.parse_expression`'s whitelist (numbers, names,
``+ - * / **``, comparisons and the language's functions), names re-checked as identifiers
that do not start with ``_``, and numbers written with ``repr(float)``. No user text is ever
pasted into the source, as in :func:`odelab.expressions.compile_expression`.

Each function of the language maps to the numpy function numba compiles (the same IEEE
semantics: ``1/0`` is inf, ``sqrt(-1)`` NaN, comparisons give 1.0/0.0); ``heaviside``,
``step``, ``min``, ``max`` and ``where`` are small helpers below with numpy's NaN rules.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Sequence

from odelab.expressions.compile import _check_argument_name, _operands
from odelab.expressions.functions import _BINARY, _COMPARATORS, _UNARY, CONSTANTS, FUNCTIONS
from odelab.expressions.parse import ParsedExpression, python_name

__all__ = ["PRELUDE", "equations_source", "events_source", "linear_source"]

_NUMPY = {
    "sin": "sin", "cos": "cos", "tan": "tan", "asin": "arcsin", "acos": "arccos", "atan": "arctan",
    "atan2": "arctan2", "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "exp": "exp", "log": "log",
    "log10": "log10", "sqrt": "sqrt", "abs": "abs", "sign": "sign", "floor": "floor", "ceil": "ceil",
}
_HELPERS = {"heaviside": "_heaviside", "step": "_step", "where": "_where", "min": "_min", "max": "_max",
            "mod": "_mod", "rem": "_rem", "square": "_square", "sawtooth": "_sawtooth"}
assert set(_NUMPY) | set(_HELPERS) == set(FUNCTIONS)

PRELUDE = '''\
import numpy as _np
from numba import njit as _njit
from numba import types as _types

_V = _types.float64[::1]
_RHS = _types.void(_types.float64, _V, _V, _V)  # kernels.RHS

_INF = _np.inf
_NAN = _np.nan


@_njit(cache=True, error_model="numpy", inline="always")
def _heaviside(x):
    return 0.0 if x < 0.0 else (0.5 if x == 0.0 else (1.0 if x > 0.0 else x))


@_njit(cache=True, error_model="numpy", inline="always")
def _step(x):
    return 0.0 if x < 0.0 else (1.0 if x >= 0.0 else x)


@_njit(cache=True, error_model="numpy", inline="always")
def _where(c, a, b):
    return a if c != 0.0 else b


@_njit(cache=True, error_model="numpy", inline="always")
def _min(a, b):
    if a != a or b != b:
        return a + b
    return a if a <= b else b


@_njit(cache=True, error_model="numpy", inline="always")
def _max(a, b):
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@_njit(cache=True, error_model="numpy", inline="always")
def _mod(a, m):
    return a if m == 0.0 else _np.mod(a, m)


@_njit(cache=True, error_model="numpy", inline="always")
def _rem(a, b):
    return _np.fmod(a, b)


@_njit(cache=True, error_model="numpy", inline="always")
def _square(t, duty=50.0):
    return 1.0 if _np.mod(t, 2.0 * _np.pi) < 2.0 * _np.pi * duty / 100.0 else -1.0


@_njit(cache=True, error_model="numpy", inline="always")
def _sawtooth(t, width=1.0):
    phase = _np.mod(t, 2.0 * _np.pi)
    if phase < 2.0 * _np.pi * width or width >= 1.0:
        return phase / (_np.pi * width) - 1.0
    return 1.0 - (phase - 2.0 * _np.pi * width) / (_np.pi * (1.0 - width))
'''


def _number(value: float) -> str:
    if math.isnan(value):
        return "_NAN"
    if math.isinf(value):
        return "_INF" if value > 0 else "(-_INF)"
    return repr(float(value))


def _node(node: ast.AST, parts: list[str], rename: dict[str, str] | None = None,
          free: frozenset[str] = frozenset()) -> str:
    if isinstance(node, ast.Constant):
        try:
            return _number(float(node.value))
        except OverflowError:  # an integer literal beyond the float range
            return "_INF"
    if isinstance(node, ast.Name):
        if node.id in CONSTANTS and node.id not in free:  # a bound name shadows it (shadowed_constants)
            return _number(CONSTANTS[node.id])
        _check_argument_name(node.id, "an argument")
        return rename.get(node.id, node.id) if rename else node.id
    if isinstance(node, ast.Attribute):  # a dotted name (a network's `mass.x`), validated by the parser
        name = f"{node.value.id}.{node.attr}"
        _check_argument_name(name, "an argument")
        return rename.get(name, python_name(name)) if rename else python_name(name)
    if isinstance(node, ast.BinOp):
        if isinstance(node.op, ast.Pow):  # numba would fold `(-1.0) ** 0.5` to a complex constant
            return f"_np.power({parts[0]}, {parts[1]})"
        return f"({parts[0]} {_BINARY[type(node.op)]} {parts[1]})"
    if isinstance(node, ast.UnaryOp):
        return f"({_UNARY[type(node.op)]}{parts[0]})"
    if isinstance(node, ast.Compare):
        tests = [f"({left} {_COMPARATORS[type(op)][0]} {right})"
                 for left, op, right in zip(parts[:-1], node.ops, parts[1:])]
        return f"(1.0 if {' and '.join(tests)} else 0.0)"
    if isinstance(node, ast.Call):
        name = node.func.id
        if name in _NUMPY:
            return f"_np.{_NUMPY[name]}({', '.join(parts)})"
        helper = _HELPERS[name]
        if name in ("min", "max"):  # variadic: nested pairs, left to right as numpy's reduction
            text = parts[0]
            for part in parts[1:]:
                text = f"{helper}({text}, {part})"
            return text
        return f"{helper}({', '.join(parts)})"
    raise AssertionError(f"unvalidated node {type(node).__name__}")  # pragma: no cover


def expression_source(parsed: ParsedExpression, rename: dict[str, str] | None = None) -> str:
    """One validated expression as numba-compatible Python source (post-order, no recursion);
    ``rename`` maps names to the source that stands for them (``t`` -> ``_tu``...). A constant
    among the free names of ``parsed`` (bound by :meth:`~ParsedExpression.binding`: a parameter
    ``e``) is a variable."""
    code: dict[int, str] = {}
    stack: list[tuple[ast.AST, bool]] = [(parsed.tree.body, False)]
    while stack:
        node, ready = stack.pop()
        if not ready:
            stack.append((node, True))
            stack.extend((child, False) for child in _operands(node))
            continue
        code[id(node)] = _node(node, [code[id(c)] for c in _operands(node)], rename, parsed.names)
    return code[id(parsed.tree.body)]


def equations_source(states: Sequence[str], parameters: Sequence[str], equations: Sequence[ParsedExpression],
                     inputs: Sequence[str] = (), input_lines: Sequence[str] = ()) -> str:
    """``rhs(t, _y, _p, _out)`` for ``d(states[i])/dt = equations[i]`` with parameters ``_p``.

    With inputs, ``_p`` starts with the clipping bounds of the inputs' time (see
    :func:`.inputs.inputs_source`, whose ``input_lines`` set ``_u0, _u1...``), then the parameters.
    """
    for name in (*states, *parameters, *inputs):
        _check_argument_name(name, "an argument")
    first = 2 if inputs else 0
    lines = ["@_njit(_RHS, cache=True, error_model=\"numpy\")", "def rhs(t, _y, _p, _out):"]
    lines += list(input_lines)
    lines += [f"    {python_name(name)} = _u{i}" for i, name in enumerate(inputs)]
    lines += [f"    {python_name(name)} = _y[{i}]" for i, name in enumerate(states)]
    lines += [f"    {name} = _p[{first + i}]" for i, name in enumerate(parameters)]
    lines += [f"    _out[{i}] = {expression_source(p)}" for i, p in enumerate(equations)]
    return "\n".join(lines) + "\n"


def events_source(states: Sequence[str], parameters: Sequence[str], whens: Sequence[ParsedExpression],
                  first: int = 0) -> str:
    """``events(t, _y, _p, _out)``: the [events] ``when`` values, parameters from ``_p[first]`` on."""
    lines = ["@_njit(_RHS, cache=True, error_model=\"numpy\")", "def events(t, _y, _p, _out):"]
    lines += [f"    {python_name(name)} = _y[{i}]" for i, name in enumerate(states)]
    lines += [f"    {name} = _p[{first + i}]" for i, name in enumerate(parameters)]
    lines += [f"    _out[{i}] = {expression_source(p)}" for i, p in enumerate(whens)]
    return "\n".join(lines) + "\n"


def linear_source(ninputs: int = 0, input_lines: Sequence[str] = ()) -> str:
    """``rhs`` for x' = A x (+ B u), A (n x n) then B (n x ninputs) row-major in the parameters
    ``_p`` (after the clipping bounds when there are inputs), as ``A @ x + B @ u``."""
    if not ninputs:
        return '''\
@_njit(_RHS, cache=True, error_model="numpy")
def rhs(t, _y, _p, _out):
    n = _y.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += _p[i * n + j] * _y[j]
        _out[i] = acc
'''
    bu = " + ".join(f"_p[_b + {k}] * _u{k}" for k in range(ninputs))
    lines = ["@_njit(_RHS, cache=True, error_model=\"numpy\")", "def rhs(t, _y, _p, _out):", *input_lines,
             "    n = _y.shape[0]",
             "    for i in range(n):",
             "        acc = 0.0",
             "        for j in range(n):",
             "            acc += _p[2 + i * n + j] * _y[j]",
             f"        _b = 2 + n * n + i * {ninputs}",
             f"        _out[i] = acc + ({bu})" if ninputs > 1 else f"        _out[i] = acc + {bu}"]
    return "\n".join(lines) + "\n"
