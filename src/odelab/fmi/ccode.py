"""C source from odelab's generated right-hand sides, re-emitted node by node.

odelab already turns a system into numba source from checked data only: the expression
language's validated trees (:mod:`odelab.solvers.compiled.codegen`), a signal's numbers as
run-time data (:mod:`odelab.solvers.compiled.inputs`), a diagram's blocks
(:mod:`odelab.systems.diagram.codegen`). This module reads that source back with :mod:`ast`
and writes C from a closed whitelist: local variables become ``l0, l1...`` (no name of the
file reaches the C text), ``_y[i]``, ``_p[i]`` and ``_out[i]`` are arrays indexed by integers,
every number is written again from its float value (``%.17g``), and every call is one of the
language's functions, mapped to a C helper of ``odelab_model.h`` or to ``<math.h>``. Anything
else (a loop, an attribute, a string, a name not assigned before) is refused: the text is
never pasted.
"""

from __future__ import annotations

import ast
import math
import re

from odelab.exceptions import InputError

__all__ = ["c_function", "c_number"]

# numba's numpy calls -> C (math.h or odelab's helpers, which keep numpy's NaN and sign rules)
_NP = {"sin": "sin", "cos": "cos", "tan": "tan", "arcsin": "asin", "arccos": "acos", "arctan": "atan",
       "arctan2": "atan2", "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "exp": "exp", "log": "log",
       "log10": "log10", "sqrt": "sqrt", "abs": "fabs", "sign": "odelab_sign", "floor": "floor", "ceil": "ceil",
       "mod": "odelab_npmod", "fmod": "fmod"}
_HELPERS = {"_heaviside": "odelab_heaviside", "_step": "odelab_step", "_where": "odelab_where",
            "_min": "odelab_min", "_max": "odelab_max", "_mod": "odelab_mod", "_rem": "fmod",
            "_square": "odelab_square", "_sawtooth": "odelab_sawtooth", "_pulse": "odelab_pulse",
            "_pow": "pow"}
_ARRAYS = {"_y": "y", "_p": "p"}
_BIN = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_CMP = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}
_LOCAL = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def c_number(value: float) -> str:
    """A double as C text, from its value (never from the user's spelling)."""
    value = float(value)
    if math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    text = f"{value:.17g}"
    if not any(c in text for c in ".eEn"):
        text += ".0"
    return f"({text})" if value < 0 else text


class _Emitter:
    def __init__(self, where: str, size: dict[str, int]):
        self.where = where
        self.size = size  # entries of y, p, out: indices are checked against them
        self.locals: dict[str, str] = {"t": "t"}
        self.lines: list[str] = []

    def refuse(self, node: ast.AST, why: str):
        raise InputError(f"the FMU generator cannot write {self.where} in C: {why} "
                         f"(line {getattr(node, 'lineno', '?')} of odelab's generated source).")

    def index(self, node: ast.AST, array: str) -> int:
        if not (isinstance(node, ast.Constant) and type(node.value) is int):
            self.refuse(node, "an index that is not an integer")
        if not 0 <= node.value < self.size[array]:
            self.refuse(node, f"index {node.value} outside {array} ({self.size[array]} entries)")
        return node.value

    def slice_of_p(self, node: ast.AST) -> tuple[int, int]:
        if not (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "_p"
                and isinstance(node.slice, ast.Slice) and node.slice.step is None):
            self.refuse(node, "a table that is not a slice of the parameter vector")
        lo = self.index(node.slice.lower, "p")
        hi = node.slice.upper
        if not (isinstance(hi, ast.Constant) and type(hi.value) is int and lo < hi.value <= self.size["p"]):
            self.refuse(node, "a slice outside the parameter vector")
        return lo, hi.value

    def expr(self, node: ast.AST) -> str:  # recursion is bounded: the expression language's MAX_DEPTH
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.refuse(node, "a constant that is not a number")
            return c_number(node.value)
        if isinstance(node, ast.Name):
            if node.id == "_INF":
                return "INFINITY"
            if node.id == "_NAN":
                return "NAN"
            if node.id not in self.locals:
                self.refuse(node, "a name used before it is assigned")
            return self.locals[node.id]
        if isinstance(node, ast.Attribute):
            if isinstance(node.value, ast.Name) and node.value.id == "_np" and node.attr == "pi":
                return c_number(math.pi)
            self.refuse(node, "an attribute")
        if isinstance(node, ast.Subscript):
            if isinstance(node.value, ast.Name) and node.value.id in _ARRAYS:
                array = _ARRAYS[node.value.id]
                return f"{array}[{self.index(node.slice, array)}]"
            self.refuse(node, "indexing of something other than the states or the parameters")
        if isinstance(node, ast.BinOp) and type(node.op) in _BIN:
            return f"({self.expr(node.left)} {_BIN[type(node.op)]} {self.expr(node.right)})"
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            return f"pow({self.expr(node.left)}, {self.expr(node.right)})"
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            return f"({'-' if isinstance(node.op, ast.USub) else '+'}{self.expr(node.operand)})"
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            return f"(!{self.expr(node.operand)})"
        if isinstance(node, ast.Compare) and all(type(op) in _CMP for op in node.ops):
            parts = [node.left, *node.comparators]
            tests = [f"({self.expr(a)} {_CMP[type(op)]} {self.expr(b)})"
                     for a, op, b in zip(parts[:-1], node.ops, parts[1:])]
            return "(" + " && ".join(tests) + ")"
        if isinstance(node, ast.BoolOp):
            op = " && " if isinstance(node.op, ast.And) else " || "
            return "(" + op.join(self.expr(v) for v in node.values) + ")"
        if isinstance(node, ast.IfExp):
            return f"({self.expr(node.test)} ? {self.expr(node.body)} : {self.expr(node.orelse)})"
        if isinstance(node, ast.Call) and not node.keywords:
            return self.call(node)
        self.refuse(node, f"a {type(node).__name__} node")

    def call(self, node: ast.Call) -> str:
        f = node.func
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "_np":
            if f.attr == "interp" and len(node.args) == 3:
                x = self.expr(node.args[0])
                (a, b), (c, d) = self.slice_of_p(node.args[1]), self.slice_of_p(node.args[2])
                if b - a != d - c:
                    self.refuse(node, "a table whose columns differ in length")
                return f"odelab_interp({x}, p + {a}, p + {c}, {b - a})"
            name = _NP.get(f.attr)
        elif isinstance(f, ast.Name):
            name = _HELPERS.get(f.id)
        else:
            name = None
        if name is None:
            self.refuse(node, "a call of a function outside the expression language")
        return f"{name}({', '.join(self.expr(a) for a in node.args)})"

    def statement(self, node: ast.stmt) -> None:
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            value = self.expr(node.value)
            target = node.targets[0]
            if isinstance(target, ast.Subscript) and isinstance(target.value, ast.Name) and target.value.id == "_out":
                self.lines.append(f"    out[{self.index(target.slice, 'out')}] = {value};")
                return
            if isinstance(target, ast.Name) and _LOCAL.match(target.id) and target.id not in ("t", "_y", "_p", "_out"):
                if target.id not in self.locals:
                    self.locals[target.id] = f"l{len(self.locals) - 1}"
                    self.lines.append(f"    double {self.locals[target.id]} = {value};")
                else:
                    self.lines.append(f"    {self.locals[target.id]} = {value};")
                return
        self.refuse(node, f"a {type(node).__name__} statement")


def c_function(source: str, function: str, c_name: str, size: dict[str, int], where: str) -> str:
    """The C twin of ``function(t, _y, _p, _out)`` in the generated module ``source``:
    ``static void c_name(double t, const double *y, const double *p, double *out)``."""
    tree = ast.parse(source)
    found = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == function]
    if len(found) != 1 or [a.arg for a in found[0].args.args] != ["t", "_y", "_p", "_out"]:
        raise InputError(f"the FMU generator found no function {function}(t, _y, _p, _out) for {where}.")
    emitter = _Emitter(where, size)
    for statement in found[0].body:
        emitter.statement(statement)
    head = f"static void {c_name}(double t, const double *y, const double *p, double *out)"
    body = ["    (void)t; (void)y; (void)p; (void)out;", *emitter.lines]
    return head + "\n{\n" + "\n".join(body) + "\n}\n"
