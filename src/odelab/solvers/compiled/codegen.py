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

import numpy as np

from odelab.expressions.compile import _check_argument_name, _operands
from odelab.expressions.functions import _BINARY, _COMPARATORS, _UNARY, CONSTANTS, FUNCTIONS
from odelab.expressions.parse import ParsedExpression, python_name

__all__ = ["PRELUDE", "CS_PRELUDE", "equations_source", "events_source", "jacobian_source", "linear_jacobian_source",
           "linear_source"]

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


def _bind_pow():
    # C's pow, called by name: numpy's scalar `**` (the Python path's right-hand side) calls it, while
    # numba's `**` lets LLVM rewrite pow(x, 2.0) as x*x, which can differ from it by a rounding
    import ctypes
    import ctypes.util

    import llvmlite.binding as ll

    libm = ctypes.CDLL(ctypes.util.find_library("m") or "libm.so.6")
    ll.add_symbol("odelab_pow", ctypes.cast(libm.pow, ctypes.c_void_p).value)


_bind_pow()
_pow = _types.ExternalFunction("odelab_pow", _types.float64(_types.float64, _types.float64))


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


@_njit(cache=True, error_model="numpy")
def _minn(args):
    out = args[0]
    for i in range(1, len(args)):
        out = _min(out, args[i])
    return out


@_njit(cache=True, error_model="numpy")
def _maxn(args):
    out = args[0]
    for i in range(1, len(args)):
        out = _max(out, args[i])
    return out


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


NESTED_MAX = 8  # min/max of more arguments take them as one tuple (see fold)


def fold(helper: str, parts: list[str], cast: str = "") -> str:
    """``min``/``max`` of several arguments, left to right as numpy's reduction: nested pairs for a
    few, and for more than :data:`NESTED_MAX` one call of the ``n``-ary helper on a tuple
    (``_maxn((a, b, ...))``), which folds them in a loop. Nested, 600 arguments made 599 calls
    deep, past what Python's compiler takes ("too many nested parentheses"), and inlined they
    took numba minutes to compile (a balanced tree of 600 inlined calls: 350 s; the tuple: 8 s).
    ``cast`` wraps each argument (``complex``: the complex-step helpers take one type)."""
    if len(parts) > NESTED_MAX:
        items = ", ".join(f"{cast}({p})" if cast else p for p in parts)
        return f"{helper}n(({items},))"
    text = parts[0]
    for part in parts[1:]:
        text = f"{helper}({text}, {part})"
    return text


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
            return f"_pow({parts[0]}, {parts[1]})"
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
        if name in ("min", "max"):
            return fold(helper, parts)
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


# --- The exact Jacobian by complex step, in generated code --------------------------------------
#
# odelab.systems.jacobian.complex_step_jacobian (the Python path's Jacobian of an expression
# system) evaluates the equations at y + i h e_j with h = 1e-200 and the expression compiler's
# complex-step functions (odelab.expressions.functions: elementary functions as
# f(x) + i f'(x) h, non-smooth ones on the real part, comparisons of real parts). The same rules
# are written here for numba, so both paths form the same Jacobian to rounding: column j is
# Im f(y + i h e_j) / h, one complex evaluation of the equations per column. Where numpy divides
# complex numbers (any operand depending on t or a state is complex there) it uses Smith's
# algorithm with a reciprocal (numpy's loops), so `_cdiv` does too.

CS_STEP = 1e-200  # odelab.systems.jacobian._H

CS_PRELUDE = '''
_JAC = _types.void(_types.float64, _V, _V, _types.float64[:, ::1])  # JAC of loops/stiff.py.txt
_LN10 = 2.302585092994046


@_njit(cache=True, error_model="numpy", inline="always")
def _cdiv(a, b):
    ar, ai, br, bi = a.real, a.imag, b.real, b.imag
    abr, abi = abs(br), abs(bi)
    if abr >= abi:
        if abr == 0.0 and abi == 0.0:
            return complex(ar / abr, ai / abr)
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return complex((ar + ai * rat) * scl, (ai - ar * rat) * scl)
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return complex((ar * rat + ai) * scl, (ai * rat - ar) * scl)


@_njit(cache=True, error_model="numpy", inline="always")
def _lin(fx, dfx, h):
    return complex(fx, 0.0 if h == 0.0 else dfx * h)


@_njit(cache=True, error_model="numpy", inline="always")
def _cpow(z, w):
    a, b, c, d = z.real, z.imag, w.real, w.imag
    value = _np.power(a, c)
    by_base = 0.0 if (b == 0.0 or c == 0.0) else c * _np.power(a, c - 1.0) * b
    by_exponent = 0.0 if d == 0.0 else value * _np.log(a) * d
    return complex(value, by_base + by_exponent)


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_atan2(y, x):
    yr, yi, xr, xi = y.real, y.imag, x.real, x.imag
    value = _np.arctan2(yr, xr)
    if yi == 0.0 and xi == 0.0:
        return complex(value, 0.0)
    return complex(value, (xr * yi - yr * xi) / (xr * xr + yr * yr))


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_abs(z):
    return complex(z) if z.real >= 0.0 else complex(-z)


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_min(a, b):
    return complex(b) if (b.real != b.real or b.real < a.real) else complex(a)


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_max(a, b):
    return complex(b) if (b.real != b.real or b.real > a.real) else complex(a)


@_njit(cache=True, error_model="numpy")
def _cs_minn(args):
    out = args[0]
    for i in range(1, len(args)):
        out = _cs_min(out, args[i])
    return out


@_njit(cache=True, error_model="numpy")
def _cs_maxn(args):
    out = args[0]
    for i in range(1, len(args)):
        out = _cs_max(out, args[i])
    return out


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_where(c, a, b):
    return complex(a) if c.real != 0.0 else complex(b)


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_mod(a, m):
    ar, mr, ai, mi = a.real, m.real, a.imag, m.imag
    value = _mod(ar, mr)
    k = _np.floor(ar / mr)
    return complex(value, ai + (0.0 if mi == 0.0 else -k * mi))


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_rem(a, m):
    ar, mr, ai, mi = a.real, m.real, a.imag, m.imag
    value = _rem(ar, mr)
    k = _np.trunc(ar / mr)
    return complex(value, ai + (0.0 if mi == 0.0 else -k * mi))


@_njit(cache=True, error_model="numpy", inline="always")
def _cs_sawtooth(t, width=1.0):
    tr, ti, w = t.real, t.imag, width.real
    value = _sawtooth(tr, w)
    if ti == 0.0:
        return complex(value, 0.0)
    phase = _np.mod(tr, 2.0 * _np.pi)
    slope = 1.0 / (_np.pi * w) if (phase < 2.0 * _np.pi * w or w >= 1.0) else -1.0 / (_np.pi * (1.0 - w))
    return complex(value, slope * ti)
'''

# f(x) + i f'(x) h: the derivative's source in the real part `_x` (expressions.functions' rules)
_LINEARISED = {
    "sin": ("_np.sin(_x)", "_np.cos(_x)"), "cos": ("_np.cos(_x)", "(-_np.sin(_x))"),
    "tan": ("_np.tan(_x)", "(1.0 / (_np.cos(_x) * _np.cos(_x)))"),
    "asin": ("_np.arcsin(_x)", "(1.0 / _np.sqrt(1.0 - _x * _x))"),
    "acos": ("_np.arccos(_x)", "(-1.0 / _np.sqrt(1.0 - _x * _x))"),
    "atan": ("_np.arctan(_x)", "(1.0 / (1.0 + _x * _x))"),
    "sinh": ("_np.sinh(_x)", "_np.cosh(_x)"), "cosh": ("_np.cosh(_x)", "_np.sinh(_x)"),
    "tanh": ("_np.tanh(_x)", "(1.0 / (_np.cosh(_x) * _np.cosh(_x)))"),
    "exp": ("_np.exp(_x)", "_np.exp(_x)"), "log": ("_np.log(_x)", "(1.0 / _x)"),
    "log10": ("_np.log10(_x)", "(1.0 / (_x * _LN10))"), "sqrt": ("_np.sqrt(_x)", "(0.5 / _np.sqrt(_x))"),
}
_ON_REAL_PART = {"sign": "_np.sign", "floor": "_np.floor", "ceil": "_np.ceil", "heaviside": "_heaviside",
                 "step": "_step", "square": "_square"}
_CS_HELPERS = {"atan2": "_cs_atan2", "abs": "_cs_abs", "min": "_cs_min", "max": "_cs_max", "where": "_cs_where",
               "mod": "_cs_mod", "rem": "_cs_rem", "sawtooth": "_cs_sawtooth"}
assert set(_LINEARISED) | set(_ON_REAL_PART) | set(_CS_HELPERS) == set(FUNCTIONS)


def _cs_node(node: ast.AST, parts: list[tuple[str, bool]], perturbed: frozenset[str], free: frozenset[str],
             lines: list[str], rename: dict[str, str]) -> tuple[str, bool]:
    """One node of the complex-step evaluation: (source, complex?). A value is complex where
    numpy's would be (it involves t or a state); `lines` receives helper statements; `rename`
    maps the states to their complex values."""
    texts = [p[0] for p in parts]
    cplx = any(p[1] for p in parts)
    if isinstance(node, ast.Name) and not (node.id in CONSTANTS and node.id not in free):
        _check_argument_name(node.id, "an argument")
        return rename.get(node.id, node.id), node.id in perturbed
    if isinstance(node, ast.Attribute):
        name = f"{node.value.id}.{node.attr}"
        _check_argument_name(name, "an argument")
        return rename.get(name, python_name(name)), name in perturbed
    if isinstance(node, (ast.Constant, ast.Name)):
        return _node(node, [], None, free), False
    if isinstance(node, ast.BinOp):
        if isinstance(node.op, ast.Pow):
            return f"_cpow({texts[0]}, {texts[1]})", True
        if isinstance(node.op, ast.Div) and cplx:
            return f"_cdiv({texts[0]}, {texts[1]})", True
        return f"({texts[0]} {_BINARY[type(node.op)]} {texts[1]})", cplx
    if isinstance(node, ast.UnaryOp):
        return f"({_UNARY[type(node.op)]}{texts[0]})", cplx
    if isinstance(node, ast.Compare):
        tests = [f"(({left}).real {_COMPARATORS[type(op)][0]} ({right}).real)"
                 for left, op, right in zip(texts[:-1], node.ops, texts[1:])]
        return f"(1.0 if {' and '.join(tests)} else 0.0)", False
    if isinstance(node, ast.Call):
        name = node.func.id
        if name in _LINEARISED:
            if not cplx:
                return _node(node, texts, None, free), False
            k = len(lines)
            f, df = _LINEARISED[name]
            lines.append(f"_w{k} = {texts[0]}")
            lines.append(f"_x = _w{k}.real")
            lines.append(f"_w{k} = _lin({f}, {df}, _w{k}.imag)")
            return f"_w{k}", True
        if name in _ON_REAL_PART:
            return f"{_ON_REAL_PART[name]}({', '.join(f'({t}).real' for t in texts)})", False
        helper = _CS_HELPERS[name]
        if name in ("min", "max"):
            return fold(helper, texts, cast="complex"), True
        return f"{helper}({', '.join(texts)})", True
    raise AssertionError(f"unvalidated node {type(node).__name__}")  # pragma: no cover


def complex_step_source(parsed: ParsedExpression, perturbed: frozenset[str], lines: list[str],
                        rename: dict[str, str]) -> str:
    """``parsed`` evaluated in complex-step arithmetic (post-order, no recursion); statements
    for linearised functions go to ``lines``, the expression's source is returned."""
    code: dict[int, tuple[str, bool]] = {}
    stack: list[tuple[ast.AST, bool]] = [(parsed.tree.body, False)]
    while stack:
        node, ready = stack.pop()
        if not ready:
            stack.append((node, True))
            stack.extend((child, False) for child in _operands(node))
            continue
        code[id(node)] = _cs_node(node, [code[id(c)] for c in _operands(node)], perturbed, parsed.names, lines,
                                  rename)
    return code[id(parsed.tree.body)][0]


def jacobian_source(states: Sequence[str], parameters: Sequence[str], equations: Sequence[ParsedExpression]) -> str:
    """``jac(t, _y, _p, _J)``: ``_J[i, j] = d equations[i] / d states[j]`` by complex step, as
    :func:`odelab.systems.jacobian.complex_step_jacobian` (every state a complex ``y + 0.0``,
    the state differentiated perturbed by ``i h``), for the entries that can be nonzero only:
    those where equation i names state j. The others are not written (the caller zeroes
    ``_J`` once): their imaginary part is exactly 0.

    Columns that no equation names together (structurally orthogonal: Curtis, Powell & Reid
    1974, :func:`odelab.solvers.numjac.column_groups`) are perturbed together, and each
    equation is evaluated once per group that holds a state it names: that evaluation reads
    the one perturbed state it names and the real values of the others, the same expression
    with the same inputs as the column's own evaluation, so each entry is the full complex
    step's to the bit, at the cost of one evaluation per structural nonzero (a chain of 100
    masses: 696 of 40,000 entries, 6 groups)."""
    from odelab.solvers.banded import structural_pattern
    from odelab.solvers.numjac import column_groups

    for name in (*states, *parameters):
        _check_argument_name(name, "an argument")
    n = len(states)
    pattern = structural_pattern([p.names for p in equations], states)
    groups = column_groups(pattern) if pattern.any() else []
    which = np.full((max(len(groups), 1), n), -1, dtype=np.int64)  # the column equation i takes in group g
    for g, members in enumerate(groups):
        for j in members:
            which[g, np.nonzero(pattern[:, j])[0]] = j
    members = [int(j) for g in groups for j in g]
    starts = np.cumsum([0] + [len(g) for g in groups]).tolist()
    lines = [f"_JAC_MEMBERS = _np.array({members!r}, dtype=_np.int64)",
             f"_JAC_STARTS = _np.array({starts!r}, dtype=_np.int64)",
             f"_JAC_WHICH = _np.array({which.ravel().tolist()!r}, dtype=_np.int64).reshape({which.shape[0]}, {n})",
             "", "",
             "@_njit(_JAC, cache=True, error_model=\"numpy\")", "def jac(t, _y, _p, _J):"]
    lines += [f"    {name} = _p[{i}]" for i, name in enumerate(parameters)]
    rename = {name: f"_z[{i}]" for i, name in enumerate(states)}
    lines += ["    t = complex(t, 0.0)", f"    _z = _np.empty({n}, dtype=_np.complex128)", f"    for _i in range({n}):",
              "        _z[_i] = complex(_y[_i] + 0.0, 0.0)", f"    for _g in range({len(groups)}):",
              "        for _m in range(_JAC_STARTS[_g], _JAC_STARTS[_g + 1]):",
              f"            _z[_JAC_MEMBERS[_m]] = complex(_y[_JAC_MEMBERS[_m]] + 0.0, {CS_STEP!r})",
              "        _c = _JAC_WHICH[_g]"]
    perturbed = frozenset({"t", *states})
    for i, p in enumerate(equations):
        if not pattern[i].any():
            continue
        helpers: list[str] = []
        text = complex_step_source(p, perturbed, helpers, rename)
        lines.append(f"        if _c[{i}] >= 0:")
        lines += [f"            {line}" for line in helpers]
        lines.append(f"            _J[{i}, _c[{i}]] = complex({text}).imag / {CS_STEP!r}")
    lines += ["        for _m in range(_JAC_STARTS[_g], _JAC_STARTS[_g + 1]):",
              "            _z[_JAC_MEMBERS[_m]] = complex(_y[_JAC_MEMBERS[_m]] + 0.0, 0.0)"]
    return "\n".join(lines) + "\n"


def linear_jacobian_source() -> str:
    """``jac`` of x' = A x: A, row-major at the start of ``_p``."""
    return '''\
@_njit(_JAC, cache=True, error_model="numpy")
def jac(t, _y, _p, _J):
    n = _y.shape[0]
    for i in range(n):
        for j in range(n):
            _J[i, j] = _p[i * n + j]
'''
