"""Convergence order and work-precision: how a method's error shrinks, and what accuracy costs.

Pure functions, arrays in and frozen dataclasses out, as in DiffEqDevTools' convergence tests
and work-precision diagrams (Rackauckas & Nie, *DifferentialEquations.jl*, J. Open Res. Softw.
5(1), 2017) and diffrax's order tests.

The observed order is the slope of the least-squares line through (log h, log error). Two
things spoil that line, and the points they spoil are left out of the fit, visibly:

* **round-off**: once the truncation error falls to the size of the rounding errors of N
  steps (about N eps |y|), refining h no longer reduces the error (it grows again);
* **steps too large**: before the asymptotic regime, the error is not yet C h^p, and the local
  slope between the coarsest steps differs from the rest.

On a pure quadrature, dy/dt = f(t) (Exercise 1), a Runge-Kutta method is only its quadrature
rule, sum b_i f(t + c_i h), whose order can exceed the method's: Kutta's third-order method is
Simpson's rule there, of order 4. :func:`quadrature_order` gives that order, and a fit that
finds it says so instead of reporting a puzzle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ROUNDOFF_FACTOR",
    "SLOPE_TOLERANCE",
    "ConvergenceFit",
    "WorkPrecisionCurve",
    "convergence_order",
    "quadrature_order",
    "quadrature_rule",
    "work_precision",
]

EPS = float(np.finfo(float).eps)
# A point is round-off when its error is below ROUNDOFF_FACTOR * eps * N * scale (N steps), the
# size the rounding errors of N steps can reach.
ROUNDOFF_FACTOR = 1.0
# Coarse points are pre-asymptotic while the local slope from them differs from the finest
# local slope by more than this (in orders): the error is not yet C h^p there.
SLOPE_TOLERANCE = 0.1

ROUNDOFF = "round-off"
TOO_LARGE = "steps too large"
NO_ERROR = "no error measured"


@dataclass(frozen=True)
class ConvergenceFit:
    """The observed order of one method from errors at several step sizes (or tolerances).

    ``h`` is sorted from coarse to fine; ``excluded[i]`` is the reason point i was left out of
    the fit ("" where it was used). ``order`` is NaN when fewer than two points remain.
    """

    label: str
    h: tuple[float, ...]
    error: tuple[float, ...]
    excluded: tuple[str, ...]
    order: float
    intercept: float  # log10 C in error = C h^order
    nominal: float | None
    warnings: tuple[str, ...]
    note: str = ""  # why the observed order differs from the nominal one, where that is known

    @property
    def used(self) -> tuple[bool, ...]:
        return tuple(not why for why in self.excluded)

    @property
    def deviation(self) -> float | None:
        """Observed minus nominal order (None without a nominal order or a fit)."""
        if self.nominal is None or not math.isfinite(self.order):
            return None
        return self.order - self.nominal

    def fitted(self, h) -> np.ndarray:
        """The fitted line C h^order at ``h``."""
        return 10.0 ** (self.intercept + self.order * np.log10(np.asarray(h, dtype=float)))

    def as_dict(self) -> dict:
        return {"label": self.label, "h": list(self.h), "error": list(self.error), "excluded": list(self.excluded),
                "order": self.order, "intercept": self.intercept, "nominal": self.nominal,
                "warnings": list(self.warnings), "note": self.note}


def _fit(logh: np.ndarray, loge: np.ndarray) -> tuple[float, float]:
    """The least-squares line through the points, in closed form (np.polyfit would import numpy.ma,
    6-16 ms on the serial end of a study run, for the same two numbers)."""
    x = np.asarray(logh, dtype=float)
    y = np.asarray(loge, dtype=float)
    dx = x - x.mean()
    slope = float(dx @ (y - y.mean()) / (dx @ dx))
    return slope, float(y.mean() - slope * x.mean())


def quadrature_order(b, c, *, highest: int = 16) -> int:
    """The order of the quadrature rule sum b_i g(c_i) of a tableau: the largest q with
    sum b_i c_i^(k-1) = 1/k for k = 1..q (1 for Euler, 2 for Heun and the midpoint rule, 4 for
    Kutta's third-order method and RK4, both Simpson's rule)."""
    b = np.asarray(b, dtype=float)
    c = np.asarray(c, dtype=float)
    q = 0
    for k in range(1, highest + 1):
        if abs(float(b @ c ** (k - 1)) - 1.0 / k) > 1e-12:
            break
        q = k
    return q


_RULES = {((0.0, 1.0),): "the left rectangle rule", ((0.5, 1.0),): "the midpoint rule",
          ((0.0, 0.5), (1.0, 0.5)): "the trapezoidal rule",
          ((0.0, 1 / 6), (0.5, 2 / 3), (1.0, 1 / 6)): "Simpson's rule"}


def quadrature_rule(b, c) -> str:
    """The name of a tableau's quadrature rule (equal nodes merged), e.g. "Simpson's rule"."""
    weights: dict[float, float] = {}
    for bi, ci in zip(np.asarray(b, dtype=float).tolist(), np.asarray(c, dtype=float).tolist()):
        if bi != 0.0:
            weights[round(ci, 12)] = weights.get(round(ci, 12), 0.0) + bi
    nodes = tuple(sorted(weights.items()))
    for rule, name in _RULES.items():
        if len(rule) == len(nodes) and all(abs(a - x) < 1e-12 and abs(w - v) < 1e-12
                                           for (a, w), (x, v) in zip(rule, nodes)):
            return name
    return "its quadrature rule"


def convergence_order(h, error, *, nominal: float | None = None, label: str = "", steps=None,
                      scale: float = 1.0, quadrature: tuple[int, str] | None = None) -> ConvergenceFit:
    """Fit the observed order of accuracy, leaving out points spoiled by round-off or large steps.

    Parameters
    ----------
    h
        Step sizes (or tolerances), any order.
    error
        The global error at each (NaN or non-positive where none was measured, e.g. a failed run).
    nominal
        The method's order, for the comparison and the warnings.
    steps
        Number of steps at each ``h`` (for the round-off floor; default: none, no floor).
    scale
        Size of the solution (max |reference|), for the round-off floor.
    quadrature
        ``(order, rule name)`` of the method's quadrature rule when the problem is a pure
        quadrature (dy/dt does not depend on y): an observed order that matches it is explained.
    """
    h = np.asarray(h, dtype=float)
    error = np.asarray(error, dtype=float)
    order = np.argsort(-h)
    h, error = h[order], error[order]
    n = h.size
    excluded = ["" for _ in range(n)]
    for i in range(n):
        if not (math.isfinite(error[i]) and error[i] > 0):
            excluded[i] = NO_ERROR
    if steps is not None:
        steps = np.asarray(steps, dtype=float)[order]
        floor = ROUNDOFF_FACTOR * EPS * np.maximum(steps, 1.0) * max(scale, EPS)
        for i in range(n):
            if not excluded[i] and error[i] < floor[i]:
                excluded[i] = ROUNDOFF
    # Round-off also shows as an error that stops falling: from the fine end, drop points whose
    # error is not clearly below the next coarser point's.
    live = [i for i in range(n) if not excluded[i]]
    while len(live) >= 3:
        last, prev = live[-1], live[-2]
        slope = math.log(error[prev] / error[last]) / math.log(h[prev] / h[last])
        rest = _local_slopes(h, error, live[:-1])
        if rest.size and slope < 0.5 * _median(rest.tolist()):
            excluded[last] = ROUNDOFF
            live.pop()
        else:
            break
    # Steps too large: from the coarse end, drop points whose local slope is still changing.
    while len(live) >= 4:
        slopes = _local_slopes(h, error, live)
        if abs(slopes[0] - slopes[-1]) > SLOPE_TOLERANCE:
            excluded[live[0]] = TOO_LARGE
            live.pop(0)
        else:
            break
    warnings = []
    if len(live) >= 2:
        slope, intercept = _fit(np.log10(h[live]), np.log10(error[live]))
    else:
        slope, intercept = math.nan, math.nan
        warnings.append(f"{label}: fewer than two usable points; no order fitted".lstrip(": "))
    left_out = [f"h={h[i]:.6g} ({excluded[i]})" for i in range(n) if excluded[i]]
    if left_out:
        warnings.append(f"{label}: {len(left_out)} point{'s' if len(left_out) != 1 else ''} left out of the fit: "
                        f"{', '.join(left_out)}".lstrip(": "))
    note = ""
    if nominal is not None and math.isfinite(slope) and abs(slope - nominal) > 0.2:
        if quadrature is not None and quadrature[0] != nominal and abs(slope - quadrature[0]) <= 0.2:
            order_q, rule = quadrature
            note = f"{rule}, order {order_q}: dy/dt does not depend on y"
            warnings.append(f"{label}: observed order {slope:.2f}, not the nominal {nominal:g}, because dy/dt does "
                            f"not depend on y here: {label} then integrates it with the quadrature rule of its "
                            f"weights and nodes, {rule}, which is of order {order_q}".lstrip(": "))
        else:
            warnings.append(f"{label}: observed order {slope:.2f} is not the nominal {nominal:g}".lstrip(": "))
    return ConvergenceFit(label=label, h=tuple(h.tolist()), error=tuple(error.tolist()), excluded=tuple(excluded),
                          order=slope, intercept=intercept, nominal=nominal, warnings=tuple(warnings), note=note)


def _median(values: list[float]) -> float:
    """np.median of a few numbers, without np.median's import of numpy.ma (6-16 ms)."""
    v = sorted(values)
    n = len(v)
    return float(v[n // 2]) if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def _local_slopes(h: np.ndarray, error: np.ndarray, idx: list[int]) -> np.ndarray:
    a, b = np.array(idx[:-1]), np.array(idx[1:])
    if a.size == 0:
        return np.empty(0)
    return np.log(error[a] / error[b]) / np.log(h[a] / h[b])


@dataclass(frozen=True)
class WorkPrecisionCurve:
    """One method's cost against accuracy over a tolerance sweep, sorted from loose to tight."""

    label: str
    tolerance: tuple[float, ...]
    error: tuple[float, ...]
    nfevals: tuple[float, ...]
    seconds: tuple[float, ...]
    slope: float  # d log(nfevals) / d log(1/error): about 1/p for a method of order p

    def as_dict(self) -> dict:
        return {"label": self.label, "tolerance": list(self.tolerance), "error": list(self.error),
                "nfevals": list(self.nfevals), "seconds": list(self.seconds), "slope": self.slope}


def work_precision(label: str, tolerance, error, nfevals, seconds) -> WorkPrecisionCurve:
    """A work-precision curve: error against function evaluations and against time."""
    tol = np.asarray(tolerance, dtype=float)
    err = np.asarray(error, dtype=float)
    fev = np.asarray(nfevals, dtype=float)
    sec = np.asarray(seconds, dtype=float)
    order = np.argsort(-tol)
    tol, err, fev, sec = tol[order], err[order], fev[order], sec[order]
    ok = np.isfinite(err) & (err > 0) & np.isfinite(fev) & (fev > 0)
    slope = math.nan
    if np.count_nonzero(ok) >= 2 and np.ptp(np.log10(err[ok])) > 0:
        slope, _ = _fit(-np.log10(err[ok]), np.log10(fev[ok]))
    return WorkPrecisionCurve(label=label, tolerance=tuple(tol.tolist()), error=tuple(err.tolist()),
                              nfevals=tuple(fev.tolist()), seconds=tuple(sec.tolist()), slope=slope)
