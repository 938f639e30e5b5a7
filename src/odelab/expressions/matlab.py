"""MATLAB habits in expressions: matrix strings and ranges accepted, the rest recognised and explained.

Students write what MATLAB taught them. Two habits are unambiguous and simply work:

- a matrix as MATLAB writes it, ``"[0 1; -k/m -b/m]"``: rows split at ``;``, elements at commas
  or at spaces, with MATLAB's rule for a sign after a space (``[a -b]`` is two elements,
  ``[a - b]`` and ``[a-b]`` one), each element an expression of the language;
- a range ``"0:0.1:15"`` (or ``"0:15"``, ``"[0:0.1:15]"``), expanded as MATLAB's colon does,
  the last element snapped to the stop when round-off leaves it a hair short.

Others are recognised and get a message saying what to write instead: ``y(1)`` indexing a
state, a unit written into a value (``"10s"``, ``"1 m"``). This module only parses text; the
loader decides where matrices and ranges are allowed.
"""

from __future__ import annotations

import ast
import math
import re

import numpy as np

__all__ = ["colon_range", "indexing_hint", "is_matrix_string", "range_parts", "split_matrix", "syntax_hint"]

_OPERATOR_BEFORE = set("+-*/^(,=<>!&|")
_OPERATOR_AFTER = set("*/^),=<>!&|")
_RANGE = re.compile(r"^\s*\[?\s*([^:\[\]]+?)\s*:\s*([^:\[\]]+?)\s*(?::\s*([^:\[\]]+?)\s*)?\]?\s*$")
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-zµ°][A-Za-z/*^0-9µ°]*)\s*$")


def is_matrix_string(text: object) -> bool:
    """``"[0 1; -3 -4]"``: a string in brackets (MATLAB's matrix syntax)."""
    return isinstance(text, str) and text.strip().startswith("[") and text.strip().endswith("]")


def _split_row(row: str) -> list[str]:
    """A row's elements: split at top-level commas, and at spaces MATLAB reads as separators."""
    # Linear in the row's length: the last non-space character of the current element is kept,
    # never recomputed by joining the element so far (a 200,000-term row took minutes).
    elements: list[str] = []
    current: list[str] = []
    last = ""  # the current element's last non-space character ("" while it is empty)
    depth = 0
    i, n = 0, len(row)
    while i < n:
        c = row[i]
        if c in "([{":
            depth += 1
        elif c in ")]}":
            depth -= 1
        if depth == 0 and c == ",":
            elements.append("".join(current))
            current, last = [], ""
            i += 1
            continue
        if depth == 0 and c.isspace():
            j = i
            while j < n and row[j].isspace():
                j += 1
            after = row[j:j + 1]
            after2 = row[j + 1:j + 2]
            if not last or not after:
                pass  # leading or trailing space
            elif last in _OPERATOR_BEFORE or after in _OPERATOR_AFTER:
                current.append(" ")  # `a * b`, `a (` ... one element
            elif after in "+-" and (after2.isspace() or after2 == ""):
                current.append(" ")  # `a - b`: a binary minus
            else:  # `a b`, `a -b`: a new element (MATLAB's rule)
                elements.append("".join(current))
                current, last = [], ""
            i = j
            continue
        current.append(c)
        if not c.isspace():
            last = c
        i += 1
    elements.append("".join(current))
    return [e.strip() for e in elements if e.strip()]


def split_matrix(text: str) -> list[list[str]]:
    """``"[0 1; -k/m -b/m]"`` -> ``[["0", "1"], ["-k/m", "-b/m"]]`` (rows at ``;`` or line breaks).

    Raises ValueError naming the row whose length differs.
    """
    body = text.strip()[1:-1]
    rows = [r for r in re.split(r";|\n", body) if r.strip()]
    matrix = [_split_row(r) for r in rows]
    widths = {len(r) for r in matrix}
    if len(widths) > 1:
        first = len(matrix[0])
        bad = next(i for i, r in enumerate(matrix) if len(r) != first)
        raise ValueError(f"row {bad + 1} has {len(matrix[bad])} elements but row 1 has {first}; every row of a "
                         "matrix needs the same number (separate elements with spaces or commas, rows with ;)")
    return matrix


def range_parts(text: object) -> tuple[str, str, str] | None:
    """``"0:0.1:15"`` -> ``("0", "0.1", "15")``; ``"0:15"`` -> ``("0", "1", "15")``; None if not a range."""
    if not isinstance(text, str):
        return None
    m = _RANGE.match(text)
    if m is None:
        return None
    a, b, c = m.groups()
    return (a, b, c) if c is not None else (a, "1", b)


def colon_range(start: float, step: float, stop: float) -> np.ndarray:
    """MATLAB's ``start:step:stop``: every start + k*step up to stop, the last snapped to stop if within round-off."""
    if step == 0 or not all(math.isfinite(v) for v in (start, step, stop)):
        raise ValueError("the step of a range must be a finite, non-zero number")
    q = (stop - start) / step
    if not math.isfinite(q):
        raise ValueError("the range has more values than can be counted (a tiny step, or a span past the largest "
                         "float); take a larger step")
    if q < 0:
        return np.array([])
    n = round(q) if abs(q - round(q)) <= 1e-10 * max(1.0, abs(q)) else math.floor(q)
    values = start + step * np.arange(n + 1)
    if n == round(q) and abs(q - round(q)) <= 1e-10 * max(1.0, abs(q)):
        values[-1] = stop
    return values


def indexing_hint(name: str, arguments: list) -> str | None:
    """``y(1)``: MATLAB indexing of the state vector; odelab names each state instead."""
    if len(arguments) == 1 and isinstance(arguments[0], ast.Constant) and isinstance(arguments[0].value, int):
        k = arguments[0].value
        return (f"`{name}({k})` looks like MATLAB indexing of the state vector; odelab names each state: list "
                f"them in `states` (e.g. states = [\"{name}{k}\", ...]) and write the name (`{name}{k}`), not "
                f"`{name}({k})`")
    if len(arguments) == 1:
        arg = arguments[0]
        if (isinstance(arg, ast.BinOp) and isinstance(arg.op, ast.Sub) and isinstance(arg.left, ast.Name)
                and arg.left.id == "t"):
            tau = ast.unparse(arg.right)
            return (f"`{name}(t - {tau})` reads as {name} delayed by {tau}: write `lag({name}, {tau})` (a delay "
                    f"equation, solved by dde23; give {name}'s values before the start in [history])")
        if isinstance(arg, ast.Name) and arg.id == "t":
            return f"`{name}(t)` is `{name}`: a state or input is written by its name alone"
    return None


def syntax_hint(text: str, key: str | None = None) -> str | None:
    """A message for MATLAB habits that are not valid expressions: units in values, matrices, ranges."""
    m = _NUMBER_UNIT.match(text)
    if m is not None:
        number, unit = m.groups()
        return (f"`{text.strip()}` has a unit in it, which this key does not read: values with units are read in "
                f"[parameters], [initial] and [time] (converted by pint to the unit [units] declares for the name, "
                f"else to SI): give it a name there (p = \"{text.strip()}\") and write that name here")
    if is_matrix_string(text) and (";" in text or " " in text.strip()[1:-1].strip()):
        return ("a MATLAB matrix is a value of its own, not part of an expression: give it whole to a matrix key "
                "(A, B, C, D), e.g. A = \"[0 1; -k/m -b/m]\", or as TOML rows [[0, 1], [\"-k/m\", \"-b/m\"]]")
    if range_parts(text) is not None:
        return ("a MATLAB range (`a:step:b`) is a list of times, not a number: give it to `time.output`, e.g. "
                "output = \"0:0.1:15\"")
    return None
