"""MATLAB expressions of block parameters (``"1/m"``, ``"[1 2*zeta*wn wn^2]"``, ``"tanh([-5:5])"``), never run.

A Simulink block's parameters are MATLAB expressions evaluated in the model's workspace. This
module parses the subset a block dialog holds (numbers, names, the arithmetic and comparison
operators, matrix literals with MATLAB's spacing rule, ranges, transposes, indexing of a
workspace array and the elementary functions) and computes two things at once for each
element: its number (workspace values known) and, where it depends on a scalar parameter, its
text in odelab's expression language (``"2*zeta*wn"``), so the written experiment file keeps
the parameters a student can change. Nothing is executed: the text is tokenised and parsed
here, with the nesting depth and the sizes bounded before any recursive step.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_ELEMENTS", "MAX_NESTING", "MExprError", "V", "evaluate", "text_of"]

MAX_TEXT = 100_000
"""A block parameter's text is at most 100,000 characters (a long lookup table is about 20,000)."""
MAX_NESTING = 32
"""Parentheses and brackets nest at most 32 deep (the parser's explicit guard; real dialogs use 3)."""
MAX_ELEMENTS = 1_000_000
"""An array value holds at most a million elements (a range 0:1e-9:1e3 is refused before it is built)."""


class MExprError(ValueError):
    """A parameter's text that is not MATLAB this reader knows, with the reason (the block's path is the caller's)."""


@dataclass
class V:
    """A value: ``num`` (a 2-D float array, MATLAB's shape) and, where elements depend on parameters,
    ``sym`` (the same shape, each element's odelab expression text; None when every element is a number)."""

    num: np.ndarray
    sym: np.ndarray | None = None

    @property
    def scalar(self) -> bool:
        return self.num.size == 1

    def texts(self) -> np.ndarray:
        """Every element as text (numbers by ``repr``), for combining with a symbolic value."""
        if self.sym is not None:
            return self.sym
        out = np.empty(self.num.shape, dtype=object)
        for idx, x in np.ndenumerate(self.num):
            out[idx] = _number_text(float(x))
        return out

    def item(self, idx) -> float | str:
        """One element as the experiment file writes it: a float, or an expression string."""
        if self.sym is not None and isinstance(self.sym[idx], str) and not _is_number_text(self.sym[idx]):
            return self.sym[idx]
        return float(self.num[idx])


def _number_text(x: float) -> str:
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "(-inf)"
    text = repr(x)
    return f"({text})" if x < 0 else text


_NUMBER_TEXT = re.compile(r"^\(?-?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?\)?$")


def _is_number_text(text: str) -> bool:
    return bool(_NUMBER_TEXT.match(text))


def text_of(v: V) -> str:
    """A scalar's text (its expression, or its number)."""
    return str(v.texts().reshape(-1)[0])


# --- tokens ---------------------------------------------------------------------------------------

_TOKEN = re.compile(r"""
    (?P<ws>[ \t]+|\.\.\.[^\n]*\n)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?)
  | (?P<name>[A-Za-z][A-Za-z0-9_]*(?:\.[A-Za-z][A-Za-z0-9_]*)*)
  | (?P<str>'(?:[^'\n]|'')*'|"(?:[^"\n])*")
  | (?P<op>\.\*|\./|\.\^|\.'|==|~=|!=|<=|>=|&&|\|\||[-+*/\\^'<>&|~!()\[\],;:=\n])
""", re.VERBOSE)

_ENDS_OPERAND = ("num", "name", "str")


def _tokens(text: str) -> list[tuple[str, str]]:
    """The tokens, with MATLAB's rules inside brackets: a space or a newline between two operands is a
    comma or a semicolon (``[a -b]`` is two elements, ``[a - b]`` one), and ``'`` after an operand is a
    transpose, elsewhere a string."""
    out: list[tuple[str, str]] = []
    pos, n = 0, len(text)
    stack: list[str] = []  # the open brackets: "[" (spaces separate) or "(" (they do not)
    space = False
    while pos < n:
        if text[pos] == "%":  # a comment to the end of the line
            end = text.find("\n", pos)
            pos = n if end < 0 else end
            continue
        if text[pos] == "'" and out and (out[-1][0] in _ENDS_OPERAND or out[-1][1] in (")", "]", "'", ".'")) \
                and not space:
            out.append(("op", "'"))
            pos += 1
            continue
        m = _TOKEN.match(text, pos)
        if not m:
            raise MExprError(f"cannot read {text[pos:pos + 12]!r}")
        kind = m.lastgroup
        value = m.group()
        pos = m.end()
        if kind == "ws":
            space = True
            continue
        if kind == "op" and value == "\n":
            if stack and stack[-1] == "[":
                out.append(("op", ";"))
            space = False
            continue
        in_matrix = bool(stack) and stack[-1] == "["
        if in_matrix and space and out and _operand_end(out[-1]) and _operand_start(kind, value, text, pos):
            out.append(("op", ","))
        space = False
        if kind == "op" and value in "([":
            stack.append(value)
            if len(stack) > MAX_NESTING:
                raise MExprError(f"brackets nest more than {MAX_NESTING} deep")
        elif kind == "op" and value in ")]":
            if not stack:
                raise MExprError(f"an unmatched {value!r}")
            stack.pop()
        out.append((kind, value))
    if stack:
        raise MExprError(f"an unclosed {stack[-1]!r}")
    return out


def _operand_end(token) -> bool:
    kind, value = token
    return kind in _ENDS_OPERAND or value in (")", "]", "'", ".'")


def _operand_start(kind, value, text, pos) -> bool:
    if kind in _ENDS_OPERAND or value in ("(", "[", "~", "!"):
        return True
    return value in "+-" and pos < len(text) and text[pos] not in " \t"  # [a -b]: a sign glued to what follows


# --- the parser -----------------------------------------------------------------------------------

_BINARY = [  # lowest precedence first (MATLAB's order)
    ("||",), ("&&",), ("|",), ("&",), ("==", "~=", "!=", "<", "<=", ">", ">="), (":",), ("+", "-"),
    ("*", "/", ".*", "./", "\\"),
]


class _Parser:
    def __init__(self, tokens, lookup: Callable[[str], V | None], missing: set):
        self.toks = tokens
        self.i = 0
        self.lookup = lookup
        self.missing = missing
        self.depth = 0

    def peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else ("end", "")

    def take(self, value=None):
        tok = self.peek()
        if value is not None and tok[1] != value:
            raise MExprError(f"expected {value!r}, found {tok[1] or 'the end'!r}")
        self.i += 1
        return tok

    def nest(self):
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise MExprError(f"the expression nests more than {MAX_NESTING} deep")

    def expression(self, level=0) -> V:
        if level == len(_BINARY):
            return self.unary()
        left = self.expression(level + 1)
        ops = _BINARY[level]
        while self.peek()[0] == "op" and self.peek()[1] in ops:
            op = self.take()[1]
            if op == ":":
                right = self.expression(level + 1)
                if self.peek()[1] == ":":
                    self.take()
                    stop = self.expression(level + 1)
                    left = _range(left, right, stop)
                else:
                    left = _range(left, V(np.ones((1, 1))), right)
                continue
            left = _binary(op, left, self.expression(level + 1))
        return left

    def unary(self) -> V:
        kind, value = self.peek()
        if kind == "op" and value in ("-", "+", "~", "!"):
            self.take()
            self.nest()
            operand = self.unary()
            self.depth -= 1
            if value == "-":
                return _elementwise(lambda a: -a, lambda a: f"(-{a})", operand)
            if value == "+":
                return operand
            return _elementwise(lambda a: (a == 0).astype(float), lambda a: f"({a} == 0)", operand)
        return self.power()

    def power(self) -> V:
        base = self.postfix()
        while self.peek()[1] in ("^", ".^"):
            op = self.take()[1]
            kind, value = self.peek()
            if kind == "op" and value in ("-", "+"):  # 2^-1
                self.take()
                exponent = self.postfix()
                if value == "-":
                    exponent = _elementwise(lambda a: -a, lambda a: f"(-{a})", exponent)
            else:
                exponent = self.postfix()
            base = _binary(op, base, exponent)
        return base

    def postfix(self) -> V:
        value = self.primary()
        while self.peek()[1] in ("'", ".'"):
            self.take()
            value = V(value.num.T.copy(), None if value.sym is None else value.sym.T.copy())
        return value

    def primary(self) -> V:
        kind, value = self.take()
        if kind == "num":
            return V(np.array([[float(value.replace("d", "e").replace("D", "e"))]]))
        if kind == "name":
            if self.peek()[1] == "(":
                return self.call(value)
            return self.name(value)
        if kind == "op" and value == "(":
            self.nest()
            inner = self.expression()
            self.take(")")
            self.depth -= 1
            return inner
        if kind == "op" and value == "[":
            self.nest()
            out = self.matrix()
            self.depth -= 1
            return out
        if kind == "str":
            raise MExprError(f"a string {value} where a number is expected")
        raise MExprError(f"unexpected {value or 'end of text'!r}")

    def name(self, name: str) -> V:
        if name in _CONSTANTS:
            return V(np.array([[_CONSTANTS[name]]]))
        found = self.lookup(name)
        if found is None:
            self.missing.add(name)
            return V(np.array([[math.nan]]), np.array([[name]], dtype=object))
        return found

    def arguments(self) -> list:
        self.take("(")
        self.nest()
        args: list = []
        while self.peek()[1] != ")":
            if self.peek()[1] == ":" and self.toks[self.i + 1][1] in (",", ")"):
                self.take()
                args.append(":")
            else:
                args.append(self.expression())
            if self.peek()[1] == ",":
                self.take()
            elif self.peek()[1] != ")":
                raise MExprError(f"expected ',' or ')', found {self.peek()[1] or 'the end'!r}")
        self.take(")")
        self.depth -= 1
        return args

    def call(self, name: str) -> V:
        args = self.arguments()
        if name not in _FUNCTIONS and name not in _CONSTANTS:
            found = self.lookup(name)
            if found is not None:
                return _index(name, found, args)
            if name not in _ARRAYS:
                self.missing.add(name)
                return V(np.array([[math.nan]]), np.array([[name]], dtype=object))
        if any(a == ":" for a in args):
            raise MExprError(f"`:` is an argument of {name}()")
        return _call(name, args)

    def matrix(self) -> V:
        rows: list[list[V]] = [[]]
        while self.peek()[1] != "]":
            tok = self.peek()
            if tok[1] == ",":
                self.take()
                continue
            if tok[1] == ";":
                self.take()
                rows.append([])
                continue
            rows[-1].append(self.expression())
        self.take("]")
        return _concatenate([r for r in rows if r])


def _concatenate(rows: list[list[V]]) -> V:
    if not rows:
        return V(np.zeros((0, 0)))
    symbolic = any(v.sym is not None for row in rows for v in row)
    built = []
    for row in rows:
        parts = [v for v in row if v.num.size]
        if not parts:
            continue
        heights = {v.num.shape[0] for v in parts}
        if len(heights) != 1:
            raise MExprError("the elements of a row of [...] have different heights")
        num = np.hstack([v.num for v in parts])
        sym = np.hstack([v.texts() for v in parts]) if symbolic else None
        built.append(V(num, sym))
    if not built:
        return V(np.zeros((0, 0)))
    widths = {v.num.shape[1] for v in built}
    if len(widths) != 1:
        raise MExprError("the rows of [...] have different lengths")
    return V(np.vstack([v.num for v in built]), np.vstack([v.sym for v in built]) if symbolic else None)


def _check_size(n: float) -> None:
    if not n <= MAX_ELEMENTS:
        raise MExprError(f"the value would hold {n:.3g} elements; at most {MAX_ELEMENTS:,} are read")


def _range(start: V, step: V, stop: V) -> V:
    if any(v.sym is not None for v in (start, step, stop)) or not all(v.scalar for v in (start, step, stop)):
        if any(v.sym is not None for v in (start, step, stop)):
            raise MExprError("a range a:h:b of parameters; write its numbers")
        raise MExprError("a range needs scalar bounds")
    a, h, b = float(start.num[0, 0]), float(step.num[0, 0]), float(stop.num[0, 0])
    if not all(math.isfinite(x) for x in (a, h, b)) or h == 0 or (b - a) / h < 0:
        return V(np.zeros((1, 0)))
    count = math.floor((b - a) / h * (1 + 1e-12) + 1e-10) + 1
    _check_size(count)
    values = a + h * np.arange(count)
    return V(values.reshape(1, -1))


def _broadcast(a: V, b: V):
    try:
        shape = np.broadcast_shapes(a.num.shape, b.num.shape)
    except ValueError:
        raise MExprError(f"sizes {a.num.shape[0]}x{a.num.shape[1]} and {b.num.shape[0]}x{b.num.shape[1]} do not "
                         "match") from None
    _check_size(float(np.prod(shape)))
    return shape


def _elementwise(f, text, *vals: V) -> V:
    shape = vals[0].num.shape
    for v in vals[1:]:
        shape = np.broadcast_shapes(shape, v.num.shape)
    with np.errstate(all="ignore"):
        num = np.asarray(f(*(np.broadcast_to(v.num, shape) for v in vals)), dtype=float)
    if all(v.sym is None for v in vals):
        return V(np.array(num, dtype=float).reshape(shape))
    texts = [np.broadcast_to(v.texts(), shape) for v in vals]
    sym = np.empty(shape, dtype=object)
    for idx in np.ndindex(*shape):
        sym[idx] = text(*(t[idx] for t in texts))
    return V(np.array(num, dtype=float).reshape(shape), sym)


_ELEMENTWISE = {
    "+": (np.add, "({} + {})"), "-": (np.subtract, "({} - {})"), ".*": (np.multiply, "({} * {})"),
    "./": (np.divide, "({} / {})"), ".^": (np.power, "({} ^ {})"),
    "==": (lambda a, b: (a == b) * 1.0, "({} == {})"), "~=": (lambda a, b: (a != b) * 1.0, "({} != {})"),
    "!=": (lambda a, b: (a != b) * 1.0, "({} != {})"), "<": (lambda a, b: (a < b) * 1.0, "({} < {})"),
    "<=": (lambda a, b: (a <= b) * 1.0, "({} <= {})"), ">": (lambda a, b: (a > b) * 1.0, "({} > {})"),
    ">=": (lambda a, b: (a >= b) * 1.0, "({} >= {})"),
    "&": (lambda a, b: ((a != 0) & (b != 0)) * 1.0, "(({} != 0) * ({} != 0))"),
    "&&": (lambda a, b: ((a != 0) & (b != 0)) * 1.0, "(({} != 0) * ({} != 0))"),
    "|": (lambda a, b: ((a != 0) | (b != 0)) * 1.0, "max({} != 0, {} != 0)"),
    "||": (lambda a, b: ((a != 0) | (b != 0)) * 1.0, "max({} != 0, {} != 0)"),
}


def _binary(op: str, a: V, b: V) -> V:
    if op in ("*", "/", "\\", "^") and (a.scalar or b.scalar) and not (op == "\\"):
        op = {"*": ".*", "/": "./", "^": ".^"}[op]
        if op == ".^" and not b.scalar:
            raise MExprError("a scalar to a matrix power")
    if op in _ELEMENTWISE:
        f, pattern = _ELEMENTWISE[op]
        _broadcast(a, b)
        return _elementwise(f, lambda x, y: pattern.format(x, y), a, b)
    if op == "*":
        if a.num.shape[1] != b.num.shape[0]:
            raise MExprError(f"a {a.num.shape[0]}x{a.num.shape[1]} times a {b.num.shape[0]}x{b.num.shape[1]} "
                             "matrix")
        num = a.num @ b.num
        if a.sym is None and b.sym is None:
            return V(num)
        ta, tb = a.texts(), b.texts()
        sym = np.empty(num.shape, dtype=object)
        for i, j in np.ndindex(*num.shape):
            sym[i, j] = "(" + " + ".join(f"{ta[i, k]} * {tb[k, j]}" for k in range(a.num.shape[1])) + ")"
        return V(num, sym)
    if a.sym is not None or b.sym is not None:
        raise MExprError(f"the matrix operation `{op}` on parameters; write the matrix's numbers")
    try:
        if op == "/":
            return V(np.linalg.solve(b.num.T, a.num.T).T)
        if op == "\\":
            return V(np.linalg.solve(a.num, b.num))
        if op == "^":
            n = float(b.num[0, 0])
            if n != int(n):
                raise MExprError("a matrix to a non-integer power")
            return V(np.linalg.matrix_power(a.num, int(n)))
    except np.linalg.LinAlgError as exc:
        raise MExprError(f"the matrix operation `{op}`: {exc}") from None
    raise MExprError(f"the operator {op!r}")


_CONSTANTS = {"pi": math.pi, "eps": float(np.finfo(float).eps), "Inf": math.inf, "inf": math.inf, "NaN": math.nan,
              "nan": math.nan, "true": 1.0, "false": 0.0}

#: elementwise functions: numpy's, and the text in odelab's language ({} the arguments)
_FUNCTIONS: dict[str, tuple[Callable, str]] = {
    **{f: (getattr(np, g), f + "({})") for f, g in (
        ("sin", "sin"), ("cos", "cos"), ("tan", "tan"), ("asin", "arcsin"), ("acos", "arccos"), ("atan", "arctan"),
        ("sinh", "sinh"), ("cosh", "cosh"), ("tanh", "tanh"), ("exp", "exp"), ("log", "log"), ("log10", "log10"),
        ("sqrt", "sqrt"), ("abs", "abs"), ("floor", "floor"), ("ceil", "ceil"), ("sign", "sign"))},
    "atan2": (np.arctan2, "atan2({}, {})"),
    "hypot": (np.hypot, "sqrt({0}^2 + {1}^2)"),
    "power": (np.power, "({} ^ {})"),
    "mod": (lambda a, m: np.where(m == 0, a, np.mod(a, np.where(m == 0, 1.0, m))), "mod({}, {})"),
    "rem": (np.fmod, "rem({}, {})"),
    "round": (lambda a: np.sign(a) * np.floor(np.abs(a) + 0.5), "(sign({0}) * floor(abs({0}) + 0.5))"),
    "fix": (lambda a: np.trunc(a), "(sign({0}) * floor(abs({0})))"),
    "min": (np.minimum, "min({}, {})"),
    "max": (np.maximum, "max({}, {})"),
    "deg2rad": (np.deg2rad, "({} * pi / 180)"),
    "rad2deg": (np.rad2deg, "({} * 180 / pi)"),
    "double": (lambda a: a, "{}"),
    "single": (lambda a: a, "{}"),
}
_ARRAYS = ("zeros", "ones", "eye", "diag", "linspace", "length", "numel", "sum", "prod", "size", "inv", "det",
           "transpose", "fliplr", "flipud", "poly", "conv", "cumsum", "repmat", "logspace")


def _numbers(name: str, args: list) -> list[np.ndarray]:
    for a in args:
        if a.sym is not None:
            raise MExprError(f"{name}() of parameters; write its numbers")
    return [a.num for a in args]


def _count(name: str, x: np.ndarray) -> int:
    value = float(x.reshape(-1)[0]) if x.size else 0.0
    if not math.isfinite(value) or value != int(value) or value < 0:
        raise MExprError(f"{name}() needs whole sizes; got {value:g}")
    return int(value)


def _shape_args(name: str, nums: list) -> tuple[int, int]:
    if not nums:
        return 1, 1
    if len(nums) == 1 and nums[0].size == 2:
        r, c = (_count(name, np.array(v)) for v in nums[0].reshape(-1))
    elif len(nums) == 1:
        r = c = _count(name, nums[0])
    else:
        r, c = _count(name, nums[0]), _count(name, nums[1])
    _check_size(float(r) * float(c))
    return r, c


def _call(name: str, args: list) -> V:
    if name in _FUNCTIONS:
        f, pattern = _FUNCTIONS[name]
        arity = pattern.count("{}") or (2 if "{1}" in pattern else 1)
        if name in ("min", "max") and len(args) == 1:  # min of a vector: its smallest element
            (x,) = _numbers(name, args)
            return V(np.array([[float((np.min if name == "min" else np.max)(x))]]))
        if len(args) != arity:
            raise MExprError(f"{name}() takes {arity} argument{'s' if arity > 1 else ''}; got {len(args)}")
        return _elementwise(f, lambda *xs: pattern.format(*xs), *args)
    nums = _numbers(name, args)
    if name in ("zeros", "ones", "eye"):
        r, c = _shape_args(name, nums)
        return V({"zeros": np.zeros, "ones": np.ones}.get(name, np.eye)((r, c)) if name != "eye" else np.eye(r, c))
    if name == "diag" and len(nums) == 1:
        x = nums[0]
        return V(np.diag(x.reshape(-1)) if 1 in x.shape else np.diag(x).reshape(-1, 1))
    if name in ("linspace", "logspace") and len(nums) in (2, 3):
        n = _count(name, nums[2]) if len(nums) == 3 else (100 if name == "linspace" else 50)
        _check_size(n)
        a, b = float(nums[0].reshape(-1)[0]), float(nums[1].reshape(-1)[0])
        return V((np.linspace(a, b, n) if name == "linspace" else np.logspace(a, b, n)).reshape(1, -1))
    if name in ("length", "numel") and len(nums) == 1:
        x = nums[0]
        return V(np.array([[float(max(x.shape) if x.size and name == "length" else x.size)]]))
    if name in ("sum", "prod", "cumsum") and len(nums) == 1:
        x = nums[0]
        axis = 1 if x.shape[0] == 1 else 0
        f = {"sum": np.sum, "prod": np.prod, "cumsum": np.cumsum}[name]
        out = f(x, axis=axis)
        return V(np.atleast_2d(out) if axis == 1 or name != "cumsum" else out)
    if name in ("inv", "det") and len(nums) == 1:
        try:
            return V(np.linalg.inv(nums[0]) if name == "inv" else np.array([[np.linalg.det(nums[0])]]))
        except np.linalg.LinAlgError as exc:
            raise MExprError(f"{name}(): {exc}") from None
    if name == "transpose" and len(nums) == 1:
        return V(nums[0].T.copy())
    if name in ("fliplr", "flipud") and len(nums) == 1:
        return V(np.fliplr(nums[0]) if name == "fliplr" else np.flipud(nums[0]))
    if name == "poly" and len(nums) == 1:
        return V(np.real(np.poly(nums[0].reshape(-1))).reshape(1, -1))
    if name == "conv" and len(nums) == 2:
        return V(np.convolve(nums[0].reshape(-1), nums[1].reshape(-1)).reshape(1, -1))
    if name == "repmat" and len(nums) in (2, 3):
        r, c = _shape_args(name, nums[1:])
        _check_size(float(nums[0].size) * r * c)
        return V(np.tile(nums[0], (r, c)))
    if name == "size" and len(nums) == 1:
        return V(np.array([list(map(float, nums[0].shape))]))
    raise MExprError(f"{name}() with {len(args)} argument{'s' if len(args) != 1 else ''}")


def _index(name: str, value: V, args: list) -> V:
    """``p(2)``, ``A(1, :)`` of a workspace array (1-based, as MATLAB)."""
    num = value.num
    idx = []
    for a in args:
        if isinstance(a, str):
            idx.append(slice(None))
            continue
        if a.sym is not None:
            raise MExprError(f"{name}(...) indexed by a parameter")
        flat = a.num.reshape(-1)
        if not np.all(np.isfinite(flat)) or np.any(flat != np.round(flat)) or np.any(flat < 1):
            raise MExprError(f"{name}(...) needs whole indices from 1")
        idx.append((flat.astype(int) - 1))
    try:
        if len(idx) == 1:
            order = num.reshape(-1, order="F")
            picked = order[idx[0]] if not isinstance(idx[0], slice) else order
            shape = (1, -1) if num.shape[0] == 1 else (-1, 1)
            sym = None if value.sym is None else (value.sym.reshape(-1, order="F")[idx[0]] if not isinstance(
                idx[0], slice) else value.sym.reshape(-1, order="F")).reshape(shape)
            return V(np.asarray(picked, dtype=float).reshape(shape), sym)
        if len(idx) == 2:
            rows = idx[0] if isinstance(idx[0], slice) else idx[0]
            cols = idx[1] if isinstance(idx[1], slice) else idx[1]
            picked = num[rows][:, cols] if not isinstance(rows, slice) else num[:, cols]
            sym = None
            if value.sym is not None:
                sym = value.sym[rows][:, cols] if not isinstance(rows, slice) else value.sym[:, cols]
            return V(np.atleast_2d(picked), None if sym is None else np.atleast_2d(sym))
    except IndexError:
        raise MExprError(f"{name}(...) indexes past its {num.shape[0]}x{num.shape[1]} value") from None
    raise MExprError(f"{name}(...) with {len(idx)} indices")


def evaluate(text: str, lookup: Callable[[str], V | None], missing: set | None = None) -> V:
    """The value of a parameter's MATLAB text; names are resolved by ``lookup`` (None: unknown, recorded in
    ``missing`` and carried as NaN with its name as text).

    Raises
    ------
    MExprError
        Text this reader does not know, with the reason.
    """
    if not isinstance(text, str):
        raise MExprError(f"expected text, got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise MExprError(f"the text is {len(text):,} characters; at most {MAX_TEXT:,} are read")
    tokens = _tokens(text.strip())
    while tokens and tokens[-1][1] in (";", ","):
        tokens.pop()
    if not tokens:
        raise MExprError("the value is empty")
    parser = _Parser(tokens, lookup, set() if missing is None else missing)
    try:
        value = parser.expression()
    except MExprError:
        raise
    except (ValueError, TypeError, IndexError, ZeroDivisionError, OverflowError, np.linalg.LinAlgError) as exc:
        raise MExprError(f"the value cannot be computed ({exc})") from None
    if parser.i != len(tokens):
        raise MExprError(f"unexpected {tokens[parser.i][1]!r}")
    return value
