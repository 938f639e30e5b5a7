"""The functions and constants of the expression language, their complex-step variants,
and the namespace (numpy helpers, error-state switch) generated functions run in."""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Iterable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

# --------------------------------------------------------------------------------------------
# Functions and constants
# --------------------------------------------------------------------------------------------


def _heaviside(x):
    """MATLAB's ``heaviside``: 0 for x < 0, 0.5 at 0, 1 for x > 0."""
    return np.heaviside(x, 0.5)


def _step(x):
    """Simulink's Step block: 0 for x < 0, 1 for x >= 0 (switches at the step time)."""
    return np.heaviside(x, 1.0)


def _min(a, b, *rest):
    """Elementwise minimum of two or more values; NaN propagates (the solver must see it)."""
    result = np.minimum(a, b)
    for c in rest:
        result = np.minimum(result, c)
    return result


def _max(a, b, *rest):
    """Elementwise maximum of two or more values; NaN propagates."""
    result = np.maximum(a, b)
    for c in rest:
        result = np.maximum(result, c)
    return result


def _where(condition, a, b):
    """``a`` where ``condition`` is nonzero, else ``b`` (elementwise)."""
    return np.where(condition, a, b)


def _mod(a, m):
    """MATLAB's ``mod``: a - floor(a/m) m, with the sign of m; ``mod(a, 0)`` is a."""
    m = np.asarray(m, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(m == 0, a, np.mod(a, np.where(m == 0, 1.0, m)))


def _rem(a, b):
    """MATLAB's ``rem``: a - fix(a/b) b, with the sign of a; ``rem(a, 0)`` is NaN (C's fmod, exact)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.fmod(np.asarray(a, dtype=float), np.asarray(b, dtype=float))


def _square(t, duty=50.0):
    """MATLAB's ``square``: period 2 pi, +1 for the first ``duty`` percent of each period, else -1."""
    phase = np.mod(t, 2.0 * math.pi)
    return np.where(phase < 2.0 * math.pi * np.asarray(duty, dtype=float) / 100.0, 1.0, -1.0)


def _sawtooth(t, width=1.0):
    """MATLAB's ``sawtooth``: period 2 pi, rising from -1 to 1 over the first ``width`` of each
    period and falling back to -1 over the rest (``width = 0.5`` is a triangle wave)."""
    w = np.asarray(width, dtype=float)
    phase = np.mod(t, 2.0 * math.pi)
    with np.errstate(divide="ignore", invalid="ignore"):
        rising = phase / (math.pi * w) - 1.0
        falling = 1.0 - (phase - 2.0 * math.pi * w) / (math.pi * (1.0 - w))
    return np.where((phase < 2.0 * math.pi * w) | (w >= 1.0), rising, falling)


#: The functions an expression may call, by name (the real-valued implementations).
FUNCTIONS: Mapping[str, Callable[..., Any]] = MappingProxyType(
    {
        "sin": np.sin,
        "cos": np.cos,
        "tan": np.tan,
        "asin": np.arcsin,
        "acos": np.arccos,
        "atan": np.arctan,
        "atan2": np.arctan2,
        "sinh": np.sinh,
        "cosh": np.cosh,
        "tanh": np.tanh,
        "exp": np.exp,
        "log": np.log,
        "log10": np.log10,
        "sqrt": np.sqrt,
        "abs": np.abs,
        "sign": np.sign,
        "min": _min,
        "max": _max,
        "floor": np.floor,
        "ceil": np.ceil,
        "heaviside": _heaviside,
        "step": _step,
        "where": _where,
        "mod": _mod,
        "rem": _rem,
        "square": _square,
        "sawtooth": _sawtooth,
    }
)

#: Named constants of the language.
CONSTANTS: Mapping[str, float] = MappingProxyType({"pi": math.pi, "e": math.e})

#: Names a file may not give to a state, input, parameter or output (a parameter may take a
#: constant's name: see :func:`shadowed_constants`).
RESERVED: frozenset[str] = frozenset(FUNCTIONS) | frozenset(CONSTANTS) | {"t"}


def shadowed_constants(names: Iterable[Any]) -> frozenset[str]:
    """The constants of the language that these names shadow: the one place of the rule.

    A parameter named like a constant is a variable, and a variable shadows a constant of the
    same name, as in MATLAB (where ``pi`` is a function a variable hides, and ``e`` is nothing
    at all: the coefficient of restitution of every dynamics book is ``e``). Wherever names are
    bound (the parser's free names, the dependency order of parameters, the Python and numba
    compilers, fit, compiled inputs, the symbolic layer of networks), the expression language
    asks this function which constants are no longer constants. Functions are never shadowed:
    a parameter named ``sin`` is refused.
    """
    found = set()
    for name in names:
        if isinstance(name, str) and name in CONSTANTS:
            found.add(name)
    return frozenset(found)


def constant_values(names: Iterable[Any] = ()) -> dict[str, float]:
    """The constants still available next to ``names``: :data:`CONSTANTS` without the shadowed."""
    shadowed = shadowed_constants(names)
    return {name: value for name, value in CONSTANTS.items() if name not in shadowed}


def shadowing_note(names: Iterable[Any]) -> list[str]:
    """One sentence per shadowed constant, for a run's notes and resolved.toml:
    ``"parameter e shadows the constant e (2.718281828459045)"``."""
    return [f"parameter {name} shadows the constant {name} ({CONSTANTS[name]!r})"
            for name in sorted(shadowed_constants(names))]

# number of arguments: exact, or (minimum, None) for variadic functions
_ARITY: dict[str, int | tuple[int, None]] = {name: 1 for name in FUNCTIONS}
_ARITY.update(atan2=2, where=3, min=(2, None), max=(2, None), mod=2, rem=2, square=(1, 2), sawtooth=(1, 2))

_FUNCTION_LIST = ", ".join(FUNCTIONS)


# --------------------------------------------------------------------------------------------
# Complex-step variants
#
# The complex-step derivative f'(x) ~ Im f(x + ih)/h (Squire & Trapp, SIAM Review 40, 1998;
# Martins, Sturdza & Alonso, ACM TOMS 29, 2003) needs every operation to carry the imaginary
# part as a first-order perturbation. Elementary functions are evaluated as
# f(x) + i f'(x) h rather than with numpy's complex functions: the real part is then exactly the
# real variant's value (NaN outside the real domain instead of a complex branch value), there
# are no branch-cut or round-off surprises for a negative base, and atan2, which numpy does not
# define for complex numbers, works. Non-smooth functions use the real part (derivative 0 a.e.).
# --------------------------------------------------------------------------------------------


def _linearised(f, df):
    def g(z):
        x, h = np.real(z), np.imag(z)
        fx = f(x)
        if not np.any(h):
            return fx
        return fx + 1j * np.where(h == 0, 0.0, df(x) * h)

    g.__name__ = f"complex_step_{f.__name__}"
    return g


def _complex_power(z, w):
    a, b = np.real(z), np.imag(z)
    c, d = np.real(w), np.imag(w)
    value = np.power(a, c)
    if not (np.any(b) or np.any(d)):
        return value
    # d(a^c) = c a^(c-1) da + a^c log(a) dc, each term only where its perturbation is nonzero
    # (so that 0*inf never turns an unperturbed entry into NaN)
    by_base = np.where((b == 0) | (c == 0), 0.0, c * np.power(a, c - 1.0) * b)
    by_exponent = np.where(d == 0, 0.0, value * np.log(a) * d)
    return value + 1j * (by_base + by_exponent)


def _complex_atan2(y, x):
    yr, yi, xr, xi = np.real(y), np.imag(y), np.real(x), np.imag(x)
    value = np.arctan2(yr, xr)
    if not (np.any(yi) or np.any(xi)):
        return value
    unperturbed = (yi == 0) & (xi == 0)
    return value + 1j * np.where(unperturbed, 0.0, (xr * yi - yr * xi) / (xr * xr + yr * yr))


def _complex_abs(z):
    return np.where(np.real(z) >= 0, z, -z)


def _on_real_part(f):
    def g(*args):
        return f(*(np.real(a) for a in args))

    g.__name__ = f"complex_step_{getattr(f, '__name__', 'function')}"
    return g


def _complex_pick(better):
    def pick(a, b, *rest):
        result = a
        for c in (b, *rest):
            cr, rr = np.real(c), np.real(result)
            result = np.where(np.isnan(cr) | better(cr, rr), c, result)
        return result

    return pick


def _complex_mod(a, m, *, fix=False):
    """mod and rem are a - k m with k = floor(a/m) (fix for rem) constant between jumps."""
    ar, mr = np.real(a), np.real(m)
    value = _rem(ar, mr) if fix else _mod(ar, mr)
    ai, mi = np.imag(a), np.imag(m)
    if not (np.any(ai) or np.any(mi)):
        return value
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.trunc(ar / mr) if fix else np.floor(ar / mr)
    slope_m = np.where(mi == 0, 0.0, -k * mi)
    return value + 1j * (ai + slope_m)


def _complex_sawtooth(t, width=1.0):
    tr, ti = np.real(t), np.imag(t)
    w = np.real(width)
    value = _sawtooth(tr, w)
    if not np.any(ti):
        return value
    phase = np.mod(tr, 2.0 * math.pi)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where((phase < 2.0 * math.pi * w) | (w >= 1.0), 1.0 / (math.pi * w), -1.0 / (math.pi * (1.0 - w)))
    return value + 1j * np.where(ti == 0, 0.0, slope * ti)


def _complex_where(condition, a, b):
    return np.where(np.real(condition), a, b)


_LN10 = math.log(10.0)
_COMPLEX_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "sin": _linearised(np.sin, np.cos),
    "cos": _linearised(np.cos, lambda x: -np.sin(x)),
    "tan": _linearised(np.tan, lambda x: 1.0 / np.cos(x) ** 2),
    "asin": _linearised(np.arcsin, lambda x: 1.0 / np.sqrt(1.0 - x * x)),
    "acos": _linearised(np.arccos, lambda x: -1.0 / np.sqrt(1.0 - x * x)),
    "atan": _linearised(np.arctan, lambda x: 1.0 / (1.0 + x * x)),
    "atan2": _complex_atan2,
    "sinh": _linearised(np.sinh, np.cosh),
    "cosh": _linearised(np.cosh, np.sinh),
    "tanh": _linearised(np.tanh, lambda x: 1.0 / np.cosh(x) ** 2),
    "exp": _linearised(np.exp, np.exp),
    "log": _linearised(np.log, lambda x: 1.0 / x),
    "log10": _linearised(np.log10, lambda x: 1.0 / (x * _LN10)),
    "sqrt": _linearised(np.sqrt, lambda x: 0.5 / np.sqrt(x)),
    "abs": _complex_abs,
    "sign": _on_real_part(np.sign),
    "min": _complex_pick(np.less),
    "max": _complex_pick(np.greater),
    "floor": _on_real_part(np.floor),
    "ceil": _on_real_part(np.ceil),
    "heaviside": _on_real_part(_heaviside),
    "step": _on_real_part(_step),
    "where": _complex_where,
    "mod": _complex_mod,
    "rem": lambda a, b: _complex_mod(a, b, fix=True),
    "square": _on_real_part(_square),
    "sawtooth": _complex_sawtooth,
}
assert _COMPLEX_FUNCTIONS.keys() == FUNCTIONS.keys()


def _compare(first, *rest):
    """A comparison chain ``first op1 second op2 third ...`` as 1.0/0.0 (``rest`` = op, value, ...)."""
    result = True
    left = first
    for i in range(0, len(rest), 2):
        right = rest[i + 1]
        result = result & rest[i](left, right)
        left = right
    return result * 1.0


def _compare_real_parts(first, *rest):
    return _compare(np.real(first), *(np.real(v) if i % 2 else v for i, v in enumerate(rest)))


def _broadcast_rows(rows, args, dtype):
    """Stack rows of different shapes into ``(len(rows), *broadcast shape of args and rows)``."""
    shape = np.broadcast_shapes(*(np.shape(a) for a in args), *(np.shape(r) for r in rows))
    out = np.empty((len(rows), *shape), dtype=dtype)
    for i, row in enumerate(rows):
        out[i] = row
    return out


# Floating-point errors are ignored during evaluation. ``np.errstate`` costs ~0.8 us per call,
# more than a small right-hand side itself; numpy >= 2 keeps the error state in a context
# variable that can be set to a prebuilt value for ~0.1 us. Fall back to np.errstate if numpy's
# internals differ from what is checked here.
def _fast_error_state():
    try:
        from numpy._core._ufunc_config import _extobj_contextvar
        from numpy._core.umath import _make_extobj

        ignore = _make_extobj(all="ignore")
        token = _extobj_contextvar.set(ignore)
        try:
            works = all(v == "ignore" for v in np.geterr().values())
        finally:
            _extobj_contextvar.reset(token)
        return (_extobj_contextvar.set, _extobj_contextvar.reset, ignore) if works else None
    except Exception:  # pragma: no cover - depends on the numpy version
        return None


_FAST_ERRSTATE = _fast_error_state()

_COMPARATORS = {
    ast.Lt: ("<", "_lt", np.less),
    ast.LtE: ("<=", "_le", np.less_equal),
    ast.Gt: (">", "_gt", np.greater),
    ast.GtE: (">=", "_ge", np.greater_equal),
    ast.Eq: ("==", "_eq", np.equal),
    ast.NotEq: ("!=", "_ne", np.not_equal),
}
_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_UNARY = {ast.USub: "-", ast.UAdd: "+"}


def _namespace(complex_step: bool) -> dict[str, Any]:
    """The globals of a generated function: helpers only, all named with a leading ``_``."""
    functions = _COMPLEX_FUNCTIONS if complex_step else FUNCTIONS
    namespace: dict[str, Any] = {"__builtins__": {}}
    namespace.update({f"_f_{name}": fn for name, fn in functions.items()})
    namespace.update({name: ufunc for _, name, ufunc in _COMPARATORS.values()})
    namespace.update(
        _compare=_compare_real_parts if complex_step else _compare,
        _pow=_complex_power,
        _coerce=np.complex128 if complex_step else np.float64,
        _dtype=np.complex128 if complex_step else np.float64,
        _array=np.array,
        _broadcast_rows=_broadcast_rows,
        _ValueError=ValueError,
        _errstate=np.errstate,
    )
    if _FAST_ERRSTATE is not None:
        namespace.update(zip(("_fp_set", "_fp_reset", "_FP_IGNORE"), _FAST_ERRSTATE))
    return namespace
