"""Tables: the interpolation of Simulink's lookup tables (1-D and 2-D, the [inputs] table type
and the diagrams' lookup-table blocks) and the Table signal, read from samples or a file."""

from __future__ import annotations

import csv
import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from odelab.exceptions import InputError
from odelab.fileio import DECIMAL_COMMA_FIX, decimal_comma_line
from odelab.signals.base import (
    ExactForm,
    Piece,
    Signal,
    SignalContext,
    SignalKey,
    Term,
    _inside,
    _shaped,
    _times,
)


def _quoted_line(line: str, rows_so_far: list) -> str:
    """A bad line of a table file, quoted (shortened) only when earlier lines were samples: a file
    that is not a table at all (a path pointed at /etc/passwd) has none of its content quoted."""
    if not rows_so_far:
        return ("text, and so did the line before it: the file is not a table of samples (two numeric "
                "columns t, u); check `file`")
    return repr(line if len(line) <= 60 else line[:57] + "...")

# -- table interpolation (the [inputs] table type and the diagrams' lookup-table block) -----------

#: Simulink's interpolation and extrapolation methods of lookup tables, in odelab's spelling
INTERPOLATIONS = ("linear", "flat", "nearest", "cubic-spline")
EXTRAPOLATIONS = ("clip", "linear")


def spline_pieces(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The coefficients (4, n - 1) of MATLAB's ``spline`` through (x, y) (not-a-knot ends; two
    points give the line, three the parabola): piece i is sum c[k, i] (t - x[i])**(3 - k)."""
    from scipy.interpolate import CubicSpline

    return np.asarray(CubicSpline(x, y, bc_type="not-a-knot").c, dtype=float)


def _re(v):
    return v.real if np.iscomplexobj(v) else v


def interpolate_1d(v, x: np.ndarray, y: np.ndarray, interpolation: str = "linear", extrapolation: str = "clip",
                   *, segment=None, spline: np.ndarray | None = None):
    """Table lookup y(v) through the points (x, y), x increasing, as Simulink's 1-D Lookup Table.

    ``interpolation``: ``"linear"``; ``"flat"`` (the value at the breakpoint at or below v);
    ``"nearest"`` (the nearest breakpoint's value, half-way goes up); ``"cubic-spline"``
    (MATLAB's ``spline``, coefficients ``spline`` from :func:`spline_pieces`).
    ``extrapolation``: ``"clip"`` (the end values) or ``"linear"`` (the end segment's line; a
    spline's end tangent). ``segment``, if given, is the interval index to use (the number of
    breakpoints at or below v, or for ``"nearest"`` of midpoints), so a caller can hold it;
    otherwise it is read off v. v may be complex (complex-step derivatives): the decisions are
    taken on its real part.
    """
    n = x.size
    r = _re(v)
    edges = 0.5 * (x[1:] + x[:-1]) if interpolation == "nearest" else x
    m = np.searchsorted(edges, r, side="right") if segment is None else np.broadcast_to(segment, np.shape(v))
    zero = 0.0 * v
    slope = np.diff(y) / np.diff(x)
    if interpolation == "nearest":
        out = y[np.clip(m, 0, n - 1)] + zero
    elif interpolation == "flat":
        out = y[np.clip(m - 1, 0, n - 1)] + zero
    elif interpolation == "cubic-spline":
        c = spline_pieces(x, y) if spline is None else spline
        j = np.clip(m - 1, 0, n - 2)
        dx = v - x[j]
        out = ((c[0, j] * dx + c[1, j]) * dx + c[2, j]) * dx + c[3, j]
    else:
        j = np.clip(m - 1, 0, n - 2)
        out = y[j] + slope[j] * (v - x[j])
    if segment is not None and interpolation != "nearest":  # the held interval decides, not v
        below, above = m == 0, m == n
    else:
        below, above = r < x[0], r > x[-1]
    if extrapolation == "clip":
        out = np.where(below, y[0] + zero, np.where(above, y[-1] + zero, out))
    elif interpolation == "cubic-spline":
        c = spline_pieces(x, y) if spline is None else spline
        h = x[-1] - x[-2]
        d_end = (3 * c[0, -1] * h + 2 * c[1, -1]) * h + c[2, -1]
        out = np.where(below, y[0] + c[2, 0] * (v - x[0]), np.where(above, y[-1] + d_end * (v - x[-1]), out))
    else:
        out = np.where(below, y[0] + slope[0] * (v - x[0]), np.where(above, y[-1] + slope[-1] * (v - x[-1]), out))
    return out


def interpolate_2d(v1, v2, x1: np.ndarray, x2: np.ndarray, table: np.ndarray, interpolation: str = "linear",
                   extrapolation: str = "clip"):
    """2-D table lookup (rows for x1, columns for x2), as Simulink's 2-D Lookup Table:
    bilinear (``"linear"``), ``"flat"`` or ``"nearest"``; ``"clip"`` or ``"linear"`` outside."""
    r1, r2 = _re(v1), _re(v2)
    zero = 0.0 * v1 + 0.0 * v2
    if interpolation in ("flat", "nearest"):
        idx = []
        for r, x in ((r1, x1), (r2, x2)):
            if interpolation == "nearest":
                k = np.searchsorted(0.5 * (x[1:] + x[:-1]), r, side="right")
            else:
                k = np.searchsorted(x, r, side="right") - 1
            idx.append(np.clip(k, 0, x.size - 1))
        return table[idx[0], idx[1]] + zero
    parts = []
    for v, r, x in ((v1, r1, x1), (v2, r2, x2)):
        i = np.clip(np.searchsorted(x, r, side="right") - 1, 0, x.size - 2)
        if extrapolation == "clip":
            v = np.where(r < x[0], x[0] + 0.0 * v, np.where(r > x[-1], x[-1] + 0.0 * v, v))
        parts.append((i, (v - x[i]) / (x[i + 1] - x[i])))
    (i, a), (j, b) = parts
    return ((1 - a) * (1 - b) * table[i, j] + a * (1 - b) * table[i + 1, j] + (1 - a) * b * table[i, j + 1]
            + a * b * table[i + 1, j + 1]) + zero


@dataclass(frozen=True, eq=False)
class Table(Signal):
    """Interpolation of samples (t_i, u_i): linear between them and held constant outside
    [t_0, t_last] by default (Simulink's 1-D Lookup Table / From Workspace).

    ``interpolation`` is ``"linear"``, ``"flat"`` (each sample held until the next),
    ``"nearest"`` or ``"cubic-spline"`` (MATLAB's ``spline``); ``extrapolation`` is ``"clip"``
    (the end values) or ``"linear"`` (the end segments continued), as
    :func:`interpolate_1d`. ``t`` must be strictly increasing (a jump is a Step added to the
    table, or ``"flat"``).
    """

    TOML: ClassVar[str] = "table"
    KEYS: ClassVar[Mapping[str, SignalKey]] = {
        "file": SignalKey("", kind="text"), "t": SignalKey((), kind="numbers", unit="t"),
        "values": SignalKey((), kind="numbers", unit="u"), "interpolation": SignalKey("linear", kind="text"),
        "extrapolation": SignalKey("clip", kind="text")}

    t: Any
    values: Any
    label: str = ""
    interpolation: str = "linear"
    extrapolation: str = "clip"

    @classmethod
    def from_toml(cls, values: Mapping[str, Any], ctx: SignalContext) -> Table:
        """From a CSV file (``file``) or from the samples themselves (``t`` and ``values``, as MATLAB's
        ``interp1(tdata, udata, t)`` gives them)."""
        key = ctx.key
        for k, allowed_values in (("interpolation", INTERPOLATIONS), ("extrapolation", EXTRAPOLATIONS)):
            if values[k] not in allowed_values:
                close = difflib.get_close_matches(str(values[k]), allowed_values, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise InputError(f"`{key}.{k}` is {values[k]!r}; use one of "
                                 f"{', '.join(repr(a) for a in allowed_values)} (Simulink's names).{hint}",
                                 key=f"{key}.{k}")
        inline = bool(values.get("t")) or bool(values.get("values"))
        if values["file"] and inline:
            raise InputError(f"`{key}` has both `file` and `t`/`values`; keep one: the samples come from the file or "
                             "from the experiment file.", key=f"{key}.file")
        if inline:
            t, u = list(values.get("t") or ()), list(values.get("values") or ())
            if ctx.max_rows and len(t) > ctx.max_rows:
                raise InputError(f"`{key}.t` has {len(t):,} samples; the budget is {ctx.max_rows:,} rows per input "
                                 "table (raise it with `odelab run --limit table_rows=N` if you mean it).",
                                 key=f"{key}.t")
            try:
                return cls(t, u, interpolation=values["interpolation"], extrapolation=values["extrapolation"])
            except InputError as exc:
                raise InputError(f"`{key}`: {exc.message[:1].lower() + exc.message[1:]}", key=key) from None
        if not values["file"]:
            raise InputError(f"`{key}` needs its samples: `file` (a CSV of t and u) or `t` and `values` (lists of "
                             "numbers).", key=f"{key}.file")
        csv_path = ctx.resolve_file(values["file"], f"{key}.file")
        if not csv_path.is_file():
            raise InputError(f"`{key}.file`: {values['file']!r} does not exist (looked for {csv_path}).",
                             key=f"{key}.file")
        try:
            return cls.from_csv(csv_path, max_rows=ctx.max_rows, interpolation=values["interpolation"],
                                extrapolation=values["extrapolation"])
        except InputError as exc:  # named from the experiment file, which is what the user runs
            text = exc.message[:1].lower() + exc.message[1:]
            if ctx.max_rows and text.startswith("the table file has more than"):
                text += (f" The budget is {ctx.max_rows:,} rows per input table (each row is a breakpoint at which "
                         f"the solver restarts); raise it with `odelab run --limit table_rows=N` if you mean it.")
            raise InputError(f"`{key}.file` {values['file']!r}: {text}", key=f"{key}.file") from None

    @classmethod
    def describe(cls, name: str, values: Mapping[str, Any]) -> str:
        if values.get("file"):
            return f"{name}: table {values.get('file')}"
        return f"{name}: table of {len(values.get('t') or ())} samples"

    def compiled_reason(self) -> str | None:
        return None

    def numba_source(self, slot) -> str:
        t, u = slot(*self.t.tolist()), slot(*self.values.tolist())  # each stored as one slice (.span)
        return f"_np.interp(_tu, {t.span}, {u.span})"

    def __post_init__(self):
        try:
            t = np.array(self.t, dtype=float)
            u = np.array(self.values, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                "`Table.t` and `Table.values` must be 1-D arrays of real numbers; got "
                f"{self.t!r} and {self.values!r}.",
                key="Table",
            ) from None
        if t.ndim != 1 or u.ndim != 1:
            raise InputError(
                f"`Table.t` and `Table.values` must be 1-D; got shapes {t.shape} and {u.shape}.",
                key="Table",
            )
        if t.size != u.size:
            raise InputError(
                f"`Table.t` has {t.size} samples but `Table.values` has {u.size}: give one value "
                "per time.",
                key="Table",
            )
        if t.size == 0:
            raise InputError("A Table needs at least one sample; got none.", key="Table")
        for name, arr in (("t", t), ("values", u)):
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise InputError(
                    f"`Table.{name}` must be finite; sample {bad[0]} is {float(arr[bad[0]])!r}.",
                    key=f"Table.{name}",
                )
        steps = np.diff(t)
        bad = np.flatnonzero(steps <= 0)
        if bad.size:
            i = int(bad[0])
            raise InputError(
                f"`Table.t` must be strictly increasing; sample {i + 1} (t = {float(t[i + 1])!r}) does "
                f"not come after sample {i} (t = {float(t[i])!r}). Sort the samples, and model a jump "
                "with a Step added to the table.",
                key="Table.t",
            )
        if self.interpolation not in INTERPOLATIONS:
            raise InputError(f"`Table.interpolation` is {self.interpolation!r}; use one of "
                             f"{', '.join(repr(m) for m in INTERPOLATIONS)}.", key="Table.interpolation")
        if self.extrapolation not in EXTRAPOLATIONS:
            raise InputError(f"`Table.extrapolation` is {self.extrapolation!r}; use one of "
                             f"{', '.join(repr(m) for m in EXTRAPOLATIONS)}.", key="Table.extrapolation")
        if t.size < 2 and (self.interpolation != "linear" or self.extrapolation != "clip"):
            raise InputError(f"A Table with interpolation {self.interpolation!r} or extrapolation "
                             f"{self.extrapolation!r} needs at least two samples.", key="Table")
        t.setflags(write=False)
        u.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "values", u)
        spline = spline_pieces(t, u) if self.interpolation == "cubic-spline" else None
        object.__setattr__(self, "_spline", spline)

    @classmethod
    def from_csv(cls, path: str | Path, *, label: str | None = None, max_rows: int | None = None,
                 interpolation: str = "linear", extrapolation: str = "clip") -> Table:
        # (messages quote a line only once the file has shown itself a table: a path pointed at
        # /etc/shadow must not print a line of it)
        """Read two columns (t, u) from a CSV file, with an optional header line.

        Commas, semicolons, tabs or spaces separate the columns; blank lines and lines that
        start with ``#`` are skipped. The label is the header of the second column, if any.
        """
        path = Path(path)
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise InputError(f"Cannot read the table file: {exc.strerror}.", source=str(path)) from None
        if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in raw[:200]:
            raise InputError("The table file is UTF-16 or binary, not text; save it as CSV UTF-8 (in Excel: "
                             "Save as, CSV UTF-8).", source=str(path))
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise InputError(f"The table file is not UTF-8 text (byte {exc.start}); save it as CSV UTF-8 (in "
                             "Excel: Save as, CSV UTF-8).", source=str(path)) from None
        times: list[float] = []
        vals: list[float] = []
        header: list[str] | None = None
        for number, line in enumerate(text.splitlines(), start=1):
            stripped = line.strip()
            if not stripped or stripped.startswith("#"):
                continue
            if decimal_comma_line(stripped):
                raise InputError(f"line {number} writes its numbers with decimal commas "
                                 f"({_quoted_line(stripped, [None])}): {DECIMAL_COMMA_FIX}.", source=str(path))
            cells = _split_row(stripped)
            try:
                numbers = [float(cell) for cell in cells]
            except ValueError:
                if not times and header is None:
                    header = cells
                    continue
                raise InputError(
                    f"line {number}: expected two numbers (t, u); got {_quoted_line(stripped, times)}.",
                    source=str(path),
                ) from None
            if len(numbers) != 2:
                raise InputError(
                    f"line {number}: expected two columns (t, u); got {len(numbers)}"
                    f"{': ' + _quoted_line(stripped, times) if times else ''}.",
                    source=str(path),
                )
            times.append(numbers[0])
            vals.append(numbers[1])
            if max_rows and len(times) > max_rows:  # stop reading: the caller's budget says why
                raise InputError(f"The table file has more than {max_rows:,} rows.", source=str(path))
        if not times:
            raise InputError("The table file has no samples (two columns t, u).", source=str(path))
        if label is None:
            label = header[1] if header and len(header) == 2 else path.stem
        try:
            return cls(times, vals, label, interpolation, extrapolation)
        except InputError as exc:
            raise exc.located(source=str(path))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Table):
            return NotImplemented
        return (
            np.array_equal(self.t, other.t)
            and np.array_equal(self.values, other.values)
            and self.label == other.label
            and (self.interpolation, self.extrapolation) == (other.interpolation, other.extrapolation)
        )

    def __hash__(self) -> int:
        return hash((self.t.tobytes(), self.values.tobytes(), self.label, self.interpolation, self.extrapolation))

    def __repr__(self) -> str:
        label = f", label={self.label!r}" if self.label else ""
        return f"Table({self.t.size} samples, t from {float(self.t[0])!r} to {float(self.t[-1])!r}{label})"

    def __call__(self, t: Any) -> float | np.ndarray:
        t = _times(t)
        if self.interpolation == "linear" and self.extrapolation == "clip":
            return _shaped(t, np.interp(t, self.t, self.values))
        return _shaped(t, interpolate_1d(t, self.t, self.values, self.interpolation, self.extrapolation,
                                         spline=self._spline))

    def _slopes(self) -> np.ndarray:
        """Slope on (-inf, t_0), each segment, and (t_last, inf): size n + 1."""
        inner = np.diff(self.values) / np.diff(self.t)
        if self.extrapolation == "linear" and inner.size:
            return np.concatenate([inner[:1], inner, inner[-1:]])
        return np.concatenate([[0.0], inner, [0.0]])

    def breakpoints(self, t0: float, tf: float) -> np.ndarray:
        t, u = self.t, self.values
        if self.interpolation == "flat":  # jumps where the held value changes
            times = t[1:][np.diff(u) != 0]
            if self.extrapolation == "linear":
                times = np.concatenate([t[:1], times, t[-1:]])
        elif self.interpolation == "nearest":
            times = (0.5 * (t[1:] + t[:-1]))[np.diff(u) != 0]
            if self.extrapolation == "linear":
                times = np.concatenate([t[:1], times, t[-1:]])
        elif self.interpolation == "cubic-spline":
            times = t  # the third derivative jumps at the knots, the first at the ends (clip)
        else:
            slopes = self._slopes()
            # the slope changes at sample i when the segments on either side differ
            times = t[slopes[1:] != slopes[:-1]]
        return _inside(np.unique(times), t0, tf)

    def exact_terms(self) -> ExactForm | None:
        if self.interpolation != "linear":
            return None  # held, nearest and spline tables are simulated (restarted at their breakpoints)
        t, u, slopes = self.t, self.values, self._slopes()

        def generate(lo: float, hi: float) -> tuple[Piece, ...]:
            # only the samples around the window: a long table gives few pieces
            i0 = max(int(np.searchsorted(t, lo, side="right")) - 1, 0)
            i1 = min(int(np.searchsorted(t, hi, side="right")), t.size - 1)
            first = (Term(float(u[i0])),) if not slopes[0] else (Term(float(u[0])), Term(float(slopes[0]),
                                                                                             float(t[0]), 1))
            pieces = [Piece(-math.inf, float(t[i0]), first if i0 == 0 else (Term(float(u[i0])),))]
            for i in range(i0, i1):
                terms = (Term(float(u[i])), Term(float(slopes[i + 1]), float(t[i]), 1))
                pieces.append(Piece(float(t[i]), float(t[i + 1]), terms))
            # constant (or the last segment continued) after the last sample; when t[i1] > hi
            # this piece lies past the window
            last = (Term(float(u[i1])),) if not slopes[-1] or i1 != t.size - 1 else (
                Term(float(u[i1])), Term(float(slopes[-1]), float(t[i1]), 1))
            pieces.append(Piece(float(t[i1]), math.inf, last))
            return tuple(pieces)

        return ExactForm(generate)


def _split_row(line: str) -> list[str]:
    for sep in (",", ";", "\t"):
        if sep in line:
            return [cell.strip() for cell in next(csv.reader([line], delimiter=sep))]
    return line.split()


