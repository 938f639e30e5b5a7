"""The safe expression language of experiment files.

Right-hand sides, exact solutions, outputs, parameters and time values in experiment files are
strings such as ``"-k/m*x - c*v + u"`` or ``"2*pi"``. The language is deliberately small:

* numbers (all evaluated as ``np.float64``) and names (``t``, states, inputs, parameters and the
  constants ``pi`` and ``e``); names are case-sensitive;
* ``+ - * /``, unary ``-``/``+``, parentheses, and power written ``^`` (as MATLAB users do) or
  ``**``; ``-x^2`` is ``-(x^2)`` as in MATLAB and Python;
* comparisons ``< <= > >= == !=`` evaluating to 1.0 or 0.0; a chain ``0 < t < 1`` means
  "and";
* the functions in :data:`FUNCTIONS`.

Nothing else: no attributes, indexing, other calls, keywords, strings, lambdas, comprehensions,
``and``/``or``/``not``, conditional expressions or complex literals. MATLAB groups ``a^b^c``
left to right and Python right to left, so an unparenthesised chain of powers that uses ``^`` is
rejected rather than silently read one way.

An expression is parsed once with :mod:`ast`, checked against a whitelist of node types, and
turned into Python source that only names its arguments and numpy helpers. That source is
compiled with empty builtins into a plain function, so evaluating costs about as much as the
arithmetic itself and no expression can reach anything outside the language. Evaluation ignores
floating-point errors (``1/0`` is inf, ``9^9^9`` cannot be written, ``9**9**9`` is inf): a
non-finite value is the solver's business, not an exception.

Every error is an :class:`~odelab.exceptions.ExpressionError` carrying the user's text and the
0-based column of the offending part, so the CLI can print a caret under it.
"""

from __future__ import annotations

import ast
import difflib
import io
import keyword
import math
import numbers
import re
import tokenize
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from odelab.exceptions import ExpressionError, InputError

__all__ = [
    "FUNCTIONS",
    "CONSTANTS",
    "RESERVED",
    "MAX_LENGTH",
    "MAX_DEPTH",
    "ParsedExpression",
    "CompiledExpression",
    "check_identifier",
    "parse_expression",
    "compile_expression",
    "compile_vector",
    "evaluate_constant",
    "evaluate_parameters",
]

#: Longest accepted expression, in characters; longer text is rejected before parsing.
MAX_LENGTH = 2000

#: Deepest accepted nesting, counted in brackets and, separately, in levels of the syntax tree
#: (each operator of a chain such as ``a+b+c`` adds a level). Python's own parser and compiler
#: recurse on the tree, so this keeps them far from ``RecursionError``.
MAX_DEPTH = 200

# Brackets are limited more tightly than tree levels: CPython's tokenizer refuses 200 levels.
_MAX_BRACKETS = 100


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
    }
)

#: Named constants of the language.
CONSTANTS: Mapping[str, float] = MappingProxyType({"pi": math.pi, "e": math.e})

#: Names a file may not give to a state, input, parameter or output.
RESERVED: frozenset[str] = frozenset(FUNCTIONS) | frozenset(CONSTANTS) | {"t"}

# number of arguments: exact, or (minimum, None) for variadic functions
_ARITY: dict[str, int | tuple[int, None]] = {name: 1 for name in FUNCTIONS}
_ARITY.update(atan2=2, where=3, min=(2, None), max=(2, None))

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


# --------------------------------------------------------------------------------------------
# Parsing and validation
# --------------------------------------------------------------------------------------------

_LOGIC_HINT = (
    "combine conditions with a chained comparison (`0 < t < 1`), a product "
    "(`(t > 1)*(x < 0)`) or `where(cond, a, b)`"
)
_LOOKALIKES = {
    "\u2212": "-",
    "\u2013": "-",
    "\u00d7": "*",
    "\u00b7": "*",
    "\u22c5": "*",
    "\u00f7": "/",
    "\u03c0": "pi",
    "\u2264": "<=",
    "\u2265": ">=",
    "\u2260": "!=",
}
_BAD_CHARACTER = re.compile(r"[^\t\n\r\x20-\x7e]")
_MATLAB_LOGIC = re.compile(r"&&|\|\|")
_MATLAB_ELEMENTWISE = re.compile(r"\.[\^*/]")
_NAME_RUN = re.compile(r"[A-Za-z0-9_]*\Z")

_FORBIDDEN_NODES: dict[type, str] = {
    ast.Attribute: "attribute access (`.`) is not allowed in expressions",
    ast.Subscript: "indexing (`[...]`) is not allowed in expressions",
    ast.Slice: "indexing (`[...]`) is not allowed in expressions",
    ast.Lambda: "lambda functions are not allowed in expressions",
    ast.ListComp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.SetComp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.DictComp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.GeneratorExp: "comprehensions (`... for ... in ...`) are not allowed in expressions",
    ast.List: "lists (`[...]`) are not allowed in expressions; an expression is one value",
    ast.Tuple: "tuples (`,`) are not allowed in expressions; an expression is one value",
    ast.Set: "sets (`{...}`) are not allowed in expressions",
    ast.Dict: "dicts (`{...}`) are not allowed in expressions",
    ast.JoinedStr: "f-strings are not allowed in expressions",
    ast.FormattedValue: "f-strings are not allowed in expressions",
    ast.NamedExpr: "assignments (`:=`) are not allowed in expressions",
    ast.IfExp: "conditional expressions (`a if c else b`) are not allowed; write `where(c, a, b)`",
    ast.BoolOp: f"`and`/`or` are not allowed; {_LOGIC_HINT}",
    ast.Starred: "starred arguments (`*`) are not allowed in expressions",
    ast.Await: "`await` is not allowed in expressions",
    ast.Yield: "`yield` is not allowed in expressions",
    ast.YieldFrom: "`yield` is not allowed in expressions",
}
_FORBIDDEN_OPERATORS: dict[type, str] = {
    ast.Mod: "`%`",
    ast.FloorDiv: "`//`",
    ast.MatMult: "`@`",
    ast.BitAnd: "`&`",
    ast.BitOr: "`|`",
    ast.BitXor: "`^`",
    ast.LShift: "`<<`",
    ast.RShift: "`>>`",
}


@dataclass(frozen=True)
class ParsedExpression:
    """A syntactically valid expression of the language, not yet bound to names.

    Attributes
    ----------
    text
        The expression as the user wrote it.
    names
        The free names it uses: variables, excluding the constants and the functions.
    tree
        Its :class:`ast.Expression`; ``^`` is already ``**`` there, and column offsets refer to
        that translated text (map them with :meth:`column`).
    key, source
        Where the text came from (TOML key path and file), used in later errors.
    """

    text: str
    names: frozenset[str]
    tree: ast.Expression = field(repr=False, compare=False)
    key: str | None = field(default=None, repr=False, compare=False)
    source: str | None = field(default=None, repr=False, compare=False)
    # first occurrence of each free name, in source order: (name, offset in the translated text)
    _occurrences: tuple[tuple[str, int], ...] = field(default=(), repr=False, compare=False)
    _columns: tuple[int, ...] = field(default=(0,), repr=False, compare=False)
    _depth: int = field(default=1, repr=False, compare=False)

    def column(self, offset: int) -> int:
        """The column in :attr:`text` of an offset into the translated (``**``) text."""
        return self._columns[max(0, min(offset, len(self._columns) - 1))]


class _Reader:
    """The text being parsed, its Python translation and the map back to user columns."""

    def __init__(self, text: str, key: str | None, source: str | None):
        self.text = text
        self.key = key
        self.source = source
        self.python = text
        self.columns: list[int] = list(range(len(text) + 1))

    def error(self, message: str, offset: int | None = None, *, column: int | None = None):
        if offset is not None:
            column = self.columns[max(0, min(offset, len(self.columns) - 1))]
        return ExpressionError(
            message, expression=self.text, column=column, source=self.source, key=self.key
        )

    def after(self, offset: int) -> int:
        """The offset of the first token after ``offset`` that is not a space or ``)``."""
        python = self.python
        while offset < len(python) and python[offset] in " )":
            offset += 1
        return offset


def _as_text(value: Any, key: str | None, source: str | None) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, (bool, np.bool_)):
        raise ExpressionError(
            f"booleans are not numbers; got {str(value).lower()}; write 1 or 0",
            expression=str(value).lower(),
            column=0,
            source=source,
            key=key,
        )
    if isinstance(value, numbers.Integral):
        try:
            return repr(int(value))
        except ValueError:  # more digits than Python converts to text
            raise ExpressionError(
                f"the integer is too long; an expression has at most {MAX_LENGTH} characters",
                expression="<integer>",
                column=None,
                source=source,
                key=key,
            ) from None
    if isinstance(value, numbers.Real):
        number = float(value)
        if not math.isfinite(number):
            raise ExpressionError(
                f"a number in an expression must be finite; got {number}",
                expression=str(number),
                column=0,
                source=source,
                key=key,
            )
        return repr(number)
    description = f"{type(value).__name__} {value!r}"
    raise ExpressionError(
        f"an expression must be a string or a number; got {description[:80]}",
        expression=repr(value)[:200],
        column=None,
        source=source,
        key=key,
    )


def _check_characters(reader: _Reader) -> None:
    text = reader.text
    if len(text) > MAX_LENGTH:
        raise reader.error(
            f"expression is {len(text)} characters long; the limit is {MAX_LENGTH}. "
            "Split it into parameters or outputs",
            column=MAX_LENGTH,
        )
    bad = _BAD_CHARACTER.search(text)
    if bad:
        ch = bad.group()
        if ord(ch) < 128:
            message = f"control character U+{ord(ch):04X} is not allowed in expressions"
        else:
            message = f"character `{ch}` (U+{ord(ch):04X}) is not allowed; expressions are ASCII"
            if ch in _LOOKALIKES:
                message += f"; write `{_LOOKALIKES[ch]}`"
        raise reader.error(message, column=bad.start())
    if not text.strip():
        raise reader.error("empty expression; write a number or a formula such as `-k*x`", column=0)

    if "~=" in text:
        raise reader.error("`~=` is MATLAB's not-equal; write `!=`", column=text.index("~="))
    logic = _MATLAB_LOGIC.search(text)
    if logic:
        raise reader.error(f"`{logic.group()}` is not supported; {_LOGIC_HINT}", column=logic.start())
    for match in _MATLAB_ELEMENTWISE.finditer(text):
        # `x.^2` is MATLAB; `2.*x` is the number `2.` times x in both languages
        before = text[: match.start()]
        run = _NAME_RUN.search(before).group()
        if before.endswith((")", "]")) or (run and not run[0].isdigit()):
            op = match.group()
            raise reader.error(
                f"`{op}` is MATLAB's elementwise operator; write `{op[1:]}` "
                "(every operation here is elementwise)",
                column=match.start(),
            )

    depth = 0
    for i, ch in enumerate(text):
        if ch in "([{":
            depth += 1
            if depth > _MAX_BRACKETS:
                raise reader.error(
                    f"brackets are nested more than {_MAX_BRACKETS} deep; "
                    "simplify the expression or split it into parameters",
                    column=i,
                )
        elif ch in ")]}":
            depth = max(0, depth - 1)


def _translate(reader: _Reader) -> set[int]:
    """Turn the text into Python: ``^`` becomes ``**``; return the offsets of those ``**``.

    The replacement is made on tokens (a ``^`` inside a string stays as it is, to be rejected
    with the string) and keeps a map from offsets in the Python text to the user's columns.
    """
    # tabs and line breaks (TOML multi-line strings) are spaces; leading spaces would be an
    # "unexpected indent" to Python
    flat = reader.text.translate({9: " ", 10: " ", 13: " "})
    start = len(flat) - len(flat.lstrip(" "))
    body = flat[start:]
    carets: set[int] = set()
    try:
        for token in tokenize.generate_tokens(io.StringIO(body).readline):
            if token.type == tokenize.OP and token.string == "^":
                carets.add(token.start[1])
            elif token.type == tokenize.COMMENT:
                raise reader.error(
                    "comments (`#`) are not allowed in expressions", column=start + token.start[1]
                )
    except (tokenize.TokenError, SyntaxError):
        pass  # unbalanced brackets or a bad token: the parser reports it, with its position

    pieces: list[str] = []
    columns: list[int] = []
    translated: set[int] = set()
    for i, ch in enumerate(body):
        if i in carets:
            translated.add(len(columns))
            pieces.append("**")
            columns += [start + i, start + i]
        else:
            pieces.append(ch)
            columns.append(start + i)
    columns.append(len(reader.text))
    reader.python = "".join(pieces)
    reader.columns = columns
    return translated


def _parse_tree(reader: _Reader) -> ast.Expression:
    python = reader.python
    try:
        with warnings.catch_warnings():
            # e.g. "'int' object is not callable" for `2(x+1)`, reported as an error below;
            # the core never prints
            warnings.simplefilter("ignore")
            return ast.parse(python, mode="eval")
    except SyntaxError as exc:
        if exc.lineno in (None, 1) and exc.offset and exc.offset > 0:
            offset = exc.offset - 1
        else:  # at the end of the text
            offset = len(python)
        raise reader.error(f"syntax error: {exc.msg}", offset) from None
    except (RecursionError, MemoryError):
        raise reader.error(_too_deep_message(), column=0) from None


def _too_deep_message() -> str:
    return (
        f"expression is nested too deeply (more than {MAX_DEPTH} levels; each bracket, call and "
        "operator of a chain such as `a+b+c` adds one); split it into parameters or outputs"
    )


def _measure_depth(reader: _Reader, tree: ast.Expression) -> int:
    deepest = 0
    stack: list[tuple[ast.AST, int]] = [(tree.body, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_DEPTH:
            if isinstance(node, ast.BinOp):  # point at the operator, not the chain's start
                offset = reader.after(node.left.end_col_offset)
            else:
                offset = getattr(node, "col_offset", 0)
            raise reader.error(_too_deep_message(), offset)
        deepest = max(deepest, depth)
        for child in reversed(list(ast.iter_child_nodes(node))):
            stack.append((child, depth + isinstance(child, ast.expr)))
    return deepest


def _did_you_mean(name: str, candidates: Iterable[str]) -> str:
    candidates = list(dict.fromkeys(candidates))
    same_but_case = [c for c in candidates if c.lower() == name.lower()]
    if same_but_case:
        return f"did you mean `{same_but_case[0]}`? (names are case-sensitive)"
    close = difflib.get_close_matches(name, candidates, n=1, cutoff=0.7)
    return f"did you mean `{close[0]}`?" if close else ""


def _forbidden_node_column(reader: _Reader, node: ast.AST) -> int:
    """Offset of the token that makes ``node`` forbidden (its `.`, `[`, `,`, `if`, `and`...)."""
    if isinstance(node, (ast.Attribute, ast.Subscript)):
        return reader.after(node.value.end_col_offset)
    if isinstance(node, ast.BoolOp):
        return reader.after(node.values[0].end_col_offset)
    if isinstance(node, ast.IfExp):
        return reader.after(node.body.end_col_offset)
    if isinstance(node, ast.Tuple) and node.elts:
        return reader.after(node.elts[0].end_col_offset)
    return getattr(node, "col_offset", 0)


def _check_call(reader: _Reader, node: ast.Call) -> list[ast.AST]:
    func = node.func
    if not isinstance(func, ast.Name):
        if type(func) in _FORBIDDEN_NODES:
            raise reader.error(_FORBIDDEN_NODES[type(func)], _forbidden_node_column(reader, func))
        paren = reader.after(func.end_col_offset)
        if isinstance(func, ast.Call):
            raise reader.error(
                "calling the result of a call (`f(x)(y)`) is not allowed", paren
            )
        raise reader.error(
            "only the listed functions can be called; to multiply, write `*` "
            "(e.g. `2*(x + 1)`, not `2(x + 1)`)",
            paren,
        )
    name = func.id
    if name not in FUNCTIONS:
        hint = _did_you_mean(name, FUNCTIONS)
        hint = f"{hint} Allowed: " if hint else "allowed: "
        raise reader.error(
            f"`{name}` is not an allowed function; {hint}{_FUNCTION_LIST}", func.col_offset
        )
    for argument in node.args:
        if isinstance(argument, ast.Starred):
            raise reader.error(_FORBIDDEN_NODES[ast.Starred], argument.col_offset)
    for kw in node.keywords:
        if kw.arg is None:
            raise reader.error("`**` unpacking is not allowed in function calls", kw.col_offset)
        raise reader.error(
            f"keyword arguments (`{kw.arg}=`) are not allowed; pass arguments by position",
            kw.col_offset,
        )
    arity, got = _ARITY[name], len(node.args)
    if isinstance(arity, tuple):
        if got < arity[0]:
            raise reader.error(
                f"`{name}` takes {arity[0]} or more arguments; got {got}", func.col_offset
            )
    elif got != arity:
        plural = "argument" if arity == 1 else "arguments"
        what = " (condition, value if true, value if false)" if name == "where" else ""
        raise reader.error(f"`{name}` takes {arity} {plural}{what}; got {got}", func.col_offset)
    return list(node.args)


def _check_power(reader: _Reader, node: ast.BinOp, carets: set[int]) -> None:
    """Reject ``a^b^c`` (and ``a^-b^c``, ``a**b^c``): MATLAB and Python group them differently."""
    outer = reader.after(node.left.end_col_offset)
    right, start = node.right, outer + 2
    # operands are unparenthesised when no `(` lies between the operator and their first token
    while isinstance(right, ast.UnaryOp) and "(" not in reader.python[start : right.col_offset]:
        start, right = right.col_offset + 1, right.operand
    if not (isinstance(right, ast.BinOp) and isinstance(right.op, ast.Pow)):
        return
    if "(" in reader.python[start : right.col_offset]:
        return
    inner = reader.after(right.left.end_col_offset)
    if outer in carets or inner in carets:
        raise reader.error(
            "chained powers like `a^b^c` are ambiguous: MATLAB groups them left to right, "
            "Python right to left; add parentheses: `(a^b)^c` or `a^(b^c)`",
            outer if outer in carets else inner,
        )


def _validate(reader: _Reader, tree: ast.Expression, carets: set[int]):
    """Check every node against the whitelist, in source order; return the free names."""
    occurrences: dict[str, int] = {}
    stack: list[ast.AST] = [tree.body]
    while stack:
        node = stack.pop()
        children: list[ast.AST] = []
        if isinstance(node, ast.Constant):
            value = node.value
            if isinstance(value, bool):
                message = "booleans (`True`/`False`) are not allowed; write 1 or 0"
            elif isinstance(value, (int, float)):
                message = ""
            elif isinstance(value, complex):
                message = "complex numbers (`1j`) are not allowed in expressions"
            elif isinstance(value, (str, bytes)):
                message = "strings are not allowed in expressions"
            elif value is None:
                message = "`None` is not allowed in expressions"
            elif value is Ellipsis:
                message = "`...` (Ellipsis) is not allowed in expressions"
            else:
                message = f"`{value!r}` is not allowed in expressions"
            if message:
                raise reader.error(message, node.col_offset)
        elif isinstance(node, ast.Name):
            name = node.id
            if name.startswith("_"):
                raise reader.error(
                    f"`{name}`: names starting with `_` are not allowed", node.col_offset
                )
            if name in FUNCTIONS:
                raise reader.error(f"`{name}` is a function; call it as `{name}(...)`", node.col_offset)
            if name not in CONSTANTS:
                occurrences.setdefault(name, node.col_offset)
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in _BINARY:
                symbol = _FORBIDDEN_OPERATORS.get(type(node.op), "this operator")
                hint = f"; {_LOGIC_HINT}" if symbol in ("`&`", "`|`") else ""
                raise reader.error(
                    f"operator {symbol} is not allowed; the operators are "
                    f"+ - * / ^ ** < <= > >= == !={hint}",
                    reader.after(node.left.end_col_offset),
                )
            if isinstance(node.op, ast.Pow):
                _check_power(reader, node, carets)
            children = [node.left, node.right]
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                symbol = "`not`" if isinstance(node.op, ast.Not) else "`~`"
                raise reader.error(f"{symbol} is not allowed; {_LOGIC_HINT}", node.col_offset)
            children = [node.operand]
        elif isinstance(node, ast.Compare):
            left = node.left
            for op, right in zip(node.ops, node.comparators):
                if type(op) not in _COMPARATORS:
                    raise reader.error(
                        "`is` and `in` are not allowed; compare with < <= > >= == !=",
                        reader.after(left.end_col_offset),
                    )
                left = right
            children = [node.left, *node.comparators]
        elif isinstance(node, ast.Call):
            children = _check_call(reader, node)
        else:
            message = _FORBIDDEN_NODES.get(
                type(node), f"`{type(node).__name__}` is not allowed in expressions"
            )
            raise reader.error(message, _forbidden_node_column(reader, node))
        stack.extend(reversed(children))
    return occurrences


def parse_expression(
    text: str | int | float | ParsedExpression,
    *,
    key: str | None = None,
    source: str | None = None,
) -> ParsedExpression:
    """Parse and validate an expression of the language.

    Parameters
    ----------
    text
        The expression, e.g. ``"-k/m*x^3"``; a number (a TOML integer or float) is accepted as
        the constant expression it denotes. A :class:`ParsedExpression` is returned unchanged.
    key
        The TOML key path the text came from (``system.equations.x``), for error messages.
    source
        The file the text came from, for error messages.

    Returns
    -------
    ParsedExpression
        The text, its free names and its syntax tree.

    Raises
    ------
    ExpressionError
        If the text is too long, nested too deeply, not valid syntax, or uses anything outside
        the language; the error carries the 0-based column of the offending part.
    """
    if isinstance(text, ParsedExpression):
        return text
    reader = _Reader(_as_text(text, key, source), key, source)
    _check_characters(reader)
    carets = _translate(reader)
    tree = _parse_tree(reader)
    depth = _measure_depth(reader, tree)
    occurrences = _validate(reader, tree, carets)
    return ParsedExpression(
        text=reader.text,
        names=frozenset(occurrences),
        tree=tree,
        key=key,
        source=source,
        _occurrences=tuple(occurrences.items()),
        _columns=tuple(reader.columns),
        _depth=depth,
    )


# --------------------------------------------------------------------------------------------
# Compilation
# --------------------------------------------------------------------------------------------


def _unknown_name_error(
    parsed: ParsedExpression, known: Sequence[str], key: str | None, source: str | None
) -> ExpressionError | None:
    known_set = set(known)
    for name, offset in parsed._occurrences:
        if name in known_set:
            continue
        hint = _did_you_mean(name, [*known, *CONSTANTS])
        listed = [*known, *CONSTANTS]
        if len(listed) > 40:
            listed = [*listed[:40], f"... ({len(listed) - 40} more)"]
        message = f"unknown name `{name}`; " + (f"{hint} " if hint else "")
        if known:
            message += f"{'K' if hint else 'k'}nown names: {', '.join(listed)}"
        else:
            message += "no names are available here, only the constants pi and e"
        return ExpressionError(
            message, expression=parsed.text, column=parsed.column(offset), source=source, key=key
        )
    return None


class _Emitter:
    """Python source for validated trees; numbers become np.float64 globals of the namespace."""

    def __init__(self, namespace: dict[str, Any], complex_step: bool):
        self.namespace = namespace
        self.complex_step = complex_step
        self._pool: dict[str, str] = {}

    def number(self, value: float) -> str:
        # np.float64 objects, not Python literals: `1/0` or `9.0**9.0**9.0` on Python floats
        # raise instead of giving inf, and Python would try to fold them at compile time
        label = repr(value)
        if label not in self._pool:
            name = f"_k{len(self._pool)}"
            self._pool[label] = name
            self.namespace[name] = np.float64(value)
        return self._pool[label]

    def expression(self, tree: ast.Expression) -> str:
        code: dict[int, str] = {}
        stack: list[tuple[ast.AST, bool]] = [(tree.body, False)]
        while stack:  # post-order without recursion: trees may be MAX_DEPTH deep
            node, ready = stack.pop()
            if not ready:
                stack.append((node, True))
                stack.extend((child, False) for child in _operands(node))
                continue
            code[id(node)] = self._node(node, [code[id(c)] for c in _operands(node)])
        return code[id(tree.body)]

    def _node(self, node: ast.AST, parts: list[str]) -> str:
        if isinstance(node, ast.Constant):
            try:
                return self.number(float(node.value))
            except OverflowError:  # an integer literal beyond the float range
                return self.number(math.inf)
        if isinstance(node, ast.Name):
            if node.id in CONSTANTS:
                return self.number(CONSTANTS[node.id])
            return node.id
        if isinstance(node, ast.BinOp):
            left, right = parts
            if self.complex_step and isinstance(node.op, ast.Pow):
                return f"_pow({left}, {right})"
            return f"({left} {_BINARY[type(node.op)]} {right})"
        if isinstance(node, ast.UnaryOp):
            return f"({_UNARY[type(node.op)]}{parts[0]})"
        if isinstance(node, ast.Compare):
            if len(node.ops) == 1 and not self.complex_step:
                return f"(({parts[0]} {_COMPARATORS[type(node.ops[0])][0]} {parts[1]}) * 1.0)"
            chain = [parts[0]]
            for op, part in zip(node.ops, parts[1:]):
                chain += [_COMPARATORS[type(op)][1], part]
            return f"_compare({', '.join(chain)})"
        if isinstance(node, ast.Call):
            return f"_f_{node.func.id}({', '.join(parts)})"
        raise AssertionError(f"unvalidated node {type(node).__name__}")  # pragma: no cover


def _operands(node: ast.AST) -> list[ast.AST]:
    if isinstance(node, ast.BinOp):
        return [node.left, node.right]
    if isinstance(node, ast.UnaryOp):
        return [node.operand]
    if isinstance(node, ast.Compare):
        return [node.left, *node.comparators]
    if isinstance(node, ast.Call):
        return list(node.args)
    return []


def _function_source(name: str, params: Sequence[str], body: list[str]) -> str:
    """A function that coerces its arguments and runs ``body`` with FP errors ignored."""
    inner = [f"{p} = _coerce({p})" for p in params] + body
    if _FAST_ERRSTATE is not None:
        lines = ["_token = _fp_set(_FP_IGNORE)", "try:"]
        lines += [f"    {line}" for line in inner]
        lines += ["finally:", "    _fp_reset(_token)"]
    else:  # pragma: no cover - numpy < 2
        lines = ["with _errstate(all='ignore'):", *(f"    {line}" for line in inner)]
    return f"def {name}({', '.join(params)}):\n" + "".join(f"    {line}\n" for line in lines)


def _define(source_code: str, name: str, namespace: dict[str, Any], error: Callable[[], Exception]):
    try:
        code = compile(source_code, f"<odelab {name}>", "exec")
    except (RecursionError, MemoryError):
        raise error() from None
    exec(code, namespace)  # the source holds validated names, numbers and helpers only
    return namespace[name]


class CompiledExpression:
    """An expression compiled into a numpy function of its free names.

    Call it with keyword arguments, one per name (extra ones are ignored):
    ``f(x=1.0, v=np.linspace(0, 1, 5))``. Values broadcast like numpy arrays; the result is a
    numpy float (or complex, for the complex-step variant) or an array. Create it with
    :func:`compile_expression`.

    Attributes
    ----------
    text
        The expression as the user wrote it.
    names
        The free names the expression uses.
    source
        The generated Python source, for debugging.
    """

    __slots__ = ("text", "names", "source", "_params", "_function")

    def __init__(self, text: str, params: tuple[str, ...], source: str, function: Callable):
        self.text = text
        self.names = frozenset(params)
        self.source = source
        self._params = params
        self._function = function

    def __call__(self, **values: Any):
        try:
            args = [values[name] for name in self._params]
        except KeyError as exc:
            raise TypeError(f"missing a value for `{exc.args[0]}` in `{self.text}`") from None
        result = self._function(*args)
        if type(result) is np.ndarray and result.ndim == 0:
            return result[()]
        return result

    def __repr__(self) -> str:
        return f"CompiledExpression({self.text!r})"


def compile_expression(
    text: str | int | float | ParsedExpression,
    *,
    names: Iterable[str],
    key: str | None = None,
    source: str | None = None,
    complex_step: bool = False,
) -> CompiledExpression:
    """Compile an expression into a function of the names it uses.

    Parameters
    ----------
    text
        The expression (or a number, or a :class:`ParsedExpression`).
    names
        The names the expression may use (states, inputs, parameters, ``t``...). The constants
        ``pi`` and ``e`` are always available.
    key, source
        Where the text came from, for error messages.
    complex_step
        Compile the variant for complex-step differentiation: arguments are complex, and
        ``Im f(x + ih)/h`` is the derivative even through ``abs``, ``min``, ``where``... (whose
        decisions use real parts).

    Returns
    -------
    CompiledExpression
        Call it as ``f(**values)``.

    Raises
    ------
    ExpressionError
        If the text is invalid or uses a name not in ``names`` (with a did-you-mean hint).
    """
    parsed = parse_expression(text, key=key, source=source)
    key = parsed.key if key is None else key
    source = parsed.source if source is None else source
    known = list(dict.fromkeys(n for n in names if n not in CONSTANTS))
    error = _unknown_name_error(parsed, known, key, source)
    if error is not None:
        raise error
    namespace = _namespace(complex_step)
    body = _Emitter(namespace, complex_step).expression(parsed.tree)
    params = tuple(name for name, _ in parsed._occurrences)
    source_code = _function_source("_odelab_expression", params, [f"return {body}"])
    function = _define(
        source_code,
        "_odelab_expression",
        namespace,
        lambda: ExpressionError(
            _too_deep_message(), expression=parsed.text, column=0, source=source, key=key
        ),
    )
    return CompiledExpression(parsed.text, params, source_code, function)


def _check_argument_name(name: Any, what: str) -> None:
    if (
        not isinstance(name, str)
        or not name.isascii()
        or not name.isidentifier()
        or keyword.iskeyword(name)
        or name.startswith("_")
        or name in FUNCTIONS
        or name in CONSTANTS
    ):
        raise InputError(
            f"`{name}` cannot be {what}: names must be ASCII identifiers, not keywords, not "
            "starting with `_`, and not a function or constant of the expression language",
            key="constants" if what == "a constant" else "args",
        )


def compile_vector(
    texts: Sequence[str | int | float | ParsedExpression],
    *,
    args: Sequence[str],
    constants: Mapping[str, float] | None = None,
    keys: Sequence[str | None] | None = None,
    source: str | None = None,
    complex_step: bool = False,
) -> Callable[..., np.ndarray]:
    """Compile several expressions into one function returning them as an array.

    This is the hot path of a simulation: the returned ``F(*args)`` evaluates every expression
    in one generated Python function (e.g. ``F(t, y1, y2, y3)`` runs
    ``array((y2*y3, -y1*y3, a*y1*y2))``), costing a few microseconds for small systems.

    Parameters
    ----------
    texts
        The expressions (strings, numbers or :class:`ParsedExpression`).
    args
        The positional arguments of ``F``, by name (e.g. ``["t", "x", "v"]``).
    constants
        Values bound by name at compile time (e.g. parameter values).
    keys
        The TOML key path of each text, for error messages.
    source
        The file the texts came from, for error messages.
    complex_step
        Compile the complex-step variant (see :func:`compile_expression`).

    Returns
    -------
    callable
        ``F(*args) -> ndarray`` of shape ``(len(texts),)`` for scalar arguments, or
        ``(len(texts), *shape)`` where ``shape`` is the broadcast shape of the arguments;
        constant rows are broadcast. ``F.source`` holds the generated Python source.

    Raises
    ------
    ExpressionError
        If a text is invalid or uses a name that is neither an argument nor a constant.
    InputError
        If ``args``/``constants`` names are not usable identifiers, repeat, or overlap, or if
        ``keys`` does not match ``texts``.
    """
    constants = {} if constants is None else dict(constants)
    args = list(args)
    for name in args:
        _check_argument_name(name, "an argument")
    for name in constants:
        _check_argument_name(name, "a constant")
    repeated = sorted({a for a in args if args.count(a) > 1} | (set(args) & set(constants)))
    if repeated:
        raise InputError(
            f"`{repeated[0]}` appears twice among the arguments and constants", key="args"
        )
    if keys is None:
        keys = [None] * len(texts)
    elif len(keys) != len(texts):
        raise InputError(f"got {len(keys)} keys for {len(texts)} expressions", key="keys")

    known = [*args, *constants]
    parsed = [parse_expression(text, key=k, source=source) for text, k in zip(texts, keys)]
    for p, k in zip(parsed, keys):
        error = _unknown_name_error(p, known, k if k is not None else p.key, source)
        if error is not None:
            raise error

    namespace = _namespace(complex_step)
    for name, value in constants.items():
        try:
            namespace[name] = np.float64(float(value))
        except (TypeError, ValueError):
            raise InputError(
                f"constant `{name}` must be a real number; got {value!r}", key=f"constants.{name}"
            ) from None
    emitter = _Emitter(namespace, complex_step)
    rows = [emitter.expression(p.tree) for p in parsed]
    used = set().union(*(p.names for p in parsed))
    unused_args = [a for a in args if a not in used]

    # np.array stacks rows of equal shape fast; rows of different shapes (a constant next to an
    # array) make it raise ValueError, and arguments no row uses can still set the shape
    dtype = ", dtype=_dtype" if complex_step else ""
    body = [f"_rows = ({''.join(row + ', ' for row in rows)})"]
    pack = [
        "try:",
        f"    _out = _array(_rows{dtype})",
        "except _ValueError:",
        f"    return _broadcast_rows(_rows, ({''.join(a + ', ' for a in args)}), _dtype)",
    ]
    if unused_args:
        pack += [
            f"if {' or '.join(a + '.ndim' for a in unused_args)}:",
            f"    return _broadcast_rows(_rows, ({''.join(a + ', ' for a in args)}), _dtype)",
        ]
    pack.append("return _out")
    source_code = _function_source("_odelab_vector", args, body)
    source_code += "".join(f"    {line}\n" for line in pack)

    def too_deep() -> ExpressionError:
        deepest = max(range(len(parsed)), key=lambda i: parsed[i]._depth)
        return ExpressionError(
            _too_deep_message(),
            expression=parsed[deepest].text,
            column=0,
            source=source,
            key=keys[deepest],
        )

    function = _define(source_code, "_odelab_vector", namespace, too_deep)
    function.source = source_code
    return function


# --------------------------------------------------------------------------------------------
# Names, constants and parameters of experiment files
# --------------------------------------------------------------------------------------------


def check_identifier(
    name: str, *, key: str | None = None, source: str | None = None, what: str = "name"
) -> str:
    """Check a name declared in a file (a state, input, parameter or output).

    Parameters
    ----------
    name
        The declared name.
    key, source
        Where it was declared (TOML key path and file), for the error message.
    what
        What the name is for ("state", "parameter"...), used in the message.

    Returns
    -------
    str
        ``name`` itself.

    Raises
    ------
    InputError
        If ``name`` is not an ASCII identifier, is a Python keyword, starts with ``_``, or is
        reserved (``t``, a constant or a function of the expression language).
    """
    where = f"`{key}`: " if key else ""
    if not isinstance(name, str):
        raise InputError(
            f"{where}a {what} name must be a string; got {name!r}", key=key, source=source
        )
    if not name:
        raise InputError(f"{where}a {what} name must not be empty", key=key, source=source)
    if not name.isascii() or not name.isidentifier():
        raise InputError(
            f"{where}`{name}` is not a valid {what} name; use ASCII letters, digits and `_`, "
            "starting with a letter (e.g. `x1`, `omega`)",
            key=key,
            source=source,
        )
    reason = ""
    if keyword.iskeyword(name):
        reason = f"`{name}` is a Python keyword"
    elif name.startswith("_"):
        reason = f"`{name}` starts with `_`, which is reserved"
    elif name == "t":
        reason = "`t` is the time variable"
    elif name in CONSTANTS:
        reason = f"`{name}` is a constant ({CONSTANTS[name]!r})"
    elif name in FUNCTIONS:
        reason = f"`{name}` is a function of the expression language"
    if reason:
        raise InputError(
            f"{where}{reason}; choose another name for this {what}", key=key, source=source
        )
    return name


def evaluate_constant(
    text: str | int | float | ParsedExpression,
    *,
    values: Mapping[str, float] | None = None,
    key: str | None = None,
    source: str | None = None,
) -> float:
    """Evaluate an expression to one finite real number (time values, parameters...).

    Parameters
    ----------
    text
        The expression, e.g. ``"2*pi/omega"``, or a number.
    values
        Values of the names it may use.
    key, source
        Where the text came from, for error messages.

    Returns
    -------
    float
        The value, as a Python float.

    Raises
    ------
    ExpressionError
        If the text is invalid, uses an unknown name, or evaluates to inf, NaN or an array.
    """
    values = {} if values is None else values
    compiled = compile_expression(text, names=values, key=key, source=source)
    result = compiled(**values)
    what = f"`{key}` = `{compiled.text}`" if key else f"`{compiled.text}`"
    if np.ndim(result) != 0:
        raise ExpressionError(
            f"{what} must evaluate to one number; got an array of shape {np.shape(result)}",
            expression=compiled.text,
            column=None,
            source=source,
            key=key,
        )
    number = float(result)
    if not math.isfinite(number):
        raise ExpressionError(
            f"{what} evaluates to {number}; it must be a finite number (check for a division "
            "by zero, an overflow, or a log or square root of a negative number)",
            expression=compiled.text,
            column=None,
            source=source,
            key=key,
        )
    return number


def evaluate_parameters(
    params: Mapping[str, float | int | str],
    *,
    source: str | None = None,
    key_prefix: str = "parameters",
) -> dict[str, float]:
    """Evaluate a file's parameters; each is a number or an expression of other parameters.

    Parameters
    ----------
    params
        Parameter names and values, in any order: ``{"k": "m*w^2", "m": 2, "w": 3}``.
    source
        The file they came from, for error messages.
    key_prefix
        The TOML table holding them; error keys are ``f"{key_prefix}.{name}"``.

    Returns
    -------
    dict
        Parameter values as floats, in the order of ``params``.

    Raises
    ------
    InputError
        If a name is not allowed (see :func:`check_identifier`), a value is neither a number
        nor a string (booleans are rejected), parameters depend on each other in a cycle, or
        a value is not finite.
    ExpressionError
        If an expression is invalid or uses an unknown name.
    """
    names = list(params)

    def key_of(name: str) -> str:
        return f"{key_prefix}.{name}"

    for name in names:
        check_identifier(name, key=key_of(name), source=source, what="parameter")
    parsed: dict[str, ParsedExpression] = {}
    for name, value in params.items():
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (str, numbers.Real)):
            raise InputError(
                f"`{key_of(name)}` must be a number or an expression string; got "
                f"{type(value).__name__} {value!r}",
                key=key_of(name),
                source=source,
            )
        parsed[name] = parse_expression(value, key=key_of(name), source=source)
        error = _unknown_name_error(parsed[name], names, key_of(name), source)
        if error is not None:
            raise error

    # Kahn's topological order: evaluate a parameter once everything it uses is known
    dependents: dict[str, list[str]] = {name: [] for name in names}
    waiting = {name: len(parsed[name].names) for name in names}
    for name in names:
        for used in parsed[name].names:
            dependents[used].append(name)
    ready = [name for name in names if waiting[name] == 0]
    values: dict[str, float] = {}
    while ready:
        name = ready.pop()
        uses = {used: values[used] for used in parsed[name].names}
        values[name] = evaluate_constant(parsed[name], values=uses, key=key_of(name), source=source)
        for dependent in dependents[name]:
            waiting[dependent] -= 1
            if waiting[dependent] == 0:
                ready.append(dependent)

    if len(values) < len(names):
        raise _cycle_error(parsed, [n for n in names if n not in values], key_of, source)
    return {name: values[name] for name in names}


def _cycle_error(parsed, unresolved: list[str], key_of, source) -> InputError:
    """Follow unresolved dependencies from the first unresolved parameter until one repeats."""
    pending = set(unresolved)
    path = [unresolved[0]]
    while True:
        name = path[-1]
        following = next(used for used, _ in parsed[name]._occurrences if used in pending)
        if following in path:
            cycle = path[path.index(following) :]
            break
        path.append(following)
    keys = [f"`{key_of(n)}`" for n in cycle]
    if len(cycle) == 1:
        message = f"{keys[0]} depends on itself"
    elif len(cycle) == 2:
        message = f"{keys[0]} and {keys[1]} depend on each other"
    else:
        message = (
            f"{', '.join(keys[:-1])} and {keys[-1]} depend on each other in a cycle "
            f"({' -> '.join([*cycle, cycle[0]])})"
        )
    fix = "give it a number" if len(cycle) == 1 else "give one of them a number"
    return InputError(f"{message}; {fix}", key=key_of(cycle[0]), source=source)
