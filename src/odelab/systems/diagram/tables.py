"""The lookup-table block: Simulink's 1-D and 2-D Lookup Table.

1-D: ``breakpoints`` and ``table`` (or ``file``, a CSV of two columns: breakpoint, value), with
``interpolation`` = ``"linear"`` (Simulink's Linear point-slope), ``"flat"`` (the value at the
breakpoint at or below u), ``"nearest"`` (the nearest breakpoint's; half-way goes up) or
``"cubic-spline"`` (MATLAB's ``spline``: not-a-knot end conditions), and ``extrapolation`` =
``"clip"`` (hold the end values) or ``"linear"`` (continue the end segment's line; for a
spline, its end tangent). The shared arithmetic is :func:`odelab.signals.interpolate_1d`, which
the [inputs] ``table`` type uses too.

2-D: ``breakpoints1`` (rows, the first input), ``breakpoints2`` (columns, the second input)
and ``table`` (a matrix, one row per breakpoint of the first input), interpolation
``"linear"`` (bilinear), ``"flat"`` or ``"nearest"``, extrapolation ``"clip"`` or ``"linear"``.

A 1-D table's formula changes at its breakpoints (a kink for linear, a jump for flat and
nearest): with zero-crossing detection on (the default) the instants u crosses one are
located, as for a saturation's corners, so a table is not smeared by the step size.
"""

from __future__ import annotations

import difflib

import numpy as np

from odelab.signals.tables import (
    EXTRAPOLATIONS,
    INTERPOLATIONS,
    interpolate_1d,
    interpolate_2d,
    spline_pieces,
)
from odelab.systems.diagram.base import (
    ZC_KEY,
    Block,
    BlockError,
    Key,
    _column,
    _real,
    register,
)

__all__ = ["LookupTable"]



def _choice(block, key, allowed):
    value = block.params[key]
    if value not in allowed:
        close = difflib.get_close_matches(str(value), allowed, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise BlockError(f"`{key}` is {value!r}; use one of {', '.join(repr(a) for a in allowed)} (Simulink's "
                         f"names).{hint}", key=key)
    return value


def _axis(block, key, values) -> np.ndarray:
    try:
        bp = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise BlockError(f"`{key}` must be a list of numbers; got {values!r}.", key=key) from None
    if bp.ndim != 1 or bp.size < 2 or not np.all(np.isfinite(bp)):
        raise BlockError(f"`{key}` must be a list of at least two finite numbers; got {values!r}.", key=key)
    bad = np.flatnonzero(np.diff(bp) <= 0)
    if bad.size:
        i = int(bad[0])
        raise BlockError(f"`{key}` must strictly increase; entry {i + 1} ({bp[i + 1]:g}) does not come after "
                         f"{bp[i]:g}.", key=key)
    return bp


@register
class LookupTable(Block):
    """Simulink's 1-D / 2-D Lookup Table (see the module)."""

    TYPE = "lookup-table"
    INPUTS = (1, 2)
    LINEAR = False
    ZC = True
    KEYS = {"breakpoints": Key("numbers", None, "1-D: the breakpoints, increasing"),
            "table": Key("matrix", None, "the values: a list (1-D) or a matrix, rows for breakpoints1 (2-D)"),
            "file": Key("text", None, "1-D: a CSV of two columns, breakpoint and value (instead of breakpoints "
                                      "and table)"),
            "breakpoints1": Key("numbers", None, "2-D: the breakpoints of the first input (the table's rows)"),
            "breakpoints2": Key("numbers", None, "2-D: the breakpoints of the second input (its columns)"),
            "interpolation": Key("text", "linear", "\"linear\", \"flat\", \"nearest\" or \"cubic-spline\""),
            "extrapolation": Key("text", "clip", "\"clip\" (hold the end values) or \"linear\""),
            "zero_crossing": ZC_KEY}
    DOC = "y = table(u) (1-D) or table(u1, u2) (2-D)"

    def __init__(self, *, data: tuple | None = None, **kw):
        self._data = data  # (breakpoints, values) read from `file` by the caller
        super().__init__(**kw)

    def check(self):

        p = self.params
        self.interpolation = _choice(self, "interpolation", INTERPOLATIONS)
        self.extrapolation = _choice(self, "extrapolation", EXTRAPOLATIONS)
        two = p["breakpoints1"] is not None or p["breakpoints2"] is not None
        self.dims = 2 if two else 1
        if len(self.inputs) != self.dims:
            raise BlockError(f"a {self.dims}-D lookup table takes {self.dims} input{'s' if self.dims > 1 else ''}; "
                             f"got {len(self.inputs)}" + (" (give breakpoints1 and breakpoints2 for a 2-D table)"
                                                          if self.dims == 1 else "") + ".",
                             key="inputs" if len(self.inputs) > 1 else "input")
        if two:
            if p["breakpoints"] is not None or p["file"] is not None:
                raise BlockError("a 2-D table takes breakpoints1, breakpoints2 and table; remove "
                                 f"`{'breakpoints' if p['breakpoints'] is not None else 'file'}`.",
                                 key="breakpoints" if p["breakpoints"] is not None else "file")
            for k in ("breakpoints1", "breakpoints2", "table"):
                if p[k] is None:
                    raise BlockError(f"`{k}` is required for a 2-D lookup table.", key=k)
            if self.interpolation == "cubic-spline":
                raise BlockError("`interpolation` \"cubic-spline\" is for 1-D tables; a 2-D table takes \"linear\", "
                                 "\"flat\" or \"nearest\".", key="interpolation")
            self.bp1, self.bp2 = _axis(self, "breakpoints1", p["breakpoints1"]), _axis(self, "breakpoints2",
                                                                                     p["breakpoints2"])
            T = np.asarray(p["table"], dtype=float)
            if T.shape != (self.bp1.size, self.bp2.size) or not np.all(np.isfinite(T)):
                raise BlockError(f"`table` must be a finite {self.bp1.size} x {self.bp2.size} matrix (one row per "
                                 f"breakpoint of breakpoints1); got shape {T.shape}.", key="table")
            self.values = T
            return
        if self._data is not None:
            bp, vals = self._data
        elif p["file"] is not None:
            raise BlockError("`file` is read by the experiment loader; in Python give breakpoints and table.",
                             key="file")
        else:
            for k in ("breakpoints", "table"):
                if p[k] is None:
                    raise BlockError(f"`{k}` is required for a 1-D lookup table (or give `file`, a CSV of two "
                                     "columns).", key=k)
            bp, vals = p["breakpoints"], p["table"]
        self.bp = _axis(self, "breakpoints" if self._data is None else "file", bp)
        v = np.asarray(vals, dtype=float).reshape(-1) if np.ndim(vals) <= 2 else np.asarray(vals)
        if v.shape != self.bp.shape or not np.all(np.isfinite(v)):
            raise BlockError(f"`table` must have one finite value per breakpoint ({self.bp.size}); got "
                             f"{np.size(vals)}.", key="table")
        self.values = v
        self.spline = spline_pieces(self.bp, v) if self.interpolation == "cubic-spline" else None
        # where the formula changes: the breakpoints, or for "nearest" the midpoints between them
        self.edges = 0.5 * (self.bp[1:] + self.bp[:-1]) if self.interpolation == "nearest" else self.bp

    @property
    def zero_crossing(self):
        return bool(self.dims == 1 and self.params.get("zero_crossing", True))

    def setup(self, widths):
        if self.dims == 2:
            if widths != [1, 1]:
                raise BlockError(f"a 2-D lookup table takes two scalar inputs; got widths {widths}.", key="inputs")
            return [1]
        return [widths[0]]

    def outputs(self, t, x, u, cplx=False):

        if self.dims == 2:
            return [interpolate_2d(u[0], u[1], self.bp1, self.bp2, self.values, self.interpolation,
                                   self.extrapolation)]
        v = u[0]
        seg = None if self.mode is None else _column(self.mode, v)
        return [interpolate_1d(v, self.bp, self.values, self.interpolation, self.extrapolation, segment=seg,
                               spline=self.spline)]

    # -- zero crossings of a 1-D table: u against every edge (breakpoint, or midpoint for
    #    "nearest"); the mode is u's interval (0: below the first edge, i: in [e[i-1], e[i]),
    #    n: at or above the last)
    def zc_values(self, x, u):
        v = np.asarray(_real(u[0]), dtype=float).reshape(-1)
        return (v[None, :] - self.edges[:, None]).reshape(-1)  # (n edges, w) flattened

    def zc_mode(self, signs, x, u):
        s = np.asarray(signs).reshape(self.edges.size, -1)
        # at an edge exactly (sign 0, no history) u counts as in the interval it starts
        return np.sum(s >= 0, axis=0)

    def zc_directions(self, mode):
        mode = np.asarray(mode).reshape(-1)
        n = self.edges.size
        d = np.full((n, mode.size), np.nan)
        cols = np.arange(mode.size)
        lower = mode - 1  # the breakpoint at or below u
        upper = mode  # the breakpoint above u
        ok = lower >= 0
        d[lower[ok], cols[ok]] = -1.0
        ok = upper < n
        d[upper[ok], cols[ok]] = 1.0
        return d.reshape(-1)

    def label(self, name):
        if self.dims == 2:
            return f"{name}\n2-D table {self.bp1.size}x{self.bp2.size}, {self.interpolation}"
        return f"{name}\ntable [{self.bp[0]:g} .. {self.bp[-1]:g}], {self.interpolation}"
