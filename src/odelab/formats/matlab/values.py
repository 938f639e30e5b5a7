"""The values a MATLAB file computes, as odelab reads it without running it.

A number is a :class:`Sym`: a literal, a named constant (``pi``), a parameter (a constant the
file names: ``k = 3``), the time, a state, an input, or an operation on those. Every ``Sym``
knows its numeric value when it is constant (``num``; ``None`` when it depends on ``t``, a
state or an input), so the same values serve the constant evaluation of a workspace script
and the translation of a right-hand side into odelab's expression language. A MATLAB array is
an :class:`Arr` of ``Sym`` (or, for plain numbers, a numpy array), in MATLAB's column-major
order.

Expressions are bounded as they are built: a ``Sym`` more than :data:`MAX_SYM_DEPTH` deep or
of more than :data:`MAX_SYM_SIZE` operations (an intermediate variable inlined too often, a
loop that doubles an expression) raises :class:`TooBig`, which the translator reports as a gap
at the line that built it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Sym", "Const", "Named", "Param", "ParamDef", "State", "Deriv", "Time", "Input", "Op", "Call", "ResultRef",
           "Arr", "Str", "Struct", "StructArray", "Cell", "FuncValue", "Unknown", "SolverOutput", "TooBig", "Unsupported",
           "MAX_SYM_DEPTH", "MAX_SYM_SIZE", "MAX_ELEMENTS", "scalar", "const"]

MAX_SYM_DEPTH = 90
"""The deepest expression the translator builds (odelab's expression language accepts 200 levels)."""

MAX_SYM_SIZE = 1200
"""The most operations one translated expression may hold (odelab's expressions are at most 2000 characters)."""

MAX_ELEMENTS = 2_000_000
"""The most elements one array may hold (``zeros(1e9, 1)`` stops here, before anything is allocated)."""


class TooBig(Exception):
    """An expression grew past the translator's bounds."""


class Unsupported(Exception):
    """A construct odelab cannot translate; the message says what to write instead."""


class Sym:
    """An element: a number, a name or an operation. ``num`` is its value when constant, else None."""

    __slots__ = ("num", "depth", "size")
    num: float | None
    depth: int
    size: int

    def leaves(self):
        yield self


def _measure(node: Sym, children: tuple) -> None:
    depth = 1 + max((c.depth for c in children), default=0)
    size = 1 + sum(c.size for c in children)
    if depth > MAX_SYM_DEPTH:
        raise TooBig(f"an expression nests more than {MAX_SYM_DEPTH} operations deep")
    if size > MAX_SYM_SIZE:
        raise TooBig(f"an expression grows past {MAX_SYM_SIZE} operations (intermediate variables inlined into "
                     "each other)")
    node.depth = depth
    node.size = size


class Const(Sym):
    """A literal number."""

    __slots__ = ("value",)

    def __init__(self, value: float):
        self.value = float(value)
        self.num = self.value
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return f"Const({self.value!r})"


class Named(Sym):
    """A constant of the expression language written by name: ``pi``."""

    __slots__ = ("name",)

    def __init__(self, name: str, value: float):
        self.name = name
        self.num = float(value)
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return self.name


@dataclass(eq=False)
class ParamDef:
    """A constant the MATLAB file names (``k = 3``, ``p.m = 2``, ``p(2)``): a ``[parameters]`` entry if used."""

    hint: str  # the name the file gives it (made a valid identifier when written)
    definition: Sym
    line: int = 0
    file: str = ""
    note: str = ""  # how it was passed: "a trailing argument of ode45", "global", "a field of p"...
    gap: str = ""  # not empty: its value is not known (a function file's argument): what to write


class Param(Sym):
    __slots__ = ("definition",)

    def __init__(self, definition: ParamDef):
        self.definition = definition
        self.num = definition.definition.num
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return f"Param({self.definition.hint})"


class State(Sym):
    """The ``index``-th state (0-based), ``y(index + 1)`` in MATLAB."""

    __slots__ = ("index",)

    def __init__(self, index: int):
        self.index = index
        self.num = None
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return f"y{self.index + 1}"


class Deriv(Sym):
    """The derivative of the ``index``-th state, ``yp(index + 1)`` of an implicit ODE ``f(t, y, yp) = 0`` (ode15i)."""

    __slots__ = ("index",)

    def __init__(self, index: int):
        self.index = index
        self.num = None
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return f"der(y{self.index + 1})"


class Time(Sym):
    __slots__ = ()

    def __init__(self):
        self.num = None
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return "t"


class Input(Sym):
    """An input signal u(t) of the experiment (``interp1`` of a table in t)."""

    __slots__ = ("name", "spec")

    def __init__(self, name: str, spec: dict):
        self.name = name
        self.spec = spec
        self.num = None
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return self.name


class ResultRef(Sym):
    """A value of a solver call's result in a script: its last time or last state (a restart loop's data)."""

    __slots__ = ("call", "kind", "index")

    def __init__(self, call: Any, kind: str, index: int = 0):
        self.call = call
        self.kind = kind  # "t_end" (the last time), "y_end" (the last state `index`), "count"
        self.index = index
        self.num = None
        self.depth = 1
        self.size = 1

    def __repr__(self) -> str:
        return f"{self.kind}[{self.index}]"


_ARITH = {"+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b}
COMPARE = ("==", "~=", "<", "<=", ">", ">=")


def _power(a: float, b: float) -> float:
    with np.errstate(all="ignore"):
        return float(np.power(np.float64(a), np.float64(b)))


def _divide(a: float, b: float) -> float:
    with np.errstate(all="ignore"):
        return float(np.float64(a) / np.float64(b))


def _compare(op: str, a: float, b: float) -> float:
    return float({"==": a == b, "~=": a != b, "<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b}[op])


class Op(Sym):
    """``a op b`` (``+ - * / ^`` and the comparisons) or ``-a`` (``op == "neg"``, ``b`` None)."""

    __slots__ = ("op", "a", "b")

    def __init__(self, op: str, a: Sym, b: Sym | None = None):
        self.op = op
        self.a = a
        self.b = b
        _measure(self, (a,) if b is None else (a, b))
        self.num = self._value()

    def _value(self) -> float | None:
        a = self.a.num
        if a is None:
            return None
        if self.op == "neg":
            return -a
        b = self.b.num
        if b is None:
            return None
        if self.op in _ARITH:
            return float(np.float64(_ARITH[self.op](np.float64(a), np.float64(b))))
        if self.op == "/":
            return _divide(a, b)
        if self.op == "^":
            return _power(a, b)
        return _compare(self.op, a, b)

    def leaves(self):
        yield from self.a.leaves()
        if self.b is not None:
            yield from self.b.leaves()

    def __repr__(self) -> str:
        return f"(-{self.a!r})" if self.op == "neg" else f"({self.a!r} {self.op} {self.b!r})"


def _numpy_functions() -> dict[str, Any]:
    from odelab.expressions.functions import FUNCTIONS

    return dict(FUNCTIONS)


_FUNCTIONS: dict[str, Any] = {}


class Call(Sym):
    """``fn(args...)``: a function of odelab's expression language (``sin``, ``where``, ``max``...)."""

    __slots__ = ("fn", "args")

    def __init__(self, fn: str, args: tuple[Sym, ...]):
        self.fn = fn
        self.args = tuple(args)
        _measure(self, self.args)
        self.num = self._value()

    def _value(self) -> float | None:
        values = [a.num for a in self.args]
        if any(v is None for v in values):
            return None
        if not _FUNCTIONS:
            _FUNCTIONS.update(_numpy_functions())
        with np.errstate(all="ignore"):
            return float(_FUNCTIONS[self.fn](*[np.float64(v) for v in values]))

    def leaves(self):
        for a in self.args:
            yield from a.leaves()

    def __repr__(self) -> str:
        return f"{self.fn}({', '.join(repr(a) for a in self.args)})"


def const(value: float) -> Const:
    return Const(value)


# --- arrays and the other values ----------------------------------------------------------------


class Arr:
    """A numeric MATLAB array (``rows`` x ``cols``): a numpy array of plain numbers, or ``Sym`` items in
    column-major order. ``origin`` names a vector assigned to a variable (its elements become the parameters
    ``name_1``, ``name_2``... when an equation uses them); ``colon`` keeps ``a:h:b`` as written."""

    __slots__ = ("rows", "cols", "data", "items", "colon", "logical", "is_char", "source")

    def __init__(self, rows: int, cols: int, data: np.ndarray | None = None, items: list[Sym] | None = None,
                 colon: tuple | None = None, logical: bool = False):
        self.rows = rows
        self.cols = cols
        self.data = data  # float64, shape (rows, cols), when every element is a plain number
        self.items = items  # list of Sym, column-major, otherwise
        self.colon = colon
        self.logical = logical
        self.is_char = False
        self.source = None  # (path, column or None, columns, header): a table read from a data file

    @staticmethod
    def numeric(values) -> "Arr":
        data = np.asarray(values, dtype=float)
        if data.ndim == 0:
            data = data.reshape(1, 1)
        elif data.ndim == 1:
            data = data.reshape(1, -1)
        elif data.ndim > 2:
            raise Unsupported("arrays of more than two dimensions are not translated")
        return Arr(data.shape[0], data.shape[1], data=data)

    @staticmethod
    def scalar(item: Sym) -> "Arr":
        if isinstance(item, Const):
            return Arr(1, 1, data=np.array([[item.value]]))
        return Arr(1, 1, items=[item])

    @staticmethod
    def of_items(rows: int, cols: int, items: list[Sym]) -> "Arr":
        if all(isinstance(i, Const) for i in items):
            data = np.array([i.value for i in items], dtype=float).reshape(cols, rows).T if items else \
                np.zeros((rows, cols))
            return Arr(rows, cols, data=data)
        return Arr(rows, cols, items=list(items))

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.cols

    @property
    def size(self) -> int:
        return self.rows * self.cols

    @property
    def is_numeric(self) -> bool:
        return self.data is not None

    def item(self, k: int) -> Sym:
        """The k-th element (0-based, column-major) as a Sym."""
        if self.data is not None:
            return Const(self.data[k % self.rows, k // self.rows])
        return self.items[k]

    def all_items(self) -> list[Sym]:
        if self.data is not None:
            return [Const(v) for v in self.data.T.reshape(-1)]
        return list(self.items)

    def numbers(self) -> np.ndarray | None:
        """The values as a (rows, cols) float array, or None if an element is not constant."""
        if self.data is not None:
            return self.data
        values = [i.num for i in self.items]
        if any(v is None for v in values):
            return None
        return np.array(values, dtype=float).reshape(self.cols, self.rows).T if values else np.zeros(self.shape)

    def is_constant(self) -> bool:
        return self.data is not None or all(i.num is not None for i in self.items)

    def scalar_value(self) -> float | None:
        if self.size != 1:
            return None
        return float(self.data[0, 0]) if self.data is not None else self.items[0].num

    def __repr__(self) -> str:
        shown = self.data.tolist() if self.data is not None else self.items
        return f"Arr({self.rows}x{self.cols}, {shown})"


def scalar(value: float) -> Arr:
    return Arr(1, 1, data=np.array([[float(value)]]))


@dataclass(eq=False)
class Str:
    """A char array or a string: ``'RelTol'``, ``"ode45"``."""

    text: str


@dataclass(eq=False)
class Struct:
    """A 1x1 struct (``odeset`` returns one): fields by name, in the order they were set."""

    fields: dict[str, Any] = field(default_factory=dict)
    origin: str = ""  # the variable it was assigned to (its fields' parameters are named origin_field)
    odeset: bool = False


@dataclass(eq=False)
class StructArray:
    """A 1 x n struct array (``pars(2).beta = 0.5``): its elements, each a :class:`Struct`."""

    items: list = field(default_factory=list)
    origin: str = ""


@dataclass(eq=False)
class Cell:
    rows: int
    cols: int
    items: list[Any]


@dataclass(eq=False)
class FuncValue:
    """A function handle: ``@name`` (a function of the file, of a file beside it, or built in) or ``@(t, y) expr``.

    An anonymous function keeps the variables it captured when it was created (MATLAB's rule); a handle to a
    nested function sees its parent's variables as they are when it is called."""

    name: str = ""  # @name
    params: list[str] | None = None  # @(params) body
    body: Any = None  # nodes.Expr
    closure: Any = None  # the Scope an anonymous function captured, or a nested function's parent scope
    text: str = ""
    line: int = 0
    file: str = ""
    from_string: bool = False  # ode45('f', ...): MATLAB 5's string name (the ODE-file protocol)


@dataclass(eq=False)
class Unknown:
    """A value odelab cannot know without running the file: the reason, where it arose, and what to write."""

    reason: str
    line: int = 0
    file: str = ""
    construct: str = ""


@dataclass(eq=False)
class SolverOutput:
    """What a solver call returned, in a script: the time (``t``), the states (``y``), the events (``te``,
    ``ye``, ``ie``) or MATLAB's solution struct (``sol``)."""

    call: Any
    kind: str
