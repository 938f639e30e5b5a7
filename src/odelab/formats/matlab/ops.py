"""MATLAB's array operations on :class:`~.values.Arr`: elementwise arithmetic with implicit expansion, the
matrix product (a constant matrix times the state vector becomes one sum per row), transposes,
concatenation, indexing with ``end``, ``:`` and ranges, and indexed assignment that grows an array
as MATLAB does (``dydt = zeros(2, 1); dydt(1) = ...``).

Plain numbers stay numpy arrays (a script's ``linspace`` and data tables); as soon as an element is a
parameter, the time or a state, the array holds :class:`~.values.Sym` items and each operation builds
expressions.
"""

from __future__ import annotations

import numpy as np

from odelab.formats.matlab.values import (COMPARE, MAX_ELEMENTS, Arr, Call, Const, Op, Sym, Unsupported)

__all__ = ["elementwise", "negate", "matmul", "transpose", "concat", "index", "assign_index", "check_elements",
           "truth", "logical_not", "logical_and", "logical_or", "COLON"]

COLON = object()  # a `:` index


def check_elements(count: float, what: str = "an array") -> None:
    if count > MAX_ELEMENTS:
        raise Unsupported(f"{what} of {count:,.0f} elements is beyond odelab's budget of {MAX_ELEMENTS:,} "
                          "elements per array")


def _broadcast(a: tuple[int, int], b: tuple[int, int]) -> tuple[int, int]:
    out = []
    for x, y in zip(a, b):
        if x == y or y == 1:
            out.append(x)
        elif x == 1:
            out.append(y)
        else:
            raise Unsupported(f"arrays of sizes {a[0]}x{a[1]} and {b[0]}x{b[1]} do not match")
    return out[0], out[1]


_NUMPY = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "^": np.power,
          "==": np.equal, "~=": np.not_equal, "<": np.less, "<=": np.less_equal, ">": np.greater,
          ">=": np.greater_equal}


def sym_op(op: str, a: Sym, b: Sym) -> Sym:
    """``a op b`` element by element, without the zeros and ones a constant matrix holds (exact in floating point
    for finite values: ``x + 0`` is x, ``0*x`` is 0, ``1*x`` is x)."""
    if op == "\\":
        return Op("/", b, a)
    if op == "*":
        term = _term(a, b)
        return Const(0.0) if term is None else term
    if op == "+":
        if isinstance(a, Const) and a.value == 0.0:
            return b
        if isinstance(b, Const) and b.value == 0.0:
            return a
    if op == "-" and isinstance(b, Const) and b.value == 0.0:
        return a
    return Op(op, a, b)


def elementwise(op: str, A: Arr, B: Arr) -> Arr:
    """``A op B`` element by element (``+ - .* ./ .\\ .^`` and comparisons), with MATLAB's implicit expansion."""
    op = op.lstrip(".") if op not in ("==",) else op
    rows, cols = _broadcast(A.shape, B.shape)
    check_elements(rows * cols)
    if A.data is not None and B.data is not None:
        with np.errstate(all="ignore"):
            if op == "\\":
                data = np.divide(B.data, A.data)
            else:
                data = _NUMPY[op](A.data, B.data)
        out = Arr(rows, cols, data=np.broadcast_to(np.asarray(data, dtype=float), (rows, cols)).copy())
        out.logical = op in COMPARE
        return out
    items = []
    for j in range(cols):
        for i in range(rows):
            items.append(sym_op(op, _at(A, i, j), _at(B, i, j)))
    out = Arr.of_items(rows, cols, items)
    out.logical = op in COMPARE
    return out


def _at(A: Arr, i: int, j: int) -> Sym:
    i = 0 if A.rows == 1 else i
    j = 0 if A.cols == 1 else j
    return A.item(j * A.rows + i)


def negate(A: Arr) -> Arr:
    if A.data is not None:
        return Arr(A.rows, A.cols, data=-A.data)
    return Arr(A.rows, A.cols, items=[_neg(i) for i in A.items])


def _neg(item: Sym) -> Sym:
    if isinstance(item, Const):
        return Const(-item.value)
    return Op("neg", item)


def _term(coefficient: Sym, x: Sym) -> Sym | None:
    """coefficient * x, without the zeros and ones a constant matrix holds (exact in floating point)."""
    if isinstance(coefficient, Const):
        if coefficient.value == 0.0:
            return None
        if coefficient.value == 1.0:
            return x
        if coefficient.value == -1.0:
            return _neg(x)
    if isinstance(x, Const):
        if x.value == 0.0:
            return None
        if x.value == 1.0:
            return coefficient
    return Op("*", coefficient, x)


def matmul(A: Arr, B: Arr) -> Arr:
    """``A * B``: scalar times array elementwise, else the matrix product (one sum of products per element)."""
    if A.size == 1 or B.size == 1:
        return elementwise("*", A, B)
    if A.cols != B.rows:
        raise Unsupported(f"a {A.rows}x{A.cols} matrix times a {B.rows}x{B.cols} one: the inner sizes differ")
    check_elements(A.rows * B.cols * max(A.cols, 1), "a matrix product")
    if A.data is not None and B.data is not None:
        return Arr(A.rows, B.cols, data=A.data @ B.data)
    items = []
    for j in range(B.cols):
        for i in range(A.rows):
            total: Sym | None = None
            for k in range(A.cols):
                term = _term(_at(A, i, k), _at(B, k, j))
                if term is None:
                    continue
                total = term if total is None else Op("+", total, term)
            items.append(total if total is not None else Const(0.0))
    return Arr.of_items(A.rows, B.cols, items)


def transpose(A: Arr) -> Arr:
    if A.data is not None:
        out = Arr(A.cols, A.rows, data=A.data.T.copy())
    else:
        items = [A.items[j * A.rows + i] for i in range(A.rows) for j in range(A.cols)]
        out = Arr(A.cols, A.rows, items=items)
    out.is_char = A.is_char
    return out


def concat(rows: list[list[Arr]]) -> Arr:
    """``[a, b; c, d]``: each row's blocks side by side, then the rows stacked (empty blocks skipped)."""
    stacked: list[Arr] = []
    for row in rows:
        blocks = [b for b in row if b.size > 0]
        if not blocks:
            continue
        height = blocks[0].rows
        if any(b.rows != height for b in blocks):
            raise Unsupported("the blocks of a row of [...] have different heights")
        stacked.append(_hcat(blocks))
    if not stacked:
        return Arr(0, 0, data=np.zeros((0, 0)))
    width = stacked[0].cols
    if any(b.cols != width for b in stacked):
        raise Unsupported("the rows of [...] have different widths")
    if len(stacked) == 1:
        return stacked[0]
    check_elements(sum(b.size for b in stacked))
    if all(b.data is not None for b in stacked):
        return Arr.numeric(np.vstack([b.data for b in stacked]))
    total = sum(b.rows for b in stacked)
    items = []
    for j in range(width):
        for b in stacked:
            items.extend(b.item(j * b.rows + i) for i in range(b.rows))
    return Arr.of_items(total, width, items)


def _hcat(blocks: list[Arr]) -> Arr:
    if len(blocks) == 1:
        return blocks[0]
    check_elements(sum(b.size for b in blocks))
    if all(b.data is not None for b in blocks):
        out = Arr.numeric(np.hstack([b.data for b in blocks]))
        out.is_char = all(b.is_char for b in blocks)
        return out
    items = []
    for b in blocks:
        items.extend(b.all_items())
    return Arr.of_items(blocks[0].rows, sum(b.cols for b in blocks), items)


# --- indexing -----------------------------------------------------------------------------------


def _positions(spec, extent: int) -> list[int]:
    """0-based positions from an index: COLON, or an Arr of 1-based whole numbers or a logical mask."""
    if spec is COLON:
        return list(range(extent))
    values = spec.numbers()
    if values is None:
        raise Unsupported("an index that depends on the time or the state is not translated")
    flat = values.T.reshape(-1)
    if spec.logical:
        if flat.size > extent and np.any(flat[extent:]):
            raise Unsupported("a logical index longer than the array")
        return [k for k, v in enumerate(flat) if v]
    out = []
    for v in flat:
        if not np.isfinite(v) or v != int(v) or v < 1:
            raise Unsupported(f"an index must be a whole number >= 1; got {v:g}")
        out.append(int(v) - 1)
    return out


def index(A: Arr, specs: list) -> Arr:
    """``A(i)``, ``A(i, j)``: MATLAB's shapes (a vector indexed by a vector keeps the vector's orientation)."""
    if len(specs) == 1:
        spec = specs[0]
        positions = _positions(spec, A.size)
        if positions and max(positions) >= A.size:
            raise Unsupported(f"index {max(positions) + 1} is beyond the {A.size} elements of the array")
        if spec is COLON:
            rows, cols = A.size, 1
        elif A.rows == 1 and A.size > 0 and (spec.rows == 1 or spec.cols == 1):
            rows, cols = 1, len(positions)
        elif A.cols == 1 and A.size > 0 and (spec.rows == 1 or spec.cols == 1):
            rows, cols = len(positions), 1
        elif spec.logical:
            rows, cols = (1, len(positions)) if A.rows == 1 else (len(positions), 1)
        else:
            rows, cols = spec.rows, spec.cols
        return _take(A, positions, rows, cols)
    if len(specs) == 2 or (len(specs) > 2 and all(s is not COLON and s.numbers() is not None and
                                                  np.all(s.numbers() == 1) for s in specs[2:])):
        ri = _positions(specs[0], A.rows)
        ci = _positions(specs[1], A.cols)
        if (ri and max(ri) >= A.rows) or (ci and max(ci) >= A.cols):
            raise Unsupported(f"an index is beyond the {A.rows}x{A.cols} array")
        positions = [c * A.rows + r for c in ci for r in ri]
        return _take(A, positions, len(ri), len(ci))
    raise Unsupported("indexing with more than two subscripts is not translated")


def _take(A: Arr, positions: list[int], rows: int, cols: int) -> Arr:
    check_elements(len(positions))
    if A.data is not None:
        flat = A.data.T.reshape(-1)
        data = flat[positions].reshape(cols, rows).T if positions else np.zeros((rows, cols))
        out = Arr(rows, cols, data=np.array(data, dtype=float))
        out.is_char = A.is_char
        return out
    return Arr.of_items(rows, cols, [A.items[p] for p in positions])


def assign_index(A: Arr | None, specs: list, B: Arr) -> Arr:
    """``A(i) = B``, ``A(i, j) = B``: a new array (growing A with zeros as MATLAB does)."""
    if A is None:
        A = Arr(0, 0, data=np.zeros((0, 0)))
    if len(specs) == 1:
        return _assign_linear(A, specs[0], B)
    if len(specs) != 2:
        raise Unsupported("assigning with more than two subscripts is not translated")
    ri = _positions(specs[0], A.rows) if specs[0] is not COLON else list(range(max(A.rows, B.rows if A.rows == 0
                                                                                    else A.rows)))
    ci = _positions(specs[1], A.cols) if specs[1] is not COLON else list(range(max(A.cols, B.cols if A.cols == 0
                                                                                    else A.cols)))
    rows = max([A.rows] + [r + 1 for r in ri])
    cols = max([A.cols] + [c + 1 for c in ci])
    check_elements(rows * cols)
    items = _grown(A, rows, cols)
    values = _source(B, len(ri) * len(ci))
    k = 0
    for c in ci:
        for r in ri:
            items[c * rows + r] = values[k]
            k += 1
    return Arr.of_items(rows, cols, items)


def _grown(A: Arr, rows: int, cols: int) -> list[Sym]:
    items: list[Sym] = [Const(0.0)] * (rows * cols)
    for c in range(A.cols):
        for r in range(A.rows):
            items[c * rows + r] = A.item(c * A.rows + r)
    return items


def _source(B: Arr, count: int) -> list[Sym]:
    if B.size == 1:
        return [B.item(0)] * count
    if B.size != count:
        raise Unsupported(f"assigning {B.size} elements to {count} places")
    return B.all_items()


def _assign_linear(A: Arr, spec, B: Arr) -> Arr:
    if spec is COLON:
        if B.size == 1:
            return Arr.of_items(A.rows, A.cols, [B.item(0)] * A.size)
        if B.size != A.size:
            raise Unsupported(f"assigning {B.size} elements to the {A.size} of A(:)")
        return Arr.of_items(A.rows, A.cols, B.all_items())
    positions = _positions(spec, A.size)
    if B.size == 0 and positions:
        raise Unsupported("deleting elements (`x(k) = []`) is not translated")
    top = max(positions, default=-1) + 1
    rows, cols = A.rows, A.cols
    if top > A.size:
        if A.size == 0:
            rows, cols = (1, top) if not (spec.cols == 1 and spec.rows > 1) else (top, 1)
        elif A.rows == 1:
            cols = top
        elif A.cols == 1:
            rows = top
        else:
            raise Unsupported("a linear index beyond a matrix's elements")
    check_elements(rows * cols)
    items = _grown(A, rows, cols) if (rows, cols) != (A.rows, A.cols) else A.all_items()
    values = _source(B, len(positions))
    for p, v in zip(positions, values):
        items[p] = v
    return Arr.of_items(rows, cols, items)


# --- logic --------------------------------------------------------------------------------------


def truth(item: Sym) -> Sym:
    """An element as 0/1: comparisons already are; anything else is `x ~= 0`."""
    if isinstance(item, Op) and item.op in COMPARE:
        return item
    if isinstance(item, Const):
        return Const(1.0 if item.value != 0 else 0.0)
    return Op("~=", item, Const(0.0))


_INVERSE = {"==": "~=", "~=": "==", "<": ">=", ">=": "<", ">": "<=", "<=": ">"}


def logical_not(A: Arr) -> Arr:
    if A.data is not None:
        out = Arr(A.rows, A.cols, data=(A.data == 0).astype(float))
    else:
        out = Arr.of_items(A.rows, A.cols, [_not(i) for i in A.items])
    out.logical = True
    return out


def _not(item: Sym) -> Sym:
    if isinstance(item, Op) and item.op in _INVERSE:
        return Op(_INVERSE[item.op], item.a, item.b)
    if isinstance(item, Const):
        return Const(1.0 if item.value == 0 else 0.0)
    return Op("==", item, Const(0.0))


def logical_and(A: Arr, B: Arr) -> Arr:
    return _logic(A, B, lambda a, b: Op("*", truth(a), truth(b)), np.logical_and)


def logical_or(A: Arr, B: Arr) -> Arr:
    return _logic(A, B, lambda a, b: Call("max", (truth(a), truth(b))), np.logical_or)


def _logic(A: Arr, B: Arr, build, numeric) -> Arr:
    rows, cols = _broadcast(A.shape, B.shape)
    if A.data is not None and B.data is not None:
        out = Arr(rows, cols, data=np.broadcast_to(numeric(A.data != 0, B.data != 0).astype(float),
                                                   (rows, cols)).copy())
    else:
        items = [build(_at(A, i, j), _at(B, i, j)) for j in range(cols) for i in range(rows)]
        out = Arr.of_items(rows, cols, items)
    out.logical = True
    return out
