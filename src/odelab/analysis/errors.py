"""Error tables against a reference, and the one rule for the headline relative error.

Per point, the relative error is the lab's |f - y| / |f|, with f the reference. Where |f| is
zero or tiny (at most ``RELATIVE_FLOOR`` times the largest |f| of that quantity) it is
undefined: such points get NaN in the table, are left out of the maximum and counted, never
reported as a silent inf.

The *headline* (the one number per quantity in the terminal, the JSON, result.json and the
report) follows :data:`HEADLINE_RULE`:

- where |f| stays at or above ``NEAR_ZERO`` (10 %) of its largest value at every output point
  (Exercise 1: f = sin t + 2 stays in [1, 3]), it is the lab's maximum of |f - y| / |f|;
  that maximum is then at most ten times the error relative to the peak, so it measures what
  a reader thinks it measures;
- where the reference comes nearer zero than that (a step response starting at rest, a
  sine, a velocity decaying to zero), the pointwise maximum is dominated by dividing by a
  small |f| (y of Exercise 2's sine input: 2.8e-2 at t = 0.02 where y = 4e-4) and says nothing
  about the solution as a whole; the headline is then max |f - y| / max |f|, the error
  relative to the reference's peak, labelled "of peak". The pointwise maximum is still
  reported beside it, with where it happens and how small |f| was there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "HEADLINE_RULE",
    "NEAR_ZERO",
    "RELATIVE_FLOOR",
    "ErrorSummary",
    "error_columns",
    "headline_basis",
    "summarize",
]

# sqrt(eps): below this fraction of the quantity's scale, |f| is round-off, not a value.
RELATIVE_FLOOR = math.sqrt(np.finfo(float).eps)
# |f| below this fraction of max |f| somewhere: the pointwise maximum no longer headlines.
NEAR_ZERO = 0.1

HEADLINE_RULE = (
    "rel error = max |f - y| / |f| over the output points (the lab's definition) when |f| stays above "
    f"{NEAR_ZERO:.0%} of max |f|; where the reference comes nearer zero, dividing by a small |f| would "
    "dominate, so the headline is max |f - y| / max |f| (\"of peak\") and the pointwise maximum is "
    "given beside it with its t and |f| there.")


@dataclass(frozen=True)
class ErrorSummary:
    """Maximum errors of one quantity (a state or an output), and its headline relative error."""

    name: str
    max_abs: float
    t_max_abs: float
    max_rel: float | None  # pointwise max |f - y| / |f|; None when undefined at every point
    t_max_rel: float | None
    undefined: int  # points where |f| is zero or tiny
    scale: float = math.nan  # max |f|
    ref_at_max_rel: float | None = None  # |f| where the pointwise maximum is
    basis: str = "pointwise"  # "pointwise" (the lab's maximum headlines) or "peak"

    @property
    def peak_rel(self) -> float | None:
        """max |f - y| / max |f|: the error relative to the reference's peak (None if f is all zero)."""
        if not self.scale > 0:
            return None
        return self.max_abs / self.scale

    @property
    def headline(self) -> float | None:
        """The relative error to show as the one number: see :data:`HEADLINE_RULE`."""
        return self.max_rel if self.basis == "pointwise" else self.peak_rel

    def as_dict(self) -> dict:
        return {"max_abs": self.max_abs, "t_max_abs": self.t_max_abs, "max_rel": self.max_rel,
                "t_max_rel": self.t_max_rel, "undefined_rel_points": self.undefined,
                "ref_at_max_rel": self.ref_at_max_rel, "scale": self.scale,
                "rel_error": self.headline, "rel_basis": self.basis}


def error_columns(values: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Absolute and relative error columns; relative is NaN where |reference| is zero or tiny."""
    values = np.asarray(values, dtype=float)
    reference = np.asarray(reference, dtype=float)
    return _error_columns(values, reference, float(np.max(np.abs(reference))) if reference.size else 0.0)


def _error_columns(values: np.ndarray, reference: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The columns of (a block of) a quantity whose largest |reference| is ``scale``."""
    abs_err = np.abs(reference - values)
    magnitude = np.abs(reference)
    defined = magnitude > RELATIVE_FLOOR * scale
    rel_err = np.full_like(abs_err, np.nan)
    np.divide(abs_err, magnitude, out=rel_err, where=defined)
    return abs_err, rel_err


def headline_basis(reference: np.ndarray) -> str:
    """"pointwise" if |f| stays at or above NEAR_ZERO of its maximum at every point, else "peak"."""
    magnitude = np.abs(np.asarray(reference, dtype=float))
    finite = magnitude[np.isfinite(magnitude)]
    return _basis(float(finite.min()), float(finite.max())) if finite.size else "peak"


def _basis(low: float, high: float) -> str:
    """The rule of :func:`headline_basis` on the smallest and largest finite |f| (low > high: none)."""
    return "pointwise" if high >= low and high > 0 and low >= NEAR_ZERO * high else "peak"


#: Points summarize() looks at at once: its temporaries stay a few MB for any length of run.
BLOCK = 1 << 16


def summarize(name: str, t: np.ndarray, values: np.ndarray, reference: np.ndarray, *, block: int = BLOCK) -> ErrorSummary:
    """Maximum absolute and relative error of one quantity, where they occur, and the headline basis.

    The numbers of :func:`error_columns` over the whole columns, their maxima at the first point
    of the largest, and :func:`headline_basis`, found ``block`` points at a time: maxima and
    counts do not depend on the blocks (tested against the whole columns)."""
    reference = np.asarray(reference, dtype=float)
    values = np.asarray(values, dtype=float)
    n = reference.size
    col_scale = 0.0 if n == 0 else -np.inf  # error_columns' scale: max |f| (NaN if some f is NaN)
    low, high = np.inf, -np.inf  # the extremes of the finite |f| (headline_basis, and the scale shown)
    for lo in range(0, n, block):
        magnitude = np.abs(reference[lo:lo + block])
        col_scale = np.maximum(col_scale, magnitude.max())
        finite = magnitude[np.isfinite(magnitude)]
        if finite.size:
            low, high = min(low, float(finite.min())), max(high, float(finite.max()))
    col_scale = float(col_scale)
    any_finite, i, best_abs = False, 0, None
    undefined, j, best_rel = 0, None, None
    for lo in range(0, n, block):
        abs_err, rel_err = _error_columns(values[lo:lo + block], reference[lo:lo + block], col_scale)
        any_finite = any_finite or bool(np.isfinite(abs_err).any())
        if not np.isnan(abs_err).all():
            k = int(np.nanargmax(abs_err))
            if best_abs is None or abs_err[k] > best_abs:
                i, best_abs = lo + k, abs_err[k]
        nan = np.isnan(rel_err)
        undefined += int(np.count_nonzero(nan))
        if not nan.all():
            k = int(np.nanargmax(rel_err))
            if best_rel is None or rel_err[k] > best_rel:
                j, best_rel = lo + k, rel_err[k]
    if not any_finite:  # as over the whole column: the first point when no error is finite
        i = 0
    max_abs = float(np.abs(reference[i] - values[i]))
    scale = high if high >= low else math.nan
    basis = _basis(low, high)
    if j is None:
        return ErrorSummary(name, max_abs, float(t[i]), None, None, undefined, scale, None, basis)
    return ErrorSummary(name, max_abs, float(t[i]), float(best_rel), float(t[j]), undefined, scale,
                        float(abs(reference[j])), basis)
