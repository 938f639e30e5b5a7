"""The value of each kind of expression node: numbers, strings, operators, matrices, ranges, handles, fields."""

from __future__ import annotations

import math

import numpy as np

from odelab.formats.matlab import nodes as n
from odelab.formats.matlab import ops
from odelab.formats.matlab.values import (Arr, Cell, Const, FuncValue, Op, SolverOutput, Str, Struct, Unknown,
                                          Unsupported)

__all__ = ["EXPRESSIONS", "colon_values", "arith"]


def _num(interp, node: n.Num, scope):
    if node.imaginary:
        raise Unsupported(f"the complex number {node.text} is not translated (odelab integrates real states)")
    return Arr(1, 1, data=np.array([[node.value]]))


def _str(interp, node: n.Str, scope):
    return Str(node.value)


def _end(interp, node: n.EndIndex, scope):
    if not scope.end_stack:
        raise Unsupported("`end` outside an index")
    return Arr(1, 1, data=np.array([[float(scope.end_stack[-1])]]))


def _colon(interp, node: n.Colon, scope):
    return Str(":")


_BINARY_ARITH = {"+", "-", ".*", "./", ".\\", ".^", "==", "~=", "<", "<=", ">", ">="}


def arith(interp, op: str, left, right):
    """``left op right`` on two values (numbers, char arrays), MATLAB's rules for each operator."""
    for value in (left, right):
        if isinstance(value, Unknown):
            return value
    a = interp.numeric(left, "an operand")
    b = interp.numeric(right, "an operand")
    if op in _BINARY_ARITH:
        return ops.elementwise(op, a, b)
    if op == "*":
        return ops.matmul(a, b)
    if op == "/":
        if b.size == 1:
            return ops.elementwise("/", a, b)
        return _solve(a, b, right_division=True)
    if op == "\\":
        if a.size == 1:
            return ops.elementwise("\\", a, b)
        return _solve(a, b, right_division=False)
    if op == "^":
        if a.size == 1 and b.size == 1:
            return ops.elementwise("^", a, b)
        return _matrix_power(a, b)
    if op in ("&", "&&"):
        return ops.logical_and(a, b)
    if op in ("|", "||"):
        return ops.logical_or(a, b)
    raise Unsupported(f"the operator `{op}` is not translated")


MAX_SYMBOLIC_SOLVE = 3
"""``M \\ f`` with a matrix that depends on the state is written by Cramer's rule up to 3 x 3."""


def _solve(a: Arr, b: Arr, right_division: bool) -> Arr:
    """``A \\ b`` (``b / A``): with a constant matrix, its inverse times b; with a small matrix that depends on the
    state (a mass matrix solved in the right-hand side), Cramer's rule."""
    if right_division:  # b / A = (A' \ b')'
        return ops.transpose(_solve(ops.transpose(b), ops.transpose(a), right_division=False))
    numbers = a.numbers()
    if a.rows != a.cols:
        raise Unsupported("`\\` with a matrix that is not square is not translated")
    if b.rows != a.rows:
        raise Unsupported(f"`\\` of a {a.rows}x{a.cols} matrix and {b.rows} rows")
    if numbers is not None:
        return ops.matmul(Arr.numeric(np.linalg.inv(numbers)), b)
    if a.rows > MAX_SYMBOLIC_SOLVE:
        raise Unsupported(f"`\\` with a {a.rows}x{a.rows} matrix that depends on the time or the state is not "
                          "translated (up to 3x3); give the matrix as odeset's Mass (M y' = f) instead")
    n = a.rows
    cols = [[a.item(j * n + i) for i in range(n)] for j in range(n)]
    det = _det(cols)
    items = []
    for k in range(b.cols):
        rhs = [b.item(k * n + i) for i in range(n)]
        for j in range(n):
            replaced = [rhs if c == j else cols[c] for c in range(n)]
            items.append(Op("/", _det(replaced), det))
    return Arr.of_items(n, b.cols, items)


def _det(cols: list[list]):
    """The determinant of a 1x1, 2x2 or 3x3 matrix given by columns (cofactor expansion)."""
    n = len(cols)
    if n == 1:
        return cols[0][0]
    if n == 2:
        return Op("-", Op("*", cols[0][0], cols[1][1]), Op("*", cols[1][0], cols[0][1]))
    total = None
    for j in range(3):
        minor = [[cols[c][r] for r in (1, 2)] for c in range(3) if c != j]
        term = Op("*", cols[j][0], _det(minor))
        total = term if total is None else (Op("-", total, term) if j == 1 else Op("+", total, term))
    return total


def _matrix_power(a: Arr, b: Arr) -> Arr:
    power = b.scalar_value()
    if b.size != 1 or power is None or power != int(power) or power < 0 or power > 64 or a.rows != a.cols:
        raise Unsupported("a matrix power is translated only for a square matrix and a whole power from 0 to 64")
    result = Arr.numeric(np.eye(a.rows))
    for _ in range(int(power)):
        result = ops.matmul(result, a)
    return result


def _binary(interp, node: n.Binary, scope):
    if node.op in ("&&", "||"):
        left = interp.eval(node.left, scope)
        if isinstance(left, Arr) and left.is_constant() and left.size >= 1:
            truth = bool(np.all(left.numbers() != 0))
            if node.op == "&&" and not truth:
                return Arr(1, 1, data=np.array([[0.0]]))
            if node.op == "||" and truth:
                return Arr(1, 1, data=np.array([[1.0]]))
            right = interp.eval(node.right, scope)
            if isinstance(right, Unknown):
                return right
            out = ops.logical_not(ops.logical_not(interp.numeric(right)))
            return out
        return arith(interp, node.op, left, interp.eval(node.right, scope))
    return arith(interp, node.op, interp.eval(node.left, scope), interp.eval(node.right, scope))


def _unary(interp, node: n.Unary, scope):
    value = interp.eval(node.operand, scope)
    if isinstance(value, Unknown):
        return value
    value = interp.numeric(value, "an operand")
    if node.op == "-":
        return ops.negate(value)
    if node.op == "~":
        return ops.logical_not(value)
    return value


def _postfix(interp, node: n.Postfix, scope):
    value = interp.eval(node.operand, scope)
    if isinstance(value, (Unknown, SolverOutput)):
        return value
    if isinstance(value, Cell):
        return Cell(value.cols, value.rows, list(value.items))
    return ops.transpose(interp.numeric(value))


def _matrix(interp, node: n.Matrix, scope):
    if node.cell:
        rows = [[v for e in row for v in _elements(interp, e, scope)] for row in node.rows]
        width = max((len(r) for r in rows), default=0)
        if any(len(r) != width for r in rows):
            raise Unsupported("the rows of a cell array {...} have different lengths")
        items = [rows[i][j] for j in range(width) for i in range(len(rows))]
        return Cell(len(rows), width, items)
    blocks: list[list[Arr]] = []
    strings = False
    for row in node.rows:
        out_row = []
        for element in row:
            for value in _elements(interp, element, scope):
                if isinstance(value, Unknown):
                    return value
                if isinstance(value, Str):
                    strings = True
                out_row.append(interp.numeric(value, "an element of [...]"))
        blocks.append(out_row)
    result = ops.concat(blocks)
    if strings and result.is_numeric and result.rows <= 1:
        return Str("".join(chr(int(c)) for c in result.data.reshape(-1)))
    return result


def _elements(interp, element: n.Expr, scope) -> list:
    if isinstance(element, n.Index) and element.brace:
        return interp.eval_multi(element, scope, 1)
    return [interp.eval(element, scope)]


def colon_values(start: float, step: float, stop: float) -> np.ndarray:
    """MATLAB's ``start:step:stop`` (odelab's own colon, so [time] output = "a:h:b" gives the same points)."""
    from odelab.expressions.matlab import colon_range

    if step == 0 or (step > 0 and start > stop) or (step < 0 and start < stop) or not all(
            math.isfinite(v) for v in (start, step, stop)):
        return np.zeros((1, 0))
    count = math.floor((stop - start) / step + 1e-10) + 1
    ops.check_elements(count, "a range")
    return np.asarray(colon_range(start, step, stop), dtype=float).reshape(1, -1)


def _range(interp, node: n.Range, scope):
    parts = [interp.eval(p, scope) if p is not None else None for p in (node.start, node.step, node.stop)]
    for p in parts:
        if isinstance(p, Unknown):
            return p
    numbers = []
    for p in parts:
        if p is None:
            numbers.append(1.0)
            continue
        value = interp.numeric(p, "a range's bound")
        if value.size == 0:
            return Arr(1, 0, data=np.zeros((1, 0)))
        number = value.item(0).num
        if number is None:
            raise Unsupported("a range whose bounds depend on the time or the state is not translated")
        numbers.append(number)
    start, step, stop = numbers
    out = Arr.numeric(colon_values(start, step, stop))
    if out.cols == 0:
        out = Arr(1, 0, data=np.zeros((1, 0)))
    out.colon = (start, step, stop)
    return out


def _anon(interp, node: n.AnonFn, scope):
    from odelab.formats.matlab.scope import Scope

    captured = Scope(scope.file, function=scope.function, mode=scope.mode)
    captured.vars = _visible(scope, interp)
    return FuncValue(params=node.params, body=node.body, closure=captured, text=_anon_text(node, scope, interp),
                     line=node.line, file=scope.file)


def _visible(scope, interp) -> dict:
    """The variables an anonymous function captures: every one it can see, as they are now."""
    out: dict = {}
    chain = []
    s = scope
    while s is not None:
        chain.append(s)
        s = s.parent
    for s in reversed(chain):
        out.update(s.vars)
    for name in scope.globals:
        if name in interp.globals:
            out[name] = interp.globals[name]
    return out


def _anon_text(node: n.AnonFn, scope, interp) -> str:
    """The anonymous function as written (``@(t, y) ...``), up to where it ends on its line."""
    source = interp.file_of(scope.file)
    if source is None or not 0 < node.line <= len(source.lines):
        return f"@({', '.join(node.params)}) ..."
    line = source.lines[node.line - 1]
    start = line.find("@(")
    if start < 0:
        return f"@({', '.join(node.params)}) ..."
    depth, quote, end = 0, None, len(line)
    seen_params = False
    for i in range(start + 1, len(line)):
        ch = line[i]
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"" and depth > 0:
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
            if depth < 0:
                end = i
                break
            if depth == 0 and not seen_params:
                seen_params = True
        elif ch in ",;%" and depth == 0 and seen_params:
            end = i
            break
    text = line[start:end].strip()
    return text if len(text) <= 80 else text[:77] + "..."


def _handle(interp, node: n.FuncHandle, scope):
    fn = interp.find_function(node.name, scope)
    closure = scope if fn is not None and getattr(fn, "parent", None) is not None else None
    return FuncValue(name=node.name, closure=closure, line=node.line, file=scope.file)


def _field(interp, node: n.Field, scope):
    base = interp.eval(node.target, scope)
    return field_of(interp, base, node.name, node.line)


def field_of(interp, base, name: str, line: int):
    if isinstance(base, Unknown):
        return base
    if isinstance(base, SolverOutput):
        from odelab.formats.matlab.results import solution_field

        return solution_field(base, name)
    if isinstance(base, Struct):
        if name in base.fields:
            return base.fields[name]
        if base.odeset:
            from odelab.formats.matlab.options import odeset_field

            return odeset_field(base, name)
        raise Unsupported(f"the struct has no field `{name}`")
    raise Unsupported(f"`.{name}` on a value that is not a struct")


def _dynfield(interp, node: n.DynField, scope):
    base = interp.eval(node.target, scope)
    return field_of(interp, base, interp.field_name(node.name, scope), node.line)


def _tilde(interp, node, scope):
    raise Unsupported("`~` is only an output placeholder")


EXPRESSIONS = {
    n.Num: _num, n.Str: _str, n.EndIndex: _end, n.Colon: _colon, n.Binary: _binary, n.Unary: _unary,
    n.Postfix: _postfix, n.Matrix: _matrix, n.Range: _range, n.AnonFn: _anon, n.FuncHandle: _handle,
    n.Field: _field, n.DynField: _dynfield, n.Tilde: _tilde,
}

__all__ += ["field_of", "Const"]
