"""Symbolic values written in odelab's expression language, with the names an experiment file gives them.

States are written by their names, parameters by names made from what the MATLAB file called
them (``k``, ``p_2``, ``par_m``: valid identifiers, none shadowing a function, the time or a
state), numbers as the shortest text that reads back as the same double. Parentheses follow
the expression language's (Python's) precedence, so MATLAB's left-associative ``a^b^c`` is
written ``(a^b)^c`` and no sum is regrouped (floating-point addition is not associative).
"""

from __future__ import annotations

import keyword
import math
import re

from odelab.formats.matlab.values import (COMPARE, Call, Const, Deriv, Input, Named, Op, Param, ParamDef, ResultRef,
                                          State, Sym, Time, Unsupported)

__all__ = ["Namer", "number_text", "identifier"]

_IDENT = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_OPS = {"==": "==", "~=": "!=", "<": "<", "<=": "<=", ">": ">", ">=": ">="}
# precedence in the expression language (Python's): comparison < + - < * / < unary - < ^ < atoms
_COMPARE, _ADD, _MUL, _UNARY, _POW, _ATOM = 1, 2, 3, 4, 5, 6


def number_text(value: float) -> str:
    """A double as the expression language reads it back bit for bit: 3, 0.51, 1e-05, 1e999 (infinity)."""
    if math.isnan(value):
        raise Unsupported("NaN in an equation is not translated")
    if math.isinf(value):
        return "1e999" if value > 0 else "-1e999"
    if value == int(value) and abs(value) < 1e15 and not (value == 0 and math.copysign(1.0, value) < 0):
        return str(int(value))
    return repr(value)


def identifier(hint: str, reserved: set[str]) -> str:
    """``hint`` as a name an experiment file accepts (not reserved, not a keyword)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", hint).strip("_") or "p"
    if not name[0].isalpha():
        name = "p" + name
    if keyword.iskeyword(name) or name in reserved or name.startswith("_"):
        name += "_"
    return name


def _reserved_words() -> set[str]:
    """Names nothing of an imported file may take (a state cannot shadow a constant either)."""
    from odelab.expressions.functions import CONSTANTS, FUNCTIONS

    return set(FUNCTIONS) | set(CONSTANTS) | {"t", "lag", "True", "False", "None"}


def _parameter_reserved() -> set[str]:
    """A parameter may shadow `e` (MATLAB has no constant e: the file's `e` is a variable), not `pi` (written as pi)."""
    return _reserved_words() - {"e"}


class Namer:
    """Names for one experiment: states (given), inputs, and the parameters its expressions use.

    ``texts`` of parameters are collected as they are met: :attr:`parameters` is the ``[parameters]``
    table (name -> number or expression text), in the order first used.
    """

    def __init__(self, states: list[str], inputs: list[str] = ()):
        self.states = list(states)
        self.inputs = list(inputs)
        self.reserved = _parameter_reserved()
        self.taken = set(self.states) | set(self.inputs)
        self.names: dict[int, str] = {}  # id(ParamDef) -> name
        self.defs: dict[str, ParamDef] = {}
        self.parameters: dict[str, object] = {}
        self.uses_pi = False
        self.inputs_used: set[str] = set()

    def param_name(self, definition: ParamDef) -> str:
        key = id(definition)
        if key in self.names:
            return self.names[key]
        base = identifier(definition.hint, self.reserved)
        name = base
        k = 2
        while name in self.taken:
            other = self.defs.get(name)
            if other is not None and _same(other, definition):
                self.names[key] = name
                return name
            name = f"{base}_{k}"
            k += 1
        self.taken.add(name)
        self.names[key] = name
        self.defs[name] = definition
        value = definition.definition
        self.parameters[name] = None  # reserve the place: parameters in the order first used
        self.parameters[name] = value.value if isinstance(value, Const) else self.text(value)
        if isinstance(self.parameters[name], float) and self.parameters[name] == int(self.parameters[name]) \
                and abs(self.parameters[name]) < 1e15:
            self.parameters[name] = int(self.parameters[name])
        return name

    def value(self, item: Sym):
        """An [initial]/[time] value: a number when the element is one (or a parameter that is one), else text."""
        if isinstance(item, Const):
            return _plain(item.value)
        if isinstance(item, Param) and isinstance(item.definition.definition, Const):
            return _plain(item.definition.definition.value)
        return self.text(item)

    def text(self, item: Sym) -> str:
        return self._text(item)[0]

    def _text(self, item: Sym) -> tuple[str, int]:
        if isinstance(item, Const):
            text = number_text(item.value)
            return text, _UNARY if text.startswith("-") else _ATOM
        if isinstance(item, Named):
            self.uses_pi = True
            return item.name, _ATOM
        if isinstance(item, Param):
            return self.param_name(item.definition), _ATOM
        if isinstance(item, State):
            return self.states[item.index], _ATOM
        if isinstance(item, Time):
            return "t", _ATOM
        if isinstance(item, Deriv):
            return f"der({self.states[item.index]})", _ATOM
        if isinstance(item, Input):
            self.inputs_used.add(item.name)
            return item.name, _ATOM
        if isinstance(item, ResultRef):
            raise Unsupported("a value from a solver's result is used in an equation")
        if isinstance(item, Call):
            return f"{item.fn}({', '.join(self._text(a)[0] for a in item.args)})", _ATOM
        if isinstance(item, Op):
            return self._op(item)
        raise Unsupported(f"{type(item).__name__} cannot be written in an expression")

    def _op(self, item: Op) -> tuple[str, int]:
        if item.op == "neg":
            inner, prec = self._text(item.a)
            return "-" + (inner if prec >= _UNARY and not inner.startswith("-") else f"({inner})"), _UNARY
        left, lp = self._text(item.a)
        right, rp = self._text(item.b)
        if item.op in COMPARE:
            return f"{_wrap(left, lp, _COMPARE + 1)} {_OPS[item.op]} {_wrap(right, rp, _COMPARE + 1)}", _COMPARE
        if item.op in ("+", "-"):
            return f"{_wrap(left, lp, _ADD)} {item.op} {_wrap(right, rp, _ADD + 1)}", _ADD
        if item.op in ("*", "/"):
            return f"{_wrap(left, lp, _MUL)}{item.op}{_wrap(right, rp, _UNARY)}", _MUL
        if item.op == "^":
            return f"{_wrap(left, lp, _ATOM)}^{_wrap(right, rp, _UNARY)}", _POW
        raise Unsupported(f"the operator {item.op} is not translated")


def _wrap(text: str, prec: int, needed: int) -> str:
    return text if prec >= needed else f"({text})"


def _plain(value: float):
    return int(value) if value == int(value) and abs(value) < 1e15 and math.isfinite(value) else value


def _same(a: ParamDef, b: ParamDef) -> bool:
    x, y = a.definition, b.definition
    if isinstance(x, Const) and isinstance(y, Const):
        return x.value == y.value or (math.isnan(x.value) and math.isnan(y.value))
    return x is y
