"""Between odelab's expression language and SymPy, both ways, without ``sympify``.

SymPy's ``sympify`` evaluates its text as Python, so user text never reaches it: expressions are
parsed by :func:`odelab.expressions.parse_expression` (its whitelist of numbers, names,
operators and the language's functions) and the checked syntax tree is turned into SymPy
here, node by node. The way back prints SymPy expressions in the expression language
(``^`` for powers, ``abs``, ``min``...), and those strings are compiled by odelab's own
compiler. Functions without a SymPy counterpart that the derivation needs (``where``, the
comparisons) stay opaque: they are carried through untouched and printed back as written.
"""

from __future__ import annotations

import ast
from collections.abc import Mapping

from odelab.exceptions import InputError

__all__ = ["to_sympy", "to_text", "require_sympy"]


def require_sympy():
    """Import SymPy, or say how to install it (only networks need it)."""
    try:
        import sympy
    except ImportError:  # pragma: no cover - sympy is a dependency of odelab
        raise InputError("kind = \"network\" derives its equations with SymPy, which is not installed: "
                         "pip install sympy (or reinstall odelab: pip install -e .).") from None
    return sympy


_FUNCTIONS = {  # the language's function -> SymPy's
    "sin": "sin", "cos": "cos", "tan": "tan", "asin": "asin", "acos": "acos", "atan": "atan",
    "atan2": "atan2", "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "exp": "exp", "log": "log",
    "sqrt": "sqrt", "abs": "Abs", "sign": "sign", "floor": "floor", "ceil": "ceiling",
    "min": "Min", "max": "Max",
}
_OPAQUE = {"heaviside", "step", "where", "log10"}
_COMPARE = {ast.Lt: ("lt", "<"), ast.LtE: ("le", "<="), ast.Gt: ("gt", ">"), ast.GtE: ("ge", ">="),
            ast.Eq: ("eq", "=="), ast.NotEq: ("ne", "!=")}
_COMPARE_TEXT = {name: text for name, text in _COMPARE.values()}


def _opaque(name: str):
    sp = require_sympy()
    return sp.Function(f"odelab_{name}")


def to_sympy(parsed, symbols: Mapping[str, object]):
    """The SymPy expression of a parsed expression; ``symbols`` maps each free name to its symbol.

    Integers stay exact; other numbers become SymPy Floats of the same binary value.
    """
    sp = require_sympy()
    parsed = parsed.binding(symbols)  # a symbol named like a constant shadows it (shadowed_constants)

    def node(n):
        if isinstance(n, ast.Constant):
            value = n.value
            if isinstance(value, int):
                return sp.Integer(value)
            if float(value).is_integer() and abs(value) < 2**53:
                return sp.Integer(int(value))
            return sp.Float(float(value), 17)
        if isinstance(n, ast.Name):
            if n.id in parsed.constants:  # still a constant: SymPy's exact pi and E
                return {"pi": sp.pi, "e": sp.E}[n.id]
            return symbols[n.id]
        if isinstance(n, ast.Attribute):
            return symbols[f"{n.value.id}.{n.attr}"]
        if isinstance(n, ast.BinOp):
            left, right = node(n.left), node(n.right)
            if isinstance(n.op, ast.Add):
                return left + right
            if isinstance(n.op, ast.Sub):
                return left - right
            if isinstance(n.op, ast.Mult):
                return left * right
            if isinstance(n.op, ast.Div):
                return left / right
            if isinstance(n.op, ast.Pow):
                return left ** right
        if isinstance(n, ast.UnaryOp):
            operand = node(n.operand)
            return -operand if isinstance(n.op, ast.USub) else operand
        if isinstance(n, ast.Compare):
            terms = [node(n.left), *(node(c) for c in n.comparators)]
            out = None
            for op, a, b in zip(n.ops, terms[:-1], terms[1:]):
                one = _opaque(_COMPARE[type(op)][0])(a, b)
                out = one if out is None else out * one
            return out
        if isinstance(n, ast.Call):
            args = [node(a) for a in n.args]
            name = n.func.id
            if name in _OPAQUE:
                return _opaque(name)(*args)
            if name == "atan2":
                return sp.atan2(*args)
            if name in ("min", "max"):
                return getattr(sp, _FUNCTIONS[name])(*args)
            return getattr(sp, _FUNCTIONS[name])(*args)
        raise AssertionError(f"unvalidated node {type(n).__name__}")  # pragma: no cover

    return node(parsed.tree.body)


def _printer_class():
    sp = require_sympy()
    from sympy.printing.precedence import PRECEDENCE, precedence
    from sympy.printing.str import StrPrinter

    back = {v: k for k, v in _FUNCTIONS.items()}

    class Printer(StrPrinter):
        """SymPy -> the expression language; sums print their positive terms first."""

        def _print_Add(self, expr, order=None):
            terms = list(self._as_ordered_terms(expr, order=order))
            terms.sort(key=lambda term: term.could_extract_minus_sign())
            out = []
            for term in terms:
                sign = "-" if term.could_extract_minus_sign() else "+"
                if sign == "-":
                    term = -term
                text = self._print(term)
                if precedence(term) <= PRECEDENCE["Add"]:
                    text = f"({text})"
                out += [sign, text]
            if out[0] == "+":
                out = out[1:]
            else:
                out = ["-" + out[1], *out[2:]]
            return " ".join(out)

        def _print_Pow(self, expr, rational=False):
            base, exp = expr.as_base_exp()
            if exp == sp.Rational(1, 2):
                return f"sqrt({self._print(base)})"
            if exp.is_Number and exp < 0:
                if exp == -1:
                    return f"1/{self.parenthesize(base, PRECEDENCE['Pow'])}"
                return f"1/{self._print(sp.Pow(base, -exp, evaluate=False))}" if not base.is_Add \
                    else f"1/{self.parenthesize(base, PRECEDENCE['Pow'])}^{self.parenthesize(-exp, PRECEDENCE['Pow'])}"
            return f"{self.parenthesize(base, PRECEDENCE['Pow'], strict=True)}^" \
                   f"{self.parenthesize(exp, PRECEDENCE['Pow'], strict=False)}"

        def _print_Mul(self, expr):
            # parameters before element variables (``b*mass.v``, not ``mass.v*b``); a quotient
            # over one denominator (``(f - k*mass.x)/m``)
            coeff, rest = expr.as_coeff_Mul()
            if coeff.is_negative:
                return "-" + self._print(sp.Mul(-coeff, rest, evaluate=False) if coeff != -1 else rest)
            num, den = [], []
            for f in sp.Mul.make_args(rest):
                b, e = f.as_base_exp()
                if e.is_Number and e.is_negative:
                    den.append(b if e == -1 else sp.Pow(b, -e, evaluate=False))
                else:
                    num.append(f)
            if coeff.is_Rational and coeff != 1:
                if coeff.p != 1:
                    num.insert(0, sp.Integer(coeff.p))
                if coeff.q != 1:
                    den.insert(0, sp.Integer(coeff.q))
            elif coeff != 1:
                num.insert(0, coeff)

            def element(f):
                return any("." in getattr(v, "name", "") for v in f.free_symbols)

            def joined(factors):
                factors = sorted(factors, key=element)
                return "*".join(self.parenthesize(f, PRECEDENCE["Mul"], strict=False) for f in factors)

            top = joined(num) if num else "1"
            if not den:
                return top
            bottom = joined(den)
            if len(den) > 1:
                bottom = f"({bottom})"
            return f"{top}/{bottom}"

        def _print_Exp1(self, expr):
            return "e"

        def _print_Pi(self, expr):
            return "pi"

        def _print_Float(self, expr):
            return repr(float(expr))

        def _print_Function(self, expr):
            name = expr.func.__name__
            args = ", ".join(self._print(a) for a in expr.args)
            if name.startswith("odelab_"):
                name = name[len("odelab_"):]
                if name in _COMPARE_TEXT:
                    a, b = (self._print(x) for x in expr.args)
                    return f"({a} {_COMPARE_TEXT[name]} {b})"
            return f"{back.get(name, name)}({args})"

        _print_Abs = _print_Function
        _print_sign = _print_Function
        _print_floor = _print_Function
        _print_ceiling = _print_Function

        def _print_MinMaxBase(self, expr):
            name = "min" if isinstance(expr, sp.Min) else "max"
            return f"{name}({', '.join(self._print(a) for a in expr.args)})"

        _print_Min = _print_MinMaxBase
        _print_Max = _print_MinMaxBase

        def _print_Symbol(self, expr):
            return expr.name

    return Printer


_PRINTER = None


def to_text(expr) -> str:
    """A SymPy expression written in odelab's expression language (``(f - b*mass.v)/m``)."""
    global _PRINTER
    if _PRINTER is None:
        _PRINTER = _printer_class()()
    return _PRINTER.doprint(expr)
