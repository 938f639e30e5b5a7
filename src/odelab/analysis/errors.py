"""Error tables against a reference: absolute and relative error at every output point.

The relative error is the lab's |f - y| / |f|, with f the reference. Where |f| is zero or
tiny (at most ``RELATIVE_FLOOR`` times the largest |f| of that quantity) it is undefined:
such points get NaN in the table, are left out of the maximum and counted, never reported as
a silent inf.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RELATIVE_FLOOR", "ErrorSummary", "error_columns", "summarize"]

# sqrt(eps): below this fraction of the quantity's scale, |f| is round-off, not a value.
RELATIVE_FLOOR = math.sqrt(np.finfo(float).eps)


@dataclass(frozen=True)
class ErrorSummary:
    """Maximum errors of one quantity (a state or an output)."""

    name: str
    max_abs: float
    t_max_abs: float
    max_rel: float | None  # None when the relative error is undefined at every point
    t_max_rel: float | None
    undefined: int  # points where |f| is zero or tiny

    def as_dict(self) -> dict:
        return {"max_abs": self.max_abs, "t_max_abs": self.t_max_abs, "max_rel": self.max_rel,
                "t_max_rel": self.t_max_rel, "undefined_rel_points": self.undefined}


def error_columns(values: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Absolute and relative error columns; relative is NaN where |reference| is zero or tiny."""
    values = np.asarray(values, dtype=float)
    reference = np.asarray(reference, dtype=float)
    abs_err = np.abs(reference - values)
    scale = float(np.max(np.abs(reference))) if reference.size else 0.0
    magnitude = np.abs(reference)
    defined = magnitude > RELATIVE_FLOOR * scale
    rel_err = np.full_like(abs_err, np.nan)
    np.divide(abs_err, magnitude, out=rel_err, where=defined)
    return abs_err, rel_err


def summarize(name: str, t: np.ndarray, values: np.ndarray, reference: np.ndarray) -> ErrorSummary:
    """Maximum absolute and relative error of one quantity, with where they occur."""
    abs_err, rel_err = error_columns(values, reference)
    i = int(np.nanargmax(abs_err)) if np.any(np.isfinite(abs_err)) else 0
    undefined = int(np.count_nonzero(np.isnan(rel_err)))
    if undefined == rel_err.size:
        return ErrorSummary(name, float(abs_err[i]), float(t[i]), None, None, undefined)
    j = int(np.nanargmax(rel_err))
    return ErrorSummary(name, float(abs_err[i]), float(t[i]), float(rel_err[j]), float(t[j]), undefined)
