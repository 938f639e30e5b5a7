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
    abs_err = np.abs(reference - values)
    scale = float(np.max(np.abs(reference))) if reference.size else 0.0
    magnitude = np.abs(reference)
    defined = magnitude > RELATIVE_FLOOR * scale
    rel_err = np.full_like(abs_err, np.nan)
    np.divide(abs_err, magnitude, out=rel_err, where=defined)
    return abs_err, rel_err


def headline_basis(reference: np.ndarray) -> str:
    """"pointwise" if |f| stays at or above NEAR_ZERO of its maximum at every point, else "peak"."""
    magnitude = np.abs(np.asarray(reference, dtype=float))
    finite = magnitude[np.isfinite(magnitude)]
    if finite.size == 0 or not finite.max() > 0:
        return "peak"
    return "pointwise" if finite.min() >= NEAR_ZERO * finite.max() else "peak"


def summarize(name: str, t: np.ndarray, values: np.ndarray, reference: np.ndarray) -> ErrorSummary:
    """Maximum absolute and relative error of one quantity, where they occur, and the headline basis."""
    reference = np.asarray(reference, dtype=float)
    abs_err, rel_err = error_columns(values, reference)
    i = int(np.nanargmax(abs_err)) if np.any(np.isfinite(abs_err)) else 0
    undefined = int(np.count_nonzero(np.isnan(rel_err)))
    finite_ref = np.abs(reference[np.isfinite(reference)])
    scale = float(finite_ref.max()) if finite_ref.size else math.nan
    basis = headline_basis(reference)
    if undefined == rel_err.size:
        return ErrorSummary(name, float(abs_err[i]), float(t[i]), None, None, undefined, scale, None, basis)
    j = int(np.nanargmax(rel_err))
    return ErrorSummary(name, float(abs_err[i]), float(t[i]), float(rel_err[j]), float(t[j]), undefined, scale,
                        float(abs(reference[j])), basis)
