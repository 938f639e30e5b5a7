"""Data tables: ``load`` of a numeric text file beside the MATLAB file, and ``interp1`` of a table.

``interp1(tdata, udata, t)`` in a right-hand side is an input u(t): a ``table`` input of the
experiment, naming the data file when the table is that file's two columns, else holding the
numbers. ``interp1`` of a table in a state (``interp1(xs, fs, y(1))``) is written as a
piecewise-linear expression when the table is short. MATLAB gives NaN outside the table's range
(unless ``'extrap'``); odelab's table holds its end values there (said in the import table).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from odelab.formats.base import IGNORED, TRANSLATED
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab.values import (Arr, Call, Const, Input, Op, Str, Time, Unknown, Unsupported)

__all__ = ["load", "load_command", "interp1", "MAX_TABLE_BYTES", "MAX_TABLE_ROWS"]

MAX_TABLE_BYTES = 10_000_000
MAX_TABLE_ROWS = 200_000
MAX_PIECEWISE = 32
_SPLIT = re.compile(r"[,;\s]+")
_METHODS = {"linear": "linear", "previous": "flat", "nearest": "nearest", "spline": "cubic-spline"}


def _resolve(interp, name: str, scope, line: int) -> Path:
    folder = Path(scope.file).resolve().parent
    candidate = Path(name)
    if candidate.is_absolute() or ".." in candidate.parts or "\x00" in name:
        raise Unsupported(f"`{name}` is outside the MATLAB file's folder; copy the data file next to it")
    path = folder / candidate
    if not path.suffix and not path.exists():
        path = path.with_suffix(".mat")
    return path


def _read_numbers(path: Path, header_allowed: bool) -> tuple[np.ndarray, bool]:
    if path.suffix.lower() == ".mat":
        raise Unsupported(f"`{path.name}` is a .mat file (binary); save the data as text or CSV "
                          "(writematrix) and load that")
    try:
        info = path.stat()
    except OSError:
        raise Unsupported(f"the data file `{path.name}` is not beside the MATLAB file") from None
    if not path.is_file() or info.st_size > MAX_TABLE_BYTES:
        raise Unsupported(f"`{path.name}` is not a data file odelab reads (a text file of at most "
                          f"{MAX_TABLE_BYTES:,} bytes)")
    raw = path.read_bytes()
    if b"\x00" in raw[:4096]:
        raise Unsupported(f"`{path.name}` is binary; save the data as text or CSV")
    rows: list[list[float]] = []
    header = False
    for number, line in enumerate(raw.decode("utf-8-sig", errors="replace").splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped[0] in "%#":
            continue
        cells = [c for c in _SPLIT.split(stripped) if c]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows and header_allowed and not header:
                header = True
                continue
            raise Unsupported(f"`{path.name}` line {number} is not numbers") from None
        if rows and len(values) != len(rows[0]):
            raise Unsupported(f"`{path.name}` line {number} has {len(values)} columns, not {len(rows[0])}")
        rows.append(values)
        if len(rows) > MAX_TABLE_ROWS:
            raise Unsupported(f"`{path.name}` has more than {MAX_TABLE_ROWS:,} rows")
    if not rows:
        raise Unsupported(f"`{path.name}` holds no numbers")
    return np.array(rows, dtype=float), header


def load(interp, args: list, node: n.Expr, scope) -> Arr:
    if not args or not isinstance(args[0], Str):
        raise Unsupported("the data file's name must be a constant string")
    name = args[0].text
    path = _resolve(interp, name, scope, node.line)
    header_allowed = not (isinstance(node, n.Index) and isinstance(node.target, n.Id)
                          and node.target.name == "load")
    data, header = _read_numbers(path, header_allowed)
    out = Arr.numeric(data)
    out.source = (str(path), None, data.shape[1], header)
    interp.note(node.line, f"load('{name}')" if not header_allowed else name, TRANSLATED,
                f"read {data.shape[0]} rows x {data.shape[1]} columns of numbers", scope.file)
    return out


def load_command(interp, stmt, scope) -> None:
    """``load data.txt``: the variable ``data``."""
    name = stmt.words[0]
    path = _resolve(interp, name, scope, stmt.line)
    try:
        data, header = _read_numbers(path, False)
    except Unsupported as exc:
        scope.set(Path(name).stem, Unknown(str(exc), stmt.line, scope.file), interp.globals)
        interp.note(stmt.line, stmt.text, IGNORED, f"not read: {exc}", scope.file)
        return
    out = Arr.numeric(data)
    out.source = (str(path), None, data.shape[1], header)
    scope.set(re.sub(r"\W", "_", Path(name).stem), out, interp.globals)
    interp.note(stmt.line, stmt.text, TRANSLATED, f"read {data.shape[0]} rows x {data.shape[1]} columns", scope.file)


def _vector(interp, value, what: str) -> Arr:
    arr = interp.numeric(value, what)
    if arr.numbers() is None:
        raise Unsupported(f"interp1's {what} must be constant numbers")
    if arr.rows != 1 and arr.cols != 1:
        raise Unsupported(f"interp1 of a matrix ({what}) is not translated: one column at a time")
    return arr


def interp1(interp, args: list, node: n.Expr, scope):
    for a in args:
        if isinstance(a, Unknown):
            return a
    texts = [a.text.lower() for a in args if isinstance(a, Str)]
    numeric_args = [a for a in args if not isinstance(a, Str)]
    method = next((t for t in texts if t != "extrap"), "linear")
    extrapolate = "extrap" in texts
    if len(numeric_args) == 2:
        v = _vector(interp, numeric_args[0], "values")
        x = Arr.numeric(np.arange(1.0, v.size + 1.0))
        query = numeric_args[1]
    elif len(numeric_args) >= 3:
        x = _vector(interp, numeric_args[0], "sample points")
        v = _vector(interp, numeric_args[1], "values")
        query = numeric_args[2]
        if len(numeric_args) > 3:
            raise Unsupported("interp1 with a numeric extrapolation value is not translated")
    else:
        raise Unsupported("interp1 needs the table and the query points")
    if method not in _METHODS:
        raise Unsupported(f"interp1's method {method!r} is not translated (odelab's tables: linear, previous, "
                          "nearest, spline)")
    xs = x.numbers().reshape(-1)
    vs = v.numbers().reshape(-1)
    if xs.size != vs.size or xs.size < 2:
        raise Unsupported("interp1's sample points and values differ in length")
    if not np.all(np.diff(xs) > 0):
        raise Unsupported("interp1's sample points must increase (odelab's tables need increasing times)")
    query = interp.numeric(query, "the query point")
    if query.numbers() is not None:
        q = query.numbers()
        with np.errstate(all="ignore"):
            out = np.interp(q, xs, vs, left=np.nan if not extrapolate else None, right=np.nan if not extrapolate
                            else None)
        if method != "linear":
            raise Unsupported("interp1 of constants with a method other than linear")
        return Arr.numeric(out)
    if query.size != 1:
        raise Unsupported("interp1 at several query points that depend on the state")
    item = query.item(0)
    if isinstance(item, Time):
        return Arr.scalar(_table_input(interp, node, scope, x, v, xs, vs, method, extrapolate))
    if method != "linear" or xs.size > MAX_PIECEWISE:
        raise Unsupported(f"interp1 of a table in the state is translated only when linear and of at most "
                          f"{MAX_PIECEWISE} points (write the table's function, or make the table an input of t)")
    interp.note(node.line, "interp1(...)", TRANSLATED, "a piecewise-linear expression of the state (held at the "
                "table's ends, where MATLAB gives NaN)", scope.file)
    return Arr.scalar(_piecewise(item, xs, vs))


def _piecewise(q, xs: np.ndarray, vs: np.ndarray):
    clipped = Call("min", (Call("max", (q, Const(float(xs[0])))), Const(float(xs[-1]))))
    value = None
    for k in range(len(xs) - 2, -1, -1):
        slope = (vs[k + 1] - vs[k]) / (xs[k + 1] - xs[k])
        segment = Op("+", Const(float(vs[k])), Op("*", Const(float(slope)), Op("-", clipped, Const(float(xs[k])))))
        value = segment if value is None else Call("where", (Op("<", clipped, Const(float(xs[k + 1]))), segment,
                                                             value))
    return value


def _table_input(interp, node: n.Expr, scope, x: Arr, v: Arr, xs, vs, method: str, extrapolate: bool) -> Input:
    spec: dict = {"type": "table"}
    source_x, source_v = getattr(x, "source", None), getattr(v, "source", None)
    if (source_x and source_v and source_x[0] == source_v[0] and source_x[1] == 0 and source_v[1] == 1
            and source_x[2] == 2):
        spec["file"] = source_x[0]  # made relative to the written file by the reader
    else:
        spec["t"] = [float(a) for a in xs]
        spec["values"] = [float(a) for a in vs]
    spec["interpolation"] = _METHODS[method]
    spec["extrapolation"] = "linear" if extrapolate else "clip"
    for name, existing in interp.inputs.items():
        if existing.spec == spec:
            return existing
    hint = "u"
    if isinstance(node, n.Index) and len(node.args) >= 2 and isinstance(node.args[1 if len(node.args) > 2 else 0],
                                                                         n.Id):
        hint = node.args[1 if len(node.args) > 2 else 0].name
    from odelab.formats.matlab.exprtext import identifier, _reserved_words

    name = identifier(hint, _reserved_words())
    base, k = name, 2
    while name in interp.inputs:
        name = f"{base}_{k}"
        k += 1
    made = Input(name, spec)
    interp.inputs[name] = made
    outside = ("extrapolated linearly, as 'extrap'" if extrapolate else
               "held at its end values outside the table, where MATLAB gives NaN")
    interp.note(node.line, "interp1(...)", TRANSLATED, f"the input {name}(t): a table ({outside})", scope.file)
    return made


__all__ += ["os"]
